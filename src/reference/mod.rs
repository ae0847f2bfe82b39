//! `gyrocomp evaluate --reference`: score a log against a measured reference.
//!
//! `gyrocomp evaluate --config FILE --input LOG --reference REF.csv[.gz]
//! [--out DIR] [--skip S] [--peers] [--offset S] [--align-s S]`
//!
//! The log is decoded once through the same assembler as replay
//! ([`crate::adis::Assembler`] via [`crate::replay::for_each_sample`]); the
//! decoded samples go to our [`Estimator`] and, with `--peers`, to VQF
//! ([`crate::peers`]) — the very same samples. Every estimator is aligned
//! and scored by the same code ([`score`]): the alignment (the mount from the
//! first rest phase, each estimator's yaw offset at its end), the rule near
//! the vertical, and the scores are documented there. Sample times come from
//! the sample counter (the first sample is t = 0); the reference's `t` is
//! on the same clock, shifted by `--offset` (the reference time of the first
//! sample).
//!
//! `--realdata DIR` ([`realdata`]) runs every recording folder under DIR
//! through `import` and this evaluation, ours and VQF, and prints one table.
//!
//! Writes into `--out`: `report.json` (ours at the top level, `peers.vqf`
//! beside it with the same keys, the alignment, the window) and
//! `errors.svg`.

pub mod plot;
pub mod realdata;
pub mod refcsv;
pub mod score;

use crate::adis::{Assembler, InputCounters, Sample};
use crate::config::Config;
use crate::estimator::Estimator;
use refcsv::{read_reference, Reference};
use score::{align, alignment_window, sample_times, score, Alignment, ErrRow, ScoreSpec, Scores, VERTICAL_LIMIT_DEG};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// The options `evaluate` takes for real data (flattened into `EvaluateArgs`).
#[derive(clap::Args, Debug, Clone, Default)]
pub struct ReferenceArgs {
    /// Score --input LOG (a candump log) against a measured reference CSV
    /// t,roll,pitch,yaw[,valid][,rest] (deg; gzip allowed). Default: none
    /// (--input is a simulate directory).
    #[arg(long, value_name = "REF.csv", requires = "input", conflicts_with_all = ["seeds", "realdata", "ablation"])]
    pub reference: Option<PathBuf>,
    /// Import and evaluate every recording folder under DIR (imu.csv.gz +
    /// reference.csv.gz [+ can.log.gz]); ours and VQF in one table. One of
    /// --input, --seeds or --realdata is required.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["input", "seeds", "ablation"])]
    pub realdata: Option<PathBuf>,
    /// Also run the peers on the same decoded samples, scored identically: VQF
    /// (vqf-rs, 9D with the magnetometer, 6D without) with --reference and
    /// --realdata; with --seeds too, VQF and Fusion (x-io's AHRS, fusion-ahrs)
    /// beside ours in every seed's rows and the summary. Default: off (always
    /// on with --realdata).
    #[arg(long)]
    pub peers: bool,
    /// Reference time of the log's first sample, s.
    #[arg(long, value_name = "S", default_value_t = 0.0, allow_hyphen_values = true)]
    pub offset: f64,
    /// Without a rest phase in the reference: estimate the mount over the
    /// first S seconds (0: no mount), s. Default: the first 5 s, and only if
    /// they look like rest (else no mount: a mount taken in motion holds the
    /// motion). Given, the mount is taken from them whatever they look like.
    /// Range: 0 up to the log's length (a window past its end is refused).
    #[arg(long, value_name = "S")]
    pub align_s: Option<f64>,
    /// With --realdata: power both estimators on S seconds into each
    /// recording (on its own clock); the samples, the car's frames and the
    /// reference rows before are left out, as for a daemon restarted while
    /// moving. --score-from counts from there. Default: from the first sample.
    #[arg(long, value_name = "S")]
    pub power_on_at: Option<f64>,
}

impl ReferenceArgs {
    pub fn active(&self) -> bool {
        self.reference.is_some() || self.realdata.is_some()
    }
}

/// How to evaluate against a reference.
#[derive(Clone, Debug)]
pub struct RefOptions {
    /// Score from this time on, s.
    pub skip: f64,
    pub offset: f64,
    pub align_s: f64,
    /// Take the mount from the first `align_s` seconds (no rest phase) even
    /// when they do not look like rest (`--align-s` given).
    pub force_align: bool,
    pub peers: bool,
    /// Real data: power on this many seconds into each recording.
    pub power_on_at: Option<f64>,
}

impl Default for RefOptions {
    fn default() -> Self {
        RefOptions { skip: 10.0, offset: 0.0, align_s: 5.0, force_align: false, peers: false, power_on_at: None }
    }
}

/// A log decoded into samples.
#[derive(Clone, Debug, Default)]
pub struct Decoded {
    pub samples: Vec<Sample>,
    pub lines: u64,
    pub bad_lines: u64,
    pub counters: InputCounters,
}

/// Decode a candump log with the config's profile and IDs.
pub fn decode<R: std::io::Read>(input: R, cfg: &Config, name: &str) -> Result<Decoded, String> {
    let mut asm = Assembler::new(cfg.profile(), cfg.input.ids);
    let mut samples = Vec::new();
    let st =
        crate::replay::for_each_sample(input, &mut asm, |s| samples.push(*s)).map_err(|(line, e)| format!("{name} line {line}: {e}"))?;
    if samples.is_empty() {
        let first = st.first_bad.map(|(n, e)| format!("; first bad line {n}: {e}")).unwrap_or_default();
        return Err(format!("{name}: no complete IMU sample ({} lines, {} bad{first})", st.lines, st.bad_lines));
    }
    Ok(Decoded { samples, lines: st.lines, bad_lines: st.bad_lines, counters: asm.counters })
}

/// Is the magnetometer configured (it may still be off: `"auto"` decides
/// from the data, see `run_ours`)?
pub fn magnetometer_configured(cfg: &Config) -> bool {
    let p = cfg.profile();
    cfg.estimator.use_magnetometer != crate::config::AutoBool::Bool(false) && p.magnetometer && p.magn_lsb > 0.0
}

/// Ours over a run: roll, pitch, yaw (deg) and mode per sample, and whether
/// the magnetometer was used.
pub type Ours = (Vec<[f64; 3]>, Vec<u8>, bool);

/// Our estimator over a log's frames, through the very pipeline the daemon
/// and `replay` run (so the vehicle's speed frames reach it when `[speed]` is
/// configured): roll, pitch, yaw (deg) and mode per sample, and whether it
/// used the magnetometer.
pub fn run_ours_log<R: std::io::Read>(log: R, cfg: &Config, name: &str) -> Result<Ours, String> {
    struct Keep(Vec<[f64; 3]>, Vec<u8>);
    impl crate::pipeline::Sink for Keep {
        fn output(&mut self, e: &crate::estimator::Estimate, _: &crate::output::Frames) {
            self.0.push([e.roll, e.pitch, e.yaw]);
            self.1.push(e.mode);
        }
    }
    let mut pipe = crate::pipeline::Pipeline::from_config(cfg).map_err(|e| format!("config: {e}"))?;
    let mut keep = Keep(Vec::new(), Vec::new());
    crate::replay::run(&mut pipe, log, &mut keep).map_err(|e| format!("{name}: {e}"))?;
    let magn = magnetometer_configured(cfg) && pipe.estimator().magnetometer().unwrap_or(true);
    Ok((keep.0, keep.1, magn))
}

/// Our estimator over the samples: roll, pitch, yaw (deg) and mode per
/// sample, and whether it used the magnetometer (yaw is scored, and VQF run
/// 9D, only then).
pub fn run_ours(samples: &[Sample], cfg: &Config) -> Ours {
    let mut e = Estimator::new(cfg);
    let mut att = Vec::with_capacity(samples.len());
    let mut modes = Vec::with_capacity(samples.len());
    for s in samples {
        let x = e.step(s);
        att.push([x.roll, x.pitch, x.yaw]);
        modes.push(x.mode);
    }
    let magn = magnetometer_configured(cfg) && e.magnetometer().unwrap_or(true);
    (att, modes, magn)
}

/// One estimator's result.
#[derive(Clone, Debug)]
pub struct Scored {
    pub name: String,
    pub scores: Scores,
    pub errors: Vec<ErrRow>,
    pub modes: Option<Vec<u8>>,
}

/// Everything one evaluation against a reference found.
#[derive(Clone, Debug)]
pub struct Evaluation {
    pub samples: usize,
    pub period: f64,
    pub skip: f64,
    pub offset: f64,
    pub magnetometer: bool,
    pub alignment: Alignment,
    /// Ours first, then the peers.
    pub results: Vec<Scored>,
}

/// Evaluate decoded samples against the reference: ours, and VQF with `peers`.
pub fn evaluate_samples(samples: &[Sample], cfg: &Config, r: &Reference, o: &RefOptions) -> Result<Evaluation, String> {
    let ours = run_ours(samples, cfg);
    evaluate_with(samples, ours, cfg, r, o)
}

/// `evaluate_samples` with our estimates given (`run_ours_log` on the log
/// the samples were decoded from).
pub fn evaluate_with(samples: &[Sample], ours: Ours, cfg: &Config, r: &Reference, o: &RefOptions) -> Result<Evaluation, String> {
    if ours.0.len() != samples.len() {
        return Err(format!("{} estimates for {} decoded samples", ours.0.len(), samples.len()));
    }
    let period = 1.0 / cfg.profile().rate_hz;
    let ts = sample_times(samples, period);
    let refq = r.at_times(&ts, o.offset);
    let end = ts.last().copied().unwrap_or(0.0);
    if o.skip >= end {
        return Err(format!("--score-from {} s is at or after the end of the log ({end:.1} s): nothing to score", o.skip));
    }
    let w = alignment_window(r, o.align_s, o.offset)?;
    if o.force_align && w.estimate_mount && !w.rest_phase && w.t1 > end {
        return Err(format!(
            "--align-s {} s: the mount window {:.1}..{:.1} s reaches past the end of the log ({end:.1} s); it must lie within the recording",
            o.align_s, w.t0, w.t1
        ));
    }
    let mut a = align(samples, &ts, &refq, &w)?;
    if w.estimate_mount && !w.rest_phase && !a.looks_at_rest && !o.force_align {
        // no rest phase, and the first seconds are not at rest either: a
        // mount taken from them holds the motion (0.1 g is 5.7 deg), so none
        let n = score::Window {
            t0: w.t0,
            t1: w.t0 + score::YAW_OFFSET_WINDOW_S,
            estimate_mount: false,
            rest_phase: false,
            refused_in_motion: true,
            source: format!(
                "no mount (no rest phase, and the first {} s do not look like rest: gyro std {:.2} deg/s, accel std {:.3} g; \
                 --align-s {} takes it from them anyway)",
                o.align_s, a.gyro_std_dps, a.accel_std_g, o.align_s
            ),
        };
        a = align(samples, &ts, &refq, &n)?;
    }
    let (att, modes, magn) = ours;
    let spec = ScoreSpec { ts: &ts, refq: &refq, align: &a, skip: o.skip, period, yaw: magn };
    let (sc, errors) = score(&att, Some(&modes), &spec);
    let mut results = vec![Scored { name: "ours".into(), scores: sc, errors, modes: Some(modes) }];
    if o.peers {
        let att = crate::peers::run_vqf(samples, period, magn);
        let (sc, errors) = score(&att, None, &spec);
        results.push(Scored { name: "vqf".into(), scores: sc, errors, modes: None });
    }
    Ok(Evaluation { samples: samples.len(), period, skip: o.skip, offset: o.offset, magnetometer: magn, alignment: a, results })
}

/// The mount column: the tilt removed, `*` when its window did not look like rest, `none` when not estimated.
fn mount_cell(a: &Alignment) -> String {
    if !a.window.estimate_mount {
        format!("{:>6}", "none")
    } else if a.looks_at_rest {
        format!("{:>6.2}", a.tilt_deg)
    } else {
        format!("{:>5.2}*", a.tilt_deg)
    }
}

fn f(v: f64, w: usize, p: usize) -> String {
    if v.is_finite() {
        format!("{v:>w$.p$}")
    } else {
        format!("{:>w$}", "-")
    }
}

/// The table header (the first column is `first`).
pub fn table_header(first: &str) -> String {
    format!(
        "{first:<26} {:<4} {:>8} {:>8} {:>9} {:>9} {:>8} {:>8} {:>10} {:>8} {:>7} {:>8} {:>7} {:>7} {:>6}\n",
        "est",
        "roll_max",
        "roll_rms",
        "pitch_max",
        "pitch_rms",
        "tilt_max",
        "tilt_rms",
        "yaw_rms",
        "scored_s",
        "vert_s",
        "fusion_s",
        "blend_s",
        "gyro_s",
        "mount"
    )
}

impl Evaluation {
    /// One table row per estimator.
    pub fn table_rows(&self, first: &str) -> String {
        let mut out = String::new();
        for (i, r) in self.results.iter().enumerate() {
            let s = &r.scores;
            let yaw = match s.yaw_rms {
                Some(v) => f(v, 10, 3),
                None => format!("{:>10}", "not scored"),
            };
            let modes = match s.mode_s {
                Some(m) => format!("{} {} {}", f(m.fusion, 8, 1), f(m.blend, 7, 1), f(m.gyro_only, 7, 1)),
                None => format!("{:>8} {:>7} {:>7}", "-", "-", "-"),
            };
            out += &format!(
                "{:<26} {:<4} {} {} {} {} {} {} {} {} {} {} {}\n",
                if i == 0 { first } else { "" },
                r.name,
                f(s.roll.max, 8, 3),
                f(s.roll.rms, 8, 3),
                f(s.pitch.max, 9, 3),
                f(s.pitch.rms, 9, 3),
                f(s.tilt_max, 8, 3),
                f(s.tilt_rms, 8, 3),
                yaw,
                f(s.scored_s, 8, 1),
                f(s.vertical_s, 7, 1),
                modes,
                mount_cell(&self.alignment)
            );
        }
        out
    }

    /// A note when the alignment window does not look like rest, or when no
    /// mount was taken because it did not.
    pub fn rest_warning(&self, name: &str) -> Option<String> {
        let a = &self.alignment;
        if a.window.refused_in_motion {
            return Some(format!("{name}: {}\n", a.window.source));
        }
        (a.window.estimate_mount && !a.looks_at_rest).then(|| {
            format!(
                "{name}: the alignment window ({}, {:.1}..{:.1} s) does not look like rest (gyro std {:.2} deg/s, accel std {:.3} g): \
                 its mount of {:.2} deg also holds whatever the unit did then\n",
                a.window.source, a.window.t0, a.window.t1, a.gyro_std_dps, a.accel_std_g, a.tilt_deg
            )
        })
    }

    /// The lines under the table that say how it was scored.
    pub fn notes(&self, reference: &str) -> String {
        let a = &self.alignment;
        let ours = &self.results[0].scores;
        format!(
            "scored against {reference} from {:.1} s; deg. Mount {:.3} deg (roll {:.3}, pitch {:.3}) from the {} ({:.3}..{:.3} s, {} samples, |f| {:.4} g); \
             yaw {}; roll/yaw not scored where |reference pitch| > {VERTICAL_LIMIT_DEG} deg ({:.1} s); no reference for {:.1} s after the skip\n",
            self.skip,
            a.tilt_deg,
            a.roll_deg,
            a.pitch_deg,
            a.window.source,
            a.window.t0,
            a.window.t1,
            a.samples,
            a.accel_g,
            if self.magnetometer { "offset removed at the end of that window" } else { "not scored (no magnetometer used)" },
            ours.vertical_s,
            ours.no_reference_s
        )
    }

    /// `report.json`: ours at the top level, the peers under `peers`.
    pub fn report(&self, input: &str, reference: &str) -> serde_json::Value {
        #[derive(Serialize)]
        struct Report<'a> {
            input: &'a str,
            reference: &'a str,
            samples: usize,
            skip_s: f64,
            offset_s: f64,
            vertical_limit_deg: f64,
            magnetometer: bool,
            alignment: &'a Alignment,
            #[serde(flatten)]
            ours: &'a Scores,
            peers: std::collections::BTreeMap<&'a str, &'a Scores>,
        }
        let peers = self.results[1..].iter().map(|r| (r.name.as_str(), &r.scores)).collect();
        serde_json::to_value(Report {
            input,
            reference,
            samples: self.samples,
            skip_s: self.skip,
            offset_s: self.offset,
            vertical_limit_deg: VERTICAL_LIMIT_DEG,
            magnetometer: self.magnetometer,
            alignment: &self.alignment,
            ours: &self.results[0].scores,
            peers,
        })
        .unwrap_or(serde_json::Value::Null)
    }

    /// Write `report.json` and `errors.svg` into `dir` (created).
    pub fn write(&self, dir: &Path, input: &str, reference: &str) -> Result<(), String> {
        crate::outfile::create_dir(dir).map_err(|e| format!("--out {}: {e}", dir.display()))?;
        let json = serde_json::to_string_pretty(&self.report(input, reference)).map_err(|e| e.to_string())?;
        let p = dir.join("report.json");
        crate::outfile::write_atomic(&p, json.as_bytes()).map_err(|e| format!("{}: {e}", p.display()))?;
        let panels: Vec<plot::Panel<'_>> =
            self.results.iter().map(|r| plot::Panel { name: &r.name, rows: &r.errors, modes: r.modes.as_deref() }).collect();
        let svg = plot::errors_svg(&panels, self.skip, self.magnetometer).map_err(|e| format!("plot: {e}"))?;
        let p = dir.join("errors.svg");
        crate::outfile::write_atomic(&p, svg.as_bytes()).map_err(|e| format!("{}: {e}", p.display()))?;
        Ok(())
    }
}

/// `evaluate --input LOG --reference REF`: the printed text.
pub fn evaluate_reference(cfg: &Config, log: &Path, reference: &Path, out: Option<&Path>, o: &RefOptions) -> Result<String, String> {
    let outs: Vec<PathBuf> = out.map(|d| vec![d.join("report.json"), d.join("errors.svg")]).unwrap_or_default();
    let outs: Vec<&Path> = outs.iter().map(PathBuf::as_path).collect();
    crate::outfile::refuse_inputs_as_outputs(&[log, reference], &outs)?;
    let name = log.display().to_string();
    if log.is_dir() {
        return Err(format!(
            "--input {name} is a directory: with --reference, --input is a candump log (a simulate directory is scored without --reference)"
        ));
    }
    if reference.is_dir() {
        return Err(format!("--reference {} is a directory: want a CSV t,roll,pitch,yaw[,valid][,rest]", reference.display()));
    }
    let file = std::fs::File::open(log).map_err(|e| format!("cannot open {name}: {e}"))?;
    let d = decode(file, cfg, &name)?;
    let file = std::fs::File::open(log).map_err(|e| format!("cannot open {name}: {e}"))?;
    let ours = run_ours_log(file, cfg, &name)?;
    let r = read_reference(reference)?;
    let ev = evaluate_with(&d.samples, ours, cfg, &r, o)?;
    let c = &d.counters;
    let mut s = format!(
        "{name}: {} samples ({} lines, {} bad; {} frames of other IDs; lost {} in {} gaps)\n",
        d.samples.len(),
        d.lines,
        d.bad_lines,
        c.unknown_id,
        c.lost,
        c.gaps
    );
    s += &table_header("log");
    let label = log.file_name().map(|n| n.to_string_lossy().to_string()).unwrap_or_default();
    s += &ev.table_rows(&label);
    s += &ev.notes(&reference.display().to_string());
    s += &ev.rest_warning(&label).unwrap_or_default();
    if let Some(dir) = out {
        ev.write(dir, &name, &reference.display().to_string())?;
        s += &format!("wrote {}/report.json, errors.svg\n", dir.display());
    }
    Ok(s)
}

/// The `evaluate` entry for real data: `Some((text, failed))` when
/// `--reference` or `--realdata` was given (`failed`: some recordings could
/// not be evaluated, the text names them), `None` to let the simulated
/// evaluation run.
pub fn dispatch(
    config: Option<&Path>,
    input: Option<&Path>,
    out: Option<&Path>,
    skip: f64,
    a: &ReferenceArgs,
) -> Result<Option<(String, Option<String>)>, String> {
    if a.power_on_at.is_some() && a.realdata.is_none() {
        return Err("--power-on-at applies to --realdata only".into());
    }
    if !a.active() {
        return Ok(None);
    }
    if !(skip.is_finite() && skip >= 0.0) {
        return Err(format!("--skip must be >= 0 s, got {skip}"));
    }
    let align_s = a.align_s.unwrap_or(RefOptions::default().align_s);
    if !(align_s.is_finite() && align_s >= 0.0) {
        return Err(format!("--align-s must be >= 0 s, got {align_s}"));
    }
    if !a.offset.is_finite() {
        return Err(format!("--offset must be a finite number of seconds, got {}", a.offset));
    }
    let cfg = match config {
        Some(p) => Config::load(p).map_err(|e| e.to_string())?,
        None => Config::default(),
    };
    cfg.adis_only("evaluate")?;
    if let Some(p) = a.power_on_at {
        if !(p.is_finite() && p >= 0.0) {
            return Err(format!("--power-on-at must be >= 0 s, got {p}"));
        }
    }
    let o = RefOptions { skip, offset: a.offset, align_s, force_align: a.align_s.is_some(), peers: a.peers, power_on_at: a.power_on_at };
    if let Some(dir) = &a.realdata {
        let label = config.map(|p| p.display().to_string()).unwrap_or_else(|| "built-in defaults".into());
        let t = realdata::run(dir, &cfg, &label, out, &o)?;
        let failed = (!t.failed.is_empty()).then(|| {
            format!("{} of the recordings under {} could not be evaluated (named under the table)", t.failed.len(), dir.display())
        });
        return Ok(Some((t.text, failed)));
    }
    let (Some(log), Some(reference)) = (input, a.reference.as_deref()) else {
        return Err("--reference needs --input LOG".into());
    };
    evaluate_reference(&cfg, log, reference, out, &o).map(|t| Some((t, None)))
}
