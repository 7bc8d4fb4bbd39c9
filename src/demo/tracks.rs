//! The sparse model: surface points with true, visibility-checked tracks, and per-image 2D
//! features that look like what SIFT + matching would give (exact projections, optional pixel
//! noise, a fraction of mismatched observations, and unmatched features).

use super::geometry::{World, BACKDROP, FLOOR};
use super::render::pixel_ray;
use super::texture::Textures;
use super::DemoOptions;
use crate::scene::{Camera, Feature, Point3D, Pose, TrackElement};
use crate::util::Rng;
use glam::{DVec2, DVec3};
use rayon::prelude::*;

/// Points sampled per surface: each object, the floor, the backdrop (denser on the objects).
const SAMPLES_PER_OBJECT: usize = 700;
const SAMPLES_FLOOR: usize = 700;
const SAMPLES_BACKDROP: usize = 1000;
/// A plain (untextured) object gets this many times fewer points: SIFT finds little on it.
const PLAIN_DIVISOR: usize = 20;
/// Unmatched features per image, as a fraction of its matched ones.
const UNMATCHED_FRACTION: f64 = 0.25;
/// A point counts as seen when the first hit along the camera ray is within this of it (m).
const VISIBLE_TOL: f64 = 1e-4;
/// Grazing surfaces give no usable features: require cos(normal, view) above this.
const MIN_FACING: f64 = 0.05;
/// A mismatched observation lands at least this far from the true projection (px).
const MIN_OUTLIER_PX: f64 = 15.0;

struct Sample {
    p: DVec3,
    n: DVec3,
    id: u8,
}

pub struct SparseModel {
    pub points: Vec<Point3D>,
    /// Per image, its features (tracks refer to them by index).
    pub features: Vec<Vec<Feature>>,
}

/// Sample surface points where the views see them: pick a view and a pixel showing the wanted
/// surface (from the per-view id buffers), jitter within the pixel, and trace.
fn sample_surface(
    world: &World,
    cam: &Camera,
    poses: &[Pose],
    ids: &[Vec<u8>],
    rng: &mut Rng,
) -> Vec<Sample> {
    let w = cam.width as usize;
    let mut out = Vec::new();
    let mut classes: Vec<(u8, usize)> = world
        .objects
        .iter()
        .enumerate()
        .map(|(i, o)| {
            let n = if o.plain {
                SAMPLES_PER_OBJECT / PLAIN_DIVISOR
            } else {
                SAMPLES_PER_OBJECT
            };
            (i as u8, n)
        })
        .collect();
    classes.push((FLOOR, SAMPLES_FLOOR));
    classes.push((BACKDROP, SAMPLES_BACKDROP));
    for (class, count) in classes {
        let pixels: Vec<Vec<u32>> = ids
            .iter()
            .map(|v| {
                v.iter()
                    .enumerate()
                    .filter(|(_, &id)| id == class)
                    .map(|(i, _)| i as u32)
                    .collect()
            })
            .collect();
        if pixels.iter().all(|p| p.is_empty()) {
            continue;
        }
        let mut got = 0;
        for _ in 0..count * 20 {
            if got == count {
                break;
            }
            let v = rng.below(poses.len());
            if pixels[v].is_empty() {
                continue;
            }
            let i = pixels[v][rng.below(pixels[v].len())] as usize;
            let px = DVec2::new((i % w) as f64 + rng.f64(), (i / w) as f64 + rng.f64());
            if let Some(hit) = world.trace(&pixel_ray(cam, &poses[v], px), None) {
                if hit.id == class {
                    out.push(Sample {
                        p: hit.p,
                        n: hit.n,
                        id: hit.id,
                    });
                    got += 1;
                }
            }
        }
    }
    out
}

/// The views that see a point, with its exact projection in each.
fn observe(world: &World, cam: &Camera, poses: &[Pose], s: &Sample) -> Vec<(usize, DVec2)> {
    let mut seen = Vec::new();
    for (v, pose) in poses.iter().enumerate() {
        let Some(px) = cam.project(pose.world_to_camera(s.p)) else {
            continue;
        };
        if !cam.contains(px) {
            continue;
        }
        let to_cam = pose.center() - s.p;
        let dist = to_cam.length();
        if s.n.dot(to_cam) < MIN_FACING * dist {
            continue;
        }
        let ray = super::geometry::Ray {
            o: pose.center(),
            d: -to_cam / dist,
        };
        match world.trace(&ray, None) {
            Some(hit) if hit.id == s.id && (hit.t - dist).abs() < VISIBLE_TOL => seen.push((v, px)),
            _ => {}
        }
    }
    seen
}

/// Build points, tracks and features. `opts.noise_px`: Gaussian pixel noise on every
/// observation; `opts.outlier_fraction`: that fraction of points gets one observation moved
/// elsewhere in its image.
pub fn build(
    world: &World,
    tex: &Textures,
    cam: &Camera,
    poses: &[Pose],
    ids: &[Vec<u8>],
    opts: &DemoOptions,
    rng: &mut Rng,
) -> SparseModel {
    let (noise_px, outlier_fraction) = (opts.noise_px, opts.outlier_fraction);
    let samples = sample_surface(world, cam, poses, ids, rng);
    let seen: Vec<Vec<(usize, DVec2)>> = samples
        .par_iter()
        .map(|s| observe(world, cam, poses, s))
        .collect();
    // Keep points seen at least twice (a single observation is no correspondence).
    let mut kept: Vec<(&Sample, Vec<(usize, DVec2)>)> = samples
        .iter()
        .zip(seen)
        .filter(|(_, obs)| obs.len() >= 2)
        .collect();

    let (w, h) = (cam.width as f64, cam.height as f64);
    let clamp = |p: DVec2| DVec2::new(p.x.clamp(0.0, w - 1e-6), p.y.clamp(0.0, h - 1e-6));
    if noise_px > 0.0 {
        for (_, obs) in kept.iter_mut() {
            for (_, xy) in obs.iter_mut() {
                *xy = clamp(*xy + DVec2::new(rng.normal(), rng.normal()) * noise_px);
            }
        }
    }
    let n_out = (outlier_fraction * kept.len() as f64).round() as usize;
    let mut order: Vec<usize> = (0..kept.len()).collect();
    rng.shuffle(&mut order);
    for &k in order.iter().take(n_out) {
        let obs = &mut kept[k].1;
        let j = rng.below(obs.len());
        let truth = obs[j].1;
        // Like a SIFT mismatch: a feature somewhere else in the image.
        for _ in 0..100 {
            let xy = DVec2::new(rng.range(0.0, w), rng.range(0.0, h));
            if (xy - truth).length() >= MIN_OUTLIER_PX {
                obs[j].1 = xy;
                break;
            }
        }
    }

    // Features per image: matched ones, then unmatched ones at random places; then shuffled so
    // nothing downstream can rely on their order.
    let mut per_image: Vec<Vec<Feature>> = vec![Vec::new(); poses.len()];
    for (pi, (_, obs)) in kept.iter().enumerate() {
        for &(v, xy) in obs {
            per_image[v].push(Feature {
                xy,
                point: Some(pi),
            });
        }
    }
    for feats in per_image.iter_mut() {
        let extra = (feats.len() as f64 * UNMATCHED_FRACTION).round() as usize;
        for _ in 0..extra {
            let xy = DVec2::new(rng.range(0.0, w), rng.range(0.0, h));
            feats.push(Feature { xy, point: None });
        }
        rng.shuffle(feats);
    }
    let mut tracks: Vec<Vec<TrackElement>> = vec![Vec::new(); kept.len()];
    for (v, feats) in per_image.iter().enumerate() {
        for (fi, f) in feats.iter().enumerate() {
            if let Some(p) = f.point {
                tracks[p].push(TrackElement {
                    image: v,
                    feature: fi,
                });
            }
        }
    }
    let points = kept
        .iter()
        .zip(tracks)
        .enumerate()
        .map(|(i, ((s, _), track))| {
            let err = track
                .iter()
                .map(|t| {
                    let px = cam
                        .project(poses[t.image].world_to_camera(s.p))
                        .unwrap_or(DVec2::ZERO);
                    (px - per_image[t.image][t.feature].xy).length()
                })
                .sum::<f64>()
                / track.len() as f64;
            let hit = super::geometry::Hit {
                t: 0.0,
                id: s.id,
                p: s.p,
                n: s.n,
            };
            let c = tex.albedo(world, &hit);
            Point3D {
                id: i as u64 + 1,
                xyz: s.p,
                rgb: c
                    .to_array()
                    .map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8),
                error: err,
                track,
            }
        })
        .collect();
    SparseModel {
        points,
        features: per_image,
    }
}
