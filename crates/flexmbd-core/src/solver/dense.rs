//! Dense LU factorization with partial pivoting for small Newton systems.
//!
//! For systems of a few dozen unknowns (a pendulum, a slider-crank with a reduced flexible
//! rod) the fixed costs of a sparse factorization and of its triangular solves dominate: a
//! dense LU of n = 30 takes n^3 / 3 = 9,000 multiply-adds, a solve n^2. Partial pivoting
//! handles the zero block of the saddle-point matrix [[S, C_q^T], [C_q, 0]], so no
//! regularization is needed. Models with at most [`DENSE_SYSTEM_SIZE`] unknowns use it.
//!
//! Modified Newton may solve with one factorization hundreds of times: once a factorization
//! has served `INVERSE_AFTER_SOLVES` solves, its explicit inverse (n substitutions) turns every
//! further solve into one matrix-vector product, which vectorizes where the short triangular
//! solves do not.

use super::sparse::SparsePattern;

/// Newton systems of at most this many unknowns are factorized densely.
pub const DENSE_SYSTEM_SIZE: usize = 64;

/// The inverse is formed at this many solves with one factorization (it costs n solves).
const INVERSE_AFTER_SOLVES: usize = 2 * DENSE_SYSTEM_SIZE;

/// LU = P A of a dense square matrix, with its storage kept between factorizations.
#[derive(Clone, Debug)]
pub struct DenseLu {
    n: usize,
    /// The factors column-major: L (unit lower, below the diagonal) and U; column j at
    /// `columns[j * n..(j + 1) * n]`.
    columns: Vec<f64>,
    /// Row swapped with row k at step k.
    pivots: Vec<usize>,
    /// Per column k, the rows of its nonzero entries: of L within k + 1..n (`lower`) and of U
    /// within 0..k (`upper`), as ranges (the substitutions skip the zeros outside: a quarter
    /// of the work of U for the slider-crank's matrix).
    lower: Vec<(usize, usize)>,
    upper: Vec<usize>,
    /// Row of the matrix at each row of the factors (P), and its inverse.
    rows: Vec<usize>,
    positions: Vec<usize>,
    factorized: bool,
    /// Solves made with the current factorization.
    solves: usize,
    /// The inverse, row-major (formed at the second solve of a factorization).
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
    /// column j of the matrix, in the row order of the pivots so far, is updated by the
    /// columns k < j of L whose entry U(k, j) is nonzero, then pivoted and scaled. Every
    /// operation runs along a contiguous column, and the zeros of a sparse Newton matrix
    /// (three quarters of the entries of the slider-crank with a modal rod, with little fill)
    /// skip their updates.
    pub fn factorize(&mut self, pattern: &SparsePattern, values: &[f64]) -> std::result::Result<(), String> {
        let n = self.n;
        self.factorized = false;
        self.solves = 0;
        self.has_inverse = false;
        self.rows.clear();
        self.rows.extend(0..n);
        self.positions.clear();
        self.positions.extend(0..n);
        let scale = largest_magnitude(values)
            .ok_or_else(|| format!("non-finite matrix entry at position {}", non_finite(values)))?;
        let tiny = 1e-300f64.max(1e-15 * scale);
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
            if !(best > tiny) {
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
        for (k, column) in self.columns.chunks_exact(n).enumerate() {
            let below = &column[k + 1..];
            self.lower[k] = match below.iter().position(|v| *v != 0.0) {
                Some(first) => {
                    (k + 1 + first, k + 2 + below.iter().rposition(|v| *v != 0.0).unwrap_or(first))
                }
                None => (k + 1, k + 1),
            };
            self.upper[k] = column[..k].iter().position(|v| *v != 0.0).unwrap_or(k);
        }
        self.factorized = true;
        Ok(())
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

    /// Forward and back substitution with the factors, by column updates.
    fn substitute(&self, rhs: &mut [f64]) {
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
    use crate::solver::sparse::{PatternBuilder, SparseLu, SparsePattern};

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
        for k in 0..n {
            assert!((x[k] - expected[k]).abs() < 1e-11 * scale, "{k}: {} vs {}", x[k], expected[k]);
        }
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
            for k in 0..n {
                assert!((x[k] - expected[k]).abs() < 1e-12, "{k}: {} vs {}", x[k], expected[k]);
            }
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
