//! `--plot`: SVG plots of the calibration.

use super::{plot_files, Bin, CalError, Calibration, AXES};
use crate::thermal::Thermal;
use std::path::{Path, PathBuf};

impl Calibration {
    /// SVG plots into `dir`: `bias_vs_temp_{x,y,z}.svg` (every run with its own
    /// turn-on bias replaced by the mean, the warm-up cut in grey, and the
    /// fit) and `warmup_run{k}.svg` (per run: bias minus its fitted curve vs
    /// time, per axis, with the cut). Each file is written through
    /// [`crate::outfile`] (never half-written). Returns the files written.
    pub fn plot(&self, dir: &Path) -> Result<Vec<PathBuf>, CalError> {
        crate::outfile::create_dir(dir).map_err(|e| CalError::Output { path: dir.display().to_string(), msg: e.to_string() })?;
        let files = plot_files(dir, self.runs.len());
        let th = self.thermal();
        // the warm-up plots show the data the fit saw, also outside the calibrated range: no clamp
        let unclamped = Thermal { t_min: f64::NEG_INFINITY, t_max: f64::INFINITY, ..th.clone() };
        for (k, p) in files.iter().enumerate() {
            let mut svg = String::new();
            let drawn = if k < 3 { self.plot_axis(&mut svg, k, &th) } else { self.plot_run(&mut svg, k - 3, &unclamped) };
            drawn
                .and_then(|()| crate::outfile::write_atomic(p, svg.as_bytes()).map_err(|e| e.to_string()))
                .map_err(|msg| CalError::Output { path: p.display().to_string(), msg })?;
        }
        Ok(files)
    }

    /// Run `k`'s turn-on bias on axis `i`: the fitted one, or for a run left
    /// out of the fit the median of its bias minus the curve over its second half.
    fn plot_offset(&self, k: usize, i: usize, th: &Thermal) -> f64 {
        let o = self.runs[k].offset[i];
        if o.is_finite() {
            return o;
        }
        let bins = &self.data[k].0;
        let mut v: Vec<f64> = bins[bins.len() / 2..].iter().map(|b| b.gyro[i] - (th.bias(b.temp)[i] - th.p2[i])).collect();
        super::screen::median(&mut v)
    }

    /// 10-s means of (x, y) pairs selected by `sel`, for plotting.
    fn decimate(bins: &[Bin], mask: &[bool], want: bool, f: impl Fn(&Bin) -> (f64, f64)) -> Vec<(f64, f64)> {
        let mut out = Vec::new();
        let (mut sx, mut sy, mut n) = (0.0, 0.0, 0);
        for (b, m) in bins.iter().zip(mask) {
            if *m != want {
                continue;
            }
            let (x, y) = f(b);
            sx += x;
            sy += y;
            n += 1;
            if n == 10 {
                out.push((sx / 10.0, sy / 10.0));
                (sx, sy, n) = (0.0, 0.0, 0);
            }
        }
        if n > 0 {
            out.push((sx / n as f64, sy / n as f64));
        }
        out
    }

    fn plot_axis(&self, svg: &mut String, i: usize, th: &Thermal) -> Result<(), String> {
        use plotters::prelude::*;
        let e = |e: &dyn std::fmt::Display| e.to_string();
        let p2 = self.axes[i].p2;
        let mut series = Vec::new();
        let (mut ylo, mut yhi) = (f64::INFINITY, f64::NEG_INFINITY);
        let (mut xlo, mut xhi) = (f64::INFINITY, f64::NEG_INFINITY);
        for (k, (bins, used)) in self.data.iter().enumerate() {
            let off = self.plot_offset(k, i, th) - p2;
            let used_pts = Self::decimate(bins, used, true, |b| (b.temp, b.gyro[i] - off));
            let cut_pts = Self::decimate(bins, used, false, |b| (b.temp, b.gyro[i] - off));
            for (x, y) in used_pts.iter().chain(&cut_pts) {
                xlo = xlo.min(*x);
                xhi = xhi.max(*x);
                ylo = ylo.min(*y);
                yhi = yhi.max(*y);
            }
            series.push((used_pts, cut_pts));
        }
        if !(xlo.is_finite() && xhi.is_finite() && xlo < xhi) {
            (xlo, xhi) = if xlo.is_finite() { (xlo, xlo + 1.0) } else { (0.0, 1.0) };
        }
        if !(ylo.is_finite() && yhi.is_finite() && ylo < yhi) {
            (ylo, yhi) = if ylo.is_finite() { (ylo, ylo + 0.01) } else { (-0.01, 0.01) };
        }
        let pad = 0.05 * (yhi - ylo);
        let root = SVGBackend::with_string(svg, (900, 600)).into_drawing_area();
        root.fill(&WHITE).map_err(|x| e(&x))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(format!("gyro {} bias vs temperature (order {} fit, 10-s means)", AXES[i], self.order), ("sans-serif", 20))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(75)
            .build_cartesian_2d(xlo..xhi, (ylo - pad)..(yhi + pad))
            .map_err(|x| e(&x))?;
        chart
            .configure_mesh()
            .x_desc("temperature, deg C")
            .y_desc("bias (turn-on bias of each run -> mean), deg/s")
            .draw()
            .map_err(|x| e(&x))?;
        let grey = RGBColor(190, 190, 190);
        for (k, (used_pts, cut_pts)) in series.iter().enumerate() {
            let c = Palette99::pick(k).to_rgba();
            chart.draw_series(cut_pts.iter().map(|&(x, y)| Circle::new((x, y), 2, grey.filled()))).map_err(|x| e(&x))?;
            chart
                .draw_series(used_pts.iter().map(move |&(x, y)| Circle::new((x, y), 2, c.filled())))
                .map_err(|x| e(&x))?
                .label(format!("run {} (cut {:.0} s, grey)", k + 1, self.runs[k].cut_s))
                .legend(move |(x, y)| Circle::new((x, y), 4, c.filled()));
        }
        let (a, b) = self.range;
        let curve: Vec<(f64, f64)> = (0..=200).map(|j| a + (b - a) * j as f64 / 200.0).map(|t| (t, th.bias(t)[i])).collect();
        chart
            .draw_series(LineSeries::new(curve, BLACK.stroke_width(2)))
            .map_err(|x| e(&x))?
            .label("fit")
            .legend(|(x, y)| PathElement::new(vec![(x - 10, y), (x + 10, y)], BLACK.stroke_width(2)));
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperLeft)
            .draw()
            .map_err(|x| e(&x))?;
        root.present().map_err(|x| e(&x))?;
        Ok(())
    }

    fn plot_run(&self, svg: &mut String, k: usize, th: &Thermal) -> Result<(), String> {
        use plotters::prelude::*;
        let e = |e: &dyn std::fmt::Display| e.to_string();
        let (bins, _) = &self.data[k];
        let rep = &self.runs[k];
        let all = vec![true; bins.len()];
        let mut series = Vec::new();
        let (mut ylo, mut yhi) = (f64::INFINITY, f64::NEG_INFINITY);
        for i in 0..3 {
            let off = self.plot_offset(k, i, th) - self.axes[i].p2;
            let pts = Self::decimate(bins, &all, true, |b| (b.t, b.gyro[i] - off - th.bias(b.temp)[i]));
            for (_, y) in &pts {
                ylo = ylo.min(*y);
                yhi = yhi.max(*y);
            }
            series.push(pts);
        }
        let xhi = bins.last().map(|b| b.t).unwrap_or(1.0).max(1.0);
        if !(ylo.is_finite() && yhi.is_finite() && ylo < yhi) {
            (ylo, yhi) = if ylo.is_finite() { (ylo, ylo + 0.01) } else { (-0.01, 0.01) };
        }
        let pad = 0.05 * (yhi - ylo);
        let root = SVGBackend::with_string(svg, (900, 500)).into_drawing_area();
        root.fill(&WHITE).map_err(|x| e(&x))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(format!("run {}: bias minus fitted curve (warm-up cut {:.0} s)", k + 1, rep.cut_s), ("sans-serif", 20))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(75)
            .build_cartesian_2d(0.0..xhi, (ylo - pad)..(yhi + pad))
            .map_err(|x| e(&x))?;
        chart.configure_mesh().x_desc("time since power-on, s").y_desc("deg/s").draw().map_err(|x| e(&x))?;
        for (i, pts) in series.into_iter().enumerate() {
            let c = Palette99::pick(i).to_rgba();
            chart
                .draw_series(LineSeries::new(pts, c))
                .map_err(|x| e(&x))?
                .label(format!("axis {}", AXES[i]))
                .legend(move |(x, y)| PathElement::new(vec![(x - 10, y), (x + 10, y)], c));
        }
        let cut = rep.cut_s;
        chart
            .draw_series(std::iter::once(PathElement::new(vec![(cut, ylo - pad), (cut, yhi + pad)], BLACK.stroke_width(2))))
            .map_err(|x| e(&x))?
            .label("cut")
            .legend(|(x, y)| PathElement::new(vec![(x - 10, y), (x + 10, y)], BLACK.stroke_width(2)));
        chart.configure_series_labels().background_style(WHITE.mix(0.85)).border_style(BLACK).draw().map_err(|x| e(&x))?;
        root.present().map_err(|x| e(&x))?;
        Ok(())
    }
}
