//! Loading a config: read the file, parse it, validate it, and resolve the
//! speed source (`[speed] dbc` relative to the config's directory, its DBC
//! loaded and its message checked). Every error names the file, and a bad
//! value also the key and where it is written (line, column from the
//! `toml_edit` spans); the parser's type words are put in a user's words.

use super::Config;
use std::path::Path;

#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("cannot read config {path}: {source}")]
    Io { path: String, source: std::io::Error },
    #[error("config {path}: {msg}")]
    Parse { path: String, msg: String },
    /// A value the parser accepted but `validate` refuses; `at` is where
    /// the key is written (None: not in the file, its default is meant).
    #[error("config {path}{}: {key}{}: {msg}", .at.as_ref().map(|a| a.to_string()).unwrap_or_default(), if .at.is_none() { " (not in the file: its default)" } else { "" })]
    Invalid { path: String, key: String, at: Option<Location>, msg: String },
}

/// A place in the config text (1-based).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Location {
    pub line: usize,
    pub column: usize,
}

impl std::fmt::Display for Location {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, ", line {}, column {}", self.line, self.column)
    }
}

/// Where `key` (`table.key`, `table.key[i]`, or a table) is written in `text`.
pub fn locate(text: &str, key: &str) -> Option<Location> {
    let doc = toml_edit::ImDocument::parse(text).ok()?;
    let (path, index) = match key.strip_suffix(']').and_then(|k| k.rsplit_once('[')) {
        Some((k, i)) => (k, i.parse::<usize>().ok()),
        None => (key, None),
    };
    let mut table: &dyn toml_edit::TableLike = doc.as_table();
    let mut span = None;
    let parts: Vec<&str> = path.split('.').collect();
    for (k, part) in parts.iter().enumerate() {
        let (kk, item) = table.get_key_value(part)?;
        span = match item {
            toml_edit::Item::Table(t) if k + 1 < parts.len() || t.span().is_some() => t.span().or_else(|| kk.span()),
            _ => kk.span(),
        };
        if k + 1 < parts.len() {
            table = item.as_table_like()?;
        } else if let Some(i) = index {
            span = item.as_array().and_then(|a| a.get(i)).and_then(|v| v.span()).or(span);
        }
    }
    let at = span?.start;
    let before = &text[..at.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.len() - before.rfind('\n').map(|p| p + 1).unwrap_or(0) + 1;
    Some(Location { line, column })
}

/// The parser's words for types, in a user's words.
fn plain_types(msg: &str) -> String {
    msg.replace("expected f64", "expected a number")
        .replace("expected u32", "expected a whole number >= 0")
        .replace("expected u8", "expected a whole number from 0 to 255")
        .replace("expected i64", "expected a whole number")
        .replace("expected a boolean", "expected true or false")
}

impl Config {
    /// Read, parse and validate a config file.
    pub fn load(path: &Path) -> Result<Config, ConfigError> {
        let p = path.display().to_string();
        let text = crate::textfile::read(path).map_err(|source| ConfigError::Io { path: p.clone(), source })?;
        let mut cfg = Config::parse(&text, &p)?;
        // `speed.dbc` relative to the config file's directory
        if cfg.speed.enabled() && Path::new(&cfg.speed.dbc).is_relative() {
            if let Some(dir) = path.parent() {
                cfg.speed.dbc = dir.join(&cfg.speed.dbc).display().to_string();
            }
        }
        if !cfg.input.format.is_adis() && Path::new(&cfg.input.dbc).is_relative() {
            if let Some(dir) = path.parent() {
                // absolute, so that the printed effective config is valid wherever it is saved
                let p = dir.join(&cfg.input.dbc);
                cfg.input.dbc = std::fs::canonicalize(&p).unwrap_or(p).display().to_string();
            }
        }
        let invalid = |(key, msg): (String, String)| ConfigError::Invalid { path: p.clone(), at: locate(&text, &key), key, msg };
        cfg.load_input_dbc().map_err(invalid)?;
        cfg.check_speed_source().map_err(invalid)?;
        Ok(cfg)
    }

    /// `[input] format = "dbc"`: read `input.dbc` (as it stands: `load` has
    /// made it relative to the config file), resolve the mapping into the
    /// decode plan and keep it; refuse a mapping without the yaw rate and
    /// ax, ay (what the reduced-axis estimator needs when an axis is
    /// missing), a reduced mapping without `EST_AID` (its validity bits), and
    /// a message whose ID is one of gyrocomp's outputs.
    pub fn load_input_dbc(&mut self) -> Result<(), (String, String)> {
        if self.input.format.is_adis() {
            return Ok(());
        }
        let path = &self.input.dbc;
        let text = crate::speed::read_dbc(Path::new(path)).map_err(|e| {
            let why = match e {
                crate::speed::DbcRead::Io(e) => format!("cannot read the DBC: {e}"),
                crate::speed::DbcRead::Text(m) => format!("not a valid DBC: {m}"),
            };
            ("input.dbc".to_string(), format!("{path}: {why}"))
        })?;
        let plan = crate::dbcin::DbcPlan::build(&self.input, &text, path, self.thermal.t0)?;
        let missing = plan.missing_motion();
        let needed: Vec<&str> = missing.iter().copied().filter(|k| ["gyro_z", "accel_x", "accel_y"].contains(k)).collect();
        if !needed.is_empty() {
            return Err((
                "input.signals".into(),
                format!(
                    "{} not mapped: a unit without all six axes needs at least the yaw rate (gyro_z) and the horizontal accelerations (accel_x, accel_y) for the reduced-axis estimator (docs/estimator.md#reduced-axes)",
                    needed.join(", ")
                ),
            ));
        }
        if !missing.is_empty() && !self.output.aid_frame {
            return Err((
                "output.aid_frame".into(),
                format!(
                    "{} not mapped, so some outputs are invalid, and which ones EST_AID says (its Invalid* bits): a reduced-axis unit needs aid_frame = true",
                    missing.join(", ")
                ),
            ));
        }
        for m in plan.msgs.iter().filter(|m| !m.extended) {
            if let Some((k, _)) = self.output.sent().find(|(_, o)| *o == m.id) {
                return Err((
                    "input.signals".into(),
                    format!("{path}: message {} has CAN ID {:#x}, which is {k}, a gyrocomp output", m.name, m.id),
                ));
            }
        }
        self.input.plan = super::dbcin::PlanSlot(Some(std::sync::Arc::new(plan)));
        Ok(())
    }

    /// Load the DBC of `[speed]` (when configured) and check that its
    /// message is not one of the IMU's or gyrocomp's own frames (those sent:
    /// `aid_id` only with `aid_frame` on).
    pub fn check_speed_source(&self) -> Result<(), (String, String)> {
        let Some(dec) = crate::speed::load(self).map_err(|e| ("speed.dbc".to_string(), e.to_string()))? else {
            return Ok(());
        };
        let (id, ext) = dec.id();
        let imu = match &self.input.plan.0 {
            Some(p) => p.find(id, ext).is_some(),
            None => !ext && self.input.format.is_adis() && self.input.ids.all().contains(&id),
        };
        if imu || (!ext && self.output.sent().any(|(_, o)| o == id)) {
            return Err((
                "speed.message".into(),
                format!("{} has CAN ID {id:#x}, which is an IMU input or a gyrocomp output ID", dec.message()),
            ));
        }
        Ok(())
    }

    /// Refuse a DBC input for a command that reads the ADIS contract only.
    pub fn adis_only(&self, command: &str) -> Result<(), String> {
        if self.input.format.is_adis() {
            return Ok(());
        }
        Err(format!(
            "{command} reads the ADIS frames only, so far; this config's [input] is format = \"dbc\" (gyrocomp replay and gyrocomp run read it)"
        ))
    }

    /// Parse and validate config text; `origin` names it in errors.
    pub fn parse(text: &str, origin: &str) -> Result<Config, ConfigError> {
        let cfg: Config = toml::from_str(text).map_err(|e| ConfigError::Parse { path: origin.into(), msg: plain_types(&e.to_string()) })?;
        cfg.validate().map_err(|(key, msg)| ConfigError::Invalid { path: origin.into(), at: locate(text, &key), key, msg })?;
        Ok(cfg)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::bad;

    #[test]
    fn value_errors_give_the_key_and_its_line() {
        let e = bad("# c\n\n[switching]\njerk_ratio = 0.2\ninner = [0.99, 1.3]\n");
        assert!(e.contains("line 5, column 1: switching.inner:"), "{e}");
        // an element of an array on a continuation line
        let e = bad("[thermal]\np1 = [0.0,\n  inf, 0.0]\n");
        assert!(e.contains("line 3, column 3: thermal.p1[1]:"), "{e}");
        // inline tables and dotted keys
        let e = bad("output = { rate_id = 0x900 }\n");
        assert!(e.contains("line 1, column 12: output.rate_id:"), "{e}");
        let e = bad("[input]\nprofile = \"adis16448\"\nids.gyro = 0x101\n");
        assert!(e.contains("line 3, column 1: input.ids:"), "{e}");
        // a default that conflicts with a value in the file is named as such
        let e = bad("[switching]\nouter = [0.99, 1.01]\n");
        assert!(e.contains("switching.inner (not in the file: its default)"), "{e}");
    }

    #[test]
    fn the_speed_belief_keys_have_their_physical_ranges() {
        for (key, v) in [
            ("max_forward_speed", "200.0"),
            ("max_reverse_speed", "-1.0"),
            ("speed_bound_sigma", "0.0"),
            ("accel_noise_quiet", "1e300"),
            ("accel_ref", "nan"),
            ("accel_bias_g", "2.0"),
        ] {
            let e = bad(&format!("[mekf]\n{key} = {v}\n"));
            assert!(e.contains(&format!("mekf.{key}")) && e.contains("line 2"), "{key}: {e}");
        }
        let c = Config::parse("[mekf]\nmax_forward_speed = 0.0\naccel_bias_g = 0.0\n", "t").unwrap();
        assert_eq!((c.mekf.max_forward_speed, c.mekf.accel_bias_g), (0.0, 0.0));
    }

    #[test]
    fn type_errors_read_in_plain_words() {
        let e = bad("[input]\nrate_hz = \"fast\"\n");
        assert!(e.contains("expected a number") && !e.contains("f64"), "{e}");
        assert!(e.contains("line 2"), "{e}");
        let e = bad("[output]\nrate_id = -1\n");
        assert!(!e.contains("u32"), "{e}");
        // a whole number where a real one is wanted is fine
        assert_eq!(Config::parse("[input]\nrate_hz = 100\n", "t").unwrap().input.rate_hz, 100.0);
    }
}
