//! Evaluating one `gyrocomp simulate` directory: every case replayed and
//! scored, the tables printed, and with `--out` report.json and the two SVG
//! plots written.

use super::{cases, errors, oracle, plot, run_row, run_table, score, write_reports, EvalOptions, Metrics, RunData, Window, MOVING_MPS};
use crate::config::Config;
use crate::estimator::Estimate;
use crate::mcapout::{McapError, McapFile};
use crate::sim::ScenarioInfo;
use serde::Serialize;
use std::path::{Path, PathBuf};

#[derive(Serialize)]
struct Report<'a> {
    input: String,
    scenario: &'a ScenarioInfo,
    score_from_s: f64,
    oracle_start_s: f64,
    cases: &'a [Metrics],
    oracle: &'a Metrics,
}

/// Per sample: time (s) and the roll/pitch/yaw error (deg).
type ErrorRow = (f64, [f64; 3]);

/// The files of a `gyrocomp simulate` directory that evaluate reads.
const RUN_FILES: [&str; 6] = ["imu.log", "truth.csv", "sensor.toml", "bias.csv", "scenario.toml", "config.toml"];

/// Evaluate one simulated directory; returns the printed tables.
pub fn evaluate_dir(cfg: &Config, dir: &Path, o: &EvalOptions) -> Result<String, String> {
    evaluate_dir_with(cfg, dir, o, None)
}

/// [`evaluate_dir`]; `config_path` (the `--config` file) is an input the
/// report must not overwrite.
pub fn evaluate_dir_with(cfg: &Config, dir: &Path, o: &EvalOptions, config_path: Option<&Path>) -> Result<String, String> {
    let data = RunData::load(dir)?;
    let part = &cfg.input.profile;
    if *part != data.info.profile {
        return Err(format!(
            "{}: the run was simulated as an {} at {} Hz, the config's part is {part}: its frames would be decoded with another part's scales (pass --config {})",
            dir.display(),
            data.info.profile,
            data.info.rate_hz,
            dir.join("config.toml").display()
        ));
    }
    let win = Window::of(&data);
    if o.score_from >= win.end {
        return Err(format!("--score-from {} s is at or after the end of the run ({:.1} s): nothing to score", o.score_from, win.end));
    }
    // --mcap: refused (an input, a directory, no such directory) before the work
    let mut mcap = match &o.mcap {
        Some(p) => {
            let inputs: Vec<PathBuf> = RUN_FILES.iter().map(|f| dir.join(f)).chain(config_path.map(Path::to_path_buf)).collect();
            let inputs: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
            crate::outfile::refuse_inputs_as_outputs(&inputs, &[p.as_path()])?;
            Some((McapFile::create(p, true, o.peers).map_err(|e| format!("cannot write {}: {e}", p.display()))?, p))
        }
        None => None,
    };
    let mut out = String::new();
    let mut metrics = Vec::new();
    let mut man = Vec::new();
    let mut first: Option<(Vec<Estimate>, Vec<ErrorRow>)> = None;
    for (name, c) in cases(cfg, o.ablation) {
        let (est, ms) = data.estimates(&c)?;
        if est.len() != data.truth.len() {
            return Err(format!("{} estimates for {} truth rows", est.len(), data.truth.len()));
        }
        let still = data.still_moving(&est);
        metrics.push(Metrics { still_moving_s: still, ..score(&name, &data, &est, ms, o.score_from) });
        man.push(Metrics { still_moving_s: still, ..score(&name, &data, &est, ms, win.start) });
        if first.is_none() || name.starts_with("default") {
            let errs = errors(&data, &est);
            first = Some((est, errs));
        }
    }
    let (est, errs) = first.ok_or("no case ran")?;
    let (orc, _) = oracle(&data, &est, win.start);
    let t = run_table();
    out += &format!(
        "-- scored over t = {:.1}..{:.1} s (from --score-from to the end); time per mode and still moving (standstill declared while the truth moves faster than {MOVING_MPS} m/s) over the whole run\n",
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
    if let Some((f, p)) = mcap.take() {
        let vqf = if o.peers {
            let samples = data.samples(cfg)?;
            if samples.len() != est.len() {
                return Err(format!("{} samples decoded for {} estimates: VQF cannot be recorded beside them", samples.len(), est.len()));
            }
            let magn = crate::reference::magnetometer_configured(cfg);
            Some(crate::peers::run_vqf(&samples, 1.0 / cfg.profile().rate_hz, magn))
        } else {
            None
        };
        write_mcap(f, &dir.join("imu.log"), &data, &est, vqf.as_deref()).map_err(|e| format!("cannot write {}: {e}", p.display()))?;
        out += &format!("wrote {}\n", p.display());
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

/// `evaluate --input DIR --mcap`: the input frames of `log`, the default
/// case's estimates and the simulated truth beside them (sample `i` of
/// each, stamped with the estimate's frame time), with `vqf` VQF's attitude
/// per sample too, then renamed into place.
pub fn write_mcap(mut f: McapFile, log: &Path, data: &RunData, est: &[Estimate], vqf: Option<&[[f64; 3]]>) -> Result<(), McapError> {
    let input = std::fs::File::open(log)?;
    let mut rd = crate::candump::LineReader::new(input);
    while let Some(line) = rd.next_line()? {
        if let Ok(l) = line {
            if let Ok(fr) = crate::candump::parse_line(l) {
                if !fr.error {
                    let raw = crate::adis::RawFrame { id: fr.id, extended: fr.extended, remote: fr.remote, fd: fr.fd, data: fr.payload() };
                    f.can(fr.t_us, &raw)?;
                }
            }
        }
    }
    for (i, ((e, t), b)) in est.iter().zip(&data.truth).zip(&data.bias).enumerate() {
        f.estimate(e)?;
        f.truth(e.t_us, t.t, t.att, *b)?;
        if let Some(v) = vqf {
            f.vqf(e.t_us, e.t, v[i])?;
        }
    }
    f.commit()
}
