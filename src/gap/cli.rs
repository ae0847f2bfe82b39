//! The `gap` subcommand's arguments and what it prints.

use super::*;

/// `gyrocomp gap` arguments.
#[derive(clap::Args, Debug)]
pub struct GapArgs {
    /// Measured data (required): a `candump -l` log in the ADIS contract
    /// (decoded with --profile; times from its first sample, which is the
    /// truth's first row) or a CSV with the header t,gx,gy,gz,ax,ay,az,mx,my,mz,temp
    /// (s, deg/s, g, gauss, deg C).
    /// Several files (with a --reference each): trials of one unit, fitted
    /// each and then jointly (report in DIR/trials.md, DIR/trials.json).
    #[arg(long, value_name = "FILE", num_args = 1.., required = true)]
    pub measured: Vec<PathBuf>,
    /// Simulated truth (one of --truth, --reference, --static): t,roll,pitch,yaw,p,q,r,fx,fy,fz[,temp] as `gyrocomp simulate`
    /// writes it (s since power-on, deg, deg/s, g, deg C). Without temp the measured
    /// temperature is used; with it, the two must agree within 1 deg C RMS.
    #[arg(long, value_name = "FILE")]
    pub truth: Option<PathBuf>,
    /// Measured reference, one per --measured file, same order:
    /// t,roll,pitch,yaw[,valid][,rest] (gzip recognised) on the measured
    /// file's clock. The truth is derived from it: body rates from the
    /// orientation's derivative low-passed at --bandwidth (the measured gyro
    /// alike), the mount estimated at the first rest phase, the reference's
    /// noise at rest added to the noise model, specific force from the
    /// measured accelerometer low-passed, only stretches where it is valid.
    #[arg(long, value_name = "REF.csv[.gz]", num_args = 1..)]
    pub reference: Vec<PathBuf>,
    /// The unit lay still: zero rotation, gravity from the accelerometer's
    /// mean; stretches between time jumps are bursts of one power cycle.
    #[arg(long = "static")]
    pub is_static: bool,
    /// Bandwidth of a truth derived with --reference or --static (-6 dB of
    /// the zero-phase low-pass applied to reference and measured alike), Hz.
    #[arg(long, value_name = "HZ", default_value_t = refdata::DEFAULT_BANDWIDTH_HZ)]
    pub bandwidth: f64,
    /// Base sensor model (required; sensor.toml shape): [gyro] effects with their
    /// tables are fixed, an effect listed without its table is fitted. Its [noise]
    /// is the noise model significance is judged with: gyro_white (deg/s/sqrt(Hz),
    /// default 0.0135) and gyro_bias_walk (deg/s/sqrt(s), default 0.0002).
    #[arg(long, value_name = "BASE.toml")]
    pub model: PathBuf,
    /// Output directory (required; created if missing): report.json, report.md,
    /// model.toml, residual.svg, finding_N_<effect>_<axis>.svg. Files of those names
    /// are replaced atomically; an input is never overwritten.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Part profile: adis16448, adis16405 or adis16465-1. Decodes the log and gives
    /// the gyro LSB (deg/s) whose quantisation noise (LSB^2/12) is part of the noise model.
    #[arg(long, value_name = "NAME", default_value = "adis16448")]
    pub profile: String,
}

/// The `gap` subcommand.
pub fn cli(a: &GapArgs) -> Result<(), String> {
    let modes = [a.truth.is_some(), !a.reference.is_empty(), a.is_static].iter().filter(|x| **x).count();
    if modes != 1 {
        return Err("give exactly one of --truth FILE (simulated), --reference FILE... (measured) and --static".into());
    }
    let bandwidth = refdata::check_bandwidth(a.bandwidth)?;
    if a.measured.is_empty() {
        return Err("--measured: at least one file".into());
    }
    let truth_of = |k: usize| -> Result<Truth, String> {
        Ok(if let Some(t) = &a.truth {
            Truth::Simulated(t.clone())
        } else if a.is_static {
            Truth::Static { bandwidth }
        } else {
            let r = a.reference.get(k).ok_or_else(|| {
                format!(
                    "--reference: {} file(s) for {} --measured file(s): give one reference per trial, in the same order",
                    a.reference.len(),
                    a.measured.len()
                )
            })?;
            Truth::Reference { path: r.clone(), bandwidth }
        })
    };
    if !a.reference.is_empty() && a.reference.len() != a.measured.len() {
        truth_of(a.measured.len() - 1)?;
        return Err(format!("--reference: {} file(s) for {} --measured file(s)", a.reference.len(), a.measured.len()));
    }
    if a.measured.len() > 1 {
        if a.truth.is_some() {
            return Err("several --measured files need a measured --reference each (or --static), not one simulated --truth".into());
        }
        let trials: Vec<(PathBuf, Truth)> =
            a.measured.iter().enumerate().map(|(k, m)| Ok((m.clone(), truth_of(k)?))).collect::<Result<_, String>>()?;
        return trials::cli(&trials, &a.model, &a.out, &a.profile);
    }
    let o = GapOptions {
        measured: a.measured[0].clone(),
        truth: match truth_of(0)? {
            Truth::Simulated(p) | Truth::Reference { path: p, .. } => p,
            Truth::Static { .. } => a.measured[0].clone(),
        },
        model: a.model.clone(),
        out: a.out.clone(),
        profile: a.profile.clone(),
        plots: true,
    };
    let r = run_with(&o, &truth_of(0)?)?;
    print_result(&r);
    Ok(())
}

/// What `gap` prints of one run.
pub fn print_result(r: &GapResult) {
    let rep = &r.report;
    let nm = &rep.noise_model;
    println!("gap: {} samples, {:.1} s of data, {:.2} s", rep.samples, rep.duration_s, r.elapsed_s);
    println!(
        "noise model: white {:.4} deg/s per sample, bias random walk {:.1e} deg/s/sqrt(s); significant when |t| >= {}",
        nm.sigma, nm.bias_walk, rep.t_min
    );
    println!("residual RMS (1-s means) base model [{}] deg/s, noise floor {:.5} deg/s", report::fmt3(&rep.rms_initial), rep.noise_floor_1s);
    for c in &rep.base_coefficients {
        println!(
            "base model's free {}: {:.4e} +- {:.1e} {}",
            c.term,
            c.coefficient,
            c.std_error,
            if c.unit == "1" { "(dimensionless)" } else { &c.unit }
        );
    }
    for f in &rep.findings {
        println!(
            "found {}: {:.4e} +- {:.1e} {} (t = {:.1}); RMS [{}] -> [{}]",
            finding_title(f),
            f.coefficient,
            f.std_error,
            if f.unit == "1" { "(dimensionless)" } else { &f.unit },
            f.t_stat,
            report::fmt3(&f.rms_before),
            report::fmt3(&f.rms_after)
        );
    }
    for w in &rep.withdrawn {
        println!("withdrawn {}: t = {:.1} once {} was added", w.term, w.t_stat, w.after);
    }
    for a in &rep.ambiguous {
        println!("{}", a.reason);
    }
    for u in &rep.unassigned {
        println!("not separable with this data: {u}");
    }
    for x in &rep.rejected {
        println!("{x}");
    }
    if rep.clean {
        println!("clean: nothing missing");
    }
    for p in &r.files {
        println!("wrote {}", p.display());
    }
}
