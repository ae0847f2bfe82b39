//! A simulated thermal-chamber run with known truth, for the tests and demos
//! of the original 90-min procedure (white noise, no bias random walk; the
//! independent generator of the issue-13 tests lives in `tests/calibrate_chamber.rs`).

use crate::adis::RawSample;
use crate::candump::LogWriter;
use crate::config::Config;
use crate::outfile::OutFile;
use crate::thermal::Thermal;
use std::io::{self, Write};
use std::path::Path;

/// A simulated thermal-chamber run with known truth, for tests and demos:
/// a static sensor (specific force (0, 0, -1) g), powered on at the chamber
/// temperature `ambient`, self-heating as `ambient + self_heat (1 - e^(-t/heat_tau_s))`,
/// gyro = `turn_on + curve(T) + warmup_amp e^(-t/warmup_tau_s) + noise`, white
/// noise of density `noise` deg/s/sqrt(Hz) (per-sample sigma `noise sqrt(rate)`),
/// quantised through the profile and written as a candump log.
#[derive(Clone, Debug)]
pub struct ChamberRun {
    pub ambient: f64,
    pub self_heat: f64,
    pub heat_tau_s: f64,
    pub duration_s: f64,
    pub turn_on: [f64; 3],
    pub warmup_amp: [f64; 3],
    pub warmup_tau_s: f64,
    pub noise: f64,
    /// Temperature sensor noise, deg C per sample.
    pub temp_noise: f64,
    /// (start s, duration s, rate deg/s): a rotation about z and back
    /// (the second half at -rate): a run that is not static.
    pub rotation: Option<(f64, f64, f64)>,
    pub seed: u64,
}

impl ChamberRun {
    pub fn new(ambient: f64, seed: u64) -> ChamberRun {
        ChamberRun {
            ambient,
            self_heat: 15.0,
            heat_tau_s: 1200.0,
            duration_s: 5400.0,
            turn_on: [0.0; 3],
            warmup_amp: [0.0; 3],
            warmup_tau_s: 120.0,
            noise: 0.0135,
            temp_noise: 0.02,
            rotation: None,
            seed,
        }
    }

    /// Temperature at `t` s after power-on.
    pub fn temp(&self, t: f64) -> f64 {
        self.ambient + self.self_heat * (1.0 - (-t / self.heat_tau_s).exp())
    }

    /// Write the run as a candump log with the profile and IDs of `cfg`.
    pub fn write<W: Write>(&self, cfg: &Config, curve: &Thermal, out: W) -> io::Result<W> {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let prof = cfg.profile();
        let ids = cfg.input.ids;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(self.seed);
        let n01 = Normal::new(0.0, 1.0).expect("unit normal");
        let sig = self.noise * prof.rate_hz.sqrt();
        let mut w = LogWriter::new(out, &cfg.can.interface);
        let n = (self.duration_s * prof.rate_hz).round() as u64;
        let t_start = 1_700_000_000_000_000u64 + self.seed % 1000 * 1_000_000;
        for k in 0..n {
            let t = k as f64 / prof.rate_hz;
            let temp = self.temp(t);
            let b = curve.bias(temp);
            let mut g = [0.0; 3];
            for i in 0..3 {
                g[i] = self.turn_on[i] + b[i] + self.warmup_amp[i] * (-t / self.warmup_tau_s).exp() + sig * n01.sample(&mut rng);
            }
            if let Some((t0, d, r)) = self.rotation {
                if t >= t0 && t < t0 + d {
                    g[2] += if t < t0 + 0.5 * d { r } else { -r };
                }
            }
            let a = [0.0, 0.0, -1.0].map(|v: f64| v + 0.002 * n01.sample(&mut rng));
            let m = [0.2, 0.0, 0.4];
            let tn = temp + self.temp_noise * n01.sample(&mut rng);
            let mut raw = RawSample::quantise(&prof, g, a, m, tn);
            raw.cnt = (k % 65536) as u16;
            let t_us = t_start + (t * 1e6).round() as u64;
            let fr = raw.encode();
            for (j, id) in ids.all().iter().enumerate() {
                w.frame(t_us + 50 * j as u64, *id, &fr[j])?;
            }
        }
        w.finish()
    }

    /// Write the run to a file (through [`OutFile`]: never half-written).
    pub fn write_file(&self, cfg: &Config, curve: &Thermal, path: &Path) -> io::Result<()> {
        let f = self.write(cfg, curve, OutFile::create(path)?)?;
        f.commit()
    }
}
