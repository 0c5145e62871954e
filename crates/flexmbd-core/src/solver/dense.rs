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
    /// Row-major factors: L (unit lower, below the diagonal) and U.
    lu: Vec<f64>,
    /// The same factors column-major, for substitutions by column updates (which vectorize).
    columns: Vec<f64>,
    /// Row swapped with row k at step k.
    pivots: Vec<usize>,
    /// Scratch: the nonzero columns of the pivot row.
    nonzero: Vec<usize>,
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
            lu: vec![0.0; n * n],
            columns: vec![0.0; n * n],
            pivots: vec![0; n],
            nonzero: Vec::with_capacity(n),
            factorized: false,
            solves: 0,
            inverse: vec![0.0; n * n],
            has_inverse: false,
            scratch: vec![0.0; n],
        }
    }

    /// Factorizes the matrix with `values` on `pattern`.
    pub fn factorize(&mut self, pattern: &SparsePattern, values: &[f64]) -> std::result::Result<(), String> {
        let n = self.n;
        self.factorized = false;
        self.solves = 0;
        self.has_inverse = false;
        self.lu.iter_mut().for_each(|x| *x = 0.0);
        let mut scale = 0.0f64;
        for c in 0..n {
            for k in pattern.col_ptr[c]..pattern.col_ptr[c + 1] {
                let v = values[k];
                if !v.is_finite() {
                    return Err(format!("non-finite matrix entry at position {k}"));
                }
                self.lu[pattern.row_idx[k] * n + c] = v;
                scale = scale.max(v.abs());
            }
        }
        let tiny = 1e-300f64.max(1e-15 * scale);
        for k in 0..n {
            // Pivot: the largest entry of column k at or below the diagonal.
            let (mut p, mut best) = (k, self.lu[k * n + k].abs());
            for i in k + 1..n {
                let v = self.lu[i * n + k].abs();
                if v > best {
                    (p, best) = (i, v);
                }
            }
            if !(best > tiny) {
                return Err(format!("the matrix is singular (no pivot in column {k})"));
            }
            self.pivots[k] = p;
            if p != k {
                for j in 0..n {
                    self.lu.swap(k * n + j, p * n + j);
                }
            }
            let pivot = self.lu[k * n + k];
            let (upper, lower) = self.lu.split_at_mut((k + 1) * n);
            let row_k = &upper[k * n + k + 1..(k + 1) * n];
            // Multibody Newton matrices are sparse (a quarter of the entries of the slider-crank
            // with a modal rod, little fill): with a sparse pivot row, only its nonzero columns
            // are updated.
            let nonzero = &mut self.nonzero;
            nonzero.clear();
            nonzero.extend(row_k.iter().enumerate().filter(|(_, v)| **v != 0.0).map(|(j, _)| j));
            let sparse = 2 * nonzero.len() < row_k.len();
            for row in lower.chunks_exact_mut(n) {
                if row[k] == 0.0 {
                    continue;
                }
                let l = row[k] / pivot;
                row[k] = l;
                let rest = &mut row[k + 1..];
                if sparse {
                    for &j in nonzero.iter() {
                        rest[j] -= l * row_k[j];
                    }
                } else {
                    for (a, b) in rest.iter_mut().zip(row_k) {
                        *a -= l * b;
                    }
                }
            }
        }
        for (j, column) in self.columns.chunks_exact_mut(n).enumerate() {
            for (c, row) in column.iter_mut().zip(self.lu.chunks_exact(n)) {
                *c = row[j];
            }
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
        for k in 0..n {
            let xk = rhs[k];
            if xk != 0.0 {
                let column = &self.columns[k * n + k + 1..(k + 1) * n];
                for (x, l) in rhs[k + 1..n].iter_mut().zip(column) {
                    *x -= l * xk;
                }
            }
        }
        for k in (0..n).rev() {
            let column = &self.columns[k * n..k * n + k + 1];
            let xk = rhs[k] / column[k];
            rhs[k] = xk;
            if xk != 0.0 {
                for (x, u) in rhs[..k].iter_mut().zip(&column[..k]) {
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
    }
}
