//! Reduced axes on the real car (docs/estimator.md, "Reduced axes"): the
//! comma2k19 RAV4's own ESC sensor (Toyota `KINEMATICS` 0x24: yaw rate, ax,
//! ay) through `config/toyota-kinematics.toml`, with and without the car's
//! wheel speeds, against the reference's heading rate. The corrected yaw
//! rate must beat the raw one; cantools decodes the output frames, the
//! `Invalid*` bits and the fill values included.

mod common;
use gyrocomp::config::Config;
use gyrocomp::estimator::{invalid, Estimate};
use gyrocomp::output::Frames;
use gyrocomp::pipeline::{Pipeline, Sink};
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::Command;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// The recording, or None (said) when its folder is absent.
fn car() -> Option<PathBuf> {
    let dir = common::realdata_dir().map(|d| d.join("comma2k19-rav4-60s"));
    match dir.filter(|d| d.is_dir()) {
        Some(d) => Some(d),
        None => {
            println!("skipped: ../shared/realdata/comma2k19-rav4-60s not found (set GYROCOMP_REALDATA to the folder of recordings)");
            None
        }
    }
}

fn gunzip(p: &Path) -> String {
    let mut text = String::new();
    flate2::read::GzDecoder::new(std::fs::File::open(p).unwrap_or_else(|e| panic!("{}: {e}", p.display())))
        .read_to_string(&mut text)
        .unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    text
}

/// Per sample: (log time s, raw yaw rate, corrected yaw rate, bias z), deg/s.
#[derive(Default)]
struct Keep(Vec<(f64, f64, f64, f64)>, Vec<Estimate>);
impl Sink for Keep {
    fn output(&mut self, e: &Estimate, _: &Frames) {
        self.0.push((e.t_us as f64 * 1e-6 - 1.7e9, e.rate[2] + e.bias[2], e.rate[2], e.bias[2]));
        self.1.push(*e);
    }
}

/// The config written next to the recording's DBC, with its wheel speeds or not.
fn config(dir: &Path, car: &Path, speed: bool) -> PathBuf {
    let mut text = std::fs::read_to_string(Path::new(ROOT).join("config/toyota-kinematics.toml")).unwrap();
    text = text.replace("dbc = \"toyota-kinematics.dbc\"", &format!("dbc = {:?}", format!("{ROOT}/config/toyota-kinematics.dbc")));
    if speed {
        text += &format!(
            "[speed]\ndbc = {:?}\nmessage = \"WHEEL_SPEEDS\"\nsignals = [\"WHEEL_SPEED_RL\", \"WHEEL_SPEED_RR\"]\n",
            car.join("toyota.dbc").display().to_string()
        );
    }
    let p = dir.join(if speed { "with_speed.toml" } else { "imu_only.toml" });
    std::fs::write(&p, text).unwrap();
    p
}

/// The mean of `(t, v)` within `t0 +- h` (None: no sample there).
fn mean_near(xs: &[(f64, f64)], t0: f64, h: f64) -> Option<f64> {
    let lo = xs.partition_point(|x| x.0 < t0 - h);
    let hi = xs.partition_point(|x| x.0 < t0 + h);
    (hi > lo).then(|| xs[lo..hi].iter().map(|x| x.1).sum::<f64>() / (hi - lo) as f64)
}

/// The reference's heading rate (deg/s, NED: turning right positive) at
/// `t`: the unwrapped yaw's central difference over +-0.25 s.
fn heading_rate(reference: &[(f64, f64)], t: f64) -> Option<f64> {
    let at = |q: f64| {
        let i = reference.partition_point(|x| x.0 < q);
        (i > 0 && i < reference.len()).then(|| {
            let (a, b) = (reference[i - 1], reference[i]);
            a.1 + (b.1 - a.1) * (q - a.0) / (b.0 - a.0)
        })
    };
    Some((at(t + 0.25)? - at(t - 0.25)?) / 0.5)
}

fn reference(car: &Path) -> Vec<(f64, f64)> {
    let text = gunzip(&car.join("reference.csv.gz"));
    let mut out: Vec<(f64, f64)> = Vec::new();
    for l in text.lines().skip(1) {
        let v: Vec<f64> = l.split(',').take(4).map(|x| x.parse().unwrap()).collect();
        let mut yaw = v[3];
        if let Some(p) = out.last() {
            yaw += 360.0 * ((p.1 - yaw) / 360.0).round();
        }
        out.push((v[0], yaw));
    }
    out
}

/// RMS of raw and corrected against the reference's heading rate, both
/// averaged over +-0.25 s on a 0.05 s grid from 1 s to 59 s.
fn rms_errors(kept: &[(f64, f64, f64, f64)], reference: &[(f64, f64)]) -> (f64, f64, f64, usize) {
    let raw: Vec<(f64, f64)> = kept.iter().map(|k| (k.0, k.1)).collect();
    let cor: Vec<(f64, f64)> = kept.iter().map(|k| (k.0, k.2)).collect();
    let (mut sr, mut sc, mut sm, mut n) = (0.0, 0.0, 0.0, 0usize);
    for i in 0..=((59.0 - 1.0) / 0.05) as usize {
        let t = 1.0 + i as f64 * 0.05;
        if let (Some(h), Some(r), Some(c)) = (heading_rate(reference, t), mean_near(&raw, t, 0.25), mean_near(&cor, t, 0.25)) {
            sr += (r - h).powi(2);
            sc += (c - h).powi(2);
            sm += r - h;
            n += 1;
        }
    }
    let n1 = n.max(1) as f64;
    ((sr / n1).sqrt(), (sc / n1).sqrt(), sm / n1, n)
}

#[test]
fn the_cars_own_yaw_rate_corrected_beats_the_raw_one() {
    let Some(car) = car() else { return };
    let log = gunzip(&car.join("can.log.gz"));
    let reference = reference(&car);
    let d = tempfile::tempdir().unwrap();
    println!("the comma2k19 RAV4, 60 s, KINEMATICS yaw rate against the reference's heading rate (+-0.25 s means, 1..59 s):");
    println!(
        "{:<22} {:>10} {:>14} {:>12} {:>16} {:>9} {:>8}",
        "config", "raw RMS", "corrected RMS", "bias end", "raw-ref mean", "stand w", "cruise w"
    );
    let mut rows = Vec::new();
    for speed in [false, true] {
        let path = config(d.path(), &car, speed);
        let cfg = Config::load(&path).unwrap_or_else(|e| panic!("{e}"));
        let mut pipe = Pipeline::from_config(&cfg).unwrap_or_else(|e| panic!("{e}"));
        let mut keep = Keep::default();
        gyrocomp::replay::run(&mut pipe, log.as_bytes(), &mut keep).unwrap();
        assert!(keep.0.len() > 4000, "{} samples", keep.0.len());
        let (raw, cor, mean, n) = rms_errors(&keep.0, &reference);
        let r = pipe.estimator().reduced().expect("the reduced-axis filter");
        let c = r.counters;
        let name = if speed { "with wheel speeds" } else { "yaw rate, ax, ay only" };
        println!(
            "{name:<22} {raw:>10.3} {cor:>14.3} {:>12.3} {mean:>16.3} {:>9} {:>8}   ({n} points)",
            r.bias(),
            c.standstill_windows,
            c.cruise_windows
        );
        for e in &keep.1 {
            assert_eq!(e.invalid, invalid::REDUCED | invalid::TEMP);
            assert!(e.is_finite() && e.roll == 0.0 && e.pitch == 0.0 && e.rate[0] == 0.0 && e.bias[1] == 0.0);
        }
        rows.push((raw, cor, r.bias(), c));
    }
    // the car never stops (7.9 m/s at its slowest): without wheel speeds the
    // quiet straight stretches pass for standstills (the known limit), with
    // them they are straight cruises, each counted as a 0.2 deg/s reading
    for (raw, cor, bias, _) in &rows {
        assert!(cor < raw, "corrected RMS {cor} not under the raw {raw}");
        assert!(*bias > 0.3 && *bias < 0.5, "bias {bias}: the raw-reference mean is about 0.41");
    }
    let (raw, cor, _, c) = rows[1];
    assert!(cor < 0.4 * raw && c.standstill_windows == 0 && c.cruise_windows > 20, "with wheel speeds: {cor} vs {raw}, {c:?}");
}

/// cantools decodes the reduced unit's output frames as the CSV says: the
/// `Invalid*` bits and the fill value of each invalid field.
#[test]
fn cantools_decodes_the_reduced_outputs_invalid_bits() {
    let Some(car) = car() else { return };
    let d = tempfile::tempdir().unwrap();
    let input = d.path().join("can.log");
    std::fs::write(&input, gunzip(&car.join("can.log.gz"))).unwrap();
    let (out, csv) = (d.path().join("out.log"), d.path().join("est.csv"));
    let o = Command::new(common::bin())
        .args(["replay", "--config"])
        .arg(config(d.path(), &car, true))
        .arg("--input")
        .arg(&input)
        .arg("--output")
        .arg(&out)
        .arg("--csv")
        .arg(&csv)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let py = Command::new("python3")
        .arg(format!("{ROOT}/tests/dbc_check.py"))
        .arg(format!("{ROOT}/config/gyrocomp.dbc"))
        .arg(&out)
        .arg(&csv)
        .output()
        .expect("python3 must be installed (tests/run-all.sh installs it with cantools)");
    let so = String::from_utf8_lossy(&py.stdout);
    assert!(py.status.success(), "cantools check failed:\n{so}\n{}", String::from_utf8_lossy(&py.stderr));
    print!("{so}");
    assert!(std::fs::read_to_string(&csv).unwrap().lines().nth(1).unwrap().ends_with(",91"), "invalid = REDUCED | TEMP");
}

/// Hand-made KINEMATICS frames (config/toyota-kinematics.toml) with a known
/// yaw-rate bias of 0.56 deg/s, the car standing 5 s, then a 2 s turn at 10
/// deg/s: the bias is learned at the standstill, the heading is the turn's
/// (not the bias's drift), roll and pitch go out invalid as the fill value.
#[test]
fn a_known_yaw_bias_is_learned_at_a_standstill_from_kinematics_frames() {
    let cfg = Config::load(&Path::new(ROOT).join("config/toyota-kinematics.toml")).unwrap_or_else(|e| panic!("{e}"));
    let plan = cfg.input.plan.0.clone().expect("the DBC plan");
    let mut pipe = Pipeline::from_config(&cfg).unwrap_or_else(|e| panic!("{e}"));
    let mut keep = Keep::default();
    struct Both<'a>(&'a mut Keep, Vec<gyrocomp::output::Decoded>);
    impl Sink for Both<'_> {
        fn output(&mut self, e: &Estimate, f: &Frames) {
            self.0.output(e, f);
            self.1.push(gyrocomp::output::decode(f));
        }
    }
    let mut sink = Both(&mut keep, Vec::new());
    let (bias, period) = (0.56, 1.0 / cfg.input.rate_hz);
    let n_still = (5.0 / period) as u64;
    let n_turn = (2.0 / period) as u64;
    for k in 0..n_still + n_turn {
        // the turn: 10 deg/s (one quantum of the 0.244 deg/s grid from 10.56)
        let rate = if k < n_still { 0.0 } else { 10.004 };
        let vals = [0.0, 0.0, rate + bias, 0.0, 0.0, 0.0, 0.0];
        for f in plan.encode(k, &vals) {
            let t_us = 1_000_000 + (k as f64 * period * 1e6) as u64;
            pipe.push(t_us, gyrocomp::adis::RawFrame::classic(f.id, &f.data), &mut sink);
        }
    }
    let decoded = sink.1;
    let r = pipe.estimator().reduced().expect("the reduced-axis filter");
    assert!((r.bias() - bias).abs() < 0.005, "bias learned {} vs {bias}", r.bias());
    assert!(r.counters.standstill_windows >= 4, "{:?}", r.counters);
    // the heading: the turn's 20 deg, within the first window's drift (0.56 deg) and the quantum
    let yaw = keep.1.last().unwrap().yaw;
    assert!((yaw - 20.0).abs() < 0.8, "heading {yaw}, the turn's 20 deg");
    let last = decoded.last().unwrap();
    assert_eq!(last.invalid, invalid::REDUCED | invalid::TEMP);
    assert_eq!((last.att[0], last.att[1]), (-327.68, -327.68), "roll and pitch: the fill value");
    assert!((last.rate[2] - 10.0).abs() < 0.02 && (last.bias[2] - bias).abs() < 0.005, "{last:?}");
}

/// A reduced unit with a temperature (an MM7.10 without its pitch rate and
/// vertical axis: `config/mm7p10.toml` less `gyro_y`, `accel_z` and `TX3`):
/// the bias learned at a standstill at 25 deg C is carried by the thermal
/// curve (0.02 deg/s per deg C) while the car drives and warms to 45 deg C;
/// without the curve it stays where it was learned.
#[test]
fn the_thermal_curve_carries_the_yaw_bias_when_a_temperature_is_mapped() {
    let d = tempfile::tempdir().unwrap();
    let base = std::fs::read_to_string(Path::new(ROOT).join("config/mm7p10.toml")).unwrap();
    let mut text: String =
        base.lines().filter(|l| !l.starts_with("gyro_y =") && !l.starts_with("accel_z =")).map(|l| format!("{l}\n")).collect();
    text = text
        .replace("dbc = \"mm7p10.dbc\"", &format!("dbc = {:?}", format!("{ROOT}/config/mm7p10.dbc")))
        .replace(", \"TX3.MSG_CNT_TX3\"]", "]");
    let run = |thermal: bool| -> (f64, u8) {
        let t = format!("{text}[thermal]\nenabled = {thermal}\nt0 = 25.0\np1 = [0.0, 0.0, 0.02]\np2 = [0.0, 0.0, 0.0]\n");
        let p = d.path().join("mm5.toml");
        std::fs::write(&p, t).unwrap();
        let cfg = Config::load(&p).unwrap_or_else(|e| panic!("{e}"));
        let plan = cfg.input.plan.0.clone().expect("the DBC plan");
        let mut pipe = Pipeline::from_config(&cfg).unwrap_or_else(|e| panic!("{e}"));
        let mut keep = Keep::default();
        let (still, drive) = (400u64, 2000u64);
        for k in 0..still + drive {
            let temp = if k < still { 25.0 } else { 25.0 + 20.0 * (k - still) as f64 / drive as f64 };
            let bias = 0.3 + 0.02 * (temp - 25.0);
            // driving: a weaving yaw rate and a shaking body, never quiet
            let (rate, shake) = if k < still { (0.0, 0.0) } else { (8.0 * (k as f64 * 0.2).sin(), 0.05 * (k as f64 * 0.9).sin()) };
            let vals = [0.0, 0.0, rate + bias, shake, shake, 0.0, temp];
            for f in plan.encode(k, &vals) {
                pipe.push(1_000_000 + k * 10_000, gyrocomp::adis::RawFrame::classic(f.id, &f.data), &mut keep);
            }
        }
        let last = keep.1.last().copied().expect("estimates");
        (last.bias[2], last.invalid)
    };
    let (with_curve, invalid_bits) = run(true);
    let (without, _) = run(false);
    println!("bias at 45 deg C: with the curve {with_curve:.3} deg/s (true 0.700), without {without:.3} (learned at 25 deg C: 0.300)");
    assert_eq!(invalid_bits, invalid::REDUCED, "a temperature is mapped: TempC valid");
    assert!((with_curve - 0.7).abs() < 0.03, "with the curve: {with_curve}");
    assert!((without - 0.3).abs() < 0.03, "without the curve: {without}");
}
