//! The sensor error model: what a MEMS IMU reports given the truth.
//!
//! This is the file contract `sensor.toml` (written by `gyrocomp simulate`,
//! read by `gyrocomp simulate --model`, used by the model-gap workflow):
//!
//! ```toml
//! [gyro]
//! effects = ["turn_on_bias", "thermal_linear", "warmup_transient"]
//! [gyro.turn_on_bias]
//! bias = [0.12, -0.31, 0.05]
//! [gyro.thermal_linear]
//! t0 = 25.0
//! p1 = [0.002, 0.0044, 0.0192]
//! [gyro.warmup_transient]
//! amplitude = [0.02, -0.01, 0.03]
//! tau_s = 60.0
//! [accel]  # optional
//! [magn]   # optional
//! [noise]  # optional
//! [vibration]  # optional
//! ```
//!
//! Only the effects named in `[gyro] effects` act; a `[gyro.<effect>]` table
//! for an effect not listed is kept (so an effect can be switched off by
//! removing its name) but has no influence. A listed effect without its
//! table is an error. Every table refuses unknown keys.
//!
//! The deterministic part of the gyro model is the pure function
//! [`GyroModel::measure`]: (truth at t, temperature, dT/dt, time since
//! power-on) -> measured rate. The stochastic parts (white rate noise, bias
//! random walk) and quantisation are applied by the simulator on top of it,
//! from `[noise]` and the part profile.
//!
//! Axis convention: body FRD, per-axis vectors are `[x, y, z]`; rates deg/s,
//! specific force g, temperature deg C, time s.

use serde::{Deserialize, Serialize};

/// One gyro error effect (the vocabulary of the model file).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Effect {
    TurnOnBias,
    ThermalLinear,
    ThermalQuadratic,
    ThermalRate,
    WarmupTransient,
    GSensitivity,
    ScaleFactor,
    Misalignment,
    TimeDelay,
}

impl Effect {
    pub const ALL: [Effect; 9] = [
        Effect::TurnOnBias,
        Effect::ThermalLinear,
        Effect::ThermalQuadratic,
        Effect::ThermalRate,
        Effect::WarmupTransient,
        Effect::GSensitivity,
        Effect::ScaleFactor,
        Effect::Misalignment,
        Effect::TimeDelay,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Effect::TurnOnBias => "turn_on_bias",
            Effect::ThermalLinear => "thermal_linear",
            Effect::ThermalQuadratic => "thermal_quadratic",
            Effect::ThermalRate => "thermal_rate",
            Effect::WarmupTransient => "warmup_transient",
            Effect::GSensitivity => "g_sensitivity",
            Effect::ScaleFactor => "scale_factor",
            Effect::Misalignment => "misalignment",
            Effect::TimeDelay => "time_delay",
        }
    }

    pub fn parse(s: &str) -> Option<Effect> {
        Effect::ALL.iter().copied().find(|e| e.name() == s)
    }
}

/// `turn_on_bias`: a constant bias drawn anew at every power-on.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TurnOnBias {
    /// Per axis `[x, y, z]`, deg/s.
    #[serde(deserialize_with = "crate::config::arrays::exactly")]
    pub bias: [f64; 3],
}

/// `thermal_linear`: `b = p1 (T - t0)` (paper eq. 20 without its offset,
/// which is part of the turn-on bias).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ThermalLinear {
    /// Reference temperature, deg C.
    pub t0: f64,
    /// Per axis `[x, y, z]`, deg/s per deg C.
    #[serde(deserialize_with = "crate::config::arrays::exactly")]
    pub p1: [f64; 3],
}

/// `thermal_quadratic`: `b = p2 (T - t0)^2`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ThermalQuadratic {
    /// Reference temperature, deg C.
    pub t0: f64,
    /// Per axis `[x, y, z]`, deg/s per deg C^2.
    #[serde(deserialize_with = "crate::config::arrays::exactly")]
    pub p2: [f64; 3],
}

/// `thermal_rate`: `b = k dT/dt` (thermal gradients inside the part while it heats).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ThermalRate {
    /// Per axis `[x, y, z]`, deg/s per (deg C/s).
    #[serde(deserialize_with = "crate::config::arrays::exactly")]
    pub k: [f64; 3],
}

/// `warmup_transient`: `b = amplitude exp(-t_on / tau_s)` after power-on.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WarmupTransient {
    /// Per axis `[x, y, z]`, deg/s at power-on.
    #[serde(deserialize_with = "crate::config::arrays::exactly")]
    pub amplitude: [f64; 3],
    /// Time constant, s (> 0).
    pub tau_s: f64,
}

/// `g_sensitivity`: `b = G f`, f the specific force in g.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GSensitivity {
    /// 3x3 matrix, rows = gyro axis, columns = specific-force axis, deg/s per g.
    #[serde(deserialize_with = "crate::config::arrays::exactly_3x3")]
    pub g: [[f64; 3]; 3],
}

/// `scale_factor`: `e_i = k_i w_i` (the same axis).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScaleFactor {
    /// Per axis `[x, y, z]`, dimensionless (0.001 = 1000 ppm).
    #[serde(deserialize_with = "crate::config::arrays::exactly")]
    pub k: [f64; 3],
}

/// `misalignment`: `e_i = sum_{j != i} m_ij w_j` (the other axes).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Misalignment {
    /// 3x3 matrix, rows = gyro axis, columns = true-rate axis, rad (small
    /// angles, dimensionless); the diagonal must be 0.
    #[serde(deserialize_with = "crate::config::arrays::exactly_3x3")]
    pub m: [[f64; 3]; 3],
}

/// `time_delay`: the measured rate lags the truth by `delay_s`; evaluated to
/// first order as `w(t - d) = w(t) - d dw/dt` (valid for d much shorter than
/// the motion's time scales, i.e. milliseconds).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimeDelay {
    /// Delay, s (>= 0).
    pub delay_s: f64,
}

/// `[gyro]`: the deterministic gyro error model.
#[derive(Clone, Debug, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GyroModel {
    /// The effects that act, by name.
    pub effects: Vec<Effect>,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub turn_on_bias: Option<TurnOnBias>,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub thermal_linear: Option<ThermalLinear>,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub thermal_quadratic: Option<ThermalQuadratic>,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub thermal_rate: Option<ThermalRate>,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub warmup_transient: Option<WarmupTransient>,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub g_sensitivity: Option<GSensitivity>,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub scale_factor: Option<ScaleFactor>,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub misalignment: Option<Misalignment>,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub time_delay: Option<TimeDelay>,
}

/// Truth and environment at one instant, what the gyro model needs.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct GyroInput {
    /// True body rate `[p, q, r]`, deg/s.
    pub rate: [f64; 3],
    /// Its time derivative, deg/s^2 (only `time_delay` uses it).
    pub rate_dot: [f64; 3],
    /// True specific force, g, body FRD.
    pub f: [f64; 3],
    /// Sensor temperature, deg C.
    pub temp: f64,
    /// dT/dt, deg C/s.
    pub temp_rate: f64,
    /// Time since power-on, s.
    pub t_on: f64,
}

/// Physical ranges of the model's numbers, wide around what MEMS parts
/// show (the ADIS16448: turn-on bias 3 deg/s 1-sigma, thermal slope about
/// 0.01 deg/s/K, g-sensitivity 0.01 deg/s/g); beyond them a model is a typo,
/// and the simulator would saturate every register or overflow.
pub const BIAS_MAX: f64 = 100.0;
/// Temperatures a part works at, deg C (automotive -40..125 with margin).
pub const TEMP_RANGE: (f64, f64) = (-60.0, 150.0);
/// Thermal slope, deg/s/K.
pub const P1_MAX: f64 = 1.0;
/// Thermal curvature, deg/s/K^2.
pub const P2_MAX: f64 = 0.1;
/// Bias per temperature rate, deg/s per K/s.
pub const THERMAL_RATE_MAX: f64 = 100.0;
/// Warm-up time constants, s.
pub const TAU_MIN_S: f64 = 0.01;
pub const TAU_MAX_S: f64 = 36000.0;
/// g-sensitivity, deg/s/g.
pub const G_SENS_MAX: f64 = 10.0;
/// Scale-factor error (fraction) and misalignment (rad).
pub const SCALE_MAX: f64 = 0.5;
/// Time delay, s.
pub const DELAY_MAX_S: f64 = 1.0;

/// Every value of `v` finite and within `lo..=hi` (`unit` for the message).
fn within(key: &str, v: &[f64], lo: f64, hi: f64, unit: &str) -> Result<(), (String, String)> {
    match v.iter().find(|x| !(x.is_finite() && (lo..=hi).contains(*x))) {
        None => Ok(()),
        Some(x) => Err((key.to_string(), format!("must be within {lo}..{hi} {unit}, got {}", crate::config::num(*x)))),
    }
}

impl GyroModel {
    pub fn has(&self, e: Effect) -> bool {
        self.effects.contains(&e)
    }

    /// Check that every listed effect has its coefficients and that they are
    /// inside their physical ranges (the `*_MAX` constants: a MEMS gyro's
    /// errors with a wide margin, so a typo of 1e300 never reaches the
    /// simulator); returns (key, message) naming the offending key.
    pub fn validate(&self) -> Result<(), (String, String)> {
        for (i, e) in self.effects.iter().enumerate() {
            if self.effects[..i].contains(e) {
                return Err(("gyro.effects".into(), format!("{} is listed twice", e.name())));
            }
            let key = format!("gyro.{}", e.name());
            let k = |field: &str| format!("{key}.{field}");
            let missing = || Err((key.clone(), format!("{} is listed in gyro.effects but [{}] is missing", e.name(), key)));
            match e {
                Effect::TurnOnBias => match &self.turn_on_bias {
                    Some(c) => within(&k("bias"), &c.bias, -BIAS_MAX, BIAS_MAX, "deg/s")?,
                    None => return missing(),
                },
                Effect::ThermalLinear => match &self.thermal_linear {
                    Some(c) => {
                        within(&k("t0"), &[c.t0], TEMP_RANGE.0, TEMP_RANGE.1, "deg C")?;
                        within(&k("p1"), &c.p1, -P1_MAX, P1_MAX, "deg/s/K")?
                    }
                    None => return missing(),
                },
                Effect::ThermalQuadratic => match &self.thermal_quadratic {
                    Some(c) => {
                        within(&k("t0"), &[c.t0], TEMP_RANGE.0, TEMP_RANGE.1, "deg C")?;
                        within(&k("p2"), &c.p2, -P2_MAX, P2_MAX, "deg/s/K^2")?
                    }
                    None => return missing(),
                },
                Effect::ThermalRate => match &self.thermal_rate {
                    Some(c) => within(&k("k"), &c.k, -THERMAL_RATE_MAX, THERMAL_RATE_MAX, "deg/s per K/s")?,
                    None => return missing(),
                },
                Effect::WarmupTransient => match &self.warmup_transient {
                    Some(c) => {
                        within(&k("amplitude"), &c.amplitude, -BIAS_MAX, BIAS_MAX, "deg/s")?;
                        within(&k("tau_s"), &[c.tau_s], TAU_MIN_S, TAU_MAX_S, "s")?;
                    }
                    None => return missing(),
                },
                Effect::GSensitivity => match &self.g_sensitivity {
                    Some(c) => within(&k("g"), c.g.as_flattened(), -G_SENS_MAX, G_SENS_MAX, "deg/s/g")?,
                    None => return missing(),
                },
                Effect::ScaleFactor => match &self.scale_factor {
                    Some(c) => within(&k("k"), &c.k, -SCALE_MAX, SCALE_MAX, "(fraction)")?,
                    None => return missing(),
                },
                Effect::Misalignment => match &self.misalignment {
                    Some(c) => {
                        within(&k("m"), c.m.as_flattened(), -SCALE_MAX, SCALE_MAX, "rad")?;
                        if (0..3).any(|i| c.m[i][i] != 0.0) {
                            return Err((k("m"), "the diagonal must be 0 (that is scale_factor)".into()));
                        }
                    }
                    None => return missing(),
                },
                Effect::TimeDelay => match &self.time_delay {
                    Some(c) => within(&k("delay_s"), &[c.delay_s], 0.0, DELAY_MAX_S, "s")?,
                    None => return missing(),
                },
            }
        }
        Ok(())
    }

    /// The additive bias (deg/s) of the listed effects that do not depend on
    /// the rate: turn-on, thermal (linear, quadratic, rate), warm-up, g-sensitivity.
    pub fn bias(&self, x: &GyroInput) -> [f64; 3] {
        let mut b = [0.0; 3];
        for e in &self.effects {
            match e {
                Effect::TurnOnBias => {
                    if let Some(c) = &self.turn_on_bias {
                        add(&mut b, &c.bias, 1.0);
                    }
                }
                Effect::ThermalLinear => {
                    if let Some(c) = &self.thermal_linear {
                        add(&mut b, &c.p1, x.temp - c.t0);
                    }
                }
                Effect::ThermalQuadratic => {
                    if let Some(c) = &self.thermal_quadratic {
                        let d = x.temp - c.t0;
                        add(&mut b, &c.p2, d * d);
                    }
                }
                Effect::ThermalRate => {
                    if let Some(c) = &self.thermal_rate {
                        add(&mut b, &c.k, x.temp_rate);
                    }
                }
                Effect::WarmupTransient => {
                    if let Some(c) = &self.warmup_transient {
                        add(&mut b, &c.amplitude, (-x.t_on.max(0.0) / c.tau_s).exp());
                    }
                }
                Effect::GSensitivity => {
                    if let Some(c) = &self.g_sensitivity {
                        for (i, bi) in b.iter_mut().enumerate() {
                            *bi += c.g[i][0] * x.f[0] + c.g[i][1] * x.f[1] + c.g[i][2] * x.f[2];
                        }
                    }
                }
                Effect::ScaleFactor | Effect::Misalignment | Effect::TimeDelay => {}
            }
        }
        b
    }

    /// The measured rate (deg/s) without noise or quantisation: the truth
    /// delayed, scaled, cross-coupled, plus the additive bias. Pure.
    pub fn measure(&self, x: &GyroInput) -> [f64; 3] {
        let mut w = x.rate;
        if let (true, Some(c)) = (self.has(Effect::TimeDelay), &self.time_delay) {
            for (k, wk) in w.iter_mut().enumerate() {
                *wk -= c.delay_s * x.rate_dot[k];
            }
        }
        let mut out = w;
        if let (true, Some(c)) = (self.has(Effect::ScaleFactor), &self.scale_factor) {
            for k in 0..3 {
                out[k] += c.k[k] * w[k];
            }
        }
        if let (true, Some(c)) = (self.has(Effect::Misalignment), &self.misalignment) {
            for i in 0..3 {
                for j in 0..3 {
                    if i != j {
                        out[i] += c.m[i][j] * w[j];
                    }
                }
            }
        }
        let b = self.bias(x);
        [out[0] + b[0], out[1] + b[1], out[2] + b[2]]
    }
}

#[inline]
fn add(b: &mut [f64; 3], v: &[f64; 3], s: f64) {
    for k in 0..3 {
        b[k] += v[k] * s;
    }
}

/// `[accel]`: accelerometer errors.
#[derive(Clone, Debug, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AccelModel {
    /// Per axis `[x, y, z]`, g.
    #[serde(deserialize_with = "crate::config::arrays::exactly")]
    pub bias: [f64; 3],
}

/// `[magn]`: the Earth field and the magnetometer errors.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MagnModel {
    /// Earth field in NED `[north, east, down]` of the magnetic frame, gauss.
    /// Magnetic north is true north in the simulator (declination 0).
    #[serde(deserialize_with = "crate::config::arrays::exactly")]
    pub field_ned: [f64; 3],
    /// Hard-iron bias per axis `[x, y, z]`, gauss.
    #[serde(deserialize_with = "crate::config::arrays::exactly")]
    pub bias: [f64; 3],
}

impl Default for MagnModel {
    fn default() -> Self {
        MagnModel { field_ned: [0.2, 0.0, 0.45], bias: [0.0; 3] }
    }
}

/// `[noise]`: stochastic terms. Densities are converted to a per-sample
/// standard deviation as `density * sqrt(rate_hz / 2)` (noise over the
/// Nyquist band of the output rate).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct NoiseModel {
    /// Gyro white rate noise density, deg/s/sqrt(Hz), all axes (ADIS16448: 0.0135).
    pub gyro_white: f64,
    /// Gyro bias random walk, deg/s/sqrt(s), all axes.
    pub gyro_bias_walk: f64,
    /// Accelerometer white noise density, g/sqrt(Hz).
    pub accel_white: f64,
    /// Magnetometer white noise, gauss per sample (1-sigma).
    pub magn_white: f64,
    /// Temperature sensor white noise, deg C per sample (1-sigma).
    pub temp_white: f64,
}

impl Default for NoiseModel {
    fn default() -> Self {
        NoiseModel { gyro_white: 0.0135, gyro_bias_walk: 0.0002, accel_white: 0.00023, magn_white: 0.0005, temp_white: 0.02 }
    }
}

impl NoiseModel {
    /// All stochastic terms off.
    pub fn none() -> Self {
        NoiseModel { gyro_white: 0.0, gyro_bias_walk: 0.0, accel_white: 0.0, magn_white: 0.0, temp_white: 0.0 }
    }
}

/// `[vibration]`: engine / road vibration, a linear oscillation of the
/// sensor mount (sub-mm). It is added to the specific force the sensor sees
/// (the accelerometer and the g-sensitivity input), not to `truth.csv`, whose
/// specific force is the vehicle's rigid-body motion. (The `urban` scenario's
/// speed-dependent road vibration is part of its truth instead, see
/// `road::RoadVibration`; this model is its engine idle vibration.)
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct VibrationModel {
    pub enabled: bool,
    /// Amplitude per axis `[x, y, z]` of each of the two tones, g.
    #[serde(deserialize_with = "crate::config::arrays::exactly")]
    pub amplitude: [f64; 3],
    /// Frequencies of the two tones, Hz (engine firing order and a harmonic).
    #[serde(deserialize_with = "crate::config::arrays::exactly")]
    pub freq_hz: [f64; 2],
}

impl Default for VibrationModel {
    fn default() -> Self {
        VibrationModel { enabled: false, amplitude: [0.0; 3], freq_hz: [27.0, 41.0] }
    }
}

/// The whole sensor model file (`sensor.toml`).
#[derive(Clone, Debug, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorModel {
    pub gyro: GyroModel,
    #[serde(default)]
    pub accel: AccelModel,
    #[serde(default)]
    pub magn: MagnModel,
    #[serde(default)]
    pub noise: NoiseModel,
    #[serde(default)]
    pub vibration: VibrationModel,
}

impl SensorModel {
    /// Parse and validate model text; errors name the key.
    pub fn parse(text: &str) -> Result<SensorModel, String> {
        let m: SensorModel = toml::from_str(text).map_err(|e| e.to_string())?;
        m.validate().map_err(|(k, msg)| where_written(text, &k, &msg))?;
        Ok(m)
    }

    pub fn load(path: &std::path::Path) -> Result<SensorModel, String> {
        let text = crate::textfile::read(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
        SensorModel::parse(&text).map_err(|e| format!("{}: {e}", path.display()))
    }

    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("a sensor model always serialises")
    }

    pub fn validate(&self) -> Result<(), (String, String)> {
        self.gyro.validate()?;
        let n = &self.noise;
        for (k, v, hi, unit) in [
            ("noise.gyro_white", n.gyro_white, 10.0, "deg/s/sqrt(Hz)"),
            ("noise.gyro_bias_walk", n.gyro_bias_walk, 1.0, "deg/s/sqrt(s)"),
            ("noise.accel_white", n.accel_white, 1.0, "g/sqrt(Hz)"),
            ("noise.magn_white", n.magn_white, 10.0, "gauss"),
            ("noise.temp_white", n.temp_white, 10.0, "deg C"),
        ] {
            within(k, &[v], 0.0, hi, unit)?;
        }
        within("accel.bias", &self.accel.bias, -2.0, 2.0, "g")?;
        within("magn.bias", &self.magn.bias, -10.0, 10.0, "gauss")?;
        within("magn.field_ned", &self.magn.field_ned, -2.0, 2.0, "gauss")?;
        within("vibration.amplitude", &self.vibration.amplitude, -20.0, 20.0, "g")?;
        within("vibration.freq_hz", &self.vibration.freq_hz, 0.01, 10000.0, "Hz")?;
        Ok(())
    }
}

/// `key: msg` with where `key` is written in `text` (line and column), or
/// that it is not written (its default is meant).
pub fn where_written(text: &str, key: &str, msg: &str) -> String {
    match crate::config::locate(text, key) {
        Some(at) => format!("line {}, column {}: {key}: {msg}", at.line, at.column),
        None => format!("{key} (not in the file: its default): {msg}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn full() -> GyroModel {
        GyroModel {
            effects: Effect::ALL.to_vec(),
            turn_on_bias: Some(TurnOnBias { bias: [0.1, -0.2, 0.3] }),
            thermal_linear: Some(ThermalLinear { t0: 25.0, p1: [0.002, 0.0044, 0.0192] }),
            thermal_quadratic: Some(ThermalQuadratic { t0: 25.0, p2: [1e-4, 0.0, -1e-4] }),
            thermal_rate: Some(ThermalRate { k: [0.5, 0.0, 0.0] }),
            warmup_transient: Some(WarmupTransient { amplitude: [0.05, 0.0, 0.0], tau_s: 10.0 }),
            g_sensitivity: Some(GSensitivity { g: [[0.0, 0.0, 0.01], [0.0; 3], [0.0; 3]] }),
            scale_factor: Some(ScaleFactor { k: [0.0, 0.01, 0.0] }),
            misalignment: Some(Misalignment { m: [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.02, 0.0, 0.0]] }),
            time_delay: Some(TimeDelay { delay_s: 0.01 }),
        }
    }

    #[test]
    fn each_effect_has_its_documented_shape() {
        let m = full();
        m.validate().unwrap();
        let x = GyroInput {
            rate: [10.0, 20.0, 0.0],
            rate_dot: [100.0, 0.0, 0.0],
            f: [0.0, 0.0, -1.0],
            temp: 35.0,
            temp_rate: 0.01,
            t_on: 10.0,
        };
        let y = m.measure(&x);
        // x: delay -> 10 - 0.01*100 = 9; bias 0.1 + 0.002*10 + 1e-4*100 + 0.5*0.01 + 0.05/e + 0.01*(-1)
        let bx = 0.1 + 0.02 + 0.01 + 0.005 + 0.05 * (-1.0f64).exp() - 0.01;
        assert!((y[0] - (9.0 + bx)).abs() < 1e-12, "{y:?}");
        // y: scale 1 %
        let by = -0.2 + 0.044;
        assert!((y[1] - (20.0 * 1.01 + by)).abs() < 1e-12);
        // z: misalignment from x (delayed rate 9)
        let bz = 0.3 + 0.192 - 0.01;
        assert!((y[2] - (0.02 * 9.0 + bz)).abs() < 1e-12);
    }

    #[test]
    fn unlisted_effects_do_not_act_and_listed_need_tables() {
        let mut m = full();
        m.effects = vec![Effect::TurnOnBias];
        let y = m.measure(&GyroInput { rate: [1.0, 2.0, 3.0], temp: 80.0, ..Default::default() });
        for (a, b) in y.iter().zip([1.1, 1.8, 3.3]) {
            assert!((a - b).abs() < 1e-12, "{y:?}");
        }
        m.effects.push(Effect::TimeDelay);
        m.time_delay = None;
        let e = m.validate().unwrap_err();
        assert_eq!(e.0, "gyro.time_delay");
    }

    #[test]
    fn model_file_round_trips_and_refuses_unknown_keys() {
        let s = SensorModel { gyro: full(), ..Default::default() };
        let text = s.to_toml();
        assert!(text.contains("[gyro.thermal_linear]"), "{text}");
        assert_eq!(SensorModel::parse(&text).unwrap(), s);
        let bad = "[gyro]\neffects = [\"turn_on_bias\"]\n[gyro.turn_on_bias]\nbias = [0,0,0]\nscale = 1\n";
        assert!(SensorModel::parse(bad).unwrap_err().contains("scale"));
        let bad = "[gyro]\neffects = [\"warp_drive\"]\n";
        assert!(SensorModel::parse(bad).is_err());
    }

    #[test]
    fn a_model_value_beyond_its_range_or_an_array_too_long_is_refused_with_its_line() {
        let e = SensorModel::parse("[gyro]\neffects = [\"turn_on_bias\"]\n[gyro.turn_on_bias]\nbias = [1e300, 0, 0]\n").unwrap_err();
        assert!(e.contains("line 4") && e.contains("gyro.turn_on_bias.bias") && e.contains("-100..100 deg/s"), "{e}");
        let e = SensorModel::parse("[gyro]\neffects = [\"turn_on_bias\"]\n[gyro.turn_on_bias]\nbias = [0.1, 0, 0, 45]\n").unwrap_err();
        assert!(e.contains("line 4") && e.contains("expected an array of 3 numbers, got 4"), "{e}");
        let e = SensorModel::parse("[gyro]\neffects = []\n[noise]\ngyro_white = 1e300\n").unwrap_err();
        assert!(e.contains("line 4") && e.contains("noise.gyro_white"), "{e}");
        SensorModel::parse("[gyro]\neffects = [\"turn_on_bias\"]\n[gyro.turn_on_bias]\nbias = [3.0, -4.5, 0.1]\n").unwrap();
    }
}
