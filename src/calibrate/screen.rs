//! Steps 2 and 3: short bins decide nothing; the static check.

use super::read::Bin;
use super::{
    RunReport, BIN_S, MEDIAN_HALF, MIN_BIN_FRACTION, MOVING_MARGIN, ROT_ABS_DPS, ROT_MIN_DPS, ROT_SD_RATIO, ROT_SIGMAS, TILT_LIMIT_DEG,
};

pub(crate) fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Which bins hold enough samples to count: at least [`MIN_BIN_FRACTION`] of
/// the run's median samples per bin. A bin with fewer (the partial bin at
/// either end of a log, a bin torn by a gap) is as noisy as its few samples
/// and decides nothing.
pub(crate) fn full_bins(bins: &[Bin]) -> Vec<bool> {
    let mut n: Vec<f64> = bins.iter().map(|b| b.n as f64).collect();
    let med = median(&mut n);
    bins.iter().map(|b| b.n as f64 >= MIN_BIN_FRACTION * med).collect()
}

fn has_accel(b: &Bin) -> bool {
    b.accel.iter().all(|v| v.is_finite())
}

/// Static check of one run over its full bins: the keep mask (false for
/// moving bins, their margin, and bins that are not full); fills the
/// report's static fields.
pub(crate) fn static_check(bins: &[Bin], full: &[bool], rep: &mut RunReport) -> Vec<bool> {
    // only full bins take part: indices into `bins`
    let idx: Vec<usize> = (0..bins.len()).filter(|&j| full[j]).collect();
    let fb: Vec<&Bin> = idx.iter().map(|&j| &bins[j]).collect();
    let n = fb.len();
    let mut moving = vec![false; n];
    let mut win = Vec::with_capacity(2 * MEDIAN_HALF + 1);
    // the stretch of each full bin (first, one past the last): the window
    // stays within it, never across a time jump
    let owned: Vec<Bin> = fb.iter().map(|b| **b).collect();
    let mut stretch = vec![(0, 0); n];
    for (a, b) in super::read::stretches(&owned) {
        stretch[a..b].iter_mut().for_each(|s| *s = (a, b));
    }
    for i in 0..3 {
        let mut dev = vec![0.0; n];
        for j in 0..n {
            // a symmetric window (narrower near the ends): the median of a
            // symmetric window of a monotone signal is its centre, so a
            // smooth warm-up transient or heating trend is never "motion"
            win.clear();
            let (s0, s1) = stretch[j];
            let h = MEDIAN_HALF.min(j - s0).min(s1 - 1 - j);
            let (lo, hi) = (j - h, j + h + 1);
            win.extend(fb[lo..hi].iter().map(|b| b.gyro[i]));
            dev[j] = fb[j].gyro[i] - median(&mut win);
        }
        let mut a: Vec<f64> = dev.iter().map(|d| d.abs()).collect();
        let sigma = 1.4826 * median(&mut a);
        let thr = (ROT_SIGMAS * sigma).max(ROT_MIN_DPS);
        let mut sds: Vec<f64> = fb.iter().map(|b| b.gyro_sd[i]).collect();
        let sd_med = median(&mut sds);
        let mut all: Vec<f64> = fb.iter().map(|b| b.gyro[i]).collect();
        let run_med = median(&mut all);
        for j in 0..n {
            let d = dev[j].abs();
            let sd_ratio = if sd_med > 0.0 { fb[j].gyro_sd[i] / sd_med } else { 0.0 };
            let sd_bad = sd_ratio > ROT_SD_RATIO || (fb[j].gyro[i] - run_med).abs() > ROT_ABS_DPS;
            if sd_ratio > ROT_SD_RATIO {
                rep.max_sd_ratio = rep.max_sd_ratio.max(sd_ratio);
            }
            if d > thr || sd_bad {
                moving[j] = true;
                if d > rep.max_rot_dps {
                    rep.max_rot_dps = d;
                    rep.max_rot_at_s = fb[j].t;
                }
            }
        }
    }
    tilt_check(&fb, &mut moving, rep);
    // the margin is counted in seconds of time, not in full bins
    let mut keep: Vec<bool> = full.to_vec();
    for (j, &m) in moving.iter().enumerate() {
        if m {
            // bins are in time order
            let m = MOVING_MARGIN as f64 * BIN_S + 1e-9;
            let lo = bins.partition_point(|b| b.t < fb[j].t - m);
            let hi = bins.partition_point(|b| b.t <= fb[j].t + m);
            keep[lo..hi].iter_mut().for_each(|k| *k = false);
        }
    }
    rep.moving_s = (0..bins.len()).filter(|&k| full[k] && !keep[k]).count() as f64 * BIN_S;
    rep.short_bins = full.iter().filter(|f| !**f).count();
    rep.is_static = rep.moving_s == 0.0;
    keep
}

/// Tilt: the angle of each full bin's specific force to the run's median
/// direction; beyond [`TILT_LIMIT_DEG`] the bin is moving.
fn tilt_check(fb: &[&Bin], moving: &mut [bool], rep: &mut RunReport) {
    let unit = |a: [f64; 3]| {
        let m = crate::estimator::quat::norm(&a);
        if m > 0.0 {
            a.map(|v| v / m)
        } else {
            [0.0; 3]
        }
    };
    let mut refd = [0.0; 3];
    for (i, r) in refd.iter_mut().enumerate() {
        let mut v: Vec<f64> = fb.iter().filter(|b| has_accel(b)).map(|b| unit(b.accel)[i]).collect();
        *r = median(&mut v);
    }
    let refd = unit(refd);
    // a recording without an accelerometer has no tilt test
    for (j, b) in fb.iter().enumerate().filter(|(_, b)| has_accel(b)) {
        let u = unit(b.accel);
        let c = (u[0] * refd[0] + u[1] * refd[1] + u[2] * refd[2]).clamp(-1.0, 1.0);
        let ang = c.acos().to_degrees();
        rep.max_tilt_deg = rep.max_tilt_deg.max(ang);
        if ang > TILT_LIMIT_DEG {
            moving[j] = true;
            if rep.max_rot_dps == 0.0 && rep.max_rot_at_s == 0.0 {
                rep.max_rot_at_s = b.t;
            }
        }
    }
}
