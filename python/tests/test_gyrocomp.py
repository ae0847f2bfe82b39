"""The Python package against the CLI it binds (same tree, same log), and
its own contracts: batch = loop, state round trip, bad input raises."""

import io
import json
import math
import pathlib
import zlib

import numpy as np
import pytest

import gyrocomp
from conftest import run, ticks_during

# the CSV's printed decimals per column (src/replay.rs write_csv_row)
DECIMALS = {"t": 6, "roll": 4, "pitch": 4, "yaw": 4, "rate_x": 4, "rate_y": 4, "rate_z": 4,
            "bias_x": 6, "bias_y": 6, "bias_z": 6, "mode": None, "temp": 3,
            "invalid": None}


def cli_csv(cli, log, tmp_path, config=None):
    out = tmp_path / "est.csv"
    cmd = [cli, "replay", "--input", log, "--csv", out]
    if config:
        cmd += ["--config", config]
    run(cmd)
    return out.read_text()


def csv_text(r):
    """The CLI's CSV, formatted from the package's arrays."""
    lines = [",".join(gyrocomp.CSV_COLUMNS)]
    for i in range(len(r["t"])):
        cells = []
        for k in gyrocomp.CSV_COLUMNS:
            d = DECIMALS[k]
            cells.append(str(int(r[k][i])) if d is None else f"{r[k][i]:.{d}f}")
        lines.append(",".join(cells))
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------ replay

def test_replay_equals_cli_csv_column_by_column(cli, road_log, tmp_path):
    text = cli_csv(cli, road_log, tmp_path)
    header, *_ = text.splitlines()
    assert header.split(",") == list(gyrocomp.CSV_COLUMNS)
    ref = np.genfromtxt(io.StringIO(text), delimiter=",", names=True)
    r = gyrocomp.replay(road_log)
    assert len(r["t"]) == len(ref) > 8000
    for k, d in DECIMALS.items():
        got = np.asarray(r[k], dtype=float)
        if d is None:
            np.testing.assert_array_equal(got, ref[k], err_msg=k)
        else:
            # the CSV rounds to d decimals: equal within half its last digit
            np.testing.assert_allclose(got, ref[k], rtol=0, atol=0.5 * 10.0**-d + 1e-12, err_msg=k)
    # and printed as the CLI prints them, the same text
    assert csv_text(r) == text


def test_replay_bytes_path_and_file_object_are_equal(road_log):
    a = gyrocomp.replay(road_log)
    b = gyrocomp.replay(road_log.read_bytes())
    c = gyrocomp.replay(str(road_log))
    with open(road_log, "rb") as f:
        d = gyrocomp.replay(f)
    for other in (b, c, d):
        assert other.keys() == a.keys()
        for k in a:
            if k == "summary":
                assert other[k]["input"] == a[k]["input"]
            else:
                np.testing.assert_array_equal(other[k], a[k], err_msg=k)


def test_replay_summary_counts(road_log):
    r = gyrocomp.replay(road_log)
    s = r["summary"]
    assert s["input"]["samples"] == len(r["t"])
    assert s["bad_lines"] == 0
    assert "samples" in s["text"]


def test_replay_with_config_equals_cli(cli, road_log, tmp_path):
    cfg = tmp_path / "paper.toml"
    cfg.write_text('[estimator]\nmode = "paper"\n')
    text = cli_csv(cli, road_log, tmp_path, config=cfg)
    assert csv_text(gyrocomp.replay(road_log, config=cfg)) == text
    # the same config given as text
    assert csv_text(gyrocomp.replay(road_log, config=cfg.read_text())) == text
    # and it is not the default's output
    assert csv_text(gyrocomp.replay(road_log)) != text


def test_replay_garbage_counts_bad_lines_and_bad_paths_raise(tmp_path):
    r = gyrocomp.replay(b"not a candump line\n\x00\xff\n")
    assert len(r["t"]) == 0 and r["summary"]["bad_lines"] == 2
    with pytest.raises(OSError, match="nope.log"):
        gyrocomp.replay(tmp_path / "nope.log")
    with pytest.raises(TypeError, match="log"):
        gyrocomp.replay(12)


def test_replay_chunks_concatenate_to_replay(road_log):
    a = gyrocomp.replay(road_log)
    for src in (road_log, road_log.read_bytes()):
        it = gyrocomp.replay_chunks(src, rows=1000)
        assert it.summary is None
        chunks = list(it)
        assert [len(c["t"]) for c in chunks] == [1000] * 8 + [193]
        for k in a:
            if k != "summary":
                np.testing.assert_array_equal(np.concatenate([c[k] for c in chunks]), a[k], err_msg=k)
        assert it.summary["input"] == a["summary"]["input"] and it.summary["text"] == a["summary"]["text"]
    # left early: the replay thread stops, nothing hangs
    it = gyrocomp.replay_chunks(road_log, rows=10)
    first = next(it)
    assert len(first["t"]) == 10
    del it
    with pytest.raises(ValueError, match="rows = 0"):
        gyrocomp.replay_chunks(road_log, rows=0)


# ------------------------------------------------------------------ estimator

@pytest.fixture(scope="module")
def samples(road_log):
    d = gyrocomp.read_log(road_log)
    assert (d["steps"][1:] == 1).all() and (d["diag"] == 0).all()
    return d


def batch(e, d, sl=slice(None), t=True):
    return e.update_batch(d["gyr"][sl], d["acc"][sl], d["mag"][sl], d["temp"][sl], d["t"][sl] if t else None)


def test_update_batch_on_the_logs_samples_equals_replay(road_log, samples):
    r = gyrocomp.replay(road_log)
    b = batch(gyrocomp.Estimator(samples["rate_hz"]), samples)
    np.testing.assert_array_equal(b["t"], r["t"])
    for c, k in enumerate(["roll", "pitch", "yaw"]):
        np.testing.assert_array_equal(b["euler"][:, c], r[k], err_msg=k)
    for c, ax in enumerate("xyz"):
        np.testing.assert_array_equal(b["rate"][:, c], r[f"rate_{ax}"])
        np.testing.assert_array_equal(b["bias"][:, c], r[f"bias_{ax}"])
    np.testing.assert_array_equal(b["mode"], r["mode"])
    np.testing.assert_array_equal(b["flags"], r["flags"])


def test_update_batch_shapes_and_types(samples):
    n = 500
    b = batch(gyrocomp.Estimator(204.8), samples, slice(0, n))
    shapes = {"quaternion": (n, 4), "euler": (n, 3), "rate": (n, 3), "bias": (n, 3), "bias_sigma": (n, 3),
              "rest": (n,), "mode": (n,), "flags": (n,), "t": (n,)}
    assert {k: v.shape for k, v in b.items()} == shapes
    assert b["rest"].dtype == np.bool_ and b["mode"].dtype == np.uint8 and b["flags"].dtype == np.uint16
    assert np.isfinite(b["bias_sigma"]).all() and (b["bias_sigma"] > 0).all()
    np.testing.assert_array_equal(b["rest"], (b["flags"] & gyrocomp.FLAGS["STANDSTILL"]) != 0)


def test_update_batch_equals_a_loop_of_update(samples):
    n = 1500
    b = batch(gyrocomp.Estimator(204.8), samples, slice(0, n))
    e = gyrocomp.Estimator(204.8)
    rows = [e.update(samples["gyr"][i], samples["acc"][i], samples["mag"][i], samples["temp"][i],
                     dt=None if i == 0 else samples["t"][i] - samples["t"][i - 1]) for i in range(n)]
    for k in ["quaternion", "euler", "rate", "bias", "bias_sigma", "rest", "mode", "flags", "t"]:
        np.testing.assert_array_equal(np.array([getattr(r, k) for r in rows]), b[k], err_msg=k)
    # split into batches, with and without times: the same
    e2 = gyrocomp.Estimator(204.8)
    parts = [batch(e2, samples, slice(0, 700)), batch(e2, samples, slice(700, 701), t=False), batch(e2, samples, slice(701, n))]
    for k in b:
        np.testing.assert_array_equal(np.concatenate([p[k] for p in parts]), b[k], err_msg=k)


def test_quaternion_is_the_euler_angles(samples):
    b = batch(gyrocomp.Estimator(204.8), samples, slice(0, 3000))
    w, x, y, z = b["quaternion"].T
    np.testing.assert_allclose(np.linalg.norm(b["quaternion"], axis=1), 1, atol=1e-12)
    roll = np.degrees(np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y)))
    pitch = np.degrees(np.arcsin(np.clip(2 * (w * y - z * x), -1, 1)))
    yaw = np.degrees(np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))
    np.testing.assert_allclose(np.stack([roll, pitch, yaw], 1), b["euler"], atol=1e-6)


def test_gaps_in_t_are_resyncs(samples):
    t = samples["t"][:400].copy()
    t[200:] += 5.0  # 5 s gap, beyond max_gap_s
    e = gyrocomp.Estimator(204.8)
    b = e.update_batch(samples["gyr"][:400], samples["acc"][:400], t=t)
    resync = (b["flags"] & gyrocomp.FLAGS["RESYNC"]) != 0
    assert resync[200] and not resync[:200].any()


# ------------------------------------------------------------------ state

def envelope(text):
    env = json.loads(text)
    assert zlib.crc32(env["state"].encode()) == env["crc32"]
    return json.loads(env["state"])


def test_state_round_trip_in_the_daemons_format(samples):
    e = gyrocomp.Estimator(204.8)
    assert e.state is None  # nothing learned yet
    batch(e, samples)
    text = e.state
    st = envelope(text)
    assert st["version"] == 1 and set(st) >= {"bias", "bias_sigma", "temp", "saved_unix", "slope"}
    np.testing.assert_allclose(st["bias"], batch(gyrocomp.Estimator(204.8), samples)["bias"][-1], atol=0.05)

    e2 = gyrocomp.Estimator(204.8)
    e2.state = text
    st2 = envelope(e2.state)
    # to the bit (serde_json's float_roundtrip: its default parser was 1 ulp off)
    assert st2["bias"] == st["bias"]
    assert st2["temp"] == st["temp"] and st2["slope"] == st["slope"]
    # the sigma grows with the state's age (bias walk), never shrinks
    assert all(b >= a for a, b in zip(st["bias_sigma"], st2["bias_sigma"]))
    # bytes work too, and the restored estimator starts from that bias, not the config's
    e3 = gyrocomp.Estimator(204.8)
    e3.state = text.encode()
    first = e3.update(samples["gyr"][0], samples["acc"][0], samples["mag"][0], st["temp"])
    fresh = gyrocomp.Estimator(204.8).update(samples["gyr"][0], samples["acc"][0], samples["mag"][0], st["temp"])
    np.testing.assert_allclose(first.bias, st["bias"], atol=1e-9)
    assert first.bias != fresh.bias
    assert not np.allclose(fresh.bias, st["bias"], atol=1e-3)
    # None restarts from the config
    e3.state = None
    assert e3.state is None and not e3.started


def test_state_refuses_a_corrupt_file(samples):
    e = gyrocomp.Estimator(204.8)
    batch(e, samples, slice(0, 3000))
    text = e.state
    env = json.loads(text)
    env["state"] = env["state"].replace('"temp":', '"temp":1', 1)
    with pytest.raises(ValueError, match="CRC"):
        e.state = json.dumps(env)
    with pytest.raises(ValueError, match="corrupt"):
        e.state = text[: len(text) // 2]
    with pytest.raises(TypeError):
        e.state = 3.5
    assert e.state == text or envelope(e.state)["bias"] == envelope(text)["bias"]  # unchanged


# ------------------------------------------------------------------ bad input

@pytest.mark.parametrize("kw, exc, msg", [
    (dict(gyr=np.zeros((5, 4))), ValueError, r"gyr: expected shape \(N, 3\), got \[5, 4\]"),
    (dict(acc=np.zeros((4, 3))), ValueError, "acc: 4 rows, gyr has 5"),
    (dict(mag=np.zeros(5)), ValueError, r"mag: expected shape \(N, 3\)"),
    (dict(temp=np.zeros((5, 1))), ValueError, r"temp: expected shape \(N,\)"),
    (dict(gyr="abc"), TypeError, "gyr: cannot be read as float64"),
    (dict(t=np.array([0, 1, 2, 2, 3]) / 204.8), ValueError, r"t\[3\].*t must increase"),
    (dict(t=np.array([0, 1, 2, np.nan, 3]) / 204.8), ValueError, r"t\[3\] is nan"),
])
def test_update_batch_bad_shapes_raise_naming_the_argument(kw, exc, msg):
    n = 5
    args = dict(gyr=np.zeros((n, 3)), acc=np.tile([0, 0, -1.0], (n, 1)), mag=None, temp=None, t=None)
    args.update(kw)
    with pytest.raises(exc, match=msg):
        gyrocomp.Estimator(204.8).update_batch(**args)


@pytest.mark.parametrize("arg, col, value, msg", [
    ("gyr", 1, np.nan, r"gyr\[7, 1\] is nan"),
    ("acc", 2, np.inf, r"acc\[7, 2\] is inf"),
    ("gyr", 0, 5000.0, r"gyr\[7, 0\] = 5000 deg/s is outside -1310.72\.\.1310.72 deg/s"),
    ("acc", 0, -40.0, r"acc\[7, 0\] = -40 g is outside"),
    ("mag", 2, 9.0, r"mag\[7, 2\] = 9 gauss is outside"),
    ("temp", None, 500.0, r"temp\[7\] = 500 deg C is outside -60\.\.150 deg C"),
])
def test_bad_values_raise_naming_row_and_column_and_change_nothing(samples, arg, col, value, msg):
    sl = slice(0, 50)
    d = {k: samples[k][sl].copy() for k in ("gyr", "acc", "mag", "temp")}
    if col is None:
        d[arg][7] = value
    else:
        d[arg][7, col] = value
    e = gyrocomp.Estimator(204.8)
    batch(e, samples, slice(0, 10), t=False)
    with pytest.raises(ValueError, match=msg):
        e.update_batch(**d)
    # the estimator did not step: it goes on as if the bad batch never came
    ref = gyrocomp.Estimator(204.8)
    batch(ref, samples, slice(0, 10), t=False)
    a = batch(e, samples, slice(10, 20), t=False)
    b = batch(ref, samples, slice(10, 20), t=False)
    for k in a:
        np.testing.assert_array_equal(a[k], b[k])


def test_update_bad_input_raises():
    e = gyrocomp.Estimator(204.8)
    with pytest.raises(ValueError, match="gyr: expected 3 values, got 2"):
        e.update([0, 0], [0, 0, -1])
    with pytest.raises(ValueError, match=r"acc\[2\] is nan"):
        e.update([0, 0, 0], [0, 0, math.nan])
    with pytest.raises(ValueError, match="dt = 0"):
        e.update([0, 0, 0], [0, 0, -1], dt=0.0)
    with pytest.raises(TypeError, match="mag"):
        e.update([0, 0, 0], [0, 0, -1], mag="x")
    assert not e.started


@pytest.mark.parametrize("rate, config, exc, msg", [
    (0.0, None, ValueError, "rate_hz = 0"),
    (math.nan, None, ValueError, "rate_hz = nan"),
    (204.8, "[estimator]\nmode = \"bogus\"\n", ValueError, "config"),
    (204.8, "[switching]\ninner = [0.99, 1.3]\n", ValueError, "line 2.*switching.inner"),
    (204.8, "/nonexistent/gyrocomp.toml", OSError, "nonexistent"),
    (204.8, 3, TypeError, "config"),
])
def test_bad_rate_and_config_raise(rate, config, exc, msg):
    with pytest.raises(exc, match=msg):
        gyrocomp.Estimator(rate, config)


def test_config_path_and_text_are_the_same(tmp_path):
    p = tmp_path / "c.toml"
    p.write_text('[estimator]\nmode = "paper"\n')
    a, b, c = gyrocomp.Estimator(204.8, p), gyrocomp.Estimator(204.8, str(p)), gyrocomp.Estimator(204.8, p.read_text())
    assert a.config == b.config == c.config != gyrocomp.Estimator(204.8).config
    assert 'mode = "paper"' in a.config


# ------------------------------------------------------------------ GIL

def test_long_calls_release_the_gil(samples):
    """Another Python thread runs while update_batch works: with the GIL
    held it could run only at a switch (every 5 ms) just before or after.
    The batch grows until one call lasts at least 0.2 s, whatever the
    machine's speed (a fixed batch ran 0.049 s on an idle machine)."""
    for reps in (16, 64, 256, 1024):
        big = {k: np.concatenate([samples[k]] * reps) for k in ("gyr", "acc", "mag", "temp")}
        e = gyrocomp.Estimator(204.8)
        t0, t1, inside = ticks_during(lambda: e.update_batch(**big))
        if t1 - t0 >= 0.2:
            break
    assert t1 - t0 >= 0.2, f"the call is too short to tell ({t1 - t0:.3f} s for {reps} copies)"
    assert len(inside) > 100


# ------------------------------------------------------------------ calibrate

@pytest.fixture(scope="module")
def chamber_runs(cli, tmp_path_factory):
    d = tmp_path_factory.mktemp("chamber")
    runs = []
    for seed in (1, 2, 3):
        out = d / f"run{seed}"
        run([cli, "simulate", "--scenario", "chamber", "--seed", seed, "--duration", 900, "--out", out])
        runs.append(out / "imu.log")
    return runs


def test_calibrate_equals_cli(cli, chamber_runs, tmp_path):
    toml = tmp_path / "thermal.toml"
    p = run([cli, "calibrate", "--order", 2, "--write", toml, "--input", *chamber_runs])
    c = gyrocomp.calibrate(chamber_runs, order=2)
    assert p.stdout.startswith(c["report"]) and "p1 = " in c["report"]
    assert toml.read_text() == c["toml"]
    assert c["coeffs"].shape == c["ci"].shape == (3, 2) and c["order"] == 2
    assert [r["name"] for r in c["runs"]] == [str(r) for r in chamber_runs]
    # bytes and file objects give the same fit
    with open(chamber_runs[2], "rb") as f:
        b = gyrocomp.calibrate([chamber_runs[0].read_bytes(), chamber_runs[1], f], order=2)
    np.testing.assert_array_equal(b["coeffs"], c["coeffs"])
    np.testing.assert_array_equal(b["ci"], c["ci"])


def test_calibrate_bad_input_raises(chamber_runs):
    with pytest.raises(ValueError, match="order = 4"):
        gyrocomp.calibrate(chamber_runs, order=4)
    with pytest.raises(ValueError, match="no run"):
        gyrocomp.calibrate([])
    with pytest.raises(TypeError, match="list of logs"):
        gyrocomp.calibrate(str(chamber_runs[0]))
    with pytest.raises(ValueError, match=r"runs\[1\]"):
        gyrocomp.calibrate([chamber_runs[0], b"garbage\n" * 100])
