//! The configuration file: one TOML document, every key optional.
//!
//! Unknown keys are refused (`deny_unknown_fields`), and `validate` refuses
//! bad values with a message that names the key and the line it is on.
//! `config/gyrocomp.toml` is the annotated full example; `gyrocomp
//! check-config FILE` prints the effective configuration ([`Config::to_toml`]).
//!
//! The steps, one file each: `schema.rs` the sections and their defaults,
//! `load.rs` reading and parsing with key-and-line errors and the speed
//! source, `validate/` the checks of every value (a physical range per numeric key, one file per group of sections), `effective.rs` the
//! resolved profile and the printed effective configuration.

pub mod arrays;
pub mod dbcin;
mod effective;
mod load;
mod schema;
mod validate;

pub use load::{locate, ConfigError, Location};
pub use schema::{
    AutoBool, CanConfig, Config, DaemonConfig, EkfConfig, EstimatorConfig, InputConfig, MekfConfig, Mode, MountingConfig, OutputConfig,
    RestConfig, SpeedConfig, SwitchingConfig, ThermalConfig,
};
pub(crate) use validate::num;
/// The ranges of `[input]`'s rate and scales (what `validate` accepts).
pub use validate::{ACCEL_LSB, GYRO_LSB, MAGN_LSB, RATE_HZ, TEMP_LSB};

/// Tests: the error `Config::parse` gives for `text`.
#[cfg(test)]
fn bad(text: &str) -> String {
    Config::parse(text, "t.toml").unwrap_err().to_string()
}
