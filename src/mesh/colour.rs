//! The colour of a surface point of a field, for vertex colours and baked textures.
//!
//! A radiance field's colour depends on the direction it is seen from; a mesh has one colour per
//! point. That one colour is the mean, over the (at most sixteen) training cameras most head-on to
//! the point on its outer side, of what each camera's ray through the point shows: the field's
//! colour in that direction composited along that ray from just before the point to two voxels
//! past it, so a point of a decimated mesh a little off the field's surface still shows what the
//! cameras saw there. The mean is weighted by the cosine of each camera's angle to the normal (a
//! head-on view sees the point sharpest). SH fields and fields with a colour network alike: the
//! network's per-direction part is computed once a ray, its per-sample part only at the few
//! samples with weight. Cameras whose view of the point the mesh itself blocks are left out
//! where the depth maps are built ([`super::visibility`]). Without the training cameras (models written
//! before they were recorded), or where no camera's ray meets the surface, an SH field gives its
//! DC term (the mean over all directions) composited along the inward normal, a network field
//! its view along the normal.

use super::fill::EMPTY;
use super::visibility::SeenFrom;
use crate::field::colour_net::MAX_ACTIVATIONS;
use crate::field::model::{Field, RayShading, MAX_CHANNELS};
use crate::field::sh::{sh_basis, SH_TERMS};
use glam::Vec3;

/// Cameras a surface point's colour is averaged over, the most head-on first. Sixteen against
/// eight (`examples/results/textured_mesh.md`, fourteenth session): a decimated surface lies a
/// little off the field's, so what each camera sees through a point differs by parallax, and the
/// mean over more of the views that will look at it fits them better (lego's default export
/// +0.08 dB, the fox head's +0.16, the demo mug's -0.02); 32 gained little more (+0.02 / +0.04)
/// and cost lego's full mesh 0.04.
const MAX_CAMERAS: usize = 16;

/// How far along a camera's ray through a surface point, and how finely, the field is read.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayReach {
    /// World units the read reaches further both ways, for a point off the field's iso-surface
    /// (a decimated mesh's): 0 for the marching-cubes mesh itself.
    pub slack: f32,
    /// The step between samples, in the field's finest voxels.
    pub step_voxels: f32,
}

impl RayReach {
    /// The marching-cubes mesh's vertices: on the surface, read a quarter voxel apart.
    pub const ON_SURFACE: RayReach = RayReach {
        slack: 0.0,
        step_voxels: 0.25,
    };
}

/// The training cameras' centres in a model's notes (`view_centres`; empty when absent).
pub fn view_centres(notes: &serde_json::Value) -> Vec<Vec3> {
    notes["view_centres"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|c| {
            let v: Vec<f32> = c
                .as_array()?
                .iter()
                .filter_map(|x| x.as_f64().map(|x| x as f32))
                .collect();
            (v.len() == 3 && v.iter().all(|x| x.is_finite())).then(|| Vec3::new(v[0], v[1], v[2]))
        })
        .collect()
}

/// The field's raw density at a world point, EMPTY where occupancy says the renderer skips it.
pub(crate) fn raw_at(field: &Field, p: Vec3) -> f32 {
    let g = field.to_grid(p);
    let dims = field.grid.dims;
    let inside = (0..3).all(|a| g[a] >= 0.0 && g[a] <= (dims[a] - 1) as f32);
    if !inside {
        return EMPTY;
    }
    let (b, fr) = field.grid.locate([g.x, g.y, g.z]);
    if !field.occupied(b) {
        return EMPTY;
    }
    let k = field.grid.corners_of(b, fr);
    field.grid.interp_density(&k)
}

/// Colour at a world point seen along `dir` on a ray shaded by `shading` ([`Field::shading`]), 0..1.
fn colour_at(field: &Field, p: Vec3, dir: Vec3, shading: &RayShading) -> [f32; 3] {
    let g = field.to_grid(p);
    let dims = field.grid.dims;
    let g = [0, 1, 2].map(|a| g[a].clamp(0.0, (dims[a] - 1) as f32));
    let (b, fr) = field.grid.locate(g);
    let k = field.grid.corners_of(b, fr);
    let mut feat = [0f32; MAX_CHANNELS];
    let ch = field.grid.channels;
    field.grid.interp_colour(&k, &mut feat[..ch - 1]);
    let mut h = [0f32; MAX_ACTIVATIONS];
    let refl = field.reflection_basis(&k, fr, dir);
    field.shade(&feat, &refl, shading, &mut h)
}

/// The shading of a ray along `dir` (`dc_only`: an SH field's mean over all directions).
fn ray_shading(field: &Field, dir: Vec3, dc_only: bool) -> RayShading {
    let mut basis = [0f32; SH_TERMS];
    if dc_only {
        basis[0] = 0.282_094_8;
    } else {
        sh_basis(field.config.sh_degree, dir, &mut basis);
    }
    field.shading(basis)
}

/// Samples with their compositing weights along `dir` through `p`, from half a voxel (and
/// the reach's slack, at most 16 voxels) before it to two voxels (and the slack) past it.
fn samples_along(field: &Field, p: Vec3, dir: Vec3, reach: RayReach) -> Vec<(Vec3, f32)> {
    let step = reach.step_voxels * field.voxel;
    let delta = step / field.config.base_voxel;
    let shift = field.shift();
    let mut trans = 1.0f32;
    let mut out = Vec::with_capacity(16);
    let steps_of = |voxels: f32| (voxels / reach.step_voxels).ceil() as i32;
    let extra = ((reach.slack / step).ceil() as i32).clamp(0, steps_of(16.0));
    for i in -steps_of(0.5) - extra..steps_of(2.0) + extra {
        let q = p + dir * (i as f32 * step);
        let raw = raw_at(field, q);
        if raw <= EMPTY {
            continue;
        }
        let alpha = 1.0 - (-crate::field::activation::softplus(raw + shift) * delta).exp();
        let w = trans * alpha;
        if w > 0.0 {
            out.push((q, w));
        }
        trans *= 1.0 - alpha;
        if trans < 1e-3 {
            break;
        }
    }
    out
}

/// Colour at a surface point `p` with normal `n` (see the module's notes), each ray read as
/// `reach` says; `seen`: the training cameras and which of them see the point.
pub fn surface_colour(
    field: &Field,
    p: Vec3,
    n: Vec3,
    reach: RayReach,
    seen: &SeenFrom,
) -> [f32; 3] {
    let slack = reach.slack;
    // (direction, cosine, whether the camera's view of the point is not blocked)
    let mut facing: Vec<(Vec3, f32, bool)> = seen
        .centres
        .iter()
        .enumerate()
        .filter_map(|(i, c)| {
            let to_cam = (*c - p).normalize_or_zero();
            let cos = to_cam.dot(n);
            (cos > 0.05).then(|| (-to_cam, cos, seen.sees(i, p, slack)))
        })
        .collect();
    // The cameras that see the point; where none does (a point the depth maps miss), every
    // facing one, as without the test.
    if facing.iter().any(|f| f.2) {
        facing.retain(|f| f.2);
    }
    // The most head-on cameras only: they see the point sharpest, and the cost stays bounded.
    facing.sort_unstable_by(|a, b| b.1.total_cmp(&a.1));
    facing.truncate(MAX_CAMERAS);
    // What each camera's ray through the point shows (so a mesh a little off the field's
    // surface still shows what the cameras saw there), weighted by the cosine.
    let mut acc = [0f32; 3];
    let mut csum = 0f32;
    for (dir, cos, _) in &facing {
        let slanted = RayReach {
            slack: slack / cos.max(0.25),
            ..reach
        };
        let Some(c) = along_ray(field, p, *dir, slanted) else {
            continue;
        };
        (0..3).for_each(|k| acc[k] += cos * c[k]);
        csum += cos;
    }
    if csum > 0.0 {
        return acc.map(|a| (a / csum).clamp(0.0, 1.0));
    }
    // No camera: along the inward normal, an SH field's mean over directions (a network's view
    // head-on).
    let samples = samples_along(field, p, -n, reach);
    let shading = ray_shading(field, -n, field.net.is_none());
    composite(&samples, |q| colour_at(field, q, -n, &shading))
        .unwrap_or_else(|| colour_at(field, p, -n, &shading))
}

/// The colour composited along the ray of direction `dir` through `p` ([`samples_along`]);
/// None where that ray meets too little.
fn along_ray(field: &Field, p: Vec3, dir: Vec3, reach: RayReach) -> Option<[f32; 3]> {
    let samples = samples_along(field, p, dir, reach);
    if samples.iter().map(|s| s.1).sum::<f32>() <= 0.2 {
        return None;
    }
    let shading = ray_shading(field, dir, false);
    composite(&samples, |q| colour_at(field, q, dir, &shading))
}

/// The weighted mean of `colour` over `samples` (None: no weight).
fn composite(samples: &[(Vec3, f32)], colour: impl Fn(Vec3) -> [f32; 3]) -> Option<[f32; 3]> {
    let wsum: f32 = samples.iter().map(|s| s.1).sum();
    if wsum <= 1e-6 {
        return None;
    }
    let mut acc = [0f32; 3];
    for (q, w) in samples {
        let c = colour(*q);
        (0..3).for_each(|k| acc[k] += w * c[k]);
    }
    Some(acc.map(|a| (a / wsum).clamp(0.0, 1.0)))
}
