//! glTF 2.0 binary (.glb) output: one mesh (POSITION, NORMAL, optional COLOR_0 or TEXCOORD_0 with
//! its base-colour texture as an embedded PNG, u32 indices) on a named node, built as a
//! `gltf_json::Root` and packed into the GLB container. The material is unlit
//! (`KHR_materials_unlit`) or a rough non-metal, as the mesh's [`Shading`] says.

use super::{Mesh, Shading};
use crate::error::{Error, Result};
use gltf_json as json;
use json::validation::Checked::Valid;
use json::validation::USize64;
use std::borrow::Cow;
use std::path::Path;

/// Write `mesh` (already in glTF's +Y-up frame) as a .glb. `extras` (JSON) is stored on the node,
/// e.g. the capture-to-glTF transform.
pub fn write_glb(mesh: &Mesh, path: &Path, extras: Option<serde_json::Value>) -> Result<()> {
    write_glbs(std::slice::from_ref(mesh), path, extras)
}

/// Write several meshes (already in glTF's frame) into one .glb, one named node each, all
/// carrying `extras`.
pub fn write_glbs(meshes: &[Mesh], path: &Path, extras: Option<serde_json::Value>) -> Result<()> {
    if meshes.is_empty() {
        return Err(Error::invalid(format!(
            "{}: no mesh to write",
            path.display()
        )));
    }
    if let Some(mesh) = meshes.iter().find(|m| m.triangles.is_empty()) {
        return Err(Error::invalid(format!(
            "{}: the mesh '{}' is empty, nothing to write",
            path.display(),
            mesh.name
        )));
    }
    let bytes = glb_bytes(meshes, extras)
        .map_err(|e| Error::format(path, format!("cannot build glTF: {e}")))?;
    crate::util::atomic::write_bytes_atomic(path, &bytes)
}

/// A glTF document and its binary chunk, built up one mesh at a time.
struct GlbBuilder {
    root: json::Root,
    bin: Vec<u8>,
    buffer: json::Index<json::Buffer>,
}

impl GlbBuilder {
    fn new() -> Self {
        let mut root = json::Root::default();
        root.asset.generator = Some(format!("objnerf {}", env!("CARGO_PKG_VERSION")));
        let buffer = root.push(json::Buffer {
            byte_length: USize64(0),
            extensions: None,
            extras: Default::default(),
            name: None,
            uri: None,
        });
        GlbBuilder {
            root,
            bin: Vec::new(),
            buffer,
        }
    }

    /// Append `data` to the binary chunk (4-byte aligned) as a buffer view.
    fn view(
        &mut self,
        data: &[u8],
        target: json::buffer::Target,
    ) -> json::Index<json::buffer::View> {
        pad_to_4(&mut self.bin, 0);
        let offset = self.bin.len();
        self.bin.extend_from_slice(data);
        self.root.push(json::buffer::View {
            buffer: self.buffer,
            byte_length: USize64(data.len() as u64),
            byte_offset: Some(USize64(offset as u64)),
            byte_stride: None,
            extensions: None,
            extras: Default::default(),
            name: None,
            target: Some(Valid(target)),
        })
    }

    /// A vertex attribute of 3-vectors, with its bounds when given (glTF requires them on
    /// POSITION).
    fn vec3s(
        &mut self,
        v: &[[f32; 3]],
        bounds: Option<([f32; 3], [f32; 3])>,
    ) -> json::Index<json::Accessor> {
        let bytes: Vec<u8> = v.iter().flatten().flat_map(|x| x.to_le_bytes()).collect();
        let view = self.view(&bytes, json::buffer::Target::ArrayBuffer);
        self.accessor(
            view,
            v.len(),
            json::accessor::Type::Vec3,
            json::accessor::ComponentType::F32,
            bounds.map(|(lo, hi)| (serde_json::json!(lo), serde_json::json!(hi))),
        )
    }

    fn indices(&mut self, triangles: &[[u32; 3]]) -> json::Index<json::Accessor> {
        let bytes: Vec<u8> = triangles
            .iter()
            .flatten()
            .flat_map(|i| i.to_le_bytes())
            .collect();
        let view = self.view(&bytes, json::buffer::Target::ElementArrayBuffer);
        self.accessor(
            view,
            triangles.len() * 3,
            json::accessor::Type::Scalar,
            json::accessor::ComponentType::U32,
            None,
        )
    }

    fn accessor(
        &mut self,
        view: json::Index<json::buffer::View>,
        count: usize,
        ty: json::accessor::Type,
        ct: json::accessor::ComponentType,
        bounds: Option<(serde_json::Value, serde_json::Value)>,
    ) -> json::Index<json::Accessor> {
        let (min, max) = bounds.unzip();
        self.root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: None,
            count: USize64(count as u64),
            component_type: Valid(json::accessor::GenericComponentType(ct)),
            extensions: None,
            extras: Default::default(),
            type_: Valid(ty),
            min,
            max,
            name: None,
            normalized: false,
            sparse: None,
        })
    }

    /// A 2-vector vertex attribute (texture coordinates).
    fn vec2s(&mut self, v: &[[f32; 2]]) -> json::Index<json::Accessor> {
        let bytes: Vec<u8> = v.iter().flatten().flat_map(|x| x.to_le_bytes()).collect();
        let view = self.view(&bytes, json::buffer::Target::ArrayBuffer);
        self.accessor(
            view,
            v.len(),
            json::accessor::Type::Vec2,
            json::accessor::ComponentType::F32,
            None,
        )
    }

    /// `img` as a PNG in the binary chunk, with a trilinear, repeating sampler.
    fn texture(
        &mut self,
        img: &image::RgbImage,
        name: &str,
    ) -> std::result::Result<json::Index<json::Texture>, String> {
        let mut png = Vec::new();
        img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .map_err(|e| e.to_string())?;
        pad_to_4(&mut self.bin, 0);
        let offset = self.bin.len();
        self.bin.extend_from_slice(&png);
        // Image data is not a vertex or index buffer: its view has no target.
        let view = self.root.push(json::buffer::View {
            buffer: self.buffer,
            byte_length: USize64(png.len() as u64),
            byte_offset: Some(USize64(offset as u64)),
            byte_stride: None,
            extensions: None,
            extras: Default::default(),
            name: None,
            target: None,
        });
        let image = self.root.push(json::Image {
            buffer_view: Some(view),
            mime_type: Some(json::image::MimeType("image/png".into())),
            name: Some(format!("{name}_base_colour")),
            uri: None,
            extensions: None,
            extras: Default::default(),
        });
        let sampler = self.root.push(json::texture::Sampler {
            mag_filter: Some(Valid(json::texture::MagFilter::Linear)),
            min_filter: Some(Valid(json::texture::MinFilter::LinearMipmapLinear)),
            ..Default::default()
        });
        Ok(self.root.push(json::Texture {
            name: Some(format!("{name}_base_colour")),
            sampler: Some(sampler),
            source: image,
            extensions: None,
            extras: Default::default(),
        }))
    }

    /// The mesh's material: its texture (if any) as base colour; unlit or a rough non-metal.
    fn material(
        &mut self,
        mesh: &Mesh,
        texture: Option<json::Index<json::Texture>>,
    ) -> json::Index<json::Material> {
        let unlit = mesh.shading == Shading::Unlit;
        if unlit {
            let ext = "KHR_materials_unlit".to_string();
            if !self.root.extensions_used.contains(&ext) {
                self.root.extensions_used.push(ext);
            }
        }
        self.root.push(json::Material {
            pbr_metallic_roughness: json::material::PbrMetallicRoughness {
                metallic_factor: json::material::StrengthFactor(0.0),
                base_color_texture: texture.map(|index| json::texture::Info {
                    index,
                    tex_coord: 0,
                    extensions: None,
                    extras: Default::default(),
                }),
                ..Default::default()
            },
            name: Some(format!("{}_material", mesh.name)),
            double_sided: false,
            extensions: unlit.then_some(json::extensions::material::Material {
                unlit: Some(json::extensions::material::Unlit {}),
            }),
            ..Default::default()
        })
    }

    /// One mesh (positions, normals, colours or UVs with a texture, indices, its material) on a
    /// named node.
    fn mesh_node(
        &mut self,
        mesh: &Mesh,
        extras: Option<Box<serde_json::value::RawValue>>,
    ) -> std::result::Result<json::Index<json::Node>, String> {
        let mut attributes = std::collections::BTreeMap::new();
        let pos = self.vec3s(&mesh.positions, Some(mesh.bounds()));
        attributes.insert(Valid(json::mesh::Semantic::Positions), pos);
        let nrm = self.vec3s(&mesh.normals, None);
        attributes.insert(Valid(json::mesh::Semantic::Normals), nrm);
        if let Some(colors) = &mesh.colors {
            // The field's colours are the photos' sRGB values; COLOR_0 is linear.
            let linear: Vec<[f32; 3]> = colors.iter().map(|c| c.map(srgb_to_linear)).collect();
            let col = self.vec3s(&linear, None);
            attributes.insert(Valid(json::mesh::Semantic::Colors(0)), col);
        }
        let mut texture = None;
        if let (Some(uvs), Some(img)) = (&mesh.uvs, &mesh.texture) {
            let uv = self.vec2s(uvs);
            attributes.insert(Valid(json::mesh::Semantic::TexCoords(0)), uv);
            texture = Some(self.texture(img, &mesh.name)?);
        }
        let indices = self.indices(&mesh.triangles);
        let material = self.material(mesh, texture);
        let gmesh = self.root.push(json::Mesh {
            extensions: None,
            extras: Default::default(),
            name: Some(mesh.name.clone()),
            primitives: vec![json::mesh::Primitive {
                attributes,
                extensions: None,
                extras: Default::default(),
                indices: Some(indices),
                material: Some(material),
                mode: Valid(json::mesh::Mode::Triangles),
                targets: None,
            }],
            weights: None,
        });
        Ok(self.root.push(json::Node {
            mesh: Some(gmesh),
            name: Some(mesh.name.clone()),
            extras,
            ..Default::default()
        }))
    }

    /// The scene of `nodes`, packed as a GLB container.
    fn finish(
        mut self,
        nodes: Vec<json::Index<json::Node>>,
    ) -> std::result::Result<Vec<u8>, String> {
        pad_to_4(&mut self.bin, 0);
        self.root.buffers[self.buffer.value()].byte_length = USize64(self.bin.len() as u64);
        let scene = self.root.push(json::Scene {
            extensions: None,
            extras: Default::default(),
            name: None,
            nodes,
        });
        self.root.scene = Some(scene);
        let mut json_bytes = json::serialize::to_string(&self.root)
            .map_err(|e| e.to_string())?
            .into_bytes();
        pad_to_4(&mut json_bytes, b' ');
        let glb = gltf::binary::Glb {
            header: gltf::binary::Header {
                magic: *b"glTF",
                version: 2,
                length: (12 + 8 + json_bytes.len() + 8 + self.bin.len()) as u32,
            },
            json: Cow::Owned(json_bytes),
            bin: Some(Cow::Owned(self.bin)),
        };
        glb.to_vec().map_err(|e| e.to_string())
    }
}

/// sRGB-encoded 0..1 to linear.
pub fn srgb_to_linear(c: f32) -> f32 {
    let c = c.clamp(0.0, 1.0);
    if c <= 0.040_45 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// GLB chunks are 4-byte aligned.
fn pad_to_4(v: &mut Vec<u8>, fill: u8) {
    while v.len() % 4 != 0 {
        v.push(fill);
    }
}

fn glb_bytes(
    meshes: &[Mesh],
    extras: Option<serde_json::Value>,
) -> std::result::Result<Vec<u8>, String> {
    let node_extras = match extras {
        Some(v) => Some(serde_json::value::to_raw_value(&v).map_err(|e| e.to_string())?),
        None => None,
    };
    let mut b = GlbBuilder::new();
    let nodes = meshes
        .iter()
        .map(|m| b.mesh_node(m, node_extras.clone()))
        .collect::<std::result::Result<_, _>>()?;
    b.finish(nodes)
}
