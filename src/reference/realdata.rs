//! `gyrocomp evaluate --realdata DIR`: every recording folder under DIR
//! (`imu.csv.gz` + `reference.csv.gz`, and `can.log.gz` when there is one)
//! through `import` (auto scales, rate from `t`, the car's bus merged) and
//! the reference evaluation, ours and VQF, in one table.
//!
//! The config of a recording is the given one (or the defaults) with the
//! import's snippet laid over it: the recording's scales and rate, and the
//! magnetometer or the thermal curve off when the recording has none. With
//! `--out`, each recording gets a folder with the imported `imu.log`, the
//! snippet `import.toml`, the effective `config.toml`, `report.json` and
//! `errors.svg`; `realdata.json` holds every row.

use super::refcsv::read_reference;
use super::{decode, evaluate_with, run_ours_log, table_header, Evaluation, RefOptions};
use crate::config::Config;
use crate::import::{import_to_memory, overlay, ImportOptions, Imported};
use crate::outfile::write_atomic;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The recording folders under `dir`, by name.
pub fn recordings(dir: &Path) -> Result<Vec<PathBuf>, String> {
    let rd = std::fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut v: Vec<PathBuf> = rd
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.join("imu.csv.gz").is_file() && p.join("reference.csv.gz").is_file())
        .collect();
    v.sort();
    if v.is_empty() {
        return Err(format!("{}: no recording folder (imu.csv.gz + reference.csv.gz) in it", dir.display()));
    }
    Ok(v)
}

/// One recording's evaluation.
pub struct Recording {
    pub name: String,
    pub import: Imported,
    pub config: Config,
    pub log: Vec<u8>,
    pub eval: Evaluation,
}

/// A recording's name: its folder's.
fn recording_name(dir: &Path) -> String {
    dir.file_name().map(|n| n.to_string_lossy().to_string()).unwrap_or_default()
}

/// Import and evaluate one recording folder (VQF always runs).
pub fn evaluate_recording(dir: &Path, base: &Config, o: &RefOptions) -> Result<Recording, String> {
    let name = recording_name(dir);
    let can = dir.join("can.log.gz");
    let can = can.is_file().then_some(can);
    let io = ImportOptions { from: o.power_on_at, ..ImportOptions::default() };
    // the import's --from is this command's --power-on-at: say the user's word
    let (log, import) = import_to_memory(&dir.join("imu.csv.gz"), can.as_deref(), &io).map_err(|e| e.replace("--from", "--power-on-at"))?;
    let config = overlay(base, &import.snippet, &format!("{name} import snippet"))?;
    let d = decode(&log[..], &config, &format!("{name} (imported log)"))?;
    if d.samples.len() != import.samples {
        return Err(format!("{name}: {} samples imported, {} decoded", import.samples, d.samples.len()));
    }
    let mut r = read_reference(&dir.join("reference.csv.gz"))?;
    if let Some(p) = o.power_on_at {
        // what the reference says before power-on is nothing to score (nor
        // a rest phase to take the mount from)
        r.rows.retain(|x| x.t >= p + o.offset);
    }
    // the log's sample clock starts at 0 at the CSV's first `t`; the
    // reference is on the CSV's clock (`--offset` shifts it further)
    let o = RefOptions { peers: true, offset: o.offset + import.t0, ..o.clone() };
    let ours = run_ours_log(&log[..], &config, &name)?;
    let eval = evaluate_with(&d.samples, ours, &config, &r, &o).map_err(|e| format!("{name}: {e}"))?;
    Ok(Recording { name, import, config, log, eval })
}

#[derive(Serialize)]
struct Row<'a> {
    recording: &'a str,
    samples: usize,
    rate_hz: f64,
    magnetometer: bool,
    alignment: &'a super::score::Alignment,
    ours: &'a super::score::Scores,
    vqf: Option<&'a super::score::Scores>,
}

/// The printed table, and the recordings that could not be evaluated
/// (named with the reason under the table too).
pub struct Table {
    pub text: String,
    pub failed: Vec<String>,
}

/// Run every recording; a recording that cannot be evaluated (a bad file,
/// no valid reference where the mount is taken) is named with the reason
/// under the table and the others go on. Err only when none could be.
pub fn run(dir: &Path, base: &Config, config_label: &str, out: Option<&Path>, o: &RefOptions) -> Result<Table, String> {
    let list = recordings(dir)?;
    let t0 = Instant::now();
    let mut recs = Vec::new();
    let mut failed = Vec::new();
    for p in &list {
        let t = Instant::now();
        match evaluate_recording(p, base, o) {
            Ok(r) => {
                eprintln!("[realdata] {}: {} samples in {:.2} s", r.name, r.eval.samples, t.elapsed().as_secs_f64());
                recs.push(r);
            }
            Err(e) => {
                let name = recording_name(p);
                // evaluate_recording's errors mostly name the recording already
                let e = if e.starts_with(&format!("{name}:")) { e } else { format!("{name}: {e}") };
                eprintln!("[realdata] not evaluated: {e}");
                failed.push(e);
            }
        }
    }
    if recs.is_empty() {
        return Err(format!("no recording under {} could be evaluated:\n  {}", dir.display(), failed.join("\n  ")));
    }
    eprintln!("[realdata] {} recordings in {:.2} s", recs.len(), t0.elapsed().as_secs_f64());
    let mut s = format!(
        "real data: {} recordings under {}, config {config_label}; scored from {:.0} s; errors in deg after the mount \
         (estimated over the first rest phase) is removed; yaw only where the magnetometer is used, after each estimator's \
         offset at the end of that phase; roll/yaw not scored where |reference pitch| > {} deg (vert_s); mount = the tilt removed, deg\n",
        recs.len(),
        dir.display(),
        o.skip,
        super::score::VERTICAL_LIMIT_DEG
    );
    if let Some(p) = o.power_on_at {
        s += &format!(
            "powered on {p} s into each recording (--power-on-at: the samples, the car's frames and the reference before are \
             left out; scored from {} s after that)\n",
            o.skip
        );
    }
    s += &table_header("recording");
    for r in &recs {
        s += &r.eval.table_rows(&r.name);
    }
    for r in &recs {
        s += &r.eval.rest_warning(&r.name).map(|w| format!("* {w}")).unwrap_or_default();
    }
    for e in &failed {
        s += &format!("* not evaluated: {e}\n");
    }
    if let Some(od) = out {
        let mut rows = Vec::new();
        for r in &recs {
            let d = od.join(&r.name);
            crate::outfile::create_dir(&d).map_err(|e| format!("{}: {e}", d.display()))?;
            let w = |name: &str, bytes: &[u8]| write_atomic(&d.join(name), bytes).map_err(|e| format!("{}/{name}: {e}", d.display()));
            w("imu.log", &r.log)?;
            w("import.toml", r.import.snippet.as_bytes())?;
            w("config.toml", r.config.to_toml().as_bytes())?;
            let src = list.iter().find(|p| p.ends_with(&r.name)).map(|p| p.display().to_string()).unwrap_or_default();
            r.eval.write(&d, &format!("{src}/imu.csv.gz"), &format!("{src}/reference.csv.gz"))?;
            rows.push(Row {
                recording: &r.name,
                samples: r.eval.samples,
                rate_hz: r.import.timing.rate_hz,
                magnetometer: r.eval.magnetometer,
                alignment: &r.eval.alignment,
                ours: &r.eval.results[0].scores,
                vqf: r.eval.results.get(1).map(|x| &x.scores),
            });
        }
        let json = serde_json::to_string_pretty(&rows).map_err(|e| e.to_string())?;
        write_atomic(&od.join("realdata.json"), json.as_bytes()).map_err(|e| format!("{}/realdata.json: {e}", od.display()))?;
        s += &format!("wrote {}/realdata.json and a folder per recording\n", od.display());
    }
    Ok(Table { text: s, failed })
}
