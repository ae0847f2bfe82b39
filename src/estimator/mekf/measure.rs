//! The measurements of the default filter: the ground-vehicle constraint and
//! the free unit's low-passed gravity, the wheel speed, the magnetic heading,
//! and the re-levelling after a sustained disagreement at rest.

use super::*;

/// The tilt error seen in `u`, the measured specific force's direction in
/// the navigation frame (unit; `-e_z` when the tilt is right): the rotation
/// that takes `u` to `-e_z` is `(dθ_x, dθ_y, 0)`; returned as the
/// innovations `(dθ_y, -dθ_x)` of the rows `h[TH + 1] = 1` and
/// `h[TH] = -1`. Near level this is `(u_x, u_y)`; it stays the whole angle
/// far from it (a filter upside down sees 180 deg, not `|u_xy|` ≈ 0, which
/// would hold it there).
pub(super) fn tilt_innovation(u: &[f64; 3]) -> [f64; 2] {
    let s = (u[0] * u[0] + u[1] * u[1]).sqrt();
    let k = if s > 1e-12 { quat::atan2(s, -u[2]) / s } else { 1.0 };
    [k * u[0], k * u[1]]
}

impl Mekf {
    /// The ground-vehicle constraint (no lateral / vertical velocity at the
    /// rear axle) or, for a unit that is not a vehicle, a bounded velocity.
    /// Returns (fused any, gated any).
    pub(super) fn velocity_updates(&mut self, omega: &[f64; 3], learn: bool, gate: f64) -> (bool, bool) {
        let gain = Gain { tilt: true, heading: true, bias: learn, velocity: false };
        // A free unit's bounded velocity tells the heading (through the
        // horizontal accelerations) only about a heading already known: with
        // one wide open (powered on in motion, re-acquired) its linearisation
        // turned broad-18, cut 5 s into its motion, 75-180 deg off.
        let open = self.cov[TH + 2][TH + 2] > FREE_HEADING_SIGMA * FREE_HEADING_SIGMA;
        let vgain = if !self.vehicle && open { Gain { heading: false, ..gain } } else { gain };
        let mut fused = false;
        let mut gated = false;
        let mut note = |u: Upd| match u {
            Upd::Fused => fused = true,
            Upd::Gated => gated = true,
            Upd::Skipped => {}
        };
        let (axes, var): (&[usize], f64) = if self.vehicle { (&[1, 2], self.p.nhc_var) } else { (&[0, 1, 2], self.p.free_var) };
        if !self.vehicle {
            for u in self.gravity_lp_update(gain, gate) {
                note(u);
            }
        }
        let mut refused = false;
        for &i in axes {
            let (nu, h) = self.body_velocity_row(i, omega);
            let u = self.update(&h, -nu, var, Gain { velocity: true, ..vgain }, gate);
            refused |= u == Upd::Gated;
            note(u);
        }
        // A unit that goes nowhere on average cannot be many m/s away from
        // standing: a velocity its bound refuses was integrated from a
        // wrong tilt (powered on in motion), and through the attitude rows
        // of that bound it would turn the heading by tens of degrees
        // (broad-18 cut 5 s into its motion: 100 m/s, the heading thrown
        // 180 deg). It is the free velocity again.
        if refused && !self.vehicle {
            self.free_velocity();
        }
        // No road has a car climb or descend faster than `max_vertical_speed`:
        // a vertical velocity beyond it is a pitch error integrated into a
        // wrong speed (powered on while driving, IMU only, a straight road
        // with no stop: nothing else tells them apart). Held to the bound,
        // one-sided, never gated; a real grade a little beyond it costs a
        // pitch error of the excess over the speed only.
        let vmax = self.p.max_vertical_speed;
        if self.vehicle && vmax > 0.0 && self.v[2].abs() > vmax && self.on(Rule::VerticalSpeedBound) {
            let mut h = [0.0; N];
            h[VE + 2] = 1.0;
            let _ = self.update(&h, vmax.copysign(self.v[2]) - self.v[2], VERTICAL_BOUND_SIGMA * VERTICAL_BOUND_SIGMA, gain, f64::INFINITY);
            self.counters.rules.note(Rule::VerticalSpeedBound);
        }
        self.speed_bound_update(omega, gain);
        (fused, gated)
    }

    /// A car powered on while driving, before a standstill has read its
    /// bias: its body cannot keep rolling or pitching, so over a window of
    /// `LEVEL_WINDOW_S` the raw gyro's turn about the horizontal is the
    /// bias's, `C̄ b` (`C̄` the attitude averaged over the window), within
    /// `LEVEL_RATE_SIGMA`. This holds under any acceleration (the
    /// accelerometer is not used), and is left out on windows that turn
    /// about the vertical by more than `LEVEL_TURN_MAX` (a tilt error would
    /// put part of the turn on the horizontal). Without it, IMU only on a
    /// straight road, nothing but the vehicle constraint at a speed the
    /// filter does not know told the roll and pitch axes' bias: a 2 deg/s
    /// pitch bias ran the comma2k19 car's pitch 7 deg off in 2 s.
    /// Called once per tick with the tick's sums; updates once per window.
    pub(super) fn level_rate_update(&mut self, t: f64, s_c: &Mat3, s_cg: &[f64; 3], gain: Gain) {
        let lw = &mut self.level;
        lw.t += t;
        for i in 0..3 {
            lw.s_cg[i] += s_cg[i];
            for j in 0..3 {
                lw.s_c[i][j] += s_c[i][j];
            }
        }
        if lw.t < LEVEL_WINDOW_S {
            return;
        }
        let LevelWindow { t: w, s_c: c, s_cg: g } = std::mem::take(&mut self.level);
        self.counters.rules.note(Rule::LevelRate);
        if self.mag_on != Some(true) {
            self.level_roll_update(gain);
        }
        let b = self.bias;
        // the mean navigation-frame rate, bias-corrected
        let r: [f64; 3] = std::array::from_fn(|k| (g[k] - (0..3).map(|j| c[k][j] * b[j]).sum::<f64>()) / w);
        if r[2].abs() > LEVEL_TURN_MAX {
            return;
        }
        for k in 0..2 {
            let mut h = [0.0; N];
            for j in 0..3 {
                h[BI + j] = -c[k][j] / w;
            }
            let _ = self.update(&h, -r[k], LEVEL_RATE_SIGMA * LEVEL_RATE_SIGMA, gain, self.p.gate);
        }
    }

    /// A car's body is level in roll to within `LEVEL_ROLL_SIGMA`: the road's
    /// crossfall and a curve's superelevation, the body's lean in a turn, a
    /// unit mounted a degree or two off its `[mounting]`. Without a heading
    /// reference (no magnetometer in use) and before a standstill has read
    /// the bias, nothing else tells the roll from the yaw-rate bias: the
    /// vehicle constraint sees only their sum in the lateral acceleration,
    /// `u δb_z = g δφ` at speed `u`. The filter then settled wherever the
    /// speed's changes happened to put it, confident and wrong (the
    /// comma2k19 car without its magnetometer: z bias 1.1 deg/s against
    /// about 3.9 with a 1-sigma of 0.2, roll 5-7 deg off). Once per level
    /// window, with the car's axes in use; never gated.
    pub(super) fn level_roll_update(&mut self, gain: Gain) {
        if let Some((roll, h)) = self.car_roll_row() {
            let _ = self.update(&h, -roll, LEVEL_ROLL_SIGMA * LEVEL_ROLL_SIGMA, gain, f64::INFINITY);
            self.counters.rules.note(Rule::LevelRoll);
        }
    }

    /// The car's roll (its axes in use) and its row of H; None on its side.
    pub(super) fn car_roll_row(&self) -> Option<(f64, [f64; N])> {
        // gravity's direction in the car's y and z axes
        let wy = rotate(&self.c, &self.axes.rows[1]);
        let wz = rotate(&self.c, &self.axes.rows[2]);
        let (gy, gz) = (wy[2], wz[2]);
        let n2 = gy * gy + gz * gz;
        if n2 < 0.25 {
            return None;
        }
        // (C_true a)_z = (C a)_z + dθx (C a)_y - dθy (C a)_x
        let mut h = [0.0; N];
        h[TH] = (gz * wy[1] - gy * wz[1]) / n2;
        h[TH + 1] = (gy * wz[0] - gz * wy[0]) / n2;
        Some((gy.atan2(gz), h))
    }

    /// `level_rate_update` runs (and the samples feed its window): a car,
    /// IMU only, before a standstill has read its bias. Between ticks this
    /// only turns false (the vehicle model left), never true.
    #[inline]
    pub(super) fn learns_level_rate(&self) -> bool {
        self.vehicle && !self.bias_known && !self.p.speed_aided && self.on(Rule::LevelRate)
    }

    /// The navigation-frame low-passed specific force as gravity (tilt
    /// only), held the more loosely the harder the unit is being moved.
    ///
    /// The low-pass lags by `accel_tau_s` (τ; the Butterworth's delay for
    /// slow changes): it sees the tilt error as it was then. A bias error δb
    /// turns the tilt at `dθ' = -C δb`, so the gravity measures
    /// `dθ(t - τ) = dθ(t) + τ C̄ δb`, `C̄` the attitude low-passed over τ
    /// (`c_lag`). While the filter learns a bias no standstill has read
    /// (provisionally, in motion) that term is in the row: a turn-on bias of
    /// several deg/s puts the lagging tilt a dozen degrees behind, and taken
    /// for a tilt error alone it taught the bias a fraction of what it is.
    /// Once a rest has read the bias, what is left of it is hundredths of a
    /// deg/s (a lag of a tenth of a degree, under the motion's share); the
    /// term then only tied the hand's motion to the bias (broad-05, -18 and
    /// -33 roll RMS up by 0.01-0.04 deg) and is left out.
    pub(super) fn gravity_lp_update(&mut self, gain: Gain, gate: f64) -> [Upd; 2] {
        let (Some(g), Some(nu)) = (self.f_lp, self.gravity_lp_innovation()) else { return [Upd::Skipped; 2] };
        let var = g.tilt_var(self.p.lp_tilt_var, self.p.tilt_motion_share2);
        let tau = if gain.bias && !self.bias_known && self.on(Rule::GravityLag) { self.p.accel_tau } else { 0.0 };
        let cl = self.c_lag;
        let mut h = [0.0; N];
        h[TH + 1] = 1.0;
        for j in 0..3 {
            h[BI + j] = tau * cl[1][j];
        }
        let a = self.update(&h, nu[0], var, gain, gate);
        let mut h = [0.0; N];
        h[TH] = -1.0;
        for j in 0..3 {
            h[BI + j] = -tau * cl[0][j];
        }
        let b = self.update(&h, nu[1], var, gain, gate);
        if a == Upd::Gated || b == Upd::Gated {
            self.gravity_refused += self.p.tick_s;
            self.gravity_held = 0.0;
        } else {
            self.gravity_refused = 0.0;
            if a == Upd::Fused && b == Upd::Fused {
                self.gravity_held += self.p.tick_s;
            }
        }
        [a, b]
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
    pub(super) fn relevel_free(&mut self) {
        let keep_bias = self.tilt_settled;
        if !keep_bias {
            // the settling starts over
            self.gravity_held = 0.0;
        }
        let Some(nu) = self.gravity_lp_innovation() else { return };
        // the whole turn, as an error state: (dθ_x, dθ_y) from the
        // innovations (dθ_y, -dθ_x); `inject` turns the attitude and the
        // low-passed force with it
        self.dx = [0.0; N];
        self.dx[TH] = -nu[1];
        self.dx[TH + 1] = nu[0];
        self.inject();
        let angle2 = self.p.init_angle_sigma * self.p.init_angle_sigma;
        // The heading was measured from the field with the wrong tilt: a
        // tilt error e turns it by up to e x tan(dip) (2-3 e at 65-70 deg
        // of dip); it opens by three times the turned angle, at most as at
        // power-on (a quarter turn), so the next undisturbed field sets it.
        let turned = (nu[0] * nu[0] + nu[1] * nu[1]).sqrt();
        let heading2 = (3.0 * turned).min(std::f64::consts::FRAC_PI_2).powi(2);
        let open_heading = heading2 > self.cov[TH + 2][TH + 2];
        let tilt_rows = [TH, TH + 1, TH + 2];
        self.decorrelate(&tilt_rows[..if open_heading { 3 } else { 2 }]);
        self.cov[TH][TH] = angle2;
        self.cov[TH + 1][TH + 1] = angle2;
        if open_heading {
            self.cov[TH + 2][TH + 2] = heading2;
        }
        if keep_bias {
            self.free_velocity();
        } else {
            self.free_velocity_and_unread_bias();
        }
        self.mag_ref = None;
        self.gravity_refused = 0.0;
        self.counters.relevels += 1;
    }

    /// The low-passed gravity's tilt innovation (`tilt_innovation`); None
    /// before there is one, or while it holds less than 0.3 g.
    fn gravity_lp_innovation(&self) -> Option<[f64; 2]> {
        let f = self.f_lp?.gravity;
        let fnm = norm(&f);
        (fnm >= 0.3).then(|| tilt_innovation(&[f[0] / fnm, f[1] / fnm, f[2] / fnm]))
    }

    /// Body-axis `i` velocity at the rear axle and its row of H.
    pub(super) fn body_velocity_row(&self, i: usize, omega: &[f64; 3]) -> (f64, [f64; N]) {
        // a car's constraint holds along its own axes (`forward_axis`)
        let (ax, l) = if self.vehicle {
            (self.axes.rows[i], self.axes.lever)
        } else {
            let mut e = [0.0; 3];
            e[i] = 1.0;
            (e, self.p.lever)
        };
        let vb = rotate_t(&self.c, &self.v);
        let wl = cross(omega, &l);
        let val = (0..3).map(|k| ax[k] * (vb[k] - wl[k])).sum::<f64>();
        // the axis in NED
        let ci = rotate(&self.c, &ax);
        let hth = cross(&ci, &self.v);
        // -a^T [l×]
        let lx = [[0.0, -l[2], l[1]], [l[2], 0.0, -l[0]], [-l[1], l[0], 0.0]];
        let mut h = [0.0; N];
        for j in 0..3 {
            h[TH + j] = hth[j];
            h[VE + j] = ci[j];
            h[BI + j] = -(0..3).map(|k| ax[k] * lx[k][j]).sum::<f64>();
        }
        (val, h)
    }

    pub(super) fn speed_update(&mut self, vw: f64, omega: &[f64; 3], learn: bool, gate: f64) -> Upd {
        let (val, mut h) = self.body_velocity_row(0, omega);
        h[SC] = -vw;
        let nu = vw * (1.0 + self.scale) - val;
        self.update(&h, nu, self.p.speed_var, Gain { tilt: true, heading: true, bias: learn, velocity: true }, gate)
    }

    /// Heading from the magnetometer. Some(fused) or None when disturbed.
    pub(super) fn heading_update(&mut self, m: &[f64; 3], at_rest: bool, learn: bool, gate: f64) -> Option<bool> {
        if self.heading_open {
            // the tick's corrections so far are in the frame a turn would leave
            self.inject();
        }
        let mn = rotate(&self.c, m);
        let nrm = norm(&mn);
        let h2 = mn[0] * mn[0] + mn[1] * mn[1];
        if nrm < 1e-6 || h2 < 1e-12 {
            return Some(false);
        }
        let dip = quat::atan2(mn[2], h2.sqrt());
        // the dip is measured with the filter's tilt: a reference taken
        // before a standstill or a saved bias anchored that tilt (powered on
        // while driving) is taken again once one has
        if self.bias_known && self.mag_ref_weak && self.on(Rule::MagRefRetake) {
            self.counters.rules.note(Rule::MagRefRetake);
            self.mag_ref = None;
        }
        if self.mag_ref.is_none() {
            self.mag_ref_weak = !self.bias_known;
        }
        match self.mag_ref {
            None => {
                // no reference (yet, or again): the field as it is now
                self.mag_ref = Some((nrm, dip));
                self.mag_dist_s = 0.0;
            }
            Some((rn, rd)) => {
                let disturbed = ((nrm / rn) - 1.0).abs() > self.p.mag_norm_tol || (dip - rd).abs() > self.p.mag_dip_tol;
                self.mag_disturbed = disturbed;
                if disturbed {
                    self.mag_dist_s += self.p.tick_s;
                    // a field that stays different for a minute and is steady
                    // at a rest is the new normal (moved car, new mounting)
                    if at_rest && self.mag_dist_s > 60.0 && self.on(Rule::MagNewNormal) {
                        self.counters.rules.note(Rule::MagNewNormal);
                        self.mag_ref = Some((nrm, dip));
                        self.mag_dist_s = 0.0;
                    }
                    return None;
                }
                self.mag_dist_s = 0.0;
            }
        }
        let psi = quat::atan2(mn[1], mn[0]);
        let nu = wrap_pi(psi - self.p.declination);
        if self.heading_open {
            // The car turned over a gap: take the field's heading whole, the
            // velocity turning with it, then fuse it as usual.
            self.turn_heading(-nu);
            self.counters.rules.note(Rule::GapHeadingOpen);
            self.heading_open = false;
            return self.heading_update(m, at_rest, learn, gate);
        }
        let mut h = [0.0; N];
        h[TH] = mn[0] * mn[2] / h2;
        h[TH + 1] = mn[1] * mn[2] / h2;
        h[TH + 2] = -1.0;
        let u = self.update(&h, nu, self.p.yaw_var, Gain { tilt: false, heading: true, bias: learn, velocity: false }, gate);
        // an undisturbed field refused for long: the heading, not the field,
        // is wrong (it was set with a wrong tilt, or drifted with a wrong z
        // bias); open it to what the field says, never a lock-out
        if u == Upd::Gated {
            self.heading_refused += self.p.tick_s;
            if self.heading_refused >= HEADING_REACQUIRE_S && self.on(Rule::HeadingReacquire) {
                self.cov[TH + 2][TH + 2] = self.cov[TH + 2][TH + 2].max(nu * nu);
                self.heading_refused = 0.0;
                self.counters.reacquired += 1;
                self.counters.rules.note(Rule::HeadingReacquire);
            }
        } else {
            self.heading_refused = 0.0;
        }
        Some(u == Upd::Fused)
    }

    /// Re-level at rest: the accelerometer (low-passed over the rest) gives
    /// roll and pitch, the low-passed gyro the bias, the velocity is zero.
    /// The covariances are widened to what was refused, then the rest's
    /// updates converge them again.
    pub(super) fn relevel(&mut self) {
        let Some(r) = self.last_rest else { return };
        let e = quat::euler(&self.c);
        let (roll, pitch) = crate::estimator::ekf::tilt_from_accel(&r.accel_lp);
        let dt = ((roll - e[0]).powi(2) + (pitch - e[1]).powi(2)).max((1.0 * D2R).powi(2));
        self.q = quat::from_euler(roll, pitch, e[2]);
        self.c = quat::to_matrix(&self.q);
        self.v = [0.0; 3];
        let mut db = 0.0f64;
        for i in 0..3 {
            db = db.max((r.gyro_lp[i] - self.bias[i]).abs());
            self.bias[i] = r.gyro_lp[i];
        }
        // decorrelate and widen tilt, bias and velocity (heading and scale keep theirs)
        self.decorrelate(&[TH, TH + 1, BI, BI + 1, BI + 2, VE, VE + 1, VE + 2]);
        for i in 0..2 {
            self.cov[TH + i][TH + i] = dt;
        }
        for i in 0..3 {
            self.cov[BI + i][BI + i] = (db * db).max((0.1 * D2R).powi(2));
            self.cov[VE + i][VE + i] = 0.01;
        }
        self.refused_still = 0.0;
        self.counters.relevels += 1;
    }
}
