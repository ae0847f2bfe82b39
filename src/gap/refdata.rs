//! A truth from a measured reference (`gap --reference`) or from a unit
//! known to lie still (`gap --static`), for real recordings.
//!
//! The simulated `--truth` gives the true rate and specific force; a real
//! recording has only a reference attitude (`t,roll,pitch,yaw[,valid][,rest]`,
//! [`crate::reference::refcsv`], on the measured file's clock). From it:
//!
//! - **body rates** from the orientation's derivative: the rotation vector of
//!   `q(k-1)^-1 q(k+1)` over `t(k+1) - t(k-1)` (body frame), then low-passed
//!   with a zero-phase windowed-sinc filter of the stated bandwidth `B`
//!   (`--bandwidth`, -6 dB at `B`) and taken every `D = round(rate / 2B)`-th
//!   sample, so that what is left of the noise is about white at the new rate.
//!   The **measured gyro goes through the same filter**: the two are compared
//!   in the same band, and every vocabulary effect (linear in rate, its
//!   derivative, specific force) commutes with it. The rate derivative is the
//!   central difference of the filtered rate at the full rate;
//! - **the mount**: the constant rotation from the reference's body to the
//!   sensor's, the shortest rotation taking the gravity the reference
//!   predicts onto the accelerometer's mean over the first rest phase (`rest
//!   = 1`, at least 1 s valid). Only its tilt is observable at rest: a yaw of
//!   the mount stays in the data as a misalignment `m[x][y] = -m[y][x]`, and
//!   an accelerometer bias of 1 mg tilts it by 0.06 deg. Reported;
//! - **the reference's noise**: the filtered reference rate's RMS over the
//!   rest phases (the true rate there is zero), as a white density at the new
//!   rate, added in quadrature to the base model's `gyro_white`, so that what
//!   the reference adds to the residual is noise, not evidence;
//! - **specific force** from the measured accelerometer through the same
//!   filter (the reference has attitude only, no positions: said in the
//!   report);
//! - **only where the reference is valid**: an output sample needs every
//!   sample of its filter window valid (reference rows valid and no farther
//!   apart than the reference's own spacing allows, the accelerometer present,
//!   the sample spacing regular). Time jumps split stretches.
//!
//! `--static`: the unit lies still; the true rate is zero, the specific
//! force the accelerometer's mean, no reference noise, and every stretch
//! between time jumps (bursts of one power cycle, e.g. the FIRM files) is
//! used, times kept as they are (time since power-on).

use super::read::{MeasRow, TruthIn};
use crate::reference::refcsv::Reference;
use nalgebra::{UnitQuaternion, Vector3};
use serde::Serialize;

/// Default bandwidth of the derived truth, Hz.
pub const DEFAULT_BANDWIDTH_HZ: f64 = 2.0;
/// Range of `--bandwidth`, Hz.
pub const BANDWIDTH_RANGE_HZ: [f64; 2] = [0.1, 100.0];
/// Shortest rest phase the mount is taken from, s.
pub const MOUNT_REST_MIN_S: f64 = 1.0;

/// The mount between the reference and the sensor.
#[derive(Clone, Debug, Serialize)]
pub struct Mount {
    /// Rotation from the reference's body to the sensor's, Z-Y-X Euler angles, deg (yaw 0: not observable at rest).
    pub roll_deg: f64,
    pub pitch_deg: f64,
    pub angle_deg: f64,
    /// The rest phase it was taken from, s.
    pub rest_from_s: f64,
    pub rest_to_s: f64,
    /// Mean accelerometer there (sensor axes), g.
    pub accel_mean_g: [f64; 3],
    pub note: String,
}

/// How the truth was derived (in report.json as `truth_from`).
#[derive(Clone, Debug, Serialize)]
pub struct Derivation {
    /// `reference` or `static`.
    pub source: String,
    pub bandwidth_hz: f64,
    pub input_rate_hz: f64,
    pub decimation: usize,
    pub rate_hz: f64,
    /// Filter taps on each side of a sample.
    pub half_width: usize,
    pub mount: Option<Mount>,
    pub specific_force: String,
    pub temperature: String,
    /// The reference's noise per axis, deg/s per sample: at rest (the
    /// filtered reference rate's RMS, the true rate being zero) and moving
    /// (the RMS of measured minus reference after a bias, a scale and a
    /// delay per axis; what else the gyro gets wrong is in it too, so it is
    /// an upper bound). The moving one, as a white density at the output
    /// rate (deg/s/sqrt(Hz)), is added to the noise model, and the data's own
    /// white level is never taken below it.
    pub reference_rest_rms: [f64; 3],
    pub reference_moving_rms: [f64; 3],
    pub reference_white_density: f64,
    /// Input samples, output samples, and the valid stretches (s).
    pub input_samples: usize,
    pub samples: usize,
    pub stretches: Vec<[f64; 2]>,
}

/// Measured and truth on one grid, ready for [`super::analyse_with`].
pub struct Derived {
    pub meas: Vec<MeasRow>,
    pub truth: Vec<TruthIn>,
    pub truth_has_temp: bool,
    pub info: Derivation,
}

impl Derivation {
    /// The reference's own noise at rest as a white density at the output
    /// rate, deg/s/sqrt(Hz): what the pairing check (rates) is judged with,
    /// since the moving level is estimated from measured minus reference and
    /// would hide a mismatched pair.
    pub fn rest_density(&self) -> f64 {
        if self.rate_hz.is_finite() && self.rate_hz > 0.0 {
            (self.reference_rest_rms.iter().map(|x| x * x).sum::<f64>() / 3.0).sqrt() / (self.rate_hz / 2.0).sqrt()
        } else {
            0.0
        }
    }

    /// A simulated truth (nothing derived).
    pub fn simulated() -> Derivation {
        Derivation {
            source: "simulated".into(),
            bandwidth_hz: f64::NAN,
            input_rate_hz: f64::NAN,
            decimation: 1,
            rate_hz: f64::NAN,
            half_width: 0,
            mount: None,
            specific_force: "the truth's".into(),
            temperature: String::new(),
            reference_rest_rms: [0.0; 3],
            reference_moving_rms: [0.0; 3],
            reference_white_density: 0.0,
            input_samples: 0,
            samples: 0,
            stretches: vec![],
        }
    }
}

/// report.md's paragraph on how the truth was derived.
pub fn render_md(d: &Derivation) -> String {
    let mut s = if d.source == "static" {
        format!(
            "Truth of a unit lying still: {} samples at {:.1} Hz (median), in {} stretch(es) between time jumps > {STATIC_JUMP_S} s \
             (one power cycle), zero rotation. Specific force: {}. Temperature: {}.\n\n",
            d.samples,
            d.input_rate_hz,
            d.stretches.len(),
            d.specific_force,
            d.temperature
        )
    } else {
        format!(
            "Truth derived from a measured reference ({} input samples at {:.1} Hz): rates low-passed at {} Hz (zero-phase, {} taps \
             each side; the measured gyro alike), every {}th sample kept ({:.2} Hz), {} samples in {} stretch(es) where it is valid. \
             Specific force: {}. Temperature: {}.\n\n",
            d.input_samples,
            d.input_rate_hz,
            d.bandwidth_hz,
            d.half_width,
            d.decimation,
            d.rate_hz,
            d.samples,
            d.stretches.len(),
            d.specific_force,
            d.temperature
        )
    };
    if let Some(m) = &d.mount {
        s += &format!(
            "Mount (reference body to sensor) from the rest phase {:.1}..{:.1} s: roll {:.3} deg, pitch {:.3} deg ({:.3} deg in all); {}.\n\n",
            m.rest_from_s, m.rest_to_s, m.roll_deg, m.pitch_deg, m.angle_deg, m.note
        );
    }
    if d.source == "reference" {
        s += &format!(
            "Reference noise per sample: at rest [{:.4}, {:.4}, {:.4}] deg/s, moving [{:.4}, {:.4}, {:.4}] deg/s (measured minus reference \
             after a bias, a scale and a delay per axis: an upper bound); {:.4} deg/s/sqrt(Hz) is added to the noise model and the \
             data's white level is not taken below it.\n\n",
            d.reference_rest_rms[0], d.reference_rest_rms[1], d.reference_rest_rms[2],
            d.reference_moving_rms[0], d.reference_moving_rms[1], d.reference_moving_rms[2], d.reference_white_density
        );
    }
    s
}

/// Check `--bandwidth`.
pub fn check_bandwidth(b: f64) -> Result<f64, String> {
    if !(BANDWIDTH_RANGE_HZ[0]..=BANDWIDTH_RANGE_HZ[1]).contains(&b) {
        return Err(format!("--bandwidth {b}: outside {}..{} Hz", BANDWIDTH_RANGE_HZ[0], BANDWIDTH_RANGE_HZ[1]));
    }
    Ok(b)
}

/// The median sample step of `meas`, s.
fn median_step(meas: &[MeasRow]) -> f64 {
    let mut d: Vec<f64> = meas.windows(2).map(|w| w[1].t - w[0].t).collect();
    d.sort_by(|a, b| a.total_cmp(b));
    d.get(d.len() / 2).copied().unwrap_or(f64::NAN)
}

/// The zero-phase low-pass: a Hann-windowed sinc, -6 dB at `b` Hz, unit DC gain.
fn kernel(rate: f64, b: f64) -> Vec<f64> {
    let h = (2.0 * rate / b).ceil() as usize;
    let fc = b / rate;
    let mut k: Vec<f64> = (0..=2 * h)
        .map(|i| {
            let n = i as f64 - h as f64;
            let sinc = if n == 0.0 { 2.0 * fc } else { (2.0 * std::f64::consts::PI * fc * n).sin() / (std::f64::consts::PI * n) };
            let w = 0.5 + 0.5 * (std::f64::consts::PI * n / (h as f64 + 1.0)).cos();
            sinc * w
        })
        .collect();
    let s: f64 = k.iter().sum();
    k.iter_mut().for_each(|x| *x /= s);
    k
}

/// Full-rate body rates of the reference (deg/s, reference body axes) at the
/// measured times; None where the reference is not valid on both sides.
fn reference_rates(meas: &[MeasRow], q: &[Option<UnitQuaternion<f64>>]) -> Vec<Option<Vector3<f64>>> {
    (0..meas.len())
        .map(|k| {
            if k == 0 || k + 1 >= meas.len() {
                return None;
            }
            let (a, b) = (q[k - 1]?, q[k + 1]?);
            let d = a.inverse() * b;
            Some(d.scaled_axis() * (180.0 / std::f64::consts::PI) / (meas[k + 1].t - meas[k - 1].t))
        })
        .collect()
}

/// The rest flag at each measured time (the nearest reference row at or before it).
fn rest_at(meas: &[MeasRow], r: &Reference) -> Vec<bool> {
    meas.iter()
        .map(|m| {
            let i = r.rows.partition_point(|x| x.t <= m.t + 1e-6);
            i > 0 && r.rows[i - 1].rest
        })
        .collect()
}

/// The mount from the first rest phase with at least [`MOUNT_REST_MIN_S`] of valid samples.
fn mount(meas: &[MeasRow], q: &[Option<UnitQuaternion<f64>>], rest: &[bool]) -> Result<(UnitQuaternion<f64>, Mount), String> {
    let mut k = 0;
    while k < meas.len() {
        if !rest[k] {
            k += 1;
            continue;
        }
        let start = k;
        let (mut fa, mut fr, mut n) = (Vector3::zeros(), Vector3::zeros(), 0usize);
        while k < meas.len() && rest[k] {
            if let Some(qk) = q[k] {
                let a = Vector3::from(meas[k].acc);
                if a.iter().all(|x| x.is_finite()) {
                    fa += a;
                    fr += qk.inverse_transform_vector(&Vector3::new(0.0, 0.0, -1.0));
                    n += 1;
                }
            }
            k += 1;
        }
        let (t0, t1) = (meas[start].t, meas[k - 1].t);
        if n < 2 || t1 - t0 < MOUNT_REST_MIN_S {
            continue;
        }
        let (fa, fr) = (fa / n as f64, fr / n as f64);
        let m = UnitQuaternion::rotation_between(&fr, &fa).ok_or("the mount: the rest phase's gravity is opposite the reference's")?;
        let (r, p, _) = m.euler_angles();
        let info = Mount {
            roll_deg: r.to_degrees(),
            pitch_deg: p.to_degrees(),
            angle_deg: m.angle().to_degrees(),
            rest_from_s: t0,
            rest_to_s: t1,
            accel_mean_g: [fa.x, fa.y, fa.z],
            note: "tilt only (a yaw of the mount is not observable at rest and stays as a misalignment m[x][y] = -m[y][x]); \
                   an accelerometer bias of 1 mg tilts it by 0.06 deg"
                .into(),
        };
        return Ok((m, info));
    }
    Err("the reference has no rest phase (rest = 1) of at least 1 s with valid rows and accelerometer: the mount between reference and sensor cannot be estimated".into())
}

/// The input to the filter: per full-rate sample, the true rate (sensor
/// axes) and a validity flag; the sample spacing must be regular in a window.
struct Input<'a> {
    meas: &'a [MeasRow],
    w: Vec<[f64; 3]>,
    ok: Vec<bool>,
}

/// Filter `x` at `j` with the kernel `k` (window inside the slice).
fn at(k: &[f64], j: usize, x: impl Fn(usize) -> f64) -> f64 {
    let h = k.len() / 2;
    k.iter().enumerate().map(|(i, c)| c * x(j + i - h)).sum()
}

/// Low-pass and decimate: one output row per `d`-th sample whose window is valid.
fn filter(inp: &Input, rate: f64, b: f64, f_static: Option<[f64; 3]>) -> (Vec<MeasRow>, Vec<TruthIn>, usize, usize) {
    let k = kernel(rate, b);
    let h = k.len() / 2;
    let d = ((rate / (2.0 * b)).round() as usize).max(1);
    let n = inp.meas.len();
    // run[i]: the number of consecutive valid samples ending at i
    let mut run = vec![0usize; n];
    for i in 0..n {
        run[i] = if inp.ok[i] { 1 + if i > 0 { run[i - 1] } else { 0 } } else { 0 };
    }
    let (mut meas, mut truth) = (Vec::new(), Vec::new());
    let mut j = h + 1;
    while j + h + 1 < n {
        if run[j + h + 1] < 2 * h + 3 {
            j += 1;
            continue;
        }
        let m = &inp.meas;
        let g = [0, 1, 2].map(|a| at(&k, j, |i| m[i].gyro[a]));
        let acc = [0, 1, 2].map(|a| at(&k, j, |i| m[i].acc[a]));
        let w = [0, 1, 2].map(|a| at(&k, j, |i| inp.w[i][a]));
        let wd = [0, 1, 2].map(|a| (at(&k, j + 1, |i| inp.w[i][a]) - at(&k, j - 1, |i| inp.w[i][a])) / (m[j + 1].t - m[j - 1].t));
        let temp = at(&k, j, |i| m[i].temp);
        meas.push(MeasRow { t: m[j].t, gyro: g, acc, temp });
        truth.push(TruthIn { t: m[j].t, rate: w, f: f_static.unwrap_or(acc), temp: f64::NAN, wd: Some(wd) });
        j += d;
    }
    (meas, truth, d, h)
}

/// Validity from the spacing: a sample is usable when its step from the
/// previous one is regular (within 1.5 median steps): time jumps and lost
/// samples split stretches.
fn regular(meas: &[MeasRow], step: f64) -> Vec<bool> {
    (0..meas.len()).map(|i| i > 0 && meas[i].t - meas[i - 1].t <= 1.5 * step && meas[i].t - meas[i - 1].t > 0.5 * step).collect()
}

/// The stretches of the output (split where consecutive rows are more than 1.5 output steps apart), s.
fn stretches(truth: &[TruthIn], d: usize, step: f64) -> Vec<[f64; 2]> {
    let mut v: Vec<[f64; 2]> = Vec::new();
    for (i, r) in truth.iter().enumerate() {
        if i == 0 || r.t - truth[i - 1].t > 1.5 * d as f64 * step {
            v.push([r.t, r.t]);
        }
        if let Some(l) = v.last_mut() {
            l[1] = r.t;
        }
    }
    v
}

/// The temperature note and whether the measured data has one.
fn temperature_of(meas: &[MeasRow]) -> (bool, String) {
    if meas.iter().all(|m| m.temp.is_finite()) {
        (true, "measured (the sensor's own reading, filtered alike)".into())
    } else {
        (false, "none: a constant 25 degC is used, so no thermal effect can be named".into())
    }
}

/// Finish: temperature, the output's checks.
fn finish(mut meas: Vec<MeasRow>, mut truth: Vec<TruthIn>, info: Derivation, has_temp: bool) -> Result<Derived, String> {
    if truth.len() < 100 {
        return Err(format!(
            "only {} samples at {:.1} Hz where the reference is valid over a whole filter window ({} samples each side): too little to fit",
            truth.len(),
            info.rate_hz,
            info.half_width
        ));
    }
    if !has_temp {
        for (m, t) in meas.iter_mut().zip(truth.iter_mut()) {
            m.temp = f64::NAN;
            t.temp = 25.0;
        }
    }
    Ok(Derived { meas, truth, truth_has_temp: !has_temp, info })
}

/// The reference's noise at rest and moving (see [`Derivation::reference_rest_rms`]).
fn reference_noise(m: &[MeasRow], t: &[TruthIn], rest: &[bool]) -> ([f64; 3], [f64; 3]) {
    let rms = |v: &[f64]| if v.is_empty() { 0.0 } else { (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt() };
    let rest_rms = [0, 1, 2].map(|a| rms(&t.iter().zip(rest).filter(|(_, r)| **r).map(|(x, _)| x.rate[a]).collect::<Vec<_>>()));
    let moving: Vec<usize> = (0..t.len()).filter(|&i| !rest[i]).collect();
    let move_rms = [0, 1, 2].map(|a| {
        if moving.len() < 10 {
            return rest_rms[a];
        }
        let x = nalgebra::DMatrix::from_fn(moving.len(), 3, |r, c| {
            let i = moving[r];
            [1.0, t[i].rate[a], t[i].wd.map_or(0.0, |d| d[a])][c]
        });
        let y = nalgebra::DVector::from_fn(moving.len(), |r, _| m[moving[r]].gyro[a] - t[moving[r]].rate[a]);
        let beta = (x.transpose() * &x).lu().solve(&(x.transpose() * &y)).unwrap_or_else(|| nalgebra::DVector::zeros(3));
        rms((y - x * beta).as_slice()).max(rest_rms[a])
    });
    (rest_rms, move_rms)
}

/// The truth from a measured reference.
pub fn from_reference(meas: &[MeasRow], r: &Reference, bandwidth: f64) -> Result<Derived, String> {
    let step = median_step(meas);
    if step.is_nan() || step <= 0.0 || meas.len() < 10 {
        return Err("the measured data has fewer than 10 samples or its time does not advance".into());
    }
    let ts: Vec<f64> = meas.iter().map(|m| m.t).collect();
    let q = r.at_times(&ts, 0.0);
    if q.iter().all(|x| x.is_none()) {
        return Err(format!(
            "the reference covers none of the measured samples (measured {:.3}..{:.3} s; the reference's t must be on the measured file's clock)",
            ts[0],
            ts[ts.len() - 1]
        ));
    }
    let rest = rest_at(meas, r);
    let (mq, mount) = mount(meas, &q, &rest)?;
    let wr = reference_rates(meas, &q);
    let reg = regular(meas, step);
    let ok: Vec<bool> = (0..meas.len()).map(|i| reg[i] && wr[i].is_some() && meas[i].acc.iter().all(|x| x.is_finite())).collect();
    let w: Vec<[f64; 3]> = wr.iter().map(|x| x.map_or([0.0; 3], |v| (mq * v).into())).collect();
    let h = (2.0 / (step * bandwidth)).ceil();
    if h * 2.0 + 3.0 > meas.len() as f64 {
        return Err(format!(
            "the filter at --bandwidth {bandwidth} Hz spans {h} samples each side at {:.1} Hz, more than the {} measured samples",
            1.0 / step,
            meas.len()
        ));
    }
    let (m, t, d, h) = filter(&Input { meas, w, ok }, 1.0 / step, bandwidth, None);
    let rate_hz = 1.0 / (step * d as f64);
    let rest_out: Vec<bool> = t.iter().map(|x| rest[meas.partition_point(|m| m.t < x.t).min(meas.len() - 1)]).collect();
    let (rest_rms, move_rms) = reference_noise(&m, &t, &rest_out);
    let density = (move_rms.iter().map(|x| x * x).sum::<f64>() / 3.0).sqrt() / (rate_hz / 2.0).sqrt();
    let (has_temp, temperature) = temperature_of(meas);
    let info = Derivation {
        source: "reference".into(),
        bandwidth_hz: bandwidth,
        input_rate_hz: 1.0 / step,
        decimation: d,
        rate_hz,
        half_width: h,
        mount: Some(mount),
        specific_force: format!("the measured accelerometer low-passed at {bandwidth} Hz (the reference has attitude only, no positions)"),
        temperature,
        reference_rest_rms: rest_rms,
        reference_moving_rms: move_rms,
        reference_white_density: density,
        input_samples: meas.len(),
        samples: t.len(),
        stretches: stretches(&t, d, step),
    };
    finish(m, t, info, has_temp)
}

/// A time jump that splits a static recording into bursts, s.
pub const STATIC_JUMP_S: f64 = 1.0;

/// The truth of a unit known to lie still: every sample as it is (no
/// filter: nothing is derived, and loggers of static data sample
/// irregularly), the rate zero, gravity the accelerometer's mean; bursts
/// between time jumps (> [`STATIC_JUMP_S`]) are stretches of one power cycle.
pub fn from_static(meas: &[MeasRow], _bandwidth: f64) -> Result<Derived, String> {
    let step = median_step(meas);
    if step.is_nan() || step <= 0.0 || meas.len() < 10 {
        return Err("the measured data has fewer than 10 samples or its time does not advance".into());
    }
    let acc: Vec<&MeasRow> = meas.iter().filter(|m| m.acc.iter().all(|x| x.is_finite())).collect();
    if acc.is_empty() {
        return Err("--static: the measured data has no accelerometer (gravity is taken from its mean)".into());
    }
    let mean = [0, 1, 2].map(|a| acc.iter().map(|m| m.acc[a]).sum::<f64>() / acc.len() as f64);
    let truth: Vec<TruthIn> =
        meas.iter().map(|m| TruthIn { t: m.t, rate: [0.0; 3], f: mean, temp: f64::NAN, wd: Some([0.0; 3]) }).collect();
    let mut stretches: Vec<[f64; 2]> = Vec::new();
    for (i, m) in meas.iter().enumerate() {
        if i == 0 || m.t - meas[i - 1].t > STATIC_JUMP_S {
            stretches.push([m.t, m.t]);
        }
        if let Some(l) = stretches.last_mut() {
            l[1] = m.t;
        }
    }
    let (has_temp, temperature) = temperature_of(meas);
    let temperature = temperature.replace(", filtered alike", "");
    let info = Derivation {
        source: "static".into(),
        bandwidth_hz: f64::NAN,
        input_rate_hz: 1.0 / step,
        decimation: 1,
        rate_hz: 1.0 / step,
        half_width: 0,
        mount: None,
        specific_force: format!(
            "the accelerometer's mean over the recording, [{:.4}, {:.4}, {:.4}] g (the unit lies still: zero rotation)",
            mean[0], mean[1], mean[2]
        ),
        temperature,
        reference_rest_rms: [0.0; 3],
        reference_moving_rms: [0.0; 3],
        reference_white_density: 0.0,
        input_samples: meas.len(),
        samples: truth.len(),
        stretches,
    };
    finish(meas.to_vec(), truth, info, has_temp)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_kernel_passes_dc_and_stops_above_the_band() {
        let k = kernel(200.0, 5.0);
        let gain = |f: f64| {
            let h = k.len() / 2;
            k.iter().enumerate().map(|(i, c)| c * (2.0 * std::f64::consts::PI * f * (i as f64 - h as f64) / 200.0).cos()).sum::<f64>()
        };
        assert!((gain(0.0) - 1.0).abs() < 1e-12);
        assert!((gain(1.0) - 1.0).abs() < 0.01, "pass band: {}", gain(1.0));
        assert!(gain(10.0).abs() < 0.01, "stop band: {}", gain(10.0));
    }
}
