//! The daemon on a real vcan bus (host vcan where the kernel has one, a QEMU
//! VM with a Debian kernel otherwise: tests/vm/run.sh picks).
//!
//! - live equals replay: a log played with canplayer; what the daemon
//!   publishes (candump) carries exactly the payloads `gyrocomp replay` writes;
//! - faults: garbage, wrong DLC, checksum errors, DIAG_STAT, counter gaps, a
//!   10x burst, a silent bus, the interface going down and up;
//! - 2 kHz for 60 s with zero lost samples.

mod common;
use gyrocomp::adis::{builtin_profile, InputIds, RawSample};
use gyrocomp::candump::{parse_line, write_line};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Mutex;

/// One VM at a time: two TCG guests on two cores starve each other.
static VM: Mutex<()> = Mutex::new(());

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Run a guest script; returns (success, console text).
fn vm(script: &str, adds: &[(&Path, &str)], collects: &[(&str, &Path)], timeout: u32) -> (bool, String) {
    let _g = VM.lock().unwrap_or_else(|e| e.into_inner());
    let d = tempfile::tempdir().unwrap();
    let sp = d.path().join("test.sh");
    std::fs::write(&sp, script).unwrap();
    let mut c = Command::new("bash");
    c.arg(root().join("tests/vm/run.sh")).arg("--timeout").arg(timeout.to_string()).arg("--script").arg(&sp);
    c.arg("--add").arg(format!("{}:/work/bin/gyrocomp", common::bin().display()));
    for (h, g) in adds {
        c.arg("--add").arg(format!("{}:{g}", h.display()));
    }
    for (g, h) in collects {
        c.arg("--collect").arg(format!("{g}:{}", h.display()));
    }
    let o = c.output().expect("bash tests/vm/run.sh");
    let text = format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    (o.status.success(), text)
}

/// (id, payload) of every frame of a candump log, in order.
fn frames(p: &Path) -> Vec<(u32, Vec<u8>)> {
    let t = std::fs::read_to_string(p).unwrap();
    t.lines()
        .filter(|l| !l.is_empty())
        .map(|l| {
            let f = parse_line(l.as_bytes()).unwrap_or_else(|e| panic!("{}: {e}: {l}", p.display()));
            (f.id, f.payload().to_vec())
        })
        .collect()
}

fn replay(cfg: &Path, input: &Path, out: &Path) -> String {
    let o = Command::new(common::bin())
        .arg("replay")
        .arg("--config")
        .arg(cfg)
        .arg("--input")
        .arg(input)
        .arg("--output")
        .arg(out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(o.status.success(), "{err}");
    err
}

const WAIT_READY: &str = r#"
i=0; until grep -q "bus open" daemon.err 2>/dev/null; do sleep 0.1; i=$((i+1)); [ $i -gt 300 ] && { echo "daemon never opened the bus"; cat daemon.err; exit 1; }; done
"#;

/// A shell function: `capture OUT IN` records the daemon's output frames
/// (0x110..0x114: the mask passes 0x110..0x117) to OUT while IN is played
/// onto the bus.
const CAPTURE: &str = r#"
capture() {
  candump -r 8388608 -L vcan0,110:7F8 > "$1" &
  C=$!
  sleep 0.5
  canplayer -I "$2" vcan0=vcan0
  sleep 0.5
  kill $C
}
"#;

const STOP: &str = r#"
kill -TERM $D
i=0; while kill -0 $D 2>/dev/null; do sleep 0.1; i=$((i+1)); [ $i -gt 10 ] && { echo "daemon did not stop within 1 s of SIGTERM"; exit 1; }; done
wait $D; echo "daemon exit $?"
"#;

fn status_flags(data: &[u8]) -> u16 {
    u16::from_le_bytes([data[0], data[1]]) >> 2
}

/// A sample log with faults; returns its candump text.
fn fault_log(cnt0: u16) -> Vec<u8> {
    let p = builtin_profile("adis16448").unwrap();
    let ids = InputIds::DEFAULT.all();
    let mut out = Vec::new();
    let mut t_us: u64 = 1_700_000_000_000_000;
    let mut cnt: u16 = cnt0;
    let period = (1e6 / p.rate_hz) as u64;
    let sample = |out: &mut Vec<u8>, t_us: u64, cnt: u16, diag: u16, corrupt: bool| {
        let k = cnt as f64 / p.rate_hz;
        let mut r = RawSample::quantise(&p, [0.2 + (0.5 * k).sin(), -0.1, 0.3], [0.0, 0.0, -1.0], [0.2, 0.0, 0.4], 30.0);
        r.cnt = cnt;
        r.diag = diag;
        let mut f = r.encode();
        if corrupt {
            f[0][1] ^= 0x10;
        }
        for i in 0..4 {
            write_line(out, t_us + 40 * i as u64, b"vcan0", ids[i], &f[i]);
        }
    };
    // 3 s clean
    for _ in 0..614 {
        sample(&mut out, t_us, cnt, 0, false);
        t_us += period;
        cnt = cnt.wrapping_add(1);
    }
    // garbage: wrong DLC on input IDs, unknown IDs (the kernel filter drops those)
    for i in 0..5 {
        write_line(&mut out, t_us + i * 10, b"vcan0", 0x101, &[1, 2, 3, 4, 5]);
        write_line(&mut out, t_us + i * 10 + 5, b"vcan0", 0x555, &[0xAA; 8]);
    }
    t_us += period;
    // 3 checksum errors, 10 DIAG_STAT samples
    for k in 0..13 {
        sample(&mut out, t_us, cnt, if k >= 3 { 0x0040 } else { 0 }, k < 3);
        t_us += period;
        cnt = cnt.wrapping_add(1);
    }
    // a counter gap of 50 samples (lost), then a 10x burst of 200 samples
    cnt = cnt.wrapping_add(50);
    t_us += 50 * period;
    for _ in 0..200 {
        sample(&mut out, t_us, cnt, 0, false);
        t_us += period / 10;
        cnt = cnt.wrapping_add(1);
    }
    // silence: 2 s without frames, then 2 s clean
    t_us += 2_000_000;
    for _ in 0..410 {
        sample(&mut out, t_us, cnt, 0, false);
        t_us += period;
        cnt = cnt.wrapping_add(1);
    }
    out
}

#[test]
fn live_equals_replay_and_faults_are_survived() {
    let d = tempfile::tempdir().unwrap();
    let cfg = d.path().join("live.toml");
    std::fs::write(
        &cfg,
        "[can]\ninterface = \"vcan0\"\n[estimator]\nwarmup_s = 1.0\nlearn_s = 3.0\n[daemon]\nsilent_after_s = 0.5\nerror_frames = true\n",
    )
    .unwrap();
    // part 1: a clean moving log; part 2: faults; part 3: after the link bounce
    let clean = d.path().join("clean.log");
    std::fs::write(&clean, common::gentle_log(204 * 6, [0.3, -0.2, 0.25], 1_700_000_000_000_000)).unwrap();
    let faults = d.path().join("faults.log");
    std::fs::write(&faults, fault_log(204 * 6)).unwrap();
    let after = d.path().join("after.log");
    // DATA_CNT continues where the fault log ended
    let after_cnt = (204 * 6 + 614 + 13 + 50 + 200 + 410) as u16;
    std::fs::write(&after, common::gentle_log_from(204 * 2, [0.0; 3], 1_800_000_000_000_000, after_cnt)).unwrap();
    let recreated = d.path().join("recreated.log");
    std::fs::write(&recreated, common::gentle_log_from(204 * 2, [0.0; 3], 1_900_000_000_000_000, after_cnt + 408)).unwrap();

    let script = format!(
        r#"
set -u
{CAPTURE}
gyrocomp run --config live.toml 2> daemon.err &
D=$!
{WAIT_READY}
capture live1.log clean.log
candump -r 8388608 -L vcan0,110:7F8 > live2.log &
C=$!
sleep 0.5
canplayer -I faults.log vcan0=vcan0
# three error frames (CAN_ERR_FLAG in the ID): counted, opted in by the config
cansend vcan0 20000004#0004000000000000
cansend vcan0 20000004#0010000000000000
cansend vcan0 20000040#0000000000000000
sleep 0.5
kill $C
# the interface goes down and comes back: the daemon reopens by itself
ip link set vcan0 down
sleep 1
ip link set vcan0 up
sleep 2.5
capture live3.log after.log
# the interface disappears and is created again: the old socket is dead, the
# daemon must reopen (with backoff) on the new one
ip link del vcan0
sleep 1
ip link add dev vcan0 type vcan
ip link set vcan0 up
sleep 3
capture live4.log recreated.log
{STOP}
cat daemon.err
"#
    );
    let l1 = d.path().join("live1.log");
    let l2 = d.path().join("live2.log");
    let l3 = d.path().join("live3.log");
    let l4 = d.path().join("live4.log");
    let err = d.path().join("daemon.err");
    let (ok, console) = vm(
        &script,
        &[
            (&cfg, "/work/live.toml"),
            (&clean, "/work/clean.log"),
            (&faults, "/work/faults.log"),
            (&after, "/work/after.log"),
            (&recreated, "/work/recreated.log"),
        ],
        &[
            ("/work/live4.log", &l4),
            ("/work/live1.log", &l1),
            ("/work/live2.log", &l2),
            ("/work/live3.log", &l3),
            ("/work/daemon.err", &err),
        ],
        600,
    );
    assert!(ok, "VM run failed:\n{console}");
    let daemon_err = std::fs::read_to_string(&err).unwrap();

    // Live equals replay on the clean log: the very same payloads, in order.
    let r1 = d.path().join("replay1.log");
    replay(&cfg, &clean, &r1);
    let is_silent = |f: &(u32, Vec<u8>)| f.0 == 0x113 && status_flags(&f.1) & gyrocomp::estimator::flags::BUS_SILENT != 0;
    // bus-silent status frames are the daemon's own addition (between canplayer runs)
    let live1: Vec<_> = frames(&l1).into_iter().filter(|f| !is_silent(f)).collect();
    let want1 = frames(&r1);
    assert_eq!(live1.len(), want1.len(), "frame count live vs replay\n{daemon_err}");
    assert!(live1 == want1, "live payloads differ from replay");

    // The fault log continues the same daemon: replay clean+faults as one log
    // and compare the part after the clean one; bus-silent status frames are
    // the daemon's own addition.
    let both = d.path().join("both.log");
    let mut b = std::fs::read(&clean).unwrap();
    b.extend(std::fs::read(&faults).unwrap());
    std::fs::write(&both, b).unwrap();
    let r2 = d.path().join("replay2.log");
    let summary = replay(&cfg, &both, &r2);
    let want2: Vec<_> = frames(&r2).split_off(want1.len());
    let live2 = frames(&l2);
    let (silent, live2): (Vec<_>, Vec<_>) = live2.into_iter().partition(is_silent);
    assert!(!silent.is_empty(), "no bus-silent status during the 2 s silence");
    assert_eq!(live2.len(), want2.len(), "fault log: frame count live vs replay\n{summary}\n{daemon_err}");
    assert!(live2 == want2, "fault log: live payloads differ from replay");
    // the counts the replay summary states are the ones injected
    for s in ["wrong_dlc 5", "checksum 3", "suspect 10", "lost 53 in 2 gaps"] {
        assert!(summary.contains(s), "{s} not in\n{summary}");
    }
    // ... and the daemon's last status frame carries them (ErrCnt, LostCnt)
    let last = &want2.iter().rev().find(|f| f.0 == 0x113).unwrap().1;
    assert_eq!((last[6], last[7]), (8, 53), "ErrCnt (5 wrong DLC + 3 checksum) / LostCnt in EST_STATUS");

    // After the link bounce, publishing resumed without a restart; writes
    // while it was down were dropped and counted, not waited on.
    let live3: Vec<_> = frames(&l3).into_iter().filter(|f| !is_silent(f)).collect();
    assert_eq!(live3.len(), 5 * 204 * 2, "frames after the link bounce\n{daemon_err}");
    // After the interface was deleted and created again: reopened, resumed.
    let live4: Vec<_> = frames(&l4).into_iter().filter(|f| !is_silent(f)).collect();
    assert_eq!(live4.len(), 5 * 204 * 2, "frames after the interface was recreated\n{daemon_err}");
    assert!(daemon_err.contains("reopening"), "{daemon_err}");
    assert!(daemon_err.matches("bus open").count() >= 2, "{daemon_err}");
    assert!(daemon_err.contains("bus silent"), "{daemon_err}");
    assert!(daemon_err.contains("input resumed"), "{daemon_err}");
    assert!(console.contains("daemon exit 0"), "{console}");
    assert!(daemon_err.contains("error_frames=3"), "{daemon_err}");
    assert!(daemon_err.contains("CAN error frame"), "{daemon_err}");
}

/// A car's bus: the IMU's frames and the wheel speeds (a simulated urban
/// drive, `[speed]` from the simulator's DBC) played together. The daemon
/// adds the speed ID to its kernel filters, decodes the speeds and publishes
/// what `gyrocomp replay` of the same log writes; the status says the speed
/// was fused.
#[test]
fn live_equals_replay_with_the_cars_wheel_speeds_configured_by_a_reload() {
    let d = tempfile::tempdir().unwrap();
    let sim = d.path().join("sim");
    let o = Command::new(common::bin())
        .args(["simulate", "--scenario", "urban", "--seed", "4", "--duration", "20", "--speed", "--out"])
        .arg(&sim)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // the simulator's config, on vcan0, with the DBC beside it
    let cfg = d.path().join("live.toml");
    let text = std::fs::read_to_string(sim.join("config.toml")).unwrap();
    std::fs::write(&cfg, format!("{text}\n[can]\ninterface = \"vcan0\"\n")).unwrap();
    std::fs::copy(sim.join("car.dbc"), d.path().join("car.dbc")).unwrap();
    // the daemon starts without [speed] and gets it by a reload (SIGHUP): the
    // kernel filters must then pass the speed message too
    let mut imu_only = String::new();
    let mut skip = false;
    for l in text.lines() {
        if l.trim_start().starts_with('[') {
            skip = l.trim() == "[speed]";
        }
        if !skip {
            imu_only += l;
            imu_only.push('\n');
        }
    }
    assert!(!imu_only.contains("[speed]") && !imu_only.contains("WHEEL_SPEEDS"), "{imu_only}");
    let first = d.path().join("first.toml");
    std::fs::write(&first, format!("{imu_only}\n[can]\ninterface = \"vcan0\"\n")).unwrap();
    let log = sim.join("imu.log");
    let script = format!(
        r#"
set -u
{CAPTURE}
cp first.toml active.toml
gyrocomp run --config active.toml 2> daemon.err &
D=$!
{WAIT_READY}
cp live.toml active.toml
kill -HUP $D
i=0; until grep -q "config reloaded" daemon.err; do sleep 0.1; i=$((i+1)); [ $i -gt 100 ] && {{ echo "no reload"; cat daemon.err; exit 1; }}; done
sleep 1
capture live.log imu.log
{STOP}
cat daemon.err
"#
    );
    let live = d.path().join("live.log");
    let err = d.path().join("daemon.err");
    let (ok, console) = vm(
        &script,
        &[(&cfg, "/work/live.toml"), (&first, "/work/first.toml"), (&d.path().join("car.dbc"), "/work/car.dbc"), (&log, "/work/imu.log")],
        &[("/work/live.log", &live), ("/work/daemon.err", &err)],
        600,
    );
    assert!(ok, "VM run failed:\n{console}");
    let daemon_err = std::fs::read_to_string(&err).unwrap();
    assert!(daemon_err.contains("vehicle speed from the bus"), "{daemon_err}");
    let r = d.path().join("replay.log");
    let summary = replay(&cfg, &log, &r);
    assert!(summary.contains("speed frames: decoded 1000"), "{summary}");
    let want = frames(&r);
    let is_silent = |f: &(u32, Vec<u8>)| f.0 == 0x113 && status_flags(&f.1) & gyrocomp::estimator::flags::BUS_SILENT != 0;
    let got: Vec<_> = frames(&live).into_iter().filter(|f| !is_silent(f)).collect();
    assert_eq!(got.len(), want.len(), "frame count live vs replay\n{daemon_err}");
    assert!(got == want, "live payloads differ from replay");
    // the speed was fused: FlagSpeedAided on the status frames once the first wheel frames are in
    let aided = got.iter().filter(|f| f.0 == 0x113 && status_flags(&f.1) & gyrocomp::estimator::flags::SPEED_AIDED != 0).count();
    let status = got.iter().filter(|f| f.0 == 0x113).count();
    assert!(aided > status * 9 / 10, "SpeedAided on {aided} of {status} status frames");
}

#[test]
fn two_khz_for_60_s_loses_nothing() {
    let d = tempfile::tempdir().unwrap();
    let cfg = d.path().join("fast.toml");
    std::fs::write(&cfg, "[input]\nprofile = \"adis16465-1\"\n[can]\ninterface = \"vcan0\"\n").unwrap();
    let p = builtin_profile("adis16465-1").unwrap();
    let ids = InputIds::DEFAULT.all();
    let n = 2000 * 60;
    let mut log = Vec::with_capacity(n * 4 * 46);
    for k in 0..n {
        let t = k as f64 / 2000.0;
        let mut r = RawSample::quantise(&p, [0.1, 0.2 * t.sin(), -0.1], [0.0, 0.01, -1.0], [0.0; 3], 35.0);
        r.cnt = k as u16;
        let f = r.encode();
        let ts = 1_700_000_000_000_000 + k as u64 * 500;
        for i in 0..4 {
            write_line(&mut log, ts + i as u64 * 100, b"vcan0", ids[i], &f[i]);
        }
    }
    let lp = d.path().join("fast.log");
    std::fs::write(&lp, &log).unwrap();
    let script = format!(
        r#"
set -u
gyrocomp run --config fast.toml 2> daemon.err &
D=$!
{WAIT_READY}
canplayer -I fast.log vcan0=vcan0
sleep 1
grep -E "VmHWM|VmRSS" /proc/$D/status
{STOP}
"#
    );
    let err = d.path().join("daemon.err");
    let (ok, console) = vm(&script, &[(&cfg, "/work/fast.toml"), (&lp, "/work/fast.log")], &[("/work/daemon.err", &err)], 900);
    assert!(ok, "VM run failed:\n{console}");
    let e = std::fs::read_to_string(&err).unwrap();
    assert!(e.contains(&format!("samples={n} dropped=0 lost=0")), "daemon summary:\n{e}");
    // peak resident memory after 60 s at 2 kHz: at most 10 MiB
    let hwm: u64 = console
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:").map(|v| v.trim().trim_end_matches("kB").trim().parse().unwrap()))
        .expect("VmHWM line");
    println!("daemon peak RSS at 2 kHz: {hwm} kB");
    assert!(hwm <= 10 * 1024, "peak RSS {hwm} kB > 10 MiB");
}
