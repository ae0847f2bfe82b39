//! `gyrocomp replay`: a candump log through the same pipeline as the daemon.
//!
//! Reads `candump -l` lines, pushes every frame into the `Pipeline`, writes the
//! output frames as a candump log stamped with the time of the input frame
//! that closed each sample, optionally writes the estimate CSV, and returns a
//! summary. Bad lines are counted, the first few reported with their line
//! number, and the replay goes on. Same input + same config = same bytes out.

use crate::adis::{Drop, InputCounters, RawFrame};
use crate::batches::Batches;
use crate::candump::{parse_line, LineError, LineReader, LogWriter};
use crate::config::Config;
use crate::estimator::Estimate;
use crate::mcapout::{McapError, McapFile, McapSink};
use crate::outfile::OutFile;
use crate::output::Frames;
use crate::pipeline::{Pipeline, Sink};
use serde::Serialize;
use std::fs::File;
use std::io::{self, Read, Write};
use std::path::Path;

/// How many bad lines are reported one by one before only counting.
pub const REPORT_BAD_LINES: u64 = 10;

#[derive(Clone, Debug, Default, Serialize)]
pub struct Summary {
    pub lines: u64,
    pub bad_lines: u64,
    pub error_frames: u64,
    pub input: InputCounters,
    /// Seconds per mode: fusion, blend, gyro only.
    pub mode_seconds: [f64; 3],
    pub mode_samples: [u64; 3],
    /// The first bad lines: (line number, reason).
    #[serde(skip)]
    pub bad_examples: Vec<(u64, LineError)>,
    /// What the estimator did.
    pub report: crate::pipeline::Report,
}

impl Summary {
    /// Count a bad line; keep the first few for the report.
    fn bad_line(&mut self, line_no: u64, err: LineError) {
        self.bad_lines += 1;
        if self.bad_examples.len() < REPORT_BAD_LINES as usize {
            self.bad_examples.push((line_no, err));
        }
    }

    /// Take the pipeline's counters and time per mode at the end of a run.
    fn finish(&mut self, pipe: &Pipeline) {
        self.input = *pipe.counters();
        self.mode_seconds = pipe.mode_seconds();
        self.mode_samples = pipe.mode_samples;
        self.report = pipe.report();
    }

    /// The human summary printed to stderr.
    pub fn render(&self) -> String {
        let c = &self.input;
        let total: f64 = self.mode_seconds.iter().sum();
        let pct = |s: f64| if total > 0.0 { 100.0 * s / total } else { 0.0 };
        let mut s = String::new();
        for (n, e) in &self.bad_examples {
            s += &format!("  bad line {n}: {e}\n");
        }
        if self.bad_lines > self.bad_examples.len() as u64 {
            s += &format!("  ... {} more bad lines\n", self.bad_lines - self.bad_examples.len() as u64);
        }
        s += &format!(
            "lines {} (bad {}), frames {}, error frames {}\nsamples {} (suspect {}), lost {} in {} gaps, counter restarts {}\n",
            self.lines, self.bad_lines, c.frames, self.error_frames, c.samples, c.suspect, c.lost, c.gaps, c.resyncs
        );
        s += "dropped:";
        for d in Drop::ALL {
            s += &format!(" {} {}", d.name(), c.get(d));
        }
        s += &format!(
            "\ntime per mode: fusion with bias learning {:.1} s ({:.1} %), aided {:.1} s ({:.1} %), gyro only {:.1} s ({:.1} %)\n",
            self.mode_seconds[0],
            pct(self.mode_seconds[0]),
            self.mode_seconds[1],
            pct(self.mode_seconds[1]),
            self.mode_seconds[2],
            pct(self.mode_seconds[2])
        );
        s += &self.report.render();
        s
    }
}

/// Where replay output goes.
pub struct ReplaySink<'a, W: Write, C: Write> {
    pub log: Option<&'a mut LogWriter<W>>,
    pub csv: Option<&'a mut C>,
    /// Every estimate, when the caller wants them in memory (evaluation).
    pub keep: Option<&'a mut Vec<Estimate>>,
    /// `--mcap`: the estimates and the input frames (its errors come back from its `finish`).
    pub mcap: Option<&'a mut McapSink>,
    pub err: Option<io::Error>,
}

impl<W: Write, C: Write> Sink for ReplaySink<'_, W, C> {
    #[inline]
    fn output(&mut self, est: &Estimate, frames: &Frames) {
        if self.err.is_some() {
            return;
        }
        if let Some(log) = self.log.as_deref_mut() {
            for f in frames.iter() {
                if let Err(e) = log.frame(est.t_us, f.id, &f.data) {
                    self.err = Some(e);
                    return;
                }
            }
        }
        if let Some(csv) = self.csv.as_deref_mut() {
            if let Err(e) = write_csv_row(csv, est) {
                self.err = Some(e);
            }
        }
        if let Some(k) = self.keep.as_deref_mut() {
            k.push(*est);
        }
        if let Some(m) = self.mcap.as_deref_mut() {
            m.output(est);
        }
    }
    fn wants_input(&self) -> bool {
        self.mcap.is_some()
    }
    fn input(&mut self, t_us: u64, frame: &RawFrame<'_>) {
        if let Some(m) = self.mcap.as_deref_mut() {
            m.input(t_us, frame);
        }
    }
}

/// The CSV's columns. `invalid`: the fields not estimated, the bits of
/// `EST_AID`'s `Invalid*` ([`crate::estimator::invalid`]; 0 all valid); an
/// invalid field is written as 0.
pub const CSV_HEADER: &str = "t,roll,pitch,yaw,rate_x,rate_y,rate_z,bias_x,bias_y,bias_z,mode,temp,invalid\n";

pub fn write_csv_row<C: Write>(c: &mut C, e: &Estimate) -> io::Result<()> {
    writeln!(
        c,
        "{:.6},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.6},{:.6},{:.6},{},{:.3},{}",
        e.t, e.roll, e.pitch, e.yaw, e.rate[0], e.rate[1], e.rate[2], e.bias[0], e.bias[1], e.bias[2], e.mode, e.temp, e.invalid
    )
}

/// Replay a stream through a pipeline into a sink. Returns the summary.
pub fn run<R: Read, S: Sink>(pipe: &mut Pipeline, input: R, sink: &mut S) -> io::Result<Summary> {
    run_inspect(pipe, input, sink, |_, _| {})
}

/// `run`, calling `after(pipeline, sink)` after every frame is pushed: a sink
/// that wants more of the estimator than the estimate (the bias sigma at a
/// standstill, for the Python binding's fleet records) reads it there.
pub fn run_inspect<R: Read, S: Sink, F: FnMut(&Pipeline, &mut S)>(
    pipe: &mut Pipeline,
    input: R,
    sink: &mut S,
    mut after: F,
) -> io::Result<Summary> {
    let mut rd = LineReader::new(input);
    let mut sum = Summary::default();
    let want_input = sink.wants_input();
    while let Some(line) = rd.next_line()? {
        sum.lines += 1;
        let parsed = match line {
            Ok([]) => {
                sum.lines -= 1;
                continue;
            }
            Ok(l) => parse_line(l),
            Err(e) => Err(e),
        };
        match parsed {
            Ok(f) if f.error => sum.error_frames += 1,
            Ok(f) => {
                let raw = RawFrame { id: f.id, extended: f.extended, remote: f.remote, fd: f.fd, data: f.payload() };
                if want_input {
                    sink.input(f.t_us, &raw);
                }
                pipe.push(f.t_us, raw, sink);
                after(pipe, sink);
            }
            Err(e) => sum.bad_line(rd.line_no, e),
        }
    }
    sum.finish(pipe);
    Ok(sum)
}

/// One parsed line, as the parsing thread hands it over.
#[derive(Clone, Copy, Debug)]
enum Item {
    Frame { t_us: u64, id: u32, extended: bool, remote: bool, fd: bool, len: u8, data: [u8; 8] },
    ErrorFrame,
    Bad { line_no: u64, err: LineError },
}

/// Parse a stream into batches of items on the current thread.
fn parse_into<R: Read>(input: R, mut batches: Batches<Item>) -> io::Result<()> {
    let mut rd = LineReader::new(input);
    while let Some(line) = rd.next_line()? {
        let item = match line {
            Ok([]) => continue,
            Ok(l) => match parse_line(l) {
                Ok(f) if f.error => Item::ErrorFrame,
                Ok(f) => {
                    let mut data = [0u8; 8];
                    let n = f.len.min(8);
                    data[..n].copy_from_slice(&f.data[..n]);
                    Item::Frame { t_us: f.t_us, id: f.id, extended: f.extended, remote: f.remote, fd: f.fd, len: f.len as u8, data }
                }
                Err(err) => Item::Bad { line_no: rd.line_no, err },
            },
            Err(err) => Item::Bad { line_no: rd.line_no, err },
        };
        if !batches.push(item) {
            return Ok(());
        }
    }
    batches.flush();
    Ok(())
}

/// An input frame as the pipeline stage hands it on: at most 8 payload bytes.
#[derive(Clone, Copy, Default)]
struct InFrame {
    t_us: u64,
    id: u32,
    extended: bool,
    remote: bool,
    fd: bool,
    len: u8,
    data: [u8; 8],
}

/// Input frames per [`Out::Inputs`]: about what fits in an output's room
/// (an `Out` is as large as its largest variant, and `replay --mcap` hands
/// over four or five frames per estimate).
const INPUTS: usize = 8;

/// What the pipeline stage hands to the sink stage.
enum Out {
    Output(Estimate, Frames),
    Dropped(u64, crate::adis::Drop),
    /// The first `n` are consecutive input frames (only when the sink wants them).
    Inputs(u8, [InFrame; INPUTS]),
}

/// Collects the pipeline's output into batches for the sink thread, the
/// input frames grouped into [`Out::Inputs`] ahead of what follows them.
struct Stage {
    out: Batches<Out>,
    n: u8,
    inputs: [InFrame; INPUTS],
}

impl Stage {
    fn input(&mut self, f: InFrame) {
        self.inputs[self.n as usize] = f;
        self.n += 1;
        if self.n as usize == INPUTS {
            self.flush_inputs();
        }
    }
    fn flush_inputs(&mut self) {
        if self.n > 0 {
            self.out.push(Out::Inputs(self.n, self.inputs));
            self.n = 0;
        }
    }
}

impl Sink for Stage {
    fn output(&mut self, est: &Estimate, frames: &Frames) {
        self.flush_inputs();
        self.out.push(Out::Output(*est, *frames));
    }
    fn dropped(&mut self, t_us: u64, cause: crate::adis::Drop) {
        self.flush_inputs();
        self.out.push(Out::Dropped(t_us, cause));
    }
}

/// `run` on three threads: this one parses, a second steps the pipeline, a
/// third feeds the sink (formats and writes). Every stage keeps the order, so
/// the output is the same bytes as `run` gives (a test checks it).
pub fn run_threaded<R: Read + Send, S: Sink + Send>(pipe: &mut Pipeline, input: R, sink: &mut S) -> io::Result<Summary> {
    use std::sync::mpsc::sync_channel;
    let (tx, rx) = sync_channel::<Vec<Item>>(4);
    let (back_tx, back_rx) = sync_channel::<Vec<Item>>(8);
    let (otx, orx) = sync_channel::<Vec<Out>>(4);
    let (oback_tx, oback_rx) = sync_channel::<Vec<Out>>(8);
    let want_input = sink.wants_input();
    std::thread::scope(|sc| {
        let writer = sc.spawn(move || {
            for mut batch in orx {
                for o in batch.drain(..) {
                    match o {
                        Out::Output(e, f) => sink.output(&e, &f),
                        Out::Dropped(t, d) => sink.dropped(t, d),
                        Out::Inputs(n, fs) => {
                            for f in &fs[..n as usize] {
                                let raw = RawFrame {
                                    id: f.id,
                                    extended: f.extended,
                                    remote: f.remote,
                                    fd: f.fd,
                                    data: &f.data[..f.len as usize],
                                };
                                sink.input(f.t_us, &raw)
                            }
                        }
                    }
                }
                let _ = oback_tx.try_send(batch);
            }
        });
        let worker = sc.spawn(move || {
            let mut out = Stage { out: Batches::new(otx, oback_rx), n: 0, inputs: [InFrame::default(); INPUTS] };
            let mut sum = Summary::default();
            for mut batch in rx {
                for it in batch.drain(..) {
                    sum.lines += 1;
                    match it {
                        Item::Frame { t_us, id, extended, remote, fd, len, data } => {
                            // Only classic payloads (<= 8 bytes) matter: FD frames are
                            // dropped as unknown by the assembler whatever they carry.
                            let n = (len as usize).min(8);
                            if want_input {
                                out.input(InFrame { t_us, id, extended, remote, fd, len: n as u8, data });
                            }
                            pipe.push(t_us, RawFrame { id, extended, remote, fd, data: &data[..n] }, &mut out)
                        }
                        Item::ErrorFrame => sum.error_frames += 1,
                        Item::Bad { line_no, err } => sum.bad_line(line_no, err),
                    }
                }
                let _ = back_tx.try_send(batch);
            }
            out.flush_inputs();
            out.out.flush();
            sum.finish(pipe);
            sum
        });
        let parsed = parse_into(input, Batches::new(tx, back_rx));
        let sum = worker.join().map_err(|_| io::Error::other("replay worker panicked"))?;
        writer.join().map_err(|_| io::Error::other("replay writer panicked"))?;
        parsed.map(|_| sum)
    })
}

/// What reading a log into samples saw.
#[derive(Clone, Debug, Default)]
pub struct LogStats {
    /// Non-empty lines.
    pub lines: u64,
    /// Lines that are not candump lines.
    pub bad_lines: u64,
    /// The first bad line: (line number, what is wrong).
    pub first_bad: Option<(u64, LineError)>,
}

/// Read a candump log through `asm`, calling `on_sample` for every complete
/// sample, in order; error frames are skipped, bad lines counted. The one
/// reading path of the offline tools (`calibrate`, `gap`). An I/O error comes
/// back with the number of the last line read.
pub fn for_each_sample<R: Read>(
    input: R,
    asm: &mut crate::adis::Assembler,
    mut on_sample: impl FnMut(&crate::adis::Sample),
) -> Result<LogStats, (u64, io::Error)> {
    let mut rd = LineReader::new(input);
    let mut st = LogStats::default();
    loop {
        let line = match rd.next_line() {
            Ok(Some(l)) => l,
            Ok(None) => return Ok(st),
            Err(e) => return Err((rd.line_no, e)),
        };
        let parsed = match line {
            Ok([]) => continue,
            Ok(l) => parse_line(l),
            Err(e) => Err(e),
        };
        st.lines += 1;
        match parsed {
            Ok(f) if f.error => {}
            Ok(f) => {
                let raw = RawFrame { id: f.id, extended: f.extended, remote: f.remote, fd: f.fd, data: f.payload() };
                if let crate::adis::Push::Sample(s) = asm.push(f.t_us, raw) {
                    on_sample(&s);
                }
            }
            Err(e) => {
                st.bad_lines += 1;
                if st.first_bad.is_none() {
                    st.first_bad = Some((rd.line_no, e));
                }
            }
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    #[error("cannot open input {path}: {source}")]
    Input { path: String, source: io::Error },
    #[error("cannot write {path}: {source}")]
    Output { path: String, source: io::Error },
    #[error("reading {path}: {source}")]
    Read { path: String, source: io::Error },
    #[error("cannot write {path}: {source}")]
    Mcap { path: String, source: McapError },
    #[error("{0}")]
    Refused(String),
}

/// Files for `replay_files`.
pub struct ReplayFiles<'a> {
    pub input: &'a Path,
    pub output: Option<&'a Path>,
    pub csv: Option<&'a Path>,
    /// `--mcap`: a Foxglove recording (`crate::mcapout`).
    pub mcap: Option<&'a Path>,
}

/// Replay a log file to an output log and/or CSV. `keep` collects estimates.
/// Outputs are written under temporary names and renamed only when the run
/// succeeds (`crate::outfile`); an output that is the input is refused.
pub fn replay_files(cfg: &Config, files: &ReplayFiles<'_>, keep: Option<&mut Vec<Estimate>>) -> Result<Summary, ReplayError> {
    let ip = files.input.display().to_string();
    let outs: Vec<&Path> = files.output.iter().chain(files.csv.iter()).chain(files.mcap.iter()).copied().collect();
    crate::outfile::refuse_inputs_as_outputs(&[files.input], &outs).map_err(ReplayError::Refused)?;
    let input = File::open(files.input).map_err(|source| ReplayError::Input { path: ip.clone(), source })?;
    let out_err = |p: &Path| {
        let path = p.display().to_string();
        move |source| ReplayError::Output { path, source }
    };
    let create = |p: &Path| OutFile::create(p).map_err(out_err(p));
    let mut log = match files.output {
        Some(p) => Some(LogWriter::new(create(p)?, &cfg.can.interface)),
        None => None,
    };
    let mut csv = match files.csv {
        Some(p) => {
            let mut w = create(p)?;
            w.write_all(CSV_HEADER.as_bytes()).map_err(out_err(p))?;
            Some(w)
        }
        None => None,
    };
    let mcap_err = |p: &Path| {
        let path = p.display().to_string();
        move |source| ReplayError::Mcap { path, source }
    };
    let mut mcap = match files.mcap {
        Some(p) => Some(McapSink::new(McapFile::create(p, false, false).map_err(mcap_err(p))?)),
        None => None,
    };
    let mut pipe = Pipeline::from_config(cfg).map_err(|e| ReplayError::Refused(format!("config: {e}")))?;
    let mut sink = ReplaySink { log: log.as_mut(), csv: csv.as_mut(), keep, mcap: mcap.as_mut(), err: None };
    let sum = run_threaded(&mut pipe, input, &mut sink).map_err(|source| ReplayError::Read { path: ip, source })?;
    if let Some(e) = sink.err.take() {
        return Err(ReplayError::Output { path: out_name(files), source: e });
    }
    drop(sink);
    if sum.input.samples == 0 {
        // Nothing to write: leave no output that looks like a result.
        return Ok(sum);
    }
    // the MCAP's errors before any output is committed
    let mcap = match (mcap, files.mcap) {
        (Some(m), Some(p)) => Some((m.finish().map_err(mcap_err(p))?, p)),
        _ => None,
    };
    if let (Some(l), Some(p)) = (log, files.output) {
        l.finish().and_then(OutFile::commit).map_err(out_err(p))?;
    }
    if let (Some(c), Some(p)) = (csv, files.csv) {
        c.commit().map_err(out_err(p))?;
    }
    if let Some((m, p)) = mcap {
        m.commit().map_err(mcap_err(p))?;
    }
    Ok(sum)
}

fn out_name(files: &ReplayFiles<'_>) -> String {
    files.output.or(files.csv).map(|p| p.display().to_string()).unwrap_or_default()
}
