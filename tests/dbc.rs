//! The DBC and the encoder cannot drift apart: frames gyrocomp wrote are
//! decoded by python `cantools` from `config/gyrocomp.dbc` and compared with
//! the estimate CSV of the same replay.

mod common;
use std::process::Command;

#[test]
fn cantools_decodes_replay_output_like_the_csv() {
    let d = tempfile::tempdir().unwrap();
    let input = d.path().join("in.log");
    // moving + learning: non-trivial rates, angles, biases, every mode flag path
    std::fs::write(&input, common::gentle_log(204 * 20, [0.31, -0.27, 0.4], 1_000_000_000)).unwrap();
    let out = d.path().join("out.log");
    let csv = d.path().join("est.csv");
    let o = Command::new(common::bin())
        .args(["replay", "--input"])
        .arg(&input)
        .arg("--output")
        .arg(&out)
        .arg("--csv")
        .arg(&csv)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let root = env!("CARGO_MANIFEST_DIR");
    let py = Command::new("python3")
        .arg(format!("{root}/tests/dbc_check.py"))
        .arg(format!("{root}/config/gyrocomp.dbc"))
        .arg(&out)
        .arg(&csv)
        .output()
        .expect("python3 must be installed (tests/run-all.sh installs it with cantools)");
    let so = String::from_utf8_lossy(&py.stdout);
    let se = String::from_utf8_lossy(&py.stderr);
    assert!(py.status.success(), "cantools check failed (pip install cantools?):\n{so}\n{se}");
    assert!(so.contains("4080 samples"), "{so}");
}
