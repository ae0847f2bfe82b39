//! The core filter: the nominal state (attitude, gyro bias, velocity, the
//! wheel-speed scale error), the error state's covariance, the error
//! accumulated by the updates of a tick, and the numerics that change them:
//! the propagation with the transition accumulated between ticks, the
//! scalar update with its innovation gate, the injection of the error into
//! the state.
//!
//! Its fields are its own: the aid sources, the classifiers and the
//! recovery rules read them through the accessors and change them only
//! through the methods here, each named for what it does to the filter
//! (widen a variance, cut a correlation, set the velocity a hypothesis
//! gives). The quaternion's matrix is kept with it: no one can set one
//! without the other.

use super::{AidStatus, Gain, Why, BI, N, SC, TH, VE};
use crate::estimator::quat::{self, rotate, Mat3, Quat};

/// State and covariance as values (see the module's doc).
#[derive(Clone, Debug)]
pub(in crate::estimator::mekf) struct Core {
    q: Quat,
    /// `q` as a matrix (body to navigation), refreshed with every change.
    c: Mat3,
    /// Bias, rad/s.
    bias: [f64; 3],
    /// Velocity (NED, m/s).
    v: [f64; 3],
    scale: f64,
    cov: [[f64; N]; N],
    dx: [f64; N],
    /// The scale error is a state (a wheel speed is configured).
    with_scale: bool,
    /// While scoring: the log-likelihood of every scored update since
    /// scoring started (`-(min(NIS, gate) + ln S) / 2` each), for comparing
    /// power-on hypotheses (`super::super::hypotheses`).
    scoring: bool,
    log_likelihood: f64,
}

/// The process noise of one tick (variances over the tick), built by the
/// filter from what the tick saw (`Mekf::propagate`): added to the diagonal
/// of the attitude, bias and scale rows, and to the velocity's block.
pub(in crate::estimator::mekf) struct ProcessNoise {
    pub theta: [f64; 3],
    pub bias: f64,
    pub v: Mat3,
    pub scale: f64,
}

impl Core {
    pub fn new(with_scale: bool) -> Core {
        let q = [1.0, 0.0, 0.0, 0.0];
        Core {
            q,
            c: quat::to_matrix(&q),
            bias: [0.0; 3],
            v: [0.0; 3],
            scale: 0.0,
            cov: [[0.0; N]; N],
            dx: [0.0; N],
            with_scale,
            scoring: false,
            log_likelihood: 0.0,
        }
    }

    #[inline]
    pub fn q(&self) -> &Quat {
        &self.q
    }

    #[inline]
    pub fn c(&self) -> &Mat3 {
        &self.c
    }

    #[inline]
    pub fn bias(&self) -> &[f64; 3] {
        &self.bias
    }

    #[inline]
    pub fn v(&self) -> &[f64; 3] {
        &self.v
    }

    #[inline]
    pub fn scale(&self) -> f64 {
        self.scale
    }

    #[inline]
    pub fn cov(&self) -> &[[f64; N]; N] {
        &self.cov
    }

    pub fn scoring(&self) -> bool {
        self.scoring
    }

    pub fn log_likelihood(&self) -> f64 {
        self.log_likelihood
    }

    /// Start or stop accumulating the log-likelihood (cleared when started).
    pub fn set_scoring(&mut self, on: bool) {
        self.scoring = on;
        if on {
            self.log_likelihood = 0.0;
        }
    }

    /// The state at power-on (and at a restart): the attitude given, the
    /// bias, the velocity zero, no scale error; the covariance diagonal
    /// with these variances and no correlation.
    pub fn reset(&mut self, q: Quat, bias: [f64; 3], var: &[f64; N]) {
        self.set_attitude(q);
        self.bias = bias;
        self.v = [0.0; 3];
        self.scale = 0.0;
        self.cov = [[0.0; N]; N];
        for (i, v) in var.iter().enumerate() {
            self.cov[i][i] = *v;
        }
    }

    /// The attitude set outright (a re-levelling, a restart).
    pub fn set_attitude(&mut self, q: Quat) {
        self.q = q;
        self.c = quat::to_matrix(&self.q);
    }

    /// Turn the attitude by the bias-corrected rate `w` (rad/s) over `dt`,
    /// renormalise the quaternion and refresh its matrix.
    pub fn integrate_attitude(&mut self, w: &[f64; 3], dt: f64) {
        let dq = quat::from_rotvec(&[w[0] * dt, w[1] * dt, w[2] * dt]);
        self.q = quat::mul(&self.q, &dq);
        // first-order renormalisation: |q| stays within 1e-15 of 1
        let n2 = self.q[0] * self.q[0] + self.q[1] * self.q[1] + self.q[2] * self.q[2] + self.q[3] * self.q[3];
        let k = 1.5 - 0.5 * n2;
        for v in self.q.iter_mut() {
            *v *= k;
        }
        self.c = quat::to_matrix(&self.q);
    }

    /// The velocity over one sample: the specific force `f` (navigation
    /// frame, in units of `gl`) plus gravity, over `dt`.
    pub fn integrate_velocity(&mut self, f: &[f64; 3], gl: f64, dt: f64) {
        for i in 0..3 {
            self.v[i] += f[i] * gl * dt;
        }
        self.v[2] += gl * dt;
    }

    /// The velocity changed by `d` (m/s): a lever arm's turn, say.
    pub fn add_velocity(&mut self, d: &[f64; 3]) {
        for i in 0..3 {
            self.v[i] += d[i];
        }
    }

    /// The velocity set outright (zero for a free unit, a re-levelled one,
    /// a speed hypothesis).
    pub fn set_velocity(&mut self, v: [f64; 3]) {
        self.v = v;
    }

    /// The bias moved by `d` (rad/s): the thermal curve's change.
    pub fn add_bias(&mut self, d: &[f64; 3]) {
        for i in 0..3 {
            self.bias[i] += d[i];
        }
    }

    /// The bias set outright (a re-levelling's, the prior's).
    pub fn set_bias(&mut self, b: [f64; 3]) {
        self.bias = b;
    }

    /// One error-state variance set outright.
    pub fn set_var(&mut self, i: usize, var: f64) {
        self.cov[i][i] = var;
    }

    /// One error-state variance at least `var`.
    pub fn floor_var(&mut self, i: usize, var: f64) {
        self.cov[i][i] = self.cov[i][i].max(var);
    }

    /// `var` added to the covariance's entry `(i, j)` alone: a widening
    /// made of symmetric pieces adds both `(i, j)` and `(j, i)`.
    pub fn add_cov(&mut self, i: usize, j: usize, var: f64) {
        self.cov[i][j] += var;
    }

    /// The velocity's 3x3 block set outright (a speed hypothesis).
    pub fn set_velocity_cov(&mut self, m: &Mat3) {
        for i in 0..3 {
            for j in 0..3 {
                self.cov[VE + i][VE + j] = m[i][j];
            }
        }
    }

    /// Clear the error accumulated by this tick's updates (a new tick).
    pub fn clear_dx(&mut self) {
        self.dx = [0.0; N];
    }

    /// The error accumulated on these rows dropped (a velocity set anew).
    pub fn drop_dx(&mut self, rows: &[usize]) {
        for &i in rows {
            self.dx[i] = 0.0;
        }
    }

    /// The whole error replaced by a tilt error `(dθ_x, dθ_y)`, to inject:
    /// a re-levelling's turn.
    pub fn set_tilt_error(&mut self, dx: f64, dy: f64) {
        self.dx = [0.0; N];
        self.dx[TH] = dx;
        self.dx[TH + 1] = dy;
    }

    /// `P = Φ P Φ^T + Q` with `Φ = [[I, A, 0, 0], [0, I, 0, 0], [B, D, I, 0], [0, 0, 0, 1]]`,
    /// `A = -Σ C dt` (`s_c`), `B = -[Σ C f dt ×]` (`dv`), `D ≈ B A / 2`.
    pub fn propagate(&mut self, s_c: &Mat3, dv: &[f64; 3], q: &ProcessNoise) {
        let mut am = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                am[i][j] = -s_c[i][j];
            }
        }
        let d = dv;
        // B = -[d×]
        let bm = [[0.0, d[2], -d[1]], [-d[2], 0.0, d[0]], [d[1], -d[0], 0.0]];
        let mut dm = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                dm[i][j] = 0.5 * (bm[i][0] * am[0][j] + bm[i][1] * am[1][j] + bm[i][2] * am[2][j]);
            }
        }
        // In place: M = Φ P changes the θ and v rows only, and the v rows
        // read the θ rows before these change; P' = M Φ^T likewise by columns.
        let p = &mut self.cov;
        for k in 0..N {
            // M = Φ P (rows): v rows += B P_θ· + D P_b·, then θ rows += A P_b·
            let (pt, pb) = ([p[TH][k], p[TH + 1][k], p[TH + 2][k]], [p[BI][k], p[BI + 1][k], p[BI + 2][k]]);
            for i in 0..3 {
                let mut sv = 0.0;
                let mut sth = 0.0;
                for j in 0..3 {
                    sv += bm[i][j] * pt[j] + dm[i][j] * pb[j];
                    sth += am[i][j] * pb[j];
                }
                p[VE + i][k] += sv;
                p[TH + i][k] += sth;
            }
        }
        for row in p.iter_mut() {
            // P' = M Φ^T (columns): v cols += M_·θ B^T + M_·b D^T, then θ cols += M_·b A^T
            let (mt, mb) = ([row[TH], row[TH + 1], row[TH + 2]], [row[BI], row[BI + 1], row[BI + 2]]);
            for i in 0..3 {
                let mut sv = 0.0;
                let mut sth = 0.0;
                for j in 0..3 {
                    sv += mt[j] * bm[i][j] + mb[j] * dm[i][j];
                    sth += mb[j] * am[i][j];
                }
                row[VE + i] += sv;
                row[TH + i] += sth;
            }
        }
        let out = p;
        for i in 0..3 {
            out[TH + i][TH + i] += q.theta[i];
            out[BI + i][BI + i] += q.bias;
        }
        for i in 0..3 {
            for j in 0..3 {
                out[VE + i][VE + j] += q.v[i][j];
            }
        }
        if self.with_scale {
            out[SC][SC] += q.scale;
        }
        // keep it symmetric
        for i in 0..N {
            for j in 0..i {
                let v = 0.5 * (out[i][j] + out[j][i]);
                out[i][j] = v;
                out[j][i] = v;
            }
        }
    }

    /// One scalar update `nu = h dx + noise(r)`, gated; the gain rows of the
    /// tilt and the bias only where allowed (Joseph form keeps P right for
    /// the restricted gain). Accumulates into `dx`. Returns fused or
    /// refused with the test ratio `ν² / (ratio_gate · S)` (`ratio_gate` the
    /// configured gate, `gate` the one this update is held to), or not
    /// applicable when the innovation's variance is not positive.
    pub fn update(&mut self, h: &[f64; N], nu: f64, r: f64, gain: Gain, gate: f64, ratio_gate: f64) -> AidStatus {
        // most rows have one to three non-zero entries
        let mut nz = [0usize; N];
        let mut n = 0;
        for (j, v) in h.iter().enumerate() {
            if *v != 0.0 {
                nz[n] = j;
                n += 1;
            }
        }
        let nz = &nz[..n];
        let p = &self.cov;
        // u = P h, as a sum of the rows of the (exactly symmetric) P:
        // contiguous, and the same sums in the same order as by columns
        let mut u = [0.0; N];
        for &j in nz {
            let (hj, row) = (h[j], &p[j]);
            for i in 0..N {
                u[i] += row[i] * hj;
            }
        }
        let mut s = r;
        let mut hdx = 0.0;
        for &j in nz {
            s += h[j] * u[j];
            hdx += h[j] * self.dx[j];
        }
        if s.is_nan() || s <= 0.0 || s.is_infinite() {
            return AidStatus::NotApplicable(Why::Unobservable);
        }
        let nu = nu - hdx;
        if self.scoring && gain.scored {
            self.log_likelihood -= 0.5 * ((nu * nu / s).min(gate) + s.ln());
        }
        let ratio = nu * nu / (ratio_gate * s);
        if nu * nu > gate * s {
            return AidStatus::Refused(ratio);
        }
        let mut k = [0.0; N];
        for i in 0..N {
            k[i] = u[i] / s;
        }
        let full = gain.tilt && gain.heading && gain.bias;
        if !gain.tilt {
            k[TH] = 0.0;
            k[TH + 1] = 0.0;
        }
        if !gain.heading {
            k[TH + 2] = 0.0;
        }
        if !gain.bias {
            k[BI] = 0.0;
            k[BI + 1] = 0.0;
            k[BI + 2] = 0.0;
        }
        for i in 0..N {
            self.dx[i] += k[i] * nu;
        }
        let p = &mut self.cov;
        if full {
            // the optimal gain: Joseph reduces to P - u u^T / s
            for i in 0..N {
                for j in 0..=i {
                    let v = p[i][j] - k[i] * u[j];
                    p[i][j] = v;
                    p[j][i] = v;
                }
            }
        } else {
            for i in 0..N {
                for j in 0..=i {
                    let v = p[i][j] - k[i] * u[j] - u[i] * k[j] + s * k[i] * k[j];
                    p[i][j] = v;
                    p[j][i] = v;
                }
            }
        }
        AidStatus::Fused(ratio)
    }

    /// Cut the correlations of these error-state rows with every other
    /// (their variances stay).
    pub fn decorrelate(&mut self, rows: &[usize]) {
        for &i in rows {
            for j in 0..N {
                if j != i {
                    self.cov[i][j] = 0.0;
                    self.cov[j][i] = 0.0;
                }
            }
        }
    }

    /// Bring the 1-sigma of these rows down to `sigma` where it is above it,
    /// their correlations scaled with them (the covariance stays positive).
    pub fn shrink(&mut self, rows: &[usize], sigma: f64) {
        for &i in rows {
            let s = (sigma / self.cov[i][i].sqrt()).min(1.0);
            for j in 0..N {
                self.cov[i][j] *= s;
                self.cov[j][i] *= s;
            }
        }
    }

    /// Apply the accumulated error to the state and clear it; the
    /// attitude's turn (navigation frame) when there was an error, for what
    /// the filter holds in the navigation frame beside the core.
    pub fn inject(&mut self) -> Option<Mat3> {
        let d = self.dx;
        if d.iter().all(|v| *v == 0.0) {
            return None;
        }
        let dq = quat::from_rotvec(&[d[TH], d[TH + 1], d[TH + 2]]);
        self.q = quat::mul(&dq, &self.q);
        let r = quat::to_matrix(&dq);
        quat::normalise(&mut self.q);
        self.c = quat::to_matrix(&self.q);
        for i in 0..3 {
            self.bias[i] += d[BI + i];
            self.v[i] += d[VE + i];
        }
        if self.with_scale {
            self.scale += d[SC];
        }
        self.dx = [0.0; N];
        Some(r)
    }

    /// Turn the whole state about the navigation frame's down axis by `psi`
    /// (rad): attitude, velocity and the covariance of the navigation-frame
    /// errors; returns the turn. Nothing in the body frame changes.
    pub fn turn_heading(&mut self, psi: f64) -> Mat3 {
        let dq = quat::from_rotvec(&[0.0, 0.0, psi]);
        let r = quat::to_matrix(&dq);
        self.q = quat::mul(&dq, &self.q);
        quat::normalise(&mut self.q);
        self.c = quat::to_matrix(&self.q);
        self.v = rotate(&r, &self.v);
        // T = blockdiag(R, I, R, 1): P' = T P T^T
        let nav = |k: usize| k < 3 || (VE..VE + 3).contains(&k);
        let mut m = self.cov;
        for i in 0..N {
            if !nav(i) {
                continue;
            }
            let b = i - i % 3;
            for j in 0..N {
                m[i][j] = (0..3).map(|k| r[i - b][k] * self.cov[b + k][j]).sum();
            }
        }
        let mut out = m;
        for j in 0..N {
            if !nav(j) {
                continue;
            }
            let b = j - j % 3;
            for i in 0..N {
                out[i][j] = (0..3).map(|k| m[i][b + k] * r[j - b][k]).sum();
            }
        }
        self.cov = out;
        r
    }

    /// Whether the nominal state is finite.
    pub fn is_finite(&self) -> bool {
        self.q.iter().all(|v| v.is_finite()) && self.bias.iter().all(|v| v.is_finite()) && self.v.iter().all(|v| v.is_finite())
    }
}

#[cfg(test)]
impl Core {
    /// The scale error set outright (tests).
    pub fn set_scale(&mut self, s: f64) {
        self.scale = s;
    }

    /// One error-state entry set outright, to inject (tests).
    pub fn set_dx(&mut self, k: usize, v: f64) {
        self.dx[k] = v;
    }

    /// The covariance set outright (tests).
    pub fn set_cov(&mut self, p: [[f64; N]; N]) {
        self.cov = p;
    }
}
