//! Which way the car drives in the sensor's frame: the axes the vehicle
//! constraint holds along, turned to the way the car is seen to pull away
//! after its still periods.
//!
//! The constraint (no lateral, no vertical velocity) holds along the car's
//! own axes, and `[mounting] rotation` turns every sample into them. A unit
//! mounted turned about the vertical and not configured so puts the car's
//! accelerations on its y axis, where the constraint holds the velocity at
//! zero: the filter reads them as roll and pitch (simulated urban drives
//! with the unit turned 90 or -60 deg and no `[mounting]`: roll and pitch
//! errors of 3-7.5 deg from 200 s on, where the unit configured so has
//! 0.1-0.4).
//!
//! A car pulls away from a standstill along its own x axis, and speeds up
//! or brakes after a steady stretch along it too. So after every still
//! period (a standstill, or a steady cruise the filter cannot tell from
//! one: with the axes wrong its speed is wrong, and its stops look like
//! cruises) the first `PULL_WINDOW_S` of motion are a pull-away: the
//! specific force with gravity put back, less the same at the still period
//! (the filter's tilt error there is in both and drops out; a cruise taken
//! for a standstill that just goes on has nothing left), is the car's
//! acceleration. Gravity is put back as the still period left it, turned by
//! the gyro since (the constraint along wrong axes moves the filter's own
//! tilt within the window). While the car turns less than `PULL_MAX_TURN`
//! about the vertical (a pull-away into a junction turn adds its
//! centripetal part) and the acceleration is at least `PULL_MIN_ACCEL`, its
//! direction in the plane across gravity is the car's x axis (forward, or
//! backward when it reverses or brakes). Once `PULLS_NEEDED` pull-aways
//! agree on one line (the mean resultant of their doubled angles at least
//! `AGREEMENT`) and that line is more than `REAXIS_ANGLE` from the axes in
//! use, the constraint's axes turn to it about the body z axis (forward as
//! most pull-aways went), counted; the velocity opens by the speed one
//! pull-away reaches. Outputs stay in the configured frame; the summary and
//! the daemon's status tell the `[mounting]` yaw that would have spared it.
//!
//! With wheel speeds the car's speed is measured along the axes in use, so
//! forward matters, and the wheels' speed has no sign (a car reversing out
//! of its space reads one too): the axes turn, or turn round for a unit
//! mounted backwards, only when the pull-aways clearly went one way along
//! their line (`SPEED_FORWARD_SHARE`). A unit powered on while driving gets
//! its axes at its first still periods; until then nothing tells the car's
//! acceleration from a tilt.

use super::*;

/// Seconds of motion after a still period that make a pull-away.
const PULL_WINDOW_S: f64 = 1.5;
/// Its mean acceleration across gravity must reach this, g.
const PULL_MIN_ACCEL: f64 = 0.05;
/// Its mean rate about the vertical must stay within this, rad/s.
const PULL_MAX_TURN: f64 = 3.0 * D2R;
/// Pull-aways that must agree before the axes turn.
const PULLS_NEEDED: u32 = 2;
/// The doubled angles' mean resultant length that counts as agreeing
/// (about 10 deg of spread).
const AGREEMENT: f64 = 0.95;
/// The axes turn when the pull-aways' line is further than this from them;
/// once turned, they follow its mean by steps of `REFINE_ANGLE`.
const REAXIS_ANGLE: f64 = 15.0 * D2R;
const REFINE_ANGLE: f64 = 0.5 * D2R;
/// With wheel speeds (unsigned: a car reversing reads a speed too) the
/// axes turn only when the pull-aways went one way along their line this
/// clearly: (forward - backward) / all, 0.5 = three in four forward.
const SPEED_FORWARD_SHARE: f64 = 0.5;

/// The vehicle's axes in the body frame: the car's x, y, z (rows) for a
/// turn `yaw` (rad) about the body z axis, and the lever arm (given in the
/// vehicle frame) in the body frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct VehicleAxes {
    pub yaw: f64,
    pub rows: Mat3,
    pub lever: [f64; 3],
}

impl VehicleAxes {
    pub(super) fn new(yaw: f64, lever: [f64; 3]) -> VehicleAxes {
        let (s, c) = yaw.sin_cos();
        let rows = [[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]];
        // l_body = rows^T l_vehicle
        let lever = std::array::from_fn(|j| (0..3).map(|i| rows[i][j] * lever[i]).sum());
        VehicleAxes { yaw, rows, lever }
    }
}

/// The pull-aways seen so far and the one being watched.
#[derive(Clone, Debug, Default)]
pub(super) struct PullAways {
    /// A still period has been seen and its pull-away is being summed.
    armed: bool,
    t: f64,
    /// The still period: seconds, Σ (specific force + down) dt (body, g).
    rest_t: f64,
    rest_sum: [f64; 3],
    /// Down in the body frame (unit): the filter's at the still period,
    /// turned by the gyro since.
    down: [f64; 3],
    /// The pull-away: Σ (specific force + down) dt (body, g) and Σ rate
    /// about down dt (rad).
    sum_a: [f64; 3],
    sum_r: f64,
    /// Pull-aways taken: Σ cos 2φ, Σ sin 2φ, Σ cos φ, Σ sin φ, their number.
    c2: f64,
    s2: f64,
    c1: f64,
    s1: f64,
    n: u32,
}

impl PullAways {
    /// The line the pull-aways agree on, forward as most went (rad from the
    /// body x axis toward y), once `PULLS_NEEDED` of them agree; and how
    /// clearly they went that way: (forward - backward) / all, about.
    fn agreed(&self) -> Option<(f64, f64)> {
        if self.n < PULLS_NEEDED {
            return None;
        }
        let n = self.n as f64;
        if (self.c2 * self.c2 + self.s2 * self.s2).sqrt() < AGREEMENT * n {
            return None;
        }
        let line = 0.5 * quat::atan2(self.s2, self.c2);
        // forward: the way most of them went along that line
        let along = self.c1 * line.cos() + self.s1 * line.sin();
        let share = along.abs() / n;
        Some(if along < 0.0 { (wrap_pi(line + std::f64::consts::PI), share) } else { (line, share) })
    }

    /// Pull-aways taken so far.
    pub(super) fn count(&self) -> u32 {
        self.n
    }

    /// A counter gap: the turn over it is not known, the pull-away being
    /// summed (if any) is dropped.
    pub(super) fn gap(&mut self) {
        self.armed = false;
    }

    /// A still tick: sum its specific force with gravity put back (`down`,
    /// the filter's, in the body frame), and arm the pull-away that follows.
    /// Gravity put back with the filter's tilt leaves the tilt's error,
    /// which the pull-away carries too and the difference drops.
    fn sum_still(&mut self, a: &Accum, down: [f64; 3]) {
        let n = a.n as f64;
        if !self.armed {
            self.armed = true;
            self.rest_t = 0.0;
            self.rest_sum = [0.0; 3];
        }
        self.rest_t += a.t;
        for i in 0..3 {
            self.rest_sum[i] += (a.accel[i] / n + down[i]) * a.t;
        }
        self.down = down;
        self.t = 0.0;
        self.sum_a = [0.0; 3];
        self.sum_r = 0.0;
    }

    /// A moving tick after a still period, `w` its mean bias-corrected rate
    /// (rad/s): sum its specific force with gravity put back, down as the
    /// still period left it turned by the gyro since (the constraint held
    /// along wrong axes moves the filter's own tilt). Once `PULL_WINDOW_S`
    /// are summed the pull-away is over: returns the car's acceleration
    /// across gravity (g, along the body x axis's part across down and
    /// down × that) when it turned less than `PULL_MAX_TURN` and the plane
    /// across gravity is well defined; None while summing or otherwise.
    fn sum_motion(&mut self, a: &Accum, w: &[f64; 3]) -> Option<(f64, f64)> {
        let n = a.n as f64;
        let turn = quat::to_matrix(&quat::from_rotvec(&w.map(|v| v * a.t)));
        self.down = rotate_t(&turn, &self.down);
        let down = self.down;
        for i in 0..3 {
            self.sum_a[i] += (a.accel[i] / n + down[i]) * a.t;
        }
        self.sum_r += (0..3).map(|i| down[i] * w[i]).sum::<f64>() * a.t;
        self.t += a.t;
        if self.t < PULL_WINDOW_S {
            return None;
        }
        self.armed = false;
        // the acceleration: what the pull-away's force has more than the
        // still period's (a cruise that just goes on has none)
        let mean_a: [f64; 3] = std::array::from_fn(|i| self.sum_a[i] / self.t - self.rest_sum[i] / self.rest_t.max(1e-9));
        let mean_r = self.sum_r / self.t;
        // the plane across gravity: the body x axis across down, and down × that
        let xd = down[0];
        let e1 = [1.0 - xd * down[0], -xd * down[1], -xd * down[2]];
        let e1n = norm(&e1);
        if e1n < 0.3 || mean_r.abs() > PULL_MAX_TURN {
            return None;
        }
        let e1 = e1.map(|v| v / e1n);
        let e2 = cross(&down, &e1);
        let x = (0..3).map(|i| mean_a[i] * e1[i]).sum::<f64>();
        let y = (0..3).map(|i| mean_a[i] * e2[i]).sum::<f64>();
        Some((x, y))
    }

    /// Take a pull-away whose acceleration across gravity is (`x`, `y`), g,
    /// when it is at least `PULL_MIN_ACCEL`: its direction's angle (and the
    /// doubled one, for the line without its sign) joins the sums. Returns
    /// whether it was taken.
    fn take(&mut self, x: f64, y: f64) -> bool {
        let a2 = x * x + y * y;
        if !a2.is_finite() || a2 < PULL_MIN_ACCEL * PULL_MIN_ACCEL {
            return false;
        }
        let phi = quat::atan2(y, x);
        self.c2 += (2.0 * phi).cos();
        self.s2 += (2.0 * phi).sin();
        self.c1 += phi.cos();
        self.s1 += phi.sin();
        self.n += 1;
        true
    }
}

impl Mekf {
    /// Once per tick after its updates, while the vehicle model is in use:
    /// sum a still period, then the first `PULL_WINDOW_S` of
    /// motion after it, take that as a pull-away, and turn the constraint's
    /// axes when the pull-aways agree on others.
    pub(super) fn watch_pull_aways(&mut self, a: &Accum, still: bool) {
        if !self.vehicle || a.n == 0 || !self.on(Rule::PullAwayAxes) {
            self.pulls.armed = false;
            return;
        }
        if still {
            self.pulls.sum_still(a, self.core.c()[2]);
            return;
        }
        if !self.pulls.armed {
            return;
        }
        let n = a.n as f64;
        let w: [f64; 3] = std::array::from_fn(|i| a.omega[i] / n);
        let Some((x, y)) = self.pulls.sum_motion(a, &w) else { return };
        if !self.pulls.take(x, y) {
            return;
        }
        let Some((yaw, forward_share)) = self.pulls.agreed() else { return };
        self.turn_axes(yaw, forward_share, x.hypot(y));
    }

    /// The pull-aways agree on the line `yaw` (rad about the body z axis,
    /// forward as `forward_share` of them clearly went): turn the
    /// constraint's axes to it when it is further than `REAXIS_ANGLE` from
    /// those in use (with wheel speeds, also round when the unit is mounted
    /// backwards), else let axes turned before follow its mean. A turn
    /// opens the velocity by the speed the last pull-away reached at
    /// `accel` (g) over its window.
    fn turn_axes(&mut self, yaw: f64, forward_share: f64, accel: f64) {
        // the constraint has no forward or backward: the line's turn from
        // the axes in use, within +-90 deg
        let d = wrap_pi(2.0 * (yaw - self.axes.yaw)) / 2.0;
        // with wheel speeds forward matters: a unit mounted backwards has
        // the pull-aways' line but the opposite way
        let backwards = wrap_pi(yaw - self.axes.yaw).abs() > std::f64::consts::FRAC_PI_2;
        let flip = self.p.speed_aided && backwards && forward_share >= SPEED_FORWARD_SHARE;
        if d.abs() <= REAXIS_ANGLE && !flip {
            // once turned (here or before a restart), they follow the
            // pull-aways' mean, keeping their forward
            if self.axes.yaw != 0.0 && d.abs() > REFINE_ANGLE {
                self.axes = VehicleAxes::new(wrap_pi(self.axes.yaw + d), self.p.lever);
            }
            return;
        }
        // the wheels' speed has no sign: with it, forward must be the way
        // most pull-aways clearly went (a car reversing out of its space)
        if self.p.speed_aided && forward_share < SPEED_FORWARD_SHARE {
            return;
        }
        self.axes = VehicleAxes::new(yaw, self.p.lever);
        self.counters.reaxed += 1;
        self.counters.rules.note(Rule::PullAwayAxes);
        // the velocity since the still period was held along the wrong axes
        // for one pull-away: open it by the speed that pull-away reached
        let dv = accel * G * PULL_WINDOW_S;
        for i in 0..3 {
            self.core.add_cov(VE + i, VE + i, dv * dv);
        }
    }

    /// The turn of the vehicle axes in use from the body's, deg about z
    /// (0 unless the pull-aways turned them), and the pull-aways seen.
    pub fn vehicle_axes(&self) -> (f64, u32) {
        (self.axes.yaw / D2R, self.pulls.count())
    }

    /// Start with the vehicle axes turned by `yaw_deg` about the body z axis
    /// (what the pull-aways found before a restart, under the same
    /// `[mounting]`); later pull-aways still turn them.
    pub fn set_vehicle_axes(&mut self, yaw_deg: f64) {
        if yaw_deg.is_finite() {
            self.axes = VehicleAxes::new(wrap_pi(yaw_deg * D2R), self.p.lever);
        }
    }
}
