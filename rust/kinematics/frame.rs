//! One rigid frame (rotation as three column vectors + translation): a lane of `Frames`.

use nalgebra::{Matrix3, Vector3};

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    /// Columns of the rotation matrix: the frame's x, y, z axes in the world frame.
    pub cols: [Vector3<f64>; 3],
    /// Origin in the world frame (mm).
    pub t: Vector3<f64>,
}

impl Frame {
    pub fn rotation(&self) -> Matrix3<f64> {
        Matrix3::from_columns(&self.cols)
    }

    /// Writes the 4x4 homogeneous matrix, row-major, into `out` (16 values).
    pub fn write_homogeneous(&self, out: &mut [f64]) {
        for r in 0..3 {
            for c in 0..3 {
                out[r * 4 + c] = self.cols[c][r];
            }
            out[r * 4 + 3] = self.t[r];
        }
        out[12..16].copy_from_slice(&[0.0, 0.0, 0.0, 1.0]);
    }
}
