//! Truth meshes: each object's analytic surface tessellated finely, every vertex exactly on the
//! surface, in world coordinates. Vertices are welded by position, so the sphere, box, torus and
//! the mug's cup are watertight; the mug's handle is an open tube whose ends sink into the wall.

use super::geometry::{Object, Shape};
use glam::DVec3;
use std::collections::HashMap;
use std::f64::consts::{PI, TAU};

/// The exact tessellation, in f64 (written out as a [`crate::mesh::Mesh`]).
#[derive(Clone, Debug, Default)]
pub struct Tessellation {
    pub vertices: Vec<DVec3>,
    pub faces: Vec<[u32; 3]>,
}

impl Tessellation {
    /// As the project's mesh type (f32 positions, normals from the faces).
    pub fn to_mesh(&self, name: &str) -> crate::mesh::Mesh {
        let mut m = crate::mesh::Mesh {
            name: name.to_string(),
            positions: self
                .vertices
                .iter()
                .map(|v| v.as_vec3().to_array())
                .collect(),
            triangles: self.faces.clone(),
            ..Default::default()
        };
        m.compute_normals();
        m
    }
}

/// Builds a mesh, merging vertices that coincide (to 1e-9 m).
#[derive(Default)]
struct Builder {
    mesh: Tessellation,
    index: HashMap<[i64; 3], u32>,
}

impl Builder {
    fn vertex(&mut self, p: DVec3) -> u32 {
        let key = (p * 1e9).round().to_array().map(|v| v as i64);
        *self.index.entry(key).or_insert_with(|| {
            self.mesh.vertices.push(p);
            (self.mesh.vertices.len() - 1) as u32
        })
    }

    /// Two triangles for the quad a-b-c-d; degenerate ones (at poles) are dropped.
    fn quad(&mut self, a: DVec3, b: DVec3, c: DVec3, d: DVec3) {
        let [a, b, c, d] = [a, b, c, d].map(|p| self.vertex(p));
        for f in [[a, b, c], [a, c, d]] {
            if f[0] != f[1] && f[1] != f[2] && f[0] != f[2] {
                self.mesh.faces.push(f);
            }
        }
    }

    /// A parametric patch: `f(u, v)` over an `nu` x `nv` grid of [0, 1]^2.
    fn patch(&mut self, nu: usize, nv: usize, f: impl Fn(f64, f64) -> DVec3) {
        for i in 0..nu {
            for j in 0..nv {
                let (u0, u1) = (i as f64 / nu as f64, (i + 1) as f64 / nu as f64);
                let (v0, v1) = (j as f64 / nv as f64, (j + 1) as f64 / nv as f64);
                self.quad(f(u0, v0), f(u1, v0), f(u1, v1), f(u0, v1));
            }
        }
    }
}

/// Angle steps computed from the integer index so that the seam (0 and 2 pi) welds exactly.
fn ring(k: f64, n: usize) -> (f64, f64) {
    let i = (k * n as f64).round() as usize % n;
    (TAU * i as f64 / n as f64).sin_cos()
}

/// The object's surface as a fine triangle mesh in world coordinates, faces wound outwards.
pub fn tessellate(obj: &Object) -> Tessellation {
    let mut b = Builder::default();
    const N: usize = 128;
    match obj.shape {
        Shape::Sphere { radius } => {
            let c = DVec3::new(0.0, 0.0, radius);
            b.patch(N, N / 2, |u, v| {
                let (s, co) = ring(u, N);
                let lat = PI * (v - 0.5);
                // Poles computed exactly so they weld.
                let (sl, cl) = if v == 0.0 {
                    (-1.0, 0.0)
                } else if v == 1.0 {
                    (1.0, 0.0)
                } else {
                    lat.sin_cos()
                };
                c + radius * DVec3::new(cl * co, cl * s, sl)
            });
        }
        Shape::Cuboid { half } => {
            let lo = DVec3::new(-half.x, -half.y, 0.0);
            let hi = DVec3::new(half.x, half.y, 2.0 * half.z);
            let n = 24;
            for axis in 0..3 {
                for side in [lo[axis], hi[axis]] {
                    let (a1, a2) = ((axis + 1) % 3, (axis + 2) % 3);
                    b.patch(n, n, |u, v| {
                        let mut p = DVec3::ZERO;
                        p[axis] = side;
                        p[a1] = lo[a1] + (hi[a1] - lo[a1]) * u;
                        p[a2] = lo[a2] + (hi[a2] - lo[a2]) * v;
                        p
                    });
                }
            }
        }
        Shape::Torus { major, minor } => {
            b.patch(N, N / 2, |u, v| {
                let (s, c) = ring(u, N);
                let (sv, cv) = ring(v, N / 2);
                let r = major + minor * cv;
                DVec3::new(r * c, r * s, minor + minor * sv)
            });
        }
        Shape::Mug {
            radius,
            height,
            wall,
            base,
            handle_major,
            handle_minor,
            handle_z,
        } => {
            // The cup as a lathe: bottom centre, outer wall, rim, inner wall, inner floor centre.
            let ri = radius - wall;
            let profile = [
                (0.0, 0.0, 8),
                (radius, 0.0, 48),
                (radius, height, 4),
                (ri, height, 44),
                (ri, base, 8),
                (0.0, base, 0),
            ];
            for seg in profile.windows(2) {
                let ((r0, z0, n), (r1, z1, _)) = (seg[0], seg[1]);
                b.patch(N, n, |u, v| {
                    let (s, c) = ring(u, N);
                    let r = r0 + (r1 - r0) * v;
                    let z = z0 + (z1 - z0) * v;
                    DVec3::new(r * c, r * s, z)
                });
            }
            // The handle: the outer half of a torus tube in the x-z plane, swept on until its
            // centre line is half-way into the wall, so its ends sink into the wall (no gap) but
            // stay out of the cavity.
            let sweep = 2.0 * (-0.5 * wall / handle_major).acos();
            b.patch(64, 32, |u, v| {
                let a = -0.5 * sweep + sweep * u;
                let (sv, cv) = ring(v, 32);
                let r = handle_major + handle_minor * cv;
                DVec3::new(
                    radius + r * a.cos(),
                    handle_minor * sv,
                    handle_z + r * a.sin(),
                )
            });
        }
    }
    let mut mesh = b.mesh;
    // Wind every face outwards by the SDF gradient: one rule for every shape.
    for f in mesh.faces.iter_mut() {
        let [a, bb, c] = f.map(|i| mesh.vertices[i as usize]);
        let n = (bb - a).cross(c - a);
        let centre = (a + bb + c) / 3.0;
        let h = 1e-6;
        let g = DVec3::new(
            obj.sdf_local(centre + DVec3::X * h) - obj.sdf_local(centre - DVec3::X * h),
            obj.sdf_local(centre + DVec3::Y * h) - obj.sdf_local(centre - DVec3::Y * h),
            obj.sdf_local(centre + DVec3::Z * h) - obj.sdf_local(centre - DVec3::Z * h),
        );
        if n.dot(g) < 0.0 {
            f.swap(1, 2);
        }
    }
    for v in mesh.vertices.iter_mut() {
        *v = obj.place.to_world(*v);
    }
    mesh
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::demo::geometry::World;
    use std::collections::HashMap;

    /// Every edge shared by exactly two faces, in opposite directions: closed and consistently
    /// wound.
    fn is_watertight(m: &Tessellation) -> bool {
        let mut edges: HashMap<(u32, u32), i32> = HashMap::new();
        for f in &m.faces {
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                *edges.entry((a.min(b), a.max(b))).or_default() += if a < b { 1 } else { -1 };
            }
        }
        let mut count: HashMap<(u32, u32), usize> = HashMap::new();
        for f in &m.faces {
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                *count.entry((a.min(b), a.max(b))).or_default() += 1;
            }
        }
        count.values().all(|&c| c == 2) && edges.values().all(|&s| s == 0)
    }

    #[test]
    fn meshes_lie_on_the_surfaces_and_close() {
        let w = World::demo();
        for obj in &w.objects {
            let m = tessellate(obj);
            assert!(m.faces.len() > 1000, "{}", obj.name);
            for v in &m.vertices {
                // On the surface; the mug's handle ends and the wall under them lie inside it.
                let sdf = obj.sdf_local(obj.place.to_local(*v));
                let ok = sdf.abs() < 1e-6 || (obj.name == "mug" && sdf < 0.0);
                assert!(ok, "{}: {sdf}", obj.name);
            }
            if obj.name != "mug" {
                assert!(is_watertight(&m), "{} is not watertight", obj.name);
            }
        }
    }
}
