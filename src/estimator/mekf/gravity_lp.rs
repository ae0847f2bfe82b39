//! A free unit's gravity: the navigation-frame specific force low-passed,
//! and how much the unit's own acceleration is likely to remain in it.
//!
//! A unit that is not a vehicle (hand-held, on a bench) goes nowhere on
//! average, so its acceleration averages out: the specific force low-passed
//! with the time constant `accel_tau_s` (3 s) is gravity, and its direction
//! is a tilt measurement. The low-pass is a second-order Butterworth (as
//! VQF's): a hand's back-and-forth motion at 0.5 Hz keeps 2 % of its
//! acceleration in it, against 11 % through a first-order low-pass of the
//! same time constant, at the same lag for slow changes.
//!
//! What the low-pass leaves of the unit's own acceleration is that
//! measurement's error. It cannot be told from a tilt error at the same
//! frequencies, but it grows with how hard the unit is being moved, which
//! is seen a little higher up: the horizontal force in the band between
//! `MOTION_BAND_TAU_S` and `accel_tau_s` (two first-order low-passes;
//! periods of about 0.3 to 3 s: a hand moving the unit back and forth;
//! engine or phone vibration lies far above it). Its mean square,
//! low-passed over `accel_tau_s`, is `motion_var`; the tilt's variance is
//! `tilt_sigma^2 + tilt_motion_share^2 x motion_var`: a unit held still or
//! turned slowly is levelled firmly, one shaken back and forth loosely.

use super::quat::{rotate, Mat3};

/// Time constant of the low-pass that bounds the motion band from above, s.
pub const MOTION_BAND_TAU_S: f64 = 0.3;

/// The low-pass gains for one step length: the first-order gains of
/// `accel_tau_s` and of the motion band, and the Butterworth's
/// coefficients `[b0, b1, b2, a1, a2]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LpGains {
    pub alpha: f64,
    pub alpha_band: f64,
    bw: [f64; 5],
}

impl LpGains {
    /// For steps of `dt` s and the time constant `tau` s.
    pub fn new(dt: f64, tau: f64) -> LpGains {
        let alpha = (dt / tau).min(1.0);
        // Butterworth with the cut-off sqrt(2) / (2 pi tau) (VQF's choice:
        // the same lag as a first-order low-pass of `tau` for slow changes),
        // discretised by the bilinear transform
        let sq2 = std::f64::consts::SQRT_2;
        let c = (alpha / sq2).tan();
        let d = c * c + sq2 * c + 1.0;
        let b0 = c * c / d;
        LpGains {
            alpha,
            alpha_band: (dt / MOTION_BAND_TAU_S).min(1.0),
            bw: [b0, 2.0 * b0, b0, 2.0 * (c * c - 1.0) / d, (1.0 - sq2 * c + c * c) / d],
        }
    }
}

/// The low-passed specific force (g, navigation frame) and the motion
/// band's mean square.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GravityLp {
    /// The Butterworth's output: gravity, for a free unit.
    pub gravity: [f64; 3],
    /// The Butterworth's two states (direct form II transposed).
    bw: [[f64; 3]; 2],
    /// Low-passed over `accel_tau_s`, first order: the motion band's floor.
    pub lp: [f64; 3],
    /// Low-passed over `MOTION_BAND_TAU_S`.
    band: [f64; 3],
    /// Mean square of the horizontal `band - lp`, low-passed over
    /// `accel_tau_s`, g^2.
    pub motion_var: f64,
    /// Samples taken since `new` while warming up (`push`).
    n: u32,
}

impl GravityLp {
    /// Settled on a constant `f`.
    pub fn new(f: &[f64; 3], g: &LpGains) -> GravityLp {
        let mut lp = GravityLp { gravity: *f, bw: [[0.0; 3]; 2], lp: *f, band: *f, motion_var: 0.0, n: 1 };
        lp.settle(g);
        lp
    }

    /// The Butterworth's states settled on `gravity`.
    fn settle(&mut self, g: &LpGains) {
        let [_, b1, b2, a1, a2] = g.bw;
        for i in 0..3 {
            self.bw[1][i] = (b2 - a2) * self.gravity[i];
            self.bw[0][i] = (b1 - a1) * self.gravity[i] + self.bw[1][i];
        }
    }

    /// One sample `f` with this step's gains.
    ///
    /// Until `accel_tau_s` worth of samples has been taken the low-passes
    /// are the mean of the samples so far (weight `1 / n`, as VQF's
    /// low-pass starts), the Butterworth held settled on it: started from
    /// its first sample alone, a unit powered on in a hand's motion held
    /// that one sample (10 g of it on broad-18) for seconds, and a
    /// re-levelling to it in the first seconds turned the tilt to it.
    #[inline]
    pub fn push(&mut self, f: &[f64; 3], g: &LpGains) {
        if self.n > 0 {
            self.n += 1;
            let k = 1.0 / self.n as f64;
            if k > g.alpha {
                let kb = k.max(g.alpha_band);
                for i in 0..3 {
                    self.gravity[i] += (f[i] - self.gravity[i]) * k;
                    self.lp[i] += (f[i] - self.lp[i]) * k;
                    self.band[i] += (f[i] - self.band[i]) * kb;
                }
                let (dn, de) = (self.band[0] - self.lp[0], self.band[1] - self.lp[1]);
                self.motion_var += (dn * dn + de * de - self.motion_var) * k;
                self.settle(g);
                return;
            }
            self.n = 0;
        }
        let [b0, b1, b2, a1, a2] = g.bw;
        for i in 0..3 {
            let x = f[i];
            let y = b0 * x + self.bw[0][i];
            self.bw[0][i] = b1 * x - a1 * y + self.bw[1][i];
            self.bw[1][i] = b2 * x - a2 * y;
            self.gravity[i] = y;
            self.lp[i] += (x - self.lp[i]) * g.alpha;
            self.band[i] += (x - self.band[i]) * g.alpha_band;
        }
        let (dn, de) = (self.band[0] - self.lp[0], self.band[1] - self.lp[1]);
        self.motion_var += (dn * dn + de * de - self.motion_var) * g.alpha;
    }

    /// The navigation frame was turned by `r` (a correction of the
    /// attitude): the stored forces turn with it.
    pub fn rotate(&mut self, r: &Mat3) {
        self.gravity = rotate(r, &self.gravity);
        self.bw = [rotate(r, &self.bw[0]), rotate(r, &self.bw[1])];
        self.lp = rotate(r, &self.lp);
        self.band = rotate(r, &self.band);
    }

    /// The variance of the tilt taken from `gravity` (rad^2): the floor
    /// `base_var` plus `share2` of the motion band's mean square.
    pub fn tilt_var(&self, base_var: f64, share2: f64) -> f64 {
        base_var + share2 * self.motion_var
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(f: impl Fn(f64) -> [f64; 3], secs: f64) -> GravityLp {
        let gains = LpGains::new(0.005, 3.0);
        let mut g = GravityLp::new(&f(0.0), &gains);
        let mut t = 0.0;
        while t < secs {
            t += 0.005;
            g.push(&f(t), &gains);
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
    fn the_butterworth_keeps_a_fiftieth_of_a_hands_motion_and_all_of_gravity() {
        // settled on a constant force: gravity is that force
        let g = run(|_| [0.1, -0.2, -0.97], 5.0);
        for i in 0..3 {
            // (rounding over 1,000 steps of a filter with poles near 1)
            assert!((g.gravity[i] - [0.1, -0.2, -0.97][i]).abs() < 1e-10, "{:?}", g.gravity);
        }
        // 0.3 g back and forth at 0.5 Hz: the Butterworth passes
        // 1 / sqrt(1 + (w / wc)^4) = 0.0225 of it (wc = sqrt(2) / 3 s), the
        // first-order low-pass 1 / sqrt(1 + (w tau)^2) = 0.105
        let w = std::f64::consts::PI;
        let gains = LpGains::new(0.005, 3.0);
        let mut g = GravityLp::new(&[0.0, 0.0, -1.0], &gains);
        let (mut bw_max, mut lp_max) = (0.0f64, 0.0f64);
        for k in 1..=(40.0 / 0.005) as u32 {
            let t = k as f64 * 0.005;
            g.push(&[0.3 * (w * t).sin(), 0.0, -1.0], &gains);
            if t > 30.0 {
                bw_max = bw_max.max(g.gravity[0].abs());
                lp_max = lp_max.max(g.lp[0].abs());
            }
        }
        let wc = std::f64::consts::SQRT_2 / 3.0;
        let expect_bw = 0.3 / (1.0 + (w / wc).powi(4)).sqrt();
        let expect_lp = 0.3 / (1.0 + (3.0 * w).powi(2)).sqrt();
        assert!((bw_max / expect_bw - 1.0).abs() < 0.05, "{bw_max} against {expect_bw}");
        assert!((lp_max / expect_lp - 1.0).abs() < 0.05, "{lp_max} against {expect_lp}");
    }

    #[test]
    fn vibration_far_above_the_band_is_not_motion() {
        // 0.3 g at 50 Hz (a phone buzzing against the unit, an engine)
        let buzz = run(|t| [0.3 * (2.0 * std::f64::consts::PI * 50.0 * t).sin(), 0.0, -1.0], 30.0);
        let hand = run(|t| [0.3 * (std::f64::consts::PI * t).sin(), 0.0, -1.0], 30.0);
        assert!(buzz.motion_var < 0.01 * hand.motion_var, "{} against {}", buzz.motion_var, hand.motion_var);
    }

    #[test]
    fn a_first_sample_in_a_hands_motion_is_one_sample_of_the_mean() {
        // powered on in the middle of a 10 g jerk, then gravity alone: the
        // low-passed gravity is the mean of what came so far (VQF's start),
        // not the first sample held by a low-pass settled on it
        let gains = LpGains::new(1.0 / 286.0, 3.0);
        let mut g = GravityLp::new(&[10.0, 0.0, -1.0], &gains);
        let tilt = |g: &GravityLp| (g.gravity[0].hypot(g.gravity[1])).atan2(-g.gravity[2]).to_degrees();
        let mut at = Vec::new();
        for k in 1..=(286 * 4) {
            g.push(&[0.0, 0.0, -1.0], &gains);
            if k % 286 == 0 {
                at.push(tilt(&g));
            }
        }
        // the mean of one 10 g sample and k - 1 of gravity: atan(10 / k)
        assert!((at[0] - (10.0f64 / 286.0).atan().to_degrees()).abs() < 0.01, "after 1 s: {:?}", at);
        assert!((at[1] - (10.0f64 / 572.0).atan().to_degrees()).abs() < 0.01, "after 2 s: {:?}", at);
        // past `accel_tau_s` the Butterworth goes on from there
        assert!(at[3] < at[2] && at[2] < 1.0, "{at:?}");
        // settled on the first sample instead, it held 84 deg a second on
        let mut held = GravityLp::new(&[10.0, 0.0, -1.0], &gains);
        held.n = 0;
        for _ in 0..286 {
            held.push(&[0.0, 0.0, -1.0], &gains);
        }
        assert!(tilt(&held) > 60.0, "{}", tilt(&held));
    }

    #[test]
    fn a_turn_of_the_frame_turns_the_forces_and_keeps_the_motion() {
        let mut g = run(|t| [0.2 * (std::f64::consts::PI * t).sin(), 0.1, -1.0], 10.0);
        let before = g;
        let r = crate::estimator::quat::to_matrix(&crate::estimator::quat::from_rotvec(&[0.0, 0.0, 0.7]));
        g.rotate(&r);
        assert_eq!(g.motion_var, before.motion_var);
        let h = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1]).sqrt();
        for (now, was) in [(g.lp, before.lp), (g.gravity, before.gravity), (g.bw[0], before.bw[0]), (g.bw[1], before.bw[1])] {
            assert!((now[2] - was[2]).abs() < 1e-15);
            assert!((h(now) - h(was)).abs() < 1e-15);
        }
        assert!((g.lp[0] - before.lp[0]).abs() > 1e-3);
        assert!((g.gravity[0] - before.gravity[0]).abs() > 1e-3);
        // and the Butterworth goes on from the turned states as if its
        // input had always been turned
        let mut turned = run(|t| rotate(&r, &[0.2 * (std::f64::consts::PI * t).sin(), 0.1, -1.0]), 10.0);
        let gains = LpGains::new(0.005, 3.0);
        for k in 1..=400 {
            let t = 10.0 + k as f64 * 0.005;
            let f = rotate(&r, &[0.2 * (std::f64::consts::PI * t).sin(), 0.1, -1.0]);
            g.push(&f, &gains);
            turned.push(&f, &gains);
        }
        for i in 0..3 {
            assert!((g.gravity[i] - turned.gravity[i]).abs() < 1e-9, "{:?} against {:?}", g.gravity, turned.gravity);
        }
    }
}
