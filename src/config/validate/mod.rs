//! Validation: every value checked after parsing; the first bad one is
//! returned as (key, message), the caller adds where the key is written.
//!
//! Every numeric key has a physical range (written beside the key in
//! `config/gyrocomp.toml`): a value outside it is no setting of a real part
//! or vehicle, and some would break the run (a window of a million seconds
//! is a buffer of gigabytes, a sigma of 1e-300 squares to zero, a scale of
//! 1e300 makes every sample infinite). One file per group of sections.

mod estimator;
mod input;
mod mekf;
#[cfg(test)]
mod tests;
mod thermal;
mod vehicle;

use super::Config;
pub use input::{ACCEL_LSB, GYRO_LSB, MAGN_LSB, RATE_HZ, TEMP_LSB};

/// A check's result: the key and why its value is refused.
type Check = Result<(), (String, String)>;

impl Config {
    /// Check every value; on failure returns (key, message).
    pub fn validate(&self) -> Check {
        input::input(self)?;
        input::can_output_daemon(self)?;
        estimator::estimator(self)?;
        estimator::ekf(&self.ekf)?;
        estimator::switching(&self.switching)?;
        thermal::thermal(&self.thermal)?;
        mekf::mekf(&self.mekf)?;
        mekf::rest(&self.rest)?;
        vehicle::mounting(&self.mounting)?;
        vehicle::speed(&self.speed)
    }
}

fn err<T>(key: &str, msg: impl Into<String>) -> Result<T, (String, String)> {
    Err((key.to_string(), msg.into()))
}

/// A number as a user writes it: 1e300 and 1e-9 in exponent form, not 301 digits.
pub(crate) fn num(v: f64) -> String {
    let a = v.abs();
    if a != 0.0 && a.is_finite() && !(1e-4..1e6).contains(&a) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

fn finite(key: &str, v: f64) -> Check {
    if v.is_finite() {
        Ok(())
    } else {
        err(key, format!("must be a finite number, got {v}"))
    }
}

/// `lo <= v <= hi`, in `unit` (empty for a ratio).
fn within(key: &str, v: f64, lo: f64, hi: f64, unit: &str) -> Check {
    finite(key, v)?;
    if (lo..=hi).contains(&v) {
        Ok(())
    } else {
        let unit = if unit.is_empty() { String::new() } else { format!(" {unit}") };
        err(key, format!("must be within {}..{}{unit}, got {}", num(lo), num(hi), num(v)))
    }
}

/// 0 (the key's "off" or "default") or `lo <= v <= hi`.
fn zero_or_within(key: &str, v: f64, lo: f64, hi: f64, unit: &str, zero_means: &str) -> Check {
    finite(key, v)?;
    if v == 0.0 || (lo..=hi).contains(&v) {
        Ok(())
    } else {
        err(key, format!("must be 0 ({zero_means}) or within {}..{} {unit}, got {}", num(lo), num(hi), num(v)))
    }
}

/// Each of three per-axis values within `lo..hi` (keys `key[0]`..`key[2]`).
fn within3(key: &str, v: &[f64; 3], lo: f64, hi: f64, unit: &str) -> Check {
    for (a, x) in v.iter().enumerate() {
        within(&format!("{key}[{a}]"), *x, lo, hi, unit)?;
    }
    Ok(())
}

/// An 11-bit CAN ID.
fn id(key: &str, v: u32) -> Check {
    if v > 0x7FF {
        return err(key, format!("must be an 11-bit CAN ID (0..=0x7FF), got {v:#x}"));
    }
    Ok(())
}

/// `n` IDs that must all differ.
fn distinct(key: &str, what: &str, ids: &[u32]) -> Check {
    for a in 0..ids.len() {
        if ids[a + 1..].contains(&ids[a]) {
            return err(key, format!("the {what} must differ, {:#x} appears twice", ids[a]));
        }
    }
    Ok(())
}
