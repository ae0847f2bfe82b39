//! Step 1: a chamber log into 1-s bins (see the module documentation).

use super::{CalError, BIN_S, MAX_BAD_FRACTION, MIN_RUN_S};
use crate::adis::Assembler;
use crate::config::Config;
use std::fs::File;
use std::io;
use std::path::Path;

/// One-second average of a static run.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Bin {
    /// Seconds since the run's first sample (bin start + half a bin).
    pub t: f64,
    pub temp: f64,
    pub gyro: [f64; 3],
    /// Within-bin standard deviation of the gyro, deg/s.
    pub gyro_sd: [f64; 3],
    pub accel: [f64; 3],
    /// Samples averaged.
    pub n: u32,
}

/// A chamber run as read from its log.
#[derive(Clone, Debug, Default)]
pub struct Run {
    pub name: String,
    pub bins: Vec<Bin>,
    pub lines: u64,
    pub bad_lines: u64,
    pub samples: u64,
    pub suspect: u64,
    pub checksum: u64,
    pub resyncs: u64,
    /// Bins whose time went backwards.
    pub backwards: u64,
}

#[derive(Default)]
struct BinAcc {
    idx: i64,
    n: u32,
    temp: f64,
    g: [f64; 3],
    g2: [f64; 3],
    a: [f64; 3],
}

impl BinAcc {
    fn take(&mut self) -> Option<Bin> {
        if self.n == 0 {
            return None;
        }
        let n = self.n as f64;
        let mean = self.g.map(|v| v / n);
        let sd = [0, 1, 2].map(|i| if self.n > 1 { ((self.g2[i] - n * mean[i] * mean[i]) / (n - 1.0)).max(0.0).sqrt() } else { 0.0 });
        let b = Bin {
            t: (self.idx as f64 + 0.5) * BIN_S,
            temp: self.temp / n,
            gyro: mean,
            gyro_sd: sd,
            accel: self.a.map(|v| v / n),
            n: self.n,
        };
        *self = BinAcc::default();
        Some(b)
    }
}

/// Read one chamber log into 1-s bins. Never panics on bad input; refuses
/// corrupt, empty and too-short logs with an error naming the file.
pub fn read_run(path: &Path, cfg: &Config) -> Result<Run, CalError> {
    let name = path.display().to_string();
    let f = File::open(path).map_err(|e| CalError::Input { path: name.clone(), msg: format!("cannot open: {e}") })?;
    read_run_from(f, &name, cfg)
}

/// [`read_run`] from any reader; `name` names it in errors.
pub fn read_run_from<R: io::Read>(input: R, name: &str, cfg: &Config) -> Result<Run, CalError> {
    let bad = |msg: String| CalError::Input { path: name.to_string(), msg };
    let mut asm = Assembler::new(cfg.profile(), cfg.input.ids);
    let mut run = Run { name: name.to_string(), ..Default::default() };
    let mut t_first: Option<u64> = None;
    let mut acc = BinAcc::default();
    let stats = crate::replay::for_each_sample(input, &mut asm, |s| {
        if s.suspect() {
            return;
        }
        let t0 = *t_first.get_or_insert(s.t_us);
        let t = s.t_us as f64 * 1e-6 - t0 as f64 * 1e-6;
        let idx = (t / BIN_S).floor() as i64;
        if acc.n > 0 && idx != acc.idx {
            if idx < acc.idx {
                run.backwards += 1;
            }
            if let Some(b) = acc.take() {
                run.bins.push(b);
            }
        }
        acc.idx = idx;
        acc.n += 1;
        acc.temp += s.temp;
        for i in 0..3 {
            acc.g[i] += s.gyro[i];
            acc.g2[i] += s.gyro[i] * s.gyro[i];
            acc.a[i] += s.accel[i];
        }
    })
    .map_err(|(line, e)| bad(format!("read error after line {line}: {e}")))?;
    run.lines = stats.lines;
    run.bad_lines = stats.bad_lines;
    let first_bad = stats.first_bad.map(|(l, e)| (l, e.to_string()));
    if let Some(b) = acc.take() {
        run.bins.push(b);
    }
    let c = asm.counters;
    run.samples = c.samples;
    run.suspect = c.suspect;
    run.checksum = c.checksum;
    run.resyncs = c.resyncs;
    if run.lines == 0 {
        return Err(bad("empty log (no line)".into()));
    }
    if run.bad_lines as f64 > MAX_BAD_FRACTION * run.lines as f64 {
        let (l, e) = first_bad.unwrap_or((0, String::new()));
        return Err(bad(format!("corrupt: {} of {} lines unparseable (first at line {l}: {e})", run.bad_lines, run.lines)));
    }
    if c.samples == 0 {
        return Err(bad(format!("no complete sample in {} lines ({} frames; wrong [input] ids or profile?)", run.lines, c.frames)));
    }
    if run.checksum as f64 > MAX_BAD_FRACTION * (c.samples + c.checksum) as f64 {
        return Err(bad(format!("corrupt: {} of {} samples fail the checksum", run.checksum, c.samples + c.checksum)));
    }
    run.bins.sort_by(|a, b| a.t.total_cmp(&b.t));
    let dur = run.bins.len() as f64 * BIN_S;
    if dur < MIN_RUN_S {
        return Err(bad(format!("too short: {dur:.0} s of samples, need at least {MIN_RUN_S:.0} s")));
    }
    if run.bins.iter().any(|b| !b.temp.is_finite() || b.gyro.iter().any(|v| !v.is_finite())) {
        return Err(bad("non-finite values".into()));
    }
    Ok(run)
}
