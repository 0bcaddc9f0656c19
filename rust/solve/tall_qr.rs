//! Householder QR of a tall, narrow matrix (thousands of rows, tens of columns: an
//! identification Jacobian) in one pass over the trailing columns per reflector.
//!
//! A reflector `H = I − τ·v·vᵀ` needs `w = vᵀ·A` of the columns it is applied to. The usual
//! algorithm reads those columns twice per reflector: once for `w`, once to apply `H`. Here the
//! pass that applies reflector `k` also sums, for every trailing column `j`, its dot product with
//! column `k + 1` below row `k + 1` — exactly what the next reflector's norm and `w` are made of —
//! so each reflector reads each column once. The arithmetic is Householder's, in another summation
//! order (backward stable like any Householder QR; no column pivoting: see [`super::DampedQr`]).
//! On a 1 000 × 24 Jacobian it takes 0.14 ms with `Qᵀr`, faer's `Mat::qr` 0.35 ms for `R` alone
//! (`cargo bench --bench core -- damped_qr`; docs/benchmarks.md).

/// `A = Q·R` of an `m × n` matrix, `m ≥ n`: `R` (n × n, upper triangular, row-major) and the
/// reflectors defining `Q`.
#[derive(Debug, Clone)]
pub struct TallQr {
    m: usize,
    n: usize,
    /// Reflector `k` in `v[k·m + k .. (k+1)·m]`, from its 1 at row `k` down (the rows above
    /// hold what `R` was made of: never read).
    v: Vec<f64>,
    tau: Vec<f64>,
    r: Vec<f64>,
}

/// Eight partial sums, so that the compiler vectorises the dot product.
const LANES: usize = 8;

impl TallQr {
    /// Factors the row-major `a` (m × n, `m ≥ n`, finite: the caller checks).
    pub fn new(a: &[f64], m: usize, n: usize) -> Self {
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2 (checked just above).
            return unsafe { Self::new_avx2(a, m, n) };
        }
        Self::factor(a, m, n)
    }

    /// [`Self::new`] compiled for AVX2 (a wheel targets baseline x86-64): four of the eight
    /// partial sums per instruction instead of two. Bit for bit the baseline build's factor: the
    /// same operations in the same order, every one elementwise (no FMA, no reassociation).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn new_avx2(a: &[f64], m: usize, n: usize) -> Self {
        Self::factor(a, m, n)
    }

    #[inline(always)]
    fn factor(a: &[f64], m: usize, n: usize) -> Self {
        debug_assert!(m >= n && a.len() == m * n);
        // Column-major working copy: a reflector is applied down whole columns.
        let mut cols = vec![0.0; n * m];
        for (j, col) in cols.chunks_exact_mut(m.max(1)).enumerate() {
            for (i, x) in col.iter_mut().enumerate() {
                *x = a[i * n + j];
            }
        }
        let (mut tau, mut r) = (vec![0.0; n], vec![0.0; n * n]);
        // below[j]: column k's dot product with column j below row k (the next reflector's sums).
        let mut below = vec![0.0; n];
        if n > 0 && m > 1 {
            let first = &cols[1..m];
            for (j, b) in below.iter_mut().enumerate() {
                *b = dot(first, &cols[j * m + 1..(j + 1) * m]);
            }
        }
        let mut w = vec![0.0; n];
        for k in 0..n {
            let x0 = cols[k * m + k];
            // H·x = β·e_k with β of the sign opposite to x0 (no cancellation in x0 − β);
            // v = (1, x_below / (x0 − β)), τ = (β − x0) / β. Nothing below: H = I.
            let (beta, t, s) = if below[k] == 0.0 {
                (x0, 0.0, 0.0)
            } else {
                let norm = (x0 * x0 + below[k]).sqrt();
                let beta = if x0 >= 0.0 { -norm } else { norm };
                (beta, (beta - x0) / beta, 1.0 / (x0 - beta))
            };
            tau[k] = t;
            r[k * n + k] = beta;
            for j in k + 1..n {
                w[j] = cols[j * m + k] + s * below[j]; // vᵀ·A[:, j]
                r[k * n + j] = cols[j * m + k] - t * w[j];
            }
            let (done, rest) = cols.split_at_mut((k + 1) * m);
            let v = &mut done[k * m..];
            v[k] = 1.0;
            v[k + 1..].iter_mut().for_each(|x| *x *= s);
            if k + 1 == n {
                break;
            }
            let v = &v[..];
            // Column k + 1 first: its rows below k + 1 are the next reflector's.
            let (next, others) = rest.split_at_mut(m);
            let lo = (k + 2).min(m);
            let a = t * w[k + 1];
            for (x, vi) in next[k..].iter_mut().zip(&v[k..]) {
                *x -= a * vi;
            }
            below[k + 1] = dot(&next[lo..], &next[lo..]);
            for j in k + 2..n {
                let col = &mut others[(j - k - 2) * m..(j - k - 1) * m];
                let a = t * w[j];
                for (x, vi) in col[k..lo].iter_mut().zip(&v[k..lo]) {
                    *x -= a * vi;
                }
                below[j] = axpy_dot(&mut col[lo..], &v[lo..], &next[lo..], a);
            }
        }
        Self { m, n, v: cols, tau, r }
    }

    /// `R` (n × n, row-major).
    pub fn r(&self) -> &[f64] {
        &self.r
    }

    /// Number of columns `n`.
    pub fn ncols(&self) -> usize {
        self.n
    }

    /// `Qᵀ·b`'s first `n` entries for `b` (m), O(m·n).
    pub fn project(&self, b: &[f64]) -> Vec<f64> {
        let mut c = b.to_vec();
        for k in 0..self.n {
            let v = &self.v[k * self.m + k..(k + 1) * self.m];
            let tail = &mut c[k..];
            let a = self.tau[k] * dot(v, tail);
            tail.iter_mut().zip(v).for_each(|(x, vi)| *x -= a * vi);
        }
        c.truncate(self.n);
        c
    }
}

#[inline(always)]
fn dot(x: &[f64], y: &[f64]) -> f64 {
    let split = x.len() - x.len() % LANES;
    let mut acc = [0.0; LANES];
    for (xc, yc) in x[..split].chunks_exact(LANES).zip(y[..split].chunks_exact(LANES)) {
        for l in 0..LANES {
            acc[l] += xc[l] * yc[l];
        }
    }
    acc.iter().sum::<f64>() + x[split..].iter().zip(&y[split..]).map(|(a, b)| a * b).sum::<f64>()
}

/// `x −= a·v`, then `h·x`, in one pass.
#[inline(always)]
fn axpy_dot(x: &mut [f64], v: &[f64], h: &[f64], a: f64) -> f64 {
    let split = x.len() - x.len() % LANES;
    let (xs, xr) = x.split_at_mut(split);
    let mut acc = [0.0; LANES];
    for ((xc, vc), hc) in xs.chunks_exact_mut(LANES).zip(v[..split].chunks_exact(LANES)).zip(h[..split].chunks_exact(LANES)) {
        for l in 0..LANES {
            xc[l] -= a * vc[l];
            acc[l] += hc[l] * xc[l];
        }
    }
    let mut sum = acc.iter().sum::<f64>();
    for ((xi, vi), hi) in xr.iter_mut().zip(&v[split..]).zip(&h[split..]) {
        *xi -= a * vi;
        sum += hi * *xi;
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;

    fn matrix(m: usize, n: usize) -> Vec<f64> {
        // Columns falling over six decades, like an unscaled identification Jacobian.
        (0..m * n)
            .map(|p| {
                let (i, j) = (p / n, p % n);
                ((i * 7 + j * 13) % 17) as f64 * 0.1 + ((i * j) as f64 * 0.37).sin() * 10f64.powi(-(j as i32) / 4)
            })
            .collect()
    }

    #[test]
    fn r_and_projection_agree_with_faer() {
        for (m, n) in [(1, 1), (3, 3), (7, 2), (40, 9), (301, 24)] {
            let a = matrix(m, n);
            let b: Vec<f64> = (0..m).map(|i| (i as f64 * 0.11).cos()).collect();
            let ours = TallQr::new(&a, m, n);
            let reference = faer::MatRef::from_row_major_slice(&a, m, n).qr();
            let (r, q) = (reference.thin_R(), reference.compute_thin_Q());
            let big = (0..n).map(|k| r[(k, k)].abs()).fold(1.0, f64::max);
            let c = ours.project(&b);
            for k in 0..n {
                let sign = if r[(k, k)] * ours.r()[k * n + k] < 0.0 { -1.0 } else { 1.0 };
                for j in 0..n {
                    let expected = if j >= k { r[(k, j)] } else { 0.0 };
                    assert!((sign * ours.r()[k * n + j] - expected).abs() < 1e-12 * big, "R[{k},{j}] of {m}x{n}");
                }
                let qtb: f64 = (0..m).map(|i| q[(i, k)] * b[i]).sum();
                assert!((sign * c[k] - qtb).abs() < 1e-10, "(Qᵀb)[{k}] of {m}x{n}");
            }
        }
    }

    #[test]
    fn the_avx2_build_is_the_baseline_build_bit_for_bit() {
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") {
            for (m, n) in [(7, 2), (40, 9), (301, 24), (512, 31)] {
                let a = matrix(m, n);
                // SAFETY: the CPU has AVX2 (checked above).
                let (base, wide) = (TallQr::factor(&a, m, n), unsafe { TallQr::new_avx2(&a, m, n) });
                assert!(base.r == wide.r && base.v == wide.v && base.tau == wide.tau, "{m}x{n}");
            }
        }
    }

    #[test]
    fn a_zero_column_is_no_reflection() {
        // Column 0 is zero (H₀ = I); column 1 is (1, 2, 3, 4, 5).
        let (m, n) = (5, 2);
        let a: Vec<f64> = (0..m).flat_map(|i| [0.0, i as f64 + 1.0]).collect();
        let f = TallQr::new(&a, m, n);
        assert!(f.r()[0] == 0.0 && f.r()[1] == 1.0, "{:?}", f.r());
        let below = 54f64.sqrt(); // ‖(2, 3, 4, 5)‖
        assert!((f.r()[3].abs() - below).abs() < 1e-12);
        // Column 1 lies in the span: all of it is explained, ‖Qᵀb‖ = ‖b‖.
        let c = f.project(&[1.0, 2.0, 3.0, 4.0, 5.0]);
        assert!(c[0] == 1.0 && (c[1].abs() - below).abs() < 1e-12, "{c:?}");
    }
}
