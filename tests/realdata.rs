//! The real-data table: every recording under `../shared/realdata` (or
//! `$GYROCOMP_REALDATA`) through `gyrocomp import` and `gyrocomp evaluate
//! --reference`, ours and VQF. Prints the table whatever ours shows; asserts
//! that it is complete and that VQF, run on the very same samples, has not
//! diverged. Skipped, saying so, where the recordings are not there.
//!
//! `cargo test --release --test realdata -- --nocapture` shows the table.

mod common;
use common::bin;
use std::path::PathBuf;
use std::process::Command;

fn realdata_dir() -> Option<PathBuf> {
    let d = match std::env::var_os("GYROCOMP_REALDATA") {
        Some(d) => PathBuf::from(d),
        None => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/realdata"),
    };
    d.is_dir().then_some(d)
}

#[test]
fn realdata_table_ours_and_vqf() {
    let Some(dir) = realdata_dir() else {
        println!("skipped: ../shared/realdata not found (set GYROCOMP_REALDATA to the folder of recordings)");
        return;
    };
    let folders: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.join("imu.csv.gz").is_file() && p.join("reference.csv.gz").is_file())
        .map(|p| p.file_name().unwrap().to_string_lossy().to_string())
        .collect();
    assert!(!folders.is_empty(), "{}: no recording folder", dir.display());
    let out = tempfile::tempdir().unwrap();
    let o = Command::new(bin())
        .args(["evaluate", "--realdata", dir.to_str().unwrap(), "--peers", "--out", out.path().to_str().unwrap()])
        .output()
        .unwrap();
    let table = String::from_utf8_lossy(&o.stdout);
    println!("$ gyrocomp evaluate --realdata {} --peers\n{table}", dir.display());
    eprint!("{}", String::from_utf8_lossy(&o.stderr));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // The table: one ours row and one vqf row per recording.
    for f in &folders {
        let at = table.lines().position(|l| l.starts_with(&format!("{f} "))).unwrap_or_else(|| panic!("{f} missing from the table"));
        let ours: Vec<&str> = table.lines().nth(at).unwrap().split_whitespace().collect();
        let vqf: Vec<&str> = table.lines().nth(at + 1).unwrap().split_whitespace().collect();
        assert_eq!((ours[1], vqf[0]), ("ours", "vqf"), "{f}");
    }
    let rows: Vec<serde_json::Value> = serde_json::from_str(&std::fs::read_to_string(out.path().join("realdata.json")).unwrap()).unwrap();
    assert_eq!(rows.len(), folders.len());
    for r in &rows {
        let name = r["recording"].as_str().unwrap();
        for who in ["ours", "vqf"] {
            let s = &r[who];
            for k in ["roll", "pitch"] {
                for m in ["max", "rms"] {
                    assert!(s[k][m].as_f64().is_some_and(f64::is_finite), "{name} {who}: {k}.{m} missing: {s}");
                }
            }
            assert!(s["tilt_rms"].as_f64().is_some_and(f64::is_finite), "{name} {who}: tilt_rms");
            assert!(s["scored_s"].as_f64().unwrap() > 30.0, "{name} {who}: under 30 s scored");
            // every recording here has a magnetometer: yaw is scored
            assert!(s["yaw_rms"].as_f64().is_some(), "{name} {who}: yaw not scored");
        }
        // VQF has not diverged: a lost vertical is tens of degrees. Where the
        // mount came from a window that looks like rest, VQF is within the
        // couple of degrees it is published at on such recordings.
        let v = &r["vqf"];
        let (rr, pr, tr) = (v["roll"]["rms"].as_f64().unwrap(), v["pitch"]["rms"].as_f64().unwrap(), v["tilt_rms"].as_f64().unwrap());
        assert!(rr < 15.0 && pr < 15.0 && v["tilt_max"].as_f64().unwrap() < 45.0, "{name}: VQF diverged: {v}");
        if r["alignment"]["looks_at_rest"].as_bool() == Some(true) {
            assert!(tr < 2.0, "{name}: VQF tilt RMS {tr} deg");
        }
    }
}
