//! `scripts/fetch-realdata --from DIR` on a BROAD trial that
//! `tests/broad_fixture.py` writes in the dataset's own hdf5 layout (known
//! rotations, rests, a second without optical reference): the folder layout,
//! units and axes, valid and rest flags (checked by the fixture), byte-identical
//! output on two runs, checksums refused on mismatch, and
//! `gyrocomp evaluate --realdata` scoring the result. No network.
//!
//! Needs python3 with h5py and numpy (tests/run-all.sh installs them); without
//! them the test says `skipped` and passes, except under CI, where it fails.

mod common;
use common::bin;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const TRIAL: &str = "broad-90-test-rotations-b";

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn h5py_available() -> bool {
    let ok = Command::new("python3").args(["-c", "import h5py, numpy"]).output().map(|o| o.status.success()).unwrap_or(false);
    if !ok {
        assert!(std::env::var_os("CI").is_none(), "python3 with h5py and numpy is missing under CI (tests/run-all.sh installs them)");
        eprintln!("skipped: python3 h5py/numpy not installed (python3 -m pip install h5py numpy, or bash tests/run-all.sh)");
    }
    ok
}

fn run(cmd: &mut Command) -> Output {
    cmd.output().expect("spawn")
}

fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

fn fetch(from: &Path, out: &Path, sums: &Path) -> Output {
    run(Command::new("bash")
        .arg(repo().join("scripts/fetch-realdata"))
        .arg("--from")
        .arg(from)
        .arg("--out")
        .arg(out)
        .env("GYROCOMP_REALDATA_SUMS", sums))
}

fn sha256(p: &Path) -> String {
    let o = run(Command::new("sha256sum").arg(p));
    assert!(o.status.success());
    String::from_utf8_lossy(&o.stdout).split_whitespace().next().unwrap().to_string()
}

#[test]
fn broad_hdf5_converts_checks_and_scores() {
    if !h5py_available() {
        return;
    }
    let d = tempfile::tempdir().unwrap();
    let hdf = d.path().join("hdf5");
    let o = run(Command::new("python3").arg(repo().join("tests/broad_fixture.py")).arg("make").arg(&hdf));
    assert!(o.status.success(), "fixture: {}", text(&o));
    let file = hdf.join("90_test_rotations_B.hdf5");
    let sums = d.path().join("sums");
    std::fs::write(&sums, "# none recorded\n").unwrap();

    // converted, with no checksum recorded: said so, and the sums file is not touched
    let (a, b) = (d.path().join("a"), d.path().join("b"));
    let o = fetch(&hdf, &a, &sums);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("NOT CHECKED"), "{}", text(&o));
    assert_eq!(std::fs::read_to_string(&sums).unwrap(), "# none recorded\n");

    // layout, units, axes, valid and rest flags
    let folder = a.join(TRIAL);
    let o = run(Command::new("python3").arg(repo().join("tests/broad_fixture.py")).arg("check").arg(&folder));
    assert!(o.status.success(), "conversion checks:\n{}", text(&o));
    let info = std::fs::read_to_string(folder.join("info.json")).unwrap();
    assert!(info.contains(&sha256(&file)), "info.json has no sha256 of its input:\n{info}");

    // a recorded checksum that matches: converted, byte-identical to the first run
    std::fs::write(&sums, format!("{}  90_test_rotations_B.hdf5\n", sha256(&file))).unwrap();
    let o = fetch(&hdf, &b, &sums);
    assert!(o.status.success() && text(&o).contains("checksum OK"), "{}", text(&o));
    let mut names: Vec<_> = std::fs::read_dir(&folder).unwrap().map(|e| e.unwrap().file_name()).collect();
    names.sort();
    assert_eq!(names, ["ATTRIBUTION.md", "imu.csv.gz", "info.json", "reference.csv.gz"]);
    for n in &names {
        assert!(
            std::fs::read(folder.join(n)).unwrap() == std::fs::read(b.join(TRIAL).join(n)).unwrap(),
            "{n:?} differs between two conversions"
        );
    }

    // a mismatch is refused, nothing written
    std::fs::write(&sums, format!("{}  90_test_rotations_B.hdf5\n", "0".repeat(64))).unwrap();
    let c = d.path().join("c");
    let o = fetch(&hdf, &c, &sums);
    assert!(!o.status.success() && text(&o).contains("refused"), "{}", text(&o));
    assert!(!c.join(TRIAL).exists());

    // gyrocomp scores it: one row for ours, one for VQF; the axes agree with
    // the reference (a sign or axis mistake would be degrees, not hundredths)
    let o = run(Command::new(bin()).arg("evaluate").arg("--realdata").arg(&a));
    let out = text(&o);
    assert!(o.status.success(), "{out}");
    let row = out.lines().find(|l| l.starts_with(TRIAL)).unwrap_or_else(|| panic!("no row for {TRIAL}:\n{out}"));
    let cols: Vec<&str> = row.split_whitespace().collect();
    assert_eq!(cols[1], "ours", "{row}");
    let tilt_rms: f64 = cols[7].parse().unwrap();
    assert!(tilt_rms < 0.2, "tilt RMS {tilt_rms} deg on a trial without noise:\n{out}");
    assert!(out.lines().any(|l| l.split_whitespace().next() == Some("vqf")), "{out}");
}
