//! Charts the benchmarks share: runs grouped into named (x, y) series, and one panel of lines and
//! points with a legend (SVG; no fonts needed). `#[path = "support/chart.rs"] mod chart_support;`
#![allow(dead_code)]

use plotters::prelude::*;
use serde_json::Value;

pub type Series = Vec<(String, Vec<(f64, f64)>)>;

/// Group runs into named series of (x, y), sorted by x.
pub fn series(
    runs: &[Value],
    name: impl Fn(&Value) -> String,
    xy: impl Fn(&Value) -> Option<(f64, f64)>,
) -> Series {
    let mut out: Series = Vec::new();
    for r in runs {
        let Some(p) = xy(r) else { continue };
        let n = name(r);
        match out.iter_mut().find(|s| s.0 == n) {
            Some(s) => s.1.push(p),
            None => out.push((n, vec![p])),
        }
    }
    for s in &mut out {
        s.1.sort_by(|a, b| a.0.total_cmp(&b.0));
    }
    out
}

pub fn panel(
    area: &DrawingArea<SVGBackend, plotters::coord::Shift>,
    title: &str,
    x_label: &str,
    y_label: &str,
    data: &Series,
) -> Result<(), Box<dyn std::error::Error>> {
    let pts = data.iter().flat_map(|s| s.1.iter());
    let (mut x1, mut y0, mut y1) = (1.0f64, f64::MAX, f64::MIN);
    for &(x, y) in pts {
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    if y0 > y1 {
        (y0, y1) = (0.0, 1.0);
    }
    let pad = 0.08 * (y1 - y0).max(1e-3);
    let mut c = ChartBuilder::on(area)
        .caption(title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(36)
        .y_label_area_size(52)
        .build_cartesian_2d(0.0..x1 * 1.08, (y0 - pad)..(y1 + pad))?;
    c.configure_mesh().x_desc(x_label).y_desc(y_label).draw()?;
    for (i, (name, p)) in data.iter().enumerate() {
        let col = Palette99::pick(i).to_rgba();
        c.draw_series(LineSeries::new(p.clone(), col.stroke_width(2)))?
            .label(name.clone())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], col.stroke_width(2)));
        c.draw_series(p.iter().map(|&q| Circle::new(q, 4, col.filled())))?;
    }
    c.configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::LowerRight)
        .draw()?;
    Ok(())
}
