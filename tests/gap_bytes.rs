//! `gap`'s from-bytes readers (what the Python package's `gyrocomp.gap`
//! reads bytes with): the same rows as the path readers, gzip recognised,
//! errors that name what they were given; and the in-memory workflow
//! ([`gyrocomp::gap::inputs::analyse`]) on bytes gives the report that
//! `gyrocomp gap --out DIR` writes to `report.json`.

use gyrocomp::adis::builtin_profile;
use gyrocomp::gap::inputs::{analyse, Source, TruthSource};
use gyrocomp::gap::{measured_from_bytes, parse_base, read_measured, read_truth, truth_from_bytes, MeasRow};
use gyrocomp::reference::refcsv::{read_reference, reference_from_bytes};
use std::io::Write;
use std::path::Path;
use std::process::Command;

const LOG: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/road-40s.log");

fn gz(bytes: &[u8]) -> Vec<u8> {
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    e.write_all(bytes).unwrap();
    e.finish().unwrap()
}

fn bits(v: &[MeasRow]) -> Vec<[u64; 8]> {
    v.iter()
        .map(|r| {
            let g = r.gyro.map(f64::to_bits);
            let a = r.acc.map(f64::to_bits);
            [r.t.to_bits(), g[0], g[1], g[2], a[0], a[1], a[2], r.temp.to_bits()]
        })
        .collect()
}

#[test]
fn measured_from_bytes_is_the_path_reader() {
    let p = builtin_profile("adis16448").unwrap();
    let bytes = std::fs::read(LOG).unwrap();
    let from_path = read_measured(Path::new(LOG), &p).unwrap();
    assert!(from_path.len() > 1000);
    assert_eq!(bits(&measured_from_bytes(&bytes, "x", &p).unwrap()), bits(&from_path));
    assert_eq!(bits(&measured_from_bytes(&gz(&bytes), "x.gz", &p).unwrap()), bits(&from_path));
    let csv = "t,gx,gy,gz,ax,ay,az,mx,my,mz,temp\n0,1,2,3,0,0,-1,,,,25\n0.01,1,2,3,0,0,-1,,,,25\n";
    let d = tempfile::tempdir().unwrap();
    std::fs::write(d.path().join("m.csv"), csv).unwrap();
    let from_file = read_measured(&d.path().join("m.csv"), &p).unwrap();
    assert_eq!(bits(&measured_from_bytes(csv.as_bytes(), "m", &p).unwrap()), bits(&from_file));
}

#[test]
fn truth_and_reference_from_bytes_are_the_path_readers() {
    let d = tempfile::tempdir().unwrap();
    let truth = "t,roll,pitch,yaw,p,q,r,fx,fy,fz,temp\n0,0,0,0,0.1,0.2,0.3,0,0,-1,25\n0.01,0,0,0,0.1,0.2,0.3,0,0,-1,25.5\n";
    std::fs::write(d.path().join("truth.csv"), truth).unwrap();
    let (a, ta) = read_truth(&d.path().join("truth.csv")).unwrap();
    let (b, tb) = truth_from_bytes(truth.as_bytes(), "t").unwrap();
    assert_eq!((ta, a.len()), (tb, b.len()));
    assert!(a.iter().zip(&b).all(|(x, y)| x.t == y.t && x.rate == y.rate && x.f == y.f && x.temp == y.temp));
    let refcsv = "t,roll,pitch,yaw,valid,rest\n0,1,2,3,1,1\n0.1,1,2,,0,0\n0.2,1.5,2,3,1,0\n";
    std::fs::write(d.path().join("ref.csv.gz"), gz(refcsv.as_bytes())).unwrap();
    let r = read_reference(&d.path().join("ref.csv.gz")).unwrap();
    assert_eq!(r.rows, reference_from_bytes(refcsv.as_bytes(), "r").unwrap().rows);
    assert_eq!(r.rows, reference_from_bytes(&gz(refcsv.as_bytes()), "r").unwrap().rows);
    assert_eq!(r.rows.len(), 3);
}

#[test]
fn bad_bytes_are_refused_naming_what_and_where() {
    let p = builtin_profile("adis16448").unwrap();
    let csv = "t,gx,gy,gz,ax,ay,az,mx,my,mz,temp\n0,1,2,3,0,0,-1,,,,25\n0.01,1,x,3,0,0,-1,,,,25\n";
    assert_eq!(measured_from_bytes(csv.as_bytes(), "measured", &p).unwrap_err(), "measured:3: column gy: bad number \"x\"");
    assert_eq!(measured_from_bytes(b"", "measured", &p).unwrap_err(), "measured: empty file");
    let e = measured_from_bytes(b"garbage\nmore garbage\n", "measured", &p).unwrap_err();
    assert!(e.starts_with("measured:1: "), "{e}");
    let e = truth_from_bytes(b"t,p,q,r\n", "truth").unwrap_err();
    assert!(e.starts_with("truth:1: header must be"), "{e}");
    let e = truth_from_bytes(b"t,roll\xff", "truth").unwrap_err();
    assert!(e.starts_with("truth: cannot read: not UTF-8 text: line 1"), "{e}");
    let e = reference_from_bytes(b"t,roll,pitch,yaw\n0,1,200,3\n", "ref").unwrap_err();
    assert!(e.contains("ref line 2, column pitch"), "{e}");
}

#[test]
fn the_workflow_on_bytes_gives_report_json() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    std::fs::write(p.join("hidden.toml"), "[gyro]\neffects = [\"turn_on_bias\", \"scale_factor\"]\n[gyro.turn_on_bias]\nbias = [0.1, -0.2, 0.05]\n[gyro.scale_factor]\nk = [0.0, 0.0, 0.005]\n").unwrap();
    let base = "[gyro]\neffects = [\"turn_on_bias\"]\n";
    std::fs::write(p.join("base.toml"), base).unwrap();
    let exe = || Command::new(env!("CARGO_BIN_EXE_gyrocomp"));
    let o = exe()
        .args(["simulate", "--scenario", "vehicle", "--seed", "5", "--duration", "300", "--model"])
        .arg(p.join("hidden.toml"))
        .arg("--out")
        .arg(p.join("sim"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (log, truth) = (p.join("sim/imu.log"), p.join("sim/truth.csv"));
    let mut gap = exe();
    gap.arg("gap").arg("--measured").arg(&log).arg("--truth").arg(&truth).arg("--model").arg(p.join("base.toml"));
    let o = gap.arg("--out").arg(p.join("gap")).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let written: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(p.join("gap/report.json")).unwrap()).unwrap();
    let bytes = |f: &Path, name: &str| Source::Bytes { name: name.into(), bytes: std::fs::read(f).unwrap() };
    let inputs = [(bytes(&log, "log"), TruthSource::Simulated(bytes(&truth, "truth")))];
    let a = analyse(&inputs, &parse_base(base).unwrap(), &builtin_profile("adis16448").unwrap()).unwrap();
    assert!(a.joint.is_none() && a.trials.len() == 1);
    let r = &a.trials[0].result;
    assert_eq!(serde_json::to_value(&r.report).unwrap(), written);
    assert_eq!(r.model.to_toml(), std::fs::read_to_string(p.join("gap/model.toml")).unwrap());
    assert_eq!(written["findings"][0]["term"], "scale_factor z");
}
