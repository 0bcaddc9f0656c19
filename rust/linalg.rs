//! Small shared helpers for viewing row-major buffers as faer matrices.

use crate::error::{check_within, CoreError, CoreResult, MAX_ABS_MATRIX};
use faer::MatRef;

/// Views `data` as an (m, n) row-major matrix after checking its length and that its entries are
/// finite and within ±[`MAX_ABS_MATRIX`].
pub fn row_major<'a>(arg: &'static str, data: &'a [f64], m: usize, n: usize) -> CoreResult<MatRef<'a, f64>> {
    if data.len() != m * n {
        return Err(CoreError::Shape { arg, expected: format!("({m}, {n})"), got: format!("{} values", data.len()) });
    }
    check_within(arg, data, MAX_ABS_MATRIX)?;
    Ok(MatRef::from_row_major_slice(data, m, n))
}

/// Unit-norm column scaling: returns the column norms and the scaled copy. Columns with (near)
/// zero norm are left at zero and flagged `false` in the returned mask.
pub fn scale_columns(j: MatRef<'_, f64>) -> (Vec<f64>, Vec<bool>, faer::Mat<f64>) {
    let n = j.ncols();
    let norms: Vec<f64> = (0..n).map(|c| j.col(c).norm_l2()).collect();
    let max = norms.iter().cloned().fold(0.0, f64::max);
    let effective: Vec<bool> = norms.iter().map(|&v| v > 1e-12 * max && v > 0.0).collect();
    let scaled = faer::Mat::from_fn(j.nrows(), n, |r, c| if effective[c] { j[(r, c)] / norms[c] } else { 0.0 });
    (norms, effective, scaled)
}
