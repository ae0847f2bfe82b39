//! The `simulate` subcommand's arguments and driver (main.rs stays thin).
//!
//! Arguments that mean nothing are refused with the reason: a duration that
//! is not a positive number of seconds, `--hard` for a scenario without
//! manoeuvres, a relative thermal-slope error outside 0..1. The files are
//! written into a temporary directory inside `--out` and renamed into place
//! only when the whole run succeeded, so a failed run leaves the files of an
//! earlier run as they were; a `--model` or `--ranges` file that would be
//! overwritten by an output is refused.

use super::{model::SensorModel, simulate, SimOptions};
use crate::adis::builtin_profile;
use crate::outfile::refuse_inputs_as_outputs;
use std::path::{Path, PathBuf};

pub use super::FILES;

/// Scenarios that have no manoeuvres for `--hard` to make harder.
const NO_MANOEUVRES: [&str; 5] = ["static", "chamber", "paper", "urban", "crawl"];

#[derive(clap::Args, Debug)]
pub struct SimulateArgs {
    /// Scenario: static (bench, 300 s), chamber (at rest in a thermal chamber,
    /// 1800 s), paper (800 s, gentle then a winding road from 350 s), vehicle
    /// (800 s, gentle then 0.3-0.4 g manoeuvres from 350 s) or urban (400 s of
    /// city driving: stops, tight turns, hills, turn-on bias up to 5 deg/s,
    /// wheel speeds on the bus), smooth (600 s of smooth driving at 2-30 m/s
    /// with little ride vibration and no stop after the pull-away; --hard:
    /// 200 s of it, then 800 s of hard driving without a stop) or crawl
    /// (600 s at 0.5-3 m/s, with stops on half of the seeds). Required.
    #[arg(long, value_name = "NAME")]
    pub scenario: String,
    /// Seed of every random draw (motion, sensor errors, noise, calibration);
    /// the same seed and options give byte-identical files.
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub seed: u64,
    /// Output directory (created if needed). Required.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// vehicle: add emergency brakes and swerves of 0.65-0.8 g to the
    /// manoeuvres; smooth: 800 s of hard driving without a stop after 200 s
    /// of the smooth drive. Off by default.
    #[arg(long)]
    pub hard: bool,
    /// Duration of the run, s (> 0). Default: the scenario's (static 300,
    /// chamber 1800, paper and vehicle 800, urban 400, smooth and crawl 600,
    /// smooth --hard 1000). At most 10 million samples (about 3.9 GB of
    /// files): 48828 s of adis16448, 12207 s of adis16405, 5000 s of
    /// adis16465-1; a longer run is refused up front with its estimate.
    #[arg(long, value_name = "S", allow_negative_numbers = true, value_parser = positive_seconds)]
    pub duration: Option<f64>,
    /// Part profile (LSBs and sample rate of the log): adis16448, adis16405 or adis16465-1.
    #[arg(long, value_name = "NAME", default_value = "adis16448")]
    pub profile: String,
    /// Use this sensor model (sensor.toml shape) instead of drawing one.
    /// Default: drawn from the scenario's ranges.
    #[arg(long, value_name = "FILE")]
    pub model: Option<PathBuf>,
    /// TOML file overriding any subset of the ranges the sensor errors are
    /// drawn from (src/sim/scenario.rs `Ranges`). Default: the scenario's ranges.
    #[arg(long, value_name = "FILE")]
    pub ranges: Option<PathBuf>,
    /// Relative error of the thermal slope written to DIR/config.toml, as a
    /// fraction (0.05 = each axis off by a factor uniform in 1 +- 5 %); 0..1.
    #[arg(long, value_name = "FRACTION", allow_negative_numbers = true, value_parser = fraction, default_value_t = 0.05)]
    pub thermal_error: f64,
    /// Start while the car is already driving (paper, vehicle, urban).
    /// Default: a parked start.
    #[arg(long)]
    pub power_on_moving: bool,
    /// The sensor mounted rotated in the vehicle: the sensor frame in the
    /// vehicle frame, Z-Y-X, deg (e.g. 0,0,90). Default: aligned with the vehicle.
    #[arg(long, value_name = "ROLL,PITCH,YAW", allow_hyphen_values = true)]
    pub mounting: Option<String>,
    /// urban: also write a [speed] section (the wheel speeds of DIR/car.dbc)
    /// into DIR/config.toml. Default: no [speed] (the wheel-speed frames are
    /// on the bus either way).
    #[arg(long)]
    pub speed: bool,
    /// Put the IMU on the bus in the format this DBC config describes
    /// ([input] format = "dbc", docs/protocol.md#dbc-input), at its rate_hz:
    /// imu.log holds its frames, config.toml its [input], its DBC is copied
    /// beside them, and adis.log with adis.toml hold the same samples in the
    /// ADIS contract at the same rate. Default: the ADIS contract only.
    #[arg(long, value_name = "CONFIG")]
    pub input_dbc: Option<PathBuf>,
}

/// Parse `ROLL,PITCH,YAW` (deg).
pub fn parse_mounting(s: &str) -> Result<[f64; 3], String> {
    let bad = || format!("--mounting wants ROLL,PITCH,YAW in deg (three numbers), got {s:?}");
    let v: Vec<f64> = s.split(',').map(|x| x.trim().parse::<f64>().map_err(|_| bad())).collect::<Result<_, _>>()?;
    <[f64; 3]>::try_from(v).map_err(|_| bad())
}

/// clap value parser: a finite number of seconds > 0.
pub fn positive_seconds(s: &str) -> Result<f64, String> {
    let v: f64 = s.trim().parse().map_err(|_| format!("{s:?} is not a number of seconds"))?;
    if !(v.is_finite() && v > 0.0) {
        return Err(format!("a duration must be a finite number of seconds > 0, got {s}"));
    }
    Ok(v)
}

/// clap value parser: a finite number of seconds >= 0.
pub fn non_negative_seconds(s: &str) -> Result<f64, String> {
    let v: f64 = s.trim().parse().map_err(|_| format!("{s:?} is not a number of seconds"))?;
    if !(v.is_finite() && v >= 0.0) {
        return Err(format!("must be a finite number of seconds >= 0, got {s}"));
    }
    Ok(v)
}

/// clap value parser: a relative error as a fraction in 0..=1 (a factor of
/// 1 +- more than 1 could flip the sign of the slope).
pub fn fraction(s: &str) -> Result<f64, String> {
    let v: f64 = s.trim().parse().map_err(|_| format!("{s:?} is not a number"))?;
    if !(v.is_finite() && (0.0..=1.0).contains(&v)) {
        return Err(format!(
            "a relative error is a fraction from 0 to 1 (0.05 = 5 %), got {s}: a factor 1 +- {s} {}",
            if v > 1.0 { "could flip the sign of the slope" } else { "means nothing" }
        ));
    }
    Ok(v)
}

/// The most samples `simulate` writes in one run: at about
/// [`FILE_BYTES_PER_SAMPLE`] bytes a sample (imu.log, truth.csv, bias.csv,
/// vehicle.csv) 10 million samples are about 3.9 GB of files; 13.5 h of an
/// adis16448 (204.8 Hz), 3.4 h of an adis16405 (819.2 Hz), 83 min of an
/// adis16465-1 (2000 Hz). A longer `--duration` is refused before anything
/// is written, with its estimate.
pub const MAX_SIMULATE_SAMPLES: f64 = 10e6;
/// The bytes of files one simulated sample takes, about (static 60 s:
/// 335; the road scenarios' vehicle.csv and wheel speeds add some 60).
pub const FILE_BYTES_PER_SAMPLE: f64 = 390.0;
/// The most samples one `evaluate --seeds` run holds in memory (each seed is
/// simulated, replayed and scored in memory): 4 million, about
/// [`MEMORY_BYTES_PER_SAMPLE`] bytes each, 1.6 GB; 5.4 h of an adis16448,
/// 81 min of an adis16405, 33 min of an adis16465-1 (its chamber's
/// default 1800 s fits).
pub const MAX_EVALUATE_SAMPLES: f64 = 4e6;
/// The memory one in-memory sample takes in `evaluate --seeds`, bytes,
/// about: its truth row, true bias, speed, four bus frames and the estimate
/// of every case kept for scoring.
pub const MEMORY_BYTES_PER_SAMPLE: f64 = 400.0;

/// Which command a run's size is checked for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Budget {
    /// `simulate`: files on disk, [`MAX_SIMULATE_SAMPLES`].
    Files,
    /// `evaluate --seeds`: memory, [`MAX_EVALUATE_SAMPLES`].
    Memory,
}

fn human_bytes(b: f64) -> String {
    let units = ["B", "kB", "MB", "GB", "TB", "PB", "EB"];
    let mut v = b;
    let mut k = 0;
    while v >= 1000.0 && k + 1 < units.len() {
        v /= 1000.0;
        k += 1;
    }
    if v >= 1000.0 {
        format!("{b:.1e} B")
    } else {
        format!("{v:.1} {}", units[k])
    }
}

/// Refuse a run longer than the command's documented limit, up front, with
/// its estimate (number of samples and bytes).
pub fn check_size(scenario: &str, hard: bool, duration: Option<f64>, profile: &str, budget: Budget) -> Result<(), String> {
    let Some(p) = builtin_profile(profile) else { return Ok(()) };
    let d = duration.unwrap_or_else(|| super::scenario::default_duration_of(scenario, hard));
    let samples = d * p.rate_hz;
    let (max, per, what, cmd) = match budget {
        Budget::Files => (MAX_SIMULATE_SAMPLES, FILE_BYTES_PER_SAMPLE, "of files", "simulate"),
        Budget::Memory => (MAX_EVALUATE_SAMPLES, MEMORY_BYTES_PER_SAMPLE, "of memory per seed", "evaluate --seeds"),
    };
    if samples > max {
        return Err(format!(
            "--duration {d} s is {samples:.3e} samples of {profile} at {} Hz, about {} {what}: over {cmd}'s limit of {max:.0e} samples \
             ({:.0} s at this rate, about {})",
            p.rate_hz,
            human_bytes(samples * per),
            max / p.rate_hz,
            human_bytes(max * per)
        ));
    }
    Ok(())
}

/// Refuse arguments that do not fit the scenario (shared with `evaluate --seeds`).
pub fn check_scenario(scenario: &str, hard: bool, duration: Option<f64>, profile: &str) -> Result<(), String> {
    if !super::scenario::SCENARIOS.contains(&scenario) {
        return Err(format!("unknown scenario {scenario:?} (known: {})", super::scenario::SCENARIOS.join(", ")));
    }
    if hard && NO_MANOEUVRES.contains(&scenario) {
        return Err(format!(
            "--hard adds emergency brakes and swerves to the vehicle scenario's manoeuvres and hard driving to the smooth one; scenario {scenario} has none to make harder"
        ));
    }
    let p = builtin_profile(profile)
        .ok_or_else(|| format!("unknown profile {profile:?} (known: {})", crate::adis::BUILTIN_PROFILES.join(", ")))?;
    if let Some(d) = duration {
        if d * p.rate_hz < 1.0 {
            return Err(format!("--duration {d} s is shorter than one sample of {profile} (1/{} s)", p.rate_hz));
        }
    }
    Ok(())
}

impl SimulateArgs {
    pub fn options(&self) -> Result<SimOptions, String> {
        check_scenario(&self.scenario, self.hard, self.duration, &self.profile)?;
        check_size(&self.scenario, self.hard, self.duration, &self.profile, Budget::Files)?;
        let mut o = SimOptions::new(&self.scenario, self.seed);
        o.hard = self.hard;
        o.duration = self.duration;
        o.profile = self.profile.clone();
        o.thermal_error = self.thermal_error;
        o.power_on_moving = self.power_on_moving;
        o.speed = self.speed;
        o.mounting = self.mounting.as_deref().map(parse_mounting).transpose()?;
        if let Some(p) = &self.input_dbc {
            o.input_dbc = Some(std::sync::Arc::new(super::dbcout::DbcSim::load(p)?));
        }
        if let Some(p) = &self.model {
            o.model = Some(SensorModel::load(p)?);
        }
        if let Some(p) = &self.ranges {
            o.ranges = Some(crate::textfile::read(p).map_err(|e| format!("cannot read {}: {e}", p.display()))?);
        }
        Ok(o)
    }

    fn inputs(&self) -> Vec<&Path> {
        [self.model.as_deref(), self.ranges.as_deref(), self.input_dbc.as_deref()].into_iter().flatten().collect()
    }
}

/// Refuse a destination that is an input or a directory.
fn check_destinations(inputs: &[&Path], outs: &[PathBuf]) -> Result<(), String> {
    let refs: Vec<&Path> = outs.iter().map(PathBuf::as_path).collect();
    refuse_inputs_as_outputs(inputs, &refs)?;
    for p in outs {
        if p.is_dir() {
            return Err(format!("{} is a directory: simulate writes a file of that name", p.display()));
        }
    }
    Ok(())
}

pub fn run(a: &SimulateArgs) -> Result<(), String> {
    let o = a.options()?;
    let inputs = a.inputs();
    check_destinations(&inputs, &FILES.map(|f| a.out.join(f)))?;
    let created = !a.out.exists();
    crate::outfile::create_dir(&a.out).map_err(|e| format!("--out {}: {e}", a.out.display()))?;
    let r = simulate_into(a, &o, &inputs);
    if r.is_err() && created {
        let _ = std::fs::remove_dir(&a.out); // only when still empty
    }
    r
}

/// Simulate into a temporary directory inside `--out`, then rename every
/// file into place (all checks first, then the renames).
fn simulate_into(a: &SimulateArgs, o: &SimOptions, inputs: &[&Path]) -> Result<(), String> {
    let stage = tempfile::Builder::new()
        .prefix(".simulate-")
        .tempdir_in(&a.out)
        .map_err(|e| format!("cannot create a temporary directory in {}: {e}", a.out.display()))?;
    let _on_signal = crate::outfile::remove_dir_on_signal(stage.path());
    let f = simulate(o, stage.path())?;
    let mut names: Vec<_> = std::fs::read_dir(stage.path())
        .and_then(|d| d.map(|e| e.map(|e| e.file_name())).collect::<Result<Vec<_>, _>>())
        .map_err(|e| format!("{}: {e}", stage.path().display()))?;
    names.sort();
    let dests: Vec<PathBuf> = names.iter().map(|n| a.out.join(n)).collect();
    check_destinations(inputs, &dests)?;
    for (n, d) in names.iter().zip(&dests) {
        std::fs::rename(stage.path().join(n), d).map_err(|e| format!("cannot move the new {} into place: {e}", d.display()))?;
    }
    if let Ok(d) = std::fs::File::open(&a.out) {
        let _ = d.sync_all();
    }
    eprintln!(
        "simulate {}{}{} seed {}: {} samples ({:.1} s at {} Hz) -> {}",
        f.info.scenario,
        if f.info.hard { " --hard" } else { "" },
        if f.info.power_on_moving { " --power-on-moving" } else { "" },
        f.info.seed,
        f.samples,
        f.info.duration_s,
        f.info.rate_hz,
        a.out.display()
    );
    if let Some(w) = &f.info.wheel_speeds {
        eprintln!(
            "wheel speeds: {} WHEEL_SPEEDS frames (0x{:03X}, every {} ms, latency {:.0} ms, tyre scale error {:+.2} %), described by car.dbc",
            f.wheel_frames,
            w.id,
            w.period_s * 1e3,
            w.latency_s * 1e3,
            w.scale_error * 100.0
        );
    }
    if let Some(s) = &f.info.stats {
        eprint!("drive statistics (also in scenario.toml [stats]):\n{}{}", super::stats::DriveStats::header(), s.row(f.info.seed));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn meaningless_values_are_refused_with_the_reason() {
        assert!(positive_seconds("-5").unwrap_err().contains("> 0"));
        assert!(positive_seconds("0").is_err());
        assert!(positive_seconds("inf").is_err());
        assert!(positive_seconds("5s").unwrap_err().contains("not a number"));
        assert_eq!(positive_seconds("60").unwrap(), 60.0);
        assert!(fraction("2").unwrap_err().contains("flip the sign"));
        assert!(fraction("-0.1").is_err());
        assert_eq!(fraction("0.05").unwrap(), 0.05);
        assert!(non_negative_seconds("-1").is_err());
        assert!(check_scenario("static", true, None, "adis16448").unwrap_err().contains("--hard"));
        assert!(check_scenario("paper", true, None, "adis16448").is_err());
        check_scenario("vehicle", true, None, "adis16448").unwrap();
        assert!(check_scenario("vehicel", false, None, "adis16448").unwrap_err().contains("known: static"));
        assert!(check_scenario("static", false, Some(0.001), "adis16448").unwrap_err().contains("one sample"));
        assert!(check_scenario("static", false, None, "adis9").unwrap_err().contains("unknown profile"));
    }

    #[test]
    fn a_run_over_the_limit_is_refused_with_its_estimate() {
        let e = check_size("static", false, Some(1e12), "adis16448", Budget::Files).unwrap_err();
        assert!(e.contains("2.048e14 samples") && e.contains("limit of 1e7 samples") && e.contains("PB"), "{e}");
        let e = check_size("static", false, Some(1e12), "adis16448", Budget::Memory).unwrap_err();
        assert!(e.contains("of memory") && e.contains("limit of 4e6"), "{e}");
        // every scenario's default duration fits at every profile
        for sc in crate::sim::scenario::SCENARIOS {
            for hard in [false, true] {
                for p in crate::adis::BUILTIN_PROFILES {
                    check_size(sc, hard, None, p, Budget::Files).unwrap();
                    check_size(sc, hard, None, p, Budget::Memory).unwrap();
                }
            }
        }
        check_size("static", false, Some(48_000.0), "adis16448", Budget::Files).unwrap();
    }
}
