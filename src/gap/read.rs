//! Step 1, **read**: the measured data, the truth and the base model, joined
//! sample by sample on the truth's time grid.
//!
//! The result ([`Samples`]) holds, per sample, everything the later steps
//! need: time since power-on, temperature and its rate, the true rate, its
//! derivative and specific force, the measured gyro, and `y`, the measured
//! gyro minus the fixed part of the base model (the truth through
//! [`GyroModel::measure`] with the coefficients the base model gives).

use crate::adis::{Assembler, InputIds, Profile};
use crate::sim::model::{Effect, GyroInput, GyroModel, SensorModel};
use std::path::Path;

/// One measured sample.
#[derive(Clone, Copy, Debug, Default)]
pub struct MeasRow {
    pub t: f64,
    pub gyro: [f64; 3],
    /// Specific force, g (NaN where the source has none).
    pub acc: [f64; 3],
    pub temp: f64,
}

/// One truth row (`temp` NaN when the file has no temp column).
#[derive(Clone, Copy, Debug, Default)]
pub struct TruthIn {
    pub t: f64,
    pub rate: [f64; 3],
    pub f: [f64; 3],
    pub temp: f64,
    /// The rate's derivative when the source gives it (a measured reference:
    /// the derivative of the smoothed rate); None: the backward difference
    /// the simulator forms, deg/s^2.
    pub wd: Option<[f64; 3]>,
}

/// Read measured data: a candump log (ADIS contract, `profile`) or the CSV.
/// Times of a log are relative to its first sample (the log's first sample
/// is the truth's first row); a CSV's times are used as they are, unless
/// they start further from the truth's start than half its length (epoch
/// seconds, say): then they too are taken relative to their first row.
pub fn read_measured(path: &Path, profile: &Profile) -> Result<Vec<MeasRow>, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("cannot open {}: {e}", path.display()))?;
    measured_from_bytes(&bytes, &path.display().to_string(), profile)
}

/// [`read_measured`] of the file's bytes (gzip recognised); `name` names
/// them in errors (`name:line: ...`).
pub fn measured_from_bytes(bytes: &[u8], name: &str, profile: &Profile) -> Result<Vec<MeasRow>, String> {
    let bytes = crate::textfile::gunzip(bytes).map_err(|e| format!("{name}: cannot read: {e}"))?;
    let first = bytes.split(|b| *b == b'\n').map(|l| l.trim_ascii()).find(|l| !l.is_empty());
    match first {
        None => Err(format!("{name}: empty file")),
        Some(l) if l.starts_with(b"t,") || l.starts_with(b"t ,") => read_meas_csv(name, &bytes),
        Some(_) => read_meas_log(name, &bytes, profile),
    }
}

fn parse_row(l: &str, n: usize, name: &str, no: usize) -> Result<Vec<f64>, String> {
    let v: Vec<&str> = l.split(',').collect();
    if v.len() != n {
        return Err(format!("{name}:{no}: want {n} columns, got {}", v.len()));
    }
    v.iter()
        .enumerate()
        .map(|(col, s)| {
            let x: f64 = s.trim().parse().map_err(|_| format!("{name}:{no}: column {}: bad number {:?}", col + 1, s.trim()))?;
            if x.is_finite() {
                Ok(x)
            } else {
                Err(format!("{name}:{no}: column {}: not a finite number {:?}", col + 1, s.trim()))
            }
        })
        .collect()
}

const MEAS_HEADER: &str = "t,gx,gy,gz,ax,ay,az,mx,my,mz,temp";
const MEAS_NAMES: [&str; 11] = ["t", "gx", "gy", "gz", "ax", "ay", "az", "mx", "my", "mz", "temp"];

/// Physical range of a measured CSV column (a MEMS IMU's with a wide
/// margin): |gyro| <= 5000 deg/s, |specific force| <= 200 g, |field| <= 10
/// gauss, temperature -60..150 deg C, time 0..1e10 s.
fn meas_range(col: usize) -> (f64, f64) {
    match col {
        0 => (0.0, 1e10),
        1..=3 => (-5000.0, 5000.0),
        4..=6 => (-200.0, 200.0),
        7..=9 => (-10.0, 10.0),
        _ => (-60.0, 150.0),
    }
}

/// One measured CSV row: t and the gyro required; accelerometer,
/// magnetometer and temperature may be empty (NaN: no such channel).
fn parse_meas_row(l: &str, name: &str, no: usize) -> Result<[f64; 11], String> {
    let v: Vec<&str> = l.split(',').collect();
    if v.len() != 11 {
        return Err(format!("{name}:{no}: want 11 columns ({MEAS_HEADER}), got {}", v.len()));
    }
    let mut out = [f64::NAN; 11];
    for (col, s) in v.iter().enumerate() {
        let s = s.trim();
        let column = MEAS_NAMES[col];
        if s.is_empty() {
            if col <= 3 {
                return Err(format!("{name}:{no}: column {column}: empty (t and the gyro are required)"));
            }
            continue;
        }
        let x: f64 = s.parse().map_err(|_| format!("{name}:{no}: column {column}: bad number {s:?}"))?;
        let (lo, hi) = meas_range(col);
        if !(lo..=hi).contains(&x) {
            return Err(format!("{name}:{no}: column {column}: {s} is outside {lo}..{hi}"));
        }
        out[col] = x;
    }
    Ok(out)
}

fn read_meas_csv(name: &str, bytes: &[u8]) -> Result<Vec<MeasRow>, String> {
    let text = std::str::from_utf8(bytes).map_err(|_| format!("{name}: not UTF-8 text"))?;
    let mut out = Vec::new();
    let mut header = false;
    let mut prev: Option<[f64; 11]> = None;
    for (i, l) in text.lines().enumerate() {
        let no = i + 1;
        if l.trim().is_empty() {
            continue;
        }
        if !header {
            let h: String = l.chars().filter(|c| !c.is_whitespace()).collect();
            if h != MEAS_HEADER {
                return Err(format!("{name}:{no}: header must be {MEAS_HEADER}"));
            }
            header = true;
            continue;
        }
        let v = parse_meas_row(l, name, no)?;
        // a row repeated field for field is one sample logged twice (the FIRM files): kept once
        if prev.is_some_and(|p: [f64; 11]| p.iter().zip(&v).all(|(a, b)| a.to_bits() == b.to_bits())) {
            continue;
        }
        prev = Some(v);
        if let Some(p) = out.last().map(|r: &MeasRow| r.t) {
            if v[0] <= p {
                return Err(format!("{name}:{no}: time {} is not after the previous row's {p}", v[0]));
            }
        }
        out.push(MeasRow { t: v[0], gyro: [v[1], v[2], v[3]], acc: [v[4], v[5], v[6]], temp: v[10] });
    }
    if out.is_empty() {
        return Err(format!("{name}: no data rows"));
    }
    Ok(out)
}

fn read_meas_log(name: &str, bytes: &[u8], profile: &Profile) -> Result<Vec<MeasRow>, String> {
    let mut asm = Assembler::new(profile.clone(), InputIds::DEFAULT);
    let mut out = Vec::new();
    let mut t_first: Option<u64> = None;
    let stats = crate::replay::for_each_sample(bytes, &mut asm, |s| {
        if s.suspect() {
            return;
        }
        let t0 = *t_first.get_or_insert(s.t_us);
        if s.t_us >= t0 {
            out.push(MeasRow { t: (s.t_us - t0) as f64 * 1e-6, gyro: s.gyro, acc: s.accel, temp: s.temp });
        }
    })
    .map_err(|(line, e)| format!("{name}: read error after line {line}: {e}"))?;
    let (lines, bad) = (stats.lines, stats.bad_lines);
    let first_bad = stats.first_bad.map(|(l, e)| (l, e.to_string()));
    if let Some((no, e)) = &first_bad {
        if bad * 100 > lines || out.is_empty() {
            return Err(format!(
                "{}:{no}: {e} ({bad} of {lines} lines malformed; not a candump log in the ADIS contract or a CSV with header {MEAS_HEADER})",
                name
            ));
        }
    }
    if out.is_empty() {
        return Err(format!("{name}: no complete ADIS sample in {lines} lines"));
    }
    Ok(out)
}

/// Read `truth.csv` (`t,roll,pitch,yaw,p,q,r,fx,fy,fz[,temp]`); true when it has `temp`.
pub fn read_truth(path: &Path) -> Result<(Vec<TruthIn>, bool), String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{}: cannot read: {e}", path.display()))?;
    truth_from_bytes(&bytes, &path.display().to_string())
}

/// [`read_truth`] of the file's bytes; `name` names them in errors (`name:line: ...`).
pub fn truth_from_bytes(bytes: &[u8], name: &str) -> Result<(Vec<TruthIn>, bool), String> {
    let text = crate::textfile::str_of(bytes).map_err(|e| format!("{name}: cannot read: {e}"))?;
    let mut it = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty());
    let (_, h) = it.next().ok_or_else(|| format!("{name}: empty file"))?;
    let h: String = h.chars().filter(|c| !c.is_whitespace()).collect();
    let base = "t,roll,pitch,yaw,p,q,r,fx,fy,fz";
    let has_temp = if h == format!("{base},temp") {
        true
    } else if h == base {
        false
    } else {
        return Err(format!("{name}:1: header must be {base},temp (temp optional)"));
    };
    let n = if has_temp { 11 } else { 10 };
    let mut out: Vec<TruthIn> = Vec::new();
    for (i, l) in it {
        let no = i + 1;
        let v = parse_row(l, n, name, no)?;
        if let Some(p) = out.last() {
            if v[0] <= p.t {
                return Err(format!("{name}:{no}: time {} is not after the previous row's {}", v[0], p.t));
            }
        }
        out.push(TruthIn {
            t: v[0],
            rate: [v[4], v[5], v[6]],
            f: [v[7], v[8], v[9]],
            temp: if has_temp { v[10] } else { f64::NAN },
            wd: None,
        });
    }
    if out.len() < 2 {
        return Err(format!("{name}: fewer than 2 data rows"));
    }
    Ok((out, has_temp))
}

/// The base model: parsed like `sensor.toml`, except that an effect listed
/// without its table is free (fitted). Errors name the file and the key.
pub fn load_base(path: &Path) -> Result<SensorModel, String> {
    let text = crate::textfile::read(path).map_err(|e| format!("{}: cannot read: {e}", path.display()))?;
    parse_base(&text).map_err(|e| format!("{}: {e}", path.display()))
}

/// [`load_base`] from text.
pub fn parse_base(text: &str) -> Result<SensorModel, String> {
    let m: SensorModel = toml::from_str(text).map_err(|e| e.to_string())?;
    let mut fixed = m.clone();
    fixed.gyro.effects = fixed_effects(&m.gyro);
    // duplicates are an error even for free effects
    for (i, e) in m.gyro.effects.iter().enumerate() {
        if m.gyro.effects[..i].contains(e) {
            return Err(format!("gyro.effects: {} is listed twice", e.name()));
        }
    }
    fixed.validate().map_err(|(k, msg)| crate::sim::model::where_written(text, &k, &msg))?;
    Ok(m)
}

/// True when the model has the coefficient table of `e`.
pub(crate) fn has_table(g: &GyroModel, e: Effect) -> bool {
    match e {
        Effect::TurnOnBias => g.turn_on_bias.is_some(),
        Effect::ThermalLinear => g.thermal_linear.is_some(),
        Effect::ThermalQuadratic => g.thermal_quadratic.is_some(),
        Effect::ThermalRate => g.thermal_rate.is_some(),
        Effect::WarmupTransient => g.warmup_transient.is_some(),
        Effect::GSensitivity => g.g_sensitivity.is_some(),
        Effect::ScaleFactor => g.scale_factor.is_some(),
        Effect::Misalignment => g.misalignment.is_some(),
        Effect::TimeDelay => g.time_delay.is_some(),
    }
}

/// The listed effects whose coefficients are given (the fixed part of the model).
pub(crate) fn fixed_effects(g: &GyroModel) -> Vec<Effect> {
    g.effects.iter().copied().filter(|e| has_table(g, *e)).collect()
}

/// Measured and truth joined sample by sample (column vectors).
pub struct Samples {
    /// Time since power-on (the truth's time), s.
    pub t: Vec<f64>,
    /// Temperature the thermal terms use (the truth's, else the measured one), deg C.
    pub temp: Vec<f64>,
    /// Its rate, deg C/s (slope of a local quadratic through +-5 s of 1-s mean temperatures).
    pub dtemp: Vec<f64>,
    /// True rate, deg/s; its derivative (backward difference, as the simulator forms it), deg/s^2; specific force, g.
    pub w: [Vec<f64>; 3],
    pub wd: [Vec<f64>; 3],
    pub f: [Vec<f64>; 3],
    /// Measured gyro, deg/s.
    pub meas: [Vec<f64>; 3],
    /// Measured gyro minus the fixed part of the base model, deg/s.
    pub y: [Vec<f64>; 3],
    /// The measured temperature (NaN where there is none), deg C.
    pub meas_temp: Vec<f64>,
    /// True when `temp` is the truth's.
    pub truth_temp: bool,
    /// Sample rate of the joined data, Hz.
    pub rate_hz: f64,
    /// Reference temperatures of the linear and quadratic thermal terms, deg C.
    pub t0_lin: f64,
    pub t0_quad: f64,
}

impl Samples {
    pub fn len(&self) -> usize {
        self.t.len()
    }

    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    pub fn duration(&self) -> f64 {
        self.t.last().copied().unwrap_or(0.0) - self.t.first().copied().unwrap_or(0.0)
    }
}

/// The median time step of the truth, s.
fn median_step(truth: &[TruthIn]) -> f64 {
    let mut d: Vec<f64> = truth.windows(2).map(|w| w[1].t - w[0].t).collect();
    d.sort_by(|a, b| a.total_cmp(b));
    d[d.len() / 2]
}

/// The time the samples `t` cover: their span less the steps longer than
/// max(1 s, 10 median steps `dt`) (a reference lost, bursts of a static
/// recording); the span itself when there is no such step.
fn covered(t: &[f64], dt: f64) -> f64 {
    let jump = (10.0 * dt).max(1.0);
    let gaps: f64 = t.windows(2).map(|w| w[1] - w[0]).filter(|d| *d > jump).sum();
    (t[t.len() - 1] - t[0]) - gaps
}

/// Join measured and truth on time; evaluate the fixed part of the base model.
pub fn join(meas: &[MeasRow], truth: &[TruthIn], truth_has_temp: bool, base: &GyroModel) -> Result<Samples, String> {
    if truth.len() < 2 {
        return Err("truth: fewer than 2 rows".into());
    }
    let t0 = truth[0].t;
    let dt = median_step(truth);
    if dt.is_nan() || dt <= 0.0 {
        return Err("truth: time does not advance".into());
    }
    // rate derivative as the simulator forms it (backward difference), or the source's own
    let mut wd = vec![[0.0; 3]; truth.len()];
    for (k, w) in wd.iter_mut().enumerate() {
        if let Some(d) = truth[k].wd {
            *w = d;
            continue;
        }
        if k == 0 {
            continue;
        }
        let h = truth[k].t - truth[k - 1].t;
        for (a, x) in w.iter_mut().enumerate() {
            *x = (truth[k].rate[a] - truth[k - 1].rate[a]) / h;
        }
    }
    // match: measured time (relative to its start for logs; CSV as given) on the truth grid
    let mt0 = meas[0].t;
    let rel = meas.iter().all(|m| m.t >= 0.0) && (mt0 - t0).abs() > 0.5 * (truth[truth.len() - 1].t - t0);
    let mut pairs: Vec<(&MeasRow, usize)> = Vec::with_capacity(meas.len());
    for m in meas {
        let t = if rel { m.t - mt0 + t0 } else { m.t };
        // the nearest truth row (a truth with gaps, e.g. a reference's valid stretches, too)
        let i = truth.partition_point(|r| r.t < t);
        let k = match (i.checked_sub(1), (i < truth.len()).then_some(i)) {
            (Some(a), Some(b)) => {
                if t - truth[a].t <= truth[b].t - t {
                    a
                } else {
                    b
                }
            }
            (Some(a), None) => a,
            (None, Some(b)) => b,
            (None, None) => continue,
        };
        if (truth[k].t - t).abs() <= 0.5 * dt && pairs.last().is_none_or(|p| p.1 < k) {
            pairs.push((m, k));
        }
    }
    if pairs.len() < meas.len() / 2 || pairs.len() < 100 {
        return Err(format!(
            "measured and truth do not line up in time: {} of {} measured samples have a truth row within half a period",
            pairs.len(),
            meas.len()
        ));
    }
    let temp = |m: &MeasRow, k: usize| if truth_has_temp { truth[k].temp } else { m.temp };
    let tt = |p: &(&MeasRow, usize)| truth[p.1].t;
    let tstart = tt(&pairs[0]);
    let span = tt(&pairs[pairs.len() - 1]) - tstart;
    // dT/dt: slope at each 1-s mean of a local quadratic through the 1-s mean
    // temperatures within +-5 s (a line would be biased by the curvature of a
    // self-heating exponential, most at the start)
    let nsec = (span.floor() as usize) + 1;
    let mut sec = vec![(0.0, 0.0, 0.0); nsec];
    for p in &pairs {
        let s = ((tt(p) - tstart).floor() as usize).min(nsec - 1);
        sec[s].0 += tt(p);
        sec[s].1 += temp(p.0, p.1);
        sec[s].2 += 1.0;
    }
    let pts: Vec<(f64, f64)> = sec.iter().filter(|s| s.2 > 0.0).map(|s| (s.0 / s.2, s.1 / s.2)).collect();
    let slope_at = |i: usize| -> f64 {
        let lo = i.saturating_sub(5);
        let hi = (i + 6).min(pts.len());
        let w = &pts[lo..hi];
        if w.len() < 2 {
            return 0.0;
        }
        // least squares of T = a + b u + c u^2, u = t - t_i; the slope at t_i is b
        let tc = pts[i].0;
        let mut m = [[0.0; 3]; 3];
        let mut v = [0.0; 3];
        for p in w {
            let u = p.0 - tc;
            let x = [1.0, u, u * u];
            for r in 0..3 {
                v[r] += x[r] * p.1;
                for c in 0..3 {
                    m[r][c] += x[r] * x[c];
                }
            }
        }
        let k = if w.len() >= 4 { 3 } else { 2 };
        let a = nalgebra::DMatrix::from_fn(k, k, |r, c| m[r][c]);
        let b = nalgebra::DVector::from_fn(k, |r, _| v[r]);
        a.lu().solve(&b).map_or(0.0, |x| x[1])
    };
    let dts: Vec<f64> = (0..pts.len()).map(slope_at).collect();
    let dtemp_at = |t: f64| -> f64 {
        let i = pts.partition_point(|p| p.0 < t);
        if i == 0 {
            return dts[0];
        }
        if i >= pts.len() {
            return dts[pts.len() - 1];
        }
        let (a, b) = (pts[i - 1], pts[i]);
        let u = (t - a.0) / (b.0 - a.0);
        dts[i - 1] * (1.0 - u) + dts[i] * u
    };
    let mut fixed = base.clone();
    fixed.effects = fixed_effects(base);
    let n = pairs.len();
    let v3 = || [Vec::with_capacity(n), Vec::with_capacity(n), Vec::with_capacity(n)];
    let mut s = Samples {
        t: Vec::with_capacity(n),
        temp: Vec::with_capacity(n),
        dtemp: Vec::with_capacity(n),
        w: v3(),
        wd: v3(),
        f: v3(),
        meas: v3(),
        y: v3(),
        meas_temp: Vec::with_capacity(n),
        truth_temp: truth_has_temp,
        rate_hz: if span > 0.0 { (n - 1) as f64 / covered(&pairs.iter().map(tt).collect::<Vec<_>>(), dt) } else { 1.0 / dt },
        t0_lin: base.thermal_linear.as_ref().map(|c| c.t0).or(base.thermal_quadratic.as_ref().map(|c| c.t0)).unwrap_or(25.0),
        t0_quad: 25.0,
    };
    s.t0_quad = base.thermal_quadratic.as_ref().map(|c| c.t0).unwrap_or(s.t0_lin);
    for (m, k) in &pairs {
        let tr = &truth[*k];
        let tc = temp(m, *k);
        let x = GyroInput { rate: tr.rate, rate_dot: wd[*k], f: tr.f, temp: tc, temp_rate: dtemp_at(tr.t), t_on: tr.t };
        let sim = fixed.measure(&x);
        s.t.push(tr.t);
        s.temp.push(tc);
        s.dtemp.push(x.temp_rate);
        s.meas_temp.push(m.temp);
        for a in 0..3 {
            s.w[a].push(tr.rate[a]);
            s.wd[a].push(wd[*k][a]);
            s.f[a].push(tr.f[a]);
            s.meas[a].push(m.gyro[a]);
            s.y[a].push(m.gyro[a] - sim[a]);
        }
    }
    Ok(s)
}
