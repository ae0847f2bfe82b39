"""A simulated fleet for the fleet tests and the bench: `gyrocomp simulate`
runs of the urban scenario, one per unit, day and power cycle, each unit with its own
hidden thermal slopes p1 (drawn by the simulator: Table 1's times 0.5..1.5,
random sign per axis) and a new turn-on bias every power cycle (`<day>.log`, `<day>-1.log`, ...).

How: day 0's run of a unit draws its sensor model (`sensor.toml`); every power cycle
then runs `--model` with that model, its turn-on bias replaced by its own
(uniform +-5 deg/s per axis, the urban range) and without the warm-up
transient (a log-start effect the per-cycle fit does not model), at its own
seed (motion, ambient temperature, noise). `--ranges` makes the self-heating
fast (15-25 deg C, tau 150-300 s), so a short log has standstills several
degrees apart.
"""

from __future__ import annotations

import concurrent.futures as cf
import pathlib
import random
import re
import shutil
import socket
import subprocess
import tomllib
from typing import Dict, List, Optional, Tuple

RANGES = """\
self_heating = [15.0, 25.0]
heating_tau_s = [150.0, 300.0]
"""

#: The fleet job's config for these units (the simulator's mounting; no
#: thermal curve: the fleet does not know each unit's).
FLEET_CONFIG = """\
[input]
profile = "adis16448"

[mounting]
rotation = [0.0, 0.0, 0.0]
lever_arm = [0.9, 0.0, 0.0]
"""


def _fmt(v: List[float]) -> str:
    return "[" + ", ".join(repr(float(x)) for x in v) + "]"


def unit_model(base: str, turn_on: List[float], p1_scale: Optional[List[float]] = None) -> str:
    """sensor.toml text with the turn-on bias replaced (and p1 scaled per
    axis if asked), the warm-up transient removed."""
    out, section = [], ""
    for line in base.splitlines():
        m = re.match(r"^\[(.+)\]\s*$", line)
        if m:
            section = m[1]
        if section == "gyro.warmup_transient":
            continue
        if section == "gyro" and line.startswith("effects"):
            line = line.replace('"warmup_transient", ', "").replace(', "warmup_transient"', "")
        if section == "gyro.turn_on_bias" and line.startswith("bias"):
            line = f"bias = {_fmt(turn_on)}"
        if section == "gyro.thermal_linear" and line.startswith("p1") and p1_scale is not None:
            p1 = tomllib.loads(line)["p1"]
            line = f"p1 = {_fmt([v * k for v, k in zip(p1, p1_scale)])}"
        out.append(line)
    return "\n".join(out) + "\n"


def simulate(binary: pathlib.Path, out: pathlib.Path, seed: int, duration: float,
             model: Optional[pathlib.Path] = None, ranges: Optional[pathlib.Path] = None) -> None:
    cmd = [str(binary), "simulate", "--scenario", "urban", "--seed", str(seed), "--duration", str(duration),
           "--out", str(out)]
    if model:
        cmd += ["--model", str(model)]
    if ranges:
        cmd += ["--ranges", str(ranges)]
    p = subprocess.run(cmd, capture_output=True, text=True)
    assert p.returncode == 0, f"{cmd}: {p.stderr}"


def make_unit(binary: pathlib.Path, work: pathlib.Path, unit: int, days: int, duration: float,
              p1_scale: Optional[List[float]] = None, seed0: int = 1000, cycles: int = 1) -> Tuple[str, List[float], Dict[str, pathlib.Path]]:
    """One unit's logs: (unit name, hidden p1, {relative key: log path})."""
    name = f"unit-{unit:02d}"
    udir = work / name
    udir.mkdir(parents=True, exist_ok=True)
    ranges = udir / "ranges.toml"
    ranges.write_text(RANGES)
    simulate(binary, udir / "draw", seed0 + 100 * unit, 1.0, ranges=ranges)
    base = (udir / "draw" / "sensor.toml").read_text()
    shutil.rmtree(udir / "draw")
    rng = random.Random(seed0 + unit)
    logs = {}
    p1 = None
    for d in range(days):
        for c in range(cycles):
            turn_on = [rng.uniform(-5.0, 5.0) for _ in range(3)]
            model = udir / f"model-{d}-{c}.toml"
            model.write_text(unit_model(base, turn_on, p1_scale))
            p1 = tomllib.loads(model.read_text())["gyro"]["thermal_linear"]["p1"]
            run = udir / f"day{d}-{c}"
            simulate(binary, run, seed0 + 100 * unit + cycles * d + c + 1, duration, model=model, ranges=ranges)
            log = udir / (f"2026-11-{d + 1:02d}" + (f"-{c}" if c else "") + ".log")
            (run / "imu.log").rename(log)
            shutil.rmtree(run)
            logs[f"{name}/{log.name}"] = log
    assert p1 is not None
    return name, list(p1), logs


def make_fleet(binary: pathlib.Path, work: pathlib.Path, units: int = 20, days: int = 5, duration: float = 180.0,
               p1_scale: Optional[Dict[int, List[float]]] = None, threads: int = 2, cycles: int = 1):
    """The fleet: ({unit: hidden p1}, {relative key: log path}), units made
    `threads` at a time; `p1_scale` scales a unit's drawn slopes (an outlier)."""
    hidden: Dict[str, List[float]] = {}
    logs: Dict[str, pathlib.Path] = {}
    with cf.ThreadPoolExecutor(threads) as ex:
        futs = [ex.submit(make_unit, binary, work, u, days, duration, (p1_scale or {}).get(u), 1000, cycles) for u in range(units)]
        for f in futs:
            name, p1, ls = f.result()
            hidden[name] = p1
            logs.update(ls)
    return hidden, dict(sorted(logs.items()))


def free_port() -> int:
    """A free port p with p + 10000 free too (SeaweedFS's gRPC port)."""
    for _ in range(200):
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            p = s.getsockname()[1]
        if p + 10000 > 65535:
            continue
        with socket.socket() as s2:
            try:
                s2.bind(("127.0.0.1", p + 10000))
            except OSError:
                continue
        return p
    raise RuntimeError("no free port pair")
