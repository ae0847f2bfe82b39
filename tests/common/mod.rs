//! Test support: small synthetic ADIS logs written through the real encoder.
#![allow(dead_code)]

use gyrocomp::adis::{builtin_profile, InputIds, RawSample};
use gyrocomp::candump::write_line;

/// A level unit turning slowly in yaw (0.3 deg/s) and rocking a little in roll with a
/// constant gyro bias, `n` samples at the ADIS16448 rate, as candump text.
pub fn gentle_log(n: u32, bias: [f64; 3], t0_us: u64) -> Vec<u8> {
    gentle_log_from(n, bias, t0_us, 0)
}

/// `gentle_log` whose DATA_CNT starts at `cnt0`.
pub fn gentle_log_from(n: u32, bias: [f64; 3], t0_us: u64, cnt0: u16) -> Vec<u8> {
    let p = builtin_profile("adis16448").unwrap();
    let ids = InputIds::DEFAULT.all();
    let dt = 1.0 / p.rate_hz;
    let mut out = Vec::new();
    for k in 0..n {
        let t = k as f64 * dt;
        // roll = 2 deg sin(0.2 t); yaw rate 0.3 deg/s
        const YAW_RATE: f64 = 0.3;
        let roll = 2f64.to_radians() * (0.2 * t).sin();
        let droll = 2.0 * 0.2 * (0.2 * t).cos(); // deg/s
        let yaw = (YAW_RATE * t).to_radians();
        let (sr, cr) = roll.sin_cos();
        // level pitch: body rates p = droll, q = sin(roll) * yaw_rate, r = cos(roll) * yaw_rate
        let gyro = [droll + bias[0], sr * YAW_RATE + bias[1], cr * YAW_RATE + bias[2]];
        let accel = [0.0, -sr, -cr];
        // field NED (0.2, 0, 0.4) gauss, rotated into the body (yaw then roll)
        let (sy, cy) = yaw.sin_cos();
        let (mx, my0, mz0) = (0.2 * cy, -0.2 * sy, 0.4);
        let magn = [mx, cr * my0 + sr * mz0, -sr * my0 + cr * mz0];
        let mut r = RawSample::quantise(&p, gyro, accel, magn, 30.0);
        r.cnt = cnt0.wrapping_add(k as u16);
        let f = r.encode();
        let ts = t0_us + (t * 1e6) as u64;
        for (i, d) in f.iter().enumerate() {
            write_line(&mut out, ts + i as u64 * 10, b"vcan0", ids[i], d);
        }
    }
    out
}

pub fn bin() -> std::path::PathBuf {
    std::path::PathBuf::from(env!("CARGO_BIN_EXE_gyrocomp"))
}

/// 3x3 matrix product (the simulator tests' own rotation algebra, independent
/// of the estimator's `quat` module).
pub fn mat_mul(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut c = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            c[i][j] = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    c
}

/// Rotation of a rotation vector (Rodrigues).
pub fn exp_so3(w: [f64; 3]) -> [[f64; 3]; 3] {
    let th = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
    let k = [[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]];
    let (a, b) = if th < 1e-12 { (1.0, 0.5) } else { (th.sin() / th, (1.0 - th.cos()) / (th * th)) };
    let k2 = mat_mul(&k, &k);
    let mut r = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            r[i][j] = if i == j { 1.0 } else { 0.0 } + a * k[i][j] + b * k2[i][j];
        }
    }
    r
}

/// Z-Y-X Euler angles of a body-to-navigation matrix, deg.
pub fn euler_deg(c: &[[f64; 3]; 3]) -> [f64; 3] {
    [c[2][1].atan2(c[2][2]).to_degrees(), (-c[2][0]).asin().to_degrees(), c[1][0].atan2(c[0][0]).to_degrees()]
}

/// A gzip text file's contents.
pub fn read_gz(p: &std::path::Path) -> String {
    use std::io::Read;
    let mut text = String::new();
    flate2::read::GzDecoder::new(std::fs::File::open(p).unwrap()).read_to_string(&mut text).unwrap();
    text
}

/// Write these lines, gzip-compressed, to `p`.
pub fn write_gz<'a>(p: &std::path::Path, lines: impl IntoIterator<Item = std::borrow::Cow<'a, str>>) {
    use std::io::Write;
    let mut out = flate2::write::GzEncoder::new(std::fs::File::create(p).unwrap(), flate2::Compression::fast());
    for line in lines {
        writeln!(out, "{line}").unwrap();
    }
    out.finish().unwrap();
}

/// A second-order Butterworth section (bilinear transform), `high` pass or
/// low pass at `fc` Hz for a signal sampled at `fs` Hz, run over `x`.
pub fn butterworth2(x: &[f64], fs: f64, fc: f64, high: bool) -> Vec<f64> {
    let w = 2.0 * std::f64::consts::PI * fc / fs;
    let (sn, cs) = w.sin_cos();
    let alpha = sn / std::f64::consts::SQRT_2;
    let a0 = 1.0 + alpha;
    let (b0, b1) = if high { ((1.0 + cs) / 2.0, -(1.0 + cs)) } else { ((1.0 - cs) / 2.0, 1.0 - cs) };
    let (b0, b1, b2, a1, a2) = (b0 / a0, b1 / a0, b0 / a0, -2.0 * cs / a0, (1.0 - alpha) / a0);
    let (mut x1, mut x2, mut y1, mut y2) = (0.0, 0.0, 0.0, 0.0);
    x.iter()
        .map(|&v| {
            let y = b0 * v + b1 * x1 + b2 * x2 - a1 * y1 - a2 * y2;
            (x2, x1, y2, y1) = (x1, v, y1, y);
            y
        })
        .collect()
}

/// The RMS of `x` (sampled at `fs` Hz) between `lo` and `hi` Hz (second-
/// order Butterworth high and low passes, run twice each), over the samples
/// `keep` selects, the first two seconds left out (the filters settling).
pub fn band_rms(x: &[f64], fs: f64, lo: f64, hi: f64, keep: impl Fn(usize) -> bool) -> f64 {
    let mut y = x.to_vec();
    for _ in 0..2 {
        y = butterworth2(&butterworth2(&y, fs, lo, true), fs, hi, false);
    }
    let skip = (2.0 * fs) as usize;
    let (s, n) = y.iter().enumerate().skip(skip).filter(|(i, _)| keep(*i)).fold((0.0, 0usize), |(s, n), (_, v)| (s + v * v, n + 1));
    (s / n.max(1) as f64).sqrt()
}

/// The folder of real recordings: `$GYROCOMP_REALDATA`, else
/// `../shared/realdata` beside the repository; None where it is not there
/// (the tests that read it say so and skip).
pub fn realdata_dir() -> Option<std::path::PathBuf> {
    let d = match std::env::var_os("GYROCOMP_REALDATA") {
        Some(d) => std::path::PathBuf::from(d),
        None => std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/realdata"),
    };
    d.is_dir().then_some(d)
}
