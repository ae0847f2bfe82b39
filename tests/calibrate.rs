//! `gyrocomp calibrate` on simulated thermal-chamber runs with known coefficients.

use gyrocomp::adis::RawSample;
use gyrocomp::calibrate::{calibrate_files, calibrate_runs, read_run, read_run_from, CalError, ChamberRun};
use gyrocomp::candump::LogWriter;
use gyrocomp::config::{Config, ThermalConfig};
use gyrocomp::thermal::Thermal;
use rand::{Rng, SeedableRng};
use std::path::{Path, PathBuf};

/// 10 Hz keeps the logs small (the noise density, not the rate, sets the
/// information per second); everything else is the ADIS16448 default.
fn cfg() -> Config {
    Config::parse("[input]\nrate_hz = 10.0\n[thermal]\nt0 = 25.0", "test").unwrap()
}

fn truth(order: u8) -> Thermal {
    Thermal::new(&ThermalConfig {
        t0: 25.0,
        order,
        p1: [0.006, -0.0044, 0.0192],
        p2: [0.0011, 0.0003, 0.0012],
        p3: if order >= 2 { [4e-5, -3e-5, 6e-5] } else { [0.0; 3] },
        p4: if order >= 3 { [0.0, 0.0, -1e-6] } else { [0.0; 3] },
        ..Default::default()
    })
}

/// Four runs at 0/20/40/60 C, each with its own turn-on bias and warm-up transient.
fn chamber(dir: &Path, curve: &Thermal, tweak: impl Fn(usize, &mut ChamberRun)) -> Vec<PathBuf> {
    let c = cfg();
    let turn_on = [[0.21, -0.35, 0.12], [-0.18, 0.05, -0.27], [0.33, 0.22, 0.08], [-0.05, -0.14, 0.31]];
    let amp = [[0.15, -0.10, 0.25], [0.08, 0.12, -0.20], [-0.12, 0.06, 0.30], [0.10, -0.15, 0.18]];
    let tau = [120.0, 90.0, 150.0, 60.0];
    (0..4)
        .map(|k| {
            let mut r = ChamberRun::new(20.0 * k as f64, 100 + k as u64);
            r.turn_on = turn_on[k];
            r.warmup_amp = amp[k];
            r.warmup_tau_s = tau[k];
            tweak(k, &mut r);
            let p = dir.join(format!("run{}_{}C.log", k + 1, 20 * k));
            r.write_file(&c, curve, &p).unwrap();
            p
        })
        .collect()
}

fn paper() -> Thermal {
    // Table 1 of the paper (deg/s per deg C, deg/s).
    Thermal::linear(25.0, [0.0020, 0.0044, 0.0192], [0.0011, 0.0003, 0.0012])
}

const TAU: [f64; 4] = [120.0, 90.0, 150.0, 60.0];

#[test]
fn four_runs_at_0_20_40_60_recover_the_slope_within_5_percent() {
    let dir = tempfile::tempdir().unwrap();
    let th = paper();
    let files = chamber(dir.path(), &th, |_, _| {});
    let cal = calibrate_files(&cfg(), &files, 1).unwrap();
    eprintln!("{}", cal.render());
    assert!(cal.warnings.is_empty(), "{:?}", cal.warnings);
    for i in 0..3 {
        let a = &cal.axes[i];
        let err = (a.coeffs[0] - th.p1[i]) / th.p1[i];
        assert!(err.abs() < 0.05, "axis {i}: p1 {} vs {} ({:.1} %)", a.coeffs[0], th.p1[i], 100.0 * err);
        // the printed 95 % interval covers the truth
        assert!((a.coeffs[0] - th.p1[i]).abs() < a.ci[0], "axis {i}: {} +- {}", a.coeffs[0], a.ci[0]);
        // residuals are the white noise of 1-s means: 0.0135 deg/s
        assert!(a.rms > 0.012 && a.rms < 0.016, "rms {}", a.rms);
    }
    // every run's warm-up transient was found and cut at about 5 tau
    for (k, r) in cal.runs.iter().enumerate() {
        assert!(r.transient, "run {k}");
        assert!(r.cut_s > 4.0 * TAU[k] && r.cut_s < 6.0 * TAU[k], "run {k}: cut {} for tau {}", r.cut_s, TAU[k]);
        assert!(r.is_static);
    }
    // each run's own turn-on bias is removed, not averaged into the slope
    let turn_on = [[0.21, -0.35, 0.12], [-0.18, 0.05, -0.27], [0.33, 0.22, 0.08], [-0.05, -0.14, 0.31]];
    for (k, r) in cal.runs.iter().enumerate() {
        for i in 0..3 {
            assert!((r.offset[i] - turn_on[k][i] - th.p2[i]).abs() < 0.01, "run {k} axis {i}: {}", r.offset[i]);
        }
    }
    // range covered: from the first used second of the 0 C run to the end of the 60 C run
    assert!(cal.range.0 > 4.0 && cal.range.0 < 8.0 && cal.range.1 > 74.0 && cal.range.1 < 75.5, "{:?}", cal.range);
    // --write: a [thermal] section the config accepts as it is
    let c = Config::parse(&cal.to_toml(), "written").unwrap();
    assert_eq!(c.thermal, cal.thermal_config());
    assert_eq!(c.thermal.t_min, Some(cal.range.0));
    assert_eq!(c.thermal.order, 1);
}

#[test]
fn second_and_third_order_curves() {
    let dir = tempfile::tempdir().unwrap();
    for order in [2u8, 3] {
        let th = truth(order);
        let files = chamber(dir.path(), &th, |_, _| {});
        let cal = calibrate_files(&cfg(), &files, order).unwrap();
        eprintln!("{}", cal.render());
        assert!(cal.warnings.is_empty(), "{:?}", cal.warnings);
        let fit = cal.thermal();
        let want = [th.p1, th.p3, th.p4];
        for i in 0..3 {
            let a = &cal.axes[i];
            assert_eq!(a.coeffs.len(), order as usize);
            assert!(((a.coeffs[0] - th.p1[i]) / th.p1[i]).abs() < 0.05, "order {order} axis {i}: p1 {:?}", a.coeffs);
            for k in 0..order as usize {
                assert!(
                    (a.coeffs[k] - want[k][i]).abs() < a.ci[k],
                    "order {order} axis {i} coeff {k}: {} +- {} vs {}",
                    a.coeffs[k],
                    a.ci[k],
                    want[k][i]
                );
            }
            // the whole curve's shape over the calibrated range, within 0.01 deg/s
            for t in [6.0, 15.0, 30.0, 45.0, 60.0, 74.0] {
                let d_fit = fit.bias(t)[i] - fit.bias(25.0)[i];
                let d_true = th.bias(t)[i] - th.bias(25.0)[i];
                assert!((d_fit - d_true).abs() < 0.01, "order {order} axis {i} at {t}: {d_fit} vs {d_true}");
            }
        }
        let c = Config::parse(&cal.to_toml(), "written").unwrap();
        assert_eq!(c.thermal, cal.thermal_config());
        assert_eq!(c.thermal.order, order);
    }
}

#[test]
fn without_a_transient_nothing_is_cut() {
    let dir = tempfile::tempdir().unwrap();
    let files = chamber(dir.path(), &paper(), |_, r| r.warmup_amp = [0.0; 3]);
    let cal = calibrate_files(&cfg(), &files, 1).unwrap();
    for r in &cal.runs {
        assert!(!r.transient && r.cut_s == 0.0, "{}: cut {} tau {}", r.name, r.cut_s, r.tau_s);
    }
}

#[test]
fn a_run_that_is_not_static_is_flagged_and_its_motion_left_out() {
    let dir = tempfile::tempdir().unwrap();
    let th = paper();
    // run 2 is turned 100 deg about z and back, 1500 s after power-on
    let files = chamber(dir.path(), &th, |k, r| {
        if k == 1 {
            r.rotation = Some((1500.0, 20.0, 10.0));
        }
    });
    let cal = calibrate_files(&cfg(), &files, 1).unwrap();
    eprintln!("{}", cal.render());
    assert_eq!(cal.warnings.len(), 1, "{:?}", cal.warnings);
    assert!(cal.warnings[0].contains("run2_20C.log") && cal.warnings[0].contains("not static"), "{}", cal.warnings[0]);
    assert!(cal.render().contains("NOT STATIC"));
    let r = &cal.runs[1];
    assert!(!r.is_static);
    assert!(r.moving_s >= 20.0 && r.moving_s <= 40.0, "moving {}", r.moving_s);
    assert!((r.max_rot_at_s - 1510.0).abs() < 15.0, "{}", r.max_rot_at_s);
    assert!(cal.runs.iter().enumerate().all(|(k, r)| k == 1 || r.is_static));
    for i in 0..3 {
        assert!(((cal.axes[i].coeffs[0] - th.p1[i]) / th.p1[i]).abs() < 0.05);
    }
}

#[test]
fn a_narrow_temperature_range_is_flagged() {
    let dir = tempfile::tempdir().unwrap();
    let c = cfg();
    let mut r = ChamberRun::new(20.0, 7);
    r.self_heat = 8.0;
    r.duration_s = 1800.0;
    r.heat_tau_s = 600.0;
    let p = dir.path().join("narrow.log");
    r.write_file(&c, &paper(), &p).unwrap();
    let cal = calibrate_files(&c, &[p], 1).unwrap();
    assert!(cal.range.1 - cal.range.0 < 10.0);
    assert_eq!(cal.warnings.len(), 1, "{:?}", cal.warnings);
    assert!(cal.warnings[0].contains("under 10 deg C"), "{}", cal.warnings[0]);
    assert!(cal.render().contains("warning: temperature range covered"));
}

fn refused(e: &CalError) -> Vec<String> {
    match e {
        CalError::Inputs(v) => v.iter().map(|e| e.to_string()).collect(),
        other => panic!("not an input error: {other}"),
    }
}

#[test]
fn corrupt_empty_and_missing_logs_are_reported_not_fitted() {
    let dir = tempfile::tempdir().unwrap();
    let c = cfg();
    let mut r = ChamberRun::new(20.0, 9);
    r.duration_s = 600.0;
    let good = dir.path().join("good.log");
    r.write_file(&c, &paper(), &good).unwrap();
    let text = std::fs::read_to_string(&good).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    // 5 % of the lines mangled
    let mangled: String =
        lines.iter().enumerate().map(|(k, l)| if k % 20 == 3 { format!("{}ZZ\n", &l[..l.len() - 2]) } else { format!("{l}\n") }).collect();
    let garbled = dir.path().join("garbled.log");
    std::fs::write(&garbled, mangled).unwrap();
    // 5 % of the gyro frames with a flipped bit: the lines parse, the checksums fail
    let flipped: String = lines
        .iter()
        .enumerate()
        .map(|(k, l)| {
            if k % 80 == 0 {
                let mut b = l.as_bytes().to_vec();
                let n = b.len();
                b[n - 5] = if b[n - 5] == b'0' { b'1' } else { b'0' };
                format!("{}\n", String::from_utf8(b).unwrap())
            } else {
                format!("{l}\n")
            }
        })
        .collect();
    let bitflip = dir.path().join("bitflip.log");
    std::fs::write(&bitflip, flipped).unwrap();
    let empty = dir.path().join("empty.log");
    std::fs::write(&empty, "").unwrap();
    let binary = dir.path().join("binary.log");
    std::fs::write(&binary, (0..100_000u32).map(|k| (k.wrapping_mul(2654435761) >> 13) as u8).collect::<Vec<u8>>()).unwrap();
    let missing = dir.path().join("missing.log");
    // a few bad lines (< 1 %: a truncated last line, say) are tolerated and reported
    let mut trunc = text.clone();
    trunc.push_str("(1700000600.000000) can0 100#0A0");
    let truncated = dir.path().join("truncated.log");
    std::fs::write(&truncated, trunc).unwrap();
    let run = read_run(&truncated, &c).unwrap();
    assert_eq!(run.bad_lines, 1);

    let inputs = vec![good.clone(), garbled, bitflip, empty, binary, missing, truncated];
    let e = calibrate_files(&c, &inputs, 1).unwrap_err();
    let msgs = refused(&e);
    eprintln!("{e}");
    assert_eq!(msgs.len(), 5, "{msgs:?}");
    let find = |name: &str| msgs.iter().find(|m| m.contains(name)).unwrap_or_else(|| panic!("{name} not reported: {msgs:?}")).clone();
    assert!(find("garbled.log").contains("unparseable"));
    assert!(find("bitflip.log").contains("checksum"));
    assert!(find("empty.log").contains("empty"));
    assert!(find("binary.log").contains("corrupt"));
    assert!(find("missing.log").contains("cannot open"));
    // a too-short log is refused too: under MIN_FIT_BINS (3) seconds, nothing
    // beyond the run's own constant (a 60-s run is fitted: its interval says
    // how little it tells)
    let mut r = ChamberRun::new(20.0, 10);
    r.duration_s = 2.0;
    let short = dir.path().join("short.log");
    r.write_file(&c, &paper(), &short).unwrap();
    assert!(refused(&calibrate_files(&c, &[short], 1).unwrap_err())[0].contains("too short"));
}

#[test]
fn command_line_writes_config_and_svg_plots() {
    let dir = tempfile::tempdir().unwrap();
    let files = chamber(dir.path(), &paper(), |_, _| {});
    let cfg_path = dir.path().join("gyrocomp.toml");
    std::fs::write(&cfg_path, "[input]\nrate_hz = 10.0\n[thermal]\nt0 = 25.0\n").unwrap();
    let out = dir.path().join("thermal.toml");
    let plots = dir.path().join("plots");
    let exe = env!("CARGO_BIN_EXE_gyrocomp");
    let mut cmd = std::process::Command::new(exe);
    cmd.arg("calibrate").arg("--config").arg(&cfg_path).arg("--input");
    cmd.args(&files);
    cmd.arg("--write").arg(&out).arg("--plot").arg(&plots);
    let o = cmd.output().unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    eprintln!("{stdout}{}", String::from_utf8_lossy(&o.stderr));
    assert!(o.status.success());
    for ax in ["x", "y", "z"] {
        assert!(stdout.contains(&format!("axis {ax}: p1 = ")), "{stdout}");
    }
    assert!(stdout.contains("cut"));
    let c = Config::load(&out).unwrap();
    assert!((c.thermal.p1[2] - 0.0192).abs() < 0.001);
    let o = std::process::Command::new(exe).arg("check-config").arg(&out).output().unwrap();
    assert!(o.status.success());
    for f in ["bias_vs_temp_x.svg", "bias_vs_temp_y.svg", "bias_vs_temp_z.svg", "warmup_run1.svg", "warmup_run4.svg"] {
        let s = std::fs::read_to_string(plots.join(f)).unwrap();
        assert!(s.starts_with("<svg") && s.trim_end().ends_with("</svg>"), "{f}");
        assert!(s.contains("<circle") || s.contains("<polyline"), "{f}");
    }
    // a corrupt input: an error naming the file, non-zero exit, nothing written
    let bad = dir.path().join("bad.log");
    std::fs::write(&bad, "not a candump log\n".repeat(50)).unwrap();
    let out2 = dir.path().join("thermal2.toml");
    let o =
        std::process::Command::new(exe).args(["calibrate", "--input"]).arg(&files[0]).arg(&bad).arg("--write").arg(&out2).output().unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("bad.log") && err.contains("corrupt"), "{err}");
    assert!(!out2.exists());
    // an output that is one of the inputs is refused before anything is written
    let before = std::fs::read(&files[1]).unwrap();
    let o = std::process::Command::new(exe)
        .args(["calibrate", "--config"])
        .arg(&cfg_path)
        .arg("--input")
        .args(&files)
        .arg("--write")
        .arg(&files[1])
        .output()
        .unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("refusing to overwrite an input"), "{err}");
    assert_eq!(std::fs::read(&files[1]).unwrap(), before);
    // no temporary file is left beside the outputs
    assert!(std::fs::read_dir(dir.path()).unwrap().all(|e| !e.unwrap().file_name().to_string_lossy().contains(".tmp-")));
    // order out of range is refused by the parser
    let o = std::process::Command::new(exe).args(["calibrate", "--order", "4", "--input"]).arg(&files[0]).output().unwrap();
    assert!(!o.status.success());
}

#[test]
fn bad_input_never_panics() {
    let c = cfg();
    let prof = c.profile();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(42);
    let mut fitted = 0;
    for round in 0..60 {
        let log: Vec<u8> = match round % 3 {
            // random bytes
            0 => (0..rng.gen_range(0..20_000)).map(|_| rng.gen()).collect(),
            // well-formed lines, random IDs, payloads and timestamps
            1 => {
                let mut w = LogWriter::new(Vec::new(), "can0");
                for _ in 0..rng.gen_range(0..5000) {
                    let d: [u8; 8] = rng.gen();
                    w.frame(rng.gen_range(0..1u64 << 40), 0x100 + rng.gen_range(0..5), &d[..rng.gen_range(0..9)]).unwrap();
                }
                w.finish().unwrap()
            }
            // valid samples (checksums right) with wild values and jumping time
            _ => {
                let mut w = LogWriter::new(Vec::new(), "can0");
                let mut t = 1_700_000_000_000_000u64;
                for k in 0..rng.gen_range(1000..4000u32) {
                    let spike = if rng.gen_bool(0.01) { rng.gen_range(-900.0..900.0) } else { 0.0 };
                    let g: [f64; 3] = [rng.gen_range(-2.0..2.0) + spike, rng.gen_range(-0.5..0.5), 0.0];
                    let temp = if rng.gen_bool(0.5) { 25.0 } else { rng.gen_range(-40.0..85.0) };
                    let mut raw = RawSample::quantise(&prof, g, [0.0, 0.0, -1.0], [0.2, 0.0, 0.4], temp);
                    raw.cnt = k as u16;
                    t += if rng.gen_bool(0.01) { rng.gen_range(0..100_000_000) } else { 100_000 };
                    for (j, f) in raw.encode().iter().enumerate() {
                        w.frame(t, 0x100 + j as u32, f).unwrap();
                    }
                }
                w.finish().unwrap()
            }
        };
        if let Ok(run) = read_run_from(&log[..], "fuzz.log", &c) {
            for order in 1..=3 {
                if let Ok(cal) = calibrate_runs(std::slice::from_ref(&run), order, 25.0) {
                    fitted += 1;
                    let _ = cal.render();
                    let _ = cal.to_toml();
                }
            }
        }
    }
    eprintln!("{fitted} fuzz fits");
    assert!(fitted > 0, "the fit path was exercised");
}

/// Not a check: writes the four simulated chamber runs of the tests (paper's
/// coefficients, 10 Hz) into $GYROCOMP_DEMO_DIR for trying the command:
/// `GYROCOMP_DEMO_DIR=/tmp/chamber cargo test --release --test calibrate -- --ignored write_demo_logs`
#[test]
#[ignore]
fn write_demo_logs() {
    let dir = PathBuf::from(std::env::var("GYROCOMP_DEMO_DIR").expect("set GYROCOMP_DEMO_DIR"));
    std::fs::create_dir_all(&dir).unwrap();
    for p in chamber(&dir, &paper(), |_, _| {}) {
        eprintln!("wrote {}", p.display());
    }
}

/// Not a check: one 30-min run at the profile's own 204.8 Hz into
/// $GYROCOMP_DEMO_DIR/full_rate.log (for timing the reader on real-size logs).
#[test]
#[ignore]
fn write_full_rate_log() {
    let dir = PathBuf::from(std::env::var("GYROCOMP_DEMO_DIR").expect("set GYROCOMP_DEMO_DIR"));
    std::fs::create_dir_all(&dir).unwrap();
    let c = Config::default();
    let mut r = ChamberRun::new(20.0, 5);
    r.duration_s = 1800.0;
    r.heat_tau_s = 600.0;
    r.warmup_amp = [0.1, -0.1, 0.2];
    r.write_file(&c, &paper(), &dir.join("full_rate.log")).unwrap();
}
