//! Composite rendering: a background and any number of placed objects in one volume-rendering
//! pass (`objnerf render-edit`).
//!
//! Each ray is carried into every field's own frame (the inverse of its placement: a similarity,
//! so the ray stays straight and distances scale by one factor) and marched there by the
//! single-field marcher ([`crate::field::render::forward`]): clipped to the field's box, empty
//! bricks skipped, its own early termination. The samples of all fields are then merged in
//! order of distance along the world ray and composited together: densities add (each sample's
//! opacity multiplies the transmittance of everything behind it) and where fields overlap their
//! colours mix in proportion to their densities. A field's opacity is invariant under scaling
//! (a sample's alpha comes from its own step in its own units), so a scaled object is as opaque
//! as the captured one. An object's colour is evaluated in its own frame (the view direction
//! turned back with it), then recoloured if asked.
//!
//! Per pixel: the colour (over the background colour where the fields leave some transmittance),
//! the opacity, the z-depth where the accumulated opacity first reaches one half (the surface a
//! Z-combine should use; +inf where it never does), and the index of the layer that contributes
//! the largest weight (0 = the background, including what shows through; i + 1 = `objects[i]`).

use crate::edit::recolour::PreparedRecolour;
use crate::edit::{LoadedBackground, LoadedEdit, Similarity};
use crate::field::render::{forward, Sample};
use crate::field::{Field, RayCamera, RenderOptions};
use glam::{Mat3, Vec3};
use rayon::prelude::*;

/// One field of the composite, with the transform from the world into its frame.
pub struct Layer<'a> {
    pub field: &'a Field,
    /// World -> the field's frame: p' = scale * rot * p + shift.
    rot: Mat3,
    shift: Vec3,
    /// Field units per world unit (world t = field t / scale).
    scale: f32,
    recolour: Option<PreparedRecolour>,
    /// The value of the object-index pass (0 = background).
    pub index: u8,
}

impl<'a> Layer<'a> {
    /// `field` placed by `to_world` (its frame -> the world).
    pub fn new(field: &'a Field, to_world: &Similarity, index: u8) -> Layer<'a> {
        let inv = to_world.inverse();
        Layer {
            field,
            rot: glam::DMat3::from_quat(inv.rotation).as_mat3(),
            shift: inv.translation.as_vec3(),
            scale: inv.scale as f32,
            recolour: None,
            index,
        }
    }

    pub fn with_recolour(mut self, r: Option<PreparedRecolour>) -> Self {
        self.recolour = r;
        self
    }
}

/// Everything a frame is drawn from.
pub struct Composite<'a> {
    pub layers: Vec<Layer<'a>>,
    /// What shows where the fields leave transmittance (sRGB 0..1).
    pub background: [f32; 3],
    pub render: RenderOptions,
}

impl<'a> Composite<'a> {
    /// The layers of a loaded edit: the background field (if any) and every visible object.
    pub fn from_edit(edit: &'a LoadedEdit, render: RenderOptions) -> Composite<'a> {
        let mut layers = Vec::new();
        let background = match &edit.background {
            LoadedBackground::Color(c) => *c,
            LoadedBackground::Field(m) => {
                layers.push(Layer::new(&m.field, &Similarity::IDENTITY, 0));
                // What a scene field leaves transparent (the sky beyond its grid) shows white,
                // as `objnerf render` draws it.
                [1.0; 3]
            }
        };
        for o in edit.visible() {
            let index = (o.index + 1).min(255) as u8;
            layers.push(
                Layer::new(o.field(), &o.to_world, index)
                    .with_recolour(o.recolour.map(|r| r.prepare())),
            );
        }
        Composite {
            layers,
            background,
            render,
        }
    }
}

/// One rendered frame; pixels row-major from the top-left.
#[derive(Clone, Debug)]
pub struct Frame {
    pub width: u32,
    pub height: u32,
    pub rgb: Vec<[f32; 3]>,
    pub alpha: Vec<f32>,
    /// z-depth along the camera's axis, in the world's units; +inf where opacity stays below 1/2.
    pub depth: Vec<f32>,
    pub index: Vec<u8>,
}

/// One pixel's result.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelOut {
    pub rgb: [f32; 3],
    pub alpha: f32,
    /// Distance along the world ray where the opacity reaches 1/2 (+inf: never).
    pub t_half: f32,
    pub index: u8,
}

/// Per-thread buffers: one sample list per layer and the merge cursors.
#[derive(Default)]
pub struct Scratch {
    samples: Vec<Vec<Sample>>,
    heads: Vec<usize>,
    weights: Vec<f32>,
}

/// Render the ray `o + t d` (d unit) through every layer.
pub fn render_ray(c: &Composite, o: Vec3, d: Vec3, s: &mut Scratch) -> PixelOut {
    let n = c.layers.len();
    s.samples.resize_with(n, Vec::new);
    s.heads.clear();
    s.heads.resize(n, 0);
    s.weights.clear();
    s.weights.resize(n, 0.0);
    for (l, buf) in c.layers.iter().zip(s.samples.iter_mut()) {
        let (ol, dl) = (l.scale * (l.rot * o) + l.shift, l.rot * d);
        forward(l.field, &c.render, ol, dl, 0.5, [0.0; 3], buf);
        if l.scale != 1.0 {
            let to_world = 1.0 / l.scale;
            for smp in buf.iter_mut() {
                smp.t *= to_world;
            }
        }
    }
    let mut trans = 1.0f32;
    let mut rgb = [0.0f32; 3];
    let mut t_half = f32::INFINITY;
    loop {
        // The nearest unmerged sample of all layers (few layers: a linear scan).
        let mut best: Option<(usize, f32)> = None;
        for (li, buf) in s.samples.iter().enumerate() {
            if let Some(smp) = buf.get(s.heads[li]) {
                if best.is_none_or(|(_, t)| smp.t < t) {
                    best = Some((li, smp.t));
                }
            }
        }
        let Some((li, _)) = best else { break };
        let smp = s.samples[li][s.heads[li]];
        s.heads[li] += 1;
        let col = match &c.layers[li].recolour {
            Some(r) => r.apply(smp.rgb),
            None => smp.rgb,
        };
        let w = trans * smp.alpha;
        for k in 0..3 {
            rgb[k] += w * col[k];
        }
        s.weights[li] += w;
        let next = trans * (1.0 - smp.alpha);
        if t_half.is_infinite() && next <= 0.5 {
            t_half = smp.t;
        }
        trans = next;
        if trans < c.render.term_thresh {
            break;
        }
    }
    for k in 0..3 {
        rgb[k] += trans * c.background[k];
    }
    // The background's weight includes what shows through every field; an object wins the
    // pixel only with more weight than the background.
    let mut bg_w = trans;
    for (l, &w) in c.layers.iter().zip(&s.weights) {
        if l.index == 0 {
            bg_w += w;
        }
    }
    let (mut index, mut best_w) = (0u8, bg_w);
    for (l, &w) in c.layers.iter().zip(&s.weights) {
        if l.index != 0 && w > best_w {
            (index, best_w) = (l.index, w);
        }
    }
    PixelOut {
        rgb,
        alpha: 1.0 - trans,
        t_half,
        index,
    }
}

/// Render a whole frame (rows in parallel).
pub fn render_frame(c: &Composite, cam: &RayCamera) -> Frame {
    let (w, h) = (cam.width, cam.height);
    let rows: Vec<Vec<(PixelOut, f32)>> = (0..h)
        .into_par_iter()
        .map_init(Scratch::default, |s, y| {
            (0..w)
                .map(|x| {
                    let idx = y * w + x;
                    let (o, d) = cam.ray(idx);
                    (render_ray(c, o, d, s), cam.ray_scale(idx))
                })
                .collect()
        })
        .collect();
    let n = (w * h) as usize;
    let mut f = Frame {
        width: w,
        height: h,
        rgb: Vec::with_capacity(n),
        alpha: Vec::with_capacity(n),
        depth: Vec::with_capacity(n),
        index: Vec::with_capacity(n),
    };
    for (p, scale) in rows.into_iter().flatten() {
        f.rgb.push(p.rgb);
        f.alpha.push(p.alpha);
        f.depth.push(p.t_half / scale);
        f.index.push(p.index);
    }
    f
}

impl Frame {
    pub fn rgb8(&self) -> image::RgbImage {
        image::RgbImage::from_fn(self.width, self.height, |x, y| {
            let p = self.rgb[(y * self.width + x) as usize];
            image::Rgb(p.map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8))
        })
    }

    pub fn alpha8(&self) -> image::GrayImage {
        image::GrayImage::from_fn(self.width, self.height, |x, y| {
            let a = self.alpha[(y * self.width + x) as usize];
            image::Luma([(a.clamp(0.0, 1.0) * 255.0).round() as u8])
        })
    }

    pub fn index8(&self) -> image::GrayImage {
        image::GrayImage::from_fn(self.width, self.height, |x, y| {
            image::Luma([self.index[(y * self.width + x) as usize]])
        })
    }
}
