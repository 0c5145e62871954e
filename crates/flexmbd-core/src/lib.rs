//! # flexmbd-core
//!
//! Flexible multibody dynamics after Shabana, "Constrained motion of deformable bodies"
//! (the seed): deformable bodies in a floating frame of reference, joints as algebraic
//! constraints, the augmented Lagrange-multiplier formulation, the recursive formulation in
//! joint coordinates with decoupled joint and elastic accelerations, and time integration.
//! The folders are the stages of a time step, each using only those above it in this list
//! (`tools/check_imports.py` checks it; `docs/architecture.md` follows one step through them):
//!
//! 1. [`math`]: Euler parameters with exact derivatives, small vectors and matrices,
//!    hyper-dual numbers, functions of time.
//! 2. [`linalg`]: compressed sparse columns, sparse LU and LDL^T (pattern and symbolic analysis
//!    once), dense LU, symmetric and envelope factors, partitions of constraint Jacobians (LU,
//!    QR, SVD), the AVX2 kernels, the worker threads of parallel factorizations.
//! 3. [`fem`] (the preprocessor, once per deformable body): elements, quadrature, materials,
//!    sections, assembly of K, M and the invariants of motion (seed eqs. 9, 16-17).
//! 4. [`body`]: rigid bodies, point masses and deformable bodies (the generalized Newton-Euler
//!    equations of seed eq. 15 from the invariants, their Jacobians), markers, stiffening.
//! 5. [`joint`] and [`force`]: constraints C(q, t) = 0 of seed eqs. 19-25 with Jacobians,
//!    Hessians and gamma, drivers, reactions; applied forces by virtual work (seed section 3).
//! 6. [`system`]: the builder, the compiled immutable `Model`, the `State`, the `Workspace`
//!    (buffers only).
//! 7. [`assembly`]: the residual and Newton matrix of the augmented equations (seed eqs. 20,
//!    26) on a pattern fixed at compile time, as an `assembly::Request` asks.
//! 8. [`linear_system`]: the solvers of the Newton systems (sparse, dense, and the condensed
//!    solver that eliminates the elastic coordinates of large bodies).
//! 9. [`formulation`]: the equations in their dense augmented and embedded forms (seed eqs. 26,
//!    30), in joint coordinates (seed eqs. 31-32), and with decoupled accelerations (seed eqs.
//!    33-41).
//! 10. [`output`]: records, reactions, sensors, energies, events.
//! 11. [`integrator`]: settings, consistent initial conditions, redundancy, index-3
//!     generalized-alpha, explicit Runge-Kutta with the seed's strategies, the one time loop.
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
pub mod names;
pub mod output;
pub mod system;
#[doc(hidden)]
pub mod testing;

pub use error::{FlexmbdError, Result};
pub use ids::{BodyId, ForceId, JointId, MarkerId, SensorId};
pub use system::{Model, State, SystemBuilder, Workspace};
