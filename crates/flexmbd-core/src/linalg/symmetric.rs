//! Sparse symmetric factorizations for the preprocessor: Cholesky LL^T of positive definite
//! matrices (stiffness matrices with enough supports, shifted K - sigma M of shift-invert
//! eigensolvers) and regularized LDL^T of quasi-definite saddle-point matrices
//! [[A, G^T], [G, 0]] (averaged RBE3 interfaces), with a fill-reducing ordering: approximate
//! minimum degree, or nested dissection of the mesh (much less fill for 3D solids).
//!
//! Nested dissection (George 1973) here is geometric: the nodes are split at the median of
//! their longest extent, the nodes on one side that touch the other side form the separator,
//! both halves are ordered recursively and the separator last. Coordinates of the mesh nodes
//! make it cheap and, on finite element meshes, close to the graph-partitioning orderings.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::ldlt::factor::{LdltParams, LdltRegularization};
use faer::linalg::cholesky::llt::factor::{LltParams, LltRegularization};
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, LdltRef, LltRef, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Spec};

use crate::error::{FlexmbdError, Result};
use crate::linalg::envelope::{reverse_cuthill_mckee, EnvelopeCholesky};
use crate::linalg::parallel;
use crate::math::Vec3;

/// Largest envelope (entries of L, 16 MiB of values) factorized in envelope form instead of
/// supernodal form. Measured on tet4 bars and cubes of 960 to 9,408 unknowns (benchmarks/
/// README.md): the envelope of the reverse Cuthill-McKee order held 0.42 to 0.65 times the
/// entries of the supernodal factor of a nested dissection, and solved 1.1 to 2.2 times
/// faster. The envelope's factorization grows with the square of its rows (a 50k bar: 27
/// million entries and 7 GFlop), hence the limit.
const ENVELOPE_LIMIT: usize = 1 << 21;

/// The envelope form is taken when its size is at most this multiple of the supernodal
/// factor's (whose dense blocks carry zeros): a row-contiguous solve over it is then faster.
const ENVELOPE_RATIO: f64 = 1.5;

/// Fill-reducing ordering of a [`SymmetricFactor`].
#[derive(Debug, Clone, Copy)]
pub enum Ordering<'a> {
    /// Approximate minimum degree on the matrix graph.
    Amd,
    /// A given elimination order (position -> unknown).
    Given(&'a [usize]),
    /// Geometric nested dissection of the nodes: `dof_nodes[i]` is the node of unknown i
    /// (`usize::MAX` for unknowns that belong to no node, such as multipliers: ordered last),
    /// `positions` the node coordinates.
    NestedDissection {
        /// Node of each unknown.
        dof_nodes: &'a [usize],
        /// Node coordinates.
        positions: &'a [Vec3],
    },
}

/// Kind of numeric factorization.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FactorKind {
    /// LL^T of a positive definite matrix; fails at a non-positive pivot.
    Cholesky,
    /// LL^T in single precision of the Jacobi-scaled matrix: half the memory and time of
    /// [`FactorKind::Cholesky`], a relative accuracy of about 1e-7 times the condition number.
    /// Meant as a preconditioner (pivots that round-off makes non-positive are regularized).
    CholeskySingle,
    /// LDL^T of a quasi-definite matrix whose first `positive` unknowns form the positive
    /// definite block and the others the constraint rows (regularized by -delta I, see
    /// [`SymmetricFactor::solve_refined`]).
    QuasiDefinite {
        /// Size of the positive definite block.
        positive: usize,
    },
}

/// A square sparse matrix in compressed sparse column form, borrowed.
#[derive(Debug, Clone, Copy)]
pub struct CscRef<'a> {
    /// Order of the matrix.
    pub n: usize,
    /// Column pointers (n + 1).
    pub col_ptr: &'a [usize],
    /// Row index of each entry.
    pub row_idx: &'a [usize],
    /// Value of each entry.
    pub values: &'a [f64],
}

/// A symmetric sparse matrix (lower triangle, CSC) with its factorization.
pub struct SymmetricFactor {
    n: usize,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    values: Vec<f64>,
    /// Entries of the matrix given to [`SymmetricFactor::new`], and how they make `values`
    /// (in the order of the summation there): what [`SymmetricFactor::refactorize`] repeats.
    given_len: usize,
    sources: Vec<Source>,
    kind: FactorKind,
    symbolic: SymbolicCholesky<usize>,
    factor: Vec<f64>,
    /// Single-precision factor of the Jacobi-scaled matrix D A D (D = diag(A)^-1/2) when
    /// the factorization is in single precision; `factor` is then empty.
    factor32: Vec<f32>,
    scaling: Vec<f64>,
    /// The envelope factor of a small positive definite matrix, used instead of the
    /// supernodal `factor` (then empty) when it is not much larger (see [`crate::linalg::envelope`]).
    envelope: Option<EnvelopeCholesky>,
    /// `Par::rayon(threads)` for more than one thread; its work runs in the process's pool
    /// ([`crate::linalg::parallel`]), which survives `fork`.
    par: Par,
    threads: usize,
}

/// Where an entry of the stored lower triangle comes from: the given entry `given` (usize::MAX:
/// the zero of a diagonal entry not given) is added to `values[lower]`, or starts it (`first`).
#[derive(Clone, Copy, Debug)]
struct Source {
    given: usize,
    lower: usize,
    first: bool,
}

impl std::fmt::Debug for SymmetricFactor {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let form = if self.envelope.is_some() { "envelope" } else { "supernodal" };
        write!(f, "SymmetricFactor(n = {}, nnz(L) = {}, {form})", self.n, self.factor_len())
    }
}

fn singular(item: &str, message: String) -> FlexmbdError {
    FlexmbdError::InvalidModel { item: item.to_string(), message }
}

impl SymmetricFactor {
    /// Analyses and factorizes the symmetric `matrix` whose lower triangle (diagonal included)
    /// is given. Entries above the diagonal are ignored. `item` names the matrix
    /// in errors. `threads` > 1 factorizes in parallel.
    pub fn new(
        item: &str,
        matrix: CscRef<'_>,
        ordering: Ordering<'_>,
        kind: FactorKind,
        threads: usize,
    ) -> Result<Self> {
        let CscRef { n, col_ptr, row_idx, values } = matrix;
        if col_ptr.len() != n + 1
            || row_idx.len() != values.len()
            || col_ptr[0] != 0
            || col_ptr[n] != values.len()
            || col_ptr.windows(2).any(|w| w[0] > w[1])
        {
            return Err(FlexmbdError::InvalidParameter {
                item: item.to_string(),
                message: format!("inconsistent CSC arrays for n = {n}"),
            });
        }
        // Keep the lower triangle, with every diagonal entry present, sorted per column.
        let mut lower_ptr = vec![0usize; n + 1];
        let mut lower_idx = Vec::with_capacity(values.len() / 2 + n);
        let mut lower_val = Vec::with_capacity(values.len() / 2 + n);
        // Per lower entry in the order summed: the given entry it takes (usize::MAX for the
        // zero of a diagonal entry not given), for `refactorize`.
        let mut sources = Vec::with_capacity(values.len() / 2 + n);
        let mut column: Vec<(usize, f64, usize)> = Vec::new();
        for c in 0..n {
            column.clear();
            column.push((c, 0.0, usize::MAX));
            for k in col_ptr[c]..col_ptr[c + 1] {
                let r = row_idx[k];
                if r >= n {
                    return Err(FlexmbdError::InvalidParameter {
                        item: item.to_string(),
                        message: format!("row index {r} out of range for n = {n}"),
                    });
                }
                if r >= c {
                    if !values[k].is_finite() {
                        return Err(FlexmbdError::NonFinite {
                            item: format!("{item} entry ({r}, {c})"),
                            time: 0.0,
                        });
                    }
                    column.push((r, values[k], k));
                }
            }
            column.sort_unstable_by_key(|e| e.0);
            let mut last = usize::MAX;
            for &(r, v, k) in &column {
                let first = r != last;
                if first {
                    lower_idx.push(r);
                    lower_val.push(v);
                    last = r;
                } else {
                    *lower_val.last_mut().expect("an entry was pushed") += v;
                }
                sources.push(Source { given: k, lower: lower_idx.len() - 1, first });
            }
            lower_ptr[c + 1] = lower_idx.len();
        }
        let view = SymbolicSparseColMatRef::new_checked(n, n, &lower_ptr, None, &lower_idx);
        let params = CholeskySymbolicParams {
            supernodal_flop_ratio_threshold: faer::sparse::linalg::SupernodalThreshold::AUTO,
            ..Default::default()
        };
        let symbolic = match ordering {
            Ordering::Amd => {
                factorize_symbolic_cholesky(view, faer::Side::Lower, SymmetricOrdering::Amd, params)
            }
            Ordering::Given(forward) => {
                let mut inverse = vec![usize::MAX; n];
                for (new, &old) in forward.iter().enumerate() {
                    if old >= n || inverse[old] != usize::MAX {
                        return Err(FlexmbdError::InvalidParameter {
                            item: item.to_string(),
                            message: format!("the ordering is not a permutation of 0..{n} (entry {old})"),
                        });
                    }
                    inverse[old] = new;
                }
                if forward.len() != n {
                    return Err(FlexmbdError::InvalidParameter {
                        item: item.to_string(),
                        message: format!("the ordering has {} entries for n = {n}", forward.len()),
                    });
                }
                let perm = PermRef::new_checked(forward, &inverse, n);
                factorize_symbolic_cholesky(view, faer::Side::Lower, SymmetricOrdering::Custom(perm), params)
            }
            Ordering::NestedDissection { dof_nodes, positions } => {
                if dof_nodes.len() != n {
                    return Err(FlexmbdError::InvalidParameter {
                        item: item.to_string(),
                        message: format!("{} unknown-to-node entries for n = {n}", dof_nodes.len()),
                    });
                }
                let forward = nested_dissection_dofs(&lower_ptr, &lower_idx, dof_nodes, positions)?;
                let mut inverse = vec![0usize; n];
                for (new, &old) in forward.iter().enumerate() {
                    inverse[old] = new;
                }
                let perm = PermRef::new_checked(&forward, &inverse, n);
                factorize_symbolic_cholesky(view, faer::Side::Lower, SymmetricOrdering::Custom(perm), params)
            }
        }
        .map_err(|e| singular(item, format!("symbolic analysis failed: {e:?}")))?;
        // Small positive definite matrices whose fill-reducing order was left to us: the
        // envelope of the reverse Cuthill-McKee order when it is small and not much larger
        // than the supernodal factor.
        let envelope = match (kind, ordering) {
            (FactorKind::Cholesky, Ordering::Amd | Ordering::NestedDissection { .. }) if n > 0 => {
                let order = reverse_cuthill_mckee(n, &lower_ptr, &lower_idx);
                let envelope = EnvelopeCholesky::new(n, &lower_ptr, &lower_idx, order);
                let len = envelope.len();
                (len <= ENVELOPE_LIMIT && len as f64 <= ENVELOPE_RATIO * symbolic.len_val() as f64)
                    .then_some(envelope)
            }
            _ => None,
        };
        let par = if threads > 1 { Par::rayon(threads) } else { Par::Seq };
        let mut this = SymmetricFactor {
            n,
            col_ptr: lower_ptr,
            row_idx: lower_idx,
            values: lower_val,
            given_len: values.len(),
            sources,
            kind,
            factor: Vec::new(),
            factor32: Vec::new(),
            scaling: Vec::new(),
            symbolic,
            envelope,
            par,
            threads,
        };
        this.factorize(item)?;
        Ok(this)
    }

    /// Factorizes anew the matrix of [`Self::new`] with other `values` on the same pattern
    /// (the same `col_ptr` and `row_idx`, entries above the diagonal ignored), keeping the
    /// ordering and the symbolic analysis (or the envelope's structure): the numeric
    /// factorization only. Summed as in [`Self::new`], so the factor equals a fresh one's
    /// bit for bit. `item` names the matrix in errors; on an error the factor is unusable
    /// until a factorization succeeds.
    pub fn refactorize(&mut self, item: &str, values: &[f64]) -> Result<()> {
        if values.len() != self.given_len {
            return Err(FlexmbdError::InvalidParameter {
                item: item.to_string(),
                message: format!(
                    "{} values for a pattern of {} entries (a refactorization keeps the pattern)",
                    values.len(),
                    self.given_len
                ),
            });
        }
        for s in &self.sources {
            let v = if s.given == usize::MAX { 0.0 } else { values[s.given] };
            if !v.is_finite() {
                return Err(FlexmbdError::NonFinite { item: format!("{item} entry {}", s.given), time: 0.0 });
            }
            if s.first {
                self.values[s.lower] = v;
            } else {
                self.values[s.lower] += v;
            }
        }
        self.factorize(item)
    }

    /// Order of the matrix.
    pub fn dim(&self) -> usize {
        self.n
    }

    /// Number of stored entries of the factor L.
    pub fn factor_len(&self) -> usize {
        self.factor.len().max(self.factor32.len()).max(self.envelope.as_ref().map_or(0, |e| e.len()))
    }

    /// Bytes held by the factor's values.
    pub fn factor_bytes(&self) -> usize {
        8 * self.factor.len() + 4 * self.factor32.len() + 8 * self.envelope.as_ref().map_or(0, |e| e.len())
    }

    /// True when the factor is stored in envelope form (small matrices, see
    /// [`crate::linalg::envelope`]), false for the supernodal form.
    pub fn is_envelope(&self) -> bool {
        self.envelope.is_some()
    }

    fn factorize(&mut self, item: &str) -> Result<()> {
        parallel::install(self.threads, || self.factorize_here(item))
    }

    fn factorize_here(&mut self, item: &str) -> Result<()> {
        let n = self.n;
        let view = SymbolicSparseColMatRef::new_checked(n, n, &self.col_ptr, None, &self.row_idx);
        if self.kind == FactorKind::CholeskySingle {
            return self.factorize_single(item);
        }
        if let Some(envelope) = &mut self.envelope {
            return envelope.factorize(&self.col_ptr, &self.row_idx, &self.values).map_err(|e| {
                singular(
                    item,
                    format!(
                        "not positive definite (pivot {:e} at unknown {}): a body without enough supports?",
                        e.pivot, e.unknown
                    ),
                )
            });
        }
        // Zeroed, keeping the memory of an earlier factorization.
        self.factor.clear();
        self.factor.resize(self.symbolic.len_val(), 0.0);
        let scale =
            (0..n).map(|c| self.values[self.col_ptr[c]].abs()).fold(0.0f64, f64::max).max(f64::MIN_POSITIVE);
        match self.kind {
            FactorKind::Cholesky => {
                let params: Spec<LltParams, f64> = Default::default();
                let req = self.symbolic.factorize_numeric_llt_scratch::<f64>(self.par, params);
                let mut memory = MemBuffer::try_new(req).map_err(|_| out_of_memory(item))?;
                let matrix = SparseColMatRef::new(view, &self.values);
                self.symbolic
                    .factorize_numeric_llt(
                        &mut self.factor,
                        matrix,
                        faer::Side::Lower,
                        LltRegularization {
                            dynamic_regularization_delta: 0.0,
                            dynamic_regularization_epsilon: 0.0,
                        },
                        self.par,
                        MemStack::new(&mut memory),
                        params,
                    )
                    .map_err(|e| {
                        singular(
                            item,
                            format!("not positive definite ({e:?}): a body without enough supports?"),
                        )
                    })?;
            }
            FactorKind::CholeskySingle => unreachable!("factorized by factorize_single"),
            FactorKind::QuasiDefinite { positive } => {
                let delta = 1e-8 * scale;
                let mut values = self.values.clone();
                for c in positive..n {
                    values[self.col_ptr[c]] -= 1e-8 / scale;
                }
                let signs: Vec<i8> = (0..n).map(|i| if i < positive { 1 } else { -1 }).collect();
                let params: Spec<LdltParams, f64> = Default::default();
                let req = self.symbolic.factorize_numeric_ldlt_scratch::<f64>(self.par, params);
                let mut memory = MemBuffer::try_new(req).map_err(|_| out_of_memory(item))?;
                let matrix = SparseColMatRef::new(view, &values);
                self.symbolic
                    .factorize_numeric_ldlt(
                        &mut self.factor,
                        matrix,
                        faer::Side::Lower,
                        LdltRegularization {
                            dynamic_regularization_signs: Some(&signs),
                            dynamic_regularization_delta: delta,
                            dynamic_regularization_epsilon: 1e-13 * scale,
                        },
                        self.par,
                        MemStack::new(&mut memory),
                        params,
                    )
                    .map_err(|e| singular(item, format!("LDL^T failed: {e:?}")))?;
            }
        }
        Ok(())
    }

    fn factorize_single(&mut self, item: &str) -> Result<()> {
        let n = self.n;
        let view = SymbolicSparseColMatRef::new_checked(n, n, &self.col_ptr, None, &self.row_idx);
        let mut scaling = vec![0.0; n];
        for c in 0..n {
            let d = self.values[self.col_ptr[c]];
            if !(d > 0.0) {
                return Err(singular(item, format!("not positive definite: diagonal entry {c} is {d:e}")));
            }
            scaling[c] = 1.0 / d.sqrt();
        }
        let mut scaled = vec![0.0f32; self.values.len()];
        for c in 0..n {
            for k in self.col_ptr[c]..self.col_ptr[c + 1] {
                scaled[k] = (self.values[k] * scaling[c] * scaling[self.row_idx[k]]) as f32;
            }
        }
        self.factor32.clear();
        self.factor32.resize(self.symbolic.len_val(), 0.0);
        let params: Spec<LltParams, f32> = Default::default();
        let req = self.symbolic.factorize_numeric_llt_scratch::<f32>(self.par, params);
        let mut memory = MemBuffer::try_new(req).map_err(|_| out_of_memory(item))?;
        let matrix = SparseColMatRef::new(view, &scaled);
        self.symbolic
            .factorize_numeric_llt(
                &mut self.factor32,
                matrix,
                faer::Side::Lower,
                // Unit diagonal: pivots that round-off drives below 1e-7 become 1e-4.
                LltRegularization {
                    dynamic_regularization_delta: 1e-4,
                    dynamic_regularization_epsilon: 1e-7,
                },
                self.par,
                MemStack::new(&mut memory),
                params,
            )
            .map_err(|e| singular(item, format!("single-precision Cholesky failed ({e:?})")))?;
        self.scaling = scaling;
        Ok(())
    }

    /// Solves A X = B in place for the columns of `rhs` (column-major, n x k) with the factor
    /// (for quasi-definite matrices: with the regularized matrix; see [`Self::solve_refined`]).
    pub fn solve_in_place(&self, rhs: &mut [f64]) -> Result<()> {
        parallel::install(self.threads, || self.solve_in_place_here(rhs))
    }

    fn solve_in_place_here(&self, rhs: &mut [f64]) -> Result<()> {
        let n = self.n;
        if n == 0 {
            return Ok(());
        }
        if rhs.len() % n != 0 {
            return Err(FlexmbdError::InvalidParameter {
                item: "right-hand side".to_string(),
                message: format!("length {} is not a multiple of n = {n}", rhs.len()),
            });
        }
        let k = rhs.len() / n;
        if self.kind == FactorKind::CholeskySingle {
            let req = self.symbolic.solve_in_place_scratch::<f32>(k, self.par);
            let mut memory = MemBuffer::try_new(req).map_err(|_| out_of_memory("solve"))?;
            let mut single: Vec<f32> =
                rhs.iter().enumerate().map(|(i, &v)| (v * self.scaling[i % n]) as f32).collect();
            let mat = MatMut::from_column_major_slice_mut(&mut single, n, k);
            LltRef::new(&self.symbolic, &self.factor32).solve_in_place_with_conj(
                Conj::No,
                mat,
                self.par,
                MemStack::new(&mut memory),
            );
            for (i, (x, &v)) in rhs.iter_mut().zip(&single).enumerate() {
                *x = f64::from(v) * self.scaling[i % n];
            }
            return finite_solution(rhs);
        }
        let mut memory = self.solve_memory(k)?;
        self.solve_with_memory(rhs, &mut memory)
    }

    /// Scratch memory for [`Self::solve_with_memory`] with `k` right-hand sides.
    pub fn solve_memory(&self, k: usize) -> Result<MemBuffer> {
        let req = StackReq::any_of(&[
            self.symbolic.solve_in_place_scratch::<f64>(k, self.par),
            StackReq::new::<f64>(self.n),
        ]);
        MemBuffer::try_new(req).map_err(|_| out_of_memory("solve"))
    }

    /// [`Self::solve_in_place`] with caller-provided scratch (from [`Self::solve_memory`] for
    /// at least as many right-hand sides): no allocation in a loop of solves. Not for
    /// single-precision factors.
    pub fn solve_with_memory(&self, rhs: &mut [f64], memory: &mut MemBuffer) -> Result<()> {
        parallel::install(self.threads, || self.solve_with_memory_here(rhs, memory))
    }

    fn solve_with_memory_here(&self, rhs: &mut [f64], memory: &mut MemBuffer) -> Result<()> {
        let n = self.n;
        if n == 0 {
            return Ok(());
        }
        let k = rhs.len() / n;
        let stack = MemStack::new(memory);
        if let Some(envelope) = &self.envelope {
            let (mut scratch, _) = stack.make_with::<f64>(n, |_| 0.0);
            for column in rhs.chunks_exact_mut(n) {
                envelope.solve(column, &mut scratch);
            }
            return finite_solution(rhs);
        }
        let mat = MatMut::from_column_major_slice_mut(rhs, n, k);
        match self.kind {
            FactorKind::Cholesky => LltRef::new(&self.symbolic, &self.factor).solve_in_place_with_conj(
                Conj::No,
                mat,
                self.par,
                stack,
            ),
            FactorKind::QuasiDefinite { .. } => LdltRef::new(&self.symbolic, &self.factor)
                .solve_in_place_with_conj(Conj::No, mat, self.par, stack),
            FactorKind::CholeskySingle => {
                return Err(FlexmbdError::InvalidParameter {
                    item: "solve".to_string(),
                    message: "a single-precision factor needs solve_in_place".to_string(),
                })
            }
        }
        finite_solution(rhs)
    }

    /// y += A x for the symmetric matrix (not the regularized one), columns of x and y.
    fn mul_add(&self, x: &[f64], y: &mut [f64]) {
        let n = self.n;
        for (xc, yc) in x.chunks_exact(n).zip(y.chunks_exact_mut(n)) {
            for c in 0..n {
                for k in self.col_ptr[c]..self.col_ptr[c + 1] {
                    let r = self.row_idx[k];
                    let v = self.values[k];
                    yc[r] += v * xc[c];
                    if r != c {
                        yc[c] += v * xc[r];
                    }
                }
            }
        }
    }

    /// Solves A X = B for B given by its rows (row-major, n x k, as NumPy's C order) and
    /// returns the rows of X. Needs less memory than [`Self::solve_in_place`] on a
    /// column-major copy: in single precision only the f32 work block and the result.
    pub fn solve_rows(&self, rows: &[f64], k: usize) -> Result<Vec<f64>> {
        parallel::install(self.threads, || self.solve_rows_here(rows, k))
    }

    fn solve_rows_here(&self, rows: &[f64], k: usize) -> Result<Vec<f64>> {
        let n = self.n;
        if rows.len() != n * k {
            return Err(FlexmbdError::InvalidParameter {
                item: "right-hand side".to_string(),
                message: format!("length {} is not n * k = {n} * {k}", rows.len()),
            });
        }
        let mut out = vec![0.0; n * k];
        if self.kind == FactorKind::CholeskySingle {
            let mut single = vec![0.0f32; n * k];
            for r in 0..n {
                for j in 0..k {
                    single[j * n + r] = (rows[r * k + j] * self.scaling[r]) as f32;
                }
            }
            let req = self.symbolic.solve_in_place_scratch::<f32>(k, self.par);
            let mut memory = MemBuffer::try_new(req).map_err(|_| out_of_memory("solve"))?;
            let mat = MatMut::from_column_major_slice_mut(&mut single, n, k);
            LltRef::new(&self.symbolic, &self.factor32).solve_in_place_with_conj(
                Conj::No,
                mat,
                self.par,
                MemStack::new(&mut memory),
            );
            for r in 0..n {
                for j in 0..k {
                    out[r * k + j] = f64::from(single[j * n + r]) * self.scaling[r];
                }
            }
        } else {
            let mut columns = vec![0.0; n * k];
            for r in 0..n {
                for j in 0..k {
                    columns[j * n + r] = rows[r * k + j];
                }
            }
            self.solve_in_place(&mut columns)?;
            for r in 0..n {
                for j in 0..k {
                    out[r * k + j] = columns[j * n + r];
                }
            }
        }
        finite_solution(&out)?;
        Ok(out)
    }

    /// A X for the symmetric matrix that was factorized (not the regularized one); `x` holds
    /// the rows of X (row-major, n x k) and the rows of A X are returned.
    pub fn multiply(&self, x: &[f64], k: usize) -> Result<Vec<f64>> {
        let n = self.n;
        if x.len() != n * k {
            return Err(FlexmbdError::InvalidParameter {
                item: "multiplied block".to_string(),
                message: format!("length {} is not n * k = {n} * {k}", x.len()),
            });
        }
        let mut y = vec![0.0; n * k];
        let mut acc = vec![0.0; k];
        for c in 0..n {
            let xc = &x[c * k..(c + 1) * k];
            acc.fill(0.0);
            for e in self.col_ptr[c]..self.col_ptr[c + 1] {
                let r = self.row_idx[e];
                let v = self.values[e];
                let xr = &x[r * k..(r + 1) * k];
                for j in 0..k {
                    acc[j] += v * xr[j];
                }
                if r != c {
                    let yr = &mut y[r * k..(r + 1) * k];
                    for j in 0..k {
                        yr[j] += v * xc[j];
                    }
                }
            }
            for (yj, aj) in y[c * k..(c + 1) * k].iter_mut().zip(&acc) {
                *yj += aj;
            }
        }
        Ok(y)
    }

    /// Solves with iterative refinement against the exact matrix: removes the effect of the
    /// regularization of quasi-definite factors (and round-off) in `steps` corrections.
    pub fn solve_refined(&self, rhs: &mut [f64], steps: usize) -> Result<()> {
        let b = rhs.to_vec();
        self.solve_in_place(rhs)?;
        for _ in 0..steps {
            let mut r = b.clone();
            let mut ax = vec![0.0; b.len()];
            self.mul_add(rhs, &mut ax);
            for (ri, ai) in r.iter_mut().zip(&ax) {
                *ri -= ai;
            }
            self.solve_in_place(&mut r)?;
            for (xi, di) in rhs.iter_mut().zip(&r) {
                *xi += di;
            }
        }
        Ok(())
    }
}

fn finite_solution(x: &[f64]) -> Result<()> {
    if !crate::math::all_finite(x) {
        return Err(FlexmbdError::NonFinite {
            item: "solution of a factorized system".to_string(),
            time: 0.0,
        });
    }
    Ok(())
}

fn out_of_memory(item: &str) -> FlexmbdError {
    FlexmbdError::InvalidModel {
        item: item.to_string(),
        message: "out of memory for the factorization".to_string(),
    }
}

/// Elimination order of the unknowns (forward permutation: position -> unknown) from a nested
/// dissection of the nodes of the graph of the lower-triangular pattern.
fn nested_dissection_dofs(
    col_ptr: &[usize],
    row_idx: &[usize],
    dof_nodes: &[usize],
    positions: &[Vec3],
) -> Result<Vec<usize>> {
    let nodes = positions.len();
    if let Some(&bad) = dof_nodes.iter().find(|&&k| k != usize::MAX && k >= nodes) {
        return Err(FlexmbdError::UnknownItem {
            kind: "node",
            id: bad,
            context: " (of a matrix unknown)".to_string(),
        });
    }
    // Node graph: nodes a != b are adjacent if an entry couples an unknown of a with one of b.
    let mut pairs: Vec<(usize, usize)> = Vec::with_capacity(row_idx.len());
    for c in 0..dof_nodes.len() {
        let b = dof_nodes[c];
        if b == usize::MAX {
            continue;
        }
        for &r in &row_idx[col_ptr[c]..col_ptr[c + 1]] {
            let a = dof_nodes[r];
            if a != usize::MAX && a != b {
                pairs.push((a, b));
                pairs.push((b, a));
            }
        }
    }
    pairs.sort_unstable();
    pairs.dedup();
    let mut adj_ptr = vec![0usize; nodes + 1];
    for &(a, _) in &pairs {
        adj_ptr[a + 1] += 1;
    }
    for a in 0..nodes {
        adj_ptr[a + 1] += adj_ptr[a];
    }
    let adj: Vec<usize> = pairs.iter().map(|p| p.1).collect();
    let order = nested_dissection(positions, &adj_ptr, &adj);
    // Unknowns node by node in that order, then those of no node.
    let mut first = vec![0usize; nodes + 1];
    for &k in dof_nodes {
        if k != usize::MAX {
            first[k + 1] += 1;
        }
    }
    for a in 0..nodes {
        first[a + 1] += first[a];
    }
    let mut by_node = vec![0usize; first[nodes]];
    let mut fill = first.clone();
    for (i, &k) in dof_nodes.iter().enumerate() {
        if k != usize::MAX {
            by_node[fill[k]] = i;
            fill[k] += 1;
        }
    }
    let mut forward = Vec::with_capacity(dof_nodes.len());
    for &a in &order {
        forward.extend_from_slice(&by_node[first[a]..first[a + 1]]);
    }
    forward.extend(dof_nodes.iter().enumerate().filter(|(_, &k)| k == usize::MAX).map(|(i, _)| i));
    Ok(forward)
}

/// Nodes at most this many are ordered as they come.
const DISSECTION_LEAF: usize = 48;

/// Geometric nested dissection of a graph with node coordinates: the elimination order of the
/// nodes (separators after the parts they separate).
pub fn nested_dissection(positions: &[Vec3], adj_ptr: &[usize], adj: &[usize]) -> Vec<usize> {
    let n = positions.len();
    let mut order = Vec::with_capacity(n);
    let mut stamp = vec![0u32; n];
    let mut counter = 0u32;
    // Explicit stack: (nodes, separator to emit after them); separators are pushed as
    // finished parts.
    enum Task {
        Split(Vec<usize>),
        Emit(Vec<usize>),
    }
    let mut stack = vec![Task::Split((0..n).collect())];
    while let Some(task) = stack.pop() {
        let mut set = match task {
            Task::Emit(nodes) => {
                order.extend(nodes);
                continue;
            }
            Task::Split(set) => set,
        };
        if set.len() <= DISSECTION_LEAF {
            order.extend(set);
            continue;
        }
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for &v in &set {
            for k in 0..3 {
                lo[k] = lo[k].min(positions[v][k]);
                hi[k] = hi[k].max(positions[v][k]);
            }
        }
        let axis = (0..3).max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b]))).unwrap_or(0);
        // Split at the median coordinate; nodes at the median go right, so that planes of
        // nodes at equal coordinates are not torn apart.
        let mid = set.len() / 2;
        set.select_nth_unstable_by(mid, |&a, &b| positions[a][axis].total_cmp(&positions[b][axis]));
        let median = positions[set[mid]][axis];
        let (mut left, mut right): (Vec<usize>, Vec<usize>) =
            set.iter().partition(|&&v| positions[v][axis] < median);
        if left.is_empty() {
            (left, right) = set.iter().partition(|&&v| positions[v][axis] <= median);
            if right.is_empty() {
                // All nodes at one coordinate along the longest extent: coincident nodes.
                order.extend(left);
                continue;
            }
        }
        counter += 1;
        for &v in &left {
            stamp[v] = counter;
        }
        let (separator, rest): (Vec<usize>, Vec<usize>) = right
            .into_iter()
            .partition(|&v| adj[adj_ptr[v]..adj_ptr[v + 1]].iter().any(|&w| stamp[w] == counter));
        // Left part first, then the right part, then the separator.
        stack.push(Task::Emit(separator));
        stack.push(Task::Split(rest));
        stack.push(Task::Split(left));
    }
    order
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::assert_all_close;

    /// The 3D Laplacian (7-point) on an m^3 grid plus `shift` on the diagonal, lower CSC.
    fn laplacian(m: usize, shift: f64) -> (usize, Vec<usize>, Vec<usize>, Vec<f64>, Vec<Vec3>) {
        let n = m * m * m;
        let id = |i: usize, j: usize, k: usize| (i * m + j) * m + k;
        let mut col_ptr = vec![0];
        let mut row_idx = Vec::new();
        let mut values = Vec::new();
        let mut positions = Vec::new();
        for i in 0..m {
            for j in 0..m {
                for k in 0..m {
                    positions.push(Vec3::new(i as f64, j as f64, k as f64));
                    row_idx.push(id(i, j, k));
                    values.push(6.0 + shift);
                    for (a, b, c) in [(i + 1, j, k), (i, j + 1, k), (i, j, k + 1)] {
                        if a < m && b < m && c < m {
                            row_idx.push(id(a, b, c));
                            values.push(-1.0);
                        }
                    }
                    col_ptr.push(row_idx.len());
                }
            }
        }
        (n, col_ptr, row_idx, values, positions)
    }

    fn csc<'a>(n: usize, col_ptr: &'a [usize], row_idx: &'a [usize], values: &'a [f64]) -> CscRef<'a> {
        CscRef { n, col_ptr, row_idx, values }
    }

    fn residual(f: &SymmetricFactor, x: &[f64], b: &[f64]) -> f64 {
        let mut ax = vec![0.0; b.len()];
        f.mul_add(x, &mut ax);
        ax.iter().zip(b).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max)
    }

    #[test]
    fn nested_dissection_has_far_less_fill_than_the_natural_order_and_about_that_of_amd() {
        let (n, cp, ri, v, pos) = laplacian(24, 0.0);
        let nodes: Vec<usize> = (0..n).collect();
        let factor = |ordering| {
            SymmetricFactor::new("K", csc(n, &cp, &ri, &v), ordering, FactorKind::Cholesky, 1).unwrap()
        };
        let nd = factor(Ordering::NestedDissection { dof_nodes: &nodes, positions: &pos });
        let amd = factor(Ordering::Amd);
        // The natural (lexicographic) order of the grid gives a banded factor with about
        // n m^2 entries.
        let banded = n * 24 * 24;
        assert!(nd.factor_len() < banded / 2, "ND {} vs banded {banded}", nd.factor_len());
        assert!(
            (nd.factor_len() as f64) < 1.25 * amd.factor_len() as f64,
            "ND {} vs AMD {}",
            nd.factor_len(),
            amd.factor_len()
        );
        let b: Vec<f64> = (0..2 * n).map(|i| ((i * 7919) % 101) as f64 - 50.0).collect();
        for f in [&nd, &amd] {
            let mut x = b.clone();
            f.solve_in_place(&mut x).unwrap();
            assert!(residual(f, &x, &b) < 1e-10);
        }
        assert!(nested_dissection(&[], &[0], &[]).is_empty());
    }

    #[test]
    fn the_last_nodes_of_a_dissection_separate_the_graph() {
        let (n, cp, ri, _, pos) = laplacian(12, 0.0);
        let nodes: Vec<usize> = (0..n).collect();
        let order = nested_dissection_dofs(&cp, &ri, &nodes, &pos).unwrap();
        // The top separator of a 12^3 grid is one plane of 144 nodes; without it, the graph
        // falls apart into two halves.
        let separator: std::collections::HashSet<usize> = order[n - 144..].iter().copied().collect();
        let mut seen = vec![false; n];
        let start = (0..n).find(|v| !separator.contains(v)).unwrap();
        let mut stack = vec![start];
        seen[start] = true;
        let id = |i: usize, j: usize, k: usize| (i * 12 + j) * 12 + k;
        while let Some(v) = stack.pop() {
            let (i, j, k) = (v / 144, (v / 12) % 12, v % 12);
            let mut next = Vec::new();
            if i > 0 {
                next.push(id(i - 1, j, k));
            }
            if i < 11 {
                next.push(id(i + 1, j, k));
            }
            if j > 0 {
                next.push(id(i, j - 1, k));
            }
            if j < 11 {
                next.push(id(i, j + 1, k));
            }
            if k > 0 {
                next.push(id(i, j, k - 1));
            }
            if k < 11 {
                next.push(id(i, j, k + 1));
            }
            for w in next {
                if !seen[w] && !separator.contains(&w) {
                    seen[w] = true;
                    stack.push(w);
                }
            }
        }
        let reached = seen.iter().filter(|&&s| s).count();
        assert!(reached < n - 144, "the separator does not separate: {reached} of {} reached", n - 144);
        assert!(reached > (n - 144) / 3, "unbalanced halves: {reached}");
    }

    #[test]
    fn single_precision_factors_take_half_the_memory_and_precondition_well() {
        let (n, cp, ri, v, pos) = laplacian(12, 0.5);
        let nodes: Vec<usize> = (0..n).collect();
        let ordering = Ordering::NestedDissection { dof_nodes: &nodes, positions: &pos };
        // The double factor in supernodal form with the same order (a given order is never
        // replaced by an envelope; the double factor of the dissection would be one here).
        let order = nested_dissection_dofs(&cp, &ri, &nodes, &pos).unwrap();
        let double =
            SymmetricFactor::new("K", csc(n, &cp, &ri, &v), Ordering::Given(&order), FactorKind::Cholesky, 1)
                .unwrap();
        assert!(!double.is_envelope());
        let single =
            SymmetricFactor::new("K", csc(n, &cp, &ri, &v), ordering, FactorKind::CholeskySingle, 1).unwrap();
        assert!(!single.is_envelope());
        assert_eq!(single.factor_len(), double.factor_len());
        assert_eq!(2 * single.factor_bytes(), double.factor_bytes());
        let b: Vec<f64> = (0..n).map(|i| ((i * 31) % 17) as f64 - 8.0).collect();
        let mut x = b.clone();
        single.solve_in_place(&mut x).unwrap();
        let scale = b.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let r = residual(&single, &x, &b) / scale;
        // Single precision: far from exact, far better than nothing.
        assert!(r < 1e-4 && r > 1e-12, "relative residual {r}");
        let mut exact = b.clone();
        double.solve_in_place(&mut exact).unwrap();
        assert!(residual(&double, &exact, &b) / scale < 1e-12);
    }

    #[test]
    fn small_definite_matrices_take_the_envelope_form_and_solve_like_the_supernodal_one() {
        // The 7-point Laplacian of a 12 x 12 x 12 grid: the envelope of its RCM order is within
        // 1.5 times the supernodal factor of the dissection, so both fill-reducing requests
        // take it; a given order keeps the supernodal form. Both solve to round-off and agree.
        let (n, cp, ri, v, pos) = laplacian(12, 0.5);
        let nodes: Vec<usize> = (0..n).collect();
        let dissection = Ordering::NestedDissection { dof_nodes: &nodes, positions: &pos };
        let order = nested_dissection_dofs(&cp, &ri, &nodes, &pos).unwrap();
        let b: Vec<f64> = (0..n).map(|i| ((i * 31) % 17) as f64 - 8.0).collect();
        let mut solutions = Vec::new();
        for (ordering, envelope) in
            [(dissection, true), (Ordering::Amd, true), (Ordering::Given(&order), false)]
        {
            let f =
                SymmetricFactor::new("K", csc(n, &cp, &ri, &v), ordering, FactorKind::Cholesky, 1).unwrap();
            assert_eq!(f.is_envelope(), envelope, "{ordering:?}");
            assert_eq!(f.factor_bytes(), 8 * f.factor_len());
            let mut x = b.clone();
            f.solve_in_place(&mut x).unwrap();
            assert!(residual(&f, &x, &b) < 1e-12 * 8.0, "{ordering:?}");
            // Two right-hand sides at once, and the scratch-memory path.
            let mut two: Vec<f64> =
                b.iter().chain(b.iter().map(|x| -x).collect::<Vec<_>>().iter()).copied().collect();
            let mut memory = f.solve_memory(2).unwrap();
            f.solve_with_memory(&mut two, &mut memory).unwrap();
            let minus_x: Vec<f64> = x.iter().map(|v| -v).collect();
            assert_all_close(&two[..n], &x, 0.0, 1e-14 * 8.0, format_args!("{ordering:?}: first of two"));
            assert_all_close(
                &two[n..],
                &minus_x,
                0.0,
                1e-14 * 8.0,
                format_args!("{ordering:?}: second of two"),
            );
            solutions.push(x);
        }
        assert_all_close(&solutions[0], &solutions[2], 0.0, 1e-12, "envelope against supernodal solution");
        // A matrix that is not positive definite names the failing unknown.
        let shifted: Vec<f64> = (0..n)
            .flat_map(|c| (cp[c]..cp[c + 1]).map(move |k| (c, k)))
            .map(|(c, k)| if ri[k] == c { v[k] - 20.0 } else { v[k] })
            .collect();
        let err =
            SymmetricFactor::new("K", csc(n, &cp, &ri, &shifted), Ordering::Amd, FactorKind::Cholesky, 1)
                .expect_err("indefinite");
        assert!(format!("{err}").contains("not positive definite (pivot"), "{err}");
    }

    #[test]
    fn refactorized_factors_solve_as_fresh_ones_for_changed_values() {
        // The iteration matrix of a step size, then of another: the values change on the same
        // pattern (here the grid Laplacian given in both triangles, with a duplicated
        // diagonal, shifted and scaled anew). The factor refactorized with the kept ordering
        // and symbolic analysis solves as a fresh factorization of the new values does, in
        // every form: envelope (fill-reducing requests), supernodal (a given order), single
        // precision, quasi-definite.
        let (n, cp, ri, v, pos) = laplacian(12, 0.5);
        let nodes: Vec<usize> = (0..n).collect();
        let order = nested_dissection_dofs(&cp, &ri, &nodes, &pos).unwrap();
        // Both triangles (the upper entries must be ignored) and a second diagonal entry.
        let mut col_ptr = vec![0];
        let mut row_idx = Vec::new();
        let mut base = Vec::new();
        let mut upper: Vec<Vec<(usize, f64)>> = vec![Vec::new(); n];
        for c in 0..n {
            for k in cp[c]..cp[c + 1] {
                if ri[k] != c {
                    upper[ri[k]].push((c, v[k]));
                }
            }
        }
        for c in 0..n {
            for &(r, x) in &upper[c] {
                row_idx.push(r);
                base.push(x);
            }
            row_idx.extend_from_slice(&ri[cp[c]..cp[c + 1]]);
            base.extend_from_slice(&v[cp[c]..cp[c + 1]]);
            row_idx.push(c);
            base.push(0.25);
            col_ptr.push(row_idx.len());
        }
        // New values: every entry scaled, the diagonal shifted (positive definite still).
        let changed: Vec<f64> = (0..n)
            .flat_map(|c| (col_ptr[c]..col_ptr[c + 1]).map(move |k| (c, k)))
            .map(|(c, k)| if row_idx[k] == c { 3.0 * base[k] + 1.7 } else { 3.0 * base[k] })
            .collect();
        let b: Vec<f64> = (0..2 * n).map(|i| ((i * 7919) % 23) as f64 - 11.0).collect();
        let dissection = Ordering::NestedDissection { dof_nodes: &nodes, positions: &pos };
        let cases = [
            (dissection, FactorKind::Cholesky, true),
            (Ordering::Amd, FactorKind::Cholesky, true),
            (Ordering::Given(&order), FactorKind::Cholesky, false),
            (dissection, FactorKind::CholeskySingle, false),
        ];
        for (ordering, kind, envelope) in cases {
            let mut kept =
                SymmetricFactor::new("A", csc(n, &col_ptr, &row_idx, &base), ordering, kind, 1).unwrap();
            assert_eq!(kept.is_envelope(), envelope, "{ordering:?} {kind:?}");
            kept.refactorize("A", &changed).unwrap();
            let fresh =
                SymmetricFactor::new("A", csc(n, &col_ptr, &row_idx, &changed), ordering, kind, 1).unwrap();
            let (mut x, mut expected) = (b.clone(), b.clone());
            kept.solve_in_place(&mut x).unwrap();
            fresh.solve_in_place(&mut expected).unwrap();
            let what = format_args!("{ordering:?} {kind:?}: refactorized against fresh solve");
            assert_all_close(&x, &expected, 1e-12, 0.0, what);
            // And it solves the new matrix (in single precision: as a preconditioner does).
            let accuracy = if kind == FactorKind::CholeskySingle { 1e-4 } else { 1e-12 };
            assert!(residual(&kept, &x, &b) < accuracy * 11.0, "{ordering:?} {kind:?}");
        }
        // Quasi-definite: a constraint row (the mean) appended as the last unknown.
        let mut q_ptr = vec![0];
        let (mut q_idx, mut q_base, mut q_changed) = (Vec::new(), Vec::new(), Vec::new());
        for c in 0..n {
            for k in col_ptr[c]..col_ptr[c + 1] {
                q_idx.push(row_idx[k]);
                q_base.push(base[k]);
                q_changed.push(changed[k]);
            }
            q_idx.push(n);
            q_base.push(1.0 / n as f64);
            q_changed.push(2.0 / n as f64);
            q_ptr.push(q_idx.len());
        }
        q_ptr.push(q_idx.len());
        let kind = FactorKind::QuasiDefinite { positive: n };
        let mut kept =
            SymmetricFactor::new("K", csc(n + 1, &q_ptr, &q_idx, &q_base), Ordering::Amd, kind, 1).unwrap();
        kept.refactorize("K", &q_changed).unwrap();
        let fresh = SymmetricFactor::new("K", csc(n + 1, &q_ptr, &q_idx, &q_changed), Ordering::Amd, kind, 1)
            .unwrap();
        let (mut x, mut expected) = (b[..n + 1].to_vec(), b[..n + 1].to_vec());
        kept.solve_refined(&mut x, 2).unwrap();
        fresh.solve_refined(&mut expected, 2).unwrap();
        assert_all_close(&x, &expected, 1e-12, 0.0, "quasi-definite: refactorized against fresh solve");
        // Values of another pattern, non-finite values and matrices that are not positive
        // definite are errors naming the matrix.
        let err = kept.refactorize("K", &q_changed[1..]).unwrap_err();
        assert!(err.to_string().contains("keeps the pattern"), "{err}");
        let mut bad = changed.clone();
        bad[col_ptr[4] - 1] = f64::NAN;
        let mut single = SymmetricFactor::new(
            "A",
            csc(n, &col_ptr, &row_idx, &base),
            Ordering::Amd,
            FactorKind::Cholesky,
            1,
        )
        .unwrap();
        assert!(matches!(single.refactorize("A", &bad), Err(FlexmbdError::NonFinite { .. })));
        let indefinite: Vec<f64> =
            changed.iter().enumerate().map(|(k, &x)| if base[k] == 0.25 { x - 40.0 } else { x }).collect();
        let err = single.refactorize("A of body 'beam'", &indefinite).unwrap_err();
        assert!(err.to_string().contains("A of body 'beam'"), "{err}");
    }

    #[test]
    fn multiply_applies_the_whole_symmetric_matrix() {
        let (n, col_ptr, row_idx, values, _) = laplacian(5, 0.3);
        let f = SymmetricFactor::new(
            "A",
            csc(n, &col_ptr, &row_idx, &values),
            Ordering::Amd,
            FactorKind::Cholesky,
            1,
        )
        .expect("factorizes");
        let k = 3;
        let x: Vec<f64> = (0..n * k).map(|i| ((i * 7919) % 13) as f64 - 6.0).collect();
        let y = f.multiply(&x, k).expect("multiplies");
        // Reference: the full matrix from both triangles of the stored lower part.
        let mut dense = vec![0.0; n * n];
        for c in 0..n {
            for e in col_ptr[c]..col_ptr[c + 1] {
                dense[row_idx[e] * n + c] = values[e];
                dense[c * n + row_idx[e]] = values[e];
            }
        }
        let expected: Vec<f64> =
            (0..n * k).map(|i| (0..n).map(|c| dense[i / k * n + c] * x[c * k + i % k]).sum()).collect();
        assert_all_close(&y, &expected, 1e-12, 1e-12, "A x, row-major");
        assert!(f.multiply(&x[1..], k).is_err());
    }

    #[test]
    fn row_major_solves_match_column_major_ones() {
        let (n, col_ptr, row_idx, values, positions) = laplacian(6, 0.2);
        let k = 3;
        let rows: Vec<f64> = (0..n * k).map(|i| ((i * 104_729) % 17) as f64 - 8.0).collect();
        let mut columns = vec![0.0; n * k];
        for r in 0..n {
            for j in 0..k {
                columns[j * n + r] = rows[r * k + j];
            }
        }
        for kind in [FactorKind::Cholesky, FactorKind::CholeskySingle] {
            let ordering =
                Ordering::NestedDissection { dof_nodes: &(0..n).collect::<Vec<_>>(), positions: &positions };
            let f = SymmetricFactor::new("A", csc(n, &col_ptr, &row_idx, &values), ordering, kind, 1)
                .expect("factorizes");
            let x = f.solve_rows(&rows, k).expect("solves");
            let mut expected = columns.clone();
            f.solve_in_place(&mut expected).expect("solves");
            let expected_rows: Vec<f64> = (0..n * k).map(|i| expected[i % k * n + i / k]).collect();
            assert_all_close(&x, &expected_rows, 1e-14, 1e-14, format_args!("{kind:?}: row-major solution"));
            assert!(f.solve_rows(&rows[1..], k).is_err());
        }
    }

    #[test]
    fn given_orderings_must_be_permutations() {
        let (n, cp, ri, v, _) = laplacian(4, 0.0);
        let reversed: Vec<usize> = (0..n).rev().collect();
        let f = SymmetricFactor::new(
            "K",
            csc(n, &cp, &ri, &v),
            Ordering::Given(&reversed),
            FactorKind::Cholesky,
            1,
        )
        .unwrap();
        let b = vec![1.0; n];
        let mut x = b.clone();
        f.solve_in_place(&mut x).unwrap();
        assert!(residual(&f, &x, &b) < 1e-12);
        let mut bad = reversed.clone();
        bad[0] = bad[1];
        let err =
            SymmetricFactor::new("K", csc(n, &cp, &ri, &v), Ordering::Given(&bad), FactorKind::Cholesky, 1)
                .unwrap_err();
        assert!(err.to_string().contains("not a permutation"), "{err}");
    }

    #[test]
    fn dissection_orders_every_node_once() {
        let (n, cp, ri, _, pos) = laplacian(9, 0.0);
        let nodes: Vec<usize> = (0..n).map(|i| if i % 50 == 7 { usize::MAX } else { i }).collect();
        let forward = nested_dissection_dofs(&cp, &ri, &nodes, &pos).unwrap();
        let mut sorted = forward.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..n).collect::<Vec<_>>());
        // Unknowns of no node come last.
        let tail: Vec<usize> = forward[n - 15..].to_vec();
        assert!(tail.iter().all(|&i| i % 50 == 7), "{tail:?}");
    }

    #[test]
    fn singular_and_indefinite_matrices_are_reported() {
        let (n, cp, ri, v, _) = laplacian(4, -6.0);
        let err = SymmetricFactor::new(
            "K_ff of body 'arm'",
            csc(n, &cp, &ri, &v),
            Ordering::Amd,
            FactorKind::Cholesky,
            1,
        )
        .unwrap_err();
        assert!(err.to_string().contains("K_ff of body 'arm'"), "{err}");
        let mut bad = v.clone();
        bad[3] = f64::NAN;
        let err = SymmetricFactor::new("M", csc(n, &cp, &ri, &bad), Ordering::Amd, FactorKind::Cholesky, 1)
            .unwrap_err();
        assert!(matches!(err, FlexmbdError::NonFinite { .. }), "{err}");
    }

    #[test]
    fn quasi_definite_saddle_point_with_refinement_is_exact() {
        // [[A, g^T], [g, 0]] with A the grid Laplacian and g the mean: minimize
        // x.A x / 2 - x_0 subject to mean(x) = 1/2.
        let (n, cp, ri, v, _) = laplacian(5, 0.0);
        let mut col_ptr = cp.clone();
        let mut row_idx = ri.clone();
        let mut values = v.clone();
        // Append the constraint row as the last column's lower entries: entry (n, c) in column c.
        let mut new_ptr = vec![0];
        let mut new_idx = Vec::new();
        let mut new_val = Vec::new();
        for c in 0..n {
            new_idx.extend_from_slice(&row_idx[col_ptr[c]..col_ptr[c + 1]]);
            new_val.extend_from_slice(&values[col_ptr[c]..col_ptr[c + 1]]);
            new_idx.push(n);
            new_val.push(1.0 / n as f64);
            new_ptr.push(new_idx.len());
        }
        new_ptr.push(new_idx.len());
        col_ptr = new_ptr;
        row_idx = new_idx;
        values = new_val;
        let f = SymmetricFactor::new(
            "saddle",
            csc(n + 1, &col_ptr, &row_idx, &values),
            Ordering::Amd,
            FactorKind::QuasiDefinite { positive: n },
            1,
        )
        .unwrap();
        let mut b = vec![0.0; n + 1];
        b[0] = 1.0;
        b[n] = 0.5;
        let mut x = b.clone();
        f.solve_refined(&mut x, 3).unwrap();
        assert!(residual(&f, &x, &b) < 1e-12, "{}", residual(&f, &x, &b));
    }
}
