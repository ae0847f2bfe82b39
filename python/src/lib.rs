//! `gyrocomp._gyrocomp`: the Python binding, at the estimator's facade
//! (`Estimator::step(sample) -> estimate`), replay (`replay::run`),
//! calibrate (`calibrate_runs`) and gap (`gap::inputs::analyse`, in
//! [`gap`](mod@gap)). The Python package `gyrocomp` re-exports it; user
//! documentation in `docs/python.md`.
//!
//! Units are the project's CSVs': deg/s, g, gauss, deg C, seconds; angles deg.
//! Every input is checked before anything is stepped, so a bad batch leaves
//! the estimator as it was and raises an exception that names the argument,
//! the row and the column. Long calls release the GIL.

use gyrocomp::adis::{Assembler, Profile, Sample};
use gyrocomp::calibrate::{self as cal, read::read_run_from, Levels, Warmup};
use gyrocomp::config::{Config, ConfigError, RATE_HZ};
use gyrocomp::daemon::state::{SavedAxes, State};
use gyrocomp::estimator::{flags, quat, Estimate, Estimator as Core};
use gyrocomp::output::Frames;
use gyrocomp::pipeline::{Pipeline, Sink};
use gyrocomp::replay as core_replay;
use numpy::{PyArray1, PyArrayDyn, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::exceptions::{PyOSError, PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList, PyString};
use std::io::{self, Read};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender};
use std::sync::{Arc, Mutex};

mod gap;
mod standstills;

const R2D: f64 = 180.0 / std::f64::consts::PI;
const D2R: f64 = std::f64::consts::PI / 180.0;

// ---------------------------------------------------------------- config

/// The config from `None` (the defaults), TOML text, or a path (str or
/// os.PathLike). A str is TOML text when it holds a newline, `=` or `[`
/// (no config file's name does), else a path.
fn load_config(config: Option<&Bound<'_, PyAny>>) -> PyResult<Config> {
    let Some(c) = config.filter(|c| !c.is_none()) else {
        return Ok(Config::default());
    };
    let cfg_err = |e: ConfigError| match e {
        ConfigError::Io { .. } => PyOSError::new_err(format!("config: {e}")),
        e => PyValueError::new_err(format!("config: {e}")),
    };
    if let Ok(s) = c.downcast::<PyString>() {
        let s = s.to_cow()?;
        let s: &str = &s;
        if s.contains(['\n', '=', '[']) || s.trim().is_empty() {
            return Config::parse(s, "<config text>").map_err(cfg_err);
        }
        return Config::load(Path::new(s)).map_err(cfg_err);
    }
    if let Ok(b) = c.downcast::<PyBytes>() {
        let s = std::str::from_utf8(b.as_bytes()).map_err(|e| PyValueError::new_err(format!("config: not UTF-8 text: {e}")))?;
        return Config::parse(s, "<config text>").map_err(cfg_err);
    }
    let p = fspath(c).map_err(|_| PyTypeError::new_err("config: expected None, TOML text (str) or a path (str or os.PathLike)"))?;
    Config::load(&p).map_err(cfg_err)
}

fn fspath(obj: &Bound<'_, PyAny>) -> PyResult<PathBuf> {
    let p = obj.py().import("os")?.call_method1("fspath", (obj,))?;
    p.extract::<PathBuf>()
}

// ---------------------------------------------------------------- input checks

/// Temperatures accepted, deg C, whatever the registers could carry.
const TEMP_C: (f64, f64) = (-60.0, 150.0);

/// A number as Python prints the non-finite ones (nan, inf, -inf).
fn num(v: f64) -> String {
    if v.is_nan() {
        "nan".into()
    } else if v.is_infinite() {
        if v > 0.0 {
            "inf".into()
        } else {
            "-inf".into()
        }
    } else {
        format!("{v}")
    }
}

/// The part's signal ranges (what its 16-bit registers can carry), for the
/// out-of-range checks.
#[derive(Clone, Copy, Debug)]
struct Ranges {
    gyr: f64,
    acc: f64,
    mag: f64,
    temp: (f64, f64),
}

impl Ranges {
    fn of(p: &Profile) -> Ranges {
        let full = 32768.0;
        // the registers' range, within what any MEMS part survives (a
        // temperature beyond it is a unit mix-up: kelvin, fahrenheit)
        let t = ((p.temp_offset - full * p.temp_lsb.abs()).max(TEMP_C.0), (p.temp_offset + full * p.temp_lsb.abs()).min(TEMP_C.1));
        Ranges { gyr: full * p.gyro_lsb.abs(), acc: full * p.accel_lsb.abs(), mag: full * p.magn_lsb.abs(), temp: t }
    }
}

fn check_value(what: &str, row: Option<usize>, col: Option<usize>, v: f64, (lo, hi): (f64, f64), unit: &str, part: &str) -> PyResult<()> {
    if v.is_finite() && v >= lo && v <= hi {
        return Ok(());
    }
    let at = match (row, col) {
        (Some(r), Some(c)) => format!("{what}[{r}, {c}]"),
        (Some(r), None) => format!("{what}[{r}]"),
        (None, Some(c)) => format!("{what}[{c}]"),
        (None, None) => what.to_string(),
    };
    if !v.is_finite() {
        return Err(PyValueError::new_err(format!("{at} is {}: every value must be finite", num(v))));
    }
    Err(PyValueError::new_err(format!("{at} = {v} {unit} is outside {lo}..{hi} {unit} ({part})")))
}

/// Whether every value is within lo..=hi (NaN is not): no early exit, so
/// that it vectorises.
fn within(v: &[f64], lo: f64, hi: f64) -> bool {
    v.iter().fold(true, |ok, x| ok & (*x >= lo) & (*x <= hi))
}

/// Three values (a sequence or a 1-D array) for `update`.
fn vec3(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<[f64; 3]> {
    let v: Vec<f64> =
        obj.extract().map_err(|_| PyTypeError::new_err(format!("{what}: expected 3 numbers (a sequence or a (3,) array)")))?;
    if v.len() != 3 {
        return Err(PyValueError::new_err(format!("{what}: expected 3 values, got {}", v.len())));
    }
    Ok([v[0], v[1], v[2]])
}

/// An (N, cols) or, with `cols` None, an (N,) float64 array, C-contiguous
/// (converted with `numpy.ascontiguousarray(x, dtype=float64)`).
fn array<'py>(obj: &Bound<'py, PyAny>, what: &str, cols: Option<usize>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let py = obj.py();
    let np = py.import("numpy")?;
    let kw = PyDict::new(py);
    kw.set_item("dtype", np.getattr("float64")?)?;
    let a = np
        .call_method("ascontiguousarray", (obj,), Some(&kw))
        .map_err(|e| PyTypeError::new_err(format!("{what}: cannot be read as float64 numbers: {e}")))?;
    let a = a.downcast_into::<PyArrayDyn<f64>>().map_err(|_| PyTypeError::new_err(format!("{what}: not a float64 array")))?;
    let shape = a.shape().to_vec();
    let want = match cols {
        Some(c) => shape.len() == 2 && shape[1] == c,
        None => shape.len() == 1,
    };
    if !want {
        let w = cols.map_or("(N,)".to_string(), |c| format!("(N, {c})"));
        return Err(PyValueError::new_err(format!("{what}: expected shape {w}, got {shape:?}")));
    }
    Ok(a)
}

// ---------------------------------------------------------------- Estimate

/// One estimate (vehicle frame): what `Estimator.update` returns.
#[pyclass(module = "gyrocomp._gyrocomp", name = "Estimate", frozen, get_all)]
#[derive(Clone, Debug)]
struct Estimate1 {
    /// Seconds since the first sample (from the sample steps).
    t: f64,
    /// [w, x, y, z]: the attitude (Z-Y-X Euler angles below) as a unit quaternion.
    quaternion: (f64, f64, f64, f64),
    /// Roll, pitch, yaw, deg.
    euler: (f64, f64, f64),
    /// Bias-corrected rate, deg/s.
    rate: (f64, f64, f64),
    /// Gyro bias, deg/s.
    bias: (f64, f64, f64),
    /// 1-sigma of the bias, deg/s (NaN in the paper's modes).
    bias_sigma: (f64, f64, f64),
    /// At rest (standstill detected).
    rest: bool,
    /// 0 fusion with bias learning, 1 aided without bias learning, 2 gyro only.
    mode: u8,
    /// Health flags (`EST_STATUS` bits; `docs/python.md`).
    flags: u16,
    /// The sample's temperature, deg C.
    temp: f64,
}

#[pymethods]
impl Estimate1 {
    fn __repr__(&self) -> String {
        format!(
            "Estimate(t={:.4}, euler=({:.3}, {:.3}, {:.3}), bias=({:.5}, {:.5}, {:.5}), rest={}, mode={}, flags={:#06x})",
            self.t,
            self.euler.0,
            self.euler.1,
            self.euler.2,
            self.bias.0,
            self.bias.1,
            self.bias.2,
            if self.rest { "True" } else { "False" },
            self.mode,
            self.flags
        )
    }
}

/// One estimate's columns, in the order of `update_batch`'s arrays.
#[derive(Clone, Copy, Debug)]
struct Row {
    t: f64,
    q: [f64; 4],
    euler: [f64; 3],
    rate: [f64; 3],
    bias: [f64; 3],
    sigma: [f64; 3],
    mode: u8,
    flags: u16,
}

/// The attitude quaternion: the default filter's own (its Euler angles are
/// the estimate's), else from the estimate's Euler angles; w >= 0.
fn row(est: &Core, e: &Estimate) -> Row {
    let (q, sigma) = match est.mekf() {
        Some(m) => (m.quaternion(), m.bias_sigma().map(|s| s * R2D)),
        None => (quat::from_euler(e.roll * D2R, e.pitch * D2R, e.yaw * D2R), [f64::NAN; 3]),
    };
    let q = if q[0] < 0.0 { q.map(|v| -v) } else { q };
    Row { t: e.t, q, euler: [e.roll, e.pitch, e.yaw], rate: e.rate, bias: e.bias, sigma, mode: e.mode, flags: e.flags }
}

// ---------------------------------------------------------------- Estimator

/// The estimator, one power cycle: `update` one sample, `update_batch` many.
#[pyclass(module = "gyrocomp._gyrocomp")]
struct Estimator {
    cfg: Config,
    est: Core,
    rate: f64,
    ranges: Ranges,
    part: String,
    /// The sample clock (s) of the last sample; None before the first.
    clock: Option<f64>,
    cnt: u16,
    t_us: u64,
}

/// A sample's steps (periods since the previous one) from its spacing.
fn steps_of(dt: f64, rate: f64) -> Option<u32> {
    let n = (dt * rate).round();
    (n >= 1.0 && n <= u32::MAX as f64).then_some(n as u32)
}

impl Estimator {
    fn fresh(cfg: &Config) -> Core {
        Core::new(cfg)
    }

    /// The sample for the core, the clock moved on by `steps`.
    fn sample(&mut self, gyro: [f64; 3], accel: [f64; 3], magn: [f64; 3], temp: f64, steps: u32, t: f64) -> Sample {
        let steps = if self.clock.is_none() { 0 } else { steps };
        self.clock = Some(t);
        self.cnt = self.cnt.wrapping_add(steps.max(1) as u16);
        self.t_us = self.t_us.saturating_add((steps as f64 / self.rate * 1e6).round() as u64);
        Sample { cnt: self.cnt, t_us: self.t_us, steps, gyro, accel, magn, temp, diag: 0 }
    }

    fn check3(&self, what: &str, row: Option<usize>, v: &[f64], lim: f64, unit: &str) -> PyResult<()> {
        for (c, x) in v.iter().enumerate() {
            check_value(what, row, Some(c), *x, (-lim, lim), unit, &self.part)?;
        }
        Ok(())
    }

    fn check_temp(&self, row: Option<usize>, v: f64) -> PyResult<()> {
        check_value("temp", row, None, v, self.ranges.temp, "deg C", &self.part)
    }

    /// The temperature used when none is given: the thermal curve's reference.
    fn default_temp(&self) -> f64 {
        self.cfg.thermal.t0
    }
}

#[pymethods]
impl Estimator {
    #[new]
    #[pyo3(signature = (rate_hz, config=None))]
    fn new(rate_hz: f64, config: Option<&Bound<'_, PyAny>>) -> PyResult<Self> {
        if !(rate_hz.is_finite() && rate_hz >= RATE_HZ.0 && rate_hz <= RATE_HZ.1) {
            return Err(PyValueError::new_err(format!("rate_hz = {}: must be within {}..{} Hz", num(rate_hz), RATE_HZ.0, RATE_HZ.1)));
        }
        let mut cfg = load_config(config)?;
        cfg.input.rate_hz = rate_hz;
        let p = cfg.profile();
        let part = format!("the range of {}'s registers", p.name);
        Ok(Estimator { est: Self::fresh(&cfg), rate: rate_hz, ranges: Ranges::of(&p), part, cfg, clock: None, cnt: 0, t_us: 0 })
    }

    /// The sample rate, Hz.
    #[getter]
    fn rate_hz(&self) -> f64 {
        self.rate
    }

    /// The effective config as TOML text (every key).
    #[getter]
    fn config(&self) -> String {
        self.cfg.to_toml()
    }

    /// Whether a sample was stepped since the start or the last reset.
    #[getter]
    fn started(&self) -> bool {
        self.clock.is_some()
    }

    /// Start a new power cycle (no prior); `state` restores one.
    fn reset(&mut self) {
        self.est = Self::fresh(&self.cfg);
        self.clock = None;
        self.cnt = 0;
        self.t_us = 0;
    }

    /// One sample: gyr deg/s, acc g, mag gauss (None: no magnetometer), temp
    /// deg C (None: the thermal curve's t0), dt s since the previous sample
    /// (None: one period; rounded to whole periods, a gap longer than
    /// `max_gap_s` is a resync). Returns the `Estimate`.
    #[pyo3(signature = (gyr, acc, mag=None, temp=None, dt=None))]
    fn update(
        &mut self,
        gyr: &Bound<'_, PyAny>,
        acc: &Bound<'_, PyAny>,
        mag: Option<&Bound<'_, PyAny>>,
        temp: Option<f64>,
        dt: Option<f64>,
    ) -> PyResult<Estimate1> {
        let g = vec3(gyr, "gyr")?;
        let a = vec3(acc, "acc")?;
        let m = match mag.filter(|m| !m.is_none()) {
            Some(m) => vec3(m, "mag")?,
            None => [0.0; 3],
        };
        self.check3("gyr", None, &g, self.ranges.gyr, "deg/s")?;
        self.check3("acc", None, &a, self.ranges.acc, "g")?;
        self.check3("mag", None, &m, self.ranges.mag, "gauss")?;
        let temp = temp.unwrap_or_else(|| self.default_temp());
        self.check_temp(None, temp)?;
        let period = 1.0 / self.rate;
        let steps = match dt {
            None => 1,
            Some(d) => steps_of(d, self.rate).filter(|_| d.is_finite()).ok_or_else(|| {
                PyValueError::new_err(format!(
                    "dt = {} s: must be finite and at least half a sample period ({:.6} s)",
                    num(d),
                    period / 2.0
                ))
            })?,
        };
        let t = self.clock.map_or(0.0, |c| c + steps as f64 * period);
        let s = self.sample(g, a, m, temp, steps, t);
        let e = self.est.step(&s);
        let r = row(&self.est, &e);
        Ok(Estimate1 {
            t: r.t,
            quaternion: (r.q[0], r.q[1], r.q[2], r.q[3]),
            euler: (r.euler[0], r.euler[1], r.euler[2]),
            rate: (r.rate[0], r.rate[1], r.rate[2]),
            bias: (r.bias[0], r.bias[1], r.bias[2]),
            bias_sigma: (r.sigma[0], r.sigma[1], r.sigma[2]),
            rest: r.flags & flags::STANDSTILL != 0,
            mode: r.mode,
            flags: r.flags,
            temp,
        })
    }

    /// N samples at once: gyr, acc (and mag) (N, 3) arrays, temp (N,), t
    /// (N,) sample times in s (None: one period apart). Returns a dict of
    /// arrays: quaternion (N, 4), euler, rate, bias, bias_sigma (N, 3),
    /// rest (N,) bool, mode (N,) uint8, flags (N,) uint16, t (N,).
    #[pyo3(signature = (gyr, acc, mag=None, temp=None, t=None))]
    fn update_batch<'py>(
        &mut self,
        py: Python<'py>,
        gyr: &Bound<'py, PyAny>,
        acc: &Bound<'py, PyAny>,
        mag: Option<&Bound<'py, PyAny>>,
        temp: Option<&Bound<'py, PyAny>>,
        t: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let ga = array(gyr, "gyr", Some(3))?;
        let n = ga.shape()[0];
        let same_n = |a: Bound<'py, PyArrayDyn<f64>>, what: &str| -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
            if a.shape()[0] != n {
                return Err(PyValueError::new_err(format!("{what}: {} rows, gyr has {n}", a.shape()[0])));
            }
            Ok(a)
        };
        let aa = same_n(array(acc, "acc", Some(3))?, "acc")?;
        let ma = mag.filter(|m| !m.is_none()).map(|m| array(m, "mag", Some(3)).and_then(|a| same_n(a, "mag"))).transpose()?;
        let ta = temp.filter(|m| !m.is_none()).map(|m| array(m, "temp", None).and_then(|a| same_n(a, "temp"))).transpose()?;
        let tt = t.filter(|m| !m.is_none()).map(|m| array(m, "t", None).and_then(|a| same_n(a, "t"))).transpose()?;
        let (gr, ar) = (ga.readonly(), aa.readonly());
        let mr = ma.as_ref().map(|a| a.readonly());
        let tr = ta.as_ref().map(|a| a.readonly());
        let ttr = tt.as_ref().map(|a| a.readonly());
        let g = gr.as_slice()?;
        let a = ar.as_slice()?;
        let m = mr.as_ref().map(|x| x.as_slice()).transpose()?;
        let tmp = tr.as_ref().map(|x| x.as_slice()).transpose()?;
        let ts = ttr.as_ref().map(|x| x.as_slice()).transpose()?;

        // check everything before stepping anything: a branch-free pass over
        // each array, and only when it fails the row by row one that names
        // the first bad value
        let r = self.ranges;
        let ok = within(g, -r.gyr, r.gyr)
            && within(a, -r.acc, r.acc)
            && m.is_none_or(|m| within(m, -r.mag, r.mag))
            && tmp.is_none_or(|t| within(t, r.temp.0, r.temp.1));
        if !ok {
            for i in 0..n {
                self.check3("gyr", Some(i), &g[3 * i..3 * i + 3], r.gyr, "deg/s")?;
                self.check3("acc", Some(i), &a[3 * i..3 * i + 3], r.acc, "g")?;
                if let Some(m) = m {
                    self.check3("mag", Some(i), &m[3 * i..3 * i + 3], r.mag, "gauss")?;
                }
                if let Some(tm) = tmp {
                    self.check_temp(Some(i), tm[i])?;
                }
            }
        }
        let period = 1.0 / self.rate;
        let mut steps = vec![1u32; n];
        for i in 0..n {
            if let Some(ts) = ts {
                if !ts[i].is_finite() {
                    return Err(PyValueError::new_err(format!("t[{i}] is {}: every value must be finite", num(ts[i]))));
                }
                let prev = if i == 0 { self.clock } else { Some(ts[i - 1]) };
                if let Some(p) = prev {
                    steps[i] = steps_of(ts[i] - p, self.rate).ok_or_else(|| {
                        PyValueError::new_err(format!(
                            "t[{i}] = {} s is not at least half a sample period ({:.6} s) after the previous sample ({p} s): t must increase",
                            ts[i],
                            period / 2.0
                        ))
                    })?;
                }
            }
        }
        let default_temp = self.default_temp();
        let mut out = Out::with_capacity(n);
        py.allow_threads(|| {
            for i in 0..n {
                let v3 = |x: &[f64]| [x[3 * i], x[3 * i + 1], x[3 * i + 2]];
                let mv = m.map_or([0.0; 3], v3);
                let temp = tmp.map_or(default_temp, |x| x[i]);
                let time = match ts {
                    Some(ts) => ts[i],
                    None => self.clock.map_or(0.0, |c| c + period),
                };
                let s = self.sample(v3(g), v3(a), mv, temp, steps[i], time);
                let e = self.est.step(&s);
                out.push(&row(&self.est, &e));
            }
        });
        out.into_dict(py)
    }

    /// The learned state in the daemon's state-file format (the text of
    /// `gyrocomp-state.json`), or None when nothing is learned yet.
    /// Assigning one (str or bytes) restarts the estimator from it, as the
    /// daemon does at start (the bias prior, its sigma grown with the
    /// state's age, the slope learner, the turned vehicle axes); None
    /// restarts it from the config.
    #[getter]
    fn get_state(&self) -> PyResult<Option<String>> {
        let Some(l) = self.est.learned() else { return Ok(None) };
        let mut st = State::from_learned(&l, now_unix(), self.est.slope_state());
        st.vehicle_axes = SavedAxes::of(&self.est, self.cfg.mounting.rotation);
        let b = st.to_file_bytes().map_err(|e| PyValueError::new_err(format!("state: {e}")))?;
        Ok(Some(String::from_utf8_lossy(&b).into_owned()))
    }

    #[setter]
    fn set_state(&mut self, state: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        let st = match state.filter(|s| !s.is_none()) {
            None => None,
            Some(s) => {
                let bytes: Vec<u8> = if let Ok(s) = s.downcast::<PyString>() {
                    s.to_cow()?.as_bytes().to_vec()
                } else if let Ok(b) = s.downcast::<PyBytes>() {
                    b.as_bytes().to_vec()
                } else {
                    return Err(PyTypeError::new_err("state: expected the state file's text (str or bytes) or None"));
                };
                Some(State::from_file_bytes(&bytes, "state").map_err(|e| PyValueError::new_err(e.to_string()))?)
            }
        };
        self.reset();
        if let Some(st) = st {
            self.est.set_prior(st.prior(now_unix(), self.cfg.ekf.bias_walk, 0.0));
            if let Some(yaw) = st.axes_for(self.cfg.mounting.rotation) {
                self.est.set_vehicle_axes(yaw);
            }
            if let Some(sl) = &st.slope {
                self.est.set_slope_state(sl);
            }
        }
        Ok(())
    }

    fn __repr__(&self) -> String {
        format!(
            "Estimator(rate_hz={}, mode={:?}, started={})",
            self.rate,
            self.cfg.estimator.mode.name(),
            if self.clock.is_some() { "True" } else { "False" }
        )
    }
}

fn now_unix() -> f64 {
    std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0.0, |d| d.as_secs_f64())
}

/// `update_batch`'s output columns.
struct Out {
    t: Vec<f64>,
    q: Vec<f64>,
    euler: Vec<f64>,
    rate: Vec<f64>,
    bias: Vec<f64>,
    sigma: Vec<f64>,
    rest: Vec<bool>,
    mode: Vec<u8>,
    flags: Vec<u16>,
}

impl Out {
    fn with_capacity(n: usize) -> Out {
        Out {
            t: Vec::with_capacity(n),
            q: Vec::with_capacity(4 * n),
            euler: Vec::with_capacity(3 * n),
            rate: Vec::with_capacity(3 * n),
            bias: Vec::with_capacity(3 * n),
            sigma: Vec::with_capacity(3 * n),
            rest: Vec::with_capacity(n),
            mode: Vec::with_capacity(n),
            flags: Vec::with_capacity(n),
        }
    }

    #[inline]
    fn push(&mut self, r: &Row) {
        self.t.push(r.t);
        self.q.extend_from_slice(&r.q);
        self.euler.extend_from_slice(&r.euler);
        self.rate.extend_from_slice(&r.rate);
        self.bias.extend_from_slice(&r.bias);
        self.sigma.extend_from_slice(&r.sigma);
        self.rest.push(r.flags & flags::STANDSTILL != 0);
        self.mode.push(r.mode);
        self.flags.push(r.flags);
    }

    fn into_dict(self, py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
        let n = self.t.len();
        let d = PyDict::new(py);
        d.set_item("quaternion", PyArray1::from_vec(py, self.q).reshape([n, 4])?)?;
        d.set_item("euler", PyArray1::from_vec(py, self.euler).reshape([n, 3])?)?;
        d.set_item("rate", PyArray1::from_vec(py, self.rate).reshape([n, 3])?)?;
        d.set_item("bias", PyArray1::from_vec(py, self.bias).reshape([n, 3])?)?;
        d.set_item("bias_sigma", PyArray1::from_vec(py, self.sigma).reshape([n, 3])?)?;
        d.set_item("rest", PyArray1::from_vec(py, self.rest))?;
        d.set_item("mode", PyArray1::from_vec(py, self.mode))?;
        d.set_item("flags", PyArray1::from_vec(py, self.flags))?;
        d.set_item("t", PyArray1::from_vec(py, self.t))?;
        Ok(d)
    }
}

// ---------------------------------------------------------------- log input

/// A log: a path, bytes, or a binary file object (`.read(n)`), read in
/// chunks (the bytes and the file object a chunk at a time under the GIL).
enum LogSource {
    Path(PathBuf),
    Bytes(Py<PyBytes>),
    File(Py<PyAny>),
}

impl LogSource {
    fn of(log: &Bound<'_, PyAny>) -> PyResult<LogSource> {
        if let Ok(b) = log.downcast::<PyBytes>() {
            return Ok(LogSource::Bytes(b.clone().unbind()));
        }
        if log.downcast::<PyString>().is_err() && log.hasattr("read")? {
            return Ok(LogSource::File(log.clone().unbind()));
        }
        let p =
            fspath(log).map_err(|_| PyTypeError::new_err("log: expected a path (str or os.PathLike), bytes, or a binary file object"))?;
        Ok(LogSource::Path(p))
    }

    fn name(&self) -> String {
        match self {
            LogSource::Path(p) => p.display().to_string(),
            LogSource::Bytes(_) => "<bytes>".into(),
            LogSource::File(_) => "<file object>".into(),
        }
    }

    /// A reader usable without the GIL.
    fn reader(self) -> PyResult<Box<dyn Read + Send>> {
        Ok(match self {
            LogSource::Path(p) => {
                let f = std::fs::File::open(&p).map_err(|e| PyOSError::new_err(format!("cannot open {}: {e}", p.display())))?;
                Box::new(f)
            }
            LogSource::Bytes(b) => Box::new(BytesReader { b, pos: 0 }),
            LogSource::File(f) => Box::new(FileReader { f }),
        })
    }
}

/// Reads a Python bytes object a chunk at a time (the GIL held per chunk).
struct BytesReader {
    b: Py<PyBytes>,
    pos: usize,
}

impl Read for BytesReader {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        Python::with_gil(|py| {
            let s = self.b.bind(py).as_bytes();
            let n = buf.len().min(s.len() - self.pos.min(s.len()));
            buf[..n].copy_from_slice(&s[self.pos..self.pos + n]);
            self.pos += n;
            Ok(n)
        })
    }
}

/// Reads a Python binary file object with `.read(n)`.
struct FileReader {
    f: Py<PyAny>,
}

impl Read for FileReader {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        Python::with_gil(|py| {
            let r = self.f.bind(py).call_method1("read", (buf.len(),)).map_err(|e| io::Error::other(e.to_string()))?;
            let b = r
                .downcast::<PyBytes>()
                .map_err(|_| io::Error::other("the file object's read() did not return bytes (open it in binary mode)"))?;
            let s = b.as_bytes();
            if s.len() > buf.len() {
                return Err(io::Error::other("the file object's read(n) returned more than n bytes"));
            }
            buf[..s.len()].copy_from_slice(s);
            Ok(s.len())
        })
    }
}

/// 256 KiB reads: few GIL round trips, memory bounded whatever the log's length.
const CHUNK: usize = 256 * 1024;

fn io_err(name: &str, e: io::Error) -> PyErr {
    PyOSError::new_err(format!("reading {name}: {e}"))
}

// ---------------------------------------------------------------- replay

/// The replay CSV's columns (`gyrocomp replay --csv`), full precision.
#[derive(Default)]
struct ReplayCols {
    t: Vec<f64>,
    euler: [Vec<f64>; 3],
    rate: [Vec<f64>; 3],
    bias: [Vec<f64>; 3],
    mode: Vec<u8>,
    temp: Vec<f64>,
    flags: Vec<u16>,
    t_us: Vec<u64>,
    /// The fields not estimated (the CSV's `invalid`).
    invalid: Vec<u8>,
}

impl Sink for ReplayCols {
    #[inline]
    fn output(&mut self, e: &Estimate, _: &Frames) {
        self.t.push(e.t);
        for (i, v) in [e.roll, e.pitch, e.yaw].into_iter().enumerate() {
            self.euler[i].push(v);
        }
        for i in 0..3 {
            self.rate[i].push(e.rate[i]);
            self.bias[i].push(e.bias[i]);
        }
        self.mode.push(e.mode);
        self.temp.push(e.temp);
        self.flags.push(e.flags);
        self.t_us.push(e.t_us);
        self.invalid.push(e.invalid);
    }
}

/// Replay a candump log (`gyrocomp replay`) and return the CSV's columns.
#[pyfunction]
#[pyo3(signature = (log, config=None))]
fn replay<'py>(py: Python<'py>, log: &Bound<'py, PyAny>, config: Option<&Bound<'py, PyAny>>) -> PyResult<Bound<'py, PyDict>> {
    let cfg = load_config(config)?;
    let src = LogSource::of(log)?;
    let name = src.name();
    let input = io::BufReader::with_capacity(CHUNK, src.reader()?);
    let mut pipe = pipeline(&cfg)?;
    let mut cols = ReplayCols::default();
    let sum = py.allow_threads(|| core_replay::run(&mut pipe, input, &mut cols));
    let sum = sum.map_err(|e| io_err(&name, e))?;
    let d = cols.into_dict(py)?;
    d.set_item("summary", summary_dict(py, &sum)?)?;
    Ok(d)
}

impl ReplayCols {
    fn len(&self) -> usize {
        self.t.len()
    }

    fn into_dict(self, py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("t", PyArray1::from_vec(py, self.t))?;
        let [r, p, y] = self.euler;
        d.set_item("roll", PyArray1::from_vec(py, r))?;
        d.set_item("pitch", PyArray1::from_vec(py, p))?;
        d.set_item("yaw", PyArray1::from_vec(py, y))?;
        for (k, v) in ["rate_x", "rate_y", "rate_z"].into_iter().zip(self.rate) {
            d.set_item(k, PyArray1::from_vec(py, v))?;
        }
        for (k, v) in ["bias_x", "bias_y", "bias_z"].into_iter().zip(self.bias) {
            d.set_item(k, PyArray1::from_vec(py, v))?;
        }
        d.set_item("mode", PyArray1::from_vec(py, self.mode))?;
        d.set_item("temp", PyArray1::from_vec(py, self.temp))?;
        d.set_item("flags", PyArray1::from_vec(py, self.flags))?;
        d.set_item("t_us", PyArray1::from_vec(py, self.t_us))?;
        d.set_item("invalid", PyArray1::from_vec(py, self.invalid))?;
        Ok(d)
    }
}

/// The pipeline `cfg` describes (`Pipeline::from_config`), its error a ValueError.
fn pipeline(cfg: &Config) -> PyResult<Pipeline> {
    Pipeline::from_config(cfg).map_err(|e| PyValueError::new_err(format!("config: {e}")))
}

/// The replay summary as a dict; its "text" is what the CLI prints.
fn summary_dict<'py>(py: Python<'py>, sum: &core_replay::Summary) -> PyResult<Bound<'py, PyAny>> {
    let js = serde_json::to_string(sum).map_err(|e| PyValueError::new_err(e.to_string()))?;
    let summary = py.import("json")?.call_method1("loads", (js,))?;
    summary.set_item("text", sum.render())?;
    Ok(summary)
}

/// What the replay thread of `replay_chunks` hands over.
enum ChunkMsg {
    Chunk(Box<ReplayCols>),
    End(io::Result<Box<core_replay::Summary>>),
}

/// Sends the columns a chunk of `rows` at a time; stops the reader when
/// nobody takes them any more.
struct ChunkSink {
    cols: ReplayCols,
    rows: usize,
    tx: SyncSender<ChunkMsg>,
    stop: Arc<AtomicBool>,
}

impl Sink for ChunkSink {
    #[inline]
    fn output(&mut self, e: &Estimate, f: &Frames) {
        self.cols.output(e, f);
        if self.cols.len() >= self.rows {
            let c = std::mem::take(&mut self.cols);
            if self.tx.send(ChunkMsg::Chunk(Box::new(c))).is_err() {
                self.stop.store(true, Ordering::Relaxed);
            }
        }
    }
}

/// A reader that ends (EOF) once `stop` is set.
struct StopReader<R> {
    inner: R,
    stop: Arc<AtomicBool>,
}

impl<R: Read> Read for StopReader<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        if self.stop.load(Ordering::Relaxed) {
            return Ok(0);
        }
        self.inner.read(buf)
    }
}

/// `replay` a chunk at a time: an iterator of dicts of at most `rows` rows
/// each (the same columns as `replay`, without the summary), for logs whose
/// estimates do not fit in memory at once. The replay runs in a thread one
/// chunk ahead; `.summary` is there once the iterator is exhausted.
#[pyclass(module = "gyrocomp._gyrocomp")]
struct ReplayChunks {
    rx: Mutex<Option<Receiver<ChunkMsg>>>,
    stop: Arc<AtomicBool>,
    name: String,
    summary: Option<Py<PyAny>>,
}

#[pymethods]
impl ReplayChunks {
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __next__<'py>(&mut self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(rx) = self.rx.lock().map_err(|_| PyRuntimeError::new_err("replay_chunks: poisoned"))?.take() else {
            return Ok(None);
        };
        let (msg, rx) = py.allow_threads(move || (rx.recv(), rx));
        match msg {
            Ok(ChunkMsg::Chunk(c)) => {
                *self.rx.lock().map_err(|_| PyRuntimeError::new_err("replay_chunks: poisoned"))? = Some(rx);
                c.into_dict(py).map(Some)
            }
            Ok(ChunkMsg::End(Ok(sum))) => {
                self.summary = Some(summary_dict(py, &sum)?.unbind());
                Ok(None)
            }
            Ok(ChunkMsg::End(Err(e))) => Err(io_err(&self.name, e)),
            Err(_) => Err(PyRuntimeError::new_err(format!("replaying {}: the replay thread ended without a result", self.name))),
        }
    }

    /// The replay summary (as `replay`'s), None until the iterator is exhausted.
    #[getter]
    fn summary(&self, py: Python<'_>) -> Option<Py<PyAny>> {
        self.summary.as_ref().map(|s| s.clone_ref(py))
    }
}

impl Drop for ReplayChunks {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
    }
}

#[pyfunction]
#[pyo3(signature = (log, config=None, rows=65536))]
fn replay_chunks(log: &Bound<'_, PyAny>, config: Option<&Bound<'_, PyAny>>, rows: usize) -> PyResult<ReplayChunks> {
    if rows == 0 {
        return Err(PyValueError::new_err("rows = 0: a chunk needs at least one row"));
    }
    let cfg = load_config(config)?;
    let src = LogSource::of(log)?;
    let name = src.name();
    let stop = Arc::new(AtomicBool::new(false));
    let input = io::BufReader::with_capacity(CHUNK, StopReader { inner: src.reader()?, stop: stop.clone() });
    let mut pipe = pipeline(&cfg)?;
    // one chunk in the channel and one being filled: memory bounded by the chunk
    let (tx, rx) = sync_channel(1);
    let mut sink = ChunkSink { cols: ReplayCols::default(), rows, tx: tx.clone(), stop: stop.clone() };
    std::thread::Builder::new()
        .name("gyrocomp-replay".into())
        .spawn(move || {
            let res = core_replay::run(&mut pipe, input, &mut sink);
            if sink.cols.len() > 0 {
                let _ = tx.send(ChunkMsg::Chunk(Box::new(std::mem::take(&mut sink.cols))));
            }
            let _ = tx.send(ChunkMsg::End(res.map(Box::new)));
        })
        .map_err(|e| PyRuntimeError::new_err(format!("cannot start the replay thread: {e}")))?;
    Ok(ReplayChunks { rx: Mutex::new(Some(rx)), stop, name, summary: None })
}

/// The samples of a candump log as the daemon assembles them, in the units
/// `Estimator.update_batch` takes.
#[pyfunction]
#[pyo3(signature = (log, config=None))]
fn read_log<'py>(py: Python<'py>, log: &Bound<'py, PyAny>, config: Option<&Bound<'py, PyAny>>) -> PyResult<Bound<'py, PyDict>> {
    let cfg = load_config(config)?;
    let src = LogSource::of(log)?;
    let name = src.name();
    let input = io::BufReader::with_capacity(CHUNK, src.reader()?);
    let p = cfg.profile();
    let period = 1.0 / p.rate_hz;
    let mut asm = Assembler::new(p, cfg.input.ids);
    #[derive(Default)]
    struct Cols {
        gyr: Vec<f64>,
        acc: Vec<f64>,
        mag: Vec<f64>,
        temp: Vec<f64>,
        t: Vec<f64>,
        t_frame: Vec<f64>,
        steps: Vec<u32>,
        cnt: Vec<u16>,
        diag: Vec<u16>,
    }
    let mut c = Cols::default();
    let mut clock = 0.0f64;
    let res = py.allow_threads(|| {
        core_replay::for_each_sample(input, &mut asm, |s| {
            if !c.t.is_empty() {
                clock += s.steps.max(1) as f64 * period;
            }
            c.gyr.extend_from_slice(&s.gyro);
            c.acc.extend_from_slice(&s.accel);
            c.mag.extend_from_slice(&s.magn);
            c.temp.push(s.temp);
            c.t.push(clock);
            c.t_frame.push(s.t_us as f64 * 1e-6);
            c.steps.push(s.steps);
            c.cnt.push(s.cnt);
            c.diag.push(s.diag);
        })
    });
    let st = res.map_err(|(line, e)| PyOSError::new_err(format!("reading {name}, line {line}: {e}")))?;
    let n = c.t.len();
    let d = PyDict::new(py);
    d.set_item("gyr", PyArray1::from_vec(py, c.gyr).reshape([n, 3])?)?;
    d.set_item("acc", PyArray1::from_vec(py, c.acc).reshape([n, 3])?)?;
    d.set_item("mag", PyArray1::from_vec(py, c.mag).reshape([n, 3])?)?;
    d.set_item("temp", PyArray1::from_vec(py, c.temp))?;
    d.set_item("t", PyArray1::from_vec(py, c.t))?;
    d.set_item("t_frame", PyArray1::from_vec(py, c.t_frame))?;
    d.set_item("steps", PyArray1::from_vec(py, c.steps))?;
    d.set_item("cnt", PyArray1::from_vec(py, c.cnt))?;
    d.set_item("diag", PyArray1::from_vec(py, c.diag))?;
    d.set_item("lines", st.lines)?;
    d.set_item("bad_lines", st.bad_lines)?;
    d.set_item("rate_hz", 1.0 / period)?;
    Ok(d)
}

// ---------------------------------------------------------------- calibrate

/// `gyrocomp calibrate`: the thermal bias curve from chamber runs (each a
/// path, bytes or a binary file object; one power cycle of a static unit).
#[pyfunction]
#[pyo3(signature = (runs, order=1, config=None))]
fn calibrate<'py>(
    py: Python<'py>,
    runs: &Bound<'py, PyAny>,
    order: u8,
    config: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    if !(1..=3).contains(&order) {
        return Err(PyValueError::new_err(format!("order = {order}: must be 1, 2 or 3")));
    }
    let cfg = load_config(config)?;
    let list: Vec<Bound<'py, PyAny>> = if runs.downcast::<PyString>().is_ok() || runs.downcast::<PyBytes>().is_ok() {
        return Err(PyTypeError::new_err("runs: expected a list of logs (paths, bytes or file objects), one per chamber run"));
    } else {
        runs.try_iter()?.collect::<PyResult<_>>()?
    };
    if list.is_empty() {
        return Err(PyValueError::new_err("runs: no run"));
    }
    let mut inputs = Vec::new();
    for (k, r) in list.iter().enumerate() {
        let src = LogSource::of(r).map_err(|e| PyTypeError::new_err(format!("runs[{k}]: {e}")))?;
        let name = match &src {
            LogSource::Path(_) => src.name(),
            _ => format!("runs[{k}]"),
        };
        inputs.push((name, src.reader()?));
    }
    let res = py.allow_threads(|| {
        let mut read = Vec::new();
        let mut errs = Vec::new();
        for (name, rd) in inputs {
            match read_run_from(io::BufReader::with_capacity(CHUNK, rd), &name, &cfg) {
                Ok(r) => read.push(r),
                Err(e) => errs.push(e),
            }
        }
        if !errs.is_empty() {
            return Err(cal::CalError::Inputs(errs));
        }
        cal::calibrate_runs(&read, order, cfg.thermal.t0)
    });
    let cal = res.map_err(|e| PyValueError::new_err(e.to_string()))?;
    let d = PyDict::new(py);
    d.set_item("order", cal.order)?;
    d.set_item("t0", cal.t0)?;
    let per_axis = |f: &dyn Fn(&cal::AxisFit) -> Vec<f64>| -> Vec<Vec<f64>> { cal.axes.iter().map(f).collect() };
    d.set_item("coeffs", numpy::PyArray2::from_vec2(py, &per_axis(&|a| a.coeffs.clone()))?)?;
    d.set_item("ci", numpy::PyArray2::from_vec2(py, &per_axis(&|a| a.ci.clone()))?)?;
    d.set_item("se", numpy::PyArray2::from_vec2(py, &per_axis(&|a| a.se.clone()))?)?;
    let col = |f: &dyn Fn(&cal::AxisFit) -> f64| PyArray1::from_vec(py, cal.axes.iter().map(f).collect::<Vec<f64>>());
    d.set_item("p2", col(&|a| a.p2))?;
    d.set_item("p2_ci", col(&|a| a.p2_ci))?;
    d.set_item("rms", col(&|a| a.rms))?;
    d.set_item("white", col(&|a| a.white))?;
    d.set_item("walk", col(&|a| a.walk))?;
    d.set_item(
        "levels",
        cal.axes
            .iter()
            .map(|a| match a.levels {
                Levels::Shared { .. } => "shared",
                Levels::PerRun { .. } => "per_run",
            })
            .collect::<Vec<_>>(),
    )?;
    d.set_item("range", (cal.range.0, cal.range.1))?;
    d.set_item("bins_used", cal.bins_used)?;
    d.set_item("warnings", cal.warnings.clone())?;
    let rl = PyList::empty(py);
    for r in &cal.runs {
        let rd = PyDict::new(py);
        rd.set_item("name", &r.name)?;
        rd.set_item("samples", r.samples)?;
        rd.set_item("duration_s", r.duration_s)?;
        rd.set_item("temp", (r.temp.0, r.temp.1))?;
        rd.set_item("used", r.used)?;
        rd.set_item("left_out", r.left_out.clone())?;
        rd.set_item("used_s", r.used_s)?;
        rd.set_item("cut_s", r.cut_s)?;
        rd.set_item("is_static", r.is_static)?;
        rd.set_item("offset", (r.offset[0], r.offset[1], r.offset[2]))?;
        let w = match r.warmup {
            Warmup::None => "none",
            Warmup::Cut => "cut",
            Warmup::AtLimit => "at_limit",
            Warmup::NotSeparable => "not_separable",
        };
        rd.set_item("warmup", w)?;
        rl.append(rd)?;
    }
    d.set_item("runs", rl)?;
    d.set_item("toml", cal.to_toml())?;
    d.set_item("report", cal.render())?;
    Ok(d)
}

// ---------------------------------------------------------------- bench

/// Bench helper: the Rust `Estimator::step` alone over the same samples
/// `update_batch` takes (one period apart, no checks, no output arrays).
/// Returns the loop's CPU time on this thread, s (as Python's
/// `time.thread_time`: a loaded machine's other work is not counted). Not
/// part of the API.
#[pyfunction]
#[pyo3(signature = (rate_hz, gyr, acc, mag, temp, config=None))]
fn _bench_step<'py>(
    py: Python<'py>,
    rate_hz: f64,
    gyr: &Bound<'py, PyAny>,
    acc: &Bound<'py, PyAny>,
    mag: &Bound<'py, PyAny>,
    temp: &Bound<'py, PyAny>,
    config: Option<&Bound<'py, PyAny>>,
) -> PyResult<f64> {
    let mut cfg = load_config(config)?;
    cfg.input.rate_hz = rate_hz;
    let (g, a, m, t) = (array(gyr, "gyr", Some(3))?, array(acc, "acc", Some(3))?, array(mag, "mag", Some(3))?, array(temp, "temp", None)?);
    let (g, a, m, t) = (g.readonly(), a.readonly(), m.readonly(), t.readonly());
    let (g, a, m, t) = (g.as_slice()?, a.as_slice()?, m.as_slice()?, t.as_slice()?);
    let samples: Vec<Sample> = (0..t.len())
        .map(|i| Sample {
            cnt: i as u16,
            t_us: (i as f64 / rate_hz * 1e6) as u64,
            steps: (i > 0) as u32,
            gyro: [g[3 * i], g[3 * i + 1], g[3 * i + 2]],
            accel: [a[3 * i], a[3 * i + 1], a[3 * i + 2]],
            magn: [m[3 * i], m[3 * i + 1], m[3 * i + 2]],
            temp: t[i],
            diag: 0,
        })
        .collect();
    Ok(py.allow_threads(|| {
        let mut est = Core::new(&cfg);
        let t0 = thread_cpu_s();
        let mut acc = 0.0;
        for s in &samples {
            acc += std::hint::black_box(est.step(s)).roll;
        }
        std::hint::black_box(acc);
        thread_cpu_s() - t0
    }))
}

/// This thread's CPU time, s (`CLOCK_THREAD_CPUTIME_ID`, what Python's
/// `time.thread_time` reads).
fn thread_cpu_s() -> f64 {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: a valid timespec to write into; the call has no other effect.
    unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

#[pymodule]
fn _gyrocomp(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Estimator>()?;
    m.add_class::<Estimate1>()?;
    m.add_function(wrap_pyfunction!(replay, m)?)?;
    m.add_function(wrap_pyfunction!(replay_chunks, m)?)?;
    m.add_class::<ReplayChunks>()?;
    m.add_function(wrap_pyfunction!(standstills::replay_standstills, m)?)?;
    m.add_function(wrap_pyfunction!(read_log, m)?)?;
    m.add_function(wrap_pyfunction!(calibrate, m)?)?;
    m.add_function(wrap_pyfunction!(gap::gap, m)?)?;
    m.add_function(wrap_pyfunction!(_bench_step, m)?)?;
    m.add("CSV_COLUMNS", core_replay::CSV_HEADER.trim().split(',').collect::<Vec<_>>())?;
    let fl = PyDict::new(m.py());
    for (name, bit) in gyrocomp::mcapout::FLAG_NAMES {
        fl.set_item(name.to_ascii_uppercase(), bit)?;
    }
    m.add("FLAGS", fl)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
