"""The engine-neutral part of the fleet job: one log in, its results out.

`process_log` maps one log (a binary stream) to its per-log record; it knows
nothing of S3 or of the engine. `run_task` wraps it with the store (read the
log, write its result object) and turns any failure into an error record, so
an engine only has to call `run_task` on every task and collect what it
returns.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import hashlib
import io
import queue
import re
import threading
import traceback
import urllib.parse
from typing import IO, Any, Dict, List, Optional, Tuple

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from .. import _gyrocomp

#: `<unit>/<YYYY-MM-DD>[-N].log` under the logs prefix.
KEY_RE = re.compile(r"^(?P<unit>[^/]+)/(?P<day>\d{4}-\d{2}-\d{2})(?:-(?P<seq>\d+))?\.log$")

#: The drop causes of the replay summary, in its order.
DROPS = ["unknown_id", "wrong_dlc", "duplicate", "out_of_order", "partial", "checksum"]

#: A log with more than this fraction of unreadable lines is a failed log.
MAX_BAD_FRACTION = 0.01

AXES = ("x", "y", "z")


class LogError(Exception):
    """A log that gives no result: the message names the log and the cause."""


class TransientError(Exception):
    """A log that could not be read whole this time (retried by the next run)."""


@dataclasses.dataclass(frozen=True)
class LogName:
    """What a log's key says: its unit, day and sequence number that day."""

    unit: str
    day: dt.date
    seq: int

    @property
    def stem(self) -> str:
        return self.day.isoformat() + (f"-{self.seq}" if self.seq else "")


def parse_key(rel: str) -> LogName:
    """`<unit>/<YYYY-MM-DD>[-N].log` (relative to the logs prefix) -> LogName;
    LogError naming the key otherwise."""
    m = KEY_RE.match(rel)
    if not m:
        raise LogError(f"key {rel!r} is not <unit>/<YYYY-MM-DD>[-N].log")
    try:
        day = dt.date.fromisoformat(m["day"])
    except ValueError as e:
        raise LogError(f"key {rel!r}: bad date: {e}") from None
    return LogName(m["unit"], day, int(m["seq"] or 0))


def unit_dir(unit: str) -> str:
    """The Hive partition directory of a unit (`unit=<url-encoded name>`)."""
    return "unit=" + urllib.parse.quote(unit, safe="")


def config_sha(config_text: Optional[str]) -> str:
    return hashlib.sha256((config_text or "").encode()).hexdigest()[:16]


class PrefetchReader(io.RawIOBase):
    """A binary stream read ahead by a thread: `depth` chunks of `chunk`
    bytes at most (memory bounded), so the download overlaps the replay.
    Counts the bytes (to tell a truncated transfer from a complete one);
    an error of the download is raised by `read`."""

    def __init__(self, raw: IO[bytes], chunk: int = 1 << 20, depth: int = 4):
        self.n = 0
        self._q: "queue.Queue[Any]" = queue.Queue(depth)
        self._buf = memoryview(b"")
        self._eof = False
        self._stop = threading.Event()

        def pump() -> None:
            try:
                while not self._stop.is_set():
                    b = raw.read(chunk)
                    self._q.put(b)
                    if not b:
                        return
                self._q.put(b"")  # stopped: the end for close()
            except BaseException as e:  # handed to the reader
                self._q.put(e)

        threading.Thread(target=pump, name="gyrocomp-fleet-prefetch", daemon=True).start()

    def readable(self) -> bool:
        return True

    def read(self, n: int = -1) -> bytes:
        if not self._buf and not self._eof:
            item = self._q.get()
            if isinstance(item, BaseException):
                self._eof = True
                raise item
            if not item:
                self._eof = True
            self._buf = memoryview(item)
        if n < 0:
            n = len(self._buf)
        b = bytes(self._buf[:n])
        self._buf = self._buf[n:]
        self.n += len(b)
        return b

    def close(self) -> None:
        self._stop.set()
        while not self._eof:  # let the pump finish its put and see the stop
            try:
                item = self._q.get(timeout=5)
            except queue.Empty:
                break
            if not item or isinstance(item, BaseException):
                break
        self._eof = True
        super().close()


# ------------------------------------------------------------------ schemas

STANDSTILL = pa.struct(
    [("t_start", pa.float64()), ("t_end", pa.float64()), ("samples", pa.int64()), ("temp", pa.float64()),
     ("temp_min", pa.float64()), ("temp_max", pa.float64())]
    + [(f"bias_{a}", pa.float64()) for a in AXES]
    + [(f"sigma_{a}", pa.float64()) for a in AXES]
    + [(f"gyro_{a}", pa.float64()) for a in AXES]
    + [(f"gyro_se_{a}", pa.float64()) for a in AXES]
)

#: The per-log table (one row per log; written under per_log/unit=U/, so the
#: unit column is the partition's).
PER_LOG = pa.schema(
    [("key", pa.string()), ("etag", pa.string()), ("day", pa.date32()), ("seq", pa.int32()), ("size", pa.int64()),
     ("samples", pa.int64()), ("duration_s", pa.float64()), ("temp_min", pa.float64()), ("temp_max", pa.float64()),
     ("n_standstills", pa.int32()), ("standstills", pa.list_(STANDSTILL))]
    + [(f"bias_{a}", pa.float64()) for a in AXES]
    + [(f"bias_sigma_{a}", pa.float64()) for a in AXES]
    + [("state", pa.string()), ("lines", pa.int64()), ("bad_lines", pa.int64()), ("frames", pa.int64()),
       ("lost", pa.int64()), ("gaps", pa.int64()), ("resyncs", pa.int64()), ("suspect", pa.int64())]
    + [(f"drop_{d}", pa.int64()) for d in DROPS]
    + [("config_sha", pa.string())]
)

#: The errors table (one row per failed log).
ERRORS = pa.schema(
    [("key", pa.string()), ("etag", pa.string()), ("unit", pa.string()), ("day", pa.date32()), ("seq", pa.int32()),
     ("error", pa.string())]
)


def _f(v: Any) -> float:
    return float(v)


def process_log(stream: Any, key: str, name: LogName, etag: str, size: int,
                config_text: Optional[str]) -> Dict[str, Any]:
    """Replay one log (a binary stream, a path or bytes) with the config and
    return its per-log record (a dict in the PER_LOG schema). Raises LogError
    (a log without samples, garbage) or what reading raised."""
    r = _gyrocomp.replay_standstills(stream, config_text)
    s = r["summary"]
    inp = s["input"]
    first = next((ln.strip() for ln in s["text"].splitlines() if ln.strip().startswith("bad line")), "")
    first = f"; first: {first}" if first else ""
    if r["samples"] == 0:
        raise LogError(f"{key}: no samples ({s['lines']} lines, {s['bad_lines']} unreadable, "
                       f"{inp['frames']} frames{first})")
    if s["bad_lines"] > MAX_BAD_FRACTION * s["lines"]:
        raise LogError(f"{key}: {s['bad_lines']} of {s['lines']} lines unreadable{first}")
    st = r["standstills"]
    k = len(st["t_start"])
    rows = []
    for i in range(k):
        row = {"t_start": _f(st["t_start"][i]), "t_end": _f(st["t_end"][i]), "samples": int(st["samples"][i]),
               "temp": _f(st["temp"][i]), "temp_min": _f(st["temp_min"][i]), "temp_max": _f(st["temp_max"][i])}
        for j, a in enumerate(AXES):
            row[f"bias_{a}"] = _f(st["bias"][i, j])
            row[f"sigma_{a}"] = _f(st["bias_sigma"][i, j])
            row[f"gyro_{a}"] = _f(st["gyro_mean"][i, j])
            row[f"gyro_se_{a}"] = _f(st["gyro_se"][i, j])
        rows.append(row)
    rec: Dict[str, Any] = {
        "key": key, "etag": etag, "day": name.day, "seq": name.seq, "size": int(size),
        "samples": int(r["samples"]), "duration_s": _f(r["t_end"]),
        "temp_min": _f(r["temp_min"]), "temp_max": _f(r["temp_max"]),
        "n_standstills": k, "standstills": rows, "state": r["state"],
        "lines": int(s["lines"]), "bad_lines": int(s["bad_lines"]), "frames": int(inp["frames"]),
        "lost": int(inp["lost"]), "gaps": int(inp["gaps"]), "resyncs": int(inp["resyncs"]),
        "suspect": int(inp["suspect"]), "config_sha": config_sha(config_text),
    }
    for j, a in enumerate(AXES):
        rec[f"bias_{a}"] = _f(r["bias"][j])
        rec[f"bias_sigma_{a}"] = _f(r["bias_sigma"][j])
    for d in DROPS:
        rec[f"drop_{d}"] = int(inp[d])
    return rec


def parquet_bytes(table: pa.Table) -> bytes:
    """A table as zstd Parquet (deterministic bytes for the same table)."""
    buf = io.BytesIO()
    pq.write_table(table, buf, compression="zstd")
    return buf.getvalue()


def result_name(name: LogName, etag: str) -> str:
    """The object name of a log's result (per_log/ or errors/ under its unit):
    the log's stem and its ETag, so a changed log is a new result."""
    return f"{name.stem}.{etag}.parquet"


@dataclasses.dataclass(frozen=True)
class Task:
    """One log for a worker: where it is, where its result goes."""

    bucket: str
    key: str  # the full object key
    rel: str  # the key under the logs prefix: <unit>/<day>[-N].log
    etag: str
    size: int
    out_bucket: str
    out_prefix: str  # ends with "/" or is ""
    config_text: Optional[str]
    endpoint_url: Optional[str]


def error_record(task: Task, msg: str) -> Dict[str, Any]:
    try:
        n: Optional[LogName] = parse_key(task.rel)
    except LogError:
        n = None
    return {"key": task.key, "etag": task.etag, "unit": n.unit if n else None, "day": n.day if n else None,
            "seq": n.seq if n else None, "error": msg}


def error_object(task: Task, final: bool = True) -> str:
    """Where a failed log's error row goes (keyed by its ETag). A final error
    (the log's content: garbage, no samples, a bad key) stays; a transient
    one (reading or writing the store) ends in `.retry.parquet` and the next
    run tries the log again."""
    tail = ".parquet" if final else ".retry.parquet"
    try:
        n = parse_key(task.rel)
        return f"{task.out_prefix}errors/{unit_dir(n.unit)}/{result_name(n, task.etag)[:-8]}{tail}"
    except LogError:
        h = hashlib.sha256(task.rel.encode()).hexdigest()[:16]
        return f"{task.out_prefix}errors/_unparsed/{h}.{task.etag}{tail}"


def result_object(task: Task, name: LogName) -> str:
    return f"{task.out_prefix}per_log/{unit_dir(name.unit)}/{result_name(name, task.etag)}"


def run_task(task: Task) -> Tuple[str, str, Optional[str]]:
    """What an engine runs per log: read it from the store, process it, write
    its result object (or its error row) in one PUT, so a result exists
    whole or not at all. Returns (key, "ok" | "error", message). Never
    raises for a bad log: the error names the key and the cause."""
    from .store import client

    s3 = client(task.endpoint_url)
    try:
        name = parse_key(task.rel)
        obj = s3.get_object(Bucket=task.bucket, Key=task.key)
        if obj.get("ETag", "").strip('"') != task.etag:
            raise TransientError(f"{task.key}: changed since it was listed (ETag {obj.get('ETag')}, listed {task.etag})")
        body = PrefetchReader(obj["Body"])
        try:
            rec = process_log(body, task.key, name, task.etag, task.size, task.config_text)
        finally:
            body.close()
        if body.n != task.size:
            raise TransientError(f"{task.key}: truncated transfer: read {body.n} of {task.size} bytes")
        data = parquet_bytes(pa.Table.from_pylist([rec], schema=PER_LOG))
        s3.put_object(Bucket=task.out_bucket, Key=result_object(task, name), Body=data)
        return task.key, "ok", None
    except Exception as e:  # any failure of this log is its error row, not the job's
        msg = str(e) if isinstance(e, (LogError, TransientError)) else f"{task.key}: {type(e).__name__}: {e}"
        if not isinstance(e, (LogError, TransientError)):
            tb = traceback.extract_tb(e.__traceback__)
            if tb:
                msg += f" (at {tb[-1].filename.rsplit('/', 1)[-1]}:{tb[-1].lineno})"
        data = parquet_bytes(pa.Table.from_pylist([error_record(task, msg)], schema=ERRORS))
        s3.put_object(Bucket=task.out_bucket, Key=error_object(task, isinstance(e, LogError)), Body=data)
        return task.key, "error", msg


def standstill_frame(per_log: pa.Table, min_standstill_s: float) -> Dict[str, np.ndarray]:
    """The standstills of a unit's logs as flat arrays (one entry per
    standstill at least `min_standstill_s` long with a finite temperature),
    with the index of its log in `per_log`."""
    logs: List[int] = []
    cols: Dict[str, List[float]] = {c: [] for c in ["t_start", "t_end", "temp"] + [f"bias_{a}" for a in AXES]
                                    + [f"sigma_{a}" for a in AXES] + [f"gyro_{a}" for a in AXES]}
    for i, ss in enumerate(per_log.column("standstills").to_pylist()):
        for s in ss or []:
            if s["t_end"] - s["t_start"] < min_standstill_s or not np.isfinite(s["temp"]):
                continue
            logs.append(i)
            for c in cols:
                cols[c].append(s[c])
    out = {c: np.asarray(v, dtype=float) for c, v in cols.items()}
    out["log"] = np.asarray(logs, dtype=int)
    return out
