//! Sparse matrices with a pattern fixed when the model is compiled, and their LU factorization.
//!
//! Every element (body, joint, force) registers the dense blocks it writes; the compressed
//! column pattern is built once, each element keeps the value indices of its blocks, and
//! assembly is a scatter into a preallocated value array. The symbolic factorization (COLAMD
//! ordering, supernodal structure) is computed once per pattern; each Newton iteration only
//! refactorizes numerically, into reused storage (house style 7: faer's symbolic/numeric split).

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::lu::partial_pivoting::factor::PartialPivLuParams;
use faer::sparse::linalg::lu::{factorize_symbolic_lu, LuRef, LuSymbolicParams, NumericLu, SymbolicLu};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Spec};

/// Error unless every entry of a solution is finite (a singular matrix otherwise).
fn finite_solution(x: &[f64]) -> std::result::Result<(), String> {
    if x.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err("the matrix is singular (the solution is not finite)".to_string())
    }
}

/// Collects the dense blocks of a square sparse matrix before its pattern is frozen.
#[derive(Debug, Default)]
pub struct PatternBuilder {
    n: usize,
    entries: Vec<(usize, usize)>,
}

impl PatternBuilder {
    /// A builder for an `n x n` matrix.
    pub fn new(n: usize) -> Self {
        PatternBuilder { n, entries: Vec::new() }
    }

    /// Registers the dense block `rows x cols` (global indices).
    pub fn add_block(&mut self, rows: &[usize], cols: &[usize]) {
        for &c in cols {
            for &r in rows {
                self.entries.push((c, r));
            }
        }
    }

    /// Registers the entry (row, col).
    pub fn add_entry(&mut self, row: usize, col: usize) {
        self.entries.push((col, row));
    }

    /// Registers the diagonal entries `indices`.
    pub fn add_diagonal(&mut self, indices: &[usize]) {
        for &i in indices {
            self.entries.push((i, i));
        }
    }

    /// Freezes the pattern (compressed sparse columns, sorted row indices).
    pub fn build(mut self) -> SparsePattern {
        self.entries.sort_unstable();
        self.entries.dedup();
        let mut col_ptr = vec![0usize; self.n + 1];
        let mut row_idx = Vec::with_capacity(self.entries.len());
        for &(c, r) in &self.entries {
            col_ptr[c + 1] += 1;
            row_idx.push(r);
        }
        for c in 0..self.n {
            col_ptr[c + 1] += col_ptr[c];
        }
        SparsePattern { n: self.n, col_ptr, row_idx }
    }
}

/// Compressed sparse column pattern of a square matrix.
#[derive(Clone, Debug)]
pub struct SparsePattern {
    /// Dimension.
    pub n: usize,
    /// Column pointers (n + 1).
    pub col_ptr: Vec<usize>,
    /// Row indices, sorted within each column.
    pub row_idx: Vec<usize>,
}

impl SparsePattern {
    /// Number of stored entries.
    pub fn nnz(&self) -> usize {
        self.row_idx.len()
    }

    /// Position of entry (row, col) in the value array; the entry must have been registered.
    pub fn index(&self, row: usize, col: usize) -> usize {
        let start = self.col_ptr[col];
        let rows = &self.row_idx[start..self.col_ptr[col + 1]];
        match rows.binary_search(&row) {
            Ok(k) => start + k,
            Err(_) => panic!("entry ({row}, {col}) is not in the sparse pattern"),
        }
    }

    /// Value indices of the dense block `rows x cols`, row-major.
    pub fn block_indices(&self, rows: &[usize], cols: &[usize]) -> Vec<usize> {
        let mut idx = Vec::with_capacity(rows.len() * cols.len());
        for &r in rows {
            for &c in cols {
                idx.push(self.index(r, c));
            }
        }
        idx
    }

    /// Matrix-vector product `y = A x` for values on this pattern.
    pub fn mul_vec(&self, values: &[f64], x: &[f64], y: &mut [f64]) {
        y.iter_mut().for_each(|v| *v = 0.0);
        for c in 0..self.n {
            for k in self.col_ptr[c]..self.col_ptr[c + 1] {
                y[self.row_idx[k]] += values[k] * x[c];
            }
        }
    }
}

/// Sparse LU with partial pivoting, symbolic analysis done once for a pattern.
pub struct SparseLu {
    pattern: SparsePattern,
    symbolic: SymbolicLu<usize>,
    numeric: NumericLu<usize, f64>,
    memory: MemBuffer,
    factorized: bool,
}

impl std::fmt::Debug for SparseLu {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "SparseLu(n = {}, nnz = {})", self.pattern.n, self.pattern.nnz())
    }
}

impl SparseLu {
    /// Symbolic analysis of `pattern`; allocates all memory the factorization and solves need.
    pub fn new(pattern: &SparsePattern) -> std::result::Result<Self, String> {
        let symbolic_view = SymbolicSparseColMatRef::new_checked(
            pattern.n,
            pattern.n,
            &pattern.col_ptr,
            None,
            &pattern.row_idx,
        );
        let symbolic = factorize_symbolic_lu(symbolic_view, LuSymbolicParams::default())
            .map_err(|e| format!("{e:?}"))?;
        let par = Par::Seq;
        let req = StackReq::any_of(&[
            symbolic.factorize_numeric_lu_scratch::<f64>(par, Default::default()),
            symbolic.solve_in_place_scratch::<f64>(1, par),
        ]);
        let memory = MemBuffer::try_new(req).map_err(|_| "out of memory".to_string())?;
        Ok(SparseLu {
            pattern: pattern.clone(),
            symbolic,
            numeric: NumericLu::new(),
            memory,
            factorized: false,
        })
    }

    /// Numeric factorization of the matrix with `values` on the pattern.
    pub fn factorize(&mut self, values: &[f64]) -> std::result::Result<(), String> {
        self.factorized = false;
        if let Some(k) = values.iter().position(|v| !v.is_finite()) {
            return Err(format!("non-finite matrix entry at position {k}"));
        }
        let p = &self.pattern;
        let symbolic_view = SymbolicSparseColMatRef::new_checked(p.n, p.n, &p.col_ptr, None, &p.row_idx);
        let matrix = SparseColMatRef::new(symbolic_view, values);
        let params: Spec<PartialPivLuParams, f64> = Default::default();
        self.symbolic
            .factorize_numeric_lu(
                &mut self.numeric,
                matrix,
                Par::Seq,
                MemStack::new(&mut self.memory),
                params,
            )
            .map_err(|e| match e {
                faer::sparse::linalg::LuError::SymbolicSingular { index } => {
                    format!("no pivot in column {index} (the matrix is singular)")
                }
                other => format!("{other:?}"),
            })?;
        self.factorized = true;
        Ok(())
    }

    /// Solves `A x = rhs` in place with the last factorization. Returns an error if the
    /// solution is not finite (a singular matrix).
    pub fn solve_in_place(&mut self, rhs: &mut [f64]) -> std::result::Result<(), String> {
        if !self.factorized {
            return Err("no valid factorization".to_string());
        }
        let n = self.pattern.n;
        let lu = LuRef::new_unchecked(&self.symbolic, &self.numeric);
        let rhs_mat = MatMut::from_column_major_slice_mut(rhs, n, 1);
        lu.solve_in_place_with_conj(Conj::No, rhs_mat, Par::Seq, MemStack::new(&mut self.memory));
        finite_solution(rhs)
    }
}

/// LDL^T factorization of the symmetric part of a saddle-point matrix
/// [[A, B^T], [B, 0]] given on a structurally symmetric pattern, regularized to the
/// quasi-definite [[A_sym + P, B^T], [B, -delta I]] (Vanderbei 1995), with a fill-reducing AMD
/// ordering computed once. Quasi-definite matrices have an LDL^T factorization in every
/// symmetric ordering, so no pivoting is needed when A_sym + P is positive definite. `P` adds
/// penalty blocks w (2p)(2p)^T for the Euler-parameter normalizations (which make a rigid
/// body's mass matrix definite along p without changing the solution dq; see
/// `generalized_alpha`). Used as the iteration matrix of modified Newton, where an
/// approximate Jacobian is enough; exact Newton steps use [`SparseLu`].
pub struct SparseLdlt {
    positive: usize,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    /// Per lower entry: the indices of (r, c) and (c, r) in the full value array
    /// (`usize::MAX` for diagonal entries absent from the full pattern).
    sources: Vec<[usize; 2]>,
    /// Per penalty block: the lower entry of (a, b) for a >= b over its four coordinates.
    penalty_entries: Vec<[usize; 10]>,
    symbolic: faer::sparse::linalg::cholesky::SymbolicCholesky<usize>,
    lower_values: Vec<f64>,
    factor: Vec<f64>,
    signs: Vec<i8>,
    memory: MemBuffer,
    factorized: bool,
}

impl std::fmt::Debug for SparseLdlt {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "SparseLdlt(n = {}, nnz(L) = {})", self.signs.len(), self.factor.len())
    }
}

impl SparseLdlt {
    /// Symbolic analysis. The first `positive` unknowns form the definite block; the others
    /// are constraint rows. `penalty_blocks` lists the Euler parameters of each normalization.
    pub fn new(
        pattern: &SparsePattern,
        positive: usize,
        penalty_blocks: &[[usize; 4]],
    ) -> std::result::Result<Self, String> {
        use faer::sparse::linalg::cholesky::{
            factorize_symbolic_cholesky, CholeskySymbolicParams, SymmetricOrdering,
        };
        let n = pattern.n;
        // Lower triangle of the pattern, plus every diagonal entry.
        let mut entries: Vec<(usize, usize)> = Vec::new();
        for c in 0..n {
            for &r in &pattern.row_idx[pattern.col_ptr[c]..pattern.col_ptr[c + 1]] {
                if r >= c {
                    entries.push((c, r));
                }
            }
            entries.push((c, c));
        }
        entries.sort_unstable();
        entries.dedup();
        let mut col_ptr = vec![0usize; n + 1];
        let mut row_idx = Vec::with_capacity(entries.len());
        let mut sources = Vec::with_capacity(entries.len());
        let find = |r: usize, c: usize| -> usize {
            let start = pattern.col_ptr[c];
            match pattern.row_idx[start..pattern.col_ptr[c + 1]].binary_search(&r) {
                Ok(k) => start + k,
                Err(_) => usize::MAX,
            }
        };
        for &(c, r) in &entries {
            col_ptr[c + 1] += 1;
            row_idx.push(r);
            sources.push([find(r, c), find(c, r)]);
        }
        for c in 0..n {
            col_ptr[c + 1] += col_ptr[c];
        }
        let lower_index = |r: usize, c: usize| -> usize {
            let (r, c) = if r >= c { (r, c) } else { (c, r) };
            col_ptr[c]
                + row_idx[col_ptr[c]..col_ptr[c + 1]].binary_search(&r).expect("entry in the lower pattern")
        };
        let penalty_entries = penalty_blocks
            .iter()
            .map(|dofs| {
                let mut e = [0usize; 10];
                let mut k = 0;
                for a in 0..4 {
                    for b in 0..=a {
                        e[k] = lower_index(dofs[a], dofs[b]);
                        k += 1;
                    }
                }
                e
            })
            .collect();
        let view = SymbolicSparseColMatRef::new_checked(n, n, &col_ptr, None, &row_idx);
        let params = CholeskySymbolicParams {
            supernodal_flop_ratio_threshold: faer::sparse::linalg::SupernodalThreshold::AUTO,
            ..Default::default()
        };
        let symbolic = factorize_symbolic_cholesky(view, faer::Side::Lower, SymmetricOrdering::Amd, params)
            .map_err(|e| format!("{e:?}"))?;
        let req = StackReq::any_of(&[
            symbolic.factorize_numeric_ldlt_scratch::<f64>(Par::Seq, Default::default()),
            symbolic.solve_in_place_scratch::<f64>(1, Par::Seq),
        ]);
        let memory = MemBuffer::try_new(req).map_err(|_| "out of memory".to_string())?;
        let signs = (0..n).map(|i| if i < positive { 1 } else { -1 }).collect();
        Ok(SparseLdlt {
            positive,
            lower_values: vec![0.0; row_idx.len()],
            factor: vec![0.0; symbolic.len_val()],
            col_ptr,
            row_idx,
            sources,
            penalty_entries,
            symbolic,
            signs,
            memory,
            factorized: false,
        })
    }

    /// Factorizes the symmetric part of the matrix with `values` (on the full pattern) plus
    /// the penalty blocks `weight (2p)(2p)^T` (one (weight, p) per block, in order).
    pub fn factorize(
        &mut self,
        values: &[f64],
        penalties: &[(f64, [f64; 4])],
    ) -> std::result::Result<(), String> {
        use faer::linalg::cholesky::ldlt::factor::{LdltParams, LdltRegularization};
        self.factorized = false;
        let mut scale = 0.0f64;
        for (k, [a, b]) in self.sources.iter().enumerate() {
            let va = if *a == usize::MAX { 0.0 } else { values[*a] };
            let vb = if *b == usize::MAX { 0.0 } else { values[*b] };
            self.lower_values[k] = 0.5 * (va + vb);
        }
        for (entries, (w, p)) in self.penalty_entries.iter().zip(penalties) {
            let mut k = 0;
            for a in 0..4 {
                for b in 0..=a {
                    self.lower_values[entries[k]] += 4.0 * w * p[a] * p[b];
                    k += 1;
                }
            }
        }
        // Scale of the definite block's diagonal, for the regularization of the other.
        for c in 0..self.positive {
            scale = scale.max(self.lower_values[self.col_ptr[c]].abs());
        }
        if !scale.is_finite() || self.lower_values.iter().any(|v| !v.is_finite()) {
            return Err("non-finite matrix entry".to_string());
        }
        // delta balances the perturbation of the matrix (relative delta) against the growth of
        // round-off when a constraint row is eliminated early (relative eps / delta).
        let scale = scale.max(f64::MIN_POSITIVE);
        let delta = 1e-8 / scale;
        for c in self.positive..self.signs.len() {
            self.lower_values[self.col_ptr[c]] -= delta;
        }
        let n = self.signs.len();
        let view = SymbolicSparseColMatRef::new_checked(n, n, &self.col_ptr, None, &self.row_idx);
        let matrix = SparseColMatRef::new(view, &self.lower_values);
        let regularization = LdltRegularization {
            dynamic_regularization_signs: Some(&self.signs),
            dynamic_regularization_delta: 1e-8 * scale,
            dynamic_regularization_epsilon: 1e-13 * scale,
        };
        let params: Spec<LdltParams, f64> = Default::default();
        self.symbolic
            .factorize_numeric_ldlt(
                &mut self.factor,
                matrix,
                faer::Side::Lower,
                regularization,
                Par::Seq,
                MemStack::new(&mut self.memory),
                params,
            )
            .map_err(|e| format!("{e:?}"))?;
        self.factorized = true;
        Ok(())
    }

    /// Solves with the last factorization.
    pub fn solve_in_place(&mut self, rhs: &mut [f64]) -> std::result::Result<(), String> {
        use faer::sparse::linalg::cholesky::LdltRef;
        if !self.factorized {
            return Err("no valid factorization".to_string());
        }
        let n = self.signs.len();
        let rhs_mat = MatMut::from_column_major_slice_mut(rhs, n, 1);
        LdltRef::new(&self.symbolic, &self.factor).solve_in_place_with_conj(
            Conj::No,
            rhs_mat,
            Par::Seq,
            MemStack::new(&mut self.memory),
        );
        finite_solution(rhs)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::assert_all_close;

    #[test]
    fn factorizes_and_solves_an_indefinite_saddle_point_system() {
        // [[2, 0, 1], [0, 0, 1], [1, 1, 0]]: zero diagonal needs pivoting.
        let mut b = PatternBuilder::new(3);
        b.add_block(&[0, 1], &[2]);
        b.add_block(&[2], &[0, 1]);
        b.add_diagonal(&[0]);
        let p = b.build();
        let mut values = vec![0.0; p.nnz()];
        for (r, c, v) in [(0, 0, 2.0), (0, 2, 1.0), (1, 2, 1.0), (2, 0, 1.0), (2, 1, 1.0)] {
            values[p.index(r, c)] = v;
        }
        let mut lu = SparseLu::new(&p).unwrap();
        lu.factorize(&values).unwrap();
        let x_true = [1.0, -2.0, 3.0];
        let mut rhs = vec![0.0; 3];
        p.mul_vec(&values, &x_true, &mut rhs);
        lu.solve_in_place(&mut rhs).unwrap();
        assert_all_close(&rhs, &x_true, 0.0, 1e-14, "LU solution");
    }

    #[test]
    fn ldlt_of_a_saddle_point_with_a_singular_block_and_penalty() {
        // Coordinates 0..4 with A = diag(0, 2, 3, 4) + a coupling, singular along e0; one
        // constraint row 2 p^T with p = e0 (a normalization), one general row. The penalty
        // w (2p)(2p)^T makes the block definite; the solution for x is unchanged and the
        // multiplier of the penalized row shifts by w * rhs, which is added back here.
        let n = 6;
        let mut b = PatternBuilder::new(n);
        let q: Vec<usize> = (0..4).collect();
        b.add_block(&q, &q);
        b.add_block(&[4, 5], &q);
        b.add_block(&q, &[4, 5]);
        let p = b.build();
        let mut values = vec![0.0; p.nnz()];
        let mut set = |r: usize, c: usize, v: f64| values[p.index(r, c)] = v;
        for (k, d) in [(1, 2.0), (2, 3.0), (3, 4.0)] {
            set(k, k, d);
        }
        set(1, 2, 0.5);
        set(2, 1, 0.5);
        set(4, 0, 2.0);
        set(0, 4, 2.0);
        for (c, v) in [(1, 1.0), (2, -1.0), (3, 0.5)] {
            set(5, c, v);
            set(c, 5, v);
        }
        let rhs = [0.3, -1.0, 2.0, 0.7, 0.4, -0.2];
        let mut exact = rhs.to_vec();
        let mut lu = SparseLu::new(&p).unwrap();
        lu.factorize(&values).unwrap();
        lu.solve_in_place(&mut exact).unwrap();
        let weight = 1.5;
        let mut ldlt = SparseLdlt::new(&p, 4, &[[0, 1, 2, 3]]).unwrap();
        // Penalty block over coordinates 0..4 with "p" = (1, 0, 0, 0).
        ldlt.factorize(&values, &[(weight, [1.0, 0.0, 0.0, 0.0])]).unwrap();
        let mut x = rhs.to_vec();
        ldlt.solve_in_place(&mut x).unwrap();
        x[4] += weight * rhs[4];
        // Accurate to the regularization (1e-8 relative); a wrong penalty correction would be
        // off by order one.
        assert_all_close(&x, &exact, 0.0, 1e-6, "LDL^T solution with penalty");
    }
}
