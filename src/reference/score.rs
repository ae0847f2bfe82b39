//! Alignment to the reference and the scores, the same for every estimator.
//!
//! **Alignment.** The reference body is mounted on the sensor, not inside
//! it: a constant tilt between the two is expected. It is estimated once,
//! from the data alone, over the *first rest phase* only (the first run of
//! `rest = 1` rows; without one, the first `--align-s` seconds from the
//! first valid reference row): the sensor's down direction is minus the
//! mean specific force over the samples of that window that have a
//! reference, the reference's is the mean of its body down vectors over the
//! same samples, and the mount is the smallest rotation taking the first
//! onto the second (a rotation about the vertical cannot be seen at rest and
//! is not estimated). It is never fitted over the whole run, and it is the
//! same for every estimator: each one's attitude `q` becomes `q M^-1` (the
//! attitude of the reference body it implies). Yaw has an arbitrary origin
//! in the reference: each estimator's own yaw offset is its mean yaw error
//! over the last second of that window, removed before yaw is scored.
//! A window where any gyro axis varies by more than 1 deg/s or any
//! accelerometer axis by more than 0.02 g (standard deviation) does not look
//! like rest: the mount is still estimated there (the rule), but flagged,
//! since it then also holds whatever acceleration the unit had. `--align-s
//! 0` with a reference without a rest phase estimates no mount at all (for a
//! reference computed in the sensor's own frame); the yaw offset is then
//! taken over the first second with a reference.
//!
//! **Scores** (from `skip` on, where the reference is valid and no gap):
//! roll and pitch error (max, RMS), tilt (inclination) error — the angle
//! between the estimated and the reference down direction, which has no
//! singularity — and, when the magnetometer is used, yaw error. Where the
//! reference pitch exceeds 80 deg in magnitude, roll and yaw are not defined
//! well enough to be scored (a small attitude error moves them by tens of
//! degrees near the vertical): they are left out there and the time is
//! reported; pitch (a latitude, never more wrong than the attitude) and tilt
//! are scored everywhere.

use super::refcsv::Reference;
use crate::adis::Sample;
use crate::peers::body_down;
use nalgebra::{UnitQuaternion, Vector3};
use serde::Serialize;

/// Roll and yaw are not scored where |reference pitch| exceeds this, deg.
pub const VERTICAL_LIMIT_DEG: f64 = 80.0;
/// Each estimator's yaw offset is its mean yaw error over this last part of the alignment window, s.
pub const YAW_OFFSET_WINDOW_S: f64 = 1.0;

pub fn wrap180(d: f64) -> f64 {
    let w = (d + 180.0).rem_euclid(360.0) - 180.0;
    if w == -180.0 {
        180.0
    } else {
        w
    }
}

/// Seconds since the first sample, from the sample counter (a restart of
/// the counter, of unknown length, counts as one period).
pub fn sample_times(samples: &[Sample], period: f64) -> Vec<f64> {
    let mut t = 0.0;
    samples
        .iter()
        .enumerate()
        .map(|(k, s)| {
            if k > 0 {
                t += s.steps.max(1) as f64 * period;
            }
            t
        })
        .collect()
}

/// The alignment window, s on the sample clock.
#[derive(Clone, Debug, Serialize)]
pub struct Window {
    pub t0: f64,
    pub t1: f64,
    /// "first rest phase" or "first N s".
    pub source: String,
    /// False: the mount is not estimated (identity).
    pub estimate_mount: bool,
    /// The window is the reference's first rest phase.
    pub rest_phase: bool,
    /// No rest phase, and the first seconds were not at rest: no mount
    /// (`source` says why).
    pub refused_in_motion: bool,
}

/// The first rest phase, or the first `align_s` seconds from the first valid
/// row. `align_s = 0` without a rest phase: no mount is estimated (the
/// reference is taken to be in the sensor's own frame); the window is then
/// the first second, for the yaw offset only.
pub fn alignment_window(r: &Reference, align_s: f64, offset: f64) -> Result<Window, String> {
    if r.has_rest {
        if let Some(a) = r.rows.iter().position(|x| x.rest) {
            let b = r.rows[a..].iter().position(|x| !x.rest).map(|n| a + n - 1).unwrap_or(r.rows.len() - 1);
            return Ok(Window {
                t0: r.rows[a].t - offset,
                t1: r.rows[b].t - offset,
                estimate_mount: true,
                rest_phase: true,
                refused_in_motion: false,
                source: "first rest phase".into(),
            });
        }
    }
    let first = r.rows.iter().find(|x| x.att.is_some()).ok_or("no valid reference row")?;
    let t0 = first.t - offset;
    if align_s == 0.0 {
        return Ok(Window {
            t0,
            t1: t0 + YAW_OFFSET_WINDOW_S,
            estimate_mount: false,
            rest_phase: false,
            refused_in_motion: false,
            source: "no mount (no rest phase, --align-s 0)".into(),
        });
    }
    Ok(Window {
        t0,
        t1: t0 + align_s,
        estimate_mount: true,
        rest_phase: false,
        refused_in_motion: false,
        source: format!("first {align_s} s (no rest phase in the reference)"),
    })
}

/// The alignment window looks like rest when no axis varies more than this
/// (standard deviation about the window's mean).
pub const REST_GYRO_STD_DPS: f64 = 1.0;
pub const REST_ACCEL_STD_G: f64 = 0.02;

/// The sensor-to-reference mount, estimated over the window.
#[derive(Clone, Debug, Serialize)]
pub struct Alignment {
    pub window: Window,
    /// Samples in the window with a reference.
    pub samples: usize,
    /// Total tilt of the mount, deg, and its roll / pitch parts.
    pub tilt_deg: f64,
    pub roll_deg: f64,
    pub pitch_deg: f64,
    /// |mean specific force| over the window, g (about 1 at rest).
    pub accel_g: f64,
    /// Largest per-axis standard deviation over the window: gyro (deg/s), specific force (g).
    pub gyro_std_dps: f64,
    pub accel_std_g: f64,
    /// Both within `REST_GYRO_STD_DPS` / `REST_ACCEL_STD_G`: the window looks
    /// like rest. If not, the mount also holds whatever the unit did then
    /// (an acceleration of 0.1 g tilts it by 5.7 deg).
    pub looks_at_rest: bool,
    /// The rotation sensor body -> reference body.
    #[serde(skip)]
    pub mount: UnitQuaternion<f64>,
}

/// Estimate the mount from the accelerometer and the reference over the window.
pub fn align(samples: &[Sample], ts: &[f64], refq: &[Option<UnitQuaternion<f64>>], w: &Window) -> Result<Alignment, String> {
    let mut f = Vector3::zeros();
    let mut d = Vector3::zeros();
    let (mut g, mut gg, mut ff) = (Vector3::zeros(), Vector3::zeros(), Vector3::zeros());
    let mut n = 0usize;
    for k in 0..samples.len() {
        if ts[k] < w.t0 || ts[k] > w.t1 {
            continue;
        }
        if let Some(q) = refq[k] {
            let a = Vector3::from(samples[k].accel);
            let w = Vector3::from(samples[k].gyro);
            f += a;
            ff += a.component_mul(&a);
            g += w;
            gg += w.component_mul(&w);
            d += body_down(&q);
            n += 1;
        }
    }
    if n == 0 {
        return Err(format!("no sample with a valid reference in the alignment window ({}, {:.3}..{:.3} s)", w.source, w.t0, w.t1));
    }
    let nf = n as f64;
    let f = f / nf;
    let std = |sum: Vector3<f64>, sq: Vector3<f64>| (sq / nf - (sum / nf).component_mul(&(sum / nf))).map(|v| v.max(0.0).sqrt()).max();
    let gyro_std_dps = std(g, gg);
    let accel_std_g = std(f * nf, ff);
    let ds = -f.normalize();
    let dr = d.normalize();
    let mount = if w.estimate_mount {
        UnitQuaternion::rotation_between(&ds, &dr)
            .ok_or("the sensor's down direction is opposite to the reference's in the alignment window (wrong axes?)")?
    } else {
        UnitQuaternion::identity()
    };
    let (r, p, _) = mount.euler_angles();
    Ok(Alignment {
        window: w.clone(),
        samples: n,
        tilt_deg: mount.angle().to_degrees(),
        roll_deg: r.to_degrees(),
        pitch_deg: p.to_degrees(),
        accel_g: f.norm(),
        gyro_std_dps,
        accel_std_g,
        looks_at_rest: gyro_std_dps <= REST_GYRO_STD_DPS && accel_std_g <= REST_ACCEL_STD_G,
        mount,
    })
}

#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct MaxRms {
    pub max: f64,
    pub rms: f64,
}

/// Seconds per estimator mode.
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct ModeSeconds {
    pub fusion: f64,
    pub blend: f64,
    pub gyro_only: f64,
}

/// One estimator's scores against the reference.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Scores {
    pub roll: MaxRms,
    pub pitch: MaxRms,
    pub tilt_rms: f64,
    pub tilt_max: f64,
    /// None when yaw is not scored (no magnetometer used).
    pub yaw_rms: Option<f64>,
    pub yaw_max: Option<f64>,
    /// The yaw offset removed (estimate - reference), deg.
    pub yaw_offset_deg: Option<f64>,
    /// Time scored (tilt and pitch), s.
    pub scored_s: f64,
    /// Time where roll and yaw were not scored (|reference pitch| > 80 deg), s.
    pub vertical_s: f64,
    /// Time after `skip` without a usable reference (invalid rows, gaps, outside it), s.
    pub no_reference_s: f64,
    /// Time of the largest tilt error, s.
    pub t_max_tilt: f64,
    /// Time per mode over the scored window (estimators that have modes).
    pub mode_s: Option<ModeSeconds>,
}

/// Per-sample errors, deg (NaN where not scored).
#[derive(Clone, Copy, Debug)]
pub struct ErrRow {
    pub t: f64,
    pub roll: f64,
    pub pitch: f64,
    pub yaw: f64,
    pub tilt: f64,
}

/// What to score.
pub struct ScoreSpec<'a> {
    pub ts: &'a [f64],
    pub refq: &'a [Option<UnitQuaternion<f64>>],
    pub align: &'a Alignment,
    pub skip: f64,
    pub period: f64,
    pub yaw: bool,
}

struct Acc {
    max: f64,
    sq: f64,
    n: usize,
}

impl Acc {
    fn new() -> Acc {
        Acc { max: 0.0, sq: 0.0, n: 0 }
    }
    fn add(&mut self, e: f64) {
        self.max = self.max.max(e.abs());
        self.sq += e * e;
        self.n += 1;
    }
    fn rms(&self) -> f64 {
        if self.n == 0 {
            f64::NAN
        } else {
            (self.sq / self.n as f64).sqrt()
        }
    }
    fn max_rms(&self) -> MaxRms {
        MaxRms { max: if self.n == 0 { f64::NAN } else { self.max }, rms: self.rms() }
    }
}

/// Score one estimator's attitude track (roll, pitch, yaw in deg per sample;
/// `modes` per sample for estimators that have them).
pub fn score(att: &[[f64; 3]], modes: Option<&[u8]>, s: &ScoreSpec<'_>) -> (Scores, Vec<ErrRow>) {
    let minv = s.align.mount.inverse();
    let aligned: Vec<UnitQuaternion<f64>> =
        att.iter().map(|a| UnitQuaternion::from_euler_angles(a[0].to_radians(), a[1].to_radians(), a[2].to_radians()) * minv).collect();
    // Yaw offset: circular mean of the yaw error over the end of the window.
    let w = &s.align.window;
    let (mut sc, mut cc) = (0.0, 0.0);
    for k in 0..att.len() {
        if s.ts[k] >= w.t1 - YAW_OFFSET_WINDOW_S && s.ts[k] <= w.t1 {
            if let Some(r) = s.refq[k] {
                let d = (aligned[k].euler_angles().2 - r.euler_angles().2).rem_euclid(std::f64::consts::TAU);
                sc += d.sin();
                cc += d.cos();
            }
        }
    }
    let yaw_off = if s.yaw && (sc != 0.0 || cc != 0.0) { Some(sc.atan2(cc).to_degrees()) } else { None };
    let (mut roll, mut pitch, mut yaw, mut tilt) = (Acc::new(), Acc::new(), Acc::new(), Acc::new());
    let mut out = Scores { yaw_offset_deg: yaw_off, ..Default::default() };
    let mut modes_n = [0usize; 3];
    let mut rows = Vec::with_capacity(att.len());
    let (mut vertical, mut missing) = (0usize, 0usize);
    for k in 0..att.len() {
        let t = s.ts[k];
        let scored = t >= s.skip;
        if scored {
            if let Some(m) = modes {
                modes_n[(m[k] as usize).min(2)] += 1;
            }
        }
        let r = match s.refq[k] {
            Some(r) => r,
            None => {
                missing += scored as usize;
                rows.push(ErrRow { t, roll: f64::NAN, pitch: f64::NAN, yaw: f64::NAN, tilt: f64::NAN });
                continue;
            }
        };
        let (er, ep, ey) = aligned[k].euler_angles();
        let (rr, rp, ry) = r.euler_angles();
        let te = body_down(&aligned[k]).angle(&body_down(&r)).to_degrees();
        let pe = (ep - rp).to_degrees();
        let near_vertical = rp.to_degrees().abs() > VERTICAL_LIMIT_DEG;
        let re = if near_vertical { f64::NAN } else { wrap180((er - rr).to_degrees()) };
        let ye = match (near_vertical, yaw_off) {
            (false, Some(o)) => wrap180((ey - ry).to_degrees() - o),
            _ => f64::NAN,
        };
        rows.push(ErrRow { t, roll: re, pitch: pe, yaw: ye, tilt: te });
        if !scored {
            continue;
        }
        if te > tilt.max {
            out.t_max_tilt = t;
        }
        tilt.add(te);
        pitch.add(pe);
        if near_vertical {
            vertical += 1;
            continue;
        }
        roll.add(re);
        if ye.is_finite() {
            yaw.add(ye);
        }
    }
    out.roll = roll.max_rms();
    out.pitch = pitch.max_rms();
    out.tilt_rms = tilt.rms();
    out.tilt_max = if tilt.n == 0 { f64::NAN } else { tilt.max };
    if yaw_off.is_some() && yaw.n > 0 {
        out.yaw_rms = Some(yaw.rms());
        out.yaw_max = Some(yaw.max);
    }
    out.scored_s = tilt.n as f64 * s.period;
    out.vertical_s = vertical as f64 * s.period;
    out.no_reference_s = missing as f64 * s.period;
    if modes.is_some() {
        let m = modes_n.map(|n| n as f64 * s.period);
        out.mode_s = Some(ModeSeconds { fusion: m[0], blend: m[1], gyro_only: m[2] });
    }
    (out, rows)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference::refcsv::RefRow;

    fn level(n: usize, tilt: [f64; 2]) -> Vec<Sample> {
        let q = UnitQuaternion::from_euler_angles(tilt[0].to_radians(), tilt[1].to_radians(), 0.3);
        let f = q.inverse_transform_vector(&Vector3::new(0.0, 0.0, -1.0));
        (0..n).map(|k| Sample { steps: (k > 0) as u32, accel: [f.x, f.y, f.z], ..Default::default() }).collect()
    }

    #[test]
    fn the_mount_is_the_tilt_between_accelerometer_and_reference() {
        // Sensor tilted roll 2, pitch -1 deg; reference body level: the mount
        // takes the sensor's down onto the reference's, and an estimator that
        // holds the sensor's true attitude then scores zero.
        let s = level(500, [2.0, -1.0]);
        let ts = sample_times(&s, 0.01);
        let rows: Vec<RefRow> = ts.iter().map(|&t| RefRow { t, att: Some([0.0, 0.0, 17.0]), rest: t < 2.995 }).collect();
        let r = Reference { rows, has_rest: true, has_valid: true };
        let w = alignment_window(&r, 5.0, 0.0).unwrap();
        assert_eq!((w.t0, w.source.as_str()), (0.0, "first rest phase"));
        assert!((w.t1 - 2.99).abs() < 1e-9);
        let refq = r.at_times(&ts, 0.0);
        let a = align(&s, &ts, &refq, &w).unwrap();
        assert!((a.tilt_deg - (2f64.powi(2) + 1.0).sqrt()).abs() < 0.01, "{}", a.tilt_deg);
        // the sensor's attitude in the reference body: roll 2, pitch -1
        assert!((a.roll_deg - 2.0).abs() < 0.02 && (a.pitch_deg + 1.0).abs() < 0.02, "{a:?}");
        let att = vec![[2.0, -1.0, 0.3f64.to_degrees()]; s.len()];
        let spec = ScoreSpec { ts: &ts, refq: &refq, align: &a, skip: 1.0, period: 0.01, yaw: true };
        let (sc, _) = score(&att, None, &spec);
        assert!(sc.tilt_max < 1e-6 && sc.roll.max < 1e-6 && sc.pitch.max < 1e-6, "{sc:?}");
        // yaw: the offset (estimate 17.19 deg vs reference 17) is removed
        assert!(sc.yaw_max.unwrap() < 1e-6);
        assert!((sc.scored_s - 4.0).abs() < 1e-9);
        // without alignment the same estimator is 2.2 deg off
        let id = Alignment { mount: UnitQuaternion::identity(), ..a.clone() };
        let spec = ScoreSpec { align: &id, ..spec };
        let (sc, _) = score(&att, None, &spec);
        assert!((sc.tilt_max - 5f64.sqrt()).abs() < 0.01, "{sc:?}");
    }

    #[test]
    fn roll_and_yaw_are_not_scored_near_the_vertical() {
        let s = level(400, [0.0, 0.0]);
        let ts = sample_times(&s, 0.01);
        let rows: Vec<RefRow> =
            ts.iter().map(|&t| RefRow { t, att: Some([0.0, if t < 2.0 { 0.0 } else { 85.0 }, 0.0]), rest: t < 1.0 }).collect();
        let r = Reference { rows, has_rest: true, has_valid: true };
        let refq = r.at_times(&ts, 0.0);
        let a = align(&s, &ts, &refq, &alignment_window(&r, 5.0, 0.0).unwrap()).unwrap();
        // the estimate is 3 deg short in pitch and 40 deg off in roll and yaw near the vertical
        let att: Vec<[f64; 3]> = ts.iter().map(|&t| if t < 2.0 { [0.0, 0.0, 0.0] } else { [40.0, 82.0, 40.0] }).collect();
        let (sc, _) = score(&att, None, &ScoreSpec { ts: &ts, refq: &refq, align: &a, skip: 0.5, period: 0.01, yaw: true });
        assert!((sc.vertical_s - 2.0).abs() < 1e-9, "{sc:?}");
        assert!(sc.roll.max < 1e-6 && sc.yaw_max.unwrap() < 1e-6, "{sc:?}");
        assert!((sc.pitch.max - 3.0).abs() < 1e-6, "{sc:?}");
        assert!(sc.tilt_max >= 3.0, "{sc:?}");
    }
}
