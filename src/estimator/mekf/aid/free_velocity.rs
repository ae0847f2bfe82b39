//! A free unit's bounded velocity: a unit that is not a vehicle (in a
//! hand, on a body) goes nowhere on average, so its velocity is zero
//! within `free_velocity_sigma` on all three axes.

use crate::estimator::mekf::*;

impl Mekf {
    /// The velocity about zero (`free_var`). It tells the heading (through
    /// the horizontal accelerations) only about a heading already known:
    /// with one wide open (powered on in motion, re-acquired) its
    /// linearisation turned broad-18, cut 5 s into its motion, 75-180 deg
    /// off. A velocity the bound refuses was integrated from a wrong tilt
    /// (powered on in motion), and through the attitude rows of that bound
    /// it would turn the heading by tens of degrees (broad-18 cut 5 s into
    /// its motion: 100 m/s, the heading thrown 180 deg): it is the free
    /// velocity again.
    pub(in crate::estimator::mekf) fn fuse_free_velocity(&mut self, omega: &[f64; 3], gain: Gain, gate: f64) -> Rows {
        let open = self.core.cov()[TH + 2][TH + 2] > FREE_HEADING_SIGMA * FREE_HEADING_SIGMA;
        let vgain = Gain { heading: gain.heading && !open, scored: true, ..gain };
        let mut s = Rows::default();
        for i in 0..3 {
            let (nu, h) = self.body_velocity_row(i, omega);
            s.push(self.update(&h, -nu, self.p.free_var, vgain, gate));
        }
        if s.refused() {
            self.free_velocity();
        }
        self.aid.set(Aid::FreeVelocity, s.status);
        s
    }

    /// A free unit's velocity: zero, `free_velocity_sigma`, uncorrelated.
    pub(in crate::estimator::mekf) fn free_velocity(&mut self) {
        self.core.decorrelate(&[VE, VE + 1, VE + 2]);
        self.core.set_velocity([0.0; 3]);
        self.core.drop_dx(&[VE, VE + 1, VE + 2]);
        for i in 0..3 {
            self.core.set_var(VE + i, self.p.free_var);
        }
    }
}
