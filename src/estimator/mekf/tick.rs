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
        self.core.clear_dx();
        self.aid = AidReport::all(if a.suspect { Why::Suspect } else { Why::NotStarted });
        let omega = [a.omega[0] / n, a.omega[1] / n, a.omega[2] / n];
        let sit = self.situation(&a, &omega);
        self.settle_free_tilt();
        let learns_in_motion = self.learns_in_motion() && (self.bias_known || self.tilt_settled);
        let learn_gravity = (a.quasi || learns_in_motion) && !a.suspect;
        let learn = !a.suspect;
        let accelerating = sit.still && self.still_tick(&a, &omega, sit.at_rest, &mut o, &mut fl);
        if !sit.still || accelerating {
            self.refused_still = 0.0;
            self.moving_tick(&a, &omega, learn, learn_gravity, &mut o, &mut fl);
        }
        let sit = Situation { at_rest: sit.at_rest && !accelerating, still: sit.still && !accelerating, ..sit };
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
        let wheel = if self.p.speed_aided { self.wheel.speed } else { None };
        let wheel_standing = self.wheel.standing(wheel, t);
        let imu_still =
            if wheel.is_some() && self.on(Rule::WheelStanding) { self.wheel.standing_s >= WHEEL_STANDING_S && a.quiet } else { a.rest };
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
    /// gravity's lag in the model (`fuse_free_gravity`) and kept through
    /// re-levellings (`relevel_free`).
    fn settle_free_tilt(&mut self) {
        if self.on(Rule::ProvisionalBias)
            && !self.bias_known
            && !self.vehicle
            && !self.tilt_settled
            && self.free_gravity.held_s >= self.p.accel_tau
        {
            self.tilt_settled = true;
            self.counters.rules.note(Rule::ProvisionalBias);
            // the field's dip, taken with the tilt before it settled, made
            // every later field look disturbed (broad-18 cut 5 s into its
            // motion: heading 75 deg off until its first rest, 33 s on)
            if self.heading.weak() && self.on(Rule::MagRefRetake) {
                self.counters.rules.note(Rule::MagRefRetake);
                self.heading.forget();
            }
            if self.learns_in_motion() {
                self.core.shrink(&[BI, BI + 1, BI + 2], PROVISIONAL_BIAS_SIGMA);
            }
        }
    }

    /// The updates of a still tick (`still_updates`) and the re-level a
    /// standstill's refused evidence may call for. True when the tick
    /// turned out to be a moving one (`accelerating`).
    fn still_tick(&mut self, a: &Accum, omega: &[f64; 3], at_rest: bool, o: &mut Outcome, fl: &mut u16) -> bool {
        let t = a.t;
        if self.still_updates(a, omega, at_rest, o) {
            return true;
        }
        if at_rest {
            *fl |= flags::STANDSTILL;
            self.counters.rest_s += t;
        }
        if o.refused {
            self.refused_still += t;
        } else {
            self.refused_still = 0.0;
        }
        // Re-levelled onto only where the filter's own tilt may be the
        // wrong one (`tilt_held`): no standstill has confirmed it yet
        // (powered on moving, a turn-on bias of several deg/s; started
        // from a saved state), a counter gap hid what the unit did, or a
        // free unit (a hand's rests are rests). A car whose tilt a
        // standstill has confirmed has had it held by the gyro since: a
        // quiet period whose specific force that tilt refuses is a smooth
        // acceleration taken for a stop (a crawl easing off, a gentle
        // pull-away), and forced in, it put that acceleration into the
        // tilt and the bias (`crawl` worst 2.30 / 3.22 deg, `smooth
        // --hard` pitch 3.52; held, 1.16 / 1.83 and 1.85, every other
        // family the same).
        if at_rest && !self.tilt_held() && self.refused_still >= self.p.relevel_s && self.on(Rule::Relevel) {
            self.inject();
            self.relevel();
            self.counters.rules.note(Rule::Relevel);
            *fl |= flags::RELEVEL;
            o.fused = true;
            o.learned = true;
        }
        self.refusals.refused_s = 0.0;
        false
    }

    /// The updates of a moving tick: the vehicle constraint or a free
    /// unit's gravity and bounded velocity, the speed bounds, the level
    /// rate of a car whose bias is unread, a free unit's re-level, the
    /// refusals' bookkeeping.
    fn moving_tick(&mut self, a: &Accum, omega: &[f64; 3], learn: bool, learn_gravity: bool, o: &mut Outcome, fl: &mut u16) {
        let t = a.t;
        for aid in [Aid::ZeroVelocity, Aid::ZeroRate, Aid::StillGravity] {
            self.aid.fill(aid, AidStatus::NotApplicable(Why::Moving));
        }
        if a.suspect {
            return;
        }
        let learn_v = if self.vehicle { learn } else { learn_gravity };
        let (f, g) = self.velocity_updates(omega, learn_v, self.p.gate);
        // a car powered on while driving: its body's rate about the
        // horizontal, averaged, is its bias's (`fuse_level_rate`)
        if self.learns_level_rate() {
            self.inject();
            let gain = Gain { tilt: true, heading: true, bias: true, scored: false };
            self.fuse_level_rate(t, &a.s_c, &a.s_cg, gain);
        } else {
            self.level = LevelWindow::default();
            let why = self.level_rate_why();
            self.aid.set(Aid::LevelRate, AidStatus::NotApplicable(why));
            self.aid.set(Aid::LevelRoll, AidStatus::NotApplicable(why));
        }
        if !self.vehicle && self.free_gravity.refused_s >= self.p.relevel_s && self.on(Rule::RelevelFree) {
            self.inject();
            self.relevel_free();
            self.counters.rules.note(Rule::RelevelFree);
            *fl |= flags::RELEVEL;
        }
        o.fused |= f;
        o.learned |= f && learn_v;
        self.refusals.tick(t, f, g);
        if g {
            *fl |= flags::GATED;
            self.counters.gated_s += t;
            self.counters.refused_max_s = self.counters.refused_max_s.max(self.refusals.refused_s);
        }
    }

    /// The velocity's measurements in motion: a car's constraint, or a free
    /// unit's gravity and bounded velocity; then a car's speed bounds.
    /// Returns (fused any, refused any) of the first.
    pub(in crate::estimator::mekf) fn velocity_updates(&mut self, omega: &[f64; 3], learn: bool, gate: f64) -> (bool, bool) {
        let gain = Gain { tilt: true, heading: true, bias: learn, scored: false };
        let s = if self.vehicle {
            for aid in [Aid::FreeGravity, Aid::FreeVelocity] {
                self.aid.set(aid, AidStatus::NotApplicable(Why::Vehicle));
            }
            self.fuse_vehicle_constraint(omega, gain, gate)
        } else {
            self.aid.set(Aid::VehicleConstraint, AidStatus::NotApplicable(Why::NotVehicle));
            let g = self.fuse_free_gravity(gain, gate);
            g.and(self.fuse_free_velocity(omega, gain, gate))
        };
        self.speed_bounds(omega, gain);
        (s.any_fused, s.refused())
    }

    /// A car's vertical and forward speed held within their bounds (in a
    /// moving tick and in a cruise alike).
    fn speed_bounds(&mut self, omega: &[f64; 3], gain: Gain) {
        self.fuse_vertical_speed(gain);
        self.fuse_forward_speed(omega, gain);
    }

    /// The wheel speed (each frame once) and the magnetic heading.
    fn speed_and_heading(&mut self, a: &Accum, omega: &[f64; 3], sit: &Situation, learn: bool, o: &mut Outcome, fl: &mut u16) {
        let (t, n, at_rest) = (a.t, a.n as f64, sit.at_rest);
        if sit.wheel.is_some() {
            *fl |= flags::SPEED_AIDED;
            self.counters.speed_used_s += t;
        }
        o.fused |= self.fuse_wheel_speed(sit.wheel, omega, at_rest, a.suspect, learn).is_fused();
        if self.mag_on != Some(true) {
            self.aid.set(Aid::Heading, AidStatus::NotApplicable(Why::NoMagnetometer));
            return;
        }
        if a.suspect {
            return;
        }
        let m = [a.magn[0] / n, a.magn[1] / n, a.magn[2] / n];
        // a free unit's tilt before a standstill has anchored it is the
        // low-passed gravity's, a heading measured with it must not
        // teach the bias either (not even provisionally)
        let learn_h = if self.vehicle || self.bias_known { learn } else { (a.quasi && learn) || at_rest };
        match self.fuse_heading(&m, at_rest, learn_h, self.p.gate) {
            AidStatus::Fused(_) => o.fused = true,
            AidStatus::NotApplicable(Why::FieldDisturbed) => {
                *fl |= flags::MAG_DISTURBED;
                self.counters.mag_disturbed_s += t;
            }
            _ => {}
        }
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
        self.counters.aid.add(&self.aid);
        self.last_aid = self.aid;
        self.last_aid_word = self.aid.packed();
    }

    /// The updates of a still unit: at a standstill (not a smooth cruise)
    /// the velocity is zero, the gyro reads the bias (zero-rate update), the
    /// specific force is gravity. Noise from the rest detector. Returns
    /// true for a quiet tick that turned out to accelerate: the tick is
    /// then a moving one.
    /// A car whose tilt a standstill has confirmed (gravity fused with the
    /// bias read) since it was last in doubt (start, restart, counter gap),
    /// and no counter gap since: its tilt is held by the gyro. Otherwise
    /// the tilt is in doubt, and a refused standstill may re-level it.
    fn tilt_held(&self) -> bool {
        self.vehicle && self.tilt_anchored && !self.after_gap
    }

    fn still_updates(&mut self, a: &Accum, omega: &[f64; 3], at_rest: bool, o: &mut Outcome) -> bool {
        let moving_only = [
            Aid::VehicleConstraint,
            Aid::FreeVelocity,
            Aid::FreeGravity,
            Aid::LevelRate,
            Aid::LevelRoll,
            Aid::VerticalSpeed,
            Aid::ForwardSpeed,
        ];
        for aid in moving_only {
            self.aid.set(aid, AidStatus::NotApplicable(Why::Still));
        }
        let gate = self.p.gate;
        let note = |u: Rows, o: &mut Outcome| {
            o.fused |= u.any_fused;
            o.learned |= u.any_fused;
            o.refused |= u.refused();
        };
        // A car whose tilt a standstill has confirmed (gravity fused with the
        // bias read) holds it on the gyro: a quiet tick whose specific force
        // that tilt refuses as gravity is
        // an acceleration (a smooth pull-away, a crawl easing off, inside
        // the rest band), whether the velocity took it for a stop or a
        // cruise. The tick is a moving one, and its rate is not the bias
        // (`accelerating`). Until then (powered on, restarted, after a
        // counter gap) the tilt is in doubt, and a standstill corrects or
        // re-levels it.
        let test_first = self.tilt_held() && self.on(Rule::Accelerating);
        if test_first {
            let g = self.fuse_still_gravity(a, gate);
            if g.refused() {
                o.refused = true;
                self.counters.rules.note(Rule::Accelerating);
                return true;
            }
            note(g, o);
        }
        if at_rest {
            let u = self.fuse_zero_velocity(gate);
            note(u, o);
        } else {
            self.aid.set(Aid::ZeroVelocity, AidStatus::NotApplicable(Why::Cruising));
        }
        let (u, read) = self.fuse_zero_rate(a, gate);
        o.bias_read = read;
        note(u, o);
        if !at_rest {
            // A cruise is a car moving: its speed stays within a car's
            // bounds, as in any moving tick. A quiet car whose tilt one bad
            // sample set at power-on integrates that tilt into a speed the
            // cruise then holds (a knock reading 30 deg, then a car standing
            // level: -61 m/s believed after 3 min, the pitch 3.2 deg off);
            // held to the bound, the speed's error turns back into the tilt.
            self.speed_bounds(omega, Gain { tilt: true, heading: true, bias: false, scored: false });
        }
        if !test_first {
            let g = self.fuse_still_gravity(a, gate);
            note(g, o);
            self.tilt_anchored |= at_rest && read && g.any_fused && !g.refused() && self.vehicle;
        }
        false
    }
}
