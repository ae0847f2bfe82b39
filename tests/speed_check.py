#!/usr/bin/env python3
"""Decode a speed message of a candump log with an independent decoder
(python cantools + the DBC), for tests/speed_dbc.rs to compare with
gyrocomp's src/speed.rs.

usage: speed_check.py DBC LOG[.gz] MESSAGE SIGNAL [SIGNAL...]

Prints one line per frame of MESSAGE's ID, in log order:
  HEX SPEED_M_S        the mean of the signals, converted to m/s from the DBC unit
  HEX OUT_OF_RANGE     a signal outside its DBC [min|max] (none for [0|0])
  HEX WRONG_DLC        a payload length other than the message's
"""
import gzip
import sys

import cantools

UNITS = {"km/h": 1 / 3.6, "kph": 1 / 3.6, "kmh": 1 / 3.6, "m/s": 1.0, "mph": 0.44704}


def main():
    dbc_path, log_path, message = sys.argv[1:4]
    signals = sys.argv[4:]
    db = cantools.database.load_file(dbc_path)
    msg = db.get_message_by_name(message)
    sigs = [msg.get_signal_by_name(s) for s in signals]
    to_ms = [UNITS[s.unit.strip().lower()] for s in sigs]
    opener = gzip.open if log_path.endswith(".gz") else open
    n = 0
    with opener(log_path, "rt") as f:
        for line in f:
            parts = line.split()
            if len(parts) != 3 or "#" not in parts[2]:
                continue
            fid, data = parts[2].split("#", 1)
            ext = len(fid) > 3
            if int(fid, 16) != msg.frame_id or ext != msg.is_extended_frame:
                continue
            payload = bytes.fromhex(data)
            n += 1
            if len(payload) != msg.length:
                print(f"{data} WRONG_DLC")
                continue
            vals = msg.decode(payload, decode_choices=False, scaling=True)
            out = False
            total = 0.0
            for s, k in zip(sigs, to_ms):
                v = vals[s.name]
                half = abs(s.scale) / 2 + 1e-9 * abs(v)
                if s.minimum is not None and v < s.minimum - half:
                    out = True
                if s.maximum is not None and v > s.maximum + half:
                    out = True
                total += v * k
            print(f"{data} OUT_OF_RANGE" if out else f"{data} {total / len(sigs)!r}")
    print(f"# {n} frames of {message}", file=sys.stderr)


if __name__ == "__main__":
    main()
