//! Small rotation helpers for the default filter: unit quaternions
//! `[w, x, y, z]` (body to navigation frame, Hamilton product), the rotation
//! matrix `C_nb` and Z-Y-X Euler angles (used only at the output).

pub type Quat = [f64; 4];
pub type Mat3 = [[f64; 3]; 3];

/// `a ⊗ b`.
#[inline]
pub fn mul(a: &Quat, b: &Quat) -> Quat {
    [
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
        a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
    ]
}

/// Normalise (and keep `w >= 0`, one of the two equal quaternions).
#[inline]
pub fn normalise(q: &mut Quat) {
    let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    let s = if q[0] < 0.0 { -1.0 / n } else { 1.0 / n };
    for v in q.iter_mut() {
        *v *= s;
    }
}

/// The quaternion of a rotation vector `r` (rad).
#[inline]
pub fn from_rotvec(r: &[f64; 3]) -> Quat {
    let a2 = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
    if a2 < 1e-4 {
        // the series of cos(a/2) and sin(a/2)/a to a^4: below 0.01 rad (a
        // step at up to 115 deg/s at 200 Hz) the next terms are under 1e-16
        let s = 0.5 - a2 * (1.0 / 48.0) + a2 * a2 * (1.0 / 3840.0);
        let c = 1.0 - a2 * 0.125 + a2 * a2 * (1.0 / 384.0);
        [c, r[0] * s, r[1] * s, r[2] * s]
    } else {
        let a = a2.sqrt();
        let (sn, cs) = (0.5 * a).sin_cos();
        let s = sn / a;
        [cs, r[0] * s, r[1] * s, r[2] * s]
    }
}

/// `C_nb` of `q` (body vector to navigation vector).
#[inline]
pub fn to_matrix(q: &Quat) -> Mat3 {
    let [w, x, y, z] = *q;
    let (xx, yy, zz) = (x * x, y * y, z * z);
    let (xy, xz, yz) = (x * y, x * z, y * z);
    let (wx, wy, wz) = (w * x, w * y, w * z);
    [
        [1.0 - 2.0 * (yy + zz), 2.0 * (xy - wz), 2.0 * (xz + wy)],
        [2.0 * (xy + wz), 1.0 - 2.0 * (xx + zz), 2.0 * (yz - wx)],
        [2.0 * (xz - wy), 2.0 * (yz + wx), 1.0 - 2.0 * (xx + yy)],
    ]
}

/// The quaternion of Z-Y-X Euler angles (rad).
pub fn from_euler(roll: f64, pitch: f64, yaw: f64) -> Quat {
    let (sr, cr) = (0.5 * roll).sin_cos();
    let (sp, cp) = (0.5 * pitch).sin_cos();
    let (sy, cy) = (0.5 * yaw).sin_cos();
    let mut q = [cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy];
    normalise(&mut q);
    q
}

/// Z-Y-X Euler angles `[roll, pitch, yaw]` (rad) of `C_nb`. At exactly
/// vertical (|pitch| = 90 deg) roll and yaw are one angle; the split is
/// arbitrary but finite. Pitch is `atan2(-c20, |(c00, c10)|)`, which stays
/// accurate near vertical where `asin(-c20)` loses half its digits.
#[inline]
pub fn euler(c: &Mat3) -> [f64; 3] {
    let cp = (c[0][0] * c[0][0] + c[1][0] * c[1][0]).sqrt();
    [atan2(c[2][1], c[2][2]), atan2(-c[2][0], cp), atan2(c[1][0], c[0][0])]
}

/// `tan(pi / 8)`.
const TAN_PI_8: f64 = 0.414_213_562_373_095_03;

/// `atan(t) / t ~ sum_k c_k t^(2k)` on `|t| <= tan(pi / 8)`: least squares
/// of `atan(t)` on 2,000 Chebyshev nodes in `t^2` (near-minimax); the
/// largest error is 1.2e-10 rad (`atan2_is_within_2e_10_of_libm_everywhere`).
const ATAN_POLY: [f64; 6] = [
    0.999_999_996_162_639_2,
    -0.333_332_698_464_466_7,
    0.199_969_819_776_730_6,
    -0.142_236_117_350_975_52,
    0.104_773_921_652_871_68,
    -0.058_309_923_908_119_97,
];

/// `atan2(y, x)` within 2e-10 rad of the exact value (the output's angle
/// resolution is 0.01 deg, 1.7e-4 rad), at a fraction of libm's cost: it is
/// most of what the Euler output costs per sample. The octant reduction
/// leaves `|t| <= tan(pi / 8)`, where `atan(t) / t` is a polynomial of degree
/// 5 in `t^2` ([`ATAN_POLY`]). Zeros, infinities and NaN go to libm.
#[inline]
pub fn atan2(y: f64, x: f64) -> f64 {
    use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};
    let (ax, ay) = (x.abs(), y.abs());
    let (num, den, swap) = if ay > ax { (ax, ay, true) } else { (ay, ax, false) };
    if !(den > 0.0 && den.is_finite()) {
        return y.atan2(x);
    }
    let z = num / den;
    let (t, off) = if z > TAN_PI_8 { ((z - 1.0) / (z + 1.0), FRAC_PI_4) } else { (z, 0.0) };
    let s = t * t;
    let s2 = s * s;
    let c = ATAN_POLY;
    // Estrin's scheme: three independent pairs, then two products
    let p = (c[0] + c[1] * s) + s2 * ((c[2] + c[3] * s) + s2 * (c[4] + c[5] * s));
    let mut a = off + t * p;
    if swap {
        a = FRAC_PI_2 - a;
    }
    if x.is_sign_negative() {
        a = PI - a;
    }
    if y.is_sign_negative() {
        -a
    } else {
        a
    }
}

/// `|v|`.
#[inline]
pub fn norm(v: &[f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// `C v`.
#[inline]
pub fn rotate(c: &Mat3, v: &[f64; 3]) -> [f64; 3] {
    [
        c[0][0] * v[0] + c[0][1] * v[1] + c[0][2] * v[2],
        c[1][0] * v[0] + c[1][1] * v[1] + c[1][2] * v[2],
        c[2][0] * v[0] + c[2][1] * v[1] + c[2][2] * v[2],
    ]
}

/// `C^T v`.
#[inline]
pub fn rotate_t(c: &Mat3, v: &[f64; 3]) -> [f64; 3] {
    [
        c[0][0] * v[0] + c[1][0] * v[1] + c[2][0] * v[2],
        c[0][1] * v[0] + c[1][1] * v[1] + c[2][1] * v[2],
        c[0][2] * v[0] + c[1][2] * v[1] + c[2][2] * v[2],
    ]
}

/// `A B`.
pub fn mat_mul(a: &Mat3, b: &Mat3) -> Mat3 {
    let mut m = [[0.0; 3]; 3];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
        }
    }
    m
}

#[inline]
pub fn cross(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

/// The matrix of Z-Y-X Euler angles (rad), `C_nb`.
pub fn matrix_from_euler(roll: f64, pitch: f64, yaw: f64) -> Mat3 {
    to_matrix(&from_euler(roll, pitch, yaw))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn euler_round_trip_and_matrix_agree() {
        for &(r, p, y) in &[(0.1, -0.2, 0.3), (3.0, 1.2, -2.9), (-1.5, -1.55, 0.0), (0.0, 0.0, 3.1)] {
            let q = from_euler(r, p, y);
            let e = euler(&to_matrix(&q));
            assert!((e[0] - r).abs() < 1e-9 && (e[1] - p).abs() < 1e-9 && (e[2] - y).abs() < 1e-9, "{e:?} vs {r} {p} {y}");
            // C_nb = Rz(y) Ry(p) Rx(r)
            let (sr, cr) = r.sin_cos();
            let (sp, cp) = p.sin_cos();
            let (sy, cy) = y.sin_cos();
            let want = [
                [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                [-sp, cp * sr, cp * cr],
            ];
            let c = to_matrix(&q);
            for i in 0..3 {
                for j in 0..3 {
                    assert!((c[i][j] - want[i][j]).abs() < 1e-12);
                }
            }
        }
    }

    #[test]
    fn atan2_is_within_2e_10_of_libm_everywhere() {
        // a dense sweep of directions and magnitudes, the axes, signed zeros
        let mut worst = 0.0f64;
        for k in 0..200_000 {
            let a = -std::f64::consts::PI + k as f64 * (2.0 * std::f64::consts::PI / 200_000.0);
            for r in [1e-300, 1e-8, 0.3, 1.0, 7.0, 1e12] {
                let (y, x) = (r * a.sin(), r * a.cos());
                worst = worst.max((atan2(y, x) - y.atan2(x)).abs());
            }
        }
        assert!(worst < 2e-10, "worst {worst:e}");
        for (y, x) in [
            (0.0, 1.0),
            (-0.0, 1.0),
            (0.0, -1.0),
            (-0.0, -1.0),
            (1.0, 0.0),
            (-1.0, -0.0),
            (0.0, 0.0),
            (-0.0, -0.0),
            (1.0, 1.0),
            (-1.0, -1.0),
        ] {
            assert!((atan2(y, x) - f64::atan2(y, x)).abs() < 2e-10, "({y}, {x})");
            assert_eq!(atan2(y, x).is_sign_negative(), f64::atan2(y, x).is_sign_negative(), "({y}, {x})");
        }
        assert!(atan2(f64::NAN, 1.0).is_nan() && atan2(1.0, f64::NAN).is_nan());
        assert_eq!(atan2(f64::INFINITY, 1.0), f64::atan2(f64::INFINITY, 1.0));
        assert_eq!(atan2(1.0, f64::NEG_INFINITY), f64::atan2(1.0, f64::NEG_INFINITY));
    }

    #[test]
    fn euler_pitch_is_accurate_near_vertical() {
        let h = std::f64::consts::FRAC_PI_2;
        for p in [h - 1e-4, h - 1e-5, -(h - 1e-7), 1.0e-9] {
            let e = euler(&matrix_from_euler(0.3, p, -0.7));
            assert!((e[1] - p).abs() < 1e-8, "{p}: {e:?}");
        }
    }

    #[test]
    fn the_series_matches_sin_and_cos_where_it_is_used() {
        for a in [1e-6, 1e-4, 3e-3, 0.0099] {
            let q = from_rotvec(&[a, 0.0, 0.0]);
            assert!((q[0] - (0.5 * a).cos()).abs() < 1e-15 && (q[1] - (0.5 * a).sin()).abs() < 1e-15, "{a}: {q:?}");
        }
    }

    #[test]
    fn rotation_vector_integration_is_exact_for_a_constant_rate() {
        // 1000 steps of 0.9 deg about a fixed axis = 900 deg about it
        let axis = [0.6, -0.0, 0.8];
        let step = 0.9f64.to_radians();
        let mut q = [1.0, 0.0, 0.0, 0.0];
        for _ in 0..1000 {
            q = mul(&q, &from_rotvec(&[axis[0] * step, axis[1] * step, axis[2] * step]));
            normalise(&mut q);
        }
        let want = from_rotvec(&[axis[0] * 5.0 * std::f64::consts::PI, 0.0, axis[2] * 5.0 * std::f64::consts::PI]);
        let c = to_matrix(&q);
        let w = to_matrix(&want);
        for i in 0..3 {
            for j in 0..3 {
                assert!((c[i][j] - w[i][j]).abs() < 1e-9);
            }
        }
    }
}
