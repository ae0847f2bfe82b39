//! The vehicle's speed from its bus ([speed]) in the estimator: start-up
//! errors name what is wrong, bad frames are counted and dropped, a silent
//! source falls back to the IMU alone (flagged), and with the wheel speeds a
//! car powered on while driving holds its attitude.

mod common;
use common::bin;
use gyrocomp::candump::{parse_line, write_line};
use gyrocomp::config::Config;
use gyrocomp::estimator::flags;
use gyrocomp::evaluate::{score, RunData};
use gyrocomp::sim::SimOptions;
use std::path::Path;
use std::process::Command;

const SPEED: &str = "[speed]\ndbc = \"car.dbc\"\nmessage = \"WHEEL_SPEEDS\"\nsignals = [\"WHEEL_SPEED_RL\", \"WHEEL_SPEED_RR\"]\n";

fn check(dir: &Path, toml: &str) -> (bool, String) {
    let p = dir.join("c.toml");
    std::fs::write(&p, toml).unwrap();
    let o = Command::new(bin()).arg("check-config").arg(&p).output().unwrap();
    (o.status.success(), String::from_utf8_lossy(&o.stderr).to_string())
}

#[test]
fn a_bad_speed_source_is_a_clear_error_at_start_up() {
    let d = tempfile::tempdir().unwrap();
    let dbc = gyrocomp::sim::wheel::EXAMPLE_DBC;
    // no DBC file (relative to the config file's directory)
    let (ok, e) = check(d.path(), SPEED);
    assert!(!ok && e.contains("speed.dbc") && e.contains("car.dbc") && e.contains("cannot read"), "{e}");
    // a DBC that does not parse
    std::fs::write(d.path().join("car.dbc"), "BO_ this is not a DBC\n").unwrap();
    let (ok, e) = check(d.path(), SPEED);
    assert!(!ok && e.contains("not a valid DBC"), "{e}");
    // a message or a signal it does not have
    std::fs::write(d.path().join("car.dbc"), dbc).unwrap();
    let (ok, e) = check(d.path(), &SPEED.replace("\"WHEEL_SPEEDS\"", "\"WHEELS\""));
    assert!(!ok && e.contains("no message named \"WHEELS\""), "{e}");
    let (ok, e) = check(d.path(), &SPEED.replace("WHEEL_SPEED_RR", "WHEEL_SPEED_XX"));
    assert!(!ok && e.contains("no signal named \"WHEEL_SPEED_XX\""), "{e}");
    // its ID taken by the IMU
    let (ok, e) = check(d.path(), &format!("{SPEED}[input.ids]\naccel = 0x1A0\n"));
    assert!(!ok && e.contains("speed.message"), "{e}");
    // and the good one, from another working directory
    let (ok, e) = check(d.path(), SPEED);
    assert!(ok, "{e}");
}

/// (t_us, id, payload) of a candump log.
fn lines(p: &Path) -> Vec<(u64, u32, Vec<u8>)> {
    std::fs::read_to_string(p)
        .unwrap()
        .lines()
        .map(|l| {
            let f = parse_line(l.as_bytes()).unwrap();
            (f.t_us, f.id, f.payload().to_vec())
        })
        .collect()
}

#[test]
fn bad_speed_frames_are_counted_and_a_silent_source_falls_back_to_the_imu() {
    let d = tempfile::tempdir().unwrap();
    let sim = d.path().join("sim");
    let o = Command::new(bin())
        .args(["simulate", "--scenario", "urban", "--seed", "7", "--duration", "60", "--speed", "--out"])
        .arg(&sim)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // rewrite the bus: 10 wheel frames with 5 bytes, 10 out of range, and no
    // wheel frames at all from 30 to 40 s
    let mut out = Vec::new();
    let (mut short, mut range) = (0, 0);
    let t0 = lines(&sim.join("imu.log"))[0].0;
    for (t, id, data) in lines(&sim.join("imu.log")) {
        let s = (t - t0) as f64 * 1e-6;
        if id == 0x1A0 {
            if (30.0..40.0).contains(&s) {
                continue;
            }
            if s > 45.0 && short < 10 {
                short += 1;
                write_line(&mut out, t, b"vcan0", id, &data[..5]);
                continue;
            }
            if s > 50.0 && range < 10 {
                range += 1;
                let mut bad = data.clone();
                bad[4..6].copy_from_slice(&i16::MAX.to_le_bytes()); // RL: 327.67 km/h, above the DBC's 300
                write_line(&mut out, t, b"vcan0", id, &bad);
                continue;
            }
        }
        write_line(&mut out, t, b"vcan0", id, &data);
    }
    let log = sim.join("faulty.log");
    std::fs::write(&log, out).unwrap();
    let csv = sim.join("est.csv");
    let o = Command::new(bin())
        .arg("replay")
        .arg("--config")
        .arg(sim.join("config.toml"))
        .arg("--input")
        .arg(&log)
        .arg("--output")
        .arg(sim.join("out.log"))
        .arg("--csv")
        .arg(&csv)
        .output()
        .unwrap();
    let summary = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{summary}");
    assert!(summary.contains("dropped wrong_dlc 10 out_of_range 10 implausible 0"), "{summary}");
    // SpeedAided off while the source is silent (after its 0.5 s timeout), on otherwise
    let mut on_before = 0;
    let mut on_silent = 0;
    let mut silent = 0;
    for (t, id, data) in lines(&sim.join("out.log")) {
        if id != 0x113 {
            continue;
        }
        let s = (t - t0) as f64 * 1e-6;
        let aided = (u16::from_le_bytes([data[0], data[1]]) >> 2) & flags::SPEED_AIDED != 0;
        if (5.0..30.0).contains(&s) && aided {
            on_before += 1;
        }
        if (30.6..40.0).contains(&s) {
            silent += 1;
            on_silent += aided as usize;
        }
    }
    assert!(on_before > 5000, "SpeedAided on {on_before} status frames before the silence");
    assert!(silent > 1500 && on_silent == 0, "SpeedAided on {on_silent} of {silent} status frames while the source was silent");
    // the estimate went on through it all
    let rows = std::fs::read_to_string(&csv).unwrap().lines().count();
    assert_eq!(rows, 1 + 60 * 2048 / 10 + 1, "{rows} CSV rows");
}

#[test]
fn with_the_wheel_speeds_a_car_powered_on_while_driving_holds_its_attitude() {
    // the IMU alone, powered on at 8-13 m/s with a turn-on bias of several
    // deg/s and no saved bias, cannot tell pitch from acceleration until it
    // stops; the wheel speeds tell it at once
    let mut o = SimOptions::new("urban", 3);
    o.power_on_moving = true;
    o.speed = true;
    let data = RunData::simulate(&o).unwrap();
    let unit = data.unit_config.clone().unwrap();
    let run = |speed: bool| {
        let mut c = Config { thermal: unit.thermal.clone(), mounting: unit.mounting.clone(), ..Config::default() };
        if speed {
            c.speed = unit.speed.clone();
        }
        let (est, ms) = data.estimates(&c).unwrap();
        score("x", &data, &est, ms, 30.0)
    };
    let with = run(true);
    let without = run(false);
    assert!(with.max_err[0] <= 2.0 && with.max_err[1] <= 2.0, "with speed {:?}", with.max_err);
    assert!(without.tilt_max() > 2.0 * with.tilt_max(), "IMU only {:?} vs with speed {:?}", without.max_err, with.max_err);
}
