//! From a recording in physical units to ADIS frames: scales, the sample
//! counter, and the candump log (optionally merged with another bus's log).

use super::csv::ImuCsv;
use crate::adis::{builtin_profile, InputIds, Profile, RawSample};
use crate::candump::{parse_line, write_line, LineReader};
use crate::config::{ACCEL_LSB, GYRO_LSB, MAGN_LSB, TEMP_LSB};
use std::io::{BufRead, Write};

/// Auto scales leave this much headroom above the data's largest |value|.
pub const HEADROOM: f64 = 1.25;
/// Largest register value.
const FULL: f64 = i16::MAX as f64;

/// How one channel's LSB was chosen.
#[derive(Clone, Debug, PartialEq)]
pub enum ScaleSource {
    /// The profile's LSB covers the data.
    Profile,
    /// The finest LSB (two significant digits) whose range covers the data
    /// with `HEADROOM`, and no finer than the config's range of the key.
    Auto,
    /// No data on the channel: the profile's LSB is kept.
    Unused,
}

/// The register scales of an import (a profile with overridden LSBs).
#[derive(Clone, Debug)]
pub struct Scales {
    pub profile: Profile,
    /// Largest |value| per channel: gyro, accel, magn, temperature about the offset.
    pub max: [f64; 4],
    pub source: [ScaleSource; 4],
}

/// The smallest "two significant digits" number >= `x` (x > 0), exact in decimal.
fn round_up_2sig(x: f64) -> f64 {
    let e = x.log10().floor() as i32 - 1;
    let m = (x / 10f64.powi(e)).ceil() as i64;
    let s = format!("{m}e{e}");
    let v: f64 = s.parse().unwrap_or(x);
    if v < x {
        format!("{}e{e}", m + 1).parse().unwrap_or(x)
    } else {
        v
    }
}

/// The finest LSB whose 16-bit range covers `max` with headroom.
pub fn auto_lsb(max: f64) -> f64 {
    round_up_2sig(max * HEADROOM / FULL)
}

fn max_abs3(v: &[[f64; 3]]) -> f64 {
    v.iter().flat_map(|x| x.iter()).fold(0.0f64, |m, x| m.max(x.abs()))
}

/// Channel `k`'s values (gyro, accel, magn, temperature about `offset`)
/// with their line and axis column.
fn channel(data: &ImuCsv, k: usize, offset: f64) -> Vec<(f64, u64, &'static str)> {
    let v3 = |v: &[[f64; 3]], names: [&'static str; 3]| -> Vec<(f64, u64, &'static str)> {
        v.iter().zip(&data.line).flat_map(|(x, l)| (0..3).map(move |i| (x[i].abs(), *l, names[i]))).collect()
    };
    match k {
        0 => v3(&data.gyro, ["gx", "gy", "gz"]),
        1 => v3(&data.accel, ["ax", "ay", "az"]),
        2 => data.magn.as_deref().map(|m| v3(m, ["mx", "my", "mz"])).unwrap_or_default(),
        _ => data.temp.as_deref().unwrap_or_default().iter().zip(&data.line).map(|(t, l)| ((t - offset).abs(), *l, "temp")).collect(),
    }
}

/// Refuse an auto scale that a few outliers made so coarse that the rest
/// of the channel is erased: 99 % of its values within one LSB of 0 while
/// its largest value set the scale. The error names the largest value's
/// line and column (the CSV's names, before `--axes`).
fn erased_by_outlier(data: &ImuCsv, k: usize, lsb: f64, offset: f64) -> Result<(), String> {
    let mut v = channel(data, k, offset);
    if v.is_empty() {
        return Ok(());
    }
    let (max, line, col) = v.iter().copied().fold((0.0, 0, ""), |m, x| if x.0 > m.0 { x } else { m });
    let at = ((v.len() as f64 * 0.99) as usize).min(v.len() - 1);
    let q = *v.select_nth_unstable_by(at, |a, b| a.0.total_cmp(&b.0)).1;
    if q.0 > 0.0 && lsb > q.0 {
        let unit = ["deg/s", "g", "gauss", "deg C"][k];
        return Err(format!(
            "line {line}, column {col}: {max} {unit} is {:.0} times the channel's 99th percentile ({} {unit}): scaled to it, the LSB would be {lsb} {unit} \
             and 99 % of the channel's values would round to 0 or +-1 LSB. An outlier? Remove the line, or give --profile",
            max / q.0,
            q.0
        ));
    }
    Ok(())
}

/// Choose the scales: the profile's LSB where it covers the data, the finest
/// LSB with headroom otherwise (or without a profile).
pub fn choose_scales(data: &ImuCsv, profile: Option<&str>) -> Result<Scales, String> {
    let base_name = profile.unwrap_or("adis16448");
    let mut p = builtin_profile(base_name)
        .ok_or_else(|| format!("unknown profile {base_name:?} (known: {})", crate::adis::BUILTIN_PROFILES.join(", ")))?;
    let max = [
        max_abs3(&data.gyro),
        max_abs3(&data.accel),
        data.magn.as_deref().map(max_abs3).unwrap_or(0.0),
        data.temp.as_deref().map(|t| t.iter().fold(0.0f64, |m, x| m.max((x - p.temp_offset).abs()))).unwrap_or(0.0),
    ];
    let lsbs = [p.gyro_lsb, p.accel_lsb, p.magn_lsb, p.temp_lsb];
    let mut source = [ScaleSource::Unused, ScaleSource::Unused, ScaleSource::Unused, ScaleSource::Unused];
    let mut chosen = lsbs;
    for k in 0..4 {
        if max[k] == 0.0 {
            continue;
        }
        if profile.is_some() && lsbs[k] > 0.0 && max[k] <= FULL * lsbs[k] {
            source[k] = ScaleSource::Profile;
        } else {
            // never finer than the config accepts (a channel that barely moves)
            let floor = [GYRO_LSB.0, ACCEL_LSB.0, MAGN_LSB.0, TEMP_LSB.0][k];
            chosen[k] = auto_lsb(max[k]).max(floor);
            source[k] = ScaleSource::Auto;
            erased_by_outlier(data, k, chosen[k], p.temp_offset)?;
        }
    }
    p.gyro_lsb = chosen[0];
    p.accel_lsb = chosen[1];
    p.magn_lsb = chosen[2];
    p.temp_lsb = chosen[3];
    Ok(Scales { profile: p, max, source })
}

/// The sample counter of every sample.
#[derive(Clone, Debug)]
pub struct Timing {
    pub rate_hz: f64,
    /// The rate was estimated from `t` (1 / median spacing).
    pub estimated: bool,
    /// Sample index from the first sample (DATA_CNT = index mod 65536).
    pub index: Vec<u64>,
    /// Counter gaps (a time gap of more than 1.5 periods) and the samples they skip.
    pub gaps: u64,
    pub lost: u64,
    /// Samples closer than half a period to the previous one, put one period after it.
    pub crowded: u64,
}

/// The counter from the time column: index = round((t - t0) * rate), at
/// least one more than the previous sample's. A gap of more than 32767
/// periods cannot be told from a counter going backwards and is refused.
pub fn plan_counter(data: &ImuCsv, rate: Option<f64>, path: &str) -> Result<Timing, String> {
    let t = &data.t;
    let (rate_hz, estimated) = match rate {
        Some(r) => (r, false),
        None => {
            if t.len() < 2 {
                return Err(format!("{path}: one sample only: the rate cannot be estimated from t (give --rate)"));
            }
            // The median spacing, refined over the whole recording: the
            // number of periods (each spacing in median periods, rounded)
            // over the time they span. Time stamps rounded to the microsecond
            // would otherwise leave a rate error that adds up over a long run.
            let mut dt: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
            dt.sort_by(|a, b| a.total_cmp(b));
            let med = dt[dt.len() / 2];
            let periods: f64 = t.windows(2).map(|w| ((w[1] - w[0]) / med).round().max(1.0)).sum();
            (periods / (t[t.len() - 1] - t[0]), true)
        }
    };
    let mut index = Vec::with_capacity(t.len());
    let (mut gaps, mut lost, mut crowded) = (0, 0, 0);
    for k in 0..t.len() {
        let want = ((t[k] - t[0]) * rate_hz).round().max(0.0) as u64;
        let i = match index.last() {
            None => 0,
            Some(&prev) => {
                let i = want.max(prev + 1);
                if want <= prev {
                    crowded += 1;
                }
                let step = i - prev;
                if step > i16::MAX as u64 {
                    return Err(format!(
                        "{path} line {}, column t: a gap of {:.3} s ({step} periods) is longer than the 16-bit sample counter can express (32767 periods)",
                        data.line[k],
                        t[k] - t[k - 1]
                    ));
                }
                if step > 1 {
                    gaps += 1;
                    lost += step - 1;
                }
                i
            }
        };
        index.push(i);
    }
    if !estimated && crowded * 2 > t.len() as u64 {
        return Err(format!(
            "{path}: --rate {rate_hz} Hz: {crowded} of the {} samples are closer than half a period (1/{rate_hz} s) to the one before; \
             the recording's t says about {:.6} Hz (leave --rate out to take it from t)",
            t.len(),
            (t.len() - 1) as f64 / (t[t.len() - 1] - t[0])
        ));
    }
    Ok(Timing { rate_hz, estimated, index, gaps, lost, crowded })
}

/// What writing the log did.
#[derive(Clone, Debug, Default)]
pub struct LogStats {
    pub samples: u64,
    pub imu_frames: u64,
    /// Lines merged from the other bus's log.
    pub merged_lines: u64,
    /// Lines of the other bus's log before the first sample, left out
    /// (`--from`: the unit was not on yet).
    pub merged_before: u64,
}

/// Another bus's candump log, merged line by line.
pub struct Merge<'a> {
    pub name: String,
    pub reader: Box<dyn BufRead + 'a>,
    /// Leave out its lines stamped before the first sample (`--from`: the
    /// unit was not on yet).
    pub drop_before: bool,
}

impl Merge<'static> {
    /// The candump log at `p` (gzip allowed), every line kept.
    pub fn open(p: &std::path::Path) -> Result<Merge<'static>, String> {
        Ok(Merge { name: p.display().to_string(), reader: super::csv::open_text(p)?, drop_before: false })
    }
}

/// One pending line of the merged log.
struct Pending {
    t_us: u64,
    line: Vec<u8>,
}

fn next_merge_line(m: &mut LineReader<Box<dyn BufRead + '_>>, name: &str, ids: &InputIds) -> Result<Option<Pending>, String> {
    loop {
        let no = m.line_no + 1;
        let line = match m.next_line().map_err(|e| format!("{name} line {no}: {e}"))? {
            None => return Ok(None),
            Some(Err(e)) => return Err(format!("{name} line {no}: {e}")),
            Some(Ok(l)) => l,
        };
        let line = line.strip_suffix(b"\r").unwrap_or(line);
        if line.iter().all(u8::is_ascii_whitespace) {
            continue;
        }
        let f = parse_line(line).map_err(|e| format!("{name} line {no}: {e}"))?;
        if !f.extended && !f.error && ids.part(f.id).is_some() {
            return Err(format!(
                "{name} line {no}: CAN ID {:03X} is one of the IMU's input IDs (0x100..0x103): the merged log would mix two sources on one ID",
                f.id
            ));
        }
        let t_us = f.t_us;
        return Ok(Some(Pending { t_us, line: line.to_vec() }));
    }
}

/// Write the recording as ADIS frames (four per sample, stamped
/// `epoch_us + t` and 120 us apart, or a quarter period at high rates),
/// merged by timestamp with `merge` when given (its lines are copied as they
/// are; on equal timestamps the other bus's line comes first).
pub fn write_log<W: Write>(
    out: &mut W,
    data: &ImuCsv,
    sc: &Scales,
    timing: &Timing,
    epoch_us: u64,
    iface: &str,
    merge: Option<Merge<'_>>,
) -> Result<LogStats, String> {
    let ids = InputIds::DEFAULT;
    let p = &sc.profile;
    let period_us = 1e6 / timing.rate_hz;
    let spacing = (period_us / 4.0).floor().clamp(0.0, 120.0) as u64;
    let mut st = LogStats::default();
    let mut buf: Vec<u8> = Vec::with_capacity(1 << 20);
    let (mut mr, mname, drop_before) = match merge {
        Some(m) => (Some(LineReader::new(m.reader)), m.name, m.drop_before),
        None => (None, String::new(), false),
    };
    let mut pending = match mr.as_mut() {
        Some(r) => next_merge_line(r, &mname, &ids)?,
        None => None,
    };
    let werr = |e: std::io::Error| format!("writing the log: {e}");
    for k in 0..data.len() {
        let t_abs = epoch_us as f64 + data.t[k] * 1e6;
        // replay reads at most twelve digits of seconds
        if !(0.0..1e18).contains(&t_abs) {
            return Err(format!(
                "line {}, column t: {} s gives a log timestamp before 1970 or beyond 999999999999 s, the most a candump log holds (--epoch {} s)",
                data.line[k],
                data.t[k],
                epoch_us / 1_000_000
            ));
        }
        let t_us = t_abs.round() as u64;
        let magn = data.magn.as_ref().map(|m| m[k]).unwrap_or([0.0; 3]);
        let temp = data.temp.as_ref().map(|t| t[k]).unwrap_or(p.temp_offset);
        let mut raw = RawSample::quantise(p, data.gyro[k], data.accel[k], magn, temp);
        raw.cnt = (timing.index[k] & 0xFFFF) as u16;
        for (i, d) in raw.encode().iter().enumerate() {
            let ft = t_us + spacing * i as u64;
            while let (Some(pd), Some(r)) = (pending.as_ref(), mr.as_mut()) {
                if pd.t_us > ft {
                    break;
                }
                if drop_before && st.imu_frames == 0 && pd.t_us < ft {
                    st.merged_before += 1;
                } else {
                    buf.extend_from_slice(&pd.line);
                    buf.push(b'\n');
                    st.merged_lines += 1;
                }
                pending = next_merge_line(r, &mname, &ids)?;
            }
            write_line(&mut buf, ft, iface.as_bytes(), ids.all()[i], d);
            st.imu_frames += 1;
        }
        st.samples += 1;
        if buf.len() >= 1 << 20 {
            out.write_all(&buf).map_err(werr)?;
            buf.clear();
        }
    }
    while let (Some(pd), Some(r)) = (pending.take(), mr.as_mut()) {
        buf.extend_from_slice(&pd.line);
        buf.push(b'\n');
        st.merged_lines += 1;
        pending = next_merge_line(r, &mname, &ids)?;
        if buf.len() >= 1 << 20 {
            out.write_all(&buf).map_err(werr)?;
            buf.clear();
        }
    }
    out.write_all(&buf).map_err(werr)?;
    Ok(st)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn auto_lsb_is_the_finest_two_digit_step_with_headroom() {
        let max = std::hint::black_box(721.3355);
        let l = auto_lsb(max);
        assert_eq!(l, 0.028);
        assert!(max * HEADROOM <= FULL * l);
        assert!(max * HEADROOM > FULL * 0.027, "0.027 would not cover it: 0.028 is the finest");
        assert_eq!(round_up_2sig(0.0012), 0.0012);
        assert_eq!(round_up_2sig(0.00121), 0.0013);
        assert_eq!(round_up_2sig(9.95), 10.0);
    }

    #[test]
    fn counter_from_time_with_a_gap_and_jitter() {
        // 100 Hz, a 0.05 s hole after the third sample, one sample 3 ms early
        let mut d = ImuCsv { t: vec![0.0, 0.01, 0.02, 0.07, 0.077, 0.09], line: (2..8).collect(), ..Default::default() };
        let tm = plan_counter(&d, None, "x").unwrap();
        assert!((tm.rate_hz - 100.0).abs() < 1e-9 && tm.estimated);
        assert_eq!(tm.index, vec![0, 1, 2, 7, 8, 9]);
        assert_eq!((tm.gaps, tm.lost, tm.crowded), (1, 4, 0));
        // a rate given too low crowds samples onto one period
        let tm = plan_counter(&d, Some(50.0), "x").unwrap();
        assert_eq!(tm.index, vec![0, 1, 2, 4, 5, 6]);
        assert!(tm.crowded >= 2);
        d.t = vec![0.0, 0.01, 400.0];
        d.line = vec![2, 3, 4];
        let e = plan_counter(&d, Some(100.0), "in.csv").unwrap_err();
        assert!(e.contains("in.csv line 4, column t") && e.contains("16-bit"), "{e}");
    }
}
