//! `gyrocomp gap`: what a gyro sensor model is missing, with evidence.
//!
//! Given measured data (a candump log in the ADIS contract, or a CSV
//! `t,gx,gy,gz,ax,ay,az,mx,my,mz,temp`), the truth (`truth.csv` as
//! `gyrocomp simulate` writes it; `temp` optional when the measured data has
//! it) and a base model (`sensor.toml` shape; effects listed without their
//! table are fitted; its `[noise]` is the noise model), the workflow runs in
//! five steps, one module each:
//!
//! 1. [`read`]: measured and truth joined sample by sample; the fixed part of
//!    the base model simulated from the truth with the simulator's own
//!    [`GyroModel::measure`](crate::sim::model::GyroModel::measure) (one
//!    physics for both).
//! 2. [`fit`]: the free coefficients by generalised least squares **at the
//!    full sample rate** with the noise model white noise + bias random walk
//!    (the random walk as the state of a Kalman filter that pre-whitens every
//!    column); standard errors from the same. Then [`check`]: measured and
//!    truth must agree (temperature, rates) and the vocabulary must be able
//!    to explain the data; otherwise the run is refused, nothing is named.
//! 3. [`localise`]: where the residual lives (correlation and decile means
//!    against time, temperature, dT/dt, specific force, rate, rate derivative).
//! 4. [`name`]: every vocabulary coefficient not yet in the model is fitted
//!    with it and judged by its own t statistic (|t| >= [`T_MIN`]), told
//!    apart from correlated rivals by joint fits, added, and the loop repeats.
//! 5. [`report`]: `report.json`, `report.md`, `model.toml` (the extended
//!    model, accepted by `gyrocomp simulate --model` and `gyrocomp gap
//!    --model`), `residual.svg` and one `finding_N_<effect>_<axis>.svg` per
//!    finding (`axis` is `all` for `time_delay`: one delay is shared by all
//!    axes and is one finding).
//!
//! **Real recordings.** [`refdata`] derives the truth from a measured
//! reference (`--reference`: rates from the orientation's derivative,
//! low-passed with the measured gyro alike; the mount at the first rest; the
//! reference's noise in the noise model; only valid stretches) or from a
//! unit lying still (`--static`); [`trials`] fits several trials of one
//! unit each and jointly (consistency at 1 %, the joint model,
//! leave-one-trial-out), [`trials_report`] prints and writes that.
//!
//! **Effect size in standard errors.** The standard error of a coefficient
//! is the one this fit reports: GLS at the full rate with white noise (the
//! model's density at the data's rate with the quantisation LSB^2/12, scaled
//! to the data's own white level) plus the bias random walk of `[noise]
//! gyro_bias_walk` starting at 0 at power-on. It depends on which other
//! coefficients are free: [`standard_errors`] computes it from the truth
//! alone (before any measurement) against the base model's free terms
//! ([`Against::Base`]: how well the data *measures* it) or also against its
//! closest rival in the vocabulary ([`Against::ClosestRival`]: how well the
//! data *names* it). `tests/gap_detection.rs` sizes hidden effects with the
//! latter. User documentation: `docs/gap.md`.

pub mod check;
#[cfg(feature = "cli")]
pub mod cli;
pub mod fit;
pub mod inputs;
pub mod localise;
pub mod name;
pub mod read;
pub mod refdata;
pub mod report;
pub mod trials;
pub mod trials_report;

pub use check::Checks;
#[cfg(feature = "cli")]
pub use cli::{cli, GapArgs};
pub use fit::{all_terms, tau_grid, unit, NoiseModel, Term, COLLINEAR_R2, TAU_MAX_S};
pub use inputs::{Analysis, Source, TruthSource};
pub use localise::{AxisLocalisation, Localisation};
pub use name::{Ambiguity, NotSeparable, Sensitivity, Withdrawn, MAX_FINDINGS, T_MIN};
pub use read::{load_base, measured_from_bytes, parse_base, read_measured, read_truth, truth_from_bytes, MeasRow, TruthIn};
pub use report::{finding_title, render_md, Finding, PlotData, Report};

use crate::adis::{builtin_profile, Profile};
use crate::sim::model::{Effect, SensorModel};
use fit::Design;
use localise::Bins;
use std::path::PathBuf;

/// Options of one workflow.
#[derive(Clone, Debug)]
pub struct GapOptions {
    pub measured: PathBuf,
    pub truth: PathBuf,
    pub model: PathBuf,
    pub out: PathBuf,
    /// Part profile (log decoding and the LSB of the noise model).
    pub profile: String,
    /// Write the SVG plots.
    pub plots: bool,
}

/// What a run of the workflow produced (in memory).
pub struct GapResult {
    pub report: Report,
    pub model: SensorModel,
    pub files: Vec<PathBuf>,
    /// What the plots show.
    pub plots: Option<PlotData>,
    /// Wall time of the analysis (and of the outputs, after [`run`]), s. Not in the files (they are deterministic).
    pub elapsed_s: f64,
}

/// Where the truth of a run comes from.
#[derive(Clone, Debug)]
pub enum Truth {
    /// `truth.csv` as `gyrocomp simulate` writes it.
    Simulated(PathBuf),
    /// Derived from a measured reference ([`refdata::from_reference`]).
    Reference { path: PathBuf, bandwidth: f64 },
    /// A unit known to lie still ([`refdata::from_static`]).
    Static { bandwidth: f64 },
}

impl Truth {
    /// The same truth as [`inputs`] reads it: its file as a [`Source`].
    pub fn source(&self) -> TruthSource {
        match self {
            Truth::Simulated(p) => TruthSource::Simulated(Source::File(p.clone())),
            Truth::Reference { path, bandwidth } => TruthSource::Reference { source: Source::File(path.clone()), bandwidth: *bandwidth },
            Truth::Static { bandwidth } => TruthSource::Static { bandwidth: *bandwidth },
        }
    }
}

/// Run the workflow on files and write the outputs.
pub fn run(o: &GapOptions) -> Result<GapResult, String> {
    run_with(o, &Truth::Simulated(o.truth.clone()))
}

/// [`run`] with the truth from `truth`.
pub fn run_with(o: &GapOptions, truth: &Truth) -> Result<GapResult, String> {
    let start = std::time::Instant::now();
    let profile = builtin_profile(&o.profile).ok_or_else(|| format!("unknown profile {:?}", o.profile))?;
    let base = load_base(&o.model)?;
    let mut res = inputs::trial("", &Source::File(o.measured.clone()), &truth.source(), &base, &profile)?.result;
    let plots = if o.plots { res.plots.as_ref() } else { None };
    res.files = report::write_outputs(o, &res.report, &res.model, plots)?;
    res.elapsed_s = start.elapsed().as_secs_f64();
    Ok(res)
}

/// The free coefficients of the base model.
fn free_terms(base: &SensorModel) -> Vec<Term> {
    base.gyro.effects.iter().filter(|e| !read::has_table(&base.gyro, **e)).flat_map(|e| all_terms(*e)).collect()
}

/// The workflow on data in memory. Outputs are not written.
pub fn analyse(
    meas: &[MeasRow],
    truth: &[TruthIn],
    truth_has_temp: bool,
    base: &SensorModel,
    profile: &Profile,
) -> Result<GapResult, String> {
    analyse_with(meas, truth, truth_has_temp, base, profile, None)
}

/// Steps 1 and 2 up to the base model's fit: the joined samples, the
/// checks, the noise model scaled to the data, the design and the base fit.
pub(crate) struct Prepared {
    pub s: read::Samples,
    pub bins: Bins,
    pub checks: Checks,
    pub noise: NoiseModel,
    pub design: Design,
    pub free: Vec<Term>,
    pub base_tau: f64,
    pub base_fit: fit::Fit,
}

/// Read, check and fit the base model (see [`analyse_with`]).
pub(crate) fn prepare(
    meas: &[MeasRow],
    truth: &[TruthIn],
    truth_has_temp: bool,
    base: &SensorModel,
    profile: &Profile,
    derived: Option<&refdata::Derivation>,
) -> Result<Prepared, String> {
    if meas.is_empty() {
        return Err("no measured samples".into());
    }
    if !truth_has_temp && meas.iter().any(|m| !m.temp.is_finite()) {
        return Err("truth has no temp column and the measured data has no temperature".into());
    }
    // 1. read
    let s = read::join(meas, truth, truth_has_temp, &base.gyro)?;
    if s.duration() < 2.0 {
        return Err(format!("too little data: {:.2} s (at least 2 s)", s.duration()));
    }
    // 2. fit; first the checks: measured and truth belong together, the vocabulary can explain them
    let bins = Bins::new(&s);
    let temperature_rms_diff = check::temperature(&s)?;
    let ref_white = derived.map_or(0.0, |d| d.reference_white_density);
    let white = base.noise.gyro_white.hypot(ref_white);
    let noise0 = NoiseModel::new(&s, white, base.noise.gyro_bias_walk, profile.gyro_lsb);
    // the pairing check with the reference's own noise (at rest), not the moving level taken from the data
    let pair_white = base.noise.gyro_white.hypot(derived.map_or(0.0, |d| d.rest_density()));
    let rates = check::rates(&s, &bins, &NoiseModel::new(&s, pair_white, base.noise.gyro_bias_walk, profile.gyro_lsb))?;
    let mut design = Design::new(&s, &noise0);
    let free = free_terms(base);
    let base_tau = base.gyro.warmup_transient.as_ref().map_or(f64::NAN, |w| w.tau_s);
    let full = check::full_vocabulary(&mut design, &free, base_tau);
    let full_s2 = full.s2();
    if full_s2 > check::FULL_S2_MAX {
        let rms = bins.rms_1s(&fit::residual(&s, &full));
        return Err(check::full_vocabulary_refusal(full_s2, &rms, noise0.floor_1s(s.rate_hz)));
    }
    let checks = Checks { temperature_rms_diff, rates, full_vocabulary_terms: full.terms.len(), full_vocabulary_variance_ratio: full_s2 };
    // the white level the data has (the model's, scaled by the full fit's whitened residual variance)
    let mut noise = noise0.scaled_to_data([0, 1, 2].map(|a| full.s2_axis(a)), s.rate_hz);
    if derived.is_some_and(|d| d.reference_white_density > 0.0) && noise.sigma < noise0.sigma {
        // a measured reference: never below its noise while moving (the rests are quieter)
        noise = noise0.scaled_to_data([1.0; 3], s.rate_hz);
    }
    drop(design);
    let mut design = Design::new(&s, &noise);
    let base_fit = design
        .fit_any(&free, if free.iter().any(|t| t.effect == Effect::WarmupTransient) { f64::NAN } else { base_tau }, true)
        .ok_or("the base model's free coefficients cannot be fitted from this data (singular)")?;
    Ok(Prepared { s, bins, checks, noise, design, free, base_tau, base_fit })
}

/// [`analyse`] with a truth derived from a measured reference
/// ([`refdata`]): its reference noise (a white density, deg/s/sqrt(Hz)) is
/// added in quadrature to the base model's `gyro_white`, and how it was
/// derived goes into the report (`truth_from`).
pub fn analyse_with(
    meas: &[MeasRow],
    truth: &[TruthIn],
    truth_has_temp: bool,
    base: &SensorModel,
    profile: &Profile,
    derived: Option<&refdata::Derivation>,
) -> Result<GapResult, String> {
    let start = std::time::Instant::now();
    let p = prepare(meas, truth, truth_has_temp, base, profile, derived)?;
    let Prepared { s, bins, checks, noise, mut design, free, base_tau, base_fit } = p;
    let floor = noise.floor_1s(s.rate_hz);
    // 3. localise the base model's residual, 4. name
    let initial_resid = fit::residual(&s, &base_fit);
    let rms_initial = bins.rms_1s(&initial_resid);
    let fixed = read::fixed_effects(&base.gyro);
    let candidates: Vec<Effect> = Effect::ALL.iter().copied().filter(|e| !fixed.contains(e)).collect();
    let named = name::name(&s, &bins, &mut design, base_fit.clone(), &candidates);
    let fin = &named.fit;
    let rms_final = bins.rms_1s(&named.resid);
    // 5. report
    let data_1s = noise.sigma_data.map(|v| v / s.rate_hz.sqrt());
    let tau_interval = if fin.tau.is_finite() { design.tau_interval(fin) } else { (f64::NAN, f64::NAN) };
    let mut findings = Vec::new();
    let mut plot_finds = Vec::new();
    for f in &named.found {
        let k = fin.index(&f.term).expect("found terms are in the final fit");
        let t = &f.term;
        let mut ev = serde_json::json!({
            "term": t.label(),
            "rule": format!("|t| >= {T_MIN} (GLS at the full rate, white noise + bias random walk), separable (R^2 < {COLLINEAR_R2}), significant given every significant rival"),
            "t_stat_when_found": f.t_when_found,
            "std_error_when_found": f.se_when_found,
            "coefficient_when_found": f.coef_when_found,
            "r2_with_current_model": f.r2,
            "contribution_rms": f.contribution_rms,
            "whitened_rms_before": f.wrms_before,
            "whitened_rms_after": f.wrms_after,
            "localisation": {
                "axis": fit::AX[f.plot_axis],
                "variable": f.loc_before.variable,
                "correlation_before": f.loc_before.correlation,
                "binned_range_before": f.loc_before.binned_range,
                "correlation_after": f.loc_after.correlation,
                "binned_range_after": f.loc_after.binned_range,
                "strongest_before": f.strongest_before,
            },
            "ranking": f.ranking.iter().map(|r| serde_json::json!({"term": r.0, "t_stat": r.1, "std_error": r.2})).collect::<Vec<_>>(),
            "rivals": f.rivals.iter().map(|r| serde_json::json!({"term": r.0, "t_alone": r.1, "t_this_given_rival": r.2, "t_rival_given_this": r.3})).collect::<Vec<_>>(),
        });
        if let Some(r) = f.ranking.iter().find(|r| r.0 != t.label()) {
            ev["runner_up"] = serde_json::json!({"term": r.0, "t_stat": r.1});
        }
        if t.effect == Effect::WarmupTransient {
            ev["tau_s"] = serde_json::json!(fin.tau);
            ev["tau_s_interval_95"] = serde_json::json!(tau_interval);
        }
        if matches!(t.effect, Effect::GSensitivity | Effect::Misalignment) {
            ev["column"] = serde_json::json!(fit::AX[t.col]);
        }
        if t.axis == 3 {
            ev["shared_by_all_axes"] = serde_json::json!(true);
        }
        if let Some((other, chi2, c2)) = &f.jointly {
            ev["found_jointly_with"] = serde_json::json!({"terms": other, "chi2": chi2, "chi2_needed": c2});
        }
        findings.push(Finding {
            effect: t.effect.name().into(),
            axis: t.axis_name().into(),
            term: t.label(),
            coefficient: fin.beta[k],
            std_error: fin.se(k),
            t_stat: fin.t_stat(k),
            unit: t.unit().into(),
            rms_before: f.rms_before,
            rms_after: f.rms_after,
            evidence: ev,
        });
        plot_finds.push((t.label(), f.plot_axis, t.effect.name().to_string(), f.loc_before.clone(), f.loc_after.clone()));
    }
    let found_effects: Vec<Effect> = named.found.iter().map(|f| f.term.effect).collect();
    let coef = |e: Effect, i: usize, j: usize| {
        let col = if matches!(e, Effect::GSensitivity | Effect::Misalignment) { j } else { 0 };
        fin.coef(&Term { effect: e, axis: i, col })
    };
    let tau = if fin.tau.is_finite() { fin.tau } else { base_tau };
    let model = report::extended_model(base, coef, tau, &found_effects);
    let clean = findings.is_empty() && named.ambiguous.is_empty();
    let report = Report {
        findings,
        clean,
        not_separable: named.not_separable,
        ambiguous: named.ambiguous,
        unassigned: named.unassigned,
        withdrawn: named.withdrawn,
        rejected: named.leads,
        rms_initial,
        rms_final,
        noise_floor_1s: floor,
        noise_floor_1s_data: data_1s,
        noise_model: noise,
        variance_ratio_initial: [0, 1, 2].map(|a| base_fit.s2_axis(a)),
        variance_ratio_final: [0, 1, 2].map(|a| fin.s2_axis(a)),
        t_min: T_MIN,
        collinear_r2: COLLINEAR_R2,
        checks,
        sensitivity: named.sensitivity,
        initial_localisation: localise::localise_all(&bins, &initial_resid, &rms_initial, floor),
        final_localisation: localise::localise_all(&bins, &named.resid, &rms_final, floor),
        samples: s.len(),
        duration_s: s.duration(),
        free_base_terms: free.iter().map(|t| t.label()).collect(),
        base_coefficients: free
            .iter()
            .filter_map(|t| {
                fin.index(t).map(|k| report::Coefficient {
                    term: t.label(),
                    coefficient: fin.beta[k],
                    std_error: fin.se(k),
                    unit: t.unit().into(),
                })
            })
            .collect(),
        truth_from: derived.cloned(),
    };
    let pd = PlotData { initial: bins.means_1s(&initial_resid), fin: bins.means_1s(&named.resid), finds: plot_finds };
    Ok(GapResult { report, model, files: vec![], plots: Some(pd), elapsed_s: start.elapsed().as_secs_f64() })
}

/// Which coefficients are free besides the ones a standard error is asked for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Against {
    /// The base model's free coefficients only: how well the data measures
    /// the coefficient when it is known to be the one missing.
    Base,
    /// Also any one other coefficient of the vocabulary (of the effects the
    /// base model does not fix), the one that leaves the largest standard
    /// error (a warm-up rival at the worst time constant of the search grid,
    /// or at `tau` when a term asked for is a warm-up): how well the data
    /// tells the coefficient from its closest rival, as the naming step must.
    ClosestRival,
}

/// Standard errors of `terms`, from the truth alone (no measurement needed):
/// GLS at the truth's rate with the base model's `[noise]` (white density
/// with the profile's LSB^2/12, bias random walk from 0 at power-on), the
/// free coefficients `against` says plus `terms` (warm-ups at `tau`). A term
/// that is not separable (R^2 on the others >= [`COLLINEAR_R2`], or zero)
/// gets infinity.
pub fn standard_errors(
    truth: &[TruthIn],
    base: &SensorModel,
    profile: &Profile,
    terms: &[Term],
    tau: f64,
    against: Against,
) -> Result<Vec<f64>, String> {
    let meas: Vec<MeasRow> = truth.iter().map(|t| MeasRow { t: t.t, gyro: t.rate, acc: t.f, temp: t.temp }).collect();
    let has_temp = truth.iter().all(|t| t.temp.is_finite());
    let s = read::join(&meas, truth, has_temp, &base.gyro)?;
    let noise = NoiseModel::new(&s, base.noise.gyro_white, base.noise.gyro_bias_walk, profile.gyro_lsb);
    let mut design = Design::new(&s, &noise);
    let free = free_terms(base);
    let tau = if tau.is_finite() { tau } else { base.gyro.warmup_transient.as_ref().map_or(f64::NAN, |w| w.tau_s) };
    let has_warm = |v: &[Term]| v.iter().any(|t| t.effect == Effect::WarmupTransient);
    // SEs of `terms` with `extra` free too (warm-ups at `tau`); None: `terms` not separable
    let ses = |design: &mut Design, extra: Option<Term>, tau: f64| -> Option<Vec<f64>> {
        let mut all = free.clone();
        all.extend(extra);
        let n0 = all.len();
        all.extend_from_slice(terms);
        let f = design.fit(&all, tau)?;
        let v: Vec<f64> =
            (0..terms.len()).map(|i| if f.r2(n0 + i) > COLLINEAR_R2 { f64::INFINITY } else { f.cov[(n0 + i, n0 + i)].sqrt() }).collect();
        Some(v)
    };
    let tau0 = if tau.is_finite() { tau } else { 60.0 };
    let Some(mut out) = ses(&mut design, None, tau0) else { return Ok(vec![f64::INFINITY; terms.len()]) };
    if against == Against::ClosestRival {
        let fixed = read::fixed_effects(&base.gyro);
        for e in Effect::ALL.iter().filter(|e| !fixed.contains(e)) {
            for r in all_terms(*e) {
                if free.contains(&r) || terms.contains(&r) {
                    continue;
                }
                let taus = if r.effect == Effect::WarmupTransient && !has_warm(terms) { tau_grid() } else { vec![tau0] };
                for t in taus {
                    // a rival the base model alone cannot separate is no rival (e.g. a zero regressor)
                    let mut alone = free.clone();
                    alone.push(r);
                    if design.fit(&alone, t).is_none_or(|f| f.r2(alone.len() - 1) > COLLINEAR_R2) {
                        continue;
                    }
                    let v = ses(&mut design, Some(r), t).unwrap_or_else(|| vec![f64::INFINITY; terms.len()]);
                    for (o, x) in out.iter_mut().zip(v) {
                        *o = o.max(x);
                    }
                }
            }
        }
    }
    Ok(out)
}
