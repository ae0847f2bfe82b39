//! Output frames: estimate -> four classic CAN frames, as `config/gyrocomp.dbc`
//! describes them (Intel byte order, signed where the DBC says `-`).
//!
//! | frame | bytes 0-1 | bytes 2-3 | bytes 4-5 | bytes 6-7 |
//! |---|---|---|---|---|
//! | GYRO_RATE_CORR | RateX i16 0.01 deg/s | RateY | RateZ | DataCnt u16 |
//! | ATTITUDE | Roll i16 0.01 deg | Pitch | Yaw | DataCnt |
//! | GYRO_BIAS | BiasX i16 0.0005 deg/s | BiasY | BiasZ | DataCnt |
//! | EST_STATUS | Mode (2 bits) + flags (14 bits) | TempC i16 0.01 C | DataCnt | ErrCnt u8, LostCnt u8 |
//!
//! Values outside a signal's range saturate (and set `RATE_SAT` for rates).

use crate::config::OutputConfig;
use crate::estimator::{flags, Estimate};

pub const RATE_SCALE: f64 = 0.01;
pub const ANGLE_SCALE: f64 = 0.01;
pub const BIAS_SCALE: f64 = 0.0005;
pub const TEMP_SCALE: f64 = 0.01;

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

/// Encode one estimate. `extra_flags` are OR-ed into the status (daemon flags).
pub fn encode(e: &Estimate, c: &StatusCounters, ids: &OutputConfig, extra_flags: u16) -> [OutFrame; 4] {
    let (rx, s0) = q16(e.rate[0], RATE_SCALE);
    let (ry, s1) = q16(e.rate[1], RATE_SCALE);
    let (rz, s2) = q16(e.rate[2], RATE_SCALE);
    let mut fl = e.flags | extra_flags;
    if s0 || s1 || s2 {
        fl |= flags::RATE_SAT;
    }
    let ang = [q16(e.roll, ANGLE_SCALE).0, q16(e.pitch, ANGLE_SCALE).0, q16(e.yaw, ANGLE_SCALE).0];
    let bias = [q16(e.bias[0], BIAS_SCALE).0, q16(e.bias[1], BIAS_SCALE).0, q16(e.bias[2], BIAS_SCALE).0];
    let mut st = [0u8; 8];
    let w0: u16 = (e.mode as u16 & 0x3) | ((fl & 0x3FFF) << 2);
    st[0..2].copy_from_slice(&w0.to_le_bytes());
    st[2..4].copy_from_slice(&q16(e.temp, TEMP_SCALE).0.to_le_bytes());
    st[4..6].copy_from_slice(&e.cnt.to_le_bytes());
    st[6] = (c.errors & 0xFF) as u8;
    st[7] = (c.lost & 0xFF) as u8;
    [
        OutFrame { id: ids.rate_id, data: put3([rx, ry, rz], e.cnt) },
        OutFrame { id: ids.attitude_id, data: put3(ang, e.cnt) },
        OutFrame { id: ids.bias_id, data: put3(bias, e.cnt) },
        OutFrame { id: ids.status_id, data: st },
    ]
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
}

pub fn decode(frames: &[OutFrame; 4]) -> Decoded {
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
    }
}
