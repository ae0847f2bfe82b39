//! Generalised least squares when the residuals are a bias random walk plus
//! white noise (steps 5 to 8 of the module documentation use it).
//!
//! Within a run, the residual of the 1-s means is `w_j + e_j`: `w` a random
//! walk (variance `q` per second) that is 0 at the run's first row (its level
//! there is the run's own constant), `e` white with variance `s^2 r_j`
//! (`r_j = 1` for a full bin). The covariance is `s^2 (R + lam D)` with
//! `lam = q / s^2` and `D_jk = min(t_j, t_k) - t_first`. The Kalman filter of
//! that local-level model maps any column to its innovations divided by their
//! standard deviations: a fixed linear map `L^-1` with `L L^T = R + lam D`, so
//! ordinary least squares on the mapped ("whitened") columns is the GLS
//! estimate, and `log det(R + lam D) = sum_j log F_j`. `lam` is chosen by
//! restricted maximum likelihood (REML), `s^2` concentrated out.
//!
//! With a **shared level** (`Design::shared_level`) the runs have one
//! constant, and each run's own level is random: a turn-on offset of
//! variance `s^2 mu` at power-on, then the walk from power-on on. The
//! Kalman filter then starts each run at variance `mu + lam t_first`
//! instead of at 0. `mu` is chosen by REML too: when the runs' levels agree
//! with one thermal curve (as far as their walks allow) the levels carry the
//! curve's information between ambients; when they differ (`mu` large) the
//! fit reduces to the per-run constants.

use nalgebra::DMatrix;

/// The rows of one run that take part in a fit, in time order.
#[derive(Clone, Debug, Default)]
pub(crate) struct Rows {
    /// Seconds since power-on.
    pub t: Vec<f64>,
    /// `(T - t0) / scale`.
    pub u: Vec<f64>,
    pub y: Vec<[f64; 3]>,
    /// Relative white-noise variance (median samples per bin / samples in this bin).
    pub r: Vec<f64>,
}

impl Rows {
    pub fn len(&self) -> usize {
        self.t.len()
    }
}

/// The Kalman filter's gains for one run at one `lam`: applying it to a
/// column whitens it.
pub(crate) struct Whitener {
    k: Vec<f64>,
    w: Vec<f64>,
    /// `log det(R + lam D)` of the run.
    pub log_det: f64,
}

impl Whitener {
    /// `mu`: None for a run with its own constant (the walk from 0 at the
    /// first row); `Some(mu)` for a shared level (variance `mu` at power-on,
    /// plus the walk until the first row).
    pub fn new(rows: &Rows, lam: f64, mu: Option<f64>) -> Whitener {
        let n = rows.len();
        let (mut k, mut w) = (Vec::with_capacity(n), Vec::with_capacity(n));
        let mut p = match (mu, rows.t.first()) {
            (Some(m), Some(&t0)) => m + lam * t0.max(0.0),
            _ => 0.0,
        };
        let mut log_det = 0.0f64;
        for j in 0..n {
            if j > 0 {
                p += lam * (rows.t[j] - rows.t[j - 1]).max(0.0);
            }
            let f = p + rows.r[j];
            k.push(p / f);
            w.push(1.0 / f.sqrt());
            log_det += f.ln();
            p *= rows.r[j] / f;
        }
        Whitener { k, w, log_det }
    }

    pub fn apply(&self, z: impl Iterator<Item = f64>) -> Vec<f64> {
        let mut m = 0.0;
        let mut out = Vec::with_capacity(self.k.len());
        for (j, zj) in z.enumerate() {
            let v = zj - m;
            out.push(v * self.w[j]);
            m += self.k[j] * v;
        }
        out
    }
}

/// A column of a design evaluated on one run's rows.
#[derive(Clone, Copy, Debug)]
enum Col {
    One,
    /// `u^k`, k >= 1.
    Poly(usize),
    /// `exp(-t / tau)`.
    Exp(f64),
}

fn eval(c: Col, rows: &Rows, j: usize) -> f64 {
    match c {
        Col::One => 1.0,
        Col::Poly(k) => rows.u[j].powi(k as i32),
        Col::Exp(tau) => (-rows.t[j] / tau).exp(),
    }
}

/// One run's columns: (global column index, values on its rows).
type RunColumns = Vec<(usize, Vec<f64>)>;

/// Columns: one constant per run (or one for all with a shared level), then
/// the shared polynomial `u^1..u^order`, then per run (in run order) its
/// transient `exp(-t / tau)` when it has one and its own extra slope `u`
/// when asked for.
pub(crate) struct Design<'a> {
    pub runs: &'a [Rows],
    pub order: usize,
    /// One constant for all runs, each run's level random (fit with `mu`).
    pub shared_level: bool,
    pub taus: Vec<Option<f64>>,
    pub own_slope: Vec<bool>,
    /// Per run: (global column, values on the rows), computed on first use
    /// (set `taus` and `own_slope` before fitting).
    values: std::cell::OnceCell<Vec<RunColumns>>,
}

impl<'a> Design<'a> {
    pub fn new(runs: &'a [Rows], order: usize) -> Design<'a> {
        Design {
            runs,
            order,
            shared_level: false,
            taus: vec![None; runs.len()],
            own_slope: vec![false; runs.len()],
            values: Default::default(),
        }
    }

    /// The design with one constant for all runs (set before fitting).
    pub fn shared(runs: &'a [Rows], order: usize) -> Design<'a> {
        Design { shared_level: true, ..Design::new(runs, order) }
    }

    /// Columns before the polynomial: the runs' constants, or the one shared.
    fn levels(&self) -> usize {
        if self.shared_level {
            1
        } else {
            self.runs.len()
        }
    }

    /// Global column of `u^k` (k >= 1).
    pub fn poly_col(&self, k: usize) -> usize {
        self.levels() + k - 1
    }

    fn values(&self) -> &Vec<RunColumns> {
        self.values.get_or_init(|| {
            self.runs
                .iter()
                .enumerate()
                .map(|(r, rows)| {
                    self.columns(r).into_iter().map(|(g, c)| (g, (0..rows.len()).map(|j| eval(c, rows, j)).collect())).collect()
                })
                .collect()
        })
    }

    /// (global column, column) of every column that is not zero on run `r`.
    fn columns(&self, r: usize) -> Vec<(usize, Col)> {
        let r_n = self.runs.len();
        let l_n = self.levels();
        let mut v = vec![(if self.shared_level { 0 } else { r }, Col::One)];
        v.extend((0..self.order).map(|k| (l_n + k, Col::Poly(k + 1))));
        let mut c = l_n + self.order;
        for q in 0..r_n {
            if let Some(tau) = self.taus[q] {
                if q == r {
                    v.push((c, Col::Exp(tau)));
                }
                c += 1;
            }
            if self.own_slope[q] {
                if q == r {
                    v.push((c, Col::Poly(1)));
                }
                c += 1;
            }
        }
        v
    }

    pub fn p(&self) -> usize {
        self.levels() + self.order + self.taus.iter().filter(|t| t.is_some()).count() + self.own_slope.iter().filter(|s| **s).count()
    }

    /// Global column of run `r`'s transient, and of its own slope.
    pub fn extra_cols(&self, r: usize) -> (Option<usize>, Option<usize>) {
        let mut tr = None;
        let mut sl = None;
        for (g, c) in self.columns(r).into_iter().skip(1 + self.order) {
            match c {
                Col::Exp(_) => tr = Some(g),
                _ => sl = Some(g),
            }
        }
        (tr, sl)
    }
}

/// A GLS fit of one axis.
pub(crate) struct AxisGls {
    pub beta: Vec<f64>,
    /// `(X~^T X~)^-1`.
    pub inv: DMatrix<f64>,
    /// Whitened residual sum of squares.
    pub rss: f64,
    pub n: usize,
    pub p: usize,
    pub log_det_v: f64,
    pub log_det_xtx: f64,
    /// Lag-1 autocorrelation of the whitened residuals (pooled over runs).
    pub rho: f64,
    /// Sum of squared plain residuals `y - X beta`.
    pub raw_ss: f64,
}

impl AxisGls {
    /// `s^2`: white-noise variance of a full 1-s bin.
    pub fn s2(&self) -> f64 {
        self.rss / (self.n.saturating_sub(self.p)).max(1) as f64
    }
    /// Standard error of coefficient `c`.
    pub fn se(&self, c: usize) -> f64 {
        (self.s2() * self.inv[(c, c)]).sqrt()
    }
    /// `-2 log` restricted likelihood, up to a constant.
    pub fn reml(&self) -> f64 {
        let dof = self.n.saturating_sub(self.p);
        if dof == 0 || self.rss.is_nan() || self.rss <= 0.0 {
            return f64::INFINITY;
        }
        dof as f64 * self.rss.ln() + self.log_det_v + self.log_det_xtx
    }
}

/// Solve the normal equations by a Cholesky factor of the matrix scaled to a
/// unit diagonal. Returns (beta, inverse, log det of the unscaled matrix);
/// None when singular or nearly so.
pub(crate) fn solve(xtx: &DMatrix<f64>, xty: &[f64]) -> Option<(Vec<f64>, DMatrix<f64>, f64)> {
    let p = xtx.nrows();
    let d: Vec<f64> = (0..p).map(|a| if xtx[(a, a)] > 0.0 && xtx[(a, a)].is_finite() { 1.0 / xtx[(a, a)].sqrt() } else { 0.0 }).collect();
    if d.contains(&0.0) {
        return None;
    }
    let ms = DMatrix::from_fn(p, p, |a, b| xtx[(a, b)] * d[a] * d[b]);
    let ch = ms.cholesky()?;
    let log_det_s: f64 = (0..p).map(|a| 2.0 * ch.l_dirty()[(a, a)].ln()).sum();
    let inv_s = ch.inverse();
    if !(0..p).all(|a| inv_s[(a, a)].is_finite() && inv_s[(a, a)] < 1e12) {
        return None;
    }
    let inv = DMatrix::from_fn(p, p, |a, b| inv_s[(a, b)] * d[a] * d[b]);
    let beta: Vec<f64> = (0..p).map(|a| (0..p).map(|b| inv[(a, b)] * xty[b]).sum()).collect();
    let log_det = log_det_s - 2.0 * d.iter().map(|v| v.ln()).sum::<f64>();
    Some((beta, inv, log_det))
}

/// GLS of axis `axis` under design `d` at `lam`. None when the design is singular.
pub(crate) fn fit_axis(d: &Design<'_>, axis: usize, lam: f64) -> Option<AxisGls> {
    fit_axis_mu(d, axis, lam, 0.0)
}

/// [`fit_axis`] with the shared level's `mu` (unused for per-run constants).
pub(crate) fn fit_axis_mu(d: &Design<'_>, axis: usize, lam: f64, mu: f64) -> Option<AxisGls> {
    let mu = d.shared_level.then_some(mu);
    let p = d.p();
    let mut xtx = DMatrix::zeros(p, p);
    let mut xty = vec![0.0; p];
    let mut log_det_v = 0.0;
    let mut n = 0;
    let mut white: Vec<(RunColumns, Vec<f64>)> = Vec::with_capacity(d.runs.len());
    for (r, rows) in d.runs.iter().enumerate() {
        if rows.len() == 0 {
            white.push((Vec::new(), Vec::new()));
            continue;
        }
        let wh = Whitener::new(rows, lam, mu);
        log_det_v += wh.log_det;
        n += rows.len();
        let cols: RunColumns = d.values()[r].iter().map(|(g, v)| (*g, wh.apply(v.iter().copied()))).collect();
        let y = wh.apply(rows.y.iter().map(|v| v[axis]));
        for (a, (ga, ca)) in cols.iter().enumerate() {
            for (gb, cb) in &cols[a..] {
                let s: f64 = ca.iter().zip(cb).map(|(x, z)| x * z).sum();
                xtx[(*ga, *gb)] += s;
                if ga != gb {
                    xtx[(*gb, *ga)] += s;
                }
            }
            xty[*ga] += ca.iter().zip(&y).map(|(x, z)| x * z).sum::<f64>();
        }
        white.push((cols, y));
    }
    if n <= p {
        return None;
    }
    let (beta, inv, log_det_xtx) = solve(&xtx, &xty)?;
    let (mut rss, mut lag, mut raw_ss) = (0.0, 0.0, 0.0);
    for (r, (cols, y)) in white.iter().enumerate() {
        let mut prev: Option<f64> = None;
        for j in 0..y.len() {
            let e = y[j] - cols.iter().map(|(g, c)| beta[*g] * c[j]).sum::<f64>();
            rss += e * e;
            if let Some(pv) = prev {
                lag += e * pv;
            }
            prev = Some(e);
        }
        let rows = &d.runs[r];
        let raw_cols = &d.values()[r];
        for j in 0..rows.len() {
            let m: f64 = raw_cols.iter().map(|(g, v)| beta[*g] * v[j]).sum();
            raw_ss += (rows.y[j][axis] - m).powi(2);
        }
    }
    let rho = if rss > 0.0 { lag / rss } else { 0.0 };
    Some(AxisGls { beta, inv, rss, n, p, log_det_v, log_det_xtx, rho, raw_ss })
}

/// `lam` grid for the REML search: 0 and 10^-9 .. 10^2, one point a decade.
pub(crate) const LAM_LOG10: (f64, f64) = (-9.0, 2.0);
/// Golden-section steps within +-1 decade of the best grid point (to 0.001 decade).
const GOLDEN_STEPS: usize = 16;

/// REML estimate of `lam = q / s^2` for one axis: the coarse grid, then a
/// golden-section search (in log10) around its best point.
pub(crate) fn reml_lambda(d: &Design<'_>, axis: usize) -> f64 {
    minimise_log10(LAM_LOG10, |v| reml_at(d, axis, v, 0.0))
}

/// `-2 log` restricted likelihood of axis `axis` at `(lam, mu)`; infinite
/// when the design is singular there.
pub(crate) fn reml_at(d: &Design<'_>, axis: usize, lam: f64, mu: f64) -> f64 {
    fit_axis_mu(d, axis, lam, mu).map(|g| g.reml()).unwrap_or(f64::INFINITY)
}

/// `mu` grid (relative to `s^2`): 0 and 10^-3 .. 10^8, one point a decade.
const MU_LOG10: (f64, f64) = (-3.0, 8.0);
/// Rounds of the alternating search over `lam` and `mu`.
const SHARED_ROUNDS: usize = 2;

/// REML estimates `(lam, mu)` of a shared-level design for one axis, by
/// alternating 1-D searches from the per-run constants' `lam0`.
pub(crate) fn reml_shared(d: &Design<'_>, axis: usize, lam0: f64) -> (f64, f64) {
    let (mut lam, mut mu) = (lam0, 0.0);
    for _ in 0..SHARED_ROUNDS {
        mu = minimise_log10(MU_LOG10, |m| reml_at(d, axis, lam, m));
        lam = minimise_log10(LAM_LOG10, |l| reml_at(d, axis, l, mu));
    }
    (lam, mu)
}

/// The largest `mu` whose restricted likelihood (at `lam`) is within
/// `chi2` (on the `-2 log` scale) of `best`, the REML at the estimate `mu`:
/// the upper end of `mu`'s profile interval, found by bisection in log10 up
/// to the grid's end.
pub(crate) fn mu_upper(d: &Design<'_>, axis: usize, lam: f64, mu: f64, best: f64, chi2: f64) -> f64 {
    upper_log10(MU_LOG10, mu, |m| reml_at(d, axis, lam, m) - best <= chi2)
}

/// The largest walk-to-white ratio `lam` whose restricted likelihood (at
/// `mu`) is within `chi2` of `best`, the REML at the estimate `lam`: the
/// upper end of the walk's profile interval (up to the grid's end). What a
/// time jump's walk may be when a few short stretches barely say.
pub(crate) fn lam_upper(d: &Design<'_>, axis: usize, lam: f64, mu: f64, best: f64, chi2: f64) -> f64 {
    upper_log10(LAM_LOG10, lam, |l| reml_at(d, axis, l, mu) - best <= chi2)
}

/// Bisection in log10 between the estimate `from` and the end of `range`
/// for the largest value that `within` accepts.
fn upper_log10(range: (f64, f64), from: f64, within: impl Fn(f64) -> bool) -> f64 {
    let top = 10f64.powf(range.1);
    if within(top) {
        return top;
    }
    let (mut a, mut b) = (if from > 0.0 { from.log10() } else { range.0 - 3.0 }, range.1);
    for _ in 0..30 {
        let c = 0.5 * (a + b);
        if within(10f64.powf(c)) {
            a = c;
        } else {
            b = c;
        }
    }
    10f64.powf(a)
}

fn minimise_log10(range: (f64, f64), f: impl Fn(f64) -> f64) -> f64 {
    let g10 = |l10: f64| f(10f64.powf(l10));
    let steps = (range.1 - range.0).round() as usize;
    let grid: Vec<f64> = (0..=steps).map(|k| range.0 + k as f64).collect();
    let vals: Vec<f64> = grid.iter().map(|&g| g10(g)).collect();
    let zero = f(0.0);
    let (kb, vb) = vals.iter().enumerate().fold((0, f64::INFINITY), |(kb, vb), (k, &v)| if v < vb { (k, v) } else { (kb, vb) });
    if !vb.is_finite() || zero <= vb {
        return 0.0;
    }
    let (mut a, mut b) = (grid[kb] - 1.0, grid[kb] + 1.0);
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let (mut c, mut e) = (b - g * (b - a), a + g * (b - a));
    let (mut fc, mut fe) = (g10(c), g10(e));
    for _ in 0..GOLDEN_STEPS {
        if fc < fe {
            b = e;
            e = c;
            fe = fc;
            c = b - g * (b - a);
            fc = g10(c);
        } else {
            a = c;
            c = e;
            fc = fe;
            e = a + g * (b - a);
            fe = g10(e);
        }
    }
    let (l, v) = if fc < fe { (c, fc) } else { (e, fe) };
    if v <= vb {
        10f64.powf(l)
    } else {
        10f64.powf(grid[kb])
    }
}

/// Precomputed whitened cross products for the search over the runs'
/// transient time constants (one design per combination would be slow):
/// per axis, per run, the Gram matrix of `[1, u^1..u^order, y]` and, for
/// every candidate `tau`, its column's products with those and itself.
/// One run's products for one axis: the Gram matrix of `[1, u^1..u^order, y]`
/// and, per candidate `tau`, its column's products with those and with itself.
struct RunPieces {
    base: DMatrix<f64>,
    exps: Vec<(Vec<f64>, f64)>,
}

pub(crate) struct TauSearch {
    order: usize,
    /// [axis][run]
    pieces: Vec<Vec<RunPieces>>,
}

impl TauSearch {
    pub fn new(runs: &[Rows], order: usize, lams: [f64; 3], grids: &[Vec<f64>]) -> TauSearch {
        let nb = order + 2;
        let pieces = (0..3)
            .map(|axis| {
                runs.iter()
                    .zip(grids)
                    .map(|(rows, grid)| {
                        let wh = Whitener::new(rows, lams[axis], None);
                        let n = rows.len();
                        let mut base: Vec<Vec<f64>> = vec![wh.apply(std::iter::repeat_n(1.0, n))];
                        for k in 1..=order {
                            base.push(wh.apply(rows.u.iter().map(|u| u.powi(k as i32))));
                        }
                        base.push(wh.apply(rows.y.iter().map(|v| v[axis])));
                        let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, z)| x * z).sum::<f64>();
                        let g = DMatrix::from_fn(nb, nb, |a, b| dot(&base[a], &base[b]));
                        let ex = grid
                            .iter()
                            .map(|&tau| {
                                let e = wh.apply(rows.t.iter().map(|t| (-t / tau).exp()));
                                (base.iter().map(|b| dot(&e, b)).collect(), dot(&e, &e))
                            })
                            .collect();
                        RunPieces { base: g, exps: ex }
                    })
                    .collect()
            })
            .collect();
        TauSearch { order, pieces }
    }

    /// Sum over the axes of log RSS with run `r`'s transient at candidate `choice[r]`.
    pub fn objective(&self, choice: &[usize]) -> f64 {
        let o = self.order;
        let r_n = choice.len();
        let p = 2 * r_n + o;
        let mut total = 0.0;
        for axis in 0..3 {
            let mut xtx = DMatrix::zeros(p, p);
            let mut xty = vec![0.0; p];
            let mut yty = 0.0;
            for (r, RunPieces { base: g, exps: ex }) in self.pieces[axis].iter().enumerate() {
                let gi = |a: usize| if a == 0 { r } else { r_n + a - 1 };
                for a in 0..=o {
                    for b in 0..=o {
                        xtx[(gi(a), gi(b))] += g[(a, b)];
                    }
                    xty[gi(a)] += g[(a, o + 1)];
                }
                yty += g[(o + 1, o + 1)];
                let (dots, ee) = &ex[choice[r]];
                let c = r_n + o + r;
                xtx[(c, c)] += ee;
                for a in 0..=o {
                    xtx[(c, gi(a))] += dots[a];
                    xtx[(gi(a), c)] += dots[a];
                }
                xty[c] += dots[o + 1];
            }
            match solve(&xtx, &xty) {
                Some((beta, _, _)) => {
                    let rss = yty - beta.iter().zip(&xty).map(|(b, v)| b * v).sum::<f64>();
                    total += rss.max(1e-300).ln();
                }
                None => return f64::INFINITY,
            }
        }
        total
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The whitening map is L^-1 with L L^T = R + lam D: check against the
    /// covariance built directly, on uneven times and weights.
    #[test]
    fn whitener_inverts_the_random_walk_covariance() {
        let t = [0.5, 1.5, 2.5, 4.5, 5.5, 9.0];
        let r = [1.0, 1.0, 2.0, 1.0, 1.5, 1.0];
        let rows = Rows { t: t.to_vec(), u: vec![0.0; 6], y: vec![[0.0; 3]; 6], r: r.to_vec() };
        let lam = 0.3;
        let wh = Whitener::new(&rows, lam, None);
        let n = t.len();
        let v = DMatrix::from_fn(n, n, |a, b| if a == b { r[a] } else { 0.0 } + lam * (t[a.min(b)] - t[0]));
        // whiten the identity: W = L^-1, then W V W^T must be I
        let mut w = DMatrix::zeros(n, n);
        for c in 0..n {
            let col = wh.apply((0..n).map(|j| if j == c { 1.0 } else { 0.0 }));
            for j in 0..n {
                w[(j, c)] = col[j];
            }
        }
        let id = &w * &v * w.transpose();
        for a in 0..n {
            for b in 0..n {
                let want = if a == b { 1.0 } else { 0.0 };
                assert!((id[(a, b)] - want).abs() < 1e-12, "({a},{b}) {}", id[(a, b)]);
            }
        }
        let ld = v.clone().cholesky().unwrap().l().diagonal().iter().map(|x| 2.0 * x.ln()).sum::<f64>();
        assert!((wh.log_det - ld).abs() < 1e-12);
    }
}
