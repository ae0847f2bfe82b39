//! Validation: every value checked after parsing; the first bad one is
//! returned as (key, message), the caller adds where the key is written.

use super::Config;
use crate::adis::{builtin_profile, BUILTIN_PROFILES};

impl Config {
    /// Check every value; on failure returns (key, message).
    pub fn validate(&self) -> Result<(), (String, String)> {
        fn err<T>(key: &str, msg: impl Into<String>) -> Result<T, (String, String)> {
            Err((key.to_string(), msg.into()))
        }
        fn finite(key: &str, v: f64) -> Result<(), (String, String)> {
            if v.is_finite() {
                Ok(())
            } else {
                err(key, format!("must be a finite number, got {v}"))
            }
        }
        fn positive(key: &str, v: f64) -> Result<(), (String, String)> {
            finite(key, v)?;
            if v > 0.0 {
                Ok(())
            } else {
                err(key, format!("must be > 0, got {v}"))
            }
        }
        fn non_negative(key: &str, v: f64) -> Result<(), (String, String)> {
            finite(key, v)?;
            if v >= 0.0 {
                Ok(())
            } else {
                err(key, format!("must be >= 0, got {v}"))
            }
        }
        fn within(key: &str, v: f64, lo: f64, hi: f64) -> Result<(), (String, String)> {
            finite(key, v)?;
            if (lo..=hi).contains(&v) {
                Ok(())
            } else {
                err(key, format!("must be within {lo}..{hi}, got {v}"))
            }
        }
        fn band(key: &str, b: [f64; 2]) -> Result<(), (String, String)> {
            finite(key, b[0])?;
            finite(key, b[1])?;
            if b[0] <= 0.0 {
                return err(key, format!("lo must be > 0, got {}", b[0]));
            }
            if b[0] >= b[1] {
                return err(key, format!("lo ({}) must be < hi ({})", b[0], b[1]));
            }
            Ok(())
        }
        fn id(key: &str, v: u32) -> Result<(), (String, String)> {
            if v > 0x7FF {
                return err(key, format!("must be an 11-bit CAN ID (0..=0x7FF), got {v:#x}"));
            }
            Ok(())
        }

        let i = &self.input;
        if builtin_profile(&i.profile).is_none() {
            return err("input.profile", format!("unknown profile {:?} (known: {})", i.profile, BUILTIN_PROFILES.join(", ")));
        }
        non_negative("input.rate_hz", i.rate_hz)?;
        for (k, v) in [("input.gyro_lsb", i.gyro_lsb), ("input.accel_lsb", i.accel_lsb), ("input.temp_lsb", i.temp_lsb)] {
            if let Some(v) = v {
                positive(k, v)?;
            }
        }
        if let Some(v) = i.magn_lsb {
            non_negative("input.magn_lsb", v)?;
        }
        if let Some(v) = i.temp_offset {
            finite("input.temp_offset", v)?;
        }
        let ids = i.ids.all();
        for (k, v) in ["input.ids.gyro", "input.ids.accel", "input.ids.magn", "input.ids.aux"].iter().zip(ids) {
            id(k, v)?;
        }
        for a in 0..4 {
            for b in a + 1..4 {
                if ids[a] == ids[b] {
                    return err("input.ids", format!("the four input IDs must differ, {:#x} appears twice", ids[a]));
                }
            }
        }
        if self.can.interface.is_empty() || self.can.interface.len() > 15 {
            return err("can.interface", "must be an interface name of 1 to 15 characters");
        }
        let e = &self.estimator;
        positive("estimator.g0_window_s", e.g0_window_s)?;
        non_negative("estimator.warmup_s", e.warmup_s)?;
        non_negative("estimator.learn_s", e.learn_s)?;
        finite("estimator.declination_deg", e.declination_deg)?;
        if e.declination_deg.abs() > 180.0 {
            return err("estimator.declination_deg", "must be within -180..180");
        }
        positive("estimator.max_gap_s", e.max_gap_s)?;
        let k = &self.ekf;
        positive("ekf.gyro_noise", k.gyro_noise)?;
        non_negative("ekf.bias_walk", k.bias_walk)?;
        positive("ekf.tilt_sigma_deg", k.tilt_sigma_deg)?;
        positive("ekf.yaw_sigma_deg", k.yaw_sigma_deg)?;
        if let Some(v) = k.init_bias_sigma {
            positive("ekf.init_bias_sigma", v)?;
        }
        positive("ekf.init_angle_sigma_deg", k.init_angle_sigma_deg)?;
        let s = &self.switching;
        band("switching.inner", s.inner)?;
        band("switching.outer", s.outer)?;
        if !(s.outer[0] <= s.inner[0] && s.inner[1] <= s.outer[1]) {
            return err("switching.inner", format!("inner band {:?} must lie inside the outer band {:?}", s.inner, s.outer));
        }
        if !(s.inner[0] <= 1.0 && 1.0 <= s.inner[1]) {
            return err("switching.inner", format!("inner band {:?} must contain 1.0 (|a| = g0)", s.inner));
        }
        positive("switching.jerk_ratio", s.jerk_ratio)?;
        positive("switching.jerk_window_s", s.jerk_window_s)?;
        let t = &self.thermal;
        finite("thermal.t0", t.t0)?;
        if !(1..=3).contains(&t.order) {
            return err("thermal.order", format!("must be 1, 2 or 3, got {}", t.order));
        }
        for a in 0..3 {
            finite(&format!("thermal.p1[{a}]"), t.p1[a])?;
            finite(&format!("thermal.p2[{a}]"), t.p2[a])?;
            finite(&format!("thermal.p3[{a}]"), t.p3[a])?;
            finite(&format!("thermal.p4[{a}]"), t.p4[a])?;
            non_negative(&format!("thermal.learn_max_dev[{a}]"), t.learn_max_dev[a])?;
        }
        if t.order < 2 && t.p3.iter().any(|v| *v != 0.0) {
            return err("thermal.p3", format!("is non-zero but thermal.order = {} (p3 is used from order 2)", t.order));
        }
        if t.order < 3 && t.p4.iter().any(|v| *v != 0.0) {
            return err("thermal.p4", format!("is non-zero but thermal.order = {} (p4 is used at order 3)", t.order));
        }
        if let Some(v) = t.t_min {
            finite("thermal.t_min", v)?;
        }
        if let Some(v) = t.t_max {
            finite("thermal.t_max", v)?;
        }
        if let (Some(lo), Some(hi)) = (t.t_min, t.t_max) {
            if lo >= hi {
                return err("thermal.t_max", format!("must be > thermal.t_min ({lo}), got {hi}"));
            }
        }
        non_negative("thermal.learn_after_s", t.learn_after_s)?;
        positive("thermal.learn_min_spread", t.learn_min_spread)?;
        let m = &self.mekf;
        positive("mekf.update_hz", m.update_hz)?;
        positive("mekf.accel_noise", m.accel_noise)?;
        non_negative("mekf.gyro_scale_error", m.gyro_scale_error)?;
        positive("mekf.rest_tilt_sigma_deg", m.rest_tilt_sigma_deg)?;
        positive("mekf.nhc_sigma", m.nhc_sigma)?;
        non_negative("mekf.max_vertical_speed", m.max_vertical_speed)?;
        within("mekf.max_forward_speed", m.max_forward_speed, 0.0, 150.0)?;
        within("mekf.max_reverse_speed", m.max_reverse_speed, 0.0, 30.0)?;
        within("mekf.speed_bound_sigma", m.speed_bound_sigma, 0.01, 30.0)?;
        within("mekf.accel_noise_quiet", m.accel_noise_quiet, 1e-6, 10.0)?;
        within("mekf.accel_ref", m.accel_ref, 1e-3, 50.0)?;
        within("mekf.accel_bias_g", m.accel_bias_g, 0.0, 0.5)?;
        positive("mekf.handheld_rate_dps", m.handheld_rate_dps)?;
        positive("mekf.free_velocity_sigma", m.free_velocity_sigma)?;
        positive("mekf.accel_tau_s", m.accel_tau_s)?;
        positive("mekf.tilt_sigma_deg", m.tilt_sigma_deg)?;
        non_negative("mekf.tilt_motion_share", m.tilt_motion_share)?;
        non_negative("mekf.motion_bias_walk", m.motion_bias_walk)?;
        positive("mekf.zupt_sigma", m.zupt_sigma)?;
        positive("mekf.zru_sigma_dps", m.zru_sigma_dps)?;
        positive("mekf.speed_sigma", m.speed_sigma)?;
        non_negative("mekf.scale_walk", m.scale_walk)?;
        positive("mekf.gate_sigma", m.gate_sigma)?;
        positive("mekf.relevel_s", m.relevel_s)?;
        positive("mekf.init_speed_sigma", m.init_speed_sigma)?;
        positive("mekf.mag_norm_tol", m.mag_norm_tol)?;
        positive("mekf.mag_dip_tol_deg", m.mag_dip_tol_deg)?;
        non_negative("mekf.dwell_s", m.dwell_s)?;
        positive("mekf.turn_rate_dps", m.turn_rate_dps)?;
        let r = &self.rest;
        positive("rest.tau_s", r.tau_s)?;
        non_negative("rest.min_s", r.min_s)?;
        positive("rest.gyro_dev_dps", r.gyro_dev_dps)?;
        positive("rest.accel_dev_g", r.accel_dev_g)?;
        positive("rest.band", r.band)?;
        positive("rest.rate_dps", r.rate_dps)?;
        positive("rest.drift_g", r.drift_g)?;
        let o = &self.output;
        let oids = [o.rate_id, o.attitude_id, o.bias_id, o.status_id];
        for (k, v) in ["output.rate_id", "output.attitude_id", "output.bias_id", "output.status_id"].iter().zip(oids) {
            id(k, v)?;
            if ids.contains(&v) {
                return err(k, format!("{v:#x} is also an input ID"));
            }
        }
        for a in 0..4 {
            for b in a + 1..4 {
                if oids[a] == oids[b] {
                    return err("output", format!("the four output IDs must differ, {:#x} appears twice", oids[a]));
                }
            }
        }
        let d = &self.daemon;
        positive("daemon.save_every_s", d.save_every_s)?;
        positive("daemon.silent_after_s", d.silent_after_s)?;
        let m = &self.mounting;
        for a in 0..3 {
            finite(&format!("mounting.rotation[{a}]"), m.rotation[a])?;
            if m.rotation[a].abs() > 180.0 {
                return err(&format!("mounting.rotation[{a}]"), format!("must be within -180..180 deg, got {}", m.rotation[a]));
            }
            finite(&format!("mounting.lever_arm[{a}]"), m.lever_arm[a])?;
            if m.lever_arm[a].abs() > 20.0 {
                return err(&format!("mounting.lever_arm[{a}]"), format!("must be within -20..20 m, got {}", m.lever_arm[a]));
            }
        }
        if m.rotation[1].abs() > 90.0 {
            return err("mounting.rotation[1]", format!("pitch must be within -90..90 deg (Z-Y-X), got {}", m.rotation[1]));
        }
        let v = &self.speed;
        if v.enabled() {
            if v.message.is_empty() {
                return err("speed.message", "must name the DBC message carrying the speed when speed.dbc is set");
            }
            if v.signals.is_empty() {
                return err("speed.signals", "must name at least one signal when speed.dbc is set");
            }
        }
        positive("speed.scale", v.scale)?;
        positive("speed.timeout_s", v.timeout_s)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use crate::config::bad;

    #[test]
    fn refuses_bad_values_naming_the_key() {
        assert!(bad("[switching]\ninner = [1.02, 1.01]").contains("switching.inner"));
        assert!(bad("[switching]\ninner = [0.7, 1.01]").contains("switching.inner"));
        assert!(bad("[switching]\nouter = [nan, 1.2]").contains("switching.outer"));
        assert!(bad("[input]\nrate_hz = -5.0").contains("input.rate_hz"));
        assert!(bad("[input]\nprofile = \"adis9999\"").contains("input.profile"));
        assert!(bad("[thermal]\np1 = [0.0, inf, 0.0]").contains("thermal.p1[1]"));
        assert!(bad("[thermal]\norder = 4").contains("thermal.order"));
        assert!(bad("[thermal]\norder = 0").contains("thermal.order"));
        assert!(bad("[thermal]\np3 = [0.0, 1e-5, 0.0]").contains("thermal.p3"));
        assert!(bad("[thermal]\norder = 2\np4 = [0.0, 0.0, 1e-7]").contains("thermal.p4"));
        assert!(bad("[thermal]\norder = 3\np4 = [0.0, nan, 0.0]").contains("thermal.p4[1]"));
        assert!(bad("[thermal]\nt_min = 40.0\nt_max = 10.0").contains("thermal.t_max"));
        assert!(bad("[thermal]\nt_min = -inf").contains("thermal.t_min"));
        assert!(bad("[thermal]\nlearn_min_spread = 0.0").contains("thermal.learn_min_spread"));
        assert!(bad("[thermal]\nlearn_max_dev = [0.01, -0.01, 0.01]").contains("thermal.learn_max_dev[1]"));
        assert!(bad("[estimator]\nmode = \"magic\"").contains("mode"));
        assert!(bad("[mekf]\ngate_sigma = 0.0").contains("mekf.gate_sigma"));
        assert!(bad("[mekf]\nupdate_hz = -1.0").contains("mekf.update_hz"));
        assert!(bad("[mekf]\ndwell_s = nan").contains("mekf.dwell_s"));
        assert!(bad("[mekf]\nnhc_sigma = inf").contains("mekf.nhc_sigma"));
        assert!(bad("[mekf]\ntilt_motion_share = -0.1").contains("mekf.tilt_motion_share"));
        assert!(bad("[mekf]\nmotion_bias_walk = -0.001").contains("mekf.motion_bias_walk"));
        assert!(bad("[mekf]\nvehicle = 1").contains("vehicle"));
        assert!(bad("[mekf]\nvehicle = \"sometimes\"").contains("vehicle"));
        assert!(bad("[rest]\nmin_s = -1.0").contains("rest.min_s"));
        assert!(bad("[rest]\ngyro_dev_dps = 0.0").contains("rest.gyro_dev_dps"));
        assert!(bad("[ekf]\ninit_bias_sigma = 0.0").contains("ekf.init_bias_sigma"));
        assert!(bad("[estimator]\nuse_magnetometer = \"sometimes\"").contains("use_magnetometer"));
        assert!(bad("[mounting]\nrotation = [0.0, 95.0, 0.0]").contains("mounting.rotation[1]"));
        assert!(bad("[mounting]\nlever_arm = [0.0, nan, 0.0]").contains("mounting.lever_arm[1]"));
        assert!(bad("[speed]\ndbc = \"car.dbc\"").contains("speed.message"));
        assert!(bad("[speed]\ntimeout_s = 0.0").contains("speed.timeout_s"));
        assert!(bad("[output]\nrate_id = 0x100").contains("output.rate_id"));
    }
}
