//! The reduced-axis estimator: a unit with the yaw rate and the horizontal
//! accelerations only (a car's own ESC sensor: `gyro_z`, `accel_x`,
//! `accel_y`, perhaps a temperature). Pure: no I/O, no allocation per step.
//!
//! What such a unit can honestly give:
//! - the yaw-rate bias: one scalar Kalman filter, a random walk
//!   (`[ekf] bias_walk`), moved between updates by the thermal curve (the
//!   facade's `dbias`, when a temperature is mapped), updated once per
//!   window of [`WINDOW_S`] in which the yaw rate reads its bias:
//!   - a standstill: with wheel speeds (`[speed]`) every one of the
//!     window under [`STAND_MS`]; without them, the yaw rate and ax, ay
//!     quiet (a constant-speed straight cruise looks the same to it);
//!   - with wheel speeds, a straight cruise: moving, the yaw rate quiet and
//!     the lateral acceleration small. The road's own curvature is unknown,
//!     so the window counts with [`CRUISE_SIGMA_DPS`], not a standstill's.
//! - heading: the corrected yaw rate integrated.
//!
//! Roll and pitch are not estimated: ax and ay without a vertical axis do
//! not separate gravity from the car's acceleration, and there are no roll
//! and pitch rates to carry them. The estimate marks them, and the x and y
//! rates and biases, invalid ([`super::invalid`]).

use super::{flags, StepIn};

/// The window over which the evidence is gathered, s.
pub const WINDOW_S: f64 = 1.0;
/// Wheels under this stand, m/s.
pub const STAND_MS: f64 = 0.05;
/// Wheels over this move (a straight cruise may teach the bias), m/s.
pub const CRUISE_MS: f64 = 3.0;
/// A quiet yaw rate: its standard deviation over the window under this,
/// deg/s (the Toyota's quantum is 0.244 deg/s: flicking between two codes
/// is quiet).
pub const QUIET_RATE_DPS: f64 = 0.2;
/// Quiet ax, ay at a standstill without wheel speeds: standard deviation, g.
pub const QUIET_ACCEL_G: f64 = 0.01;
/// A straight cruise: the mean lateral acceleration under this, g.
pub const CRUISE_AY_G: f64 = 0.03;
/// One straight-cruise window's yaw-rate noise: the road's curvature, deg/s.
pub const CRUISE_SIGMA_DPS: f64 = 0.2;

/// A window's mean yaw rate farther from the bias than this many sigma
/// (and [`GATE_FLOOR_DPS`]) is a steady turn: it teaches nothing.
pub const GATE: f64 = 3.0;
pub const GATE_FLOOR_DPS: f64 = 0.5;

/// The settings (from the config: `reduced_params`).
#[derive(Clone, Copy, Debug)]
pub struct ReducedParams {
    /// Bias random walk, (deg/s)^2 per s.
    pub q_bias: f64,
    /// One standstill window's yaw-rate noise, deg/s.
    pub rest_sigma: f64,
    /// The initial bias's 1-sigma without a prior, deg/s.
    pub init_sigma: f64,
    /// Whether wheel speeds are configured.
    pub speed_aided: bool,
    /// Whether a temperature is mapped.
    pub temp_mapped: bool,
}

/// How a window was read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Window {
    Moving,
    Standstill,
    Cruise,
}

/// Sums over the window in progress.
#[derive(Clone, Copy, Debug, Default)]
struct Sums {
    n: u32,
    t: f64,
    gz: [f64; 2],
    ax: [f64; 2],
    ay: [f64; 2],
    /// The lowest and highest wheel speed seen; `unknown` any sample without one.
    v_min: f64,
    v_max: f64,
    unknown: bool,
}

fn std(s: [f64; 2], n: f64) -> f64 {
    (s[1] / n - (s[0] / n).powi(2)).max(0.0).sqrt()
}

impl Sums {
    fn push(&mut self, dt: f64, gz: f64, a: &[f64; 3], v: Option<f64>) {
        if self.n == 0 {
            *self = Sums { v_min: f64::INFINITY, v_max: 0.0, ..Sums::default() };
        }
        self.n += 1;
        self.t += dt;
        for (s, x) in [(&mut self.gz, gz), (&mut self.ax, a[0]), (&mut self.ay, a[1])] {
            s[0] += x;
            s[1] += x * x;
        }
        match v {
            Some(v) => {
                self.v_min = self.v_min.min(v.abs());
                self.v_max = self.v_max.max(v.abs());
            }
            None => self.unknown = true,
        }
    }

    /// What the window says, with its mean yaw rate (deg/s).
    fn read(&self, speed_aided: bool) -> (Window, f64) {
        let n = f64::from(self.n.max(1));
        let mean = self.gz[0] / n;
        let quiet = std(self.gz, n) < QUIET_RATE_DPS;
        let speed = speed_aided && !self.unknown;
        // with wheel speeds the wheels decide; without, the quiet yaw rate and ax, ay
        let stands =
            if speed { self.v_max < STAND_MS } else { quiet && std(self.ax, n) < QUIET_ACCEL_G && std(self.ay, n) < QUIET_ACCEL_G };
        let w = if stands {
            Window::Standstill
        } else if speed && quiet && self.v_min > CRUISE_MS && (self.ay[0] / n).abs() < CRUISE_AY_G {
            Window::Cruise
        } else {
            Window::Moving
        };
        (w, mean)
    }
}

/// The reduced-axis filter's state.
#[derive(Clone, Debug)]
pub struct Reduced {
    p: ReducedParams,
    /// Yaw-rate bias and its variance, deg/s and (deg/s)^2.
    bias: f64,
    var: f64,
    /// Heading, deg (-180..180).
    yaw: f64,
    sums: Sums,
    speed: Option<f64>,
    speed_new: bool,
    /// The last window's reading (standstill or cruise flagged with it).
    last: Window,
    /// Whether the bias is known (a prior or an update).
    known: bool,
    pub counters: ReducedCounters,
}

/// What the reduced filter did, for the summary.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct ReducedCounters {
    /// Windows read as standstills and as straight cruises (each an update).
    pub standstill_windows: u32,
    pub cruise_windows: u32,
    /// Seconds with a fresh wheel speed.
    pub speed_s: f64,
}

impl Reduced {
    pub fn new(p: ReducedParams) -> Reduced {
        Reduced {
            p,
            bias: 0.0,
            var: p.init_sigma * p.init_sigma,
            yaw: 0.0,
            sums: Sums::default(),
            speed: None,
            speed_new: false,
            last: Window::Moving,
            known: false,
            counters: ReducedCounters::default(),
        }
    }

    /// Start on the first sample: the initial bias (deg/s) and, from a prior,
    /// its sigma.
    pub fn start(&mut self, bias: f64, sigma: Option<f64>) {
        let counters = self.counters;
        *self = Reduced::new(self.p);
        self.counters = counters;
        self.bias = if bias.is_finite() { bias } else { 0.0 };
        if let Some(s) = sigma.filter(|s| s.is_finite()) {
            self.var = s.max(1e-4).powi(2);
            self.known = true;
        }
    }

    /// The wheel speed (m/s) while fresh; `new` when a frame arrived.
    pub fn set_speed(&mut self, v: Option<f64>, new: bool) {
        self.speed = v.filter(|v| v.is_finite());
        self.speed_new = new;
    }

    /// A gap was not integrated: the window in progress is dropped.
    pub fn resync(&mut self) {
        self.sums = Sums::default();
    }

    /// One sample. Returns (mode, flags): mode 0 when a window taught the
    /// bias on it, 2 otherwise (gyro only).
    pub fn step(&mut self, s: &StepIn) -> (u8, u16) {
        let dt = if s.dt.is_finite() { s.dt.max(0.0) } else { 0.0 };
        self.bias += s.dbias[2];
        self.var += self.p.q_bias * dt;
        let gz = s.gyro[2];
        self.yaw = wrap180(self.yaw + (gz - self.bias) * dt);
        let mut mode = 2;
        if !s.suspect {
            self.sums.push(dt, gz, &s.accel, self.speed);
            if self.sums.t >= WINDOW_S {
                let (w, mean) = self.sums.read(self.p.speed_aided);
                self.last = w;
                if self.update(w, mean) {
                    mode = 0;
                }
                self.sums = Sums::default();
            }
        }
        let mut fl = 0;
        if self.last == Window::Standstill {
            fl |= flags::STANDSTILL;
        }
        if !self.known {
            fl |= flags::LEARNING;
        }
        if self.p.speed_aided && self.speed.is_some() {
            fl |= flags::SPEED_AIDED;
            self.counters.speed_s += dt;
        }
        (mode, fl)
    }

    /// The window's mean yaw rate as a measurement of the bias.
    fn update(&mut self, w: Window, mean: f64) -> bool {
        let r = match w {
            Window::Standstill => {
                self.counters.standstill_windows += 1;
                self.p.rest_sigma
            }
            Window::Cruise => {
                self.counters.cruise_windows += 1;
                CRUISE_SIGMA_DPS
            }
            Window::Moving => return false,
        };
        // a quiet rate far from the bias is a steady turn, not the bias
        if !mean.is_finite() || (mean - self.bias).abs() > (GATE * self.var.sqrt()).max(GATE_FLOOR_DPS) {
            return false;
        }
        let k = self.var / (self.var + r * r);
        self.bias += k * (mean - self.bias);
        self.var *= 1.0 - k;
        self.known = true;
        true
    }

    /// Yaw-rate bias, deg/s.
    pub fn bias(&self) -> f64 {
        self.bias
    }

    /// Its 1-sigma, deg/s.
    pub fn bias_sigma(&self) -> f64 {
        self.var.sqrt()
    }

    /// Heading, deg.
    pub fn yaw(&self) -> f64 {
        self.yaw
    }

    /// Whether the bias was learned or given.
    pub fn known(&self) -> bool {
        self.known
    }

    pub fn is_finite(&self) -> bool {
        self.bias.is_finite() && self.var.is_finite() && self.yaw.is_finite()
    }

    pub fn params(&self) -> &ReducedParams {
        &self.p
    }
}

/// An angle in deg into -180..180.
fn wrap180(a: f64) -> f64 {
    if !a.is_finite() {
        return 0.0;
    }
    let w = (a + 180.0).rem_euclid(360.0) - 180.0;
    if w < -180.0 {
        w + 360.0
    } else {
        w
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params(speed_aided: bool) -> ReducedParams {
        ReducedParams { q_bias: 0.0005f64.powi(2), rest_sigma: 0.005, init_sigma: 1.0, speed_aided, temp_mapped: false }
    }

    fn input(dt: f64, gz: f64, ax: f64) -> StepIn {
        StepIn { dt, gyro: [0.0, 0.0, gz], accel: [ax, 0.0, 0.0], g0: 1.0, ..StepIn::default() }
    }

    #[test]
    fn a_standstill_teaches_the_yaw_bias() {
        let mut r = Reduced::new(params(false));
        r.start(0.0, None);
        // 5 s standing at 100 Hz with a 0.7 deg/s bias and noise flicking +-0.05
        for i in 0..500 {
            let n = if i % 2 == 0 { 0.05 } else { -0.05 };
            r.step(&input(0.01, 0.7 + n, 0.001 * n));
        }
        assert!((r.bias() - 0.7).abs() < 0.01, "bias {}", r.bias());
        assert!(r.known());
        assert_eq!(r.counters.standstill_windows, 5);
    }

    #[test]
    fn wheels_decide_a_standstill_and_a_straight_cruise_counts_less() {
        let mut r = Reduced::new(params(true));
        r.start(0.0, None);
        // moving straight at 15 m/s, then a turn (rate noisy): the turn teaches nothing
        r.set_speed(Some(15.0), true);
        for i in 0..300 {
            let turn = if i >= 200 { 5.0 * ((i as f64) * 0.3).sin() } else { 0.0 };
            r.step(&input(0.01, 0.4 + turn, 0.0));
        }
        assert_eq!((r.counters.cruise_windows, r.counters.standstill_windows), (2, 0));
        let after_cruise = r.bias_sigma();
        assert!((r.bias() - 0.4).abs() < 0.05 && after_cruise > 0.1, "{} {}", r.bias(), after_cruise);
        // standing (wheels at 0) with a shaking body: the wheels decide
        r.set_speed(Some(0.0), true);
        for i in 0..100 {
            r.step(&input(0.01, 0.4, if i % 2 == 0 { 0.05 } else { -0.05 }));
        }
        assert_eq!(r.counters.standstill_windows, 1);
        assert!(r.bias_sigma() < 0.01, "sigma {}", r.bias_sigma());
    }

    #[test]
    fn heading_integrates_the_corrected_rate_and_wraps() {
        let mut r = Reduced::new(params(false));
        r.start(1.0, Some(0.01));
        for _ in 0..100 {
            r.step(&input(0.1, 1.0 + 20.0, 0.0));
        }
        assert!((r.yaw() - (-160.0)).abs() < 1e-6, "yaw {}", r.yaw());
        assert_eq!(wrap180(540.0), -180.0);
        assert_eq!(wrap180(f64::NAN), 0.0);
    }
}
