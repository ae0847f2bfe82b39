//! `gyrocomp run`: the daemon. The I/O shell around the core `Pipeline`.
//!
//! One current-thread tokio runtime. The main loop owns the pipeline and
//! reads the bus (kernel filters pass only the four input IDs); output frames
//! go through a bounded channel to one writer task, so a full transmit queue
//! (ENOBUFS) never blocks the input path: frames are dropped and counted.
//! The same loop pings the systemd watchdog, so a stalled loop gets the
//! service restarted. SIGHUP reloads the config (a bad one is refused and the
//! old one kept), SIGTERM saves the state and stops.

pub mod notify;
pub mod state;

use crate::adis::{Drop, RawFrame};
use crate::config::Config;
use crate::estimator::{flags, Estimate};
use crate::output::{encode, Frames, OutFrame, StatusCounters};
use crate::pipeline::{Pipeline, Sink};
use anyhow::Context;
use notify::Notifier;
use socketcan::tokio::CanSocket;
use socketcan::{CanFilter, CanFrame, EmbeddedFrame, SocketOptions, StandardId};
use state::{SavedAxes, State, Store};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};
use tokio::signal::unix::{signal, SignalKind};
use tokio::sync::{mpsc, watch};
use tracing::{error, info, warn};

/// Depth of the output queue between the loop and the writer task (frames).
pub const TX_QUEUE: usize = 4096;
/// Frames read per wake-up at most before the loop looks at signals and timers again.
pub const RX_BATCH: usize = 256;
/// Receive buffer asked of the kernel (it caps it at net.core.rmem_max).
pub const RX_BUFFER: libc::c_int = 4 << 20;
const EFF_RTR_MASK: u32 = 0x7FF | 0x8000_0000 | 0x4000_0000;

/// Counters of the daemon shell (the input path's are in the pipeline).
#[derive(Debug, Default)]
pub struct ShellCounters {
    pub tx_dropped: AtomicU64,
    pub tx_errors: AtomicU64,
    pub error_frames: AtomicU64,
    pub reopens: AtomicU64,
}

/// Logs a message for a cause at most once per `every`, with the count since.
#[derive(Debug)]
pub struct RateLimited {
    every: Duration,
    last: Option<Instant>,
    suppressed: u64,
}

impl RateLimited {
    pub fn new(every: Duration) -> Self {
        RateLimited { every, last: None, suppressed: 0 }
    }
    /// Returns Some(number suppressed since the last report) when a report is due.
    pub fn due(&mut self, now: Instant) -> Option<u64> {
        match self.last {
            Some(t) if now.duration_since(t) < self.every => {
                self.suppressed += 1;
                None
            }
            _ => {
                self.last = Some(now);
                let s = self.suppressed;
                self.suppressed = 0;
                Some(s)
            }
        }
    }
}

/// The daemon's sink: output frames into the writer's queue (never waits).
pub struct BusSink<'a> {
    tx: &'a mpsc::Sender<CanFrame>,
    shell: &'a ShellCounters,
    last: Option<Estimate>,
    samples: u64,
    drop_logs: [RateLimited; 6],
}

impl<'a> BusSink<'a> {
    pub fn new(tx: &'a mpsc::Sender<CanFrame>, shell: &'a ShellCounters) -> BusSink<'a> {
        BusSink { tx, shell, last: None, samples: 0, drop_logs: std::array::from_fn(|_| RateLimited::new(Duration::from_secs(10))) }
    }
    /// Samples output so far.
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// Queue one frame for the writer; a full queue drops it and counts it.
    pub fn queue(&self, f: &OutFrame) {
        if let Some(cf) = can_frame(f) {
            if self.tx.try_send(cf).is_err() {
                self.shell.tx_dropped.fetch_add(1, Ordering::Relaxed);
            }
        }
    }
}

fn can_frame(f: &OutFrame) -> Option<CanFrame> {
    StandardId::new(f.id as u16).and_then(|id| CanFrame::new(id, &f.data))
}

impl Sink for BusSink<'_> {
    fn output(&mut self, est: &Estimate, frames: &Frames) {
        self.last = Some(*est);
        self.samples += 1;
        for f in frames.iter() {
            self.queue(f);
        }
    }
    fn dropped(&mut self, _t_us: u64, cause: Drop) {
        let i = Drop::ALL.iter().position(|d| *d == cause).unwrap_or(0);
        if let Some(sup) = self.drop_logs[i].due(Instant::now()) {
            warn!(cause = cause.name(), suppressed_since_last = sup, "input dropped");
        }
    }
}

fn now_unix() -> f64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map(|d| d.as_secs_f64()).unwrap_or(0.0)
}

fn now_us() -> u64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map(|d| d.as_micros() as u64).unwrap_or(0)
}

/// Open the bus with receive filters for the input IDs (a DBC input's
/// messages) and the vehicle's speed message when `[speed]` is configured.
/// A classic CAN socket: a DBC input's CAN FD messages are read from logs
/// (`replay`), not live yet.
pub fn open_bus(cfg: &Config, speed: Option<(u32, bool)>) -> std::io::Result<CanSocket> {
    let s = CanSocket::open(&cfg.can.interface)?;
    let mut filters: Vec<CanFilter> = match &cfg.input.plan.0 {
        // a DBC input: its messages (J1939: any priority), extended ones with the EFF flag in id and mask
        Some(plan) if !cfg.input.format.is_adis() => plan
            .msgs
            .iter()
            .map(|m| {
                if m.extended {
                    CanFilter::new(m.id | libc::CAN_EFF_FLAG, m.mask | libc::CAN_EFF_FLAG | libc::CAN_RTR_FLAG)
                } else {
                    CanFilter::new(m.id, EFF_RTR_MASK)
                }
            })
            .collect(),
        _ => cfg.input.ids.all().iter().map(|id| CanFilter::new(*id, EFF_RTR_MASK)).collect(),
    };
    if let Some((id, ext)) = speed {
        // an extended ID matches only with the EFF flag set in id and mask
        let flag = if ext { libc::CAN_EFF_FLAG } else { 0 };
        filters.push(CanFilter::new(id | flag, EFF_RTR_MASK));
    }
    s.set_filters(&filters)?;
    set_rcvbuf(&s, RX_BUFFER);
    if cfg.daemon.error_frames {
        s.set_error_filter_accept_all()?;
    } else {
        s.set_error_filter_drop_all()?;
    }
    Ok(s)
}

/// Whether a reload changes which input frames the kernel filters pass
/// (the format, or a DBC input's messages; `Config`'s equality ignores the plan).
fn input_filters_changed(new: &Config, old: &Config) -> bool {
    let ids = |c: &Config| c.input.plan.0.as_ref().map(|p| p.msgs.iter().map(|m| (m.id, m.mask, m.extended)).collect::<Vec<_>>());
    new.input.format != old.input.format || ids(new) != ids(old)
}

/// Ask for a larger receive buffer so bursts wait in the kernel, not get lost.
/// SO_RCVBUFFORCE works with CAP_NET_ADMIN; otherwise SO_RCVBUF, capped by the
/// kernel at net.core.rmem_max. Failure is harmless and logged.
fn set_rcvbuf(s: &CanSocket, bytes: libc::c_int) {
    use std::os::fd::AsRawFd;
    let fd = s.as_raw_fd();
    let set = |opt| {
        // SAFETY: setsockopt on our own socket with a c_int option value.
        unsafe {
            libc::setsockopt(
                fd,
                libc::SOL_SOCKET,
                opt,
                &bytes as *const libc::c_int as *const libc::c_void,
                std::mem::size_of::<libc::c_int>() as libc::socklen_t,
            )
        }
    };
    if set(libc::SO_RCVBUFFORCE) != 0 && set(libc::SO_RCVBUF) != 0 {
        warn!(error = %std::io::Error::last_os_error(), "cannot enlarge the receive buffer");
    }
}

/// The kernel's index of an interface, 0 when there is none.
pub fn ifindex(name: &str) -> u32 {
    match std::ffi::CString::new(name) {
        // SAFETY: a valid NUL-terminated string; the call only reads it.
        Ok(c) => unsafe { libc::if_nametoindex(c.as_ptr()) },
        Err(_) => 0,
    }
}

/// Where the state file lives: `daemon.state_dir`, else `$STATE_DIRECTORY`.
pub fn state_dir(cfg: &Config) -> Option<PathBuf> {
    if !cfg.daemon.state_dir.is_empty() {
        return Some(PathBuf::from(&cfg.daemon.state_dir));
    }
    // systemd may pass several, colon-separated: the first is ours.
    std::env::var("STATE_DIRECTORY").ok().and_then(|v| v.split(':').next().map(PathBuf::from)).filter(|p| !p.as_os_str().is_empty())
}

/// Build a pipeline, with the saved state as its prior when there is one.
fn build_pipeline(cfg: &Config, store: Option<&Store>, carry: Option<(crate::estimator::Learned, Option<SavedAxes>)>) -> Pipeline {
    // the config was checked at load; a DBC gone since is an IMU-only run, logged
    let speed = crate::speed::load(cfg).unwrap_or_else(|e| {
        warn!(error = %e, "speed source unusable: IMU only");
        None
    });
    if let Some(d) = &speed {
        info!(message = d.message(), id = format!("{:#x}", d.id().0), "vehicle speed from the bus");
    }
    let mut pipe = Pipeline::with_speed(cfg, speed);
    if let Some((l, axes)) = carry {
        pipe.estimator_mut().set_prior(l);
        // the turned vehicle axes mean something under the same mounting only
        if let Some(yaw) = axes.and_then(|a| a.yaw_for(cfg.mounting.rotation)) {
            pipe.estimator_mut().set_vehicle_axes(yaw);
        }
        return pipe;
    }
    if let Some(store) = store {
        match store.load() {
            Ok(Some(st)) => {
                let p = st.prior(now_unix(), cfg.ekf.bias_walk, 0.0);
                info!(bias = ?p.bias, sigma = ?p.bias_sigma, temp = p.temp, path = %store.path.display(), "loaded learned bias");
                pipe.estimator_mut().set_prior(p);
                match st.axes_for(cfg.mounting.rotation) {
                    Some(yaw) if pipe.estimator_mut().set_vehicle_axes(yaw) => {
                        info!(
                            yaw_deg = yaw,
                            "loaded the vehicle axes the pull-aways turned ([mounting] rotation yaw {:.1} would say so)", -yaw
                        )
                    }
                    None if st.vehicle_axes.is_some() => warn!("saved vehicle axes were found under another [mounting] rotation: not used"),
                    _ => {}
                }
                if let Some(sl) = &st.slope {
                    if pipe.estimator_mut().set_slope_state(sl) {
                        info!(cycles = sl.cycles, spread = sl.spread, "loaded the thermal slope learner");
                    } else {
                        warn!("saved thermal slope learner ignored (learning off, or saved under another p1)");
                    }
                }
            }
            Ok(None) => info!(path = %store.path.display(), "no saved state; starting from the config"),
            Err(e) => warn!("{e}"),
        }
    }
    pipe
}

fn save_state(store: Option<&Store>, pipe: &Pipeline, mounting: [f64; 3]) {
    let (Some(store), Some(l)) = (store, pipe.estimator().learned()) else { return };
    let mut st = State::from_learned(&l, now_unix(), pipe.estimator().slope_state());
    st.vehicle_axes = SavedAxes::of(pipe.estimator(), mounting);
    match store.save(&st) {
        Ok(()) => tracing::debug!(path = %store.path.display(), "state saved"),
        Err(e) => warn!("saving state: {e}"),
    }
}

/// The writer task: frames from the queue onto the current socket.
async fn writer(mut rx: mpsc::Receiver<CanFrame>, mut sock: watch::Receiver<Option<Arc<CanSocket>>>, shell: Arc<ShellCounters>) {
    let mut log = RateLimited::new(Duration::from_secs(5));
    while let Some(f) = rx.recv().await {
        let s = sock.borrow_and_update().clone();
        let Some(s) = s else {
            shell.tx_dropped.fetch_add(1, Ordering::Relaxed);
            continue;
        };
        // Never wait on a full queue: ENOBUFS / EAGAIN drop the frame.
        if let Err(e) = s.try_write_frame(f) {
            shell.tx_dropped.fetch_add(1, Ordering::Relaxed);
            shell.tx_errors.fetch_add(1, Ordering::Relaxed);
            if let Some(sup) = log.due(Instant::now()) {
                warn!(error = %e, suppressed_since_last = sup, "output frame dropped");
            }
        }
    }
}

/// Run the daemon until SIGTERM/SIGINT.
pub fn run(config_path: &Path) -> anyhow::Result<()> {
    let cfg = Config::load(config_path).map_err(|e| anyhow::anyhow!("{e}"))?;
    let rt = tokio::runtime::Builder::new_current_thread().enable_all().build().context("starting the runtime")?;
    rt.block_on(daemon(config_path.to_path_buf(), cfg))
}

async fn daemon(config_path: PathBuf, mut cfg: Config) -> anyhow::Result<()> {
    let mut notifier = Notifier::from_env();
    let mut sigterm = signal(SignalKind::terminate()).context("SIGTERM handler")?;
    let mut sigint = signal(SignalKind::interrupt()).context("SIGINT handler")?;
    let mut sighup = signal(SignalKind::hangup()).context("SIGHUP handler")?;
    let shell = Arc::new(ShellCounters::default());
    let (tx, rx) = mpsc::channel::<CanFrame>(TX_QUEUE);
    let (sock_tx, sock_rx) = watch::channel::<Option<Arc<CanSocket>>>(None);
    tokio::spawn(writer(rx, sock_rx, shell.clone()));

    let mut store = state_dir(&cfg).map(|d| Store::new(&d));
    let mut pipe = build_pipeline(&cfg, store.as_ref(), None);
    let mut rate_warned = false;
    let mut sink = BusSink::new(&tx, &shell);
    let mut backoff = Duration::from_millis(100);
    let mut open_log = RateLimited::new(Duration::from_secs(10));
    let mut err_log = RateLimited::new(Duration::from_secs(10));
    let mut last_sample = Instant::now();
    let mut silent = false;
    let mut last_save = Instant::now();
    let mut last_status = Instant::now() - Duration::from_secs(10);
    let mut silent_status_at = Instant::now();
    let mut tx_dropped_seen = 0u64;
    info!(interface = %cfg.can.interface, mode = cfg.estimator.mode.name(), "gyrocomp starting");

    'outer: loop {
        // (Re)open the bus, with backoff, still answering signals meanwhile.
        let bound = ifindex(&cfg.can.interface);
        let sock = match open_bus(&cfg, pipe.speed_id()) {
            Ok(s) => {
                backoff = Duration::from_millis(100);
                info!(interface = %cfg.can.interface, "bus open");
                Arc::new(s)
            }
            Err(e) => {
                if let Some(sup) = open_log.due(Instant::now()) {
                    warn!(interface = %cfg.can.interface, error = %e, retries_since_last = sup, "cannot open the bus; retrying");
                }
                notifier.status(&format!("waiting for {}: {e}", cfg.can.interface));
                notifier.watchdog_if_due();
                tokio::select! {
                    _ = tokio::time::sleep(backoff) => {}
                    _ = sigterm.recv() => break 'outer,
                    _ = sigint.recv() => break 'outer,
                }
                backoff = (backoff * 2).min(Duration::from_secs(2));
                continue;
            }
        };
        let _ = sock_tx.send(Some(sock.clone()));
        let tick = Duration::from_secs_f64((cfg.daemon.silent_after_s / 2.0).clamp(0.01, 0.25));
        let mut ticker = tokio::time::interval(tick);
        let mut last_if_check = Instant::now();
        ticker.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            tokio::select! {
                biased;
                _ = sigterm.recv() => break 'outer,
                _ = sigint.recv() => break 'outer,
                _ = sighup.recv() => {
                    notifier.reloading();
                    match Config::load(&config_path) {
                        Ok(new) => {
                            let was_speed = pipe.speed_id();
                            let axes = SavedAxes::of(pipe.estimator(), cfg.mounting.rotation);
                            let carry = pipe.estimator().learned().map(|l| (l, axes));
                            let bus_changed = new.can.interface != cfg.can.interface
                                || new.input.ids != cfg.input.ids
                                || input_filters_changed(&new, &cfg)
                                || new.daemon.error_frames != cfg.daemon.error_frames;
                            cfg = new;
                            store = state_dir(&cfg).map(|d| Store::new(&d));
                            pipe = build_pipeline(&cfg, store.as_ref(), carry);
                            // the kernel filters hold the speed message's ID too
                            let reopen = bus_changed || pipe.speed_id() != was_speed;
                            info!(path = %config_path.display(), "config reloaded");
                            notifier.ready();
                            if reopen {
                                let _ = sock_tx.send(None);
                                continue 'outer;
                            }
                        }
                        Err(e) => {
                            error!("reload refused, keeping the running config: {e}");
                            notifier.ready();
                        }
                    }
                }
                r = sock.read_frame() => {
                    // One wake-up, then drain what the kernel already holds (bounded),
                    // so a burst costs one trip through select! rather than one per frame.
                    let mut next = Some(r);
                    let mut n = 0;
                    while let Some(r) = next.take() {
                        match r {
                            Ok(CanFrame::Error(ef)) => {
                                let total = shell.error_frames.fetch_add(1, Ordering::Relaxed) + 1;
                                if let Some(sup) = err_log.due(Instant::now()) {
                                    warn!(error = ?socketcan::CanError::from(ef), total, suppressed_since_last = sup, "CAN error frame");
                                }
                            }
                            Ok(f) => {
                                let n0 = sink.samples;
                                let td = shell.tx_dropped.load(Ordering::Relaxed);
                                pipe.extra_flags = if td != tx_dropped_seen { flags::TX_DROP } else { 0 };
                                pipe.push(now_us(), RawFrame::from_frame(&f), &mut sink);
                                if sink.samples != n0 {
                                    tx_dropped_seen = td;
                                    last_sample = Instant::now();
                                    if silent {
                                        silent = false;
                                        info!("input resumed");
                                    }
                                    if !notifier.ready_sent() {
                                        notifier.ready();
                                    }
                                    // The processing path keeps the watchdog fed.
                                    notifier.watchdog_if_due();
                                }
                            }
                            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => break,
                            Err(e) => {
                                shell.reopens.fetch_add(1, Ordering::Relaxed);
                                warn!(interface = %cfg.can.interface, error = %e, "bus read failed; reopening");
                                let _ = sock_tx.send(None);
                                tokio::time::sleep(backoff).await;
                                backoff = (backoff * 2).min(Duration::from_secs(2));
                                continue 'outer;
                            }
                        }
                        n += 1;
                        if n < RX_BATCH {
                            next = Some(sock.try_read_frame());
                        }
                    }
                }
                _ = ticker.tick() => {
                    let now = Instant::now();
                    if now.duration_since(last_sample).as_secs_f64() > cfg.daemon.silent_after_s {
                        if !silent {
                            silent = true;
                            warn!(after_s = cfg.daemon.silent_after_s, "no input samples: bus silent");
                        }
                        // Say so on the bus, at the silence timeout's pace.
                        if now.duration_since(silent_status_at).as_secs_f64() >= cfg.daemon.silent_after_s {
                            silent_status_at = now;
                            if let Some(est) = sink.last {
                                let frames = encode(&est, &StatusCounters::from(pipe.counters()), &cfg.output, flags::BUS_SILENT);
                                sink.queue(&frames[crate::output::STATUS]);
                            }
                        }
                        // Idle is not stalled: the loop is alive, say so.
                        notifier.watchdog_if_due();
                        // A socket bound to an interface that was deleted (and
                        // perhaps created again) stays silent without an error:
                        // look at the interface's index and reopen if it changed.
                        if now.duration_since(last_if_check) >= Duration::from_secs(1) {
                            last_if_check = now;
                            let idx = ifindex(&cfg.can.interface);
                            if idx != bound {
                                shell.reopens.fetch_add(1, Ordering::Relaxed);
                                warn!(interface = %cfg.can.interface, was = bound, now = idx, "interface vanished or was recreated; reopening");
                                let _ = sock_tx.send(None);
                                continue 'outer;
                            }
                        }
                    }
                    if now.duration_since(last_status) >= Duration::from_secs(1) {
                        last_status = now;
                        notifier.status(&status_line(&sink.last, silent, &pipe, &shell));
                        if !rate_warned {
                            if let Some((c, m)) = pipe.report().rate_mismatch() {
                                rate_warned = true;
                                warn!(configured_hz = c, timestamps_hz = m, "the configured sample rate disagrees with the frame timestamps by more than 1 %; dt comes from [input] rate_hz");
                            }
                        }
                    }
                    if now.duration_since(last_save).as_secs_f64() >= cfg.daemon.save_every_s {
                        last_save = now;
                        save_state(store.as_ref(), &pipe, cfg.mounting.rotation);
                    }
                }
            }
        }
    }
    notifier.stopping();
    save_state(store.as_ref(), &pipe, cfg.mounting.rotation);
    let c = pipe.counters();
    info!(
        samples = c.samples,
        dropped = c.dropped(),
        lost = c.lost,
        tx_dropped = shell.tx_dropped.load(Ordering::Relaxed),
        error_frames = shell.error_frames.load(Ordering::Relaxed),
        "gyrocomp stopped"
    );
    Ok(())
}

fn status_line(last: &Option<Estimate>, silent: bool, pipe: &Pipeline, shell: &ShellCounters) -> String {
    let c = pipe.counters();
    let mode = |m: u8| ["fusion", "aided", "gyro_only"].get(m as usize).copied().unwrap_or("?");
    let r = pipe.report();
    let mut what = String::new();
    if let Some(k) = &r.mekf {
        what = format!(
            "; standstill {:.0} s, re-levels {}, restarts {}, refused {:.0} s, rules acted: {}",
            k.rest_s, k.relevels, k.restarts, k.gated_s, k.rules
        );
        if let Some(a) = &r.aid_now {
            what += &format!("; aid sources now: {a}");
        }
        if let Some(q) = k.rest_never_found() {
            what += &format!(" (none found yet: the quietest deviations were {q})");
        }
        if let Some(sp) = &r.speed {
            what += &format!(", speed used {:.0} s ({} frames, {} dropped)", k.speed_used_s, sp.decoded, sp.dropped());
        }
        if let (Some((yaw, _)), true) = (r.vehicle_axes, k.reaxed > 0) {
            what += &format!(", vehicle axes turned {yaw:.0} deg (the car pulls away along it: [mounting] rotation yaw {:.0})", -yaw);
        }
        what += match r.magnetometer {
            Some(true) => ", magnetometer on",
            Some(false) => ", magnetometer off",
            None => "",
        };
        if let Some(p) = &r.power_on {
            what += &match p.ended {
                None => format!(", power-on speed {:.0} m/s leads (hypotheses running)", p.speed_ms),
                Some((_, why)) => format!(", power-on speed {:.0} m/s kept ({})", p.speed_ms, why.describe()),
            };
        }
    }
    match last {
        None => format!("waiting for samples; dropped {}", c.dropped()),
        Some(e) => format!(
            "{}mode {} rates {:.2} {:.2} {:.2} deg/s bias {:.4} {:.4} {:.4} deg/s; samples {} dropped {} lost {} tx_dropped {}{what}",
            if silent { "BUS SILENT; " } else { "" },
            mode(e.mode),
            e.rate[0],
            e.rate[1],
            e.rate[2],
            e.bias[0],
            e.bias[1],
            e.bias[2],
            c.samples,
            c.dropped(),
            c.lost,
            shell.tx_dropped.load(Ordering::Relaxed)
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rate_limiter_counts_suppressed() {
        let mut r = RateLimited::new(Duration::from_secs(10));
        let t0 = Instant::now();
        assert_eq!(r.due(t0), Some(0));
        assert_eq!(r.due(t0 + Duration::from_secs(1)), None);
        assert_eq!(r.due(t0 + Duration::from_secs(2)), None);
        assert_eq!(r.due(t0 + Duration::from_secs(11)), Some(2));
    }

    #[test]
    fn full_output_queue_drops_and_counts_without_blocking() {
        let est = Estimate::default();
        let frames = encode(&est, &StatusCounters::default(), &crate::config::OutputConfig::default(), 0);
        assert_eq!(frames.len(), 5, "four frames and EST_AID");
        let (tx, _rx) = mpsc::channel::<CanFrame>(frames.len());
        let shell = ShellCounters::default();
        let mut sink = BusSink::new(&tx, &shell);
        sink.output(&est, &frames); // fills the queue
        sink.output(&est, &frames); // nothing reads: all five dropped
        assert_eq!(shell.tx_dropped.load(Ordering::Relaxed), 5);
        assert_eq!(sink.samples, 2);
    }
}
