//! `[estimator]`, `[ekf]` (the paper's filter) and `[switching]`.

use super::{err, within, Check};
use crate::config::{Config, EkfConfig, SwitchingConfig};

/// `[estimator]`: windows and timers in seconds, and the gap that is a resync.
pub(super) fn estimator(c: &Config) -> Check {
    let e = &c.estimator;
    // g0 is the mean |a| while the unit is still after power-on: a minute is long
    within("estimator.g0_window_s", e.g0_window_s, 0.001, 60.0, "s")?;
    // MEMS warm-up transients last minutes; an hour covers the slowest
    within("estimator.warmup_s", e.warmup_s, 0.0, 3600.0, "s")?;
    within("estimator.learn_s", e.learn_s, 0.0, 3600.0, "s")?;
    within("estimator.declination_deg", e.declination_deg, -180.0, 180.0, "deg")?;
    within("estimator.max_gap_s", e.max_gap_s, 0.001, 60.0, "s")?;
    // shorter than one sample period, every sample would be a resync
    let period = 1.0 / c.profile().rate_hz;
    if e.max_gap_s < period {
        return err(
            "estimator.max_gap_s",
            format!("must be at least one sample period ({period} s at {} Hz), got {} s", c.profile().rate_hz, e.max_gap_s),
        );
    }
    Ok(())
}

/// `[ekf]`: noise densities and sigmas. The lower bounds keep every
/// variance a normal f64 (a sigma of 1e-300 squares to zero and the filter
/// divides by it); the upper ones are beyond any meaning (an angle's sigma
/// beyond half a turn, a bias beyond any MEMS part's range).
pub(super) fn ekf(k: &EkfConfig) -> Check {
    // navigation-grade gyros 1e-5, MEMS 0.003..0.1 deg/s/sqrt(Hz)
    within("ekf.gyro_noise", k.gyro_noise, 1e-6, 10.0, "deg/s/sqrt(Hz)")?;
    within("ekf.bias_walk", k.bias_walk, 0.0, 1.0, "deg/s/sqrt(s)")?;
    within("ekf.tilt_sigma_deg", k.tilt_sigma_deg, 1e-4, 90.0, "deg")?;
    within("ekf.yaw_sigma_deg", k.yaw_sigma_deg, 1e-4, 180.0, "deg")?;
    if let Some(v) = k.init_bias_sigma {
        // MEMS turn-on bias: up to 20 deg/s (consumer parts)
        within("ekf.init_bias_sigma", v, 1e-4, 100.0, "deg/s")?;
    }
    within("ekf.init_angle_sigma_deg", k.init_angle_sigma_deg, 1e-3, 180.0, "deg")
}

/// `[switching]`: the bands on |a|/g0 and the acceleration-change criterion.
pub(super) fn switching(s: &SwitchingConfig) -> Check {
    band("switching.inner", s.inner)?;
    band("switching.outer", s.outer)?;
    if !(s.outer[0] <= s.inner[0] && s.inner[1] <= s.outer[1]) {
        return err("switching.inner", format!("inner band {:?} must lie inside the outer band {:?}", s.inner, s.outer));
    }
    if !(s.inner[0] <= 1.0 && 1.0 <= s.inner[1]) {
        return err("switching.inner", format!("inner band {:?} must contain 1.0 (|a| = g0)", s.inner));
    }
    within("switching.jerk_ratio", s.jerk_ratio, 1e-3, 100.0, "per s")?;
    // the window is a ring of jerk_window_s x rate_hz samples (10 s at 100 kHz: 32 MB)
    within("switching.jerk_window_s", s.jerk_window_s, 0.01, 10.0, "s")
}

/// A band `[lo, hi]` on |a|/g0, `0.05 <= lo < hi <= 20` (20 g: the
/// largest accelerometer ranges are 16 g).
fn band(key: &str, b: [f64; 2]) -> Check {
    within(&format!("{key}[0]"), b[0], 0.05, 20.0, "(|a|/g0)")?;
    within(&format!("{key}[1]"), b[1], 0.05, 20.0, "(|a|/g0)")?;
    if b[0] >= b[1] {
        return err(key, format!("lo ({}) must be < hi ({})", b[0], b[1]));
    }
    Ok(())
}
