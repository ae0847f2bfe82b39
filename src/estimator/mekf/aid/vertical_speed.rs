//! The vertical-speed bound: no road has a car climb or descend faster
//! than `max_vertical_speed`.

use crate::estimator::mekf::*;

impl Mekf {
    /// A vertical velocity beyond the bound is a pitch error integrated
    /// into a wrong speed (powered on while driving, IMU only, a straight
    /// road with no stop: nothing else tells them apart). Held to the
    /// bound (1-sigma `VERTICAL_BOUND_SIGMA`), one-sided, never gated; a
    /// real grade a little beyond it costs a pitch error of the excess over
    /// the speed only.
    pub(in crate::estimator::mekf) fn fuse_vertical_speed(&mut self, gain: Gain) {
        let vmax = self.p.max_vertical_speed;
        let s = if !self.vehicle {
            AidStatus::NotApplicable(Why::NotVehicle)
        } else if !self.on(Rule::VerticalSpeedBound) || vmax <= 0.0 {
            AidStatus::NotApplicable(Why::RuleOff)
        } else if self.core.v()[2].abs() <= vmax {
            AidStatus::NotApplicable(Why::WithinBound)
        } else {
            let mut h = [0.0; N];
            h[VE + 2] = 1.0;
            let var = VERTICAL_BOUND_SIGMA * VERTICAL_BOUND_SIGMA;
            let s = self.update(&h, vmax.copysign(self.core.v()[2]) - self.core.v()[2], var, gain, f64::INFINITY);
            self.counters.rules.note(Rule::VerticalSpeedBound);
            s
        };
        self.aid.set(Aid::VerticalSpeed, s);
    }
}
