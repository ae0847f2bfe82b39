"""The engines: the same function (`core.run_task`) over every task, on Dask
distributed or on Spark. Each returns one (key, status, message) per task,
in the tasks' order, and drives a progress bar of logs done / to do."""

from __future__ import annotations

import os
import sys
import threading
import time
from typing import Any, Callable, List, Optional, Sequence, Tuple

from .core import Task

Result = Tuple[str, str, Optional[str]]


def _bar(total: int, initial: int, enabled: bool) -> Any:
    from tqdm import tqdm

    return tqdm(total=total, initial=initial, desc="logs", unit="log", disable=not enabled, file=sys.stderr)


def local_dask_cluster(workers: int = 2) -> Any:
    """A Dask LocalCluster on 127.0.0.1 (no dashboard, no profiler):
    `workers` processes of one thread each."""
    import dask
    from distributed import LocalCluster

    # no statistical profiler in the workers: it samples the running task's
    # stack every 10 ms, about a fifth of a short log's cost (docs/fleet.md)
    with dask.config.set({"distributed.worker.profile.enabled": False}):
        return LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                            dashboard_address=None, worker_dashboard_address=None)


def map_dask(fn: Callable[[Task], Result], tasks: Sequence[Task], client: Any, bar: Any) -> List[Result]:
    """Run fn on every task on a Dask client. A task whose workers kept dying
    (KilledWorker) or that raised is an error row, not a failed job."""
    from distributed import as_completed

    futs = client.map(fn, list(tasks), pure=False)
    index = {f.key: i for i, f in enumerate(futs)}
    out: List[Optional[Result]] = [None] * len(futs)
    pending = as_completed(futs)
    del futs  # a result taken is released: a worker lost later does not take it along (no recompute)
    for f in pending:
        i = index[f.key]
        try:
            out[i] = f.result()
        except Exception as e:  # the worker died running it too often, or the task raised
            out[i] = _driver_error(tasks[i], f"{tasks[i].key}: the task failed on the engine: {type(e).__name__}: {e}")
        f.release()
        bar.update(1)
    return [o for o in out if o is not None]


def spark_session(master: str = "local[2]") -> Any:
    """A SparkSession bound to 127.0.0.1 (no UI), its Python workers this
    interpreter."""
    os.environ.setdefault("PYSPARK_PYTHON", sys.executable)
    os.environ.setdefault("PYSPARK_DRIVER_PYTHON", sys.executable)
    os.environ.setdefault("SPARK_LOCAL_IP", "127.0.0.1")
    from pyspark.sql import SparkSession

    return (SparkSession.builder.master(master).appName("gyrocomp-fleet")
            .config("spark.driver.host", "127.0.0.1").config("spark.driver.bindAddress", "127.0.0.1")
            .config("spark.ui.enabled", "false").config("spark.ui.showConsoleProgress", "false")
            .config("spark.python.worker.reuse", "true")
            .getOrCreate())


def map_spark(fn: Callable[[Task], Result], tasks: Sequence[Task], spark: Any, bar: Any) -> List[Result]:
    """Run fn on every task as an RDD map (one partition per log); the bar
    follows the stage's completed tasks."""
    sc = spark.sparkContext
    group = f"gyrocomp-fleet-{time.time_ns()}"
    box: dict = {}

    def collect() -> None:
        try:
            sc.setJobGroup(group, "gyrocomp fleet")
            box["out"] = sc.parallelize(list(tasks), max(1, len(tasks))).map(fn).collect()
        except Exception as e:  # reported below, on the caller's thread
            box["err"] = e

    th = threading.Thread(target=collect, daemon=True)
    th.start()
    done = 0
    st = sc.statusTracker()
    while th.is_alive():
        th.join(0.2)
        n = 0
        for jid in st.getJobIdsForGroup(group):
            job = st.getJobInfo(jid)
            for sid in job.stageIds if job else []:
                info = st.getStageInfo(sid)
                if info:
                    n += info.numCompletedTasks
        if n > done:
            bar.update(n - done)
            done = n
    if "err" in box:
        raise box["err"]
    bar.update(len(tasks) - done)
    return list(box["out"])


def _driver_error(task: Task, msg: str) -> Result:
    """Write a failed task's error row from the driver (the worker could not).
    A transient one (`.retry.parquet`): the engine cannot tell the log that
    killed its workers from another one that was on the same worker when it
    died, so the next run tries the log again."""
    import pyarrow as pa

    from .core import ERRORS, error_object, error_record, parquet_bytes
    from .store import client

    data = parquet_bytes(pa.Table.from_pylist([error_record(task, msg)], schema=ERRORS))
    client(task.endpoint_url).put_object(Bucket=task.out_bucket, Key=error_object(task, False), Body=data)
    return task.key, "error", msg
