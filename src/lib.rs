//! gyrocomp: MEMS gyro bias compensation for ADIS-class IMUs on SocketCAN.
//!
//! The pure core (no I/O, no tokio): [`adis`] decoding, the estimator
//! ([`estimator`] with [`estimator::ekf`] and [`estimator::switching`], [`thermal`]), [`output`] encoding,
//! and the [`pipeline`] that chains them. Around it the I/O shell:
//! [`candump`] log files, [`replay`], and the daemon.

pub mod adis;
pub mod align;
pub mod batches;
pub mod calibrate;
pub mod candump;
pub mod config;
pub mod daemon;
pub mod dbcin;
pub mod estimator;
pub mod evaluate;
pub mod gap;
pub mod import;
pub mod mcapout;
pub mod outfile;
pub mod output;
pub mod peers;
pub mod pipeline;
pub mod reference;
pub mod replay;
pub mod sim;
pub mod speed;
pub mod textfile;
pub mod thermal;
