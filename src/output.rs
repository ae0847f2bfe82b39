//! Output frames: estimate -> five classic CAN frames (four with `[output]
//! aid_frame = false`), as `config/gyrocomp.dbc` describes them (Intel byte
//! order, signed where the DBC says `-`).
//!
//! | frame | bytes 0-1 | bytes 2-3 | bytes 4-5 | bytes 6-7 |
//! |---|---|---|---|---|
//! | GYRO_RATE_CORR | RateX i16 0.01 deg/s | RateY | RateZ | DataCnt u16 |
//! | ATTITUDE | Roll i16 0.01 deg | Pitch | Yaw | DataCnt |
//! | GYRO_BIAS | BiasX i16 0.0005 deg/s | BiasY | BiasZ | DataCnt |
//! | EST_STATUS | Mode (2 bits) + flags (14 bits) | TempC i16 0.01 C | DataCnt | ErrCnt u8, LostCnt u8 |
//! | EST_AID | u32 (bytes 0-3): 12 two-bit fields `Aid<Name>`, source `i` of `Aid::ALL` at bits `2i..2i+1`; bits 24-30 `Invalid<Field>` ([`crate::estimator::invalid`]), bit 31 0 | | WorstRatio u16 0.01 | DataCnt |
//!
//! A field the estimate marks invalid (a reduced-axis unit's roll, pitch, x
//! and y rates and biases) is sent as raw `0x8000` ([`FILL`]: outside Roll's
//! and Pitch's range) with its `Invalid*` bit set; the six-axis filters send
//! every bit 0.
//!
//! Values outside a signal's range saturate (and set `RATE_SAT` for rates);
//! `WorstRatio` saturates at 655.35, and a non-finite ratio is sent as that.

use crate::config::OutputConfig;
use crate::estimator::mekf::{Aid, AidWord};
use crate::estimator::{flags, Estimate};

pub const RATE_SCALE: f64 = 0.01;
pub const ANGLE_SCALE: f64 = 0.01;
pub const BIAS_SCALE: f64 = 0.0005;
pub const TEMP_SCALE: f64 = 0.01;
/// `WorstRatio` of `EST_AID`.
pub const RATIO_SCALE: f64 = 0.01;
/// The largest `WorstRatio` (u16::MAX * 0.01): larger and non-finite ratios are sent as it.
pub const RATIO_MAX: f64 = u16::MAX as f64 * RATIO_SCALE;
/// The bits of the `EST_AID` status word that hold a source (2 per source of
/// `Aid::ALL`); the others are 0.
pub const AID_MASK: u32 = ((1u64 << (2 * Aid::ALL.len())) - 1) as u32;
/// The names of the 2-bit codes of `EST_AID`, as the DBC's `VAL_` gives them.
pub const AID_CODES: [&str; 3] = ["not_applicable", "fused", "refused"];
/// The raw value of a field marked invalid.
pub const FILL: i16 = i16::MIN;
/// Where `Estimate::invalid` sits in the `EST_AID` word.
pub const INVALID_SHIFT: u32 = 24;
/// Index of `EST_STATUS` in [`Frames`].
pub const STATUS: usize = 3;
/// Index of `EST_AID` in [`Frames`] (when sent).
pub const AID: usize = 4;

/// One output frame: 11-bit ID and 8 data bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OutFrame {
    pub id: u32,
    pub data: [u8; 8],
}

/// Input-path counters published (modulo 256) in EST_STATUS.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StatusCounters {
    /// Frames and samples dropped by the input checks (all causes but unknown IDs).
    pub errors: u64,
    /// Samples lost in counter gaps.
    pub lost: u64,
}

impl From<&crate::adis::InputCounters> for StatusCounters {
    fn from(c: &crate::adis::InputCounters) -> Self {
        StatusCounters { errors: c.errors(), lost: c.lost }
    }
}

/// Scale, round to nearest, saturate. Returns (raw, saturated).
#[inline]
fn q16(v: f64, scale: f64) -> (i16, bool) {
    let x = (v / scale).round();
    if !x.is_finite() {
        return (0, true);
    }
    if x > i16::MAX as f64 {
        (i16::MAX, true)
    } else if x < i16::MIN as f64 {
        (i16::MIN, true)
    } else {
        (x as i16, false)
    }
}

#[inline]
fn put3(v: [i16; 3], cnt: u16) -> [u8; 8] {
    let mut d = [0u8; 8];
    for i in 0..3 {
        d[2 * i..2 * i + 2].copy_from_slice(&v[i].to_le_bytes());
    }
    d[6..8].copy_from_slice(&cnt.to_le_bytes());
    d
}

/// The frames of one estimate, in bus order: `GYRO_RATE_CORR`, `ATTITUDE`,
/// `GYRO_BIAS`, `EST_STATUS` and `EST_AID` (unless `[output] aid_frame =
/// false`). Dereferences to the slice of the frames sent.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Frames {
    all: [OutFrame; 5],
    n: u8,
}

impl std::ops::Deref for Frames {
    type Target = [OutFrame];
    fn deref(&self) -> &[OutFrame] {
        &self.all[..self.n as usize]
    }
}

/// The test ratio as `WorstRatio` carries it, before rounding: within
/// `0..=RATIO_MAX`, a non-finite ratio `RATIO_MAX` (never NaN or infinite).
#[inline]
pub fn ratio_sent(r: f64) -> f64 {
    if r.is_finite() {
        r.clamp(0.0, RATIO_MAX)
    } else {
        RATIO_MAX
    }
}

/// The payload of `EST_AID`: the status word (bits of no source cleared),
/// the invalid fields (bits 24-30), `WorstRatio` and `DataCnt`.
#[inline]
pub fn aid_payload(aid: &AidWord, invalid: u8, cnt: u16) -> [u8; 8] {
    let mut d = [0u8; 8];
    let word = (aid.status & AID_MASK) | u32::from(invalid & 0x7F) << INVALID_SHIFT;
    d[0..4].copy_from_slice(&word.to_le_bytes());
    // within 0..=65535 after the clamp: the cast neither wraps nor saturates
    let r = (ratio_sent(aid.worst_ratio) / RATIO_SCALE).round() as u16;
    d[4..6].copy_from_slice(&r.to_le_bytes());
    d[6..8].copy_from_slice(&cnt.to_le_bytes());
    d
}

/// Encode one estimate. `extra_flags` are OR-ed into the status (daemon flags).
pub fn encode(e: &Estimate, c: &StatusCounters, ids: &OutputConfig, extra_flags: u16) -> Frames {
    use crate::estimator::invalid as inv;
    // an invalid field: the fill value, never saturated
    let q = |v: f64, scale: f64, bit: u8| if e.invalid & bit != 0 { (FILL, false) } else { q16(v, scale) };
    let (rx, s0) = q(e.rate[0], RATE_SCALE, inv::RATE_X);
    let (ry, s1) = q(e.rate[1], RATE_SCALE, inv::RATE_Y);
    let (rz, s2) = q(e.rate[2], RATE_SCALE, inv::RATE_Z);
    let mut fl = e.flags | extra_flags;
    if s0 || s1 || s2 {
        fl |= flags::RATE_SAT;
    }
    let ang = [q(e.roll, ANGLE_SCALE, inv::ROLL).0, q(e.pitch, ANGLE_SCALE, inv::PITCH).0, q(e.yaw, ANGLE_SCALE, inv::YAW).0];
    let bias = [q(e.bias[0], BIAS_SCALE, inv::RATE_X).0, q(e.bias[1], BIAS_SCALE, inv::RATE_Y).0, q(e.bias[2], BIAS_SCALE, inv::RATE_Z).0];
    let mut st = [0u8; 8];
    let w0: u16 = (e.mode as u16 & 0x3) | ((fl & 0x3FFF) << 2);
    st[0..2].copy_from_slice(&w0.to_le_bytes());
    st[2..4].copy_from_slice(&q16(e.temp, TEMP_SCALE).0.to_le_bytes());
    st[4..6].copy_from_slice(&e.cnt.to_le_bytes());
    st[6] = (c.errors & 0xFF) as u8;
    st[7] = (c.lost & 0xFF) as u8;
    Frames {
        all: [
            OutFrame { id: ids.rate_id, data: put3([rx, ry, rz], e.cnt) },
            OutFrame { id: ids.attitude_id, data: put3(ang, e.cnt) },
            OutFrame { id: ids.bias_id, data: put3(bias, e.cnt) },
            OutFrame { id: ids.status_id, data: st },
            OutFrame { id: ids.aid_id, data: aid_payload(&e.aid, e.invalid, e.cnt) },
        ],
        n: if ids.aid_frame { 5 } else { 4 },
    }
}

/// Decoded output frames (the inverse of `encode`, for tests and tools).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Decoded {
    pub rate: [f64; 3],
    pub att: [f64; 3],
    pub bias: [f64; 3],
    pub mode: u8,
    pub flags: u16,
    pub temp: f64,
    pub cnt: u16,
    pub errors: u8,
    pub lost: u8,
    /// `EST_AID`: the status word and `WorstRatio` (None when not sent).
    pub aid: Option<AidWord>,
    /// `EST_AID`'s `Invalid*` bits (0 when it is not sent).
    pub invalid: u8,
}

/// Decode the frames of one estimate: the four of every sample, and
/// `EST_AID` when there is a fifth. Panics with fewer than four.
pub fn decode(frames: &[OutFrame]) -> Decoded {
    let g = |d: &[u8; 8], i: usize, s: f64| i16::from_le_bytes([d[2 * i], d[2 * i + 1]]) as f64 * s;
    let st = &frames[3].data;
    let w0 = u16::from_le_bytes([st[0], st[1]]);
    Decoded {
        rate: [0, 1, 2].map(|i| g(&frames[0].data, i, RATE_SCALE)),
        att: [0, 1, 2].map(|i| g(&frames[1].data, i, ANGLE_SCALE)),
        bias: [0, 1, 2].map(|i| g(&frames[2].data, i, BIAS_SCALE)),
        mode: (w0 & 0x3) as u8,
        flags: w0 >> 2,
        temp: g(st, 1, TEMP_SCALE),
        cnt: u16::from_le_bytes([st[4], st[5]]),
        errors: st[6],
        lost: st[7],
        aid: frames.get(AID).map(|f| decode_aid(&f.data).0),
        invalid: frames
            .get(AID)
            .map_or(0, |f| (u32::from_le_bytes([f.data[0], f.data[1], f.data[2], f.data[3]]) >> INVALID_SHIFT) as u8 & 0x7F),
    }
}

/// Decode an `EST_AID` payload: the status word (the sources' bits) and
/// `WorstRatio`, and `DataCnt`.
pub fn decode_aid(d: &[u8; 8]) -> (AidWord, u16) {
    let status = u32::from_le_bytes([d[0], d[1], d[2], d[3]]) & AID_MASK;
    let worst_ratio = u16::from_le_bytes([d[4], d[5]]) as f64 * RATIO_SCALE;
    (AidWord { status, worst_ratio }, u16::from_le_bytes([d[6], d[7]]))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn est(status: u32, worst_ratio: f64) -> Estimate {
        Estimate { cnt: 0xBEEF, aid: AidWord { status, worst_ratio }, ..Default::default() }
    }

    fn aid_bytes(status: u32, worst_ratio: f64) -> [u8; 8] {
        let f = encode(&est(status, worst_ratio), &StatusCounters::default(), &OutputConfig::default(), 0);
        assert_eq!(f.len(), 5);
        assert_eq!(f[AID].id, 0x114);
        f[AID].data
    }

    #[test]
    fn est_aid_carries_the_word_the_ratio_and_the_counter() {
        // zero_velocity fused, zero_rate refused, heading (the 12th) fused
        let w = 0b01 | 0b10 << 2 | 0b01 << 22;
        assert_eq!(aid_bytes(w, 1.234), [0x09, 0x00, 0x40, 0x00, 0x7B, 0x00, 0xEF, 0xBE]);
        // rounded to the nearest 0.01
        assert_eq!(aid_bytes(0, 0.004)[4..6], [0, 0]);
        assert_eq!(aid_bytes(0, 0.005)[4..6], [1, 0]);
        assert_eq!(aid_bytes(0, 655.344)[4..6], 65534u16.to_le_bytes());
        // the fields of no source (bits 24..31) are 0 whatever the word says
        assert_eq!(aid_bytes(0xFFFF_FFFF, 0.0)[0..4], [0xFF, 0xFF, 0xFF, 0x00]);
        assert_eq!(AID_MASK, 0x00FF_FFFF);
    }

    #[test]
    fn worst_ratio_saturates_and_is_never_non_finite() {
        for r in [655.35, 655.36, 700.0, 1e300, f64::MAX, f64::INFINITY, f64::NEG_INFINITY, f64::NAN] {
            assert_eq!(aid_bytes(0, r)[4..6], [0xFF, 0xFF], "ratio {r}");
            assert_eq!(ratio_sent(r), RATIO_MAX, "ratio {r}");
        }
        for r in [-1.0, -0.0, -f64::MAX] {
            assert_eq!(aid_bytes(0, r)[4..6], [0, 0], "ratio {r}");
        }
        assert_eq!(ratio_sent(3.5), 3.5);
        assert!((RATIO_MAX - 655.35).abs() < 1e-9);
    }

    #[test]
    fn invalid_fields_go_out_as_the_fill_value_with_their_bits() {
        use crate::estimator::invalid;
        let e = Estimate {
            rate: [1.0, 2.0, 3.0],
            bias: [0.1, 0.2, 0.3],
            roll: 5.0,
            pitch: 6.0,
            yaw: 7.0,
            invalid: invalid::REDUCED | invalid::TEMP,
            ..est(0b01, 0.0)
        };
        let f = encode(&e, &StatusCounters::default(), &OutputConfig::default(), 0);
        let d = decode(&f);
        assert_eq!(d.invalid, invalid::REDUCED | invalid::TEMP);
        assert_eq!(d.aid.map(|a| a.status), Some(0b01), "the sources' word unchanged");
        assert_eq!(f[AID].data[3], 0b0101_1011);
        let fill = FILL as f64;
        assert_eq!((d.rate, d.bias[..2].to_vec()), ([fill * RATE_SCALE, fill * RATE_SCALE, 3.0], vec![fill * BIAS_SCALE; 2]));
        assert_eq!(d.att, [fill * ANGLE_SCALE, fill * ANGLE_SCALE, 7.0]);
        assert_eq!(d.flags & flags::RATE_SAT, 0, "a fill value is not a saturation");
        // all valid: bits 24-31 are 0, as before
        assert_eq!(aid_bytes(0xFFFF_FFFF, 0.0)[3], 0);
    }

    #[test]
    fn est_aid_decodes_back_and_can_be_switched_off() {
        let e = est(0b10 << (2 * Aid::Heading as u32) | 0b01, 2.5);
        let on = encode(&e, &StatusCounters::default(), &OutputConfig::default(), 0);
        let ids: Vec<u32> = on.iter().map(|f| f.id).collect();
        assert_eq!(ids, [0x110, 0x111, 0x112, 0x113, 0x114]);
        let d = decode(&on);
        let aid = d.aid.expect("EST_AID decoded");
        assert_eq!(aid.status, e.aid.status);
        assert_eq!((aid.code(Aid::ZeroVelocity), aid.code(Aid::Heading), aid.code(Aid::ZeroRate)), (1, 2, 0));
        assert!((aid.worst_ratio - 2.5).abs() < 1e-12);
        assert_eq!(decode_aid(&on[AID].data).1, 0xBEEF);
        let off = OutputConfig { aid_frame: false, ..OutputConfig::default() };
        let f = encode(&e, &StatusCounters::default(), &off, 0);
        assert_eq!(f.len(), 4);
        assert_eq!(f[..], on[..4], "the four others unchanged");
        assert_eq!(decode(&f).aid, None);
    }
}
