//! `L` samples evaluated in lockstep (structure of arrays), so that every elementary
//! transform is one loop across samples that the compiler vectorises, and a polynomial
//! sine/cosine that vectorises the same way (libm's `sin_cos` is a scalar call per angle).
//!
//! Three widths are used: `LANES` (4) where each sample carries much more state than its frame
//! (the sigma points of a filter update, the Jacobian of a batch below `SMALL_BATCH`), 16 for the
//! Jacobian of a larger batch (its per-parameter derivatives in L2, the frames in AVX2 registers:
//! `measurement::JACOBIAN_GROUP`), and `BLOCK` (64) for plain poses, where a block of frames (6 KiB) stays in L1 and each op is a
//! long vector loop: with 4 lanes the twelve frame values do not fit in the 16 SSE2 registers
//! and every op spills, and the per-op dispatch is paid every 4 samples instead of every 64.

use super::{Frame, Op};
use nalgebra::Vector3;

/// Samples per group where each sample carries a lot of state.
pub const LANES: usize = 4;
/// Samples per group for plain poses.
pub const BLOCK: usize = 64;
/// Batches smaller than this run in `LANES` groups: a block would be mostly padding (one pose:
/// 3.8 µs per Python `fk` call in a block, 1.6 µs in 4 lanes; 64 poses: 4.0 µs vs 7.3 µs).
pub const SMALL_BATCH: usize = 16;
/// One value per sample of a group.
pub type Lane<const L: usize = LANES> = [f64; L];
/// A 3-vector per sample: `v[row][lane]`.
pub type Vec3L<const L: usize = LANES> = [Lane<L>; 3];

#[inline(always)]
fn lanewise<const L: usize>(f: impl Fn(usize) -> f64) -> Lane<L> {
    std::array::from_fn(f)
}

#[inline(always)]
pub fn splat<const L: usize>(v: f64) -> Lane<L> {
    [v; L]
}

/// Angles beyond this go through libm (the two-term π/2 reduction below is exact to ~1e-16
/// relative only while `k·PIO2_1` stays exact).
const REDUCTION_LIMIT: f64 = 1.0e5;

/// Sine and cosine of every lane: Cody–Waite reduction to [−π/4, π/4] and fdlibm's kernel
/// polynomials (error ≲ 2 ulp for |x| < 1e5).
#[inline(always)]
#[allow(clippy::excessive_precision)] // fdlibm's k_sin.c / k_cos.c constants verbatim, to check against the source
pub fn sin_cos<const L: usize>(x: &Lane<L>) -> (Lane<L>, Lane<L>) {
    const PIO2_1: f64 = 1.570_796_326_734_125_614_17;
    const PIO2_1T: f64 = 6.077_100_506_506_192_249_32e-11;
    const S: [f64; 6] = [
        -1.666_666_666_666_663_243_48e-01,
        8.333_333_333_322_489_461_24e-03,
        -1.984_126_982_985_794_931_34e-04,
        2.755_731_370_707_006_767_89e-06,
        -2.505_076_025_340_686_341_95e-08,
        1.589_690_995_211_550_102_21e-10,
    ];
    const C: [f64; 6] = [
        4.166_666_666_666_660_190_37e-02,
        -1.388_888_888_887_410_957_49e-03,
        2.480_158_728_947_672_941_78e-05,
        -2.755_731_435_139_066_330_35e-07,
        2.087_572_321_298_174_827_90e-09,
        -1.135_964_755_778_819_482_65e-11,
    ];
    // Round-to-nearest by adding 1.5·2⁵² (exact for |x| < 2⁵¹), so no libm `round` call blocks
    // vectorisation; the low bits of the sum are k mod 4. Quadrant swaps and signs are bit
    // selects: (sin, cos) = (s, c), (c, −s), (−s, −c), (−c, s) for k mod 4 = 0, 1, 2, 3.
    // Each stage is its own loop over lanes so that the compiler vectorises it.
    const SHIFT: f64 = 6_755_399_441_055_744.0;
    let shifted = lanewise::<L>(|l| x[l] * std::f64::consts::FRAC_2_PI + SHIFT);
    let k = lanewise::<L>(|l| shifted[l] - SHIFT);
    let r = lanewise::<L>(|l| (x[l] - k[l] * PIO2_1) - k[l] * PIO2_1T);
    let z = lanewise::<L>(|l| r[l] * r[l]);
    let sr = lanewise::<L>(|l| r[l] + r[l] * z[l] * (S[0] + z[l] * (S[1] + z[l] * (S[2] + z[l] * (S[3] + z[l] * (S[4] + z[l] * S[5]))))));
    let cr = lanewise::<L>(|l| {
        1.0 - 0.5 * z[l] + z[l] * z[l] * (C[0] + z[l] * (C[1] + z[l] * (C[2] + z[l] * (C[3] + z[l] * (C[4] + z[l] * C[5])))))
    });
    let mut s = [0.0; L];
    let mut c = [0.0; L];
    for l in 0..L {
        let q = shifted[l].to_bits();
        let swap = 0u64.wrapping_sub(q & 1);
        let (sb, cb) = (sr[l].to_bits(), cr[l].to_bits());
        let a = (sb & !swap) | (cb & swap);
        let b = (cb & !swap) | (sb & swap);
        s[l] = f64::from_bits(a ^ (((q >> 1) & 1) << 63));
        c[l] = f64::from_bits(b ^ ((((q + 1) >> 1) & 1) << 63));
    }
    if x.iter().any(|v| v.abs() > REDUCTION_LIMIT) {
        for l in 0..L {
            if x[l].abs() > REDUCTION_LIMIT {
                (s[l], c[l]) = x[l].sin_cos();
            }
        }
    }
    (s, c)
}

/// A value given per lane or once for all lanes.
pub trait PerLane: Copy {
    fn at(self, l: usize) -> f64;
}

impl PerLane for f64 {
    #[inline(always)]
    fn at(self, _: usize) -> f64 {
        self
    }
}

impl<const L: usize> PerLane for &Lane<L> {
    #[inline(always)]
    fn at(self, l: usize) -> f64 {
        self[l]
    }
}

/// `L` rigid frames: rotation columns `cols[c][row][lane]` and origins `t[row][lane]`.
#[derive(Debug, Clone, Copy)]
pub struct Frames<const L: usize = LANES> {
    pub cols: [Vec3L<L>; 3],
    pub t: Vec3L<L>,
}

impl<const L: usize> Frames<L> {
    pub fn identity() -> Self {
        let mut cols = [[splat(0.0); 3]; 3];
        for (k, col) in cols.iter_mut().enumerate() {
            col[k] = splat(1.0);
        }
        Self { cols, t: [splat(0.0); 3] }
    }

    /// Post-multiplies every lane by the elementary transform `op`: a translation by `v`, a
    /// rotation with sines `s` and cosines `c` — per lane (`Lane`) or one value for all (`f64`,
    /// kept in a register instead of being spread over a lane array).
    #[inline(always)]
    pub fn apply<V: PerLane>(&mut self, op: &Op, v: V, s: V, c: V) {
        // R·R_k mixes the two other columns (i, j) = (k+1, k+2) mod 3; a translation adds column
        // k. Spelled out per axis so the indices are constants (a frame indexed at run time
        // cannot live in registers).
        match (op.rotation, op.axis) {
            (true, 0) => self.rotate::<1, 2, V>(s, c),
            (true, 1) => self.rotate::<2, 0, V>(s, c),
            (true, _) => self.rotate::<0, 1, V>(s, c),
            (false, 0) => self.translate::<0, V>(v),
            (false, 1) => self.translate::<1, V>(v),
            (false, _) => self.translate::<2, V>(v),
        }
    }

    #[inline(always)]
    fn translate<const K: usize, V: PerLane>(&mut self, v: V) {
        for r in 0..3 {
            for l in 0..L {
                self.t[r][l] += self.cols[K][r][l] * v.at(l);
            }
        }
    }

    #[inline(always)]
    fn rotate<const I: usize, const J: usize, V: PerLane>(&mut self, s: V, c: V) {
        for r in 0..3 {
            for l in 0..L {
                let (ci, cj) = (self.cols[I][r][l], self.cols[J][r][l]);
                self.cols[I][r][l] = ci * c.at(l) + cj * s.at(l);
                self.cols[J][r][l] = cj * c.at(l) - ci * s.at(l);
            }
        }
    }

    /// The frame of lane `l`.
    pub fn lane(&self, l: usize) -> Frame {
        let v = |a| lane_vec(a, l);
        Frame { cols: [v(&self.cols[0]), v(&self.cols[1]), v(&self.cols[2])], t: v(&self.t) }
    }
}

/// Lane `l` of a 3-vector.
#[inline(always)]
pub fn lane_vec<const L: usize>(a: &Vec3L<L>, l: usize) -> Vector3<f64> {
    Vector3::new(a[0][l], a[1][l], a[2][l])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sin_cos_matches_libm() {
        let mut worst: f64 = 0.0;
        for k in -200_000..200_000 {
            let x = [k as f64 * 1e-4, k as f64 * 0.37, -(k as f64) * 2.5e-3, k as f64 * 1e-9];
            let (s, c) = sin_cos(&x);
            for l in 0..LANES {
                let (es, ec) = x[l].sin_cos();
                worst = worst.max((s[l] - es).abs()).max((c[l] - ec).abs());
            }
        }
        assert!(worst < 4e-16, "worst absolute error {worst:e}");
        let huge = [1e6, -3e9, 1e300, 0.5];
        let (s, c) = sin_cos(&huge);
        for l in 0..3 {
            assert_eq!((s[l], c[l]), huge[l].sin_cos(), "lane {l}");
        }
    }
}
