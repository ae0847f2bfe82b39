//! `gyrocomp evaluate`: replay a simulated run and score it against its truth.
//!
//! Single run (`--input DIR`, a `gyrocomp simulate` directory): replays
//! `DIR/imu.log` with the config, scores roll/pitch/yaw (max and RMS error),
//! the bias (against `DIR/bias.csv`) and the time per mode, and writes
//! `report.json` and two SVG plots into the report directory. With
//! `--ablation` the paper's three cases and the default mode run on the same
//! log and print as one table.
//!
//! Many seeds (`--seeds A..B --scenario NAME`): each seed is simulated in
//! memory (the same frames `simulate` would write) and replayed through the
//! same pipeline; the config's thermal curve is replaced by the seed's
//! calibration (the drawn slope known to +-`thermal_error`).
//!
//! Scores start at `score_from_s` (default 10 s: no estimator is asked to be
//! right at its first sample). The **oracle floor** integrates the measured
//! gyro with the deterministic sensor error known exactly (every effect of
//! `sensor.toml` evaluated on the truth; only white noise, bias random walk
//! and quantisation remain) from the true attitude at the start of the
//! manoeuvres, and reports its max roll/pitch error over the rest of the run.

use crate::adis::RawFrame;
use crate::config::{Config, Mode};
use crate::estimator::Estimate;
use crate::output::OutFrame;
use crate::pipeline::{Pipeline, Sink};
use crate::replay::{replay_files, ReplayFiles};
use crate::sim::model::{GyroInput, SensorModel};
use crate::sim::motion::{c_nb, wrap180};
use crate::sim::{self, read_bias, read_info, read_truth, vibration, ScenarioInfo, SimOptions, TruthRow};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Everything scoring needs about one run.
pub struct RunData {
    pub info: ScenarioInfo,
    pub model: SensorModel,
    pub truth: Vec<TruthRow>,
    /// True additive gyro bias per sample, deg/s.
    pub bias: Vec<[f64; 3]>,
    /// The run's own calibrated config (thermal curve known to +-thermal_error).
    pub unit_config: Option<Config>,
    source: Source,
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
        Ok(RunData { info, model, truth, bias, unit_config, source: Source::Log(dir.join("imu.log")) })
    }

    /// Simulate in memory.
    pub fn simulate(o: &SimOptions) -> Result<RunData, String> {
        let run = sim::prepare(o)?;
        let mut truth = Vec::new();
        let mut bias = Vec::new();
        let mut frames = Vec::new();
        for b in sim::bus(&run, o.seed) {
            let tr = &b.truth;
            truth.push(TruthRow { t: tr.t, att: [tr.roll, tr.pitch, tr.yaw], rate: tr.rate, f: tr.f, temp: tr.temp });
            bias.push(b.measured.bias);
            frames.extend_from_slice(b.frames());
        }
        let unit_config = Some(Config::parse(&run.config_toml, "simulated unit").map_err(|e| e.to_string())?);
        let dbc = run.wheel.is_some().then_some(sim::wheel::EXAMPLE_DBC);
        Ok(RunData { info: run.info, model: run.model, truth, bias, unit_config, source: Source::Frames(frames, dbc) })
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
        let mut est = Vec::with_capacity(self.truth.len());
        match &self.source {
            Source::Log(p) => {
                let sum =
                    replay_files(cfg, &ReplayFiles { input: p, output: None, csv: None }, Some(&mut est)).map_err(|e| e.to_string())?;
                Ok((est, sum.mode_seconds))
            }
            Source::Frames(fr, dbc) => {
                struct Keep<'a>(&'a mut Vec<Estimate>);
                impl Sink for Keep<'_> {
                    fn output(&mut self, e: &Estimate, _: &[OutFrame; 4]) {
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
                Ok((est, pipe.mode_seconds()))
            }
        }
    }
}

/// Scores of one estimator run.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Metrics {
    pub name: String,
    /// Max |error| of roll, pitch, yaw over the scored samples, deg.
    pub max_err: [f64; 3],
    /// RMS error of roll, pitch, yaw, deg.
    pub rms_err: [f64; 3],
    /// RMS and max |bias error| per axis, deg/s.
    pub bias_rms: [f64; 3],
    pub bias_max: [f64; 3],
    /// Seconds in fusion, blend, gyro only.
    pub mode_seconds: [f64; 3],
    pub samples: usize,
    /// Time of the largest roll or pitch error, s.
    pub t_max_tilt: f64,
}

impl Metrics {
    /// max(max roll error, max pitch error).
    pub fn tilt_max(&self) -> f64 {
        self.max_err[0].max(self.max_err[1])
    }
}

/// Errors of the estimate against the truth, per sample: (t, [roll, pitch, yaw]).
pub fn errors(data: &RunData, est: &[Estimate]) -> Vec<(f64, [f64; 3])> {
    est.iter().zip(&data.truth).map(|(e, t)| (t.t, [wrap180(e.roll - t.att[0]), e.pitch - t.att[1], wrap180(e.yaw - t.att[2])])).collect()
}

pub fn score(name: &str, data: &RunData, est: &[Estimate], mode_seconds: [f64; 3], from: f64) -> Metrics {
    let mut m = Metrics { name: name.into(), mode_seconds, ..Default::default() };
    let mut sq = [0.0; 3];
    let mut bsq = [0.0; 3];
    for ((e, t), b) in est.iter().zip(&data.truth).zip(&data.bias) {
        if t.t < from {
            continue;
        }
        let err = [wrap180(e.roll - t.att[0]), e.pitch - t.att[1], wrap180(e.yaw - t.att[2])];
        if err[0].abs().max(err[1].abs()) > m.tilt_max() {
            m.t_max_tilt = t.t;
        }
        for i in 0..3 {
            m.max_err[i] = m.max_err[i].max(err[i].abs());
            sq[i] += err[i] * err[i];
            let be = e.bias[i] - b[i];
            m.bias_max[i] = m.bias_max[i].max(be.abs());
            bsq[i] += be * be;
        }
        m.samples += 1;
    }
    let n = m.samples.max(1) as f64;
    for i in 0..3 {
        m.rms_err[i] = (sq[i] / n).sqrt();
        m.bias_rms[i] = (bsq[i] / n).sqrt();
    }
    m
}

/// The oracle floor: the measured gyro (decoded from the estimates:
/// `rate + bias`) corrected by the deterministic error model evaluated on the
/// truth, integrated from the true attitude at `start`. Returns its metrics
/// over `[start, end]` and its per-sample errors.
pub fn oracle(data: &RunData, est: &[Estimate], start: f64) -> (Metrics, Vec<(f64, [f64; 3])>) {
    let dt = 1.0 / data.info.rate_hz;
    let n = est.len().min(data.truth.len());
    let mut m = Metrics { name: "oracle floor".into(), ..Default::default() };
    // No sample at or after `start` (a run that ends before its manoeuvres): nothing to score.
    let k0 = match data.truth[..n].iter().position(|t| t.t >= start) {
        Some(k) => k,
        None => return (m, Vec::new()),
    };
    let tr = &data.truth;
    let att0 = tr[k0].att.map(f64::to_radians);
    let mut c = c_nb(att0[0], att0[1], att0[2]);
    let mut sq = [0.0; 3];
    let mut errs = Vec::with_capacity(n - k0);
    for k in k0 + 1..n {
        let t = &tr[k];
        let p = &tr[k - 1];
        let vib = vibration(&data.model.vibration, t.t);
        let x = GyroInput {
            rate: t.rate,
            rate_dot: [0, 1, 2].map(|i| (t.rate[i] - p.rate[i]) / dt),
            f: [t.f[0] + vib[0], t.f[1] + vib[1], t.f[2] + vib[2]],
            temp: t.temp,
            temp_rate: (t.temp - p.temp) / dt,
            t_on: t.t,
        };
        let det = data.model.gyro.measure(&x);
        let e = &est[k];
        let w: [f64; 3] = [0, 1, 2].map(|i| (e.rate[i] + e.bias[i] - (det[i] - t.rate[i])).to_radians() * dt);
        c = mat_mul(&c, &exp_so3(w));
        let a = euler(&c);
        let err = [wrap180(a[0] - t.att[0]), a[1] - t.att[1], wrap180(a[2] - t.att[2])];
        for i in 0..3 {
            m.max_err[i] = m.max_err[i].max(err[i].abs());
            sq[i] += err[i] * err[i];
        }
        m.samples += 1;
        errs.push((t.t, err));
    }
    let nn = m.samples.max(1) as f64;
    m.rms_err = sq.map(|s| (s / nn).sqrt());
    (m, errs)
}

fn mat_mul(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut c = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            c[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
        }
    }
    c
}

fn exp_so3(w: [f64; 3]) -> [[f64; 3]; 3] {
    let th2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
    let th = th2.sqrt();
    let (a, b) = if th < 1e-9 { (1.0 - th2 / 6.0, 0.5 - th2 / 24.0) } else { (th.sin() / th, (1.0 - th.cos()) / th2) };
    let k = [[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]];
    let k2 = mat_mul(&k, &k);
    let mut r = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            r[i][j] = if i == j { 1.0 } else { 0.0 } + a * k[i][j] + b * k2[i][j];
        }
    }
    r
}

fn euler(c: &[[f64; 3]; 3]) -> [f64; 3] {
    [c[2][1].atan2(c[2][2]).to_degrees(), (-c[2][0]).clamp(-1.0, 1.0).asin().to_degrees(), c[1][0].atan2(c[0][0]).to_degrees()]
}

/// The ablation cases: the paper's three, then the default mode.
pub fn cases(base: &Config, ablation: bool) -> Vec<(String, Config)> {
    let with = |m: Mode| {
        let mut c = base.clone();
        c.estimator.mode = m;
        c
    };
    if !ablation {
        return vec![(base.estimator.mode.name().to_string(), base.clone())];
    }
    let default = Config::default().estimator.mode;
    let mut v = vec![
        ("1 startup_average".to_string(), with(Mode::StartupAverage)),
        ("2 startup_thermal".to_string(), with(Mode::StartupThermal)),
        ("3 paper".to_string(), with(Mode::Paper)),
    ];
    if default != Mode::Paper {
        v.push((format!("default ({})", default.name()), with(default)));
    }
    v
}

/// A text table whose header names every column and gives its unit on a
/// second line. Columns are as wide as their header (at least 8); a longer
/// cell widens its row, it is never cut.
pub struct Table {
    cols: Vec<(&'static str, &'static str, usize)>,
    /// Leading columns that are text (left-aligned).
    left: usize,
}

impl Table {
    /// Columns as (name, unit); the first is left-aligned, the others right-aligned.
    pub fn new(cols: &[(&'static str, &'static str)]) -> Table {
        Table { cols: cols.iter().map(|(n, u)| (*n, *u, n.len().max(u.len()).max(8))).collect(), left: 1 }
    }

    /// The first `n` columns are text (left-aligned).
    pub fn text_columns(mut self, n: usize) -> Table {
        self.left = n;
        self
    }

    /// The same columns with column `k` `w` characters wide (or its header's width).
    pub fn width(mut self, k: usize, w: usize) -> Table {
        self.cols[k].2 = w.max(self.cols[k].0.len()).max(self.cols[k].1.len());
        self
    }

    /// The two header lines.
    pub fn header(&self) -> String {
        let names: Vec<String> = self.cols.iter().map(|c| c.0.to_string()).collect();
        let units: Vec<String> = self.cols.iter().map(|c| c.1.to_string()).collect();
        self.line(&names) + &self.line(&units)
    }

    /// One row.
    pub fn line(&self, cells: &[String]) -> String {
        let mut s = String::new();
        for (k, (c, (_, _, w))) in cells.iter().zip(&self.cols).enumerate() {
            let sep = if k == 0 { "" } else { "  " };
            if k < self.left {
                s += &format!("{sep}{c:<w$}");
            } else {
                s += &format!("{sep}{c:>w$}");
            }
        }
        s.trim_end().to_string() + "\n"
    }
}

/// `v` with `d` decimals, or `-` when it is not a number.
fn num(v: f64, d: usize) -> String {
    if v.is_finite() {
        format!("{v:.d$}")
    } else {
        "-".into()
    }
}

/// The columns of a single run's table.
pub fn run_table() -> Table {
    Table::new(&[
        ("case", ""),
        ("max roll", "deg"),
        ("max pitch", "deg"),
        ("max yaw", "deg"),
        ("rms roll", "deg"),
        ("rms pitch", "deg"),
        ("rms yaw", "deg"),
        ("rms bias", "deg/s"),
        ("run in fusion", "s"),
        ("run in blend", "s"),
        ("run gyro only", "s"),
    ])
    .width(0, 22)
}

/// One row of [`run_table`]; the oracle floor has no bias and no modes.
pub fn run_row(t: &Table, m: &Metrics, oracle: bool) -> String {
    let brms = (m.bias_rms.iter().map(|b| b * b).sum::<f64>() / 3.0).sqrt();
    let mut c = vec![m.name.clone()];
    c.extend(m.max_err.iter().chain(&m.rms_err).map(|v| num(*v, 3)));
    if oracle {
        c.extend(["-"; 4].map(String::from));
    } else {
        c.push(num(brms, 5));
        c.extend(m.mode_seconds.iter().map(|v| num(*v, 1)));
    }
    t.line(&c)
}

/// The part of a run the manoeuvres-only scores and the oracle floor cover.
#[derive(Clone, Copy, Debug)]
pub struct Window {
    pub start: f64,
    /// Time of the last sample, s.
    pub end: f64,
}

impl Window {
    pub fn of(data: &RunData) -> Window {
        Window { start: data.info.manoeuvre_start_s, end: data.truth.last().map(|t| t.t).unwrap_or(0.0) }
    }

    /// No sample after the start: nothing to score, no oracle floor.
    pub fn is_empty(&self) -> bool {
        self.start >= self.end
    }

    /// The table title of the window.
    pub fn title(&self, scenario: &str) -> String {
        if self.start <= 0.0 {
            format!("oracle window, t = 0.0..{:.1} s (scenario {scenario} has no manoeuvres: the whole run)", self.end)
        } else {
            format!("manoeuvres only, t = {:.1}..{:.1} s (the oracle floor's window)", self.start, self.end)
        }
    }

    /// The warning printed instead of an empty window's table.
    pub fn warning(&self) -> String {
        format!(
            "warning: no manoeuvres to score: the run ends at {:.1} s, before the scenario's manoeuvres start \
             (paper and vehicle: 350 s); the manoeuvres-only scores and the oracle floor are left out (use a longer --duration)",
            self.end
        )
    }
}

#[derive(Serialize)]
struct Report<'a> {
    input: String,
    scenario: &'a ScenarioInfo,
    score_from_s: f64,
    oracle_start_s: f64,
    cases: &'a [Metrics],
    oracle: &'a Metrics,
}

/// Options of `gyrocomp evaluate`.
#[derive(Clone, Debug)]
pub struct EvalOptions {
    pub score_from: f64,
    pub ablation: bool,
    pub out: Option<PathBuf>,
}

/// Per sample: time (s) and the roll/pitch/yaw error (deg).
type ErrorRow = (f64, [f64; 3]);

/// The files of a `gyrocomp simulate` directory that evaluate reads.
const RUN_FILES: [&str; 6] = ["imu.log", "truth.csv", "sensor.toml", "bias.csv", "scenario.toml", "config.toml"];

/// Write the report files: every destination checked first (not an input,
/// not a directory), then each written through a temporary file.
fn write_reports(dir: &Path, inputs: &[&Path], files: &[(&str, Vec<u8>)]) -> Result<(), String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let dests: Vec<PathBuf> = files.iter().map(|(n, _)| dir.join(n)).collect();
    let refs: Vec<&Path> = dests.iter().map(PathBuf::as_path).collect();
    crate::outfile::refuse_inputs_as_outputs(inputs, &refs)?;
    if let Some(d) = dests.iter().find(|d| d.is_dir()) {
        return Err(format!("{} is a directory: the report is a file of that name", d.display()));
    }
    for (d, (_, bytes)) in dests.iter().zip(files) {
        crate::outfile::write_atomic(d, bytes).map_err(|e| format!("{}: {e}", d.display()))?;
    }
    Ok(())
}

/// Evaluate one simulated directory; returns the printed tables.
pub fn evaluate_dir(cfg: &Config, dir: &Path, o: &EvalOptions) -> Result<String, String> {
    evaluate_dir_with(cfg, dir, o, None)
}

/// [`evaluate_dir`]; `config_path` (the `--config` file) is an input the
/// report must not overwrite.
pub fn evaluate_dir_with(cfg: &Config, dir: &Path, o: &EvalOptions, config_path: Option<&Path>) -> Result<String, String> {
    let data = RunData::load(dir)?;
    let win = Window::of(&data);
    if o.score_from >= win.end {
        return Err(format!("--score-from {} s is at or after the end of the run ({:.1} s): nothing to score", o.score_from, win.end));
    }
    let mut out = String::new();
    let mut metrics = Vec::new();
    let mut man = Vec::new();
    let mut first: Option<(Vec<Estimate>, Vec<ErrorRow>)> = None;
    for (name, c) in cases(cfg, o.ablation) {
        let (est, ms) = data.estimates(&c)?;
        if est.len() != data.truth.len() {
            return Err(format!("{} estimates for {} truth rows", est.len(), data.truth.len()));
        }
        metrics.push(score(&name, &data, &est, ms, o.score_from));
        man.push(score(&name, &data, &est, ms, win.start));
        if first.is_none() || name.starts_with("default") {
            let errs = errors(&data, &est);
            first = Some((est, errs));
        }
    }
    let (est, errs) = first.ok_or("no case ran")?;
    let (orc, _) = oracle(&data, &est, win.start);
    let t = run_table();
    out += &format!(
        "-- scored over t = {:.1}..{:.1} s (from --score-from to the end); time per mode over the whole run\n",
        o.score_from, win.end
    );
    out += &t.header();
    for m in &metrics {
        out += &run_row(&t, m, false);
    }
    if win.is_empty() {
        eprintln!("{}", win.warning());
        out += &win.warning();
        out += "\n";
    } else {
        out += &format!("-- {}\n", win.title(&data.info.scenario));
        out += &t.header();
        for m in &man {
            out += &run_row(&t, m, false);
        }
        out += &run_row(&t, &orc, true);
        out += "(oracle floor: the measured gyro with the deterministic error known exactly, integrated from the true attitude at the window's start)\n";
    }
    if let Some(rd) = &o.out {
        let rep = Report {
            input: dir.display().to_string(),
            scenario: &data.info,
            score_from_s: o.score_from,
            oracle_start_s: win.start,
            cases: &metrics,
            oracle: &orc,
        };
        let json = serde_json::to_string_pretty(&rep).map_err(|e| e.to_string())?;
        let mut att = String::new();
        plot::attitude_error(&mut att, &errs, &est).map_err(|e| format!("plot: {e}"))?;
        let mut bias = String::new();
        plot::bias(&mut bias, &est, &data).map_err(|e| format!("plot: {e}"))?;
        let inputs: Vec<PathBuf> = RUN_FILES.iter().map(|f| dir.join(f)).chain(config_path.map(Path::to_path_buf)).collect();
        let inputs: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
        write_reports(
            rd,
            &inputs,
            &[("report.json", json.into_bytes()), ("attitude_error.svg", att.into_bytes()), ("bias.svg", bias.into_bytes())],
        )?;
        out += &format!("wrote {}/report.json, attitude_error.svg, bias.svg\n", rd.display());
    }
    Ok(out)
}

/// One seed's results.
#[derive(Clone, Debug, Serialize)]
pub struct SeedRow {
    pub seed: u64,
    /// Scored from `score_from`.
    pub cases: Vec<Metrics>,
    /// Scored over the manoeuvres only (the oracle floor's window).
    pub manoeuvres: Vec<Metrics>,
    pub oracle: Metrics,
}

/// Median of a slice (upper median for even lengths is avoided: mean of the two middle values).
pub fn median(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let mut s = v.to_vec();
    s.sort_by(|a, b| a.total_cmp(b));
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    }
}

/// Evaluate many seeds of a scenario; prints progress to stderr, returns the tables.
pub fn evaluate_seeds(base: &Config, sim: &SimOptions, seeds: std::ops::RangeInclusive<u64>, o: &EvalOptions) -> Result<String, String> {
    evaluate_seeds_with(base, sim, seeds, o, None)
}

/// [`evaluate_seeds`]; `config_path` (the `--config` file) is an input the
/// report must not overwrite.
pub fn evaluate_seeds_with(
    base: &Config,
    sim: &SimOptions,
    seeds: std::ops::RangeInclusive<u64>,
    o: &EvalOptions,
    config_path: Option<&Path>,
) -> Result<String, String> {
    let list: Vec<u64> = seeds.collect();
    let mut rows: Vec<SeedRow> = Vec::new();
    let case_list = cases(base, o.ablation);
    let mut out = String::new();
    let per_seed = Table::new(&[
        ("seed", ""),
        ("case", ""),
        ("max roll", "deg"),
        ("max pitch", "deg"),
        ("rms yaw", "deg"),
        ("rms bias", "deg/s"),
        ("t max tilt", "s"),
        ("man max roll", "deg"),
        ("man max pitch", "deg"),
        ("man rms yaw", "deg"),
        ("oracle roll", "deg"),
        ("oracle pitch", "deg"),
    ])
    .text_columns(2)
    .width(0, 5)
    .width(1, 22);
    let mut win: Option<Window> = None;
    for (i, &seed) in list.iter().enumerate() {
        let mut so = sim.clone();
        so.seed = seed;
        let data = RunData::simulate(&so)?;
        let w = Window::of(&data);
        if win.is_none() {
            if o.score_from >= w.end {
                return Err(format!(
                    "--score-from {} s is at or after the end of the runs ({:.1} s): nothing to score",
                    o.score_from, w.end
                ));
            }
            let head = format!(
                "per seed: max roll/pitch, rms yaw, rms bias and the time of the largest tilt error over t = {:.1}..{:.1} s; \
                 'man' over {}; 'oracle' the oracle floor there\n{}",
                o.score_from,
                w.end,
                if w.is_empty() {
                    "the manoeuvres (none in these runs)".to_string()
                } else {
                    format!("t = {:.1}..{:.1} s", w.start, w.end)
                },
                per_seed.header()
            );
            eprint!("{head}");
            out += &head;
            if w.is_empty() {
                eprintln!("{}", w.warning());
            }
        }
        let w = *win.get_or_insert(w);
        let mut ms = Vec::new();
        let mut man = Vec::new();
        let mut orc = None;
        for (name, c) in &case_list {
            let mut c = c.clone();
            if let Some(u) = &data.unit_config {
                c.thermal = u.thermal.clone();
                c.mounting = u.mounting.clone();
                c.speed = u.speed.clone();
            }
            let (est, mode_s) = data.estimates(&c)?;
            if orc.is_none() {
                orc = Some(oracle(&data, &est, w.start).0);
            }
            ms.push(score(name, &data, &est, mode_s, o.score_from));
            man.push(score(name, &data, &est, mode_s, w.start));
        }
        let orc = orc.ok_or("no case")?;
        for (m, mm) in ms.iter().zip(&man) {
            let brms = (m.bias_rms.iter().map(|b| b * b).sum::<f64>() / 3.0).sqrt();
            let gone = |v: f64| if w.is_empty() { "-".to_string() } else { num(v, 3) };
            let line = per_seed.line(&[
                seed.to_string(),
                m.name.clone(),
                num(m.max_err[0], 3),
                num(m.max_err[1], 3),
                num(m.rms_err[2], 3),
                num(brms, 5),
                num(m.t_max_tilt, 1),
                gone(mm.max_err[0]),
                gone(mm.max_err[1]),
                gone(mm.rms_err[2]),
                gone(orc.max_err[0]),
                gone(orc.max_err[1]),
            ]);
            out += &line;
            eprint!("[{}/{}] {line}", i + 1, list.len());
        }
        rows.push(SeedRow { seed, cases: ms, manoeuvres: man, oracle: orc });
    }
    let w = win.ok_or("no seed")?;
    let orc_med = median(&rows.iter().map(|r| r.oracle.tilt_max()).collect::<Vec<_>>());
    let name =
        format!("{}{}{}", sim.scenario, if sim.hard { " --hard" } else { "" }, if sim.power_on_moving { " --power-on-moving" } else { "" });
    let duration = sim.duration.unwrap_or_else(|| sim::scenario::default_duration(&sim.scenario));
    out += &format!("\nsummary over {} seeds of {name} ({duration} s)", rows.len());
    if w.is_empty() {
        out += &format!("\n{}\n", w.warning());
    } else {
        out += &format!(
            "; oracle floor (median over the seeds of the max roll/pitch error, t = {:.1}..{:.1} s) {:.3} deg\n",
            w.start, w.end, orc_med
        );
    }
    let ratio_ok = !w.is_empty() && orc_med.is_finite() && orc_med > 0.0;
    if !w.is_empty() && !ratio_ok {
        let msg = format!("warning: the oracle floor is {orc_med} deg: no ratio to it is given");
        eprintln!("{msg}");
        out += &msg;
        out += "\n";
    }
    out += "(worst = the largest over the seeds; median max = the median over the seeds of each seed's max roll/pitch error; \
             ratio = median max / oracle floor; seeds <= 2 deg: seeds whose max roll and pitch error are within 2 deg)\n";
    let summary = Table::new(&[
        ("case", ""),
        ("worst roll", "deg"),
        ("worst pitch", "deg"),
        ("median max", "deg"),
        ("ratio to oracle", "x"),
        ("worst rms yaw", "deg"),
        ("seeds <= 2 deg", "of total"),
        ("worst seed", ""),
    ])
    .width(0, 22);
    let mut windows = vec![(format!("scored over t = {:.1}..{:.1} s", o.score_from, w.end), false)];
    if !w.is_empty() {
        windows.push((w.title(&sim.scenario), true));
    }
    for (title, man) in windows {
        out += &format!("-- {title}\n");
        out += &summary.header();
        for (ci, (name, _)) in case_list.iter().enumerate() {
            let pick = |r: &SeedRow| if man { r.manoeuvres[ci].clone() } else { r.cases[ci].clone() };
            let per: Vec<Metrics> = rows.iter().map(pick).collect();
            let wr = per.iter().map(|m| m.max_err[0]).fold(0.0, f64::max);
            let wp = per.iter().map(|m| m.max_err[1]).fold(0.0, f64::max);
            let med = median(&per.iter().map(|m| m.tilt_max()).collect::<Vec<_>>());
            let wy = per.iter().map(|m| m.rms_err[2]).fold(0.0, f64::max);
            let ok = per.iter().filter(|m| m.tilt_max() <= 2.0).count();
            let worst = rows.iter().zip(&per).max_by(|a, b| a.1.tilt_max().total_cmp(&b.1.tilt_max())).map(|r| r.0.seed).unwrap_or(0);
            out += &summary.line(&[
                name.clone(),
                num(wr, 3),
                num(wp, 3),
                num(med, 3),
                if ratio_ok { num(med / orc_med, 2) } else { "-".into() },
                num(wy, 3),
                format!("{ok}/{}", rows.len()),
                worst.to_string(),
            ]);
        }
    }
    if let Some(rd) = &o.out {
        let json = serde_json::to_string_pretty(&rows).map_err(|e| e.to_string())?;
        let inputs: Vec<&Path> = config_path.into_iter().collect();
        write_reports(rd, &inputs, &[("report.json", json.into_bytes())])?;
        out += &format!("wrote {}\n", rd.join("report.json").display());
    }
    Ok(out)
}

/// SVG plots (plotters, SVG backend only: no font files needed).
mod plot {
    use super::RunData;
    use crate::estimator::Estimate;
    use plotters::prelude::*;

    type R = Result<(), Box<dyn std::error::Error>>;

    /// At most ~`n` points of a series.
    fn every(len: usize, n: usize) -> usize {
        (len / n).max(1)
    }

    pub fn attitude_error(svg: &mut String, errs: &[(f64, [f64; 3])], est: &[Estimate]) -> R {
        let root = SVGBackend::with_string(svg, (1200, 500)).into_drawing_area();
        root.fill(&WHITE)?;
        let t1 = errs.last().map(|e| e.0).unwrap_or(1.0).max(1e-3);
        let m = errs.iter().flat_map(|e| e.1.iter()).map(|v| v.abs()).fold(0.5f64, f64::max).min(60.0) * 1.1;
        let mut ch = ChartBuilder::on(&root)
            .caption("attitude error (estimate - truth); shading: green fusion, yellow blend", ("sans-serif", 18))
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(50)
            .build_cartesian_2d(0.0..t1, -m..m)?;
        ch.configure_mesh().x_desc("t, s").y_desc("deg").draw()?;
        // mode shading, one rectangle per run of equal mode
        let mut k = 0;
        while k < est.len() {
            let mode = est[k].mode;
            let mut j = k;
            while j + 1 < est.len() && est[j + 1].mode == mode {
                j += 1;
            }
            let col = match mode {
                0 => Some(RGBColor(200, 240, 200)),
                1 => Some(RGBColor(250, 240, 190)),
                _ => None,
            };
            if let Some(col) = col {
                ch.draw_series(std::iter::once(Rectangle::new([(est[k].t, -m), (est[j].t.max(est[k].t + 0.005), m)], col.filled())))?;
            }
            k = j + 1;
        }
        let step = every(errs.len(), 4000);
        for (i, (name, col)) in [("roll", RED), ("pitch", BLUE), ("yaw", BLACK)].iter().enumerate() {
            ch.draw_series(LineSeries::new(errs.iter().step_by(step).map(|e| (e.0, e.1[i].clamp(-m, m))), col))?
                .label(*name)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], col));
        }
        ch.configure_series_labels().border_style(BLACK).background_style(WHITE).draw()?;
        root.present()?;
        Ok(())
    }

    pub fn bias(svg: &mut String, est: &[Estimate], data: &RunData) -> R {
        let root = SVGBackend::with_string(svg, (1200, 500)).into_drawing_area();
        root.fill(&WHITE)?;
        let t1 = est.last().map(|e| e.t).unwrap_or(1.0).max(1e-3);
        let all = est.iter().flat_map(|e| e.bias.iter()).chain(data.bias.iter().flat_map(|b| b.iter()));
        let (lo, hi) = all.fold((f64::MAX, f64::MIN), |(l, h), v| (l.min(*v), h.max(*v)));
        let pad = ((hi - lo) * 0.05).max(0.01);
        let mut ch = ChartBuilder::on(&root)
            .caption("gyro bias: estimate (solid) vs truth (thin)", ("sans-serif", 18))
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..t1, (lo - pad)..(hi + pad))?;
        ch.configure_mesh().x_desc("t, s").y_desc("deg/s").draw()?;
        let step = every(est.len(), 4000);
        for (i, (name, col)) in [("x", RED), ("y", BLUE), ("z", BLACK)].iter().enumerate() {
            ch.draw_series(LineSeries::new(est.iter().step_by(step).map(|e| (e.t, e.bias[i])), col.stroke_width(2)))?
                .label(format!("estimate {name}"))
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], col.stroke_width(2)));
            ch.draw_series(LineSeries::new(data.truth.iter().zip(&data.bias).step_by(step).map(|(t, b)| (t.t, b[i])), col.mix(0.5)))?;
        }
        ch.configure_series_labels().border_style(BLACK).background_style(WHITE).draw()?;
        root.present()?;
        Ok(())
    }
}

/// Parse `A..B` (inclusive) or a single seed.
pub fn parse_seeds(s: &str) -> Result<std::ops::RangeInclusive<u64>, String> {
    let bad = || format!("--seeds wants A..B (inclusive) or N, got {s:?}");
    match s.split_once("..") {
        Some((a, b)) => {
            let a: u64 = a.trim().parse().map_err(|_| bad())?;
            let b: u64 = b.trim().trim_start_matches('=').parse().map_err(|_| bad())?;
            if a > b {
                return Err(bad());
            }
            Ok(a..=b)
        }
        None => {
            let a: u64 = s.trim().parse().map_err(|_| bad())?;
            Ok(a..=a)
        }
    }
}

/// The `evaluate` subcommand.
#[derive(clap::Args, Debug)]
#[command(group(clap::ArgGroup::new("what").required(true).args(["input", "seeds", "realdata"])))]
pub struct EvaluateArgs {
    /// gyrocomp config (TOML). Default: the built-in defaults. With --seeds its
    /// [thermal] section is replaced by each simulated unit's calibration.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// A `gyrocomp simulate` directory to replay and score, or with --reference a
    /// candump log. One of --input, --seeds or --realdata is required.
    #[arg(long, value_name = "DIR", conflicts_with = "seeds")]
    pub input: Option<PathBuf>,
    /// Report directory: report.json (and with --input attitude_error.svg,
    /// bias.svg). Default: no report files.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Also run the paper's three cases (startup_average, startup_thermal,
    /// paper) and print them with the default mode. Off by default.
    #[arg(long)]
    pub ablation: bool,
    /// Simulate (in memory) and evaluate these seeds: A..B inclusive, or one
    /// seed N. Required unless --input is given; needs --scenario.
    #[arg(long, value_name = "A..B", requires = "scenario")]
    pub seeds: Option<String>,
    /// With --seeds: the scenario to simulate (static, chamber, paper, vehicle). Required with --seeds.
    #[arg(long, value_name = "NAME", requires = "seeds")]
    pub scenario: Option<String>,
    /// With --seeds, vehicle only: add emergency brakes and swerves of 0.65-0.8 g. Off by default.
    #[arg(long, requires = "seeds")]
    pub hard: bool,
    /// With --seeds: the simulated runs start while the car is already
    /// driving (urban, vehicle, paper). Default: a parked start.
    #[arg(long, requires = "seeds")]
    pub power_on_moving: bool,
    /// With --seeds (urban): the estimator uses the car's wheel speeds
    /// ([speed] of each run's config). Default: IMU only.
    #[arg(long, requires = "seeds")]
    pub speed: bool,
    /// With --seeds: duration of each run, s (> 0). Default: the scenario's
    /// (static 300, chamber 1800, paper and vehicle 800, urban 400; the
    /// manoeuvres of paper and vehicle start at 350).
    #[arg(long, value_name = "S", requires = "seeds", allow_negative_numbers = true, value_parser = crate::sim::cli::positive_seconds)]
    pub duration: Option<f64>,
    /// With --seeds: relative error of the thermal slope the estimator is
    /// given, a fraction 0..1 (0.05 = each axis off by up to +-5 %).
    #[arg(long, value_name = "FRACTION", allow_negative_numbers = true, value_parser = crate::sim::cli::fraction, default_value_t = 0.05)]
    pub thermal_error: f64,
    /// Score from this time on, s after power-on (>= 0); the manoeuvres-only
    /// scores start where the manoeuvres do. Alias: --skip.
    #[arg(
        long,
        visible_alias = "skip",
        value_name = "S",
        allow_negative_numbers = true,
        value_parser = crate::sim::cli::non_negative_seconds,
        default_value_t = 10.0
    )]
    pub score_from: f64,
    /// Real data: --reference, --realdata, --peers, --offset, --align-s (`gyrocomp::reference`).
    #[command(flatten)]
    pub real: crate::reference::ReferenceArgs,
}

pub fn run(a: &EvaluateArgs) -> Result<(), String> {
    if let Some(text) = crate::reference::dispatch(a.config.as_deref(), a.input.as_deref(), a.out.as_deref(), a.score_from, &a.real)? {
        print!("{text}");
        return Ok(());
    }
    let cfg = match &a.config {
        Some(p) => Config::load(p).map_err(|e| e.to_string())?,
        None => Config::default(),
    };
    let o = EvalOptions { score_from: a.score_from, ablation: a.ablation, out: a.out.clone() };
    let text = match (&a.input, &a.seeds) {
        (Some(dir), None) => evaluate_dir_with(&cfg, dir, &o, a.config.as_deref())?,
        (None, Some(s)) => {
            let sc = a.scenario.as_deref().ok_or("--seeds needs --scenario")?;
            crate::sim::cli::check_scenario(sc, a.hard, a.duration, &cfg.input.profile)?;
            let mut so = SimOptions::new(sc, 0);
            so.hard = a.hard;
            so.power_on_moving = a.power_on_moving;
            so.speed = a.speed;
            so.duration = a.duration;
            so.thermal_error = a.thermal_error;
            so.profile = cfg.input.profile.clone();
            evaluate_seeds_with(&cfg, &so, parse_seeds(s)?, &o, a.config.as_deref())?
        }
        _ => return Err("evaluate needs --input DIR or --seeds A..B --scenario NAME".into()),
    };
    print!("{text}");
    Ok(())
}
