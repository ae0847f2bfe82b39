//! The estimator: `step(sample) -> estimate`. Pure: no I/O, no clock, no
//! allocation per step. The daemon and `gyrocomp replay` both call it.
//!
//! This facade does what every filter needs and nothing filter-specific:
//! - rotates each sample from the sensor frame into the vehicle frame
//!   (`[mounting] rotation`); every output is in the vehicle frame;
//! - the time step from the sample counter (`dt = steps / rate`); a gap
//!   longer than `max_gap_s` is a resync (not integrated, flagged);
//! - g0, the mean |a| over the first `g0_window_s` seconds;
//! - the thermal curve: its change since the previous sample moves the bias
//!   (the curve anchored at whatever the filter learned last), with the
//!   field-learned slope correction (`[thermal] learn`) applied;
//! - the prior (the daemon's saved bias) and what is saved.
//!
//! The filters, one file each, own their state:
//! - [`mekf`] (`mode = "mekf"`, the default): quaternion error-state filter
//!   with standstill updates and the ground-vehicle constraint;
//! - [`paper`] (`paper`, `startup_thermal`, `startup_average`): the published
//!   method, faithful, on the 6-state Euler-angle EKF of [`ekf`], and its
//!   comparison cases;
//! - [`reduced`]: a unit without all six axes (a car's yaw rate, ax and
//!   ay): the yaw-rate bias and heading only, the rest marked invalid;
//! - [`rest`]: the standstill detector; [`switching`]: the paper's
//!   bands and acceleration-change criterion (the policy on top of both).

pub mod ekf;
pub mod hypotheses;
pub mod mekf;
pub mod paper;
pub mod quat;
pub mod reduced;
pub mod rest;
pub mod switching;

use crate::adis::Sample;
use crate::config::{Config, Mode};
use crate::estimator::switching::Switching;
use crate::thermal::{SlopeLearner, SlopeParams, SlopeState, Thermal};
use hypotheses::{BankEnd, MekfBank};
use mekf::{AidWord, MagUse, Mekf, MekfCounters, MekfParams, G};
use paper::Paper;
use reduced::{Reduced, ReducedParams};
use rest::RestParams;

const D2R: f64 = std::f64::consts::PI / 180.0;
const R2D: f64 = 180.0 / std::f64::consts::PI;
/// The length assumed for a counter restart (a gap of unknown length), s.
const UNKNOWN_GAP_S: f64 = 10.0;

/// Health flags carried in `EST_STATUS` (the DBC puts flag bit `i` at bit `i + 2`).
pub mod flags {
    /// DIAG_STAT != 0: the sample was not fused.
    pub const SUSPECT: u16 = 1 << 0;
    /// Inside the warm-up after power-on (g0 being measured; in `paper`
    /// mode also the warm-up exclusion: the bias is not learned).
    pub const WARMUP: u16 = 1 << 1;
    /// `paper`: inside the learning window. `mekf`: the bias is not known
    /// yet (no standstill seen, no saved bias), it is being learned.
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
    /// At rest (standstill): zero-velocity and zero-rate updates.
    pub const STANDSTILL: u16 = 1 << 8;
    /// A measurement was refused by the innovation gate.
    pub const GATED: u16 = 1 << 9;
    /// Output frames were dropped on write since the last status (set by the daemon).
    pub const TX_DROP: u16 = 1 << 10;
    /// The filter re-levelled at rest: its gate had refused a standstill's
    /// evidence for `relevel_s` (the filter, not the data, was wrong).
    pub const RELEVEL: u16 = 1 << 11;
    /// The magnetic field is disturbed (norm or dip far from the reference
    /// learned at rest): no heading updates.
    pub const MAG_DISTURBED: u16 = 1 << 12;
    /// The vehicle's own speed was fused.
    pub const SPEED_AIDED: u16 = 1 << 13;
    // The status word holds 14 flags (bits 2-15 of EST_STATUS): all taken.
}

/// Which published fields are not estimated (`Estimate::invalid`; sent in
/// `EST_AID` bits 24-30, bit `i` here at bit `24 + i`). 0 (all valid) from
/// the six-axis filters; a reduced-axis unit (`reduced`) sets the axes it
/// cannot give. An invalid field is 0 in the estimate and the CSV, and raw
/// `0x8000` in its output frame.
pub mod invalid {
    /// RateX and BiasX (no x gyro).
    pub const RATE_X: u8 = 1 << 0;
    /// RateY and BiasY (no y gyro).
    pub const RATE_Y: u8 = 1 << 1;
    /// RateZ and BiasZ (no z gyro; never in use: every mapping has one).
    pub const RATE_Z: u8 = 1 << 2;
    /// Roll: not observable without a vertical axis and a roll rate.
    pub const ROLL: u8 = 1 << 3;
    /// Pitch: likewise.
    pub const PITCH: u8 = 1 << 4;
    /// Yaw (never in use: heading is integrated from the yaw rate).
    pub const YAW: u8 = 1 << 5;
    /// TempC: no temperature mapped (the reported value is `thermal.t0`).
    pub const TEMP: u8 = 1 << 6;
    /// What a unit with the yaw rate, ax and ay only cannot give.
    pub const REDUCED: u8 = RATE_X | RATE_Y | ROLL | PITCH;
}

/// What the estimator says about one sample. Angles deg, rates deg/s, all in
/// the vehicle frame.
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
    /// 0 fusion with bias learning, 1 aided without bias learning, 2 gyro only.
    pub mode: u8,
    pub temp: f64,
    pub flags: u16,
    /// |a| / g0.
    pub ratio: f64,
    /// What the default filter's aid sources did at its last update tick
    /// (`mekf::aid`; all not applicable in the paper's modes): `EST_AID`.
    pub aid: AidWord,
    /// The fields not estimated ([`invalid`]; 0: all valid).
    pub invalid: u8,
}

/// g0: the mean |f| (g) over the first `g0_window_s` seconds, and over the
/// first sample whatever its time; 1 before any non-zero reading. The
/// reference of the paper's |a| / g0 bands; `rest::GravityRef` decides
/// whether it is gravity. The facade and `gyrocomp align` keep one.
#[derive(Clone, Copy, Debug)]
pub struct G0Mean {
    value: f64,
    sum: f64,
    n: u64,
}

impl Default for G0Mean {
    fn default() -> Self {
        G0Mean { value: 1.0, sum: 0.0, n: 0 }
    }
}

impl G0Mean {
    /// One sample at `t` s since the first; true while inside the window
    /// (still measuring).
    pub fn push(&mut self, t: f64, window_s: f64, accel: &[f64; 3]) -> bool {
        if t < window_s || self.n == 0 {
            let amag = quat::norm(accel);
            if amag > 0.0 {
                self.sum += amag;
                self.n += 1;
                self.value = self.sum / self.n as f64;
            }
            true
        } else {
            false
        }
    }

    pub fn value(&self) -> f64 {
        self.value
    }
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

/// One sample as the filters see it: in the vehicle frame, with the step and
/// the thermal curve's change already worked out by the facade.
#[derive(Clone, Copy, Debug, Default)]
pub struct StepIn {
    /// Time step, s (0 on the first sample).
    pub dt: f64,
    /// Seconds since the first sample.
    pub t: f64,
    /// deg/s, g, gauss, deg C.
    pub gyro: [f64; 3],
    pub accel: [f64; 3],
    pub magn: [f64; 3],
    pub temp: f64,
    pub g0: f64,
    /// The thermal curve's change since the previous sample, deg/s.
    pub dbias: [f64; 3],
    pub suspect: bool,
}

/// The filter in use. Built once per power cycle, so the variants' sizes
/// do not matter; the default filter stays inline for the hot path.
#[derive(Clone, Debug)]
#[allow(clippy::large_enum_variant)]
enum Filter {
    Paper(Paper),
    /// The default filter with its power-on speed hypotheses.
    Mekf(Box<MekfBank>),
    /// A unit without all six axes: the yaw-rate bias and heading.
    Reduced(Reduced),
}

#[derive(Clone, Debug)]
pub struct Estimator {
    mode: Mode,
    period: f64,
    max_gap: f64,
    g0_window: f64,
    warmup: f64,
    /// Sensor to vehicle rotation (None = identity).
    mount: Option<quat::Mat3>,
    thermal_on: bool,
    thermal: Thermal,
    /// The configured curve (`thermal` = this plus the learned slope correction).
    thermal_base: Thermal,
    slope: Option<SlopeLearner>,
    slope_after: f64,
    filter: Filter,
    started: bool,
    t: f64,
    g0: G0Mean,
    temp_prev: f64,
    prior: Option<Learned>,
    init_bias_sigma: f64,
    /// Restarts from the prior after a non-finite state (flagged `RESYNC`).
    nonfinite_restarts: u64,
}

/// What the filter in use made of one sample (`Estimator::step_filter`).
#[derive(Clone, Copy, Debug)]
struct FilterOut {
    mode: u8,
    flags: u16,
    /// `|a| / g0` as the switching policy read it.
    ratio: f64,
    /// Roll, pitch, yaw, rad.
    att: [f64; 3],
    /// Bias, deg/s.
    bias: [f64; 3],
    /// A learning point for the thermal slope: (temp, bias deg/s, weight s).
    slope_point: Option<(f64, [f64; 3], f64)>,
    /// The filter's state is finite.
    finite: bool,
    /// What the default filter's aid sources did at its last tick.
    aid: AidWord,
    /// The fields not estimated.
    invalid: u8,
}

/// The power-on speed hypotheses' outcome (`hypotheses`), for the summary
/// and the status.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct PowerOnSpeed {
    /// The power-on forward speed of the hypothesis published, m/s.
    pub speed_ms: f64,
    /// When the bank ended (s after power-on) and why; None while it runs.
    pub ended: Option<(f64, BankEnd)>,
}

/// The default filter's settings from the config.
pub fn mekf_params(cfg: &Config) -> MekfParams {
    let p = cfg.profile();
    let k = &cfg.ekf;
    let m = &cfg.mekf;
    let r = &cfg.rest;
    let mag = if !p.magnetometer {
        MagUse::Off
    } else {
        match cfg.estimator.use_magnetometer {
            crate::config::AutoBool::Auto => MagUse::Auto,
            crate::config::AutoBool::Bool(true) => MagUse::On,
            crate::config::AutoBool::Bool(false) => MagUse::Off,
        }
    };
    MekfParams {
        tick_s: 1.0 / m.update_hz,
        q_gyro: (k.gyro_noise * D2R).powi(2),
        gyro_scale: m.gyro_scale_error,
        q_bias: (k.bias_walk * D2R).powi(2),
        q_bias_motion: (m.motion_bias_walk * D2R).powi(2),
        q_accel: m.accel_noise * m.accel_noise,
        q_scale: m.scale_walk * m.scale_walk,
        nhc_var: m.nhc_sigma * m.nhc_sigma,
        max_vertical_speed: m.max_vertical_speed,
        max_forward_speed: m.max_forward_speed,
        max_reverse_speed: m.max_reverse_speed,
        speed_bound_sigma: m.speed_bound_sigma,
        q_accel_quiet: m.accel_noise_quiet * m.accel_noise_quiet,
        accel_ref: m.accel_ref,
        accel_bias_g: m.accel_bias_g,
        vehicle: match m.vehicle {
            crate::config::AutoBool::Auto => mekf::Vehicle::Auto,
            crate::config::AutoBool::Bool(true) => mekf::Vehicle::On,
            crate::config::AutoBool::Bool(false) => mekf::Vehicle::Off,
        },
        handheld_rate: m.handheld_rate_dps * D2R,
        free_var: m.free_velocity_sigma * m.free_velocity_sigma,
        accel_tau: m.accel_tau_s,
        lp_tilt_var: (m.tilt_sigma_deg * D2R).powi(2),
        tilt_motion_share2: m.tilt_motion_share * m.tilt_motion_share,
        zupt_var: m.zupt_sigma * m.zupt_sigma,
        tilt_floor: (m.rest_tilt_sigma_deg * D2R).powi(2),
        zru_floor: (m.zru_sigma_dps * D2R).powi(2),
        yaw_var: (k.yaw_sigma_deg * D2R).powi(2),
        speed_var: m.speed_sigma * m.speed_sigma,
        gate: m.gate_sigma * m.gate_sigma,
        stop_nis: m.stop_sigma * m.stop_sigma,
        relevel_s: m.relevel_s,
        lever: cfg.mounting.lever_arm,
        mag,
        declination: cfg.estimator.declination_deg * D2R,
        mag_norm_tol: m.mag_norm_tol,
        mag_dip_tol: m.mag_dip_tol_deg * D2R,
        init_angle_sigma: k.init_angle_sigma_deg * D2R,
        init_bias_sigma: cfg.init_bias_sigma() * D2R,
        init_speed_sigma: m.init_speed_sigma,
        init_scale_sigma: 0.03,
        dwell_s: m.dwell_s,
        turn_rate: m.turn_rate_dps * D2R,
        rest: RestParams::from_config(r),
        g0_window_s: cfg.estimator.g0_window_s,
        speed_aided: cfg.speed.enabled(),
        // names checked by `Config::validate`
        off: mekf::RulesOff::from_names(&m.ablate).unwrap_or_default(),
    }
}

/// The reduced-axis filter's settings, when the DBC mapping lacks a motion
/// axis (None: all six mapped, or the ADIS input).
pub fn reduced_params(cfg: &Config) -> Option<ReducedParams> {
    let plan = cfg.input.plan.0.as_ref().filter(|p| !cfg.input.format.is_adis() && !p.missing_motion().is_empty())?;
    Some(ReducedParams {
        q_bias: cfg.ekf.bias_walk.powi(2),
        rest_sigma: cfg.mekf.zru_sigma_dps.max(1e-4),
        init_sigma: cfg.init_bias_sigma(),
        speed_aided: cfg.speed.enabled(),
        temp_mapped: plan.channels[6].is_some(),
    })
}

impl Estimator {
    pub fn new(cfg: &Config) -> Estimator {
        let p = cfg.profile();
        let e = &cfg.estimator;
        let switching = Switching::new(&cfg.switching, p.rate_hz);
        let reduced = reduced_params(cfg);
        let filter = match (reduced, e.mode) {
            (Some(r), _) => Filter::Reduced(Reduced::new(r)),
            (None, Mode::Mekf) => Filter::Mekf(Box::new(MekfBank::new(Mekf::new(mekf_params(cfg), switching)))),
            (None, _) => {
                let use_mag = p.magnetometer && !matches!(e.use_magnetometer, crate::config::AutoBool::Bool(false));
                Filter::Paper(Paper::new(cfg, switching, use_mag))
            }
        };
        let r = cfg.mounting.matrix();
        Estimator {
            mode: e.mode,
            period: 1.0 / p.rate_hz,
            max_gap: e.max_gap_s,
            g0_window: e.g0_window_s,
            warmup: e.warmup_s,
            mount: r,
            // a reduced unit: the curve only with a temperature mapped
            thermal_on: cfg.thermal.enabled && e.mode != Mode::StartupAverage && reduced.is_none_or(|r| r.temp_mapped),
            thermal: Thermal::new(&cfg.thermal),
            thermal_base: Thermal::new(&cfg.thermal),
            slope: (cfg.thermal.learn && cfg.thermal.enabled).then(|| {
                let th = &cfg.thermal;
                SlopeLearner::new(SlopeParams { min_spread: th.learn_min_spread, max_dev: th.learn_max_dev }, th.p1)
            }),
            slope_after: cfg.thermal.learn_after_s,
            filter,
            started: false,
            t: 0.0,
            g0: G0Mean::default(),
            temp_prev: 0.0,
            prior: None,
            init_bias_sigma: cfg.init_bias_sigma(),
            nonfinite_restarts: 0,
        }
    }

    /// Start from a bias learned earlier (loaded before the first sample).
    /// It replaces the thermal curve's absolute value as the prior.
    pub fn set_prior(&mut self, prior: Learned) {
        self.prior = Some(prior);
    }

    /// The default filter's vehicle axes as the pull-aways turned them (deg
    /// about the unit's z axis), for saving; None when they are the
    /// configured ones (or in the paper's modes).
    pub fn vehicle_axes_turned(&self) -> Option<f64> {
        self.mekf().map(|m| m.vehicle_axes().0).filter(|y| *y != 0.0)
    }

    /// Start with the default filter's vehicle axes turned (deg, from
    /// `vehicle_axes_turned` before a restart). Returns whether it applies
    /// (the default mode).
    pub fn set_vehicle_axes(&mut self, yaw_deg: f64) -> bool {
        match &mut self.filter {
            Filter::Mekf(b) => {
                b.filter_mut().set_vehicle_axes(yaw_deg);
                true
            }
            Filter::Paper(_) | Filter::Reduced(_) => false,
        }
    }

    /// The bias the estimator holds now and at what temperature, for saving:
    /// the bias of the last sample that learned it.
    pub fn learned(&self) -> Option<Learned> {
        if !self.started {
            return self.prior;
        }
        let l = match &self.filter {
            Filter::Paper(p) => p.learned(),
            Filter::Mekf(b) => b.filter().last_learned().map(|(temp, bias)| {
                let m = b.filter();
                let s = m.bias_sigma();
                Learned { bias, bias_sigma: [s[0] * R2D, s[1] * R2D, s[2] * R2D], temp }
            }),
            Filter::Reduced(r) => {
                r.known().then(|| Learned { bias: [0.0, 0.0, r.bias()], bias_sigma: [0.0, 0.0, r.bias_sigma()], temp: self.temp_prev })
            }
        };
        l.or(self.prior)
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
        self.g0.value()
    }

    /// The default filter's counters (None in the paper's modes).
    pub fn mekf_counters(&self) -> Option<MekfCounters> {
        match &self.filter {
            Filter::Mekf(b) => Some(b.filter().counters()),
            Filter::Paper(_) | Filter::Reduced(_) => None,
        }
    }

    /// Whether the magnetometer is in use (None: not decided yet).
    pub fn magnetometer(&self) -> Option<bool> {
        match &self.filter {
            Filter::Mekf(b) => b.filter().magnetometer(),
            Filter::Paper(_) | Filter::Reduced(_) => None,
        }
    }

    /// The default filter (for tests and diagnostics).
    pub fn mekf(&self) -> Option<&Mekf> {
        match &self.filter {
            Filter::Mekf(b) => Some(b.filter()),
            Filter::Paper(_) | Filter::Reduced(_) => None,
        }
    }

    /// The power-on speed hypotheses' outcome (None: not run, as in the
    /// paper's modes, with wheel speeds, or for a unit set not to be a vehicle).
    pub fn power_on_speed(&self) -> Option<PowerOnSpeed> {
        match &self.filter {
            Filter::Mekf(b) => b.power_on(),
            Filter::Paper(_) | Filter::Reduced(_) => None,
        }
    }

    /// The paper's EKF (for tests and diagnostics).
    pub fn paper(&self) -> Option<&Paper> {
        match &self.filter {
            Filter::Paper(p) => Some(p),
            Filter::Mekf(_) | Filter::Reduced(_) => None,
        }
    }

    /// The reduced-axis filter (None with all six axes).
    pub fn reduced(&self) -> Option<&Reduced> {
        match &self.filter {
            Filter::Reduced(r) => Some(r),
            _ => None,
        }
    }

    /// The vehicle's speed (m/s) for the default filter: the latest one
    /// while it is fresh, None when there is none (not configured, stale);
    /// `new` when a frame arrived since the previous sample.
    pub fn set_speed(&mut self, v: Option<f64>, new: bool) {
        match &mut self.filter {
            Filter::Mekf(b) => b.filter_mut().set_speed(v, new),
            Filter::Reduced(r) => r.set_speed(v, new),
            Filter::Paper(_) => {}
        }
    }

    /// The initial bias (deg/s) and its sigma: the prior moved by the curve
    /// to this temperature, else the curve's absolute value.
    fn initial_bias(&self, temp: f64) -> ([f64; 3], Option<[f64; 3]>) {
        match (&self.prior, self.mode) {
            (Some(pr), _) => {
                let d = if self.thermal_on { self.thermal.delta(pr.temp, temp) } else { [0.0; 3] };
                ([pr.bias[0] + d[0], pr.bias[1] + d[1], pr.bias[2] + d[2]], Some(pr.bias_sigma))
            }
            (None, Mode::StartupAverage) => ([0.0; 3], None),
            (None, _) if self.thermal_on => (self.thermal.bias(temp), None),
            (None, _) => ([0.0; 3], None),
        }
    }

    fn start(&mut self, s: &StepIn) {
        let (bias, sigma) = self.initial_bias(s.temp);
        match &mut self.filter {
            Filter::Paper(p) => p.start(s, bias, sigma),
            Filter::Mekf(b) => {
                let sig = sigma.map_or([self.init_bias_sigma * D2R; 3], |v| v.map(|x| (x * D2R).max(1e-4 * D2R)));
                b.start(&s.accel, &s.magn, bias.map(|b| b * D2R), sig, sigma.is_some());
            }
            Filter::Reduced(r) => r.start(bias[2], sigma.map(|s| s[2])),
        }
        self.temp_prev = s.temp;
        self.started = true;
        self.t = 0.0;
    }

    /// Step the estimator on one sample.
    pub fn step(&mut self, s: &Sample) -> Estimate {
        let (gyro, accel, magn) = match &self.mount {
            None => (s.gyro, s.accel, s.magn),
            Some(r) => (quat::rotate(r, &s.gyro), quat::rotate(r, &s.accel), quat::rotate(r, &s.magn)),
        };
        let mut inp =
            StepIn { dt: 0.0, t: 0.0, gyro, accel, magn, temp: s.temp, g0: self.g0.value(), dbias: [0.0; 3], suspect: s.suspect() };
        let (dt, resync, mut fl) = self.advance_clock(s, &inp);
        let t = self.t;
        fl |= self.g0_and_thermal(t, s.temp, &accel, &mut inp);
        inp.dt = dt;
        inp.t = t;
        let out = self.step_filter(s, &inp, resync);
        fl |= out.flags;
        if s.suspect() {
            fl |= flags::SUSPECT;
        }
        self.learn_slope(out.slope_point, t);
        let (att, bias) = (out.att, out.bias);
        let mut est = Estimate {
            cnt: s.cnt,
            t_us: s.t_us,
            t,
            roll: att[0] * R2D,
            pitch: att[1] * R2D,
            yaw: att[2] * R2D,
            rate: [gyro[0] - bias[0], gyro[1] - bias[1], gyro[2] - bias[2]],
            bias,
            mode: out.mode,
            temp: s.temp,
            flags: fl,
            ratio: out.ratio,
            aid: out.aid,
            invalid: 0,
        };
        mark_invalid(&mut est, out.invalid);
        if out.finite && est.is_finite() {
            est
        } else {
            self.restart_nonfinite(&inp, est)
        }
    }

    /// The time step from the sample counter (`steps / rate`), and the clock
    /// moved on by it: 0 on the first sample, which starts the filter on
    /// `inp`; one period over a counter restart or a gap longer than
    /// `max_gap_s`, which is not integrated but a resync (flagged `RESYNC`).
    /// Returns (dt, resync, flags).
    fn advance_clock(&mut self, s: &Sample, inp: &StepIn) -> (f64, bool, u16) {
        let mut fl = 0u16;
        let mut dt = s.steps as f64 * self.period;
        let mut resync = false;
        if !self.started {
            self.start(inp);
            dt = 0.0;
        } else if s.steps == 0 || dt > self.max_gap {
            // Unknown or long gap: do not integrate the gyro across it.
            fl |= flags::RESYNC;
            resync = true;
            dt = self.period;
        }
        self.t += dt;
        (dt, resync, fl)
    }

    /// g0 (the mean |a| over the first `g0_window_s`, flagged `WARMUP`
    /// while measured; the default filter's warm-up too) and the thermal
    /// curve's change since the previous sample (`temp` deg C), which moves
    /// the filter's bias; both into `inp`. Returns the flags.
    fn g0_and_thermal(&mut self, t: f64, temp: f64, accel: &[f64; 3], inp: &mut StepIn) -> u16 {
        let mut fl = 0u16;
        if self.g0.push(t, self.g0_window, accel) {
            fl |= flags::WARMUP;
        }
        if t < self.warmup && self.mode == Mode::Mekf {
            fl |= flags::WARMUP;
        }
        if self.thermal_on && self.thermal.clamps(temp) {
            fl |= flags::THERMAL_CLAMP;
        }
        let db = if self.thermal_on { self.thermal.delta(self.temp_prev, temp) } else { [0.0; 3] };
        self.temp_prev = temp;
        inp.g0 = self.g0.value();
        inp.dbias = db;
        fl
    }

    /// The filter in use on one sample, a resync first after a gap. The
    /// default filter's power-on speed hypotheses step with it; when they
    /// switch to another copy, that copy's step is what is published.
    fn step_filter(&mut self, s: &Sample, inp: &StepIn, resync: bool) -> FilterOut {
        let thermal = &self.thermal;
        let thermal_on = self.thermal_on;
        match &mut self.filter {
            Filter::Paper(p) => {
                if resync {
                    p.resync();
                }
                let (mode, fl, ratio, sp) = p.step(inp, thermal_on, |a, b| thermal.delta(a, b));
                let b = p.bias_deg();
                let slope_point = sp.then_some((s.temp, b, inp.dt));
                FilterOut {
                    mode,
                    flags: fl,
                    ratio,
                    att: p.attitude(),
                    bias: b,
                    slope_point,
                    finite: p.state_is_finite(),
                    aid: AidWord::default(),
                    invalid: 0,
                }
            }
            Filter::Reduced(r) => {
                if resync {
                    r.resync();
                }
                let (mode, fl) = r.step(inp);
                let invalid = invalid::REDUCED | if r.params().temp_mapped { 0 } else { invalid::TEMP };
                FilterOut {
                    mode,
                    flags: fl,
                    ratio: quat::norm(&inp.accel) / inp.g0,
                    att: [0.0, 0.0, r.yaw() * D2R],
                    bias: [0.0, 0.0, r.bias()],
                    slope_point: None,
                    finite: r.is_finite(),
                    aid: AidWord::default(),
                    invalid,
                }
            }
            Filter::Mekf(bank) => {
                // a counter restart is a gap of unknown length
                let gap = resync.then_some(if s.steps == 0 { UNKNOWN_GAP_S } else { s.steps as f64 * self.period });
                let (mode, fl, ratio) = bank.step(inp, gap);
                let m = bank.filter_mut();
                let b = m.bias();
                let slope_point = m.take_rest_point();
                let bias = [b[0] * R2D, b[1] * R2D, b[2] * R2D];
                FilterOut { mode, flags: fl, ratio, att: m.euler(), bias, slope_point, finite: m.started(), aid: m.aid_word(), invalid: 0 }
            }
        }
    }

    /// Field learning of the thermal slope: the filter's learning points
    /// after `learn_after_s` (`t` s since power-on), inside the calibrated
    /// range, correct the curve's slope.
    fn learn_slope(&mut self, slope_point: Option<(f64, [f64; 3], f64)>, t: f64) {
        if let (Some((temp, b, w)), true) = (slope_point, t >= self.slope_after) {
            if !self.thermal.clamps(temp) {
                let c = self.thermal_base.bias(temp);
                if let Some(l) = self.slope.as_mut() {
                    l.push(temp, [b[0] - c[0], b[1] - c[1], b[2] - c[2]], w);
                }
                self.apply_slope();
            }
        }
    }

    /// The state or the output went non-finite (a filter driven beyond its
    /// numbers: it cannot happen with a config inside its ranges and finite
    /// input): restart from the prior on this sample, count it, and publish
    /// the restarted filter's attitude and bias, any value still non-finite
    /// as 0, flagged `RESYNC` (the attitude was not integrated over it).
    fn restart_nonfinite(&mut self, inp: &StepIn, est: Estimate) -> Estimate {
        self.nonfinite_restarts += 1;
        self.started = false;
        let keep_t = self.t;
        self.start(inp);
        self.t = keep_t;
        let (att, bias) = match &self.filter {
            Filter::Paper(p) => (p.attitude(), p.bias_deg()),
            Filter::Mekf(b) => (b.filter().euler(), b.filter().bias().map(|b| b * R2D)),
            Filter::Reduced(r) => ([0.0, 0.0, r.yaw() * D2R], [0.0, 0.0, r.bias()]),
        };
        let f = |v: f64| if v.is_finite() { v } else { 0.0 };
        let bias = bias.map(f);
        let mut out = Estimate {
            roll: f(att[0] * R2D),
            pitch: f(att[1] * R2D),
            yaw: f(att[2] * R2D),
            rate: [f(inp.gyro[0] - bias[0]), f(inp.gyro[1] - bias[1]), f(inp.gyro[2] - bias[2])],
            bias,
            temp: f(est.temp),
            ratio: f(est.ratio),
            flags: est.flags | flags::RESYNC,
            ..est
        };
        mark_invalid(&mut out, est.invalid);
        out
    }

    /// Restarts from the prior after a non-finite state since power-on.
    pub fn nonfinite_restarts(&self) -> u64 {
        self.nonfinite_restarts
    }
}

/// The fields `invalid` names set to their fill value, 0 (the output frames
/// send them as raw `0x8000`), and the word kept in the estimate.
fn mark_invalid(e: &mut Estimate, invalid: u8) {
    e.invalid = invalid;
    for (i, bit) in [invalid::RATE_X, invalid::RATE_Y, invalid::RATE_Z].into_iter().enumerate() {
        if invalid & bit != 0 {
            e.rate[i] = 0.0;
            e.bias[i] = 0.0;
        }
    }
    for (v, bit) in [(&mut e.roll, invalid::ROLL), (&mut e.pitch, invalid::PITCH), (&mut e.yaw, invalid::YAW)] {
        if invalid & bit != 0 {
            *v = 0.0;
        }
    }
}

impl Estimate {
    /// Whether every published number is finite.
    pub fn is_finite(&self) -> bool {
        [self.t, self.roll, self.pitch, self.yaw, self.temp, self.ratio].iter().chain(&self.rate).chain(&self.bias).all(|v| v.is_finite())
    }
}

/// Standard gravity, m/s^2 (for tools that convert g).
pub const STANDARD_GRAVITY: f64 = G;

#[cfg(test)]
mod tests;
