//! How the filter drives its core (`core`): the process noise of a tick
//! (what the tick's motion says of the velocity's and the attitude's
//! uncertainty), the update held to the configured gate, and the injection,
//! which turns what the filter holds in the navigation frame beside the core
//! (the low-passed force, the lagged attitude) with the attitude.

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

    /// The covariance over the accumulated interval: the core's transition
    /// with this tick's process noise (the gyro's white noise and its
    /// scale error's share of the turn on the attitude, the bias walk, in
    /// motion the walk of a unit that learns there, the velocity's noise,
    /// the scale's walk).
    pub(in crate::estimator::mekf) fn propagate(&mut self, a: &Accum) {
        let q_bias = if self.learns_in_motion() && !a.rest { self.p.q_bias.max(self.p.q_bias_motion) } else { self.p.q_bias };
        let t = a.t;
        // A scale error turns the heading by its share of the turn about the
        // vertical only (a turn about a horizontal axis tilts the unit); the
        // tilt keeps the whole turn, a bound on its share
        let turned = self.p.gyro_scale * a.turned;
        let turned_z = self.p.gyro_scale * a.turned_z;
        let theta = std::array::from_fn(|i| {
            let s = if i == 2 { turned_z } else { turned };
            self.p.q_gyro * t + s * s
        });
        let v = self.velocity_noise(a).map(|row| row.map(|q| q * t));
        let noise = ProcessNoise { theta, bias: q_bias * t, v, scale: self.p.q_scale * t };
        self.core.propagate(&a.s_c, &a.dv, &noise);
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

    /// One scalar update held to `gate` (`Core::update`), its test ratio
    /// against the configured gate.
    #[inline]
    pub(in crate::estimator::mekf) fn update(&mut self, h: &[f64; N], nu: f64, r: f64, gain: Gain, gate: f64) -> AidStatus {
        self.core.update(h, nu, r, gain, gate, self.p.gate)
    }

    /// Apply the accumulated error to the state and clear it (`Core::inject`);
    /// the low-passed force and the lagged attitude turn with the attitude.
    pub(in crate::estimator::mekf) fn inject(&mut self) {
        let Some(r) = self.core.inject() else { return };
        if let Some(lp) = self.f_lp.as_mut() {
            // the low-passed force was rotated with the old attitude
            lp.rotate(&r);
        }
        self.c_lag = quat::mat_mul(&r, &self.c_lag);
    }
}
