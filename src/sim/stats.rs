//! Driving statistics of a simulated run, to compare with real drives
//! (`scenario.toml [stats]`, printed by `gyrocomp simulate`).
//!
//! Definitions (all from the truth, one value per IMU sample):
//! - `a_x` is the vehicle's longitudinal acceleration `dv/dt` in g (not the
//!   accelerometer, which also sees the grade and vibration);
//! - a stop is a maximal stretch with |v| < 0.1 m/s of at least 1 s (a stop
//!   still running at the end of the run is reported but not counted in
//!   `stop_durations_s`);
//! - a turn is a maximal stretch with |yaw rate| >= 4 deg/s of one sign whose
//!   heading change is at least 10 deg;
//! - lateral acceleration is `v * yaw rate` of the vehicle, g;
//! - `frac_quiet_accel` is the fraction of time with |a_x| > 0.1 g while the
//!   specific force norm (without vibration) is within 1.5 % of 1 g: the
//!   stretches where an |a| band cannot tell acceleration from gravity.

use super::motion::{Truth, G};
use super::urban::STOP_SPEED;
use serde::{Deserialize, Serialize};

/// Statistics of one run (`[stats]` of `scenario.toml`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DriveStats {
    /// Fraction of samples with |a_x| > 0.05 g and > 0.1 g.
    pub frac_ax_over_005g: f64,
    pub frac_ax_over_01g: f64,
    /// 95th percentile of |a_x|, g.
    pub p95_ax_g: f64,
    /// Fraction with |a_x| > 0.1 g and ||f| - 1| < 1.5 %.
    pub frac_quiet_accel: f64,
    /// Completed stops and their durations, s.
    pub stops: usize,
    pub stop_durations_s: Vec<f64>,
    pub turns: usize,
    pub max_lateral_g: f64,
    pub max_yaw_rate_dps: f64,
    pub pitch_min_deg: f64,
    pub pitch_max_deg: f64,
    pub roll_max_abs_deg: f64,
    /// Speed at the first sample, lowest and highest speed, m/s.
    pub first_speed_ms: f64,
    pub min_speed_ms: f64,
    pub max_speed_ms: f64,
    /// Time spent reversing (v < -0.1 m/s), s.
    pub reversing_s: f64,
}

/// Accumulates [`DriveStats`] sample by sample.
#[derive(Default)]
pub struct StatsAcc {
    dt: f64,
    n: usize,
    ax: Vec<f32>,
    quiet: usize,
    stop_start: Option<f64>,
    stop_durations: Vec<f64>,
    turn: Option<(f64, f64)>,
    turns: usize,
    s: DriveStats,
    last_t: f64,
}

impl StatsAcc {
    pub fn new(rate_hz: f64) -> StatsAcc {
        StatsAcc { dt: 1.0 / rate_hz, ..Default::default() }
    }

    pub fn push(&mut self, tr: &Truth) {
        let s = &mut self.s;
        if self.n == 0 {
            s.first_speed_ms = tr.speed;
            s.min_speed_ms = tr.speed;
            s.max_speed_ms = tr.speed;
            s.pitch_min_deg = tr.pitch;
            s.pitch_max_deg = tr.pitch;
        }
        self.n += 1;
        self.last_t = tr.t;
        let ax = tr.a_long.abs();
        self.ax.push(ax as f32);
        // |f| of the motion alone: gravity plus the sensor's acceleration
        let fa = [tr.acc[0] / G, tr.acc[1] / G, tr.acc[2] / G - 1.0];
        let fnorm = (fa[0] * fa[0] + fa[1] * fa[1] + fa[2] * fa[2]).sqrt();
        if ax > 0.1 && (fnorm - 1.0).abs() < 0.015 {
            self.quiet += 1;
        }
        s.min_speed_ms = s.min_speed_ms.min(tr.speed);
        s.max_speed_ms = s.max_speed_ms.max(tr.speed);
        s.pitch_min_deg = s.pitch_min_deg.min(tr.pitch);
        s.pitch_max_deg = s.pitch_max_deg.max(tr.pitch);
        s.roll_max_abs_deg = s.roll_max_abs_deg.max(tr.roll.abs());
        s.max_lateral_g = s.max_lateral_g.max(tr.a_lat.abs());
        s.max_yaw_rate_dps = s.max_yaw_rate_dps.max(tr.rate[2].abs());
        if tr.speed < -STOP_SPEED {
            s.reversing_s += self.dt;
        }
        // stops
        let stopped = tr.speed.abs() < STOP_SPEED;
        match (stopped, self.stop_start) {
            (true, None) => self.stop_start = Some(tr.t),
            (false, Some(t0)) => {
                if tr.t - t0 >= 1.0 {
                    self.stop_durations.push(tr.t - t0);
                }
                self.stop_start = None;
            }
            _ => {}
        }
        // turns
        let r = tr.rate[2];
        let sign = if r >= 4.0 {
            1.0
        } else if r <= -4.0 {
            -1.0
        } else {
            0.0
        };
        match self.turn {
            Some((sg, h)) if sg == sign => self.turn = Some((sg, h + r * self.dt)),
            Some((_, h)) => {
                if h.abs() >= 10.0 {
                    self.turns += 1;
                }
                self.turn = if sign != 0.0 { Some((sign, r * self.dt)) } else { None };
            }
            None if sign != 0.0 => self.turn = Some((sign, r * self.dt)),
            None => {}
        }
    }

    pub fn finish(mut self) -> DriveStats {
        let n = self.ax.len().max(1) as f64;
        let r4 = |x: f64| (x * 1e4).round() / 1e4;
        let mut s = self.s;
        s.frac_ax_over_005g = r4(self.ax.iter().filter(|a| **a > 0.05).count() as f64 / n);
        s.frac_ax_over_01g = r4(self.ax.iter().filter(|a| **a > 0.1).count() as f64 / n);
        s.frac_quiet_accel = r4(self.quiet as f64 / n);
        self.ax.sort_by(|a, b| a.total_cmp(b));
        if !self.ax.is_empty() {
            let k = ((0.95 * (self.ax.len() - 1) as f64).round() as usize).min(self.ax.len() - 1);
            s.p95_ax_g = r4(self.ax[k] as f64);
        }
        if let Some((_, h)) = self.turn {
            if h.abs() >= 10.0 {
                self.turns += 1;
            }
        }
        s.turns = self.turns;
        s.stops = self.stop_durations.len();
        s.stop_durations_s = self.stop_durations.iter().map(|d| (d * 100.0).round() / 100.0).collect();
        for x in [
            &mut s.max_lateral_g,
            &mut s.max_yaw_rate_dps,
            &mut s.pitch_min_deg,
            &mut s.pitch_max_deg,
            &mut s.roll_max_abs_deg,
            &mut s.first_speed_ms,
            &mut s.min_speed_ms,
            &mut s.max_speed_ms,
            &mut s.reversing_s,
        ] {
            *x = r4(*x);
        }
        s
    }
}

impl DriveStats {
    pub fn header() -> String {
        format!(
            "{:>5} {:>7} {:>7} {:>7} {:>7} {:>5} {:>11} {:>5} {:>7} {:>7} {:>13} {:>6} {:>6} {:>5}\n",
            "seed",
            "ax>.05g",
            "ax>.1g",
            "p95_ax",
            "quiet",
            "stops",
            "stop_s",
            "turns",
            "lat_g",
            "yaw_dps",
            "pitch_deg",
            "v0",
            "v_min",
            "rev_s"
        )
    }

    pub fn row(&self, seed: u64) -> String {
        let (lo, hi) = self.stop_durations_s.iter().fold((f64::MAX, f64::MIN), |(l, h), d| (l.min(*d), h.max(*d)));
        let stop_s = if self.stop_durations_s.is_empty() { "-".to_string() } else { format!("{lo:.2}-{hi:.2}") };
        format!(
            "{:>5} {:>7.3} {:>7.3} {:>7.3} {:>7.3} {:>5} {:>11} {:>5} {:>7.3} {:>7.1} {:>13} {:>6.2} {:>6.2} {:>5.1}\n",
            seed,
            self.frac_ax_over_005g,
            self.frac_ax_over_01g,
            self.p95_ax_g,
            self.frac_quiet_accel,
            self.stops,
            stop_s,
            self.turns,
            self.max_lateral_g,
            self.max_yaw_rate_dps,
            format!("{:.1}..{:.1}", self.pitch_min_deg, self.pitch_max_deg),
            self.first_speed_ms,
            self.min_speed_ms,
            self.reversing_s
        )
    }
}
