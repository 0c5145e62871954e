//! Preallocated buffers and derived quantities (house style 1 and 3): everything the
//! assembly and the solvers write during a step, sized once when a simulation starts, so that
//! the hot path does not allocate.

use crate::body::flexible::{FlexibleBody, FlexibleScratch, FlexibleTangent, REFERENCE_COORDINATES};
use crate::body::is_condensed;
use crate::body::marker::MarkerKinematics;
use crate::body::rigid::RigidTangent;
use crate::body::BodyKind;
use crate::force::ForceLocal;
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

/// Workspace of a simulation of one model.
pub struct Workspace {
    /// Kinematics of every marker (filled by `update_kinematics`).
    pub markers: Vec<MarkerKinematics>,
    /// Residual [r (coordinates); C (constraints)] (system size); filled by `assemble`.
    pub residual: Vec<f64>,
    /// Values of the Newton matrix on the model's pattern (nnz); filled by `assemble`.
    pub values: Vec<f64>,
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
    /// without `condensed_blocks`, their reference-elastic coupling with
    /// `structured_coupling`; see [`crate::assembly::Request`]). A condensed body's elastic pattern holds most of the
    /// matrix's entries (about 43,000 of the 45,085 with a body of 960 elastic coordinates):
    /// zeroing it at every refresh of the iteration matrix cost more than the rest of its
    /// assembly.
    pub fn zero_matrix(&mut self, model: &Model, condensed_blocks: bool, structured_coupling: bool) {
        let slot = match (condensed_blocks, structured_coupling) {
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

    /// Allocates every buffer for `model` (the linear solvers are apart:
    /// [`crate::linear_system::LinearSolvers`]).
    pub fn new(model: &Model) -> Self {
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
