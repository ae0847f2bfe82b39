//! Step 2, **fit**: every effect of the vocabulary is linear in its
//! coefficients given the truth (except the warm-up time constant, found by
//! a 1-D search), so the model is a linear regression of `y` (measured minus
//! the fixed part of the model) on regressors that are the simulator's own
//! formulas. The noise is what the simulator (and a real MEMS gyro) has:
//! white rate noise plus a bias random walk. The fit is generalised least
//! squares at the full sample rate with that noise model:
//!
//! - the noise of one axis is `e_k + b_k`, `e` white (variance `r`, the model's
//!   density times `sqrt(rate / 2)` combined with the quantisation `LSB^2 / 12`,
//!   or the data's own white level when higher), `b` the random walk
//!   (`b_{k+1} = b_k + q sqrt(dt) eta`), which starts at 0 at power-on (t = 0
//!   of the truth: the constant part of the bias at power-on is the turn-on
//!   bias);
//! - a Kalman filter of that local-level model turns `y` and every regressor
//!   into innovations divided by their standard deviation (the filter's gains
//!   do not depend on the data, so this is one linear map, the same for
//!   every column: the exact GLS transform, "pre-whitening");
//! - ordinary least squares on the whitened columns is the GLS estimate, and
//!   `(X'X)^-1` of the whitened columns is its covariance. A coefficient's
//!   standard error is `sqrt((X'X)^-1_kk)`, widened by the whitened residual
//!   variance of its axis when that exceeds 1 (the model's noise level was too
//!   low), never narrowed.
//!
//! Rate-dependent terms (`scale_factor`, `misalignment`, `time_delay`,
//! `g_sensitivity`) draw their information from the fast content, where the
//! noise is white; slow terms (thermal, warm-up) from what the random walk
//! leaves: the filter weighs each band by its noise as the model says.
//!
//! Every column of every axis is one of 16 signals (1, T - t0, (T - t0)^2,
//! dT/dt, f, w, -dw/dt per axis, y per axis) or the warm-up exponential, so the
//! whitened signals' Gram matrix is computed once and every fit is a small
//! solve on it.

use super::read::Samples;
use crate::sim::model::Effect;
use nalgebra::{DMatrix, DVector};

pub(crate) const AX: [&str; 3] = ["x", "y", "z"];

/// A term whose regressor's R^2 on the current model's exceeds this is not
/// separable: freeing the others multiplies its standard error by more than
/// 100 (below that, its t statistic judges it).
pub const COLLINEAR_R2: f64 = 0.9999;
/// Longest warm-up time constant searched, s.
pub const TAU_MAX_S: f64 = 300.0;
/// Shortest warm-up time constant searched, s.
pub const TAU_MIN_S: f64 = 5.0;

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

    /// The axis as the reports name it: `x`, `y`, `z` or `all` (one shared delay).
    pub fn axis_name(&self) -> &'static str {
        if self.axis == 3 {
            "all"
        } else {
            AX[self.axis]
        }
    }

    pub fn unit(&self) -> &'static str {
        unit(self.effect)
    }

    /// The axes whose rows the term enters.
    pub fn axes(&self) -> Vec<usize> {
        if self.axis == 3 {
            vec![0, 1, 2]
        } else {
            vec![self.axis]
        }
    }

    /// Its column on `axis`, if any.
    fn col_on(&self, axis: usize) -> Option<Col> {
        if self.effect == Effect::TimeDelay {
            return Some(Col::Sig(S_WD + axis));
        }
        if self.axis != axis {
            return None;
        }
        Some(match self.effect {
            Effect::TurnOnBias => Col::Sig(S_ONE),
            Effect::ThermalLinear => Col::Sig(S_TLIN),
            Effect::ThermalQuadratic => Col::Sig(S_TQUAD),
            Effect::ThermalRate => Col::Sig(S_DTEMP),
            Effect::WarmupTransient => Col::Warm,
            Effect::GSensitivity => Col::Sig(S_F + self.col),
            Effect::ScaleFactor => Col::Sig(S_W + axis),
            Effect::Misalignment => Col::Sig(S_W + self.col),
            Effect::TimeDelay => unreachable!(),
        })
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

/// Every coefficient of an effect (per axis; per matrix element; one shared delay).
pub fn all_terms(e: Effect) -> Vec<Term> {
    match e {
        Effect::TimeDelay => vec![Term { effect: e, axis: 3, col: 0 }],
        Effect::GSensitivity => (0..9).map(|k| Term { effect: e, axis: k / 3, col: k % 3 }).collect(),
        Effect::Misalignment => (0..9).filter(|k| k / 3 != k % 3).map(|k| Term { effect: e, axis: k / 3, col: k % 3 }).collect(),
        _ => (0..3).map(|a| Term { effect: e, axis: a, col: 0 }).collect(),
    }
}

/// Log-spaced warm-up time constants searched, s: [`TAU_MIN_S`] to
/// [`TAU_MAX_S`] (a power-on transient settles within minutes; slower
/// changes are thermal, and an exponential of a longer time constant is a
/// ramp that the data cannot tell from a constant plus drift).
pub fn tau_grid() -> Vec<f64> {
    (0..21).map(|k| TAU_MIN_S * (TAU_MAX_S / TAU_MIN_S).powf(k as f64 / 20.0)).collect()
}

// The signals every column is made of.
const S_ONE: usize = 0;
const S_TLIN: usize = 1;
const S_TQUAD: usize = 2;
const S_DTEMP: usize = 3;
const S_F: usize = 4;
const S_W: usize = 7;
const S_WD: usize = 10;
const S_Y: usize = 13;
const NSIG: usize = 16;

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Col {
    Sig(usize),
    /// `exp(-t / tau)`
    Warm,
}

/// Value of signal `sig` at sample `k` (before whitening).
#[inline]
fn raw(s: &Samples, sig: usize, k: usize) -> f64 {
    match sig {
        S_ONE => 1.0,
        S_TLIN => s.temp[k] - s.t0_lin,
        S_TQUAD => (s.temp[k] - s.t0_quad).powi(2),
        S_DTEMP => s.dtemp[k],
        4..=6 => s.f[sig - S_F][k],
        7..=9 => s.w[sig - S_W][k],
        // measured = w(t - d) = w - d dw/dt: the column of d is -dw/dt
        10..=12 => -s.wd[sig - S_WD][k],
        _ => s.y[sig - S_Y][k],
    }
}

/// The noise model the fit and its standard errors use.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct NoiseModel {
    /// White rate noise density of the base model's `[noise] gyro_white`, deg/s/sqrt(Hz).
    pub white_density: f64,
    /// Gyro LSB of the profile, deg/s.
    pub lsb: f64,
    /// Per-sample white noise the model predicts (density x sqrt(rate/2), with LSB^2/12), deg/s.
    pub sigma_model: f64,
    /// Per-sample white noise of the data per axis (the model's scaled by the
    /// whitened residual variance with every vocabulary term fitted), deg/s.
    pub sigma_data: [f64; 3],
    /// Per-sample white noise used: the data's, all axes together, deg/s.
    pub sigma: f64,
    /// Bias random walk of `[noise] gyro_bias_walk`, deg/s/sqrt(s).
    pub bias_walk: f64,
    /// Memory of the whitening filter in steady state (1 / (gain x rate)), s:
    /// content slower than this is weighed down by the random walk.
    pub filter_memory_s: f64,
}

impl NoiseModel {
    /// The base model's noise at the data's rate.
    pub fn new(s: &Samples, white_density: f64, bias_walk: f64, lsb: f64) -> NoiseModel {
        let sigma_model = ((white_density * (s.rate_hz / 2.0).sqrt()).powi(2) + lsb * lsb / 12.0).sqrt();
        let mut n = NoiseModel {
            white_density,
            lsb,
            sigma_model,
            sigma_data: [sigma_model; 3],
            sigma: sigma_model,
            bias_walk,
            filter_memory_s: 0.0,
        };
        n.set_sigma(sigma_model, s.rate_hz);
        n
    }

    fn set_sigma(&mut self, sigma: f64, rate_hz: f64) {
        self.sigma = sigma;
        let qs = self.bias_walk * self.bias_walk / rate_hz;
        let r = sigma * sigma;
        let p = 0.5 * (qs + (qs * qs + 4.0 * qs * r).sqrt());
        let gain = p / (p + r);
        self.filter_memory_s = if gain > 0.0 { 1.0 / (gain * rate_hz) } else { f64::INFINITY };
    }

    /// The white level scaled to the data's: `s2_axis` are the whitened
    /// residual variances per axis of a fit with every vocabulary term (in
    /// units of this model's), so the data's white level is the model's times
    /// their square root; the level used is that of all axes together.
    pub fn scaled_to_data(&self, s2_axis: [f64; 3], rate_hz: f64) -> NoiseModel {
        let mut n = *self;
        n.sigma_data = s2_axis.map(|v| self.sigma_model * v.max(0.0).sqrt());
        let mean = s2_axis.iter().sum::<f64>() / 3.0;
        n.set_sigma(self.sigma_model * mean.max(1e-6).sqrt(), rate_hz);
        n
    }

    /// White-noise level of 1-s means, deg/s.
    pub fn floor_1s(&self, rate_hz: f64) -> f64 {
        self.sigma / rate_hz.sqrt()
    }
}

/// The Kalman filter of the local-level noise model as a linear map:
/// per sample its gain and 1/sqrt(innovation variance).
struct Whitener {
    gain: Vec<f64>,
    scale: Vec<f64>,
}

impl Whitener {
    fn new(t: &[f64], sigma: f64, q: f64) -> Whitener {
        let r = sigma * sigma;
        let q2 = q * q;
        let mut p = q2 * t.first().copied().unwrap_or(0.0).max(0.0);
        let mut gain = Vec::with_capacity(t.len());
        let mut scale = Vec::with_capacity(t.len());
        for k in 0..t.len() {
            let f = p + r;
            gain.push(p / f);
            scale.push(1.0 / f.sqrt());
            let next = if k + 1 < t.len() { (t[k + 1] - t[k]).max(0.0) } else { 0.0 };
            p = p * r / f + q2 * next;
        }
        Whitener { gain, scale }
    }

    /// Whiten `x` into `out`.
    fn apply(&self, x: impl Iterator<Item = f64>, out: &mut [f64]) {
        let mut level = 0.0;
        for (k, (v, o)) in x.zip(out.iter_mut()).enumerate() {
            let innov = v - level;
            *o = innov * self.scale[k];
            level += self.gain[k] * innov;
        }
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    // four accumulators: vectorises and keeps the sum accurate
    let mut s = [0.0; 4];
    let (ca, ra) = a.split_at(a.len() / 4 * 4);
    let (cb, rb) = b.split_at(ca.len());
    for (x, y) in ca.chunks_exact(4).zip(cb.chunks_exact(4)) {
        for i in 0..4 {
            s[i] += x[i] * y[i];
        }
    }
    let mut t = (s[0] + s[1]) + (s[2] + s[3]);
    for (x, y) in ra.iter().zip(rb) {
        t += x * y;
    }
    t
}

/// The whitened signals and their Gram matrix (the sufficient statistics of every fit).
pub(crate) struct Design {
    n: usize,
    white: Vec<f64>,
    wh: Whitener,
    t: Vec<f64>,
    gram: [[f64; NSIG]; NSIG],
    /// Warm-up column products (tau bits, products with the signals, with itself).
    warm: Vec<(u64, [f64; NSIG], f64)>,
}

/// A fitted model.
#[derive(Clone, Debug)]
pub(crate) struct Fit {
    pub terms: Vec<Term>,
    /// Warm-up time constant (NaN without a warm-up term).
    pub tau: f64,
    pub beta: Vec<f64>,
    /// `(X'X)^-1` of the whitened columns (the covariance for unit innovation variance).
    pub cov: DMatrix<f64>,
    /// Diagonal of `X'X` (for R^2).
    pub xtx_diag: Vec<f64>,
    /// Whitened residual sum of squares per axis.
    pub sse_axis: [f64; 3],
    /// Samples per axis.
    pub n: usize,
}

impl Fit {
    pub fn sse(&self) -> f64 {
        self.sse_axis.iter().sum()
    }

    fn params_on(&self, axis: usize) -> usize {
        self.terms.iter().filter(|t| t.axis == axis || t.axis == 3).count()
    }

    /// Whitened residual variance of an axis (1 when the noise model is right and nothing is missing).
    pub fn s2_axis(&self, axis: usize) -> f64 {
        self.sse_axis[axis] / (self.n as f64 - self.params_on(axis) as f64).max(1.0)
    }

    /// Whitened residual variance over all axes.
    pub fn s2(&self) -> f64 {
        self.sse() / (3.0 * self.n as f64 - self.terms.len() as f64).max(1.0)
    }

    /// Standard error of coefficient `k`, widened (never narrowed) by the whitened residual variance of its axes.
    pub fn se(&self, k: usize) -> f64 {
        let t = &self.terms[k];
        let s2 = if t.axis == 3 { self.s2() } else { self.s2_axis(t.axis) };
        (self.cov[(k, k)] * s2.max(1.0)).sqrt()
    }

    /// Coefficient over its standard error.
    pub fn t_stat(&self, k: usize) -> f64 {
        self.beta[k] / self.se(k)
    }

    /// R^2 of term `k`'s whitened regressor on the others'.
    pub fn r2(&self, k: usize) -> f64 {
        let d = self.xtx_diag[k];
        if d > 0.0 {
            (1.0 - 1.0 / (d * self.cov[(k, k)])).clamp(0.0, 1.0)
        } else {
            1.0
        }
    }

    pub fn index(&self, t: &Term) -> Option<usize> {
        self.terms.iter().position(|x| x == t)
    }

    pub fn coef(&self, t: &Term) -> f64 {
        self.index(t).map_or(0.0, |k| self.beta[k])
    }
}

/// Solve the normal equations (scaled to unit diagonal); None when (numerically) singular.
fn solve(a: &DMatrix<f64>, b: &DVector<f64>) -> Option<(DVector<f64>, DMatrix<f64>)> {
    let p = a.nrows();
    if p == 0 {
        return Some((DVector::zeros(0), DMatrix::zeros(0, 0)));
    }
    let d: Vec<f64> = (0..p).map(|i| if a[(i, i)] > 0.0 { 1.0 / a[(i, i)].sqrt() } else { 0.0 }).collect();
    if d.iter().any(|x| *x == 0.0 || !x.is_finite()) {
        return None;
    }
    let s = DMatrix::from_fn(p, p, |i, j| a[(i, j)] * d[i] * d[j]);
    let inv_s = s.cholesky()?.inverse();
    // 1 / (1 - R^2) beyond 1e10: collinear to working precision
    if (0..p).any(|i| !(inv_s[(i, i)].is_finite()) || inv_s[(i, i)] > 1e10) {
        return None;
    }
    let inv = DMatrix::from_fn(p, p, |i, j| inv_s[(i, j)] * d[i] * d[j]);
    let beta = &inv * b;
    Some((beta, inv))
}

impl Design {
    /// Whiten every signal of `s` with `noise` and form their Gram matrix.
    pub fn new(s: &Samples, noise: &NoiseModel) -> Design {
        let n = s.len();
        let wh = Whitener::new(&s.t, noise.sigma, noise.bias_walk);
        let mut white = vec![0.0; NSIG * n];
        for (sig, out) in white.chunks_exact_mut(n).enumerate() {
            wh.apply((0..n).map(|k| raw(s, sig, k)), out);
        }
        let mut gram = [[0.0; NSIG]; NSIG];
        for i in 0..NSIG {
            for j in i..NSIG {
                let v = dot(&white[i * n..(i + 1) * n], &white[j * n..(j + 1) * n]);
                gram[i][j] = v;
                gram[j][i] = v;
            }
        }
        Design { n, white, wh, t: s.t.clone(), gram, warm: Vec::new() }
    }

    /// Products of the whitened warm-up column of time constant `tau` (computed once per tau).
    fn warm_products(&mut self, tau: f64) -> usize {
        let key = tau.to_bits();
        if let Some(i) = self.warm.iter().position(|w| w.0 == key) {
            return i;
        }
        let n = self.n;
        let mut col = vec![0.0; n];
        self.wh.apply(self.t.iter().map(|t| (-t.max(0.0) / tau).exp()), &mut col);
        let mut prod = [0.0; NSIG];
        for (i, p) in prod.iter_mut().enumerate() {
            *p = dot(&col, &self.white[i * n..(i + 1) * n]);
        }
        let own = dot(&col, &col);
        self.warm.push((key, prod, own));
        self.warm.len() - 1
    }

    /// Product of two columns (`warm` indexes the warm-up products).
    fn g(&self, a: Col, b: Col, warm: Option<usize>) -> f64 {
        match (a, b) {
            (Col::Sig(i), Col::Sig(j)) => self.gram[i][j],
            (Col::Warm, Col::Sig(j)) | (Col::Sig(j), Col::Warm) => self.warm[warm.expect("warm-up products")].1[j],
            (Col::Warm, Col::Warm) => self.warm[warm.expect("warm-up products")].2,
        }
    }

    /// Fit `terms` (warm-up time constant `tau`). None when singular.
    pub fn fit(&mut self, terms: &[Term], tau: f64) -> Option<Fit> {
        let warm = if terms.iter().any(|t| t.effect == Effect::WarmupTransient) {
            if !(tau.is_finite() && tau > 0.0) {
                return None;
            }
            Some(self.warm_products(tau))
        } else {
            None
        };
        let p = terms.len();
        let mut a = DMatrix::zeros(p, p);
        let mut b = DVector::zeros(p);
        let cols: Vec<[Option<Col>; 3]> = terms.iter().map(|t| [t.col_on(0), t.col_on(1), t.col_on(2)]).collect();
        for ax in 0..3 {
            let y = Col::Sig(S_Y + ax);
            for i in 0..p {
                let Some(ci) = cols[i][ax] else { continue };
                b[i] += self.g(ci, y, warm);
                for j in i..p {
                    if let Some(cj) = cols[j][ax] {
                        a[(i, j)] += self.g(ci, cj, warm);
                    }
                }
            }
        }
        for i in 0..p {
            for j in 0..i {
                a[(i, j)] = a[(j, i)];
            }
        }
        let (beta, cov) = solve(&a, &b)?;
        let mut sse_axis = [0.0; 3];
        for (ax, s) in sse_axis.iter_mut().enumerate() {
            let y = Col::Sig(S_Y + ax);
            let mut v = self.gram[S_Y + ax][S_Y + ax];
            for i in 0..p {
                let Some(ci) = cols[i][ax] else { continue };
                v -= 2.0 * beta[i] * self.g(ci, y, warm);
                for j in 0..p {
                    if let Some(cj) = cols[j][ax] {
                        v += beta[i] * beta[j] * self.g(ci, cj, warm);
                    }
                }
            }
            *s = v.max(0.0);
        }
        Some(Fit {
            terms: terms.to_vec(),
            tau: if warm.is_some() { tau } else { f64::NAN },
            beta: beta.iter().copied().collect(),
            cov,
            xtx_diag: (0..p).map(|i| a[(i, i)]).collect(),
            sse_axis,
            n: self.n,
        })
    }

    /// Fit `terms` with a warm-up term whose time constant is not known:
    /// the best of the grid (`refine`: then a golden-section search around it).
    pub fn fit_search_tau(&mut self, terms: &[Term], refine: bool) -> Option<Fit> {
        let mut best: Option<Fit> = None;
        for tau in tau_grid() {
            if let Some(f) = self.fit(terms, tau) {
                if best.as_ref().is_none_or(|b| f.sse() < b.sse()) {
                    best = Some(f);
                }
            }
        }
        let b = best?;
        if !refine {
            return Some(b);
        }
        let step = (TAU_MAX_S / TAU_MIN_S).powf(1.0 / 20.0);
        let (mut lo, mut hi) = ((b.tau / step).max(TAU_MIN_S).ln(), (b.tau * step).min(TAU_MAX_S).ln());
        let g = 0.618_033_988_75;
        let mut fb = b;
        for _ in 0..14 {
            let m1 = hi - g * (hi - lo);
            let m2 = lo + g * (hi - lo);
            let f1 = self.fit(terms, m1.exp());
            let f2 = self.fit(terms, m2.exp());
            let s1 = f1.as_ref().map_or(f64::INFINITY, |f| f.sse());
            let s2 = f2.as_ref().map_or(f64::INFINITY, |f| f.sse());
            let better = if s1 < s2 {
                hi = m2;
                f1
            } else {
                lo = m1;
                f2
            };
            if let Some(f) = better {
                if f.sse() < fb.sse() {
                    fb = f;
                }
            }
        }
        Some(fb)
    }

    /// Approximate 95 % interval of the warm-up time constant of `fit`: the
    /// time constants whose best fit raises the whitened residual sum of
    /// squares by at most 4 (times the residual variance when above 1) over
    /// the best, scanned on a log grid of +-3x (clipped to the search range).
    pub fn tau_interval(&mut self, fit: &Fit) -> (f64, f64) {
        let limit = fit.sse() + 4.0 * fit.s2().max(1.0);
        let (mut lo, mut hi) = (fit.tau, fit.tau);
        for k in 1..=60 {
            let t = fit.tau * 3f64.powf(-(k as f64) / 60.0);
            if t < TAU_MIN_S || self.fit(&fit.terms, t).is_none_or(|f| f.sse() > limit) {
                break;
            }
            lo = t;
        }
        for k in 1..=60 {
            let t = fit.tau * 3f64.powf(k as f64 / 60.0);
            if t > TAU_MAX_S || self.fit(&fit.terms, t).is_none_or(|f| f.sse() > limit) {
                break;
            }
            hi = t;
        }
        (lo, hi)
    }

    /// Fit `terms`: with the time constant `tau` when it is known (finite),
    /// searched when the terms have a warm-up and it is not.
    pub fn fit_any(&mut self, terms: &[Term], tau: f64, refine: bool) -> Option<Fit> {
        if terms.iter().any(|t| t.effect == Effect::WarmupTransient) && !tau.is_finite() {
            self.fit_search_tau(terms, refine)
        } else {
            self.fit(terms, tau)
        }
    }
}

/// The residual `y - X beta` of a fit at every sample (not whitened), per axis, deg/s.
pub(crate) fn residual(s: &Samples, fit: &Fit) -> [Vec<f64>; 3] {
    let mut r = [s.y[0].clone(), s.y[1].clone(), s.y[2].clone()];
    let warm: Vec<f64> = if fit.tau.is_finite() { s.t.iter().map(|t| (-t.max(0.0) / fit.tau).exp()).collect() } else { Vec::new() };
    for (ax, ra) in r.iter_mut().enumerate() {
        for (k, term) in fit.terms.iter().enumerate() {
            let c = fit.beta[k];
            match term.col_on(ax) {
                None => {}
                Some(Col::Warm) => ra.iter_mut().zip(&warm).for_each(|(x, w)| *x -= c * w),
                Some(Col::Sig(sig)) => {
                    for (i, x) in ra.iter_mut().enumerate() {
                        *x -= c * raw(s, sig, i);
                    }
                }
            }
        }
    }
    r
}

/// RMS over the samples of what `coef` times a term's regressor adds on its
/// axes (the largest over the axes for the shared delay), deg/s.
pub(crate) fn contribution_rms(s: &Samples, term: &Term, tau: f64, coef: f64) -> f64 {
    let n = s.len().max(1) as f64;
    term.axes()
        .iter()
        .map(|&a| {
            let ss: f64 = match term.col_on(a) {
                None => 0.0,
                Some(Col::Warm) => s.t.iter().map(|t| (coef * (-t.max(0.0) / tau).exp()).powi(2)).sum(),
                Some(Col::Sig(sig)) => (0..s.len()).map(|k| (coef * raw(s, sig, k)).powi(2)).sum(),
            };
            (ss / n).sqrt()
        })
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The whitening filter is the GLS transform: with white noise only it is a
    /// scaling; with a random walk, the innovations of a pure random walk plus white
    /// noise have unit variance.
    #[test]
    fn whitened_noise_has_unit_variance() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let n = 200_000;
        let rate = 200.0;
        let t: Vec<f64> = (0..n).map(|k| k as f64 / rate).collect();
        let (sigma, q) = (0.1, 0.01);
        let mut b = 0.0;
        let mut y = Vec::with_capacity(n);
        for k in 0..n {
            if k > 0 {
                b += q * (1.0 / rate).sqrt() * rng.sample::<f64, _>(rand_distr::StandardNormal);
            }
            y.push(b + sigma * rng.sample::<f64, _>(rand_distr::StandardNormal));
        }
        let w = Whitener::new(&t, sigma, q);
        let mut out = vec![0.0; n];
        w.apply(y.iter().copied(), &mut out);
        let var = out.iter().map(|v| v * v).sum::<f64>() / n as f64;
        assert!((var - 1.0).abs() < 0.02, "{var}");
        // lag-1 autocorrelation ~0 (the raw noise' first differences would have -0.5)
        let c1 = out.windows(2).map(|p| p[0] * p[1]).sum::<f64>() / n as f64;
        assert!(c1.abs() < 0.01, "{c1}");
        // the same data read as white noise only: innovations are far from unit variance
        let w0 = Whitener::new(&t, sigma, 0.0);
        w0.apply(y.iter().copied(), &mut out);
        let var0 = out.iter().map(|v| v * v).sum::<f64>() / n as f64;
        assert!(var0 > 2.0, "{var0}");
    }
}
