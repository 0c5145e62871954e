//! Newton's method of a generalized-alpha step (the increment equation of the module
//! documentation): the iterations with their matrix reuse and convergence tests, the
//! factorizations and solves of the Newton and projection matrices, the weighted increment
//! norm, and the update of the state by an increment.

use super::{Factorization, JacobianCache, StepReport};
use crate::assembly::{assemble, ElasticRows, MatrixCoefficients, Request, StateView};
use crate::error::{FlexmbdError, Result};
use crate::integrator::settings::NewtonSettings;
use crate::linear_system::{LinearSolvers, NO_SOLVERS};
use crate::system::{Model, State, Workspace};

/// Factorizes the assembled Newton matrix in `ws.values` (assembled with the coefficients
/// `coef`) with `kind`. For LDL^T the normalization constraints get the penalty
/// s kappa (2p)(2p)^T: adding s kappa C_n^T C_n to the coordinate block leaves dq unchanged
/// (C_n dq is fixed by the constraint rows) and only shifts dmu_n by s kappa C_n dq, which
/// `solve` takes back. Models with condensed deformable bodies factorize their Schur
/// complement instead (`linear_system::condensed`; LU of the reduced system, whatever `kind`).
pub(super) fn factorize(
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
pub(super) fn solve(
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
            if kind == Factorization::Projection {
                projection.solve_in_place(&mut ws.solution)
            } else {
                newton.solve_gyroscopic(&mut ws.solution)
            }
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
/// Where the step's own error is larger, the weight is instead `step_error`, the fraction
/// kappa (`NewtonSettings::error_fraction`) of the local error estimate
/// c h^2 |q_dd(n+1) - q_dd(n)|_inf of the step at this iterate: an iteration error far below the
/// error the step makes anyway does not change the solution's accuracy (Hairer and Wanner,
/// Solving ODEs II, section IV.8: the simplified Newton iteration of implicit Runge-Kutta
/// methods stops at kappa = 0.01-0.1 of the error tolerance). The soft tet beam
/// (benchmarks/soft_beam.py, README "Soft bodies") swings with elastic accelerations that
/// change by a good part of themselves within a step; a test at tol = 1e-6 of them asks for
/// iterations that leave its end state as it is to 2e-7 m, against the step's own 1.3e-4 m.
///
/// Multipliers (only with `multipliers`): the generalized constraint force of their
/// increment, |C_q^T dlambda|_inf, against tol max(1, |C_q^T lambda|_inf), with tol widened
/// by the factor that `step_error` widened the positions' weight. In the index-3
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
    step_error: f64,
    state: &State,
    increment: &[f64],
    multipliers: Option<ConstraintForces>,
) -> IncrementNorm {
    let tolerance_weight = tol * largest_acceleration.max(1.0) / coef.mass;
    let acceleration_weight = tolerance_weight.max(step_error);
    let tol = tol * (acceleration_weight / tolerance_weight);
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
    IncrementNorm {
        norm: worst.1,
        worst: worst.0,
        position,
        loosened: acceleration_weight > tolerance_weight,
    }
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
    /// Whether the step's error set the weight (`step_error` above the tolerance's).
    loosened: bool,
}

/// The Newton update of the coordinates, velocities and accelerations of `state` by
/// (1, gamma', beta') dq; returns max |q_dd| after it and max |q_dd - q_dd(n)| (q_dd(n): the
/// state's `previous_accelerations`, which the predictor set), 0 for none, NaN entries passed
/// over, in the same pass: four partial maxima each (a single running maximum is a chain of
/// dependent operations), by comparisons the compiler vectorizes.
fn update_state(state: &mut State, dq: &[f64], coef: &MatrixCoefficients) -> (f64, f64) {
    let (v, m) = (coef.velocity, coef.mass);
    let n = dq.len();
    let (q, qd, qdd, before) = (
        &mut state.coordinates[..n],
        &mut state.velocities[..n],
        &mut state.accelerations[..n],
        &state.previous_accelerations[..n],
    );
    let mut largest = [0.0f64; 4];
    let mut change = [0.0f64; 4];
    let groups =
        q.chunks_mut(4).zip(qd.chunks_mut(4)).zip(qdd.chunks_mut(4)).zip(before.chunks(4)).zip(dq.chunks(4));
    for ((((q, qd), qdd), before), dq) in groups {
        for i in 0..dq.len() {
            let d = dq[i];
            q[i] += d;
            qd[i] += v * d;
            qdd[i] += m * d;
            let a = qdd[i].abs();
            largest[i] = if a > largest[i] { a } else { largest[i] };
            let c = (qdd[i] - before[i]).abs();
            change[i] = if c > change[i] { c } else { change[i] };
        }
    }
    let top = |x: [f64; 4]| x.into_iter().fold(0.0, |t, a| if a > t { a } else { t });
    (top(largest), top(change))
}
/// Newton iterations from the state in `next`. With `reuse`, a factorization cached for this
/// step size is used as long as it contracts well (and refreshed when it does not); without,
/// the matrix is refactorized every iteration.
/// `local_error`: c h^2 of the step's local error estimate c h^2 |q_dd(n+1) - q_dd(n)| (see
/// [`increment_norm`]).
#[allow(clippy::too_many_arguments)]
pub(super) fn iterate(
    model: &Model,
    coef: MatrixCoefficients,
    newton: &NewtonSettings,
    reuse: bool,
    kind: Factorization,
    h: f64,
    local_error: f64,
    next: &mut State,
    ws: &mut Workspace,
    solvers: &mut LinearSolvers,
    cache: &mut JacobianCache,
) -> Result<StepReport> {
    let nq = model.coordinate_count;
    let s = coef.scale;
    let mut report = StepReport::default();
    let mut previous_norm = f64::INFINITY;
    let mut previous_rate = 0.0;
    let mut second_norm = f64::INFINITY;
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
        // Elastic rows of condensed bodies from the last condensed solve after the first
        // iteration (see `ElasticRows`; the update of the coordinates below is the one it
        // requires).
        let elastic_rows = match (condensed_rows, iteration) {
            (false, _) => ElasticRows::Whole,
            (true, 0) => ElasticRows::Keep,
            (true, _) => ElasticRows::Update { scale: s },
        };
        let structured_coupling = need_matrix && kind != Factorization::Projection;
        let matrix = need_matrix.then_some(coef);
        match assemble_iterate(model, next, ws, solvers, matrix, structured_coupling, elastic_rows) {
            // A residual that is not finite where the iteration has moved the state (an
            // iteration running away: a tumbling beam with an offset mass, through the
            // symmetrized matrix) fails the attempt, which is retried; at the predictor it
            // is the model's, and named.
            Err(error @ FlexmbdError::NonFinite { .. }) if iteration > 0 => {
                return Ok(abandon(report, cache, error.to_string()));
            }
            result => result?,
        }
        if need_matrix {
            if let Err(detail) = factorize(model, ws, solvers, kind, &coef, &next.coordinates) {
                return Ok(abandon(report, cache, format!("singular Newton matrix: {detail}")));
            }
            *cache = JacobianCache { step_size: Some(h), kind, age: 0 };
            report.factorizations += 1;
        }
        if let Err(detail) = solve_increment(model, ws, solvers, kind, s) {
            return Ok(abandon(report, cache, format!("singular Newton matrix: {detail}")));
        }
        // With a matrix reused from an earlier iterate, the multipliers are tested through the
        // constraint forces C_q^T dlambda of the increment (and C_q^T lambda before it), with
        // the Jacobians of this iterate: nonzero only at the constraints' coordinates. So is
        // the condensed iteration matrix even when factorized at this iterate: it is not the
        // exact Jacobian (the constant A, the mass part of the reference coupling), and its
        // multipliers converge at its rate, not to second order.
        let check_multipliers = !need_matrix || approximate_matrix;
        if check_multipliers {
            constraint_forces_of_increment(model, next, ws);
        }
        let (largest_acceleration, change) = apply_increment(model, next, &ws.solution, &coef);
        let step_error = newton.error_fraction * local_error * change;
        report.iterations = iteration + 1;
        let multipliers = check_multipliers.then_some(ConstraintForces {
            rows: &ws.constraint_coordinates,
            increment: &ws.scratch[0],
            force: &ws.scratch[1],
            scale: s,
        });
        let increment = &ws.solution[..nq];
        let norm = increment_norm(
            &coef,
            newton.tolerance,
            largest_acceleration,
            step_error,
            next,
            increment,
            multipliers,
        );
        report.increment_norm = norm.norm;
        report.worst = norm.worst;
        // (the norm's comparisons pass NaN entries over, and an infinite acceleration makes
        // it 0: "converged" on a non-finite state, which a tumbling beam with an offset mass
        // reached through the symmetrized matrix)
        let finite = largest_acceleration.is_finite() && ws.solution.iter().all(|x| x.is_finite());
        if !norm.norm.is_finite() || !finite {
            return Ok(abandon(report, cache, "non-finite increment".to_string()));
        }
        let current_matrix = need_matrix || fresh_at_predictor;
        let remaining = newton.max_iterations - 1 - iteration;
        let history = Iterations { previous_norm, previous_rate, second_norm, iteration, remaining };
        let outcome = convergence(&norm, &history, need_matrix, current_matrix, approximate_matrix);
        match outcome {
            Convergence::Converged => {
                report.converged = true;
                if approximate_matrix && slow_without_gyroscopic_block(&report) {
                    if let LinearSolvers::Condensed { newton, .. } = solvers {
                        if !newton.gyroscopic() {
                            newton.set_gyroscopic(true);
                            cache.step_size = None;
                        }
                    }
                }
                return Ok(report);
            }
            Convergence::Diverging { contraction } => {
                report.contraction = contraction;
                report.failure = Some(format!("increments grow (contraction rate {contraction:.2})"));
                return Ok(report);
            }
            Convergence::TooSlow { contraction } => {
                report.contraction = contraction;
                report.failure = Some(format!(
                    "contraction rate {contraction:.2} too slow to converge in {} iterations",
                    newton.max_iterations
                ));
                return Ok(report);
            }
            Convergence::Continuing { rate, contraction } => {
                if iteration > 0 {
                    report.contraction = report.contraction.max(contraction);
                }
                // Slow contraction: refresh the matrix at the current iterate, unless it is
                // the condensed solver's factorized at this step's predictor, which a refresh
                // would make again nearly as it is (its angular velocity is the last converged
                // state's, and q moves little within a step) and whose rate is that of the
                // terms it leaves out, not of its age: on the soft tet beam
                // (benchmarks/soft_beam.py, 1k, 2 s) refreshing at rates above the limit took
                // 1.49 factorizations per step for 5.75 iterations, not refreshing 1.01 for
                // 5.51.
                let rate_of_the_matrix = approximate_matrix && fresh_at_predictor;
                if reuse && rate > newton.contraction_limit && iteration > 0 && !rate_of_the_matrix {
                    cache.step_size = None;
                }
                previous_rate = rate;
            }
        }
        if iteration == 1 {
            second_norm = norm.norm;
        }
        previous_norm = norm.norm;
    }
    report.failure = Some(format!("no convergence in {} iterations", newton.max_iterations));
    Ok(report)
}

/// Whether a converged iteration with the condensed iteration matrix was slow enough for the
/// coarse stage with the gyroscopic block (`CondensedSolver::solve_gyroscopic`) to pay its
/// products: at least `GYROSCOPIC_ITERATIONS` iterations contracting at
/// `GYROSCOPIC_CONTRACTION` or slower. The condensed solver then keeps the stage for the rest
/// of the run. The soft tet beam's iterations (benchmarks/soft_beam.py) contract at 0.1 to 0.3,
/// faster with the stage (with Newton's tolerance of the step's error, 3 iterations in most
/// steps: the stage is switched on at the first of them, t = 0.16-0.19 s); the stiff nodal
/// bars' contract at 1e-3 to 1e-2 in 2 to 3 iterations, which it would not cut: they keep
/// the plain solves.
fn slow_without_gyroscopic_block(report: &StepReport) -> bool {
    report.iterations >= GYROSCOPIC_ITERATIONS && report.contraction >= GYROSCOPIC_CONTRACTION
}

/// See [`slow_without_gyroscopic_block`].
const GYROSCOPIC_ITERATIONS: usize = 3;
const GYROSCOPIC_CONTRACTION: f64 = 0.05;

/// `report` of iterations that end with `failure`; the cached factorization is dropped.
fn abandon(mut report: StepReport, cache: &mut JacobianCache, failure: String) -> StepReport {
    cache.step_size = None;
    report.failure = Some(failure);
    report
}

/// Assembles the residual of the iterate `next` (and the Newton matrix with the coefficients
/// `matrix`, if given) into `ws`; `structured_coupling` and `elastic_rows` as in [`Request`].
fn assemble_iterate(
    model: &Model,
    next: &State,
    ws: &mut Workspace,
    solvers: &mut LinearSolvers,
    matrix: Option<MatrixCoefficients>,
    structured_coupling: bool,
    elastic_rows: ElasticRows,
) -> Result<()> {
    let images = if matches!(elastic_rows, ElasticRows::Update { .. }) {
        solvers.coupling_images()
    } else {
        Vec::new()
    };
    let request =
        Request { matrix, condensed_blocks: false, structured_coupling, elastic_rows, images: &images };
    let assembled = assemble(model, StateView::of(next), ws, &request);
    drop(images);
    assembled
}

/// The Newton increment [dq; s dlambda] into `ws.solution`: the right-hand side -[s r; C]
/// from `ws.residual`, solved with the factorization `kind` (s = `scale`).
fn solve_increment(
    model: &Model,
    ws: &mut Workspace,
    solvers: &mut LinearSolvers,
    kind: Factorization,
    scale: f64,
) -> std::result::Result<(), String> {
    let nq = model.coordinate_count;
    let nc = model.constraint_count;
    let (coordinate_rows, constraint_rows) = ws.residual[..nq + nc].split_at(nq);
    for (x, r) in ws.solution[..nq].iter_mut().zip(coordinate_rows) {
        *x = -scale * r;
    }
    for (x, r) in ws.solution[nq..nq + nc].iter_mut().zip(constraint_rows) {
        *x = -r;
    }
    solve(model, ws, solvers, kind, scale)
}

/// The constraint forces of the multipliers' test at the iterate `next`, before its update:
/// C_q^T dlambda of the increment in `ws.solution` into `ws.scratch[0]` and C_q^T lambda into
/// `ws.scratch[1]` (both at `ws.constraint_coordinates`, where they are nonzero).
fn constraint_forces_of_increment(model: &Model, next: &State, ws: &mut Workspace) {
    let nq = model.coordinate_count;
    let [force_increment, force, _] = &mut ws.scratch;
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

/// Updates `next` by the increment [dq; s dlambda] in `solution`; returns max |q_dd| after it
/// and max |q_dd - q_dd(n)| (see [`update_state`]).
fn apply_increment(
    model: &Model,
    next: &mut State,
    solution: &[f64],
    coef: &MatrixCoefficients,
) -> (f64, f64) {
    let nq = model.coordinate_count;
    let largest = update_state(next, &solution[..nq], coef);
    for k in 0..model.constraint_count {
        next.multipliers[k] += solution[nq + k] / coef.scale;
    }
    largest
}

/// What the Newton iteration does after an increment.
enum Convergence {
    Converged,
    /// The increments grow (contraction rate `contraction` >= 1): the iteration stops.
    Diverging {
        contraction: f64,
    },
    /// The increments shrink, too slowly to converge in the iterations left (with a matrix
    /// factorized at this iterate, which a refresh would not change): the iteration stops.
    TooSlow {
        contraction: f64,
    },
    /// Another iteration; `rate` is the ratio of the last two increment norms, `contraction`
    /// the contraction rate of the iteration (see [`convergence`]).
    Continuing {
        rate: f64,
        contraction: f64,
    },
}

/// Where an iteration stands before the tests of [`convergence`]: the norm of the increment
/// before this one and the ratio of that one to its predecessor (0 before the second), the
/// norm of the second increment (infinite before it), the index of this iteration and how many
/// may follow it.
struct Iterations {
    previous_norm: f64,
    previous_rate: f64,
    second_norm: f64,
    iteration: usize,
    remaining: usize,
}

/// The convergence tests after the increment with weighted norm `norm`. `fresh_matrix`: the
/// matrix was factorized at this iterate; `current_matrix`: it was factorized at this iterate
/// or at this step's predictor; `approximate_matrix`: it is not the exact Jacobian however
/// fresh (the condensed solver's).
///
/// Divergence and slow convergence are judged by the contraction rate theta of the iteration
/// (Hairer and Wanner, Solving ODEs II, section IV.8, and their RADAU5): from the third
/// increment on, the geometric mean sqrt(theta_k theta_(k-1)) of the last two ratios of
/// increment norms theta_k = |dx_k| / |dx_(k-1)|. An iteration whose error has components
/// that contract at different rates (the approximate iteration matrices of condensed bodies,
/// a matrix reused from an earlier iterate) can make one increment tiny and the next larger
/// again while it still converges: one ratio above 1 is not divergence, theta >= 1 is. With a
/// matrix from an earlier step (not `current_matrix`), one ratio above 1 is: the step
/// starts again with a fresh matrix (`step`), the usual cure of a stale one. The
/// iteration also stops when, with an approximate matrix factorized at this iterate (whose
/// iteration converges linearly: a refresh does not change its rate, while an exact Newton
/// matrix converges faster and faster, which no rate predicts), the mean ratio since
/// the second increment, theta_m = (|dx_k| / |dx_1|)^(1 / (k - 1)), predicts that it cannot
/// converge in the iterations left: the estimated error theta/(1 - theta) |dx| of the test of
/// convergence below, after r more increments of theta_m each, is
/// theta_m^(r + 1) / (1 - theta_m) |dx_k| > 1 with r the iterations left. The mean over the
/// iteration, not the last one or two ratios, because the ratios of an approximate matrix
/// alternate (0.27, 0.66, 0.27, ... on a stiff spinning beam of 80 elements) or spike (0.005,
/// 2.5, 0.1 on the soft tet beam), and a prediction from one of them failed steps that
/// converged.
fn convergence(
    norm: &IncrementNorm,
    history: &Iterations,
    fresh_matrix: bool,
    current_matrix: bool,
    approximate_matrix: bool,
) -> Convergence {
    let Iterations { previous_norm, previous_rate, second_norm, iteration, remaining } = *history;
    let rate = norm.norm / previous_norm;
    // Remaining error estimated from the contraction rate (Hairer and Wanner). With a
    // matrix reused from an earlier step, the first rate (measured from the predictor,
    // whose error is of another order) is not trusted; with a matrix factorized at the
    // predictor, the first increment was a Newton step and the rate after it measures the
    // contraction of the iterations that follow. An approximate matrix (the condensed
    // solver's) contracts unevenly, a ratio of 0.005 followed by 2.5 (see `convergence`'s
    // documentation): against the step's error (`NewtonSettings::error_fraction`, a weight
    // far above the tolerance's), its estimate takes the larger of the last two ratios, from
    // the third increment on. Estimated from one ratio, on the soft tet beam (10k, 0.5 s) at
    // kappa = 0.03, it passed iterations whose error moved the end tip by 9e-5 m; from two,
    // by 2e-7 m. At the tolerance's weight one ratio serves (the tip as with two to 2e-9 m,
    // 3.51 iterations per step against 3.70).
    let (rate_trusted, estimate_rate) = if approximate_matrix && norm.loosened {
        (iteration >= 2, rate.max(previous_rate))
    } else {
        (iteration > 1 || (iteration == 1 && current_matrix), rate)
    };
    let estimated_error_small =
        rate_trusted && estimate_rate < 1.0 && estimate_rate / (1.0 - estimate_rate) * norm.norm <= 1.0;
    // Near singular configurations the Newton matrix is ill-conditioned and the increments
    // stall at a round-off level amplified by its condition: once the relative position
    // increment is below 1e-10 and no longer decreases, with a current matrix, the
    // iteration has converged as far as it can.
    let at_roundoff = norm.position <= 1e-10;
    let stalled_at_roundoff = fresh_matrix && iteration >= 1 && rate >= 0.5 && at_roundoff;
    let contraction = if iteration >= 2 { (rate * previous_rate).sqrt() } else { rate };
    if norm.norm <= 1.0 || estimated_error_small || stalled_at_roundoff {
        Convergence::Converged
    } else if iteration >= 2 && !at_roundoff && (contraction >= 1.0 || !current_matrix && rate > 1.0) {
        Convergence::Diverging { contraction: contraction.max(rate) }
    } else if let Some(mean) = (approximate_matrix && fresh_matrix && iteration >= 2 && !at_roundoff)
        .then(|| (norm.norm / second_norm).powf(1.0 / (iteration - 1) as f64))
        .filter(|&mean| mean < 1.0 && mean.powi(remaining as i32 + 1) / (1.0 - mean) * norm.norm > 1.0)
    {
        Convergence::TooSlow { contraction: mean }
    } else {
        Convergence::Continuing { rate, contraction }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The outcome of the convergence tests on a sequence of increment norms with the matrix
    /// (`approximate` or exact) factorized at the iterations in `fresh` and, if `current`, at
    /// the predictor, as `iterate` runs them (12 iterations at most): the last iteration
    /// tested and the outcome.
    fn outcome(norms: &[f64], fresh: &[usize], current: bool, approximate: bool) -> (usize, Convergence) {
        let (mut previous_norm, mut previous_rate, mut second_norm) = (f64::INFINITY, 0.0, f64::INFINITY);
        for (iteration, &n) in norms.iter().enumerate() {
            let norm = IncrementNorm { norm: n, worst: 0, position: 1e-3, loosened: false };
            let history = Iterations {
                previous_norm,
                previous_rate,
                second_norm,
                iteration,
                remaining: 11 - iteration,
            };
            let fresh_here = (current && iteration == 0) || fresh.contains(&iteration);
            match convergence(&norm, &history, fresh_here, current || fresh_here, approximate) {
                Convergence::Continuing { rate, .. } if iteration + 1 < norms.len() => previous_rate = rate,
                done => return (iteration, done),
            }
            if iteration == 1 {
                second_norm = n;
            }
            previous_norm = n;
        }
        unreachable!("the sequence ends in an outcome")
    }

    #[test]
    fn one_growing_increment_of_a_converging_iteration_is_not_divergence() {
        // Measured on the soft tet beam (benchmarks/soft_beam.py, 1k, t = 1.314 s): the
        // approximate condensed iteration matrix nearly solves one component of the error in
        // the third increment, the fourth is 2.5 times larger, and the iteration, refreshed
        // there, converges in two more. A test on that one ratio called it diverging and the
        // step was retried and rejected (135 rejections in 2 s); the contraction rate over
        // the last two ratios, sqrt(0.005 * 2.54) = 0.11, lets it go on.
        let measured = [1.300e6, 1.032e5, 4.683e2, 1.190e3, 1.262e2, 1.3e1, 0.9];
        assert!(matches!(outcome(&measured, &[4], true, true), (6, Convergence::Converged)));
        // With a matrix from an earlier step, the growing increment restarts the step with a
        // fresh matrix, as before (a stale matrix is the usual cause).
        assert!(matches!(outcome(&measured, &[], false, true), (3, Convergence::Diverging { .. })));
        // Increments that keep growing are divergence (theta = sqrt(2 * 3) >= 1) ...
        let growing = [1.0e6, 1.0e5, 2.0e5, 6.0e5];
        assert!(
            matches!(outcome(&growing, &[], true, false), (3, Convergence::Diverging { contraction }) if contraction > 2.4)
        );
        // ... and an approximate matrix factorized at the third iterate, contracting at 0.7
        // from 1e5 with nine iterations left, cannot converge in them: 0.7^10 / 0.3 * 7e4 > 1.
        let slow = [1.0e7, 1.0e5, 7.0e4];
        let too_slow = outcome(&slow, &[2], true, true);
        assert!(matches!(too_slow, (2, Convergence::TooSlow { contraction }) if contraction == 0.7));
        // An exact Newton matrix factorized at every iterate converges faster and faster (the
        // hardening spring of tests/test_errors.py: ratios 0.39, 0.34, then converged in 12
        // iterations): no prediction.
        let newton = [9.981e5, 3.903e5, 1.333e5, 2.0e3];
        assert!(matches!(outcome(&newton, &[1, 2, 3], true, false), (3, Convergence::Continuing { .. })));
        // Ratios that alternate (0.27, 0.66) contract at their mean: measured on the spin-up
        // beam of 80 elements at h = 5e-3 (t = 2.105 s), whose last ratio alone would predict
        // no convergence in the eight iterations left, their mean (0.42) convergence.
        let alternating = [9.962e1, 9.907e1, 2.629e1, 1.733e1];
        assert!(matches!(outcome(&alternating, &[2, 3], true, true), (3, Convergence::Continuing { .. })));
        // The same rate with the matrix of the predictor goes on.
        assert!(matches!(
            outcome(&[1.0e7, 1.0e5, 7.0e4, 3.0e3], &[], true, true),
            (3, Convergence::Continuing { .. })
        ));
    }

    #[test]
    fn the_steps_error_widens_the_positions_weight_and_the_multipliers_test_alike() {
        // tol = 1e-6, max |q_dd| = 10, beta' = 4: the tolerance's weight of a position
        // increment is 2.5e-6.
        let coef = MatrixCoefficients {
            mass: 4.0,
            velocity: 2.0,
            position: 1.0,
            identity: 0.0,
            elastic_identity: 0.0,
            scale: 0.25,
        };
        let n = 3;
        let state = State {
            time: 0.0,
            coordinates: vec![0.5; n],
            velocities: vec![0.0; n],
            accelerations: vec![10.0; n],
            multipliers: Vec::new(),
            algorithmic_accelerations: vec![0.0; n],
            discrete: Vec::new(),
            previous_accelerations: vec![0.0; n],
            previous_multipliers: Vec::new(),
            previous_step_size: 0.0,
        };
        let increment = [0.0, 5e-6, -1e-6];
        // Constraint forces: |C_q^T dlambda| = 3e-5 / s at row 2 against |C_q^T lambda| = 10.
        let (force_increment, force) = ([0.0, 0.0, 3e-5 * 0.25], [0.0, 0.0, 10.0]);
        let forces = || {
            Some(ConstraintForces {
                rows: &[2],
                increment: &force_increment,
                force: &force,
                scale: coef.scale,
            })
        };
        let tight = increment_norm(&coef, 1e-6, 10.0, 0.0, &state, &increment, forces());
        assert!(!tight.loosened);
        assert_eq!(tight.worst, 2, "the multipliers' test: 3e-5 / (1e-6 * 10) = 3");
        assert!((tight.norm - 3.0).abs() < 1e-12, "{}", tight.norm);
        // A step error below the tolerance's weight changes nothing.
        let below = increment_norm(&coef, 1e-6, 10.0, 1e-6, &state, &increment, forces());
        assert!(!below.loosened && below.norm == tight.norm);
        // A step error of 1e-5 widens both by 4: positions 5e-6 / 1e-5, multipliers 3 / 4.
        let wide = increment_norm(&coef, 1e-6, 10.0, 1e-5, &state, &increment, forces());
        assert!(wide.loosened);
        assert_eq!(wide.worst, 2);
        assert!((wide.norm - 0.75).abs() < 1e-12, "{}", wide.norm);
        let positions = increment_norm(&coef, 1e-6, 10.0, 1e-5, &state, &increment, None);
        assert_eq!(positions.worst, 1);
        assert!(
            (positions.norm - 0.5).abs() < 1e-8,
            "{} (the round-off floor 1e-14 |q| in the weight)",
            positions.norm
        );
    }

    #[test]
    fn against_the_steps_error_an_approximate_matrix_estimates_from_two_ratios() {
        // Ratios 0.005 then 0.4 of a condensed iteration: at the tolerance's weight the second
        // increment's estimate 0.005 / 0.995 * 150 < 1 passes; against the step's error
        // (loosened) it waits for the third increment, whose estimate takes the larger ratio.
        let test = |loosened: bool, norms: &[f64]| {
            let (mut previous_norm, mut previous_rate, mut second_norm) = (f64::INFINITY, 0.0, f64::INFINITY);
            for (iteration, &n) in norms.iter().enumerate() {
                let norm = IncrementNorm { norm: n, worst: 0, position: 1e-3, loosened };
                let history =
                    Iterations { previous_norm, previous_rate, second_norm, iteration, remaining: 9 };
                match convergence(&norm, &history, iteration == 0, true, true) {
                    Convergence::Continuing { rate, .. } => previous_rate = rate,
                    Convergence::Converged => return Some(iteration),
                    _ => return None,
                }
                if iteration == 1 {
                    second_norm = n;
                }
                previous_norm = n;
            }
            None
        };
        assert_eq!(test(false, &[3.0e4, 150.0, 60.0, 1.0]), Some(1));
        // 0.4 / 0.6 * 60 = 40 > 1: on to the fourth.
        assert_eq!(test(true, &[3.0e4, 150.0, 60.0, 1.0]), Some(3));
        // 0.1 / 0.9 * 6 < 1 with the ratios 0.005 and 0.04 (the larger: 0.04 / 0.96 * 6).
        assert_eq!(test(true, &[3.0e4, 150.0, 6.0]), Some(2));
    }

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
                    previous_accelerations: vector(0.25),
                    previous_multipliers: Vec::new(),
                    previous_step_size: 0.0,
                };
                let mut dq = vector(0.1);
                dq[at] = -40.0;
                let coef = MatrixCoefficients {
                    mass: 3.0,
                    velocity: 2.0,
                    position: 1.0,
                    identity: 0.0,
                    elastic_identity: 0.0,
                    scale: 1.0,
                };
                let before = state.clone();
                let (largest, change) = update_state(&mut state, &dq, &coef);
                let expected_change = (0..n)
                    .map(|k| (state.accelerations[k] - before.previous_accelerations[k]).abs())
                    .fold(0.0f64, f64::max);
                assert_eq!(change, expected_change, "n {n}, at {at}");
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
                    assert_eq!(update_state(&mut again, &zero, &coef).0, expected, "NaN passed over");
                }
            }
        }
    }
}
