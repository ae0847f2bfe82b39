//! `gyrocomp simulate --input-dbc CONFIG`: the simulated IMU on the bus in
//! the format a DBC config describes. `imu.log` then carries the DBC
//! frames (and the wheel speeds, as always), `config.toml` that config's
//! `[input]` with the simulation's other sections, and the DBC is copied
//! beside them; the same samples in the ADIS contract at the same rate are
//! written as `adis.log` with `adis.toml`, so that the two input paths can
//! be compared on one truth.

use super::BusSample;
use crate::adis::InputIds;
use crate::config::{Config, InputConfig};
use crate::dbcin::DbcPlan;
use crate::outfile::OutFile;
use std::io::Write;
use std::path::Path;
use std::sync::Arc;

/// The files `--input-dbc` adds (besides the DBC, under its own name).
pub const TWIN_FILES: [&str; 2] = ["adis.log", "adis.toml"];

/// A DBC format to simulate in, from a config file.
#[derive(Clone, Debug)]
pub struct DbcSim {
    pub plan: Arc<DbcPlan>,
    /// The DBC's file name (written beside config.toml) and text.
    pub dbc_name: String,
    pub dbc_text: String,
    /// The config's `[input]`, its `dbc` the file name, as TOML.
    pub input_toml: String,
}

impl DbcSim {
    /// Load the config at `path` (format = "dbc", all six motion axes).
    pub fn load(path: &Path) -> Result<DbcSim, String> {
        let cfg = Config::load(path).map_err(|e| format!("--input-dbc: {e}"))?;
        let plan = match (&cfg.input.plan.0, cfg.input.format.is_adis()) {
            (Some(p), false) => p.clone(),
            _ => return Err(format!("--input-dbc {}: its [input] is not format = \"dbc\"", path.display())),
        };
        let dbc = Path::new(&cfg.input.dbc);
        let dbc_name = dbc.file_name().map(|n| n.to_string_lossy().to_string()).unwrap_or_default();
        let taken = super::FILES.iter().chain(TWIN_FILES.iter()).chain(["vehicle.csv", "car.dbc"].iter());
        if dbc_name.is_empty() || taken.into_iter().any(|f| *f == dbc_name) {
            return Err(format!("--input-dbc: the DBC's file name {dbc_name:?} is one simulate writes itself; rename it"));
        }
        let dbc_text = crate::speed::read_dbc(dbc).map_err(|e| format!("--input-dbc: {}: {e:?}", dbc.display()))?;
        #[derive(serde::Serialize)]
        struct Section<'a> {
            input: &'a InputConfig,
        }
        let mut input = cfg.input.clone();
        input.dbc = dbc_name.clone();
        let text = toml::to_string(&Section { input: &input }).map_err(|e| e.to_string())?;
        // without the ADIS-only keys (profile, [input.ids]), which a DBC input does not read
        let mut input_toml = String::new();
        let mut section = "";
        for l in text.lines() {
            if l.starts_with('[') {
                section = l;
            }
            if section == "[input.ids]" || (section == "[input]" && l.starts_with("profile = ")) {
                continue;
            }
            input_toml += l;
            input_toml += "\n";
        }
        Ok(DbcSim { plan, dbc_name, dbc_text, input_toml })
    }
}

/// One candump -l line of any frame (extended IDs, CAN FD).
fn line(out: &mut impl Write, t_us: u64, id: u32, extended: bool, data: &[u8]) -> std::io::Result<()> {
    let hex: String = data.iter().map(|b| format!("{b:02X}")).collect();
    let ident = if extended { format!("{id:08X}") } else { format!("{id:03X}") };
    let sep = if data.len() > 8 { "##0" } else { "#" };
    writeln!(out, "({}.{:06}) vcan0 {ident}{sep}{hex}", t_us / 1_000_000, t_us % 1_000_000)
}

/// Writes one sample's bus: the DBC frames (and the other frames) into
/// `imu.log`, the ADIS frames into `adis.log`.
pub struct Writer {
    plan: Arc<DbcPlan>,
    pub imu: std::io::BufWriter<OutFile>,
    pub adis: std::io::BufWriter<OutFile>,
    k: u64,
}

impl Writer {
    pub fn new(sim: &DbcSim, imu: OutFile, adis: OutFile) -> Writer {
        Writer { plan: sim.plan.clone(), imu: std::io::BufWriter::new(imu), adis: std::io::BufWriter::new(adis), k: 0 }
    }

    /// The frames of one sample; returns how many were the other frames (wheel speeds).
    pub fn sample(&mut self, s: &BusSample) -> std::io::Result<u64> {
        let ids = InputIds::DEFAULT.all();
        let m = &s.measured;
        let vals = [m.gyro[0], m.gyro[1], m.gyro[2], m.accel[0], m.accel[1], m.accel[2], m.temp];
        let mut others = 0;
        let mut sent = false;
        for f in s.frames() {
            if !ids.contains(&f.id) {
                line(&mut self.imu, f.t_us, f.id, false, &f.data)?;
                others += 1;
                continue;
            }
            line(&mut self.adis, f.t_us, f.id, false, &f.data)?;
            if !sent {
                // the DBC frames back to back (~150 us each), from the sample's first frame's time
                for (i, e) in self.plan.encode(self.k, &vals).iter().enumerate() {
                    line(&mut self.imu, f.t_us + 150 * i as u64, e.id, e.extended, &e.data)?;
                }
                sent = true;
            }
        }
        self.k += 1;
        Ok(others)
    }

    /// Flush both logs and rename them into place.
    pub fn commit(self) -> std::io::Result<()> {
        self.imu.into_inner().map_err(|e| e.into_error())?.commit()?;
        self.adis.into_inner().map_err(|e| e.into_error())?.commit()
    }
}

/// Refuse a DBC message that would collide with the simulated wheel-speed frames.
pub fn check_ids(sim: &DbcSim, wheel_id: Option<u32>) -> Result<(), String> {
    if let Some(w) = wheel_id {
        if let Some(m) = sim.plan.msgs.iter().find(|m| m.matches(w, false)) {
            return Err(format!("--input-dbc: message {} has the ID of the simulated WHEEL_SPEEDS frame ({w:#x})", m.name));
        }
    }
    Ok(())
}
