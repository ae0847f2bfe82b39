//! A standing car does not turn (`gravity_turned`): over a quiet period its
//! gravity keeps its direction in the car's own frame. A car rolling
//! smoothly over a change of grade pitches at its speed times the road's
//! vertical curvature, and a car in a long gentle curve on a banked road
//! rolls: to an IMU alone that is the one sign of motion a quiet period
//! still carries, when there is no vibration, no acceleration and no turn
//! the magnetometer sees. Measured only (never the filter's state), so the
//! power-on bank's copies decide alike.

use crate::estimator::mekf::*;

/// The direction of a quiet period's specific force in the body frame: a
/// reference, and the tick means low-passed over 1 s.
#[derive(Clone, Debug, Default)]
pub(in crate::estimator::mekf) struct GravityWatch {
    /// The reference direction (unit), taken once the low-pass has had a
    /// second, and again every `GRAVITY_TURN_WINDOW_S`.
    reference: Option<[f64; 3]>,
    lp: [f64; 3],
    /// Seconds of the low-pass, then of the reference.
    age: f64,
    /// Seconds left during which the unit counts as turning.
    hold: f64,
}

impl GravityWatch {
    /// One quiet tick of `t` s whose mean specific force is `f` (g): true
    /// while the gravity has turned by more than `GRAVITY_TURN_DEG` within
    /// a window, and for a window after.
    pub(in crate::estimator::mekf) fn quiet_tick(&mut self, f: &[f64; 3], t: f64) -> bool {
        let n = norm(f);
        if !(n > 0.5 && t > 0.0) {
            return self.hold > 0.0;
        }
        let u = [f[0] / n, f[1] / n, f[2] / n];
        if self.age == 0.0 && self.reference.is_none() {
            self.lp = u;
        }
        let k = t.min(1.0);
        for (l, v) in self.lp.iter_mut().zip(u) {
            *l += (v - *l) * k;
        }
        self.age += t;
        self.hold = (self.hold - t).max(0.0);
        let ln = norm(&self.lp);
        let dir = [self.lp[0] / ln, self.lp[1] / ln, self.lp[2] / ln];
        match self.reference {
            None if self.age >= 1.0 => {
                self.reference = Some(dir);
                self.age = 0.0;
            }
            None => {}
            Some(r) => {
                let cos = (r[0] * dir[0] + r[1] * dir[1] + r[2] * dir[2]).clamp(-1.0, 1.0);
                if cos.acos() > GRAVITY_TURN_DEG * D2R {
                    self.hold = GRAVITY_TURN_WINDOW_S;
                    self.reference = Some(dir);
                    self.age = 0.0;
                } else if self.age >= GRAVITY_TURN_WINDOW_S {
                    self.reference = Some(dir);
                    self.age = 0.0;
                }
            }
        }
        self.hold > 0.0
    }
}

impl Mekf {
    /// A quiet tick of a vehicle during which its gravity has turned in its
    /// own frame (`GravityWatch`); the watch starts again whenever the tick
    /// is not quiet.
    pub(in crate::estimator::mekf) fn gravity_turned(&mut self, a: &Accum) -> bool {
        if !a.quiet || !self.vehicle || a.n == 0 {
            self.quiet_gravity = GravityWatch::default();
            return false;
        }
        let n = a.n as f64;
        self.quiet_gravity.quiet_tick(&[a.accel[0] / n, a.accel[1] / n, a.accel[2] / n], a.t)
    }
}

#[cfg(test)]
mod tests {
    use crate::estimator::mekf::*;

    /// Level and still for a minute, with a rest's scatter: never turning. Pitching at 0.1 deg/s
    /// (a car at 2 m/s over a crest of 1 km radius): turning within 7 s
    /// (0.5 deg, and the 1-s low-pass's lag),
    /// and still for a while after it levels out, at most a window.
    #[test]
    fn gravity_turning_in_the_body_is_motion_and_a_steady_one_is_not() {
        let mut w = GravityWatch::default();
        let dt = 0.04;
        // a quiet rest's tick means scatter by a few mg (0.2 deg)
        for i in 0..1500 {
            let e = |k: f64| 0.004 * (i as f64 * k).sin();
            assert!(!w.quiet_tick(&[e(1.7), e(2.3), -1.0 + e(0.9)], dt), "a rest taken for motion at tick {i}");
        }
        let mut first = None;
        for i in 0..500 {
            let th = (0.1 * D2R) * i as f64 * dt;
            if w.quiet_tick(&[-th.sin(), 0.0, -th.cos()], dt) && first.is_none() {
                first = Some(i as f64 * dt);
            }
        }
        let at = first.expect("a pitch rate of 0.1 deg/s is motion");
        assert!(at <= 7.0, "found after {at} s");
        let th = (0.1 * D2R) * 500.0 * dt;
        let mut held = 0.0;
        while w.quiet_tick(&[-th.sin(), 0.0, -th.cos()], dt) {
            held += dt;
            assert!(held <= GRAVITY_TURN_WINDOW_S, "held for ever");
        }
        assert!(held > 0.0, "let go the moment it levelled");
    }
}
