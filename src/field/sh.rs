//! The real spherical-harmonic basis of a direction, to degree 3: SH colour's (on the grid, to
//! degree 2) and a colour network's view and reflection inputs.

use glam::Vec3;

pub fn sh_coeffs(degree: u32) -> usize {
    ((degree + 1) * (degree + 1)) as usize
}

/// The most terms of a direction's SH basis: degree 3, which only a colour network's view input
/// takes (SH colour on the grid stops at degree 2: its 27 colour channels fill
/// [`MAX_CHANNELS`](super::model::MAX_CHANNELS)).
pub const SH_TERMS: usize = 16;

/// Real spherical-harmonic basis (the constants of Plenoxels/PlenOctrees) for a unit direction.
#[inline]
pub fn sh_basis(degree: u32, d: Vec3, out: &mut [f32; SH_TERMS]) {
    const C0: f32 = 0.282_094_8;
    const C1: f32 = 0.488_602_5;
    const C2: [f32; 5] = [
        1.092_548_4,
        -1.092_548_4,
        0.315_391_57,
        -1.092_548_4,
        0.546_274_2,
    ];
    out[0] = C0;
    if degree >= 1 {
        out[1] = -C1 * d.y;
        out[2] = C1 * d.z;
        out[3] = -C1 * d.x;
    }
    if degree >= 2 {
        let (x, y, z) = (d.x, d.y, d.z);
        out[4] = C2[0] * x * y;
        out[5] = C2[1] * y * z;
        out[6] = C2[2] * (2.0 * z * z - x * x - y * y);
        out[7] = C2[3] * x * z;
        out[8] = C2[4] * (x * x - y * y);
    }
    if degree >= 3 {
        const C3: [f32; 7] = [
            -0.590_043_6,
            2.890_611_4,
            -0.457_045_8,
            0.373_176_33,
            -0.457_045_8,
            1.445_305_7,
            -0.590_043_6,
        ];
        let (x, y, z) = (d.x, d.y, d.z);
        let (xx, yy, zz) = (x * x, y * y, z * z);
        out[9] = C3[0] * y * (3.0 * xx - yy);
        out[10] = C3[1] * x * y * z;
        out[11] = C3[2] * y * (4.0 * zz - xx - yy);
        out[12] = C3[3] * z * (2.0 * zz - 3.0 * xx - 3.0 * yy);
        out[13] = C3[4] * x * (4.0 * zz - xx - yy);
        out[14] = C3[5] * z * (xx - yy);
        out[15] = C3[6] * x * (xx - 3.0 * yy);
    }
}
