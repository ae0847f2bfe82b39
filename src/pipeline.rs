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
use crate::estimator::{Estimate, Estimator};
use crate::output::{encode, OutFrame, StatusCounters};
use crate::speed::{SpeedCounts, SpeedDecoder};

/// Receives what the pipeline produces.
pub trait Sink {
    /// One estimate and its four output frames (stamped `est.t_us`).
    fn output(&mut self, est: &Estimate, frames: &[OutFrame; 4]);
    /// A frame or sample was dropped (already counted in the pipeline).
    fn dropped(&mut self, _t_us: u64, _cause: Drop) {}
}

/// A sink that keeps nothing (benchmarks, warm-ups).
pub struct NullSink;
impl Sink for NullSink {
    fn output(&mut self, _: &Estimate, _: &[OutFrame; 4]) {}
}

pub struct Pipeline {
    assembler: Assembler,
    estimator: Estimator,
    ids: OutputConfig,
    /// Flags the shell adds to every status frame (bus silent, tx drops).
    pub extra_flags: u16,
    /// Samples per estimator mode (0 fusion, 1 blend, 2 gyro only).
    pub mode_samples: [u64; 3],
    period: f64,
    speed: Option<SpeedInput>,
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

impl Pipeline {
    /// A pipeline without a speed source.
    pub fn new(cfg: &Config) -> Pipeline {
        Pipeline::with_speed(cfg, None)
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
            assembler: Assembler::new(p.clone(), cfg.input.ids),
            estimator: Estimator::new(cfg),
            ids: cfg.output.clone(),
            extra_flags: 0,
            mode_samples: [0; 3],
            period: 1.0 / p.rate_hz,
            speed,
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
                if let Some(sp) = &mut self.speed {
                    // held until it is older than the timeout (frame times)
                    let fresh = sp.last.filter(|(t, _)| s.t_us.saturating_sub(*t) <= sp.timeout_us).map(|(_, v)| v);
                    self.estimator.set_speed(fresh, sp.new);
                    sp.new = false;
                }
                let est = self.estimator.step(&s);
                self.mode_samples[(est.mode as usize).min(2)] += 1;
                let sc = StatusCounters::from(&self.assembler.counters);
                let frames = encode(&est, &sc, &self.ids, self.extra_flags);
                sink.output(&est, &frames);
            }
        }
    }

    pub fn counters(&self) -> &InputCounters {
        &self.assembler.counters
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

    /// The input IDs (for receive filters).
    pub fn input_ids(&self) -> [u32; 4] {
        self.assembler.ids().all()
    }

    /// Seconds of samples per mode.
    pub fn mode_seconds(&self) -> [f64; 3] {
        self.mode_samples.map(|n| n as f64 * self.period)
    }
}
