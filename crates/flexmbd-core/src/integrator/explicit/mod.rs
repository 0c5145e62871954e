//! Explicit integration of the constrained equations of motion: the three strategies of seed
//! section 4 ("Numerical solution of the augmented equations"), each with the accelerations
//! from the augmented system (seed eq. 26) or from the embedding technique (seed eqs. 27-30),
//! and a classical Runge-Kutta method of order 4 (fixed step), the embedded Dormand-Prince
//! 5(4) pair (error-controlled step) or, for stiff deformable bodies, the implicit TR-BDF2
//! (error-controlled step; the folder keeps its name: the strategies are those of the explicit
//! integration):
//!
//! 1. `IntegrateAll`: integrate q and q_dot, dependent and independent. The constraints hold
//!    only at the acceleration level, so C and C_q q_dot + C_t drift; Baumgarte's
//!    stabilization replaces gamma by gamma - 2 alpha (C_q q_dot + C_t) - beta^2 C. The drift
//!    is recorded (constraint violation of every output) and reported as an event when it
//!    passes a threshold.
//! 2. `CoordinatePartitioning` (Wehage and Haug): integrate the independent coordinates and
//!    velocities only; at every evaluation the dependent coordinates solve C(q, t) = 0 by
//!    Newton-Raphson and the dependent velocities C_qd qd_d = -(C_qi qd_i + C_t). The partition
//!    is chosen at the start and again (an event) when the dependent block becomes
//!    ill-conditioned.
//! 3. `Projection`: integrate all, then after each step project q onto C = 0 and q_dot onto the
//!    velocity constraints (minimum-norm corrections).
//!
//! The linear algebra is dense (`formulation::augmented`): explicit solvers are meant for rigid
//! and small deformable models, up to `EXPLICIT_COORDINATE_LIMIT` coordinates.
//!
//! Joint coordinates (seed section 5) integrate the joint coordinates of an open tree instead;
//! the body coordinates follow from them.
//!
//! The folder: `engine` (the right-hand sides of every strategy), `partitioning` (2),
//! `projection` (3), `joint_coordinates`, `runge_kutta` (the methods, their stages and error
//! estimate), `trbdf2` (the implicit method and its Newton iterations) and `run` (the start of
//! a run and the step attempts of the time loop).

mod engine;
mod joint_coordinates;
mod partitioning;
mod projection;
mod run;
mod runge_kutta;
mod trbdf2;

pub use run::run;
