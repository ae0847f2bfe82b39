//! `cargo bench`: ns per estimator step, per pipeline sample (frames in,
//! frames out), and replay throughput on an in-memory candump log, with
//! socketcan's own dump reader beside ours for comparison.

mod support;
use criterion::{black_box, criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use gyrocomp::adis::{builtin_profile, Assembler, InputIds, Push, RawFrame, Sample};
use gyrocomp::candump::write_line;
use gyrocomp::config::Config;
use gyrocomp::estimator::Estimator;
use gyrocomp::pipeline::{NullSink, Pipeline};
use gyrocomp::replay;
use support::raw_samples;

fn samples(n: u32) -> Vec<Sample> {
    let p = builtin_profile("adis16448").unwrap();
    let mut a = Assembler::new(p, InputIds::DEFAULT);
    let ids = InputIds::DEFAULT.all();
    let mut out = Vec::new();
    for f in raw_samples(n) {
        for i in 0..4 {
            if let Push::Sample(s) = a.push(0, RawFrame::classic(ids[i], &f[i])) {
                out.push(s);
            }
        }
    }
    out
}

fn log_bytes(n: u32) -> Vec<u8> {
    let ids = InputIds::DEFAULT.all();
    let mut out = Vec::new();
    for (k, f) in raw_samples(n).iter().enumerate() {
        for i in 0..4 {
            write_line(&mut out, 1_700_000_000_000_000 + k as u64 * 4883 + i as u64 * 50, b"vcan0", ids[i], &f[i]);
        }
    }
    out
}

fn cfg() -> Config {
    Config::parse("[estimator]\nwarmup_s = 1.0\nlearn_s = 5.0\n[thermal]\np1 = [0.002, 0.0044, 0.0192]", "bench").unwrap()
}

fn bench(c: &mut Criterion) {
    let ss = samples(100_000);
    let cfg = cfg();

    let mut g = c.benchmark_group("estimator");
    g.throughput(Throughput::Elements(1));
    let paper =
        Config::parse("[estimator]\nmode = \"paper\"\nwarmup_s = 1.0\nlearn_s = 5.0\n[thermal]\np1 = [0.002, 0.0044, 0.0192]", "bench")
            .unwrap();
    let speed = Config::parse(
        "[estimator]\nwarmup_s = 1.0\nlearn_s = 5.0\n[thermal]\np1 = [0.002, 0.0044, 0.0192]\n\
         [speed]\ndbc = \"car.dbc\"\nmessage = \"WHEEL_SPEEDS\"\nsignals = [\"RL\", \"RR\"]",
        "bench",
    )
    .unwrap();
    for (name, cfg) in [("step_default_mekf", &cfg), ("step_default_mekf_with_speed", &speed), ("step_paper", &paper)] {
        let with_speed = cfg.speed.enabled();
        let mut est = Estimator::new(cfg);
        // steady state: past warm-up and learning
        for s in &ss[..20_000] {
            est.step(s);
        }
        let mut i = 20_000;
        g.bench_function(name, |b| {
            b.iter(|| {
                if with_speed {
                    // a 50 Hz wheel speed: a new frame every fourth sample
                    est.set_speed(Some(black_box(10.0)), i % 4 == 0);
                }
                let e = est.step(black_box(&ss[i]));
                i += 1;
                if i == ss.len() {
                    i = 20_000;
                }
                e
            })
        });
    }
    // The first second after power-on: the default filter runs its bank of
    // power-on speed hypotheses (seven filters, and the free copy) until the first standstill
    // or 60 s; per sample, a fresh estimator each batch.
    let first = (204.8f64) as usize;
    g.throughput(Throughput::Elements(first as u64));
    g.bench_function("first_second_default_mekf_with_speed_hypotheses", |b| {
        b.iter_batched(
            || Estimator::new(&cfg),
            |mut est| {
                for s in &ss[..first] {
                    black_box(est.step(black_box(s)));
                }
                est
            },
            BatchSize::SmallInput,
        )
    });
    g.throughput(Throughput::Elements(1));
    // The yardstick: VQF (vqf-rs, a port of the published C++ VQF), 9D, on
    // the same samples converted to its conventions (FLU, m/s^2, rad/s).
    let flu = |v: [f64; 3]| [v[0], -v[1], -v[2]];
    let d2r = std::f64::consts::PI / 180.0;
    let conv: Vec<([f64; 3], [f64; 3], [f64; 3])> =
        ss.iter().map(|s| (flu(s.gyro).map(|w| w * d2r), flu(s.accel).map(|a| a * 9.80665), flu(s.magn))).collect();
    let mut vqf = vqf_rs::VQF::new(1.0 / 204.8, None, None, None);
    for (gy, ac, mg) in &conv[..20_000] {
        vqf.update(*gy, *ac, Some(*mg));
    }
    let mut i = 20_000;
    g.bench_function("vqf_rs_9d_update", |b| {
        b.iter(|| {
            let (gy, ac, mg) = &conv[i];
            vqf.update(black_box(*gy), black_box(*ac), Some(black_box(*mg)));
            i += 1;
            if i == conv.len() {
                i = 20_000;
            }
            vqf.quat_9d()
        })
    });
    g.finish();

    let frames = raw_samples(100_000);
    let ids = InputIds::DEFAULT.all();
    let mut g = c.benchmark_group("pipeline");
    g.throughput(Throughput::Elements(1));
    let mut pipe = Pipeline::new(&cfg);
    let mut k = 0usize;
    g.bench_function("sample_4_frames_in_5_out", |b| {
        b.iter(|| {
            let f = &frames[k % frames.len()];
            for j in 0..4 {
                pipe.push(k as u64, RawFrame::classic(ids[j], black_box(&f[j])), &mut NullSink);
            }
            k += 1;
        })
    });
    g.finish();

    let n = 200_000u32;
    let log = log_bytes(n);
    let mut g = c.benchmark_group("replay");
    g.sample_size(10);
    g.throughput(Throughput::Elements(n as u64));
    g.bench_function("candump_in_candump_out_200k_samples", |b| {
        b.iter_batched(
            || Vec::with_capacity(log.len() + 4096),
            |out: Vec<u8>| {
                let mut w = gyrocomp::candump::LogWriter::new(out, "vcan0");
                let mut pipe = Pipeline::new(&cfg);
                let mut sink = replay::ReplaySink::<Vec<u8>, Vec<u8>> { log: Some(&mut w), csv: None, keep: None, mcap: None, err: None };
                let s = replay::run(&mut pipe, &log[..], &mut sink).unwrap();
                assert_eq!(s.input.samples, n as u64);
                w.finish().unwrap()
            },
            BatchSize::PerIteration,
        )
    });
    g.throughput(Throughput::Elements(4 * n as u64));
    g.bench_function("parse_only_ours_800k_lines", |b| {
        b.iter(|| {
            let mut rd = gyrocomp::candump::LineReader::new(&log[..]);
            let mut acc = 0u64;
            while let Some(Ok(l)) = rd.next_line().unwrap() {
                acc += gyrocomp::candump::parse_line(l).unwrap().t_us;
            }
            acc
        })
    });
    g.bench_function("parse_only_socketcan_dump_800k_lines", |b| {
        b.iter(|| {
            let rd = socketcan::dump::Reader::from_reader(&log[..]);
            let mut acc = 0u64;
            for r in rd {
                acc += r.unwrap().t_us;
            }
            acc
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
