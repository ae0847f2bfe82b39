//! A silent bus: the counter gap's widening of what the unit may have done
//! meanwhile (`resync`), and the exact turn of the whole state to the
//! heading a car turned to over it (`turn_heading`).

use crate::estimator::mekf::*;

impl Mekf {
    /// A counter gap of `gap_s` seconds (the gyro was not integrated across
    /// it): widen what the unit may have done meanwhile, at most
    /// `GAP_TURN_RATE` of turn (a quarter turn in all) and `GAP_ACCEL` of
    /// change of speed.
    ///
    /// A unit that is not a vehicle may have turned any way: its attitude
    /// opens on all three axes. A car drove on along its own x axis, its body
    /// within a few degrees of its road: what it did over the gap is a turn
    /// of the whole state (attitude and velocity together), which nothing in
    /// the body frame sees, plus a change of speed along its x axis. So its
    /// attitude opens by at most `GAP_VEHICLE_TILT`, the velocity's error is
    /// the attitude's (`δv = -[v×] δθ`, fully correlated) plus the change of
    /// speed, and the heading the car turned to is left to the magnetometer
    /// (`heading_open`: its next heading turns attitude and velocity together,
    /// exactly). Widening the attitude by the whole turn instead, the
    /// velocity fixed in the navigation frame, made the first constraint
    /// updates after the gap read the turn as roll, pitch and speed: 20-50
    /// deg of error on simulated urban drives.
    pub fn resync(&mut self, gap_s: f64) {
        let gap = gap_s.max(0.0);
        let att = (GAP_ATT_BASE + GAP_TURN_RATE * gap).min(std::f64::consts::FRAC_PI_2);
        let speed_var = GAP_SPEED_VAR + (GAP_ACCEL * gap).powi(2);
        if self.vehicle {
            let a2 = att.min(GAP_VEHICLE_TILT).powi(2);
            // V = -[v×]: the velocity's error for an attitude error
            let v = self.core.v();
            let vx = [[0.0, v[2], -v[1]], [-v[2], 0.0, v[0]], [v[1], -v[0], 0.0]];
            let cx = rotate(self.core.c(), &self.axes.rows[0]);
            for i in 0..3 {
                for j in 0..3 {
                    // ΔP_vθ = V ΔP_θθ, ΔP_vv = V ΔP_θθ V^T + the speed along body x
                    let pvt = vx[i][j] * a2;
                    self.core.add_cov(VE + i, TH + j, pvt);
                    self.core.add_cov(TH + j, VE + i, pvt);
                    let pvv = (0..3).map(|k| vx[i][k] * vx[j][k]).sum::<f64>() * a2;
                    self.core.add_cov(VE + i, VE + j, pvv + speed_var * cx[i] * cx[j]);
                }
                self.core.add_cov(TH + i, TH + i, a2);
            }
            self.heading.set_open(self.on(Rule::GapHeadingOpen));
            self.tilt_anchored = false;
            self.lever_pending = true;
        } else {
            for i in 0..3 {
                self.core.add_cov(TH + i, TH + i, att * att);
                self.core.add_cov(VE + i, VE + i, speed_var);
            }
        }
        // the tick's means of the measurements are of after the gap only
        // (its propagation sums stay: they are the motion before it)
        let a = &mut self.acc;
        a.n = 0;
        a.gyro = [0.0; 3];
        a.omega = [0.0; 3];
        a.magn = [0.0; 3];
        a.accel = [0.0; 3];
        a.accel2 = 0.0;
        self.rest.reset();
        self.switching.reset();
        self.pulls.gap();
        self.dwell = 0.0;
        self.quiet_since_gap = false;
        self.after_gap = true;
        self.bias_sigma_cache = self.bias_sigma();
    }

    /// Turn the whole state about the navigation frame's down axis by `psi`
    /// (rad): attitude, velocity, the low-passed force, and the covariance of
    /// the navigation-frame errors. Nothing in the body frame changes.
    pub(in crate::estimator::mekf) fn turn_heading(&mut self, psi: f64) {
        let r = self.core.turn_heading(psi);
        if let Some(lp) = self.f_lp.as_mut() {
            lp.rotate(&r);
        }
    }
}
