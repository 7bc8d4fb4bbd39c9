//! Two UV unwrappers on the same meshes: `uvunwrap` (pure Rust, the one objnerf uses) and xatlas
//! (C++) through its Python binding, as nerfstudio's `ns-export` runs it (the Rust binding on
//! crates.io, `xatlas-rs` 0.1.3, ships bindings with MSVC-mangled names and does not link on
//! Linux). Each packs one 2048 px page with 8 px padding; measured: wall time, charts, and texel
//! use (the share of the page's texels whose centre lies in a triangle, counted the same way for
//! both).
//!
//!     cargo run --release --example uv_unwrap_compare -- --model runs/demo/run/mug/model.objf
//!
//! The meshes: the model's marching-cubes mesh decimated to a few budgets. Prints a JSON object
//! (kept in `examples/results/textured_mesh.md`).

#[path = "support/bench.rs"]
mod bench;

use bench::{git_commit, machine};
use objnerf::mesh::decimate::decimate;
use objnerf::mesh::from_field::{mesh_field, FieldMeshOptions};
use objnerf::mesh::Mesh;
use std::time::Instant;

const PAGE: u32 = 2048;
const PADDING: u32 = 8;

/// Share of a `PAGE`² page's texel centres inside some triangle of `uv` (0..1 coordinates).
fn texel_use(uv: &[[f32; 2]], tris: &[[u32; 3]]) -> f64 {
    let s = PAGE as usize;
    let mut hit = vec![false; s * s];
    for t in tris {
        let p = t.map(|i| glam::Vec2::from(uv[i as usize]) * PAGE as f32);
        let area = (p[1] - p[0]).perp_dot(p[2] - p[0]);
        if area.abs() < 1e-12 {
            continue;
        }
        let lo = p[0].min(p[1]).min(p[2]);
        let hi = p[0].max(p[1]).max(p[2]);
        for y in (lo.y - 0.5).ceil().max(0.0) as usize..=((hi.y - 0.5).floor() as usize).min(s - 1)
        {
            for x in
                (lo.x - 0.5).ceil().max(0.0) as usize..=((hi.x - 0.5).floor() as usize).min(s - 1)
            {
                let c = glam::Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                let w0 = (p[1] - c).perp_dot(p[2] - c) / area;
                let w1 = (p[2] - c).perp_dot(p[0] - c) / area;
                if w0 >= 0.0 && w1 >= 0.0 && 1.0 - w0 - w1 >= 0.0 {
                    hit[x + s * y] = true;
                }
            }
        }
    }
    hit.iter().filter(|h| **h).count() as f64 / (s * s) as f64
}

fn with_uvunwrap(m: &Mesh) -> serde_json::Value {
    let idx: Vec<u32> = m.triangles.iter().flatten().copied().collect();
    let t = Instant::now();
    let atlas = uvunwrap::generate(
        &[uvunwrap::MeshInput::new(&m.positions, &idx)],
        &uvunwrap::Options {
            density: uvunwrap::Density::Auto { page_size: PAGE },
            padding: PADDING,
            ..Default::default()
        },
    )
    .expect("uvunwrap");
    let secs = t.elapsed().as_secs_f64();
    let o = &atlas.meshes[0];
    let v_scale = atlas.height as f32 / PAGE as f32;
    let uv: Vec<[f32; 2]> = o
        .vertices
        .iter()
        .map(|v| [v.uv[0], v.uv[1] * v_scale])
        .collect();
    let tris: Vec<[u32; 3]> = o
        .indices
        .chunks_exact(3)
        .map(|t| [t[0], t[1], t[2]])
        .collect();
    serde_json::json!({
        "seconds": secs, "charts": atlas.chart_count, "pages": atlas.page_count,
        "texel_use": texel_use(&uv, &tris), "vertices": uv.len(),
    })
}

const XATLAS_PY: &str = r#"
import json, sys, time
import numpy as np
import xatlas
pos = np.fromfile(sys.argv[1], dtype=np.float32).reshape(-1, 3)
idx = np.fromfile(sys.argv[2], dtype=np.uint32).reshape(-1, 3)
page, padding = int(sys.argv[3]), int(sys.argv[4])
t = time.perf_counter()
atlas = xatlas.Atlas()
atlas.add_mesh(pos, idx)
pack = xatlas.PackOptions()
pack.resolution = page
pack.padding = padding
atlas.generate(pack_options=pack)
secs = time.perf_counter() - t
vmap, faces, uvs = atlas[0]
np.asarray(uvs, dtype=np.float32).tofile(sys.argv[5])
np.asarray(faces, dtype=np.uint32).tofile(sys.argv[6])
print(json.dumps({"seconds": secs, "charts": atlas.chart_count, "pages": atlas.atlas_count,
                  "width": atlas.width, "height": atlas.height, "version": xatlas.__version__ if hasattr(xatlas, "__version__") else None}))
"#;

/// xatlas through its Python binding (the one nerfstudio's `ns-export` uses), in a venv under
/// the models dir; time measured inside Python around `Atlas.generate`.
fn with_xatlas(m: &Mesh, py: &std::path::Path, dir: &std::path::Path) -> serde_json::Value {
    let f = |n: &str| dir.join(n);
    let pos: Vec<u8> = m
        .positions
        .iter()
        .flatten()
        .flat_map(|x| x.to_le_bytes())
        .collect();
    let idx: Vec<u8> = m
        .triangles
        .iter()
        .flatten()
        .flat_map(|x| x.to_le_bytes())
        .collect();
    std::fs::write(f("pos.f32"), pos).expect("write");
    std::fs::write(f("idx.u32"), idx).expect("write");
    std::fs::write(f("x.py"), XATLAS_PY).expect("write");
    let o = std::process::Command::new(py)
        .arg(f("x.py"))
        .args([f("pos.f32"), f("idx.u32")])
        .args([PAGE.to_string(), PADDING.to_string()])
        .args([f("uv.f32"), f("faces.u32")])
        .output()
        .expect("python runs");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut r: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    let uv: Vec<[f32; 2]> = std::fs::read(f("uv.f32"))
        .expect("uvs")
        .chunks_exact(8)
        .map(|c| {
            let g = |i: usize| f32::from_le_bytes(c[i..i + 4].try_into().unwrap());
            [g(0), g(4)]
        })
        .collect();
    let tris: Vec<[u32; 3]> = std::fs::read(f("faces.u32"))
        .expect("faces")
        .chunks_exact(12)
        .map(|c| {
            let g = |i: usize| u32::from_le_bytes(c[i..i + 4].try_into().unwrap());
            [g(0), g(4), g(8)]
        })
        .collect();
    // xatlas crops nothing: the page is width x height texels, uvs 0..1 of it.
    let (w, h) = (
        r["width"].as_f64().unwrap_or(0.0),
        r["height"].as_f64().unwrap_or(0.0),
    );
    let scaled: Vec<[f32; 2]> = uv
        .iter()
        .map(|p| {
            [
                p[0] * (w / PAGE as f64) as f32,
                p[1] * (h / PAGE as f64) as f32,
            ]
        })
        .collect();
    r["texel_use"] = serde_json::json!(texel_use(&scaled, &tris));
    r["vertices"] = serde_json::json!(uv.len());
    r
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let model = args
        .iter()
        .position(|a| a == "--model")
        .and_then(|i| args.get(i + 1))
        .ok_or("--model MODEL.objf is required")?;
    let model = objnerf::field::io::load_field(std::path::Path::new(model))?;
    let (full, _) = mesh_field(&model.field, "m", &FieldMeshOptions::default(), None)?;
    let venv = objnerf::models::ModelsDir::from_env()?
        .root
        .join("venvs/bench-xatlas");
    let py = bench::ensure_venv(&venv, "import xatlas, numpy", &["xatlas", "numpy"])?;
    let dir = tempfile::tempdir()?;
    let mut rows = Vec::new();
    for budget in [2_000, 5_000, 20_000, full.triangles.len()] {
        let (m, _) = decimate(&full, Some(budget), 0.0, 0.0)?;
        let a = with_uvunwrap(&m);
        let b = with_xatlas(&m, &py, dir.path());
        eprintln!(
            "{} triangles: uvunwrap {a}\n  xatlas {b}",
            m.triangles.len()
        );
        rows.push(serde_json::json!({"triangles": m.triangles.len(), "uvunwrap": a, "xatlas": b}));
    }
    let out = serde_json::json!({
        "what": format!("UV unwrap of the marching-cubes mesh of a model decimated to budgets: one {PAGE} px page, {PADDING} px padding; texel use = share of texel centres inside a triangle"),
        "machine": machine(),
        "git_commit": git_commit(),
        "rows": rows,
    });
    println!("{}", serde_json::to_string_pretty(&out)?);
    Ok(())
}
