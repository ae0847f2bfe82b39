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
    /// Run the daemon on the bus named by `[can] interface`.
    Run {
        #[arg(long)]
        config: PathBuf,
    },
    /// Simulate a scenario: DIR/imu.log (ADIS on CAN), truth.csv, sensor.toml, bias.csv, scenario.toml, config.toml.
    Simulate(gyrocomp::sim::cli::SimulateArgs),
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
        Cmd::Run { config } => {
            init_logging();
            gyrocomp::daemon::run(&config).map_err(|e| format!("{e:#}"))
        }
        Cmd::CheckConfig { file } => Config::load(&file).map(|c| print!("{}", c.to_toml())).map_err(|e| e.to_string()),
        Cmd::Simulate(a) => gyrocomp::sim::cli::run(&a),
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

/// journald when stderr is connected to the journal (systemd sets
/// JOURNAL_STREAM), plain stderr otherwise. RUST_LOG filters (default info).
fn init_logging() {
    use tracing_subscriber::prelude::*;
    let filter = tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into());
    if std::env::var_os("JOURNAL_STREAM").is_some() {
        if let Ok(j) = tracing_journald::layer() {
            tracing_subscriber::registry().with(filter).with(j).init();
            return;
        }
    }
    use std::io::IsTerminal;
    tracing_subscriber::fmt().with_env_filter(filter).with_ansi(std::io::stderr().is_terminal()).with_writer(std::io::stderr).init();
}
