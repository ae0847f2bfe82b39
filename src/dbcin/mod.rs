//! Any CAN IMU described by its DBC file (`[input] format = "dbc"`).
//!
//! At config load, [`DbcPlan::build`] reads the DBC with `can-dbc`, finds
//! every mapped signal, counter, validity signal and CRC, and keeps per
//! message a list of extractors ([`extract::Extractor`]: byte window,
//! shift, width, signedness) with each channel's scale already folded into
//! one factor and one offset in gyrocomp's units (deg/s, g, deg C), the
//! sign flip included. [`DbcAssembler`] then turns frames into
//! [`crate::adis::Sample`]s: matching a frame is a compare per message
//! (J1939: on PGN and source address), decoding a few shifts and one
//! multiply-add per signal; nothing is allocated or looked up by name per
//! frame. Drops are counted by the same causes as the ADIS path.
//!
//! Pure: the DBC file is read once, by the caller of [`DbcPlan::build`].

mod assemble;
mod encode;
pub mod extract;
mod plan;

pub use assemble::DbcAssembler;
pub use encode::Encoded;
pub use plan::{Assembly, Channel, Crc, DbcPlan, MsgPlan, MAX_MESSAGES};

/// Standard gravity, m/s^2 per g.
pub const G0: f64 = 9.80665;

/// Which channels a plan measures, one bit per [`crate::config::dbcin::CHANNELS`] entry.
pub type Measured = u8;

/// Bits of the six motion channels (gyro x..z, accel x..z).
pub const MOTION: Measured = 0b0011_1111;

#[cfg(test)]
mod tests;
