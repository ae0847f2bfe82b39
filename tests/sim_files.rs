//! `gyrocomp simulate` files: determinism, the ADIS log, the model file.

use gyrocomp::config::Config;
use gyrocomp::estimator::Estimate;
use gyrocomp::replay::{replay_files, ReplayFiles};
use gyrocomp::sim::model::SensorModel;
use gyrocomp::sim::{prepare, read_truth, samples, simulate, SimOptions};
use std::path::Path;

const FILES: [&str; 6] = ["imu.log", "truth.csv", "sensor.toml", "bias.csv", "scenario.toml", "config.toml"];

fn opts(scenario: &str, seed: u64, dur: f64) -> SimOptions {
    let mut o = SimOptions::new(scenario, seed);
    o.duration = Some(dur);
    o
}

fn read(d: &Path, f: &str) -> Vec<u8> {
    std::fs::read(d.join(f)).unwrap()
}

#[test]
fn same_seed_same_bytes_other_seed_other_bytes() {
    let t = tempfile::tempdir().unwrap();
    let (a, b, c) = (t.path().join("a"), t.path().join("b"), t.path().join("c"));
    let mut o = opts("vehicle", 11, 20.0);
    o.hard = true;
    simulate(&o, &a).unwrap();
    simulate(&o, &b).unwrap();
    o.seed = 12;
    simulate(&o, &c).unwrap();
    for f in FILES {
        assert_eq!(read(&a, f), read(&b, f), "{f} differs for the same seed");
    }
    for f in ["imu.log", "truth.csv", "sensor.toml"] {
        assert_ne!(read(&a, f), read(&c, f), "{f} equal for another seed");
    }
}

#[test]
fn quantised_log_replays_and_decodes_to_the_measurement() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path().join("run");
    let o = opts("paper", 2, 15.0);
    let files = simulate(&o, &d).unwrap();
    let cfg = Config::load(&d.join("config.toml")).unwrap();
    let mut est: Vec<Estimate> = Vec::new();
    let sum = replay_files(&cfg, &ReplayFiles { input: &d.join("imu.log"), output: None, csv: None, mcap: None }, Some(&mut est)).unwrap();
    assert_eq!(sum.bad_lines, 0);
    assert_eq!(sum.input.dropped(), 0);
    assert_eq!(sum.input.samples, files.samples);
    assert_eq!(est.len() as u64, files.samples);
    let truth = read_truth(&d.join("truth.csv")).unwrap();
    assert_eq!(truth.len() as u64, files.samples);
    // Decoded gyro (rate + bias of the estimate) = the measurement rounded to the LSB.
    let run = prepare(&o).unwrap();
    let lsb = run.profile.gyro_lsb;
    for ((k, (tr, m, _raw)), e) in samples(&run, o.seed).enumerate().zip(&est) {
        assert!((tr.t - truth[k].t).abs() < 1e-6);
        assert!((e.t - tr.t).abs() < 1e-9, "sample {k}: t {} vs {}", e.t, tr.t);
        for i in 0..3 {
            let dec = e.rate[i] + e.bias[i];
            assert!((dec - m.gyro[i]).abs() <= 0.5 * lsb + 1e-9, "sample {k} axis {i}: {dec} vs {}", m.gyro[i]);
            assert!((truth[k].att[i] - [tr.roll, tr.pitch, tr.yaw][i]).abs() < 1e-5);
        }
        assert!((e.temp - m.temp).abs() <= 0.5 * run.profile.temp_lsb + 1e-9);
    }
}

#[test]
fn a_forced_model_is_what_the_log_carries() {
    // Only a turn-on bias, no noise: at rest the decoded gyro is the bias to one LSB.
    let model = SensorModel::parse(
        "[gyro]\neffects = [\"turn_on_bias\"]\n[gyro.turn_on_bias]\nbias = [0.3, -0.12, 0.5]\n\
         [noise]\ngyro_white = 0.0\ngyro_bias_walk = 0.0\naccel_white = 0.0\nmagn_white = 0.0\ntemp_white = 0.0\n",
    )
    .unwrap();
    let mut o = opts("static", 1, 5.0);
    o.model = Some(model.clone());
    let run = prepare(&o).unwrap();
    assert_eq!(run.model, model);
    for (_, m, raw) in samples(&run, 1) {
        for (i, b) in [0.3, -0.12, 0.5].iter().enumerate() {
            assert!((m.gyro[i] - b).abs() < 1e-12);
            assert_eq!(raw.gyro[i], (b / 0.04f64).round() as i16);
        }
    }
}

#[test]
fn sensor_toml_reproduces_the_run() {
    let t = tempfile::tempdir().unwrap();
    let (a, b) = (t.path().join("a"), t.path().join("b"));
    let o = opts("vehicle", 4, 10.0);
    simulate(&o, &a).unwrap();
    let mut o2 = o.clone();
    o2.model = Some(SensorModel::load(&a.join("sensor.toml")).unwrap());
    simulate(&o2, &b).unwrap();
    // the TOML round trip of the drawn floats is exact
    assert_eq!(read(&a, "imu.log"), read(&b, "imu.log"));
}

#[test]
fn ranges_switch_effects_and_refuse_unknown_keys() {
    let mut o = opts("vehicle", 4, 5.0);
    o.ranges = Some("effects = [\"turn_on_bias\", \"time_delay\"]\nturn_on_bias = 0.1\n[noise]\ngyro_white = 0.0\n".into());
    let run = prepare(&o).unwrap();
    let g = &run.model.gyro;
    assert_eq!(g.effects.len(), 2);
    assert!(g.thermal_linear.is_none() && g.time_delay.is_some());
    assert!(g.turn_on_bias.as_ref().unwrap().bias.iter().all(|b| b.abs() <= 0.1));
    assert_eq!(run.model.noise.gyro_white, 0.0);
    assert!(run.model.noise.gyro_bias_walk > 0.0);
    o.ranges = Some("turn_on = 0.1\n".into());
    assert!(prepare(&o).is_err());
}
