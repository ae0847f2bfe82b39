//! The DBC input path against the ADIS one (issue 41: a DBC-decoded sample
//! costs at most twice an ADIS one). `input`: frames into a sample only
//! (matching, checks, decoding, assembly); `pipeline`: the same with the
//! estimator and the output frames. The frames are made up front (ADIS by
//! its encoder, DBC by the plan's), one sample a call.
//!
//! cargo bench --bench input

use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use gyrocomp::adis::{builtin_profile, Assembler, InputIds, RawFrame, RawSample};
use gyrocomp::config::Config;
use gyrocomp::dbcin::{DbcAssembler, Encoded};
use gyrocomp::pipeline::{NullSink, Pipeline};
use std::path::Path;

/// Samples in the cycle: a multiple of every counter's modulus (16-bit ADIS, 4-bit MM7.10).
const N: usize = 65_536;

fn motion(k: usize) -> ([f64; 3], [f64; 3], f64) {
    let t = k as f64 / 100.0;
    ([0.3 * t.sin(), 0.1, -0.2 + 0.05 * t.cos()], [0.01 * t.cos(), 0.02, -1.0], 30.0 + 0.001 * t)
}

fn adis_frames() -> Vec<[[u8; 8]; 4]> {
    let p = builtin_profile("adis16448").unwrap();
    (0..N)
        .map(|k| {
            let (g, a, t) = motion(k);
            let mut r = RawSample::quantise(&p, g, a, [0.2, 0.0, 0.4], t);
            r.cnt = k as u16;
            r.encode()
        })
        .collect()
}

fn dbc(config: &str) -> (Config, Vec<Vec<Encoded>>) {
    let cfg = Config::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("config").join(config)).unwrap();
    let plan = cfg.input.plan.0.clone().unwrap();
    let frames = (0..N)
        .map(|k| {
            let (g, a, t) = motion(k);
            plan.encode(k as u64, &[g[0], g[1], g[2], a[0], a[1], a[2], t])
        })
        .collect();
    (cfg, frames)
}

fn raw(e: &Encoded) -> RawFrame<'_> {
    RawFrame { id: e.id, extended: e.extended, remote: false, fd: false, data: &e.data }
}

fn bench(c: &mut Criterion) {
    let adis = adis_frames();
    let ids = InputIds::DEFAULT.all();
    let (mm7_cfg, mm7) = dbc("mm7p10.toml");
    let (j_cfg, j1939) = dbc("j1939-imu.toml");

    let mut g = c.benchmark_group("input");
    g.throughput(Throughput::Elements(1));
    let mut a = Assembler::new(builtin_profile("adis16448").unwrap(), InputIds::DEFAULT);
    let mut k = 0usize;
    g.bench_function("adis_sample_4_frames", |b| {
        b.iter(|| {
            let f = &adis[k % N];
            for j in 0..4 {
                black_box(a.push(k as u64, RawFrame::classic(ids[j], black_box(&f[j]))));
            }
            k += 1;
        })
    });
    let mut d = DbcAssembler::new(mm7_cfg.input.plan.0.clone().unwrap());
    let mut k = 0usize;
    g.bench_function("dbc_mm7p10_sample_3_frames", |b| {
        b.iter(|| {
            for f in &mm7[k % N] {
                black_box(d.push(k as u64, raw(black_box(f))));
            }
            k += 1;
        })
    });
    let mut d = DbcAssembler::new(j_cfg.input.plan.0.clone().unwrap());
    let mut k = 0usize;
    g.bench_function("dbc_j1939_sample_2_frames", |b| {
        b.iter(|| {
            for (i, f) in j1939[k % N].iter().enumerate() {
                black_box(d.push(k as u64 * 10_000 + i as u64 * 150, raw(black_box(f))));
            }
            k += 1;
        })
    });
    g.finish();

    let mut g = c.benchmark_group("pipeline_by_input");
    g.throughput(Throughput::Elements(1));
    let cfg = Config::parse("[input]\nrate_hz = 100.0\n", "bench").unwrap();
    let mut pipe = Pipeline::new(&cfg);
    let mut k = 0usize;
    g.bench_function("adis_sample", |b| {
        b.iter(|| {
            let f = &adis[k % N];
            for j in 0..4 {
                pipe.push(k as u64 * 10_000, RawFrame::classic(ids[j], black_box(&f[j])), &mut NullSink);
            }
            k += 1;
        })
    });
    let mut pipe = Pipeline::new(&mm7_cfg);
    let mut k = 0usize;
    g.bench_function("dbc_mm7p10_sample", |b| {
        b.iter(|| {
            for f in &mm7[k % N] {
                pipe.push(k as u64 * 10_000, raw(black_box(f)), &mut NullSink);
            }
            k += 1;
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
