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
    ///
    /// Prints a summary (samples, drops by cause, time per mode) on stderr.
    /// Needs at least one of --output, --csv and --mcap. An output that is the
    /// input (the same file after resolving links) is refused; outputs are
    /// written under a temporary name and renamed only when the run succeeds.
    #[command(group(clap::ArgGroup::new("outputs").required(true).multiple(true).args(["output", "csv", "mcap"])))]
    Replay {
        /// Config file (TOML, see config/gyrocomp.toml). Default: the built-in defaults.
        #[arg(long, value_name = "FILE")]
        config: Option<PathBuf>,
        /// Input log in `candump -l` format, one frame a line. Required.
        #[arg(long, value_name = "IN.log")]
        input: PathBuf,
        /// Write the output frames here as a candump log (on the config's [can] interface), each
        /// stamped with the time of the input frame that closed its sample.
        /// At least one of --output, --csv and --mcap is required.
        #[arg(long, value_name = "OUT.log")]
        output: Option<PathBuf>,
        /// Write one CSV row per sample here: t (s from the first sample, by the
        /// sample counter), roll, pitch, yaw (deg), rate_x..z (deg/s), bias_x..z
        /// (deg/s), mode (0 fusion, 1 aided, 2 gyro only), temp (deg C),
        /// invalid (the fields not estimated, EST_AID's Invalid* bits: 0 all
        /// valid; an invalid field is written as 0).
        /// At least one of --output, --csv and --mcap is required.
        #[arg(long, value_name = "EST.csv")]
        csv: Option<PathBuf>,
        /// Write an MCAP recording here for Foxglove / PlotJuggler (docs/mcap.md):
        /// the attitude as tf2_msgs/msg/TFMessage on /tf (world ENU -> base_link
        /// FLU), the estimate (rates, bias, temperature, mode, flags, aid
        /// sources) on /gyrocomp/estimate, the input frames on /can/rx; ROS 2
        /// CDR messages with their message definitions in the file, log times
        /// from the frames' own timestamps. At least one of --output, --csv and
        /// --mcap is required.
        #[arg(long, value_name = "OUT.mcap")]
        mcap: Option<PathBuf>,
    },
    /// Fit the thermal bias curve from thermal-chamber runs (candump logs of a static sensor).
    ///
    /// One log per power cycle, recorded from power-on while the sensor
    /// self-heats in the chamber. Each run's warm-up transient is found by a
    /// joint fit of `c_run + curve(T) + A exp(-t/tau)` (tau 5..300 s) and cut at
    /// 5 tau when significant (|A| > 5 standard errors); each run's own turn-on
    /// bias `c_run` is removed; the shared curve is fitted by least squares on
    /// 1-s means about the config's `[thermal] t0` (default 25 C), with 95 %
    /// intervals. Corrupt logs (over 1 % bad lines or checksum failures),
    /// empty or shorter than 120 s are refused by name. Details: the
    /// `gyrocomp::calibrate` module documentation.
    Calibrate {
        /// Config file (TOML): its [input] decodes the logs, its [thermal] t0 is
        /// the curve's reference temperature. Default: the built-in defaults (t0 = 25 C).
        #[arg(long, value_name = "FILE")]
        config: Option<PathBuf>,
        /// One input per run (one power cycle each): a candump -l log, or a
        /// recording in the project's CSV format (t,gx,gy,gz,ax,ay,az,mx,my,mz,temp;
        /// .csv or .csv.gz; the magnetometer may be empty), which may come in
        /// bursts with time jumps between them. Required.
        #[arg(long, value_name = "RUN", num_args = 1.., required = true)]
        input: Vec<PathBuf>,
        /// Polynomial order: 1 (linear, as in the paper), 2 or 3.
        #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u8).range(1..=3))]
        order: u8,
        /// Write the fitted [thermal] section to this file (a config the daemon
        /// accepts as it is). Default: not written.
        #[arg(long, value_name = "OUT.toml")]
        write: Option<PathBuf>,
        /// Write SVG plots into this directory. Default: no plots.
        #[arg(long, value_name = "DIR")]
        plot: Option<PathBuf>,
    },
    /// Validate a config file and print the effective configuration.
    ///
    /// A bad value or a parse error is reported with its key and line; the
    /// printed configuration has every key (defaults filled in, the sample
    /// rate resolved from the profile, CAN IDs in hex) and is itself a valid
    /// config file.
    CheckConfig {
        /// Config file to check (TOML). Required.
        #[arg(value_name = "FILE")]
        file: PathBuf,
    },
    /// Run the daemon on the bus named by `[can] interface`.
    ///
    /// Reads the four input IDs, publishes the output frames, notifies
    /// systemd (READY, WATCHDOG, STATUS); SIGHUP reloads the config, SIGTERM
    /// saves the state and stops.
    Run {
        /// Config file (TOML, see config/gyrocomp.toml). Required.
        #[arg(long, value_name = "FILE")]
        config: PathBuf,
    },
    /// Simulate a scenario: DIR/imu.log (ADIS on CAN), truth.csv, sensor.toml, bias.csv, scenario.toml, config.toml.
    ///
    /// The files are written under temporary names and renamed into DIR only
    /// when the whole run succeeded; --model or --ranges inside DIR under an
    /// output's name is refused.
    Simulate(gyrocomp::sim::cli::SimulateArgs),
    /// Replay a simulated run (or many seeds) and score it against the truth.
    Evaluate(gyrocomp::evaluate::EvaluateArgs),
    /// Find what a gyro sensor model is missing: fit, localise and name effects against measured data and truth.
    ///
    /// Writes DIR/report.json, report.md, model.toml (the extended model) and
    /// SVG plots. Significance rule and details: the `gyrocomp::gap` module documentation.
    Gap(gyrocomp::gap::GapArgs),
    /// Convert a CSV recording (t,gx,gy,gz,ax,ay,az[,mx,my,mz][,temp]) into an ADIS candump log.
    ///
    /// Scales, counter and the config snippet: the `gyrocomp::import` module documentation.
    Import(gyrocomp::import::ImportArgs),
    /// Propose the [mounting] rotation of a sensor from a recording of its vehicle.
    ///
    /// Roll and pitch from the gravity the standstills show (their mean: a
    /// single stop may be on a slope), yaw from the line along which the
    /// vehicle accelerates and brakes while driving straight, forward from
    /// the pull-aways after the standstills. Prints the evidence and the
    /// [mounting] section.
    Align(gyrocomp::align::AlignArgs),
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
        Cmd::Replay { config, input, output, csv, mcap } => cmd_replay(config, input, output, csv, mcap),
        Cmd::Run { config } => {
            init_logging();
            gyrocomp::daemon::run(&config).map_err(|e| format!("{e:#}"))
        }
        Cmd::Calibrate { config, input, order, write, plot } => cmd_calibrate(config, input, order, write, plot),
        Cmd::CheckConfig { file } => Config::load(&file).map(|c| print!("{}", c.to_toml())).map_err(|e| e.to_string()),
        Cmd::Simulate(a) => gyrocomp::sim::cli::run(&a),
        Cmd::Evaluate(a) => gyrocomp::evaluate::run(&a),
        Cmd::Gap(a) => gyrocomp::gap::cli(&a),
        Cmd::Import(a) => gyrocomp::import::run(&a),
        Cmd::Align(a) => gyrocomp::align::run(&a),
    };
    match r {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("gyrocomp: error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn cmd_replay(
    config: Option<PathBuf>,
    input: PathBuf,
    output: Option<PathBuf>,
    csv: Option<PathBuf>,
    mcap: Option<PathBuf>,
) -> Result<(), String> {
    if output.is_none() && csv.is_none() && mcap.is_none() {
        return Err("replay needs at least one of --output, --csv and --mcap".into());
    }
    // the config is an input too (replay_files itself guards --input)
    let outs: Vec<&std::path::Path> = output.iter().chain(&csv).chain(&mcap).map(PathBuf::as_path).collect();
    gyrocomp::outfile::refuse_inputs_as_outputs(&config.iter().map(PathBuf::as_path).collect::<Vec<_>>(), &outs)?;
    let cfg = load_config(&config)?;
    let files = ReplayFiles { input: &input, output: output.as_deref(), csv: csv.as_deref(), mcap: mcap.as_deref() };
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

fn cmd_calibrate(
    config: Option<PathBuf>,
    input: Vec<PathBuf>,
    order: u8,
    write: Option<PathBuf>,
    plot: Option<PathBuf>,
) -> Result<(), String> {
    let cfg = load_config(&config)?;
    cfg.adis_only("calibrate")?;
    gyrocomp::calibrate::cli(&cfg, config.as_deref(), &input, order, write.as_deref(), plot.as_deref())
}
