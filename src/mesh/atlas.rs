//! A UV atlas for a mesh: charts cut, flattened (LSCM + ARAP) and packed into one square page
//! by `uvunwrap` (pure Rust; chosen over xatlas by the measured comparison in
//! `examples/uv_unwrap_compare.rs`, `examples/results/textured_mesh.md`).

use super::Mesh;
use crate::error::{Error, Result};
use serde::Serialize;

/// What the unwrap made.
#[derive(Clone, Debug, Serialize)]
pub struct AtlasReport {
    /// The texture's side in texels (square).
    pub size: u32,
    pub charts: u32,
    /// Share of the page's texels covered by chart surface.
    pub utilization: f32,
    /// Empty texels kept around each chart.
    pub padding: u32,
    /// Vertices before and after splitting along chart seams.
    pub vertices_before: usize,
    pub vertices_after: usize,
}

/// Empty texels around each chart (the bake dilates the charts' colour into them, so bilinear
/// filtering at a seam reads the chart's own colour). Two, not more: a detailed mesh has many
/// charts (lego at 50k triangles: 11 775), and 8 texels around each left them 0.75% of a
/// 2048 px page.
pub const PADDING: u32 = 2;

/// Unwrap `mesh` into a `size` x `size` page. The result has the same triangles in the same
/// order, vertices split along chart seams (positions, normals and colours copied) and `uvs`
/// in glTF's convention.
pub fn unwrap(mesh: &Mesh, size: u32) -> Result<(Mesh, AtlasReport)> {
    if !(16..=16384).contains(&size) {
        return Err(Error::invalid(format!(
            "texture size {size}: use 16 to 16384 texels"
        )));
    }
    let indices: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
    let input = uvunwrap::MeshInput::new(&mesh.positions, &indices);
    // Many small charts (a detailed mesh) may not fit one page with their padding: halve the
    // padding until they do.
    let mut padding = PADDING;
    let atlas = loop {
        let options = uvunwrap::Options {
            density: uvunwrap::Density::Auto { page_size: size },
            padding,
            ..Default::default()
        };
        let atlas = uvunwrap::generate(std::slice::from_ref(&input), &options)
            .map_err(|e| Error::invalid(format!("UV unwrap of '{}': {e}", mesh.name)))?;
        if atlas.page_count == 1 || padding == 1 {
            break atlas;
        }
        padding /= 2;
    };
    if atlas.page_count != 1 {
        return Err(Error::invalid(format!(
            "UV unwrap of '{}': its {} charts do not fit one {size} px page; use a larger texture \
             or fewer triangles",
            mesh.name, atlas.chart_count
        )));
    }
    let out = &atlas.meshes[0];
    // The page is cropped to the rows used; the texture stays square (mipmaps, web viewers), so
    // v is rescaled onto the full page.
    let v_scale = atlas.height as f32 / size as f32;
    let pick = |xs: &[[f32; 3]]| -> Vec<[f32; 3]> {
        out.vertices.iter().map(|v| xs[v.xref as usize]).collect()
    };
    let m = Mesh {
        name: mesh.name.clone(),
        positions: pick(&mesh.positions),
        normals: pick(&mesh.normals),
        colors: mesh.colors.as_deref().map(pick),
        uvs: Some(
            out.vertices
                .iter()
                .map(|v| [v.uv[0], v.uv[1] * v_scale])
                .collect(),
        ),
        texture: None,
        shading: mesh.shading,
        triangles: out
            .indices
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
            .collect(),
    };
    let report = AtlasReport {
        size,
        charts: atlas.chart_count,
        utilization: atlas.utilization * v_scale,
        padding,
        vertices_before: mesh.positions.len(),
        vertices_after: m.positions.len(),
    };
    Ok((m, report))
}
