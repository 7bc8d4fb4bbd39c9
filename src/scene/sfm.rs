//! `objnerf sfm`: give a scene 2D-3D feature tracks with the real COLMAP (Debian package
//! `colmap`, CPU). Two modes:
//! - **full reconstruction** from an images folder (features, exhaustive matching, mapper), and
//! - **triangulation with known poses** for a posed scene without tracks (e.g. NeRF-synthetic),
//!   which keeps the scene's cameras and world frame and only adds points and tracks.
//!
//! Images may be downscaled before feature extraction; the model is scaled back to the full image
//! size afterwards, so its intrinsics and 2D features always match the original images.

use crate::error::{Error, Result};
use crate::scene::formats::colmap::{self, ModelFormat};
use crate::scene::io::{is_image, read_image};
use crate::scene::{Scene, SourceFormat};
use crate::util::{Detail, Progress};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

#[derive(Clone, Debug)]
pub struct SfmOptions {
    /// Downscale images by this factor before feature extraction (1 = full size).
    pub downscale: u32,
    /// COLMAP camera model for full reconstruction.
    pub camera_model: String,
    /// Most SIFT features per image.
    pub max_features: u32,
    /// "auto" (posed scenes: pairs chosen from the poses; otherwise exhaustive), "exhaustive",
    /// "sequential" or "pairs" (posed scenes only).
    pub matcher: String,
    /// With pose-chosen pairs: match each image with this many neighbours.
    pub pair_neighbours: usize,
    /// COLMAP's threads (-1 = all cores).
    pub threads: i32,
    /// Replace the output folder if it exists.
    pub overwrite: bool,
}

impl Default for SfmOptions {
    fn default() -> Self {
        SfmOptions {
            downscale: 1,
            camera_model: "SIMPLE_RADIAL".into(),
            max_features: 8192,
            matcher: "auto".into(),
            pair_neighbours: 12,
            threads: -1,
            overwrite: false,
        }
    }
}

/// What a run did.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SfmReport {
    pub mode: &'static str,
    pub num_images: usize,
    pub num_registered: usize,
    pub num_points: usize,
    pub mean_track_length: f64,
    pub seconds: f64,
    pub model_dir: PathBuf,
    /// Image pairs matched when they were chosen from the poses (triangulation).
    pub matched_pairs: Option<usize>,
}

/// What `objnerf sfm` was given.
pub enum SfmInput {
    /// A folder of images without poses: full reconstruction.
    Images(PathBuf),
    /// A posed scene: triangulation with its poses.
    Posed(Scene),
}

fn has_images(dir: &Path) -> bool {
    std::fs::read_dir(dir)
        .map(|d| d.flatten().any(|e| is_image(&e.path())))
        .unwrap_or(false)
}

/// A posed scene if `input` reads as one (and `force_reconstruct` is off), else a folder of images.
pub fn resolve_input(input: &Path, force_reconstruct: bool) -> Result<SfmInput> {
    match Scene::load(input) {
        Ok(scene) if !force_reconstruct => Ok(SfmInput::Posed(scene)),
        other => {
            for dir in [input.to_path_buf(), input.join("images")] {
                if dir.is_dir() && has_images(&dir) {
                    return Ok(SfmInput::Images(dir));
                }
            }
            match other {
                Err(e) => Err(e),
                Ok(_) => Err(Error::format(input, "no images folder to reconstruct from")),
            }
        }
    }
}

/// Find the `colmap` program, or say how to install it.
pub fn colmap_program() -> Result<PathBuf> {
    let candidates = std::env::var_os("OBJNERF_COLMAP")
        .map(PathBuf::from)
        .into_iter()
        .chain(std::env::var_os("PATH").into_iter().flat_map(|p| {
            std::env::split_paths(&p)
                .map(|d| d.join("colmap"))
                .collect::<Vec<_>>()
        }));
    for c in candidates {
        if c.is_file() {
            return Ok(c);
        }
    }
    Err(Error::external(
        "colmap",
        "not found on PATH: install it with `sudo apt-get install -y colmap` (Debian/Ubuntu) or set OBJNERF_COLMAP to the program",
    ))
}

/// COLMAP's programs as one progress stage of three steps (features, matching, mapping or
/// triangulation).
struct Steps<'a> {
    progress: &'a dyn Progress,
    done: std::cell::Cell<u64>,
}

impl<'a> Steps<'a> {
    fn new(progress: &'a dyn Progress) -> Self {
        progress.begin("colmap", 3);
        Steps {
            progress,
            done: std::cell::Cell::new(0),
        }
    }

    fn finished(&self, program: &str) {
        self.done.set(self.done.get() + 1);
        self.progress
            .advance(self.done.get(), Detail::Item(program));
    }
}

impl Drop for Steps<'_> {
    fn drop(&mut self) {
        self.progress.end();
    }
}

fn run_colmap(program: &Path, args: &[String], log: &Path, steps: &Steps) -> Result<()> {
    let stage = args.first().cloned().unwrap_or_default();
    let out = Command::new(program)
        .args(args)
        .env("QT_QPA_PLATFORM", "offscreen")
        .output()
        .map_err(|e| Error::external("colmap", format!("cannot run {}: {e}", program.display())))?;
    let mut text = String::from_utf8_lossy(&out.stdout).to_string();
    text.push_str(&String::from_utf8_lossy(&out.stderr));
    use std::io::Write;
    if let Ok(mut f) = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(log)
    {
        let _ = writeln!(f, "$ colmap {}\n{text}", args.join(" "));
    }
    if !out.status.success() {
        let tail: String = text
            .lines()
            .rev()
            .take(15)
            .collect::<Vec<_>>()
            .into_iter()
            .rev()
            .collect::<Vec<_>>()
            .join("\n");
        return Err(Error::external(
            format!("colmap {stage}"),
            format!("failed ({}); log {}:\n{tail}", out.status, log.display()),
        ));
    }
    steps.finished(&stage);
    Ok(())
}

/// Fail early (before minutes of COLMAP) when the output folder would be refused at the end.
fn check_out(out: &Path, opts: &SfmOptions) -> Result<()> {
    drop(crate::util::AtomicDir::new(out, opts.overwrite)?);
    Ok(())
}

/// Prepare `work/images/NNNNN.ext`: symlinks to the originals, or downscaled copies. Sorted names
/// make COLMAP's image ids follow the scene's order.
fn stage_images(paths: &[PathBuf], work: &Path, downscale: u32) -> Result<Vec<String>> {
    let dir = work.join("images");
    std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
    let mut names = Vec::with_capacity(paths.len());
    for (i, p) in paths.iter().enumerate() {
        let ext = p
            .extension()
            .map(|e| e.to_string_lossy().to_lowercase())
            .unwrap_or_else(|| "png".into());
        let name = if downscale > 1 {
            format!("{i:05}.png")
        } else {
            format!("{i:05}.{ext}")
        };
        let dst = dir.join(&name);
        if downscale > 1 {
            let img = read_image(p)?;
            let (w, h) = (img.width(), img.height());
            let (nw, nh) = (
                ((w as f64 / downscale as f64).round() as u32).max(1),
                ((h as f64 / downscale as f64).round() as u32).max(1),
            );
            let small = img.resize_exact(nw, nh, image::imageops::FilterType::Triangle);
            small.save(&dst).map_err(|e| Error::image(&dst, e))?;
        } else {
            let abs = std::fs::canonicalize(p).map_err(|e| Error::io(p, e))?;
            std::os::unix::fs::symlink(&abs, &dst).map_err(|e| Error::io(&dst, e))?;
        }
        names.push(name);
    }
    Ok(names)
}

fn s(x: impl ToString) -> String {
    x.to_string()
}

/// Image pairs worth matching for a posed scene: each image with its `k` nearest neighbours by
/// viewing direction (angle between optical axes, ties broken by centre distance), limited to
/// axes within 90 degrees. Far fewer than all pairs, and the ones that share a view of the scene.
pub fn pairs_from_poses(scene: &Scene, k: usize) -> Vec<(usize, usize)> {
    let axes: Vec<glam::DVec3> = scene
        .images
        .iter()
        .map(|im| im.pose.camera_to_world_dir(glam::DVec3::Z))
        .collect();
    let mut pairs = std::collections::BTreeSet::new();
    for i in 0..scene.images.len() {
        let mut cand: Vec<(f64, f64, usize)> = (0..scene.images.len())
            .filter(|&j| j != i && axes[i].dot(axes[j]) > 0.0)
            .map(|j| {
                let angle = axes[i].dot(axes[j]).clamp(-1.0, 1.0).acos();
                (
                    angle,
                    (scene.images[i].pose.center() - scene.images[j].pose.center()).length(),
                    j,
                )
            })
            .collect();
        cand.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
        for &(_, _, j) in cand.iter().take(k) {
            pairs.insert((i.min(j), i.max(j)));
        }
    }
    pairs.into_iter().collect()
}

/// Image name → (image id, camera id) from a COLMAP database.
fn database_ids(db: &Path) -> Result<std::collections::HashMap<String, (u32, u32)>> {
    let err = |e: rusqlite::Error| Error::format(db, format!("cannot read COLMAP's database: {e}"));
    let conn =
        rusqlite::Connection::open_with_flags(db, rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY)
            .map_err(err)?;
    let mut stmt = conn
        .prepare("SELECT image_id, name, camera_id FROM images")
        .map_err(err)?;
    let rows = stmt
        .query_map([], |r| {
            Ok((
                r.get::<_, String>(1)?,
                (r.get::<_, u32>(0)?, r.get::<_, u32>(2)?),
            ))
        })
        .map_err(err)?;
    rows.collect::<std::result::Result<_, _>>().map_err(err)
}

/// Where the features of the staged images get matched.
struct MatchPlan<'a> {
    /// Pairs (indices into `staged`) for a posed scene, or None.
    pairs: Option<&'a [(usize, usize)]>,
    staged: &'a [String],
}

fn extract_and_match(
    program: &Path,
    work: &Path,
    opts: &SfmOptions,
    camera_args: &[String],
    plan: MatchPlan,
    log: &Path,
    steps: &Steps,
) -> Result<()> {
    let db = work.join("database.db");
    let mut args = vec![
        s("feature_extractor"),
        s("--database_path"),
        db.display().to_string(),
        s("--image_path"),
        work.join("images").display().to_string(),
        s("--SiftExtraction.use_gpu"),
        s("0"),
        s("--SiftExtraction.max_num_features"),
        opts.max_features.to_string(),
        s("--SiftExtraction.num_threads"),
        opts.threads.to_string(),
    ];
    args.extend_from_slice(camera_args);
    run_colmap(program, &args, log, steps)?;
    let mut args = match (opts.matcher.as_str(), plan.pairs) {
        ("auto" | "pairs", Some(pairs)) => {
            let list = work.join("pairs.txt");
            let text: String = pairs
                .iter()
                .map(|&(i, j)| format!("{} {}\n", plan.staged[i], plan.staged[j]))
                .collect();
            std::fs::write(&list, text).map_err(|e| Error::io(&list, e))?;
            vec![
                s("matches_importer"),
                s("--match_list_path"),
                list.display().to_string(),
                s("--match_type"),
                s("pairs"),
            ]
        }
        ("pairs", None) => {
            return Err(Error::invalid(
                "--matcher pairs needs a posed scene (pairs are chosen from the poses)",
            ))
        }
        ("auto" | "exhaustive", _) => vec![s("exhaustive_matcher")],
        ("sequential", _) => vec![s("sequential_matcher")],
        (m, _) => {
            return Err(Error::invalid(format!(
                "unknown matcher '{m}': use auto, exhaustive, sequential or pairs"
            )))
        }
    };
    args.extend([
        s("--database_path"),
        db.display().to_string(),
        s("--SiftMatching.use_gpu"),
        s("0"),
        s("--SiftMatching.num_threads"),
        opts.threads.to_string(),
    ]);
    run_colmap(program, &args, log, steps)
}

/// Full reconstruction of the images in `images_dir`; writes `out/sparse/0` and links
/// `out/images` to the images. `progress` hears COLMAP's three programs finish.
pub fn reconstruct(
    images_dir: &Path,
    out: &Path,
    opts: &SfmOptions,
    progress: &dyn Progress,
) -> Result<SfmReport> {
    let start = Instant::now();
    let program = colmap_program()?;
    check_out(out, opts)?;
    let mut paths: Vec<PathBuf> = std::fs::read_dir(images_dir)
        .map_err(|e| Error::io(images_dir, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| is_image(p))
        .collect();
    paths.sort();
    if paths.len() < 2 {
        return Err(Error::format(
            images_dir,
            format!(
                "found {} images; structure from motion needs at least 2",
                paths.len()
            ),
        ));
    }
    let work = tempfile::Builder::new()
        .prefix("objnerf-sfm-")
        .tempdir()
        .map_err(|e| Error::io(std::env::temp_dir(), e))?;
    let log = work.path().join("colmap.log");
    let staged = stage_images(&paths, work.path(), opts.downscale)?;
    let steps = Steps::new(progress);
    extract_and_match(
        &program,
        work.path(),
        opts,
        &[
            s("--ImageReader.single_camera"),
            s("1"),
            s("--ImageReader.camera_model"),
            opts.camera_model.clone(),
        ],
        MatchPlan {
            pairs: None,
            staged: &staged,
        },
        &log,
        &steps,
    )?;
    let sparse = work.path().join("sparse");
    std::fs::create_dir_all(&sparse).map_err(|e| Error::io(&sparse, e))?;
    run_colmap(
        &program,
        &[
            s("mapper"),
            s("--database_path"),
            work.path().join("database.db").display().to_string(),
            s("--image_path"),
            work.path().join("images").display().to_string(),
            s("--output_path"),
            sparse.display().to_string(),
            s("--Mapper.num_threads"),
            opts.threads.to_string(),
        ],
        &log,
        &steps,
    )?;
    // COLMAP may split the images into several models: keep the one with the most images.
    let mut best: Option<Scene> = None;
    for entry in std::fs::read_dir(&sparse)
        .map_err(|e| Error::io(&sparse, e))?
        .flatten()
    {
        if colmap::detect(&entry.path()).is_some() {
            let m = colmap::read_model(&entry.path(), &work.path().join("images"))?;
            if best
                .as_ref()
                .is_none_or(|b| m.images.len() > b.images.len())
            {
                best = Some(m);
            }
        }
    }
    let mut model = best.ok_or_else(|| {
        Error::external(
            "colmap mapper",
            format!(
                "registered no images (too few matches?); log {}",
                log.display()
            ),
        )
    })?;
    let originals: Vec<String> = paths
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().to_string())
        .collect();
    rename_and_rescale(&mut model, &staged, &originals, &paths)?;
    finish(
        model,
        out,
        images_dir,
        "reconstruct",
        paths.len(),
        start,
        work,
    )
}

/// Triangulate points for a posed scene, keeping its cameras and poses. Writes `out/sparse/0`
/// (image names as in the scene, relative to `out/images`, which links to the scene's folder).
/// `progress` hears COLMAP's three programs finish.
pub fn triangulate(
    scene: &Scene,
    out: &Path,
    opts: &SfmOptions,
    progress: &dyn Progress,
) -> Result<SfmReport> {
    let start = Instant::now();
    let program = colmap_program()?;
    check_out(out, opts)?;
    let root = image_root(scene)?;
    let work = tempfile::Builder::new()
        .prefix("objnerf-sfm-")
        .tempdir()
        .map_err(|e| Error::io(std::env::temp_dir(), e))?;
    let log = work.path().join("colmap.log");
    let paths: Vec<PathBuf> = scene.images.iter().map(|im| im.path.clone()).collect();
    let staged = stage_images(&paths, work.path(), opts.downscale)?;

    // The model COLMAP starts from: our cameras (at the staged size), poses, no points.
    let mut known = scene.clone();
    known.points.clear();
    for (im, name) in known.images.iter_mut().zip(&staged) {
        im.features.clear();
        im.name = name.clone();
    }
    for (i, c) in known.cameras.iter_mut().enumerate() {
        c.id = i as u32 + 1;
        c.camera = c.camera.downscaled(opts.downscale);
    }
    for (i, im) in known.images.iter_mut().enumerate() {
        im.id = i as u32 + 1;
    }
    // One camera per image in the database, with the known intrinsics, so ids line up.
    let single = known.cameras.len() == 1;
    let cam = &known.cameras[0].camera;
    let cam_args = vec![
        s("--ImageReader.single_camera"),
        s(if single { "1" } else { "0" }),
        s("--ImageReader.single_camera_per_image"),
        s(if single { "0" } else { "1" }),
        s("--ImageReader.camera_model"),
        s(cam.model.name()),
        s("--ImageReader.camera_params"),
        cam.params
            .iter()
            .map(|p| p.to_string())
            .collect::<Vec<_>>()
            .join(","),
    ];
    if !single {
        // One camera per image; the ids come from COLMAP's database below.
        let cams: Vec<_> = known
            .images
            .iter()
            .map(|im| known.cameras[im.camera].camera.clone())
            .collect();
        known.cameras = cams
            .into_iter()
            .enumerate()
            .map(|(i, camera)| crate::scene::SceneCamera {
                id: i as u32 + 1,
                camera,
            })
            .collect();
        for (i, im) in known.images.iter_mut().enumerate() {
            im.camera = i;
        }
    }
    let pairs = pairs_from_poses(scene, opts.pair_neighbours);
    let steps = Steps::new(progress);
    extract_and_match(
        &program,
        work.path(),
        opts,
        &cam_args,
        MatchPlan {
            pairs: Some(&pairs),
            staged: &staged,
        },
        &log,
        &steps,
    )?;
    // COLMAP numbers images and cameras as its extractor threads finish, not in list order:
    // take the ids from its database so the known model lines up with it.
    let ids = database_ids(&work.path().join("database.db"))?;
    for im in known.images.iter_mut() {
        let &(image_id, camera_id) = ids.get(&im.name).ok_or_else(|| {
            Error::external(
                "colmap feature_extractor",
                format!("image '{}' is missing from its database", im.name),
            )
        })?;
        im.id = image_id;
        known.cameras[im.camera].id = camera_id;
    }
    let input = work.path().join("known");
    colmap::write_model(&known, &input, ModelFormat::Text)?;
    let tri = work.path().join("triangulated");
    std::fs::create_dir_all(&tri).map_err(|e| Error::io(&tri, e))?;
    run_colmap(
        &program,
        &[
            s("point_triangulator"),
            s("--database_path"),
            work.path().join("database.db").display().to_string(),
            s("--image_path"),
            work.path().join("images").display().to_string(),
            s("--input_path"),
            input.display().to_string(),
            s("--output_path"),
            tri.display().to_string(),
            s("--Mapper.num_threads"),
            opts.threads.to_string(),
        ],
        &log,
        &steps,
    )?;
    let mut model = colmap::read_model(&tri, &work.path().join("images"))?;
    // The poses must come back unchanged; a mismatch means the database ids did not line up.
    for im in &model.images {
        let k = staged.iter().position(|n| *n == im.name).ok_or_else(|| {
            Error::external(
                "colmap point_triangulator",
                format!("unknown image '{}' in its output", im.name),
            )
        })?;
        let d = (im.pose.center() - scene.images[k].pose.center()).length();
        if d > 1e-6 * (1.0 + scene.images[k].pose.center().length()) {
            return Err(Error::external(
                "colmap point_triangulator",
                format!(
                    "image '{}' moved by {d}: database ids did not match",
                    scene.images[k].name
                ),
            ));
        }
    }
    let originals: Vec<String> = scene
        .images
        .iter()
        .map(|im| relative_name(&im.path, &root))
        .collect();
    rename_and_rescale(&mut model, &staged, &originals, &paths)?;
    // Keep the scene's exact intrinsics and poses (COLMAP's text round trip is exact, but the
    // original numbers are the reference).
    for im in &mut model.images {
        if let Some(k) = originals.iter().position(|n| *n == im.name) {
            im.pose = scene.images[k].pose;
        }
    }
    let mut report = finish(
        model,
        out,
        &root,
        "triangulate",
        scene.images.len(),
        start,
        work,
    )?;
    report.matched_pairs = Some(pairs.len());
    Ok(report)
}

/// The folder all the scene's images sit under (their longest common ancestor).
fn image_root(scene: &Scene) -> Result<PathBuf> {
    let mut root: Option<PathBuf> = None;
    for im in &scene.images {
        let abs = std::fs::canonicalize(&im.path).map_err(|e| Error::io(&im.path, e))?;
        let parent = abs.parent().unwrap_or(Path::new("/")).to_path_buf();
        root = Some(match root {
            None => parent,
            Some(r) => {
                let mut r = r;
                while !parent.starts_with(&r) {
                    r = r.parent().unwrap_or(Path::new("/")).to_path_buf();
                }
                r
            }
        });
    }
    root.ok_or_else(|| Error::format(&scene.source, "the scene has no images"))
}

fn relative_name(path: &Path, root: &Path) -> String {
    let abs = std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
    abs.strip_prefix(root)
        .unwrap_or(&abs)
        .to_string_lossy()
        .to_string()
}

/// Give the model's images their original names and paths, and scale cameras and features
/// from the staged (downscaled) size back to the original image size.
fn rename_and_rescale(
    model: &mut Scene,
    staged: &[String],
    originals: &[String],
    paths: &[PathBuf],
) -> Result<()> {
    let mut scale_for_camera: Vec<Option<(u32, u32)>> = vec![None; model.cameras.len()];
    for im in &mut model.images {
        let k = staged.iter().position(|n| *n == im.name).ok_or_else(|| {
            Error::external(
                "colmap",
                format!("unknown image '{}' in its output", im.name),
            )
        })?;
        im.name = originals[k].clone();
        im.path = paths[k].clone();
        let (w, h) = image::image_dimensions(&paths[k]).map_err(|e| Error::image(&paths[k], e))?;
        let cam = &model.cameras[im.camera].camera;
        let (sx, sy) = (w as f64 / cam.width as f64, h as f64 / cam.height as f64);
        for f in &mut im.features {
            f.xy.x *= sx;
            f.xy.y *= sy;
        }
        scale_for_camera[im.camera] = Some((w, h));
    }
    for (c, size) in model.cameras.iter_mut().zip(scale_for_camera) {
        if let Some((w, h)) = size {
            c.camera = c.camera.resized(w, h);
        }
    }
    Ok(())
}

fn finish(
    mut model: Scene,
    out: &Path,
    images_root: &Path,
    mode: &'static str,
    num_images: usize,
    start: Instant,
    work: tempfile::TempDir,
) -> Result<SfmReport> {
    // Checked empty (or --overwrite) before COLMAP ran.
    let dest = crate::util::AtomicDir::new(out, true)?;
    let model_dir = dest.path().join("sparse/0");
    colmap::write_model(&model, &model_dir, ModelFormat::Binary)?;
    let abs_root = std::fs::canonicalize(images_root).map_err(|e| Error::io(images_root, e))?;
    std::os::unix::fs::symlink(&abs_root, dest.path().join("images"))
        .map_err(|e| Error::io(dest.path().join("images"), e))?;
    let _ = std::fs::copy(
        work.path().join("colmap.log"),
        dest.path().join("colmap.log"),
    );
    let out = dest.commit()?;
    model.source = out.join("sparse/0");
    model.format = SourceFormat::ColmapBinary;
    let obs: usize = model.points.iter().map(|p| p.track.len()).sum();
    Ok(SfmReport {
        mode,
        num_images,
        num_registered: model.images.len(),
        num_points: model.points.len(),
        mean_track_length: if model.points.is_empty() {
            0.0
        } else {
            obs as f64 / model.points.len() as f64
        },
        seconds: start.elapsed().as_secs_f64(),
        model_dir: out.join("sparse/0"),
        matched_pairs: None,
    })
}
