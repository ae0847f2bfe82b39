#!/usr/bin/env python3
"""Read a `gyrocomp replay --mcap` (or `evaluate --mcap`) recording with the
python `mcap` reader (pip install mcap) and check it: the channels, their
schemas and encodings, the message counts, per-channel monotonic log times
equal to the messages' own timestamps, consecutive sequence numbers, unit
quaternions, finite numbers; on gyrocomp.Estimate the aid sources as the
schema lists them, each 0, 1 or 2 and together the aid_status word.

usage: mcap_check.py FILE SAMPLES CAN_FRAMES [TOPIC=SCHEMA ...]
Prints one line "mcap ok: ..." (with how many estimates had an aid source
fused and refused) and exits 0, or names the first problem and exits 1.
"""
import json
import math
import sys

from mcap.reader import make_reader

BASE = {
    "/tf": "foxglove.FrameTransform",
    "/gyrocomp/estimate": "gyrocomp.Estimate",
    "/can/rx": "gyrocomp.CanFrame",
}


def fail(msg):
    print(f"mcap check failed: {msg}")
    sys.exit(1)


def finite(v, where):
    if isinstance(v, dict):
        for k, x in v.items():
            finite(x, f"{where}.{k}")
    elif isinstance(v, list):
        for i, x in enumerate(v):
            finite(x, f"{where}[{i}]")
    elif isinstance(v, float) and not math.isfinite(v):
        fail(f"non-finite {where}")


def main():
    path, samples, can_frames = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
    want = dict(BASE)
    for a in sys.argv[4:]:
        t, s = a.split("=", 1)
        want[t] = s
    with open(path, "rb") as f:
        r = make_reader(f)
        summ = r.get_summary()
        got = {c.topic: summ.schemas[c.schema_id] for c in summ.channels.values()}
        if sorted(got) != sorted(want):
            fail(f"topics {sorted(got)}, want {sorted(want)}")
        for t, s in got.items():
            if s.name != want[t] or s.encoding != "jsonschema":
                fail(f"{t}: schema {s.name} ({s.encoding}), want {want[t]} (jsonschema)")
            json.loads(s.data)
        for c in summ.channels.values():
            if c.message_encoding != "json":
                fail(f"{c.topic}: message encoding {c.message_encoding}")
        # the aid sources in the schema's order: source i at bits 2i..2i+1
        aid_names = None
        for s in summ.schemas.values():
            if s.name == "gyrocomp.Estimate":
                aid_names = list(json.loads(s.data)["properties"]["aid"]["properties"])
        aid_fused = aid_refused = 0
        counts, last, seq = {}, {}, {}
        for schema, ch, m in r.iter_messages(log_time_order=False):
            t = ch.topic
            counts[t] = counts.get(t, 0) + 1
            if t in last and m.log_time < last[t]:
                fail(f"{t}: log time {m.log_time} after {last[t]}")
            last[t] = m.log_time
            if t in seq and m.sequence != seq[t] + 1:
                fail(f"{t}: sequence {m.sequence} after {seq[t]}")
            seq[t] = m.sequence
            if m.publish_time != m.log_time:
                fail(f"{t}: publish time {m.publish_time} != log time {m.log_time}")
            d = json.loads(m.data)
            ts = d["timestamp"]
            if ts["sec"] * 1_000_000_000 + ts["nsec"] != m.log_time:
                fail(f"{t}: timestamp {ts} is not the log time {m.log_time}")
            finite(d, t)
            if schema.name == "foxglove.FrameTransform":
                q = d["rotation"]
                n = math.sqrt(q["x"] ** 2 + q["y"] ** 2 + q["z"] ** 2 + q["w"] ** 2)
                if abs(n - 1.0) > 1e-9:
                    fail(f"{t}: |q| = {n} at {m.log_time}")
                if d["parent_frame_id"] != "world" or not d["child_frame_id"].startswith("base_link"):
                    fail(f"{t}: frames {d['parent_frame_id']} -> {d['child_frame_id']}")
            if schema.name == "gyrocomp.CanFrame" and len(d["data"]) != 2 * d["len"]:
                fail(f"{t}: len {d['len']} with {len(d['data'])} bytes")
            if schema.name == "gyrocomp.Estimate":
                aid = d["aid"]
                if list(aid) != aid_names:
                    fail(f"{t}: aid sources {list(aid)}, the schema's {aid_names}")
                if any(v not in (0, 1, 2) for v in aid.values()):
                    fail(f"{t}: aid codes {aid} at {m.log_time}")
                word = sum(aid[n] << (2 * i) for i, n in enumerate(aid_names))
                if word != d["aid_status"]:
                    fail(f"{t}: aid_status {d['aid_status']} but the sources say {word} at {m.log_time}")
                if not 0.0 <= d["aid_worst_ratio"] <= 655.35:
                    fail(f"{t}: aid_worst_ratio {d['aid_worst_ratio']} at {m.log_time}")
                aid_fused += any(v == 1 for v in aid.values())
                aid_refused += any(v == 2 for v in aid.values())
        for t in want:
            n = counts.get(t, 0)
            expect = can_frames if t == "/can/rx" else samples
            if n != expect:
                fail(f"{t}: {n} messages, want {expect}")
        st = summ.statistics
        if st.message_count != sum(counts.values()):
            fail(f"statistics say {st.message_count} messages, read {sum(counts.values())}")
    print(f"mcap ok: {len(want)} channels, {samples} samples, {can_frames} CAN frames; "
          f"an aid source fused at {aid_fused}, refused at {aid_refused} estimates")


if __name__ == "__main__":
    main()
