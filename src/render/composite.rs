//! Composite rendering: a background and any number of placed objects in one volume-rendering
//! pass (`objnerf render-edit`).
//!
//! Each ray is carried into every field's own frame (the inverse of its placement: a similarity,
//! so the ray stays straight and distances scale by one factor) and marched there by the
//! single-field marcher ([`crate::field::march::forward`]): clipped to the field's box, empty
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
use crate::field::eval::{gray8, rgb8};
use crate::field::march::{forward, Sample};
use crate::field::{Field, RayCamera, RenderOptions};
use glam::{Mat3, Vec3};
use rayon::prelude::*;

/// One field of the composite, with the transform from the world into its frame.
pub struct Layer<'a> {
    pub field: &'a Field,
    /// World -> the field's frame: p' = scale * rot * p + shift.
    pub(super) rot: Mat3,
    pub(super) shift: Vec3,
    /// Field units per world unit (world t = field t / scale).
    pub(super) scale: f32,
    pub(super) recolour: Option<PreparedRecolour>,
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

impl Scratch {
    /// Per layer, the weight it took in the last ray [`render_ray`] drew (which decides the
    /// object index).
    pub fn weights(&self) -> &[f32] {
        &self.weights
    }
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
    for (v, b) in rgb.iter_mut().zip(c.background) {
        *v += trans * b;
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
        rgb8(self.width, self.height, &self.rgb)
    }

    pub fn alpha8(&self) -> image::GrayImage {
        gray8(self.width, self.height, &self.alpha)
    }

    pub fn index8(&self) -> image::GrayImage {
        image::GrayImage::from_fn(self.width, self.height, |x, y| {
            image::Luma([self.index[(y * self.width + x) as usize]])
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::model::FieldConfig;
    use glam::{DQuat, DVec3};

    /// A field over -1..1 with a sharp ball of radius `r` about `c` in one colour (SH DC only).
    fn ball(c: Vec3, r: f32, rgb: [f32; 3]) -> Field {
        let mut f = Field::new(
            FieldConfig {
                sh_degree: 0,
                alpha_init: 0.01,
                base_voxel: 0.05,
            },
            Vec3::splat(-1.0),
            Vec3::splat(1.0),
            [41, 41, 41],
        );
        // SH DC coefficient whose sigmoid(C0 * k) is the colour.
        let logit = |v: f32| (v / (1.0 - v)).ln() / 0.282_094_8;
        for v in 0..f.grid.num_vertices() {
            let [x, y, z] = f.grid.vertex_coords(v as u32);
            let p = Vec3::new(x as f32, y as f32, z as f32) * f.voxel - 1.0;
            *f.grid.density_mut(v) = if (p - c).length() < r { 8.0 } else { -30.0 };
            for (k, c) in rgb.iter().enumerate() {
                f.grid.colour_mut(v)[k] = logit(*c);
            }
        }
        f.prune_occupancy(0.5, 1e-4);
        f
    }

    fn opts() -> RenderOptions {
        RenderOptions::default()
    }

    #[test]
    fn one_layer_in_place_renders_as_the_field_alone() {
        let f = ball(Vec3::new(0.1, -0.2, 0.0), 0.4, [0.8, 0.3, 0.1]);
        let bg = [0.2, 0.5, 0.9];
        let c = Composite {
            layers: vec![Layer::new(&f, &Similarity::IDENTITY, 0)],
            background: bg,
            render: opts(),
        };
        let mut s = Scratch::default();
        let mut scratch = Vec::new();
        for i in 0..50 {
            let o = Vec3::new(-3.0, 0.04 * i as f32 - 1.0, 0.3);
            let d = Vec3::new(1.0, 0.01 * (i % 7) as f32, -0.1).normalize();
            let a = render_ray(&c, o, d, &mut s);
            let b = crate::field::march::render_ray(&f, &opts(), o, d, bg, &mut scratch);
            assert_eq!(a.rgb, b.rgb, "ray {i}");
            assert_eq!(a.alpha, b.alpha, "ray {i}");
        }
    }

    /// Moved, turned and scaled: the ball is drawn where the similarity puts it, as large as it
    /// says, and as opaque as the original.
    #[test]
    fn a_placed_field_is_drawn_where_its_transform_puts_it() {
        let (c0, r0) = (Vec3::new(0.3, 0.0, -0.2), 0.3);
        let f = ball(c0, r0, [0.2, 0.7, 0.3]);
        let sim = Similarity {
            scale: 1.5,
            rotation: DQuat::from_rotation_z(1.2) * DQuat::from_rotation_x(0.4),
            translation: DVec3::new(2.0, -1.0, 0.5),
        };
        let comp = Composite {
            layers: vec![Layer::new(&f, &sim, 3)],
            background: [1.0; 3],
            render: opts(),
        };
        let centre = sim.apply(c0.as_dvec3()).as_vec3();
        let mut s = Scratch::default();
        let eye = Vec3::new(-2.0, 1.5, 1.0);
        let to = (centre - eye).normalize();
        let hit = render_ray(&comp, eye, to, &mut s);
        let want = (centre - eye).length() - 1.5 * r0;
        assert!(hit.alpha > 0.99 && hit.index == 3, "{hit:?}");
        assert!(
            (hit.t_half - want).abs() < 1.5 * f.voxel * 1.5,
            "surface at {} not {want}",
            hit.t_half
        );
        assert!((hit.rgb[1] - 0.7).abs() < 0.02, "{:?}", hit.rgb);
        // A ray passing 1.2 scaled radii from the centre misses; at 0.8 it hits.
        let side = to.cross(Vec3::Z).normalize();
        for (k, hits) in [(1.2, false), (0.8, true)] {
            let aim = centre + side * (k * 1.5 * r0);
            let r = render_ray(&comp, eye, (aim - eye).normalize(), &mut s);
            assert_eq!(r.alpha > 0.5, hits, "offset {k}: {r:?}");
            assert_eq!(r.index, if hits { 3 } else { 0 });
        }
    }

    /// Two fields in the same place: densities add, so the opacity is that of the doubled
    /// optical depth; the nearer of two separate fields hides the farther.
    #[test]
    fn overlapping_fields_add_and_nearer_fields_hide() {
        let f = ball(Vec3::ZERO, 0.5, [0.5, 0.5, 0.5]);
        let mut thin = f.clone();
        for v in 0..thin.grid.num_vertices() {
            let density = thin.grid.density_mut(v);
            if *density > 0.0 {
                *density = 0.0;
            }
        }
        let one = Composite {
            layers: vec![Layer::new(&thin, &Similarity::IDENTITY, 1)],
            background: [1.0; 3],
            render: opts(),
        };
        let two = Composite {
            layers: vec![
                Layer::new(&thin, &Similarity::IDENTITY, 1),
                Layer::new(&thin, &Similarity::IDENTITY, 2),
            ],
            background: [1.0; 3],
            render: opts(),
        };
        let mut s = Scratch::default();
        let (o, d) = (Vec3::new(-3.0, 0.01, 0.02), Vec3::X);
        let a1 = render_ray(&one, o, d, &mut s).alpha;
        let a2 = render_ray(&two, o, d, &mut s).alpha;
        assert!(a1 > 0.1 && a1 < 0.9, "{a1}");
        assert!(
            (a2 - (1.0 - (1.0 - a1).powi(2))).abs() < 1e-4,
            "{a1} -> {a2}"
        );
        // Red in front of green along +x.
        let red = ball(Vec3::ZERO, 0.3, [0.9, 0.1, 0.1]);
        let green = ball(Vec3::ZERO, 0.3, [0.1, 0.9, 0.1]);
        let shift = |x: f64| Similarity {
            translation: DVec3::new(x, 0.0, 0.0),
            ..Similarity::IDENTITY
        };
        let both = Composite {
            layers: vec![
                Layer::new(&green, &shift(1.0), 2),
                Layer::new(&red, &shift(-1.0), 1),
            ],
            background: [1.0; 3],
            render: opts(),
        };
        let r = render_ray(&both, o, d, &mut s);
        assert_eq!(r.index, 1);
        assert!(r.rgb[0] > 0.85 && r.rgb[1] < 0.15, "{:?}", r.rgb);
        let back = render_ray(&both, Vec3::new(3.0, 0.0, 0.0), -d, &mut s);
        assert_eq!(back.index, 2);
    }
}
