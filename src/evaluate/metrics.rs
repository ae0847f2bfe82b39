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

/// Score one run of an estimator from `from` (s) on: the attitude errors,
/// the bias errors against the true bias, and the seconds per mode it
/// reported.
pub fn score(name: &str, data: &RunData, est: &[Estimate], mode_seconds: [f64; 3], from: f64) -> Metrics {
    let att: Vec<[f64; 3]> = est.iter().map(|e| [e.roll, e.pitch, e.yaw]).collect();
    let mut m = score_attitude(name, data, &att, from);
    m.mode_seconds = mode_seconds;
    let mut bsq = [0.0; 3];
    for ((e, t), b) in est.iter().zip(&data.truth).zip(&data.bias) {
        if t.t < from {
            continue;
        }
        for i in 0..3 {
            let be = e.bias[i] - b[i];
            m.bias_max[i] = m.bias_max[i].max(be.abs());
            bsq[i] += be * be;
        }
    }
    let n = m.samples.max(1) as f64;
    m.bias_rms = bsq.map(|s| (s / n).sqrt());
    m
}

/// Score an attitude track (roll, pitch, yaw in deg per sample, in step
/// with the truth) from `from` (s) on: the attitude errors only; bias and
/// modes are not a number (a peer's bias is not scored, it has no modes).
pub fn score_attitude(name: &str, data: &RunData, att: &[[f64; 3]], from: f64) -> Metrics {
    let mut m =
        Metrics { name: name.into(), bias_rms: [f64::NAN; 3], bias_max: [f64::NAN; 3], mode_seconds: [f64::NAN; 3], ..Default::default() };
    let mut sq = [0.0; 3];
    for (a, t) in att.iter().zip(&data.truth) {
        if t.t < from {
            continue;
        }
        let err = [wrap180(a[0] - t.att[0]), a[1] - t.att[1], wrap180(a[2] - t.att[2])];
        if err[0].abs().max(err[1].abs()) > m.tilt_max() {
            m.t_max_tilt = t.t;
        }
        for i in 0..3 {
            m.max_err[i] = m.max_err[i].max(err[i].abs());
            sq[i] += err[i] * err[i];
        }
        m.samples += 1;
    }
    let n = m.samples.max(1) as f64;
    m.rms_err = sq.map(|s| (s / n).sqrt());
    m
}

/// Seconds of a run a peer's yaw offset is taken from when the run has no
/// rest phase at its start (as `evaluate --realdata`'s default `--align-s`).
pub const PEER_ALIGN_S: f64 = 5.0;
/// The truth is at rest while every axis of its rate is under this, deg/s,
/// and its speed (road scenarios) under this, m/s.
pub const REST_RATE_DPS: f64 = 1e-3;
pub const REST_SPEED_MPS: f64 = 1e-3;

/// The window a peer's yaw offset is taken from, s: as `evaluate
/// --realdata` takes it, the first rest phase (here the truth's: from the
/// first sample while it neither turns nor moves), else the first
/// [`PEER_ALIGN_S`] s; the offset is the mean yaw error over the last
/// [`crate::reference::score::YAW_OFFSET_WINDOW_S`] of it.
pub fn rest_window(data: &RunData) -> (f64, f64) {
    let tr = &data.truth;
    let t0 = tr.first().map_or(0.0, |t| t.t);
    let still = |k: usize| {
        tr[k].rate.iter().all(|w| w.abs() < REST_RATE_DPS)
            && data.speed.as_ref().is_none_or(|v| v.get(k).is_some_and(|v| v.abs() < REST_SPEED_MPS))
    };
    let n = (0..tr.len()).take_while(|&k| still(k)).count();
    // a rest phase of a second or more; else the first seconds
    let t1 = if n > 0 && tr[n - 1].t - t0 >= 1.0 { tr[n - 1].t } else { t0 + PEER_ALIGN_S };
    (t1 - crate::reference::score::YAW_OFFSET_WINDOW_S, t1)
}

/// A peer's yaw offset (its yaw minus the truth's, a circular mean over the
/// `window`, deg; 0 when no sample is in it).
pub fn yaw_offset(data: &RunData, att: &[[f64; 3]], window: (f64, f64)) -> f64 {
    let (mut s, mut c) = (0.0, 0.0);
    for (a, t) in att.iter().zip(&data.truth) {
        if t.t >= window.0 && t.t <= window.1 {
            let d = (a[2] - t.att[2]).to_radians();
            s += d.sin();
            c += d.cos();
        }
    }
    if s == 0.0 && c == 0.0 {
        0.0
    } else {
        s.atan2(c).to_degrees()
    }
}

/// A peer's attitude track with its yaw offset ([`yaw_offset`] over
/// [`rest_window`]) removed, and the offset (deg).
pub fn peer_track(data: &RunData, att: &[[f64; 3]]) -> (Vec<[f64; 3]>, f64) {
    let off = yaw_offset(data, att, rest_window(data));
    (att.iter().map(|a| [a[0], a[1], wrap180(a[2] - off)]).collect(), off)
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
    use crate::sim::SimOptions;

    fn run(scenario: &str, secs: f64, moving: bool) -> RunData {
        let mut o = SimOptions::new(scenario, 5);
        o.duration = Some(secs);
        o.power_on_moving = moving;
        RunData::simulate(&o).unwrap()
    }

    #[test]
    fn a_peers_yaw_offset_is_taken_at_the_end_of_the_first_rest_phase() {
        // static: the whole run is at rest; the offset over its last second
        let d = run("static", 20.0, false);
        let end = d.truth.last().unwrap().t;
        assert_eq!(rest_window(&d), (end - 1.0, end));
        // a parked start: the rest ends where the truth first turns or moves
        let d = run("smooth", 30.0, false);
        let (a, b) = rest_window(&d);
        let k = d.truth.iter().position(|t| t.t > b).unwrap();
        assert!(b > 1.0 && b < 25.0 && (b - a - 1.0).abs() < 1e-12, "({a}, {b})");
        let moving =
            |k: usize| d.truth[k].rate.iter().any(|w| w.abs() >= REST_RATE_DPS) || d.speed.as_ref().unwrap()[k].abs() >= REST_SPEED_MPS;
        assert!(moving(k) && !moving(k - 1));
        // started while driving: no rest phase, the first 5 s as realdata's default
        let d = run("smooth", 30.0, true);
        assert_eq!(rest_window(&d), (PEER_ALIGN_S - 1.0, PEER_ALIGN_S));
    }

    #[test]
    fn a_yaw_offset_is_a_circular_mean_and_is_removed() {
        let d = run("static", 12.0, false);
        // a yaw 179.5 then -179.5 deg off the truth: the mean is 180, not 0
        let att: Vec<[f64; 3]> =
            d.truth.iter().enumerate().map(|(k, t)| [t.att[0], t.att[1], t.att[2] + if k % 2 == 0 { 179.5 } else { -179.5 }]).collect();
        let off = yaw_offset(&d, &att, rest_window(&d));
        assert!((wrap180(off) - 180.0).abs() < 0.01 || (wrap180(off) + 180.0).abs() < 0.01, "{off}");
        let (track, _) = peer_track(&d, &att);
        let m = score_attitude("p", &d, &track, 0.0);
        assert!(m.max_err[2] < 0.51 && m.max_err[0] == 0.0 && m.max_err[1] == 0.0, "{:?}", m.max_err);
        // a peer's bias and modes are not scored
        assert!(m.bias_rms.iter().chain(&m.mode_seconds).all(|v| v.is_nan()) && m.still_moving_s.is_none());
        // no sample in the window: no offset
        assert_eq!(yaw_offset(&d, &att, (100.0, 101.0)), 0.0);
    }

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
