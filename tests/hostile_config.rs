//! Hostile configs (issue 38) as a user meets them: `gyrocomp check-config`
//! and `gyrocomp replay` refuse each with exit code 1 (an error, not a
//! panic's 101 or an abort's 134) naming the key, and a refused replay
//! writes nothing. Before, each of these passed check-config and then broke
//! replay: an allocation of 32 GB, NaN published with exit 0, values of an
//! array silently dropped, a speed source that reads nothing.

mod common;
use common::bin;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const ROAD: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/road-40s.log");

/// Each hostile config and the key its refusal must name.
const HOSTILE: [(&str, &str); 14] = [
    ("[input]\nrate_hz = 1e9\n", "input.rate_hz"),
    ("[input]\nrate_hz = 1e-300\n", "input.rate_hz"),
    ("[switching]\njerk_window_s = 1e12\n", "switching.jerk_window_s"),
    ("[switching]\njerk_window_s = 1e6\n", "switching.jerk_window_s"),
    ("[input]\ngyro_lsb = 1e300\n", "input.gyro_lsb"),
    ("[thermal]\np1 = [1e300, 0.0, 0.0]\n", "thermal.p1[0]"),
    ("[thermal]\np2 = [0.0, 1e300, 0.0]\n", "thermal.p2[1]"),
    (
        "[estimator]\nmode = \"paper\"\n[ekf]\ngyro_noise = 1e-300\nbias_walk = 1e-300\ntilt_sigma_deg = 1e-300\n\
         yaw_sigma_deg = 1e-300\ninit_bias_sigma = 1e-300\ninit_angle_sigma_deg = 1e-300\n",
        "ekf.gyro_noise",
    ),
    ("[mounting]\nrotation = [0, 0, 0, 45]\n", "mounting.rotation"),
    ("[thermal]\np1 = [0.0, 0.0, 0.0, 0.01]\n", "thermal.p1"),
    ("[switching]\ninner = [0.985, 1.0, 1.015]\n", "switching.inner"),
    ("[mounting]\nlever_arm = [0.0, 0.0, 0.0, 1.0]\n", "mounting.lever_arm"),
    ("[speed]\nsignals = [\"WHEEL_SPEED_RL\", \"WHEEL_SPEED_RR\"]\n", "speed.signals"),
    ("[speed]\ndbc = \"long.dbc\"\nmessage = \"LONG\"\nsignals = [\"S\"]\n", "speed.dbc"),
];

/// A DBC whose speed message claims 99 bytes.
const LONG_DBC: &str = "VERSION \"\"\n\nNS_ :\n\nBS_:\n\nBU_: X\n\nBO_ 1200 LONG: 99 X\n SG_ S : 0|16@1+ (0.01,0) [0|0] \"km/h\" X\n";

fn gyrocomp(args: &[&str]) -> Output {
    Command::new(bin()).args(args).output().unwrap()
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// `toml` written as `name.toml` in `dir` (beside the long DBC).
fn config(dir: &Path, name: &str, toml: &str) -> PathBuf {
    std::fs::write(dir.join("long.dbc"), LONG_DBC).unwrap();
    let p = dir.join(format!("{name}.toml"));
    std::fs::write(&p, toml).unwrap();
    p
}

/// Exit code 1 and the key named in stderr.
fn assert_refused(o: &Output, key: &str, what: &str) {
    let err = text(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{what}: exit {:?}, want 1 (refused, not crashed)\n{err}", o.status);
    assert!(err.contains(key), "{what}: {key} not named:\n{err}");
    assert!(!err.contains("panicked"), "{what}: {err}");
}

#[test]
fn check_config_refuses_each_hostile_config_naming_the_key() {
    let d = tempfile::tempdir().unwrap();
    for (k, (toml, key)) in HOSTILE.iter().enumerate() {
        let p = config(d.path(), &format!("h{k}"), toml);
        let o = gyrocomp(&["check-config", p.to_str().unwrap()]);
        assert_refused(&o, key, toml);
        assert!(o.stdout.is_empty(), "{toml}: printed an effective config:\n{}", text(&o.stdout));
    }
    // the line too, and the length wanted
    let p = config(d.path(), "rot", "[mounting]\nrotation = [0, 0, 0, 45]\n");
    let err = text(&gyrocomp(&["check-config", p.to_str().unwrap()]).stderr);
    assert!(err.contains("line 2") && err.contains("expected an array of 3 numbers") && err.contains("got 4"), "{err}");
    let p = config(d.path(), "dbc", HOSTILE[13].0);
    let err = text(&gyrocomp(&["check-config", p.to_str().unwrap()]).stderr);
    assert!(err.contains("long.dbc") && err.contains("LONG") && err.contains("99 bytes"), "{err}");
}

#[test]
fn replay_refuses_a_hostile_config_and_writes_nothing() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("out");
    std::fs::create_dir(&out).unwrap();
    for (k, (toml, key)) in HOSTILE.iter().enumerate() {
        let p = config(d.path(), &format!("h{k}"), toml);
        let o = gyrocomp(&[
            "replay",
            "--config",
            p.to_str().unwrap(),
            "--input",
            ROAD,
            "--output",
            out.join("out.log").to_str().unwrap(),
            "--csv",
            out.join("est.csv").to_str().unwrap(),
        ]);
        assert_refused(&o, key, toml);
        let left: Vec<_> = std::fs::read_dir(&out).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert!(left.is_empty(), "{toml}: left {left:?} in the output directory");
    }
}

/// The lower edges of the sigmas are sound: paper mode with every `[ekf]`
/// sigma at its smallest, and the default filter with its sigmas at theirs,
/// replay the road recording with no NaN or infinity in the estimates
/// (1e-300 gave NaN on every row but the first).
#[test]
fn replay_at_the_lowest_sigmas_publishes_finite_estimates() {
    let d = tempfile::tempdir().unwrap();
    for (name, toml) in [
        (
            "paper",
            "[estimator]\nmode = \"paper\"\n[ekf]\ngyro_noise = 1e-6\nbias_walk = 0.0\ntilt_sigma_deg = 1e-4\n\
             yaw_sigma_deg = 1e-4\ninit_bias_sigma = 1e-4\ninit_angle_sigma_deg = 1e-3\n",
        ),
        (
            "mekf",
            "[mekf]\nrest_tilt_sigma_deg = 1e-4\naccel_noise = 1e-5\nnhc_sigma = 1e-4\naccel_noise_quiet = 1e-6\n\
             free_velocity_sigma = 1e-3\ntilt_sigma_deg = 1e-4\nzupt_sigma = 1e-5\nzru_sigma_dps = 1e-6\nspeed_sigma = 1e-4\n\
             init_speed_sigma = 1e-3\nspeed_bound_sigma = 0.01\n[ekf]\ninit_bias_sigma = 1e-4\ninit_angle_sigma_deg = 1e-3\n",
        ),
    ] {
        let p = config(d.path(), name, toml);
        let csv = d.path().join(format!("{name}.csv"));
        let o = gyrocomp(&["replay", "--config", p.to_str().unwrap(), "--input", ROAD, "--csv", csv.to_str().unwrap()]);
        assert!(o.status.success(), "{name}: {}", text(&o.stderr));
        let est = std::fs::read_to_string(&csv).unwrap();
        let rows = est.lines().count();
        assert!(rows > 8000, "{name}: {rows} rows");
        let bad = est.lines().skip(1).filter(|l| l.split(',').any(|v| v.contains("NaN") || v.contains("inf"))).count();
        assert_eq!(bad, 0, "{name}: {bad} of {rows} rows not finite");
    }
}
