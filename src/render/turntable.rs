//! Turntable renders of an object field: cameras around the object's box, looking at its centre,
//! the world's up kept up, at the elevation and over the arc the training cameras saw it from
//! (all the way round where they surround it); written as numbered PNGs and an animated GIF.

use crate::error::{Error, Result};
use crate::field::{eval::render_view, Field, RayCamera, RenderOptions};
use crate::scene::{camera::Camera, frames::Pose};
use crate::util::atomic::{save_image_atomic, write_bytes_atomic};
use crate::util::stats::median;
use crate::util::{Detail, Progress};
use glam::DVec3;
use image::{Delay, Frame, RgbaImage};
use serde::Serialize;
use std::path::Path;

#[derive(Clone, Debug)]
pub struct TurntableOptions {
    pub frames: usize,
    pub width: u32,
    pub height: u32,
    /// Camera height above the object's centre, degrees (default: the training cameras' median,
    /// else [`DEFAULT_ELEVATION_DEG`]).
    pub elevation_deg: Option<f64>,
    /// Horizontal field of view, degrees.
    pub fov_deg: f64,
}

impl Default for TurntableOptions {
    fn default() -> Self {
        TurntableOptions {
            frames: 24,
            width: 320,
            height: 240,
            elevation_deg: None,
            fov_deg: 40.0,
        }
    }
}

/// The elevation of a turntable with no cameras to follow.
pub const DEFAULT_ELEVATION_DEG: f64 = 25.0;
/// Cameras all round leave no gap in azimuth wider than this: the turntable goes all the way
/// round. A wider gap is a side no photo saw, and the turntable sweeps the arc they did see.
pub const FULL_ORBIT_MAX_GAP_DEG: f64 = 90.0;
/// The elevations a turntable follows the cameras to (a capture from straight above or below
/// would spin the object about the view axis).
const ELEVATION_RANGE_DEG: (f64, f64) = (-30.0, 75.0);

/// Where a turntable's cameras go around the object's centre: the training cameras' directions
/// decide the elevation and the arc of azimuths, so the frames show sides the photos saw.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Orbit {
    /// Above the object's centre, degrees.
    pub elevation_deg: f64,
    /// The first frame's azimuth about up, degrees from `up.any_orthonormal_vector()`.
    pub start_deg: f64,
    /// The arc covered: 360 goes round once; less sweeps out to its end and back.
    pub arc_deg: f64,
}

impl Orbit {
    /// Round the object at `elevation_deg`, from azimuth 0.
    pub fn full(elevation_deg: f64) -> Orbit {
        Orbit {
            elevation_deg,
            start_deg: 0.0,
            arc_deg: 360.0,
        }
    }

    /// The orbit the cameras at `seen_from` suggest around `centre`: their median elevation
    /// (unless `elevation_deg` is given), all the way round from the first camera's azimuth
    /// when no gap between their azimuths exceeds [`FULL_ORBIT_MAX_GAP_DEG`], else the arc
    /// they cover, from one end.
    pub fn following(
        centre: DVec3,
        up: DVec3,
        seen_from: &[DVec3],
        elevation_deg: Option<f64>,
    ) -> Orbit {
        let (side, fwd) = azimuth_axes(up);
        let up = up.normalize();
        let dirs: Vec<DVec3> = seen_from
            .iter()
            .filter_map(|c| (*c - centre).try_normalize())
            .collect();
        let elevation = elevation_deg.unwrap_or_else(|| {
            let e = dirs
                .iter()
                .map(|d| d.dot(up).clamp(-1.0, 1.0).asin().to_degrees())
                .collect();
            median(e).map_or(DEFAULT_ELEVATION_DEG, |m| {
                m.clamp(ELEVATION_RANGE_DEG.0, ELEVATION_RANGE_DEG.1)
            })
        });
        let azimuth = |d: &DVec3| d.dot(fwd).atan2(d.dot(side)).to_degrees().rem_euclid(360.0);
        let mut az: Vec<f64> = dirs
            .iter()
            .filter(|d| d.cross(up).length() > 1e-6)
            .map(azimuth)
            .collect();
        let Some(&first) = az.first() else {
            return Orbit::full(elevation);
        };
        az.sort_by(f64::total_cmp);
        // The widest gap between neighbouring azimuths, the last wrapping round to the first
        // (a lone camera leaves a gap of 360).
        let n = az.len();
        let (gap, gap_end) = (0..n)
            .map(|i| match az.get(i + 1) {
                Some(&next) => (next - az[i], next),
                None => (az[0] + 360.0 - az[i], az[0]),
            })
            .max_by(|a, b| a.0.total_cmp(&b.0))
            .expect("one azimuth at least");
        let (start_deg, arc_deg) = if gap <= FULL_ORBIT_MAX_GAP_DEG {
            (first, 360.0)
        } else {
            (gap_end, 360.0 - gap)
        };
        Orbit {
            elevation_deg: elevation,
            start_deg,
            arc_deg,
        }
    }

    /// Frame `i` of `frames`'s azimuth, degrees: evenly round a full orbit; out along the arc
    /// and back (eased at the ends, so the loop has no jump) on a sweep.
    fn azimuth_deg(&self, i: usize, frames: usize) -> f64 {
        let f = i as f64 / frames.max(1) as f64;
        if self.arc_deg >= 360.0 {
            self.start_deg + 360.0 * f
        } else {
            self.start_deg + self.arc_deg * 0.5 * (1.0 - (std::f64::consts::TAU * f).cos())
        }
    }
}

/// The axes azimuth is measured in about `up`.
fn azimuth_axes(up: DVec3) -> (DVec3, DVec3) {
    let up = up.normalize();
    let side = up.any_orthonormal_vector();
    (side, up.cross(side))
}

/// The turntable's views: the box `lo..hi` (e.g. the mesh's bounds) in frame from every
/// direction of `orbit`.
pub fn turntable_views(
    lo: DVec3,
    hi: DVec3,
    up: DVec3,
    orbit: &Orbit,
    opts: &TurntableOptions,
) -> Vec<RayCamera> {
    let centre = 0.5 * (lo + hi);
    let radius = 0.5 * (hi - lo).length();
    let fx = 0.5 * opts.width as f64 / (0.5 * opts.fov_deg.to_radians()).tan();
    // The narrower side's half-angle decides the distance that fits a sphere around the box.
    let half = (0.5 * opts.width.min(opts.height) as f64 / fx).atan();
    let dist = radius / half.sin() * 1.05;
    let up = up.normalize();
    let (side, fwd) = azimuth_axes(up);
    let camera = Camera::pinhole(
        opts.width,
        opts.height,
        fx,
        fx,
        0.5 * opts.width as f64,
        0.5 * opts.height as f64,
    );
    let (se, ce) = orbit.elevation_deg.to_radians().sin_cos();
    (0..opts.frames)
        .map(|i| {
            let a = orbit.azimuth_deg(i, opts.frames).to_radians();
            let dir = (side * a.cos() + fwd * a.sin()) * ce + up * se;
            let pose = Pose::look_at(centre + dir * dist, centre, up);
            RayCamera::new(format!("frame_{i:03}"), camera.clone(), pose)
        })
        .collect()
}

/// Render `orbit` around `lo..hi` on `background` and write `dir/frame_NNN.png` and `gif`
/// (looping, 12 fps). `progress` hears one step per frame of the current stage.
#[allow(clippy::too_many_arguments)]
pub fn write_turntable(
    field: &Field,
    (lo, hi): (DVec3, DVec3),
    up: DVec3,
    orbit: &Orbit,
    opts: &TurntableOptions,
    background: [f32; 3],
    dir: &Path,
    gif: &Path,
    progress: &dyn Progress,
) -> Result<usize> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let render = RenderOptions::default();
    let mut frames = Vec::new();
    for (i, v) in turntable_views(lo, hi, up, orbit, opts).iter().enumerate() {
        let r = render_view(field, &render, v, background);
        let img = r.rgb8();
        let file = format!("{}.png", v.name);
        save_image_atomic(&dir.join(&file), &img.clone().into())?;
        frames.push(img);
        progress.advance(i as u64 + 1, Detail::Item(&file));
    }
    let mut bytes = Vec::new();
    {
        let mut enc = image::codecs::gif::GifEncoder::new_with_speed(&mut bytes, 10);
        enc.set_repeat(image::codecs::gif::Repeat::Infinite)
            .map_err(|e| Error::image(gif, e))?;
        for f in &frames {
            let rgba: RgbaImage = image::DynamicImage::ImageRgb8(f.clone()).into_rgba8();
            let delay = Delay::from_numer_denom_ms(1000, 12);
            enc.encode_frame(Frame::from_parts(rgba, 0, 0, delay))
                .map_err(|e| Error::image(gif, e))?;
        }
    }
    write_bytes_atomic(gif, &bytes)?;
    Ok(frames.len())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Camera centres at `elev_deg` above the origin, at the given azimuths about +Z (measured
    /// in the turntable's own azimuth axes), 3 units away.
    fn cameras(elev_deg: f64, azimuths_deg: &[f64]) -> Vec<DVec3> {
        let (side, fwd) = azimuth_axes(DVec3::Z);
        let (se, ce) = elev_deg.to_radians().sin_cos();
        azimuths_deg
            .iter()
            .map(|a| {
                let a = a.to_radians();
                ((side * a.cos() + fwd * a.sin()) * ce + DVec3::Z * se) * 3.0
            })
            .collect()
    }

    #[test]
    fn cameras_all_round_give_a_full_orbit_at_their_elevation() {
        let az: Vec<f64> = (0..12).map(|i| 100.0 + 30.0 * i as f64).collect();
        let o = Orbit::following(DVec3::ZERO, DVec3::Z, &cameras(40.0, &az), None);
        assert_eq!(o.arc_deg, 360.0);
        assert!((o.start_deg - 100.0).abs() < 1e-9, "{o:?}");
        assert!((o.elevation_deg - 40.0).abs() < 1e-9, "{o:?}");
        let given = Orbit::following(DVec3::ZERO, DVec3::Z, &cameras(40.0, &az), Some(10.0));
        assert_eq!(given.elevation_deg, 10.0);
        assert_eq!(
            Orbit::following(DVec3::ZERO, DVec3::Z, &[], None),
            Orbit::full(25.0)
        );
    }

    #[test]
    fn cameras_on_one_side_give_a_sweep_that_stays_within_their_arc() {
        // A forward capture across the wrap at 0: azimuths 340..20 degrees.
        let az: Vec<f64> = (0..9).map(|i| (340.0 + 5.0 * i as f64) % 360.0).collect();
        let o = Orbit::following(DVec3::ZERO, DVec3::Z, &cameras(10.0, &az), None);
        assert!((o.arc_deg - 40.0).abs() < 1e-9, "{o:?}");
        assert!((o.start_deg - 340.0).abs() < 1e-9, "{o:?}");
        let opts = TurntableOptions::default();
        let views = turntable_views(DVec3::splat(-0.5), DVec3::splat(0.5), DVec3::Z, &o, &opts);
        let (side, fwd) = azimuth_axes(DVec3::Z);
        for v in &views {
            let c = v.pose.center();
            let a = c.dot(fwd).atan2(c.dot(side)).to_degrees().rem_euclid(360.0);
            let from_start = (a - 340.0).rem_euclid(360.0);
            assert!(from_start <= 40.0 + 1e-6, "{} at {a}", v.name);
            let e = c.normalize().dot(DVec3::Z).asin().to_degrees();
            assert!((e - 10.0).abs() < 1e-6);
        }
        // Out to the far end and back.
        let last = |i: usize| views[i].pose.center();
        assert!((last(0) - last(opts.frames / 2)).length() > 0.5);
    }
}
