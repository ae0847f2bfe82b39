//! The DBC and the encoder cannot drift apart: frames gyrocomp wrote are
//! decoded by python `cantools` from `config/gyrocomp.dbc` and compared with
//! the estimate CSV of the same replay, and `EST_AID` with the aid word of
//! each estimate the library returns for the same log.

mod common;
use gyrocomp::config::Config;
use gyrocomp::estimator::mekf::Aid;
use gyrocomp::output::AID_CODES;
use gyrocomp::replay::{replay_files, ReplayFiles};
use std::path::Path;
use std::process::Command;

/// `gyrocomp replay` of `input` (with `config`, else the defaults) to a log
/// and a CSV; the library's estimates of the same log as `aid.csv`; then
/// `tests/dbc_check.py` on them. Returns its output.
fn cantools_check(dir: &Path, input: &Path, config: Option<&Path>) -> String {
    let out = dir.join("out.log");
    let csv = dir.join("est.csv");
    let mut c = Command::new(common::bin());
    c.arg("replay");
    if let Some(p) = config {
        c.arg("--config").arg(p);
    }
    let o = c.arg("--input").arg(input).arg("--output").arg(&out).arg("--csv").arg(&csv).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    // what the library says of each estimate's aid sources, by name
    let cfg = config.map_or_else(Config::default, |p| Config::load(p).unwrap());
    let mut est = Vec::new();
    replay_files(&cfg, &ReplayFiles { input, output: None, csv: None, mcap: None }, Some(&mut est)).unwrap();
    let mut aid = String::from("cnt");
    for a in Aid::ALL {
        aid += &format!(",{}", a.name());
    }
    aid += ",worst_ratio\n";
    for e in &est {
        aid += &e.cnt.to_string();
        for a in Aid::ALL {
            aid += &format!(",{}", AID_CODES[e.aid.code(a) as usize]);
        }
        aid += &format!(",{}\n", e.aid.worst_ratio);
    }
    let aid_csv = dir.join("aid.csv");
    std::fs::write(&aid_csv, aid).unwrap();

    let root = env!("CARGO_MANIFEST_DIR");
    let py = Command::new("python3")
        .arg(format!("{root}/tests/dbc_check.py"))
        .arg(format!("{root}/config/gyrocomp.dbc"))
        .arg(&out)
        .arg(&csv)
        .arg(&aid_csv)
        .output()
        .expect("python3 must be installed (tests/run-all.sh installs it with cantools)");
    let so = String::from_utf8_lossy(&py.stdout).to_string();
    let se = String::from_utf8_lossy(&py.stderr);
    assert!(py.status.success(), "cantools check failed (pip install cantools?):\n{so}\n{se}");
    print!("{so}");
    so
}

/// "EST_AID: N frames, source statuses not_applicable A, fused F, refused R" -> (A, F, R).
fn statuses(so: &str) -> (u64, u64, u64) {
    let line = so.lines().find(|l| l.starts_with("EST_AID: ")).unwrap_or_else(|| panic!("no EST_AID line in {so}"));
    let n = |k: &str| -> u64 {
        let at = line.find(&format!("{k} ")).unwrap_or_else(|| panic!("no {k} in {line}")) + k.len() + 1;
        line[at..].split(|c: char| !c.is_ascii_digit()).next().unwrap().parse().unwrap()
    };
    (n("not_applicable"), n("fused"), n("refused"))
}

#[test]
fn cantools_decodes_replay_output_like_the_csv() {
    let d = tempfile::tempdir().unwrap();
    let input = d.path().join("in.log");
    // moving + learning: non-trivial rates, angles, biases, every mode flag path
    std::fs::write(&input, common::gentle_log(204 * 20, [0.31, -0.27, 0.4], 1_000_000_000)).unwrap();
    let so = cantools_check(d.path(), &input, None);
    assert!(so.contains("4080 samples"), "{so}");
    let (na, fused, refused) = statuses(&so);
    assert_eq!(na + fused + refused, 4080 * Aid::ALL.len() as u64, "{so}");
    assert!(fused > 0, "{so}");
}

/// A simulated city drive that starts parked, with the magnetometer: its
/// EST_AID frames, decoded by cantools, say at every sample what the
/// library's estimates say, codes 1 and 2 included (the zero-rate and still
/// gravity updates are refused at a few ticks of the stop).
#[test]
fn cantools_decodes_est_aid_of_a_drive_like_the_library() {
    let d = tempfile::tempdir().unwrap();
    let sim = d.path().join("sim");
    let o = Command::new(common::bin())
        .args(["simulate", "--scenario", "urban", "--seed", "1", "--duration", "60", "--out"])
        .arg(&sim)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let so = cantools_check(d.path(), &sim.join("imu.log"), Some(&sim.join("config.toml")));
    let (na, fused, refused) = statuses(&so);
    let samples = std::fs::read_to_string(d.path().join("est.csv")).unwrap().lines().count() as u64 - 1;
    assert!(samples > 12_000, "{so}");
    assert_eq!(na + fused + refused, samples * Aid::ALL.len() as u64, "{so}");
    assert!(fused > samples && refused > 0, "{so}");
}
