//! Implicit index-3 generalized-alpha method for constrained mechanical systems
//! (Arnold and Bruls, Multibody System Dynamics 18, 2007, Algorithm 1; Chung and Hulbert 1993
//! for the parameters), with Bottasso's scaling of the constraint equations.
//!
//! Per step of size h the unknowns are q_dd(n+1) and lambda(n+1); with the auxiliary
//! accelerations a:
//!   (1 - alpha_m) a(n+1) + alpha_m a(n) = (1 - alpha_f) q_dd(n+1) + alpha_f q_dd(n)
//!   q(n+1)     = q(n) + h q_dot(n) + h^2 (1/2 - beta) a(n) + h^2 beta a(n+1)
//!   q_dot(n+1) = q_dot(n) + h (1 - gamma) a(n) + h gamma a(n+1)
//! and the equations r = M q_dd - F - Q_e + C_q^T lambda = 0, C(q, t(n+1)) = 0 are solved by
//! Newton's method in the increment dq, with dq_dot = gamma' dq, dq_dd = beta' dq,
//! gamma' = gamma/(beta h), beta' = (1 - alpha_m)/((1 - alpha_f) beta h^2). The coordinate
//! rows are multiplied by s = beta h^2 and the multiplier increment is s dlambda, which keeps
//! the Newton matrix well conditioned for small h:
//!   [[s (beta' M + gamma' D + K), C_q^T], [C_q, 0]] [dq; s dlambda] = -[s r; C].
//!
//! A run (`run`) starts from consistent initial conditions with the auxiliary accelerations of
//! Arnold and Bruls, and makes its step attempts through the time loop (`time_loop`): the
//! predictor and Newton's method (`newton`), then the projection of the velocities in the
//! metric of the mass matrix (`projection`) where it is on.

mod newton;
mod projection;
mod run;

pub(crate) use run::run;

use crate::assembly::MatrixCoefficients;
use crate::error::{FlexmbdError, Result};
use crate::integrator::settings::{JacobianUpdate, LinearSolver, NewtonSettings};
use crate::linear_system::LinearSolvers;
use crate::system::{Model, State, Workspace};
use newton::iterate;

/// The four parameters of the method.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GeneralizedAlpha {
    /// alpha_m.
    pub alpha_m: f64,
    /// alpha_f.
    pub alpha_f: f64,
    /// beta (Newmark).
    pub beta: f64,
    /// gamma (Newmark).
    pub gamma: f64,
}

impl GeneralizedAlpha {
    /// Parameters of second order and optimal dissipation for the spectral radius at infinite
    /// frequency `rho` in [0, 1] (1: no numerical dissipation).
    pub fn from_spectral_radius(rho: f64) -> Result<Self> {
        if !(0.0..=1.0).contains(&rho) {
            return Err(FlexmbdError::InvalidParameter {
                item: "generalized-alpha".to_string(),
                message: format!("spectral radius must be in [0, 1], got {rho}"),
            });
        }
        let alpha_m = (2.0 * rho - 1.0) / (rho + 1.0);
        let alpha_f = rho / (rho + 1.0);
        let gamma = 0.5 + alpha_f - alpha_m;
        let beta = 0.25 * (gamma + 0.5) * (gamma + 0.5);
        Ok(GeneralizedAlpha { alpha_m, alpha_f, beta, gamma })
    }

    /// The constant c of the local error estimate c h^2 |q_dd(n+1) - q_dd(n)| of a step in
    /// the positions (the error-based step control's, and the yardstick of Newton's
    /// `NewtonSettings::error_fraction`): |beta - 1/6|, at least 1/12 (the trapezoidal rule's
    /// beta = 1/4 has the error (1/12) h^3 q_ddd).
    pub fn local_error_constant(&self) -> f64 {
        (self.beta - 1.0 / 6.0).abs().max(1.0 / 12.0)
    }

    /// Iteration-matrix coefficients for step size h: (beta', gamma', s).
    pub fn coefficients(&self, h: f64) -> MatrixCoefficients {
        let s = self.beta * h * h;
        MatrixCoefficients {
            mass: (1.0 - self.alpha_m) / ((1.0 - self.alpha_f) * s),
            velocity: self.gamma / (self.beta * h),
            position: 1.0,
            identity: 0.0,
            elastic_identity: 0.0,
            scale: s,
        }
    }
}

/// What happened in one attempted step.
#[derive(Clone, Debug, Default)]
pub struct StepReport {
    /// True if Newton's method converged.
    pub converged: bool,
    /// Newton iterations made.
    pub iterations: usize,
    /// Numeric factorizations made.
    pub factorizations: usize,
    /// Last weighted increment norm (converged at <= 1).
    pub increment_norm: f64,
    /// Contraction rate of the iteration (see `newton::convergence`): the largest after the
    /// first increment of a converged iteration, the last of a failed one; 0 when not measured.
    pub contraction: f64,
    /// Coordinate index of the largest last increment.
    pub worst: usize,
    /// Why it failed, if it did (for messages).
    pub failure: Option<String>,
}

/// Which factorization holds a matrix.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Factorization {
    /// Sparse LU of the exact Newton matrix.
    #[default]
    Lu,
    /// LDL^T of the symmetrized, quasi-definite Newton matrix.
    Ldlt,
    /// LDL^T of the mass-matrix saddle point of the velocity projection.
    Projection,
}

/// Cache of the factorized Newton matrix between steps (modified Newton).
#[derive(Clone, Debug, Default)]
pub struct JacobianCache {
    /// Step size the current factorization was made for (None: no valid factorization).
    pub step_size: Option<f64>,
    /// The factorization it is held in.
    pub kind: Factorization,
    /// Steps taken with it.
    pub age: usize,
}

/// Sets `next` to the predictor of a step of size h from `current`: q_dd(n+1) and
/// lambda(n+1) extrapolated linearly from the last two steps (constant at the first step);
/// q(n+1), q_dot(n+1) follow from the generalized-alpha update.
fn predict(method: &GeneralizedAlpha, h: f64, current: &State, next: &mut State) {
    let GeneralizedAlpha { alpha_m, alpha_f, beta, gamma } = *method;
    let ratio = if current.previous_step_size > 0.0 { h / current.previous_step_size } else { 0.0 };
    next.time = current.time + h;
    next.previous_step_size = h;
    next.discrete.copy_from_slice(&current.discrete);
    next.previous_accelerations.copy_from_slice(&current.accelerations);
    next.previous_multipliers.copy_from_slice(&current.multipliers);
    for (k, l) in next.multipliers.iter_mut().enumerate() {
        let now = current.multipliers[k];
        *l = now + ratio * (now - current.previous_multipliers[k]);
    }
    for k in 0..current.coordinates.len() {
        let qdd = current.accelerations[k];
        let guess = qdd + ratio * (qdd - current.previous_accelerations[k]);
        let a_n = current.algorithmic_accelerations[k];
        let a = (alpha_f * qdd + (1.0 - alpha_f) * guess - alpha_m * a_n) / (1.0 - alpha_m);
        next.accelerations[k] = guess;
        next.algorithmic_accelerations[k] = a;
        next.coordinates[k] =
            current.coordinates[k] + h * current.velocities[k] + h * h * ((0.5 - beta) * a_n + beta * a);
        next.velocities[k] = current.velocities[k] + h * ((1.0 - gamma) * a_n + gamma * a);
    }
}

/// Attempts one step of size `h` from `current` into `next`. Non-convergence is reported in
/// the returned report (the caller may retry with a smaller step); errors that a smaller step
/// cannot cure (callbacks, NaN in the model data) are returned as `Err`.
#[allow(clippy::too_many_arguments)]
pub fn step(
    model: &Model,
    method: &GeneralizedAlpha,
    newton: &NewtonSettings,
    project_velocities: bool,
    h: f64,
    current: &State,
    next: &mut State,
    ws: &mut Workspace,
    solvers: &mut LinearSolvers,
    cache: &mut JacobianCache,
) -> Result<StepReport> {
    let coef = method.coefficients(h);

    // With one factorization per step, the matrix is refreshed at the predictor and kept for
    // the step's iterations. If an attempt that reused a matrix fails, the step restarts
    // from the predictor with full Newton.
    if newton.jacobian == JacobianUpdate::EveryStep {
        cache.step_size = None;
    }
    let reuse = newton.jacobian != JacobianUpdate::EveryIteration;
    let (first_kind, exact_kind) = factorization_kinds(newton.linear_solver, reuse);
    if let LinearSolvers::Condensed { newton, .. } = solvers {
        newton.set_angular_velocities(model, &current.coordinates, &current.velocities);
    }
    predict(method, h, current, next);
    let local_error = method.local_error_constant() * h * h;
    let mut report =
        iterate(model, coef, newton, reuse, first_kind, h, local_error, next, ws, solvers, cache)?;
    if !report.converged && reuse && (report.factorizations < report.iterations || first_kind != exact_kind) {
        let first = report.clone();
        predict(method, h, current, next);
        cache.step_size = None;
        let second =
            iterate(model, coef, newton, false, exact_kind, h, local_error, next, ws, solvers, cache)?;
        report = second;
        report.iterations += first.iterations;
        report.factorizations += first.factorizations;
    }
    if !report.converged {
        return Ok(report);
    }
    // An iteration whose first increment ran away (a singular symmetrized matrix: a tumbling
    // beam with an offset mass reached q ~ 1e223) meets the test of increments relative to the
    // accelerations it reached: a step that moves a coordinate by more than STEP_MOVE_LIMIT
    // times max(1, |q|) has not converged to the motion.
    if let Some((k, moved)) = runaway_coordinate(&current.coordinates, &next.coordinates) {
        report.converged = false;
        report.worst = k;
        report.failure = Some(format!("the step moved the coordinate by {moved:.3e} of its size"));
        cache.step_size = None;
        return Ok(report);
    }
    cache.age += 1;
    let max_age = if solvers.is_condensed() { newton.condensed_matrix_age } else { newton.max_matrix_age };
    if cache.age >= max_age {
        cache.step_size = None;
    }
    // Velocity projection in the metric of the mass matrix (`projection`).
    if project_velocities && model.constraint_count > 0 {
        projection::project(model, next, ws, solvers, &mut report)?;
        if !report.converged {
            return Ok(report);
        }
    }
    update_algorithmic_accelerations(model, method, current, next);
    Ok(report)
}

/// Largest change of a coordinate over one step, relative to max(1, |q|), that a converged
/// step may make (a body at 1000 m/s near the origin moves 1 m in a step of 1 ms).
const STEP_MOVE_LIMIT: f64 = 100.0;

/// The coordinate that a step from `before` to `after` moved by more than `STEP_MOVE_LIMIT`
/// times max(1, its size), and that relative change; None where none did (or a change
/// is not finite: the time loop names it).
fn runaway_coordinate(before: &[f64], after: &[f64]) -> Option<(usize, f64)> {
    let mut worst = None;
    for (k, (a, b)) in before.iter().zip(after).enumerate() {
        let moved = (b - a).abs() / a.abs().max(1.0);
        if moved > STEP_MOVE_LIMIT && worst.map_or(true, |(_, m)| moved > m) {
            worst = Some((k, moved));
        }
    }
    worst
}

/// The factorizations of a step's Newton matrix: of its first attempt, and of the exact
/// attempt that follows a failed one (LDL^T of the symmetrized matrix is tried first with
/// `LinearSolver::Auto` and matrix reuse).
fn factorization_kinds(solver: LinearSolver, reuse: bool) -> (Factorization, Factorization) {
    match solver {
        LinearSolver::Lu => (Factorization::Lu, Factorization::Lu),
        LinearSolver::Ldlt => (Factorization::Ldlt, Factorization::Ldlt),
        LinearSolver::Auto if reuse => (Factorization::Ldlt, Factorization::Lu),
        LinearSolver::Auto => (Factorization::Lu, Factorization::Lu),
    }
}

/// Auxiliary accelerations a(n+1) of `next` from its converged q_dd:
/// (1 - alpha_m) a(n+1) = (1 - alpha_f) q_dd(n+1) + alpha_f q_dd(n) - alpha_m a(n).
fn update_algorithmic_accelerations(
    model: &Model,
    method: &GeneralizedAlpha,
    current: &State,
    next: &mut State,
) {
    let GeneralizedAlpha { alpha_m, alpha_f, .. } = *method;
    for k in 0..model.coordinate_count {
        next.algorithmic_accelerations[k] = (alpha_f * current.accelerations[k]
            + (1.0 - alpha_f) * next.accelerations[k]
            - alpha_m * current.algorithmic_accelerations[k])
            / (1.0 - alpha_m);
    }
}
