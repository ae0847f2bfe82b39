//! `gyrocomp evaluate --ablate`: every named situation rule of the default
//! filter (`estimator::mekf::Rule`) switched off alone, next to the default,
//! on the simulated families (`--seeds`) and the real recordings
//! (`--realdata`). A rule earns its place where switching it off makes the
//! figures worse, on data it was not shaped on.

use super::data::RunData;
use super::metrics::score;
use crate::config::Config;
use crate::estimator::mekf::Rule;
use crate::sim::SimOptions;
use std::path::Path;

/// A simulated family: a scenario, with --hard, powered on moving.
#[derive(Clone, Debug, PartialEq)]
pub struct Family {
    pub scenario: String,
    pub hard: bool,
    pub power_on_moving: bool,
}

impl Family {
    pub fn new(scenario: &str, hard: bool, power_on_moving: bool) -> Family {
        Family { scenario: scenario.into(), hard, power_on_moving }
    }

    /// "smooth hard pom".
    pub fn label(&self) -> String {
        format!("{}{}{}", self.scenario, if self.hard { " hard" } else { "" }, if self.power_on_moving { " pom" } else { "" })
    }
}

/// The vehicle families the rules are weighed on (the hand-held unit's are
/// the real BROAD recordings).
pub fn families() -> Vec<Family> {
    [
        ("smooth", false, false),
        ("smooth", false, true),
        ("smooth", true, false),
        ("crawl", false, false),
        ("crawl", false, true),
        ("urban", false, false),
        ("urban", false, true),
        ("vehicle", true, false),
    ]
    .iter()
    .map(|(s, h, p)| Family::new(s, *h, *p))
    .collect()
}

/// Worst max roll and pitch over the seeds (deg) and the worst seconds of
/// standstill declared while the truth moved.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Worst {
    pub roll: f64,
    pub pitch: f64,
    pub still_moving_s: f64,
}

impl Worst {
    fn tilt(&self) -> f64 {
        self.roll.max(self.pitch)
    }
}

/// The rows of the ablation: "default" and one per rule switched off.
fn variants(base: &Config, rules: &[Rule]) -> Vec<(String, Config)> {
    let mut out = vec![("default".to_string(), base.clone())];
    for r in rules {
        let mut c = base.clone();
        c.mekf.ablate = vec![r.name().to_string()];
        out.push((format!("-{}", r.name()), c));
    }
    out
}

/// Worst figures per variant on one family over `seeds` (each seed
/// simulated once, every variant replayed on it), from `score_from` s.
pub fn family(
    base: &Config,
    f: &Family,
    seeds: std::ops::RangeInclusive<u64>,
    duration: Option<f64>,
    rules: &[Rule],
    score_from: f64,
) -> Result<Vec<Worst>, String> {
    let vars = variants(base, rules);
    let mut worst = vec![Worst::default(); vars.len()];
    for seed in seeds {
        let mut so = SimOptions::new(&f.scenario, seed);
        so.hard = f.hard;
        so.power_on_moving = f.power_on_moving;
        so.duration = duration;
        so.profile = base.input.profile.clone();
        let data = RunData::simulate(&so).map_err(|e| format!("{} seed {seed}: {e}", f.label()))?;
        for ((_, c), w) in vars.iter().zip(worst.iter_mut()) {
            let mut c = c.clone();
            if let Some(u) = &data.unit_config {
                c.thermal = u.thermal.clone();
                c.mounting = u.mounting.clone();
            }
            let (est, mode_s) = data.estimates(&c)?;
            let m = score("", &data, &est, mode_s, score_from);
            w.roll = w.roll.max(m.max_err[0]);
            w.pitch = w.pitch.max(m.max_err[1]);
            w.still_moving_s = w.still_moving_s.max(data.still_moving(&est).unwrap_or(0.0));
        }
        eprintln!("[ablate] {} seed {seed}: {} variants", f.label(), vars.len());
    }
    Ok(worst)
}

/// Roll and pitch RMS (deg) of ours per variant on one recording.
pub fn recording(base: &Config, dir: &Path, rules: &[Rule]) -> Result<Vec<(f64, f64)>, String> {
    let o = crate::reference::RefOptions::default();
    variants(base, rules)
        .iter()
        .map(|(_, c)| {
            let r = crate::reference::realdata::evaluate_recording(dir, c, &o)?;
            let s = &r.eval.results.first().ok_or("no result")?.scores;
            Ok((s.roll.rms, s.pitch.rms))
        })
        .collect()
}

/// What `--ablate` runs.
pub struct AblateRun<'a> {
    pub seeds: Option<std::ops::RangeInclusive<u64>>,
    /// One family (with --scenario), else [`families`].
    pub families: Vec<Family>,
    pub duration: Option<f64>,
    pub realdata: Option<&'a Path>,
    pub rules: Vec<Rule>,
    pub score_from: f64,
}

/// The rules named in a comma list (all when None).
pub fn parse_rules(list: Option<&str>) -> Result<Vec<Rule>, String> {
    match list {
        None => Ok(Rule::ALL.to_vec()),
        Some(s) => {
            s.split(',').map(|n| n.trim()).filter(|n| !n.is_empty()).map(|n| Rule::parse(n).map_err(|e| format!("--rules: {e}"))).collect()
        }
    }
}

/// The ablation tables: the families' worst roll / pitch (and the worst
/// seconds of a standstill declared while moving), and the recordings' roll
/// / pitch RMS; a verdict per rule: on how many columns switching it off
/// made the worst tilt (families; or the seconds of a standstill declared
/// while moving, by 5 % and 1 s) or the tilt RMS (recordings) worse or
/// better by more than 5 %.
pub fn run(base: &Config, a: &AblateRun) -> Result<String, String> {
    if a.rules.is_empty() {
        return Err("--ablate: no rule to switch off".into());
    }
    let vars = variants(base, &a.rules);
    let mut cols: Vec<String> = Vec::new();
    // per column: per variant (a, b, tilt measure)
    let mut cells: Vec<Vec<(f64, f64, f64)>> = Vec::new();
    let mut still: Vec<Vec<f64>> = Vec::new();
    if let Some(seeds) = &a.seeds {
        for f in &a.families {
            let w = family(base, f, seeds.clone(), a.duration, &a.rules, a.score_from)?;
            cols.push(f.label());
            cells.push(w.iter().map(|w| (w.roll, w.pitch, w.tilt())).collect());
            still.push(w.iter().map(|w| w.still_moving_s).collect());
        }
    }
    let n_fam = cols.len();
    if let Some(dir) = a.realdata {
        for rec in crate::reference::realdata::recordings(dir)? {
            let name = rec.file_name().map(|n| n.to_string_lossy().to_string()).unwrap_or_default();
            let r = recording(base, &rec, &a.rules).map_err(|e| format!("{name}: {e}"))?;
            eprintln!("[ablate] {name}: {} variants", r.len());
            cols.push(name);
            cells.push(r.iter().map(|(x, y)| (*x, *y, x.hypot(*y))).collect());
        }
    }
    if cols.is_empty() {
        return Err("--ablate needs --seeds A..B (the simulated families) and/or --realdata DIR".into());
    }
    let mut out = String::new();
    out += "ablation: each named rule of the default filter switched off alone ([mekf] ablate = [\"name\"]), next to the default\n";
    if let Some(s) = &a.seeds {
        out += &format!(
            "families: worst max roll / pitch over seeds {}..{} from {} s (deg), and the worst seconds of a standstill declared while the truth moved faster than 0.5 m/s\n",
            s.start(),
            s.end(),
            a.score_from
        );
    }
    if a.realdata.is_some() {
        out += "recordings: roll / pitch RMS of ours (deg), as `evaluate --realdata` scores them\n";
    }
    out += "verdict: columns where the rule's absence made the worst tilt (the larger of roll and pitch) or, on the families, the seconds of a standstill declared while moving worse / better by more than 5 % (and 1 s); the recordings by their tilt RMS\n";
    out += &format!("{:<24}", "variant");
    for (k, c) in cols.iter().enumerate() {
        out += &format!(" | {:>20}", if k < n_fam { format!("{c} (still s)") } else { c.clone() });
    }
    out += " | verdict\n";
    for (v, (name, _)) in vars.iter().enumerate() {
        out += &format!("{name:<24}");
        let (mut worse, mut better) = (0, 0);
        for (k, col) in cells.iter().enumerate() {
            let (x, y, t) = col[v];
            let s = if k < n_fam { format!("{x:.2}/{y:.2} ({:.0})", still[k][v]) } else { format!("{x:.3}/{y:.3}") };
            out += &format!(" | {s:>20}");
            let t0 = col[0].2;
            // a standstill declared while moving counts as much as the tilt
            let (s, s0) = if k < n_fam { (still[k][v], still[k][0]) } else { (0.0, 0.0) };
            let more_still = s > 1.05 * s0 && s > s0 + 1.0;
            let less_still = s < s0 / 1.05 && s < s0 - 1.0;
            if v > 0 && (t > 1.05 * t0 || (more_still && t >= t0 / 1.05)) {
                worse += 1;
            } else if v > 0 && (t < t0 / 1.05 || less_still) {
                better += 1;
            }
        }
        if v == 0 {
            out += " |\n";
        } else {
            out += &format!(" | worse {worse} / better {better}\n");
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rules_are_parsed_by_name_and_an_unknown_one_is_named() {
        assert_eq!(parse_rules(None).unwrap().len(), Rule::ALL.len());
        assert_eq!(parse_rules(Some("cruise, level_rate")).unwrap(), vec![Rule::Cruise, Rule::LevelRate]);
        let e = parse_rules(Some("cruise,nope")).unwrap_err();
        assert!(e.contains("\"nope\"") && e.contains("forward_speed_bound"), "{e}");
    }

    #[test]
    fn a_rule_switched_off_changes_the_filter_and_the_default_is_the_default() {
        // urban powered on moving runs the speed bank; switched off, the
        // filter keeps its zero-speed start and the figures differ
        let base = Config::default();
        let f = Family::new("urban", false, true);
        let w = family(&base, &f, 1..=1, Some(60.0), &[Rule::SpeedHypotheses], 10.0).unwrap();
        assert_eq!(w.len(), 2);
        assert!(w.iter().all(|w| w.roll.is_finite() && w.pitch.is_finite()));
        assert_ne!(w[0], w[1], "switching the bank off changed nothing");
        let again = family(&base, &f, 1..=1, Some(60.0), &[], 10.0).unwrap();
        assert_eq!(again[0], w[0], "the default row is the default filter");
    }
}
