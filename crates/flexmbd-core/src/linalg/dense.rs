//! Dense LU factorization with partial pivoting for small Newton systems.
//!
//! For systems of a few dozen unknowns (a pendulum, a slider-crank with a reduced flexible
//! rod) the fixed costs of a sparse factorization and of its triangular solves dominate: a
//! dense LU of n = 30 takes n^3 / 3 = 9,000 multiply-adds, a solve n^2. Partial pivoting
//! handles the zero block of the saddle-point matrix [[S, C_q^T], [C_q, 0]], so no
//! regularization is needed. Models with at most [`DENSE_SYSTEM_SIZE`] unknowns use it.
//!
//! The Newton matrices of one model share a pattern and change little from one refresh to the
//! next: after a factorization with pivot search, the next ones reuse its pivots and nonzero
//! structure (bit masks of rows, n <= 64) while each kept pivot is at least a tenth of the
//! largest entry below it (threshold partial pivoting). On the slider-crank's 47 x 47 matrix a
//! refactorization takes 5.0 us against 6.9 us with the search.
//!
//! Modified Newton may solve with one factorization hundreds of times: once a factorization
//! has served `INVERSE_AFTER_SOLVES` solves, its explicit inverse (n substitutions) turns every
//! further solve into one matrix-vector product, which vectorizes where the short triangular
//! solves do not. The substitutions and refactorizations are compiled a second time for AVX2
//! (vectors of four, the same results), taken where the CPU has it.

use crate::linalg::sparse::SparsePattern;

/// Newton systems of at most this many unknowns are factorized densely.
pub const DENSE_SYSTEM_SIZE: usize = 64;

/// The inverse is formed at this many solves with one factorization (it costs n solves).
const INVERSE_AFTER_SOLVES: usize = 2 * DENSE_SYSTEM_SIZE;

/// A refactorization keeps a pivot at least this fraction of the largest entry below it
/// (threshold partial pivoting), else the matrix is factorized with a new pivot search.
const PIVOT_THRESHOLD: f64 = 0.1;

/// A pivot below this fraction of the largest entry of its column of the matrix makes the
/// matrix singular.
const SINGULAR_PIVOT: f64 = 1e-15;

/// The zero-pivot limit of column `j`: `relative` times its largest entry (at least 1e-300).
#[inline(always)]
fn column_limit(pattern: &SparsePattern, values: &[f64], j: usize, relative: f64) -> f64 {
    let largest =
        values[pattern.col_ptr[j]..pattern.col_ptr[j + 1]].iter().fold(0.0f64, |m, v| m.max(v.abs()));
    1e-300f64.max(relative * largest)
}

/// Nonzero structure of a factorization, per column as bit masks of (permuted) rows.
#[derive(Clone, Debug)]
struct Structure {
    /// Entries of the pattern.
    matrix: Vec<u64>,
    /// Of L, below the diagonal.
    lower: Vec<u64>,
    /// Of U, above the diagonal.
    upper: Vec<u64>,
}

/// LU = P A of a dense square matrix, with its storage kept between factorizations.
#[derive(Clone, Debug)]
pub struct DenseLu {
    n: usize,
    /// The factors column-major: L (unit lower, below the diagonal) and U; column j at
    /// `columns[j * n..(j + 1) * n]`.
    columns: Vec<f64>,
    /// Row swapped with row k at step k.
    pivots: Vec<usize>,
    /// Per column k, the span of rows of its structurally nonzero entries: of L within
    /// k + 1..n (`lower`) and of U within 0..k (`upper`, from its start to k); the
    /// substitutions skip the zeros outside (a quarter of the work of U for the
    /// slider-crank's matrix).
    lower: Vec<(usize, usize)>,
    upper: Vec<usize>,
    /// The nonzero structure of the last factorization with pivot search, kept to refactorize
    /// the next matrices of the same pattern with the same pivots (None for n > 64).
    structure: Option<Structure>,
    /// Factorizations with pivot search made (the others were refactorizations).
    pivot_searches: usize,
    /// Row of the matrix at each row of the factors (P), and its inverse.
    rows: Vec<usize>,
    positions: Vec<usize>,
    factorized: bool,
    /// Solves made with the current factorization.
    solves: usize,
    /// The inverse, row-major (formed at the `INVERSE_AFTER_SOLVES`-th solve of a
    /// factorization).
    inverse: Vec<f64>,
    has_inverse: bool,
    /// Scratch vector (n).
    scratch: Vec<f64>,
}

impl DenseLu {
    /// Storage for an `n x n` matrix.
    pub fn new(n: usize) -> Self {
        DenseLu {
            n,
            columns: vec![0.0; n * n],
            pivots: vec![0; n],
            lower: vec![(0, 0); n],
            upper: vec![0; n],
            structure: None,
            pivot_searches: 0,
            rows: Vec::with_capacity(n),
            positions: Vec::with_capacity(n),
            factorized: false,
            solves: 0,
            inverse: vec![0.0; n * n],
            has_inverse: false,
            scratch: vec![0.0; n],
        }
    }

    /// Factorizes the matrix with `values` on `pattern`, column by column (left-looking):
    /// column j of the matrix, in the row order of the pivots, is updated by the columns k < j
    /// of L whose entry U(k, j) is nonzero, then pivoted and scaled; every operation runs
    /// along a contiguous column.
    ///
    /// A matrix of the pattern of the last factorization is first refactorized with its pivots
    /// and nonzero structure (no pivot search, only the updates the structure has): Newton
    /// matrices of one model change little between refreshes, so the pivots of the last
    /// search stay good. A pivot smaller than `PIVOT_THRESHOLD` times the largest entry below
    /// it (or a pattern entry outside the structure) sends the matrix to a new factorization
    /// with pivot search.
    pub fn factorize(&mut self, pattern: &SparsePattern, values: &[f64]) -> std::result::Result<(), String> {
        self.factorized = false;
        self.solves = 0;
        self.has_inverse = false;
        largest_magnitude(values)
            .ok_or_else(|| format!("non-finite matrix entry at position {}", non_finite(values)))?;
        // A pivot counts as zero below `SINGULAR_PIVOT` times the largest entry of its own
        // column of the matrix, not of the whole matrix: the multipliers' pivots of a heavy
        // body (C M^-1 C^T, 5e-8 for the Euler parameters' normalization of a 200 t body of
        // inertia 2e7 kg m^2) were under 1e-15 times its mass matrix's 8e7.
        let tiny = SINGULAR_PIVOT;
        if !self.refactorize(pattern, values, tiny) {
            self.factorize_pivoting(pattern, values, tiny)?;
            self.analyze(pattern);
        }
        self.factorized = true;
        Ok(())
    }

    /// The factorization with partial pivoting (the largest entry of each column).
    fn factorize_pivoting(
        &mut self,
        pattern: &SparsePattern,
        values: &[f64],
        tiny: f64,
    ) -> std::result::Result<(), String> {
        let n = self.n;
        self.structure = None;
        self.pivot_searches += 1;
        self.rows.clear();
        self.rows.extend(0..n);
        self.positions.clear();
        self.positions.extend(0..n);
        for j in 0..n {
            let (done, rest) = self.columns.split_at_mut(j * n);
            let x = &mut rest[..n];
            x.iter_mut().for_each(|v| *v = 0.0);
            for k in pattern.col_ptr[j]..pattern.col_ptr[j + 1] {
                x[self.positions[pattern.row_idx[k]]] = values[k];
            }
            for (k, l) in done.chunks_exact(n).enumerate() {
                let u = x[k];
                if u != 0.0 {
                    for (xi, li) in x[k + 1..].iter_mut().zip(&l[k + 1..]) {
                        *xi -= u * li;
                    }
                }
            }
            // Pivot: the largest entry at or below the diagonal.
            let (mut p, mut best) = (j, x[j].abs());
            for (i, v) in x.iter().enumerate().skip(j + 1) {
                if v.abs() > best {
                    (p, best) = (i, v.abs());
                }
            }
            if !(best > column_limit(pattern, values, j, tiny)) {
                return Err(format!("the matrix is singular (no pivot in column {j})"));
            }
            self.pivots[j] = p;
            if p != j {
                x.swap(j, p);
                for l in done.chunks_exact_mut(n) {
                    l.swap(j, p);
                }
                self.rows.swap(j, p);
                self.positions[self.rows[j]] = j;
                self.positions[self.rows[p]] = p;
            }
            let inverse_pivot = 1.0 / x[j];
            x[j + 1..].iter_mut().for_each(|v| *v *= inverse_pivot);
        }
        Ok(())
    }

    /// The nonzero structure of L and U for the pattern with the pivots just chosen (every
    /// pattern entry taken as nonzero: a superset of the numeric nonzeros of any matrix of
    /// the pattern), as bit masks of rows, and the spans of the substitutions from it.
    fn analyze(&mut self, pattern: &SparsePattern) {
        let n = self.n;
        if n > 64 {
            for k in 0..n {
                self.lower[k] = (k + 1, n);
                self.upper[k] = 0;
            }
            return;
        }
        let mut st = Structure { matrix: vec![0; n], lower: vec![0; n], upper: vec![0; n] };
        for j in 0..n {
            let a = (pattern.col_ptr[j]..pattern.col_ptr[j + 1])
                .fold(0u64, |m, k| m | 1 << self.positions[pattern.row_idx[k]]);
            let mut x = a | 1 << j;
            for k in 0..j {
                if x >> k & 1 == 1 {
                    x |= st.lower[k];
                }
            }
            let through_j = if j == 63 { u64::MAX } else { (1u64 << (j + 1)) - 1 };
            st.matrix[j] = a;
            st.upper[j] = x & ((1u64 << j) - 1);
            st.lower[j] = x & !through_j;
        }
        for k in 0..n {
            let l = st.lower[k];
            self.lower[k] = if l == 0 {
                (k + 1, k + 1)
            } else {
                (l.trailing_zeros() as usize, 64 - l.leading_zeros() as usize)
            };
            self.upper[k] = if st.upper[k] == 0 { k } else { st.upper[k].trailing_zeros() as usize };
        }
        self.structure = Some(st);
    }

    /// Refactorizes with the pivots and structure of the last factorization with pivot
    /// search; false (and no usable factorization) if there is none, if the pattern has an
    /// entry outside the structure, or if a pivot is too small.
    fn refactorize(&mut self, pattern: &SparsePattern, values: &[f64], tiny: f64) -> bool {
        #[cfg(target_arch = "x86_64")]
        if crate::linalg::simd::has_avx2_fma() {
            // SAFETY: the CPU supports AVX2 (checked above).
            return unsafe { self.refactorize_avx2(pattern, values, tiny) };
        }
        self.refactorize_portable(pattern, values, tiny)
    }

    /// [`Self::refactorize`] compiled for AVX2 (the same operations in vectors of four).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn refactorize_avx2(&mut self, pattern: &SparsePattern, values: &[f64], tiny: f64) -> bool {
        self.refactorize_portable(pattern, values, tiny)
    }

    #[inline(always)]
    fn refactorize_portable(&mut self, pattern: &SparsePattern, values: &[f64], tiny: f64) -> bool {
        let n = self.n;
        let Some(st) = &self.structure else { return false };
        for j in 0..n {
            let (done, rest) = self.columns.split_at_mut(j * n);
            let x = &mut rest[..n];
            x.iter_mut().for_each(|v| *v = 0.0);
            let mut a = 0u64;
            for k in pattern.col_ptr[j]..pattern.col_ptr[j + 1] {
                let r = self.positions[pattern.row_idx[k]];
                a |= 1 << r;
                x[r] = values[k];
            }
            if a & !st.matrix[j] != 0 {
                return false;
            }
            let mut bits = st.upper[j];
            while bits != 0 {
                let k = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let u = x[k];
                if u != 0.0 {
                    let (start, end) = self.lower[k];
                    for (xi, li) in x[start..end].iter_mut().zip(&done[k * n + start..k * n + end]) {
                        *xi -= u * li;
                    }
                }
            }
            let pivot = x[j].abs();
            let below = x[j + 1..].iter().fold(0.0f64, |m, v| if v.abs() > m { v.abs() } else { m });
            if !(pivot > column_limit(pattern, values, j, tiny) && pivot >= PIVOT_THRESHOLD * below) {
                return false;
            }
            let inverse_pivot = 1.0 / x[j];
            x[j + 1..].iter_mut().for_each(|v| *v *= inverse_pivot);
        }
        true
    }

    /// Solves `A x = rhs` in place with the last factorization.
    pub fn solve_in_place(&mut self, rhs: &mut [f64]) -> std::result::Result<(), String> {
        if !self.factorized {
            return Err("no valid factorization".to_string());
        }
        self.solves += 1;
        if self.solves == INVERSE_AFTER_SOLVES {
            self.form_inverse();
        }
        if self.has_inverse {
            let n = self.n;
            self.scratch.copy_from_slice(&rhs[..n]);
            for (x, row) in rhs.iter_mut().zip(self.inverse.chunks_exact(n)) {
                *x = row.iter().zip(&self.scratch).map(|(a, b)| a * b).sum();
            }
        } else {
            self.substitute(rhs);
        }
        if rhs.iter().all(|v| v.is_finite()) {
            Ok(())
        } else {
            Err("the matrix is singular (the solution is not finite)".to_string())
        }
    }

    /// Forward and back substitution with the factors, by column updates (compiled for AVX2
    /// where the CPU has it: the updates then run in vectors of four, with the same
    /// operations, so the results are the same bit for bit).
    fn substitute(&self, rhs: &mut [f64]) {
        #[cfg(target_arch = "x86_64")]
        if crate::linalg::simd::has_avx2_fma() {
            // SAFETY: the CPU supports AVX2 (checked above).
            return unsafe { self.substitute_avx2(rhs) };
        }
        self.substitute_portable(rhs);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn substitute_avx2(&self, rhs: &mut [f64]) {
        self.substitute_portable(rhs);
    }

    #[inline(always)]
    fn substitute_portable(&self, rhs: &mut [f64]) {
        let n = self.n;
        for k in 0..n {
            rhs.swap(k, self.pivots[k]);
        }
        for (k, column) in self.columns.chunks_exact(n).enumerate() {
            let xk = rhs[k];
            let (start, end) = self.lower[k];
            if xk != 0.0 {
                for (x, l) in rhs[start..end].iter_mut().zip(&column[start..end]) {
                    *x -= l * xk;
                }
            }
        }
        for (k, column) in self.columns.chunks_exact(n).enumerate().rev() {
            let xk = rhs[k] / column[k];
            rhs[k] = xk;
            let start = self.upper[k];
            if xk != 0.0 {
                for (x, u) in rhs[start..k].iter_mut().zip(&column[start..k]) {
                    *x -= u * xk;
                }
            }
        }
    }

    /// The inverse, column by column from unit vectors, stored row-major.
    fn form_inverse(&mut self) {
        let n = self.n;
        let mut column = vec![0.0; n];
        for j in 0..n {
            column.iter_mut().for_each(|x| *x = 0.0);
            column[j] = 1.0;
            self.substitute(&mut column);
            for i in 0..n {
                self.inverse[i * n + j] = column[i];
            }
        }
        self.has_inverse = true;
    }
}

/// The largest |v| of finite `values`, or None if one is not finite. In four lanes without
/// NaN handling (v * 0 is NaN exactly for a non-finite v): a sequential f64::max is a chain
/// of dependent, NaN-aware maxima, a fifth of a factorization of the slider-crank's matrix.
fn largest_magnitude(values: &[f64]) -> Option<f64> {
    let (mut largest, mut probe) = ([0.0f64; 4], [0.0f64; 4]);
    let chunks = values.chunks_exact(4);
    let rest = chunks.remainder();
    for chunk in chunks {
        for i in 0..4 {
            let a = chunk[i].abs();
            largest[i] = if a > largest[i] { a } else { largest[i] };
            probe[i] += chunk[i] * 0.0;
        }
    }
    for &v in rest {
        largest[0] = if v.abs() > largest[0] { v.abs() } else { largest[0] };
        probe[0] += v * 0.0;
    }
    let finite = probe.iter().sum::<f64>() == 0.0;
    finite.then(|| largest.iter().fold(0.0f64, |m, &v| if v > m { v } else { m }))
}

/// Position of the first non-finite value.
fn non_finite(values: &[f64]) -> usize {
    values.iter().position(|v| !v.is_finite()).unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::sparse::{PatternBuilder, SparseLu, SparsePattern};
    use crate::testing::assert_all_close;

    /// The sparse LU solution of the system (pattern `p`, `values`) for `rhs`, and the dense
    /// LU factorization of the same matrix.
    fn sparse_solve_and_dense_factor(p: &SparsePattern, values: &[f64], rhs: &[f64]) -> (Vec<f64>, DenseLu) {
        let mut expected = rhs.to_vec();
        let mut sparse = SparseLu::new(p).unwrap();
        sparse.factorize(values).unwrap();
        sparse.solve_in_place(&mut expected).unwrap();
        let mut dense = DenseLu::new(p.n);
        dense.factorize(p, values).unwrap();
        (expected, dense)
    }

    #[test]
    fn dense_lu_of_a_sparse_saddle_point_system_with_pivoting_solves_like_the_sparse_lu() {
        // 40 coordinates with a sparse coupling pattern and 12 constraint rows, numbered first
        // (zero diagonal block: rows are swapped), so that both the sparse and the dense row
        // updates run.
        let (nq, nc) = (40, 12);
        let n = nq + nc;
        let mut seed = 5u64;
        let mut next = move || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((seed >> 11) as f64) / ((1u64 << 53) as f64)
        };
        let mut entries = Vec::new();
        for i in nc..n {
            entries.push((i, i, 5.0 + next()));
            for j in nc..n {
                if i != j && next() < 0.12 {
                    entries.push((i, j, next() - 0.5));
                }
            }
        }
        for c in 0..nc {
            for j in nc..n {
                if next() < 0.2 || j == nc + 3 * c {
                    let v = next() + 0.5;
                    entries.push((c, j, v));
                    entries.push((j, c, v));
                }
            }
        }
        let mut b = PatternBuilder::new(n);
        for &(r, c, _) in &entries {
            b.add_entry(r, c);
        }
        let p = b.build();
        let mut values = vec![0.0; p.nnz()];
        for &(r, c, v) in &entries {
            values[p.index(r, c)] = v;
        }
        let rhs: Vec<f64> = (0..n).map(|k| (k as f64 * 0.37).cos()).collect();
        let (expected, mut dense) = sparse_solve_and_dense_factor(&p, &values, &rhs);
        assert!((0..n).any(|k| dense.pivots[k] != k), "no row was swapped");
        let mut x = rhs.clone();
        dense.solve_in_place(&mut x).unwrap();
        let scale = expected.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert_all_close(&x, &expected, 0.0, 1e-11 * scale, "dense against sparse solution");
        // The matrix changed by up to 2 %: refactorized with the pivots of the first
        // factorization (no new search), and solved as accurately.
        let changed: Vec<f64> = values.iter().map(|v| v * (1.0 + 0.02 * (next() - 0.5))).collect();
        let (_, mut portable) = sparse_solve_and_dense_factor(&p, &values, &rhs);
        dense.factorize(&p, &changed).unwrap();
        assert_eq!(dense.pivot_searches, 1);
        let mut x = rhs.clone();
        dense.solve_in_place(&mut x).unwrap();
        let (expected, _) = sparse_solve_and_dense_factor(&p, &changed, &rhs);
        let scale = expected.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert_all_close(&x, &expected, 0.0, 1e-11 * scale, "refactorized against sparse solution");
        // The portable refactorization and substitution (the ones above ran compiled for AVX2
        // where the CPU has it) give the same solution, bit for bit.
        assert!(portable.refactorize_portable(&p, &changed, 1e-300));
        let mut y = rhs.clone();
        portable.substitute_portable(&mut y);
        assert_eq!(x, y);
    }

    /// The solution of the dense factorization of `values` (full pattern `p`) for `rhs`,
    /// checked against the matrix, and the pivot searches made so far.
    fn solve_checked(dense: &mut DenseLu, p: &SparsePattern, values: &[f64], rhs: &[f64]) -> usize {
        dense.factorize(p, values).unwrap();
        let mut x = rhs.to_vec();
        dense.solve_in_place(&mut x).unwrap();
        let mut ax = vec![0.0; p.n];
        for c in 0..p.n {
            for k in p.col_ptr[c]..p.col_ptr[c + 1] {
                ax[p.row_idx[k]] += values[k] * x[c];
            }
        }
        assert_all_close(&ax, rhs, 0.0, 1e-13, "A x against rhs");
        dense.pivot_searches
    }

    #[test]
    fn refactorization_keeps_pivots_above_the_threshold_and_searches_again_below_it() {
        let mut b = PatternBuilder::new(2);
        b.add_block(&[0, 1], &[0, 1]);
        let p = b.build();
        let matrix = |a: [[f64; 2]; 2]| {
            let mut values = vec![0.0; p.nnz()];
            for r in 0..2 {
                for c in 0..2 {
                    values[p.index(r, c)] = a[r][c];
                }
            }
            values
        };
        let mut dense = DenseLu::new(2);
        let rhs = [1.0, -2.0];
        // Column 0 pivots on row 1 (3 > 1).
        assert_eq!(solve_checked(&mut dense, &p, &matrix([[1.0, 2.0], [3.0, 4.0]]), &rhs), 1);
        // 0.5 >= 0.1 * 1: the pivot is kept.
        assert_eq!(solve_checked(&mut dense, &p, &matrix([[1.0, 2.0], [0.5, 4.0]]), &rhs), 1);
        // 0.01 < 0.1 * 1: a new search (which pivots on row 0), then an exact zero there.
        assert_eq!(solve_checked(&mut dense, &p, &matrix([[1.0, 2.0], [0.01, 4.0]]), &rhs), 2);
        assert_eq!(solve_checked(&mut dense, &p, &matrix([[0.0, 2.0], [3.0, 4.0]]), &rhs), 3);
        // A diagonal pattern (a new search: the kept pivot of column 0 would be its zero), then
        // the full one again, with entries outside the diagonal's structure: a new search.
        let mut b = PatternBuilder::new(2);
        b.add_entry(0, 0);
        b.add_entry(1, 1);
        let diagonal = b.build();
        let values = vec![2.0, 5.0];
        assert_eq!(solve_checked(&mut dense, &diagonal, &values, &rhs), 4);
        assert_eq!(solve_checked(&mut dense, &p, &matrix([[1.0, 2.0], [3.0, 4.0]]), &rhs), 5);
    }

    #[test]
    fn dense_lu_solves_a_saddle_point_system_like_the_sparse_lu() {
        // [[S, C^T], [C, 0]] with an unsymmetric S: the zero block needs pivoting.
        let n = 7;
        let mut b = PatternBuilder::new(n);
        let q: Vec<usize> = (0..5).collect();
        b.add_block(&q, &q);
        b.add_block(&[5, 6], &q);
        b.add_block(&q, &[5, 6]);
        let p = b.build();
        let mut values = vec![0.0; p.nnz()];
        let mut set = |r: usize, c: usize, v: f64| values[p.index(r, c)] = v;
        for i in 0..5 {
            for j in 0..5 {
                set(i, j, if i == j { 4.0 + i as f64 } else { 0.3 * (i as f64 - 2.0 * j as f64) / 7.0 });
            }
            set(5, i, 1.0 + i as f64);
            set(i, 5, 1.0 + i as f64);
            set(6, i, (i as f64 - 1.5).powi(2));
            set(i, 6, (i as f64 - 1.5).powi(2));
        }
        let rhs: Vec<f64> = (0..n).map(|k| (k as f64 * 0.7).sin()).collect();
        let (expected, mut dense) = sparse_solve_and_dense_factor(&p, &values, &rhs);
        // The first solve by substitution, the next ones with the inverse.
        for _ in 0..3 {
            let mut x = rhs.clone();
            dense.solve_in_place(&mut x).unwrap();
            assert_all_close(&x, &expected, 0.0, 1e-12, "dense against sparse solution");
        }
        // A singular matrix is reported, not solved.
        let zeros = vec![0.0; p.nnz()];
        assert!(dense.factorize(&p, &zeros).is_err());
        // A non-finite entry is reported with its position, wherever it is (in the four lanes
        // of the scan for the largest entry, or in their remainder).
        for position in [0, 5, values.len() - 1] {
            for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                let mut broken = values.clone();
                broken[position] = bad;
                let message = dense.factorize(&p, &broken).unwrap_err();
                assert!(message.contains(&format!("position {position}")), "{message}");
            }
        }
        assert_eq!(largest_magnitude(&[1.0, -7.5, 2.0, 0.0, 3.0, -8.0]), Some(8.0));
    }
}
