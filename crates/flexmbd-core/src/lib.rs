//! # flexmbd-core
//!
//! Flexible multibody dynamics after Shabana, "Constrained motion of deformable bodies"
//! (the seed): bodies in absolute coordinates, joints as algebraic constraints, the augmented
//! Lagrange-multiplier formulation, and implicit time integration. The pipeline, in the order
//! a time step runs it:
//!
//! 1. [`math`]: Euler parameters with exact first and second derivatives, small vectors and
//!    matrices, functions of time.
//! 2. [`body`]: rigid bodies and point masses; the generalized Newton-Euler equations of
//!    seed eq. 15 (inertia forces, mass matrix, quadratic velocity vector) and their
//!    Jacobians; markers (frames on bodies) with their kinematics.
//! 3. [`force`]: gravity, point forces and torques, spring-dampers, user callbacks, by virtual
//!    work (seed section 3).
//! 4. [`joint`]: constraint equations C(q, t) = 0 of seed eqs. 19-25 in dot-product form,
//!    their Jacobians, Hessians and gamma; drivers; reaction forces.
//! 5. [`system`]: the `SystemBuilder`, the compiled immutable `Model`, the `State` and the
//!    preallocated `Workspace`.
//! 6. [`solver`]: assembly of the augmented system (seed eqs. 20, 26) on a sparse pattern fixed
//!    at compile time, sparse LU (symbolic once, numeric per iteration), consistent initial
//!    conditions, index-3 generalized-alpha with step-size control, the time loop.
//! 7. [`output`]: recorded results, reactions, sensors, energies.
//!
//! The preprocessor (seed section 3, "computational strategy"), run once per deformable body:
//! [`fem`]: materials, beam sections, element kernels, assembly, invariants of motion.
//!
//! Units are SI by convention; the core itself is unit-agnostic.

pub mod assembly;
pub mod body;
pub mod error;
pub mod fem;
pub mod force;
pub mod formulation;
pub mod ids;
pub mod integrator;
pub mod joint;
pub mod linalg;
pub mod linear_system;
pub mod math;
pub mod output;
pub mod system;

pub use error::{FlexmbdError, Result};
pub use ids::{BodyId, ForceId, JointId, MarkerId, SensorId};
pub use system::{Model, State, SystemBuilder, Workspace};
