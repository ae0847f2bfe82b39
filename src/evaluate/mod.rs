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
//! calibration (the drawn slope known to +-`thermal_error`). With `--peers`
//! VQF and Fusion run on each seed's decoded samples beside ours.
//!
//! Scores start at `score_from_s` (default 10 s: no estimator is asked to be
//! right at its first sample). The **oracle floor** integrates the measured
//! gyro with the deterministic sensor error known exactly (every effect of
//! `sensor.toml` evaluated on the truth; only white noise, bias random walk
//! and quantisation remain) from the true attitude at the start of the
//! manoeuvres, and reports its max roll/pitch error over the rest of the run.
//!
//! The steps, one file each: `data.rs` the run (loaded or simulated) and the
//! replay, `metrics.rs` the scores and the oracle floor, `table.rs` the text
//! tables, `dir.rs` one directory, `seeds.rs` many seeds, `plot.rs` the SVG
//! plots; here the options, the ablation cases, the report writing and the
//! subcommand.

pub mod ablate;
mod data;
mod dir;
mod metrics;
mod plot;
mod seeds;
mod table;

pub use data::RunData;
pub use dir::{evaluate_dir, evaluate_dir_with};
pub use metrics::{
    errors, oracle, peer_track, rest_window, score, score_attitude, still_moving_s, yaw_offset, Metrics, Window, MOVING_MPS,
};
pub use seeds::{evaluate_seeds, evaluate_seeds_with, median, run_peers, PeerTrack, SeedRow, PEERS};
pub use table::{run_row, run_table, Table};

use crate::config::{Config, Mode};
use crate::sim::SimOptions;
use std::path::{Path, PathBuf};

/// `--thermal-error` when not given: each axis's slope off by up to +-5 %.
pub const DEFAULT_THERMAL_ERROR: f64 = 0.05;

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

/// Options of `gyrocomp evaluate`.
#[derive(Clone, Debug)]
pub struct EvalOptions {
    pub score_from: f64,
    pub ablation: bool,
    pub out: Option<PathBuf>,
    /// With many seeds: VQF and Fusion beside ours ([`seeds::run_peers`]).
    pub peers: bool,
    /// With --input DIR: the recording of the default case with the truth
    /// beside it ([`dir::write_mcap`]).
    pub mcap: Option<PathBuf>,
}

/// Write the report files: every destination checked first (not an input,
/// not a directory), then each written through a temporary file.
fn write_reports(dir: &Path, inputs: &[&Path], files: &[(&str, Vec<u8>)]) -> Result<(), String> {
    crate::outfile::create_dir(dir).map_err(|e| format!("--out {}: {e}", dir.display()))?;
    let dests: Vec<PathBuf> = files.iter().map(|(n, _)| dir.join(n)).collect();
    let refs: Vec<&Path> = dests.iter().map(PathBuf::as_path).collect();
    crate::outfile::refuse_inputs_as_outputs(inputs, &refs)?;
    if let Some(d) = dests.iter().find(|d| d.is_dir()) {
        return Err(format!("{} is a directory: the report is a file of that name", d.display()));
    }
    for (d, (_, bytes)) in dests.iter().zip(files) {
        crate::outfile::write_atomic(d, bytes).map_err(|e| format!("{}: {e}", d.display()))?;
    }
    Ok(())
}

/// The most seeds one `evaluate --seeds` run takes: each is a whole
/// simulated run (seconds to minutes each), and the per-seed rows are kept
/// for the summary.
pub const MAX_SEEDS: u64 = 10_000;

/// Parse `A..B` (inclusive) or a single seed; at most [`MAX_SEEDS`] seeds.
pub fn parse_seeds(s: &str) -> Result<std::ops::RangeInclusive<u64>, String> {
    let bad = || format!("--seeds wants A..B (inclusive) or N, got {s:?}");
    match s.split_once("..") {
        Some((a, b)) => {
            let a: u64 = a.trim().parse().map_err(|_| bad())?;
            let b: u64 = b.trim().trim_start_matches('=').parse().map_err(|_| bad())?;
            if a > b {
                return Err(bad());
            }
            let n = (b - a) as u128 + 1;
            if n > MAX_SEEDS as u128 {
                return Err(format!(
                    "--seeds {s}: {n} seeds, over the limit of {MAX_SEEDS} (each seed is a whole simulated run); split the range"
                ));
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
#[command(group(clap::ArgGroup::new("what").required(true).args(["input", "seeds", "realdata"])))]
pub struct EvaluateArgs {
    /// gyrocomp config (TOML). Default: with --input DIR the run's own
    /// DIR/config.toml (the unit as simulated: its part, mounting, thermal
    /// calibration), else the built-in defaults. With --seeds its [thermal]
    /// section is replaced by each simulated unit's calibration.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// A `gyrocomp simulate` directory to replay and score, or with --reference a
    /// candump log. One of --input, --seeds or --realdata is required.
    #[arg(long, value_name = "DIR", conflicts_with = "seeds")]
    pub input: Option<PathBuf>,
    /// Report directory: report.json (and with --input attitude_error.svg,
    /// bias.svg). Default: no report files.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Also run the paper's three cases (startup_average, startup_thermal,
    /// paper) and print them with the default mode. Off by default.
    #[arg(long)]
    pub ablation: bool,
    /// Simulate (in memory) and evaluate these seeds: A..B inclusive, or one
    /// seed N; at most 10000 seeds. Required unless --input is given; needs
    /// --scenario (with --ablate: every vehicle family unless --scenario).
    #[arg(long, value_name = "A..B")]
    pub seeds: Option<String>,
    /// With --seeds: the scenario to simulate (static, chamber, paper,
    /// vehicle, urban, smooth, crawl). Required with --seeds.
    #[arg(long, value_name = "NAME", requires = "seeds")]
    pub scenario: Option<String>,
    /// With --seeds: vehicle, add emergency brakes and swerves of 0.65-0.8 g;
    /// smooth, 800 s of hard driving after 200 s of the smooth drive. Off by
    /// default.
    #[arg(long, requires = "seeds")]
    pub hard: bool,
    /// With --seeds: the simulated runs start while the car is already
    /// driving (urban, vehicle, paper, smooth, crawl). Default: a parked start.
    #[arg(long, requires = "seeds")]
    pub power_on_moving: bool,
    /// With --seeds: a TOML file overriding any subset of the ranges the
    /// sensor errors are drawn from, as `simulate --ranges` takes it (e.g.
    /// `turn_on_bias = 0.5`, deg/s: a unit whose turn-on bias is within
    /// VQF's bias clip of 2 deg/s). Default: the scenario's ranges.
    #[arg(long, value_name = "FILE", requires = "seeds")]
    pub ranges: Option<std::path::PathBuf>,
    /// With --seeds (urban): the estimator uses the car's wheel speeds
    /// ([speed] of each run's config). Default: IMU only.
    #[arg(long, requires = "seeds")]
    pub speed: bool,
    /// With --seeds: duration of each run, s (> 0). Default: the scenario's
    /// (static 300, chamber 1800, paper and vehicle 800, urban 400, smooth and
    /// crawl 600, smooth --hard 1000; the manoeuvres of paper and vehicle start
    /// at 350). At most 4 million samples a run (held in memory, about
    /// 1.6 GB): 19531 s of adis16448, 4882 s of adis16405, 2000 s of
    /// adis16465-1; longer is refused up front with its estimate.
    #[arg(long, value_name = "S", requires = "seeds", allow_negative_numbers = true, value_parser = crate::sim::cli::positive_seconds)]
    pub duration: Option<f64>,
    /// With --seeds: relative error of the thermal slope the estimator is
    /// given, a fraction 0..1 (0.05 = each axis off by up to +-5 %).
    /// Default: 0.05.
    #[arg(long, value_name = "FRACTION", allow_negative_numbers = true, value_parser = crate::sim::cli::fraction)]
    pub thermal_error: Option<f64>,
    /// Score from this time on, s after power-on (>= 0); the manoeuvres-only
    /// scores start where the manoeuvres do. Alias: --skip.
    #[arg(
        long,
        visible_alias = "skip",
        value_name = "S",
        allow_negative_numbers = true,
        value_parser = crate::sim::cli::non_negative_seconds,
        default_value_t = 10.0
    )]
    pub score_from: f64,
    /// Switch each named situation rule of the default filter off alone
    /// (`[mekf] ablate`) and print the figures next to the default's: with
    /// --seeds the worst roll/pitch of the vehicle families (smooth, crawl,
    /// urban, each parked and powered on moving, smooth --hard, vehicle
    /// --hard; or only --scenario's), with --realdata the roll/pitch RMS of
    /// every recording. Off by default.
    #[arg(long, conflicts_with_all = ["input", "ablation", "peers"])]
    pub ablate: bool,
    /// With --ablate: only these rules, a comma list of names (the rules
    /// and what each does: docs/estimator.md). Default: every rule.
    #[arg(long, value_name = "LIST", requires = "ablate")]
    pub rules: Option<String>,
    /// With --input DIR (a simulate directory): write an MCAP recording here
    /// (docs/mcap.md): replay's channels for the default case, and the
    /// simulated truth beside them on /truth/tf and /truth/estimate; with
    /// --peers VQF's attitude on /vqf/tf and /vqf/estimate. Default: no
    /// recording.
    #[arg(long, value_name = "OUT.mcap", requires = "input", conflicts_with_all = ["seeds", "ablate"])]
    pub mcap: Option<PathBuf>,
    /// Real data: --reference, --realdata, --peers, --offset, --align-s (`gyrocomp::reference`).
    #[command(flatten)]
    pub real: crate::reference::ReferenceArgs,
}

/// `--ablate`: the rules switched off one at a time ([`ablate::run`]).
fn run_ablate(a: &EvaluateArgs) -> Result<(), String> {
    let cfg = match &a.config {
        Some(p) => Config::load(p).map_err(|e| e.to_string())?,
        None => Config::default(),
    };
    cfg.adis_only("evaluate")?;
    if a.real.reference.is_some() || a.real.power_on_at.is_some() {
        return Err("--ablate runs on --seeds (the simulated families) or --realdata DIR".into());
    }
    let families = match a.scenario.as_deref() {
        Some(sc) => {
            crate::sim::cli::check_scenario(sc, a.hard, a.duration, &cfg.input.profile)?;
            vec![ablate::Family::new(sc, a.hard, a.power_on_moving)]
        }
        None => ablate::families(),
    };
    let run = ablate::AblateRun {
        seeds: a.seeds.as_deref().map(parse_seeds).transpose()?,
        families,
        duration: a.duration,
        realdata: a.real.realdata.as_deref(),
        rules: ablate::parse_rules(a.rules.as_deref())?,
        score_from: a.score_from,
    };
    print!("{}", ablate::run(&cfg, &run)?);
    Ok(())
}

pub fn run(a: &EvaluateArgs) -> Result<(), String> {
    if a.ablate {
        return run_ablate(a);
    }
    if a.mcap.is_some() && (a.real.reference.is_some() || a.real.realdata.is_some()) {
        return Err("--mcap writes the recording of a simulate directory (--input DIR); not yet with --reference or --realdata".into());
    }
    if let Some((text, failed)) =
        crate::reference::dispatch(a.config.as_deref(), a.input.as_deref(), a.out.as_deref(), a.score_from, &a.real)?
    {
        print!("{text}");
        return failed.map_or(Ok(()), Err);
    }
    if a.real.align_s.is_some() || a.real.offset != 0.0 {
        return Err("--align-s and --offset apply to a measured reference only (--reference or --realdata)".into());
    }
    if a.seeds.is_none() {
        // options of the simulated seeds or of a measured reference mean
        // nothing to a simulate directory: refused, never ignored
        let given = [
            (a.thermal_error.is_some(), "--thermal-error (each seed's calibration; a directory has its own config.toml)"),
            (
                a.real.peers && a.mcap.is_none(),
                "--peers (VQF and Fusion with --seeds, VQF with --reference or --realdata, VQF in the --mcap recording)",
            ),
            (a.scenario.is_some(), "--scenario (with --seeds; a directory's scenario is its scenario.toml)"),
            (a.hard, "--hard (with --seeds)"),
            (a.power_on_moving, "--power-on-moving (with --seeds)"),
            (a.speed, "--speed (with --seeds)"),
            (a.duration.is_some(), "--duration (with --seeds)"),
            (a.ranges.is_some(), "--ranges (with --seeds)"),
        ];
        if let Some((_, what)) = given.iter().find(|g| g.0) {
            return Err(format!("--input DIR replays a simulate directory: {what} does not apply to it"));
        }
    }
    // a simulated run is decoded and scored with its own unit's config
    // unless told otherwise (another part's scales and rate decode garbage)
    let run_config = a.input.as_ref().map(|d| d.join("config.toml")).filter(|p| a.seeds.is_none() && p.is_file());
    let cfg = match a.config.as_ref().or(run_config.as_ref()) {
        Some(p) => Config::load(p).map_err(|e| e.to_string())?,
        None => Config::default(),
    };
    cfg.adis_only("evaluate")?;
    let mut note = String::new();
    if let (Some(dir), None, None) = (&a.input, &a.config, &run_config) {
        let p = cfg.profile();
        note = format!(
            "note: {} has no config.toml and no --config was given: the built-in defaults are used (profile {}, {} Hz, mode {}, thermal curve {}, mounting {:?})\n",
            dir.display(),
            p.name,
            p.rate_hz,
            cfg.estimator.mode.name(),
            if cfg.thermal.enabled { "on" } else { "off" },
            cfg.mounting.rotation
        );
        eprint!("{note}");
    }
    let o = EvalOptions { score_from: a.score_from, ablation: a.ablation, out: a.out.clone(), peers: a.real.peers, mcap: a.mcap.clone() };
    let text = match (&a.input, &a.seeds) {
        (Some(dir), None) => evaluate_dir_with(&cfg, dir, &o, a.config.as_deref())?,
        (None, Some(s)) => {
            let sc = a.scenario.as_deref().ok_or("--seeds needs --scenario")?;
            crate::sim::cli::check_scenario(sc, a.hard, a.duration, &cfg.input.profile)?;
            crate::sim::cli::check_size(sc, a.hard, a.duration, &cfg.input.profile, crate::sim::cli::Budget::Memory)?;
            let mut so = SimOptions::new(sc, 0);
            so.hard = a.hard;
            so.power_on_moving = a.power_on_moving;
            so.speed = a.speed;
            so.duration = a.duration;
            so.thermal_error = a.thermal_error.unwrap_or(DEFAULT_THERMAL_ERROR);
            if let Some(p) = &a.ranges {
                let text = crate::textfile::read(p).map_err(|e| format!("--ranges {}: {e}", p.display()))?;
                // refused here, with the file's name, not once per seed
                crate::sim::scenario::Ranges::with_overrides(sc, &text).map_err(|e| format!("--ranges {}: {e}", p.display()))?;
                so.ranges = Some(text);
            }
            so.profile = cfg.input.profile.clone();
            evaluate_seeds_with(&cfg, &so, parse_seeds(s)?, &o, a.config.as_deref())?
        }
        _ => return Err("evaluate needs --input DIR or --seeds A..B --scenario NAME".into()),
    };
    print!("{note}{text}");
    Ok(())
}
