"""`python -m gyrocomp.fleet --logs s3://BUCKET/PREFIX --out s3://BUCKET/OUT
[--engine dask|spark] [--config CFG]`: see docs/fleet.md."""

from __future__ import annotations

import argparse
import sys
from typing import List, Optional

from .job import run_job


def main(argv: Optional[List[str]] = None) -> int:
    p = argparse.ArgumentParser(prog="python -m gyrocomp.fleet", description=(
        "Replay every <unit>/<YYYY-MM-DD>[-N].log under --logs on Dask or Spark and write zstd Parquet tables "
        "(per log, per unit, per fleet, errors) under --out. Logs whose results exist (same key and ETag) "
        "are skipped, so a re-run after a crash only does what is left."))
    p.add_argument("--logs", required=True, help="s3://BUCKET/PREFIX of the logs")
    p.add_argument("--out", required=True, help="s3://BUCKET/PREFIX of the tables (one config per --out)")
    p.add_argument("--engine", choices=["dask", "spark"], default="dask", help="default: dask")
    p.add_argument("--config", help="gyrocomp config file (default: the built-in defaults)")
    p.add_argument("--scheduler", help="dask: a scheduler address (default: a LocalCluster on 127.0.0.1)")
    p.add_argument("--workers", type=int, default=2, help="dask LocalCluster: worker processes (default 2)")
    p.add_argument("--master", default="local[2]", help="spark: the master (default local[2])")
    p.add_argument("--endpoint-url", help="S3 endpoint (default: AWS_ENDPOINT_URL, else AWS)")
    p.add_argument("--min-standstill-s", type=float, default=1.0,
                   help="standstills shorter than this are not fitted, s (default 1)")
    p.add_argument("--t-ref", type=float, default=25.0, help="temperature of the trend's offsets, deg C (default 25)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    a = p.parse_args(argv)
    try:
        r = run_job(a.logs, a.out, engine=a.engine, config=a.config, scheduler=a.scheduler, workers=a.workers,
                    master=a.master, endpoint_url=a.endpoint_url, progress=not a.no_progress,
                    min_standstill_s=a.min_standstill_s, t_ref=a.t_ref)
    except (ValueError, OSError) as e:
        print(f"gyrocomp.fleet: {e}", file=sys.stderr)
        return 1
    print(f"logs {r.logs}: processed {r.processed}, skipped {r.skipped} (results there), failed {r.failed}; "
          f"units {r.units}, outlier units {r.outliers}; tables under {r.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
