//! `objnerf mesh`: marching cubes on a trained model, decimated and textured.

use clap::Args;
use glam::DVec3;
use objnerf::edit::Recolour;
use objnerf::mesh::frame::{Origin, Placement};
use objnerf::mesh::from_field::{mesh_model, FieldMeshOptions};
use objnerf::mesh::textured::{ExportOptions, TextureSize};
use objnerf::mesh::Shading;
use objnerf::{Error, Result};
use std::path::PathBuf;

/// How the written mesh is made (shared by `mesh` and `extract`).
#[derive(Args, Debug)]
pub struct MeshExportArgs {
    /// Triangle budget: the mesh is decimated to at most this many triangles (default: a fifth
    /// of the marching-cubes mesh, at most 100 000).
    #[arg(long, conflicts_with = "full")]
    pub triangles: Option<usize>,
    /// Keep the full marching-cubes mesh (no decimation).
    #[arg(long)]
    pub full: bool,
    /// Side of the baked base-colour texture in pixels (.glb), or auto: texels of half the
    /// field's finest voxel, a power of two from 512 to 4096.
    #[arg(long, default_value = "auto")]
    pub texture: String,
    /// Vertex colours instead of a UV atlas and baked texture.
    #[arg(long)]
    pub vertex_colours: bool,
    /// The glTF material: unlit (KHR_materials_unlit: the colour as captured) or pbr (lit by
    /// the viewer).
    #[arg(long, default_value = "unlit")]
    pub material: String,
    /// Metres per capture unit (the glTF is then in metres).
    #[arg(long, conflicts_with = "height")]
    pub scale: Option<f64>,
    /// The object's height along up in metres: sets the scale.
    #[arg(long)]
    pub height: Option<f64>,
}

impl MeshExportArgs {
    pub fn export(&self) -> Result<ExportOptions> {
        let shading = match self.material.to_ascii_lowercase().as_str() {
            "unlit" => Shading::Unlit,
            "pbr" => Shading::Pbr,
            m => {
                return Err(Error::invalid(format!(
                    "--material {m}: expected unlit or pbr"
                )))
            }
        };
        let defaults = ExportOptions::default();
        Ok(ExportOptions {
            // A budget asked for in triangles is that budget; none: the default's (a fifth of
            // the full mesh, at most 100 000).
            max_triangles: match self.full {
                true => None,
                false => self.triangles.or(defaults.max_triangles),
            },
            fraction_of_full: match self.triangles {
                Some(_) => None,
                None => defaults.fraction_of_full,
            },
            texture: match self.vertex_colours {
                true => None,
                false => Some(TextureSize::parse(&self.texture)?),
            },
            shading,
            ..defaults
        })
    }

    pub fn placement(&self, origin: Origin) -> Placement {
        Placement {
            origin,
            metres_per_unit: self.scale,
            height_metres: self.height,
        }
    }
}

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
    #[arg(long, default_value_t = FieldMeshOptions::default().iso_alpha)]
    pub iso: f32,
    /// Drop pieces with fewer triangles than this fraction of the largest (0 keeps all).
    #[arg(long, default_value_t = FieldMeshOptions::default().min_component)]
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
    /// Recolour the vertex colours as render-edit does: a target '#RRGGBB' (hue and chroma
    /// taken, OKLab lightness kept) or 'hue:DEGREES' (a hue rotation).
    #[arg(long)]
    pub recolour: Option<String>,
    /// How far to recolour (0..1).
    #[arg(long, default_value_t = 1.0, requires = "recolour")]
    pub recolour_strength: f32,
    #[command(flatten)]
    pub export: MeshExportArgs,
    /// The glTF origin: base (the object stands at 0), centre, or capture (the capture's own).
    #[arg(long, default_value = "base")]
    pub origin: String,
    /// Print what was written as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Parse `--up`.
fn parse_up(s: &str) -> Result<Option<DVec3>> {
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
            recolour: self
                .recolour
                .as_deref()
                .map(|r| Recolour::from_spec(r, self.recolour_strength))
                .transpose()
                .map_err(|e| Error::invalid(format!("--recolour: {e}")))?,
            seen_from: Vec::new(),
            vertex_colours: true,
            export: self.export.export()?,
            placement: self.export.placement(Origin::parse(&self.origin)?),
        };
        let (_, out) = mesh_model(&self.model, &self.out, &name, &opts, up)?;
        if self.json {
            super::print_json(&out);
        }
        let r = &out.mesh;
        let e = &out.export;
        println!(
            "{}: {} vertices, {} triangles (full mesh {} triangles: grid {}x{}x{}, iso alpha {}, {} small pieces removed)",
            out.path.display(),
            e.vertices,
            e.triangles,
            r.triangles,
            r.sample_dims[0],
            r.sample_dims[1],
            r.sample_dims[2],
            r.iso_alpha,
            r.pieces_removed
        );
        if let Some(a) = &e.atlas {
            println!(
                "texture: {0}x{0} px, {1} charts, {2:.0}% of texels used",
                a.size,
                a.charts,
                100.0 * a.utilization
            );
        }
        if let Some(frame) = &out.frame {
            println!(
                "frame: {}; origin {:?}, units: {}",
                frame.why, frame.origin, frame.units
            );
        }
        println!("{:.1} s, peak memory {} MiB", out.seconds, out.peak_rss_mib);
        Ok(())
    }
}
