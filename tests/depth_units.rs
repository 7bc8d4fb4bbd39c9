//! Every depth file objnerf writes says its unit: 16-bit PNGs in millimetres carry a
//! `depth_unit: mm` text chunk, EXRs in metres a `depthUnit: m` header attribute, and a
//! transforms.json that lists depth says `depth_unit_scale_factor: 0.001` (nerfstudio's own
//! default, so nerfstudio reads the PNGs right without flags). Read back with the png and exr
//! crates, as other tools would.
mod common;

use objnerf::Scene;
use std::path::Path;

fn png_texts(path: &Path) -> Vec<(String, String)> {
    let file = std::io::BufReader::new(std::fs::File::open(path).unwrap());
    let reader = png::Decoder::new(file).read_info().unwrap();
    let info = reader.info();
    assert_eq!(
        (info.color_type, info.bit_depth),
        (png::ColorType::Grayscale, png::BitDepth::Sixteen),
        "{}",
        path.display()
    );
    info.uncompressed_latin1_text
        .iter()
        .map(|t| (t.keyword.clone(), t.text.clone()))
        .collect()
}

fn exr_unit(path: &Path) -> Option<String> {
    let meta = exr::meta::MetaData::read_from_file(path, false).unwrap();
    match meta.headers[0]
        .own_attributes
        .other
        .get(&exr::prelude::Text::from("depthUnit"))
    {
        Some(exr::prelude::AttributeValue::Text(t)) => Some(t.to_string()),
        _ => None,
    }
}

fn mm() -> Vec<(String, String)> {
    vec![("depth_unit".into(), "mm".into())]
}

#[test]
fn demo_truth_and_nerfstudio_export_say_their_depth_unit() {
    let dir = tempfile::tempdir().unwrap();
    let demo = demo_scene(dir.path(), "6", "160x120");
    // The demo's truth depth: PNG (mm) and EXR (m), and its transforms.json.
    let png = demo.join("truth/depth/view_000.png");
    let exr = demo.join("truth/depth/view_000.exr");
    assert_eq!(png_texts(&png), mm());
    assert_eq!(exr_unit(&exr).as_deref(), Some("m"));
    let tf: serde_json::Value =
        serde_json::from_slice(&std::fs::read(demo.join("transforms.json")).unwrap()).unwrap();
    assert_eq!(tf["depth_unit_scale_factor"], 0.001);
    let truth = objnerf::scene::io::read_depth(&exr, 1.0).unwrap();
    // A declared unit wins over the caller's assumption: both read as metres (to the rounding
    // to whole millimetres).
    for scale in [1.0, 1000.0] {
        let d = objnerf::scene::io::read_depth(&png, scale).unwrap();
        let worst = d
            .metres
            .iter()
            .zip(&truth.metres)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        assert!(
            worst <= 0.00051,
            "PNG read with scale {scale}: off by {worst} m"
        );
    }

    // A nerfstudio export: depth/ in millimetres, said in each file and in transforms.json.
    let out = dir.path().join("ns");
    common::objnerf_ok(&[
        "export",
        "nerfstudio",
        demo.join("transforms.json").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let tf: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("transforms.json")).unwrap()).unwrap();
    assert_eq!(tf["depth_unit_scale_factor"], 0.001);
    let frames = tf["frames"].as_array().unwrap();
    assert_eq!(frames.len(), 6);
    for f in frames {
        let p = out.join(f["depth_file_path"].as_str().unwrap());
        assert_eq!(png_texts(&p), mm(), "{}", p.display());
    }
    let scene = Scene::load(&out.join("transforms.json")).unwrap();
    assert_eq!(scene.depth_scale, 1000.0);
    let im = &scene.images[scene.find_image("view_000").unwrap()];
    let d = objnerf::scene::io::read_depth(im.depth_path.as_ref().unwrap(), 1000.0).unwrap();
    let hit = truth.metres.iter().filter(|m| **m > 0.0).count();
    assert!(hit > 1000, "{hit} pixels with depth");
    for (a, b) in d.metres.iter().zip(&truth.metres) {
        assert!((a - b).abs() <= 0.00051, "{a} vs {b}");
    }
}

#[test]
fn a_transforms_json_in_metres_reads_as_metres() {
    let dir = tempfile::tempdir().unwrap();
    let demo = demo_scene(dir.path(), "4", "64x48");
    let path = demo.join("transforms.json");
    let mut tf: serde_json::Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    tf["depth_unit_scale_factor"] = serde_json::json!(1.0);
    std::fs::write(&path, serde_json::to_string(&tf).unwrap()).unwrap();
    assert_eq!(Scene::load(&path).unwrap().depth_scale, 1.0);
    tf["depth_unit_scale_factor"] = serde_json::json!(-2.0);
    std::fs::write(&path, serde_json::to_string(&tf).unwrap()).unwrap();
    let err = Scene::load(&path).unwrap_err().to_string();
    assert!(
        err.contains("transforms.json") && err.contains("depth_unit_scale_factor"),
        "{err}"
    );
}

/// `objnerf demo-scene` of `views` views at `size` in `dir/demo`.
fn demo_scene(dir: &std::path::Path, views: &str, size: &str) -> std::path::PathBuf {
    let demo = dir.join("demo");
    common::objnerf_ok(&[
        "demo-scene",
        "--out",
        demo.to_str().unwrap(),
        "--views",
        views,
        "--size",
        size,
    ]);
    demo
}
