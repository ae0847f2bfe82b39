//! `gyrocomp.replay_standstills`: a replay that keeps only what the fleet
//! job needs (every standstill's learned bias, the temperature range, the
//! final state), memory bounded by the number of standstills.

use super::*;

/// One standstill (a run of estimates flagged STANDSTILL) of a replay.
#[derive(Clone, Copy, Debug)]
struct Standstill {
    t_start: f64,
    t_end: f64,
    samples: u64,
    temp_sum: f64,
    temp_n: u64,
    temp_min: f64,
    temp_max: f64,
    /// The bias and its 1-sigma at the standstill's last sample, deg/s.
    bias: [f64; 3],
    sigma: [f64; 3],
    /// Sums of the measured rate (the bias-corrected rate plus the bias: the
    /// gyro in the vehicle frame) and of its square, per axis.
    gyro_sum: [f64; 3],
    gyro_sq: [f64; 3],
}

/// Keeps a replay's standstills and its temperature range, nothing per
/// sample: memory bounded by the number of standstills.
struct StandstillSink {
    cur: Option<Standstill>,
    done: Vec<Standstill>,
    samples: u64,
    temp_min: f64,
    temp_max: f64,
    t_end: f64,
    /// The last estimate was at rest: read the sigma after this push.
    fresh: bool,
    last_bias: [f64; 3],
}

impl StandstillSink {
    fn new() -> StandstillSink {
        StandstillSink {
            cur: None,
            done: Vec::new(),
            samples: 0,
            temp_min: f64::INFINITY,
            temp_max: f64::NEG_INFINITY,
            t_end: 0.0,
            fresh: false,
            last_bias: [f64::NAN; 3],
        }
    }

    fn close(&mut self) {
        if let Some(c) = self.cur.take() {
            self.done.push(c);
        }
    }
}

impl Sink for StandstillSink {
    #[inline]
    fn output(&mut self, e: &Estimate, _: &Frames) {
        self.samples += 1;
        self.t_end = e.t;
        self.last_bias = e.bias;
        let finite_t = e.temp.is_finite();
        if finite_t {
            self.temp_min = self.temp_min.min(e.temp);
            self.temp_max = self.temp_max.max(e.temp);
        }
        if e.flags & flags::STANDSTILL == 0 {
            self.close();
            return;
        }
        let c = self.cur.get_or_insert(Standstill {
            t_start: e.t,
            t_end: e.t,
            samples: 0,
            temp_sum: 0.0,
            temp_n: 0,
            temp_min: f64::INFINITY,
            temp_max: f64::NEG_INFINITY,
            bias: e.bias,
            sigma: [f64::NAN; 3],
            gyro_sum: [0.0; 3],
            gyro_sq: [0.0; 3],
        });
        c.t_end = e.t;
        c.samples += 1;
        c.bias = e.bias;
        for i in 0..3 {
            let g = e.rate[i] + e.bias[i];
            c.gyro_sum[i] += g;
            c.gyro_sq[i] += g * g;
        }
        if finite_t {
            c.temp_sum += e.temp;
            c.temp_n += 1;
            c.temp_min = c.temp_min.min(e.temp);
            c.temp_max = c.temp_max.max(e.temp);
        }
        self.fresh = true;
    }
}

/// A replay that keeps only what a fleet job needs: every standstill's
/// learned bias (at its last sample) with its 1-sigma, its mean measured rate
/// (the gyro in the vehicle frame) with its standard error, its temperature, the
/// temperature range, the final state and the summary. The log is streamed
/// in 256 KiB chunks, so memory does not grow with its length.
#[pyfunction]
#[pyo3(signature = (log, config=None))]
pub fn replay_standstills<'py>(
    py: Python<'py>,
    log: &Bound<'py, PyAny>,
    config: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let cfg = load_config(config)?;
    let src = LogSource::of(log)?;
    let name = src.name();
    let input = io::BufReader::with_capacity(CHUNK, src.reader()?);
    let mut pipe = pipeline(&cfg)?;
    let mut sink = StandstillSink::new();
    let (sum, state, sigma) = py.allow_threads(|| {
        let sum = core_replay::run_inspect(&mut pipe, input, &mut sink, |p, s| {
            if s.fresh {
                s.fresh = false;
                if let (Some(m), Some(c)) = (p.estimator().mekf(), s.cur.as_mut()) {
                    c.sigma = m.bias_sigma().map(|v| v * R2D);
                }
            }
        });
        sink.close();
        let est = pipe.estimator();
        let state = est.learned().map(|l| {
            // saved at t = 0 (the Unix epoch): the same log gives the same state text
            let mut st = State::from_learned(&l, 0.0, est.slope_state());
            st.vehicle_axes = SavedAxes::of(est, cfg.mounting.rotation);
            st.to_file_bytes()
        });
        let sigma = est.mekf().map_or([f64::NAN; 3], |m| m.bias_sigma().map(|v| v * R2D));
        (sum, state, sigma)
    });
    let sum = sum.map_err(|e| io_err(&name, e))?;
    let d = PyDict::new(py);
    let ss = &sink.done;
    let k = ss.len();
    let col = |f: &dyn Fn(&Standstill) -> f64| PyArray1::from_vec(py, ss.iter().map(f).collect::<Vec<f64>>());
    let st = PyDict::new(py);
    st.set_item("t_start", col(&|s| s.t_start))?;
    st.set_item("t_end", col(&|s| s.t_end))?;
    st.set_item("samples", PyArray1::from_vec(py, ss.iter().map(|s| s.samples).collect::<Vec<u64>>()))?;
    st.set_item("temp", col(&|s| if s.temp_n > 0 { s.temp_sum / s.temp_n as f64 } else { f64::NAN }))?;
    st.set_item("temp_min", col(&|s| if s.temp_n > 0 { s.temp_min } else { f64::NAN }))?;
    st.set_item("temp_max", col(&|s| if s.temp_n > 0 { s.temp_max } else { f64::NAN }))?;
    let flat = |f: &dyn Fn(&Standstill) -> [f64; 3]| -> PyResult<Bound<'py, PyAny>> {
        Ok(PyArray1::from_vec(py, ss.iter().flat_map(f).collect::<Vec<f64>>()).reshape([k, 3])?.into_any())
    };
    st.set_item("bias", flat(&|s| s.bias)?)?;
    st.set_item("bias_sigma", flat(&|s| s.sigma)?)?;
    // the mean measured rate at rest and its standard error (sample scatter / sqrt(n))
    let n = |s: &Standstill| s.samples as f64;
    st.set_item("gyro_mean", flat(&|s| s.gyro_sum.map(|v| v / n(s)))?)?;
    st.set_item(
        "gyro_se",
        flat(&|s| {
            if s.samples < 2 {
                return [f64::NAN; 3];
            }
            std::array::from_fn(|i| {
                let m = s.gyro_sum[i] / n(s);
                let var = ((s.gyro_sq[i] - n(s) * m * m) / (n(s) - 1.0)).max(0.0);
                (var / n(s)).sqrt()
            })
        })?,
    )?;
    d.set_item("standstills", st)?;
    d.set_item("samples", sink.samples)?;
    let (lo, hi) = if sink.temp_min <= sink.temp_max { (sink.temp_min, sink.temp_max) } else { (f64::NAN, f64::NAN) };
    d.set_item("temp_min", lo)?;
    d.set_item("temp_max", hi)?;
    d.set_item("t_end", sink.t_end)?;
    d.set_item("bias", PyArray1::from_vec(py, sink.last_bias.to_vec()))?;
    d.set_item("bias_sigma", PyArray1::from_vec(py, sigma.to_vec()))?;
    let state = match state {
        Some(b) => Some(String::from_utf8_lossy(&b.map_err(|e| PyValueError::new_err(format!("state: {e}")))?).into_owned()),
        None => None,
    };
    d.set_item("state", state)?;
    d.set_item("summary", summary_dict(py, &sum)?)?;
    Ok(d)
}
