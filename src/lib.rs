//! gyrocomp: MEMS gyro bias compensation for ADIS-class IMUs on SocketCAN.
//!
//! The pure core (no I/O, no tokio): [`adis`] decoding, the estimator
//! ([`estimator`] with [`estimator::ekf`] and [`estimator::switching`], [`thermal`]), [`output`] encoding,
//! and the [`pipeline`] that chains them. Around it the I/O shell:
//! [`candump`] log files, [`replay`], and the daemon.
//!
//! Feature `cli` (default) builds the binary's parts: the daemon, the
//! offline commands (`align`, `evaluate`, `gap`, `import`, `reference`, `sim`)
//! and their plots. Without it the library is what the Python package binds
//! (with [`gap`] and the [`sim`] model it needs, but no plots).

pub mod adis;
#[cfg(feature = "cli")]
pub mod align;
pub mod batches;
pub mod calibrate;
pub mod candump;
pub mod config;
#[cfg(feature = "cli")]
pub mod daemon;
/// Without `cli`: the daemon's state file only (the Python package reads and writes it).
#[cfg(not(feature = "cli"))]
pub mod daemon {
    pub mod state;
}
pub mod dbcin;
pub mod estimator;
#[cfg(feature = "cli")]
pub mod evaluate;
pub mod gap;
#[cfg(feature = "cli")]
pub mod import;
pub mod mcapout;
pub mod outfile;
pub mod output;
pub mod peers;
pub mod pipeline;
#[cfg(feature = "cli")]
pub mod reference;
/// Without `cli`: the reference CSV reader only (`gap` derives a truth from it).
#[cfg(not(feature = "cli"))]
pub mod reference {
    pub mod refcsv;
}
pub mod replay;
pub mod sim;
pub mod speed;
pub mod textfile;
pub mod thermal;
