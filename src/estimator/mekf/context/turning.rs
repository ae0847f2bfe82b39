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
        if !self.vehicle || self.scoring || !self.on(Rule::TurningAtSpeed) {
            return false;
        }
        // the centripetal acceleration in the body frame, g
        let w_n = rotate(&self.c, omega);
        let ac = rotate_t(&self.c, &cross(&w_n, &self.v));
        let acn = norm(&ac);
        if acn < TURNING_AT_SPEED_G * G {
            return false;
        }
        let f_rest = rotate_t(&self.c, &[0.0, 0.0, -1.0]);
        let d = [f[0] - f_rest[0], f[1] - f_rest[1], f[2] - f_rest[2]];
        let along = (d[0] * ac[0] + d[1] * ac[1] + d[2] * ac[2]) / acn;
        let across = (norm(&d).powi(2) - along * along).max(0.0).sqrt();
        along >= TURNING_AT_SPEED_G && along >= 2.0 * across
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
            self.quiet_field = None;
            return false;
        }
        let n = a.n as f64;
        let m = [a.magn[0] / n, a.magn[1] / n, a.magn[2] / n];
        let Some(m0) = self.quiet_field else {
            self.quiet_field = Some(m);
            return false;
        };
        let (nm, n0) = (norm(&m), norm(&m0));
        if nm <= 0.0 || n0 <= 0.0 || (nm / n0 - 1.0).abs() > self.p.mag_norm_tol {
            return false;
        }
        let cos = ((m[0] * m0[0] + m[1] * m0[1] + m[2] * m0[2]) / (nm * n0)).clamp(-1.0, 1.0);
        cos.acos() > FIELD_TURN_DEG * D2R
    }
}
