#!/usr/bin/env python3
"""Frames of a DBC-described IMU, encoded by python cantools, for gyrocomp to decode.

Usage: dbc_input_check.py CONFIG.toml N SEED OUT.log OUT.csv

Reads the config's [input] (tomllib) and its DBC (cantools), draws N samples of
random raw values for every signal of the sample's messages, sets the counters
(with a skip every 37 samples), the validity signals (wrong one sample in 9) and
the CRC (CRC-8 SAE J1850, written out here) and writes the frames as a candump
log. Every 50th sample has one frame's CRC corrupted. OUT.csv holds, per sample
gyrocomp must deliver, the channels as this script computes them from cantools'
decoding and the config's mapping (sign flips, sign-magnitude, units), and
whether the sample is suspect; the last line counts the corrupted frames. The
mapping's semantics are implemented here again, independently of gyrocomp.
"""
import math
import os
import random
import sys
import tomllib

import cantools

CHANNELS = ["gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z", "temp"]
UNITS = {
    "deg/s": (1.0, 0.0), "rad/s": (180.0 / math.pi, 0.0),
    "g": (1.0, 0.0), "m/s^2": (1.0 / 9.80665, 0.0),
    "degc": (1.0, 0.0), "k": (1.0, -273.15),
}


def kind(ch):
    return "gyro" if ch.startswith("gyro") else "accel" if ch.startswith("accel") else "temp"


def crc8_j1850(data):
    table = []
    for i in range(256):
        c = i
        for _ in range(8):
            c = ((c << 1) ^ 0x1D) & 0xFF if c & 0x80 else (c << 1) & 0xFF
        table.append(c)
    c = 0xFF
    for b in data:
        c = table[c ^ b]
    return c ^ 0xFF


def main():
    cfg_path, n, seed, out_log, out_csv = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4], sys.argv[5]
    with open(cfg_path, "rb") as f:
        inp = tomllib.load(f)["input"]
    db = cantools.database.load_file(os.path.join(os.path.dirname(cfg_path), inp["dbc"]), strict=False)
    rng = random.Random(seed)
    units = {k: v.lower() for k, v in inp.get("units", {}).items()}
    sa = inp.get("source_address")

    # channel -> (message, signal, flip, sign-bit signal or None)
    mapping, msgs = {}, []
    for ch in CHANNELS:
        ref = inp.get("signals", {}).get(ch)
        if ref is None:
            continue
        sign = None
        if isinstance(ref, dict):
            sign = ref["sign_bit"].split(".")[1]
            ref = ref["signal"]
        flip = -1.0 if ref.startswith("-") else 1.0
        m, s = ref.lstrip("-").split(".")
        mapping[ch] = (m, s, flip, sign)
        if m not in msgs:
            msgs.append(m)
    counters = {}
    for c in inp.get("sample", {}).get("counter", []):
        m, s = c.split(".")
        counters[m] = s
    valid = {}
    for k, v in inp.get("valid", {}).items():
        m, s = k.split(".")
        valid.setdefault(m, []).append((s, v))
    width = {db.get_message_by_name(m).get_signal_by_name(s).length for m, s in counters.items()}
    modulus = 1 << (width.pop() if width else 16)

    log, rows, corrupted = [], [], 0
    t_us, cnt = 1_700_000_000_000_000, 0
    for k in range(n):
        if k % 37 == 36:
            cnt = (cnt + 1) % modulus  # a lost sample
        suspect, decoded, bad, dropped = False, {}, (k % 50 == 49), False
        for i, name in enumerate(msgs):
            msg = db.get_message_by_name(name)
            raw = {}
            for sig in msg.signals:
                lo, hi = (-(1 << (sig.length - 1)), (1 << (sig.length - 1)) - 1) if sig.is_signed else (0, (1 << sig.length) - 1)
                raw[sig.name] = rng.randint(lo, hi)
            if name in counters:
                raw[counters[name]] = cnt
            for s, want in valid.get(name, []):
                if rng.randrange(9) != 0:
                    raw[s] = want
                suspect |= raw[s] != want
            crc = next((s for s in msg.signals if "CRC" in s.name.upper() and "J1850" in (s.comment or "").upper()), None)
            if crc is not None:
                raw[crc.name] = 0
            data = bytearray(msg.encode(raw, scaling=False, strict=False))
            if crc is not None:
                at = crc.start // 8
                data[at] = crc8_j1850(bytes(data[:at] + data[at + 1:]))
                if bad and i == 0:
                    data[at] ^= 0x5A
                    corrupted += 1
                    dropped = True
            decoded[name] = msg.decode(bytes(data), decode_choices=False, scaling=True)
            fid = msg.frame_id
            if sa is not None:
                fid = (fid & 0x03FFFF00) | sa | (rng.randrange(8) << 26)  # any priority
            ident = f"{fid:08X}" if msg.is_extended_frame else f"{fid:03X}"
            sep = "##0" if msg.length > 8 else "#"
            log.append(f"({(t_us + 300 * i) / 1e6:.6f}) vcan0 {ident}{sep}{bytes(data).hex().upper()}\n")
        if not dropped:
            row = []
            for ch in CHANNELS:
                if ch not in mapping:
                    row.append("")
                    continue
                m, s, flip, sign = mapping[ch]
                sig = db.get_message_by_name(m).get_signal_by_name(s)
                unit = units.get(kind(ch), sig.unit or "").lower()
                mul, add = UNITS[unit]
                v = (decoded[m][s] * mul + add) * flip
                if sign is not None and decoded[m][sign]:
                    v = -v
                row.append(repr(v))
            rows.append(",".join(row) + f",{int(suspect)}\n")
        cnt = (cnt + 1) % modulus
        t_us += 10_000
    with open(out_log, "w") as f:
        f.writelines(log)
    with open(out_csv, "w") as f:
        f.write(",".join(CHANNELS) + ",suspect\n")
        f.writelines(rows)
        f.write(f"# corrupted {corrupted}\n")
    print(f"{n} samples encoded by cantools {cantools.__version__}, {len(rows)} to deliver, {corrupted} frames with a bad CRC")


if __name__ == "__main__":
    main()
