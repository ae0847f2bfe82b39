//! `[thermal]`: the bias curve `b(T) = p2 + p1 d + p3 d^2 + p4 d^3`, deg/s,
//! `d = T - t0` in deg C, and its field learning.
//!
//! Temperatures lie within -60..150 deg C (the automotive grades reach -40
//! and 150). Each term of the curve stays within 100 deg/s at 100 deg C from
//! t0 (|p1| <= 1 deg/s/K, |p3| <= 0.01, |p4| <= 1e-4): real parts drift by
//! 0.002..0.2 deg/s/K, and a bias of 100 deg/s is beyond any MEMS gyro's.

use super::{err, within, within3, Check};
use crate::config::ThermalConfig;

/// Temperatures of the curve, deg C.
const T_RANGE: (f64, f64) = (-60.0, 150.0);

pub(super) fn thermal(t: &ThermalConfig) -> Check {
    within("thermal.t0", t.t0, T_RANGE.0, T_RANGE.1, "deg C")?;
    if !(1..=3).contains(&t.order) {
        return err("thermal.order", format!("must be 1, 2 or 3, got {}", t.order));
    }
    within3("thermal.p1", &t.p1, -1.0, 1.0, "deg/s per deg C")?;
    // the turn-on bias of consumer MEMS gyros is up to 20 deg/s
    within3("thermal.p2", &t.p2, -100.0, 100.0, "deg/s")?;
    within3("thermal.p3", &t.p3, -0.01, 0.01, "deg/s per (deg C)^2")?;
    within3("thermal.p4", &t.p4, -1e-4, 1e-4, "deg/s per (deg C)^3")?;
    if t.order < 2 && t.p3.iter().any(|v| *v != 0.0) {
        return err("thermal.p3", format!("is non-zero but thermal.order = {} (p3 is used from order 2)", t.order));
    }
    if t.order < 3 && t.p4.iter().any(|v| *v != 0.0) {
        return err("thermal.p4", format!("is non-zero but thermal.order = {} (p4 is used at order 3)", t.order));
    }
    if let Some(v) = t.t_min {
        within("thermal.t_min", v, T_RANGE.0, T_RANGE.1, "deg C")?;
    }
    if let Some(v) = t.t_max {
        within("thermal.t_max", v, T_RANGE.0, T_RANGE.1, "deg C")?;
    }
    if let (Some(lo), Some(hi)) = (t.t_min, t.t_max) {
        if lo >= hi {
            return err("thermal.t_max", format!("must be > thermal.t_min ({lo}), got {hi}"));
        }
    }
    // a timer after power-on: beyond a day it never starts in a vehicle's power cycle
    within("thermal.learn_after_s", t.learn_after_s, 0.0, 86_400.0, "s")?;
    within("thermal.learn_min_spread", t.learn_min_spread, 0.1, 100.0, "deg C")?;
    within3("thermal.learn_max_dev", &t.learn_max_dev, 0.0, 1.0, "deg/s per deg C")
}
