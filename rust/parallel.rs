//! Data parallelism over samples (rayon). Every sample is computed independently and written to
//! its own rows, so results are bit-identical whatever the number of threads
//! (`RAYON_NUM_THREADS=1` gives the single-core figures of the benchmarks).

use crate::kinematics::LANES;
use rayon::prelude::*;

/// Samples per task (a multiple of `LANES`): large enough to amortise scheduling, small enough
/// to balance two cores.
const CHUNK: usize = 256;

/// Fills `out` — consecutive rows of `width` values, one row per sample — group by group:
/// `fill(first, count, rows, scratch)` computes samples `first .. first+count` (`count ≤ LANES`)
/// into `rows` (`count·width` values). Each parallel task makes its own scratch with `make`.
pub fn for_each_group<S, M, F>(out: &mut [f64], width: usize, make: M, fill: F)
where
    M: Fn() -> S + Sync,
    F: Fn(usize, usize, &mut [f64], &mut S) + Sync,
{
    if width == 0 {
        return;
    }
    let run = |(c, chunk): (usize, &mut [f64])| {
        let mut scratch = make();
        let samples = chunk.len() / width;
        for g in (0..samples).step_by(LANES) {
            let count = LANES.min(samples - g);
            fill(c * CHUNK + g, count, &mut chunk[g * width..(g + count) * width], &mut scratch);
        }
    };
    // One chunk (a small batch, e.g. one sample of a filter update) runs on the calling thread:
    // handing it to the pool would cost more than the work.
    if out.len() <= CHUNK * width {
        run((0, out));
    } else {
        out.par_chunks_mut(CHUNK * width).enumerate().for_each(run);
    }
}
