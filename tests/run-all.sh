#!/usr/bin/env bash
# The whole test suite, as README says: installs what the tests need when it is
# missing (python cantools, h5py, numpy, mcap and mcap-ros2-support; qemu, busybox, can-utils and a Debian kernel with the
# CAN modules for the vcan VM; debootstrap for the systemd VM), then runs
# `cargo test --release` (unit, integration, property, vcan and systemd tests)
# and builds the benchmarks; then the Python package's wheel and its pytest
# suite (python/ci.sh, which installs maturin, pytest and numpy in a venv).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

if ! python3 -c "import cantools" 2>/dev/null; then
    echo "[run-all] installing python cantools"
    python3 -m pip install --quiet --disable-pip-version-check cantools
fi
if ! python3 -c "import h5py, numpy" 2>/dev/null; then
    echo "[run-all] installing python h5py and numpy (scripts/fetch-realdata's converter)"
    python3 -m pip install --quiet --disable-pip-version-check h5py numpy
fi
if ! python3 -c "import mcap, mcap_ros2.decoder" 2>/dev/null; then
    echo "[run-all] installing python mcap and mcap-ros2-support (the reader and CDR decoder tests/mcap.rs checks replay --mcap with)"
    python3 -m pip install --quiet --disable-pip-version-check mcap mcap-ros2-support
fi
echo "[run-all] preparing the vcan / systemd test harness"
bash tests/vm/prepare.sh

cargo build --release --all-targets
cargo test --release --test realdata -- --nocapture  # prints the real-data table, or "skipped: ../shared/realdata not found"
cargo test --release -- --test-threads=2
bash python/ci.sh
