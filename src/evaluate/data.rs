//! One run to score: a `gyrocomp simulate` directory loaded from disk, or a
//! seed simulated in memory (the same frames `simulate` would write), with
//! its truth and true bias; and the estimator replayed over its input.

use crate::adis::{Assembler, Push, RawFrame, Sample};
use crate::config::Config;
use crate::estimator::Estimate;
use crate::output::Frames;
use crate::pipeline::{Pipeline, Sink};
use crate::replay::{replay_files, ReplayFiles};
use crate::sim::model::SensorModel;
use crate::sim::{self, read_bias, read_info, read_truth, ScenarioInfo, SimOptions, TruthRow};
use std::path::{Path, PathBuf};

/// Everything scoring needs about one run.
pub struct RunData {
    pub info: ScenarioInfo,
    pub model: SensorModel,
    pub truth: Vec<TruthRow>,
    /// True additive gyro bias per sample, deg/s.
    pub bias: Vec<[f64; 3]>,
    /// The truth's speed per sample, m/s (road scenarios: `vehicle.csv`).
    pub speed: Option<Vec<f64>>,
    /// The run's own calibrated config (thermal curve known to +-thermal_error).
    pub unit_config: Option<Config>,
    source: Source,
}

/// One replay of the estimator over a run.
struct Replayed {
    est: Vec<Estimate>,
    /// Seconds in fusion, blend, gyro only.
    mode_seconds: [f64; 3],
    /// The estimator's magnetometer decision (None: undecided, or a mode without one).
    magnetometer: Option<bool>,
}

enum Source {
    Log(PathBuf),
    /// The whole bus of an in-memory run (IMU frames and wheel speeds), and
    /// the DBC text that describes its wheel speeds (urban).
    Frames(Vec<sim::BusFrame>, Option<&'static str>),
}

impl RunData {
    /// Load a `gyrocomp simulate` directory.
    pub fn load(dir: &Path) -> Result<RunData, String> {
        let info = read_info(&dir.join("scenario.toml"))?;
        let model = SensorModel::load(&dir.join("sensor.toml"))?;
        let truth = read_truth(&dir.join("truth.csv"))?;
        let bias: Vec<[f64; 3]> = read_bias(&dir.join("bias.csv"))?.into_iter().map(|(_, b)| b).collect();
        if bias.len() != truth.len() {
            return Err(format!("{}: bias.csv and truth.csv differ in length", dir.display()));
        }
        let unit_config = Config::load(&dir.join("config.toml")).ok();
        let vehicle = dir.join("vehicle.csv");
        let speed = if vehicle.is_file() { Some(sim::read_vehicle_speed(&vehicle)?) } else { None };
        if speed.as_ref().is_some_and(|v| v.len() != truth.len()) {
            return Err(format!("{}: vehicle.csv and truth.csv differ in length", dir.display()));
        }
        Ok(RunData { info, model, truth, bias, speed, unit_config, source: Source::Log(dir.join("imu.log")) })
    }

    /// Simulate in memory.
    pub fn simulate(o: &SimOptions) -> Result<RunData, String> {
        let run = sim::prepare(o)?;
        let mut truth = Vec::new();
        let mut bias = Vec::new();
        let mut frames = Vec::new();
        let road = run.spec.road.is_some();
        let mut speed = Vec::new();
        for b in sim::bus(&run, o.seed) {
            if road {
                speed.push(b.truth.speed);
            }
            let tr = &b.truth;
            truth.push(TruthRow { t: tr.t, att: [tr.roll, tr.pitch, tr.yaw], rate: tr.rate, f: tr.f, temp: tr.temp });
            bias.push(b.measured.bias);
            frames.extend_from_slice(b.frames());
        }
        let unit_config = Some(Config::parse(&run.config_toml, "simulated unit").map_err(|e| e.to_string())?);
        let dbc = run.wheel.is_some().then_some(sim::wheel::EXAMPLE_DBC);
        let speed = road.then_some(speed);
        Ok(RunData { info: run.info, model: run.model, truth, bias, speed, unit_config, source: Source::Frames(frames, dbc) })
    }

    /// [`super::still_moving_s`] of `est` against the run's truth speed; none
    /// without a vehicle truth.
    pub fn still_moving(&self, est: &[Estimate]) -> Option<f64> {
        self.speed.as_ref().map(|v| super::still_moving_s(est, v, 1.0 / self.info.rate_hz))
    }

    /// Run the estimator over the run's input.
    pub fn estimates(&self, cfg: &Config) -> Result<(Vec<Estimate>, [f64; 3]), String> {
        self.estimates_with(cfg, |_| {})
    }

    /// `estimates`, with `prepare` run on the estimator before the first
    /// sample (a saved bias as the prior, say; in-memory runs only).
    pub fn estimates_with(
        &self,
        cfg: &Config,
        prepare: impl FnOnce(&mut crate::estimator::Estimator),
    ) -> Result<(Vec<Estimate>, [f64; 3]), String> {
        self.replay(cfg, prepare).map(|r| (r.est, r.mode_seconds))
    }

    /// [`Self::estimates`], and whether the estimator used the magnetometer
    /// (configured, and not found absent or implausible in the run), as
    /// `evaluate --realdata` decides it for the peers: VQF and Fusion fuse
    /// the magnetometer when ours did.
    pub fn estimates_and_magnetometer(&self, cfg: &Config) -> Result<(Vec<Estimate>, [f64; 3], bool), String> {
        let r = self.replay(cfg, |_| {})?;
        Ok((r.est, r.mode_seconds, crate::reference::magnetometer_configured(cfg) && r.magnetometer.unwrap_or(true)))
    }

    /// The samples the estimator is given, decoded from the run's frames
    /// with `cfg`'s profile and CAN IDs (the frames of other IDs, the wheel
    /// speeds, are not samples): the peers' input.
    pub fn samples(&self, cfg: &Config) -> Result<Vec<Sample>, String> {
        match &self.source {
            Source::Log(p) => {
                let name = p.display().to_string();
                let f = std::fs::File::open(p).map_err(|e| format!("{name}: {e}"))?;
                Ok(crate::reference::decode(std::io::BufReader::new(f), cfg, &name)?.samples)
            }
            Source::Frames(fr, _) => {
                let mut asm = Assembler::new(cfg.profile(), cfg.input.ids);
                let mut out = Vec::with_capacity(self.truth.len());
                for f in fr {
                    if let Push::Sample(s) = asm.push(f.t_us, RawFrame::classic(f.id, &f.data)) {
                        out.push(s);
                    }
                }
                if out.is_empty() {
                    return Err(format!("simulated run (seed {}): no complete IMU sample in {} frames", self.info.seed, fr.len()));
                }
                Ok(out)
            }
        }
    }

    /// Run the estimator over the run's input.
    fn replay(&self, cfg: &Config, prepare: impl FnOnce(&mut crate::estimator::Estimator)) -> Result<Replayed, String> {
        let mut est = Vec::with_capacity(self.truth.len());
        match &self.source {
            Source::Log(p) => {
                let sum = replay_files(cfg, &ReplayFiles { input: p, output: None, csv: None, mcap: None }, Some(&mut est))
                    .map_err(|e| e.to_string())?;
                if est.len() != self.truth.len() && sum.bad_lines > 0 {
                    // a damaged log: name it and its bad lines
                    let first: Vec<String> = sum.bad_examples.iter().take(3).map(|(n, e)| format!("line {n}: {e}")).collect();
                    return Err(format!(
                        "{}: {} estimates for {} truth rows: {} of its {} lines are not candump frames ({}{})",
                        p.display(),
                        est.len(),
                        self.truth.len(),
                        sum.bad_lines,
                        sum.lines,
                        first.join("; "),
                        if sum.bad_lines > first.len() as u64 { "; ..." } else { "" }
                    ));
                }
                Ok(Replayed { est, mode_seconds: sum.mode_seconds, magnetometer: sum.report.magnetometer })
            }
            Source::Frames(fr, dbc) => {
                struct Keep<'a>(&'a mut Vec<Estimate>);
                impl Sink for Keep<'_> {
                    fn output(&mut self, e: &Estimate, _: &Frames) {
                        self.0.push(*e);
                    }
                }
                // the wheel speeds of an in-memory run are described by its own DBC text
                let speed = match (cfg.speed.enabled(), dbc) {
                    (false, _) => None,
                    (true, Some(text)) => {
                        Some(crate::speed::SpeedDecoder::from_dbc_text(text, "car.dbc", &cfg.speed).map_err(|e| e.to_string())?)
                    }
                    (true, None) => crate::speed::load(cfg).map_err(|e| e.to_string())?,
                };
                let mut pipe = Pipeline::with_speed(cfg, speed);
                prepare(pipe.estimator_mut());
                let mut sink = Keep(&mut est);
                for f in fr {
                    pipe.push(f.t_us, RawFrame::classic(f.id, &f.data), &mut sink);
                }
                Ok(Replayed { est, mode_seconds: pipe.mode_seconds(), magnetometer: pipe.estimator().magnetometer() })
            }
        }
    }
}
