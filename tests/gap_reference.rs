//! `gyrocomp gap --reference`: the truth derived from a measured reference.
//!
//! Without `../shared`: a simulated drive whose reference CSV the test writes
//! in the recordings' format (`t,roll,pitch,yaw,valid,rest`), the reference's
//! body tilted from the sensor's by a known mount and lost for 5 s in the
//! middle, the sensor with a hidden time delay. `gap --reference` must report
//! the mount, use only the two valid stretches, find the delay within its
//! interval, refuse a reference of another run, and write the same bytes
//! twice. Several such trials: the delay consistent and added, the
//! leave-one-out residual lower.
//!
//! With `../shared/realdata` (skipped, saying so, without it): the five
//! BROAD trials through `gap --measured ... --reference ...`.

mod common;
use common::{bin, realdata_dir};
use gyrocomp::adis::{builtin_profile, RawSample};
use gyrocomp::sim::model::SensorModel;
use gyrocomp::sim::{prepare, samples, SimOptions};
use nalgebra::{Rotation3, UnitQuaternion};
use std::path::Path;
use std::process::Command;

const BASE: &str = "[gyro]\neffects = [\"turn_on_bias\", \"thermal_linear\"]\n";
const DELAY_S: f64 = 0.02;
/// The mount (reference body to sensor): roll, pitch, deg.
const MOUNT_DEG: [f64; 2] = [0.4, -0.3];

/// A simulated drive written as the recordings are: `imu.csv` (the sensor,
/// with the hidden delay) and `reference.csv` (the truth's attitude of a
/// body tilted by the mount; invalid for 5 s from 150 s; rest where the
/// truth does not move).
fn write_trial(dir: &Path, seed: u64) {
    std::fs::create_dir_all(dir).unwrap();
    let unit = format!(
        "[gyro]\neffects = [\"turn_on_bias\", \"thermal_linear\", \"time_delay\"]\n[gyro.turn_on_bias]\nbias = [0.12, -0.31, 0.05]\n\
         [gyro.thermal_linear]\nt0 = 25.0\np1 = [0.002, 0.0044, 0.0192]\n[gyro.time_delay]\ndelay_s = {DELAY_S}\n"
    );
    let mut o = SimOptions::new("vehicle", seed);
    o.duration = Some(300.0);
    o.model = Some(SensorModel::parse(&unit).unwrap());
    let run = prepare(&o).unwrap();
    let prof = builtin_profile("adis16448").unwrap();
    // v_sensor = M v_ref, so the reference body's attitude is C_sensor M
    let m = Rotation3::from_euler_angles(MOUNT_DEG[0].to_radians(), MOUNT_DEG[1].to_radians(), 0.0);
    let mut imu = String::from("t,gx,gy,gz,ax,ay,az,mx,my,mz,temp\n");
    let mut refcsv = String::from("t,roll,pitch,yaw,valid,rest\n");
    let mut moved = false;
    for (tr, meas, _) in samples(&run, seed) {
        let raw = RawSample::quantise(&prof, meas.gyro, meas.accel, meas.magn, meas.temp);
        let g = raw.gyro.map(|v| v as f64 * prof.gyro_lsb);
        let a = meas.accel;
        imu += &format!("{:.6},{},{},{},{},{},{},,,,{}\n", tr.t, g[0], g[1], g[2], a[0], a[1], a[2], meas.temp);
        moved |= tr.rate.iter().any(|r| r.abs() > 1e-6);
        let c = UnitQuaternion::from_euler_angles(tr.roll.to_radians(), tr.pitch.to_radians(), tr.yaw.to_radians())
            * UnitQuaternion::from_rotation_matrix(&m);
        let (r, p, y) = c.euler_angles();
        if (150.0..155.0).contains(&tr.t) {
            refcsv += &format!("{:.6},,,,0,{}\n", tr.t, u8::from(!moved));
        } else {
            refcsv += &format!("{:.6},{},{},{},1,{}\n", tr.t, r.to_degrees(), p.to_degrees(), y.to_degrees(), u8::from(!moved));
        }
    }
    std::fs::write(dir.join("imu.csv"), imu).unwrap();
    std::fs::write(dir.join("reference.csv"), refcsv).unwrap();
}

fn gap(args: &[&Path], out: &Path) -> std::process::Output {
    let mut c = Command::new(bin());
    c.arg("gap");
    for a in args {
        c.arg(a);
    }
    c.arg("--out").arg(out).output().unwrap()
}

fn report(out: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap()
}

#[test]
fn a_reference_with_a_mount_and_a_gap_gives_the_hidden_delay() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    write_trial(&p.join("a"), 11);
    write_trial(&p.join("b"), 12);
    std::fs::write(p.join("base.toml"), BASE).unwrap();
    let (imu, refa, base) = (p.join("a/imu.csv"), p.join("a/reference.csv"), p.join("base.toml"));
    let o = gap(&[Path::new("--measured"), &imu, Path::new("--reference"), &refa, Path::new("--model"), &base], &p.join("out"));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r = report(&p.join("out"));
    let tf = &r["truth_from"];
    println!("{}", serde_json::to_string_pretty(tf).unwrap());
    // the mount: the sim's accelerometer has no bias, so only its noise over the rest limits the tilt
    let m = &tf["mount"];
    let (roll, pitch) = (m["roll_deg"].as_f64().unwrap(), m["pitch_deg"].as_f64().unwrap());
    assert!((roll - MOUNT_DEG[0]).abs() < 0.02 && (pitch - MOUNT_DEG[1]).abs() < 0.02, "mount {roll} {pitch}");
    assert_eq!(tf["stretches"].as_array().unwrap().len(), 2, "the 5 s the reference lost split the data");
    let f = r["findings"].as_array().unwrap();
    let delay = f.iter().find(|x| x["effect"] == "time_delay").unwrap_or_else(|| panic!("no delay found: {f:?}"));
    let (c, se) = (delay["coefficient"].as_f64().unwrap(), delay["std_error"].as_f64().unwrap());
    println!("delay {c} +- {se}");
    assert!((c - DELAY_S).abs() < 4.0 * se, "delay {c} +- {se}, hidden {DELAY_S}");
    // misalignment left by the mount: removed (at most a term below 4 SE would be left)
    assert!(!f.iter().any(|x| x["effect"] == "misalignment"), "the mount was not removed: {f:?}");
    // the same inputs, the same bytes
    let o2 = gap(&[Path::new("--measured"), &imu, Path::new("--reference"), &refa, Path::new("--model"), &base], &p.join("out2"));
    assert!(o2.status.success());
    assert_eq!(std::fs::read(p.join("out/report.json")).unwrap(), std::fs::read(p.join("out2/report.json")).unwrap());
    // another run's reference is refused, and nothing is written
    let refb = p.join("b/reference.csv");
    let o3 = gap(&[Path::new("--measured"), &imu, Path::new("--reference"), &refb, Path::new("--model"), &base], &p.join("out3"));
    let e = String::from_utf8_lossy(&o3.stderr);
    assert!(!o3.status.success() && e.contains("do not agree"), "{e}");
    assert!(!p.join("out3").exists());
}

#[test]
fn trials_agree_on_the_delay_and_the_held_out_residual_shrinks() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    for (k, s) in ["a", "b", "c"].iter().zip([21, 22, 23]) {
        write_trial(&p.join(k), s);
    }
    std::fs::write(p.join("base.toml"), BASE).unwrap();
    let mut c = Command::new(bin());
    c.arg("gap").arg("--measured");
    for k in ["a", "b", "c"] {
        c.arg(p.join(k).join("imu.csv"));
    }
    c.arg("--reference");
    for k in ["a", "b", "c"] {
        c.arg(p.join(k).join("reference.csv"));
    }
    let c2 = Command::new(c.get_program())
        .args(c.get_args())
        .arg("--model")
        .arg(p.join("base.toml"))
        .arg("--out")
        .arg(p.join("out2"))
        .output()
        .unwrap();
    let o = c.arg("--model").arg(p.join("base.toml")).arg("--out").arg(p.join("out")).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    println!("{}", String::from_utf8_lossy(&o.stdout));
    assert!(c2.status.success());
    for f in ["trials.json", "model.toml", "a/report.json"] {
        assert_eq!(
            std::fs::read(p.join("out").join(f)).unwrap(),
            std::fs::read(p.join("out2").join(f)).unwrap(),
            "{f}: the same inputs, the same bytes"
        );
    }
    let j: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(p.join("out/trials.json")).unwrap()).unwrap();
    let rows = j["effects"].as_array().unwrap();
    let delay = rows.iter().find(|r| r["term"] == "time_delay").expect("the delay is named");
    assert_eq!(delay["added"], true, "{delay}");
    assert_eq!(delay["consistent"], true);
    let (c, se) = (delay["joint"].as_f64().unwrap(), delay["joint_std_error"].as_f64().unwrap());
    assert!((c - DELAY_S).abs() < 4.0 * se, "joint delay {c} +- {se}");
    let model = std::fs::read_to_string(p.join("out/model.toml")).unwrap();
    assert!(model.contains("time_delay") && !model.contains("[gyro.turn_on_bias]"), "{model}");
    for h in j["leave_one_out"].as_array().unwrap() {
        let axes = h["axes"].as_array().unwrap();
        assert!(!axes.is_empty(), "{h}");
        for a in axes {
            let k = ["x", "y", "z"].iter().position(|x| *x == a).unwrap();
            let (b, e) = (h["rms_base"][k].as_f64().unwrap(), h["rms_extended"][k].as_f64().unwrap());
            assert!(e < b, "{}: axis {a}: {b} -> {e}", h["trial"]);
        }
    }
}

const BROAD: [&str; 5] =
    ["broad-05-slow-rotation", "broad-14-slow-translation", "broad-18-fast-translation", "broad-27-vibration", "broad-33-magnet-2cm"];

/// The five BROAD trials: the delay named on every one, consistent, added;
/// the leave-one-out residual lower on every named axis. Prints the tables
/// docs/gap.md shows (`cargo test --release --test gap_reference broad -- --nocapture`).
#[test]
fn broad_trials_of_one_unit() {
    let Some(dir) = realdata_dir() else {
        println!("skipped: ../shared/realdata not found (set GYROCOMP_REALDATA to the folder of recordings)");
        return;
    };
    if let Some(n) = BROAD.iter().find(|n| !dir.join(n).is_dir()) {
        println!("skipped: {} not found", dir.join(n).display());
        return;
    }
    let d = tempfile::tempdir().unwrap();
    std::fs::write(d.path().join("base.toml"), "[gyro]\neffects = [\"turn_on_bias\"]\n").unwrap();
    let mut c = Command::new(bin());
    c.arg("gap").arg("--measured");
    BROAD.iter().for_each(|n| {
        c.arg(dir.join(n).join("imu.csv.gz"));
    });
    c.arg("--reference");
    BROAD.iter().for_each(|n| {
        c.arg(dir.join(n).join("reference.csv.gz"));
    });
    let out = d.path().join("out");
    let o = c.arg("--model").arg(d.path().join("base.toml")).arg("--out").arg(&out).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    println!("{}", String::from_utf8_lossy(&o.stdout));
    let j: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("trials.json")).unwrap()).unwrap();
    let rows = j["effects"].as_array().unwrap();
    let delay = rows.iter().find(|r| r["term"] == "time_delay").expect("the delay is named");
    assert_eq!(delay["named_on"], 5);
    for r in rows.iter().filter(|r| r["added"] == true) {
        assert_eq!(r["consistent"], true, "an added term is consistent: {r}");
    }
    for h in j["leave_one_out"].as_array().unwrap() {
        for a in h["axes"].as_array().unwrap() {
            let k = ["x", "y", "z"].iter().position(|x| *x == a).unwrap();
            let (b, e) = (h["rms_base"][k].as_f64().unwrap(), h["rms_extended"][k].as_f64().unwrap());
            assert!(e < b, "{}: axis {a}: {b} -> {e}", h["trial"]);
        }
    }
}

/// `--static`: a still unit logged in two bursts 600 s apart, one row
/// logged twice: two stretches of one power cycle, the repeated row kept
/// once, the turn-on bias given with its interval, nothing else named.
#[test]
fn a_still_unit_in_two_bursts() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    let bias = [4.5, -0.2, 1.1];
    let mut rng = 12345u64;
    let mut noise = || {
        // a deterministic uniform generator; the sum of 12 is about normal
        (0..12)
            .map(|_| {
                rng = rng.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                (rng >> 11) as f64 / (1u64 << 53) as f64
            })
            .sum::<f64>()
            - 6.0
    };
    let mut csv = String::from("t,gx,gy,gz,ax,ay,az,mx,my,mz,temp\n");
    for burst in [0.0, 600.0] {
        for k in 0..2000 {
            let t = burst + 10.0 + k as f64 * 0.01;
            let g: Vec<f64> = bias.iter().map(|b| b + 0.1 * noise()).collect();
            let row = format!("{t:.4},{},{},{},0.01,-0.02,-1.0,,,,{:.2}\n", g[0], g[1], g[2], 30.0 + burst / 600.0);
            csv += &row;
            if k == 700 {
                csv += &row;
            }
        }
    }
    std::fs::write(p.join("imu.csv"), csv).unwrap();
    std::fs::write(p.join("base.toml"), "[gyro]\neffects = [\"turn_on_bias\"]\n").unwrap();
    let o = gap(
        &[Path::new("--measured"), &p.join("imu.csv"), Path::new("--static"), Path::new("--model"), &p.join("base.toml")],
        &p.join("out"),
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    println!("{}", String::from_utf8_lossy(&o.stdout));
    let r = report(&p.join("out"));
    assert_eq!(r["truth_from"]["stretches"].as_array().unwrap().len(), 2);
    assert_eq!(r["samples"], 4000, "the repeated row is kept once");
    assert!(r["findings"].as_array().unwrap().is_empty(), "{}", r["findings"]);
    for (a, b) in bias.iter().enumerate() {
        let c = &r["base_coefficients"][a];
        let (v, se) = (c["coefficient"].as_f64().unwrap(), c["std_error"].as_f64().unwrap());
        assert!((v - b).abs() < 4.0 * se, "turn-on bias {a}: {v} +- {se}");
    }
}

/// The static thermal recordings (`../shared/static-thermal`; skipped,
/// saying so, without it): on the MPU6050 runs `gap --static` names nothing
/// but what the base model fits (the turn-on bias); at most a linear slope.
#[test]
fn static_thermal_recordings_claim_no_more_than_they_carry() {
    let Some(dir) = realdata_dir().map(|d| d.join("../static-thermal")).filter(|d| d.is_dir()) else {
        println!("skipped: ../shared/static-thermal not found");
        return;
    };
    let d = tempfile::tempdir().unwrap();
    std::fs::write(d.path().join("base.toml"), "[gyro]\neffects = [\"turn_on_bias\"]\n").unwrap();
    for name in ["mpu6050-static-10min", "mpu6050-static-x-forward", "mpu6050-static-z-front-x-up", "mpu6050-static-z-front-y-down"] {
        let imu = dir.join(name).join("imu.csv.gz");
        if !imu.is_file() {
            println!("skipped {name}: not found");
            continue;
        }
        let out = d.path().join(name);
        let o = gap(&[Path::new("--measured"), &imu, Path::new("--static"), Path::new("--model"), &d.path().join("base.toml")], &out);
        assert!(o.status.success(), "{name}: {}", String::from_utf8_lossy(&o.stderr));
        println!("{name}:\n{}", String::from_utf8_lossy(&o.stdout));
        let r = report(&out);
        for f in r["findings"].as_array().unwrap() {
            assert_eq!(f["effect"], "thermal_linear", "{name}: a static recording of 0.5 degC carries no {}", f["effect"]);
        }
    }
}

/// Bad input: refused with what and where, nothing written.
#[test]
fn bad_reference_input_is_refused_with_its_place() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    write_trial(&p.join("a"), 31);
    std::fs::write(p.join("base.toml"), BASE).unwrap();
    let (imu, refa, base) = (p.join("a/imu.csv"), p.join("a/reference.csv"), p.join("base.toml"));
    let text = std::fs::read_to_string(&refa).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    lines[5] = format!("{},0.1,1e300,3.0,1,1", lines[5].split(',').next().unwrap());
    std::fs::write(p.join("bad.csv"), lines.join("\n")).unwrap();
    let (bad, nope) = (p.join("bad.csv"), p.join("nope.csv"));
    let cases: Vec<(Vec<&std::ffi::OsStr>, &str)> = vec![
        (vec!["--reference".as_ref(), bad.as_os_str()], "line 6, column pitch"),
        (vec!["--reference".as_ref(), refa.as_os_str(), refa.as_os_str()], "--reference: 2 file(s) for 1"),
        (vec!["--reference".as_ref(), refa.as_os_str(), "--bandwidth".as_ref(), "0".as_ref()], "--bandwidth 0"),
        (vec!["--reference".as_ref(), refa.as_os_str(), "--static".as_ref()], "exactly one of"),
        (vec!["--reference".as_ref(), nope.as_os_str()], "nope.csv"),
    ];
    for (args, want) in cases {
        let out = p.join("out");
        let o = Command::new(bin())
            .arg("gap")
            .arg("--measured")
            .arg(&imu)
            .args(&args)
            .arg("--model")
            .arg(&base)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && e.contains(want), "{args:?}: want {want:?}: {e}");
        assert!(!out.exists(), "{args:?}: wrote {}", out.display());
    }
}
