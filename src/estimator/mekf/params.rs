//! The filter's settings, in its own units (rad, s, m), and its two
//! three-way switches (`MagUse`, `Vehicle`).

use super::rules::RulesOff;
use crate::estimator::rest::RestParams;

/// Whether the magnetometer is used for heading.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MagUse {
    /// Decided from the field over the first second: off when it is zero,
    /// absent or implausible for Earth's (|m| outside 0.1..1.0 gauss).
    Auto,
    On,
    Off,
}

/// Whether the unit is in a ground vehicle (`[mekf] vehicle`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Vehicle {
    /// A vehicle until the body's roll and pitch rates say otherwise: a car
    /// body rolls and pitches by a few deg/s, a hand-held unit by tens.
    Auto,
    On,
    Off,
}

/// Settings of the filter, in its own units (rad, s, m).
#[derive(Clone, Debug, PartialEq)]
pub struct MekfParams {
    /// Seconds between covariance propagations / measurement updates.
    pub tick_s: f64,
    /// Gyro white noise, rad^2/s; bias random walk, rad^2/s^3; accelerometer
    /// (and vehicle-model) noise, (m/s^2)^2/Hz; speed-scale walk, 1/s.
    pub q_gyro: f64,
    /// Relative gyro scale / misalignment uncertainty: the attitude's
    /// variance grows by (this x rotation angle)^2.
    pub gyro_scale: f64,
    pub q_bias: f64,
    /// Not a vehicle, moving: the bias walk (rad/s)^2/s; 0 = the bias is
    /// learned in motion only when quasi-static (see `MekfConfig`).
    pub q_bias_motion: f64,
    pub q_accel: f64,
    pub q_scale: f64,
    /// Ground-vehicle constraint variance (m/s)^2.
    pub nhc_var: f64,
    /// A vehicle's largest vertical speed, m/s (0: no bound).
    pub max_vertical_speed: f64,
    /// A vehicle's forward-speed band, m/s (`speed_bound_update`; forward
    /// 0: no bound), and the bound's sigma, m/s.
    pub max_forward_speed: f64,
    pub max_reverse_speed: f64,
    pub speed_bound_sigma: f64,
    /// The velocity noise of a quiet car, (m/s^2)^2/Hz, and the
    /// acceleration (m/s^2) from which it is `q_accel` (`velocity_noise`).
    pub q_accel_quiet: f64,
    pub accel_ref: f64,
    /// The accelerometer bias, g, whose turn since the last stop ages the
    /// velocity (`velocity_age_var`).
    pub accel_bias_g: f64,
    /// Whether the unit is in a ground vehicle.
    pub vehicle: Vehicle,
    /// `Vehicle::Auto`: the RMS over 3 s of the body x/y rates' swing about
    /// their 3-s mean above which the unit is not in a ground vehicle (rad/s).
    pub handheld_rate: f64,
    /// Velocity variance of a bounded-velocity unit (hand-held): applied on
    /// all axes when not a vehicle.
    pub free_var: f64,
    /// Not a vehicle: time constant of the navigation-frame low-pass of the
    /// specific force (s), the floor of the variance of the tilt it gives
    /// (rad^2), and the share of the motion band's acceleration that adds
    /// to it (squared; see `gravity_lp`).
    pub accel_tau: f64,
    pub lp_tilt_var: f64,
    pub tilt_motion_share2: f64,
    pub zupt_var: f64,
    /// Floor of the at-rest tilt update's variance (accelerometer bias), rad^2.
    pub tilt_floor: f64,
    /// Floor of the zero-rate update's variance, (rad/s)^2.
    pub zru_floor: f64,
    pub yaw_var: f64,
    pub speed_var: f64,
    /// The velocity's NIS against zero beyond which a quiet period is a
    /// cruise, not a stop (stop_sigma^2).
    pub stop_nis: f64,
    /// NIS gate (gate_sigma^2).
    pub gate: f64,
    pub relevel_s: f64,
    pub lever: [f64; 3],
    pub mag: MagUse,
    pub declination: f64,
    pub mag_norm_tol: f64,
    pub mag_dip_tol: f64,
    pub init_angle_sigma: f64,
    pub init_bias_sigma: f64,
    pub init_speed_sigma: f64,
    pub init_scale_sigma: f64,
    pub dwell_s: f64,
    pub turn_rate: f64,
    pub rest: RestParams,
    pub g0_window_s: f64,
    pub speed_aided: bool,
    /// The situation rules switched off (ablation only; none by default).
    pub off: RulesOff,
}
