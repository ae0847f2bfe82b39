#!/usr/bin/env bash
# Boot a small Debian root with systemd as PID 1 in a QEMU (TCG) VM, install binaries and
# unit files, and run a check script there with vcan0 up; exit with the check's code.
#
# Usage: tests/vm/systemd.sh [--timeout SECS] [--mem MB] [--smp N] --script CHECK.sh
#            [--bin HOSTPATH[:GUESTPATH]]... [--unit HOSTFILE]... [--enable UNIT]...
#            [--add HOSTPATH[:GUESTPATH]]... [--add-dir HOSTDIR[:GUESTDIR]]...
#            [--collect GUESTPATH:HOSTPATH]... [--env NAME=VALUE]... [-- ARGS for CHECK.sh]
#        tests/vm/systemd.sh --build-only     (just build the cached root and exit)
#
#   --timeout SECS  limit for CHECK.sh (default 300; it then fails with rc 124)
#   --mem MB        guest memory (default 1536: the whole root lives in RAM)
#   --bin           install an executable; GUESTPATH defaults to /usr/local/bin/<basename>
#   --unit          install a unit file into /etc/systemd/system/ (not enabled)
#   --enable UNIT   enable an installed unit at boot (linked into multi-user.target.wants)
#   --add/--add-dir copy data in (default under /work, the check's cwd)
#   --collect       copy a file back out after the check (a missing file fails the run)
#
# CHECK.sh runs under /bin/sh (dash) as root from gyrocomp-check.service (After=basic.target,
# not waited for by multi-user.target), after "modprobe vcan" and vcan0 is up; it may
# "systemctl start" the units under test, "systemctl is-system-running --wait" for the
# enabled ones, use journalctl etc.  Its output appears on this script's stdout.
set -euo pipefail
. "$(dirname "${BASH_SOURCE[0]}")/lib.sh"

# Bump to re-pack the cached root after changing finish_rootfs (build_rootfs, the
# debootstrap, is redone only when ROOTFS_PKGS changes or its directory is removed).
ROOTFS_FORMAT=2
ROOTFS_PKGS=systemd-sysv,udev,iproute2,kmod,can-utils

TIMEOUT=300 MEM=1536 SMP=2 SCRIPT='' BUILD_ONLY=0
BINS=() UNITS=() ENABLES=() ADDS=() ADD_DIRS=() COLLECTS=() ENVS=() ARGS=()
while [ $# -gt 0 ]; do
    case $1 in
        --timeout) TIMEOUT=${2:?--timeout needs SECS}; shift ;;
        --mem) MEM=${2:?--mem needs MB}; shift ;;
        --smp) SMP=${2:?--smp needs N}; shift ;;
        --script) SCRIPT=${2:?--script needs a file}; shift ;;
        --bin) BINS+=("${2:?--bin needs HOSTPATH[:GUESTPATH]}"); shift ;;
        --unit) UNITS+=("${2:?--unit needs a file}"); shift ;;
        --enable) ENABLES+=("${2:?--enable needs a unit name}"); shift ;;
        --add) ADDS+=("${2:?--add needs HOSTPATH[:GUESTPATH]}"); shift ;;
        --add-dir) ADD_DIRS+=("${2:?--add-dir needs HOSTDIR[:GUESTDIR]}"); shift ;;
        --collect) COLLECTS+=("${2:?--collect needs GUESTPATH:HOSTPATH}"); shift ;;
        --env) ENVS+=("${2:?--env needs NAME=VALUE}"); shift ;;
        --build-only) BUILD_ONLY=1 ;;
        --) shift; ARGS=("$@"); break ;;
        -h|--help) usage; exit 0 ;;
        *) die "systemd.sh: unknown argument '$1' (see --help)" ;;
    esac
    shift
done
if [ $BUILD_ONLY = 0 ]; then
    [ -n "$SCRIPT" ] || die "systemd.sh: --script CHECK.sh is required (see --help)"
    [ -f "$SCRIPT" ] || die "systemd.sh: no such check script: $SCRIPT"
fi
[[ $TIMEOUT =~ ^[0-9]+$ ]] || die "--timeout must be a number of seconds"
for e in "${ENVS[@]}"; do [[ $e =~ ^[A-Za-z_][A-Za-z0-9_]*= ]] || die "bad --env '$e' (want NAME=VALUE)"; done
for c in "${COLLECTS[@]}"; do [[ $c == /*:?* ]] || die "bad --collect '$c' (want /GUEST/PATH:HOSTPATH)"; done
for u in "${UNITS[@]}"; do [ -f "$u" ] || die "no such unit file: $u"; done
need_root

q() { printf "'%s'" "$(printf '%s' "$1" | sed "s/'/'\\\\''/g")"; }

# --- the cached root ------------------------------------------------------------------

CODENAME=$(. /etc/os-release && echo "${VERSION_CODENAME:-bookworm}")

# The Debian mirror apt is configured with (never hard-coded): GYROCOMP_VM_MIRROR, else
# apt's own index targets, else the first matching entry of the sources files.
apt_mirror() {
    local m=${GYROCOMP_VM_MIRROR:-}
    # shellcheck disable=SC2016  # $(REPO_URI) is apt's format field
    [ -n "$m" ] || m=$(apt-get indextargets --format '$(REPO_URI)' "Release: $CODENAME" \
                         'Identifier: Packages' 2>/dev/null | head -n 1 || true)
    [ -n "$m" ] || m=$(awk -v c="$CODENAME" '
            tolower($1) == "uris:" { u = $2 } tolower($1) == "suites:" { for (i = 2; i <= NF; i++) if ($i == c) { print u; exit } }
            /^$/ { u = "" }' /etc/apt/sources.list.d/*.sources 2>/dev/null | head -n 1 || true)
    [ -n "$m" ] || m=$(awk -v c="$CODENAME" '$1 == "deb" {
            for (i = 2; i <= NF; i++) if ($i !~ /^\[/ && $i !~ /\]$/ && $i !~ /=/) break
            if ($(i + 1) == c) { print $i; exit } }' /etc/apt/sources.list /etc/apt/sources.list.d/*.list 2>/dev/null | head -n 1 || true)
    [ -n "$m" ] || die "cannot find the Debian mirror for '$CODENAME' in apt's configuration (set GYROCOMP_VM_MIRROR)"
    echo "$m"
}

# debootstrap the plain Debian root once (the slow part, ~1 min), without docs/locales.
build_rootfs() {
    local dir=$1 mirror proxy t0
    mirror=$(apt_mirror)
    # debootstrap fetches with wget: hand it apt's proxy, if apt has one.
    proxy=$(apt-config dump --format '%v' Acquire::http::Proxy 2>/dev/null || true)
    [ -n "$proxy" ] && [ "$proxy" != DIRECT ] && export http_proxy=$proxy
    log "debootstrap $CODENAME from $mirror (minbase + $ROOTFS_PKGS)"
    rm -rf "$dir.tmp"; mkdir -p "$CACHE/debs"
    t0=$(now)
    if ! debootstrap --variant=minbase --include="$ROOTFS_PKGS" --cache-dir="$CACHE/debs" \
            "$CODENAME" "$dir.tmp" "$mirror" > "$CACHE/debootstrap.log" 2>&1; then
        tail -n 30 "$CACHE/debootstrap.log" >&2
        die "debootstrap failed (full log: $CACHE/debootstrap.log)"
    fi
    log "debootstrap took $(( $(now) - t0 ))s"
    local r="$dir.tmp"
    rm -rf "$r"/usr/share/{doc,man,info,locale,lintian,linda}/* "$r"/var/cache/apt/* \
           "$r"/var/lib/apt/lists/* "$r"/var/cache/debconf/*-old "$r"/var/log/*.log \
           "$r"/usr/lib/udev/hwdb.bin "$r"/usr/lib/udev/hwdb.d
    rm -rf "$dir"; mv "$r" "$dir"
}

# Configure the root for quick, quiet boots, add this kernel's net/ and CAN modules, and
# pack it.  The root is packed uncompressed: gunzip of ~160 MB inside TCG costs ~10 s a boot.
finish_rootfs() {
    local r=$1 out=$2 u
    # No gettys on the console that carries our data; skip what a RAM-only VM does not need.
    for u in serial-getty@.service getty@.service console-getty.service getty.target \
             apt-daily.timer apt-daily-upgrade.timer e2scrub_all.timer e2scrub_reap.service \
             fstrim.timer dpkg-db-backup.timer systemd-timesyncd.service \
             systemd-firstboot.service systemd-networkd-wait-online.service \
             systemd-journal-flush.service systemd-update-utmp.service \
             systemd-update-utmp-runlevel.service systemd-random-seed.service \
             systemd-pstore.service systemd-binfmt.service systemd-hwdb-update.service \
             proc-sys-fs-binfmt_misc.automount sys-kernel-debug.mount sys-kernel-tracing.mount \
             sys-kernel-config.mount sys-fs-fuse-connections.mount dev-hugepages.mount \
             modprobe@dm_mod.service modprobe@efi_pstore.service modprobe@fuse.service \
             modprobe@drm.service; do
        ln -sfn /dev/null "$r/etc/systemd/system/$u"
    done
    echo gyrocomp-vm > "$r/etc/hostname"
    : > "$r/etc/fstab"
    printf '127.0.0.1 localhost gyrocomp-vm\n::1 localhost\n' > "$r/etc/hosts"
    ln -sfn /lib/systemd/systemd "$r/init"
    mkdir -p "$r/work" "$r/usr/local/sbin"
    rm -rf "$r"/lib/modules/*
    mkdir -p "$r/lib/modules/$KVER"
    cp -a "$KROOT/lib/modules/$KVER/." "$r/lib/modules/$KVER/"
    chroot "$r" depmod -a "$KVER"
    log "packing the root into $out"
    pack_cpio "$r" "$out" none
}

ensure_rootfs() {
    local key
    key=$(echo "$ROOTFS_PKGS" | md5sum | cut -c1-8)
    ROOT_DIR="$CACHE/rootfs/$CODENAME-$key"
    ROOT_CPIO="$CACHE/rootfs/$CODENAME-$key-f$CACHE_FORMAT.$ROOTFS_FORMAT-$KVER.cpio"
    [ -f "$ROOT_CPIO" ] && return 0
    mkdir -p "$CACHE/rootfs"
    [ -d "$ROOT_DIR" ] || build_rootfs "$ROOT_DIR"
    find "$CACHE/rootfs" -mindepth 1 -maxdepth 1 ! -path "$ROOT_DIR" -exec rm -rf {} +
    local t0; t0=$(now)
    finish_rootfs "$ROOT_DIR" "$ROOT_CPIO"
    log "root ready ($(du -sh "$ROOT_DIR" | cut -f1) in $ROOT_CPIO, $(( $(now) - t0 ))s)"
}

"$VM_DIR/prepare.sh" --quiet
load_kernel_env || die "prepare.sh did not leave a kernel in $CACHE/kernel"
with_lock rootfs ensure_rootfs
ensure_rootfs   # set ROOT_DIR/ROOT_CPIO here
[ $BUILD_ONLY = 1 ] && exit 0

# --- the per-run overlay --------------------------------------------------------------

mkdir -p "$CACHE/runs"
RUNDIR=$(mktemp -d "$CACHE/runs/systemd.XXXXXX")
# shellcheck disable=SC2064
trap "[ \"\${GYROCOMP_VM_KEEP:-0}\" = 1 ] && echo '[vm] kept $RUNDIR' >&2 || rm -rf '$RUNDIR'" EXIT
S="$RUNDIR/stage"
mkdir -p "$S/work/.gyrocomp" "$S/usr/local/sbin" "$S/etc/systemd/system/multi-user.target.wants"

for s in "${BINS[@]}"; do
    parse_spec "$s" /usr/local/bin; [ -f "$SPEC_HOST" ] || die "--bin $s: not a file"
    stage_file "$SPEC_HOST" "$S" "$SPEC_GUEST"; chmod 755 "$S$SPEC_GUEST"
done
for s in "${ADDS[@]}"; do
    parse_spec "$s" /work; [ -f "$SPEC_HOST" ] || die "--add $s: not a file (use --add-dir)"
    stage_file "$SPEC_HOST" "$S" "$SPEC_GUEST"
done
for s in "${ADD_DIRS[@]}"; do
    parse_spec "$s" /work; [ -d "$SPEC_HOST" ] || die "--add-dir $s: not a directory"
    mkdir -p "$S$SPEC_GUEST"; cp -a "$SPEC_HOST/." "$S$SPEC_GUEST/"
done
for u in "${UNITS[@]}"; do cp "$u" "$S/etc/systemd/system/$(basename "$u")"; done
for u in "${ENABLES[@]}"; do
    [ -f "$S/etc/systemd/system/$u" ] || [ -f "$ROOT_DIR/lib/systemd/system/$u" ] \
        || die "--enable $u: no such unit (give it with --unit)"
    ln -sf "../$u" "$S/etc/systemd/system/multi-user.target.wants/$u"
done
stage_libs_for_tree "$S" "$ROOT_DIR"
rebase_on_symlinks "$S" "$ROOT_DIR"

cp "$SCRIPT" "$S/usr/local/sbin/gyrocomp-check"; chmod 755 "$S/usr/local/sbin/gyrocomp-check"
: > "$S/work/.gyrocomp/collect"
CSPECS=() i=0
for c in "${COLLECTS[@]}"; do
    i=$((i + 1)); echo "$i ${c%%:*}" >> "$S/work/.gyrocomp/collect"
    CSPECS+=("$i:$(realpath -m "${c#*:}")")
done

# The unit and its wrapper: vcan0 up, run the check, collect, report, power off.
cat > "$S/etc/systemd/system/gyrocomp-check.service" <<EOF
[Unit]
Description=gyrocomp VM check
# No default dependencies: multi-user.target is then not ordered after this unit, so the
# boot can finish (systemctl is-system-running --wait works) while the check runs, and
# the check never waits for units under test that hang in "activating".
DefaultDependencies=no
After=basic.target

[Service]
Type=exec
ExecStart=/usr/local/sbin/gyrocomp-check-run
TimeoutStartSec=infinity
StandardOutput=journal+console
StandardError=journal+console

[Install]
WantedBy=multi-user.target
EOF
ln -sf ../gyrocomp-check.service "$S/etc/systemd/system/multi-user.target.wants/gyrocomp-check.service"
{
    cat <<EOF
#!/bin/sh
exec </dev/null >/dev/ttyS0 2>&1
dmesg -n 1     # keep kernel messages off the console (it carries our data)
export PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin
export HOME=/root TMPDIR=/tmp GYROCOMP_VCAN_BACKEND=systemd GYROCOMP_WORK=/work
EOF
    for e in "${ENVS[@]}"; do printf 'export %s=%s\n' "${e%%=*}" "$(q "${e#*=}")"; done
    cat <<EOF
rc=0
if modprobe vcan && ip link add dev vcan0 type vcan && ip link set vcan0 up; then
  cd /work
  # timeout makes its own process group: kill what the check leaves behind afterwards.
  timeout -k 5 $TIMEOUT /bin/sh /usr/local/sbin/gyrocomp-check $(for a in "${ARGS[@]}"; do printf '%s ' "$(q "$a")"; done) &
  tpid=\$!
  wait \$tpid; rc=\$?
  kill -KILL -\$tpid 2>/dev/null
  [ \$rc = 124 ] && echo "[vm] CHECK.sh timed out after ${TIMEOUT}s"
else
  echo "[vm] could not set up vcan0"; rc=125
fi
cd /
EOF
    guest_collect_snippet /work/.gyrocomp/collect
    cat <<EOF
echo
echo "$MARK_RESULT rc=\$rc"
sleep 1        # let the UART drain before the power goes
systemctl poweroff -ff
EOF
} > "$S/usr/local/sbin/gyrocomp-check-run"
chmod 755 "$S/usr/local/sbin/gyrocomp-check-run"
find "$S" -type d -exec chmod 755 {} +
pack_cpio "$S" "$RUNDIR/run.cpio.gz"
cat "$ROOT_CPIO" "$RUNDIR/run.cpio.gz" > "$RUNDIR/initrd.img"

# --- boot -----------------------------------------------------------------------------

CONSOLE="$RUNDIR/console.log"
HOST_TO=$((TIMEOUT + 300))
BIOS=(); [ -f /usr/share/qemu/qboot.rom ] && BIOS=(-bios /usr/share/qemu/qboot.rom)
log "back end: QEMU TCG VM with systemd, kernel $KVER, ${MEM} MB, $SMP CPU(s), timeout ${TIMEOUT}s (+300s boot margin)"
T0=$(now)
set +e
# shellcheck disable=SC2086  # GYROCOMP_VM_QEMU_ARGS: extra qemu arguments, split on spaces
timeout -k 10 "$HOST_TO" qemu-system-x86_64 -accel tcg -cpu max "${BIOS[@]}" -m "$MEM" -smp "$SMP" \
    -nographic -no-reboot -nodefaults -serial stdio -monitor none ${GYROCOMP_VM_QEMU_ARGS:-} \
    -kernel "$KERNEL_IMG" -initrd "$RUNDIR/initrd.img" \
    -append "console=ttyS0 quiet loglevel=3 panic=-1 systemd.unit=multi-user.target systemd.show_status=0" \
    </dev/null 2>&1 | console_filter "$CONSOLE"
QRC=${PIPESTATUS[0]}
set -e
cp "$CONSOLE" "$CACHE/last-systemd-console.log" 2>/dev/null || true
log "VM ran $(( $(now) - T0 ))s (console log: $CACHE/last-systemd-console.log)"

LINE=$(grep -a "^$MARK_RESULT rc=[0-9]*\$" "$CONSOLE" | tail -n 1 || true)
if [ -z "$LINE" ]; then
    if [ "$QRC" = 124 ] || [ "$QRC" = 137 ]; then
        log "FAIL: the VM did not finish within ${HOST_TO}s (no $MARK_RESULT line; did systemd reach multi-user.target?)"
        exit 124
    fi
    log "FAIL: the VM stopped without a $MARK_RESULT line (qemu exit $QRC; kernel panic or crash?)"
    exit 125
fi
RC=${LINE##*rc=}
if [ ${#CSPECS[@]} -gt 0 ] && ! extract_collected "$CONSOLE" "${CSPECS[@]}"; then
    [ "$RC" = 0 ] && RC=1
fi
log "result: rc=$RC"
exit "$RC"
