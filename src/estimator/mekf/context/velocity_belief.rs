//! What the filter's own velocity says about the car: whether a still
//! period is a stop or a smooth cruise (`zero_velocity_nis`), and how far
//! that velocity may have drifted since the last stop (`velocity_age_var`).
//! The bounds a car's forward speed keeps when nothing measures it are an
//! aid source (`aid/forward_speed.rs`).

use crate::estimator::mekf::*;

impl Mekf {
    /// The velocity's NIS against standing, `vᵀ (P_vv + (σ_zupt² + age) I)⁻¹ v`:
    /// beyond `stop_sigma`², the velocity state refuses a standstill. A
    /// covariance that is not positive definite says the velocity is not
    /// known: 0 (nothing refuses the stop).
    pub(in crate::estimator::mekf) fn zero_velocity_nis(&self) -> f64 {
        let p_vv: Mat3 = std::array::from_fn(|i| std::array::from_fn(|j| self.core.cov()[VE + i][VE + j]));
        nis_against_zero(&p_vv, self.core.v(), self.p.zupt_var + self.velocity_age_var())
    }

    /// The variance, (m/s)^2, an accelerometer bias of `accel_bias_g` has
    /// added to the velocity since the last standstill. At the stop the
    /// tilt took the bias in (the two are one there); once the car has
    /// turned by Δψ the bias no longer cancels, and the velocity integrates
    /// `|R(Δψ) − I| b = 2 |sin(Δψ/2)| b`. On a straight road it stays 0.
    pub(in crate::estimator::mekf) fn velocity_age_var(&self) -> f64 {
        if !self.on(Rule::VelocityAge) {
            return 0.0;
        }
        let s = self.p.accel_bias_g * G * self.turn_exposure;
        s * s
    }

    /// Per tick: the heading turned since the last standstill, integrated
    /// (`velocity_age_var`); a standstill starts it again.
    pub(in crate::estimator::mekf) fn age_velocity(&mut self, t: f64, at_rest: bool) {
        let yaw = quat::euler(self.core.c())[2];
        if at_rest {
            self.turn_exposure = 0.0;
            self.yaw_at_stop = Some(yaw);
            return;
        }
        let y0 = *self.yaw_at_stop.get_or_insert(yaw);
        self.turn_exposure += 2.0 * (0.5 * wrap_pi(yaw - y0)).sin().abs() * t;
    }
}

/// `vᵀ (P + extra I)⁻¹ v`: how far zero lies from the velocity `v` held
/// with covariance `P`, `extra` the variance added on each axis; 0 when the
/// sum is not positive definite (the velocity is not known).
pub(in crate::estimator::mekf) fn nis_against_zero(p: &Mat3, v: &[f64; 3], extra: f64) -> f64 {
    let mut m = *p;
    for (i, row) in m.iter_mut().enumerate() {
        row[i] += extra;
    }
    let adj = [
        [m[1][1] * m[2][2] - m[1][2] * m[2][1], m[0][2] * m[2][1] - m[0][1] * m[2][2], m[0][1] * m[1][2] - m[0][2] * m[1][1]],
        [m[1][2] * m[2][0] - m[1][0] * m[2][2], m[0][0] * m[2][2] - m[0][2] * m[2][0], m[0][2] * m[1][0] - m[0][0] * m[1][2]],
        [m[1][0] * m[2][1] - m[1][1] * m[2][0], m[0][1] * m[2][0] - m[0][0] * m[2][1], m[0][0] * m[1][1] - m[0][1] * m[1][0]],
    ];
    let det = m[0][0] * adj[0][0] + m[0][1] * adj[1][0] + m[0][2] * adj[2][0];
    if !(det > 0.0 && det.is_finite()) {
        return 0.0;
    }
    let x = rotate(&adj, v);
    ((v[0] * x[0] + v[1] * x[1] + v[2] * x[2]) / det).max(0.0)
}

#[cfg(test)]
mod tests {
    use crate::estimator::mekf::*;

    /// A level car (vehicle model on, no magnetometer) started with an
    /// unread bias, its forward speed `u` known to `sigma`.
    fn car(u: f64, sigma: f64) -> Mekf {
        let p = crate::estimator::mekf_params(&crate::config::Config::default());
        let sw = Switching::new(&crate::config::SwitchingConfig::default(), 200.0);
        let mut m = Mekf::new(MekfParams { vehicle: Vehicle::On, mag: MagUse::Off, ..p }, sw);
        m.start(&[0.0, 0.0, -1.0], &[0.0; 3], [0.0; 3], [0.2 * D2R; 3], false);
        m.set_speed_hypothesis(u, sigma);
        m.set_scoring(false);
        m
    }

    /// Feed `s` seconds of a perfectly quiet IMU (gravity, no rate) at
    /// 200 Hz; the seconds flagged standstill.
    fn quiet(m: &mut Mekf, s: f64) -> f64 {
        let dt = 1.0 / 200.0;
        let mut standing = 0.0;
        for k in 0..(s / dt) as usize {
            let st = StepIn {
                dt,
                t: k as f64 * dt,
                gyro: [0.0; 3],
                accel: [0.0, 0.0, -1.0],
                magn: [0.0; 3],
                temp: 20.0,
                g0: 1.0,
                dbias: [0.0; 3],
                suspect: false,
            };
            if m.step(&st).1 & flags::STANDSTILL != 0 {
                standing += dt;
            }
        }
        standing
    }

    /// A car cruising at 15 m/s on a straight is as quiet as a parked one:
    /// its velocity refuses the standstill (no flag, the speed kept), with
    /// the bias not yet read and no timer forcing a re-level. The same
    /// quiet with the speed known to be 0, or not known at all, is a stop.
    #[test]
    fn a_quiet_imu_at_a_known_speed_is_a_cruise_not_a_stop() {
        let mut cruise = car(15.0, 0.5);
        assert_eq!(quiet(&mut cruise, 20.0), 0.0, "no standstill at 15 m/s");
        assert!((cruise.forward_speed() - 15.0).abs() < 0.5, "the speed is kept: {}", cruise.forward_speed());
        assert_eq!(cruise.counters().relevels, 0, "no re-level");
        let mut parked = car(0.0, 0.5);
        assert!(quiet(&mut parked, 20.0) > 15.0, "a parked car stands");
        let mut unknown = car(15.0, 30.0);
        assert!(quiet(&mut unknown, 20.0) > 15.0, "a speed not known does not refuse a stop");
    }

    /// The velocity since the last stop ages with the heading turned (the
    /// accelerometer's bias no longer cancels against the tilt): 2 m/s known
    /// to 0.1 m/s refuses a stop on a straight, not after a long winding
    /// crawl.
    #[test]
    fn a_velocity_integrated_through_turns_no_longer_refuses_a_stop() {
        let mut m = car(2.0, 0.1);
        m.age_velocity(0.1, true);
        assert!(m.zero_velocity_nis() > m.p.stop_nis, "{}", m.zero_velocity_nis());
        // 300 s of driving straight: nothing exposed
        m.age_velocity(300.0, false);
        assert_eq!(m.velocity_age_var(), 0.0);
        // then a half turn held for 60 s: 0.01 g x 2 x 60 s = 11.8 m/s
        m.core.set_attitude(quat::from_euler(0.0, 0.0, std::f64::consts::PI));
        m.age_velocity(60.0, false);
        let s = m.velocity_age_var().sqrt();
        assert!((s - m.p.accel_bias_g * G * 120.0).abs() < 1e-6, "{s}");
        assert!(m.zero_velocity_nis() < m.p.stop_nis, "{}", m.zero_velocity_nis());
    }

    /// A forward speed beyond the band is held to it, one-sided: 80 m/s
    /// comes down towards 60, -12 up towards -5, 30 is left alone; with the
    /// bound off (0) nothing changes.
    #[test]
    fn a_forward_speed_no_car_has_is_held_to_the_band() {
        let omega = [0.0; 3];
        // an integrated speed, known to 5 m/s
        let run = |u: f64, fwd: f64| {
            let mut m = car(u, 5.0);
            m.p.max_forward_speed = fwd;
            m.core.clear_dx();
            m.fuse_forward_speed(&omega, Gain { tilt: true, heading: true, bias: false, scored: true });
            // the source says what it did: held beyond the band, nothing inside it
            let s = m.aid.get(Aid::ForwardSpeed);
            let held = (fwd > 0.0 && u > fwd) || u < -m.p.max_reverse_speed;
            assert_eq!(s.is_fused(), held, "{u} {fwd}: {s}");
            m.inject();
            m.forward_speed()
        };
        assert!(run(80.0, 60.0) < 62.0 && run(80.0, 60.0) > 57.0, "{}", run(80.0, 60.0));
        assert!(run(-12.0, 60.0) > -6.0 && run(-12.0, 60.0) < -4.0, "{}", run(-12.0, 60.0));
        assert_eq!(run(30.0, 60.0), run(30.0, 0.0));
        assert!((run(80.0, 0.0) - 80.0).abs() < 1e-9);
    }

    /// The velocity's noise follows the car's acceleration: quiet it is
    /// `q_accel_quiet` on every axis; braking at 1 m/s^2 it is `q_accel`
    /// along the braking and stays quiet across it (the vertical and the
    /// lateral channel); shaking by 0.1 g RMS it is `q_accel` on every axis;
    /// knocked far more.
    #[test]
    fn the_velocity_noise_of_a_quiet_car_is_small_and_braking_is_along_the_road() {
        let m = car(10.0, 0.5);
        let (quiet, full) = (m.p.q_accel_quiet, m.p.q_accel);
        let near = |a: f64, b: f64| (a - b).abs() < 1e-12;
        let still = Accum { t: 1.0, n: 1, accel: [0.0, 0.0, -1.0], accel2: 1.0, dv: [0.0, 0.0, -G], ..Accum::default() };
        let q = m.velocity_noise(&still);
        assert!((0..3).all(|i| near(q[i][i], quiet) && (0..3).all(|j| i == j || q[i][j] == 0.0)), "{q:?}");
        // braking along north at 1 m/s^2
        let braking = Accum { dv: [-1.0, 0.0, -G], ..still.clone() };
        let q = m.velocity_noise(&braking);
        assert!(near(q[0][0], full), "along: {q:?}");
        assert!(near(q[1][1], quiet) && near(q[2][2], quiet), "across: {q:?}");
        // braking along north-east: the same noise, turned
        let s = std::f64::consts::FRAC_1_SQRT_2;
        let q = m.velocity_noise(&Accum { dv: [-s, -s, -G], ..still.clone() });
        assert!(near(q[0][0], 0.5 * (full + quiet)) && near(q[0][1], 0.5 * (full - quiet)) && near(q[2][2], quiet), "{q:?}");
        // two samples at ±0.1 g about gravity
        let shaking = Accum { n: 2, accel: [0.0, 0.0, -2.0], accel2: 2.0 * (1.0 + 0.01), dv: [0.0, 0.0, -G], ..still.clone() };
        let q = m.velocity_noise(&shaking);
        assert!((0..3).all(|i| near(q[i][i], full)), "{q:?}");
        // braking while shaking: never more than the whole of `q_accel`
        let q = m.velocity_noise(&Accum { dv: [-1.0, 0.0, -G], ..shaking.clone() });
        assert!(near(q[0][0], full), "{q:?}");
        assert!(quiet < 0.02 * full);
        // a knock, ±2 g about gravity within the tick: no car's change of
        // speed, the velocity's noise far above `q_accel`
        let knock = Accum { n: 2, accel: [0.0, 0.0, -2.0], accel2: 2.0 * (1.0 + 4.0), dv: [0.0, 0.0, -G], ..still.clone() };
        let q = m.velocity_noise(&knock);
        assert!((0..3).all(|i| q[i][i] > 100.0 * full), "{q:?}");
    }
}
