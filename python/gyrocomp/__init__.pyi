"""Type stubs of the gyrocomp package (the Rust module gyrocomp._gyrocomp).

Units: gyro deg/s, specific force g, magnetic field gauss, temperature
deg C, time s, angles deg; every output in the vehicle frame.
"""

import os
from typing import IO, Any, Dict, Iterator, List, Optional, Sequence, Tuple, TypedDict, Union

import numpy as np
import numpy.typing as npt

__version__: str
#: The columns of `gyrocomp replay --csv`, in order.
CSV_COLUMNS: List[str]
#: Health flag bits of `flags` (the EST_STATUS word's flags), by name.
FLAGS: Dict[str, int]

_Config = Union[None, str, bytes, "os.PathLike[str]"]
_Log = Union[str, bytes, "os.PathLike[str]", IO[bytes]]
_Vec3 = Union[Sequence[float], npt.NDArray[np.float64]]
_F64 = npt.NDArray[np.float64]

class Estimate:
    """One estimate, what `Estimator.update` returns."""

    t: float
    """Seconds since the first sample (from the sample steps)."""
    quaternion: Tuple[float, float, float, float]
    """[w, x, y, z], w >= 0: the attitude, vehicle to level (NED) frame."""
    euler: Tuple[float, float, float]
    """Roll, pitch, yaw (Z-Y-X), deg."""
    rate: Tuple[float, float, float]
    """Bias-corrected rate, deg/s."""
    bias: Tuple[float, float, float]
    """Gyro bias, deg/s."""
    bias_sigma: Tuple[float, float, float]
    """1-sigma of the bias, deg/s (NaN in the paper's modes)."""
    rest: bool
    """At rest: a standstill is detected."""
    mode: int
    """0 fusion with bias learning, 1 aided without bias learning, 2 gyro only."""
    flags: int
    """Health flags (FLAGS)."""
    temp: float
    """The sample's temperature, deg C."""

class BatchResult(TypedDict):
    quaternion: _F64  # (N, 4)
    euler: _F64  # (N, 3) deg
    rate: _F64  # (N, 3) deg/s
    bias: _F64  # (N, 3) deg/s
    bias_sigma: _F64  # (N, 3) deg/s
    rest: npt.NDArray[np.bool_]  # (N,)
    mode: npt.NDArray[np.uint8]  # (N,)
    flags: npt.NDArray[np.uint16]  # (N,)
    t: _F64  # (N,) s since the first sample

class Estimator:
    """The estimator for one power cycle of one unit.

    `config`: None (the defaults), TOML text, or the path of a config file
    (the daemon's format; a str holding a newline, '=' or '[' is text).
    `rate_hz` overrides its `[input] rate_hz`.
    """

    def __init__(self, rate_hz: float, config: _Config = None) -> None: ...
    @property
    def rate_hz(self) -> float: ...
    @property
    def config(self) -> str:
        """The effective config as TOML text (every key)."""
    @property
    def started(self) -> bool:
        """Whether a sample was stepped since the start or the last reset."""
    def reset(self) -> None:
        """Start a new power cycle from the config (no prior)."""
    def update(
        self,
        gyr: _Vec3,
        acc: _Vec3,
        mag: Optional[_Vec3] = None,
        temp: Optional[float] = None,
        dt: Optional[float] = None,
    ) -> Estimate:
        """One sample. mag None: no magnetometer; temp None: the thermal
        curve's t0; dt None: one period (else rounded to whole periods; a gap
        over `max_gap_s` is a resync)."""
    def update_batch(
        self,
        gyr: npt.ArrayLike,
        acc: npt.ArrayLike,
        mag: Optional[npt.ArrayLike] = None,
        temp: Optional[npt.ArrayLike] = None,
        t: Optional[npt.ArrayLike] = None,
    ) -> BatchResult:
        """N samples: gyr, acc, mag (N, 3), temp (N,), t (N,) sample times in
        s (None: one period apart). All checked before any is stepped."""
    @property
    def state(self) -> Optional[str]:
        """The learned state as the daemon's state file's text (None: nothing
        learned). Assigning one (str or bytes, or None) restarts the
        estimator from it, as the daemon does at start."""
    @state.setter
    def state(self, value: Union[None, str, bytes]) -> None: ...

def replay(log: _Log, config: _Config = None) -> Dict[str, Any]:
    """`gyrocomp replay --csv` as arrays: the CSV's columns (t, roll, pitch,
    yaw, rate_x..z, bias_x..z, mode, temp) at full precision, plus flags,
    t_us and summary (a dict; its 'text' is what the CLI prints). The log (a
    path, bytes or a binary file object) is read in 256 KiB chunks."""

class ReplayChunks(Iterator[Dict[str, Any]]):
    """`replay` a chunk at a time (what `replay_chunks` returns)."""

    def __iter__(self) -> "ReplayChunks": ...
    def __next__(self) -> Dict[str, Any]: ...
    @property
    def summary(self) -> Optional[Dict[str, Any]]:
        """`replay`'s summary, once the iterator is exhausted (None before)."""

def replay_chunks(log: _Log, config: _Config = None, rows: int = 65536) -> ReplayChunks:
    """`replay` as an iterator of dicts of at most `rows` rows each (the same
    columns, without the summary): memory bounded by the chunk whatever the
    log's length. The replay runs in a thread one chunk ahead."""

class StandstillArrays(TypedDict):
    t_start: _F64  # (K,) s since the first sample
    t_end: _F64  # (K,) s, the standstill's last sample
    samples: npt.NDArray[np.uint64]  # (K,)
    temp: _F64  # (K,) mean temperature, deg C
    temp_min: _F64  # (K,) deg C
    temp_max: _F64  # (K,) deg C
    bias: _F64  # (K, 3) the learned bias at the standstill's last sample, deg/s
    bias_sigma: _F64  # (K, 3) its 1-sigma, deg/s (NaN in the paper's modes)
    gyro_mean: _F64  # (K, 3) the mean measured rate (rate + bias, vehicle frame), deg/s
    gyro_se: _F64  # (K, 3) its standard error (sample scatter / sqrt(n)), deg/s

def replay_standstills(log: _Log, config: _Config = None) -> Dict[str, Any]:
    """`replay` keeping only what a fleet job needs (memory flat in the
    log's length): standstills (StandstillArrays: one entry per run of
    estimates flagged STANDSTILL), samples, temp_min, temp_max (deg C),
    t_end (s), bias, bias_sigma (3,) at the last sample (deg/s), state (the
    daemon's state file's text at the end, saved_unix 0; None: nothing
    learned) and summary (as `replay`'s)."""

def read_log(log: _Log, config: _Config = None) -> Dict[str, Any]:
    """The samples of a candump log as the daemon assembles them: gyr, acc,
    mag (N, 3), temp, t (sample counter time, s), t_frame (frame time, s),
    steps, cnt, diag (N,), and lines, bad_lines, rate_hz."""

def calibrate(runs: Sequence[_Log], order: int = 1, config: _Config = None) -> Dict[str, Any]:
    """`gyrocomp calibrate`: the thermal bias curve from chamber runs (one
    log per power cycle). coeffs, ci, se (3, order) in deg/s per (deg C)^k,
    p2, p2_ci, rms, white, walk (3,), levels, range, bins_used, warnings,
    runs (a dict each), toml (the [thermal] section), report (the CLI's
    text)."""

_Input = Union[str, bytes, "os.PathLike[str]"]

def gap(
    measured: Union[_Input, Sequence[_Input]],
    truth: Optional[_Input] = None,
    reference: Union[None, _Input, Sequence[_Input]] = None,
    model: _Config = None,
    static: bool = False,
    bandwidth: float = 2.0,
    profile: str = "adis16448",
) -> Dict[str, Any]:
    """`gyrocomp gap`: what a gyro sensor model is missing, with evidence,
    nothing written. measured: a candump log (ADIS contract, decoded with
    `profile`) or a CSV t,gx,gy,gz,ax,ay,az,mx,my,mz,temp (s, deg/s, g,
    gauss, deg C), as a path or bytes (gzip recognised); a list of them for
    several trials of one unit. The truth is exactly one of: truth (a
    simulated truth.csv t,roll,pitch,yaw,p,q,r,fx,fy,fz[,temp] in s, deg,
    deg/s, g, deg C), reference (a measured t,roll,pitch,yaw[,valid][,rest]
    in s and deg, one per measured input) or static=True (the unit lay
    still); bandwidth (Hz, 0.1..100) is the low-pass of a derived truth.
    model: the base model (sensor.toml shape: effects with their tables are
    fixed, listed without them fitted; its [noise] judges significance) as
    a path or TOML text; None: no effect, the default noise.

    One input: the dict report.json holds (findings with effect, axis,
    term, coefficient, std_error, t_stat, unit, rms_before/rms_after (3,)
    deg/s and evidence; base_coefficients, rms_initial/rms_final (1-s
    means, deg/s), noise_model, checks, localisation, ...) and model, the
    extended model as TOML (model.toml). Several: trials.json's effects
    (per-trial coefficients, chi2 consistency, joint estimate, added),
    leave_one_out and consistency_level, trials (each trial's dict by
    name: the path's folder or stem, trialN for bytes) and model (the
    joint model as TOML). Bad input raises ValueError naming the input
    (the path, or measured/truth/reference[k] for bytes) and the line."""
