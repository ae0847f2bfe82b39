//! What the daemon learned, kept across restarts.
//!
//! One small JSON file under the state directory (systemd `StateDirectory=`),
//! written atomically: a temporary file in the same directory, fsync, rename
//! over the old one, fsync of the directory. The file carries a CRC-32 of its
//! payload, so a torn or corrupted file is detected and ignored with a
//! warning rather than trusted.

use crate::estimator::Learned;
use crate::thermal::SlopeState;
use serde::{Deserialize, Serialize};
use std::fs::{self, File};
use std::io::Write;
use std::path::{Path, PathBuf};

pub const FILE_NAME: &str = "gyrocomp-state.json";
pub const VERSION: u32 = 1;

/// The saved state.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct State {
    pub version: u32,
    /// Bias, deg/s, and its 1-sigma.
    pub bias: [f64; 3],
    pub bias_sigma: [f64; 3],
    /// Temperature at which the bias was held, deg C.
    pub temp: f64,
    /// Wall-clock time of the save, seconds since the Unix epoch.
    pub saved_unix: f64,
    /// The thermal slope learner's sums, when field learning is on.
    #[serde(default)]
    pub slope: Option<SlopeState>,
    /// The vehicle axes the pull-aways turned (a unit mounted turned and
    /// not configured so), with the `[mounting]` they were found under.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vehicle_axes: Option<SavedAxes>,
}

/// The default filter's turned vehicle axes (`Estimator::vehicle_axes_turned`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SavedAxes {
    /// Their turn about the unit's z axis, deg.
    pub yaw_deg: f64,
    /// `[mounting] rotation` when they were found, deg: under another one
    /// they mean nothing.
    pub mounting: [f64; 3],
}

impl SavedAxes {
    /// The estimator's turned axes, if any, found under `mounting`.
    pub fn of(est: &crate::estimator::Estimator, mounting: [f64; 3]) -> Option<SavedAxes> {
        est.vehicle_axes_turned().map(|yaw_deg| SavedAxes { yaw_deg, mounting })
    }

    /// Their turn (deg) if they were found under `mounting`.
    pub fn yaw_for(&self, mounting: [f64; 3]) -> Option<f64> {
        (self.mounting == mounting).then_some(self.yaw_deg)
    }
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Envelope {
    crc32: u32,
    state: String,
}

#[derive(Debug, thiserror::Error)]
pub enum StateError {
    #[error("{0}: {1}")]
    Io(String, std::io::Error),
    #[error("{0}: corrupt state file ({1}); ignored")]
    Corrupt(String, String),
}

impl State {
    pub fn from_learned(l: &Learned, saved_unix: f64, slope: Option<SlopeState>) -> State {
        State { version: VERSION, bias: l.bias, bias_sigma: l.bias_sigma, temp: l.temp, saved_unix, slope, vehicle_axes: None }
    }

    /// The saved vehicle axes if they were found under `mounting`.
    pub fn axes_for(&self, mounting: [f64; 3]) -> Option<f64> {
        self.vehicle_axes.and_then(|a| a.yaw_for(mounting))
    }

    /// The prior for the estimator. The bias sigma grows with the age of the
    /// state (random walk `walk` deg/s/sqrt(s)), and never below `floor`.
    pub fn prior(&self, now_unix: f64, walk: f64, floor: f64) -> Learned {
        let age = (now_unix - self.saved_unix).max(0.0);
        let grow = walk * walk * age;
        Learned { bias: self.bias, bias_sigma: self.bias_sigma.map(|s| (s * s + grow).sqrt().max(floor)), temp: self.temp }
    }

    /// The state file's bytes, as [`Store::save`] writes them: the JSON
    /// envelope (payload and its CRC-32) and a newline.
    pub fn to_file_bytes(&self) -> std::io::Result<Vec<u8>> {
        let payload = serde_json::to_string(self).map_err(std::io::Error::other)?;
        let env = Envelope { crc32: crc32fast::hash(payload.as_bytes()), state: payload };
        let mut bytes = serde_json::to_vec_pretty(&env).map_err(std::io::Error::other)?;
        bytes.push(b'\n');
        Ok(bytes)
    }

    /// A state file's bytes, checked as [`Store::load`] checks them (CRC,
    /// fields, ranges); `name` names the file in errors.
    pub fn from_file_bytes(bytes: &[u8], name: &str) -> Result<State, StateError> {
        let corrupt = |e: String| StateError::Corrupt(name.to_string(), e);
        let env: Envelope = serde_json::from_slice(bytes).map_err(|e| corrupt(e.to_string()))?;
        if crc32fast::hash(env.state.as_bytes()) != env.crc32 {
            return Err(corrupt("CRC mismatch".into()));
        }
        let st: State = serde_json::from_str(&env.state).map_err(|e| corrupt(e.to_string()))?;
        st.valid().map_err(corrupt)?;
        Ok(st)
    }

    fn valid(&self) -> Result<(), String> {
        if self.version != VERSION {
            return Err(format!("version {} (want {VERSION})", self.version));
        }
        let ts = [self.temp, self.saved_unix];
        let all = self.bias.iter().chain(self.bias_sigma.iter()).chain(ts.iter());
        if let Some(a) = &self.vehicle_axes {
            if !(a.yaw_deg.is_finite() && a.yaw_deg.abs() <= 180.0 && a.mounting.iter().all(|v| v.is_finite())) {
                return Err("vehicle axes out of range".into());
            }
        }
        let sl: Vec<f64> = match &self.slope {
            Some(s) => s.base.iter().chain(s.sty.iter()).copied().chain([s.stt, s.spread]).collect(),
            None => Vec::new(),
        };
        for v in all.chain(sl.iter()) {
            if !v.is_finite() {
                return Err("a value is not finite".into());
            }
        }
        if self.bias.iter().any(|b| b.abs() > 50.0) || self.bias_sigma.iter().any(|s| *s < 0.0) {
            return Err("bias out of range".into());
        }
        Ok(())
    }
}

/// Where the state lives.
#[derive(Clone, Debug)]
pub struct Store {
    pub path: PathBuf,
}

impl Store {
    pub fn new(dir: &Path) -> Store {
        Store { path: dir.join(FILE_NAME) }
    }

    /// Load the state. `Ok(None)` when there is none.
    pub fn load(&self) -> Result<Option<State>, StateError> {
        let name = self.path.display().to_string();
        let text = match fs::read(&self.path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(StateError::Io(name, e)),
        };
        State::from_file_bytes(&text, &name).map(Some)
    }

    /// Save atomically: temp file, fsync, rename, fsync the directory.
    pub fn save(&self, st: &State) -> Result<(), StateError> {
        let name = self.path.display().to_string();
        let io = |e| StateError::Io(name.clone(), e);
        let bytes = st.to_file_bytes().map_err(io)?;
        let tmp = self.path.with_extension("json.tmp");
        {
            let mut f = File::create(&tmp).map_err(io)?;
            f.write_all(&bytes).map_err(io)?;
            f.sync_all().map_err(io)?;
        }
        fs::rename(&tmp, &self.path).map_err(io)?;
        if let Some(dir) = self.path.parent() {
            if let Ok(d) = File::open(dir) {
                let _ = d.sync_all();
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn st() -> State {
        State {
            version: VERSION,
            bias: [0.1, -0.2, 0.3],
            bias_sigma: [0.01; 3],
            temp: 33.5,
            saved_unix: 1000.0,
            slope: None,
            vehicle_axes: None,
        }
    }

    #[test]
    fn round_trip_and_missing() {
        let d = tempfile::tempdir().unwrap();
        let s = Store::new(d.path());
        assert!(s.load().unwrap().is_none());
        s.save(&st()).unwrap();
        assert_eq!(s.load().unwrap(), Some(st()));
        assert!(!d.path().join("gyrocomp-state.json.tmp").exists());
        // with the slope learner's sums
        let sl = SlopeState { base: [0.002, 0.0044, 0.0192], stt: 12.5, sty: [0.01, -0.02, 0.03], spread: 7.5, cycles: 2 };
        let with = State { slope: Some(sl), ..st() };
        s.save(&with).unwrap();
        assert_eq!(s.load().unwrap(), Some(with));
        // with turned vehicle axes: kept for the mounting they were found
        // under only
        let axes = State { vehicle_axes: Some(SavedAxes { yaw_deg: -89.8, mounting: [0.0, 0.0, 0.0] }), ..st() };
        s.save(&axes).unwrap();
        let back = s.load().unwrap().unwrap();
        assert_eq!(back, axes);
        assert_eq!(back.axes_for([0.0; 3]), Some(-89.8));
        assert_eq!(back.axes_for([0.0, 0.0, 90.0]), None);
        // a file without them (as written before they existed) loads
        s.save(&st()).unwrap();
        assert!(!fs::read_to_string(&s.path).unwrap().contains("vehicle_axes"));
        assert_eq!(s.load().unwrap().unwrap().axes_for([0.0; 3]), None);
        // out of range: refused as corrupt
        for yaw in [f64::NAN, 400.0] {
            let bad = State { vehicle_axes: Some(SavedAxes { yaw_deg: yaw, mounting: [0.0; 3] }), ..st() };
            assert!(bad.valid().is_err(), "{yaw}");
        }
    }

    #[test]
    fn torn_and_corrupt_files_are_refused() {
        let d = tempfile::tempdir().unwrap();
        let s = Store::new(d.path());
        s.save(&st()).unwrap();
        let good = fs::read(&s.path).unwrap();
        // torn: every truncation is refused
        for cut in [1, good.len() / 3, good.len() / 2, good.len() - 3] {
            fs::write(&s.path, &good[..cut]).unwrap();
            assert!(matches!(s.load(), Err(StateError::Corrupt(..))), "cut {cut}");
        }
        // a changed digit inside the payload: CRC mismatch
        let text = String::from_utf8(good.clone()).unwrap().replacen("0.3", "0.4", 1);
        fs::write(&s.path, text).unwrap();
        let e = s.load().unwrap_err().to_string();
        assert!(e.contains("CRC"), "{e}");
        fs::write(&s.path, b"\x00\xff garbage").unwrap();
        assert!(s.load().is_err());
    }

    #[test]
    fn prior_sigma_grows_with_age() {
        let p = st().prior(1000.0 + 3600.0, 0.001, 0.0);
        assert!((p.bias_sigma[0] - (0.01f64.powi(2) + 1e-6 * 3600.0).sqrt()).abs() < 1e-12);
        assert_eq!(p.bias, st().bias);
    }
}
