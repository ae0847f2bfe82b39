//! `gyrocomp import`: a CSV recording into the ADIS contract.
//!
//! `gyrocomp import --csv IN.csv[.gz] --out OUT.log [--rate HZ] [--profile NAME]
//! [--config-out SNIPPET.toml] [--axes MAP] [--can CAR.log[.gz]]`
//!
//! - Input: `t,gx,gy,gz,ax,ay,az,mx,my,mz,temp` (s, deg/s, g, gauss, deg C;
//!   FRD body axes; see [`csv`]). `--axes` maps another body convention onto
//!   FRD: `x,-y,-z` takes a FLU (x forward, y left, z up) recording; the map
//!   must be a rotation (a reflection is refused).
//! - Output: a `candump -l` log in the README's contract: four frames per
//!   sample (0x100..0x103) with the checksum, DATA_CNT = round((t - t0) x
//!   rate) mod 65536 (a time gap becomes a counter gap), each frame stamped
//!   `--epoch` (default 1 700 000 000 s, the simulator's) + t, frames 120 us
//!   apart. The rate is `--rate` or 1 / the median spacing of `t`.
//! - Scales: with `--profile`, the profile's LSB on every channel it covers;
//!   otherwise (or without a profile) the finest LSB, to two significant
//!   digits, whose 16-bit range covers the channel's largest |value| x 1.25.
//!   Temperature is coded about the profile's offset (adis16448: 31 C); a
//!   recording without temperature sends TEMP_OUT = 0.
//! - `--config-out` writes the `[input]` section (profile, rate, every LSB,
//!   the input IDs) and what the recording implies: no magnetometer column
//!   -> `[estimator] use_magnetometer = false`; no temperature column -> the
//!   thermal curve off (`[thermal] enabled = false`). Replaying the log
//!   with it gives the CSV's values within half an LSB.
//! - `--can CAR.log` merges another candump log into the output by
//!   timestamp (its lines copied as they are), so one log carries the IMU and
//!   the vehicle's frames as a real bus would. A line of it that is not a
//!   candump line, or a frame on one of the IMU's IDs, is refused.
//! - Bad input is an error naming the file, line and column; outputs are
//!   written under temporary names and renamed only when everything succeeded.

pub mod csv;
pub mod encode;

use crate::config::Config;
use crate::outfile::{refuse_inputs_as_outputs, OutFile};
pub use csv::{open_text, read_imu_csv, read_imu_csv_from, AxesMap, ImuCsv};
pub use encode::{choose_scales, plan_counter, write_log, LogStats, Merge, ScaleSource, Scales, Timing};
use std::io::Write;
use std::path::{Path, PathBuf};

/// The `import` subcommand.
#[derive(clap::Args, Debug, Clone)]
pub struct ImportArgs {
    /// The recording: t,gx,gy,gz,ax,ay,az[,mx,my,mz][,temp] (s, deg/s, g,
    /// gauss, deg C), gzip allowed. Required.
    #[arg(long, value_name = "IN.csv")]
    pub csv: PathBuf,
    /// The candump -l log to write. Required.
    #[arg(long, value_name = "OUT.log")]
    pub out: PathBuf,
    /// Sample rate, Hz, 1..100000 (the config's [input] rate_hz range).
    /// Default: 1 / the median spacing of t.
    #[arg(long, value_name = "HZ", allow_negative_numbers = true, value_parser = parse_rate)]
    pub rate: Option<f64>,
    /// Use this profile's scales where they cover the data (adis16448,
    /// adis16405, adis16465-1). Default: the finest LSB per channel whose
    /// 16-bit range covers the data with headroom.
    #[arg(long, value_name = "NAME")]
    pub profile: Option<String>,
    /// Write the matching config snippet ([input], and what the recording
    /// implies: magnetometer or thermal curve off). Default: none.
    #[arg(long, value_name = "SNIPPET.toml")]
    pub config_out: Option<PathBuf>,
    /// The recording's body axes as FRD: e.g. x,-y,-z for a FLU recording.
    #[arg(long, default_value = "x,y,z")]
    pub axes: String,
    /// Merge this candump log (another bus, e.g. the vehicle's) into the
    /// output by timestamp; gzip allowed. Default: none.
    #[arg(long, value_name = "CAR.log")]
    pub can: Option<PathBuf>,
    /// Interface name on the IMU's lines.
    #[arg(long, default_value = "can0")]
    pub iface: String,
    /// Log time of t = 0, s since 1970: 0..9999999999 (up to the year 2286,
    /// the ten digits candump writes).
    #[arg(long, default_value_t = crate::sim::LOG_EPOCH_S, allow_negative_numbers = true, value_parser = parse_epoch)]
    pub epoch: u64,
    /// Leave out the samples before this t (s, the recording's clock), and
    /// the merged log's lines before the first sample kept: the unit powered
    /// on there (a daemon restarted while moving). Default: from the first
    /// sample.
    #[arg(long, value_name = "S", allow_hyphen_values = true)]
    pub from: Option<f64>,
}

/// The latest `--epoch`, s since 1970 (the year 2286): the ten digits of
/// seconds candump writes; replay reads at most twelve.
pub const MAX_EPOCH_S: u64 = 9_999_999_999;

/// clap value parser of `--rate`: a number of Hz within the config's
/// `[input] rate_hz` range.
pub fn parse_rate(s: &str) -> Result<f64, String> {
    let (lo, hi) = crate::config::RATE_HZ;
    let v: f64 = s.trim().parse().map_err(|_| format!("{s:?} is not a number of Hz (want {lo}..{hi} Hz)"))?;
    if !(v.is_finite() && (lo..=hi).contains(&v)) {
        return Err(format!("a sample rate must be within {lo}..{hi} Hz (the config's [input] rate_hz range), got {s}"));
    }
    Ok(v)
}

/// clap value parser of `--epoch`: whole seconds since 1970, 0..=[`MAX_EPOCH_S`].
pub fn parse_epoch(s: &str) -> Result<u64, String> {
    let want = format!("want whole seconds since 1970, 0..={MAX_EPOCH_S} (up to the year 2286)");
    match s.trim().parse::<u64>() {
        Ok(v) if v <= MAX_EPOCH_S => Ok(v),
        Ok(_) => Err(format!("{s} is too far ahead: {want}")),
        Err(_) => Err(format!("{s:?}: {want}")),
    }
}

/// Options of an import (the args without the output paths).
#[derive(Clone, Debug)]
pub struct ImportOptions {
    pub rate: Option<f64>,
    pub profile: Option<String>,
    pub axes: AxesMap,
    pub iface: String,
    pub epoch: u64,
    /// Samples before this t are left out (`--from`).
    pub from: Option<f64>,
}

impl Default for ImportOptions {
    fn default() -> Self {
        ImportOptions {
            rate: None,
            profile: None,
            axes: AxesMap::IDENTITY,
            iface: "can0".into(),
            epoch: crate::sim::LOG_EPOCH_S,
            from: None,
        }
    }
}

impl ImportOptions {
    fn check(&self) -> Result<(), String> {
        if let Some(r) = self.rate {
            parse_rate(&r.to_string()).map_err(|e| format!("--rate: {e}"))?;
        }
        if self.epoch > MAX_EPOCH_S {
            return Err(format!("--epoch {}: {}", self.epoch, parse_epoch(&self.epoch.to_string()).unwrap_err()));
        }
        if !self.axes.is_rotation() {
            return Err("--axes: the map is a reflection (it would turn a right-handed frame left-handed); flip one more sign".into());
        }
        if let Some(f) = self.from {
            if !f.is_finite() {
                return Err(format!("--from must be a finite number of seconds, got {f}"));
            }
        }
        if self.iface.is_empty() || self.iface.len() > 15 || self.iface.contains(char::is_whitespace) {
            return Err(format!("--iface {:?}: want an interface name of 1 to 15 characters without spaces", self.iface));
        }
        Ok(())
    }
}

/// What an import did.
#[derive(Clone, Debug)]
pub struct Imported {
    pub samples: usize,
    /// `t` of the first sample, s: the reference time of the log's first
    /// sample (`evaluate --offset`).
    pub t0: f64,
    pub duration_s: f64,
    pub scales: Scales,
    pub timing: Timing,
    pub log: LogStats,
    pub has_magn: bool,
    pub has_temp: bool,
    pub ignored: Vec<String>,
    /// The config snippet (always made; written with `--config-out`).
    pub snippet: String,
}

impl Imported {
    /// The human summary.
    pub fn render(&self, src: &str) -> String {
        let p = &self.scales.profile;
        let how = |k: usize| match self.scales.source[k] {
            ScaleSource::Profile => format!("profile {}", p.name),
            ScaleSource::Auto => format!("auto: max {:.4}", self.scales.max[k]),
            ScaleSource::Unused => "no data".to_string(),
        };
        let mut s = format!(
            "import {src}: {} samples, {:.3} s, rate {} Hz ({}); {} counter gaps ({} samples), {} samples crowded onto the next period\n",
            self.samples,
            self.duration_s,
            self.timing.rate_hz,
            if self.timing.estimated { "from t" } else { "--rate" },
            self.timing.gaps,
            self.timing.lost,
            self.timing.crowded
        );
        s += &format!(
            "scales: gyro {} deg/s ({}), accel {} g ({}), magn {} gauss ({}), temp {} C about {} C ({})\n",
            p.gyro_lsb,
            how(0),
            p.accel_lsb,
            how(1),
            p.magn_lsb,
            how(2),
            p.temp_lsb,
            p.temp_offset,
            how(3)
        );
        s += &format!(
            "magnetometer {}, temperature {}{}\n",
            if self.has_magn { "recorded" } else { "absent (off in the snippet)" },
            if self.has_temp { "recorded" } else { "absent (thermal curve off in the snippet)" },
            if self.ignored.is_empty() { String::new() } else { format!("; ignored columns: {}", self.ignored.join(", ")) }
        );
        s += &format!("frames: {} IMU, {} merged from the other log", self.log.imu_frames, self.log.merged_lines);
        if self.log.merged_before > 0 {
            s += &format!(" ({} of its lines before the first sample left out)", self.log.merged_before);
        }
        s += "\n";
        if self.t0 != 0.0 {
            s += &format!(
                "the first sample is t = {} s in the CSV (the log's sample clock starts at 0): score it against a reference on the CSV's clock with `evaluate --offset {}`\n",
                self.t0, self.t0
            );
        }
        s
    }
}

/// The config snippet of an import.
pub fn snippet(src: &str, sc: &Scales, tm: &Timing, has_magn: bool, has_temp: bool, samples: usize) -> String {
    let p = &sc.profile;
    let mut s = format!("# gyrocomp import of {src}: {samples} samples\n");
    s += "[input]\n";
    s += &format!("profile = \"{}\"\n", p.name);
    s += &format!("rate_hz = {:?}\n", tm.rate_hz);
    s += &format!("gyro_lsb = {:?}\naccel_lsb = {:?}\nmagn_lsb = {:?}\n", p.gyro_lsb, p.accel_lsb, p.magn_lsb);
    s += &format!("temp_lsb = {:?}\ntemp_offset = {:?}\n", p.temp_lsb, p.temp_offset);
    s += "[input.ids]\ngyro = 0x100\naccel = 0x101\nmagn = 0x102\naux = 0x103\n";
    if !has_magn {
        s += "[estimator]\n# the recording has no magnetometer\nuse_magnetometer = false\n";
    }
    if !has_temp {
        s += "[thermal]\n# the recording has no temperature: the thermal curve is off\n";
        s += "enabled = false\n";
    }
    s
}

/// Lay a snippet (TOML) over a config, key by key, and validate the result.
pub fn overlay(base: &Config, snippet: &str, origin: &str) -> Result<Config, String> {
    fn merge(a: &mut toml::Value, b: &toml::Value) {
        match (a, b) {
            (toml::Value::Table(at), toml::Value::Table(bt)) => {
                for (k, v) in bt {
                    match at.get_mut(k) {
                        Some(av) if av.is_table() && v.is_table() => merge(av, v),
                        _ => {
                            at.insert(k.clone(), v.clone());
                        }
                    }
                }
            }
            (a, b) => *a = b.clone(),
        }
    }
    let mut v: toml::Value = toml::from_str(&base.to_toml()).map_err(|e| format!("{origin}: {e}"))?;
    let s: toml::Value = toml::from_str(snippet).map_err(|e| format!("{origin}: {e}"))?;
    merge(&mut v, &s);
    let text = toml::to_string(&v).map_err(|e| format!("{origin}: {e}"))?;
    Config::parse(&text, origin).map_err(|e| e.to_string())
}

/// Import a recording into `out` (any writer); `merge` is another bus's log.
pub fn import_to<W: Write>(csv: &Path, o: &ImportOptions, merge: Option<Merge<'_>>, out: &mut W) -> Result<Imported, String> {
    o.check()?;
    let src = csv.display().to_string();
    let mut data = read_imu_csv(csv, &o.axes)?;
    if let Some(f) = o.from {
        let end = data.t[data.len() - 1];
        data.keep_from(f);
        if data.is_empty() {
            return Err(format!("{src}: no sample at or after --from {f} s (the recording ends at t = {end} s)"));
        }
    }
    let scales = choose_scales(&data, o.profile.as_deref()).map_err(|e| if e.starts_with("line ") { format!("{src} {e}") } else { e })?;
    let timing = plan_counter(&data, o.rate, &src)?;
    let merge = merge.map(|m| Merge { drop_before: o.from.is_some(), ..m });
    let log = write_log(out, &data, &scales, &timing, o.epoch * 1_000_000, &o.iface, merge).map_err(|e| {
        if e.starts_with("line ") {
            format!("{src} {e}")
        } else {
            e
        }
    })?;
    let has_magn = data.magn.is_some();
    let has_temp = data.temp.is_some();
    let name = csv.file_name().map(|n| n.to_string_lossy().to_string()).unwrap_or_else(|| src.clone());
    let snippet = snippet(&name, &scales, &timing, has_magn, has_temp, data.len());
    Ok(Imported {
        samples: data.len(),
        t0: data.t[0],
        duration_s: data.t[data.len() - 1] - data.t[0],
        scales,
        timing,
        log,
        has_magn,
        has_temp,
        ignored: data.ignored,
        snippet,
    })
}

/// Import into memory: the log's bytes and what the import did.
pub fn import_to_memory(csv: &Path, can: Option<&Path>, o: &ImportOptions) -> Result<(Vec<u8>, Imported), String> {
    let merge = can.map(Merge::open).transpose()?;
    let mut buf = Vec::new();
    let imp = import_to(csv, o, merge, &mut buf)?;
    Ok((buf, imp))
}

/// `gyrocomp import`.
pub fn run(a: &ImportArgs) -> Result<(), String> {
    let o = ImportOptions {
        rate: a.rate,
        profile: a.profile.clone(),
        axes: AxesMap::parse(&a.axes)?,
        iface: a.iface.clone(),
        epoch: a.epoch,
        from: a.from,
    };
    let mut inputs: Vec<&Path> = vec![&a.csv];
    if let Some(c) = &a.can {
        inputs.push(c);
    }
    let mut outputs: Vec<&Path> = vec![&a.out];
    if let Some(c) = &a.config_out {
        outputs.push(c);
    }
    refuse_inputs_as_outputs(&inputs, &outputs)?;
    let merge = a.can.as_deref().map(Merge::open).transpose()?;
    let oerr = |p: &Path| {
        let p = p.display().to_string();
        move |e: std::io::Error| format!("cannot write {p}: {e}")
    };
    let mut log = OutFile::create(&a.out).map_err(oerr(&a.out))?;
    let imp = import_to(&a.csv, &o, merge, &mut log)?;
    let snip = match &a.config_out {
        Some(p) => {
            let mut f = OutFile::create(p).map_err(oerr(p))?;
            f.write_all(imp.snippet.as_bytes()).map_err(oerr(p))?;
            Some(f)
        }
        None => None,
    };
    log.commit().map_err(oerr(&a.out))?;
    if let (Some(f), Some(p)) = (snip, &a.config_out) {
        f.commit().map_err(oerr(p))?;
    }
    eprint!("{}", imp.render(&a.csv.display().to_string()));
    eprintln!("wrote {}{}", a.out.display(), a.config_out.as_ref().map(|p| format!(" and {}", p.display())).unwrap_or_default());
    Ok(())
}
