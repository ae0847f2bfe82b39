//! `gyrocomp calibrate`: the thermal bias curve from thermal-chamber runs.
//!
//! The paper's procedure (sensor off, chamber set, wait; power on, wait to
//! working temperature, record; repeat at other ambients; fit, discarding the
//! fast transient after power-on) as a command. Each input is one power cycle
//! of a static sensor: a candump log, or a recording in the project's CSV
//! format (`t,gx,gy,gz,ax,ay,az,mx,my,mz,temp`, gzip or not; read by the same
//! reader as `gyrocomp gap --measured`). User documentation with examples:
//! `docs/calibrate.md`.
//!
//! # What it does, exactly
//! 1. **Read** ([`read`]). Frames are assembled into samples exactly as the
//!    daemon does (profile, IDs and rate from the config). Suspect samples
//!    (DIAG_STAT != 0) are skipped. Samples are averaged into 1-s bins (time
//!    from the log's timestamps, relative to the first sample): mean gyro,
//!    mean specific force, mean temperature, the within-bin standard
//!    deviation of the gyro and the number of samples. A log is **refused**
//!    (reported, never fitted) when it cannot be read, has no complete
//!    sample, more than 1 % of its lines unparseable, more than 1 % of its
//!    samples failing the checksum, or fewer than [`MIN_FIT_BINS`] seconds of
//!    data. A CSV's channels calibration does not need (the magnetometer) may
//!    be empty on any line; its temperature may not (refused with the line).
//!    Bins follow the timestamps: a recording in **bursts** (time jumps
//!    longer than [`JUMP_S`] between them) is read as separate *stretches*
//!    of one power cycle, not as a gap in the samples: nothing is filled in,
//!    the static check stays within a stretch, and the walk (step 5) spans
//!    the jumps.
//! 2. **Short bins decide nothing.** A bin with fewer than
//!    [`MIN_BIN_FRACTION`] of the run's median samples per bin (the partial
//!    bin at either end of a log, a bin torn by a gap) is left out of the
//!    static check and of the fit: one sample is not a 1-s mean.
//! 3. **Static check** (over the full bins). A bin is *moving* when, on any
//!    axis, its mean gyro departs from the median of the 31 bins centred on
//!    it within its stretch (fewer near the stretch's ends, always symmetric, so that a smooth
//!    monotone trend such as the warm-up transient is never motion) by more than `max(0.05 deg/s, 8 sigma)` (sigma: the run's robust
//!    scatter of that difference), or its within-bin gyro standard deviation
//!    exceeds 3 times the run's median, or its mean gyro is more than 5 deg/s
//!    from the run's median, or its specific-force direction is more than
//!    1 deg from the run's median direction. Moving bins, widened by 5 s on
//!    each side, are left out of the fit and the run is reported as **not
//!    static**.
//! 4. **Self-heating.** `T(t) = T_end - rise exp(-t / tau_heat)` is fitted
//!    to the run's temperature (`tau_heat` on a geometric grid, 10 s to
//!    10^5 s; a best `tau_heat` longer than the run, or at the grid's end,
//!    is no exponential approach seen: no self-heating found). When the run self-heats (`|rise| >= MIN_RISE_C` and the curve
//!    explains at least [`MIN_HEAT_R2`] of the temperature variance), a
//!    warm-up transient of that run may be at most `tau_heat / FAST_RATIO`
//!    ([`FAST_RATIO`] = 3) slow: a transient as slow as the self-heating is
//!    the same curve in time (`curve(T(t))` is `c + k exp(-t / tau_heat)`)
//!    and cannot be told from it. Otherwise the limit is [`TAU_MAX_S`].
//! 5. **Residual model** ([`gls`]). Within a run the residual of the 1-s
//!    means is a bias random walk (variance `q` per second, from 0 at the
//!    run's first bin used: the run's constant takes its level) plus white
//!    noise (`s^2` per full bin, `s^2 n_median / n` for a bin of `n`
//!    samples). Every fit is generalised least squares under that
//!    covariance (Kalman-filter whitening), with `q / s^2` per axis by
//!    restricted maximum likelihood and `s^2` concentrated out. With a walk,
//!    the slope is learned from the temperature's *change* within each run;
//!    ordinary least squares would treat hundreds of correlated seconds as
//!    independent and print intervals several times too narrow.
//! 6. **Warm-up transients** ([`warmup`]). All runs are fitted jointly with
//!    `bias = c_run + curve(T) + A_run exp(-t / tau_run)`; each `tau_run` on a
//!    geometric grid from [`TAU_MIN_S`] to the run's limit (step 4) by
//!    coordinate descent, the walk re-estimated after each of 2 rounds. The
//!    transient is *significant* when `|A| > 5 SE(A)` on some axis (SE from
//!    the GLS). Per run:
//!    - not significant: nothing is cut;
//!    - significant and faster than the limit: the cut is `5 tau_run` (the
//!      transient has decayed to e^-5 = 0.7 %);
//!    - significant at the limit (the fit wants a transient as slow as it is
//!      allowed: a slow transient and self-heating are confounded): the cut
//!      is `5 x limit`, then the run's own slope after the cut (an extra
//!      column) is compared with the shared one: beyond [`CONSISTENT_Z`]
//!      standard errors on some axis the run is **not separable** and is
//!      left out of the fit; within, it is kept with that conservative cut;
//!    - a run with fewer than [`MIN_FIT_BINS`] bins left (after the static
//!      check and the cut) is left out.
//!
//!    Every decision is printed per run. The command fails only when no run
//!    is left; when every run was left out as not separable, they are used
//!    anyway with their cuts, with a warning that the slope may be biased.
//! 7. **Fit.** After the cuts, per axis, by GLS (step 5) on the 1-s bins,
//!    one of two level models ([`Levels`]):
//!    - **one curve**: `bias = p2 + u_run + sum_k a_k (T - t0)^k`, `u_run` a
//!      random turn-on offset of standard deviation `sigma_u` at power-on
//!      (the walk from power-on on), `sigma_u` by REML with the walk
//!      (`gls::reml_shared`). The runs' levels at their ambients then carry
//!      the slope as well as the temperature changes within them;
//!    - **each run its own**: `bias = c_run + sum_k a_k (T - t0)^k`, `p2` the
//!      mean `c_run`: only the changes within runs carry the slope.
//!
//!    One curve is never used when the runs lie in different orientations
//!    (the median specific-force directions of two runs more than
//!    [`TILT_LIMIT_DEG`] apart): their levels then differ by a g-sensitive
//!    bias the curve does not model. Otherwise one curve is used when the levels agree with it: `sigma_u = 0` is not
//!    rejected (REML drop <= [`SPREAD_TEST_CHI2`], 1 %). `p1 = a_1`,
//!    `p3 = a_2`, `p4 = a_3`.
//! 8. **Confidence intervals (95 %).** For `a_k`: `t * SE`, `SE` from the GLS
//!    (`s^2 (X~^T X~)^-1`), `t` the Student quantile with `n - p` degrees of
//!    freedom, times `sqrt((1 + rho) / (1 - rho))` when the whitened
//!    residuals' lag-1 autocorrelation `rho` is positive (what the walk model
//!    leaves unexplained). With one curve, `SE` is the larger of those at the
//!    REML `sigma_u` and at its one-sided 95 % upper bound
//!    ([`MU_UPPER_CHI2`]): a few runs say little about a spread. For `p2`:
//!    with one curve its GLS `SE` the same way; else
//!    `t * sd(c_run) / sqrt(runs)` with runs - 1 degrees of freedom (none
//!    with one run). When a run keeps a time jump (bursts), the few seconds
//!    within its stretches bound the walk across the jump only loosely: the
//!    interval is also computed at the walk's one-sided 95 % upper bound
//!    (REML profile, [`MU_UPPER_CHI2`]) and the wider one is printed.
//! 9. **Warnings**: range covered (over the bins used) under 10 deg C, runs
//!    not static, transients not separable or at the limit, runs left out,
//!    counter restarts in a log, timestamps going backwards.

pub mod chamber;
mod fit;
pub mod gls;
#[cfg(feature = "cli")]
mod plot;
pub mod read;
mod render;
mod screen;
pub mod warmup;

pub use chamber::ChamberRun;
pub use read::{read_run, read_run_from, Bin, Run};

use crate::config::Config;
pub use fit::calibrate_runs;
use std::path::{Path, PathBuf};

/// Bin length, seconds.
pub const BIN_S: f64 = 1.0;
/// A gap between two bins longer than this (s) is a time jump: the run is
/// read as separate stretches of one power cycle (the static check's local
/// median is taken within a stretch; the walk spans the jump).
pub const JUMP_S: f64 = MEDIAN_HALF as f64 * BIN_S;
/// Largest fraction of bad lines / checksum failures before a log is refused.
pub const MAX_BAD_FRACTION: f64 = 0.01;
/// A bin with fewer than this fraction of the run's median samples per bin decides nothing.
pub const MIN_BIN_FRACTION: f64 = 0.5;
/// Warm-up time-constant grid, seconds.
pub const TAU_MIN_S: f64 = 5.0;
pub const TAU_MAX_S: f64 = 300.0;
pub(crate) const TAU_GRID: usize = 24;
/// A warm-up transient must be this many times faster than the run's self-heating.
pub const FAST_RATIO: f64 = 3.0;
/// Self-heating smaller than this (deg C) sets no limit on the transient.
pub const MIN_RISE_C: f64 = 1.0;
/// ... nor one the exponential describes worse than this (R^2).
pub const MIN_HEAT_R2: f64 = 0.9;
/// Transient significance, in standard errors of its amplitude.
pub const TRANSIENT_Z: f64 = 5.0;
/// A run whose transient is at the limit is kept when its own slope after the
/// cut is within this many standard errors of the shared one.
pub const CONSISTENT_Z: f64 = 3.0;
/// Cut = this many time constants.
pub const CUT_TAUS: f64 = 5.0;
/// A run with fewer static seconds than this is refused (when read) or left
/// out (after the static check and the warm-up cut). Three 1-s bins are the
/// fewest that tell anything beyond the run's own constant and give the
/// static check's local median a window; a few seconds' weak information is
/// what the interval says, not a reason to refuse them.
pub const MIN_FIT_BINS: usize = 3;
/// Warn when the temperature range covered is below this, deg C.
pub const MIN_RANGE_C: f64 = 10.0;
/// Static check thresholds.
pub const ROT_MIN_DPS: f64 = 0.05;
pub const ROT_SIGMAS: f64 = 8.0;
pub const ROT_SD_RATIO: f64 = 3.0;
pub const ROT_ABS_DPS: f64 = 5.0;
pub const TILT_LIMIT_DEG: f64 = 1.0;
pub const MEDIAN_HALF: usize = 15;
pub const MOVING_MARGIN: usize = 5;

/// `-2 log` restricted-likelihood drop that bounds the run-to-run spread
/// from above (one-sided 95 %: the chi-square(1) 90 % point).
pub const MU_UPPER_CHI2: f64 = 2.71;

/// `-2 log` restricted-likelihood drop at which the runs' levels are taken
/// to differ (a run-to-run turn-on spread beyond the walks, at 1 %): each run
/// then gets its own constant. A stricter test would let a real spread into
/// the shared level; a looser one throws away the levels' slope information
/// on 1 in 20 good calibrations (measured in docs/calibrate.md).
pub const SPREAD_TEST_CHI2: f64 = 6.63;

/// How the intervals are computed (printed with them).
pub const INTERVAL_METHOD: &str =
    "GLS with a run-to-run turn-on spread, a bias random walk and white noise (REML), at the spread's 95 % upper bound, Student t";

#[derive(Debug, thiserror::Error)]
pub enum CalError {
    #[error("{path}: {msg}")]
    Input { path: String, msg: String },
    #[error("{} input(s) refused:\n{}", .0.len(), .0.iter().map(|e| format!("  {e}")).collect::<Vec<_>>().join("\n"))]
    Inputs(Vec<CalError>),
    /// An input error already naming its file and line (`file:line: ...`).
    #[error("{0}")]
    Located(String),
    #[error("fit: {0}")]
    Fit(String),
    #[error("cannot write {path}: {msg}")]
    Output { path: String, msg: String },
}

/// The warm-up decision for one run (step 6 of the module documentation).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Warmup {
    /// No significant transient: nothing cut.
    #[default]
    None,
    /// A significant transient faster than the limit: cut `5 tau`.
    Cut,
    /// Significant at the limit; cut `5 x limit`; the run's slope after the
    /// cut agrees with the others' (or cannot be compared: one run).
    AtLimit,
    /// Significant at the limit and the run's slope after the cut disagrees
    /// with the others': the transient cannot be told from self-heating.
    NotSeparable,
}

/// What the fit says about one run.
#[derive(Clone, Debug, Default)]
pub struct RunReport {
    pub name: String,
    pub samples: u64,
    pub bad_lines: u64,
    pub duration_s: f64,
    /// Temperature over the whole run, deg C.
    pub temp: (f64, f64),
    /// Self-heating fitted to the temperature: rise (deg C) and time
    /// constant (s); NaN when the temperature does not vary.
    pub heat_rise_c: f64,
    pub heat_tau_s: f64,
    /// The slowest transient allowed (step 4), s.
    pub tau_limit_s: f64,
    /// Warm-up transient: time constant, amplitude per axis at t = 0, its
    /// size in standard errors (largest over the axes), whether it is
    /// significant, and the decision.
    pub tau_s: f64,
    pub amplitude: [f64; 3],
    pub transient_z: f64,
    pub transient: bool,
    pub warmup: Warmup,
    /// For a transient at the limit: the run's own slope after the cut
    /// against the shared one, in standard errors (NaN otherwise).
    pub slope_z: f64,
    /// Seconds dropped at the start.
    pub cut_s: f64,
    /// Whether the run is in the fit, and why not.
    pub used: bool,
    pub left_out: Option<String>,
    /// Seconds of data used in the fit, and their temperature range.
    pub used_s: f64,
    pub used_temp: (f64, f64),
    /// Turn-on bias at t0 (the run's own constant), deg/s (NaN when left out).
    pub offset: [f64; 3],
    /// Static check: seconds left out as moving, largest gyro deviation, largest tilt.
    pub moving_s: f64,
    pub max_rot_dps: f64,
    pub max_rot_at_s: f64,
    pub max_tilt_deg: f64,
    /// Largest within-bin gyro standard deviation over the run's median,
    /// among the bins it marked moving (0 when none).
    pub max_sd_ratio: f64,
    pub is_static: bool,
    /// Bins with too few samples to count (step 2).
    pub short_bins: usize,
    /// The run's stretches (s since its first sample, start and end): more
    /// than one when it was recorded in bursts with time jumps between them.
    pub stretches: Vec<(f64, f64)>,
}

/// How the runs' turn-on levels enter one axis's fit (step 7).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Levels {
    /// One level for all runs, each run's offset random: `spread` its REML
    /// standard deviation, `upper` the upper end of its one-sided 95 %
    /// profile interval (deg/s). The levels at the different ambients carry
    /// the slope too.
    Shared { spread: f64, upper: f64 },
    /// The runs' levels differ beyond their walks (or one run): each run its
    /// own constant; `spread` the constants' standard deviation (deg/s).
    /// Only the temperature's change within the runs carries the slope.
    /// `posed`: because the runs lie in different orientations (their
    /// levels then carry a g-sensitive bias), not because they were tested.
    PerRun { spread: f64, posed: bool },
}

impl Default for Levels {
    fn default() -> Levels {
        Levels::PerRun { spread: f64::NAN, posed: false }
    }
}

/// The fitted curve of one axis.
#[derive(Clone, Debug, Default)]
pub struct AxisFit {
    /// a_1..a_order: coefficients of (T - t0)^k, deg/s per (deg C)^k.
    pub coeffs: Vec<f64>,
    /// 95 % half-widths of `coeffs`.
    pub ci: Vec<f64>,
    /// Standard errors of `coeffs` (before the Student quantile).
    pub se: Vec<f64>,
    /// Mean turn-on bias at t0 over the runs, and its 95 % half-width (NaN with one run).
    pub p2: f64,
    pub p2_ci: f64,
    /// How the runs' levels entered the fit, with the run-to-run spread of
    /// the turn-on bias.
    pub levels: Levels,
    /// RMS of the residuals of the 1-s means (walk included), deg/s.
    pub rms: f64,
    /// Lag-1 autocorrelation of the whitened residuals.
    pub rho: f64,
    /// Estimated white noise of a 1-s mean, deg/s, and bias random walk, deg/s/sqrt(s).
    pub white: f64,
    pub walk: f64,
    /// With runs read as stretches: the walk's 95 % upper bound, where the
    /// interval is also taken (NaN otherwise), deg/s/sqrt(s); negative when
    /// the data do not bound it within the grid (its end, 10 times the white
    /// noise per sqrt(s), is used).
    pub walk_upper: f64,
}

/// A calibration: the curve, per-run reports, warnings, and the data behind
/// them (for plots).
#[derive(Clone, Debug)]
pub struct Calibration {
    pub order: u8,
    pub t0: f64,
    pub axes: [AxisFit; 3],
    /// Temperature range covered by the bins used, deg C.
    pub range: (f64, f64),
    pub bins_used: usize,
    pub runs: Vec<RunReport>,
    pub warnings: Vec<String>,
    /// Per run: the bins, and for each bin whether it was used in the fit.
    pub data: Vec<(Vec<Bin>, Vec<bool>)>,
}

/// Student t 97.5 % quantile.
pub fn t975(dof: usize) -> f64 {
    const T: [f64; 30] = [
        12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160, 2.145, 2.131, 2.120, 2.110, 2.101,
        2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056, 2.052, 2.048, 2.045, 2.042,
    ];
    match dof {
        0 => f64::NAN,
        d if d <= 30 => T[d - 1],
        d => 1.96 + 2.5 / d as f64,
    }
}

/// Read the inputs (logs or CSVs) and fit. Every refused input is reported (all of them, not just the first).
pub fn calibrate_files(cfg: &Config, inputs: &[PathBuf], order: u8) -> Result<Calibration, CalError> {
    if inputs.is_empty() {
        return Err(CalError::Fit("no input".into()));
    }
    let mut runs = Vec::new();
    let mut errs = Vec::new();
    for p in inputs {
        match read_run(p, cfg) {
            Ok(r) => runs.push(r),
            Err(e) => errs.push(e),
        }
    }
    if !errs.is_empty() {
        return Err(CalError::Inputs(errs));
    }
    calibrate_runs(&runs, order, cfg.thermal.t0)
}

/// The files `--plot DIR` writes for `runs` inputs.
pub fn plot_files(dir: &Path, runs: usize) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = AXES.iter().map(|a| dir.join(format!("bias_vs_temp_{a}.svg"))).collect();
    v.extend((1..=runs).map(|k| dir.join(format!("warmup_run{k}.svg"))));
    v
}

/// `gyrocomp calibrate`: fit, print the report, write `--write` and `--plot`
/// outputs (refusing an output that is an input, the config among them, and
/// a log given twice, before anything is read).
#[cfg(feature = "cli")]
pub fn cli(
    cfg: &Config,
    config: Option<&Path>,
    inputs: &[PathBuf],
    order: u8,
    write: Option<&Path>,
    plot: Option<&Path>,
) -> Result<(), String> {
    let mut outs: Vec<PathBuf> = write.iter().map(|p| p.to_path_buf()).collect();
    if let Some(d) = plot {
        outs.extend(plot_files(d, inputs.len()));
    }
    for (k, a) in inputs.iter().enumerate() {
        for b in &inputs[k + 1..] {
            if crate::outfile::same_file(a, b) {
                return Err(format!(
                    "--input {} and {} are the same log: each chamber run is one power cycle, given once",
                    a.display(),
                    b.display()
                ));
            }
        }
    }
    let ins: Vec<&Path> = inputs.iter().map(|p| p.as_path()).chain(config).collect();
    let os: Vec<&Path> = outs.iter().map(|p| p.as_path()).collect();
    crate::outfile::refuse_inputs_as_outputs(&ins, &os)?;
    let cal = calibrate_files(cfg, inputs, order).map_err(|e| e.to_string())?;
    print!("{}", cal.render());
    if let Some(p) = write {
        cal.write_toml(p).map_err(|e| e.to_string())?;
        println!("wrote {}", p.display());
    }
    if let Some(d) = plot {
        for p in cal.plot(d).map_err(|e| e.to_string())? {
            println!("wrote {}", p.display());
        }
    }
    Ok(())
}

const AXES: [&str; 3] = ["x", "y", "z"];
