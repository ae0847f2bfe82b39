"""Fixtures: the repository's road log and the `gyrocomp` binary built from
the same tree (its `replay --csv` and `calibrate` are what the package must
equal). GYROCOMP_BIN names the binary; else CARGO_TARGET_DIR/release or
target/release. A missing binary fails the tests that need it: build it
with `cargo build --release`.
"""

import os
import pathlib
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
ROAD = ROOT / "tests" / "data" / "road-40s.log"


@pytest.fixture(scope="session")
def road_log():
    assert ROAD.is_file(), f"{ROAD} is missing"
    return ROAD


@pytest.fixture(scope="session")
def cli():
    cands = []
    if os.environ.get("GYROCOMP_BIN"):
        cands.append(pathlib.Path(os.environ["GYROCOMP_BIN"]))
    else:
        tgt = os.environ.get("CARGO_TARGET_DIR")
        if tgt:
            cands.append(pathlib.Path(tgt) / "release" / "gyrocomp")
        cands.append(ROOT / "target" / "release" / "gyrocomp")
    for c in cands:
        if c.is_file():
            return c
    pytest.fail(f"the gyrocomp binary was not found at {', '.join(map(str, cands))}: "
                "build it with `cargo build --release` or set GYROCOMP_BIN")


def run(cmd, **kw):
    """Run a command; on failure show its stderr."""
    p = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, **kw)
    assert p.returncode == 0, f"{cmd} failed ({p.returncode}):\n{p.stderr}"
    return p


def ticks_during(call):
    """Run `call()` while another Python thread stamps the clock as fast as
    it can: (t0, t1, stamps inside the call's 15-ms-trimmed span). With the
    GIL held by the call, that thread could run only at a switch (every
    5 ms) just before or after."""
    import threading
    import time
    stamps = []
    done = threading.Event()

    def count():
        while not done.is_set():
            stamps.append(time.perf_counter())

    th = threading.Thread(target=count)
    th.start()
    try:
        t0 = time.perf_counter()
        call()
        t1 = time.perf_counter()
    finally:
        done.set()
        th.join()
    return t0, t1, [s for s in stamps if t0 + 0.015 < s < t1 - 0.015]
