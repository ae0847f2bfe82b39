//! Several trials of one unit: `gap --measured A B ... --reference RA RB ...`.
//!
//! 1. Every trial goes through the workflow alone (its outputs in
//!    `DIR/<trial>/`).
//! 2. The terms named on any trial are fitted on **every** trial together
//!    with the base model's free terms (a fixed set, nothing named), giving
//!    each coefficient per trial with its standard error.
//! 3. Per term: the inverse-variance weighted joint estimate and the
//!    consistency test `chi2 = sum (b_i - b)^2 / se_i^2` on `n - 1` degrees
//!    of freedom against its 1 % critical value. A term is **added** to the
//!    joint model (`DIR/model.toml`) when it was named on at least two trials,
//!    the trials agree (chi2 below the 1 % value) and the joint |t| >= 4. A
//!    term named on one trial only is reported as such and not added; one the
//!    trials disagree on is reported as inconsistent and not added.
//! 4. Leave-one-trial-out: for each trial, steps 2-3 on the others give a
//!    joint model; the held-out trial's residual (RMS of 1-s means, the base
//!    model's free terms fitted) with the base model and with that model,
//!    side by side, on the axes of the terms it adds.
//!
//! The unit's turn-on bias is a property of a power-on, not of the unit: it
//! stays free in every model (as the base model has it).

use super::fit::{all_terms, Term, AX};
use super::name::T_MIN;
use super::read::{has_table, load_base};
use super::refdata::Derived;
use super::{inputs, prepare, report, GapOptions, GapResult, Source, Truth};
use crate::adis::{builtin_profile, Profile};
use crate::sim::model::{Effect, GyroModel, SensorModel};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Two-sided 1 % level of the consistency test.
pub const CONSISTENCY_LEVEL: f64 = 0.01;

/// One trial: its name, its data and its own workflow run.
pub struct Trial {
    pub name: String,
    pub data: Derived,
    pub result: GapResult,
}

/// One coefficient on one trial.
#[derive(Clone, Debug, Serialize)]
pub struct PerTrial {
    pub trial: String,
    pub coefficient: f64,
    pub std_error: f64,
    /// Named by the trial's own workflow.
    pub named: bool,
}

/// One term across the trials.
#[derive(Clone, Debug, Serialize)]
pub struct TermRow {
    pub term: String,
    pub unit: String,
    pub per_trial: Vec<PerTrial>,
    pub named_on: usize,
    pub chi2: f64,
    pub dof: usize,
    pub chi2_critical: f64,
    pub consistent: bool,
    pub joint: f64,
    pub joint_std_error: f64,
    pub joint_t: f64,
    pub added: bool,
    pub verdict: String,
}

/// The chi-square quantile (Wilson-Hilferty) at upper-tail probability `p` (z for p = 0.01: 2.3263).
pub fn chi2_critical(dof: usize, p: f64) -> f64 {
    let z = if (p - 0.01).abs() < 1e-12 { 2.326_347_874 } else { inv_normal_upper(p) };
    let k = dof.max(1) as f64;
    let c = 1.0 - 2.0 / (9.0 * k) + z * (2.0 / (9.0 * k)).sqrt();
    k * c * c * c
}

/// Upper-tail normal quantile by bisection on erfc (only used for p other than 1 %).
fn inv_normal_upper(p: f64) -> f64 {
    let (mut lo, mut hi) = (-10.0f64, 10.0f64);
    for _ in 0..200 {
        let m = 0.5 * (lo + hi);
        if 0.5 * libm_erfc(m / std::f64::consts::SQRT_2) > p {
            lo = m;
        } else {
            hi = m;
        }
    }
    0.5 * (lo + hi)
}

/// erfc (Abramowitz-Stegun 7.1.26, |error| < 1.5e-7).
fn libm_erfc(x: f64) -> f64 {
    let t = 1.0 / (1.0 + 0.327_591_1 * x.abs());
    let y = t * (0.254_829_592 + t * (-0.284_496_736 + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
    let e = y * (-x * x).exp();
    if x >= 0.0 {
        e
    } else {
        2.0 - e
    }
}

/// The term of a finding's label.
fn term_of(label: &str) -> Option<Term> {
    Effect::ALL.iter().flat_map(|e| all_terms(*e)).find(|t| t.label() == label)
}

/// The terms named on the trials `idx`, in a fixed order (the vocabulary's).
fn named_terms(trials: &[Trial], idx: &[usize]) -> Vec<Term> {
    let named: Vec<Term> = idx.iter().flat_map(|&i| trials[i].result.report.findings.iter().filter_map(|f| term_of(&f.term))).collect();
    Effect::ALL.iter().flat_map(|e| all_terms(*e)).filter(|t| named.contains(t)).collect()
}

/// `terms` fitted with the base model's free terms on one trial: (coefficient, standard error) each.
pub fn fit_fixed(d: &Derived, base: &SensorModel, profile: &Profile, terms: &[Term]) -> Result<Vec<(f64, f64)>, String> {
    let mut p = prepare(&d.meas, &d.truth, d.truth_has_temp, base, profile, Some(&d.info))?;
    let mut all = p.free.clone();
    all.extend_from_slice(terms);
    let warm = all.iter().any(|t| t.effect == Effect::WarmupTransient);
    let f = p
        .design
        .fit_any(&all, if warm { f64::NAN } else { p.base_tau }, true)
        .ok_or("the trial's terms cannot be fitted together (singular)")?;
    terms
        .iter()
        .map(|t| f.index(t).map(|k| (f.beta[k], f.se(k))).ok_or_else(|| format!("{} could not be fitted on this trial", t.label())))
        .collect()
}

/// The joint estimate and the consistency of one term over the trials `idx`.
fn judge(term: &Term, trials: &[Trial], idx: &[usize], fits: &[Vec<(f64, f64)>], col: usize) -> TermRow {
    let per: Vec<PerTrial> = idx
        .iter()
        .zip(fits)
        .map(|(&i, f)| PerTrial {
            trial: trials[i].name.clone(),
            coefficient: f[col].0,
            std_error: f[col].1,
            named: trials[i].result.report.findings.iter().any(|x| x.term == term.label()),
        })
        .collect();
    let w: f64 = per.iter().map(|p| 1.0 / (p.std_error * p.std_error)).sum();
    let joint = per.iter().map(|p| p.coefficient / (p.std_error * p.std_error)).sum::<f64>() / w;
    let joint_se = 1.0 / w.sqrt();
    let chi2: f64 = per.iter().map(|p| ((p.coefficient - joint) / p.std_error).powi(2)).sum();
    let dof = per.len().saturating_sub(1);
    let crit = chi2_critical(dof, CONSISTENCY_LEVEL);
    let consistent = dof == 0 || chi2 <= crit;
    let named_on = per.iter().filter(|p| p.named).count();
    let joint_t = joint / joint_se;
    let (added, verdict) = if named_on < 2 {
        (false, format!("named on {named_on} trial only: not added"))
    } else if !consistent {
        (false, format!("the trials disagree (chi2 {chi2:.1} > {crit:.1} on {dof} dof, 1 %): not added"))
    } else if joint_t.abs() < T_MIN {
        (false, format!("joint |t| = {:.1} < {T_MIN}: not added", joint_t.abs()))
    } else {
        (true, format!("consistent (chi2 {chi2:.1} <= {crit:.1} on {dof} dof), named on {named_on} trials: added"))
    };
    TermRow {
        term: term.label(),
        unit: term.unit().into(),
        per_trial: per,
        named_on,
        chi2,
        dof,
        chi2_critical: crit,
        consistent,
        joint,
        joint_std_error: joint_se,
        joint_t,
        added,
        verdict,
    }
}

/// Steps 2-3 over the trials `idx`: one row per term named on any of them.
pub fn joint_rows(trials: &[Trial], idx: &[usize], base: &SensorModel, profile: &Profile) -> Result<Vec<TermRow>, String> {
    let terms = named_terms(trials, idx);
    if terms.is_empty() {
        return Ok(vec![]);
    }
    let fits: Vec<Vec<(f64, f64)>> = idx
        .iter()
        .map(|&i| fit_fixed(&trials[i].data, base, profile, &terms).map_err(|e| format!("{}: {e}", trials[i].name)))
        .collect::<Result<_, _>>()?;
    Ok(terms.iter().enumerate().map(|(c, t)| judge(t, trials, idx, &fits, c)).collect())
}

/// Remove an effect's coefficient table (it is free again).
fn clear_table(g: &mut GyroModel, e: Effect) {
    match e {
        Effect::TurnOnBias => g.turn_on_bias = None,
        Effect::ThermalLinear => g.thermal_linear = None,
        Effect::ThermalQuadratic => g.thermal_quadratic = None,
        Effect::ThermalRate => g.thermal_rate = None,
        Effect::WarmupTransient => g.warmup_transient = None,
        Effect::GSensitivity => g.g_sensitivity = None,
        Effect::ScaleFactor => g.scale_factor = None,
        Effect::Misalignment => g.misalignment = None,
        Effect::TimeDelay => g.time_delay = None,
    }
}

/// The base model with the added terms fixed at their joint values (other
/// coefficients of the same effect 0); the base model's free effects stay free.
pub fn joint_model(base: &SensorModel, rows: &[TermRow]) -> SensorModel {
    let added: Vec<(Term, f64)> = rows.iter().filter(|r| r.added).filter_map(|r| term_of(&r.term).map(|t| (t, r.joint))).collect();
    let effects: Vec<Effect> = Effect::ALL.iter().copied().filter(|e| added.iter().any(|(t, _)| t.effect == *e)).collect();
    let coef = |e: Effect, i: usize, j: usize| {
        let i = if e == Effect::TimeDelay { 3 } else { i };
        added
            .iter()
            .find(|(t, _)| t.effect == e && t.axis == i && (t.col == j || !matches!(e, Effect::GSensitivity | Effect::Misalignment)))
            .map_or(0.0, |x| x.1)
    };
    let mut m = report::extended_model(base, coef, f64::NAN, &effects);
    for e in base.gyro.effects.iter().filter(|e| !has_table(&base.gyro, **e) && !effects.contains(e)) {
        clear_table(&mut m.gyro, *e);
    }
    m
}

/// The residual RMS of 1-s means per axis with `model` (its free terms fitted) on one trial.
pub fn residual_rms(d: &Derived, model: &SensorModel, profile: &Profile) -> Result<[f64; 3], String> {
    let p = prepare(&d.meas, &d.truth, d.truth_has_temp, model, profile, Some(&d.info))?;
    Ok(p.bins.rms_1s(&super::fit::residual(&p.s, &p.base_fit)))
}

/// One held-out trial of the cross-validation.
#[derive(Clone, Debug, Serialize)]
pub struct HeldOut {
    pub trial: String,
    /// The terms the other trials' joint model adds.
    pub added: Vec<String>,
    /// The axes those terms act on (x, y, z).
    pub axes: Vec<String>,
    pub rms_base: [f64; 3],
    pub rms_extended: [f64; 3],
    /// The extended model, as TOML.
    pub model: String,
}

/// The axes a term acts on.
fn term_axes(t: &Term) -> Vec<usize> {
    if t.axis == 3 {
        vec![0, 1, 2]
    } else {
        vec![t.axis]
    }
}

/// Step 4.
pub fn leave_one_out(trials: &[Trial], base: &SensorModel, profile: &Profile) -> Result<Vec<HeldOut>, String> {
    let mut out = Vec::new();
    for i in 0..trials.len() {
        let others: Vec<usize> = (0..trials.len()).filter(|&k| k != i).collect();
        let rows = joint_rows(trials, &others, base, profile)?;
        let model = joint_model(base, &rows);
        let added: Vec<Term> = rows.iter().filter(|r| r.added).filter_map(|r| term_of(&r.term)).collect();
        let mut axes: Vec<usize> = added.iter().flat_map(term_axes).collect();
        axes.sort();
        axes.dedup();
        let name = &trials[i].name;
        let rms_base = residual_rms(&trials[i].data, base, profile).map_err(|e| format!("{name} (base model): {e}"))?;
        let rms_extended = residual_rms(&trials[i].data, &model, profile).map_err(|e| format!("{name} (extended model): {e}"))?;
        out.push(HeldOut {
            trial: name.clone(),
            added: added.iter().map(|t| t.label()).collect(),
            axes: axes.iter().map(|a| AX[*a].to_string()).collect(),
            rms_base,
            rms_extended,
            model: model.to_toml(),
        });
    }
    Ok(out)
}

/// A trial's name: the measured file's folder for `imu.csv[.gz]` / `imu.log`, else its stem; made unique.
pub(crate) fn trial_names(paths: &[PathBuf]) -> Vec<String> {
    let mut names: Vec<String> = paths
        .iter()
        .map(|p| {
            let stem = p.file_name().map(|n| n.to_string_lossy().to_string()).unwrap_or_default();
            let stem = stem.split('.').next().unwrap_or("").to_string();
            let dir = p.parent().and_then(|d| d.file_name()).map(|n| n.to_string_lossy().to_string());
            match dir {
                Some(d) if stem == "imu" && !d.is_empty() => d,
                _ => stem,
            }
        })
        .collect();
    let orig = names.clone();
    for (i, n) in names.iter_mut().enumerate() {
        if n.is_empty() || orig.iter().filter(|o| *o == n).count() > 1 {
            *n = format!("trial{}-{n}", i + 1);
        }
    }
    names
}

/// The `gap` subcommand with several trials.
pub fn cli(trials_in: &[(PathBuf, Truth)], model: &Path, out: &Path, profile_name: &str) -> Result<(), String> {
    let profile = builtin_profile(profile_name).ok_or_else(|| format!("unknown profile {profile_name:?}"))?;
    let base = load_base(model)?;
    let names = trial_names(&trials_in.iter().map(|t| t.0.clone()).collect::<Vec<_>>());
    let mut inputs: Vec<&Path> = vec![model];
    for (m, t) in trials_in {
        inputs.push(m);
        if let Truth::Reference { path, .. } | Truth::Simulated(path) = t {
            inputs.push(path);
        }
    }
    let mut trials = Vec::new();
    for ((m, truth), name) in trials_in.iter().zip(&names) {
        let o = GapOptions {
            measured: m.clone(),
            truth: match truth {
                Truth::Reference { path, .. } | Truth::Simulated(path) => path.clone(),
                Truth::Static { .. } => m.clone(),
            },
            model: model.to_path_buf(),
            out: out.join(name),
            profile: profile_name.into(),
            plots: true,
        };
        let mut t = inputs::trial(name, &Source::File(m.clone()), &truth.source(), &base, &profile).map_err(|e| format!("{name}: {e}"))?;
        t.result.files = report::write_outputs(&o, &t.result.report, &t.result.model, t.result.plots.as_ref())?;
        trials.push(t);
    }
    let j = joint(&trials, &base, &profile)?;
    let text = super::trials_report::render(&trials, &j.rows, &j.leave_one_out, model, out);
    print!("{text}");
    super::trials_report::write(out, &inputs, &text, &j)?;
    Ok(())
}

/// Steps 2-4 on every trial: what `trials.json` holds ([`Joint::to_json`]) and the joint model.
pub struct Joint {
    pub rows: Vec<TermRow>,
    pub leave_one_out: Vec<HeldOut>,
    pub model: SensorModel,
}

impl Joint {
    /// `trials.json`: the terms across the trials, leave-one-trial-out and the consistency level.
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({ "effects": self.rows, "leave_one_out": self.leave_one_out, "consistency_level": CONSISTENCY_LEVEL })
    }
}

/// The joint analysis of trials each run alone (steps 2-4).
pub fn joint(trials: &[Trial], base: &SensorModel, profile: &Profile) -> Result<Joint, String> {
    let all: Vec<usize> = (0..trials.len()).collect();
    let rows = joint_rows(trials, &all, base, profile)?;
    let model = joint_model(base, &rows);
    let leave_one_out = leave_one_out(trials, base, profile)?;
    Ok(Joint { rows, leave_one_out, model })
}

#[cfg(test)]
mod tests {
    use super::super::read::fixed_effects;
    use super::*;

    #[test]
    fn the_chi2_critical_values_at_1_percent() {
        // tables: 6.635 (1), 9.210 (2), 13.277 (4), 23.209 (10)
        for (k, v) in [(1, 6.635), (2, 9.210), (4, 13.277), (10, 23.209)] {
            let c = chi2_critical(k, 0.01);
            assert!((c - v).abs() / v < 0.02, "dof {k}: {c} vs {v}");
        }
        assert!((inv_normal_upper(0.01) - 2.3263).abs() < 1e-3);
    }

    #[test]
    fn names_from_folders_and_unique() {
        let n = trial_names(&[PathBuf::from("/a/broad-05/imu.csv.gz"), PathBuf::from("/b/x.log"), PathBuf::from("/c/x.csv")]);
        assert_eq!(n, vec!["broad-05", "trial2-x", "trial3-x"]);
    }

    #[test]
    fn the_joint_model_keeps_the_base_free_terms_free() {
        let base = super::super::parse_base("[gyro]\neffects = [\"turn_on_bias\"]\n").unwrap();
        let row = |term: &str, added: bool, joint: f64| TermRow {
            term: term.into(),
            unit: String::new(),
            per_trial: vec![],
            named_on: 2,
            chi2: 0.0,
            dof: 1,
            chi2_critical: 6.6,
            consistent: true,
            joint,
            joint_std_error: 1.0,
            joint_t: 10.0,
            added,
            verdict: String::new(),
        };
        let m = joint_model(
            &base,
            &[row("time_delay", true, 0.004), row("misalignment m[z][y]", true, -0.005), row("scale_factor x", false, 0.1)],
        );
        assert!(m.gyro.turn_on_bias.is_none() && m.gyro.effects.contains(&Effect::TurnOnBias));
        assert_eq!(m.gyro.time_delay.as_ref().unwrap().delay_s, 0.004);
        let mis = m.gyro.misalignment.as_ref().unwrap().m;
        assert_eq!(mis[2][1], -0.005);
        assert_eq!(mis.iter().flatten().filter(|x| **x != 0.0).count(), 1);
        assert!(m.gyro.scale_factor.is_none() && !m.gyro.effects.contains(&Effect::ScaleFactor));
        assert_eq!(fixed_effects(&m.gyro), vec![Effect::Misalignment, Effect::TimeDelay]);
    }
}
