//! Identifiability of a calibration problem and the covariance of its estimate.
//!
//! Everything is computed on the column-scaled Jacobian (unit-norm columns), so the answer does
//! not depend on mixing mm and rad. The rank is the number of singular values above
//! `tol·σ₁`; a column-pivoted QR picks the identifiable subset in order of independence, the
//! columns the caller names `first` (a session's set-up) before the others while they add
//! something of their own; every other parameter is written as a combination of that subset,
//! which says what it is redundant with (e.g. `theta1` with `base_rz`). Covariance: `σ̂² (JᵀJ)⁺` with
//! `σ̂² = ‖r‖² / (rows − rank)`.
//!
//! Both work on the triangular factor `R` (n × n) of the scaled `J` (m × n): `RᵀR = ĴᵀĴ`, so its
//! singular values, right singular vectors and pivoted QR (Businger & Golub 1965; Golub & Van
//! Loan §5.4.1) are those of `Ĵ`, at the cost of an n × n problem after one tall-skinny QR.

use crate::error::{check_len, CoreError, CoreResult};
use crate::linalg::{column_scales, row_major};
use crate::solve::TallQr;
use faer::prelude::*;
use faer::Mat;
use rayon::prelude::*;

/// Coefficients below this (on unit-norm columns) are not reported as redundancy partners.
pub const REDUNDANCY_COEF_MIN: f64 = 1e-6;

/// Pivot tie margin: columns whose remaining norm is within this relative distance of the largest
/// are a tie, broken by the lowest column index. Exactly equal scaled columns (`theta1` and
/// `base_rz`) differ after the QR by round-off (~1e-15 relative, up to ~1e-12 after 10⁵ rows),
/// far below it, so the choice never hangs on rounding; columns 1e-9 apart in what they
/// add are equally good pivots.
pub const PIVOT_TIE_REL: f64 = 1e-9;

/// A column named `first` is pivoted before the others while its remaining norm is at least this
/// fraction of the largest: a redundancy between a set-up member and a kinematic parameter
/// (`tool_x`, `tool_y` and `theta6` of a position sensor) is then resolved to the set-up, which a
/// session places anew, and the robot's parameter stays at its nominal value, instead of turning
/// on which of them happens to add the larger norm. Below the fraction, a set-up column adds too
/// little to be worth a worse-conditioned basis, and the largest norm decides.
pub const FIRST_MIN_REL: f64 = 1e-3;

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

/// Rows per block of [`triangular_factor`]: a block (512 × ≤ 60 values, ≤ 240 KB) stays in
/// cache while it is factored, where one QR of all the rows streams them from memory once per
/// column; fixed, so the factor does not depend on the number of threads.
const TSQR_ROWS: usize = 512;

/// The triangular factor `R` (n, n) of the row-major `a` (m, n) with its columns multiplied by
/// `scale` (`a·S = Q·R`, `Q` not formed): the singular values, right singular vectors and
/// least-squares solutions of `a·S` are those of `R`, so what follows works on an n × n matrix.
/// A tall-skinny QR (Demmel et al. 2012): blocks of [`TSQR_ROWS`] rows scaled (a copy that
/// stays in cache) and factored in parallel ([`TallQr`]), their `R`s stacked and factored the
/// same way until one block is left. With fewer rows than columns, `a·S` padded with zero rows.
fn triangular_factor(a: &[f64], m: usize, n: usize, scale: &[f64]) -> Mat<f64> {
    let scaled = |block: &[f64]| -> Vec<f64> { block.chunks_exact(n).flat_map(|row| row.iter().zip(scale).map(|(x, s)| x * s)).collect() };
    if m < n {
        let b = scaled(a);
        return Mat::from_fn(n, n, |i, j| if i < m { b[i * n + j] } else { 0.0 });
    }
    let rows = TSQR_ROWS.max(2 * n); // each level at least halves the rows
    if m <= rows {
        let qr = TallQr::new(&scaled(a), m, n);
        return Mat::from_fn(n, n, |i, j| qr.r()[i * n + j]);
    }
    // A last block shorter than n rows is stacked as it is: the same Gram matrix.
    let factor =
        |block: &[f64]| if block.len() < n * n { scaled(block) } else { TallQr::new(&scaled(block), block.len() / n, n).r().to_vec() };
    let stacked: Vec<f64> = a.par_chunks(rows * n).map(factor).flatten().collect();
    triangular_factor(&stacked, stacked.len() / n, n, &vec![1.0; n])
}

/// `R` of [`triangular_factor`] of `a` with unit-norm columns (`norms`), the columns without
/// effect set to zero.
fn scaled_factor(a: &[f64], m: usize, n: usize, norms: &[f64], effective: &[bool]) -> Mat<f64> {
    let scale: Vec<f64> = norms.iter().zip(effective).map(|(&v, &e)| if e { 1.0 / v } else { 0.0 }).collect();
    triangular_factor(a, m, n, &scale)
}

/// Column-pivoted Householder QR of `a` (p, k): returns the pivot order (`perm[i]` is the column
/// of `a` in position `i`) and `R` (min(p, k), k), upper triangular in pivot order, with
/// `a[:, perm] = Q·R`. Each step takes the column with the largest remaining norm (recomputed,
/// not downdated: k is small) among the columns `first` marks, if that norm is at least
/// [`FIRST_MIN_REL`] of the largest of all, otherwise among all; ties within [`PIVOT_TIE_REL`]
/// go to the lowest column index.
pub fn pivoted_qr(a: faer::MatRef<'_, f64>, first: &[bool]) -> (Vec<usize>, Mat<f64>) {
    let (p, k) = (a.nrows(), a.ncols());
    assert_eq!(first.len(), k, "one `first` flag per column");
    let mut cols: Vec<Vec<f64>> = (0..k).map(|c| (0..p).map(|r| a[(r, c)]).collect()).collect();
    let mut perm: Vec<usize> = (0..k).collect();
    let steps = p.min(k);
    for i in 0..steps {
        let norms: Vec<f64> = cols[i..].iter().map(|c| c[i..].iter().map(|v| v * v).sum::<f64>().sqrt()).collect();
        let largest = norms.iter().copied().fold(0.0, f64::max);
        let marked = |j: usize| first[perm[i + j]];
        let preferred = (0..norms.len()).filter(|&j| marked(j)).map(|j| norms[j]).fold(0.0, f64::max);
        let (pool, top) = if preferred > 0.0 && preferred >= FIRST_MIN_REL * largest { (true, preferred) } else { (false, largest) };
        let best = (0..norms.len())
            .filter(|&j| (!pool || marked(j)) && norms[j] >= top * (1.0 - PIVOT_TIE_REL))
            .min_by_key(|&j| perm[i + j])
            .unwrap_or(0);
        cols.swap(i, i + best);
        perm.swap(i, i + best);
        let alpha = norms[best];
        if alpha == 0.0 {
            break; // every remaining column is zero below row i: R's rest is zero
        }
        // Householder reflector v = x − β·e₁ with β = −sign(x₀)‖x‖ (no cancellation).
        let beta = if cols[i][i] > 0.0 { -alpha } else { alpha };
        let mut v = cols[i][i..].to_vec();
        v[0] -= beta;
        let vv: f64 = v.iter().map(|x| x * x).sum();
        for col in cols[i + 1..].iter_mut() {
            let f = 2.0 * v.iter().zip(&col[i..]).map(|(x, y)| x * y).sum::<f64>() / vv;
            col[i..].iter_mut().zip(&v).for_each(|(y, x)| *y -= f * x);
        }
        cols[i][i] = beta;
        cols[i][i + 1..].iter_mut().for_each(|y| *y = 0.0);
    }
    (perm, Mat::from_fn(steps, k, |r, c| if r <= c { cols[c][r] } else { 0.0 }))
}

/// Identifiability analysis of `J` (m, n) row-major.
///
/// The triangular factor (n, n) of the scaled `J`, then a column-pivoted QR of its columns with
/// an effect ([`pivoted_qr`], the columns `first` marks before the others) picks the
/// identifiable subset; the singular values and the redundancy coefficients come from that QR's
/// triangular factor.
///
/// Errors: `Shape`, `NonFinite`, `InvalidParameter` (tol outside (0, 1)).
pub fn identifiability(j: &[f64], m: usize, n: usize, tol: f64, first: &[bool]) -> CoreResult<Identifiability> {
    check_tol(tol)?;
    row_major("J", j, m, n)?;
    check_len("first", first.len(), n)?;
    let (column_norms, effective) = column_scales(j, n);
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
        // R's columns of the columns with an effect: the same Gram matrix as theirs in Ĵ.
        let factor = scaled_factor(j, m, n, &column_norms, &effective);
        let sub = Mat::from_fn(n, k, |row, c| factor[(row, eff_idx[c])]);
        let marked: Vec<bool> = eff_idx.iter().map(|&c| first[c]).collect();
        let (fwd, r) = pivoted_qr(sub.as_ref(), &marked); // r: (k, k) when m ≥ k (n ≥ k rows always)
        let s = singular_values(r.as_ref())?;
        // With fewer rows than columns (m < k) the extra values are zeros: keep min(m, n).
        let kept = s.len().min(values.len());
        values[..kept].copy_from_slice(&s[..kept]);
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
    row_major("J", j, m, n)?;
    let rv = row_major("r", r, m, 1)?;
    let (norms, effective) = column_scales(j, n);
    let factor = scaled_factor(j, m, n, &norms, &effective);
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
    use proptest::prelude::*;

    /// Columns (x, 2·v, 2·v, y) with |x| = 1 < |y| = 1.5 < |2v| = 2: the first pivot is a tie of
    /// columns 1 and 2 (lowest index wins), after which column 2 has nothing left.
    #[test]
    fn exact_tie_goes_to_the_lowest_column_index() {
        let v = [0.6, 0.0, 0.8, 0.0];
        let rows: Vec<[f64; 4]> =
            (0..4).map(|i| [if i == 1 { 1.0 } else { 0.0 }, 2.0 * v[i], 2.0 * v[i], if i == 3 { 1.5 } else { 0.0 }]).collect();
        let a = Mat::from_fn(4, 4, |r, c| rows[r][c]);
        let (perm, r) = pivoted_qr(a.as_ref(), &[false; 4]);
        assert_eq!(perm, vec![1, 3, 0, 2]);
        assert!(r[(3, 3)].abs() < 1e-15);
        // The same with the duplicate first and a last-bit difference between the two.
        let b = Mat::from_fn(4, 4, |r, c| if c == 2 { a[(r, 1)] * (1.0 + 1e-15) } else { a[(r, c)] });
        assert_eq!(pivoted_qr(b.as_ref(), &[false; 4]).0, vec![1, 3, 0, 2]);
    }

    /// theta1 and base_rz alike: scaled columns 1 and 3 equal up to sign, either one the copy,
    /// on a tall matrix (the triangular factor's two threads). Column 0 takes the first pivot
    /// (all unit norms tie), so the pair's tie is met after a Householder step: the lower index
    /// is identifiable, the other redundant with coefficient ±1.
    #[test]
    fn equal_scaled_columns_keep_the_lower_index() {
        let m = 600;
        let f = |i: usize, c: usize| ((i * (c + 3)) as f64 * 0.37).sin() + 0.1 * c as f64;
        for (dup, orig) in [(1usize, 3usize), (3, 1)] {
            let j: Vec<f64> = (0..m).flat_map(|i| (0..4).map(move |c| if c == dup { -2.5 * f(i, orig) } else { f(i, c) })).collect();
            let id = identifiability(&j, m, 4, 1e-9, &[false; 4]).unwrap();
            assert_eq!(id.rank, 3);
            assert!(id.identifiable.contains(&1) && !id.identifiable.contains(&3), "{:?}", id.identifiable);
            assert_eq!(id.redundant.len(), 1);
            let (col, partners) = &id.redundant[0];
            assert_eq!((*col, partners.len(), partners[0].0), (3, 1, 1));
            assert!((partners[0].1.abs() - 1.0).abs() < 1e-12);
        }
    }

    /// A position sensor's tool point (t_x, t_y) turned by theta6: the theta6 column is
    /// t_x·(tool_y column) − t_y·(tool_x column), so the three have rank 2. Unmarked, the pivots
    /// follow the norms and may keep theta6; with the set-up marked `first`, tool_x and tool_y are
    /// identifiable and theta6 is the redundant one, whatever the norms. A marked column that adds
    /// less than [`FIRST_MIN_REL`] of the largest waits for the others.
    #[test]
    fn marked_columns_are_pivoted_first_while_they_add_enough() {
        let m = 50;
        let g = gaussian_like(3, m, 3);
        let (tx, ty) = (0.3, 0.4);
        // Columns: theta6, tool_x, tool_y (theta6 first: the lowest index wins the unit-norm tie).
        let j: Vec<f64> = (0..m).flat_map(|i| [tx * g[(i, 1)] - ty * g[(i, 0)], g[(i, 0)], g[(i, 1)]]).collect();
        let plain = identifiability(&j, m, 3, 1e-9, &[false; 3]).unwrap();
        assert_eq!((plain.rank, plain.identifiable[0]), (2, 0));
        let id = identifiability(&j, m, 3, 1e-9, &[false, true, true]).unwrap();
        assert_eq!(id.rank, 2);
        assert_eq!(id.identifiable.iter().copied().collect::<std::collections::BTreeSet<_>>(), [1, 2].into());
        assert_eq!(id.redundant.len(), 1);
        assert_eq!(id.redundant[0].0, 0);
        // Two marked columns, nearly copies (the second adds 1e-4 of the first's norm): once one is
        // taken, the other adds less than FIRST_MIN_REL and the unmarked column goes before it.
        let near: Vec<f64> = (0..m).flat_map(|i| [g[(i, 0)], g[(i, 1)], g[(i, 0)] + 1e-4 * g[(i, 2)]]).collect();
        let a = Mat::from_fn(m, 3, |i, c| near[i * 3 + c]);
        let (perm, _) = pivoted_qr(a.as_ref(), &[true, false, true]);
        assert_eq!(perm[1], 1, "{perm:?}");
        let wrong = identifiability(&j, m, 3, 1e-9, &[true; 2]);
        assert!(matches!(wrong, Err(CoreError::Shape { arg: "first", .. })));
    }

    fn gaussian_like(seed: u64, p: usize, k: usize) -> Mat<f64> {
        // A fixed xorshift stream: sums of uniforms, scaled per column (mm and rad mixed).
        let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        let mut next = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let scales: Vec<f64> = (0..k).map(|_| 10f64.powf(4.0 * next())).collect();
        Mat::from_fn(p, k, |_, c| (next() + next() + next()) * scales[c])
    }

    fn row_major_of(a: &Mat<f64>) -> Vec<f64> {
        (0..a.nrows()).flat_map(|i| (0..a.ncols()).map(move |j| a[(i, j)])).collect()
    }

    /// Column norms summed row by row: tiny and huge Jacobians (squares that would underflow or
    /// reach 1e300) give the analysis of the same Jacobian at unit scale.
    #[test]
    fn scale_of_the_jacobian_does_not_matter() {
        let a = gaussian_like(7, 40, 5);
        let j = row_major_of(&a);
        let want = identifiability(&j, 40, 5, 1e-9, &[false; 5]).unwrap();
        for scale in [1e-170, 1e140] {
            let got = identifiability(&j.iter().map(|v| v * scale).collect::<Vec<_>>(), 40, 5, 1e-9, &[false; 5]).unwrap();
            assert_eq!((got.rank, &got.identifiable), (want.rank, &want.identifiable));
            for (g, w) in got.column_norms.iter().zip(&want.column_norms) {
                assert!((g / scale - w).abs() <= 1e-14 * w, "{g} vs {w}");
            }
        }
    }

    /// Blocks, a second level and a short last block (2 600 rows of 7: 6 blocks of 512, the last
    /// 40 rows; then 42 rows), and one block: `R` equals faer's QR of the whole matrix up to the
    /// signs of its rows.
    #[test]
    fn blocked_triangular_factor_is_the_qr_factor() {
        for m in [2600, 3076, 300] {
            let a = gaussian_like(m as u64, m, 7);
            let got = triangular_factor(&row_major_of(&a), m, 7, &[1.0; 7]);
            let want = a.qr().thin_R().to_owned();
            for i in 0..want.nrows() {
                let sign = if (got[(i, i)] > 0.0) == (want[(i, i)] > 0.0) { 1.0 } else { -1.0 };
                for j in 0..7 {
                    let w = if j >= i { want[(i, j)] } else { 0.0 };
                    assert!(
                        (sign * got[(i, j)] - w).abs() <= 1e-12 * want[(0, 0)].abs() * 7f64.powi(3),
                        "m {m} R[{i},{j}]: {} vs {w}",
                        got[(i, j)]
                    );
                }
            }
        }
    }

    proptest! {
        /// On full-rank matrices (no ties) the pivots and |R| equal faer's column-pivoted QR of
        /// the matrix itself, and of its triangular factor (the same Gram matrix).
        #[test]
        fn pivoted_qr_equals_faer(seed in 0u64..1_000_000, k in 1usize..12, extra in 0usize..300) {
            let a = gaussian_like(seed, k + extra, k);
            let qr = a.col_piv_qr();
            let want_perm: Vec<usize> = qr.P().arrays().0.to_vec();
            let want_r = qr.thin_R();
            let none = vec![false; k];
            for (what, got) in [("matrix", pivoted_qr(a.as_ref(), &none)), ("factor", pivoted_qr(triangular_factor(&row_major_of(&a), k + extra, k, &vec![1.0; k]).as_ref(), &none))] {
                prop_assert_eq!(&got.0, &want_perm, "{} pivots", what);
                let scale = want_r[(0, 0)].abs();
                for r in 0..k {
                    for c in r..k {
                        let (g, w) = (got.1[(r, c)].abs(), want_r[(r, c)].abs());
                        prop_assert!((g - w).abs() <= 1e-11 * scale, "{} R[{},{}]: {} vs {}", what, r, c, g, w);
                    }
                }
            }
        }
    }

    /// Entries whose squares overflow made every column "no effect" and the rank 0; they are an
    /// `OutOfRange` error now.
    #[test]
    fn overflowing_entries_are_an_error_not_a_wrong_rank() {
        let j = [1e300, 1.0, 1e300, 2.0, 0.0, 1.0];
        assert!(matches!(identifiability(&j, 3, 2, 1e-9, &[false; 2]), Err(CoreError::OutOfRange { arg: "J", index: 0, .. })));
        assert!(matches!(covariance(&j, &[1.0, 2.0, 3.0], 3, 2, 1e-9), Err(CoreError::OutOfRange { arg: "J", .. })));
    }

    #[test]
    fn finds_duplicate_and_dead_columns() {
        // Columns: c0, c1, c2 = 2·c0 (redundant with c0), c3 = 0 (no effect).
        let rows = [[1.0, 0.0, 2.0, 0.0], [0.0, 1.0, 0.0, 0.0], [1.0, 1.0, 2.0, 0.0], [2.0, -1.0, 4.0, 0.0]];
        let j: Vec<f64> = rows.iter().flatten().copied().collect();
        let id = identifiability(&j, 4, 4, 1e-9, &[false; 4]).unwrap();
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
