//! SO(3) helpers for the pose model: logarithm, inverse right Jacobian, quaternions (w, x, y, z).

use nalgebra::{Matrix3, Quaternion, Rotation3, UnitQuaternion, Vector3};

/// Unit quaternion `[w, x, y, z]` of a rotation matrix, sign chosen with `w >= 0`.
pub fn quaternion_from_matrix(r: &Matrix3<f64>) -> [f64; 4] {
    let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(*r));
    let s = if q.w < 0.0 { -1.0 } else { 1.0 };
    [s * q.w, s * q.i, s * q.j, s * q.k]
}

/// Rotation matrix of a quaternion `[w, x, y, z]` (normalised here; the caller has checked it is
/// not zero).
pub fn matrix_from_quaternion(q: &[f64]) -> Matrix3<f64> {
    UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3])).to_rotation_matrix().into_inner()
}

/// Rotation vector `log(R)` (rad), through the quaternion so that it stays accurate near π.
pub fn log(r: &Matrix3<f64>) -> Vector3<f64> {
    let [w, x, y, z] = quaternion_from_matrix(r);
    let v = Vector3::new(x, y, z);
    let s = v.norm();
    if s < 1e-12 {
        // θ ≈ 2 s and axis = v / s, so log ≈ 2 v.
        return 2.0 * v;
    }
    v * (2.0 * s.atan2(w) / s)
}

fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// Inverse right Jacobian of SO(3): `log(exp(φ)·exp(δ)) ≈ φ + J_r⁻¹(φ) δ`.
pub fn right_jacobian_inverse(phi: &Vector3<f64>) -> Matrix3<f64> {
    let theta = phi.norm();
    let k = skew(phi);
    // Series limit of 1/θ² − (1+cos θ)/(2θ sin θ) as θ → 0 is 1/12.
    let c = if theta < 1e-4 {
        1.0 / 12.0 + theta * theta / 720.0
    } else {
        1.0 / (theta * theta) - (1.0 + theta.cos()) / (2.0 * theta * theta.sin())
    };
    Matrix3::identity() + 0.5 * k + c * k * k
}
