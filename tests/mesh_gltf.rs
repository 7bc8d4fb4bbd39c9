//! Marching cubes → glTF binary, checked by the Khronos glTF-Validator and read back.
mod common;

use objnerf::mesh::{gltf::write_glb, io, marching::marching_cubes, Mesh};

fn sphere_mesh(n: usize) -> Mesh {
    let c = (n - 1) as f32 / 2.0;
    let r = c * 0.7;
    let mut v = vec![0f32; n * n * n];
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let d = ((x as f32 - c).powi(2) + (y as f32 - c).powi(2) + (z as f32 - c).powi(2))
                    .sqrt();
                v[x + n * (y + n * z)] = r - d;
            }
        }
    }
    let grid = marching_cubes(&v, [n, n, n], 0.0);
    let mut m = Mesh::from_grid(
        "sphere",
        grid,
        glam::DVec3::splat(-1.0),
        glam::DVec3::splat(2.0 / (n - 1) as f64),
    );
    m.colors = Some(
        m.positions
            .iter()
            .map(|p| [0.5 + 0.5 * p[0], 0.5 + 0.5 * p[1], 0.5])
            .collect(),
    );
    m
}

#[test]
fn glb_passes_the_khronos_validator_and_loads_back() {
    let mesh = sphere_mesh(40);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sphere.glb");
    write_glb(
        &mesh,
        &path,
        Some(serde_json::json!({"objnerf": {"note": "test"}})),
    )
    .unwrap();
    let report = common::validate_gltf(&path);
    assert_eq!(report["numErrors"], 0, "validator errors: {report}");

    let (doc, buffers, _) = gltf::import(&path).unwrap();
    let gm = doc.meshes().next().unwrap();
    assert_eq!(gm.name(), Some("sphere"));
    assert_eq!(doc.nodes().next().unwrap().name(), Some("sphere"));
    let prim = gm.primitives().next().unwrap();
    let reader = prim.reader(|b| Some(&buffers[b.index()]));
    assert_eq!(
        reader.read_positions().unwrap().count(),
        mesh.positions.len()
    );
    assert_eq!(reader.read_normals().unwrap().count(), mesh.normals.len());
    assert_eq!(
        reader.read_colors(0).unwrap().into_rgb_f32().count(),
        mesh.positions.len()
    );
    assert_eq!(
        reader.read_indices().unwrap().into_u32().count(),
        mesh.triangles.len() * 3
    );

    // PLY and OBJ beside it.
    io::write_ply(&mesh, &dir.path().join("sphere.ply")).unwrap();
    io::write_obj(&mesh, &dir.path().join("sphere.obj")).unwrap();
    let obj = std::fs::read_to_string(dir.path().join("sphere.obj")).unwrap();
    assert_eq!(
        obj.lines().filter(|l| l.starts_with("f ")).count(),
        mesh.triangles.len()
    );
}

#[test]
fn empty_mesh_and_unwritable_path_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let empty = Mesh {
        name: "nothing".into(),
        ..Default::default()
    };
    let err = write_glb(&empty, &dir.path().join("e.glb"), None)
        .unwrap_err()
        .to_string();
    assert!(err.contains("empty"), "{err}");
    assert!(!dir.path().join("e.glb").exists());
    // A path below a regular file cannot be created.
    std::fs::write(dir.path().join("file"), b"x").unwrap();
    let err = write_glb(&sphere_mesh(12), &dir.path().join("file/out.glb"), None)
        .unwrap_err()
        .to_string();
    assert!(err.contains("file"), "{err}");
}

#[test]
fn small_pieces_are_removed() {
    let mut a = sphere_mesh(24);
    let n = a.positions.len() as u32;
    // A lone triangle far away.
    a.positions
        .extend([[5.0, 5.0, 5.0], [5.1, 5.0, 5.0], [5.0, 5.1, 5.0]]);
    a.normals.extend([[0.0, 0.0, 1.0]; 3]);
    a.colors.as_mut().unwrap().extend([[1.0; 3]; 3]);
    a.triangles.push([n, n + 1, n + 2]);
    assert_eq!(a.remove_small_components(0.01), 1);
    assert_eq!(a.positions.len(), n as usize);
    assert!(a.triangles.iter().flatten().all(|&i| i < n));
}
