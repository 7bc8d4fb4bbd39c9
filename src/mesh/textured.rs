//! From the full marching-cubes mesh to the one people import: decimated to a triangle budget,
//! then either unwrapped with its base colour baked into a texture (the default) or kept with
//! vertex colours.

use super::atlas::{unwrap, AtlasReport};
use super::bake::{bake_base_colour, BakeReport};
use super::colour::RayReach;
use super::decimate::{
    decimate, DecimateReport, DEFAULT_FRACTION_OF_FULL, DEFAULT_MAX_TRIANGLES,
    DEFAULT_TOLERANCE_VOXELS, VERTEX_COLOUR_WEIGHT,
};
use super::visibility::{occlusion_tolerance, SeenFrom};
use super::{Mesh, Shading};
use crate::edit::Recolour;
use crate::error::Result;
use crate::field::model::Field;
use glam::Vec3;
use serde::Serialize;
use std::time::Instant;

/// The baked texture's size.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TextureSize {
    /// Texels of half the field's finest voxel over the mesh's surface (the field holds no finer
    /// colour: its colour is trilinear between voxel corners, and a voxel is sized to about one
    /// photo pixel), as a power of two from [`AUTO_MIN`] to [`AUTO_MAX`].
    Auto,
    /// This many texels a side.
    Side(u32),
}

/// The smallest and largest automatic texture sides (nerfstudio bakes 1024–2048).
pub const AUTO_MIN: u32 = 512;
pub const AUTO_MAX: u32 = 4096;

/// Texels per finest voxel, along each side, for [`TextureSize::Auto`].
const TEXELS_PER_VOXEL: f32 = 2.0;

/// How far, in decimation errors (the simplifier's largest), the bake marches each camera's
/// ray before and past a texel. The error is a bound on the mesh's move, but where the field
/// holds relief finer than the triangles (studs, fur) the surface a camera saw through the
/// texel can lie further along its ray. Measured (`examples/results/textured_mesh.md`,
/// fourteenth session), default exports inside the mask at held-out views, x1 -> x4: lego
/// 22.43 -> 22.57 dB, fox head 17.76 -> 18.07, demo mug 19.48 -> 19.51 (x0.5 lego 22.37, x2
/// 22.50).
const BAKE_SLACK_FACTOR: f32 = 4.0;

/// The bake's step along each camera's ray, in finest voxels (vertex colours read a quarter
/// voxel: [`RayReach::ON_SURFACE`]). The bake reads a ray per texel and camera, sixteen million
/// on lego's 2048 px page, and colouring the samples is most of its time; at half a voxel the
/// default exports score the same at held-out views (`examples/results/textured_mesh.md`,
/// fifteenth session: lego 22.57 dB, fox head 18.07, demo mug 19.51, each unchanged) and
/// `objnerf mesh` takes 287 s on lego (461 s at a quarter voxel) and 230 s on the fox head (308 s).
const BAKE_STEP_VOXELS: f32 = 0.5;

/// The share of a page the atlas is expected to cover (measured: 0.53–0.69).
const EXPECTED_USE: f32 = 0.5;

impl TextureSize {
    /// The side for `mesh` (world units) of a field with finest voxel `voxel`.
    pub fn side(self, mesh: &Mesh, voxel: f32) -> u32 {
        match self {
            TextureSize::Side(s) => s,
            TextureSize::Auto => {
                let area = surface_area(mesh) as f32;
                let texels = area * (TEXELS_PER_VOXEL / voxel).powi(2) / EXPECTED_USE;
                let side = texels.sqrt().ceil().max(1.0) as u32;
                side.next_power_of_two().clamp(AUTO_MIN, AUTO_MAX)
            }
        }
    }

    /// `auto` or a number of texels.
    pub fn parse(s: &str) -> Result<TextureSize> {
        if s.eq_ignore_ascii_case("auto") {
            return Ok(TextureSize::Auto);
        }
        s.parse().map(TextureSize::Side).map_err(|_| {
            crate::error::Error::invalid(format!(
                "--texture {s}: expected auto or a size in pixels"
            ))
        })
    }
}

/// The mesh's surface area (world units squared).
fn surface_area(mesh: &Mesh) -> f64 {
    let p = |i: u32| glam::Vec3::from(mesh.positions[i as usize]).as_dvec3();
    mesh.triangles
        .iter()
        .map(|t| 0.5 * (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0])).length())
        .sum()
}

/// How the exported mesh is made from the full one.
#[derive(Clone, Debug, PartialEq)]
pub struct ExportOptions {
    /// Triangle budget (None: the full mesh, no decimation).
    pub max_triangles: Option<usize>,
    /// A budget relative to the full mesh as well (the smaller applies): the default, a fifth
    /// ([`DEFAULT_FRACTION_OF_FULL`]); None where a budget was asked for in triangles.
    pub fraction_of_full: Option<f64>,
    /// Decimation stops where the surface would move this many finest voxels.
    pub tolerance_voxels: f32,
    /// The baked base-colour texture (None: vertex colours, no texture).
    pub texture: Option<TextureSize>,
    pub shading: Shading,
}

impl Default for ExportOptions {
    fn default() -> Self {
        ExportOptions {
            max_triangles: Some(DEFAULT_MAX_TRIANGLES),
            fraction_of_full: Some(DEFAULT_FRACTION_OF_FULL),
            tolerance_voxels: DEFAULT_TOLERANCE_VOXELS,
            texture: Some(TextureSize::Auto),
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
/// field's world frame), as `opts` says; its colours read as the vertex colours were (the
/// training cameras at `seen_from`, `recolour`).
pub fn export_mesh(
    field: &Field,
    full: &Mesh,
    opts: &ExportOptions,
    seen_from: &[Vec3],
    recolour: Option<Recolour>,
) -> Result<(Mesh, ExportReport)> {
    let mut report = ExportReport {
        shading: opts.shading,
        ..Default::default()
    };
    let t = Instant::now();
    let mut mesh = match opts.max_triangles {
        Some(_) => {
            let tol = opts.tolerance_voxels * field.voxel;
            let budget = opts.max_triangles.map(|b| match opts.fraction_of_full {
                Some(f) => b.min(((full.triangles.len() as f64 * f).ceil() as usize).max(1)),
                None => b,
            });
            // Colour edges keep their vertices where the colour is in the vertices; with a
            // texture the page holds it and the geometry alone decides.
            let colour_weight = match opts.texture {
                Some(_) => 0.0,
                None => VERTEX_COLOUR_WEIGHT,
            };
            let (m, r) = decimate(full, budget, tol, colour_weight)?;
            report.decimate = Some(r);
            m
        }
        None => full.clone(),
    };
    report.decimate_seconds = t.elapsed().as_secs_f64();
    mesh.shading = opts.shading;
    if let Some(texture) = opts.texture {
        let size = texture.side(&mesh, field.voxel);
        let t = Instant::now();
        let (mut m, atlas) = unwrap(&mesh, size)?;
        report.unwrap_seconds = t.elapsed().as_secs_f64();
        let t = Instant::now();
        // The bake reads each camera's ray through a texel out to a few times the decimation's
        // own error, so it finds the surface that camera saw there.
        let reach = RayReach {
            slack: BAKE_SLACK_FACTOR * report.decimate.as_ref().map_or(0.0, |d| d.error),
            step_voxels: BAKE_STEP_VOXELS,
        };
        // Which cameras see a texel: depth maps of the full mesh, the reference surface.
        let seen = SeenFrom::with_occlusion(seen_from, full, occlusion_tolerance(field));
        let (img, bake) = bake_base_colour(field, &m, size, reach, &seen, recolour)?;
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
