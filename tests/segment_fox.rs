//! fox (50 real phone photos): one click on the head in 0001.jpg, masks for every view.
//!
//! Ignored by default: COLMAP's matching of fox takes 5-15 minutes on a 2-core machine. Run it
//! with `cargo test --release --test segment_fox -- --ignored --nocapture`; set
//! `OBJNERF_FOX_SFM=DIR` to reuse a model made by
//! `objnerf sfm ../shared/data/fox/transforms.json --out DIR --downscale 2 --max-features 4096`.
//! fox has no truth masks: the test checks what can be checked without them (every view ok,
//! none tiny or the background) and leaves the contact sheet for a person to look at.
mod common;

use std::path::PathBuf;

#[test]
#[ignore = "COLMAP on fox takes 5-15 minutes; run with --ignored"]
fn fox_head_from_one_click_in_every_view() {
    let Some(fox) = common::shared_data("fox") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let sfm = match std::env::var_os("OBJNERF_FOX_SFM") {
        Some(p) => PathBuf::from(p),
        None => {
            let out = dir.path().join("fox_sfm");
            common::sfm(&fox.join("transforms.json"), &out);
            out
        }
    };
    let seg = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("fox_seg");
    common::objnerf_ok(&[
        "segment",
        sfm.to_str().unwrap(),
        "--view",
        "0001.jpg",
        "--object",
        "fox",
        "--point",
        "660,700",
        "--out",
        seg.to_str().unwrap(),
        "--overwrite",
    ]);
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(seg.join("report.json")).unwrap()).unwrap();
    let views = report["objects"][0]["views"].as_array().unwrap();
    assert_eq!(views.len(), 50);
    let mut problems = vec![];
    for v in views {
        let name = v["view"].as_str().unwrap();
        let mask = image::open(seg.join("masks/fox").join(name).with_extension("png"))
            .unwrap()
            .to_luma8();
        let fraction = mask.pixels().filter(|p| p[0] > 127).count() as f64 / mask.len() as f64;
        println!(
            "{name} {} coverage {:.2} mask {:.0}% of the image, {} prompts ({} projected)",
            v["status"],
            v["expected_coverage"],
            100.0 * fraction,
            v["num_prompts"],
            v["num_projected"]
        );
        // Close-ups fill most of the frame; more than 90% would be the wall.
        if v["status"] != "ok" || !(0.02..0.9).contains(&fraction) {
            problems.push(name.to_string());
        }
    }
    println!(
        "contact sheet: {}",
        seg.join("contact_sheet_fox.png").display()
    );
    assert!(problems.is_empty(), "views not segmented: {problems:?}");
}
