//! The `simulate` subcommand's arguments and driver (main.rs stays thin).

use super::{model::SensorModel, simulate, SimOptions};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct SimulateArgs {
    /// static, chamber, paper, vehicle or urban.
    #[arg(long)]
    pub scenario: String,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output directory.
    #[arg(long)]
    pub out: PathBuf,
    /// vehicle: add short manoeuvres above 0.6 g.
    #[arg(long)]
    pub hard: bool,
    /// Duration, s (default: the scenario's).
    #[arg(long)]
    pub duration: Option<f64>,
    /// Part profile.
    #[arg(long, default_value = "adis16448")]
    pub profile: String,
    /// Use this sensor model (sensor.toml shape) instead of drawing one.
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// TOML file overriding the ranges the sensor errors are drawn from.
    #[arg(long)]
    pub ranges: Option<PathBuf>,
    /// Relative error of the thermal slope written to DIR/config.toml.
    #[arg(long, default_value_t = 0.05)]
    pub thermal_error: f64,
    /// Start while the car is already driving (paper, vehicle, urban).
    #[arg(long)]
    pub power_on_moving: bool,
    /// The sensor mounted rotated in the vehicle: the sensor frame in the
    /// vehicle frame, Z-Y-X, deg (e.g. 0,0,90).
    #[arg(long, value_name = "ROLL,PITCH,YAW", allow_hyphen_values = true)]
    pub mounting: Option<String>,
    /// urban: also write a [speed] section (the wheel speeds of DIR/car.dbc) into DIR/config.toml.
    #[arg(long)]
    pub speed: bool,
}

/// Parse `ROLL,PITCH,YAW` (deg).
pub fn parse_mounting(s: &str) -> Result<[f64; 3], String> {
    let bad = || format!("--mounting wants ROLL,PITCH,YAW in deg (three numbers), got {s:?}");
    let v: Vec<f64> = s.split(',').map(|x| x.trim().parse::<f64>().map_err(|_| bad())).collect::<Result<_, _>>()?;
    <[f64; 3]>::try_from(v).map_err(|_| bad())
}

impl SimulateArgs {
    pub fn options(&self) -> Result<SimOptions, String> {
        let mut o = SimOptions::new(&self.scenario, self.seed);
        o.hard = self.hard;
        o.duration = self.duration;
        o.profile = self.profile.clone();
        o.thermal_error = self.thermal_error;
        o.power_on_moving = self.power_on_moving;
        o.speed = self.speed;
        o.mounting = self.mounting.as_deref().map(parse_mounting).transpose()?;
        if let Some(p) = &self.model {
            o.model = Some(SensorModel::load(p)?);
        }
        if let Some(p) = &self.ranges {
            o.ranges = Some(std::fs::read_to_string(p).map_err(|e| format!("cannot read {}: {e}", p.display()))?);
        }
        Ok(o)
    }
}

pub fn run(a: &SimulateArgs) -> Result<(), String> {
    let o = a.options()?;
    let f = simulate(&o, &a.out)?;
    eprintln!(
        "simulate {}{}{} seed {}: {} samples ({:.1} s at {} Hz) -> {}",
        f.info.scenario,
        if f.info.hard { " --hard" } else { "" },
        if f.info.power_on_moving { " --power-on-moving" } else { "" },
        f.info.seed,
        f.samples,
        f.info.duration_s,
        f.info.rate_hz,
        f.dir.display()
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
