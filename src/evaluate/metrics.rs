//! Scoring one estimator run against the truth: the attitude and bias
//! errors ([`Metrics`]), the oracle floor, and the window (the manoeuvres)
//! that the manoeuvres-only scores and the oracle floor cover.

use super::RunData;
use crate::estimator::{flags, Estimate};
use crate::sim::model::GyroInput;
use crate::sim::motion::{c_nb, wrap180};
use crate::sim::vibration;
use serde::Serialize;

/// Scores of one estimator run.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Metrics {
    pub name: String,
    /// Max |error| of roll, pitch, yaw over the scored samples, deg.
    pub max_err: [f64; 3],
    /// RMS error of roll, pitch, yaw, deg.
    pub rms_err: [f64; 3],
    /// RMS and max |bias error| per axis, deg/s.
    pub bias_rms: [f64; 3],
    pub bias_max: [f64; 3],
    /// Seconds in fusion, blend, gyro only.
    pub mode_seconds: [f64; 3],
    pub samples: usize,
    /// Time of the largest roll or pitch error, s.
    pub t_max_tilt: f64,
    /// Seconds of the whole run during which the estimate declared a
    /// standstill while the truth moved faster than [`MOVING_MPS`]; none
    /// without a vehicle truth (or for a peer, which declares none).
    pub still_moving_s: Option<f64>,
}

/// The truth's |speed| above which a declared standstill is wrong, m/s.
pub const MOVING_MPS: f64 = 0.5;

/// Seconds (one sample period per sample) during which `est` declares a
/// standstill ([`flags::STANDSTILL`]) while |speed| > [`MOVING_MPS`].
pub fn still_moving_s(est: &[Estimate], speed: &[f64], period: f64) -> f64 {
    let n = est.iter().zip(speed).filter(|(e, v)| e.flags & flags::STANDSTILL != 0 && v.abs() > MOVING_MPS).count();
    n as f64 * period
}

impl Metrics {
    /// max(max roll error, max pitch error).
    pub fn tilt_max(&self) -> f64 {
        self.max_err[0].max(self.max_err[1])
    }
}

/// Errors of the estimate against the truth, per sample: (t, [roll, pitch, yaw]).
pub fn errors(data: &RunData, est: &[Estimate]) -> Vec<(f64, [f64; 3])> {
    est.iter().zip(&data.truth).map(|(e, t)| (t.t, [wrap180(e.roll - t.att[0]), e.pitch - t.att[1], wrap180(e.yaw - t.att[2])])).collect()
}

pub fn score(name: &str, data: &RunData, est: &[Estimate], mode_seconds: [f64; 3], from: f64) -> Metrics {
    let mut m = Metrics { name: name.into(), mode_seconds, ..Default::default() };
    let mut sq = [0.0; 3];
    let mut bsq = [0.0; 3];
    for ((e, t), b) in est.iter().zip(&data.truth).zip(&data.bias) {
        if t.t < from {
            continue;
        }
        let err = [wrap180(e.roll - t.att[0]), e.pitch - t.att[1], wrap180(e.yaw - t.att[2])];
        if err[0].abs().max(err[1].abs()) > m.tilt_max() {
            m.t_max_tilt = t.t;
        }
        for i in 0..3 {
            m.max_err[i] = m.max_err[i].max(err[i].abs());
            sq[i] += err[i] * err[i];
            let be = e.bias[i] - b[i];
            m.bias_max[i] = m.bias_max[i].max(be.abs());
            bsq[i] += be * be;
        }
        m.samples += 1;
    }
    let n = m.samples.max(1) as f64;
    for i in 0..3 {
        m.rms_err[i] = (sq[i] / n).sqrt();
        m.bias_rms[i] = (bsq[i] / n).sqrt();
    }
    m
}

/// The oracle floor: the measured gyro (decoded from the estimates:
/// `rate + bias`) corrected by the deterministic error model evaluated on the
/// truth, integrated from the true attitude at `start`. Returns its metrics
/// over `[start, end]` and its per-sample errors.
pub fn oracle(data: &RunData, est: &[Estimate], start: f64) -> (Metrics, Vec<(f64, [f64; 3])>) {
    let dt = 1.0 / data.info.rate_hz;
    let n = est.len().min(data.truth.len());
    let mut m = Metrics { name: "oracle floor".into(), ..Default::default() };
    // No sample at or after `start` (a run that ends before its manoeuvres): nothing to score.
    let k0 = match data.truth[..n].iter().position(|t| t.t >= start) {
        Some(k) => k,
        None => return (m, Vec::new()),
    };
    let tr = &data.truth;
    let att0 = tr[k0].att.map(f64::to_radians);
    let mut c = c_nb(att0[0], att0[1], att0[2]);
    let mut sq = [0.0; 3];
    let mut errs = Vec::with_capacity(n - k0);
    for k in k0 + 1..n {
        let t = &tr[k];
        let p = &tr[k - 1];
        let vib = vibration(&data.model.vibration, t.t);
        let x = GyroInput {
            rate: t.rate,
            rate_dot: [0, 1, 2].map(|i| (t.rate[i] - p.rate[i]) / dt),
            f: [t.f[0] + vib[0], t.f[1] + vib[1], t.f[2] + vib[2]],
            temp: t.temp,
            temp_rate: (t.temp - p.temp) / dt,
            t_on: t.t,
        };
        let det = data.model.gyro.measure(&x);
        let e = &est[k];
        let w: [f64; 3] = [0, 1, 2].map(|i| (e.rate[i] + e.bias[i] - (det[i] - t.rate[i])).to_radians() * dt);
        c = mat_mul(&c, &exp_so3(w));
        let a = euler(&c);
        let err = [wrap180(a[0] - t.att[0]), a[1] - t.att[1], wrap180(a[2] - t.att[2])];
        for i in 0..3 {
            m.max_err[i] = m.max_err[i].max(err[i].abs());
            sq[i] += err[i] * err[i];
        }
        m.samples += 1;
        errs.push((t.t, err));
    }
    let nn = m.samples.max(1) as f64;
    m.rms_err = sq.map(|s| (s / nn).sqrt());
    (m, errs)
}

fn mat_mul(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut c = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            c[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
        }
    }
    c
}

fn exp_so3(w: [f64; 3]) -> [[f64; 3]; 3] {
    let th2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
    let th = th2.sqrt();
    let (a, b) = if th < 1e-9 { (1.0 - th2 / 6.0, 0.5 - th2 / 24.0) } else { (th.sin() / th, (1.0 - th.cos()) / th2) };
    let k = [[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]];
    let k2 = mat_mul(&k, &k);
    let mut r = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            r[i][j] = if i == j { 1.0 } else { 0.0 } + a * k[i][j] + b * k2[i][j];
        }
    }
    r
}

fn euler(c: &[[f64; 3]; 3]) -> [f64; 3] {
    [c[2][1].atan2(c[2][2]).to_degrees(), (-c[2][0]).clamp(-1.0, 1.0).asin().to_degrees(), c[1][0].atan2(c[0][0]).to_degrees()]
}

/// The part of a run the manoeuvres-only scores and the oracle floor cover.
#[derive(Clone, Copy, Debug)]
pub struct Window {
    pub start: f64,
    /// Time of the last sample, s.
    pub end: f64,
}

impl Window {
    pub fn of(data: &RunData) -> Window {
        Window { start: data.info.manoeuvre_start_s, end: data.truth.last().map(|t| t.t).unwrap_or(0.0) }
    }

    /// No sample after the start: nothing to score, no oracle floor.
    pub fn is_empty(&self) -> bool {
        self.start >= self.end
    }

    /// The table title of the window.
    pub fn title(&self, scenario: &str) -> String {
        if self.start <= 0.0 {
            format!("oracle window, t = 0.0..{:.1} s (scenario {scenario} has no manoeuvres: the whole run)", self.end)
        } else {
            format!("manoeuvres only, t = {:.1}..{:.1} s (the oracle floor's window)", self.start, self.end)
        }
    }

    /// The warning printed instead of an empty window's table.
    pub fn warning(&self) -> String {
        format!(
            "warning: no manoeuvres to score: the run ends at {:.1} s, before the scenario's manoeuvres start \
             (paper and vehicle: 350 s); the manoeuvres-only scores and the oracle floor are left out (use a longer --duration)",
            self.end
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn still_moving_counts_standstill_while_the_truth_moves() {
        // 100 Hz: 1.5 s standstill at 2 m/s, 1 s standstill at 0.3 m/s,
        // 2 s moving at 2 m/s without a standstill.
        let mut est = Vec::new();
        let mut speed = Vec::new();
        for (n, v, still) in [(150, 2.0, true), (100, 0.3, true), (200, -2.0, false)] {
            for _ in 0..n {
                est.push(Estimate { flags: if still { flags::STANDSTILL } else { 0 }, ..Default::default() });
                speed.push(v);
            }
        }
        assert!((still_moving_s(&est, &speed, 0.01) - 1.5).abs() < 1e-9);
        // reversing counts too: |speed|
        speed[0] = -2.0;
        assert!((still_moving_s(&est, &speed, 0.01) - 1.5).abs() < 1e-9);
        assert_eq!(still_moving_s(&est, &vec![0.0; est.len()], 0.01), 0.0);
    }
}
