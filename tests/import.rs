//! `gyrocomp import` as a user runs it: a CSV recording into the ADIS
//! contract, replayed back with the snippet it wrote.

mod common;
use common::bin;
use gyrocomp::adis::Sample;
use gyrocomp::config::{AutoBool, Config};
use gyrocomp::reference::decode;
use gyrocomp::reference::score::sample_times;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// A synthetic recording: 100 Hz from t = 3.25 s with a 0.2 s
/// hole after sample 150, every channel moving. Values in FRD, rounded to
/// the CSV's six decimals.
struct Rec {
    t: Vec<f64>,
    v: Vec<[f64; 10]>,
}

fn recording(n: usize) -> Rec {
    let mut t = Vec::new();
    let mut v = Vec::new();
    for k in 0..n {
        let tk = 3.25 + k as f64 * 0.01 + if k > 150 { 0.2 } else { 0.0 };
        let s = (0.7 * tk).sin();
        let c = (1.3 * tk).cos();
        v.push([
            250.0 * s,
            -37.5 * c + 3.0,
            0.4 * s * c,
            0.31 * c,
            -0.2 * s,
            -1.0 + 0.6 * s * s,
            0.21 * c,
            -0.05 * s,
            0.43,
            24.0 + 8.0 * s,
        ]);
        t.push(tk);
    }
    // as the CSV carries them (6 decimals)
    let v = v.into_iter().map(|x: [f64; 10]| x.map(|y| (y * 1e6).round() / 1e6)).collect();
    Rec { t, v }
}

fn csv_text(r: &Rec, header: &str, row: impl Fn(f64, &[f64; 10]) -> String) -> String {
    let mut s = format!("{header}\n");
    for (t, v) in r.t.iter().zip(&r.v) {
        s += &row(*t, v);
        s.push('\n');
    }
    s
}

fn full_row(t: f64, v: &[f64; 10]) -> String {
    let mut s = format!("{t:.6}");
    for x in v {
        s += &format!(",{x:.6}");
    }
    s
}

const HEADER: &str = "t,gx,gy,gz,ax,ay,az,mx,my,mz,temp";

fn import(args: &[&str]) -> Output {
    Command::new(bin()).arg("import").args(args).output().unwrap()
}

fn ok(o: &Output) -> String {
    let e = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(o.status.success(), "import failed: {e}");
    e
}

fn p(x: &Path) -> &str {
    x.to_str().unwrap()
}

/// The samples of a log as the snippet's config decodes them.
fn replayed(log: &Path, snippet: &Path) -> (Config, Vec<Sample>) {
    let cfg = Config::load(snippet).unwrap();
    let d = decode(std::fs::File::open(log).unwrap(), &cfg, "out").unwrap();
    (cfg, d.samples)
}

fn check_round_trip(r: &Rec, cfg: &Config, samples: &[Sample], magn: bool, temp: bool) {
    let pr = cfg.profile();
    assert_eq!(samples.len(), r.t.len());
    let ts = sample_times(samples, 1.0 / pr.rate_hz);
    let lsb = [pr.gyro_lsb, pr.accel_lsb, pr.magn_lsb, pr.temp_lsb];
    for (k, s) in samples.iter().enumerate() {
        // time from the counter: the CSV's t from its first sample
        assert!((ts[k] - (r.t[k] - r.t[0])).abs() < 1e-6, "sample {k}: t {} vs {}", ts[k], r.t[k] - r.t[0]);
        let v = &r.v[k];
        for i in 0..3 {
            assert!((s.gyro[i] - v[i]).abs() <= 0.5 * lsb[0] + 1e-12, "gyro {k}/{i}: {} vs {}", s.gyro[i], v[i]);
            assert!((s.accel[i] - v[3 + i]).abs() <= 0.5 * lsb[1] + 1e-12, "accel {k}/{i}");
            let want_m = if magn { v[6 + i] } else { 0.0 };
            assert!((s.magn[i] - want_m).abs() <= 0.5 * lsb[2] + 1e-12, "magn {k}/{i}: {} vs {want_m}", s.magn[i]);
        }
        let want_t = if temp { v[9] } else { pr.temp_offset };
        assert!((s.temp - want_t).abs() <= 0.5 * lsb[3] + 1e-12, "temp {k}: {} vs {want_t}", s.temp);
    }
}

#[test]
fn csv_round_trip_through_import_and_replay() {
    let d = tempfile::tempdir().unwrap();
    let r = recording(400);
    // gzip input, as the real recordings come
    let csv = d.path().join("imu.csv.gz");
    let mut gz = flate2::write::GzEncoder::new(std::fs::File::create(&csv).unwrap(), flate2::Compression::default());
    gz.write_all(csv_text(&r, HEADER, full_row).as_bytes()).unwrap();
    gz.finish().unwrap();
    let (log, snip) = (d.path().join("out.log"), d.path().join("in.toml"));
    let err = ok(&import(&["--csv", p(&csv), "--out", p(&log), "--config-out", p(&snip)]));
    assert!(err.contains("400 samples") && err.contains("1 counter gaps (20 samples)"), "{err}");
    let (cfg, samples) = replayed(&log, &snip);
    assert!((cfg.profile().rate_hz - 100.0).abs() < 1e-9, "rate estimated from t: {}", cfg.profile().rate_hz);
    assert_eq!(cfg.estimator.use_magnetometer, AutoBool::Auto, "the recording has a magnetometer");
    assert!(cfg.thermal.enabled, "the recording has a temperature");
    check_round_trip(&r, &cfg, &samples, true, true);
    // Auto scales: the finest two-digit LSB with headroom (250 deg/s * 1.25 / 32767 -> 0.0096).
    assert_eq!(cfg.profile().gyro_lsb, 0.0096);
    // the contract: four frames a sample, one timestamp each, the counter gap
    let text = std::fs::read_to_string(&log).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 4 * 400);
    assert!(lines[0].starts_with("(1700000003.250000) can0 100#"), "{}", lines[0]);
    assert!(lines[3].starts_with("(1700000003.250360) can0 103#"), "{}", lines[3]);
    assert!(samples[151].steps == 21 && samples.iter().filter(|s| s.steps > 1).count() == 1);
    // and the binary replays it with the snippet, the gap counted
    let o = Command::new(bin())
        .args(["replay", "--config", p(&snip), "--input", p(&log), "--csv", p(&d.path().join("e.csv"))])
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success() && e.contains("samples 400") && e.contains("lost 20 in 1 gaps"), "{e}");
    // same input, same bytes
    let log2 = d.path().join("out2.log");
    ok(&import(&["--csv", p(&csv), "--out", p(&log2)]));
    assert_eq!(std::fs::read(&log).unwrap(), std::fs::read(&log2).unwrap());
}

#[test]
fn no_magnetometer_or_temperature_turns_them_off_in_the_snippet() {
    let d = tempfile::tempdir().unwrap();
    let r = recording(200);
    // mx..temp present but empty (as in the real recordings) ...
    let csv = d.path().join("a.csv");
    std::fs::write(&csv, csv_text(&r, HEADER, |t, v| format!("{},,,,", full_row(t, v).rsplitn(5, ',').last().unwrap()))).unwrap();
    // ... or absent
    let csv_b = d.path().join("b.csv");
    std::fs::write(&csv_b, csv_text(&r, "t,gx,gy,gz,ax,ay,az", |t, v| full_row(t, v).rsplitn(5, ',').last().unwrap().to_string())).unwrap();
    for c in [&csv, &csv_b] {
        let (log, snip) = (d.path().join("o.log"), d.path().join("o.toml"));
        ok(&import(&["--csv", p(c), "--out", p(&log), "--config-out", p(&snip)]));
        let text = std::fs::read_to_string(&snip).unwrap();
        let (cfg, samples) = replayed(&log, &snip);
        assert_eq!(cfg.estimator.use_magnetometer, AutoBool::Bool(false), "{text}");
        assert!(!cfg.thermal.enabled, "{text}");
        check_round_trip(&r, &cfg, &samples, false, false);
        // The snippet laid over a config with a thermal curve and the magnetometer on turns both off.
        let base = Config::parse("[thermal]\np1 = [0.01, 0.02, 0.03]\np2 = [0.1, 0.1, 0.1]\nlearn = true\n", "base").unwrap();
        let merged = gyrocomp::import::overlay(&base, &text, "snippet").unwrap();
        assert!(!merged.thermal.enabled && merged.estimator.use_magnetometer == AutoBool::Bool(false));
        assert_eq!(merged.profile(), cfg.profile());
    }
}

#[test]
fn profile_scales_where_they_cover_the_data_and_axes_maps() {
    let d = tempfile::tempdir().unwrap();
    let r = recording(200);
    let csv = d.path().join("a.csv");
    std::fs::write(&csv, csv_text(&r, HEADER, full_row)).unwrap();
    let (log, snip) = (d.path().join("o.log"), d.path().join("o.toml"));
    ok(&import(&["--csv", p(&csv), "--out", p(&log), "--config-out", p(&snip), "--profile", "adis16448", "--rate", "100"]));
    let (cfg, samples) = replayed(&log, &snip);
    let pr = cfg.profile();
    assert_eq!((pr.gyro_lsb, pr.accel_lsb, pr.magn_lsb, pr.temp_lsb), (0.04, 0.833e-3, 142.9e-6, 0.07386));
    check_round_trip(&r, &cfg, &samples, true, true);
    // ADIS16405's 0.05 deg/s covers 1638 deg/s: a faster gyro gets its own scale, the rest stays
    let big = Rec { t: r.t.clone(), v: r.v.iter().map(|v| [v[0] * 10.0, v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8], v[9]]).collect() };
    let max = big.v.iter().map(|v| v[0].abs()).fold(0.0, f64::max);
    assert!(max > 32767.0 * 0.05, "{max}");
    std::fs::write(&csv, csv_text(&big, HEADER, full_row)).unwrap();
    ok(&import(&["--csv", p(&csv), "--out", p(&log), "--config-out", p(&snip), "--profile", "adis16405"]));
    let (cfg, samples) = replayed(&log, &snip);
    let pr = cfg.profile();
    assert_eq!((pr.gyro_lsb, pr.accel_lsb), (0.073, 3.33e-3), "gyro auto ({max} * 1.25 / 32767 up to two digits), accel the profile's");
    check_round_trip(&big, &cfg, &samples, true, true);
    // A FLU recording with --axes x,-y,-z reads back as the FRD values.
    let flu = d.path().join("flu.csv");
    std::fs::write(
        &flu,
        csv_text(&r, HEADER, |t, v| {
            let f = [v[0], -v[1], -v[2], v[3], -v[4], -v[5], v[6], -v[7], -v[8], v[9]];
            full_row(t, &f)
        }),
    )
    .unwrap();
    ok(&import(&["--csv", p(&flu), "--out", p(&log), "--config-out", p(&snip), "--axes", "x,-y,-z"]));
    let (cfg, samples) = replayed(&log, &snip);
    check_round_trip(&r, &cfg, &samples, true, true);
    let o = import(&["--csv", p(&flu), "--out", p(&log), "--axes", "x,y,-z"]);
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("reflection"));
}

/// A car's bus on the recording's clock (t + epoch): 0x0B4 every 7 ms, an
/// extended frame, a remote frame, from before the IMU's first sample
/// (3.25 s) to after its last.
fn car_bus() -> String {
    let mut car = String::new();
    let mut n_car = 0;
    let mut tc = 3.2;
    while tc < 5.8 {
        car += &format!("({:.6}) can0 0B4#000000001D0B7A5E\n", 1_700_000_000.0 + tc);
        if n_car % 50 == 0 {
            car += &format!("({:.6}) can0 18FEF100#0102\n({:.6}) can0 224#R\n", 1_700_000_000.0 + tc, 1_700_000_000.0 + tc);
        }
        n_car += 1;
        tc += 0.007;
    }
    car
}

/// `recording(200)` as a CSV beside `car_bus()` as a log, and where the
/// import writes (the log, the snippet).
struct Files {
    r: Rec,
    csv: PathBuf,
    car: String,
    car_p: PathBuf,
    log: PathBuf,
    snip: PathBuf,
}

fn recording_and_car_bus(dir: &Path) -> Files {
    let r = recording(200);
    let csv = dir.join("a.csv");
    std::fs::write(&csv, csv_text(&r, HEADER, full_row)).unwrap();
    let car = car_bus();
    let car_p = dir.join("car.log");
    std::fs::write(&car_p, &car).unwrap();
    Files { r, csv, car, car_p, log: dir.join("o.log"), snip: dir.join("o.toml") }
}

#[test]
fn another_bus_is_merged_by_timestamp() {
    let d = tempfile::tempdir().unwrap();
    let Files { r, csv, car, car_p, log, snip } = recording_and_car_bus(d.path());
    let err = ok(&import(&["--csv", p(&csv), "--out", p(&log), "--config-out", p(&snip), "--can", p(&car_p)]));
    let text = std::fs::read_to_string(&log).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 4 * 200 + car.lines().count(), "{err}");
    // every car line verbatim, in its order; the whole log in time order
    let imu = |l: &str| ["100#", "101#", "102#", "103#"].iter().any(|id| l.contains(&format!("can0 {id}")));
    let kept: Vec<&str> = lines.iter().copied().filter(|l| !imu(l)).collect();
    assert_eq!(kept, car.lines().collect::<Vec<_>>());
    let stamps: Vec<u64> = lines.iter().map(|l| gyrocomp::candump::parse_line(l.as_bytes()).unwrap().t_us).collect();
    assert!(stamps.windows(2).all(|w| w[0] <= w[1]), "not in time order");
    assert!(lines[0].contains("0B4#") && lines.last().unwrap().contains("0B4#"), "car frames before and after the IMU's");
    // the IMU decodes as before
    let (cfg, samples) = replayed(&log, &snip);
    check_round_trip(&r, &cfg, &samples, true, true);
    // a car log on one of the IMU's IDs, or with a bad line, is refused by line
    std::fs::write(&car_p, format!("{}(1700000004.000000) can0 101#0011223344556677\n", &car[..car.find('\n').unwrap() + 1])).unwrap();
    let o = import(&["--csv", p(&csv), "--out", p(&log), "--can", p(&car_p)]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("car.log line 2") && e.contains("101"), "{e}");
    std::fs::write(&car_p, "(1700000003.300000) can0 0B4#00\nnot a candump line\n").unwrap();
    let o = import(&["--csv", p(&csv), "--out", p(&log), "--can", p(&car_p)]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("car.log line 2"), "{e}");
}

/// `--from S`: the unit powered on at S (a daemon restarted while moving).
/// The log holds the samples from S on, on the recording's clock, and the
/// car's lines from the first of them on; they decode as the recording cut
/// there by hand would. A `--from` past the end is refused, naming it, and
/// writes nothing.
#[test]
fn from_powers_the_unit_on_later_with_the_car_bus_from_then_on() {
    let d = tempfile::tempdir().unwrap();
    let Files { r, csv, car, car_p, log, snip } = recording_and_car_bus(d.path());
    let err = ok(&import(&["--csv", p(&csv), "--out", p(&log), "--config-out", p(&snip), "--can", p(&car_p), "--from", "4.0"]));
    let k0 = r.t.iter().position(|t| *t >= 4.0).unwrap();
    assert_eq!(k0, 75);
    let cut = Rec { t: r.t[k0..].to_vec(), v: r.v[k0..].to_vec() };
    let text = std::fs::read_to_string(&log).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let first_imu = gyrocomp::candump::parse_line(lines[0].as_bytes()).unwrap().t_us;
    assert_eq!(first_imu, 1_700_000_000_000_000 + (cut.t[0] * 1e6).round() as u64, "the log starts at the first sample kept");
    // the car's lines from the first sample on, verbatim and in order
    let stamp = |l: &str| gyrocomp::candump::parse_line(l.as_bytes()).unwrap().t_us;
    let car_after: Vec<&str> = car.lines().filter(|l| stamp(l) >= first_imu).collect();
    let imu = |l: &str| ["100#", "101#", "102#", "103#"].iter().any(|id| l.contains(&format!("can0 {id}")));
    assert_eq!(lines.iter().copied().filter(|l| !imu(l)).collect::<Vec<_>>(), car_after);
    assert_eq!(lines.len(), 4 * cut.t.len() + car_after.len());
    let before = car.lines().count() - car_after.len();
    assert!(before > 0 && err.contains(&format!("{before} of its lines before the first sample left out")), "{err}");
    assert!(err.contains("the first sample is t = 4"), "{err}");
    let (cfg, samples) = replayed(&log, &snip);
    check_round_trip(&cut, &cfg, &samples, true, true);
    // past the end: refused, nothing written
    let log2 = d.path().join("late.log");
    let o = import(&["--csv", p(&csv), "--out", p(&log2), "--from", "99"]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("--from 99") && e.contains("ends at t = 5.44"), "{e}");
    assert!(!log2.exists());
}

/// Each kind of bad input: a clear error naming the line and the column,
/// exit 1, and no output left that looks like a good log (an old one kept).
#[test]
fn bad_csvs_are_refused_by_line_and_column() {
    let d = tempfile::tempdir().unwrap();
    let good = csv_text(&recording(20), HEADER, full_row);
    let lines: Vec<String> = good.lines().map(String::from).collect();
    let with = |k: usize, f: &dyn Fn(&str) -> String| {
        let mut l = lines.clone();
        l[k] = f(&l[k]);
        l.join("\n") + "\n"
    };
    let field = |line: &str, i: usize, v: &str| {
        let mut f: Vec<String> = line.split(',').map(String::from).collect();
        f[i] = v.into();
        f.join(",")
    };
    let cases: Vec<(&str, String, &[&str])> = vec![
        ("non-numeric", with(5, &|l| field(l, 2, "1.2.3")), &["line 6, column gy", "not a number"]),
        ("non-increasing time", with(8, &|l| field(l, 0, "3.25")), &["line 9, column t", "not after"]),
        ("equal time", with(8, &|_| lines[7].clone()), &["line 9, column t"]),
        ("missing column", good.replacen("t,gx,gy,gz,ax,ay,az", "t,gx,gy,gz,ax,ay,accz", 1), &["line 1", "missing required column(s) az"]),
        ("NaN in gyro", with(3, &|l| field(l, 3, "NaN")), &["line 4, column gz", "not a finite number"]),
        ("NaN in accel", with(12, &|l| field(l, 4, "nan")), &["line 13, column ax", "not a finite number"]),
        ("inf in accel", with(12, &|l| field(l, 6, "-inf")), &["line 13, column az"]),
        ("empty accel", with(7, &|l| field(l, 5, "")), &["line 8, column ay", "empty"]),
        ("short line", with(7, &|l| l.rsplitn(2, ',').last().unwrap().to_string()), &["line 8", "10 fields"]),
        ("empty file", String::new(), &["empty file"]),
        ("header only", format!("{HEADER}\n"), &["no data lines"]),
    ];
    let out = d.path().join("out.log");
    let snip = d.path().join("out.toml");
    for (what, text, want) in cases {
        let csv = d.path().join("bad.csv");
        std::fs::write(&csv, &text).unwrap();
        std::fs::write(&out, "old log\n").unwrap();
        let _ = std::fs::remove_file(&snip);
        let o = import(&["--csv", p(&csv), "--out", p(&out), "--config-out", p(&snip)]);
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{what}: {e}");
        for w in want {
            assert!(e.contains(w), "{what}: want {w:?} in {e}");
        }
        assert!(e.contains("bad.csv"), "{what}: the file is named: {e}");
        assert_eq!(std::fs::read_to_string(&out).unwrap(), "old log\n", "{what}: the old output was touched");
        assert!(!snip.exists(), "{what}: a snippet was written");
        let names: Vec<PathBuf> = std::fs::read_dir(d.path()).unwrap().map(|e| e.unwrap().path()).collect();
        assert!(names.iter().all(|n| !n.to_string_lossy().contains(".tmp-")), "{what}: temporary left: {names:?}");
    }
    // a missing file, and an output that is the input
    let o = import(&["--csv", p(&d.path().join("nope.csv")), "--out", p(&out)]);
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("nope.csv"));
    let csv = d.path().join("good.csv");
    std::fs::write(&csv, &good).unwrap();
    let o = import(&["--csv", p(&csv), "--out", p(&csv)]);
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("refusing to overwrite an input"));
    assert_eq!(std::fs::read_to_string(&csv).unwrap(), good);
}
