"""gyrocomp from Python: the estimator, replay, calibrate and gap of the Rust crate.

Units are the project's CSVs': gyro deg/s, specific force g, magnetic field
gauss, temperature deg C, time s, angles deg. See docs/python.md.
"""

from ._gyrocomp import (
    CSV_COLUMNS,
    FLAGS,
    Estimate,
    Estimator,
    __version__,
    calibrate,
    gap,
    read_log,
    replay,
    replay_chunks,
    replay_standstills,
)

__all__ = [
    "CSV_COLUMNS",
    "FLAGS",
    "Estimate",
    "Estimator",
    "__version__",
    "calibrate",
    "gap",
    "read_log",
    "replay",
    "replay_chunks",
    "replay_standstills",
]
