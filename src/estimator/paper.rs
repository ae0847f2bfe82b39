//! The paper's method, faithful (`mode = "paper"`), and its comparison cases
//! (`startup_average`, `startup_thermal`).
//!
//! - `paper`: the 6-state Euler-angle EKF (`crate::estimator::ekf`) fuses roll/pitch from
//!   the accelerometer and the magnetic heading. Inside the inner |a|/g0 band
//!   it learns the bias; between the bands a weighted blend (noise / w, no
//!   bias learning); outside, or when the acceleration-change criterion
//!   fires, gyro only with the thermal curve anchored at the last EKF bias.
//!   Warm-up exclusion for `warmup_s`; the mean EKF bias over the learning
//!   window's quasi-static samples becomes the initial bias.
//! - `startup_average` / `startup_thermal`: the paper's cases 1 and 2: the
//!   gyro integrated with the bias averaged over the learning window, without
//!   / with the thermal curve; no fusion at all.

use super::{flags, Learned, StepIn};
use crate::config::{Config, Mode};
use crate::estimator::ekf::{heading_from_mag, tilt_from_accel, wrap_pi, Ekf, Learn};
use crate::estimator::switching::{Band, Decision, Switching};
use nalgebra::Vector3;

const D2R: f64 = std::f64::consts::PI / 180.0;
const R2D: f64 = 180.0 / std::f64::consts::PI;

#[derive(Clone, Debug)]
pub struct Paper {
    mode: Mode,
    warmup: f64,
    learn_end: f64,
    declination: f64,
    use_mag: bool,
    q_gyro: f64,
    q_bias: f64,
    r_tilt: f64,
    r_yaw: f64,
    angle_sigma: f64,
    bias_sigma: f64,
    switching: Switching,
    ekf: Ekf,
    /// Learning-window accumulators (mean EKF bias / mean raw gyro).
    learn_sum: [f64; 3],
    learn_temp_sum: f64,
    learn_n: u64,
    learn_done: bool,
    /// The bias and temperature of the last quasi-static (mode 0) sample.
    last_fused: Option<(f64, [f64; 3])>,
}

impl Paper {
    pub fn new(cfg: &Config, switching: Switching, use_mag: bool) -> Paper {
        let e = &cfg.estimator;
        let k = &cfg.ekf;
        Paper {
            mode: e.mode,
            warmup: e.warmup_s,
            learn_end: e.warmup_s + e.learn_s,
            declination: e.declination_deg * D2R,
            use_mag,
            q_gyro: (k.gyro_noise * D2R).powi(2),
            q_bias: (k.bias_walk * D2R).powi(2),
            r_tilt: (k.tilt_sigma_deg * D2R).powi(2),
            r_yaw: (k.yaw_sigma_deg * D2R).powi(2),
            angle_sigma: k.init_angle_sigma_deg * D2R,
            bias_sigma: cfg.init_bias_sigma() * D2R,
            switching,
            ekf: Ekf::new(Vector3::zeros(), Vector3::zeros(), 1.0, 1.0),
            learn_sum: [0.0; 3],
            learn_temp_sum: 0.0,
            learn_n: 0,
            learn_done: false,
            last_fused: None,
        }
    }

    fn measure(&self, s: &StepIn, roll: f64, pitch: f64) -> Vector3<f64> {
        let (r, p) = tilt_from_accel(&s.accel);
        let y = if self.use_mag { wrap_pi(heading_from_mag(&s.magn, roll, pitch) + self.declination) } else { 0.0 };
        Vector3::new(r, p, y)
    }

    /// Start on the first sample with the given initial bias (deg/s).
    pub fn start(&mut self, s: &StepIn, bias: [f64; 3], prior_sigma: Option<[f64; 3]>) {
        let (r, p) = tilt_from_accel(&s.accel);
        let z = self.measure(s, r, p);
        let b = Vector3::from(bias) * D2R;
        self.ekf = Ekf::new(z, b, self.angle_sigma, self.bias_sigma);
        if let Some(sig) = prior_sigma {
            for i in 0..3 {
                let sig = (sig[i] * D2R).max(1e-4 * D2R);
                self.ekf.pbb[(i, i)] = sig * sig;
            }
        }
    }

    /// A counter gap: the angles are widened, the jerk history forgotten.
    pub fn resync(&mut self) {
        self.ekf.inflate_angles((5.0 * D2R).powi(2));
        self.switching.reset();
    }

    /// One sample; returns (mode, flags, |a|/g0, slope-learning point).
    pub fn step(&mut self, s: &StepIn, thermal_on: bool, thermal_delta: impl Fn(f64, f64) -> [f64; 3]) -> (u8, u16, f64, bool) {
        let mut fl = 0u16;
        let omega = Vector3::new(s.gyro[0], s.gyro[1], s.gyro[2]) * D2R;
        let db = Vector3::from(s.dbias) * D2R;
        if s.dt > 0.0 {
            self.ekf.predict(&omega, s.dt, self.q_gyro, self.q_bias, &db);
        } else {
            self.ekf.bias += db;
        }
        let dec = self.switching.classify(&s.accel, s.g0);
        if dec.jerk {
            fl |= flags::JERK;
        }
        let t = s.t;
        let warm = t < self.warmup;
        let learning = !warm && !self.learn_done;
        if warm {
            fl |= flags::WARMUP;
        }
        if learning {
            fl |= flags::LEARNING;
        }
        let mut mode = 2u8;
        if self.mode == Mode::Paper {
            if s.suspect {
                fl |= flags::SUSPECT;
            } else if !dec.jerk && dec.band != Band::Outside {
                mode = self.fuse(s, &dec, warm);
            }
            if learning && mode == 0 {
                self.learn_point(self.bias_deg(), s.temp);
            }
        } else if s.suspect {
            fl |= flags::SUSPECT;
        } else if learning {
            self.learn_point(s.gyro, s.temp);
        }
        // the slope learner takes quasi-static samples after the learning window
        let slope_point = self.mode == Mode::Paper && mode == 0 && self.learn_done;

        if !self.learn_done && t >= self.learn_end && !warm {
            self.end_learning(s.temp, thermal_on, thermal_delta);
        }
        (mode, fl, dec.ratio, slope_point)
    }

    /// `paper`, a sample inside the outer band without a jerk: the EKF
    /// fuses roll/pitch from the accelerometer and the magnetic heading.
    /// Inside the inner band it learns the bias too (after the warm-up;
    /// mode 0); between the bands it blends (mode 1). Returns the mode.
    fn fuse(&mut self, s: &StepIn, dec: &Decision, warm: bool) -> u8 {
        let z = self.measure(s, self.ekf.att[0], self.ekf.att[1]);
        if dec.band == Band::Inner {
            let r = Vector3::new(self.r_tilt, self.r_tilt, self.r_yaw);
            let learn = if warm { Learn::AnglesOnly } else { Learn::AnglesAndBias };
            self.ekf.update(&z, &r, self.use_mag, learn);
            if !warm {
                self.last_fused = Some((s.temp, self.bias_deg()));
            }
            0
        } else {
            // Blend: the accelerometer's weight falls linearly from the
            // inner to the outer band edge; its noise grows as 1/w.
            let w = dec.weight.max(1e-3);
            let r = Vector3::new(self.r_tilt / w, self.r_tilt / w, self.r_yaw / w);
            self.ekf.update(&z, &r, self.use_mag, Learn::AnglesOnly);
            1
        }
    }

    /// One point of the learning window (deg/s: the EKF bias in `paper`,
    /// the raw gyro in the comparison cases) at `temp` deg C.
    fn learn_point(&mut self, b: [f64; 3], temp: f64) {
        for k in 0..3 {
            self.learn_sum[k] += b[k];
        }
        self.learn_temp_sum += temp;
        self.learn_n += 1;
    }

    /// The learning window is over (`temp` deg C now): its mean becomes the
    /// bias, carried by the thermal curve from the window's mean
    /// temperature to now.
    fn end_learning(&mut self, temp: f64, thermal_on: bool, thermal_delta: impl Fn(f64, f64) -> [f64; 3]) {
        self.learn_done = true;
        if self.learn_n > 0 {
            let n = self.learn_n as f64;
            let tm = self.learn_temp_sum / n;
            let d = if thermal_on { thermal_delta(tm, temp) } else { [0.0; 3] };
            for k in 0..3 {
                self.ekf.bias[k] = (self.learn_sum[k] / n + d[k]) * D2R;
            }
            if self.mode == Mode::Paper {
                self.last_fused = Some((temp, self.bias_deg()));
            }
        }
    }

    pub fn state_is_finite(&self) -> bool {
        self.ekf.state_is_finite()
    }

    /// Roll, pitch, yaw (rad).
    pub fn attitude(&self) -> [f64; 3] {
        [self.ekf.att[0], self.ekf.att[1], self.ekf.att[2]]
    }

    pub fn bias_deg(&self) -> [f64; 3] {
        [self.ekf.bias[0] * R2D, self.ekf.bias[1] * R2D, self.ekf.bias[2] * R2D]
    }

    /// The bias of the last quasi-static sample, for saving.
    pub fn learned(&self) -> Option<Learned> {
        let (temp, bias) = self.last_fused?;
        let s = |i: usize| self.ekf.pbb[(i, i)].max(0.0).sqrt() * R2D;
        Some(Learned { bias, bias_sigma: [s(0), s(1), s(2)], temp })
    }

    /// The EKF (for tests and diagnostics).
    pub fn ekf(&self) -> &Ekf {
        &self.ekf
    }
}
