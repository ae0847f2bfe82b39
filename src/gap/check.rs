//! Before naming anything: do the measured data and the truth belong
//! together, and can the vocabulary explain them at all? A gap analysis of
//! one run against the truth of another would otherwise "find" scale factors
//! of -96 % or call a residual 93x the noise floor clean. Three checks, each
//! refusing with a message that says what disagreed and by how much:
//!
//! 1. **Temperature** (when both files have one): the truth's temperature is
//!    what the thermal terms are fitted against; it must agree with the
//!    sensor's own reading within [`TEMP_TOL_C`] RMS.
//! 2. **Rates**: on every axis where the truth moves (fast content of
//!    0.1-s means, 10-s running mean removed, at least [`EXCITED_SNR`] times
//!    the noise of a 0.1-s mean), the measured rate must follow the true one:
//!    correlation at least [`RATE_CORR_MIN`] and regression slope within
//!    [`RATE_SLOPE`] (a gyro error of the vocabulary changes the rate by
//!    percent, not by its sign or size). The measured rate is regressed on
//!    the true rate and its derivative, so that a time delay (in the
//!    vocabulary: `ω(t - τ) ≈ ω - τ ω'`) is allowed for: a car's body
//!    shakes at 3-50 Hz on its road, and a 20-ms delay alone took the
//!    plain correlation of a simulated drive's 0.1-s means to 0.898.
//! 3. **Explainable**: the base model with every vocabulary term added
//!    (including corrections to the fixed coefficients), fitted with the
//!    noise model, must leave a whitened residual variance of at most
//!    [`FULL_S2_MAX`] times the noise model's (residual RMS twice the noise):
//!    otherwise the data has errors the vocabulary cannot describe, the files
//!    are not the same run, or the base model's `[noise]` is far from the
//!    data's. (Within that, the same fit scales the noise model's white level
//!    to the data's, see [`NoiseModel::scaled_to_data`].)

use super::fit::{all_terms, Design, Fit, NoiseModel, Term, AX};
use super::localise::Bins;
use super::read::Samples;
use crate::sim::model::Effect;
use serde::Serialize;

/// Largest RMS difference of measured and truth temperature, deg C.
pub const TEMP_TOL_C: f64 = 1.0;
/// Smallest correlation of measured and true rate (fast content) on an axis that moves.
pub const RATE_CORR_MIN: f64 = 0.9;
/// Range of the slope of measured on true rate (fast content).
pub const RATE_SLOPE: [f64; 2] = [0.5, 1.5];
/// An axis moves when its fast content's standard deviation is this many times the noise of a 0.1-s mean.
pub const EXCITED_SNR: f64 = 10.0;
/// Largest whitened residual variance (in units of the noise model's) with every vocabulary term fitted.
pub const FULL_S2_MAX: f64 = 4.0;
/// Half width of the running mean removed before comparing rates, in 0.1-s bins (10 s in all).
const HP_HALF: usize = 50;

#[derive(Clone, Debug, Serialize)]
pub struct RateCheck {
    pub axis: String,
    /// Standard deviation of the true rate's fast content, deg/s.
    pub truth_std: f64,
    /// Whether the axis moves enough to be compared.
    pub compared: bool,
    /// Multiple correlation of the measured rate with the true rate and its
    /// derivative (a time delay allowed for), signed as the slope.
    pub correlation: f64,
    pub slope: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct Checks {
    /// RMS of measured minus truth temperature, deg C (None when one of them has none).
    pub temperature_rms_diff: Option<f64>,
    pub rates: Vec<RateCheck>,
    /// Terms of the full-vocabulary fit and its whitened residual variance (1 = the noise model's).
    pub full_vocabulary_terms: usize,
    pub full_vocabulary_variance_ratio: f64,
}

/// Check 1.
pub(crate) fn temperature(s: &Samples) -> Result<Option<f64>, String> {
    if !s.truth_temp {
        return Ok(None);
    }
    let (mut ss, mut n, mut max) = (0.0, 0.0, 0.0f64);
    for (m, t) in s.meas_temp.iter().zip(&s.temp) {
        if m.is_finite() {
            let d = m - t;
            ss += d * d;
            n += 1.0;
            max = max.max(d.abs());
        }
    }
    if n == 0.0 {
        return Ok(None);
    }
    let rms = (ss / n).sqrt();
    if rms > TEMP_TOL_C {
        return Err(format!(
            "measured and truth do not agree: the measured temperature differs from the truth's by {rms:.2} degC RMS \
             (at most {max:.2} degC; allowed {TEMP_TOL_C} degC RMS). They are not the same run, or the truth's temperature \
             is another sensor's (leave its temp column out to fit against the measured one). Refusing to name effects."
        ));
    }
    Ok(Some(rms))
}

/// Bin means minus their centred running mean over +-HP_HALF bins (empty bins NaN and skipped).
fn high_pass(m: &[f64]) -> Vec<f64> {
    let n = m.len();
    let mut cs = vec![0.0; n + 1];
    let mut cn = vec![0.0; n + 1];
    for k in 0..n {
        let ok = m[k].is_finite();
        cs[k + 1] = cs[k] + if ok { m[k] } else { 0.0 };
        cn[k + 1] = cn[k] + if ok { 1.0 } else { 0.0 };
    }
    (0..n)
        .map(|k| {
            let lo = k.saturating_sub(HP_HALF);
            let hi = (k + HP_HALF + 1).min(n);
            let c = cn[hi] - cn[lo];
            if m[k].is_finite() && c > 0.0 {
                m[k] - (cs[hi] - cs[lo]) / c
            } else {
                f64::NAN
            }
        })
        .collect()
}

/// Central difference at `k` per bin from the nearest finite bins within 5 on each side (NaN if none).
fn central(m: &[f64], k: usize) -> f64 {
    let j = (1..=5).filter_map(|d| k.checked_sub(d)).find(|&j| m[j].is_finite());
    let l = (1..=5).map(|d| k + d).find(|&l| l < m.len() && m[l].is_finite());
    match (j, l) {
        (Some(j), Some(l)) => (m[l] - m[j]) / (l - j) as f64,
        _ => f64::NAN,
    }
}

/// Check 2.
pub(crate) fn rates(s: &Samples, bins: &Bins, noise: &NoiseModel) -> Result<Vec<RateCheck>, String> {
    let per_bin = s.rate_hz * super::localise::LOC_BIN_S;
    let bin_noise = noise.sigma / per_bin.max(1.0).sqrt();
    let mut out = Vec::new();
    for a in 0..3 {
        let tm = high_pass(&bins.means(&s.w[a]));
        let mm = high_pass(&bins.means(&s.meas[a]));
        // the true rate's derivative (central difference of the bin means,
        // the nearest filled bins within 5 on each side: a truth at a few Hz
        // leaves bins empty; its unit does not matter to the regression)
        let dm: Vec<f64> = (0..tm.len()).map(|k| central(&tm, k)).collect();
        let pts: Vec<[f64; 3]> =
            (0..tm.len()).filter(|&k| tm[k].is_finite() && mm[k].is_finite() && dm[k].is_finite()).map(|k| [tm[k], dm[k], mm[k]]).collect();
        let n = pts.len().max(1) as f64;
        let mean = |i: usize| pts.iter().map(|p| p[i]).sum::<f64>() / n;
        let (mx, md, my) = (mean(0), mean(1), mean(2));
        let (mut sxx, mut sdd, mut sxd, mut syy, mut sxy, mut sdy) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        for p in &pts {
            let (x, d, y) = (p[0] - mx, p[1] - md, p[2] - my);
            sxx += x * x;
            sdd += d * d;
            sxd += x * d;
            syy += y * y;
            sxy += x * y;
            sdy += d * y;
        }
        let truth_std = (sxx / n).sqrt();
        let compared = truth_std >= EXCITED_SNR * bin_noise;
        // measured = slope true + c true' (a delay): the multiple correlation
        let det = sxx * sdd - sxd * sxd;
        let (slope, c) = if det > 1e-12 * sxx * sdd {
            ((sxy * sdd - sdy * sxd) / det, (sdy * sxx - sxy * sxd) / det)
        } else if sxx > 0.0 {
            (sxy / sxx, 0.0)
        } else {
            (0.0, 0.0)
        };
        let explained = slope * sxy + c * sdy;
        let correlation = if syy > 0.0 && explained > 0.0 { (explained / syy).sqrt().copysign(slope) } else { 0.0 };
        if compared && (correlation < RATE_CORR_MIN || !(RATE_SLOPE[0]..=RATE_SLOPE[1]).contains(&slope)) {
            return Err(format!(
                "measured and truth do not agree: on axis {} the measured rate follows the true rate (a time delay allowed for) with correlation {correlation:.3} \
                 and slope {slope:.3} where the truth moves ({truth_std:.3} deg/s RMS of fast motion, 0.1-s means less their 10-s \
                 running mean); a gyro error of the vocabulary keeps the correlation above {RATE_CORR_MIN} and the slope within \
                 {}..{}. They are not the same run, not aligned in time, or their axes differ. Refusing to name effects.",
                AX[a], RATE_SLOPE[0], RATE_SLOPE[1]
            ));
        }
        out.push(RateCheck { axis: AX[a].into(), truth_std, compared, correlation, slope });
    }
    Ok(out)
}

/// `first`, then every vocabulary term not in `exclude` that is not
/// collinear with the ones before it (warm-up columns at `tau`, 60 s when
/// not known).
pub(crate) fn vocabulary_basis(design: &mut Design, first: &[Term], exclude: &[Term], tau: f64) -> Vec<Term> {
    let mut terms: Vec<Term> = first.to_vec();
    let tau0 = if tau.is_finite() { tau } else { 60.0 };
    for e in Effect::ALL {
        for t in all_terms(e) {
            if terms.contains(&t) || exclude.contains(&t) {
                continue;
            }
            terms.push(t);
            let keep = design.fit(&terms, tau0).is_some_and(|f| f.r2(terms.len() - 1) < 0.9999);
            if !keep {
                terms.pop();
            }
        }
    }
    terms
}

/// Check 3: the fit with every vocabulary term that is not collinear with
/// the ones before it (the base's free terms first; a warm-up's time
/// constant searched unless the base model gives it).
pub(crate) fn full_vocabulary(design: &mut Design, free: &[Term], base_tau: f64) -> Fit {
    let terms = vocabulary_basis(design, free, &[], base_tau);
    design
        .fit_any(&terms, base_tau, false)
        .or_else(|| design.fit(&terms, if base_tau.is_finite() { base_tau } else { 60.0 }))
        .expect("the full-vocabulary terms were each checked to be fittable")
}

/// The message of a failed check 3.
pub(crate) fn full_vocabulary_refusal(s2: f64, rms: &[f64; 3], floor: f64) -> String {
    format!(
        "measured and truth do not agree: even with every effect of the vocabulary fitted, the whitened residual variance is \
         {s2:.1}x the noise model's (at most {FULL_S2_MAX}x allowed; residual RMS of 1-s means [{:.4}, {:.4}, {:.4}] deg/s, \
         {:.0}x the white-noise level {floor:.5} deg/s). The files are not the same run, the data has errors the \
         vocabulary cannot describe, or the base model's [noise] is far from the data's. Refusing to name effects.",
        rms[0],
        rms[1],
        rms[2],
        rms.iter().copied().fold(0.0, f64::max) / floor
    )
}
