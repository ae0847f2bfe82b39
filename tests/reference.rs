//! `gyrocomp evaluate --reference`: scoring against a measured reference,
//! proved on simulated runs whose truth is known exactly.

mod common;
use common::bin;
use gyrocomp::config::Config;
use gyrocomp::reference::refcsv::read_reference;
use gyrocomp::reference::score::wrap180;
use gyrocomp::reference::{decode, evaluate_samples, run_ours, Evaluation, RefOptions};
use gyrocomp::sim::{read_truth, simulate, SimOptions, TruthRow};
use nalgebra::UnitQuaternion;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The sensor's attitude in the reference body (a constant mounting tilt), deg.
const MOUNT: [f64; 2] = [1.5, -2.0];

/// A 120-s vehicle run (parked for the first 3 s) without accelerometer bias,
/// so the accelerometer's tilt at rest is the truth's.
fn sim(dir: &Path) -> (Config, Vec<gyrocomp::adis::Sample>, Vec<TruthRow>) {
    let mut o = SimOptions::new("vehicle", 4);
    o.duration = Some(120.0);
    o.ranges = Some("accel_bias = 0.0\n".into());
    simulate(&o, dir).unwrap();
    let cfg = Config::load(&dir.join("config.toml")).unwrap();
    let d = decode(std::fs::File::open(dir.join("imu.log")).unwrap(), &cfg, "imu.log").unwrap();
    let truth = read_truth(&dir.join("truth.csv")).unwrap();
    assert_eq!(d.samples.len(), truth.len());
    (cfg, d.samples, truth)
}

fn q(a: [f64; 3]) -> UnitQuaternion<f64> {
    UnitQuaternion::from_euler_angles(a[0].to_radians(), a[1].to_radians(), a[2].to_radians())
}

fn deg(q: &UnitQuaternion<f64>) -> [f64; 3] {
    let (r, p, y) = q.euler_angles();
    [r.to_degrees(), p.to_degrees(), y.to_degrees()]
}

/// The reference body's attitude: the truth with the mount taken out.
fn reference_rows(truth: &[TruthRow]) -> Vec<(f64, [f64; 3])> {
    let m = q([MOUNT[0], MOUNT[1], 0.0]);
    truth.iter().map(|r| (r.t, deg(&(q(r.att) * m.inverse())))).collect()
}

/// Write a reference CSV: `cols` = "rest" (rest for t < 3 s), or "" (no rest
/// column); `invalid(t)` rows get valid = 0 and `garbage` angles.
fn write_ref(path: &Path, rows: &[(f64, [f64; 3])], rest: bool, invalid: &dyn Fn(f64) -> bool, garbage: &str) {
    let mut s = String::from(if rest { "t,roll,pitch,yaw,valid,rest\n" } else { "t,roll,pitch,yaw,valid\n" });
    for (t, a) in rows {
        let r = if rest { format!(",{}", (*t < 3.0) as u8) } else { String::new() };
        if invalid(*t) {
            s += &format!("{t:.6},{garbage},0{r}\n");
        } else {
            s += &format!("{t:.6},{:.6},{:.6},{:.6},1{r}\n", a[0], a[1], a[2]);
        }
    }
    std::fs::write(path, s).unwrap();
}

/// Max and RMS of the error against the simulator's own truth, from `skip`.
fn truth_scores(att: &[[f64; 3]], truth: &[TruthRow], skip: f64) -> [[f64; 2]; 2] {
    let mut out = [[0.0f64; 2]; 2];
    let mut n = 0.0;
    for (a, t) in att.iter().zip(truth) {
        if t.t < skip {
            continue;
        }
        let e = [wrap180(a[0] - t.att[0]), a[1] - t.att[1]];
        for i in 0..2 {
            out[i][0] = out[i][0].max(e[i].abs());
            out[i][1] += e[i] * e[i];
        }
        n += 1.0;
    }
    for o in &mut out {
        o[1] = (o[1] / n).sqrt();
    }
    out
}

fn close(got: f64, want: f64, what: &str) {
    // The same error seen from a body tilted by the mount (2.5 deg = 0.044 rad)
    // splits into roll and pitch differently by at most about that fraction.
    assert!((got - want).abs() <= 0.02 + 0.05 * want.abs(), "{what}: {got} vs truth {want}");
}

/// `gyrocomp evaluate --reference ... --align-s S` (S given: without a rest
/// phase the mount is taken from the first S seconds whatever they hold).
fn eval(cfg: &Config, samples: &[gyrocomp::adis::Sample], refp: &Path, align_s: f64) -> Evaluation {
    let r = read_reference(refp).unwrap();
    evaluate_samples(samples, cfg, &r, &RefOptions { skip: 10.0, align_s, force_align: true, peers: true, ..Default::default() }).unwrap()
}

#[test]
fn a_known_mounting_tilt_is_recovered_and_scores_match_the_truth() {
    let d = tempfile::tempdir().unwrap();
    let (cfg, samples, truth) = sim(&d.path().join("run"));
    let refp = d.path().join("ref.csv");
    write_ref(&refp, &reference_rows(&truth), true, &|_| false, "");
    let ev = eval(&cfg, &samples, &refp, 5.0);
    let a = &ev.alignment;
    assert_eq!(a.window.source, "first rest phase");
    assert!((a.roll_deg - MOUNT[0]).abs() < 0.05 && (a.pitch_deg - MOUNT[1]).abs() < 0.05, "mount recovered as {a:?}");
    // Ours against the reference equals ours against the truth.
    let (att, _, _) = run_ours(&samples, &cfg);
    let want = truth_scores(&att, &truth, 10.0);
    let ours = &ev.results[0].scores;
    eprintln!(
        "against the reference (mount {:.3}/{:.3} deg recovered): roll {:.3}/{:.3}, pitch {:.3}/{:.3} (max/RMS); against the truth: roll {:.3}/{:.3}, pitch {:.3}/{:.3}",
        a.roll_deg, a.pitch_deg, ours.roll.max, ours.roll.rms, ours.pitch.max, ours.pitch.rms, want[0][0], want[0][1], want[1][0], want[1][1]
    );
    close(ours.roll.max, want[0][0], "roll max");
    close(ours.roll.rms, want[0][1], "roll rms");
    close(ours.pitch.max, want[1][0], "pitch max");
    close(ours.pitch.rms, want[1][1], "pitch rms");
    assert!((ours.scored_s - 110.0).abs() < 0.01 && ours.vertical_s == 0.0 && ours.no_reference_s == 0.0, "{ours:?}");
    let ms = ours.mode_s.unwrap();
    assert!((ms.fusion + ms.blend + ms.gyro_only - 110.0).abs() < 0.01);
    // Yaw: each estimator's offset at the end of the rest phase removed.
    let yaw_err = |k: usize| wrap180(att[k][2] - truth[k].att[2]);
    let rate = cfg.profile().rate_hz;
    let end = (3.0 * rate) as usize;
    let off = (end - rate as usize..end).map(yaw_err).sum::<f64>() / rate;
    // The mount's turn about the vertical cannot be seen at rest (the smallest
    // rotation is taken): with the unit parked 1-4 deg off level it shifts the
    // yaw origin by up to 2.5 deg x sin(4 deg) = 0.17 deg, which the offset absorbs.
    assert!((ours.yaw_offset_deg.unwrap() - off).abs() < 0.2, "yaw offset {:?} vs {off}", ours.yaw_offset_deg);
    let n = truth.iter().filter(|t| t.t >= 10.0).count() as f64;
    let yaw_rms = ((0..truth.len()).filter(|&k| truth[k].t >= 10.0).map(|k| wrap180(yaw_err(k) - off).powi(2)).sum::<f64>() / n).sqrt();
    close(ours.yaw_rms.unwrap(), yaw_rms, "yaw rms");
    // VQF on the same samples, scored the same way, tracks the drive within
    // two degrees RMS (its largest error is the 0.08 g pull-away, which any
    // filter without a speed reads as 4.6 deg of pitch); a frame or sign error
    // in the conversion would be tens of degrees.
    let vqf = &ev.results[1].scores;
    assert!(vqf.roll.rms < 2.0 && vqf.pitch.rms < 2.0, "vqf {vqf:?}");
    assert_eq!(vqf.scored_s, ours.scored_s);
    // Without the mount removed (no rest phase, --align-s 0) the same run is off by the mount.
    let plain = d.path().join("plain.csv");
    write_ref(&plain, &reference_rows(&truth), false, &|_| false, "");
    let ev0 = eval(&cfg, &samples, &plain, 0.0);
    assert!(!ev0.alignment.window.estimate_mount && ev0.alignment.tilt_deg == 0.0);
    let o0 = &ev0.results[0].scores;
    assert!((o0.roll.rms - want[0][1]).abs() > 0.5 || (o0.pitch.rms - want[1][1]).abs() > 0.5, "the mount made no difference: {o0:?}");
}

#[test]
fn gaps_are_not_scored_and_without_rest_the_first_seconds_align() {
    let d = tempfile::tempdir().unwrap();
    let (cfg, samples, truth) = sim(&d.path().join("run"));
    let rows = reference_rows(&truth);
    let gap = |t: f64| (40.0..45.0).contains(&t) || (70.0..70.5).contains(&t);
    // valid = 0 rows with wild angles, and with empty ones
    let (wild, empty, cut) = (d.path().join("wild.csv"), d.path().join("empty.csv"), d.path().join("cut.csv"));
    write_ref(&wild, &rows, false, &gap, "170.0,-80.0,33.0");
    write_ref(&empty, &rows, false, &gap, ",,");
    // the same rows simply left out
    let kept: Vec<(f64, [f64; 3])> = rows.iter().copied().filter(|(t, _)| !gap(*t)).collect();
    write_ref(&cut, &kept, false, &|_| false, "");
    let full = d.path().join("full.csv");
    write_ref(&full, &rows, false, &|_| false, "");
    let ev_full = eval(&cfg, &samples, &full, 3.0);
    let a = &ev_full.alignment;
    assert!(a.window.source.starts_with("first 3 s") && a.window.t1 == 3.0, "{a:?}");
    assert!((a.roll_deg - MOUNT[0]).abs() < 0.05 && (a.pitch_deg - MOUNT[1]).abs() < 0.05, "mount from the first 3 s: {a:?}");
    // A reference on another clock: --offset is the reference time of the first sample.
    let shifted = d.path().join("shifted.csv");
    write_ref(&shifted, &rows.iter().map(|(t, a)| (t + 1000.0, *a)).collect::<Vec<_>>(), false, &|_| false, "");
    let r = read_reference(&shifted).unwrap();
    let o = RefOptions { skip: 10.0, align_s: 3.0, offset: 1000.0, force_align: true, peers: true, power_on_at: None };
    let ev_shift = evaluate_samples(&samples, &cfg, &r, &o).unwrap();
    for (x, y) in ev_shift.results.iter().zip(&ev_full.results) {
        let (a, b) = (&x.scores, &y.scores);
        assert!((a.roll.rms - b.roll.rms).abs() < 1e-6 && (a.pitch.max - b.pitch.max).abs() < 1e-6, "{}: {a:?} vs {b:?}", x.name);
        assert_eq!(a.no_reference_s, 0.0);
    }
    let s_cut = eval(&cfg, &samples, &cut, 3.0);
    for p in [&wild, &empty] {
        let ev = eval(&cfg, &samples, p, 3.0);
        for (x, y) in ev.results.iter().zip(&s_cut.results) {
            let (a, b) = (&x.scores, &y.scores);
            assert_eq!((a.roll, a.pitch, a.tilt_rms, a.yaw_rms), (b.roll, b.pitch, b.tilt_rms, b.yaw_rms), "{}", x.name);
            // 5.5 s of invalid rows; a sample between the last valid and the
            // first invalid row is not interpolated either (one per gap edge).
            let period = 1.0 / cfg.profile().rate_hz;
            assert!(a.no_reference_s > 5.5 - 0.01 && a.no_reference_s < 5.5 + 4.0 * period + 0.01, "{}: {}", x.name, a.no_reference_s);
            let f = &ev_full.results.iter().find(|r| r.name == x.name).unwrap().scores;
            assert!((f.scored_s - a.scored_s - 5.5).abs() < 0.01);
            assert!(a.roll.max <= f.roll.max && a.tilt_max <= f.tilt_max, "{}: wild angles were scored", x.name);
            // and the gaps are gaps in the error series
            let t = 42.0;
            let e = x.errors.iter().find(|e| (e.t - t).abs() < 0.003).unwrap();
            assert!(e.tilt.is_nan() && e.roll.is_nan());
        }
    }
}

#[test]
fn without_rest_and_with_motion_in_the_first_seconds_no_mount_is_taken_unless_asked() {
    // No rest column, and the car pulls away within the first 5 s: a mount
    // taken from them would hold the pull-away. By default none is taken
    // (the same scores as --align-s 0), and the reason is given; --align-s 5
    // takes it anyway.
    let d = tempfile::tempdir().unwrap();
    let (cfg, samples, truth) = sim(&d.path().join("run"));
    let plain = d.path().join("plain.csv");
    write_ref(&plain, &reference_rows(&truth), false, &|_| false, "");
    let r = read_reference(&plain).unwrap();
    let def = evaluate_samples(&samples, &cfg, &r, &RefOptions { peers: true, ..Default::default() }).unwrap();
    let a = &def.alignment;
    println!("default: {}", a.window.source);
    assert!(!a.window.estimate_mount && a.window.refused_in_motion && a.tilt_deg == 0.0, "{a:?}");
    assert!(a.window.source.contains("do not look like rest") && a.window.source.contains("--align-s 5"), "{}", a.window.source);
    assert!(def.rest_warning("run").unwrap().contains("no mount"));
    let none = eval(&cfg, &samples, &plain, 0.0);
    for (x, y) in def.results.iter().zip(&none.results) {
        assert_eq!((x.scores.roll, x.scores.pitch, x.scores.tilt_rms), (y.scores.roll, y.scores.pitch, y.scores.tilt_rms), "{}", x.name);
    }
    let forced = eval(&cfg, &samples, &plain, 5.0);
    let f = &forced.alignment;
    assert!(f.window.estimate_mount && !f.looks_at_rest && f.tilt_deg > 0.0, "{f:?}");
    assert!(forced.rest_warning("run").unwrap().contains("does not look like rest"));
}

fn run(args: &[&str]) -> std::process::Output {
    Command::new(bin()).args(args).output().unwrap()
}

fn p(x: &Path) -> &str {
    x.to_str().unwrap()
}

#[test]
fn the_command_writes_the_report_and_refuses_bad_references() {
    let d = tempfile::tempdir().unwrap();
    let dir = d.path().join("run");
    let (_, _, truth) = sim(&dir);
    let refp = d.path().join("ref.csv");
    write_ref(&refp, &reference_rows(&truth), true, &|t| (50.0..51.0).contains(&t), ",,");
    let out = d.path().join("rep");
    let (cfgp, log) = (dir.join("config.toml"), dir.join("imu.log"));
    let base = ["evaluate", "--config", p(&cfgp), "--input", p(&log)];
    let o = run(&[&base[..], &["--reference", p(&refp), "--out", p(&out), "--peers", "--skip", "12"]].concat());
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(text.contains("ours") && text.contains("vqf") && text.contains("from 12.0 s"), "{text}");
    let rep: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    for who in [&rep, &rep["peers"]["vqf"]] {
        for k in ["roll", "pitch"] {
            assert!(who[k]["max"].as_f64().unwrap() >= who[k]["rms"].as_f64().unwrap(), "{k}: {who}");
        }
        assert!(who["tilt_rms"].as_f64().unwrap() > 0.0);
        assert!(who["yaw_rms"].as_f64().is_some(), "the run has a magnetometer: yaw is scored");
    }
    assert_eq!(rep["skip_s"].as_f64(), Some(12.0));
    assert!((rep["alignment"]["roll_deg"].as_f64().unwrap() - MOUNT[0]).abs() < 0.05);
    assert!(rep["mode_s"]["fusion"].as_f64().is_some() && rep["peers"]["vqf"]["mode_s"].is_null());
    let svg = std::fs::read_to_string(out.join("errors.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("vqf") && svg.contains("tilt"));
    // Without the magnetometer, yaw is not scored (null), for VQF too.
    let nomag = d.path().join("nomag.toml");
    std::fs::write(&nomag, format!("{}\n[estimator]\nuse_magnetometer = false\n", std::fs::read_to_string(&cfgp).unwrap())).unwrap();
    let o = run(&["evaluate", "--config", p(&nomag), "--input", p(&log), "--reference", p(&refp), "--out", p(&out), "--peers"]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success() && text.contains("not scored"), "{text}{}", String::from_utf8_lossy(&o.stderr));
    let rep: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert!(rep["yaw_rms"].is_null() && rep["peers"]["vqf"]["yaw_rms"].is_null());
    // Bad references: named by line and column, exit 1.
    let good = std::fs::read_to_string(&refp).unwrap();
    let mut lines: Vec<String> = good.lines().map(String::from).collect();
    let mut n = 0;
    let mut bad = |k: usize, f: &dyn Fn(&str) -> String| -> PathBuf {
        let old = lines[k].clone();
        lines[k] = f(&old);
        n += 1;
        let path = d.path().join(format!("bad{n}.csv"));
        std::fs::write(&path, lines.join("\n")).unwrap();
        lines[k] = old;
        path
    };
    let set = |l: &str, i: usize, v: &str| {
        let mut f: Vec<&str> = l.split(',').collect();
        f[i] = v;
        f.join(",")
    };
    let cases: Vec<(PathBuf, Vec<&str>)> = vec![
        (bad(20, &|l| set(l, 2, "x1")), vec!["line 21, column pitch", "not a number"]),
        (bad(20, &|l| set(l, 3, "")), vec!["line 21, column yaw", "empty"]),
        (bad(20, &|l| set(l, 0, "0.001")), vec!["line 21, column t", "not after"]),
        (bad(20, &|l| set(l, 4, "2")), vec!["line 21, column valid", "0 or 1"]),
        (bad(0, &|_| "t,roll,pitch,valid,rest".into()), vec!["line 1", "missing required column(s) yaw"]),
    ];
    for (path, want) in cases {
        let o = run(&[&base[..], &["--reference", p(&path)]].concat());
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{e}");
        for w in want {
            assert!(e.contains(w) && e.contains(p(&path)), "want {w:?}: {e}");
        }
    }
    // --reference needs --input; --realdata on a folder without recordings says so
    let o = run(&["evaluate", "--reference", p(&refp)]);
    assert!(!o.status.success());
    let o = run(&["evaluate", "--realdata", p(d.path())]);
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("no recording folder"));
    // --align-s and --offset mean nothing without a measured reference
    for extra in [["--align-s", "3"], ["--offset", "2"]] {
        let o = run(&[&["evaluate", "--scenario", "static", "--seeds", "1", "--duration", "20"][..], &extra[..]].concat());
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && e.contains("--align-s and --offset apply to a measured reference only"), "{extra:?}: {e}");
    }
}

/// `--realdata`: a recording's clock need not start at 0 (the log's
/// sample clock does; the reference is on the CSV's clock), and a folder
/// that cannot be evaluated is named under the table while the others are
/// scored (exit 1 all the same, for scripts).
#[test]
fn realdata_recordings_on_any_clock_and_a_bad_one_does_not_stop_the_others() {
    let d = tempfile::tempdir().unwrap();
    let (_, samples, truth) = sim(&d.path().join("run"));
    let root = d.path().join("recordings");
    let rows = reference_rows(&truth);
    for (name, shift, broken) in [("rec-a", 0.0, false), ("rec-b", 1000.0, false), ("rec-c", 0.0, true)] {
        let dir = root.join(name);
        std::fs::create_dir_all(&dir).unwrap();
        let mut imu = String::from("t,gx,gy,gz,ax,ay,az,mx,my,mz,temp\n");
        for (s, tr) in samples.iter().zip(&truth) {
            let v = [s.gyro, s.accel, s.magn].concat();
            let v: Vec<String> = v.iter().map(|x| format!("{x:.7}")).collect();
            imu += &format!("{:.6},{},{:.3}\n", tr.t + shift, v.join(","), s.temp);
        }
        let mut reference = String::from("t,roll,pitch,yaw,valid,rest\n");
        for (t, a) in &rows {
            let valid = !broken as u8;
            reference += &format!("{:.6},{:.6},{:.6},{:.6},{valid},{}\n", t + shift, a[0], a[1], a[2], (*t < 3.0) as u8);
        }
        for (file, text) in [("imu.csv.gz", imu), ("reference.csv.gz", reference)] {
            common::write_gz(&dir.join(file), text.lines().map(Into::into));
        }
    }
    let o = run(&["evaluate", "--realdata", p(&root)]);
    let (out, err) = (String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    assert_eq!(o.status.code(), Some(1), "{out}{err}");
    assert!(err.contains("1 of the recordings") && err.contains("could not be evaluated"), "{err}");
    assert!(out.contains("* not evaluated: rec-c: ") && out.contains("no valid reference row"), "{out}");
    // the same recording 1000 s later on its clock scores the same, to the digit
    let row = |name: &str| -> String {
        let i = out.find(&format!("\n{name} ")).unwrap_or_else(|| panic!("no row {name}: {out}"));
        out[i + 1 + name.len()..].lines().take(2).collect::<Vec<_>>().join("\n")
    };
    let (a, b) = (row("rec-a"), row("rec-b"));
    assert!(a.contains("ours") && a.contains("vqf"), "{a}");
    assert_eq!(a, b, "the shifted clock scored differently");
    // the mount was found in the shifted one too (MOUNT, within the digits printed)
    assert!(b.split_whitespace().last().unwrap().trim_end_matches('*').parse::<f64>().unwrap() > 1.0, "{b}");
}

/// `--realdata --power-on-at S`: both estimators powered on S s into each
/// recording score exactly as the same recording cut there by hand (its
/// samples and reference rows from S on); the table says so. Past a
/// recording's end it is named as not evaluated; without --realdata the
/// option is refused.
#[test]
fn realdata_power_on_at_scores_as_the_recording_cut_by_hand() {
    let d = tempfile::tempdir().unwrap();
    let (_, samples, truth) = sim(&d.path().join("run"));
    let rows = reference_rows(&truth);
    let write = |root: &Path, from: f64| {
        let dir = root.join("rec");
        std::fs::create_dir_all(&dir).unwrap();
        let mut imu = String::from("t,gx,gy,gz,ax,ay,az,mx,my,mz,temp\n");
        for (s, tr) in samples.iter().zip(&truth).filter(|(_, tr)| tr.t >= from) {
            let v: Vec<String> = [s.gyro, s.accel, s.magn].concat().iter().map(|x| format!("{x:.7}")).collect();
            imu += &format!("{:.6},{},{:.3}\n", tr.t, v.join(","), s.temp);
        }
        let mut reference = String::from("t,roll,pitch,yaw,valid,rest\n");
        for (t, a) in rows.iter().filter(|(t, _)| *t >= from) {
            reference += &format!("{t:.6},{:.6},{:.6},{:.6},1,{}\n", a[0], a[1], a[2], (*t < 3.0) as u8);
        }
        for (file, text) in [("imu.csv.gz", imu), ("reference.csv.gz", reference)] {
            common::write_gz(&dir.join(file), text.lines().map(Into::into));
        }
    };
    let (whole, cut) = (d.path().join("whole"), d.path().join("cut"));
    write(&whole, f64::NEG_INFINITY);
    write(&cut, 40.0);
    let table = |o: &std::process::Output| -> String {
        let (out, err) = (String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
        assert!(o.status.success(), "{out}{err}");
        let i = out.find("\nrec ").unwrap_or_else(|| panic!("no row: {out}"));
        out[i + 1..].lines().take(2).collect::<Vec<_>>().join("\n")
    };
    let o = run(&["evaluate", "--realdata", p(&whole), "--power-on-at", "40"]);
    assert!(String::from_utf8_lossy(&o.stdout).contains("powered on 40 s into each recording"));
    let later = table(&o);
    assert_eq!(later, table(&run(&["evaluate", "--realdata", p(&cut)])), "not the recording cut by hand");
    assert_ne!(later, table(&run(&["evaluate", "--realdata", p(&whole)])), "the option changed nothing");
    let o = run(&["evaluate", "--realdata", p(&whole), "--power-on-at", "500"]);
    let out = String::from_utf8_lossy(&o.stdout).to_string() + &String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && out.contains("rec") && out.contains("no sample at or after --power-on-at 500"), "{out}");
    let o = run(&["evaluate", "--input", p(&d.path().join("run")), "--power-on-at", "40"]);
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("--realdata"));
}
