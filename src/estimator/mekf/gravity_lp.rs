//! A free unit's gravity: the navigation-frame specific force low-passed,
//! and how much the unit's own acceleration is likely to remain in it.
//!
//! A unit that is not a vehicle (hand-held, on a bench) goes nowhere on
//! average, so its acceleration averages out: the specific force low-passed
//! over `accel_tau_s` (3 s) is gravity, and its direction is a tilt
//! measurement. What the low-pass leaves of the unit's own acceleration is
//! that measurement's error. It cannot be told from a tilt error at the
//! same frequencies, but it grows with how hard the unit is being moved,
//! which is seen a little higher up: the horizontal force in the band
//! between `MOTION_BAND_TAU_S` and `accel_tau_s` (periods of about 0.3 to
//! 3 s: a hand moving the unit back and forth; engine or phone vibration
//! lies far above it). Its mean square, low-passed over `accel_tau_s`, is
//! `motion_var`; the tilt's variance is
//! `tilt_sigma^2 + tilt_motion_share^2 x motion_var`: a unit held still or
//! turned slowly is levelled firmly, one shaken back and forth loosely.

use super::quat::{rotate, Mat3};

/// Time constant of the low-pass that bounds the motion band from above, s.
pub const MOTION_BAND_TAU_S: f64 = 0.3;

/// The low-passed specific force (g, navigation frame) and the motion
/// band's mean square.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GravityLp {
    /// Low-passed over `accel_tau_s`: gravity, for a free unit.
    pub lp: [f64; 3],
    /// Low-passed over `MOTION_BAND_TAU_S`.
    band: [f64; 3],
    /// Mean square of the horizontal `band - lp`, low-passed over
    /// `accel_tau_s`, g^2.
    pub motion_var: f64,
}

impl GravityLp {
    pub fn new(f: &[f64; 3]) -> GravityLp {
        GravityLp { lp: *f, band: *f, motion_var: 0.0 }
    }

    /// One sample `f` with the low-pass gains of `accel_tau_s` and of the
    /// motion band for this step.
    #[inline]
    pub fn push(&mut self, f: &[f64; 3], alpha: f64, alpha_band: f64) {
        for i in 0..3 {
            self.lp[i] += (f[i] - self.lp[i]) * alpha;
            self.band[i] += (f[i] - self.band[i]) * alpha_band;
        }
        let (dn, de) = (self.band[0] - self.lp[0], self.band[1] - self.lp[1]);
        self.motion_var += (dn * dn + de * de - self.motion_var) * alpha;
    }

    /// The navigation frame was turned by `r` (a correction of the
    /// attitude): the stored forces turn with it.
    pub fn rotate(&mut self, r: &Mat3) {
        self.lp = rotate(r, &self.lp);
        self.band = rotate(r, &self.band);
    }

    /// The variance of the tilt taken from `lp` (rad^2): the floor
    /// `base_var` plus `share2` of the motion band's mean square.
    pub fn tilt_var(&self, base_var: f64, share2: f64) -> f64 {
        base_var + share2 * self.motion_var
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(f: impl Fn(f64) -> [f64; 3], secs: f64) -> GravityLp {
        let dt = 0.005;
        let (a, ab) = (dt / 3.0, dt / MOTION_BAND_TAU_S);
        let mut g = GravityLp::new(&f(0.0));
        let mut t = 0.0;
        while t < secs {
            t += dt;
            g.push(&f(t), a, ab);
        }
        g
    }

    #[test]
    fn a_still_unit_has_no_motion_and_a_shaken_one_has_it_in_proportion() {
        let still = run(|_| [0.0, 0.0, -1.0], 30.0);
        assert_eq!(still.motion_var, 0.0);
        assert_eq!(still.tilt_var(1e-4, 0.04), 1e-4);
        // a hand moving the unit back and forth along north, 0.5 Hz
        let shake = |amp: f64| move |t: f64| [amp * (std::f64::consts::PI * t).sin(), 0.0, -1.0];
        let small = run(shake(0.05), 30.0);
        let large = run(shake(0.5), 30.0);
        assert!(small.motion_var > 0.0);
        // the mean square scales with the square of the acceleration
        let ratio = large.motion_var / small.motion_var;
        assert!((ratio - 100.0).abs() < 1.0, "ratio {ratio}");
        // a 0.5 Hz motion passes the band with |1/(1+jωτ_band) - 1/(1+jωτ)|^2
        // = 0.425 of its mean square (within the 3-s low-pass's ripple)
        let share = large.motion_var / (0.5 * 0.5 * 0.5);
        assert!((share - 0.425).abs() < 0.03, "{share}");
        // and the tilt is held more loosely
        assert!(large.tilt_var(1e-4, 0.04) > small.tilt_var(1e-4, 0.04));
    }

    #[test]
    fn vibration_far_above_the_band_is_not_motion() {
        // 0.3 g at 50 Hz (a phone buzzing against the unit, an engine)
        let buzz = run(|t| [0.3 * (2.0 * std::f64::consts::PI * 50.0 * t).sin(), 0.0, -1.0], 30.0);
        let hand = run(|t| [0.3 * (std::f64::consts::PI * t).sin(), 0.0, -1.0], 30.0);
        assert!(buzz.motion_var < 0.01 * hand.motion_var, "{} against {}", buzz.motion_var, hand.motion_var);
    }

    #[test]
    fn a_turn_of_the_frame_turns_the_forces_and_keeps_the_motion() {
        let mut g = run(|t| [0.2 * (std::f64::consts::PI * t).sin(), 0.1, -1.0], 10.0);
        let before = g;
        let r = crate::estimator::quat::to_matrix(&crate::estimator::quat::from_rotvec(&[0.0, 0.0, 0.7]));
        g.rotate(&r);
        assert_eq!(g.motion_var, before.motion_var);
        assert!((g.lp[2] - before.lp[2]).abs() < 1e-15);
        let h = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1]).sqrt();
        assert!((h(g.lp) - h(before.lp)).abs() < 1e-15);
        assert!((g.lp[0] - before.lp[0]).abs() > 1e-3);
    }
}
