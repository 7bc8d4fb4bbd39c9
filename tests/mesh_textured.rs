//! `objnerf mesh` writes a decimated, textured, unlit glTF by default: on a field made here (a
//! ball, red above its equator and blue below, SH degree 1 with a view-dependent term), the .glb
//! passes the Khronos validator, holds the texture and the unlit material, keeps the budget and
//! the stated origin and scale; the baked texture's colours are the field's, and drawn by the
//! mesh rasteriser the textured mesh matches the field's own render about as well as the full
//! vertex-coloured mesh does.
mod common;

use glam::Vec3;
use objnerf::field::io::{save, ModelParts, IDENTITY};
use objnerf::field::{Field, FieldConfig, RayCamera, RenderOptions, View};
use objnerf::mesh::colour::view_centres;
use objnerf::mesh::from_field::{mesh_field, FieldMeshOptions};
use objnerf::mesh::raster::masked_psnr;
use objnerf::mesh::textured::{export_mesh, ExportOptions, TextureSize};
use objnerf::scene::{Camera, Pose};
use std::path::Path;
use std::process::Command;

const RADIUS: f32 = 0.3;

fn logit(p: f32) -> f32 {
    (p / (1.0 - p)).ln()
}

/// A ball of radius 0.3 in a 48³ grid: red (z > 0) or blue, plus a view-dependent term along x.
fn ball() -> Field {
    let mut f = Field::new(
        FieldConfig {
            sh_degree: 1,
            alpha_init: 0.01,
            base_voxel: 0.02,
        },
        Vec3::splat(-0.5),
        Vec3::splat(0.5),
        [48, 48, 48],
    );
    let dc = 1.0 / 0.282_094_8;
    for v in 0..f.grid.num_vertices() {
        let g = f.grid.vertex_coords(v as u32);
        let p = f.box_min + Vec3::new(g[0] as f32, g[1] as f32, g[2] as f32) * f.voxel;
        *f.grid.density_mut(v) = if p.length() < RADIUS { 8.0 } else { -20.0 };
        let rgb = if p.z > 0.0 {
            [0.85, 0.1, 0.1]
        } else {
            [0.1, 0.15, 0.8]
        };
        let c = f.grid.colour_mut(v);
        for k in 0..3 {
            // SH degree 1: 4 coefficients per channel; a small term along x.
            c[k * 4] = logit(rgb[k]) * dc;
            c[k * 4 + 3] = 0.5;
        }
    }
    f
}

fn ring_cameras() -> Vec<RayCamera> {
    (0..12)
        .map(|i| {
            let a = i as f64 * std::f64::consts::TAU / 12.0;
            let eye = glam::DVec3::new(2.0 * a.cos(), 2.0 * a.sin(), 0.8 * (i % 3) as f64 - 0.8);
            let pose = Pose::look_at(eye, glam::DVec3::ZERO, glam::DVec3::Z);
            RayCamera::new(
                format!("v{i}"),
                Camera::pinhole(96, 96, 120.0, 120.0, 48.0, 48.0),
                pose,
            )
        })
        .collect()
}

fn save_ball(path: &Path, cams: &[RayCamera]) -> Field {
    let f = ball();
    let centres: Vec<[f32; 3]> = cams.iter().map(|c| c.center().to_array()).collect();
    save(
        path,
        &ModelParts {
            field: &f,
            final_dims: [48, 48, 48],
            world_transform: IDENTITY,
            train: None,
            step: 0,
            adam: None,
            net_adam: None,
            notes: serde_json::json!({"kind": "object", "up": [0.0, 0.0, 1.0], "up_why": "test",
                                      "view_centres": centres}),
        },
    )
    .unwrap();
    f
}

fn mesh(args: &[&str]) -> (bool, String) {
    let out = Command::new(common::objnerf_bin())
        .arg("mesh")
        .args(args)
        .output()
        .unwrap();
    let text =
        String::from_utf8_lossy(&out.stdout).to_string() + &String::from_utf8_lossy(&out.stderr);
    (out.status.success(), text)
}

#[test]
fn mesh_writes_a_textured_unlit_glb_at_the_stated_scale() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("ball.objf");
    save_ball(&model, &ring_cameras());
    let glb = dir.path().join("ball.glb");
    let m = model.to_str().unwrap();
    let (ok, out) = mesh(&[
        m,
        "--out",
        glb.to_str().unwrap(),
        "--triangles",
        "800",
        "--texture",
        "256",
        "--height",
        "1.5",
    ]);
    assert!(ok, "{out}");
    let v = common::validate_gltf(&glb);
    assert_eq!(v["numErrors"], 0, "{v}");
    assert_eq!(v["info"]["extensionsUsed"][0], "KHR_materials_unlit", "{v}");
    assert_eq!(v["info"]["hasTextures"], true, "{v}");

    let (doc, buffers, images) = gltf::import(&glb).unwrap();
    let prim = doc.meshes().next().unwrap().primitives().next().unwrap();
    assert!(prim.material().unlit());
    let tex = prim
        .material()
        .pbr_metallic_roughness()
        .base_color_texture()
        .expect("a base-colour texture");
    let img = &images[tex.texture().source().index()];
    assert_eq!((img.width, img.height), (256, 256));
    let r = prim.reader(|b| Some(&buffers[b.index()]));
    let pos: Vec<[f32; 3]> = r.read_positions().unwrap().collect();
    let uvs: Vec<[f32; 2]> = r.read_tex_coords(0).unwrap().into_f32().collect();
    let tris = r.read_indices().unwrap().into_u32().count() / 3;
    assert!(tris <= 800 && tris > 400, "{tris}");
    assert!(r.read_colors(0).is_none());

    // +Y up, origin at the base, 1.5 m tall.
    let (lo, hi) = pos
        .iter()
        .fold(([f32::MAX; 3], [f32::MIN; 3]), |(l, h), p| {
            (
                [0, 1, 2].map(|k| l[k].min(p[k])),
                [0, 1, 2].map(|k| h[k].max(p[k])),
            )
        });
    assert!(
        lo[1].abs() < 1e-4 && (hi[1] - 1.5).abs() < 1e-3,
        "{lo:?} {hi:?}"
    );
    assert!((lo[0] + hi[0]).abs() < 1e-3 && (lo[2] + hi[2]).abs() < 1e-3);
    let extras = doc
        .nodes()
        .next()
        .unwrap()
        .extras()
        .as_ref()
        .unwrap()
        .get()
        .to_string();
    assert!(
        extras.contains("\"origin\":\"base\"") && extras.contains("metres"),
        "{extras}"
    );

    // The texture at each vertex: red in the upper half (glTF +Y), blue in the lower.
    let (mut right, mut total) = (0, 0);
    for (p, uv) in pos.iter().zip(&uvs) {
        let x = ((uv[0] * 256.0) as u32).min(255);
        let y = ((uv[1] * 256.0) as u32).min(255);
        let c = &img.pixels[3 * (x + 256 * y) as usize..][..3];
        let mid = 0.75;
        if (p[1] - mid).abs() < 0.1 {
            continue; // the equator, where the colours meet
        }
        total += 1;
        let red = c[0] > c[2];
        right += usize::from(red == (p[1] > mid));
    }
    assert!(right as f64 > 0.97 * total as f64, "{right} of {total}");

    // Vertex colours and a lit material by flag; the full mesh.
    let glb2 = dir.path().join("vc.glb");
    let (ok, out) = mesh(&[
        m,
        "--out",
        glb2.to_str().unwrap(),
        "--vertex-colours",
        "--material",
        "pbr",
        "--full",
        "--origin",
        "capture",
    ]);
    assert!(ok, "{out}");
    let v = common::validate_gltf(&glb2);
    assert_eq!(v["numErrors"], 0, "{v}");
    let (doc, buffers, images) = gltf::import(&glb2).unwrap();
    assert!(images.is_empty());
    let prim = doc.meshes().next().unwrap().primitives().next().unwrap();
    assert!(!prim.material().unlit());
    let r = prim.reader(|b| Some(&buffers[b.index()]));
    assert!(r.read_colors(0).is_some() && r.read_tex_coords(0).is_none());
    let full_tris = r.read_indices().unwrap().into_u32().count() / 3;
    assert!(full_tris > 5 * 800, "{full_tris}");
}

#[test]
fn the_textured_mesh_draws_like_the_field() {
    let cams = ring_cameras();
    let dir = tempfile::tempdir().unwrap();
    let field = save_ball(&dir.path().join("b.objf"), &cams);
    let model = objnerf::field::io::load_field(&dir.path().join("b.objf")).unwrap();
    // The field drawn from three new directions is the target; its alpha is the mask.
    let views: Vec<View> = [(0.3, 0.4), (2.0, -0.3), (4.0, 0.1)]
        .iter()
        .map(|&(a, z): &(f64, f64)| {
            let eye = glam::DVec3::new(2.0 * a.cos(), 2.0 * a.sin(), z);
            let pose = Pose::look_at(eye, glam::DVec3::ZERO, glam::DVec3::Z);
            let cam = Camera::pinhole(96, 96, 120.0, 120.0, 48.0, 48.0);
            let rc = RayCamera::new("t".into(), cam.clone(), pose);
            let r =
                objnerf::field::eval::render_view(&field, &RenderOptions::default(), &rc, [0.0; 3]);
            let rgba = r
                .rgb
                .iter()
                .zip(&r.alpha)
                .map(|(c, a)| {
                    let c = c.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8);
                    [c[0], c[1], c[2], if *a > 0.99 { 255 } else { 0 }]
                })
                .collect();
            View::new("t".into(), cam, pose, rgba)
        })
        .collect();
    let opts = FieldMeshOptions {
        seen_from: view_centres(&model.notes),
        ..Default::default()
    };
    assert_eq!(opts.seen_from.len(), cams.len());
    let (full, _) = mesh_field(&field, "b", &opts, Some(glam::DVec3::Z)).unwrap();
    let full_psnr = masked_psnr(&full, &views);
    let textured_opts = FieldMeshOptions {
        export: ExportOptions {
            max_triangles: Some(full.triangles.len() / 5),
            fraction_of_full: None,
            texture: Some(TextureSize::Side(512)),
            ..Default::default()
        },
        ..opts
    };
    let (textured, report) = export_mesh(
        &field,
        &full,
        &textured_opts.export,
        &textured_opts.seen_from,
        None,
    )
    .unwrap();
    assert!(textured.triangles.len() <= full.triangles.len() / 5);
    let tex_psnr = masked_psnr(&textured, &views);
    println!(
        "full mesh {} triangles {full_psnr:.2} dB; textured {} triangles {tex_psnr:.2} dB ({:?})",
        full.triangles.len(),
        textured.triangles.len(),
        report.atlas
    );
    assert!(full_psnr > 25.0, "{full_psnr}");
    assert!(tex_psnr > full_psnr - 0.5, "{tex_psnr} vs {full_psnr}");
}
