//! A rigid frame (rotation as three column vectors + translation), updated in place by
//! elementary transforms.

use super::Op;
use nalgebra::{Matrix3, Vector3};

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    /// Columns of the rotation matrix: the frame's x, y, z axes in the world frame.
    pub cols: [Vector3<f64>; 3],
    /// Origin in the world frame (mm).
    pub t: Vector3<f64>,
}

impl Frame {
    pub fn identity() -> Self {
        Self {
            cols: [Vector3::x(), Vector3::y(), Vector3::z()],
            t: Vector3::zeros(),
        }
    }

    /// Post-multiplies by the elementary transform `op` with value `v` (mm for a translation;
    /// a rotation uses its precomputed sine and cosine `s`, `c`).
    #[inline]
    pub fn apply(&mut self, op: &Op, (v, s, c): (f64, f64, f64)) {
        let k = op.axis;
        if op.rotation {
            // R·R_k(v) mixes the two other columns (i, j) = (k+1, k+2) mod 3.
            let (i, j) = ((k + 1) % 3, (k + 2) % 3);
            let (ci, cj) = (self.cols[i], self.cols[j]);
            self.cols[i] = ci * c + cj * s;
            self.cols[j] = cj * c - ci * s;
        } else {
            self.t += self.cols[k] * v;
        }
    }

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
