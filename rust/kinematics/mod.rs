//! Serial-chain forward kinematics: the paper's eq. (1)–(2) (standard DH), Craig's modified DH,
//! and Hayati's extra rotation β about y, with a base and a tool frame.
//!
//! A chain is compiled once into a flat list of elementary transforms (`Op`), each a rotation or a
//! translation along one local axis and driven by one entry of the parameter vector (plus a joint
//! variable). Forward kinematics post-multiplies a frame by each op in place: a rotation touches
//! two columns, a translation one vector, so a 6-joint pose costs a few hundred flops.
//!
//! Parameter vector layout (see `docs/core-model.md`), N joints, length `5N + 17`:
//! `alpha_i a_i d_i theta_i beta_i` per joint, then `base_{x,y,z,rx,ry,rz}`,
//! `tool_{x,y,z,rx,ry,rz}`, `anchor_{x,y,z}`, `cable_offset`, `cable_scale`.
//! Units: mm and rad (`cable_scale` is dimensionless).

mod frame;
mod lanes;
mod layout;

pub use frame::Frame;
use lanes::sin_cos;
pub use lanes::{lane_vec, splat, Frames, Lane, Vec3L, BLOCK, LANES, SMALL_BATCH};
pub use layout::Layout;

use crate::error::{check_kinematic_input, check_len, CoreError, CoreResult};
use crate::parallel::for_each_group;

/// Link convention of one joint.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Convention {
    /// Standard DH: `Rz(θ+q)·Tz(d)·Tx(a)·Rx(α)·Ry(β)`.
    Dh,
    /// Modified DH (Craig): `Rx(α)·Tx(a)·Ry(β)·Rz(θ+q)·Tz(d)`.
    Mdh,
}

impl Convention {
    pub fn parse(s: &str) -> CoreResult<Self> {
        match s.to_ascii_lowercase().as_str() {
            "dh" => Ok(Self::Dh),
            "mdh" => Ok(Self::Mdh),
            other => Err(CoreError::InvalidParameter { arg: "conventions", reason: format!("expected 'dh' or 'mdh'; got '{other}'") }),
        }
    }
}

/// What the joint variable drives.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointKind {
    /// `q` adds to θ (rad).
    Revolute,
    /// `q` adds to d (mm).
    Prismatic,
}

impl JointKind {
    pub fn parse(s: &str) -> CoreResult<Self> {
        match s.to_ascii_lowercase().as_str() {
            "revolute" | "r" => Ok(Self::Revolute),
            "prismatic" | "p" => Ok(Self::Prismatic),
            other => {
                Err(CoreError::InvalidParameter { arg: "kinds", reason: format!("expected 'revolute' or 'prismatic'; got '{other}'") })
            }
        }
    }
}

/// One elementary transform: rotation about / translation along local axis `axis` (0=x,1=y,2=z)
/// by `params[param]` (+ `q[joint]` when driven by a joint).
#[derive(Debug, Clone, Copy)]
pub struct Op {
    pub axis: usize,
    pub rotation: bool,
    pub param: usize,
    pub joint: Option<usize>,
}

/// Per-op constants of one parameter vector: the parameter value and, for ops not driven by a
/// joint, its sine and cosine — so a batch evaluates only the joints' trigonometry per sample.
#[derive(Debug, Clone)]
pub struct Prepared {
    ops: Vec<[f64; 3]>,
    /// `false` for ops that are the identity for these parameters (skipped).
    active: Vec<bool>,
}

/// Per-op constants of `LANES` parameter vectors (one per lane), for evaluating one joint
/// vector under several parameter sets at once (the sigma points of a filter update).
#[derive(Debug, Clone)]
pub struct PreparedLanes {
    ops: Vec<[Lane; 3]>,
}

/// Copies joint vectors `first .. first+count` of `q` ((m, n) row-major) into lanes
/// `out[j][lane]`, repeating the last one in unused lanes.
#[inline(always)]
pub fn gather_lanes<const L: usize>(q: &[f64], n: usize, first: usize, count: usize, out: &mut [Lane<L>]) {
    for l in 0..L {
        let i = first + l.min(count - 1);
        for (j, lane) in out.iter_mut().enumerate() {
            lane[l] = q[i * n + j];
        }
    }
}

/// A compiled serial chain: base, N links, tool.
#[derive(Debug, Clone)]
pub struct Chain {
    conventions: Vec<Convention>,
    kinds: Vec<JointKind>,
    layout: Layout,
    ops: Vec<Op>,
    /// Ops `[0, flange_end)` give the flange frame; the rest is the tool.
    flange_end: usize,
}

const X: usize = 0;
const Y: usize = 1;
const Z: usize = 2;

impl Chain {
    /// Builds a chain from one convention and one kind per joint.
    ///
    /// Errors: `Shape` if the lists differ in length or are empty.
    pub fn new(conventions: Vec<Convention>, kinds: Vec<JointKind>) -> CoreResult<Self> {
        if conventions.is_empty() || conventions.len() != kinds.len() {
            return Err(CoreError::Shape {
                arg: "kinds",
                expected: format!("({},) matching `conventions` (at least one joint)", conventions.len()),
                got: format!("({},)", kinds.len()),
            });
        }
        let layout = Layout::new(conventions.len());
        let rot = |axis, param, joint| Op { axis, rotation: true, param, joint };
        let trans = |axis, param, joint| Op { axis, rotation: false, param, joint };
        let rpy_block = |start: usize| {
            [
                trans(X, start, None),
                trans(Y, start + 1, None),
                trans(Z, start + 2, None),
                rot(Z, start + 5, None),
                rot(Y, start + 4, None),
                rot(X, start + 3, None),
            ]
        };
        let mut ops: Vec<Op> = rpy_block(layout.base()).to_vec();
        for (j, (&conv, &kind)) in conventions.iter().zip(&kinds).enumerate() {
            let (alpha, a, d, theta, beta) = layout.joint(j);
            let (q_theta, q_d) = match kind {
                JointKind::Revolute => (Some(j), None),
                JointKind::Prismatic => (None, Some(j)),
            };
            let link = match conv {
                Convention::Dh => [rot(Z, theta, q_theta), trans(Z, d, q_d), trans(X, a, None), rot(X, alpha, None), rot(Y, beta, None)],
                Convention::Mdh => [rot(X, alpha, None), trans(X, a, None), rot(Y, beta, None), rot(Z, theta, q_theta), trans(Z, d, q_d)],
            };
            ops.extend_from_slice(&link);
        }
        let flange_end = ops.len();
        ops.extend_from_slice(&rpy_block(layout.tool()));
        Ok(Self { conventions, kinds, layout, ops, flange_end })
    }

    /// Parses convention and kind names (`"dh"|"mdh"`, `"revolute"|"prismatic"`).
    pub fn from_names<S: AsRef<str>>(conventions: &[S], kinds: &[S]) -> CoreResult<Self> {
        let c = conventions.iter().map(|s| Convention::parse(s.as_ref())).collect::<CoreResult<_>>()?;
        let k = kinds.iter().map(|s| JointKind::parse(s.as_ref())).collect::<CoreResult<_>>()?;
        Self::new(c, k)
    }

    pub fn n_joints(&self) -> usize {
        self.conventions.len()
    }
    pub fn layout(&self) -> &Layout {
        &self.layout
    }
    pub fn conventions(&self) -> &[Convention] {
        &self.conventions
    }
    pub fn kinds(&self) -> &[JointKind] {
        &self.kinds
    }

    /// Validates a parameter vector and a batch of joint vectors; returns the sample count.
    ///
    /// Errors: `Shape` (lengths), `NonFinite`, `OutOfRange`.
    pub fn check_inputs(&self, params: &[f64], q: &[f64]) -> CoreResult<usize> {
        check_len("params", params.len(), self.layout.n_params())?;
        check_kinematic_input("params", params)?;
        let n = self.n_joints();
        if !q.len().is_multiple_of(n) {
            return Err(CoreError::Shape {
                arg: "q",
                expected: format!("(m, {n})"),
                got: format!("{} values, not a multiple of {n}", q.len()),
            });
        }
        check_kinematic_input("q", q)?;
        Ok(q.len() / n)
    }

    /// Per-op constants of one parameter vector (see [`Prepared`]).
    pub fn prepare(&self, params: &[f64]) -> Prepared {
        let ops = self
            .ops
            .iter()
            .map(|op| {
                let v = params[op.param];
                let (s, c) = if op.rotation && op.joint.is_none() { v.sin_cos() } else { (0.0, 1.0) };
                [v, s, c]
            })
            .collect();
        // A constant op with value 0 is the identity: base, tool rotations and β are usually 0.
        let active = self.ops.iter().map(|op| op.joint.is_some() || params[op.param] != 0.0).collect();
        Prepared { ops, active }
    }

    /// Post-multiplies `f` by op `k` for a group of joint vectors (`q[j][lane]`): constant ops
    /// with their prepared value, joint ops with the joint variable added per lane.
    #[inline(always)]
    fn apply_op<const L: usize>(&self, k: usize, pre: &Prepared, q: &[Lane<L>], f: &mut Frames<L>) {
        let [v, s, c] = pre.ops[k];
        let op = &self.ops[k];
        match op.joint {
            None => f.apply(op, v, s, c),
            Some(j) => {
                let mut vl = q[j];
                vl.iter_mut().for_each(|x| *x += v);
                let (s, c) = if op.rotation { sin_cos(&vl) } else { (splat(0.0), splat(1.0)) };
                f.apply(op, &vl, &s, &c);
            }
        }
    }

    /// Poses of the flange (`tool = false`) or of the tool frame for `L` joint vectors
    /// `q[j][lane]`. Inputs are assumed validated (`check_inputs`).
    #[inline(always)]
    pub fn forward<const L: usize>(&self, pre: &Prepared, q: &[Lane<L>], tool: bool) -> Frames<L> {
        let end = if tool { self.ops.len() } else { self.flange_end };
        let mut f = Frames::identity();
        for k in 0..end {
            if pre.active[k] {
                self.apply_op(k, pre, q, &mut f);
            }
        }
        f
    }

    /// Per-op constants of `LANES` parameter vectors (see [`PreparedLanes`]).
    pub fn prepare_lanes(&self, params: [&[f64]; LANES]) -> PreparedLanes {
        let ops = self
            .ops
            .iter()
            .map(|op| {
                let v: Lane = std::array::from_fn(|l| params[l][op.param]);
                let (s, c) = if op.rotation && op.joint.is_none() { sin_cos(&v) } else { (splat(0.0), splat(1.0)) };
                [v, s, c]
            })
            .collect();
        PreparedLanes { ops }
    }

    /// Tool (or flange) frames of one joint vector `q` (N) under the `LANES` parameter vectors
    /// of `pre`. Inputs are assumed validated.
    #[inline(always)]
    pub fn forward_param_lanes(&self, pre: &PreparedLanes, q: &[f64], tool: bool) -> Frames {
        let end = if tool { self.ops.len() } else { self.flange_end };
        let mut f = Frames::identity();
        for (op, [v, s, c]) in self.ops[..end].iter().zip(&pre.ops) {
            match op.joint {
                None => f.apply(op, v, s, c),
                Some(j) => {
                    let vl: Lane = std::array::from_fn(|l| v[l] + q[j]);
                    let (s, c) = if op.rotation { sin_cos(&vl) } else { (splat(0.0), splat(1.0)) };
                    f.apply(op, &vl, &s, &c);
                }
            }
        }
        f
    }

    /// Number of elementary ops (the length of the scratch buffer of `forward_with_jacobian`).
    pub fn n_ops(&self) -> usize {
        self.ops.len()
    }

    /// Tool frames of `L` samples and their derivatives with respect to every parameter:
    /// `dp[k]` (mm per unit of parameter k) of the tool origin and `dw[k]` (rad per unit) of its
    /// orientation (only when `orientation`), in the base (world) frame, for the parameters
    /// flagged in `wanted` (length `n_params`); the others, and parameters outside the chain
    /// (sensor block), keep whatever `dp`, `dw` held. `dp`, `dw` have length `n_params`; `axes`
    /// is scratch space of length `n_ops`.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub fn forward_with_jacobian<const L: usize>(
        &self,
        pre: &Prepared,
        q: &[Lane<L>],
        wanted: &[bool],
        orientation: bool,
        axes: &mut [(Vec3L<L>, Vec3L<L>)],
        dp: &mut [Vec3L<L>],
        dw: &mut [Vec3L<L>],
    ) -> Frames<L> {
        // An elementary rotation about world axis ω through o moves the end point by ω×(p−o);
        // a translation along world axis u moves it by u. Axes and origins are those of the
        // frame *before* the op, so they are recorded on the way out and used once p is known.
        let mut f = Frames::identity();
        for (k, op) in self.ops.iter().enumerate() {
            if wanted[op.param] {
                axes[k].0 = f.cols[op.axis];
                if op.rotation {
                    axes[k].1 = f.t;
                }
            }
            if pre.active[k] {
                self.apply_op(k, pre, q, &mut f);
            }
        }
        for (op, (w, o)) in self.ops.iter().zip(axes.iter()) {
            if !wanted[op.param] {
                continue;
            }
            if op.rotation {
                let mut d = [splat::<L>(0.0); 3];
                for r in 0..3 {
                    for l in 0..L {
                        d[r][l] = f.t[r][l] - o[r][l];
                    }
                }
                let out = &mut dp[op.param];
                for l in 0..L {
                    out[0][l] = w[1][l] * d[2][l] - w[2][l] * d[1][l];
                    out[1][l] = w[2][l] * d[0][l] - w[0][l] * d[2][l];
                    out[2][l] = w[0][l] * d[1][l] - w[1][l] * d[0][l];
                }
                if orientation {
                    dw[op.param] = *w;
                }
            } else {
                dp[op.param] = *w;
                if orientation {
                    dw[op.param] = [splat(0.0); 3];
                }
            }
        }
        f
    }

    /// Batched forward kinematics: `q` is (m, N) row-major; returns (m, 4, 4) row-major.
    ///
    /// Errors: `Shape`, `NonFinite`.
    pub fn fk_batch(&self, params: &[f64], q: &[f64], tool: bool) -> CoreResult<Vec<f64>> {
        let mut out = vec![0.0; q.len() / self.n_joints() * 16];
        self.fk_into(params, q, tool, &mut out)?;
        Ok(out)
    }

    /// [`Chain::fk_batch`] into a caller's buffer `out` ((m, 4, 4) row-major, every value
    /// written), so that the Python binding fills the NumPy array in place.
    ///
    /// Errors: `Shape` (also when `out` does not hold m·16 values), `NonFinite`.
    pub fn fk_into(&self, params: &[f64], q: &[f64], tool: bool, out: &mut [f64]) -> CoreResult<()> {
        let m = self.check_inputs(params, q)?;
        check_len("out", out.len(), m * 16)?;
        let n = self.n_joints();
        let pre = self.prepare(params);
        if m < SMALL_BATCH {
            for_each_group::<LANES, _, _, _>(
                out,
                16,
                || vec![splat::<LANES>(0.0); n],
                |first, count, rows, ql| self.fk_rows(&pre, q, tool, first, count, rows, ql),
            );
        } else {
            for_each_group::<BLOCK, _, _, _>(
                out,
                16,
                || vec![splat::<BLOCK>(0.0); n],
                #[inline(always)]
                |first, count, rows, ql| self.fk_rows(&pre, q, tool, first, count, rows, ql),
            );
        }
        Ok(())
    }

    /// The (4, 4) rows of samples `first .. first+count` of `q` into `rows`, `L` at a time
    /// (`ql`: scratch of N lanes).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub(crate) fn fk_rows<const L: usize>(
        &self,
        pre: &Prepared,
        q: &[f64],
        tool: bool,
        first: usize,
        count: usize,
        rows: &mut [f64],
        ql: &mut [Lane<L>],
    ) {
        gather_lanes(q, self.n_joints(), first, count, ql);
        let f = self.forward(pre, ql, tool);
        for (l, row) in rows.chunks_exact_mut(16).enumerate() {
            f.lane(l).write_homogeneous(row);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    fn hsr() -> (Chain, Vec<f64>) {
        let (chain, mut p) = crate::fixtures::hsr_jr680();
        let tool = chain.layout().tool();
        p[tool..tool + 6].fill(0.0);
        (chain, p)
    }

    fn single(chain: &Chain, p: &[f64], q: &[f64], tool: bool) -> Frame {
        let mut ql = vec![splat::<LANES>(0.0); q.len()];
        gather_lanes(q, q.len(), 0, 1, &mut ql);
        chain.forward(&chain.prepare(p), &ql, tool).lane(0)
    }

    /// The paper's eq. (1) link matrix, multiplied out directly.
    fn dh_matrix(alpha: f64, a: f64, d: f64, theta: f64) -> nalgebra::Matrix4<f64> {
        let (st, ct) = theta.sin_cos();
        let (sa, ca) = alpha.sin_cos();
        nalgebra::Matrix4::new(ct, -st * ca, st * sa, a * ct, st, ct * ca, -ct * sa, a * st, 0.0, sa, ca, d, 0.0, 0.0, 0.0, 1.0)
    }

    #[test]
    fn dh_chain_matches_eq1_product() {
        let (chain, p) = hsr();
        let q = [0.3, -0.2, 0.5, 1.1, -0.7, 2.0];
        let f = single(&chain, &p, &q, false);
        let mut expected = nalgebra::Matrix4::<f64>::identity();
        for (j, &qj) in q.iter().enumerate() {
            let (ia, ii, id, it, _) = chain.layout().joint(j);
            expected *= dh_matrix(p[ia], p[ii], p[id], p[it] + qj);
        }
        let mut got = [0.0; 16];
        f.write_homogeneous(&mut got);
        for r in 0..4 {
            for c in 0..4 {
                assert!((got[r * 4 + c] - expected[(r, c)]).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn jacobian_matches_central_differences() {
        let (chain, mut p) = hsr();
        let tool = chain.layout().tool();
        p[tool] = 12.0;
        p[tool + 1] = -30.0;
        p[tool + 2] = 95.0;
        p[tool + 4] = 0.2;
        let q = [0.1, -1.2, 0.4, 0.9, 0.5, -0.3];
        let n = p.len();
        let mut dpl = vec![[splat(0.0); 3]; n];
        let mut dwl = vec![[splat(0.0); 3]; n];
        let mut axes = vec![([splat(0.0); 3], [splat(0.0); 3]); chain.n_ops()];
        let mut ql = vec![splat::<LANES>(0.0); 6];
        gather_lanes(&q, 6, 0, 1, &mut ql);
        let f0 = chain.forward_with_jacobian(&chain.prepare(&p), &ql, &vec![true; n], true, &mut axes, &mut dpl, &mut dwl).lane(0);
        let dp: Vec<Vector3<f64>> = dpl.iter().map(|v| lane_vec(v, 0)).collect();
        let dw: Vec<Vector3<f64>> = dwl.iter().map(|v| lane_vec(v, 0)).collect();
        for k in 0..n {
            let h = 1e-6;
            let mut pp = p.clone();
            pp[k] += h;
            let fp = single(&chain, &pp, &q, true);
            pp[k] -= 2.0 * h;
            let fm = single(&chain, &pp, &q, true);
            let num = (fp.t - fm.t) / (2.0 * h);
            assert!((num - dp[k]).norm() < 1e-5 * (1.0 + dp[k].norm()), "param {k}");
            // Angular velocity from the rotation difference: skew(ω) ≈ (R+ − R−)/(2h)·R0ᵀ.
            let dr = (fp.rotation() - fm.rotation()) / (2.0 * h) * f0.rotation().transpose();
            let w = Vector3::new(dr[(2, 1)], dr[(0, 2)], dr[(1, 0)]);
            assert!((w - dw[k]).norm() < 1e-6, "param {k}: {w} vs {}", dw[k]);
        }
    }
}
