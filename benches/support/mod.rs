//! Input shared by the benchmarks: encoded ADIS samples of gentle motion with
//! excursions through all three bands, at the ADIS16448 rate.

use gyrocomp::adis::{builtin_profile, RawSample};

pub fn raw_samples(n: u32) -> Vec<[[u8; 8]; 4]> {
    let p = builtin_profile("adis16448").unwrap();
    (0..n)
        .map(|k| {
            let t = k as f64 / p.rate_hz;
            let a = 1.0 + 0.25 * (0.05 * t).sin();
            let mut r = RawSample::quantise(
                &p,
                [5.0 * (0.3 * t).sin() + 0.2, 3.0 * (0.2 * t).cos() - 0.1, 10.0 * (0.1 * t).sin()],
                [0.05 * (0.3 * t).sin(), 0.03, -a],
                [0.2, 0.05, 0.4],
                30.0 + 0.01 * t,
            );
            r.cnt = k as u16;
            r.encode()
        })
        .collect()
}
