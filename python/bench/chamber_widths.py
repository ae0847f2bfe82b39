"""The fleet's per-unit slope intervals beside those of one 90-min chamber
ramp of the same unit (docs/fleet.md prints what this prints).

    python python/bench/chamber_widths.py [--units 20]

For each unit of the test fleet (python/tests/fleet_sim.py, the same seeds:
the same hidden slopes as test_fleet.py's units): the field fit from its 10
logs (5 days x 2 power cycles of 180 s; `process_log` and the per-unit fit in
this process, no store, no engine), and `gyrocomp.calibrate` (the chamber fit,
GLS with a bias random walk) on one 5400-s `chamber` run simulated with the
same sensor model (cycle 0's turn-on bias, no warm-up transient). Prints the
95 % interval's full width per unit-axis and whether it holds the hidden p1.
"""

from __future__ import annotations

import argparse
import pathlib
import shutil
import sys
import tempfile
import tomllib

import numpy as np
import pyarrow as pa

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))
sys.path.insert(0, str(HERE))

from bench_fleet import binary  # noqa: E402
from fleet_sim import FLEET_CONFIG, make_unit  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--units", type=int, default=20)
    a = ap.parse_args()
    import gyrocomp
    from gyrocomp.fleet.core import PER_LOG, parse_key, process_log
    from gyrocomp.fleet.job import unit_tables

    gc = binary()
    work = pathlib.Path(tempfile.mkdtemp(prefix="chamber-widths-"))
    fw, cw, fin, cin = [], [], 0, 0
    try:
        print("unit axis   hidden p1 | fleet fit [95 %]          width  | chamber fit [95 %]        width")
        for u in range(a.units):
            scale = [1.0, 1.0, 8.0] if u == 19 else None  # the test fleet's outlier unit
            name, p1, logs = make_unit(gc, work, u, 5, 180.0, scale, 1000, 2)
            recs = [process_log(str(p), k, parse_key(k), "-", p.stat().st_size, FLEET_CONFIG) for k, p in logs.items()]
            per_unit, _, _ = unit_tables(pa.Table.from_pylist(recs, schema=PER_LOG), 1.0, 25.0)
            ch = work / name / "chamber"
            simulate_chamber(gc, ch, work / name / "model-0-0.toml", 5000 + u)
            cal = gyrocomp.calibrate([ch / "imu.log"], 1)
            hidden = tomllib.loads((work / name / "model-0-0.toml").read_text())["gyro"]["thermal_linear"]["p1"]
            assert np.allclose(hidden, p1)
            for j, (r, h) in enumerate(zip(per_unit.to_pylist(), p1)):
                c, ci = float(cal["coeffs"][j, 0]), float(cal["ci"][j, 0])
                fi, ci_in = r["slope_lo"] <= h <= r["slope_hi"], c - ci <= h <= c + ci
                fin += fi
                cin += ci_in
                fw.append(r["slope_hi"] - r["slope_lo"])
                cw.append(2 * ci)
                print(f"{name} {r['axis']} {h:+.5f} | {r['slope']:+.5f} [{r['slope_lo']:+.5f}, {r['slope_hi']:+.5f}] "
                      f"{fw[-1]:.5f}{'' if fi else ' OUT'} | {c:+.5f} [{c - ci:+.5f}, {c + ci:+.5f}] {cw[-1]:.5f}"
                      f"{'' if ci_in else ' OUT'}")
            shutil.rmtree(work / name)
        n = len(fw)
        print(f"fleet fit (10 logs of 180 s, 30 min in all): median width {np.median(fw):.5f} deg/s/C, "
              f"{fin}/{n} inside")
        print(f"one 90-min chamber ramp: median width {np.median(cw):.5f} deg/s/C, {cin}/{n} inside")
    finally:
        shutil.rmtree(work, ignore_errors=True)


def simulate_chamber(gc: pathlib.Path, out: pathlib.Path, model: pathlib.Path, seed: int) -> None:
    """One 90-min chamber run of the unit's model (the simulator's chamber
    ranges: ambient -10..50 deg C, 12-20 deg C of self-heating)."""
    import subprocess

    cmd = [str(gc), "simulate", "--scenario", "chamber", "--seed", str(seed), "--duration", "5400",
           "--model", str(model), "--out", str(out)]
    p = subprocess.run(cmd, capture_output=True, text=True)
    assert p.returncode == 0, f"{cmd}: {p.stderr}"


if __name__ == "__main__":
    main()
