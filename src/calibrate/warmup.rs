//! Steps 4 and 6: the run's self-heating time constant, and the warm-up
//! transients found under it.

use super::gls::{fit_axis, reml_lambda, Design, Rows, TauSearch};
use super::{FAST_RATIO, MIN_HEAT_R2, MIN_RISE_C, TAU_GRID, TAU_MAX_S, TAU_MIN_S};

/// `T(t) = T_end - rise exp(-t / tau_s)` fitted to a run's temperature.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Heating {
    /// deg C from power-on to the end of the curve (negative when cooling).
    pub rise: f64,
    pub tau_s: f64,
    /// Fraction of the temperature variance the curve explains.
    pub r2: f64,
}

const HEAT_GRID: usize = 81;
/// The self-heating grid's end, s.
const HEAT_TAU_MAX_S: f64 = 1e5;

/// Least squares of `a + b exp(-t / tau)` with `tau` on a geometric grid
/// from 10 s to 100 000 s. None with fewer than 3 points, a constant
/// temperature, or no exponential approach seen (the best time constant
/// longer than the run, or at the grid's end): no self-heating found.
pub(crate) fn fit_heating(t: &[f64], temp: &[f64]) -> Option<Heating> {
    let n = t.len();
    if n < 3 {
        return None;
    }
    let tm = temp.iter().sum::<f64>() / n as f64;
    let sst: f64 = temp.iter().map(|v| (v - tm).powi(2)).sum();
    if sst.is_nan() || sst <= 0.0 {
        return None;
    }
    let mut best: Option<(f64, f64, f64)> = None; // (rss, tau, b)
    for k in 0..HEAT_GRID {
        let tau = 10f64.powf(1.0 + (HEAT_TAU_MAX_S.log10() - 1.0) * k as f64 / (HEAT_GRID - 1) as f64);
        let e: Vec<f64> = t.iter().map(|x| (-x / tau).exp()).collect();
        let em = e.iter().sum::<f64>() / n as f64;
        let see: f64 = e.iter().map(|v| (v - em).powi(2)).sum();
        if see.is_nan() || see <= 1e-12 * n as f64 {
            continue;
        }
        let set: f64 = e.iter().zip(temp).map(|(a, b)| (a - em) * (b - tm)).sum();
        let b = set / see;
        let rss = sst - b * set;
        if best.is_none_or(|(r, _, _)| rss < r) {
            best = Some((rss, tau, b));
        }
    }
    // a time constant longer than the run (or at the grid's end) is no
    // exponential approach seen: over less than one time constant the curve
    // is a straight line, and its "rise" an extrapolation (a slow drift, or
    // a flat temperature's quantisation steps, fit this way)
    let span = t[n - 1] - t[0];
    best.filter(|&(_, tau, _)| tau <= span && tau < 0.999 * HEAT_TAU_MAX_S).map(|(rss, tau, b)| Heating {
        rise: -b,
        tau_s: tau,
        r2: (1.0 - rss / sst).clamp(0.0, 1.0),
    })
}

/// The slowest warm-up transient this run can tell from its self-heating:
/// `tau_heat / FAST_RATIO` when the run self-heats (a rise of at least
/// `MIN_RISE_C` that the exponential describes), else `TAU_MAX_S`.
pub(crate) fn tau_limit(h: Option<&Heating>) -> f64 {
    match h {
        Some(h) if h.rise.abs() >= MIN_RISE_C && h.r2 >= MIN_HEAT_R2 => (h.tau_s / FAST_RATIO).clamp(TAU_MIN_S, TAU_MAX_S),
        _ => TAU_MAX_S,
    }
}

/// Candidate time constants up to `limit` (the limit itself is the last).
pub(crate) fn tau_grid(limit: f64) -> Vec<f64> {
    let (a, b) = (TAU_MIN_S.ln(), TAU_MAX_S.ln());
    let mut g: Vec<f64> =
        (0..TAU_GRID).map(|k| (a + (b - a) * k as f64 / (TAU_GRID - 1) as f64).exp()).filter(|&v| v < 0.999 * limit).collect();
    g.push(limit);
    g
}

/// What the joint fit says about each run's transient.
pub(crate) struct Transients {
    pub tau: Vec<f64>,
    pub at_limit: Vec<bool>,
    /// Amplitude at t = 0 per axis, deg/s.
    pub amp: Vec<[f64; 3]>,
    /// Largest |A| / SE(A) over the axes.
    pub z: Vec<f64>,
    /// The walk-to-white variance ratio per axis in the model with the transients.
    pub lams: [f64; 3],
}

const ROUNDS: usize = 2;
const SWEEPS: usize = 3;

/// The joint fit `c_run + curve(T) + A_run exp(-t / tau_run)` under the
/// random-walk residual model: each `tau_run` on its grid by coordinate
/// descent, the walk re-estimated after each round. None when singular.
pub(crate) fn find(rows: &[Rows], order: usize, limits: &[f64]) -> Option<Transients> {
    let r_n = rows.len();
    let grids: Vec<Vec<f64>> = limits.iter().map(|&l| tau_grid(l)).collect();
    let d0 = Design::new(rows, order);
    let mut lams = [0, 1, 2].map(|i| reml_lambda(&d0, i));
    let mut choice: Vec<usize> = grids.iter().map(|g| g.len() / 2).collect();
    let design = |choice: &[usize]| {
        let mut d = Design::new(rows, order);
        d.taus = choice.iter().zip(&grids).map(|(&k, g)| Some(g[k])).collect();
        d
    };
    for _ in 0..ROUNDS {
        let s = TauSearch::new(rows, order, lams, &grids);
        let mut best = s.objective(&choice);
        for _ in 0..SWEEPS {
            let mut changed = false;
            for r in 0..r_n {
                let keep = choice[r];
                let mut bk = keep;
                for k in 0..grids[r].len() {
                    choice[r] = k;
                    let j = s.objective(&choice);
                    if j < best {
                        best = j;
                        bk = k;
                    }
                }
                choice[r] = bk;
                changed |= bk != keep;
            }
            if !changed {
                break;
            }
        }
        let d = design(&choice);
        lams = [0, 1, 2].map(|i| reml_lambda(&d, i));
    }
    let d = design(&choice);
    let fits: Vec<_> = (0..3).map(|i| fit_axis(&d, i, lams[i])).collect::<Option<Vec<_>>>()?;
    let mut out = Transients { tau: vec![0.0; r_n], at_limit: vec![false; r_n], amp: vec![[0.0; 3]; r_n], z: vec![0.0; r_n], lams };
    for r in 0..r_n {
        let c = d.extra_cols(r).0?;
        out.tau[r] = grids[r][choice[r]];
        out.at_limit[r] = choice[r] + 1 == grids[r].len();
        for i in 0..3 {
            out.amp[r][i] = fits[i].beta[c];
            let se = fits[i].se(c);
            if se > 0.0 {
                out.z[r] = out.z[r].max(fits[i].beta[c].abs() / se);
            }
        }
    }
    Some(out)
}

/// How far run `r`'s own linear slope (an extra column on its rows) lies
/// from the shared curve's, in standard errors, largest over the axes.
/// None when the others cannot pin the shared slope (no other run with rows).
pub(crate) fn own_slope_z(rows: &[Rows], order: usize, r: usize, lams: [f64; 3]) -> Option<f64> {
    if !rows.iter().enumerate().any(|(q, x)| q != r && x.len() > 0) {
        return None;
    }
    let mut d = Design::new(rows, order);
    d.own_slope[r] = true;
    let c = d.extra_cols(r).1?;
    let mut z = 0.0f64;
    for i in 0..3 {
        let g = fit_axis(&d, i, lams[i])?;
        let se = g.se(c);
        if se > 0.0 {
            z = z.max(g.beta[c].abs() / se);
        }
    }
    Some(z)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn heating_time_constant_is_recovered_and_limits_the_transient() {
        let t: Vec<f64> = (0..600).map(|k| k as f64 + 0.5).collect();
        let temp: Vec<f64> = t.iter().map(|x| 20.0 + 10.0 * (1.0 - (-x / 180.0).exp())).collect();
        let h = fit_heating(&t, &temp).unwrap();
        assert!((h.tau_s / 180.0 - 1.0).abs() < 0.07, "{h:?}");
        assert!((h.rise - 10.0).abs() < 0.3 && h.r2 > 0.999, "{h:?}");
        let lim = tau_limit(Some(&h));
        assert!((lim - h.tau_s / FAST_RATIO).abs() < 1e-9);
        let g = tau_grid(lim);
        assert_eq!(*g.last().unwrap(), lim);
        assert!(g.windows(2).all(|w| w[0] < w[1]) && (g[0] - TAU_MIN_S).abs() < 1e-9, "{g:?}");
        // no self-heating: the general limit
        let flat = vec![25.0; 600];
        assert_eq!(tau_limit(fit_heating(&t, &flat).as_ref()), TAU_MAX_S);
    }

    /// A flat temperature with quantisation steps and a slight drift (an
    /// MPU6050 at room temperature) is no self-heating: once printed as
    /// "-79.1 deg C, tau 100000 s" (the fit at its grid's end), and a drift
    /// as a rise of 12.8 deg C with tau 15849 s over 130 s.
    #[test]
    fn a_flat_drifting_temperature_is_no_self_heating() {
        let t: Vec<f64> = (0..130).map(|k| k as f64 + 0.5).collect();
        let temp: Vec<f64> = t.iter().map(|x| 25.2 + ((0.0008 * x) * 340.0).round() / 340.0).collect();
        assert!(fit_heating(&t, &temp).is_none(), "{:?}", fit_heating(&t, &temp));
    }
}
