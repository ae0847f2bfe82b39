# shellcheck shell=bash
# Shared helpers for the tests/vm scripts. Sourced, never run.

VM_DIR="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
REPO_ROOT="$(cd "$VM_DIR/../.." && pwd)"
CACHE="${GYROCOMP_VM_CACHE:-$REPO_ROOT/target/vm}"
# Bump when the layout of cached artefacts changes, to force a rebuild.
CACHE_FORMAT=2

# shellcheck disable=SC2034  # used by the scripts that source this file
# Console markers shared by the guests and the host-side parsers.
MARK_RESULT="GYROCOMP-VM-RESULT"
MARK_COLLECT_BEGIN="GYROCOMP-VM-COLLECT-BEGIN"
MARK_COLLECT_END="GYROCOMP-VM-COLLECT-END"

# Print the comment block at the top of the running script (its usage text).
usage() { awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; }

log() { printf '[vm] %s\n' "$*" >&2; }
die() { printf '[vm] ERROR: %s\n' "$*" >&2; exit 1; }
now() { date +%s; }

need_root() {
    [ "$(id -u)" = 0 ] || die "must run as root (apt-get, modprobe, ip link, chroot)"
}

# Run "$@" holding an exclusive lock on $CACHE/$1.lock (parallel runs share the cache).
with_lock() {
    local name=$1; shift
    mkdir -p "$CACHE"
    (
        flock -w 1800 9 || die "timed out waiting for lock $CACHE/$name.lock"
        "$@"
    ) 9>"$CACHE/$name.lock"
}

# Host-side helpers ------------------------------------------------------------

# Is this a dynamically linked ELF file?  (static ones need no libraries)
is_dynamic_elf() {
    [ -f "$1" ] || return 1
    [ "$(head -c 4 "$1" 2>/dev/null | od -An -c | tr -d ' \n')" = '177ELF' ] || return 1
    ldd "$1" >/dev/null 2>&1
}

# Absolute paths of the shared libraries (and loader) that ldd lists for $1.
elf_libs() {
    ldd "$1" 2>/dev/null | awk '
        $2 == "=>" && $3 ~ /^\// { print $3; next }
        $1 ~ /^\// { print $1 }'
}

# Copy $1 into the staging tree $2 at absolute path $3, following symlinks.
stage_file() {
    local src=$1 root=$2 dst=$3
    mkdir -p "$root$(dirname "$dst")"
    cp -L --preserve=mode "$src" "$root$dst"
}

# Copy the libraries every dynamic ELF under $2 needs into $2 (same absolute path
# as on the host).  Libraries already present in the optional base tree $3 are skipped.
stage_libs_for_tree() {
    local root=$1 base=${2:-} f lib
    while IFS= read -r -d '' f; do
        is_dynamic_elf "$f" || continue
        while IFS= read -r lib; do
            [ -e "$root$lib" ] && continue
            [ -n "$base" ] && [ -e "$base$lib" ] && continue
            stage_file "$lib" "$root" "$lib"
        done < <(elf_libs "$f")
    done < <(find "$root" -type f -perm /111 -print0)
}

# Where the base tree $2 has a symlink for a directory of the staging tree $1 (merged
# /usr: bin -> usr/bin, lib -> usr/lib ...), move the staged files to the link's target:
# a directory entry in the overlay archive would replace the base's symlink.
rebase_on_symlinks() {
    local stage=$1 base=$2 d rel link tgt moved=1
    while [ $moved = 1 ]; do
        moved=0
        while IFS= read -r d; do
            rel=${d#"$stage"}
            [ -L "$base$rel" ] || continue
            link=$(readlink "$base$rel")
            case $link in
                /*) tgt=$link ;;
                *) tgt=$(realpath -m -s "$(dirname "$rel")/$link") ;;
            esac
            mkdir -p "$stage$tgt"
            cp -a "$d/." "$stage$tgt/"
            rm -rf "$d"
            moved=1; break
        done < <(find "$stage" -mindepth 1 -type d | LC_ALL=C sort)
    done
}

# Pack the staging tree $1 into the newc cpio $2 (owned by root, atomic), compressed
# with gzip -1 unless $3 is "none".
pack_cpio() {
    local root=$1 out=$2 z=${3:-gzip}
    chmod 755 "$root"
    (cd "$root" && find . -mindepth 1 | LC_ALL=C sort | cpio --quiet -o -H newc -R 0:0) \
        | if [ "$z" = none ]; then cat; else gzip -1; fi > "$out.tmp.$$"
    mv -f "$out.tmp.$$" "$out"
}

# Parse a "HOST[:GUEST]" argument; GUEST defaults to $2/<basename>, a relative GUEST
# is taken under $2 and a GUEST ending in "/" gets the basename appended.
# Sets SPEC_HOST and SPEC_GUEST.
parse_spec() {
    local spec=$1 defdir=$2
    if [[ $spec == *:* ]]; then SPEC_HOST=${spec%%:*}; SPEC_GUEST=${spec#*:}
    else SPEC_HOST=$spec; SPEC_GUEST=; fi
    [ -n "$SPEC_HOST" ] || die "empty host path in '$spec'"
    [ -e "$SPEC_HOST" ] || die "no such file: $SPEC_HOST (from '$spec')"
    SPEC_HOST=$(realpath "$SPEC_HOST")
    if [ -z "$SPEC_GUEST" ]; then SPEC_GUEST="$defdir/$(basename "$SPEC_HOST")"
    elif [[ $SPEC_GUEST != /* ]]; then SPEC_GUEST="$defdir/$SPEC_GUEST"; fi
    if [[ $SPEC_GUEST == */ ]]; then SPEC_GUEST="$SPEC_GUEST$(basename "$SPEC_HOST")"; fi
    return 0
}

# The prepared kernel: sets KVER, VMLINUZ, VMLINUX, KERNEL_IMG, KMOD_DIR (modules), KROOT.
# shellcheck disable=SC2034,SC2153  # the variables come from the env file
load_kernel_env() {
    [ -f "$CACHE/kernel/env" ] || return 1
    # shellcheck disable=SC1091
    . "$CACHE/kernel/env"
    [ "${KFORMAT:-}" = "$CACHE_FORMAT" ] || return 1
    [ -f "$VMLINUZ" ] && [ -d "$KMOD_DIR" ] || return 1
    # What -kernel gets: the ELF vmlinux (PVH boot) unless GYROCOMP_VM_BZIMAGE=1.
    KERNEL_IMG=$VMLINUZ
    if [ -n "${VMLINUX:-}" ] && [ -f "$VMLINUX" ] && [ "${GYROCOMP_VM_BZIMAGE:-0}" != 1 ]; then
        KERNEL_IMG=$VMLINUX
    fi
}

# Console stream filter: strip CRs, save everything to $1, show all but collect blocks.
console_filter() {
    awk -v logf="$1" -v b="$MARK_COLLECT_BEGIN " -v e="$MARK_COLLECT_END " '
        { gsub(/\r/, ""); print > logf; fflush(logf) }
        index($0, b) == 1 { skip = 1; next }
        index($0, e) == 1 { skip = 0; next }
        !skip { print; fflush() }'
}

# Extract the collected files from a console log $1.  Each remaining argument is
# "IDX:HOSTPATH".  Returns non-zero if a file is missing or corrupted.
extract_collected() {
    local logf=$1; shift
    local spec idx dst bad=0 tmp
    for spec in "$@"; do
        idx=${spec%%:*}; dst=${spec#*:}
        tmp=$(mktemp)
        # Lines strictly between BEGIN idx and END idx; END carries the guest's size.
        awk -v b="$MARK_COLLECT_BEGIN $idx" -v e="$MARK_COLLECT_END $idx" '
            $0 == b { on = 1; next }
            index($0, e " ") == 1 { on = 0; next }
            on { print }' "$logf" > "$tmp"
        local want
        want=$(awk -v e="$MARK_COLLECT_END $idx " 'index($0, e) == 1 { print $NF }' "$logf" | tail -n 1)
        if [ -z "$want" ] || [ "$want" = missing ]; then
            log "collect: guest file #$idx for $dst was not found in the guest"
            bad=1
        else
            mkdir -p "$(dirname "$dst")"
            if base64 -d -i < "$tmp" > "$dst" 2>/dev/null && [ "$(stat -c %s "$dst")" = "$want" ]; then
                log "collected $dst ($want bytes)"
            else
                log "collect: $dst is corrupt (expected $want bytes, got $(stat -c %s "$dst" 2>/dev/null || echo 0))"
                bad=1
            fi
        fi
        rm -f "$tmp"
    done
    return $bad
}

# A POSIX sh snippet (for the guests) that prints each file listed in the file
# $1 (lines "IDX GUESTPATH") base64-encoded between marker lines.
guest_collect_snippet() {
    cat <<EOF
if [ -f "$1" ]; then
  while read -r idx path; do
    [ -n "\$idx" ] || continue
    echo "$MARK_COLLECT_BEGIN \$idx"
    if [ -f "\$path" ]; then
      base64 "\$path"
      echo "$MARK_COLLECT_END \$idx \$(wc -c < "\$path")"
    else
      echo "$MARK_COLLECT_END \$idx missing"
    fi
  done < "$1"
fi
EOF
}
