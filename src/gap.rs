//! `gyrocomp gap`: what a gyro sensor model is missing, with evidence.
//!
//! Given measured data (a candump log in the ADIS contract, or a CSV
//! `t,gx,gy,gz,ax,ay,az,mx,my,mz,temp`), the truth (`truth.csv` as
//! `gyrocomp simulate` writes it; `temp` optional when the measured data has
//! it) and a base model (`sensor.toml` shape; effects listed without their
//! table are fitted), the workflow repeats:
//!
//! 1. **Simulate** the measured gyro from the truth with the current model:
//!    effects with coefficients go through the simulator's own
//!    [`GyroModel::measure`] (one physics for both); free coefficients are
//!    fitted by least squares on regressors that are the same formulas
//!    (every effect is linear in its coefficients given the truth, except
//!    the warm-up time constant, found by a 1-D search). The fit runs on
//!    0.1-s means (exact for linear terms: the mean of `c x` is `c` times the
//!    mean of `x`), which keeps the rate and rate-derivative content that
//!    `scale_factor`, `misalignment` and `time_delay` need.
//! 2. **Localise** the residual `measured - simulated` per axis: its
//!    correlation with, and quantile-binned means against, time,
//!    temperature, dT/dt, specific force, rate and rate derivative.
//! 3. **Name** the effect: every element of the vocabulary not yet in the
//!    model (per axis; per matrix element for `g_sensitivity` and
//!    `misalignment`; one shared delay for `time_delay`) is fitted jointly
//!    with the current model and ranked by ΔBIC. The best is accepted only
//!    when ALL of the following hold (the significance rule):
//!    - ΔBIC = N ln(SSE0/SSE1) − k ln N > [`BIC_MIN`] (strong evidence);
//!    - two-fold cross-validation on alternating 20-s blocks (shorter in a
//!      short run, at least 8 blocks; fit on one set of blocks, predict the
//!      other, both ways) lowers the held-out SSE;
//!    - what it explains (RMS over 1-s means of the change of the simulated
//!      gyro) is at least [`SIZE_MIN`] × the white-noise level the model
//!      predicts for 1-s means (noise density × sqrt(rate/2) combined with
//!      LSB²/12, over sqrt(samples per second));
//!    - Occam for nested candidates: `turn_on_bias` is the limit of
//!      `warmup_transient` (time constant to infinity); when their simulated
//!      gyros differ by less than that size threshold, the constant is taken
//!      and the pair is not an ambiguity;
//!    - it is identifiable: its regressor is not nearly collinear with the
//!      current model's (R² < [`COLLINEAR_R2`]) and the data could detect
//!      it at a plausible size (plausible / standard error ≥ 3);
//!    - no other candidate with nearly the same evidence (ΔBIC within
//!      [`BIC_MIN`]) has a regressor correlated with it beyond
//!      [`AMBIGUOUS_CORR`] after the current model is projected out;
//!      nor a correlated one (|ρ| > 0.5) within [`BIC_TIE`] of it;
//!      otherwise both are reported as *not separable with this data*,
//!      neither is added, and nothing more is added on that axis (a
//!      weaker explanation of the same residual would be a guess).
//! 4. **Add** it with its fitted coefficient, re-fit, record the residual RMS
//!    (of 1-s means, per axis) before and after.
//!
//! The loop stops when no candidate passes (at most [`MAX_FINDINGS`]); the
//! report then compares the final residual RMS with the predicted
//! white-noise level (`final_localisation[].ratio_to_floor`). `clean` is true
//! when nothing was found and no pair was left ambiguous. `not_separable`
//! lists the candidates the data cannot judge at all on the base model's
//! residual (no excitation, e.g. `scale_factor` on a bench at rest, or
//! collinear, e.g. `g_sensitivity` to the constant gravity column against a
//! turn-on bias). A fitted negative `time_delay` (measured leads truth) is not
//! accepted. Findings report the coefficients of the final joint fit (also in
//! `model.toml`); `evidence.coefficient_when_found` keeps the value at the
//! time of the finding. Residual RMS values are over 1-s means of the
//! residual (seconds with under half the nominal samples are left out).
//!
//! Outputs in DIR: `report.json`, `model.toml` (the extended model with all
//! coefficients, accepted by `gyrocomp simulate --model` and `gyrocomp gap
//! --model`), `report.md`, `residual.svg` (before/after) and one
//! `finding_N_<effect>_<axis>.svg` per finding (the localisation that named it).

use crate::adis::{builtin_profile, Assembler, InputIds, Profile};
use crate::sim::model::{
    Effect, GSensitivity, GyroInput, GyroModel, Misalignment, ScaleFactor, SensorModel, ThermalLinear, ThermalQuadratic, ThermalRate,
    TimeDelay, TurnOnBias, WarmupTransient,
};
use nalgebra::{DMatrix, DVector};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Width of the fit bins, s.
pub const FIT_BIN_S: f64 = 0.1;
/// ΔBIC a candidate needs (strong evidence).
pub const BIC_MIN: f64 = 10.0;
/// Minimum explained RMS (1-s means) in units of the predicted white-noise level of 1-s means.
pub const SIZE_MIN: f64 = 0.5;
/// R² of a candidate regressor on the current model's above which it is not separable.
pub const COLLINEAR_R2: f64 = 0.995;
/// Partial correlation between two close candidates above which they are not separable.
pub const AMBIGUOUS_CORR: f64 = 0.95;
/// ΔBIC difference below which two correlated (|ρ| > 0.5) candidates are a tie
/// ("not worth more than a bare mention", Kass & Raftery).
pub const BIC_TIE: f64 = 2.0;
/// Length of the alternating cross-validation blocks, s.
pub const CV_BLOCK_S: f64 = 20.0;
/// At most this many effects are added.
pub const MAX_FINDINGS: usize = 12;
const AX: [&str; 3] = ["x", "y", "z"];

/// One measured sample.
#[derive(Clone, Copy, Debug, Default)]
pub struct MeasRow {
    pub t: f64,
    pub gyro: [f64; 3],
    pub temp: f64,
}

/// One truth row (`temp` NaN when the file has no temp column).
#[derive(Clone, Copy, Debug, Default)]
pub struct TruthIn {
    pub t: f64,
    pub rate: [f64; 3],
    pub f: [f64; 3],
    pub temp: f64,
}

/// Read measured data: a candump log (ADIS contract, `profile`) or the CSV.
/// Times of a log are relative to its first sample (the log's first sample
/// is the truth's first row); a CSV's times are used as they are, unless
/// they start further from the truth's start than half its length (epoch
/// seconds, say): then they too are taken relative to their first row.
pub fn read_measured(path: &Path, profile: &Profile) -> Result<Vec<MeasRow>, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{}: cannot read: {e}", path.display()))?;
    let first = bytes.split(|b| *b == b'\n').map(|l| l.trim_ascii()).find(|l| !l.is_empty());
    match first {
        None => Err(format!("{}: empty file", path.display())),
        Some(l) if l.starts_with(b"t,") || l.starts_with(b"t ,") => read_meas_csv(path, &bytes),
        Some(_) => read_meas_log(path, &bytes, profile),
    }
}

fn parse_row(l: &str, n: usize, path: &Path, no: usize) -> Result<Vec<f64>, String> {
    let v: Vec<&str> = l.split(',').collect();
    if v.len() != n {
        return Err(format!("{}:{no}: want {n} columns, got {}", path.display(), v.len()));
    }
    v.iter()
        .map(|s| {
            let x: f64 = s.trim().parse().map_err(|_| format!("{}:{no}: bad number {:?}", path.display(), s.trim()))?;
            if x.is_finite() {
                Ok(x)
            } else {
                Err(format!("{}:{no}: not a finite number {:?}", path.display(), s.trim()))
            }
        })
        .collect()
}

const MEAS_HEADER: &str = "t,gx,gy,gz,ax,ay,az,mx,my,mz,temp";

fn read_meas_csv(path: &Path, bytes: &[u8]) -> Result<Vec<MeasRow>, String> {
    let text = std::str::from_utf8(bytes).map_err(|_| format!("{}: not UTF-8 text", path.display()))?;
    let mut out = Vec::new();
    let mut header = false;
    for (i, l) in text.lines().enumerate() {
        let no = i + 1;
        if l.trim().is_empty() {
            continue;
        }
        if !header {
            let h: String = l.chars().filter(|c| !c.is_whitespace()).collect();
            if h != MEAS_HEADER {
                return Err(format!("{}:{no}: header must be {MEAS_HEADER}", path.display()));
            }
            header = true;
            continue;
        }
        let v = parse_row(l, 11, path, no)?;
        if let Some(p) = out.last().map(|r: &MeasRow| r.t) {
            if v[0] <= p {
                return Err(format!("{}:{no}: time {} is not after the previous row's {p}", path.display(), v[0]));
            }
        }
        out.push(MeasRow { t: v[0], gyro: [v[1], v[2], v[3]], temp: v[10] });
    }
    if out.is_empty() {
        return Err(format!("{}: no data rows", path.display()));
    }
    Ok(out)
}

fn read_meas_log(path: &Path, bytes: &[u8], profile: &Profile) -> Result<Vec<MeasRow>, String> {
    let mut asm = Assembler::new(profile.clone(), InputIds::DEFAULT);
    let mut out = Vec::new();
    let mut t_first: Option<u64> = None;
    let stats = crate::replay::for_each_sample(bytes, &mut asm, |s| {
        if s.suspect() {
            return;
        }
        let t0 = *t_first.get_or_insert(s.t_us);
        if s.t_us >= t0 {
            out.push(MeasRow { t: (s.t_us - t0) as f64 * 1e-6, gyro: s.gyro, temp: s.temp });
        }
    })
    .map_err(|(line, e)| format!("{}: read error after line {line}: {e}", path.display()))?;
    let (lines, bad) = (stats.lines, stats.bad_lines);
    let first_bad = stats.first_bad.map(|(l, e)| (l, e.to_string()));
    if let Some((no, e)) = &first_bad {
        if bad * 100 > lines || out.is_empty() {
            return Err(format!(
                "{}:{no}: {e} ({bad} of {lines} lines malformed; not a candump log in the ADIS contract or a CSV with header {MEAS_HEADER})",
                path.display()
            ));
        }
    }
    if out.is_empty() {
        return Err(format!("{}: no complete ADIS sample in {lines} lines", path.display()));
    }
    Ok(out)
}

/// Read `truth.csv` (`t,roll,pitch,yaw,p,q,r,fx,fy,fz[,temp]`).
pub fn read_truth(path: &Path) -> Result<(Vec<TruthIn>, bool), String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: cannot read: {e}", path.display()))?;
    let mut it = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty());
    let (_, h) = it.next().ok_or_else(|| format!("{}: empty file", path.display()))?;
    let h: String = h.chars().filter(|c| !c.is_whitespace()).collect();
    let base = "t,roll,pitch,yaw,p,q,r,fx,fy,fz";
    let has_temp = if h == format!("{base},temp") {
        true
    } else if h == base {
        false
    } else {
        return Err(format!("{}:1: header must be {base},temp (temp optional)", path.display()));
    };
    let n = if has_temp { 11 } else { 10 };
    let mut out: Vec<TruthIn> = Vec::new();
    for (i, l) in it {
        let no = i + 1;
        let v = parse_row(l, n, path, no)?;
        if let Some(p) = out.last() {
            if v[0] <= p.t {
                return Err(format!("{}:{no}: time {} is not after the previous row's {}", path.display(), v[0], p.t));
            }
        }
        out.push(TruthIn { t: v[0], rate: [v[4], v[5], v[6]], f: [v[7], v[8], v[9]], temp: if has_temp { v[10] } else { f64::NAN } });
    }
    if out.len() < 2 {
        return Err(format!("{}: fewer than 2 data rows", path.display()));
    }
    Ok((out, has_temp))
}

/// The base model: parsed like `sensor.toml`, except that an effect listed
/// without its table is free (fitted). Errors name the file and the key.
pub fn load_base(path: &Path) -> Result<SensorModel, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: cannot read: {e}", path.display()))?;
    parse_base(&text).map_err(|e| format!("{}: {e}", path.display()))
}

/// [`load_base`] from text.
pub fn parse_base(text: &str) -> Result<SensorModel, String> {
    let m: SensorModel = toml::from_str(text).map_err(|e| e.to_string())?;
    let mut fixed = m.clone();
    fixed.gyro.effects = fixed_effects(&m.gyro);
    // duplicates are an error even for free effects
    for (i, e) in m.gyro.effects.iter().enumerate() {
        if m.gyro.effects[..i].contains(e) {
            return Err(format!("gyro.effects: {} is listed twice", e.name()));
        }
    }
    fixed.validate().map_err(|(k, msg)| format!("{k}: {msg}"))?;
    Ok(m)
}

fn has_table(g: &GyroModel, e: Effect) -> bool {
    match e {
        Effect::TurnOnBias => g.turn_on_bias.is_some(),
        Effect::ThermalLinear => g.thermal_linear.is_some(),
        Effect::ThermalQuadratic => g.thermal_quadratic.is_some(),
        Effect::ThermalRate => g.thermal_rate.is_some(),
        Effect::WarmupTransient => g.warmup_transient.is_some(),
        Effect::GSensitivity => g.g_sensitivity.is_some(),
        Effect::ScaleFactor => g.scale_factor.is_some(),
        Effect::Misalignment => g.misalignment.is_some(),
        Effect::TimeDelay => g.time_delay.is_some(),
    }
}

fn fixed_effects(g: &GyroModel) -> Vec<Effect> {
    g.effects.iter().copied().filter(|e| has_table(g, *e)).collect()
}

/// One free coefficient of the model: an effect, its gyro axis (3 = all
/// axes, `time_delay`) and, for matrix effects, the column.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Term {
    pub effect: Effect,
    pub axis: usize,
    pub col: usize,
}

impl Term {
    pub fn label(&self) -> String {
        match self.effect {
            Effect::GSensitivity => format!("g_sensitivity g[{}][{}]", AX[self.axis], AX[self.col]),
            Effect::Misalignment => format!("misalignment m[{}][{}]", AX[self.axis], AX[self.col]),
            Effect::TimeDelay => "time_delay".into(),
            e => format!("{} {}", e.name(), AX[self.axis]),
        }
    }

    fn unit(&self) -> &'static str {
        unit(self.effect)
    }

    /// The regressor's home variable (what the localisation plot shows).
    fn variable(&self) -> usize {
        match self.effect {
            Effect::TurnOnBias | Effect::WarmupTransient => V_T,
            Effect::ThermalLinear | Effect::ThermalQuadratic => V_TEMP,
            Effect::ThermalRate => V_DTEMP,
            Effect::GSensitivity => V_F + self.col,
            Effect::ScaleFactor => V_W + self.axis,
            Effect::Misalignment => V_W + self.col,
            Effect::TimeDelay => V_WD + self.axis.min(2),
        }
    }

    /// A plausible (upper-end) size for an ADIS-class part: the data must be
    /// able to detect the term at this size (3 standard errors) to judge it.
    fn plausible(&self) -> f64 {
        match self.effect {
            Effect::TurnOnBias => 0.5,
            Effect::ThermalLinear => 0.02,
            Effect::ThermalQuadratic => 1e-4,
            Effect::ThermalRate => 1.0,
            Effect::WarmupTransient => 0.1,
            Effect::GSensitivity => 0.02,
            Effect::ScaleFactor => 0.005,
            Effect::Misalignment => 0.005,
            Effect::TimeDelay => 0.005,
        }
    }
}

/// Unit of an effect's coefficient.
pub fn unit(e: Effect) -> &'static str {
    match e {
        Effect::TurnOnBias | Effect::WarmupTransient => "deg/s",
        Effect::ThermalLinear => "deg/s/degC",
        Effect::ThermalQuadratic => "deg/s/degC^2",
        Effect::ThermalRate => "deg/s/(degC/s)",
        Effect::GSensitivity => "deg/s/g",
        Effect::ScaleFactor => "1",
        Effect::Misalignment => "rad",
        Effect::TimeDelay => "s",
    }
}

fn all_terms(e: Effect) -> Vec<Term> {
    match e {
        Effect::TimeDelay => vec![Term { effect: e, axis: 3, col: 0 }],
        Effect::GSensitivity => (0..9).map(|k| Term { effect: e, axis: k / 3, col: k % 3 }).collect(),
        Effect::Misalignment => (0..9).filter(|k| k / 3 != k % 3).map(|k| Term { effect: e, axis: k / 3, col: k % 3 }).collect(),
        _ => (0..3).map(|a| Term { effect: e, axis: a, col: 0 }).collect(),
    }
}

// Localisation variables.
const V_T: usize = 0;
const V_TEMP: usize = 1;
const V_DTEMP: usize = 2;
const V_F: usize = 3;
const V_W: usize = 6;
const V_WD: usize = 9;
const NVAR: usize = 12;
const VAR_NAMES: [&str; NVAR] =
    ["time", "temperature", "dT/dt", "f_x", "f_y", "f_z", "rate_x", "rate_y", "rate_z", "rate_dot_x", "rate_dot_y", "rate_dot_z"];
const VAR_UNITS: [&str; NVAR] = ["s", "degC", "degC/s", "g", "g", "g", "deg/s", "deg/s", "deg/s", "deg/s^2", "deg/s^2", "deg/s^2"];

/// Mean of the samples in one fit bin.
#[derive(Clone, Copy, Debug, Default)]
struct Bin {
    n: f64,
    t: f64,
    /// measured minus the fixed part of the model (which includes the truth rate)
    y: [f64; 3],
    w: [f64; 3],
    wd: [f64; 3],
    f: [f64; 3],
    temp: f64,
    temp2: f64,
    dtemp: f64,
    /// weight of the bin in the fits: its sample count over the mean count
    wt: f64,
    /// 1-s group and cross-validation fold
    sec: usize,
    fold: usize,
}

impl Bin {
    fn var(&self, v: usize) -> f64 {
        match v {
            V_T => self.t,
            V_TEMP => self.temp,
            V_DTEMP => self.dtemp,
            3..=5 => self.f[v - V_F],
            6..=8 => self.w[v - V_W],
            _ => self.wd[v - V_WD],
        }
    }
}

/// Everything the fits need: the bins and the reference temperatures.
struct Data {
    bins: Vec<Bin>,
    /// nominal sample rate, Hz
    rate_hz: f64,
    t0_lin: f64,
    t0_quad: f64,
    nsec: usize,
}

impl Data {
    /// Value of a term's regressor in the row of `axis` of bin `b`.
    #[inline]
    fn x(&self, term: &Term, tau: f64, b: &Bin, axis: usize) -> f64 {
        if term.effect == Effect::TimeDelay {
            return -b.wd[axis];
        }
        if term.axis != axis {
            return 0.0;
        }
        match term.effect {
            Effect::TurnOnBias => 1.0,
            Effect::ThermalLinear => b.temp - self.t0_lin,
            Effect::ThermalQuadratic => b.temp2 - 2.0 * self.t0_quad * b.temp + self.t0_quad * self.t0_quad,
            Effect::ThermalRate => b.dtemp,
            Effect::WarmupTransient => (-b.t.max(0.0) / tau).exp(),
            Effect::GSensitivity => b.f[term.col],
            Effect::ScaleFactor => b.w[axis],
            Effect::Misalignment => b.w[term.col],
            Effect::TimeDelay => unreachable!(),
        }
    }
}

/// Normal equations of one fit, per cross-validation fold.
struct Normal {
    p: usize,
    xtx: [DMatrix<f64>; 2],
    xty: [DVector<f64>; 2],
    yty: [f64; 2],
    rows: [f64; 2],
    /// rows per axis (for ΔBIC over the affected axes) and y'y per axis
    yty_axis: [f64; 3],
}

/// A fitted model: terms, their coefficients and the fit statistics.
#[derive(Clone, Debug)]
struct Fit {
    terms: Vec<Term>,
    tau: f64,
    beta: DVector<f64>,
    /// inverse of X'X (all data)
    inv: DMatrix<f64>,
    sse: f64,
    sse_axis: [f64; 3],
    /// held-out SSE (fit on one fold, predict the other, summed)
    sse_cv: f64,
    rows: f64,
}

fn solve(a: &DMatrix<f64>, b: &DVector<f64>) -> Option<(DVector<f64>, DMatrix<f64>)> {
    let p = a.nrows();
    if p == 0 {
        return Some((DVector::zeros(0), DMatrix::zeros(0, 0)));
    }
    // scale to unit diagonal for conditioning
    let d: Vec<f64> = (0..p).map(|i| if a[(i, i)] > 0.0 { 1.0 / a[(i, i)].sqrt() } else { 0.0 }).collect();
    if d.iter().any(|x| *x == 0.0 || !x.is_finite()) {
        return None;
    }
    let s = DMatrix::from_fn(p, p, |i, j| a[(i, j)] * d[i] * d[j]);
    let ch = s.cholesky()?;
    let inv_s = ch.inverse();
    // guard against numerically singular systems
    if (0..p).any(|i| !(inv_s[(i, i)].is_finite()) || inv_s[(i, i)] > 1e10) {
        return None;
    }
    let inv = DMatrix::from_fn(p, p, |i, j| inv_s[(i, j)] * d[i] * d[j]);
    let beta = &inv * b;
    Some((beta, inv))
}

impl Data {
    fn normal(&self, terms: &[Term], tau: f64) -> Normal {
        let p = terms.len();
        let mut xtx = [DMatrix::zeros(p, p), DMatrix::zeros(p, p)];
        let mut xty = [DVector::zeros(p), DVector::zeros(p)];
        let mut yty = [0.0; 2];
        let mut rows = [0.0; 2];
        let mut yty_axis = [0.0; 3];
        let mut x = vec![0.0; p];
        // terms touching each axis
        let idx: Vec<Vec<usize>> = (0..3).map(|a| (0..p).filter(|&k| terms[k].axis == a || terms[k].axis == 3).collect()).collect();
        for b in &self.bins {
            let fo = b.fold;
            for a in 0..3 {
                let y = b.y[a];
                let w = b.wt;
                yty[fo] += w * y * y;
                yty_axis[a] += w * y * y;
                rows[fo] += 1.0;
                let id = &idx[a];
                for &k in id {
                    x[k] = self.x(&terms[k], tau, b, a);
                }
                let m = &mut xtx[fo];
                for (ii, &i) in id.iter().enumerate() {
                    xty[fo][i] += w * x[i] * y;
                    let wx = w * x[i];
                    for &j in &id[ii..] {
                        m[(i, j)] += wx * x[j];
                    }
                }
            }
        }
        for m in xtx.iter_mut() {
            for i in 0..p {
                for j in 0..i {
                    m[(i, j)] = m[(j, i)];
                }
            }
        }
        Normal { p, xtx, xty, yty, rows, yty_axis }
    }

    /// Fit `terms` (warm-up time constant `tau`). None when singular.
    fn fit(&self, terms: &[Term], tau: f64) -> Option<Fit> {
        let n = self.normal(terms, tau);
        let a = &n.xtx[0] + &n.xtx[1];
        let b = &n.xty[0] + &n.xty[1];
        let (beta, inv) = solve(&a, &b)?;
        let sse_of = |m: &DMatrix<f64>, v: &DVector<f64>, yy: f64, be: &DVector<f64>| {
            if n.p == 0 {
                yy
            } else {
                (yy - 2.0 * be.dot(v) + (m * be).dot(be)).max(0.0)
            }
        };
        let sse = sse_of(&a, &b, n.yty[0] + n.yty[1], &beta);
        let mut sse_cv = 0.0;
        for k in 0..2 {
            let o = 1 - k;
            let be = match solve(&n.xtx[k], &n.xty[k]) {
                Some((be, _)) => be,
                None => beta.clone(),
            };
            sse_cv += sse_of(&n.xtx[o], &n.xty[o], n.yty[o], &be);
        }
        let mut sse_axis = [0.0; 3];
        // per-axis SSE: y'y_a - 2 beta_a' X_a'y + ... computed directly from residuals
        if n.p == 0 {
            sse_axis = n.yty_axis;
        } else {
            for bn in &self.bins {
                for (a, s) in sse_axis.iter_mut().enumerate() {
                    let mut r = bn.y[a];
                    for (k, t) in terms.iter().enumerate() {
                        if t.axis == a || t.axis == 3 {
                            r -= beta[k] * self.x(t, tau, bn, a);
                        }
                    }
                    *s += bn.wt * r * r;
                }
            }
        }
        Some(Fit { terms: terms.to_vec(), tau, beta, inv, sse, sse_axis, sse_cv, rows: n.rows[0] + n.rows[1] })
    }

    /// The model prediction of a fit on bin `b`, axis `a`.
    fn pred(&self, fit: &Fit, b: &Bin, a: usize) -> f64 {
        let mut s = 0.0;
        for (k, t) in fit.terms.iter().enumerate() {
            if t.axis == a || t.axis == 3 {
                s += fit.beta[k] * self.x(t, fit.tau, b, a);
            }
        }
        s
    }

    /// Samples a second needs to count in the 1-s statistics (half the
    /// nominal count: a partial second at either end would weigh as much
    /// as a full one with several times its noise).
    fn full_sec(&self) -> f64 {
        0.5 * self.rate_hz
    }

    /// Residuals of a fit, 1-s means per axis: `(t, [r; 3])`.
    fn resid_1s(&self, fit: &Fit) -> Vec<(f64, [f64; 3])> {
        let mut acc = vec![(0.0, [0.0; 3], 0.0); self.nsec];
        for b in &self.bins {
            let e = &mut acc[b.sec];
            e.0 += b.n * b.t;
            e.2 += b.n;
            for a in 0..3 {
                e.1[a] += b.n * (b.y[a] - self.pred(fit, b, a));
            }
        }
        let full = self.full_sec();
        acc.into_iter().filter(|e| e.2 >= full).map(|e| (e.0 / e.2, [e.1[0] / e.2, e.1[1] / e.2, e.1[2] / e.2])).collect()
    }

    fn rms_1s(&self, fit: &Fit) -> [f64; 3] {
        let r = self.resid_1s(fit);
        let mut s = [0.0; 3];
        for (_, v) in &r {
            for a in 0..3 {
                s[a] += v[a] * v[a];
            }
        }
        let n = r.len().max(1) as f64;
        [(s[0] / n).sqrt(), (s[1] / n).sqrt(), (s[2] / n).sqrt()]
    }

    /// RMS over 1-s means of the difference of two fits' predictions, per axis.
    fn diff_rms_1s(&self, f1: &Fit, f0: &Fit) -> [f64; 3] {
        let mut acc = vec![([0.0; 3], 0.0); self.nsec];
        for b in &self.bins {
            let e = &mut acc[b.sec];
            e.1 += b.n;
            for a in 0..3 {
                e.0[a] += b.n * (self.pred(f1, b, a) - self.pred(f0, b, a));
            }
        }
        let mut s = [0.0; 3];
        let mut n = 0.0;
        let full = self.full_sec();
        for (v, w) in acc.iter().filter(|e| e.1 >= full) {
            n += 1.0;
            for a in 0..3 {
                s[a] += (v[a] / w).powi(2);
            }
        }
        let n = f64::max(n, 1.0);
        [(s[0] / n).sqrt(), (s[1] / n).sqrt(), (s[2] / n).sqrt()]
    }
}

/// Log-spaced warm-up time constants searched, s: 5 s to [`TAU_MAX_S`]
/// (a power-on transient settles within minutes; slower changes are
/// thermal, and an exponential of a longer time constant is a ramp that
/// the data cannot tell from a constant plus drift).
fn tau_grid() -> Vec<f64> {
    (0..21).map(|k| 5.0 * (TAU_MAX_S / 5.0).powf(k as f64 / 20.0)).collect()
}

/// Longest warm-up time constant searched, s.
pub const TAU_MAX_S: f64 = 300.0;

/// Options of one workflow.
#[derive(Clone, Debug)]
pub struct GapOptions {
    pub measured: PathBuf,
    pub truth: PathBuf,
    pub model: PathBuf,
    pub out: PathBuf,
    /// Part profile (log decoding and the LSB of the noise floor).
    pub profile: String,
    /// Write the SVG plots.
    pub plots: bool,
}

/// Localisation of one axis' residual against one variable.
#[derive(Clone, Debug, Serialize)]
pub struct Localisation {
    pub variable: String,
    pub unit: String,
    /// Pearson correlation of the residual (0.1-s means) with the variable.
    pub correlation: f64,
    /// Quantile bins of the variable: (centre, mean residual, count).
    pub bins: Vec<(f64, f64, usize)>,
    /// Range of the binned mean residual, deg/s.
    pub binned_range: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct Finding {
    pub effect: String,
    pub axis: String,
    pub coefficient: f64,
    pub unit: String,
    pub rms_before: [f64; 3],
    pub rms_after: [f64; 3],
    pub evidence: serde_json::Value,
}

#[derive(Clone, Debug, Serialize)]
pub struct NotSeparable {
    pub effect: String,
    pub term: String,
    pub axis: String,
    pub reason: String,
}

#[derive(Clone, Debug, Serialize)]
pub struct Ambiguity {
    pub effects: [String; 2],
    pub terms: [String; 2],
    pub axis: String,
    pub partial_correlation: f64,
    pub delta_bic: [f64; 2],
    pub reason: String,
}

#[derive(Clone, Debug, Serialize)]
pub struct Report {
    pub findings: Vec<Finding>,
    pub clean: bool,
    /// Candidates the data cannot judge (no excitation / collinear), from the first iteration.
    pub not_separable: Vec<NotSeparable>,
    /// Pairs the data cannot tell apart (neither was added).
    pub ambiguous: Vec<Ambiguity>,
    pub rms_initial: [f64; 3],
    pub rms_final: [f64; 3],
    /// White-noise level of 1-s means: predicted by the model and estimated from the data.
    pub noise_floor_1s: f64,
    pub noise_floor_1s_empirical: [f64; 3],
    /// Localisation of the base model's residual per axis (the strongest
    /// variables by |correlation|, with the range of their decile means).
    pub initial_localisation: Vec<serde_json::Value>,
    /// The same for the final residual.
    pub final_localisation: Vec<serde_json::Value>,
    pub samples: usize,
    pub duration_s: f64,
    pub elapsed_s: f64,
    pub free_base_terms: Vec<String>,
}

/// What a run of the workflow produced (in memory).
pub struct GapResult {
    pub report: Report,
    pub model: SensorModel,
    pub files: Vec<PathBuf>,
    /// What the plots show.
    pub plots: Option<PlotData>,
}

/// Join measured and truth on time; build the fit bins.
fn build_data(meas: &[MeasRow], truth: &[TruthIn], truth_has_temp: bool, base: &GyroModel) -> Result<(Data, Vec<[f64; 3]>), String> {
    let t0 = truth[0].t;
    let dt = (truth[truth.len() - 1].t - t0) / (truth.len() - 1) as f64;
    if dt.is_nan() || dt <= 0.0 {
        return Err("truth: time does not advance".into());
    }
    // rate derivative as the simulator forms it (backward difference)
    let mut wd = vec![[0.0; 3]; truth.len()];
    for (k, w) in wd.iter_mut().enumerate().skip(1) {
        let h = truth[k].t - truth[k - 1].t;
        for (a, x) in w.iter_mut().enumerate() {
            *x = (truth[k].rate[a] - truth[k - 1].rate[a]) / h;
        }
    }
    // match: measured time (relative to its start for logs; CSV as given) on the truth grid
    let mt0 = meas[0].t;
    let rel = meas.iter().all(|m| m.t >= 0.0) && (mt0 - t0).abs() > 0.5 * (truth[truth.len() - 1].t - t0);
    let mut pairs = Vec::with_capacity(meas.len());
    for m in meas {
        let t = if rel { m.t - mt0 + t0 } else { m.t };
        let k = ((t - t0) / dt).round();
        if k < 0.0 || k >= truth.len() as f64 {
            continue;
        }
        let k = k as usize;
        if (truth[k].t - t).abs() <= 0.5 * dt {
            pairs.push((m, k));
        }
    }
    if pairs.len() < meas.len() / 2 || pairs.len() < 100 {
        return Err(format!(
            "measured and truth do not line up in time: {} of {} measured samples have a truth row within half a period",
            pairs.len(),
            meas.len()
        ));
    }
    let temp = |m: &MeasRow, k: usize| if truth_has_temp { truth[k].temp } else { m.temp };
    // dT/dt: slope of a local line through 1-s mean temperatures (+-5 s)
    let tr0 = pairs[0].0.t;
    let tt = |p: &(&MeasRow, usize)| truth[p.1].t;
    let tstart = tt(&pairs[0]);
    let nsec = ((tt(&pairs[pairs.len() - 1]) - tstart).floor() as usize) + 1;
    let mut sec = vec![(0.0, 0.0, 0.0); nsec];
    for p in &pairs {
        let s = ((tt(p) - tstart).floor() as usize).min(nsec - 1);
        sec[s].0 += tt(p);
        sec[s].1 += temp(p.0, p.1);
        sec[s].2 += 1.0;
    }
    let pts: Vec<(f64, f64)> = sec.iter().filter(|s| s.2 > 0.0).map(|s| (s.0 / s.2, s.1 / s.2)).collect();
    let _ = tr0;
    let slope_at = |t: f64| -> f64 {
        let i = pts.partition_point(|p| p.0 < t);
        let lo = i.saturating_sub(5);
        let hi = (i + 5).min(pts.len());
        let w = &pts[lo..hi];
        if w.len() < 2 {
            return 0.0;
        }
        let n = w.len() as f64;
        let mx = w.iter().map(|p| p.0).sum::<f64>() / n;
        let my = w.iter().map(|p| p.1).sum::<f64>() / n;
        let sxx: f64 = w.iter().map(|p| (p.0 - mx).powi(2)).sum();
        let sxy: f64 = w.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
        if sxx > 0.0 {
            sxy / sxx
        } else {
            0.0
        }
    };
    let dts: Vec<f64> = pts.iter().map(|p| slope_at(p.0)).collect();
    let dtemp_at = |t: f64| -> f64 {
        let i = pts.partition_point(|p| p.0 < t);
        if i == 0 {
            return dts[0];
        }
        if i >= pts.len() {
            return dts[pts.len() - 1];
        }
        let (a, b) = (pts[i - 1], pts[i]);
        let u = (t - a.0) / (b.0 - a.0);
        dts[i - 1] * (1.0 - u) + dts[i] * u
    };
    let mut fixed = base.clone();
    fixed.effects = fixed_effects(base);
    let nbin = (((tt(&pairs[pairs.len() - 1]) - tstart) / FIT_BIN_S).floor() as usize) + 1;
    let mut bins = vec![Bin::default(); nbin];
    let mut raw_resid: Vec<[f64; 3]> = Vec::with_capacity(pairs.len());
    for p in &pairs {
        let (m, k) = (p.0, p.1);
        let tr = &truth[k];
        let t = tr.t;
        let tc = temp(m, k);
        let x = GyroInput { rate: tr.rate, rate_dot: wd[k], f: tr.f, temp: tc, temp_rate: dtemp_at(t), t_on: t };
        let sim = fixed.measure(&x);
        let j = (((t - tstart) / FIT_BIN_S).floor() as usize).min(nbin - 1);
        let b = &mut bins[j];
        b.n += 1.0;
        b.t += t;
        b.temp += tc;
        b.temp2 += tc * tc;
        b.dtemp += x.temp_rate;
        let mut r = [0.0; 3];
        for a in 0..3 {
            b.y[a] += m.gyro[a] - sim[a];
            r[a] = m.gyro[a] - tr.rate[a];
            b.w[a] += tr.rate[a];
            b.wd[a] += wd[k][a];
            b.f[a] += tr.f[a];
        }
        raw_resid.push(r);
    }
    // cross-validation blocks: 20 s, shorter for short runs (at least 8 blocks)
    let block = CV_BLOCK_S.min((tt(&pairs[pairs.len() - 1]) - tstart) / 8.0).max(FIT_BIN_S);
    let mut out = Vec::with_capacity(nbin);
    let mean_n = pairs.len() as f64 / bins.iter().filter(|b| b.n > 0.0).count().max(1) as f64;
    for mut b in bins.into_iter().filter(|b| b.n > 0.0) {
        b.wt = b.n / mean_n;
        let n = b.n;
        b.t /= n;
        b.temp /= n;
        b.temp2 /= n;
        b.dtemp /= n;
        for a in 0..3 {
            b.y[a] /= n;
            b.w[a] /= n;
            b.wd[a] /= n;
            b.f[a] /= n;
        }
        b.sec = ((b.t - tstart).floor().max(0.0) as usize).min(nsec - 1);
        b.fold = (((b.t - tstart) / block).floor() as usize) % 2;
        out.push(b);
    }
    let t0_lin = base.thermal_linear.as_ref().map(|c| c.t0).or(base.thermal_quadratic.as_ref().map(|c| c.t0)).unwrap_or(25.0);
    let t0_quad = base.thermal_quadratic.as_ref().map(|c| c.t0).unwrap_or(t0_lin);
    let span = tt(&pairs[pairs.len() - 1]) - tstart;
    let rate_hz = if span > 0.0 { (pairs.len() - 1) as f64 / span } else { 1.0 / dt };
    Ok((Data { bins: out, rate_hz, t0_lin, t0_quad, nsec }, raw_resid))
}

/// Robust per-sample white-noise estimate from first differences (MAD), per axis.
fn empirical_sigma(raw: &[[f64; 3]]) -> [f64; 3] {
    let mut out = [0.0; 3];
    for (a, o) in out.iter_mut().enumerate() {
        let mut d: Vec<f64> = raw.windows(2).map(|w| (w[1][a] - w[0][a]).abs()).collect();
        if d.is_empty() {
            continue;
        }
        let mid = d.len() / 2;
        let (_, m, _) = d.select_nth_unstable_by(mid, |x, y| x.total_cmp(y));
        *o = *m / 0.6745 / std::f64::consts::SQRT_2;
    }
    out
}

fn localise(data: &Data, fit: &Fit, axis: usize, v: usize) -> Localisation {
    let pts: Vec<(f64, f64)> = data.bins.iter().map(|b| (b.var(v), b.y[axis] - data.pred(fit, b, axis))).collect();
    let n = pts.len() as f64;
    let mx = pts.iter().map(|p| p.0).sum::<f64>() / n;
    let my = pts.iter().map(|p| p.1).sum::<f64>() / n;
    let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
    for p in &pts {
        sxx += (p.0 - mx).powi(2);
        syy += (p.1 - my).powi(2);
        sxy += (p.0 - mx) * (p.1 - my);
    }
    let corr = if sxx > 0.0 && syy > 0.0 { sxy / (sxx * syy).sqrt() } else { 0.0 };
    let mut sorted = pts.clone();
    sorted.sort_by(|a, b| a.0.total_cmp(&b.0));
    let nb = 10.min(sorted.len());
    let mut bins = Vec::new();
    for k in 0..nb {
        let s = &sorted[k * sorted.len() / nb..(k + 1) * sorted.len() / nb];
        if s.is_empty() {
            continue;
        }
        let c = s.iter().map(|p| p.0).sum::<f64>() / s.len() as f64;
        let m = s.iter().map(|p| p.1).sum::<f64>() / s.len() as f64;
        bins.push((c, m, s.len()));
    }
    let lo = bins.iter().map(|b| b.1).fold(f64::INFINITY, f64::min);
    let hi = bins.iter().map(|b| b.1).fold(f64::NEG_INFINITY, f64::max);
    Localisation {
        variable: VAR_NAMES[v].into(),
        unit: VAR_UNITS[v].into(),
        correlation: corr,
        bins,
        binned_range: if hi >= lo { hi - lo } else { 0.0 },
    }
}

/// The strongest localisation variables of one axis, by |correlation|.
fn localise_axis(data: &Data, fit: &Fit, axis: usize, top: usize) -> Vec<Localisation> {
    let mut v: Vec<Localisation> = (0..NVAR).map(|k| localise(data, fit, axis, k)).collect();
    v.sort_by(|a, b| b.correlation.abs().total_cmp(&a.correlation.abs()));
    v.truncate(top);
    v
}

/// One evaluated candidate.
struct Cand {
    term: Term,
    fit: Fit,
    dbic: f64,
    cv_gain: f64,
    size: f64,
    r2: f64,
    se: f64,
    identifiable: Result<(), String>,
}

fn axes_of(t: &Term) -> Vec<usize> {
    if t.axis == 3 {
        vec![0, 1, 2]
    } else {
        vec![t.axis]
    }
}

fn evaluate(data: &Data, cur: &Fit, term: Term, sigma_bin: f64) -> Option<Cand> {
    let mut terms = cur.terms.clone();
    terms.push(term);
    let fit = if term.effect == Effect::WarmupTransient && !cur.terms.iter().any(|t| t.effect == Effect::WarmupTransient) {
        // 1-D search over tau (linear amplitude), then a golden-section refinement
        let grid = tau_grid();
        let mut best: Option<Fit> = None;
        for &tau in &grid {
            if let Some(f) = data.fit(&terms, tau) {
                if best.as_ref().is_none_or(|b| f.sse < b.sse) {
                    best = Some(f);
                }
            }
        }
        let b = best?;
        let (mut lo, mut hi) = ((b.tau / 1.25).ln(), (b.tau * 1.25).ln());
        let g = 0.618_033_988_75;
        let mut fb = b;
        for _ in 0..12 {
            let m1 = hi - g * (hi - lo);
            let m2 = lo + g * (hi - lo);
            let f1 = data.fit(&terms, m1.exp());
            let f2 = data.fit(&terms, m2.exp());
            let s1 = f1.as_ref().map_or(f64::INFINITY, |f| f.sse);
            let s2 = f2.as_ref().map_or(f64::INFINITY, |f| f.sse);
            if s1 < s2 {
                hi = m2;
                if let Some(f) = f1 {
                    if f.sse < fb.sse {
                        fb = f;
                    }
                }
            } else {
                lo = m1;
                if let Some(f) = f2 {
                    if f.sse < fb.sse {
                        fb = f;
                    }
                }
            }
        }
        fb
    } else {
        match data.fit(&terms, cur.tau) {
            Some(f) => f,
            None => {
                return Some(Cand {
                    term,
                    fit: cur.clone(),
                    dbic: f64::NEG_INFINITY,
                    cv_gain: 0.0,
                    size: 0.0,
                    r2: 1.0,
                    se: f64::INFINITY,
                    identifiable: Err(
                        "not separable with this data: its regressor is zero or exactly collinear with the current model".into()
                    ),
                })
            }
        }
    };
    let k = fit.terms.len() - 1;
    let axes = axes_of(&term);
    let sse0: f64 = axes.iter().map(|a| cur.sse_axis[*a]).sum();
    let sse1: f64 = axes.iter().map(|a| fit.sse_axis[*a]).sum();
    let nrows = fit.rows / 3.0 * axes.len() as f64;
    let extra = if term.effect == Effect::WarmupTransient && cur.tau.is_nan() { 2.0 } else { 1.0 };
    let dbic = nrows * (sse0 / sse1.max(1e-300)).ln() - extra * nrows.ln();
    let cv_gain = (cur.sse_cv - fit.sse_cv) / cur.sse_cv.max(1e-300);
    let size = data.diff_rms_1s(&fit, cur).iter().cloned().fold(0.0, f64::max);
    // identifiability from the joint normal matrix
    let a = data.normal(&fit.terms, fit.tau);
    let xtx = &a.xtx[0] + &a.xtx[1];
    let norm2 = xtx[(k, k)];
    let resid2 = 1.0 / fit.inv[(k, k)];
    let r2 = if norm2 > 0.0 { (1.0 - resid2 / norm2).clamp(0.0, 1.0) } else { 1.0 };
    // detection power against the white noise the model predicts (the
    // residual's own level would count effects not yet modelled as noise)
    let se = sigma_bin * fit.inv[(k, k)].sqrt();
    let identifiable = if term.effect == Effect::TimeDelay && fit.beta[k] < 0.0 {
        Err(format!("the measured rate leads the truth ({:.2e} s): not a time_delay (the vocabulary has no lead)", fit.beta[k]))
    } else if r2 > COLLINEAR_R2 {
        Err(format!("not separable with this data: its regressor is collinear with the current model's (R^2 = {r2:.4})"))
    } else if term.plausible() / se < 3.0 {
        Err(format!(
            "not separable with this data: too little excitation (standard error {se:.3e} {} against a plausible size {:.1e})",
            term.unit(),
            term.plausible()
        ))
    } else {
        Ok(())
    };
    Some(Cand { term, fit, dbic, cv_gain, size, r2, se, identifiable })
}

/// Partial correlation of two candidate terms given the current model.
fn partial_corr(data: &Data, cur: &Fit, t1: Term, t2: Term, tau: f64) -> f64 {
    let mut terms = cur.terms.clone();
    terms.push(t1);
    terms.push(t2);
    let n = data.normal(&terms, tau);
    let a = &n.xtx[0] + &n.xtx[1];
    let p = terms.len();
    match solve(&a, &DVector::zeros(p)) {
        Some((_, inv)) => -inv[(p - 2, p - 1)] / (inv[(p - 2, p - 2)] * inv[(p - 1, p - 1)]).sqrt(),
        None => 1.0,
    }
}

fn coef_of(fit: &Fit, t: &Term) -> f64 {
    fit.terms.iter().position(|x| x == t).map_or(0.0, |k| fit.beta[k])
}

/// Run the workflow on files and write the outputs.
pub fn run(o: &GapOptions) -> Result<GapResult, String> {
    let start = std::time::Instant::now();
    let profile = builtin_profile(&o.profile).ok_or_else(|| format!("unknown profile {:?}", o.profile))?;
    let base = load_base(&o.model)?;
    let meas = read_measured(&o.measured, &profile)?;
    let (truth, has_temp) = read_truth(&o.truth)?;
    let mut res = analyse(&meas, &truth, has_temp, &base, &profile)?;
    res.report.elapsed_s = start.elapsed().as_secs_f64();
    res.files = write_outputs(o, &mut res)?;
    // elapsed including the outputs
    res.report.elapsed_s = start.elapsed().as_secs_f64();
    let p = o.out.join("report.json");
    std::fs::write(&p, serde_json::to_string_pretty(&res.report).map_err(|e| e.to_string())? + "\n")
        .map_err(|e| format!("{}: {e}", p.display()))?;
    Ok(res)
}

/// Internal state kept for the plots.
pub struct PlotData {
    initial: Vec<(f64, [f64; 3])>,
    fin: Vec<(f64, [f64; 3])>,
    /// per finding: the term, the localisation variable points before/after (x, r)
    finds: Vec<(String, usize, String, Localisation, Localisation)>,
}

/// The workflow on data in memory. Outputs are not written.
pub fn analyse(
    meas: &[MeasRow],
    truth: &[TruthIn],
    truth_has_temp: bool,
    base: &SensorModel,
    profile: &Profile,
) -> Result<GapResult, String> {
    let start = std::time::Instant::now();
    if !truth_has_temp && meas.iter().any(|m| !m.temp.is_finite()) {
        return Err("truth has no temp column and the measured data has no temperature".into());
    }
    let (data, raw) = build_data(meas, truth, truth_has_temp, &base.gyro)?;
    if data.bins.len() < 20 {
        return Err(format!("too little data: {} bins of {FIT_BIN_S} s", data.bins.len()));
    }
    // the measured rate (a CSV need not be at the profile's rate)
    let rate = data.rate_hz;
    let sigma_s = ((base.noise.gyro_white * (rate / 2.0).sqrt()).powi(2) + profile.gyro_lsb.powi(2) / 12.0).sqrt();
    let per_bin = data.bins.iter().map(|b| b.n).sum::<f64>() / data.bins.len() as f64;
    let sigma_bin = sigma_s / per_bin.sqrt();
    let floor_1s = sigma_s / rate.sqrt();
    let emp = empirical_sigma(&raw);
    let emp_1s = [emp[0] / rate.sqrt(), emp[1] / rate.sqrt(), emp[2] / rate.sqrt()];
    // the white-noise level used by the size rule: the model's, or the data's when higher
    let floor = emp_1s.iter().cloned().fold(floor_1s, f64::max);

    // free terms of the base model
    let mut free: Vec<Term> = Vec::new();
    for e in &base.gyro.effects {
        if !has_table(&base.gyro, *e) {
            free.extend(all_terms(*e));
        }
    }
    let free_has_warm = free.iter().any(|t| t.effect == Effect::WarmupTransient);
    let mut cur = if free_has_warm {
        let mut best: Option<Fit> = None;
        for tau in tau_grid() {
            if let Some(f) = data.fit(&free, tau) {
                if best.as_ref().is_none_or(|b| f.sse < b.sse) {
                    best = Some(f);
                }
            }
        }
        best.ok_or("the base model's free coefficients cannot be fitted from this data (singular)")?
    } else {
        let tau = base.gyro.warmup_transient.as_ref().map_or(f64::NAN, |w| w.tau_s);
        data.fit(&free, tau).ok_or("the base model's free coefficients cannot be fitted from this data (singular)")?
    };
    let initial_fit = cur.clone();
    if std::env::var_os("GAP_DEBUG").is_some() {
        eprintln!("initial beta {:?} terms {:?} bins {} first {:?}", cur.beta.as_slice(), cur.terms, data.bins.len(), &data.bins[..2]);
    }
    let rms_initial = data.rms_1s(&cur);
    let mut findings = Vec::new();
    let mut not_separable: Vec<NotSeparable> = Vec::new();
    let mut ambiguous: Vec<Ambiguity> = Vec::new();
    let mut excluded: Vec<Term> = Vec::new();
    // axes whose leading explanation was not separable: nothing more is added there
    let mut blocked = [false; 3];
    let mut plot_finds = Vec::new();
    let mut first = true;
    // candidates: every term of every effect not in the model (fixed effects count as present)
    let fixed_eff = fixed_effects(&base.gyro);
    while findings.len() < MAX_FINDINGS {
        let cands: Vec<Term> = Effect::ALL
            .iter()
            .filter(|e| !fixed_eff.contains(e))
            .flat_map(|e| all_terms(*e))
            .filter(|t| !cur.terms.contains(t) && !excluded.contains(t) && (t.axis == 3 || !blocked[t.axis]))
            .collect();
        let mut evals: Vec<Cand> = cands.into_iter().filter_map(|t| evaluate(&data, &cur, t, sigma_bin)).collect();
        if first {
            for c in &evals {
                if let Err(r) = &c.identifiable {
                    not_separable.push(NotSeparable {
                        effect: c.term.effect.name().into(),
                        term: c.term.label(),
                        axis: if c.term.axis == 3 { "all".into() } else { AX[c.term.axis].into() },
                        reason: r.clone(),
                    });
                }
            }
            first = false;
        }
        evals.sort_by(|a, b| b.dbic.total_cmp(&a.dbic));
        let passes = |c: &Cand| c.identifiable.is_ok() && c.dbic > BIC_MIN && c.cv_gain > 0.0 && c.size >= SIZE_MIN * floor;
        let Some(bi) = evals.iter().position(passes) else { break };
        let mut bi = bi;
        // Occam: a simpler candidate (fewer parameters) whose simulated gyro
        // differs from the best one's by less than the size threshold explains
        // the same thing; take the simpler one.
        let params = |c: &Cand| if c.term.effect == Effect::WarmupTransient && cur.tau.is_nan() { 2 } else { 1 };
        // the simpler model is a limit of the other (a warm-up of long time constant is a constant)
        let nested = |simple: &Cand, other: &Cand| {
            simple.term.effect == Effect::TurnOnBias && other.term.effect == Effect::WarmupTransient && simple.term.axis == other.term.axis
        };
        for (k, c) in evals.iter().enumerate() {
            let b = &evals[bi];
            if k == bi || !passes(c) || params(c) >= params(b) || !nested(c, b) {
                continue;
            }
            let d = data.diff_rms_1s(&c.fit, &b.fit).iter().cloned().fold(0.0, f64::max);
            if d < SIZE_MIN * floor {
                bi = k;
            }
        }
        let best = &evals[bi];
        // ambiguity: a close rival whose regressor is nearly the same given the current model
        let mut amb = None;
        for c in evals.iter().filter(|c| passes(c) && c.term != best.term && c.dbic >= best.dbic - BIC_MIN) {
            let share = axes_of(&c.term).iter().any(|a| axes_of(&best.term).contains(a));
            if !share {
                continue;
            }
            // a rival with more parameters that Occam set aside (same prediction in practice)
            if nested(best, c) && data.diff_rms_1s(&c.fit, &best.fit).iter().cloned().fold(0.0, f64::max) < SIZE_MIN * floor {
                continue;
            }
            let tau = if best.term.effect == Effect::WarmupTransient { best.fit.tau } else { c.fit.tau };
            let rho = partial_corr(&data, &cur, best.term, c.term, tau);
            if rho.abs() > AMBIGUOUS_CORR || (best.dbic - c.dbic < BIC_TIE && rho.abs() > 0.5) {
                amb = Some((c.term, c.dbic, rho));
                break;
            }
        }
        if let Some((t2, d2, rho)) = amb {
            let axis = if best.term.axis == 3 { t2.axis } else { best.term.axis };
            ambiguous.push(Ambiguity {
                effects: [best.term.effect.name().into(), t2.effect.name().into()],
                terms: [best.term.label(), t2.label()],
                axis: if axis == 3 { "all".into() } else { AX[axis].into() },
                partial_correlation: rho,
                delta_bic: [best.dbic, d2],
                reason: format!(
                    "not separable with this data: {} and {} explain the residual about equally (dBIC {:.1} vs {:.1}) and their regressors correlate at {:.3} once the current model is removed; neither is added",
                    best.term.label(),
                    t2.label(),
                    best.dbic,
                    d2,
                    rho
                ),
            });
            excluded.push(best.term);
            excluded.push(t2);
            for t in [best.term, t2] {
                if t.axis < 3 {
                    blocked[t.axis] = true;
                }
            }
            continue;
        }
        let rms_before = data.rms_1s(&cur);
        let rms_after = data.rms_1s(&best.fit);
        let coef = coef_of(&best.fit, &best.term);
        let axis = if best.term.axis == 3 {
            // the axis where the delay explains most
            let d = data.diff_rms_1s(&best.fit, &cur);
            (0..3).max_by(|a, b| d[*a].total_cmp(&d[*b])).unwrap()
        } else {
            best.term.axis
        };
        let v = best.term.variable().min(if best.term.axis == 3 { V_WD + axis } else { NVAR - 1 });
        let v = if best.term.axis == 3 { V_WD + axis } else { v };
        let loc_before = localise(&data, &cur, axis, v);
        let loc_after = localise(&data, &best.fit, axis, v);
        let strongest = localise_axis(&data, &cur, axis, 3);
        let runner = evals.iter().filter(|c| c.term != best.term && c.dbic.is_finite()).max_by(|a, b| a.dbic.total_cmp(&b.dbic));
        let mut ev = serde_json::json!({
            "term": best.term.label(),
            "rule": format!("dBIC > {BIC_MIN}, held-out SSE lower, explained RMS >= {SIZE_MIN} x noise floor, identifiable, no equally good correlated rival"),
            "delta_bic": best.dbic,
            "cv_heldout_sse_gain": best.cv_gain,
            "explained_rms_1s": best.size,
            "noise_floor_1s": floor,
            "std_error": best.se,
            "t_stat": coef / best.se,
            "r2_with_current_model": best.r2,
            "localisation": {
                "variable": loc_before.variable,
                "correlation_before": loc_before.correlation,
                "binned_range_before": loc_before.binned_range,
                "correlation_after": loc_after.correlation,
                "binned_range_after": loc_after.binned_range,
                "strongest_before": strongest.iter().map(|l| serde_json::json!({"variable": l.variable, "correlation": l.correlation, "binned_range": l.binned_range})).collect::<Vec<_>>(),
            },
            "ranking": evals.iter().filter(|c| c.dbic.is_finite()).take(5).map(|c| serde_json::json!({"term": c.term.label(), "delta_bic": c.dbic, "cv_heldout_sse_gain": c.cv_gain, "explained_rms_1s": c.size})).collect::<Vec<_>>(),
        });
        if let Some(r) = runner {
            ev["runner_up"] = serde_json::json!({"term": r.term.label(), "delta_bic": r.dbic});
        }
        if best.term.effect == Effect::WarmupTransient {
            ev["tau_s"] = serde_json::json!(best.fit.tau);
        }
        if matches!(best.term.effect, Effect::GSensitivity | Effect::Misalignment) {
            ev["column"] = serde_json::json!(AX[best.term.col]);
        }
        findings.push(Finding {
            effect: best.term.effect.name().into(),
            axis: AX[axis].into(),
            coefficient: coef,
            unit: best.term.unit().into(),
            rms_before,
            rms_after,
            evidence: ev,
        });
        plot_finds.push((best.term.label(), axis, best.term.effect.name().to_string(), loc_before, loc_after));
        cur = best.fit.clone();
    }
    // the coefficients of the final joint fit (later findings can correct
    // earlier ones when their regressors are correlated)
    for f in findings.iter_mut() {
        let when = f.coefficient;
        f.evidence["coefficient_when_found"] = serde_json::json!(when);
        if let Some(t) = cur.terms.iter().find(|t| Some(t.label()) == f.evidence["term"].as_str().map(String::from)) {
            f.coefficient = coef_of(&cur, t);
        }
        if f.effect == "warmup_transient" {
            f.evidence["tau_s"] = serde_json::json!(cur.tau);
        }
    }
    let rms_final = data.rms_1s(&cur);
    let model = extended_model(base, &cur, &findings);
    let locs = |fit: &Fit, rms: &[f64; 3]| -> Vec<serde_json::Value> {
        (0..3)
            .map(|a| {
                let l = localise_axis(&data, fit, a, 3);
                serde_json::json!({"axis": AX[a], "rms_1s": rms[a], "ratio_to_floor": rms[a] / floor,
                    "strongest": l.iter().map(|l| serde_json::json!({"variable": l.variable, "correlation": l.correlation, "binned_range": l.binned_range})).collect::<Vec<_>>()})
            })
            .collect()
    };
    let final_localisation = locs(&cur, &rms_final);
    let initial_localisation = locs(&initial_fit, &rms_initial);
    let clean = findings.is_empty() && ambiguous.is_empty();
    let report = Report {
        findings,
        clean,
        not_separable,
        ambiguous,
        rms_initial,
        rms_final,
        noise_floor_1s: floor_1s,
        noise_floor_1s_empirical: emp_1s,
        initial_localisation,
        final_localisation,
        samples: raw.len(),
        duration_s: data.bins.last().map_or(0.0, |b| b.t) - data.bins[0].t,
        elapsed_s: start.elapsed().as_secs_f64(),
        free_base_terms: free.iter().map(|t| t.label()).collect(),
    };
    let pd = PlotData { initial: data.resid_1s(&initial_fit), fin: data.resid_1s(&cur), finds: plot_finds };
    Ok(GapResult { report, model, files: vec![], plots: Some(pd) })
}

/// The base model with every free coefficient filled in and the found effects added.
fn extended_model(base: &SensorModel, fit: &Fit, findings: &[Finding]) -> SensorModel {
    let mut m = base.clone();
    let g = &mut m.gyro;
    let mut effects = g.effects.clone();
    for f in findings {
        let e = Effect::parse(&f.effect).expect("findings name vocabulary effects");
        if !effects.contains(&e) {
            effects.push(e);
        }
    }
    let free: Vec<Effect> = effects.iter().copied().filter(|e| !has_table(&base.gyro, *e)).collect();
    let v3 = |e: Effect| -> [f64; 3] {
        let mut v = [0.0; 3];
        for (a, x) in v.iter_mut().enumerate() {
            *x = coef_of(fit, &Term { effect: e, axis: a, col: 0 });
        }
        v
    };
    let m33 = |e: Effect| -> [[f64; 3]; 3] {
        let mut v = [[0.0; 3]; 3];
        for (i, row) in v.iter_mut().enumerate() {
            for (j, x) in row.iter_mut().enumerate() {
                *x = coef_of(fit, &Term { effect: e, axis: i, col: j });
            }
        }
        v
    };
    let t0_lin = g.thermal_linear.as_ref().map(|c| c.t0).or(g.thermal_quadratic.as_ref().map(|c| c.t0)).unwrap_or(25.0);
    let t0_quad = g.thermal_quadratic.as_ref().map(|c| c.t0).unwrap_or(t0_lin);
    for e in free {
        match e {
            Effect::TurnOnBias => g.turn_on_bias = Some(TurnOnBias { bias: v3(e) }),
            Effect::ThermalLinear => g.thermal_linear = Some(ThermalLinear { t0: t0_lin, p1: v3(e) }),
            Effect::ThermalQuadratic => g.thermal_quadratic = Some(ThermalQuadratic { t0: t0_quad, p2: v3(e) }),
            Effect::ThermalRate => g.thermal_rate = Some(ThermalRate { k: v3(e) }),
            Effect::WarmupTransient => g.warmup_transient = Some(WarmupTransient { amplitude: v3(e), tau_s: fit.tau }),
            Effect::GSensitivity => g.g_sensitivity = Some(GSensitivity { g: m33(e) }),
            Effect::ScaleFactor => g.scale_factor = Some(ScaleFactor { k: v3(e) }),
            Effect::Misalignment => g.misalignment = Some(Misalignment { m: m33(e) }),
            Effect::TimeDelay => g.time_delay = Some(TimeDelay { delay_s: coef_of(fit, &Term { effect: e, axis: 3, col: 0 }).max(0.0) }),
        }
    }
    g.effects = effects;
    m
}

fn fmt3(v: &[f64; 3]) -> String {
    format!("{:.5}, {:.5}, {:.5}", v[0], v[1], v[2])
}

fn write_outputs(o: &GapOptions, res: &mut GapResult) -> Result<Vec<PathBuf>, String> {
    let dir = &o.out;
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut files = Vec::new();
    let w = |name: &str, text: &str| -> Result<PathBuf, String> {
        let p = dir.join(name);
        std::fs::write(&p, text).map_err(|e| format!("{}: {e}", p.display()))?;
        Ok(p)
    };
    files.push(w("model.toml", &res.model.to_toml())?);
    files.push(w("report.md", &render_md(&res.report, o))?);
    if o.plots {
        if let Some(pd) = &res.plots {
            let p = dir.join("residual.svg");
            plot_residual(&p, pd).map_err(|e| format!("{}: {e}", p.display()))?;
            files.push(p);
            for (k, f) in pd.finds.iter().enumerate() {
                let p = dir.join(format!("finding_{}_{}_{}.svg", k + 1, f.2, AX[f.1]));
                plot_finding(&p, f).map_err(|e| format!("{}: {e}", p.display()))?;
                files.push(p);
            }
        }
    }
    files.push(dir.join("report.json"));
    Ok(files)
}

/// report.md.
pub fn render_md(r: &Report, o: &GapOptions) -> String {
    let mut s = String::new();
    s += "# Model gap report\n\n";
    s += &format!(
        "Measured `{}`, truth `{}`, base model `{}`: {} samples over {:.1} s; {:.2} s.\n\n",
        o.measured.display(),
        o.truth.display(),
        o.model.display(),
        r.samples,
        r.duration_s,
        r.elapsed_s
    );
    s += &format!(
        "Residual RMS of 1-s means with the base model (free terms fitted): [{}] deg/s; white-noise level of 1-s means predicted by the model {:.5} deg/s (from the data [{}]).\n\n",
        fmt3(&r.rms_initial),
        r.noise_floor_1s,
        fmt3(&r.noise_floor_1s_empirical)
    );
    let where_ = |title: &str, v: &[serde_json::Value]| -> String {
        let mut s = format!("### {title}\n\n| axis | RMS 1-s, deg/s | / noise | strongest variables (correlation, decile-mean range deg/s) |\n|---|---|---|---|\n");
        for l in v {
            let st: Vec<String> = l["strongest"]
                .as_array()
                .map(|a| {
                    a.iter()
                        .map(|x| {
                            format!(
                                "{} ({:+.2}, {:.4})",
                                x["variable"].as_str().unwrap_or(""),
                                x["correlation"].as_f64().unwrap_or(0.0),
                                x["binned_range"].as_f64().unwrap_or(0.0)
                            )
                        })
                        .collect()
                })
                .unwrap_or_default();
            s += &format!(
                "| {} | {:.5} | {:.2} | {} |\n",
                l["axis"].as_str().unwrap_or(""),
                l["rms_1s"].as_f64().unwrap_or(0.0),
                l["ratio_to_floor"].as_f64().unwrap_or(0.0),
                st.join("; ")
            );
        }
        s + "\n"
    };
    s += &where_("Where the base model fails", &r.initial_localisation);
    if r.findings.is_empty() && r.ambiguous.is_empty() {
        s += "**No missing effect found**: no candidate passed the significance rule.\n\n";
    }
    for (k, f) in r.findings.iter().enumerate() {
        let ev = &f.evidence;
        let l = &ev["localisation"];
        s += &format!(
            "## {}. `{}` (axis {}) — coefficient {:.4e} {}\n\n",
            k + 1,
            ev["term"].as_str().unwrap_or(&f.effect),
            f.axis,
            f.coefficient,
            if f.unit == "1" { "(dimensionless)" } else { &f.unit }
        );
        s += &format!(
            "- where: the residual on {} correlated with {} at {:.3} (binned range {:.4} deg/s), after: {:.3} ({:.4} deg/s)\n",
            f.axis,
            l["variable"].as_str().unwrap_or(""),
            l["correlation_before"].as_f64().unwrap_or(0.0),
            l["binned_range_before"].as_f64().unwrap_or(0.0),
            l["correlation_after"].as_f64().unwrap_or(0.0),
            l["binned_range_after"].as_f64().unwrap_or(0.0)
        );
        s += &format!(
            "- why: dBIC {:.1}, held-out SSE gain {:.2} %, explains {:.4} deg/s RMS (1-s means), t = {:.1}\n",
            ev["delta_bic"].as_f64().unwrap_or(0.0),
            100.0 * ev["cv_heldout_sse_gain"].as_f64().unwrap_or(0.0),
            ev["explained_rms_1s"].as_f64().unwrap_or(0.0),
            ev["t_stat"].as_f64().unwrap_or(0.0)
        );
        if let Some(r) = ev.get("runner_up") {
            s += &format!("- runner-up: {} (dBIC {:.1})\n", r["term"].as_str().unwrap_or(""), r["delta_bic"].as_f64().unwrap_or(0.0));
        }
        s += &format!("- residual RMS [x, y, z]: before [{}], after [{}] deg/s\n\n", fmt3(&f.rms_before), fmt3(&f.rms_after));
    }
    if !r.ambiguous.is_empty() {
        s += "## Not separable with this data\n\n";
        for a in &r.ambiguous {
            s += &format!("- {}\n", a.reason);
        }
        s += "\n";
    }
    if !r.not_separable.is_empty() {
        s += "## Candidates this data cannot judge (on the base model's residual)\n\n";
        for n in &r.not_separable {
            s += &format!("- {}: {}\n", n.term, n.reason);
        }
        s += "\n";
    }
    s += &where_("What is left", &r.final_localisation);
    s += &format!(
        "Final residual RMS of 1-s means [{}] deg/s ({}).\n",
        fmt3(&r.rms_final),
        if r.clean { "clean: the base model explains the data" } else { "see model.toml for the extended model" }
    );
    s
}

fn plot_residual(path: &Path, pd: &PlotData) -> Result<(), String> {
    use plotters::prelude::*;
    let e = |x: &dyn std::fmt::Display| x.to_string();
    let root = SVGBackend::new(path, (1000, 900)).into_drawing_area();
    root.fill(&WHITE).map_err(|x| e(&x))?;
    let areas = root.split_evenly((3, 1));
    for (a, area) in areas.iter().enumerate() {
        let pts = |v: &[(f64, [f64; 3])]| v.iter().map(|p| (p.0, p.1[a])).collect::<Vec<_>>();
        let (i, f) = (pts(&pd.initial), pts(&pd.fin));
        let x0 = i.first().map_or(0.0, |p| p.0);
        let x1 = i.last().map_or(1.0, |p| p.0).max(x0 + 1.0);
        let m = i.iter().chain(&f).map(|p| p.1.abs()).filter(|v| v.is_finite()).fold(1e-4, f64::max) * 1.05;
        let mut ch = ChartBuilder::on(area)
            .caption(format!("gyro {} residual (1-s means): base model vs extended model", AX[a]), ("sans-serif", 16))
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(60)
            .build_cartesian_2d(x0..x1, -m..m)
            .map_err(|x| e(&x))?;
        ch.configure_mesh().x_desc("t, s").y_desc("deg/s").draw().map_err(|x| e(&x))?;
        let grey = RGBColor(160, 160, 160);
        ch.draw_series(LineSeries::new(i, grey.stroke_width(1)))
            .map_err(|x| e(&x))?
            .label("before")
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 15, y)], grey));
        ch.draw_series(LineSeries::new(f, BLUE.stroke_width(1)))
            .map_err(|x| e(&x))?
            .label("after")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 15, y)], BLUE));
        ch.configure_series_labels().background_style(WHITE.mix(0.8)).border_style(BLACK).draw().map_err(|x| e(&x))?;
    }
    root.present().map_err(|x| e(&x))?;
    Ok(())
}

fn plot_finding(path: &Path, f: &(String, usize, String, Localisation, Localisation)) -> Result<(), String> {
    use plotters::prelude::*;
    let e = |x: &dyn std::fmt::Display| x.to_string();
    let (label, axis, _, before, after) = f;
    let root = SVGBackend::new(path, (900, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(|x| e(&x))?;
    let all: Vec<(f64, f64)> = before.bins.iter().chain(&after.bins).map(|b| (b.0, b.1)).collect();
    let mut x0 = all.iter().map(|p| p.0).fold(f64::INFINITY, f64::min);
    let mut x1 = all.iter().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max);
    if !x0.is_finite() {
        x0 = 0.0;
    }
    if !x1.is_finite() || x1 <= x0 {
        x1 = x0 + 1.0;
    }
    let m = all.iter().map(|p| p.1.abs()).fold(1e-4, f64::max) * 1.1;
    let mut ch = ChartBuilder::on(&root)
        .caption(format!("{label}: gyro {} residual vs {} (decile means)", AX[*axis], before.variable), ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(x0..x1, -m..m)
        .map_err(|x| e(&x))?;
    ch.configure_mesh().x_desc(format!("{}, {}", before.variable, before.unit)).y_desc("mean residual, deg/s").draw().map_err(|x| e(&x))?;
    for (loc, c, name) in [(before, RED, "before"), (after, BLUE, "after")] {
        let pts: Vec<(f64, f64)> = loc.bins.iter().map(|b| (b.0, b.1)).collect();
        ch.draw_series(LineSeries::new(pts.clone(), c.stroke_width(2)))
            .map_err(|x| e(&x))?
            .label(format!("{name} (r = {:.3})", loc.correlation))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 15, y)], c));
        ch.draw_series(pts.into_iter().map(|p| Circle::new(p, 3, c.filled()))).map_err(|x| e(&x))?;
    }
    ch.configure_series_labels().background_style(WHITE.mix(0.8)).border_style(BLACK).draw().map_err(|x| e(&x))?;
    root.present().map_err(|x| e(&x))?;
    Ok(())
}

/// `gyrocomp gap` arguments.
#[derive(clap::Args, Debug)]
pub struct GapArgs {
    /// Measured data: a candump log (ADIS contract) or a CSV t,gx,gy,gz,ax,ay,az,mx,my,mz,temp.
    #[arg(long)]
    pub measured: PathBuf,
    /// truth.csv as `gyrocomp simulate` writes it (temp optional when the measured data has it).
    #[arg(long)]
    pub truth: PathBuf,
    /// Base gyro sensor model (sensor.toml shape; effects listed without a table are fitted).
    #[arg(long)]
    pub model: PathBuf,
    /// Output directory: report.json, report.md, model.toml, SVG plots.
    #[arg(long)]
    pub out: PathBuf,
    /// Part profile (log decoding, LSB of the noise floor).
    #[arg(long, default_value = "adis16448")]
    pub profile: String,
}

/// The `gap` subcommand.
pub fn cli(a: &GapArgs) -> Result<(), String> {
    let o = GapOptions {
        measured: a.measured.clone(),
        truth: a.truth.clone(),
        model: a.model.clone(),
        out: a.out.clone(),
        profile: a.profile.clone(),
        plots: true,
    };
    let r = run(&o)?;
    let rep = &r.report;
    println!("gap: {} samples, {:.1} s of data, {:.2} s", rep.samples, rep.duration_s, rep.elapsed_s);
    println!("residual RMS (1-s means) base model [{}] deg/s, noise floor {:.5} deg/s", fmt3(&rep.rms_initial), rep.noise_floor_1s);
    for f in &rep.findings {
        println!(
            "found {} on {}: {:.4e} {} (dBIC {:.1}); RMS [{}] -> [{}]",
            f.evidence["term"].as_str().unwrap_or(&f.effect),
            f.axis,
            f.coefficient,
            f.unit,
            f.evidence["delta_bic"].as_f64().unwrap_or(0.0),
            fmt3(&f.rms_before),
            fmt3(&f.rms_after)
        );
    }
    for a in &rep.ambiguous {
        println!("{}", a.reason);
    }
    if rep.clean {
        println!("clean: nothing missing");
    }
    for p in &r.files {
        println!("wrote {}", p.display());
    }
    Ok(())
}
