//! `gyrocomp calibrate`: the thermal bias curve from thermal-chamber runs.
//!
//! The paper's procedure (sensor off, chamber set, wait; power on, wait to
//! working temperature, record; repeat at other ambients; fit, discarding the
//! fast transient after power-on) as a command. Each input is one candump log
//! of one power cycle of a static sensor. User documentation with examples:
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
//!    samples failing the checksum, or less than [`MIN_RUN_S`] of data.
//! 2. **Short bins decide nothing.** A bin with fewer than
//!    [`MIN_BIN_FRACTION`] of the run's median samples per bin (the partial
//!    bin at either end of a log, a bin torn by a gap) is left out of the
//!    static check and of the fit: one sample is not a 1-s mean.
//! 3. **Static check** (over the full bins). A bin is *moving* when, on any
//!    axis, its mean gyro departs from the median of the 31 bins centred on
//!    it (fewer near the ends of the run, always symmetric, so that a smooth
//!    monotone trend such as the warm-up transient is never motion) by more than `max(0.05 deg/s, 8 sigma)` (sigma: the run's robust
//!    scatter of that difference), or its within-bin gyro standard deviation
//!    exceeds 3 times the run's median, or its mean gyro is more than 5 deg/s
//!    from the run's median, or its specific-force direction is more than
//!    1 deg from the run's median direction. Moving bins, widened by 5 s on
//!    each side, are left out of the fit and the run is reported as **not
//!    static**.
//! 4. **Self-heating.** `T(t) = T_end - rise exp(-t / tau_heat)` is fitted
//!    to the run's temperature (`tau_heat` on a geometric grid, 10 s to
//!    10^5 s). When the run self-heats (`|rise| >= MIN_RISE_C` and the curve
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
//!    One curve is used when the levels agree with it: `sigma_u = 0` is not
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
//!    with one run).
//! 9. **Warnings**: range covered (over the bins used) under 10 deg C, runs
//!    not static, transients not separable or at the limit, runs left out,
//!    counter restarts in a log, timestamps going backwards.

pub mod chamber;
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
use gls::{fit_axis, fit_axis_mu, mu_upper, reml_at, reml_lambda, reml_shared, Design, Rows};
use std::path::{Path, PathBuf};

/// Bin length, seconds.
pub const BIN_S: f64 = 1.0;
/// Shortest usable run, seconds of data.
pub const MIN_RUN_S: f64 = 120.0;
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
/// A run with fewer bins than this left for the fit is left out.
pub const MIN_FIT_BINS: usize = 30;
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
    #[error("{} input log(s) refused:\n{}", .0.len(), .0.iter().map(|e| format!("  {e}")).collect::<Vec<_>>().join("\n"))]
    Inputs(Vec<CalError>),
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
    pub is_static: bool,
    /// Bins with too few samples to count (step 2).
    pub short_bins: usize,
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
    PerRun { spread: f64 },
}

impl Default for Levels {
    fn default() -> Levels {
        Levels::PerRun { spread: f64::NAN }
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

/// One run's bins prepared for the fit.
struct Prepared<'a> {
    bins: &'a [Bin],
    keep: Vec<bool>,
    n_med: f64,
}

impl Prepared<'_> {
    fn rows(&self, t0: f64, scale: f64, cut: f64) -> Rows {
        let mut r = Rows::default();
        for (b, k) in self.bins.iter().zip(&self.keep) {
            if *k && b.t >= cut {
                r.t.push(b.t);
                r.u.push((b.temp - t0) / scale);
                r.y.push(b.gyro);
                r.r.push(self.n_med / b.n.max(1) as f64);
            }
        }
        r
    }
}

/// Fit the curve to chamber runs already read. `t0` is the reference temperature.
pub fn calibrate_runs(runs: &[Run], order: u8, t0: f64) -> Result<Calibration, CalError> {
    if !(1..=3).contains(&order) {
        return Err(CalError::Fit(format!("order must be 1, 2 or 3, got {order}")));
    }
    if runs.is_empty() {
        return Err(CalError::Fit("no run".into()));
    }
    if !t0.is_finite() {
        return Err(CalError::Fit(format!("t0 must be finite, got {t0}")));
    }
    let order_u = order as usize;
    let r_n = runs.len();
    let mut reports: Vec<RunReport> = Vec::with_capacity(r_n);
    let mut prep: Vec<Prepared<'_>> = Vec::with_capacity(r_n);
    let mut warnings = Vec::new();
    for run in runs {
        let mut rep = RunReport {
            name: run.name.clone(),
            samples: run.samples,
            bad_lines: run.bad_lines,
            duration_s: run.bins.len() as f64 * BIN_S,
            heat_rise_c: f64::NAN,
            heat_tau_s: f64::NAN,
            slope_z: f64::NAN,
            offset: [f64::NAN; 3],
            used: true,
            ..Default::default()
        };
        let (lo, hi) = run.bins.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), b| (l.min(b.temp), h.max(b.temp)));
        rep.temp = (lo, hi);
        let full = screen::full_bins(&run.bins);
        let keep = screen::static_check(&run.bins, &full, &mut rep);
        if !rep.is_static {
            warnings.push(format!(
                "{}: not static: rotation detected (largest |gyro - local median| {:.3} deg/s at t = {:.0} s, largest tilt {:.2} deg); {:.0} s left out of the fit",
                run.name, rep.max_rot_dps, rep.max_rot_at_s, rep.max_tilt_deg, rep.moving_s
            ));
        }
        if run.resyncs > 0 {
            warnings.push(format!("{}: {} sample-counter restart(s): is this one power cycle?", run.name, run.resyncs));
        }
        if run.backwards > 0 {
            warnings.push(format!("{}: timestamps go backwards {} time(s)", run.name, run.backwards));
        }
        let (kt, ktemp): (Vec<f64>, Vec<f64>) = run.bins.iter().zip(&keep).filter(|(_, k)| **k).map(|(b, _)| (b.t, b.temp)).unzip();
        let heat = warmup::fit_heating(&kt, &ktemp);
        if let Some(h) = &heat {
            rep.heat_rise_c = h.rise;
            rep.heat_tau_s = h.tau_s;
        }
        rep.tau_limit_s = warmup::tau_limit(heat.as_ref());
        if kt.len() < MIN_FIT_BINS {
            rep.used = false;
            rep.left_out = Some(format!("only {} static seconds (need {MIN_FIT_BINS})", kt.len()));
        }
        let mut ns: Vec<f64> = run.bins.iter().map(|b| b.n as f64).collect();
        let n_med = screen::median(&mut ns).max(1.0);
        reports.push(rep);
        prep.push(Prepared { bins: &run.bins, keep, n_med });
    }
    let cand: Vec<usize> = (0..r_n).filter(|&r| reports[r].used).collect();
    if cand.is_empty() {
        return Err(no_run_left(&reports));
    }
    let scale = cand
        .iter()
        .flat_map(|&r| prep[r].bins.iter().zip(&prep[r].keep).filter(|(_, k)| **k).map(|(b, _)| (b.temp - t0).abs()))
        .fold(1.0f64, f64::max);

    // Step 6: the transients, on everything that is static.
    let rows_all: Vec<Rows> = cand.iter().map(|&r| prep[r].rows(t0, scale, f64::NEG_INFINITY)).collect();
    let limits: Vec<f64> = cand.iter().map(|&r| reports[r].tau_limit_s).collect();
    let tr = warmup::find(&rows_all, order_u, &limits);
    let mut cuts = vec![0.0; r_n];
    let mut lams = [0.0; 3];
    match &tr {
        Some(tr) => {
            lams = tr.lams;
            for (c, &r) in cand.iter().enumerate() {
                let rep = &mut reports[r];
                rep.tau_s = tr.tau[c];
                rep.amplitude = tr.amp[c];
                rep.transient_z = tr.z[c];
                rep.transient = tr.z[c] > TRANSIENT_Z;
                rep.warmup = match (rep.transient, tr.at_limit[c]) {
                    (false, _) => Warmup::None,
                    (true, false) => Warmup::Cut,
                    (true, true) => Warmup::AtLimit,
                };
                if rep.transient {
                    cuts[r] = CUT_TAUS * tr.tau[c];
                }
                rep.cut_s = cuts[r];
            }
        }
        None => warnings.push(
            "the warm-up transients could not be fitted (the runs do not determine the curve and a transient each): nothing cut".into(),
        ),
    }
    for &r in &cand {
        let left = prep[r].rows(t0, scale, cuts[r]).len();
        if left < MIN_FIT_BINS {
            let rep = &mut reports[r];
            rep.used = false;
            rep.left_out = Some(format!("{left} s left after the warm-up cut of {:.0} s (need {MIN_FIT_BINS})", cuts[r]));
            if rep.warmup == Warmup::AtLimit {
                rep.warmup = Warmup::NotSeparable;
            }
        }
    }
    // Transients at the limit: does the run's slope after the cut agree with the others'?
    let at_limit: Vec<usize> = (0..r_n).filter(|&r| reports[r].used && reports[r].warmup == Warmup::AtLimit).collect();
    let mut not_separable = Vec::new();
    for &r in &at_limit {
        let inn: Vec<usize> = (0..r_n).filter(|&q| reports[q].used).collect();
        let rows: Vec<Rows> = inn.iter().map(|&q| prep[q].rows(t0, scale, cuts[q])).collect();
        let pos = inn.iter().position(|&q| q == r).expect("run is in");
        if let Some(z) = warmup::own_slope_z(&rows, order_u, pos, lams) {
            reports[r].slope_z = z;
            if z > CONSISTENT_Z {
                not_separable.push(r);
            }
        }
    }
    for &r in &not_separable {
        let rep = &mut reports[r];
        rep.warmup = Warmup::NotSeparable;
        rep.used = false;
        rep.left_out = Some(format!(
            "its warm-up transient cannot be told from its self-heating (slope after the cut {:.1} SE from the other runs')",
            rep.slope_z
        ));
    }
    if !(0..r_n).any(|r| reports[r].used) {
        // every run left out: use those left out only as not separable, with their cuts
        let back: Vec<usize> = not_separable.clone();
        if back.is_empty() {
            return Err(no_run_left(&reports));
        }
        for &r in &back {
            reports[r].used = true;
            reports[r].left_out = None;
        }
        warnings.push(format!(
            "no run separates its warm-up transient from its self-heating: {} used anyway with the cuts shown; the slope may be biased (record longer, or from a cold start with a faster transient)",
            back.iter().map(|&r| reports[r].name.as_str()).collect::<Vec<_>>().join(", ")
        ));
    }
    for rep in &reports {
        match rep.warmup {
            Warmup::NotSeparable => warnings.push(format!(
                "{}: warm-up transient not separable from the self-heating (the fit wants the slowest transient allowed, tau_heat / {FAST_RATIO:.0} = {:.0} s){}",
                rep.name,
                rep.tau_limit_s,
                if rep.used { "".to_string() } else { ": left out of the fit; calibrated from the other runs".to_string() }
            )),
            Warmup::AtLimit => warnings.push(format!(
                "{}: warm-up transient at the {:.0} s limit (tau_heat / {FAST_RATIO:.0}, or the {TAU_MAX_S:.0} s grid end): cut {:.0} s, conservatively{}",
                rep.name,
                rep.tau_limit_s,
                rep.cut_s,
                if rep.slope_z.is_finite() {
                    format!("; its slope after the cut agrees with the other runs' ({:.1} SE)", rep.slope_z)
                } else {
                    "; cannot be checked against other runs".to_string()
                }
            )),
            _ => {}
        }
        if !rep.used && rep.warmup != Warmup::NotSeparable {
            if let Some(why) = &rep.left_out {
                warnings.push(format!("{}: left out of the fit: {why}", rep.name));
            }
        }
    }

    // Step 7: the fit after the cuts.
    let used: Vec<usize> = (0..r_n).filter(|&r| reports[r].used).collect();
    let rows: Vec<Rows> = used.iter().map(|&r| prep[r].rows(t0, scale, cuts[r])).collect();
    let d = Design::new(&rows, order_u);
    let lams = [0, 1, 2].map(|i| reml_lambda(&d, i));
    let not_determined = || {
        CalError::Fit(format!(
            "order {order} is not determined by these runs (temperature varies too little within the runs after the warm-up cut)"
        ))
    };
    // each run's own constant: what each run read at t0 (the per-run report)
    let own = (0..3).map(|i| fit_axis(&d, i, lams[i])).collect::<Option<Vec<_>>>().ok_or_else(not_determined)?;
    let u_n = used.len();
    let n = own[0].n;
    let ds = Design::shared(&rows, order_u);
    let mut axes = Vec::with_capacity(3);
    for i in 0..3 {
        let own = &own[i];
        // the curve: one level for all runs, each run's turn-on offset random
        // (step 7), unless the runs' levels say they differ
        let (lam, mu) = reml_shared(&ds, i, lams[i]);
        let shared_fit = fit_axis_mu(&ds, i, lam, mu).filter(|g| u_n > 1 && reml_at(&ds, i, lam, 0.0) - g.reml() <= SPREAD_TEST_CHI2);
        let axis = if let Some(g) = shared_fit {
            // the interval at the largest spread the runs allow, if wider
            let up = mu_upper(&ds, i, lam, mu, g.reml(), MU_UPPER_CHI2);
            let wide = fit_axis_mu(&ds, i, lam, up).ok_or_else(not_determined)?;
            let s2 = g.s2();
            let cols: Vec<usize> = (1..=order_u).map(|k| ds.poly_col(k)).collect();
            let mut a = axis_fit(&g, Some(&wide), &cols, scale);
            a.p2 = g.beta[0];
            a.p2_ci = t975(g.n - g.p) * g.se(0).max(wide.se(0)) * inflation(g.rho);
            a.levels = Levels::Shared { spread: (mu * s2).sqrt(), upper: (up * s2).sqrt() };
            a.walk = (lam * s2).sqrt();
            a
        } else {
            let cols: Vec<usize> = (1..=order_u).map(|k| d.poly_col(k)).collect();
            let mut a = axis_fit(own, None, &cols, scale);
            let offs: Vec<f64> = (0..u_n).map(|q| own.beta[q]).collect();
            let mean = offs.iter().sum::<f64>() / u_n as f64;
            let sd = if u_n > 1 { (offs.iter().map(|o| (o - mean) * (o - mean)).sum::<f64>() / (u_n - 1) as f64).sqrt() } else { f64::NAN };
            a.p2 = mean;
            a.p2_ci = if u_n > 1 { t975(u_n - 1) * sd / (u_n as f64).sqrt() } else { f64::NAN };
            a.levels = Levels::PerRun { spread: sd };
            a.walk = (lams[i] * own.s2()).sqrt();
            a
        };
        axes.push(AxisFit { rms: (own.raw_ss / n as f64).sqrt(), ..axis });
    }
    let axes: [AxisFit; 3] = axes.try_into().expect("three axes");
    let mut range = (f64::INFINITY, f64::NEG_INFINITY);
    let mut data = Vec::with_capacity(r_n);
    for r in 0..r_n {
        let pr = &prep[r];
        let rep = &mut reports[r];
        let mask: Vec<bool> = pr.bins.iter().zip(&pr.keep).map(|(b, k)| rep.used && *k && b.t >= cuts[r]).collect();
        let mut ur = (f64::INFINITY, f64::NEG_INFINITY);
        for (b, _) in pr.bins.iter().zip(&mask).filter(|(_, m)| **m) {
            ur = (ur.0.min(b.temp), ur.1.max(b.temp));
        }
        rep.used_s = mask.iter().filter(|m| **m).count() as f64 * BIN_S;
        if rep.used {
            rep.used_temp = ur;
            let q = used.iter().position(|&x| x == r).expect("used run");
            rep.offset = [0, 1, 2].map(|i| own[i].beta[q]);
            range = (range.0.min(ur.0), range.1.max(ur.1));
        } else {
            rep.used_temp = (f64::NAN, f64::NAN);
        }
        data.push((pr.bins.to_vec(), mask));
    }
    if range.1 - range.0 < MIN_RANGE_C {
        warnings.push(format!(
            "temperature range covered is {:.1} deg C ({:.1}..{:.1}), under {MIN_RANGE_C:.0} deg C: the curve is poorly determined and is clamped outside it",
            range.1 - range.0,
            range.0,
            range.1
        ));
    }
    Ok(Calibration { order, t0, axes, range, bins_used: n, runs: reports, warnings, data })
}

/// `sqrt((1 + rho) / (1 - rho))` for a positive lag-1 autocorrelation of
/// the whitened residuals (what the walk model leaves unexplained), else 1.
fn inflation(rho: f64) -> f64 {
    if rho > 0.0 {
        ((1.0 + rho) / (1.0 - rho).max(1e-3)).sqrt()
    } else {
        1.0
    }
}

/// The curve's coefficients (columns `cols` of `g`, scaled back by
/// `scale^k`) with 95 % intervals: Student t times the standard error,
/// the larger of `g`'s and `wide`'s, times the autocorrelation inflation.
fn axis_fit(g: &gls::AxisGls, wide: Option<&gls::AxisGls>, cols: &[usize], scale: f64) -> AxisFit {
    let infl = inflation(g.rho);
    let tq = t975(g.n - g.p);
    let mut a = AxisFit { rho: g.rho, white: g.s2().sqrt(), ..AxisFit::default() };
    for (k, &c) in cols.iter().enumerate() {
        let sk = scale.powi(k as i32 + 1);
        let se = g.se(c).max(wide.map_or(0.0, |w| w.se(c)));
        a.coeffs.push(g.beta[c] / sk);
        a.se.push(se * infl / sk);
        a.ci.push(tq * se * infl / sk);
    }
    a
}

fn no_run_left(reports: &[RunReport]) -> CalError {
    CalError::Fit(format!(
        "no run left to fit:\n{}",
        reports.iter().map(|r| format!("  {}: {}", r.name, r.left_out.as_deref().unwrap_or("?"))).collect::<Vec<_>>().join("\n")
    ))
}

/// Read the logs and fit. Every refused log is reported (all of them, not just the first).
pub fn calibrate_files(cfg: &Config, inputs: &[PathBuf], order: u8) -> Result<Calibration, CalError> {
    if inputs.is_empty() {
        return Err(CalError::Fit("no input log".into()));
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
