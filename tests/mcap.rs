//! `gyrocomp replay --mcap` as a user runs it on the README's bundled log, the
//! recording read back by the python `mcap` reader and Foxglove's CDR decoder (tests/mcap_check.py):
//! channels, schemas, one message per sample (one per input frame on
//! /can/rx), monotonic times, unit quaternions, the aid sources by name; the
//! same bytes twice; the other outputs the same bytes with or without it; bad
//! paths refused.

mod common;
use std::path::Path;
use std::process::{Command, Output};

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

fn replay(args: &[&std::ffi::OsStr]) -> Output {
    let mut c = Command::new(common::bin());
    c.arg("replay")
        .arg("--config")
        .arg(format!("{ROOT}/config/gyrocomp.toml"))
        .arg("--input")
        .arg(format!("{ROOT}/tests/data/road-40s.log"));
    c.args(args);
    c.output().unwrap()
}

/// The number after `key ` in replay's summary.
fn count(summary: &str, key: &str) -> u64 {
    let at = summary.find(&format!("{key} ")).unwrap_or_else(|| panic!("no {key} in {summary}"));
    summary[at + key.len() + 1..].split(|c: char| !c.is_ascii_digit()).next().unwrap().parse().unwrap()
}

/// Whether python3 with the `mcap` and `mcap_ros2` (Foxglove's CDR decoder) modules is here. Absent: fails under CI
/// (tests/run-all.sh installs it), says so and skips elsewhere.
fn python_mcap() -> bool {
    let ok = Command::new("python3").args(["-c", "import mcap, mcap_ros2.decoder"]).output().map(|o| o.status.success()).unwrap_or(false);
    if !ok {
        assert!(
            std::env::var_os("CI").is_none(),
            "python3 with the mcap and mcap_ros2 modules is required under CI (tests/run-all.sh installs them: pip install mcap mcap-ros2-support)"
        );
        eprintln!(
            "skipped: python3 or its mcap / mcap_ros2 modules not found (pip install mcap mcap-ros2-support, or run tests/run-all.sh)"
        );
    }
    ok
}

#[test]
fn replay_mcap_reads_back_in_python_and_is_deterministic() {
    let d = tempfile::tempdir().unwrap();
    let (m1, m2) = (d.path().join("a.mcap"), d.path().join("b.mcap"));
    let o = replay(&["--mcap".as_ref(), m1.as_os_str()]);
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(o.status.success(), "{err}");
    let samples = count(&err, "samples");
    let frames = count(&err, "frames");
    assert!(samples > 8000 && frames >= 4 * samples, "{err}");
    let o = replay(&["--mcap".as_ref(), m2.as_os_str()]);
    assert!(o.status.success());
    let a = std::fs::read(&m1).unwrap();
    assert!(a.starts_with(b"\x89MCAP0\r\n") && a.ends_with(b"\x89MCAP0\r\n"), "not an MCAP");
    assert!(a == std::fs::read(&m2).unwrap(), "two runs wrote different MCAP bytes");
    // only the MCAP in the directory: the temporary file was renamed
    assert_eq!(std::fs::read_dir(d.path()).unwrap().count(), 2);

    if !python_mcap() {
        return;
    }
    let py = Command::new("python3")
        .arg(format!("{ROOT}/tests/mcap_check.py"))
        .arg(&m1)
        .arg(samples.to_string())
        .arg(frames.to_string())
        .output()
        .unwrap();
    let so = String::from_utf8_lossy(&py.stdout);
    assert!(py.status.success(), "{so}{}", String::from_utf8_lossy(&py.stderr));
    assert!(so.contains(&format!("mcap ok: 3 channels, {samples} samples, {frames} CAN frames")), "{so}");
    // the default filter's aid sources by name: some fused at most estimates
    let fused: u64 = so.split("an aid source fused at ").nth(1).and_then(|r| r.split(',').next()).and_then(|n| n.parse().ok()).unwrap_or(0);
    assert!(fused > samples / 2, "{so}");
}

#[test]
fn the_other_outputs_are_the_same_bytes_with_or_without_mcap() {
    let d = tempfile::tempdir().unwrap();
    let p = |n: &str| d.path().join(n);
    let (o1, c1, o2, c2, m) = (p("o1.log"), p("c1.csv"), p("o2.log"), p("c2.csv"), p("m.mcap"));
    let a = replay(&["--output".as_ref(), o1.as_os_str(), "--csv".as_ref(), c1.as_os_str()]);
    let b = replay(&["--output".as_ref(), o2.as_os_str(), "--csv".as_ref(), c2.as_os_str(), "--mcap".as_ref(), m.as_os_str()]);
    assert!(a.status.success() && b.status.success(), "{}", String::from_utf8_lossy(&b.stderr));
    assert_eq!(a.stderr, b.stderr, "the summary changed");
    assert!(std::fs::read(&o1).unwrap() == std::fs::read(&o2).unwrap(), "--output differs with --mcap");
    assert!(std::fs::read(&c1).unwrap() == std::fs::read(&c2).unwrap(), "--csv differs with --mcap");
    assert!(m.exists());
}

#[test]
fn a_bad_mcap_path_is_refused_by_name() {
    let d = tempfile::tempdir().unwrap();
    let csv = d.path().join("est.csv");
    let check = |mcap: &Path, want: &str| {
        let o = replay(&["--csv".as_ref(), csv.as_os_str(), "--mcap".as_ref(), mcap.as_os_str()]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{err}");
        assert!(err.contains(&format!("gyrocomp: error: cannot write {}: {want}", mcap.display())), "{err}");
        assert!(!err.contains("panicked"), "{err}");
        assert!(!csv.exists(), "the CSV was committed although the run was refused");
    };
    check(d.path(), "is a directory");
    let missing = d.path().join("no/such/out.mcap");
    check(&missing, &format!("its directory {} does not exist", d.path().join("no/such").display()));
    // the input as the MCAP: refused before anything is written
    let input = Path::new(ROOT).join("tests/data/road-40s.log");
    let o = replay(&["--mcap".as_ref(), input.as_os_str()]);
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("road-40s.log"));
}

#[test]
fn evaluate_mcap_has_the_truth_and_vqf_beside_the_estimate() {
    let d = tempfile::tempdir().unwrap();
    let sim = d.path().join("sim");
    let o = Command::new(common::bin())
        .args(["simulate", "--scenario", "paper", "--seed", "2", "--duration", "30", "--out"])
        .arg(&sim)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let m = d.path().join("eval.mcap");
    let eval = || Command::new(common::bin()).args(["evaluate", "--peers", "--input"]).arg(&sim).arg("--mcap").arg(&m).output().unwrap();
    let o = eval();
    let so = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{so}{}", String::from_utf8_lossy(&o.stderr));
    assert!(so.contains(&format!("wrote {}", m.display())), "{so}");
    let a = std::fs::read(&m).unwrap();
    assert!(eval().status.success());
    assert!(a == std::fs::read(&m).unwrap(), "two evaluations wrote different MCAP bytes");
    // with --seeds there is no one run to record: refused by clap
    let o = Command::new(common::bin()).args(["evaluate", "--seeds", "1", "--scenario", "static", "--mcap"]).arg(&m).output().unwrap();
    assert!(!o.status.success());
    // --peers with --input DIR means something only for the recording
    let o = Command::new(common::bin()).args(["evaluate", "--peers", "--input"]).arg(&sim).output().unwrap();
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("--peers"));

    if !python_mcap() {
        return;
    }
    let samples = std::fs::read_to_string(sim.join("truth.csv")).unwrap().lines().count() - 1;
    let frames = std::fs::read_to_string(sim.join("imu.log")).unwrap().lines().filter(|l| !l.is_empty()).count();
    let py = Command::new("python3")
        .arg(format!("{ROOT}/tests/mcap_check.py"))
        .arg(&m)
        .arg(samples.to_string())
        .arg(frames.to_string())
        .args([
            "/truth/tf=tf2_msgs/msg/TFMessage",
            "/truth/estimate=gyrocomp.Attitude",
            "/vqf/tf=tf2_msgs/msg/TFMessage",
            "/vqf/estimate=gyrocomp.Attitude",
        ])
        .output()
        .unwrap();
    let so = String::from_utf8_lossy(&py.stdout);
    assert!(py.status.success(), "{so}{}", String::from_utf8_lossy(&py.stderr));
    assert!(so.contains(&format!("mcap ok: 7 channels, {samples} samples")), "{so}");
}
