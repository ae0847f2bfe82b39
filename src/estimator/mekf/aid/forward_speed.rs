//! The forward-speed bound: a car's forward speed stays within
//! `-max_reverse_speed .. max_forward_speed`.

use crate::estimator::mekf::*;

impl Mekf {
    /// A forward velocity beyond the band is a pitch (or an accelerometer
    /// bias) integrated into a speed no car has, with no stop or wheel to
    /// say so. Held to the bound (1-sigma `speed_bound_sigma`), one-sided,
    /// never gated: inside the band it says nothing (a crawl is not pulled
    /// to a cruise).
    pub(in crate::estimator::mekf) fn fuse_forward_speed(&mut self, omega: &[f64; 3], gain: Gain) {
        let (fwd, rev) = (self.p.max_forward_speed, self.p.max_reverse_speed);
        let s = if !self.vehicle {
            AidStatus::NotApplicable(Why::NotVehicle)
        } else if fwd <= 0.0 || !self.on(Rule::ForwardSpeedBound) {
            AidStatus::NotApplicable(Why::RuleOff)
        } else {
            let (val, h) = self.body_velocity_row(0, omega);
            let bound = if val > fwd {
                Some(fwd)
            } else if val < -rev {
                Some(-rev)
            } else {
                None
            };
            match bound {
                None => AidStatus::NotApplicable(Why::WithinBound),
                Some(b) => {
                    let var = self.p.speed_bound_sigma * self.p.speed_bound_sigma;
                    let s = self.update(&h, b - val, var, gain, f64::INFINITY);
                    self.counters.rules.note(Rule::ForwardSpeedBound);
                    s
                }
            }
        };
        self.aid.set(Aid::ForwardSpeed, s);
    }
}
