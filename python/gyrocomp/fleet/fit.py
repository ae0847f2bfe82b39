"""Per-unit fits and the fleet's outliers.

The thermal slope is the field-learning fit (`[thermal] learn`, docs/method.md):
the standstill biases of all a unit's power cycles regressed on temperature
with the sums centred per power cycle, so each log's turn-on bias drops out
and the slope is shared. Its interval is the ordinary least-squares one from
the residuals (Student t, N - logs - 1 degrees of freedom). The bias trend
over days is the per-log turn-on offset (the log's mean standstill bias moved
to `t_ref` by the fitted slope) regressed on the day.
"""

from __future__ import annotations

import math
from typing import Dict, List, Optional, Sequence

import numpy as np
from scipy import stats

#: Robust z-score (0.6745 (x - median) / MAD) beyond which a unit is an outlier.
OUTLIER_Z = 3.5


def slope_fit(temp: np.ndarray, bias: np.ndarray, log: np.ndarray, level: float = 0.95) -> Dict[str, float]:
    """Slope of bias on temperature, sums centred per log. Returns slope,
    se, lo, hi (the `level` interval), dof, n (standstills used), logs (power
    cycles with at least two), spread (the largest temperature range within
    one log), rms (residual). NaN where the data cannot say."""
    nan = float("nan")
    out = {"slope": nan, "se": nan, "lo": nan, "hi": nan, "dof": 0, "n": 0, "logs": 0, "spread": nan, "rms": nan}
    xs: List[np.ndarray] = []
    ys: List[np.ndarray] = []
    spread = 0.0
    for g in np.unique(log):
        m = log == g
        if m.sum() < 2:
            continue
        x, y = temp[m], bias[m]
        xs.append(x - x.mean())
        ys.append(y - y.mean())
        spread = max(spread, float(x.max() - x.min()))
    if not xs:
        return out
    x, y = np.concatenate(xs), np.concatenate(ys)
    sxx = float(x @ x)
    out.update(n=int(x.size), logs=len(xs), spread=spread)
    dof = x.size - len(xs) - 1
    if sxx <= 0.0:
        return out
    s = float(x @ y) / sxx
    r = y - s * x
    out.update(slope=s, dof=int(dof))
    if dof >= 1:
        var = float(r @ r) / dof
        se = math.sqrt(var / sxx)
        q = float(stats.t.ppf(0.5 + level / 2, dof))
        out.update(se=se, lo=s - q * se, hi=s + q * se, rms=math.sqrt(var))
    return out


def trend_fit(days: np.ndarray, offset: np.ndarray, level: float = 0.95) -> Dict[str, float]:
    """Linear trend of the per-log offsets over days (deg/s per day) with its
    interval; NaN with fewer than three logs (or one day)."""
    nan = float("nan")
    out = {"drift": nan, "se": nan, "lo": nan, "hi": nan}
    ok = np.isfinite(offset)
    d, o = days[ok].astype(float), offset[ok]
    if d.size < 3 or np.ptp(d) == 0:
        return out
    dc = d - d.mean()
    sxx = float(dc @ dc)
    b = float(dc @ (o - o.mean())) / sxx
    r = o - o.mean() - b * dc
    dof = d.size - 2
    se = math.sqrt(float(r @ r) / dof / sxx)
    q = float(stats.t.ppf(0.5 + level / 2, dof))
    out.update(drift=b, se=se, lo=b - q * se, hi=b + q * se)
    return out


def robust_z(values: Sequence[float]) -> np.ndarray:
    """0.6745 (x - median) / MAD over the finite values (NaN elsewhere, and
    all NaN when the MAD is 0)."""
    v = np.asarray(values, dtype=float)
    z = np.full(v.shape, np.nan)
    ok = np.isfinite(v)
    if ok.sum() < 3:
        return z
    med = np.median(v[ok])
    mad = np.median(np.abs(v[ok] - med))
    if mad > 0:
        z[ok] = 0.6745 * (v[ok] - med) / mad
    return z


def offsets(temp: np.ndarray, bias: np.ndarray, log: np.ndarray, n_logs: int, slope: Optional[float],
            t_ref: float) -> np.ndarray:
    """Each log's turn-on offset: its mean standstill bias moved to t_ref by
    the slope (NaN for a log without standstills, or without a slope)."""
    out = np.full(n_logs, np.nan)
    if slope is None or not np.isfinite(slope):
        return out
    for g in np.unique(log):
        m = log == g
        out[g] = float(np.mean(bias[m] - slope * (temp[m] - t_ref)))
    return out
