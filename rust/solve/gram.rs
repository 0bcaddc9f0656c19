//! `JᵀJ` of a sparse Jacobian in CSR form: the normal matrix of a model with joint maps.
//!
//! A joint map adds four B-spline coefficients per residual row to the few dozen dense columns
//! of the geometry, so each row holds ~50 entries of several hundred columns. Forming `JᵀJ`
//! from the rows (every pair of a row's entries) costs `Σ nnz_row²/2` multiply-adds — a tenth of
//! the dense product and a third of scipy's general sparse-sparse product, which also builds a
//! sparse result it does not need. The rows are cut into [`PARTS`] fixed blocks summed in order,
//! so the result does not depend on the number of threads.

use crate::error::{check_finite, CoreError, CoreResult};
use rayon::prelude::*;

/// Row blocks accumulated separately (each an `n × n` buffer) and added in order.
const PARTS: usize = 4;
/// Side of the tiles in which the row blocks' sums are mirrored.
const TILE: usize = 64;
/// Largest `n` accepted: the result alone is `n²` doubles (8·10⁸ bytes at this bound).
pub const MAX_GRAM_COLUMNS: usize = 10_000;

/// `JᵀJ` (n × n, row-major) of the CSR matrix `(indptr, indices, data)` with `ncols` columns.
pub fn sparse_gram(indptr: &[usize], indices: &[usize], data: &[f64], ncols: usize) -> CoreResult<Vec<f64>> {
    let bad = |reason: String| Err(CoreError::InvalidParameter { arg: "J", reason });
    if ncols > MAX_GRAM_COLUMNS {
        return bad(format!("at most {MAX_GRAM_COLUMNS} columns; got {ncols}"));
    }
    if indptr.is_empty() || indptr[0] != 0 || indptr.windows(2).any(|w| w[1] < w[0]) {
        return bad("indptr must start at 0 and never decrease".into());
    }
    let nnz = indptr[indptr.len() - 1];
    if indices.len() != nnz || data.len() != nnz {
        return bad(format!("indptr ends at {nnz} but there are {} indices and {} values", indices.len(), data.len()));
    }
    if let Some(&c) = indices.iter().find(|&&c| c >= ncols) {
        return bad(format!("column index {c} is not below the column count {ncols}"));
    }
    check_finite("J", data)?;
    let rows = indptr.len() - 1;
    let step = rows.div_ceil(PARTS).max(1);
    let partial = |part: usize| {
        let mut acc = vec![0.0; ncols * ncols];
        let mut runs = Vec::new();
        for i in (part * step).min(rows)..((part + 1) * step).min(rows) {
            // Each pair of entries once, in either triangle (mirrored below), added as slices
            // over the row's runs of consecutive columns (the geometry's dense columns, a joint
            // map's four spline coefficients), which vectorise: a run with itself by its upper
            // triangle, two runs in the rows of the later one's entries.
            let (start, end) = (indptr[i], indptr[i + 1]);
            runs.clear();
            let mut p = start;
            while p < end {
                let len = leading_run(&indices[p..end]);
                runs.push((p, p + len));
                p += len;
            }
            for (a, &(a0, a1)) in runs.iter().enumerate() {
                let (first, values) = (indices[a0], &data[a0..a1]);
                for (t, &value) in values.iter().enumerate() {
                    let at = (first + t) * ncols + first + t;
                    axpy(&mut acc[at..at + values.len() - t], value, &values[t..]);
                }
                for &(b0, b1) in &runs[a + 1..] {
                    for u in b0..b1 {
                        let at = indices[u] * ncols + first;
                        axpy(&mut acc[at..at + values.len()], data[u], values);
                    }
                }
            }
        }
        acc
    };
    let parts: Vec<Vec<f64>> = (0..PARTS).into_par_iter().map(partial).collect();
    // A pair landed at (col p, col q) in either triangle: G = Σ_parts H + Hᵀ − diag(H), by tiles
    // (the transposed reads stay in cache) and bands of rows in parallel; each element sums the
    // parts in order, so the result does not depend on the number of threads.
    let mut gram = vec![0.0; ncols * ncols];
    if ncols > 0 {
        gram.par_chunks_mut(TILE * ncols).enumerate().for_each(|(band, out)| {
            let a0 = band * TILE;
            for b0 in (0..ncols).step_by(TILE) {
                for part in &parts {
                    for (da, row) in out.chunks_mut(ncols).enumerate() {
                        let a = a0 + da;
                        for b in b0..(b0 + TILE).min(ncols) {
                            row[b] += if a == b { part[a * ncols + a] } else { part[a * ncols + b] + part[b * ncols + a] };
                        }
                    }
                }
            }
        });
    }
    Ok(gram)
}

/// Length of the leading run of consecutive column indices (`c, c+1, c+2, …`) of a CSR row.
fn leading_run(indices: &[usize]) -> usize {
    match indices.first() {
        None => 0,
        Some(&c) => indices.iter().enumerate().take_while(|&(t, &i)| i == c + t).count(),
    }
}

/// `y += a·x` over equal-length slices.
fn axpy(y: &mut [f64], a: f64, x: &[f64]) {
    for (y, x) in y.iter_mut().zip(x) {
        *y += a * x;
    }
}

/// Rows per block of [`normal_equations`]: fixed, so the sums (and the result) do not depend on
/// the number of threads.
const DENSE_BLOCK: usize = 2048;

/// The normal equations `(JᵀJ (n × n), Jᵀr (n))` of a dense `J` (m, n) row-major and `r` (m):
/// fixed row blocks multiplied in parallel (faer) and summed in order. The normal matrix of a
/// calibration (n ≈ 30) costs a fraction of a QR of `J`; the caller decides whether its
/// conditioning allows solving with it.
///
/// Errors: `Shape`, `NonFinite`, `OutOfRange`, `InvalidParameter` (more than [`MAX_GRAM_COLUMNS`] columns).
pub fn normal_equations(j: &[f64], r: &[f64], m: usize, n: usize) -> CoreResult<(Vec<f64>, Vec<f64>)> {
    if n > MAX_GRAM_COLUMNS {
        return Err(CoreError::InvalidParameter { arg: "J", reason: format!("at most {MAX_GRAM_COLUMNS} columns; got {n}") });
    }
    let jm = crate::linalg::row_major("J", j, m, n)?;
    let rv = crate::linalg::row_major("r", r, m, 1)?;
    let blocks = m.div_ceil(DENSE_BLOCK).max(1);
    let partial = |b: usize| {
        let (first, rows) = ((b * DENSE_BLOCK).min(m), DENSE_BLOCK.min(m - (b * DENSE_BLOCK).min(m)));
        let block = jm.subrows(first, rows);
        let gram: faer::Mat<f64> = block.transpose() * block;
        let g: faer::Mat<f64> = block.transpose() * rv.subrows(first, rows);
        (gram, g)
    };
    let parts: Vec<(faer::Mat<f64>, faer::Mat<f64>)> = (0..blocks).into_par_iter().map(partial).collect();
    let (mut gram, mut g) = (vec![0.0; n * n], vec![0.0; n]);
    for (pg, pv) in parts {
        for a in 0..n {
            for b in 0..n {
                gram[a * n + b] += pg[(a, b)];
            }
            g[a] += pv[(a, 0)];
        }
    }
    Ok((gram, g))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_equations_match_the_definition() {
        let (m, n) = (5000, 7);
        let j: Vec<f64> = (0..m * n).map(|k| ((k * 7919) % 1000) as f64 / 500.0 - 1.0).collect();
        let r: Vec<f64> = (0..m).map(|k| ((k * 104729) % 997) as f64 / 997.0).collect();
        let (gram, g) = normal_equations(&j, &r, m, n).unwrap();
        for a in 0..n {
            let ga: f64 = (0..m).map(|i| j[i * n + a] * r[i]).sum();
            assert!((g[a] - ga).abs() <= 1e-10 * (1.0 + ga.abs()));
            for b in 0..n {
                let e: f64 = (0..m).map(|i| j[i * n + a] * j[i * n + b]).sum();
                assert!((gram[a * n + b] - e).abs() <= 1e-10 * (1.0 + e.abs()), "{a} {b}");
            }
        }
        assert!(normal_equations(&j, &r[1..], m, n).is_err());
    }

    fn dense_gram(rows: &[Vec<f64>], n: usize) -> Vec<f64> {
        let mut g = vec![0.0; n * n];
        for r in rows {
            for a in 0..n {
                for b in 0..n {
                    g[a * n + b] += r[a] * r[b];
                }
            }
        }
        g
    }

    #[test]
    fn matches_the_dense_product() {
        // a pseudo-random sparse matrix: 300 rows, 12 columns, about a third filled
        let (m, n) = (300, 12);
        let mut seed = 7u64;
        let mut next = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let (mut indptr, mut indices, mut data, mut rows) = (vec![0], vec![], vec![], vec![]);
        for _ in 0..m {
            let mut row = vec![0.0; n];
            for (c, v) in row.iter_mut().enumerate() {
                if next() < 0.35 {
                    *v = next() * 2.0 - 1.0;
                    indices.push(c);
                    data.push(*v);
                }
            }
            indptr.push(indices.len());
            rows.push(row);
        }
        let got = sparse_gram(&indptr, &indices, &data, n).unwrap();
        for (g, e) in got.iter().zip(dense_gram(&rows, n)) {
            assert!((g - e).abs() <= 1e-12 * (1.0 + e.abs()), "{g} vs {e}");
        }
    }

    #[test]
    fn matches_the_dense_product_with_dense_leading_columns() {
        // the layout of a model with joint maps: a run of dense columns (not always from
        // column 0), then a few scattered ones, some rows unsorted or empty
        let (m, n) = (200, 15);
        let mut seed = 11u64;
        let mut next = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let (mut indptr, mut indices, mut data, mut rows) = (vec![0], vec![], vec![], vec![]);
        for i in 0..m {
            let mut row = vec![0.0; n];
            let first = i % 3;
            let mut cols: Vec<usize> = if i % 17 == 0 {
                vec![]
            } else {
                (first..first + 6).collect()
            };
            cols.extend((9..n).filter(|_| next() < 0.4));
            if i % 5 == 0 {
                cols.reverse();
            }
            for c in cols {
                row[c] = next() * 2.0 - 1.0;
                indices.push(c);
                data.push(row[c]);
            }
            indptr.push(indices.len());
            rows.push(row);
        }
        let got = sparse_gram(&indptr, &indices, &data, n).unwrap();
        for (g, e) in got.iter().zip(dense_gram(&rows, n)) {
            assert!((g - e).abs() <= 1e-12 * (1.0 + e.abs()), "{g} vs {e}");
        }
    }

    #[test]
    fn refuses_malformed_input() {
        assert!(sparse_gram(&[0, 2], &[0, 5], &[1.0, 2.0], 3).is_err()); // column out of range
        assert!(sparse_gram(&[0, 2, 1], &[0, 1], &[1.0, 2.0], 3).is_err()); // indptr decreases
        assert!(sparse_gram(&[0, 2], &[0, 1], &[1.0, f64::NAN], 3).is_err()); // not finite
        assert!(sparse_gram(&[0, 3], &[0, 1], &[1.0, 2.0], 3).is_err()); // lengths disagree
        assert_eq!(sparse_gram(&[0], &[], &[], 2).unwrap(), vec![0.0; 4]); // no rows
    }
}
