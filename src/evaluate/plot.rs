//! SVG plots (plotters, SVG backend only: no font files needed).

use super::RunData;
use crate::estimator::Estimate;
use crate::reference::plot::mode_spans;
use plotters::prelude::*;

type R = Result<(), Box<dyn std::error::Error>>;

/// At most ~`n` points of a series.
fn every(len: usize, n: usize) -> usize {
    (len / n).max(1)
}

pub fn attitude_error(svg: &mut String, errs: &[(f64, [f64; 3])], est: &[Estimate]) -> R {
    let root = SVGBackend::with_string(svg, (1200, 500)).into_drawing_area();
    root.fill(&WHITE)?;
    let t1 = errs.last().map(|e| e.0).unwrap_or(1.0).max(1e-3);
    let m = errs.iter().flat_map(|e| e.1.iter()).map(|v| v.abs()).fold(0.5f64, f64::max).min(60.0) * 1.1;
    let mut ch = ChartBuilder::on(&root)
        .caption("attitude error (estimate - truth); shading: green fusion, yellow blend", ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(50)
        .build_cartesian_2d(0.0..t1, -m..m)?;
    ch.configure_mesh().x_desc("t, s").y_desc("deg").draw()?;
    // mode shading, one rectangle per run of equal mode
    for (a, b, col) in mode_spans(est.len(), |k| est[k].mode, |k| est[k].t) {
        ch.draw_series(std::iter::once(Rectangle::new([(a, -m), (b, m)], col.filled())))?;
    }
    let step = every(errs.len(), 4000);
    for (i, (name, col)) in [("roll", RED), ("pitch", BLUE), ("yaw", BLACK)].iter().enumerate() {
        ch.draw_series(LineSeries::new(errs.iter().step_by(step).map(|e| (e.0, e.1[i].clamp(-m, m))), col))?
            .label(*name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], col));
    }
    ch.configure_series_labels().border_style(BLACK).background_style(WHITE).draw()?;
    root.present()?;
    Ok(())
}

pub fn bias(svg: &mut String, est: &[Estimate], data: &RunData) -> R {
    let root = SVGBackend::with_string(svg, (1200, 500)).into_drawing_area();
    root.fill(&WHITE)?;
    let t1 = est.last().map(|e| e.t).unwrap_or(1.0).max(1e-3);
    let all = est.iter().flat_map(|e| e.bias.iter()).chain(data.bias.iter().flat_map(|b| b.iter()));
    let (lo, hi) = all.fold((f64::MAX, f64::MIN), |(l, h), v| (l.min(*v), h.max(*v)));
    let pad = ((hi - lo) * 0.05).max(0.01);
    let mut ch = ChartBuilder::on(&root)
        .caption("gyro bias: estimate (solid) vs truth (thin)", ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..t1, (lo - pad)..(hi + pad))?;
    ch.configure_mesh().x_desc("t, s").y_desc("deg/s").draw()?;
    let step = every(est.len(), 4000);
    for (i, (name, col)) in [("x", RED), ("y", BLUE), ("z", BLACK)].iter().enumerate() {
        ch.draw_series(LineSeries::new(est.iter().step_by(step).map(|e| (e.t, e.bias[i])), col.stroke_width(2)))?
            .label(format!("estimate {name}"))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], col.stroke_width(2)));
        ch.draw_series(LineSeries::new(data.truth.iter().zip(&data.bias).step_by(step).map(|(t, b)| (t.t, b[i])), col.mix(0.5)))?;
    }
    ch.configure_series_labels().border_style(BLACK).background_style(WHITE).draw()?;
    root.present()?;
    Ok(())
}
