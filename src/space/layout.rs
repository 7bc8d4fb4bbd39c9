//! Which [`Space`] a scene field lives in, chosen from the capture's layout, and where its grid's
//! box lies in that space.
//!
//! The cameras' optical axes say how the capture was taken. Their mean resultant length (|mean
//! of the unit axes|) is near 1 when all cameras face one way and near 0 when they surround the
//! scene; their focus (the point nearest to every axis) is what they look at.
//! - **forward**: every axis within [`FORWARD_MAX_DEG`] of the mean axis (LLFF: a handheld sweep
//!   facing a scene). NDC of the mean camera.
//! - **box**: the cameras surround the scene (mean resultant < [`SURROUND_RESULTANT`]) and the
//!   sparse points stay within [`BOX_MAX_REACH`] times the cameras' distance from the focus (a
//!   turntable, the demo scene with its backdrop).
//! - **unbounded**: anything else: cameras on one side of a room (fox), or around an object with a
//!   far background (Mip-NeRF 360). Contraction about the focus, the inner ball holding the
//!   cameras.

use crate::error::{Error, Result};
use crate::scene::Scene;
use crate::space::{NdcSpace, Space};
use crate::util::choice::named_choices;
use crate::util::stats::quantile;
use glam::{DMat3, DVec3, Vec3};
use serde::Serialize;

/// Most degrees between a camera's axis and the mean axis for a forward-facing capture (LLFF
/// sweeps stay within ~15 degrees; fox's views of a head on a wall spread over 60).
pub const FORWARD_MAX_DEG: f64 = 30.0;
/// Below this mean resultant length the axes point in every direction: the cameras surround the
/// scene (a ring of 36 views gives ~0.2 from its downward tilt).
pub const SURROUND_RESULTANT: f64 = 0.5;
/// A surrounded scene is bounded when 95% of its sparse points lie within this multiple of the
/// cameras' largest distance from the focus (the demo's backdrop: 2.1; a Mip-NeRF 360 garden's
/// trees: > 5).
pub const BOX_MAX_REACH: f64 = 3.0;

/// What `--space` asks for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SpaceChoice {
    #[default]
    Auto,
    Box,
    Unbounded,
    Forward,
}

named_choices!(SpaceChoice, "space", {
    Auto => "auto",
    Box => "box",
    Unbounded => "unbounded",
    Forward => "forward",
});

/// The capture's layout as the cameras and points show it.
#[derive(Clone, Debug, Serialize)]
pub struct Layout {
    /// |mean of the unit optical axes|.
    pub axis_resultant: f64,
    /// Largest angle between a camera's axis and the mean axis, degrees.
    pub max_axis_deg: f64,
    /// The point nearest to every optical axis (least squares).
    pub focus: [f64; 3],
    /// Largest camera distance from the focus.
    pub camera_reach: f64,
    /// 95th percentile of the sparse points' distance from the focus (0 without points).
    pub point_reach: f64,
}

/// A chosen space with its grid box (space coordinates) and why.
#[derive(Clone, Debug)]
pub struct SpaceSetup {
    pub space: Space,
    pub box_min: Vec3,
    pub box_max: Vec3,
    /// The world length one pixel covers near the centre of interest, in space units: the voxel
    /// size at one voxel per pixel.
    pub pixel_footprint: f32,
    /// World distance from each camera within which the grid holds nothing (0: none): what a
    /// single camera alone sees up close is where a field grows floaters that explain its own
    /// pixels. DVGO's `near_clip` for 360-degree scenes.
    pub near_clip: f32,
    pub layout: Layout,
    pub why: String,
}

/// The scene starts this fraction of the way to the nearest surface any view sees (the 5th
/// percentile of each view's tracked points' depths, least over the views).
pub const NEAR_CLIP_FRACTION: f64 = 0.5;

/// World distance from the cameras that holds no scene ([`SpaceSetup::near_clip`]). A capture
/// with poses alone (no tracked points, depth images or bounds) takes the cameras' focus as
/// its nearest surface: fox from `transforms.json` grew fog in front of its cameras without
/// it (3000 steps at downscale 4: held out 11.71 -> 22.70 dB; examples/results/scene_field.md,
/// "Fox's fog: no near clip without points").
fn near_clip(scene: &Scene, focus: DVec3) -> f32 {
    // The least over the views of a depth each gives (None: no view gives one).
    let least = |depth: &dyn Fn(&crate::scene::ImageView) -> Option<f64>| {
        scene.images.iter().filter_map(depth).reduce(f64::min)
    };
    let nearest_points = least(&|im| {
        let depths: Vec<f64> = im
            .features
            .iter()
            .filter_map(|f| f.point)
            .map(|p| im.pose.world_to_camera(scene.points[p].xyz).z)
            .filter(|z| *z > 0.0)
            .collect();
        quantile(depths, 0.05)
    });
    // Depth images or bounds say where the near surfaces are; with neither, the focus stands in.
    let measured = scene
        .images
        .iter()
        .any(|im| im.depth_path.is_some() || im.depth_bounds.is_some());
    let near = nearest_points.or_else(|| {
        (!measured)
            .then(|| least(&|im| Some(im.pose.world_to_camera(focus).z).filter(|z| *z > 0.0)))
            .flatten()
    });
    near.map_or(0.0, |n| (NEAR_CLIP_FRACTION * n) as f32)
}

/// Measure the layout of `scene`'s cameras and points.
pub fn layout(scene: &Scene) -> Result<Layout> {
    if scene.images.len() < 2 {
        return Err(Error::invalid(format!(
            "{}: a scene field needs at least two views",
            scene.source.display()
        )));
    }
    let axes: Vec<DVec3> = scene
        .images
        .iter()
        .map(|im| im.pose.camera_to_world_dir(DVec3::Z).normalize())
        .collect();
    let centers: Vec<DVec3> = scene.images.iter().map(|im| im.pose.center()).collect();
    let mean = axes.iter().sum::<DVec3>() / axes.len() as f64;
    let resultant = mean.length();
    let mean_axis = mean.normalize_or(DVec3::Z);
    let max_axis_deg = axes
        .iter()
        .map(|a| a.dot(mean_axis).clamp(-1.0, 1.0).acos().to_degrees())
        .fold(0.0, f64::max);
    let focus = focus_point(&centers, &axes);
    let camera_reach = centers
        .iter()
        .map(|c| (*c - focus).length())
        .fold(0.0, f64::max);
    let dists: Vec<f64> = scene
        .points
        .iter()
        .map(|p| (p.xyz - focus).length())
        .collect();
    Ok(Layout {
        axis_resultant: resultant,
        max_axis_deg,
        focus: focus.to_array(),
        camera_reach,
        point_reach: quantile(dists, 0.95).unwrap_or(0.0),
    })
}

/// The point nearest (least squares) to every camera's optical axis; the mean camera centre
/// pushed along the mean axis when the axes are near parallel (no unique point).
fn focus_point(centers: &[DVec3], axes: &[DVec3]) -> DVec3 {
    let mut a = DMat3::ZERO;
    let mut b = DVec3::ZERO;
    for (c, d) in centers.iter().zip(axes) {
        // (I - d d^T) projects onto the plane across the axis.
        let p = DMat3::IDENTITY - DMat3::from_cols(*d * d.x, *d * d.y, *d * d.z);
        a += p;
        b += p * *c;
    }
    let mean_c = centers.iter().sum::<DVec3>() / centers.len() as f64;
    if a.determinant().abs() > 1e-6 * centers.len().pow(3) as f64 {
        let f = a.inverse() * b;
        if f.is_finite() {
            return f;
        }
    }
    mean_c
}

/// Choose the space for a scene field of `scene` (or take `choice`) and set up its box, for
/// training views downscaled by `downscale`.
pub fn choose_space(scene: &Scene, choice: SpaceChoice, downscale: u32) -> Result<SpaceSetup> {
    let l = layout(scene)?;
    let (kind, reason) = match choice {
        SpaceChoice::Auto => auto_kind(&l),
        c => (c, "given with --space".to_string()),
    };
    match kind {
        SpaceChoice::Forward => forward_setup(scene, l, reason, downscale),
        SpaceChoice::Unbounded => Ok(unbounded_setup(scene, l, reason, downscale)),
        _ => box_setup(scene, l, reason, downscale),
    }
}

fn auto_kind(l: &Layout) -> (SpaceChoice, String) {
    if l.max_axis_deg <= FORWARD_MAX_DEG {
        return (
            SpaceChoice::Forward,
            format!(
                "forward: every camera faces within {:.0} deg of one direction (<= {FORWARD_MAX_DEG})",
                l.max_axis_deg
            ),
        );
    }
    let reach = l.point_reach / l.camera_reach.max(1e-9);
    if l.axis_resultant < SURROUND_RESULTANT && reach <= BOX_MAX_REACH {
        return (
            SpaceChoice::Box,
            format!(
                "box: the cameras surround the scene (mean axis resultant {:.2} < {SURROUND_RESULTANT}) and 95% of its points lie within {reach:.1}x their distance from the focus (<= {BOX_MAX_REACH})",
                l.axis_resultant
            ),
        );
    }
    let why = if l.axis_resultant >= SURROUND_RESULTANT {
        format!(
            "the cameras face one side (mean axis resultant {:.2} >= {SURROUND_RESULTANT}, axes spread {:.0} deg)",
            l.axis_resultant, l.max_axis_deg
        )
    } else {
        format!("the scene reaches {reach:.1}x the cameras' distance from the focus (> {BOX_MAX_REACH})")
    };
    (SpaceChoice::Unbounded, format!("unbounded: {why}"))
}

/// Median over views of (distance from `p` to the camera) / focal: the world length one pixel
/// covers at `p`.
fn footprint_at(scene: &Scene, p: DVec3, downscale: u32) -> f64 {
    let mut v: Vec<f64> = scene
        .images
        .iter()
        .map(|im| {
            let (fx, fy) = scene.camera_of(im).focal();
            (im.pose.center() - p).length() * downscale.max(1) as f64 / fx.max(fy)
        })
        .collect();
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn box_setup(scene: &Scene, l: Layout, reason: String, downscale: u32) -> Result<SpaceSetup> {
    // The sparse points (robust: 1st-99th percentiles) and the cameras: what every camera looks
    // into. Padded by 5% per side.
    let mut lo = DVec3::splat(f64::MAX);
    let mut hi = DVec3::splat(f64::MIN);
    for im in &scene.images {
        lo = lo.min(im.pose.center());
        hi = hi.max(im.pose.center());
    }
    if !scene.points.is_empty() {
        for a in 0..3 {
            let v: Vec<f64> = scene.points.iter().map(|p| p.xyz[a]).collect();
            lo[a] = lo[a].min(quantile(v.clone(), 0.01).unwrap_or(lo[a]));
            hi[a] = hi[a].max(quantile(v, 0.99).unwrap_or(hi[a]));
        }
    }
    let pad = (hi - lo) * 0.05;
    let (lo, hi) = (lo - pad, hi + pad);
    let focus = DVec3::from_array(l.focus);
    Ok(SpaceSetup {
        space: Space::Box,
        box_min: lo.as_vec3(),
        box_max: hi.as_vec3(),
        pixel_footprint: footprint_at(scene, focus, downscale) as f32,
        near_clip: near_clip(scene, focus),
        why: format!(
            "{reason}; box {:.2} x {:.2} x {:.2} from the sparse points and cameras",
            hi.x - lo.x,
            hi.y - lo.y,
            hi.z - lo.z
        ),
        layout: l,
    })
}

fn unbounded_setup(scene: &Scene, l: Layout, reason: String, downscale: u32) -> SpaceSetup {
    let focus = DVec3::from_array(l.focus);
    // The inner ball holds every camera (and so what they stand among) at full resolution.
    let radius = (l.camera_reach * 1.1).max(1e-3);
    let foot = footprint_at(scene, focus, downscale) / radius;
    SpaceSetup {
        space: Space::Unbounded {
            center: focus.as_vec3().to_array(),
            radius: radius as f32,
        },
        box_min: Vec3::splat(-2.0),
        box_max: Vec3::splat(2.0),
        pixel_footprint: foot as f32,
        near_clip: near_clip(scene, focus),
        why: format!(
            "{reason}; contraction about the cameras' focus ({:.2}, {:.2}, {:.2}), inner radius {radius:.2} (1.1x the farthest camera)",
            focus.x, focus.y, focus.z
        ),
        layout: l,
    }
}

/// Cells along NDC depth: NeRF samples forward-facing scenes with 64 + 128 points per ray.
const NDC_DEPTH_CELLS: f32 = 192.0;

fn forward_setup(scene: &Scene, l: Layout, reason: String, downscale: u32) -> Result<SpaceSetup> {
    // The reference camera: the mean camera (LLFF's recentring), looking along the mean axis,
    // its up the cameras' mean up, the median intrinsics.
    let n = scene.images.len() as f64;
    let center = scene
        .images
        .iter()
        .map(|im| im.pose.center())
        .sum::<DVec3>()
        / n;
    let fwd = scene
        .images
        .iter()
        .map(|im| im.pose.camera_to_world_dir(DVec3::Z))
        .sum::<DVec3>()
        .normalize();
    let down = scene
        .images
        .iter()
        .map(|im| im.pose.camera_to_world_dir(DVec3::Y))
        .sum::<DVec3>();
    let right = down.cross(fwd).normalize();
    let down = fwd.cross(right);
    // Rows: world -> reference camera.
    let rot = DMat3::from_cols(right, down, fwd).transpose();
    let mut cams: Vec<(f64, f64, f64, f64)> = scene
        .images
        .iter()
        .map(|im| {
            let c = scene.camera_of(im);
            let (fx, fy) = c.focal();
            (fx, fy, c.width as f64, c.height as f64)
        })
        .collect();
    cams.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (fx, fy, w, h) = cams[cams.len() / 2];
    // Near: just in front of the nearest scene points (1st percentile depth), else a tenth of the
    // cameras' spread.
    let depths: Vec<f64> = scene
        .points
        .iter()
        .map(|p| (rot * (p.xyz - center)).z)
        .filter(|z| *z > 0.0)
        .collect();
    let spread = scene
        .images
        .iter()
        .map(|im| (im.pose.center() - center).length())
        .fold(0.0, f64::max);
    // Without a sparse model, the nearest of the depth bounds the capture gives (LLFF; NeRF puts
    // its near plane at 0.75 of it).
    let nearest_bound = scene
        .images
        .iter()
        .filter_map(|im| im.depth_bounds.map(|b| b[0]))
        .reduce(f64::min);
    let (near, near_from) = match (quantile(depths, 0.01), nearest_bound) {
        (Some(z), _) => (0.8 * z, "the nearest points"),
        (None, Some(b)) => (0.8 * b, "the capture's nearest depth bound"),
        (None, None) => ((0.1 * spread).max(1e-3), "a tenth of the cameras' spread"),
    };
    let voxel_xy = 2.0 / w as f32 * downscale.max(1) as f32;
    let z_scale = NDC_DEPTH_CELLS * voxel_xy / 2.0;
    let ndc = NdcSpace {
        rotation: rot.as_mat3().transpose().to_cols_array_2d(),
        center: center.as_vec3().to_array(),
        scale_xy: [(2.0 * fx / w) as f32, (2.0 * fy / h) as f32],
        near: near as f32,
        z_scale,
    };
    let space = Space::Ndc(ndc);
    let (lo, hi) = ndc_extent(scene, &space)?;
    Ok(SpaceSetup {
        space,
        box_min: lo,
        box_max: hi,
        pixel_footprint: voxel_xy,
        // The NDC grid starts at the near plane, in front of every camera.
        near_clip: 0.0,
        why: format!(
            "{reason}; NDC of the mean camera, near plane {near:.3} ({near_from}), depth axis sampled in {NDC_DEPTH_CELLS} cells of disparity"
        ),
        layout: l,
    })
}

/// The NDC box every training ray passes through: the image corners' rays of every view, from
/// the near plane to infinity, padded by 2%.
fn ndc_extent(scene: &Scene, space: &Space) -> Result<(Vec3, Vec3)> {
    let Space::Ndc(n) = space else {
        unreachable!("ndc_extent is for NDC spaces")
    };
    let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
    let big = Vec3::splat(1e6);
    for im in &scene.images {
        let cam = scene.camera_of(im);
        for (u, v) in [
            (0.0, 0.0),
            (cam.width as f64, 0.0),
            (0.0, cam.height as f64),
            (cam.width as f64, cam.height as f64),
        ] {
            let d = im
                .pose
                .camera_to_world_dir(cam.unproject(glam::DVec2::new(u, v)))
                .normalize();
            if let Some(crate::space::RayPath::Line { o, d, s0, s1, .. }) =
                space.ray_path(im.pose.center().as_vec3(), d.as_vec3(), -big, big)
            {
                for s in [s0, s1] {
                    let p = o + d * s;
                    lo = lo.min(p);
                    hi = hi.max(p);
                }
            }
        }
    }
    if lo.x > hi.x {
        return Err(Error::invalid(format!(
            "{}: no camera looks past the NDC near plane {:.3}: this capture is not forward-facing (try --space unbounded)",
            scene.source.display(),
            n.near
        )));
    }
    let pad = (hi - lo) * 0.02;
    Ok((lo - pad, hi + pad))
}
