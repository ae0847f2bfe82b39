//! `gyrocomp evaluate`: replay a simulated run and score it against its truth.
//!
//! Single run (`--input DIR`, a `gyrocomp simulate` directory): replays
//! `DIR/imu.log` with the config, scores roll/pitch/yaw (max and RMS error),
//! the bias (against `DIR/bias.csv`) and the time per mode, and writes
//! `report.json` and two SVG plots into the report directory. With
//! `--ablation` the paper's three cases and the default mode run on the same
//! log and print as one table.
//!
//! Many seeds (`--seeds A..B --scenario NAME`): each seed is simulated in
//! memory (the same frames `simulate` would write) and replayed through the
//! same pipeline; the config's thermal curve is replaced by the seed's
//! calibration (the drawn slope known to +-`thermal_error`).
//!
//! Scores start at `score_from_s` (default 10 s: no estimator is asked to be
//! right at its first sample). The **oracle floor** integrates the measured
//! gyro with the deterministic sensor error known exactly (every effect of
//! `sensor.toml` evaluated on the truth; only white noise, bias random walk
//! and quantisation remain) from the true attitude at the start of the
//! manoeuvres, and reports its max roll/pitch error over the rest of the run.

use crate::adis::{InputIds, RawFrame};
use crate::config::{Config, Mode};
use crate::estimator::Estimate;
use crate::output::OutFrame;
use crate::pipeline::{Pipeline, Sink};
use crate::replay::{replay_files, ReplayFiles};
use crate::sim::model::{GyroInput, SensorModel};
use crate::sim::motion::{c_nb, wrap180};
use crate::sim::{self, read_bias, read_info, read_truth, vibration, ScenarioInfo, SimOptions, TruthRow};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Everything scoring needs about one run.
pub struct RunData {
    pub info: ScenarioInfo,
    pub model: SensorModel,
    pub truth: Vec<TruthRow>,
    /// True additive gyro bias per sample, deg/s.
    pub bias: Vec<[f64; 3]>,
    /// The run's own calibrated config (thermal curve known to +-thermal_error).
    pub unit_config: Option<Config>,
    source: Source,
}

enum Source {
    Log(PathBuf),
    Frames(Vec<[[u8; 8]; 4]>),
}

impl RunData {
    /// Load a `gyrocomp simulate` directory.
    pub fn load(dir: &Path) -> Result<RunData, String> {
        let info = read_info(&dir.join("scenario.toml"))?;
        let model = SensorModel::load(&dir.join("sensor.toml"))?;
        let truth = read_truth(&dir.join("truth.csv"))?;
        let bias: Vec<[f64; 3]> = read_bias(&dir.join("bias.csv"))?.into_iter().map(|(_, b)| b).collect();
        if bias.len() != truth.len() {
            return Err(format!("{}: bias.csv and truth.csv differ in length", dir.display()));
        }
        let unit_config = Config::load(&dir.join("config.toml")).ok();
        Ok(RunData { info, model, truth, bias, unit_config, source: Source::Log(dir.join("imu.log")) })
    }

    /// Simulate in memory.
    pub fn simulate(o: &SimOptions) -> Result<RunData, String> {
        let run = sim::prepare(o)?;
        let mut truth = Vec::new();
        let mut bias = Vec::new();
        let mut frames = Vec::new();
        for (tr, m, raw) in sim::samples(&run, o.seed) {
            truth.push(TruthRow { t: tr.t, att: [tr.roll, tr.pitch, tr.yaw], rate: tr.rate, f: tr.f, temp: tr.temp });
            bias.push(m.bias);
            frames.push(raw.encode());
        }
        let unit_config = Some(Config::parse(&run.config_toml, "simulated unit").map_err(|e| e.to_string())?);
        Ok(RunData { info: run.info, model: run.model, truth, bias, unit_config, source: Source::Frames(frames) })
    }

    /// Run the estimator over the run's input.
    pub fn estimates(&self, cfg: &Config) -> Result<(Vec<Estimate>, [f64; 3]), String> {
        let mut est = Vec::with_capacity(self.truth.len());
        match &self.source {
            Source::Log(p) => {
                let sum =
                    replay_files(cfg, &ReplayFiles { input: p, output: None, csv: None }, Some(&mut est)).map_err(|e| e.to_string())?;
                Ok((est, sum.mode_seconds))
            }
            Source::Frames(fr) => {
                struct Keep<'a>(&'a mut Vec<Estimate>);
                impl Sink for Keep<'_> {
                    fn output(&mut self, e: &Estimate, _: &[OutFrame; 4]) {
                        self.0.push(*e);
                    }
                }
                let mut pipe = Pipeline::new(cfg);
                let ids = InputIds::DEFAULT.all();
                let mut sink = Keep(&mut est);
                for (k, f) in fr.iter().enumerate() {
                    let t_us = sim::LOG_EPOCH_S * 1_000_000 + (self.truth[k].t * 1e6).round() as u64;
                    for i in 0..4 {
                        pipe.push(t_us + 120 * i as u64, RawFrame::classic(ids[i], &f[i]), &mut sink);
                    }
                }
                Ok((est, pipe.mode_seconds()))
            }
        }
    }
}

/// Scores of one estimator run.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Metrics {
    pub name: String,
    /// Max |error| of roll, pitch, yaw over the scored samples, deg.
    pub max_err: [f64; 3],
    /// RMS error of roll, pitch, yaw, deg.
    pub rms_err: [f64; 3],
    /// RMS and max |bias error| per axis, deg/s.
    pub bias_rms: [f64; 3],
    pub bias_max: [f64; 3],
    /// Seconds in fusion, blend, gyro only.
    pub mode_seconds: [f64; 3],
    pub samples: usize,
    /// Time of the largest roll or pitch error, s.
    pub t_max_tilt: f64,
}

impl Metrics {
    /// max(max roll error, max pitch error).
    pub fn tilt_max(&self) -> f64 {
        self.max_err[0].max(self.max_err[1])
    }
}

/// Errors of the estimate against the truth, per sample: (t, [roll, pitch, yaw]).
pub fn errors(data: &RunData, est: &[Estimate]) -> Vec<(f64, [f64; 3])> {
    est.iter().zip(&data.truth).map(|(e, t)| (t.t, [wrap180(e.roll - t.att[0]), e.pitch - t.att[1], wrap180(e.yaw - t.att[2])])).collect()
}

pub fn score(name: &str, data: &RunData, est: &[Estimate], mode_seconds: [f64; 3], from: f64) -> Metrics {
    let mut m = Metrics { name: name.into(), mode_seconds, ..Default::default() };
    let mut sq = [0.0; 3];
    let mut bsq = [0.0; 3];
    for ((e, t), b) in est.iter().zip(&data.truth).zip(&data.bias) {
        if t.t < from {
            continue;
        }
        let err = [wrap180(e.roll - t.att[0]), e.pitch - t.att[1], wrap180(e.yaw - t.att[2])];
        if err[0].abs().max(err[1].abs()) > m.tilt_max() {
            m.t_max_tilt = t.t;
        }
        for i in 0..3 {
            m.max_err[i] = m.max_err[i].max(err[i].abs());
            sq[i] += err[i] * err[i];
            let be = e.bias[i] - b[i];
            m.bias_max[i] = m.bias_max[i].max(be.abs());
            bsq[i] += be * be;
        }
        m.samples += 1;
    }
    let n = m.samples.max(1) as f64;
    for i in 0..3 {
        m.rms_err[i] = (sq[i] / n).sqrt();
        m.bias_rms[i] = (bsq[i] / n).sqrt();
    }
    m
}

/// The oracle floor: the measured gyro (decoded from the estimates:
/// `rate + bias`) corrected by the deterministic error model evaluated on the
/// truth, integrated from the true attitude at `start`. Returns its metrics
/// over `[start, end]` and its per-sample errors.
pub fn oracle(data: &RunData, est: &[Estimate], start: f64) -> (Metrics, Vec<(f64, [f64; 3])>) {
    let dt = 1.0 / data.info.rate_hz;
    let n = est.len().min(data.truth.len());
    let k0 = data.truth.iter().position(|t| t.t >= start).unwrap_or(0).min(n.saturating_sub(1));
    let tr = &data.truth;
    let att0 = tr[k0].att.map(f64::to_radians);
    let mut c = c_nb(att0[0], att0[1], att0[2]);
    let mut m = Metrics { name: "oracle floor".into(), ..Default::default() };
    let mut sq = [0.0; 3];
    let mut errs = Vec::with_capacity(n - k0);
    for k in k0 + 1..n {
        let t = &tr[k];
        let p = &tr[k - 1];
        let vib = vibration(&data.model.vibration, t.t);
        let x = GyroInput {
            rate: t.rate,
            rate_dot: [0, 1, 2].map(|i| (t.rate[i] - p.rate[i]) / dt),
            f: [t.f[0] + vib[0], t.f[1] + vib[1], t.f[2] + vib[2]],
            temp: t.temp,
            temp_rate: (t.temp - p.temp) / dt,
            t_on: t.t,
        };
        let det = data.model.gyro.measure(&x);
        let e = &est[k];
        let w: [f64; 3] = [0, 1, 2].map(|i| (e.rate[i] + e.bias[i] - (det[i] - t.rate[i])).to_radians() * dt);
        c = mat_mul(&c, &exp_so3(w));
        let a = euler(&c);
        let err = [wrap180(a[0] - t.att[0]), a[1] - t.att[1], wrap180(a[2] - t.att[2])];
        for i in 0..3 {
            m.max_err[i] = m.max_err[i].max(err[i].abs());
            sq[i] += err[i] * err[i];
        }
        m.samples += 1;
        errs.push((t.t, err));
    }
    let nn = m.samples.max(1) as f64;
    m.rms_err = sq.map(|s| (s / nn).sqrt());
    (m, errs)
}

fn mat_mul(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut c = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            c[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
        }
    }
    c
}

fn exp_so3(w: [f64; 3]) -> [[f64; 3]; 3] {
    let th2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
    let th = th2.sqrt();
    let (a, b) = if th < 1e-9 { (1.0 - th2 / 6.0, 0.5 - th2 / 24.0) } else { (th.sin() / th, (1.0 - th.cos()) / th2) };
    let k = [[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]];
    let k2 = mat_mul(&k, &k);
    let mut r = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            r[i][j] = if i == j { 1.0 } else { 0.0 } + a * k[i][j] + b * k2[i][j];
        }
    }
    r
}

fn euler(c: &[[f64; 3]; 3]) -> [f64; 3] {
    [c[2][1].atan2(c[2][2]).to_degrees(), (-c[2][0]).clamp(-1.0, 1.0).asin().to_degrees(), c[1][0].atan2(c[0][0]).to_degrees()]
}

/// The ablation cases: the paper's three, then the default mode.
pub fn cases(base: &Config, ablation: bool) -> Vec<(String, Config)> {
    let with = |m: Mode| {
        let mut c = base.clone();
        c.estimator.mode = m;
        c
    };
    if !ablation {
        return vec![(base.estimator.mode.name().to_string(), base.clone())];
    }
    let default = Config::default().estimator.mode;
    let mut v = vec![
        ("1 startup_average".to_string(), with(Mode::StartupAverage)),
        ("2 startup_thermal".to_string(), with(Mode::StartupThermal)),
        ("3 paper".to_string(), with(Mode::Paper)),
    ];
    if default != Mode::Paper {
        v.push((format!("default ({})", default.name()), with(default)));
    }
    v
}

pub fn table_header() -> String {
    format!(
        "{:<22} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>9} {:>7} {:>7} {:>7}\n",
        "case", "roll_max", "pitch_mx", "yaw_max", "roll_rms", "pitch_rm", "yaw_rms", "bias_rms", "fuse_s", "blend_s", "gyro_s"
    )
}

pub fn table_row(m: &Metrics) -> String {
    let brms = (m.bias_rms.iter().map(|b| b * b).sum::<f64>() / 3.0).sqrt();
    format!(
        "{:<22} {:>8.3} {:>8.3} {:>8.3} {:>8.3} {:>8.3} {:>8.3} {:>9.5} {:>7.1} {:>7.1} {:>7.1}\n",
        m.name,
        m.max_err[0],
        m.max_err[1],
        m.max_err[2],
        m.rms_err[0],
        m.rms_err[1],
        m.rms_err[2],
        brms,
        m.mode_seconds[0],
        m.mode_seconds[1],
        m.mode_seconds[2]
    )
}

#[derive(Serialize)]
struct Report<'a> {
    input: String,
    scenario: &'a ScenarioInfo,
    score_from_s: f64,
    oracle_start_s: f64,
    cases: &'a [Metrics],
    oracle: &'a Metrics,
}

/// Options of `gyrocomp evaluate`.
#[derive(Clone, Debug)]
pub struct EvalOptions {
    pub score_from: f64,
    pub ablation: bool,
    pub out: Option<PathBuf>,
}

/// Per sample: time (s) and the roll/pitch/yaw error (deg).
type ErrorRow = (f64, [f64; 3]);

/// Evaluate one simulated directory; returns the printed table.
pub fn evaluate_dir(cfg: &Config, dir: &Path, o: &EvalOptions) -> Result<String, String> {
    let data = RunData::load(dir)?;
    let mut out = String::new();
    let mut metrics = Vec::new();
    let mut first: Option<(Vec<Estimate>, Vec<ErrorRow>)> = None;
    for (name, c) in cases(cfg, o.ablation) {
        let (est, ms) = data.estimates(&c)?;
        if est.len() != data.truth.len() {
            return Err(format!("{} estimates for {} truth rows", est.len(), data.truth.len()));
        }
        metrics.push(score(&name, &data, &est, ms, o.score_from));
        if first.is_none() || name.starts_with("default") {
            let errs = errors(&data, &est);
            first = Some((est, errs));
        }
    }
    let (est, errs) = first.ok_or("no case ran")?;
    let (orc, _) = oracle(&data, &est, data.info.manoeuvre_start_s);
    out += &table_header();
    for m in &metrics {
        out += &table_row(m);
    }
    out += &table_row(&orc);
    out += &format!(
        "(scored from {:.1} s; oracle floor from {:.1} s: gyro with the deterministic error known exactly)\n",
        o.score_from, data.info.manoeuvre_start_s
    );
    if let Some(rd) = &o.out {
        std::fs::create_dir_all(rd).map_err(|e| format!("{}: {e}", rd.display()))?;
        let rep = Report {
            input: dir.display().to_string(),
            scenario: &data.info,
            score_from_s: o.score_from,
            oracle_start_s: data.info.manoeuvre_start_s,
            cases: &metrics,
            oracle: &orc,
        };
        let p = rd.join("report.json");
        std::fs::write(&p, serde_json::to_string_pretty(&rep).map_err(|e| e.to_string())?).map_err(|e| format!("{}: {e}", p.display()))?;
        plot::attitude_error(&rd.join("attitude_error.svg"), &errs, &est).map_err(|e| format!("plot: {e}"))?;
        plot::bias(&rd.join("bias.svg"), &est, &data).map_err(|e| format!("plot: {e}"))?;
        out += &format!("wrote {}/report.json, attitude_error.svg, bias.svg\n", rd.display());
    }
    Ok(out)
}

/// One seed's results.
#[derive(Clone, Debug, Serialize)]
pub struct SeedRow {
    pub seed: u64,
    /// Scored from `score_from`.
    pub cases: Vec<Metrics>,
    /// Scored over the manoeuvres only (the oracle floor's window).
    pub manoeuvres: Vec<Metrics>,
    pub oracle: Metrics,
}

/// Median of a slice (upper median for even lengths is avoided: mean of the two middle values).
pub fn median(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let mut s = v.to_vec();
    s.sort_by(|a, b| a.total_cmp(b));
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    }
}

/// Evaluate many seeds of a scenario; prints progress to stderr, returns the table.
pub fn evaluate_seeds(base: &Config, sim: &SimOptions, seeds: std::ops::RangeInclusive<u64>, o: &EvalOptions) -> Result<String, String> {
    let list: Vec<u64> = seeds.collect();
    let mut rows: Vec<SeedRow> = Vec::new();
    let case_list = cases(base, o.ablation);
    let mut out = String::new();
    let head = format!(
        "{:>5} {:<22} {:>8} {:>8} {:>8} {:>8} {:>7} | {:>8} {:>8} {:>8} | {:>8} {:>8}\n",
        "seed", "case", "roll_max", "pitch_mx", "yaw_rms", "bias_rms", "t_max", "m_roll", "m_pitch", "m_yawrms", "orc_roll", "orc_pitc"
    );
    eprint!("{head}");
    out += &head;
    for (i, &seed) in list.iter().enumerate() {
        let mut so = sim.clone();
        so.seed = seed;
        let data = RunData::simulate(&so)?;
        let mut ms = Vec::new();
        let mut man = Vec::new();
        let mut orc = None;
        for (name, c) in &case_list {
            let mut c = c.clone();
            if let Some(u) = &data.unit_config {
                c.thermal = u.thermal.clone();
                c.mounting = u.mounting.clone();
            }
            let (est, mode_s) = data.estimates(&c)?;
            if orc.is_none() {
                orc = Some(oracle(&data, &est, data.info.manoeuvre_start_s).0);
            }
            ms.push(score(name, &data, &est, mode_s, o.score_from));
            man.push(score(name, &data, &est, mode_s, data.info.manoeuvre_start_s));
        }
        let orc = orc.ok_or("no case")?;
        for (m, mm) in ms.iter().zip(&man) {
            let brms = (m.bias_rms.iter().map(|b| b * b).sum::<f64>() / 3.0).sqrt();
            let line = format!(
                "{:>5} {:<22} {:>8.3} {:>8.3} {:>8.3} {:>8.5} {:>7.1} | {:>8.3} {:>8.3} {:>8.3} | {:>8.3} {:>8.3}\n",
                seed,
                m.name,
                m.max_err[0],
                m.max_err[1],
                m.rms_err[2],
                brms,
                m.t_max_tilt,
                mm.max_err[0],
                mm.max_err[1],
                mm.rms_err[2],
                orc.max_err[0],
                orc.max_err[1]
            );
            out += &line;
            eprint!("[{}/{}] {line}", i + 1, list.len());
        }
        rows.push(SeedRow { seed, cases: ms, manoeuvres: man, oracle: orc });
    }
    let orc_med = median(&rows.iter().map(|r| r.oracle.tilt_max()).collect::<Vec<_>>());
    out += &format!(
        "\nsummary over {} seeds of {}{}{} ({} s), scored from {:.0} s; oracle floor (median of per-seed max roll/pitch) {:.3} deg\n",
        rows.len(),
        sim.scenario,
        if sim.hard { " --hard" } else { "" },
        if sim.power_on_moving { " --power-on-moving" } else { "" },
        sim.duration.unwrap_or_else(|| sim::scenario::default_duration(&sim.scenario)),
        o.score_from,
        orc_med
    );
    for (title, man) in [(format!("scored from {:.0} s", o.score_from), false), ("manoeuvres only (oracle window)".to_string(), true)] {
        out += &format!("-- {title}\n");
        out += &format!(
            "{:<22} {:>9} {:>10} {:>10} {:>9} {:>12} {:>11} {:>10}\n",
            "case", "worst_rol", "worst_pitc", "median_max", "ratio_orc", "worst_yawrms", "seeds<=2deg", "worst_seed"
        );
        for (ci, (name, _)) in case_list.iter().enumerate() {
            let pick = |r: &SeedRow| if man { r.manoeuvres[ci].clone() } else { r.cases[ci].clone() };
            let per: Vec<Metrics> = rows.iter().map(pick).collect();
            let wr = per.iter().map(|m| m.max_err[0]).fold(0.0, f64::max);
            let wp = per.iter().map(|m| m.max_err[1]).fold(0.0, f64::max);
            let med = median(&per.iter().map(|m| m.tilt_max()).collect::<Vec<_>>());
            let wy = per.iter().map(|m| m.rms_err[2]).fold(0.0, f64::max);
            let ok = per.iter().filter(|m| m.tilt_max() <= 2.0).count();
            let worst = rows.iter().zip(&per).max_by(|a, b| a.1.tilt_max().total_cmp(&b.1.tilt_max())).map(|r| r.0.seed).unwrap_or(0);
            out += &format!(
                "{:<22} {:>9.3} {:>10.3} {:>10.3} {:>9.2} {:>12.3} {:>8}/{:<2} {:>10}\n",
                name,
                wr,
                wp,
                med,
                med / orc_med,
                wy,
                ok,
                rows.len(),
                worst
            );
        }
    }
    if let Some(rd) = &o.out {
        std::fs::create_dir_all(rd).map_err(|e| format!("{}: {e}", rd.display()))?;
        let p = rd.join("report.json");
        std::fs::write(&p, serde_json::to_string_pretty(&rows).map_err(|e| e.to_string())?).map_err(|e| format!("{}: {e}", p.display()))?;
        out += &format!("wrote {}\n", p.display());
    }
    Ok(out)
}

/// SVG plots (plotters, SVG backend only: no font files needed).
mod plot {
    use super::RunData;
    use crate::estimator::Estimate;
    use plotters::prelude::*;
    use std::path::Path;

    type R = Result<(), Box<dyn std::error::Error>>;

    /// At most ~`n` points of a series.
    fn every(len: usize, n: usize) -> usize {
        (len / n).max(1)
    }

    pub fn attitude_error(path: &Path, errs: &[(f64, [f64; 3])], est: &[Estimate]) -> R {
        let root = SVGBackend::new(path, (1200, 500)).into_drawing_area();
        root.fill(&WHITE)?;
        let t1 = errs.last().map(|e| e.0).unwrap_or(1.0).max(1e-3);
        let m = errs.iter().flat_map(|e| e.1.iter()).map(|v| v.abs()).fold(0.5f64, f64::max).min(60.0) * 1.1;
        let mut ch = ChartBuilder::on(&root)
            .caption("attitude error (estimate - truth); shading: green fusion, yellow blend", ("sans-serif", 18))
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(50)
            .build_cartesian_2d(0.0..t1, -m..m)?;
        ch.configure_mesh().x_desc("t, s").y_desc("deg").draw()?;
        // mode shading, one rectangle per run of equal mode
        let mut k = 0;
        while k < est.len() {
            let mode = est[k].mode;
            let mut j = k;
            while j + 1 < est.len() && est[j + 1].mode == mode {
                j += 1;
            }
            let col = match mode {
                0 => Some(RGBColor(200, 240, 200)),
                1 => Some(RGBColor(250, 240, 190)),
                _ => None,
            };
            if let Some(col) = col {
                ch.draw_series(std::iter::once(Rectangle::new([(est[k].t, -m), (est[j].t.max(est[k].t + 0.005), m)], col.filled())))?;
            }
            k = j + 1;
        }
        let step = every(errs.len(), 4000);
        for (i, (name, col)) in [("roll", RED), ("pitch", BLUE), ("yaw", BLACK)].iter().enumerate() {
            ch.draw_series(LineSeries::new(errs.iter().step_by(step).map(|e| (e.0, e.1[i].clamp(-m, m))), col))?
                .label(*name)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], col));
        }
        ch.configure_series_labels().border_style(BLACK).background_style(WHITE).draw()?;
        root.present()?;
        Ok(())
    }

    pub fn bias(path: &Path, est: &[Estimate], data: &RunData) -> R {
        let root = SVGBackend::new(path, (1200, 500)).into_drawing_area();
        root.fill(&WHITE)?;
        let t1 = est.last().map(|e| e.t).unwrap_or(1.0).max(1e-3);
        let all = est.iter().flat_map(|e| e.bias.iter()).chain(data.bias.iter().flat_map(|b| b.iter()));
        let (lo, hi) = all.fold((f64::MAX, f64::MIN), |(l, h), v| (l.min(*v), h.max(*v)));
        let pad = ((hi - lo) * 0.05).max(0.01);
        let mut ch = ChartBuilder::on(&root)
            .caption("gyro bias: estimate (solid) vs truth (thin)", ("sans-serif", 18))
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..t1, (lo - pad)..(hi + pad))?;
        ch.configure_mesh().x_desc("t, s").y_desc("deg/s").draw()?;
        let step = every(est.len(), 4000);
        for (i, (name, col)) in [("x", RED), ("y", BLUE), ("z", BLACK)].iter().enumerate() {
            ch.draw_series(LineSeries::new(est.iter().step_by(step).map(|e| (e.t, e.bias[i])), col.stroke_width(2)))?
                .label(format!("estimate {name}"))
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], col.stroke_width(2)));
            ch.draw_series(LineSeries::new(data.truth.iter().zip(&data.bias).step_by(step).map(|(t, b)| (t.t, b[i])), col.mix(0.5)))?;
        }
        ch.configure_series_labels().border_style(BLACK).background_style(WHITE).draw()?;
        root.present()?;
        Ok(())
    }
}

/// Parse `A..B` (inclusive) or a single seed.
pub fn parse_seeds(s: &str) -> Result<std::ops::RangeInclusive<u64>, String> {
    let bad = || format!("--seeds wants A..B (inclusive) or N, got {s:?}");
    match s.split_once("..") {
        Some((a, b)) => {
            let a: u64 = a.trim().parse().map_err(|_| bad())?;
            let b: u64 = b.trim().trim_start_matches('=').parse().map_err(|_| bad())?;
            if a > b {
                return Err(bad());
            }
            Ok(a..=b)
        }
        None => {
            let a: u64 = s.trim().parse().map_err(|_| bad())?;
            Ok(a..=a)
        }
    }
}

/// The `evaluate` subcommand.
#[derive(clap::Args, Debug)]
pub struct EvaluateArgs {
    /// gyrocomp config (default: built-in defaults).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// A `gyrocomp simulate` directory.
    #[arg(long, conflicts_with = "seeds")]
    pub input: Option<PathBuf>,
    /// Report directory (report.json and SVG plots).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Also run the paper's three cases and print them with the default mode.
    #[arg(long)]
    pub ablation: bool,
    /// Simulate and evaluate these seeds, A..B inclusive (needs --scenario).
    #[arg(long)]
    pub seeds: Option<String>,
    #[arg(long, requires = "seeds")]
    pub scenario: Option<String>,
    #[arg(long, requires = "seeds")]
    pub hard: bool,
    /// The simulated runs start while the car is already driving.
    #[arg(long, requires = "seeds")]
    pub power_on_moving: bool,
    #[arg(long, requires = "seeds")]
    pub duration: Option<f64>,
    /// Relative error of the thermal slope the estimator is given (with --seeds).
    #[arg(long, default_value_t = 0.05)]
    pub thermal_error: f64,
    /// Score from this time on, s.
    #[arg(long, default_value_t = 10.0, visible_alias = "skip")]
    pub score_from: f64,
    /// Real data: --reference, --realdata, --peers, --offset, --align-s (`gyrocomp::reference`).
    #[command(flatten)]
    pub real: crate::reference::ReferenceArgs,
}

pub fn run(a: &EvaluateArgs) -> Result<(), String> {
    if let Some(text) = crate::reference::dispatch(a.config.as_deref(), a.input.as_deref(), a.out.as_deref(), a.score_from, &a.real)? {
        print!("{text}");
        return Ok(());
    }
    let cfg = match &a.config {
        Some(p) => Config::load(p).map_err(|e| e.to_string())?,
        None => Config::default(),
    };
    let o = EvalOptions { score_from: a.score_from, ablation: a.ablation, out: a.out.clone() };
    let text = match (&a.input, &a.seeds) {
        (Some(dir), None) => evaluate_dir(&cfg, dir, &o)?,
        (None, Some(s)) => {
            let sc = a.scenario.as_deref().ok_or("--seeds needs --scenario")?;
            let mut so = SimOptions::new(sc, 0);
            so.hard = a.hard;
            so.power_on_moving = a.power_on_moving;
            so.duration = a.duration;
            so.thermal_error = a.thermal_error;
            so.profile = cfg.input.profile.clone();
            evaluate_seeds(&cfg, &so, parse_seeds(s)?, &o)?
        }
        _ => return Err("evaluate needs --input DIR or --seeds A..B --scenario NAME".into()),
    };
    print!("{text}");
    Ok(())
}
