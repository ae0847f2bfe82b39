//! Step 5, **report**: `report.json`, `report.md`, `model.toml` (the base
//! model with every free coefficient filled in and the found effects added),
//! `residual.svg` and one `finding_N_<effect>_<axis>.svg` per finding, all
//! written through [`crate::outfile`] (never half-written, never over an input).

use super::check::Checks;
use super::fit::NoiseModel;
#[cfg(feature = "cli")]
use super::fit::AX;
use super::localise::{AxisLocalisation, Localisation};
use super::name::{Ambiguity, NotSeparable, Sensitivity, Withdrawn};
use super::read::has_table;
use super::GapOptions;
use crate::outfile;
use crate::sim::model::{
    Effect, GSensitivity, Misalignment, ScaleFactor, SensorModel, ThermalLinear, ThermalQuadratic, ThermalRate, TimeDelay, TurnOnBias,
    WarmupTransient,
};
use serde::Serialize;
use std::path::{Path, PathBuf};

#[derive(Clone, Debug, Serialize)]
pub struct Finding {
    pub effect: String,
    /// `x`, `y`, `z`, or `all` for `time_delay` (one delay shared by all axes).
    pub axis: String,
    /// The coefficient's name (`scale_factor z`, `misalignment m[y][z]`, `time_delay`).
    pub term: String,
    /// Coefficient of the final joint fit.
    pub coefficient: f64,
    /// Its standard error (white noise + bias random walk, full rate).
    pub std_error: f64,
    pub t_stat: f64,
    pub unit: String,
    /// Residual RMS of 1-s means per axis before and after the finding, deg/s.
    pub rms_before: [f64; 3],
    pub rms_after: [f64; 3],
    pub evidence: serde_json::Value,
}

#[derive(Clone, Debug, Serialize)]
pub struct Report {
    pub findings: Vec<Finding>,
    /// Nothing found and no pair left not separable.
    pub clean: bool,
    /// Candidates the data cannot judge (no excitation / collinear), on the base model's residual.
    pub not_separable: Vec<NotSeparable>,
    /// Pairs the data cannot tell apart (neither was added).
    pub ambiguous: Vec<Ambiguity>,
    /// Significant candidates not added: not significant given the terms left not separable.
    pub unassigned: Vec<String>,
    /// Findings withdrawn because a later one explains them.
    pub withdrawn: Vec<Withdrawn>,
    /// Significant negative delays (the measured rate leads the truth), not added.
    pub rejected: Vec<String>,
    /// Residual RMS of 1-s means per axis, base model (free terms fitted) and final, deg/s.
    pub rms_initial: [f64; 3],
    pub rms_final: [f64; 3],
    /// White-noise level of 1-s means (the noise model's white part), deg/s.
    pub noise_floor_1s: f64,
    /// The same per axis from the data's own white noise, deg/s.
    pub noise_floor_1s_data: [f64; 3],
    pub noise_model: NoiseModel,
    /// Whitened residual variance per axis (1 = the noise model's), base model and final.
    pub variance_ratio_initial: [f64; 3],
    pub variance_ratio_final: [f64; 3],
    /// The significance rule's thresholds.
    pub t_min: f64,
    pub collinear_r2: f64,
    /// Whether measured and truth agree (see `gyrocomp::gap::check`).
    pub checks: Checks,
    /// Standard error of every candidate on the base model's residual and the smallest coefficient that would be found.
    pub sensitivity: Vec<Sensitivity>,
    /// Localisation of the base model's residual per axis (the strongest
    /// variables by |correlation|, with the range of their decile means).
    pub initial_localisation: Vec<AxisLocalisation>,
    /// The same for the final residual.
    pub final_localisation: Vec<AxisLocalisation>,
    pub samples: usize,
    pub duration_s: f64,
    pub free_base_terms: Vec<String>,
    /// The base model's free coefficients in the final fit (e.g. the turn-on bias), with their standard errors.
    pub base_coefficients: Vec<Coefficient>,
    /// How the truth was derived from a measured reference or a still unit (`gap --reference` / `--static`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub truth_from: Option<super::refdata::Derivation>,
}

/// A fitted coefficient.
#[derive(Clone, Debug, Serialize)]
pub struct Coefficient {
    pub term: String,
    pub coefficient: f64,
    pub std_error: f64,
    pub unit: String,
}

/// What the plots show (drawn only with the `cli` feature).
#[cfg_attr(not(feature = "cli"), allow(dead_code))]
pub struct PlotData {
    pub(crate) initial: Vec<(f64, [f64; 3])>,
    pub(crate) fin: Vec<(f64, [f64; 3])>,
    /// per finding: label, axis shown, file stem, localisation before/after
    pub(crate) finds: Vec<(String, usize, String, Localisation, Localisation)>,
}

/// The base model with every free coefficient filled in from the fit and the found effects added.
pub(crate) fn extended_model(base: &SensorModel, coef: impl Fn(Effect, usize, usize) -> f64, tau: f64, found: &[Effect]) -> SensorModel {
    let mut m = base.clone();
    let g = &mut m.gyro;
    let mut effects = g.effects.clone();
    for e in found {
        if !effects.contains(e) {
            effects.push(*e);
        }
    }
    let free: Vec<Effect> = effects.iter().copied().filter(|e| !has_table(&base.gyro, *e)).collect();
    let v3 = |e: Effect| -> [f64; 3] { [coef(e, 0, 0), coef(e, 1, 0), coef(e, 2, 0)] };
    let m33 = |e: Effect| -> [[f64; 3]; 3] {
        let mut v = [[0.0; 3]; 3];
        for (i, row) in v.iter_mut().enumerate() {
            for (j, x) in row.iter_mut().enumerate() {
                *x = coef(e, i, j);
            }
        }
        v
    };
    let t0_lin = g.thermal_linear.as_ref().map(|c| c.t0).or(g.thermal_quadratic.as_ref().map(|c| c.t0)).unwrap_or(25.0);
    let t0_quad = g.thermal_quadratic.as_ref().map(|c| c.t0).unwrap_or(t0_lin);
    for e in free {
        match e {
            Effect::TurnOnBias => g.turn_on_bias = Some(TurnOnBias { bias: v3(e) }),
            Effect::ThermalLinear => g.thermal_linear = Some(ThermalLinear { t0: t0_lin, p1: v3(e) }),
            Effect::ThermalQuadratic => g.thermal_quadratic = Some(ThermalQuadratic { t0: t0_quad, p2: v3(e) }),
            Effect::ThermalRate => g.thermal_rate = Some(ThermalRate { k: v3(e) }),
            Effect::WarmupTransient => g.warmup_transient = Some(WarmupTransient { amplitude: v3(e), tau_s: tau }),
            Effect::GSensitivity => g.g_sensitivity = Some(GSensitivity { g: m33(e) }),
            Effect::ScaleFactor => g.scale_factor = Some(ScaleFactor { k: v3(e) }),
            Effect::Misalignment => g.misalignment = Some(Misalignment { m: m33(e) }),
            Effect::TimeDelay => g.time_delay = Some(TimeDelay { delay_s: coef(e, 3, 0).max(0.0) }),
        }
    }
    g.effects = effects;
    m
}

pub(crate) fn fmt3(v: &[f64; 3]) -> String {
    format!("{:.5}, {:.5}, {:.5}", v[0], v[1], v[2])
}

/// How a finding is named in text: `scale_factor z`, or the shared delay said as such.
pub fn finding_title(f: &Finding) -> String {
    if f.axis == "all" {
        format!("{} (one delay shared by all axes)", f.term)
    } else {
        f.term.clone()
    }
}

fn io(p: &Path) -> impl Fn(std::io::Error) -> String + '_ {
    move |e| format!("{}: {e}", p.display())
}

/// The files a run writes, in order (the finding plots depend on the findings).
pub(crate) fn output_names(r: &Report, plots: bool) -> Vec<String> {
    let mut v = vec!["model.toml".to_string(), "report.md".to_string()];
    if plots {
        v.push("residual.svg".into());
        for (k, f) in r.findings.iter().enumerate() {
            v.push(format!("finding_{}_{}_{}.svg", k + 1, f.effect, f.axis));
        }
    }
    v.push("report.json".into());
    v
}

/// Write every output into `o.out` (created if needed); returns the paths.
pub(crate) fn write_outputs(
    o: &GapOptions,
    report: &Report,
    model: &SensorModel,
    plots: Option<&PlotData>,
) -> Result<Vec<PathBuf>, String> {
    let dir = &o.out;
    let names = output_names(report, plots.is_some());
    let paths: Vec<PathBuf> = names.iter().map(|n| dir.join(n)).collect();
    let outs: Vec<&Path> = paths.iter().map(|p| p.as_path()).collect();
    outfile::refuse_inputs_as_outputs(&[&o.measured, &o.truth, &o.model], &outs)?;
    outfile::create_dir(dir).map_err(|e| format!("--out {}: {e}", dir.display()))?;
    let write = |p: &Path, bytes: &[u8]| outfile::write_atomic(p, bytes).map_err(io(p));
    write(&paths[0], model.to_toml().as_bytes())?;
    write(&paths[1], render_md(report, o).as_bytes())?;
    let mut k = 2;
    if let Some(pd) = plots {
        write(&paths[k], plot_residual(pd)?.as_bytes())?;
        k += 1;
        for f in &pd.finds {
            write(&paths[k], plot_finding(f)?.as_bytes())?;
            k += 1;
        }
    }
    let json = serde_json::to_string_pretty(report).map_err(|e| e.to_string())? + "\n";
    write(&paths[k], json.as_bytes())?;
    Ok(paths)
}

/// report.md.
pub fn render_md(r: &Report, o: &GapOptions) -> String {
    let mut s = String::new();
    let nm = &r.noise_model;
    s += "# Model gap report\n\n";
    s += &format!(
        "Measured `{}`, truth `{}`, base model `{}`: {} samples over {:.1} s.\n\n",
        o.measured.display(),
        o.truth.display(),
        o.model.display(),
        r.samples,
        r.duration_s
    );
    if let Some(d) = &r.truth_from {
        s += &super::refdata::render_md(d);
    }
    s += &format!(
        "Noise model: white {:.4} deg/s per sample (model {:.4}, data [{:.4}, {:.4}, {:.4}]), bias random walk {:.2e} deg/s/sqrt(s) \
         (whitening filter memory {:.0} s). Every coefficient is judged by its own t statistic at the full rate with this noise \
         model: found when |t| >= {}.\n\n",
        nm.sigma, nm.sigma_model, nm.sigma_data[0], nm.sigma_data[1], nm.sigma_data[2], nm.bias_walk, nm.filter_memory_s, r.t_min
    );
    s += &format!(
        "Residual RMS of 1-s means with the base model (free terms fitted): [{}] deg/s; white-noise level of 1-s means {:.5} deg/s \
         (from the data [{}]); whitened residual variance [{:.3}, {:.3}, {:.3}] x the noise model's.\n\n",
        fmt3(&r.rms_initial),
        r.noise_floor_1s,
        fmt3(&r.noise_floor_1s_data),
        r.variance_ratio_initial[0],
        r.variance_ratio_initial[1],
        r.variance_ratio_initial[2]
    );
    let c = &r.checks;
    s += "Measured and truth agree: ";
    if let Some(d) = c.temperature_rms_diff {
        s += &format!("temperature within {d:.3} degC RMS; ");
    }
    for rc in &c.rates {
        if rc.compared {
            s += &format!("rate {} correlation {:.4}, slope {:.4}; ", rc.axis, rc.correlation, rc.slope);
        }
    }
    s += &format!(
        "with every vocabulary term ({}) the whitened residual variance is {:.3}x the noise model's.\n\n",
        c.full_vocabulary_terms, c.full_vocabulary_variance_ratio
    );
    let where_ = |title: &str, v: &[AxisLocalisation]| -> String {
        let mut s = format!("### {title}\n\n| axis | RMS 1-s, deg/s | / noise | strongest variables (correlation, decile-mean range deg/s) |\n|---|---|---|---|\n");
        for l in v {
            let st: Vec<String> =
                l.strongest.iter().map(|x| format!("{} ({:+.2}, {:.4})", x.variable, x.correlation, x.binned_range)).collect();
            s += &format!("| {} | {:.5} | {:.2} | {} |\n", l.axis, l.rms_1s, l.ratio_to_floor, st.join("; "));
        }
        s + "\n"
    };
    s += &where_("Where the base model fails", &r.initial_localisation);
    if r.findings.is_empty() && r.ambiguous.is_empty() {
        s += "**No missing effect found**: no candidate is significant.\n\n";
    }
    for (k, f) in r.findings.iter().enumerate() {
        let ev = &f.evidence;
        let l = &ev["localisation"];
        let axis = if f.axis == "all" { "one delay shared by all axes".to_string() } else { format!("axis {}", f.axis) };
        s += &format!(
            "## {}. `{}` ({axis}) — coefficient {:.4e} ± {:.1e} {}\n\n",
            k + 1,
            f.term,
            f.coefficient,
            f.std_error,
            if f.unit == "1" { "(dimensionless)" } else { &f.unit }
        );
        s += &format!(
            "- why: t = {:.1} (|t| >= {} needed), R^2 with the model before it {:.3}, adds {:.4} deg/s RMS at the full rate\n",
            f.t_stat,
            r.t_min,
            ev["r2_with_current_model"].as_f64().unwrap_or(0.0),
            ev["contribution_rms"].as_f64().unwrap_or(0.0)
        );
        s += &format!(
            "- where: the residual on {} against {}: correlation {:.3} (decile-mean range {:.4} deg/s) before, {:.3} ({:.4} deg/s) after\n",
            l["axis"].as_str().unwrap_or(""),
            l["variable"].as_str().unwrap_or(""),
            l["correlation_before"].as_f64().unwrap_or(0.0),
            l["binned_range_before"].as_f64().unwrap_or(0.0),
            l["correlation_after"].as_f64().unwrap_or(0.0),
            l["binned_range_after"].as_f64().unwrap_or(0.0)
        );
        if let Some(rv) = ev["rivals"].as_array().filter(|a| !a.is_empty()) {
            let v: Vec<String> = rv
                .iter()
                .take(4)
                .map(|x| {
                    format!(
                        "{} (t {:.1} alone; jointly this {:.1}, it {:.1})",
                        x["term"].as_str().unwrap_or(""),
                        x["t_alone"].as_f64().unwrap_or(0.0),
                        x["t_this_given_rival"].as_f64().unwrap_or(0.0),
                        x["t_rival_given_this"].as_f64().unwrap_or(0.0)
                    )
                })
                .collect();
            let more = if rv.len() > 4 { format!("; {} more in report.json", rv.len() - 4) } else { String::new() };
            s += &format!("- told apart from: {}{more}\n", v.join("; "));
        }
        if let Some(j) = ev.get("found_jointly_with") {
            s += &format!(
                "- found as a pair with {} (neither significant alone: they hide each other); joint chi-square {:.1} (>= {:.1} needed)\n",
                j["terms"].as_array().map(|a| a.iter().filter_map(|x| x.as_str()).collect::<Vec<_>>().join(", ")).unwrap_or_default(),
                j["chi2"].as_f64().unwrap_or(0.0),
                j["chi2_needed"].as_f64().unwrap_or(0.0)
            );
        }
        s += &format!("- residual RMS of 1-s means [x, y, z]: before [{}], after [{}] deg/s\n\n", fmt3(&f.rms_before), fmt3(&f.rms_after));
    }
    if !r.withdrawn.is_empty() {
        s += "## Withdrawn\n\n";
        for w in &r.withdrawn {
            s += &format!("- {}: t = {:.1} once {} was added\n", w.term, w.t_stat, w.after);
        }
        s += "\n";
    }
    if !r.ambiguous.is_empty() {
        s += "## Not separable with this data\n\n";
        for a in &r.ambiguous {
            s += &format!("- {}\n", a.reason);
        }
        for u in &r.unassigned {
            s += &format!("- {u}\n");
        }
        s += "\n";
    }
    for x in &r.rejected {
        s += &format!("- {x}\n\n");
    }
    if !r.not_separable.is_empty() {
        s += "## Candidates this data cannot judge (on the base model's residual)\n\n";
        for n in &r.not_separable {
            s += &format!("- {}: {}\n", n.term, n.reason);
        }
        s += "\n";
    }
    s += &where_("What is left", &r.final_localisation);
    s += &format!(
        "Final residual RMS of 1-s means [{}] deg/s; whitened residual variance [{:.3}, {:.3}, {:.3}] ({}).\n",
        fmt3(&r.rms_final),
        r.variance_ratio_final[0],
        r.variance_ratio_final[1],
        r.variance_ratio_final[2],
        if r.clean { "clean: the base model explains the data" } else { "see model.toml for the extended model" }
    );
    s
}

#[cfg(feature = "cli")]
fn plot_residual(pd: &PlotData) -> Result<String, String> {
    use plotters::prelude::*;
    let e = |x: &dyn std::fmt::Display| x.to_string();
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (1000, 900)).into_drawing_area();
        root.fill(&WHITE).map_err(|x| e(&x))?;
        let areas = root.split_evenly((3, 1));
        for (a, area) in areas.iter().enumerate() {
            let pts = |v: &[(f64, [f64; 3])]| v.iter().map(|p| (p.0, p.1[a])).collect::<Vec<_>>();
            let (i, f) = (pts(&pd.initial), pts(&pd.fin));
            let x0 = i.first().map_or(0.0, |p| p.0);
            let x1 = i.last().map_or(1.0, |p| p.0).max(x0 + 1.0);
            let m = i.iter().chain(&f).map(|p| p.1.abs()).filter(|v| v.is_finite()).fold(1e-4, f64::max) * 1.05;
            let mut ch = ChartBuilder::on(area)
                .caption(format!("gyro {} residual (1-s means): base model vs extended model", AX[a]), ("sans-serif", 16))
                .margin(8)
                .x_label_area_size(30)
                .y_label_area_size(60)
                .build_cartesian_2d(x0..x1, -m..m)
                .map_err(|x| e(&x))?;
            ch.configure_mesh().x_desc("t, s").y_desc("deg/s").draw().map_err(|x| e(&x))?;
            let grey = RGBColor(160, 160, 160);
            ch.draw_series(LineSeries::new(i, grey.stroke_width(1)))
                .map_err(|x| e(&x))?
                .label("before")
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 15, y)], grey));
            ch.draw_series(LineSeries::new(f, BLUE.stroke_width(1)))
                .map_err(|x| e(&x))?
                .label("after")
                .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 15, y)], BLUE));
            ch.configure_series_labels().background_style(WHITE.mix(0.8)).border_style(BLACK).draw().map_err(|x| e(&x))?;
        }
        root.present().map_err(|x| e(&x))?;
    }
    Ok(svg)
}

#[cfg(feature = "cli")]
fn plot_finding(f: &(String, usize, String, Localisation, Localisation)) -> Result<String, String> {
    use plotters::prelude::*;
    let e = |x: &dyn std::fmt::Display| x.to_string();
    let (label, axis, _, before, after) = f;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (900, 600)).into_drawing_area();
        root.fill(&WHITE).map_err(|x| e(&x))?;
        let all: Vec<(f64, f64)> = before.bins.iter().chain(&after.bins).map(|b| (b.0, b.1)).collect();
        let mut x0 = all.iter().map(|p| p.0).fold(f64::INFINITY, f64::min);
        let mut x1 = all.iter().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max);
        if !x0.is_finite() {
            x0 = 0.0;
        }
        if !x1.is_finite() || x1 <= x0 {
            x1 = x0 + 1.0;
        }
        let m = all.iter().map(|p| p.1.abs()).fold(1e-4, f64::max) * 1.1;
        let mut ch = ChartBuilder::on(&root)
            .caption(format!("{label}: gyro {} residual vs {} (decile means)", AX[*axis], before.variable), ("sans-serif", 18))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(x0..x1, -m..m)
            .map_err(|x| e(&x))?;
        ch.configure_mesh()
            .x_desc(format!("{}, {}", before.variable, before.unit))
            .y_desc("mean residual, deg/s")
            .draw()
            .map_err(|x| e(&x))?;
        for (loc, c, name) in [(before, RED, "before"), (after, BLUE, "after")] {
            let pts: Vec<(f64, f64)> = loc.bins.iter().map(|b| (b.0, b.1)).collect();
            ch.draw_series(LineSeries::new(pts.clone(), c.stroke_width(2)))
                .map_err(|x| e(&x))?
                .label(format!("{name} (r = {:.3})", loc.correlation))
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 15, y)], c));
            ch.draw_series(pts.into_iter().map(|p| Circle::new(p, 3, c.filled()))).map_err(|x| e(&x))?;
        }
        ch.configure_series_labels().background_style(WHITE.mix(0.8)).border_style(BLACK).draw().map_err(|x| e(&x))?;
        root.present().map_err(|x| e(&x))?;
    }
    Ok(svg)
}

/// Without `cli` (the Python package) there is no plotting library: runs that ask for plots are refused.
#[cfg(not(feature = "cli"))]
fn plot_residual(_: &PlotData) -> Result<String, String> {
    Err("the SVG plots need gyrocomp's `cli` feature".into())
}

#[cfg(not(feature = "cli"))]
fn plot_finding(_: &(String, usize, String, Localisation, Localisation)) -> Result<String, String> {
    Err("the SVG plots need gyrocomp's `cli` feature".into())
}
