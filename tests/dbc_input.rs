//! `[input] format = "dbc"` against an independent decoder: python
//! `cantools` encodes frames from the shipped DBCs (and one of odd layouts:
//! Motorola, a negative factor, a sign-magnitude pair, a 32-byte CAN FD
//! message), computes the channels from its own decoding and the config's
//! mapping, and gyrocomp's decoding of the same log must give the same
//! numbers; the Toyota KINEMATICS message is checked the same way on the
//! real comma2k19 recording. `check-config` prints the mapping and refuses
//! what cannot run.

mod common;
use gyrocomp::adis::{InputCounters, Push, RawFrame, Sample};
use gyrocomp::candump::parse_line;
use gyrocomp::config::Config;
use gyrocomp::dbcin::{DbcAssembler, DbcPlan};
use std::path::Path;
use std::process::Command;
use std::sync::Arc;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// Every sample gyrocomp assembles from a candump log with `plan`.
fn decode(plan: Arc<DbcPlan>, log: &str) -> (Vec<Sample>, InputCounters) {
    let mut a = DbcAssembler::new(plan);
    let mut out = Vec::new();
    for line in log.lines() {
        let f = parse_line(line.as_bytes()).unwrap_or_else(|e| panic!("{line}: {e}"));
        let raw = RawFrame { id: f.id, extended: f.extended, remote: f.remote, fd: f.fd, data: f.payload() };
        if let Push::Sample(s) = a.push(f.t_us, raw) {
            out.push(s);
        }
    }
    (out, a.counters)
}

fn python(args: &[&str]) -> String {
    let o = Command::new("python3").args(args).output().expect("python3 must be installed (tests/run-all.sh installs cantools)");
    let (so, se) = (String::from_utf8_lossy(&o.stdout).to_string(), String::from_utf8_lossy(&o.stderr));
    assert!(o.status.success(), "python failed (pip install cantools?):\n{so}\n{se}");
    so
}

/// cantools encodes `n` samples for `config`; gyrocomp decodes them; every channel compared.
fn cross_check(config: &Path, n: usize) {
    let d = tempfile::tempdir().unwrap();
    let (log, csv) = (d.path().join("in.log"), d.path().join("want.csv"));
    let so = python(&[
        &format!("{ROOT}/tests/dbc_input_check.py"),
        config.to_str().unwrap(),
        &n.to_string(),
        "41",
        log.to_str().unwrap(),
        csv.to_str().unwrap(),
    ]);
    print!("{so}");
    let cfg = Config::load(config).unwrap_or_else(|e| panic!("{e}"));
    let (got, counters) = decode(cfg.input.plan.0.clone().expect("a plan"), &std::fs::read_to_string(&log).unwrap());
    let want = std::fs::read_to_string(&csv).unwrap();
    let mut rows: Vec<&str> = want.lines().skip(1).collect();
    let corrupted: u64 = rows.pop().and_then(|l| l.strip_prefix("# corrupted ")).unwrap().parse().unwrap();
    assert_eq!(got.len(), rows.len(), "samples delivered; counters {counters:?}");
    assert_eq!(counters.checksum, corrupted, "{counters:?}");
    assert!(rows.len() > n * 9 / 10, "{}", rows.len());
    let mut suspects = 0;
    for (k, (s, row)) in got.iter().zip(&rows).enumerate() {
        let v: Vec<&str> = row.split(',').collect();
        let chans = [s.gyro[0], s.gyro[1], s.gyro[2], s.accel[0], s.accel[1], s.accel[2], s.temp];
        for (c, (x, w)) in chans.iter().zip(&v[..7]).enumerate() {
            if w.is_empty() {
                continue;
            }
            let w: f64 = w.parse().unwrap();
            assert!((x - w).abs() <= 1e-9 * w.abs().max(1.0), "sample {k} channel {c}: gyrocomp {x}, cantools {w}");
        }
        assert_eq!(s.suspect(), v[7] == "1", "sample {k}: {s:?} vs {row}");
        suspects += s.suspect() as usize;
    }
    // the log holds every kind of sample the check is about
    assert!(suspects > 0 || cfg.input.valid.is_empty(), "no suspect sample drawn");
}

#[test]
fn cantools_encodes_the_mm7p10_frames_gyrocomp_decodes() {
    cross_check(&Path::new(ROOT).join("config/mm7p10.toml"), 2000);
}

#[test]
fn cantools_encodes_the_j1939_frames_gyrocomp_decodes() {
    cross_check(&Path::new(ROOT).join("config/j1939-imu.toml"), 2000);
}

/// Motorola, a negative factor, a sign-magnitude pair, rad/s and m/s^2, CAN FD.
const ODD_DBC: &str = r#"VERSION ""

NS_ :

BS_:

BU_: X

BO_ 257 ESP_02: 8 X
 SG_ ESP_Gierrate : 40|14@1+ (0.01,0) [0|163.83] "deg/s" X
 SG_ ESP_VZ_Gierrate : 54|1@1+ (1,0) [0|1] "" X
 SG_ HondaYaw : 7|16@0- (-0.1,0) [-3276.8|3276.7] "deg/s" X
 SG_ Cnt : 59|4@1+ (1,0) [0|15] "" X

BO_ 2147484000 IMU_FD: 32 X
 SG_ AX : 64|16@1- (0.001,0) [0|0] "m/s^2" X
 SG_ AY : 87|16@0- (0.001,0.5) [0|0] "m/s^2" X
 SG_ AZ : 96|16@1- (-0.001,0) [0|0] "m/s^2" X
 SG_ Temp : 200|12@1+ (0.1,200) [0|0] "K" X
 SG_ Cnt : 248|4@1+ (1,0) [0|15] "" X
"#;

const ODD_TOML: &str = r#"[input]
format = "dbc"
dbc = "odd.dbc"
rate_hz = 50.0
[input.signals]
gyro_x = "-ESP_02.HondaYaw"
gyro_y = "ESP_02.HondaYaw"
gyro_z = { signal = "ESP_02.ESP_Gierrate", sign_bit = "ESP_02.ESP_VZ_Gierrate" }
accel_x = "IMU_FD.AX"
accel_y = "-IMU_FD.AY"
accel_z = "IMU_FD.AZ"
temp = "IMU_FD.Temp"
[input.sample]
counter = ["ESP_02.Cnt", "IMU_FD.Cnt"]
"#;

#[test]
fn cantools_encodes_odd_layouts_gyrocomp_decodes() {
    let d = tempfile::tempdir().unwrap();
    std::fs::write(d.path().join("odd.dbc"), ODD_DBC).unwrap();
    std::fs::write(d.path().join("odd.toml"), ODD_TOML).unwrap();
    cross_check(&d.path().join("odd.toml"), 1000);
}

/// The car's own sensor on a real recording: gyrocomp with the shipped
/// config/toyota-kinematics.{toml,dbc} against cantools with the
/// recording's own toyota.dbc (opendbc's), frame by frame.
#[test]
fn toyota_kinematics_on_the_comma2k19_recording_decodes_as_cantools() {
    let dir = Path::new(ROOT).join("../shared/realdata/comma2k19-rav4-60s");
    if !dir.join("can.log.gz").exists() || !dir.join("toyota.dbc").exists() {
        eprintln!("SKIPPED: {} (can.log.gz, toyota.dbc) is not there; it is the comma2k19 RAV4 recording", dir.display());
        return;
    }
    let mut text = String::new();
    use std::io::Read;
    flate2::read::GzDecoder::new(std::fs::File::open(dir.join("can.log.gz")).unwrap()).read_to_string(&mut text).unwrap();
    // the KINEMATICS plan, reduced axes and all
    let toml = std::fs::read_to_string(Path::new(ROOT).join("config/toyota-kinematics.toml")).unwrap();
    let dbc = std::fs::read_to_string(Path::new(ROOT).join("config/toyota-kinematics.dbc")).unwrap();
    let cfg = Config::parse(&toml, "toyota-kinematics.toml").unwrap();
    let plan = DbcPlan::build(&cfg.input, &dbc, "toyota-kinematics.dbc", 25.0).unwrap();
    assert_eq!(plan.missing_motion(), ["gyro_x", "gyro_y", "accel_z"]);
    let (got, counters) = decode(Arc::new(plan), &text);
    let py = r##"
import gzip, sys, cantools
db = cantools.database.load_file(sys.argv[1] + "/toyota.dbc", strict=False)
m = db.get_message_by_name("KINEMATICS")
for line in gzip.open(sys.argv[1] + "/can.log.gz", "rt"):
    ident, data = line.split()[2].split("#")
    if int(ident, 16) == m.frame_id:
        v = m.decode(bytes.fromhex(data), decode_choices=False)
        print(repr(v["YAW_RATE"]), repr(v["ACCEL_X"]), repr(v["ACCEL_Y"]))
"##;
    let want = python(&["-c", py, dir.to_str().unwrap()]);
    let want: Vec<Vec<f64>> = want.lines().map(|l| l.split(' ').map(|x| x.parse().unwrap()).collect()).collect();
    assert_eq!(got.len(), want.len(), "{counters:?}");
    assert!(want.len() > 4000, "{}", want.len());
    for (k, (s, w)) in got.iter().zip(&want).enumerate() {
        // gyro_z = -YAW_RATE (deg/s); accel in g from m/s^2
        let g0 = gyrocomp::dbcin::G0;
        assert!((s.gyro[2] + w[0]).abs() < 1e-9, "frame {k}: {} vs {}", s.gyro[2], w[0]);
        assert!((s.accel[0] - w[1] / g0).abs() < 1e-9 && (s.accel[1] - w[2] / g0).abs() < 1e-9, "frame {k}: {s:?} vs {w:?}");
        assert_eq!((s.gyro[0], s.gyro[1], s.accel[2]), (0.0, 0.0, 0.0));
    }
    // every other frame of the bus is counted, none taken
    assert_eq!(counters.samples as usize, want.len());
    assert!(counters.unknown_id > 40_000, "{counters:?}");
}

fn check_config(path: &Path) -> (bool, String, String) {
    let o = Command::new(common::bin()).arg("check-config").arg(path).output().unwrap();
    (o.status.success(), String::from_utf8_lossy(&o.stdout).to_string(), String::from_utf8_lossy(&o.stderr).to_string())
}

#[test]
fn check_config_prints_the_mapping_and_refuses_what_cannot_run() {
    let (ok, out, err) = check_config(&Path::new(ROOT).join("config/mm7p10.toml"));
    assert!(ok, "{err}");
    for want in [
        "#   gyro_y = -TX3.PitchRate: bit 0 size 16 Intel unsigned, factor 0.005 offset -163.84 \"deg/s\"",
        "-> -0.005 deg/s per LSB, offset 163.84 deg/s",
        "#   sample: the 3 messages with equal 4-bit counters",
        "#   message TX1 id 0x174, 8 bytes, CRC-8 SAE J1850 in byte 7 checked",
        "format = \"dbc\"\n",
    ] {
        assert!(out.contains(want), "{want} missing:\n{out}");
    }
    // the printed config is itself a valid config, wherever it is saved
    let d = tempfile::tempdir().unwrap();
    std::fs::write(d.path().join("printed.toml"), &out).unwrap();
    let (ok, again, err) = check_config(&d.path().join("printed.toml"));
    assert!(ok && again == out, "{err}\n{again}");
    // reduced axes: accepted, the mapping printed and what is not estimated said
    let toyota = Path::new(ROOT).join("config/toyota-kinematics.toml");
    let (ok, out, err) = check_config(&toyota);
    assert!(ok, "{err}");
    for want in
        ["#   gyro_z = -KINEMATICS.YAW_RATE: bit 1 size 10 Motorola", "# reduced axes (gyro_x, gyro_y, accel_z not mapped)", "roll, pitch"]
    {
        assert!(out.contains(want), "{want} missing:\n{out}");
    }
    // without the yaw rate or a horizontal axis, or without EST_AID: refused, saying why
    let base = std::fs::read_to_string(&toyota)
        .unwrap()
        .replace("dbc = \"toyota-kinematics.dbc\"", &format!("dbc = \"{ROOT}/config/toyota-kinematics.dbc\""));
    for (edit, key, want) in [
        (base.replace("accel_y = \"KINEMATICS.ACCEL_Y\"\n", ""), "input.signals", "accel_y not mapped: a unit without all six axes needs"),
        (base.replace("gyro_z = \"-KINEMATICS.YAW_RATE\"", "gyro_x = \"-KINEMATICS.YAW_RATE\""), "input.signals", "gyro_z not mapped"),
        (format!("{base}[output]\naid_frame = false\n"), "output.aid_frame", "needs aid_frame = true"),
    ] {
        std::fs::write(d.path().join("reduced.toml"), edit).unwrap();
        let (ok, _, err) = check_config(&d.path().join("reduced.toml"));
        assert!(!ok && err.contains(want) && err.contains(key) && err.contains("reduced.toml"), "{want}: {err}");
    }
    // a signal the DBC lacks: the key, its line, the config and the DBC named
    let text = std::fs::read_to_string(Path::new(ROOT).join("config/mm7p10.toml")).unwrap().replace("TX2.AX\"", "TX2.AXX\"");
    std::fs::write(d.path().join("bad.toml"), text.replace("dbc = \"mm7p10.dbc\"", &format!("dbc = \"{ROOT}/config/mm7p10.dbc\"")))
        .unwrap();
    let (ok, _, err) = check_config(&d.path().join("bad.toml"));
    assert!(!ok && err.contains("bad.toml") && err.contains("input.signals.accel_x") && err.contains("line 12"), "{err}");
    assert!(err.contains("mm7p10.dbc: message TX2 has no signal named \"AXX\""), "{err}");
    // a DBC that is not there
    std::fs::write(d.path().join("nodbc.toml"), "[input]\nformat = \"dbc\"\ndbc = \"none.dbc\"\nrate_hz = 100.0\n[input.signals]\ngyro_z = \"A.B\"\n[input.sample]\nwindow_ms = 2.0\n").unwrap();
    let (ok, _, err) = check_config(&d.path().join("nodbc.toml"));
    assert!(!ok && err.contains("input.dbc") && err.contains("none.dbc") && err.contains("cannot read the DBC"), "{err}");
    // DBC keys with the ADIS format
    std::fs::write(d.path().join("adis.toml"), "[input]\ndbc = \"x.dbc\"\n").unwrap();
    let (ok, _, err) = check_config(&d.path().join("adis.toml"));
    assert!(!ok && err.contains("line 2, column 1: input.dbc") && err.contains("set format = \"dbc\""), "{err}");
}
