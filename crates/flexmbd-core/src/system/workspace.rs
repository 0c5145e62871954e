//! Preallocated buffers and derived quantities (house style 1 and 3): everything the
//! assembly and the solvers write during a step, sized once when a simulation starts, so that
//! the hot path does not allocate.

use crate::body::flexible::{FlexibleBody, FlexibleScratch, FlexibleTangent, REFERENCE_COORDINATES};
use crate::body::marker::MarkerKinematics;
use crate::body::rigid::RigidTangent;
use crate::body::BodyKind;
use crate::error::{FlexmbdError, Result};
use crate::force::ForceLocal;
use crate::linalg::dense::{DenseLu, DENSE_SYSTEM_SIZE};
use crate::linalg::sparse::{SparseLdlt, SparseLu};
use crate::linear_system::condensed::{has_condensed_bodies, is_condensed, CondensedSolver};
use crate::math::dense::DenseMatrix;
use crate::system::model::Model;

/// Buffers of one joint (local coordinates = body i's, then body j's).
#[derive(Clone, Debug)]
pub struct JointLocal {
    /// C (equations); filled by the assembly.
    pub values: Vec<f64>,
    /// C_q (equations x local); filled by the assembly.
    pub jacobian: DenseMatrix,
    /// sum_e lambda_e d2C_e/dq2 (local x local); filled by the assembly.
    pub hessian: DenseMatrix,
    /// Scratch vectors (local).
    pub scratch: Vec<f64>,
    /// Scratch for a gradient (local).
    pub gradient: Vec<f64>,
    /// Scratch for a time derivative of a gradient (local).
    pub gradient_time: Vec<f64>,
    /// Driver values (f, f', f'') at the assembly time.
    pub driver: [f64; 3],
}

/// Buffers of one deformable body.
#[derive(Clone, Debug)]
pub struct FlexibleWork {
    /// Kernel scratch (products with the invariants).
    pub scratch: FlexibleScratch,
    /// Tangent of the inertia force; filled by the assembly.
    pub tangent: FlexibleTangent,
    /// Body force (7 + n_f); filled by the assembly.
    pub force: Vec<f64>,
    /// Values on the body's elastic pattern (nnz of the pattern); filled by the assembly.
    pub elastic_values: Vec<f64>,
    /// Gravity Jacobian blocks (p, f) 4 x n_f and (f, p) n_f x 4; filled by the assembly.
    pub gravity_pf: Vec<f64>,
    /// See `gravity_pf`.
    pub gravity_fp: Vec<f64>,
    /// Condensed bodies in Newton iterations: the elastic rows of the residual without their
    /// linear part at the last assembly (n_f; see [`ElasticRows`]).
    pub nonlinear: Vec<f64>,
    /// Whether `nonlinear` holds the rows of an earlier assembly.
    pub rows_kept: bool,
}

impl FlexibleWork {
    /// Buffers for `body`.
    pub fn new(body: &FlexibleBody) -> Self {
        let n = body.elastic_count;
        FlexibleWork {
            scratch: FlexibleScratch::for_body(body),
            tangent: FlexibleTangent::with_size(n),
            force: vec![0.0; REFERENCE_COORDINATES + n],
            elastic_values: vec![0.0; body.pattern.nnz()],
            gravity_pf: vec![0.0; 4 * n],
            gravity_fp: vec![0.0; 4 * n],
            nonlinear: vec![0.0; n],
            rows_kept: false,
        }
    }
}

/// The factorizations a simulation keeps.
pub enum LinearSolvers {
    /// Models without condensed bodies: factorizations of the whole Newton matrix.
    Direct {
        /// Sparse LU of the last factorized matrix (exact Newton steps, initial conditions).
        lu: Box<SparseLu>,
        /// Symmetric quasi-definite LDL^T of the last factorized iteration matrix (modified
        /// Newton).
        ldlt: Box<SparseLdlt>,
        /// LDL^T of [[M, C_q^T], [C_q, 0]] for the velocity projection (kept apart so that
        /// the Newton matrix can be reused by the next step).
        projection: Box<SparseLdlt>,
    },
    /// Small models (at most `solver::dense::DENSE_SYSTEM_SIZE` unknowns): dense LU.
    Dense {
        /// Newton iteration matrix (modified and exact Newton).
        newton: Box<DenseLu>,
        /// Projection, acceleration and initial-condition systems.
        projection: Box<DenseLu>,
    },
    /// Models with large deformable bodies: their elastic coordinates condensed out
    /// (`solver::condensed`), one solver for the Newton matrix, one for the projection and
    /// acceleration systems.
    Condensed {
        /// Newton iteration matrix.
        newton: Box<CondensedSolver>,
        /// Projection, acceleration and initial-condition systems.
        projection: Box<CondensedSolver>,
    },
    /// No factorizations: a workspace for evaluating the equations only
    /// (`Workspace::for_evaluation`).
    None,
}

/// How the assembly forms the elastic rows of condensed bodies. Their linear part
/// L = M_ff qf_dd + D_ff qf_dot + K_ff q_f changes in a Newton iteration that updates
/// (q, q_dot, q_dd) by (1, v, m) dq by exactly (m M_ff + v D_ff + K_ff) dq_f = A dq_f / s, and
/// the condensed solve gives A dq_f = b_F - W dq_J (W: the coupling columns it eliminated with,
/// b_F = -s r_F). So with the rest of the rows N (everything but L) kept from the last
/// assembly, the rows at the new iterate are N' - N - W dq_J / s: no products with K_ff and
/// M_ff after the first iteration of a step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ElasticRows {
    /// Assembled whole (every assembly outside the Newton iterations).
    Whole,
    /// Assembled whole, and N kept (first iteration of a step).
    Keep,
    /// From the last solve of the condensed Newton solver, whose right-hand side had the
    /// scale `scale` (later iterations; valid only right after such a solve and update).
    Update {
        /// s of the Newton matrix.
        scale: f64,
    },
}

/// Workspace of a simulation of one model.
pub struct Workspace {
    /// Kinematics of every marker (filled by `update_kinematics`).
    pub markers: Vec<MarkerKinematics>,
    /// Residual [r (coordinates); C (constraints)] (system size); filled by `assemble`.
    pub residual: Vec<f64>,
    /// Values of the Newton matrix on the model's pattern (nnz); filled by `assemble`.
    pub values: Vec<f64>,
    /// The factorizations of the linear solves.
    pub linear: LinearSolvers,
    /// Whether the assembly writes the elastic blocks of condensed bodies into the Newton
    /// matrix (their condensed solves never read them; analyses that need the whole matrix
    /// keep the default, true).
    pub assemble_condensed_blocks: bool,
    /// Whether the matrix being assembled is the Newton iteration matrix of a model with
    /// condensed bodies, whose solver takes the coupling of each condensed body with its own
    /// reference coordinates from its structured mass part (`CondensedSolver::factorize`): the
    /// assembly then leaves those blocks out, and with them the inertia products only they
    /// need. Set by the integrator around that assembly; false otherwise.
    pub structured_condensed_coupling: bool,
    /// How the elastic rows of condensed bodies are assembled; set by the integrator around
    /// its Newton iterations, `Whole` otherwise.
    pub elastic_rows: ElasticRows,
    /// Weight kappa of the normalization penalty of each rigid body (kg m^2): a third of the
    /// trace of its inertia about the body origin.
    pub normalization_weights: Vec<f64>,
    /// Penalty blocks (weight, p) of the LDL^T factorization (normalizations); filled by the
    /// integrator.
    pub penalties: Vec<(f64, [f64; 4])>,
    /// Rigid-body tangent scratch (7 x 7 blocks).
    pub rigid: RigidTangent,
    /// Body-level force scratch (up to 7 entries).
    pub body_force: Vec<f64>,
    /// Per body: the buffers of a deformable body (None for the others).
    pub flexible: Vec<Option<FlexibleWork>>,
    /// Per joint.
    pub joints: Vec<JointLocal>,
    /// Per force element.
    pub forces: Vec<ForceLocal>,
    /// Right-hand side and solution of linear solves (system size).
    pub solution: Vec<f64>,
    /// Scratch vectors (system size).
    pub scratch: [Vec<f64>; 3],
    /// The coordinates of the joints and normalizations, sorted: where constraint forces
    /// C_q^T lambda can be nonzero.
    pub constraint_coordinates: Vec<usize>,
    /// Ranges of `values` that a matrix assembly zeroes when it leaves blocks of condensed
    /// bodies out (see [`Workspace::zero_matrix`]), made at the first such assembly.
    matrix_ranges: [Option<Vec<std::ops::Range<usize>>>; 3],
}

impl Workspace {
    /// Zeroes `values` for a matrix assembly: every entry but the blocks of condensed bodies
    /// that the assembly leaves out and that no solver then reads (their elastic blocks
    /// without `assemble_condensed_blocks`, their reference-elastic coupling with
    /// `structured_condensed_coupling`). A condensed body's elastic pattern holds most of the
    /// matrix's entries (about 43,000 of the 45,085 with a body of 960 elastic coordinates):
    /// zeroing it at every refresh of the iteration matrix cost more than the rest of its
    /// assembly.
    pub fn zero_matrix(&mut self, model: &Model) {
        let slot = match (self.assemble_condensed_blocks, self.structured_condensed_coupling) {
            (true, false) => {
                self.values.iter_mut().for_each(|x| *x = 0.0);
                return;
            }
            (false, false) => 0,
            (false, true) => 1,
            (true, true) => 2,
        };
        let ranges = self.matrix_ranges[slot].get_or_insert_with(|| {
            let mut left_out = vec![false; model.layout.pattern.nnz()];
            for (bi, body) in model.bodies.iter().enumerate() {
                if !is_condensed(&body.kind) {
                    continue;
                }
                let entries = &model.layout.bodies[bi];
                let mut blocks: Vec<&[usize]> = Vec::new();
                if slot != 2 {
                    blocks.push(&entries.elastic);
                }
                if slot != 0 {
                    blocks.extend([&entries.reference_elastic[..], &entries.elastic_reference[..]]);
                }
                for &k in blocks.into_iter().flatten() {
                    left_out[k] = true;
                }
            }
            let mut ranges = Vec::new();
            let mut start = None;
            for (k, &out) in left_out.iter().chain([&true]).enumerate() {
                match (start, out) {
                    (None, false) => start = Some(k),
                    (Some(s), true) => {
                        ranges.push(s..k);
                        start = None;
                    }
                    _ => {}
                }
            }
            ranges
        });
        for r in ranges.iter() {
            self.values[r.clone()].iter_mut().for_each(|x| *x = 0.0);
        }
    }

    /// Allocates every buffer for `model` and performs the symbolic factorization.
    pub fn new(model: &Model) -> Result<Self> {
        let linear = Self::linear_solvers(model)?;
        Ok(Self::with_linear_solvers(model, linear))
    }

    /// A workspace that evaluates the equations (assembly) but has no sparse factorizations:
    /// for the dense solvers and analyses.
    pub fn for_evaluation(model: &Model) -> Self {
        Self::with_linear_solvers(model, LinearSolvers::None)
    }

    fn linear_solvers(model: &Model) -> Result<LinearSolvers> {
        let size = model.system_size();
        Ok(if has_condensed_bodies(model) {
            LinearSolvers::Condensed {
                newton: Box::new(CondensedSolver::with_images(model, true, true)?),
                projection: Box::new(CondensedSolver::new(model, false)?),
            }
        } else if size <= DENSE_SYSTEM_SIZE {
            LinearSolvers::Dense {
                newton: Box::new(DenseLu::new(size)),
                projection: Box::new(DenseLu::new(size)),
            }
        } else {
            let lu = SparseLu::new(&model.layout.pattern).map_err(|detail| FlexmbdError::SingularMatrix {
                time: 0.0,
                context: "symbolic analysis of the Newton matrix".to_string(),
                detail,
            })?;
            let blocks: Vec<[usize; 4]> = model.normalizations.iter().map(|nz| nz.dofs).collect();
            let symmetric = |context: &str| {
                SparseLdlt::new(&model.layout.pattern, model.coordinate_count, &blocks).map_err(|detail| {
                    FlexmbdError::SingularMatrix { time: 0.0, context: context.to_string(), detail }
                })
            };
            LinearSolvers::Direct {
                lu: Box::new(lu),
                ldlt: Box::new(symmetric("symbolic analysis of the iteration matrix")?),
                projection: Box::new(symmetric("symbolic analysis of the projection matrix")?),
            }
        })
    }

    fn with_linear_solvers(model: &Model, linear: LinearSolvers) -> Self {
        let n = model.system_size();
        let normalization_weights = model
            .normalizations
            .iter()
            .map(|nz| match &model.bodies[nz.body.0].kind {
                BodyKind::Rigid(rb) => rb.inertia.trace() / 3.0,
                BodyKind::Flexible(fb) => fb.undeformed_inertia().trace() / 3.0,
                _ => 1.0,
            })
            .collect();
        Workspace {
            markers: model.markers.iter().map(|m| MarkerKinematics::with_size(m.dofs.len())).collect(),
            residual: vec![0.0; n],
            values: vec![0.0; model.layout.pattern.nnz()],
            linear,
            assemble_condensed_blocks: true,
            structured_condensed_coupling: false,
            elastic_rows: ElasticRows::Whole,
            penalties: vec![(0.0, [0.0; 4]); model.normalizations.len()],
            normalization_weights,
            rigid: RigidTangent::default(),
            body_force: vec![0.0; 7],
            flexible: model
                .bodies
                .iter()
                .map(|b| match &b.kind {
                    BodyKind::Flexible(fb) => Some(FlexibleWork::new(fb)),
                    _ => None,
                })
                .collect(),
            joints: model
                .joints
                .iter()
                .map(|j| {
                    let (ne, nd) = (j.equations.len(), j.dofs.len());
                    JointLocal {
                        values: vec![0.0; ne],
                        jacobian: DenseMatrix::zeros(ne, nd),
                        hessian: DenseMatrix::zeros(nd, nd),
                        scratch: vec![0.0; nd],
                        gradient: vec![0.0; nd],
                        gradient_time: vec![0.0; nd],
                        driver: [0.0; 3],
                    }
                })
                .collect(),
            forces: model.forces.iter().map(|f| ForceLocal::with_size(f.dofs.len())).collect(),
            solution: vec![0.0; n],
            scratch: [vec![0.0; n], vec![0.0; n], vec![0.0; n]],
            constraint_coordinates: constraint_coordinates(model),
            matrix_ranges: Default::default(),
        }
    }
}

/// The coordinates of the joints and normalizations, sorted, each once.
fn constraint_coordinates(model: &Model) -> Vec<usize> {
    let mut rows: Vec<usize> = model
        .normalizations
        .iter()
        .flat_map(|nz| nz.dofs)
        .chain(model.joints.iter().flat_map(|j| j.dofs.iter().copied()))
        .collect();
    rows.sort_unstable();
    rows.dedup();
    rows
}
