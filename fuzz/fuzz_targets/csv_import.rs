//! `gyrocomp::import::read_imu_csv_from` (the CSV importer) on arbitrary
//! bytes, then the scales and the counter plan: never panics; what it
//! accepts is finite, within the documented column ranges, with t strictly
//! increasing, and every auto scale within the config's LSB ranges.
#![no_main]
use gyrocomp::import::{choose_scales, plan_counter, read_imu_csv_from, AxesMap};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut rd: &[u8] = data;
    let Ok(c) = read_imu_csv_from(&mut rd, "fuzz.csv", &AxesMap::IDENTITY) else { return };
    assert!(!c.is_empty());
    assert!(c.t.windows(2).all(|w| w[1] > w[0]), "t not increasing");
    for g in &c.gyro {
        assert!(g.iter().all(|x| x.is_finite() && x.abs() <= 10_000.0));
    }
    for a in &c.accel {
        assert!(a.iter().all(|x| x.is_finite() && x.abs() <= 1000.0));
    }
    if let Ok(s) = choose_scales(&c, None) {
        let p = &s.profile;
        assert!(p.gyro_lsb > 0.0 && p.gyro_lsb <= 1.0, "gyro LSB {}", p.gyro_lsb);
        assert!(p.accel_lsb > 0.0 && p.accel_lsb <= 0.1, "accel LSB {}", p.accel_lsb);
    }
    let _ = plan_counter(&c, None, "fuzz.csv");
});
