//! `gyrocomp gap` through the binary: files in, files out; bad input.

use std::path::Path;
use std::process::Command;

fn exe() -> Command {
    Command::new(env!("CARGO_BIN_EXE_gyrocomp"))
}

fn ok(c: &mut Command) -> String {
    let o = c.output().unwrap();
    let out = String::from_utf8_lossy(&o.stdout).to_string() + &String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{out}");
    out
}

/// Runs, must fail; returns stderr.
fn fails(c: &mut Command) -> String {
    let o = c.output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(!o.status.success(), "should fail: {err}");
    assert!(!err.contains("panicked"), "{err}");
    err
}

fn gap(m: &Path, truth: &Path, model: &Path, out: &Path) -> Command {
    let mut c = exe();
    c.arg("gap").arg("--measured").arg(m).arg("--truth").arg(truth).arg("--model").arg(model).arg("--out").arg(out);
    c
}

const HIDDEN: &str = "[gyro]
effects = [\"turn_on_bias\", \"thermal_linear\", \"scale_factor\"]
[gyro.turn_on_bias]
bias = [0.12, -0.31, 0.05]
[gyro.thermal_linear]
t0 = 25.0
p1 = [0.002, 0.0044, 0.0192]
[gyro.scale_factor]
k = [0.0, 0.0, 0.005]
";
const PAPER: &str = "[gyro]\neffects = [\"turn_on_bias\", \"thermal_linear\"]\n";

#[test]
fn log_in_report_and_model_out_model_accepted_back() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    std::fs::write(p.join("hidden.toml"), HIDDEN).unwrap();
    std::fs::write(p.join("paper.toml"), PAPER).unwrap();
    ok(exe()
        .args(["simulate", "--scenario", "vehicle", "--seed", "1", "--duration", "800", "--model"])
        .arg(p.join("hidden.toml"))
        .arg("--out")
        .arg(p.join("sim")));
    let out = ok(&mut gap(&p.join("sim/imu.log"), &p.join("sim/truth.csv"), &p.join("paper.toml"), &p.join("gap")));
    assert!(out.contains("found scale_factor z"), "{out}");
    let rep: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(p.join("gap/report.json")).unwrap()).unwrap();
    assert_eq!(rep["clean"], false);
    let f = &rep["findings"][0];
    assert_eq!(f["effect"], "scale_factor");
    assert_eq!(f["axis"], "z");
    assert_eq!(f["unit"], "1");
    let k = f["coefficient"].as_f64().unwrap();
    assert!((k - 0.005).abs() <= 0.0005, "{k}");
    for key in ["rms_before", "rms_after"] {
        assert_eq!(f[key].as_array().unwrap().len(), 3);
    }
    assert!(f["rms_after"][2].as_f64().unwrap() <= 0.5 * f["rms_before"][2].as_f64().unwrap());
    let (t, se) = (f["t_stat"].as_f64().unwrap(), f["std_error"].as_f64().unwrap());
    assert!(t.abs() >= gyrocomp::gap::T_MIN && se > 0.0 && (k / se - t).abs() < 1e-6 * t.abs(), "t {t}, SE {se}");
    for name in ["report.md", "model.toml", "residual.svg", "finding_1_scale_factor_z.svg"] {
        let t = std::fs::read_to_string(p.join("gap").join(name)).unwrap();
        assert!(!t.is_empty(), "{name}");
        if name.ends_with(".svg") {
            assert!(t.contains("<svg"), "{name}");
        }
    }
    let md = std::fs::read_to_string(p.join("gap/report.md")).unwrap();
    assert!(md.contains("scale_factor z"), "{md}");
    // the extended model is accepted as it is by simulate --model ...
    ok(exe()
        .args(["simulate", "--scenario", "vehicle", "--seed", "2", "--duration", "60", "--model"])
        .arg(p.join("gap/model.toml"))
        .arg("--out")
        .arg(p.join("sim2")));
    // ... and by gap --model: on the same data, nothing is missing any more
    let out = ok(&mut gap(&p.join("sim/imu.log"), &p.join("sim/truth.csv"), &p.join("gap/model.toml"), &p.join("gap2")));
    assert!(out.contains("clean"), "{out}");
    let rep: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(p.join("gap2/report.json")).unwrap()).unwrap();
    assert_eq!(rep["clean"], true);
    assert_eq!(rep["findings"].as_array().unwrap().len(), 0);
}

#[test]
fn csv_measured_and_truth_without_temp() {
    // measured as CSV (from the log's samples), truth without its temp column
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    std::fs::write(p.join("hidden.toml"), HIDDEN).unwrap();
    std::fs::write(p.join("paper.toml"), PAPER).unwrap();
    ok(exe()
        .args(["simulate", "--scenario", "vehicle", "--seed", "3", "--duration", "600", "--model"])
        .arg(p.join("hidden.toml"))
        .arg("--out")
        .arg(p.join("sim")));
    let log = std::fs::read(p.join("sim/imu.log")).unwrap();
    let prof = gyrocomp::adis::builtin_profile("adis16448").unwrap();
    let mut asm = gyrocomp::adis::Assembler::new(prof, gyrocomp::adis::InputIds::DEFAULT);
    let mut csv = String::from("t,gx,gy,gz,ax,ay,az,mx,my,mz,temp\n");
    let mut t0 = None;
    for line in log.split(|b| *b == b'\n').filter(|l| !l.is_empty()) {
        let f = gyrocomp::candump::parse_line(line).unwrap();
        let raw = gyrocomp::adis::RawFrame { id: f.id, extended: f.extended, remote: f.remote, fd: f.fd, data: f.payload() };
        if let gyrocomp::adis::Push::Sample(s) = asm.push(f.t_us, raw) {
            let t = (s.t_us - *t0.get_or_insert(s.t_us)) as f64 * 1e-6;
            csv += &format!(
                "{t:.6},{},{},{},{},{},{},{},{},{},{}\n",
                s.gyro[0], s.gyro[1], s.gyro[2], s.accel[0], s.accel[1], s.accel[2], s.magn[0], s.magn[1], s.magn[2], s.temp
            );
        }
    }
    std::fs::write(p.join("m.csv"), csv).unwrap();
    let truth = std::fs::read_to_string(p.join("sim/truth.csv")).unwrap();
    let no_temp: String = truth.lines().map(|l| l.rsplit_once(',').unwrap().0.to_string() + "\n").collect();
    std::fs::write(p.join("truth.csv"), no_temp).unwrap();
    let out = ok(&mut gap(&p.join("m.csv"), &p.join("truth.csv"), &p.join("paper.toml"), &p.join("gap")));
    assert!(out.contains("found scale_factor z"), "{out}");
}

#[test]
fn bad_input_is_named() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    std::fs::write(p.join("paper.toml"), PAPER).unwrap();
    ok(exe().args(["simulate", "--scenario", "static", "--seed", "1", "--duration", "20", "--out"]).arg(p.join("sim")));
    let (log, truth, model) = (p.join("sim/imu.log"), p.join("sim/truth.csv"), p.join("paper.toml"));
    let out = p.join("gap");
    // missing files
    let e = fails(&mut gap(&p.join("nope.log"), &truth, &model, &out));
    assert!(e.contains("nope.log"), "{e}");
    let e = fails(&mut gap(&log, &p.join("nope.csv"), &model, &out));
    assert!(e.contains("nope.csv"), "{e}");
    let e = fails(&mut gap(&log, &truth, &p.join("nope.toml"), &out));
    assert!(e.contains("nope.toml"), "{e}");
    // unknown effect name in the model: file and key
    std::fs::write(p.join("bad.toml"), "[gyro]\neffects = [\"turn_on_bias\", \"warp_drive\"]\n").unwrap();
    let e = fails(&mut gap(&log, &truth, &p.join("bad.toml"), &out));
    assert!(e.contains("bad.toml") && e.contains("warp_drive"), "{e}");
    // unknown key in an effect table
    std::fs::write(p.join("bad2.toml"), "[gyro]\neffects = [\"turn_on_bias\"]\n[gyro.turn_on_bias]\nbias = [0, 0, 0]\nscale = 1\n")
        .unwrap();
    let e = fails(&mut gap(&log, &truth, &p.join("bad2.toml"), &out));
    assert!(e.contains("bad2.toml") && e.contains("scale"), "{e}");
    // a model beyond its physical ranges (the simulator and the fit overflowed:
    // [noise] gyro_white = 1e300 panicked in check 3): file, line and key
    for (text, key, line) in [
        ("[gyro]\neffects = []\n[noise]\ngyro_white = 1e300\n", "noise.gyro_white", "line 4"),
        ("[gyro]\neffects = []\n[noise]\ngyro_bias_walk = 1e300\n", "noise.gyro_bias_walk", "line 4"),
        ("[gyro]\neffects = [\"turn_on_bias\"]\n[gyro.turn_on_bias]\nbias = [1e300, 0, 0]\n", "gyro.turn_on_bias.bias", "line 4"),
    ] {
        std::fs::write(p.join("huge.toml"), text).unwrap();
        let e = fails(&mut gap(&log, &truth, &p.join("huge.toml"), &out));
        assert!(e.contains("huge.toml") && e.contains(key) && e.contains(line) && e.contains("must be within"), "{e}");
        let o = exe()
            .args(["simulate", "--scenario", "static", "--duration", "20", "--model"])
            .arg(p.join("huge.toml"))
            .arg("--out")
            .arg(p.join("s2"))
            .output()
            .unwrap();
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{e}");
        assert!(e.contains(key) && e.contains(line), "{e}");
    }
    // malformed truth CSV: file and line
    let mut t = std::fs::read_to_string(&truth).unwrap();
    let at = t.match_indices('\n').nth(5).unwrap().0;
    t.insert_str(at + 1, "1.0,abc,0,0,0,0,0,0,0,0,25\n");
    std::fs::write(p.join("t_bad.csv"), t).unwrap();
    let e = fails(&mut gap(&log, &p.join("t_bad.csv"), &model, &out));
    assert!(e.contains("t_bad.csv:7"), "{e}");
    // malformed measured CSV: file and line
    std::fs::write(p.join("m_bad.csv"), "t,gx,gy,gz,ax,ay,az,mx,my,mz,temp\n0,0,0,0,0,0,0,0,0,0,25\n0.1,0,0\n").unwrap();
    let e = fails(&mut gap(&p.join("m_bad.csv"), &truth, &model, &out));
    assert!(e.contains("m_bad.csv:3"), "{e}");
    // a log that is not a log: file and line
    std::fs::write(p.join("junk.log"), "hello\nworld\n").unwrap();
    let e = fails(&mut gap(&p.join("junk.log"), &truth, &model, &out));
    assert!(e.contains("junk.log:1"), "{e}");
    // measured and truth that do not overlap in time
    std::fs::write(p.join("late.csv"), "t,gx,gy,gz,ax,ay,az,mx,my,mz,temp\n1000,0,0,0,0,0,0,0,0,0,25\n1000.1,0,0,0,0,0,0,0,0,0,25\n")
        .unwrap();
    let e = fails(&mut gap(&p.join("late.csv"), &truth, &model, &out));
    assert!(e.contains("line up"), "{e}");
}

const CLEAN: &str = "[gyro]
effects = [\"turn_on_bias\", \"thermal_linear\"]
[gyro.turn_on_bias]
bias = [0.12, -0.31, 0.05]
[gyro.thermal_linear]
t0 = 25.0
p1 = [0.002, 0.0044, 0.0192]
";

fn simulate(p: &Path, model: &str, scenario: &str, seed: u32, duration: u32, dir: &str) {
    std::fs::write(p.join(format!("{dir}.toml")), model).unwrap();
    ok(exe()
        .args(["simulate", "--scenario", scenario, "--seed", &seed.to_string(), "--duration", &duration.to_string(), "--model"])
        .arg(p.join(format!("{dir}.toml")))
        .arg("--out")
        .arg(p.join(dir)));
}

#[test]
fn clean_run_finds_nothing() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    std::fs::write(p.join("paper.toml"), PAPER).unwrap();
    simulate(p, CLEAN, "vehicle", 4, 400, "sim");
    let out = ok(&mut gap(&p.join("sim/imu.log"), &p.join("sim/truth.csv"), &p.join("paper.toml"), &p.join("gap")));
    assert!(out.contains("clean: nothing missing") && !out.contains("found "), "{out}");
    let rep: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(p.join("gap/report.json")).unwrap()).unwrap();
    assert_eq!(rep["clean"], true);
    assert_eq!(rep["findings"].as_array().unwrap().len(), 0);
    assert_eq!(rep["ambiguous"].as_array().unwrap().len(), 0);
    // the noise model fits the data: whitened residual variance near 1 on every axis
    for v in rep["variance_ratio_final"].as_array().unwrap() {
        assert!((v.as_f64().unwrap() - 1.0).abs() < 0.05, "{}", rep["variance_ratio_final"]);
    }
    // same inputs, byte-identical outputs
    ok(&mut gap(&p.join("sim/imu.log"), &p.join("sim/truth.csv"), &p.join("paper.toml"), &p.join("gap2")));
    for name in ["report.json", "report.md", "model.toml", "residual.svg"] {
        assert!(std::fs::read(p.join("gap").join(name)).unwrap() == std::fs::read(p.join("gap2").join(name)).unwrap(), "{name} differs");
    }
}

#[test]
fn shared_time_delay_is_one_finding_for_all_axes() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    std::fs::write(p.join("paper.toml"), PAPER).unwrap();
    let hidden = CLEAN.replace("\"thermal_linear\"]", "\"thermal_linear\", \"time_delay\"]") + "[gyro.time_delay]\ndelay_s = 0.004\n";
    simulate(p, &hidden, "vehicle", 5, 400, "sim");
    let out = ok(&mut gap(&p.join("sim/imu.log"), &p.join("sim/truth.csv"), &p.join("paper.toml"), &p.join("gap")));
    assert!(out.contains("found time_delay (one delay shared by all axes): "), "{out}");
    assert!(!out.contains(" on z") && !out.contains("found on"), "{out}");
    let rep: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(p.join("gap/report.json")).unwrap()).unwrap();
    let f = &rep["findings"][0];
    assert_eq!(f["effect"], "time_delay");
    assert_eq!(f["axis"], "all");
    assert_eq!(f["evidence"]["shared_by_all_axes"], true);
    let k = f["coefficient"].as_f64().unwrap();
    assert!((k - 0.004).abs() <= 0.0004, "{k}");
    assert_eq!(rep["findings"].as_array().unwrap().len(), 1, "{}", rep["findings"]);
    let md = std::fs::read_to_string(p.join("gap/report.md")).unwrap();
    assert!(md.contains("`time_delay` (one delay shared by all axes)"), "{md}");
    assert!(p.join("gap/finding_1_time_delay_all.svg").exists());
}

#[test]
fn mismatched_measured_and_truth_are_refused() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    std::fs::write(p.join("paper.toml"), PAPER).unwrap();
    simulate(p, CLEAN, "vehicle", 1, 300, "a");
    simulate(p, CLEAN, "vehicle", 2, 300, "b");
    // measured of run a, truth of run b: the temperatures disagree
    let e = fails(&mut gap(&p.join("a/imu.log"), &p.join("b/truth.csv"), &p.join("paper.toml"), &p.join("gap")));
    assert!(e.contains("measured and truth do not agree") && e.contains("temperature") && e.contains("Refusing"), "{e}");
    assert!(!p.join("gap/report.json").exists(), "a refused run writes no report");
    // without the truth's temperature: the rates disagree
    let truth = std::fs::read_to_string(p.join("b/truth.csv")).unwrap();
    let no_temp: String = truth.lines().map(|l| l.rsplit_once(',').unwrap().0.to_string() + "\n").collect();
    std::fs::write(p.join("b_no_temp.csv"), no_temp).unwrap();
    let e = fails(&mut gap(&p.join("a/imu.log"), &p.join("b_no_temp.csv"), &p.join("paper.toml"), &p.join("gap")));
    assert!(e.contains("measured and truth do not agree") && e.contains("correlation") && e.contains("Refusing"), "{e}");
    // the same files matched are accepted
    ok(&mut gap(&p.join("b/imu.log"), &p.join("b_no_temp.csv"), &p.join("paper.toml"), &p.join("gap")));
}

#[test]
fn every_option_explains_itself() {
    let o = exe().args(["gap", "--help"]).output().unwrap();
    let h = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{h}");
    for want in [
        "--measured",
        "--truth",
        "--model",
        "--out",
        "--profile",
        "deg/s",
        "deg C",
        "deg/s/sqrt(Hz)",
        "default 0.0135",
        "default 0.0002",
        "[default: adis16448]",
        "LSB",
    ] {
        assert!(h.contains(want), "gap --help lacks {want:?}:\n{h}");
    }
}

#[test]
fn an_input_is_never_an_output() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    std::fs::write(p.join("paper.toml"), PAPER).unwrap();
    simulate(p, CLEAN, "static", 1, 30, "sim");
    // the output directory holds the base model under an output's name
    std::fs::create_dir_all(p.join("gap")).unwrap();
    std::fs::write(p.join("gap/model.toml"), PAPER).unwrap();
    let e = fails(&mut gap(&p.join("sim/imu.log"), &p.join("sim/truth.csv"), &p.join("gap/model.toml"), &p.join("gap")));
    assert!(e.contains("refusing to overwrite an input"), "{e}");
    assert_eq!(std::fs::read_to_string(p.join("gap/model.toml")).unwrap(), PAPER);
}
