//! Vehicle speed from the car's own CAN bus, described by the car's DBC
//! (`[speed]` of the config; documentation in `docs/speed.md`).
//!
//! [`SpeedDecoder::from_config`] loads the DBC with the `can-dbc` crate,
//! finds the configured message and signals by name and keeps, per signal,
//! what decoding needs: bit layout (Intel or Motorola byte order), signed or
//! unsigned, factor and offset, the DBC range and the unit's factor to m/s
//! (`km/h`, `kph`, `kmh`, `m/s`, `mps`, `mph`; any other unit is refused,
//! naming it). Load errors name the file and the message or signal.
//!
//! [`SpeedDecoder::decode`] turns one frame's payload into a speed in m/s:
//! the mean of the configured signals times `scale`. It allocates nothing.
//! A frame it cannot use is a [`SpeedDrop`], to be counted: a payload length
//! other than the message's DLC, a signal outside its DBC range `[min|max]`
//! (a range `[0|0]` means "none", as in the DBC convention), or a speed that
//! is physically implausible (|v| > [`MAX_PLAUSIBLE_MS`]).
//!
//! A message longer than 8 bytes (a classic CAN frame's most) is refused at
//! load time: frames of CAN FD are never taken as speed frames.
//!
//! Pure: no I/O besides reading the DBC file at load time, no tokio.

use crate::config::SpeedConfig;
use can_dbc::{ByteOrder, Dbc, MessageId, MultiplexIndicator, NumericValue, ValueType};
use std::path::Path;

/// Speeds beyond this magnitude (m/s, 360 km/h) are dropped as implausible.
pub const MAX_PLAUSIBLE_MS: f64 = 100.0;

/// Why a speed source cannot be used (start-up errors).
#[derive(Debug, thiserror::Error)]
pub enum SpeedError {
    #[error("[speed] is not configured (speed.dbc is empty)")]
    NotConfigured,
    #[error("speed.signals: name at least one signal of {message}")]
    NoSignals { message: String },
    #[error("speed.scale must be finite and > 0, got {0}")]
    BadScale(f64),
    #[error("{path}: cannot read the DBC: {source}")]
    Read {
        path: String,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: not a valid DBC: {msg}")]
    Parse { path: String, msg: String },
    #[error("{path}: no message named {message:?} (the DBC has: {known})")]
    NoMessage { path: String, message: String, known: String },
    #[error("{path}: message {message} has no signal named {signal:?} (it has: {known})")]
    NoSignal { path: String, message: String, signal: String, known: String },
    #[error("{path}: signal {message}.{signal}: unit {unit:?} is not a speed unit gyrocomp knows (km/h, kph, kmh, m/s, mps, mph)")]
    Unit { path: String, message: String, signal: String, unit: String },
    #[error("{path}: message {message} is {size} bytes long (its DLC); a classic CAN frame carries 0 to 8 and gyrocomp reads no CAN FD speed frames, so every frame would drop as wrong_dlc")]
    Length { path: String, message: String, size: u64 },
    #[error("{path}: signal {message}.{signal}: {why}")]
    Unsupported { path: String, message: String, signal: String, why: String },
}

/// Why one frame gave no speed (run-time, counted).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpeedDrop {
    /// The payload length is not the message's DLC.
    WrongDlc { got: usize, want: usize },
    /// A signal is outside its DBC range (`signal` indexes the configured signals).
    OutOfRange { signal: usize },
    /// |speed| above [`MAX_PLAUSIBLE_MS`].
    Implausible,
}

impl SpeedDrop {
    /// Short name of the cause (for counters and logs).
    pub fn name(&self) -> &'static str {
        match self {
            SpeedDrop::WrongDlc { .. } => "wrong_dlc",
            SpeedDrop::OutOfRange { .. } => "out_of_range",
            SpeedDrop::Implausible => "implausible",
        }
    }
}

/// Decoded frames and drops by cause.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SpeedCounts {
    pub decoded: u64,
    pub wrong_dlc: u64,
    pub out_of_range: u64,
    pub implausible: u64,
}

impl SpeedCounts {
    pub fn record(&mut self, r: &Result<f64, SpeedDrop>) {
        match r {
            Ok(_) => self.decoded += 1,
            Err(SpeedDrop::WrongDlc { .. }) => self.wrong_dlc += 1,
            Err(SpeedDrop::OutOfRange { .. }) => self.out_of_range += 1,
            Err(SpeedDrop::Implausible) => self.implausible += 1,
        }
    }

    pub fn dropped(&self) -> u64 {
        self.wrong_dlc + self.out_of_range + self.implausible
    }
}

/// Factor from a DBC unit string to m/s.
pub fn unit_to_ms(unit: &str) -> Option<f64> {
    let u: String = unit.trim().to_ascii_lowercase().chars().filter(|c| !c.is_whitespace()).collect();
    match u.as_str() {
        "km/h" | "kph" | "kmh" | "km/hr" => Some(1.0 / 3.6),
        "m/s" | "mps" => Some(1.0),
        "mph" | "mi/h" => Some(0.44704),
        _ => None,
    }
}

/// A parser's message as a terminal may show it: control characters
/// escaped, each line cut at 160 characters.
pub(crate) fn printable(msg: &str) -> String {
    msg.lines()
        .map(|l| {
            let esc: String = l
                .chars()
                .flat_map(|c| if c.is_control() && c != '\t' { c.escape_default().collect::<Vec<_>>() } else { vec![c] })
                .collect();
            match esc.char_indices().nth(160) {
                Some((k, _)) => format!("{} ...", &esc[..k]),
                None => esc,
            }
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// One signal, ready to decode.
#[derive(Clone, Debug, PartialEq)]
struct Sig {
    start: usize,
    size: usize,
    motorola: bool,
    signed: bool,
    factor: f64,
    offset: f64,
    /// DBC range, physical units (None when the DBC gives `[0|0]`).
    range: Option<(f64, f64)>,
    to_ms: f64,
}

impl Sig {
    /// Bit positions the signal occupies, most significant first for
    /// Motorola, least significant first for Intel (DBC numbering: byte i,
    /// bit j is `8 i + j`).
    fn positions(&self) -> impl Iterator<Item = Option<usize>> + '_ {
        let mut pos = Some(self.start);
        (0..self.size).map(move |_| {
            let here = pos;
            pos = match (here, self.motorola) {
                (Some(p), false) => Some(p + 1),
                (Some(p), true) if p % 8 == 0 => Some(p + 15),
                (Some(p), true) => Some(p - 1),
                (None, _) => None,
            };
            here
        })
    }

    #[inline]
    fn raw(&self, d: &[u8]) -> u64 {
        let bit = |p: usize| u64::from((d[p >> 3] >> (p & 7)) & 1);
        let mut v = 0u64;
        if self.motorola {
            let mut p = self.start;
            for _ in 0..self.size {
                v = (v << 1) | bit(p);
                p = if p & 7 == 0 { p + 15 } else { p - 1 };
            }
        } else {
            for k in 0..self.size {
                v |= bit(self.start + k) << k;
            }
        }
        v
    }

    #[inline]
    fn value(&self, d: &[u8]) -> f64 {
        let r = self.raw(d);
        let x = if self.signed && self.size < 64 && (r >> (self.size - 1)) & 1 == 1 {
            (r | (u64::MAX << self.size)) as i64 as f64
        } else if self.signed {
            r as i64 as f64
        } else {
            r as f64
        };
        x * self.factor + self.offset
    }

    fn in_range(&self, x: f64) -> bool {
        match self.range {
            None => true,
            Some((lo, hi)) => {
                let tol = 0.5 * self.factor.abs() + 1e-9 * x.abs();
                x >= lo - tol && x <= hi + tol
            }
        }
    }
}

/// Why gyrocomp cannot decode `s` of `msg` (multiplexed, or an IEEE float), if it cannot.
pub(crate) fn not_plain_integer(dbc: &Dbc, msg: &can_dbc::Message, s: &can_dbc::Signal) -> Option<&'static str> {
    if !matches!(s.multiplexer_indicator, MultiplexIndicator::Plain) {
        return Some("multiplexed signals are not supported");
    }
    let float = dbc.signal_extended_value_type_list.iter().any(|x| {
        x.message_id == msg.id
            && x.signal_name == s.name
            && !matches!(x.signal_extended_value_type, can_dbc::SignalExtendedValueType::SignedOrUnsignedInteger)
    });
    float.then_some("IEEE float signals (SIG_VALTYPE_) are not supported")
}

/// Decodes the configured speed message of a DBC.
#[derive(Clone, Debug, PartialEq)]
pub struct SpeedDecoder {
    id: u32,
    extended: bool,
    dlc: usize,
    message: String,
    names: Vec<String>,
    units: Vec<String>,
    sigs: Vec<Sig>,
    scale: f64,
}

/// A DBC number as f64.
pub(crate) fn num(v: &NumericValue) -> f64 {
    match *v {
        NumericValue::Uint(x) => x as f64,
        NumericValue::Int(x) => x as f64,
        NumericValue::Double(x) => x,
    }
}

impl SpeedDecoder {
    /// Load `cfg.dbc` (a path as given; the caller resolves relative paths).
    pub fn from_config(cfg: &SpeedConfig) -> Result<SpeedDecoder, SpeedError> {
        if !cfg.enabled() {
            return Err(SpeedError::NotConfigured);
        }
        SpeedDecoder::from_dbc(Path::new(&cfg.dbc), cfg)
    }

    /// Load the DBC at `path` (`cfg.dbc` is not used).
    pub fn from_dbc(path: &Path, cfg: &SpeedConfig) -> Result<SpeedDecoder, SpeedError> {
        let name = path.display().to_string();
        let text = read_dbc(path).map_err(|e| match e {
            DbcRead::Io(source) => SpeedError::Read { path: name.clone(), source },
            DbcRead::Text(msg) => SpeedError::Parse { path: name.clone(), msg },
        })?;
        SpeedDecoder::from_dbc_text(&text, &name, cfg)
    }

    /// Build from DBC text; `origin` names it in errors.
    pub fn from_dbc_text(text: &str, origin: &str, cfg: &SpeedConfig) -> Result<SpeedDecoder, SpeedError> {
        let path = origin.to_string();
        if !(cfg.scale.is_finite() && cfg.scale > 0.0) {
            return Err(SpeedError::BadScale(cfg.scale));
        }
        let dbc = Dbc::try_from(text).map_err(|e| SpeedError::Parse { path: path.clone(), msg: printable(&e.to_string()) })?;
        let msg = dbc.messages.iter().find(|m| m.name == cfg.message).ok_or_else(|| SpeedError::NoMessage {
            path: path.clone(),
            message: cfg.message.clone(),
            known: list(dbc.messages.iter().map(|m| m.name.as_str())),
        })?;
        if cfg.signals.is_empty() {
            return Err(SpeedError::NoSignals { message: msg.name.clone() });
        }
        let (id, extended) = match msg.id {
            MessageId::Standard(x) => (u32::from(x), false),
            MessageId::Extended(x) => (x, true),
        };
        // classic CAN only: the pipeline takes no FD frame as a speed frame
        if msg.size > 8 {
            return Err(SpeedError::Length { path: path.clone(), message: msg.name.clone(), size: msg.size });
        }
        let dlc = msg.size as usize;
        let mut sigs = Vec::with_capacity(cfg.signals.len());
        let mut units = Vec::with_capacity(cfg.signals.len());
        for want in &cfg.signals {
            let s = msg.signals.iter().find(|s| &s.name == want).ok_or_else(|| SpeedError::NoSignal {
                path: path.clone(),
                message: msg.name.clone(),
                signal: want.clone(),
                known: list(msg.signals.iter().map(|s| s.name.as_str())),
            })?;
            let unsupported =
                |why: String| SpeedError::Unsupported { path: path.clone(), message: msg.name.clone(), signal: s.name.clone(), why };
            if let Some(why) = not_plain_integer(&dbc, msg, s) {
                return Err(unsupported(why.into()));
            }
            if s.size == 0 || s.size > 64 {
                return Err(unsupported(format!("size {} bits (want 1..64)", s.size)));
            }
            if !(s.factor.is_finite() && s.factor != 0.0 && s.offset.is_finite()) {
                return Err(unsupported(format!("factor {} and offset {} must be finite, the factor non-zero", s.factor, s.offset)));
            }
            let to_ms = unit_to_ms(&s.unit).ok_or_else(|| SpeedError::Unit {
                path: path.clone(),
                message: msg.name.clone(),
                signal: s.name.clone(),
                unit: s.unit.clone(),
            })?;
            let (lo, hi) = (num(&s.min), num(&s.max));
            let sig = Sig {
                start: s.start_bit as usize,
                size: s.size as usize,
                motorola: s.byte_order == ByteOrder::BigEndian,
                signed: s.value_type == ValueType::Signed,
                factor: s.factor,
                offset: s.offset,
                range: (!(lo == 0.0 && hi == 0.0) && lo <= hi).then_some((lo, hi)),
                to_ms,
            };
            if let Some(bad) = sig.positions().find(|p| p.is_none_or(|p| p >= 8 * dlc)) {
                let at = bad.map(|p| format!("bit {p}")).unwrap_or_else(|| "a bit before bit 0".into());
                return Err(unsupported(format!("occupies {at}, outside the message's {dlc} bytes")));
            }
            sigs.push(sig);
            units.push(s.unit.clone());
        }
        Ok(SpeedDecoder { id, extended, dlc, message: msg.name.clone(), names: cfg.signals.clone(), units, sigs, scale: cfg.scale })
    }

    /// CAN ID of the message and whether it is an extended (29-bit) ID.
    pub fn id(&self) -> (u32, bool) {
        (self.id, self.extended)
    }

    /// Payload length the message has.
    pub fn dlc(&self) -> usize {
        self.dlc
    }

    pub fn message(&self) -> &str {
        &self.message
    }

    /// The configured signals and their DBC units.
    pub fn signals(&self) -> impl Iterator<Item = (&str, &str)> {
        self.names.iter().map(String::as_str).zip(self.units.iter().map(String::as_str))
    }

    /// One signal's physical value in its DBC unit (no range check), for
    /// diagnostics and tests; `None` for a wrong length or index.
    pub fn signal_value(&self, k: usize, data: &[u8]) -> Option<f64> {
        (data.len() == self.dlc).then(|| self.sigs.get(k).map(|s| s.value(data))).flatten()
    }

    /// The speed a frame's payload carries, m/s (mean of the configured
    /// signals, times `scale`), or why it carries none.
    pub fn decode(&self, data: &[u8]) -> Result<f64, SpeedDrop> {
        if data.len() != self.dlc {
            return Err(SpeedDrop::WrongDlc { got: data.len(), want: self.dlc });
        }
        let mut sum = 0.0;
        for (k, s) in self.sigs.iter().enumerate() {
            let x = s.value(data);
            if !s.in_range(x) {
                return Err(SpeedDrop::OutOfRange { signal: k });
            }
            sum += x * s.to_ms;
        }
        let v = sum / self.sigs.len() as f64 * self.scale;
        if v.is_nan() || v.abs() > MAX_PLAUSIBLE_MS {
            return Err(SpeedDrop::Implausible);
        }
        Ok(v)
    }
}

/// Why a DBC file could not be read as text.
#[derive(Debug)]
pub(crate) enum DbcRead {
    Io(std::io::Error),
    Text(String),
}

/// A DBC file's text: UTF-8, or Windows-1252 as DBC editors write it; a
/// binary file is refused with where its first control byte is.
pub(crate) fn read_dbc(path: &Path) -> Result<String, DbcRead> {
    let bytes = std::fs::read(path).map_err(DbcRead::Io)?;
    if let Some(at) = bytes.iter().position(|b| b.is_ascii_control() && !b"\t\n\r\x0c".contains(b)) {
        let line = bytes[..at].iter().filter(|b| **b == b'\n').count() + 1;
        return Err(DbcRead::Text(format!("a binary file, not DBC text (control byte {:#04x} at line {line}, byte {at})", bytes[at])));
    }
    match String::from_utf8(bytes) {
        Ok(t) => Ok(t),
        Err(e) => can_dbc::decode_cp1252(e.as_bytes())
            .map(|c| c.into_owned())
            .ok_or_else(|| DbcRead::Text("neither UTF-8 nor Windows-1252 text".into())),
    }
}

/// The decoder of a config's `[speed]` (None when it is not configured).
/// `speed.dbc` is used as it stands: `Config::load` has made it absolute
/// (relative to the config file's directory).
pub fn load(cfg: &crate::config::Config) -> Result<Option<SpeedDecoder>, SpeedError> {
    if !cfg.speed.enabled() {
        return Ok(None);
    }
    SpeedDecoder::from_config(&cfg.speed).map(Some)
}

fn list<'a>(names: impl Iterator<Item = &'a str>) -> String {
    let v: Vec<&str> = names.collect();
    if v.is_empty() {
        "nothing".into()
    } else {
        v.join(", ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg(message: &str, signals: &[&str]) -> SpeedConfig {
        SpeedConfig {
            dbc: "x.dbc".into(),
            message: message.into(),
            signals: signals.iter().map(|s| s.to_string()).collect(),
            scale: 1.0,
            timeout_s: 0.5,
        }
    }

    const DBC: &str = r#"VERSION ""

NS_ :

BS_:

BU_: X

BO_ 170 TOYOTA: 8 X
 SG_ FR : 7|16@0+ (0.01,-67.67) [0|250] "km/h" X
 SG_ RL : 55|16@0+ (0.01,-67.67) [0|250] "km/h" X

BO_ 416 SIGNED: 8 X
 SG_ A : 0|16@1- (0.01,0) [-60|300] "km/h" X
 SG_ B : 48|16@1- (0.01,0) [-60|300] "kph" X
 SG_ M : 12|12@0- (0.5,0) [0|0] "m/s" X
 SG_ U : 40|3@1+ (1,0) [0|0] "mph" X
 SG_ W : 60|8@1+ (1,0) [0|0] "furlong/fortnight" X

BO_ 2147484000 EXT: 2 X
 SG_ V : 0|16@1+ (0.001,0) [0|0] "m/s" X
"#;

    fn dec(message: &str, signals: &[&str]) -> SpeedDecoder {
        SpeedDecoder::from_dbc_text(DBC, "t.dbc", &cfg(message, signals)).unwrap()
    }

    #[test]
    fn motorola_unsigned_with_offset() {
        let d = dec("TOYOTA", &["FR", "RL"]);
        assert_eq!(d.id(), (170, false));
        // FR: big-endian u16 in bytes 0-1; RL in bytes 6-7. raw 10000 -> 32.33 km/h
        let mut p = [0u8; 8];
        p[0..2].copy_from_slice(&10000u16.to_be_bytes());
        p[6..8].copy_from_slice(&12000u16.to_be_bytes());
        let v = d.decode(&p).unwrap();
        let want = (0.5 * ((100.0 - 67.67) + (120.0 - 67.67))) / 3.6;
        assert!((v - want).abs() < 1e-12, "{v} vs {want}");
        // raw 0 = -67.67 km/h: outside [0|250]
        p[0..2].copy_from_slice(&0u16.to_be_bytes());
        assert_eq!(d.decode(&p), Err(SpeedDrop::OutOfRange { signal: 0 }));
    }

    #[test]
    fn intel_signed_and_units() {
        let d = dec("SIGNED", &["A", "B"]);
        let mut p = [0u8; 8];
        p[0..2].copy_from_slice(&(-1234i16).to_le_bytes());
        p[6..8].copy_from_slice(&(-1266i16).to_le_bytes());
        let v = d.decode(&p).unwrap();
        assert!((v - (-12.5 / 3.6)).abs() < 1e-12, "{v}");
        // -70 km/h is below the range [-60|300]
        p[0..2].copy_from_slice(&(-7000i16).to_le_bytes());
        assert_eq!(d.decode(&p), Err(SpeedDrop::OutOfRange { signal: 0 }));
        // exactly at the range edge is in range
        p[0..2].copy_from_slice(&(-6000i16).to_le_bytes());
        assert!(d.decode(&p).is_ok());
    }

    #[test]
    fn motorola_signed_across_bytes_and_short_unsigned() {
        // M: start bit 12 (byte 1, bit 4) MSB first, 12 bits: byte1 bits 4..0, byte2 bits 7..1
        let d = dec("SIGNED", &["M"]);
        let mut p = [0u8; 8];
        // raw = -3 (12-bit two's complement 0xFFD): bits 1111 1111 1101
        // byte 1 bits 4..0 take the 5 MSBs 11111, byte 2 bits 7..1 take 1111101
        p[1] = 0b0001_1111;
        p[2] = 0b1111_1010;
        assert!((d.decode(&p).unwrap() - (-1.5)).abs() < 1e-12);
        assert_eq!(d.signal_value(0, &p), Some(-1.5));
        let u = dec("SIGNED", &["U"]);
        let mut p = [0u8; 8];
        p[5] = 0b0000_0101; // bits 40..42 = 5
        assert!((u.decode(&p).unwrap() - 5.0 * 0.44704).abs() < 1e-12);
    }

    #[test]
    fn extended_id_and_wrong_dlc() {
        let d = dec("EXT", &["V"]);
        assert_eq!(d.id(), (0x160, true));
        assert_eq!(d.dlc(), 2);
        assert_eq!(d.decode(&[0x10, 0x27]), Ok(10.0));
        assert_eq!(d.decode(&[0x10, 0x27, 0]), Err(SpeedDrop::WrongDlc { got: 3, want: 2 }));
        assert_eq!(d.decode(&[]), Err(SpeedDrop::WrongDlc { got: 0, want: 2 }));
        // 65.535 m/s is plausible; with a scale of 2 it is not
        let mut c = cfg("EXT", &["V"]);
        c.scale = 2.0;
        let d2 = SpeedDecoder::from_dbc_text(DBC, "t.dbc", &c).unwrap();
        assert_eq!(d2.decode(&[0xFF, 0xFF]), Err(SpeedDrop::Implausible));
        let mut n = SpeedCounts::default();
        for r in [d.decode(&[0x10, 0x27]), d.decode(&[1]), d2.decode(&[0xFF, 0xFF])] {
            n.record(&r);
        }
        assert_eq!(n, SpeedCounts { decoded: 1, wrong_dlc: 1, out_of_range: 0, implausible: 1 });
    }

    #[test]
    fn load_errors_name_the_file_and_the_name() {
        let e = SpeedDecoder::from_dbc_text(DBC, "t.dbc", &cfg("NOPE", &["A"])).unwrap_err().to_string();
        assert!(e.contains("t.dbc") && e.contains("\"NOPE\"") && e.contains("TOYOTA"), "{e}");
        let e = SpeedDecoder::from_dbc_text(DBC, "t.dbc", &cfg("SIGNED", &["A", "Z"])).unwrap_err().to_string();
        assert!(e.contains("t.dbc") && e.contains("SIGNED") && e.contains("\"Z\""), "{e}");
        let e = SpeedDecoder::from_dbc_text(DBC, "t.dbc", &cfg("SIGNED", &["W"])).unwrap_err().to_string();
        assert!(e.contains("SIGNED.W") && e.contains("furlong/fortnight"), "{e}");
        let e = SpeedDecoder::from_dbc_text("BO_ 1 X: 8 Y\n SG_ garbage", "bad.dbc", &cfg("X", &["A"])).unwrap_err().to_string();
        assert!(e.contains("bad.dbc") && e.contains("not a valid DBC"), "{e}");
        let e = SpeedDecoder::from_dbc_text(DBC, "t.dbc", &cfg("SIGNED", &[])).unwrap_err().to_string();
        assert!(e.contains("speed.signals"), "{e}");
        let e = SpeedDecoder::from_config(&SpeedConfig::default()).unwrap_err().to_string();
        assert!(e.contains("not configured"), "{e}");
    }

    #[test]
    fn a_signal_outside_its_message_is_refused() {
        let text = "VERSION \"\"\n\nNS_ :\n\nBS_:\n\nBU_: X\n\nBO_ 5 SHORT: 2 X\n SG_ S : 8|16@1+ (1,0) [0|0] \"m/s\" X\n";
        let e = SpeedDecoder::from_dbc_text(text, "s.dbc", &cfg("SHORT", &["S"])).unwrap_err().to_string();
        assert!(e.contains("SHORT.S") && e.contains("bit 16") && e.contains("2 bytes"), "{e}");
        // Motorola running off the end of the last byte
        let text = text.replace("8|16@1+", "15|16@0+");
        let e = SpeedDecoder::from_dbc_text(&text, "s.dbc", &cfg("SHORT", &["S"])).unwrap_err().to_string();
        assert!(e.contains("outside the message"), "{e}");
    }

    #[test]
    fn a_message_longer_than_a_classic_can_frame_is_refused() {
        let text = "VERSION \"\"\n\nNS_ :\n\nBS_:\n\nBU_: X\n\nBO_ 5 LONG: 99 X\n SG_ S : 0|16@1+ (1,0) [0|0] \"m/s\" X\n";
        let e = SpeedDecoder::from_dbc_text(text, "l.dbc", &cfg("LONG", &["S"])).unwrap_err().to_string();
        assert!(e.contains("l.dbc") && e.contains("message LONG") && e.contains("99 bytes") && e.contains("0 to 8"), "{e}");
        let d = SpeedDecoder::from_dbc_text(&text.replace(": 99 X", ": 8 X"), "l.dbc", &cfg("LONG", &["S"])).unwrap();
        assert_eq!(d.dlc(), 8);
    }

    #[test]
    fn units() {
        for (u, f) in [("km/h", 1.0 / 3.6), ("KPH", 1.0 / 3.6), (" m/s ", 1.0), ("mph", 0.44704)] {
            assert_eq!(unit_to_ms(u), Some(f), "{u}");
        }
        assert_eq!(unit_to_ms(""), None);
        assert_eq!(unit_to_ms("rpm"), None);
    }

    #[test]
    fn a_binary_file_is_not_dumped_as_dbc_text() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("car.dbc");
        let mut bytes = b"VERSION \"\"\n".to_vec();
        bytes.extend((0u8..=255).cycle().take(5000));
        std::fs::write(&p, &bytes).unwrap();
        let cfg = SpeedConfig { message: "X".into(), signals: vec!["A".into()], ..Default::default() };
        let e = SpeedDecoder::from_dbc(&p, &cfg).err().unwrap().to_string();
        assert!(e.contains("a binary file, not DBC text") && e.contains("line 2"), "{e}");
        assert!(e.len() < 300 && !e.chars().any(|c| c.is_control() && c != '\n'), "{e}");
        let long = format!("VERSION \"\"\n{}\u{7f}\n", "x".repeat(5000));
        let e = SpeedDecoder::from_dbc_text(&long, "t.dbc", &cfg).err().unwrap().to_string();
        assert!(e.len() < 1500 && !e.contains('\u{7f}'), "{e}");
    }
}
