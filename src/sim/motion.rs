//! Truth motion: attitude, body rates and specific force that belong together.
//!
//! A ground vehicle is described by its longitudinal and lateral acceleration
//! commands (g, smooth piecewise profiles), its body roll/pitch (analytic
//! functions: road and suspension motion, lean in turns, squat/dive, bumps),
//! and its vertical bumps. Speed `v` and heading `psi` are integrated (RK4 on
//! a fine sub-step) from `dv/dt = g a_long`, `dpsi/dt = g a_lat / v`; the NED
//! acceleration is `dv/dt u + v dpsi/dt u_perp + (0, 0, z'')`, so the specific
//! force `f_b = C_bn (a_n - g_n) / g` is that of a real path, and the body
//! rates are `E(roll, pitch)^-1 * [roll', pitch', psi']` with the Euler-angle
//! derivatives taken analytically, so they integrate to the truth attitude.
//!
//! Frames: body FRD, NED, Z-Y-X Euler (yaw, pitch, roll).

use std::f64::consts::PI;

/// Standard gravity, m/s^2 (1 g of specific force).
pub const G: f64 = 9.80665;
const D2R: f64 = PI / 180.0;
const R2D: f64 = 180.0 / PI;

/// A profile through knots `(t_i, v_i)`, eased with a half cosine between
/// consecutive knots (value and slope continuous; slope 0 at the knots),
/// constant before the first and after the last knot.
#[derive(Clone, Debug, Default)]
pub struct Ease {
    pub knots: Vec<(f64, f64)>,
}

impl Ease {
    pub fn constant(v: f64) -> Ease {
        Ease { knots: vec![(0.0, v)] }
    }

    /// Append a knot; times must increase.
    pub fn push(&mut self, t: f64, v: f64) {
        debug_assert!(self.knots.last().is_none_or(|k| t > k.0));
        self.knots.push((t, v));
    }

    pub fn last(&self) -> (f64, f64) {
        *self.knots.last().unwrap_or(&(0.0, 0.0))
    }

    /// Value and time derivative at `t`.
    pub fn eval(&self, t: f64) -> (f64, f64) {
        let (v, dv, _) = self.eval2(t);
        (v, dv)
    }

    /// Value, first and second time derivative at `t` (the second derivative
    /// jumps at the knots: the profile is C1, not C2).
    pub fn eval2(&self, t: f64) -> (f64, f64, f64) {
        let k = &self.knots;
        if k.is_empty() {
            return (0.0, 0.0, 0.0);
        }
        if t <= k[0].0 {
            return (k[0].1, 0.0, 0.0);
        }
        let i = k.partition_point(|p| p.0 <= t);
        if i >= k.len() {
            return (k[k.len() - 1].1, 0.0, 0.0);
        }
        let (t0, v0) = k[i - 1];
        let (t1, v1) = k[i];
        let d = t1 - t0;
        let s = (t - t0) / d;
        let v = v0 + (v1 - v0) * 0.5 * (1.0 - (PI * s).cos());
        let dv = (v1 - v0) * 0.5 * PI * (PI * s).sin() / d;
        let ddv = (v1 - v0) * 0.5 * PI * PI * (PI * s).cos() / (d * d);
        (v, dv, ddv)
    }
}

/// `amp sin(2 pi freq t + phase)`.
#[derive(Clone, Copy, Debug)]
pub struct Sine {
    pub amp: f64,
    pub freq: f64,
    pub phase: f64,
}

impl Sine {
    pub fn eval(&self, t: f64) -> (f64, f64) {
        let w = 2.0 * PI * self.freq;
        let a = w * t + self.phase;
        (self.amp * a.sin(), self.amp * w * a.cos())
    }

    /// Value, first and second derivative with respect to the argument.
    pub fn eval2(&self, x: f64) -> (f64, f64, f64) {
        let w = 2.0 * PI * self.freq;
        let (s, c) = (w * x + self.phase).sin_cos();
        (self.amp * s, self.amp * w * c, -self.amp * w * w * s)
    }
}

fn sum_sines(s: &[Sine], t: f64) -> (f64, f64) {
    s.iter().fold((0.0, 0.0), |acc, x| {
        let (v, d) = x.eval(t);
        (acc.0 + v, acc.1 + d)
    })
}

/// The speed (m/s) at which a road sine's period is the time it takes to
/// drive it: its wavelength is `SINE_SPEED / freq` (at 15 m/s, in the middle
/// of the planar scenarios' 8-22 m/s, a sine of 40 s is a 600-m grade).
pub const SINE_SPEED: f64 = 15.0;

/// The body's tilt and the road's grade (`TruthGen::tilt`), rad and rad/s.
#[derive(Clone, Copy, Debug)]
struct Tilt {
    roll: f64,
    pitch: f64,
    droll: f64,
    dpitch: f64,
    grade: f64,
    dgrade: f64,
}

/// A road bump: vertical acceleration `accel sin(2 pi (t - t0) / dur)` (m/s^2
/// given in g) over one period (no net vertical velocity), with a pitch pulse
/// `pitch (1 - cos(2 pi s)) / 2`.
#[derive(Clone, Copy, Debug)]
pub struct Bump {
    pub t0: f64,
    pub dur: f64,
    /// g (down positive in NED).
    pub accel: f64,
    /// deg.
    pub pitch: f64,
}

/// Temperature of the sensor: ambient, self-heating towards a working
/// temperature with a time constant, and an optional slow drift.
#[derive(Clone, Copy, Debug)]
pub struct Thermal {
    /// Temperature at power-on, deg C.
    pub ambient: f64,
    /// Self-heating rise, deg C.
    pub rise: f64,
    /// Its time constant, s.
    pub tau: f64,
    /// Extra linear drift, deg C/s (ambient change).
    pub drift: f64,
    /// Chamber temperature cycle: amplitude, deg C, of `sin(2 pi t / cycle_period)`
    /// added to the temperature (0 = none; no built-in scenario sets it, the
    /// model-gap tests use it to separate `thermal_rate` from `thermal_linear`).
    pub cycle_amp: f64,
    /// Period of the temperature cycle, s (used only when `cycle_amp != 0`).
    pub cycle_period: f64,
}

impl Thermal {
    pub fn eval(&self, t: f64) -> (f64, f64) {
        let e = (-t / self.tau).exp();
        let (temp, rate) = (self.ambient + self.rise * (1.0 - e) + self.drift * t, self.rise * e / self.tau + self.drift);
        if self.cycle_amp != 0.0 {
            let w = 2.0 * std::f64::consts::PI / self.cycle_period;
            return (temp + self.cycle_amp * (w * t).sin(), rate + self.cycle_amp * w * (w * t).cos());
        }
        (temp, rate)
    }
}

/// Everything that defines a truth run.
#[derive(Clone, Debug)]
pub struct MotionSpec {
    pub duration: f64,
    /// Longitudinal acceleration command, g.
    pub a_long: Ease,
    /// Lateral (centripetal, right positive) acceleration command, g.
    pub a_lat: Ease,
    /// Initial speed, m/s.
    pub v0: f64,
    /// Initial heading, deg.
    pub yaw0: f64,
    /// Static roll/pitch offsets (mounting, parking slope), deg.
    pub roll0: f64,
    pub pitch0: f64,
    /// Road/suspension roll and pitch, deg.
    pub roll_sines: Vec<Sine>,
    pub pitch_sines: Vec<Sine>,
    /// Body roll per g of lateral acceleration, deg/g (negative: leans out of the turn).
    pub roll_per_lat: f64,
    /// Body pitch per g of longitudinal acceleration, deg/g (positive: squats nose-up).
    pub pitch_per_long: f64,
    pub bumps: Vec<Bump>,
    /// Ride vibration of the body (planar model): roll and pitch, deg, as
    /// sines of the distance (`freq` in cycles per metre): the road's texture
    /// shaking the body at `speed / wavelength` Hz, nothing at a standstill
    /// ([`super::scenario::ride`]). Not part of the grade. The road
    /// kinematics carry it in `RoadSpec::road_roll` / `road_pitch`.
    pub ride_roll: Vec<Sine>,
    pub ride_pitch: Vec<Sine>,
    pub thermal: Thermal,
    /// Start of the manoeuvres, s (scored window for the oracle floor).
    pub manoeuvre_start: f64,
    /// Road kinematics ([`super::road`]): when set, the vehicle follows a
    /// 3-D road (grades, camber, a yaw-rate command, a lever arm, reversing),
    /// and `a_lat`, `roll_sines`, `pitch_sines`, `bumps`, `roll0`, `pitch0`
    /// are not used. `None`: the planar model of the older scenarios.
    pub road: Option<super::road::RoadSpec>,
}

/// The truth at one sample.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Truth {
    pub t: f64,
    /// deg, yaw wrapped to (-180, 180].
    pub roll: f64,
    pub pitch: f64,
    pub yaw: f64,
    /// Body rates `[p, q, r]`, deg/s.
    pub rate: [f64; 3],
    /// Specific force, body FRD, g (without the sensor model's vibration;
    /// road kinematics: at the sensor position, with the road vibration).
    pub f: [f64; 3],
    /// deg C and deg C/s.
    pub temp: f64,
    pub temp_rate: f64,
    /// Velocity and acceleration in NED, m/s and m/s^2.
    pub vel: [f64; 3],
    pub acc: [f64; 3],
    /// Speed along the track, m/s (road kinematics: of the rear-axle centre,
    /// negative when reversing).
    pub speed: f64,
    /// Longitudinal acceleration `dv/dt` of the vehicle, g.
    pub a_long: f64,
    /// Lateral (centripetal) acceleration `v * yaw rate` of the vehicle, g.
    pub a_lat: f64,
    /// Distance travelled along the road, m (0 for the scenarios at rest).
    pub dist: f64,
    /// Road grade, deg (positive uphill; 0 for the scenarios at rest).
    pub grade: f64,
}

/// Body-to-NED rotation matrix `C_nb` of Z-Y-X Euler angles (rad).
pub fn c_nb(roll: f64, pitch: f64, yaw: f64) -> [[f64; 3]; 3] {
    let (sf, cf) = roll.sin_cos();
    let (st, ct) = pitch.sin_cos();
    let (sp, cp) = yaw.sin_cos();
    [
        [ct * cp, sf * st * cp - cf * sp, cf * st * cp + sf * sp],
        [ct * sp, sf * st * sp + cf * cp, cf * st * sp - sf * cp],
        [-st, sf * ct, cf * ct],
    ]
}

/// `C^T v` (NED to body with `C = C_nb`).
pub fn to_body(c: &[[f64; 3]; 3], v: &[f64; 3]) -> [f64; 3] {
    [
        c[0][0] * v[0] + c[1][0] * v[1] + c[2][0] * v[2],
        c[0][1] * v[0] + c[1][1] * v[1] + c[2][1] * v[2],
        c[0][2] * v[0] + c[1][2] * v[1] + c[2][2] * v[2],
    ]
}

/// `C v` (body to NED).
pub fn to_ned(c: &[[f64; 3]; 3], v: &[f64; 3]) -> [f64; 3] {
    [
        c[0][0] * v[0] + c[0][1] * v[1] + c[0][2] * v[2],
        c[1][0] * v[0] + c[1][1] * v[1] + c[1][2] * v[2],
        c[2][0] * v[0] + c[2][1] * v[1] + c[2][2] * v[2],
    ]
}

/// Wrap degrees to (-180, 180].
pub fn wrap180(a: f64) -> f64 {
    let r = (a + 180.0).rem_euclid(360.0) - 180.0;
    if r == -180.0 {
        180.0
    } else {
        r
    }
}

/// Streams the truth at a fixed sample rate.
pub struct TruthGen<'a> {
    spec: &'a MotionSpec,
    dt: f64,
    k: u64,
    /// Integrated speed (m/s) and heading (rad) at the current sample time.
    v: f64,
    psi: f64,
    substeps: u32,
    /// Distance travelled (road kinematics), m.
    dist: f64,
}

impl<'a> TruthGen<'a> {
    pub fn new(spec: &'a MotionSpec, rate_hz: f64) -> TruthGen<'a> {
        TruthGen { spec, dt: 1.0 / rate_hz, k: 0, v: spec.v0, psi: spec.yaw0 * D2R, substeps: 4, dist: 0.0 }
    }

    /// Number of samples in the run.
    pub fn len(&self) -> u64 {
        (self.spec.duration / self.dt).floor() as u64 + 1
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    fn psi_dot(&self, t: f64, v: f64) -> f64 {
        if v > 0.5 {
            G * self.spec.a_lat.eval(t).0 / v
        } else {
            0.0
        }
    }

    fn vdot(&self, t: f64) -> f64 {
        G * self.spec.a_long.eval(t).0
    }

    /// Roll and pitch (rad) and their rates (rad/s) at `t`, a distance
    /// `dist` (m) along the road at speed `v` (m/s), and the road's grade
    /// (rad, uphill positive) and its rate.
    ///
    /// The road's camber and grade, and the sway they excite, lie along the
    /// road: the sines are functions of the distance travelled, their
    /// periods the time it takes to drive them at [`SINE_SPEED`]. A parked
    /// car is still; the faster it drives, the faster they come. The pitch
    /// sines are the grade, which the car climbs (its velocity follows it:
    /// `truth_now`).
    fn tilt(&self, t: f64, dist: f64, v: f64) -> Tilt {
        let s = self.spec;
        let x = dist / SINE_SPEED;
        let xr = v / SINE_SPEED;
        let (rs, drs) = sum_sines(&s.roll_sines, x);
        let (ps, dps) = sum_sines(&s.pitch_sines, x);
        let (drs, dps) = (drs * xr, dps * xr);
        // ride vibration: sines of the distance itself
        let (rr, drr) = sum_sines(&s.ride_roll, dist);
        let (rp, drp) = sum_sines(&s.ride_pitch, dist);
        let (drs, dps_body) = (drs + drr * v, dps + drp * v);
        let (al, dal) = s.a_lat.eval(t);
        let (ag, dag) = s.a_long.eval(t);
        let (mut bp, mut dbp) = (0.0, 0.0);
        for b in &s.bumps {
            if t > b.t0 && t < b.t0 + b.dur {
                let x = 2.0 * PI * (t - b.t0) / b.dur;
                bp += b.pitch * 0.5 * (1.0 - x.cos());
                dbp += b.pitch * 0.5 * x.sin() * 2.0 * PI / b.dur;
            }
        }
        let roll = s.roll0 + rs + rr + s.roll_per_lat * al;
        let droll = drs + s.roll_per_lat * dal;
        let pitch = s.pitch0 + ps + rp + s.pitch_per_long * ag + bp;
        let dpitch = dps_body + s.pitch_per_long * dag + dbp;
        Tilt { roll: roll * D2R, pitch: pitch * D2R, droll: droll * D2R, dpitch: dpitch * D2R, grade: ps * D2R, dgrade: dps * D2R }
    }

    /// Vertical (down) acceleration m/s^2 and velocity m/s from the bumps.
    fn vertical(&self, t: f64) -> (f64, f64) {
        let (mut a, mut v) = (0.0, 0.0);
        for b in &self.spec.bumps {
            if t > b.t0 && t < b.t0 + b.dur {
                let w = 2.0 * PI / b.dur;
                let x = w * (t - b.t0);
                a += b.accel * G * x.sin();
                v += b.accel * G * (1.0 - x.cos()) / w;
            }
        }
        (a, v)
    }

    fn truth_now(&self) -> Truth {
        let t = self.k as f64 * self.dt;
        if let Some(road) = &self.spec.road {
            return road.truth(self.spec, t, self.v, self.psi, self.dist);
        }
        let v = self.v;
        let Tilt { roll, pitch, droll, dpitch, grade, dgrade } = self.tilt(t, self.dist, v);
        let psi = self.psi;
        let dpsi = self.psi_dot(t, v);
        // body rates = E^-1 [roll', pitch', yaw']
        let (sf, cf) = roll.sin_cos();
        let (st, ct) = pitch.sin_cos();
        let p = droll - st * dpsi;
        let q = cf * dpitch + sf * ct * dpsi;
        let r = -sf * dpitch + cf * ct * dpsi;
        let (sp, cp) = psi.sin_cos();
        let vdot = if v > 0.0 || self.vdot(t) > 0.0 { self.vdot(t) } else { 0.0 };
        let (az, vz) = self.vertical(t);
        // along the road: horizontally v cos(grade), climbing v sin(grade)
        let (sg, cg) = grade.sin_cos();
        let vh = v * cg;
        let dvh = vdot * cg - v * sg * dgrade;
        let acc = [dvh * cp - vh * dpsi * sp, dvh * sp + vh * dpsi * cp, az - vdot * sg - v * cg * dgrade];
        let vel = [vh * cp, vh * sp, vz - v * sg];
        let c = c_nb(roll, pitch, psi);
        let f = to_body(&c, &[acc[0] / G, acc[1] / G, acc[2] / G - 1.0]);
        let (temp, temp_rate) = self.spec.thermal.eval(t);
        Truth {
            t,
            roll: roll * R2D,
            pitch: pitch * R2D,
            yaw: wrap180(psi * R2D),
            rate: [p * R2D, q * R2D, r * R2D],
            f,
            temp,
            temp_rate,
            vel,
            acc,
            speed: v,
            a_long: vdot / G,
            a_lat: v * dpsi / G,
            dist: self.dist,
            grade: grade * R2D,
        }
    }

    /// Advance speed and heading by one sample period (RK4 sub-steps).
    fn advance(&mut self) {
        let h = self.dt / self.substeps as f64;
        if let Some(road) = &self.spec.road {
            let t = self.k as f64 * self.dt;
            (self.v, self.psi, self.dist) = road.advance(self.spec, t, self.dt, self.substeps, (self.v, self.psi, self.dist));
            self.k += 1;
            return;
        }
        let mut t = self.k as f64 * self.dt;
        for _ in 0..self.substeps {
            let (v, psi) = (self.v, self.psi);
            let f = |tt: f64, vv: f64| -> (f64, f64) {
                let a = if vv > 0.0 || self.vdot(tt) > 0.0 { self.vdot(tt) } else { 0.0 };
                (a, self.psi_dot(tt, vv))
            };
            let k1 = f(t, v);
            let k2 = f(t + h / 2.0, v + h / 2.0 * k1.0);
            let k3 = f(t + h / 2.0, v + h / 2.0 * k2.0);
            let k4 = f(t + h, v + h * k3.0);
            self.v = (v + h / 6.0 * (k1.0 + 2.0 * k2.0 + 2.0 * k3.0 + k4.0)).max(0.0);
            self.psi = psi + h / 6.0 * (k1.1 + 2.0 * k2.1 + 2.0 * k3.1 + k4.1);
            self.dist += 0.5 * (v + self.v) * h;
            t += h;
        }
        self.k += 1;
    }
}

impl Iterator for TruthGen<'_> {
    type Item = Truth;
    fn next(&mut self) -> Option<Truth> {
        if self.k >= self.len() {
            return None;
        }
        let tr = self.truth_now();
        self.advance();
        Some(tr)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ease_derivative_matches_finite_difference() {
        let e = Ease { knots: vec![(0.0, 0.0), (2.0, 1.0), (5.0, 1.0), (6.0, -0.5)] };
        for i in 0..700 {
            let t = -0.5 + i as f64 * 0.01;
            let h = 1e-6;
            let fd = (e.eval(t + h).0 - e.eval(t - h).0) / (2.0 * h);
            assert!((fd - e.eval(t).1).abs() < 1e-5, "t {t}: {fd} vs {}", e.eval(t).1);
        }
        assert_eq!(e.eval(3.0).0, 1.0);
        assert_eq!(e.eval(10.0).0, -0.5);
    }

    #[test]
    fn rotation_is_orthonormal_and_zyx() {
        let c = c_nb(0.3, -0.2, 1.1);
        for i in 0..3 {
            for j in 0..3 {
                let d: f64 = (0..3).map(|k| c[k][i] * c[k][j]).sum();
                assert!((d - if i == j { 1.0 } else { 0.0 }).abs() < 1e-12);
            }
        }
        // level, gravity (0,0,-1) specific force reads (0,0,-1) in the body
        let f = to_body(&c_nb(0.0, 0.0, 0.7), &[0.0, 0.0, -1.0]);
        assert!((f[2] + 1.0).abs() < 1e-12);
        // nose up: body x points up, specific force has +x component sin(theta)
        let th = 0.2;
        let f = to_body(&c_nb(0.0, th, 0.0), &[0.0, 0.0, -1.0]);
        assert!((f[0] - th.sin()).abs() < 1e-12);
    }
}
