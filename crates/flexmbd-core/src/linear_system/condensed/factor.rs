//! The factorizations of the condensed solver: A of each condensed body (sparse Cholesky, one
//! per set of coefficients, at most two kept, each with the solves of the body's coupling rows)
//! and the LU of the reduced (Schur complement) system.

use super::Block;
use crate::assembly::MatrixCoefficients;
use crate::body::flexible::FlexibleBody;
use crate::error::Result;
use crate::linalg::dense::{DenseLu, DENSE_SYSTEM_SIZE};
use crate::linalg::sparse::{SparseLu, SparsePattern};
use crate::linalg::symmetric::{CscRef, FactorKind, Ordering, SymmetricFactor};

/// The coefficients that define A (m, v, p, the elastic coordinates' i, s).
type Key = [f64; 5];

fn key(c: &MatrixCoefficients) -> Key {
    [c.mass, c.velocity, c.position, c.elastic_identity, c.scale]
}

/// Whether a factorization of A made for the coefficients `kept` serves `wanted`: each equal
/// to round-off, as the integrator's step sizes.
fn same_key(kept: &Key, wanted: &Key) -> bool {
    kept.iter().zip(wanted).all(|(&a, &b)| crate::math::equal_to_round_off(a, b))
}

/// A factorized A of one body for one set of coefficients.
pub(super) struct BlockFactor {
    key: Key,
    /// Cholesky factor, or None when A = s i I (only the identity term).
    factor: Option<SymmetricFactor>,
    /// s i when A is a multiple of the identity.
    diagonal: f64,
    /// A^-1 [I1^T, J_f0^T, S] (n x 12, column-major): the solves of the coupling with the
    /// body's own reference coordinates, made once per factorization (see `coupling_rows` and
    /// `reference_coupling`).
    pub(super) influence: Vec<f64>,
    /// A^-1 Q of the first vectors of the block's coupling basis Q (n each, column-major):
    /// solved when a factorization first needs them.
    pub(super) basis_solved: Vec<f64>,
    /// The deformation part dJ^T of the rotation coupling at the last solves with it (3 n,
    /// empty before), the rows J_f = J_f0 + dJ of the deformed body there and their solves
    /// A^-1 J_f^T (see `reference_coupling`).
    pub(super) deformation: Vec<f64>,
    pub(super) deformed_rows: Vec<f64>,
    pub(super) deformed_solved: Vec<f64>,
    /// q_f of `deformation`, and the smallest norm of the rows J_f0 + dJ there (the cheap
    /// test of `reference_coupling`).
    pub(super) deformation_at: Vec<f64>,
    pub(super) deformation_rows: f64,
    /// The products G = U^T V of the row vectors U with the column vectors V of the
    /// structured coupling (`ReferenceCoupling`), ROW_VECTORS x COLUMN_VECTORS row-major;
    /// empty until made, and made again when dJ is solved again. `gram_deformed`: with dJ.
    pub(super) gram: Vec<f64>,
    pub(super) gram_deformed: bool,
    /// The products V_u^T A_i V_v of the first six column vectors with the antisymmetric
    /// A_i, i = 0..3 (3 x 6 x 6), for the coarse stage's gyroscopic block; empty until made,
    /// and made again with G.
    pub(super) antisymmetric_gram: Vec<f64>,
    /// A_i V_v of the same (3 x 6 vectors of n_f, i-major), made with them.
    pub(super) antisymmetric_images: Vec<f64>,
    /// Scratch of single solves (allocated at the first).
    memory: Option<faer::dyn_stack::MemBuffer>,
}

impl BlockFactor {
    /// A factorization with no solves kept yet: `factor`, or A = `diagonal` I when None.
    fn new(key: Key, factor: Option<SymmetricFactor>, diagonal: f64) -> Self {
        BlockFactor {
            key,
            factor,
            diagonal,
            influence: Vec::new(),
            basis_solved: Vec::new(),
            deformation: Vec::new(),
            deformed_rows: Vec::new(),
            deformed_solved: Vec::new(),
            deformation_at: Vec::new(),
            deformation_rows: 0.0,
            gram: Vec::new(),
            gram_deformed: false,
            antisymmetric_gram: Vec::new(),
            antisymmetric_images: Vec::new(),
            memory: None,
        }
    }

    /// Solves for one or more right-hand sides (column-major).
    pub(super) fn solve_in_place(&mut self, x: &mut [f64]) -> Result<()> {
        match &self.factor {
            Some(f) if x.len() == f.dim() => {
                if self.memory.is_none() {
                    self.memory = Some(f.solve_memory(1)?);
                }
                f.solve_with_memory(x, self.memory.as_mut().expect("allocated above"))
            }
            Some(f) => f.solve_in_place(x),
            None => {
                x.iter_mut().for_each(|v| *v /= self.diagonal);
                Ok(())
            }
        }
    }
}

/// The values of A = s (m M_ff + v D_ff + p K_ff + i I) of the deformable body `fb` for the
/// coefficients `c`, on the pattern of [`elastic_iteration_pattern`].
fn elastic_iteration_values(fb: &FlexibleBody, c: &MatrixCoefficients) -> Vec<f64> {
    let mut on_pattern = vec![0.0; fb.pattern.nnz()];
    fb.mass_matrix.add_to_pattern(c.scale * c.mass, &mut on_pattern);
    fb.damping.add_to_pattern(c.scale * c.velocity, &mut on_pattern);
    fb.stiffness.add_to_pattern(c.scale * c.position, &mut on_pattern);
    let ep = &fb.pattern;
    let mut values = Vec::with_capacity(ep.nnz() + ep.n);
    for col in 0..ep.n {
        values.extend_from_slice(&on_pattern[ep.col_ptr[col]..ep.col_ptr[col + 1]]);
        values.push(c.scale * c.elastic_identity);
    }
    values
}

/// The pattern of A (column pointers, row indices): the body's pattern with a diagonal entry
/// appended to every column (duplicates are summed by the factorization) for the identity term.
fn elastic_iteration_pattern(fb: &FlexibleBody) -> (Vec<usize>, Vec<usize>) {
    let ep = &fb.pattern;
    let mut col_ptr = Vec::with_capacity(ep.n + 1);
    let mut row_idx = Vec::with_capacity(ep.nnz() + ep.n);
    col_ptr.push(0);
    for col in 0..ep.n {
        row_idx.extend_from_slice(&ep.row_idx[ep.col_ptr[col]..ep.col_ptr[col + 1]]);
        row_idx.push(col);
        col_ptr.push(row_idx.len());
    }
    (col_ptr, row_idx)
}

/// The sparse Cholesky factor of A of the deformable body `fb` (`n` = n_f) for the
/// coefficients `c`: `recycled` (a factor of A for other coefficients) factorized anew with
/// its ordering and symbolic analysis, or else a new factor, ordered by nested dissection when
/// the body has node positions, else by minimum degree.
fn elastic_iteration_factor(
    fb: &FlexibleBody,
    c: &MatrixCoefficients,
    n: usize,
    recycled: Option<SymmetricFactor>,
) -> Result<SymmetricFactor> {
    const ITEM: &str = "elastic iteration matrix";
    let values = elastic_iteration_values(fb, c);
    if let Some(mut factor) = recycled {
        factor.refactorize(ITEM, &values)?;
        return Ok(factor);
    }
    let (col_ptr, row_idx) = elastic_iteration_pattern(fb);
    let matrix = CscRef { n, col_ptr: &col_ptr, row_idx: &row_idx, values: &values };
    let ordering = match (&fb.dof_nodes, &fb.node_positions) {
        (Some(nodes), Some(positions)) => Ordering::NestedDissection { dof_nodes: nodes, positions },
        _ => Ordering::Amd,
    };
    SymmetricFactor::new(ITEM, matrix, ordering, FactorKind::Cholesky, 1)
}

/// The LU factorization of the reduced (Schur complement) system: dense for systems of at
/// most `DENSE_SYSTEM_SIZE` unknowns (the pendulum bar's is 13 x 13, whose sparse
/// factorization cost about 46,000 instructions, a dense one a few thousand), else sparse.
pub(super) enum ReducedLu {
    Dense { lu: DenseLu, pattern: SparsePattern },
    Sparse(SparseLu),
}

impl ReducedLu {
    pub(super) fn new(pattern: SparsePattern) -> std::result::Result<Self, String> {
        Ok(if pattern.n <= DENSE_SYSTEM_SIZE {
            ReducedLu::Dense { lu: DenseLu::new(pattern.n), pattern }
        } else {
            ReducedLu::Sparse(SparseLu::new(&pattern)?)
        })
    }

    pub(super) fn factorize(&mut self, values: &[f64]) -> std::result::Result<(), String> {
        match self {
            ReducedLu::Dense { lu, pattern } => lu.factorize(pattern, values),
            ReducedLu::Sparse(lu) => lu.factorize(values),
        }
    }

    pub(super) fn solve_in_place(&mut self, x: &mut [f64]) -> std::result::Result<(), String> {
        match self {
            ReducedLu::Dense { lu, .. } => lu.solve_in_place(x),
            ReducedLu::Sparse(lu) => lu.solve_in_place(x),
        }
    }
}

/// Rows of I1 (i = 0..3), of J_f0 = int rho u0~ S (i = 3..6: Ibar_jk - Ibar_kj for
/// (i, j, k) cyclic), and the symmetric S_kl = Ibar_kl + Ibar_lk of the centrifugal coupling
/// (i = 6..12: the pairs of [`SYMMETRIC_PAIRS`]), each n_f long.
pub(super) fn coupling_rows(fb: &FlexibleBody, i: usize) -> Vec<f64> {
    let n = fb.elastic_count;
    let ibar = |k: usize, l: usize| &fb.ibar[(3 * k + l) * n..(3 * k + l + 1) * n];
    if i < 3 {
        return fb.i1[i * n..(i + 1) * n].to_vec();
    }
    if i >= 6 {
        let (k, l) = SYMMETRIC_PAIRS[i - 6];
        return ibar(k, l).iter().zip(ibar(l, k)).map(|(x, y)| x + y).collect();
    }
    let i = i - 3;
    let (j, k) = ((i + 1) % 3, (i + 2) % 3);
    ibar(j, k).iter().zip(ibar(k, j)).map(|(x, y)| x - y).collect()
}

/// The pairs (k, l) of the symmetric rows S_kl of `coupling_rows` 6..12.
pub(super) const SYMMETRIC_PAIRS: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)];

impl Block {
    /// Makes `current` a factorization of A for the coefficients `c`, reusing a kept one.
    pub(super) fn select_factor(&mut self, fb: &FlexibleBody, c: &MatrixCoefficients) -> Result<()> {
        let k = key(c);
        if let Some(pos) = self.factors.iter().position(|f| same_key(&f.key, &k)) {
            self.current = pos;
            return Ok(());
        }
        let only_identity = c.mass == 0.0 && c.velocity == 0.0 && c.position == 0.0;
        // The factor that makes room for the new one lends it its symbolic analysis.
        let evicted = if self.factors.len() >= 2 { self.factors.pop().and_then(|f| f.factor) } else { None };
        let mut factor = if only_identity {
            BlockFactor::new(k, None, c.scale * c.elastic_identity)
        } else {
            BlockFactor::new(k, Some(elastic_iteration_factor(fb, c, self.n, evicted)?), 0.0)
        };
        let mut influence = Vec::with_capacity(12 * self.n);
        for i in 0..12 {
            influence.extend(coupling_rows(fb, i));
        }
        factor.solve_in_place(&mut influence)?;
        factor.influence = influence;
        self.factors.truncate(1);
        self.factors.insert(0, factor);
        self.current = 0;
        Ok(())
    }
}
