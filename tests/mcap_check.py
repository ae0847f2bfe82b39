#!/usr/bin/env python3
"""Read a `gyrocomp replay --mcap` (or `evaluate --mcap`) recording with the
python `mcap` reader and Foxglove's ROS 2 decoder for it (pip install mcap
mcap-ros2-support: it decodes a CDR message from the `ros2msg` schema in
the file, as Foxglove does) and check it: the channels, their schemas and
encodings, the message counts, per-channel monotonic log times equal to the
messages' own timestamps, consecutive sequence numbers, the CDR sizes the
schemas give, unit quaternions and the frames' names, finite numbers; on
gyrocomp/msg/Estimate the flags as the flag word's bits and the aid sources
as the schema lists them, each 0, 1 or 2 and together the aid_status word.

usage: mcap_check.py FILE SAMPLES CAN_FRAMES [TOPIC=SCHEMA ...]
Prints one line "mcap ok: ..." (with how many estimates had an aid source
fused and refused) and exits 0, or names the first problem and exits 1.
"""
import json
import math
import re
import sys

from mcap.decoder import DecoderFactory
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory as Ros2DecoderFactory

BASE = {
    "/tf": "tf2_msgs/msg/TFMessage",
    "/gyrocomp/estimate": "gyrocomp/msg/Estimate",
    "/can/rx": "gyrocomp/msg/CanFrame",
}
SECTION = "=" * 80 + "\n"


def fail(msg):
    print(f"mcap check failed: {msg}")
    sys.exit(1)


def fields(schema_text, section=None):
    """Field names of a ros2msg schema's first section or its `MSG: section`."""
    parts = schema_text.split(SECTION)
    text = parts[0] if section is None else next(p for p in parts if p.startswith(f"MSG: {section}\n"))
    out = []
    for line in text.splitlines():
        line = line.split("#")[0].strip()
        if line and not line.startswith("MSG:"):
            out.append(line.split()[1])
    return out


def plain(v):
    """A decoded ROS 2 message as dicts and lists."""
    if hasattr(v, "__slots__"):
        return {k: plain(getattr(v, k)) for k in v.__slots__}
    if isinstance(v, list):
        return [plain(x) for x in v]
    return v


def finite(v, where):
    if isinstance(v, dict):
        for k, x in v.items():
            finite(x, f"{where}.{k}")
    elif isinstance(v, list):
        for i, x in enumerate(v):
            finite(x, f"{where}[{i}]")
    elif isinstance(v, float) and not math.isfinite(v):
        fail(f"non-finite {where}")


class JsonDecoderFactory(DecoderFactory):
    """The `json` channels (evaluate's attitudes beside the estimate)."""

    def decoder_for(self, message_encoding, schema):
        return json.loads if message_encoding == "json" else None


def cdr_string(n):
    """Bytes of a CDR string of n characters: length, characters, NUL."""
    return 4 + n + 1


def main():
    path, samples, can_frames = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
    want = dict(BASE)
    for a in sys.argv[4:]:
        t, s = a.split("=", 1)
        want[t] = s
    with open(path, "rb") as f:
        r = make_reader(f, decoder_factories=[Ros2DecoderFactory(), JsonDecoderFactory()])
        summ = r.get_summary()
        got = {c.topic: summ.schemas[c.schema_id] for c in summ.channels.values()}
        if sorted(got) != sorted(want):
            fail(f"topics {sorted(got)}, want {sorted(want)}")
        for c in summ.channels.values():
            s = summ.schemas[c.schema_id]
            if s.name != want[c.topic]:
                fail(f"{c.topic}: schema {s.name}, want {want[c.topic]}")
            ros = "/msg/" in s.name
            if (s.encoding, c.message_encoding) != (("ros2msg", "cdr") if ros else ("jsonschema", "json")):
                fail(f"{c.topic}: schema encoding {s.encoding}, message encoding {c.message_encoding}")
            if not ros:
                json.loads(s.data)
        est_text = next((s.data.decode() for s in summ.schemas.values() if s.name == "gyrocomp/msg/Estimate"), None)
        if est_text is None:
            fail("no gyrocomp/msg/Estimate schema")
        top = fields(est_text)
        if top != ["timestamp", "t", "cnt", "roll", "pitch", "yaw", "rate", "bias", "temp", "mode",
                   "accel_ratio", "flags", "flag", "aid_status", "aid_worst_ratio", "aid", "invalid"]:
            fail(f"gyrocomp/msg/Estimate fields {top}")
        # the flags with their bit (from the schema's comments), the aid
        # sources in the schema's order: source i at bits 2i..2i+1
        flag_bits = [(m.group(1), int(m.group(2)))
                     for m in re.finditer(r"^bool (\w+) # bit (\d+) of flags$", est_text, re.M)]
        if [n for n, _ in flag_bits] != fields(est_text, "gyrocomp/Flags"):
            fail(f"flag bits {flag_bits}")
        aid_names = fields(est_text, "gyrocomp/AidSources")
        aid_fused = aid_refused = 0
        counts, last, seq = {}, {}, {}
        for schema, ch, m, msg in r.iter_decoded_messages(log_time_order=False):
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
            d = msg if isinstance(msg, dict) else plain(msg)
            finite(d, t)
            if schema.name == "tf2_msgs/msg/TFMessage":
                if len(d["transforms"]) != 1:
                    fail(f"{t}: {len(d['transforms'])} transforms at {m.log_time}")
                tr = d["transforms"][0]
                parent, child = tr["header"]["frame_id"], tr["child_frame_id"]
                if parent != "world" or not child.startswith("base_link"):
                    fail(f"{t}: frames {parent} -> {child}")
                size = 4 + 8 + cdr_string(len(parent))
                size += (-size) % 4 + cdr_string(len(child))
                size += (-size) % 8 + 7 * 8
                if len(m.data) != 4 + size:
                    fail(f"{t}: {len(m.data)} bytes, the schema says {4 + size}")
                ts = tr["header"]["stamp"]
                q = tr["transform"]["rotation"]
                n = math.sqrt(q["x"] ** 2 + q["y"] ** 2 + q["z"] ** 2 + q["w"] ** 2)
                if abs(n - 1.0) > 1e-9:
                    fail(f"{t}: |q| = {n} at {m.log_time}")
                if any(v != 0.0 for v in tr["transform"]["translation"].values()):
                    fail(f"{t}: a translation at {m.log_time}")
            elif schema.name == "gyrocomp/msg/CanFrame":
                ts = d["timestamp"]
                if len(d["data"]) != d["len"] or len(m.data) != 24 + d["len"]:
                    fail(f"{t}: len {d['len']} with {len(d['data'])} bytes, message {len(m.data)} bytes")
            elif schema.name == "gyrocomp/msg/Estimate":
                ts = d["timestamp"]
                if len(m.data) != 4 + 92 + len(aid_names) + 1:
                    fail(f"{t}: {len(m.data)} bytes")
                if list(d) != top:
                    fail(f"{t}: fields {list(d)}")
                for name, bit in flag_bits:
                    if d["flag"][name] != bool(d["flags"] >> bit & 1):
                        fail(f"{t}: flag.{name} is not bit {bit} of flags {d['flags']} at {m.log_time}")
                aid = d["aid"]
                if list(aid) != aid_names:
                    fail(f"{t}: aid sources {list(aid)}, the schema's {aid_names}")
                if any(v not in (0, 1, 2) for v in aid.values()):
                    fail(f"{t}: aid codes {aid} at {m.log_time}")
                word = sum(aid[n] << (2 * i) for i, n in enumerate(aid_names))
                if word != d["aid_status"]:
                    fail(f"{t}: aid_status {d['aid_status']} but the sources say {word} at {m.log_time}")
                if not 0.0 <= d["aid_worst_ratio"] <= 655.36:
                    fail(f"{t}: aid_worst_ratio {d['aid_worst_ratio']} at {m.log_time}")
                if not 0 <= d["invalid"] < 128:
                    fail(f"{t}: invalid {d['invalid']} at {m.log_time}")
                aid_fused += any(v == 1 for v in aid.values())
                aid_refused += any(v == 2 for v in aid.values())
            else:
                ts = d["timestamp"]
                ts = {"sec": ts["sec"], "nanosec": ts["nsec"]}
            if ts["sec"] * 1_000_000_000 + ts["nanosec"] != m.log_time:
                fail(f"{t}: timestamp {ts} is not the log time {m.log_time}")
        for t in want:
            n = counts.get(t, 0)
            expect = can_frames if t == "/can/rx" else samples
            if n != expect:
                fail(f"{t}: {n} messages, want {expect}")
        st = summ.statistics
        if st.message_count != sum(counts.values()):
            fail(f"statistics say {st.message_count} messages, read {sum(counts.values())}")
        by_id = {c.id: c.topic for c in summ.channels.values()}
        if {by_id[i]: n for i, n in st.channel_message_counts.items()} != counts:
            fail(f"statistics' channel counts {st.channel_message_counts}, read {counts}")
        if not summ.chunk_indexes or st.chunk_count != len(summ.chunk_indexes):
            fail(f"{st.chunk_count} chunks, {len(summ.chunk_indexes)} chunk indexes")
    print(f"mcap ok: {len(want)} channels, {samples} samples, {can_frames} CAN frames; "
          f"an aid source fused at {aid_fused}, refused at {aid_refused} estimates")


if __name__ == "__main__":
    main()
