//! Linear solves with the elastic coordinates of large deformable bodies condensed out through
//! a constant factorized matrix: what M_ff and K_ff being constant allows (seed section 3,
//! "computational strategy", and section 5, eq. 41, where the constant M_ff is the pivot that
//! decouples the elastic accelerations).
//!
//! Split the unknowns of the Newton system N x = r into F (the elastic coordinates of the
//! condensed bodies) and S (everything else: rigid bodies, reference coordinates, multipliers).
//! The iteration matrix keeps N_SS, N_SF and N_FS as assembled, and replaces N_FF, body by body,
//! by the constant A = s (m M_ff + v D_ff + p K_ff + i I) with the coefficients of the solve
//! (generalized-alpha: m = beta', v = gamma', p = 1; the acceleration system: m = 1). What it
//! leaves out of N_FF (the velocity-dependent inertia terms sum c_kl I_kl, the geometric
//! stiffness, the constraint Hessians at elastic markers) is small against A at the step sizes
//! of an implicit integration, so modified Newton still converges, to the exact solution: the
//! residual is exact. A is factorized (sparse Cholesky) once per set of coefficients and kept.
//!
//! With the coupling columns J (the S unknowns that touch F: the body's reference coordinates,
//! the multipliers of joints at its elastic markers, ...) and Z = A^-1 N_FJ (|J| solves, when
//! the iteration matrix is refreshed), the Schur complement S_hat = N_SS - N_SF Z differs from
//! N_SS only in the dense J x J block, and is factorized by sparse LU. A solve then costs one
//! solve with A per body, the small LU solve and a dense product with Z:
//!   y = A^-1 r_F,   S_hat x_S = r_S - N_SF y,   x_F = y - Z x_J.

use crate::assembly::MatrixCoefficients;
use crate::body::flexible::{dot, FlexibleBody, REFERENCE_COORDINATES};
use crate::body::{is_condensed, BodyKind};
use crate::error::{FlexmbdError, Result};
use crate::linalg::dense::{DenseLu, DENSE_SYSTEM_SIZE};
use crate::linalg::simd::{dot4, update4, GROUP};
use crate::linalg::sparse::{PatternBuilder, SparseLu, SparsePattern};
use crate::linalg::symmetric::{CscRef, FactorKind, Ordering, SymmetricFactor};
use crate::math::Vec3;
use crate::system::model::Model;

/// The coefficients that define A (m, v, p, i, s).
type Key = [f64; 5];

fn key(c: &MatrixCoefficients) -> Key {
    [c.mass, c.velocity, c.position, c.identity, c.scale]
}

/// Whether a factorization of A made for the coefficients `kept` serves `wanted`: each equal
/// to round-off, as the integrator's step sizes.
fn same_key(kept: &Key, wanted: &Key) -> bool {
    kept.iter().zip(wanted).all(|(&a, &b)| crate::math::equal_to_round_off(a, b))
}

/// The entries (local f, value index) of one coupling unknown j: N_{f, j}, then N_{j, f}.
type Coupling = (Vec<(usize, usize)>, Vec<(usize, usize)>);

/// A factorized A of one body for one set of coefficients.
struct BlockFactor {
    key: Key,
    /// Cholesky factor, or None when A = s i I (only the identity term).
    factor: Option<SymmetricFactor>,
    /// s i when A is a multiple of the identity.
    diagonal: f64,
    /// A^-1 [I1^T, J_f0^T, S] (n x 12, column-major): the solves of the coupling with the
    /// body's own reference coordinates, made once per factorization (see `coupling_rows` and
    /// `reference_coupling`).
    influence: Vec<f64>,
    /// A^-1 Q of the first vectors of the block's coupling basis Q (n each, column-major):
    /// solved when a factorization first needs them.
    basis_solved: Vec<f64>,
    /// The deformation part dJ^T of the rotation coupling at the last solves with it (3 n,
    /// empty before), the rows J_f = J_f0 + dJ of the deformed body there and their solves
    /// A^-1 J_f^T (see `reference_coupling`).
    deformation: Vec<f64>,
    deformed_rows: Vec<f64>,
    deformed_solved: Vec<f64>,
    /// q_f of `deformation`, and the smallest norm of the rows J_f0 + dJ there (the cheap
    /// test of `reference_coupling`).
    deformation_at: Vec<f64>,
    deformation_rows: f64,
    /// The products G = U^T V of the row vectors U with the column vectors V of the
    /// structured coupling (`ReferenceCoupling`), ROW_VECTORS x COLUMN_VECTORS row-major;
    /// empty until made, and made again when dJ is solved again. `gram_deformed`: with dJ.
    gram: Vec<f64>,
    gram_deformed: bool,
    /// Scratch of single solves (allocated at the first).
    memory: Option<faer::dyn_stack::MemBuffer>,
}

impl BlockFactor {
    /// Solves for one or more right-hand sides (column-major).
    fn solve_in_place(&mut self, x: &mut [f64]) -> Result<()> {
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

/// One condensed body: its F range, coupling columns and factorizations.
struct Block {
    /// Body index.
    body: usize,
    /// First global index of its elastic coordinates.
    first: usize,
    /// n_f.
    n: usize,
    /// Coupling unknowns J (global indices in S).
    coupling: Vec<usize>,
    /// Per coupling column j: (local row f, value index) of the entries N_{f, J[j]}.
    column_entries: Vec<Vec<(usize, usize)>>,
    /// Per coupling row j: (local column f, value index) of the entries N_{J[j], f}.
    row_entries: Vec<Vec<(usize, usize)>>,
    /// The values of `row_entries` at the last factorization (the solves need N_JF after the
    /// global values have been overwritten).
    row_values: Vec<Vec<f64>>,
    /// Reduced value index of each (J[a], J[b]) pair, row-major |J| x |J|.
    schur_entries: Vec<usize>,
    /// Z = A^-1 N_FJ, column-major n x |J|.
    z: Vec<f64>,
    /// W = N_FJ as eliminated (A Z = W), column-major n x |J| (only with `keep_image`).
    w: Vec<f64>,
    /// W x_J of the last solve (n; only with `keep_image`), formed from `last_x` when asked.
    image: Vec<f64>,
    /// x_J of the last solve (only with `keep_image`; empty after a factorization).
    last_x: Vec<f64>,
    /// Per coupling row: whether its entries are all n_f columns in order (then the products
    /// with it are plain dot products).
    dense_rows: Vec<bool>,
    /// Factorizations of A, most recently used first (at most two).
    factors: Vec<BlockFactor>,
    /// Which factor the current Z belongs to.
    current: usize,
    /// Position in `coupling` of each of the body's reference coordinates [R, p].
    reference: [usize; 7],
    /// Orthonormal basis Q of the coupling columns N_Fj met so far (other than the reference
    /// coordinates), n each, column-major; see `other_couplings`.
    basis: Vec<f64>,
    /// The support of those columns (the union of their entries; the basis vectors, being
    /// combinations of them, are zero elsewhere), made at the first use, with the position of
    /// each coordinate in it (usize::MAX outside), and the basis on the support alone: the
    /// Gram-Schmidt products run over the support (a joint at a face of 16 nodes of the 1k bar:
    /// 48 of its 960 coordinates).
    support: Option<Vec<usize>>,
    support_position: Vec<usize>,
    basis_compact: Vec<f64>,
    /// The rows of `coupling_rows` (12 n: I1, J_f0, S_kl), then T = S_00 + S_11 + S_22 and
    /// the nine Ibar_kl (10 n), made at the first use (see `ReferenceCoupling`).
    reference_rows: Vec<f64>,
    /// The coupling with the reference coordinates of the last factorization, applied from
    /// kept vectors in the solves; None when it was formed in `z`, `w` and `row_values`
    /// (the exact solver, and reference rows that are not dense).
    structured: Option<ReferenceCoupling>,
    /// Whether a structured coupling is applied from the kept vectors (else formed; false
    /// only in tests, which compare the two).
    apply_kept: bool,
    /// Scratch of dJ^T (3 n).
    deformation: Vec<f64>,
    /// Bound of the norms of the body's antisymmetric matrices (made at the first use).
    antisymmetric_bound: Option<f64>,
    /// Body-frame angular velocity of the velocity part of the structured reference coupling
    /// (see `CondensedSolver::set_angular_velocities`; zero until set).
    angular_velocity: Vec3,
}

/// Largest size of a block's coupling basis (6 per marker on the body would need it).
const BASIS_LIMIT: usize = 24;

/// A coupling column is taken from the basis when the part of it outside the basis is at most
/// this fraction of it (round-off: the columns of a marker coupling lie in the basis exactly).
const SPAN_TOLERANCE: f64 = 1e-10;

/// A factorization keeps A^-1 dJ^T of the deformation part of the rotation coupling while dJ
/// differs from the one solved by at most this fraction of the row J_f0 + dJ (see
/// `reference_coupling`).
const DEFORMATION_TOLERANCE: f64 = 1e-2;

/// Numbers of the row and column vectors of [`ReferenceCoupling`].
const ROW_VECTORS: usize = 16;
const COLUMN_VECTORS: usize = 12;

/// The structured coupling of a condensed body with its seven reference coordinates
/// (`Block::reference_coupling`), as combinations of kept vectors of n_f entries whose
/// coefficients depend on the rotation and angular velocity only:
/// - the rows N_jF: on the row vectors U = [I1 (3), J_f (3), T, Ibar_kl (9)], with J_f the
///   rows of J_f0 + dJ (deformed) or J_f0, and T = S_00 + S_11 + S_22;
/// - the columns as eliminated N_Fj: on [I1 (3), J_f (3), S_kl (6)], and their solves
///   Z_j = A^-1 N_Fj on the column vectors V = A^-1 of the same.
///
/// A solve applies them as they are (U^T y: sixteen dot products, V (C x_ref): twelve vector
/// updates) instead of forming the seven rows and columns at every refresh of the iteration
/// matrix (195 multiply-adds per elastic coordinate, more than the solves' extra ones), and
/// the block N_JF Z of the reference rows and columns is R G C with the kept G = U^T V.
#[derive(Clone, Copy, Debug)]
struct ReferenceCoupling {
    /// R: the coefficients of the rows of the reference coordinates (in the order of
    /// `Block::reference`) on the row vectors.
    rows: [[f64; ROW_VECTORS]; 7],
    /// C: the coefficients of the columns on the column vectors, `columns[v][b]`.
    columns: [[f64; 7]; COLUMN_VECTORS],
    /// Whether J_f is that of the deformed body (the factor's `deformed_rows`).
    deformed: bool,
    /// The vectors with nonzero coefficients are the first `row_count` and `column_count`
    /// (6 each without the velocity part).
    row_count: usize,
    column_count: usize,
}

/// Row vector k of [`ReferenceCoupling`] (`rows`: `Block::reference_rows`, m = n_f).
fn row_vector<'a>(rows: &'a [f64], factor: &'a BlockFactor, deformed: bool, m: usize, k: usize) -> &'a [f64] {
    match k {
        3..6 if deformed => &factor.deformed_rows[(k - 3) * m..(k - 2) * m],
        0..6 => &rows[k * m..(k + 1) * m],
        _ => &rows[(k + 6) * m..(k + 7) * m],
    }
}

/// Column vector v of [`ReferenceCoupling`]: A^-1 of the column as eliminated.
fn column_vector(factor: &BlockFactor, deformed: bool, m: usize, v: usize) -> &[f64] {
    match v {
        3..6 if deformed => &factor.deformed_solved[(v - 3) * m..(v - 2) * m],
        _ => &factor.influence[v * m..(v + 1) * m],
    }
}

/// Column v as eliminated of [`ReferenceCoupling`] (the rows of `coupling_rows`, or J_f0 + dJ).
fn eliminated_vector<'a>(
    rows: &'a [f64],
    factor: &'a BlockFactor,
    deformed: bool,
    m: usize,
    v: usize,
) -> &'a [f64] {
    match v {
        3..6 if deformed => &factor.deformed_rows[(v - 3) * m..(v - 2) * m],
        _ => &rows[v * m..(v + 1) * m],
    }
}

/// The dot products of `y` with the vectors `vector(0..count)`, four at a time.
fn dots<'a, const N: usize>(count: usize, vector: impl Fn(usize) -> &'a [f64], y: &[f64]) -> [f64; N] {
    let mut out = [0.0; N];
    for g in (0..count).step_by(GROUP) {
        let k = GROUP.min(count - g);
        let sums = dot4(std::array::from_fn(|i| vector(g + i.min(k - 1))), y);
        out[g..g + k].copy_from_slice(&sums[..k]);
    }
    out
}

/// out -= sum_v x[v] vector(v) over v < count, four vectors at a time.
fn subtract_combination<'a>(out: &mut [f64], count: usize, vector: impl Fn(usize) -> &'a [f64], x: &[f64]) {
    for g in (0..count).step_by(GROUP) {
        let k = GROUP.min(count - g);
        let coefficients = std::array::from_fn(|i| if i < k { x[g + i] } else { 0.0 });
        update4(out, coefficients, std::array::from_fn(|i| vector(g + i.min(k - 1))));
    }
}

/// The LU factorization of the reduced (Schur complement) system: dense for systems of at
/// most `DENSE_SYSTEM_SIZE` unknowns (the pendulum bar's is 13 x 13, whose sparse
/// factorization cost about 46,000 instructions, a dense one a few thousand), else sparse.
enum ReducedLu {
    Dense { lu: DenseLu, pattern: SparsePattern },
    Sparse(SparseLu),
}

impl ReducedLu {
    fn new(pattern: SparsePattern) -> std::result::Result<Self, String> {
        Ok(if pattern.n <= DENSE_SYSTEM_SIZE {
            ReducedLu::Dense { lu: DenseLu::new(pattern.n), pattern }
        } else {
            ReducedLu::Sparse(SparseLu::new(&pattern)?)
        })
    }

    fn factorize(&mut self, values: &[f64]) -> std::result::Result<(), String> {
        match self {
            ReducedLu::Dense { lu, pattern } => lu.factorize(pattern, values),
            ReducedLu::Sparse(lu) => lu.factorize(values),
        }
    }

    fn solve_in_place(&mut self, x: &mut [f64]) -> std::result::Result<(), String> {
        match self {
            ReducedLu::Dense { lu, .. } => lu.solve_in_place(x),
            ReducedLu::Sparse(lu) => lu.solve_in_place(x),
        }
    }
}

/// The condensed linear solver of a model (one per kind of matrix kept: Newton iteration
/// matrix, projection / acceleration matrix).
pub struct CondensedSolver {
    blocks: Vec<Block>,
    /// Global index -> reduced index (usize::MAX for condensed unknowns).
    reduced_of: Vec<usize>,
    /// Reduced index -> global index.
    global_of: Vec<usize>,
    /// For each reduced value, the global value index it copies (usize::MAX for the fill of
    /// the J x J blocks).
    copy_from: Vec<usize>,
    reduced_values: Vec<f64>,
    lu: ReducedLu,
    /// Whether the coupling with the reference coordinates comes from its mass part (an
    /// iteration matrix) or as assembled (exact: for the direct solves of the projection and
    /// acceleration systems).
    approximate_reference: bool,
    /// Scratch: per block its y = A^-1 r_F (n each, concatenated), reduced rhs.
    y: Vec<f64>,
    rhs: Vec<f64>,
    factorized: bool,
    /// Whether the solves keep W x_J of each block (see `coupling_images`).
    keep_image: bool,
}

impl std::fmt::Debug for CondensedSolver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "CondensedSolver({} bodies, reduced n = {})", self.blocks.len(), self.global_of.len())
    }
}

fn flexible(model: &Model, body: usize) -> &FlexibleBody {
    match &model.bodies[body].kind {
        BodyKind::Flexible(f) => f,
        _ => unreachable!("condensed bodies are flexible"),
    }
}

impl CondensedSolver {
    /// Lays out the split of the model's Newton matrix (pattern `model.layout.pattern`). With
    /// `approximate_reference`, the coupling of each body with its reference coordinates is
    /// taken from its mass and velocity parts without solves (for iteration matrices, see
    /// `factorize`); else as assembled (exact).
    pub fn new(model: &Model, approximate_reference: bool) -> Result<Self> {
        Self::with_images(model, approximate_reference, false)
    }

    /// [`CondensedSolver::new`]; with `keep_image`, every solve also keeps W x_J of each block
    /// (see [`CondensedSolver::coupling_images`]).
    pub fn with_images(model: &Model, approximate_reference: bool, keep_image: bool) -> Result<Self> {
        let pattern = &model.layout.pattern;
        let n = pattern.n;
        let mut reduced_of = vec![0usize; n];
        let mut blocks = Vec::new();
        for (bi, body) in model.bodies.iter().enumerate() {
            if is_condensed(&body.kind) {
                let fb = flexible(model, bi);
                let first = body.offset + REFERENCE_COORDINATES;
                for k in first..first + fb.elastic_count {
                    reduced_of[k] = usize::MAX;
                }
                blocks.push((bi, first, fb.elastic_count));
            }
        }
        let mut global_of = Vec::new();
        for (g, r) in reduced_of.iter_mut().enumerate() {
            if *r != usize::MAX {
                *r = global_of.len();
                global_of.push(g);
            }
        }
        let in_block = |g: usize| blocks.iter().position(|&(_, first, m)| g >= first && g < first + m);
        // Coupling entries of every block, from the global pattern.
        let mut coupling_sets: Vec<std::collections::BTreeMap<usize, Coupling>> =
            vec![Default::default(); blocks.len()];
        let mut builder = PatternBuilder::new(global_of.len());
        for c in 0..n {
            for k in pattern.col_ptr[c]..pattern.col_ptr[c + 1] {
                let r = pattern.row_idx[k];
                match (in_block(r), in_block(c)) {
                    (None, None) => builder.add_entry(reduced_of[r], reduced_of[c]),
                    (Some(b), None) => {
                        coupling_sets[b].entry(c).or_default().0.push((r - blocks[b].1, k));
                    }
                    (None, Some(b)) => {
                        coupling_sets[b].entry(r).or_default().1.push((c - blocks[b].1, k));
                    }
                    (Some(_), Some(_)) => {}
                }
            }
        }
        for set in &coupling_sets {
            let j: Vec<usize> = set.keys().map(|&g| reduced_of[g]).collect();
            builder.add_block(&j, &j);
        }
        builder.add_diagonal(&(0..global_of.len()).collect::<Vec<_>>());
        let reduced_pattern = builder.build();
        let mut copy_from = vec![usize::MAX; reduced_pattern.nnz()];
        for c in 0..n {
            if reduced_of[c] == usize::MAX {
                continue;
            }
            for k in pattern.col_ptr[c]..pattern.col_ptr[c + 1] {
                let r = pattern.row_idx[k];
                if reduced_of[r] != usize::MAX {
                    copy_from[reduced_pattern.index(reduced_of[r], reduced_of[c])] = k;
                }
            }
        }
        let lu = ReducedLu::new(reduced_pattern.clone()).map_err(|detail| FlexmbdError::SingularMatrix {
            time: 0.0,
            context: "symbolic analysis of the condensed Newton matrix".to_string(),
            detail,
        })?;
        let mut out_blocks = Vec::with_capacity(blocks.len());
        let mut y_len = 0;
        for ((bi, first, m), set) in blocks.into_iter().zip(coupling_sets) {
            let coupling: Vec<usize> = set.keys().copied().collect();
            let reduced: Vec<usize> = coupling.iter().map(|&g| reduced_of[g]).collect();
            let schur_entries = reduced_pattern.block_indices(&reduced, &reduced);
            let (column_entries, row_entries): (Vec<_>, Vec<Vec<(usize, usize)>>) = set.into_values().unzip();
            let row_values = row_entries.iter().map(|e| vec![0.0; e.len()]).collect();
            let offset = model.bodies[bi].offset;
            let mut reference = [0usize; 7];
            for (r, slot) in reference.iter_mut().enumerate() {
                *slot = coupling.iter().position(|&g| g == offset + r).ok_or_else(|| {
                    FlexmbdError::InvalidModel {
                        item: format!("body '{}'", model.bodies[bi].name),
                        message: "condensed body without reference coupling".to_string(),
                    }
                })?;
            }
            y_len += m;
            out_blocks.push(Block {
                body: bi,
                first,
                n: m,
                z: vec![0.0; m * coupling.len()],
                w: if keep_image { vec![0.0; m * coupling.len()] } else { Vec::new() },
                image: if keep_image { vec![0.0; m] } else { Vec::new() },
                last_x: Vec::new(),
                dense_rows: row_entries
                    .iter()
                    .map(|e| e.len() == m && e.iter().enumerate().all(|(i, &(f, _))| f == i))
                    .collect(),
                coupling,
                column_entries,
                row_entries,
                row_values,
                schur_entries,
                factors: Vec::new(),
                current: 0,
                reference,
                basis: Vec::new(),
                support: None,
                support_position: Vec::new(),
                basis_compact: Vec::new(),
                reference_rows: Vec::new(),
                structured: None,
                apply_kept: true,
                deformation: Vec::new(),
                antisymmetric_bound: None,
                angular_velocity: Vec3::ZERO,
            });
        }
        Ok(CondensedSolver {
            blocks: out_blocks,
            reduced_values: vec![0.0; reduced_pattern.nnz()],
            rhs: vec![0.0; global_of.len()],
            y: vec![0.0; y_len],
            reduced_of,
            global_of,
            copy_from,
            lu,
            approximate_reference,
            factorized: false,
            keep_image,
        })
    }

    /// Per condensed body (body index): W x_J of the last solve, where W = N_FJ are the coupling columns the factorization
    /// eliminated with, so that the elastic part x_F of that solve has A x_F = b_F - W x_J
    /// (b: the right-hand side). Empty slices unless made `with_images`, and after a
    /// factorization until the next solve.
    pub fn coupling_images(&mut self) -> impl Iterator<Item = (usize, &[f64])> + '_ {
        for block in &mut self.blocks {
            let m = block.n;
            if block.last_x.is_empty() {
                block.image.clear();
                continue;
            }
            block.image.resize(m, 0.0);
            block.image.iter_mut().for_each(|v| *v = 0.0);
            if let Some(rc) = &block.structured {
                // The reference columns as eliminated: [I1, J_f, S_kl] (C x_ref).
                let (rows, factor) = (&block.reference_rows, &block.factors[block.current]);
                let x_ref = block.reference.map(|a| -block.last_x[a]);
                subtract_combination(
                    &mut block.image,
                    rc.column_count,
                    |v| eliminated_vector(rows, factor, rc.deformed, m, v),
                    &rc.combination(&x_ref),
                );
            }
            for (j, (&xj, w)) in block.last_x.iter().zip(block.w.chunks_exact(m)).enumerate() {
                if xj != 0.0 && !block.applied_from_kept(j) {
                    block.image.iter_mut().zip(w).for_each(|(o, wv)| *o += wv * xj);
                }
            }
        }
        self.blocks.iter().map(|b| (b.body, &b.image[..]))
    }

    /// Sets the body-frame angular velocity of each condensed body, from the coordinates `q`
    /// and velocities `qd`, for the velocity part of the structured coupling with its reference
    /// coordinates in the next factorizations (see `reference_coupling`). The integrator
    /// passes those of the last converged state: the predictor's reference velocities carry
    /// the error of its accelerations, which the elastic vibration of the frame's nodes makes
    /// large (0.4 rad/s on the 1k pendulum bar swinging at 0.1 rad/s).
    pub fn set_angular_velocities(&mut self, model: &Model, q: &[f64], qd: &[f64]) {
        for block in &mut self.blocks {
            let o = model.bodies[block.body].offset;
            let p = [q[o + 3], q[o + 4], q[o + 5], q[o + 6]];
            let pd = [qd[o + 3], qd[o + 4], qd[o + 5], qd[o + 6]];
            let l = crate::math::euler::l_matrix(&p);
            block.angular_velocity =
                Vec3(std::array::from_fn(|i| 2.0 * (0..4).map(|k| l[i][k] * pd[k]).sum::<f64>()));
        }
    }

    /// Size of the reduced (Schur complement) system.
    pub fn reduced_size(&self) -> usize {
        self.global_of.len()
    }

    /// Factorizes the iteration matrix with the assembled `values` (global pattern) and the
    /// constant blocks A for the coefficients `c`, at coordinates `q`.
    ///
    /// With `approximate_reference`, the coupling of each body with its own reference
    /// coordinates enters through its mass part s m [I1^T A^T, J_f^T 2L] (and the
    /// transpose), with J_f = int rho u~ S = J_f0 + dJ(q_f): the undeformed part of Z comes
    /// from the influence A^-1 [I1^T, J_f0^T] kept with the factorization, the deformation
    /// part from three solves; and through the velocity part of the undeformed body at the
    /// angular velocity of `set_angular_velocities` (relative size h w against the mass part:
    /// with it a step of the 1k pendulum bar takes 2.85 instead of 2.98 Newton iterations over
    /// 3 s, see `reference_coupling`). The position part left out is of relative size h^2 (g / L);
    /// the other couplings (joints and forces at elastic markers) are taken as assembled, one
    /// solve per coupling column.
    pub fn factorize(
        &mut self,
        model: &Model,
        values: &[f64],
        c: &MatrixCoefficients,
        q: &[f64],
    ) -> Result<()> {
        self.factorized = false;
        for (r, &g) in self.reduced_values.iter_mut().zip(&self.copy_from) {
            *r = if g == usize::MAX { 0.0 } else { values[g] };
        }
        for block in &mut self.blocks {
            block.last_x.clear();
            block.structured = None;
            let fb = flexible(model, block.body);
            block.select_factor(fb, c)?;
            let (m, nj) = (block.n, block.coupling.len());
            let structured = self.approximate_reference;
            let reference = block.reference;
            let is_reference = |j: usize| structured && reference.contains(&j);
            // Z = A^-1 N_FJ of the other coupling columns.
            let others: Vec<usize> = (0..nj).filter(|&j| !is_reference(j)).collect();
            block.other_couplings(&others, values)?;
            for (j, (stored, entries)) in block.row_values.iter_mut().zip(&block.row_entries).enumerate() {
                if !is_reference(j) {
                    for (v, &(_, k)) in stored.iter_mut().zip(entries) {
                        *v = values[k];
                    }
                }
            }
            let reference_block = if structured {
                block.reference_coupling(fb, c, &q[model.bodies[block.body].offset..])?
            } else {
                None
            };
            // S_hat(J, J) -= N_JF Z: the reference block, when structured, from
            // `reference_coupling`, the other rows against the reference columns and the
            // reference rows against the other columns through the kept vectors; the rest a
            // dense row against four columns of Z at a time.
            let column = |b: usize| &block.z[b * m..(b + 1) * m];
            let all: Vec<usize> = (0..nj).collect();
            let structured = block.structured;
            if let Some(rb) = &reference_block {
                for (ra, &ja) in block.reference.iter().enumerate() {
                    for (rc, &jb) in block.reference.iter().enumerate() {
                        self.reduced_values[block.schur_entries[ja * nj + jb]] -= rb[ra][rc];
                    }
                }
            }
            let factor = &block.factors[block.current];
            for (a, entries) in block.row_entries.iter().enumerate() {
                if block.applied_from_kept(a) {
                    continue;
                }
                let stored = &block.row_values[a];
                let schur = &block.schur_entries[a * nj..(a + 1) * nj];
                let columns = if structured.is_some() { &others } else { &all };
                if block.dense_rows[a] {
                    // Groups of four columns; the last group filled up with its last column.
                    for group in columns.chunks(GROUP) {
                        let count = group.len();
                        let sums = dot4(std::array::from_fn(|i| column(group[i.min(count - 1)])), stored);
                        for (&b, sum) in group.iter().zip(sums) {
                            self.reduced_values[schur[b]] -= sum;
                        }
                    }
                } else {
                    for &b in columns {
                        self.reduced_values[schur[b]] -= gather_dot(entries, stored, column(b));
                    }
                }
                if let Some(rc) = &structured {
                    // N_aF Z_ref = (N_aF V) C.
                    let vector = |v: usize| column_vector(factor, rc.deformed, m, v);
                    let products: [f64; COLUMN_VECTORS] = if block.dense_rows[a] {
                        dots(rc.column_count, vector, stored)
                    } else {
                        std::array::from_fn(|v| {
                            if v < rc.column_count {
                                gather_dot(entries, stored, vector(v))
                            } else {
                                0.0
                            }
                        })
                    };
                    for (b, &jb) in block.reference.iter().enumerate() {
                        let sum: f64 = products.iter().zip(&rc.columns).map(|(p, col)| p * col[b]).sum();
                        self.reduced_values[schur[jb]] -= sum;
                    }
                }
            }
            if let Some(rc) = &structured {
                // N_ref,F Z_b = R (U^T Z_b) for the other columns b.
                for &b in &others {
                    let products: [f64; ROW_VECTORS] = dots(
                        rc.row_count,
                        |k| row_vector(&block.reference_rows, factor, rc.deformed, m, k),
                        column(b),
                    );
                    for (row, &ja) in rc.rows.iter().zip(&block.reference) {
                        let sum: f64 = products.iter().zip(row).map(|(p, r)| p * r).sum();
                        self.reduced_values[block.schur_entries[ja * nj + b]] -= sum;
                    }
                }
            }
        }
        self.lu.factorize(&self.reduced_values).map_err(|detail| FlexmbdError::SingularMatrix {
            time: 0.0,
            context: "condensed Newton matrix".to_string(),
            detail,
        })?;
        self.factorized = true;
        Ok(())
    }

    /// Solves in place (global vector) with the last factorization.
    pub fn solve_in_place(&mut self, x: &mut [f64]) -> std::result::Result<(), String> {
        if !self.factorized {
            return Err("no valid factorization".to_string());
        }
        for (r, &g) in self.rhs.iter_mut().zip(&self.global_of) {
            *r = x[g];
        }
        let mut offset = 0;
        for block in &mut self.blocks {
            let y = &mut self.y[offset..offset + block.n];
            y.copy_from_slice(&x[block.first..block.first + block.n]);
            block.factors[block.current].solve_in_place(y).map_err(|e| e.to_string())?;
            let y = &*y;
            let reduced = |a: usize| self.reduced_of[block.coupling[a]];
            if let Some(rc) = &block.structured {
                // The reference rows R (U^T y).
                let (m, factor) = (block.n, &block.factors[block.current]);
                let products: [f64; ROW_VECTORS] =
                    dots(rc.row_count, |k| row_vector(&block.reference_rows, factor, rc.deformed, m, k), y);
                for (row, &a) in rc.rows.iter().zip(&block.reference) {
                    self.rhs[reduced(a)] -= products.iter().zip(row).map(|(p, r)| p * r).sum::<f64>();
                }
            }
            // The other rows: dense ones four at a time (one pass over y for four of them).
            let mut dense = [0usize; GROUP];
            let mut count = 0;
            for (a, entries) in block.row_entries.iter().enumerate() {
                if block.applied_from_kept(a) {
                    continue;
                }
                let stored = &block.row_values[a];
                if !block.dense_rows[a] {
                    self.rhs[reduced(a)] -= gather_dot(entries, stored, y);
                    continue;
                }
                dense[count] = a;
                count += 1;
                if count == GROUP {
                    let rows = dense.map(|a| &block.row_values[a][..]);
                    for (&a, sum) in dense.iter().zip(dot4(rows, y)) {
                        self.rhs[reduced(a)] -= sum;
                    }
                    count = 0;
                }
            }
            if count > 0 {
                // The last group filled up with its last row.
                let rows: [&[f64]; GROUP] =
                    std::array::from_fn(|i| &block.row_values[dense[i.min(count - 1)]][..]);
                for (&a, sum) in dense[..count].iter().zip(dot4(rows, y)) {
                    self.rhs[reduced(a)] -= sum;
                }
            }
            offset += block.n;
        }
        self.lu.solve_in_place(&mut self.rhs)?;
        for (&r, &g) in self.rhs.iter().zip(&self.global_of) {
            x[g] = r;
        }
        let mut offset = 0;
        for block in &mut self.blocks {
            let y = &self.y[offset..offset + block.n];
            let out = &mut x[block.first..block.first + block.n];
            out.copy_from_slice(y);
            let x_j = |a: usize| self.rhs[self.reduced_of[block.coupling[a]]];
            if self.keep_image {
                block.last_x.clear();
                block.last_x.extend((0..block.coupling.len()).map(x_j));
            }
            // out -= Z x_J: the reference columns V (C x_ref), the others four columns of Z at
            // a time (one pass over out for four).
            let n = block.n;
            if let Some(rc) = &block.structured {
                let factor = &block.factors[block.current];
                let x_ref = block.reference.map(x_j);
                subtract_combination(
                    out,
                    rc.column_count,
                    |v| column_vector(factor, rc.deformed, n, v),
                    &rc.combination(&x_ref),
                );
            }
            let column = |j: usize| &block.z[j * n..(j + 1) * n];
            let mut group = [(0usize, 0.0f64); GROUP];
            let mut count = 0;
            for j in 0..block.coupling.len() {
                let xj = x_j(j);
                if xj != 0.0 && !block.applied_from_kept(j) {
                    group[count] = (j, xj);
                    count += 1;
                    if count == GROUP {
                        update4(out, group.map(|(_, x)| x), group.map(|(j, _)| column(j)));
                        count = 0;
                    }
                }
            }
            for &(j, xj) in &group[..count] {
                for (o, zv) in out.iter_mut().zip(column(j)) {
                    *o -= zv * xj;
                }
            }
            offset += block.n;
        }
        if !crate::math::all_finite(x) {
            return Err("the matrix is singular (the solution is not finite)".to_string());
        }
        Ok(())
    }
}

impl ReferenceCoupling {
    /// C x: the coefficients on the column vectors of the reference columns' values `x`.
    fn combination(&self, x: &[f64; 7]) -> [f64; COLUMN_VECTORS] {
        std::array::from_fn(|v| self.columns[v].iter().zip(x).map(|(c, x)| c * x).sum())
    }
}

/// sum_e values[e] x[f_e] over the entries (f_e, _) of a coupling row, with four partial sums
/// (a single sum is a chain of dependent additions, latency-bound on rows of n_f entries).
fn gather_dot(entries: &[(usize, usize)], values: &[f64], x: &[f64]) -> f64 {
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

/// Rows of I1 (i = 0..3), of J_f0 = int rho u0~ S (i = 3..6: Ibar_jk - Ibar_kj for
/// (i, j, k) cyclic), and the symmetric S_kl = Ibar_kl + Ibar_lk of the centrifugal coupling
/// (i = 6..12: the pairs of [`SYMMETRIC_PAIRS`]), each n_f long.
fn coupling_rows(fb: &FlexibleBody, i: usize) -> Vec<f64> {
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
const SYMMETRIC_PAIRS: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)];

/// Coefficients over the S_kl of [`SYMMETRIC_PAIRS`] of the velocity part of the coupling
/// column of p_c of the undeformed body: sum_m dfw_m (2 L)_mc, with the derivative of the
/// elastic rows' inertia force by the angular velocity w,
/// dfw_m = sum_(k != m) (w_k S_km - w_m S_kk) (`body::flexible`'s velocity (f, p) block at
/// q_f = 0, qf_dot = 0).
fn centrifugal_weights(w: &Vec3, two_l: &[[f64; 4]; 3], col: usize) -> [f64; 6] {
    let mut g = [0.0; 6];
    for (slot, &(k, l)) in SYMMETRIC_PAIRS.iter().enumerate() {
        g[slot] = if k == l {
            -(0..3).filter(|&m| m != k).map(|m| w[m] * two_l[m][col]).sum::<f64>()
        } else {
            w[k] * two_l[l][col] + w[l] * two_l[k][col]
        };
    }
    g
}

impl Block {
    /// Whether coupling unknown `j` is a reference coordinate whose row and column the solves
    /// apply from the kept vectors of the structured coupling (not from `z`, `w` and
    /// `row_values`).
    fn applied_from_kept(&self, j: usize) -> bool {
        self.structured.is_some() && self.reference.contains(&j)
    }

    /// Z = A^-1 N_Fj of the coupling columns `columns` that are not the body's reference
    /// coordinates (joints and forces at its markers, and through them other bodies). A
    /// marker's kinematics depends on q_f through A(p) times constant body-frame rows of its
    /// Jacobians, so these columns stay in a space of dimension at most 6 per marker: each
    /// column is split over an orthonormal basis Q of the columns met so far (Gram-Schmidt,
    /// two passes, over the columns' support), a part outside it extends Q, and Z_j =
    /// (A^-1 Q) c_j with A^-1 Q solved once per factorization of A. After the first
    /// factorization, these columns need no solves.
    /// The reference columns of an exact solver (not in a fixed space) and columns met when
    /// Q is full are solved directly.
    fn other_couplings(&mut self, columns: &[usize], values: &[f64]) -> Result<()> {
        if columns.is_empty() {
            return Ok(());
        }
        let m = self.n;
        if self.support.is_none() {
            let mut support: Vec<usize> = columns
                .iter()
                .filter(|j| !self.reference.contains(j))
                .flat_map(|&j| self.column_entries[j].iter().map(|e| e.0))
                .collect();
            support.sort_unstable();
            support.dedup();
            self.support_position = vec![usize::MAX; m];
            for (i, &f) in support.iter().enumerate() {
                self.support_position[f] = i;
            }
            self.support = Some(support);
        }
        let support = self.support.as_deref().unwrap_or(&[]);
        let ns = support.len();
        let mut direct = Vec::new();
        let mut split = Vec::with_capacity(columns.len());
        let mut v = vec![0.0; ns];
        for &j in columns {
            if self.reference.contains(&j) {
                direct.push(j);
                continue;
            }
            v.iter_mut().for_each(|x| *x = 0.0);
            for &(f, k) in &self.column_entries[j] {
                v[self.support_position[f]] = values[k];
            }
            let norm = dot(&v, &v).sqrt();
            let mut c = vec![0.0; self.basis.len() / m];
            if ns > 0 {
                for _pass in 0..2 {
                    for (ci, q) in c.iter_mut().zip(self.basis_compact.chunks_exact(ns)) {
                        let d = dot(q, &v);
                        *ci += d;
                        v.iter_mut().zip(q).for_each(|(x, qv)| *x -= d * qv);
                    }
                }
            }
            let outside = dot(&v, &v).sqrt();
            if outside > SPAN_TOLERANCE * norm {
                if c.len() >= BASIS_LIMIT {
                    direct.push(j);
                    continue;
                }
                let start = self.basis.len();
                self.basis.resize(start + m, 0.0);
                for (&f, x) in support.iter().zip(&v) {
                    self.basis[start + f] = x / outside;
                }
                self.basis_compact.extend(v.iter().map(|x| x / outside));
                c.push(outside);
            }
            split.push((j, c));
        }
        let factor = &mut self.factors[self.current];
        let solved = factor.basis_solved.len();
        if solved < self.basis.len() {
            let mut packed = self.basis[solved..].to_vec();
            factor.solve_in_place(&mut packed)?;
            factor.basis_solved.extend(packed);
        }
        let keep_image = !self.w.is_empty();
        for (j, c) in split {
            let z = &mut self.z[j * m..(j + 1) * m];
            z.iter_mut().for_each(|x| *x = 0.0);
            crate::linalg::simd::dense_mul_add(m, &factor.basis_solved[..c.len() * m], 1.0, &c, z);
            if keep_image {
                // The column as eliminated: Q c_j (A Z_j = Q c_j exactly), on the support.
                let w = &mut self.w[j * m..(j + 1) * m];
                w.iter_mut().for_each(|x| *x = 0.0);
                for (i, &f) in support.iter().enumerate() {
                    w[f] = c.iter().enumerate().map(|(k, ck)| ck * self.basis_compact[k * ns + i]).sum();
                }
            }
        }
        if !direct.is_empty() {
            let mut packed = vec![0.0; m * direct.len()];
            for (slot, &j) in direct.iter().enumerate() {
                for &(f, k) in &self.column_entries[j] {
                    packed[slot * m + f] = values[k];
                }
                if keep_image {
                    self.w[j * m..(j + 1) * m].copy_from_slice(&packed[slot * m..(slot + 1) * m]);
                }
            }
            factor.solve_in_place(&mut packed)?;
            for (slot, &j) in direct.iter().enumerate() {
                self.z[j * m..(j + 1) * m].copy_from_slice(&packed[slot * m..(slot + 1) * m]);
            }
        }
        Ok(())
    }

    /// The coupling of the reference coordinates from their mass and velocity parts (see
    /// `factorize`), at the body coordinates `qb`, as the coefficients of a
    /// [`ReferenceCoupling`] (in `structured`, with its block N_JF Z of the reference rows and
    /// columns returned), or formed in `z`, `w` and `row_values` when the reference rows are
    /// not dense (None returned, `structured` None). The rotation coupling is that of the
    /// deformed body, J_f = J_f0 + dJ(q_f) with dJ_i^T = -(I_jk - I_kj) q_f: the undeformed J_f0
    /// alone errs by dJ, which is not small where J_f0 is (a slender beam about its own axis),
    /// and made the modified Newton iteration diverge at every step size (a modal beam hinged
    /// at a node). Its solves take three solves (A^-1 dJ^T, packed) when q_f != 0, which a
    /// factorization keeps for later refreshes while dJ moves by at most
    /// `DEFORMATION_TOLERANCE` of J_f (the coupling of an iteration matrix is then as at the
    /// deformation of the solves, off by that fraction at most: a pendulum bar of solids
    /// changes dJ by 0.1-0.3 % of J_f between refreshes and needs the solves once).
    fn reference_coupling(
        &mut self,
        fb: &FlexibleBody,
        c: &MatrixCoefficients,
        qb: &[f64],
    ) -> Result<Option<[[f64; 7]; 7]>> {
        let m = self.n;
        let sm = c.scale * c.mass;
        let p = [qb[3], qb[4], qb[5], qb[6]];
        let a = crate::math::euler::rotation_matrix(&p);
        let l = crate::math::euler::l_matrix(&p);
        let qf = &qb[REFERENCE_COORDINATES..REFERENCE_COORDINATES + m];
        if self.reference_rows.is_empty() {
            self.reference_rows = (0..12).flat_map(|i| coupling_rows(fb, i)).collect();
            let s_kk = |k: usize| &self.reference_rows[(6 + k) * m..(7 + k) * m];
            let trace: Vec<f64> = (0..m).map(|f| s_kk(0)[f] + s_kk(1)[f] + s_kk(2)[f]).collect();
            self.reference_rows.extend(trace);
            self.reference_rows.extend_from_slice(&fb.ibar[..9 * m]);
        }
        // The velocity part of the rotation columns (the centrifugal coupling of the undeformed
        // body; the Coriolis part from qf_dot and the deformation are left out).
        let sv = c.scale * c.velocity;
        let w = self.angular_velocity;
        let spinning = sm != 0.0 && sv != 0.0 && (w[0] != 0.0 || w[1] != 0.0 || w[2] != 0.0);
        let two_l: [[f64; 4]; 3] = std::array::from_fn(|i| std::array::from_fn(|k| 2.0 * l[i][k]));
        let deformed = sm != 0.0 && qf.iter().any(|&x| x != 0.0);
        let factor = &mut self.factors[self.current];
        if deformed {
            // dJ_i^T, i = 0..3, solved again unless the kept one is within the tolerance. Since
            // dJ is linear in q_f, |dJ_i(q_f) - dJ_i(q_kept)| <= b |q_f - q_kept| with b a bound
            // of the norms of the antisymmetric matrices (`FlexibleBody::
            // antisymmetric_norm_bound`); with r the smallest row norm |J_f0 + dJ| at the kept
            // deformation, d (1 + tol) <= tol r for d = b |q_f - q_kept| implies the test below
            // (|J_f0 + dJ(q_f)| >= r - d) without forming dJ(q_f), a product with the mass
            // matrix (about a third of a refresh of the 1k pendulum bar).
            if self.antisymmetric_bound.is_none() {
                self.antisymmetric_bound = Some(fb.antisymmetric_norm_bound());
            }
            let bound = self.antisymmetric_bound.unwrap_or(f64::INFINITY);
            let near = !factor.deformation.is_empty() && {
                let d2: f64 = qf.iter().zip(&factor.deformation_at).map(|(x, y)| (x - y) * (x - y)).sum();
                let d = bound * d2.sqrt();
                d * (1.0 + DEFORMATION_TOLERANCE) <= DEFORMATION_TOLERANCE * factor.deformation_rows
            };
            if !near {
                self.deformation.resize(3 * m, 0.0);
                self.deformation.iter_mut().for_each(|x| *x = 0.0);
                fb.add_antisymmetric_products(-1.0, qf, &mut self.deformation);
                let rows = &self.reference_rows[3 * m..6 * m];
                let row_norm = |d: &[f64], i: usize| -> f64 {
                    d[i * m..(i + 1) * m]
                        .iter()
                        .zip(&rows[i * m..])
                        .map(|(x, y)| (x + y) * (x + y))
                        .sum::<f64>()
                        .sqrt()
                };
                let kept = !factor.deformation.is_empty()
                    && (0..3).all(|i| {
                        let (new, old) =
                            (&self.deformation[i * m..(i + 1) * m], &factor.deformation[i * m..(i + 1) * m]);
                        let change: f64 = new.iter().zip(old).map(|(x, y)| (x - y) * (x - y)).sum();
                        change.sqrt() <= DEFORMATION_TOLERANCE * row_norm(&self.deformation, i)
                    });
                if !kept {
                    let mut solved = self.deformation.clone();
                    factor.solve_in_place(&mut solved)?;
                    factor.deformation.clone_from(&self.deformation);
                    factor.deformed_rows = rows.iter().zip(&factor.deformation).map(|(x, d)| x + d).collect();
                    factor.deformed_solved =
                        factor.influence[3 * m..6 * m].iter().zip(&solved).map(|(x, d)| x + d).collect();
                    factor.deformation_at.clear();
                    factor.deformation_at.extend_from_slice(qf);
                    factor.deformation_rows =
                        (0..3).map(|i| row_norm(&factor.deformation, i)).fold(f64::INFINITY, f64::min);
                    factor.gram.clear();
                }
            }
        }
        // The coefficients, zero without the mass term (then the coupling is left out).
        let (row_count, column_count) = match (sm != 0.0, spinning) {
            (false, _) => (0, 0),
            (true, false) => (6, 6),
            (true, true) => (ROW_VECTORS, COLUMN_VECTORS),
        };
        let mut coupling = ReferenceCoupling {
            rows: [[0.0; ROW_VECTORS]; 7],
            columns: [[0.0; 7]; COLUMN_VECTORS],
            deformed,
            row_count,
            column_count,
        };
        // Columns R_k: s m A^-1 I1^T A^T e_k; columns p_c: s m A^-1 J_f^T 2L e_c and the
        // centrifugal part s v sum_m dfw_m (2 L)_mc on the six S_kl; the rows N_jF are their
        // transposes, with the velocity parts of the rows: (R, f) = A 2 w~ I1 (on the rows of
        // I1), and (p, f) = 2 L^T r with r_l = s v (w_l T - 2 sum_k w_k Ibar_kl) (undeformed).
        // Without the rows' velocity part the error operator of the iteration, though of about
        // the same spectral radius, is far from normal (the norm of its coordinate block 0.1
        // against 5.6e-3 with it: 1k pendulum bar at 5 rad/s, dense matrices), and the first
        // iteration of a step, from the predictor, contracts that much less.
        if sm != 0.0 {
            let aw = a.mul_mat(&w.skew());
            for o in 0..3 {
                for v in 0..3 {
                    coupling.columns[v][o] = sm * a.0[o][v];
                    coupling.rows[o][v] = sm * a.0[o][v] + if spinning { 2.0 * sv * aw.0[o][v] } else { 0.0 };
                }
            }
            for o in 0..4 {
                for v in 0..3 {
                    coupling.columns[3 + v][3 + o] = sm * two_l[v][o];
                    coupling.rows[3 + o][3 + v] = sm * two_l[v][o];
                }
            }
        }
        if spinning {
            for o in 0..4 {
                for (slot, g) in centrifugal_weights(&w, &two_l, o).into_iter().enumerate() {
                    coupling.columns[6 + slot][3 + o] = sv * g;
                }
                coupling.rows[3 + o][6] = (0..3).map(|k| two_l[k][o] * sv * w[k]).sum();
                for k in 0..3 {
                    for lr in 0..3 {
                        coupling.rows[3 + o][7 + 3 * k + lr] = -2.0 * sv * w[k] * two_l[lr][o];
                    }
                }
            }
        }
        if !self.apply_kept || !self.reference.iter().all(|&j| self.dense_rows[j]) {
            self.structured = None;
            self.form_reference(&coupling);
            return Ok(None);
        }
        self.structured = Some(coupling);
        let factor = &mut self.factors[self.current];
        // The block N_JF Z of the reference rows and columns, R G C: no pass over the
        // n_f-vectors but when G is made.
        if factor.gram.is_empty() || factor.gram_deformed != deformed {
            let rows = &self.reference_rows;
            let mut gram = vec![0.0; ROW_VECTORS * COLUMN_VECTORS];
            for (k, g) in gram.chunks_exact_mut(COLUMN_VECTORS).enumerate() {
                let u = row_vector(rows, factor, deformed, m, k);
                let sums: [f64; COLUMN_VECTORS] =
                    dots(COLUMN_VECTORS, |v| column_vector(factor, deformed, m, v), u);
                g.copy_from_slice(&sums);
            }
            factor.gram = gram;
            factor.gram_deformed = deformed;
        }
        // (R G) C, rows of R G first.
        let mut block = [[0.0; 7]; 7];
        for (ra, out) in coupling.rows.iter().zip(block.iter_mut()) {
            let mut rg = [0.0; COLUMN_VECTORS];
            for (&rk, g) in ra.iter().zip(factor.gram.chunks_exact(COLUMN_VECTORS)) {
                if rk != 0.0 {
                    rg.iter_mut().zip(g).for_each(|(x, gv)| *x += rk * gv);
                }
            }
            for (b, o) in out.iter_mut().enumerate() {
                *o = rg.iter().zip(&coupling.columns).map(|(x, col)| x * col[b]).sum();
            }
        }
        Ok(Some(block))
    }

    /// Forms the columns Z and W (as eliminated, with `keep_image`) and the rows N_jF of the
    /// reference coordinates from the coefficients of `coupling` (the rows at their entries).
    fn form_reference(&mut self, coupling: &ReferenceCoupling) {
        let m = self.n;
        let (rows, factor, deformed) = (&self.reference_rows, &self.factors[self.current], coupling.deformed);
        for (b, &j) in self.reference.iter().enumerate() {
            let z = &mut self.z[j * m..(j + 1) * m];
            z.iter_mut().for_each(|x| *x = 0.0);
            let x: [f64; COLUMN_VECTORS] = std::array::from_fn(|v| -coupling.columns[v][b]);
            subtract_combination(z, coupling.column_count, |v| column_vector(factor, deformed, m, v), &x);
            if let Some(w) = self.w.get_mut(j * m..(j + 1) * m) {
                w.iter_mut().for_each(|x| *x = 0.0);
                subtract_combination(
                    w,
                    coupling.column_count,
                    |v| eliminated_vector(rows, factor, deformed, m, v),
                    &x,
                );
            }
            let row = &mut self.row_values[j];
            for (&(f, _), r) in self.row_entries[j].iter().zip(row.iter_mut()) {
                *r = (0..coupling.row_count)
                    .map(|k| coupling.rows[b][k] * row_vector(rows, factor, deformed, m, k)[f])
                    .sum();
            }
        }
    }

    /// Makes `current` a factorization of A for the coefficients `c`, reusing a kept one.
    fn select_factor(&mut self, fb: &FlexibleBody, c: &MatrixCoefficients) -> Result<()> {
        let k = key(c);
        if let Some(pos) = self.factors.iter().position(|f| same_key(&f.key, &k)) {
            self.current = pos;
            return Ok(());
        }
        let only_identity = c.mass == 0.0 && c.velocity == 0.0 && c.position == 0.0;
        let mut factor = if only_identity {
            BlockFactor {
                key: k,
                factor: None,
                diagonal: c.scale * c.identity,
                influence: Vec::new(),
                basis_solved: Vec::new(),
                deformation: Vec::new(),
                deformed_rows: Vec::new(),
                deformed_solved: Vec::new(),
                deformation_at: Vec::new(),
                deformation_rows: 0.0,
                gram: Vec::new(),
                gram_deformed: false,
                memory: None,
            }
        } else {
            let mut on_pattern = vec![0.0; fb.pattern.nnz()];
            fb.mass_matrix.add_to_pattern(c.scale * c.mass, &mut on_pattern);
            fb.damping.add_to_pattern(c.scale * c.velocity, &mut on_pattern);
            fb.stiffness.add_to_pattern(c.scale * c.position, &mut on_pattern);
            // The pattern with a diagonal entry appended to every column (duplicates are
            // summed by the factorization) for the identity term.
            let ep = &fb.pattern;
            let mut col_ptr = Vec::with_capacity(ep.n + 1);
            let mut row_idx = Vec::with_capacity(ep.nnz() + ep.n);
            let mut values = Vec::with_capacity(ep.nnz() + ep.n);
            col_ptr.push(0);
            for col in 0..ep.n {
                for k in ep.col_ptr[col]..ep.col_ptr[col + 1] {
                    row_idx.push(ep.row_idx[k]);
                    values.push(on_pattern[k]);
                }
                row_idx.push(col);
                values.push(c.scale * c.identity);
                col_ptr.push(row_idx.len());
            }
            let matrix = CscRef { n: self.n, col_ptr: &col_ptr, row_idx: &row_idx, values: &values };
            let ordering = match (&fb.dof_nodes, &fb.node_positions) {
                (Some(nodes), Some(positions)) => Ordering::NestedDissection { dof_nodes: nodes, positions },
                _ => Ordering::Amd,
            };
            let factor =
                SymmetricFactor::new("elastic iteration matrix", matrix, ordering, FactorKind::Cholesky, 1)?;
            BlockFactor {
                key: k,
                factor: Some(factor),
                diagonal: 0.0,
                influence: Vec::new(),
                basis_solved: Vec::new(),
                deformation: Vec::new(),
                deformed_rows: Vec::new(),
                deformed_solved: Vec::new(),
                deformation_at: Vec::new(),
                deformation_rows: 0.0,
                gram: Vec::new(),
                gram_deformed: false,
                memory: None,
            }
        };
        let mut influence = Vec::with_capacity(12 * self.n);
        for i in 0..12 {
            influence.extend(coupling_rows(fb, i));
        }
        factor.solve_in_place(&mut influence)?;
        factor.influence = influence;
        if self.factors.len() >= 2 {
            self.factors.pop();
        }
        self.factors.insert(0, factor);
        self.current = 0;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assembly::{assemble, ElasticRows, Request, StateView};
    use crate::body::flexible::tests::PointBody;
    use crate::body::marker::MarkerElastic;
    use crate::joint::JointKind;
    use crate::linear_system::LinearSolvers;
    use crate::math::{Mat3, Vec3};
    use crate::system::{State, SystemBuilder, Workspace};

    /// Iteration-matrix coefficients shared by the tests (s m = 1, as for generalized-alpha).
    const ITERATION: MatrixCoefficients =
        MatrixCoefficients { mass: 4.0e4, velocity: 2.0e2, position: 1.0, identity: 0.0, scale: 2.5e-5 };

    /// A rigid link hinged to the ground and a deformable body hinged to it (at a reference
    /// marker, or at an elastic one), the deformable body condensed or not.
    fn model(condense: bool, elastic_marker: bool) -> Model {
        let mut sys = SystemBuilder::new();
        sys.set_gravity(Vec3([0.0, -9.81, 0.0])).unwrap();
        let link = sys
            .add_rigid_body(
                "link",
                2.0,
                Mat3::diagonal(Vec3([0.1, 0.2, 0.2])),
                Vec3::ZERO,
                Vec3([0.5, 0.0, 0.0]),
                Mat3::IDENTITY,
                Vec3::ZERO,
                Vec3::ZERO,
            )
            .unwrap();
        let mut input = PointBody::random(8, 6, 41).input(30.0, 0.5);
        input.condense = Some(condense);
        let body = FlexibleBody::new("flexible", input).unwrap();
        let fb = sys
            .add_flexible_body(
                "flexible",
                body,
                Vec3([1.0, 0.0, 0.0]),
                Mat3::IDENTITY,
                Vec3::ZERO,
                Vec3::ZERO,
                vec![0.01; 6],
                vec![],
            )
            .unwrap();
        let ground = sys.ground();
        let g = sys.add_marker("", ground, Vec3::ZERO, Mat3::IDENTITY).unwrap();
        let a = sys.add_marker("", link, Vec3([-0.5, 0.0, 0.0]), Mat3::IDENTITY).unwrap();
        let b = sys.add_marker("", link, Vec3([0.5, 0.0, 0.0]), Mat3::IDENTITY).unwrap();
        let c = if elastic_marker {
            let mut lcg = crate::body::flexible::tests::Lcg(7);
            let mut shape =
                || crate::math::dense::Jacobian3 { n: 6, data: (0..18).map(|_| 0.2 * lcg.next()).collect() };
            let elastic =
                MarkerElastic { indices: (0..6).collect(), translation: shape(), rotation: shape() };
            sys.add_flexible_marker("", fb, Vec3([0.3, 0.1, 0.0]), Mat3::IDENTITY, elastic).unwrap()
        } else {
            sys.add_marker("", fb, Vec3::ZERO, Mat3::IDENTITY).unwrap()
        };
        sys.add_joint("", JointKind::Revolute, [g, a]).unwrap();
        sys.add_joint("", JointKind::Revolute, [b, c]).unwrap();
        sys.compile().unwrap()
    }

    #[test]
    fn condensed_solves_equal_the_direct_solves_where_the_elastic_block_is_constant() {
        // At rest (w = alpha = 0) the elastic block of the Newton matrix is exactly
        // s (m M_ff + v D_ff + p K_ff): the exact condensed solver must reproduce the LU solve.
        for elastic_marker in [false, true] {
            compare_solves(elastic_marker);
        }
    }

    #[test]
    fn approximate_reference_coupling_is_exact_in_its_mass_part_for_a_deformed_body() {
        // With only the mass term (no velocity or position parts to leave out) the structured
        // coupling must reproduce the direct solve, also when the body is deformed: it uses
        // the deformed J_f = J_f0 + dJ(q_f), not the undeformed J_f0.
        let (direct, condensed) = (model(false, false), model(true, false));
        let mut state = State::initial(&direct, 0.0);
        let offset = direct.bodies[2].offset + REFERENCE_COORDINATES;
        for (k, x) in state.coordinates[offset..offset + 6].iter_mut().enumerate() {
            *x = 0.05 * (k as f64 - 2.5);
        }
        let rhs = test_rhs(direct.system_size());
        let c = MatrixCoefficients::ACCELERATION;
        let expected = direct_solve(&direct, &state, c, &rhs);
        let (x, _) = condensed_solve(&condensed, &state, c, &rhs, true);
        assert_close(&x, &expected);
    }

    #[test]
    fn elastic_rows_from_the_solve_equal_the_assembled_rows() {
        // One Newton iteration as the integrator makes it (rows kept at the first assembly,
        // structured coupling, update of q, q_dot, q_dd by (1, v, m) dq): the residual at the
        // new iterate from the solve's coupling image must equal the one assembled whole, in
        // a moving, deformed state with multipliers (joint at an elastic marker).
        let model = model(true, true);
        let mut state = moving_deformed_state(&model);
        state.multipliers.iter_mut().enumerate().for_each(|(k, l)| *l = 0.4 * k as f64 - 1.1);
        let offset = model.bodies[2].offset + REFERENCE_COORDINATES;
        let c = ITERATION;
        let (nq, s) = (model.coordinate_count, c.scale);
        let mut ws = Workspace::new(&model);
        let mut solvers = LinearSolvers::new(&model).unwrap();
        let keep = Request {
            structured_coupling: true,
            elastic_rows: ElasticRows::Keep,
            ..Request::solving(Some(c))
        };
        assemble(&model, StateView::of(&state), &mut ws, &keep).unwrap();
        let before = scale_of(&ws.residual);
        let mut x: Vec<f64> =
            ws.residual.iter().enumerate().map(|(k, r)| if k < nq { -s * r } else { -r }).collect();
        let LinearSolvers::Condensed { newton, .. } = &mut solvers else { panic!("condensed solvers") };
        newton.factorize(&model, &ws.values, &c, &state.coordinates).unwrap();
        newton.solve_in_place(&mut x).unwrap();
        for k in 0..nq {
            state.coordinates[k] += x[k];
            state.velocities[k] += c.velocity * x[k];
            state.accelerations[k] += c.mass * x[k];
        }
        for (l, dl) in state.multipliers.iter_mut().zip(&x[nq..]) {
            *l += dl / s;
        }
        let images = solvers.coupling_images();
        let update = Request {
            elastic_rows: ElasticRows::Update { scale: s },
            images: &images,
            ..Request::solving(None)
        };
        assemble(&model, StateView::of(&state), &mut ws, &update).unwrap();
        drop(images);
        let updated = ws.residual.clone();
        let mut whole = Workspace::new(&model);
        assemble(&model, StateView::of(&state), &mut whole, &Request::residual()).unwrap();
        let elastic = offset..offset + 6;
        let worst = (0..updated.len()).fold(0.0f64, |m, k| m.max((updated[k] - whole.residual[k]).abs()));
        assert!(worst <= 1e-12 * before, "rows off by {worst} (residual before {before})");
        // Not trivially equal: the elastic rows are not zero, and the image is not small.
        let rows = elastic.fold(0.0f64, |m, k| m.max(whole.residual[k].abs()));
        assert!(rows > 1e-3 * before, "{rows} vs {before}");
        let image = newton_image(&mut solvers, 2);
        assert!(image.iter().any(|&v| v.abs() > 1e-3 * before * s), "the coupling image is not needed");
    }

    #[test]
    fn structured_reference_coupling_has_the_velocity_part_of_a_spinning_body() {
        // Undeformed, no elastic velocities, spinning about a skew axis: the structured
        // columns of the reference coordinates (as eliminated) and their rows must equal the
        // assembled mass and velocity parts of N_F,ref and N_ref,F exactly (no position part:
        // coefficient 0).
        let model = model(true, false);
        let mut state = State::initial(&model, 0.0);
        let o = model.bodies[2].offset;
        let w = [0.7, -1.3, 2.1];
        for i in 0..3 {
            state.velocities[o + 4 + i] = 0.5 * w[i];
        }
        let elastic = o + REFERENCE_COORDINATES..o + REFERENCE_COORDINATES + 6;
        state.coordinates[elastic.clone()].iter_mut().for_each(|x| *x = 0.0);
        state.velocities[elastic].iter_mut().for_each(|x| *x = 0.0);
        let c = MatrixCoefficients { position: 0.0, ..ITERATION };
        let ws = assembled(&model, &state, c);
        let mut mass_only = Workspace::new(&model);
        let mass = MatrixCoefficients { velocity: 0.0, ..c };
        assemble(&model, StateView::of(&state), &mut mass_only, &Request::matrix(mass)).unwrap();
        let mut solver = CondensedSolver::with_images(&model, true, true).unwrap();
        solver.set_angular_velocities(&model, &state.coordinates, &state.velocities);
        solver.factorize(&model, &ws.values, &c, &state.coordinates).unwrap();
        let block = &mut solver.blocks[0];
        let coupling = block.structured.expect("a structured coupling");
        block.form_reference(&coupling);
        let m = block.n;
        let mut velocity_part = 0.0f64;
        for col in 0..7 {
            let j = block.reference[col];
            let mut assembled = vec![0.0; m];
            for &(f, k) in &block.column_entries[j] {
                assembled[f] = ws.values[k];
            }
            let eliminated = &block.w[j * m..(j + 1) * m];
            let mass_column = |f: usize| {
                block.column_entries[j].iter().find(|e| e.0 == f).map_or(0.0, |&(_, k)| mass_only.values[k])
            };
            let scale = scale_of(&assembled);
            for f in 0..m {
                assert!(
                    (eliminated[f] - assembled[f]).abs() <= 1e-12 * scale,
                    "column {col}, row {f}: {} vs {} (mass part {})",
                    eliminated[f],
                    assembled[f],
                    block.row_values[j][f]
                );
            }
            if col >= 3 {
                let mass_only: f64 =
                    (0..m).map(|f| (eliminated[f] - mass_column(f)).abs()).fold(0.0, f64::max);
                velocity_part = velocity_part.max(mass_only / scale);
            }
            // The row N_jF likewise.
            let mut assembled_row = vec![0.0; m];
            for &(f, k) in &block.row_entries[j] {
                assembled_row[f] = ws.values[k];
            }
            let row_scale = scale_of(&assembled_row);
            for (f, &(g, _)) in block.row_entries[j].iter().enumerate() {
                let (ours, theirs) = (block.row_values[j][f], assembled_row[g]);
                assert!(
                    (ours - theirs).abs() <= 1e-12 * row_scale,
                    "row {col}, column {g}: {ours} vs {theirs}"
                );
            }
        }
        // Not trivially equal: the velocity part is not negligible against the mass part.
        assert!(velocity_part > 1e-4, "velocity part {velocity_part}");
    }

    #[test]
    fn reference_schur_block_from_the_small_products_equals_the_dot_products() {
        // Deformed (dJ solved) and spinning: the block N_JF Z of the reference rows and columns
        // from R G C (`reference_coupling`) equals the dot products of the rows and columns it
        // formed, and the factorization subtracted it (the solve test above covers that).
        let model = model(true, false);
        let state = moving_deformed_state(&model);
        let ws = assembled(&model, &state, ITERATION);
        let mut solver = CondensedSolver::with_images(&model, true, true).unwrap();
        solver.set_angular_velocities(&model, &state.coordinates, &state.velocities);
        assert!(solver.blocks[0].angular_velocity.0.iter().any(|&x| x.abs() > 0.1), "spinning");
        solver.factorize(&model, &ws.values, &ITERATION, &state.coordinates).unwrap();
        let block = &mut solver.blocks[0];
        let q = &state.coordinates[model.bodies[block.body].offset..];
        let structured = block.reference_coupling(flexible(&model, block.body), &ITERATION, q).unwrap();
        let structured = structured.expect("dense reference rows");
        assert!(!block.factors[block.current].deformation.is_empty(), "dJ solved");
        let coupling = block.structured.expect("a structured coupling");
        assert_eq!((coupling.row_count, coupling.column_count), (ROW_VECTORS, COLUMN_VECTORS));
        block.form_reference(&coupling);
        let m = block.n;
        let explicit: Vec<Vec<f64>> = block
            .reference
            .iter()
            .map(|&ja| {
                block
                    .reference
                    .iter()
                    .map(|&jb| dot(&block.row_values[ja], &block.z[jb * m..(jb + 1) * m]))
                    .collect()
            })
            .collect();
        let scale = explicit.iter().flatten().fold(0.0f64, |s, x| s.max(x.abs()));
        assert!(scale > 0.0);
        for a in 0..7 {
            for b in 0..7 {
                let (ours, theirs) = (structured[a][b], explicit[a][b]);
                assert!((ours - theirs).abs() <= 1e-11 * scale, "({a}, {b}): {ours} vs {theirs}");
            }
        }
    }

    #[test]
    fn reference_coupling_applied_from_kept_vectors_equals_the_formed_one() {
        // Deformed, spinning, with a joint at an elastic marker (other coupling columns and
        // rows): the structured coupling applied from its kept vectors (Schur complement,
        // solves, coupling images) must equal the one formed in Z, W and the rows.
        let model = model(true, true);
        let state = moving_deformed_state(&model);
        let ws = assembled(&model, &state, ITERATION);
        let rhs = test_rhs(model.system_size());
        let mut results = Vec::new();
        for apply_kept in [true, false] {
            let mut solver = CondensedSolver::with_images(&model, true, true).unwrap();
            solver.blocks[0].apply_kept = apply_kept;
            solver.set_angular_velocities(&model, &state.coordinates, &state.velocities);
            solver.factorize(&model, &ws.values, &ITERATION, &state.coordinates).unwrap();
            assert_eq!(solver.blocks[0].structured.is_some(), apply_kept);
            let others =
                (0..solver.blocks[0].coupling.len()).filter(|j| !solver.blocks[0].reference.contains(j));
            assert!(others.count() > 0, "other coupling columns");
            let mut x = rhs.clone();
            solver.solve_in_place(&mut x).unwrap();
            let image: Vec<f64> = solver.coupling_images().next().unwrap().1.to_vec();
            results.push((solver.reduced_values.clone(), x, image));
        }
        let (kept, formed) = (&results[0], &results[1]);
        for (ours, theirs) in [(&kept.0, &formed.0), (&kept.1, &formed.1), (&kept.2, &formed.2)] {
            let scale = scale_of(theirs);
            assert!(scale > 0.0);
            for (k, (a, b)) in ours.iter().zip(theirs.iter()).enumerate() {
                assert!((a - b).abs() <= 1e-12 * scale, "{k}: {a} vs {b} (scale {scale})");
            }
        }
    }

    #[test]
    fn dense_and_sparse_reduced_factorizations_give_the_same_solves() {
        // Small reduced systems are factorized dense, large ones sparse: both must solve alike.
        let model = model(true, true);
        let state = moving_deformed_state(&model);
        let c = ITERATION;
        let ws = assembled(&model, &state, c);
        let rhs = test_rhs(model.system_size());
        let mut solves = Vec::new();
        for sparse in [false, true] {
            let mut solver = CondensedSolver::new(&model, true).unwrap();
            if sparse {
                let ReducedLu::Dense { pattern, .. } = &solver.lu else { panic!("a small system is dense") };
                solver.lu = ReducedLu::Sparse(SparseLu::new(pattern).unwrap());
            }
            solver.factorize(&model, &ws.values, &c, &state.coordinates).unwrap();
            let mut x = rhs.clone();
            solver.solve_in_place(&mut x).unwrap();
            solves.push(x);
        }
        assert_close(&solves[1], &solves[0]);
    }

    fn newton_image(solvers: &mut LinearSolvers, body: usize) -> Vec<f64> {
        let LinearSolvers::Condensed { newton, .. } = solvers else { panic!("condensed solvers") };
        newton.coupling_images().find(|(b, _)| *b == body).map(|(_, i)| i.to_vec()).unwrap()
    }

    #[test]
    fn factorizations_of_a_serve_coefficients_equal_to_round_off() {
        // A step shortened by round-off (coefficients a few ulps off) keeps the factor of A;
        // other coefficients get their own (at most two are kept).
        let condensed = model(true, false);
        let mut solver = CondensedSolver::new(&condensed, true).unwrap();
        let mut ws = Workspace::new(&condensed);
        let state = State::initial(&condensed, 0.0);
        let method =
            crate::integrator::generalized_alpha::GeneralizedAlpha::from_spectral_radius(0.9).unwrap();
        let h = 1e-3;
        for (step, factors) in [(h, 1), (h * (1.0 - 4.0 * f64::EPSILON), 1), (h * (1.0 - 1e-9), 2)] {
            let c = method.coefficients(step);
            assemble(&condensed, StateView::of(&state), &mut ws, &Request::matrix(c)).unwrap();
            solver.factorize(&condensed, &ws.values, &c, &state.coordinates).unwrap();
            assert_eq!(solver.blocks[0].factors.len(), factors, "step {step:e}");
        }
    }

    #[test]
    fn deformation_solves_are_kept_while_the_deformation_coupling_changes_little() {
        // A factorization at a deformation close to that of the kept solves of dJ reuses them
        // (its solve is then close to, not equal to, the direct one); a larger change solves
        // again and is exact (mass part only, as above).
        let (direct, condensed) = (model(false, false), model(true, false));
        let c = MatrixCoefficients::ACCELERATION;
        let rhs = test_rhs(direct.system_size());
        let mut solver = CondensedSolver::new(&condensed, true).unwrap();
        let mut ws = Workspace::new(&condensed);
        let offset = direct.bodies[2].offset + REFERENCE_COORDINATES;
        let mut kept = Vec::new();
        for (factor, exact) in [(1.0, true), (1.0 + 1e-4, false), (2.0, true)] {
            let mut state = State::initial(&direct, 0.0);
            for (k, x) in state.coordinates[offset..offset + 6].iter_mut().enumerate() {
                *x = 0.05 * factor * (k as f64 - 2.5);
            }
            let expected = direct_solve(&direct, &state, c, &rhs);
            assemble(&condensed, StateView::of(&state), &mut ws, &Request::matrix(c)).unwrap();
            solver.factorize(&condensed, &ws.values, &c, &state.coordinates).unwrap();
            let mut x = rhs.clone();
            solver.solve_in_place(&mut x).unwrap();
            let scale = scale_of(&expected);
            let worst = x.iter().zip(&expected).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            if exact {
                assert!(worst < 1e-9 * scale, "factor {factor}: off by {worst} (scale {scale})");
            } else {
                assert!(worst > 1e-12 * scale && worst < 1e-3 * scale, "factor {factor}: off by {worst}");
            }
            let block = &solver.blocks[0];
            kept.push(block.factors[block.current].deformation.clone());
        }
        assert_eq!(kept[0], kept[1], "the solves of dJ were made again for a small change");
        assert_ne!(kept[1], kept[2], "the solves of dJ were kept for a large change");
    }

    #[test]
    fn marker_couplings_of_later_factorizations_come_from_the_coupling_basis() {
        // The joint at the elastic marker couples through A(p) times constant marker rows: the
        // first factorization spans them, later ones at other rotations reuse that span
        // (no solves) and still reproduce the direct solve (zero velocities and multipliers:
        // the elastic block is constant there).
        let (direct, condensed) = (model(false, true), model(true, true));
        let c = ITERATION;
        let rhs = test_rhs(direct.system_size());
        let mut solver = CondensedSolver::new(&condensed, false).unwrap();
        let mut ws = Workspace::new(&condensed);
        let axis = Vec3([0.3, -0.5, 0.8]) * (1.0 / Vec3([0.3, -0.5, 0.8]).norm());
        let mut sizes = Vec::new();
        for angle in [0.0f64, 0.4, 1.3, -2.0] {
            let mut state = State::initial(&direct, 0.0);
            for (body, turn) in [(1, 0.5 * angle), (2, angle)] {
                let o = direct.bodies[body].offset;
                let (cos, sin) = ((0.5 * turn).cos(), (0.5 * turn).sin());
                state.coordinates[o + 3..o + 7].copy_from_slice(&[
                    cos,
                    sin * axis[0],
                    sin * axis[1],
                    sin * axis[2],
                ]);
            }
            let expected = direct_solve(&direct, &state, c, &rhs);
            assemble(&condensed, StateView::of(&state), &mut ws, &Request::matrix(c)).unwrap();
            solver.factorize(&condensed, &ws.values, &c, &state.coordinates).unwrap();
            let mut x = rhs.clone();
            solver.solve_in_place(&mut x).unwrap();
            assert_close(&x, &expected);
            let block = &solver.blocks[0];
            sizes.push((
                block.basis.len() / block.n,
                block.factors[block.current].basis_solved.len() / block.n,
            ));
        }
        assert!(sizes[0].0 > 0 && sizes[0].0 <= 6, "{sizes:?}");
        assert!(sizes.iter().all(|&s| s == (sizes[0].0, sizes[0].0)), "{sizes:?}");
    }

    #[test]
    fn structured_solver_reads_no_assembled_reference_elastic_blocks() {
        // The Newton matrix assembled without the reference-elastic blocks of the condensed
        // body (as the integrator does) must give the structured solver the same solves as the
        // whole matrix, in a moving, deformed state.
        let model = model(true, true);
        let state = moving_deformed_state(&model);
        let c = ITERATION;
        let rhs = test_rhs(model.system_size());
        let solves: Vec<Vec<f64>> = [false, true]
            .into_iter()
            .map(|structured| {
                let mut ws = Workspace::new(&model);
                let request = Request { structured_coupling: structured, ..Request::solving(Some(c)) };
                assemble(&model, StateView::of(&state), &mut ws, &request).unwrap();
                let mut solver = CondensedSolver::new(&model, true).unwrap();
                solver.factorize(&model, &ws.values, &c, &state.coordinates).unwrap();
                let mut x = rhs.clone();
                solver.solve_in_place(&mut x).unwrap();
                x
            })
            .collect();
        let scale = scale_of(&solves[0]);
        for (k, (a, b)) in solves[0].iter().zip(&solves[1]).enumerate() {
            assert!((a - b).abs() <= 1e-12 * scale, "{k}: {a} vs {b}");
        }
    }

    /// A state of the test model with velocities, accelerations and the deformable
    /// body's elastic coordinates set.
    fn moving_deformed_state(model: &Model) -> State {
        let mut state = State::initial(model, 0.0);
        for (k, v) in state.velocities.iter_mut().enumerate() {
            *v = 0.3 * ((k * 7 % 5) as f64 - 2.0);
        }
        for (k, a) in state.accelerations.iter_mut().enumerate() {
            *a = 2.0 * ((k * 3 % 7) as f64 - 3.0);
        }
        let offset = model.bodies[2].offset + REFERENCE_COORDINATES;
        for (k, x) in state.coordinates[offset..offset + 6].iter_mut().enumerate() {
            *x = 0.02 * (k as f64 - 2.5);
        }
        state
    }

    /// A workspace with the residual and Newton matrix of `model` at `state` assembled with
    /// the coefficients `c`.
    fn assembled(model: &Model, state: &State, c: MatrixCoefficients) -> Workspace {
        let mut ws = Workspace::new(model);
        assemble(model, StateView::of(state), &mut ws, &Request::matrix(c)).unwrap();
        ws
    }

    fn test_rhs(n: usize) -> Vec<f64> {
        (0..n).map(|k| ((k * 37 % 11) as f64 - 5.0) * 0.1).collect()
    }

    /// The sparse LU solve of the assembled Newton matrix of `model` with coefficients `c`.
    fn direct_solve(model: &Model, state: &State, c: MatrixCoefficients, rhs: &[f64]) -> Vec<f64> {
        let mut ws = Workspace::new(model);
        assemble(model, StateView::of(state), &mut ws, &Request::matrix(c)).unwrap();
        let mut lu = SparseLu::new(&model.layout.pattern).unwrap();
        lu.factorize(&ws.values).unwrap();
        let mut x = rhs.to_vec();
        lu.solve_in_place(&mut x).unwrap();
        x
    }

    /// The condensed solve (exact or structured reference coupling) and the reduced size.
    fn condensed_solve(
        model: &Model,
        state: &State,
        c: MatrixCoefficients,
        rhs: &[f64],
        approximate_reference: bool,
    ) -> (Vec<f64>, usize) {
        let mut ws = Workspace::new(model);
        assemble(model, StateView::of(state), &mut ws, &Request::matrix(c)).unwrap();
        let mut solver = CondensedSolver::new(model, approximate_reference).unwrap();
        solver.factorize(model, &ws.values, &c, &state.coordinates).unwrap();
        let mut x = rhs.to_vec();
        solver.solve_in_place(&mut x).unwrap();
        (x, solver.reduced_size())
    }

    fn scale_of(v: &[f64]) -> f64 {
        v.iter().fold(0.0f64, |m, x| m.max(x.abs()))
    }

    fn assert_close(x: &[f64], expected: &[f64]) {
        let scale = scale_of(expected);
        for (k, (a, b)) in x.iter().zip(expected).enumerate() {
            assert!((a - b).abs() < 1e-9 * scale, "{k}: {a} vs {b}");
        }
    }

    fn compare_solves(elastic_marker: bool) {
        let (direct, condensed) = (model(false, elastic_marker), model(true, elastic_marker));
        assert!(!direct.has_condensed_bodies() && condensed.has_condensed_bodies());
        let mut state = State::initial(&direct, 0.0);
        // Multipliers of joints at elastic markers enter N_FF through the constraint Hessian,
        // which A leaves out: zero there for an exact comparison.
        if !elastic_marker {
            state.multipliers.iter_mut().enumerate().for_each(|(k, l)| *l = 0.1 * k as f64 - 0.3);
        }
        let n = direct.system_size();
        let rhs = test_rhs(n);
        let coefficients = [MatrixCoefficients::ACCELERATION, ITERATION];
        for c in coefficients {
            let expected = direct_solve(&direct, &state, c, &rhs);
            let (x, reduced) = condensed_solve(&condensed, &state, c, &rhs, false);
            assert_eq!(reduced, n - 6);
            assert_close(&x, &expected);
            // The approximate reference coupling is an iteration matrix: its solve is close.
            let (y, _) = condensed_solve(&condensed, &state, c, &rhs, true);
            let scale = scale_of(&expected);
            let worst = (0..n).fold(0.0f64, |m, k| m.max((y[k] - expected[k]).abs()));
            assert!(worst < 0.2 * scale, "approximate solve off by {worst} (scale {scale})");
        }
    }
}
