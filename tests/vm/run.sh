#!/usr/bin/env bash
# Run a POSIX sh test script with a real SocketCAN bus "vcan0" (up), and exit with its code.
#
# Usage: tests/vm/run.sh [--timeout SECS] [--mem MB] [--smp N] --script TEST.sh
#            [--add HOSTPATH[:GUESTPATH]]... [--add-dir HOSTDIR[:GUESTDIR]]...
#            [--collect GUESTPATH:HOSTPATH]... [--env NAME=VALUE]... [-- ARGS for TEST.sh]
#
#   --timeout SECS  limit for TEST.sh itself (default 300); it then fails with rc 124
#   --mem MB        guest memory (VM back end, default 512);  --smp N: guest CPUs (default 2)
#   --add           copy a file in; GUESTPATH defaults to /work/<basename>, relative paths are
#                   under /work, a trailing "/" means "into this directory". Dynamic ELF
#                   files bring along the shared libraries ldd lists.
#   --add-dir       copy a directory tree in (default /work/<basename>)
#   --collect       copy a file back out after the test (e.g. /tmp/candump.log:out/c.log);
#                   a missing file fails the run
#   --env           set an environment variable for TEST.sh
#
# TEST.sh runs under busybox sh with cwd /work (= $GYROCOMP_WORK), /work/bin and /work on
# PATH, candump/cansend/canplayer/cangen/cansequence available, GYROCOMP_VCAN_BACKEND set.
# Its stdout/stderr appear on this script's stdout.  Back end (env GYROCOMP_VCAN=host|vm
# forces one): "host" if this kernel can create a vcan, else a QEMU (TCG) VM booting a
# Debian kernel with a busybox initramfs.  In host mode /work is a temp dir: test scripts
# should use relative paths (or $GYROCOMP_WORK), and absolute GUESTPATHs outside /work
# land under that dir.  busybox sh runs its own applets before PATH: "ip" is busybox's
# ip; call /usr/sbin/ip for iproute2's (-details, -statistics), present in both back ends.
# GYROCOMP_VM_KEEP=1 keeps the run directory (console log, initrd);
# GYROCOMP_VM_QEMU_ARGS adds qemu arguments; GYROCOMP_VM_CACHE moves the cache.
set -euo pipefail
. "$(dirname "${BASH_SOURCE[0]}")/lib.sh"

TIMEOUT=300 MEM=512 SMP=2 SCRIPT=''
ADDS=() ADD_DIRS=() COLLECTS=() ENVS=() ARGS=()
while [ $# -gt 0 ]; do
    case $1 in
        --timeout) TIMEOUT=${2:?--timeout needs SECS}; shift ;;
        --mem) MEM=${2:?--mem needs MB}; shift ;;
        --smp) SMP=${2:?--smp needs N}; shift ;;
        --script) SCRIPT=${2:?--script needs a file}; shift ;;
        --add) ADDS+=("${2:?--add needs HOSTPATH[:GUESTPATH]}"); shift ;;
        --add-dir) ADD_DIRS+=("${2:?--add-dir needs HOSTDIR[:GUESTDIR]}"); shift ;;
        --collect) COLLECTS+=("${2:?--collect needs GUESTPATH:HOSTPATH}"); shift ;;
        --env) ENVS+=("${2:?--env needs NAME=VALUE}"); shift ;;
        --) shift; ARGS=("$@"); break ;;
        -h|--help) usage; exit 0 ;;
        *) die "run.sh: unknown argument '$1' (see --help)" ;;
    esac
    shift
done
[ -n "$SCRIPT" ] || die "run.sh: --script TEST.sh is required (see --help)"
[ -f "$SCRIPT" ] || die "run.sh: no such test script: $SCRIPT"
[[ $TIMEOUT =~ ^[0-9]+$ ]] || die "--timeout must be a number of seconds"
[[ $MEM =~ ^[0-9]+$ ]] || die "--mem must be a number of MB"
for e in "${ENVS[@]}"; do [[ $e =~ ^[A-Za-z_][A-Za-z0-9_]*= ]] || die "bad --env '$e' (want NAME=VALUE)"; done
for c in "${COLLECTS[@]}"; do [[ $c == /*:?* ]] || die "bad --collect '$c' (want /GUEST/PATH:HOSTPATH)"; done
need_root

# Shell-quote for embedding in generated sh scripts.
q() { printf "'%s'" "$(printf '%s' "$1" | sed "s/'/'\\\\''/g")"; }

# --- back end choice ------------------------------------------------------------------

HOST_VCAN_CREATED=0
# Try to get a host vcan0; succeeds if it exists or could be created.
host_vcan() {
    if ip link show dev vcan0 >/dev/null 2>&1; then
        ip link set vcan0 up 2>/dev/null || return 1
        return 0
    fi
    if command -v modprobe >/dev/null; then modprobe vcan >/dev/null 2>&1 || true; fi
    ip link add dev vcan0 type vcan >/dev/null 2>&1 || return 1
    HOST_VCAN_CREATED=1
    ip link set vcan0 up || return 1
}
cleanup_host_vcan() {
    if [ $HOST_VCAN_CREATED = 1 ]; then ip link del dev vcan0 2>/dev/null || true; fi
}

# --- host back end --------------------------------------------------------------------

# Map a guest path onto the host run dir $1 (/work -> $1, other absolute paths under $1).
host_map() {
    local work=$1 p=$2
    case $p in
        /work) echo "$work" ;;
        /work/*) echo "$work/${p#/work/}" ;;
        *) echo "$work$p" ;;
    esac
}

run_host() {
    "$VM_DIR/prepare.sh" --host-only --quiet
    local work extra_path="" s p
    work=$(mktemp -d /tmp/gyrocomp-host.XXXXXX)
    # shellcheck disable=SC2064
    trap "cleanup_host_vcan; [ \"\${GYROCOMP_VM_KEEP:-0}\" = 1 ] || rm -rf '$work'" EXIT
    chmod 755 "$work"
    for s in "${ADDS[@]}"; do
        parse_spec "$s" /work; [ -f "$SPEC_HOST" ] || die "--add $s: not a file (use --add-dir)"
        p=$(host_map "$work" "$SPEC_GUEST")
        mkdir -p "$(dirname "$p")"; cp -L --preserve=mode "$SPEC_HOST" "$p"
        case $SPEC_GUEST in /work/*) ;; *) [ -x "$p" ] && extra_path="$(dirname "$p"):$extra_path" ;; esac
    done
    for s in "${ADD_DIRS[@]}"; do
        parse_spec "$s" /work; [ -d "$SPEC_HOST" ] || die "--add-dir $s: not a directory"
        p=$(host_map "$work" "$SPEC_GUEST")
        mkdir -p "$p"; cp -a "$SPEC_HOST/." "$p/"
    done
    mkdir -p "$work/.gyrocomp"; cp "$SCRIPT" "$work/.gyrocomp/test.sh"

    local shell=(sh)   # busybox sh, as in the VM
    if [ -x /bin/busybox ]; then shell=(/bin/busybox sh)
    elif command -v busybox >/dev/null; then shell=(busybox sh); fi
    local e envargs=(GYROCOMP_VCAN_BACKEND=host GYROCOMP_WORK="$work"
                     PATH="$work/bin:$work:$extra_path$PATH")
    for e in "${ENVS[@]}"; do envargs+=("$e"); done
    log "back end: host vcan0; work dir $work"
    local rc=0 pid
    # timeout runs the test in its own process group: kill leftovers (e.g. candump &) after.
    (cd "$work" && exec env "${envargs[@]}" timeout -k 10 "$TIMEOUT" "${shell[@]}" .gyrocomp/test.sh "${ARGS[@]}" </dev/null 2>&1) &
    pid=$!
    wait $pid || rc=$?
    kill -KILL -- "-$pid" 2>/dev/null || true
    [ $rc = 124 ] && log "TEST.sh timed out after ${TIMEOUT}s"

    local c guest dst bad=0
    for c in "${COLLECTS[@]}"; do
        guest=${c%%:*}; dst=${c#*:}
        case $guest in /work|/work/*) p=$(host_map "$work" "$guest") ;; *) p=$guest ;; esac
        if [ -f "$p" ]; then mkdir -p "$(dirname "$dst")"; cp "$p" "$dst"; log "collected $dst"
        else log "collect: $guest not found"; bad=1; fi
    done
    [ $rc = 0 ] && [ $bad = 1 ] && rc=1
    log "result: rc=$rc"
    return $rc
}

# --- VM back end ----------------------------------------------------------------------

CAN_UTILS=(candump cansend canplayer cangen cansequence canbusload cangw cansniffer canfdtest)

# The cached part of the initramfs: busybox, modules, can-utils and their libraries.
build_base() {
    local out=$1 root=$2 bb a t lib
    rm -rf "$root"; mkdir -p "$root"
    (cd "$root" && mkdir -p bin sbin usr/bin usr/sbin usr/local/bin lib/x86_64-linux-gnu lib64 \
        mod etc proc sys dev tmp run root work var/tmp)
    bb=/bin/busybox; [ -x $bb ] || bb=$(command -v busybox)
    cp "$bb" "$root/bin/busybox"
    for a in $("$bb" --list); do
        [ "$a" = busybox ] || ln -sf busybox "$root/bin/$a"
    done
    for t in "${CAN_UTILS[@]}"; do
        if command -v "$t" >/dev/null; then cp -L "$(command -v "$t")" "$root/usr/bin/$t"; fi
    done
    # iproute2's ip (shadows busybox's: -details, -statistics, CAN FD mtu...), if installed.
    if [ -x /usr/sbin/ip ] || [ -x /sbin/ip ]; then cp -L "$(command -v ip)" "$root/usr/sbin/ip"; fi
    cp "$KMOD_DIR"/*.ko "$root/mod/"
    # libgcc_s is dlopen'ed by glibc (thread cancellation) and linked by Rust binaries.
    lib=/lib/x86_64-linux-gnu/libgcc_s.so.1
    if [ -e $lib ]; then stage_file $lib "$root" $lib; fi
    stage_libs_for_tree "$root"
    mknod -m 600 "$root/dev/console" c 5 1
    mknod -m 666 "$root/dev/null" c 1 3
    chmod 1777 "$root/tmp" "$root/var/tmp"
    printf 'root:x:0:0:root:/root:/bin/sh\nnobody:x:65534:65534:nobody:/nonexistent:/bin/false\n' > "$root/etc/passwd"
    printf 'root:x:0:\nnogroup:x:65534:\n' > "$root/etc/group"
    printf '127.0.0.1 localhost\n::1 localhost\n' > "$root/etc/hosts"
    echo gyrocomp-vm > "$root/etc/hostname"
    pack_cpio "$root" "$out"
}

ensure_base() {
    local key
    # Rebuild when the kernel, busybox, can-utils or this script change.
    key=$({ echo "$CACHE_FORMAT $KVER"; cat "$0" "$VM_DIR/lib.sh";
            for t in busybox "${CAN_UTILS[@]}"; do command -v "$t" || true; done | xargs -r md5sum;
          } | md5sum | cut -c1-12)
    BASE_CPIO="$CACHE/initramfs/base-$key.cpio.gz"
    BASE_ROOT="$CACHE/initramfs/base-$key"
    if [ ! -f "$BASE_CPIO" ]; then
        log "building base initramfs $BASE_CPIO"
        mkdir -p "$CACHE/initramfs"
        find "$CACHE/initramfs" -mindepth 1 -maxdepth 1 -name 'base-*' -exec rm -rf {} +
        build_base "$BASE_CPIO" "$BASE_ROOT"
    fi
}

# /init for the guest: mount, load CAN modules, vcan0 up, run the test, collect, report.
write_init() {
    local f=$1 e
    {
        cat <<EOF
#!/bin/sh
export PATH=/work/bin:/work:/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin
export HOME=/root TMPDIR=/tmp GYROCOMP_VCAN_BACKEND=vm GYROCOMP_WORK=/work
chmod 755 /
mount -t proc proc /proc
mount -t sysfs sysfs /sys
mount -t devtmpfs devtmpfs /dev
mkdir -p /dev/pts /dev/shm
mount -t devpts devpts /dev/pts
mount -t tmpfs tmpfs /dev/shm
mount -t tmpfs -o mode=1777 tmpfs /tmp
mount -t tmpfs tmpfs /run
exec </dev/null >/dev/console 2>&1
dmesg -n 1          # keep kernel messages off the console (it carries our data)
hostname gyrocomp-vm
ip link set lo up
EOF
        for e in "${ENVS[@]}"; do printf 'export %s=%s\n' "${e%%=*}" "$(q "${e#*=}")"; done
        cat <<EOF
rc=0
for m in can can-raw can-dev vcan can-gw vxcan can-bcm; do
  [ -f /mod/\$m.ko ] || continue
  insmod /mod/\$m.ko || { echo "[vm] insmod \$m.ko failed"; rc=125; }
done
if [ \$rc = 0 ] && ip link add dev vcan0 type vcan && ip link set vcan0 up; then
  cd /work
  sh /work/.gyrocomp/test.sh $(for a in "${ARGS[@]}"; do printf '%s ' "$(q "$a")"; done) &
  tpid=\$!
  ( sleep $TIMEOUT; echo "[vm] TEST.sh timed out after ${TIMEOUT}s"; : > /run/timedout
    kill -TERM \$tpid; sleep 5; kill -KILL \$tpid ) &
  wpid=\$!
  wait \$tpid; rc=\$?
  kill \$wpid 2>/dev/null
  [ -e /run/timedout ] && rc=124
else
  echo "[vm] could not set up vcan0"; rc=125
fi
cd /
kill -KILL -1 2>/dev/null   # stop whatever the test left running (only PID 1 survives)
sleep 0.2
EOF
        guest_collect_snippet /work/.gyrocomp/collect
        cat <<EOF
echo
echo "$MARK_RESULT rc=\$rc"
sleep 1             # let the UART drain before the power goes
poweroff -f
sleep 60
EOF
    } > "$f"
    chmod 755 "$f"
}

run_vm() {
    "$VM_DIR/prepare.sh" --quiet
    load_kernel_env || die "prepare.sh did not leave a kernel in $CACHE/kernel"
    with_lock initramfs ensure_base
    ensure_base   # sets BASE_CPIO/BASE_ROOT in this shell (already built)

    local rundir stage s i=0 c
    mkdir -p "$CACHE/runs"
    rundir=$(mktemp -d "$CACHE/runs/run.XXXXXX")
    # shellcheck disable=SC2064
    trap "[ \"\${GYROCOMP_VM_KEEP:-0}\" = 1 ] && echo '[vm] kept $rundir' >&2 || rm -rf '$rundir'" EXIT
    stage="$rundir/stage"
    mkdir -p "$stage/work/.gyrocomp"
    for s in "${ADDS[@]}"; do
        parse_spec "$s" /work; [ -f "$SPEC_HOST" ] || die "--add $s: not a file (use --add-dir)"
        stage_file "$SPEC_HOST" "$stage" "$SPEC_GUEST"
    done
    for s in "${ADD_DIRS[@]}"; do
        parse_spec "$s" /work; [ -d "$SPEC_HOST" ] || die "--add-dir $s: not a directory"
        mkdir -p "$stage$SPEC_GUEST"; cp -a "$SPEC_HOST/." "$stage$SPEC_GUEST/"
    done
    stage_libs_for_tree "$stage" "$BASE_ROOT"
    rebase_on_symlinks "$stage" "$BASE_ROOT"
    cp "$SCRIPT" "$stage/work/.gyrocomp/test.sh"
    : > "$stage/work/.gyrocomp/collect"
    local cspecs=()
    for c in "${COLLECTS[@]}"; do
        i=$((i + 1))
        echo "$i ${c%%:*}" >> "$stage/work/.gyrocomp/collect"
        cspecs+=("$i:$(realpath -m "${c#*:}")")
    done
    write_init "$stage/init"
    # Directories that also exist in the base must keep its modes (the kernel applies them).
    find "$stage" -type d -exec chmod 755 {} +
    pack_cpio "$stage" "$rundir/run.cpio.gz"
    cat "$BASE_CPIO" "$rundir/run.cpio.gz" > "$rundir/initrd.gz"   # concatenated archives

    local console="$rundir/console.log" host_to=$((TIMEOUT + 120)) qrc=0 t0
    log "back end: QEMU TCG VM, kernel $KVER, ${MEM} MB, $SMP CPU(s), timeout ${TIMEOUT}s (+120s boot margin)"
    t0=$(now)
    set +e
    # qboot: quicker than SeaBIOS and writes nothing on the console.  -cpu max offers
    # RDRAND, so the guest's RNG is ready at once (getrandom() would block for ~20 s).
    local bios=()
    [ -f /usr/share/qemu/qboot.rom ] && bios=(-bios /usr/share/qemu/qboot.rom)
    # shellcheck disable=SC2086  # GYROCOMP_VM_QEMU_ARGS: extra qemu arguments, split on spaces
    timeout -k 10 "$host_to" qemu-system-x86_64 -accel tcg -cpu max "${bios[@]}" -m "$MEM" -smp "$SMP" \
        -nographic -no-reboot -nodefaults -serial stdio -monitor none ${GYROCOMP_VM_QEMU_ARGS:-} \
        -kernel "$KERNEL_IMG" -initrd "$rundir/initrd.gz" \
        -append "console=ttyS0 quiet loglevel=3 panic=-1" </dev/null 2>&1 \
        | console_filter "$console"
    qrc=${PIPESTATUS[0]}
    set -e
    cp "$console" "$CACHE/last-console.log" 2>/dev/null || true
    log "VM ran $(( $(now) - t0 ))s (console log: $CACHE/last-console.log)"

    local line rc
    line=$(grep -a "^$MARK_RESULT rc=[0-9]*\$" "$console" | tail -n 1 || true)
    if [ -z "$line" ]; then
        if [ "$qrc" = 124 ] || [ "$qrc" = 137 ]; then
            log "FAIL: the VM did not finish within ${host_to}s (no $MARK_RESULT line)"; return 124
        fi
        log "FAIL: the VM stopped without a $MARK_RESULT line (qemu exit $qrc; kernel panic or crash?)"
        return 125
    fi
    rc=${line##*rc=}
    if [ ${#cspecs[@]} -gt 0 ] && ! extract_collected "$console" "${cspecs[@]}"; then
        [ "$rc" = 0 ] && rc=1
    fi
    log "result: rc=$rc"
    return "$rc"
}

# --- main -----------------------------------------------------------------------------

case ${GYROCOMP_VCAN:-auto} in
    host) host_vcan || die "GYROCOMP_VCAN=host but this kernel cannot create a vcan (no SocketCAN?)"
          run_host ;;
    vm) run_vm ;;
    auto) if host_vcan; then run_host; else run_vm; fi ;;
    *) die "GYROCOMP_VCAN must be host or vm, not '$GYROCOMP_VCAN'" ;;
esac
