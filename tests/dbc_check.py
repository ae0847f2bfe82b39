#!/usr/bin/env python3
"""Decode gyrocomp's output log with an independent decoder (cantools + the DBC)
and compare every signal with the estimate CSV that gyrocomp wrote beside it,
and EST_AID with the aid words of the same replay's estimates.

usage: dbc_check.py DBC OUT.log EST.csv [AID.csv]   (exit 0 = all frames agree)

AID.csv (written by tests/dbc.rs from the library's estimates): `cnt`, one
column per aid source named as the library names it (`zero_velocity`, ...)
holding its status as the DBC's value name (`not_applicable`, `fused`,
`refused`), and `worst_ratio` (the estimate's ratio, before the frame's
saturation). Its source columns, in order, must be the DBC's `Aid<Name>`
signals at bits 0, 2, 4, ...
"""
import csv
import math
import sys

import cantools

FOUR = ["GYRO_RATE_CORR", "ATTITUDE", "GYRO_BIAS", "EST_STATUS"]
# EST_AID bits 24-30: the fields not estimated (the CSV's `invalid`, bit i at 24 + i)
INVALID = ["InvalidRateX", "InvalidRateY", "InvalidRateZ", "InvalidRoll", "InvalidPitch", "InvalidYaw", "InvalidTemp"]
# which Invalid bit covers a signal; an invalid one is sent as raw 0x8000
COVERS = {"RateX": 0, "BiasX": 0, "RateY": 1, "BiasY": 1, "RateZ": 2, "BiasZ": 2, "Roll": 3, "Pitch": 4, "Yaw": 5}


def camel(name):
    """zero_velocity -> AidZeroVelocity (the DBC's signal of a source)."""
    return "Aid" + "".join(w.capitalize() for w in name.split("_"))


def check_aid_layout(msg, sources):
    """The DBC's EST_AID: one 2-bit signal per source at bits 2i, in the
    library's order, WorstRatio and DataCnt, nothing else."""
    sigs = {s.name: s for s in msg.signals}
    want = [camel(n) for n in sources] + INVALID + ["WorstRatio", "DataCnt"]
    if sorted(sigs) != sorted(want):
        raise SystemExit(f"EST_AID signals {sorted(sigs)}, want {sorted(want)}")
    for i, n in enumerate(sources):
        s = sigs[camel(n)]
        if (s.start, s.length, s.byte_order, s.is_signed) != (2 * i, 2, "little_endian", False):
            raise SystemExit(f"{s.name}: start {s.start} length {s.length} {s.byte_order}, want bit {2 * i}, 2 bits, unsigned Intel")
        choices = {int(k): str(v) for k, v in (s.choices or {}).items()}
        if choices != {0: "not_applicable", 1: "fused", 2: "refused"}:
            raise SystemExit(f"{s.name}: value names {choices}")
    for i, n in enumerate(INVALID):
        s = sigs[n]
        if (s.start, s.length, s.is_signed) != (24 + i, 1, False):
            raise SystemExit(f"{n}: start {s.start} length {s.length}, want bit {24 + i}, 1 bit")
    w = sigs["WorstRatio"]
    if (w.start, w.length, w.scale, w.is_signed) != (32, 16, 0.01, False):
        raise SystemExit(f"WorstRatio: start {w.start} length {w.length} scale {w.scale}")


def main():
    dbc_path, log_path, csv_path = sys.argv[1:4]
    aid_path = sys.argv[4] if len(sys.argv) > 4 else None
    db = cantools.database.load_file(dbc_path)
    rows = list(csv.DictReader(open(csv_path)))
    frames = []
    for line in open(log_path):
        ts, _iface, body = line.split()
        fid, data = body.split("#")
        frames.append((int(fid, 16), bytes.fromhex(data)))
    per = len(frames) // max(len(rows), 1)
    assert per in (4, 5) and len(frames) == per * len(rows), (len(frames), len(rows))
    names = FOUR + ["EST_AID"] if per == 5 else FOUR
    for want in names:
        db.get_message_by_name(want)  # raises if the DBC lacks it
    aid_rows, sources = None, None
    if aid_path:
        if per != 5:
            raise SystemExit(f"{per} frames per sample: no EST_AID to compare with {aid_path}")
        aid_rows = list(csv.DictReader(open(aid_path)))
        if len(aid_rows) != len(rows):
            raise SystemExit(f"{len(aid_rows)} estimates in {aid_path}, {len(rows)} in {csv_path}")
        sources = [c for c in aid_rows[0].keys() if c not in ("cnt", "worst_ratio")]
        check_aid_layout(db.get_message_by_name("EST_AID"), sources)
    # half an LSB of the signal plus the CSV's own rounding
    tol = {"RateX": 0.0051, "RateY": 0.0051, "RateZ": 0.0051,
           "Roll": 0.0051, "Pitch": 0.0051, "Yaw": 0.0051,
           "BiasX": 0.000251, "BiasY": 0.000251, "BiasZ": 0.000251, "TempC": 0.0056}
    col = {"RateX": "rate_x", "RateY": "rate_y", "RateZ": "rate_z",
           "Roll": "roll", "Pitch": "pitch", "Yaw": "yaw",
           "BiasX": "bias_x", "BiasY": "bias_y", "BiasZ": "bias_z", "TempC": "temp"}
    checked = 0
    seen = {"not_applicable": 0, "fused": 0, "refused": 0}
    for k, row in enumerate(rows):
        cnts = set()
        invalid = int(row.get("invalid", 0))
        for j, name in enumerate(names):
            fid, data = frames[per * k + j]
            msg = db.get_message_by_frame_id(fid)
            assert msg.name == name, (k, msg.name, name)
            sig = msg.decode(data, decode_choices=False)
            cnts.add(sig["DataCnt"])
            for s, v in sig.items():
                if s in col:
                    ref = float(row[col[s]])
                    if s in COVERS and invalid >> COVERS[s] & 1:
                        ref = -32768 * msg.get_signal_by_name(s).scale  # the fill value
                    if s == "Yaw" and abs(v - ref) > 359:
                        ref = v  # +-180 wrap rounds either way
                    if abs(v - ref) > tol[s]:
                        raise SystemExit(f"sample {k}: {s} decoded {v} vs csv {ref}")
                    checked += 1
            if name == "EST_STATUS":
                if int(sig["Mode"]) != int(row["mode"]):
                    raise SystemExit(f"sample {k}: Mode {sig['Mode']} vs {row['mode']}")
                checked += 1
            if name == "EST_AID":
                if data[3] != invalid:
                    raise SystemExit(f"sample {k}: EST_AID bits 24-31 are {data[3]:#x}, the CSV's invalid {invalid:#x}")
                for i, n in enumerate(INVALID):
                    if sig[n] != invalid >> i & 1:
                        raise SystemExit(f"sample {k}: {n} decoded {sig[n]} vs the CSV's invalid {invalid:#x}")
                    checked += 1
                if aid_rows is None:
                    continue
                lib = aid_rows[k]
                if int(lib["cnt"]) != sig["DataCnt"]:
                    raise SystemExit(f"sample {k}: EST_AID DataCnt {sig['DataCnt']} vs the estimate's {lib['cnt']}")
                named = msg.decode(data, decode_choices=True)
                for n in sources:
                    got = str(named[camel(n)])
                    if got != lib[n]:
                        raise SystemExit(f"sample {k}: {camel(n)} decoded {got} vs the library's {n} {lib[n]}")
                    seen[got] += 1
                    checked += 1
                r = float(lib["worst_ratio"])
                want = min(max(r, 0.0), 655.35) if math.isfinite(r) else 655.35
                if abs(sig["WorstRatio"] - want) > 0.005 + 1e-9:
                    raise SystemExit(f"sample {k}: WorstRatio decoded {sig['WorstRatio']} vs the library's {r}")
                checked += 1
        if len(cnts) != 1:
            raise SystemExit(f"sample {k}: DataCnt differs across frames {cnts}")
    print(f"dbc_check: {len(rows)} samples, {checked} signal values agree")
    if aid_rows is not None:
        print(f"EST_AID: {len(rows)} frames, source statuses not_applicable {seen['not_applicable']}, "
              f"fused {seen['fused']}, refused {seen['refused']}")


if __name__ == "__main__":
    main()
