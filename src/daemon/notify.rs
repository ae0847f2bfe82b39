//! systemd notification: READY, STATUS, WATCHDOG, RELOADING, STOPPING.
//! Without `NOTIFY_SOCKET` (not under systemd) every call is a no-op.

use sd_notify::NotifyState;
use std::time::{Duration, Instant};

pub struct Notifier {
    enabled: bool,
    /// Half of WATCHDOG_USEC, when the watchdog is on.
    watchdog_every: Option<Duration>,
    last_ping: Instant,
    ready: bool,
}

impl Notifier {
    pub fn from_env() -> Notifier {
        let enabled = std::env::var_os("NOTIFY_SOCKET").is_some();
        let mut usec = 0u64;
        let watchdog_every =
            if enabled && sd_notify::watchdog_enabled(false, &mut usec) && usec > 0 { Some(Duration::from_micros(usec / 2)) } else { None };
        if let Some(w) = watchdog_every {
            tracing::info!(every_ms = w.as_millis() as u64, "systemd watchdog on");
        }
        Notifier { enabled, watchdog_every, last_ping: Instant::now(), ready: false }
    }

    fn send(&self, s: &[NotifyState]) {
        if self.enabled {
            if let Err(e) = sd_notify::notify(false, s) {
                tracing::warn!(error = %e, "sd_notify failed");
            }
        }
    }

    pub fn ready_sent(&self) -> bool {
        self.ready
    }

    /// READY=1: the bus is open and the first sample is out.
    pub fn ready(&mut self) {
        self.ready = true;
        self.send(&[NotifyState::Ready]);
    }

    pub fn reloading(&self) {
        self.send(&[NotifyState::Reloading]);
    }

    pub fn stopping(&self) {
        self.send(&[NotifyState::Stopping]);
    }

    pub fn status(&self, s: &str) {
        self.send(&[NotifyState::Status(s)]);
    }

    /// WATCHDOG=1 if half the watchdog period has passed since the last one.
    pub fn watchdog_if_due(&mut self) {
        if let Some(every) = self.watchdog_every {
            if self.last_ping.elapsed() >= every {
                self.last_ping = Instant::now();
                self.send(&[NotifyState::Watchdog]);
            }
        }
    }
}
