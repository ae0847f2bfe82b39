//! Power-on speed hypotheses of the default filter.
//!
//! A vehicle computer may power on (or its daemon restart) while the car is
//! driving. Without wheel speeds nothing tells the filter how fast: it
//! starts at zero speed with a wide sigma, and a car that is really doing
//! 13 m/s then turns. The velocity error, fixed in the navigation frame,
//! becomes a lateral velocity in the turn, and the filter (whose bias is
//! still unknown) reads part of it as roll and bias: roll and pitch errors
//! of 20-35 deg before the first stop on the simulated urban drives. The
//! same filter started within +-5 m/s of the true speed stays under 2 deg.
//!
//! So at power-on the filter runs as a bank: the published filter (zero
//! speed, `init_speed_sigma`, the filter as it always started) and one copy
//! per forward speed `SPEED_STEP`, `2 SPEED_STEP`, ... up to `SPEED_MAX`,
//! each with `SPEED_STEP / 2` sigma. They see the same samples and make the
//! same decisions (rest, vehicle, policy) from the measurements; each
//! scores the measurements by its own prediction (the log-likelihood of the
//! innovations, `Mekf::log_likelihood`). The best one is published; another
//! replaces it when it leads by `SWITCH_NATS`. The bank ends, keeping the
//! best, at the first standstill that every plausible copy takes for one
//! (the speed is then known to be zero; a copy whose own velocity refuses
//! the stop takes it for a smooth cruise, and the quiet IMU cannot tell
//! them apart), after `BANK_S` seconds, or when the unit turns out not to
//! be a vehicle. A zero-velocity update is not scored: it is what a copy
//! assumes, not a measurement every copy shares.
//!
//! With `vehicle = "auto"` the bank also runs one copy as a free unit from
//! power-on. A hand whose first seconds look like a car body's is taken for
//! a car until its rates say otherwise, and the vehicle model meanwhile
//! learns a bias and a tilt from the hand's motion (broad-14 powered on at
//! 60 s: roll / pitch RMS 0.392 / 0.277 against VQF's 0.354 / 0.231). When
//! the vehicle model is left while the bank runs, that copy is published:
//! from then on the filter is, to the bit, one configured `vehicle = false`
//! (0.351 / 0.231). Without it (vehicle configured, wheel speeds) the
//! zero-speed filter is kept.
//!
//! The hypotheses are forward speeds, and so is a car powered on while
//! driving: it does not reverse faster than `REVERSE_MAX`. A hypothesis
//! whose forward speed has run below that has a pitch error integrated into
//! its speed (`g dθ` per second: IMU only, nothing else tells them apart
//! between turns), and is never published while a plausible one runs: the
//! likeliest plausible one is, without the `SWITCH_NATS` lead (the
//! comma2k19 car powered on 5 s into its drive: the zero-speed filter kept
//! by its likelihood ran to -20 m/s with its pitch 13 deg off).
//! It costs one step per filter while it runs; no allocation per step.

use super::mekf::{Mekf, Rule};
use super::{PowerOnSpeed, StepIn};

/// Spacing of the forward-speed hypotheses, m/s (each has half of it as
/// its sigma), and the largest (130 km/h).
pub const SPEED_STEP: f64 = 6.0;
pub const SPEED_MAX: f64 = 36.0;
/// Number of alternative hypotheses (besides the published zero-speed one).
const ALTERNATIVES: usize = (SPEED_MAX / SPEED_STEP) as usize;
/// A hypothesis replaces the published one when its log-likelihood is
/// larger by this much (a likelihood ratio of e^10, 22 000: on a parked or
/// straight start the hypotheses wander within a few nats of each other;
/// powered on moving, the first turn puts tens to hundreds between them).
pub const SWITCH_NATS: f64 = 10.0;
/// The bank ends this long after power-on at the latest, s.
pub const BANK_S: f64 = 60.0;
/// The fastest a car powered on while driving is taken to reverse, m/s
/// (18 km/h: reversing out of a space or a drive is slower).
pub const REVERSE_MAX: f64 = 5.0;

/// Whether the filter's forward speed is one a car powered on while
/// driving can have (`REVERSE_MAX`).
fn plausible(m: &Mekf) -> bool {
    m.forward_speed() >= -REVERSE_MAX
}

/// The alternatives to the published filter, while the bank runs.
#[derive(Clone, Debug)]
pub struct SpeedHypotheses {
    alternatives: Vec<Mekf>,
    /// With `vehicle = "auto"`: the filter run as a free unit from power-on,
    /// published if the unit turns out not to be a vehicle while the bank
    /// runs (what the vehicle model did meanwhile is void).
    free: Option<Mekf>,
    /// Power-on speed of each hypothesis, m/s: `[0]` the published filter's,
    /// `[i + 1]` that of `alternatives[i]`.
    speeds: Vec<f64>,
}

/// Why the bank ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum BankEnd {
    /// The first standstill: the speed is zero, whatever it was.
    Standstill,
    /// `BANK_S` after power-on.
    Timeout,
    /// The motion is not a ground vehicle's.
    NotVehicle,
}

impl BankEnd {
    pub fn describe(self) -> &'static str {
        match self {
            BankEnd::Standstill => "first standstill",
            BankEnd::Timeout => "time limit",
            BankEnd::NotVehicle => "not a vehicle",
        }
    }
}

/// What the bank did on a sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BankStep {
    /// Another hypothesis is published from this sample on.
    pub switched: bool,
    /// The bank has ended (the published filter is the one kept), and why.
    pub ended: Option<BankEnd>,
}

impl SpeedHypotheses {
    /// The bank for a filter just started (`published`); it starts scoring.
    pub fn new(published: &mut Mekf) -> SpeedHypotheses {
        published.set_scoring(true);
        let free = published.free_unit_copy();
        let mut alternatives = Vec::with_capacity(ALTERNATIVES);
        let mut speeds = vec![0.0];
        for k in 1..=ALTERNATIVES {
            let u = k as f64 * SPEED_STEP;
            let mut m = published.clone();
            m.set_speed_hypothesis(u, 0.5 * SPEED_STEP);
            alternatives.push(m);
            speeds.push(u);
        }
        SpeedHypotheses { alternatives, free, speeds }
    }

    /// The power-on speed of the hypothesis published now, m/s.
    pub fn published_speed(&self) -> f64 {
        self.speeds[0]
    }

    /// Step every alternative on the sample the published filter has just
    /// stepped on (`resync`: the facade's resync of it, the gap in
    /// seconds, applied to each first), then publish the best and decide whether the bank ends.
    pub fn step(&mut self, s: &StepIn, resync: Option<f64>, published: &mut Mekf) -> BankStep {
        for m in self.alternatives.iter_mut().chain(self.free.as_mut()) {
            if let Some(gap) = resync {
                m.resync(gap);
            }
            m.step(s);
        }
        // an implausible published filter gives way to the likeliest
        // plausible alternative, without the lead
        let floor = if plausible(published) { published.log_likelihood() + SWITCH_NATS } else { f64::NEG_INFINITY };
        let (mut best, mut best_ll) = (usize::MAX, floor);
        for (i, m) in self.alternatives.iter().enumerate() {
            if plausible(m) && m.log_likelihood() > best_ll {
                best = i;
                best_ll = m.log_likelihood();
            }
        }
        let mut switched = best != usize::MAX;
        if switched {
            std::mem::swap(published, &mut self.alternatives[best]);
            self.speeds.swap(0, best + 1);
        }
        if !published.vehicle() {
            // not a car: the hypotheses were a car's speeds, and what the
            // vehicle model taught meanwhile (a bias, a tilt that took a
            // hand's motion for a car's) is void; the filter run as a free
            // unit from power-on is what it should have been
            if let Some(free) = self.free.as_mut() {
                std::mem::swap(published, free);
                self.speeds[0] = 0.0;
                return BankStep { switched: true, ended: Some(BankEnd::NotVehicle) };
            }
            if self.speeds[0] != 0.0 {
                if let Some(i) = self.speeds.iter().position(|u| *u == 0.0) {
                    std::mem::swap(published, &mut self.alternatives[i - 1]);
                    self.speeds.swap(0, i);
                    switched = true;
                }
            }
            published.set_scoring(false);
            return BankStep { switched, ended: Some(BankEnd::NotVehicle) };
        }
        // A standstill ends the bank only when every plausible copy takes
        // it for one: a copy whose velocity refuses it (a cruise at its
        // speed) is as likely until evidence separates them (a turn, the
        // time limit). The zero-speed copy of a car powered on in a smooth
        // cruise found its "first standstill" 1.8 s after power-on and ended
        // the bank at 0 m/s (`smooth --power-on-moving` seeds 2, 5, 9).
        let standing = |m: &Mekf| m.last_step().1 & super::flags::STANDSTILL != 0;
        let all_stand = self.alternatives.iter().all(|m| !plausible(m) || standing(m));
        let ended = if standing(published) && all_stand {
            Some(BankEnd::Standstill)
        } else if s.t >= BANK_S {
            Some(BankEnd::Timeout)
        } else {
            None
        };
        if ended.is_some() {
            published.set_scoring(false);
        }
        BankStep { switched, ended }
    }
}

/// The default filter as the facade holds it: the published filter and,
/// while they run, the power-on speed hypotheses. The bank owns every copy;
/// which one is published is its own business (the facade reads the
/// published one, never swaps it).
#[derive(Clone, Debug)]
pub struct MekfBank {
    published: Mekf,
    hypotheses: Option<Box<SpeedHypotheses>>,
    power_on: Option<PowerOnSpeed>,
}

impl MekfBank {
    pub fn new(m: Mekf) -> MekfBank {
        MekfBank { published: m, hypotheses: None, power_on: None }
    }

    /// The published filter.
    pub fn filter(&self) -> &Mekf {
        &self.published
    }

    /// The published filter, to configure between samples (its speed, its
    /// vehicle axes).
    pub fn filter_mut(&mut self) -> &mut Mekf {
        &mut self.published
    }

    /// The hypotheses' outcome (None: not run).
    pub fn power_on(&self) -> Option<PowerOnSpeed> {
        self.power_on
    }

    /// Start the published filter on the first sample (`Mekf::start`) and,
    /// unless the unit is known not to be a car or its wheels will say how
    /// fast, the hypotheses: a car may be moving at power-on.
    pub fn start(&mut self, accel: &[f64; 3], magn: &[f64; 3], bias: [f64; 3], bias_sigma: [f64; 3], known: bool) {
        let m = &mut self.published;
        m.start(accel, magn, bias, bias_sigma, known);
        self.hypotheses = (m.vehicle() && !m.speed_aided() && m.on(Rule::SpeedHypotheses)).then(|| Box::new(SpeedHypotheses::new(m)));
        self.power_on = self.hypotheses.as_ref().map(|_| PowerOnSpeed { speed_ms: 0.0, ended: None });
    }

    /// One sample, after a counter gap of `gap` seconds if any: every copy
    /// steps, the best is published. Returns what the published filter's
    /// step returned (mode, flags, `|a| / g0`).
    pub fn step(&mut self, inp: &StepIn, gap: Option<f64>) -> (u8, u16, f64) {
        let m = &mut self.published;
        if let Some(g) = gap {
            m.resync(g);
        }
        let mut out = m.step(inp);
        if let Some(h) = self.hypotheses.as_mut() {
            let b = h.step(inp, gap, m);
            if b.switched {
                // another filter is published: what its step returned
                out = m.last_step();
            }
            self.power_on = Some(PowerOnSpeed { speed_ms: h.published_speed(), ended: b.ended.map(|e| (inp.t, e)) });
            if b.ended.is_some() {
                self.hypotheses = None;
            }
        }
        out
    }
}
