//! `cargo bench --bench mcap`: `gyrocomp replay` of a simulated 10-minute
//! drive (smooth, seed 3, adis16448 at 204.8 Hz: 122,881 samples, 521,524
//! input frames: the IMU's four per sample and 30,000 wheel-speed frames)
//! to `--output` and `--csv`, with and without `--mcap`, the files written
//! through `replay_files` as the command writes them (temp file, sync,
//! rename). Issue 40's target: the MCAP adds at most 30 % to the
//! replay's wall time; docs/mcap.md records what this measured.

use criterion::{criterion_group, criterion_main, Criterion};
use gyrocomp::config::Config;
use gyrocomp::replay::{replay_files, ReplayFiles};
use std::process::Command;
use std::time::Instant;

fn bench(c: &mut Criterion) {
    let d = tempfile::tempdir().unwrap();
    let sim = d.path().join("sim");
    let o = Command::new(env!("CARGO_BIN_EXE_gyrocomp"))
        .args(["simulate", "--scenario", "smooth", "--seed", "3", "--out"])
        .arg(&sim)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let cfg = Config::load(&sim.join("config.toml")).unwrap();
    let input = sim.join("imu.log");
    let (log, csv, mcap) = (d.path().join("out.log"), d.path().join("est.csv"), d.path().join("out.mcap"));
    let plain = ReplayFiles { input: &input, output: Some(&log), csv: Some(&csv), mcap: None };
    let with = ReplayFiles { input: &input, output: Some(&log), csv: Some(&csv), mcap: Some(&mcap) };
    let run = |f: &ReplayFiles<'_>| {
        let s = replay_files(&cfg, f, None).unwrap();
        assert_eq!(s.input.samples, 122_881);
    };

    let mut g = c.benchmark_group("replay_10min");
    g.sample_size(10);
    g.bench_function("output_csv", |b| b.iter(|| run(&plain)));
    g.bench_function("output_csv_mcap", |b| b.iter(|| run(&with)));
    g.finish();

    // The ratio the target is about: medians of 7 alternating runs each.
    let (mut a, mut m) = (Vec::new(), Vec::new());
    for _ in 0..7 {
        let t = Instant::now();
        run(&plain);
        a.push(t.elapsed().as_secs_f64());
        let t = Instant::now();
        run(&with);
        m.push(t.elapsed().as_secs_f64());
    }
    let med = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let (a, m) = (med(&mut a), med(&mut m));
    let size = std::fs::metadata(&mcap).map(|m| m.len()).unwrap_or(0);
    println!("replay_10min: --output --csv {:.3} s, with --mcap {:.3} s: ratio {:.2} (MCAP {:.1} MB)", a, m, m / a, size as f64 / 1e6);
}

criterion_group!(benches, bench);
criterion_main!(benches);
