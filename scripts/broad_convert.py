#!/usr/bin/env python3
"""Convert one BROAD trial (github dlaidig/broad, data_hdf5/*.hdf5, CC-BY-4.0)
into the recording folder that `gyrocomp evaluate --realdata DIR` reads.

usage: broad_convert.py IN.hdf5 OUT_DIR [--name NAME]

The hdf5 file holds, at its root (the dataset's own layout):
  imu_gyr (N,3) rad/s, imu_acc (N,3) m/s^2, imu_mag (N,3) uT, all in the
  IMU frame S (x forward, y left, z up);
  opt_quat (N,4) w,x,y,z: the optical body's orientation, S -> E (a vector
  v_S in the world frame E is q v_S q*), E east-north-up; NaN where the
  optical system lost the body;
  movement (N,) 1 where the trial moves, 0 at rest; sampling_rate (Hz).

OUT_DIR gets (see docs/realdata.md):
  imu.csv.gz        t,gx,gy,gz,ax,ay,az,mx,my,mz,temp  s, deg/s, g, gauss,
                    temp empty (the myon aktos-t has no temperature channel);
                    FRD body: S (x, y, z) is mapped as (x, -y, -z), so a level
                    unit at rest reads (0, 0, -1) g
  reference.csv.gz  t,roll,pitch,yaw,valid,rest  Z-Y-X Euler angles (deg) of
                    the FRD body in a north-east-down world (NED = (y, x, -z)
                    of ENU); valid=0 and empty angles where opt_quat is NaN;
                    rest=1 where movement is 0
  info.json         source, licence, sensor, rate, axes
  ATTRIBUTION.md    the dataset, its authors and licence

The output is deterministic: fixed number formats, gzip with mtime 0 and no
file name in its header, every file written under a temporary name and renamed.
Two conversions of the same file are byte-identical.
"""
import argparse
import gzip
import hashlib
import io
import json
import math
import os
import sys

import h5py
import numpy as np

# m/s^2 per g. The dataset gives m/s^2; the recordings gyrocomp scores give g.
G = 9.81
COMMIT = "7e2f8189bb4a"

# S (x fwd, y left, z up) -> FRD body B: (x, -y, -z).
S_TO_B = np.diag([1.0, -1.0, -1.0])
# ENU world E -> NED world N: (y, x, -z).
E_TO_N = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])

ATTRIBUTION = """# Attribution

This folder was converted by gyrocomp's `scripts/fetch-realdata` from
`data_hdf5/{src}` of BROAD, the Berlin Robust Orientation Estimation
Assessment Dataset (github: dlaidig/broad, commit {commit}).

D. Laidig, M. Caruso, A. Cereatti, T. Seel. BROAD - A Benchmark for Robust
Inertial Orientation Estimation. Data, 6 (7):1-20, 2021.
https://doi.org/10.3390/data6070072

Licence: Creative Commons Attribution 4.0 International (CC-BY-4.0),
https://creativecommons.org/licenses/by/4.0/

Changes made: units (rad/s -> deg/s, m/s^2 -> g with g = 9.81 m/s^2,
uT -> gauss), axes (the IMU frame S (x fwd, y left, z up) as FRD (x, -y, -z);
the ENU world as NED), the optical quaternion as Z-Y-X Euler angles, the
movement flag as `rest`. No sample was added, removed or filtered.
"""


def quat_to_matrix(q):
    """Rotation matrices (N,3,3) of unit quaternions (N,4) w,x,y,z."""
    q = q / np.linalg.norm(q, axis=1)[:, None]
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    r = np.empty((q.shape[0], 3, 3))
    r[:, 0, 0] = 1 - 2 * (y * y + z * z)
    r[:, 0, 1] = 2 * (x * y - w * z)
    r[:, 0, 2] = 2 * (x * z + w * y)
    r[:, 1, 0] = 2 * (x * y + w * z)
    r[:, 1, 1] = 1 - 2 * (x * x + z * z)
    r[:, 1, 2] = 2 * (y * z - w * x)
    r[:, 2, 0] = 2 * (x * z - w * y)
    r[:, 2, 1] = 2 * (y * z + w * x)
    r[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return r


def euler_zyx_ned_frd(quat):
    """(roll, pitch, yaw) in deg of the FRD body in NED from BROAD's S -> ENU quaternions."""
    r = E_TO_N @ quat_to_matrix(quat) @ S_TO_B  # B -> N
    roll = np.degrees(np.arctan2(r[:, 2, 1], r[:, 2, 2]))
    pitch = np.degrees(-np.arcsin(np.clip(r[:, 2, 0], -1.0, 1.0)))
    yaw = np.degrees(np.arctan2(r[:, 1, 0], r[:, 0, 0]))
    return roll, pitch, yaw


def read_broad(path):
    with h5py.File(path, "r") as f:
        missing = [k for k in ("imu_gyr", "imu_acc", "imu_mag", "opt_quat", "movement", "sampling_rate") if k not in f]
        if missing:
            raise SystemExit(f"{path}: not a BROAD trial: no {', '.join(missing)}")
        d = {k: np.asarray(f[k][()], dtype=float) for k in ("imu_gyr", "imu_acc", "imu_mag", "opt_quat")}
        d["movement"] = np.asarray(f["movement"][()]).reshape(-1)
        d["sampling_rate"] = float(np.asarray(f["sampling_rate"][()]).reshape(-1)[0])
    n = d["imu_gyr"].shape[0]
    for k, cols in (("imu_gyr", 3), ("imu_acc", 3), ("imu_mag", 3), ("opt_quat", 4)):
        if d[k].shape != (n, cols):
            raise SystemExit(f"{path}: {k} has shape {d[k].shape}, expected ({n}, {cols})")
        if k != "opt_quat" and not np.all(np.isfinite(d[k])):
            raise SystemExit(f"{path}: {k} has non-finite values")
    if d["movement"].shape != (n,):
        raise SystemExit(f"{path}: movement has {d['movement'].shape[0]} values, expected {n}")
    if not (math.isfinite(d["sampling_rate"]) and d["sampling_rate"] > 0):
        raise SystemExit(f"{path}: sampling_rate {d['sampling_rate']} is not a rate")
    return d


def gz_bytes(text):
    buf = io.BytesIO()
    with gzip.GzipFile(filename="", mode="wb", fileobj=buf, mtime=0, compresslevel=9) as g:
        g.write(text.encode())
    return buf.getvalue()


def write_atomic(path, data):
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def convert(src, out, name_in_source):
    with open(src, "rb") as f:
        sha256 = hashlib.sha256(f.read()).hexdigest()
    d = read_broad(src)
    n = d["imu_gyr"].shape[0]
    rate = d["sampling_rate"]
    t = np.arange(n) / rate
    gyr = np.degrees(d["imu_gyr"] @ S_TO_B)  # deg/s, FRD (S_TO_B is its own transpose)
    acc = (d["imu_acc"] @ S_TO_B) / G  # g
    mag = (d["imu_mag"] @ S_TO_B) / 100.0  # uT -> gauss
    lines = ["t,gx,gy,gz,ax,ay,az,mx,my,mz,temp"]
    for i in range(n):
        g, a, m = gyr[i], acc[i], mag[i]
        lines.append(
            f"{t[i]:.6f},{g[0]:.5f},{g[1]:.5f},{g[2]:.5f},{a[0]:.6f},{a[1]:.6f},{a[2]:.6f},{m[0]:.5f},{m[1]:.5f},{m[2]:.5f},"
        )
    imu = "\n".join(lines) + "\n"

    quat = d["opt_quat"]
    valid = np.all(np.isfinite(quat), axis=1) & (np.linalg.norm(np.nan_to_num(quat), axis=1) > 0.5)
    q = np.where(valid[:, None], quat, np.array([1.0, 0.0, 0.0, 0.0]))
    roll, pitch, yaw = euler_zyx_ned_frd(q)
    rest = d["movement"] == 0
    lines = ["t,roll,pitch,yaw,valid,rest"]
    for i in range(n):
        r = 1 if rest[i] else 0
        if valid[i]:
            lines.append(f"{t[i]:.6f},{roll[i]:.4f},{pitch[i]:.4f},{yaw[i]:.4f},1,{r}")
        else:
            lines.append(f"{t[i]:.6f},,,,0,{r}")
    ref = "\n".join(lines) + "\n"

    info = {
        "source": f"BROAD (dlaidig/broad @ {COMMIT}) data_hdf5/{name_in_source}",
        "license": "CC-BY-4.0",
        "attribution": "D. Laidig, M. Caruso, A. Cereatti, T. Seel, BROAD - A Benchmark for Robust Inertial Orientation Estimation, Data 6(7), 2021, doi:10.3390/data6070072",
        "sensor": "myon aktos-t IMU (MEMS), no temperature channel",
        "rate_hz": rate,
        "samples": n,
        "reference": "OptiTrack optical motion capture (marker body on the IMU); yaw origin arbitrary",
        "axes": "FRD body; the dataset frame S (x fwd, y left, z up) mapped as (x, -y, -z); world ENU mapped to NED",
        "units": f"gyro deg/s (from rad/s), accelerometer g (m/s^2 / {G}), magnetometer gauss (uT / 100)",
        "rest_phases": "rest=1 where the dataset marks no movement",
        "converted_by": "scripts/fetch-realdata (scripts/broad_convert.py)",
    }
    info["sha256"] = sha256
    os.makedirs(out, exist_ok=True)
    write_atomic(os.path.join(out, "imu.csv.gz"), gz_bytes(imu))
    write_atomic(os.path.join(out, "reference.csv.gz"), gz_bytes(ref))
    write_atomic(os.path.join(out, "info.json"), (json.dumps(info, indent=1) + "\n").encode())
    write_atomic(os.path.join(out, "ATTRIBUTION.md"), ATTRIBUTION.format(src=name_in_source, commit=COMMIT).encode())
    print(f"{out}: {n} samples, {n / rate:.1f} s at {rate:.3f} Hz, {int((~valid).sum())} without reference, {int(rest.sum())} at rest")


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("hdf5")
    p.add_argument("out")
    p.add_argument("--name", help="the file's name in the dataset (default: the input's file name)")
    a = p.parse_args()
    convert(a.hdf5, a.out, a.name or os.path.basename(a.hdf5))


if __name__ == "__main__":
    sys.exit(main())
