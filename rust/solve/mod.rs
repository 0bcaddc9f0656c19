//! The damped step of LM / VSLM (the paper's eq. 14–15):
//! `(JᵀJ + λD) δ = Jᵀr` with `D = diag(JᵀJ)` (Marquardt) or `I` (Levenberg, eq. 14).
//!
//! Two factorisations of the same step:
//! - [`solve_damped`], the normal equations as the paper writes them: Cholesky (faer) first;
//!   when the damped matrix is not numerically positive definite — the DH identification model
//!   is rank-deficient and λ may be 0 — a rank-revealing SVD gives the minimum-norm step instead
//!   of a huge, meaningless one. Forming `JᵀJ` squares the condition number: directions of `J`
//!   below ~3·10⁻⁷ of the largest are treated as null.
//! - [`solve_damped_lstsq`], the least-squares solution of the augmented system
//!   `[J; √λ·D^½] δ ≈ [r; 0]` by column-pivoted QR of `J` itself (as MINPACK does) whenever
//!   the normal equations are ill-conditioned, so directions down to ~10⁻¹³ are kept: robocal's
//!   production LM uses it, because on ill-conditioned real data the normal equations stall it
//!   in a flat valley.
//! - [`DampedQr`], the same least-squares step with `D = I` for many `λ` and right-hand sides
//!   from one factorisation of `J` (MINPACK's `lmpar`/`qrsolv` idea): `J = Q·R` once per
//!   Jacobian, then each step is the small problem `[R; √λ·I] δ ≈ [Qᵀb; 0]`, `O(n³)` instead
//!   of `O(m·n²)`. The caller scales the columns (`J·D^-½`) to get Marquardt's damping.

mod gram;
mod tall_qr;
pub use gram::{fold_products, normal_equations, sparse_gram, stack_csr, Csr, FoldProducts, MAX_FOLD_PRODUCTS, MAX_GRAM_COLUMNS};
pub use tall_qr::TallQr;

use crate::error::{CoreError, CoreResult};
use crate::linalg::row_major;
use faer::prelude::*;
use faer::{Mat, MatRef, Side};
use std::cmp::Ordering;

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
            other => {
                Err(CoreError::InvalidParameter { arg: "damping", reason: format!("expected 'marquardt' or 'identity'; got '{other}'") })
            }
        }
    }
}

/// Which factorisation produced the step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SolveMethod {
    Cholesky,
    Qr,
    Svd,
}

impl SolveMethod {
    pub fn name(self) -> &'static str {
        match self {
            Self::Cholesky => "cholesky",
            Self::Qr => "qr",
            Self::Svd => "svd",
        }
    }
}

/// Relative size below which a pivot or singular value counts as zero.
const RANK_TOL: f64 = 1e-13;

/// The checked views of `J` (m, n) and `r` (m).
fn damped_inputs<'a>(j: &'a [f64], r: &'a [f64], m: usize, n: usize, lambda: f64) -> CoreResult<(MatRef<'a, f64>, MatRef<'a, f64>)> {
    let jm = row_major("J", j, m, n)?;
    let rv = row_major("r", r, m, 1)?;
    check_lambda(lambda)?;
    Ok((jm, rv))
}

fn check_lambda(lambda: f64) -> CoreResult<()> {
    if !(lambda >= 0.0 && lambda.is_finite()) {
        return Err(CoreError::InvalidParameter { arg: "lam", reason: format!("must be finite and >= 0; got {lambda}") });
    }
    Ok(())
}

/// Solves `(JᵀJ + λD) δ = Jᵀr` for `J` (m, n) row-major and `r` (m) by the normal equations.
///
/// Errors: `Shape`, `NonFinite`, `OutOfRange`, `InvalidParameter` (λ < 0 or not finite).
pub fn solve_damped(j: &[f64], r: &[f64], m: usize, n: usize, lambda: f64, damping: Damping) -> CoreResult<(Vec<f64>, SolveMethod)> {
    let (jm, rv) = damped_inputs(j, r, m, n, lambda)?;
    let a: Mat<f64> = jm.transpose() * jm;
    let g: Mat<f64> = jm.transpose() * rv;
    solve_damped_normal(a.as_ref(), g.as_ref(), lambda, damping)
}

/// The same step from the normal matrix `A = JᵀJ` (n, n) and gradient `g = Jᵀr` (n, 1).
pub fn solve_damped_normal(a: MatRef<'_, f64>, g: MatRef<'_, f64>, lambda: f64, damping: Damping) -> CoreResult<(Vec<f64>, SolveMethod)> {
    let damped = damped_normal_matrix(a, lambda, damping);
    // A factorisation that only succeeded through rounding (pivot ~ eps·max) gives a step
    // dominated by noise; treat it as singular.
    if let Some(x) = cholesky_step(damped.as_ref(), g, RANK_TOL) {
        return Ok((x, SolveMethod::Cholesky));
    }
    let x = min_norm_lstsq(damped.as_ref(), g, RANK_TOL * a.nrows() as f64)?;
    Ok((x, SolveMethod::Svd))
}

/// `A + λD`.
fn damped_normal_matrix(a: MatRef<'_, f64>, lambda: f64, damping: Damping) -> Mat<f64> {
    let mut damped = a.to_owned();
    for i in 0..a.nrows() {
        damped[(i, i)] += lambda * if damping == Damping::Marquardt { a[(i, i)] } else { 1.0 };
    }
    damped
}

/// The Cholesky solution of `M x = g` if `M` factors with every squared pivot above
/// `min_ratio` times the largest.
fn cholesky_step(m: MatRef<'_, f64>, g: MatRef<'_, f64>, min_ratio: f64) -> Option<Vec<f64>> {
    let n = m.nrows();
    let llt = m.llt(Side::Lower).ok()?;
    let l = llt.L();
    let pivots: Vec<f64> = (0..n).map(|i| l[(i, i)] * l[(i, i)]).collect();
    let max = pivots.iter().cloned().fold(0.0, f64::max);
    let min = pivots.iter().cloned().fold(f64::INFINITY, f64::min);
    // Not greater, NaN included.
    if n > 0 && min.partial_cmp(&(min_ratio * max)) != Some(Ordering::Greater) {
        return None;
    }
    let x = llt.solve(g);
    Some((0..n).map(|i| x[(i, 0)]).collect())
}

/// Squared Cholesky pivots above this fraction of the largest mean a damped normal matrix of
/// condition below ~10¹² (`J`'s below ~10⁶, as in most calibrations): its step is accurate to
/// ~10⁻⁴, plenty for an LM step whose gain ratio is checked, and the normal equations are
/// several times cheaper than QR. Below it [`solve_damped_lstsq`] factors `J`.
const WELL_CONDITIONED: f64 = 1e-12;

/// The same step as the least-squares solution of `[J; √λ·D^½] δ ≈ [r; 0]`: by the normal
/// equations (Cholesky) when they are well conditioned ([`WELL_CONDITIONED`]), else in columns
/// scaled to unit norm (so the rank test is scale-free) by column-pivoted QR, or — when the augmented
/// matrix is rank-deficient (λ = 0, a column without effect) — the minimum-norm solution through
/// its SVD, with singular values below `ε·(m + n)` of the largest treated as zero (NumPy's
/// `lstsq` default).
///
/// Errors: `Shape`, `NonFinite`, `OutOfRange`, `InvalidParameter` (λ < 0 or not finite).
pub fn solve_damped_lstsq(j: &[f64], r: &[f64], m: usize, n: usize, lambda: f64, damping: Damping) -> CoreResult<(Vec<f64>, SolveMethod)> {
    let (jm, rv) = damped_inputs(j, r, m, n, lambda)?;
    if n == 0 {
        return Ok((Vec::new(), SolveMethod::Qr));
    }
    let a: Mat<f64> = jm.transpose() * jm;
    let g: Mat<f64> = jm.transpose() * rv;
    if let Some(x) = cholesky_step(damped_normal_matrix(a.as_ref(), lambda, damping).as_ref(), g.as_ref(), WELL_CONDITIONED) {
        return Ok((x, SolveMethod::Cholesky));
    }
    let norms: Vec<f64> = (0..n).map(|c| jm.col(c).norm_l2()).collect();
    let scale: Vec<f64> = norms.iter().map(|&v| if v > 0.0 { v } else { 1.0 }).collect();
    let sqrt_lambda = lambda.sqrt();
    let aug = Mat::from_fn(m + n, n, |row, c| {
        if row < m {
            jm[(row, c)] / scale[c]
        } else if row - m == c {
            // √λ·D^½ in scaled columns: √λ·‖J_c‖/scale_c (Marquardt), √λ/scale_c (identity).
            sqrt_lambda * if damping == Damping::Marquardt { norms[c] } else { 1.0 } / scale[c]
        } else {
            0.0
        }
    });
    let rhs = Mat::from_fn(m + n, 1, |row, _| if row < m { rv[(row, 0)] } else { 0.0 });
    let rcond = f64::EPSILON * (m + n) as f64;
    let qr = aug.col_piv_qr();
    let diag = qr.thin_R().diagonal().column_vector();
    let rmax = (0..n).fold(0.0f64, |hi, k| hi.max(diag[k].abs()));
    // (Comparisons with NaN are false: a factorisation gone wrong takes the SVD path too.)
    let full_rank = rmax > 0.0 && (0..n).all(|k| diag[k].abs() > rcond * rmax);
    let (y, how) = if full_rank {
        let y = qr.solve_lstsq(&rhs);
        ((0..n).map(|k| y[(k, 0)]).collect::<Vec<f64>>(), SolveMethod::Qr)
    } else {
        (min_norm_lstsq(aug.as_ref(), rhs.as_ref(), rcond)?, SolveMethod::Svd)
    };
    Ok((y.iter().zip(&scale).map(|(v, s)| v / s).collect(), how))
}

/// `J` (m, n) factored as `J = Q·R` (Householder QR: [`TallQr`]) for the damped steps
/// `min ‖J·δ − b‖² + λ‖δ‖²` of several `λ` and `b`. No column pivoting here: each step's small
/// system `[R; √λ·I]` is factored with it ([`Self::solve`]), which is where a rank deficiency
/// shows, and Householder QR is backward stable without it (and faster: docs/benchmarks.md).
#[derive(Debug, Clone)]
pub struct DampedQr {
    qr: TallQr,
    m: usize,
}

impl DampedQr {
    /// Factors `J` (m, n) row-major; fewer rows than columns are padded with zero rows (which
    /// change no least-squares problem). Errors: `Shape`, `NonFinite`, `OutOfRange`.
    pub fn new(j: &[f64], m: usize, n: usize) -> CoreResult<Self> {
        row_major("J", j, m, n)?;
        let qr = if m >= n {
            TallQr::new(j, m, n)
        } else {
            let mut padded = j.to_vec();
            padded.resize(n * n, 0.0);
            TallQr::new(&padded, n, n)
        };
        Ok(Self { qr, m })
    }

    /// Number of columns of `J`.
    pub fn ncols(&self) -> usize {
        self.qr.ncols()
    }

    /// `R` (n × n, upper triangular, row-major): `JᵀJ = RᵀR`, so `J`'s singular values and right
    /// singular vectors are `R`'s (an SVD of n × n instead of m × n).
    pub fn r(&self) -> &[f64] {
        self.qr.r()
    }

    /// `Qᵀb` (n) for `b` (m): `‖Qᵀr‖` is the norm of `r`'s projection on the columns of `J`.
    /// Errors: `Shape`, `NonFinite`, `OutOfRange`.
    pub fn project(&self, b: &[f64]) -> CoreResult<Vec<f64>> {
        row_major("b", b, self.m, 1)?;
        if self.m >= self.ncols() {
            return Ok(self.qr.project(b));
        }
        let mut padded = b.to_vec();
        padded.resize(self.ncols(), 0.0);
        Ok(self.qr.project(&padded))
    }

    /// The step `δ` minimising `‖J·δ − b‖² + λ‖δ‖²` from `c = Qᵀb` ([`Self::project`]): the
    /// least squares of `[R; √λ·I] δ ≈ [c; 0]`; its minimum-norm solution through
    /// the SVD when that is rank-deficient (λ = 0 and `J` singular).
    /// Errors: `Shape`, `NonFinite`, `OutOfRange`, `InvalidParameter` (λ < 0 or not finite).
    pub fn solve(&self, c: &[f64], lambda: f64) -> CoreResult<Vec<f64>> {
        let n = self.ncols();
        let cv = row_major("c", c, n, 1)?;
        check_lambda(lambda)?;
        let sqrt_lambda = lambda.sqrt();
        let r = self.qr.r();
        let aug = Mat::from_fn(2 * n, n, |row, col| {
            if row < n {
                r[row * n + col]
            } else if row - n == col {
                sqrt_lambda
            } else {
                0.0
            }
        });
        let rhs = Mat::from_fn(2 * n, 1, |row, _| if row < n { cv[(row, 0)] } else { 0.0 });
        let rcond = f64::EPSILON * (self.m + n) as f64;
        let qr = aug.col_piv_qr();
        let diag = qr.thin_R().diagonal().column_vector();
        let rmax = (0..n).fold(0.0f64, |hi, k| hi.max(diag[k].abs()));
        let full_rank = rmax > 0.0 && (0..n).all(|k| diag[k].abs() > rcond * rmax);
        if full_rank {
            let y = qr.solve_lstsq(&rhs);
            Ok((0..n).map(|k| y[(k, 0)]).collect())
        } else {
            min_norm_lstsq(aug.as_ref(), rhs.as_ref(), rcond)
        }
    }
}

/// Minimum-norm least-squares solution of `A x ≈ b` (also of a singular symmetric system)
/// through the thin SVD of `A`, singular values
/// at or below `rcond` of the largest treated as zero.
fn min_norm_lstsq(a: MatRef<'_, f64>, b: MatRef<'_, f64>, rcond: f64) -> CoreResult<Vec<f64>> {
    let svd = a.thin_svd().map_err(|e| CoreError::NoConvergence(format!("SVD of the damped system: {e:?}")))?;
    let s = svd.S().column_vector();
    let smax = (0..s.nrows()).map(|i| s[i]).fold(0.0, f64::max);
    let utb: Mat<f64> = svd.U().transpose() * b;
    let mut x = vec![0.0; a.ncols()];
    for k in 0..s.nrows() {
        if s[k] > rcond * smax && s[k] > 0.0 {
            let coef = utb[(k, 0)] / s[k];
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
        for solve in [solve_damped, solve_damped_lstsq] {
            let (x, how) = solve(&j, &r, 2, 2, 0.0, Damping::Identity).unwrap();
            assert_eq!(how, SolveMethod::Svd);
            assert!((x[0] - 0.5).abs() < 1e-12 && (x[1] - 0.5).abs() < 1e-12, "{x:?}");
        }
    }

    #[test]
    fn negative_lambda_is_rejected() {
        let err = solve_damped(&[1.0], &[1.0], 1, 1, -1.0, Damping::Identity).unwrap_err();
        assert!(err.to_string().contains("lam"));
        let err = solve_damped_lstsq(&[1.0], &[1.0], 1, 1, -1.0, Damping::Identity).unwrap_err();
        assert!(err.to_string().contains("lam"));
    }

    #[test]
    fn lstsq_equals_the_normal_equations_on_a_well_conditioned_problem() {
        let j = [1.0, 0.0, 0.0, 2.0, 1.0, 1.0];
        let r = [1.0, 2.0, 3.0];
        for damping in [Damping::Marquardt, Damping::Identity] {
            for lambda in [0.0, 0.3, 10.0] {
                let (a, _) = solve_damped(&j, &r, 3, 2, lambda, damping).unwrap();
                let (b, how) = solve_damped_lstsq(&j, &r, 3, 2, lambda, damping).unwrap();
                assert_eq!(how, SolveMethod::Cholesky, "well conditioned: the normal equations");
                assert!((a[0] - b[0]).abs() < 1e-12 && (a[1] - b[1]).abs() < 1e-12, "{a:?} vs {b:?}");
            }
        }
    }

    #[test]
    fn lstsq_keeps_a_direction_the_normal_equations_drop() {
        // Columns (1, 1, 0) and (1, 1 + 1e-8, 1e-8): condition ~3e8, so JᵀJ's ~1e17 is below the
        // normal equations' rank tolerance; the exact solution for r = J·(1, -1) is (1, -1).
        let e = 1e-8;
        let j = [1.0, 1.0, 1.0, 1.0 + e, 0.0, e];
        let r = [0.0, -e, -e];
        let (x, how) = solve_damped_lstsq(&j, &r, 3, 2, 0.0, Damping::Marquardt).unwrap();
        assert_eq!(how, SolveMethod::Qr);
        assert!((x[0] - 1.0).abs() < 1e-6 && (x[1] + 1.0).abs() < 1e-6, "{x:?}");
        let (x, how) = solve_damped(&j, &r, 3, 2, 0.0, Damping::Marquardt).unwrap();
        assert_eq!(how, SolveMethod::Svd);
        assert!((x[0] - 1.0).abs() > 0.5, "the normal equations resolved it after all: {x:?}");
    }

    #[test]
    fn damped_qr_equals_the_augmented_least_squares_for_any_lambda() {
        // Ill-conditioned columns; J·δ ≈ r with (J, r) fixed.
        let j = [1.0, 2.0, 0.0, 1.0, 2.0 + 1e-6, 1.0, 0.0, 1.0, 3.0, 2.0, 4.0, 0.5];
        let r = [1.0, -2.0, 0.5, 3.0];
        let f = DampedQr::new(&j, 4, 3).unwrap();
        let c = f.project(&r).unwrap();
        for lambda in [0.0, 1e-3, 0.7, 50.0] {
            let a = f.solve(&c, lambda).unwrap();
            let (b, _) = solve_damped_lstsq(&j, &r, 4, 3, lambda, Damping::Identity).unwrap();
            for k in 0..3 {
                assert!((a[k] - b[k]).abs() < 1e-6 * (1.0 + b[k].abs()), "lambda {lambda}: {a:?} vs {b:?}");
            }
        }
    }

    #[test]
    fn damped_qr_projection_norm_is_the_explained_part_of_r() {
        // r in the column space of J: ‖Qᵀr‖ = ‖r‖.
        let j = [1.0, 0.0, 0.0, 1.0, 1.0, 1.0];
        let r = [2.0, -1.0, 1.0];
        let c = DampedQr::new(&j, 3, 2).unwrap().project(&r).unwrap();
        let norm = (c[0] * c[0] + c[1] * c[1]).sqrt();
        assert!((norm - 6f64.sqrt()).abs() < 1e-12);
        assert!(DampedQr::new(&j, 3, 2).unwrap().solve(&c, -1.0).unwrap_err().to_string().contains("lam"));
        // Fewer rows than columns: the minimum-norm solution of the underdetermined system.
        let f = DampedQr::new(&[1.0, 1.0, 0.0], 1, 3).unwrap();
        let step = f.solve(&f.project(&[2.0]).unwrap(), 0.0).unwrap();
        assert!((step[0] - 1.0).abs() < 1e-12 && (step[1] - 1.0).abs() < 1e-12 && step[2].abs() < 1e-12, "{step:?}");
    }

    #[test]
    fn damped_qr_r_is_a_triangular_factor_of_jtj() {
        // 4 x 3, and 1 x 3 (padded with zero rows): RᵀR = JᵀJ, R upper triangular.
        for (j, m) in [(vec![1.0, 2.0, 0.0, 1.0, 2.5, 1.0, 0.0, 1.0, 3.0, 2.0, 4.0, 0.5], 4), (vec![1.0, 1.0, 0.0], 1)] {
            let r = DampedQr::new(&j, m, 3).unwrap().r().to_vec();
            for a in 0..3 {
                for b in 0..3 {
                    let rtr: f64 = (0..3).map(|k| r[k * 3 + a] * r[k * 3 + b]).sum();
                    let jtj: f64 = (0..m).map(|i| j[i * 3 + a] * j[i * 3 + b]).sum();
                    assert!((rtr - jtj).abs() < 1e-12 * (1.0 + jtj.abs()), "({a},{b}) of {m}x3: {rtr} vs {jtj}");
                    assert!(a <= b || r[a * 3 + b] == 0.0, "R[{a},{b}] below the diagonal of {m}x3");
                }
            }
        }
    }

    #[test]
    fn lstsq_gives_a_column_without_effect_no_step() {
        let r = [1.0, 2.0];
        let j = [1.0, 0.0, 2.0, 0.0];
        let (x, _) = solve_damped_lstsq(&j, &r, 2, 2, 0.1, Damping::Marquardt).unwrap();
        assert!(x[1] == 0.0 && x[0].is_finite());
    }
}
