//! The damped normal-equation step of LM / VSLM (the paper's eq. 14–15):
//! `(JᵀJ + λD) δ = Jᵀr` with `D = diag(JᵀJ)` (Marquardt) or `I` (Levenberg, eq. 14).
//!
//! Cholesky (faer) first. When the damped matrix is not numerically positive definite — the DH
//! identification model is rank-deficient and λ may be 0 — a rank-revealing SVD gives the
//! minimum-norm step instead of a huge, meaningless one.

use crate::error::{CoreError, CoreResult};
use crate::linalg::row_major;
use faer::prelude::*;
use faer::{Mat, MatRef, Side};

/// Damping matrix `D`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Damping {
    /// `D = diag(JᵀJ)`: scale-invariant (Marquardt 1963).
    Marquardt,
    /// `D = I`: the paper's eq. (14).
    Identity,
}

impl Damping {
    pub fn parse(s: &str) -> CoreResult<Self> {
        match s.to_ascii_lowercase().as_str() {
            "marquardt" => Ok(Self::Marquardt),
            "identity" | "levenberg" => Ok(Self::Identity),
            other => Err(CoreError::InvalidParameter {
                arg: "damping",
                reason: format!("expected 'marquardt' or 'identity'; got '{other}'"),
            }),
        }
    }
}

/// Which factorisation produced the step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SolveMethod {
    Cholesky,
    Svd,
}

impl SolveMethod {
    pub fn name(self) -> &'static str {
        match self {
            Self::Cholesky => "cholesky",
            Self::Svd => "svd",
        }
    }
}

/// Relative size below which a pivot or singular value counts as zero.
const RANK_TOL: f64 = 1e-13;

/// Solves `(JᵀJ + λD) δ = Jᵀr` for `J` (m, n) row-major and `r` (m).
///
/// Errors: `Shape`, `NonFinite`, `InvalidParameter` (λ < 0 or not finite).
pub fn solve_damped(j: &[f64], r: &[f64], m: usize, n: usize, lambda: f64, damping: Damping) -> CoreResult<(Vec<f64>, SolveMethod)> {
    let jm = row_major("J", j, m, n)?;
    let rv = row_major("r", r, m, 1)?;
    if !(lambda >= 0.0 && lambda.is_finite()) {
        return Err(CoreError::InvalidParameter {
            arg: "lam",
            reason: format!("must be finite and >= 0; got {lambda}"),
        });
    }
    let a: Mat<f64> = jm.transpose() * jm;
    let g: Mat<f64> = jm.transpose() * rv;
    solve_damped_normal(a.as_ref(), g.as_ref(), lambda, damping)
}

/// The same step from the normal matrix `A = JᵀJ` (n, n) and gradient `g = Jᵀr` (n, 1).
pub fn solve_damped_normal(a: MatRef<'_, f64>, g: MatRef<'_, f64>, lambda: f64, damping: Damping) -> CoreResult<(Vec<f64>, SolveMethod)> {
    let n = a.nrows();
    let mut damped = a.to_owned();
    for i in 0..n {
        damped[(i, i)] += lambda * if damping == Damping::Marquardt { a[(i, i)] } else { 1.0 };
    }
    if let Ok(llt) = damped.llt(Side::Lower) {
        let l = llt.L();
        let diag: Vec<f64> = (0..n).map(|i| l[(i, i)] * l[(i, i)]).collect();
        let max = diag.iter().cloned().fold(0.0, f64::max);
        let min = diag.iter().cloned().fold(f64::INFINITY, f64::min);
        // A factorisation that only succeeded through rounding (pivot ~ eps·max) gives a step
        // dominated by noise; treat it as singular.
        if n == 0 || min > RANK_TOL * max {
            let x = llt.solve(g);
            return Ok(((0..n).map(|i| x[(i, 0)]).collect(), SolveMethod::Cholesky));
        }
    }
    let x = pseudo_solve(damped.as_ref(), g)?;
    Ok((x, SolveMethod::Svd))
}

/// Minimum-norm solution of a symmetric system through its SVD.
fn pseudo_solve(a: MatRef<'_, f64>, g: MatRef<'_, f64>) -> CoreResult<Vec<f64>> {
    let n = a.nrows();
    let svd = a
        .thin_svd()
        .map_err(|e| CoreError::NoConvergence(format!("SVD of the damped normal matrix: {e:?}")))?;
    let s = svd.S().column_vector();
    let smax = (0..s.nrows()).map(|i| s[i]).fold(0.0, f64::max);
    let utg: Mat<f64> = svd.U().transpose() * g;
    let mut x = vec![0.0; n];
    for k in 0..s.nrows() {
        if s[k] > RANK_TOL * smax * n as f64 && s[k] > 0.0 {
            let coef = utg[(k, 0)] / s[k];
            for (i, xi) in x.iter_mut().enumerate() {
                *xi += svd.V()[(i, k)] * coef;
            }
        }
    }
    Ok(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn full_rank_matches_direct_solution() {
        // J = [[1,0],[0,2],[1,1]], r = [1,2,3]: normal equations [[2,1],[1,5]] x = [4,7].
        let j = [1.0, 0.0, 0.0, 2.0, 1.0, 1.0];
        let r = [1.0, 2.0, 3.0];
        let (x, how) = solve_damped(&j, &r, 3, 2, 0.0, Damping::Marquardt).unwrap();
        assert_eq!(how, SolveMethod::Cholesky);
        assert!((x[0] - 13.0 / 9.0).abs() < 1e-12 && (x[1] - 10.0 / 9.0).abs() < 1e-12);
    }

    #[test]
    fn rank_deficient_falls_back_to_minimum_norm() {
        // Two identical columns: the minimum-norm solution splits the step equally.
        let j = [1.0, 1.0, 2.0, 2.0];
        let r = [1.0, 2.0];
        let (x, how) = solve_damped(&j, &r, 2, 2, 0.0, Damping::Identity).unwrap();
        assert_eq!(how, SolveMethod::Svd);
        assert!((x[0] - 0.5).abs() < 1e-12 && (x[1] - 0.5).abs() < 1e-12);
    }

    #[test]
    fn negative_lambda_is_rejected() {
        let err = solve_damped(&[1.0], &[1.0], 1, 1, -1.0, Damping::Identity).unwrap_err();
        assert!(err.to_string().contains("lam"));
    }
}
