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
    let mut s = a
        .singular_values()
        .map_err(|e| CoreError::NoConvergence(format!("SVD of the scaled Jacobian: {e:?}")))?;
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
        Err(CoreError::InvalidParameter {
            arg: "tol",
            reason: format!("must lie in (0, 1); got {tol}"),
        })
    }
}

/// Identifiability analysis of `J` (m, n) row-major.
///
/// Errors: `Shape`, `NonFinite`, `InvalidParameter` (tol outside (0, 1)).
pub fn identifiability(j: &[f64], m: usize, n: usize, tol: f64) -> CoreResult<Identifiability> {
    check_tol(tol)?;
    let jm = row_major("J", j, m, n)?;
    let (column_norms, effective, scaled) = scale_columns(jm);
    let singular_values = singular_values(scaled.as_ref())?;
    let rank = rank_of(&singular_values, tol);
    let condition_number = if rank == 0 { f64::INFINITY } else { singular_values[0] / singular_values[rank - 1] };

    let eff_idx: Vec<usize> = (0..n).filter(|&c| effective[c]).collect();
    let no_effect: Vec<usize> = (0..n).filter(|&c| !effective[c]).collect();
    let sub = Mat::from_fn(m, eff_idx.len(), |r, c| scaled[(r, eff_idx[c])]);
    let identifiable: Vec<usize> = if eff_idx.is_empty() {
        Vec::new()
    } else {
        let qr = sub.col_piv_qr();
        let (fwd, _) = qr.P().arrays();
        fwd.iter().take(rank).map(|&k| eff_idx[k]).collect()
    };

    let mut redundant = Vec::new();
    let others: Vec<usize> = eff_idx.iter().copied().filter(|c| !identifiable.contains(c)).collect();
    if !identifiable.is_empty() && !others.is_empty() {
        let basis = Mat::from_fn(m, identifiable.len(), |r, c| scaled[(r, identifiable[c])]);
        let rhs = Mat::from_fn(m, others.len(), |r, c| scaled[(r, others[c])]);
        let coefs = basis.qr().solve_lstsq(&rhs);
        for (c, &col) in others.iter().enumerate() {
            let partners = identifiable
                .iter()
                .enumerate()
                .map(|(k, &id)| (id, coefs[(k, c)]))
                .filter(|(_, v)| v.abs() > REDUNDANCY_COEF_MIN)
                .collect();
            redundant.push((col, partners));
        }
    }
    Ok(Identifiability { singular_values, rank, condition_number, column_norms, identifiable, no_effect, redundant })
}

/// Parameter covariance `σ̂² (JᵀJ)⁺` of a least-squares fit with Jacobian `J` (m, n) and final
/// residuals `r` (m). The pseudo-inverse is taken on the column-scaled Jacobian (rank by
/// `tol`); columns with no effect get zero rows and columns. Returns `(cov (n·n row-major),
/// σ̂², dof, rank)`.
///
/// Errors: `Shape`, `NonFinite`, `InvalidParameter` (no degrees of freedom left).
pub fn covariance(j: &[f64], r: &[f64], m: usize, n: usize, tol: f64) -> CoreResult<(Vec<f64>, f64, usize, usize)> {
    check_tol(tol)?;
    let jm = row_major("J", j, m, n)?;
    let rv = row_major("r", r, m, 1)?;
    let (norms, effective, scaled) = scale_columns(jm);
    let svd = scaled
        .thin_svd()
        .map_err(|e| CoreError::NoConvergence(format!("SVD of the scaled Jacobian: {e:?}")))?;
    let s = svd.S().column_vector();
    let k = s.nrows();
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
