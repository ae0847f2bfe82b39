//! Per-sample latency through the daemon's own code path, bus excluded:
//! from the closing (AUX) input frame entering the pipeline to the last of
//! the output frames (five: the four and `EST_AID`) queued for the writer
//! task (`daemon::BusSink`).
//! 1 M samples; prints p50 / p99 / p99.9 / max. Run: `cargo bench --bench latency`.

mod support;
use gyrocomp::adis::{InputIds, RawFrame};
use gyrocomp::config::Config;
use gyrocomp::daemon::{BusSink, ShellCounters};
use gyrocomp::pipeline::Pipeline;
use socketcan::CanFrame;
use std::time::Instant;

fn main() {
    let n: usize = std::env::var("LATENCY_SAMPLES").ok().and_then(|v| v.parse().ok()).unwrap_or(1_000_000);
    let frames = support::raw_samples(n as u32);
    let cfg = Config::parse("[estimator]\nwarmup_s = 1.0\nlearn_s = 5.0\n[thermal]\np1 = [0.002, 0.0044, 0.0192]", "bench").unwrap();
    let mut pipe = Pipeline::new(&cfg);
    let (tx, mut rx) = tokio::sync::mpsc::channel::<CanFrame>(gyrocomp::daemon::TX_QUEUE);
    let shell = ShellCounters::default();
    let mut sink = BusSink::new(&tx, &shell);
    let ids = InputIds::DEFAULT.all();
    let mut lat = vec![0u32; n];
    for (k, f) in frames.iter().enumerate() {
        for j in 0..3 {
            pipe.push(k as u64, RawFrame::classic(ids[j], &f[j]), &mut sink);
        }
        let t0 = Instant::now();
        pipe.push(k as u64, RawFrame::classic(ids[3], &f[3]), &mut sink);
        let dt = t0.elapsed();
        lat[k] = dt.as_nanos().min(u32::MAX as u128) as u32;
        // the writer task's side, outside the timed path
        while rx.try_recv().is_ok() {}
    }
    assert_eq!(sink.samples(), n as u64);
    assert_eq!(shell.tx_dropped.load(std::sync::atomic::Ordering::Relaxed), 0);
    let mut s = lat.clone();
    s.sort_unstable();
    let q = |x: f64| s[((n as f64 * x) as usize).min(n - 1)];
    let mean = lat.iter().map(|v| *v as f64).sum::<f64>() / n as f64;
    println!(
        "latency closing frame -> 5 output frames queued, {n} samples: p50 {} ns, p99 {} ns, p99.9 {} ns, max {} ns, mean {:.0} ns",
        q(0.5),
        q(0.99),
        q(0.999),
        s[n - 1],
        mean
    );
}
