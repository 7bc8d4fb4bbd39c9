//! Decimation to a triangle budget with meshoptimizer's edge-collapse simplifier.
//!
//! Marching cubes spends triangles evenly, one or two per surface voxel; flat and gently curved
//! parts need far fewer. The simplifier collapses edges by quadric error, keeping every remaining
//! vertex at one of the original positions (so per-vertex values such as colours stay valid).
//! Two limits apply: at most `max_triangles`, and no fewer than the geometry needs to stay within
//! `tolerance` world units of the original surface (collapses stop there even under the budget).

use super::Mesh;
use crate::error::{Error, Result};
use serde::Serialize;

/// The default triangle budget: 50 000 triangles. A textured mesh carries its colour in the
/// texture, so triangles only have to hold the shape; 50k keeps a web viewer (three.js,
/// model-viewer) interactive on a phone and a Blender scene of dozens of objects light, while a
/// single object's silhouette at 1–2k px needs no more (the marching-cubes mesh of the demo mug
/// holds its shape to a quarter voxel with far fewer: see `examples/results/textured_mesh.md`).
pub const DEFAULT_MAX_TRIANGLES: usize = 50_000;

/// The default budget relative to the marching-cubes mesh as well: a fifth of its triangles
/// (the smaller of this and [`DEFAULT_MAX_TRIANGLES`] applies). With the colour in the texture,
/// a fifth of the triangles drew the demo mug, lego and the fox head at held-out views at or
/// above the full vertex-coloured mesh (`examples/results/textured_mesh.md`), where the quarter
/// voxel alone left small objects at 28%.
pub const DEFAULT_FRACTION_OF_FULL: f64 = 0.2;

/// Collapses stop once the surface would move this many of the field's finest voxels.
pub const DEFAULT_TOLERANCE_VOXELS: f32 = 0.25;

/// What [`decimate`] did.
#[derive(Clone, Debug, Serialize)]
pub struct DecimateReport {
    pub triangles_before: usize,
    pub triangles_after: usize,
    /// The simplifier's own error estimate, in world units (the largest surface deviation it
    /// accepted).
    pub error: f32,
    /// The budget asked for (None: none, only the tolerance).
    pub max_triangles: Option<usize>,
    pub tolerance: f32,
}

/// Simplify `mesh` to at most `max_triangles` (None: no budget) and as few as `tolerance` (world
/// units) allows. Normals are recomputed; colours are kept (vertices keep original positions).
pub fn decimate(
    mesh: &Mesh,
    max_triangles: Option<usize>,
    tolerance: f32,
) -> Result<(Mesh, DecimateReport)> {
    if max_triangles == Some(0) {
        return Err(Error::invalid(
            "a triangle budget of 0 leaves nothing: give at least 1",
        ));
    }
    if !(tolerance >= 0.0 && tolerance.is_finite()) {
        return Err(Error::invalid(format!(
            "the decimation tolerance must be a length of 0 or more, not {tolerance}"
        )));
    }
    let indices: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
    let before = mesh.triangles.len();
    let opts = meshopt::SimplifyOptions::ErrorAbsolute;
    // First as far as the tolerance allows; then, when that is still over budget, to the budget
    // whatever the error.
    let mut error = 0f32;
    let mut out = meshopt::simplify_decoder(
        &indices,
        &mesh.positions,
        0,
        tolerance,
        opts,
        Some(&mut error),
    );
    if let Some(budget) = max_triangles {
        if out.len() / 3 > budget {
            let mut e2 = 0f32;
            out = meshopt::simplify_decoder(
                &out,
                &mesh.positions,
                budget * 3,
                f32::MAX,
                opts,
                Some(&mut e2),
            );
            error = error.max(e2);
        }
    }
    let mut m = mesh.clone();
    m.triangles = out.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
    m.drop_unused_vertices();
    m.compute_normals();
    let report = DecimateReport {
        triangles_before: before,
        triangles_after: m.triangles.len(),
        error,
        max_triangles,
        tolerance,
    };
    Ok((m, report))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::marching::marching_cubes;
    use glam::DVec3;

    fn sphere(n: usize) -> Mesh {
        let c = (n - 1) as f32 / 2.0;
        let r = c * 0.7;
        let mut v = vec![0f32; n * n * n];
        for z in 0..n {
            for y in 0..n {
                for x in 0..n {
                    let d = DVec3::new(x as f64, y as f64, z as f64) - DVec3::splat(c as f64);
                    v[x + n * (y + n * z)] = r - d.length() as f32;
                }
            }
        }
        let g = marching_cubes(&v, [n, n, n], 0.0);
        Mesh::from_grid(
            "s",
            g,
            DVec3::splat(-1.0),
            DVec3::splat(2.0 / (n - 1) as f64),
        )
    }

    #[test]
    fn meets_the_budget_and_keeps_the_shape() {
        let m = sphere(48);
        assert!(m.triangles.len() > 10_000);
        let (d, r) = decimate(&m, Some(2000), 0.0).unwrap();
        assert!(
            d.triangles.len() <= 2000 && d.triangles.len() > 1500,
            "{r:?}"
        );
        assert_eq!(r.triangles_after, d.triangles.len());
        // Every vertex still on the sphere of radius 0.7 (to a voxel).
        for p in &d.positions {
            let l = glam::Vec3::from(*p).length();
            assert!((l - 0.7).abs() < 0.05, "{l}");
        }
        let cd = crate::mesh::chamfer::chamfer_distance(&m, &d, 20_000, 1);
        assert!(cd < 0.01, "{cd}");
        // A tolerance alone: fewer triangles for a looser one.
        let (a, _) = decimate(&m, None, 0.001).unwrap();
        let (b, _) = decimate(&m, None, 0.02).unwrap();
        assert!(b.triangles.len() < a.triangles.len());
        assert!(decimate(&m, Some(0), 0.0).is_err());
    }
}
