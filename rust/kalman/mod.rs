//! One sweep of the paper's UKF (eq. 8–12) over the training samples, parameters as the state.
//!
//! The state `x` is the vector of free parameters `params[cols]` with identity transition and
//! process noise `Q` per sample; each sample is one observation. Per sample, the Merwe sigma
//! points `χ` of `(x, P)` give the prior `x̄ = Σ Wm χ = x` and `P⁻ = P + Q` (the sigma points
//! reproduce `P` exactly, eq. 9); their predicted observations in residual form
//! `z = h(χ) − y = −r(χ)` give `ẑ`, `S = Σ Wc (z − ẑ)(z − ẑ)ᵀ + R` (eq. 10) and
//! `P_xz = Σ Wc (χ − x̄)(z − ẑ)ᵀ`, the gain `K = P_xz S⁻¹` (eq. 11), and
//! `x ← x̄ − K ẑ`, `P ← P⁻ − K S Kᵀ` (eq. 12, observation 0). The sigma points of one sample are
//! evaluated `LANES` at a time (one joint vector, several parameter sets), so a whole sweep runs
//! here without returning to Python.

use crate::error::{check_finite, CoreError, CoreResult};
use crate::kinematics::{Chain, LANES};
use crate::measurement::{residual_of, Batch};
use crate::sigma::merwe_weights;
use nalgebra::{DMatrix, DVector};

/// Filter settings: Merwe sigma-point parameters and the noise covariances.
pub struct UkfSettings<'a> {
    pub alpha: f64,
    pub beta: f64,
    pub kappa: f64,
    /// Process noise per sample, (n, n) row-major.
    pub q: &'a [f64],
    /// Measurement noise of one sample, (k, k) row-major.
    pub r: &'a [f64],
}

fn square(arg: &'static str, data: &[f64], n: usize) -> CoreResult<DMatrix<f64>> {
    if data.len() != n * n {
        return Err(CoreError::Shape { arg, expected: format!("({n}, {n})"), got: format!("{} values", data.len()) });
    }
    check_finite(arg, data)?;
    Ok(DMatrix::from_row_slice(n, n, data))
}

/// Runs one sweep over the samples of `batch` (which holds the full parameter vector whose
/// `cols` entries are the state) from state `x` (n) and covariance `p` (n, n). Returns the new
/// `(x, P)`, `P` row-major.
///
/// Errors: `Shape`, `NonFinite`, `InvalidParameter`, `NotPositiveDefinite` (a covariance lost
/// positive definiteness at a named sample), `Singular` (an innovation covariance `S`).
pub fn ukf_sweep(batch: &Batch, cols: &[usize], x: &[f64], p: &[f64], settings: &UkfSettings) -> CoreResult<(Vec<f64>, Vec<f64>)> {
    let chain: &Chain = batch.chain;
    let y_all = batch.y.ok_or_else(|| CoreError::InvalidParameter { arg: "y", reason: "the filter needs the measured values".into() })?;
    let n = cols.len();
    let n_params = chain.layout().n_params();
    if n == 0 || x.len() != n {
        return Err(CoreError::Shape { arg: "x", expected: format!("({n},) matching `cols`, n >= 1"), got: format!("({},)", x.len()) });
    }
    if let Some(&bad) = cols.iter().find(|&&c| c >= n_params) {
        return Err(CoreError::InvalidParameter {
            arg: "cols",
            reason: format!("column index {bad} out of range for {n_params} parameters"),
        });
    }
    check_finite("x", x)?;
    let k = batch.measurement.res_width();
    let w = batch.measurement.obs_width();
    let mut p = square("P", p, n)?;
    let q = square("Q", settings.q, n)?;
    let r = square("R", settings.r, k)?;
    let (wm, wc) = merwe_weights(n, settings.alpha, settings.beta, settings.kappa)?;
    let nf = n as f64;
    let spread = settings.alpha * settings.alpha * (nf + settings.kappa);
    let sensor_at = chain.layout().sensor();
    let n_sigma = 2 * n + 1;
    let mut x = DVector::from_column_slice(x);
    let mut params: Vec<Vec<f64>> = vec![batch.params.to_vec(); n_sigma];
    let mut z = DMatrix::zeros(n_sigma, k);
    let mut res = vec![0.0; k];
    for i in 0..batch.m {
        let l = (&p * spread)
            .cholesky()
            .ok_or_else(|| CoreError::NotPositiveDefinite(format!("the parameter covariance before sample {i} (0-based) of the sweep")))?;
        let l = l.unpack();
        for (s, ps) in params.iter_mut().enumerate() {
            for (a, &col) in cols.iter().enumerate() {
                let offset = match s {
                    0 => 0.0,
                    s if s <= n => l[(a, s - 1)],
                    s => -l[(a, s - 1 - n)],
                };
                ps[col] = x[a] + offset;
            }
        }
        let q_i = &batch.q[i * chain.n_joints()..(i + 1) * chain.n_joints()];
        let y_i = &y_all[i * w..(i + 1) * w];
        for first in (0..n_sigma).step_by(LANES) {
            let lane_params: [&[f64]; LANES] = std::array::from_fn(|lane| params[(first + lane).min(n_sigma - 1)].as_slice());
            let frames = chain.forward_param_lanes(&chain.prepare_lanes(lane_params), q_i, true);
            for lane in 0..LANES.min(n_sigma - first) {
                let sensor = &lane_params[lane][sensor_at..sensor_at + 5];
                residual_of(batch.measurement, sensor, y_i, &frames.lane(lane), &mut res);
                for c in 0..k {
                    z[(first + lane, c)] = -res[c];
                }
            }
        }
        let z_mean = z.tr_mul(&DVector::from_column_slice(&wm));
        let mut s_cov = r.clone();
        let mut pxz = DMatrix::zeros(n, k);
        for (s, &wc_s) in wc.iter().enumerate().skip(1) {
            // χ_s − x̄ is ±col(L); the centre point (s = 0) has zero state deviation.
            let dz = z.row(s).transpose() - &z_mean;
            let dx = if s <= n { l.column(s - 1).into_owned() } else { -l.column(s - 1 - n) };
            s_cov += wc_s * &dz * dz.transpose();
            pxz += wc_s * dx * dz.transpose();
        }
        let dz0 = z.row(0).transpose() - &z_mean;
        s_cov += wc[0] * &dz0 * dz0.transpose();
        let s_chol =
            s_cov.clone().cholesky().ok_or_else(|| CoreError::Singular(format!("the innovation covariance at sample {i} (0-based)")))?;
        let gain = s_chol.solve(&pxz.transpose()).transpose();
        x -= &gain * &z_mean;
        p = &p + &q - &gain * &s_cov * gain.transpose();
        p = (&p + p.transpose()) * 0.5;
        for ps in params.iter_mut() {
            ps.copy_from_slice(batch.params);
        }
    }
    Ok((x.as_slice().to_vec(), p.transpose().as_slice().to_vec()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixtures::hsr_jr680;
    use crate::measurement::Measurement;

    #[test]
    fn a_sweep_pulls_a_wrong_parameter_towards_the_truth() {
        let (chain, truth) = hsr_jr680();
        let q: Vec<f64> = (0..60 * 6).map(|k| ((k as f64) * 0.618_033_988_75).fract() * 2.0 - 1.0).collect();
        let y = Batch::new(&chain, Measurement::Cable, &truth, &q, None).unwrap().predict();
        let a2 = chain.layout().joint(1).1;
        let mut start = truth.clone();
        start[a2] += 0.8;
        let batch = Batch::new(&chain, Measurement::Cable, &start, &q, Some(&y)).unwrap();
        let settings = UkfSettings { alpha: 0.1, beta: 2.0, kappa: 0.0, q: &[1e-12], r: &[0.03 * 0.03] };
        let (x, p) = ukf_sweep(&batch, &[a2], &[start[a2]], &[1.0], &settings).unwrap();
        assert!((x[0] - truth[a2]).abs() < 0.01, "a2 = {} vs {}", x[0], truth[a2]);
        assert!(p[0] > 0.0 && p[0] < 1e-3);
    }
}
