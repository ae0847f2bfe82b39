#!/usr/bin/env python3
"""Seed corpora for the fuzz targets, from the project's own files.

Writes fuzz/corpus/<target>/ (gitignored) from tests/data/road-40s.log,
config/gyrocomp.toml and config/example-car.dbc. Deterministic: the same files every time.
"""
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
OUT = os.path.join(ROOT, "fuzz", "corpus")


def put(target, name, data):
    d = os.path.join(OUT, target)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, name), "wb") as f:
        f.write(data)


def main():
    with open(os.path.join(ROOT, "tests", "data", "road-40s.log"), "rb") as f:
        lines = f.read().split(b"\n")[:4000]
    # candump_line: single lines, and the other kinds of frame a log can hold
    for k, line in enumerate(lines[:64]):
        put("candump_line", f"road-{k:03}", line)
    extra = [
        b"(1700000000.000100) can0 12345678#0011223344556677",
        b"(1700000000.000200) can0 101#R",
        b"(1700000000.000300) can0 101#R8",
        b"(1700000000.000400) can0 100##1AABBCCDDEEFF00112233",
        b"(1700000000.000500) can0 20000004#0004000000000000",
        b"(1700000000.000600) can0 100#0102030405060708 R",
        b"(1700000000.000700) can0 100#0102030405060708\r",
    ]
    for k, line in enumerate(extra):
        put("candump_line", f"kind-{k}", line)
    # line_reader: 4 chunk-size bytes, then a piece of the log
    for k, n in enumerate([8, 40, 200]):
        put("line_reader", f"road-{n}", bytes([k * 50 + 1, 3, 90, 255]) + b"\n".join(lines[:n]) + b"\n")
    put("line_reader", "long-line", bytes([255, 255, 255, 255]) + b"x" * 700 + b"\n" + lines[0] + b"\n")
    # adis_assembler / pipeline: [selector] then per frame [part] + 8 payload bytes
    frames = []
    for line in lines:
        if b"#" not in line:
            continue
        ident, data = line.split(b" ")[-1].split(b"#")
        part = int(ident, 16) - 0x100
        if 0 <= part < 4 and len(data) == 16:
            frames.append(bytes([part]) + bytes.fromhex(data.decode()))
    for n in [16, 120, 400]:
        body = b"".join(frames[: 4 * n])
        for sel in [0x00, 0x81]:
            put("adis_assembler", f"road-{n}-{sel:02x}", bytes([sel]) + body)
        for sel in [0x80, 0x81, 0x82, 0x83, 0x85]:
            put("pipeline", f"road-{n}-{sel:02x}", bytes([sel]) + body)
    # dbc: the example car's DBC, then a 0 byte and a few frames
    with open(os.path.join(ROOT, "config", "example-car.dbc"), "rb") as f:
        dbc = f.read()
    put("dbc", "example-car", dbc)
    put("dbc", "example-car-frames", dbc + b"\x00" + bytes([8]) + bytes(range(8)) + bytes([5]) + b"\xff" * 5)
    # config: the shipped example and small ones
    with open(os.path.join(ROOT, "config", "gyrocomp.toml"), "rb") as f:
        put("config", "shipped", f.read())
    for k, text in enumerate([
        b"",
        b"[input]\nprofile = \"adis16405\"\nrate_hz = 0.0\n",
        b"[input.ids]\ngyro = 0x200\n",
        b"[switching]\ninner = [0.99, 1.01]\nouter = [0.8, 1.2]\n",
        b"[thermal]\norder = 3\np1 = [0.002, 0.0044, 0.0192]\np3 = [1e-5, 0.0, 0.0]\np4 = [0.0, 0.0, 1e-7]\nt_min = 0.0\nt_max = 70.0\n",
        b"[estimator]\nmode = \"paper\"\n[robust]\nvehicle_model = false\n",
        b"output = { rate_id = 0x210 }\n",
    ]):
        put("config", f"small-{k}", text)
    print(f"seed corpora in {OUT}", file=sys.stderr)


if __name__ == "__main__":
    main()
