//! `gyrocomp align` on simulated drives with a sensor mounted rotated: it
//! proposes the mounting, and the estimator run with that proposal holds the
//! vehicle's attitude.

mod common;
use common::bin;
use gyrocomp::config::Config;
use gyrocomp::evaluate::{score, RunData};
use std::process::Command;

fn proposed(out: &str) -> [f64; 3] {
    let line = out.lines().find(|l| l.starts_with("rotation = [")).unwrap_or_else(|| panic!("no rotation in\n{out}"));
    let inner = &line["rotation = [".len()..line.find(']').unwrap()];
    let v: Vec<f64> = inner.split(',').map(|x| x.trim().parse().unwrap()).collect();
    [v[0], v[1], v[2]]
}

/// The mounting roll and pitch that the stops' gravity implies: each
/// standstill `align` reported, its mean road grade from vehicle.csv, the
/// gravity that grade gives in the vehicle frame seen through the true
/// mounting, averaged by length.
fn stops_gravity(dir: &std::path::Path, out: &str, m: [f64; 3]) -> [f64; 2] {
    let d = std::f64::consts::PI / 180.0;
    let veh = std::fs::read_to_string(dir.join("vehicle.csv")).unwrap();
    let rows: Vec<(f64, f64)> = veh
        .lines()
        .skip(1)
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            (v[0], v[5])
        })
        .collect();
    let r = gyrocomp::estimator::quat::matrix_from_euler(m[0] * d, m[1] * d, m[2] * d);
    let mut sum = [0.0; 3];
    for line in out.lines().filter(|l| l.starts_with("standstill at")) {
        let w: Vec<&str> = line.split_whitespace().collect();
        let (t0, len): (f64, f64) = (w[2].parse().unwrap(), w[5].parse().unwrap());
        let g: Vec<f64> = rows.iter().filter(|(t, _)| *t >= t0 && *t < t0 + len).map(|(_, g)| *g).collect();
        if g.is_empty() {
            continue; // shorter than the printed resolution
        }
        let grade = g.iter().sum::<f64>() / g.len() as f64 * d;
        let fv = [grade.sin(), 0.0, -grade.cos()];
        let fs = gyrocomp::estimator::quat::rotate_t(&r, &fv);
        for i in 0..3 {
            sum[i] += fs[i] * len;
        }
    }
    let (roll, pitch) = gyrocomp::estimator::ekf::tilt_from_accel(&sum);
    [roll / d, pitch / d]
}

fn angle_diff(a: f64, b: f64) -> f64 {
    ((a - b + 540.0) % 360.0 - 180.0).abs()
}

#[test]
fn align_recovers_a_rotated_mounting_and_the_estimator_holds_with_it() {
    let d = tempfile::tempdir().unwrap();
    // the last run starts while driving (a 0.1-0.2 g pull-away with road
    // vibration in the first second): its g0 is not gravity, and taken as
    // gravity it made steady accelerations pass for stops (proposed roll
    // -0.24, pitch 4.23 for a mounting of 3, 2)
    for (seed, m, moving) in
        [(3u64, [4.0, -3.0, 35.0], false), (5, [-2.0, 5.0, -120.0], false), (6, [180.0, 0.0, 90.0], false), (7, [3.0, 2.0, -60.0], true)]
    {
        let dir = d.path().join(format!("run{seed}"));
        let o = Command::new(bin())
            .args(["simulate", "--scenario", "urban", "--seed", &seed.to_string(), "--out"])
            .arg(&dir)
            .arg(format!("--mounting={},{},{}", m[0], m[1], m[2]))
            .args(if moving { &["--power-on-moving"][..] } else { &[][..] })
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let o = Command::new(bin()).args(["align", "--input"]).arg(dir.join("imu.log")).output().unwrap();
        let out = String::from_utf8_lossy(&o.stdout).to_string();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let p = proposed(&out);
        // The stops are on hills (grades of +-7 deg): what gravity at the
        // stops says is the mounting tilted by their mean grade. Work that
        // out from the simulator's own record of the road.
        let expect = stops_gravity(&dir, &out, m);
        println!("seed {seed}: true {m:?}, with the stops' mean grade {expect:?}, proposed {p:?}");
        // budget: the accelerometer bias the simulator draws (up to 0.005 g
        // per axis, 0.4 deg of tilt) and the body settling after a stop
        for i in 0..2 {
            assert!(angle_diff(p[i], expect[i]) < 1.0, "axis {i}: {p:?} vs {expect:?}\n{out}");
        }
        assert!(angle_diff(p[2], m[2]) < 2.0, "yaw: {p:?} vs {m:?}\n{out}");
        // the estimator with the proposed mounting in place of the true one:
        // its vehicle-frame attitude is off by no more than the mounting is
        let off = (0..3).map(|i| angle_diff(p[i], m[i])).fold(0.0, f64::max);
        let data = RunData::load(&dir).unwrap();
        let mut cfg = Config::load(&dir.join("config.toml")).unwrap();
        cfg.mounting.rotation = p;
        let (est, ms) = data.estimates(&cfg).unwrap();
        // powered on while driving, IMU only, the attitude is unknown until
        // the first stops (docs/estimator.md, known limits): scored from 100 s
        let s = score("aligned", &data, &est, ms, if moving { 100.0 } else { 10.0 });
        assert!(s.tilt_max() < off + 1.0, "seed {seed}: max roll/pitch {:?} with a mounting {off:.2} deg off", s.max_err);
    }
}

#[test]
fn align_without_a_standstill_says_why() {
    let d = tempfile::tempdir().unwrap();
    let dir = d.path().join("moving");
    let o = Command::new(bin())
        .args(["simulate", "--scenario", "urban", "--seed", "2", "--power-on-moving", "--duration", "40", "--out"])
        .arg(&dir)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = Command::new(bin()).args(["align", "--input"]).arg(dir.join("imu.log")).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    if o.status.success() {
        // a stop inside the first 40 s: then it must have said so
        assert!(String::from_utf8_lossy(&o.stdout).contains("standstill at"));
    } else {
        assert!(err.contains("no standstill"), "{err}");
    }
    let o = Command::new(bin()).args(["align", "--input"]).arg(d.path().join("nope.log")).output().unwrap();
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("cannot open"));
}
