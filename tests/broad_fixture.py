#!/usr/bin/env python3
"""A BROAD trial written in the dataset's own hdf5 layout, and the checks of
its conversion by scripts/fetch-realdata (tests/fetch_realdata.rs).

usage: broad_fixture.py make DIR        writes DIR/90_test_rotations_B.hdf5
       broad_fixture.py check FOLDER    checks the converted folder (exit 0 = all hold)

The trial (IMU frame S: x fwd, y left, z up; world ENU; 2000/7 Hz as BROAD):
rest 12 s level and facing north; +30 deg about S x at 15 deg/s, held 3 s,
back; rest 3 s; +40 deg about S z (a left turn) at 20 deg/s; rest 3 s;
+20 deg about S y at 10 deg/s (nose down), held, back; rest to 40 s. The
optical quaternion is NaN for 1 s during the turn. Gyro bias (0.01,
-0.02, 0.015) rad/s.
"""
import gzip
import json
import math
import os
import sys

import numpy as np

RATE = 2000.0 / 7.0
N = int(40 * RATE)
G = 9.81
BIAS = np.array([0.01, -0.02, 0.015])
MAG_E = np.array([0.0, 20.0, -40.0])  # uT, ENU: north and down


def rotmat(q):
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def qmul(a, b):
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ]
    )


def schedule():
    """(first sample, end sample, body rate rad/s in S) of every motion
    segment; whole samples, so the integrated angles are exact."""
    segs = []
    k = int(12.0 * RATE)
    for axis, deg, rate_dps, hold in (((1, 0, 0), 30, 15, 3.0), ((0, 0, 1), 40, 20, None), ((0, 1, 0), 20, 10, 2.0)):
        n = int(round(deg / rate_dps * RATE))
        w = np.array(axis, float) * math.radians(deg) / n * RATE
        segs.append((k, k + n, w))
        k += n
        if hold is not None:
            k += int(hold * RATE)
            segs.append((k, k + n, -w))
            k += n
        k += int(3.0 * RATE)
    return segs


def make(folder):
    import h5py

    segs = schedule()
    # The yaw turn (S z) is not undone: the unit ends facing 40 deg west of north.
    q = np.array([math.cos(math.radians(90) / 2), 0, 0, math.sin(math.radians(90) / 2)])  # S x north: +90 about ENU z
    quat = np.empty((N, 4))
    gyr = np.empty((N, 3))
    acc = np.empty((N, 3))
    mag = np.empty((N, 3))
    move = np.zeros(N, dtype=np.uint8)
    dt = 1.0 / RATE
    for i in range(N):
        w = np.zeros(3)
        for a, b, ws in segs:
            if a <= i < b:
                w = ws
                move[i] = 1
        r = rotmat(q)
        quat[i] = q
        gyr[i] = w + BIAS
        acc[i] = r.T @ np.array([0.0, 0.0, G])
        mag[i] = r.T @ MAG_E
        ang = np.linalg.norm(w) * dt
        if ang > 0:
            ax = w / np.linalg.norm(w)
            q = qmul(q, np.r_[math.cos(ang / 2), math.sin(ang / 2) * ax])
            q /= np.linalg.norm(q)
    a = segs[2][0] + 100  # during the turn
    quat[a : a + int(RATE)] = np.nan
    os.makedirs(folder, exist_ok=True)
    with h5py.File(os.path.join(folder, "90_test_rotations_B.hdf5"), "w") as f:
        f.create_dataset("imu_gyr", data=gyr)
        f.create_dataset("imu_acc", data=acc)
        f.create_dataset("imu_mag", data=mag)
        f.create_dataset("opt_quat", data=quat)
        f.create_dataset("opt_pos", data=np.zeros((N, 3)))
        f.create_dataset("movement", data=move)
        f.create_dataset("sampling_rate", data=RATE)


def read_csv_gz(path):
    lines = gzip.open(path, "rt").read().splitlines()
    return lines[0], [l.split(",") for l in lines[1:]]


def check(folder):
    fails = []

    def expect(cond, what):
        if not cond:
            fails.append(what)

    for f in ("imu.csv.gz", "reference.csv.gz", "info.json", "ATTRIBUTION.md"):
        expect(os.path.isfile(os.path.join(folder, f)), f"{f} missing")
    head, imu = read_csv_gz(os.path.join(folder, "imu.csv.gz"))
    expect(head == "t,gx,gy,gz,ax,ay,az,mx,my,mz,temp", f"imu header {head}")
    rhead, ref = read_csv_gz(os.path.join(folder, "reference.csv.gz"))
    expect(rhead == "t,roll,pitch,yaw,valid,rest", f"reference header {rhead}")
    expect(len(imu) == N and len(ref) == N, f"{len(imu)} imu rows, {len(ref)} reference rows, expected {N}")
    expect(all(r[10] == "" for r in imu), "temp not empty")
    expect(all(r[0] == s[0] for r, s in zip(imu, ref)), "imu and reference clocks differ")
    expect(abs(float(imu[100][0]) - 100 / RATE) < 1e-6, f"t of sample 100 is {imu[100][0]}")
    info = json.load(open(os.path.join(folder, "info.json")))
    expect(info["license"] == "CC-BY-4.0" and "Laidig" in info["attribution"], "info.json attribution")
    expect(abs(info["rate_hz"] - RATE) < 1e-9 and info["samples"] == N, "info.json rate/samples")
    expect("CC-BY-4.0" in open(os.path.join(folder, "ATTRIBUTION.md")).read(), "ATTRIBUTION.md licence")

    def row(t):
        return int(round(t * RATE))

    # level at rest, facing north: az -1 g, gyro = the bias in deg/s on FRD axes (x, -y, -z)
    i = row(5.0)
    ax, ay, az = (float(v) for v in imu[i][4:7])
    expect(abs(ax) < 1e-5 and abs(ay) < 1e-5 and abs(az + 1.0) < 1e-5, f"level rest reads ({ax}, {ay}, {az}) g")
    gx, gy, gz = (float(v) for v in imu[i][1:4])
    want = np.degrees(BIAS) * np.array([1, -1, -1])
    expect(np.allclose([gx, gy, gz], want, atol=1e-4), f"gyro at rest {gx, gy, gz}, expected {want}")
    mx, my, mz = (float(v) for v in imu[i][7:10])
    expect(abs(mx - 0.2) < 1e-5 and abs(my) < 1e-5 and abs(mz - 0.4) < 1e-5, f"mag at rest ({mx}, {my}, {mz}) gauss")
    r = ref[i]
    expect(r[4] == "1" and r[5] == "1", f"rest row valid/rest {r[4]}/{r[5]}")
    expect(all(abs(float(v)) < 1e-3 for v in r[1:4]), f"level, north: roll/pitch/yaw {r[1:4]}")
    # +30 deg about S x (forward): FRD roll +30 (right side down); ay = -sin 30, az = -cos 30
    segs = schedule()
    i = segs[0][1] + 100  # in the hold
    expect(abs(float(ref[i][1]) - 30) < 0.01 and abs(float(ref[i][2])) < 0.01, f"roll hold reads {ref[i][1:4]}")
    ax, ay, az = (float(v) for v in imu[i][4:7])
    expect(abs(ay + 0.5) < 1e-4 and abs(az + math.sqrt(0.75)) < 1e-4, f"rolled unit reads ({ax}, {ay}, {az}) g")
    # the optical system lost the body for 1 s during the turn: valid=0, angles empty
    lost = [k for k in range(N) if ref[k][4] == "0"]
    expect(len(lost) == int(RATE) and lost[0] == segs[2][0] + 100, f"{len(lost)} rows without reference from {lost[:1]}")
    expect(all(ref[k][1:4] == ["", "", ""] for k in lost), "angles written where the quaternion is NaN")
    expect(all(ref[k][5] == "0" for k in lost), "rest during the motion")
    # after the left turn of 40 deg about S z (up), from north: NED yaw -40, level
    i = segs[2][1] + 100
    expect(abs(float(ref[i][3]) + 40) < 0.01 and abs(float(ref[i][1])) < 0.01, f"after the turn {ref[i][1:4]}")
    # +20 deg about S y (left): nose down, FRD pitch -20, so f_B = (sin -20 deg, 0, -cos 20 deg)
    i = segs[3][1] + 100
    expect(abs(float(ref[i][2]) + 20) < 0.01, f"pitch hold reads {ref[i][1:4]}")
    ax = float(imu[i][4])
    expect(abs(ax + math.sin(math.radians(20))) < 1e-4, f"pitched unit reads ax {ax} g")
    # rest flags: rest exactly where movement is 0
    moving = [any(a <= k < b for a, b, _ in segs) for k in range(N)]
    expect(all((ref[k][5] == "0") == moving[k] for k in range(N)), "rest flags differ from movement")
    if fails:
        print("\n".join(fails))
        return 1
    print(f"{folder}: all checks hold")
    return 0


if __name__ == "__main__":
    if sys.argv[1] == "make":
        make(sys.argv[2])
    else:
        sys.exit(check(sys.argv[2]))
