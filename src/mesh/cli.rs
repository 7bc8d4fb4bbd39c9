//! `objnerf mesh MODEL --out mesh.glb`: marching cubes on a trained field, written as glTF
//! binary, PLY or OBJ (by the output's extension).

use super::frame::GltfFrame;
use super::from_field::{mesh_field, FieldMeshOptions, FieldMeshReport};
use super::{gltf::write_glb, io, Mesh};
use crate::error::{Error, Result};
use clap::Args;
use glam::DVec3;
use serde::Serialize;
use std::path::{Path, PathBuf};

#[derive(Args, Debug)]
pub struct MeshCmd {
    /// A model file written by `objnerf train` (or `extract`).
    pub model: PathBuf,
    /// Output: .glb (glTF binary, +Y up), .obj (+Y up) or .ply (the capture's own frame).
    #[arg(long)]
    pub out: PathBuf,
    /// Samples along the box's longest side (default: the field's own grid).
    #[arg(long)]
    pub resolution: Option<usize>,
    /// Surface opacity: where one voxel of material would be this opaque (0..1).
    #[arg(long, default_value_t = 0.5)]
    pub iso: f32,
    /// Drop pieces with fewer triangles than this fraction of the largest (0 keeps all).
    #[arg(long, default_value_t = 0.05)]
    pub min_component: f64,
    /// Keep empty space enclosed by the surface (default: filled, the outer surface of a solid).
    #[arg(long)]
    pub keep_cavities: bool,
    /// The capture's up axis (+x, -x, +y, -y, +z, -z) or 'auto' (from the training scene's cameras).
    #[arg(long, default_value = "auto")]
    pub up: String,
    /// Name of the mesh's node (default: the model file's stem).
    #[arg(long)]
    pub name: Option<String>,
}

/// What `objnerf mesh` wrote.
#[derive(Clone, Debug, Serialize)]
pub struct MeshOutput {
    pub path: PathBuf,
    pub mesh: FieldMeshReport,
    pub frame: GltfFrame,
    /// Bounds in the capture's world units (before the glTF frame change).
    pub bounds_min: [f32; 3],
    pub bounds_max: [f32; 3],
}

/// Parse `--up`.
pub fn parse_up(s: &str) -> Result<Option<DVec3>> {
    Ok(Some(match s.to_ascii_lowercase().as_str() {
        "auto" => return Ok(None),
        "+x" | "x" => DVec3::X,
        "-x" => DVec3::NEG_X,
        "+y" | "y" => DVec3::Y,
        "-y" => DVec3::NEG_Y,
        "+z" | "z" => DVec3::Z,
        "-z" => DVec3::NEG_Z,
        _ => {
            return Err(Error::invalid(format!(
                "--up {s}: expected auto, +x, -x, +y, -y, +z or -z"
            )))
        }
    }))
}

/// The glTF frame for a model: from `up`, else the cameras of the scene it was trained on.
pub fn frame_for_model(model: &crate::field::io::Model, up: Option<DVec3>) -> GltfFrame {
    if let Some(u) = up {
        return GltfFrame::from_up(u, "given with --up".into());
    }
    let scene = model
        .notes
        .get("scene")
        .and_then(|s| s.as_str())
        .map(PathBuf::from);
    match scene.as_deref().map(crate::Scene::load) {
        Some(Ok(s)) => GltfFrame::for_scene(&s),
        _ => GltfFrame::from_up(
            DVec3::Z,
            "the training scene could not be read: assumed +Z up (give --up)".into(),
        ),
    }
}

/// Write `mesh` (in the capture's world units) to `path`, its format by extension.
pub fn write_mesh(mesh: &Mesh, frame: &GltfFrame, path: &Path) -> Result<()> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let mut turned = mesh.clone();
    turned.transform(frame.matrix());
    match ext.as_str() {
        "glb" => write_glb(&turned, path, Some(frame.extras())),
        "obj" => io::write_obj(&turned, path),
        "ply" => io::write_ply(mesh, path),
        _ => Err(Error::invalid(format!(
            "{}: unknown mesh format '{ext}' (use .glb, .obj or .ply)",
            path.display()
        ))),
    }
}

/// Load a model, mesh it and write the mesh.
pub fn mesh_model(
    model_path: &Path,
    out: &Path,
    name: &str,
    opts: &FieldMeshOptions,
    up: Option<DVec3>,
) -> Result<(Mesh, MeshOutput)> {
    let model = crate::field::io::load_field(model_path)?;
    let (mesh, report) = mesh_field(&model.field, name, opts)
        .map_err(|e| Error::invalid(format!("{}: {e}", model_path.display())))?;
    let frame = frame_for_model(&model, up);
    write_mesh(&mesh, &frame, out)?;
    let (lo, hi) = mesh.bounds();
    Ok((
        mesh,
        MeshOutput {
            path: out.to_path_buf(),
            mesh: report,
            frame,
            bounds_min: lo,
            bounds_max: hi,
        },
    ))
}

impl MeshCmd {
    pub fn run(self) -> Result<()> {
        let up = parse_up(&self.up)?;
        let name = self.name.clone().unwrap_or_else(|| {
            self.model
                .file_stem()
                .map(|s| s.to_string_lossy().to_string())
                .unwrap_or_else(|| "object".into())
        });
        let opts = FieldMeshOptions {
            resolution: self.resolution,
            iso_alpha: self.iso,
            min_component: self.min_component,
            fill_cavities: !self.keep_cavities,
        };
        let (_, out) = mesh_model(&self.model, &self.out, &name, &opts, up)?;
        let r = &out.mesh;
        println!(
            "{}: {} vertices, {} triangles (grid {}x{}x{}, iso alpha {}, {} small pieces removed)",
            out.path.display(),
            r.vertices,
            r.triangles,
            r.sample_dims[0],
            r.sample_dims[1],
            r.sample_dims[2],
            r.iso_alpha,
            r.pieces_removed
        );
        println!("frame: {}", out.frame.why);
        Ok(())
    }
}
