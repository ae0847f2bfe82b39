//! Road kinematics: a ground vehicle on a 3-D road, seen by a sensor at a
//! lever arm from the rear-axle centre.
//!
//! - The rear-axle centre `P` moves along the road tangent
//!   `t = (cos g cos psi, cos g sin psi, -sin g)` (NED) with the signed speed
//!   `v` (negative when reversing): no lateral or vertical velocity at `P`
//!   apart from what the suspension angles below add relative to the body.
//!   `dv/dt = g0 a_long(t)`, `dpsi/dt = yaw_rate(t)` (commands), and the
//!   grade `g(s)` is a function of the distance `s` travelled, so a hill
//!   stays where it is while the car stands.
//! - Body attitude, Z-Y-X Euler: yaw `psi`; pitch = grade + road unevenness
//!   (distance) + squat/dive `pitch_per_long * a_long`; roll = camber and
//!   unevenness (distance) + lean `roll_per_lat * v * yaw_rate / g0`. The
//!   road frame `Rz(psi) Ry(grade)` composed with the suspension rotation is
//!   exactly this Euler triple, so `P`'s velocity in the body deviates from
//!   body x only by the suspension angles (about 1 deg: what the vehicle
//!   constraint's sigma is for).
//! - Body rates `w = E(roll, pitch)^-1 [roll', pitch', psi']` and their
//!   derivative `w'` are analytic (the profiles' first and second
//!   derivatives, chain rule through `s' = v`).
//! - The sensor at lever arm `l` (body axes, m, from `P`):
//!   `v_S = v_P + C_nb (w x l)`, `a_S = a_P + C_nb (w' x l + w x (w x l))`,
//!   specific force `f = C_bn (a_S - g_n) / g0`, plus road vibration (speed
//!   dependent, zero mean; it is in `f` but not in `a_S`/`v_S`).

use super::motion::{c_nb, to_body, to_ned, wrap180, Ease, MotionSpec, Sine, Truth, G};
use std::f64::consts::PI;

const D2R: f64 = PI / 180.0;
const R2D: f64 = 180.0 / PI;

/// Road vibration at the sensor: tones whose amplitude grows with speed
/// (zero at standstill, full from `v_ref`).
#[derive(Clone, Debug, Default)]
pub struct RoadVibration {
    /// `(frequency Hz, phase rad, amplitude [x, y, z] g)`.
    pub tones: Vec<(f64, f64, [f64; 3])>,
    /// Speed from which the amplitude is full, m/s.
    pub v_ref: f64,
}

impl RoadVibration {
    /// Vibration specific force at `t` and speed `v`, g.
    pub fn eval(&self, t: f64, v: f64) -> [f64; 3] {
        let mut out = [0.0; 3];
        if self.tones.is_empty() || self.v_ref <= 0.0 {
            return out;
        }
        let m = (v.abs() / self.v_ref).min(1.0);
        if m == 0.0 {
            return out;
        }
        for (f, ph, a) in &self.tones {
            let s = (2.0 * PI * f * t + ph).sin() * m;
            for k in 0..3 {
                out[k] += a[k] * s;
            }
        }
        out
    }
}

/// What the road model adds to a [`MotionSpec`]; the spec's `a_long`, `v0`,
/// `yaw0`, `roll_per_lat`, `pitch_per_long`, `thermal` and `duration` are used.
#[derive(Clone, Debug, Default)]
pub struct RoadSpec {
    /// Yaw-rate command (the Euler yaw rate), deg/s.
    pub yaw_rate: Ease,
    /// Road grade, deg, as sines of the distance (`freq` in cycles per metre).
    pub grade: Vec<Sine>,
    /// Body pitch from road unevenness, deg, sines of the distance.
    pub road_pitch: Vec<Sine>,
    /// Body roll from camber and unevenness, deg, sines of the distance.
    pub road_roll: Vec<Sine>,
    /// Sensor position from the rear-axle centre, body axes (FRD), m.
    pub lever_arm: [f64; 3],
    pub vibration: RoadVibration,
}

fn sum2(s: &[Sine], x: f64) -> (f64, f64, f64) {
    s.iter().fold((0.0, 0.0, 0.0), |a, w| {
        let (v, d, dd) = w.eval2(x);
        (a.0 + v, a.1 + d, a.2 + dd)
    })
}

pub fn cross(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

/// Euler angles (rad) with their first and second time derivatives.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EulerMotion {
    pub angle: [f64; 3],
    pub rate: [f64; 3],
    pub accel: [f64; 3],
}

impl EulerMotion {
    /// Body rates `[p, q, r]` and their time derivative, rad/s and rad/s^2.
    pub fn body_rates(&self) -> ([f64; 3], [f64; 3]) {
        let [phi, th, _] = self.angle;
        let [dphi, dth, dpsi] = self.rate;
        let [ddphi, ddth, ddpsi] = self.accel;
        let (sf, cf) = phi.sin_cos();
        let (st, ct) = th.sin_cos();
        let w = [dphi - st * dpsi, cf * dth + sf * ct * dpsi, -sf * dth + cf * ct * dpsi];
        let wd = [
            ddphi - ct * dth * dpsi - st * ddpsi,
            -sf * dphi * dth + cf * ddth + cf * dphi * ct * dpsi - sf * st * dth * dpsi + sf * ct * ddpsi,
            -cf * dphi * dth - sf * ddth - sf * dphi * ct * dpsi - cf * st * dth * dpsi + cf * ct * ddpsi,
        ];
        (w, wd)
    }
}

impl RoadSpec {
    /// Euler motion and the grade (rad, and its time derivative) at time `t`,
    /// signed speed `v` (m/s), heading `psi` (rad), distance `s` (m).
    pub fn euler(&self, spec: &MotionSpec, t: f64, v: f64, psi: f64, s: f64) -> (EulerMotion, f64, f64) {
        let (al, al1, al2) = spec.a_long.eval2(t);
        let (vd, vdd) = (G * al, G * al1);
        let (r0, r1, r2) = self.yaw_rate.eval2(t);
        let (r0, r1, r2) = (r0 * D2R, r1 * D2R, r2 * D2R);
        let (g0, g1, g2) = sum2(&self.grade, s);
        let (p0, p1, p2) = sum2(&self.road_pitch, s);
        let (b0, b1, b2) = sum2(&self.road_roll, s);
        // distance profiles: x' = x_s v, x'' = x_ss v^2 + x_s v'
        let d1 = |x1: f64| x1 * v;
        let d2 = |x1: f64, x2: f64| x2 * v * v + x1 * vd;
        let kp = spec.pitch_per_long * D2R;
        let kr = spec.roll_per_lat * D2R / G;
        let lat = v * r0;
        let lat1 = vd * r0 + v * r1;
        let lat2 = vdd * r0 + 2.0 * vd * r1 + v * r2;
        let grade = g0 * D2R;
        let grade_rate = d1(g1) * D2R;
        let m = EulerMotion {
            angle: [(b0 * D2R) + kr * lat, grade + p0 * D2R + kp * al, psi],
            rate: [d1(b1) * D2R + kr * lat1, grade_rate + d1(p1) * D2R + kp * al1, r0],
            accel: [d2(b1, b2) * D2R + kr * lat2, (d2(g1, g2) + d2(p1, p2)) * D2R + kp * al2, r1],
        };
        (m, grade, grade_rate)
    }

    /// The truth at time `t` for the integrated state `(v, psi, s)`.
    pub fn truth(&self, spec: &MotionSpec, t: f64, v: f64, psi: f64, s: f64) -> Truth {
        let (al, _) = spec.a_long.eval(t);
        let vd = G * al;
        let (e, gr, gr_rate) = self.euler(spec, t, v, psi, s);
        let dpsi = e.rate[2];
        let (sg, cg) = gr.sin_cos();
        let (sp, cp) = psi.sin_cos();
        let tan = [cg * cp, cg * sp, -sg];
        let dtan = [-dpsi * cg * sp - gr_rate * sg * cp, dpsi * cg * cp - gr_rate * sg * sp, -gr_rate * cg];
        let v_p = tan.map(|x| v * x);
        let a_p = [0, 1, 2].map(|i| vd * tan[i] + v * dtan[i]);
        let c = c_nb(e.angle[0], e.angle[1], psi);
        let (w, wd) = e.body_rates();
        let l = &self.lever_arm;
        let wl = cross(&w, l);
        let lever_acc = {
            let a = cross(&wd, l);
            let b = cross(&w, &wl);
            [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
        };
        let dv_s = to_ned(&c, &wl);
        let da_s = to_ned(&c, &lever_acc);
        let vel = [0, 1, 2].map(|i| v_p[i] + dv_s[i]);
        let acc = [0, 1, 2].map(|i| a_p[i] + da_s[i]);
        let mut f = to_body(&c, &[acc[0] / G, acc[1] / G, acc[2] / G - 1.0]);
        let vib = self.vibration.eval(t, v);
        for k in 0..3 {
            f[k] += vib[k];
        }
        let (temp, temp_rate) = spec.thermal.eval(t);
        Truth {
            t,
            roll: e.angle[0] * R2D,
            pitch: e.angle[1] * R2D,
            yaw: wrap180(psi * R2D),
            rate: w.map(|x| x * R2D),
            f,
            temp,
            temp_rate,
            vel,
            acc,
            speed: v,
            a_long: al,
            a_lat: v * dpsi / G,
            dist: s,
            grade: gr * R2D,
        }
    }

    /// Advance `(v, psi, s)` from `t` by `dt` (RK4, `n` sub-steps).
    pub fn advance(&self, spec: &MotionSpec, t: f64, dt: f64, n: u32, state: (f64, f64, f64)) -> (f64, f64, f64) {
        let h = dt / n as f64;
        let (mut v, mut psi, mut s) = state;
        let mut t = t;
        let vdot = |tt: f64| G * spec.a_long.eval(tt).0;
        let pdot = |tt: f64| self.yaw_rate.eval(tt).0 * D2R;
        for _ in 0..n {
            // v and psi are integrals of functions of t alone; s' = v.
            let (a1, a2, a3) = (vdot(t), vdot(t + h / 2.0), vdot(t + h));
            let (p1, p2, p3) = (pdot(t), pdot(t + h / 2.0), pdot(t + h));
            let k1 = v;
            let k2 = v + h / 2.0 * a1;
            let k3 = v + h / 2.0 * a2;
            let k4 = v + h * a2;
            s += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
            v += h / 6.0 * (a1 + 4.0 * a2 + a3);
            psi += h / 6.0 * (p1 + 4.0 * p2 + p3);
            t += h;
        }
        (v, psi, s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::motion::Thermal;

    fn spec(road: RoadSpec) -> MotionSpec {
        let mut a_long = Ease::default();
        for (t, a) in [(0.0, 0.0), (1.0, 0.15), (3.0, 0.15), (4.5, -0.2), (6.0, 0.05), (8.0, 0.0)] {
            a_long.push(t, a);
        }
        MotionSpec {
            duration: 8.0,
            a_long,
            a_lat: Ease::constant(0.0),
            v0: 6.0,
            yaw0: 30.0,
            roll0: 0.0,
            pitch0: 0.0,
            roll_sines: vec![],
            pitch_sines: vec![],
            roll_per_lat: -4.0,
            pitch_per_long: 3.0,
            bumps: vec![],
            ride_roll: vec![],
            ride_pitch: vec![],
            thermal: Thermal { ambient: 20.0, rise: 0.0, tau: 100.0, drift: 0.0, cycle_amp: 0.0, cycle_period: 1.0 },
            manoeuvre_start: 0.0,
            road: Some(road),
        }
    }

    fn road() -> RoadSpec {
        let mut yaw_rate = Ease::default();
        for (t, r) in [(0.0, 0.0), (0.5, 30.0), (2.0, 30.0), (3.0, -20.0), (5.0, 10.0), (7.0, 0.0)] {
            yaw_rate.push(t, r);
        }
        RoadSpec {
            yaw_rate,
            grade: vec![Sine { amp: 5.0, freq: 1.0 / 60.0, phase: 0.3 }],
            road_pitch: vec![Sine { amp: 0.3, freq: 1.0 / 7.0, phase: 1.0 }],
            road_roll: vec![Sine { amp: 1.0, freq: 1.0 / 40.0, phase: 2.0 }],
            lever_arm: [0.9, -0.2, -0.4],
            vibration: RoadVibration::default(),
        }
    }

    /// The analytic Euler and body-rate derivatives against central differences
    /// along the integrated state.
    #[test]
    fn analytic_derivatives_match_finite_differences() {
        let r = road();
        let sp = spec(r.clone());
        let mut st = (sp.v0, sp.yaw0 * D2R, 0.0);
        let dt = 1e-3;
        let mut prev: Option<(EulerMotion, [f64; 3], [f64; 3])> = None;
        let mut prev2: Option<(EulerMotion, [f64; 3], [f64; 3])> = None;
        let mut checked = 0;
        for k in 0..7000 {
            let t = k as f64 * dt;
            let (e, _, _) = r.euler(&sp, t, st.0, st.1, st.2);
            let (w, wd) = e.body_rates();
            if let (Some(p), Some(pp)) = (prev, prev2) {
                // central differences at t - dt; the profiles' second
                // derivatives jump at their knots, so skip those instants
                let tk = t - dt;
                let near_knot = [0.0, 0.5, 1.0, 2.0, 3.0, 4.5, 5.0, 6.0, 7.0].iter().any(|x: &f64| (tk - x).abs() < 2.5 * dt);
                for i in 0..3 {
                    if near_knot {
                        continue;
                    }
                    let fd = (e.angle[i] - pp.0.angle[i]) / (2.0 * dt);
                    assert!((fd - p.0.rate[i]).abs() < 1e-5, "t {tk} angle {i}: {fd} vs {}", p.0.rate[i]);
                    let fd = (e.rate[i] - pp.0.rate[i]) / (2.0 * dt);
                    assert!((fd - p.0.accel[i]).abs() < 1e-4, "t {tk} angle rate {i}: {fd} vs {}", p.0.accel[i]);
                    let fd = (w[i] - pp.1[i]) / (2.0 * dt);
                    assert!((fd - p.2[i]).abs() < 1e-4, "t {tk} body rate {i}: {fd} vs {}", p.2[i]);
                    checked += 1;
                }
            }
            prev2 = prev;
            prev = Some((e, w, wd));
            st = r.advance(&sp, t, dt, 4, st);
        }
        assert!(checked > 20000, "{checked}");
    }

    /// The sensor's specific force integrates to the change of its velocity.
    #[test]
    fn specific_force_integrates_to_sensor_velocity() {
        let r = road();
        let sp = spec(r.clone());
        let dt = 1e-3;
        let mut st = (sp.v0, sp.yaw0 * D2R, 0.0);
        let first = r.truth(&sp, 0.0, st.0, st.1, st.2);
        let mut vel = first.vel;
        let mut prev = first;
        for k in 1..8000 {
            st = r.advance(&sp, (k - 1) as f64 * dt, dt, 4, st);
            let tr = r.truth(&sp, k as f64 * dt, st.0, st.1, st.2);
            for tt in [&prev, &tr] {
                let c = c_nb(tt.roll * D2R, tt.pitch * D2R, tt.yaw * D2R);
                let a = to_ned(&c, &tt.f);
                for i in 0..3 {
                    vel[i] += 0.5 * dt * G * (a[i] + if i == 2 { 1.0 } else { 0.0 });
                }
            }
            prev = tr;
        }
        for i in 0..3 {
            assert!((vel[i] - prev.vel[i]).abs() < 2e-3, "axis {i}: integrated {} vs {}", vel[i], prev.vel[i]);
        }
    }

    /// The rear-axle centre moves along body x up to the suspension angles;
    /// the sensor ahead of it sees the yaw rate times the lever arm sideways.
    #[test]
    fn sensor_velocity_has_the_lever_arm_sideslip() {
        let mut r = road();
        r.road_pitch.clear();
        r.road_roll.clear();
        r.grade.clear();
        r.lever_arm = [0.9, 0.0, 0.0];
        let mut sp = spec(r.clone());
        sp.pitch_per_long = 0.0;
        sp.roll_per_lat = 0.0;
        let tr = r.truth(&sp, 1.5, 7.0, 0.4, 0.0);
        let c = c_nb(tr.roll * D2R, tr.pitch * D2R, tr.yaw * D2R);
        let vb = to_body(&c, &tr.vel);
        let rz = tr.rate[2] * D2R;
        assert!((rz - 30.0 * D2R).abs() < 1e-12);
        assert!((vb[0] - 7.0).abs() < 1e-12 && (vb[1] - 0.9 * rz).abs() < 1e-12 && vb[2].abs() < 1e-12, "{vb:?}");
    }
}
