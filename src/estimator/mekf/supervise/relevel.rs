//! Re-levelling, the recovery of a tilt the data keep refusing: at a
//! standstill whose evidence the gate has refused for `relevel_s`
//! (`relevel`), and for a unit that is not a vehicle whose low-passed
//! gravity has been refused for as long in motion (`relevel_free`).

use crate::estimator::mekf::*;

impl Mekf {
    /// Re-level at rest: the accelerometer (low-passed over the rest) gives
    /// roll and pitch, the low-passed gyro the bias, the velocity is zero.
    /// The covariances are widened to what was refused, then the rest's
    /// updates converge them again.
    pub(in crate::estimator::mekf) fn relevel(&mut self) {
        let Some(r) = self.last_rest else { return };
        let e = quat::euler(self.core.c());
        let (roll, pitch) = crate::estimator::ekf::tilt_from_accel(&r.accel_lp);
        let dt = ((roll - e[0]).powi(2) + (pitch - e[1]).powi(2)).max((1.0 * D2R).powi(2));
        self.core.set_attitude(quat::from_euler(roll, pitch, e[2]));
        self.core.set_velocity([0.0; 3]);
        let mut db = 0.0f64;
        for i in 0..3 {
            db = db.max((r.gyro_lp[i] - self.core.bias()[i]).abs());
        }
        self.core.set_bias(r.gyro_lp);
        // decorrelate and widen tilt, bias and velocity (heading and scale keep theirs)
        self.core.decorrelate(&[TH, TH + 1, BI, BI + 1, BI + 2, VE, VE + 1, VE + 2]);
        for i in 0..2 {
            self.core.set_var(TH + i, dt);
        }
        for i in 0..3 {
            self.core.set_var(BI + i, (db * db).max((0.1 * D2R).powi(2)));
            self.core.set_var(VE + i, 0.01);
        }
        self.refused_still = 0.0;
        self.counters.relevels += 1;
    }

    /// Re-level a unit that is not a vehicle in motion, after its low-passed
    /// gravity has been refused for `relevel_s`: that gravity, not the
    /// filter's tilt, is right (a unit powered on in motion took its first
    /// tilt from one sample of the hand's acceleration; VQF takes this
    /// gravity whole on every sample). The tilt turns to it, the turned
    /// angle becomes its sigma; a bias no standstill has read goes back to
    /// the prior if it was learned with that wrong tilt, before the tilt had
    /// settled; one learned since (provisionally, the gravity's lag in the
    /// model) is kept and learning goes on: with a turn-on bias of several
    /// deg/s the tilt is refused again and again while that bias is still
    /// being learned, and throwing it back each time kept the hand's tilt
    /// a dozen degrees off for as long as it was not put down. The field's
    /// dip was measured with the wrong tilt too.
    pub(in crate::estimator::mekf) fn relevel_free(&mut self) {
        let keep_bias = self.tilt_settled;
        if !keep_bias {
            // the settling starts over
            self.free_gravity.held_s = 0.0;
        }
        let Some(nu) = self.gravity_lp_innovation() else { return };
        // the whole turn, as an error state: (dθ_x, dθ_y) from the
        // innovations (dθ_y, -dθ_x); `inject` turns the attitude and the
        // low-passed force with it
        self.core.set_tilt_error(-nu[1], nu[0]);
        self.inject();
        let angle2 = self.p.init_angle_sigma * self.p.init_angle_sigma;
        // The heading was measured from the field with the wrong tilt: a
        // tilt error e turns it by up to e x tan(dip) (2-3 e at 65-70 deg
        // of dip); it opens by three times the turned angle, at most as at
        // power-on (a quarter turn), so the next undisturbed field sets it.
        let turned = (nu[0] * nu[0] + nu[1] * nu[1]).sqrt();
        let heading2 = (3.0 * turned).min(std::f64::consts::FRAC_PI_2).powi(2);
        let open_heading = heading2 > self.core.cov()[TH + 2][TH + 2];
        let tilt_rows = [TH, TH + 1, TH + 2];
        self.core.decorrelate(&tilt_rows[..if open_heading { 3 } else { 2 }]);
        self.core.set_var(TH, angle2);
        self.core.set_var(TH + 1, angle2);
        if open_heading {
            self.core.set_var(TH + 2, heading2);
        }
        if keep_bias {
            self.free_velocity();
        } else {
            self.free_velocity_and_unread_bias();
        }
        self.heading.forget();
        self.free_gravity.refused_s = 0.0;
        self.counters.relevels += 1;
    }
}
