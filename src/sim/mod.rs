//! `gyrocomp simulate`: truth motion, a sensor error model, and the ADIS log
//! the sensor would have put on the bus.
//!
//! Output directory:
//! - `imu.log`: candump -l, the ADIS contract, quantised to the profile's LSBs;
//! - `truth.csv`: `t,roll,pitch,yaw,p,q,r,fx,fy,fz,temp` (s, deg, deg/s, g, deg C);
//! - `sensor.toml`: the sensor error parameters actually drawn ([`model`]);
//! - `bias.csv`: `t,bx,by,bz`, the true additive gyro bias (deg/s) including
//!   its random walk (what a perfect bias estimator would output);
//! - `scenario.toml`: name, seed, duration, the start of the manoeuvres;
//! - `config.toml`: a gyrocomp config for this unit whose thermal curve is the
//!   drawn linear slope with a per-axis error (a chamber calibration known to
//!   +-`thermal_error`).
//!
//! Determinism: everything is drawn from `ChaCha8Rng::seed_from_u64(seed)`
//! on separate streams (motion, sensor, noise, calibration), so the same
//! seed and options give byte-identical files.

pub mod cli;
pub mod model;
pub mod motion;
pub mod scenario;

use crate::adis::{builtin_profile, InputIds, Profile, RawSample};
use crate::candump::LogWriter;
use model::{
    Effect, GSensitivity, GyroInput, GyroModel, Misalignment, ScaleFactor, SensorModel, ThermalLinear, ThermalQuadratic, ThermalRate,
    TimeDelay, TurnOnBias, VibrationModel, WarmupTransient,
};
use motion::{c_nb, to_body, MotionSpec, Truth, TruthGen};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use scenario::{sym, uni, Ranges, TABLE1_P1};
use serde::{Deserialize, Serialize};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// Time of the first frame in the log, s since the epoch.
pub const LOG_EPOCH_S: u64 = 1_700_000_000;

/// Options of one simulation.
#[derive(Clone, Debug)]
pub struct SimOptions {
    pub scenario: String,
    pub seed: u64,
    pub hard: bool,
    /// Seconds; None = the scenario's default.
    pub duration: Option<f64>,
    /// Part profile name.
    pub profile: String,
    /// Force this sensor model instead of drawing one.
    pub model: Option<SensorModel>,
    /// Ranges overrides (TOML text).
    pub ranges: Option<String>,
    /// Relative error of the thermal slope written to `config.toml`.
    pub thermal_error: f64,
}

impl SimOptions {
    pub fn new(scenario: &str, seed: u64) -> SimOptions {
        SimOptions {
            scenario: scenario.into(),
            seed,
            hard: false,
            duration: None,
            profile: "adis16448".into(),
            model: None,
            ranges: None,
            thermal_error: 0.05,
        }
    }
}

/// `scenario.toml`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScenarioInfo {
    pub scenario: String,
    pub seed: u64,
    pub hard: bool,
    pub duration_s: f64,
    pub rate_hz: f64,
    pub profile: String,
    /// Start of the manoeuvres (the oracle floor's window starts here), s.
    pub manoeuvre_start_s: f64,
    /// Relative error of the thermal slope in `config.toml`.
    pub thermal_error: f64,
}

fn stream(seed: u64, s: u64) -> ChaCha8Rng {
    let mut r = ChaCha8Rng::seed_from_u64(seed);
    r.set_stream(s);
    r
}

/// Draw a sensor model from the ranges.
pub fn draw_model(rng: &mut ChaCha8Rng, r: &Ranges) -> SensorModel {
    let v3 = |rng: &mut ChaCha8Rng, m: f64| [sym(rng, m), sym(rng, m), sym(rng, m)];
    let m33 = |rng: &mut ChaCha8Rng, m: f64, diag: bool| {
        let mut a = [[0.0; 3]; 3];
        for (i, row) in a.iter_mut().enumerate() {
            for (j, x) in row.iter_mut().enumerate() {
                if diag || i != j {
                    *x = sym(rng, m);
                }
            }
        }
        a
    };
    // Every coefficient is drawn whether or not its effect is on, so that
    // switching one effect off does not change the others' values.
    let turn_on = TurnOnBias { bias: v3(rng, r.turn_on_bias) };
    let mut p1 = [0.0; 3];
    for (k, p) in p1.iter_mut().enumerate() {
        let s = if rng.gen_bool(0.5) { 1.0 } else { -1.0 };
        *p = s * TABLE1_P1[k] * uni(rng, r.thermal_linear_factor);
    }
    let lin = ThermalLinear { t0: r.thermal_t0, p1 };
    let quad = ThermalQuadratic { t0: r.thermal_t0, p2: v3(rng, r.thermal_quadratic) };
    let trate = ThermalRate { k: v3(rng, r.thermal_rate) };
    let warm = WarmupTransient { amplitude: v3(rng, r.warmup_amplitude), tau_s: uni(rng, r.warmup_tau_s) };
    let gs = GSensitivity { g: m33(rng, r.g_sensitivity, true) };
    let sf = ScaleFactor { k: v3(rng, r.scale_factor) };
    let mis = Misalignment { m: m33(rng, r.misalignment, false) };
    let td = TimeDelay { delay_s: uni(rng, r.time_delay_s) };
    let on = |e: Effect| r.effects.contains(&e);
    let gyro = GyroModel {
        effects: Effect::ALL.iter().copied().filter(|e| on(*e)).collect(),
        turn_on_bias: on(Effect::TurnOnBias).then_some(turn_on),
        thermal_linear: on(Effect::ThermalLinear).then_some(lin),
        thermal_quadratic: on(Effect::ThermalQuadratic).then_some(quad),
        thermal_rate: on(Effect::ThermalRate).then_some(trate),
        warmup_transient: on(Effect::WarmupTransient).then_some(warm),
        g_sensitivity: on(Effect::GSensitivity).then_some(gs),
        scale_factor: on(Effect::ScaleFactor).then_some(sf),
        misalignment: on(Effect::Misalignment).then_some(mis),
        time_delay: on(Effect::TimeDelay).then_some(td),
    };
    let accel = model::AccelModel { bias: v3(rng, r.accel_bias) };
    let magn = model::MagnModel { bias: v3(rng, r.magn_bias), ..Default::default() };
    let vz = uni(rng, r.vibration_g);
    let vibration = VibrationModel {
        enabled: vz > 0.0,
        amplitude: [0.5 * vz, 0.5 * vz, vz],
        freq_hz: [uni(rng, [22.0, 35.0]), uni(rng, [50.0, 70.0])],
    };
    SensorModel { gyro, accel, magn, noise: r.noise.clone(), vibration }
}

/// Vibration specific force at `t`, g (two tones per axis, fixed phases).
pub fn vibration(v: &VibrationModel, t: f64) -> [f64; 3] {
    if !v.enabled {
        return [0.0; 3];
    }
    let mut out = [0.0; 3];
    for (k, o) in out.iter_mut().enumerate() {
        for (j, f) in v.freq_hz.iter().enumerate() {
            let ph = 2.1 * k as f64 + 0.7 * j as f64;
            *o += v.amplitude[k] * (2.0 * std::f64::consts::PI * f * t + ph).sin();
        }
    }
    out
}

/// Stochastic state of one sensor (bias random walk, noise streams).
pub struct Sensor<'a> {
    pub model: &'a SensorModel,
    rng: ChaCha8Rng,
    walk: [f64; 3],
    prev_rate: Option<[f64; 3]>,
    dt: f64,
    gyro_sigma: f64,
    accel_sigma: f64,
    walk_sigma: f64,
}

/// What the sensor measured (physical units) and the true additive bias.
#[derive(Clone, Copy, Debug, Default)]
pub struct Measured {
    pub gyro: [f64; 3],
    pub accel: [f64; 3],
    pub magn: [f64; 3],
    pub temp: f64,
    /// True additive gyro bias (deterministic part + random walk), deg/s.
    pub bias: [f64; 3],
}

impl<'a> Sensor<'a> {
    pub fn new(model: &'a SensorModel, rate_hz: f64, rng: ChaCha8Rng) -> Sensor<'a> {
        let dt = 1.0 / rate_hz;
        let bw = (rate_hz / 2.0).sqrt();
        let n = &model.noise;
        Sensor {
            model,
            rng,
            walk: [0.0; 3],
            prev_rate: None,
            dt,
            gyro_sigma: n.gyro_white * bw,
            accel_sigma: n.accel_white * bw,
            walk_sigma: n.gyro_bias_walk * dt.sqrt(),
        }
    }

    fn n(&mut self) -> f64 {
        self.rng.sample::<f64, _>(StandardNormal)
    }

    /// Measure the truth at one sample (the truth of consecutive samples in order).
    pub fn measure(&mut self, tr: &Truth) -> Measured {
        let m = self.model;
        let vib = vibration(&m.vibration, tr.t);
        let f = [tr.f[0] + vib[0], tr.f[1] + vib[1], tr.f[2] + vib[2]];
        let rate_dot = match self.prev_rate {
            Some(p) => [(tr.rate[0] - p[0]) / self.dt, (tr.rate[1] - p[1]) / self.dt, (tr.rate[2] - p[2]) / self.dt],
            None => [0.0; 3],
        };
        self.prev_rate = Some(tr.rate);
        let x = GyroInput { rate: tr.rate, rate_dot, f, temp: tr.temp, temp_rate: tr.temp_rate, t_on: tr.t };
        let det = m.gyro.measure(&x);
        let det_bias = m.gyro.bias(&x);
        let mut out = Measured::default();
        for k in 0..3 {
            if tr.t > 0.0 {
                let w = self.n();
                self.walk[k] += self.walk_sigma * w;
            }
            let e = self.n();
            out.gyro[k] = det[k] + self.walk[k] + self.gyro_sigma * e;
            out.bias[k] = det_bias[k] + self.walk[k];
            let e = self.n();
            out.accel[k] = f[k] + m.accel.bias[k] + self.accel_sigma * e;
        }
        let c = c_nb(tr.roll.to_radians(), tr.pitch.to_radians(), tr.yaw.to_radians());
        let mb = to_body(&c, &m.magn.field_ned);
        for k in 0..3 {
            let e = self.n();
            out.magn[k] = mb[k] + m.magn.bias[k] + m.noise.magn_white * e;
        }
        let e = self.n();
        out.temp = tr.temp + m.noise.temp_white * e;
        out
    }
}

/// Everything a simulation produces, in memory (for tests and evaluate).
pub struct SimRun {
    pub info: ScenarioInfo,
    pub spec: MotionSpec,
    pub model: SensorModel,
    pub profile: Profile,
    /// gyrocomp config text with the (perturbed) thermal curve.
    pub config_toml: String,
}

/// Prepare a run: draw the motion, the sensor and the calibration.
pub fn prepare(o: &SimOptions) -> Result<SimRun, String> {
    let profile = builtin_profile(&o.profile).ok_or_else(|| format!("unknown profile {:?}", o.profile))?;
    if !scenario::SCENARIOS.contains(&o.scenario.as_str()) {
        return Err(format!("unknown scenario {:?} (known: {})", o.scenario, scenario::SCENARIOS.join(", ")));
    }
    let ranges = match &o.ranges {
        Some(t) => Ranges::with_overrides(&o.scenario, t)?,
        None => Ranges::for_scenario(&o.scenario),
    };
    let duration = o.duration.unwrap_or_else(|| scenario::default_duration(&o.scenario));
    if !(duration.is_finite() && duration > 0.0) {
        return Err(format!("--duration must be > 0, got {duration}"));
    }
    if !(o.thermal_error.is_finite() && o.thermal_error >= 0.0) {
        return Err(format!("--thermal-error must be >= 0, got {}", o.thermal_error));
    }
    let spec = scenario::motion(&o.scenario, o.hard, duration, &mut stream(o.seed, 1), &ranges)?;
    let model = match &o.model {
        Some(m) => m.clone(),
        None => draw_model(&mut stream(o.seed, 2), &ranges),
    };
    model.validate().map_err(|(k, m)| format!("sensor model: {k}: {m}"))?;
    // The unit's calibration: the linear slope (or 0 without that effect),
    // each axis off by a factor uniform in 1 +- thermal_error.
    let mut cal = stream(o.seed, 4);
    let (t0, p1) = match &model.gyro.thermal_linear {
        Some(l) if model.gyro.has(Effect::ThermalLinear) => (l.t0, l.p1),
        _ => (25.0, [0.0; 3]),
    };
    let p1c: Vec<String> = p1.iter().map(|p| format!("{:.7}", p * (1.0 + sym(&mut cal, o.thermal_error)))).collect();
    let config_toml = format!(
        "# gyrocomp config for simulated unit {} seed {}: thermal slope known to +-{} %.\n[input]\nprofile = \"{}\"\n\n[thermal]\nt0 = {:.3}\np1 = [{}]\np2 = [0.0, 0.0, 0.0]\n",
        o.scenario,
        o.seed,
        o.thermal_error * 100.0,
        o.profile,
        t0,
        p1c.join(", ")
    );
    let info = ScenarioInfo {
        scenario: o.scenario.clone(),
        seed: o.seed,
        hard: o.hard,
        duration_s: duration,
        rate_hz: profile.rate_hz,
        profile: o.profile.clone(),
        manoeuvre_start_s: spec.manoeuvre_start,
        thermal_error: o.thermal_error,
    };
    Ok(SimRun { info, spec, model, profile, config_toml })
}

/// Streams `(truth, measured, raw sample)` for a prepared run.
pub fn samples(run: &SimRun, seed: u64) -> impl Iterator<Item = (Truth, Measured, RawSample)> + '_ {
    let mut sensor = Sensor::new(&run.model, run.profile.rate_hz, stream(seed, 3));
    let p = &run.profile;
    TruthGen::new(&run.spec, p.rate_hz).enumerate().map(move |(k, tr)| {
        let m = sensor.measure(&tr);
        let mut raw = RawSample::quantise(p, m.gyro, m.accel, if p.magnetometer { m.magn } else { [0.0; 3] }, m.temp);
        raw.cnt = k as u16;
        (tr, m, raw)
    })
}

pub const TRUTH_HEADER: &str = "t,roll,pitch,yaw,p,q,r,fx,fy,fz,temp\n";

/// Append one truth.csv row.
pub fn write_truth_row(out: &mut impl Write, tr: &Truth) -> std::io::Result<()> {
    writeln!(
        out,
        "{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.7},{:.7},{:.7},{:.4}",
        tr.t, tr.roll, tr.pitch, tr.yaw, tr.rate[0], tr.rate[1], tr.rate[2], tr.f[0], tr.f[1], tr.f[2], tr.temp
    )
}

/// The files a simulation wrote.
#[derive(Clone, Debug)]
pub struct SimFiles {
    pub dir: PathBuf,
    pub samples: u64,
    pub info: ScenarioInfo,
}

fn io_err(p: &Path) -> impl Fn(std::io::Error) -> String + '_ {
    move |e| format!("{}: {e}", p.display())
}

/// Run a simulation and write its files into `dir` (created if needed).
pub fn simulate(o: &SimOptions, dir: &Path) -> Result<SimFiles, String> {
    let run = prepare(o)?;
    std::fs::create_dir_all(dir).map_err(io_err(dir))?;
    let create = |name: &str| -> Result<(PathBuf, BufWriter<File>), String> {
        let p = dir.join(name);
        let f = File::create(&p).map_err(io_err(&p))?;
        Ok((p, BufWriter::with_capacity(1 << 20, f)))
    };
    let (log_p, log_f) = create("imu.log")?;
    let (truth_p, mut truth) = create("truth.csv")?;
    let (bias_p, mut bias) = create("bias.csv")?;
    let mut log = LogWriter::new(log_f, "vcan0");
    truth.write_all(TRUTH_HEADER.as_bytes()).map_err(io_err(&truth_p))?;
    bias.write_all(b"t,bx,by,bz\n").map_err(io_err(&bias_p))?;
    let ids = InputIds::DEFAULT.all();
    let mut n = 0u64;
    for (tr, m, raw) in samples(&run, o.seed) {
        let t_us = LOG_EPOCH_S * 1_000_000 + (tr.t * 1e6).round() as u64;
        for (i, d) in raw.encode().iter().enumerate() {
            // four frames back to back (~120 us each at 1 Mbit/s)
            log.frame(t_us + 120 * i as u64, ids[i], d).map_err(io_err(&log_p))?;
        }
        write_truth_row(&mut truth, &tr).map_err(io_err(&truth_p))?;
        writeln!(bias, "{:.6},{:.7},{:.7},{:.7}", tr.t, m.bias[0], m.bias[1], m.bias[2]).map_err(io_err(&bias_p))?;
        n += 1;
    }
    log.finish().map_err(io_err(&log_p))?.flush().map_err(io_err(&log_p))?;
    truth.flush().map_err(io_err(&truth_p))?;
    bias.flush().map_err(io_err(&bias_p))?;
    let write = |name: &str, text: &str| -> Result<(), String> {
        let p = dir.join(name);
        std::fs::write(&p, text).map_err(io_err(&p))
    };
    write("sensor.toml", &run.model.to_toml())?;
    write("scenario.toml", &toml::to_string(&run.info).map_err(|e| e.to_string())?)?;
    write("config.toml", &run.config_toml)?;
    Ok(SimFiles { dir: dir.to_path_buf(), samples: n, info: run.info })
}

/// One row of truth.csv.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TruthRow {
    pub t: f64,
    pub att: [f64; 3],
    pub rate: [f64; 3],
    pub f: [f64; 3],
    pub temp: f64,
}

fn parse_floats<const N: usize>(line: &str, path: &Path, no: usize) -> Result<[f64; N], String> {
    let mut out = [0.0; N];
    let mut it = line.split(',');
    for o in out.iter_mut() {
        let s = it.next().ok_or_else(|| format!("{}:{no}: want {N} columns", path.display()))?;
        *o = s.trim().parse().map_err(|_| format!("{}:{no}: bad number {s:?}", path.display()))?;
    }
    if it.next().is_some() {
        return Err(format!("{}:{no}: want {N} columns", path.display()));
    }
    Ok(out)
}

/// Read truth.csv.
pub fn read_truth(path: &Path) -> Result<Vec<TruthRow>, String> {
    let text = std::fs::read_to_string(path).map_err(io_err(path))?;
    let mut lines = text.lines();
    if lines.next().map(|h| h.trim()) != Some(TRUTH_HEADER.trim()) {
        return Err(format!("{}: header must be {}", path.display(), TRUTH_HEADER.trim()));
    }
    lines
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, l)| {
            let v = parse_floats::<11>(l, path, i + 2)?;
            Ok(TruthRow { t: v[0], att: [v[1], v[2], v[3]], rate: [v[4], v[5], v[6]], f: [v[7], v[8], v[9]], temp: v[10] })
        })
        .collect()
}

/// Read bias.csv: `(t, [bx, by, bz])`.
pub fn read_bias(path: &Path) -> Result<Vec<(f64, [f64; 3])>, String> {
    let text = std::fs::read_to_string(path).map_err(io_err(path))?;
    text.lines()
        .enumerate()
        .skip(1)
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, l)| parse_floats::<4>(l, path, i + 1).map(|v| (v[0], [v[1], v[2], v[3]])))
        .collect()
}

/// Read scenario.toml.
pub fn read_info(path: &Path) -> Result<ScenarioInfo, String> {
    let text = std::fs::read_to_string(path).map_err(io_err(path))?;
    toml::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))
}
