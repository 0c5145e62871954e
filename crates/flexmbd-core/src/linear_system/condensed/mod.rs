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
//!
//! The files follow the life of a solver: `layout` splits the unknowns and lays out the reduced
//! system once; `factor` holds the factorizations (A of each body, LU of the reduced system);
//! `factorize` forms the Schur complement, with the columns Z of the couplings at elastic
//! markers from `coupling_basis` and the coupling with the body's own reference coordinates
//! from `reference`; `solve` applies it all; `kernels` are the dot products and vector updates
//! they share.

use crate::body::flexible::FlexibleBody;
use crate::body::BodyKind;
use crate::math::Vec3;
use crate::system::model::Model;

mod coarse;
mod coupling_basis;
mod factor;
mod factorize;
mod kernels;
mod layout;
mod reference;
mod solve;
#[cfg(test)]
mod tests;

use factor::{BlockFactor, ReducedLu};
use reference::ReferenceCoupling;

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
    /// The fraction of J_f by which dJ may move before its solves are made again
    /// (`reference::DEFORMATION_TOLERANCE`, or `COARSE_DEFORMATION_TOLERANCE` with the coarse
    /// stage; set at each factorization).
    deformation_tolerance: f64,
    /// Bound of the norms of the body's antisymmetric matrices (made at the first use).
    antisymmetric_bound: Option<f64>,
    /// Body-frame angular velocity of the velocity part of the structured reference coupling
    /// (see `CondensedSolver::set_angular_velocities`; zero until set).
    angular_velocity: Vec3,
    /// The coefficients y_f on the kept vectors V_u of the coarse stage's correction of the
    /// last solve (None when it made none): its image -E y_f (E_u = A V_u, the columns as
    /// eliminated) is part of what the solve eliminated, A x_F = b_F - W x_J - E y_f (see
    /// `coupling_images`).
    gyroscopic_coefficients: Option<[f64; 6]>,
}

impl Block {
    /// Whether coupling unknown `j` is a reference coordinate whose row and column the solves
    /// apply from the kept vectors of the structured coupling (not from `z`, `w` and
    /// `row_values`).
    fn applied_from_kept(&self, j: usize) -> bool {
        self.structured.is_some() && self.reference.contains(&j)
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
    /// Whether the iteration matrix takes the gyroscopic block of the elastic rows (see
    /// `set_gyroscopic`).
    gyroscopic: bool,
    /// s gamma' of the last factorization of an iteration matrix (0 otherwise).
    gyroscopic_scale: f64,
    /// The pattern of the reduced system and the coarse stage (see `coarse`).
    reduced_pattern: crate::linalg::sparse::SparsePattern,
    coarse: Option<coarse::Coarse>,
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

    /// Makes the solves of the iteration matrix take the gyroscopic block of each condensed
    /// body's elastic rows (`on`), from the next factorization: see `solve_gyroscopic`.
    pub fn set_gyroscopic(&mut self, on: bool) {
        self.gyroscopic = on;
    }

    /// Whether the solves take the gyroscopic block (`set_gyroscopic`).
    pub fn gyroscopic(&self) -> bool {
        self.gyroscopic
    }

    /// Solves in place (global vector) with the iteration matrix P, then, with the gyroscopic
    /// setting, the coarse stage of `coarse`: the Galerkin correction with
    /// P + G + the exact rotation rows on the reduced unknowns and the six kept vectors
    /// A^-1 [I1^T, J_f^T] of each body, where G = s gamma' 2 int rho S^T w~ S
    /// = -2 s gamma' sum_i w_i A_i is the gyroscopic block of the elastic rows (A_i = I_jk -
    /// I_kj, w of `set_angular_velocities`), which the Cholesky factor of A cannot hold.
    /// Without the setting, or for a matrix that is not an iteration matrix, a plain solve.
    pub fn solve_gyroscopic(&mut self, x: &mut [f64]) -> std::result::Result<(), String> {
        self.solve_in_place(x)?;
        if self.gyroscopic && self.gyroscopic_scale != 0.0 {
            self.coarse_stage(x);
        }
        Ok(())
    }

    /// Size of the reduced (Schur complement) system.
    pub fn reduced_size(&self) -> usize {
        self.global_of.len()
    }
}
