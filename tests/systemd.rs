//! The service unit under a real systemd (PID 1 in a QEMU VM booting a small
//! Debian root): it reaches active through READY=1, a process frozen with
//! SIGSTOP is killed by the watchdog and restarted, and the state learned
//! before the restart is loaded after it.

mod common;
use std::path::PathBuf;
use std::process::Command;

#[test]
fn unit_runs_under_systemd_with_watchdog_restart_and_state() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let d = tempfile::tempdir().unwrap();
    let feed = d.path().join("feed.log");
    std::fs::write(&feed, common::gentle_log(204 * 10, [0.25, -0.15, 0.2], 1_700_000_000_000_000)).unwrap();
    let cfg = d.path().join("gyrocomp.toml");
    std::fs::write(&cfg, "[can]\ninterface = \"vcan0\"\n[estimator]\nwarmup_s = 1.0\nlearn_s = 2.0\n[daemon]\nsave_every_s = 1.0\n")
        .unwrap();
    let check = d.path().join("check.sh");
    std::fs::write(
        &check,
        r#"#!/bin/sh
set -u
fail() { echo "CHECK-FAIL: $*"; journalctl -u gyrocomp --no-pager -o short-monotonic | tail -40; exit 1; }
mkdir -p /etc/gyrocomp
cp /work/gyrocomp.toml /etc/gyrocomp/gyrocomp.toml
systemd-analyze verify /etc/systemd/system/gyrocomp.service || fail "systemd-analyze verify"
echo "CHECK: verify ok"
# samples on the bus, looping
( while true; do canplayer -I /work/feed.log vcan0=vcan0; done ) &
systemctl start gyrocomp.service || fail "start"
[ "$(systemctl is-active gyrocomp.service)" = active ] || fail "not active after start"
echo "CHECK: active via READY=1"
sleep 5
P1=$(systemctl show -p MainPID --value gyrocomp.service)
[ -s /var/lib/gyrocomp/gyrocomp-state.json ] || fail "no state file after 5 s"
echo "CHECK: state saved"
kill -STOP "$P1"
echo "CHECK: froze $P1"
i=0
while :; do
  P2=$(systemctl show -p MainPID --value gyrocomp.service)
  [ "$P2" != "$P1" ] && [ "$P2" != 0 ] && [ "$(systemctl is-active gyrocomp.service)" = active ] && break
  i=$((i+1)); [ $i -gt 60 ] && fail "not restarted within 30 s"
  sleep 0.5
done
N=$(systemctl show -p NRestarts --value gyrocomp.service)
echo "CHECK: restarted as $P2 (NRestarts=$N)"
[ "$N" -ge 1 ] || fail "NRestarts $N"
journalctl -u gyrocomp.service --no-pager -o cat | grep -q "watchdog timeout" || journalctl --no-pager -o cat | grep -qi "watchdog timeout" || fail "no watchdog timeout in the journal"
echo "CHECK: watchdog timeout logged"
sleep 1
journalctl -u gyrocomp.service --no-pager -o cat _PID="$P2" | grep -q "loaded learned bias" || fail "restarted instance did not load the state"
echo "CHECK: state loaded after restart"
systemctl reload gyrocomp.service || fail "reload"
sleep 1
journalctl -u gyrocomp.service --no-pager -o cat _PID="$P2" | grep -q "config reloaded" || fail "SIGHUP did not reload"
[ "$(systemctl is-active gyrocomp.service)" = active ] || fail "not active after reload"
echo "CHECK: reloaded"
# a bad config on reload is refused and logged; the service keeps running on the old one
cp /etc/gyrocomp/gyrocomp.toml /tmp/good.toml
printf '[switching]\ninner = [1.2, 0.9]\n' >> /etc/gyrocomp/gyrocomp.toml
systemctl reload gyrocomp.service || fail "reload (bad config)"
sleep 1
journalctl -u gyrocomp.service --no-pager -o cat _PID="$P2" | grep -q "reload refused" || fail "bad config not refused"
[ "$(systemctl is-active gyrocomp.service)" = active ] || fail "not active after a refused reload"
[ "$(systemctl show -p MainPID --value gyrocomp.service)" = "$P2" ] || fail "restarted on a refused reload"
cp /tmp/good.toml /etc/gyrocomp/gyrocomp.toml
echo "CHECK: bad reload refused, old config kept"
T0=$(date +%s%N)
systemctl stop gyrocomp.service
T1=$(date +%s%N)
echo "CHECK: stop took $(( (T1 - T0) / 1000000 )) ms"
systemctl show -p Result --value gyrocomp.service
echo "CHECK: all ok"
"#,
    )
    .unwrap();
    let o = Command::new("bash")
        .arg(root.join("tests/vm/systemd.sh"))
        .args(["--timeout", "240", "--script"])
        .arg(&check)
        .arg("--bin")
        .arg(format!("{}:/usr/bin/gyrocomp", common::bin().display()))
        .arg("--unit")
        .arg(root.join("systemd/gyrocomp.service"))
        .arg("--add")
        .arg(format!("{}:/work/feed.log", feed.display()))
        .arg("--add")
        .arg(format!("{}:/work/gyrocomp.toml", cfg.display()))
        .output()
        .expect("bash tests/vm/systemd.sh");
    let text = format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    assert!(o.status.success(), "systemd VM run failed:\n{text}");
    for want in [
        "CHECK: active via READY=1",
        "CHECK: state saved",
        "CHECK: watchdog timeout logged",
        "CHECK: state loaded after restart",
        "CHECK: reloaded",
        "CHECK: bad reload refused, old config kept",
        "CHECK: all ok",
    ] {
        assert!(text.contains(want), "missing {want:?}:\n{text}");
    }
}
