//! The paper's 6-state extended Kalman filter: `x = [roll, pitch, yaw, b_p, b_q, b_r]`.
//!
//! Units inside: radians, rad/s, seconds. The gyro is the input; the process
//! model is the rigid-body Euler-angle kinematics with `w = omega - b` and a
//! constant bias (process noise lets it move; the thermal curve moves it by a
//! known amount per step). Measurements are roll/pitch from the accelerometer
//! and yaw from the magnetometer, `H = [I3 | 0]`.
//!
//! The covariance is kept in 3x3 blocks `[[Paa, Pab], [Pab^T, Pbb]]` because
//! `F = [[Fa, -G dt], [0, I]]` and `H = [I | 0]`: the block form does the same
//! arithmetic as the dense 6x6 one with a third of the multiplications.

use nalgebra::{Matrix3, Matrix6, Vector3, Vector6};
use std::f64::consts::PI;

/// Largest |pitch| the filter holds: the Euler-angle kinematics are singular
/// at 90 deg and the covariance is numerically meaningless well before it. A
/// ground vehicle never comes near; a state pushed there is clamped.
pub const PITCH_LIMIT: f64 = 85.0 * PI / 180.0;

/// Wrap an angle to (-pi, pi].
#[inline]
pub fn wrap_pi(a: f64) -> f64 {
    if a > -PI && a <= PI {
        return a;
    }
    let r = (a + PI).rem_euclid(2.0 * PI) - PI;
    if r == -PI {
        PI
    } else {
        r
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct Ekf {
    /// Angles [roll, pitch, yaw], rad.
    pub att: Vector3<f64>,
    /// Gyro bias [p, q, r], rad/s.
    pub bias: Vector3<f64>,
    pub paa: Matrix3<f64>,
    pub pab: Matrix3<f64>,
    pub pbb: Matrix3<f64>,
}

/// The matrix that maps body rates to Euler-angle rates.
#[inline]
pub fn euler_rate_matrix(roll: f64, pitch: f64) -> Matrix3<f64> {
    let (sp, cp) = roll.sin_cos();
    let (st, ct) = pitch.sin_cos();
    let tt = st / ct;
    Matrix3::new(1.0, sp * tt, cp * tt, 0.0, cp, -sp, 0.0, sp / ct, cp / ct)
}

/// The process model's continuous derivative of the state, `f(x, omega)`.
pub fn process_f(x: &Vector6<f64>, omega: &Vector3<f64>) -> Vector6<f64> {
    let w = omega - Vector3::new(x[3], x[4], x[5]);
    let d = euler_rate_matrix(x[0], x[1]) * w;
    Vector6::new(d[0], d[1], d[2], 0.0, 0.0, 0.0)
}

/// Analytic Jacobian `df/dx` of `process_f`.
pub fn process_jacobian(x: &Vector6<f64>, omega: &Vector3<f64>) -> Matrix6<f64> {
    let (aa, g) = angle_jacobian(x[0], x[1], &(omega - Vector3::new(x[3], x[4], x[5])));
    let mut j = Matrix6::zeros();
    j.fixed_view_mut::<3, 3>(0, 0).copy_from(&aa);
    j.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-g));
    j
}

/// `(d angle_dot / d angles, G)` for corrected rates `w`.
#[inline]
fn angle_jacobian(roll: f64, pitch: f64, w: &Vector3<f64>) -> (Matrix3<f64>, Matrix3<f64>) {
    let (sp, cp) = roll.sin_cos();
    let (st, ct) = pitch.sin_cos();
    let tt = st / ct;
    let (wq, wr) = (w[1], w[2]);
    let a = sp * wq + cp * wr; // sin(phi) wq + cos(phi) wr
    let b = cp * wq - sp * wr; // cos(phi) wq - sin(phi) wr
    let c2 = ct * ct;
    let aa = Matrix3::new(b * tt, a / c2, 0.0, -a, 0.0, 0.0, b / ct, a * st / c2, 0.0);
    let g = Matrix3::new(1.0, sp * tt, cp * tt, 0.0, cp, -sp, 0.0, sp / ct, cp / ct);
    (aa, g)
}

/// Which parts of the state a measurement update may move.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Learn {
    /// Angles and bias (full EKF update).
    AnglesAndBias,
    /// Angles only; the bias and its covariance are left as they are.
    AnglesOnly,
}

impl Ekf {
    pub fn new(att: Vector3<f64>, bias: Vector3<f64>, angle_sigma: f64, bias_sigma: f64) -> Ekf {
        Ekf {
            att,
            bias,
            paa: Matrix3::from_diagonal_element(angle_sigma * angle_sigma),
            pab: Matrix3::zeros(),
            pbb: Matrix3::from_diagonal_element(bias_sigma * bias_sigma),
        }
    }

    pub fn state(&self) -> Vector6<f64> {
        Vector6::new(self.att[0], self.att[1], self.att[2], self.bias[0], self.bias[1], self.bias[2])
    }

    /// The full 6x6 covariance.
    pub fn covariance(&self) -> Matrix6<f64> {
        let mut p = Matrix6::zeros();
        p.fixed_view_mut::<3, 3>(0, 0).copy_from(&self.paa);
        p.fixed_view_mut::<3, 3>(0, 3).copy_from(&self.pab);
        p.fixed_view_mut::<3, 3>(3, 0).copy_from(&self.pab.transpose());
        p.fixed_view_mut::<3, 3>(3, 3).copy_from(&self.pbb);
        p
    }

    /// Predict over `dt` with gyro `omega` (rad/s). `q_gyro` is the gyro
    /// white-noise variance rate (rad^2/s), `q_bias` the bias random-walk
    /// variance rate ((rad/s)^2/s), `dbias` the thermal curve's change of the
    /// bias over the step (rad/s).
    pub fn predict(&mut self, omega: &Vector3<f64>, dt: f64, q_gyro: f64, q_bias: f64, dbias: &Vector3<f64>) {
        let w = omega - self.bias;
        let (aa, g) = angle_jacobian(self.att[0], self.att[1], &w);
        let rate = g * w;
        // Covariance with the Jacobians at the prior state.
        let fa = Matrix3::identity() + aa * dt;
        let fb = g * (-dt);
        let m = fa * self.paa + fb * self.pab.transpose();
        let n = fa * self.pab + fb * self.pbb;
        let mut paa = m * fa.transpose() + n * fb.transpose();
        paa += (g * g.transpose()) * (q_gyro * dt);
        self.paa = symmetric(&paa);
        self.pab = n;
        self.pbb += Matrix3::from_diagonal_element(q_bias * dt);
        // State.
        self.att += rate * dt;
        self.bias += dbias;
        self.normalise_angles();
    }

    /// Measurement update with `z = [roll, pitch, yaw]` (rad) and diagonal
    /// noise variances `r`. With `yaw == false` only roll and pitch are used.
    /// Returns the innovation (rad) and the normalised innovation squared.
    pub fn update(&mut self, z: &Vector3<f64>, r: &Vector3<f64>, yaw: bool, learn: Learn) -> (Vector3<f64>, f64) {
        let mut nu = Vector3::new(wrap_pi(z[0] - self.att[0]), z[1] - self.att[1], wrap_pi(z[2] - self.att[2]));
        let mut s = self.paa + Matrix3::from_diagonal(r);
        // P H^T, split into the angle rows and the bias rows.
        let mut pa = self.paa;
        let mut pb = self.pab.transpose();
        if !yaw {
            nu[2] = 0.0;
            for k in 0..3 {
                s[(2, k)] = 0.0;
                s[(k, 2)] = 0.0;
                pa[(k, 2)] = 0.0;
                pb[(k, 2)] = 0.0;
            }
            s[(2, 2)] = 1.0;
        }
        let si = match s.try_inverse() {
            Some(si) => si,
            None => return (nu, f64::INFINITY),
        };
        let nis = (nu.transpose() * si * nu)[0];
        let ka = pa * si;
        self.att += ka * nu;
        // Joseph form, (I - K H) P (I - K H)^T + K R K^T, in blocks: it keeps P
        // symmetric positive definite even where the Euler kinematics make it
        // badly conditioned (pitch near its limit), and it is exact for the
        // angles-only gain K = [Ka; 0] as well.
        let h = mask_h(yaw);
        let rm = Matrix3::from_diagonal(&masked_r(r, yaw));
        let a = Matrix3::identity() - ka * h;
        let kar = ka * rm;
        match learn {
            Learn::AnglesAndBias => {
                let kb = pb * si;
                self.bias += kb * nu;
                let kbh = kb * h;
                let apaa = a * self.paa;
                let paa = apaa * a.transpose() + kar * ka.transpose();
                let pab = a * self.pab - apaa * kbh.transpose() + kar * kb.transpose();
                let pbh = self.pab.transpose() * kbh.transpose();
                let pbb = self.pbb - pbh - pbh.transpose() + kbh * self.paa * kbh.transpose() + kb * rm * kb.transpose();
                self.paa = symmetric(&paa);
                self.pab = pab;
                self.pbb = symmetric(&pbb);
            }
            Learn::AnglesOnly => {
                self.paa = symmetric(&(a * self.paa * a.transpose() + kar * ka.transpose()));
                self.pab = a * self.pab;
            }
        }
        self.normalise_angles();
        (nu, nis)
    }

    /// Inflate the angle variances (after a gap or a resync).
    pub fn inflate_angles(&mut self, var: f64) {
        self.paa += Matrix3::from_diagonal_element(var);
    }

    fn normalise_angles(&mut self) {
        self.att[0] = wrap_pi(self.att[0]);
        self.att[1] = self.att[1].clamp(-PITCH_LIMIT, PITCH_LIMIT);
        self.att[2] = wrap_pi(self.att[2]);
    }

    /// The six state values are finite (what reaches the bus). A non-finite
    /// covariance reaches the state at the next update, so checking the state
    /// every step catches it one step later at the latest.
    #[inline]
    pub fn state_is_finite(&self) -> bool {
        let mut ok = true;
        for v in self.att.iter().chain(self.bias.iter()) {
            ok &= v.is_finite();
        }
        ok
    }

    /// Every value of the state and covariance is finite. A NaN or an
    /// infinity anywhere makes the plain sum non-finite, so one pass of adds
    /// (which the compiler vectorises) answers it.
    pub fn is_finite(&self) -> bool {
        let mut s = 0.0;
        for v in self.att.iter().chain(self.bias.iter()) {
            s += *v;
        }
        for m in [&self.paa, &self.pab, &self.pbb] {
            for v in m.as_slice() {
                s += *v;
            }
        }
        s.is_finite()
    }
}

#[inline]
fn symmetric(m: &Matrix3<f64>) -> Matrix3<f64> {
    (m + m.transpose()) * 0.5
}

#[inline]
fn mask_h(yaw: bool) -> Matrix3<f64> {
    Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, if yaw { 1.0 } else { 0.0 }))
}

#[inline]
fn masked_r(r: &Vector3<f64>, yaw: bool) -> Vector3<f64> {
    Vector3::new(r[0], r[1], if yaw { r[2] } else { 0.0 })
}

/// Roll and pitch (rad) from specific force in FRD (a level, resting unit reads (0, 0, -1)).
#[inline]
pub fn tilt_from_accel(f: &[f64; 3]) -> (f64, f64) {
    let roll = (-f[1]).atan2(-f[2]);
    let pitch = f[0].atan2((f[1] * f[1] + f[2] * f[2]).sqrt());
    (roll, pitch)
}

/// Tilt-compensated magnetic heading (rad, not wrapped) from the body field
/// `m` at the given roll and pitch.
#[inline]
pub fn heading_from_mag(m: &[f64; 3], roll: f64, pitch: f64) -> f64 {
    let (sp, cp) = roll.sin_cos();
    let (st, ct) = pitch.sin_cos();
    heading_from_mag_trig(m, [sp, cp, st, ct])
}

/// `heading_from_mag` with `[sin roll, cos roll, sin pitch, cos pitch]` given.
#[inline]
pub fn heading_from_mag_trig(m: &[f64; 3], [sp, cp, st, ct]: [f64; 4]) -> f64 {
    let xh = m[0] * ct + m[1] * sp * st + m[2] * cp * st;
    let yh = m[1] * cp - m[2] * sp;
    (-yh).atan2(xh)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jacobian_matches_finite_differences() {
        let cases = [
            (Vector6::new(0.1, -0.2, 0.3, 0.01, -0.02, 0.005), Vector3::new(0.3, -0.1, 0.2)),
            (Vector6::new(-1.0, 0.7, -2.5, -0.05, 0.0, 0.02), Vector3::new(-0.5, 0.9, -0.4)),
            (Vector6::new(2.9, -1.3, 1.0, 0.0, 0.0, 0.0), Vector3::new(0.0, 0.0, 1.0)),
        ];
        for (x, om) in cases {
            let j = process_jacobian(&x, &om);
            for k in 0..6 {
                let h = 1e-6;
                let mut xp = x;
                let mut xm = x;
                xp[k] += h;
                xm[k] -= h;
                let col = (process_f(&xp, &om) - process_f(&xm, &om)) / (2.0 * h);
                for i in 0..6 {
                    assert!((col[i] - j[(i, k)]).abs() < 1e-6 * (1.0 + col[i].abs()), "d f{i}/d x{k}: fd {} vs {}", col[i], j[(i, k)]);
                }
            }
        }
    }

    #[test]
    fn measurement_jacobian_is_identity_block() {
        // h(x) = angles: finite differences of h give [I | 0].
        let x = Vector6::new(0.2, 0.1, -0.3, 0.01, 0.02, 0.03);
        let h = |x: &Vector6<f64>| Vector3::new(x[0], x[1], x[2]);
        for k in 0..6 {
            let mut xp = x;
            xp[k] += 1e-6;
            let d = (h(&xp) - h(&x)) / 1e-6;
            for i in 0..3 {
                let want = if i == k { 1.0 } else { 0.0 };
                assert!((d[i] - want).abs() < 1e-6);
            }
        }
    }

    #[test]
    fn block_covariance_matches_dense_form() {
        let mut e = Ekf::new(Vector3::new(0.1, 0.2, 0.3), Vector3::new(0.01, -0.01, 0.02), 0.1, 0.01);
        e.pab = Matrix3::new(1e-4, 2e-5, 0.0, 0.0, 3e-5, 1e-5, 2e-5, 0.0, 1e-4);
        let p0 = e.covariance();
        let om = Vector3::new(0.4, -0.3, 0.2);
        let dt = 0.005;
        let x0 = e.state();
        let f = Matrix6::identity() + process_jacobian(&x0, &om) * dt;
        e.predict(&om, dt, 0.0, 0.0, &Vector3::zeros());
        let dense = f * p0 * f.transpose();
        let p1 = e.covariance();
        for (a, b) in dense.iter().zip(p1.iter()) {
            assert!((a - b).abs() < 1e-12, "{a} vs {b}");
        }
        // Dense Kalman update against the block one.
        let r = Vector3::new(1e-4, 2e-4, 3e-4);
        let z = Vector3::new(0.12, 0.18, 0.33);
        let mut hm = nalgebra::Matrix3x6::zeros();
        hm.fixed_view_mut::<3, 3>(0, 0).copy_from(&Matrix3::identity());
        let s = hm * p1 * hm.transpose() + Matrix3::from_diagonal(&r);
        let k = p1 * hm.transpose() * s.try_inverse().unwrap();
        let x_before = e.state();
        let nu = z - Vector3::new(x_before[0], x_before[1], x_before[2]);
        let x_dense = x_before + k * nu;
        let p_dense = (Matrix6::identity() - k * hm) * p1;
        e.update(&z, &r, true, Learn::AnglesAndBias);
        for (a, b) in x_dense.iter().zip(e.state().iter()) {
            assert!((a - b).abs() < 1e-12);
        }
        for (a, b) in p_dense.iter().zip(e.covariance().iter()) {
            assert!((a - b).abs() < 1e-12);
        }
    }

    #[test]
    fn tilt_and_heading_conventions() {
        // Level: (0,0,-1) -> roll 0, pitch 0.
        let (r, p) = tilt_from_accel(&[0.0, 0.0, -1.0]);
        assert!(r.abs() < 1e-12 && p.abs() < 1e-12);
        // Nose up 10 deg: f = (sin th, 0, -cos th).
        let th = 10f64.to_radians();
        let (r, p) = tilt_from_accel(&[th.sin(), 0.0, -th.cos()]);
        assert!(r.abs() < 1e-12 && (p - th).abs() < 1e-12);
        // Right wing down 20 deg: f = (0, -sin phi, -cos phi).
        let ph = 20f64.to_radians();
        let (r, _) = tilt_from_accel(&[0.0, -ph.sin(), -ph.cos()]);
        assert!((r - ph).abs() < 1e-12);
        // Heading 30 deg, level: m_b = (mN cos psi, -mN sin psi, mD).
        let psi = 30f64.to_radians();
        let h = heading_from_mag(&[0.2 * psi.cos(), -0.2 * psi.sin(), 0.4], 0.0, 0.0);
        assert!((h - psi).abs() < 1e-12);
    }

    #[test]
    fn is_finite_sees_any_nan_or_infinity() {
        let e = Ekf::new(Vector3::new(0.1, 0.2, 0.3), Vector3::zeros(), 0.1, 0.01);
        assert!(e.is_finite());
        for k in 0..33 {
            for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                let mut f = e.clone();
                match k {
                    0..=2 => f.att[k] = bad,
                    3..=5 => f.bias[k - 3] = bad,
                    6..=14 => f.paa[k - 6] = bad,
                    15..=23 => f.pab[k - 15] = bad,
                    _ => f.pbb[k - 24] = bad,
                }
                assert!(!f.is_finite(), "value {k} = {bad}");
            }
        }
    }

    #[test]
    fn wrap() {
        assert!((wrap_pi(3.0 * PI) - PI).abs() < 1e-12);
        assert!((wrap_pi(-3.5 * PI) - 0.5 * PI).abs() < 1e-12);
        assert_eq!(wrap_pi(0.3), 0.3);
    }
}
