//! Zero velocity (ZUPT): at a standstill, not a smooth cruise, the
//! velocity is zero on all three axes.

use crate::estimator::mekf::*;

impl Mekf {
    /// The standstill's zero velocity, noise `zupt_var`. Not scored for
    /// the power-on bank: a standstill is what this copy assumes, not a
    /// measurement every copy shares (scored, the copy that took a cruise
    /// for a stop gained nats from its own assumption).
    pub(in crate::estimator::mekf) fn fuse_zero_velocity(&mut self, gate: f64) -> Rows {
        let all = Gain { tilt: true, heading: true, bias: true, scored: false };
        let mut s = Rows::default();
        for i in 0..3 {
            let mut h = [0.0; N];
            h[VE + i] = 1.0;
            s.push(self.update(&h, -self.core.v()[i], self.p.zupt_var, all, gate));
        }
        self.aid.set(Aid::ZeroVelocity, s.status);
        s
    }
}
