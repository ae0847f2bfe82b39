//! Step 4, **name**: every coefficient of the vocabulary not yet in the model
//! (per axis; per matrix element for `g_sensitivity` and `misalignment`; one
//! delay shared by all axes for `time_delay`) is fitted jointly with the
//! current model, and judged by its own t statistic (coefficient over its
//! standard error with the white + random-walk noise model, see
//! [`super::fit`]). The rule, in order:
//!
//! - **separable**: its whitened regressor is not collinear with the current
//!   model's (R^2 < [`COLLINEAR_R2`]); otherwise it is listed as *not separable
//!   with this data* (no excitation, e.g. `scale_factor` on a bench at rest,
//!   or collinear, e.g. `g_sensitivity` to a constant gravity against a
//!   turn-on bias);
//! - **significant**: |t| >= [`T_MIN`]. With about 35 candidates per round
//!   this is a family-wise false-find rate of about 0.2 % per round on data
//!   with nothing missing (Bonferroni: 35 x 2 x (1 - Phi(4)) = 0.0022);
//! - a negative `time_delay` (the measured rate leads the truth) is not a
//!   delay: it is reported, not added;
//! - **told apart from its rivals**: the most significant candidate `b` is
//!   fitted jointly with every other significant candidate `c` that shares an
//!   axis with it. When `b` stays significant given `c`, `c` does not compete.
//!   When it does not but `c` stays significant given `b`, `c` is the better
//!   explanation and takes `b`'s place. When neither stays significant given
//!   the other, the data cannot tell them apart: both are reported as *not
//!   separable with this data* and neither is added -- except that
//!   `turn_on_bias` is the limit of `warmup_transient` (time constant to
//!   infinity), so of that pair the simpler is taken. A later candidate (or
//!   pair) that is not significant when fitted together with the terms of
//!   such pairs on its axes explains what the data could not assign and
//!   would be a guess as well: it is reported (`unassigned`), not added;
//! - it is added; a term found earlier that is no longer significant in the
//!   joint fit (a later finding explains what it did) is withdrawn;
//! - when no candidate is significant alone, pairs sharing an axis are
//!   tried: two effects can hide each other (see `pair_search`). The best
//!   pair is added when its joint whitened chi-square drop reaches
//!   `2 ln(pairs tried / PAIR_FAMILY_RATE)` (Bonferroni, the same 0.2 %
//!   family-wise rate) and both are significant in it.
//!
//! The loop stops when nothing passes (at most [`MAX_FINDINGS`]).

use super::fit::{all_terms, contribution_rms, residual, Design, Fit, Term, COLLINEAR_R2};
use super::localise::{variable, Bins, Localisation, Strongest};
use super::read::Samples;
use crate::sim::model::Effect;
use serde::Serialize;

/// A candidate is significant when |coefficient / standard error| reaches this.
pub const T_MIN: f64 = 4.0;
/// At most this many effects are added.
pub const MAX_FINDINGS: usize = 12;
/// Family-wise false-find rate of one round of the pair search.
pub const PAIR_FAMILY_RATE: f64 = 0.002;

#[derive(Clone, Debug, Serialize)]
pub struct NotSeparable {
    pub effect: String,
    pub term: String,
    pub axis: String,
    pub reason: String,
}

#[derive(Clone, Debug, Serialize)]
pub struct Ambiguity {
    pub effects: [String; 2],
    pub terms: [String; 2],
    pub axis: String,
    /// t of each alone (added to the current model).
    pub t_alone: [f64; 2],
    /// t of each when both are fitted.
    pub t_joint: [f64; 2],
    pub reason: String,
}

/// A term found earlier and withdrawn (no longer significant once a later one was added).
#[derive(Clone, Debug, Serialize)]
pub struct Withdrawn {
    pub term: String,
    pub t_stat: f64,
    pub after: String,
}

/// What this data could detect: a candidate's standard error on the base model's residual.
#[derive(Clone, Debug, Serialize)]
pub struct Sensitivity {
    pub term: String,
    pub unit: String,
    pub std_error: f64,
    /// `T_MIN` standard errors: the smallest coefficient that would be found.
    pub min_detectable: f64,
}

/// A candidate evaluated against the current model.
struct Cand {
    term: Term,
    fit: Fit,
    t: f64,
    se: f64,
    r2: f64,
}

impl Cand {
    fn k(&self) -> usize {
        self.fit.terms.len() - 1
    }
}

/// One finding, with what the report shows about it.
pub(crate) struct Found {
    pub term: Term,
    pub coef_when_found: f64,
    pub se_when_found: f64,
    pub t_when_found: f64,
    pub r2: f64,
    pub rms_before: [f64; 3],
    pub rms_after: [f64; 3],
    pub wrms_before: [f64; 3],
    pub wrms_after: [f64; 3],
    pub contribution_rms: f64,
    /// The axis the localisation shows (for the shared delay: where it explains most).
    pub plot_axis: usize,
    pub loc_before: Localisation,
    pub loc_after: Localisation,
    pub strongest_before: Vec<Strongest>,
    /// (term, t, standard error) of the five most significant candidates.
    pub ranking: Vec<(String, f64, f64)>,
    /// Rivals it was fitted jointly with: (term, t of the rival alone, t of this one given it, t of the rival given this one).
    pub rivals: Vec<(String, f64, f64, f64)>,
    /// Found as a pair (neither significant alone): the other term, the pair's chi-square and its threshold.
    pub jointly: Option<(Vec<String>, f64, f64)>,
}

pub(crate) struct Naming {
    pub fit: Fit,
    pub found: Vec<Found>,
    pub withdrawn: Vec<Withdrawn>,
    pub not_separable: Vec<NotSeparable>,
    pub ambiguous: Vec<Ambiguity>,
    /// Significant candidates not added because they are not significant given the terms left not separable.
    pub unassigned: Vec<String>,
    /// Significant negative delays (measured leads truth), not added.
    pub leads: Vec<String>,
    pub sensitivity: Vec<Sensitivity>,
    /// The residual of the final fit (per sample).
    pub resid: [Vec<f64>; 3],
}

fn whitened_rms(f: &Fit) -> [f64; 3] {
    f.sse_axis.map(|s| (s / f.n.max(1) as f64).sqrt())
}

/// Fit the current model plus `extra` (searching a new warm-up's time constant).
fn fit_with(design: &mut Design, cur: &Fit, extra: &[Term], refine: bool) -> Option<Fit> {
    let mut terms = cur.terms.clone();
    terms.extend_from_slice(extra);
    design.fit_any(&terms, cur.tau, refine)
}

fn nested(simple: &Term, other: &Term) -> bool {
    simple.effect == Effect::TurnOnBias && other.effect == Effect::WarmupTransient && simple.axis == other.axis
}

fn shares_axis(a: &Term, b: &Term) -> bool {
    a.axes().iter().any(|x| b.axes().contains(x))
}

/// |t| of `a` and `b` when both are added to the current model (0, 0 when they are collinear).
fn joint_t(design: &mut Design, cur: &Fit, a: &Term, b: &Term, tau_hint: f64) -> (f64, f64) {
    let mut terms = cur.terms.clone();
    terms.push(*a);
    terms.push(*b);
    let tau = if cur.tau.is_finite() { cur.tau } else { tau_hint };
    match design.fit_any(&terms, tau, false) {
        Some(f) => {
            let p = f.terms.len();
            (f.t_stat(p - 2).abs(), f.t_stat(p - 1).abs())
        }
        None => (0.0, 0.0),
    }
}

/// The naming loop from the base model's fit `base`.
pub(crate) fn name(s: &Samples, bins: &Bins, design: &mut Design, base: Fit, candidates_of: &[Effect]) -> Naming {
    let mut cur = base;
    let mut resid = residual(s, &cur);
    let mut rms = bins.rms_1s(&resid);
    let mut out = Naming {
        fit: cur.clone(),
        found: Vec::new(),
        withdrawn: Vec::new(),
        not_separable: Vec::new(),
        ambiguous: Vec::new(),
        unassigned: Vec::new(),
        leads: Vec::new(),
        sensitivity: Vec::new(),
        resid: [Vec::new(), Vec::new(), Vec::new()],
    };
    let mut excluded: Vec<Term> = Vec::new();
    // terms of pairs left not separable: what they explain is not assigned to anything else
    let mut unresolved: Vec<Term> = Vec::new();
    let mut first = true;
    while out.found.len() < MAX_FINDINGS {
        let terms: Vec<Term> =
            candidates_of.iter().flat_map(|e| all_terms(*e)).filter(|t| !cur.terms.contains(t) && !excluded.contains(t)).collect();
        let mut evals: Vec<Cand> = Vec::new();
        for term in terms {
            let sep = match fit_with(design, &cur, &[term], false) {
                None => {
                    Err("not separable with this data: its regressor is zero or exactly collinear with the current model's".to_string())
                }
                Some(f) => {
                    let k = f.terms.len() - 1;
                    let r2 = f.r2(k);
                    if r2 > COLLINEAR_R2 {
                        Err(format!("not separable with this data: its regressor is collinear with the current model's (R^2 = {r2:.4})"))
                    } else {
                        let (t, se) = (f.t_stat(k), f.se(k));
                        evals.push(Cand { term, fit: f, t, se, r2 });
                        Ok(())
                    }
                }
            };
            if let (true, Err(reason)) = (first, sep) {
                out.not_separable.push(NotSeparable {
                    effect: term.effect.name().into(),
                    term: term.label(),
                    axis: term.axis_name().into(),
                    reason,
                });
            }
        }
        if first {
            out.sensitivity = evals
                .iter()
                .map(|c| Sensitivity { term: c.term.label(), unit: c.term.unit().into(), std_error: c.se, min_detectable: T_MIN * c.se })
                .collect();
            first = false;
        }
        evals.sort_by(|a, b| b.t.abs().total_cmp(&a.t.abs()));
        let leads = |c: &Cand| c.term.effect == Effect::TimeDelay && c.t < 0.0;
        for c in evals.iter().filter(|c| c.t.abs() >= T_MIN && leads(c)) {
            let msg = format!(
                "time_delay: the measured rate leads the truth ({:.3e} s, t = {:.1}): not a delay (the vocabulary has no lead); not added",
                c.fit.beta[c.k()],
                c.t
            );
            if !out.leads.contains(&msg) {
                out.leads.push(msg);
            }
        }
        let passes = |c: &Cand| c.t.abs() >= T_MIN && !leads(c);
        let Some(mut bi) = evals.iter().position(passes) else {
            // nothing alone: two coefficients that cancel each other?
            let Some((pair, next, chi2, c2)) = pair_search(design, &cur, &evals, &unresolved) else { break };
            let fresh = accept(s, bins, design, &mut cur, &mut resid, &mut rms, &mut out, &mut excluded, &evals, &pair, next, vec![]);
            for f in out.found.iter_mut().rev().take(fresh) {
                f.jointly = Some((pair.iter().filter(|t| **t != f.term).map(|t| t.label()).collect(), chi2, c2));
            }
            continue;
        };
        // rivals: joint fits with every other significant candidate sharing an axis
        let mut rivals = Vec::new();
        let mut amb: Option<(usize, f64, f64)> = None;
        let mut restarts = 0;
        'rivals: loop {
            rivals.clear();
            for (ci, c) in evals.iter().enumerate() {
                if ci == bi || !passes(c) || !shares_axis(&c.term, &evals[bi].term) {
                    continue;
                }
                let b = &evals[bi];
                let hint = if b.fit.tau.is_finite() { b.fit.tau } else { c.fit.tau };
                let (tb, tc) = joint_t(design, &cur, &b.term, &c.term, hint);
                rivals.push((c.term.label(), c.t, tb, tc));
                if tb >= T_MIN {
                    continue;
                }
                if restarts < 4 && (nested(&c.term, &b.term) || tc >= T_MIN) {
                    // the simpler limit, or the explanation needed even given b
                    bi = ci;
                    restarts += 1;
                    continue 'rivals;
                }
                if nested(&b.term, &c.term) {
                    continue;
                }
                amb = Some((ci, tb, tc));
                break;
            }
            break;
        }
        if let Some((ci, tb, tc)) = amb {
            let (b, c) = (&evals[bi], &evals[ci]);
            let axis = if b.term.axis == 3 { c.term.axis_name() } else { b.term.axis_name() };
            out.ambiguous.push(Ambiguity {
                effects: [b.term.effect.name().into(), c.term.effect.name().into()],
                terms: [b.term.label(), c.term.label()],
                axis: axis.into(),
                t_alone: [b.t, c.t],
                t_joint: [tb, tc],
                reason: format!(
                    "not separable with this data: {} (t = {:.1} alone) and {} (t = {:.1} alone) explain the same residual; \
                     fitted together neither is significant (t = {tb:.1} and {tc:.1}, {T_MIN} needed); neither is added",
                    b.term.label(),
                    b.t,
                    c.term.label(),
                    c.t
                ),
            });
            for t in [b.term, c.term] {
                excluded.push(t);
                unresolved.push(t);
            }
            continue;
        }
        // a candidate that is not significant given what the data could not
        // assign (the terms of the pairs left not separable) would be a guess too
        let b = &evals[bi];
        if let Some(tb) = t_given(design, &cur, &unresolved, &[b.term], b.fit.tau).filter(|t| t[0].abs() < T_MIN).map(|t| t[0]) {
            let given: Vec<String> = unresolved.iter().filter(|a| shares_axis(a, &b.term)).map(|a| a.label()).collect();
            out.unassigned.push(format!(
                "{} (t = {:.1} alone) is not significant given {} (t = {tb:.1}), left not separable: not added",
                b.term.label(),
                b.t,
                given.join(", ")
            ));
            excluded.push(b.term);
            continue;
        }
        let best = &evals[bi];
        // a new warm-up: its time constant refined
        let new_warm = best.term.effect == Effect::WarmupTransient && !cur.tau.is_finite();
        let next = if new_warm { fit_with(design, &cur, &[best.term], true).unwrap_or_else(|| best.fit.clone()) } else { best.fit.clone() };
        let term = best.term;
        accept(s, bins, design, &mut cur, &mut resid, &mut rms, &mut out, &mut excluded, &evals, &[term], next, rivals);
    }
    out.found.retain(|f| cur.index(&f.term).is_some());
    out.fit = cur;
    out.resid = resid;
    out
}

/// Add `terms` (fitted in `next`) to the model: withdraw earlier findings no
/// longer significant, record the findings. Returns how many were recorded.
#[allow(clippy::too_many_arguments)]
fn accept(
    s: &Samples,
    bins: &Bins,
    design: &mut Design,
    cur: &mut Fit,
    resid: &mut [Vec<f64>; 3],
    rms: &mut [f64; 3],
    out: &mut Naming,
    excluded: &mut Vec<Term>,
    evals: &[Cand],
    terms: &[Term],
    mut next: Fit,
    rivals: Vec<(String, f64, f64, f64)>,
) -> usize {
    let names: Vec<String> = terms.iter().map(|t| t.label()).collect();
    // a warm-up's time constant, found with the model as it was, searched again with the new terms
    if next.tau.is_finite() && !terms.iter().any(|t| t.effect == Effect::WarmupTransient) {
        if let Some(f) = design.fit_search_tau(&next.terms, true).filter(|f| f.sse() < next.sse()) {
            next = f;
        }
    }
    // withdraw what is no longer significant: an earlier finding, or a new term
    // that the time constant searched again explains away
    let mut terms: Vec<Term> = terms.to_vec();
    loop {
        let weak = out
            .found
            .iter()
            .map(|f| f.term)
            .chain(terms.iter().copied())
            .filter_map(|t| next.index(&t).map(|k| (t, next.t_stat(k))))
            .find(|(_, t)| t.abs() < T_MIN);
        let Some((wt, tw)) = weak else { break };
        let keep: Vec<Term> = next.terms.iter().copied().filter(|t| *t != wt).collect();
        match design.fit_any(&keep, next.tau, false) {
            Some(f) => {
                if terms.contains(&wt) {
                    terms.retain(|t| *t != wt);
                } else {
                    out.withdrawn.push(Withdrawn { term: wt.label(), t_stat: tw, after: names.join(" and ") });
                }
                excluded.push(wt);
                next = f;
            }
            None => break,
        }
    }
    let resid_next = residual(s, &next);
    let rms_next = bins.rms_1s(&resid_next);
    for term in &terms {
        let k = next.index(term).expect("an accepted term is in its fit");
        let plot_axis = if term.axis == 3 {
            (0..3).max_by(|a, b| (cur.sse_axis[*a] - next.sse_axis[*a]).total_cmp(&(cur.sse_axis[*b] - next.sse_axis[*b]))).unwrap_or(0)
        } else {
            term.axis
        };
        let v = variable(term, plot_axis);
        out.found.push(Found {
            term: *term,
            coef_when_found: next.beta[k],
            se_when_found: next.se(k),
            t_when_found: next.t_stat(k),
            r2: evals.iter().find(|c| c.term == *term).map_or(f64::NAN, |c| c.r2),
            rms_before: *rms,
            rms_after: rms_next,
            wrms_before: whitened_rms(cur),
            wrms_after: whitened_rms(&next),
            contribution_rms: contribution_rms(s, term, next.tau, next.beta[k]),
            plot_axis,
            loc_before: bins.localise(&resid[plot_axis], v),
            loc_after: bins.localise(&resid_next[plot_axis], v),
            strongest_before: bins.strongest(&resid[plot_axis], 3).iter().map(Strongest::from).collect(),
            ranking: evals.iter().take(5).map(|c| (c.term.label(), c.t, c.se)).collect(),
            rivals: rivals.clone(),
            jointly: None,
        });
    }
    *cur = next;
    *resid = resid_next;
    *rms = rms_next;
    terms.len()
}

/// When no coefficient is significant alone: the pair sharing an axis whose
/// joint fit lowers the whitened residual most, accepted when that drop (a
/// chi-square with 2 degrees of freedom) reaches `2 ln(pairs / PAIR_FAMILY_RATE)`
/// (Bonferroni over the pairs tried) and both coefficients are significant
/// (|t| >= [`T_MIN`]) in it. Two effects can cancel each other: in a drive the
/// lateral specific force follows the yaw rate, so a g-sensitivity to it and a
/// misalignment from the yaw axis of opposite signs hide each other.
fn pair_search(design: &mut Design, cur: &Fit, evals: &[Cand], unresolved: &[Term]) -> Option<([Term; 2], Fit, f64, f64)> {
    let mut tried = 0usize;
    let mut best: Option<([Term; 2], Fit, f64)> = None;
    for i in 0..evals.len() {
        for j in i + 1..evals.len() {
            let (a, b) = (&evals[i], &evals[j]);
            if !shares_axis(&a.term, &b.term) {
                continue;
            }
            tried += 1;
            let tau = if cur.tau.is_finite() {
                cur.tau
            } else if a.fit.tau.is_finite() {
                a.fit.tau
            } else {
                b.fit.tau
            };
            let mut terms = cur.terms.clone();
            terms.push(a.term);
            terms.push(b.term);
            let Some(f) = design.fit(&terms, tau) else { continue };
            let p = f.terms.len();
            let (ta, tb) = (f.t_stat(p - 2), f.t_stat(p - 1));
            let lead = |t: &Term, v: f64| t.effect == Effect::TimeDelay && v < 0.0;
            if ta.abs() < T_MIN || tb.abs() < T_MIN || lead(&a.term, ta) || lead(&b.term, tb) {
                continue;
            }
            let chi2 = (cur.sse() - f.sse()) / f.s2().max(1.0);
            if t_given(design, cur, unresolved, &[a.term, b.term], tau).is_some_and(|t| t.iter().any(|v| v.abs() < T_MIN)) {
                continue;
            }
            if best.as_ref().is_none_or(|x| chi2 > x.2) {
                best = Some(([a.term, b.term], f, chi2));
            }
        }
    }
    let c2 = 2.0 * (tried.max(1) as f64 / PAIR_FAMILY_RATE).ln();
    best.filter(|x| x.2 >= c2).map(|(t, f, chi2)| (t, f, chi2, c2))
}

/// t of `terms` fitted with the current model and the `unresolved` terms that
/// share an axis with them (those collinear with the ones before them left
/// out); None when there are no such terms or the fit is singular.
fn t_given(design: &mut Design, cur: &Fit, unresolved: &[Term], terms: &[Term], tau_hint: f64) -> Option<Vec<f64>> {
    let u: Vec<Term> = unresolved.iter().copied().filter(|a| terms.iter().any(|t| shares_axis(a, t)) && !cur.terms.contains(a)).collect();
    if u.is_empty() {
        return None;
    }
    let tau = if cur.tau.is_finite() { cur.tau } else { tau_hint };
    let mut all = cur.terms.clone();
    for a in u {
        all.push(a);
        if design.fit_any(&all, tau, false).is_none() {
            all.pop();
        }
    }
    let n0 = all.len();
    all.extend_from_slice(terms);
    let f = design.fit_any(&all, tau, false)?;
    Some((0..terms.len()).map(|i| f.t_stat(n0 + i)).collect())
}
