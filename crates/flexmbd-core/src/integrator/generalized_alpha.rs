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

use crate::assembly::{assemble, MatrixCoefficients, StateView};
use crate::assembly::{ElasticRows, Request};
use crate::error::{FlexmbdError, Result};
use crate::integrator::settings::{JacobianUpdate, LinearSolver, NewtonSettings};
use crate::linear_system::{LinearSolvers, NO_SOLVERS};
use crate::system::{Model, State, Workspace};

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

    /// Iteration-matrix coefficients for step size h: (beta', gamma', s).
    pub fn coefficients(&self, h: f64) -> MatrixCoefficients {
        let s = self.beta * h * h;
        MatrixCoefficients {
            mass: (1.0 - self.alpha_m) / ((1.0 - self.alpha_f) * s),
            velocity: self.gamma / (self.beta * h),
            position: 1.0,
            identity: 0.0,
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

/// Factorizes the assembled Newton matrix in `ws.values` (assembled with the coefficients
/// `coef`) with `kind`. For LDL^T the normalization constraints get the penalty
/// s kappa (2p)(2p)^T: adding s kappa C_n^T C_n to the coordinate block leaves dq unchanged
/// (C_n dq is fixed by the constraint rows) and only shifts dmu_n by s kappa C_n dq, which
/// `solve` takes back. Models with condensed deformable bodies factorize their Schur
/// complement instead (`linear_system::condensed`; LU of the reduced system, whatever `kind`).
fn factorize(
    model: &Model,
    ws: &mut Workspace,
    solvers: &mut LinearSolvers,
    kind: Factorization,
    coef: &MatrixCoefficients,
    q: &[f64],
) -> std::result::Result<(), String> {
    let scale = coef.scale;
    match solvers {
        LinearSolvers::Dense { newton, projection } => {
            let target = if kind == Factorization::Projection { projection } else { newton };
            target.factorize(&model.layout.pattern, &ws.values)
        }
        LinearSolvers::Condensed { newton, projection } => {
            let target = if kind == Factorization::Projection { projection } else { newton };
            target.factorize(model, &ws.values, coef, q).map_err(|e| e.to_string())
        }
        LinearSolvers::Direct { lu, ldlt, projection } => match kind {
            Factorization::Lu => lu.factorize(&ws.values),
            Factorization::Ldlt | Factorization::Projection => {
                for (k, nz) in model.normalizations.iter().enumerate() {
                    ws.penalties[k] = (
                        scale * ws.normalization_weights[k],
                        [q[nz.dofs[0]], q[nz.dofs[1]], q[nz.dofs[2]], q[nz.dofs[3]]],
                    );
                }
                let target = if kind == Factorization::Ldlt { ldlt } else { projection };
                target.factorize(&ws.values, &ws.penalties)
            }
        },
        LinearSolvers::None => Err(NO_SOLVERS.to_string()),
    }
}

/// Solves with the factorization `kind` in place in `ws.solution`.
fn solve(
    model: &Model,
    ws: &mut Workspace,
    solvers: &mut LinearSolvers,
    kind: Factorization,
    scale: f64,
) -> std::result::Result<(), String> {
    match solvers {
        LinearSolvers::Dense { newton, projection } => {
            let target = if kind == Factorization::Projection { projection } else { newton };
            target.solve_in_place(&mut ws.solution)
        }
        LinearSolvers::Condensed { newton, projection } => {
            let target = if kind == Factorization::Projection { projection } else { newton };
            target.solve_in_place(&mut ws.solution)
        }
        LinearSolvers::Direct { lu, ldlt, projection } => match kind {
            Factorization::Lu => lu.solve_in_place(&mut ws.solution),
            Factorization::Ldlt | Factorization::Projection => {
                let nq = model.coordinate_count;
                // C_n dq equals the right-hand side of the normalization rows.
                for (k, nz) in model.normalizations.iter().enumerate() {
                    ws.scratch[2][k] = ws.solution[nq + nz.row];
                }
                let target = if kind == Factorization::Ldlt { ldlt } else { projection };
                target.solve_in_place(&mut ws.solution)?;
                for (k, nz) in model.normalizations.iter().enumerate() {
                    ws.solution[nq + nz.row] += scale * ws.normalization_weights[k] * ws.scratch[2][k];
                }
                Ok(())
            }
        },
        LinearSolvers::None => Err(NO_SOLVERS.to_string()),
    }
}

/// Weighted norm of the Newton increment (converged at <= 1), the index of its largest entry,
/// and the largest position increment relative to max(1, |q_k|) (the round-off test of the
/// iteration). The norm has two parts.
///
/// Positions: each increment is measured against
///   w_k = tol max(1, |q_dd|_inf) / beta' + 1e-14 max(1, |q_k|):
/// the first term is the tolerance on the accelerations (dq_dd = beta' dq; a tolerance on
/// positions alone would let an equation-of-motion residual of order tol/(beta h^2) pass,
/// whose velocity error accumulates), the second the round-off floor of the positions, which
/// dominates for very small steps.
///
/// Multipliers (only with `multipliers`): the generalized constraint force of their
/// increment, |C_q^T dlambda|_inf, against tol max(1, |C_q^T lambda|_inf). In the index-3
/// form a multiplier error does not show in dq at all (q is held by C(q) = 0), so an
/// iteration with a matrix reused from an earlier iterate needs this test, and so does one
/// with the approximate iteration matrix of condensed bodies. A step with the exact matrix
/// factorized at the current iterate gives multipliers accurate to second order in dq,
/// and near singular configurations their increments are round-off amplified by the inverse
/// of the smallest singular value of C_q, which no test could pass: there it is skipped.
fn increment_norm(
    coef: &MatrixCoefficients,
    tol: f64,
    largest_acceleration: f64,
    state: &State,
    increment: &[f64],
    multipliers: Option<ConstraintForces>,
) -> IncrementNorm {
    let acceleration_weight = tol * largest_acceleration.max(1.0) / coef.mass;
    // One pass for the norm and the relative position increment, dividing only where a ratio
    // may grow (a product compares).
    let (largest, at, position) =
        crate::linalg::simd::increment_ratios(increment, &state.coordinates, acceleration_weight);
    let mut worst = (at, largest);
    if let Some(ConstraintForces { rows, increment, force, scale }) = multipliers {
        let f_scale = rows.iter().fold(1.0f64, |m, &d| m.max(force[d].abs()));
        let (mut k, mut df) = (0, 0.0f64);
        for &d in rows {
            let v = (increment[d] / scale).abs();
            if v > df {
                (k, df) = (d, v);
            }
        }
        let v = df / (tol * f_scale);
        if v > worst.1 {
            worst = (k, v);
        }
    }
    IncrementNorm { norm: worst.1, worst: worst.0, position }
}

/// The constraint forces of the multipliers' test in [`increment_norm`]: C_q^T dlambda
/// (`increment`, times `scale`) and C_q^T lambda (`force`), nonzero only at `rows` (the
/// coordinates of the joints and normalizations).
struct ConstraintForces<'a> {
    rows: &'a [usize],
    increment: &'a [f64],
    force: &'a [f64],
    scale: f64,
}

/// The weighted increment norm, the index of its largest entry, and the largest position
/// increment relative to max(1, |q_k|).
struct IncrementNorm {
    norm: f64,
    worst: usize,
    position: f64,
}

/// The Newton update of the coordinates, velocities and accelerations of `state` by
/// (1, gamma', beta') dq; returns max |q_dd| after it (0 for none; NaN entries are passed
/// over), in the same pass: four partial maxima (a single running maximum is a chain of
/// dependent operations), by comparisons the compiler vectorizes.
fn update_state(state: &mut State, dq: &[f64], coef: &MatrixCoefficients) -> f64 {
    let (v, m) = (coef.velocity, coef.mass);
    let n = dq.len();
    let (q, qd, qdd) =
        (&mut state.coordinates[..n], &mut state.velocities[..n], &mut state.accelerations[..n]);
    let mut largest = [0.0f64; 4];
    let groups = q.chunks_mut(4).zip(qd.chunks_mut(4)).zip(qdd.chunks_mut(4)).zip(dq.chunks(4));
    for (((q, qd), qdd), dq) in groups {
        for (i, top) in largest.iter_mut().enumerate().take(dq.len()) {
            let d = dq[i];
            q[i] += d;
            qd[i] += v * d;
            qdd[i] += m * d;
            let a = qdd[i].abs();
            *top = if a > *top { a } else { *top };
        }
    }
    largest.into_iter().fold(0.0, |t, a| if a > t { a } else { t })
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

/// Newton iterations from the state in `next`. With `reuse`, a factorization cached for this
/// step size is used as long as it contracts well (and refreshed when it does not); without,
/// the matrix is refactorized every iteration.
#[allow(clippy::too_many_arguments)]
fn iterate(
    model: &Model,
    coef: MatrixCoefficients,
    newton: &NewtonSettings,
    reuse: bool,
    kind: Factorization,
    h: f64,
    next: &mut State,
    ws: &mut Workspace,
    solvers: &mut LinearSolvers,
    cache: &mut JacobianCache,
) -> Result<StepReport> {
    let nq = model.coordinate_count;
    let nc = model.constraint_count;
    let s = coef.scale;
    let mut report = StepReport::default();
    let mut previous_norm = f64::INFINITY;
    // Whether the matrix was factorized at the predictor, in the first iteration of this step.
    let mut fresh_at_predictor = false;
    // The condensed solver's iteration matrix (not the exact Jacobian, see below).
    let approximate_matrix = kind != Factorization::Projection && solvers.is_condensed();
    let condensed_rows = approximate_matrix && coef.position == 1.0 && coef.identity == 0.0;
    for iteration in 0..newton.max_iterations {
        // A step shortened by round-off to land on an output time keeps the matrix.
        let same_h = cache.step_size.is_some_and(|c| crate::math::equal_to_round_off(c, h));
        let need_matrix = !reuse || !same_h || cache.kind != kind;
        fresh_at_predictor |= iteration == 0 && need_matrix;
        let view = StateView::of(next);
        // Elastic rows of condensed bodies from the last condensed solve after the first
        // iteration (see `ElasticRows`; the update of the coordinates below is the one it
        // requires).
        let elastic_rows = match (condensed_rows, iteration) {
            (false, _) => ElasticRows::Whole,
            (true, 0) => ElasticRows::Keep,
            (true, _) => ElasticRows::Update { scale: s },
        };
        let images = if matches!(elastic_rows, ElasticRows::Update { .. }) {
            solvers.coupling_images()
        } else {
            Vec::new()
        };
        let request = Request {
            matrix: need_matrix.then_some(coef),
            condensed_blocks: false,
            structured_coupling: need_matrix && kind != Factorization::Projection,
            elastic_rows,
            images: &images,
        };
        let assembled = assemble(model, view, ws, &request);
        drop(images);
        assembled?;
        if need_matrix {
            if let Err(detail) = factorize(model, ws, solvers, kind, &coef, &next.coordinates) {
                cache.step_size = None;
                report.failure = Some(format!("singular Newton matrix: {detail}"));
                return Ok(report);
            }
            cache.step_size = Some(h);
            cache.kind = kind;
            cache.age = 0;
            report.factorizations += 1;
        }
        let (coordinate_rows, constraint_rows) = ws.residual[..nq + nc].split_at(nq);
        for (x, r) in ws.solution[..nq].iter_mut().zip(coordinate_rows) {
            *x = -s * r;
        }
        for (x, r) in ws.solution[nq..nq + nc].iter_mut().zip(constraint_rows) {
            *x = -r;
        }
        if let Err(detail) = solve(model, ws, solvers, kind, s) {
            cache.step_size = None;
            report.failure = Some(format!("singular Newton matrix: {detail}"));
            return Ok(report);
        }
        // With a matrix reused from an earlier iterate, the multipliers are tested through the
        // constraint forces C_q^T dlambda of the increment (and C_q^T lambda before it), with
        // the Jacobians of this iterate: nonzero only at the constraints' coordinates. So is
        // the condensed iteration matrix even when factorized at this iterate: it is not the
        // exact Jacobian (the constant A, the mass part of the reference coupling), and its
        // multipliers converge at its rate, not to second order.
        let check_multipliers = !need_matrix || approximate_matrix;
        let [force_increment, force, _] = &mut ws.scratch;
        if check_multipliers {
            for &d in &ws.constraint_coordinates {
                force_increment[d] = 0.0;
                force[d] = 0.0;
            }
            let (q, lambda) = (&next.coordinates, &next.multipliers);
            crate::assembly::add_constraint_force_pair(
                model,
                q,
                &ws.joints,
                [&ws.solution[nq..], lambda],
                [&mut force_increment[..], &mut force[..]],
            );
        }
        let largest_acceleration = update_state(next, &ws.solution[..nq], &coef);
        for k in 0..nc {
            next.multipliers[k] += ws.solution[nq + k] / s;
        }
        report.iterations = iteration + 1;
        let multipliers = check_multipliers.then_some(ConstraintForces {
            rows: &ws.constraint_coordinates,
            increment: &ws.scratch[0],
            force: &ws.scratch[1],
            scale: s,
        });
        let IncrementNorm { norm, worst, position: position_increment } = increment_norm(
            &coef,
            newton.tolerance,
            largest_acceleration,
            next,
            &ws.solution[..nq],
            multipliers,
        );
        report.increment_norm = norm;
        report.worst = worst;
        if !norm.is_finite() {
            report.failure = Some("non-finite increment".to_string());
            cache.step_size = None;
            return Ok(report);
        }
        let rate = norm / previous_norm;
        // Remaining error estimated from the contraction rate (Hairer and Wanner). With a
        // matrix reused from an earlier step, the first rate (measured from the predictor,
        // whose error is of another order) is not trusted; with a matrix factorized at the
        // predictor, the first increment was a Newton step and the rate after it measures the
        // contraction of the iterations that follow.
        let rate_trusted = iteration > 1 || (iteration == 1 && (need_matrix || fresh_at_predictor));
        let estimated_error_small = rate_trusted && rate < 1.0 && rate / (1.0 - rate) * norm <= 1.0;
        // Near singular configurations the Newton matrix is ill-conditioned and the increments
        // stall at a round-off level amplified by its condition: once the relative position
        // increment is below 1e-10 and no longer decreases, with a current matrix, the
        // iteration has converged as far as it can.
        let at_roundoff = position_increment <= 1e-10;
        let stalled_at_roundoff = need_matrix && iteration >= 1 && rate >= 0.5 && at_roundoff;
        if norm <= 1.0 || estimated_error_small || stalled_at_roundoff {
            report.converged = true;
            return Ok(report);
        }
        if iteration >= 2 && rate > 1.0 && !at_roundoff {
            report.failure = Some(format!("increments grow (contraction rate {rate:.2})"));
            return Ok(report);
        }
        if reuse && rate > newton.contraction_limit && iteration > 0 {
            // Slow contraction: refresh the matrix at the current iterate.
            cache.step_size = None;
        }
        previous_norm = norm;
    }
    report.failure = Some(format!("no convergence in {} iterations", newton.max_iterations));
    Ok(report)
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
    let nq = model.coordinate_count;
    let nc = model.constraint_count;
    let GeneralizedAlpha { alpha_m, alpha_f, .. } = *method;
    let coef = method.coefficients(h);

    // With one factorization per step, the matrix is refreshed at the predictor and kept for
    // the step's iterations. If an attempt that reused a matrix fails, the step restarts
    // from the predictor with full Newton.
    if newton.jacobian == JacobianUpdate::EveryStep {
        cache.step_size = None;
    }
    let reuse = newton.jacobian != JacobianUpdate::EveryIteration;
    let (first_kind, exact_kind) = match newton.linear_solver {
        LinearSolver::Lu => (Factorization::Lu, Factorization::Lu),
        LinearSolver::Ldlt => (Factorization::Ldlt, Factorization::Ldlt),
        LinearSolver::Auto if reuse => (Factorization::Ldlt, Factorization::Lu),
        LinearSolver::Auto => (Factorization::Lu, Factorization::Lu),
    };
    if let LinearSolvers::Condensed { newton, .. } = solvers {
        newton.set_angular_velocities(model, &current.coordinates, &current.velocities);
    }
    predict(method, h, current, next);
    let mut report = iterate(model, coef, newton, reuse, first_kind, h, next, ws, solvers, cache)?;
    if !report.converged && reuse && (report.factorizations < report.iterations || first_kind != exact_kind) {
        let first = report.clone();
        predict(method, h, current, next);
        cache.step_size = None;
        let second = iterate(model, coef, newton, false, exact_kind, h, next, ws, solvers, cache)?;
        report = second;
        report.iterations += first.iterations;
        report.factorizations += first.factorizations;
    }
    if !report.converged {
        return Ok(report);
    }
    cache.age += 1;
    let max_age = if solvers.is_condensed() { newton.condensed_matrix_age } else { newton.max_matrix_age };
    if cache.age >= max_age {
        cache.step_size = None;
    }

    // Velocity projection in the metric of the mass matrix: the correction dv solves
    // [[M, C_q^T], [C_q, 0]] [dv; mu] = [0; -(C_q q_dot + C_t)], the smallest change of kinetic
    // energy that satisfies the velocity constraints. It removes the undamped error mode along
    // the constraint normals that the index-3 method has at spectral radius 1 (the
    // trapezoidal rule). The Newton matrix is no metric for it: with gyroscopic and stiffness
    // terms it need not be definite, and projecting with it destabilizes fast-spinning bodies.
    // The matrix is factorized by its own LDL^T (quasi-definite with the normalization
    // penalties), so that the next step may reuse the Newton matrix.
    if project_velocities && nc > 0 {
        let view = StateView::of(next);
        assemble(model, view, ws, &Request::solving(Some(MatrixCoefficients::ACCELERATION)))?;
        if let Err(detail) = factorize(
            model,
            ws,
            solvers,
            Factorization::Projection,
            &MatrixCoefficients::ACCELERATION,
            &next.coordinates,
        ) {
            report.converged = false;
            report.failure = Some(format!("singular mass matrix in the velocity projection: {detail}"));
            return Ok(report);
        }
        report.factorizations += 1;
        let mut violation = std::mem::take(&mut ws.scratch[1]);
        crate::assembly::velocity_violation(model, &next.velocities, ws, &mut violation[..nc]);
        ws.solution[..nq].iter_mut().for_each(|x| *x = 0.0);
        for k in 0..nc {
            ws.solution[nq + k] = -violation[k];
        }
        ws.scratch[1] = violation;
        if let Err(detail) = solve(model, ws, solvers, Factorization::Projection, 1.0) {
            report.converged = false;
            report.failure = Some(format!("velocity projection: {detail}"));
            return Ok(report);
        }
        for k in 0..nq {
            next.velocities[k] += ws.solution[k];
        }
        // Accelerations and multipliers consistent with the projected velocities (seed eq. 26,
        // with the matrix just factorized): otherwise q_dd, lambda and the auxiliary
        // accelerations carry the removed velocity error into the next step, which fast
        // gyroscopic bodies amplify.
        next.accelerations.iter_mut().for_each(|x| *x = 0.0);
        next.multipliers.iter_mut().for_each(|x| *x = 0.0);
        let view = StateView::of(next);
        assemble(model, view, ws, &Request::solving(None))?;
        let mut gamma = std::mem::take(&mut ws.scratch[1]);
        let mut ct = std::mem::take(&mut ws.scratch[0]);
        let terms =
            crate::assembly::constraint_time_terms(model, view, ws, &mut ct[..nc], Some(&mut gamma[..nc]));
        for k in 0..nq {
            ws.solution[k] = -ws.residual[k];
        }
        ws.solution[nq..].copy_from_slice(&gamma[..nc]);
        ws.scratch[0] = ct;
        ws.scratch[1] = gamma;
        terms?;
        if let Err(detail) = solve(model, ws, solvers, Factorization::Projection, 1.0) {
            report.converged = false;
            report.failure = Some(format!("consistent accelerations after the projection: {detail}"));
            return Ok(report);
        }
        next.accelerations.copy_from_slice(&ws.solution[..nq]);
        next.multipliers.copy_from_slice(&ws.solution[nq..]);
    }
    // Auxiliary accelerations from the converged q_dd.
    for k in 0..nq {
        next.algorithmic_accelerations[k] = (alpha_f * current.accelerations[k]
            + (1.0 - alpha_f) * next.accelerations[k]
            - alpha_m * current.algorithmic_accelerations[k])
            / (1.0 - alpha_m);
    }
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn state_update_returns_the_largest_acceleration_after_it() {
        // Lengths that leave 0 to 3 entries after the groups of four, the largest entry in
        // each position, a NaN passed over.
        for n in [1usize, 4, 6, 9, 11] {
            for at in 0..n {
                let f = |k: usize, s: f64| s * ((k * 7 % 5) as f64 - 2.0);
                let vector = |s: f64| (0..n).map(|k| f(k, s)).collect::<Vec<f64>>();
                let mut state = State {
                    time: 0.0,
                    coordinates: vector(1.0),
                    velocities: vector(0.5),
                    accelerations: vector(-2.0),
                    multipliers: Vec::new(),
                    algorithmic_accelerations: vec![0.0; n],
                    discrete: Vec::new(),
                    previous_accelerations: vec![0.0; n],
                    previous_multipliers: Vec::new(),
                    previous_step_size: 0.0,
                };
                let mut dq = vector(0.1);
                dq[at] = -40.0;
                let coef =
                    MatrixCoefficients { mass: 3.0, velocity: 2.0, position: 1.0, identity: 0.0, scale: 1.0 };
                let before = state.clone();
                let largest = update_state(&mut state, &dq, &coef);
                for k in 0..n {
                    assert_eq!(state.coordinates[k], before.coordinates[k] + dq[k]);
                    assert_eq!(state.velocities[k], before.velocities[k] + 2.0 * dq[k]);
                    assert_eq!(state.accelerations[k], before.accelerations[k] + 3.0 * dq[k]);
                }
                let expected = state.accelerations.iter().fold(0.0f64, |m, a| m.max(a.abs()));
                assert_eq!(largest, expected, "n {n}, at {at}");
                assert_eq!(largest, state.accelerations[at].abs());
                if n > 1 {
                    state.accelerations[(at + 1) % n] = f64::NAN;
                    let mut again = state.clone();
                    let zero = vec![0.0; n];
                    assert_eq!(update_state(&mut again, &zero, &coef), expected, "NaN passed over");
                }
            }
        }
    }
}
