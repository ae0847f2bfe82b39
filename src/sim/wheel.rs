//! Wheel speeds on the simulated bus, as `config/example-car.dbc` describes
//! them: message `WHEEL_SPEEDS` (ID 0x1A0, 11 bit, DLC 8), every 20 ms, four
//! signed 16-bit Intel signals `WHEEL_SPEED_FL/FR/RL/RR` in 0.01 km/h
//! (negative while reversing).
//!
//! What a real car's ABS module does and the simulator reproduces: each
//! frame carries the speeds of `latency_s` ago (drawn per run, 20-80 ms);
//! every wheel reads `1 + scale_error` times its true speed (a tyre radius
//! off by up to 3 %, drawn per run); a little white noise; frames are
//! `period` apart with up to 0.2 ms of jitter. The wheels' true speeds come
//! from the rear-axle speed `v` and the yaw rate `r` (rad/s): rear
//! `v + r track/2` (left, outside in a right turn) and `v - r track/2`
//! (right); the steered front wheels `sign(v) |(v +- r track/2, r wheelbase)|`.

use super::motion::Truth;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;

/// The DBC of the simulated car (`config/example-car.dbc`).
pub const EXAMPLE_DBC: &str = include_str!("../../config/example-car.dbc");
/// `WHEEL_SPEEDS` in it.
pub const WHEEL_SPEEDS_ID: u32 = 0x1A0;
pub const WHEEL_SPEEDS_MESSAGE: &str = "WHEEL_SPEEDS";
/// The signals the simulated `config.toml` averages (the rear wheels).
pub const REAR_SIGNALS: [&str; 2] = ["WHEEL_SPEED_RL", "WHEEL_SPEED_RR"];
/// Resolution of the signals, km/h.
pub const LSB_KMH: f64 = 0.01;

/// The drawn wheel-speed source of one run (`[wheel_speeds]` of `scenario.toml`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WheelParams {
    /// CAN ID of `WHEEL_SPEEDS`.
    pub id: u32,
    /// Frame period, s.
    pub period_s: f64,
    /// Age of the speeds a frame carries, s.
    pub latency_s: f64,
    /// Every wheel reads `(1 + scale_error)` times its true speed.
    pub scale_error: f64,
    /// White noise per wheel and frame, km/h (1 sigma).
    pub noise_kmh: f64,
    /// A wheel slower than this reads 0, km/h.
    pub dead_band_kmh: f64,
    /// Rear track and wheelbase, m.
    pub track_m: f64,
    pub wheelbase_m: f64,
    /// Time of the first frame's period slot, s from the first IMU sample.
    pub phase_s: f64,
}

/// True wheel speeds `[FL, FR, RL, RR]`, m/s, of a vehicle with rear-axle
/// speed `v` (m/s, signed) and yaw rate `r` (rad/s, FRD: positive turning right).
pub fn wheel_speeds(v: f64, r: f64, track: f64, wheelbase: f64) -> [f64; 4] {
    let (left, right) = (v + r * track / 2.0, v - r * track / 2.0);
    let side = r * wheelbase;
    let s = if v < 0.0 { -1.0 } else { 1.0 };
    [s * left.hypot(side), s * right.hypot(side), left, right]
}

/// The `WHEEL_SPEEDS` payload for speeds in km/h (rounded to 0.01 km/h,
/// saturated to the signed 16-bit range).
pub fn encode(kmh: [f64; 4]) -> [u8; 8] {
    let mut d = [0u8; 8];
    for (i, x) in kmh.iter().enumerate() {
        let raw = (x / LSB_KMH).round().clamp(i16::MIN as f64, i16::MAX as f64) as i16;
        d[2 * i..2 * i + 2].copy_from_slice(&raw.to_le_bytes());
    }
    d
}

/// Produces the wheel-speed frames from the truth stream.
pub struct WheelBus {
    p: WheelParams,
    rng: ChaCha8Rng,
    /// `(t, v, r rad/s)` of recent truth samples.
    hist: VecDeque<(f64, f64, f64)>,
    /// Index of the next frame.
    j: u64,
    /// Bus time of the next frame, s, and its jitter, us.
    next: (f64, u64),
}

impl WheelBus {
    pub fn new(p: WheelParams, mut rng: ChaCha8Rng) -> WheelBus {
        // the first frame whose content (latency_s earlier) is inside the run
        let j = ((p.latency_s - p.phase_s) / p.period_s).ceil().max(0.0) as u64;
        let jit = rng.gen_range(0..=200u64);
        let t = p.phase_s + j as f64 * p.period_s;
        WheelBus { p, rng, hist: VecDeque::with_capacity(64), j, next: (t, jit) }
    }

    pub fn params(&self) -> &WheelParams {
        &self.p
    }

    /// Record the truth of the next IMU sample.
    pub fn push(&mut self, tr: &Truth) {
        self.hist.push_back((tr.t, tr.speed, tr.rate[2].to_radians()));
        // keep what the next frame may still need
        let need = self.next.0 - self.p.latency_s;
        while self.hist.len() > 2 && self.hist[1].0 <= need {
            self.hist.pop_front();
        }
    }

    /// The next frame `(t_us from the first sample, payload)` if its bus time
    /// is before `before_us` and the truth it carries has been pushed.
    pub fn pop_before(&mut self, before_us: u64) -> Option<(u64, [u8; 8])> {
        let t_us = (self.next.0 * 1e6).round() as u64 + self.next.1;
        if t_us >= before_us {
            return None;
        }
        self.pop_any()
    }

    /// The next frame, whatever its bus time, if its content is known.
    pub fn pop_any(&mut self) -> Option<(u64, [u8; 8])> {
        let t_us = (self.next.0 * 1e6).round() as u64 + self.next.1;
        let tc = self.next.0 - self.p.latency_s;
        let last = self.hist.back()?;
        if tc > last.0 + 1e-9 {
            return None;
        }
        let k = self.hist.iter().position(|h| h.0 >= tc - 1e-12).unwrap_or(0);
        let (v, r) = if k == 0 {
            (self.hist[0].1, self.hist[0].2)
        } else {
            let (a, b) = (self.hist[k - 1], self.hist[k]);
            let w = (tc - a.0) / (b.0 - a.0);
            (a.1 + w * (b.1 - a.1), a.2 + w * (b.2 - a.2))
        };
        let sp = wheel_speeds(v, r, self.p.track_m, self.p.wheelbase_m);
        let mut kmh = [0.0; 4];
        for (o, s) in kmh.iter_mut().zip(sp) {
            let n: f64 = self.rng.sample(StandardNormal);
            let kmh = s * 3.6 * (1.0 + self.p.scale_error);
            *o = if kmh.abs() < self.p.dead_band_kmh { 0.0 } else { kmh + self.p.noise_kmh * n };
        }
        self.j += 1;
        self.next = (self.p.phase_s + self.j as f64 * self.p.period_s, self.rng.gen_range(0..=200u64));
        Some((t_us, encode(kmh)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rear_wheels_differ_by_the_yaw_rate_times_the_track() {
        // right turn (r > 0): the left wheels are outside
        let w = wheel_speeds(10.0, 0.5, 1.6, 2.7);
        assert!((w[2] - 10.4).abs() < 1e-12 && (w[3] - 9.6).abs() < 1e-12);
        assert!((0.5 * (w[2] + w[3]) - 10.0).abs() < 1e-12);
        assert!(w[0] > w[2] && w[1] > w[3]);
        let b = wheel_speeds(-2.0, 0.0, 1.6, 2.7);
        assert_eq!(b, [-2.0; 4]);
    }

    #[test]
    fn payload_is_signed_little_endian_centi_kmh() {
        let d = encode([100.0, -100.0, 0.004, -0.006]);
        assert_eq!(d, [0x10, 0x27, 0xF0, 0xD8, 0, 0, 0xFF, 0xFF]);
        assert_eq!(&encode([1e6, -1e6, 0.0, 0.0])[..4], &[0xFF, 0x7F, 0x00, 0x80]);
    }
}
