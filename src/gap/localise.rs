//! Step 3, **localise**: where the residual `measured - model` lives. Per
//! axis, its Pearson correlation with, and decile means against, each
//! variable a vocabulary effect depends on (time, temperature, dT/dt,
//! specific force, rate, rate derivative), on 0.1-s means; and the RMS of
//! 1-s means (seconds with under half the nominal samples are left out: a
//! partial second at either end would weigh as much as a full one with
//! several times its noise).

use super::fit::{Term, AX};
use super::read::Samples;
use crate::sim::model::Effect;
use serde::Serialize;

/// Width of the localisation bins, s.
pub const LOC_BIN_S: f64 = 0.1;

pub(crate) const V_T: usize = 0;
pub(crate) const V_TEMP: usize = 1;
pub(crate) const V_DTEMP: usize = 2;
pub(crate) const V_F: usize = 3;
pub(crate) const V_W: usize = 6;
pub(crate) const V_WD: usize = 9;
pub(crate) const NVAR: usize = 12;
const VAR_NAMES: [&str; NVAR] =
    ["time", "temperature", "dT/dt", "f_x", "f_y", "f_z", "rate_x", "rate_y", "rate_z", "rate_dot_x", "rate_dot_y", "rate_dot_z"];
const VAR_UNITS: [&str; NVAR] = ["s", "degC", "degC/s", "g", "g", "g", "deg/s", "deg/s", "deg/s", "deg/s^2", "deg/s^2", "deg/s^2"];

/// The variable a term's regressor depends on, on `axis` (what its localisation shows).
pub(crate) fn variable(t: &Term, axis: usize) -> usize {
    match t.effect {
        Effect::TurnOnBias | Effect::WarmupTransient => V_T,
        Effect::ThermalLinear | Effect::ThermalQuadratic => V_TEMP,
        Effect::ThermalRate => V_DTEMP,
        Effect::GSensitivity => V_F + t.col,
        Effect::ScaleFactor => V_W + t.axis,
        Effect::Misalignment => V_W + t.col,
        Effect::TimeDelay => V_WD + axis,
    }
}

/// Localisation of one axis' residual against one variable.
#[derive(Clone, Debug, Serialize)]
pub struct Localisation {
    pub variable: String,
    pub unit: String,
    /// Pearson correlation of the residual (0.1-s means) with the variable.
    pub correlation: f64,
    /// Decile bins of the variable: (centre, mean residual, count).
    pub bins: Vec<(f64, f64, usize)>,
    /// Range of the binned mean residual, deg/s.
    pub binned_range: f64,
}

/// The 0.1-s bins: which bin each sample falls in, the variables' means per bin, 1-s groups.
pub(crate) struct Bins {
    of_sample: Vec<u32>,
    count: Vec<f64>,
    /// bin means of the variables (bins with samples only are used)
    vars: Vec<[f64; NVAR]>,
    /// the second of each bin
    sec: Vec<usize>,
    nsec: usize,
    /// samples a second needs to count in the 1-s statistics
    full_sec: f64,
}

impl Bins {
    pub fn new(s: &Samples) -> Bins {
        let t0 = s.t[0];
        let nbin = ((s.duration() / LOC_BIN_S).floor() as usize) + 1;
        let mut of_sample = Vec::with_capacity(s.len());
        let mut count = vec![0.0; nbin];
        let mut vars = vec![[0.0; NVAR]; nbin];
        for k in 0..s.len() {
            let b = (((s.t[k] - t0) / LOC_BIN_S).floor().max(0.0) as usize).min(nbin - 1);
            of_sample.push(b as u32);
            count[b] += 1.0;
            let v = &mut vars[b];
            v[V_T] += s.t[k];
            v[V_TEMP] += s.temp[k];
            v[V_DTEMP] += s.dtemp[k];
            for a in 0..3 {
                v[V_F + a] += s.f[a][k];
                v[V_W + a] += s.w[a][k];
                v[V_WD + a] += s.wd[a][k];
            }
        }
        for (v, n) in vars.iter_mut().zip(&count) {
            if *n > 0.0 {
                v.iter_mut().for_each(|x| *x /= n);
            }
        }
        let per_sec = (1.0 / LOC_BIN_S).round() as usize;
        let sec: Vec<usize> = (0..nbin).map(|b| b / per_sec).collect();
        let nsec = sec.last().map_or(1, |s| s + 1);
        Bins { of_sample, count, vars, sec, nsec, full_sec: 0.5 * s.rate_hz }
    }

    /// Bin means of a per-sample series (NaN for empty bins).
    pub fn means(&self, x: &[f64]) -> Vec<f64> {
        let mut m = vec![0.0; self.count.len()];
        for (v, b) in x.iter().zip(&self.of_sample) {
            m[*b as usize] += v;
        }
        m.iter_mut().zip(&self.count).for_each(|(v, n)| *v = if *n > 0.0 { *v / n } else { f64::NAN });
        m
    }

    /// 1-s means of a per-sample series per axis: `(t, [r; 3])`, full seconds only.
    pub fn means_1s(&self, x: &[Vec<f64>; 3]) -> Vec<(f64, [f64; 3])> {
        let mut acc = vec![(0.0, [0.0; 3], 0.0); self.nsec];
        for a in 0..3 {
            let m = self.means(&x[a]);
            for (b, v) in m.iter().enumerate() {
                if self.count[b] > 0.0 {
                    let e = &mut acc[self.sec[b]];
                    e.1[a] += self.count[b] * v;
                    if a == 0 {
                        e.0 += self.count[b] * self.vars[b][V_T];
                        e.2 += self.count[b];
                    }
                }
            }
        }
        acc.into_iter().filter(|e| e.2 >= self.full_sec).map(|e| (e.0 / e.2, [e.1[0] / e.2, e.1[1] / e.2, e.1[2] / e.2])).collect()
    }

    /// RMS of the 1-s means per axis.
    pub fn rms_1s(&self, x: &[Vec<f64>; 3]) -> [f64; 3] {
        let m = self.means_1s(x);
        let mut s = [0.0; 3];
        for (_, v) in &m {
            for a in 0..3 {
                s[a] += v[a] * v[a];
            }
        }
        let n = m.len().max(1) as f64;
        s.map(|v| (v / n).sqrt())
    }

    /// A residual (per sample) against variable `v`.
    pub fn localise(&self, resid: &[f64], v: usize) -> Localisation {
        self.localise_means(&self.means(resid), v)
    }

    /// The same from the residual's bin means.
    fn localise_means(&self, m: &[f64], v: usize) -> Localisation {
        let pts: Vec<(f64, f64)> =
            m.iter().enumerate().filter(|(b, r)| self.count[*b] > 0.0 && r.is_finite()).map(|(b, r)| (self.vars[b][v], *r)).collect();
        let n = pts.len().max(1) as f64;
        let mx = pts.iter().map(|p| p.0).sum::<f64>() / n;
        let my = pts.iter().map(|p| p.1).sum::<f64>() / n;
        let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
        for p in &pts {
            sxx += (p.0 - mx).powi(2);
            syy += (p.1 - my).powi(2);
            sxy += (p.0 - mx) * (p.1 - my);
        }
        let corr = if sxx > 0.0 && syy > 0.0 { sxy / (sxx * syy).sqrt() } else { 0.0 };
        let mut sorted = pts;
        sorted.sort_by(|a, b| a.0.total_cmp(&b.0));
        let nb = 10.min(sorted.len());
        let mut bins = Vec::new();
        for k in 0..nb {
            let s = &sorted[k * sorted.len() / nb..(k + 1) * sorted.len() / nb];
            if s.is_empty() {
                continue;
            }
            let c = s.iter().map(|p| p.0).sum::<f64>() / s.len() as f64;
            let m = s.iter().map(|p| p.1).sum::<f64>() / s.len() as f64;
            bins.push((c, m, s.len()));
        }
        let lo = bins.iter().map(|b| b.1).fold(f64::INFINITY, f64::min);
        let hi = bins.iter().map(|b| b.1).fold(f64::NEG_INFINITY, f64::max);
        Localisation {
            variable: VAR_NAMES[v].into(),
            unit: VAR_UNITS[v].into(),
            correlation: corr,
            bins,
            binned_range: if hi >= lo { hi - lo } else { 0.0 },
        }
    }

    /// The strongest variables of one axis' residual, by |correlation|.
    pub fn strongest(&self, resid: &[f64], top: usize) -> Vec<Localisation> {
        let m = self.means(resid);
        let mut v: Vec<Localisation> = (0..NVAR).map(|k| self.localise_means(&m, k)).collect();
        v.sort_by(|a, b| b.correlation.abs().total_cmp(&a.correlation.abs()));
        v.truncate(top);
        v
    }
}

/// Per axis: RMS of 1-s means, its ratio to the white-noise level of 1-s means, the strongest variables.
#[derive(Clone, Debug, Serialize)]
pub struct AxisLocalisation {
    pub axis: String,
    pub rms_1s: f64,
    pub ratio_to_floor: f64,
    pub strongest: Vec<Strongest>,
}

#[derive(Clone, Debug, Serialize)]
pub struct Strongest {
    pub variable: String,
    pub correlation: f64,
    pub binned_range: f64,
}

impl From<&Localisation> for Strongest {
    fn from(l: &Localisation) -> Strongest {
        Strongest { variable: l.variable.clone(), correlation: l.correlation, binned_range: l.binned_range }
    }
}

/// The localisation of a residual on every axis.
pub(crate) fn localise_all(bins: &Bins, resid: &[Vec<f64>; 3], rms: &[f64; 3], floor: f64) -> Vec<AxisLocalisation> {
    (0..3)
        .map(|a| AxisLocalisation {
            axis: AX[a].into(),
            rms_1s: rms[a],
            ratio_to_floor: rms[a] / floor,
            strongest: bins.strongest(&resid[a], 3).iter().map(Strongest::from).collect(),
        })
        .collect()
}
