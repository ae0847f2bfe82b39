//! The `urban` scenario: city driving as real recordings show it.
//!
//! What it reproduces (issue 11; `tests/sim_urban.rs` checks it on 20 seeds
//! with [`super::stats::DriveStats`]):
//! - the longitudinal acceleration never rests long: it is eased from one
//!   level to the next (levels of 0.01-0.22 g drawn around a wandering target
//!   speed of 6-14 m/s), so |a_x| exceeds 0.05 g about half of the time and
//!   0.1 g about a third, 95th percentile 0.15-0.22 g;
//! - stops of 5-7 s (|v| < 0.1 m/s) every 30-60 s, braking at 0.12-0.22 g,
//!   pulling away at 0.12-0.22 g; the run starts with one (power-on at a
//!   standstill) unless `power_on_moving`, which starts at 8-13 m/s;
//! - one reversing manoeuvre (at the first stop after 35 % of the run): back
//!   to -1.5..-2.5 m/s, stop, then forward again;
//! - slow-downs to 5.5-8 m/s every 12-25 s where tight corners fit, and about
//!   90 turns per 400 s (heading changes of 15-100 deg) placed wherever the
//!   speed allows them: yaw rate up to 45 deg/s, lateral acceleration
//!   `v * r` up to 0.6 g;
//! - hills: the grade is a function of distance, two sines (3.5-4.5 deg at
//!   250-600 m, 1.5-2.5 deg at 80-200 m): grades within +-7 deg; camber
//!   and road unevenness (distance), body lean 3-5 deg/g and squat/dive
//!   2.5-4 deg/g;
//! - the sensor at `Ranges::lever_arm` (default 0.9 m ahead of the rear axle),
//!   road vibration growing with speed, engine idle vibration (the sensor
//!   model's two tones, small) that is all there is at a stop.

use super::motion::{Ease, MotionSpec, Sine, G};
use super::road::{RoadSpec, RoadVibration};
use super::scenario::{thermal, uni, Ranges};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use std::f64::consts::PI;

/// Highest planned speed, m/s (56 km/h).
pub const V_MAX: f64 = 15.5;
/// Lowest speed while driving between stops, m/s.
const V_MIN: f64 = 3.0;
/// Below this |speed| the vehicle counts as stopped, m/s.
pub const STOP_SPEED: f64 = 0.1;
/// Highest yaw-rate command, deg/s.
pub const MAX_YAW_RATE: f64 = 45.0;
/// Highest lateral acceleration `v * r`, g.
pub const MAX_LAT: f64 = 0.6;

/// The longitudinal plan: an eased acceleration profile with the speed
/// tracked exactly at the knots (the mean of a half-cosine ease between two
/// levels is their average).
pub(super) struct Long {
    pub(super) a: Ease,
    pub(super) t: f64,
    pub(super) v: f64,
    lvl: f64,
}

impl Long {
    pub(super) fn new(v0: f64) -> Long {
        let mut a = Ease::default();
        a.push(0.0, 0.0);
        Long { a, t: 0.0, v: v0, lvl: 0.0 }
    }

    /// Ease to `lvl` (g) over `ramp` s, hold it `hold` s.
    pub(super) fn seg(&mut self, lvl: f64, ramp: f64, hold: f64) {
        self.v += G * (0.5 * (self.lvl + lvl) * ramp + lvl * hold);
        self.t += ramp;
        self.a.push(self.t, lvl);
        if hold > 0.0 {
            self.t += hold;
            self.a.push(self.t, lvl);
        }
        self.lvl = lvl;
    }

    /// Reach `target` m/s with zero acceleration at the end: ease to a level
    /// of magnitude `mag` (g) over `r1`, hold, ease to 0 over `r2`. Returns
    /// the level used (smaller than `mag` when the change is short).
    pub(super) fn reach(&mut self, target: f64, mag: f64, r1: f64, r2: f64) -> f64 {
        let dv = target - self.v;
        let solve = |l0: f64| -> (f64, f64) {
            let l = dv.signum() * mag;
            let h = (dv / G - 0.5 * (l0 + l) * r1 - 0.5 * l * r2) / l;
            if h >= 0.0 {
                (l, h)
            } else {
                ((2.0 * dv / G - l0 * r1) / (r1 + r2), 0.0)
            }
        };
        let (mut l, mut h) = solve(self.lvl);
        if l * dv <= 0.0 || l.abs() < 0.02 {
            // the current level overshoots: come back to 0 first
            self.seg(0.0, 1.0, 0.0);
            let dv2 = target - self.v;
            let ll = dv2.signum() * mag;
            let hh = (dv2 / G - 0.5 * ll * r1 - 0.5 * ll * r2) / ll;
            (l, h) = if hh >= 0.0 { (ll, hh) } else { (2.0 * dv2 / G / (r1 + r2), 0.0) };
        }
        self.seg(l, r1, h);
        self.seg(0.0, r2, 0.0);
        self.v = target;
        l
    }
}

/// Time from the end (or start) of a half-cosine ease between 0 and `lvl`
/// (g) over `ramp` s to the moment the speed it made is `STOP_SPEED`.
fn ease_stop_time(lvl: f64, ramp: f64) -> f64 {
    let v = |u: f64| 0.5 * lvl.abs() * G * (u - ramp / PI * (PI * u / ramp).sin());
    if v(ramp) <= STOP_SPEED {
        return ramp;
    }
    let (mut lo, mut hi) = (0.0, ramp);
    for _ in 0..50 {
        let m = 0.5 * (lo + hi);
        if v(m) < STOP_SPEED {
            lo = m;
        } else {
            hi = m;
        }
    }
    0.5 * (lo + hi)
}

/// A longitudinal level magnitude, g: small (cruise), medium, or brisk.
fn magnitude(rng: &mut ChaCha8Rng) -> f64 {
    let u: f64 = rng.gen();
    if u < 0.42 {
        uni(rng, [0.01, 0.05])
    } else if u < 0.70 {
        uni(rng, [0.05, 0.1])
    } else {
        uni(rng, [0.1, 0.2])
    }
}

struct Planner<'a> {
    rng: &'a mut ChaCha8Rng,
    p: Long,
    target: f64,
}

impl Planner<'_> {
    /// One driving segment towards the wandering target speed, keeping the
    /// speed in [V_MIN, V_MAX] even if the next segment eases back to 0.
    fn drive(&mut self) {
        if (self.p.v - self.target).abs() < 1.0 {
            self.target = uni(self.rng, [6.0, 14.0]);
        }
        let m = magnitude(self.rng);
        let l = if self.p.v < self.target { m } else { -m };
        let ramp = uni(self.rng, [0.8, 1.8]);
        let mut hold = uni(self.rng, [0.5, 3.5]);
        let v1 = self.p.v + G * 0.5 * (self.p.lvl + l) * ramp;
        let tail = G * l * 0.9;
        hold = if l > 0.0 { hold.min((V_MAX - tail - v1) / (G * l)) } else { hold.min((v1 + tail - V_MIN) / (G * -l)) };
        let v_ramp_end = v1 + tail;
        if hold < 0.0 || !(V_MIN..=V_MAX).contains(&v_ramp_end) {
            // no room at this level: ease back to (almost) constant speed
            let ramp = uni(self.rng, [0.8, 1.5]);
            self.p.seg(0.0, ramp, uni(self.rng, [0.3, 1.0]));
            return;
        }
        self.p.seg(l, ramp, hold);
    }

    /// A stop: brake to 0, stand, and return the level the braking ended with.
    fn brake_to_stop(&mut self) -> f64 {
        let b = uni(self.rng, [0.12, 0.22]);
        let (r1, r2) = (uni(self.rng, [0.8, 1.5]), uni(self.rng, [0.8, 1.5]));
        let l = self.p.reach(0.0, b, r1, r2);
        ease_stop_time(l, r2)
    }

    /// Stand still so that the stop (|v| < STOP_SPEED) lasts 5-7 s, given the
    /// time already below STOP_SPEED before (`pre`) and after (`post`) it.
    fn stand(&mut self, pre: f64, post: f64) {
        let d = uni(self.rng, [5.05, 6.95]);
        let hold = (d - pre - post).max(0.5);
        self.p.seg(0.0, hold, 0.0);
    }
}

/// Pre-computed `(r1, mag)` of a pull-away so that the stop before it can be
/// sized: the ease-out time below STOP_SPEED is known before planning it.
fn pull_params(rng: &mut ChaCha8Rng, mag: [f64; 2]) -> (f64, f64) {
    (uni(rng, [0.8, 1.5]), uni(rng, mag))
}

/// Build the `urban` motion.
pub fn motion(rng: &mut ChaCha8Rng, r: &Ranges, duration: f64, power_on_moving: bool) -> MotionSpec {
    let v0 = if power_on_moving { uni(rng, [8.0, 13.0]) } else { 0.0 };
    let yaw0 = rng.gen_range(-180.0..180.0);
    let mut pl = Planner { p: Long::new(v0), target: uni(rng, [6.0, 14.0]), rng };
    let reverse_after = 0.35 * duration;
    let mut reversed = false;
    let start_forward = |pl: &mut Planner, pre: f64| {
        let (r1, mag) = pull_params(pl.rng, [0.12, 0.22]);
        pl.stand(pre, ease_stop_time(mag, r1));
        let target = uni(pl.rng, [8.0, 13.0]);
        let r2 = uni(pl.rng, [0.8, 1.5]);
        pl.p.reach(target, mag, r1, r2);
    };
    if !power_on_moving {
        start_forward(&mut pl, 0.0);
    }
    let mut next_stop = pl.p.t + uni(pl.rng, [30.0, 60.0]);
    let mut next_slow = pl.p.t + uni(pl.rng, [12.0, 25.0]);
    while pl.p.t < duration {
        if pl.p.t >= next_stop && pl.p.v > 4.0 {
            let pre = pl.brake_to_stop();
            if !reversed && pl.p.t > reverse_after {
                reversed = true;
                let (r1, mag) = pull_params(pl.rng, [0.08, 0.12]);
                pl.stand(pre, ease_stop_time(mag, r1));
                let back = -uni(pl.rng, [1.5, 2.5]);
                let r2 = uni(pl.rng, [0.8, 1.5]);
                pl.p.reach(back, mag, r1, r2);
                let cruise = uni(pl.rng, [0.5, 1.5]);
                pl.p.seg(0.0, cruise, 0.0);
                let b = uni(pl.rng, [0.08, 0.15]);
                let (r1, r2) = (uni(pl.rng, [0.8, 1.5]), uni(pl.rng, [0.8, 1.5]));
                let l = pl.p.reach(0.0, b, r1, r2);
                start_forward(&mut pl, ease_stop_time(l, r2));
            } else {
                start_forward(&mut pl, pre);
            }
            next_stop = pl.p.t + uni(pl.rng, [30.0, 60.0]);
            next_slow = next_slow.max(pl.p.t + uni(pl.rng, [3.0, 8.0]));
        } else if pl.p.t >= next_slow && pl.p.v > 6.0 {
            // slow down for a corner, roll through it, go on
            let slow = uni(pl.rng, [5.5, 8.0]);
            let mag = uni(pl.rng, [0.08, 0.22]);
            let (r1, r2) = (uni(pl.rng, [0.8, 1.5]), uni(pl.rng, [0.8, 1.5]));
            pl.p.reach(slow, mag, r1, r2);
            let hold = uni(pl.rng, [2.5, 5.0]);
            pl.p.seg(0.0, hold, 0.0);
            next_slow = pl.p.t + uni(pl.rng, [12.0, 25.0]);
        } else {
            pl.drive();
        }
    }
    let end = pl.p.t + 1.0;
    pl.p.a.push(end, 0.0);
    let a_long = pl.p.a;
    let yaw_rate = turns(pl.rng, &a_long, v0, duration);
    let rng = pl.rng;
    let grade = vec![slow_sine(rng, [3.5, 4.5], [250.0, 600.0]), slow_sine(rng, [1.5, 2.5], [80.0, 200.0])];
    let road_pitch = vec![slow_sine(rng, [0.1, 0.3], [4.0, 15.0])];
    let road_roll = vec![slow_sine(rng, [0.5, 1.5], [50.0, 300.0]), slow_sine(rng, [0.1, 0.3], [3.0, 12.0])];
    let vibration = ride_vibration(rng, r);
    let thermal = thermal(rng, r);
    let roll_per_lat = -uni(rng, [3.0, 5.0]);
    let pitch_per_long = uni(rng, [2.5, 4.0]);
    MotionSpec {
        duration,
        a_long,
        a_lat: Ease::constant(0.0),
        v0,
        yaw0,
        roll0: 0.0,
        pitch0: 0.0,
        roll_sines: vec![],
        pitch_sines: vec![],
        roll_per_lat,
        pitch_per_long,
        bumps: vec![],
        ride_roll: vec![],
        ride_pitch: vec![],
        thermal,
        manoeuvre_start: 10.0_f64.min(duration),
        road: Some(RoadSpec { yaw_rate, grade, road_pitch, road_roll, lever_arm: r.lever_arm, vibration }),
    }
}

/// Speed on a 10 ms grid from the acceleration profile.
/// A sine of amplitude drawn from `amp` and wavelength (period, s) drawn
/// from `period`, at a random phase: the road's grades, camber and swell.
pub(super) fn slow_sine(rng: &mut ChaCha8Rng, amp: [f64; 2], period: [f64; 2]) -> Sine {
    Sine { amp: uni(rng, amp), freq: 1.0 / uni(rng, period), phase: rng.gen_range(0.0..2.0 * PI) }
}

/// The ride vibration of a road car: a level drawn from
/// `road_vibration_g` (g, vertical; lateral 0.5x, longitudinal 0.4x) in
/// six tones of 8-45 Hz, none when the level is 0. The tones are drawn
/// either way, so the draws after them do not depend on the level.
pub(super) fn ride_vibration(rng: &mut ChaCha8Rng, r: &Ranges) -> RoadVibration {
    let vz: f64 = uni(rng, r.road_vibration_g);
    let tones = (0..6)
        .map(|_| {
            let f = uni(rng, [8.0, 45.0]);
            let ph = rng.gen_range(0.0..2.0 * PI);
            (f, ph, [0.4 * vz, 0.5 * vz, vz])
        })
        .collect();
    RoadVibration { tones: if vz > 0.0 { tones } else { vec![] }, v_ref: 10.0 }
}

fn speed_grid(a_long: &Ease, v0: f64, duration: f64) -> Vec<f64> {
    let h = 0.01;
    let n = (duration / h).ceil() as usize + 2;
    let mut v = Vec::with_capacity(n);
    let mut x = v0;
    for k in 0..n {
        v.push(x);
        let t = k as f64 * h;
        x += h / 6.0 * G * (a_long.eval(t).0 + 4.0 * a_long.eval(t + h / 2.0).0 + a_long.eval(t + h).0);
    }
    v
}

/// Place turns where the speed allows them: a yaw-rate command of eased
/// pulses, |r| <= MAX_YAW_RATE and `|v| r <= MAX_LAT g` over each pulse.
fn turns(rng: &mut ChaCha8Rng, a_long: &Ease, v0: f64, duration: f64) -> Ease {
    let v = speed_grid(a_long, v0, duration);
    let idx = |t: f64| ((t / 0.01) as usize).min(v.len() - 1);
    let span = |a: f64, b: f64| {
        let s = &v[idx(a)..=idx(b)];
        (s.iter().cloned().fold(f64::MAX, f64::min), s.iter().cloned().fold(f64::MIN, f64::max))
    };
    let mut yaw = Ease::default();
    yaw.push(0.0, 0.0);
    let mut t = 0.5;
    while t < duration - 4.0 {
        t += uni(rng, [0.1, 0.7]);
        let vt = v[idx(t)];
        if vt < 2.5 {
            t += 0.5;
            continue;
        }
        let (dpsi, lat) =
            if vt < 9.0 { (uni(rng, [45.0, 95.0]), uni(rng, [0.35, MAX_LAT])) } else { (uni(rng, [15.0, 35.0]), uni(rng, [0.15, 0.45])) };
        let ramp = uni(rng, [0.5, 1.0]);
        let sign = if rng.gen_bool(0.5) { 1.0 } else { -1.0 };
        let mut peak = MAX_YAW_RATE.min((lat * G / vt).to_degrees());
        let mut ok = false;
        let mut hold = 0.0;
        for _ in 0..4 {
            if dpsi < peak * ramp {
                peak = dpsi / ramp;
            }
            hold = dpsi / peak - ramp;
            let (lo, hi) = span(t, t + 2.0 * ramp + hold);
            if lo < 2.0 {
                ok = false;
                break;
            }
            let cap = MAX_YAW_RATE.min((lat * G / hi).to_degrees());
            ok = peak <= cap + 1e-9;
            if ok {
                break;
            }
            peak = cap;
        }
        if !ok || t + 2.0 * ramp + hold > duration {
            t += 0.5;
            continue;
        }
        yaw.push(t, 0.0);
        yaw.push(t + ramp, sign * peak);
        if hold > 1e-6 {
            yaw.push(t + ramp + hold, sign * peak);
        }
        t += 2.0 * ramp + hold;
        yaw.push(t, 0.0);
    }
    yaw
}
