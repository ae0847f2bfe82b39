//! The real-data table: every recording under `../shared/realdata` (or
//! `$GYROCOMP_REALDATA`) through `gyrocomp import` and `gyrocomp evaluate
//! --reference`, ours and VQF. Prints the table whatever ours shows; asserts
//! that it is complete and that VQF, run on the very same samples, has not
//! diverged. Skipped, saying so, where the recordings are not there.
//!
//! `cargo test --release --test realdata -- --nocapture` shows the table.

mod common;
use common::{bin, read_gz, realdata_dir, write_gz};
use std::path::PathBuf;
use std::process::Command;

/// The BROAD recordings among `names` that are under the folder of
/// recordings, each one that is not said; said too when none is (or the
/// folder is not there).
fn broad_recordings(names: &[&'static str]) -> Vec<(&'static str, PathBuf)> {
    let Some(dir) = realdata_dir() else {
        println!("skipped: ../shared/realdata not found (set GYROCOMP_REALDATA to the folder of recordings)");
        return Vec::new();
    };
    let found: Vec<_> = names
        .iter()
        .filter_map(|&name| {
            let rec = dir.join(name);
            if !rec.is_dir() {
                println!("skipped {name}: not found");
            }
            rec.is_dir().then_some((name, rec))
        })
        .collect();
    if found.is_empty() {
        println!("skipped: none of {names:?} is under {}", dir.display());
    }
    found
}

/// The recording `name` under the folder of recordings; None (said) when
/// it or the folder is not there.
fn one_recording(name: &str) -> Option<PathBuf> {
    let Some(dir) = realdata_dir() else {
        println!("skipped: ../shared/realdata not found (set GYROCOMP_REALDATA to the folder of recordings)");
        return None;
    };
    let rec = dir.join(name);
    if !rec.is_dir() {
        println!("skipped: {} not found", rec.display());
        return None;
    }
    Some(rec)
}

/// Ours and VQF on the recording `rec` powered on `at` s into it
/// (`--power-on-at`), the built-in defaults.
fn powered_on_at(rec: &std::path::Path, at: f64) -> (gyrocomp::reference::score::Scores, gyrocomp::reference::score::Scores) {
    powered_on_at_with(rec, &gyrocomp::config::Config::default(), at)
}

/// The same with the config `cfg`.
fn powered_on_at_with(
    rec: &std::path::Path,
    cfg: &gyrocomp::config::Config,
    at: f64,
) -> (gyrocomp::reference::score::Scores, gyrocomp::reference::score::Scores) {
    use gyrocomp::reference::RefOptions;
    let o = RefOptions { power_on_at: Some(at), ..RefOptions::default() };
    let mut r = gyrocomp::reference::realdata::evaluate_recording(rec, cfg, &o).unwrap();
    let vqf = r.eval.results.pop().unwrap().scores;
    (r.eval.results.pop().unwrap().scores, vqf)
}

/// The bar for "no divergence": roll and pitch max under 10 deg
/// (from 10 s after power-on); `what` names the run in the message.
fn assert_not_diverged(ours: &gyrocomp::reference::score::Scores, what: &str) {
    assert!(ours.roll.max < 10.0 && ours.pitch.max < 10.0, "{what}: diverged: roll max {} pitch max {}", ours.roll.max, ours.pitch.max);
}

/// "roll max/RMS ours a/b VQF c/d, pitch ours e/f VQF g/h deg".
fn ours_and_vqf(ours: &gyrocomp::reference::score::Scores, vqf: &gyrocomp::reference::score::Scores) -> String {
    format!(
        "roll max/RMS ours {:.2}/{:.3} VQF {:.2}/{:.3}, pitch ours {:.2}/{:.3} VQF {:.2}/{:.3} deg",
        ours.roll.max, ours.roll.rms, vqf.roll.max, vqf.roll.rms, ours.pitch.max, ours.pitch.rms, vqf.pitch.max, vqf.pitch.rms
    )
}

/// A yaw RMS as the tests print it: "1.23", or "not scored".
fn yaw_text(y: Option<f64>) -> String {
    y.map_or("not scored".into(), |y| format!("{y:.2}"))
}

/// `text`, a CSV with a header, gzip-compressed to `p`, each row's fields
/// changed by `edit` first.
fn write_csv_gz(p: &std::path::Path, text: &str, mut edit: impl FnMut(&mut [String])) {
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    let rows = lines.map(|line| {
        let mut f: Vec<String> = line.split(',').map(String::from).collect();
        edit(&mut f);
        f.join(",").into()
    });
    write_gz(p, std::iter::once(header.into()).chain(rows));
}

/// The five BROAD recordings of `../shared/realdata`.
const BROAD: [&str; 5] =
    ["broad-05-slow-rotation", "broad-14-slow-translation", "broad-18-fast-translation", "broad-27-vibration", "broad-33-magnet-2cm"];

#[test]
fn realdata_table_ours_and_vqf() {
    let Some(dir) = realdata_dir() else {
        println!("skipped: ../shared/realdata not found (set GYROCOMP_REALDATA to the folder of recordings)");
        return;
    };
    let folders: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.join("imu.csv.gz").is_file() && p.join("reference.csv.gz").is_file())
        .map(|p| p.file_name().unwrap().to_string_lossy().to_string())
        .collect();
    assert!(!folders.is_empty(), "{}: no recording folder", dir.display());
    let out = tempfile::tempdir().unwrap();
    let o = Command::new(bin())
        .args(["evaluate", "--realdata", dir.to_str().unwrap(), "--peers", "--out", out.path().to_str().unwrap()])
        .output()
        .unwrap();
    let table = String::from_utf8_lossy(&o.stdout);
    println!("$ gyrocomp evaluate --realdata {} --peers\n{table}", dir.display());
    eprint!("{}", String::from_utf8_lossy(&o.stderr));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // The table: one ours row and one vqf row per recording.
    for f in &folders {
        let at = table.lines().position(|l| l.starts_with(&format!("{f} "))).unwrap_or_else(|| panic!("{f} missing from the table"));
        let ours: Vec<&str> = table.lines().nth(at).unwrap().split_whitespace().collect();
        let vqf: Vec<&str> = table.lines().nth(at + 1).unwrap().split_whitespace().collect();
        assert_eq!((ours[1], vqf[0]), ("ours", "vqf"), "{f}");
    }
    let rows: Vec<serde_json::Value> = serde_json::from_str(&std::fs::read_to_string(out.path().join("realdata.json")).unwrap()).unwrap();
    assert_eq!(rows.len(), folders.len());
    for r in &rows {
        let name = r["recording"].as_str().unwrap();
        for who in ["ours", "vqf"] {
            let s = &r[who];
            for k in ["roll", "pitch"] {
                for m in ["max", "rms"] {
                    assert!(s[k][m].as_f64().is_some_and(f64::is_finite), "{name} {who}: {k}.{m} missing: {s}");
                }
            }
            assert!(s["tilt_rms"].as_f64().is_some_and(f64::is_finite), "{name} {who}: tilt_rms");
            assert!(s["scored_s"].as_f64().unwrap() > 30.0, "{name} {who}: under 30 s scored");
            // every recording here has a magnetometer: yaw is scored
            assert!(s["yaw_rms"].as_f64().is_some(), "{name} {who}: yaw not scored");
        }
        // VQF has not diverged: a lost vertical is tens of degrees. Where the
        // mount came from a window that looks like rest, VQF is within the
        // couple of degrees it is published at on such recordings.
        let v = &r["vqf"];
        let (rr, pr, tr) = (v["roll"]["rms"].as_f64().unwrap(), v["pitch"]["rms"].as_f64().unwrap(), v["tilt_rms"].as_f64().unwrap());
        assert!(rr < 15.0 && pr < 15.0 && v["tilt_max"].as_f64().unwrap() < 45.0, "{name}: VQF diverged: {v}");
        if r["alignment"]["looks_at_rest"].as_bool() == Some(true) {
            assert!(tr < 2.0, "{name}: VQF tilt RMS {tr} deg");
        }
        // Ours (issue 11): no divergence, and within reach of VQF on the same
        // samples wherever the mount came from a window at rest. (Not every
        // RMS is at or below VQF's: see docs/results.md, "Real recordings".)
        let u = &r["ours"];
        if r["alignment"]["looks_at_rest"].as_bool() == Some(true) {
            let (rm, pm) = (u["roll"]["max"].as_f64().unwrap(), u["pitch"]["max"].as_f64().unwrap());
            assert!(rm < 10.0 && pm < 10.0, "{name}: ours diverged, max roll {rm} pitch {pm}");
            let (ut, vt) = (u["tilt_rms"].as_f64().unwrap(), v["tilt_rms"].as_f64().unwrap());
            // 5 %: a hand-held unit levelled through the Butterworth and
            // learning its gyro's error in motion is within 0.3 % of VQF's
            // tilt or below it on every BROAD recording (broad-14 was 16 %
            // above it before)
            assert!(ut < 1.05 * vt, "{name}: ours tilt RMS {ut} against VQF's {vt}");
        }
        // A recording that moves from its first sample (the car): no mount is
        // taken from a window in motion, and ours holds better than VQF.
        if r["alignment"]["window"]["refused_in_motion"].as_bool() == Some(true) {
            let (rm, pm) = (u["roll"]["max"].as_f64().unwrap(), u["pitch"]["max"].as_f64().unwrap());
            assert!(rm < 10.0 && pm < 10.0, "{name}: ours diverged, max roll {rm} pitch {pm}");
            let (ut, vt) = (u["tilt_rms"].as_f64().unwrap(), v["tilt_rms"].as_f64().unwrap());
            assert!(ut < vt, "{name}: ours tilt RMS {ut} against VQF's {vt}");
        }
    }
}

/// The simulator's car shakes on its road as the real car does. The real
/// car's roll and pitch rates, 3-45 Hz (its phone gyro at 104 Hz, 12-20 m/s
/// throughout), against the simulated `vehicle` car's at 14-20 m/s, the same
/// filters: within a factor 1.6 either way on both axes. Before the ride
/// vibration (`sim::scenario::RIDE`) the simulated car had only its gyro's
/// noise there, a sixth to a quarter of the real car's, and a simulated car
/// driving looked to the rest detector as still as one standing.
#[test]
fn the_simulated_car_shakes_on_its_road_as_the_real_car_does() {
    let Some(car) = one_recording("comma2k19-rav4-60s") else { return };
    let text = read_gz(&car.join("imu.csv.gz"));
    let rows: Vec<Vec<f64>> = text.lines().skip(1).map(|l| l.split(',').take(3).map(|v| v.parse().unwrap()).collect()).collect();
    let fs = (rows.len() - 1) as f64 / (rows[rows.len() - 1][0] - rows[0][0]);
    let axis = |k: usize| rows.iter().map(|r| r[k]).collect::<Vec<f64>>();
    let real = [1, 2].map(|k| common::band_rms(&axis(k), fs, 3.0, 45.0, |_| true));
    let run = gyrocomp::sim::prepare(&gyrocomp::sim::SimOptions::new("vehicle", 1)).unwrap();
    let (mut gyro, mut speed) = (Vec::new(), Vec::new());
    for (tr, m, _) in gyrocomp::sim::samples(&run, 1).take((340.0 * run.profile.rate_hz) as usize) {
        gyro.push(m.gyro);
        speed.push(tr.speed);
    }
    let keep = |i: usize| (14.0..20.0).contains(&speed[i]);
    let sim = [0, 1].map(|k| common::band_rms(&gyro.iter().map(|g| g[k]).collect::<Vec<f64>>(), run.profile.rate_hz, 3.0, 45.0, keep));
    println!(
        "roll / pitch rate 3-45 Hz RMS: the real car {:.3} / {:.3} deg/s, the simulated car {:.3} / {:.3}",
        real[0], real[1], sim[0], sim[1]
    );
    for k in 0..2 {
        let r = sim[k] / real[k];
        assert!(r > 1.0 / 1.6 && r < 1.6, "axis {k}: simulated {} against real {} deg/s", sim[k], real[k]);
    }
}

/// The car (comma2k19): IMU only and with its own wheel speeds, described by
/// its DBC (Motorola byte order), merged from its bus log. The reference has
/// no rest phase and the car brakes in its first seconds, so the mount is not
/// estimated (`--align-s 0`: the reference is the phone's own frame).
#[test]
fn the_car_with_and_without_its_wheel_speeds() {
    let Some(car) = one_recording("comma2k19-rav4-60s") else { return };
    if !car.join("toyota.dbc").is_file() {
        println!("skipped: {} has no toyota.dbc", car.display());
        return;
    }
    let d = tempfile::tempdir().unwrap();
    let (log, snip) = (d.path().join("car.log"), d.path().join("snippet.toml"));
    let o = Command::new(bin())
        .args(["import", "--csv"])
        .arg(car.join("imu.csv.gz"))
        .arg("--can")
        .arg(car.join("can.log.gz"))
        .arg("--out")
        .arg(&log)
        .arg("--config-out")
        .arg(&snip)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let imu_only = std::fs::read_to_string(&snip).unwrap();
    let with_speed = format!(
        "{imu_only}[speed]\ndbc = {:?}\nmessage = \"WHEEL_SPEEDS\"\nsignals = [\"WHEEL_SPEED_RL\", \"WHEEL_SPEED_RR\"]\n",
        car.join("toyota.dbc").display().to_string()
    );
    let run = |name: &str, text: &str| -> (Vec<f64>, Vec<f64>) {
        let cfg = d.path().join(name);
        std::fs::write(&cfg, text).unwrap();
        let o = Command::new(bin())
            .args(["evaluate", "--config"])
            .arg(&cfg)
            .arg("--input")
            .arg(&log)
            .arg("--reference")
            .arg(car.join("reference.csv.gz"))
            .args(["--peers", "--align-s", "0"])
            .output()
            .unwrap();
        let out = String::from_utf8_lossy(&o.stdout).to_string();
        println!("$ gyrocomp evaluate --config {name} --input car.log --reference reference.csv.gz --peers --align-s 0\n{out}");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let row = |who: &str| -> Vec<f64> {
            let l = out.lines().find(|l| l.split_whitespace().any(|w| w == who)).unwrap();
            l.split_whitespace().skip_while(|w| *w != who).skip(1).take(4).map(|v| v.parse().unwrap()).collect()
        };
        (row("ours"), row("vqf"))
    };
    let (alone, vqf) = run("imu_only.toml", &imu_only);
    let (speed, _) = run("with_speed.toml", &with_speed);
    // roll max, roll rms, pitch max, pitch rms
    assert!(speed[0] <= 1.5 && speed[2] <= 1.5, "with its wheel speeds: max roll {} pitch {}", speed[0], speed[2]);
    assert!(speed[3] < alone[3] && speed[2] < alone[2], "the wheel speeds did not help: {speed:?} vs {alone:?}");
    // IMU only, ours keeps the roll better than VQF on the same samples, and
    // the pitch too: powered on at 8 m/s on a straight with no stop, the
    // vertical-speed bound stops the pitch error from running into a wrong
    // speed (without it: pitch RMS 6.1 deg against VQF's 3.7)
    assert!(alone[1] < vqf[1], "IMU only roll RMS {} vs VQF {}", alone[1], vqf[1]);
    assert!(alone[3] < vqf[3], "IMU only pitch RMS {} vs VQF {}", alone[3], vqf[3]);
}

/// Why a free unit learns its bias in motion (docs/estimator.md, "A free
/// unit's gyro in motion"): on broad-14 the gyro alone, started from the
/// reference at the end of each rest with that rest's mean gyro as its
/// bias, is off by far more at the next rest than that bias's uncertainty
/// explains. Prints the error per motion phase.
#[test]
fn the_hand_held_gyro_alone_drifts_between_rests() {
    use gyrocomp::config::Config;
    use gyrocomp::reference::realdata::evaluate_recording;
    use gyrocomp::reference::refcsv::read_reference;
    use gyrocomp::reference::score::sample_times;
    use gyrocomp::reference::RefOptions;
    use nalgebra::{UnitQuaternion, Vector3};
    let Some(rec) = one_recording("broad-14-slow-translation") else { return };
    let r = evaluate_recording(&rec, &Config::default(), &RefOptions::default()).unwrap();
    let d = gyrocomp::reference::decode(&r.log[..], &r.config, "broad-14").unwrap();
    let period = r.eval.period;
    let ts = sample_times(&d.samples, period);
    let reference = read_reference(&rec.join("reference.csv.gz")).unwrap();
    let att = reference.at_times(&ts, 0.0);
    // the reference's rest flag at each sample (rows and samples share the clock)
    let mut j = 0;
    let rest: Vec<bool> = ts
        .iter()
        .map(|&t| {
            while j + 1 < reference.rows.len() && reference.rows[j + 1].t <= t + 1e-6 {
                j += 1;
            }
            reference.rows[j].rest
        })
        .collect();
    // rest phases of at least 3 s
    let n3 = (3.0 / period) as usize;
    let mut phases = Vec::new();
    let mut k = 0;
    while k < rest.len() {
        let s = k;
        while k < rest.len() && rest[k] {
            k += 1;
        }
        if k - s >= n3 {
            phases.push((s, k));
        }
        k += 1;
    }
    assert!(phases.len() >= 5, "{} rest phases", phases.len());
    let d2r = std::f64::consts::PI / 180.0;
    let mut errors = Vec::new();
    for w in phases.windows(2) {
        let ((_, end), (next, _)) = (w[0], w[1]);
        let mean = |a: usize, b: usize| {
            let n = (b - a) as f64;
            (0..3).map(|i| d.samples[a..b].iter().map(|s| s.gyro[i]).sum::<f64>() / n).collect::<Vec<f64>>()
        };
        let bias = mean(end - n3, end);
        // 1-sigma of that bias: the gyro's scatter over the 3 s / sqrt(samples)
        let sd = (0..3)
            .map(|i| {
                let v = d.samples[end - n3..end].iter().map(|s| (s.gyro[i] - bias[i]).powi(2)).sum::<f64>() / n3 as f64;
                (v / n3 as f64).sqrt()
            })
            .fold(0.0f64, f64::max);
        let stop = next + (0.5 / period) as usize;
        let (Some(mut q), Some(q_ref)) = (att[end - 1], att[stop]) else {
            continue;
        };
        for s in &d.samples[end..stop] {
            let w = Vector3::new(s.gyro[0] - bias[0], s.gyro[1] - bias[1], s.gyro[2] - bias[2]) * (d2r * period);
            q *= UnitQuaternion::from_scaled_axis(w);
        }
        let e = (q_ref.inverse() * q).scaled_axis() / d2r;
        let moving_s = (next - end) as f64 * period;
        // 3 sigma of what the rest's bias uncertainty alone would leave
        let bound = 3.0 * sd * (moving_s + 0.5);
        println!(
            "motion {:5.1}-{:5.1} s: the gyro alone is off by x {:+.2} y {:+.2} z {:+.2} deg at the next rest (3 sigma of the rest bias: {bound:.3} deg)",
            ts[end],
            ts[next],
            e.x,
            e.y,
            e.z
        );
        errors.push((e.x.hypot(e.y), bound));
    }
    // in tilt (x, y), every phase but at most one is beyond what the rest
    // bias's uncertainty explains
    let beyond = errors.iter().filter(|(e, b)| e > b).count();
    assert!(errors.len() >= 4 && beyond + 1 >= errors.len(), "{errors:?}");
}

/// Real turn-on biases are several deg/s (a real ADIS16448 was measured at
/// 4.5 deg/s on one axis); the BROAD units' are 0.2-0.5. The same
/// recordings with (+3, -2, +4) deg/s more on the gyro: the first rest reads
/// the bias, and ours is where it was, while VQF (whose bias estimate is
/// bounded to 2 deg/s) is not. Prints the tilt RMS of both, before and after.
#[test]
fn a_turn_on_bias_of_several_deg_per_s_changes_nothing_after_the_first_rest() {
    use gyrocomp::config::Config;
    use gyrocomp::reference::realdata::evaluate_recording;
    use gyrocomp::reference::RefOptions;
    let extra = [3.0, -2.0, 4.0];
    let tmp = tempfile::tempdir().unwrap();
    for (name, rec) in broad_recordings(&["broad-05-slow-rotation", "broad-18-fast-translation", "broad-33-magnet-2cm"]) {
        // the same recording, every gyro reading shifted by `extra`
        let biased = tmp.path().join(name);
        std::fs::create_dir(&biased).unwrap();
        let text = read_gz(&rec.join("imu.csv.gz"));
        let header = text.lines().next().unwrap();
        assert!(header.starts_with("t,gx,gy,gz,"), "{name}: header {header}");
        write_csv_gz(&biased.join("imu.csv.gz"), &text, |f| {
            for i in 0..3 {
                let v: f64 = f[1 + i].parse().unwrap();
                f[1 + i] = format!("{}", v + extra[i]);
            }
        });
        std::fs::copy(rec.join("reference.csv.gz"), biased.join("reference.csv.gz")).unwrap();
        let tilt = |d: &std::path::Path| {
            let r = evaluate_recording(d, &Config::default(), &RefOptions::default()).unwrap();
            (r.eval.results[0].scores.tilt_rms, r.eval.results[1].scores.tilt_rms)
        };
        let (ours, vqf) = tilt(&rec);
        let (ours_b, vqf_b) = tilt(&biased);
        println!(
            "{name}: tilt RMS ours {ours:.3} -> {ours_b:.3} deg, VQF {vqf:.3} -> {vqf_b:.3} deg with (+3, -2, +4) deg/s more turn-on bias"
        );
        assert!((ours_b - ours).abs() < 0.02, "{name}: ours {ours} -> {ours_b}");
        assert!(ours_b < vqf_b, "{name}: ours {ours_b} against VQF {vqf_b}");
    }
}

/// A daemon restarted in a hand that is moving: the five BROAD recordings
/// cut to begin 15 s after their first rest ends (the first sample's tilt is
/// one sample of the hand's acceleration: broad-18's reads upside down). The
/// cut files keep their clock (`t` starts at 40-60 s): the evaluation takes
/// the reference from there. No divergence: roll and pitch within 10 deg of
/// the reference from 10 s on (the criterion); before the exact tilt
/// innovation, the re-levelling in motion and the void vehicle model, four
/// of the five went to 25-180 deg. And within 5 deg (VQF's worst on the same
/// samples is 2.6): while `vehicle = "auto"` took broad-14's jittering hand
/// for a car until its first rest, its pitch reached 7.6 deg. And roll and
/// pitch RMS within 25 % of VQF's. The same recordings cut 5 s after their
/// first rest ends: no divergence, and the yaw RMS under 10 deg where it is
/// scored. Prints ours and VQF.
#[test]
fn powered_on_in_a_moving_hand_no_recording_diverges() {
    for (name, rec) in broad_recordings(&BROAD) {
        let reference = read_gz(&rec.join("reference.csv.gz"));
        let header: Vec<&str> = reference.lines().next().unwrap().split(',').collect();
        let (ti, ri) = (0, header.iter().position(|h| *h == "rest").expect("a rest column"));
        // the end of the first rest: the first row marked moving after one marked resting
        let mut seen_rest = false;
        let mut rest_end = None;
        for line in reference.lines().skip(1) {
            let f: Vec<&str> = line.split(',').collect();
            let rest = f[ri] == "1";
            seen_rest |= rest;
            if seen_rest && !rest {
                rest_end = Some(f[ti].parse::<f64>().unwrap());
                break;
            }
        }
        for after in [15.0, 5.0] {
            let t0 = rest_end.expect("a rest phase that ends") + after;
            let (ours, vqf) = powered_on_at(&rec, t0);
            println!(
                "{name} from {t0:.1} s: {}, yaw RMS ours {} VQF {} ({:.0} s scored)",
                ours_and_vqf(&ours, &vqf),
                yaw_text(ours.yaw_rms),
                yaw_text(vqf.yaw_rms),
                ours.scored_s
            );
            assert!(ours.scored_s > 60.0, "{name}: {} s scored: the reference was not found on the cut clock", ours.scored_s);
            assert_not_diverged(&ours, name);
            if after == 5.0 {
                // 5 s in, the heading: broad-18's dip, taken with a tilt still
                // wrong, had kept its heading 75-180 deg off (yaw RMS 31.7)
                if let Some(y) = ours.yaw_rms {
                    assert!(y < 10.0, "{name} from {t0:.1} s: yaw RMS {y} deg");
                }
                continue;
            }
            assert!(ours.roll.max < 5.0 && ours.pitch.max < 5.0, "{name}: roll max {} pitch max {} deg", ours.roll.max, ours.pitch.max);
            // and within a quarter of VQF's RMS (broad-18's roll is 18 % above
            // it): broad-27's x bias, never learned before its first rest, had
            // held its roll at 2.9 times VQF's
            for (axis, o, v) in [("roll", ours.roll.rms, vqf.roll.rms), ("pitch", ours.pitch.rms, vqf.pitch.rms)] {
                assert!(o < 1.25 * v, "{name}: {axis} RMS ours {o} against VQF's {v}");
            }
        }
    }
}

/// Powered on in the middle of broad-18's fast translations (10 g, 625
/// deg/s) at 37, 40 and 80 s (`--power-on-at`): the first sample is a hand's
/// jerk, so the first tilt reads it. The low-passed gravity, started from
/// that one sample, held it for seconds: at 80 s roll max 10.6 deg (RMS
/// 1.36; VQF 1.93 / 0.36), at 40 s pitch max 5.8. Started from the mean of
/// the samples so far, as VQF's low-pass starts: within 3 deg. Prints ours
/// and VQF.
#[test]
fn powered_on_in_a_fast_translation_the_first_jerk_is_not_held() {
    for (name, rec) in broad_recordings(&["broad-18-fast-translation"]) {
        for at in [37.0, 40.0, 80.0] {
            let (ours, vqf) = powered_on_at(&rec, at);
            println!("{name} powered on at {at} s: {}", ours_and_vqf(&ours, &vqf));
            assert!(ours.roll.max < 3.0 && ours.pitch.max < 3.0, "at {at} s: roll max {} pitch max {}", ours.roll.max, ours.pitch.max);
        }
    }
}

/// Powered on in a hand whose slow motion the vehicle model takes for a
/// car's for its first 7 s (broad-14 powered on at 60 s): what that model
/// taught meanwhile (a bias learned from the hand's motion, a tilt put
/// against it) used to stay behind when `"auto"` left it (roll max 2.28,
/// RMS 0.392; pitch max 1.54, RMS 0.277 against VQF's 1.16/0.354 and
/// 0.78/0.231). The power-on bank runs the filter as a free unit from
/// power-on beside it, and that one goes on: roll RMS at or under VQF's,
/// pitch max under 1 deg. Prints ours and VQF.
#[test]
fn powered_on_in_a_hand_taken_for_a_car_the_vehicle_models_work_is_void() {
    for (name, rec) in broad_recordings(&["broad-14-slow-translation"]) {
        let (ours, vqf) = powered_on_at(&rec, 60.0);
        println!("{name} powered on at 60 s: {}", ours_and_vqf(&ours, &vqf));
        assert!(ours.roll.rms <= vqf.roll.rms, "roll RMS {} above VQF's {}", ours.roll.rms, vqf.roll.rms);
        assert!(ours.pitch.max < 1.0, "pitch max {}", ours.pitch.max);
    }
}

/// Powered on anywhere in a hand's motion: the five BROAD recordings with
/// both estimators powered on at 40, 50, 60, 70, 80, 90, 100 and 120 s
/// (`--power-on-at`; mostly in motion, the bias unread): none diverges
/// (roll and pitch max under 10 deg), and over the 40 starts ours' mean
/// roll and pitch RMS are no worse than VQF's. Before a free unit took its
/// tilt as settled after `accel_tau_s` (3 s) of the low-passed gravity
/// rather than 10 s, it learned no bias for the first 10 s and more: mean
/// roll RMS 0.365 against VQF's 0.339 (23 of the 40 above VQF's). Prints
/// every start.
#[test]
fn powered_on_anywhere_in_a_hands_motion() {
    let recs = broad_recordings(&BROAD);
    if recs.len() < BROAD.len() {
        println!("skipped: not every BROAD recording is there");
        return;
    }
    let (mut ours_sum, mut vqf_sum, mut n) = ([0.0; 2], [0.0; 2], 0.0);
    for at in [40.0, 50.0, 60.0, 70.0, 80.0, 90.0, 100.0, 120.0] {
        for (name, rec) in &recs {
            let (ours, vqf) = powered_on_at(rec, at);
            println!("{name} at {at} s: {}", ours_and_vqf(&ours, &vqf));
            assert_not_diverged(&ours, &format!("{name} at {at} s"));
            ours_sum[0] += ours.roll.rms;
            ours_sum[1] += ours.pitch.rms;
            vqf_sum[0] += vqf.roll.rms;
            vqf_sum[1] += vqf.pitch.rms;
            n += 1.0;
        }
    }
    let (o, v) = (ours_sum.map(|x| x / n), vqf_sum.map(|x| x / n));
    println!("mean over {n} starts: roll RMS ours {:.3} VQF {:.3}, pitch RMS ours {:.3} VQF {:.3} deg", o[0], v[0], o[1], v[1]);
    assert!(o[0] <= v[0] && o[1] <= v[1], "mean roll/pitch RMS ours {o:?} against VQF's {v:?}");
}

/// A daemon restarted while the car drives: the car recording with both
/// estimators powered on 5, 10, 20, 30 and 40 s into it (`--power-on-at`),
/// IMU only (its turn-on bias of several deg/s unknown again, no stop to read
/// it, the speed unknown): no divergence (roll and pitch max under 10 deg
/// from 10 s after power-on, the bar). Prints ours and VQF. At 5 s
/// the zero-speed hypothesis, kept by its likelihood, ran to -20 m/s with
/// its pitch 13 deg off (max 13.4 deg); no car powered on while driving
/// reverses that fast, and the bank publishes a plausible one instead
/// (`hypotheses::REVERSE_MAX`).
#[test]
fn the_car_restarted_while_driving_does_not_diverge() {
    let Some(rec) = one_recording("comma2k19-rav4-60s") else { return };
    for at in [5.0, 10.0, 20.0, 30.0, 40.0] {
        let (ours, vqf) = powered_on_at(&rec, at);
        println!("powered on at {at} s: {} ({:.0} s scored)", ours_and_vqf(&ours, &vqf), ours.scored_s);
        assert!(ours.scored_s > 9.0, "{} s scored", ours.scored_s);
        assert_not_diverged(&ours, &format!("at {at} s"));
        // the body's rate about the horizontal, zero on average, tells the
        // roll axis's bias (at 20 s it had been 3.3 deg RMS: a z bias taken
        // for a turn, and roll put against it)
        assert!(ours.roll.rms <= vqf.roll.rms, "at {at} s: roll RMS {} above VQF's {}", ours.roll.rms, vqf.roll.rms);
    }
}

/// The car without its magnetometer (`use_magnetometer = false`: a part
/// without one, or a field "auto" finds implausible), powered on 0, 10, 20,
/// 30 and 40 s into its drive, IMU only, no stop: nothing but the vehicle
/// constraint's lateral acceleration tells the roll from the yaw-rate
/// bias, and it sees only their sum (`u δb_z = g δφ`). A car's body is
/// level within a few degrees (`level_roll_update`): that settles it. Over
/// the five power-ons the roll RMS is below VQF's (without that update:
/// 2.87 deg mean, the drive from 0 s 3.87 with a z bias 1.1 deg/s where the
/// magnetometer finds 3.9; VQF 1.56), and none diverges.
#[test]
fn the_car_without_its_magnetometer_keeps_its_roll() {
    let Some(rec) = one_recording("comma2k19-rav4-60s") else { return };
    let cfg = gyrocomp::config::Config::parse("[estimator]\nuse_magnetometer = false\n", "test").unwrap();
    let (mut ours_sum, mut vqf_sum) = (0.0, 0.0);
    for at in [0.0, 10.0, 20.0, 30.0, 40.0] {
        let (ours, vqf) = powered_on_at_with(&rec, &cfg, at);
        println!("no magnetometer, powered on at {at} s: {}", ours_and_vqf(&ours, &vqf));
        assert_not_diverged(&ours, &format!("no magnetometer, at {at} s"));
        ours_sum += ours.roll.rms;
        vqf_sum += vqf.roll.rms;
    }
    let (ours, vqf) = (ours_sum / 5.0, vqf_sum / 5.0);
    println!("mean roll RMS over the five: ours {ours:.3} VQF {vqf:.3} deg");
    assert!(ours < vqf, "mean roll RMS {ours:.3} above VQF's {vqf:.3}");
}

/// Any mounting, on real motion: the five BROAD recordings as if the unit
/// had been mounted upside down, on its side, nose up by 85 deg (its rests
/// then 5 deg from vertical) and turned 45/-60/30 deg (Z-Y-X) in the rig:
/// every sample's gyro, accelerometer and magnetometer turned into that
/// sensor frame, the reference's attitude turned with them. A filter whose
/// state is the attitude itself (a quaternion) and whose every measurement
/// is a vector sees the same motion: its tilt error (the invariant part of
/// the attitude; roll and pitch split it differently in every frame) stays
/// within 2 % of the unrotated one, at or near VQF's on the same samples as
/// on the unrotated recordings (the table's 5 % bar). The paper's filter
/// (`mode = "paper"`: roll, pitch and yaw as its state) is run on the
/// nose-up mounting too, to show what the test tells: its tilt error there
/// is several times ours.
#[test]
fn any_mounting_leaves_the_tilt_error_as_it_was() {
    use gyrocomp::config::Config;
    use gyrocomp::estimator::quat::{euler, matrix_from_euler};
    use gyrocomp::reference::realdata::evaluate_recording;
    use gyrocomp::reference::RefOptions;
    const D2R: f64 = std::f64::consts::PI / 180.0;
    let mounts: [(&str, [f64; 3]); 4] = [
        ("upside down", [180.0, 0.0, 0.0]),
        ("on its side", [90.0, 0.0, 0.0]),
        ("nose up", [0.0, 85.0, 0.0]),
        ("45/-60/30", [45.0, -60.0, 30.0]),
    ];
    let tmp = tempfile::tempdir().unwrap();
    for (name, rec) in broad_recordings(&BROAD) {
        // tilt RMS ours, VQF; and "roll/pitch RMS ours, VQF"
        let mut split = String::new();
        let mut tilt = |d: &std::path::Path, label: &str| {
            let r = evaluate_recording(d, &Config::default(), &RefOptions::default()).unwrap();
            let (o, v) = (&r.eval.results[0].scores, &r.eval.results[1].scores);
            split += &format!(
                "{}{label} {:.3}/{:.3} {:.3}/{:.3}",
                if split.is_empty() { "  roll/pitch RMS ours VQF: " } else { ", " },
                o.roll.rms,
                o.pitch.rms,
                v.roll.rms,
                v.pitch.rms
            );
            (o.tilt_rms, v.tilt_rms)
        };
        let (ours0, vqf0) = tilt(&rec, "as recorded");
        let (imu, reference) = (read_gz(&rec.join("imu.csv.gz")), read_gz(&rec.join("reference.csv.gz")));
        let mut line = format!("{name}: tilt RMS ours/VQF {ours0:.3}/{vqf0:.3} deg as recorded");
        for (label, [r, p, y]) in mounts {
            // the sensor frame in the rig's: v_sensor = M^T v_rig, C_ns = C_nb M
            let m = matrix_from_euler(r * D2R, p * D2R, y * D2R);
            let turn = |v: [f64; 3]| std::array::from_fn::<f64, 3, _>(|i| (0..3).map(|k| m[k][i] * v[k]).sum());
            let turned = tmp.path().join(format!("{name}-{}", label.replace(['/', ' '], "_")));
            std::fs::create_dir(&turned).unwrap();
            write_csv_gz(&turned.join("imu.csv.gz"), &imu, |f| {
                for c in [1, 4, 7] {
                    let v = turn(std::array::from_fn(|i| f[c + i].parse::<f64>().unwrap()));
                    for i in 0..3 {
                        f[c + i] = format!("{:.7}", v[i]);
                    }
                }
            });
            write_csv_gz(&turned.join("reference.csv.gz"), &reference, |f| {
                if let (Ok(rr), Ok(pr), Ok(yr)) = (f[1].parse::<f64>(), f[2].parse::<f64>(), f[3].parse::<f64>()) {
                    let c = matrix_from_euler(rr * D2R, pr * D2R, yr * D2R);
                    let cs: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| c[i][k] * m[k][j]).sum()));
                    let e = euler(&cs);
                    for i in 0..3 {
                        f[1 + i] = format!("{:.6}", e[i] / D2R);
                    }
                }
            });
            let (ours, vqf) = tilt(&turned, label);
            line += &format!(", {label} {ours:.3}/{vqf:.3}");
            if label == "nose up" {
                let cfg = Config::parse("[estimator]\nmode = \"paper\"\n", "test").unwrap();
                let paper = evaluate_recording(&turned, &cfg, &RefOptions::default()).unwrap().eval.results[0].scores.tilt_rms;
                line += &format!(" (paper mode {paper:.3})");
                assert!(paper > 3.0 * ours, "{name} mounted nose up: paper mode {paper} deg, ours {ours}: the test cannot tell");
            }
            assert!((ours / ours0 - 1.0).abs() < 0.02, "{name} mounted {label}: ours' tilt RMS {ours} deg against {ours0} as recorded");
            assert!(ours < 1.05 * vqf, "{name} mounted {label}: ours' tilt RMS {ours} deg against VQF's {vqf}");
        }
        println!("{line}\n{split}");
    }
}

/// The hand-held unit as further recordings of it may find it, made from the
/// five BROAD recordings (every change written into a copy of `imu.csv`):
/// - tapped: every 2-6 s a knock of 3-8 g for 14 ms in a new direction,
///   with a 50-200 deg/s gyro doublet that turns the unit by nothing (the
///   reference, which did not see it, stays right), also at its rests;
/// - a magnet passing by: fields of 0.2-1.5 gauss (Earth's is 0.46 here)
///   swelling and fading over 3-10 s, 1-10 s apart, each in a new direction;
/// - no magnetometer (its columns empty);
/// - sampled at a third of the rate (95 Hz: blocks of three averaged).
///
/// Each is run through ours and VQF on the same samples. No divergence, and
/// ours within the real-data table's 5 % of VQF's tilt RMS on every one.
/// With the magnet the heading is the test: a field that is not Earth's is
/// refused by its norm or dip (`[mekf] mag_norm_tol`, `mag_dip_tol_deg`),
/// so ours keeps a heading VQF loses: yaw RMS 0.99-2.08 deg against VQF's
/// 15.9-53.9. With the gate opened (`mag_norm_tol = 100`,
/// `mag_dip_tol_deg = 180`) ours read the magnet as north: broad-05 yaw
/// RMS 98.8 deg against VQF's 20.3, and the test failed.
/// Prints ours and VQF.
#[test]
fn the_hand_held_unit_tapped_passed_by_a_magnet_without_magnetometer_or_sampled_slower() {
    use gyrocomp::config::Config;
    use gyrocomp::reference::realdata::evaluate_recording;
    use gyrocomp::reference::RefOptions;
    use rand::{Rng, SeedableRng};
    use rand_distr::{Distribution, UnitSphere};
    let tmp = tempfile::tempdir().unwrap();
    let mut seed = 1u64;
    for (name, rec) in broad_recordings(&BROAD) {
        let text = read_gz(&rec.join("imu.csv.gz"));
        let header = text.lines().next().unwrap();
        assert!(header.starts_with("t,gx,gy,gz,ax,ay,az,mx,my,mz,"), "{name}: header {header}");
        // t and the nine sensor columns; BROAD has no temperature, written back empty
        let rows: Vec<Vec<f64>> =
            text.lines().skip(1).map(|l| l.split(',').take(10).map(|x| x.parse::<f64>().unwrap_or(f64::NAN)).collect()).collect();
        let dt = (rows[rows.len() - 1][0] - rows[0][0]) / (rows.len() - 1) as f64;
        seed += 1;
        let mut draw = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let unit = |d: &mut rand_chacha::ChaCha8Rng| -> [f64; 3] { UnitSphere.sample(d) };
        for case in ["tapped", "magnet", "no magnetometer", "a third of the rate"] {
            let mut r = rows.clone();
            match case {
                "tapped" => {
                    let mut i = (draw.gen_range(1.0..4.0) / dt) as usize;
                    while i + 4 < r.len() {
                        let (a, u, w, v) = (draw.gen_range(3.0..8.0), unit(&mut draw), draw.gen_range(50.0..200.0), unit(&mut draw));
                        for k in 0..4 {
                            let s = (std::f64::consts::PI * (k as f64 + 0.5) / 4.0).sin();
                            let sign = if k < 2 { 1.0 } else { -1.0 };
                            for j in 0..3 {
                                r[i + k][4 + j] += a * s * u[j];
                                r[i + k][1 + j] += w * v[j] * sign;
                            }
                        }
                        i += (draw.gen_range(2.0..6.0) / dt) as usize;
                    }
                }
                "magnet" => {
                    let (t_first, t_last) = (r[0][0], r[r.len() - 1][0]);
                    let mut t0 = t_first + draw.gen_range(0.0..5.0);
                    while t0 < t_last {
                        let (len, amp, u) = (draw.gen_range(3.0..10.0), draw.gen_range(0.2..1.5), unit(&mut draw));
                        for row in r.iter_mut().filter(|row| row[0] >= t0 && row[0] <= t0 + len) {
                            let e = amp * 0.5 * (1.0 - (2.0 * std::f64::consts::PI * (row[0] - t0) / len).cos());
                            for j in 0..3 {
                                row[7 + j] += e * u[j];
                            }
                        }
                        t0 += len + draw.gen_range(1.0..10.0);
                    }
                }
                "no magnetometer" => {
                    for row in r.iter_mut() {
                        row[7..10].fill(f64::NAN);
                    }
                }
                _ => {
                    r = r.chunks_exact(3).map(|b| (0..10).map(|c| (b[0][c] + b[1][c] + b[2][c]) / 3.0).collect()).collect();
                }
            }
            let dir = tmp.path().join(case.replace(' ', "-")).join(name);
            std::fs::create_dir_all(&dir).unwrap();
            let field = |x: f64| if x.is_nan() { String::new() } else { format!("{x}") };
            let lines = r.iter().map(|row| (row.iter().map(|&x| field(x)).collect::<Vec<_>>().join(",") + ",").into());
            write_gz(&dir.join("imu.csv.gz"), std::iter::once(header.into()).chain(lines));
            std::fs::copy(rec.join("reference.csv.gz"), dir.join("reference.csv.gz")).unwrap();
            let mut res = evaluate_recording(&dir, &Config::default(), &RefOptions::default()).unwrap();
            let vqf = res.eval.results.pop().unwrap().scores;
            let ours = res.eval.results.pop().unwrap().scores;
            println!(
                "{name}, {case}: {}, tilt RMS ours {:.3} VQF {:.3}, yaw RMS ours {} VQF {}",
                ours_and_vqf(&ours, &vqf),
                ours.tilt_rms,
                vqf.tilt_rms,
                yaw_text(ours.yaw_rms),
                yaw_text(vqf.yaw_rms)
            );
            assert_not_diverged(&ours, &format!("{name}, {case}"));
            assert!(ours.tilt_rms < 1.05 * vqf.tilt_rms, "{name}, {case}: tilt RMS ours {} against VQF's {}", ours.tilt_rms, vqf.tilt_rms);
            match case {
                "magnet" => {
                    let (o, v) = (ours.yaw_rms.unwrap(), vqf.yaw_rms.unwrap());
                    assert!(o < v, "{name}, a magnet passing by: yaw RMS ours {o} against VQF's {v}");
                }
                "no magnetometer" => assert!(ours.yaw_rms.is_none(), "{name}: yaw scored without a magnetometer"),
                _ => {}
            }
        }
    }
}

/// `--power-on-at` beyond a recording's end is refused in this command's
/// words (it spoke of the importer's `--from`).
#[test]
fn power_on_at_beyond_the_end_is_named_as_the_user_wrote_it() {
    let Some(rec) = one_recording("comma2k19-rav4-60s") else { return };
    let o = gyrocomp::reference::RefOptions { power_on_at: Some(1e9), ..Default::default() };
    let e = gyrocomp::reference::realdata::evaluate_recording(&rec, &gyrocomp::config::Config::default(), &o).err().unwrap();
    assert!(e.contains("--power-on-at 1000000000 s") && !e.contains("--from"), "{e}");
}
