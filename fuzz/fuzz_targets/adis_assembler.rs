//! Arbitrary frame sequences into `gyrocomp::adis::Assembler`: never panics;
//! every frame is counted once; every sample it emits has finite values.
#![no_main]
use gyrocomp::adis::{builtin_profile, Assembler, InputIds, Push, RawFrame};
use libfuzzer_sys::fuzz_target;

mod frames;

fuzz_target!(|input: &[u8]| {
    let profile =
        builtin_profile(["adis16448", "adis16405", "adis16465-1"][(input.first().copied().unwrap_or(0) & 0x7F) as usize % 3]).unwrap();
    let mut a = Assembler::new(profile, InputIds::DEFAULT);
    let mut pushed = 0u64;
    let mut samples = 0u64;
    for f in frames::Frames::new(input.get(1..).unwrap_or(&[]), input.first().is_some_and(|c| c & 0x80 != 0)) {
        pushed += 1;
        let raw = RawFrame { id: f.id, extended: f.extended, remote: f.remote, fd: f.fd, data: &f.data[..f.len] };
        match a.push(f.t_us, raw) {
            Push::Sample(s) => {
                samples += 1;
                assert!(s.gyro.iter().chain(&s.accel).chain(&s.magn).all(|v| v.is_finite()) && s.temp.is_finite());
            }
            Push::Pending | Push::Dropped(_) => {}
        }
    }
    assert_eq!(a.counters.frames, pushed);
    assert_eq!(a.counters.samples, samples);
});
