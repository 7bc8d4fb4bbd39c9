//! Chamfer distance between two triangle meshes: points sampled on each surface (area-weighted,
//! seeded), nearest neighbours found through a uniform grid, distances averaged both ways; and
//! the same over only the parts of each surface some camera sees ([`chamfer_distance_seen`]),
//! for a capture whose cameras cannot see all of an object (the inside of a cup from a ring).

use crate::field::RayCamera;
use crate::mesh::raster::depth_map;
use crate::mesh::Mesh;
use crate::util::Rng;
use glam::DVec3;
use rayon::prelude::*;
use std::collections::HashMap;

/// `n` points on the surface, area-weighted, deterministic for `seed`.
pub fn sample_surface(mesh: &Mesh, n: usize, seed: u64) -> Vec<DVec3> {
    let p = |i: u32| DVec3::from_array(mesh.positions[i as usize].map(|x| x as f64));
    let areas: Vec<f64> = mesh
        .triangles
        .iter()
        .map(|t| 0.5 * (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0])).length())
        .collect();
    let total: f64 = areas.iter().sum();
    if total <= 0.0 || n == 0 {
        return vec![];
    }
    let mut cdf = Vec::with_capacity(areas.len());
    let mut acc = 0.0;
    for a in &areas {
        acc += a / total;
        cdf.push(acc);
    }
    let mut rng = Rng::new(seed);
    (0..n)
        .map(|_| {
            let u = rng.f64();
            let k = cdf.partition_point(|c| *c < u).min(cdf.len() - 1);
            let t = mesh.triangles[k];
            let (mut a, mut b) = (rng.f64(), rng.f64());
            if a + b > 1.0 {
                a = 1.0 - a;
                b = 1.0 - b;
            }
            p(t[0]) + (p(t[1]) - p(t[0])) * a + (p(t[2]) - p(t[0])) * b
        })
        .collect()
}

/// Nearest-neighbour queries on a point set through a hash grid.
pub struct PointGrid {
    cell: f64,
    cells: HashMap<[i64; 3], Vec<DVec3>>,
}

impl PointGrid {
    pub fn new(points: &[DVec3]) -> Self {
        let (lo, hi) = points.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(l, h), p| (l.min(*p), h.max(*p)),
        );
        let extent = (hi - lo).max_element().max(1e-9);
        // About two points per occupied cell on a surface.
        let cell = extent / (points.len() as f64 / 2.0).sqrt().max(1.0);
        let mut cells: HashMap<[i64; 3], Vec<DVec3>> = HashMap::new();
        for p in points {
            cells.entry(Self::key(*p, cell)).or_default().push(*p);
        }
        PointGrid { cell, cells }
    }

    fn key(p: DVec3, cell: f64) -> [i64; 3] {
        [
            (p.x / cell).floor() as i64,
            (p.y / cell).floor() as i64,
            (p.z / cell).floor() as i64,
        ]
    }

    /// Distance to the nearest point: growing shells of cells around the query, and past
    /// [`NEAR_SHELLS`] of them (a query far from the set: a mesh nowhere near the other) every
    /// point, which is exact and costs one pass instead of the cube of the distance in cells.
    pub fn nearest(&self, q: DVec3) -> f64 {
        let k = Self::key(q, self.cell);
        let mut best = f64::INFINITY;
        for r in 0i64..=NEAR_SHELLS {
            // Once a point is found, one more shell settles it: any closer point is within r+1.
            if best < (r as f64 - 1.0).max(0.0) * self.cell {
                return best;
            }
            for dz in -r..=r {
                for dy in -r..=r {
                    for dx in -r..=r {
                        if dx.abs().max(dy.abs()).max(dz.abs()) != r {
                            continue;
                        }
                        if let Some(v) = self.cells.get(&[k[0] + dx, k[1] + dy, k[2] + dz]) {
                            for p in v {
                                best = best.min((*p - q).length());
                            }
                        }
                    }
                }
            }
        }
        if best < NEAR_SHELLS as f64 * self.cell {
            return best;
        }
        self.cells
            .values()
            .flatten()
            .fold(best, |b, p| b.min((*p - q).length()))
    }
}

/// Shells of cells searched around a query before [`PointGrid::nearest`] scans every point.
const NEAR_SHELLS: i64 = 8;

/// Symmetric Chamfer distance: the mean of (mean distance a→b, mean distance b→a), with `n`
/// samples on each mesh.
pub fn chamfer_distance(a: &Mesh, b: &Mesh, n: usize, seed: u64) -> f64 {
    let pa = sample_surface(a, n, seed);
    let pb = sample_surface(b, n, seed ^ 0x5EED);
    if pa.is_empty() || pb.is_empty() {
        return f64::INFINITY;
    }
    let (ga, gb) = (PointGrid::new(&pa), PointGrid::new(&pb));
    0.5 * (mean_distance(&pa, &gb) + mean_distance(&pb, &ga))
}

/// Mean distance from `points` to the nearest point of `to` (infinity for no points).
fn mean_distance(points: &[DVec3], to: &PointGrid) -> f64 {
    if points.is_empty() || to.cells.is_empty() {
        return f64::INFINITY;
    }
    points.par_iter().map(|p| to.nearest(*p)).sum::<f64>() / points.len() as f64
}

/// Visibility is drawn at this many times each camera's resolution, so its depth test is finer
/// than the camera's pixels.
const VISIBILITY_UPSCALE: u32 = 4;

/// A point counts as seen when it lies no more than this many (upscaled) pixels' width behind
/// the mesh's depth at its pixel: half a pixel of the camera's own image, so that a point on the
/// visible surface passes however the z-buffer's pixel centres fall on it, and one a voxel
/// behind it does not.
const SEEN_TOLERANCE_PX: f32 = 2.0;

/// Which of `points` (on `mesh`'s surface) some camera of `cams` sees: in front of it, inside
/// its image and not behind the mesh's own surface there (occlusion by `mesh` only).
pub fn seen_by(points: &[DVec3], mesh: &Mesh, cams: &[RayCamera]) -> Vec<bool> {
    let mut seen = vec![false; points.len()];
    for cam in cams {
        let (w, h) = (
            cam.width * VISIBILITY_UPSCALE,
            cam.height * VISIBILITY_UPSCALE,
        );
        let fine = RayCamera::new(cam.name.clone(), cam.camera.resized(w, h), cam.pose);
        let depth = depth_map(mesh, &fine);
        let centre = fine.center().as_dvec3();
        let forward = fine.pose.camera_to_world_dir(DVec3::Z);
        let focal = fine.focal() as f64;
        seen.par_iter_mut().zip(points).for_each(|(s, p)| {
            if *s {
                return;
            }
            let z = (*p - centre).dot(forward);
            let Some((x, y)) = fine.project(p.as_vec3()) else {
                return;
            };
            if z <= 0.0 || x < 0.0 || y < 0.0 || x >= w as f32 || y >= h as f32 {
                return;
            }
            let d = depth[x as usize + w as usize * y as usize] as f64;
            *s = z <= d + SEEN_TOLERANCE_PX as f64 * z / focal;
        });
    }
    seen
}

/// Chamfer distance over the seen parts of two surfaces ([`chamfer_distance_seen`]).
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct SeenChamfer {
    /// The mean of the two directions.
    pub distance: f64,
    /// Mean distance from `a`'s seen points to `b` (all of its samples).
    pub a_to_b: f64,
    /// Mean distance from `b`'s seen points to `a` (all of its samples).
    pub b_to_a: f64,
    /// Share of `a`'s samples some camera sees.
    pub a_seen: f64,
    /// Share of `b`'s samples some camera sees.
    pub b_seen: f64,
}

/// Chamfer distance counting only the points of each surface that some camera of `cams` sees
/// in that surface's own mesh ([`seen_by`]); each is measured to the nearest of all the other
/// surface's samples, seen or not. What a capture cannot show (the inside of a cup below what
/// any camera sees past the rim, an underside on the floor) is left out of both directions.
pub fn chamfer_distance_seen(
    a: &Mesh,
    b: &Mesh,
    cams: &[RayCamera],
    n: usize,
    seed: u64,
) -> SeenChamfer {
    let pa = sample_surface(a, n, seed);
    let pb = sample_surface(b, n, seed ^ 0x5EED);
    let (sa, sb) = (seen_by(&pa, a, cams), seen_by(&pb, b, cams));
    let (ga, gb) = (PointGrid::new(&pa), PointGrid::new(&pb));
    let mean_to = |pts: &[DVec3], seen: &[bool], grid: &PointGrid| {
        let kept: Vec<DVec3> = pts
            .iter()
            .zip(seen)
            .filter(|s| *s.1)
            .map(|s| *s.0)
            .collect();
        mean_distance(&kept, grid)
    };
    let share = |s: &[bool]| s.iter().filter(|x| **x).count() as f64 / s.len().max(1) as f64;
    let (ab, ba) = (mean_to(&pa, &sa, &gb), mean_to(&pb, &sb, &ga));
    SeenChamfer {
        distance: 0.5 * (ab + ba),
        a_to_b: ab,
        b_to_a: ba,
        a_seen: share(&sa),
        b_seen: share(&sb),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_matches_brute_force() {
        let mut rng = Rng::new(3);
        let pts: Vec<DVec3> = (0..500)
            .map(|_| DVec3::new(rng.f64(), rng.f64(), rng.f64() * 0.1))
            .collect();
        let g = PointGrid::new(&pts);
        for _ in 0..100 {
            let q = DVec3::new(
                rng.range(-0.5, 1.5),
                rng.range(-0.5, 1.5),
                rng.range(-0.5, 0.5),
            );
            let brute = pts
                .iter()
                .map(|p| (*p - q).length())
                .fold(f64::INFINITY, f64::min);
            assert!((g.nearest(q) - brute).abs() < 1e-12);
        }
        // Far from every point (a thousand cells away; shell by shell that search never ended).
        let q = DVec3::new(40.0, -30.0, 50.0);
        let brute = pts
            .iter()
            .map(|p| (*p - q).length())
            .fold(f64::INFINITY, f64::min);
        assert_eq!(g.nearest(q), brute);
    }

    /// A box open at the top seen from above at an angle: its floor's far part and the inner
    /// wall below the sightlines past the rim are unseen, its outer walls facing the camera seen.
    #[test]
    fn an_open_box_seen_from_one_side_hides_its_inside() {
        let mesh = open_box();
        let cam = crate::scene::Camera::pinhole(160, 120, 120.0, 120.0, 80.0, 60.0);
        let pose = crate::scene::Pose::look_at(
            DVec3::new(4.0, 0.0, 3.0),
            DVec3::new(0.0, 0.0, 0.5),
            DVec3::Z,
        );
        let cams = [RayCamera::new("v".into(), cam, pose)];
        let pts = [
            DVec3::new(1.0, 0.0, 0.5),   // outer wall facing the camera
            DVec3::new(0.5, 0.0, 0.0),   // the floor just inside the near wall: hidden by it
            DVec3::new(0.9, 0.0, 0.05),  // low on the near wall's inner face: hidden
            DVec3::new(-0.8, 0.0, 0.0),  // the floor's far part: seen past the rim
            DVec3::new(-0.99, 0.0, 0.1), // low on the far wall, just off it: seen
        ];
        assert_eq!(
            seen_by(&pts, &mesh, &cams),
            vec![true, false, false, true, true]
        );
        let c = chamfer_distance_seen(&mesh, &mesh, &cams, 4000, 1);
        assert!(c.a_seen > 0.2 && c.a_seen < 0.8, "{c:?}");
        assert!(c.distance < 0.05, "{c:?}");
    }

    /// Four walls of a 2 x 2 x 1 box (x, y in -1..1, z in 0..1) and its floor, no lid.
    fn open_box() -> Mesh {
        let mut positions = vec![];
        let mut triangles = vec![];
        let mut quad = |q: [[f32; 3]; 4]| {
            let base = positions.len() as u32;
            positions.extend(q);
            triangles.push([base, base + 1, base + 2]);
            triangles.push([base, base + 2, base + 3]);
        };
        let c = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];
        for k in 0..4 {
            let (a, b) = (c[k], c[(k + 1) % 4]);
            quad([
                [a[0], a[1], 0.0],
                [b[0], b[1], 0.0],
                [b[0], b[1], 1.0],
                [a[0], a[1], 1.0],
            ]);
        }
        quad(c.map(|p| [p[0], p[1], 0.0]));
        Mesh {
            positions,
            triangles,
            ..Default::default()
        }
    }
}
