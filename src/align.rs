//! `gyrocomp align`: propose the `[mounting] rotation` of a sensor from a
//! recording of the vehicle it sits in.
//!
//! - Roll and pitch of the mounting: the specific force at the vehicle's
//!   standstills is gravity alone, seen in the sensor frame. Every standstill
//!   (the estimator's own detector, `[rest]`) gives a direction; their mean
//!   is taken, because a single stop may be on a slope (each stop's tilt is
//!   printed: their spread is the road's). The detector's gravity is the
//!   estimator's (`GravityRef`): g0 only if the recording starts still
//!   (one that starts while driving holds the car's acceleration in g0),
//!   then |f| at the stops.
//! - Yaw of the mounting: a vehicle accelerates and brakes along its own x
//!   axis. In the levelled sensor frame, the horizontal specific force while
//!   driving straight (|yaw rate| < 2 deg/s) and accelerating or braking
//!   (> 0.05 g) lies along one line; its principal direction is the
//!   vehicle's x axis. Forward is the way the vehicle pulls away after its
//!   standstills.
//!
//! The result is printed as a `[mounting]` section, with the evidence.

use crate::adis::{Assembler, Sample};
use crate::config::Config;
use crate::estimator::quat::{self, norm};
use crate::estimator::rest::{GravityRef, RestDetector, RestParams};
use crate::estimator::G0Mean;
use std::path::PathBuf;

const D2R: f64 = std::f64::consts::PI / 180.0;

/// The `align` subcommand.
#[derive(clap::Args, Debug)]
pub struct AlignArgs {
    /// The recording: a candump -l log of the sensor in its vehicle, with
    /// standstills and some straight acceleration or braking. Required.
    #[arg(long, value_name = "LOG")]
    pub input: PathBuf,
    /// gyrocomp config (TOML) for the input's profile, IDs and `[rest]`
    /// thresholds; its `[mounting]` is ignored. Default: built-in defaults.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
}

/// What `align` found.
#[derive(Clone, Debug, PartialEq)]
pub struct Alignment {
    /// Mounting roll, pitch, yaw (deg), Z-Y-X, the sensor frame in the vehicle frame.
    pub rotation: [f64; 3],
    /// Each standstill: start (s), length (s), and the tilt it shows (roll, pitch deg).
    pub rests: Vec<(f64, f64, [f64; 2])>,
    /// Straight acceleration samples used for the yaw, and how far they
    /// spread about their line (deg, 1-sigma); None when too few.
    pub yaw_evidence: Option<(usize, f64)>,
    /// Pull-aways that told forward from backward.
    pub pull_aways: usize,
}

impl Alignment {
    pub fn render(&self) -> String {
        let mut s = String::new();
        for (t, len, [r, p]) in &self.rests {
            s += &format!("standstill at {t:.1} s for {len:.1} s: gravity says roll {r:.2} pitch {p:.2} deg\n");
        }
        match self.yaw_evidence {
            Some((n, spread)) => s += &format!(
                "yaw: {n} samples of straight acceleration or braking (spread {spread:.1} deg about their line), forward from {} pull-aways\n",
                self.pull_aways
            ),
            None => s += "yaw: not enough straight acceleration or braking (> 0.05 g, |yaw rate| < 2 deg/s): yaw left at 0\n",
        }
        s += &format!(
            "\n[mounting]\nrotation = [{:.2}, {:.2}, {:.2}]   # deg: roll, pitch, yaw of the sensor in the vehicle\n",
            self.rotation[0], self.rotation[1], self.rotation[2]
        );
        s
    }
}

/// Find the mounting from decoded samples (sensor frame).
pub fn align(samples: &[Sample], cfg: &Config) -> Result<Alignment, String> {
    let p = cfg.profile();
    let mut det = RestDetector::new(RestParams::from_config(&cfg.rest));
    let dt = 1.0 / p.rate_hz;
    // gravity's reference for the detector as the estimator keeps it: g0
    // over `g0_window_s` only if the unit was steady then (a recording that
    // starts while driving holds the car's acceleration in g0, and every
    // stop would fail the band), then |f| at the rests
    let window = cfg.estimator.g0_window_s;
    let mut g_ref = GravityRef::default();
    let mut g0 = G0Mean::default();
    // 1. standstills and their mean specific force
    let mut rests: Vec<(usize, usize, [f64; 3])> = Vec::new();
    let mut cur: Option<(usize, [f64; 3], usize)> = None;
    // the gyro at the standstills is its bias (deg/s)
    let mut bias_sum = [0.0; 3];
    let mut bias_n = 0usize;
    for (k, s) in samples.iter().enumerate() {
        let t = k as f64 * dt;
        g0.push(t, window, &s.accel);
        let g = s.gyro.map(|v| v * D2R);
        let st = det.push(&g, &s.accel, dt, g_ref.get(), &[0.0; 3], [f64::INFINITY; 3]);
        g_ref.observe(Some(&st), t, g0.value(), window, dt);
        if st.rest {
            for i in 0..3 {
                bias_sum[i] += s.gyro[i];
            }
            bias_n += 1;
        }
        match (st.rest, &mut cur) {
            (true, Some((_, sum, n))) => {
                for i in 0..3 {
                    sum[i] += s.accel[i];
                }
                *n += 1;
            }
            (true, None) => cur = Some((k, s.accel, 1)),
            (false, Some((start, sum, n))) => {
                rests.push((*start, *n, sum.map(|v| v / *n as f64)));
                cur = None;
            }
            (false, None) => {}
        }
    }
    if let Some((start, sum, n)) = cur {
        rests.push((start, n, sum.map(|v| v / n as f64)));
    }
    let bias = bias_sum.map(|v| v / bias_n.max(1) as f64);
    if rests.is_empty() {
        return Err("no standstill found (gyro and accelerometer quiet for [rest] min_s): roll and pitch need one".into());
    }
    let mut gm = [0.0; 3];
    for (_, n, f) in &rests {
        let u = norm(f);
        for i in 0..3 {
            gm[i] += f[i] / u * *n as f64;
        }
    }
    let (roll, pitch) = crate::estimator::ekf::tilt_from_accel(&gm);
    let level = quat::matrix_from_euler(roll, pitch, 0.0);
    // 2. straight acceleration in the levelled frame: its principal line
    let (mut sxx, mut sxy, mut syy, mut n) = (0.0, 0.0, 0.0, 0usize);
    let mut lp = [0.0; 3];
    let mut wz_lp = 0.0;
    let a = (dt / 0.5).min(1.0);
    let mut horiz = Vec::with_capacity(samples.len());
    for s in samples {
        let f = quat::rotate(&level, &s.accel);
        let w = quat::rotate(&level, &[s.gyro[0] - bias[0], s.gyro[1] - bias[1], s.gyro[2] - bias[2]]);
        for i in 0..3 {
            lp[i] += (f[i] - lp[i]) * a;
        }
        wz_lp += (w[2] - wz_lp) * a;
        horiz.push([lp[0], lp[1]]);
        let h2 = lp[0] * lp[0] + lp[1] * lp[1];
        if wz_lp.abs() < 2.0 && h2 > 0.05 * 0.05 {
            sxx += lp[0] * lp[0];
            sxy += lp[0] * lp[1];
            syy += lp[1] * lp[1];
            n += 1;
        }
    }
    let mut yaw = 0.0;
    let mut evidence = None;
    let mut pull_aways = 0;
    if n >= (p.rate_hz as usize) {
        // principal axis of the 2x2 scatter
        let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
        let (c, s) = (angle.cos(), angle.sin());
        let along = sxx * c * c + 2.0 * sxy * c * s + syy * s * s;
        let across = (sxx * s * s - 2.0 * sxy * c * s + syy * c * c).max(0.0);
        let spread = (across / along.max(1e-12)).sqrt().atan() / D2R;
        // forward: the mean specific force over the 3 s after each standstill
        let mut fwd = 0.0;
        for (start, len, _) in &rests {
            let end = start + len;
            let to = (end + (3.0 * p.rate_hz) as usize).min(horiz.len());
            if end >= to {
                continue;
            }
            let m: f64 = horiz[end..to].iter().map(|h| h[0] * c + h[1] * s).sum::<f64>() / (to - end) as f64;
            if m.abs() > 0.02 {
                fwd += m.signum();
                pull_aways += 1;
            }
        }
        let forward = if fwd < 0.0 { angle + std::f64::consts::PI } else { angle };
        // the vehicle's x axis appears at `forward` in the levelled sensor
        // frame: the sensor is turned by -forward in the vehicle
        yaw = crate::estimator::ekf::wrap_pi(-forward);
        evidence = Some((n, spread));
    }
    let rotation = [roll / D2R, pitch / D2R, yaw / D2R];
    let rests = rests
        .iter()
        .map(|(start, len, f)| {
            let (r, p) = crate::estimator::ekf::tilt_from_accel(f);
            (*start as f64 * dt, *len as f64 * dt, [r / D2R, p / D2R])
        })
        .collect();
    Ok(Alignment { rotation, rests, yaw_evidence: evidence, pull_aways })
}

/// The command: decode the log, align, print.
pub fn run(a: &AlignArgs) -> Result<(), String> {
    let cfg = match &a.config {
        Some(p) => Config::load(p).map_err(|e| e.to_string())?,
        None => Config::default(),
    };
    cfg.adis_only("align")?;
    let name = a.input.display().to_string();
    let file = std::fs::File::open(&a.input).map_err(|e| format!("cannot open {name}: {e}"))?;
    let mut asm = Assembler::new(cfg.profile(), cfg.input.ids);
    let mut samples = Vec::new();
    crate::replay::for_each_sample(file, &mut asm, |s| samples.push(*s)).map_err(|(line, e)| format!("{name} line {line}: {e}"))?;
    if samples.is_empty() {
        return Err(format!("{name}: no complete IMU sample"));
    }
    let al = align(&samples, &cfg)?;
    print!("{}", al.render());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A level car whose sensor is mounted at `mount` (deg): `phases` of
    /// (seconds, forward acceleration g, vibration on); 200 Hz.
    fn drive(mount: [f64; 3], phases: &[(f64, f64, bool)]) -> Vec<Sample> {
        let c = quat::matrix_from_euler(mount[0] * D2R, mount[1] * D2R, mount[2] * D2R);
        let bias = [1.0, -0.5, 0.3];
        let mut out = Vec::new();
        let mut k = 0u32;
        for &(secs, a, vib) in phases {
            for _ in 0..(secs * 200.0) as u32 {
                let t = k as f64 / 200.0;
                let w = |amp: f64, hz: f64| amp * (2.0 * std::f64::consts::PI * hz * t).sin();
                // road vibration while driving, engine idle at the stops
                let (fv, gv) =
                    if vib { ([w(0.08, 29.0), w(0.05, 23.0), w(0.06, 31.0)], w(1.5, 17.0)) } else { ([w(0.01, 29.0), 0.0, 0.0], 0.0) };
                let f = quat::rotate_t(&c, &[a + fv[0], fv[1], -1.0 + fv[2]]);
                let g = quat::rotate_t(&c, &[gv, 0.0, 0.0]);
                out.push(Sample {
                    cnt: k as u16,
                    t_us: 0,
                    steps: u32::from(k > 0),
                    gyro: [g[0] + bias[0], g[1] + bias[1], g[2] + bias[2]],
                    accel: f,
                    magn: [0.0; 3],
                    temp: 25.0,
                    diag: 0,
                });
                k += 1;
            }
        }
        out
    }

    #[test]
    fn a_recording_that_starts_while_driving_still_finds_its_stops() {
        // The first second holds a 0.15 g pull-away with road vibration: its
        // mean |f| (1.01 g) is not gravity. Taken as gravity, the +-0.5 %
        // band hid every stop ("no standstill found").
        let cfg = Config::parse("[input]\nprofile = \"adis16448\"\nrate_hz = 200.0", "test").unwrap();
        let mount = [2.0, -3.0, 30.0];
        let s = drive(
            mount,
            &[(4.0, 0.15, true), (8.0, 0.0, false), (4.0, 0.15, true), (6.0, 0.0, false), (3.0, -0.15, true), (6.0, 0.0, false)],
        );
        let first: f64 = s[..200].iter().map(|s| norm(&s.accel)).sum::<f64>() / 200.0;
        assert!(first > 1.008, "the test needs a first second off gravity: {first}");
        let a = align(&s, &cfg).unwrap();
        assert!(a.rests.len() >= 3, "{a:?}");
        assert!((a.rotation[0] - mount[0]).abs() < 0.1 && (a.rotation[1] - mount[1]).abs() < 0.1, "{a:?}");
        assert!(crate::estimator::ekf::wrap_pi((a.rotation[2] - mount[2]) * D2R).abs() / D2R < 1.0, "{a:?}");
    }

    #[test]
    fn a_recording_that_starts_at_rest_keeps_g0_as_gravity() {
        // An accelerometer reading 1.5 % high: a still start makes that the
        // reference, so the stops pass the +-0.5 % band.
        let cfg = Config::parse("[input]\nprofile = \"adis16448\"\nrate_hz = 200.0", "test").unwrap();
        let mut s = drive([0.0, 0.0, 0.0], &[(6.0, 0.0, false), (4.0, 0.15, true), (6.0, 0.0, false)]);
        for x in s.iter_mut() {
            x.accel = x.accel.map(|v| v * 1.015);
        }
        let a = align(&s, &cfg).unwrap();
        assert_eq!(a.rests.len(), 2, "{a:?}");
    }
}
