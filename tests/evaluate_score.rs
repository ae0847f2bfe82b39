//! `gyrocomp evaluate` scores known cases right.

use gyrocomp::config::Config;
use gyrocomp::evaluate::{evaluate_dir, oracle, score, EvalOptions, Metrics, RunData};
use gyrocomp::sim::model::SensorModel;
use gyrocomp::sim::{simulate, SimOptions};

const NO_WALK: &str = "[noise]\ngyro_white = 0.0135\ngyro_bias_walk = 0.0\naccel_white = 0.00023\nmagn_white = 0.0005\ntemp_white = 0.0\n";

#[test]
fn a_known_thermal_bias_error_is_scored_right() {
    // At rest; turn-on bias plus 0.02 deg/s/C on x only. The start-up average
    // (30 s after 1 s) learns the bias at the mean temperature of its window
    // and never follows the temperature: the x bias error and the roll error
    // it integrates to are known from the truth temperature.
    let model = SensorModel::parse(&format!(
        "[gyro]\neffects = [\"turn_on_bias\", \"thermal_linear\"]\n[gyro.turn_on_bias]\nbias = [0.32, -0.12, 0.48]\n\
         [gyro.thermal_linear]\nt0 = 25.0\np1 = [0.02, 0.0, 0.0]\n{NO_WALK}"
    ))
    .unwrap();
    let t = tempfile::tempdir().unwrap();
    let dir = t.path().join("run");
    let mut o = SimOptions::new("static", 9);
    o.duration = Some(200.0);
    o.model = Some(model);
    simulate(&o, &dir).unwrap();
    let data = RunData::load(&dir).unwrap();
    let cfg = Config::parse("[estimator]\nmode = \"startup_average\"\nwarmup_s = 1.0\nlearn_s = 30.0\n", "t").unwrap();
    let (est, ms) = data.estimates(&cfg).unwrap();
    let m = score("sa", &data, &est, ms, 31.5);
    let m_all = score("sa", &data, &est, ms, 0.0);
    assert!((ms[2] - 200.0).abs() < 0.01, "time in gyro-only {ms:?}");
    let tr = &data.truth;
    let win: Vec<f64> = tr.iter().filter(|r| r.t >= 1.0 && r.t <= 31.0).map(|r| r.temp).collect();
    let tbar = win.iter().sum::<f64>() / win.len() as f64;
    let t_end = tr.last().unwrap().temp;
    let want_bias = 0.02 * (t_end - tbar);
    assert!(want_bias > 0.05, "the run must heat: {want_bias}");
    assert!((m.bias_max[0] - want_bias).abs() < 0.005, "bias error x {} vs {want_bias}", m.bias_max[0]);
    assert!(m.bias_max[1] < 0.005 && m.bias_max[2] < 0.005, "{:?}", m.bias_max);
    let dt = 1.0 / 204.8;
    // before the window closes the bias held is 0: the whole true bias integrates
    let before: f64 = tr.iter().zip(&data.bias).filter(|(r, _)| r.t <= 31.0).map(|(_, b)| b[0] * dt).sum();
    let want_roll: f64 = before + tr.iter().filter(|r| r.t > 31.0).map(|r| 0.02 * (r.temp - tbar) * dt).sum::<f64>();
    assert!(want_roll > 1.0);
    assert!((m_all.max_err[0] - want_roll).abs() < 0.05 * want_roll + 0.2, "roll max {} vs {want_roll}", m_all.max_err[0]);
    // The oracle knows the thermal slope: only white noise and quantisation remain.
    let (orc, _) = oracle(&data, &est, 0.0);
    assert!(orc.max_err[0] < 0.2 && orc.max_err[1] < 0.2, "oracle {:?}", orc.max_err);
}

#[test]
fn the_oracle_removes_every_deterministic_effect() {
    // Moving vehicle, every rate-dependent effect on, no noise: the oracle
    // integrates to the truth; the same gyro without the correction does not.
    let model = SensorModel::parse(
        "[gyro]\neffects = [\"turn_on_bias\", \"g_sensitivity\", \"scale_factor\", \"misalignment\", \"warmup_transient\"]\n\
         [gyro.turn_on_bias]\nbias = [0.2, -0.3, 0.1]\n[gyro.g_sensitivity]\ng = [[0.0, 0.01, 0.0], [0.01, 0.0, 0.0], [0.0, 0.0, 0.01]]\n\
         [gyro.scale_factor]\nk = [0.003, -0.003, 0.003]\n[gyro.misalignment]\nm = [[0.0, 0.002, 0.0], [0.0, 0.0, 0.002], [0.002, 0.0, 0.0]]\n\
         [gyro.warmup_transient]\namplitude = [0.1, 0.1, -0.1]\ntau_s = 20.0\n\
         [noise]\ngyro_white = 0.0\ngyro_bias_walk = 0.0\naccel_white = 0.0\nmagn_white = 0.0\ntemp_white = 0.0\n",
    )
    .unwrap();
    let mut o = SimOptions::new("vehicle", 3);
    o.duration = Some(120.0);
    o.model = Some(model);
    let data = RunData::simulate(&o).unwrap();
    let cfg = Config::parse("[estimator]\nmode = \"startup_average\"\n", "t").unwrap();
    let (est, _) = data.estimates(&cfg).unwrap();
    let (orc, errs) = oracle(&data, &est, 20.0);
    assert_eq!(errs.len() as f64, (100.0 * 204.8f64).round());
    // only quantisation (0.04 deg/s LSB, no dither) is left
    assert!(orc.max_err.iter().all(|e| *e < 0.3), "oracle {:?}", orc.max_err);
    let m = score("sa", &data, &est, [0.0; 3], 20.0);
    assert!(m.max_err[2] > 3.0 * orc.max_err[2], "uncorrected yaw {} vs oracle {}", m.max_err[2], orc.max_err[2]);
}

#[test]
fn ablation_prints_the_three_paper_cases_and_writes_the_report() {
    let t = tempfile::tempdir().unwrap();
    let dir = t.path().join("run");
    let mut o = SimOptions::new("paper", 5);
    o.duration = Some(40.0);
    simulate(&o, &dir).unwrap();
    let cfg = Config::load(&dir.join("config.toml")).unwrap();
    let rep = t.path().join("rep");
    let text =
        evaluate_dir(&cfg, &dir, &EvalOptions { score_from: 10.0, ablation: true, out: Some(rep.clone()), peers: false, mcap: None })
            .unwrap();
    for case in ["1 startup_average", "2 startup_thermal", "3 paper"] {
        assert!(text.contains(case), "{text}");
    }
    // 40 s of `paper` end before its manoeuvres: no oracle floor, a warning instead
    assert!(text.contains("warning: no manoeuvres to score"), "{text}");
    assert!(!text.lines().any(|l| l.starts_with("oracle floor") || l.contains("inf")), "{text}");
    let j: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(rep.join("report.json")).unwrap()).unwrap();
    assert!(j["cases"].as_array().unwrap().len() >= 3);
    assert_eq!(j["oracle"]["samples"], 0, "an oracle floor over a window the run never reaches");
    for svg in ["attitude_error.svg", "bias.svg"] {
        let s = std::fs::read_to_string(rep.join(svg)).unwrap();
        assert!(s.starts_with("<svg") && s.contains("polyline"), "{svg}");
    }
}

/// The default filter holds the attitude through the manoeuvres of a
/// `vehicle --hard` run within the targets, and the ground-vehicle
/// constraint is what does it: with the vehicle model off (a unit that goes
/// nowhere on average) the same run misses them.
#[test]
fn default_holds_attitude_through_hard_manoeuvres() {
    let mut o = SimOptions::new("vehicle", 6);
    o.hard = true;
    let data = RunData::simulate(&o).unwrap();
    let start = data.info.manoeuvre_start_s;
    let run = |extra: &str| {
        let mut c = Config::parse(extra, "test").unwrap();
        c.thermal = data.unit_config.as_ref().unwrap().thermal.clone();
        let (est, ms) = data.estimates(&c).unwrap();
        (score("default", &data, &est, ms, start), oracle(&data, &est, start).0)
    };
    let (m, orc) = run("");
    assert!(m.max_err[0] <= 2.0 && m.max_err[1] <= 2.0, "max roll/pitch {:?}", m.max_err);
    assert!(m.tilt_max() <= 1.5 * orc.tilt_max(), "{} vs oracle {}", m.tilt_max(), orc.tilt_max());
    assert!(m.rms_err[2] <= 3.0, "yaw rms {}", m.rms_err[2]);
    let (off, _) = run("[mekf]\nvehicle = false\n");
    assert!(off.tilt_max() > 2.0 && off.tilt_max() > 2.0 * m.tilt_max(), "without the model {} vs {}", off.tilt_max(), m.tilt_max());
}

/// City driving with a turn-on bias of several deg/s (the `urban`
/// scenario, IMU only): standstills re-anchor everything, the velocity model
/// keeps sustained accelerations out of the tilt. The paper's filter, given
/// the same samples, loses the attitude.
#[test]
fn default_holds_attitude_in_city_driving() {
    let o = SimOptions::new("urban", 4);
    let data = RunData::simulate(&o).unwrap();
    let run = |extra: &str| {
        let mut c = Config::parse(extra, "test").unwrap();
        let u = data.unit_config.as_ref().unwrap();
        c.thermal = u.thermal.clone();
        c.mounting = u.mounting.clone();
        let (est, ms) = data.estimates(&c).unwrap();
        score("x", &data, &est, ms, 10.0)
    };
    let m = run("");
    assert!(m.max_err[0] <= 1.0 && m.max_err[1] <= 1.0, "max roll/pitch {:?}", m.max_err);
    let paper = run("[estimator]\nmode = \"paper\"\n");
    assert!(paper.tilt_max() > 5.0 * m.tilt_max(), "paper {} vs {}", paper.tilt_max(), m.tilt_max());
}

/// The default filter on `scenario` `seed` powered on while driving (the
/// unit's own calibration and mounting, no saved state), scored from each
/// of `from_s`.
fn powered_on_while_driving(scenario: &str, seed: u64, from_s: &[f64]) -> Vec<Metrics> {
    let mut o = SimOptions::new(scenario, seed);
    o.power_on_moving = true;
    let data = RunData::simulate(&o).unwrap();
    let mut c = Config::default();
    let u = data.unit_config.as_ref().unwrap();
    c.thermal = u.thermal.clone();
    c.mounting = u.mounting.clone();
    let (est, ms) = data.estimates(&c).unwrap();
    from_s.iter().map(|&f| score("x", &data, &est, ms, f)).collect()
}

/// The default filter on urban `seed` powered on while driving, IMU only,
/// no saved state, scored from `from_s`.
fn urban_powered_on_while_driving(seed: u64, from_s: f64) -> Metrics {
    powered_on_while_driving("urban", seed, &[from_s]).remove(0)
}

/// Powered on while driving, IMU only, no saved state (a daemon's first start
/// on the road): before the first stop nothing tells a tilt from an
/// acceleration, but the filter must not diverge for good. On the seeds that
/// diverged before (a bias run out of the part's range, stops never seen as
/// standstills because g0 held the car's acceleration, a confidently wrong
/// bias that hid every later stop), every seed holds roll and pitch within
/// 1 deg from 100 s on.
#[test]
fn default_powered_on_while_driving_converges_at_the_stops() {
    for seed in [3u64, 6, 7, 9, 15, 16] {
        let m = urban_powered_on_while_driving(seed, 100.0);
        assert!(m.max_err[0] <= 1.0 && m.max_err[1] <= 1.0, "seed {seed}: max roll/pitch from 100 s {:?}", m.max_err);
    }
}

/// Issue 11's urban target holds powered on while driving too (IMU only, no
/// saved state, scored from 10 s): median of the per-seed max roll/pitch
/// error <= 3 deg, worst <= 5 deg over 20 seeds. Before the power-on speed
/// hypotheses the filter took the moving car for standing: median 7.2, worst
/// 36.6 deg.
#[test]
fn default_powered_on_while_driving_meets_the_urban_target_from_10_s() {
    let mut maxes = Vec::new();
    for seed in 1..=20u64 {
        let m = urban_powered_on_while_driving(seed, 10.0);
        println!("seed {seed}: max roll {:.3} pitch {:.3} deg", m.max_err[0], m.max_err[1]);
        maxes.push(m.max_err[0].max(m.max_err[1]));
    }
    maxes.sort_by(|a, b| a.total_cmp(b));
    let (median, worst) = (0.5 * (maxes[9] + maxes[10]), maxes[19]);
    println!("median {median:.3} worst {worst:.3} deg");
    assert!(median <= 3.0 && worst <= 5.0, "median {median} worst {worst}");
}

/// A car powered on while driving (IMU and magnetometer, no saved state)
/// that never stops: `vehicle --power-on-moving` seed 18 drives 800 s
/// without a standstill, its bias never read at rest. Twice a steady, gentle
/// turn at constant speed (3-4 deg/s, 0.06-0.09 g: within the rest band on
/// |f|, every signal steady) was taken for a standstill and re-levelled
/// onto: the turn read as a 3-4 deg/s bias, the velocity zeroed at 10-16
/// m/s. The first time the filter's own motion said it was a turn
/// (`turning_at_speed`); the second time its speed had run to zero, and only
/// the field, turning in the car's frame, said so (`field_turned`). Without
/// them: max roll/pitch 11.3 / 10.7 deg from 10 s and 10.3 / 10.7 in the
/// manoeuvres.
#[test]
fn a_car_that_never_stops_takes_no_steady_turn_for_a_standstill() {
    let m = powered_on_while_driving("vehicle", 18, &[10.0, 350.0]);
    let (all, man) = (&m[0], &m[1]);
    println!("from 10 s {:?}, from 350 s {:?}", all.max_err, man.max_err);
    assert!(all.max_err[0] <= 3.0 && all.max_err[1] <= 3.0, "max roll/pitch from 10 s {:?}", all.max_err);
    assert!(man.max_err[0] <= 2.0 && man.max_err[1] <= 2.0, "max roll/pitch in the manoeuvres {:?}", man.max_err);
}

/// A crawl at 0.5-3 m/s whose quiet moments are taken for stops: once a
/// standstill has read the bias the gyro holds the tilt, and a quiet
/// period whose specific force that tilt refuses (a crawl easing off or on)
/// is not re-levelled onto. `crawl` seed 2 reached 2.30 / 3.22 deg with
/// the re-level forcing that acceleration into the tilt and the bias.
#[test]
fn a_crawl_is_not_re_levelled_onto_its_gentle_accelerations() {
    let data = RunData::simulate(&SimOptions::new("crawl", 2)).unwrap();
    let mut c = Config::default();
    let u = data.unit_config.as_ref().unwrap();
    c.thermal = u.thermal.clone();
    c.mounting = u.mounting.clone();
    let (est, ms) = data.estimates(&c).unwrap();
    let m = score("x", &data, &est, ms, 10.0);
    println!("crawl seed 2: max roll/pitch {:?}", m.max_err);
    assert!(m.max_err[0] <= 1.0 && m.max_err[1] <= 1.5, "max roll/pitch {:?}", m.max_err);
}

/// A car powered on in a smooth cruise, IMU only: the zero-speed copy of
/// the power-on bank takes the quiet IMU for a standstill within 2 s, the
/// copies at the car's speed take it for a cruise; the bank is not ended
/// by that "first standstill" (it ended there at 1.9 s, keeping 0 m/s,
/// before), but runs until evidence or its time limit.
#[test]
fn a_smooth_cruise_at_power_on_does_not_end_the_speed_bank() {
    let d = tempfile::tempdir().unwrap();
    let run = d.path().join("run");
    let bin = env!("CARGO_BIN_EXE_gyrocomp");
    let sim = std::process::Command::new(bin)
        .args(["simulate", "--scenario", "smooth", "--power-on-moving", "--seed", "2", "--duration", "80", "--out"])
        .arg(&run)
        .output()
        .unwrap();
    assert!(sim.status.success(), "{}", String::from_utf8_lossy(&sim.stderr));
    let o = std::process::Command::new(bin)
        .arg("replay")
        .arg("--config")
        .arg(run.join("config.toml"))
        .arg("--input")
        .arg(run.join("imu.log"))
        .arg("--output")
        .arg(d.path().join("out.log"))
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&o.stdout).to_string() + &String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{text}");
    let line = text.lines().find(|l| l.starts_with("power-on speed")).unwrap_or_else(|| panic!("{text}"));
    assert!(line.contains("time limit") && !line.contains("first standstill"), "{line}");
}
