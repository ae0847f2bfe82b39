"""The fleet job: per-log, per-unit and fleet tables from many logs in object
storage, on Dask or Spark (`python -m gyrocomp.fleet --help`; docs/fleet.md).

`process_log` is the engine-neutral function (a log stream in, its per-log
record out); `run_task` wraps it with the store; `run_job` runs the job.
"""

from .core import KEY_RE, LogError, LogName, Task, parse_key, process_log, run_task
from .fit import robust_z, slope_fit, trend_fit
from .job import JobResult, reduce, run_job

__all__ = [
    "KEY_RE",
    "JobResult",
    "LogError",
    "LogName",
    "Task",
    "parse_key",
    "process_log",
    "reduce",
    "robust_z",
    "run_job",
    "run_task",
    "slope_fit",
    "trend_fit",
]
