//! The small kernels of the condensed solves: dot products of a vector with several kept
//! vectors, updates by combinations of them (four at a time, AVX2 where available), and the
//! dot product of a sparse coupling row.

use crate::linalg::simd::{dot4, update4, GROUP};

/// The dot products of `y` with the vectors `vector(0..count)`, four at a time.
pub(super) fn dots<'a, const N: usize>(
    count: usize,
    vector: impl Fn(usize) -> &'a [f64],
    y: &[f64],
) -> [f64; N] {
    let mut out = [0.0; N];
    for g in (0..count).step_by(GROUP) {
        let k = GROUP.min(count - g);
        let sums = dot4(std::array::from_fn(|i| vector(g + i.min(k - 1))), y);
        out[g..g + k].copy_from_slice(&sums[..k]);
    }
    out
}

/// out -= sum_v x[v] vector(v) over v < count, four vectors at a time.
pub(super) fn subtract_combination<'a>(
    out: &mut [f64],
    count: usize,
    vector: impl Fn(usize) -> &'a [f64],
    x: &[f64],
) {
    for g in (0..count).step_by(GROUP) {
        let k = GROUP.min(count - g);
        let coefficients = std::array::from_fn(|i| if i < k { x[g + i] } else { 0.0 });
        update4(out, coefficients, std::array::from_fn(|i| vector(g + i.min(k - 1))));
    }
}

/// sum_e values[e] x[f_e] over the entries (f_e, _) of a coupling row, with four partial sums
/// (a single sum is a chain of dependent additions, latency-bound on rows of n_f entries).
pub(super) fn gather_dot(entries: &[(usize, usize)], values: &[f64], x: &[f64]) -> f64 {
    let (e4, v4) = (entries.chunks_exact(4), values.chunks_exact(4));
    let tail: f64 = e4.remainder().iter().zip(v4.remainder()).map(|(&(f, _), v)| v * x[f]).sum();
    let mut acc = [0.0f64; 4];
    for (e, v) in e4.zip(v4) {
        for k in 0..4 {
            acc[k] += v[k] * x[e[k].0];
        }
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}
