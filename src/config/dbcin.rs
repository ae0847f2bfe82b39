//! `[input] format = "dbc"`: the keys that describe an IMU by its DBC file
//! (`[input.signals]`, `[input.units]`, `[input.sample]`, `[input.valid]`,
//! `dbc`, `source_address`), and their checks that need no file. The DBC
//! itself is read, and the mapping resolved against it, by
//! [`crate::dbcin::DbcPlan`] when the config is loaded.

use serde::de::Error as _;
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::collections::BTreeMap;
use std::sync::Arc;

/// Which frame contract `[input]` reads.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum InputFormat {
    /// The ADIS-style four frames with DATA_CNT and CHECKSUM (today's contract).
    #[default]
    Adis,
    /// Any IMU whose frames a DBC file describes.
    Dbc,
}

impl InputFormat {
    pub fn is_adis(&self) -> bool {
        *self == InputFormat::Adis
    }
}

/// One mapped signal: `"MESSAGE.SIGNAL"` (a leading `-` flips its sign), or
/// a magnitude with a separate sign bit (the bit set meaning negative).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SignalRef {
    Name(String),
    SignMagnitude { signal: String, sign_bit: String },
}

impl SignalRef {
    /// The signal names it refers to (the magnitude first).
    pub fn names(&self) -> Vec<&str> {
        match self {
            SignalRef::Name(n) => vec![n.as_str()],
            SignalRef::SignMagnitude { signal, sign_bit } => vec![signal.as_str(), sign_bit.as_str()],
        }
    }
}

impl Serialize for SignalRef {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            SignalRef::Name(n) => s.serialize_str(n),
            SignalRef::SignMagnitude { signal, sign_bit } => {
                let mut m = BTreeMap::new();
                m.insert("sign_bit", sign_bit);
                m.insert("signal", signal);
                m.serialize(s)
            }
        }
    }
}

impl<'de> Deserialize<'de> for SignalRef {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        const WANT: &str = "expected \"MESSAGE.SIGNAL\" or { signal = \"MESSAGE.SIGNAL\", sign_bit = \"MESSAGE.SIGNAL\" }";
        match toml::Value::deserialize(d)? {
            toml::Value::String(s) => Ok(SignalRef::Name(s)),
            toml::Value::Table(t) => {
                if let Some(k) = t.keys().find(|k| *k != "signal" && *k != "sign_bit") {
                    return Err(D::Error::custom(format!("unknown key {k:?}: {WANT}")));
                }
                let get = |k: &str| match t.get(k) {
                    Some(toml::Value::String(s)) => Ok(s.clone()),
                    _ => Err(D::Error::custom(format!("missing or non-text {k}: {WANT}"))),
                };
                Ok(SignalRef::SignMagnitude { signal: get("signal")?, sign_bit: get("sign_bit")? })
            }
            other => Err(D::Error::custom(format!("got {}: {WANT}", other.type_str()))),
        }
    }
}

/// `[input.signals]`: the physical channel each signal carries. An absent
/// axis is not measured.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SignalsConfig {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gyro_x: Option<SignalRef>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gyro_y: Option<SignalRef>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gyro_z: Option<SignalRef>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub accel_x: Option<SignalRef>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub accel_y: Option<SignalRef>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub accel_z: Option<SignalRef>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub temp: Option<SignalRef>,
}

/// The channels' keys, in [`SignalsConfig::channels`] order.
pub const CHANNELS: [&str; 7] = ["gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z", "temp"];

impl SignalsConfig {
    /// The seven channels, in [`CHANNELS`] order.
    pub fn channels(&self) -> [Option<&SignalRef>; 7] {
        [&self.gyro_x, &self.gyro_y, &self.gyro_z, &self.accel_x, &self.accel_y, &self.accel_z, &self.temp].map(Option::as_ref)
    }
    pub fn is_empty(&self) -> bool {
        self.channels().iter().all(Option::is_none)
    }
}

/// `[input.units]`: the unit of each kind where the DBC's is missing or wrong.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct UnitsConfig {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gyro: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub accel: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub temp: Option<String>,
}

impl UnitsConfig {
    pub fn is_empty(&self) -> bool {
        self.gyro.is_none() && self.accel.is_none() && self.temp.is_none()
    }
}

/// `[input.sample]`: how frames become one sample.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SampleConfig {
    /// One counter signal per message: a sample is the frames whose counters are equal.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub counter: Vec<String>,
    /// Or: a sample is one frame of each message within this window, ms.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub window_ms: Option<f64>,
}

impl SampleConfig {
    pub fn is_empty(&self) -> bool {
        self.counter.is_empty() && self.window_ms.is_none()
    }
}

/// The decode plan built from the DBC at load time (not a key: never
/// parsed or printed). Equality ignores it: it follows from the keys and
/// the file.
#[derive(Clone, Debug, Default)]
pub struct PlanSlot(pub Option<Arc<crate::dbcin::DbcPlan>>);

impl PartialEq for PlanSlot {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

/// Range of `[input.sample] window_ms`, ms: a tenth of a millisecond (an
/// 8 kHz part's frames) to a second (the slowest sample worth estimating on).
pub const WINDOW_MS: (f64, f64) = (0.1, 1000.0);

/// Units accepted for each kind: (kind, names, factor to gyrocomp's unit, offset).
pub fn unit_factor(kind: Kind, unit: &str) -> Option<(f64, f64)> {
    let u: String = unit.trim().chars().filter(|c| !c.is_whitespace()).collect::<String>().to_ascii_lowercase();
    match kind {
        Kind::Gyro => match u.as_str() {
            "deg/s" | "°/s" | "dps" | "deg/sec" => Some((1.0, 0.0)),
            "rad/s" | "rad/sec" => Some((180.0 / std::f64::consts::PI, 0.0)),
            _ => None,
        },
        Kind::Accel => match u.as_str() {
            "g" => Some((1.0, 0.0)),
            "m/s^2" | "m/s2" | "m/s²" | "mps2" => Some((1.0 / crate::dbcin::G0, 0.0)),
            _ => None,
        },
        Kind::Temp => match u.as_str() {
            "degc" | "°c" | "c" | "deg_c" => Some((1.0, 0.0)),
            "k" => Some((1.0, -273.15)),
            _ => None,
        },
    }
}

/// The kind of a channel (what its unit must measure).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    Gyro,
    Accel,
    Temp,
}

impl Kind {
    pub fn of_channel(k: usize) -> Kind {
        match k {
            0..=2 => Kind::Gyro,
            3..=5 => Kind::Accel,
            _ => Kind::Temp,
        }
    }
    pub fn key(self) -> &'static str {
        match self {
            Kind::Gyro => "gyro",
            Kind::Accel => "accel",
            Kind::Temp => "temp",
        }
    }
    pub fn known(self) -> &'static str {
        match self {
            Kind::Gyro => "deg/s, rad/s",
            Kind::Accel => "g, m/s^2",
            Kind::Temp => "degC, K",
        }
    }
}

/// `"MESSAGE.SIGNAL"` (after any leading `-`) split, or why it is not one.
pub fn split_ref(s: &str) -> Result<(&str, &str), String> {
    match s.split_once('.') {
        Some((m, sig)) if !m.is_empty() && !sig.is_empty() && !sig.contains('.') && !m.starts_with('-') => Ok((m, sig)),
        _ => Err(format!("{s:?} is not \"MESSAGE.SIGNAL\"")),
    }
}

/// Deserialize helper for `[input.valid]`: a table of "MESSAGE.SIGNAL" = whole number.
pub type ValidMap = BTreeMap<String, i64>;
