//! `[mounting]` and `[speed]`: the sensor in the vehicle, the vehicle's speed.

use super::{err, within, within3, Check};
use crate::config::{MountingConfig, SpeedConfig};

pub(super) fn mounting(m: &MountingConfig) -> Check {
    within3("mounting.rotation", &m.rotation, -180.0, 180.0, "deg")?;
    // a sensor farther than 20 m from the rear axle is not in the car
    within3("mounting.lever_arm", &m.lever_arm, -20.0, 20.0, "m")?;
    if m.rotation[1].abs() > 90.0 {
        return err("mounting.rotation[1]", format!("pitch must be within -90..90 deg (Z-Y-X), got {}", m.rotation[1]));
    }
    Ok(())
}

pub(super) fn speed(v: &SpeedConfig) -> Check {
    if v.enabled() {
        if v.message.is_empty() {
            return err("speed.message", "must name the DBC message carrying the speed when speed.dbc is set");
        }
        if v.signals.is_empty() {
            return err("speed.signals", "must name at least one signal when speed.dbc is set");
        }
    } else {
        // a half-written [speed]: without the DBC nothing would be read, and nothing said
        for (key, set) in [("speed.signals", !v.signals.is_empty()), ("speed.message", !v.message.is_empty())] {
            if set {
                return err(key, "is set but speed.dbc is empty, so no speed would be read: set speed.dbc to the car's DBC file");
            }
        }
    }
    // a tyre correction is a few %; 0.1..10 also mends a DBC factor off by ten
    within("speed.scale", v.scale, 0.1, 10.0, "")?;
    // a speed older than 10 s says nothing about the car now
    within("speed.timeout_s", v.timeout_s, 0.001, 10.0, "s")
}
