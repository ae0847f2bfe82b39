//! Recovery from a filter that has lost its way: the velocity re-acquired
//! after its constraints were refused for long (`velocity_reacquire`), and
//! a restart from the prior when the filter has diverged (`restart_lost`,
//! `restart_bias_range`).

use crate::estimator::mekf::*;

impl Mekf {
    /// `velocity_reacquire`: the velocity constraints refused in motion for
    /// `relevel_s`.
    pub(in crate::estimator::mekf) fn reacquire_velocity(&mut self) {
        if self.refusals.refused_s >= self.p.relevel_s && self.on(Rule::VelocityReacquire) {
            // The velocity constraints have been refused for long: the
            // velocity, not the vehicle, is wrong. Widen it so they take hold
            // again (the attitude is left alone: it is what they correct).
            for i in 0..3 {
                self.core.add_cov(VE + i, VE + i, 1.0);
            }
            self.refusals.refused_s = 0.0;
            self.counters.reacquired += 1;
            self.counters.rules.note(Rule::VelocityReacquire);
        }
    }

    /// `restart_lost`, `restart_bias_range`: a diverged filter starts again
    /// from its prior (true when it did).
    pub(in crate::estimator::mekf) fn restart_if_diverged(&mut self, at_rest: bool) -> bool {
        let (pb, ps) = self.prior;
        // Before a standstill (or a saved state) has shown the bias, a bias
        // beyond the part's range is the filter's divergence, not the part;
        // a bias read at rest is evidence, whatever its size.
        let lost = self.refusals.share > LOST_SHARE && self.on(Rule::RestartLost);
        let unbelievable = self.on(Rule::RestartBiasRange)
            && !self.bias_known
            && !at_rest
            && (0..3).any(|i| (self.core.bias()[i] - pb[i]).abs() > BIAS_LIMIT_SIGMAS * ps[i].max(self.p.init_bias_sigma));
        if lost || unbelievable {
            self.counters.rules.note(if lost { Rule::RestartLost } else { Rule::RestartBiasRange });
            self.restart_from_prior();
            return true;
        }
        false
    }

    /// A diverged state (its bias outside the part's range): start again
    /// from the prior, the attitude from the low-passed specific force, the
    /// heading and what was learned about gravity and the magnetometer kept.
    pub(in crate::estimator::mekf) fn restart_from_prior(&mut self) {
        let (pb, ps) = self.prior;
        let f = self.body_f_lp;
        let yaw = quat::euler(self.core.c())[2];
        let (roll, pitch) = crate::estimator::ekf::tilt_from_accel(&f);
        self.initialise([roll, pitch, yaw], pb, ps);
        self.bias_known = false;
        // the field's dip was measured with the diverged tilt
        self.heading.forget();
        self.refused_still = 0.0;
        self.quiet_since_gap = false;
        self.refusals = VelocityRefusals::default();
        self.free_gravity.refused_s = 0.0;
        self.counters.restarts += 1;
    }
}
