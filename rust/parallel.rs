//! Data parallelism over samples (rayon). Every sample is computed independently and written to
//! its own rows, so results are bit-identical whatever the number of threads
//! (`RAYON_NUM_THREADS=1` gives the single-core figures of the benchmarks).

use rayon::prelude::*;

/// Samples per task (a multiple of every group size): large enough to amortise scheduling, small
/// enough to balance two cores.
const CHUNK: usize = 256;

/// Fills `out` — consecutive rows of `width` values, one row per sample — group by group:
/// `fill(first, count, rows, scratch)` computes samples `first .. first+count` (`count ≤ G`)
/// into `rows` (`count·width` values). Each parallel task makes its own scratch with `make`.
pub fn for_each_group<const G: usize, S, M, F>(out: &mut [f64], width: usize, make: M, fill: F)
where
    M: Fn() -> S + Sync,
    F: Fn(usize, usize, &mut [f64], &mut S) + Sync,
{
    if width == 0 {
        return;
    }
    // Wide groups (`BLOCK` plain poses) run 1.5x faster compiled for AVX2, chosen at run time
    // since a wheel targets baseline x86-64. Results are bit-identical: Rust never fuses a
    // multiply and an add (no FMA), and every operation is elementwise across lanes. 4-lane
    // groups measured 10 % slower with it, so they keep SSE2.
    #[cfg(target_arch = "x86_64")]
    let avx2 = G >= 16 && std::is_x86_feature_detected!("avx2");
    let run = |(c, chunk): (usize, &mut [f64])| {
        let mut scratch = make();
        #[cfg(target_arch = "x86_64")]
        if avx2 {
            // SAFETY: the CPU has AVX2 (checked at run time above).
            return unsafe { fill_chunk_avx2::<G, S, F>(c * CHUNK, chunk, width, &mut scratch, &fill) };
        }
        fill_chunk::<G, S, F>(c * CHUNK, chunk, width, &mut scratch, &fill)
    };
    // One chunk (a small batch, e.g. one sample of a filter update) runs on the calling thread:
    // handing it to the pool would cost more than the work.
    if out.len() <= CHUNK * width {
        run((0, out));
    } else {
        out.par_chunks_mut(CHUNK * width).enumerate().for_each(run);
    }
}

/// [`for_each_group`] filling two outputs at once: `fill(first, count, rows, extra, scratch)`
/// writes `count·width` values of `out` and `count·extra_width` of `extra` (both > 0 wide), so
/// that one pass over the samples yields two per-sample results (a Jacobian and its residuals).
/// Groups of `G` samples; wide groups (`G` ≥ 16) compiled for AVX2 where the CPU has it, as in
/// [`for_each_group`] (bit-identical results).
pub fn for_each_group_pair<const G: usize, S, M, F>(out: &mut [f64], width: usize, extra: &mut [f64], extra_width: usize, make: M, fill: F)
where
    M: Fn() -> S + Sync,
    F: Fn(usize, usize, &mut [f64], &mut [f64], &mut S) + Sync,
{
    #[cfg(target_arch = "x86_64")]
    let avx2 = G >= 16 && std::is_x86_feature_detected!("avx2");
    let run = |(c, (chunk, more)): (usize, (&mut [f64], &mut [f64]))| {
        // The chunk's rows of `extra` ride in the scratch: the groups are those of `for_each_group`.
        let first = c * CHUNK;
        let mut state = (make(), more);
        // Inlined into the AVX2 build with `fill` (stable Rust takes a closure's attribute in a call's arguments).
        let both = std::convert::identity(
            #[inline(always)]
            |g: usize, count: usize, rows: &mut [f64], state: &mut (S, &mut [f64])| {
                let at = (g - first) * extra_width;
                fill(g, count, rows, &mut state.1[at..at + count * extra_width], &mut state.0)
            },
        );
        #[cfg(target_arch = "x86_64")]
        if avx2 {
            // SAFETY: the CPU has AVX2 (checked at run time above).
            return unsafe { fill_chunk_avx2::<G, _, _>(first, chunk, width, &mut state, &both) };
        }
        fill_chunk::<G, _, _>(first, chunk, width, &mut state, &both)
    };
    if out.len() <= CHUNK * width {
        run((0, (out, extra)));
    } else {
        out.par_chunks_mut(CHUNK * width).zip(extra.par_chunks_mut(CHUNK * extra_width)).enumerate().for_each(run);
    }
}

/// Groups of one task's chunk, in order; the body of both builds below.
#[inline(always)]
pub(crate) fn fill_chunk<const G: usize, S, F>(first: usize, chunk: &mut [f64], width: usize, scratch: &mut S, fill: &F)
where
    F: Fn(usize, usize, &mut [f64], &mut S),
{
    let samples = chunk.len() / width;
    for g in (0..samples).step_by(G) {
        let count = G.min(samples - g);
        fill(first + g, count, &mut chunk[g * width..(g + count) * width], scratch);
    }
}

/// [`fill_chunk`] compiled for AVX2: `fill` must be `#[inline(always)]` to be compiled with it.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
pub(crate) unsafe fn fill_chunk_avx2<const G: usize, S, F>(first: usize, chunk: &mut [f64], width: usize, scratch: &mut S, fill: &F)
where
    F: Fn(usize, usize, &mut [f64], &mut S),
{
    fill_chunk::<G, S, F>(first, chunk, width, scratch, fill)
}
