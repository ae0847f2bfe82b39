//! `[mekf]` (the default filter) and `[rest]` (the standstill detector).
//!
//! Sigmas and noise densities are bounded below where their square would
//! still be far from an f64's limits and far under any sensor's noise, and
//! above where they no longer say anything (a velocity sigma beyond the
//! speed of a car, an angle's beyond a half turn). Timers are bounded by an
//! hour: longer, the condition never completes in a drive.

use super::{within, Check};
use crate::config::{MekfConfig, RestConfig};

pub(super) fn mekf(m: &MekfConfig) -> Check {
    // the state is propagated at every sample; ticks faster than the samples are one per sample
    within("mekf.update_hz", m.update_hz, 1.0, 10_000.0, "Hz")?;
    within("mekf.gyro_scale_error", m.gyro_scale_error, 0.0, 0.5, "")?;
    within("mekf.rest_tilt_sigma_deg", m.rest_tilt_sigma_deg, 1e-4, 10.0, "deg")?;
    within("mekf.accel_noise", m.accel_noise, 1e-5, 100.0, "m/s^2/sqrt(Hz)")?;
    within("mekf.handheld_rate_dps", m.handheld_rate_dps, 0.1, 1000.0, "deg/s")?;
    within("mekf.nhc_sigma", m.nhc_sigma, 1e-4, 10.0, "m/s")?;
    within("mekf.max_vertical_speed", m.max_vertical_speed, 0.0, 50.0, "m/s")?;
    within("mekf.max_forward_speed", m.max_forward_speed, 0.0, 150.0, "m/s")?;
    within("mekf.max_reverse_speed", m.max_reverse_speed, 0.0, 30.0, "m/s")?;
    within("mekf.speed_bound_sigma", m.speed_bound_sigma, 0.01, 30.0, "m/s")?;
    within("mekf.accel_noise_quiet", m.accel_noise_quiet, 1e-6, 10.0, "m/s^2/sqrt(Hz)")?;
    within("mekf.accel_ref", m.accel_ref, 1e-3, 50.0, "m/s^2")?;
    within("mekf.accel_bias_g", m.accel_bias_g, 0.0, 0.5, "g")?;
    within("mekf.free_velocity_sigma", m.free_velocity_sigma, 1e-3, 100.0, "m/s")?;
    within("mekf.accel_tau_s", m.accel_tau_s, 0.1, 600.0, "s")?;
    within("mekf.tilt_sigma_deg", m.tilt_sigma_deg, 1e-4, 90.0, "deg")?;
    within("mekf.tilt_motion_share", m.tilt_motion_share, 0.0, 1.0, "")?;
    within("mekf.motion_bias_walk", m.motion_bias_walk, 0.0, 1.0, "deg/s/sqrt(s)")?;
    within("mekf.zupt_sigma", m.zupt_sigma, 1e-5, 10.0, "m/s")?;
    within("mekf.zru_sigma_dps", m.zru_sigma_dps, 1e-6, 10.0, "deg/s")?;
    within("mekf.speed_sigma", m.speed_sigma, 1e-4, 30.0, "m/s")?;
    within("mekf.scale_walk", m.scale_walk, 0.0, 0.1, "1/sqrt(s)")?;
    within("mekf.gate_sigma", m.gate_sigma, 0.5, 100.0, "sigma")?;
    within("mekf.stop_sigma", m.stop_sigma, 0.5, 100.0, "sigma")?;
    within("mekf.relevel_s", m.relevel_s, 0.01, 3600.0, "s")?;
    within("mekf.init_speed_sigma", m.init_speed_sigma, 1e-3, 150.0, "m/s")?;
    // 100 and 180 open the gate (an experiment: every field is taken as Earth's)
    within("mekf.mag_norm_tol", m.mag_norm_tol, 1e-3, 100.0, "")?;
    within("mekf.mag_dip_tol_deg", m.mag_dip_tol_deg, 0.01, 180.0, "deg")?;
    within("mekf.dwell_s", m.dwell_s, 0.0, 3600.0, "s")?;
    within("mekf.turn_rate_dps", m.turn_rate_dps, 1e-3, 1000.0, "deg/s")?;
    crate::estimator::mekf::RulesOff::from_names(&m.ablate).map(|_| ()).map_err(|e| ("mekf.ablate".to_string(), e))
}

pub(super) fn rest(r: &RestConfig) -> Check {
    within("rest.tau_s", r.tau_s, 0.01, 60.0, "s")?;
    within("rest.min_s", r.min_s, 0.0, 3600.0, "s")?;
    within("rest.gyro_dev_dps", r.gyro_dev_dps, 1e-4, 100.0, "deg/s")?;
    within("rest.accel_dev_g", r.accel_dev_g, 1e-5, 1.0, "g")?;
    within("rest.band", r.band, 1e-5, 0.5, "")?;
    within("rest.rate_dps", r.rate_dps, 1e-4, 100.0, "deg/s")?;
    within("rest.drift_g", r.drift_g, 1e-5, 1.0, "g")
}
