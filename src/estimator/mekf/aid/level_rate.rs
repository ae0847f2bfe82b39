//! The level rate: a car powered on while driving, before a standstill has
//! read its bias. Its body cannot keep rolling or pitching, so over a
//! window of `LEVEL_WINDOW_S` the raw gyro's turn about the horizontal is
//! the bias's.

use crate::estimator::mekf::*;

/// The window: seconds, Σ C dt, Σ C ω_raw dt.
#[derive(Clone, Debug, Default)]
pub(in crate::estimator::mekf) struct LevelWindow {
    pub t: f64,
    pub s_c: Mat3,
    pub s_cg: [f64; 3],
}

impl Mekf {
    /// Over a window of `LEVEL_WINDOW_S` the raw gyro's turn about the
    /// horizontal is the bias's, `C̄ b` (`C̄` the attitude averaged over the
    /// window), within `LEVEL_RATE_SIGMA`. This holds under any acceleration
    /// (the accelerometer is not used), and is left out on windows that turn
    /// about the vertical by more than `LEVEL_TURN_MAX` (a tilt error would
    /// put part of the turn on the horizontal). Without it, IMU only on a
    /// straight road, nothing but the vehicle constraint at a speed the
    /// filter does not know told the roll and pitch axes' bias: a 2 deg/s
    /// pitch bias ran the comma2k19 car's pitch 7 deg off in 2 s.
    /// Called once per tick with the tick's sums; updates once per window,
    /// and the level roll with it (`fuse_level_roll`).
    pub(in crate::estimator::mekf) fn fuse_level_rate(&mut self, t: f64, s_c: &Mat3, s_cg: &[f64; 3], gain: Gain) {
        let lw = &mut self.level;
        lw.t += t;
        for i in 0..3 {
            lw.s_cg[i] += s_cg[i];
            for j in 0..3 {
                lw.s_c[i][j] += s_c[i][j];
            }
        }
        if lw.t < LEVEL_WINDOW_S {
            self.aid.set(Aid::LevelRate, AidStatus::NotApplicable(Why::Window));
            return;
        }
        let LevelWindow { t: w, s_c: c, s_cg: g } = std::mem::take(&mut self.level);
        self.counters.rules.note(Rule::LevelRate);
        if self.mag_on != Some(true) {
            self.fuse_level_roll(gain);
        } else {
            self.aid.set(Aid::LevelRoll, AidStatus::NotApplicable(Why::HeadingReference));
        }
        let b = self.core.bias();
        // the mean navigation-frame rate, bias-corrected
        let r: [f64; 3] = std::array::from_fn(|k| (g[k] - (0..3).map(|j| c[k][j] * b[j]).sum::<f64>()) / w);
        if r[2].abs() > LEVEL_TURN_MAX {
            self.aid.set(Aid::LevelRate, AidStatus::NotApplicable(Why::Turning));
            return;
        }
        let mut s = AidStatus::NotApplicable(Why::Unobservable);
        for k in 0..2 {
            let mut h = [0.0; N];
            for j in 0..3 {
                h[BI + j] = -c[k][j] / w;
            }
            s = s.and_row(self.update(&h, -r[k], LEVEL_RATE_SIGMA * LEVEL_RATE_SIGMA, gain, self.p.gate));
        }
        self.aid.set(Aid::LevelRate, s);
    }

    /// `fuse_level_rate` runs (and the samples feed its window): a car,
    /// IMU only, before a standstill has read its bias. Between ticks this
    /// only turns false (the vehicle model left), never true.
    #[inline]
    pub(in crate::estimator::mekf) fn learns_level_rate(&self) -> bool {
        self.vehicle && !self.bias_known && !self.p.speed_aided && self.on(Rule::LevelRate)
    }

    /// Why the level rate does not run (`learns_level_rate` false).
    pub(in crate::estimator::mekf) fn level_rate_why(&self) -> Why {
        if !self.vehicle {
            Why::NotVehicle
        } else if self.bias_known {
            Why::BiasKnown
        } else if self.p.speed_aided {
            Why::Wheels
        } else {
            Why::RuleOff
        }
    }
}
