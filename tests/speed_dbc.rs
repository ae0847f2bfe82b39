//! Speed from the car's bus described by its DBC (`src/speed.rs`): decoded
//! like python `cantools` decodes the same DBC, on the simulated urban bus and
//! on a real car's bus (comma2k19, Toyota RAV4, Motorola byte order); bad
//! input is a clear error or a counted drop, never a panic.

use gyrocomp::config::SpeedConfig;
use gyrocomp::sim::{read_truth, simulate, SimOptions};
use gyrocomp::speed::{SpeedCounts, SpeedDecoder, SpeedDrop, SpeedError};
use proptest::prelude::*;
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Counts this thread's heap allocations (tests run in parallel threads).
struct Counting;
thread_local! {
    static COUNT: Cell<u64> = const { Cell::new(0) };
}
fn allocs() -> u64 {
    COUNT.with(|c| c.get())
}
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        let _ = COUNT.try_with(|c| c.set(c.get() + 1));
        System.alloc(l)
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        System.dealloc(p, l)
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, n: usize) -> *mut u8 {
        let _ = COUNT.try_with(|c| c.set(c.get() + 1));
        System.realloc(p, l, n)
    }
}
#[global_allocator]
static A: Counting = Counting;

fn cfg(dbc: &Path, message: &str, signals: &[&str]) -> SpeedConfig {
    SpeedConfig {
        dbc: dbc.display().to_string(),
        message: message.into(),
        signals: signals.iter().map(|s| s.to_string()).collect(),
        scale: 1.0,
        timeout_s: 0.5,
    }
}

fn example_dbc() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("config/example-car.dbc")
}

fn hex(s: &str) -> Vec<u8> {
    (0..s.len() / 2).map(|i| u8::from_str_radix(&s[2 * i..2 * i + 2], 16).unwrap()).collect()
}

/// Run tests/speed_check.py; returns `(payload, cantools' verdict)` per frame.
fn cantools(dbc: &Path, log: &Path, message: &str, signals: &[&str]) -> Vec<(Vec<u8>, String)> {
    let root = env!("CARGO_MANIFEST_DIR");
    let out = Command::new("python3")
        .arg(format!("{root}/tests/speed_check.py"))
        .arg(dbc)
        .arg(log)
        .arg(message)
        .args(signals)
        .output()
        .expect("python3 must be installed (tests/run-all.sh installs it with cantools)");
    assert!(out.status.success(), "cantools check failed (pip install cantools?):\n{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| {
            let (h, v) = l.split_once(' ').unwrap();
            (hex(h), v.to_string())
        })
        .collect()
}

/// Compare every frame; returns the decoded speeds.
fn compare(dec: &SpeedDecoder, frames: &[(Vec<u8>, String)]) -> (Vec<f64>, SpeedCounts) {
    let mut n = SpeedCounts::default();
    let mut speeds = Vec::new();
    for (k, (p, want)) in frames.iter().enumerate() {
        let got = dec.decode(p);
        n.record(&got);
        match (got, want.as_str()) {
            (Ok(v), w) if w.parse::<f64>().is_ok() => {
                let w: f64 = w.parse().unwrap();
                assert!((v - w).abs() <= 1e-9 * (1.0 + w.abs()), "frame {k} {p:02X?}: gyrocomp {v} m/s, cantools {w}");
                speeds.push(v);
            }
            (Err(SpeedDrop::OutOfRange { .. }), "OUT_OF_RANGE") | (Err(SpeedDrop::WrongDlc { .. }), "WRONG_DLC") => {}
            (got, w) => panic!("frame {k} {p:02X?}: gyrocomp {got:?}, cantools {w}"),
        }
    }
    (speeds, n)
}

/// Every WHEEL_SPEEDS frame of a simulated urban log decodes as cantools
/// decodes it; and the speed is the rear-axle speed of the truth, `latency_s`
/// late and `1 + scale_error` too large, through stops and the reversing.
#[test]
fn simulated_urban_wheel_speeds_decode_like_cantools_and_carry_the_truth() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path().join("urban");
    let mut o = SimOptions::new("urban", 9);
    o.speed = true;
    let files = simulate(&o, &d).unwrap();
    let w = files.info.wheel_speeds.clone().unwrap();
    let c = gyrocomp::config::Config::load(&d.join("config.toml")).unwrap();
    let mut sc = c.speed.clone();
    sc.dbc = d.join(&c.speed.dbc).display().to_string();
    let dec = SpeedDecoder::from_config(&sc).unwrap();
    assert_eq!(dec.id(), (0x1A0, false));
    assert_eq!(dec.signals().collect::<Vec<_>>(), [("WHEEL_SPEED_RL", "km/h"), ("WHEEL_SPEED_RR", "km/h")]);
    let frames = cantools(&d.join("car.dbc"), &d.join("imu.log"), "WHEEL_SPEEDS", &["WHEEL_SPEED_RL", "WHEEL_SPEED_RR"]);
    assert_eq!(frames.len() as u64, files.wheel_frames);
    let (speeds, n) = compare(&dec, &frames);
    assert_eq!(n.dropped(), 0);
    let (lo, hi) = speeds.iter().fold((f64::MAX, f64::MIN), |(l, h), v| (l.min(*v), h.max(*v)));
    println!("{} frames, {lo:.2}..{hi:.2} m/s, latency {} s, scale error {}", speeds.len(), w.latency_s, w.scale_error);
    assert!(lo < -1.0 && hi > 12.0, "{lo}..{hi}: reversing and driving");
    assert!(speeds.iter().filter(|v| **v == 0.0).count() > 5 * 50 * 5, "stops read exactly 0");
    // against the truth (vehicle.csv: t,speed,...)
    let truth: Vec<(f64, f64)> = std::fs::read_to_string(d.join("vehicle.csv"))
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| {
            let mut it = l.split(',');
            (it.next().unwrap().parse().unwrap(), it.next().unwrap().parse().unwrap())
        })
        .collect();
    assert_eq!(truth.len(), read_truth(&d.join("truth.csv")).unwrap().len());
    let log = std::fs::read_to_string(d.join("imu.log")).unwrap();
    let t0 = gyrocomp::sim::LOG_EPOCH_S as f64;
    let times: Vec<f64> =
        log.lines().filter(|l| l.contains(" 1A0#")).map(|l| l[1..l.find(')').unwrap()].parse::<f64>().unwrap() - t0).collect();
    assert_eq!(times.len(), speeds.len());
    let rate = files.info.rate_hz;
    let mut worst = 0.0f64;
    for (tb, v) in times.iter().zip(&speeds) {
        let tc = tb - w.latency_s;
        let k = (tc * rate).floor() as usize;
        let a = (tc * rate) - k as f64;
        let vt = truth[k].1 + a * (truth[(k + 1).min(truth.len() - 1)].1 - truth[k].1);
        let want = vt * (1.0 + w.scale_error);
        if want.abs() > 0.2 {
            worst = worst.max((v - want).abs());
        }
    }
    println!("decoded vs (1 + scale error) x true rear-axle speed {} s earlier: worst {worst:.4} m/s", w.latency_s);
    // noise 0.03 km/h (1 sigma) per wheel, 0.01 km/h steps, 0.2 ms jitter
    assert!(worst < 0.05, "{worst} m/s");
}

/// The real bus: comma2k19's RAV4, WHEEL_SPEEDS (0xAA) in Motorola byte
/// order, unsigned with an offset, decoded like cantools decodes it.
#[test]
fn comma2k19_wheel_speeds_decode_like_cantools() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/realdata/comma2k19-rav4-60s");
    let (dbc, log) = (dir.join("toyota.dbc"), dir.join("can.log.gz"));
    if !dbc.exists() || !log.exists() {
        println!("skipped: {} or {} not found", dbc.display(), log.display());
        return;
    }
    for signals in
        [&["WHEEL_SPEED_RL", "WHEEL_SPEED_RR"][..], &["WHEEL_SPEED_FL", "WHEEL_SPEED_FR", "WHEEL_SPEED_RL", "WHEEL_SPEED_RR"][..]]
    {
        let dec = SpeedDecoder::from_config(&cfg(&dbc, "WHEEL_SPEEDS", signals)).unwrap();
        assert_eq!(dec.id(), (0xAA, false));
        let frames = cantools(&dbc, &log, "WHEEL_SPEEDS", signals);
        let (speeds, n) = compare(&dec, &frames);
        let (lo, hi) = speeds.iter().fold((f64::MAX, f64::MIN), |(l, h), v| (l.min(*v), h.max(*v)));
        println!(
            "comma2k19 {signals:?}: {} frames, {} decoded, {} out of range, speed {lo:.2}..{hi:.2} m/s",
            frames.len(),
            n.decoded,
            n.out_of_range
        );
        assert!(frames.len() > 4000, "{} frames", frames.len());
        assert!(n.decoded as usize > frames.len() * 9 / 10);
        assert!(lo > 0.0 && hi < 40.0, "a car driving on a public road: {lo}..{hi}");
    }
}

#[test]
fn bad_dbc_input_is_a_clear_error() {
    let t = tempfile::tempdir().unwrap();
    // missing file
    let missing = t.path().join("no-such.dbc");
    let e = SpeedDecoder::from_config(&cfg(&missing, "WHEEL_SPEEDS", &["WHEEL_SPEED_RL"])).unwrap_err();
    assert!(matches!(e, SpeedError::Read { .. }));
    assert!(e.to_string().contains("no-such.dbc"), "{e}");
    // not a DBC
    let bad = t.path().join("bad.dbc");
    std::fs::write(&bad, "BO_ 416 WHEEL_SPEEDS: 8 ABS\n SG_ WHEEL_SPEED_RL : 32|16@1- (0.01,0) [-60|300 \"km/h\" IMU\n").unwrap();
    let e = SpeedDecoder::from_config(&cfg(&bad, "WHEEL_SPEEDS", &["WHEEL_SPEED_RL"])).unwrap_err().to_string();
    assert!(e.contains("bad.dbc") && e.contains("not a valid DBC"), "{e}");
    std::fs::write(&bad, [0xFFu8, 0xFE, 0x00, 0x81]).unwrap();
    let e = SpeedDecoder::from_config(&cfg(&bad, "WHEEL_SPEEDS", &["WHEEL_SPEED_RL"])).unwrap_err().to_string();
    assert!(e.contains("bad.dbc"), "{e}");
    // missing message, missing signal, a unit that is not a speed
    let ex = example_dbc();
    let e = SpeedDecoder::from_config(&cfg(&ex, "WHEEL_SPEED", &["WHEEL_SPEED_RL"])).unwrap_err().to_string();
    assert!(e.contains("example-car.dbc") && e.contains("\"WHEEL_SPEED\"") && e.contains("WHEEL_SPEEDS"), "{e}");
    let e = SpeedDecoder::from_config(&cfg(&ex, "WHEEL_SPEEDS", &["WHEEL_SPEED_RL", "WHEEL_SPEED_RX"])).unwrap_err().to_string();
    assert!(e.contains("example-car.dbc") && e.contains("\"WHEEL_SPEED_RX\"") && e.contains("WHEEL_SPEED_RR"), "{e}");
    let text = std::fs::read_to_string(&ex).unwrap().replacen("\"km/h\"", "\"rpm\"", 1);
    let odd = t.path().join("odd.dbc");
    std::fs::write(&odd, text).unwrap();
    let e = SpeedDecoder::from_config(&cfg(&odd, "WHEEL_SPEEDS", &["WHEEL_SPEED_FL"])).unwrap_err().to_string();
    assert!(e.contains("odd.dbc") && e.contains("WHEEL_SPEEDS.WHEEL_SPEED_FL") && e.contains("\"rpm\""), "{e}");
    // a Windows-1252 DBC (a degree sign in a comment) loads
    let mut bytes = std::fs::read(&ex).unwrap();
    bytes.extend_from_slice(b"CM_ BO_ 416 \"at 20 \xB0C\";\n");
    let cp = t.path().join("cp1252.dbc");
    std::fs::write(&cp, bytes).unwrap();
    assert!(SpeedDecoder::from_config(&cfg(&cp, "WHEEL_SPEEDS", &["WHEEL_SPEED_RL"])).is_ok());
}

#[test]
fn bad_frames_are_counted_drops() {
    let dec = SpeedDecoder::from_config(&cfg(&example_dbc(), "WHEEL_SPEEDS", &["WHEEL_SPEED_RL", "WHEEL_SPEED_RR"])).unwrap();
    let mut p = [0u8; 8];
    p[4..6].copy_from_slice(&3600i16.to_le_bytes());
    p[6..8].copy_from_slice(&3400i16.to_le_bytes());
    assert!((dec.decode(&p).unwrap() - 35.0 / 3.6).abs() < 1e-12);
    assert_eq!(dec.decode(&p[..7]), Err(SpeedDrop::WrongDlc { got: 7, want: 8 }));
    assert_eq!(dec.decode(&[]), Err(SpeedDrop::WrongDlc { got: 0, want: 8 }));
    // -70 km/h is outside [-60|300]; 310 km/h too
    p[6..8].copy_from_slice(&(-7000i16).to_le_bytes());
    assert_eq!(dec.decode(&p), Err(SpeedDrop::OutOfRange { signal: 1 }));
    p[6..8].copy_from_slice(&31000i16.to_le_bytes());
    assert_eq!(dec.decode(&p), Err(SpeedDrop::OutOfRange { signal: 1 }));
    // in range but not a car's speed (a scale of 2 makes 300 km/h 167 m/s)
    let mut c = cfg(&example_dbc(), "WHEEL_SPEEDS", &["WHEEL_SPEED_RL", "WHEEL_SPEED_RR"]);
    c.scale = 2.0;
    let d2 = SpeedDecoder::from_config(&c).unwrap();
    p[4..6].copy_from_slice(&30000i16.to_le_bytes());
    p[6..8].copy_from_slice(&30000i16.to_le_bytes());
    assert_eq!(d2.decode(&p), Err(SpeedDrop::Implausible));
    assert_eq!(SpeedDrop::Implausible.name(), "implausible");
}

/// Decoding allocates nothing (Intel and Motorola, good frames and drops).
#[test]
fn decode_allocates_nothing() {
    let ours = SpeedDecoder::from_config(&cfg(&example_dbc(), "WHEEL_SPEEDS", &["WHEEL_SPEED_RL", "WHEEL_SPEED_RR"])).unwrap();
    let toyota = SpeedDecoder::from_dbc_text(
        "VERSION \"\"\n\nNS_ :\n\nBS_:\n\nBU_: X\n\nBO_ 170 WHEEL_SPEEDS: 8 X\n SG_ WHEEL_SPEED_RL : 55|16@0+ (0.01,-67.67) [0|250] \"km/h\" X\n",
        "toyota",
        &cfg(Path::new("toyota"), "WHEEL_SPEEDS", &["WHEEL_SPEED_RL"]),
    )
    .unwrap();
    let frames: Vec<[u8; 8]> = (0..1000u32).map(|k| (k.wrapping_mul(2654435761) as u64 * 0x9E3779B97F4A7C15).to_le_bytes()).collect();
    let mut n = SpeedCounts::default();
    let before = allocs();
    for f in &frames {
        n.record(&ours.decode(f));
        n.record(&toyota.decode(f));
        n.record(&ours.decode(&f[..5]));
    }
    let after = allocs();
    assert_eq!(after - before, 0, "{} allocations in {} decodes", after - before, 3 * frames.len());
    assert!(n.decoded > 0 && n.out_of_range > 0 && n.wrong_dlc == 1000, "{n:?}");
}

proptest! {
    /// Any payload of any length: a speed within the plausible range, or a drop.
    #[test]
    fn any_payload_decodes_or_drops(p in proptest::collection::vec(any::<u8>(), 0..16)) {
        let dec = SpeedDecoder::from_config(&cfg(&example_dbc(), "WHEEL_SPEEDS", &["WHEEL_SPEED_FL", "WHEEL_SPEED_RR"])).unwrap();
        match dec.decode(&p) {
            Ok(v) => prop_assert!(v.is_finite() && v.abs() <= 100.0 && p.len() == 8),
            Err(SpeedDrop::WrongDlc { got, want }) => prop_assert!(got == p.len() && want == 8 && got != 8),
            Err(_) => prop_assert_eq!(p.len(), 8),
        }
    }
}

/// Every prefix of the example DBC, and the DBC with any one line cut in two or
/// a number replaced by garbage: a decoder or a clear error, never a panic
/// (the DBC parser reads a file the user hands the daemon at start-up).
#[test]
fn a_damaged_dbc_is_an_error_never_a_panic() {
    let text = std::fs::read_to_string(example_dbc()).unwrap();
    let c = cfg(Path::new("car.dbc"), "WHEEL_SPEEDS", &["WHEEL_SPEED_RL", "WHEEL_SPEED_RR"]);
    let mut texts: Vec<String> = (0..=text.len()).filter(|&n| text.is_char_boundary(n)).map(|n| text[..n].to_string()).collect();
    let lines: Vec<&str> = text.lines().collect();
    for (k, l) in lines.iter().enumerate() {
        for bad in ["", "|", "99999999999999999999999", "-", "\"", "@"] {
            let mut v = lines.clone();
            let half = &l[..l.len() / 2];
            let cut = format!("{half}{bad}");
            v[k] = &cut;
            texts.push(v.join("\n"));
        }
    }
    let (mut ok, mut refused) = (0, 0);
    for t in &texts {
        match std::panic::catch_unwind(|| SpeedDecoder::from_dbc_text(t, "car.dbc", &c)) {
            Ok(Ok(dec)) => {
                ok += 1;
                // whatever it accepted decodes a frame or drops it
                let _ = dec.decode(&[0x12; 8]);
            }
            Ok(Err(e)) => {
                refused += 1;
                assert!(!e.to_string().is_empty());
            }
            Err(_) => panic!("the DBC decoder panicked on:\n{t}"),
        }
    }
    println!("damaged DBCs: {} accepted, {} refused", ok, refused);
    assert!(ok >= 1 && refused >= 1, "{ok} accepted, {refused} refused");
}
