//! Closed-form start for the cable model's anchor `P0` and sensor zero `L0`.
//!
//! `‖p_i − P0‖ = L_i + L0`, squared: `‖p_i‖² − L_i² = 2 p_i·P0 + 2 L_i L0 + c` with
//! `c = L0² − ‖P0‖²` — linear in `(P0, L0, c)`. Solved by least squares (SVD, so a degenerate
//! set of positions is reported instead of returning garbage). Exact on noiseless data.

use crate::error::{check_kinematic_input, CoreError, CoreResult};
use nalgebra::{DMatrix, DVector};
use std::cmp::Ordering;

/// Anchor `P0` (mm, base frame) and `cable_offset` `L0` (mm) from tool points `p` (m, 3)
/// row-major and cable lengths `l` (m).
///
/// Errors: `Shape` (lengths, fewer than 5 samples), `NonFinite`, `OutOfRange`, `Singular` (positions that do
/// not determine the anchor, e.g. all on one plane through a line of symmetry).
pub fn cable_initial_guess(p: &[f64], l: &[f64]) -> CoreResult<([f64; 3], f64)> {
    let m = l.len();
    if p.len() != 3 * m || m < 5 {
        return Err(CoreError::Shape {
            arg: "p",
            expected: format!("({m}, 3) matching `L`, with at least 5 samples"),
            got: format!("{} values for {m} lengths", p.len()),
        });
    }
    check_kinematic_input("p", p)?;
    check_kinematic_input("L", l)?;
    // Centre the positions so the linear system is well scaled (|p|² would be ~1e6 otherwise).
    let mut centre = [0.0; 3];
    for row in p.chunks_exact(3) {
        for c in 0..3 {
            centre[c] += row[c] / m as f64;
        }
    }
    let mut a = DMatrix::zeros(m, 5);
    let mut b = DVector::zeros(m);
    for (i, row) in p.chunks_exact(3).enumerate() {
        let x = [row[0] - centre[0], row[1] - centre[1], row[2] - centre[2]];
        a[(i, 0)] = 2.0 * x[0];
        a[(i, 1)] = 2.0 * x[1];
        a[(i, 2)] = 2.0 * x[2];
        a[(i, 3)] = 2.0 * l[i];
        a[(i, 4)] = 1.0;
        b[i] = x[0] * x[0] + x[1] * x[1] + x[2] * x[2] - l[i] * l[i];
    }
    // A bounded iteration count: an SVD that does not converge is an error, never a hang.
    let svd = a
        .try_svd(true, true, f64::EPSILON, 10_000)
        .ok_or_else(|| CoreError::Singular(format!("the SVD of the {m}-sample cable anchor system did not converge")))?;
    let smax = svd.singular_values.max();
    let smin = svd.singular_values.min();
    // Not greater, NaN included.
    if smin.partial_cmp(&(1e-10 * smax)) != Some(Ordering::Greater) {
        return Err(CoreError::Singular(format!(
            "the {m} tool positions and lengths do not determine the cable anchor (condition number {:.3e}); \
             use configurations spread over 3-D space",
            smax / smin
        )));
    }
    let sol = svd.solve(&b, 0.0).map_err(|e| CoreError::Singular(format!("cable anchor least squares: {e}")))?;
    Ok(([sol[0] + centre[0], sol[1] + centre[1], sol[2] + centre[2]], sol[3]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_on_noiseless_data() {
        let anchor = [350.0, -820.0, -40.0];
        let l0 = 123.4;
        let mut p = Vec::new();
        let mut l = Vec::new();
        for i in 0..12 {
            let t = i as f64;
            let x = [900.0 + 100.0 * (t * 0.7).sin(), 200.0 * (t * 1.3).cos(), 800.0 + 150.0 * (t * 0.4).sin()];
            let d = ((x[0] - anchor[0]).powi(2) + (x[1] - anchor[1]).powi(2) + (x[2] - anchor[2]).powi(2)).sqrt();
            p.extend_from_slice(&x);
            l.push(d - l0);
        }
        let (a, off) = cable_initial_guess(&p, &l).unwrap();
        for c in 0..3 {
            assert!((a[c] - anchor[c]).abs() < 1e-6);
        }
        assert!((off - l0).abs() < 1e-6);
    }

    #[test]
    fn degenerate_positions_are_reported() {
        let p = [100.0, 0.0, 0.0].repeat(8);
        let l = vec![50.0; 8];
        assert!(matches!(cable_initial_guess(&p, &l), Err(CoreError::Singular(_))));
    }
}
