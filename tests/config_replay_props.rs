//! Property test (issue 38): any config `check-config` accepts, driven
//! through replay, publishes finite estimates only. Random configs are built
//! from the documented ranges of the numeric keys (log-uniform where the
//! range spans decades, the bounds themselves included), in every estimator
//! mode; a config the validator refuses for a rule between keys is
//! rejected (`prop_assume`: too many rejects fail the test).

use gyrocomp::config::Config;
use gyrocomp::estimator::Estimate;
use gyrocomp::output::Frames;
use gyrocomp::pipeline::{Pipeline, Sink};
use proptest::prelude::*;

const ROAD: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/road-40s.log");

/// (key, table, low, high) as the validator's ranges (src/config/validate).
const KEYS: &[(&str, &str, f64, f64)] = &[
    ("estimator", "g0_window_s", 0.001, 60.0),
    ("estimator", "warmup_s", 0.0, 3600.0),
    ("estimator", "learn_s", 0.0, 3600.0),
    ("estimator", "max_gap_s", 0.001, 60.0),
    ("ekf", "gyro_noise", 1e-6, 10.0),
    ("ekf", "bias_walk", 0.0, 1.0),
    ("ekf", "tilt_sigma_deg", 1e-4, 90.0),
    ("ekf", "yaw_sigma_deg", 1e-4, 180.0),
    ("ekf", "init_bias_sigma", 1e-4, 100.0),
    ("ekf", "init_angle_sigma_deg", 1e-3, 180.0),
    ("switching", "jerk_ratio", 1e-3, 100.0),
    ("switching", "jerk_window_s", 0.01, 10.0),
    ("mekf", "update_hz", 1.0, 10_000.0),
    ("mekf", "gyro_scale_error", 0.0, 0.5),
    ("mekf", "rest_tilt_sigma_deg", 1e-4, 10.0),
    ("mekf", "accel_noise", 1e-5, 100.0),
    ("mekf", "nhc_sigma", 1e-4, 10.0),
    ("mekf", "zupt_sigma", 1e-5, 10.0),
    ("mekf", "zru_sigma_dps", 1e-6, 10.0),
    ("mekf", "scale_walk", 0.0, 0.1),
    ("mekf", "gate_sigma", 0.5, 100.0),
    ("mekf", "tilt_sigma_deg", 1e-4, 90.0),
    ("mekf", "motion_bias_walk", 0.0, 1.0),
    ("mekf", "accel_bias_g", 0.0, 0.5),
    ("rest", "tau_s", 0.01, 60.0),
    ("rest", "gyro_dev_dps", 1e-4, 100.0),
    ("rest", "accel_dev_g", 1e-5, 1.0),
    ("rest", "band", 1e-5, 0.5),
    ("input", "gyro_lsb", 1e-5, 1.0),
    ("input", "accel_lsb", 1e-6, 0.1),
    ("input", "rate_hz", 1.0, 100_000.0),
];

const MODES: [&str; 4] = ["startup_average", "startup_thermal", "paper", "mekf"];

/// A value of [lo, hi]: a bound, or log-uniform (uniform when lo is 0) inside.
fn value(lo: f64, hi: f64, pick: u8, u: f64) -> f64 {
    match pick % 8 {
        0 => lo,
        1 => hi,
        _ if lo > 0.0 => (lo.ln() + u * (hi.ln() - lo.ln())).exp().clamp(lo, hi),
        _ => lo + u * (hi - lo),
    }
}

fn config_text(mode: usize, keys: &[(usize, u8, f64)], p1: [f64; 3], p2: [f64; 3]) -> String {
    let mut tables: std::collections::BTreeMap<&str, Vec<String>> = Default::default();
    tables.entry("estimator").or_default().push(format!("mode = \"{}\"", MODES[mode]));
    tables.entry("thermal").or_default().push(format!("p1 = {p1:?}\np2 = {p2:?}"));
    let mut seen = std::collections::BTreeSet::new();
    for &(k, pick, u) in keys {
        let (t, key, lo, hi) = KEYS[k % KEYS.len()];
        if seen.insert((t, key)) {
            tables.entry(t).or_default().push(format!("{key} = {:?}", value(lo, hi, pick, u)));
        }
    }
    tables.iter().map(|(t, v)| format!("[{t}]\n{}\n", v.join("\n"))).collect()
}

struct Check(usize, Option<String>);
impl Sink for Check {
    fn output(&mut self, e: &Estimate, _: &Frames) {
        self.0 += 1;
        let v = [e.roll, e.pitch, e.yaw, e.rate[0], e.rate[1], e.rate[2], e.bias[0], e.bias[1], e.bias[2], e.t];
        if self.1.is_none() && !v.iter().all(|x| x.is_finite()) {
            self.1 = Some(format!("sample {}: {e:?}", self.0));
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, .. ProptestConfig::default() })]

    #[test]
    fn every_accepted_config_replays_to_finite_estimates(
        mode in 0usize..4,
        keys in prop::collection::vec((0usize..64, any::<u8>(), 0.0f64..1.0), 0..12),
        p1 in prop::array::uniform3(-1.0f64..1.0),
        p2 in prop::array::uniform3(-100.0f64..100.0),
    ) {
        let text = config_text(mode, &keys, p1, p2);
        let cfg = Config::parse(&text, "random");
        prop_assume!(cfg.is_ok());
        let cfg = cfg.unwrap();
        // the first 12 s of the road log (the rest does not add a case)
        let road = std::fs::read_to_string(ROAD).unwrap();
        let head: String = road.lines().take(10_000).map(|l| format!("{l}\n")).collect();
        let speed = gyrocomp::speed::load(&cfg).unwrap();
        let mut pipe = Pipeline::with_speed(&cfg, speed);
        let mut sink = Check(0, None);
        gyrocomp::replay::run(&mut pipe, head.as_bytes(), &mut sink).unwrap();
        prop_assert!(sink.0 > 0, "no estimate\n{}", text);
        prop_assert!(sink.1.is_none(), "{}\nconfig:\n{}", sink.1.unwrap_or_default(), text);
    }
}

#[test]
fn the_bounds_of_every_range_are_accepted_and_replay_finite() {
    // each key at its low and its high bound, alone, in every mode; a bound
    // a rule between keys refuses (max_gap_s under one sample period) is
    // skipped, but those are few
    let (mut ran, mut skipped) = (0, 0);
    for mode in 0..MODES.len() {
        for k in 0..KEYS.len() {
            for pick in [0u8, 1] {
                let text = config_text(mode, &[(k, pick, 0.0)], [0.0; 3], [0.0; 3]);
                let Ok(cfg) = Config::parse(&text, "bound") else {
                    skipped += 1;
                    continue;
                };
                ran += 1;
                let road = std::fs::read_to_string(ROAD).unwrap();
                let head: String = road.lines().take(4_000).map(|l| format!("{l}\n")).collect();
                let mut pipe = Pipeline::with_speed(&cfg, None);
                let mut sink = Check(0, None);
                gyrocomp::replay::run(&mut pipe, head.as_bytes(), &mut sink).unwrap();
                assert!(sink.1.is_none(), "{}\nconfig:\n{text}", sink.1.unwrap());
            }
        }
    }
    assert!(skipped * 10 <= ran, "{ran} bounds replayed, {skipped} refused");
}
