//! `[input]`, `[input.ids]`, `[can]`, `[output]` and `[daemon]`.

use super::{distinct, err, id, within, zero_or_within, Check};
use crate::adis::{builtin_profile, BUILTIN_PROFILES};
use crate::config::Config;

/// Range of `[input] rate_hz` other than 0, Hz: the slowest data set worth
/// estimating on to four times the fastest MEMS output data rate (32 kHz).
pub const RATE_HZ: (f64, f64) = (1.0, 100_000.0);
/// Range of `[input] gyro_lsb`, deg/s per LSB: the built-in parts use
/// 0.00625..0.05; a 16-bit register then spans +-0.33 to +-32767 deg/s.
pub const GYRO_LSB: (f64, f64) = (1e-5, 1.0);
/// Range of `[input] accel_lsb`, g per LSB (parts: 0.25e-3..3.33e-3).
pub const ACCEL_LSB: (f64, f64) = (1e-6, 0.1);
/// Range of `[input] magn_lsb` other than 0 (no magnetometer), gauss per
/// LSB (parts: 0.14e-3..0.5e-3; Earth's field is 0.25..0.65 gauss).
pub const MAGN_LSB: (f64, f64) = (1e-7, 0.01);
/// Range of `[input] temp_lsb`, deg C per LSB (parts: 0.07..0.14).
pub const TEMP_LSB: (f64, f64) = (1e-4, 10.0);

/// `[input]` and its IDs.
pub(super) fn input(c: &Config) -> Check {
    let i = &c.input;
    if builtin_profile(&i.profile).is_none() {
        return err("input.profile", format!("unknown profile {:?} (known: {})", i.profile, BUILTIN_PROFILES.join(", ")));
    }
    zero_or_within("input.rate_hz", i.rate_hz, RATE_HZ.0, RATE_HZ.1, "Hz", "the profile's nominal rate")?;
    for (k, v, (lo, hi), unit) in [
        ("input.gyro_lsb", i.gyro_lsb, GYRO_LSB, "deg/s per LSB"),
        ("input.accel_lsb", i.accel_lsb, ACCEL_LSB, "g per LSB"),
        ("input.temp_lsb", i.temp_lsb, TEMP_LSB, "deg C per LSB"),
    ] {
        if let Some(v) = v {
            within(k, v, lo, hi, unit)?;
        }
    }
    if let Some(v) = i.magn_lsb {
        zero_or_within("input.magn_lsb", v, MAGN_LSB.0, MAGN_LSB.1, "gauss per LSB", "no magnetometer")?;
    }
    if let Some(v) = i.temp_offset {
        within("input.temp_offset", v, -100.0, 200.0, "deg C")?;
    }
    let ids = i.ids.all();
    for (k, v) in ["input.ids.gyro", "input.ids.accel", "input.ids.magn", "input.ids.aux"].iter().zip(ids) {
        id(k, v)?;
    }
    distinct("input.ids", "four input IDs", &ids)
}

/// `[can]`, `[output]` and `[daemon]`.
pub(super) fn can_output_daemon(c: &Config) -> Check {
    if c.can.interface.is_empty() || c.can.interface.len() > 15 {
        return err("can.interface", "must be an interface name of 1 to 15 characters");
    }
    let ids = c.input.ids.all();
    let o = &c.output;
    for (k, v) in o.keyed_ids() {
        id(k, v)?;
    }
    // the IDs sent (aid_id only with aid_frame on) differ from the input IDs
    // and from each other; a clash is named at the later key
    for (i, (k, v)) in o.sent().enumerate() {
        if ids.contains(&v) {
            return err(k, format!("{v:#x} is also an input ID"));
        }
        if let Some((other, _)) = o.sent().take(i).find(|(_, w)| *w == v) {
            return err(k, format!("{v:#x} is also {other}: the output IDs must differ"));
        }
    }
    let d = &c.daemon;
    within("daemon.save_every_s", d.save_every_s, 0.1, 86_400.0, "s")?;
    within("daemon.silent_after_s", d.silent_after_s, 0.01, 3600.0, "s")
}
