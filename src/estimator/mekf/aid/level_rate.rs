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
    /// (the accelerometer is not used). In a turn a tilt error puts part of
    /// the turn on the horizontal: the row carries that term, so the window
    /// tells the tilt as well as the bias. (Windows turning faster than 3
    /// deg/s were left out instead: a car powered on at 14 m/s with a 4
    /// deg/s z bias looked to be turning on every window, its 2 deg/s pitch
    /// bias went unread for 9 s and its pitch ran 10 deg off, `smooth
    /// --power-on-moving` seed 6.) Without it, IMU only on a
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
        // r is what the filter's attitude makes of the body's rate. With a
        // tilt error δθ (true C = (I + [δθ×]) Ĉ) the true rate is
        // r + δθ × r - C̄ δb: in a turn part of r_z lands on the
        // horizontal. δθ over the window is its mean, δθ + C̄ δb w/2 (the
        // bias error turns the tilt at -C δb).
        let rx = [[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]];
        let mut s = AidStatus::NotApplicable(Why::Unobservable);
        for k in 0..2 {
            let mut h = [0.0; N];
            for j in 0..3 {
                h[TH + j] = -rx[k][j];
                h[BI + j] = -c[k][j] / w - 0.5 * (0..3).map(|m| rx[k][m] * c[m][j]).sum::<f64>();
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
