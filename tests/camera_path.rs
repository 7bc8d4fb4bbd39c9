//! nerfstudio camera paths: written then read gives the same cameras, a path in the viewer's frame
//! (with its dataparser_transforms.json) gives the cameras of the same path in the data frame,
//! every file states its frame, and bad files are clear errors.

mod common;
mod support;

use glam::{DMat3, DMat4, DVec3};
use objnerf::scene::camera_path::{
    CameraPath, DataparserTransform, FrameName, Orbit, PathCamera, PathFrame, PathLens, FRAME_KEY,
};
use objnerf::scene::{Camera, CameraModel, Pose};
use std::path::Path;

fn orbit() -> CameraPath {
    CameraPath::orbit(&Orbit {
        center: DVec3::new(0.2, -0.1, 0.3),
        radius: 2.5,
        elevation: 0.8,
        up: DVec3::new(0.05, 0.02, 1.0),
        views: 12,
        fov_y_deg: 42.0,
        width: 320,
        height: 240,
        fps: 24.0,
    })
    .unwrap()
}

fn max_diff(a: [[f64; 4]; 3], b: [[f64; 4]; 3]) -> f64 {
    a.iter()
        .flatten()
        .zip(b.iter().flatten())
        .fold(0.0, |m, (x, y)| m.max((x - y).abs()))
}

fn assert_same_cameras(a: &CameraPath, b: &CameraPath, tol: f64) {
    assert_eq!((a.width, a.height, a.lens), (b.width, b.height, b.lens));
    assert_eq!(a.cameras.len(), b.cameras.len());
    for (i, (x, y)) in a.cameras.iter().zip(&b.cameras).enumerate() {
        let d = max_diff(x.pose.c2w_opencv(), y.pose.c2w_opencv());
        assert!(d <= tol, "camera {i}: poses differ by {d:e}");
        assert_eq!(x.camera.model, y.camera.model);
        for (p, q) in x.camera.params.iter().zip(&y.camera.params) {
            assert!(
                (p - q).abs() <= tol * p.abs().max(1.0),
                "camera {i}: {p} vs {q}"
            );
        }
    }
}

#[test]
fn orbit_rings_the_centre() {
    let path = orbit();
    assert_eq!(path.cameras.len(), 12);
    assert!((path.seconds - 0.5).abs() < 1e-12);
    let up = DVec3::new(0.05, 0.02, 1.0).normalize();
    let centre = DVec3::new(0.2, -0.1, 0.3);
    for c in &path.cameras {
        // On the optical axis, in front; at the right height and distance from the up axis.
        let p = c.pose.world_to_camera(centre);
        assert!(p.x.abs() < 1e-12 && p.y.abs() < 1e-12 && p.z > 0.0);
        let off = c.pose.center() - centre;
        assert!((off.dot(up) - 0.8).abs() < 1e-12);
        assert!(((off - off.dot(up) * up).length() - 2.5).abs() < 1e-12);
        // Upright: the image's up (-y in OpenCV) leans towards the world's up.
        assert!(c.pose.camera_to_world_dir(-DVec3::Y).dot(up) > 0.0);
        let (fx, fy) = c.camera.focal();
        assert_eq!(fx, fy);
        assert!((2.0 * (120.0 / fy).atan().to_degrees() - 42.0).abs() < 1e-12);
    }
    // Consecutive cameras are a twelfth of a turn apart, counter-clockwise about up.
    let (a, b) = (
        path.cameras[0].pose.center() - centre,
        path.cameras[1].pose.center() - centre,
    );
    let (a, b) = (a - a.dot(up) * up, b - b.dot(up) * up);
    assert!((a.angle_between(b) - std::f64::consts::TAU / 12.0).abs() < 1e-12);
    assert!(a.cross(b).dot(up) > 0.0);
}

#[test]
fn written_then_read_is_the_same_path() {
    let tmp = tempfile::tempdir().unwrap();
    let file = tmp.path().join("camera_path.json");
    let path = orbit();
    path.write(&file, &PathFrame::Data).unwrap();
    let back = CameraPath::read(&file, &PathFrame::Data).unwrap();
    // Poses exactly (the OpenGL flip is a negation), intrinsics through fov and back.
    for (a, b) in path.cameras.iter().zip(&back.cameras) {
        assert_eq!(a.pose.c2w_opencv(), b.pose.c2w_opencv());
    }
    assert_same_cameras(&path, &back, 1e-12);
    assert_eq!((back.fps, back.seconds), (path.fps, path.seconds));
    // What ns-render and the viewer read is there.
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&file).unwrap()).unwrap();
    assert_eq!(json["camera_type"], "perspective");
    assert_eq!(json["render_height"], 240);
    assert_eq!(json["camera_path"].as_array().unwrap().len(), 12);
    assert_eq!(json["keyframes"].as_array().unwrap().len(), 12);
    assert_eq!(json["camera_path"][3]["camera_to_world"][15], 1.0);
    assert!((json["camera_path"][0]["fov"].as_f64().unwrap() - 42.0).abs() < 1e-12);

    // A fisheye path keeps its lens.
    let mut fish = path.clone();
    fish.lens = PathLens::Fisheye;
    for c in &mut fish.cameras {
        c.camera =
            objnerf::scene::camera_path::path_camera(PathLens::Fisheye, 320, 240, 120.0).unwrap();
    }
    fish.write(&file, &PathFrame::Data).unwrap();
    let back = CameraPath::read(&file, &PathFrame::Data).unwrap();
    assert_same_cameras(&fish, &back, 1e-12);
    assert_eq!(back.cameras[0].camera.model, CameraModel::OpenCvFisheye);
}

#[test]
fn scene_views_as_a_path() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = support::tiny_scene(tmp.path());
    let path = CameraPath::from_scene_views(&scene, 10.0).unwrap();
    assert_eq!(path.cameras.len(), 3);
    assert_eq!((path.width, path.height), (8, 8));
    for (c, im) in path.cameras.iter().zip(&scene.images) {
        assert_eq!(c.pose, im.pose);
        // The vertical field of view is the view's.
        let fy = scene.camera_of(im).focal().1;
        assert!((c.camera.focal().1 - fy).abs() < 1e-12);
    }
    let file = tmp.path().join("views.json");
    path.write(&file, &PathFrame::Data).unwrap();
    assert_same_cameras(
        &path,
        &CameraPath::read(&file, &PathFrame::Data).unwrap(),
        1e-12,
    );
}

/// nerfstudio's colmap applied_transform (x <-> y, z negated) moved, and a dataparser transform
/// that rotates, moves and scales, as `ns-train` would write them.
fn transforms() -> ([[f64; 4]; 3], [[f64; 4]; 3], f64) {
    let applied = [
        [0.0, 1.0, 0.0, 0.25],
        [1.0, 0.0, 0.0, -0.5],
        [0.0, 0.0, -1.0, 1.0],
    ];
    let r = DMat3::from_axis_angle(DVec3::new(0.3, -0.5, 0.8).normalize(), 0.7);
    let t = DVec3::new(0.4, -1.2, 0.35);
    let transform = [0, 1, 2].map(|i| [r.row(i).x, r.row(i).y, r.row(i).z, t[i]]);
    (applied, transform, 0.37)
}

fn mat4(m: &[[f64; 4]; 3]) -> DMat4 {
    DMat4::from_cols_array_2d(&[
        [m[0][0], m[1][0], m[2][0], 0.0],
        [m[0][1], m[1][1], m[2][1], 0.0],
        [m[0][2], m[1][2], m[2][2], 0.0],
        [m[0][3], m[1][3], m[2][3], 1.0],
    ])
}

#[test]
fn viewer_frame_and_data_frame_give_the_same_cameras() {
    let tmp = tempfile::tempdir().unwrap();
    let data_path = orbit();
    let data_file = tmp.path().join("data.json");
    data_path.write(&data_file, &PathFrame::Data).unwrap();
    let (applied, transform, scale) = transforms();
    // dataparser_transforms.json as nerfstudio writes it.
    let dpt_file = tmp.path().join("dataparser_transforms.json");
    let dpt = serde_json::json!({"transform": transform, "scale": scale});
    std::fs::write(&dpt_file, serde_json::to_string_pretty(&dpt).unwrap()).unwrap();
    // The same path as the viewer writes it, computed here from the matrices: original = A^-1 *
    // data, viewer = scale * T * original; the camera's axes turn, its scale is taken out.
    let to_viewer =
        DMat4::from_scale(DVec3::splat(scale)) * mat4(&transform) * mat4(&applied).inverse();
    let mut json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&data_file).unwrap()).unwrap();
    // nerfstudio's viewer states no frame: read in the one the reader is given.
    json.as_object_mut().unwrap().remove(FRAME_KEY);
    for entry in json["camera_path"].as_array_mut().unwrap() {
        let m: Vec<f64> = serde_json::from_value(entry["camera_to_world"].clone()).unwrap();
        let c2w = DMat4::from_cols_array(&m.try_into().unwrap()).transpose();
        let mut v = to_viewer * c2w;
        for axis in [&mut v.x_axis, &mut v.y_axis, &mut v.z_axis] {
            *axis /= scale;
        }
        entry["camera_to_world"] = serde_json::json!(v.transpose().to_cols_array());
    }
    let viewer_file = tmp.path().join("viewer.json");
    std::fs::write(&viewer_file, serde_json::to_string(&json).unwrap()).unwrap();

    let frame = PathFrame::Viewer(DataparserTransform::read(&dpt_file, Some(applied)).unwrap());
    let from_viewer = CameraPath::read(&viewer_file, &frame).unwrap();
    let from_data = CameraPath::read(&data_file, &PathFrame::Data).unwrap();
    assert_same_cameras(&from_data, &from_viewer, 1e-6);
    // And our writer's viewer frame is the viewer's.
    let ours = tmp.path().join("ours.json");
    data_path.write(&ours, &frame).unwrap();
    assert_same_cameras(&data_path, &CameraPath::read(&ours, &frame).unwrap(), 1e-9);
    let ours: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&ours).unwrap()).unwrap();
    assert_eq!(ours[FRAME_KEY], "viewer");
    for (a, b) in ours["camera_path"]
        .as_array()
        .unwrap()
        .iter()
        .zip(json["camera_path"].as_array().unwrap())
    {
        for k in 0..16 {
            let (x, y) = (
                a["camera_to_world"][k].as_f64().unwrap(),
                b["camera_to_world"][k].as_f64().unwrap(),
            );
            assert!((x - y).abs() < 1e-9, "{x} vs {y}");
        }
    }
    // Without the dataset's applied_transform the cameras are elsewhere: it matters.
    let wrong = PathFrame::Viewer(DataparserTransform::read(&dpt_file, None).unwrap());
    let moved = CameraPath::read(&viewer_file, &wrong).unwrap();
    let d = max_diff(
        moved.cameras[0].pose.c2w_opencv(),
        from_data.cameras[0].pose.c2w_opencv(),
    );
    assert!(d > 0.1, "{d}");
}

/// nerfstudio's colmap applied_transform, a quarter turn about z moved by (1, 2, 3) and a scale of
/// 1/2: a camera at (0.2, -0.4, 1) with the data frame's axes is, worked out by hand, at
/// (0.4, 0.8, 1) in the viewer's, its x and z axes reversed.
#[test]
fn a_known_transform_takes_a_camera_to_the_viewer_frame_and_back() {
    let tmp = tempfile::tempdir().unwrap();
    let dpt_file = tmp.path().join("dataparser_transforms.json");
    let quarter_turn = [
        [0.0, -1.0, 0.0, 1.0],
        [1.0, 0.0, 0.0, 2.0],
        [0.0, 0.0, 1.0, 3.0],
    ];
    let json = serde_json::json!({"transform": quarter_turn, "scale": 0.5});
    std::fs::write(&dpt_file, json.to_string()).unwrap();
    let colmap = [
        [0.0, 1.0, 0.0, 0.0],
        [1.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, -1.0, 0.0],
    ];
    let frame = PathFrame::Viewer(DataparserTransform::read(&dpt_file, Some(colmap)).unwrap());
    let pose = Pose::from_c2w_opengl([
        [1.0, 0.0, 0.0, 0.2],
        [0.0, 1.0, 0.0, -0.4],
        [0.0, 0.0, 1.0, 1.0],
    ])
    .unwrap();
    let path = CameraPath::from_poses(64, 48, 30.0, &[(pose, 50.0)]).unwrap();
    let file = tmp.path().join("viewer.json");
    path.write(&file, &frame).unwrap();
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&file).unwrap()).unwrap();
    assert_eq!(json[FRAME_KEY], "viewer");
    let want = [
        -1.0, 0.0, 0.0, 0.4, 0.0, 1.0, 0.0, 0.8, 0.0, 0.0, -1.0, 1.0, 0.0, 0.0, 0.0, 1.0,
    ];
    for (k, w) in want.iter().enumerate() {
        let got = json["camera_path"][0]["camera_to_world"][k]
            .as_f64()
            .unwrap();
        assert!((got - w).abs() < 1e-12, "entry {k}: {got} vs {w}");
    }
    let back = CameraPath::read(&file, &frame).unwrap();
    assert!(max_diff(back.cameras[0].pose.c2w_opengl(), pose.c2w_opengl()) < 1e-12);

    // A whole orbit, data -> viewer -> data, under the tilted transform of `transforms()`.
    let (applied, transform, scale) = transforms();
    let json = serde_json::json!({"transform": transform, "scale": scale});
    std::fs::write(&dpt_file, json.to_string()).unwrap();
    let frame = PathFrame::Viewer(DataparserTransform::read(&dpt_file, Some(applied)).unwrap());
    orbit().write(&file, &frame).unwrap();
    let (back, stated) = CameraPath::read_stated(&file, &frame).unwrap();
    assert_eq!(stated, Some(FrameName::Viewer));
    assert_same_cameras(&orbit(), &back, 1e-9);
}

/// Every file states its frame; a reader follows what a file states, refuses a viewer-frame file
/// without the run's transform and a frame it does not know, naming the file.
#[test]
fn files_state_their_frame_and_unknown_frames_are_errors() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let (applied, transform, scale) = transforms();
    let dpt_file = t.join("dataparser_transforms.json");
    let json = serde_json::json!({"transform": transform, "scale": scale});
    std::fs::write(&dpt_file, json.to_string()).unwrap();
    let viewer = PathFrame::Viewer(DataparserTransform::read(&dpt_file, Some(applied)).unwrap());
    let stated = |file: &Path| -> serde_json::Value {
        serde_json::from_str::<serde_json::Value>(&std::fs::read_to_string(file).unwrap()).unwrap()
            [FRAME_KEY]
            .clone()
    };
    let (data_file, viewer_file) = (t.join("data.json"), t.join("viewer.json"));
    orbit().write(&data_file, &PathFrame::Data).unwrap();
    orbit().write(&viewer_file, &viewer).unwrap();
    assert_eq!(stated(&data_file), "data");
    assert_eq!(stated(&viewer_file), "viewer");

    // A data-frame file is read as data even where the reader could undo a viewer frame.
    let (back, said) = CameraPath::read_stated(&data_file, &viewer).unwrap();
    assert_eq!(said, Some(FrameName::Data));
    assert_same_cameras(&orbit(), &back, 1e-12);
    // A viewer-frame file read where only the data frame is known (as render-edit reads paths).
    let e = CameraPath::read(&viewer_file, &PathFrame::Data)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("viewer.json")
            && e.contains("viewer frame")
            && e.contains("--dataparser-transforms"),
        "{e}"
    );
    for bad in [
        serde_json::json!("world"),
        serde_json::json!("Viewer"),
        serde_json::json!(3),
    ] {
        let shown = bad.to_string();
        let e = read_error(t, "unknown_frame", |j| j[FRAME_KEY] = bad);
        assert!(
            e.contains(&format!("objnerf_frame is {shown}")) && e.contains("does not know"),
            "{e}"
        );
        let file = t.join("unknown_frame.json");
        assert!(CameraPath::read(&file, &viewer).is_err());
    }
}

/// A one-camera path file with `edit` applied to its JSON; returns the read error.
fn read_error(tmp: &Path, name: &str, edit: impl FnOnce(&mut serde_json::Value)) -> String {
    let file = tmp.join(format!("{name}.json"));
    CameraPath::from_poses(64, 48, 30.0, &[(orbit().cameras[0].pose, 50.0)])
        .unwrap()
        .write(&file, &PathFrame::Data)
        .unwrap();
    let mut json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&file).unwrap()).unwrap();
    edit(&mut json);
    std::fs::write(&file, serde_json::to_string(&json).unwrap()).unwrap();
    let e = CameraPath::read(&file, &PathFrame::Data)
        .unwrap_err()
        .to_string();
    assert!(e.contains(&file.display().to_string()), "{e}");
    e
}

#[test]
fn bad_camera_paths_are_clear_errors() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let cam0 = |j: &mut serde_json::Value| j["camera_path"][0].clone();
    let e = read_error(t, "shear", |j| {
        j["camera_path"][0]["camera_to_world"][0] = 2.0.into()
    });
    assert!(
        e.contains("camera_path[0]") && e.contains("not rigid"),
        "{e}"
    );
    let e = read_error(t, "no_width", |j| {
        j.as_object_mut().unwrap().remove("render_width");
    });
    assert!(e.contains("missing key 'render_width'"), "{e}");
    let e = read_error(t, "no_fov", |j| {
        let mut c = cam0(j);
        c.as_object_mut().unwrap().remove("fov");
        j["camera_path"] = serde_json::json!([cam0(j), c]);
    });
    assert!(e.contains("camera_path[1]: missing key 'fov'"), "{e}");
    let e = read_error(t, "no_matrix", |j| {
        j["camera_path"][0]
            .as_object_mut()
            .unwrap()
            .remove("camera_to_world");
    });
    assert!(e.contains("missing key 'camera_to_world'"), "{e}");
    let e = read_error(t, "short", |j| {
        j["camera_path"][0]["camera_to_world"]
            .as_array_mut()
            .unwrap()
            .pop();
    });
    assert!(e.contains("15 numbers, not 16"), "{e}");
    for fov in [0.0, -10.0, 180.0] {
        let e = read_error(t, "fov", |j| j["camera_path"][0]["fov"] = fov.into());
        assert!(e.contains("is not a field of view"), "{e}");
    }
    let e = read_error(t, "type", |j| j["camera_type"] = "orthographic".into());
    assert!(e.contains("unknown camera_type 'orthographic'"), "{e}");
    let e = read_error(t, "panorama", |j| {
        j["camera_type"] = "equirectangular".into()
    });
    assert!(e.contains("panorama"), "{e}");
    let e = read_error(t, "seconds", |j| j["seconds"] = 0.0.into());
    assert!(e.contains("seconds = 0"), "{e}");

    // NaN, as Python's json module writes it.
    let file = t.join("nan.json");
    let good = std::fs::read_to_string(t.join("fov.json")).unwrap();
    std::fs::write(&file, good.replace("180.0", "NaN")).unwrap();
    let e = CameraPath::read(&file, &PathFrame::Data)
        .unwrap_err()
        .to_string();
    assert!(e.contains("nan.json") && e.contains("NaN"), "{e}");

    // A non-rigid dataparser transform.
    let dpt = t.join("dataparser_transforms.json");
    let m = [
        [2.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
    ];
    std::fs::write(
        &dpt,
        serde_json::json!({"transform": m, "scale": 1.0}).to_string(),
    )
    .unwrap();
    let e = DataparserTransform::read(&dpt, None)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("dataparser_transforms.json") && e.contains("uniform scale"),
        "{e}"
    );
}

#[test]
fn paths_a_camera_path_cannot_hold_are_refused_and_nothing_is_written() {
    let tmp = tempfile::tempdir().unwrap();
    let file = tmp.path().join("out.json");
    let mut path = orbit();
    let pose: Pose = path.cameras[0].pose;
    path.cameras.push(PathCamera {
        pose,
        camera: Camera::new(
            CameraModel::OpenCv,
            320,
            240,
            vec![300.0, 300.0, 160.0, 120.0, 0.1, 0.0, 0.0, 0.0],
        )
        .unwrap(),
    });
    let e = path.write(&file, &PathFrame::Data).unwrap_err().to_string();
    assert!(e.contains("camera 12") && e.contains("distortion"), "{e}");
    path.cameras[12].camera = Camera::pinhole(320, 240, 300.0, 300.0, 150.0, 120.0);
    let e = path.write(&file, &PathFrame::Data).unwrap_err().to_string();
    assert!(e.contains("centred principal point"), "{e}");
    assert!(!file.exists());
    assert_eq!(std::fs::read_dir(tmp.path()).unwrap().count(), 0);
}

/// In `t`: a run's dataparser_transforms.json (`transforms()`), the dataset it trained on with its
/// applied_transform, and the viewer frame they make.
fn nerfstudio_run(t: &Path) -> (std::path::PathBuf, std::path::PathBuf, PathFrame) {
    let (applied, transform, scale) = transforms();
    let dpt = t.join("dataparser_transforms.json");
    let json = serde_json::json!({"transform": transform, "scale": scale});
    std::fs::write(&dpt, json.to_string()).unwrap();
    let mut scene = support::tiny_scene(&t.join("data"));
    scene.applied_transform = Some(applied);
    scene.points.iter_mut().for_each(|p| p.track.clear());
    scene.images.iter_mut().for_each(|i| i.features.clear());
    let tf = t.join("data/transforms.json");
    objnerf::scene::formats::nerfstudio::write(&scene, &tf).unwrap();
    let frame = PathFrame::Viewer(DataparserTransform::read(&dpt, Some(applied)).unwrap());
    (dpt, tf, frame)
}

/// `objnerf camera-path` on a path in the viewer's frame, with the run's dataparser_transforms.json
/// and the dataset whose applied_transform nerfstudio applied: it prints the data-frame cameras
/// (1e-6) and writes them as a data-frame path; a bad path is a clear error and writes nothing.
#[test]
fn cli_reads_a_viewer_path_into_the_data_frame() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let (dpt, tf, frame) = nerfstudio_run(t);
    let path = orbit();
    let viewer = t.join("viewer.json");
    path.write(&viewer, &frame).unwrap();

    let out = t.join("data_path.json");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let args = [
        "camera-path".to_string(),
        s(&viewer),
        "--dataparser-transforms".into(),
        s(&dpt),
        "--scene".into(),
        s(&tf),
        "--out".into(),
        s(&out),
        "--json".into(),
    ];
    let o = common::objnerf_ok(&args.iter().map(String::as_str).collect::<Vec<_>>());
    let printed: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(printed["camera_type"], "perspective");
    assert_eq!(printed["cameras"].as_array().unwrap().len(), 12);
    let mut worst = 0.0f64;
    for (c, want) in printed["cameras"]
        .as_array()
        .unwrap()
        .iter()
        .zip(&path.cameras)
    {
        let m: Vec<f64> = serde_json::from_value(c["camera_to_world"].clone()).unwrap();
        let got = [0, 1, 2].map(|r| [m[r * 4], m[r * 4 + 1], m[r * 4 + 2], m[r * 4 + 3]]);
        worst = worst.max(max_diff(got, want.pose.c2w_opengl()));
        let (fx, fy) = want.camera.focal();
        let (cx, cy) = want.camera.principal_point();
        for (k, v) in [("fx", fx), ("fy", fy), ("cx", cx), ("cy", cy)] {
            assert!((c[k].as_f64().unwrap() - v).abs() < 1e-9, "{k}");
        }
        assert_eq!(
            (c["width"].as_u64(), c["height"].as_u64()),
            (Some(320), Some(240))
        );
    }
    assert!(worst < 1e-6, "viewer-frame path read by the CLI: {worst:e}");
    assert_same_cameras(
        &path,
        &CameraPath::read(&out, &PathFrame::Data).unwrap(),
        1e-9,
    );

    // The text summary, and a bad path: an error naming the file, exit 1, no --out written.
    let o = common::objnerf_ok(&["camera-path", &s(&out)]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("12 perspective camera(s) at 320x240"),
        "{text}"
    );
    let bad = t.join("bad.json");
    let mut broken: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    broken["camera_path"][3]["fov"] = (-42.0).into();
    std::fs::write(&bad, broken.to_string()).unwrap();
    let not_written = t.join("never.json");
    let o = std::process::Command::new(common::objnerf_bin())
        .args(["camera-path", &s(&bad), "--out", &s(&not_written)])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        err.contains("bad.json") && err.contains("camera_path[3]: fov = -42"),
        "{err}"
    );
    assert!(!not_written.exists());
}

/// `objnerf camera-path --frame viewer`: a data-frame path (as the Blender add-on writes it) goes
/// to nerfstudio's viewer frame exactly as the library writes it, stating so; `--frame viewer`
/// without the run's transform and a file in an unknown frame are clear errors writing nothing.
#[test]
fn cli_writes_a_data_path_in_the_viewer_frame() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let (dpt, tf, frame) = nerfstudio_run(t);
    let data = t.join("data_path.json");
    orbit().write(&data, &PathFrame::Data).unwrap();

    let s = |p: &Path| p.to_str().unwrap().to_string();
    let out = t.join("viewer_path.json");
    let o = common::objnerf_ok(&[
        "camera-path",
        &s(&data),
        "--dataparser-transforms",
        &s(&dpt),
        "--scene",
        &s(&tf),
        "--out",
        &s(&out),
        "--frame",
        "viewer",
    ]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("read in the data frame, the dataset's own world (as the file states)")
            && text.contains("in nerfstudio's viewer frame"),
        "{text}"
    );
    let library = t.join("library.json");
    orbit().write(&library, &frame).unwrap();
    let read = |p: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
    };
    let (got, want) = (read(&out), read(&library));
    assert_eq!(got[FRAME_KEY], "viewer");
    for (a, b) in got["camera_path"]
        .as_array()
        .unwrap()
        .iter()
        .zip(want["camera_path"].as_array().unwrap())
    {
        for k in 0..16 {
            let (x, y) = (
                a["camera_to_world"][k].as_f64().unwrap(),
                b["camera_to_world"][k].as_f64().unwrap(),
            );
            assert!((x - y).abs() < 1e-12, "{x} vs {y}");
        }
    }
    assert_same_cameras(&orbit(), &CameraPath::read(&out, &frame).unwrap(), 1e-9);

    let fails = |args: &[&str], needle: &str| {
        let o = std::process::Command::new(common::objnerf_bin())
            .args(args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{err}");
        assert!(err.contains(needle), "{err}");
    };
    let never = t.join("never.json");
    fails(
        &[
            "camera-path",
            &s(&data),
            "--out",
            &s(&never),
            "--frame",
            "viewer",
        ],
        "--frame viewer needs the training run's --dataparser-transforms",
    );
    let mut unknown = read(&data);
    unknown[FRAME_KEY] = "dataset".into();
    let unknown_file = t.join("unknown.json");
    std::fs::write(&unknown_file, unknown.to_string()).unwrap();
    fails(
        &["camera-path", &s(&unknown_file), "--out", &s(&never)],
        "unknown.json: ",
    );
    fails(
        &["camera-path", &s(&out), "--out", &s(&never)],
        "viewer frame",
    );
    assert!(!never.exists());
}
