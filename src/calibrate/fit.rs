//! `calibrate_runs`: the module documentation's steps 2-8 on runs already
//! read, one function per step: each run screened and its self-heating
//! fitted (`prepare`), the warm-up transients and their cuts (`cut_transients`),
//! the runs whose transient cannot be told from their self-heating
//! (`separate`), the curve (`fit_axes`), and the calibration assembled
//! (`assemble`).

use super::gls::{self, fit_axis, fit_axis_mu, mu_upper, reml_at, reml_lambda, reml_shared, Design, Rows};
use super::*;

/// One run's bins prepared for the fit.
struct Prepared<'a> {
    bins: &'a [Bin],
    keep: Vec<bool>,
    n_med: f64,
}

/// What every fit's rows share: the reference temperature, the scale of
/// `T - t0`, the curve's order.
#[derive(Clone, Copy)]
struct Basis {
    t0: f64,
    scale: f64,
    order: usize,
}

/// A run's bins and, for each, whether it was used in the fit.
type RunData = (Vec<Bin>, Vec<bool>);

impl Prepared<'_> {
    fn rows(&self, b: Basis, cut: f64) -> Rows {
        let (t0, scale) = (b.t0, b.scale);
        let mut r = Rows::default();
        for (b, k) in self.bins.iter().zip(&self.keep) {
            if *k && b.t >= cut {
                r.t.push(b.t);
                r.u.push((b.temp - t0) / scale);
                r.y.push(b.gyro);
                r.r.push(self.n_med / b.n.max(1) as f64);
            }
        }
        r
    }
}

/// Fit the curve to chamber runs already read. `t0` is the reference temperature.
pub fn calibrate_runs(runs: &[Run], order: u8, t0: f64) -> Result<Calibration, CalError> {
    if !(1..=3).contains(&order) {
        return Err(CalError::Fit(format!("order must be 1, 2 or 3, got {order}")));
    }
    if runs.is_empty() {
        return Err(CalError::Fit("no run".into()));
    }
    if !t0.is_finite() {
        return Err(CalError::Fit(format!("t0 must be finite, got {t0}")));
    }
    let order_u = order as usize;
    let mut warnings = Vec::new();
    let (mut reports, prep): (Vec<RunReport>, Vec<Prepared<'_>>) = runs.iter().map(|run| prepare(run, &mut warnings)).unzip();
    let cand: Vec<usize> = (0..runs.len()).filter(|&r| reports[r].used).collect();
    if cand.is_empty() {
        return Err(no_run_left(&reports));
    }
    let scale = cand
        .iter()
        .flat_map(|&r| prep[r].bins.iter().zip(&prep[r].keep).filter(|(_, k)| **k).map(|(b, _)| (b.temp - t0).abs()))
        .fold(1.0f64, f64::max);
    let basis = Basis { t0, scale, order: order_u };
    let (cuts, lams) = cut_transients(&prep, &mut reports, &cand, basis, &mut warnings);
    separate(&prep, &mut reports, &cuts, lams, basis, &mut warnings)?;
    warmup_warnings(&reports, &mut warnings);
    // Step 7: the fit after the cuts.
    let used: Vec<usize> = (0..runs.len()).filter(|&r| reports[r].used).collect();
    let rows: Vec<Rows> = used.iter().map(|&r| prep[r].rows(basis, cuts[r])).collect();
    // a time jump between the rows a run keeps: the walk spans it
    let jumps = rows.iter().any(|r| r.t.windows(2).any(|w| w[1] - w[0] > JUMP_S));
    let pose = pose_spread_deg(&prep, &used);
    let same_pose = pose <= TILT_LIMIT_DEG;
    if !same_pose {
        warnings.push(format!(
            "the runs lie in different orientations (gravity directions up to {pose:.1} deg apart): a g-sensitive bias differs between them, so their levels do not carry the slope; each run has its own constant (only the temperature's change within the runs tells the slope)"
        ));
    }
    let (axes, own) = fit_axes(&rows, order, scale, jumps, same_pose)?;
    let n = own[0].n;
    let (range, data) = assemble(&prep, &mut reports, &cuts, &used, &own);
    if range.1 - range.0 < MIN_RANGE_C {
        warnings.push(format!(
            "temperature range covered is {:.1} deg C ({:.1}..{:.1}), under {MIN_RANGE_C:.0} deg C: the curve is poorly determined and is clamped outside it",
            range.1 - range.0,
            range.0,
            range.1
        ));
    }
    Ok(Calibration { order, t0, axes, range, bins_used: n, runs: reports, warnings, data })
}

/// Steps 2-4 for one run: its report, the static check's bins kept, the
/// self-heating fit and the transient's limit, and the warnings they give.
fn prepare<'a>(run: &'a Run, warnings: &mut Vec<String>) -> (RunReport, Prepared<'a>) {
    let mut rep = RunReport {
        name: run.name.clone(),
        samples: run.samples,
        bad_lines: run.bad_lines,
        duration_s: run.bins.len() as f64 * BIN_S,
        heat_rise_c: f64::NAN,
        heat_tau_s: f64::NAN,
        slope_z: f64::NAN,
        offset: [f64::NAN; 3],
        used: true,
        ..Default::default()
    };
    let (lo, hi) = run.bins.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), b| (l.min(b.temp), h.max(b.temp)));
    rep.temp = (lo, hi);
    rep.stretches =
        read::stretches(&run.bins).into_iter().map(|(a, b)| (run.bins[a].t - 0.5 * BIN_S, run.bins[b - 1].t + 0.5 * BIN_S)).collect();
    let full = screen::full_bins(&run.bins);
    let keep = screen::static_check(&run.bins, &full, &mut rep);
    if !rep.is_static {
        warnings.push(format!(
            "{}: not static: rotation detected (largest |gyro - local median| {:.3} deg/s at t = {:.0} s, largest tilt {:.2} deg{}); {:.0} s left out of the fit",
            run.name,
            rep.max_rot_dps,
            rep.max_rot_at_s,
            rep.max_tilt_deg,
            if rep.max_sd_ratio > 0.0 { format!(", a within-bin gyro SD {:.1} x the run's median", rep.max_sd_ratio) } else { String::new() },
            rep.moving_s
        ));
    }
    if run.resyncs > 0 {
        warnings.push(format!("{}: {} sample-counter restart(s): is this one power cycle?", run.name, run.resyncs));
    }
    if run.backwards > 0 {
        warnings.push(format!("{}: timestamps go backwards {} time(s)", run.name, run.backwards));
    }
    let (kt, ktemp): (Vec<f64>, Vec<f64>) = run.bins.iter().zip(&keep).filter(|(_, k)| **k).map(|(b, _)| (b.t, b.temp)).unzip();
    let heat = warmup::fit_heating(&kt, &ktemp);
    if let Some(h) = &heat {
        rep.heat_rise_c = h.rise;
        rep.heat_tau_s = h.tau_s;
    }
    rep.tau_limit_s = warmup::tau_limit(heat.as_ref());
    if kt.len() < MIN_FIT_BINS {
        rep.used = false;
        rep.left_out = Some(format!("only {} static seconds (need {MIN_FIT_BINS})", kt.len()));
    }
    let mut ns: Vec<f64> = run.bins.iter().map(|b| b.n as f64).collect();
    let n_med = screen::median(&mut ns).max(1.0);
    (rep, Prepared { bins: &run.bins, keep, n_med })
}

/// Step 6: the warm-up transients fitted on everything static (the runs
/// `cand`), each run's decision and cut; a run left with too few bins after
/// its cut is left out. Returns the cut of every run (s) and the walks the
/// transients' fit found (zero when it failed).
fn cut_transients(
    prep: &[Prepared<'_>],
    reports: &mut [RunReport],
    cand: &[usize],
    basis: Basis,
    warnings: &mut Vec<String>,
) -> (Vec<f64>, [f64; 3]) {
    let rows_all: Vec<Rows> = cand.iter().map(|&r| prep[r].rows(basis, f64::NEG_INFINITY)).collect();
    let limits: Vec<f64> = cand.iter().map(|&r| reports[r].tau_limit_s).collect();
    let mut cuts = vec![0.0; reports.len()];
    let mut lams = [0.0; 3];
    match warmup::find(&rows_all, basis.order, &limits) {
        Some(tr) => {
            lams = tr.lams;
            for (c, &r) in cand.iter().enumerate() {
                let rep = &mut reports[r];
                rep.tau_s = tr.tau[c];
                rep.amplitude = tr.amp[c];
                rep.transient_z = tr.z[c];
                rep.transient = tr.z[c] > TRANSIENT_Z;
                rep.warmup = match (rep.transient, tr.at_limit[c]) {
                    (false, _) => Warmup::None,
                    (true, false) => Warmup::Cut,
                    (true, true) => Warmup::AtLimit,
                };
                if rep.transient {
                    cuts[r] = CUT_TAUS * tr.tau[c];
                }
                rep.cut_s = cuts[r];
            }
        }
        None => warnings.push(
            "the warm-up transients could not be fitted (the runs do not determine the curve and a transient each): nothing cut".into(),
        ),
    }
    for &r in cand {
        let left = prep[r].rows(basis, cuts[r]).len();
        if left < MIN_FIT_BINS {
            let rep = &mut reports[r];
            rep.used = false;
            rep.left_out = Some(format!("{left} s left after the warm-up cut of {:.0} s (need {MIN_FIT_BINS})", cuts[r]));
            if rep.warmup == Warmup::AtLimit {
                rep.warmup = Warmup::NotSeparable;
            }
        }
    }
    (cuts, lams)
}

/// Step 6, transients at the limit: a run whose own slope after the cut
/// disagrees with the others' is not separable and left out. When every
/// run is then left out, those left out only as not separable are used
/// anyway, with a warning; an error when none is.
fn separate(
    prep: &[Prepared<'_>],
    reports: &mut [RunReport],
    cuts: &[f64],
    lams: [f64; 3],
    basis: Basis,
    warnings: &mut Vec<String>,
) -> Result<(), CalError> {
    let r_n = reports.len();
    let at_limit: Vec<usize> = (0..r_n).filter(|&r| reports[r].used && reports[r].warmup == Warmup::AtLimit).collect();
    let mut not_separable = Vec::new();
    for &r in &at_limit {
        let inn: Vec<usize> = (0..r_n).filter(|&q| reports[q].used).collect();
        let rows: Vec<Rows> = inn.iter().map(|&q| prep[q].rows(basis, cuts[q])).collect();
        let pos = inn.iter().position(|&q| q == r).expect("run is in");
        if let Some(z) = warmup::own_slope_z(&rows, basis.order, pos, lams) {
            reports[r].slope_z = z;
            if z > CONSISTENT_Z {
                not_separable.push(r);
            }
        }
    }
    for &r in &not_separable {
        let rep = &mut reports[r];
        rep.warmup = Warmup::NotSeparable;
        rep.used = false;
        rep.left_out = Some(format!(
            "its warm-up transient cannot be told from its self-heating (slope after the cut {:.1} SE from the other runs')",
            rep.slope_z
        ));
    }
    if (0..r_n).any(|r| reports[r].used) {
        return Ok(());
    }
    if not_separable.is_empty() {
        return Err(no_run_left(reports));
    }
    for &r in &not_separable {
        reports[r].used = true;
        reports[r].left_out = None;
    }
    warnings.push(format!(
        "no run separates its warm-up transient from its self-heating: {} used anyway with the cuts shown; the slope may be biased (record longer, or from a cold start with a faster transient)",
        not_separable.iter().map(|&r| reports[r].name.as_str()).collect::<Vec<_>>().join(", ")
    ));
    Ok(())
}

/// The warnings of every run's warm-up decision and of every run left out.
fn warmup_warnings(reports: &[RunReport], warnings: &mut Vec<String>) {
    for rep in reports {
        match rep.warmup {
            Warmup::NotSeparable => warnings.push(format!(
                "{}: warm-up transient not separable from the self-heating (the fit wants the slowest transient allowed, tau_heat / {FAST_RATIO:.0} = {:.0} s){}",
                rep.name,
                rep.tau_limit_s,
                if rep.used { "".to_string() } else { ": left out of the fit; calibrated from the other runs".to_string() }
            )),
            Warmup::AtLimit => warnings.push(format!(
                "{}: warm-up transient at the {:.0} s limit (tau_heat / {FAST_RATIO:.0}, or the {TAU_MAX_S:.0} s grid end): cut {:.0} s, conservatively{}",
                rep.name,
                rep.tau_limit_s,
                rep.cut_s,
                if rep.slope_z.is_finite() {
                    format!("; its slope after the cut agrees with the other runs' ({:.1} SE)", rep.slope_z)
                } else {
                    "; cannot be checked against other runs".to_string()
                }
            )),
            _ => {}
        }
        if !rep.used && rep.warmup != Warmup::NotSeparable {
            if let Some(why) = &rep.left_out {
                warnings.push(format!("{}: left out of the fit: {why}", rep.name));
            }
        }
    }
}

/// Step 7, per axis: the curve under one of the two level models, and each
/// run's own constant (the per-run fits, for the runs' reports). With
/// `jumps` (a run read as stretches), the intervals are taken at the walk's
/// 95 % upper bound too, if wider: the walk across a jump is extrapolated
/// from what the short stretches show, and they may barely bound it.
/// With `same_pose` false (the runs in different orientations) the levels
/// are never shared.
fn fit_axes(rows: &[Rows], order: u8, scale: f64, jumps: bool, same_pose: bool) -> Result<([AxisFit; 3], Vec<gls::AxisGls>), CalError> {
    let order_u = order as usize;
    let d = Design::new(rows, order_u);
    let lams = [0, 1, 2].map(|i| reml_lambda(&d, i));
    let not_determined = || {
        CalError::Fit(format!(
            "order {order} is not determined by these runs (temperature varies too little within the runs after the warm-up cut)"
        ))
    };
    // each run's own constant: what each run read at t0 (the per-run report)
    let own = (0..3).map(|i| fit_axis(&d, i, lams[i])).collect::<Option<Vec<_>>>().ok_or_else(not_determined)?;
    let n = own[0].n;
    let ds = Design::shared(rows, order_u);
    let mut axes = Vec::with_capacity(3);
    for i in 0..3 {
        // the curve: one level for all runs, each run's turn-on offset random
        // (step 7), unless the runs' levels say they differ
        let axis = match same_pose.then(|| shared_axis(&ds, i, lams[i], scale, jumps)).flatten() {
            Some(a) => a.ok_or_else(not_determined)?,
            None => per_run_axis(&d, &own[i], i, lams[i], scale, jumps, !same_pose),
        };
        axes.push(AxisFit { rms: (own[i].raw_ss / n as f64).sqrt(), ..axis });
    }
    Ok((axes.try_into().expect("three axes"), own))
}

/// The largest angle between the runs' gravity directions (the median
/// direction of each run's specific force over its bins kept), deg; 0 with
/// one run or without an accelerometer.
fn pose_spread_deg(prep: &[Prepared<'_>], used: &[usize]) -> f64 {
    let dirs: Vec<[f64; 3]> = used
        .iter()
        .filter_map(|&r| {
            let bins: Vec<&Bin> = prep[r]
                .bins
                .iter()
                .zip(&prep[r].keep)
                .filter(|(b, k)| **k && b.accel.iter().all(|v| v.is_finite()))
                .map(|(b, _)| b)
                .collect();
            let m: [f64; 3] = std::array::from_fn(|i| screen::median(&mut bins.iter().map(|b| b.accel[i]).collect::<Vec<_>>()));
            let n = crate::estimator::quat::norm(&m);
            (!bins.is_empty() && n > 0.0).then(|| m.map(|v| v / n))
        })
        .collect();
    let mut worst = 0.0f64;
    for (k, a) in dirs.iter().enumerate() {
        for b in &dirs[k + 1..] {
            let c = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]).clamp(-1.0, 1.0);
            worst = worst.max(c.acos().to_degrees());
        }
    }
    worst
}

/// The fit at the walk's 95 % upper bound (`mu` fixed) and that bound as
/// deg/s/sqrt(s) (negative at the grid's end: not bounded), when `jumps`.
fn at_walk_upper(d: &Design<'_>, axis: usize, g: &gls::AxisGls, lam: f64, mu: f64, jumps: bool) -> Option<(gls::AxisGls, f64)> {
    if !jumps {
        return None;
    }
    let up = gls::lam_upper(d, axis, lam, mu, g.reml(), MU_UPPER_CHI2).max(lam);
    // at the grid's end the data do not bound the walk at all: negative
    let sign = if up >= 0.999 * 10f64.powf(gls::LAM_LOG10.1) { -1.0 } else { 1.0 };
    fit_axis_mu(d, axis, up, mu).map(|w| (w, sign * (up * g.s2()).sqrt()))
}

/// One axis with one level for all runs: None when the runs' levels differ
/// (or one run); `Some(None)` when the fit at the spread's upper bound is singular.
fn shared_axis(ds: &Design<'_>, i: usize, lam0: f64, scale: f64, jumps: bool) -> Option<Option<AxisFit>> {
    let u_n = ds.runs.len();
    let (lam, mu) = reml_shared(ds, i, lam0);
    let g = fit_axis_mu(ds, i, lam, mu).filter(|g| u_n > 1 && reml_at(ds, i, lam, 0.0) - g.reml() <= SPREAD_TEST_CHI2)?;
    // the interval at the largest spread the runs allow, if wider
    let up = mu_upper(ds, i, lam, mu, g.reml(), MU_UPPER_CHI2);
    let Some(wide) = fit_axis_mu(ds, i, lam, up) else {
        return Some(None);
    };
    let walk_up = at_walk_upper(ds, i, &g, lam, mu, jumps);
    let walk_upper = walk_up.as_ref().map_or(f64::NAN, |w| w.1);
    let wides: Vec<gls::AxisGls> = std::iter::once(wide).chain(walk_up.map(|w| w.0)).collect();
    let s2 = g.s2();
    let order = ds.order;
    let cols: Vec<usize> = (1..=order).map(|k| ds.poly_col(k)).collect();
    let mut a = axis_fit(&g, &wides, &cols, scale);
    a.p2 = g.beta[0];
    let se0 = wides.iter().map(|w| w.se(0)).fold(g.se(0), f64::max);
    a.p2_ci = t975(g.n - g.p) * se0 * inflation(g.rho);
    a.levels = Levels::Shared { spread: (mu * s2).sqrt(), upper: (up * s2).sqrt() };
    a.walk = (lam * s2).sqrt();
    a.walk_upper = walk_upper;
    Some(Some(a))
}

/// One axis with each run its own constant (`own`, the per-run fit at `lam`);
/// `posed`: because the runs lie in different orientations.
fn per_run_axis(d: &Design<'_>, own: &gls::AxisGls, i: usize, lam: f64, scale: f64, jumps: bool, posed: bool) -> AxisFit {
    let u_n = d.runs.len();
    let cols: Vec<usize> = (1..=d.order).map(|k| d.poly_col(k)).collect();
    let walk_up = at_walk_upper(d, i, own, lam, 0.0, jumps);
    let walk_upper = walk_up.as_ref().map_or(f64::NAN, |w| w.1);
    let wides: Vec<gls::AxisGls> = walk_up.into_iter().map(|w| w.0).collect();
    let mut a = axis_fit(own, &wides, &cols, scale);
    let offs: Vec<f64> = (0..u_n).map(|q| own.beta[q]).collect();
    let mean = offs.iter().sum::<f64>() / u_n as f64;
    let sd = if u_n > 1 { (offs.iter().map(|o| (o - mean) * (o - mean)).sum::<f64>() / (u_n - 1) as f64).sqrt() } else { f64::NAN };
    a.p2 = mean;
    a.p2_ci = if u_n > 1 { t975(u_n - 1) * sd / (u_n as f64).sqrt() } else { f64::NAN };
    a.levels = Levels::PerRun { spread: sd, posed };
    a.walk = (lam * own.s2()).sqrt();
    a.walk_upper = walk_upper;
    a
}

/// Step 8: every run's bins with the mask of those used, its seconds and
/// temperatures used and its turn-on offsets (`own`, in the order of
/// `used`); the temperature range of all bins used.
fn assemble(
    prep: &[Prepared<'_>],
    reports: &mut [RunReport],
    cuts: &[f64],
    used: &[usize],
    own: &[gls::AxisGls],
) -> ((f64, f64), Vec<RunData>) {
    let mut range = (f64::INFINITY, f64::NEG_INFINITY);
    let mut data = Vec::with_capacity(prep.len());
    for (r, pr) in prep.iter().enumerate() {
        let rep = &mut reports[r];
        let mask: Vec<bool> = pr.bins.iter().zip(&pr.keep).map(|(b, k)| rep.used && *k && b.t >= cuts[r]).collect();
        let mut ur = (f64::INFINITY, f64::NEG_INFINITY);
        for (b, _) in pr.bins.iter().zip(&mask).filter(|(_, m)| **m) {
            ur = (ur.0.min(b.temp), ur.1.max(b.temp));
        }
        rep.used_s = mask.iter().filter(|m| **m).count() as f64 * BIN_S;
        if rep.used {
            rep.used_temp = ur;
            let q = used.iter().position(|&x| x == r).expect("used run");
            rep.offset = [0, 1, 2].map(|i| own[i].beta[q]);
            range = (range.0.min(ur.0), range.1.max(ur.1));
        } else {
            rep.used_temp = (f64::NAN, f64::NAN);
        }
        data.push((pr.bins.to_vec(), mask));
    }
    (range, data)
}

/// `sqrt((1 + rho) / (1 - rho))` for a positive lag-1 autocorrelation of
/// the whitened residuals (what the walk model leaves unexplained), else 1.
fn inflation(rho: f64) -> f64 {
    if rho > 0.0 {
        ((1.0 + rho) / (1.0 - rho).max(1e-3)).sqrt()
    } else {
        1.0
    }
}

/// The curve's coefficients (columns `cols` of `g`, scaled back by
/// `scale^k`) with 95 % intervals: Student t times the standard error,
/// the largest of `g`'s and the `wides`', times the autocorrelation inflation.
fn axis_fit(g: &gls::AxisGls, wides: &[gls::AxisGls], cols: &[usize], scale: f64) -> AxisFit {
    let infl = inflation(g.rho);
    let tq = t975(g.n - g.p);
    let mut a = AxisFit { rho: g.rho, white: g.s2().sqrt(), walk_upper: f64::NAN, ..AxisFit::default() };
    for (k, &c) in cols.iter().enumerate() {
        let sk = scale.powi(k as i32 + 1);
        let se = wides.iter().map(|w| w.se(c)).fold(g.se(c), f64::max);
        a.coeffs.push(g.beta[c] / sk);
        a.se.push(se * infl / sk);
        a.ci.push(tq * se * infl / sk);
    }
    a
}

fn no_run_left(reports: &[RunReport]) -> CalError {
    CalError::Fit(format!(
        "no run left to fit:\n{}",
        reports.iter().map(|r| format!("  {}: {}", r.name, r.left_out.as_deref().unwrap_or("?"))).collect::<Vec<_>>().join("\n")
    ))
}
