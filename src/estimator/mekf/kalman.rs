//! The error-state Kalman filter's numerics: the covariance propagation
//! with the transition accumulated between ticks, the scalar update with its
//! innovation gate, and the injection of the error state into the nominal one.

use super::*;

impl Mekf {
    /// The propagation of `propagate` without process noise, over the
    /// samples accumulated so far (for tests).
    #[cfg(test)]
    pub(in crate::estimator::mekf) fn propagate_noiseless(&mut self) {
        let a = self.acc.clone();
        let saved = (self.p.q_gyro, self.p.q_bias, self.p.q_accel, self.p.q_scale, self.p.gyro_scale, self.p.q_bias_motion);
        self.p.q_gyro = 0.0;
        self.p.q_bias = 0.0;
        self.p.q_bias_motion = 0.0;
        self.p.q_accel = 0.0;
        self.p.q_scale = 0.0;
        self.p.gyro_scale = 0.0;
        self.propagate(&a);
        (self.p.q_gyro, self.p.q_bias, self.p.q_accel, self.p.q_scale, self.p.gyro_scale, self.p.q_bias_motion) = saved;
    }

    /// `P = Φ P Φ^T + Q` with `Φ = [[I, A, 0, 0], [0, I, 0, 0], [B, D, I, 0], [0, 0, 0, 1]]`,
    /// `A = -Σ C dt`, `B = -[Σ C f dt ×]`, `D ≈ B A / 2`.
    pub(in crate::estimator::mekf) fn propagate(&mut self, a: &Accum) {
        let mut am = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                am[i][j] = -a.s_c[i][j];
            }
        }
        let d = a.dv;
        // B = -[d×]
        let bm = [[0.0, d[2], -d[1]], [-d[2], 0.0, d[0]], [d[1], -d[0], 0.0]];
        let mut dm = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                dm[i][j] = 0.5 * (bm[i][0] * am[0][j] + bm[i][1] * am[1][j] + bm[i][2] * am[2][j]);
            }
        }
        let q_bias = if self.learns_in_motion() && !a.rest { self.p.q_bias.max(self.p.q_bias_motion) } else { self.p.q_bias };
        // In place: M = Φ P changes the θ and v rows only, and the v rows
        // read the θ rows before these change; P' = M Φ^T likewise by columns.
        let q_v = self.velocity_noise(a);
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
        let t = a.t;
        // A scale error turns the heading by its share of the turn about the
        // vertical only (a turn about a horizontal axis tilts the unit); the
        // tilt keeps the whole turn, a bound on its share
        let turned = self.p.gyro_scale * a.turned;
        let turned_z = self.p.gyro_scale * a.turned_z;
        for i in 0..3 {
            let s = if i == 2 { turned_z } else { turned };
            out[TH + i][TH + i] += self.p.q_gyro * t + s * s;
            out[BI + i][BI + i] += q_bias * t;
        }
        for i in 0..3 {
            for j in 0..3 {
                out[VE + i][VE + j] += q_v[i][j] * t;
            }
        }
        if self.p.speed_aided {
            out[SC][SC] += self.p.q_scale * t;
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

    /// The velocity's noise over the tick, (m/s)^2/s per navigation axis: a
    /// car's acceleration is not white (a vehicle's only). Quiet, it is
    /// `q_accel_quiet` on every axis (a car's smooth cruise keeps its speed,
    /// and a velocity that wandered as under braking would let a cruise
    /// pass for a stop). Shaking (the vibration about the tick's mean) it
    /// rises towards `q_accel` on every axis, in proportion to the
    /// vibration's power against `accel_ref` squared, and far beyond for a
    /// knock. The car's own change of velocity (the tick's mean
    /// acceleration beyond gravity) brings its share of `q_accel` along
    /// that acceleration only: a car speeding up on a straight keeps its
    /// vertical and lateral channels quiet, so the vehicle constraint there
    /// still sees the tilt (isotropic, a smooth pull-away's 0.05 g let the
    /// vertical velocity take up the constraint's innovations, and the pitch
    /// of the simulated `smooth` seed 8 ran 3 deg off while the car sped up).
    /// The shares add to at most the whole of `q_accel`.
    pub(in crate::estimator::mekf) fn velocity_noise(&self, a: &Accum) -> Mat3 {
        let (t, n) = (a.t, a.n as f64);
        let iso = |q: f64| [[q, 0.0, 0.0], [0.0, q, 0.0], [0.0, 0.0, q]];
        // a hand's motion is not a car's: a free unit keeps `q_accel`
        if !self.vehicle || t <= 0.0 || a.n == 0 || !self.on(Rule::QuietVelocityNoise) {
            return iso(self.p.q_accel);
        }
        let mean = [a.accel[0] / n, a.accel[1] / n, a.accel[2] / n];
        let var = (a.accel2 / n - (mean[0] * mean[0] + mean[1] * mean[1] + mean[2] * mean[2])).max(0.0) * G * G;
        let d = [a.dv[0] / t, a.dv[1] / t, a.dv[2] / t + G];
        let d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        // a knock: vibration beyond any car body's ride within the tick,
        // whose integral is no car's change of speed
        let r2 = self.p.accel_ref * self.p.accel_ref;
        let shock = if self.on(Rule::KnockNoise) { (var - (SHOCK_G * G).powi(2)).max(0.0) } else { 0.0 };
        let vib = (var / r2).min(1.0);
        let span = (self.p.q_accel - self.p.q_accel_quiet).max(0.0);
        let mut q = iso(self.p.q_accel_quiet + span * (vib + shock / r2));
        // the car's own change of velocity is along its acceleration: the
        // noise it brings (scale and alignment errors of the specific force)
        // lies along it, not across (a car speeding up on a straight keeps
        // its vertical and lateral channels quiet)
        let dyn_share = (d2 / r2).min(1.0 - vib);
        if dyn_share > 0.0 && d2 > 0.0 {
            let k = span * dyn_share / d2;
            for i in 0..3 {
                for j in 0..3 {
                    q[i][j] += k * d[i] * d[j];
                }
            }
        }
        q
    }

    /// One scalar update `nu = h dx + noise(r)`, gated; the gain rows of the
    /// tilt and the bias only where allowed (Joseph form keeps P right for
    /// the restricted gain). Accumulates into `dx`. Returns fused or
    /// refused with the test ratio `ν² / (gate_sigma² · S)`, or not
    /// applicable when the innovation's variance is not positive.
    pub(in crate::estimator::mekf) fn update(&mut self, h: &[f64; N], nu: f64, r: f64, gain: Gain, gate: f64) -> AidStatus {
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
        let ratio = nu * nu / (self.p.gate * s);
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
    pub(in crate::estimator::mekf) fn decorrelate(&mut self, rows: &[usize]) {
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
    pub(in crate::estimator::mekf) fn shrink(&mut self, rows: &[usize], sigma: f64) {
        for &i in rows {
            let s = (sigma / self.cov[i][i].sqrt()).min(1.0);
            for j in 0..N {
                self.cov[i][j] *= s;
                self.cov[j][i] *= s;
            }
        }
    }

    /// Apply the accumulated error to the state and clear it.
    pub(in crate::estimator::mekf) fn inject(&mut self) {
        let d = self.dx;
        if d.iter().all(|v| *v == 0.0) {
            return;
        }
        let dq = quat::from_rotvec(&[d[TH], d[TH + 1], d[TH + 2]]);
        self.q = quat::mul(&dq, &self.q);
        let r = quat::to_matrix(&dq);
        if let Some(lp) = self.f_lp.as_mut() {
            // the low-passed force was rotated with the old attitude
            lp.rotate(&r);
        }
        self.c_lag = quat::mat_mul(&r, &self.c_lag);
        quat::normalise(&mut self.q);
        self.c = quat::to_matrix(&self.q);
        for i in 0..3 {
            self.bias[i] += d[BI + i];
            self.v[i] += d[VE + i];
        }
        if self.p.speed_aided {
            self.scale += d[SC];
        }
        self.dx = [0.0; N];
    }
}
