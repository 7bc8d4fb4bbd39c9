//! Plain mesh formats: binary PLY (with normals and colours) and Wavefront OBJ.

use super::frame::GltfFrame;
use super::Mesh;
use crate::error::{Error, Result};
use crate::util::write_atomic;
use std::path::Path;

pub fn write_ply(mesh: &Mesh, path: &Path) -> Result<()> {
    write_atomic(path, |w| {
        writeln!(
            w,
            "ply\nformat binary_little_endian 1.0\ncomment objnerf mesh {}",
            mesh.name
        )?;
        writeln!(w, "element vertex {}", mesh.positions.len())?;
        writeln!(w, "property float x\nproperty float y\nproperty float z")?;
        writeln!(w, "property float nx\nproperty float ny\nproperty float nz")?;
        if mesh.colors.is_some() {
            writeln!(
                w,
                "property uchar red\nproperty uchar green\nproperty uchar blue"
            )?;
        }
        writeln!(
            w,
            "element face {}\nproperty list uchar uint vertex_indices\nend_header",
            mesh.triangles.len()
        )?;
        for (i, p) in mesh.positions.iter().enumerate() {
            for v in p.iter().chain(mesh.normals.get(i).unwrap_or(&[0.0; 3])) {
                w.write_all(&v.to_le_bytes())?;
            }
            if let Some(c) = &mesh.colors {
                w.write_all(&c[i].map(to_u8))?;
            }
        }
        for t in &mesh.triangles {
            w.write_all(&[3])?;
            for i in t {
                w.write_all(&i.to_le_bytes())?;
            }
        }
        Ok(())
    })
}

pub fn write_obj(mesh: &Mesh, path: &Path) -> Result<()> {
    write_atomic(path, |w| {
        writeln!(w, "# objnerf mesh {}\no {}", mesh.name, mesh.name)?;
        for (i, p) in mesh.positions.iter().enumerate() {
            match &mesh.colors {
                Some(c) => writeln!(
                    w,
                    "v {} {} {} {} {} {}",
                    p[0], p[1], p[2], c[i][0], c[i][1], c[i][2]
                )?,
                None => writeln!(w, "v {} {} {}", p[0], p[1], p[2])?,
            }
        }
        for n in &mesh.normals {
            writeln!(w, "vn {} {} {}", n[0], n[1], n[2])?;
        }
        for t in &mesh.triangles {
            let [a, b, c] = t.map(|i| i + 1);
            writeln!(w, "f {a}//{a} {b}//{b} {c}//{c}")?;
        }
        Ok(())
    })
}

/// A colour channel in 0..1 as a byte. The mesh's colours are already sRGB-encoded (the
/// photos' values, [`Mesh::colors`]): encoding them again washed every PLY out.
fn to_u8(c: f32) -> u8 {
    (c.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

/// Read a triangle mesh from a PLY file (positions and faces; normals recomputed).
pub fn read_ply(path: &Path) -> Result<Mesh> {
    let data = crate::scene::formats::ply::read_mesh(path)?;
    let mut m = Mesh {
        name: path
            .file_stem()
            .map(|s| s.to_string_lossy().to_string())
            .unwrap_or_default(),
        positions: data
            .vertices
            .iter()
            .map(|(p, _)| p.as_vec3().to_array())
            .collect(),
        triangles: data.triangles,
        ..Default::default()
    };
    m.compute_normals();
    Ok(m)
}

/// The mesh formats objnerf writes, by file extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MeshFormat {
    /// glTF binary, +Y up.
    Glb,
    /// Wavefront OBJ, +Y up.
    Obj,
    /// PLY, in the capture's own frame.
    Ply,
}

impl MeshFormat {
    /// The format of `path` by its extension, or an error naming the ones there are.
    pub fn of(path: &Path) -> Result<MeshFormat> {
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        match ext.as_str() {
            "glb" => Ok(MeshFormat::Glb),
            "obj" => Ok(MeshFormat::Obj),
            "ply" => Ok(MeshFormat::Ply),
            _ => Err(Error::invalid(format!(
                "{}: unknown mesh format '{ext}' (use .glb, .obj or .ply)",
                path.display()
            ))),
        }
    }

    /// Whether the mesh is turned into glTF's +Y-up frame (PLY keeps the capture's frame).
    pub fn needs_frame(self) -> bool {
        self != MeshFormat::Ply
    }
}

/// Write `mesh` (in the capture's world units) to `path`, its format by extension; `frame` turns
/// it to +Y up for .glb and .obj (it may be `None` for .ply only).
pub fn write_mesh(mesh: &Mesh, frame: Option<&GltfFrame>, path: &Path) -> Result<()> {
    let format = MeshFormat::of(path)?;
    if format == MeshFormat::Ply {
        return write_ply(mesh, path);
    }
    let frame = frame.ok_or_else(|| {
        Error::invalid(format!(
            "{}: a .glb or .obj mesh needs the capture's up direction",
            path.display()
        ))
    })?;
    let mut turned = mesh.clone();
    turned.transform(frame.matrix());
    match format {
        MeshFormat::Glb => super::gltf::write_glb(&turned, path, Some(frame.extras())),
        _ => write_obj(&turned, path),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ply_colours_are_written_as_the_mesh_holds_them() {
        let mesh = Mesh {
            name: "t".into(),
            positions: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            normals: vec![[0.0, 0.0, 1.0]; 3],
            colors: Some(vec![[0.5, 0.0, 1.0]; 3]),
            triangles: vec![[0, 1, 2]],
            ..Default::default()
        };
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.ply");
        write_ply(&mesh, &path).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let body = bytes
            .windows(11)
            .position(|w| w == b"end_header\n")
            .unwrap()
            + 11;
        // The first vertex: 3 floats of position, 3 of normal, then its colour.
        assert_eq!(bytes[body + 24..body + 27], [128, 0, 255]);
    }
}
