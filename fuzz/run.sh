#!/usr/bin/env bash
# Fuzz every target for a bounded time: `bash fuzz/run.sh [SECONDS_PER_TARGET] [TARGET...]`
# (default 60 s each, all targets). Installs cargo-fuzz when it is missing,
# seeds the corpora from the project's files (fuzz/seed.py), and stops at the
# first crash with its input in fuzz/artifacts/<target>/ (exit status non-zero).
# Without a sanitizer (the code under test is safe Rust) but with debug
# assertions and overflow checks.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
secs=${1:-60}
shift || true
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
    targets=(candump_line line_reader adis_assembler pipeline config dbc csv_import reference_csv truth_csv gap_model)
fi
if ! command -v cargo-fuzz >/dev/null; then
    echo "[fuzz] installing cargo-fuzz"
    cargo install --locked cargo-fuzz
fi
# libFuzzer needs a nightly compiler; the stable one accepts its flags with
# RUSTC_BOOTSTRAP when no nightly toolchain is installed.
if rustup toolchain list 2>/dev/null | grep -q '^nightly'; then
    fuzz=(cargo +nightly fuzz)
else
    export RUSTC_BOOTSTRAP=1
    fuzz=(cargo fuzz)
fi
python3 fuzz/seed.py
log=$(mktemp)
trap 'rm -f "$log"' EXIT
for t in "${targets[@]}"; do
    echo "[fuzz] $t for ${secs} s"
    rc=0
    "${fuzz[@]}" run --sanitizer none --debug-assertions "$t" -- -max_total_time="$secs" -max_len=8192 -print_final_stats=1 >"$log" 2>&1 || rc=$?
    grep -E '^(INFO: seed corpus|#[0-9]+ +DONE|stat::number_of_executed_units|stat::average_exec_per_sec|Done [0-9]+ runs)' "$log" || true
    if [ "$rc" -ne 0 ]; then
        tail -n 40 "$log"
        echo "[fuzz] $t: CRASH (exit $rc), input in fuzz/artifacts/$t/"
        exit 1
    fi
done
echo "[fuzz] no crash in ${#targets[@]} targets, ${secs} s each"
