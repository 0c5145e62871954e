//! Solvers: assembly of the augmented equations, sparse linear algebra, consistent initial
//! conditions and the acceleration system (seed eq. 26), the generalized-alpha integrator and
//! the time loop.

pub mod assembly;
pub mod condensed;
pub mod dense;
pub mod dense_system;
pub mod explicit;
pub mod generalized_alpha;
pub mod initial;
pub mod partition;
pub mod recursive;
pub mod redundancy;
pub mod settings;
pub mod simulate;
pub mod sparse;

pub use settings::{
    Integrator, JacobianUpdate, LinearSolver, NewtonSettings, SimulationSettings, StepControl,
    VelocityProjection,
};
pub use simulate::{simulate, Progress, SimulationOutcome};
