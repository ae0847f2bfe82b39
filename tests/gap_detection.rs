//! Detection rate of `gyrocomp gap` against the size of the hidden effect,
//! in standard errors of its coefficient.
//!
//! Each draw (deterministic, from its index): a scenario (`vehicle`, 400 s,
//! with the ambient changing by +-0.005..0.015 deg C/s, or `chamber`, 600 s
//! at rest with the chamber cycling the temperature +-5..15 deg C over
//! 200..600 s: in both, T and dT/dt are then not tied), one or
//! two hidden coefficients (an effect of the vocabulary, uniformly; one of
//! its coefficients, uniformly: an axis, a matrix element, or the one shared
//! delay), and a size `s` per hidden coefficient, log-uniform in 2..20, in
//! units of its standard error, defined before any measurement from the
//! truth (`gyrocomp::gap::standard_errors` with `Against::ClosestRival`):
//! generalised least squares at the full rate, white noise (ADIS16448
//! density at 204.8 Hz with the LSB's quantisation) plus the bias random walk
//! (0.0002 deg/s/sqrt(s)) from 0 at power-on, with the base model's free
//! terms, the hidden coefficients and any one other coefficient of the
//! vocabulary free -- the largest such standard error, i.e. against the
//! closest rival (a rival warm-up at the worst time constant of the search
//! grid). That is the precision with which the data can *name* the effect,
//! not only see that something is there. The coefficient is `+-s` standard errors
//! (a delay is positive). A coefficient that the scenario cannot separate
//! from its closest rival (R^2 >= 0.9999, or a zero regressor, e.g. a scale
//! factor at rest) has no finite standard error: it is drawn again, and the
//! count is printed.
//!
//! The unit: the base model's effects (`turn_on_bias` +-0.5 deg/s,
//! `thermal_linear` at the paper's Table 1 slopes times 0.5..1.5, drawn by the
//! simulator) unless one of them is the hidden effect (then the base model
//! lacks it, and only the hidden coefficient is non-zero), plus the hidden
//! coefficients; the simulator's noise, vibration (vehicle) and quantisation.
//! The base model given to the tool: `turn_on_bias` and `thermal_linear`,
//! both free, less the hidden effects.
//!
//! Per hidden coefficient: **named right** (a finding of that effect on that
//! axis and, for a matrix, column), **coefficient within 10 %**, **within 2
//! standard errors** (the reported one), **residual down** (residual RMS of
//! 1-s means on its axis, summed over the axes for the delay, lower at the
//! end than with the base model). **False finds**: findings of coefficients
//! not hidden. Then 20 clean runs (10 vehicle, 10 chamber): every finding
//! is false.
//!
//! `cargo test --release --test gap_detection detection_rate -- --ignored --nocapture`
//! runs the full evaluation (200 draws, 20 clean runs) and writes the plot
//! to `$GAP_DETECTION_OUT` (default `target/gap-detection/`); the fast
//! subset below runs in the normal test run.

use gyrocomp::adis::{builtin_profile, Profile, RawSample};
use gyrocomp::gap::{all_terms, analyse, parse_base, standard_errors, Against, GapResult, MeasRow, Term, TruthIn, T_MIN};
use gyrocomp::sim::model::{
    Effect, GSensitivity, Misalignment, ScaleFactor, SensorModel, ThermalQuadratic, ThermalRate, TimeDelay, TurnOnBias, WarmupTransient,
};
use gyrocomp::sim::motion::{Truth, TruthGen};
use gyrocomp::sim::scenario::Ranges;
use gyrocomp::sim::{draw_model, prepare, Sensor, SimOptions};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::fmt::Write as _;

const VEHICLE_S: f64 = 400.0;
const CHAMBER_S: f64 = 600.0;
const SIZE_RANGE: [f64; 2] = [2.0, 20.0];
/// Size bins of the table, SE.
const BINS: [(f64, f64); 4] = [(2.0, 3.0), (3.0, 5.0), (5.0, 10.0), (10.0, 20.0)];

/// One hidden coefficient.
#[derive(Clone, Copy, Debug)]
struct Hidden {
    term: Term,
    /// size, standard errors
    size: f64,
    se: f64,
    coef: f64,
}

/// One run: scenario, its motion/temperature seed, the hidden coefficients.
struct Draw {
    index: u64,
    scenario: &'static str,
    hidden: Vec<Hidden>,
    tau: f64,
    env: Env,
}

/// What a draw changes in its scenario's temperature: the chamber's cycle
/// (amplitude deg C, period s), the vehicle's ambient change (deg C/s).
#[derive(Clone, Copy, Debug)]
struct Env {
    cycle: Option<(f64, f64)>,
    drift: f64,
}

impl Env {
    fn draw(scenario: &str, rng: &mut ChaCha8Rng) -> Env {
        if scenario == "chamber" {
            Env { cycle: Some((rng.gen_range(5.0..15.0), rng.gen_range(200.0..600.0))), drift: 0.0 }
        } else {
            let sign = if rng.gen_bool(0.5) { 1.0 } else { -1.0 };
            Env { cycle: None, drift: sign * rng.gen_range(0.005..0.015) }
        }
    }
}

/// What one hidden coefficient came to.
#[derive(Clone, Copy, Debug)]
struct Outcome {
    hidden: Hidden,
    named: bool,
    within_10: bool,
    within_2se: bool,
    residual_down: bool,
}

fn profile() -> Profile {
    builtin_profile("adis16448").unwrap()
}

fn duration(scenario: &str) -> f64 {
    if scenario == "vehicle" {
        VEHICLE_S
    } else {
        CHAMBER_S
    }
}

/// The truth of a draw's scenario (seed = the draw's index).
fn truth_of(scenario: &str, index: u64, env: Env) -> (Vec<Truth>, SensorModel) {
    let mut o = SimOptions::new(scenario, index);
    o.duration = Some(duration(scenario));
    // a placeholder model: the motion does not depend on it
    o.model = Some(SensorModel::parse("[gyro]\neffects = []\n").unwrap());
    let mut run = prepare(&o).unwrap();
    if let Some((a, p)) = env.cycle {
        run.spec.thermal.cycle_amp = a;
        run.spec.thermal.cycle_period = p;
    }
    run.spec.thermal.drift = env.drift;
    let truth: Vec<Truth> = TruthGen::new(&run.spec, run.profile.rate_hz).collect();
    // the unit's drawn parameters (turn-on bias, thermal slope, noise, vibration)
    let mut rng = ChaCha8Rng::seed_from_u64(index);
    rng.set_stream(2);
    let unit = draw_model(&mut rng, &Ranges::for_scenario(scenario));
    (truth, unit)
}

fn truth_in(truth: &[Truth]) -> Vec<TruthIn> {
    truth.iter().map(|t| TruthIn { t: t.t, rate: t.rate, f: t.f, temp: t.temp, wd: None }).collect()
}

const PAPER: [Effect; 2] = [Effect::TurnOnBias, Effect::ThermalLinear];

/// The base model given to the tool: the paper's effects, free, less the hidden ones.
fn base_for(hidden: &[Term]) -> SensorModel {
    let names: Vec<String> =
        PAPER.iter().filter(|e| !hidden.iter().any(|h| h.effect == **e)).map(|e| format!("\"{}\"", e.name())).collect();
    parse_base(&format!("[gyro]\neffects = [{}]\n", names.join(", "))).unwrap()
}

/// Draw `index`: scenario, hidden coefficients and sizes. `sizes` is the range drawn from.
/// Counts redraws of coefficients the scenario cannot separate in `skipped`.
fn draw(index: u64, sizes: [f64; 2], skipped: &mut Vec<(String, &'static str)>) -> (Draw, Vec<Truth>, SensorModel) {
    let mut rng = ChaCha8Rng::seed_from_u64(0x6a70 + index);
    let scenario = if rng.gen_bool(0.5) { "vehicle" } else { "chamber" };
    let env = Env::draw(scenario, &mut rng);
    let (truth, unit) = truth_of(scenario, index, env);
    let ti = truth_in(&truth);
    let count = if rng.gen_bool(0.5) { 1 } else { 2 };
    let tau = rng.gen_range(20.0..60.0);
    let mut terms: Vec<Term> = Vec::new();
    let mut ses = Vec::new();
    let mut tries = 0;
    while terms.len() < count && tries < 100 {
        tries += 1;
        let e = Effect::ALL[rng.gen_range(0..Effect::ALL.len())];
        let all = all_terms(e);
        let t = all[rng.gen_range(0..all.len())];
        if terms.contains(&t) {
            continue;
        }
        let mut cand = terms.clone();
        cand.push(t);
        let se = standard_errors(&ti, &base_for(&cand), &profile(), &cand, tau, Against::ClosestRival).unwrap();
        if se.iter().any(|s| !s.is_finite()) {
            skipped.push((t.label(), scenario));
            continue;
        }
        terms = cand;
        ses = se;
    }
    let hidden: Vec<Hidden> = terms
        .iter()
        .zip(&ses)
        .map(|(t, se)| {
            let size = (sizes[0].ln() + rng.gen::<f64>() * (sizes[1] / sizes[0]).ln()).exp();
            let sign = if t.effect == Effect::TimeDelay || rng.gen_bool(0.5) { 1.0 } else { -1.0 };
            Hidden { term: *t, size, se: *se, coef: sign * size * se }
        })
        .collect();
    (Draw { index, scenario, hidden, tau, env }, truth, unit)
}

/// The true sensor: the unit's base effects (unless hidden) plus the hidden coefficients.
fn true_model(unit: &SensorModel, hidden: &[Hidden], tau: f64) -> SensorModel {
    let mut m = unit.clone();
    let g = &mut m.gyro;
    let base_hidden = |e: Effect| hidden.iter().any(|h| h.term.effect == e);
    g.effects = PAPER.iter().copied().filter(|e| !base_hidden(*e)).collect();
    g.turn_on_bias = Some(TurnOnBias { bias: unit.gyro.turn_on_bias.as_ref().unwrap().bias });
    g.thermal_linear = unit.gyro.thermal_linear.clone();
    for e in Effect::ALL.iter().copied().filter(|e| base_hidden(*e)) {
        let v3 = || {
            let mut v = [0.0; 3];
            for h in hidden.iter().filter(|h| h.term.effect == e) {
                v[h.term.axis] = h.coef;
            }
            v
        };
        let m33 = || {
            let mut v = [[0.0; 3]; 3];
            for h in hidden.iter().filter(|h| h.term.effect == e) {
                v[h.term.axis][h.term.col] = h.coef;
            }
            v
        };
        match e {
            Effect::TurnOnBias => g.turn_on_bias = Some(TurnOnBias { bias: v3() }),
            Effect::ThermalLinear => g.thermal_linear.as_mut().unwrap().p1 = v3(),
            Effect::ThermalQuadratic => g.thermal_quadratic = Some(ThermalQuadratic { t0: 25.0, p2: v3() }),
            Effect::ThermalRate => g.thermal_rate = Some(ThermalRate { k: v3() }),
            Effect::WarmupTransient => g.warmup_transient = Some(WarmupTransient { amplitude: v3(), tau_s: tau }),
            Effect::GSensitivity => g.g_sensitivity = Some(GSensitivity { g: m33() }),
            Effect::ScaleFactor => g.scale_factor = Some(ScaleFactor { k: v3() }),
            Effect::Misalignment => g.misalignment = Some(Misalignment { m: m33() }),
            Effect::TimeDelay => g.time_delay = Some(TimeDelay { delay_s: hidden.iter().find(|h| h.term.effect == e).unwrap().coef }),
        }
        g.effects.push(e);
    }
    m.validate().unwrap();
    m
}

/// Measure the truth with `model` (noise stream from the draw's index), quantised as the log would be.
fn measure(truth: &[Truth], model: &SensorModel, index: u64) -> Vec<MeasRow> {
    let p = profile();
    let mut rng = ChaCha8Rng::seed_from_u64(index);
    rng.set_stream(3);
    let mut sensor = Sensor::new(model, p.rate_hz, rng);
    truth
        .iter()
        .map(|tr| {
            let m = sensor.measure(tr);
            let raw = RawSample::quantise(&p, m.gyro, m.accel, m.magn, m.temp);
            MeasRow { t: tr.t, gyro: raw.gyro.map(|v| v as f64 * p.gyro_lsb), acc: tr.f, temp: m.temp }
        })
        .collect()
}

/// Run the tool on a draw: its result (or the refusal) and the outcome per hidden coefficient.
fn evaluate(d: &Draw, truth: &[Truth], unit: &SensorModel) -> (Result<GapResult, String>, Vec<Outcome>) {
    let model = true_model(unit, &d.hidden, d.tau);
    let meas = measure(truth, &model, d.index);
    let terms: Vec<Term> = d.hidden.iter().map(|h| h.term).collect();
    let r = analyse(&meas, &truth_in(truth), true, &base_for(&terms), &profile());
    let outcomes = d
        .hidden
        .iter()
        .map(|h| {
            let Ok(r) = &r else {
                return Outcome { hidden: *h, named: false, within_10: false, within_2se: false, residual_down: false };
            };
            let rep = &r.report;
            let f = rep.findings.iter().find(|f| f.term == h.term.label());
            let ss = |v: &[f64; 3]| h.term.axes().iter().map(|a| v[*a] * v[*a]).sum::<f64>();
            Outcome {
                hidden: *h,
                named: f.is_some(),
                within_10: f.is_some_and(|f| ((f.coefficient - h.coef) / h.coef).abs() <= 0.10),
                within_2se: f.is_some_and(|f| (f.coefficient - h.coef).abs() <= 2.0 * f.std_error),
                residual_down: ss(&rep.rms_final) < ss(&rep.rms_initial),
            }
        })
        .collect();
    (r, outcomes)
}

/// Findings of coefficients that were not hidden.
fn false_finds(r: &GapResult, hidden: &[Hidden]) -> Vec<String> {
    r.report
        .findings
        .iter()
        .filter(|f| !hidden.iter().any(|h| h.term.label() == f.term))
        .map(|f| format!("{} (t = {:.1})", f.term, f.t_stat))
        .collect()
}

/// Probability that |N(s, 1)| >= T_MIN: what a perfect t test names at size s.
fn power(s: f64) -> f64 {
    0.5 * (erfc((T_MIN - s) / std::f64::consts::SQRT_2) + erfc((T_MIN + s) / std::f64::consts::SQRT_2))
}

/// Probability that |N(0, 1/s)| <= 0.1: an unbiased estimate at s standard errors within 10 %.
fn within_10_bound(s: f64) -> f64 {
    1.0 - erfc(0.1 * s / std::f64::consts::SQRT_2)
}

/// Complementary error function (Numerical Recipes' erfcc, |error| < 1.2e-7).
fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let r = t
        * (-z * z - 1.26551223
            + t * (1.00002368
                + t * (0.37409196
                    + t * (0.09678418
                        + t * (-0.18628806
                            + t * (0.27886807 + t * (-1.13520398 + t * (1.48851587 + t * (-0.82215223 + t * 0.17087277)))))))))
            .exp();
    if x >= 0.0 {
        r
    } else {
        2.0 - r
    }
}

/// A clean run: the unit with nothing hidden. Returns the findings (all false) and ambiguities.
fn clean_run(index: u64, scenario: &'static str) -> Result<(Vec<String>, usize), String> {
    let mut rng = ChaCha8Rng::seed_from_u64(0xc1ea + index);
    let env = Env::draw(scenario, &mut rng);
    let (truth, unit) = truth_of(scenario, 1000 + index, env);
    let model = true_model(&unit, &[], 30.0);
    let meas = measure(&truth, &model, 1000 + index);
    let r = analyse(&meas, &truth_in(&truth), true, &base_for(&[]), &profile())?;
    Ok((false_finds(&r, &[]), r.report.ambiguous.len()))
}

struct Tally {
    n: usize,
    named: usize,
    w10: usize,
    w2: usize,
    down: usize,
    power: f64,
    bound10: f64,
}

impl Tally {
    fn new() -> Tally {
        Tally { n: 0, named: 0, w10: 0, w2: 0, down: 0, power: 0.0, bound10: 0.0 }
    }
    fn add(&mut self, o: &Outcome) {
        self.n += 1;
        self.named += o.named as usize;
        self.w10 += o.within_10 as usize;
        self.w2 += o.within_2se as usize;
        self.down += o.residual_down as usize;
        self.power += power(o.hidden.size);
        self.bound10 += within_10_bound(o.hidden.size);
    }
    fn pct(&self, k: usize) -> f64 {
        100.0 * k as f64 / self.n.max(1) as f64
    }
    fn row(&self, label: &str) -> String {
        let named_of = self.named.max(1) as f64;
        format!(
            "{label:<10} {:>6} {:>7.1} % {:>7.1} % {:>7.1} % {:>7.1} % {:>7.1} % {:>7.1} %\n",
            self.n,
            self.pct(self.named),
            100.0 * self.power / self.n.max(1) as f64,
            100.0 * self.w10 as f64 / named_of,
            100.0 * self.bound10 / self.n.max(1) as f64,
            100.0 * self.w2 as f64 / named_of,
            self.pct(self.down)
        )
    }
}

/// The table of a set of outcomes.
fn table(outcomes: &[Outcome]) -> String {
    let mut s = String::new();
    s += "size (SE)  hidden   named    perfect  coef<=10%  bound   <=2 SE   resid down\n";
    s += "                             t test   (of named)          (named)\n";
    for (lo, hi) in BINS {
        let mut t = Tally::new();
        outcomes.iter().filter(|o| o.hidden.size >= lo && o.hidden.size < hi + 1e-9).for_each(|o| t.add(o));
        s += &t.row(&format!("{lo}-{hi}"));
    }
    let mut t = Tally::new();
    outcomes.iter().filter(|o| o.hidden.size >= 5.0).for_each(|o| t.add(o));
    s += &t.row(">= 5");
    s
}

/// Per effect, hidden coefficients of 5 SE and more: named / count.
fn per_effect(outcomes: &[Outcome]) -> String {
    let mut s = String::from("named right at >= 5 SE per effect:");
    for e in Effect::ALL {
        let v: Vec<&Outcome> = outcomes.iter().filter(|o| o.hidden.term.effect == e && o.hidden.size >= 5.0).collect();
        let _ = write!(s, " {} {}/{};", e.name(), v.iter().filter(|o| o.named).count(), v.len());
    }
    s.pop();
    s + "\n"
}

/// Detection rate against size: measured (log-spaced bins) and the perfect t test's.
fn plot(outcomes: &[Outcome], path: &std::path::Path) -> Result<(), String> {
    use plotters::prelude::*;
    let e = |x: &dyn std::fmt::Display| x.to_string();
    let edges: Vec<f64> = (0..=8).map(|k| SIZE_RANGE[0] * (SIZE_RANGE[1] / SIZE_RANGE[0]).powf(k as f64 / 8.0)).collect();
    let mut pts = Vec::new();
    for w in edges.windows(2) {
        let v: Vec<&Outcome> = outcomes.iter().filter(|o| o.hidden.size >= w[0] && o.hidden.size < w[1] + 1e-9).collect();
        if !v.is_empty() {
            let rate = v.iter().filter(|o| o.named).count() as f64 / v.len() as f64;
            pts.push(((w[0] * w[1]).sqrt(), 100.0 * rate, v.len()));
        }
    }
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (900, 560)).into_drawing_area();
        root.fill(&WHITE).map_err(|x| e(&x))?;
        let mut ch = ChartBuilder::on(&root)
            .caption("gyrocomp gap: hidden effects named right vs size (grey: 5 SE, 95 %)", ("sans-serif", 20))
            .margin(14)
            .x_label_area_size(45)
            .y_label_area_size(60)
            .build_cartesian_2d(
                (SIZE_RANGE[0]..SIZE_RANGE[1]).log_scale().with_key_points(vec![2.0, 3.0, 4.0, 5.0, 7.0, 10.0, 15.0, 20.0]),
                0.0..105.0,
            )
            .map_err(|x| e(&x))?;
        ch.configure_mesh()
            .x_desc("size of the hidden coefficient, standard errors against its closest rival (white noise + bias random walk, full rate)")
            .y_desc("named right, %")
            .draw()
            .map_err(|x| e(&x))?;
        let curve: Vec<(f64, f64)> = (0..=200)
            .map(|k| SIZE_RANGE[0] * (SIZE_RANGE[1] / SIZE_RANGE[0]).powf(k as f64 / 200.0))
            .map(|s| (s, 100.0 * power(s)))
            .collect();
        ch.draw_series(LineSeries::new(curve, BLACK.stroke_width(1)))
            .map_err(|x| e(&x))?
            .label(format!("perfect t test, |t| >= {T_MIN}"))
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 15, y)], BLACK));
        ch.draw_series(LineSeries::new(vec![(5.0, 0.0), (5.0, 105.0)], RGBColor(150, 150, 150).stroke_width(1))).map_err(|x| e(&x))?;
        ch.draw_series(LineSeries::new(vec![(SIZE_RANGE[0], 95.0), (SIZE_RANGE[1], 95.0)], RGBColor(150, 150, 150).stroke_width(1)))
            .map_err(|x| e(&x))?;
        ch.draw_series(pts.iter().map(|p| Circle::new((p.0, p.1), 5, BLUE.filled())))
            .map_err(|x| e(&x))?
            .label("gyrocomp gap (bins of 1/8 decade)")
            .legend(|(x, y)| Circle::new((x + 7, y), 4, BLUE.filled()));
        ch.draw_series(pts.iter().map(|p| Text::new(format!("{}", p.2), (p.0, p.1 - 6.0), ("sans-serif", 12)))).map_err(|x| e(&x))?;
        ch.configure_series_labels()
            .position(SeriesLabelPosition::LowerRight)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|x| e(&x))?;
        root.present().map_err(|x| e(&x))?;
    }
    gyrocomp::outfile::write_atomic(path, svg.as_bytes()).map_err(|e| format!("{}: {e}", path.display()))
}

fn describe(d: &Draw) -> String {
    let h: Vec<String> =
        d.hidden.iter().map(|h| format!("{} {:+.3e} ({:.1} SE of {:.2e})", h.term.label(), h.coef, h.size, h.se)).collect();
    let env = match d.env.cycle {
        Some(c) => format!("cycle {:.1} C / {:.0} s", c.0, c.1),
        None => format!("ambient {:+.4} C/s", d.env.drift),
    };
    format!("draw {} {} ({env}): {}", d.index, d.scenario, h.join(", "))
}

/// What a set of draws came to.
struct Run {
    outcomes: Vec<Outcome>,
    /// findings of coefficients not hidden
    falses: Vec<String>,
    /// draws the tool refused
    refused: Vec<String>,
    /// coefficients redrawn as not separable in their scenario: (term, scenario)
    skipped: Vec<(String, &'static str)>,
}

/// Run draws `0..n` (sizes from `sizes`); progress on stderr.
fn run_draws(n: u64, sizes: [f64; 2], verbose: bool) -> Run {
    let (mut outcomes, mut falses, mut refused, mut skipped) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for i in 0..n {
        let (d, truth, unit) = draw(i, sizes, &mut skipped);
        let (r, o) = evaluate(&d, &truth, &unit);
        match &r {
            Ok(r) => {
                for f in false_finds(r, &d.hidden) {
                    falses.push(format!("{}: false find {f}", describe(&d)));
                }
            }
            Err(e) => refused.push(format!("{}: refused: {e}", describe(&d))),
        }
        if verbose {
            let miss: Vec<String> = o.iter().filter(|o| !o.named).map(|o| o.hidden.term.label()).collect();
            let amb = r.as_ref().map_or(0, |r| r.report.ambiguous.len());
            eprintln!(
                "{}{}{}",
                describe(&d),
                if miss.is_empty() { String::new() } else { format!(" -- missed {}", miss.join(", ")) },
                if amb > 0 { format!(" ({amb} not separable)") } else { String::new() }
            );
        }
        outcomes.extend(o);
    }
    Run { outcomes, falses, refused, skipped }
}

/// The full evaluation: prints the table, writes the plot.
#[test]
#[ignore]
fn detection_rate_against_size() {
    let t0 = std::time::Instant::now();
    let n = std::env::var("GAP_DETECTION_DRAWS").ok().and_then(|s| s.parse().ok()).unwrap_or(200);
    let Run { outcomes, falses, refused, skipped } = run_draws(n, SIZE_RANGE, true);
    let mut clean_false = Vec::new();
    let mut clean_amb = 0;
    for i in 0..20 {
        let sc = if i < 10 { "vehicle" } else { "chamber" };
        match clean_run(i, sc) {
            Ok((f, a)) => {
                clean_false.extend(f.into_iter().map(|f| format!("clean {sc} {i}: {f}")));
                clean_amb += a;
            }
            Err(e) => clean_false.push(format!("clean {sc} {i}: refused: {e}")),
        }
    }
    let mut out = format!(
        "gap detection: {n} draws (vehicle {VEHICLE_S} s with an ambient change; chamber {CHAMBER_S} s with a temperature cycle), \
         1-2 hidden coefficients each, sizes log-uniform {}..{} SE (against the closest rival); significant when |t| >= {T_MIN}\n",
        SIZE_RANGE[0], SIZE_RANGE[1]
    );
    out += &table(&outcomes);
    out += &per_effect(&outcomes);
    out += &format!("false finds in the draws: {}; refused draws: {}\n", falses.len(), refused.len());
    out += &format!("clean runs: 20 (10 vehicle, 10 chamber): false finds {}, not-separable pairs {clean_amb}\n", clean_false.len());
    let mut sk: Vec<String> = skipped.iter().map(|(t, s)| format!("{t} in {s}")).collect();
    sk.sort();
    sk.dedup();
    out += &format!("redrawn as not separable in their scenario: {} ({})\n", skipped.len(), sk.join(", "));
    for f in falses.iter().chain(&refused).chain(&clean_false) {
        out += &format!("  {f}\n");
    }
    let dir = std::path::PathBuf::from(
        std::env::var("GAP_DETECTION_OUT").unwrap_or_else(|_| concat!(env!("CARGO_MANIFEST_DIR"), "/target/gap-detection").into()),
    );
    std::fs::create_dir_all(&dir).unwrap();
    plot(&outcomes, &dir.join("gap_detection.svg")).unwrap();
    gyrocomp::outfile::write_atomic(&dir.join("gap_detection.txt"), out.as_bytes()).unwrap();
    println!("{out}wrote {}\n{:.0} s", dir.join("gap_detection.svg").display(), t0.elapsed().as_secs_f64());
}

/// The fast subset: the first draws, sized 8..20 SE (where a perfect t test names
/// more than 99.99 %), must all be named right with no false find; three clean runs find nothing.
#[test]
fn large_hidden_effects_are_named_and_clean_runs_stay_clean() {
    let Run { outcomes, falses, refused, .. } = run_draws(6, [8.0, 20.0], true);
    assert!(refused.is_empty(), "{refused:?}");
    assert!(falses.is_empty(), "{falses:?}");
    for o in &outcomes {
        assert!(o.named, "{} ({:.1} SE, {:+.3e}) not named", o.hidden.term.label(), o.hidden.size, o.hidden.coef);
        assert!(o.within_2se, "{} coefficient not within 2 SE", o.hidden.term.label());
        assert!(o.residual_down, "{}: residual not down", o.hidden.term.label());
    }
    for (i, sc) in [(0, "vehicle"), (10, "chamber"), (1, "vehicle")] {
        let (f, a) = clean_run(i, sc).unwrap();
        assert!(f.is_empty() && a == 0, "clean {sc} {i}: {f:?}, {a} not separable");
    }
}

/// One draw in detail: `GAP_DRAW=N cargo test --release --test gap_detection one_draw -- --ignored --nocapture`.
#[test]
#[ignore]
fn one_draw() {
    let i: u64 = std::env::var("GAP_DRAW").ok().and_then(|s| s.parse().ok()).unwrap_or(0);
    let mut sk = Vec::new();
    let (d, truth, unit) = draw(i, SIZE_RANGE, &mut sk);
    let (r, _) = evaluate(&d, &truth, &unit);
    println!("{}", describe(&d));
    match r {
        Ok(r) => {
            for a in &r.report.ambiguous {
                println!("{}", a.reason);
            }
            for f in &r.report.findings {
                println!("found {} {:.4e} t {:.1} rivals {}", f.term, f.coefficient, f.t_stat, f.evidence["rivals"]);
            }
            println!("var ratio {:?} checks {:?}", r.report.variance_ratio_final, r.report.checks.full_vocabulary_variance_ratio);
        }
        Err(e) => println!("{e}"),
    }
}

/// Standard errors of one coefficient per effect, against the base model and
/// against its closest rival, in the scenarios of the draws (and an 800 s
/// vehicle run): which effects each scenario can name.
#[test]
#[ignore]
fn separability_table() {
    for (sc, dur, cyc, drift) in [
        ("vehicle", 400.0, None, 0.01),
        ("vehicle", 800.0, None, 0.01),
        ("vehicle", 400.0, None, -0.005),
        ("chamber", 600.0, Some((10.0, 400.0)), 0.0),
    ] {
        let mut o = SimOptions::new(sc, 5);
        o.duration = Some(dur);
        o.model = Some(SensorModel::parse("[gyro]\neffects = []\n").unwrap());
        let mut run = prepare(&o).unwrap();
        if let Some((a, p)) = cyc {
            run.spec.thermal.cycle_amp = a;
            run.spec.thermal.cycle_period = p;
        }
        run.spec.thermal.drift = drift;
        let truth: Vec<Truth> = TruthGen::new(&run.spec, run.profile.rate_hz).collect();
        let ti = truth_in(&truth);
        let mut line = format!("{sc} {dur} {drift}:");
        for e in Effect::ALL {
            let t = all_terms(e)[if e == Effect::TimeDelay { 0 } else { 1 }];
            let b = standard_errors(&ti, &base_for(&[t]), &profile(), &[t], 30.0, Against::Base).unwrap()[0];
            let r = standard_errors(&ti, &base_for(&[t]), &profile(), &[t], 30.0, Against::ClosestRival).unwrap()[0];
            line += &format!(" {} {:.1e}/{:.1e};", t.label(), b, r);
        }
        println!("{line}");
    }
}
