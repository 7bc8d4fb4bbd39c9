//! Chamfer distance between two triangle meshes: points sampled on each surface (area-weighted,
//! seeded), nearest neighbours found through a uniform grid, distances averaged both ways.

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
    let ab: f64 = pa.par_iter().map(|p| gb.nearest(*p)).sum::<f64>() / pa.len() as f64;
    let ba: f64 = pb.par_iter().map(|p| ga.nearest(*p)).sum::<f64>() / pb.len() as f64;
    0.5 * (ab + ba)
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
}
