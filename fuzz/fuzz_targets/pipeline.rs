//! The whole core path (`gyrocomp::pipeline::Pipeline`: assembly, the
//! estimator of the chosen mode, output encoding) on arbitrary frame
//! sequences: never panics; every estimate it publishes is finite.
#![no_main]
use gyrocomp::adis::RawFrame;
use gyrocomp::config::Config;
use gyrocomp::estimator::Estimate;
use gyrocomp::output::Frames;
use gyrocomp::pipeline::{Pipeline, Sink};
use libfuzzer_sys::fuzz_target;

mod frames;

struct Check(u64);
impl Sink for Check {
    fn output(&mut self, e: &Estimate, _: &Frames) {
        self.0 += 1;
        let all = [e.roll, e.pitch, e.yaw, e.rate[0], e.rate[1], e.rate[2], e.bias[0], e.bias[1], e.bias[2], e.t];
        assert!(all.iter().all(|v| v.is_finite()), "non-finite estimate {e:?}");
    }
}

fuzz_target!(|input: &[u8]| {
    let sel = input.first().copied().unwrap_or(0) & 0x7F;
    let mode = ["robust", "paper", "startup_average", "startup_thermal"][sel as usize % 4];
    let profile = ["adis16448", "adis16405", "adis16465-1"][(sel as usize / 4) % 3];
    let cfg = Config::parse(
        &format!("[input]\nprofile = \"{profile}\"\n[estimator]\nmode = \"{mode}\"\nwarmup_s = 0.05\nlearn_s = 0.1\ng0_window_s = 0.02\n"),
        "fuzz",
    )
    .unwrap();
    let mut p = Pipeline::new(&cfg);
    let mut sink = Check(0);
    for f in frames::Frames::new(input.get(1..).unwrap_or(&[]), input.first().is_some_and(|c| c & 0x80 != 0)) {
        let raw = RawFrame { id: f.id, extended: f.extended, remote: f.remote, fd: f.fd, data: &f.data[..f.len] };
        p.push(f.t_us, raw, &mut sink);
    }
    assert_eq!(p.counters().samples, sink.0);
});
