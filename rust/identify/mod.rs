//! Identifiability of a calibration problem and the covariance of its estimate.
//!
//! Everything is computed on the column-scaled Jacobian (unit-norm columns), so the answer does
//! not depend on mixing mm and rad. The rank is the number of singular values above
//! `tol·σ₁`; a column-pivoted QR (faer) picks the identifiable subset in order of independence;
//! every other parameter is written as a combination of that subset, which says what it is
//! redundant with (e.g. `theta1` with `base_rz`). Covariance: `σ̂² (JᵀJ)⁺` with
//! `σ̂² = ‖r‖² / (rows − rank)`.

use crate::error::{CoreError, CoreResult};
use crate::linalg::{row_major, scale_columns};
use faer::prelude::*;
use faer::Mat;

/// Coefficients below this (on unit-norm columns) are not reported as redundancy partners.
pub const REDUNDANCY_COEF_MIN: f64 = 1e-6;

#[derive(Debug, Clone, PartialEq)]
pub struct Identifiability {
    /// Singular values of the column-scaled Jacobian, descending (min(m, n) values).
    pub singular_values: Vec<f64>,
    pub rank: usize,
    /// `σ₁ / σ_rank` (infinite when the rank is 0).
    pub condition_number: f64,
    /// Euclidean norms of the unscaled columns.
    pub column_norms: Vec<f64>,
    /// Identifiable parameters (column indices), most independent first.
    pub identifiable: Vec<usize>,
    /// Columns with no effect on the residuals at all.
    pub no_effect: Vec<usize>,
    /// For each other column j: the identifiable columns k and coefficients c with
    /// `Ĵ_j ≈ Σ c_k Ĵ_k` (scaled columns).
    pub redundant: Vec<(usize, Vec<(usize, f64)>)>,
}

fn singular_values(a: faer::MatRef<'_, f64>) -> CoreResult<Vec<f64>> {
    let mut s = a.singular_values().map_err(|e| CoreError::NoConvergence(format!("SVD of the scaled Jacobian: {e:?}")))?;
    s.sort_by(|x, y| y.total_cmp(x));
    Ok(s)
}

fn rank_of(s: &[f64], tol: f64) -> usize {
    let s1 = s.first().copied().unwrap_or(0.0);
    s.iter().filter(|&&v| v > tol * s1 && v > 0.0).count()
}

fn check_tol(tol: f64) -> CoreResult<()> {
    if tol > 0.0 && tol < 1.0 {
        Ok(())
    } else {
        Err(CoreError::InvalidParameter { arg: "tol", reason: format!("must lie in (0, 1); got {tol}") })
    }
}

/// The triangular factor `R` (n, n) of `a` (m, n) with `m ≥ n` (`a = Q·R`, `Q` not formed): the
/// singular values, right singular vectors and least-squares solutions of `a` are those of `R`,
/// so what follows works on an n × n matrix. Tall matrices are split in two halves factored on
/// two threads, their `R`s stacked and factored again (a tall-skinny QR).
fn triangular_factor(a: faer::MatRef<'_, f64>) -> Mat<f64> {
    let (m, n) = (a.nrows(), a.ncols());
    let r_of = |block: faer::MatRef<'_, f64>| {
        let r = block.qr().thin_R().to_owned();
        // (thin_R has min(rows, n) rows: a short block pads with zero rows.)
        Mat::from_fn(n, n, |i, j| if i < r.nrows() && j >= i { r[(i, j)] } else { 0.0 })
    };
    if m < 8 * n.max(16) {
        return if m >= n { r_of(a) } else { Mat::from_fn(n, n, |i, j| if i < m { a[(i, j)] } else { 0.0 }) };
    }
    let half = m / 2;
    let (top, bottom) = rayon::join(|| r_of(a.subrows(0, half)), || r_of(a.subrows(half, m - half)));
    let stacked = Mat::from_fn(2 * n, n, |i, j| if i < n { top[(i, j)] } else { bottom[(i - n, j)] });
    r_of(stacked.as_ref())
}

/// Identifiability analysis of `J` (m, n) row-major.
///
/// One column-pivoted QR of the scaled `J` (m, n) picks the identifiable subset; the singular
/// values and the redundancy coefficients come from its triangular factor (n, n).
///
/// Errors: `Shape`, `NonFinite`, `InvalidParameter` (tol outside (0, 1)).
pub fn identifiability(j: &[f64], m: usize, n: usize, tol: f64) -> CoreResult<Identifiability> {
    check_tol(tol)?;
    let jm = row_major("J", j, m, n)?;
    let (column_norms, effective, scaled) = scale_columns(jm);
    let eff_idx: Vec<usize> = (0..n).filter(|&c| effective[c]).collect();
    let no_effect: Vec<usize> = (0..n).filter(|&c| !effective[c]).collect();
    let k = eff_idx.len();
    // Columns without effect are zero: they add zero singular values and nothing else.
    let mut values = vec![0.0; m.min(n)];
    let mut identifiable = Vec::new();
    let mut redundant = Vec::new();
    let rank;
    if k == 0 {
        rank = 0;
    } else {
        let sub = Mat::from_fn(m, k, |r, c| scaled[(r, eff_idx[c])]);
        let qr = sub.col_piv_qr();
        let (fwd, _) = qr.P().arrays();
        let r = qr.thin_R(); // (min(m, k), k), columns in pivot order
        let s = singular_values(r)?;
        values[..s.len()].copy_from_slice(&s);
        rank = rank_of(&values, tol);
        identifiable = fwd.iter().take(rank).map(|&c| eff_idx[c]).collect();
        // Each other column (pivot position p ≥ rank) in the basis of the first `rank` pivoted
        // columns: the least squares R₁₁·c = R₁ₚ (rows below `rank` are what the basis cannot explain).
        if rank > 0 && rank < k {
            let r11 = r.get(..rank, ..rank);
            let rhs = r.get(..rank, rank..k).to_owned();
            let coefs = r11.qr().solve_lstsq(&rhs);
            for (c, &p) in fwd.iter().enumerate().skip(rank) {
                let partners =
                    (0..rank).map(|b| (eff_idx[fwd[b]], coefs[(b, c - rank)])).filter(|(_, v)| v.abs() > REDUNDANCY_COEF_MIN).collect();
                redundant.push((eff_idx[p], partners));
            }
            redundant.sort_by_key(|(col, _)| *col);
        }
    }
    let condition_number = if rank == 0 { f64::INFINITY } else { values[0] / values[rank - 1] };
    Ok(Identifiability { singular_values: values, rank, condition_number, column_norms, identifiable, no_effect, redundant })
}

/// Parameter covariance `σ̂² (JᵀJ)⁺` of a least-squares fit with Jacobian `J` (m, n) and final
/// residuals `r` (m). The pseudo-inverse is taken on the column-scaled Jacobian (rank by
/// `tol`), through the SVD of its triangular factor (the same singular values and vectors);
/// columns with no effect get zero rows and columns. Returns `(cov (n·n row-major), σ̂², dof,
/// rank)`.
///
/// Errors: `Shape`, `NonFinite`, `InvalidParameter` (no degrees of freedom left).
pub fn covariance(j: &[f64], r: &[f64], m: usize, n: usize, tol: f64) -> CoreResult<(Vec<f64>, f64, usize, usize)> {
    check_tol(tol)?;
    let jm = row_major("J", j, m, n)?;
    let rv = row_major("r", r, m, 1)?;
    let (norms, effective, scaled) = scale_columns(jm);
    let factor = triangular_factor(scaled.as_ref());
    let svd = factor.thin_svd().map_err(|e| CoreError::NoConvergence(format!("SVD of the scaled Jacobian: {e:?}")))?;
    let s = svd.S().column_vector();
    let k = s.nrows().min(m);
    let s1 = (0..k).map(|i| s[i]).fold(0.0, f64::max);
    let keep: Vec<usize> = (0..k).filter(|&i| s[i] > tol * s1 && s[i] > 0.0).collect();
    let rank = keep.len();
    if m <= rank {
        return Err(CoreError::InvalidParameter {
            arg: "J",
            reason: format!("{m} residuals leave no degrees of freedom for {rank} identifiable parameters"),
        });
    }
    let dof = m - rank;
    let sigma2 = rv.col(0).squared_norm_l2() / dof as f64;
    let v = svd.V();
    let mut cov = vec![0.0; n * n];
    for a in (0..n).filter(|&a| effective[a]) {
        for b in (0..n).filter(|&b| effective[b]) {
            let sum: f64 = keep.iter().map(|&i| v[(a, i)] * v[(b, i)] / (s[i] * s[i])).sum();
            cov[a * n + b] = sigma2 * sum / (norms[a] * norms[b]);
        }
    }
    Ok((cov, sigma2, dof, rank))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Entries whose squares overflow made every column "no effect" and the rank 0; they are an
    /// `OutOfRange` error now.
    #[test]
    fn overflowing_entries_are_an_error_not_a_wrong_rank() {
        let j = [1e300, 1.0, 1e300, 2.0, 0.0, 1.0];
        assert!(matches!(identifiability(&j, 3, 2, 1e-9), Err(CoreError::OutOfRange { arg: "J", index: 0, .. })));
        assert!(matches!(covariance(&j, &[1.0, 2.0, 3.0], 3, 2, 1e-9), Err(CoreError::OutOfRange { arg: "J", .. })));
    }

    #[test]
    fn finds_duplicate_and_dead_columns() {
        // Columns: c0, c1, c2 = 2·c0 (redundant with c0), c3 = 0 (no effect).
        let rows = [[1.0, 0.0, 2.0, 0.0], [0.0, 1.0, 0.0, 0.0], [1.0, 1.0, 2.0, 0.0], [2.0, -1.0, 4.0, 0.0]];
        let j: Vec<f64> = rows.iter().flatten().copied().collect();
        let id = identifiability(&j, 4, 4, 1e-9).unwrap();
        assert_eq!(id.rank, 2);
        assert_eq!(id.no_effect, vec![3]);
        assert_eq!(id.identifiable.len(), 2);
        assert_eq!(id.redundant.len(), 1);
        let (col, partners) = &id.redundant[0];
        // Scaled c0 and c2 are the same unit vector: the redundant one equals the other with coefficient 1.
        assert!([0, 2].contains(col));
        assert_eq!(partners.len(), 1);
        assert!((partners[0].1 - 1.0).abs() < 1e-12);
    }

    #[test]
    fn covariance_of_linear_fit() {
        // Straight line y = a + b·x, residuals known: cov = σ² (JᵀJ)⁻¹.
        let x = [0.0, 1.0, 2.0, 3.0, 4.0];
        let j: Vec<f64> = x.iter().flat_map(|&v| [1.0, v]).collect();
        let r = [0.1, -0.2, 0.05, 0.1, -0.05];
        let (cov, s2, dof, rank) = covariance(&j, &r, 5, 2, 1e-9).unwrap();
        assert_eq!((dof, rank), (3, 2));
        let expected_s2 = r.iter().map(|v| v * v).sum::<f64>() / 3.0;
        assert!((s2 - expected_s2).abs() < 1e-15);
        // (JᵀJ)⁻¹ for [[5,10],[10,30]] = [[0.6,-0.2],[-0.2,0.1]].
        let inv = [0.6, -0.2, -0.2, 0.1];
        for i in 0..4 {
            assert!((cov[i] - s2 * inv[i]).abs() < 1e-12, "{i}: {} vs {}", cov[i], s2 * inv[i]);
        }
    }
}
