//! Intrinsics for the COLMAP camera models, with projection and unprojection through their lens
//! distortion. Pixel convention (DESIGN.md §2): (0, 0) is the top-left corner of the image and the
//! centre of the first pixel is (0.5, 0.5). Camera frame: OpenCV (x right, y down, z forward).

use glam::{DVec2, DVec3};
use serde::{Deserialize, Serialize};

/// The COLMAP camera models, with COLMAP's numeric ids (0-10).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum CameraModel {
    SimplePinhole,
    Pinhole,
    SimpleRadial,
    Radial,
    OpenCv,
    OpenCvFisheye,
    FullOpenCv,
    Fov,
    SimpleRadialFisheye,
    RadialFisheye,
    ThinPrismFisheye,
}

const ALL_MODELS: [CameraModel; 11] = [
    CameraModel::SimplePinhole,
    CameraModel::Pinhole,
    CameraModel::SimpleRadial,
    CameraModel::Radial,
    CameraModel::OpenCv,
    CameraModel::OpenCvFisheye,
    CameraModel::FullOpenCv,
    CameraModel::Fov,
    CameraModel::SimpleRadialFisheye,
    CameraModel::RadialFisheye,
    CameraModel::ThinPrismFisheye,
];

impl CameraModel {
    pub fn id(self) -> i32 {
        ALL_MODELS.iter().position(|&m| m == self).unwrap() as i32
    }

    /// The model for a COLMAP id; `None` for ids outside 0-10.
    pub fn from_id(id: i32) -> Option<Self> {
        usize::try_from(id)
            .ok()
            .and_then(|i| ALL_MODELS.get(i).copied())
    }

    /// COLMAP's name, as in cameras.txt.
    pub fn name(self) -> &'static str {
        match self {
            CameraModel::SimplePinhole => "SIMPLE_PINHOLE",
            CameraModel::Pinhole => "PINHOLE",
            CameraModel::SimpleRadial => "SIMPLE_RADIAL",
            CameraModel::Radial => "RADIAL",
            CameraModel::OpenCv => "OPENCV",
            CameraModel::OpenCvFisheye => "OPENCV_FISHEYE",
            CameraModel::FullOpenCv => "FULL_OPENCV",
            CameraModel::Fov => "FOV",
            CameraModel::SimpleRadialFisheye => "SIMPLE_RADIAL_FISHEYE",
            CameraModel::RadialFisheye => "RADIAL_FISHEYE",
            CameraModel::ThinPrismFisheye => "THIN_PRISM_FISHEYE",
        }
    }

    pub fn from_name(name: &str) -> Option<Self> {
        ALL_MODELS.iter().copied().find(|m| m.name() == name)
    }

    /// Number of parameters COLMAP stores for this model.
    pub fn num_params(self) -> usize {
        match self {
            CameraModel::SimplePinhole => 3,
            CameraModel::Pinhole => 4,
            CameraModel::SimpleRadial => 4,
            CameraModel::Radial => 5,
            CameraModel::OpenCv => 8,
            CameraModel::OpenCvFisheye => 8,
            CameraModel::FullOpenCv => 12,
            CameraModel::Fov => 5,
            CameraModel::SimpleRadialFisheye => 4,
            CameraModel::RadialFisheye => 5,
            CameraModel::ThinPrismFisheye => 12,
        }
    }

    /// Whether objnerf can project through this model. FOV and THIN_PRISM_FISHEYE are rare in
    /// practice and are rejected when a scene is read rather than projected wrongly.
    pub fn is_supported(self) -> bool {
        !matches!(self, CameraModel::Fov | CameraModel::ThinPrismFisheye)
    }

    fn single_focal(self) -> bool {
        matches!(
            self,
            CameraModel::SimplePinhole
                | CameraModel::SimpleRadial
                | CameraModel::Radial
                | CameraModel::SimpleRadialFisheye
                | CameraModel::RadialFisheye
        )
    }
}

/// One camera's intrinsics: a COLMAP model, the image size in pixels and the model's parameters
/// in COLMAP's order (focal length(s), principal point, then distortion).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Camera {
    pub model: CameraModel,
    pub width: u32,
    pub height: u32,
    pub params: Vec<f64>,
}

impl Camera {
    /// A camera, checked: supported model, right parameter count, finite positive focal length,
    /// non-zero size. The error is a sentence for the reader to wrap with the file name.
    pub fn new(
        model: CameraModel,
        width: u32,
        height: u32,
        params: Vec<f64>,
    ) -> std::result::Result<Self, String> {
        if !model.is_supported() {
            return Err(format!(
                "camera model {} (id {}) is not supported; use one of SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV, OPENCV_FISHEYE, FULL_OPENCV, SIMPLE_RADIAL_FISHEYE, RADIAL_FISHEYE",
                model.name(),
                model.id()
            ));
        }
        if params.len() != model.num_params() {
            return Err(format!(
                "camera model {} takes {} parameters, got {}",
                model.name(),
                model.num_params(),
                params.len()
            ));
        }
        if width == 0 || height == 0 {
            return Err(format!("camera size {width}x{height} is empty"));
        }
        if params.iter().any(|p| !p.is_finite()) {
            return Err(format!("camera parameters are not finite: {params:?}"));
        }
        let cam = Camera {
            model,
            width,
            height,
            params,
        };
        let (fx, fy) = cam.focal();
        if fx <= 0.0 || fy <= 0.0 {
            return Err(format!(
                "camera focal length must be positive, got ({fx}, {fy})"
            ));
        }
        Ok(cam)
    }

    /// A pinhole camera (no distortion).
    pub fn pinhole(width: u32, height: u32, fx: f64, fy: f64, cx: f64, cy: f64) -> Self {
        Camera {
            model: CameraModel::Pinhole,
            width,
            height,
            params: vec![fx, fy, cx, cy],
        }
    }

    pub fn focal(&self) -> (f64, f64) {
        if self.model.single_focal() {
            (self.params[0], self.params[0])
        } else {
            (self.params[0], self.params[1])
        }
    }

    pub fn principal_point(&self) -> (f64, f64) {
        if self.model.single_focal() {
            (self.params[1], self.params[2])
        } else {
            (self.params[2], self.params[3])
        }
    }

    fn extra(&self) -> &[f64] {
        let start = if self.model.single_focal() { 3 } else { 4 };
        &self.params[start..]
    }

    /// True when the model has no distortion terms, or all of them are zero.
    pub fn is_pinhole(&self) -> bool {
        let fisheye = matches!(
            self.model,
            CameraModel::OpenCvFisheye
                | CameraModel::SimpleRadialFisheye
                | CameraModel::RadialFisheye
        );
        !fisheye && self.extra().iter().all(|&k| k == 0.0)
    }

    /// Horizontal and vertical field of view in radians (pinhole approximation).
    pub fn fov(&self) -> (f64, f64) {
        let (fx, fy) = self.focal();
        (
            2.0 * (0.5 * self.width as f64 / fx).atan(),
            2.0 * (0.5 * self.height as f64 / fy).atan(),
        )
    }

    /// Apply the lens distortion to normalised image coordinates (x/z, y/z), as COLMAP does.
    pub fn distort(&self, p: DVec2) -> DVec2 {
        let (u, v) = (p.x, p.y);
        let k = self.extra();
        match self.model {
            CameraModel::SimplePinhole | CameraModel::Pinhole => p,
            CameraModel::SimpleRadial => {
                let r2 = u * u + v * v;
                p * (1.0 + k[0] * r2)
            }
            CameraModel::Radial => {
                let r2 = u * u + v * v;
                p * (1.0 + k[0] * r2 + k[1] * r2 * r2)
            }
            CameraModel::OpenCv => {
                let (k1, k2, p1, p2) = (k[0], k[1], k[2], k[3]);
                let (u2, v2, uv) = (u * u, v * v, u * v);
                let r2 = u2 + v2;
                let radial = k1 * r2 + k2 * r2 * r2;
                DVec2::new(
                    u + u * radial + 2.0 * p1 * uv + p2 * (r2 + 2.0 * u2),
                    v + v * radial + 2.0 * p2 * uv + p1 * (r2 + 2.0 * v2),
                )
            }
            CameraModel::FullOpenCv => {
                let (k1, k2, p1, p2, k3, k4, k5, k6) =
                    (k[0], k[1], k[2], k[3], k[4], k[5], k[6], k[7]);
                let (u2, v2, uv) = (u * u, v * v, u * v);
                let r2 = u2 + v2;
                let (r4, r6) = (r2 * r2, r2 * r2 * r2);
                let radial =
                    (1.0 + k1 * r2 + k2 * r4 + k3 * r6) / (1.0 + k4 * r2 + k5 * r4 + k6 * r6);
                DVec2::new(
                    u * radial + 2.0 * p1 * uv + p2 * (r2 + 2.0 * u2),
                    v * radial + 2.0 * p2 * uv + p1 * (r2 + 2.0 * v2),
                )
            }
            CameraModel::OpenCvFisheye
            | CameraModel::SimpleRadialFisheye
            | CameraModel::RadialFisheye => {
                let r = (u * u + v * v).sqrt();
                if r < f64::EPSILON {
                    return p;
                }
                let theta = r.atan();
                let t2 = theta * theta;
                let poly = match self.model {
                    CameraModel::OpenCvFisheye => {
                        1.0 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3])))
                    }
                    CameraModel::SimpleRadialFisheye => 1.0 + k[0] * t2,
                    _ => 1.0 + t2 * (k[0] + t2 * k[1]),
                };
                p * (theta * poly / r)
            }
            CameraModel::Fov | CameraModel::ThinPrismFisheye => {
                unreachable!("unsupported models are rejected in Camera::new")
            }
        }
    }

    /// Invert [`Camera::distort`] by Newton's method with a numeric Jacobian (COLMAP's approach).
    pub fn undistort(&self, target: DVec2) -> DVec2 {
        if self.is_pinhole() {
            return target;
        }
        let mut p = target;
        const EPS: f64 = 1e-9;
        for _ in 0..100 {
            let f = self.distort(p) - target;
            if f.length_squared() < 1e-28 {
                break;
            }
            let hx = EPS.max(p.x.abs() * 1e-6);
            let hy = EPS.max(p.y.abs() * 1e-6);
            let dx = (self.distort(p + DVec2::new(hx, 0.0))
                - self.distort(p - DVec2::new(hx, 0.0)))
                / (2.0 * hx);
            let dy = (self.distort(p + DVec2::new(0.0, hy))
                - self.distort(p - DVec2::new(0.0, hy)))
                / (2.0 * hy);
            let det = dx.x * dy.y - dy.x * dx.y;
            if det.abs() < 1e-300 {
                break;
            }
            let step = DVec2::new(
                (dy.y * f.x - dy.x * f.y) / det,
                (-dx.y * f.x + dx.x * f.y) / det,
            );
            p -= step;
            if step.length_squared() < 1e-30 {
                break;
            }
        }
        p
    }

    /// Project a point in the camera frame to pixel coordinates; `None` behind the camera.
    pub fn project(&self, p_cam: DVec3) -> Option<DVec2> {
        if p_cam.z <= 1e-12 {
            return None;
        }
        let d = self.distort(DVec2::new(p_cam.x / p_cam.z, p_cam.y / p_cam.z));
        let (fx, fy) = self.focal();
        let (cx, cy) = self.principal_point();
        Some(DVec2::new(fx * d.x + cx, fy * d.y + cy))
    }

    /// The camera-frame direction (z = 1) through a pixel position.
    pub fn unproject(&self, pixel: DVec2) -> DVec3 {
        let (fx, fy) = self.focal();
        let (cx, cy) = self.principal_point();
        let n = self.undistort(DVec2::new((pixel.x - cx) / fx, (pixel.y - cy) / fy));
        DVec3::new(n.x, n.y, 1.0)
    }

    /// The direction through the centre of pixel (col, row).
    pub fn pixel_center_ray(&self, col: u32, row: u32) -> DVec3 {
        self.unproject(DVec2::new(col as f64 + 0.5, row as f64 + 0.5))
    }

    /// Whether a pixel position lies inside the image.
    pub fn contains(&self, pixel: DVec2) -> bool {
        pixel.x >= 0.0
            && pixel.y >= 0.0
            && pixel.x < self.width as f64
            && pixel.y < self.height as f64
    }

    /// The same camera for images resized to `width` x `height`: focal lengths and principal
    /// point scale with the image (corner-origin pixels, so cx' = cx * width / W exactly).
    pub fn resized(&self, width: u32, height: u32) -> Camera {
        let sx = width as f64 / self.width as f64;
        let sy = height as f64 / self.height as f64;
        let mut params = self.params.clone();
        if self.model.single_focal() {
            // One focal length: scale it by the mean factor (equal for aspect-preserving resizes).
            params[0] *= 0.5 * (sx + sy);
            params[1] *= sx;
            params[2] *= sy;
        } else {
            params[0] *= sx;
            params[1] *= sy;
            params[2] *= sx;
            params[3] *= sy;
        }
        Camera {
            model: self.model,
            width,
            height,
            params,
        }
    }

    /// The camera for images binned by an integer factor: each output pixel averages a `factor`
    /// x `factor` block, the last columns and rows that do not fill a block are dropped (the size
    /// is floor(W / factor) x floor(H / factor), as nerfstudio sizes its downscaled images), so
    /// every intrinsic scales by exactly 1/factor (nerfstudio's `rescale_output_resolution`):
    /// pixel centre u' + 0.5 of the binned image is u = factor * (u' + 0.5) of the original.
    /// This is how training, rendering and evaluation downscale (`field::rays::load_views`).
    pub fn binned(&self, factor: u32) -> Camera {
        let f = factor.max(1);
        let s = 1.0 / f as f64;
        let mut params = self.params.clone();
        let n = if self.model.single_focal() { 3 } else { 4 };
        for p in &mut params[..n] {
            *p *= s;
        }
        Camera {
            model: self.model,
            width: self.width / f,
            height: self.height / f,
            params,
        }
    }

    /// The camera for images downscaled by an integer factor (sizes rounded as image resizers do).
    pub fn downscaled(&self, factor: u32) -> Camera {
        let f = factor.max(1);
        let w = ((self.width as f64 / f as f64).round() as u32).max(1);
        let h = ((self.height as f64 / f as f64).round() as u32).max(1);
        self.resized(w, h)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cameras() -> Vec<Camera> {
        vec![
            Camera::new(
                CameraModel::SimplePinhole,
                640,
                480,
                vec![500.0, 320.0, 240.0],
            )
            .unwrap(),
            Camera::new(
                CameraModel::Pinhole,
                640,
                480,
                vec![500.0, 510.0, 321.0, 239.0],
            )
            .unwrap(),
            Camera::new(
                CameraModel::SimpleRadial,
                640,
                480,
                vec![500.0, 320.0, 240.0, 0.05],
            )
            .unwrap(),
            Camera::new(
                CameraModel::Radial,
                640,
                480,
                vec![500.0, 320.0, 240.0, 0.05, -0.02],
            )
            .unwrap(),
            Camera::new(
                CameraModel::OpenCv,
                1080,
                1920,
                vec![
                    1375.52,
                    1374.49,
                    554.558,
                    965.268,
                    0.0578421,
                    -0.0805099,
                    -0.000980296,
                    0.00015575,
                ],
            )
            .unwrap(),
            Camera::new(
                CameraModel::OpenCvFisheye,
                640,
                480,
                vec![300.0, 300.0, 320.0, 240.0, 0.1, -0.05, 0.01, -0.002],
            )
            .unwrap(),
            Camera::new(
                CameraModel::FullOpenCv,
                640,
                480,
                vec![
                    500.0, 500.0, 320.0, 240.0, 0.1, -0.05, 0.001, -0.001, 0.01, 0.02, -0.01, 0.003,
                ],
            )
            .unwrap(),
            Camera::new(
                CameraModel::SimpleRadialFisheye,
                640,
                480,
                vec![300.0, 320.0, 240.0, 0.05],
            )
            .unwrap(),
            Camera::new(
                CameraModel::RadialFisheye,
                640,
                480,
                vec![300.0, 320.0, 240.0, 0.05, -0.01],
            )
            .unwrap(),
        ]
    }

    /// Binning by f (sizes floored, intrinsics / f) puts every point at the original pixel / f,
    /// for every model (distortion acts on normalised coordinates and is unchanged).
    #[test]
    fn binned_projects_to_the_pixel_over_f() {
        for cam in cameras() {
            let cam = Camera {
                width: 641,
                height: 481,
                ..cam
            };
            for f in [2u32, 3] {
                let b = cam.binned(f);
                assert_eq!((b.width, b.height), (641 / f, 481 / f));
                for p in [DVec3::new(0.1, -0.2, 1.0), DVec3::new(-0.3, 0.25, 2.0)] {
                    let (full, small) = (cam.project(p).unwrap(), b.project(p).unwrap());
                    assert!((small * f as f64 - full).length() < 1e-9, "{:?}", cam.model);
                }
            }
        }
    }

    #[test]
    fn pixel_ray_pixel_round_trip_every_model() {
        for cam in cameras() {
            for &(x, y) in &[
                (0.5, 0.5),
                (100.25, 37.5),
                (cam.width as f64 - 0.5, cam.height as f64 - 0.5),
                (320.0, 240.0),
            ] {
                let px = DVec2::new(x, y);
                let ray = cam.unproject(px);
                let back = cam.project(ray * 2.7).unwrap();
                assert!(
                    (back - px).length() < 1e-4,
                    "{:?}: {px} -> {back}",
                    cam.model
                );
            }
        }
    }

    #[test]
    fn ids_and_names_round_trip() {
        for id in 0..11 {
            let m = CameraModel::from_id(id).unwrap();
            assert_eq!(m.id(), id);
            assert_eq!(CameraModel::from_name(m.name()), Some(m));
        }
        assert_eq!(CameraModel::from_id(11), None);
        assert_eq!(CameraModel::from_id(-1), None);
    }

    #[test]
    fn rejects_bad_cameras() {
        assert!(Camera::new(CameraModel::Fov, 10, 10, vec![1.0; 5]).is_err());
        assert!(Camera::new(CameraModel::Pinhole, 10, 10, vec![1.0; 3]).is_err());
        assert!(Camera::new(CameraModel::Pinhole, 10, 10, vec![f64::NAN, 1.0, 1.0, 1.0]).is_err());
        assert!(Camera::new(CameraModel::Pinhole, 0, 10, vec![1.0; 4]).is_err());
    }

    #[test]
    fn downscale_keeps_pixel_centres() {
        let cam = Camera::pinhole(800, 800, 1111.11, 1111.11, 400.0, 400.0);
        let small = cam.downscaled(4);
        assert_eq!((small.width, small.height), (200, 200));
        // The image centre maps to the image centre, and so does the ray through it.
        let r_big = cam.unproject(DVec2::new(400.0, 400.0));
        let r_small = small.unproject(DVec2::new(100.0, 100.0));
        assert!((r_big - r_small).length() < 1e-12);
    }
}
