//! A mesh out of an object field: marching cubes on the field's raw density, vertex colours from
//! its view-independent colour.
//!
//! The iso-level is an opacity: the surface is where one finest voxel of material would be
//! `iso_alpha` opaque, i.e. density softplus(raw + shift) = -ln(1 - iso_alpha) per voxel length.
//! Marching cubes runs on the *raw* grid with the matching raw level: softplus is monotone and the
//! field interpolates raw values before activating them (DVGO's post-activation), so cutting the
//! raw trilinear field at one level is exactly the surface the renderer sees.

use super::colour::{raw_at, surface_colour, view_centres, RayReach};
use super::fill::{fill_cavities, GridUp, EMPTY, SEAL_VOXELS};
use super::frame::{GltfFrame, Placement};
use super::io::MeshFormat;
use super::textured::{export_mesh, ExportOptions, ExportReport};
use super::visibility::{occlusion_tolerance, SeenFrom};
use super::{marching::marching_cubes, Mesh};
use crate::error::{Error, Result};
use crate::field::model::Field;
use glam::{DVec3, Vec3};
use rayon::prelude::*;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// The default surface opacity. Fields of real captures hold soft surfaces (fur, fine parts, a
/// voxel partly covered) as a few voxels of thinner matter that together are opaque: cut at
/// 0.5 a voxel, they came out full of holes (lego's tracks, the fox's fur) and in fragments. At
/// 0.2 the mesh drawn at held-out views, inside the mask, scored lego +5.0 dB, the fox head
/// +6.5 dB (with every piece kept), the demo mug +0.56 dB; the mug's Chamfer to its true mesh
/// moved 1.54 -> 1.58% of the diagonal (`examples/results/textured_mesh.md`, "Where the mesh's
/// surface is cut").
pub const DEFAULT_ISO_ALPHA: f32 = 0.2;

/// How to cut a field into a mesh.
#[derive(Clone, Debug)]
pub struct FieldMeshOptions {
    /// Samples along the box's longest side (default: the field's own vertex grid, where the
    /// trilinear field is exact).
    pub resolution: Option<usize>,
    /// Opacity of one finest voxel at the surface (0..1).
    pub iso_alpha: f32,
    /// Drop connected pieces with fewer triangles than this fraction of the largest (0 keeps all,
    /// the default: a real capture's soft surface breaks into pieces that are surface, not
    /// floaters; dropping those under 5% of the largest cost the fox head 1 dB).
    pub min_component: f64,
    /// Fill empty space that cannot be reached from outside the object (see [`fill_cavities`]).
    pub fill_cavities: bool,
    /// Recolour the vertex colours as `render-edit` recolours the field's radiance.
    pub recolour: Option<crate::edit::Recolour>,
    /// The training cameras' centres (world): a surface point's colour is the mean of the
    /// field's towards those on its outer side (empty: the view-independent colour; see
    /// [`super::colour`]). [`mesh_model`] reads them from the model's notes.
    pub seen_from: Vec<Vec3>,
    /// Give the marching-cubes mesh vertex colours (default). Off where only a texture baked
    /// from the field is written (`objnerf mesh` to .glb): the colours of a million vertices read
    /// from 16 cameras each were a third of lego's export, and nothing used them.
    pub vertex_colours: bool,
    /// Decimation, texture and material of the mesh written ([`export_mesh`]).
    pub export: ExportOptions,
    /// Origin and scale in the glTF (.glb, .obj).
    pub placement: Placement,
}

impl Default for FieldMeshOptions {
    fn default() -> Self {
        FieldMeshOptions {
            resolution: None,
            iso_alpha: DEFAULT_ISO_ALPHA,
            min_component: 0.0,
            fill_cavities: true,
            recolour: None,
            seen_from: Vec::new(),
            vertex_colours: true,
            export: ExportOptions::default(),
            placement: Placement {
                origin: super::frame::Origin::Base,
                ..Default::default()
            },
        }
    }
}

/// What the extraction did, for reports.
#[derive(Clone, Debug, Serialize)]
pub struct FieldMeshReport {
    pub sample_dims: [usize; 3],
    pub iso_alpha: f32,
    pub iso_raw: f32,
    pub pieces_removed: usize,
    /// Empty samples enclosed by the surface, made solid.
    pub cavity_samples_filled: usize,
    pub vertices: usize,
    pub triangles: usize,
}

/// The raw density level matching an opacity per finest voxel.
pub fn iso_raw(field: &Field, iso_alpha: f32) -> Result<f32> {
    if !(iso_alpha > 0.0 && iso_alpha < 1.0) {
        return Err(Error::invalid(format!(
            "the iso-level is an opacity and must lie strictly between 0 and 1, not {iso_alpha}"
        )));
    }
    Ok(field.raw_for_alpha(iso_alpha, 1.0))
}

/// Cut `field` at `opts.iso_alpha` into a mesh in the field's world units, with normals and
/// vertex colours. Errors when nothing in the field reaches the iso-level.
pub fn mesh_field(
    field: &Field,
    name: &str,
    opts: &FieldMeshOptions,
    up: Option<DVec3>,
) -> Result<(Mesh, FieldMeshReport)> {
    if field.space != crate::space::Space::Box {
        return Err(Error::invalid(format!(
            "this is a scene field in {} space: meshes are made from object fields (box space)",
            field.space.name()
        )));
    }
    let iso = iso_raw(field, opts.iso_alpha)?;
    let extent = field.box_max - field.box_min;
    let (spacing, inner) = match opts.resolution {
        Some(n) if n < 4 => {
            return Err(Error::invalid(format!(
                "--resolution {n}: use at least 4 samples along the longest side"
            )))
        }
        Some(n) => {
            let s = extent.max_element() / (n - 1) as f32;
            (s, [0, 1, 2].map(|a| (extent[a] / s).round() as usize + 1))
        }
        None => (field.voxel, field.grid.dims),
    };
    // One empty sample around the box closes surfaces that touch its faces.
    let dims = inner.map(|d| d + 2);
    let origin = field.box_min - Vec3::splat(spacing);
    let [nx, ny, nz] = dims;
    let mut values = vec![EMPTY; nx * ny * nz];
    values
        .par_chunks_mut(nx * ny)
        .enumerate()
        .for_each(|(z, slab)| {
            if z == 0 || z == nz - 1 {
                return;
            }
            for y in 1..ny - 1 {
                for x in 1..nx - 1 {
                    let p = origin + Vec3::new(x as f32, y as f32, z as f32) * spacing;
                    // Sample positions on the far faces may overshoot the box by rounding.
                    let p = p.min(field.box_max);
                    slab[x + nx * y] = raw_at(field, p);
                }
            }
        });
    if !values.iter().any(|&v| v > iso) {
        let max = values.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        let max_alpha = if max <= EMPTY {
            0.0
        } else {
            1.0 - (-crate::field::activation::softplus(max + field.shift())).exp()
        };
        return Err(Error::invalid(format!(
            "the field is empty at iso-level {}: its most opaque voxel reaches alpha {max_alpha:.4}; \
             lower --iso or check the training (masks, box)",
            opts.iso_alpha
        )));
    }
    let cavity_samples_filled = if opts.fill_cavities {
        let seal = SEAL_VOXELS * field.voxel / spacing;
        fill_cavities(&mut values, dims, iso, seal, up.map(GridUp::of))
    } else {
        0
    };
    let grid = marching_cubes(&values, dims, iso);
    let mut mesh = Mesh::from_grid(name, grid, origin.as_dvec3(), DVec3::splat(spacing as f64));
    let pieces_removed = if opts.min_component > 0.0 {
        mesh.remove_small_components(opts.min_component)
    } else {
        0
    };
    if opts.vertex_colours {
        colour_vertices(field, &mut mesh, opts);
    }
    let report = FieldMeshReport {
        sample_dims: dims,
        iso_alpha: opts.iso_alpha,
        iso_raw: iso,
        pieces_removed,
        cavity_samples_filled,
        vertices: mesh.positions.len(),
        triangles: mesh.triangles.len(),
    };
    Ok((mesh, report))
}

/// Each vertex's colour from the training cameras that see it ([`surface_colour`]).
fn colour_vertices(field: &Field, mesh: &mut Mesh, opts: &FieldMeshOptions) {
    let recolour = opts.recolour.map(|r| r.prepare());
    let seen = SeenFrom::with_occlusion(&opts.seen_from, mesh, occlusion_tolerance(field));
    let colors: Vec<[f32; 3]> = mesh
        .positions
        .par_iter()
        .zip(&mesh.normals)
        .map(|(p, n)| {
            let (p, n) = (Vec3::from_array(*p), Vec3::from_array(*n));
            let c = surface_colour(field, p, n, RayReach::ON_SURFACE, &seen);
            recolour.map_or(c, |r| r.apply(c))
        })
        .collect();
    mesh.colors = Some(colors);
}

/// What `objnerf mesh` wrote.
#[derive(Clone, Debug, Serialize)]
pub struct MeshOutput {
    pub path: PathBuf,
    /// The full marching-cubes mesh.
    pub mesh: FieldMeshReport,
    /// From the full mesh to the one written: decimation, atlas, bake, material.
    pub export: ExportReport,
    /// The capture-to-glTF frame with origin and scale (None: a .ply of a model that records
    /// no up direction).
    pub frame: Option<GltfFrame>,
    /// Bounds in the capture's world units (before the glTF frame change).
    pub bounds_min: [f32; 3],
    pub bounds_max: [f32; 3],
    pub seconds: f64,
    pub peak_rss_mib: u64,
}

/// Load a model, mesh it and write the mesh (textured for .glb unless told otherwise; PLY and
/// OBJ carry vertex colours).
pub fn mesh_model(
    model_path: &Path,
    out: &Path,
    name: &str,
    opts: &FieldMeshOptions,
    up: Option<DVec3>,
) -> Result<(Mesh, MeshOutput)> {
    let t = std::time::Instant::now();
    let format = MeshFormat::of(out)?;
    let model = crate::field::io::load_field(model_path)?;
    // The fill uses up where it is known; a model with nothing to mesh says so before a missing
    // up does. PLY keeps the capture's frame: no up direction needed.
    let frame = GltfFrame::for_model(&model, up);
    let up = frame.as_ref().ok().map(|f| DVec3::from_array(f.up));
    let mut opts = opts.clone();
    if opts.seen_from.is_empty() {
        opts.seen_from = view_centres(&model.notes);
    }
    if format != MeshFormat::Glb {
        opts.export.texture = None;
    }
    // A texture holds the colour: the full mesh's own vertex colours would go unused.
    opts.vertex_colours = opts.export.texture.is_none();
    let (full, report) = mesh_field(&model.field, name, &opts, up)
        .map_err(|e| Error::invalid(format!("{}: {e}", model_path.display())))?;
    let (mesh, export) = export_mesh(
        &model.field,
        &full,
        &opts.export,
        &opts.seen_from,
        opts.recolour,
    )
    .map_err(|e| Error::invalid(format!("{}: {e}", model_path.display())))?;
    let frame = match format.needs_frame() {
        true => Some(opts.placement.frame(&frame?, &mesh.positions)?),
        false => frame.ok(),
    };
    super::io::write_mesh(&mesh, frame.as_ref(), out)?;
    let (lo, hi) = mesh.bounds();
    Ok((
        mesh,
        MeshOutput {
            path: out.to_path_buf(),
            mesh: report,
            export,
            frame,
            bounds_min: lo,
            bounds_max: hi,
            seconds: t.elapsed().as_secs_f64(),
            peak_rss_mib: crate::util::mem::peak_rss_mib(),
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::model::FieldConfig;

    /// A ball of soft matter, each voxel 0.3 opaque, so it is opaque only through several voxels
    /// (fur, a partly covered voxel): the default cut finds its surface, the former 0.5 none.
    #[test]
    fn a_surface_opaque_only_over_several_voxels_is_meshed() {
        let dims = [21, 21, 21];
        let cfg = FieldConfig {
            sh_degree: 0,
            alpha_init: 0.01,
            base_voxel: 0.1,
        };
        let mut f = Field::new(cfg, Vec3::splat(-1.0), Vec3::splat(1.0), dims);
        let (soft, air) = (f.raw_for_alpha(0.3, 1.0), f.raw_for_alpha(1e-4, 1.0));
        for v in 0..f.grid.num_vertices() {
            let c = f.grid.vertex_coords(v as u32).map(|x| x as f32 * 0.1 - 1.0);
            let r = Vec3::from(c).length();
            *f.grid.density_mut(v) = if r < 0.6 { soft } else { air };
        }
        let opts = FieldMeshOptions::default();
        let (mesh, report) = mesh_field(&f, "ball", &opts, Some(DVec3::Z)).unwrap();
        assert!(report.triangles > 100, "{report:?}");
        let (lo, hi) = mesh.bounds();
        assert!((hi[0] - lo[0] - 1.2).abs() < 0.2, "{lo:?} {hi:?}");
        let old = FieldMeshOptions {
            iso_alpha: 0.5,
            ..opts
        };
        assert!(mesh_field(&f, "ball", &old, Some(DVec3::Z)).is_err());
    }
}
