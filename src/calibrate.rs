//! `gyrocomp calibrate`: the thermal bias curve from thermal-chamber runs.
//!
//! The paper's procedure (sensor off, chamber set, wait; power on, wait to
//! working temperature, record; repeat at other ambients; fit, discarding the
//! fast transient after power-on) as a command. Each input is one candump log
//! of one power cycle of a static sensor.
//!
//! # What it does, exactly
//! 1. **Read.** Frames are assembled into samples exactly as the daemon does
//!    (profile, IDs and rate from the config). Suspect samples (DIAG_STAT != 0)
//!    are skipped. Samples are averaged into 1-s bins (time from the log's
//!    timestamps, relative to the first sample): mean gyro, mean specific
//!    force, mean temperature, and the within-bin standard deviation of the gyro.
//!    A log is **refused** (reported, never fitted) when it cannot be read, has
//!    no complete sample, more than 1 % of its lines unparseable, more than 1 %
//!    of its samples failing the checksum, or less than [`MIN_RUN_S`] of data.
//! 2. **Static check.** A 1-s bin is *moving* when, on any axis, its mean gyro
//!    departs from the median of the 31 bins around it by more than
//!    `max(0.05 deg/s, 8 sigma)` (sigma: the run's robust scatter of that
//!    difference), or its within-bin gyro standard deviation exceeds 3 times
//!    the run's median, or its mean gyro is more than 5 deg/s from the run's
//!    median (no thermal drift is that large), or its specific-force direction
//!    is more than 1 deg from the run's median direction. Moving bins, widened by 5 s on each side, are
//!    left out of the fit and the run is reported as **not static**.
//! 3. **Warm-up cut.** All runs are fitted jointly with the model
//!    `bias = c_run + curve(T) + A_run exp(-t / tau_run)` (curve: the polynomial
//!    of the chosen order without constant; `c_run`: the run's own turn-on
//!    bias; `A_run` per axis, `tau_run` shared by the axes of a run). For fixed
//!    `tau`s the model is linear; each `tau_run` is chosen on a geometric grid
//!    from [`TAU_MIN_S`] to [`TAU_MAX_S`] by coordinate descent (3 sweeps)
//!    minimising the noise-weighted residual sum of squares of the three axes.
//!    The transient of a run is *significant* when `|A| > 5 SE(A)` on some axis;
//!    the run's cut is then `5 tau_run` (the transient has decayed to
//!    e^-5 = 0.7 % of its amplitude), otherwise 0. Transients slower than
//!    `TAU_MAX_S` cannot be told from self-heating and are reported as such.
//! 4. **Fit.** After the cuts, `bias = c_run + sum_k a_k (T - t0)^k`, k = 1..order,
//!    by least squares on the 1-s bins, per axis. `p1 = a_1`, `p3 = a_2`,
//!    `p4 = a_3`; `p2` = the mean of the runs' `c_run` (the mean turn-on bias at
//!    t0; the runs differ by a constant, so the absolute value is only a prior).
//! 5. **Confidence intervals (95 %).** For `a_k`: `t * s * sqrt((X^T X)^-1_kk)`,
//!    `s^2` = residual variance (`RSS / (n - p)`), `t` the Student quantile
//!    (1.96 for large n), times `sqrt((1 + rho) / (1 - rho))` when the residuals'
//!    lag-1 autocorrelation `rho` is positive (AR(1) effective sample size: the
//!    1-s residuals are rarely white). For `p2`: `t * sd(c_run) / sqrt(runs)`
//!    with runs - 1 degrees of freedom (none with one run).
//! 6. **Warnings**: range covered (over the bins used) under 10 deg C, runs not
//!    static, transients at the `TAU_MAX_S` limit, counter restarts in a log.

use crate::adis::{Assembler, RawSample};
use crate::candump::LogWriter;
use crate::config::{Config, ThermalConfig};
use crate::thermal::Thermal;
use nalgebra::{DMatrix, DVector};
use std::fmt::Write as _;
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

/// Bin length, seconds.
pub const BIN_S: f64 = 1.0;
/// Shortest usable run, seconds of data.
pub const MIN_RUN_S: f64 = 120.0;
/// Largest fraction of bad lines / checksum failures before a log is refused.
pub const MAX_BAD_FRACTION: f64 = 0.01;
/// Warm-up time-constant grid, seconds.
pub const TAU_MIN_S: f64 = 5.0;
pub const TAU_MAX_S: f64 = 300.0;
/// Transient significance, in standard errors of its amplitude.
pub const TRANSIENT_Z: f64 = 5.0;
/// Cut = this many time constants.
pub const CUT_TAUS: f64 = 5.0;
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
const TAU_GRID: usize = 24;

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

/// One-second average of a static run.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Bin {
    /// Seconds since the run's first sample (bin start + half a bin).
    pub t: f64,
    pub temp: f64,
    pub gyro: [f64; 3],
    /// Within-bin standard deviation of the gyro, deg/s.
    pub gyro_sd: [f64; 3],
    pub accel: [f64; 3],
    pub n: u32,
}

/// A chamber run as read from its log.
#[derive(Clone, Debug, Default)]
pub struct Run {
    pub name: String,
    pub bins: Vec<Bin>,
    pub lines: u64,
    pub bad_lines: u64,
    pub samples: u64,
    pub suspect: u64,
    pub checksum: u64,
    pub resyncs: u64,
    /// Bins whose time went backwards.
    pub backwards: u64,
}

#[derive(Default)]
struct BinAcc {
    idx: i64,
    n: u32,
    temp: f64,
    g: [f64; 3],
    g2: [f64; 3],
    a: [f64; 3],
}

impl BinAcc {
    fn take(&mut self) -> Option<Bin> {
        if self.n == 0 {
            return None;
        }
        let n = self.n as f64;
        let mean = self.g.map(|v| v / n);
        let sd = [0, 1, 2].map(|i| if self.n > 1 { ((self.g2[i] - n * mean[i] * mean[i]) / (n - 1.0)).max(0.0).sqrt() } else { 0.0 });
        let b = Bin {
            t: (self.idx as f64 + 0.5) * BIN_S,
            temp: self.temp / n,
            gyro: mean,
            gyro_sd: sd,
            accel: self.a.map(|v| v / n),
            n: self.n,
        };
        *self = BinAcc::default();
        Some(b)
    }
}

/// Read one chamber log into 1-s bins. Never panics on bad input; refuses
/// corrupt, empty and too-short logs with an error naming the file.
pub fn read_run(path: &Path, cfg: &Config) -> Result<Run, CalError> {
    let name = path.display().to_string();
    let f = File::open(path).map_err(|e| CalError::Input { path: name.clone(), msg: format!("cannot open: {e}") })?;
    read_run_from(f, &name, cfg)
}

/// [`read_run`] from any reader; `name` names it in errors.
pub fn read_run_from<R: io::Read>(input: R, name: &str, cfg: &Config) -> Result<Run, CalError> {
    let bad = |msg: String| CalError::Input { path: name.to_string(), msg };
    let mut asm = Assembler::new(cfg.profile(), cfg.input.ids);
    let mut run = Run { name: name.to_string(), ..Default::default() };
    let mut t_first: Option<u64> = None;
    let mut acc = BinAcc::default();
    let stats = crate::replay::for_each_sample(input, &mut asm, |s| {
        if s.suspect() {
            return;
        }
        let t0 = *t_first.get_or_insert(s.t_us);
        let t = s.t_us as f64 * 1e-6 - t0 as f64 * 1e-6;
        let idx = (t / BIN_S).floor() as i64;
        if acc.n > 0 && idx != acc.idx {
            if idx < acc.idx {
                run.backwards += 1;
            }
            if let Some(b) = acc.take() {
                run.bins.push(b);
            }
        }
        acc.idx = idx;
        acc.n += 1;
        acc.temp += s.temp;
        for i in 0..3 {
            acc.g[i] += s.gyro[i];
            acc.g2[i] += s.gyro[i] * s.gyro[i];
            acc.a[i] += s.accel[i];
        }
    })
    .map_err(|(line, e)| bad(format!("read error after line {line}: {e}")))?;
    run.lines = stats.lines;
    run.bad_lines = stats.bad_lines;
    let first_bad = stats.first_bad.map(|(l, e)| (l, e.to_string()));
    if let Some(b) = acc.take() {
        run.bins.push(b);
    }
    let c = asm.counters;
    run.samples = c.samples;
    run.suspect = c.suspect;
    run.checksum = c.checksum;
    run.resyncs = c.resyncs;
    if run.lines == 0 {
        return Err(bad("empty log (no line)".into()));
    }
    if run.bad_lines as f64 > MAX_BAD_FRACTION * run.lines as f64 {
        let (l, e) = first_bad.unwrap_or((0, String::new()));
        return Err(bad(format!("corrupt: {} of {} lines unparseable (first at line {l}: {e})", run.bad_lines, run.lines)));
    }
    if c.samples == 0 {
        return Err(bad(format!("no complete sample in {} lines ({} frames; wrong [input] ids or profile?)", run.lines, c.frames)));
    }
    if run.checksum as f64 > MAX_BAD_FRACTION * (c.samples + c.checksum) as f64 {
        return Err(bad(format!("corrupt: {} of {} samples fail the checksum", run.checksum, c.samples + c.checksum)));
    }
    run.bins.sort_by(|a, b| a.t.total_cmp(&b.t));
    let dur = run.bins.len() as f64 * BIN_S;
    if dur < MIN_RUN_S {
        return Err(bad(format!("too short: {dur:.0} s of samples, need at least {MIN_RUN_S:.0} s")));
    }
    if run.bins.iter().any(|b| !b.temp.is_finite() || b.gyro.iter().any(|v| !v.is_finite())) {
        return Err(bad("non-finite values".into()));
    }
    Ok(run)
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
    /// Warm-up transient: time constant, amplitude per axis at t = 0, and
    /// whether it is significant.
    pub tau_s: f64,
    pub amplitude: [f64; 3],
    pub transient: bool,
    /// Seconds dropped at the start.
    pub cut_s: f64,
    /// Seconds of data used in the fit, and their temperature range.
    pub used_s: f64,
    pub used_temp: (f64, f64),
    /// Turn-on bias at t0 (the run's own constant), deg/s.
    pub offset: [f64; 3],
    /// Static check: seconds left out as moving, largest gyro deviation, largest tilt.
    pub moving_s: f64,
    pub max_rot_dps: f64,
    pub max_rot_at_s: f64,
    pub max_tilt_deg: f64,
    pub is_static: bool,
}

/// The fitted curve of one axis.
#[derive(Clone, Debug, Default)]
pub struct AxisFit {
    /// a_1..a_order: coefficients of (T - t0)^k, deg/s per (deg C)^k.
    pub coeffs: Vec<f64>,
    /// 95 % half-widths of `coeffs`.
    pub ci: Vec<f64>,
    /// Mean turn-on bias at t0 over the runs, and its 95 % half-width (NaN with one run).
    pub p2: f64,
    pub p2_ci: f64,
    /// Run-to-run standard deviation of the turn-on bias.
    pub turn_on_sd: f64,
    /// RMS of the residuals of the 1-s means, deg/s.
    pub rms: f64,
    /// Lag-1 autocorrelation of the residuals.
    pub rho: f64,
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

fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Static check of one run: (keep mask, report fields filled in).
fn static_check(bins: &[Bin], rep: &mut RunReport) -> Vec<bool> {
    let n = bins.len();
    let mut moving = vec![false; n];
    let mut win = Vec::with_capacity(2 * MEDIAN_HALF + 1);
    for i in 0..3 {
        let mut dev = vec![0.0; n];
        for j in 0..n {
            win.clear();
            let lo = j.saturating_sub(MEDIAN_HALF);
            let hi = (j + MEDIAN_HALF + 1).min(n);
            win.extend(bins[lo..hi].iter().map(|b| b.gyro[i]));
            dev[j] = bins[j].gyro[i] - median(&mut win);
        }
        let mut a: Vec<f64> = dev.iter().map(|d| d.abs()).collect();
        let sigma = 1.4826 * median(&mut a);
        let thr = (ROT_SIGMAS * sigma).max(ROT_MIN_DPS);
        let mut sds: Vec<f64> = bins.iter().map(|b| b.gyro_sd[i]).collect();
        let sd_med = median(&mut sds);
        let mut all: Vec<f64> = bins.iter().map(|b| b.gyro[i]).collect();
        let run_med = median(&mut all);
        for j in 0..n {
            let d = dev[j].abs();
            let sd_bad = (sd_med > 0.0 && bins[j].gyro_sd[i] > ROT_SD_RATIO * sd_med) || (bins[j].gyro[i] - run_med).abs() > ROT_ABS_DPS;
            if d > thr || sd_bad {
                moving[j] = true;
            }
            if (d > thr || sd_bad) && d > rep.max_rot_dps {
                rep.max_rot_dps = d;
                rep.max_rot_at_s = bins[j].t;
            }
        }
    }
    // tilt: angle of each bin's specific force to the run's median direction
    let unit = |a: [f64; 3]| {
        let m = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
        if m > 0.0 {
            a.map(|v| v / m)
        } else {
            [0.0; 3]
        }
    };
    let mut refd = [0.0; 3];
    for (i, r) in refd.iter_mut().enumerate() {
        let mut v: Vec<f64> = bins.iter().map(|b| unit(b.accel)[i]).collect();
        *r = median(&mut v);
    }
    let refd = unit(refd);
    for (j, b) in bins.iter().enumerate() {
        let u = unit(b.accel);
        let c = (u[0] * refd[0] + u[1] * refd[1] + u[2] * refd[2]).clamp(-1.0, 1.0);
        let ang = c.acos().to_degrees();
        rep.max_tilt_deg = rep.max_tilt_deg.max(ang);
        if ang > TILT_LIMIT_DEG {
            moving[j] = true;
        }
    }
    let mut keep = vec![true; n];
    for j in 0..n {
        if moving[j] {
            let lo = j.saturating_sub(MOVING_MARGIN);
            let hi = (j + MOVING_MARGIN + 1).min(n);
            keep[lo..hi].iter_mut().for_each(|k| *k = false);
        }
    }
    rep.moving_s = keep.iter().filter(|k| !**k).count() as f64 * BIN_S;
    rep.is_static = rep.moving_s == 0.0;
    keep
}

/// Linear least squares on accumulated normal equations, 3 right-hand sides.
struct Normal {
    xtx: DMatrix<f64>,
    xty: DMatrix<f64>,
    yty: [f64; 3],
    n: usize,
}

impl Normal {
    fn new(p: usize) -> Normal {
        Normal { xtx: DMatrix::zeros(p, p), xty: DMatrix::zeros(p, 3), yty: [0.0; 3], n: 0 }
    }
    #[inline]
    fn add(&mut self, x: &[f64], y: &[f64; 3]) {
        let p = x.len();
        for a in 0..p {
            if x[a] == 0.0 {
                continue;
            }
            for b in a..p {
                self.xtx[(a, b)] += x[a] * x[b];
            }
            for i in 0..3 {
                self.xty[(a, i)] += x[a] * y[i];
            }
        }
        for i in 0..3 {
            self.yty[i] += y[i] * y[i];
        }
        self.n += 1;
    }
    /// (beta p x 3, (X^T X)^-1, rss per axis)
    fn solve(&self) -> Option<(DMatrix<f64>, DMatrix<f64>, [f64; 3])> {
        let p = self.xtx.nrows();
        let mut m = self.xtx.clone();
        for a in 0..p {
            for b in 0..a {
                m[(a, b)] = m[(b, a)];
            }
        }
        // scale to unit diagonal for conditioning
        let d: Vec<f64> = (0..p).map(|a| if m[(a, a)] > 0.0 { 1.0 / m[(a, a)].sqrt() } else { 0.0 }).collect();
        if d.contains(&0.0) {
            return None;
        }
        let ms = DMatrix::from_fn(p, p, |a, b| m[(a, b)] * d[a] * d[b]);
        let ch = ms.cholesky()?;
        let inv_s = ch.inverse();
        // reject near-singular systems
        let cond_ok = (0..p).all(|a| inv_s[(a, a)].is_finite() && inv_s[(a, a)] < 1e12);
        if !cond_ok {
            return None;
        }
        let inv = DMatrix::from_fn(p, p, |a, b| inv_s[(a, b)] * d[a] * d[b]);
        let beta = &inv * &self.xty;
        let mut rss = [0.0; 3];
        for (i, r) in rss.iter_mut().enumerate() {
            let bcol: DVector<f64> = beta.column(i).into();
            let ycol: DVector<f64> = self.xty.column(i).into();
            // rss = y'y - 2 b'X'y + b'X'X b = y'y - b'X'y (normal equations)
            *r = (self.yty[i] - bcol.dot(&ycol)).max(0.0);
        }
        Some((beta, inv, rss))
    }
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

struct Prepared<'a> {
    bins: &'a [Bin],
    keep: Vec<bool>,
}

/// Columns: run intercepts (R), polynomial (order), then optional exponentials (R).
fn accumulate(runs: &[Prepared<'_>], order: usize, t0: f64, scale: f64, taus: Option<&[f64]>, cut: &[f64]) -> Normal {
    let r_n = runs.len();
    let p = r_n + order + if taus.is_some() { r_n } else { 0 };
    let mut ne = Normal::new(p);
    let mut x = vec![0.0; p];
    for (r, run) in runs.iter().enumerate() {
        for (b, keep) in run.bins.iter().zip(&run.keep) {
            if !keep || b.t < cut[r] {
                continue;
            }
            x.iter_mut().for_each(|v| *v = 0.0);
            x[r] = 1.0;
            let u = (b.temp - t0) / scale;
            let mut uk = 1.0;
            for k in 0..order {
                uk *= u;
                x[r_n + k] = uk;
            }
            if let Some(t) = taus {
                x[r_n + order + r] = (-b.t / t[r]).exp();
            }
            ne.add(&x, &b.gyro);
        }
    }
    ne
}

fn tau_grid() -> Vec<f64> {
    let (a, b) = (TAU_MIN_S.ln(), TAU_MAX_S.ln());
    (0..TAU_GRID).map(|k| (a + (b - a) * k as f64 / (TAU_GRID - 1) as f64).exp()).collect()
}

/// Fit the curve to chamber runs already read. `t0` is the reference temperature.
pub fn calibrate_runs(runs: &[Run], order: u8, t0: f64) -> Result<Calibration, CalError> {
    if !(1..=3).contains(&order) {
        return Err(CalError::Fit(format!("order must be 1, 2 or 3, got {order}")));
    }
    if runs.is_empty() {
        return Err(CalError::Fit("no run".into()));
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
            ..Default::default()
        };
        let (lo, hi) = run.bins.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), b| (l.min(b.temp), h.max(b.temp)));
        rep.temp = (lo, hi);
        let keep = static_check(&run.bins, &mut rep);
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
        if keep.iter().filter(|k| **k).count() < 10 {
            return Err(CalError::Fit(format!("{}: fewer than 10 static seconds", run.name)));
        }
        reports.push(rep);
        prep.push(Prepared { bins: &run.bins, keep });
    }
    let scale = prep.iter().flat_map(|p| p.bins.iter().map(|b| (b.temp - t0).abs())).fold(1.0f64, f64::max);

    // Noise per axis: robust scatter of first differences of kept bins.
    let mut w = [1.0; 3];
    for (i, wi) in w.iter_mut().enumerate() {
        let mut d: Vec<f64> = Vec::new();
        for p in &prep {
            for j in 1..p.bins.len() {
                if p.keep[j] && p.keep[j - 1] {
                    d.push((p.bins[j].gyro[i] - p.bins[j - 1].gyro[i]).abs());
                }
            }
        }
        let s = 1.4826 * median(&mut d) / std::f64::consts::SQRT_2;
        *wi = if s > 0.0 { 1.0 / (s * s) } else { 1.0 };
    }

    // Warm-up transients: coordinate descent over each run's tau.
    let grid = tau_grid();
    let zero_cut = vec![0.0; r_n];
    let objective = |taus: &[f64]| -> f64 {
        let ne = accumulate(&prep, order_u, t0, scale, Some(taus), &zero_cut);
        match ne.solve() {
            Some((_, _, rss)) => (0..3).map(|i| w[i] * rss[i]).sum(),
            None => f64::INFINITY,
        }
    };
    let mut taus = vec![grid[grid.len() / 2]; r_n];
    let mut best = objective(&taus);
    for _sweep in 0..3 {
        let mut changed = false;
        for r in 0..r_n {
            let keep_tau = taus[r];
            let mut best_tau = keep_tau;
            for &g in &grid {
                taus[r] = g;
                let j = objective(&taus);
                if j < best {
                    best = j;
                    best_tau = g;
                }
            }
            taus[r] = best_tau;
            changed |= best_tau != keep_tau;
        }
        if !changed {
            break;
        }
    }
    let ne = accumulate(&prep, order_u, t0, scale, Some(&taus), &zero_cut);
    let (beta, inv, rss) = ne
        .solve()
        .ok_or_else(|| CalError::Fit("the data do not determine the curve and the warm-up transients (too few temperatures?)".into()))?;
    let p_full = 2 * r_n + order_u;
    let dof = ne.n.saturating_sub(p_full).max(1) as f64;
    let mut cuts = vec![0.0; r_n];
    for r in 0..r_n {
        let col = r_n + order_u + r;
        let mut z = 0.0f64;
        let mut amp = [0.0; 3];
        for i in 0..3 {
            amp[i] = beta[(col, i)];
            let se = (rss[i] / dof * inv[(col, col)]).sqrt();
            if se > 0.0 {
                z = z.max(amp[i].abs() / se);
            }
        }
        let rep = &mut reports[r];
        rep.tau_s = taus[r];
        rep.amplitude = amp;
        rep.transient = z > TRANSIENT_Z;
        if rep.transient {
            cuts[r] = (CUT_TAUS * taus[r]).min(rep.duration_s);
            if taus[r] >= TAU_MAX_S * 0.999 {
                warnings.push(format!(
                    "{}: warm-up transient at least as slow as the {TAU_MAX_S:.0} s limit: it cannot be told from self-heating (or the curve needs a higher --order); cut {:.0} s may be short",
                    rep.name, cuts[r]
                ));
            }
        }
        rep.cut_s = cuts[r];
    }

    for (r, pr) in prep.iter().enumerate() {
        if !pr.bins.iter().zip(&pr.keep).any(|(b, k)| *k && b.t >= cuts[r]) {
            return Err(CalError::Fit(format!(
                "{}: nothing left after the warm-up cut of {:.0} s (run too short for its transient)",
                reports[r].name, cuts[r]
            )));
        }
    }

    // The fit after the cuts.
    let ne = accumulate(&prep, order_u, t0, scale, None, &cuts);
    let p = r_n + order_u;
    if ne.n <= p + 1 {
        return Err(CalError::Fit(format!("only {} seconds left after the warm-up cuts", ne.n)));
    }
    let (beta, inv, rss) = ne.solve().ok_or_else(|| {
        CalError::Fit(format!(
            "order {order} is not determined by these runs (temperature varies too little within the runs after the warm-up cut)"
        ))
    })?;
    let n = ne.n;
    let dof = n - p;
    // residuals: RMS and lag-1 autocorrelation per axis; used ranges
    let mut range = (f64::INFINITY, f64::NEG_INFINITY);
    let mut rho = [0.0; 3];
    let mut sum_rr = [0.0; 3];
    let mut sum_r2 = [0.0; 3];
    let mut data = Vec::with_capacity(r_n);
    for (r, pr) in prep.iter().enumerate() {
        let mut prev: Option<[f64; 3]> = None;
        let mut used = vec![false; pr.bins.len()];
        let mut ur = (f64::INFINITY, f64::NEG_INFINITY);
        for (j, b) in pr.bins.iter().enumerate() {
            if !pr.keep[j] || b.t < cuts[r] {
                prev = None;
                continue;
            }
            used[j] = true;
            ur = (ur.0.min(b.temp), ur.1.max(b.temp));
            let u = (b.temp - t0) / scale;
            let mut res = [0.0; 3];
            for i in 0..3 {
                let mut m = beta[(r, i)];
                let mut uk = 1.0;
                for k in 0..order_u {
                    uk *= u;
                    m += beta[(r_n + k, i)] * uk;
                }
                res[i] = b.gyro[i] - m;
                sum_r2[i] += res[i] * res[i];
                if let Some(pv) = prev {
                    sum_rr[i] += res[i] * pv[i];
                }
            }
            prev = Some(res);
        }
        let rep = &mut reports[r];
        rep.used_s = used.iter().filter(|u| **u).count() as f64 * BIN_S;
        rep.used_temp = ur;
        rep.offset = [0, 1, 2].map(|i| beta[(r, i)]);
        range = (range.0.min(ur.0), range.1.max(ur.1));
        data.push((pr.bins.to_vec(), used));
    }
    for i in 0..3 {
        rho[i] = if sum_r2[i] > 0.0 { sum_rr[i] / sum_r2[i] } else { 0.0 };
    }
    let tq = t975(dof);
    let axes = [0, 1, 2].map(|i| {
        let s2 = rss[i] / dof as f64;
        let infl = if rho[i] > 0.0 { ((1.0 + rho[i]) / (1.0 - rho[i]).max(1e-3)).sqrt() } else { 1.0 };
        let mut coeffs = Vec::with_capacity(order_u);
        let mut ci = Vec::with_capacity(order_u);
        for k in 0..order_u {
            let sk = scale.powi(k as i32 + 1);
            coeffs.push(beta[(r_n + k, i)] / sk);
            ci.push(tq * (s2 * inv[(r_n + k, r_n + k)]).sqrt() * infl / sk);
        }
        let offs: Vec<f64> = (0..r_n).map(|r| beta[(r, i)]).collect();
        let mean = offs.iter().sum::<f64>() / r_n as f64;
        let sd = if r_n > 1 { (offs.iter().map(|o| (o - mean) * (o - mean)).sum::<f64>() / (r_n - 1) as f64).sqrt() } else { f64::NAN };
        AxisFit {
            coeffs,
            ci,
            p2: mean,
            p2_ci: if r_n > 1 { t975(r_n - 1) * sd / (r_n as f64).sqrt() } else { f64::NAN },
            turn_on_sd: sd,
            rms: (rss[i] / n as f64).sqrt(),
            rho: rho[i],
        }
    });
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

const AXES: [&str; 3] = ["x", "y", "z"];

impl Calibration {
    /// The fitted curve as a config section (no learning settings: defaults).
    pub fn thermal_config(&self) -> ThermalConfig {
        let c = |k: usize| [0, 1, 2].map(|i| self.axes[i].coeffs.get(k).copied().unwrap_or(0.0));
        ThermalConfig {
            t0: self.t0,
            p1: c(0),
            p2: [0, 1, 2].map(|i| self.axes[i].p2),
            order: self.order,
            p3: c(1),
            p4: c(2),
            t_min: Some(self.range.0),
            t_max: Some(self.range.1),
            ..ThermalConfig::default()
        }
    }

    pub fn thermal(&self) -> Thermal {
        Thermal::new(&self.thermal_config())
    }

    /// The `[thermal]` section `--write` emits; a config file accepts it as it is.
    pub fn to_toml(&self) -> String {
        let th = self.thermal_config();
        let arr = |a: [f64; 3]| format!("[{:?}, {:?}, {:?}]", a[0], a[1], a[2]);
        let mut s = String::new();
        let _ = writeln!(s, "# gyrocomp calibrate: {} run(s), order {}, {} s of data used", self.runs.len(), self.order, self.bins_used);
        for r in &self.runs {
            let _ = writeln!(s, "#   {}: warm-up cut {:.0} s, used {:.1}..{:.1} deg C", r.name, r.cut_s, r.used_temp.0, r.used_temp.1);
        }
        let _ = writeln!(s, "# b(T) = p2 + p1 (T - t0) + p3 (T - t0)^2 + p4 (T - t0)^3, deg/s; clamped outside [t_min, t_max]");
        let _ = writeln!(s, "# p2 is the mean turn-on bias of the runs at t0 (it changes at every power-on).");
        let _ = writeln!(s, "[thermal]");
        let _ = writeln!(s, "t0 = {:?}", th.t0);
        let _ = writeln!(s, "order = {}", th.order);
        let _ = writeln!(s, "p1 = {}", arr(th.p1));
        let _ = writeln!(s, "p2 = {}", arr(th.p2));
        if self.order >= 2 {
            let _ = writeln!(s, "p3 = {}", arr(th.p3));
        }
        if self.order >= 3 {
            let _ = writeln!(s, "p4 = {}", arr(th.p4));
        }
        let _ = writeln!(s, "t_min = {:?}", self.range.0);
        let _ = writeln!(s, "t_max = {:?}", self.range.1);
        s
    }

    /// The human report.
    pub fn render(&self) -> String {
        let mut s = String::new();
        for (k, r) in self.runs.iter().enumerate() {
            let _ = writeln!(
                s,
                "run {} {}: {} samples, {:.0} s, {:.1}..{:.1} deg C{}",
                k + 1,
                r.name,
                r.samples,
                r.duration_s,
                r.temp.0,
                r.temp.1,
                if r.bad_lines > 0 { format!(", {} bad lines skipped", r.bad_lines) } else { String::new() }
            );
            if r.transient {
                let _ = writeln!(
                    s,
                    "  warm-up: tau {:.0} s, amplitude [{:.4}, {:.4}, {:.4}] deg/s -> cut {:.0} s (5 tau)",
                    r.tau_s, r.amplitude[0], r.amplitude[1], r.amplitude[2], r.cut_s
                );
            } else {
                let _ = writeln!(s, "  warm-up: no significant transient -> cut 0 s");
            }
            let _ = writeln!(
                s,
                "  used {:.0} s, {:.1}..{:.1} deg C; turn-on bias at t0 [{:.4}, {:.4}, {:.4}] deg/s; {}",
                r.used_s,
                r.used_temp.0,
                r.used_temp.1,
                r.offset[0],
                r.offset[1],
                r.offset[2],
                if r.is_static { "static".to_string() } else { format!("NOT STATIC ({:.0} s left out)", r.moving_s) }
            );
        }
        let _ = writeln!(
            s,
            "fit: order {}, t0 = {} deg C, {} s of 1-s means, {} run(s); 95 % intervals",
            self.order,
            self.t0,
            self.bins_used,
            self.runs.len()
        );
        let names = ["p1", "p3", "p4"];
        let units = ["deg/s/C", "deg/s/C^2", "deg/s/C^3"];
        for (i, a) in self.axes.iter().enumerate() {
            let mut line = format!("axis {}:", AXES[i]);
            for k in 0..a.coeffs.len() {
                line += &format!(" {} = {:.6e} +- {:.1e} {},", names[k], a.coeffs[k], a.ci[k], units[k]);
            }
            if a.p2_ci.is_finite() {
                line += &format!(" p2 = {:.4} +- {:.4} deg/s,", a.p2, a.p2_ci);
            } else {
                line += &format!(" p2 = {:.4} deg/s (one run: no interval),", a.p2);
            }
            line += &format!(
                " residual RMS {:.4} deg/s, range {:.1}..{:.1} deg C ({:.1} deg C)",
                a.rms,
                self.range.0,
                self.range.1,
                self.range.1 - self.range.0
            );
            let _ = writeln!(s, "{line}");
        }
        for w in &self.warnings {
            let _ = writeln!(s, "warning: {w}");
        }
        s
    }

    /// Write the `[thermal]` section to `path`.
    pub fn write_toml(&self, path: &Path) -> Result<(), CalError> {
        std::fs::write(path, self.to_toml()).map_err(|e| CalError::Output { path: path.display().to_string(), msg: e.to_string() })
    }

    /// SVG plots into `dir`: `bias_vs_temp_{x,y,z}.svg` (every run with its own
    /// turn-on bias replaced by the mean, the warm-up cut in grey, and the
    /// fit) and `warmup_run{k}.svg` (per run: bias minus its fitted curve vs
    /// time, per axis, with the cut). Returns the files written.
    pub fn plot(&self, dir: &Path) -> Result<Vec<PathBuf>, CalError> {
        std::fs::create_dir_all(dir).map_err(|e| CalError::Output { path: dir.display().to_string(), msg: e.to_string() })?;
        let mut out = Vec::new();
        let th = self.thermal();
        for i in 0..3 {
            let p = dir.join(format!("bias_vs_temp_{}.svg", AXES[i]));
            self.plot_axis(&p, i, &th).map_err(|msg| CalError::Output { path: p.display().to_string(), msg })?;
            out.push(p);
        }
        // the warm-up plots show the data the fit saw, also outside the calibrated range: no clamp
        let unclamped = Thermal { t_min: f64::NEG_INFINITY, t_max: f64::INFINITY, ..th.clone() };
        for k in 0..self.runs.len() {
            let p = dir.join(format!("warmup_run{}.svg", k + 1));
            self.plot_run(&p, k, &unclamped).map_err(|msg| CalError::Output { path: p.display().to_string(), msg })?;
            out.push(p);
        }
        Ok(out)
    }

    /// 10-s means of (x, y) pairs selected by `sel`, for plotting.
    fn decimate(bins: &[Bin], mask: &[bool], want: bool, f: impl Fn(&Bin) -> (f64, f64)) -> Vec<(f64, f64)> {
        let mut out = Vec::new();
        let (mut sx, mut sy, mut n) = (0.0, 0.0, 0);
        for (b, m) in bins.iter().zip(mask) {
            if *m != want {
                continue;
            }
            let (x, y) = f(b);
            sx += x;
            sy += y;
            n += 1;
            if n == 10 {
                out.push((sx / 10.0, sy / 10.0));
                (sx, sy, n) = (0.0, 0.0, 0);
            }
        }
        if n > 0 {
            out.push((sx / n as f64, sy / n as f64));
        }
        out
    }

    fn plot_axis(&self, path: &Path, i: usize, th: &Thermal) -> Result<(), String> {
        use plotters::prelude::*;
        let e = |e: &dyn std::fmt::Display| e.to_string();
        let p2 = self.axes[i].p2;
        let mut series = Vec::new();
        let (mut ylo, mut yhi) = (f64::INFINITY, f64::NEG_INFINITY);
        let (mut xlo, mut xhi) = (f64::INFINITY, f64::NEG_INFINITY);
        for (k, (bins, used)) in self.data.iter().enumerate() {
            let off = self.runs[k].offset[i] - p2;
            let used_pts = Self::decimate(bins, used, true, |b| (b.temp, b.gyro[i] - off));
            let cut_pts = Self::decimate(bins, used, false, |b| (b.temp, b.gyro[i] - off));
            for (x, y) in used_pts.iter().chain(&cut_pts) {
                xlo = xlo.min(*x);
                xhi = xhi.max(*x);
                ylo = ylo.min(*y);
                yhi = yhi.max(*y);
            }
            series.push((used_pts, cut_pts));
        }
        if !(xlo.is_finite() && xhi.is_finite() && xlo < xhi) {
            (xlo, xhi) = if xlo.is_finite() { (xlo, xlo + 1.0) } else { (0.0, 1.0) };
        }
        if !(ylo.is_finite() && yhi.is_finite() && ylo < yhi) {
            (ylo, yhi) = if ylo.is_finite() { (ylo, ylo + 0.01) } else { (-0.01, 0.01) };
        }
        let pad = 0.05 * (yhi - ylo);
        let root = SVGBackend::new(path, (900, 600)).into_drawing_area();
        root.fill(&WHITE).map_err(|x| e(&x))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(format!("gyro {} bias vs temperature (order {} fit, 10-s means)", AXES[i], self.order), ("sans-serif", 20))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(75)
            .build_cartesian_2d(xlo..xhi, (ylo - pad)..(yhi + pad))
            .map_err(|x| e(&x))?;
        chart
            .configure_mesh()
            .x_desc("temperature, deg C")
            .y_desc("bias (turn-on bias of each run -> mean), deg/s")
            .draw()
            .map_err(|x| e(&x))?;
        let grey = RGBColor(190, 190, 190);
        for (k, (used_pts, cut_pts)) in series.iter().enumerate() {
            let c = Palette99::pick(k).to_rgba();
            chart.draw_series(cut_pts.iter().map(|&(x, y)| Circle::new((x, y), 2, grey.filled()))).map_err(|x| e(&x))?;
            chart
                .draw_series(used_pts.iter().map(move |&(x, y)| Circle::new((x, y), 2, c.filled())))
                .map_err(|x| e(&x))?
                .label(format!("run {} (cut {:.0} s, grey)", k + 1, self.runs[k].cut_s))
                .legend(move |(x, y)| Circle::new((x, y), 4, c.filled()));
        }
        let (a, b) = self.range;
        let curve: Vec<(f64, f64)> = (0..=200).map(|j| a + (b - a) * j as f64 / 200.0).map(|t| (t, th.bias(t)[i])).collect();
        chart
            .draw_series(LineSeries::new(curve, BLACK.stroke_width(2)))
            .map_err(|x| e(&x))?
            .label("fit")
            .legend(|(x, y)| PathElement::new(vec![(x - 10, y), (x + 10, y)], BLACK.stroke_width(2)));
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperLeft)
            .draw()
            .map_err(|x| e(&x))?;
        root.present().map_err(|x| e(&x))?;
        Ok(())
    }

    fn plot_run(&self, path: &Path, k: usize, th: &Thermal) -> Result<(), String> {
        use plotters::prelude::*;
        let e = |e: &dyn std::fmt::Display| e.to_string();
        let (bins, _) = &self.data[k];
        let rep = &self.runs[k];
        let all = vec![true; bins.len()];
        let mut series = Vec::new();
        let (mut ylo, mut yhi) = (f64::INFINITY, f64::NEG_INFINITY);
        for i in 0..3 {
            let off = rep.offset[i] - self.axes[i].p2;
            let pts = Self::decimate(bins, &all, true, |b| (b.t, b.gyro[i] - off - th.bias(b.temp)[i]));
            for (_, y) in &pts {
                ylo = ylo.min(*y);
                yhi = yhi.max(*y);
            }
            series.push(pts);
        }
        let xhi = bins.last().map(|b| b.t).unwrap_or(1.0).max(1.0);
        if !(ylo.is_finite() && yhi.is_finite() && ylo < yhi) {
            (ylo, yhi) = if ylo.is_finite() { (ylo, ylo + 0.01) } else { (-0.01, 0.01) };
        }
        let pad = 0.05 * (yhi - ylo);
        let root = SVGBackend::new(path, (900, 500)).into_drawing_area();
        root.fill(&WHITE).map_err(|x| e(&x))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(format!("run {}: bias minus fitted curve (warm-up cut {:.0} s)", k + 1, rep.cut_s), ("sans-serif", 20))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(75)
            .build_cartesian_2d(0.0..xhi, (ylo - pad)..(yhi + pad))
            .map_err(|x| e(&x))?;
        chart.configure_mesh().x_desc("time since power-on, s").y_desc("deg/s").draw().map_err(|x| e(&x))?;
        for (i, pts) in series.into_iter().enumerate() {
            let c = Palette99::pick(i).to_rgba();
            chart
                .draw_series(LineSeries::new(pts, c))
                .map_err(|x| e(&x))?
                .label(format!("axis {}", AXES[i]))
                .legend(move |(x, y)| PathElement::new(vec![(x - 10, y), (x + 10, y)], c));
        }
        let cut = rep.cut_s;
        chart
            .draw_series(std::iter::once(PathElement::new(vec![(cut, ylo - pad), (cut, yhi + pad)], BLACK.stroke_width(2))))
            .map_err(|x| e(&x))?
            .label("cut")
            .legend(|(x, y)| PathElement::new(vec![(x - 10, y), (x + 10, y)], BLACK.stroke_width(2)));
        chart.configure_series_labels().background_style(WHITE.mix(0.85)).border_style(BLACK).draw().map_err(|x| e(&x))?;
        root.present().map_err(|x| e(&x))?;
        Ok(())
    }
}

/// A simulated thermal-chamber run with known truth, for tests and demos:
/// a static sensor (specific force (0, 0, -1) g), powered on at the chamber
/// temperature `ambient`, self-heating as `ambient + self_heat (1 - e^(-t/heat_tau_s))`,
/// gyro = `turn_on + curve(T) + warmup_amp e^(-t/warmup_tau_s) + noise`, white
/// noise of density `noise` deg/s/sqrt(Hz) (per-sample sigma `noise sqrt(rate)`),
/// quantised through the profile and written as a candump log.
#[derive(Clone, Debug)]
pub struct ChamberRun {
    pub ambient: f64,
    pub self_heat: f64,
    pub heat_tau_s: f64,
    pub duration_s: f64,
    pub turn_on: [f64; 3],
    pub warmup_amp: [f64; 3],
    pub warmup_tau_s: f64,
    pub noise: f64,
    /// Temperature sensor noise, deg C per sample.
    pub temp_noise: f64,
    /// (start s, duration s, rate deg/s): a rotation about z and back
    /// (the second half at -rate): a run that is not static.
    pub rotation: Option<(f64, f64, f64)>,
    pub seed: u64,
}

impl ChamberRun {
    pub fn new(ambient: f64, seed: u64) -> ChamberRun {
        ChamberRun {
            ambient,
            self_heat: 15.0,
            heat_tau_s: 1200.0,
            duration_s: 5400.0,
            turn_on: [0.0; 3],
            warmup_amp: [0.0; 3],
            warmup_tau_s: 120.0,
            noise: 0.0135,
            temp_noise: 0.02,
            rotation: None,
            seed,
        }
    }

    /// Temperature at `t` s after power-on.
    pub fn temp(&self, t: f64) -> f64 {
        self.ambient + self.self_heat * (1.0 - (-t / self.heat_tau_s).exp())
    }

    /// Write the run as a candump log with the profile and IDs of `cfg`.
    pub fn write<W: Write>(&self, cfg: &Config, curve: &Thermal, out: W) -> io::Result<W> {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let prof = cfg.profile();
        let ids = cfg.input.ids;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(self.seed);
        let n01 = Normal::new(0.0, 1.0).expect("unit normal");
        let sig = self.noise * prof.rate_hz.sqrt();
        let mut w = LogWriter::new(out, &cfg.can.interface);
        let n = (self.duration_s * prof.rate_hz).round() as u64;
        let t_start = 1_700_000_000_000_000u64 + self.seed % 1000 * 1_000_000;
        for k in 0..n {
            let t = k as f64 / prof.rate_hz;
            let temp = self.temp(t);
            let b = curve.bias(temp);
            let mut g = [0.0; 3];
            for i in 0..3 {
                g[i] = self.turn_on[i] + b[i] + self.warmup_amp[i] * (-t / self.warmup_tau_s).exp() + sig * n01.sample(&mut rng);
            }
            if let Some((t0, d, r)) = self.rotation {
                if t >= t0 && t < t0 + d {
                    g[2] += if t < t0 + 0.5 * d { r } else { -r };
                }
            }
            let a = [0.0, 0.0, -1.0].map(|v: f64| v + 0.002 * n01.sample(&mut rng));
            let m = [0.2, 0.0, 0.4];
            let tn = temp + self.temp_noise * n01.sample(&mut rng);
            let mut raw = RawSample::quantise(&prof, g, a, m, tn);
            raw.cnt = (k % 65536) as u16;
            let t_us = t_start + (t * 1e6).round() as u64;
            let fr = raw.encode();
            for (j, id) in ids.all().iter().enumerate() {
                w.frame(t_us + 50 * j as u64, *id, &fr[j])?;
            }
        }
        w.finish()
    }

    /// Write the run to a file.
    pub fn write_file(&self, cfg: &Config, curve: &Thermal, path: &Path) -> io::Result<()> {
        let f = BufWriter::new(File::create(path)?);
        self.write(cfg, curve, f)?;
        Ok(())
    }
}
