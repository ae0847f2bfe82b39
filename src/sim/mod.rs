//! `gyrocomp simulate`: truth motion, a sensor error model, and the ADIS log
//! the sensor would have put on the bus.
//!
//! Output directory:
//! - `imu.log`: candump -l, the ADIS contract, quantised to the profile's LSBs;
//! - `imu.log` also carries the car's `WHEEL_SPEEDS` frames in the `urban`
//!   scenario ([`wheel`]), interleaved by timestamp, and `car.dbc` describes them;
//! - `truth.csv`: `t,roll,pitch,yaw,p,q,r,fx,fy,fz,temp` (s, deg, deg/s, g, deg C),
//!   the vehicle's attitude and rates (vehicle frame) and the specific force
//!   at the sensor position (vehicle axes; with the urban road vibration);
//! - `vehicle.csv` (urban): `t,speed,a_long,a_lat,dist,grade` (m/s of the
//!   rear-axle centre, negative reversing; g; g; m; deg);
//! - `sensor.toml`: the sensor error parameters actually drawn ([`model`]);
//! - `bias.csv`: `t,bx,by,bz`, the true additive gyro bias (deg/s) including
//!   its random walk (what a perfect bias estimator would output);
//! - `scenario.toml`: name, seed, duration, the start of the manoeuvres, the
//!   mounting, and (urban) the wheel-speed source drawn and the drive's
//!   statistics ([`stats`]);
//! - `config.toml`: a gyrocomp config for this unit whose thermal curve is the
//!   drawn linear slope with a per-axis error (a chamber calibration known to
//!   +-`thermal_error`); `[mounting]` (urban, or with a mounting rotation);
//!   `[speed]` only when asked (`SimOptions::speed`), so that one run can be
//!   evaluated with and without the wheel speeds.
//!
//! Determinism: everything is drawn from `ChaCha8Rng::seed_from_u64(seed)`
//! on separate streams (motion, sensor, noise, calibration), so the same
//! seed and options give byte-identical files.

#[cfg(feature = "cli")]
pub mod cli;
pub mod dbcout;
pub mod model;
pub mod motion;
pub mod road;
pub mod scenario;
pub mod smooth;
pub mod stats;
pub mod urban;
pub mod wheel;

use crate::adis::{builtin_profile, InputIds, Profile, RawSample};
use crate::candump::LogWriter;
use crate::outfile::OutFile;
use model::{
    Effect, GSensitivity, GyroInput, GyroModel, Misalignment, ScaleFactor, SensorModel, ThermalLinear, ThermalQuadratic, ThermalRate,
    TimeDelay, TurnOnBias, VibrationModel, WarmupTransient,
};
use motion::{c_nb, to_body, to_ned, MotionSpec, Truth, TruthGen};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use scenario::{sym, uni, MotionOptions, Ranges, TABLE1_P1};
use serde::{Deserialize, Serialize};
use stats::{DriveStats, StatsAcc};
use std::io::Write;
use std::path::{Path, PathBuf};
use wheel::{WheelBus, WheelParams};

/// The files `simulate` writes into its directory.
pub const FILES: [&str; 6] = ["imu.log", "truth.csv", "sensor.toml", "bias.csv", "scenario.toml", "config.toml"];

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
    /// Start while already driving (paper, vehicle, urban).
    pub power_on_moving: bool,
    /// The sensor frame in the vehicle frame, Z-Y-X `[roll, pitch, yaw]`, deg.
    pub mounting: Option<[f64; 3]>,
    /// Write a `[speed]` section (the wheel speeds of `car.dbc`) into `config.toml`.
    pub speed: bool,
    /// Put the IMU on the bus in this DBC format (at its rate), with the ADIS twin beside it.
    pub input_dbc: Option<std::sync::Arc<dbcout::DbcSim>>,
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
            power_on_moving: false,
            mounting: None,
            speed: false,
            input_dbc: None,
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
    /// The run started while the car was driving.
    #[serde(default, skip_serializing_if = "is_false")]
    pub power_on_moving: bool,
    /// The sensor frame in the vehicle frame, Z-Y-X `[roll, pitch, yaw]`, deg.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mounting: Option<[f64; 3]>,
    /// Sensor position from the rear-axle centre, vehicle axes, m (urban).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lever_arm: Option<[f64; 3]>,
    /// The wheel-speed source drawn for this run (urban).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wheel_speeds: Option<WheelParams>,
    /// The drive's statistics (urban).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stats: Option<DriveStats>,
}

fn is_false(b: &bool) -> bool {
    !*b
}

/// Rotation matrix of the sensor frame in the vehicle frame (maps sensor
/// vectors to vehicle vectors) from Z-Y-X `[roll, pitch, yaw]` in deg.
pub fn mounting_matrix(rpy_deg: [f64; 3]) -> [[f64; 3]; 3] {
    c_nb(rpy_deg[0].to_radians(), rpy_deg[1].to_radians(), rpy_deg[2].to_radians())
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
    /// Sensor frame in the vehicle frame (None: aligned).
    mount: Option<[[f64; 3]; 3]>,
}

/// What the sensor measured (physical units) and the true additive bias.
#[derive(Clone, Copy, Debug, Default)]
pub struct Measured {
    pub gyro: [f64; 3],
    pub accel: [f64; 3],
    pub magn: [f64; 3],
    pub temp: f64,
    /// True additive gyro bias (deterministic part + random walk), deg/s,
    /// in the vehicle frame (the sensor-frame bias rotated by the mounting).
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
            mount: None,
        }
    }

    /// Mount the sensor rotated in the vehicle: `rpy_deg` is the sensor frame
    /// in the vehicle frame (Z-Y-X, deg). Its samples are then in the sensor
    /// frame; the truth stays in the vehicle frame.
    pub fn with_mounting(mut self, rpy_deg: Option<[f64; 3]>) -> Sensor<'a> {
        self.mount = rpy_deg.filter(|m| *m != [0.0; 3]).map(mounting_matrix);
        self
    }

    fn n(&mut self) -> f64 {
        self.rng.sample::<f64, _>(StandardNormal)
    }

    /// Measure the truth at one sample (the truth of consecutive samples in order).
    pub fn measure(&mut self, tr: &Truth) -> Measured {
        let m = self.model;
        let vib = vibration(&m.vibration, tr.t);
        let mut f = [tr.f[0] + vib[0], tr.f[1] + vib[1], tr.f[2] + vib[2]];
        let mut rate = tr.rate;
        if let Some(r) = &self.mount {
            f = to_body(r, &f);
            rate = to_body(r, &rate);
        }
        let rate_dot = match self.prev_rate {
            Some(p) => [(rate[0] - p[0]) / self.dt, (rate[1] - p[1]) / self.dt, (rate[2] - p[2]) / self.dt],
            None => [0.0; 3],
        };
        self.prev_rate = Some(rate);
        let x = GyroInput { rate, rate_dot, f, temp: tr.temp, temp_rate: tr.temp_rate, t_on: tr.t };
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
        let mut mb = to_body(&c, &m.magn.field_ned);
        if let Some(r) = &self.mount {
            mb = to_body(r, &mb);
            out.bias = to_ned(r, &out.bias);
        }
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
    /// The wheel-speed source (urban).
    pub wheel: Option<WheelParams>,
    /// `--input-dbc`: the config of `adis.log`, the same unit in the ADIS contract.
    pub adis_twin: Option<String>,
}

/// Prepare a run: draw the motion, the sensor and the calibration.
pub fn prepare(o: &SimOptions) -> Result<SimRun, String> {
    let mut profile = builtin_profile(&o.profile).ok_or_else(|| format!("unknown profile {:?}", o.profile))?;
    if let Some(d) = &o.input_dbc {
        profile.rate_hz = d.plan.rate_hz;
    }
    if !scenario::SCENARIOS.contains(&o.scenario.as_str()) {
        return Err(format!("unknown scenario {:?} (known: {})", o.scenario, scenario::SCENARIOS.join(", ")));
    }
    let ranges = match &o.ranges {
        Some(t) => Ranges::with_overrides(&o.scenario, t)?,
        None => Ranges::for_scenario(&o.scenario),
    };
    let duration = o.duration.unwrap_or_else(|| scenario::default_duration_of(&o.scenario, o.hard));
    if !(duration.is_finite() && duration > 0.0) {
        return Err(format!("--duration must be > 0, got {duration}"));
    }
    if !(o.thermal_error.is_finite() && o.thermal_error >= 0.0) {
        return Err(format!("--thermal-error must be >= 0, got {}", o.thermal_error));
    }
    if let Some(m) = o.mounting {
        if m.iter().any(|x| !x.is_finite() || x.abs() > 180.0) || m[1].abs() > 90.0 {
            return Err(format!("--mounting wants roll,pitch,yaw in deg (roll and yaw within +-180, pitch within +-90), got {m:?}"));
        }
    }
    if o.speed && !scenario::ROAD_SCENARIOS.contains(&o.scenario.as_str()) {
        return Err(format!("--speed: only the urban, smooth and crawl scenarios put wheel speeds on the bus, not {:?}", o.scenario));
    }
    let mo = MotionOptions { hard: o.hard, power_on_moving: o.power_on_moving };
    let mut spec = scenario::motion_with(&o.scenario, &mo, duration, &mut stream(o.seed, 1), &ranges)?;
    if !matches!(o.scenario.as_str(), "static" | "chamber") {
        // on a stream of its own: every other draw of the seed stays as it was
        scenario::add_ride(&mut spec, &mut stream(o.seed, 7), ranges.ride_scale);
    }
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
    let adis_input = format!("[input]\nprofile = \"{}\"\n", o.profile);
    let input = match &o.input_dbc {
        Some(d) => d.input_toml.clone(),
        None => adis_input.clone(),
    };
    let header = format!(
        "# gyrocomp config for simulated unit {} seed {}: thermal slope known to +-{} %.\n",
        o.scenario,
        o.seed,
        o.thermal_error * 100.0
    );
    let rest = format!("\n[thermal]\nt0 = {:.3}\np1 = [{}]\np2 = [0.0, 0.0, 0.0]\n", t0, p1c.join(", "));
    let mut config_toml = format!("{header}{input}{rest}");
    // the same unit in the ADIS contract at the DBC format's rate (`--input-dbc`)
    // (its magnetometer off: the DBC unit has none, and the two are to see the same)
    let mut adis_twin = o
        .input_dbc
        .as_ref()
        .map(|d| format!("{header}{adis_input}rate_hz = {:?}\n{rest}\n[estimator]\nuse_magnetometer = false\n", d.plan.rate_hz));
    let lever_arm = spec.road.as_ref().map(|r| r.lever_arm);
    if o.mounting.is_some() || lever_arm.is_some() {
        let fmt = |v: [f64; 3]| v.iter().map(|x| format!("{x:?}")).collect::<Vec<_>>().join(", ");
        let m = format!(
            "\n[mounting]\nrotation = [{}]\nlever_arm = [{}]\n",
            fmt(o.mounting.unwrap_or([0.0; 3])),
            fmt(lever_arm.unwrap_or([0.0; 3]))
        );
        config_toml += &m;
        if let Some(t) = adis_twin.as_mut() {
            *t += &m;
        }
    }
    // The wheel-speed source: drawn on its own stream, whatever the flags.
    let wheel = scenario::ROAD_SCENARIOS.contains(&o.scenario.as_str()).then(|| {
        let mut w = stream(o.seed, 5);
        WheelParams {
            id: wheel::WHEEL_SPEEDS_ID,
            period_s: 0.02,
            latency_s: (uni(&mut w, ranges.wheel_latency_s) * 1e4).round() / 1e4,
            scale_error: (sym(&mut w, ranges.wheel_scale_error) * 1e5).round() / 1e5,
            noise_kmh: ranges.wheel_noise_kmh,
            dead_band_kmh: 3.6 * urban::STOP_SPEED,
            track_m: 1.6,
            wheelbase_m: 2.7,
            phase_s: (uni(&mut w, [0.0, 0.02]) * 1e5).round() / 1e5,
        }
    });
    if o.speed {
        let sp = format!(
            "\n# Wheel speeds from the car's bus (car.dbc beside this file); the tyre scale error is not known here.\n\
             [speed]\ndbc = \"car.dbc\"\nmessage = \"{}\"\nsignals = [\"{}\", \"{}\"]\nscale = 1.0\ntimeout_s = 0.5\n",
            wheel::WHEEL_SPEEDS_MESSAGE,
            wheel::REAR_SIGNALS[0],
            wheel::REAR_SIGNALS[1]
        );
        config_toml += &sp;
        if let Some(t) = adis_twin.as_mut() {
            *t += &sp;
        }
    }
    if let Some(d) = &o.input_dbc {
        dbcout::check_ids(d, wheel.as_ref().map(|w| w.id))?;
    }
    let info = ScenarioInfo {
        scenario: o.scenario.clone(),
        seed: o.seed,
        hard: o.hard,
        duration_s: duration,
        rate_hz: profile.rate_hz,
        profile: o.profile.clone(),
        manoeuvre_start_s: spec.manoeuvre_start,
        thermal_error: o.thermal_error,
        power_on_moving: o.power_on_moving,
        mounting: o.mounting,
        lever_arm,
        wheel_speeds: wheel.clone(),
        stats: None,
    };
    Ok(SimRun { info, spec, model, profile, config_toml, wheel, adis_twin })
}

/// Streams `(truth, measured, raw sample)` for a prepared run.
pub fn samples(run: &SimRun, seed: u64) -> impl Iterator<Item = (Truth, Measured, RawSample)> + '_ {
    let mut sensor = Sensor::new(&run.model, run.profile.rate_hz, stream(seed, 3)).with_mounting(run.info.mounting);
    let p = &run.profile;
    TruthGen::new(&run.spec, p.rate_hz).enumerate().map(move |(k, tr)| {
        let m = sensor.measure(&tr);
        let mut raw = RawSample::quantise(p, m.gyro, m.accel, if p.magnetometer { m.magn } else { [0.0; 3] }, m.temp);
        raw.cnt = k as u16;
        (tr, m, raw)
    })
}

/// One CAN frame of the simulated bus: time (us since the epoch), ID, payload.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BusFrame {
    pub t_us: u64,
    pub id: u32,
    pub data: [u8; 8],
}

/// One IMU sample with the bus frames up to it, in time order: the sample's
/// four ADIS frames and the wheel-speed frames sent before and between them
/// (after the last sample: the remaining wheel frames whose speeds are known).
pub struct BusSample {
    pub truth: Truth,
    pub measured: Measured,
    pub raw: RawSample,
    frames: [BusFrame; 8],
    n: usize,
}

impl BusSample {
    pub fn frames(&self) -> &[BusFrame] {
        &self.frames[..self.n]
    }
}

/// Time of a sample's first frame, us since the epoch.
pub fn sample_time_us(t: f64) -> u64 {
    LOG_EPOCH_S * 1_000_000 + (t * 1e6).round() as u64
}

/// The whole bus of a prepared run (what `imu.log` carries), sample by sample.
pub fn bus(run: &SimRun, seed: u64) -> impl Iterator<Item = BusSample> + '_ {
    let ids = InputIds::DEFAULT.all();
    let total = TruthGen::new(&run.spec, run.profile.rate_hz).len() as usize;
    let mut wheels = run.wheel.clone().map(|p| WheelBus::new(p, stream(seed, 6)));
    samples(run, seed).enumerate().map(move |(k, (tr, m, raw))| {
        let t_us = sample_time_us(tr.t);
        let mut out = BusSample { truth: tr, measured: m, raw, frames: [BusFrame::default(); 8], n: 0 };
        let push = |o: &mut BusSample, f: BusFrame| {
            if o.n < o.frames.len() {
                o.frames[o.n] = f;
                o.n += 1;
            }
        };
        if let Some(w) = wheels.as_mut() {
            w.push(&tr);
        }
        let epoch = LOG_EPOCH_S * 1_000_000;
        for (i, d) in raw.encode().iter().enumerate() {
            // four frames back to back (~120 us each at 1 Mbit/s)
            let ti = t_us + 120 * i as u64;
            if let Some(w) = wheels.as_mut() {
                while let Some((tw, wd)) = w.pop_before(ti - epoch) {
                    push(&mut out, BusFrame { t_us: epoch + tw, id: wheel::WHEEL_SPEEDS_ID, data: wd });
                }
            }
            push(&mut out, BusFrame { t_us: ti, id: ids[i], data: *d });
        }
        if k + 1 == total {
            if let Some(w) = wheels.as_mut() {
                while let Some((tw, wd)) = w.pop_any() {
                    push(&mut out, BusFrame { t_us: epoch + tw, id: wheel::WHEEL_SPEEDS_ID, data: wd });
                }
            }
        }
        out
    })
}

pub const TRUTH_HEADER: &str = "t,roll,pitch,yaw,p,q,r,fx,fy,fz,temp\n";
pub const VEHICLE_HEADER: &str = "t,speed,a_long,a_lat,dist,grade\n";

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
    /// Wheel-speed frames in `imu.log`.
    pub wheel_frames: u64,
    pub info: ScenarioInfo,
}

fn io_err(p: &Path) -> impl Fn(std::io::Error) -> String + '_ {
    move |e| format!("{}: {e}", p.display())
}

/// Run a simulation and write its files into `dir` (created if needed).
/// Every file is written under a temporary name and renamed when complete.
pub fn simulate(o: &SimOptions, dir: &Path) -> Result<SimFiles, String> {
    let mut run = prepare(o)?;
    crate::outfile::create_dir(dir).map_err(io_err(dir))?;
    let create = |name: &str| -> Result<(PathBuf, OutFile), String> {
        let p = dir.join(name);
        let f = OutFile::create(&p).map_err(io_err(&p))?;
        Ok((p, f))
    };
    let (log_p, log_f) = create("imu.log")?;
    let (truth_p, mut truth) = create("truth.csv")?;
    let (bias_p, mut bias) = create("bias.csv")?;
    let is_road = run.spec.road.is_some();
    let mut vehicle = if is_road { Some(create("vehicle.csv")?) } else { None };
    let (mut log, mut twin) = match &o.input_dbc {
        None => (Some(LogWriter::new(log_f, "vcan0")), None),
        Some(d) => (None, Some(dbcout::Writer::new(d, log_f, create(dbcout::TWIN_FILES[0])?.1))),
    };
    truth.write_all(TRUTH_HEADER.as_bytes()).map_err(io_err(&truth_p))?;
    bias.write_all(BIAS_HEADER.as_bytes()).map_err(io_err(&bias_p))?;
    if let Some((p, f)) = vehicle.as_mut() {
        f.write_all(VEHICLE_HEADER.as_bytes()).map_err(io_err(p))?;
    }
    let mut acc = StatsAcc::new(run.profile.rate_hz);
    let (mut n, mut nw) = (0u64, 0u64);
    for s in bus(&run, o.seed) {
        match (log.as_mut(), twin.as_mut()) {
            (Some(log), _) => {
                for f in s.frames() {
                    log.frame(f.t_us, f.id, &f.data).map_err(io_err(&log_p))?;
                    nw += u64::from(f.id == wheel::WHEEL_SPEEDS_ID);
                }
            }
            (None, Some(t)) => nw += t.sample(&s).map_err(io_err(&log_p))?,
            (None, None) => {}
        }
        let (tr, m) = (&s.truth, &s.measured);
        write_truth_row(&mut truth, tr).map_err(io_err(&truth_p))?;
        writeln!(bias, "{:.6},{:.7},{:.7},{:.7}", tr.t, m.bias[0], m.bias[1], m.bias[2]).map_err(io_err(&bias_p))?;
        if let Some((p, f)) = vehicle.as_mut() {
            writeln!(f, "{:.6},{:.5},{:.6},{:.6},{:.3},{:.5}", tr.t, tr.speed, tr.a_long, tr.a_lat, tr.dist, tr.grade)
                .map_err(io_err(p))?;
            acc.push(tr);
        }
        n += 1;
    }
    if is_road {
        run.info.stats = Some(acc.finish());
    }
    if let Some(log) = log {
        log.finish().map_err(io_err(&log_p))?.commit().map_err(io_err(&log_p))?;
    }
    if let Some(t) = twin {
        t.commit().map_err(io_err(&log_p))?;
    }
    truth.commit().map_err(io_err(&truth_p))?;
    bias.commit().map_err(io_err(&bias_p))?;
    if let Some((p, f)) = vehicle {
        f.commit().map_err(io_err(&p))?;
    }
    let write = |name: &str, text: &str| -> Result<(), String> {
        let p = dir.join(name);
        crate::outfile::write_atomic(&p, text.as_bytes()).map_err(io_err(&p))
    };
    write("sensor.toml", &run.model.to_toml())?;
    write("scenario.toml", &toml::to_string(&run.info).map_err(|e| e.to_string())?)?;
    write("config.toml", &run.config_toml)?;
    if run.wheel.is_some() {
        write("car.dbc", wheel::EXAMPLE_DBC)?;
    }
    if let (Some(d), Some(twin)) = (&o.input_dbc, &run.adis_twin) {
        write(&d.dbc_name, &d.dbc_text)?;
        write(dbcout::TWIN_FILES[1], twin)?;
    }
    Ok(SimFiles { dir: dir.to_path_buf(), samples: n, wheel_frames: nw, info: run.info })
}

/// The driving statistics of a prepared run's truth (road kinematics).
pub fn drive_stats(run: &SimRun) -> DriveStats {
    let mut acc = StatsAcc::new(run.profile.rate_hz);
    for tr in TruthGen::new(&run.spec, run.profile.rate_hz) {
        acc.push(&tr);
    }
    acc.finish()
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

/// A simulator CSV (truth.csv, bias.csv, vehicle.csv) parsed from `text`:
/// the header must be `header`; every value a finite number (an error names
/// the file, line and column); `t`, the first column, strictly increasing
/// (two rows swapped are refused where time first goes back).
pub fn parse_table<const N: usize>(text: &str, path: &Path, header: &str) -> Result<Vec<[f64; N]>, String> {
    let p = path.display();
    let names: Vec<&str> = header.trim().split(',').collect();
    debug_assert_eq!(names.len(), N);
    let mut lines = text.lines();
    if lines.next().map(|h| h.trim().trim_start_matches('\u{feff}')) != Some(header.trim()) {
        return Err(format!("{p} line 1 (header): want {}", header.trim()));
    }
    let mut out: Vec<[f64; N]> = Vec::new();
    for (i, l) in lines.enumerate() {
        let no = i + 2;
        if l.trim().is_empty() {
            continue;
        }
        let mut row = [0.0; N];
        let mut it = l.split(',');
        for (k, o) in row.iter_mut().enumerate() {
            let s = it.next().ok_or_else(|| format!("{p} line {no}: {k} fields, want {N} ({})", header.trim()))?.trim();
            *o = match s.parse::<f64>() {
                Ok(v) if v.is_finite() => v,
                Ok(_) => return Err(format!("{p} line {no}, column {}: {s} is not a finite number", names[k])),
                Err(_) => return Err(format!("{p} line {no}, column {}: not a number: {s:?}", names[k])),
            };
        }
        if it.next().is_some() {
            return Err(format!("{p} line {no}: {} fields, want {N} ({})", l.split(',').count(), header.trim()));
        }
        if let Some(prev) = out.last() {
            if row[0] <= prev[0] {
                return Err(format!(
                    "{p} line {no}, column t: time {} s is not after the previous row's {} s (rows out of order?)",
                    row[0], prev[0]
                ));
            }
        }
        out.push(row);
    }
    Ok(out)
}

fn read_text(path: &Path) -> Result<String, String> {
    crate::textfile::read(path).map_err(|e| format!("{}: {e}", path.display()))
}

/// The header of bias.csv.
pub const BIAS_HEADER: &str = "t,bx,by,bz\n";

/// Read truth.csv.
pub fn read_truth(path: &Path) -> Result<Vec<TruthRow>, String> {
    parse_truth(&read_text(path)?, path)
}

/// [`read_truth`] of text (`path` names it in errors).
pub fn parse_truth(text: &str, path: &Path) -> Result<Vec<TruthRow>, String> {
    Ok(parse_table::<11>(text, path, TRUTH_HEADER)?
        .into_iter()
        .map(|v| TruthRow { t: v[0], att: [v[1], v[2], v[3]], rate: [v[4], v[5], v[6]], f: [v[7], v[8], v[9]], temp: v[10] })
        .collect())
}

/// Read bias.csv: `(t, [bx, by, bz])`.
pub fn read_bias(path: &Path) -> Result<Vec<(f64, [f64; 3])>, String> {
    Ok(parse_table::<4>(&read_text(path)?, path, BIAS_HEADER)?.into_iter().map(|v| (v[0], [v[1], v[2], v[3]])).collect())
}

/// Read vehicle.csv: the truth's speed per sample, m/s (negative reversing).
pub fn read_vehicle_speed(path: &Path) -> Result<Vec<f64>, String> {
    Ok(parse_table::<6>(&read_text(path)?, path, VEHICLE_HEADER)?.into_iter().map(|v| v[1]).collect())
}

/// Read scenario.toml.
pub fn read_info(path: &Path) -> Result<ScenarioInfo, String> {
    let text = std::fs::read_to_string(path).map_err(io_err(path))?;
    toml::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))
}
