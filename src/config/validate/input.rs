//! `[input]`, `[input.ids]`, `[can]`, `[output]` and `[daemon]`.

use super::{distinct, err, id, within, zero_or_within, Check};
use crate::adis::{builtin_profile, BUILTIN_PROFILES};
use crate::config::dbcin::{split_ref, unit_factor, Kind, CHANNELS, WINDOW_MS};
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
    if !i.format.is_adis() {
        return dbc(c);
    }
    let dbc_keys = [
        ("input.dbc", !i.dbc.is_empty()),
        ("input.source_address", i.source_address.is_some()),
        ("input.signals", !i.signals.is_empty()),
        ("input.units", !i.units.is_empty()),
        ("input.sample", !i.sample.is_empty()),
        ("input.valid", !i.valid.is_empty()),
    ];
    if let Some((k, _)) = dbc_keys.iter().find(|(_, set)| *set) {
        return err(k, "describes a DBC input, but [input] format is \"adis\" (the default): set format = \"dbc\"");
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

/// `[input] format = "dbc"`: what can be checked without the DBC file
/// (the file is read, and the names resolved, by `Config::load`).
fn dbc(c: &Config) -> Check {
    let i = &c.input;
    if i.dbc.is_empty() {
        return err("input.dbc", "format = \"dbc\" needs the DBC file (relative to the config file)");
    }
    if i.rate_hz == 0.0 {
        return err("input.rate_hz", "format = \"dbc\" needs the nominal sample rate, Hz (a DBC does not say it)");
    }
    within("input.rate_hz", i.rate_hz, RATE_HZ.0, RATE_HZ.1, "Hz")?;
    if i.ids != crate::adis::InputIds::DEFAULT {
        return err("input.ids", "are the ADIS frames' IDs; a DBC input's IDs are its DBC's");
    }
    if i.profile != crate::config::InputConfig::default().profile {
        return err("input.profile", "is an ADIS part; a DBC input's scales are its DBC's");
    }
    for (k, v) in [
        ("input.gyro_lsb", i.gyro_lsb),
        ("input.accel_lsb", i.accel_lsb),
        ("input.magn_lsb", i.magn_lsb),
        ("input.temp_lsb", i.temp_lsb),
        ("input.temp_offset", i.temp_offset),
    ] {
        if v.is_some() {
            return err(k, "is a scale of the ADIS frames; with format = \"dbc\" the DBC gives the scales");
        }
    }
    if let Some(sa) = i.source_address {
        if sa > 253 {
            return err("input.source_address", format!("must be a J1939 unit's address, 0..=253 (254 is null, 255 global), got {sa}"));
        }
    }
    for (k, r) in i.signals.channels().into_iter().enumerate() {
        for n in r.map(|r| r.names()).unwrap_or_default() {
            split_ref(n.strip_prefix('-').unwrap_or(n)).or_else(|why| err(&format!("input.signals.{}", CHANNELS[k]), why))?;
        }
    }
    for (kind, u) in [(Kind::Gyro, &i.units.gyro), (Kind::Accel, &i.units.accel), (Kind::Temp, &i.units.temp)] {
        if let Some(u) = u {
            if unit_factor(kind, u).is_none() {
                return err(
                    &format!("input.units.{}", kind.key()),
                    format!("{u:?} is not a {} unit gyrocomp converts ({})", kind.key(), kind.known()),
                );
            }
        }
    }
    for (n, r) in i.sample.counter.iter().enumerate() {
        split_ref(r).or_else(|why| err(&format!("input.sample.counter[{n}]"), why))?;
    }
    if let Some(w) = i.sample.window_ms {
        within("input.sample.window_ms", w, WINDOW_MS.0, WINDOW_MS.1, "ms")?;
    }
    if i.sample.counter.is_empty() == i.sample.window_ms.is_none() {
        return err("input.sample", "name either counter (one signal per message) or window_ms, not both and not neither");
    }
    for r in i.valid.keys() {
        split_ref(r).or_else(|why| err("input.valid", why))?;
    }
    Ok(())
}

/// `[can]`, `[output]` and `[daemon]`.
pub(super) fn can_output_daemon(c: &Config) -> Check {
    if c.can.interface.is_empty() || c.can.interface.len() > 15 {
        return err("can.interface", "must be an interface name of 1 to 15 characters");
    }
    // (a DBC input's IDs are checked against these when the DBC is loaded)
    let ids = if c.input.format.is_adis() { c.input.ids.all() } else { [u32::MAX; 4] };
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
