//! Recolouring that keeps shading: a colour's OKLab lightness is kept and its hue and chroma are
//! moved, towards a target colour's or by a hue rotation (Björn Ottosson's OKLab, on linear sRGB).
//! Where the new colour falls outside the sRGB gamut at that lightness, its chroma is reduced
//! (hue and lightness kept) until it fits, so dark and bright shades stay dark and bright.

use glam::Vec3;

/// `#RRGGBB` as sRGB 0..1.
pub fn parse_hex_colour(s: &str) -> std::result::Result<[f32; 3], String> {
    let hex = s.strip_prefix('#').unwrap_or("");
    if hex.len() != 6 || !hex.chars().all(|c| c.is_ascii_hexdigit()) {
        return Err(format!("'{s}' is not a colour written #RRGGBB"));
    }
    let v = |i: usize| u8::from_str_radix(&hex[i..i + 2], 16).expect("checked hex") as f32 / 255.0;
    Ok([v(0), v(2), v(4)])
}

/// `#rrggbb` from sRGB 0..1.
pub fn hex_colour(rgb: [f32; 3]) -> String {
    let b = rgb.map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8);
    format!("#{:02x}{:02x}{:02x}", b[0], b[1], b[2])
}

/// How to recolour an object (the edit file's `recolour`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Recolour {
    /// Towards the target's hue and chroma (sRGB 0..1), by `strength` in 0..1.
    Target { rgb: [f32; 3], strength: f32 },
    /// A hue rotation of `degrees * strength` in OKLab's a-b plane.
    Hue { degrees: f32, strength: f32 },
}

#[inline]
fn to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

#[inline]
fn to_srgb(c: f32) -> f32 {
    if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// OKLab (L, a, b) of an sRGB colour (0..1).
pub fn srgb_to_oklab(rgb: [f32; 3]) -> Vec3 {
    let [r, g, b] = rgb.map(to_linear);
    let l = 0.412_221_46 * r + 0.536_332_55 * g + 0.051_445_995 * b;
    let m = 0.211_903_5 * r + 0.680_699_5 * g + 0.107_396_96 * b;
    let s = 0.088_302_46 * r + 0.281_718_85 * g + 0.629_978_7 * b;
    let (l, m, s) = (l.cbrt(), m.cbrt(), s.cbrt());
    Vec3::new(
        0.210_454_26 * l + 0.793_617_8 * m - 0.004_072_047 * s,
        1.977_998_5 * l - 2.428_592_2 * m + 0.450_593_7 * s,
        0.025_904_037 * l + 0.782_771_77 * m - 0.808_675_77 * s,
    )
}

/// Linear sRGB of an OKLab colour (may lie outside 0..1).
fn oklab_to_linear(lab: Vec3) -> Vec3 {
    let l = lab.x + 0.396_337_78 * lab.y + 0.215_803_76 * lab.z;
    let m = lab.x - 0.105_561_346 * lab.y - 0.063_854_17 * lab.z;
    let s = lab.x - 0.089_484_18 * lab.y - 1.291_485_5 * lab.z;
    let (l, m, s) = (l * l * l, m * m * m, s * s * s);
    Vec3::new(
        4.076_741_7 * l - 3.307_711_6 * m + 0.230_969_94 * s,
        -1.268_438 * l + 2.609_757_4 * m - 0.341_319_38 * s,
        -0.004_196_086_3 * l - 0.703_418_6 * m + 1.707_614_7 * s,
    )
}

fn in_gamut(c: Vec3) -> bool {
    const EPS: f32 = 1e-5;
    c.min_element() >= -EPS && c.max_element() <= 1.0 + EPS
}

/// sRGB (0..1) of an OKLab colour, its chroma reduced until it fits the gamut (bisection).
pub fn oklab_to_srgb(lab: Vec3) -> [f32; 3] {
    let lin = oklab_to_linear(lab);
    let fitted = if in_gamut(lin) {
        lin
    } else {
        let grey = oklab_to_linear(Vec3::new(lab.x.clamp(0.0, 1.0), 0.0, 0.0));
        let (mut lo, mut hi) = (0.0f32, 1.0f32);
        for _ in 0..12 {
            let mid = 0.5 * (lo + hi);
            if in_gamut(oklab_to_linear(Vec3::new(lab.x, lab.y * mid, lab.z * mid))) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        if lo > 0.0 {
            oklab_to_linear(Vec3::new(lab.x, lab.y * lo, lab.z * lo))
        } else {
            grey
        }
    };
    [fitted.x, fitted.y, fitted.z].map(|c| to_srgb(c.clamp(0.0, 1.0)))
}

impl Recolour {
    /// From a command-line spec: a target `#RRGGBB` or `hue:DEGREES`, with a strength in 0..1.
    pub fn from_spec(spec: &str, strength: f32) -> Result<Recolour, String> {
        if !(0.0..=1.0).contains(&strength) {
            return Err(format!(
                "recolour strength {strength} is not between 0 and 1"
            ));
        }
        if let Some(d) = spec.strip_prefix("hue:") {
            let degrees: f32 = d
                .trim()
                .parse()
                .ok()
                .filter(|v: &f32| v.is_finite())
                .ok_or_else(|| format!("recolour '{spec}': hue:DEGREES needs a number"))?;
            return Ok(Recolour::Hue { degrees, strength });
        }
        let rgb = parse_hex_colour(spec).map_err(|e| format!("recolour {e} (or hue:DEGREES)"))?;
        Ok(Recolour::Target { rgb, strength })
    }

    /// The precomputed form, for applying to many colours.
    pub fn prepare(&self) -> PreparedRecolour {
        match *self {
            Recolour::Target { rgb, strength } => {
                let t = srgb_to_oklab(rgb);
                PreparedRecolour {
                    target_ab: Some([t.y, t.z]),
                    strength: strength.clamp(0.0, 1.0),
                    cos_sin: [1.0, 0.0],
                }
            }
            Recolour::Hue { degrees, strength } => {
                let (s, c) = (degrees * strength).to_radians().sin_cos();
                PreparedRecolour {
                    target_ab: None,
                    strength: strength.clamp(0.0, 1.0),
                    cos_sin: [c, s],
                }
            }
        }
    }

    /// Recolour one sRGB colour (0..1).
    pub fn apply(&self, rgb: [f32; 3]) -> [f32; 3] {
        self.prepare().apply(rgb)
    }
}

/// A [`Recolour`] with the target's OKLab and the rotation's sine and cosine computed once.
#[derive(Clone, Copy, Debug)]
pub struct PreparedRecolour {
    target_ab: Option<[f32; 2]>,
    strength: f32,
    cos_sin: [f32; 2],
}

impl PreparedRecolour {
    /// (the target's OKLab a-b, if a target; the strength; the hue turn's cosine and sine):
    /// what the GPU renderer applies in the same arithmetic.
    pub fn parts(&self) -> (Option<[f32; 2]>, f32, [f32; 2]) {
        (self.target_ab, self.strength, self.cos_sin)
    }

    /// Recolour one sRGB colour (0..1): lightness kept, a-b moved.
    pub fn apply(&self, rgb: [f32; 3]) -> [f32; 3] {
        let lab = srgb_to_oklab(rgb);
        let (a, b) = match self.target_ab {
            Some([ta, tb]) => (
                lab.y + self.strength * (ta - lab.y),
                lab.z + self.strength * (tb - lab.z),
            ),
            None => {
                let [c, s] = self.cos_sin;
                (c * lab.y - s * lab.z, s * lab.y + c * lab.z)
            }
        };
        oklab_to_srgb(Vec3::new(lab.x, a, b))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn oklab_round_trips_and_matches_reference_values() {
        // Ottosson's reference: sRGB white is L = 1, a = b = 0; pure blue (0, 0, 1) is
        // (0.4520, -0.0325, -0.3115).
        let w = srgb_to_oklab([1.0; 3]);
        assert!(
            (w - Vec3::new(1.0, 0.0, 0.0)).abs().max_element() < 1e-4,
            "{w}"
        );
        let b = srgb_to_oklab([0.0, 0.0, 1.0]);
        assert!(
            (b - Vec3::new(0.452, -0.0325, -0.3115)).abs().max_element() < 1e-3,
            "{b}"
        );
        for rgb in [[0.2, 0.5, 0.7], [0.9, 0.1, 0.3], [0.05, 0.05, 0.06]] {
            let back = oklab_to_srgb(srgb_to_oklab(rgb));
            for c in 0..3 {
                assert!((back[c] - rgb[c]).abs() < 1e-4, "{rgb:?} -> {back:?}");
            }
        }
    }

    #[test]
    fn recolour_keeps_lightness_and_takes_the_target_hue() {
        let blue = [0.125, 0.314, 1.0];
        let r = Recolour::Target {
            rgb: blue,
            strength: 1.0,
        };
        let target_hue = {
            let t = srgb_to_oklab(blue);
            t.z.atan2(t.y)
        };
        for rgb in [[0.78, 0.14, 0.1], [0.3, 0.3, 0.3], [0.9, 0.8, 0.6]] {
            let out = r.apply(rgb);
            let (a, b) = (srgb_to_oklab(rgb), srgb_to_oklab(out));
            assert!((a.x - b.x).abs() < 2e-3, "lightness {} -> {}", a.x, b.x);
            assert!((b.z.atan2(b.y) - target_hue).abs() < 1e-2, "{out:?}");
        }
        // Strength 0 changes nothing; a full turn of hue changes nothing.
        let none = Recolour::Target {
            rgb: blue,
            strength: 0.0,
        };
        let turn = Recolour::Hue {
            degrees: 360.0,
            strength: 1.0,
        };
        for rgb in [[0.78, 0.14, 0.1], [0.2, 0.6, 0.3]] {
            for out in [none.apply(rgb), turn.apply(rgb)] {
                for c in 0..3 {
                    assert!((out[c] - rgb[c]).abs() < 1e-4);
                }
            }
        }
    }
}
