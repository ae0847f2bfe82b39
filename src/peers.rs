//! Peer estimators run on the very samples ours sees, for `evaluate --peers`
//! (a recording against its reference, and simulated seeds): VQF here, Fusion
//! in [`fusion`].
//!
//! VQF (D. Laidig, T. Seel, "VQF: Highly accurate IMU orientation estimation
//! with bias estimation and magnetic disturbance rejection", Information
//! Fusion 2023) through the `vqf-rs` crate: a direct port of the official C++
//! implementation, in f64, with the 6D (gyro + accelerometer) and 9D (+
//! magnetometer) updates, rest and motion bias estimation and magnetic
//! disturbance rejection, all at the published default parameters. (The
//! `vqf` crate has no magnetometer update, so it cannot be the 9D peer.)
//!
//! Conventions. Our samples are FRD body, deg/s, specific force in g (a
//! level unit reads (0, 0, -1)), gauss. VQF wants a z-up body, rad/s, m/s^2
//! with +9.81 up at rest, and returns the body-to-world quaternion of a
//! z-up world (ENU once the magnetometer is fused). So the body vectors go
//! in as FLU = (x, -y, -z) (gyro in rad/s, specific force times
//! `G`), and the quaternion comes back as `C_ned_frd = T_ned_enu C_enu_flu
//! T_flu_frd`, whose Z-Y-X Euler angles are comparable with ours. A fixed
//! world yaw offset does not matter: the evaluation removes each
//! estimator's yaw offset at the end of the first rest phase.

pub mod fusion;

pub use fusion::run_fusion;

use crate::adis::Sample;
use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

/// Standard gravity, m/s^2.
pub const G: f64 = 9.80665;

/// FLU <- FRD (and back: it is its own inverse).
fn t_flu_frd() -> Matrix3<f64> {
    Matrix3::new(1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0)
}

/// NED <- ENU.
fn t_ned_enu() -> Matrix3<f64> {
    Matrix3::new(0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, -1.0)
}

/// A body vector FRD -> FLU.
#[inline]
pub fn frd_to_flu(v: [f64; 3]) -> [f64; 3] {
    [v[0], -v[1], -v[2]]
}

/// VQF's body(FLU)-to-world(ENU) quaternion (w, x, y, z) -> our attitude:
/// the rotation FRD body -> NED world.
pub fn vqf_to_ned_frd(q: [f64; 4]) -> UnitQuaternion<f64> {
    let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[0], q[1], q[2], q[3]));
    let c = t_ned_enu() * q.to_rotation_matrix().into_inner() * t_flu_frd();
    UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(c))
}

/// Z-Y-X Euler angles (roll, pitch, yaw), deg, of a body -> NED rotation.
pub fn euler_deg(q: &UnitQuaternion<f64>) -> [f64; 3] {
    let (r, p, y) = q.euler_angles();
    [r.to_degrees(), p.to_degrees(), y.to_degrees()]
}

/// VQF on a sequence of samples: roll, pitch, yaw (deg, FRD in NED) after
/// every sample. `period` is the sample period (s); a sample after a counter
/// gap integrates its rate over the whole gap. `magn`: the 9D filter (the
/// magnetometer fused), else 6D.
pub fn run_vqf(samples: &[Sample], period: f64, magn: bool) -> Vec<[f64; 3]> {
    let mut f = vqf_rs::VQF::new(period, None, None, None);
    let mut out = Vec::with_capacity(samples.len());
    let d2r = std::f64::consts::PI / 180.0;
    for s in samples {
        let gyr = frd_to_flu(s.gyro).map(|w| w * d2r);
        let acc = frd_to_flu(s.accel).map(|a| a * G);
        let steps = s.steps.max(1) as f64;
        f.update_gyr_with_ts(gyr, period * steps);
        f.update_acc(acc);
        let q = if magn {
            f.update_mag(frd_to_flu(s.magn));
            f.quat_9d()
        } else {
            f.quat_6d()
        };
        out.push(euler_deg(&vqf_to_ned_frd([q.0, q.1, q.2, q.3])));
    }
    out
}

/// The down direction (NED z) in the body of a body -> NED rotation.
pub fn body_down(q: &UnitQuaternion<f64>) -> Vector3<f64> {
    q.inverse_transform_vector(&Vector3::z())
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A body turning through large roll, pitch and yaw without translation:
    /// the exact rates, specific force and field for each sample.
    pub(crate) fn tumbling(rate: f64, secs: f64) -> (Vec<Sample>, Vec<[f64; 3]>) {
        let n = (rate * secs) as usize;
        let m_ned = Vector3::new(0.2, 0.03, 0.45);
        let mut s = Vec::with_capacity(n);
        let mut truth = Vec::with_capacity(n);
        for k in 0..n {
            let t = k as f64 / rate;
            // Euler angles (rad) and their rates; still for the first 5 s.
            let w = |a: f64, f: f64, ph: f64| {
                let u = (t - 5.0).max(0.0);
                (a * (f * u + ph).sin() - a * ph.sin(), if t < 5.0 { 0.0 } else { a * f * (f * u + ph).cos() })
            };
            let (r0, rd) = w(0.7, 0.31, 0.0);
            let (p0, pd) = w(0.5, 0.23, 0.4);
            let (y0, yd) = w(2.0, 0.11, 0.0);
            let (roll, pitch, yaw) = (r0 + 0.05, p0 - 0.03, y0 + 0.6);
            let (sr, cr) = roll.sin_cos();
            let (sp, cp) = pitch.sin_cos();
            let body = [rd - yd * sp, pd * cr + yd * sr * cp, -pd * sr + yd * cr * cp].map(f64::to_degrees);
            let q = UnitQuaternion::from_euler_angles(roll, pitch, yaw);
            let f = q.inverse_transform_vector(&Vector3::new(0.0, 0.0, -1.0));
            let m = q.inverse_transform_vector(&m_ned);
            s.push(Sample {
                cnt: k as u16,
                steps: if k == 0 { 0 } else { 1 },
                gyro: body,
                accel: [f.x, f.y, f.z],
                magn: [m.x, m.y, m.z],
                ..Default::default()
            });
            truth.push([roll, pitch, yaw].map(f64::to_degrees));
        }
        (s, truth)
    }

    pub(crate) fn wrap(d: f64) -> f64 {
        (d + 180.0).rem_euclid(360.0) - 180.0
    }

    /// The worst roll/pitch and yaw errors (deg) of `est` against `truth`
    /// from sample `from` on, the estimate's yaw taken less `yaw_off`.
    pub(crate) fn worst_errors(est: &[[f64; 3]], truth: &[[f64; 3]], from: usize, yaw_off: f64) -> (f64, f64) {
        let (mut worst_rp, mut worst_y) = (0.0f64, 0.0f64);
        for (e, t) in est.iter().zip(truth).skip(from) {
            worst_rp = worst_rp.max(wrap(e[0] - t[0]).abs()).max((e[1] - t[1]).abs());
            worst_y = worst_y.max(wrap(e[2] - yaw_off - t[2]).abs());
        }
        (worst_rp, worst_y)
    }

    #[test]
    fn frame_conversions_are_rotations_and_round_trip() {
        // A body attitude expressed through VQF's frames and back is the same.
        let ours = UnitQuaternion::from_euler_angles(0.3, -0.4, 2.0);
        let c_enu_flu = t_ned_enu().transpose() * ours.to_rotation_matrix().into_inner() * t_flu_frd();
        let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(c_enu_flu));
        let back = vqf_to_ned_frd([q.w, q.i, q.j, q.k]);
        assert!(back.angle_to(&ours) < 1e-12);
        assert!((t_flu_frd().determinant() - 1.0).abs() < 1e-15 && (t_ned_enu().determinant() - 1.0).abs() < 1e-15);
    }

    #[test]
    fn vqf_tracks_a_tumbling_body_in_our_conventions() {
        // Roll +-40 deg, pitch +-29 deg, yaw +-115 deg: a sign or axis error in
        // the conversion shows up as tens of degrees.
        let rate = 200.0;
        let (s, truth) = tumbling(rate, 120.0);
        for magn in [false, true] {
            let est = run_vqf(&s, 1.0 / rate, magn);
            // yaw: 9D is absolute (magnetic north of the simulated field, 8.5 deg
            // east of north here); 6D has an arbitrary origin, fixed at 5 s.
            let k0 = (5.0 * rate) as usize;
            let off = if magn { 0.0 } else { wrap(est[k0][2] - truth[k0][2]) };
            let decl = 0.03f64.atan2(0.2).to_degrees();
            let (worst_rp, worst_y) = worst_errors(&est, &truth, (30.0 * rate) as usize, off - if magn { decl } else { 0.0 });
            assert!(worst_rp < 1.0, "magn {magn}: worst roll/pitch error {worst_rp}");
            assert!(worst_y < 2.0, "magn {magn}: worst yaw error {worst_y}");
        }
    }
}
