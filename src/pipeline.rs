//! The one core path: frames -> sample -> estimator -> estimate -> frames.
//!
//! With a speed source (`[speed]`, a [`SpeedDecoder`] built by the shell)
//! the vehicle's speed frames are decoded here too and handed to the
//! estimator: the latest speed is held (zero-order) and used at the
//! estimator's next update; older than `speed.timeout_s` (by frame
//! timestamps) it is not used and the estimate falls back to IMU only. The
//! measurement's noise (`[mekf] speed_sigma`) covers the bus latency times
//! the acceleration (20-80 ms at 2 m/s^2 is 0.04-0.16 m/s).
//!
//! The daemon and `gyrocomp replay` both drive a `Pipeline`; results are
//! pushed into a `Sink` (as ripgrep's searcher pushes into its sink), so the
//! pipeline never does I/O itself. No allocation per frame.

use crate::adis::{Assembler, Drop, InputCounters, Push, RawFrame};
use crate::config::{Config, OutputConfig};
use crate::dbcin::{DbcAssembler, DbcPlan};
use crate::estimator::{Estimate, Estimator};
use crate::output::{encode, Frames, StatusCounters};
use crate::speed::{SpeedCounts, SpeedDecoder};
use std::sync::Arc;

/// Receives what the pipeline produces.
pub trait Sink {
    /// One estimate and its output frames (stamped `est.t_us`): the four of
    /// every sample, and `EST_AID` unless `[output] aid_frame = false`.
    fn output(&mut self, est: &Estimate, frames: &Frames);
    /// A frame or sample was dropped (already counted in the pipeline).
    fn dropped(&mut self, _t_us: u64, _cause: Drop) {}
    /// Whether [`Sink::input`] is to be called (`replay --mcap`); asked once,
    /// before the run. False: the input frames are not handed over at all.
    fn wants_input(&self) -> bool {
        false
    }
    /// An input frame, handed over just before it is pushed into the
    /// pipeline (so before the outputs of the sample it closes).
    fn input(&mut self, _t_us: u64, _frame: &RawFrame<'_>) {}
}

/// A sink that keeps nothing (benchmarks, warm-ups).
pub struct NullSink;
impl Sink for NullSink {
    fn output(&mut self, _: &Estimate, _: &Frames) {}
}

/// The input path: the ADIS frames, or a DBC-described IMU's.
#[derive(Clone, Debug)]
enum Input {
    Adis(Assembler),
    Dbc(DbcAssembler),
}

impl Input {
    #[inline]
    fn push(&mut self, t_us: u64, frame: RawFrame<'_>) -> Push {
        match self {
            Input::Adis(a) => a.push(t_us, frame),
            Input::Dbc(a) => a.push(t_us, frame),
        }
    }
    fn counters(&self) -> &InputCounters {
        match self {
            Input::Adis(a) => &a.counters,
            Input::Dbc(a) => &a.counters,
        }
    }
}

pub struct Pipeline {
    assembler: Input,
    estimator: Estimator,
    ids: OutputConfig,
    /// Flags the shell adds to every status frame (bus silent, tx drops).
    pub extra_flags: u16,
    /// Samples per estimator mode (0 fusion, 1 blend, 2 gyro only).
    pub mode_samples: [u64; 3],
    period: f64,
    speed: Option<SpeedInput>,
    /// Rate check: the first sample's time, and periods counted since (by DATA_CNT).
    first_t_us: Option<u64>,
    last_t_us: u64,
    steps: u64,
    /// Samples whose frame time is before the previous sample's.
    backwards: u64,
    /// Any sample seen (for the span of a log too short to check the rate).
    any: bool,
}

/// The frame times' span needed before the configured rate is checked
/// against them, s.
pub const RATE_CHECK_S: f64 = 5.0;

/// What the pipeline and its estimator did, for the replay summary and the
/// daemon's status: a user must never see "fusion 0 %" without the reason.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Report {
    /// The default filter's counters (None in the paper's modes).
    pub mekf: Option<crate::estimator::mekf::MekfCounters>,
    /// The magnetometer in use (None: not decided yet, or paper mode).
    pub magnetometer: Option<bool>,
    /// The vehicle model in use (None in the paper's modes).
    pub vehicle: Option<bool>,
    /// The vehicle constraint's axes: their turn about the unit's z axis
    /// (deg, 0 unless the pull-aways turned them) and the pull-aways seen
    /// (None in the paper's modes).
    pub vehicle_axes: Option<(f64, u32)>,
    /// What every aid source of the default filter did at its last update
    /// tick (None in the paper's modes).
    #[serde(skip)]
    pub aid_now: Option<crate::estimator::mekf::AidReport>,
    /// The power-on speed hypotheses' outcome (None when they did not run).
    pub power_on: Option<crate::estimator::PowerOnSpeed>,
    /// Speed frames decoded and dropped (None without `[speed]`).
    #[serde(skip)]
    pub speed: Option<SpeedCounts>,
    /// The configured sample rate and the one the frame timestamps show
    /// (Hz), once 5 s of samples are in.
    pub rate: Option<(f64, f64)>,
    /// The frame times' span since the rate check last started, s (a check
    /// needs 5 s), None before any sample.
    pub span_s: Option<f64>,
    /// Samples whose frame time ran backwards (before the previous sample's).
    pub time_backwards: u64,
    /// Restarts from the prior after the filter's state went non-finite
    /// (flagged `RESYNC`; 0 with a config inside its ranges).
    pub nonfinite_restarts: u64,
    /// The reduced-axis filter's windows and its yaw-rate bias and sigma
    /// (deg/s) now (None with all six axes).
    pub reduced: Option<(crate::estimator::reduced::ReducedCounters, f64, f64)>,
}

impl Report {
    /// The rates when they disagree by more than 1 %.
    pub fn rate_mismatch(&self) -> Option<(f64, f64)> {
        self.rate.filter(|(c, m)| (m / c - 1.0).abs() > 0.01)
    }

    /// Human lines (for the replay summary).
    pub fn render(&self) -> String {
        let mut s = String::new();
        if self.nonfinite_restarts > 0 {
            s += &format!(
                "the filter's state went non-finite {} times: each restarted it from the prior (flagged FlagResync; nothing non-finite was published); a config beyond its physical ranges, or a sample beyond its part's\n",
                self.nonfinite_restarts
            );
        }
        if let Some(c) = &self.mekf {
            s += &format!(
                "standstill {:.1} s, re-levels {}, updates refused by the gate {:.1} s (longest run {:.1} s), velocity re-acquired {} times, restarts from the prior {}\n",
                c.rest_s, c.relevels, c.gated_s, c.refused_max_s, c.reacquired, c.restarts
            );
            s += &format!("rules that acted (ticks, or times for an event): {}\n", c.rules);
            s += &format!("aid sources (update ticks fused/refused, the worst refused test ratio): {}\n", c.aid);
            if let Some(a) = &self.aid_now {
                s += &format!("aid sources at the last update: {a}\n");
            }
            if let Some(q) = c.rest_never_found() {
                s += &format!(
                    "standstill never found: the quietest deviations were {q}; if the unit stood still, its noise or vibration is above them (a noisier part than the ADIS16448, seen in blocks of about 204.8 Hz, needs its own [rest])\n"
                );
            }
            s += &match self.vehicle {
                Some(true) => "vehicle model: on (no lateral/vertical velocity at the rear axle)\n".to_string(),
                Some(false) => {
                    "vehicle model: off (the motion is not a ground vehicle's: low-passed gravity and a bounded velocity)\n".to_string()
                }
                None => String::new(),
            };
            if let (Some((yaw, pulls)), true) = (self.vehicle_axes, c.reaxed > 0) {
                s += &format!(
                    "vehicle axes: turned {yaw:.1} deg about the unit's z axis to the way the car pulled away ({pulls} pull-aways after still periods): the unit is mounted turned; [mounting] rotation yaw {:.1} deg would say so (gyrocomp align)\n",
                    -yaw
                );
            }
            if let Some(p) = &self.power_on {
                s += &match p.ended {
                    Some((t, why)) => format!(
                        "power-on speed: {:.0} m/s kept (hypotheses 0-{:.0} m/s, ended at {:.1} s: {})\n",
                        p.speed_ms,
                        crate::estimator::hypotheses::SPEED_MAX,
                        t,
                        why.describe()
                    ),
                    None => format!(
                        "power-on speed: {:.0} m/s leads (hypotheses 0-{:.0} m/s, still running)\n",
                        p.speed_ms,
                        crate::estimator::hypotheses::SPEED_MAX
                    ),
                };
            }
            s += &match self.magnetometer {
                Some(true) => format!("magnetometer: used, disturbed {:.1} s (no heading updates then)\n", c.mag_disturbed_s),
                Some(false) => {
                    "magnetometer: not used (off in the config, absent, zero or implausible for Earth's field): yaw from the gyro alone\n"
                        .to_string()
                }
                None => String::new(),
            };
        }
        if let Some((c, b, sd)) = &self.reduced {
            s += &format!(
                "reduced axes: yaw-rate bias {b:.3} +- {sd:.3} deg/s, taught by {} standstill and {} straight-cruise windows of {} s (mode fusion on the sample that ends one); heading from the corrected yaw rate; roll, pitch and the x, y rates and biases not estimated (EST_AID Invalid* bits)\n",
                c.standstill_windows,
                c.cruise_windows,
                crate::estimator::reduced::WINDOW_S
            );
        }
        if let Some(sp) = &self.speed {
            let used = self.mekf.map(|c| c.speed_used_s).or(self.reduced.map(|r| r.0.speed_s)).unwrap_or(0.0);
            s += &format!(
                "speed frames: decoded {}, dropped wrong_dlc {} out_of_range {} implausible {}; speed used {:.1} s\n",
                sp.decoded, sp.wrong_dlc, sp.out_of_range, sp.implausible, used
            );
        }
        if self.time_backwards > 0 {
            s += &format!(
                "WARNING: the frame timestamps ran backwards {} times: the log's times are not one clock (logs joined, or a clock set back); dt comes from DATA_CNT and [input] rate_hz, and the rate is checked over the times since the last step back\n",
                self.time_backwards
            );
        }
        if let Some(span) = self.span_s.filter(|s| *s < RATE_CHECK_S) {
            s += &format!(
                "the configured rate was not checked against the frame timestamps: they span {span:.2} s, under the {RATE_CHECK_S} s a check needs\n"
            );
        }
        if let Some((c, m)) = self.rate_mismatch() {
            s += &format!("WARNING: the configured rate {c} Hz disagrees with the frame timestamps ({m:.3} Hz) by more than 1 %: dt comes from the configured rate ([input] rate_hz)\n");
        }
        s
    }
}

/// The vehicle's speed frames: decoder, the latest speed and its time.
struct SpeedInput {
    dec: SpeedDecoder,
    id: u32,
    extended: bool,
    timeout_us: u64,
    last: Option<(u64, f64)>,
    new: bool,
    counts: SpeedCounts,
}

/// The input path a config names. A DBC input whose plan was not built
/// (a config parsed from text, not loaded from its file) takes no frame:
/// every one is counted as `unknown_id`.
fn input(cfg: &Config) -> Input {
    if cfg.input.format.is_adis() {
        return Input::Adis(Assembler::new(cfg.profile(), cfg.input.ids));
    }
    let plan = cfg.input.plan.0.clone().unwrap_or_else(|| {
        Arc::new(DbcPlan {
            path: String::new(),
            msgs: Vec::new(),
            channels: [None; 7],
            assembly: crate::dbcin::Assembly::Window { us: 0 },
            rate_hz: cfg.input.rate_hz,
            temp_default: cfg.thermal.t0,
            lines: Vec::new(),
        })
    });
    Input::Dbc(DbcAssembler::new(plan))
}

impl Pipeline {
    /// A pipeline without a speed source.
    pub fn new(cfg: &Config) -> Pipeline {
        Pipeline::with_speed(cfg, None)
    }

    /// The pipeline `cfg` describes: with the vehicle's speed frames when
    /// `[speed]` is configured (its DBC read now; a DBC that cannot be read
    /// is the error).
    pub fn from_config(cfg: &Config) -> Result<Pipeline, crate::speed::SpeedError> {
        Ok(Pipeline::with_speed(cfg, crate::speed::load(cfg)?))
    }

    /// A pipeline that also decodes the vehicle's speed frames.
    pub fn with_speed(cfg: &Config, speed: Option<SpeedDecoder>) -> Pipeline {
        let p = cfg.profile();
        let speed = speed.map(|dec| {
            let (id, extended) = dec.id();
            SpeedInput {
                dec,
                id,
                extended,
                timeout_us: (cfg.speed.timeout_s * 1e6) as u64,
                last: None,
                new: false,
                counts: SpeedCounts::default(),
            }
        });
        Pipeline {
            assembler: input(cfg),
            estimator: Estimator::new(cfg),
            ids: cfg.output.clone(),
            extra_flags: 0,
            mode_samples: [0; 3],
            period: 1.0 / p.rate_hz,
            speed,
            first_t_us: None,
            last_t_us: 0,
            steps: 0,
            backwards: 0,
            any: false,
        }
    }

    /// Push one received frame.
    #[inline]
    pub fn push<S: Sink>(&mut self, t_us: u64, frame: RawFrame<'_>, sink: &mut S) {
        if let Some(sp) = &mut self.speed {
            if frame.id == sp.id && frame.extended == sp.extended && !frame.remote && !frame.fd {
                let r = sp.dec.decode(frame.data);
                sp.counts.record(&r);
                if let Ok(v) = r {
                    sp.last = Some((t_us, v));
                    sp.new = true;
                }
                return;
            }
        }
        match self.assembler.push(t_us, frame) {
            Push::Pending => {}
            Push::Dropped(d) => sink.dropped(t_us, d),
            Push::Sample(s) => {
                if self.any && s.t_us < self.last_t_us {
                    // the clock went back: the span so far says nothing; start over
                    self.backwards += 1;
                    self.first_t_us = None;
                }
                self.any = true;
                if self.first_t_us.is_none() || s.steps == 0 {
                    // (re)start the rate check at the first sample and at a counter restart
                    self.first_t_us = Some(s.t_us);
                    self.steps = 0;
                } else {
                    self.steps += s.steps as u64;
                }
                self.last_t_us = s.t_us;
                if let Some(sp) = &mut self.speed {
                    // held until it is older than the timeout (frame times)
                    let fresh = sp.last.filter(|(t, _)| s.t_us.saturating_sub(*t) <= sp.timeout_us).map(|(_, v)| v);
                    self.estimator.set_speed(fresh, sp.new);
                    sp.new = false;
                }
                let est = self.estimator.step(&s);
                self.mode_samples[(est.mode as usize).min(2)] += 1;
                let sc = StatusCounters::from(self.assembler.counters());
                let frames = encode(&est, &sc, &self.ids, self.extra_flags);
                sink.output(&est, &frames);
            }
        }
    }

    pub fn counters(&self) -> &InputCounters {
        self.assembler.counters()
    }

    /// What the estimator did (for summaries and the status).
    pub fn report(&self) -> Report {
        let span = self.first_t_us.map_or(0.0, |f| self.last_t_us.saturating_sub(f) as f64 * 1e-6);
        Report {
            mekf: self.estimator.mekf_counters(),
            magnetometer: self.estimator.magnetometer(),
            vehicle: self.estimator.mekf().map(|m| m.vehicle()),
            vehicle_axes: self.estimator.mekf().map(|m| m.vehicle_axes()),
            aid_now: self.estimator.mekf().map(|m| *m.aid_report()),
            power_on: self.estimator.power_on_speed(),
            speed: self.speed_counts(),
            rate: (span >= RATE_CHECK_S).then(|| (1.0 / self.period, self.steps as f64 / span)),
            span_s: self.any.then_some(span),
            time_backwards: self.backwards,
            nonfinite_restarts: self.estimator.nonfinite_restarts(),
            reduced: self.estimator.reduced().map(|r| (r.counters, r.bias(), r.bias_sigma())),
        }
    }

    /// Speed frames decoded and dropped by cause (None without a speed source).
    pub fn speed_counts(&self) -> Option<SpeedCounts> {
        self.speed.as_ref().map(|s| s.counts)
    }

    /// The speed frame's CAN ID and whether it is extended (for receive filters).
    pub fn speed_id(&self) -> Option<(u32, bool)> {
        self.speed.as_ref().map(|s| (s.id, s.extended))
    }

    pub fn estimator(&self) -> &Estimator {
        &self.estimator
    }

    pub fn estimator_mut(&mut self) -> &mut Estimator {
        &mut self.estimator
    }

    /// The ADIS input IDs (for receive filters; the DBC input's are in its plan).
    pub fn input_ids(&self) -> [u32; 4] {
        match &self.assembler {
            Input::Adis(a) => a.ids().all(),
            Input::Dbc(_) => [u32::MAX; 4],
        }
    }

    /// Seconds of samples per mode.
    pub fn mode_seconds(&self) -> [f64; 3] {
        self.mode_samples.map(|n| n as f64 * self.period)
    }
}
