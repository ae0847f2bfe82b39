//! Reading an IMU recording as CSV: `t,gx,gy,gz,ax,ay,az,mx,my,mz,temp`.
//!
//! Columns are found by name in the header (any order; unknown columns are
//! ignored and listed). `t` (s), `gx..gz` (deg/s) and `ax..az` (g, specific
//! force) are required; `mx,my,mz` (gauss, all three or none) and `temp`
//! (deg C) may be absent, or present with every value empty. A value is a
//! finite number within its column's physical range ([`RANGES`]: gyro
//! +-10000 deg/s, accel +-1000 g, magn +-100 gauss, temp -100..200 deg C);
//! anything else is an error naming the line and the column.
//! Gzip input (`.gz`) is recognised by its magic bytes, whatever the name.

use std::fs::File;
use std::io::{BufRead, BufReader};
use std::path::Path;

/// The columns this reader knows, in the contract's order.
pub const COLUMNS: [&str; 11] = ["t", "gx", "gy", "gz", "ax", "ay", "az", "mx", "my", "mz", "temp"];
/// The first seven are required.
const REQUIRED: usize = 7;

/// Open a text file, transparently gunzipping it when it starts with the gzip magic.
pub fn open_text(path: &Path) -> Result<Box<dyn BufRead>, String> {
    let mut f = File::open(path).map_err(|e| format!("cannot open {}: {e}", path.display()))?;
    let mut magic = [0u8; 2];
    let n = crate::textfile::read_up_to(&mut f, &mut magic).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    let f = File::open(path).map_err(|e| format!("cannot open {}: {e}", path.display()))?;
    if n == 2 && magic == [0x1f, 0x8b] {
        Ok(Box::new(BufReader::with_capacity(1 << 16, flate2::read::MultiGzDecoder::new(BufReader::new(f)))))
    } else {
        Ok(Box::new(BufReader::with_capacity(1 << 16, f)))
    }
}

/// A body-axis mapping onto FRD: `x,-y,-z` means FRD x = source x,
/// FRD y = -source y, FRD z = -source z (the FLU -> FRD map).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxesMap {
    /// Source axis index for each FRD axis.
    pub src: [usize; 3],
    /// Sign for each FRD axis.
    pub sign: [f64; 3],
}

impl AxesMap {
    pub const IDENTITY: AxesMap = AxesMap { src: [0, 1, 2], sign: [1.0; 3] };

    /// Parse `x,-y,-z` (three entries, each an optionally signed x, y or z,
    /// every source axis used once).
    pub fn parse(s: &str) -> Result<AxesMap, String> {
        let bad = |why: &str| format!("--axes {s:?}: {why} (want three of x, y, z with optional signs, e.g. x,-y,-z)");
        let parts: Vec<&str> = s.split(',').map(str::trim).collect();
        if parts.len() != 3 {
            return Err(bad("not three entries"));
        }
        let mut m = AxesMap::IDENTITY;
        let mut used = [false; 3];
        for (i, p) in parts.iter().enumerate() {
            let (sign, axis) = match p.as_bytes() {
                [b'-', a] => (-1.0, *a),
                [b'+', a] | [a] => (1.0, *a),
                _ => return Err(bad(&format!("entry {p:?}"))),
            };
            let k = match axis.to_ascii_lowercase() {
                b'x' => 0,
                b'y' => 1,
                b'z' => 2,
                _ => return Err(bad(&format!("entry {p:?}"))),
            };
            if used[k] {
                return Err(bad(&format!("axis {} used twice", axis as char)));
            }
            used[k] = true;
            m.src[i] = k;
            m.sign[i] = sign;
        }
        Ok(m)
    }

    /// Map a source vector onto FRD.
    pub fn apply(&self, v: [f64; 3]) -> [f64; 3] {
        [0, 1, 2].map(|i| self.sign[i] * v[self.src[i]])
    }

    /// A proper rotation (determinant +1)? A reflection would turn a
    /// right-handed frame into a left-handed one.
    pub fn is_rotation(&self) -> bool {
        // sign of the permutation times the product of the signs
        let p = self.src;
        let inversions = (p[0] > p[1]) as u8 + (p[0] > p[2]) as u8 + (p[1] > p[2]) as u8;
        let perm = if inversions.is_multiple_of(2) { 1.0 } else { -1.0 };
        perm * self.sign[0] * self.sign[1] * self.sign[2] > 0.0
    }
}

/// An IMU recording in FRD, physical units.
#[derive(Clone, Debug, Default)]
pub struct ImuCsv {
    /// Line number of every sample (1-based, the header is line 1).
    pub line: Vec<u64>,
    pub t: Vec<f64>,
    pub gyro: Vec<[f64; 3]>,
    pub accel: Vec<[f64; 3]>,
    /// None when the recording has no magnetometer.
    pub magn: Option<Vec<[f64; 3]>>,
    /// None when the recording has no temperature.
    pub temp: Option<Vec<f64>>,
    /// Header columns this reader does not know (ignored).
    pub ignored: Vec<String>,
}

impl ImuCsv {
    pub fn len(&self) -> usize {
        self.t.len()
    }
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Keep the samples at and after `t0` (s, the recording's clock).
    pub fn keep_from(&mut self, t0: f64) {
        let k = self.t.iter().position(|t| *t >= t0).unwrap_or(self.t.len());
        self.line.drain(..k);
        self.t.drain(..k);
        self.gyro.drain(..k);
        self.accel.drain(..k);
        if let Some(m) = self.magn.as_mut() {
            m.drain(..k);
        }
        if let Some(x) = self.temp.as_mut() {
            x.drain(..k);
        }
    }
}

/// The physical range of each column (`t` any finite number): beyond any
/// real part's range with a wide margin. The fastest MEMS gyros measure
/// +-4000 deg/s, high-g accelerometers +-400 g, magnetometers +-50 gauss
/// (Earth's field is 0.25..0.65); parts work from -55 to 125 deg C.
pub const RANGES: [(&str, f64, f64, &str); 4] = [
    ("gx,gy,gz", -10_000.0, 10_000.0, "deg/s"),
    ("ax,ay,az", -1000.0, 1000.0, "g"),
    ("mx,my,mz", -100.0, 100.0, "gauss"),
    ("temp", -100.0, 200.0, "deg C"),
];

/// The range of column `k` of [`COLUMNS`] (none for `t`).
fn range_of(k: usize) -> Option<(f64, f64, &'static str)> {
    let r = match k {
        1..=3 => RANGES[0],
        4..=6 => RANGES[1],
        7..=9 => RANGES[2],
        10 => RANGES[3],
        _ => return None,
    };
    Some((r.1, r.2, r.3))
}

/// Parse one field: empty -> None, a finite number within the column's
/// physical range -> Some, else an error naming the line and column.
fn field(s: &str, k: usize, path: &str, no: u64) -> Result<Option<f64>, String> {
    let name = COLUMNS[k];
    let s = s.trim();
    if s.is_empty() {
        return Ok(None);
    }
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() => match range_of(k) {
            Some((lo, hi, unit)) if !(lo..=hi).contains(&v) => {
                Err(format!("{path} line {no}, column {name}: {s} {unit} is beyond any real part's range (want {lo}..{hi} {unit})"))
            }
            _ => Ok(Some(v)),
        },
        Ok(v) => Err(format!("{path} line {no}, column {name}: {v} is not a finite number")),
        Err(_) => Err(format!("{path} line {no}, column {name}: not a number: {s:?}")),
    }
}

/// Read the recording, mapping the axes onto FRD.
pub fn read_imu_csv(path: &Path, axes: &AxesMap) -> Result<ImuCsv, String> {
    let p = path.display().to_string();
    let mut rd = open_text(path)?;
    read_imu_csv_from(&mut rd, &p, axes)
}

/// [`read_imu_csv`] from a reader (`p` names it in errors).
pub fn read_imu_csv_from(rd: &mut dyn BufRead, p: &str, axes: &AxesMap) -> Result<ImuCsv, String> {
    let p = p.to_string();
    let mut buf = String::new();
    let mut bytes = Vec::new();
    let mut no: u64 = 0;
    let mut next_line = |buf: &mut String, no: &mut u64| -> Result<bool, String> {
        buf.clear();
        bytes.clear();
        let n = rd.read_until(b'\n', &mut bytes).map_err(|e| format!("{p} line {}: {e}", *no + 1))?;
        *no += 1;
        match std::str::from_utf8(&bytes) {
            Ok(s) => buf.push_str(s),
            Err(e) => {
                let t = crate::textfile::not_text(&bytes, e.valid_up_to());
                return Err(format!("{p} line {no}, {}", t.replace("line 1, ", "")));
            }
        }
        while buf.ends_with('\n') || buf.ends_with('\r') {
            buf.pop();
        }
        Ok(n > 0)
    };
    if !next_line(&mut buf, &mut no)? {
        return Err(format!("{p}: empty file (want a header line {})", COLUMNS.join(",")));
    }
    let header: Vec<String> = buf.split(',').map(|h| h.trim().trim_start_matches('\u{feff}').to_string()).collect();
    // Column index of each known name.
    let mut col: [Option<usize>; 11] = [None; 11];
    let mut ignored = Vec::new();
    for (i, h) in header.iter().enumerate() {
        match COLUMNS.iter().position(|c| c == h) {
            Some(k) if col[k].is_some() => return Err(format!("{p} line 1 (header): column {h} appears twice")),
            Some(k) => col[k] = Some(i),
            None => ignored.push(h.clone()),
        }
    }
    let missing: Vec<&str> = (0..REQUIRED).filter(|&k| col[k].is_none()).map(|k| COLUMNS[k]).collect();
    if !missing.is_empty() {
        return Err(format!(
            "{p} line 1 (header): missing required column(s) {} (want {}; mx,my,mz,temp optional)",
            missing.join(", "),
            COLUMNS.join(",")
        ));
    }
    let mag_cols = col[7..10].iter().filter(|c| c.is_some()).count();
    if mag_cols != 0 && mag_cols != 3 {
        return Err(format!("{p} line 1 (header): the magnetometer columns mx, my, mz go together (found {mag_cols} of 3)"));
    }
    let mut out = ImuCsv { ignored, ..Default::default() };
    let mut magn = Vec::new();
    let mut temp = Vec::new();
    // Whether the optional channels carry values (decided by the first data line).
    let mut has_mag: Option<bool> = if mag_cols == 3 { None } else { Some(false) };
    let mut has_temp: Option<bool> = if col[10].is_some() { None } else { Some(false) };
    let mut vals = [None; 11];
    loop {
        if !next_line(&mut buf, &mut no)? {
            break;
        }
        if buf.trim().is_empty() {
            continue;
        }
        let fields: Vec<&str> = buf.split(',').collect();
        if fields.len() != header.len() {
            return Err(format!("{p} line {no}: {} fields, the header has {}", fields.len(), header.len()));
        }
        for k in 0..11 {
            vals[k] = match col[k] {
                Some(i) => field(fields[i], k, &p, no)?,
                None => None,
            };
        }
        for k in 0..REQUIRED {
            if vals[k].is_none() {
                return Err(format!("{p} line {no}, column {}: empty (a required column)", COLUMNS[k]));
            }
        }
        let t = vals[0].unwrap_or_default();
        if let Some(&prev) = out.t.last() {
            if t <= prev {
                return Err(format!("{p} line {no}, column t: time {t} s is not after the previous line's {prev} s (time must increase)"));
            }
        }
        // Optional channels: recorded on every line or on none.
        let mag_here = vals[7..10].iter().filter(|v| v.is_some()).count();
        if mag_cols == 3 {
            let present = match mag_here {
                0 => false,
                3 => true,
                _ => {
                    let k = (7..10).find(|&k| vals[k].is_none()).unwrap_or(7);
                    return Err(format!("{p} line {no}, column {}: empty while the other magnetometer columns have values", COLUMNS[k]));
                }
            };
            match has_mag {
                None => has_mag = Some(present),
                Some(h) if h != present => {
                    return Err(format!(
                        "{p} line {no}, column mx: {} here but {} on the first data line (a channel is recorded on every line or on none)",
                        if present { "a value" } else { "empty" },
                        if h { "values" } else { "empty" }
                    ))
                }
                _ => {}
            }
        }
        if col[10].is_some() {
            let present = vals[10].is_some();
            match has_temp {
                None => has_temp = Some(present),
                Some(h) if h != present => {
                    return Err(format!(
                    "{p} line {no}, column temp: {} here but {} on the first data line (a channel is recorded on every line or on none)",
                    if present { "a value" } else { "empty" },
                    if h { "a value" } else { "empty" }
                ))
                }
                _ => {}
            }
        }
        let v3 = |a: usize| [vals[a].unwrap_or(0.0), vals[a + 1].unwrap_or(0.0), vals[a + 2].unwrap_or(0.0)];
        out.line.push(no);
        out.t.push(t);
        out.gyro.push(axes.apply(v3(1)));
        out.accel.push(axes.apply(v3(4)));
        if has_mag == Some(true) {
            magn.push(axes.apply(v3(7)));
        }
        if has_temp == Some(true) {
            temp.push(vals[10].unwrap_or(0.0));
        }
    }
    if out.t.is_empty() {
        return Err(format!("{p}: no data lines after the header"));
    }
    if has_mag == Some(true) {
        out.magn = Some(magn);
    }
    if has_temp == Some(true) {
        out.temp = Some(temp);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axes_maps_parse_and_apply() {
        let m = AxesMap::parse("x,-y,-z").unwrap();
        assert_eq!(m.apply([1.0, 2.0, 3.0]), [1.0, -2.0, -3.0]);
        assert!(m.is_rotation());
        let m = AxesMap::parse("y, x, -z").unwrap();
        assert_eq!(m.apply([1.0, 2.0, 3.0]), [2.0, 1.0, -3.0]);
        assert!(m.is_rotation());
        assert!(!AxesMap::parse("x,y,-z").unwrap().is_rotation());
        for bad in ["x,y", "x,x,z", "x,y,w", "x,--y,z", ""] {
            assert!(AxesMap::parse(bad).is_err(), "{bad}");
        }
    }

    fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn optional_channels_absent_or_empty() {
        let d = tempfile::tempdir().unwrap();
        let p = write(d.path(), "a.csv", "t,gx,gy,gz,ax,ay,az,mx,my,mz,temp\n0,1,2,3,0,0,-1,,,,\n0.01,1,2,3,0,0,-1,,,,\n");
        let c = read_imu_csv(&p, &AxesMap::IDENTITY).unwrap();
        assert_eq!(c.len(), 2);
        assert!(c.magn.is_none() && c.temp.is_none());
        let p = write(d.path(), "b.csv", "az,ay,ax,gz,gy,gx,t,extra\n-1,0,0.5,3,2,1,0,9\n");
        let c = read_imu_csv(&p, &AxesMap::parse("x,-y,-z").unwrap()).unwrap();
        assert_eq!(c.gyro[0], [1.0, -2.0, -3.0]);
        assert_eq!(c.accel[0], [0.5, 0.0, 1.0]);
        assert_eq!(c.ignored, vec!["extra".to_string()]);
    }

    #[test]
    fn a_value_beyond_any_part_is_refused_with_its_line_and_column() {
        let d = tempfile::tempdir().unwrap();
        for (row, col) in [("0.01,1e300,2,3,0,0,-1,25", "gx"), ("0.01,1,2,3,0,0,-2000,25", "az"), ("0.01,1,2,3,0,0,-1,900", "temp")] {
            let p = write(d.path(), "a.csv", &format!("t,gx,gy,gz,ax,ay,az,temp\n0,1,2,3,0,0,-1,25\n{row}\n"));
            let e = read_imu_csv(&p, &AxesMap::IDENTITY).unwrap_err();
            assert!(e.contains(&format!("line 3, column {col}")) && e.contains("beyond any real part's range"), "{e}");
        }
    }

    #[test]
    fn a_channel_that_comes_and_goes_is_refused() {
        let d = tempfile::tempdir().unwrap();
        let p = write(d.path(), "a.csv", "t,gx,gy,gz,ax,ay,az,temp\n0,1,2,3,0,0,-1,25\n0.01,1,2,3,0,0,-1,\n");
        let e = read_imu_csv(&p, &AxesMap::IDENTITY).unwrap_err();
        assert!(e.contains("line 3, column temp"), "{e}");
        let p = write(d.path(), "b.csv", "t,gx,gy,gz,ax,ay,az,mx,my,mz\n0,1,2,3,0,0,-1,0.1,,0.3\n");
        let e = read_imu_csv(&p, &AxesMap::IDENTITY).unwrap_err();
        assert!(e.contains("line 2, column my"), "{e}");
    }
}
