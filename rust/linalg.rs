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

/// Column norms of the row-major `j` (m, n) and which columns have an effect: those whose norm
/// is above `1e-12` times the largest (and not zero). Dividing by the norms of these gives
/// unit-norm columns; the others count as zero. Summed row by row (a column of a row-major
/// matrix is one value per cache line: n strided passes cost ten times one contiguous pass),
/// each column scaled by its largest entry first, so that no square underflows or overflows.
pub fn column_scales(j: &[f64], n: usize) -> (Vec<f64>, Vec<bool>) {
    let mut largest = vec![0.0f64; n];
    for row in j.chunks_exact(n.max(1)) {
        largest.iter_mut().zip(row).for_each(|(l, &x)| *l = l.max(x.abs()));
    }
    let inverse: Vec<f64> = largest.iter().map(|&l| if l > 0.0 { 1.0 / l } else { 0.0 }).collect();
    let mut sums = vec![0.0f64; n];
    for row in j.chunks_exact(n.max(1)) {
        sums.iter_mut().zip(row).zip(&inverse).for_each(|((s, &x), &i)| *s += (x * i) * (x * i));
    }
    let norms: Vec<f64> = sums.iter().zip(&largest).map(|(&s, &l)| l * s.sqrt()).collect();
    let max = norms.iter().cloned().fold(0.0, f64::max);
    let effective: Vec<bool> = norms.iter().map(|&v| v > 1e-12 * max && v > 0.0).collect();
    (norms, effective)
}
