//! Step 1: a chamber log, or a recording in the project's CSV format, into
//! 1-s bins (see the module documentation).

use super::{CalError, BIN_S, JUMP_S, MAX_BAD_FRACTION, MIN_FIT_BINS};
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

/// Samples into 1-s bins by their time since the run's first sample: a
/// bin's time is where its samples lie, so a time jump (a recording in
/// bursts) leaves no bin in between and the walk model spans it.
#[derive(Default)]
struct Binner {
    acc: BinAcc,
    bins: Vec<Bin>,
    t_first: Option<f64>,
    /// Bins whose time went backwards.
    backwards: u64,
}

impl Binner {
    fn push(&mut self, t_s: f64, temp: f64, gyro: [f64; 3], accel: [f64; 3]) {
        let t0 = *self.t_first.get_or_insert(t_s);
        let idx = ((t_s - t0) / BIN_S).floor() as i64;
        let acc = &mut self.acc;
        if acc.n > 0 && idx != acc.idx {
            if idx < acc.idx {
                self.backwards += 1;
            }
            if let Some(b) = acc.take() {
                self.bins.push(b);
            }
        }
        acc.idx = idx;
        acc.n += 1;
        acc.temp += temp;
        for i in 0..3 {
            acc.g[i] += gyro[i];
            acc.g2[i] += gyro[i] * gyro[i];
            acc.a[i] += accel[i];
        }
    }

    /// The bins in time order.
    fn finish(mut self) -> (Vec<Bin>, u64) {
        if let Some(b) = self.acc.take() {
            self.bins.push(b);
        }
        self.bins.sort_by(|a, b| a.t.total_cmp(&b.t));
        (self.bins, self.backwards)
    }
}

/// Read one run into 1-s bins: a candump log, or a recording in the
/// project's CSV format (`t,gx,gy,gz,ax,ay,az,mx,my,mz,temp`, gzip or not,
/// recognised by its header; read by the same reader as `gyrocomp gap
/// --measured`). Never panics on bad input; refuses corrupt, empty and
/// too-short inputs with an error naming the file (and the line).
pub fn read_run(path: &Path, cfg: &Config) -> Result<Run, CalError> {
    let name = path.display().to_string();
    let open = |e: io::Error| CalError::Input { path: name.clone(), msg: format!("cannot open: {e}") };
    let mut f = File::open(path).map_err(open)?;
    let mut head = [0u8; 4];
    let n = crate::textfile::read_up_to(&mut f, &mut head).map_err(open)?;
    let gz = head[..n].starts_with(&[0x1f, 0x8b]);
    if gz || is_csv(&head[..n]) {
        let bytes = std::fs::read(path).map_err(open)?;
        let plain =
            crate::textfile::gunzip(&bytes).map_err(|e| CalError::Input { path: name.clone(), msg: format!("cannot read: {e}") })?;
        if is_csv(&plain) {
            return read_csv_run(&plain, &name, cfg);
        }
        // a gzipped candump log
        return read_run_from(&plain[..], &name, cfg);
    }
    io::Seek::rewind(&mut f).map_err(open)?;
    read_run_from(f, &name, cfg)
}

/// Whether text starts with the project's CSV header (`t,...`).
fn is_csv(head: &[u8]) -> bool {
    let h = head.trim_ascii_start();
    h.starts_with(b"t,") || h.starts_with(b"t ,")
}

/// The line number of the first data line of a CSV whose last column (temp) is empty.
fn first_empty_temp_line(bytes: &[u8]) -> Option<usize> {
    let bytes = crate::textfile::gunzip(bytes).ok()?;
    let text = std::str::from_utf8(&bytes).ok()?;
    let mut lines = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty());
    lines.next()?;
    lines.find(|(_, l)| l.rsplit(',').next().is_some_and(|v| v.trim().is_empty())).map(|(i, _)| i + 1)
}

/// A recording in the project's CSV format (its bytes, gzip recognised)
/// into 1-s bins. The channels calibration does not need (the
/// magnetometer) may be empty on any line; the temperature is required
/// (rows without it are refused with their line); the accelerometer may be
/// absent (the static check then has no tilt test). A CSV does not start at
/// power-on: its times are taken relative to its first row.
pub fn read_csv_run(bytes: &[u8], name: &str, cfg: &Config) -> Result<Run, CalError> {
    let rows = crate::gap::read::measured_from_bytes(bytes, name, &cfg.profile()).map_err(CalError::Located)?;
    if rows.iter().any(|r| !r.temp.is_finite()) {
        let line = first_empty_temp_line(bytes).map_or(String::new(), |l| format!(":{l}"));
        return Err(CalError::Located(format!("{name}{line}: column temp: empty (calibration needs the temperature of every sample)")));
    }
    let mut b = Binner::default();
    for r in &rows {
        b.push(r.t, r.temp, r.gyro, r.acc);
    }
    let (bins, backwards) = b.finish();
    let run = Run { name: name.to_string(), bins, lines: rows.len() as u64, samples: rows.len() as u64, backwards, ..Default::default() };
    check_bins(run, name)
}

/// [`read_run`] from any reader; `name` names it in errors.
pub fn read_run_from<R: io::Read>(input: R, name: &str, cfg: &Config) -> Result<Run, CalError> {
    let bad = |msg: String| CalError::Input { path: name.to_string(), msg };
    let mut asm = Assembler::new(cfg.profile(), cfg.input.ids);
    let mut run = Run { name: name.to_string(), ..Default::default() };
    let mut bin = Binner::default();
    let stats = crate::replay::for_each_sample(input, &mut asm, |s| {
        if !s.suspect() {
            bin.push(s.t_us as f64 * 1e-6, s.temp, s.gyro, s.accel);
        }
    })
    .map_err(|(line, e)| bad(format!("read error after line {line}: {e}")))?;
    run.lines = stats.lines;
    run.bad_lines = stats.bad_lines;
    let first_bad = stats.first_bad.map(|(l, e)| (l, e.to_string()));
    (run.bins, run.backwards) = bin.finish();
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
    check_bins(run, name)
}

/// The checks every run's bins pass: enough seconds to tell anything
/// ([`MIN_FIT_BINS`]), finite values.
fn check_bins(run: Run, name: &str) -> Result<Run, CalError> {
    let bad = |msg: String| CalError::Input { path: name.to_string(), msg };
    let dur = run.bins.len() as f64 * BIN_S;
    if run.bins.len() < MIN_FIT_BINS {
        return Err(bad(format!("too short: {dur:.0} s of samples, need at least {MIN_FIT_BINS} s")));
    }
    if run.bins.iter().any(|b| !b.temp.is_finite() || b.gyro.iter().any(|v| !v.is_finite())) {
        return Err(bad("non-finite values".into()));
    }
    Ok(run)
}

/// The run's stretches: maximal sequences of bins without a time jump
/// longer than [`JUMP_S`], as (first bin, one past the last bin).
pub fn stretches(bins: &[Bin]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut start = 0;
    for j in 1..=bins.len() {
        if j == bins.len() || bins[j].t - bins[j - 1].t > JUMP_S {
            if j > start {
                out.push((start, j));
            }
            start = j;
        }
    }
    out
}
