//! The Fusion peer: x-io Technologies' Fusion AHRS (the revised Mahony
//! filter of chapter 7 of Madgwick's thesis, with gyroscope offset
//! correction, acceleration and magnetic rejection and their recovery),
//! through the `fusion-ahrs` crate, a port of the C library (in f32, as the
//! C is), checked by its authors against the C library's outputs.
//!
//! Settings: those of the library's Python package `imufusion` in its
//! advanced example: gain 0.5, gyroscope range 2000 deg/s, acceleration
//! rejection 10 deg, magnetic rejection 10 deg, recovery after 5 s of
//! rejection; the gyroscope offset correction (`Bias`) at the library's
//! defaults (the offset is learned while every axis reads under 3 deg/s for
//! 3 s, through a first-order low-pass filter of 0.02 Hz), applied to each
//! gyroscope sample before the AHRS update, as the example does.
//!
//! Conventions. Fusion takes the body in the sensor's own axes and an earth
//! convention; with NED it expects a level sensor to read (0, 0, -1) g on an
//! FRD body, which is how our samples come (deg/s, g, gauss: Fusion
//! normalises the field). Its quaternion rotates the body into NED, so it is
//! our attitude as it stands. A sample after a counter gap integrates its rate
//! over the whole gap (the sample period is set for that update).

use super::euler_deg;
use crate::adis::Sample;
use fusion_ahrs::{Ahrs, AhrsSettings, Bias, BiasSettings, Convention, Vector};
use nalgebra::{Quaternion, UnitQuaternion};

/// Fusion's settings for a sample rate (Hz): those of `imufusion`'s advanced example.
pub fn settings(rate_hz: f64) -> (AhrsSettings, BiasSettings) {
    let sample_rate = rate_hz as f32;
    let ahrs = AhrsSettings {
        sample_rate,
        convention: Convention::Ned,
        gain: 0.5,
        gyroscope_range: 2000.0,
        acceleration_rejection: 10.0,
        magnetic_rejection: 10.0,
        rejection_timeout: 5.0,
    };
    (ahrs, BiasSettings { sample_rate, ..BiasSettings::default() })
}

fn v(a: [f64; 3]) -> Vector {
    Vector::new(a[0] as f32, a[1] as f32, a[2] as f32)
}

/// Fusion's attitude (FRD body -> NED) as ours.
fn attitude(a: &Ahrs) -> UnitQuaternion<f64> {
    let q = a.quaternion();
    UnitQuaternion::from_quaternion(Quaternion::new(q.w as f64, q.x as f64, q.y as f64, q.z as f64))
}

/// Fusion on a sequence of samples: roll, pitch, yaw (deg, FRD in NED)
/// after every sample, and the gyroscope offset it has learned (deg/s) at
/// the end. `period` is the sample period (s, > 0); `magn`: the magnetometer
/// fused, else gyroscope and accelerometer only (the heading starts at 0).
pub fn run_fusion_with_offset(samples: &[Sample], period: f64, magn: bool) -> (Vec<[f64; 3]>, [f64; 3]) {
    let (sa, sb) = settings(1.0 / period);
    let mut ahrs = Ahrs::with_settings(sa);
    let mut bias = Bias::with_settings(sb);
    let mut out = Vec::with_capacity(samples.len());
    for s in samples {
        ahrs.set_sample_period((period * s.steps.max(1) as f64) as f32);
        let gyro = bias.update(v(s.gyro));
        if magn {
            ahrs.update(gyro, v(s.accel), v(s.magn));
        } else {
            ahrs.update_no_magnetometer(gyro, v(s.accel));
        }
        out.push(euler_deg(&attitude(&ahrs)));
    }
    let o = bias.offset();
    (out, [o.x as f64, o.y as f64, o.z as f64])
}

/// Fusion on a sequence of samples: roll, pitch, yaw (deg, FRD in NED)
/// after every sample ([`run_fusion_with_offset`]).
pub fn run_fusion(samples: &[Sample], period: f64, magn: bool) -> Vec<[f64; 3]> {
    run_fusion_with_offset(samples, period, magn).0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::peers::tests::{tumbling, worst_errors, wrap};
    use nalgebra::Vector3;

    /// `n` samples of a unit at rest at roll, pitch (deg), reading `gyro` (deg/s).
    fn at_rest(n: usize, roll: f64, pitch: f64, gyro: [f64; 3]) -> Vec<Sample> {
        let q = UnitQuaternion::from_euler_angles(roll.to_radians(), pitch.to_radians(), 0.3);
        let f = q.inverse_transform_vector(&Vector3::new(0.0, 0.0, -1.0));
        let m = q.inverse_transform_vector(&Vector3::new(0.2, 0.0, 0.45));
        (0..n)
            .map(|k| Sample {
                cnt: k as u16,
                steps: (k > 0) as u32,
                gyro,
                accel: [f.x, f.y, f.z],
                magn: [m.x, m.y, m.z],
                ..Default::default()
            })
            .collect()
    }

    #[test]
    fn a_static_unit_converges_to_its_tilt() {
        for (roll, pitch) in [(0.0, 0.0), (5.0, -3.0), (-20.0, 12.0)] {
            let s = at_rest(2000, roll, pitch, [0.0; 3]);
            for magn in [false, true] {
                let att = run_fusion(&s, 0.01, magn);
                let last = att.last().unwrap();
                assert!((last[0] - roll).abs() < 0.05 && (last[1] - pitch).abs() < 0.05, "magn {magn}: {last:?} vs {roll}, {pitch}");
            }
        }
    }

    #[test]
    fn a_constant_rotation_is_tracked() {
        // level, yawing at 20 deg/s for 10 s after 5 s at rest: the heading
        // (6D: from 0 at power-on) turns by 200 deg, roll and pitch stay level
        let rate = 100.0;
        let mut s = at_rest(500, 0.0, 0.0, [0.0; 3]);
        let n = s.len();
        for k in 0..1000 {
            let yaw = (20.0 * (k + 1) as f64 / rate).to_radians();
            let q = UnitQuaternion::from_euler_angles(0.0, 0.0, yaw);
            let m = q.inverse_transform_vector(&Vector3::new(0.2, 0.0, 0.45));
            s.push(Sample {
                cnt: (n + k) as u16,
                steps: 1,
                gyro: [0.0, 0.0, 20.0],
                accel: [0.0, 0.0, -1.0],
                magn: [m.x, m.y, m.z],
                ..Default::default()
            });
        }
        let att = run_fusion(&s, 1.0 / rate, false);
        let turned = wrap(att.last().unwrap()[2] - att[n - 1][2]);
        assert!((turned - wrap(200.0)).abs() < 0.1, "turned {turned}");
        assert!(att.iter().all(|a| a[0].abs() < 0.05 && a[1].abs() < 0.05));
    }

    #[test]
    fn an_offset_is_learned_at_rest() {
        // 0.5 deg/s on x, -0.3 on z at rest for 5 min: the 0.02 Hz filter
        // has long settled after its 3 s stationary period
        let s = at_rest(30_000, 2.0, 1.0, [0.5, 0.0, -0.3]);
        let (att, off) = run_fusion_with_offset(&s, 0.01, false);
        assert!((off[0] - 0.5).abs() < 0.01 && off[1].abs() < 0.01 && (off[2] + 0.3).abs() < 0.01, "{off:?}");
        // the heading has stopped drifting
        let drift = wrap(att[29_999][2] - att[24_000][2]);
        assert!(drift.abs() < 0.1, "heading drift {drift} deg in the last minute");
    }

    #[test]
    fn fusion_tracks_a_tumbling_body_in_our_conventions() {
        // the same tumbling body as VQF's test: a sign or axis error shows up
        // as tens of degrees
        let rate = 200.0;
        let (s, truth) = tumbling(rate, 120.0);
        for magn in [false, true] {
            let est = run_fusion(&s, 1.0 / rate, magn);
            let k0 = (5.0 * rate) as usize;
            let decl = 0.03f64.atan2(0.2).to_degrees();
            let off = if magn { -decl } else { wrap(est[k0][2] - truth[k0][2]) };
            let (worst_rp, worst_y) = worst_errors(&est, &truth, (30.0 * rate) as usize, off);
            assert!(worst_rp < 3.0, "magn {magn}: worst roll/pitch error {worst_rp}");
            assert!(worst_y < 5.0, "magn {magn}: worst yaw error {worst_y}");
        }
    }
}
