//! Is a quiet period a turn? A car in a steady, gentle turn is as quiet
//! to the rest detector as a standing one: the specific force along the
//! centripetal acceleration of the filter's own motion
//! (`turning_at_speed`), or the magnetic field turning in the car's frame
//! (`field_turned`), says it turns.

use crate::estimator::mekf::*;

impl Mekf {
    /// A still period that is a car in a steady, gentle turn: its |f| is
    /// within the rest band of gravity (0.08 g lateral is 0.3 % on |f|) and
    /// every signal is steady; before a standstill has read the bias the
    /// detector cannot tell the turn's rate from a bias. What tells them
    /// apart is where the specific force lies: off the gravity the filter's
    /// attitude predicts by at least `TURNING_AT_SPEED_G`, and along the
    /// centripetal acceleration of the filter's own motion (its velocity
    /// turned at its bias-corrected rate), at least twice as far as across
    /// it. The direction is what counts, not the size: the speed of a car
    /// powered on while driving is known to tens of percent at best (the
    /// simulated `vehicle --power-on-moving` seed 18 turned at 3.2 deg/s
    /// for 1.5 s at a speed the filter held 60 % high: 0.057 g off gravity,
    /// 0.004 g across the predicted 0.089 g; taken for a standstill it read
    /// the turn as a 3 deg/s bias and ran to 10 deg). Left to the rest
    /// detector while the power-on bank scores its copies (they must make
    /// the same decisions).
    pub(in crate::estimator::mekf) fn turning_at_speed(&self, omega: &[f64; 3], f: &[f64; 3]) -> bool {
        self.vehicle && !self.core.scoring() && self.on(Rule::TurningAtSpeed) && along_centripetal(self.core.c(), self.core.v(), omega, f)
    }

    /// A car standing still keeps its magnetic field where it is in its own
    /// frame (the car's own iron turns with it); a car in a steady turn
    /// turns the Earth's field by its yaw rate times the cosine of the dip.
    /// The field is taken when the rest detector's conditions begin to hold
    /// (a second before it says rest); a field that has turned by more than
    /// `FIELD_TURN_DEG` since, with its norm unchanged (a norm that changes
    /// is a disturbance, and says nothing), is a turn. This does not need
    /// the speed, which a car powered on while driving may have lost: the
    /// simulated `vehicle --power-on-moving` seed 18 held 0 m/s at 8 m/s
    /// in a 4 deg/s turn, read the turn as its bias and ran to 9 deg.
    /// Only with the magnetometer in use, only for a vehicle.
    pub(in crate::estimator::mekf) fn field_turned(&mut self, a: &Accum) -> bool {
        if !a.quiet || !self.vehicle || self.mag_on != Some(true) || a.n == 0 {
            self.quiet_field.reset();
            return false;
        }
        let n = a.n as f64;
        self.quiet_field.turned(&[a.magn[0] / n, a.magn[1] / n, a.magn[2] / n], self.p.mag_norm_tol)
    }
}

/// Whether the specific force `f` (g, body) lies off the gravity the
/// attitude `c` predicts by at least `TURNING_AT_SPEED_G`, along the
/// centripetal acceleration of the velocity `v` (m/s, NED) turned at the
/// rate `omega` (rad/s, body), at least twice as far as across it.
pub(in crate::estimator::mekf) fn along_centripetal(c: &Mat3, v: &[f64; 3], omega: &[f64; 3], f: &[f64; 3]) -> bool {
    // the centripetal acceleration in the body frame, m/s^2
    let w_n = rotate(c, omega);
    let ac = rotate_t(c, &cross(&w_n, v));
    let acn = norm(&ac);
    if acn < TURNING_AT_SPEED_G * G {
        return false;
    }
    let f_rest = rotate_t(c, &[0.0, 0.0, -1.0]);
    let d = [f[0] - f_rest[0], f[1] - f_rest[1], f[2] - f_rest[2]];
    let along = (d[0] * ac[0] + d[1] * ac[1] + d[2] * ac[2]) / acn;
    let across = (norm(&d).powi(2) - along * along).max(0.0).sqrt();
    along >= TURNING_AT_SPEED_G && along >= 2.0 * across
}

/// The magnetic field (body frame, a tick's mean) when a quiet period began,
/// and whether it has turned since (`field_turned`).
#[derive(Clone, Debug, Default)]
pub(in crate::estimator::mekf) struct FieldWatch(Option<[f64; 3]>);

impl FieldWatch {
    /// The quiet period ended.
    pub fn reset(&mut self) {
        self.0 = None;
    }

    /// One more quiet tick's field `m` (gauss): whether it has turned by
    /// more than `FIELD_TURN_DEG` from the first, its norm within
    /// `norm_tol` of the first's (a norm that changes is a disturbance,
    /// and says nothing).
    pub fn turned(&mut self, m: &[f64; 3], norm_tol: f64) -> bool {
        let Some(m0) = self.0 else {
            self.0 = Some(*m);
            return false;
        };
        let (nm, n0) = (norm(m), norm(&m0));
        if nm <= 0.0 || n0 <= 0.0 || (nm / n0 - 1.0).abs() > norm_tol {
            return false;
        }
        let cos = ((m[0] * m0[0] + m[1] * m0[1] + m[2] * m0[2]) / (nm * n0)).clamp(-1.0, 1.0);
        cos.acos() > FIELD_TURN_DEG * D2R
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_field_turned_past_its_threshold_is_a_turn_and_a_changed_norm_says_nothing() {
        let mut w = FieldWatch::default();
        let m0 = [0.2, 0.0, 0.4];
        assert!(!w.turned(&m0, 0.1));
        let turn = |deg: f64| {
            let (s, c) = (deg * D2R).sin_cos();
            [0.2 * c, 0.2 * s, 0.4]
        };
        // the horizontal part turns by the car's yaw; the field by less
        assert!(!w.turned(&turn(2.0), 0.1));
        assert!(w.turned(&turn(5.0), 0.1));
        assert!(!w.turned(&[0.4, 0.0, 0.8], 0.1), "a doubled field is a disturbance");
        w.reset();
        assert!(!w.turned(&turn(5.0), 0.1), "a new quiet period starts from its own field");
    }

    #[test]
    fn a_specific_force_along_the_centripetal_acceleration_is_a_turn() {
        let c = quat::to_matrix(&[1.0, 0.0, 0.0, 0.0]);
        let v = [10.0, 0.0, 0.0];
        let w = [0.0, 0.0, 3.0 * D2R];
        // 10 m/s at 3 deg/s: 0.53 m/s^2 (0.053 g) to the right (+y)
        let ac = 10.0 * 3.0 * D2R / G;
        assert!(along_centripetal(&c, &v, &w, &[0.0, ac, -1.0]));
        assert!(!along_centripetal(&c, &v, &w, &[ac, 0.0, -1.0]), "forward is no turn");
        assert!(!along_centripetal(&c, &v, &w, &[0.0, 0.0, -1.0]), "gravity alone is no turn");
        assert!(!along_centripetal(&c, &[0.5, 0.0, 0.0], &w, &[0.0, ac, -1.0]), "too slow to turn so");
    }
}
