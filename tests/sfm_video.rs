//! `objnerf sfm VIDEO`: a phone-style video (H.264 in MP4, yuv420p, 30 fps) made with ffmpeg
//! from the demo scene's ring of views, each view shown for three frames of which two are
//! blurred (as a hand-held camera blurs frames while it moves): the real ffmpeg gives the sharp
//! frame of each view (a few seconds), and, in an ignored test (about 90 s on 2 cores:
//! `cargo test --release --test sfm_video -- --ignored`), COLMAP a registered model of them;
//! bad videos are refused by name.
mod common;

use objnerf::Scene;
use std::path::{Path, PathBuf};
use std::process::Command;

fn have(program: &str, why: &str) -> bool {
    let ok = Command::new(program)
        .arg("-version")
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok {
        common::skip(&format!(
            "{program} is not installed ({why}; scripts/setup installs it)"
        ));
    }
    ok
}

fn ffmpeg(args: &[&str]) {
    let out = Command::new("ffmpeg")
        .args(["-v", "error", "-y"])
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "ffmpeg {}: {}",
        args.join(" "),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// `views` as a video, three frames each: the sharp view at position `k % 3` of view `k`'s
/// three, the other two blurred (Gaussian, sigma 2.5 px). Returns the video frame index of each
/// sharp view.
fn blurred_video(views: &[PathBuf], dir: &Path) -> (PathBuf, Vec<usize>) {
    let frames = dir.join("frames");
    std::fs::create_dir_all(&frames).unwrap();
    let mut sharp = Vec::new();
    for (k, v) in views.iter().enumerate() {
        let img = image::open(v).unwrap().to_rgb8();
        let blurred = image::imageops::blur(&img, 2.5);
        for j in 0..3 {
            let n = 3 * k + j;
            let f = if j == k % 3 {
                sharp.push(n);
                &img
            } else {
                &blurred
            };
            f.save(frames.join(format!("f_{:05}.png", n + 1))).unwrap();
        }
    }
    let video = dir.join("phone.mp4");
    ffmpeg(&[
        "-framerate",
        "30",
        "-i",
        frames.join("f_%05d.png").to_str().unwrap(),
        "-c:v",
        "libx264",
        "-pix_fmt",
        "yuv420p",
        "-crf",
        "18",
        video.to_str().unwrap(),
    ]);
    (video, sharp)
}

fn mean_abs_diff(a: &image::RgbImage, b: &image::RgbImage) -> f64 {
    let s: f64 = a
        .as_raw()
        .iter()
        .zip(b.as_raw())
        .map(|(x, y)| (*x as f64 - *y as f64).abs())
        .sum();
    s / a.as_raw().len() as f64
}

/// The demo's views (`views` of them, at `size`) in name order.
fn demo_views(dir: &Path, views: &str, size: &str) -> Vec<PathBuf> {
    let scene_dir = dir.join("scene");
    common::objnerf_ok(&[
        "demo-scene",
        "--out",
        scene_dir.to_str().unwrap(),
        "--views",
        views,
        "--size",
        size,
    ]);
    let mut views: Vec<PathBuf> = std::fs::read_dir(scene_dir.join("images"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    views.sort();
    views
}

/// Each written frame is its view, not a blurred neighbour.
fn assert_frames_are_the_views(files: &[PathBuf], views: &[PathBuf]) {
    assert_eq!(files.len(), views.len());
    for (file, view) in files.iter().zip(views) {
        let got = image::open(file).unwrap().to_rgb8();
        let view = image::open(view).unwrap().to_rgb8();
        let blurred = image::imageops::blur(&view, 2.5);
        let (d_sharp, d_blur) = (mean_abs_diff(&got, &view), mean_abs_diff(&got, &blurred));
        assert!(
            d_sharp < 0.6 * d_blur,
            "{}: {d_sharp:.2} from its view, {d_blur:.2} from the blurred one",
            file.display()
        );
    }
}

#[test]
fn the_sharp_frame_of_each_window_is_taken() {
    if !have("ffmpeg", "it decodes videos") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let views = demo_views(dir.path(), "12", "320x240");
    let (video, sharp) = blurred_video(&views, dir.path());
    let out = dir.path().join("frames");
    let taken = objnerf::scene::sfm::take_frames(&video, 12, &out, &objnerf::util::Silent).unwrap();
    assert_eq!(taken.summary.frames_in_video, 36);
    let chosen: Vec<usize> = taken.frames.iter().map(|f| f.frame).collect();
    assert_eq!(chosen, sharp);
    assert!(taken.summary.mean_sharpness_chosen > 2.0 * taken.summary.mean_sharpness_all);
    assert_frames_are_the_views(&taken.paths, &views);
    let stages: Vec<&str> = taken.stages.iter().map(|s| s.stage.as_str()).collect();
    assert_eq!(stages, ["frame selection", "frame extraction"]);
    // Fewer frames than asked for: every frame.
    let all = dir.path().join("all");
    let every =
        objnerf::scene::sfm::take_frames(&video, 300, &all, &objnerf::util::Silent).unwrap();
    assert_eq!(every.paths.len(), 36);
}

#[test]
#[ignore = "COLMAP on 24 frames: about 90 s on 2 cores"]
fn phone_style_video_to_a_registered_model_from_its_sharp_frames() {
    if !have("ffmpeg", "it decodes videos") || objnerf::scene::sfm::colmap_program().is_err() {
        common::skip("needs ffmpeg and colmap (scripts/setup installs them)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    // 24 views at 480x360 (72 video frames): about 60 s of COLMAP, most of it matching (18
    // views registered too, but fewer are not sure to find an initial pair).
    let views = demo_views(dir.path(), "24", "480x360");
    let (video, sharp) = blurred_video(&views, dir.path());
    let out = dir.path().join("sfm");
    let run = common::objnerf_ok(&[
        "sfm",
        video.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--frames",
        "24",
        "--max-features",
        "2048",
        "--json",
    ]);
    let report: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    eprintln!(
        "{}",
        serde_json::to_string_pretty(&report["stages"]).unwrap()
    );
    assert_eq!(report["video"]["frames_in_video"], 72, "{report}");
    assert_eq!(report["num_images"], 24, "{report}");
    assert_eq!(report["num_registered"], 24, "{report}");
    let stages: Vec<&str> = report["stages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["stage"].as_str().unwrap())
        .collect();
    assert_eq!(
        stages,
        [
            "frame selection",
            "frame extraction",
            "features",
            "matching",
            "mapping"
        ]
    );
    // The sharp frame of every window was chosen (the blurred ones score far lower) ...
    let listed: Vec<serde_json::Value> =
        serde_json::from_str(&std::fs::read_to_string(out.join("frames.json")).unwrap()).unwrap();
    let chosen: Vec<usize> = listed
        .iter()
        .map(|f| f["frame"].as_u64().unwrap() as usize)
        .collect();
    assert_eq!(chosen, sharp);
    // ... and the files written are those frames.
    let files: Vec<PathBuf> = listed
        .iter()
        .map(|f| out.join("images").join(f["file"].as_str().unwrap()))
        .collect();
    assert_frames_are_the_views(&files, &views);
    // A model of the frames, which live in the output folder (not a link), and its database.
    let model = Scene::load(&out).unwrap();
    assert_eq!(model.images.len(), 24);
    assert!(model.points.len() > 300, "{} points", model.points.len());
    let errs = model.reprojection_errors();
    let mean = errs.iter().sum::<f64>() / errs.len() as f64;
    assert!(mean < 1.0, "mean reprojection error {mean} px");
    assert!(!std::fs::symlink_metadata(out.join("images"))
        .unwrap()
        .file_type()
        .is_symlink());
    assert!(out.join("database.db").is_file());
}

/// `objnerf sfm FILE --out OUT` fails naming FILE with `what`, and leaves nothing behind.
fn refused(file: &Path, what: &str) {
    let dir = file.parent().unwrap();
    let out = dir.join("out");
    let run = Command::new(common::objnerf_bin())
        .args([
            "sfm",
            file.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(!run.status.success());
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(
        err.contains(file.to_str().unwrap()) && err.contains(what),
        "expected '{what}' about {}: {err}",
        file.display()
    );
    assert!(!out.exists(), "nothing half-written");
    let leftovers: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
        .filter(|n| n.contains("objnerf-partial"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

#[test]
fn videos_ffmpeg_cannot_use_are_refused_by_name() {
    if !have("ffmpeg", "it decodes videos") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    // Not a video at all.
    let text = dir.path().join("notes.mp4");
    std::fs::write(&text, "a shopping list, not a video\n").unwrap();
    refused(&text, "ffmpeg cannot read it as a video");
    // Sound only.
    let audio = dir.path().join("sound.m4a");
    ffmpeg(&[
        "-f",
        "lavfi",
        "-i",
        "anullsrc",
        "-t",
        "0.5",
        audio.to_str().unwrap(),
    ]);
    refused(&audio, "no video stream");
    if objnerf::scene::sfm::colmap_program().is_err() {
        // Frames are counted once COLMAP is found and the output claimed.
        common::skip("the frame counts need colmap (scripts/setup installs it)");
        return;
    }
    // A video stream without a frame.
    let empty = dir.path().join("empty.avi");
    blank_video(&empty, 0);
    refused(&empty, "the video has no frames");
    // One frame.
    let one = dir.path().join("one.avi");
    blank_video(&one, 1);
    refused(&one, "one frame");
}

/// A 64x64 blank MPEG-4 video of `frames` frames at `path`.
fn blank_video(path: &std::path::Path, frames: usize) {
    let frames = frames.to_string();
    ffmpeg(&[
        "-f",
        "lavfi",
        "-i",
        "color=s=64x64:d=0.1",
        "-frames:v",
        &frames,
        "-c:v",
        "mpeg4",
        path.to_str().unwrap(),
    ]);
}
