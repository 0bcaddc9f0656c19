//! Joint configurations: samples whose joint values agree within a tolerance on every joint
//! (Chebyshev distance, chained) form one configuration.
//!
//! A sweep along the joint with the widest range: after sorting by it, only the samples within
//! `tol` further along can be partners, so the work is `O(m log m + m·w)` with `w` the samples
//! per `tol`-wide window (a few for distinct configurations), and pairs are merged by
//! union-find. The labels are the chained components of the pairs `max_k |q_ik − q_jk| ≤ tol`
//! (a k-d tree's `query_pairs` with `p = inf`, then connected components, bit for bit),
//! numbered in order of first appearance. `robocal.data.splits.configuration_groups` keeps a
//! component only where it spans at most `tol` on every joint and cuts a wider one (a sweep in
//! steps under `tol`) into groups around representatives.

use crate::error::{check_finite, CoreError, CoreResult};

fn find(parent: &mut [usize], mut i: usize) -> usize {
    while parent[i] != i {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    i
}

/// One label per sample of `q` (m, n) row-major: `0..g-1` in order of first appearance;
/// samples within `tol` of each other on every joint (chained) share a label.
///
/// Errors: `Shape`, `NonFinite`, `InvalidParameter` (tol not finite or negative).
pub fn configuration_groups(q: &[f64], m: usize, n: usize, tol: f64) -> CoreResult<Vec<usize>> {
    if q.len() != m * n || (m > 0 && n == 0) {
        return Err(CoreError::Shape { arg: "q", expected: format!("({m}, {n}) with n >= 1"), got: format!("{} values", q.len()) });
    }
    check_finite("q", q)?;
    if !(tol.is_finite() && tol >= 0.0) {
        return Err(CoreError::InvalidParameter { arg: "tol", reason: format!("must be finite and >= 0; got {tol}") });
    }
    if m == 0 {
        return Ok(Vec::new());
    }
    let range = |c: usize| {
        let (lo, hi) = (0..m).fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), i| (lo.min(q[i * n + c]), hi.max(q[i * n + c])));
        hi - lo
    };
    let sweep = (0..n).max_by(|&a, &b| range(a).total_cmp(&range(b))).unwrap_or(0);
    // (value along the sweep, sample) pairs sorted by value: the sweep reads them in order.
    let mut order: Vec<(f64, usize)> = (0..m).map(|i| (q[i * n + sweep], i)).collect();
    order.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
    let mut parent: Vec<usize> = (0..m).collect();
    for (a, &(vi, i)) in order.iter().enumerate() {
        let qi = &q[i * n..(i + 1) * n];
        for &(vj, j) in &order[a + 1..] {
            if vj - vi > tol {
                break;
            }
            if qi.iter().zip(&q[j * n..(j + 1) * n]).all(|(x, y)| (x - y).abs() <= tol) {
                let (ri, rj) = (find(&mut parent, i), find(&mut parent, j));
                if ri != rj {
                    parent[ri.max(rj)] = ri.min(rj);
                }
            }
        }
    }
    let mut label = vec![usize::MAX; m];
    let mut next = 0;
    let mut out = Vec::with_capacity(m);
    for i in 0..m {
        let root = find(&mut parent, i);
        if label[root] == usize::MAX {
            label[root] = next;
            next += 1;
        }
        out.push(label[root]);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chains_revisits_and_numbers_by_first_appearance() {
        // 0 and 3 within tol; 3 and 4 within tol (so 0, 3, 4 chained); 1 alone; 2 and 5 equal.
        let q = [0.0, 0.0, 5.0, 5.0, 1.0, 1.0, 0.0009, 0.0, 0.0018, 0.0005, 1.0, 1.0];
        assert_eq!(configuration_groups(&q, 6, 2, 1e-3).unwrap(), vec![0, 1, 2, 0, 0, 2]);
        // The tolerance is inclusive on every joint, as a k-d tree's `query_pairs` with p = inf.
        assert_eq!(configuration_groups(&[0.0, 0.0, 0.5, 0.25], 2, 2, 0.5).unwrap(), vec![0, 0]);
        assert_eq!(configuration_groups(&[0.0, 0.0, 0.5, 0.75], 2, 2, 0.5).unwrap(), vec![0, 1]);
        assert_eq!(configuration_groups(&[], 0, 6, 1e-3).unwrap(), Vec::<usize>::new());
    }

    #[test]
    fn refuses_bad_input() {
        assert!(configuration_groups(&[0.0, f64::NAN], 1, 2, 1e-3).is_err());
        assert!(configuration_groups(&[0.0, 1.0], 1, 2, -1.0).is_err());
        assert!(configuration_groups(&[0.0, 1.0, 2.0], 2, 2, 1e-3).is_err());
    }
}
