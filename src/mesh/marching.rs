//! Marching cubes on a dense scalar grid, in parallel over z-slabs, with one vertex per crossed
//! grid edge (shared by the cells around it, so the mesh comes out welded).
//!
//! Grid values are x-fastest: `v[x + nx * (y + ny * z)]`. Cube corners (Bourke's numbering):
//! 0 (0,0,0) 1 (1,0,0) 2 (1,1,0) 3 (0,1,0) 4 (0,0,1) 5 (1,0,1) 6 (1,1,1) 7 (0,1,1); a corner is
//! "inside" when its value is above `iso` (density), and triangles wind counter-clockwise seen
//! from outside, so normals point out of the object.

use super::tables::TRI_TABLE;
use rayon::prelude::*;
use std::collections::HashMap;

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
const CORNERS: [(usize, usize, usize); 8] = [
    (0, 0, 0),
    (1, 0, 0),
    (1, 1, 0),
    (0, 1, 0),
    (0, 0, 1),
    (1, 0, 1),
    (1, 1, 1),
    (0, 1, 1),
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
    let parts: Vec<(usize, GridMesh)> = (0..slabs.div_ceil(per))
        .into_par_iter()
        .map(|c| {
            let z0 = c * per;
            let z1 = ((c + 1) * per).min(slabs);
            (z0, march_chunk(values, dims, iso, z0, z1))
        })
        .collect();
    stitch(parts)
}

/// The grid a chunk reads, and how a crossing edge becomes a vertex.
struct Grid<'a> {
    v: &'a [f32],
    nx: usize,
    ny: usize,
    iso: f32,
}

impl Grid<'_> {
    fn at(&self, x: usize, y: usize, z: usize) -> f32 {
        self.v[x + self.nx * (y + self.ny * z)]
    }

    /// The vertex where the surface crosses the edge a-b, linearly interpolated.
    fn vertex(&self, mesh: &mut GridMesh, a: [usize; 3], b: [usize; 3]) -> u32 {
        let (va, vb) = (self.at(a[0], a[1], a[2]), self.at(b[0], b[1], b[2]));
        let t = ((self.iso - va) / (vb - va)).clamp(0.0, 1.0);
        let p = [0, 1, 2].map(|k| a[k] as f32 + t * (b[k] as f32 - a[k] as f32));
        mesh.positions.push(p);
        (mesh.positions.len() - 1) as u32
    }

    /// Vertex ids of the crossed x- and y-edges of plane z (NONE where not crossed).
    fn plane_edges(&self, mesh: &mut GridMesh, z: usize) -> (Vec<u32>, Vec<u32>) {
        let (nx, ny, iso) = (self.nx, self.ny, self.iso);
        let mut xe = vec![NONE; nx * ny];
        let mut ye = vec![NONE; nx * ny];
        for y in 0..ny {
            for x in 0..nx {
                let inside = self.at(x, y, z) > iso;
                if x + 1 < nx && (self.at(x + 1, y, z) > iso) != inside {
                    xe[x + nx * y] = self.vertex(mesh, [x, y, z], [x + 1, y, z]);
                }
                if y + 1 < ny && (self.at(x, y + 1, z) > iso) != inside {
                    ye[x + nx * y] = self.vertex(mesh, [x, y, z], [x, y + 1, z]);
                }
            }
        }
        (xe, ye)
    }
}

/// Cells with z in [z0, z1): a rolling pair of planes of x/y-edge vertex ids, and z-edge ids.
fn march_chunk(v: &[f32], [nx, ny, _]: [usize; 3], iso: f32, z0: usize, z1: usize) -> GridMesh {
    let g = Grid { v, nx, ny, iso };
    let at = |x: usize, y: usize, z: usize| g.at(x, y, z);
    let mut mesh = GridMesh::default();
    let (mut xe0, mut ye0) = g.plane_edges(&mut mesh, z0);
    for z in z0..z1 {
        let (xe1, ye1) = g.plane_edges(&mut mesh, z + 1);
        let mut ze = vec![NONE; nx * ny];
        for y in 0..ny {
            for x in 0..nx {
                if (at(x, y, z) > iso) != (at(x, y, z + 1) > iso) {
                    ze[x + nx * y] = g.vertex(&mut mesh, [x, y, z], [x, y, z + 1]);
                }
            }
        }
        for y in 0..ny - 1 {
            for x in 0..nx - 1 {
                let mut case = 0usize;
                for (i, &(dx, dy, dz)) in CORNERS.iter().enumerate() {
                    // Bourke's table sets a bit for corners below the iso-level.
                    if at(x + dx, y + dy, z + dz) <= iso {
                        case |= 1 << i;
                    }
                }
                if case == 0 || case == 255 {
                    continue;
                }
                let edge_id = |e: i8| -> u32 {
                    let (axis, dx, dy, dz) = EDGES[e as usize];
                    let i = (x + dx) + nx * (y + dy);
                    match (axis, dz) {
                        (0, 0) => xe0[i],
                        (0, _) => xe1[i],
                        (1, 0) => ye0[i],
                        (1, _) => ye1[i],
                        _ => ze[i],
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
        xe0 = xe1;
        ye0 = ye1;
    }
    // Vertices made for edges no triangle used are dropped in `stitch`.
    mesh
}

/// Join the chunks: the vertices on a shared plane were computed from the same two samples in
/// both chunks, so they are bit-identical and merge by exact position. Unused vertices go too.
fn stitch(parts: Vec<(usize, GridMesh)>) -> GridMesh {
    let mut out = GridMesh::default();
    let mut seen: HashMap<[u32; 3], u32> = HashMap::new();
    for (_, part) in parts {
        let mut used = vec![false; part.positions.len()];
        for t in &part.triangles {
            for &i in t {
                used[i as usize] = true;
            }
        }
        let mut remap = vec![NONE; part.positions.len()];
        for (i, p) in part.positions.iter().enumerate() {
            if !used[i] {
                continue;
            }
            let key = p.map(f32::to_bits);
            remap[i] = *seen.entry(key).or_insert_with(|| {
                out.positions.push(*p);
                (out.positions.len() - 1) as u32
            });
        }
        out.triangles
            .extend(part.triangles.iter().map(|t| t.map(|i| remap[i as usize])));
    }
    out.triangles
        .retain(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2]);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

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
