//! The model as COLMAP stores it: ids everywhere. The binary and text readers fill these; the
//! model turns them into a `Scene` and back.

pub(super) struct RawCamera {
    pub(super) id: u32,
    pub(super) model_id: i32,
    pub(super) width: u64,
    pub(super) height: u64,
    pub(super) params: Vec<f64>,
}

pub(super) struct RawImage {
    pub(super) id: u32,
    pub(super) qvec: [f64; 4],
    pub(super) tvec: [f64; 3],
    pub(super) camera_id: u32,
    pub(super) name: String,
    /// (x, y, point3D id or -1)
    pub(super) points2d: Vec<(f64, f64, i64)>,
}

pub(super) struct RawPoint {
    pub(super) id: u64,
    pub(super) xyz: [f64; 3],
    pub(super) rgb: [u8; 3],
    pub(super) error: f64,
    /// (image id, point2D index)
    pub(super) track: Vec<(u32, u32)>,
}
