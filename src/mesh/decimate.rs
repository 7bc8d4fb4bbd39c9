//! Decimation to a triangle budget with meshoptimizer's edge-collapse simplifier.
//!
//! Marching cubes spends triangles evenly, one or two per surface voxel; flat and gently curved
//! parts need far fewer. The simplifier collapses edges by quadric error, keeping every remaining
//! vertex at one of the original positions (so per-vertex values such as colours stay valid).
//! Two limits apply: at most `max_triangles`, and no fewer than the geometry needs to stay within
//! `tolerance` world units of the original surface (collapses stop there even under the budget).
//! A mesh that carries its colour in its vertices (no texture) can ask the collapses to the
//! budget to weigh the colour as well, so colour edges keep their vertices.

use super::Mesh;
use crate::error::{Error, Result};
use serde::Serialize;

/// The default triangle budget: 100 000 triangles, Apple's rule of thumb for a model in AR Quick
/// Look (100k polygons with one set of 2048 px textures, WWDC 2018, restated by Apple in 2021 for
/// every device down to the iPhone 7): the most a phone's viewer is asked to draw, and light for
/// Blender and desktop web viewers (three.js, model-viewer). A textured mesh carries its colour
/// in the texture, so triangles only have to hold the shape; relief smaller than the budget's
/// triangles (lego's studs and rods) is what they cannot hold: at 50 000 (nerfstudio's
/// `ns-export` default) lego drew 0.18 dB under its full mesh at held-out views, at 100 000 0.05
/// above (`examples/results/textured_mesh.md`).
pub const DEFAULT_MAX_TRIANGLES: usize = 100_000;

/// The default budget relative to the marching-cubes mesh as well: a fifth of its triangles
/// (the smaller of this and [`DEFAULT_MAX_TRIANGLES`] applies). With the colour in the texture,
/// a fifth of the triangles drew the demo mug, lego and the fox head at held-out views at or
/// above the full vertex-coloured mesh (`examples/results/textured_mesh.md`), where the quarter
/// voxel alone left small objects at 28%.
pub const DEFAULT_FRACTION_OF_FULL: f64 = 0.2;

/// Collapses stop once the surface would move this many of the field's finest voxels.
pub const DEFAULT_TOLERANCE_VOXELS: f32 = 0.25;

/// How much the collapses to the budget weigh a difference of vertex colour (0..1 a channel)
/// against the surface's move, when the colour is in the vertices: meshoptimizer's attribute
/// weight (its positions normalised to the mesh's extent), of the order its documentation gives
/// for unit-range attributes. Measured (`examples/results/textured_mesh.md`): vertex-coloured
/// exports gain 1.2 dB inside the mask on lego and 1.7 on the demo mug, the fox head's fur is
/// even (-0.03); textured ones lost up to 0.24 dB with it, so they do not use it.
pub const VERTEX_COLOUR_WEIGHT: f32 = 0.5;

/// What [`decimate`] did.
#[derive(Clone, Debug, Serialize)]
pub struct DecimateReport {
    pub triangles_before: usize,
    pub triangles_after: usize,
    /// The simplifier's own error estimate, in world units (the largest surface deviation it
    /// accepted; with the colour weighed, the colour's share is in it as well).
    pub error: f32,
    /// The budget asked for (None: none, only the tolerance).
    pub max_triangles: Option<usize>,
    pub tolerance: f32,
}

/// Simplify `mesh` to at most `max_triangles` (None: no budget) and as few as `tolerance` (world
/// units) allows. Normals are recomputed; colours are kept (vertices keep original positions).
/// `colour_weight` > 0 weighs the vertex colours in the collapses to the budget
/// ([`VERTEX_COLOUR_WEIGHT`]); 0, or a mesh without colours: the geometry alone.
pub fn decimate(
    mesh: &Mesh,
    max_triangles: Option<usize>,
    tolerance: f32,
    colour_weight: f32,
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
    // The colours as meshoptimizer's attributes, and no vertex locked.
    let weighed: Option<(Vec<f32>, Vec<bool>)> = match &mesh.colors {
        Some(c) if colour_weight > 0.0 => Some((
            c.iter().flatten().copied().collect(),
            vec![false; mesh.positions.len()],
        )),
        _ => None,
    };
    // One simplifier pass from `from` down to `target` indices within `target_error`.
    let simplify = |from: &[u32], target: usize, target_error: f32| {
        let mut e = 0f32;
        let out = match &weighed {
            Some((attrs, unlocked)) => meshopt::simplify_with_attributes_and_locks_decoder(
                from,
                &mesh.positions,
                attrs,
                &[colour_weight; 3],
                std::mem::size_of::<[f32; 3]>(),
                unlocked,
                target,
                target_error,
                opts,
                Some(&mut e),
            ),
            None => meshopt::simplify_decoder(
                from,
                &mesh.positions,
                target,
                target_error,
                opts,
                Some(&mut e),
            ),
        };
        (out, e)
    };
    // First as far as the tolerance allows; then, when that is still over budget, to the budget
    // whatever the error.
    let (mut out, mut error) = simplify(&indices, 0, tolerance);
    if let Some(budget) = max_triangles {
        if out.len() / 3 > budget {
            let (o, e2) = simplify(&out, budget * 3, f32::MAX);
            out = o;
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
        let (d, r) = decimate(&m, Some(2000), 0.0, 0.0).unwrap();
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
        let (a, _) = decimate(&m, None, 0.001, 0.0).unwrap();
        let (b, _) = decimate(&m, None, 0.02, 0.0).unwrap();
        assert!(b.triangles.len() < a.triangles.len());
        assert!(decimate(&m, Some(0), 0.0, 0.0).is_err());
    }

    /// A flat n x n grid of vertices over the unit square, dark left of x = 0.5 and light right.
    fn plane_with_a_colour_step(n: usize) -> Mesh {
        let mut positions = Vec::new();
        let mut colors = Vec::new();
        for y in 0..n {
            for x in 0..n {
                let (u, v) = (x as f32 / (n - 1) as f32, y as f32 / (n - 1) as f32);
                positions.push([u, v, 0.0]);
                colors.push(if u < 0.5 { [0.1; 3] } else { [0.9; 3] });
            }
        }
        let at = |x: usize, y: usize| (x + n * y) as u32;
        let mut triangles = Vec::new();
        for y in 0..n - 1 {
            for x in 0..n - 1 {
                triangles.push([at(x, y), at(x + 1, y), at(x + 1, y + 1)]);
                triangles.push([at(x, y), at(x + 1, y + 1), at(x, y + 1)]);
            }
        }
        let mut m = Mesh {
            name: "plane".into(),
            positions,
            colors: Some(colors),
            triangles,
            ..Default::default()
        };
        m.compute_normals();
        m
    }

    /// Triangles whose vertices' colours differ by more than `by`: where the drawn colour is a
    /// blend across a step.
    fn blended(m: &Mesh, by: f32) -> usize {
        let c = m.colors.as_ref().unwrap();
        m.triangles
            .iter()
            .filter(|t| {
                let v: Vec<f32> = t.iter().map(|&i| c[i as usize][0]).collect();
                let (lo, hi) = v
                    .iter()
                    .fold((1f32, 0f32), |a, &x| (a.0.min(x), a.1.max(x)));
                hi - lo > by
            })
            .count()
    }

    #[test]
    fn weighing_the_colour_keeps_a_colour_edge_on_a_flat_surface() {
        let m = plane_with_a_colour_step(21);
        // The geometry alone collapses the flat square to a few triangles, each blending dark
        // into light over half the square.
        let (geo, _) = decimate(&m, Some(200), 1e-4, 0.0).unwrap();
        assert!(geo.triangles.len() < 40, "{}", geo.triangles.len());
        let wide = geo.triangles.iter().any(|t| {
            let xs: Vec<f32> = t.iter().map(|&i| geo.positions[i as usize][0]).collect();
            let (lo, hi) = xs
                .iter()
                .fold((1f32, 0f32), |a, &x| (a.0.min(x), a.1.max(x)));
            lo < 0.3 && hi > 0.7
        });
        assert!(wide && blended(&geo, 0.5) > 0);
        // Weighing the colour keeps the two columns either side of the step: only the thin
        // strip between them blends, and the rest is flat colour.
        let (col, _) = decimate(&m, Some(200), 1e-4, VERTEX_COLOUR_WEIGHT).unwrap();
        let c = col.colors.as_ref().unwrap();
        let strip = col
            .positions
            .iter()
            .zip(c)
            .filter(|(p, _)| (p[0] - 0.5).abs() < 0.06);
        assert!(strip.clone().any(|(_, c)| c[0] < 0.5) && strip.clone().any(|(_, c)| c[0] > 0.5));
        for t in &col.triangles {
            let xs: Vec<f32> = t.iter().map(|&i| col.positions[i as usize][0]).collect();
            let (lo, hi) = xs
                .iter()
                .fold((1f32, 0f32), |a, &x| (a.0.min(x), a.1.max(x)));
            let mixed = blended(
                &Mesh {
                    triangles: vec![*t],
                    ..col.clone()
                },
                0.5,
            ) == 1;
            // A blending triangle lies within the strip between the step's two columns.
            assert!(!mixed || (lo >= 0.45 - 1e-4 && hi <= 0.55 + 1e-4), "{xs:?}");
        }
    }
}
