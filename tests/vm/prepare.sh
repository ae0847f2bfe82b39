#!/usr/bin/env bash
# Install the tools the VM test harness needs and fetch a Debian kernel with CAN modules.
#
# Usage: tests/vm/prepare.sh [--host-only] [--rootfs] [--refresh] [--quiet]
#   --host-only  only the tools needed to run tests on a host vcan (no kernel, no qemu)
#   --rootfs     also build the cached systemd root (debootstrap, ~1 min; systemd.sh does it on demand)
#   --refresh    look up the newest kernel package again even if one is cached
#   --quiet      print nothing when everything is already in place
# Cache: ${GYROCOMP_VM_CACHE:-<repo>/target/vm}.  Afterwards $CACHE/kernel/env defines
# KVER, VMLINUZ, KMOD_DIR (can.ko, can-raw.ko, can-dev.ko, vcan.ko, can-gw.ko, vxcan.ko).
set -euo pipefail
. "$(dirname "${BASH_SOURCE[0]}")/lib.sh"

HOST_ONLY=0 ROOTFS=0 REFRESH=0 QUIET=0
while [ $# -gt 0 ]; do
    case $1 in
        --host-only) HOST_ONLY=1 ;;
        --rootfs) ROOTFS=1 ;;
        --refresh) REFRESH=1 ;;
        --quiet) QUIET=1 ;;
        -h|--help) usage; exit 0 ;;
        *) die "prepare.sh: unknown argument '$1' (see --help)" ;;
    esac
    shift
done
need_root
export DEBIAN_FRONTEND=noninteractive

# command -> Debian package providing it
HOST_PKGS=(busybox:busybox-static candump:can-utils ip:iproute2 modprobe:kmod timeout:coreutils flock:util-linux)
VM_PKGS=(qemu-system-x86_64:qemu-system-x86 cpio:cpio gzip:gzip debootstrap:debootstrap
         systemd-analyze:systemd ldd:libc-bin base64:coreutils xz:xz-utils)

APT_UPDATED=0
apt_update_once() {
    [ $APT_UPDATED = 1 ] && return 0
    log "apt-get update"
    apt-get update -qq || die "apt-get update failed (are the Debian package mirrors reachable?)"
    APT_UPDATED=1
}

# apt-get update only when the package lists are absent or do not know a package.
ensure_pkgs() {
    local missing=() spec cmd pkg
    for spec in "$@"; do
        cmd=${spec%%:*}; pkg=${spec#*:}
        command -v "$cmd" >/dev/null 2>&1 && continue
        # busybox-static installs /bin/busybox; qemu may be installed but off PATH: both fine
        [ "$cmd" = busybox ] && [ -x /bin/busybox ] && continue
        missing+=("$pkg")
    done
    [ ${#missing[@]} -eq 0 ] && return 0
    mapfile -t missing < <(printf '%s\n' "${missing[@]}" | sort -u)
    if ! compgen -G '/var/lib/apt/lists/*_Packages*' >/dev/null; then apt_update_once; fi
    local p
    for p in "${missing[@]}"; do
        if [ -z "$(apt-cache policy "$p" 2>/dev/null | awk '/Candidate:/ && $2 != "(none)"')" ]; then
            apt_update_once; break
        fi
    done
    log "apt-get install ${missing[*]}"
    if ! apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null; then
        [ $APT_UPDATED = 1 ] && die "apt-get install ${missing[*]} failed"
        apt_update_once   # stale lists give 404s: refresh once and retry
        apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null \
            || die "apt-get install ${missing[*]} failed"
    fi
}

# Which linux-image-<ver>-amd64 does the linux-image-amd64 meta package point at?
current_kernel_pkg() {
    local pkg
    pkg=$(apt-cache depends linux-image-amd64 2>/dev/null \
          | awk '$1 == "Depends:" && $2 ~ /^linux-image-[0-9]/ { print $2; exit }')
    if [ -z "$pkg" ]; then
        apt_update_once
        pkg=$(apt-cache depends linux-image-amd64 2>/dev/null \
              | awk '$1 == "Depends:" && $2 ~ /^linux-image-[0-9]/ { print $2; exit }')
    fi
    [ -n "$pkg" ] || die "apt-cache depends linux-image-amd64 names no linux-image-<version> package"
    echo "$pkg"
}

# Decompress the ELF kernel inside a bzImage (as the kernel's scripts/extract-vmlinux does).
extract_vmlinux() {
    local z=$1 out=$2 magic dec off
    for magic in 'xz:\xfd7zXZ\x00' 'zstd:\x28\xb5\x2f\xfd' 'gzip:\x1f\x8b\x08'; do
        dec=${magic%%:*}; magic=${magic#*:}
        command -v "$dec" >/dev/null || continue
        for off in $(LC_ALL=C grep -obUaP "$magic" "$z" | cut -d: -f1 | head -n 5); do
            # The decompressor complains about the bytes after the stream: judge the output.
            tail -c "+$((off + 1))" "$z" | "$dec" -dc > "$out.tmp" 2>/dev/null || true
            if [ "$(head -c 4 "$out.tmp" | od -An -c | tr -d ' \n')" = '177ELF' ] \
                    && [ "$(stat -c %s "$out.tmp")" -gt 1000000 ]; then
                mv -f "$out.tmp" "$out"; return 0
            fi
        done
    done
    rm -f "$out.tmp"; return 1
}

prepare_kernel() {
    if [ $REFRESH = 0 ] && load_kernel_env; then
        [ $QUIET = 1 ] || log "kernel $KVER already prepared in $CACHE/kernel"
        return 0
    fi
    local pkg kdir deb
    pkg=$(current_kernel_pkg)
    kdir="$CACHE/kernel/$pkg"
    mkdir -p "$kdir"
    deb=$(compgen -G "$kdir/${pkg}_*.deb" | head -n 1 || true)
    if [ -z "$deb" ]; then
        log "apt-get download $pkg"
        (cd "$kdir" && { apt-get download -qq "$pkg" 2>&1 | grep -v 'unsandboxed' >&2; } || true)
        deb=$(compgen -G "$kdir/${pkg}_*.deb" | head -n 1 || true)
        [ -n "$deb" ] || die "apt-get download $pkg failed"
    fi
    local kver vmlinuz moddir m f tmp="$kdir/root.tmp"
    rm -rf "$tmp"
    dpkg -x "$deb" "$tmp"
    vmlinuz=$(compgen -G "$tmp/boot/vmlinuz-*" | head -n 1 || true)
    [ -n "$vmlinuz" ] || die "$deb holds no boot/vmlinuz-*"
    kver=${vmlinuz##*/vmlinuz-}
    # Keep only what the guests use: the kernel, net/ and CAN driver modules (systemd.sh
    # copies these into its root), and the modules.* index files.
    mkdir -p "$tmp.keep/boot" "$tmp.keep/lib/modules/$kver/kernel/drivers/net"
    mv "$vmlinuz" "$tmp.keep/boot/"
    mv "$tmp/lib/modules/$kver/kernel/net" "$tmp.keep/lib/modules/$kver/kernel/"
    mv "$tmp/lib/modules/$kver/kernel/drivers/net/can" "$tmp.keep/lib/modules/$kver/kernel/drivers/net/"
    mv "$tmp/lib/modules/$kver"/modules.* "$tmp.keep/lib/modules/$kver/"
    rm -rf "$tmp" "$kdir/root"
    mv "$tmp.keep" "$kdir/root"
    vmlinuz="$kdir/root/boot/vmlinuz-$kver"
    moddir="$kdir/mods"
    rm -rf "$moddir" && mkdir -p "$moddir"
    # Required modules first, then the optional ones.
    for m in can can-raw can-dev vcan can-gw vxcan can-bcm; do
        f=$(find "$kdir/root/lib/modules/$kver" -name "$m.ko*" | head -n 1)
        if [ -z "$f" ]; then
            case $m in can|can-raw|can-dev|vcan) die "module $m.ko not found in $pkg";; esac
            continue
        fi
        case $f in
            *.ko) cp "$f" "$moddir/$m.ko" ;;
            *.ko.xz) xz -dc "$f" > "$moddir/$m.ko" ;;
            *.ko.zst) zstd -qdc "$f" > "$moddir/$m.ko" ;;
            *.ko.gz) gzip -dc "$f" > "$moddir/$m.ko" ;;
        esac
    done
    # The uncompressed ELF kernel boots through its PVH entry: ~5 s quicker under TCG
    # than letting the bzImage decompress itself.
    local vmlinux="$kdir/vmlinux"
    if extract_vmlinux "$vmlinuz" "$vmlinux"; then
        log "extracted $vmlinux (booted via PVH)"
    else
        log "could not extract an ELF vmlinux from $vmlinuz; the VMs boot the bzImage"
        vmlinux=
    fi
    cat > "$CACHE/kernel/env.tmp" <<EOF
KFORMAT=$CACHE_FORMAT
KPKG=$pkg
KVER=$kver
KROOT=$kdir/root
VMLINUZ=$vmlinuz
VMLINUX=$vmlinux
KMOD_DIR=$moddir
EOF
    mv -f "$CACHE/kernel/env.tmp" "$CACHE/kernel/env"
    # Drop other kernels' leftovers.
    find "$CACHE/kernel" -mindepth 1 -maxdepth 1 -type d ! -name "$pkg" -exec rm -rf {} +
    log "kernel $kver ready: $vmlinuz; modules: $(cd "$moddir" && echo *.ko)"
}

main() {
    mkdir -p "$CACHE"
    ensure_pkgs "${HOST_PKGS[@]}"
    [ $HOST_ONLY = 1 ] && return 0
    ensure_pkgs "${VM_PKGS[@]}"
    with_lock kernel prepare_kernel
    if [ $ROOTFS = 1 ]; then
        "$VM_DIR/systemd.sh" --build-only
    fi
}
main
