#!/usr/bin/env bash
# Self-test of the harness with can-utils only: a vcan run (host or VM back end, whichever
# run.sh picks), exit-code passing, file transfer in and out, and (unless --quick) a
# systemd VM run.  Prints wall times and ends with "selftest: N passed, N failed".
#
# Usage: tests/vm/selftest.sh [--quick]
set -euo pipefail
. "$(dirname "${BASH_SOURCE[0]}")/lib.sh"

QUICK=0
case ${1:-} in --quick) QUICK=1 ;; "") ;; *) die "usage: selftest.sh [--quick]" ;; esac

T=$(mktemp -d /tmp/gyrocomp-selftest.XXXXXX)
trap 'rm -rf "$T"' EXIT
PASS=0 FAIL=0 TIMES=()
check() {   # check NAME EXPECTED_RC CMD...
    local name=$1 want=$2 rc=0 t0; shift 2
    t0=$(now)
    echo "=== selftest: $name"
    "$@" || rc=$?
    TIMES+=("$name: $(( $(now) - t0 ))s")
    if [ "$rc" = "$want" ]; then PASS=$((PASS + 1)); echo "=== ok: $name"
    else FAIL=$((FAIL + 1)); echo "=== FAILED: $name (rc=$rc, wanted $want)"; fi
}

t0=$(now)
"$VM_DIR/prepare.sh"
TIMES+=("prepare: $(( $(now) - t0 ))s")

# 1. vcan: candump sees a cansend frame; the link goes down and up again.
head -c 100000 /dev/urandom > "$T/blob"
md5sum < "$T/blob" | cut -d' ' -f1 > "$T/blob.md5"
cat > "$T/vcan.sh" <<'EOF'
set -e
echo "back end: $GYROCOMP_VCAN_BACKEND, kernel $(uname -r)"
ip link show vcan0 | grep -q 'UP' || { echo "vcan0 is not up"; exit 1; }
candump -L vcan0 > /tmp/c.log &
i=0
until grep -q '123#DEADBEEF' /tmp/c.log; do    # candump needs a moment to start
  i=$((i + 1)); [ $i -le 50 ] || { echo "candump never saw the frame"; exit 1; }
  cansend vcan0 123#DEADBEEF; sleep 0.2
done
echo "candump saw: $(grep -m1 '123#DEADBEEF' /tmp/c.log)"
ip link set vcan0 down
if ip link show vcan0 | grep -q ',UP'; then echo "vcan0 still up"; exit 1; fi
if cansend vcan0 124#01 2>/dev/null; then echo "cansend worked on a down link"; exit 1; fi
ip link set vcan0 up
ip link show vcan0 | grep -q ',UP' || { echo "vcan0 did not come up"; exit 1; }
# A raw socket reading a link that goes down gets ENETDOWN: candump quits ("Network is
# down"), so listen again.
candump -L vcan0 > /tmp/c2.log &
i=0
until grep -q '125#CAFE' /tmp/c2.log; do
  i=$((i + 1)); [ $i -le 50 ] || { echo "no frame after down/up"; exit 1; }
  cansend vcan0 125#CAFE; sleep 0.2
done
cat /tmp/c2.log >> /tmp/c.log
[ "$(md5sum < data/blob | cut -d' ' -f1)" = "$(cat blob.md5)" ] || { echo "added file corrupt"; exit 1; }
md5sum < data/blob | cut -d' ' -f1 > /tmp/blob.md5
cp data/blob /tmp/blob.back
echo "vcan checks passed"
EOF
vcan_run() {
    "$VM_DIR/run.sh" --timeout 120 --script "$T/vcan.sh" --add "$T/blob:data/" --add "$T/blob.md5" \
        --collect "/tmp/c.log:$T/out/c.log" --collect "/tmp/blob.back:$T/out/blob" || return $?
    grep -q '125#CAFE' "$T/out/c.log" || { echo "collected candump log lacks the frame"; return 1; }
    cmp "$T/blob" "$T/out/blob" || { echo "collected blob differs"; return 1; }
}
check "vcan (run.sh)" 0 vcan_run

# 2. The test's exit code is passed through.
printf 'echo "exiting with 7"\nexit 7\n' > "$T/rc.sh"
check "exit code (run.sh)" 7 "$VM_DIR/run.sh" --timeout 60 --script "$T/rc.sh"

# 3. systemd as PID 1: a trivial unit starts and is active; vcan0 is there too.
if [ $QUICK = 0 ]; then
    cat > "$T/gyrocomp-selftest.service" <<'EOF'
[Unit]
Description=gyrocomp harness self-test unit
[Service]
ExecStart=/bin/sh -c 'echo selftest unit running; exec sleep infinity'
EOF
    cat > "$T/check.sh" <<'EOF'
set -e
echo "PID 1: $(cat /proc/1/comm); system: $(systemctl is-system-running --wait || true)"
systemctl start gyrocomp-selftest.service
systemctl is-active gyrocomp-selftest.service
journalctl -u gyrocomp-selftest.service --no-pager -o cat | grep -q 'selftest unit running'
candump -L vcan0 > /tmp/c.log &
sleep 1
cansend vcan0 321#BEEF
sleep 1
grep '321#BEEF' /tmp/c.log
systemctl stop gyrocomp-selftest.service
! systemctl is-active gyrocomp-selftest.service
echo "systemd checks passed"
EOF
    t0=$(now)
    "$VM_DIR/systemd.sh" --build-only
    TIMES+=("systemd root (debootstrap + pack, cached after the first run): $(( $(now) - t0 ))s")
    check "systemd (systemd.sh)" 0 "$VM_DIR/systemd.sh" --timeout 180 --script "$T/check.sh" \
        --unit "$T/gyrocomp-selftest.service"
fi

echo "=== timings:"
printf '  %s\n' "${TIMES[@]}"
echo "selftest: $PASS passed, $FAIL failed"
[ $FAIL = 0 ]
