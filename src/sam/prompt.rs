//! Prompts for SAM's decoder: points (object or background), one box, and an optional low-res mask
//! from an earlier prediction. Coordinates are continuous pixel coordinates of the original image
//! with (0, 0) at the top-left corner of the top-left pixel, so that pixel (i, j) has its centre at
//! (i + 0.5, j + 0.5) (COLMAP's convention, used everywhere in objnerf).

use crate::error::{Error, Result};

/// One click.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Point {
    pub x: f32,
    pub y: f32,
    /// true: on the object; false: background.
    pub positive: bool,
}

/// A box `[x0, y0, x1, y1]` (corners, same convention as points).
pub type BoxPrompt = [f32; 4];

/// SAM's low-res mask side (the decoder's `mask_input` / `low_res_masks` are 256 x 256).
pub const LOW_RES: usize = 256;

#[derive(Clone, Debug, Default)]
pub struct Prompts {
    pub points: Vec<Point>,
    pub bbox: Option<BoxPrompt>,
    /// Logits (256 x 256, row-major) of an earlier prediction on the same image, to refine it.
    pub mask_input: Option<Vec<f32>>,
}

impl Prompts {
    pub fn new() -> Self {
        Self::default()
    }
    /// One point on the object.
    pub fn click(x: f32, y: f32) -> Self {
        Prompts::new().point(x, y, true)
    }
    pub fn point(mut self, x: f32, y: f32, positive: bool) -> Self {
        self.points.push(Point { x, y, positive });
        self
    }
    pub fn with_box(mut self, b: BoxPrompt) -> Self {
        self.bbox = Some(b);
        self
    }
    /// Refine: feed the previous prediction's low-res logits back in.
    pub fn with_mask_input(mut self, low_res: Vec<f32>) -> Self {
        self.mask_input = Some(low_res);
        self
    }

    /// Reject prompts that cannot be meant for a `width` x `height` image: no prompt at all,
    /// coordinates outside `[0, width] x [0, height]` or not finite, an inverted box, a mask of the
    /// wrong size.
    pub fn validate(&self, width: u32, height: u32) -> Result<()> {
        if self.points.is_empty() && self.bbox.is_none() {
            return Err(Error::invalid(
                "no prompt: give at least one point or a box",
            ));
        }
        let (w, h) = (width as f32, height as f32);
        let inside = |x: f32, y: f32| {
            x.is_finite() && y.is_finite() && (0.0..=w).contains(&x) && (0.0..=h).contains(&y)
        };
        for p in &self.points {
            if !inside(p.x, p.y) {
                return Err(Error::invalid(format!(
                    "point ({}, {}) is outside the {width}x{height} image (coordinates run from 0,0 at the top-left corner to {width},{height})",
                    p.x, p.y
                )));
            }
        }
        if let Some([x0, y0, x1, y1]) = self.bbox {
            if !inside(x0, y0) || !inside(x1, y1) {
                return Err(Error::invalid(format!(
                    "box ({x0}, {y0}, {x1}, {y1}) is outside the {width}x{height} image"
                )));
            }
            if x1 <= x0 || y1 <= y0 {
                return Err(Error::invalid(format!(
                    "box ({x0}, {y0}, {x1}, {y1}) is empty: need x0 < x1 and y0 < y1"
                )));
            }
        }
        if let Some(m) = &self.mask_input {
            if m.len() != LOW_RES * LOW_RES {
                return Err(Error::invalid(format!(
                    "mask input has {} values, expected {LOW_RES}x{LOW_RES}",
                    m.len()
                )));
            }
        }
        Ok(())
    }

    /// The decoder's `point_coords` (flattened N x 2, in the resized 1024 frame) and
    /// `point_labels`. `scale` is resized/original. SAM adds 0.5 to its coordinates before the
    /// positional encoding (it treats them as pixel indices), so a continuous coordinate `u` becomes
    /// `u * scale - 0.5`: the click lands on exactly the same spot of the resized image.
    pub fn decoder_inputs(&self, scale: f64) -> (Vec<f32>, Vec<f32>) {
        let map = |u: f32| (u as f64 * scale - 0.5) as f32;
        let mut coords = Vec::new();
        let mut labels = Vec::new();
        for p in &self.points {
            coords.extend([map(p.x), map(p.y)]);
            labels.push(if p.positive { 1.0 } else { 0.0 });
        }
        match self.bbox {
            Some([x0, y0, x1, y1]) => {
                coords.extend([map(x0), map(y0), map(x1), map(y1)]);
                labels.extend([2.0, 3.0]);
            }
            // Without a box the ONNX decoder expects a padding point (label -1).
            None => {
                coords.extend([0.0, 0.0]);
                labels.push(-1.0);
            }
        }
        (coords, labels)
    }
}

/// Parse `x,y[,fg|bg]` (also `+`/`-`, `1`/`0`, `pos`/`neg`); the default is a positive point.
pub fn parse_point(s: &str) -> Result<Point> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    let bad = || {
        Error::invalid(format!(
            "--point {s:?}: expected x,y or x,y,fg or x,y,bg (pixel coordinates)"
        ))
    };
    if parts.len() < 2 || parts.len() > 3 {
        return Err(bad());
    }
    let x: f32 = parts[0].parse().map_err(|_| bad())?;
    let y: f32 = parts[1].parse().map_err(|_| bad())?;
    let positive = match parts.get(2).map(|t| t.to_ascii_lowercase()) {
        None => true,
        Some(t) => match t.as_str() {
            "fg" | "+" | "1" | "pos" | "positive" => true,
            "bg" | "-" | "0" | "neg" | "negative" => false,
            _ => return Err(bad()),
        },
    };
    Ok(Point { x, y, positive })
}

/// Parse `x0,y0,x1,y1`.
pub fn parse_box(s: &str) -> Result<BoxPrompt> {
    let v: Vec<f32> = s
        .split(',')
        .map(|t| t.trim().parse::<f32>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| Error::invalid(format!("--box {s:?}: expected x0,y0,x1,y1")))?;
    match v[..] {
        [a, b, c, d] => Ok([a, b, c, d]),
        _ => Err(Error::invalid(format!("--box {s:?}: expected x0,y0,x1,y1"))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse() {
        assert_eq!(
            parse_point("10,20").unwrap(),
            Point {
                x: 10.0,
                y: 20.0,
                positive: true
            }
        );
        assert!(!parse_point("1.5, 2,bg").unwrap().positive);
        assert!(parse_point("1").is_err());
        assert!(parse_point("1,2,maybe").is_err());
        assert_eq!(parse_box("0,1,2,3").unwrap(), [0.0, 1.0, 2.0, 3.0]);
        assert!(parse_box("0,1,2").is_err());
    }

    #[test]
    fn validate_and_map() {
        let p = Prompts::click(10.0, 5.0);
        assert!(p.validate(20, 10).is_ok());
        assert!(Prompts::click(21.0, 5.0).validate(20, 10).is_err());
        assert!(Prompts::click(f32::NAN, 5.0).validate(20, 10).is_err());
        assert!(Prompts::new().validate(20, 10).is_err());
        assert!(Prompts::new()
            .with_box([5.0, 5.0, 1.0, 8.0])
            .validate(20, 10)
            .is_err());
        // Pixel (0, 0)'s centre maps to the centre of resized pixel (0, 0) at scale 2 ... in SAM's
        // index convention: 0.5 * 2 - 0.5 = 0.5, whose +0.5 shift gives 1.0 = 0.5 * 2. Consistent.
        let (c, l) = p.decoder_inputs(2.0);
        assert_eq!(c, vec![19.5, 9.5, 0.0, 0.0]);
        assert_eq!(l, vec![1.0, -1.0]);
        let (c, l) = Prompts::new()
            .with_box([0.0, 0.0, 4.0, 2.0])
            .decoder_inputs(1.0);
        assert_eq!(c, vec![-0.5, -0.5, 3.5, 1.5]);
        assert_eq!(l, vec![2.0, 3.0]);
    }
}
