//! The SVG charts every benchmark writes: a grid of panels, each a few named layers of (x, y)
//! points drawn as lines, markers or dashes, with a legend. One drawing routine, so every chart
//! in `examples/results/` looks alike; no fonts are embedded (SVG text).

use plotters::prelude::*;
pub use plotters::prelude::{RGBColor, SeriesLabelPosition};
use serde_json::Value;
use std::ops::Range;

/// What a chart returns: plotters' errors are boxed.
pub type ChartResult<T> = std::result::Result<T, Box<dyn std::error::Error>>;

/// How a layer's points are drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Mark {
    /// Joined by a line, a marker on each point.
    LineAndPoints,
    /// Markers of this radius (pixels) only.
    Points(u32),
    /// A thin dashed line (reference levels: floors, medians).
    Dashed,
    /// Filled bars from 0 to each point, this wide in x. Stacks are drawn tallest first, each
    /// layer holding its running total.
    Bars(f64),
}

/// One named series of a panel.
#[derive(Clone, Debug)]
pub struct Layer {
    /// The legend's entry (None: not in the legend).
    pub name: Option<String>,
    pub colour: RGBColor,
    pub points: Vec<(f64, f64)>,
    pub mark: Mark,
}

impl Layer {
    pub fn new(name: impl Into<String>, colour: RGBColor, points: Vec<(f64, f64)>) -> Layer {
        Layer {
            name: Some(name.into()),
            colour,
            points,
            mark: Mark::LineAndPoints,
        }
    }

    pub fn mark(mut self, mark: Mark) -> Layer {
        self.mark = mark;
        self
    }

    /// A dashed horizontal line at `y` across `x`.
    pub fn level(name: Option<&str>, colour: RGBColor, y: f64, x: &Range<f64>) -> Layer {
        Layer {
            name: name.map(str::to_string),
            colour,
            points: vec![(x.start, y), (x.end, y)],
            mark: Mark::Dashed,
        }
    }
}

/// One panel: axes, layers and where the legend goes.
#[derive(Clone, Debug)]
pub struct Panel {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub x: Range<f64>,
    pub y: Range<f64>,
    pub layers: Vec<Layer>,
    pub legend: SeriesLabelPosition,
}

impl Panel {
    /// A panel whose axes fit its layers: x from 0 (or below) to 8 % past the largest x, y
    /// padded by 8 % of its span.
    pub fn fitted(title: &str, x_label: &str, y_label: &str, layers: Vec<Layer>) -> Panel {
        let pts = || layers.iter().flat_map(|l| l.points.iter());
        let x0 = pts().map(|p| p.0).fold(0.0f64, f64::min);
        let x1 = pts().map(|p| p.0).fold(1.0f64, f64::max);
        let (mut y0, mut y1) =
            pts().fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.1), b.max(p.1)));
        if y0 > y1 {
            (y0, y1) = (0.0, 1.0);
        }
        let pad = 0.08 * (y1 - y0).max(1e-3);
        Panel {
            title: title.to_string(),
            x_label: x_label.to_string(),
            y_label: y_label.to_string(),
            x: x0..x1 * 1.08,
            y: (y0 - pad)..(y1 + pad),
            layers,
            legend: SeriesLabelPosition::LowerRight,
        }
    }
}

/// The colour of the `i`th series of a chart (plotters' 99-colour palette), its pale colours
/// darkened so a point shows on white (pale yellow was invisible).
pub fn palette(i: usize) -> RGBColor {
    const MOST_LUMA: f32 = 170.0;
    let (r, g, b) = Palette99::pick(i).rgb();
    let luma = 0.299 * r as f32 + 0.587 * g as f32 + 0.114 * b as f32;
    let k = (MOST_LUMA / luma).min(1.0);
    let dim = |c: u8| (c as f32 * k).round() as u8;
    RGBColor(dim(r), dim(g), dim(b))
}

/// An SVG of `size` pixels with `panels` laid out in `rows` rows (filled row by row).
pub fn svg(size: (u32, u32), rows: usize, panels: &[Panel]) -> ChartResult<String> {
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, size).into_drawing_area();
        root.fill(&WHITE)?;
        let cols = panels.len().div_ceil(rows.max(1)).max(1);
        for (area, panel) in root.split_evenly((rows.max(1), cols)).iter().zip(panels) {
            draw_panel(area, panel)?;
        }
        root.present()?;
    }
    Ok(out)
}

fn draw_panel(
    area: &DrawingArea<SVGBackend, plotters::coord::Shift>,
    p: &Panel,
) -> ChartResult<()> {
    let mut c = ChartBuilder::on(area)
        .caption(&p.title, ("sans-serif", 17))
        .margin(12)
        .x_label_area_size(36)
        .y_label_area_size(52)
        .build_cartesian_2d(p.x.clone(), p.y.clone())?;
    c.configure_mesh()
        .x_desc(p.x_label.as_str())
        .y_desc(p.y_label.as_str())
        .draw()?;
    let clamp = |&(x, y): &(f64, f64)| (x, y.clamp(p.y.start, p.y.end));
    for layer in &p.layers {
        let col = layer.colour;
        let pts: Vec<(f64, f64)> = layer.points.iter().map(clamp).collect();
        let drawn = match layer.mark {
            Mark::LineAndPoints => {
                c.draw_series(pts.iter().map(|&q| Circle::new(q, 4, col.filled())))?;
                c.draw_series(LineSeries::new(pts, col.stroke_width(2)))?
            }
            Mark::Points(r) => {
                c.draw_series(pts.iter().map(|&q| Circle::new(q, r, col.filled())))?
            }
            Mark::Dashed => c.draw_series(DashedLineSeries::new(pts, 6, 4, col.stroke_width(1)))?,
            Mark::Bars(w) => c.draw_series(pts.iter().map(|&(x, y)| {
                let base = 0f64.clamp(p.y.start, p.y.end);
                Rectangle::new([(x - w / 2.0, base), (x + w / 2.0, y)], col.filled())
            }))?,
        };
        if let Some(name) = &layer.name {
            match layer.mark {
                Mark::Points(r) => drawn
                    .label(name.as_str())
                    .legend(move |(x, y)| Circle::new((x + 8, y), r.min(5), col.filled())),
                Mark::Bars(_) => drawn.label(name.as_str()).legend(move |(x, y)| {
                    Rectangle::new([(x + 2, y - 5), (x + 14, y + 5)], col.filled())
                }),
                _ => drawn.label(name.as_str()).legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 16, y)], col.stroke_width(2))
                }),
            };
        }
    }
    if p.layers.iter().any(|l| l.name.is_some()) {
        c.configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .position(p.legend.clone())
            .draw()?;
    }
    Ok(())
}

/// Benchmark runs (JSON objects) grouped into named series of (x, y), each sorted by x; runs
/// `xy` gives no point for are left out.
pub fn series(
    runs: &[Value],
    name: impl Fn(&Value) -> String,
    xy: impl Fn(&Value) -> Option<(f64, f64)>,
) -> Vec<(String, Vec<(f64, f64)>)> {
    let mut out: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
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

/// Named series as layers, coloured from the palette in order.
pub fn layers(series: Vec<(String, Vec<(f64, f64)>)>) -> Vec<Layer> {
    series
        .into_iter()
        .enumerate()
        .map(|(i, (name, pts))| Layer::new(name, palette(i), pts))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_chart_names_its_panels_and_series() {
        let runs: Vec<Value> = serde_json::from_str(
            r#"[{"m": "a", "t": 2, "q": 0.5}, {"m": "a", "t": 1, "q": 0.4}, {"m": "b", "t": 3}]"#,
        )
        .unwrap();
        let s = series(
            &runs,
            |r| r["m"].as_str().unwrap().to_string(),
            |r| Some((r["t"].as_f64()?, r["q"].as_f64()?)),
        );
        assert_eq!(s, vec![("a".to_string(), vec![(1.0, 0.4), (2.0, 0.5)])]);
        let mut p = Panel::fitted("quality", "seconds", "score", layers(s));
        p.layers
            .push(Layer::level(Some("floor"), RGBColor(0, 0, 0), 0.45, &p.x));
        let out = svg((400, 300), 1, &[p]).unwrap();
        assert!(out.starts_with("<svg") && out.contains("quality") && out.contains("floor"));
    }
}
