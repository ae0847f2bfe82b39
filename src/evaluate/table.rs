//! The printed text tables: a [`Table`] with a name and a unit per column,
//! and the rows of a single run's table.

use super::Metrics;

/// A text table whose header names every column and gives its unit on a
/// second line. Columns are as wide as their header (at least 8); a longer
/// cell widens its row, it is never cut.
pub struct Table {
    cols: Vec<(&'static str, &'static str, usize)>,
    /// Leading columns that are text (left-aligned).
    left: usize,
}

impl Table {
    /// Columns as (name, unit); the first is left-aligned, the others right-aligned.
    pub fn new(cols: &[(&'static str, &'static str)]) -> Table {
        Table { cols: cols.iter().map(|(n, u)| (*n, *u, n.len().max(u.len()).max(8))).collect(), left: 1 }
    }

    /// The first `n` columns are text (left-aligned).
    pub fn text_columns(mut self, n: usize) -> Table {
        self.left = n;
        self
    }

    /// The same columns with column `k` `w` characters wide (or its header's width).
    pub fn width(mut self, k: usize, w: usize) -> Table {
        self.cols[k].2 = w.max(self.cols[k].0.len()).max(self.cols[k].1.len());
        self
    }

    /// The two header lines.
    pub fn header(&self) -> String {
        let names: Vec<String> = self.cols.iter().map(|c| c.0.to_string()).collect();
        let units: Vec<String> = self.cols.iter().map(|c| c.1.to_string()).collect();
        self.line(&names) + &self.line(&units)
    }

    /// One row.
    pub fn line(&self, cells: &[String]) -> String {
        let mut s = String::new();
        for (k, (c, (_, _, w))) in cells.iter().zip(&self.cols).enumerate() {
            let sep = if k == 0 { "" } else { "  " };
            if k < self.left {
                s += &format!("{sep}{c:<w$}");
            } else {
                s += &format!("{sep}{c:>w$}");
            }
        }
        s.trim_end().to_string() + "\n"
    }
}

/// `v` with `d` decimals, or `-` when it is not a number.
pub(super) fn num(v: f64, d: usize) -> String {
    if v.is_finite() {
        format!("{v:.d$}")
    } else {
        "-".into()
    }
}

/// The columns of a single run's table.
pub fn run_table() -> Table {
    Table::new(&[
        ("case", ""),
        ("max roll", "deg"),
        ("max pitch", "deg"),
        ("max yaw", "deg"),
        ("rms roll", "deg"),
        ("rms pitch", "deg"),
        ("rms yaw", "deg"),
        ("rms bias", "deg/s"),
        ("run in fusion", "s"),
        ("run in blend", "s"),
        ("run gyro only", "s"),
        ("still moving", "s"),
    ])
    .width(0, 22)
}

/// One row of [`run_table`]; the oracle floor has no bias and no modes.
pub fn run_row(t: &Table, m: &Metrics, oracle: bool) -> String {
    let brms = (m.bias_rms.iter().map(|b| b * b).sum::<f64>() / 3.0).sqrt();
    let mut c = vec![m.name.clone()];
    c.extend(m.max_err.iter().chain(&m.rms_err).map(|v| num(*v, 3)));
    if oracle {
        c.extend(["-"; 5].map(String::from));
    } else {
        c.push(num(brms, 5));
        c.extend(m.mode_seconds.iter().map(|v| num(*v, 1)));
        c.push(num(m.still_moving_s.unwrap_or(f64::NAN), 2));
    }
    t.line(&c)
}
