//! Measurement models, batched over samples (rows are samples, row-major buffers):
//!
//! - `cable` — the paper's eq. (7) with a sensor zero and scale:
//!   `L = cable_scale·‖p − anchor‖ − cable_offset` (mm), `p` the tool point.
//! - `position` — a 3-D point in the measurement frame: `p` (base = measurement → robot base).
//! - `pose` — a 6-D pose; observations `x,y,z,qw,qx,qy,qz`, residual `(y_p − p, log(R_meas·Rᵀ))`.
//!
//! Residuals are `r = y − h(θ)`; the identification Jacobian is `J = ∂h/∂θ` (the paper's
//! `e = J·X`, eq. 5), so `r(θ+δ) ≈ r(θ) − J·δ`. For `pose` the rotation rows carry the inverse
//! right Jacobian of SO(3) and are the exact derivative of the residual.

mod cable_init;
#[cfg(test)]
mod proptests;
pub mod so3;

pub use cable_init::cable_initial_guess;

use crate::error::{check_kinematic_input, CoreError, CoreResult};
use crate::kinematics::{gather_lanes, lane_vec, splat, Chain, Frame, Frames, Lane, Prepared, Vec3L, BLOCK, LANES, SMALL_BATCH};
use crate::parallel::{for_each_group, for_each_group_pair};
use nalgebra::Vector3;
use rayon::prelude::*;

/// Scratch of one Jacobian task of `L`-sample groups: joint lanes, the ops' axes and origins, `dp`, `dw`.
type JacobianScratch<const L: usize> = (Vec<Lane<L>>, Vec<(Vec3L<L>, Vec3L<L>)>, Vec<Vec3L<L>>, Vec<Vec3L<L>>);

/// Samples per group of a Jacobian batch of [`SMALL_BATCH`] samples or more: wide enough for
/// the AVX2 build of the groups (`parallel`). In 4-lane SSE2 groups the forward kinematics cost
/// 2.5 times the residuals' (16 000 cable samples: 4.2 ms for one column against 1.6 ms); in 16
/// the residuals with 7 columns take 3.2 ms instead of 4.9, with 25 columns 5.7 instead of 6.7.
/// Smaller batches (a filter's single samples) keep `LANES`.
const JACOBIAN_GROUP: usize = 16;

/// What a sample observes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Measurement {
    Cable,
    Position,
    Pose,
}

impl Measurement {
    pub fn parse(s: &str) -> CoreResult<Self> {
        match s.to_ascii_lowercase().as_str() {
            "cable" => Ok(Self::Cable),
            "position" => Ok(Self::Position),
            "pose" => Ok(Self::Pose),
            other => Err(CoreError::InvalidParameter {
                arg: "measurement",
                reason: format!("expected 'cable', 'position' or 'pose'; got '{other}'"),
            }),
        }
    }

    /// Values observed per sample: 1 (L), 3 (x,y,z), 7 (x,y,z,qw,qx,qy,qz).
    pub fn obs_width(self) -> usize {
        match self {
            Self::Cable => 1,
            Self::Position => 3,
            Self::Pose => 7,
        }
    }

    /// Residual components per sample: 1, 3, 6.
    pub fn res_width(self) -> usize {
        match self {
            Self::Cable => 1,
            Self::Position => 3,
            Self::Pose => 6,
        }
    }
}

/// A validated batch: chain, parameters, joint vectors and (optionally) observations.
pub struct Batch<'a> {
    pub chain: &'a Chain,
    pub measurement: Measurement,
    pub params: &'a [f64],
    pub q: &'a [f64],
    pub y: Option<&'a [f64]>,
    pub m: usize,
    prepared: Prepared,
}

impl<'a> Batch<'a> {
    /// Checks lengths and finiteness; for `pose`, that every observed quaternion has unit norm
    /// (to 1e-3). `y` may be omitted where it is not needed (prediction, cable/position Jacobian).
    ///
    /// Errors: `Shape`, `NonFinite`, `OutOfRange`, `InvalidParameter`.
    pub fn new(chain: &'a Chain, measurement: Measurement, params: &'a [f64], q: &'a [f64], y: Option<&'a [f64]>) -> CoreResult<Self> {
        let m = chain.check_inputs(params, q)?;
        if m == 0 {
            return Err(CoreError::Shape {
                arg: "q",
                expected: format!("(m, {}) with m >= 1", chain.n_joints()),
                got: format!("(0, {})", chain.n_joints()),
            });
        }
        if let Some(y) = y {
            let w = measurement.obs_width();
            if y.len() != m * w {
                return Err(CoreError::Shape { arg: "y", expected: format!("({m}, {w})"), got: format!("{} values", y.len()) });
            }
            check_kinematic_input("y", y)?;
            if measurement == Measurement::Pose {
                for (i, row) in y.chunks_exact(7).enumerate() {
                    let n = (row[3] * row[3] + row[4] * row[4] + row[5] * row[5] + row[6] * row[6]).sqrt();
                    if (n - 1.0).abs() > 1e-3 {
                        return Err(CoreError::InvalidParameter {
                            arg: "y",
                            reason: format!("row {i}: quaternion (qw,qx,qy,qz) must have unit norm; got norm {n}"),
                        });
                    }
                }
            }
        }
        let prepared = chain.prepare(params);
        Ok(Self { chain, measurement, params, q, y, m, prepared })
    }

    /// Scratch lanes for one group's joint vectors.
    fn q_scratch<const L: usize>(&self) -> Vec<Lane<L>> {
        vec![splat(0.0); self.chain.n_joints()]
    }

    /// Tool frames of samples `first .. first+count` (unused lanes repeat the last sample).
    #[inline(always)]
    fn tool_frames<const L: usize>(&self, first: usize, count: usize, ql: &mut [Lane<L>]) -> Frames<L> {
        gather_lanes(self.q, self.chain.n_joints(), first, count, ql);
        self.chain.forward(&self.prepared, ql, true)
    }

    /// The observations, or an error saying that this computation needs them.
    fn observed(&self) -> CoreResult<&[f64]> {
        self.y.ok_or_else(|| CoreError::InvalidParameter {
            arg: "y",
            reason: format!("the {:?} residuals need the measured values", self.measurement).to_lowercase(),
        })
    }

    /// Observations of sample `i`; only called after `observed()` succeeded.
    fn y_row(&self, i: usize) -> &[f64] {
        let w = self.measurement.obs_width();
        &self.y.unwrap_or_default()[i * w..(i + 1) * w]
    }

    /// The sensor block `anchor_x, anchor_y, anchor_z, cable_offset, cable_scale`.
    fn sensor(&self) -> &[f64] {
        let s = self.chain.layout().sensor();
        &self.params[s..s + 5]
    }

    /// Model prediction of one sample with tool frame `f` into `out` (obs_width values).
    fn predict_row(&self, f: &Frame, out: &mut [f64]) {
        match self.measurement {
            Measurement::Cable => {
                let (dist, _, offset, scale) = cable_terms(self.sensor(), &f.t);
                out[0] = scale * dist - offset;
            }
            Measurement::Position => out.copy_from_slice(f.t.as_slice()),
            Measurement::Pose => {
                out[..3].copy_from_slice(f.t.as_slice());
                out[3..].copy_from_slice(&so3::quaternion_from_matrix(&f.rotation()));
            }
        }
    }

    /// Residual `y − h` of sample `i` given its tool frame.
    fn residual_row(&self, i: usize, f: &Frame, out: &mut [f64]) {
        residual_of(self.measurement, self.sensor(), self.y_row(i), f, out);
    }

    /// Model predictions, (m, obs_width) row-major.
    pub fn predict(&self) -> Vec<f64> {
        self.per_sample(self.measurement.obs_width(), false)
    }

    /// Residuals `y − h`, (m, res_width) row-major.
    ///
    /// Errors: `InvalidParameter` when the batch has no observations.
    pub fn residuals(&self) -> CoreResult<Vec<f64>> {
        self.observed()?;
        Ok(self.per_sample(self.measurement.res_width(), true))
    }

    /// Residuals (`residual`) or predictions of every sample, `width` values each.
    fn per_sample(&self, width: usize, residual: bool) -> Vec<f64> {
        let mut out = vec![0.0; self.m * width];
        if self.m < SMALL_BATCH {
            for_each_group::<LANES, _, _, _>(
                &mut out,
                width,
                || self.q_scratch::<LANES>(),
                |first, count, rows, ql| self.sample_rows(residual, first, count, rows, ql),
            );
        } else {
            for_each_group::<BLOCK, _, _, _>(
                &mut out,
                width,
                || self.q_scratch::<BLOCK>(),
                #[inline(always)]
                |first, count, rows, ql| self.sample_rows(residual, first, count, rows, ql),
            );
        }
        out
    }

    /// Rows of samples `first .. first+count` (see `per_sample`), `L` at a time.
    #[inline(always)]
    fn sample_rows<const L: usize>(&self, residual: bool, first: usize, count: usize, rows: &mut [f64], ql: &mut [Lane<L>]) {
        let f = self.tool_frames(first, count, ql);
        for (l, row) in rows.chunks_exact_mut(rows.len() / count).enumerate() {
            if residual {
                self.residual_row(first + l, &f.lane(l), row);
            } else {
                self.predict_row(&f.lane(l), row);
            }
        }
    }

    /// Identification Jacobian `∂h/∂params[cols]`, (m·res_width, cols.len()) row-major.
    ///
    /// Errors: `InvalidParameter` if a column index is out of range, or for `pose` without
    /// observations (its rotation rows depend on the residual).
    pub fn jacobian(&self, cols: &[usize]) -> CoreResult<Vec<f64>> {
        if self.measurement == Measurement::Pose {
            self.observed()?;
        }
        let wanted = self.wanted(cols)?;
        let mut out = vec![0.0; self.m * self.measurement.res_width() * cols.len()];
        if self.m < SMALL_BATCH {
            self.jacobian_into::<LANES>(cols, &wanted, &mut out);
        } else {
            self.jacobian_into::<JACOBIAN_GROUP>(cols, &wanted, &mut out);
        }
        Ok(out)
    }

    /// [`Self::jacobian`] into `out`, in groups of `L` samples.
    fn jacobian_into<const L: usize>(&self, cols: &[usize], wanted: &[bool], out: &mut [f64]) {
        for_each_group::<L, _, _, _>(
            out,
            self.measurement.res_width() * cols.len(),
            || self.jacobian_scratch::<L>(),
            #[inline(always)]
            |first, count, rows, scratch| {
                let f = self.frames_with_derivatives(first, count, wanted, scratch);
                self.jacobian_group(first, count, &f, &scratch.2, &scratch.3, cols, rows);
            },
        );
    }

    /// Residuals `y − h` (m·res_width) and the Jacobian of [`Self::jacobian`] in one pass over the
    /// samples: the Jacobian's forward kinematics gives the tool frames the residuals are made of
    /// (the same operations in the same order as [`Self::residuals`]: bit for bit its values).
    ///
    /// Errors: those of [`Self::residuals`] and [`Self::jacobian`].
    pub fn residuals_and_jacobian(&self, cols: &[usize]) -> CoreResult<(Vec<f64>, Vec<f64>)> {
        self.observed()?;
        let wanted = self.wanted(cols)?;
        let k = self.measurement.res_width();
        if cols.is_empty() {
            return Ok((self.residuals()?, Vec::new()));
        }
        let (mut r, mut out) = (vec![0.0; self.m * k], vec![0.0; self.m * k * cols.len()]);
        if self.m < SMALL_BATCH {
            self.residuals_and_jacobian_into::<LANES>(cols, &wanted, &mut r, &mut out);
        } else {
            self.residuals_and_jacobian_into::<JACOBIAN_GROUP>(cols, &wanted, &mut r, &mut out);
        }
        Ok((r, out))
    }

    /// [`Self::residuals_and_jacobian`] into `r` and `out`, in groups of `L` samples.
    fn residuals_and_jacobian_into<const L: usize>(&self, cols: &[usize], wanted: &[bool], r: &mut [f64], out: &mut [f64]) {
        let k = self.measurement.res_width();
        for_each_group_pair::<L, _, _, _>(
            out,
            k * cols.len(),
            r,
            k,
            || self.jacobian_scratch::<L>(),
            #[inline(always)]
            |first, count, rows, res, scratch| {
                let f = self.frames_with_derivatives(first, count, wanted, scratch);
                self.jacobian_group(first, count, &f, &scratch.2, &scratch.3, cols, rows);
                for (l, row) in res.chunks_exact_mut(k).enumerate() {
                    self.residual_row(first + l, &f.lane(l), row);
                }
            },
        );
    }

    /// Which parameters `cols` asks for (length `n_params`), or an error naming a column out of range.
    fn wanted(&self, cols: &[usize]) -> CoreResult<Vec<bool>> {
        let n_params = self.chain.layout().n_params();
        if let Some(&bad) = cols.iter().find(|&&c| c >= n_params) {
            return Err(CoreError::InvalidParameter {
                arg: "cols",
                reason: format!("column index {bad} out of range for {n_params} parameters"),
            });
        }
        let mut wanted = vec![false; n_params];
        cols.iter().for_each(|&c| wanted[c] = true);
        Ok(wanted)
    }

    /// Scratch of [`Self::frames_with_derivatives`]: joint lanes, the ops' axes, `dp`, `dw`.
    fn jacobian_scratch<const L: usize>(&self) -> JacobianScratch<L> {
        let zero: Vec3L<L> = [splat(0.0); 3];
        let n_params = self.chain.layout().n_params();
        (self.q_scratch::<L>(), vec![(zero, zero); self.chain.n_ops()], vec![zero; n_params], vec![zero; n_params])
    }

    /// Tool frames of samples `first .. first+count` with the derivatives of the `wanted`
    /// parameters in `scratch.2` (`dp`) and `scratch.3` (`dw`).
    #[inline(always)]
    fn frames_with_derivatives<const L: usize>(
        &self,
        first: usize,
        count: usize,
        wanted: &[bool],
        scratch: &mut JacobianScratch<L>,
    ) -> Frames<L> {
        let (ql, axes, dp, dw) = scratch;
        gather_lanes(self.q, self.chain.n_joints(), first, count, ql);
        let orientation = self.measurement == Measurement::Pose;
        self.chain.forward_with_jacobian(&self.prepared, ql, wanted, orientation, axes, dp, dw)
    }

    /// The Jacobian rows of samples `first .. first+count` (lanes of `f`, `dp`, `dw`) into
    /// `rows` (`count · res_width · cols.len()` values), restricted to `cols`.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn jacobian_group<const L: usize>(
        &self,
        first: usize,
        count: usize,
        f: &Frames<L>,
        dp: &[Vec3L<L>],
        dw: &[Vec3L<L>],
        cols: &[usize],
        rows: &mut [f64],
    ) {
        let nc = cols.len();
        let width = self.measurement.res_width() * nc;
        match self.measurement {
            Measurement::Cable => {
                let s = self.chain.layout().sensor();
                let terms: [_; L] = std::array::from_fn(|l| cable_terms(self.sensor(), &lane_vec(&f.t, l)));
                let scale = self.params[s + 4];
                let u: Vec3L<L> = std::array::from_fn(|r| std::array::from_fn(|l| terms[l].1[r]));
                for (c, &col) in cols.iter().enumerate() {
                    let v: Lane<L> = match col.checked_sub(s) {
                        Some(a @ 0..=2) => std::array::from_fn(|l| -scale * u[a][l]),
                        Some(3) => splat(-1.0),
                        Some(4) => std::array::from_fn(|l| terms[l].0),
                        _ => {
                            let d = &dp[col];
                            std::array::from_fn(|l| scale * (u[0][l] * d[0][l] + u[1][l] * d[1][l] + u[2][l] * d[2][l]))
                        }
                    };
                    for l in 0..count {
                        rows[l * width + c] = v[l];
                    }
                }
            }
            Measurement::Position => {
                for (c, &col) in cols.iter().enumerate() {
                    for r in 0..3 {
                        for l in 0..count {
                            rows[l * width + r * nc + c] = dp[col][r][l];
                        }
                    }
                }
            }
            Measurement::Pose => {
                for (l, block) in rows.chunks_exact_mut(width).enumerate() {
                    let mut e = [0.0; 6];
                    self.residual_row(first + l, &f.lane(l), &mut e);
                    let jinv = so3::right_jacobian_inverse(&Vector3::new(e[3], e[4], e[5]));
                    for (c, &col) in cols.iter().enumerate() {
                        let rot = jinv * lane_vec(&dw[col], l);
                        for r in 0..3 {
                            block[r * nc + c] = dp[col][r][l];
                            block[(r + 3) * nc + c] = rot[r];
                        }
                    }
                }
            }
        }
    }
}

/// Distance, unit direction, offset and scale of the cable model for tool point `p`, with
/// `sensor` = `anchor_x, anchor_y, anchor_z, cable_offset, cable_scale`.
pub(crate) fn cable_terms(sensor: &[f64], p: &Vector3<f64>) -> (f64, Vector3<f64>, f64, f64) {
    let diff = p - Vector3::new(sensor[0], sensor[1], sensor[2]);
    let dist = diff.norm();
    // A tool point exactly on the anchor has no direction; any unit vector is a valid
    // subgradient, and returning one keeps the Jacobian finite.
    let u = if dist > 0.0 { diff / dist } else { Vector3::x() };
    (dist, u, sensor[3], sensor[4])
}

/// Residual `y − h` of one sample with tool frame `f` and observation `y` into `out`.
pub fn residual_of(measurement: Measurement, sensor: &[f64], y: &[f64], f: &Frame, out: &mut [f64]) {
    match measurement {
        Measurement::Cable => {
            let (dist, _, offset, scale) = cable_terms(sensor, &f.t);
            out[0] = y[0] - (scale * dist - offset);
        }
        Measurement::Position => {
            for c in 0..3 {
                out[c] = y[c] - f.t[c];
            }
        }
        Measurement::Pose => {
            for c in 0..3 {
                out[c] = y[c] - f.t[c];
            }
            let e = so3::log(&(so3::matrix_from_quaternion(&y[3..7]) * f.rotation().transpose()));
            out[3..6].copy_from_slice(e.as_slice());
        }
    }
}

/// Residuals of every sigma point: row `s` holds `r(θ_s)` (m·res_width values) where `θ_s` is
/// `params` with `params[cols] = sigmas[s]`. `sigmas` is (S, cols.len()) row-major.
///
/// Errors: `Shape`, `NonFinite`, `OutOfRange`, `InvalidParameter`.
pub fn sigma_residuals(batch: &Batch, cols: &[usize], sigmas: &[f64]) -> CoreResult<Vec<f64>> {
    let n_params = batch.chain.layout().n_params();
    if let Some(&bad) = cols.iter().find(|&&c| c >= n_params) {
        return Err(CoreError::InvalidParameter {
            arg: "cols",
            reason: format!("column index {bad} out of range for {n_params} parameters"),
        });
    }
    let nc = cols.len();
    if nc == 0 || !sigmas.len().is_multiple_of(nc) {
        return Err(CoreError::Shape {
            arg: "sigmas",
            expected: format!("(S, {nc}) with {nc} >= 1"),
            got: format!("{} values", sigmas.len()),
        });
    }
    check_kinematic_input("sigmas", sigmas)?;
    let width = batch.m * batch.measurement.res_width();
    let mut out = vec![0.0; sigmas.len() / nc * width];
    // Parallel over parameter sets (a population or the sigma points): each writes its own row,
    // so the result does not depend on the number of threads.
    out.par_chunks_mut(width.max(1)).zip(sigmas.par_chunks_exact(nc)).try_for_each(|(row, sigma)| {
        let mut params = batch.params.to_vec();
        for (&col, &v) in cols.iter().zip(sigma) {
            params[col] = v;
        }
        let b = Batch { params: &params, prepared: batch.chain.prepare(&params), ..*batch };
        row.copy_from_slice(&b.residuals()?);
        Ok(())
    })?;
    Ok(out)
}
