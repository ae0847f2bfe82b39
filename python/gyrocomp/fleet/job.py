"""The fleet job: list the logs, skip those with results, map the rest on an
engine, then reduce every result into the per-unit and fleet tables.

Layout under OUT (zstd Parquet; `unit=U` is a Hive partition):

- `per_log/unit=U/<day>[-N].<etag>.parquet`: one row per log (written by the
  worker that processed it, in one PUT: whole or absent);
- `errors/unit=U/<day>[-N].<etag>.parquet`: one row per failed log;
- `standstills/unit=U/part-0.parquet`: every standstill of the unit's logs;
- `per_unit/unit=U/part-0.parquet`: the thermal slope per axis with its 95 %
  interval, and the bias drift over days;
- `trend/unit=U/part-0.parquet`: each log's turn-on offset (the trend's points);
- `fleet/summary.parquet`, `fleet/outliers.parquet`, `fleet/errors.parquet`;
- `_job.json` (the config's hash: one OUT holds one config's results) and
  `_done.json`, written last (the counts; absent while a run is going on).
"""

from __future__ import annotations

import concurrent.futures as cf
import dataclasses
import io
import json
import urllib.parse
from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from . import fit
from .core import (AXES, ERRORS, PER_LOG, LogError, LogName, Task, config_sha, error_object, parquet_bytes,
                   parse_key, result_object, standstill_frame, unit_dir)
from .engines import _bar, local_dask_cluster, map_dask, map_spark, spark_session
from .store import client, list_objects, parse_url


@dataclasses.dataclass
class JobResult:
    logs: int  # logs listed
    processed: int  # run this time
    skipped: int  # results already there (same key and ETag)
    failed: int  # error rows now in the errors table
    units: int
    outliers: int
    out: str


def _config_text(config: Optional[str]) -> Optional[str]:
    if config is None:
        return None
    if "\n" in config or "=" in config or "[" in config:
        return config
    with open(config, encoding="utf-8") as f:
        return f.read()


def list_tasks(logs_url: str, out_url: str, config_text: Optional[str], endpoint_url: Optional[str]) -> List[Task]:
    """Every `*.log` object under the logs prefix, sorted by key."""
    bucket, prefix = parse_url(logs_url)
    out_bucket, out_prefix = parse_url(out_url)
    s3 = client(endpoint_url)
    tasks = [Task(bucket, o["Key"], o["Key"][len(prefix):], o["ETag"], o["Size"], out_bucket, out_prefix, config_text,
                  endpoint_url)
             for o in list_objects(s3, bucket, prefix) if o["Key"].endswith(".log")]
    return sorted(tasks, key=lambda t: t.key)


def expected_objects(t: Task) -> Tuple[Optional[str], str, str]:
    """(the result object, the final error object, the transient error
    object) a task may have written."""
    try:
        name: Optional[LogName] = parse_key(t.rel)
    except LogError:
        name = None
    return (result_object(t, name) if name else None), error_object(t, True), error_object(t, False)


def _res_of_err(k: str, out_prefix: str) -> str:
    """The result object of the same log as an error object."""
    k = k.replace(out_prefix + "errors/", out_prefix + "per_log/", 1)
    return k[: -len(".retry.parquet")] + ".parquet" if k.endswith(".retry.parquet") else k


def run_job(logs_url: str, out_url: str, engine: str = "dask", config: Optional[str] = None,
            scheduler: Optional[str] = None, workers: int = 2, master: str = "local[2]",
            endpoint_url: Optional[str] = None, progress: bool = True, min_standstill_s: float = 1.0,
            t_ref: float = 25.0, dask_client: Any = None, spark: Any = None) -> JobResult:
    """The whole job. `config`: a path or TOML text (None: the defaults).
    Dask: `dask_client`, else `scheduler` (an address), else a LocalCluster
    of `workers` processes. Spark: `spark` (a session), else `master`."""
    if engine not in ("dask", "spark"):
        raise ValueError(f"engine {engine!r}: expected dask or spark")
    text = _config_text(config)
    if text is not None:
        from .. import _gyrocomp

        _gyrocomp.Estimator(204.8, text)  # a bad config fails here, naming its line, before any task
    out_bucket, out_prefix = parse_url(out_url)
    s3 = client(endpoint_url)
    _check_manifest(s3, out_bucket, out_prefix, config_sha(text))
    s3.delete_object(Bucket=out_bucket, Key=out_prefix + "_done.json")
    tasks = list_tasks(logs_url, out_url, text, endpoint_url)
    existing = {o["Key"] for sub in ("per_log/", "errors/") for o in list_objects(s3, out_bucket, out_prefix + sub)}
    # done: a result, or a final error row (a transient one, e.g. the store's, is retried)
    todo = [t for t in tasks if not any(k in existing for k in expected_objects(t)[:2] if k)]
    bar = _bar(len(tasks), len(tasks) - len(todo), progress)
    try:
        if todo and engine == "dask":
            own = None
            if dask_client is None:
                from distributed import Client

                if scheduler:
                    dask_client = own = Client(scheduler)
                else:
                    cluster = local_dask_cluster(workers)
                    dask_client = own = Client(cluster)
            try:
                from .core import run_task

                map_dask(run_task, todo, dask_client, bar)
            finally:
                if own is not None:
                    cl = own.cluster
                    own.close()
                    if cl is not None and not scheduler:
                        cl.close()
        elif todo:
            from .core import run_task

            own_spark = spark is None
            spark = spark or spark_session(master)
            try:
                map_spark(run_task, todo, spark, bar)
            finally:
                if own_spark:
                    spark.stop()
    finally:
        bar.close()
    res = reduce(tasks, out_url, endpoint_url, min_standstill_s, t_ref)
    res.processed, res.skipped = len(todo), len(tasks) - len(todo)
    s3.put_object(Bucket=out_bucket, Key=out_prefix + "_done.json",
                  Body=json.dumps(dataclasses.asdict(res), indent=1, sort_keys=True).encode())
    return res


def _check_manifest(s3: Any, bucket: str, prefix: str, sha: str) -> None:
    key = prefix + "_job.json"
    try:
        old = json.loads(s3.get_object(Bucket=bucket, Key=key)["Body"].read())
    except s3.exceptions.NoSuchKey:
        old = None
    if old is not None and old.get("config_sha") != sha:
        raise ValueError(f"s3://{bucket}/{prefix}: holds results of another config (config_sha "
                         f"{old.get('config_sha')}, this one {sha}): use another --out")
    if old is None:
        s3.put_object(Bucket=bucket, Key=key, Body=json.dumps({"config_sha": sha}).encode())


def _read_tables(s3: Any, bucket: str, keys: Sequence[str]) -> List[pa.Table]:
    def one(k: str) -> pa.Table:
        return pq.read_table(io.BytesIO(s3.get_object(Bucket=bucket, Key=k)["Body"].read()))

    with cf.ThreadPoolExecutor(8) as ex:
        return list(ex.map(one, keys))


def _put(s3: Any, bucket: str, key: str, table: pa.Table) -> None:
    s3.put_object(Bucket=bucket, Key=key, Body=parquet_bytes(table))


def _unit_of_dir(d: str) -> str:
    return urllib.parse.unquote(d[len("unit="):])


def reduce(tasks: Sequence[Task], out_url: str, endpoint_url: Optional[str], min_standstill_s: float = 1.0,
           t_ref: float = 25.0) -> JobResult:
    """Read every current per-log result and error row, delete stale ones (a
    log changed or gone), and write the standstills, per-unit, trend and
    fleet tables. Deterministic: rows sorted, same results, same bytes."""
    out_bucket, out_prefix = parse_url(out_url)
    s3 = client(endpoint_url)
    want_res, want_err = set(), set()
    for t in tasks:
        r, e, e2 = expected_objects(t)
        if r:
            want_res.add(r)
        want_err.update((e, e2))
    have_res = sorted(o["Key"] for o in list_objects(s3, out_bucket, out_prefix + "per_log/"))
    have_err = sorted(o["Key"] for o in list_objects(s3, out_bucket, out_prefix + "errors/"))
    res_keys = [k for k in have_res if k in want_res]
    res_set = set(res_keys)
    # a log with a result and a transient error row (a retry that worked): the result counts;
    # with a final and a transient one (a retry that failed for good): the final one
    have_err_set = set(have_err)
    err_keys = [k for k in have_err if k in want_err and _res_of_err(k, out_prefix) not in res_set
                and not (k.endswith(".retry.parquet") and k[: -len(".retry.parquet")] + ".parquet" in have_err_set)]
    want_err = set(err_keys)
    for k in [k for k in have_res if k not in res_set] + [k for k in have_err if k not in want_err]:
        s3.delete_object(Bucket=out_bucket, Key=k)

    # per-log rows by unit
    by_unit: Dict[str, List[pa.Table]] = {}
    for k, tab in zip(res_keys, _read_tables(s3, out_bucket, res_keys)):
        u = _unit_of_dir(k[len(out_prefix + "per_log/"):].split("/", 1)[0])
        by_unit.setdefault(u, []).append(tab)
    errs = _read_tables(s3, out_bucket, err_keys)
    errors = (pa.concat_tables(errs) if errs else pa.Table.from_pylist([], schema=ERRORS))
    errors = errors.sort_by([("key", "ascending")])
    _put(s3, out_bucket, out_prefix + "fleet/errors.parquet", errors)

    units = sorted(by_unit)
    summary_rows: List[Dict[str, Any]] = []
    for u in units:
        logs = pa.concat_tables(by_unit[u]).sort_by([("day", "ascending"), ("seq", "ascending")])
        per_unit, trend, still = unit_tables(logs, min_standstill_s, t_ref)
        d = out_prefix + "{}/" + unit_dir(u) + "/part-0.parquet"
        _put(s3, out_bucket, d.format("per_unit"), per_unit)
        _put(s3, out_bucket, d.format("trend"), trend)
        _put(s3, out_bucket, d.format("standstills"), still)
        row: Dict[str, Any] = {"unit": u, "logs": logs.num_rows,
                               "failed": sum(1 for e in errors.column("unit").to_pylist() if e == u),
                               "days": len(set(logs.column("day").to_pylist())),
                               "samples": int(pa.compute.sum(logs.column("samples")).as_py()),
                               "standstills": int(pa.compute.sum(logs.column("n_standstills")).as_py()),
                               "temp_min": float(pa.compute.min(logs.column("temp_min")).as_py()),
                               "temp_max": float(pa.compute.max(logs.column("temp_max")).as_py())}
        pu = per_unit.to_pylist()
        for a, r in zip(AXES, pu):
            for c in ("slope", "slope_lo", "slope_hi", "drift", "drift_lo", "drift_hi"):
                row[f"{c}_{a}"] = r[c]
        summary_rows.append(row)
    # stale unit tables (a unit whose logs are gone)
    for sub in ("per_unit/", "trend/", "standstills/"):
        for o in list_objects(s3, out_bucket, out_prefix + sub):
            if _unit_of_dir(o["Key"][len(out_prefix + sub):].split("/", 1)[0]) not in by_unit:
                s3.delete_object(Bucket=out_bucket, Key=o["Key"])

    outliers: List[Dict[str, Any]] = []
    for what in ("slope", "drift"):
        for a in AXES:
            vals = [r[f"{what}_{a}"] for r in summary_rows]
            z = fit.robust_z(vals)
            for r, v, zz in zip(summary_rows, vals, z):
                r[f"z_{what}_{a}"] = float(zz)
                if np.isfinite(zz) and abs(zz) > fit.OUTLIER_Z:
                    outliers.append({"unit": r["unit"], "what": what, "axis": a, "value": float(v),
                                     "robust_z": float(zz)})
    for r in summary_rows:
        r["outlier"] = any(o["unit"] == r["unit"] for o in outliers)
    outliers.sort(key=lambda o: (o["unit"], o["what"], o["axis"]))
    _put(s3, out_bucket, out_prefix + "fleet/summary.parquet", _table(summary_rows, _summary_schema()))
    _put(s3, out_bucket, out_prefix + "fleet/outliers.parquet", _table(outliers, OUTLIERS))
    return JobResult(logs=len(tasks), processed=0, skipped=0, failed=errors.num_rows, units=len(units),
                     outliers=len({o["unit"] for o in outliers}), out=out_url)


OUTLIERS = pa.schema([("unit", pa.string()), ("what", pa.string()), ("axis", pa.string()), ("value", pa.float64()),
                      ("robust_z", pa.float64())])

PER_UNIT = pa.schema([("axis", pa.string()), ("slope", pa.float64()), ("slope_se", pa.float64()),
                      ("slope_lo", pa.float64()), ("slope_hi", pa.float64()), ("dof", pa.int32()),
                      ("standstills", pa.int32()), ("logs_fit", pa.int32()), ("spread", pa.float64()),
                      ("rms", pa.float64()), ("learned_slope", pa.float64()), ("learned_lo", pa.float64()),
                      ("learned_hi", pa.float64()), ("drift", pa.float64()), ("drift_se", pa.float64()),
                      ("drift_lo", pa.float64()), ("drift_hi", pa.float64()), ("logs", pa.int32()),
                      ("first_day", pa.date32()), ("last_day", pa.date32())])

TREND = pa.schema([("key", pa.string()), ("day", pa.date32()), ("seq", pa.int32()), ("standstills", pa.int32()),
                   ("temp", pa.float64())] + [(f"offset_{a}", pa.float64()) for a in AXES])


def _summary_schema() -> pa.Schema:
    f: List[Tuple[str, pa.DataType]] = [("unit", pa.string()), ("logs", pa.int64()), ("failed", pa.int64()),
                                        ("days", pa.int64()), ("samples", pa.int64()), ("standstills", pa.int64()),
                                        ("temp_min", pa.float64()), ("temp_max", pa.float64())]
    for c in ("slope", "slope_lo", "slope_hi", "drift", "drift_lo", "drift_hi"):
        f += [(f"{c}_{a}", pa.float64()) for a in AXES]
    for what in ("slope", "drift"):
        f += [(f"z_{what}_{a}", pa.float64()) for a in AXES]
    f.append(("outlier", pa.bool_()))
    return pa.schema(f)


def _table(rows: List[Dict[str, Any]], schema: pa.Schema) -> pa.Table:
    return pa.Table.from_pylist(rows, schema=schema)


def unit_tables(logs: pa.Table, min_standstill_s: float, t_ref: float) -> Tuple[pa.Table, pa.Table, pa.Table]:
    """One unit's per-log rows (sorted by day, seq) -> (per_unit, trend,
    standstills) tables."""
    s = standstill_frame(logs, min_standstill_s)
    days = np.array([d.toordinal() for d in logs.column("day").to_pylist()], dtype=float)
    n_logs = logs.num_rows
    rows, offs = [], {}
    for a in AXES:
        f = fit.slope_fit(s["temp"], s[f"gyro_{a}"], s["log"])
        fl = fit.slope_fit(s["temp"], s[f"bias_{a}"], s["log"])
        o = fit.offsets(s["temp"], s[f"gyro_{a}"], s["log"], n_logs, f["slope"], t_ref)
        offs[a] = o
        tr = fit.trend_fit(days, o)
        rows.append({"axis": a, "slope": f["slope"], "slope_se": f["se"], "slope_lo": f["lo"], "slope_hi": f["hi"],
                     "dof": f["dof"], "standstills": f["n"], "logs_fit": f["logs"], "spread": f["spread"],
                     "rms": f["rms"], "learned_slope": fl["slope"], "learned_lo": fl["lo"],
                     "learned_hi": fl["hi"], "drift": tr["drift"], "drift_se": tr["se"], "drift_lo": tr["lo"],
                     "drift_hi": tr["hi"], "logs": n_logs, "first_day": logs.column("day")[0].as_py(),
                     "last_day": logs.column("day")[n_logs - 1].as_py()})
    per_unit = _table(rows, PER_UNIT)
    keys = logs.column("key").to_pylist()
    seqs = logs.column("seq").to_pylist()
    trend_rows = []
    for i in range(n_logs):
        m = s["log"] == i
        r = {"key": keys[i], "day": logs.column("day")[i].as_py(), "seq": seqs[i], "standstills": int(m.sum()),
             "temp": float(np.mean(s["temp"][m])) if m.any() else float("nan")}
        for a in AXES:
            r[f"offset_{a}"] = float(offs[a][i])
        trend_rows.append(r)
    trend = _table(trend_rows, TREND)
    flat = []
    for key, day, seq, ss in zip(keys, logs.column("day").to_pylist(), seqs, logs.column("standstills").to_pylist()):
        for x in ss or []:
            flat.append({"key": key, "day": day, "seq": seq, **x})
    still = pa.Table.from_pylist(flat, schema=pa.schema([("key", pa.string()), ("day", pa.date32()),
                                                         ("seq", pa.int32())] + list(PER_LOG.field("standstills").type.value_type)))
    return per_unit, trend, still
