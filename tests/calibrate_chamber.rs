//! Issue 13: `gyrocomp calibrate` on chamber runs it was not written against.
//!
//! The generator here is the issue's text, not the calibrate code's model:
//! four 600 s power cycles at 0/20/40/60 deg C ambient; self-heating
//! `rise (1 - exp(-t / tau_heat))` with `tau_heat` uniform in 150..250 s and
//! `rise` in 8..12 deg C; a warm-up transient `A exp(-t / tau_w)` with `tau_w`
//! in 15..40 s and `|A|` in 0.05..0.3 deg/s per axis (random sign); a turn-on
//! bias uniform in +-0.5 deg/s per axis and run; ADIS16448 white rate noise
//! 0.0135 deg/s/sqrt(Hz) (per-sample sigma over the Nyquist band,
//! `0.0135 sqrt(rate / 2)`); a bias random walk of [`WALK`] deg/s/sqrt(s)
//! (1.9393e-5 rad/s^2/sqrt(Hz), the `gyroscope_random_walk` of the EuRoC MAV
//! dataset's ADIS16448; Kalibr's ADIS16448 example gives 4.0e-6, i.e.
//! 0.00023 deg/s/sqrt(s), about the simulator's default 0.0002; the
//! ignored report takes `GYROCOMP_WALK`); temperature-sensor noise 0.02 deg C; accelerometer
//! noise 0.00023 g/sqrt(Hz); timestamps with up to 300 us of arrival jitter.
//! Every sample is quantised through the ADIS16448 frame encoding into a
//! candump log, which the command reads as it reads a real one. The unit's
//! slopes are the paper's Table 1 (0.0020, 0.0044, 0.0192 deg/s/C). 10 Hz
//! keeps the logs small (the noise density, not the rate, sets the
//! information per second).

use gyrocomp::adis::RawSample;
use gyrocomp::calibrate::{calibrate_runs, read_run_from, Calibration, Run, Warmup};
use gyrocomp::candump::LogWriter;
use gyrocomp::config::Config;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use std::path::PathBuf;

/// Bias random walk, deg/s/sqrt(s) (overridable for the ignored reports: `GYROCOMP_WALK`).
const WALK: f64 = 0.0011;
const WHITE: f64 = 0.0135;
const P1: [f64; 3] = [0.0020, 0.0044, 0.0192];
const T0: f64 = 25.0;
const AMBIENTS: [f64; 4] = [0.0, 20.0, 40.0, 60.0];

fn cfg(rate: f64) -> Config {
    Config::parse(&format!("[input]\nrate_hz = {rate:?}\n[thermal]\nt0 = 25.0"), "test").unwrap()
}

fn walk() -> f64 {
    std::env::var("GYROCOMP_WALK").ok().and_then(|v| v.parse().ok()).unwrap_or(WALK)
}

/// Half-width of the uniform turn-on bias, deg/s per axis and run
/// (overridable for the ignored reports: `GYROCOMP_TURN_ON`; 0 is a unit
/// whose bias is its thermal curve at every power-on).
const TURN_ON: f64 = 0.5;

fn turn_on() -> f64 {
    std::env::var("GYROCOMP_TURN_ON").ok().and_then(|v| v.parse().ok()).unwrap_or(TURN_ON)
}

/// One power cycle in the chamber, as the issue describes it.
#[derive(Clone, Debug)]
struct Cycle {
    ambient: f64,
    rise: f64,
    tau_heat: f64,
    warm_amp: [f64; 3],
    warm_tau: f64,
    turn_on: [f64; 3],
    duration: f64,
    walk: f64,
    /// Extra samples after `duration`, the last one off by `last_sample_dz` deg/s on z (the partial-bin tests).
    extra_samples: u64,
    last_sample_dz: f64,
    /// (start s, fraction) of the next second's samples lost, the survivors off by `gap_dz` deg/s on z.
    gap: Option<(f64, f64)>,
    gap_dz: f64,
    seed: u64,
}

fn sym(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    let v = rng.gen_range(lo..hi);
    if rng.gen_bool(0.5) {
        v
    } else {
        -v
    }
}

impl Cycle {
    fn draw(rng: &mut ChaCha8Rng, ambient: f64) -> Cycle {
        Cycle {
            ambient,
            rise: rng.gen_range(8.0..12.0),
            tau_heat: rng.gen_range(150.0..250.0),
            warm_amp: [0; 3].map(|_| sym(rng, 0.05, 0.3)),
            warm_tau: rng.gen_range(15.0..40.0),
            turn_on: [0; 3].map(|_| rng.gen_range(-1.0..1.0) * turn_on()),
            duration: 600.0,
            walk: walk(),
            extra_samples: 0,
            last_sample_dz: 0.0,
            gap: None,
            gap_dz: 0.0,
            seed: rng.gen(),
        }
    }

    fn temp(&self, t: f64) -> f64 {
        self.ambient + self.rise * (1.0 - (-t / self.tau_heat).exp())
    }

    /// The candump log of this cycle, at the rate of `cfg`.
    fn log(&self, cfg: &Config) -> Vec<u8> {
        let prof = cfg.profile();
        let rate = prof.rate_hz;
        let dt = 1.0 / rate;
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        let mut n = || rng.sample::<f64, _>(StandardNormal);
        let white = WHITE * (rate / 2.0).sqrt();
        let accel = 0.00023 * (rate / 2.0).sqrt();
        let mut w = [0.0; 3];
        let mut out = LogWriter::new(Vec::new(), "can0");
        let count = (self.duration * rate).round() as u64 + self.extra_samples;
        let start = 1_750_000_000_000_000u64 + self.seed % 1_000_000;
        for k in 0..count {
            let t = k as f64 * dt;
            let temp = self.temp(t);
            let mut g = [0.0; 3];
            for i in 0..3 {
                if k > 0 {
                    w[i] += self.walk * dt.sqrt() * n();
                }
                let mut e = white * n();
                if self.extra_samples > 0 && k + 1 == count && i == 2 {
                    // the last sample's noise, set
                    e = self.last_sample_dz;
                }
                g[i] = self.turn_on[i] + P1[i] * (temp - T0) + self.warm_amp[i] * (-t / self.warm_tau).exp() + w[i] + e;
            }
            let a = [0.0, 0.0, -1.0].map(|v: f64| v + accel * n());
            if let Some((g0, frac)) = self.gap {
                if t >= g0 && t < g0 + frac {
                    continue;
                }
                if t >= g0 + frac && t < g0 + 1.0 {
                    g[2] += self.gap_dz;
                }
            }
            let mut raw = RawSample::quantise(&prof, g, a, [0.2, 0.0, 0.4], temp + 0.02 * n());
            raw.cnt = (k % 65536) as u16;
            // arrival jitter, never earlier than the sample (the first sample sets the clock)
            let jitter = if k == 0 { 0 } else { (n().abs() * 100.0).min(300.0) as u64 };
            let t_us = start + (t * 1e6).round() as u64 + jitter;
            for (j, (id, f)) in cfg.input.ids.all().iter().zip(raw.encode()).enumerate() {
                out.frame(t_us + 40 * j as u64, *id, &f).unwrap();
            }
        }
        out.finish().unwrap()
    }

    fn run(&self, cfg: &Config, name: &str) -> Run {
        read_run_from(&self.log(cfg)[..], name, cfg).unwrap()
    }
}

/// The issue's four runs for repeat `rep`.
fn four_cycles(rep: u64) -> Vec<Cycle> {
    let mut rng = ChaCha8Rng::seed_from_u64(13_000 + rep);
    AMBIENTS.iter().map(|&a| Cycle::draw(&mut rng, a)).collect()
}

fn calibrate(cycles: &[Cycle], cfg: &Config) -> Calibration {
    let runs: Vec<Run> = cycles.iter().enumerate().map(|(k, c)| c.run(cfg, &format!("run{}_{}C.log", k + 1, c.ambient))).collect();
    calibrate_runs(&runs, 1, T0).unwrap_or_else(|e| panic!("calibration failed: {e}"))
}

/// Per axis: (estimate inside its interval, relative error).
fn score(cal: &Calibration) -> [(bool, f64); 3] {
    [0, 1, 2].map(|i| {
        let a = &cal.axes[i];
        ((a.coeffs[0] - P1[i]).abs() <= a.ci[0], (a.coeffs[0] - P1[i]) / P1[i])
    })
}

#[test]
fn four_600_s_chamber_runs_calibrate_and_cut_only_the_fast_transient() {
    let c = cfg(10.0);
    let cycles = four_cycles(0);
    let cal = calibrate(&cycles, &c);
    eprintln!("{}", cal.render());
    for (k, (r, cy)) in cal.runs.iter().zip(&cycles).enumerate() {
        assert!(r.used, "run {k} left out: {:?}", r.left_out);
        // the self-heating time constant is read from the temperature
        assert!((r.heat_tau_s / cy.tau_heat - 1.0).abs() < 0.1, "run {k}: tau_heat {} vs {}", r.heat_tau_s, cy.tau_heat);
        // the transient is found, faster than the limit, and cut at about 5 tau_w: never the whole run
        assert_eq!(r.warmup, Warmup::Cut, "run {k}");
        assert!(r.cut_s > 3.5 * cy.warm_tau && r.cut_s < 7.0 * cy.warm_tau, "run {k}: cut {} for tau_w {}", r.cut_s, cy.warm_tau);
        assert!(r.used_s > 350.0, "run {k}: used {}", r.used_s);
        assert!(r.is_static);
    }
    // the walk the data carry is the walk the fit estimates
    for a in &cal.axes {
        assert!((a.walk / WALK - 1.0).abs() < 0.35, "walk {} vs {WALK}", a.walk);
    }
    let out = cal.render();
    assert!(out.contains("self-heating:") && out.contains("bias walk") && out.contains("REML"), "{out}");
    // deterministic: the same logs give the same report and the same [thermal] section
    let again = calibrate(&cycles, &c);
    assert_eq!(again.render(), out);
    assert_eq!(again.to_toml(), cal.to_toml());
}

/// Over `n` independent 4-run calibrations, per axis: how many printed 95 %
/// intervals hold the truth, the RMS relative error, how many estimates are within 5 %.
fn coverage(n: u64, verbose: bool) -> ([usize; 3], [f64; 3], [usize; 3]) {
    coverage_of(n, verbose, |_| {})
}

/// [`coverage`] of cycles changed by `tweak` after they are drawn.
fn coverage_of(n: u64, verbose: bool, tweak: impl Fn(&mut Cycle)) -> ([usize; 3], [f64; 3], [usize; 3]) {
    let c = cfg(10.0);
    let mut inside = [0usize; 3];
    let mut sq = [0.0; 3];
    let mut within5 = [0usize; 3];
    for rep in 0..n {
        let mut cycles = four_cycles(rep);
        cycles.iter_mut().for_each(&tweak);
        let cal = calibrate(&cycles, &c);
        let s = score(&cal);
        for i in 0..3 {
            inside[i] += s[i].0 as usize;
            sq[i] += s[i].1 * s[i].1;
            within5[i] += (s[i].1.abs() <= 0.05) as usize;
        }
        if verbose {
            let cell = |i: usize| {
                let a = &cal.axes[i];
                format!("{:.5} +- {:.5} ({:+6.1} %{})", a.coeffs[0], a.ci[0], 100.0 * s[i].1, if s[i].0 { "" } else { ", OUTSIDE" })
            };
            let cuts: Vec<String> = cal.runs.iter().map(|r| format!("{:.0}", r.cut_s)).collect();
            println!("{rep:3}  x {}  y {}  z {}  cuts [{}] s", cell(0), cell(1), cell(2), cuts.join(", "));
        }
    }
    (inside, sq.map(|v| (v / n as f64).sqrt()), within5)
}

/// The issue's target: with the bias random walk, the old ordinary least
/// squares put most fitted slopes outside their intervals; over 100
/// independent 4-run calibrations these 95 % intervals must hold the true
/// slope at least 90 times on every axis.
#[test]
fn intervals_hold_their_coverage_under_a_bias_random_walk() {
    let n = 100;
    let (inside, rms, _) = coverage(n, false);
    eprintln!("inside {inside:?} of {n}, rms relative error {rms:?}");
    for i in 0..3 {
        assert!(inside[i] >= 90, "axis {i}: {} of {n}", inside[i]);
    }
}

/// A unit whose bias at power-on is its thermal curve (no run-to-run
/// turn-on offset; the issue names none): the four runs' levels at
/// 0/20/40/60 deg C then carry the slope as well, and the fit must use them.
/// With each run's own constant (the levels thrown away) the relative RMS
/// error of p1 over these draws is about 115 / 53 / 12 % (x / y / z); with
/// one curve it is about 15 / 8 / 3.5 %, and the intervals still hold.
#[test]
fn without_turn_on_offsets_the_runs_levels_carry_the_slope() {
    let n = 30;
    let (inside, rms, within5) = coverage_of(n, false, |c| c.turn_on = [0.0; 3]);
    eprintln!("inside {inside:?} of {n}, rms relative error {rms:?}, within 5 % {within5:?}");
    for i in 0..3 {
        assert!(inside[i] >= 27, "axis {i}: {} of {n}", inside[i]);
    }
    assert!(rms[0] < 0.35 && rms[1] < 0.18 && rms[2] < 0.06, "rms relative error {rms:?}");
    assert!(within5[2] >= 27, "z within 5 %: {} of {n}", within5[2]);
    // and the report says how the levels were used
    let cycles: Vec<Cycle> = four_cycles(0).into_iter().map(|c| Cycle { turn_on: [0.0; 3], ..c }).collect();
    let out = calibrate(&cycles, &cfg(10.0)).render();
    assert!(out.contains("levels: one curve"), "{out}");
    // with the offsets of the other tests, each run keeps its own constant
    let out = calibrate(&four_cycles(0), &cfg(10.0)).render();
    assert!(out.matches("levels: each run its own").count() == 3, "{out}");
}

/// The same 100 calibrations, every one printed (p1 per axis, interval, error):
/// `cargo test --release --test calibrate_chamber -- --ignored --nocapture coverage_over_100`
/// (`GYROCOMP_WALK=0.0005` for another walk, `GYROCOMP_TURN_ON=0` for a unit without turn-on offsets).
#[test]
#[ignore]
fn coverage_over_100_calibrations() {
    let n = 100;
    println!("bias random walk {} deg/s/sqrt(s); turn-on +-{} deg/s; truth p1 = {P1:?} deg/s/C", walk(), turn_on());
    let (inside, rms, within5) = coverage(n, true);
    println!("intervals holding the truth: x {} y {} z {} of {n}", inside[0], inside[1], inside[2]);
    println!("rms relative error of p1: x {:.1} % y {:.1} % z {:.1} %", 100.0 * rms[0], 100.0 * rms[1], 100.0 * rms[2]);
    println!("p1 within 5 %: x {} y {} z {} of {n}", within5[0], within5[1], within5[2]);
    for i in 0..3 {
        assert!(inside[i] >= 90, "axis {i}: {} of {n}", inside[i]);
    }
}

#[test]
fn the_last_bin_of_1800_s_plus_one_sample_decides_nothing() {
    // the full ADIS16448 rate: one sample of white noise alone is 0.14 deg/s rms
    let c = cfg(204.8);
    let mut rng = ChaCha8Rng::seed_from_u64(77);
    let mut cy = Cycle::draw(&mut rng, 20.0);
    cy.duration = 1800.0;
    cy.extra_samples = 1;
    // the extra sample's noise on z is +0.35 deg/s: 2.5 sigma of one sample, ordinary noise
    cy.last_sample_dz = 0.35;
    let run = cy.run(&c, "run_1800s.log");
    let last = run.bins.last().unwrap();
    assert_eq!(last.n, 1, "the last bin holds the one extra sample");
    assert!((last.gyro[2] - run.bins[run.bins.len() - 2].gyro[2]).abs() > 0.2, "the extra sample stands out: {last:?}");
    let cal = calibrate_runs(std::slice::from_ref(&run), 1, T0).unwrap();
    eprintln!("{}", cal.render());
    let r = &cal.runs[0];
    assert!(r.is_static, "{}", cal.render());
    assert!(!cal.render().contains("NOT STATIC") && !cal.warnings.iter().any(|w| w.contains("not static")), "{:?}", cal.warnings);
    // and it carries no weight in the fit: the last bin is not used
    assert!(!cal.data[0].1.last().unwrap());
    assert!((r.used_s - (1800.0 - r.cut_s)).abs() <= 1.0, "used {} cut {}", r.used_s, r.cut_s);
    // a bin torn by a gap in the middle (5 of its 205 samples) decides nothing either
    let mut gap = cy.clone();
    gap.extra_samples = 0;
    gap.gap = Some((900.0, 0.97));
    gap.gap_dz = 0.35;
    let run = gap.run(&c, "run_gap.log");
    let torn = run.bins.iter().find(|b| b.t > 900.0 && b.t < 901.0).unwrap();
    assert!(torn.n < 10, "{torn:?}");
    let cal = calibrate_runs(std::slice::from_ref(&run), 1, T0).unwrap();
    assert!(cal.runs[0].is_static, "{}", cal.render());
}

#[test]
fn a_run_whose_transient_is_as_slow_as_its_self_heating_is_named_and_the_others_calibrate() {
    let c = cfg(10.0);
    let mut cycles = four_cycles(1);
    // run 2: a "transient" with the self-heating's own time constant
    cycles[1].warm_tau = cycles[1].tau_heat;
    cycles[1].warm_amp = [0.3, -0.3, 0.3];
    let cal = calibrate(&cycles, &c);
    let out = cal.render();
    eprintln!("{out}");
    let r = &cal.runs[1];
    assert!(matches!(r.warmup, Warmup::NotSeparable | Warmup::AtLimit), "{:?}", r.warmup);
    assert!(out.contains("NOT SEPARABLE") || out.contains("limit"), "{out}");
    assert!(cal.warnings.iter().any(|w| w.contains("run2_20C.log")), "{:?}", cal.warnings);
    // the others are calibrated as usual
    for k in [0, 2, 3] {
        assert!(cal.runs[k].used && cal.runs[k].warmup == Warmup::Cut, "run {k}: {:?}", cal.runs[k].warmup);
    }
    for i in 0..3 {
        let a = &cal.axes[i];
        assert!((a.coeffs[0] - P1[i]).abs() <= a.ci[0], "axis {i}: {} +- {} vs {}", a.coeffs[0], a.ci[0], P1[i]);
    }
}

/// A large transient with the self-heating's own time constant, on a unit
/// with a quieter bias (the simulator's default walk, 0.0002 deg/s/sqrt(s)):
/// after the conservative cut the run's own slope still disagrees with the
/// other runs', so it is named not separable, left out, and the other three
/// calibrate.
#[test]
fn a_large_slow_transient_is_not_separable_and_the_run_is_left_out() {
    let c = cfg(10.0);
    let mut cycles = four_cycles(3);
    for cy in cycles.iter_mut() {
        cy.walk = 0.0002;
    }
    cycles[2].warm_tau = cycles[2].tau_heat;
    cycles[2].warm_amp = [0.6, -0.6, 0.6];
    let cal = calibrate(&cycles, &c);
    let out = cal.render();
    eprintln!("{out}");
    let r = &cal.runs[2];
    assert_eq!(r.warmup, Warmup::NotSeparable);
    assert!(!r.used && r.slope_z > 3.0, "{r:?}");
    assert!(out.contains("NOT SEPARABLE") && out.contains("LEFT OUT"), "{out}");
    assert!(cal.warnings.iter().any(|w| w.contains("run3_40C.log") && w.contains("calibrated from the other runs")), "{:?}", cal.warnings);
    assert!(out.contains("3 of 4 runs"), "{out}");
    for k in [0, 1, 3] {
        assert!(cal.runs[k].used, "run {k}");
    }
    for i in 0..3 {
        let a = &cal.axes[i];
        assert!((a.coeffs[0] - P1[i]).abs() <= a.ci[0], "axis {i}: {} +- {} vs {}", a.coeffs[0], a.ci[0], P1[i]);
    }
    // the plots still show the run left out (grey), with finite coordinates
    let dir = tempfile::tempdir().unwrap();
    let files = cal.plot(dir.path()).unwrap();
    assert_eq!(files.len(), 7);
    for f in &files {
        let svg = std::fs::read_to_string(f).unwrap();
        assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>") && !svg.contains("NaN"), "{}", f.display());
    }
    let run3 = std::fs::read_to_string(dir.path().join("warmup_run3.svg")).unwrap();
    assert!(run3.contains("<polyline"), "run 3's residual is drawn");
}

/// A single run whose transient is slower than its limit (tau_heat / 3):
/// the fit wants the slowest transient allowed, the run is cut
/// conservatively, and it says so; there is no other run to check it against,
/// and the command still gives a result. (A transient with exactly the
/// self-heating's time constant is the self-heating curve itself: in a run
/// alone no method can see it, only other runs can; see the test above.)
#[test]
fn one_run_with_a_slow_transient_still_gives_a_result_and_says_so() {
    let c = cfg(10.0);
    let mut cy = four_cycles(2).remove(1);
    cy.warm_tau = 0.6 * cy.tau_heat;
    cy.warm_amp = [0.3, 0.3, -0.3];
    // a quiet bias: with the walk, one run alone cannot even see this transient (3 SE)
    cy.walk = 0.0;
    let run = cy.run(&c, "alone.log");
    let cal = calibrate_runs(&[run], 1, T0).unwrap();
    eprintln!("{}", cal.render());
    let r = &cal.runs[0];
    assert!(r.used);
    assert_eq!(r.warmup, Warmup::AtLimit);
    assert!((r.cut_s - 5.0 * r.tau_limit_s).abs() < 1e-9);
    assert!(cal.warnings.iter().any(|w| w.contains("alone.log") && w.contains("cannot be checked")), "{:?}", cal.warnings);
    assert!(cal.axes.iter().all(|a| a.coeffs[0].is_finite() && a.ci[0].is_finite()));
}

/// Not a check: writes the issue's four runs (repeat `GYROCOMP_REPEAT`, default 0) and
/// their truth into $GYROCOMP_DEMO_DIR, for trying the command:
/// `GYROCOMP_DEMO_DIR=/tmp/issue13 cargo test --release --test calibrate_chamber -- --ignored write_issue13_logs`
#[test]
#[ignore]
fn write_issue13_logs() {
    let dir = PathBuf::from(std::env::var("GYROCOMP_DEMO_DIR").expect("set GYROCOMP_DEMO_DIR"));
    let rep: u64 = std::env::var("GYROCOMP_REPEAT").ok().and_then(|v| v.parse().ok()).unwrap_or(0);
    std::fs::create_dir_all(&dir).unwrap();
    let c = cfg(10.0);
    let mut truth = format!("# repeat {rep}; p1 = {P1:?} deg/s/C, t0 = {T0}\n");
    for (k, cy) in four_cycles(rep).iter().enumerate() {
        let p = dir.join(format!("run{}_{}C.log", k + 1, cy.ambient));
        std::fs::write(&p, cy.log(&c)).unwrap();
        truth += &format!("# {}: {cy:?}\n", p.display());
        eprintln!("wrote {}", p.display());
    }
    std::fs::write(dir.join("truth.txt"), truth).unwrap();
    std::fs::write(dir.join("demo.toml"), "[input]\nrate_hz = 10.0\n[thermal]\nt0 = 25.0\n").unwrap();
}
