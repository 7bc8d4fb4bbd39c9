//! glTF 2.0 binary (.glb) output: one mesh (POSITION, NORMAL, optional COLOR_0, u32 indices) on a
//! named node, built as a `gltf_json::Root` and packed into the GLB container.

use super::Mesh;
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

fn glb_bytes(
    meshes: &[Mesh],
    extras: Option<serde_json::Value>,
) -> std::result::Result<Vec<u8>, String> {
    let mut bin: Vec<u8> = Vec::new();
    let mut root = json::Root::default();
    root.asset.generator = Some(format!("objnerf {}", env!("CARGO_PKG_VERSION")));
    let buffer = root.push(json::Buffer {
        byte_length: USize64(0),
        extensions: None,
        extras: Default::default(),
        name: None,
        uri: None,
    });

    let view =
        |root: &mut json::Root, bin: &mut Vec<u8>, data: &[u8], target: json::buffer::Target| {
            while bin.len() % 4 != 0 {
                bin.push(0);
            }
            let offset = bin.len();
            bin.extend_from_slice(data);
            root.push(json::buffer::View {
                buffer,
                byte_length: USize64(data.len() as u64),
                byte_offset: Some(USize64(offset as u64)),
                byte_stride: None,
                extensions: None,
                extras: Default::default(),
                name: None,
                target: Some(Valid(target)),
            })
        };
    let f32_bytes =
        |v: &[[f32; 3]]| -> Vec<u8> { v.iter().flatten().flat_map(|x| x.to_le_bytes()).collect() };
    let accessor = |root: &mut json::Root,
                    view: json::Index<json::buffer::View>,
                    count: usize,
                    ty: json::accessor::Type,
                    ct: json::accessor::ComponentType,
                    min: Option<serde_json::Value>,
                    max: Option<serde_json::Value>| {
        root.push(json::Accessor {
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
    };

    let node_extras = match extras {
        Some(v) => Some(serde_json::value::to_raw_value(&v).map_err(|e| e.to_string())?),
        None => None,
    };
    let mut nodes = Vec::new();
    for mesh in meshes {
        let (lo, hi) = mesh.bounds();
        let pv = view(
            &mut root,
            &mut bin,
            &f32_bytes(&mesh.positions),
            json::buffer::Target::ArrayBuffer,
        );
        let pos = accessor(
            &mut root,
            pv,
            mesh.positions.len(),
            json::accessor::Type::Vec3,
            json::accessor::ComponentType::F32,
            Some(serde_json::json!(lo)),
            Some(serde_json::json!(hi)),
        );
        let nv = view(
            &mut root,
            &mut bin,
            &f32_bytes(&mesh.normals),
            json::buffer::Target::ArrayBuffer,
        );
        let nrm = accessor(
            &mut root,
            nv,
            mesh.normals.len(),
            json::accessor::Type::Vec3,
            json::accessor::ComponentType::F32,
            None,
            None,
        );
        let mut attributes = std::collections::BTreeMap::new();
        attributes.insert(Valid(json::mesh::Semantic::Positions), pos);
        attributes.insert(Valid(json::mesh::Semantic::Normals), nrm);
        if let Some(colors) = &mesh.colors {
            let cv = view(
                &mut root,
                &mut bin,
                &f32_bytes(colors),
                json::buffer::Target::ArrayBuffer,
            );
            let col = accessor(
                &mut root,
                cv,
                colors.len(),
                json::accessor::Type::Vec3,
                json::accessor::ComponentType::F32,
                None,
                None,
            );
            attributes.insert(Valid(json::mesh::Semantic::Colors(0)), col);
        }
        let idx: Vec<u8> = mesh
            .triangles
            .iter()
            .flatten()
            .flat_map(|i| i.to_le_bytes())
            .collect();
        let iv = view(
            &mut root,
            &mut bin,
            &idx,
            json::buffer::Target::ElementArrayBuffer,
        );
        let indices = accessor(
            &mut root,
            iv,
            mesh.triangles.len() * 3,
            json::accessor::Type::Scalar,
            json::accessor::ComponentType::U32,
            None,
            None,
        );
        let material = root.push(json::Material {
            pbr_metallic_roughness: json::material::PbrMetallicRoughness {
                metallic_factor: json::material::StrengthFactor(0.0),
                ..Default::default()
            },
            name: Some(format!("{}_material", mesh.name)),
            double_sided: false,
            ..Default::default()
        });
        let gmesh = root.push(json::Mesh {
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
        nodes.push(root.push(json::Node {
            mesh: Some(gmesh),
            name: Some(mesh.name.clone()),
            extras: node_extras.clone(),
            ..Default::default()
        }));
    }
    while bin.len() % 4 != 0 {
        bin.push(0);
    }
    root.buffers[buffer.value()].byte_length = USize64(bin.len() as u64);

    let scene = root.push(json::Scene {
        extensions: None,
        extras: Default::default(),
        name: None,
        nodes,
    });
    root.scene = Some(scene);

    let json_string = json::serialize::to_string(&root).map_err(|e| e.to_string())?;
    let mut json_bytes = json_string.into_bytes();
    while json_bytes.len() % 4 != 0 {
        json_bytes.push(b' ');
    }
    let glb = gltf::binary::Glb {
        header: gltf::binary::Header {
            magic: *b"glTF",
            version: 2,
            length: (12 + 8 + json_bytes.len() + 8 + bin.len()) as u32,
        },
        json: Cow::Owned(json_bytes),
        bin: Some(Cow::Owned(bin)),
    };
    glb.to_vec().map_err(|e| e.to_string())
}
