//! The `smooth` and `crawl` scenarios: driving that gives an IMU no stop.
//!
//! Both use the road kinematics ([`super::road`]) with the sensor 0.9 m
//! ahead of the rear axle, as `urban` does.
//!
//! - `smooth`: a car that drives smoothly (a good road, a damped mount, an
//!   electric car, a tram): its ride vibration 0-0.3 of the comma2k19 car's
//!   (`Ranges::ride_scale`), road vibration and engine tones as small, a
//!   cruise speed drawn per seed in 2..30 m/s (log-uniform), long holds at
//!   constant speed, gentle speed changes of 0.02-0.06 g to targets within
//!   +-30 % of the cruise speed, long gentle curves (0.02-0.1 g, at most
//!   10 deg/s), grades of a few degrees as sines of the distance, and **no
//!   stop** after the parked start's pull-away (`power_on_moving`: already
//!   at the cruise speed). `hard` keeps the smooth drive for its first
//!   `HARD_FROM_S` and then drives hard without a stop until the end:
//!   sustained 0.3 g turns of 15-25 s, 0.2-0.3 g accelerations and
//!   brakings, 0.65-0.8 g emergency brakes and swerves, speeds 3-40 m/s.
//! - `crawl`: 0.5-3 m/s (a traffic jam, a tractor, a forklift) with
//!   accelerations of 0.02-0.08 g and turns of up to 15 deg/s; half of the
//!   seeds (drawn) stop every 20-90 s for 3-20 s, the others never stop
//!   after the pull-away.

use super::motion::{Ease, MotionSpec, G};
use super::road::RoadSpec;
use super::scenario::{thermal, uni, Ranges};
use super::urban::{ride_vibration, slow_sine, Long};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// `smooth --hard`: the smooth drive lasts this long before the hard one, s.
pub const HARD_FROM_S: f64 = 200.0;
/// Highest yaw rate of a smooth curve, deg/s.
const SMOOTH_MAX_YAW_RATE: f64 = 10.0;
/// Highest yaw rate of a crawl's turn, deg/s.
const CRAWL_MAX_YAW_RATE: f64 = 15.0;

/// A turn planned inside a constant-speed hold: starts at `t`, eases to
/// `peak` deg/s over `ramp`, holds it `hold` s, eases back over `ramp`.
#[derive(Clone, Copy, Debug)]
struct Turn {
    t: f64,
    ramp: f64,
    hold: f64,
    peak: f64,
}

/// The longitudinal plan and the turns placed in its constant-speed holds.
struct Drive<'a> {
    rng: &'a mut ChaCha8Rng,
    p: Long,
    turns: Vec<Turn>,
}

impl Drive<'_> {
    /// Ease the acceleration to zero over `ramp` and hold the speed for
    /// `hold` s; with `lat` (g) and a heading change `dpsi` (deg), a turn
    /// of that lateral acceleration inside the hold (its rate capped at
    /// `max_rate` deg/s, its length at the hold's).
    fn cruise(&mut self, ramp: f64, hold: f64, turn: Option<(f64, f64, f64)>) {
        self.p.seg(0.0, ramp, hold);
        let Some((lat, dpsi, max_rate)) = turn else { return };
        let v = self.p.v.abs();
        if v < 0.3 || hold < 3.0 {
            return;
        }
        let t0 = self.p.t - hold;
        let tr = uni(self.rng, [1.0, 2.5]).min(0.3 * hold);
        let mut peak = max_rate.min((lat * G / v).to_degrees());
        // the turn fits into the hold: 2 ramps and its own hold
        let room = hold - 2.0 * tr - 0.5;
        let mut th = dpsi / peak - tr;
        if th < 0.0 {
            peak = dpsi / tr;
            th = 0.0;
        }
        if th > room {
            th = room.max(0.0);
        }
        let start = t0 + 0.25 + uni(self.rng, [0.0, (room - th).max(0.0)]);
        let sign = if self.rng.gen_bool(0.5) { 1.0 } else { -1.0 };
        self.turns.push(Turn { t: start, ramp: tr, hold: th, peak: sign * peak });
    }

    /// Reach `target` m/s at `mag` g with ramps drawn in `ramps`.
    fn change(&mut self, target: f64, mag: f64, ramps: [f64; 2]) {
        let (r1, r2) = (uni(self.rng, ramps), uni(self.rng, ramps));
        self.p.reach(target, mag, r1, r2);
    }

    fn yaw_rate(&self) -> Ease {
        let mut e = Ease::default();
        e.push(0.0, 0.0);
        for t in &self.turns {
            let last = e.last().0;
            let t0 = t.t.max(last + 1e-3);
            e.push(t0, 0.0);
            e.push(t0 + t.ramp, t.peak);
            if t.hold > 1e-6 {
                e.push(t0 + t.ramp + t.hold, t.peak);
            }
            e.push(t0 + 2.0 * t.ramp + t.hold, 0.0);
        }
        e
    }
}

fn sign(rng: &mut ChaCha8Rng) -> f64 {
    if rng.gen_bool(0.5) {
        1.0
    } else {
        -1.0
    }
}

/// The smooth drive from `d.p.t` to `until` around the cruise speed `vc`.
fn smooth_phase(d: &mut Drive, vc: f64, until: f64) {
    while d.p.t < until {
        match d.rng.gen_range(0..3) {
            // a gentle speed change, within +-30 % of the cruise speed
            0 => {
                let target = (vc * uni(d.rng, [0.7, 1.3])).clamp(2.0, 30.0);
                let mag = uni(d.rng, [0.02, 0.06]);
                d.change(target, mag, [2.0, 4.0]);
            }
            // a long gentle curve at constant speed
            1 => {
                let hold = uni(d.rng, [15.0, 60.0]);
                let turn = (uni(d.rng, [0.02, 0.1]), uni(d.rng, [10.0, 90.0]), SMOOTH_MAX_YAW_RATE);
                d.cruise(2.0, hold, Some(turn));
            }
            // a straight at constant speed
            _ => {
                let hold = uni(d.rng, [10.0, 60.0]);
                d.cruise(2.0, hold, None);
            }
        }
    }
}

/// Hard driving from `d.p.t` to `until`, never below 3 m/s.
fn hard_phase(d: &mut Drive, until: f64) {
    let (lo, hi) = (3.0, 40.0);
    while d.p.t < until {
        let v = d.p.v;
        match d.rng.gen_range(0..5) {
            // a long acceleration or braking, 0.2-0.3 g
            0 => {
                let target = if v < 0.5 * (lo + hi) { uni(d.rng, [v + 5.0, hi]) } else { uni(d.rng, [lo + 5.0, v - 5.0]) };
                let mag = uni(d.rng, [0.2, 0.3]);
                d.change(target.clamp(lo + 2.0, hi), mag, [0.8, 1.5]);
            }
            // a sustained turn of 0.3 g for 15-25 s
            1 => {
                let len = uni(d.rng, [15.0, 25.0]);
                let r = (0.3 * G / v.max(lo)).to_degrees().min(45.0);
                d.cruise(1.0, len + 3.0, Some((0.3, r * len, 45.0)));
            }
            // an emergency brake of 0.65-0.8 g from speed
            2 if v > 16.0 => {
                let target = uni(d.rng, [lo + 2.0, v - 10.0]);
                let mag = uni(d.rng, [0.65, 0.8]);
                d.change(target, mag, [0.3, 0.6]);
            }
            // a swerve: 0.65-0.8 g one way, then the other
            3 => {
                let lead = uni(d.rng, [1.0, 3.0]);
                d.cruise(0.8, lead, None);
                let g = uni(d.rng, [0.65, 0.8]);
                let peak = (g * G / v.max(lo)).to_degrees().min(45.0) * sign(d.rng);
                let (ramp, hold) = (uni(d.rng, [0.3, 0.6]), uni(d.rng, [0.5, 1.5]));
                let t = d.p.t;
                d.turns.push(Turn { t, ramp, hold, peak });
                d.turns.push(Turn { t: t + 2.0 * ramp + hold + 1e-3, ramp, hold, peak: -peak });
                d.cruise(0.5, 4.0 * ramp + 2.0 * hold + 1.0, None);
            }
            _ => {
                let hold = uni(d.rng, [3.0, 10.0]);
                d.cruise(1.0, hold, None);
            }
        }
    }
}

/// The crawl from `d.p.t` to `until`: 0.5-3 m/s, with stops when `stops`.
fn crawl_phase(d: &mut Drive, until: f64, stops: bool) {
    let mut next_stop = d.p.t + uni(d.rng, [20.0, 90.0]);
    while d.p.t < until {
        if stops && d.p.t >= next_stop {
            let mag = uni(d.rng, [0.03, 0.1]);
            d.change(0.0, mag, [0.8, 1.5]);
            let stand = uni(d.rng, [3.0, 20.0]);
            d.p.seg(0.0, 0.5, stand);
            let (target, mag) = (uni(d.rng, [0.5, 3.0]), uni(d.rng, [0.03, 0.08]));
            d.change(target, mag, [0.8, 1.5]);
            next_stop = d.p.t + uni(d.rng, [20.0, 90.0]);
            continue;
        }
        if d.rng.gen_bool(0.5) {
            let (target, mag) = (uni(d.rng, [0.5, 3.0]), uni(d.rng, [0.02, 0.08]));
            d.change(target, mag, [0.8, 2.0]);
        } else {
            let hold = uni(d.rng, [5.0, 30.0]);
            let turn = d.rng.gen_bool(0.6).then(|| (0.08, uni(d.rng, [20.0, 90.0]), CRAWL_MAX_YAW_RATE));
            d.cruise(1.0, hold, turn);
        }
    }
}

/// The road (grades, camber, unevenness), the vibration and the temperature
/// every smooth or crawling drive shares.
fn road(rng: &mut ChaCha8Rng, r: &Ranges, duration: f64, a_long: Ease, yaw_rate: Ease, v0: f64, start: f64) -> MotionSpec {
    let yaw0 = rng.gen_range(-180.0..180.0);
    let grade = vec![slow_sine(rng, [1.5, 3.0], [300.0, 900.0]), slow_sine(rng, [0.5, 1.5], [80.0, 250.0])];
    let road_pitch = vec![slow_sine(rng, [0.02, 0.1], [4.0, 15.0])];
    let road_roll = vec![slow_sine(rng, [0.5, 1.5], [50.0, 300.0]), slow_sine(rng, [0.02, 0.1], [3.0, 12.0])];
    let vibration = ride_vibration(rng, r);
    let thermal = thermal(rng, r);
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
        roll_per_lat: -uni(rng, [3.0, 5.0]),
        pitch_per_long: uni(rng, [2.5, 4.0]),
        bumps: vec![],
        ride_roll: vec![],
        ride_pitch: vec![],
        thermal,
        manoeuvre_start: start.min(duration),
        road: Some(RoadSpec { yaw_rate, grade, road_pitch, road_roll, lever_arm: r.lever_arm, vibration }),
    }
}

/// The parked start: stand 4-6 s, then pull away gently to `target`.
fn pull_away(d: &mut Drive, target: f64, mag: [f64; 2]) {
    let stand = uni(d.rng, [4.0, 6.0]);
    d.p.seg(0.0, 0.5, stand);
    let mag = uni(d.rng, mag);
    d.change(target, mag, [1.5, 3.0]);
}

/// Build the `smooth` motion.
pub fn smooth(rng: &mut ChaCha8Rng, r: &Ranges, duration: f64, power_on_moving: bool, hard: bool) -> MotionSpec {
    let vc = (2.0f64.ln() + rng.gen::<f64>() * (30.0f64 / 2.0).ln()).exp();
    let v0 = if power_on_moving { vc } else { 0.0 };
    let mut d = Drive { p: Long::new(v0), turns: Vec::new(), rng };
    if !power_on_moving {
        pull_away(&mut d, vc, [0.04, 0.1]);
    }
    let smooth_until = if hard { HARD_FROM_S.min(duration) } else { duration };
    smooth_phase(&mut d, vc, smooth_until);
    if hard {
        hard_phase(&mut d, duration);
    }
    finish(d, r, duration, v0, if hard { HARD_FROM_S } else { 10.0 })
}

/// Build the `crawl` motion; whether it stops is drawn per seed.
pub fn crawl(rng: &mut ChaCha8Rng, r: &Ranges, duration: f64, power_on_moving: bool) -> MotionSpec {
    let stops = rng.gen_bool(0.5);
    let v0 = if power_on_moving { uni(rng, [0.5, 3.0]) } else { 0.0 };
    let mut d = Drive { p: Long::new(v0), turns: Vec::new(), rng };
    if !power_on_moving {
        let target = uni(d.rng, [0.5, 3.0]);
        pull_away(&mut d, target, [0.03, 0.08]);
    }
    crawl_phase(&mut d, duration, stops);
    finish(d, r, duration, v0, 10.0)
}

fn finish(mut d: Drive, r: &Ranges, duration: f64, v0: f64, start: f64) -> MotionSpec {
    let end = d.p.t + 1.0;
    d.p.a.push(end, 0.0);
    let yaw_rate = d.yaw_rate();
    road(d.rng, r, duration, d.p.a, yaw_rate, v0, start)
}
