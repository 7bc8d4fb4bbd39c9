//! Meshes out of object fields: marching cubes, cleanup (welded by construction, small pieces
//! removed, normals), and writers for glTF binary, PLY and OBJ.

pub mod atlas;
pub mod bake;
pub mod chamfer;
pub mod colour;
pub mod decimate;
pub mod fill;
pub mod frame;
pub mod from_field;
pub mod gltf;
pub mod io;
pub mod marching;
pub mod mesh_checks;
pub mod raster;
mod tables;
pub mod textured;
pub mod visibility;

use glam::{DMat4, DVec3};

/// A triangle mesh in world units with per-vertex normals, optional per-vertex colours and an
/// optional base-colour texture.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    pub name: String,
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    /// RGB in 0..1, one per vertex: the field's colour, which is the photos' (sRGB-encoded)
    /// values (the glTF writer decodes them to the linear COLOR_0 glTF asks for).
    pub colors: Option<Vec<[f32; 3]>>,
    /// Texture coordinates, one per vertex, glTF's convention ((0, 0): the image's top-left).
    pub uvs: Option<Vec<[f32; 2]>>,
    /// The base colour the `uvs` index, 8-bit sRGB.
    pub texture: Option<std::sync::Arc<image::RgbImage>>,
    /// How a viewer shades the colour.
    pub shading: Shading,
    pub triangles: Vec<[u32; 3]>,
}

/// The material a mesh is written with.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Shading {
    /// `KHR_materials_unlit`: the colour shown as captured. A radiance field's colour already
    /// holds the capture's lighting; lighting it again darkens and shades it twice.
    #[default]
    Unlit,
    /// glTF's metallic-roughness material (non-metal, rough), lit by the viewer's lights.
    Pbr,
}

/// The change of frame from a Z-up capture world (nerfstudio, Blender, NeRF-synthetic, the demo
/// scene) to glTF's +Y-up right-handed frame: (x, y, z) -> (x, z, -y).
pub fn z_up_to_gltf() -> DMat4 {
    DMat4::from_cols_array(&[
        1.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0,
    ])
}

impl Mesh {
    /// A marching-cubes mesh in grid coordinates mapped to the world: sample (i, j, k) of the
    /// grid lies at `origin + (i, j, k) * voxel`.
    pub fn from_grid(name: &str, grid: marching::GridMesh, origin: DVec3, voxel: DVec3) -> Mesh {
        let positions = grid
            .positions
            .iter()
            .map(|p| {
                let w = origin + DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64) * voxel;
                [w.x as f32, w.y as f32, w.z as f32]
            })
            .collect();
        let mut m = Mesh {
            name: name.to_string(),
            positions,
            triangles: grid.triangles,
            ..Default::default()
        };
        m.compute_normals();
        m
    }

    /// Area-weighted vertex normals from the faces.
    pub fn compute_normals(&mut self) {
        let mut n = vec![DVec3::ZERO; self.positions.len()];
        for t in &self.triangles {
            let [a, b, c] =
                t.map(|i| DVec3::from_array(self.positions[i as usize].map(|x| x as f64)));
            let fnrm = (b - a).cross(c - a);
            for &i in t {
                n[i as usize] += fnrm;
            }
        }
        self.normals = n
            .iter()
            .map(|v| {
                let u = v.normalize_or(DVec3::Z);
                [u.x as f32, u.y as f32, u.z as f32]
            })
            .collect();
    }

    /// Apply an affine transform to positions (and its inverse-transpose to normals).
    pub fn transform(&mut self, m: DMat4) {
        let nm = glam::DMat3::from_mat4(m).inverse().transpose();
        for p in &mut self.positions {
            let w = m.transform_point3(DVec3::from_array(p.map(|x| x as f64)));
            *p = [w.x as f32, w.y as f32, w.z as f32];
        }
        for n in &mut self.normals {
            let w = (nm * DVec3::from_array(n.map(|x| x as f64))).normalize_or(DVec3::Z);
            *n = [w.x as f32, w.y as f32, w.z as f32];
        }
    }

    /// The connected piece of every triangle, as the id of a representative vertex (pieces are
    /// joined through shared vertices).
    pub fn triangle_components(&self) -> Vec<u32> {
        let n = self.positions.len();
        let mut parent: Vec<u32> = (0..n as u32).collect();
        fn find(p: &mut [u32], mut x: u32) -> u32 {
            while p[x as usize] != x {
                p[x as usize] = p[p[x as usize] as usize];
                x = p[x as usize];
            }
            x
        }
        for t in &self.triangles {
            let r0 = find(&mut parent, t[0]);
            for &v in &t[1..] {
                let r = find(&mut parent, v);
                if r != r0 {
                    parent[r as usize] = r0;
                }
            }
        }
        self.triangles
            .iter()
            .map(|t| find(&mut parent, t[0]))
            .collect()
    }

    /// Triangles per connected piece, largest first.
    pub fn component_sizes(&self) -> Vec<usize> {
        let mut count = std::collections::HashMap::<u32, usize>::new();
        for r in self.triangle_components() {
            *count.entry(r).or_default() += 1;
        }
        let mut sizes: Vec<usize> = count.into_values().collect();
        sizes.sort_unstable_by(|a, b| b.cmp(a));
        sizes
    }

    /// Remove connected pieces with fewer than `min_fraction` of the largest piece's triangles.
    /// Returns the number of pieces removed.
    pub fn remove_small_components(&mut self, min_fraction: f64) -> usize {
        let roots = self.triangle_components();
        let mut count = std::collections::HashMap::<u32, usize>::new();
        for r in &roots {
            *count.entry(*r).or_default() += 1;
        }
        let largest = count.values().copied().max().unwrap_or(0);
        let keep_root = |r: &u32| count[r] as f64 >= min_fraction * largest as f64;
        let removed = count.keys().filter(|r| !keep_root(r)).count();
        if removed == 0 {
            return 0;
        }
        let tris: Vec<[u32; 3]> = self
            .triangles
            .iter()
            .zip(&roots)
            .filter(|(_, r)| keep_root(r))
            .map(|(t, _)| *t)
            .collect();
        self.triangles = tris;
        self.drop_unused_vertices();
        removed
    }

    /// Remove vertices no triangle uses (renumbering the triangles).
    pub(crate) fn drop_unused_vertices(&mut self) {
        let mut remap = vec![u32::MAX; self.positions.len()];
        let mut next = 0u32;
        for t in &self.triangles {
            for &i in t {
                if remap[i as usize] == u32::MAX {
                    remap[i as usize] = next;
                    next += 1;
                }
            }
        }
        let mut pos = vec![[0f32; 3]; next as usize];
        let mut nrm = vec![
            [0f32; 3];
            if self.normals.is_empty() {
                0
            } else {
                next as usize
            }
        ];
        let mut col = self.colors.as_ref().map(|_| vec![[0f32; 3]; next as usize]);
        let mut uvs = self.uvs.as_ref().map(|_| vec![[0f32; 2]; next as usize]);
        for (old, &new) in remap.iter().enumerate() {
            if new != u32::MAX {
                if let (Some(u), Some(src)) = (uvs.as_mut(), self.uvs.as_ref()) {
                    u[new as usize] = src[old];
                }
                pos[new as usize] = self.positions[old];
                if !nrm.is_empty() {
                    nrm[new as usize] = self.normals[old];
                }
                if let (Some(c), Some(src)) = (col.as_mut(), self.colors.as_ref()) {
                    c[new as usize] = src[old];
                }
            }
        }
        for t in &mut self.triangles {
            *t = t.map(|i| remap[i as usize]);
        }
        self.positions = pos;
        self.normals = nrm;
        self.colors = col;
        self.uvs = uvs;
    }

    /// Axis-aligned bounds (min, max); zeros for an empty mesh.
    pub fn bounds(&self) -> ([f32; 3], [f32; 3]) {
        if self.positions.is_empty() {
            return ([0.0; 3], [0.0; 3]);
        }
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for p in &self.positions {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        (lo, hi)
    }
}
