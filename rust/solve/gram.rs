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
    if ncols > MAX_GRAM_COLUMNS {
        return Err(CoreError::InvalidParameter { arg: "J", reason: format!("at most {MAX_GRAM_COLUMNS} columns; got {ncols}") });
    }
    check_csr("J", &Csr { indptr, indices, data, ncols })?;
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

/// A CSR matrix borrowed from its three arrays.
#[derive(Clone, Copy)]
pub struct Csr<'a> {
    pub indptr: &'a [usize],
    pub indices: &'a [usize],
    pub data: &'a [f64],
    pub ncols: usize,
}

impl Csr<'_> {
    fn rows(&self) -> usize {
        self.indptr.len() - 1
    }

    /// Row `i`'s column indices and values.
    fn row(&self, i: usize) -> (&[usize], &[f64]) {
        let (a, b) = (self.indptr[i], self.indptr[i + 1]);
        (&self.indices[a..b], &self.data[a..b])
    }
}

/// Errors: `InvalidParameter` (an `indptr` that does not start at 0 or decreases, lengths that
/// disagree with it, a column index beyond `ncols`), `NonFinite`.
fn check_csr(arg: &'static str, m: &Csr) -> CoreResult<()> {
    let bad = |reason: String| Err(CoreError::InvalidParameter { arg, reason });
    if m.indptr.is_empty() || m.indptr[0] != 0 || m.indptr.windows(2).any(|w| w[1] < w[0]) {
        return bad("indptr must start at 0 and never decrease".into());
    }
    let nnz = m.indptr[m.indptr.len() - 1];
    if m.indices.len() != nnz || m.data.len() != nnz {
        return bad(format!("indptr ends at {nnz} but there are {} indices and {} values", m.indices.len(), m.data.len()));
    }
    if let Some(&c) = m.indices.iter().find(|&&c| c >= m.ncols) {
        return bad(format!("column index {c} is not below the column count {}", m.ncols));
    }
    check_finite(arg, m.data)
}

/// A CSR matrix's `(indptr, indices)`.
pub type CsrPattern = (Vec<usize>, Vec<usize>);

/// The CSR arrays of a Jacobian laid out from its blocks: per row `i` of the `m` data rows, the
/// dense block's `nd` values (row-major `dense`, in columns `dense_cols`), then each thin block's
/// entries (CSR, `m` rows, columns shifted by its offset), all times `weights[i]`; then the rows
/// of `extra` as they are (a problem's prior and roughness rows), whose column count is the
/// Jacobian's (a thin block's is what its offset leaves). Returns the pattern `(indptr,
/// indices)` if `pattern` is set (a problem's is the same at every `x`: the caller keeps the
/// first) and the values. One pass: what scipy needed an index layout and a scatter for.
///
/// Errors: `InvalidParameter` (a malformed CSR, a block of another row count, lengths that
/// disagree), `NonFinite`.
pub fn stack_csr(
    dense: &[f64],
    dense_cols: &[usize],
    thin: &[(Csr, usize)],
    weights: &[f64],
    extra: Csr,
    pattern: bool,
) -> CoreResult<(Option<CsrPattern>, Vec<f64>)> {
    let (m, nd) = (weights.len(), dense_cols.len());
    let bad = |arg: &'static str, reason: String| Err(CoreError::InvalidParameter { arg, reason });
    if dense.len() != m * nd {
        return bad("dense", format!("{m} rows of {nd} values need {} values; got {}", m * nd, dense.len()));
    }
    check_finite("dense", dense)?;
    check_finite("weights", weights)?;
    check_csr("extra", &extra)?;
    if let Some(&c) = dense_cols.iter().find(|&&c| c >= extra.ncols) {
        return bad("dense_cols", format!("column index {c} is not below the column count {}", extra.ncols));
    }
    for (block, _) in thin {
        check_csr("thin", block)?;
        if block.rows() != m {
            return bad("thin", format!("a block has {} rows; the dense block {m}", block.rows()));
        }
    }
    let nnz = m * nd + thin.iter().map(|(b, _)| b.data.len()).sum::<usize>() + extra.data.len();
    let mut data = Vec::with_capacity(nnz);
    for i in 0..m {
        let w = weights[i];
        data.extend(dense[i * nd..(i + 1) * nd].iter().map(|v| v * w));
        for (block, _) in thin {
            data.extend(block.row(i).1.iter().map(|v| v * w));
        }
    }
    data.extend_from_slice(extra.data);
    if !pattern {
        return Ok((None, data));
    }
    let (mut indptr, mut indices) = (Vec::with_capacity(m + extra.rows() + 1), Vec::with_capacity(nnz));
    indptr.push(0);
    for i in 0..m {
        indices.extend_from_slice(dense_cols);
        for (block, offset) in thin {
            indices.extend(block.row(i).0.iter().map(|c| c + offset));
        }
        indptr.push(indices.len());
    }
    for i in 0..extra.rows() {
        indices.extend_from_slice(extra.row(i).0);
        indptr.push(indices.len());
    }
    Ok((Some((indptr, indices)), data))
}

/// Largest output of [`fold_products`], in doubles over all labellings (8·10⁸ bytes).
pub const MAX_FOLD_PRODUCTS: usize = 100_000_000;

/// One labelling's products: `CᵀJ` (folds × nc × p), `Cᵀr` (folds × nc), `CᵀC` (folds × nc × nc),
/// row-major.
#[derive(Debug)]
pub struct FoldProducts {
    pub ctj: Vec<f64>,
    pub ctr: Vec<f64>,
    pub ctc: Vec<f64>,
}

/// The products of `C` (n × nc) with `J` (n × p), `r` (n) and itself over the rows of each fold:
/// for each labelling (`labels[s]`, a fold below `folds[s]` per row), fold `f`'s
/// `C_fᵀJ_f, C_fᵀr_f, C_fᵀC_f`. A screening's held-out folds need these for every candidate;
/// one pass over the rows gives them all (per row, every pair of a `C` entry with a `J` entry)
/// instead of a sparse product per fold. Labellings run in parallel, each summing its rows in order, so the
/// result does not depend on the number of threads.
///
/// Errors: `InvalidParameter` (a malformed CSR, `J`, `r` or a labelling of another row count, a
/// label not below its fold count, an output beyond [`MAX_FOLD_PRODUCTS`]), `NonFinite`.
pub fn fold_products(c: Csr, j: Csr, r: &[f64], labels: &[Vec<usize>], folds: &[usize]) -> CoreResult<Vec<FoldProducts>> {
    check_csr("C", &c)?;
    check_csr("J", &j)?;
    check_finite("r", r)?;
    let bad = |arg: &'static str, reason: String| Err(CoreError::InvalidParameter { arg, reason });
    let n = c.rows();
    if j.rows() != n || r.len() != n {
        return bad("J", format!("C has {n} rows but J has {} and r {}", j.rows(), r.len()));
    }
    if labels.len() != folds.len() {
        return bad("labels", format!("{} labellings but {} fold counts", labels.len(), folds.len()));
    }
    let (nc, p) = (c.ncols, j.ncols);
    let size: usize = folds.iter().map(|&f| f.saturating_mul(nc).saturating_mul(p + nc + 1)).fold(0, usize::saturating_add);
    if size > MAX_FOLD_PRODUCTS {
        return bad("C", format!("the products would hold {size} values; at most {MAX_FOLD_PRODUCTS}"));
    }
    for (s, (label, &count)) in labels.iter().zip(folds).enumerate() {
        if label.len() != n {
            return bad("labels", format!("labelling {s} has {} labels for {n} rows", label.len()));
        }
        if let Some(row) = label.iter().position(|&f| f >= count) {
            return bad("labels", format!("labelling {s} gives row {row} fold {} of {count}", label[row]));
        }
    }
    let one = |(label, &count): (&Vec<usize>, &usize)| {
        let mut out = FoldProducts { ctj: vec![0.0; count * nc * p], ctr: vec![0.0; count * nc], ctc: vec![0.0; count * nc * nc] };
        for (i, &f) in label.iter().enumerate() {
            let ((c_cols, c_vals), (j_cols, j_vals)) = (c.row(i), j.row(i));
            for (&a, &ca) in c_cols.iter().zip(c_vals) {
                let at = f * nc + a;
                let ctj = &mut out.ctj[at * p..(at + 1) * p];
                for (&b, &jb) in j_cols.iter().zip(j_vals) {
                    ctj[b] += ca * jb;
                }
                out.ctr[at] += ca * r[i];
                let ctc = &mut out.ctc[at * nc..(at + 1) * nc];
                for (&b, &cb) in c_cols.iter().zip(c_vals) {
                    ctc[b] += ca * cb;
                }
            }
        }
        out
    };
    Ok(labels.par_iter().zip(folds).map(one).collect())
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
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let (mut indptr, mut indices, mut data, mut rows) = (vec![0], vec![], vec![], vec![]);
        for i in 0..m {
            let mut row = vec![0.0; n];
            let first = i % 3;
            let mut cols: Vec<usize> = if i % 17 == 0 { vec![] } else { (first..first + 6).collect() };
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

    #[test]
    fn fold_products_match_the_definition() {
        // 7 rows, C (7 × 2), J (7 × 3), two labellings
        // rows with one, two or no entries of C
        let c_rows: Vec<Vec<(usize, f64)>> = (0..7)
            .map(|i| match i % 3 {
                0 => vec![(0, 1.0 + i as f64)],
                1 => vec![(0, -2.0), (1, 0.5 * i as f64)],
                _ => vec![],
            })
            .collect();
        let j_rows: Vec<Vec<(usize, f64)>> = (0..7).map(|i| vec![(0, 1.0), (2, (i as f64).sin())]).collect();
        let csr = |rows: &Vec<Vec<(usize, f64)>>| {
            let mut indptr = vec![0];
            let (mut indices, mut data) = (vec![], vec![]);
            for row in rows {
                for &(c, v) in row {
                    indices.push(c);
                    data.push(v);
                }
                indptr.push(indices.len());
            }
            (indptr, indices, data)
        };
        let ((ci, cj, cd), (ji, jj, jd)) = (csr(&c_rows), csr(&j_rows));
        let r: Vec<f64> = (0..7).map(|i| i as f64 - 3.0).collect();
        let labels = vec![vec![0, 1, 2, 0, 1, 2, 0], vec![1, 1, 1, 0, 0, 0, 0]];
        let c = Csr { indptr: &ci, indices: &cj, data: &cd, ncols: 2 };
        let j = Csr { indptr: &ji, indices: &jj, data: &jd, ncols: 3 };
        let out = fold_products(c, j, &r, &labels, &[3, 2]).unwrap();
        let dense = |rows: &Vec<Vec<(usize, f64)>>, i: usize, n: usize| {
            let mut v = vec![0.0; n];
            for &(a, x) in &rows[i] {
                v[a] += x;
            }
            v
        };
        for (s, products) in out.iter().enumerate() {
            let folds = if s == 0 { 3 } else { 2 };
            let (mut ctj, mut ctr, mut ctc) = (vec![0.0; folds * 6], vec![0.0; folds * 2], vec![0.0; folds * 4]);
            for i in 0..7 {
                let (f, ci, ji) = (labels[s][i], dense(&c_rows, i, 2), dense(&j_rows, i, 3));
                for a in 0..2 {
                    for b in 0..3 {
                        ctj[(f * 2 + a) * 3 + b] += ci[a] * ji[b];
                    }
                    ctr[f * 2 + a] += ci[a] * r[i];
                    for b in 0..2 {
                        ctc[(f * 2 + a) * 2 + b] += ci[a] * ci[b];
                    }
                }
            }
            for (got, want) in [(&products.ctj, &ctj), (&products.ctr, &ctr), (&products.ctc, &ctc)] {
                assert!(got.iter().zip(want.iter()).all(|(g, w)| (g - w).abs() <= 1e-12 * (1.0 + w.abs())), "{got:?} != {want:?}");
            }
        }
    }

    #[test]
    fn fold_products_refuse_malformed_input() {
        let (indptr, indices, data) = (vec![0, 1, 2], vec![0, 1], vec![1.0, 2.0]);
        let c = Csr { indptr: &indptr, indices: &indices, data: &data, ncols: 2 };
        let err = |labels: Vec<Vec<usize>>, folds: &[usize], r: &[f64]| fold_products(c, c, r, &labels, folds).unwrap_err().to_string();
        assert!(err(vec![vec![0, 2]], &[2], &[1.0, 1.0]).contains("row 1 fold 2 of 2"));
        assert!(err(vec![vec![0]], &[2], &[1.0, 1.0]).contains("1 labels for 2 rows"));
        assert!(err(vec![vec![0, 1]], &[2], &[1.0]).contains("C has 2 rows"));
        assert!(err(vec![vec![0, 1]], &[2], &[1.0, f64::NAN]).contains("`r` must be finite"));
        let bad = Csr { indptr: &indptr, indices: &[0, 5], data: &data, ncols: 2 };
        assert!(fold_products(bad, c, &[1.0, 1.0], &[vec![0, 0]], &[1]).unwrap_err().to_string().contains("column index 5"));
    }

    #[test]
    fn stack_csr_lays_dense_then_thin_entries_then_extra_rows() {
        // 2 rows: dense columns [0, 1]; a thin block at offset 2 with row 0: col 1, row 1: none
        let (tp, ti, td) = (vec![0, 1, 1], vec![1], vec![5.0]);
        let thin = [(Csr { indptr: &tp, indices: &ti, data: &td, ncols: 2 }, 2)];
        let (ep, ei, ed) = (vec![0, 1], vec![3], vec![7.0]);
        let extra = Csr { indptr: &ep, indices: &ei, data: &ed, ncols: 4 };
        let (layout, data) = stack_csr(&[1.0, 2.0, 3.0, 4.0], &[0, 1], &thin, &[10.0, 100.0], extra, true).unwrap();
        let (indptr, indices) = layout.unwrap();
        assert_eq!(indptr, vec![0, 3, 5, 6]);
        assert_eq!(indices, vec![0, 1, 3, 0, 1, 3]);
        assert_eq!(data, vec![10.0, 20.0, 50.0, 300.0, 400.0, 7.0]);
        let (layout, values) = stack_csr(&[1.0, 2.0, 3.0, 4.0], &[0, 1], &thin, &[10.0, 100.0], extra, false).unwrap();
        assert!(layout.is_none() && values == data);
        assert!(stack_csr(&[1.0, 2.0, 3.0], &[0, 1], &thin, &[10.0, 100.0], extra, true)
            .unwrap_err()
            .to_string()
            .contains("need 4 values"));
    }
}
