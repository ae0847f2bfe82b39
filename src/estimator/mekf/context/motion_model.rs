//! Vehicle or hand-held (`[mekf] vehicle`): which motion model the filter
//! runs, how `"auto"` decides it from the measurements, and what leaving
//! the vehicle model voids.

use crate::estimator::mekf::*;

impl Mekf {
    /// `vehicle = "auto"`, once per sample while the vehicle model is in
    /// use: the body rates (rad/s, raw) and specific force (g) decide.
    pub(in crate::estimator::mekf) fn watch_vehicle_model(&mut self, gyro: &[f64; 3], accel: &[f64; 3]) {
        if !self.may_leave_vehicle_model() {
            return;
        }
        // decided on the measurements, never on the filter's own
        // state (a diverged filter must not talk itself out of the
        // vehicle model): how the roll/pitch rates swing about their
        // own 3-s mean (a steady rate is a bias of any size, not a
        // hand), and the tilt of the low-passed specific force
        let (pb, _) = self.prior;
        let m = &mut self.xy_rate_mean;
        let (wx, wy) = (gyro[0] - pb[0] - m[0], gyro[1] - pb[1] - m[1]);
        let a3 = self.alpha_1s / 3.0;
        m[0] += wx * a3;
        m[1] += wy * a3;
        self.xy_rate2 += (wx * wx + wy * wy - self.xy_rate2) * a3;
        for i in 0..3 {
            self.body_f_lp[i] += (accel[i] - self.body_f_lp[i]) * self.alpha_1s;
        }
        // a car body never tilts past 45 deg either
        let upright = -self.body_f_lp[2] > std::f64::consts::FRAC_1_SQRT_2 * norm(&self.body_f_lp);
        if self.xy_rate2 > self.p.handheld_rate * self.p.handheld_rate || !upright {
            self.leave_vehicle_model();
        }
    }

    /// The vehicle model is in use and `"auto"` may still leave it (IMU only:
    /// with the car's own speed it is a vehicle).
    fn may_leave_vehicle_model(&self) -> bool {
        self.vehicle && self.p.vehicle == Vehicle::Auto && !self.p.speed_aided && self.on(Rule::LeaveVehicleModel)
    }

    /// The unit is not in a vehicle after all. Before a standstill has read
    /// the bias (powered on in a hand, moving), what the vehicle constraint
    /// taught is void: the bias goes back to its prior, the tilt opens to
    /// the low-passed gravity. The velocity is a free unit's.
    fn leave_vehicle_model(&mut self) {
        self.vehicle = false;
        self.counters.rules.note(Rule::LeaveVehicleModel);
        if !self.bias_known {
            let a = self.p.init_angle_sigma * self.p.init_angle_sigma;
            self.core.decorrelate(&[TH, TH + 1]);
            for i in 0..2 {
                self.core.floor_var(TH + i, a);
            }
        }
        self.free_velocity_and_unread_bias();
    }

    /// A free unit's velocity (zero, `free_velocity_sigma`) and, while no
    /// standstill has read it, the prior bias with the prior's sigma (what
    /// was learned with a wrong tilt or a wrong model is void): what the end
    /// of the vehicle model and a re-levelling in motion leave.
    pub(in crate::estimator::mekf) fn free_velocity_and_unread_bias(&mut self) {
        self.free_velocity();
        if !self.bias_known {
            self.core.decorrelate(&[BI, BI + 1, BI + 2]);
            let (pb, ps) = self.prior;
            self.core.set_bias(pb);
            for i in 0..3 {
                self.core.set_var(BI + i, ps[i] * ps[i]);
            }
        }
    }

    /// With `vehicle = "auto"` (IMU only), a copy of this filter just
    /// started that runs the free unit's model from here on: what the
    /// filter would have been had it known from power-on that the unit is
    /// not in a vehicle (the power-on bank keeps it, `hypotheses.rs`).
    /// None when the vehicle model is configured or the speed measured.
    pub fn free_unit_copy(&self) -> Option<Mekf> {
        if !self.may_leave_vehicle_model() || !self.on(Rule::FreeUnitCopy) {
            return None;
        }
        // as `vehicle = false` starts: zero velocity, `init_speed_sigma`
        let mut m = self.clone();
        m.vehicle = false;
        m.set_scoring(false);
        Some(m)
    }

    /// A unit that is not a vehicle, with a motion walk configured: it
    /// learns its bias from the low-passed gravity while it moves.
    #[inline]
    pub(in crate::estimator::mekf) fn learns_in_motion(&self) -> bool {
        !self.vehicle && self.p.q_bias_motion > 0.0
    }
}
