//! Scenarios: the motion, the temperature and the ranges the sensor errors
//! are drawn from.
//!
//! - `static`: bench, unit at rest (slightly tilted), self-heating.
//! - `chamber`: thermal-chamber run as in the paper: power-on at the chamber
//!   ambient, self-heating to the working temperature, 30 min at rest.
//! - `paper`: 800 s road-like run: gentle driving (a few degrees of roll and
//!   pitch, slow turns, speed changes), then sustained acceleration from
//!   about 350 s (a winding road with no straight, constant-speed stretch).
//! - `vehicle`: gentle driving, then from 350 s long 0.3 g accelerations and
//!   brakings, constant-radius 0.4 g turns of 20-30 s, short cruises between
//!   them, vertical bumps, engine vibration, temperature rising 10-20 deg C,
//!   turn-on bias up to +-0.5 deg/s; `hard` adds short manoeuvres above 0.6 g.
//! - `urban`: city driving with the statistics of real drives ([`super::urban`]):
//!   continuous 0.05-0.2 g speed changes, 5-7 s stops, about 90 tight turns
//!   per 400 s (up to 0.6 g, 45 deg/s), hills of +-7 deg, a reversing
//!   manoeuvre, the sensor 0.9 m ahead of the rear axle, wheel speeds on the
//!   bus, turn-on bias up to +-5 deg/s.
//!
//! `power_on_moving` (paper, vehicle, urban): the run starts while the car is
//! already driving (no parked start).

use super::model::{Effect, NoiseModel};
use super::motion::{Bump, Ease, MotionSpec, Sine, Thermal, G};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

pub const SCENARIOS: [&str; 7] = ["static", "chamber", "paper", "vehicle", "urban", "smooth", "crawl"];

/// Ranges the sensor parameters and environment are drawn from. Every field
/// can be overridden by `gyrocomp simulate --ranges FILE` (a TOML file with
/// any subset of these keys); an effect is switched off by leaving it out of
/// `effects`, a noise term by setting it to 0.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Ranges {
    /// Gyro effects that act (names of the model file's vocabulary).
    pub effects: Vec<Effect>,
    /// Turn-on bias: uniform in +-this per axis, deg/s.
    pub turn_on_bias: f64,
    /// Linear thermal slope: the paper's Table 1 p1 per axis
    /// (0.0020, 0.0044, 0.0192 deg/s/C) times a factor uniform in this
    /// range, with a random sign.
    #[serde(deserialize_with = "crate::config::arrays::exactly")]
    pub thermal_linear_factor: [f64; 2],
    /// Reference temperature of the thermal terms, deg C.
    pub thermal_t0: f64,
    /// Quadratic thermal coefficient: uniform in +-this, deg/s/C^2.
    pub thermal_quadratic: f64,
    /// Thermal-rate coefficient: uniform in +-this, deg/s per (C/s).
    pub thermal_rate: f64,
    /// Warm-up transient amplitude: uniform in +-this per axis, deg/s.
    pub warmup_amplitude: f64,
    /// Warm-up time constant, s: uniform in this range.
    #[serde(deserialize_with = "crate::config::arrays::exactly")]
    pub warmup_tau_s: [f64; 2],
    /// g-sensitivity: each matrix element uniform in +-this, deg/s/g.
    pub g_sensitivity: f64,
    /// Scale-factor error: uniform in +-this per axis (dimensionless).
    pub scale_factor: f64,
    /// Misalignment: each off-diagonal element uniform in +-this, rad.
    pub misalignment: f64,
    /// Time delay, s: uniform in this range.
    #[serde(deserialize_with = "crate::config::arrays::exactly")]
    pub time_delay_s: [f64; 2],
    /// Accelerometer bias: uniform in +-this per axis, g.
    pub accel_bias: f64,
    /// Magnetometer hard-iron bias: uniform in +-this per axis, gauss.
    pub magn_bias: f64,
    /// Stochastic terms, used as given.
    pub noise: NoiseModel,
    /// Engine/road vibration amplitude per tone on the z axis, g, uniform in
    /// this range (x and y get half); [0, 0] switches vibration off.
    #[serde(deserialize_with = "crate::config::arrays::exactly")]
    pub vibration_g: [f64; 2],
    /// Temperature at power-on, deg C: uniform in this range.
    #[serde(deserialize_with = "crate::config::arrays::exactly")]
    pub ambient: [f64; 2],
    /// Self-heating rise, deg C: uniform in this range.
    #[serde(deserialize_with = "crate::config::arrays::exactly")]
    pub self_heating: [f64; 2],
    /// Self-heating time constant, s: uniform in this range.
    #[serde(deserialize_with = "crate::config::arrays::exactly")]
    pub heating_tau_s: [f64; 2],
    /// Sensor position from the rear-axle centre, vehicle axes (x forward,
    /// y right, z down), m. Only the road kinematics of `urban` model it;
    /// the other scenarios refuse a non-zero value.
    #[serde(default)]
    #[serde(deserialize_with = "crate::config::arrays::exactly")]
    pub lever_arm: [f64; 3],
    /// Road vibration (urban), per tone on the z axis at speed, g: uniform in
    /// this range (x 0.4, y 0.5 of it; six tones of 8-45 Hz; zero at a stop).
    #[serde(default)]
    #[serde(deserialize_with = "crate::config::arrays::exactly")]
    pub road_vibration_g: [f64; 2],
    /// Wheel speeds (urban): latency of the frames, s, uniform in this range.
    #[serde(default)]
    #[serde(deserialize_with = "crate::config::arrays::exactly")]
    pub wheel_latency_s: [f64; 2],
    /// Wheel speeds: tyre scale error, uniform in +-this (dimensionless).
    #[serde(default)]
    pub wheel_scale_error: f64,
    /// Wheel speeds: white noise per wheel and frame, km/h.
    #[serde(default)]
    pub wheel_noise_kmh: f64,
    /// The car body's ride vibration ([`RIDE`]) times a factor uniform in
    /// this range (1: the comma2k19 car's; `smooth` 0-0.3).
    #[serde(default = "one_one")]
    #[serde(deserialize_with = "crate::config::arrays::exactly")]
    pub ride_scale: [f64; 2],
}

fn one_one() -> [f64; 2] {
    [1.0, 1.0]
}

/// The paper's Table 1 slopes p1, deg/s per deg C.
pub const TABLE1_P1: [f64; 3] = [0.0020, 0.0044, 0.0192];

impl Ranges {
    fn base() -> Ranges {
        Ranges {
            effects: vec![Effect::TurnOnBias, Effect::ThermalLinear, Effect::WarmupTransient],
            turn_on_bias: 0.5,
            thermal_linear_factor: [0.5, 1.5],
            thermal_t0: 25.0,
            thermal_quadratic: 5e-5,
            thermal_rate: 0.5,
            warmup_amplitude: 0.05,
            warmup_tau_s: [20.0, 60.0],
            g_sensitivity: 0.009,
            scale_factor: 0.002,
            misalignment: 0.0009,
            time_delay_s: [0.0005, 0.003],
            accel_bias: 0.005,
            magn_bias: 0.005,
            noise: NoiseModel::default(),
            vibration_g: [0.0, 0.0],
            ambient: [20.0, 30.0],
            self_heating: [8.0, 12.0],
            heating_tau_s: [150.0, 300.0],
            lever_arm: [0.0; 3],
            road_vibration_g: [0.0, 0.0],
            wheel_latency_s: [0.0, 0.0],
            wheel_scale_error: 0.0,
            wheel_noise_kmh: 0.0,
            ride_scale: one_one(),
        }
    }

    /// The default ranges of a scenario.
    pub fn for_scenario(name: &str) -> Ranges {
        let mut r = Ranges::base();
        match name {
            "chamber" => {
                r.ambient = [-10.0, 50.0];
                r.self_heating = [12.0, 20.0];
                r.heating_tau_s = [300.0, 600.0];
            }
            "paper" => {
                r.vibration_g = [0.005, 0.015];
                r.self_heating = [10.0, 15.0];
                r.heating_tau_s = [150.0, 300.0];
            }
            "vehicle" => {
                r.effects = vec![
                    Effect::TurnOnBias,
                    Effect::ThermalLinear,
                    Effect::WarmupTransient,
                    Effect::GSensitivity,
                    Effect::ScaleFactor,
                    Effect::Misalignment,
                ];
                r.vibration_g = [0.02, 0.04];
                r.self_heating = [10.0, 20.0];
                r.heating_tau_s = [150.0, 300.0];
            }
            "urban" | "smooth" | "crawl" => {
                r.effects = vec![
                    Effect::TurnOnBias,
                    Effect::ThermalLinear,
                    Effect::WarmupTransient,
                    Effect::GSensitivity,
                    Effect::ScaleFactor,
                    Effect::Misalignment,
                ];
                // real turn-on biases are several deg/s (an ADIS16448 measured 4.5)
                r.turn_on_bias = 5.0;
                // engine idle: the sensor model's two tones, small (all there is at a stop)
                r.vibration_g = [0.003, 0.008];
                r.road_vibration_g = [0.006, 0.012];
                r.ambient = [5.0, 35.0];
                r.self_heating = [8.0, 15.0];
                r.heating_tau_s = [300.0, 900.0];
                r.lever_arm = [0.9, 0.0, 0.0];
                r.wheel_latency_s = [0.02, 0.08];
                r.wheel_scale_error = 0.03;
                r.wheel_noise_kmh = 0.03;
                if name != "urban" {
                    // a smooth car: a damped body, an electric or quiet
                    // engine, a good road (a crawl shakes little anyway)
                    r.ride_scale = [0.0, 0.3];
                    r.road_vibration_g = [0.0, 0.0036];
                    r.vibration_g = [0.0, 0.003];
                }
            }
            _ => {}
        }
        r
    }

    /// The scenario's ranges with the keys of `text` (TOML) laid over them.
    pub fn with_overrides(name: &str, text: &str) -> Result<Ranges, String> {
        let base = toml::Value::try_from(Ranges::for_scenario(name)).map_err(|e| e.to_string())?;
        let over: toml::Value = toml::from_str(text).map_err(|e| e.to_string())?;
        let (mut base, over) = match (base, over) {
            (toml::Value::Table(b), toml::Value::Table(o)) => (b, o),
            _ => return Err("ranges must be a TOML table".into()),
        };
        for (k, v) in over {
            if !base.contains_key(&k) {
                return Err(format!("unknown key {k:?} in ranges"));
            }
            if k == "noise" {
                if let (Some(toml::Value::Table(bn)), toml::Value::Table(on)) = (base.get_mut("noise"), &v) {
                    for (nk, nv) in on {
                        bn.insert(nk.clone(), nv.clone());
                    }
                    continue;
                }
            }
            base.insert(k, v);
        }
        let r: Ranges = toml::Value::Table(base).try_into().map_err(|e: toml::de::Error| e.to_string())?;
        let [lo, hi] = r.ride_scale;
        if !(lo.is_finite() && hi.is_finite() && 0.0 <= lo && lo <= hi && hi <= MAX_RIDE_SCALE) {
            return Err(format!(
                "ranges: ride_scale = [{lo:?}, {hi:?}]: want 0 <= low <= high <= {MAX_RIDE_SCALE} (times the comma2k19 car's ride vibration)"
            ));
        }
        r.check()?;
        Ok(r)
    }

    /// Every half-width a finite number >= 0, every range finite with
    /// low <= high, the lever arm within 10 m: a negative half-width (an
    /// empty range read as its mirror) or a range the other way round is
    /// refused naming the key (the drawn model's own ranges then bound the
    /// sizes, `SensorModel::validate`).
    fn check(&self) -> Result<(), String> {
        let half = [
            ("turn_on_bias", self.turn_on_bias),
            ("thermal_quadratic", self.thermal_quadratic),
            ("thermal_rate", self.thermal_rate),
            ("warmup_amplitude", self.warmup_amplitude),
            ("g_sensitivity", self.g_sensitivity),
            ("scale_factor", self.scale_factor),
            ("misalignment", self.misalignment),
            ("accel_bias", self.accel_bias),
            ("magn_bias", self.magn_bias),
            ("wheel_scale_error", self.wheel_scale_error),
            ("wheel_noise_kmh", self.wheel_noise_kmh),
        ];
        for (k, v) in half {
            if !(v.is_finite() && v >= 0.0) {
                return Err(format!("ranges: {k} = {v:?}: want a finite half-width >= 0 (uniform in +-{k})"));
            }
        }
        let pairs = [
            ("thermal_linear_factor", self.thermal_linear_factor),
            ("warmup_tau_s", self.warmup_tau_s),
            ("time_delay_s", self.time_delay_s),
            ("vibration_g", self.vibration_g),
            ("ambient", self.ambient),
            ("self_heating", self.self_heating),
            ("heating_tau_s", self.heating_tau_s),
            ("road_vibration_g", self.road_vibration_g),
            ("wheel_latency_s", self.wheel_latency_s),
        ];
        for (k, [lo, hi]) in pairs {
            if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
                return Err(format!("ranges: {k} = [{lo:?}, {hi:?}]: want finite low <= high"));
            }
        }
        if self.lever_arm.iter().any(|l| !(l.is_finite() && l.abs() <= 10.0)) {
            return Err(format!("ranges: lever_arm = {:?}: want each within -10..10 m (a car's rear axle to its sensor)", self.lever_arm));
        }
        Ok(())
    }
}

/// The largest `ride_scale`: three times the comma2k19 car's ride (a rough
/// road or a stiff body; beyond it the body's sines are no longer a car's).
pub const MAX_RIDE_SCALE: f64 = 3.0;

/// Uniform in `[lo, hi]` (lo when the range is empty).
pub fn uni(rng: &mut ChaCha8Rng, r: [f64; 2]) -> f64 {
    if r[1] > r[0] {
        rng.gen_range(r[0]..=r[1])
    } else {
        r[0]
    }
}

/// Uniform in `[-m, m]`.
pub fn sym(rng: &mut ChaCha8Rng, m: f64) -> f64 {
    if m > 0.0 {
        rng.gen_range(-m..=m)
    } else {
        0.0
    }
}

/// Builds the command profiles segment by segment, tracking the speed.
struct Plan {
    a_long: Ease,
    a_lat: Ease,
    t: f64,
    /// Speed at `t` (exact for the eased profile: the mean of a cosine ease
    /// between two levels is their average).
    v: f64,
    long: f64,
    lat: f64,
}

impl Plan {
    fn new(v0: f64) -> Plan {
        let mut a_long = Ease::default();
        let mut a_lat = Ease::default();
        a_long.push(0.0, 0.0);
        a_lat.push(0.0, 0.0);
        Plan { a_long, a_lat, t: 0.0, v: v0, long: 0.0, lat: 0.0 }
    }

    /// Ease to the levels (g) over `ramp` s, then hold them for `hold` s.
    fn seg(&mut self, long: f64, lat: f64, ramp: f64, hold: f64) {
        let t1 = self.t + ramp;
        self.v += G * 0.5 * (self.long + long) * ramp;
        self.a_long.push(t1, long);
        self.a_lat.push(t1, lat);
        self.v += G * long * hold;
        let t2 = t1 + hold;
        self.a_long.push(t2, long);
        self.a_lat.push(t2, lat);
        self.t = t2;
        self.long = long;
        self.lat = lat;
    }

    /// Longest hold at `long` g (after a ramp) keeping the speed within [lo, hi].
    fn max_hold(&self, long: f64, ramp: f64, lo: f64, hi: f64) -> f64 {
        let v1 = self.v + G * 0.5 * (self.long + long) * ramp;
        if long > 0.0 {
            ((hi - v1) / (G * long)).max(0.0)
        } else if long < 0.0 {
            ((v1 - lo) / (G * -long)).max(0.0)
        } else {
            f64::INFINITY
        }
    }
}

fn sines(rng: &mut ChaCha8Rng, amps: [f64; 2], periods: [f64; 2], n: usize) -> Vec<Sine> {
    (0..n)
        .map(|_| Sine { amp: uni(rng, amps), freq: 1.0 / uni(rng, periods), phase: rng.gen_range(0.0..2.0 * std::f64::consts::PI) })
        .collect()
}

/// The speed at which [`RIDE`]'s rates are the ones given, m/s.
pub const RIDE_SPEED: f64 = 18.0;

/// A car body's ride vibration, as the real car measured it: the comma2k19
/// RAV4 at 15-20 m/s (`../shared/realdata`, its 3-12 Hz and 12-50 Hz bands,
/// RMS over 10-s windows, median) shook at roll 0.29 and 0.25 deg/s, pitch
/// 0.37 and 0.70 deg/s, where the simulated car had only the gyro's noise
/// (0.04-0.1). Per axis and band: `(axis 0 roll / 1 pitch, wavelengths m,
/// RMS rate deg/s at RIDE_SPEED, tones)`. The road's texture at wavelength
/// `l` shakes the body at `v / l` Hz, its rate growing with the speed.
pub const RIDE: [(usize, [f64; 2], f64, usize); 4] =
    [(0, [1.5, 6.0], 0.29, 6), (0, [0.36, 1.5], 0.25, 6), (1, [1.5, 6.0], 0.37, 6), (1, [0.36, 1.5], 0.70, 6)];

/// Give a driving scenario's car its ride vibration ([`ride`]): the planar
/// model's `ride_roll` / `ride_pitch`, the road kinematics' `road_roll` /
/// `road_pitch` (both sines of the distance).
pub fn add_ride(spec: &mut MotionSpec, rng: &mut ChaCha8Rng, scale: [f64; 2]) {
    // drawn only for a range (every other scenario's draws stay as they were)
    let k = uni(rng, scale);
    let (mut roll, mut pitch) = ride(rng);
    for s in roll.iter_mut().chain(pitch.iter_mut()) {
        s.amp *= k;
    }
    match spec.road.as_mut() {
        Some(road) => {
            road.road_roll.extend(roll);
            road.road_pitch.extend(pitch);
        }
        None => {
            spec.ride_roll = roll;
            spec.ride_pitch = pitch;
        }
    }
}

/// The ride vibration of one simulated car (roll, pitch: deg, sines of the
/// distance in cycles per metre), each band's RMS within +-30 % of [`RIDE`]'s.
pub fn ride(rng: &mut ChaCha8Rng) -> (Vec<Sine>, Vec<Sine>) {
    let mut out = (Vec::new(), Vec::new());
    for (axis, lambda, rms, n) in RIDE {
        let per_tone = rms * uni(rng, [0.7, 1.3]) / (n as f64).sqrt();
        for _ in 0..n {
            let l = uni(rng, lambda);
            // rate amplitude sqrt(2) rms = amp 2 pi v / l at v = RIDE_SPEED
            let amp = per_tone * std::f64::consts::SQRT_2 * l / (2.0 * std::f64::consts::PI * RIDE_SPEED);
            let sine = Sine { amp, freq: 1.0 / l, phase: rng.gen_range(0.0..2.0 * std::f64::consts::PI) };
            if axis == 0 {
                out.0.push(sine);
            } else {
                out.1.push(sine);
            }
        }
    }
    out
}

/// The unit's temperature: ambient, self-heating and its time constant drawn from the ranges.
pub(super) fn thermal(rng: &mut ChaCha8Rng, r: &Ranges) -> Thermal {
    Thermal {
        ambient: uni(rng, r.ambient),
        rise: uni(rng, r.self_heating),
        tau: uni(rng, r.heating_tau_s),
        drift: 0.0,
        cycle_amp: 0.0,
        cycle_period: 1.0,
    }
}

fn at_rest(rng: &mut ChaCha8Rng, r: &Ranges, duration: f64) -> MotionSpec {
    MotionSpec {
        duration,
        a_long: Ease::constant(0.0),
        a_lat: Ease::constant(0.0),
        v0: 0.0,
        yaw0: rng.gen_range(-180.0..180.0),
        roll0: sym(rng, 2.0),
        pitch0: sym(rng, 2.0),
        roll_sines: vec![],
        pitch_sines: vec![],
        roll_per_lat: 0.0,
        pitch_per_long: 0.0,
        bumps: vec![],
        ride_roll: vec![],
        ride_pitch: vec![],
        thermal: thermal(rng, r),
        manoeuvre_start: 0.0,
        road: None,
    }
}

/// Gentle driving from `p.t` to `until`: speed changes of 0.03-0.08 g, slow
/// turns of 0.03-0.08 g, cruises. Speeds kept in 8..22 m/s.
fn gentle(rng: &mut ChaCha8Rng, p: &mut Plan, until: f64) {
    while p.t < until - 20.0 {
        let ramp = uni(rng, [1.5, 3.0]);
        match rng.gen_range(0..3) {
            0 => {
                let a = uni(rng, [0.03, 0.08]) * if p.v > 15.0 { -1.0 } else { 1.0 };
                let hold = uni(rng, [4.0, 12.0]).min(p.max_hold(a, ramp, 8.0, 22.0));
                p.seg(a, 0.0, ramp, hold);
            }
            1 => {
                let lat = uni(rng, [0.03, 0.08]) * if rng.gen_bool(0.5) { 1.0 } else { -1.0 };
                p.seg(0.0, lat, ramp, uni(rng, [6.0, 18.0]));
            }
            _ => p.seg(0.0, 0.0, ramp, uni(rng, [3.0, 10.0])),
        }
    }
    let left = (until - p.t - 2.0).max(0.0);
    p.seg(0.0, 0.0, 2.0, left);
}

fn road(rng: &mut ChaCha8Rng, r: &Ranges, duration: f64, power_on_moving: bool) -> (MotionSpec, Plan) {
    let v0 = if power_on_moving { 12.0 } else { 0.0 };
    let mut p = Plan::new(v0);
    if power_on_moving {
        // Already driving at 12 m/s.
        p.seg(0.0, 0.0, 0.5, 2.0);
    } else {
        // Engine on, parked for 3 s, then pull away gently (0.08 g to ~12 m/s).
        p.seg(0.0, 0.0, 0.5, 2.5);
        p.seg(0.08, 0.0, 2.0, 13.0);
        p.seg(0.0, 0.0, 2.0, 0.0);
    }
    let spec = MotionSpec {
        duration,
        a_long: Ease::default(),
        a_lat: Ease::default(),
        v0,
        yaw0: rng.gen_range(-180.0..180.0),
        roll0: sym(rng, 1.0),
        pitch0: sym(rng, 1.0),
        // Road camber and suspension: a few degrees, slow; plus a small fast sway.
        roll_sines: [sines(rng, [1.0, 2.5], [15.0, 60.0], 2), sines(rng, [0.1, 0.3], [0.7, 2.0], 1)].concat(),
        // Grades: a few degrees over a minute or two; pitch sway.
        pitch_sines: [sines(rng, [1.0, 2.5], [40.0, 120.0], 2), sines(rng, [0.1, 0.3], [0.8, 2.5], 1)].concat(),
        roll_per_lat: -uni(rng, [3.0, 5.0]),
        pitch_per_long: uni(rng, [2.0, 4.0]),
        bumps: vec![],
        ride_roll: vec![],
        ride_pitch: vec![],
        thermal: thermal(rng, r),
        manoeuvre_start: 350.0_f64.min(duration),
        road: None,
    };
    (spec, p)
}

fn bumps(rng: &mut ChaCha8Rng, from: f64, to: f64, every: [f64; 2], accel: [f64; 2]) -> Vec<Bump> {
    let mut v = Vec::new();
    let mut t = from + uni(rng, every);
    while t < to - 1.0 {
        v.push(Bump { t0: t, dur: uni(rng, [0.2, 0.5]), accel: uni(rng, accel), pitch: sym(rng, 0.5) });
        t += uni(rng, every);
    }
    v
}

/// Build the motion of a scenario.
pub fn motion(name: &str, hard: bool, duration: f64, rng: &mut ChaCha8Rng, r: &Ranges) -> Result<MotionSpec, String> {
    motion_with(name, &MotionOptions { hard, power_on_moving: false }, duration, rng, r)
}

/// Scenario options that shape the motion.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MotionOptions {
    /// vehicle: add short manoeuvres above 0.6 g.
    pub hard: bool,
    /// paper, vehicle, urban: start while already driving.
    pub power_on_moving: bool,
}

/// Build the motion of a scenario with its options.
pub fn motion_with(name: &str, o: &MotionOptions, duration: f64, rng: &mut ChaCha8Rng, r: &Ranges) -> Result<MotionSpec, String> {
    let hard = o.hard;
    if r.lever_arm != [0.0; 3] && !ROAD_SCENARIOS.contains(&name) {
        return Err(format!("ranges: lever_arm needs the road kinematics of the urban, smooth or crawl scenario, not {name:?}"));
    }
    if o.power_on_moving && matches!(name, "static" | "chamber") {
        return Err(format!("--power-on-moving: the {name} scenario does not move"));
    }
    if hard && matches!(name, "urban" | "crawl") {
        return Err(format!("--hard is a variant of the vehicle and smooth scenarios; {name} has its own manoeuvres"));
    }
    match name {
        "static" | "chamber" => Ok(at_rest(rng, r, duration)),
        "urban" => Ok(super::urban::motion(rng, r, duration, o.power_on_moving)),
        "smooth" => Ok(super::smooth::smooth(rng, r, duration, o.power_on_moving, hard)),
        "crawl" => Ok(super::smooth::crawl(rng, r, duration, o.power_on_moving)),
        "paper" => {
            let (mut spec, mut p) = road(rng, r, duration, o.power_on_moving);
            gentle(rng, &mut p, spec.manoeuvre_start);
            // Sustained acceleration: a winding road, one curve into the next,
            // speed changing all the time; never a straight constant-speed stretch.
            while p.t < duration {
                let lat = uni(rng, [0.15, 0.3]) * if rng.gen_bool(0.5) { 1.0 } else { -1.0 };
                let a = uni(rng, [0.1, 0.2]) * if p.v > 18.0 { -1.0 } else { 1.0 };
                let ramp = uni(rng, [1.0, 2.0]);
                let hold = uni(rng, [6.0, 15.0]).min(p.max_hold(a, ramp, 8.0, 28.0)).max(2.0);
                p.seg(a, lat, ramp, hold);
            }
            spec.bumps = bumps(rng, 5.0, duration, [8.0, 25.0], [0.05, 0.15]);
            spec.a_long = p.a_long;
            spec.a_lat = p.a_lat;
            Ok(spec)
        }
        "vehicle" => {
            let (mut spec, mut p) = road(rng, r, duration, o.power_on_moving);
            gentle(rng, &mut p, spec.manoeuvre_start);
            let (lo, hi) = (8.0, 33.0);
            while p.t < duration {
                let ramp = uni(rng, [0.8, 1.5]);
                let pick = rng.gen_range(0..if hard { 7 } else { 6 });
                match pick {
                    // long acceleration / braking, 0.3 g, as long as the speed range allows
                    0 | 1 => {
                        let a = if p.v < 0.5 * (lo + hi) { 0.3 } else { -0.3 };
                        let hold = p.max_hold(a, ramp, lo, hi).min(uni(rng, [5.0, 10.0]));
                        p.seg(a, 0.0, ramp, hold);
                    }
                    // constant-radius turn, 0.4 g, 20-30 s
                    2 | 3 => {
                        let lat = 0.4 * if rng.gen_bool(0.5) { 1.0 } else { -1.0 };
                        p.seg(0.0, lat, ramp, uni(rng, [20.0, 30.0]));
                    }
                    // braking into a turn, then accelerating out of it
                    4 => {
                        let lat = uni(rng, [0.3, 0.4]) * if rng.gen_bool(0.5) { 1.0 } else { -1.0 };
                        let hold = p.max_hold(-0.2, ramp, lo, hi).min(3.0);
                        p.seg(-0.2, 0.0, ramp, hold);
                        p.seg(0.0, lat, ramp, uni(rng, [10.0, 20.0]));
                        let hold = p.max_hold(0.2, ramp, lo, hi).min(4.0);
                        p.seg(0.2, 0.0, ramp, hold);
                    }
                    // a short cruise
                    5 => p.seg(0.0, 0.0, ramp, uni(rng, [2.0, 8.0])),
                    // hard: a short manoeuvre above 0.6 g (emergency brake or swerve)
                    _ => {
                        let g = uni(rng, [0.65, 0.8]);
                        let ramp = uni(rng, [0.3, 0.6]);
                        if p.v > 16.0 && rng.gen_bool(0.5) {
                            let hold = p.max_hold(-g, ramp, lo, hi).min(uni(rng, [1.0, 2.5]));
                            p.seg(-g, 0.0, ramp, hold);
                        } else {
                            let s = if rng.gen_bool(0.5) { 1.0 } else { -1.0 };
                            p.seg(0.0, s * g, ramp, uni(rng, [1.0, 2.0]));
                            p.seg(0.0, -s * g, ramp, uni(rng, [1.0, 2.0]));
                        }
                    }
                }
            }
            p.seg(0.0, 0.0, 1.0, 0.0);
            spec.bumps = [
                bumps(rng, 5.0, spec.manoeuvre_start, [10.0, 30.0], [0.05, 0.15]),
                bumps(rng, spec.manoeuvre_start, duration, [4.0, 12.0], if hard { [0.2, 0.5] } else { [0.1, 0.3] }),
            ]
            .concat();
            spec.a_long = p.a_long;
            spec.a_lat = p.a_lat;
            Ok(spec)
        }
        _ => Err(format!("unknown scenario {name:?} (known: {})", SCENARIOS.join(", "))),
    }
}

/// Default duration of a scenario, s.
pub fn default_duration(name: &str) -> f64 {
    default_duration_of(name, false)
}

/// Default duration of a scenario and its `--hard` variant, s.
pub fn default_duration_of(name: &str, hard: bool) -> f64 {
    match name {
        "static" => 300.0,
        "chamber" => 1800.0,
        "urban" => 400.0,
        "smooth" if hard => super::smooth::HARD_FROM_S + 800.0,
        "smooth" | "crawl" => 600.0,
        _ => 800.0,
    }
}

/// The scenarios that drive on the road kinematics ([`super::road`]).
pub const ROAD_SCENARIOS: [&str; 3] = ["urban", "smooth", "crawl"];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_negative_half_width_a_reversed_range_or_a_far_lever_arm_is_refused() {
        for (bad, key) in [
            ("turn_on_bias = -1", "turn_on_bias"),
            ("scale_factor = nan", "scale_factor"),
            ("ambient = [30.0, 5.0]", "ambient"),
            ("lever_arm = [1e9, 0.0, 0.0]", "lever_arm"),
        ] {
            let e = Ranges::with_overrides("urban", bad).unwrap_err();
            assert!(e.contains(key), "{bad}: {e}");
        }
        assert!(Ranges::with_overrides("urban", "turn_on_bias = 0.5\nambient = [5.0, 5.0]").is_ok());
        for sc in SCENARIOS {
            assert!(Ranges::for_scenario(sc).check().is_ok(), "{sc}");
        }
    }

    #[test]
    fn a_ride_scale_outside_a_cars_range_is_refused() {
        for bad in ["[-5.0, 1.0]", "[0.0, 1e300]", "[0.5, 0.2]", "[0.0, nan]"] {
            let e = Ranges::with_overrides("smooth", &format!("ride_scale = {bad}")).unwrap_err();
            assert!(e.contains("ride_scale") && e.contains("0 <= low <= high <= 3"), "{bad}: {e}");
        }
        let r = Ranges::with_overrides("smooth", "ride_scale = [0.0, 3.0]").unwrap();
        assert_eq!(r.ride_scale, [0.0, 3.0]);
        assert_eq!(Ranges::with_overrides("urban", "").unwrap().ride_scale, [1.0, 1.0]);
    }
}
