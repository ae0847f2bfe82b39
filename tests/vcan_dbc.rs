//! The DBC input live: the daemon with the MM7.10 example config on a real
//! vcan (a QEMU VM where the host has none, tests/vm/run.sh picks), the
//! simulated MM7.10 frames (`simulate --input-dbc`) played with canplayer
//! among frames it must not take (another unit's extended IDs, an ID the
//! kernel filter drops); what it publishes carries exactly the payloads
//! `gyrocomp replay` writes from the same log.

mod common;
use gyrocomp::candump::parse_line;
use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn frames(p: &Path) -> Vec<(u32, Vec<u8>)> {
    std::fs::read_to_string(p)
        .unwrap()
        .lines()
        .filter(|l| !l.is_empty())
        .map(|l| {
            let f = parse_line(l.as_bytes()).unwrap_or_else(|e| panic!("{}: {e}: {l}", p.display()));
            (f.id, f.payload().to_vec())
        })
        .collect()
}

#[test]
fn mm7p10_live_equals_replay() {
    let d = tempfile::tempdir().unwrap();
    let sim = d.path().join("sim");
    let o = Command::new(common::bin())
        .args(["simulate", "--scenario", "vehicle", "--seed", "5", "--duration", "8", "--out"])
        .arg(&sim)
        .arg("--input-dbc")
        .arg(root().join("config/mm7p10.toml"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // the daemon's config: the simulated unit's, on vcan0
    let cfg = d.path().join("live.toml");
    let mut text = std::fs::read_to_string(sim.join("config.toml")).unwrap();
    text += "\n[can]\ninterface = \"vcan0\"\n[estimator]\nwarmup_s = 1.0\nlearn_s = 3.0\n";
    std::fs::write(&cfg, &text).unwrap();
    std::fs::copy(sim.join("mm7p10.dbc"), d.path().join("mm7p10.dbc")).unwrap();
    // the MM7.10 frames with others between them: a J1939 unit's extended
    // frame with the low 11 bits of TX1 (0x174), and an unrelated standard ID
    let mut log = String::new();
    for l in std::fs::read_to_string(sim.join("imu.log")).unwrap().lines() {
        log += l;
        log += "\n";
        if l.contains(" 174#") {
            let t = &l[..l.find(')').unwrap() + 1];
            log += &format!("{t} vcan0 18FF0174#0011223344556677\n{t} vcan0 555#AABBCCDDEEFF0011\n");
        }
    }
    let input = d.path().join("in.log");
    std::fs::write(&input, &log).unwrap();

    let script = r#"
set -u
gyrocomp run --config live.toml 2> daemon.err &
D=$!
i=0; until grep -q "bus open" daemon.err 2>/dev/null; do sleep 0.1; i=$((i+1)); [ $i -gt 300 ] && { echo "daemon never opened the bus"; cat daemon.err; exit 1; }; done
candump -r 8388608 -L vcan0,110:7F8 > live.log &
C=$!
sleep 0.5
canplayer -I in.log vcan0=vcan0
sleep 0.5
kill $C
kill -TERM $D
wait $D; echo "daemon exit $?"
cat daemon.err
"#;
    let sp = d.path().join("test.sh");
    std::fs::write(&sp, script).unwrap();
    let live = d.path().join("live.log");
    let err = d.path().join("daemon.err");
    let mut c = Command::new("bash");
    c.arg(root().join("tests/vm/run.sh")).args(["--timeout", "600", "--script"]).arg(&sp);
    c.arg("--add").arg(format!("{}:/work/bin/gyrocomp", common::bin().display()));
    for (h, g) in [(&cfg, "/work/live.toml"), (&d.path().join("mm7p10.dbc"), "/work/mm7p10.dbc"), (&input, "/work/in.log")] {
        c.arg("--add").arg(format!("{}:{g}", h.display()));
    }
    c.arg("--collect").arg(format!("/work/live.log:{}", live.display()));
    c.arg("--collect").arg(format!("/work/daemon.err:{}", err.display()));
    let o = c.output().expect("bash tests/vm/run.sh");
    let console = format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    assert!(o.status.success(), "VM run failed:\n{console}");
    assert!(console.contains("daemon exit 0"), "{console}");
    let daemon_err = std::fs::read_to_string(&err).unwrap_or_default();

    let want_log = d.path().join("replay.log");
    let o = Command::new(common::bin())
        .arg("replay")
        .arg("--config")
        .arg(&cfg)
        .arg("--input")
        .arg(&input)
        .arg("--output")
        .arg(&want_log)
        .output()
        .unwrap();
    let summary = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(o.status.success(), "{summary}");
    // replay sees the foreign frames (unknown_id); live, the kernel filter keeps them out
    assert!(summary.contains("samples 801 ") && summary.contains("unknown_id 1602"), "{summary}");
    let silent =
        |f: &(u32, Vec<u8>)| f.0 == 0x113 && (u16::from_le_bytes([f.1[0], f.1[1]]) >> 2) & gyrocomp::estimator::flags::BUS_SILENT != 0;
    let got: Vec<_> = frames(&live).into_iter().filter(|f| !silent(f)).collect();
    let want = frames(&want_log);
    assert_eq!(want.len(), 801 * 5);
    assert_eq!(got.len(), want.len(), "frame count live vs replay\n{daemon_err}");
    assert!(got == want, "live payloads differ from replay\n{daemon_err}");
}
