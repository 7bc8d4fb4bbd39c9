//! Self-checks of an object's mesh (see [`crate::util::warnings`]): many disconnected pieces,
//! and a surface that is mostly the field's box (the field filled its box instead of finding
//! the object). A field with no surface at all is an error of `mesh_field` already.

use super::Mesh;
use crate::util::warnings::{Stage, Warning};
use glam::Vec3;

/// More pieces than this (each at least [`PIECE_FRACTION`] of the largest, so not specks) means
/// the object came out in fragments or with large floaters; a single object is one piece, or a
/// few where thin parts (handles, legs) break at the field's resolution.
pub const MAX_PIECES: usize = 3;
/// A piece counts towards [`MAX_PIECES`] with at least this fraction of the largest piece's
/// triangles (what the mesher dropped before it kept every piece).
pub const PIECE_FRACTION: f64 = 0.05;
/// More than this fraction of vertices on the box's faces (within [`BOX_FACE_VOXELS`]) means
/// the surface is the box, not the object: the box is padded around the masks' visual hull, so
/// a real surface touches it only where the object meets the floor or the frame.
pub const MAX_ON_BOX: f64 = 0.25;
/// How near a face (in finest voxels) a vertex counts as on it.
pub const BOX_FACE_VOXELS: f32 = 1.5;

/// The fraction of `mesh`'s vertices within [`BOX_FACE_VOXELS`] of a face of the box.
pub fn fraction_on_box(mesh: &Mesh, lo: Vec3, hi: Vec3, voxel: f32) -> f64 {
    if mesh.positions.is_empty() {
        return 0.0;
    }
    let tol = BOX_FACE_VOXELS * voxel;
    let on = mesh
        .positions
        .iter()
        .filter(|p| {
            let p = Vec3::from_array(**p);
            (p - lo).min_element() < tol || (hi - p).min_element() < tol
        })
        .count();
    on as f64 / mesh.positions.len() as f64
}

/// Every mesh check for `object`'s mesh, cut from a field with box `lo`..`hi` and finest voxel
/// `voxel`.
pub fn check_mesh(object: &str, mesh: &Mesh, lo: Vec3, hi: Vec3, voxel: f32) -> Vec<Warning> {
    let mut out = Vec::new();
    let sizes = mesh.component_sizes();
    let largest = sizes.first().copied().unwrap_or(0) as f64;
    let pieces = sizes
        .iter()
        .filter(|s| **s as f64 >= PIECE_FRACTION * largest)
        .count();
    if pieces > MAX_PIECES {
        out.push(
            Warning::new(
                Stage::Mesh,
                "mesh_fragmented",
                pieces as f64,
                MAX_PIECES as f64,
                format!(
                    "the mesh is {pieces} disconnected pieces: the field is fragmented or holds floaters; check the turntable"
                ),
            )
            .about(object),
        );
    }
    let on_box = fraction_on_box(mesh, lo, hi, voxel);
    if on_box > MAX_ON_BOX {
        out.push(
            Warning::new(
                Stage::Mesh,
                "mesh_on_box",
                on_box,
                MAX_ON_BOX,
                format!(
                    "{:.0}% of the mesh lies on the field's box: the field filled its box instead of finding the object's surface (masks that disagree across views?)",
                    100.0 * on_box
                ),
            )
            .about(object),
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad(at: [f32; 3], size: f32, offset: u32) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
        let [x, y, z] = at;
        (
            vec![
                [x, y, z],
                [x + size, y, z],
                [x + size, y + size, z],
                [x, y + size, z],
            ],
            vec![
                [offset, offset + 1, offset + 2],
                [offset, offset + 2, offset + 3],
            ],
        )
    }

    #[test]
    fn pieces_and_box_faces_are_counted() {
        let mut m = Mesh::default();
        for k in 0..5 {
            let (p, t) = quad([k as f32 * 2.0, 0.5, 5.0], 1.0, m.positions.len() as u32);
            m.positions.extend(p);
            m.triangles.extend(t);
        }
        assert_eq!(m.component_sizes(), vec![2; 5]);
        let w = check_mesh("o", &m, Vec3::ZERO, Vec3::splat(10.0), 0.1);
        assert_eq!(
            w.iter().map(|w| w.code).collect::<Vec<_>>(),
            ["mesh_fragmented"]
        );
        // Every vertex on the z = 10 face: the surface is the box.
        let w = check_mesh(
            "o",
            &m,
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(11.0, 11.0, 5.05),
            0.1,
        );
        assert!(w.iter().any(|w| w.code == "mesh_on_box"));
    }
}
