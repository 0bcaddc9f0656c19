//! The unscented transform of the paper's UKF (eq. 8–11): Merwe scaled sigma points and their
//! weights (van der Merwe 2004; filterpy's `MerweScaledSigmaPoints(n, alpha, beta, kappa)`), and
//! the weighted mean, covariance and cross-covariance of propagated points.
//! Propagation through a measurement model is `measurement::sigma_residuals`.

use crate::error::{check_finite, CoreError, CoreResult};
use nalgebra::{DMatrix, DVector};

/// Mean and covariance weights `(Wm, Wc)` for dimension `n`.
///
/// Errors: `InvalidParameter` when `α ≤ 0` or `n + λ ≤ 0`.
pub fn merwe_weights(n: usize, alpha: f64, beta: f64, kappa: f64) -> CoreResult<(Vec<f64>, Vec<f64>)> {
    let nf = n as f64;
    let lambda = alpha * alpha * (nf + kappa) - nf;
    // Written as the valid domain so that a NaN `alpha` or `kappa` fails it.
    if !(alpha > 0.0 && nf + lambda > 0.0 && beta.is_finite() && kappa.is_finite()) {
        return Err(CoreError::InvalidParameter {
            arg: "alpha",
            reason: format!("need alpha > 0 and alpha²·(n+kappa) > 0; got alpha={alpha}, kappa={kappa}, n={n}"),
        });
    }
    let w = 1.0 / (2.0 * (nf + lambda));
    let mut wm = vec![w; 2 * n + 1];
    let mut wc = vec![w; 2 * n + 1];
    wm[0] = lambda / (nf + lambda);
    wc[0] = wm[0] + 1.0 - alpha * alpha + beta;
    Ok((wm, wc))
}

/// Sigma points `(2n+1, n)` row-major around mean `x` (n) with covariance `p` (n, n) row-major:
/// `χ₀ = x`, `χ_i = x + col_i(L)`, `χ_{n+i} = x − col_i(L)`, `L Lᵀ = (n+λ)P`. Returns the points
/// and the weights.
///
/// Errors: `Shape`, `NonFinite`, `InvalidParameter`, `NotPositiveDefinite`.
pub fn merwe_sigma_points(x: &[f64], p: &[f64], alpha: f64, beta: f64, kappa: f64) -> CoreResult<(Vec<f64>, Vec<f64>, Vec<f64>)> {
    let n = x.len();
    if n == 0 {
        return Err(CoreError::Shape { arg: "x", expected: "(n,) with n >= 1".into(), got: "(0,)".into() });
    }
    if p.len() != n * n {
        return Err(CoreError::Shape { arg: "P", expected: format!("({n}, {n})"), got: format!("{} values", p.len()) });
    }
    check_finite("x", x)?;
    check_finite("P", p)?;
    let (wm, wc) = merwe_weights(n, alpha, beta, kappa)?;
    let nf = n as f64;
    let lambda = alpha * alpha * (nf + kappa) - nf;
    let pm = DMatrix::from_row_slice(n, n, p) * (nf + lambda);
    let asym = (&pm - pm.transpose()).abs().max();
    if asym > 1e-9 * pm.abs().max() {
        return Err(CoreError::InvalidParameter { arg: "P", reason: format!("must be symmetric; max |P − Pᵀ| = {asym:e}") });
    }
    let l = pm.cholesky().ok_or_else(|| CoreError::NotPositiveDefinite("`P` (sigma-point covariance)".into()))?.unpack();
    let mut out = Vec::with_capacity((2 * n + 1) * n);
    out.extend_from_slice(x);
    for sign in [1.0, -1.0] {
        for i in 0..n {
            out.extend((0..n).map(|r| x[r] + sign * l[(r, i)]));
        }
    }
    Ok((out, wm, wc))
}

/// Weighted statistics of propagated sigma points: `sx` (S, n) the points, `sy` (S, k) their
/// images, row-major. Returns `(ŷ (k), S_yy (k, k), P_xy (n, k))`, the paper's eq. (10)–(11).
///
/// Errors: `Shape`, `NonFinite`.
pub fn unscented_transform(
    sx: &[f64],
    n: usize,
    sy: &[f64],
    k: usize,
    wm: &[f64],
    wc: &[f64],
) -> CoreResult<(Vec<f64>, Vec<f64>, Vec<f64>)> {
    let s = wm.len();
    let shape = |arg, len: usize, expected: String| Err(CoreError::Shape { arg, expected, got: format!("{len} values") });
    if s == 0 {
        return shape("Wm", 0, "(S,) with S >= 1".into());
    }
    if wc.len() != s {
        return shape("Wc", wc.len(), format!("({s},) like `Wm`"));
    }
    if sx.len() != s * n {
        return shape("sigmas_x", sx.len(), format!("({s}, {n}): one row per weight"));
    }
    if sy.len() != s * k {
        return shape("sigmas_y", sy.len(), format!("({s}, {k}): one row per weight"));
    }
    for (arg, v) in [("sigmas_x", sx), ("sigmas_y", sy), ("Wm", wm), ("Wc", wc)] {
        check_finite(arg, v)?;
    }
    let x = DMatrix::from_row_slice(s, n, sx);
    let y = DMatrix::from_row_slice(s, k, sy);
    let wm_v = DVector::from_column_slice(wm);
    let x_mean = x.transpose() * &wm_v;
    let y_mean = y.transpose() * &wm_v;
    let mut dy = y;
    let mut dx = x;
    for i in 0..s {
        dy.row_mut(i).iter_mut().zip(y_mean.iter()).for_each(|(v, m)| *v -= m);
        dx.row_mut(i).iter_mut().zip(x_mean.iter()).for_each(|(v, m)| *v -= m);
    }
    let mut wdy = dy.clone();
    for (i, &w) in wc.iter().enumerate() {
        wdy.row_mut(i).scale_mut(w);
    }
    let cov = dy.transpose() * &wdy;
    let cross = dx.transpose() * &wdy;
    // Finite inputs can still overflow in the weighted products: an error, never inf or NaN.
    if [y_mean.as_slice(), cov.as_slice(), cross.as_slice()].iter().any(|m| m.iter().any(|v| !v.is_finite())) {
        return Err(CoreError::InvalidParameter {
            arg: "sigmas_y",
            reason: "with `sigmas_x` and the weights too large: their weighted products overflow float64".into(),
        });
    }
    let to_row_major = |m: DMatrix<f64>| m.transpose().as_slice().to_vec();
    Ok((y_mean.as_slice().to_vec(), to_row_major(cov), to_row_major(cross)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overflowing_weighted_products_are_an_error() {
        let big = 1e200;
        let got = unscented_transform(&[0.0, 1.0], 1, &[big, -big], 1, &[0.5, 0.5], &[0.5, 0.5]);
        assert!(matches!(got, Err(CoreError::InvalidParameter { arg: "sigmas_y", .. })), "{got:?}");
    }

    #[test]
    fn sigma_points_reproduce_mean_and_covariance() {
        let x = [1.0, -2.0, 0.5];
        let p = [2.0, 0.3, 0.1, 0.3, 1.0, -0.2, 0.1, -0.2, 0.5];
        let (pts, wm, wc) = merwe_sigma_points(&x, &p, 0.3, 2.0, 0.0).unwrap();
        let (mean, cov, cross) = unscented_transform(&pts, 3, &pts, 3, &wm, &wc).unwrap();
        for i in 0..3 {
            assert!((mean[i] - x[i]).abs() < 1e-12);
        }
        for i in 0..9 {
            assert!((cov[i] - p[i]).abs() < 1e-10, "{i}");
            assert!((cross[i] - p[i]).abs() < 1e-10, "{i}");
        }
    }

    #[test]
    fn indefinite_covariance_is_reported() {
        let err = merwe_sigma_points(&[0.0, 0.0], &[1.0, 2.0, 2.0, 1.0], 0.5, 2.0, 0.0).unwrap_err();
        assert!(matches!(err, CoreError::NotPositiveDefinite(_)));
    }
}
