//! The SVG of the errors against the reference over time: one panel per
//! estimator, ours with its mode shaded (green fusion, yellow blend, none
//! gyro only), the skipped start greyed over.

use super::score::ErrRow;
use plotters::prelude::*;

type R<T> = Result<T, Box<dyn std::error::Error>>;
/// A named, coloured error series.
type Series = (&'static str, RGBColor, fn(&ErrRow) -> f64);

/// The mode shading of a plot over `n` samples (`mode(k)`, `t(k)`): per
/// run of equal mode, its time span and colour (green fusion, yellow blend;
/// gyro only is not shaded).
pub fn mode_spans(n: usize, mode: impl Fn(usize) -> u8, t: impl Fn(usize) -> f64) -> Vec<(f64, f64, RGBColor)> {
    let mut out = Vec::new();
    let mut k = 0;
    while k < n {
        let m = mode(k);
        let mut j = k;
        while j + 1 < n && mode(j + 1) == m {
            j += 1;
        }
        let col = match m {
            0 => Some(RGBColor(200, 240, 200)),
            1 => Some(RGBColor(250, 240, 190)),
            _ => None,
        };
        if let Some(col) = col {
            out.push((t(k), t(j).max(t(k) + 0.005), col));
        }
        k = j + 1;
    }
    out
}

/// One panel: a name, the error rows, the modes (ours).
pub struct Panel<'a> {
    pub name: &'a str,
    pub rows: &'a [ErrRow],
    pub modes: Option<&'a [u8]>,
}

/// The SVG text.
pub fn errors_svg(panels: &[Panel<'_>], skip: f64, yaw: bool) -> R<String> {
    let mut s = String::new();
    {
        let h = 360 * panels.len().max(1) as u32;
        let root = SVGBackend::with_string(&mut s, (1200, h)).into_drawing_area();
        root.fill(&WHITE)?;
        let areas = root.split_evenly((panels.len().max(1), 1));
        for (p, area) in panels.iter().zip(areas.iter()) {
            panel(area, p, skip, yaw)?;
        }
        root.present()?;
    }
    Ok(s)
}

fn panel<DB: DrawingBackend>(area: &DrawingArea<DB, plotters::coord::Shift>, p: &Panel<'_>, skip: f64, yaw: bool) -> R<()>
where
    DB::ErrorType: 'static,
{
    let rows = p.rows;
    let t1 = rows.last().map(|e| e.t).unwrap_or(1.0).max(1e-3);
    let vals = rows.iter().flat_map(|e| [e.roll, e.pitch, if yaw { e.yaw } else { f64::NAN }, e.tilt]);
    let m = vals.filter(|v| v.is_finite()).map(f64::abs).fold(0.5f64, f64::max).min(90.0) * 1.1;
    let caption = if p.modes.is_some() {
        format!("{}: error against the reference (aligned), deg; green fusion, yellow blend, grey not scored (skip)", p.name)
    } else {
        format!("{}: error against the reference (aligned), deg; grey not scored (skip)", p.name)
    };
    let mut ch = ChartBuilder::on(area)
        .caption(caption, ("sans-serif", 16))
        .margin(8)
        .x_label_area_size(30)
        .y_label_area_size(45)
        .build_cartesian_2d(0.0..t1, -m..m)?;
    ch.configure_mesh().x_desc("t, s").y_desc("deg").draw()?;
    if let Some(modes) = p.modes {
        for (a, b, col) in mode_spans(modes.len(), |k| modes[k], |k| rows[k].t) {
            ch.draw_series(std::iter::once(Rectangle::new([(a, -m), (b, m)], col.filled())))?;
        }
    }
    if skip > 0.0 {
        ch.draw_series(std::iter::once(Rectangle::new([(0.0, -m), (skip.min(t1), m)], RGBColor(160, 160, 160).mix(0.45).filled())))?;
    }
    let step = (rows.len() / 4000).max(1);
    let series: [Series; 4] =
        [("roll", RED, |e| e.roll), ("pitch", BLUE, |e| e.pitch), ("yaw", BLACK, |e| e.yaw), ("tilt", MAGENTA, |e| e.tilt)];
    for (name, col, get) in series {
        if name == "yaw" && !yaw {
            continue;
        }
        // Break the line where the value is not scored (NaN).
        let mut segs: Vec<Vec<(f64, f64)>> = vec![Vec::new()];
        for e in rows.iter().step_by(step) {
            let v = get(e);
            if v.is_finite() {
                if let Some(s) = segs.last_mut() {
                    s.push((e.t, v.clamp(-m, m)));
                }
            } else if !segs.last().map(|s| s.is_empty()).unwrap_or(true) {
                segs.push(Vec::new());
            }
        }
        let mut first = true;
        for s in segs.into_iter().filter(|s| !s.is_empty()) {
            let a = ch.draw_series(LineSeries::new(s, col))?;
            if first {
                a.label(name).legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], col));
                first = false;
            }
        }
    }
    ch.configure_series_labels().border_style(BLACK).background_style(WHITE).draw()?;
    Ok(())
}
