//! The configuration's types: one serde struct per TOML section, each with
//! its defaults (`Default`), unknown keys refused (`deny_unknown_fields`).
//! Every key is optional; a missing one takes the default written here,
//! once, in each struct's `Default` (the doc comments do not repeat the
//! values). `check-config` prints them from there; the shipped
//! `config/gyrocomp.toml` and the `[mekf]` table of `docs/estimator.md`
//! are checked against them by `tests/defaults.rs`.

use super::dbcin::{InputFormat, PlanSlot, SampleConfig, SignalsConfig, UnitsConfig, ValidMap};
use crate::adis::InputIds;
use serde::de::Error as _;
use serde::{Deserialize, Deserializer, Serialize};

/// A TOML array of exactly `N` numbers; any other length is an error naming
/// `key` and the length wanted. serde's own `[f64; N]` takes the first `N`
/// values and drops the rest without a word (the toml deserializer does not
/// check for leftovers), so `rotation = [0, 0, 0, 45]` would load as
/// `[0, 0, 0]`.
fn exact<'de, D: Deserializer<'de>, const N: usize>(d: D, key: &str, what: &str) -> Result<[f64; N], D::Error> {
    let v = Vec::<f64>::deserialize(d)?;
    <[f64; N]>::try_from(v.as_slice())
        .map_err(|_| D::Error::custom(format!("{key}: expected an array of {N} numbers ({what}), got {} values", v.len())))
}

/// One `deserialize_with` function per fixed-length key: [`exact`] with its name.
macro_rules! exact_fn {
    ($($f:ident: $n:literal, $key:literal, $what:literal;)*) => {$(
        fn $f<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; $n], D::Error> {
            exact(d, $key, $what)
        }
    )*};
}

exact_fn! {
    exact_inner: 2, "switching.inner", "[lo, hi]";
    exact_outer: 2, "switching.outer", "[lo, hi]";
    exact_p1: 3, "thermal.p1", "one per axis x, y, z";
    exact_p2: 3, "thermal.p2", "one per axis x, y, z";
    exact_p3: 3, "thermal.p3", "one per axis x, y, z";
    exact_p4: 3, "thermal.p4", "one per axis x, y, z";
    exact_learn_max_dev: 3, "thermal.learn_max_dev", "one per axis x, y, z";
    exact_rotation: 3, "mounting.rotation", "[roll, pitch, yaw]";
    exact_lever_arm: 3, "mounting.lever_arm", "[x, y, z]";
}

/// `[input.ids]`: every key optional, the others keep their defaults.
fn partial_ids<'de, D: Deserializer<'de>>(d: D) -> Result<InputIds, D::Error> {
    #[derive(Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Partial {
        gyro: Option<u32>,
        accel: Option<u32>,
        magn: Option<u32>,
        aux: Option<u32>,
    }
    let p = Partial::deserialize(d)?;
    let d = InputIds::DEFAULT;
    Ok(InputIds {
        gyro: p.gyro.unwrap_or(d.gyro),
        accel: p.accel.unwrap_or(d.accel),
        magn: p.magn.unwrap_or(d.magn),
        aux: p.aux.unwrap_or(d.aux),
    })
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct Config {
    pub input: InputConfig,
    pub can: CanConfig,
    pub estimator: EstimatorConfig,
    pub ekf: EkfConfig,
    pub switching: SwitchingConfig,
    pub thermal: ThermalConfig,
    pub mekf: MekfConfig,
    pub rest: RestConfig,
    pub output: OutputConfig,
    pub daemon: DaemonConfig,
    pub mounting: MountingConfig,
    pub speed: SpeedConfig,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct InputConfig {
    /// Part profile: adis16448 (default), adis16405, adis16465-1.
    pub profile: String,
    /// Sample rate, Hz; 0 = the profile's nominal rate.
    pub rate_hz: f64,
    /// Input frame IDs; each key optional (default 0x100..0x103).
    #[serde(deserialize_with = "partial_ids")]
    pub ids: InputIds,
    /// Overrides of the profile's scales (None = the profile's value).
    pub gyro_lsb: Option<f64>,
    pub accel_lsb: Option<f64>,
    pub magn_lsb: Option<f64>,
    pub temp_lsb: Option<f64>,
    pub temp_offset: Option<f64>,
    /// `"adis"` (default: the four ADIS frames) or `"dbc"` (the keys below).
    #[serde(skip_serializing_if = "InputFormat::is_adis")]
    pub format: InputFormat,
    /// The IMU's DBC file, relative to the config file (format = "dbc").
    #[serde(skip_serializing_if = "String::is_empty")]
    pub dbc: String,
    /// J1939: the unit's source address; its messages match on PGN and this
    /// address, whatever the priority bits.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub source_address: Option<u8>,
    #[serde(skip_serializing_if = "SignalsConfig::is_empty")]
    pub signals: SignalsConfig,
    #[serde(skip_serializing_if = "UnitsConfig::is_empty")]
    pub units: UnitsConfig,
    #[serde(skip_serializing_if = "SampleConfig::is_empty")]
    pub sample: SampleConfig,
    /// "MESSAGE.SIGNAL" = the raw value it must hold for a sample to be fused.
    #[serde(skip_serializing_if = "ValidMap::is_empty")]
    pub valid: ValidMap,
    /// The DBC decode plan, built by `Config::load` (format = "dbc").
    #[serde(skip)]
    pub plan: PlanSlot,
}

impl Default for InputConfig {
    fn default() -> Self {
        InputConfig {
            profile: "adis16448".into(),
            rate_hz: 0.0,
            ids: InputIds::DEFAULT,
            gyro_lsb: None,
            accel_lsb: None,
            magn_lsb: None,
            temp_lsb: None,
            temp_offset: None,
            format: InputFormat::Adis,
            dbc: String::new(),
            source_address: None,
            signals: SignalsConfig::default(),
            units: UnitsConfig::default(),
            sample: SampleConfig::default(),
            valid: ValidMap::new(),
            plan: PlanSlot::default(),
        }
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CanConfig {
    /// SocketCAN interface the daemon reads and writes.
    pub interface: String,
}

impl Default for CanConfig {
    fn default() -> Self {
        CanConfig { interface: "can0".into() }
    }
}

/// Which estimator runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Mode {
    /// Paper case 1: gyro with the start-up-average bias, no thermal curve.
    StartupAverage,
    /// Paper case 2: start-up-average bias plus the thermal curve.
    StartupThermal,
    /// Paper case 3: EKF + thermal curve anchored at the last EKF bias + switching, as published.
    Paper,
    /// The default: a quaternion error-state Kalman filter (attitude, gyro
    /// bias, velocity) with standstill updates, the ground-vehicle
    /// constraint and the paper's policy on top (`src/estimator/mekf/`).
    /// `"robust"`, the previous default's name, selects it too.
    #[serde(alias = "robust")]
    Mekf,
}

impl Mode {
    pub fn name(self) -> &'static str {
        match self {
            Mode::StartupAverage => "startup_average",
            Mode::StartupThermal => "startup_thermal",
            Mode::Paper => "paper",
            Mode::Mekf => "mekf",
        }
    }
}

/// A setting that is `"auto"`, `true` or `false`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AutoBool {
    /// Off when the field is zero, absent or implausible for Earth's.
    Auto,
    Bool(bool),
}

impl Serialize for AutoBool {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            AutoBool::Auto => s.serialize_str("auto"),
            AutoBool::Bool(b) => s.serialize_bool(*b),
        }
    }
}

impl<'de> Deserialize<'de> for AutoBool {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl serde::de::Visitor<'_> for V {
            type Value = AutoBool;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("\"auto\", true or false")
            }
            fn visit_bool<E: serde::de::Error>(self, v: bool) -> Result<AutoBool, E> {
                Ok(AutoBool::Bool(v))
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<AutoBool, E> {
                match v {
                    "auto" => Ok(AutoBool::Auto),
                    _ => Err(E::invalid_value(serde::de::Unexpected::Str(v), &self)),
                }
            }
        }
        d.deserialize_any(V)
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EstimatorConfig {
    pub mode: Mode,
    /// Seconds after power-on over which g0 = mean |a| is measured.
    pub g0_window_s: f64,
    /// Seconds after power-on that never teach the bias (warm-up exclusion).
    pub warmup_s: f64,
    /// Length of the learning window after warm-up, seconds; the mean EKF bias
    /// over it (quasi-static samples only) becomes the initial bias.
    pub learn_s: f64,
    /// Magnetic declination, deg (east positive), added to the magnetometer heading.
    pub declination_deg: f64,
    /// Use the magnetometer for yaw: "auto" (default: off when the field is
    /// zero, absent or implausible for Earth's), true or false. Ignored for
    /// parts without one.
    pub use_magnetometer: AutoBool,
    /// A counter gap longer than this is a resync (no integration over it), seconds.
    pub max_gap_s: f64,
}

impl Default for EstimatorConfig {
    fn default() -> Self {
        EstimatorConfig {
            mode: Mode::Mekf,
            g0_window_s: 1.0,
            warmup_s: 10.0,
            learn_s: 60.0,
            declination_deg: 0.0,
            use_magnetometer: AutoBool::Auto,
            max_gap_s: 0.1,
        }
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EkfConfig {
    /// Gyro white noise density, deg/s/sqrt(Hz) (process noise on the angles).
    pub gyro_noise: f64,
    /// Bias random walk, deg/s/sqrt(s) (process noise on the bias).
    pub bias_walk: f64,
    /// 1-sigma of roll/pitch from the accelerometer, deg.
    pub tilt_sigma_deg: f64,
    /// 1-sigma of the magnetometer heading, deg.
    pub yaw_sigma_deg: f64,
    /// Initial 1-sigma of the bias, deg/s. Default: the part profile's
    /// turn-on bias sigma (adis16448 and adis16405 3 deg/s, adis16465-1 1 deg/s).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub init_bias_sigma: Option<f64>,
    /// Initial 1-sigma of the angles, deg.
    pub init_angle_sigma_deg: f64,
}

impl Default for EkfConfig {
    fn default() -> Self {
        EkfConfig {
            gyro_noise: 0.02,
            bias_walk: 0.0005,
            tilt_sigma_deg: 1.0,
            yaw_sigma_deg: 3.0,
            init_bias_sigma: None,
            init_angle_sigma_deg: 5.0,
        }
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SwitchingConfig {
    /// Inner band on |a|/g0: full fusion with bias learning.
    #[serde(deserialize_with = "exact_inner")]
    pub inner: [f64; 2],
    /// Outer band on |a|/g0: between inner and outer a weighted blend; outside gyro only.
    #[serde(deserialize_with = "exact_outer")]
    pub outer: [f64; 2],
    /// Acceleration-change criterion: no fusion when |slope of a| > jerk_ratio * mean|a| per second.
    pub jerk_ratio: f64,
    /// Window over which the slope and mean of the acceleration are taken, seconds.
    pub jerk_window_s: f64,
}

impl Default for SwitchingConfig {
    fn default() -> Self {
        SwitchingConfig { inner: [0.985, 1.015], outer: [0.80, 1.20], jerk_ratio: 0.20, jerk_window_s: 1.0 }
    }
}

/// The thermal bias curve and its field learning.
///
/// Per axis `b(T) = p2 + p1 (T - t0) + p3 (T - t0)^2 + p4 (T - t0)^3`, deg/s,
/// with `p3` used from `order = 2` and `p4` at `order = 3`. The first two
/// keys are the paper's eq. 20 (`W = p1 (T - T0) + p2`), so a config with only
/// `t0`, `p1`, `p2` is the paper's linear curve. Outside `[t_min, t_max]` (the
/// calibrated range; each bound optional) the curve is evaluated at the
/// nearest edge and the estimate carries `FlagThermalClamp`.
/// `gyrocomp calibrate --write` emits this section.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ThermalConfig {
    /// false for parts without a temperature channel: the curve and its
    /// learning are not used (the temperature is still reported).
    pub enabled: bool,
    /// Reference temperature of the curve, deg C.
    pub t0: f64,
    /// Slope per axis, deg/s per deg C.
    #[serde(deserialize_with = "exact_p1")]
    pub p1: [f64; 3],
    /// Bias at t0 per axis, deg/s.
    #[serde(deserialize_with = "exact_p2")]
    pub p2: [f64; 3],
    /// Polynomial order, 1 (default, linear as in the paper), 2 or 3.
    pub order: u8,
    /// Quadratic coefficient per axis, deg/s per (deg C)^2; must be 0 unless order >= 2.
    #[serde(deserialize_with = "exact_p3")]
    pub p3: [f64; 3],
    /// Cubic coefficient per axis, deg/s per (deg C)^3; must be 0 unless order = 3.
    #[serde(deserialize_with = "exact_p4")]
    pub p4: [f64; 3],
    /// Lower edge of the calibrated temperature range, deg C. Default: none (no clamp below).
    pub t_min: Option<f64>,
    /// Upper edge of the calibrated temperature range, deg C. Default: none (no clamp above).
    pub t_max: Option<f64>,
    /// Refine the slope `p1` in the field from the EKF bias learned in
    /// quasi-static stretches at different temperatures.
    pub learn: bool,
    /// Seconds after power-on before the slope learner takes any point (the
    /// sensor's warm-up transient is not a thermal trend).
    pub learn_after_s: f64,
    /// Temperature spread (max - min within one power cycle, deg C) the learner
    /// must have seen before the slope moves at all.
    pub learn_min_spread: f64,
    /// Largest change of the learned slope from the configured `p1`, per
    /// axis, deg/s per deg C.
    #[serde(deserialize_with = "exact_learn_max_dev")]
    pub learn_max_dev: [f64; 3],
}

impl Default for ThermalConfig {
    fn default() -> Self {
        ThermalConfig {
            enabled: true,
            t0: 25.0,
            p1: [0.0; 3],
            p2: [0.0; 3],
            order: 1,
            p3: [0.0; 3],
            p4: [0.0; 3],
            t_min: None,
            t_max: None,
            learn: false,
            learn_after_s: 600.0,
            learn_min_spread: 5.0,
            learn_max_dev: [0.01; 3],
        }
    }
}

/// `[mekf]`: the default filter's settings (ignored by the paper's modes).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MekfConfig {
    /// Rate of the covariance propagation and the measurement updates, Hz
    /// (the state is propagated at every sample).
    pub update_hz: f64,
    /// Relative gyro scale-factor and misalignment uncertainty: the tilt's
    /// variance grows by (this x angle turned)^2, the heading's by (this x
    /// angle turned about the vertical)^2.
    pub gyro_scale_error: f64,
    /// Floor of the 1-sigma of the tilt measured at rest (accelerometer
    /// bias, a surface that is not quite still), deg.
    pub rest_tilt_sigma_deg: f64,
    /// Accelerometer and vehicle-model noise driving the velocity,
    /// m/s^2/sqrt(Hz).
    pub accel_noise: f64,
    /// The unit is in a ground vehicle: no lateral and no vertical velocity
    /// at the rear axle (`[mounting] lever_arm`). false: a unit that goes
    /// nowhere on average (hand-held, on a bench): a bounded velocity on
    /// every axis and the low-passed specific force as gravity. "auto"
    /// (default): a vehicle until the body's roll/pitch rates swing about
    /// their 3-s mean by more than `handheld_rate_dps` (RMS over 3 s), which
    /// no car body does.
    pub vehicle: AutoBool,
    /// See `vehicle = "auto"`, deg/s.
    pub handheld_rate_dps: f64,
    /// 1-sigma of the vehicle constraint (sideslip, suspension), m/s.
    pub nhc_sigma: f64,
    /// A vehicle's largest vertical speed, m/s: no road has the car climb or
    /// descend faster (7 % at 100 km/h). Beyond it the vertical velocity is
    /// held to the bound (1-sigma 0.5 m/s); 0 turns the bound off.
    pub max_vertical_speed: f64,
    /// A vehicle's forward-speed band, m/s: with nothing else measuring
    /// it, a car's speed stays within `-max_reverse_speed ..
    /// max_forward_speed`; a forward velocity beyond is held to the bound
    /// (one-sided, never gated, 1-sigma `speed_bound_sigma`). Inside the
    /// band it says nothing. 0 turns the bound off.
    pub max_forward_speed: f64,
    pub max_reverse_speed: f64,
    pub speed_bound_sigma: f64,
    /// The velocity noise of a quiet car, m/s^2/sqrt(Hz): a car cruising
    /// smoothly keeps its speed. It rises to `accel_noise` as the tick's
    /// acceleration (its mean beyond gravity and its vibration) reaches
    /// `accel_ref`, m/s^2.
    pub accel_noise_quiet: f64,
    pub accel_ref: f64,
    /// The accelerometer's bias, g: the tilt takes it in at a stop; once
    /// the car has turned it drives the velocity, and a velocity that old
    /// no longer refuses a standstill.
    pub accel_bias_g: f64,
    /// 1-sigma of the velocity of a unit that is not a vehicle, m/s.
    pub free_velocity_sigma: f64,
    /// Not a vehicle: time constant of the navigation-frame low-pass of the
    /// specific force whose direction is fused as gravity, s.
    pub accel_tau_s: f64,
    /// Not a vehicle: 1-sigma of that tilt measurement for a unit held
    /// still or turned slowly, deg.
    pub tilt_sigma_deg: f64,
    /// Not a vehicle: the share of the unit's acceleration in the motion
    /// band (periods of 0.3 to `accel_tau_s` s, RMS) taken to remain in the
    /// low-pass; it adds to that tilt's 1-sigma in quadrature, so that a
    /// unit moved back and forth is levelled loosely. 0 turns it off.
    pub tilt_motion_share: f64,
    /// Not a vehicle: random walk of the gyro bias while the unit moves,
    /// deg/s/sqrt(s). A hand-held MEMS gyro's error in motion is not its
    /// bias at rest (on the BROAD recordings the gyro alone drifts by about
    /// 1 deg over each 20-30 s of motion and comes back to its rest bias at
    /// the next rest); the bias is then learned in motion too, from the
    /// low-passed gravity, with this walk. 0: the paper's policy (the bias
    /// is learned only when the data say quasi-static).
    pub motion_bias_walk: f64,
    /// 1-sigma of the zero-velocity update at rest, m/s.
    pub zupt_sigma: f64,
    /// Floor of the zero-rate update's 1-sigma at rest, deg/s (the measured
    /// gyro noise over the rest is used when larger).
    pub zru_sigma_dps: f64,
    /// 1-sigma of the vehicle speed measurement, m/s.
    pub speed_sigma: f64,
    /// Random walk of the speed scale (tyre radius), 1/sqrt(s).
    pub scale_walk: f64,
    /// Innovation gate: a measurement with NIS > gate_sigma^2 is refused.
    pub gate_sigma: f64,
    /// A quiet period is a stop only when zero lies within this many sigmas
    /// of the velocity the filter believes (the velocity's NIS against zero
    /// below `stop_sigma`^2); beyond, it is a smooth cruise. A decision
    /// between two hypotheses, not an outlier gate: a stop taken for a
    /// cruise still reads the bias and the tilt and misses only the
    /// zero-velocity update, while a cruise taken for a stop zeroes a
    /// velocity the later stops are judged by.
    pub stop_sigma: f64,
    /// Seconds of refused standstill evidence after which the filter
    /// re-levels on it (flagged).
    pub relevel_s: f64,
    /// 1-sigma of the velocity at power-on, m/s (the car may be moving).
    pub init_speed_sigma: f64,
    /// Relative change of the field's norm that counts as a magnetic disturbance.
    pub mag_norm_tol: f64,
    /// Change of the field's dip angle that counts as a magnetic disturbance, deg.
    pub mag_dip_tol_deg: f64,
    /// The paper's quasi-static conditions (inner band, acceleration-change
    /// criterion quiet, turn rate low) must hold this long before the bias
    /// is learned outside a standstill, s.
    pub dwell_s: f64,
    /// Largest bias-corrected rate still counted as quasi-static, deg/s.
    pub turn_rate_dps: f64,
    /// For ablation only: the filter's named situation rules to switch off
    /// (`src/estimator/mekf/rules.rs`, `gyrocomp evaluate --ablate`).
    /// Default none: the default filter has every rule on.
    pub ablate: Vec<String>,
}

impl Default for MekfConfig {
    fn default() -> Self {
        MekfConfig {
            update_hz: 25.0,
            gyro_scale_error: 0.01,
            rest_tilt_sigma_deg: 0.05,
            accel_noise: 0.1,
            vehicle: AutoBool::Auto,
            handheld_rate_dps: 15.0,
            nhc_sigma: 0.3,
            max_vertical_speed: 2.0,
            max_forward_speed: 60.0,
            max_reverse_speed: 5.0,
            speed_bound_sigma: 1.0,
            accel_noise_quiet: 0.01,
            accel_ref: 0.5,
            accel_bias_g: 0.01,
            free_velocity_sigma: 1.0,
            accel_tau_s: 3.0,
            tilt_sigma_deg: 0.2,
            tilt_motion_share: 0.03,
            motion_bias_walk: 0.005,
            zupt_sigma: 0.02,
            zru_sigma_dps: 0.005,
            speed_sigma: 0.1,
            scale_walk: 1e-4,
            gate_sigma: 4.0,
            stop_sigma: 2.0,
            relevel_s: 1.5,
            init_speed_sigma: 15.0,
            mag_norm_tol: 0.1,
            mag_dip_tol_deg: 6.0,
            dwell_s: 2.0,
            turn_rate_dps: 3.0,
            ablate: Vec::new(),
        }
    }
}

/// `[rest]`: the standstill detector (`src/estimator/rest.rs`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RestConfig {
    /// Time constant of the low-passes (signals and their deviations), s.
    pub tau_s: f64,
    /// The conditions must hold this long, s.
    pub min_s: f64,
    /// Largest RMS deviation of the gyro from its low-pass, deg/s (engine
    /// idle vibration passes, driving does not).
    pub gyro_dev_dps: f64,
    /// Largest RMS deviation of the specific force from its low-pass (summed
    /// over the axes), g: engine idle vibration of 0.02-0.04 g per axis
    /// passes.
    pub accel_dev_g: f64,
    /// Largest | |f|/g - 1 | of the low-passed specific force, with g the
    /// gravity this unit measures (g0 when it was steady while measured,
    /// then the mean |f| over its rests; before either, 3 % about 1 g). A
    /// steady 0.1 g acceleration is 0.5 %.
    pub band: f64,
    /// Largest low-passed bias-corrected rate, deg/s (plus three bias sigmas).
    pub rate_dps: f64,
    /// Largest change of the low-passed specific force since the conditions
    /// began, g (a car creeping away from a stop is not standing).
    pub drift_g: f64,
}

impl Default for RestConfig {
    fn default() -> Self {
        RestConfig { tau_s: 0.5, min_s: 1.0, gyro_dev_dps: 0.6, accel_dev_g: 0.05, band: 0.005, rate_dps: 0.5, drift_g: 0.01 }
    }
}

/// Output frame IDs (the DBC describes the defaults) and whether `EST_AID` is sent.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OutputConfig {
    pub rate_id: u32,
    pub attitude_id: u32,
    pub bias_id: u32,
    pub status_id: u32,
    /// `EST_AID`: which aid sources of the default filter were fused or refused.
    pub aid_id: u32,
    /// Send `EST_AID`, the fifth frame of a sample; false: four frames a
    /// sample (a bus with no room for it), and `aid_id` is not used.
    pub aid_frame: bool,
}

impl Default for OutputConfig {
    fn default() -> Self {
        OutputConfig { rate_id: 0x110, attitude_id: 0x111, bias_id: 0x112, status_id: 0x113, aid_id: 0x114, aid_frame: true }
    }
}

impl OutputConfig {
    /// Every output ID with its key, `aid_id` included whether or not it is sent.
    pub fn keyed_ids(&self) -> [(&'static str, u32); 5] {
        [
            ("output.rate_id", self.rate_id),
            ("output.attitude_id", self.attitude_id),
            ("output.bias_id", self.bias_id),
            ("output.status_id", self.status_id),
            ("output.aid_id", self.aid_id),
        ]
    }

    /// The IDs of the frames sent, with their keys: the four of every
    /// sample, and `aid_id` when `aid_frame` is on.
    pub fn sent(&self) -> impl Iterator<Item = (&'static str, u32)> {
        self.keyed_ids().into_iter().take(if self.aid_frame { 5 } else { 4 })
    }
}

/// Daemon-only settings (ignored by replay).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DaemonConfig {
    /// Directory of the state file; empty = $STATE_DIRECTORY, else no state.
    pub state_dir: String,
    /// Seconds between state saves.
    pub save_every_s: f64,
    /// Seconds without a sample before the bus is reported silent.
    pub silent_after_s: f64,
    /// Receive CAN error frames and count them.
    pub error_frames: bool,
}

impl Default for DaemonConfig {
    fn default() -> Self {
        DaemonConfig { state_dir: String::new(), save_every_s: 10.0, silent_after_s: 0.5, error_frames: false }
    }
}

/// `[mounting]`: where the sensor sits in the vehicle.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MountingConfig {
    /// The sensor frame in the vehicle frame as Z-Y-X Euler angles
    /// `[roll, pitch, yaw]`, deg. Every sample is rotated into the vehicle
    /// frame (FRD) before the estimator; outputs are in the vehicle frame.
    /// Default `[0, 0, 0]` (sensor axes = vehicle axes).
    #[serde(deserialize_with = "exact_rotation")]
    pub rotation: [f64; 3],
    /// Position of the sensor from the centre of the rear axle, vehicle
    /// axes (x forward, y right, z down), m.
    #[serde(deserialize_with = "exact_lever_arm")]
    pub lever_arm: [f64; 3],
}

impl Default for MountingConfig {
    fn default() -> Self {
        MountingConfig { rotation: [0.0; 3], lever_arm: [0.0; 3] }
    }
}

/// `[speed]`: the vehicle's own speed from its CAN bus, described by its DBC.
/// Off unless `dbc` is set.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SpeedConfig {
    /// The car's DBC file. Empty (default): no speed input.
    pub dbc: String,
    /// Message name in the DBC that carries the speed signals.
    pub message: String,
    /// Signal names in that message; their values are averaged. The unit is
    /// the DBC's (km/h, m/s or mph).
    pub signals: Vec<String>,
    /// Factor applied to the decoded speed (e.g. a tyre correction).
    pub scale: f64,
    /// A speed older than this is not used (and flagged), s.
    pub timeout_s: f64,
}

impl Default for SpeedConfig {
    fn default() -> Self {
        SpeedConfig { dbc: String::new(), message: String::new(), signals: Vec::new(), scale: 1.0, timeout_s: 0.5 }
    }
}

impl MountingConfig {
    /// Sensor-to-vehicle rotation matrix (None when the rotation is zero).
    pub fn matrix(&self) -> Option<[[f64; 3]; 3]> {
        if self.rotation == [0.0; 3] {
            return None;
        }
        let d = std::f64::consts::PI / 180.0;
        Some(crate::estimator::quat::matrix_from_euler(self.rotation[0] * d, self.rotation[1] * d, self.rotation[2] * d))
    }
}

impl SpeedConfig {
    /// True when a speed source is configured.
    pub fn enabled(&self) -> bool {
        !self.dbc.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::bad;

    #[test]
    fn empty_is_default_and_valid() {
        let c = Config::parse("", "t.toml").unwrap();
        assert_eq!(c, Config::default());
        assert_eq!(c.profile().rate_hz, 204.8);
        // the printed effective config parses back to the same effective config
        assert_eq!(Config::parse(&c.to_toml(), "x").unwrap(), c.effective());
    }

    #[test]
    fn a_partial_ids_table_keeps_the_other_defaults() {
        for text in ["[input.ids]\ngyro = 0x200\n", "[input]\nids = { gyro = 0x200 }\n", "[input]\nids.gyro = 0x200\n"] {
            let c = Config::parse(text, "t").unwrap_or_else(|e| panic!("{text}: {e}"));
            assert_eq!(c.input.ids, InputIds { gyro: 0x200, ..InputIds::DEFAULT });
        }
        assert!(bad("[input.ids]\ngyr = 0x200\n").contains("gyr"));
    }

    #[test]
    fn the_annotated_example_shows_the_defaults() {
        // config/gyrocomp.toml documents every key with its default value,
        // except the values marked "example" there.
        let text = include_str!("../../config/gyrocomp.toml");
        let mut c = Config::parse(text, "config/gyrocomp.toml").unwrap();
        let d = Config::default();
        assert_eq!(c.can.interface, "vcan0");
        c.can = d.can.clone();
        assert_eq!(c.thermal.p1, [0.0020, 0.0044, 0.0192]);
        c.thermal.p1 = d.thermal.p1;
        c.thermal.p2 = d.thermal.p2;
        assert_eq!(c, d);
        for section in [
            "input",
            "input.ids",
            "can",
            "estimator",
            "ekf",
            "switching",
            "thermal",
            "mekf",
            "rest",
            "output",
            "daemon",
            "mounting",
            "speed",
        ] {
            assert!(text.contains(&format!("\n[{section}]\n")), "section [{section}] is not documented");
        }
    }

    #[test]
    fn use_magnetometer_and_vehicle_take_auto_or_a_bool_and_robust_is_the_default_filter() {
        let c = Config::parse("[estimator]\nuse_magnetometer = \"auto\"\n[mekf]\nvehicle = false", "t").unwrap();
        assert_eq!((c.estimator.use_magnetometer, c.mekf.vehicle), (AutoBool::Auto, AutoBool::Bool(false)));
        let c = Config::parse("[estimator]\nuse_magnetometer = true\nmode = \"robust\"", "t").unwrap();
        assert_eq!((c.estimator.use_magnetometer, c.estimator.mode), (AutoBool::Bool(true), Mode::Mekf));
        assert_eq!(Config::parse(&c.to_toml(), "x").unwrap(), c.effective());
    }

    #[test]
    fn refuses_unknown_keys() {
        let e = bad("[switching]\ninnr = [0.9, 1.1]");
        assert!(e.contains("innr"), "{e}");
        let e = bad("[swtching]\n");
        assert!(e.contains("swtching"), "{e}");
    }

    #[test]
    fn thermal_paper_contract_and_polynomial_form() {
        // The paper's form keeps working as it is, and means order 1, no clamp, no learning.
        let c = Config::parse("[thermal]\nt0 = 20.0\np1 = [0.002, 0.0044, 0.0192]\np2 = [0.0011, 0.0003, 0.0012]", "t").unwrap();
        assert_eq!(c.thermal.order, 1);
        assert_eq!((c.thermal.t_min, c.thermal.t_max, c.thermal.learn), (None, None, false));
        let c = Config::parse(
            "[thermal]\norder = 3\np1 = [1.0, 1.0, 1.0]\np3 = [1e-4, 0.0, 0.0]\np4 = [0.0, 0.0, -1e-6]\nt_min = 0.0\nt_max = 70.0\nlearn = true",
            "t",
        )
        .unwrap();
        assert_eq!(c.thermal.p4[2], -1e-6);
        assert_eq!(c.thermal.t_max, Some(70.0));
        assert_eq!(Config::parse(&c.to_toml(), "x").unwrap(), c.effective());
    }
}
