//! The decode plan: the config's mapping resolved against the DBC, once.

use super::extract::{low_bits, Extractor};
use super::{Measured, MOTION};
use crate::config::dbcin::{split_ref, unit_factor, Kind, SignalRef, CHANNELS};
use crate::config::InputConfig;
use crate::speed::num;
use can_dbc::{Dbc, Message, MessageId, Signal};

/// Most messages one sample may span.
pub const MAX_MESSAGES: usize = 16;

/// How frames become one sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Assembly {
    /// The frames whose counters (modulo `modulus`) are equal.
    Counter { modulus: u32 },
    /// One frame of each message within `us` microseconds of the first.
    Window { us: u64 },
}

/// A checksum scheme gyrocomp knows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Crc {
    /// CRC-8 SAE J1850 (poly 0x1D, init 0xFF, final xor 0xFF) over the
    /// message's other bytes in order, in the byte `at`.
    J1850 { at: u8 },
}

impl Crc {
    /// Whether the payload's checksum holds.
    #[inline]
    pub fn ok(&self, d: &[u8]) -> bool {
        match *self {
            Crc::J1850 { at } => j1850(d, at as usize) == d[at as usize],
        }
    }
}

/// CRC-8 SAE J1850 of `d` without its byte `skip`.
#[inline]
pub(super) fn j1850(d: &[u8], skip: usize) -> u8 {
    let mut c: u8 = 0xFF;
    for (i, b) in d.iter().enumerate() {
        if i != skip {
            c = J1850[(c ^ b) as usize];
        }
    }
    c ^ 0xFF
}

/// CRC-8 SAE J1850 (poly 0x1D) by byte, made at compile time.
const J1850: [u8; 256] = {
    let mut t = [0u8; 256];
    let mut i = 0;
    while i < 256 {
        let mut c = i as u8;
        let mut k = 0;
        while k < 8 {
            c = if c & 0x80 != 0 { (c << 1) ^ 0x1D } else { c << 1 };
            k += 1;
        }
        t[i] = c;
        i += 1;
    }
    t
};

/// One message of the sample.
#[derive(Clone, Debug, PartialEq)]
pub struct MsgPlan {
    pub name: String,
    /// The ID a frame must have after `mask` (J1939: PGN and source address).
    pub id: u32,
    pub mask: u32,
    pub extended: bool,
    /// Payload length, bytes (the DBC's; up to 64 for CAN FD).
    pub len: usize,
    pub counter: Option<Extractor>,
    pub crc: Option<Crc>,
    /// Indexes into [`DbcPlan::channels`] of the channels this message carries.
    pub channels: Vec<usize>,
    /// Validity signals: extractor, the raw bits wanted (two's complement when
    /// signed), the diag bit set when they differ.
    pub valid: Vec<(Extractor, u64, u16)>,
}

impl MsgPlan {
    #[inline]
    pub fn matches(&self, id: u32, extended: bool) -> bool {
        extended == self.extended && id & self.mask == self.id
    }
}

/// One physical channel: `raw * a + b` in gyrocomp's unit, negated when the sign bit is set.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Channel {
    pub sig: Extractor,
    pub sign: Option<Extractor>,
    pub a: f64,
    pub b: f64,
}

impl Channel {
    #[inline]
    pub fn value(&self, d: &[u8]) -> f64 {
        let x = self.sig.value_f64(d) * self.a + self.b;
        match self.sign {
            Some(s) if s.raw(d) != 0 => -x,
            _ => x,
        }
    }
}

/// The whole plan.
#[derive(Clone, Debug, PartialEq)]
pub struct DbcPlan {
    /// The DBC file, as named in errors.
    pub path: String,
    pub msgs: Vec<MsgPlan>,
    /// gyro x..z (deg/s), accel x..z (g), temp (deg C), in [`CHANNELS`] order.
    pub channels: [Option<Channel>; 7],
    pub assembly: Assembly,
    pub rate_hz: f64,
    /// The temperature reported when none is mapped, deg C.
    pub temp_default: f64,
    /// The effective mapping, one line each (for `check-config`).
    pub lines: Vec<String>,
}

/// A build error: the config key and the message (which names the DBC file).
pub type PlanError = (String, String);

fn e<T>(key: &str, msg: String) -> Result<T, PlanError> {
    Err((key.to_string(), msg))
}

struct Ctx<'a> {
    dbc: &'a Dbc,
    path: &'a str,
    sa: Option<u8>,
    msgs: Vec<MsgPlan>,
}

impl<'a> Ctx<'a> {
    /// The message and signal `r` ("MESSAGE.SIGNAL") names, and the message's index in the plan.
    fn find(&mut self, key: &str, r: &str) -> Result<(usize, &'a Message, &'a Signal), PlanError> {
        let (m, s) = split_ref(r).or_else(|why| e(key, why))?;
        let dbc = self.dbc;
        let Some(msg) = dbc.messages.iter().find(|x| x.name == m) else {
            let known: Vec<&str> = dbc.messages.iter().map(|x| x.name.as_str()).collect();
            return e(key, format!("{}: no message named {m:?} (it has: {})", self.path, known.join(", ")));
        };
        let Some(sig) = msg.signals.iter().find(|x| x.name == s) else {
            let known: Vec<&str> = msg.signals.iter().map(|x| x.name.as_str()).collect();
            return e(key, format!("{}: message {m} has no signal named {s:?} (it has: {})", self.path, known.join(", ")));
        };
        if let Some(why) = crate::speed::not_plain_integer(dbc, msg, sig) {
            return e(key, format!("{}: {r}: {why}", self.path));
        }
        let k = match self.msgs.iter().position(|x| x.name == msg.name) {
            Some(k) => k,
            None => {
                let p = self.message(key, msg)?;
                self.msgs.push(p);
                self.msgs.len() - 1
            }
        };
        Ok((k, msg, sig))
    }

    fn message(&self, key: &str, msg: &Message) -> Result<MsgPlan, PlanError> {
        if self.msgs.len() == MAX_MESSAGES {
            return e(key, format!("a sample may span at most {MAX_MESSAGES} messages"));
        }
        let len = msg.size as usize;
        if !(1..=64).contains(&len) {
            return e(key, format!("{}: message {} is {} bytes long; CAN carries 1 to 64", self.path, msg.name, msg.size));
        }
        let (id, mask, extended) = match (msg.id, self.sa) {
            (MessageId::Standard(x), _) => (u32::from(x), 0x7FF, false),
            (MessageId::Extended(x), None) => (x, 0x1FFF_FFFF, true),
            (MessageId::Extended(x), Some(sa)) => {
                // J1939: the priority bits never matter; PDU1 (PF < 240) carries
                // a destination address in PS, which is not part of the PGN
                let pdu1 = (x >> 16) & 0xFF < 240;
                let mask = if pdu1 { 0x03FF_00FF } else { 0x03FF_FFFF };
                ((x & mask & !0xFF) | u32::from(sa), mask, true)
            }
        };
        let crc = self.crc(msg, len);
        Ok(MsgPlan { name: msg.name.clone(), id, mask, extended, len, counter: None, crc, channels: Vec::new(), valid: Vec::new() })
    }

    /// A CRC signal of a scheme the DBC names in its comment (`CM_ SG_ ... "... J1850 ..."`).
    fn crc(&self, msg: &Message, len: usize) -> Option<Crc> {
        msg.signals.iter().find_map(|s| {
            let named = s.name.to_ascii_uppercase().contains("CRC");
            let j1850 = self.dbc.comments.iter().any(|c| {
                matches!(c, can_dbc::Comment::Signal { message_id, name, comment }
                    if *message_id == msg.id && *name == s.name && comment.to_ascii_uppercase().contains("J1850"))
            });
            let aligned = s.size == 8 && s.start_bit % 8 == if s.byte_order == can_dbc::ByteOrder::BigEndian { 7 } else { 0 };
            (named && j1850 && aligned && (s.start_bit / 8) < len as u64).then_some(Crc::J1850 { at: (s.start_bit / 8) as u8 })
        })
    }
}

impl DbcPlan {
    /// Resolve `input`'s mapping against the DBC text `text` (read from
    /// `path`, which names it in errors). `temp_default`: deg C reported
    /// when no temperature is mapped.
    pub fn build(input: &InputConfig, text: &str, path: &str, temp_default: f64) -> Result<DbcPlan, PlanError> {
        let dbc = Dbc::try_from(text)
            .map_err(|x| ("input.dbc".to_string(), format!("{path}: not a valid DBC: {}", crate::speed::printable(&x.to_string()))))?;
        let mut cx = Ctx { dbc: &dbc, path, sa: input.source_address, msgs: Vec::new() };
        let mut channels: [Option<Channel>; 7] = [None; 7];
        let mut lines = Vec::new();
        for (k, r) in input.signals.channels().into_iter().enumerate() {
            let Some(r) = r else { continue };
            let key = format!("input.signals.{}", CHANNELS[k]);
            let (ch, line) = channel(&mut cx, input, k, r, &key)?;
            channels[k] = Some(ch);
            lines.push(line);
        }
        if cx.msgs.is_empty() {
            return e("input.signals", format!("map at least one signal of {path} (gyro_x .. accel_z, temp)"));
        }
        let assembly = assembly(&mut cx, input, &mut lines)?;
        valid(&mut cx, input, &mut lines)?;
        for m in &cx.msgs {
            let how = match m.crc {
                Some(Crc::J1850 { at }) => format!("CRC-8 SAE J1850 in byte {at} checked"),
                None => "no checksum known".into(),
            };
            let id = if m.extended { format!("{:#010x}/{:#010x}", m.id, m.mask) } else { format!("{:#05x}", m.id) };
            lines.push(format!("message {} id {id}, {} bytes, {how}", m.name, m.len));
        }
        Ok(DbcPlan { path: path.to_string(), msgs: cx.msgs, channels, assembly, rate_hz: input.rate_hz, temp_default, lines })
    }

    /// The channels mapped, one bit each ([`CHANNELS`] order).
    pub fn measured(&self) -> Measured {
        self.channels.iter().enumerate().fold(0, |m, (k, c)| if c.is_some() { m | 1 << k } else { m })
    }

    /// The motion axes (gyro, accel) not mapped, by key.
    pub fn missing_motion(&self) -> Vec<&'static str> {
        (0..6).filter(|k| self.measured() & MOTION & (1 << k) == 0).map(|k| CHANNELS[k]).collect()
    }

    /// The index of the message a frame belongs to.
    #[inline]
    pub fn find(&self, id: u32, extended: bool) -> Option<usize> {
        self.msgs.iter().position(|m| m.matches(id, extended))
    }
}

/// One channel: its signal (and sign bit), its unit and its scale.
fn channel(cx: &mut Ctx<'_>, input: &InputConfig, k: usize, r: &SignalRef, key: &str) -> Result<(Channel, String), PlanError> {
    let (name, sign_bit) = match r {
        SignalRef::Name(n) => (n.as_str(), None),
        SignalRef::SignMagnitude { signal, sign_bit } => (signal.as_str(), Some(sign_bit.as_str())),
    };
    let (flip, name) = match name.strip_prefix('-') {
        Some(n) => (-1.0, n),
        None => (1.0, name),
    };
    let (mi, msg, sig) = cx.find(key, name)?;
    let len = cx.msgs[mi].len;
    let ex = Extractor::of(sig, len).or_else(|why| e(key, format!("{}: {name}: {why}", cx.path)))?;
    if !(sig.factor.is_finite() && sig.factor != 0.0 && sig.offset.is_finite()) {
        return e(key, format!("{}: {name}: factor {} and offset {} must be finite, the factor non-zero", cx.path, sig.factor, sig.offset));
    }
    let sign = match sign_bit {
        None => None,
        Some(sb) => {
            let (si, _, s) = cx.find(key, sb)?;
            if si != mi {
                return e(key, format!("{}: the sign bit {sb} is not in {}, the magnitude's message", cx.path, msg.name));
            }
            Some(Extractor::of(s, len).or_else(|why| e(key, format!("{}: {sb}: {why}", cx.path)))?)
        }
    };
    let kind = Kind::of_channel(k);
    let over = match kind {
        Kind::Gyro => &input.units.gyro,
        Kind::Accel => &input.units.accel,
        Kind::Temp => &input.units.temp,
    };
    let (unit, ukey) = match over {
        Some(u) => (u.as_str(), format!("input.units.{}", kind.key())),
        None => (sig.unit.as_str(), key.to_string()),
    };
    let Some((conv, add)) = unit_factor(kind, unit) else {
        let whose = if over.is_some() { "the configured unit".to_string() } else { format!("{}'s unit in {}", name, cx.path) };
        return e(
            &ukey,
            format!("{whose} {unit:?} is not a {} unit gyrocomp converts ({}); set [input.units] {}", kind.key(), kind.known(), kind.key()),
        );
    };
    let (a, b) = (sig.factor * conv * flip, (sig.offset * conv + add) * flip);
    cx.msgs[mi].channels.push(k);
    let order = if ex.motorola { "Motorola" } else { "Intel" };
    let sg = if ex.signed { "signed" } else { "unsigned" };
    let out = match kind {
        Kind::Gyro => "deg/s",
        Kind::Accel => "g",
        Kind::Temp => "degC",
    };
    let (lo, hi) = (num(&sig.min), num(&sig.max));
    let mut line = format!(
        "{} = {}{name}: bit {} size {} {order} {sg}, factor {} offset {} {unit:?} (DBC range [{lo}|{hi}]) -> {} {out} per LSB, offset {} {out}",
        CHANNELS[k],
        if flip < 0.0 { "-" } else { "" },
        sig.start_bit,
        sig.size,
        sig.factor,
        sig.offset,
        a,
        b
    );
    if let Some(sb) = sign_bit {
        line += &format!(", negative when {sb} is set");
    }
    Ok((Channel { sig: ex, sign, a, b }, line))
}

/// `[input.sample]`: counters (one per message, of one width) or a window.
fn assembly(cx: &mut Ctx<'_>, input: &InputConfig, lines: &mut Vec<String>) -> Result<Assembly, PlanError> {
    let s = &input.sample;
    match (s.counter.is_empty(), s.window_ms) {
        (true, Some(w)) => {
            lines.push(format!("sample: one frame of each of the {} messages within {w} ms", cx.msgs.len()));
            Ok(Assembly::Window { us: (w * 1000.0).round() as u64 })
        }
        (false, None) => {
            let n_mapped = cx.msgs.len();
            let mut width = None;
            for (i, c) in s.counter.iter().enumerate() {
                let key = format!("input.sample.counter[{i}]");
                let (mi, _, sig) = cx.find(&key, c)?;
                if mi >= n_mapped {
                    return e(&key, format!("{c} is in a message no mapped signal is in: it cannot join a sample"));
                }
                if cx.msgs[mi].counter.is_some() {
                    return e(&key, format!("a second counter for message {}", cx.msgs[mi].name));
                }
                let ex = Extractor::of(sig, cx.msgs[mi].len).or_else(|why| e(&key, format!("{}: {c}: {why}", cx.path)))?;
                if !(2..=16).contains(&ex.size) {
                    return e(&key, format!("{c} is {} bits wide; a counter must have 2 to 16 bits", ex.size));
                }
                if width.is_some_and(|w| w != ex.size) {
                    return e(
                        &key,
                        format!(
                            "{c} is {} bits wide, the counters before it {} bits: equal counters cannot be matched",
                            ex.size,
                            width.unwrap_or(0)
                        ),
                    );
                }
                width = Some(ex.size);
                cx.msgs[mi].counter = Some(ex);
            }
            if let Some(m) = cx.msgs.iter().find(|m| m.counter.is_none()) {
                return e("input.sample.counter", format!("message {} has no counter: name one counter signal per message", m.name));
            }
            let w = width.unwrap_or(16);
            lines.push(format!("sample: the {} messages with equal {w}-bit counters", cx.msgs.len()));
            Ok(Assembly::Counter { modulus: 1 << w })
        }
        _ => e("input.sample", "name either counter (one signal per message) or window_ms, not both and not neither".into()),
    }
}

/// `[input.valid]`: signals in the sample's messages, values their raw range can hold.
fn valid(cx: &mut Ctx<'_>, input: &InputConfig, lines: &mut Vec<String>) -> Result<(), PlanError> {
    let n_mapped = cx.msgs.len();
    for (bit, (r, want)) in input.valid.iter().enumerate() {
        if bit >= 16 {
            return e("input.valid", "at most 16 validity signals".into());
        }
        let (mi, _, sig) = cx.find("input.valid", r)?;
        if mi >= n_mapped {
            return e("input.valid", format!("{r} is in a message no mapped signal is in"));
        }
        let ex = Extractor::of(sig, cx.msgs[mi].len).or_else(|why| e("input.valid", format!("{}: {r}: {why}", cx.path)))?;
        let (lo, hi) = ex.raw_range();
        if !(lo..=hi).contains(&i128::from(*want)) {
            return e(
                "input.valid",
                format!("{r} = {want}: a {}-bit {} signal holds {lo}..{hi}", ex.size, if ex.signed { "signed" } else { "unsigned" }),
            );
        }
        cx.msgs[mi].valid.push((ex, *want as u64 & low_bits(ex.size), 1 << bit));
        lines.push(format!("valid: {r} must be {want} (raw), else the sample is suspect (diag bit {bit})"));
    }
    Ok(())
}
