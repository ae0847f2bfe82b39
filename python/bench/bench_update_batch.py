"""Bench (not a test): `Estimator.update_batch` per sample against the Rust
`Estimator::step` alone on the same samples, in the same build.

    python python/bench/bench_update_batch.py [LOG ...]

Default: tests/data/road-40s.log (the default filter's power-on speed
hypotheses run all through it: no standstill) and, when the gyrocomp binary
is found (GYROCOMP_BIN, CARGO_TARGET_DIR/release, target/release), a 300 s
simulated static run (`gyrocomp simulate --scenario static`), where the bank
ends at the first standstill and the steady-state step is measured. Each
case: the best of 15 alternating runs of each, in this thread's CPU time
(time.thread_time; the Rust loop reads the same clock), so that other work
on a shared machine is not counted.
"""

import os
import pathlib
import subprocess
import sys
import tempfile
import time

import gyrocomp
import gyrocomp._gyrocomp as native

ROOT = pathlib.Path(__file__).resolve().parents[2]


def binary():
    for c in (os.environ.get("GYROCOMP_BIN"),
              os.environ.get("CARGO_TARGET_DIR") and os.path.join(os.environ["CARGO_TARGET_DIR"], "release", "gyrocomp"),
              ROOT / "target" / "release" / "gyrocomp"):
        if c and os.path.isfile(c):
            return c
    return None


def case(name, log, reps=15):
    d = gyrocomp.read_log(log)
    n = len(d["t"])
    args = (d["gyr"], d["acc"], d["mag"], d["temp"])
    best_b = best_s = float("inf")
    for _ in range(reps):
        e = gyrocomp.Estimator(d["rate_hz"])
        t0 = time.thread_time()
        e.update_batch(*args, d["t"])
        best_b = min(best_b, time.thread_time() - t0)
        best_s = min(best_s, native._bench_step(d["rate_hz"], *args))
    b, s = best_b / n * 1e9, best_s / n * 1e9
    print(f"{name}: {n} samples: update_batch {b:.1f} ns/sample, Rust step {s:.1f} ns/sample, ratio {b / s:.3f}")
    return b / s


def main():
    logs = [(pathlib.Path(p).name, p) for p in sys.argv[1:]]
    with tempfile.TemporaryDirectory() as tmp:
        if not logs:
            logs.append(("road-40s.log (power-on hypotheses all through)", ROOT / "tests" / "data" / "road-40s.log"))
            exe = binary()
            if exe:
                subprocess.run([exe, "simulate", "--scenario", "static", "--seed", "1", "--out", tmp],
                               check=True, capture_output=True)
                logs.append(("simulated static 300 s (steady state after the first standstill)", os.path.join(tmp, "imu.log")))
            else:
                print("(no gyrocomp binary: the simulated steady-state case is skipped)")
        for name, log in logs:
            case(name, log)


if __name__ == "__main__":
    main()
