"""gyrocomp.gap against `gyrocomp gap`: inputs simulated by the binary
(`gyrocomp simulate` with hidden effects), the same analysis from bytes and
from paths, and the same numbers as report.json / trials.json; bad input
raises naming what and where."""

import json

import pytest

import gyrocomp

from conftest import run, ticks_during

HIDDEN = """[gyro]
effects = ["turn_on_bias", "scale_factor", "time_delay"]
[gyro.turn_on_bias]
bias = [0.1, -0.2, 0.05]
[gyro.scale_factor]
k = [0.0, 0.0, 0.005]
[gyro.time_delay]
delay_s = 0.004
"""
BASE = '[gyro]\neffects = ["turn_on_bias"]\n'


def reference_of(truth_csv):
    """A measured reference from the simulated truth: its angles, every row
    valid, rest where the true rates are zero (the mount is taken there)."""
    lines = truth_csv.read_text().splitlines()
    out = ["t,roll,pitch,yaw,valid,rest"]
    for line in lines[1:]:
        v = line.split(",")
        still = all(float(x) == 0.0 for x in v[4:7])
        out.append(",".join(v[:4]) + f",1,{int(still)}")
    return "\n".join(out) + "\n"


@pytest.fixture(scope="module")
def sims(cli, tmp_path_factory):
    """Two 300-s drives of one unit (seeds 1 and 2) with a hidden scale
    factor on z and a 4-ms delay: imu.log, truth.csv, ref.csv each."""
    d = tmp_path_factory.mktemp("gap")
    (d / "hidden.toml").write_text(HIDDEN)
    (d / "base.toml").write_text(BASE)
    out = []
    for seed in (1, 2):
        s = d / f"sim{seed}"
        run([cli, "simulate", "--scenario", "vehicle", "--seed", seed, "--duration", 300,
             "--model", d / "hidden.toml", "--out", s])
        (s / "ref.csv").write_text(reference_of(s / "truth.csv"))
        out.append(s)
    return d, out


def test_gap_bytes_equals_paths_equals_cli_report_json(cli, sims):
    d, (s1, _) = sims
    run([cli, "gap", "--measured", s1 / "imu.log", "--truth", s1 / "truth.csv",
         "--model", d / "base.toml", "--out", d / "out1"])
    written = json.loads((d / "out1" / "report.json").read_text())
    from_paths = gyrocomp.gap(s1 / "imu.log", truth=str(s1 / "truth.csv"), model=d / "base.toml")
    from_bytes = gyrocomp.gap((s1 / "imu.log").read_bytes(), truth=(s1 / "truth.csv").read_bytes(), model=BASE)
    assert from_bytes == from_paths
    model = from_paths.pop("model")
    assert model == (d / "out1" / "model.toml").read_text()
    assert from_paths == written
    found = {(f["effect"], f["axis"]): f for f in written["findings"]}
    assert set(found) == {("scale_factor", "z"), ("time_delay", "all")}
    sf = found[("scale_factor", "z")]
    assert abs(sf["coefficient"] - 0.005) < 4 * sf["std_error"] and abs(sf["t_stat"]) >= written["t_min"]
    assert [c["term"] for c in written["base_coefficients"]] == ["turn_on_bias x", "turn_on_bias y", "turn_on_bias z"]


def test_gap_trials_equal_cli_trials_json(cli, sims):
    d, sims_ = sims
    logs = [s / "imu.log" for s in sims_]
    refs = [s / "ref.csv" for s in sims_]
    out = d / "out2"
    run([cli, "gap", "--measured", *logs, "--reference", *refs, "--model", d / "base.toml", "--out", out])
    from_paths = gyrocomp.gap(logs, reference=refs, model=str(d / "base.toml"))
    assert from_paths.pop("model") == (out / "model.toml").read_text()
    trials = from_paths.pop("trials")
    assert from_paths == json.loads((out / "trials.json").read_text())
    assert list(trials) == ["sim1", "sim2"]
    for name, rep in trials.items():
        assert rep.pop("model") == (out / name / "model.toml").read_text()
        assert rep == json.loads((out / name / "report.json").read_text())
        assert rep["truth_from"]["source"] != "simulated"
    added = {e["term"] for e in from_paths["effects"] if e["added"]}
    assert added == {"scale_factor z", "time_delay"}
    # from bytes: the same numbers, the trials named trial1, trial2
    from_bytes = gyrocomp.gap([p.read_bytes() for p in logs], reference=[p.read_bytes() for p in refs], model=BASE)
    by_name = dict(zip(["sim1", "sim2"], ["trial1", "trial2"]))
    assert list(from_bytes["trials"]) == ["trial1", "trial2"]
    for name, rep in trials.items():
        b = from_bytes["trials"][by_name[name]]
        b.pop("model")
        assert b == rep
    for e in from_bytes["effects"]:
        for p in e["per_trial"]:
            p["trial"] = {v: k for k, v in by_name.items()}[p["trial"]]
    for h in from_bytes["leave_one_out"]:
        h["trial"] = {v: k for k, v in by_name.items()}[h["trial"]]
    from_bytes.pop("trials")
    from_bytes.pop("model")
    assert from_bytes == from_paths


GOOD_TRUTH = "t,roll,pitch,yaw,p,q,r,fx,fy,fz,temp\n0,0,0,0,0,0,0,0,0,-1,25\n1,0,0,0,0,0,0,0,0,-1,25\n"
CSV_HEAD = "t,gx,gy,gz,ax,ay,az,mx,my,mz,temp\n"


@pytest.mark.parametrize("kw,exc,msg", [
    (dict(measured=b"garbage\nnot a log\n", truth=GOOD_TRUTH.encode()), ValueError, r"^measured:1: .*not a candump log"),
    (dict(measured=(CSV_HEAD + "0,1,2,3,0,0,-1,,,,25\n0.1,1,x,3,0,0,-1,,,,25\n").encode(), truth=GOOD_TRUTH.encode()),
     ValueError, r'^measured:3: column gy: bad number "x"'),
    (dict(measured=(CSV_HEAD + "0,1,2,3,0,0,-1,,,,25\n").encode(), truth=b"t,p,q,r\n0,0,0,0\n"),
     ValueError, r"^truth:1: header must be t,roll,pitch,yaw,p,q,r,fx,fy,fz,temp"),
    (dict(measured=[b"a", b"b"], reference=[b"t,roll,pitch,yaw\n"]), ValueError, r"^reference: 1 input\(s\) for 2 measured"),
    (dict(measured=[b"a", b"b"], truth=b"x"), ValueError, r"several measured inputs need a measured reference each"),
    (dict(measured=b"a"), ValueError, r"^give exactly one of truth= \(simulated\), reference= \(measured\) and static=True"),
    (dict(measured=b"a", static=True, bandwidth=0.0), ValueError, r"^bandwidth = 0: outside 0.1..100 Hz"),
    (dict(measured=b"a", static=True, model="[gyro]\neffects = [\"nope\"]\n"), ValueError, r"(?s)^model: TOML parse error at line 2, column 12.*unknown variant `nope`"),
    (dict(measured=b"a", static=True, profile="adis9"), ValueError, r"^profile \"adis9\": unknown"),
    (dict(measured="/nonexistent/imu.log", static=True), FileNotFoundError, r"^measured: /nonexistent/imu.log: no such file"),
    (dict(measured=3, static=True), TypeError, r"^measured: expected a path"),
])
def test_gap_bad_input_raises_naming_what_and_where(kw, exc, msg):
    with pytest.raises(exc, match=msg):
        gyrocomp.gap(**kw)


def test_gap_bad_reference_row_names_its_line(sims):
    _, (s1, _) = sims
    ref = (s1 / "ref.csv").read_text().splitlines()
    ref[5] = ref[5].split(",")[0] + ",0,200,0,1,1"
    with pytest.raises(ValueError, match=r"^reference line 6, column pitch"):
        gyrocomp.gap((s1 / "imu.log").read_bytes(), reference="\n".join(ref).encode() + b"\n", model=BASE)


def test_gap_releases_the_gil(sims):
    """Another Python thread runs while gap works (two trials with their
    joint analysis and leave-one-out: a call of about half a second)."""
    _, sims_ = sims
    logs = [(s / "imu.log").read_bytes() for s in sims_]
    refs = [(s / "ref.csv").read_bytes() for s in sims_]
    t0, t1, inside = ticks_during(lambda: gyrocomp.gap(logs, reference=refs, model=BASE))
    assert t1 - t0 >= 0.1, f"the call is too short to tell ({t1 - t0:.3f} s)"
    assert len(inside) > 100


def test_gap_static_equals_cli(cli, tmp_path):
    """static=True: a still unit, gzipped bytes and the path alike."""
    import gzip
    run([cli, "simulate", "--scenario", "static", "--seed", 1, "--duration", 60, "--out", tmp_path / "st"])
    (tmp_path / "base.toml").write_text(BASE)
    log = tmp_path / "st" / "imu.log"
    run([cli, "gap", "--measured", log, "--static", "--model", tmp_path / "base.toml", "--out", tmp_path / "out"])
    written = json.loads((tmp_path / "out" / "report.json").read_text())
    from_path = gyrocomp.gap(log, static=True, model=tmp_path / "base.toml")
    from_gz = gyrocomp.gap(gzip.compress(log.read_bytes()), static=True, model=BASE.encode())
    assert from_gz == from_path
    from_path.pop("model")
    assert from_path == written
    assert written["truth_from"]["source"] != "simulated"
