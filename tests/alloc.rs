//! No heap allocation per sample in the core: a counting global allocator
//! watches the pipeline (assembly, estimator, encoding) in steady state.

use gyrocomp::adis::{builtin_profile, InputIds, RawFrame, RawSample};
use gyrocomp::config::Config;
use gyrocomp::pipeline::{NullSink, Pipeline};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

struct Counting;
thread_local! {
    // per test thread: tests run in parallel and must not see each other's allocations
    static COUNT: Cell<u64> = const { Cell::new(0) };
}

fn bump() {
    let _ = COUNT.try_with(|c| c.set(c.get() + 1));
}

fn allocs() -> u64 {
    COUNT.with(|c| c.get())
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        bump();
        System.alloc(l)
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        System.dealloc(p, l)
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, n: usize) -> *mut u8 {
        bump();
        System.realloc(p, l, n)
    }
}

#[global_allocator]
static A: Counting = Counting;

#[test]
fn pipeline_step_does_not_allocate() {
    let p = builtin_profile("adis16448").unwrap();
    let frames: Vec<[[u8; 8]; 4]> = (0..50_000u32)
        .map(|k| {
            let t = k as f64 / 204.8;
            let mut r = RawSample::quantise(&p, [0.3 * t.sin(), 0.1, -0.2], [0.01 * t.cos(), 0.0, -1.0], [0.2, 0.0, 0.4], 30.0 + t * 0.01);
            r.cnt = k as u16;
            r.encode()
        })
        .collect();
    let cfg = Config::parse("[thermal]\np1 = [0.002, 0.004, 0.019]", "t").unwrap();
    let mut pipe = Pipeline::new(&cfg);
    let ids = InputIds::DEFAULT.all();
    let mut sink = NullSink;
    // warm-up: the first samples, through warm-up and learning transitions
    for (k, f) in frames.iter().enumerate().take(20_000) {
        for i in 0..4 {
            pipe.push(k as u64, RawFrame::classic(ids[i], &f[i]), &mut sink);
        }
    }
    let before = allocs();
    for (k, f) in frames.iter().enumerate().skip(20_000) {
        for i in 0..4 {
            pipe.push(k as u64, RawFrame::classic(ids[i], &f[i]), &mut sink);
        }
    }
    let after = allocs();
    assert_eq!(pipe.counters().samples, 50_000);
    assert_eq!(after - before, 0, "{} allocations in 30000 samples", after - before);
}

#[test]
fn daemon_output_path_does_not_allocate() {
    use gyrocomp::daemon::{BusSink, ShellCounters};
    let p = builtin_profile("adis16448").unwrap();
    let frames: Vec<[[u8; 8]; 4]> = (0..30_000u32)
        .map(|k| {
            let t = k as f64 / 204.8;
            let mut r = RawSample::quantise(&p, [0.3 * t.sin(), 0.1, -0.2], [0.01 * t.cos(), 0.0, -1.0], [0.2, 0.0, 0.4], 30.0);
            r.cnt = k as u16;
            r.encode()
        })
        .collect();
    let cfg = Config::parse("", "t").unwrap();
    let mut pipe = Pipeline::new(&cfg);
    let (tx, mut rx) = tokio::sync::mpsc::channel::<socketcan::CanFrame>(gyrocomp::daemon::TX_QUEUE);
    let shell = ShellCounters::default();
    let mut sink = BusSink::new(&tx, &shell);
    let ids = InputIds::DEFAULT.all();
    let mut run = |range: std::ops::Range<usize>, sink: &mut BusSink<'_>| {
        for k in range {
            for i in 0..4 {
                pipe.push(k as u64, RawFrame::classic(ids[i], &frames[k][i]), sink);
            }
            while rx.try_recv().is_ok() {}
        }
    };
    run(0..20_000, &mut sink);
    let before = allocs();
    run(20_000..30_000, &mut sink);
    let after = allocs();
    assert_eq!(sink.samples(), 30_000);
    assert_eq!(after - before, 0, "{} allocations in 10000 samples through BusSink", after - before);
}

#[test]
fn dbc_input_path_does_not_allocate() {
    // the MM7.10 example: three frames a sample, counters, CRCs, a validity signal
    let cfg = Config::load(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("config/mm7p10.toml")).unwrap();
    let plan = cfg.input.plan.0.clone().unwrap();
    let frames: Vec<Vec<gyrocomp::dbcin::Encoded>> = (0..30_000u64)
        .map(|k| {
            let t = k as f64 / 100.0;
            plan.encode(k, &[0.3 * t.sin(), 0.1, -0.2, 0.01 * t.cos(), 0.0, -1.0, 30.0 + t * 0.01])
        })
        .collect();
    let mut pipe = Pipeline::new(&cfg);
    let mut sink = NullSink;
    let mut run = |range: std::ops::Range<usize>, pipe: &mut Pipeline| {
        for k in range {
            for f in &frames[k] {
                let raw = RawFrame { id: f.id, extended: f.extended, remote: false, fd: false, data: &f.data };
                pipe.push(k as u64 * 10_000, raw, &mut sink);
            }
        }
    };
    run(0..20_000, &mut pipe);
    let before = allocs();
    run(20_000..30_000, &mut pipe);
    let after = allocs();
    assert_eq!(pipe.counters().samples, 30_000);
    assert_eq!(after - before, 0, "{} allocations in 10000 DBC samples", after - before);
}
