//! Evaluating many seeds of a scenario: each simulated in memory, every
//! case scored per seed (one progress line per seed on stderr), then the
//! summary over the seeds (worst, median, ratio to the oracle floor) and
//! with `--out` report.json.
//!
//! With `--peers`, VQF and Fusion ([`crate::peers`]) run on the very samples
//! ours decodes from each seed's frames (with the magnetometer when ours used
//! it, as `evaluate --realdata` runs them), and are scored as ours is, over
//! the same windows, after their own yaw offset is removed
//! ([`super::metrics::peer_track`]: their heading has an origin of its own).
//! They declare no standstill, learn a bias ours does not score, and have no
//! modes: those cells are '-'.

use super::{
    cases, oracle, peer_track, score, score_attitude, table::num, write_reports, EvalOptions, Metrics, RunData, Table, Window, MOVING_MPS,
};
use crate::config::Config;
use crate::sim::{self, SimOptions};
use serde::Serialize;
use std::path::Path;

/// One seed's results.
#[derive(Clone, Debug, Serialize)]
pub struct SeedRow {
    pub seed: u64,
    /// Scored from `score_from`: ours (each case), then the peers.
    pub cases: Vec<Metrics>,
    /// Scored over the manoeuvres only (the oracle floor's window).
    pub manoeuvres: Vec<Metrics>,
    pub oracle: Metrics,
}

/// The peers `--peers` runs beside ours, in their row order.
pub const PEERS: [&str; 2] = ["vqf", "fusion"];

/// A peer's name and its roll, pitch, yaw per sample (deg).
pub type PeerTrack = (&'static str, Vec<[f64; 3]>);

/// The peers over a run's samples (decoded with `cfg`, the config ours ran
/// with; 9D when `magn`, as ours used the magnetometer), each with its yaw
/// offset removed: (name, roll/pitch/yaw per sample, deg).
pub fn run_peers(data: &RunData, cfg: &Config, magn: bool) -> Result<Vec<PeerTrack>, String> {
    let samples = data.samples(cfg)?;
    if samples.len() != data.truth.len() {
        return Err(format!(
            "{} samples decoded for {} truth rows: the peers cannot be scored against the truth",
            samples.len(),
            data.truth.len()
        ));
    }
    let period = 1.0 / cfg.profile().rate_hz;
    let vqf = crate::peers::run_vqf(&samples, period, magn);
    let fusion = crate::peers::run_fusion(&samples, period, magn);
    Ok(vec![(PEERS[0], peer_track(data, &vqf).0), (PEERS[1], peer_track(data, &fusion).0)])
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
    let peers: &[&str] = if o.peers { &PEERS } else { &[] };
    let names: Vec<String> = case_list.iter().map(|(n, _)| n.clone()).chain(peers.iter().map(|p| p.to_string())).collect();
    let mut out = String::new();
    let per_seed = per_seed_table();
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
            let head = per_seed_head(&per_seed, &w, o.score_from);
            eprint!("{head}");
            out += &head;
            if w.is_empty() {
                eprintln!("{}", w.warning());
            }
        }
        let w = *win.get_or_insert(w);
        let row = score_seed(&data, seed, &case_list, &w, o)?;
        for line in seed_lines(&per_seed, &row, &w) {
            out += &line;
            eprint!("[{}/{}] {line}", i + 1, list.len());
        }
        rows.push(row);
    }
    let w = win.ok_or("no seed")?;
    out += &summary(sim, &rows, &names, &w, o.score_from);
    if let Some(rd) = &o.out {
        let json = serde_json::to_string_pretty(&rows).map_err(|e| e.to_string())?;
        let inputs: Vec<&Path> = config_path.into_iter().collect();
        write_reports(rd, &inputs, &[("report.json", json.into_bytes())])?;
        out += &format!("wrote {}\n", rd.join("report.json").display());
    }
    Ok(out)
}

/// The per-seed table's columns.
fn per_seed_table() -> Table {
    Table::new(&[
        ("seed", ""),
        ("case", ""),
        ("max roll", "deg"),
        ("max pitch", "deg"),
        ("rms yaw", "deg"),
        ("rms bias", "deg/s"),
        ("t max tilt", "s"),
        ("still moving", "s"),
        ("man max roll", "deg"),
        ("man max pitch", "deg"),
        ("man rms yaw", "deg"),
        ("oracle roll", "deg"),
        ("oracle pitch", "deg"),
    ])
    .text_columns(2)
    .width(0, 5)
    .width(1, 22)
}

/// What the per-seed table's columns mean over these windows, and its header.
fn per_seed_head(per_seed: &Table, w: &Window, score_from: f64) -> String {
    format!(
        "per seed: max roll/pitch, rms yaw, rms bias and the time of the largest tilt error over t = {:.1}..{:.1} s; \
         'still moving' the seconds of the whole run with a standstill declared while the truth moves faster than {MOVING_MPS} m/s \
         ('-': no vehicle truth); 'man' over {}; 'oracle' the oracle floor there\n{}",
        score_from,
        w.end,
        if w.is_empty() { "the manoeuvres (none in these runs)".to_string() } else { format!("t = {:.1}..{:.1} s", w.start, w.end) },
        per_seed.header()
    )
}

/// One seed: every case run and scored from `score_from` and over the
/// manoeuvres, the peers beside them with `--peers`, and the oracle floor.
fn score_seed(data: &RunData, seed: u64, case_list: &[(String, Config)], w: &Window, o: &EvalOptions) -> Result<SeedRow, String> {
    let mut ms = Vec::new();
    let mut man = Vec::new();
    let mut orc = None;
    // the first case's config and magnetometer decision, for the peers
    let mut first: Option<(Config, bool)> = None;
    for (name, c) in case_list {
        let mut c = c.clone();
        if let Some(u) = &data.unit_config {
            c.thermal = u.thermal.clone();
            c.mounting = u.mounting.clone();
            c.speed = u.speed.clone();
        }
        let (est, mode_s, magn) = data.estimates_and_magnetometer(&c)?;
        if orc.is_none() {
            orc = Some(oracle(data, &est, w.start).0);
        }
        let still = data.still_moving(&est);
        ms.push(Metrics { still_moving_s: still, ..score(name, data, &est, mode_s, o.score_from) });
        man.push(Metrics { still_moving_s: still, ..score(name, data, &est, mode_s, w.start) });
        first.get_or_insert((c, magn));
    }
    if o.peers {
        let (c, magn) = first.as_ref().ok_or("no case")?;
        for (name, att) in run_peers(data, c, *magn).map_err(|e| format!("seed {seed}: {e}"))? {
            ms.push(score_attitude(name, data, &att, o.score_from));
            man.push(score_attitude(name, data, &att, w.start));
        }
    }
    let oracle = orc.ok_or("no case")?;
    Ok(SeedRow { seed, cases: ms, manoeuvres: man, oracle })
}

/// A seed's lines of the per-seed table, one per case and peer.
fn seed_lines(per_seed: &Table, row: &SeedRow, w: &Window) -> Vec<String> {
    let orc = &row.oracle;
    let gone = |v: f64| if w.is_empty() { "-".to_string() } else { num(v, 3) };
    row.cases
        .iter()
        .zip(&row.manoeuvres)
        .map(|(m, mm)| {
            let brms = (m.bias_rms.iter().map(|b| b * b).sum::<f64>() / 3.0).sqrt();
            per_seed.line(&[
                row.seed.to_string(),
                m.name.clone(),
                num(m.max_err[0], 3),
                num(m.max_err[1], 3),
                num(m.rms_err[2], 3),
                num(brms, 5),
                num(m.t_max_tilt, 1),
                num(m.still_moving_s.unwrap_or(f64::NAN), 2),
                gone(mm.max_err[0]),
                gone(mm.max_err[1]),
                gone(mm.rms_err[2]),
                gone(orc.max_err[0]),
                gone(orc.max_err[1]),
            ])
        })
        .collect()
}

/// The summary over the seeds: its title with the oracle floor, and per
/// case the worst, median and ratio, scored from `score_from` and over the
/// manoeuvres.
fn summary(sim: &SimOptions, rows: &[SeedRow], names: &[String], w: &Window, score_from: f64) -> String {
    let mut out = String::new();
    let orc_med = median(&rows.iter().map(|r| r.oracle.tilt_max()).collect::<Vec<_>>());
    let name =
        format!("{}{}{}", sim.scenario, if sim.hard { " --hard" } else { "" }, if sim.power_on_moving { " --power-on-moving" } else { "" });
    let duration = sim.duration.unwrap_or_else(|| sim::scenario::default_duration_of(&sim.scenario, sim.hard));
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
    let table = Table::new(&[
        ("case", ""),
        ("worst roll", "deg"),
        ("worst pitch", "deg"),
        ("median max", "deg"),
        ("ratio to oracle", "x"),
        ("worst rms yaw", "deg"),
        ("seeds <= 2 deg", "of total"),
        ("worst seed", ""),
        ("worst still moving", "s"),
    ])
    .width(0, 22);
    let mut windows = vec![(format!("scored over t = {:.1}..{:.1} s", score_from, w.end), false)];
    if !w.is_empty() {
        windows.push((w.title(&sim.scenario), true));
    }
    for (title, man) in windows {
        out += &format!("-- {title}\n");
        out += &table.header();
        for (ci, name) in names.iter().enumerate() {
            let pick = |r: &SeedRow| if man { r.manoeuvres[ci].clone() } else { r.cases[ci].clone() };
            let per: Vec<Metrics> = rows.iter().map(pick).collect();
            let wr = per.iter().map(|m| m.max_err[0]).fold(0.0, f64::max);
            let wp = per.iter().map(|m| m.max_err[1]).fold(0.0, f64::max);
            let med = median(&per.iter().map(|m| m.tilt_max()).collect::<Vec<_>>());
            let wy = per.iter().map(|m| m.rms_err[2]).fold(0.0, f64::max);
            let ok = per.iter().filter(|m| m.tilt_max() <= 2.0).count();
            let worst = rows.iter().zip(&per).max_by(|a, b| a.1.tilt_max().total_cmp(&b.1.tilt_max())).map(|r| r.0.seed).unwrap_or(0);
            out += &table.line(&[
                name.clone(),
                num(wr, 3),
                num(wp, 3),
                num(med, 3),
                if ratio_ok { num(med / orc_med, 2) } else { "-".into() },
                num(wy, 3),
                format!("{ok}/{}", rows.len()),
                worst.to_string(),
                num(per.iter().filter_map(|m| m.still_moving_s).fold(f64::NAN, f64::max), 2),
            ]);
        }
    }
    out
}
