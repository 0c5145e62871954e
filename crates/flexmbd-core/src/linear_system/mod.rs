//! The solvers of the Newton systems that the integrator owns: the condensed solver, which
//! eliminates the elastic coordinates of large deformable bodies through their constant
//! factorized iteration matrices (the sparse LU of the whole matrix is in [`crate::linalg`]).

pub mod condensed;

use crate::error::{FlexmbdError, Result};
use crate::linalg::dense::{DenseLu, DENSE_SYSTEM_SIZE};
use crate::linalg::sparse::{SparseLdlt, SparseLu};
use crate::system::Model;
use condensed::CondensedSolver;

/// Message of a solve attempted without linear solvers.
pub const NO_SOLVERS: &str = "no linear solvers (evaluation only)";

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
    /// Small models (at most `linalg::dense::DENSE_SYSTEM_SIZE` unknowns): dense LU.
    Dense {
        /// Newton iteration matrix (modified and exact Newton).
        newton: Box<DenseLu>,
        /// Projection, acceleration and initial-condition systems.
        projection: Box<DenseLu>,
    },
    /// Models with large deformable bodies: their elastic coordinates condensed out
    /// (`linear_system::condensed`), one solver for the Newton matrix, one for the projection and
    /// acceleration systems.
    Condensed {
        /// Newton iteration matrix.
        newton: Box<CondensedSolver>,
        /// Projection, acceleration and initial-condition systems.
        projection: Box<CondensedSolver>,
    },
    /// No factorizations: a workspace for evaluating the equations only
    /// (evaluation only).
    None,
}

impl LinearSolvers {
    /// The factorizations of `model`'s Newton matrices, symbolic analysis done: condensed for
    /// models with condensed bodies, dense LU for small ones, sparse LU and LDL^T otherwise.
    pub fn new(model: &Model) -> Result<Self> {
        let size = model.system_size();
        Ok(if model.has_condensed_bodies() {
            Self::Condensed {
                newton: Box::new(CondensedSolver::with_images(model, true, true)?),
                projection: Box::new(CondensedSolver::new(model, false)?),
            }
        } else if size <= DENSE_SYSTEM_SIZE {
            Self::Dense { newton: Box::new(DenseLu::new(size)), projection: Box::new(DenseLu::new(size)) }
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
            Self::Direct {
                lu: Box::new(lu),
                ldlt: Box::new(symmetric("symbolic analysis of the iteration matrix")?),
                projection: Box::new(symmetric("symbolic analysis of the projection matrix")?),
            }
        })
    }

    /// Whether the elastic coordinates of condensed bodies are condensed out.
    pub fn is_condensed(&self) -> bool {
        matches!(self, Self::Condensed { .. })
    }

    /// The images of the coupling columns of the last solve of the condensed Newton solver,
    /// by body (empty for the other solvers): what the assembly of `ElasticRows::Update`
    /// rows needs.
    pub fn coupling_images(&mut self) -> Vec<(usize, &[f64])> {
        match self {
            Self::Condensed { newton, .. } => newton.coupling_images().collect(),
            _ => Vec::new(),
        }
    }
}
