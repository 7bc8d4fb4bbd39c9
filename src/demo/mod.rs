//! The built-in demo scene: analytic objects rendered by a CPU ray tracer, with exact truth.
//!
//! Four textured objects (`mug`, `sphere`, `box`, `torus`) stand on a tiled floor inside a
//! cylindrical backdrop (world z-up, metres). `views` pinhole cameras sit on a ring around them,
//! looking at the centre; view 0 sees every object clearly, and from the opposite side of the ring
//! the box hides most of the sphere. [`write_demo_scene`] writes a folder that `Scene::load` reads
//! (`sparse/0` + `images/`) together with the truth the later stages are measured against:
//!
//! ```text
//! images/view_000.png ...           colour, anti-aliased
//! sparse/0/{cameras,images,points3D}.bin   COLMAP model with true, visibility-checked tracks
//! transforms.json, sparse_pc.ply    nerfstudio, depth_file_path -> truth/depth/*.png
//! truth/depth/view_000.{png,exr}    z-depth: 16-bit millimetres / f32 metres
//! truth/masks/<object>/view_000.png visible mask of each object (0/255)
//! truth/meshes/<object>.{ply,obj}   exact surface, tessellated, world coordinates
//! truth/objects.json                click in view 0, visible fraction per view, bounds
//! truth/removed/<object>/view_000.png  the view without that object (a removal's truth); also
//!                                   for every pair, truth/removed/<a>+<b>/ (names in scene order)
//! poses_bounds.npy                  LLFF poses and depth bounds (forward-facing layout only)
//! ```
//!
//! With [`DemoLayout::Forward`] the cameras stand on a plane in front of the scene, all facing it
//! (an LLFF-style forward-facing capture), instead of on the ring.
//!
//! Everything is a pure function of the options: all randomness goes through [`Rng`] seeded from
//! `seed`, and the parallel rendering writes each pixel from its position alone.

pub mod edit_truth;
pub mod fields;
pub mod geometry;
pub mod holdout;
pub mod mesh;
pub mod render;
pub mod texture;
pub mod tracks;
pub mod variants;
pub mod writer;

pub use geometry::{World, OBJECT_NAMES};
pub use variants::Variant;
pub use writer::{read_truth, truth_masks, ObjectTruth};

use crate::error::{Error, Result};
use crate::scene::formats::colmap::{self, ModelFormat};
use crate::scene::{ImageView, Scene, SceneCamera, SourceFormat};
use crate::util::choice::named_choices;
use crate::util::{AtomicDir, Rng};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// How to make the demo scene.
#[derive(Clone, Debug, PartialEq)]
pub struct DemoOptions {
    pub seed: u64,
    pub views: usize,
    pub width: u32,
    pub height: u32,
    /// Standard deviation of Gaussian noise on the 2D features, in pixels.
    pub noise_px: f64,
    /// Fraction of 3D points given one wrong observation (like SIFT mismatches).
    pub outlier_fraction: f64,
    /// Replace `out` if it exists and is not empty.
    pub overwrite: bool,
    /// A harder version of the scene ([`Variant`]).
    pub variant: Variant,
    /// Where the cameras stand.
    pub layout: DemoLayout,
}

/// Where the demo's cameras stand.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DemoLayout {
    /// A ring around the scene, looking at its centre (a turntable capture).
    #[default]
    Ring,
    /// A grid on a plane in front of the scene, all facing it (LLFF's forward-facing captures).
    Forward,
}

named_choices!(DemoLayout, "layout", {
    Ring => "ring",
    Forward => "forward",
});

impl Default for DemoOptions {
    fn default() -> Self {
        DemoOptions {
            seed: 0,
            views: 36,
            width: 320,
            height: 240,
            noise_px: 0.0,
            outlier_fraction: 0.0,
            overwrite: false,
            variant: Variant::Standard,
            layout: DemoLayout::Ring,
        }
    }
}

impl DemoOptions {
    /// Reject options that cannot make a usable scene, with a sentence saying why.
    pub fn validate(&self) -> Result<()> {
        if !(2..=1000).contains(&self.views) {
            return Err(Error::invalid(format!(
                "--views must be between 2 and 1000 (tracks need two views), got {}",
                self.views
            )));
        }
        for (what, v) in [("width", self.width), ("height", self.height)] {
            if !(32..=4096).contains(&v) {
                return Err(Error::invalid(format!(
                    "image {what} must be between 32 and 4096 pixels, got {v}"
                )));
            }
        }
        if !(self.noise_px.is_finite() && self.noise_px >= 0.0) {
            return Err(Error::invalid(format!(
                "--noise must be a finite number of pixels >= 0, got {}",
                self.noise_px
            )));
        }
        if !(0.0..=1.0).contains(&self.outlier_fraction) {
            return Err(Error::invalid(format!(
                "--outliers must be a fraction between 0 and 1, got {}",
                self.outlier_fraction
            )));
        }
        Ok(())
    }
}

/// Parse an image size written `WxH` (e.g. `320x240`).
pub fn parse_size(s: &str) -> Result<(u32, u32)> {
    let bad = || Error::invalid(format!("size '{s}' is not WIDTHxHEIGHT, e.g. 320x240"));
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    Ok((
        w.trim().parse().map_err(|_| bad())?,
        h.trim().parse().map_err(|_| bad())?,
    ))
}

/// What [`write_demo_scene`] made.
#[derive(Clone, Debug)]
pub struct DemoSummary {
    pub out: PathBuf,
    pub views: usize,
    pub points: usize,
    pub observations: usize,
    pub objects: Vec<ObjectTruth>,
    pub seconds: f64,
}

/// The image name of view `i`.
pub fn view_name(i: usize) -> String {
    format!("view_{i:03}.png")
}

/// Render the demo scene and write it, with its truth, to `out` (built in a temporary folder
/// and renamed into place, so `out` is either complete or untouched).
pub fn write_demo_scene(opts: &DemoOptions, out: &Path) -> Result<DemoSummary> {
    opts.validate()?;
    let start = Instant::now();
    let dir = AtomicDir::new(out, opts.overwrite)?;
    let root = dir.path().to_path_buf();
    let world = opts.variant.world();
    let tex = texture::Textures::new(opts.seed);
    let mut rng = Rng::new(opts.seed);
    let cam = render::demo_camera(opts.width, opts.height);
    let mut poses = match opts.layout {
        DemoLayout::Ring => render::demo_poses(opts.views, &mut rng),
        DemoLayout::Forward => render::forward_poses(opts.views, &mut rng),
    };
    opts.variant.adjust_poses(&world, &cam, &mut poses);
    let names: Vec<String> = (0..opts.views).map(view_name).collect();
    let object_names: Vec<&str> = world.objects.iter().map(|o| o.name).collect();

    // Views one after another, each view's rows in parallel.
    let mut ids = Vec::with_capacity(opts.views);
    let mut bounds = Vec::with_capacity(opts.views);
    for (name, pose) in names.iter().zip(&poses) {
        let r = render::render_view(&world, &tex, &cam, pose);
        writer::write_view(&root, name, (opts.width, opts.height), &r, &object_names)?;
        for set in removal_sets(world.objects.len()) {
            let rgb = render::render_without(&world, &tex, &cam, pose, &set, &r);
            let names: Vec<&str> = set.iter().map(|&k| world.objects[k].name).collect();
            let dir = writer::removed_dir(&root, &names);
            writer::write_removed(&dir, name, opts.width, opts.height, rgb)?;
        }
        bounds.push(depth_bounds(&r.depth));
        ids.push(r.ids);
    }

    let sparse = tracks::build(&world, &tex, &cam, &poses, &ids, opts, &mut rng);
    let observations = sparse.points.iter().map(|p| p.track.len()).sum();
    let images = names
        .iter()
        .zip(&poses)
        .zip(sparse.features)
        .enumerate()
        .map(|(i, ((name, pose), features))| {
            let stem = name.trim_end_matches(".png");
            ImageView {
                id: i as u32 + 1,
                name: name.clone(),
                path: root.join("images").join(name),
                camera: 0,
                pose: *pose,
                mask_path: None,
                depth_path: Some(writer::depth_paths(&root, stem).0),
                features,
                depth_bounds: None,
            }
        })
        .collect();
    let scene = Scene {
        source: out.to_path_buf(),
        format: SourceFormat::Demo,
        cameras: vec![SceneCamera {
            id: 1,
            camera: cam.clone(),
        }],
        images,
        points: sparse.points,
        depth_scale: 1000.0,
        applied_transform: None,
    };
    let n_points = scene.points.len();
    colmap::write_model(&scene, &root.join("sparse/0"), ModelFormat::Binary)?;

    crate::scene::formats::nerfstudio::write(&scene, &root.join("transforms.json"))?;
    if opts.layout == DemoLayout::Forward {
        crate::scene::formats::llff::write(&scene, &bounds, &root.join("poses_bounds.npy"))?;
    }

    for obj in &world.objects {
        let m = mesh::tessellate(obj).to_mesh(obj.name);
        let d = root.join("truth/meshes");
        crate::mesh::io::write_ply(&m, &d.join(format!("{}.ply", obj.name)))?;
        crate::mesh::io::write_obj(&m, &d.join(format!("{}.obj", obj.name)))?;
    }

    let (w, h) = (opts.width as usize, opts.height as usize);
    let mut objects = Vec::new();
    for (k, obj) in world.objects.iter().enumerate() {
        let mut visible = BTreeMap::new();
        for (v, pose) in poses.iter().enumerate() {
            let full = render::silhouette_area(&world, k, &cam, pose);
            let seen = ids[v].iter().filter(|&&id| id == k as u8).count() as f64;
            // The two areas are counted on different pixel sets; clamp the rounding excess.
            let frac = if full > 0.0 {
                (seen / full).min(1.0)
            } else {
                0.0
            };
            visible.insert(names[v].clone(), frac);
        }
        // The click: in view 0, or for an object it does not see, the first view that does.
        let (view, click) = ids
            .iter()
            .enumerate()
            .find_map(|(v, ids)| {
                let mask: Vec<bool> = ids.iter().map(|&id| id == k as u8).collect();
                writer::farthest_interior(&mask, w, h).map(|c| (v, c))
            })
            .ok_or_else(|| {
                Error::invalid(format!(
                    "object '{}' is not visible in any view at {}x{}",
                    obj.name, opts.width, opts.height
                ))
            })?;
        let (lo, hi) = obj.world_bbox();
        objects.push(ObjectTruth {
            name: obj.name.to_string(),
            view: names[view].clone(),
            click,
            visible,
            bbox_min: lo.to_array(),
            bbox_max: hi.to_array(),
        });
    }
    writer::write_truth(&root.join("truth/objects.json"), &objects)?;

    let out = dir.commit()?;
    Ok(DemoSummary {
        out,
        views: opts.views,
        points: n_points,
        observations,
        objects,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// A view's near and far depth (LLFF's bounds): the nearest and farthest surface hit, padded by
/// 10%.
fn depth_bounds(depth: &[f32]) -> [f64; 2] {
    let (lo, hi) = depth
        .iter()
        .filter(|d| **d > 0.0)
        .fold((f32::MAX, 0.0f32), |(lo, hi), &d| (lo.min(d), hi.max(d)));
    if hi <= 0.0 {
        return [0.1, 10.0];
    }
    [0.9 * lo as f64, 1.1 * hi as f64]
}

/// The sets of objects whose removal the demo renders the truth of: each object, and each pair.
fn removal_sets(n: usize) -> Vec<Vec<usize>> {
    let mut sets: Vec<Vec<usize>> = (0..n).map(|k| vec![k]).collect();
    for a in 0..n {
        for b in a + 1..n {
            sets.push(vec![a, b]);
        }
    }
    sets
}
