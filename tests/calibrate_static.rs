//! `gyrocomp calibrate` on static recordings in the project's CSV format
//! (issue 39, item 4): read directly, in bursts with time jumps between
//! them (separate stretches of one power cycle, the bias walk spanning the
//! jumps), short runs counted by their static seconds.
//!
//! Without `../shared/static-thermal` the real-data tests print that they
//! are skipped; the hand-made CSVs run everywhere.

mod common;
use common::realdata_dir;
use gyrocomp::calibrate::{calibrate_files, CalError, Calibration};
use gyrocomp::config::Config;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

const HEADER: &str = "t,gx,gy,gz,ax,ay,az,mx,my,mz,temp";

fn cfg() -> Config {
    Config::parse("[thermal]\nt0 = 25.0", "test").unwrap()
}

/// A deterministic standard normal (xorshift and Box-Muller).
struct Normal(u64);

impl Normal {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    fn next(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    }
}

/// A still unit in bursts of `burst_s` s at 100 Hz, starting at the times
/// `starts` (s) at the temperatures `temps`: bias `b0 + slope (T - 25)` plus
/// a bias random walk (`walk` deg/s/sqrt(s), running through the jumps) and
/// white noise of 0.1 deg/s per sample. The magnetometer is empty on every
/// other line.
fn bursts_csv(starts: &[f64], temps: &[f64], burst_s: f64, slope: [f64; 3], walk: f64, seed: u64) -> String {
    let mut rng = Normal(seed);
    let b0 = [0.4, -0.2, 1.1];
    let mut w = [0.0; 3];
    let mut t_prev = starts[0];
    let mut out = format!("{HEADER}\n");
    let mut line = 0;
    for (&t0, &temp) in starts.iter().zip(temps) {
        for k in 0..(burst_s * 100.0) as usize {
            let t = t0 + k as f64 * 0.01;
            let dt = t - t_prev;
            t_prev = t;
            let g: [f64; 3] = std::array::from_fn(|i| {
                w[i] += walk * dt.sqrt() * rng.next();
                b0[i] + slope[i] * (temp - 25.0) + w[i] + 0.1 * rng.next()
            });
            let mag = if line % 2 == 0 { "0.2,0.01,-0.4" } else { ",," };
            line += 1;
            let _ = writeln!(out, "{t:.3},{:.5},{:.5},{:.5},0.0,0.0,1.0,{mag},{temp:.3}", g[0], g[1], g[2]);
        }
    }
    out
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn input_error(e: &CalError) -> String {
    match e {
        CalError::Inputs(v) if v.len() == 1 => v[0].to_string(),
        other => panic!("not one input error: {other}"),
    }
}

/// Two 5-s bursts 30 min apart, 20 deg C apart, with a known slope: read as
/// two stretches of one power cycle (without this, calibrate read no CSV,
/// and a 10-s run was too short), and the slope recovered within its 95 %
/// interval on every axis, the interval reflecting the walk over the jump.
#[test]
fn two_bursts_recover_a_known_slope_within_the_interval() {
    let dir = tempfile::tempdir().unwrap();
    let slope = [0.02, -0.01, 0.0];
    let mut widths = Vec::new();
    for seed in 1..=5u64 {
        let csv = bursts_csv(&[100.0, 1900.0], &[30.0, 50.0], 5.0, slope, 2e-4, seed);
        let p = write(dir.path(), &format!("bursts{seed}.csv"), &csv);
        let cal = calibrate_files(&cfg(), &[p], 1).unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        let r = &cal.runs[0];
        assert_eq!(r.stretches.len(), 2, "seed {seed}: {:?}", r.stretches);
        assert!((r.stretches[1].0 - 1800.0).abs() < 1.5, "seed {seed}: {:?}", r.stretches);
        assert_eq!(r.cut_s, 0.0, "seed {seed}: no warm-up cut on bursts");
        assert!(r.used && r.is_static, "seed {seed}: {}", cal.render());
        for (i, a) in cal.axes.iter().enumerate() {
            assert!(
                (a.coeffs[0] - slope[i]).abs() <= a.ci[0],
                "seed {seed} axis {i}: p1 {} +- {} misses {}\n{}",
                a.coeffs[0],
                a.ci[0],
                slope[i],
                cal.render()
            );
            assert!(a.walk_upper.is_finite() && a.walk_upper != 0.0, "seed {seed}: the interval is taken at the walk's upper bound");
            widths.push(a.ci[0]);
        }
        let out = cal.render();
        assert!(out.contains("read as 2 stretches of one power cycle"), "{out}");
    }
    // 10 s of data bound the walk only loosely: the half-width (0.03 to
    // 0.09 deg/s/C here) is set by the walk's 95 % upper bound over the
    // 30-min jump, far above what the true walk would give (2e-4 x
    // sqrt(1800) / 20 = 4e-4): what these data say without a walk known
    // beforehand. Still, a 20 deg C step bounds the slope to a fraction of
    // a deg/s/C.
    let widest = widths.iter().cloned().fold(0.0, f64::max);
    eprintln!("interval half-widths {widths:.4?}");
    assert!(widest < 0.15, "{widths:?}");
}

/// The CSV reader's errors name the file and the line; an empty
/// magnetometer is fine, an empty temperature is not.
#[test]
fn csv_errors_name_the_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let good = bursts_csv(&[0.0], &[25.0], 10.0, [0.0; 3], 0.0, 3);
    let mut lines: Vec<String> = good.lines().map(String::from).collect();
    // line 5: the temperature missing
    let l = &lines[4];
    lines[4] = l[..l.rfind(',').unwrap() + 1].to_string();
    let p = write(dir.path(), "notemp.csv", &(lines.join("\n") + "\n"));
    let e = input_error(&calibrate_files(&cfg(), &[p], 1).unwrap_err());
    assert!(e.contains("notemp.csv:5") && e.contains("temp"), "{e}");
    // line 7: a bad number
    let mut lines: Vec<String> = good.lines().map(String::from).collect();
    lines[6] = lines[6].replacen(',', ",x", 1);
    let p = write(dir.path(), "bad.csv", &(lines.join("\n") + "\n"));
    let e = input_error(&calibrate_files(&cfg(), &[p], 1).unwrap_err());
    assert!(e.contains("bad.csv:7") && e.contains("gx"), "{e}");
    // two seconds: too short to tell anything beyond the run's constant
    let short = bursts_csv(&[0.0], &[25.0], 2.0, [0.0; 3], 0.0, 3);
    let p = write(dir.path(), "short.csv", &short);
    let e = input_error(&calibrate_files(&cfg(), &[p], 1).unwrap_err());
    assert!(e.contains("too short"), "{e}");
}

fn static_thermal() -> Option<PathBuf> {
    let d = realdata_dir().map(|d| d.join("../static-thermal")).filter(|d| d.is_dir());
    if d.is_none() {
        println!("skipped: ../shared/static-thermal not found");
    }
    d
}

const MPU: [&str; 4] = ["mpu6050-static-10min", "mpu6050-static-x-forward", "mpu6050-static-z-front-x-up", "mpu6050-static-z-front-y-down"];

/// No warm-up cut, no self-heating claimed, nothing left out, order 1 only.
fn claims_nothing_else(cal: &Calibration, what: &str) {
    let out = cal.render();
    for r in &cal.runs {
        assert!(r.used, "{what}: {} left out\n{out}", r.name);
        assert_eq!(r.cut_s, 0.0, "{what}: {}: a warm-up cut\n{out}", r.name);
        assert!(!r.transient, "{what}: {}: a warm-up transient claimed\n{out}", r.name);
    }
    assert!(!out.contains("NOT SEPARABLE") && !out.contains("-79."), "{what}\n{out}");
}

/// The four MPU6050 runs, read as they are (the magnetometer empty on some
/// lines): jointly and each alone, every slope's interval includes zero or
/// overlaps the joint one; no warm-up cut, no self-heating.
#[test]
fn mpu6050_runs_give_slopes_that_include_zero_or_agree() {
    let Some(dir) = static_thermal() else { return };
    let files: Vec<PathBuf> = MPU.iter().map(|n| dir.join(n).join("imu.csv.gz")).collect();
    let joint = calibrate_files(&cfg(), &files, 1).unwrap();
    println!("{}", joint.render());
    claims_nothing_else(&joint, "joint");
    for r in &joint.runs {
        assert!(r.heat_tau_s.is_nan() || r.heat_rise_c.abs() < 1.0, "{}: self-heating claimed on 0.5 deg C\n{}", r.name, joint.render());
    }
    let overlap = |a: (f64, f64), b: (f64, f64)| (a.0 - b.0).abs() <= a.1 + b.1;
    let singles: Vec<Calibration> = files.iter().map(|f| calibrate_files(&cfg(), std::slice::from_ref(f), 1).unwrap()).collect();
    for i in 0..3 {
        let j = (joint.axes[i].coeffs[0], joint.axes[i].ci[0]);
        for (s, name) in singles.iter().zip(MPU) {
            claims_nothing_else(s, name);
            let o = (s.axes[i].coeffs[0], s.axes[i].ci[0]);
            println!("axis {i} {name}: p1 = {:.4} +- {:.4} deg/s/C (joint {:.4} +- {:.4})", o.0, o.1, j.0, j.1);
            assert!(o.0.abs() <= o.1 || overlap(o, j), "axis {i} {name}: {o:?} neither includes zero nor agrees with the joint {j:?}");
            assert!(j.0.abs() <= j.1 || overlap(o, j), "axis {i}: joint {j:?} neither includes zero nor agrees with {name} {o:?}");
        }
    }
}

/// The FIRM standby files: accepted as they are, read as two stretches of
/// one power cycle; wide slopes (two points and an unknown walk over 18 and
/// 54 min) that include zero; no warm-up cut.
#[test]
fn firm_bursts_are_two_stretches_with_wide_slopes() {
    let Some(dir) = static_thermal() else { return };
    for (name, jump) in [("firm-standby-launch4", 3251.0), ("firm-standby-launch1", 1073.0)] {
        let f = dir.join(name).join("imu.csv.gz");
        let cal = calibrate_files(&cfg(), &[f], 1).unwrap_or_else(|e| panic!("{name}: {e}"));
        println!("{}", cal.render());
        let r = &cal.runs[0];
        assert_eq!(r.stretches.len(), 2, "{name}: {:?}", r.stretches);
        assert!((r.stretches[1].0 - jump).abs() < 3.0, "{name}: {:?}", r.stretches);
        assert_eq!(r.cut_s, 0.0, "{name}: a warm-up cut");
        assert!(!r.transient, "{name}: a warm-up transient claimed");
        for (i, a) in cal.axes.iter().enumerate() {
            assert!(a.coeffs[0].abs() <= a.ci[0], "{name} axis {i}: p1 {} +- {} excludes zero", a.coeffs[0], a.ci[0]);
        }
    }
}
