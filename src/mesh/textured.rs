//! From the full marching-cubes mesh to the one people import: decimated to a triangle budget,
//! then either unwrapped with its base colour baked into a texture (the default) or kept with
//! vertex colours.

use super::atlas::{unwrap, AtlasReport};
use super::bake::{bake_base_colour, BakeReport};
use super::decimate::{decimate, DecimateReport, DEFAULT_MAX_TRIANGLES, DEFAULT_TOLERANCE_VOXELS};
use super::from_field::FieldMeshOptions;
use super::{Mesh, Shading};
use crate::error::Result;
use crate::field::model::Field;
use serde::Serialize;
use std::time::Instant;

/// The default texture: 2048 px, nerfstudio's upper default and what a 50k-triangle object needs
/// for texels finer than its field's voxels (measured in `examples/results/textured_mesh.md`).
pub const DEFAULT_TEXTURE_SIZE: u32 = 2048;

/// How the exported mesh is made from the full one.
#[derive(Clone, Debug, PartialEq)]
pub struct ExportOptions {
    /// Triangle budget (None: the full mesh, no decimation).
    pub max_triangles: Option<usize>,
    /// Decimation stops where the surface would move this many finest voxels.
    pub tolerance_voxels: f32,
    /// Side of the baked base-colour texture (None: vertex colours, no texture).
    pub texture_size: Option<u32>,
    pub shading: Shading,
}

impl Default for ExportOptions {
    fn default() -> Self {
        ExportOptions {
            max_triangles: Some(DEFAULT_MAX_TRIANGLES),
            tolerance_voxels: DEFAULT_TOLERANCE_VOXELS,
            texture_size: Some(DEFAULT_TEXTURE_SIZE),
            shading: Shading::Unlit,
        }
    }
}

/// What [`export_mesh`] did, with the time of each step.
#[derive(Clone, Debug, Default, Serialize)]
pub struct ExportReport {
    pub decimate: Option<DecimateReport>,
    pub atlas: Option<AtlasReport>,
    pub bake: Option<BakeReport>,
    pub shading: Shading,
    pub triangles: usize,
    pub vertices: usize,
    pub decimate_seconds: f64,
    pub unwrap_seconds: f64,
    pub bake_seconds: f64,
}

/// The mesh to write, from `full` (the field's marching-cubes mesh with vertex colours, in the
/// field's world frame), as `mesh_opts.export` says (its colours read as the vertex colours
/// were: `seen_from`, `recolour`).
pub fn export_mesh(
    field: &Field,
    full: &Mesh,
    mesh_opts: &FieldMeshOptions,
) -> Result<(Mesh, ExportReport)> {
    let opts = &mesh_opts.export;
    let mut report = ExportReport {
        shading: opts.shading,
        ..Default::default()
    };
    let t = Instant::now();
    let mut mesh = match opts.max_triangles {
        Some(_) => {
            let tol = opts.tolerance_voxels * field.voxel;
            let (m, r) = decimate(full, opts.max_triangles, tol)?;
            report.decimate = Some(r);
            m
        }
        None => full.clone(),
    };
    report.decimate_seconds = t.elapsed().as_secs_f64();
    mesh.shading = opts.shading;
    if let Some(size) = opts.texture_size {
        let t = Instant::now();
        let (mut m, atlas) = unwrap(&mesh, size)?;
        report.unwrap_seconds = t.elapsed().as_secs_f64();
        let t = Instant::now();
        // The bake reads the field around each texel out to the decimation's own error.
        let slack = report.decimate.as_ref().map_or(0.0, |d| d.error);
        let (img, bake) = bake_base_colour(field, &m, size, slack, mesh_opts)?;
        report.bake_seconds = t.elapsed().as_secs_f64();
        m.colors = None;
        m.texture = Some(std::sync::Arc::new(img));
        report.atlas = Some(atlas);
        report.bake = Some(bake);
        mesh = m;
    }
    report.triangles = mesh.triangles.len();
    report.vertices = mesh.positions.len();
    Ok((mesh, report))
}
