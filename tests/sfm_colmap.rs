//! `objnerf sfm` against the COLMAP of today: a test double `colmap` that answers as COLMAP 3.13
//! does (only the FeatureExtraction / FeatureMatching option names; issue 52 allows the double)
//! and hands the work to the real COLMAP installed here under the names it knows, and COLMAP's
//! database kept beside the model so that COLMAP itself takes the project up again.
mod common;

use objnerf::Scene;
use std::path::Path;
use std::process::Command;

/// COLMAP 3.13.0's option parser in front of an older COLMAP: `help` says 3.13.0; the options
/// 3.13.0 dropped (colmap PR 3465) are refused as 3.13 refuses them, their new names are
/// passed on under the old ones. Every call is logged.
const DOUBLE: &str = r#"#!/bin/bash
case "$1" in
  help|-h|--help)
    echo "COLMAP 3.13.0 -- Structure-from-Motion and Multi-View Stereo"
    echo "(Commit test double on $(date +%F) without CUDA)"
    exit 0;;
esac
echo "$*" >> "@LOG@"
args=()
for a in "$@"; do
  case "$a" in
    --SiftExtraction.use_gpu|--SiftExtraction.num_threads|--SiftExtraction.gpu_index|\
    --SiftMatching.use_gpu|--SiftMatching.num_threads|--SiftMatching.gpu_index|\
    --SiftMatching.max_num_matches|--SiftMatching.guided_matching)
      echo "Failed to parse options - unrecognised option '$a'" >&2; exit 1;;
    --FeatureExtraction.*) args+=("--SiftExtraction.${a#--FeatureExtraction.}");;
    --FeatureMatching.*) args+=("--SiftMatching.${a#--FeatureMatching.}");;
    *) args+=("$a");;
  esac
done
exec "@REAL@" "${args[@]}"
"#;

fn write_double(dir: &Path, real: &Path, log: &Path) {
    use std::os::unix::fs::PermissionsExt;
    std::fs::create_dir_all(dir).unwrap();
    let script = DOUBLE
        .replace("@LOG@", log.to_str().unwrap())
        .replace("@REAL@", real.to_str().unwrap());
    let path = dir.join("colmap");
    std::fs::write(&path, script).unwrap();
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755)).unwrap();
}

fn keypoints(db: &rusqlite::Connection, image_id: i64) -> Vec<[f64; 2]> {
    let (cols, data): (usize, Vec<u8>) = db
        .query_row(
            "SELECT cols, data FROM keypoints WHERE image_id = ?1",
            [image_id],
            |r| Ok((r.get(0)?, r.get(1)?)),
        )
        .unwrap();
    let v: Vec<f64> = data
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().unwrap()) as f64)
        .collect();
    v.chunks_exact(cols).map(|r| [r[0], r[1]]).collect()
}

/// Sampson distance (px) of a match under F (row-major), x2' F x1 = 0.
fn sampson(f: &[f64], a: [f64; 2], b: [f64; 2]) -> f64 {
    let x1 = [a[0], a[1], 1.0];
    let x2 = [b[0], b[1], 1.0];
    let fx1: Vec<f64> = (0..3)
        .map(|r| (0..3).map(|c| f[3 * r + c] * x1[c]).sum())
        .collect();
    let ftx2: Vec<f64> = (0..3)
        .map(|c| (0..3).map(|r| f[3 * r + c] * x2[r]).sum())
        .collect();
    let num: f64 = (0..3).map(|i| x2[i] * fx1[i]).sum();
    let den = fx1[0].powi(2) + fx1[1].powi(2) + ftx2[0].powi(2) + ftx2[1].powi(2);
    num.abs() / den.sqrt()
}

/// Two-view geometries with a fundamental matrix: the mean Sampson distance of their inlier
/// matches, in pixels of the images the keypoints are in.
fn mean_epipolar_error(db: &rusqlite::Connection) -> (usize, f64) {
    let mut stmt = db
        .prepare(
            "SELECT pair_id, data, F FROM two_view_geometries WHERE rows > 0 AND config IN (2, 3)",
        )
        .unwrap();
    let rows: Vec<(i64, Vec<u8>, Vec<u8>)> = stmt
        .query_map([], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)))
        .unwrap()
        .map(|r| r.unwrap())
        .collect();
    let (mut sum, mut n) = (0.0, 0usize);
    for (pair, data, f) in &rows {
        let (id1, id2) = (pair / i32::MAX as i64, pair % i32::MAX as i64);
        let (k1, k2) = (keypoints(db, id1), keypoints(db, id2));
        let f: Vec<f64> = f
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
            .collect();
        for m in data.chunks_exact(8) {
            let i = u32::from_le_bytes(m[..4].try_into().unwrap()) as usize;
            let j = u32::from_le_bytes(m[4..].try_into().unwrap()) as usize;
            sum += sampson(&f, k1[i], k2[j]);
            n += 1;
        }
    }
    (rows.len(), sum / n.max(1) as f64)
}

#[test]
fn colmap_3_13_option_names_and_the_database_kept_for_its_gui() {
    let Ok(real) = objnerf::scene::sfm::colmap_program() else {
        common::skip("colmap is not installed (scripts/setup installs it)");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let (bin, log) = (dir.path().join("bin"), dir.path().join("double.log"));
    write_double(&bin, &real, &log);
    let scene_dir = dir.path().join("scene");
    // 18 views at 480x360, features found at half size: 25 s on 2 cores.
    common::objnerf_ok(&[
        "demo-scene",
        "--out",
        scene_dir.to_str().unwrap(),
        "--views",
        "18",
        "--size",
        "480x360",
    ]);
    let out = dir.path().join("sfm");
    let path = format!(
        "{}:{}",
        bin.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let run = Command::new(common::objnerf_bin())
        .args(["sfm", scene_dir.join("images").to_str().unwrap()])
        .args(["--out", out.to_str().unwrap(), "--json"])
        .args(["--downscale", "2", "--max-features", "2048"])
        .env("PATH", &path)
        .env_remove("OBJNERF_COLMAP")
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert_eq!(report["colmap_version"], "3.13.0", "{report}");
    assert_eq!(report["num_registered"], 18, "{report}");
    let stages: Vec<&str> = report["stages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["stage"].as_str().unwrap())
        .collect();
    assert_eq!(stages, ["features", "matching", "mapping"]);
    let calls = std::fs::read_to_string(&log).unwrap();
    assert_eq!(calls.lines().count(), 3, "{calls}");
    for name in ["--FeatureExtraction.use_gpu", "--FeatureMatching.use_gpu"] {
        assert!(calls.contains(name), "{name} not passed: {calls}");
    }

    // The database: the model's image names and the original image size.
    let model = Scene::load(&out).unwrap();
    assert_eq!(model.images.len(), 18);
    let db_path = out.join("database.db");
    let db =
        rusqlite::Connection::open_with_flags(&db_path, rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY)
            .unwrap();
    let check: String = db
        .query_row("PRAGMA integrity_check", [], |r| r.get(0))
        .unwrap();
    assert_eq!(check, "ok");
    let mut names: Vec<(i64, String)> = db
        .prepare("SELECT image_id, name FROM images ORDER BY name")
        .unwrap()
        .query_map([], |r| Ok((r.get(0)?, r.get(1)?)))
        .unwrap()
        .map(|r| r.unwrap())
        .collect();
    let mut model_names: Vec<&str> = model.images.iter().map(|im| im.name.as_str()).collect();
    model_names.sort();
    assert_eq!(
        names.iter().map(|(_, n)| n.as_str()).collect::<Vec<_>>(),
        model_names
    );
    let size: (u32, u32) = db
        .query_row("SELECT width, height FROM cameras", [], |r| {
            Ok((r.get(0)?, r.get(1)?))
        })
        .unwrap();
    assert_eq!(size, (480, 360));
    // Keypoints were scaled as the model's features were: COLMAP's model holds every keypoint.
    for (id, name) in names.drain(..) {
        let im = &model.images[model.find_image(&name).unwrap()];
        let kp = keypoints(&db, id);
        assert_eq!(kp.len(), im.features.len(), "{name}");
        for (k, f) in kp.iter().zip(&im.features) {
            let d = ((k[0] - f.xy.x).powi(2) + (k[1] - f.xy.y).powi(2)).sqrt();
            assert!(d < 1e-3, "{name}: keypoint {k:?} vs feature {:?}", f.xy);
        }
    }
    // The fundamental matrices were scaled with them: inliers lie on their epipolar lines.
    let (pairs, err) = mean_epipolar_error(&db);
    eprintln!("{pairs} two-view geometries, mean Sampson distance {err:.3} px at full size");
    assert!(pairs > 20, "{pairs} pairs");
    assert!(err < 1.5, "mean Sampson distance {err} px");
    drop(db);

    // COLMAP takes the project up again: its point triangulator reads the model with the
    // database (it refuses one whose image names differ from the model's).
    let tri = dir.path().join("tri");
    std::fs::create_dir_all(&tri).unwrap();
    let again = Command::new(&real)
        .args(["point_triangulator", "--database_path"])
        .arg(&db_path)
        .arg("--image_path")
        .arg(out.join("images"))
        .arg("--input_path")
        .arg(out.join("sparse/0"))
        .arg("--output_path")
        .arg(&tri)
        .env("QT_QPA_PLATFORM", "offscreen")
        .output()
        .unwrap();
    assert!(
        again.status.success(),
        "{}",
        String::from_utf8_lossy(&again.stderr)
    );
    let retri = objnerf::scene::formats::colmap::read_model(&tri, &out.join("images")).unwrap();
    assert_eq!(retri.images.len(), 18);
    assert!(
        retri.points.len() as f64 > 0.8 * model.points.len() as f64,
        "{} points again, {} before",
        retri.points.len(),
        model.points.len()
    );
}

#[test]
fn an_unknown_colmap_version_is_named() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let bin = dir.path().join("bin");
    std::fs::create_dir_all(&bin).unwrap();
    std::fs::write(bin.join("colmap"), "#!/bin/sh\necho 'usage: colmap'\n").unwrap();
    std::fs::set_permissions(bin.join("colmap"), std::fs::Permissions::from_mode(0o755)).unwrap();
    let imgs = dir.path().join("imgs");
    std::fs::create_dir_all(&imgs).unwrap();
    for i in 0..2 {
        image::RgbImage::new(8, 8)
            .save(imgs.join(format!("{i}.png")))
            .unwrap();
    }
    let out = Command::new(common::objnerf_bin())
        .args(["sfm", imgs.to_str().unwrap(), "--out"])
        .arg(dir.path().join("o"))
        .env("PATH", &bin)
        .env_remove("OBJNERF_COLMAP")
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("cannot tell the version") && err.contains("usage: colmap"),
        "{err}"
    );
    assert!(!dir.path().join("o").exists(), "nothing half-written");
}
