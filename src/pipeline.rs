//! The one core path: frames -> sample -> estimator -> estimate -> frames.
//!
//! The daemon and `gyrocomp replay` both drive a `Pipeline`; results are
//! pushed into a `Sink` (as ripgrep's searcher pushes into its sink), so the
//! pipeline never does I/O itself. No allocation per frame.

use crate::adis::{Assembler, Drop, InputCounters, Push, RawFrame};
use crate::config::{Config, OutputConfig};
use crate::estimator::{Estimate, Estimator};
use crate::output::{encode, OutFrame, StatusCounters};

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
}

impl Pipeline {
    pub fn new(cfg: &Config) -> Pipeline {
        let p = cfg.profile();
        Pipeline {
            assembler: Assembler::new(p.clone(), cfg.input.ids),
            estimator: Estimator::new(cfg),
            ids: cfg.output.clone(),
            extra_flags: 0,
            mode_samples: [0; 3],
            period: 1.0 / p.rate_hz,
        }
    }

    /// Push one received frame.
    #[inline]
    pub fn push<S: Sink>(&mut self, t_us: u64, frame: RawFrame<'_>, sink: &mut S) {
        match self.assembler.push(t_us, frame) {
            Push::Pending => {}
            Push::Dropped(d) => sink.dropped(t_us, d),
            Push::Sample(s) => {
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
