use super::quat;
use super::*;
use crate::adis::Sample;
use std::f64::consts::PI;

/// A unit at rest, level, heading `yaw_deg`, with a constant gyro bias.
fn rest(cnt: u16, bias: [f64; 3], yaw_deg: f64, temp: f64) -> Sample {
    let psi = yaw_deg * D2R;
    Sample {
        cnt,
        t_us: 0,
        steps: if cnt == 0 { 0 } else { 1 },
        gyro: bias,
        accel: [0.0, 0.0, -1.0],
        magn: [0.2 * psi.cos(), -0.2 * psi.sin(), 0.4],
        temp,
        diag: 0,
    }
}

/// These tests pin the paper's behaviour: paper mode unless the text names a mode.
fn cfg(text: &str) -> Config {
    let mut c = Config::parse(text, "test").unwrap();
    if !text.contains("mode =") {
        c.estimator.mode = Mode::Paper;
    }
    c
}

#[test]
fn learns_a_constant_bias_at_rest() {
    for (mode, secs) in [("paper", 40.0), ("mekf", 40.0)] {
        let c = cfg(&format!("[estimator]\nmode = \"{mode}\"\nwarmup_s = 2.0\nlearn_s = 20.0"));
        let mut e = Estimator::new(&c);
        let bias = [0.3, -0.2, 0.45];
        let mut last = Estimate::default();
        for k in 0..(204.8 * secs) as u32 {
            last = e.step(&rest(k as u16, bias, 30.0, 25.0));
        }
        for i in 0..3 {
            assert!((last.bias[i] - bias[i]).abs() < 0.01, "axis {i}: {:?}", last.bias);
            assert!(last.rate[i].abs() < 0.01);
        }
        assert!(last.roll.abs() < 0.05 && last.pitch.abs() < 0.05);
        assert!((last.yaw - 30.0).abs() < 0.2, "yaw {}", last.yaw);
        assert_eq!(last.mode, 0);
        assert_eq!(last.flags & (flags::WARMUP | flags::LEARNING), 0);
    }
}

#[test]
fn warmup_samples_do_not_teach_the_bias() {
    let c = cfg("[estimator]\nwarmup_s = 5.0\nlearn_s = 5.0");
    let mut e = Estimator::new(&c);
    let mut est = Estimate::default();
    for k in 0..(204.8 * 4.5) as u32 {
        est = e.step(&rest(k as u16, [0.5, 0.5, 0.5], 0.0, 25.0));
        assert!(est.flags & flags::WARMUP != 0);
    }
    assert_eq!(est.bias, [0.0; 3]);
}

#[test]
fn thermal_curve_is_anchored_at_the_last_ekf_bias() {
    // Learn at 25 C, then go out of band (|a| = 1.5 g) and warm by 10 C:
    // the bias must be the learned one plus p1 * 10, not p1 (T - t0) + p2.
    let c = cfg("[estimator]\nmode = \"paper\"\nwarmup_s = 1.0\nlearn_s = 10.0\n[thermal]\nt0 = 0.0\np1 = [0.002, 0.0044, 0.0192]\np2 = [1.0, 1.0, 1.0]");
    let mut e = Estimator::new(&c);
    let b0 = [0.1, -0.1, 0.2];
    let n = (204.8 * 90.0) as u32;
    let mut cnt = 0u16;
    for _ in 0..n {
        e.step(&rest(cnt, b0, 0.0, 25.0));
        cnt = cnt.wrapping_add(1);
    }
    let held = e.learned().unwrap();
    for i in 0..3 {
        assert!((held.bias[i] - b0[i]).abs() < 0.01, "{:?}", held);
    }
    let mut est = Estimate::default();
    for k in 0..1000 {
        let mut s = rest(cnt, b0, 0.0, 25.0 + 10.0 * k as f64 / 999.0);
        s.accel = [0.0, 0.0, -1.5];
        est = e.step(&s);
        cnt = cnt.wrapping_add(1);
        assert_eq!(est.mode, 2);
    }
    let p1 = [0.002, 0.0044, 0.0192];
    for i in 0..3 {
        let want = held.bias[i] + p1[i] * (35.0 - held.temp);
        assert!((est.bias[i] - want).abs() < 1e-9, "axis {i}: {} vs {want}", est.bias[i]);
    }
}

#[test]
fn startup_average_ignores_thermal_and_fusion() {
    let c = cfg("[estimator]\nmode = \"startup_average\"\nwarmup_s = 1.0\nlearn_s = 5.0\n[thermal]\np1 = [0.1, 0.1, 0.1]");
    let mut e = Estimator::new(&c);
    let mut est = Estimate::default();
    for k in 0..(204.8 * 10.0) as u32 {
        est = e.step(&rest(k as u16, [0.2, 0.0, -0.3], 0.0, 25.0 + k as f64 * 0.001));
        assert_eq!(est.mode, 2);
    }
    assert!((est.bias[0] - 0.2).abs() < 1e-9 && (est.bias[2] + 0.3).abs() < 1e-9);
}

#[test]
fn suspect_and_out_of_band_samples_are_not_fused() {
    let c = cfg("[estimator]\nmode = \"paper\"\ng0_window_s = 0.001");
    let mut e = Estimator::new(&c);
    e.step(&rest(0, [0.0; 3], 0.0, 25.0));
    let mut s = rest(1, [0.0; 3], 0.0, 25.0);
    s.diag = 4;
    let est = e.step(&s);
    assert_eq!(est.mode, 2);
    assert!(est.flags & flags::SUSPECT != 0);
    let mut s = rest(2, [0.0; 3], 0.0, 25.0);
    s.accel = [0.0, 0.0, -1.1];
    assert_eq!(e.step(&s).mode, 1);
    s.accel = [0.0, 0.0, -1.25];
    s.cnt = 3;
    assert_eq!(e.step(&s).mode, 2);
}

#[test]
fn thermal_curve_clamps_outside_the_calibrated_range_and_flags_it() {
    let c = cfg("[estimator]\nwarmup_s = 1.0\nlearn_s = 5.0\n[thermal]\nt0 = 25.0\norder = 2\np1 = [0.01, 0.01, 0.01]\np3 = [0.001, 0.0, 0.0]\nt_min = 10.0\nt_max = 40.0");
    let mut e = Estimator::new(&c);
    let mut cnt = 0u16;
    for _ in 0..(204.8 * 10.0) as u32 {
        let est = e.step(&rest(cnt, [0.0; 3], 0.0, 30.0));
        assert_eq!(est.flags & flags::THERMAL_CLAMP, 0);
        cnt = cnt.wrapping_add(1);
    }
    let held = e.learned().unwrap().bias;
    // out of band, warming from 30 to 50 C: the curve moves the bias up to 40 C only
    let mut est = Estimate::default();
    for k in 0..1000 {
        let temp = 30.0 + 20.0 * k as f64 / 999.0;
        let mut s = rest(cnt, [0.0; 3], 0.0, temp);
        s.accel = [0.0, 0.0, -1.5];
        est = e.step(&s);
        cnt = cnt.wrapping_add(1);
        assert_eq!(est.flags & flags::THERMAL_CLAMP != 0, temp > 40.0, "at {temp}");
    }
    let f = |t: f64| 0.01 * (t - 25.0) + 0.001 * (t - 25.0) * (t - 25.0);
    assert!((est.bias[0] - (held[0] + f(40.0) - f(30.0))).abs() < 1e-9, "{:?}", est.bias);
    assert!((est.bias[1] - (held[1] + 0.1)).abs() < 1e-9);
    // startup_average does not use the curve, so it never clamps
    let c = cfg("[estimator]\nmode = \"startup_average\"\n[thermal]\nt_max = 20.0");
    let mut e = Estimator::new(&c);
    assert_eq!(e.step(&rest(0, [0.0; 3], 0.0, 30.0)).flags & flags::THERMAL_CLAMP, 0);
}

#[test]
fn long_gap_is_a_resync_not_an_integration() {
    let c = cfg("");
    let mut e = Estimator::new(&c);
    for k in 0..100u16 {
        e.step(&rest(k, [0.0; 3], 0.0, 25.0));
    }
    let mut s = rest(1100, [0.0; 3], 0.0, 25.0);
    s.gyro = [50.0, 0.0, 0.0];
    s.steps = 1000;
    let est = e.step(&s);
    assert!(est.flags & flags::RESYNC != 0);
    // integrated over one period, not 4.9 s
    assert!(est.roll.abs() < 1.0, "roll {}", est.roll);
}

// the default filter (mekf)
mod aid;
mod mekf;

/// A filter driven beyond its numbers (every `[ekf]` sigma 1e-300, which no
/// config inside its ranges can ask for; a sample of 1e300 deg/s or NaN) never
/// publishes a non-finite value: it restarts from the prior, flagged
/// `RESYNC` and counted (replay published NaN attitude on 8192 of 8193 rows).
#[test]
fn a_non_finite_state_restarts_from_the_prior_and_is_never_published() {
    let mut paper = cfg("");
    paper.ekf.gyro_noise = 1e-300;
    paper.ekf.bias_walk = 1e-300;
    paper.ekf.tilt_sigma_deg = 1e-300;
    paper.ekf.yaw_sigma_deg = 1e-300;
    paper.ekf.init_angle_sigma_deg = 1e-300;
    paper.ekf.init_bias_sigma = Some(1e-300);
    let mekf = cfg("[estimator]\nmode = \"mekf\"");
    // a NaN no decoder makes, to reach the guard from the input side too
    for (name, c, bad) in [("paper, sigmas 1e-300, a NaN sample", paper, f64::NAN), ("mekf, a 1e300 deg/s sample", mekf, 1e300)] {
        let mut e = Estimator::new(&c);
        let mut restarted = 0;
        for k in 0..(204.8 * 30.0) as u32 {
            let mut s = rest(k as u16, [0.3, -0.2, 0.1], 0.0, 25.0);
            if k % 1000 == 999 {
                s.gyro = [bad, -bad, bad];
            }
            let est = e.step(&s);
            assert!(est.is_finite(), "{name}: sample {k} published {est:?}");
            if e.nonfinite_restarts() > restarted {
                assert!(est.flags & flags::RESYNC != 0, "{name}: a restart not flagged at sample {k}");
                restarted = e.nonfinite_restarts();
            }
        }
        assert!(restarted > 0, "{name}: the state never went non-finite: the test tests nothing");
    }
}
