//! The tilt filter of `mode = "robust"`: roll, pitch, the x/y gyro bias and
//! the forward speed of a ground vehicle. Pure: plain arrays, no I/O, no
//! allocation.
//!
//! Model (body FRD, specific force `f` in g, `G` = 1 g in m/s^2). A ground
//! vehicle moves along its body x axis (non-holonomic: no sideslip, no lift),
//! so its acceleration in the body frame is `omega x (v, 0, 0) + (dv/dt, 0, 0)
//! = (dv/dt, v r, -v q)` and
//!
//! ```text
//! f_x = (dv/dt) / G + sin(pitch)
//! f_y = v r / G     - sin(roll) cos(pitch)
//! ```
//!
//! The gyro drives roll and pitch; `f_x` drives the speed,
//! `dv/dt = G (f_x - sin(pitch))`; `f_y` is a measurement that holds on a
//! straight (it is the roll, whatever the vehicle's speed changes) and in a
//! turn (the centripetal `v r` is predicted from the speed the filter holds).
//! A pitch error makes the speed drift, and the next turn shows that drift in
//! `f_y`: pitch is observable through turns, roll always. The vertical axis
//! is not used: suspension pitch rates would read as `-v q` there.
//!
//! State `x = [roll, pitch, b_x, b_y, v]` (rad, rad, rad/s, rad/s, m/s). The
//! z bias belongs to the yaw filter and is passed in.

/// 1 g, m/s^2.
pub const G: f64 = 9.80665;
const PITCH_LIMIT: f64 = crate::ekf::PITCH_LIMIT;

pub const ROLL: usize = 0;
pub const PITCH: usize = 1;
pub const BX: usize = 2;
pub const BY: usize = 3;
pub const SPEED: usize = 4;

#[derive(Clone, Debug, PartialEq)]
pub struct VehicleTilt {
    pub x: [f64; 5],
    pub p: [[f64; 5]; 5],
    /// `[sin roll, cos roll, sin pitch, cos pitch]` of `x`, kept in step
    /// with it (every step needs them; computed once).
    pub trig: [f64; 4],
}

#[inline]
fn trig_of(roll: f64, pitch: f64) -> [f64; 4] {
    let (sp, cp) = roll.sin_cos();
    let (st, ct) = pitch.sin_cos();
    [sp, cp, st, ct]
}

/// Noise of the process model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProcessNoise {
    /// Gyro white noise, rad^2/s.
    pub gyro: f64,
    /// Bias random walk, (rad/s)^2/s.
    pub bias: f64,
    /// Speed random walk (accelerometer noise and model error), (m/s)^2/s.
    pub speed: f64,
}

/// What a scalar update did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Update {
    /// Applied, with its normalised innovation squared.
    Fused(f64),
    /// Refused by the innovation gate, with its normalised innovation squared.
    Gated(f64),
}

impl VehicleTilt {
    /// Start at `roll`, `pitch` (rad) with the bias `b` (rad/s) and speed `v`;
    /// 1-sigma values of the angles, the bias and the speed.
    pub fn new(roll: f64, pitch: f64, b: [f64; 2], v: f64, sigma: [f64; 3]) -> VehicleTilt {
        let mut p = [[0.0; 5]; 5];
        p[ROLL][ROLL] = sigma[0] * sigma[0];
        p[PITCH][PITCH] = sigma[0] * sigma[0];
        p[BX][BX] = sigma[1] * sigma[1];
        p[BY][BY] = sigma[1] * sigma[1];
        p[SPEED][SPEED] = sigma[2] * sigma[2];
        VehicleTilt { x: [roll, pitch, b[0], b[1], v], p, trig: trig_of(roll, pitch) }
    }

    /// Predict over `dt` with the gyro `omega` (rad/s), the z bias `bz`
    /// (rad/s), the measured `f_x` (g) and the thermal curve's change of
    /// the x/y bias over the step `db` (rad/s).
    #[inline]
    pub fn predict(&mut self, omega: &[f64; 3], bz: f64, fx: f64, dt: f64, q: &ProcessNoise, db: [f64; 2]) {
        let [phi, th, bx, by, _] = self.x;
        let wx = omega[0] - bx;
        let wy = omega[1] - by;
        let wz = omega[2] - bz;
        let [sp, cp, st, ct] = self.trig;
        let ct = ct.max(1e-3);
        let tt = st / ct;
        let a = sp * wy + cp * wz;
        let roll_rate = wx + tt * a;
        let pitch_rate = cp * wy - sp * wz;
        // F = I + A dt; the non-zero entries of A:
        let a00 = tt * (cp * wy - sp * wz);
        let a01 = a / (ct * ct);
        let a03 = -sp * tt;
        let a10 = -a;
        let a13 = -cp;
        let a41 = -G * ct;
        // P = F P F^T + Q, written out for the sparse F (rows 2 and 3 are identity).
        let p = &self.p;
        // M = F P (rows of F times P)
        let mut m = [[0.0; 5]; 5];
        for j in 0..5 {
            m[0][j] = p[0][j] + dt * (a00 * p[0][j] + a01 * p[1][j] - p[2][j] + a03 * p[3][j]);
            m[1][j] = p[1][j] + dt * (a10 * p[0][j] + a13 * p[3][j]);
            m[2][j] = p[2][j];
            m[3][j] = p[3][j];
            m[4][j] = p[4][j] + dt * a41 * p[1][j];
        }
        // P' = M F^T
        let mut n = [[0.0; 5]; 5];
        for i in 0..5 {
            let r = &m[i];
            n[i][0] = r[0] + dt * (a00 * r[0] + a01 * r[1] - r[2] + a03 * r[3]);
            n[i][1] = r[1] + dt * (a10 * r[0] + a13 * r[3]);
            n[i][2] = r[2];
            n[i][3] = r[3];
            n[i][4] = r[4] + dt * a41 * r[1];
        }
        let qa = q.gyro * dt;
        n[0][0] += qa * (1.0 + tt * tt);
        n[1][1] += qa;
        n[2][2] += q.bias * dt;
        n[3][3] += q.bias * dt;
        n[4][4] += q.speed * dt;
        self.p = n;
        self.x[ROLL] = crate::ekf::wrap_pi(phi + roll_rate * dt);
        self.x[PITCH] = (th + pitch_rate * dt).clamp(-PITCH_LIMIT, PITCH_LIMIT);
        self.x[BX] += db[0];
        self.x[BY] += db[1];
        self.x[SPEED] += G * (fx - st) * dt;
        self.trig = trig_of(self.x[ROLL], self.x[PITCH]);
    }

    /// Scalar measurement update: innovation `nu`, row `h` of the Jacobian,
    /// noise variance `r`. Refused when the normalised innovation squared
    /// exceeds `gate`. With `learn_bias == false` the gain to the bias is
    /// zero (Joseph form keeps the covariance right for that gain).
    pub fn update(&mut self, nu: f64, h: &[f64; 5], r: f64, learn_bias: bool, gate: f64) -> Update {
        let mut ph = [0.0; 5];
        for (i, v) in ph.iter_mut().enumerate() {
            *v = (0..5).map(|j| self.p[i][j] * h[j]).sum();
        }
        let s: f64 = (0..5).map(|j| h[j] * ph[j]).sum::<f64>() + r;
        if s.is_nan() || s <= 0.0 {
            return Update::Gated(f64::INFINITY);
        }
        let nis = nu * nu / s;
        if nis > gate {
            return Update::Gated(nis);
        }
        let mut k = [0.0; 5];
        for i in 0..5 {
            k[i] = ph[i] / s;
        }
        if !learn_bias {
            k[BX] = 0.0;
            k[BY] = 0.0;
        }
        for i in 0..5 {
            self.x[i] += k[i] * nu;
        }
        self.x[ROLL] = crate::ekf::wrap_pi(self.x[ROLL]);
        self.x[PITCH] = self.x[PITCH].clamp(-PITCH_LIMIT, PITCH_LIMIT);
        self.trig = trig_of(self.x[ROLL], self.x[PITCH]);
        // Joseph form: P = A P A^T + r k k^T, A = I - k h^T.
        let mut hp = [0.0; 5];
        for (j, v) in hp.iter_mut().enumerate() {
            *v = (0..5).map(|l| h[l] * self.p[l][j]).sum();
        }
        let mut ap = [[0.0; 5]; 5];
        for i in 0..5 {
            for j in 0..5 {
                ap[i][j] = self.p[i][j] - k[i] * hp[j];
            }
        }
        let mut np = [[0.0; 5]; 5];
        for i in 0..5 {
            for j in 0..5 {
                let aph: f64 = (0..5).map(|l| ap[i][l] * h[l]).sum();
                np[i][j] = ap[i][j] - aph * k[j] + r * k[i] * k[j];
            }
        }
        for i in 0..5 {
            for j in 0..i {
                let v = 0.5 * (np[i][j] + np[j][i]);
                np[i][j] = v;
                np[j][i] = v;
            }
        }
        self.p = np;
        Update::Fused(nis)
    }

    /// `f_y` measurement: the predicted lateral specific force (g) at body
    /// z rate `r` (rad/s) and its Jacobian row.
    #[inline]
    pub fn lateral(&self, r: f64) -> (f64, [f64; 5]) {
        let [sp, cp, st, ct] = self.trig;
        let h = self.x[SPEED] * r / G - sp * ct;
        (h, [-cp * ct, sp * st, 0.0, 0.0, r / G])
    }

    /// `f_x` as a pitch measurement (a vehicle at constant speed): the
    /// predicted longitudinal specific force (g) and its Jacobian row.
    #[inline]
    pub fn longitudinal(&self) -> (f64, [f64; 5]) {
        let [_, _, st, ct] = self.trig;
        (st, [0.0, ct, 0.0, 0.0, 0.0])
    }

    /// Widen the angle variances (after a gap, or to re-level).
    pub fn inflate_angles(&mut self, var: f64) {
        self.p[ROLL][ROLL] += var;
        self.p[PITCH][PITCH] += var;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn q() -> ProcessNoise {
        ProcessNoise { gyro: 1e-6, bias: 1e-12, speed: 0.01 }
    }

    /// The covariance predict equals F P F^T + Q with F from finite
    /// differences of the state predict.
    #[test]
    fn predict_covariance_matches_finite_difference_jacobian() {
        let mut base = VehicleTilt::new(0.3, -0.2, [0.01, -0.02], 12.0, [0.1, 0.01, 3.0]);
        // some correlation
        base.p[0][4] = 0.05;
        base.p[4][0] = 0.05;
        base.p[1][3] = -0.0005;
        base.p[3][1] = -0.0005;
        let omega = [0.2, -0.3, 0.4];
        let (bz, fx, dt) = (0.01, 0.1, 0.01);
        let step = |x: [f64; 5]| {
            let mut t = base.clone();
            t.x = x;
            t.trig = trig_of(x[0], x[1]);
            t.predict(&omega, bz, fx, dt, &ProcessNoise { gyro: 0.0, bias: 0.0, speed: 0.0 }, [0.0; 2]);
            t.x
        };
        let mut f = [[0.0; 5]; 5];
        for j in 0..5 {
            // step scaled to the value, so round-off stays below the tolerance
            let e = 1e-6 * base.x[j].abs().max(1.0);
            let mut xp = base.x;
            xp[j] += e;
            let mut xm = base.x;
            xm[j] -= e;
            let (a, b) = (step(xp), step(xm));
            for i in 0..5 {
                f[i][j] = (a[i] - b[i]) / (2.0 * e);
            }
        }
        let mut want = [[0.0; 5]; 5];
        for i in 0..5 {
            for j in 0..5 {
                for k in 0..5 {
                    for l in 0..5 {
                        want[i][j] += f[i][k] * base.p[k][l] * f[j][l];
                    }
                }
            }
        }
        let mut got = base.clone();
        got.predict(&omega, bz, fx, dt, &ProcessNoise { gyro: 0.0, bias: 0.0, speed: 0.0 }, [0.0; 2]);
        for i in 0..5 {
            for j in 0..5 {
                assert!(
                    (got.p[i][j] - want[i][j]).abs() < 1e-9 * (1.0 + want[i][j].abs()),
                    "P[{i}][{j}] {} vs {}",
                    got.p[i][j],
                    want[i][j]
                );
            }
        }
    }

    /// The lateral Jacobian row matches finite differences of the model.
    #[test]
    fn lateral_row_matches_finite_differences() {
        let t = VehicleTilt::new(0.2, 0.1, [0.0; 2], 15.0, [0.1, 0.01, 3.0]);
        let r = 0.3;
        let (_, h) = t.lateral(r);
        for j in 0..5 {
            let e = 1e-6;
            let mut a = t.clone();
            a.x[j] += e;
            a.trig = trig_of(a.x[0], a.x[1]);
            let mut b = t.clone();
            b.x[j] -= e;
            b.trig = trig_of(b.x[0], b.x[1]);
            let d = (a.lateral(r).0 - b.lateral(r).0) / (2.0 * e);
            assert!((d - h[j]).abs() < 1e-8, "column {j}: {d} vs {}", h[j]);
        }
    }

    /// A turn at constant speed with a roll the accelerometer alone would get
    /// wrong by the centripetal acceleration: the filter learns the speed
    /// and holds the roll.
    #[test]
    fn turn_at_speed_is_not_read_as_roll() {
        let (v, r, roll) = (20.0, 0.2, 2.0f64.to_radians());
        let fy = v * r / G - roll.sin();
        let fz = -roll.cos();
        // what the accelerometer alone says
        let naive = (-fy).atan2(-fz);
        assert!((naive - roll).abs() > 20f64.to_radians());
        let mut t = VehicleTilt::new(roll, 0.0, [0.0; 2], 0.0, [1f64.to_radians(), 1e-4, 10.0]);
        let dt = 0.005;
        for k in 0..4000 {
            // body rates of a level-ish turn: the yaw rate appears on z (and y via roll)
            let omega = [0.0, roll.sin() * r, roll.cos() * r];
            t.predict(&omega, 0.0, 0.0, dt, &q(), [0.0; 2]);
            if k % 100 == 0 {
                let (h, row) = t.lateral(omega[2]);
                let fy = v * omega[2] / G - roll.sin();
                let u = t.update(fy - h, &row, 0.01f64.powi(2), false, 1e9);
                assert!(matches!(u, Update::Fused(_)));
            }
        }
        assert!((t.x[ROLL] - roll).abs() < 0.5f64.to_radians(), "roll {}", t.x[ROLL].to_degrees());
        assert!((t.x[SPEED] - v).abs() < 2.0, "speed {}", t.x[SPEED]);
    }

    /// A pitch error makes the speed drift, and a turn then shows it.
    #[test]
    fn pitch_error_is_found_through_a_turn() {
        let truth_pitch = 0.0f64;
        let mut t = VehicleTilt::new(0.0, 3f64.to_radians(), [0.0; 2], 10.0, [3f64.to_radians(), 1e-5, 1.0]);
        let dt = 0.005;
        let v = 10.0;
        for k in 0..12000 {
            let tt = k as f64 * dt;
            let r = if tt > 20.0 { 0.15 } else { 0.0 };
            let fx = truth_pitch.sin();
            t.predict(&[0.0, 0.0, r], 0.0, fx, dt, &q(), [0.0; 2]);
            if k % 100 == 0 {
                let (h, row) = t.lateral(r);
                let fy = v * r / G;
                t.update(fy - h, &row, 0.01f64.powi(2), false, 1e9);
            }
        }
        assert!(t.x[PITCH].abs() < 0.5f64.to_radians(), "pitch {}", t.x[PITCH].to_degrees());
    }

    #[test]
    fn zero_bias_gain_leaves_the_bias_alone() {
        let mut t = VehicleTilt::new(0.0, 0.0, [0.01, 0.02], 0.0, [0.1, 0.01, 1.0]);
        t.p[0][2] = 0.0005;
        t.p[2][0] = 0.0005;
        let (h, row) = t.lateral(0.0);
        assert!(matches!(t.update(0.05 - h, &row, 1e-4, false, 1e9), Update::Fused(_)));
        assert_eq!(t.x[BX], 0.01);
        assert_eq!(t.x[BY], 0.02);
        let (h, row) = t.lateral(0.0);
        assert!(matches!(t.update(0.05 - h, &row, 1e-4, true, 1e9), Update::Fused(_)));
        assert!(t.x[BX] != 0.01);
        // a gate refuses
        let (h, row) = t.lateral(0.0);
        assert!(matches!(t.update(10.0 - h, &row, 1e-4, true, 9.0), Update::Gated(_)));
    }
}
