#!/usr/bin/env python3
"""Decode gyrocomp's output log with an independent decoder (cantools + the DBC)
and compare every signal with the estimate CSV that gyrocomp wrote beside it.

usage: dbc_check.py DBC OUT.log EST.csv   (exit 0 = all frames agree)
"""
import csv
import sys

import cantools


def main():
    dbc_path, log_path, csv_path = sys.argv[1:4]
    db = cantools.database.load_file(dbc_path)
    rows = list(csv.DictReader(open(csv_path)))
    frames = []
    for line in open(log_path):
        ts, _iface, body = line.split()
        fid, data = body.split("#")
        frames.append((int(fid, 16), bytes.fromhex(data)))
    assert len(frames) == 4 * len(rows), (len(frames), len(rows))
    names = ["GYRO_RATE_CORR", "ATTITUDE", "GYRO_BIAS", "EST_STATUS"]
    for want in names:
        db.get_message_by_name(want)  # raises if the DBC lacks it
    # half an LSB of the signal plus the CSV's own rounding
    tol = {"RateX": 0.0051, "RateY": 0.0051, "RateZ": 0.0051,
           "Roll": 0.0051, "Pitch": 0.0051, "Yaw": 0.0051,
           "BiasX": 0.000251, "BiasY": 0.000251, "BiasZ": 0.000251, "TempC": 0.0056}
    col = {"RateX": "rate_x", "RateY": "rate_y", "RateZ": "rate_z",
           "Roll": "roll", "Pitch": "pitch", "Yaw": "yaw",
           "BiasX": "bias_x", "BiasY": "bias_y", "BiasZ": "bias_z", "TempC": "temp"}
    checked = 0
    for k, row in enumerate(rows):
        cnts = set()
        for j, name in enumerate(names):
            fid, data = frames[4 * k + j]
            msg = db.get_message_by_frame_id(fid)
            assert msg.name == name, (k, msg.name, name)
            sig = msg.decode(data, decode_choices=False)
            cnts.add(sig["DataCnt"])
            for s, v in sig.items():
                if s in col:
                    ref = float(row[col[s]])
                    if s == "Yaw" and abs(v - ref) > 359:
                        ref = v  # +-180 wrap rounds either way
                    if abs(v - ref) > tol[s]:
                        raise SystemExit(f"sample {k}: {s} decoded {v} vs csv {ref}")
                    checked += 1
            if name == "EST_STATUS":
                if int(sig["Mode"]) != int(row["mode"]):
                    raise SystemExit(f"sample {k}: Mode {sig['Mode']} vs {row['mode']}")
                checked += 1
        if len(cnts) != 1:
            raise SystemExit(f"sample {k}: DataCnt differs across frames {cnts}")
    print(f"dbc_check: {len(rows)} samples, {checked} signal values agree")


if __name__ == "__main__":
    main()
