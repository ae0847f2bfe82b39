//! The estimator: `step(sample) -> estimate`. Pure: no I/O, no clock, no
//! allocation per step. The daemon and `gyrocomp replay` both call it.
//!
//! Modes (`[estimator] mode`):
//! - `paper`: the published method. EKF bias learning in the inner band,
//!   weighted blend between the bands, gyro only outside with the thermal
//!   curve anchored at the last EKF bias; jerk criterion; warm-up exclusion;
//!   the mean EKF bias over the learning window becomes the initial bias.
//! - `robust` (the default): the paper's structure with the guards of
//!   `[robust]` (see `step_robust` and README "Accuracy beyond the paper").
//! - `startup_thermal`, `startup_average`: the paper's comparison cases 2 and
//!   1: the gyro integrated with the bias averaged over the learning window,
//!   with / without the thermal curve; no fusion at all.
//!
//! Thermal curve (`[thermal]`, see `thermal`): polynomial up to third order,
//! evaluated at the nearest edge outside `[t_min, t_max]`, with
//! `flags::THERMAL_CLAMP` on every sample where that happens (modes that use
//! the curve). With `[thermal] learn = true` (mode `paper` only: it needs the
//! EKF's bias) a `SlopeLearner` refines `p1` from the bias held in
//! quasi-static samples after the learning window and `learn_after_s`;
//! `slope_state` / `set_slope_state` save and restore what it learned.

use crate::adis::Sample;
use crate::config::{Config, Mode};
use crate::ekf::{heading_from_mag, heading_from_mag_trig, tilt_from_accel, wrap_pi, Ekf, Learn};
use crate::switching::{Band, Switching};
use crate::thermal::{SlopeLearner, SlopeParams, SlopeState, Thermal};
use crate::vehicle::{self, ProcessNoise, Update, VehicleTilt};
use nalgebra::Vector3;

const D2R: f64 = std::f64::consts::PI / 180.0;
const R2D: f64 = 180.0 / std::f64::consts::PI;

/// Health flags carried in `EST_STATUS` (bit numbers are the DBC's).
pub mod flags {
    /// DIAG_STAT != 0: the sample was not fused.
    pub const SUSPECT: u16 = 1 << 0;
    /// Inside the warm-up exclusion: the bias is not learned.
    pub const WARMUP: u16 = 1 << 1;
    /// Inside the learning window.
    pub const LEARNING: u16 = 1 << 2;
    /// A counter gap or restart: attitude was not integrated over it.
    pub const RESYNC: u16 = 1 << 3;
    /// The acceleration-change criterion fired.
    pub const JERK: u16 = 1 << 4;
    /// Temperature outside the thermal curve's calibrated range (clamped).
    pub const THERMAL_CLAMP: u16 = 1 << 5;
    /// An output rate saturated its signal range.
    pub const RATE_SAT: u16 = 1 << 6;
    /// No input sample for `daemon.silent_after_s` (set by the daemon).
    pub const BUS_SILENT: u16 = 1 << 7;
    /// g0 is still being measured.
    pub const INIT: u16 = 1 << 8;
    /// A measurement was refused by the innovation gate.
    pub const GATED: u16 = 1 << 9;
    /// Output frames were dropped on write since the last status (set by the daemon).
    pub const TX_DROP: u16 = 1 << 10;
}

/// What the estimator says about one sample. Angles deg, rates deg/s.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Estimate {
    pub cnt: u16,
    pub t_us: u64,
    /// Seconds since the first sample, from the sample counter.
    pub t: f64,
    pub roll: f64,
    pub pitch: f64,
    pub yaw: f64,
    /// Bias-corrected rates.
    pub rate: [f64; 3],
    pub bias: [f64; 3],
    /// 0 fusion (inner band), 1 blend, 2 gyro only / thermal.
    pub mode: u8,
    pub temp: f64,
    pub flags: u16,
    /// |a| / g0.
    pub ratio: f64,
}

/// What the estimator learned, for the daemon's state file.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Learned {
    /// Bias, deg/s.
    pub bias: [f64; 3],
    /// 1-sigma of the bias, deg/s.
    pub bias_sigma: [f64; 3],
    /// Temperature at which the bias was held, deg C.
    pub temp: f64,
}

#[derive(Clone, Debug)]
pub struct Estimator {
    mode: Mode,
    period: f64,
    max_gap: f64,
    g0_window: f64,
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
    thermal: Thermal,
    /// The configured curve (`thermal` = this plus the learned slope correction).
    thermal_base: Thermal,
    /// Field learning of the slope (`[thermal] learn`), and when it may start (s).
    slope: Option<SlopeLearner>,
    slope_after: f64,
    switching: Switching,
    ekf: Ekf,
    started: bool,
    t: f64,
    g0: f64,
    g0_sum: f64,
    g0_n: u64,
    temp_prev: f64,
    /// Learning-window accumulators (mean EKF bias / mean raw gyro).
    learn_sum: [f64; 3],
    learn_temp_sum: f64,
    learn_n: u64,
    learn_done: bool,
    /// A bias given from outside (the daemon's state file) at start.
    prior: Option<Learned>,
    /// The bias and temperature of the last quasi-static (mode 0) sample.
    last_fused: Option<(f64, [f64; 3])>,
    robust: Robust,
}

/// State and settings of `mode = "robust"`.
#[derive(Clone, Debug)]
struct Robust {
    /// Low-pass time constant (s), dwell (s), turn-rate gate (rad/s),
    /// NIS gate, lock-out (s), variance of f_x (or f_y) as tilt, g^2.
    tau: f64,
    dwell_need: f64,
    turn_rate: f64,
    gate: f64,
    lockout: f64,
    r_tilt: f64,
    blend: bool,
    /// Gyro-compensated low-passed specific force, g (None until the first sample).
    f_lp: Option<Vector3<f64>>,
    /// The yaw / z-bias filter: yaw (rad), z bias (rad/s), covariance.
    yaw: f64,
    yaw_bz: f64,
    yaw_p: [[f64; 2]; 2],
    /// Low-passed heading rate (rad/s).
    yaw_rate_lp: f64,
    /// Seconds the quasi-static conditions have held.
    dwell: f64,
    /// Seconds of refused tilt measurements under quasi-static conditions.
    refused: f64,
    /// Mode of the last tilt update attempt (0 fused, 1 blended, 2 refused or none).
    held: u8,
    /// Seconds between tilt updates, and since the last one.
    fuse_every: f64,
    since_fuse: f64,
    /// The tilt / x-y bias / speed filter, and whether it has started.
    vt: VehicleTilt,
    on: bool,
    /// Use the ground-vehicle model (lateral specific force fused always).
    vehicle: bool,
    /// Lateral specific-force variance, g^2; process noise; initial speed sigma, m/s.
    r_lat: f64,
    qn: ProcessNoise,
    speed_sigma0: f64,
    /// Low-passed bias-corrected body z rate, rad/s.
    r_lp: f64,
}

impl Robust {
    /// The accelerometer as tilt: `f_x` as pitch and, without the vehicle
    /// model, `f_y` as roll, each with variance `r`, gated. True when every
    /// update was fused.
    fn tilt_update(&mut self, f_lp: &Vector3<f64>, r: f64, learn_bias: bool) -> bool {
        let (h, row) = self.vt.longitudinal();
        let mut ok = matches!(self.vt.update(f_lp[0] - h, &row, r, learn_bias, self.gate), Update::Fused(_));
        if !self.vehicle {
            let (h, row) = self.vt.lateral(0.0);
            ok &= matches!(self.vt.update(f_lp[1] - h, &row, r, learn_bias, self.gate), Update::Fused(_));
        }
        ok
    }
}

impl Estimator {
    pub fn new(cfg: &Config) -> Estimator {
        let p = cfg.profile();
        let e = &cfg.estimator;
        let k = &cfg.ekf;
        let q_gyro = (k.gyro_noise * D2R).powi(2);
        let q_bias = (k.bias_walk * D2R).powi(2);
        Estimator {
            mode: e.mode,
            period: 1.0 / p.rate_hz,
            max_gap: e.max_gap_s,
            g0_window: e.g0_window_s,
            warmup: e.warmup_s,
            learn_end: e.warmup_s + e.learn_s,
            declination: e.declination_deg * D2R,
            use_mag: e.use_magnetometer && p.magnetometer,
            q_gyro,
            q_bias,
            r_tilt: (k.tilt_sigma_deg * D2R).powi(2),
            r_yaw: (k.yaw_sigma_deg * D2R).powi(2),
            angle_sigma: k.init_angle_sigma_deg * D2R,
            bias_sigma: k.init_bias_sigma * D2R,
            thermal: Thermal::new(&cfg.thermal),
            thermal_base: Thermal::new(&cfg.thermal),
            slope: cfg.thermal.learn.then(|| {
                let th = &cfg.thermal;
                SlopeLearner::new(SlopeParams { min_spread: th.learn_min_spread, max_dev: th.learn_max_dev }, th.p1)
            }),
            slope_after: cfg.thermal.learn_after_s,
            switching: Switching::new(&cfg.switching, p.rate_hz),
            ekf: Ekf::new(Vector3::zeros(), Vector3::zeros(), 1.0, 1.0),
            started: false,
            t: 0.0,
            g0: 1.0,
            g0_sum: 0.0,
            g0_n: 0,
            temp_prev: 0.0,
            learn_sum: [0.0; 3],
            learn_temp_sum: 0.0,
            learn_n: 0,
            learn_done: false,
            prior: None,
            last_fused: None,
            robust: Robust {
                tau: cfg.robust.accel_tau_s,
                dwell_need: cfg.robust.dwell_s,
                turn_rate: cfg.robust.turn_rate_dps * D2R,
                gate: cfg.robust.gate_sigma * cfg.robust.gate_sigma,
                lockout: cfg.robust.lockout_s,
                r_tilt: (cfg.robust.tilt_sigma_deg * D2R).sin().powi(2),
                blend: cfg.robust.blend,
                f_lp: None,
                yaw_rate_lp: 0.0,
                yaw: 0.0,
                yaw_bz: 0.0,
                yaw_p: [[0.0; 2]; 2],
                dwell: 0.0,
                refused: 0.0,
                held: 2,
                fuse_every: cfg.robust.fuse_every_s,
                since_fuse: 0.0,
                vt: VehicleTilt::new(0.0, 0.0, [0.0; 2], 0.0, [0.0; 3]),
                on: false,
                vehicle: cfg.robust.vehicle_model,
                r_lat: cfg.robust.lateral_sigma_g.powi(2),
                qn: ProcessNoise { gyro: q_gyro, bias: q_bias, speed: cfg.robust.speed_noise.powi(2) },
                speed_sigma0: cfg.robust.init_speed_sigma,
                r_lp: 0.0,
            },
        }
    }

    /// Start from a bias learned earlier (loaded before the first sample).
    /// It replaces the thermal curve's absolute value as the prior; the
    /// learning window still runs and refines it.
    pub fn set_prior(&mut self, prior: Learned) {
        self.prior = Some(prior);
    }

    /// The bias the estimator holds now and at what temperature, for saving.
    /// Prefers the bias of the last quasi-static sample (what the EKF learned).
    pub fn learned(&self) -> Option<Learned> {
        if !self.started {
            return self.prior;
        }
        let (temp, bias) = match self.last_fused {
            Some(lf) => lf,
            None => return self.prior,
        };
        let s = |i: usize| self.ekf.pbb[(i, i)].max(0.0).sqrt() * R2D;
        Some(Learned { bias, bias_sigma: [s(0), s(1), s(2)], temp })
    }

    /// The thermal curve in use (its `p1` includes the learned correction).
    pub fn thermal(&self) -> &Thermal {
        &self.thermal
    }

    /// What the slope learner has learned (None when `[thermal] learn` is off), for saving.
    pub fn slope_state(&self) -> Option<SlopeState> {
        self.slope.as_ref().map(|l| l.state())
    }

    /// Continue slope learning from a saved state (before the first sample).
    /// False when learning is off or the state was saved under another `p1`.
    pub fn set_slope_state(&mut self, st: &SlopeState) -> bool {
        let ok = self.slope.as_mut().is_some_and(|l| l.restore(st));
        self.apply_slope();
        ok
    }

    fn apply_slope(&mut self) {
        if let Some(l) = &self.slope {
            let c = l.correction();
            for i in 0..3 {
                self.thermal.p1[i] = self.thermal_base.p1[i] + c[i];
            }
        }
    }

    pub fn g0(&self) -> f64 {
        self.g0
    }

    fn measure(&self, s: &Sample, roll: f64, pitch: f64) -> Vector3<f64> {
        let (r, p) = tilt_from_accel(&s.accel);
        let y = if self.use_mag { wrap_pi(heading_from_mag(&s.magn, roll, pitch) + self.declination) } else { 0.0 };
        Vector3::new(r, p, y)
    }

    fn start(&mut self, s: &Sample) {
        let (r, p) = tilt_from_accel(&s.accel);
        let z = self.measure(s, r, p);
        let bias = match (&self.prior, self.mode) {
            (Some(pr), _) => {
                let d = self.thermal.delta(pr.temp, s.temp);
                [pr.bias[0] + d[0], pr.bias[1] + d[1], pr.bias[2] + d[2]]
            }
            (None, Mode::StartupAverage) => [0.0; 3],
            (None, _) => self.thermal.bias(s.temp),
        };
        let b = Vector3::from(bias) * D2R;
        self.ekf = Ekf::new(z, b, self.angle_sigma, self.bias_sigma);
        if let Some(pr) = &self.prior {
            for i in 0..3 {
                let sig = (pr.bias_sigma[i] * D2R).max(1e-4 * D2R);
                self.ekf.pbb[(i, i)] = sig * sig;
            }
        }
        self.temp_prev = s.temp;
        self.started = true;
        self.robust.on = false;
        self.t = 0.0;
    }

    /// Step the estimator on one sample.
    pub fn step(&mut self, s: &Sample) -> Estimate {
        let mut fl = 0u16;
        let mut dt = s.steps as f64 * self.period;
        let mut resync = false;
        if !self.started {
            self.start(s);
            dt = 0.0;
        } else if s.steps == 0 || dt > self.max_gap {
            // Unknown or long gap: do not integrate the gyro across it.
            fl |= flags::RESYNC;
            resync = true;
            dt = self.period;
            self.ekf.inflate_angles((5.0 * D2R).powi(2));
            self.switching.reset();
        }
        self.t += dt;
        let t = self.t;

        // g0: mean |a| over the first g0_window seconds.
        if t < self.g0_window || self.g0_n == 0 {
            let amag = (s.accel[0] * s.accel[0] + s.accel[1] * s.accel[1] + s.accel[2] * s.accel[2]).sqrt();
            if amag > 0.0 {
                self.g0_sum += amag;
                self.g0_n += 1;
                self.g0 = self.g0_sum / self.g0_n as f64;
            }
            fl |= flags::INIT;
        }

        // Predict: the gyro drives the angles; the thermal curve moves the bias.
        let omega = Vector3::new(s.gyro[0], s.gyro[1], s.gyro[2]) * D2R;
        let thermal_on = self.mode != Mode::StartupAverage;
        if thermal_on && self.thermal.clamps(s.temp) {
            fl |= flags::THERMAL_CLAMP;
        }
        let db = if thermal_on { Vector3::from(self.thermal.delta(self.temp_prev, s.temp)) * D2R } else { Vector3::zeros() };
        self.temp_prev = s.temp;
        if self.mode == Mode::Robust {
            // step_robust predicts its own filters
        } else if dt > 0.0 {
            self.ekf.predict(&omega, dt, self.q_gyro, self.q_bias, &db);
        } else {
            self.ekf.bias += db;
        }

        let dec = self.switching.classify(&s.accel, self.g0);
        if dec.jerk {
            fl |= flags::JERK;
        }
        let warm = t < self.warmup;
        let learning = !warm && !self.learn_done;
        if warm {
            fl |= flags::WARMUP;
        }
        if learning {
            fl |= flags::LEARNING;
        }

        let mut mode = 2u8;
        match self.mode {
            Mode::Paper => {
                if s.suspect() {
                    fl |= flags::SUSPECT;
                } else if !dec.jerk && dec.band != Band::Outside {
                    let z = self.measure(s, self.ekf.att[0], self.ekf.att[1]);
                    if dec.band == Band::Inner {
                        let r = Vector3::new(self.r_tilt, self.r_tilt, self.r_yaw);
                        let learn = if warm { Learn::AnglesOnly } else { Learn::AnglesAndBias };
                        self.ekf.update(&z, &r, self.use_mag, learn);
                        mode = 0;
                        if !warm {
                            self.last_fused = Some((s.temp, self.bias_deg()));
                        }
                    } else {
                        // Blend: the accelerometer's weight falls linearly from the
                        // inner to the outer band edge; its noise grows as 1/w.
                        let w = dec.weight.max(1e-3);
                        let r = Vector3::new(self.r_tilt / w, self.r_tilt / w, self.r_yaw / w);
                        self.ekf.update(&z, &r, self.use_mag, Learn::AnglesOnly);
                        mode = 1;
                    }
                }
                if learning && mode == 0 {
                    let b = self.bias_deg();
                    for k in 0..3 {
                        self.learn_sum[k] += b[k];
                    }
                    self.learn_temp_sum += s.temp;
                    self.learn_n += 1;
                }
            }
            Mode::Robust => {
                mode = self.step_robust(s, &omega, dt, &db, dec.jerk, warm, resync, &mut fl);
            }
            Mode::StartupAverage | Mode::StartupThermal => {
                if s.suspect() {
                    fl |= flags::SUSPECT;
                } else if learning {
                    for k in 0..3 {
                        self.learn_sum[k] += s.gyro[k];
                    }
                    self.learn_temp_sum += s.temp;
                    self.learn_n += 1;
                }
            }
        }

        // Field learning of the thermal slope: quasi-static samples after the
        // learning window and `learn_after_s`, inside the calibrated range.
        if self.slope.is_some() && mode == 0 && self.learn_done && t >= self.slope_after && !self.thermal.clamps(s.temp) {
            let b = self.bias_deg();
            let c = self.thermal_base.bias(s.temp);
            if let Some(l) = self.slope.as_mut() {
                l.push(s.temp, [b[0] - c[0], b[1] - c[1], b[2] - c[2]], dt);
            }
            self.apply_slope();
        }

        if !self.learn_done && t >= self.learn_end && !warm {
            self.learn_done = true;
            if self.learn_n > 0 {
                // The window's mean becomes the bias, carried by the thermal
                // curve from the window's mean temperature to now.
                let n = self.learn_n as f64;
                let tm = self.learn_temp_sum / n;
                let d = if thermal_on { self.thermal.delta(tm, s.temp) } else { [0.0; 3] };
                for k in 0..3 {
                    self.ekf.bias[k] = (self.learn_sum[k] / n + d[k]) * D2R;
                }
                if self.mode == Mode::Paper {
                    self.last_fused = Some((s.temp, self.bias_deg()));
                }
            }
        }

        if !self.ekf.state_is_finite() {
            // Cannot happen with finite input; never let a NaN reach the bus.
            self.started = false;
            self.start(s);
            fl |= flags::RESYNC;
        }

        let bias = self.bias_deg();
        Estimate {
            cnt: s.cnt,
            t_us: s.t_us,
            t,
            roll: self.ekf.att[0] * R2D,
            pitch: self.ekf.att[1] * R2D,
            yaw: self.ekf.att[2] * R2D,
            rate: [s.gyro[0] - bias[0], s.gyro[1] - bias[1], s.gyro[2] - bias[2]],
            bias,
            mode,
            temp: s.temp,
            flags: fl,
            ratio: dec.ratio,
        }
    }

    /// One sample of `mode = "robust"`; returns the mode (0 fusion with
    /// bias learning, 1 accelerometer-aided without bias learning, 2 gyro only).
    #[allow(clippy::too_many_arguments)]
    fn step_robust(
        &mut self,
        s: &Sample,
        omega: &Vector3<f64>,
        dt: f64,
        db: &Vector3<f64>,
        jerk: bool,
        warm: bool,
        resync: bool,
        fl: &mut u16,
    ) -> u8 {
        let rb = &mut self.robust;
        if !rb.on {
            // first sample (or a restart): the filters start from the EKF's start
            let e = &self.ekf;
            rb.vt = VehicleTilt::new(e.att[0], e.att[1], [e.bias[0], e.bias[1]], 0.0, [self.angle_sigma, self.bias_sigma, rb.speed_sigma0]);
            rb.vt.p[vehicle::BX][vehicle::BX] = e.pbb[(0, 0)];
            rb.vt.p[vehicle::BY][vehicle::BY] = e.pbb[(1, 1)];
            rb.yaw = e.att[2];
            rb.yaw_bz = e.bias[2];
            rb.yaw_p = [[self.angle_sigma * self.angle_sigma, 0.0], [0.0, e.pbb[(2, 2)]]];
            rb.f_lp = None;
            rb.on = true;
        }
        if resync {
            rb.vt.inflate_angles((5.0 * D2R) * (5.0 * D2R));
        }
        // The thermal curve moves the bias (anchored at what the filters hold).
        rb.yaw_bz += db[2];
        let om = [omega[0], omega[1], omega[2]];
        if dt > 0.0 {
            rb.vt.predict(&om, rb.yaw_bz, s.accel[0], dt, &rb.qn, [db[0], db[1]]);
        } else {
            rb.vt.x[vehicle::BX] += db[0];
            rb.vt.x[vehicle::BY] += db[1];
        }
        let x = rb.vt.x;
        let w = Vector3::new(om[0] - x[vehicle::BX], om[1] - x[vehicle::BY], om[2] - rb.yaw_bz);
        let f = Vector3::new(s.accel[0], s.accel[1], s.accel[2]);
        // Gyro-compensated low-pass: a vector fixed in NED turns in the body
        // frame as df/dt = -w x f; gravity then passes without lag.
        let a = (dt / rb.tau).min(1.0);
        let f_lp = match rb.f_lp {
            None => f,
            Some(lp) => {
                let rot = lp - w.cross(&lp) * dt;
                rot + (f - rot) * a
            }
        };
        rb.f_lp = Some(f_lp);
        // The body z rate, low-passed alike, for the centripetal term.
        rb.r_lp += (w[2] - rb.r_lp) * a;
        // The band decision on the specific force less the vehicle's
        // predicted centripetal acceleration (none without the model).
        let lat = if rb.vehicle { x[vehicle::SPEED] * rb.r_lp / vehicle::G } else { 0.0 };
        let fy = f_lp[1] - lat;
        let ratio = (f_lp[0] * f_lp[0] + fy * fy + f_lp[2] * f_lp[2]).sqrt() / self.g0;
        let (band, weight) = self.switching.band(ratio);
        // Turning at speed means a centripetal acceleration that |a| hardly
        // shows (0.1 g changes |a| by 0.5 %): gate on the low-passed heading rate.
        let [sr, cr, _, cp] = rb.vt.trig;
        let yaw_rate = (sr * w[1] + cr * w[2]) / cp.max(1e-3);
        rb.yaw_rate_lp += (yaw_rate - rb.yaw_rate_lp) * a;
        let turning = rb.yaw_rate_lp.abs() > rb.turn_rate;
        let quiet = band == Band::Inner && !jerk && !turning && !s.suspect();
        rb.dwell = if quiet { rb.dwell + dt } else { 0.0 };
        if s.suspect() {
            *fl |= flags::SUSPECT;
        }
        let settled = quiet && rb.dwell >= rb.dwell_need;
        let mut mode = 2u8;
        rb.since_fuse += dt;
        // The low-passed specific force is correlated over ~tau: fuse it at
        // intervals, not every sample, so its noise is not counted many times over.
        let due = rb.since_fuse + 1e-9 >= rb.fuse_every;
        let blend_ok = rb.blend && band == Band::Blend && !jerk && !turning && !s.suspect();
        let lateral_ok = rb.vehicle && !jerk && !s.suspect();
        if !due {
            // between updates: the mode of the last update, while its conditions hold
            let holds = (rb.held == 0 && settled) || (rb.held == 1 && (blend_ok || lateral_ok));
            mode = if holds { rb.held } else { 2 };
        } else {
            rb.since_fuse = 0.0;
            let mut gated = false;
            let mut lateral_fused = false;
            if lateral_ok {
                // f_y on straights and in turns; it teaches the bias only when
                // the rest says quasi-static (the paper's structure).
                let (h, row) = rb.vt.lateral(rb.r_lp);
                match rb.vt.update(f_lp[1] - h, &row, rb.r_lat, settled && !warm, rb.gate) {
                    Update::Fused(_) => lateral_fused = true,
                    Update::Gated(_) => gated = true,
                }
            }
            if settled {
                let ok = rb.tilt_update(&f_lp, rb.r_tilt, !warm);
                if ok && (lateral_fused || !rb.vehicle) {
                    rb.refused = 0.0;
                    mode = 0;
                } else {
                    gated = true;
                    rb.refused += rb.fuse_every.max(dt);
                    if rb.refused >= rb.lockout {
                        // Refused for too long while everything says quasi-static:
                        // the filter, not the accelerometer, is wrong. Re-level on
                        // the measurement (angles only: a jump this size must not
                        // be read as a bias) with the angle covariance widened to it.
                        let r = if rb.vehicle { rb.r_lp } else { 0.0 };
                        let (h, row) = rb.vt.longitudinal();
                        let n0 = f_lp[0] - h;
                        let n1 = f_lp[1] - rb.vt.lateral(r).0;
                        rb.vt.inflate_angles(n0 * n0 + n1 * n1);
                        rb.vt.update(n0, &row, rb.r_tilt, false, f64::INFINITY);
                        let (h, row) = rb.vt.lateral(r);
                        rb.vt.update(f_lp[1] - h, &row, rb.r_tilt, false, f64::INFINITY);
                        rb.refused = 0.0;
                        mode = 0;
                    }
                }
            } else if blend_ok {
                // Angles only, noise growing as the blend weight falls; gated.
                let k = 1.0 / (weight * weight).max(1e-6);
                if rb.tilt_update(&f_lp, rb.r_tilt * k, false) {
                    mode = 1;
                } else {
                    gated = true;
                }
            }
            if mode == 2 && lateral_fused {
                mode = 1;
            }
            if gated {
                *fl |= flags::GATED;
            }
            rb.held = mode;
        }
        // The EKF holds what goes out (and what the yaw filter reads).
        let x = rb.vt.x;
        self.ekf.att[0] = x[vehicle::ROLL];
        self.ekf.att[1] = x[vehicle::PITCH];
        self.ekf.bias[0] = x[vehicle::BX];
        self.ekf.bias[1] = x[vehicle::BY];
        self.ekf.pbb[(0, 0)] = rb.vt.p[vehicle::BX][vehicle::BX];
        self.ekf.pbb[(1, 1)] = rb.vt.p[vehicle::BY][vehicle::BY];
        // Yaw: the magnetometer is not disturbed by acceleration, but its
        // heading is computed with the filter's own roll and pitch; fused
        // together with the tilt it would pull the tilt and the x/y bias
        // through their correlations with yaw. So yaw and the z bias have
        // their own two-state Kalman filter.
        self.ekf.bias[2] = rb.yaw_bz;
        self.ekf.att[2] = rb.yaw;
        let freeze = warm || !settled;
        let trig = rb.vt.trig;
        self.yaw_filter(s, omega, dt, freeze, trig);
        self.ekf.pbb[(2, 2)] = self.robust.yaw_p[1][1];
        if mode == 0 && !warm {
            self.last_fused = Some((s.temp, self.bias_deg()));
        }
        mode
    }

    /// The robust mode's yaw / z-bias filter: predict with the Euler yaw
    /// rate, update with the magnetometer heading (no yaw without one).
    /// `trig`: sin/cos of the roll and pitch the EKF holds.
    fn yaw_filter(&mut self, s: &Sample, omega: &Vector3<f64>, dt: f64, freeze_bias: bool, trig: [f64; 4]) {
        let rb = &mut self.robust;
        let [sr, cr, _, cp] = trig;
        let cp = cp.max(1e-3);
        let g = cr / cp;
        if dt > 0.0 {
            let w = omega - self.ekf.bias;
            // yaw rate with the filter's z bias (ekf.bias[2] was set to it)
            let rate = (sr * w[1] + cr * w[2]) / cp;
            rb.yaw = wrap_pi(rb.yaw + rate * dt);
            // P = F P F^T + Q, F = [[1, -g dt], [0, 1]]
            let p = rb.yaw_p;
            let a = -g * dt;
            let p00 = p[0][0] + 2.0 * a * p[0][1] + a * a * p[1][1] + self.q_gyro * dt;
            let p01 = p[0][1] + a * p[1][1];
            let p11 = p[1][1] + self.q_bias * dt;
            rb.yaw_p = [[p00, p01], [p01, p11]];
        }
        if self.use_mag && !s.suspect() {
            let z = wrap_pi(heading_from_mag_trig(&s.magn, trig) + self.declination);
            let nu = wrap_pi(z - rb.yaw);
            let p = rb.yaw_p;
            let sv = p[0][0] + self.r_yaw;
            let k0 = p[0][0] / sv;
            let k1 = if freeze_bias { 0.0 } else { p[0][1] / sv };
            rb.yaw = wrap_pi(rb.yaw + k0 * nu);
            rb.yaw_bz += k1 * nu;
            // Joseph form for the (possibly frozen) gain, H = [1, 0]
            let (i00, i10) = (1.0 - k0, -k1);
            let r = self.r_yaw;
            let n00 = i00 * i00 * p[0][0] + r * k0 * k0;
            let n01 = i00 * (i10 * p[0][0] + p[0][1]) + r * k0 * k1;
            let n11 = i10 * i10 * p[0][0] + 2.0 * i10 * p[0][1] + p[1][1] + r * k1 * k1;
            rb.yaw_p = [[n00, n01], [n01, n11]];
        }
        self.ekf.att[2] = rb.yaw;
        self.ekf.bias[2] = rb.yaw_bz;
    }

    fn bias_deg(&self) -> [f64; 3] {
        [self.ekf.bias[0] * R2D, self.ekf.bias[1] * R2D, self.ekf.bias[2] * R2D]
    }

    /// The EKF (for tests and diagnostics).
    pub fn ekf(&self) -> &Ekf {
        &self.ekf
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::adis::Sample;

    /// A unit at rest, level, heading `yaw_deg`, with a constant gyro bias.
    fn rest(cnt: u16, bias: [f64; 3], yaw_deg: f64, temp: f64) -> Sample {
        let psi = yaw_deg * D2R;
        Sample {
            cnt,
            t_us: 0,
            steps: if cnt == 0 { 0 } else { 1 },
            gyro: bias,
            accel: [0.0, 0.0, -1.0],
            magn: [0.2 * psi.cos(), -0.2 * psi.sin(), 0.4],
            temp,
            diag: 0,
        }
    }

    /// These tests pin the paper's behaviour: paper mode unless the text names a mode.
    fn cfg(text: &str) -> Config {
        let mut c = Config::parse(text, "test").unwrap();
        if !text.contains("mode =") {
            c.estimator.mode = Mode::Paper;
        }
        c
    }

    #[test]
    fn learns_a_constant_bias_at_rest() {
        // robust: the z bias has its own yaw filter, whose loop with the
        // magnetometer settles more slowly (about a minute, not 40 s)
        for (mode, secs) in [("paper", 40.0), ("robust", 120.0)] {
            let c = cfg(&format!("[estimator]\nmode = \"{mode}\"\nwarmup_s = 2.0\nlearn_s = 20.0"));
            let mut e = Estimator::new(&c);
            let bias = [0.3, -0.2, 0.45];
            let mut last = Estimate::default();
            for k in 0..(204.8 * secs) as u32 {
                last = e.step(&rest(k as u16, bias, 30.0, 25.0));
            }
            for i in 0..3 {
                assert!((last.bias[i] - bias[i]).abs() < 0.01, "axis {i}: {:?}", last.bias);
                assert!(last.rate[i].abs() < 0.01);
            }
            assert!(last.roll.abs() < 0.05 && last.pitch.abs() < 0.05);
            assert!((last.yaw - 30.0).abs() < 0.2, "yaw {}", last.yaw);
            assert_eq!(last.mode, 0);
            assert_eq!(last.flags & (flags::WARMUP | flags::LEARNING), 0);
        }
    }

    #[test]
    fn warmup_samples_do_not_teach_the_bias() {
        let c = cfg("[estimator]\nwarmup_s = 5.0\nlearn_s = 5.0");
        let mut e = Estimator::new(&c);
        let mut est = Estimate::default();
        for k in 0..(204.8 * 4.5) as u32 {
            est = e.step(&rest(k as u16, [0.5, 0.5, 0.5], 0.0, 25.0));
            assert!(est.flags & flags::WARMUP != 0);
        }
        assert_eq!(est.bias, [0.0; 3]);
    }

    #[test]
    fn thermal_curve_is_anchored_at_the_last_ekf_bias() {
        // Learn at 25 C, then go out of band (|a| = 1.5 g) and warm by 10 C:
        // the bias must be the learned one plus p1 * 10, not p1 (T - t0) + p2.
        let c = cfg("[estimator]\nmode = \"paper\"\nwarmup_s = 1.0\nlearn_s = 10.0\n[thermal]\nt0 = 0.0\np1 = [0.002, 0.0044, 0.0192]\np2 = [1.0, 1.0, 1.0]");
        let mut e = Estimator::new(&c);
        let b0 = [0.1, -0.1, 0.2];
        let n = (204.8 * 90.0) as u32;
        let mut cnt = 0u16;
        for _ in 0..n {
            e.step(&rest(cnt, b0, 0.0, 25.0));
            cnt = cnt.wrapping_add(1);
        }
        let held = e.learned().unwrap();
        for i in 0..3 {
            assert!((held.bias[i] - b0[i]).abs() < 0.01, "{:?}", held);
        }
        let mut est = Estimate::default();
        for k in 0..1000 {
            let mut s = rest(cnt, b0, 0.0, 25.0 + 10.0 * k as f64 / 999.0);
            s.accel = [0.0, 0.0, -1.5];
            est = e.step(&s);
            cnt = cnt.wrapping_add(1);
            assert_eq!(est.mode, 2);
        }
        let p1 = [0.002, 0.0044, 0.0192];
        for i in 0..3 {
            let want = held.bias[i] + p1[i] * (35.0 - held.temp);
            assert!((est.bias[i] - want).abs() < 1e-9, "axis {i}: {} vs {want}", est.bias[i]);
        }
    }

    #[test]
    fn startup_average_ignores_thermal_and_fusion() {
        let c = cfg("[estimator]\nmode = \"startup_average\"\nwarmup_s = 1.0\nlearn_s = 5.0\n[thermal]\np1 = [0.1, 0.1, 0.1]");
        let mut e = Estimator::new(&c);
        let mut est = Estimate::default();
        for k in 0..(204.8 * 10.0) as u32 {
            est = e.step(&rest(k as u16, [0.2, 0.0, -0.3], 0.0, 25.0 + k as f64 * 0.001));
            assert_eq!(est.mode, 2);
        }
        assert!((est.bias[0] - 0.2).abs() < 1e-9 && (est.bias[2] + 0.3).abs() < 1e-9);
    }

    #[test]
    fn suspect_and_out_of_band_samples_are_not_fused() {
        let c = cfg("[estimator]\nmode = \"paper\"\ng0_window_s = 0.001");
        let mut e = Estimator::new(&c);
        e.step(&rest(0, [0.0; 3], 0.0, 25.0));
        let mut s = rest(1, [0.0; 3], 0.0, 25.0);
        s.diag = 4;
        let est = e.step(&s);
        assert_eq!(est.mode, 2);
        assert!(est.flags & flags::SUSPECT != 0);
        let mut s = rest(2, [0.0; 3], 0.0, 25.0);
        s.accel = [0.0, 0.0, -1.1];
        assert_eq!(e.step(&s).mode, 1);
        s.accel = [0.0, 0.0, -1.25];
        s.cnt = 3;
        assert_eq!(e.step(&s).mode, 2);
    }

    #[test]
    fn thermal_curve_clamps_outside_the_calibrated_range_and_flags_it() {
        let c = cfg("[estimator]\nwarmup_s = 1.0\nlearn_s = 5.0\n[thermal]\nt0 = 25.0\norder = 2\np1 = [0.01, 0.01, 0.01]\np3 = [0.001, 0.0, 0.0]\nt_min = 10.0\nt_max = 40.0");
        let mut e = Estimator::new(&c);
        let mut cnt = 0u16;
        for _ in 0..(204.8 * 10.0) as u32 {
            let est = e.step(&rest(cnt, [0.0; 3], 0.0, 30.0));
            assert_eq!(est.flags & flags::THERMAL_CLAMP, 0);
            cnt = cnt.wrapping_add(1);
        }
        let held = e.bias_deg();
        // out of band, warming from 30 to 50 C: the curve moves the bias up to 40 C only
        let mut est = Estimate::default();
        for k in 0..1000 {
            let temp = 30.0 + 20.0 * k as f64 / 999.0;
            let mut s = rest(cnt, [0.0; 3], 0.0, temp);
            s.accel = [0.0, 0.0, -1.5];
            est = e.step(&s);
            cnt = cnt.wrapping_add(1);
            assert_eq!(est.flags & flags::THERMAL_CLAMP != 0, temp > 40.0, "at {temp}");
        }
        let f = |t: f64| 0.01 * (t - 25.0) + 0.001 * (t - 25.0) * (t - 25.0);
        assert!((est.bias[0] - (held[0] + f(40.0) - f(30.0))).abs() < 1e-9, "{:?}", est.bias);
        assert!((est.bias[1] - (held[1] + 0.1)).abs() < 1e-9);
        // startup_average does not use the curve, so it never clamps
        let c = cfg("[estimator]\nmode = \"startup_average\"\n[thermal]\nt_max = 20.0");
        let mut e = Estimator::new(&c);
        assert_eq!(e.step(&rest(0, [0.0; 3], 0.0, 30.0)).flags & flags::THERMAL_CLAMP, 0);
    }

    #[test]
    fn long_gap_is_a_resync_not_an_integration() {
        let c = cfg("");
        let mut e = Estimator::new(&c);
        for k in 0..100u16 {
            e.step(&rest(k, [0.0; 3], 0.0, 25.0));
        }
        let mut s = rest(1100, [0.0; 3], 0.0, 25.0);
        s.gyro = [50.0, 0.0, 0.0];
        s.steps = 1000;
        let est = e.step(&s);
        assert!(est.flags & flags::RESYNC != 0);
        // integrated over one period, not 4.9 s
        assert!(est.roll.abs() < 1.0, "roll {}", est.roll);
    }

    /// Level at rest with a bias, then (from `t_acc` for `dur` s) a sustained
    /// forward acceleration `acc` g that |a| hardly shows, no rotation.
    fn accel_run(mode: &str, acc: f64, t_acc: f64, dur: f64, total: f64) -> Vec<Estimate> {
        // A tight tilt noise so that the gate, not a low gain, is what is tested
        // (the default tilt_sigma_deg = 2 lets a slow 5 deg disturbance creep in).
        let c = cfg(&format!("[estimator]\nmode = \"{mode}\"\nwarmup_s = 2.0\nlearn_s = 20.0\n[robust]\ntilt_sigma_deg = 0.3"));
        let mut e = Estimator::new(&c);
        let mut out = Vec::new();
        for k in 0..(204.8 * total) as u32 {
            let t = k as f64 / 204.8;
            let mut s = rest(k as u16, [0.1, -0.1, 0.2], 0.0, 25.0);
            if t >= t_acc && t < t_acc + dur {
                s.accel = [acc, 0.0, -1.0];
            }
            out.push(e.step(&s));
        }
        out
    }

    #[test]
    fn robust_refuses_a_sustained_acceleration_the_paper_fuses() {
        // 0.1 g forward for 20 s: |a| = 1.005 g, inside the inner band; the
        // accelerometer says pitch 5.7 deg, the gyro says nothing moved.
        let worst = |v: &[Estimate]| v.iter().skip((204.8 * 60.0) as usize).map(|e| e.pitch.abs()).fold(0.0, f64::max);
        let paper = accel_run("paper", 0.1, 90.0, 20.0, 130.0);
        let robust = accel_run("robust", 0.1, 90.0, 20.0, 130.0);
        assert!(worst(&paper) > 3.0, "paper pitch {}", worst(&paper));
        assert!(worst(&robust) < 0.5, "robust pitch {}", worst(&robust));
        // and the bias it holds is not dragged
        let b = robust.last().unwrap().bias;
        assert!((b[1] + 0.1).abs() < 0.01, "{b:?}");
    }

    #[test]
    fn robust_gate_cannot_lock_out_forever() {
        // After learning, the accelerometer reports a 6 deg tilt the gyro
        // never saw (e.g. the unit was re-mounted while off the bus): the gate
        // refuses it at first, then the lock-out re-levels on it.
        let c = cfg("[estimator]\nmode = \"robust\"\nwarmup_s = 2.0\nlearn_s = 20.0\n[robust]\nlockout_s = 20.0\ntilt_sigma_deg = 0.3");
        let mut e = Estimator::new(&c);
        let th = 6f64.to_radians();
        let mut est = Estimate::default();
        let mut gated = false;
        for k in 0..(204.8 * 150.0) as u32 {
            let t = k as f64 / 204.8;
            let mut s = rest(k as u16, [0.1, -0.1, 0.2], 0.0, 25.0);
            if t >= 60.0 {
                s.accel = [th.sin(), 0.0, -th.cos()];
            }
            est = e.step(&s);
            if t > 61.0 && t < 70.0 {
                gated |= est.flags & flags::GATED != 0;
                assert!(est.pitch < 2.0, "took the jump at once: {} at {t}", est.pitch);
            }
        }
        assert!(gated);
        assert!((est.pitch - 6.0).abs() < 0.3, "pitch {}", est.pitch);
    }
}
