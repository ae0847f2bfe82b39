//! The `simulate` subcommand's arguments and driver (main.rs stays thin).

use super::{model::SensorModel, simulate, SimOptions};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct SimulateArgs {
    /// static, chamber, paper or vehicle.
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
}

impl SimulateArgs {
    pub fn options(&self) -> Result<SimOptions, String> {
        let mut o = SimOptions::new(&self.scenario, self.seed);
        o.hard = self.hard;
        o.duration = self.duration;
        o.profile = self.profile.clone();
        o.thermal_error = self.thermal_error;
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
        "simulate {}{} seed {}: {} samples ({:.1} s at {} Hz) -> {}",
        f.info.scenario,
        if f.info.hard { " --hard" } else { "" },
        f.info.seed,
        f.samples,
        f.info.duration_s,
        f.info.rate_hz,
        f.dir.display()
    );
    Ok(())
}
