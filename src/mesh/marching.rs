//! Marching cubes on a dense scalar grid, in parallel over z-slabs, with one vertex per crossed
//! grid edge (shared by the cells around it, so the mesh comes out welded).
//!
//! Grid values are x-fastest: `v[x + nx * (y + ny * z)]`. Cube corners (Bourke's numbering):
//! 0 (0,0,0) 1 (1,0,0) 2 (1,1,0) 3 (0,1,0) 4 (0,0,1) 5 (1,0,1) 6 (1,1,1) 7 (0,1,1); a corner is
//! "inside" when its value is above `iso` (density), and triangles wind counter-clockwise seen
//! from outside, so normals point out of the object.

use super::tables::TRI_TABLE;
use rayon::prelude::*;

/// Which grid edge each of the 12 cube edges is: (axis 0=x 1=y 2=z, corner offset dx, dy, dz).
const EDGES: [(u8, usize, usize, usize); 12] = [
    (0, 0, 0, 0),
    (1, 1, 0, 0),
    (0, 0, 1, 0),
    (1, 0, 0, 0),
    (0, 0, 0, 1),
    (1, 1, 0, 1),
    (0, 0, 1, 1),
    (1, 0, 0, 1),
    (2, 0, 0, 0),
    (2, 1, 0, 0),
    (2, 1, 1, 0),
    (2, 0, 1, 0),
];
const NONE: u32 = u32::MAX;

/// A triangle mesh in grid coordinates (vertex at grid index space: sample (x, y, z) is at (x, y, z)).
#[derive(Clone, Debug, Default)]
pub struct GridMesh {
    pub positions: Vec<[f32; 3]>,
    pub triangles: Vec<[u32; 3]>,
}

/// The iso-surface `value = iso` of the grid.
pub fn marching_cubes(values: &[f32], dims: [usize; 3], iso: f32) -> GridMesh {
    let [nx, ny, nz] = dims;
    assert_eq!(values.len(), nx * ny * nz, "grid size does not match dims");
    if nx < 2 || ny < 2 || nz < 2 {
        return GridMesh::default();
    }
    let slabs = nz - 1;
    let chunks = (rayon::current_num_threads() * 4).clamp(1, slabs);
    let per = slabs.div_ceil(chunks);
    let parts: Vec<Chunk> = (0..slabs.div_ceil(per))
        .into_par_iter()
        .map(|c| {
            let z0 = c * per;
            let z1 = ((c + 1) * per).min(slabs);
            march_chunk(values, dims, iso, z0, z1)
        })
        .collect();
    stitch(parts)
}

/// One chunk's mesh, and which of its vertices lie on its first and last planes (shared with the
/// chunks before and after it).
struct Chunk {
    mesh: GridMesh,
    first_plane: std::ops::Range<u32>,
    last_plane: std::ops::Range<u32>,
}

/// The grid a chunk reads, and how a crossing edge becomes a vertex.
struct Grid<'a> {
    v: &'a [f32],
    nx: usize,
    ny: usize,
    iso: f32,
}

/// A row of samples: all outside, all inside, or both.
#[derive(Clone, Copy, PartialEq)]
enum Row {
    Out,
    In,
    Mixed,
}

/// One plane of samples: inside bits (below the iso-level, Bourke's convention: bit set = 1),
/// the vertex ids of its crossed x- and y-edges (NONE where not crossed), and per-row states.
struct Plane {
    below: Vec<u8>,
    xe: Vec<u32>,
    ye: Vec<u32>,
    rows: Vec<Row>,
}

impl Grid<'_> {
    #[inline]
    fn at(&self, x: usize, y: usize, z: usize) -> f32 {
        self.v[x + self.nx * (y + self.ny * z)]
    }

    /// The vertex where the surface crosses the edge a-b, linearly interpolated.
    #[inline]
    fn vertex(&self, mesh: &mut GridMesh, a: [usize; 3], b: [usize; 3]) -> u32 {
        let (va, vb) = (self.at(a[0], a[1], a[2]), self.at(b[0], b[1], b[2]));
        let t = ((self.iso - va) / (vb - va)).clamp(0.0, 1.0);
        let p = [0, 1, 2].map(|k| a[k] as f32 + t * (b[k] as f32 - a[k] as f32));
        mesh.positions.push(p);
        (mesh.positions.len() - 1) as u32
    }

    fn plane(&self, mesh: &mut GridMesh, z: usize) -> Plane {
        let (nx, ny, iso) = (self.nx, self.ny, self.iso);
        let base = nx * ny * z;
        let below: Vec<u8> = self.v[base..base + nx * ny]
            .iter()
            .map(|&v| (v <= iso) as u8)
            .collect();
        let mut xe = vec![NONE; nx * ny];
        let mut ye = vec![NONE; nx * ny];
        let mut rows = vec![Row::Mixed; ny];
        for y in 0..ny {
            let r = &below[nx * y..nx * (y + 1)];
            let all = r.iter().all(|&b| b == r[0]);
            rows[y] = match (all, r[0]) {
                (true, 1) => Row::Out,
                (true, _) => Row::In,
                _ => Row::Mixed,
            };
            if rows[y] == Row::Mixed {
                for x in 0..nx - 1 {
                    if r[x] != r[x + 1] {
                        xe[x + nx * y] = self.vertex(mesh, [x, y, z], [x + 1, y, z]);
                    }
                }
            }
            if y + 1 < ny {
                let r1 = &below[nx * (y + 1)..nx * (y + 2)];
                for x in 0..nx {
                    if r[x] != r1[x] {
                        ye[x + nx * y] = self.vertex(mesh, [x, y, z], [x, y + 1, z]);
                    }
                }
            }
        }
        Plane {
            below,
            xe,
            ye,
            rows,
        }
    }
}

/// Cells with z in [z0, z1): a rolling pair of planes, and the z-edges between them. Rows of
/// cells whose four sample rows are all inside or all outside are skipped whole.
fn march_chunk(v: &[f32], [nx, ny, _]: [usize; 3], iso: f32, z0: usize, z1: usize) -> Chunk {
    let g = Grid { v, nx, ny, iso };
    let mut mesh = GridMesh::default();
    let mut p0 = g.plane(&mut mesh, z0);
    let first_plane = 0..mesh.positions.len() as u32;
    let mut last_plane = first_plane.clone();
    let mut ze = vec![NONE; nx * ny];
    for z in z0..z1 {
        let start = mesh.positions.len() as u32;
        let p1 = g.plane(&mut mesh, z + 1);
        last_plane = start..mesh.positions.len() as u32;
        for y in 0..ny {
            // A row without z-crossings keeps stale ids: no cell's triangles name an edge that
            // does not cross, so they are never read.
            if p0.rows[y] != Row::Mixed && p0.rows[y] == p1.rows[y] {
                continue;
            }
            for x in 0..nx {
                let i = x + nx * y;
                ze[i] = if p0.below[i] != p1.below[i] {
                    g.vertex(&mut mesh, [x, y, z], [x, y, z + 1])
                } else {
                    NONE
                };
            }
        }
        for y in 0..ny - 1 {
            let rs = [p0.rows[y], p0.rows[y + 1], p1.rows[y], p1.rows[y + 1]];
            if rs[0] != Row::Mixed && rs.iter().all(|&r| r == rs[0]) {
                continue;
            }
            let (b0, b1) = (&p0.below, &p1.below);
            for x in 0..nx - 1 {
                let i = x + nx * y;
                let case = (b0[i]
                    | b0[i + 1] << 1
                    | b0[i + 1 + nx] << 2
                    | b0[i + nx] << 3
                    | b1[i] << 4
                    | b1[i + 1] << 5
                    | b1[i + 1 + nx] << 6
                    | b1[i + nx] << 7) as usize;
                if case == 0 || case == 255 {
                    continue;
                }
                let edge_id = |e: i8| -> u32 {
                    let (axis, dx, dy, dz) = EDGES[e as usize];
                    let j = i + dx + nx * dy;
                    match (axis, dz) {
                        (0, 0) => p0.xe[j],
                        (0, _) => p1.xe[j],
                        (1, 0) => p0.ye[j],
                        (1, _) => p1.ye[j],
                        _ => ze[j],
                    }
                };
                for tri in TRI_TABLE[case].chunks(3) {
                    if tri[0] < 0 {
                        break;
                    }
                    // With bits set below the iso-level, Bourke's winding is counter-clockwise
                    // seen from the low side: outward for a density.
                    mesh.triangles
                        .push([edge_id(tri[0]), edge_id(tri[1]), edge_id(tri[2])]);
                }
            }
        }
        p0 = p1;
    }
    Chunk {
        mesh,
        first_plane,
        last_plane,
    }
}

/// Join the chunks: a chunk's first plane is the one before it's last plane, computed from the
/// same samples in the same order, so its vertices map one to one onto those.
fn stitch(parts: Vec<Chunk>) -> GridMesh {
    let mut out = GridMesh::default();
    let mut prev_last: Option<std::ops::Range<u32>> = None;
    for part in parts {
        let offset = out.positions.len() as u32;
        let shared = prev_last
            .as_ref()
            .map(|r| (r.start, part.first_plane.len() as u32));
        let n_first = part.first_plane.len() as u32;
        let remap = |i: u32| -> u32 {
            match shared {
                // first_plane starts at 0 in every chunk
                Some((prev_start, _)) if i < n_first => prev_start + i,
                Some(_) => offset + i - n_first,
                None => offset + i,
            }
        };
        let skip = if shared.is_some() {
            n_first as usize
        } else {
            0
        };
        out.positions
            .extend_from_slice(&part.mesh.positions[skip..]);
        out.triangles
            .extend(part.mesh.triangles.iter().map(|t| t.map(remap)));
        prev_last = Some(
            remap(part.last_plane.start)
                ..remap(part.last_plane.start) + part.last_plane.len() as u32,
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    fn sphere_grid(n: usize, r: f32) -> Vec<f32> {
        let c = (n - 1) as f32 / 2.0;
        let mut v = vec![0f32; n * n * n];
        for z in 0..n {
            for y in 0..n {
                for x in 0..n {
                    let d =
                        ((x as f32 - c).powi(2) + (y as f32 - c).powi(2) + (z as f32 - c).powi(2))
                            .sqrt();
                    v[x + n * (y + n * z)] = r - d; // > 0 inside
                }
            }
        }
        v
    }

    fn signed_volume(m: &GridMesh) -> f64 {
        m.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| m.positions[i as usize].map(|x| x as f64));
                (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                    + a[2] * (b[0] * c[1] - b[1] * c[0]))
                    / 6.0
            })
            .sum()
    }

    #[test]
    fn sphere_is_closed_outward_and_the_right_size() {
        let (n, r) = (48, 18.0f32);
        let m = marching_cubes(&sphere_grid(n, r), [n, n, n], 0.0);
        let c = (n - 1) as f32 / 2.0;
        for p in &m.positions {
            let d = ((p[0] - c).powi(2) + (p[1] - c).powi(2) + (p[2] - c).powi(2)).sqrt();
            assert!((d - r).abs() < 0.05, "vertex at radius {d}");
        }
        // Watertight: every edge is shared by exactly two triangles.
        let mut edges: HashMap<(u32, u32), i32> = HashMap::new();
        for t in &m.triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                *edges.entry((a.min(b), a.max(b))).or_default() += 1;
            }
        }
        assert!(
            edges.values().all(|&c| c == 2),
            "open or non-manifold edges"
        );
        // Outward winding gives a positive volume close to the sphere's.
        let vol = signed_volume(&m);
        let want = 4.0 / 3.0 * std::f64::consts::PI * (r as f64).powi(3);
        assert!((vol - want).abs() / want < 0.01, "volume {vol} vs {want}");
        // Euler characteristic of a sphere.
        let chi = m.positions.len() as i64 - edges.len() as i64 + m.triangles.len() as i64;
        assert_eq!(chi, 2);
    }

    #[test]
    fn empty_and_full_grids_give_no_triangles() {
        assert!(marching_cubes(&[0.0; 27], [3, 3, 3], 0.5)
            .triangles
            .is_empty());
        assert!(marching_cubes(&[1.0; 27], [3, 3, 3], 0.5)
            .triangles
            .is_empty());
    }
}
