//! `gyrocomp simulate --input-dbc CONFIG`: the same simulated unit on the
//! bus in a DBC format (imu.log) and in the ADIS contract (adis.log), at
//! one rate. Decoded, the two agree sample by sample within the sum of the
//! two formats' half LSBs; replayed, their estimates agree; and the same
//! seed gives the same bytes.

mod common;
use gyrocomp::adis::{Assembler, Push, RawFrame, Sample};
use gyrocomp::candump::parse_line;
use gyrocomp::config::Config;
use gyrocomp::dbcin::DbcAssembler;
use std::path::Path;
use std::process::Command;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

fn run(args: &[&str]) -> String {
    let o = Command::new(common::bin()).args(args).output().unwrap();
    assert!(o.status.success(), "{args:?}: {}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stderr).to_string()
}

fn simulate(config: &str, out: &Path, seconds: &str) {
    let c = format!("{ROOT}/config/{config}");
    run(&["simulate", "--scenario", "vehicle", "--seed", "3", "--duration", seconds, "--out", out.to_str().unwrap(), "--input-dbc", &c]);
}

fn samples(log: &Path, mut push: impl FnMut(u64, RawFrame<'_>) -> Option<Sample>) -> Vec<Sample> {
    let text = std::fs::read_to_string(log).unwrap();
    text.lines()
        .filter_map(|l| {
            let f = parse_line(l.as_bytes()).unwrap();
            push(f.t_us, RawFrame { id: f.id, extended: f.extended, remote: f.remote, fd: f.fd, data: f.payload() })
        })
        .collect()
}

/// Both logs decoded: every channel within half an LSB of each format of the other.
fn samples_agree_within_quantisation(dir: &Path) -> usize {
    let dbc = Config::load(&dir.join("config.toml")).unwrap();
    let adis = Config::load(&dir.join("adis.toml")).unwrap();
    let plan = dbc.input.plan.0.clone().unwrap();
    let mut a = DbcAssembler::new(plan.clone());
    let got = samples(&dir.join("imu.log"), |t, f| if let Push::Sample(s) = a.push(t, f) { Some(s) } else { None });
    let mut b = Assembler::new(adis.profile(), adis.input.ids);
    let want = samples(&dir.join("adis.log"), |t, f| if let Push::Sample(s) = b.push(t, f) { Some(s) } else { None });
    assert_eq!(got.len(), want.len());
    assert_eq!(a.counters.dropped() + b.counters.dropped(), 0, "{:?} {:?}", a.counters, b.counters);
    let p = adis.profile();
    let adis_lsb = [p.gyro_lsb, p.gyro_lsb, p.gyro_lsb, p.accel_lsb, p.accel_lsb, p.accel_lsb, p.temp_lsb];
    let mut worst = [0.0f64; 7];
    for (k, (s, w)) in got.iter().zip(&want).enumerate() {
        assert_eq!((s.steps, s.t_us.abs_diff(w.t_us) < 1000), (w.steps, true), "sample {k}");
        let x = [s.gyro[0], s.gyro[1], s.gyro[2], s.accel[0], s.accel[1], s.accel[2], s.temp];
        let y = [w.gyro[0], w.gyro[1], w.gyro[2], w.accel[0], w.accel[1], w.accel[2], w.temp];
        for c in 0..7 {
            let Some(ch) = plan.channels[c] else { continue };
            let tol = 0.5 * (ch.a.abs() + adis_lsb[c]) + 1e-9;
            let d = (x[c] - y[c]).abs();
            assert!(d <= tol, "sample {k} channel {c}: dbc {} adis {} (tolerance {tol})", x[c], y[c]);
            worst[c] = worst[c].max(d / tol);
        }
    }
    // the tolerance is not loose: some sample comes near it on every gyro axis
    assert!(worst[..3].iter().all(|w| *w > 0.5), "{worst:?}");
    got.len()
}

#[test]
fn mm7p10_and_adis_carry_the_same_samples_and_give_the_same_estimates() {
    let d = tempfile::tempdir().unwrap();
    simulate("mm7p10.toml", d.path(), "300");
    let n = samples_agree_within_quantisation(d.path());
    assert_eq!(n, 30001);
    let p = |f: &str| d.path().join(f).to_str().unwrap().to_string();
    run(&["replay", "--config", &p("config.toml"), "--input", &p("imu.log"), "--csv", &p("dbc.csv")]);
    run(&["replay", "--config", &p("adis.toml"), "--input", &p("adis.log"), "--csv", &p("adis.csv")]);
    let rows = |f: &str| -> Vec<Vec<f64>> {
        std::fs::read_to_string(d.path().join(f))
            .unwrap()
            .lines()
            .skip(1)
            .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
            .collect()
    };
    let (x, y) = (rows("dbc.csv"), rows("adis.csv"));
    assert_eq!(x.len(), y.len());
    let rms = |c: usize| (x.iter().zip(&y).map(|(a, b)| (a[c] - b[c]).powi(2)).sum::<f64>() / x.len() as f64).sqrt();
    // roll, pitch (deg), rates (deg/s), biases (deg/s)
    for (c, lim) in [(1, 0.1), (2, 0.1), (4, 0.03), (5, 0.03), (6, 0.03), (7, 0.01), (8, 0.01), (9, 0.02)] {
        assert!(rms(c) < lim, "column {c}: rms difference {} >= {lim}", rms(c));
    }
    // the learned bias at the end, against the truth, is as good on either path
    let bias: Vec<f64> = std::fs::read_to_string(d.path().join("bias.csv"))
        .unwrap()
        .lines()
        .last()
        .unwrap()
        .split(',')
        .map(|v| v.parse().unwrap())
        .collect();
    for k in 0..3 {
        let (e1, e2) = (x.last().unwrap()[7 + k] - bias[1 + k], y.last().unwrap()[7 + k] - bias[1 + k]);
        assert!(e1.abs() < 0.01 && e2.abs() < 0.01, "axis {k}: dbc {e1} adis {e2}");
    }
    // determinism: the same seed and config give the same bytes
    let d2 = tempfile::tempdir().unwrap();
    simulate("mm7p10.toml", d2.path(), "300");
    for f in ["imu.log", "adis.log", "config.toml", "adis.toml", "mm7p10.dbc"] {
        assert!(std::fs::read(d.path().join(f)).unwrap() == std::fs::read(d2.path().join(f)).unwrap(), "{f} differs");
    }
    run(&["replay", "--config", &p("config.toml"), "--input", &p("imu.log"), "--csv", &p("dbc2.csv")]);
    assert!(std::fs::read(d.path().join("dbc.csv")).unwrap() == std::fs::read(d.path().join("dbc2.csv")).unwrap());
}

#[test]
fn j1939_and_adis_carry_the_same_samples() {
    // (no temperature in ARI/ACCS: the estimates differ where the thermal curve acts, so only the samples are compared)
    let d = tempfile::tempdir().unwrap();
    simulate("j1939-imu.toml", d.path(), "60");
    assert_eq!(samples_agree_within_quantisation(d.path()), 6001);
    let log = std::fs::read_to_string(d.path().join("imu.log")).unwrap();
    assert!(log.lines().next().unwrap().contains(" 0CF02A80#"), "{}", &log[..80]);
}

#[test]
fn the_adis_only_commands_refuse_a_dbc_config() {
    let d = tempfile::tempdir().unwrap();
    simulate("mm7p10.toml", d.path(), "10");
    let p = |f: &str| d.path().join(f).to_str().unwrap().to_string();
    for args in [
        vec!["align", "--config", &p("config.toml"), "--input", &p("imu.log")],
        vec!["calibrate", "--config", &p("config.toml"), "--input", &p("imu.log")],
        vec!["evaluate", "--input", &p("")],
    ] {
        let o = Command::new(common::bin()).args(&args).output().unwrap();
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && e.contains("reads the ADIS frames only") && e.contains("format = \"dbc\""), "{args:?}: {e}");
    }
}

#[test]
fn an_adis_config_is_refused_a_reduced_one_simulates() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("x");
    // the car's own yaw-rate sensor: its frames, and its replay marks what it cannot give
    let o = Command::new(common::bin())
        .args(["simulate", "--scenario", "static", "--duration", "6", "--out", out.to_str().unwrap(), "--input-dbc"])
        .arg(format!("{ROOT}/config/toyota-kinematics.toml"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let csv = out.join("est.csv");
    let o = Command::new(common::bin())
        .args(["replay", "--config"])
        .arg(out.join("config.toml"))
        .arg("--input")
        .arg(out.join("imu.log"))
        .arg("--csv")
        .arg(&csv)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&csv).unwrap();
    let last = text.lines().last().unwrap();
    // roll and pitch 0 (invalid), mode 0 or 2, invalid = rate x, y, roll, pitch, temp
    assert!(last.starts_with(|c: char| c.is_ascii_digit()) && last.ends_with(",91"), "{last}");
    let f: Vec<f64> = last.split(',').map(|v| v.parse().unwrap()).collect();
    assert_eq!((f[1], f[2], f[4], f[5]), (0.0, 0.0, 0.0, 0.0), "{last}");
    std::fs::remove_dir_all(&out).unwrap();
    // the ADIS config: refused
    {
        let (c, want) = ("gyrocomp.toml", "not format = \"dbc\"");
        let o = Command::new(common::bin())
            .args([
                "simulate",
                "--scenario",
                "static",
                "--duration",
                "1",
                "--out",
                out.to_str().unwrap(),
                "--input-dbc",
                &format!("{ROOT}/config/{c}"),
            ])
            .output()
            .unwrap();
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && e.contains(want), "{c}: {e}");
        assert!(!out.exists());
    }
}
