//! One tick of the default filter: the covariance propagated over the
//! samples accumulated since the last, then the measurement updates the
//! policy allows (standstill, cruise, vehicle constraints, wheel speed,
//! heading), the restart checks and the tick's flags.

use super::*;

/// What a tick's unit is doing (`Mekf::situation`).
struct Situation {
    /// The wheels' speed, fused (None without `[speed]` or when stale).
    wheel: Option<f64>,
    still: bool,
    at_rest: bool,
}

impl Mekf {
    /// Propagate the covariance over the accumulated interval and run the
    /// measurement updates the policy allows: the situation (still, at
    /// rest or cruising, moving), the updates of a still or a moving unit,
    /// the wheel speed and the heading, the named recovery rules, and the
    /// tick's outcome.
    pub(super) fn tick(&mut self, temp: f64) {
        let a = std::mem::take(&mut self.acc);
        self.acc = Accum { quasi: true, rest: true, quiet: true, ..Accum::default() };
        let t = a.t;
        if t <= 0.0 || a.n == 0 {
            return;
        }
        self.propagate(&a);
        let k = (t / self.p.accel_tau).min(1.0);
        for i in 0..3 {
            for j in 0..3 {
                self.c_lag[i][j] += (a.s_c[i][j] / t - self.c_lag[i][j]) * k;
            }
        }
        let n = a.n as f64;
        let mut fl = 0u16;
        let mut o = Outcome::default();
        self.dx = [0.0; N];
        let omega = [a.omega[0] / n, a.omega[1] / n, a.omega[2] / n];
        let sit = self.situation(&a, &omega);
        self.settle_free_tilt();
        let learns_in_motion = self.learns_in_motion() && (self.bias_known || self.tilt_settled);
        let learn_gravity = (a.quasi || learns_in_motion) && !a.suspect;
        let learn = !a.suspect;
        if sit.still {
            self.still_tick(&a, sit.at_rest, &mut o, &mut fl);
        } else {
            self.refused_still = 0.0;
            self.moving_tick(&a, &omega, learn, learn_gravity, &mut o, &mut fl);
        }
        self.speed_and_heading(&a, &omega, &sit, learn, &mut o, &mut fl);
        self.reacquire_velocity();
        self.inject();
        // a pull-away after a still period shows the car's x axis
        self.watch_pull_aways(&a, sit.still);
        if self.restart_if_diverged(sit.at_rest) {
            self.tick_flags = fl | flags::RELEVEL;
            return;
        }
        self.finish_tick(temp, t, sit.at_rest, &o, fl);
    }

    /// What the tick's unit is doing: still (at rest, or a smooth cruise the
    /// velocity refuses to stop), or moving; the wheels' speed when fused.
    fn situation(&mut self, a: &Accum, omega: &[f64; 3]) -> Situation {
        let (t, n) = (a.t, a.n as f64);
        // With wheel speeds the wheels decide that the car stands (read
        // standing for WHEEL_STANDING_S), the IMU only that it is quiet, with
        // no wait for the detector's time: a steady 0.05 g deceleration looks
        // like rest to an IMU alone. (The detector's rest implies quiet.)
        let wheel = if self.p.speed_aided { self.speed } else { None };
        let wheel_standing = wheel.is_some_and(|v| v.abs() < WHEEL_STANDING);
        self.wheel_standing_s = if wheel_standing { self.wheel_standing_s + t } else { 0.0 };
        let imu_still =
            if wheel.is_some() && self.on(Rule::WheelStanding) { self.wheel_standing_s >= WHEEL_STANDING_S && a.quiet } else { a.rest };
        // IMU only, a steady gentle turn looks still too (`turning_at_speed`,
        // `field_turned`)
        let f_mean = [a.accel[0] / n, a.accel[1] / n, a.accel[2] / n];
        let field_turned = self.field_turned(a) && self.on(Rule::FieldTurned);
        let turning = !field_turned && imu_still && wheel.is_none() && self.turning_at_speed(omega, &f_mean);
        // and a car rolling over a change of grade pitches (`gravity_turned`)
        let gravity_turned = self.gravity_turned(a) && self.on(Rule::GravityTurned);
        if imu_still && wheel.is_none() {
            if field_turned {
                self.counters.rules.note(Rule::FieldTurned);
            } else if turning {
                self.counters.rules.note(Rule::TurningAtSpeed);
            } else if gravity_turned {
                self.counters.rules.note(Rule::GravityTurned);
            }
        }
        let still = imu_still && !a.suspect && (wheel.is_some() || !(field_turned || turning || gravity_turned));
        // A stop is a physical event: a car the filter knows to be moving
        // cannot stand without a deceleration the accelerometer measured. A
        // still period whose zero velocity the velocity state refuses (its
        // NIS against zero beyond `stop_sigma`²) is a smooth cruise: the gyro
        // still reads the bias on a straight and gravity is still gravity,
        // but the velocity is not zero. A velocity that has become unknown
        // (a gap widens it; an accelerometer bias turned with the car since
        // its last stop, `velocity_age_var`) lets the standstill in. Only a
        // vehicle cruises: a free unit's velocity is a bounded guess about
        // zero (it goes nowhere on average), never evidence of speed.
        // After a counter gap the velocity is a guess (the unit may have been
        // knocked, re-mounted or stopped meanwhile): the first quiet period
        // after it is judged with the velocity unknown.
        if a.quiet {
            self.quiet_since_gap = self.after_gap;
        } else if self.quiet_since_gap {
            self.after_gap = false;
            self.quiet_since_gap = false;
        }
        let after_gap = self.after_gap && self.on(Rule::GapVelocityUnknown);
        let cruising =
            self.on(Rule::Cruise) && self.vehicle && !wheel_standing && still && !after_gap && self.zero_velocity_nis() > self.p.stop_nis;
        if cruising {
            self.counters.rules.note(Rule::Cruise);
        }
        if after_gap && still && self.vehicle {
            self.counters.rules.note(Rule::GapVelocityUnknown);
        }
        if wheel.is_some() && still {
            self.counters.rules.note(Rule::WheelStanding);
        }
        let at_rest = still && !cruising;
        self.age_velocity(t, at_rest);
        Situation { wheel, still, at_rest }
    }

    /// The paper's policy: what takes the accelerometer for gravity (the
    /// low-passed tilt and the bounded velocity of a unit that is not a
    /// vehicle) teaches the bias only when the data say quasi-static.
    /// What holds under any acceleration (standstill, the vehicle
    /// constraint, the wheel speed, the magnetic heading) always does.
    /// A unit that is not a vehicle learns it in motion too, with its
    /// motion walk (`q_bias_motion`): its gyro's error in motion is not
    /// its bias at rest; but only once a standstill (or a saved state)
    /// has read the bias. Powered on in motion, the low-passed gravity
    /// lags a tilt still being found: learning a bias of the part's
    /// range (3 deg/s) from it ran away on every BROAD recording started
    /// 15 s into its motion (10-44 deg of roll). So it corrects the tilt
    /// only until the tilt has settled on that gravity (taken without a
    /// break for `accel_tau_s`); from then on a steady residual
    /// is the bias's, learned provisionally from a sigma brought down to
    /// `PROVISIONAL_BIAS_SIGMA` (the cut broad-27's 0.46 deg/s x bias had
    /// held its roll 1.3 deg off for the 100 s to its first rest), the
    /// gravity's lag in the model (`gravity_lp_update`) and kept through
    /// re-levellings (`relevel_free`).
    fn settle_free_tilt(&mut self) {
        if self.on(Rule::ProvisionalBias)
            && !self.bias_known
            && !self.vehicle
            && !self.tilt_settled
            && self.gravity_held >= self.p.accel_tau
        {
            self.tilt_settled = true;
            self.counters.rules.note(Rule::ProvisionalBias);
            // the field's dip, taken with the tilt before it settled, made
            // every later field look disturbed (broad-18 cut 5 s into its
            // motion: heading 75 deg off until its first rest, 33 s on)
            if self.mag_ref_weak && self.on(Rule::MagRefRetake) {
                self.counters.rules.note(Rule::MagRefRetake);
                self.mag_ref = None;
            }
            if self.learns_in_motion() {
                self.shrink(&[BI, BI + 1, BI + 2], PROVISIONAL_BIAS_SIGMA);
            }
        }
    }

    /// The updates of a still tick (`still_updates`) and the re-level a
    /// standstill's refused evidence may call for.
    fn still_tick(&mut self, a: &Accum, at_rest: bool, o: &mut Outcome, fl: &mut u16) {
        let t = a.t;
        if at_rest {
            *fl |= flags::STANDSTILL;
            self.counters.rest_s += t;
        }
        self.still_updates(a, at_rest, o);
        if o.refused {
            self.refused_still += t;
        } else {
            self.refused_still = 0.0;
        }
        // Re-levelled onto only where the filter's own tilt may be the
        // wrong one: no standstill has read the bias yet (powered on
        // moving, a turn-on bias of several deg/s), a counter gap hid
        // what the unit did, or a free unit (a hand's rests are rests).
        // A car whose bias a standstill has read has had its tilt held
        // by the gyro since: a quiet period whose specific force that
        // tilt refuses is a smooth acceleration taken for a stop (a
        // crawl easing off, a gentle pull-away), and forced in, it put
        // that acceleration into the tilt and the bias (`crawl` worst
        // 2.30 / 3.22 deg, `smooth --hard` pitch 3.52; held, 1.16 / 1.83
        // and 1.85, every other family the same).
        let tilt_in_doubt = !self.bias_known || !self.vehicle || self.after_gap;
        if at_rest && tilt_in_doubt && self.refused_still >= self.p.relevel_s && self.on(Rule::Relevel) {
            self.inject();
            self.relevel();
            self.counters.rules.note(Rule::Relevel);
            *fl |= flags::RELEVEL;
            o.fused = true;
            o.learned = true;
        }
        self.nhc_refused = 0.0;
    }

    /// The updates of a moving tick: the vehicle constraint or a free
    /// unit's gravity and bounded velocity, the level rate of a car whose
    /// bias is unread, a free unit's re-level, the refusals' bookkeeping.
    fn moving_tick(&mut self, a: &Accum, omega: &[f64; 3], learn: bool, learn_gravity: bool, o: &mut Outcome, fl: &mut u16) {
        let t = a.t;
        if !a.suspect {
            let learn_v = if self.vehicle { learn } else { learn_gravity };
            let (f, g) = self.velocity_updates(omega, learn_v, self.p.gate);
            // a car powered on while driving: its body's rate about the
            // horizontal, averaged, is its bias's (`level_rate_update`)
            if self.learns_level_rate() {
                self.inject();
                let gain = Gain { tilt: true, heading: true, bias: true, velocity: false };
                self.level_rate_update(t, &a.s_c, &a.s_cg, gain);
            } else {
                self.level = LevelWindow::default();
            }
            if !self.vehicle && self.gravity_refused >= self.p.relevel_s && self.on(Rule::RelevelFree) {
                self.inject();
                self.relevel_free();
                self.counters.rules.note(Rule::RelevelFree);
                *fl |= flags::RELEVEL;
            }
            o.fused |= f;
            o.learned |= f && learn_v;
            let k = (t / LOST_TAU_S).min(1.0);
            self.refused_share += ((if g && !f { 1.0 } else { 0.0 }) - self.refused_share) * k;
            if g {
                *fl |= flags::GATED;
                self.counters.gated_s += t;
                self.nhc_refused += t;
                self.counters.refused_max_s = self.counters.refused_max_s.max(self.nhc_refused);
            } else {
                self.nhc_refused = 0.0;
            }
        }
    }

    /// The wheel speed (each frame once) and the magnetic heading.
    fn speed_and_heading(&mut self, a: &Accum, omega: &[f64; 3], sit: &Situation, learn: bool, o: &mut Outcome, fl: &mut u16) {
        let (t, n, at_rest) = (a.t, a.n as f64, sit.at_rest);
        if let Some(vw) = sit.wheel {
            *fl |= flags::SPEED_AIDED;
            self.counters.speed_used_s += t;
            // each frame once; at a standstill the zero-velocity update says it
            if self.speed_new && !at_rest && !a.suspect && self.speed_update(vw, omega, learn, self.p.gate) == Upd::Fused {
                o.fused = true;
            }
        }
        self.speed_new = false;
        if self.mag_on == Some(true) && !a.suspect {
            let m = [a.magn[0] / n, a.magn[1] / n, a.magn[2] / n];
            // a free unit's tilt before a standstill has anchored it is the
            // low-passed gravity's, a heading measured with it must not
            // teach the bias either (not even provisionally)
            let learn_h = if self.vehicle || self.bias_known { learn } else { (a.quasi && learn) || at_rest };
            match self.heading_update(&m, at_rest, learn_h, self.p.gate) {
                Some(true) => o.fused = true,
                Some(false) => {}
                None => {
                    *fl |= flags::MAG_DISTURBED;
                    self.counters.mag_disturbed_s += t;
                }
            }
        }
    }

    /// `velocity_reacquire`: the velocity constraints refused in motion for
    /// `relevel_s`.
    fn reacquire_velocity(&mut self) {
        if self.nhc_refused >= self.p.relevel_s && self.on(Rule::VelocityReacquire) {
            // The velocity constraints have been refused for long: the
            // velocity, not the vehicle, is wrong. Widen it so they take hold
            // again (the attitude is left alone: it is what they correct).
            for i in 0..3 {
                self.cov[VE + i][VE + i] += 1.0;
            }
            self.nhc_refused = 0.0;
            self.counters.reacquired += 1;
            self.counters.rules.note(Rule::VelocityReacquire);
        }
    }

    /// `restart_lost`, `restart_bias_range`: a diverged filter starts again
    /// from its prior (true when it did).
    fn restart_if_diverged(&mut self, at_rest: bool) -> bool {
        let (pb, ps) = self.prior;
        // Before a standstill (or a saved state) has shown the bias, a bias
        // beyond the part's range is the filter's divergence, not the part;
        // a bias read at rest is evidence, whatever its size.
        let lost = self.refused_share > LOST_SHARE && self.on(Rule::RestartLost);
        let unbelievable = self.on(Rule::RestartBiasRange)
            && !self.bias_known
            && !at_rest
            && (0..3).any(|i| (self.bias[i] - pb[i]).abs() > BIAS_LIMIT_SIGMAS * ps[i].max(self.p.init_bias_sigma));
        if lost || unbelievable {
            self.counters.rules.note(if lost { Rule::RestartLost } else { Rule::RestartBiasRange });
            self.restart_from_prior();
            return true;
        }
        false
    }

    /// The tick's outcome: the bias read, the learning point, the mode and
    /// the flags the following samples carry.
    fn finish_tick(&mut self, temp: f64, t: f64, at_rest: bool, o: &Outcome, mut fl: u16) {
        // known once a standstill has *read* it (a refused zero-rate update
        // says the filter's bias is wrong, not known)
        if at_rest && o.bias_read {
            self.bias_known = true;
        }
        if at_rest {
            self.rest_point = Some((temp, self.bias_deg(), t));
        } else {
            self.rest_point = None;
        }
        if o.learned && o.fused {
            self.last_learned = Some((temp, self.bias_deg()));
        }
        self.mode = match (o.fused, o.learned) {
            (true, true) => 0,
            (true, false) => 1,
            _ => 2,
        };
        if !self.bias_known {
            fl |= flags::LEARNING;
        }
        if o.refused {
            fl |= flags::GATED;
        }
        self.tick_flags = fl;
    }

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
    fn turning_at_speed(&self, omega: &[f64; 3], f: &[f64; 3]) -> bool {
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
    fn field_turned(&mut self, a: &Accum) -> bool {
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

    /// The updates of a still unit: the gyro reads the bias (zero-rate
    /// update), the specific force is gravity, and at a standstill (not a
    /// smooth cruise) the velocity is zero. Noise from the rest detector.
    fn still_updates(&mut self, a: &Accum, at_rest: bool, o: &mut Outcome) {
        let n = a.n as f64;
        let gate = self.p.gate;
        let all = Gain { tilt: true, heading: true, bias: true, velocity: false };
        let note = |u: Upd, o: &mut Outcome| match u {
            Upd::Fused => {
                o.fused = true;
                o.learned = true;
            }
            Upd::Gated => o.refused = true,
            Upd::Skipped => {}
        };
        if at_rest {
            for i in 0..3 {
                let mut h = [0.0; N];
                h[VE + i] = 1.0;
                // not scored for the power-on bank: a standstill is what this
                // copy assumes, not a measurement every copy shares (scored,
                // the copy that took a cruise for a stop gained nats from
                // its own assumption)
                let u = self.update(&h, -self.v[i], self.p.zupt_var, all, gate);
                note(u, o);
            }
        }
        let gvar = self.last_rest.map_or(self.p.zru_floor, |r| r.gyro_var / 3.0);
        let r_zru = (gvar / n).max(self.p.zru_floor);
        let mut read = 0;
        for i in 0..3 {
            let mut h = [0.0; N];
            h[BI + i] = 1.0;
            let u = self.update(&h, a.gyro[i] / n - self.bias[i], r_zru, all, gate);
            read += (u == Upd::Fused) as u32;
            note(u, o);
        }
        o.bias_read = read == 3;
        let f = [a.accel[0] / n, a.accel[1] / n, a.accel[2] / n];
        let fnm = norm(&f);
        if fnm > 0.5 {
            let u = rotate(&self.c, &[f[0] / fnm, f[1] / fnm, f[2] / fnm]);
            let avar = self.last_rest.map_or(1e-4, |r| r.accel_var / 3.0);
            let r_tilt = (avar / n).max(self.p.tilt_floor);
            let nu = measure::tilt_innovation(&u);
            // A cruise's tilt error has run into its velocity since the tilt
            // was last right (the velocity integrates g times it): the tilt
            // update corrects that velocity too, by their covariance, as an
            // unrestricted Kalman update does. With the velocity held out, a
            // smooth 0.03 g pull-away the rest detector takes for still put
            // half a degree into the pitch and left the speed a third short,
            // and the car, still crawling, later passed for stopped
            // (`crawl` seed 3). Only once a standstill has read the bias:
            // before, the tilt's error is mostly the bias's, which the
            // covariance of a filter that far off does not describe (a
            // copy of the power-on bank then believed a speed that refused
            // the first stop).
            let all = Gain { velocity: !at_rest && self.bias_known, ..all };
            let mut h = [0.0; N];
            h[TH + 1] = 1.0;
            let up = self.update(&h, nu[0], r_tilt, all, gate);
            note(up, o);
            let mut h = [0.0; N];
            h[TH] = -1.0;
            let up = self.update(&h, nu[1], r_tilt, all, gate);
            note(up, o);
        }
    }
}
