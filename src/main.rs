use clap::{Parser, Subcommand};
use gyrocomp::config::Config;
use gyrocomp::replay::{replay_files, ReplayFiles};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Parser)]
#[command(name = "gyrocomp", version, about = "MEMS gyro bias compensation for ADIS-class IMUs on SocketCAN")]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Replay a candump -l log through the estimator; write output frames (and a CSV).
    Replay {
        #[arg(long)]
        config: Option<PathBuf>,
        #[arg(long)]
        input: PathBuf,
        #[arg(long)]
        output: Option<PathBuf>,
        #[arg(long)]
        csv: Option<PathBuf>,
    },
    /// Validate a config file and print the effective configuration.
    CheckConfig { file: PathBuf },
    /// Simulate a scenario: DIR/imu.log (ADIS on CAN), truth.csv, sensor.toml, bias.csv, scenario.toml, config.toml.
    Simulate(gyrocomp::sim::cli::SimulateArgs),
    /// Replay a simulated run (or many seeds) and score it against the truth.
    Evaluate(gyrocomp::evaluate::EvaluateArgs),
}

fn load_config(p: &Option<PathBuf>) -> Result<Config, String> {
    match p {
        Some(p) => Config::load(p).map_err(|e| e.to_string()),
        None => Ok(Config::default()),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let r = match cli.cmd {
        Cmd::Replay { config, input, output, csv } => cmd_replay(config, input, output, csv),
        Cmd::CheckConfig { file } => Config::load(&file).map(|c| print!("{}", c.to_toml())).map_err(|e| e.to_string()),
        Cmd::Simulate(a) => gyrocomp::sim::cli::run(&a),
        Cmd::Evaluate(a) => gyrocomp::evaluate::run(&a),
    };
    match r {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("gyrocomp: error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn cmd_replay(config: Option<PathBuf>, input: PathBuf, output: Option<PathBuf>, csv: Option<PathBuf>) -> Result<(), String> {
    let cfg = load_config(&config)?;
    if output.is_none() && csv.is_none() {
        return Err("replay needs --output and/or --csv".into());
    }
    let files = ReplayFiles { input: &input, output: output.as_deref(), csv: csv.as_deref() };
    let sum = replay_files(&cfg, &files, None).map_err(|e| e.to_string())?;
    eprint!("replay {}:\n{}", input.display(), sum.render());
    if sum.input.samples == 0 {
        return Err(format!(
            "{}: no complete sample ({} lines, {} bad, {} frames)",
            input.display(),
            sum.lines,
            sum.bad_lines,
            sum.input.frames
        ));
    }
    Ok(())
}
