//! The measured reference: `t,roll,pitch,yaw[,valid][,rest]`.
//!
//! Z-Y-X Euler angles (deg) of the FRD body in a north-east-down world; `t`
//! in seconds on the log's clock. `valid = 0` marks rows where the reference
//! lost track (their angles may be empty and are never used); `rest = 1`
//! marks rows where the unit is known to be still. Both columns are
//! optional (every row valid; no rest phase known). Gzip is recognised.

use nalgebra::UnitQuaternion;
use std::path::Path;

/// One reference row.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefRow {
    pub t: f64,
    /// Roll, pitch, yaw (deg); None where `valid = 0`.
    pub att: Option<[f64; 3]>,
    pub rest: bool,
}

/// A reference track.
#[derive(Clone, Debug, Default)]
pub struct Reference {
    pub rows: Vec<RefRow>,
    /// The file had a `rest` column.
    pub has_rest: bool,
    /// The file had a `valid` column.
    pub has_valid: bool,
}

const NAMES: [&str; 6] = ["t", "roll", "pitch", "yaw", "valid", "rest"];

fn flag(s: &str, name: &str, path: &str, no: u64) -> Result<bool, String> {
    match s.trim() {
        "1" => Ok(true),
        "0" | "" => Ok(false),
        other => Err(format!("{path} line {no}, column {name}: want 0 or 1, got {other:?}")),
    }
}

fn number(s: &str, name: &str, path: &str, no: u64) -> Result<f64, String> {
    let s = s.trim();
    if s.is_empty() {
        return Err(format!("{path} line {no}, column {name}: empty (on a valid row)"));
    }
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(v) => Err(format!("{path} line {no}, column {name}: {v} is not a finite number")),
        Err(_) => Err(format!("{path} line {no}, column {name}: not a number: {s:?}")),
    }
}

/// An Euler angle within +-`max` deg (roll and yaw +-360, pitch +-90).
fn angle(s: &str, name: &str, max: f64, path: &str, no: u64) -> Result<f64, String> {
    let v = number(s, name, path, no)?;
    if v.abs() > max + 1e-9 {
        return Err(format!("{path} line {no}, column {name}: {v} deg is outside -{max}..{max}"));
    }
    Ok(v)
}

/// Read a reference CSV.
pub fn read_reference(path: &Path) -> Result<Reference, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("cannot open {}: {e}", path.display()))?;
    reference_from_bytes(&bytes, &path.display().to_string())
}

/// [`read_reference`] of the file's bytes (gzip recognised); `p` names them in errors.
pub fn reference_from_bytes(bytes: &[u8], p: &str) -> Result<Reference, String> {
    let bytes = crate::textfile::gunzip(bytes).map_err(|e| format!("{p}: {e}"))?;
    let text = crate::textfile::str_of(&bytes).map_err(|e| format!("{p}: {e}"))?;
    parse_reference(text, p)
}

/// [`read_reference`] of text (`p` names it in errors).
pub fn parse_reference(text: &str, p: &str) -> Result<Reference, String> {
    let mut lines = text.lines().enumerate();
    let header = match lines.next() {
        Some((_, h)) => h,
        None => return Err(format!("{p}: empty file (want a header t,roll,pitch,yaw[,valid][,rest])")),
    };
    let mut col = [None; 6];
    for (i, h) in header.split(',').enumerate() {
        let h = h.trim().trim_start_matches('\u{feff}');
        if let Some(k) = NAMES.iter().position(|n| *n == h) {
            if col[k].is_some() {
                return Err(format!("{p} line 1 (header): column {h} appears twice"));
            }
            col[k] = Some(i);
        }
    }
    let missing: Vec<&str> = (0..4).filter(|&k| col[k].is_none()).map(|k| NAMES[k]).collect();
    if !missing.is_empty() {
        return Err(format!(
            "{p} line 1 (header): missing required column(s) {} (want t,roll,pitch,yaw[,valid][,rest])",
            missing.join(", ")
        ));
    }
    let ncol = header.split(',').count();
    let mut r = Reference { rows: Vec::new(), has_rest: col[5].is_some(), has_valid: col[4].is_some() };
    for (i, line) in lines {
        let no = i as u64 + 1;
        if line.trim().is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split(',').collect();
        if f.len() != ncol {
            return Err(format!("{p} line {no}: {} fields, the header has {ncol}", f.len()));
        }
        let get = |k: usize| col[k].map(|c| f[c]).unwrap_or("");
        let t = number(get(0), "t", p, no)?;
        if let Some(prev) = r.rows.last() {
            if t <= prev.t {
                return Err(format!("{p} line {no}, column t: time {t} s is not after the previous line's {} s", prev.t));
            }
        }
        let valid = if col[4].is_some() { flag(get(4), "valid", p, no)? } else { true };
        let rest = if col[5].is_some() { flag(get(5), "rest", p, no)? } else { false };
        let att = if valid {
            Some([angle(get(1), "roll", 360.0, p, no)?, angle(get(2), "pitch", 90.0, p, no)?, angle(get(3), "yaw", 360.0, p, no)?])
        } else {
            None
        };
        r.rows.push(RefRow { t, att, rest });
    }
    if !r.rows.iter().any(|x| x.att.is_some()) {
        return Err(format!("{p}: no valid reference row"));
    }
    Ok(r)
}

/// Body -> NED rotation of Z-Y-X Euler angles in degrees.
pub fn quat_deg(a: [f64; 3]) -> UnitQuaternion<f64> {
    UnitQuaternion::from_euler_angles(a[0].to_radians(), a[1].to_radians(), a[2].to_radians())
}

impl Reference {
    /// The reference attitude at each time `ts[k] + offset`: interpolated
    /// (slerp) between the two rows around it when both are valid and no
    /// farther apart than 2.5 times the median row spacing; None otherwise
    /// (a gap, an invalid row, or outside the reference). `ts` ascending.
    pub fn at_times(&self, ts: &[f64], offset: f64) -> Vec<Option<UnitQuaternion<f64>>> {
        let rows = &self.rows;
        let q: Vec<Option<UnitQuaternion<f64>>> = rows.iter().map(|r| r.att.map(quat_deg)).collect();
        let mut sp: Vec<f64> = rows.windows(2).map(|w| w[1].t - w[0].t).collect();
        sp.sort_by(|a, b| a.total_cmp(b));
        let max_gap = sp.get(sp.len() / 2).copied().unwrap_or(f64::INFINITY) * 2.5;
        // a sample within a microsecond of a row takes that row
        let tol = 1e-6;
        let mut j = 0usize;
        ts.iter()
            .map(|&t0| {
                let t = t0 + offset;
                while j + 1 < rows.len() && rows[j + 1].t <= t + tol {
                    j += 1;
                }
                if (rows[j].t - t).abs() <= tol {
                    return q[j];
                }
                if j + 1 >= rows.len() || rows[j].t > t {
                    return None;
                }
                match (q[j], q[j + 1]) {
                    (Some(a), Some(b)) if rows[j + 1].t - rows[j].t <= max_gap => {
                        let u = (t - rows[j].t) / (rows[j + 1].t - rows[j].t);
                        Some(a.try_slerp(&b, u, 1e-9).unwrap_or(if u < 0.5 { a } else { b }))
                    }
                    _ => None,
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolates_inside_and_refuses_gaps() {
        let row = |t: f64, yaw: Option<f64>| RefRow { t, att: yaw.map(|y| [0.0, 0.0, y]), rest: false };
        let r = Reference {
            rows: vec![row(0.0, Some(0.0)), row(0.1, Some(10.0)), row(0.2, None), row(0.3, Some(30.0)), row(1.0, Some(40.0))],
            has_rest: false,
            has_valid: true,
        };
        let a = r.at_times(&[0.05, 0.1, 0.15, 0.25, 0.5, 1.0, 1.5, -0.1], 0.0);
        let yaw = |q: &Option<UnitQuaternion<f64>>| q.map(|q| q.euler_angles().2.to_degrees());
        assert!((yaw(&a[0]).unwrap() - 5.0).abs() < 1e-9);
        assert!((yaw(&a[1]).unwrap() - 10.0).abs() < 1e-9);
        assert_eq!(a[2], None, "next to an invalid row");
        assert_eq!(a[3], None, "next to an invalid row");
        assert_eq!(a[4], None, "a 0.7 s gap between rows is not bridged");
        assert!((yaw(&a[5]).unwrap() - 40.0).abs() < 1e-9);
        assert_eq!((a[6], a[7]), (None, None), "outside the reference");
        let b = r.at_times(&[0.0], 0.05);
        assert!((yaw(&b[0]).unwrap() - 5.0).abs() < 1e-9, "offset");
    }
}
