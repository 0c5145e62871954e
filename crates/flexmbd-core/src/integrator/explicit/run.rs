//! A run with an explicit integrator: consistent initial conditions (dense), the partition or
//! the joint coordinates at the start, and the step attempts the time loop makes: a
//! Runge-Kutta step of the strategy's integrated vector, the corrections after an accepted step
//! (projection, rebasing, a new partition), and the events of singular configurations and
//! constraint drift.

use super::engine::Engine;
use super::partitioning::{first_partition, redundant_rows_event};
use super::runge_kutta::{self, Stages};
use super::trbdf2::{self, Newton, Outcome};
use crate::error::{FlexmbdError, Result};
use crate::formulation::augmented::DenseEquations;
use crate::formulation::recursive::TreeLinearization;
use crate::integrator::discrete::{start_discrete, update_discrete};
use crate::integrator::initial::{dense_initial_conditions, report_initial_correction, starting_state};
use crate::integrator::progress::Progress;
use crate::integrator::settings::{ExplicitMethod, ExplicitSettings, SimulationSettings, Strategy};
use crate::integrator::time_loop::{time_loop, Attempt, Growth, Retry, Stepper};
use crate::output::{Event, Output, Statistics};
use crate::system::{Model, State, Workspace};

/// Runs the explicit integrator of `explicit`; keeps the last accepted state in `last_state`
/// (also on failure).
pub fn run(
    model: &Model,
    settings: &SimulationSettings,
    explicit: &ExplicitSettings,
    observer: &mut dyn FnMut(&Progress) -> bool,
    output: &mut Output,
    last_state: &mut Option<State>,
) -> Result<()> {
    settings.validate()?;
    explicit.validate(model)?;
    let mut ws = Workspace::new(model);
    let mut eq = DenseEquations::new(model);
    let mut state = starting_state(model, settings.start_time, settings.start.as_ref())?;
    let (given_q, given_qd) = (state.coordinates.clone(), state.velocities.clone());
    let violated = dense_initial_conditions(model, &mut ws, &mut eq, &mut state, &settings.initial)?;
    report_initial_correction(model, &given_q, &given_qd, &state, &violated, settings, output)?;
    start_discrete(model, &mut state, &mut ws, settings, &mut output.events)?;

    let partition = first_partition(model, explicit, &mut ws, &mut eq, &state)?;
    let mut engine = Engine::new(model, explicit, ws, eq, partition, &state);
    if explicit.strategy == Strategy::JointCoordinates {
        engine.start_joint_coordinates(&mut state, output)?;
    }
    engine.singular_limit = explicit.singular_factor * engine.partition.condition.max(1.0);
    output.events.extend(redundant_rows_event(model, &engine.partition, state.time));
    if settings.continues() {
        engine.complete(&mut state)?;
    } else {
        engine.record(&mut state, output)?;
    }
    *last_state = Some(state.clone());

    let mut y = Vec::new();
    engine.pack(&mut y);
    let mut steps = ExplicitSteps {
        engine,
        step_floor: settings.step_floor(),
        stages: Stages::new(y),
        first_derivative_valid: false,
        singular_before: 0,
        near_singular: false,
        drift_reported: false,
        last_state,
        newton: Newton::default(),
    };
    time_loop(model, settings, &mut steps, observer, output, &mut state)?;
    count_evaluations(&steps.engine, &steps.newton, &mut output.statistics);
    Ok(())
}

/// What the explicit steps of a run work with.
struct ExplicitSteps<'a, 'b> {
    /// The evaluations of the right-hand sides.
    engine: Engine<'a>,
    /// The smallest step size (`SimulationSettings::step_floor`).
    step_floor: f64,
    /// The integrated vector and the Runge-Kutta stages.
    stages: Stages,
    /// Whether `stages.k[0]` holds dy/dt at the accepted state (first same as last).
    first_derivative_valid: bool,
    /// Evaluations near a singular configuration before the current attempt.
    singular_before: usize,
    /// Whether the last accepted step was near a singular configuration (reported once when
    /// the run comes near one).
    near_singular: bool,
    /// Whether the constraint drift was reported (once per run).
    drift_reported: bool,
    /// The last accepted state that was checked and recorded, kept for a failure.
    last_state: &'b mut Option<State>,
    /// The iteration matrix of the implicit method (TR-BDF2), kept between steps.
    newton: Newton,
}

impl Stepper for ExplicitSteps<'_, '_> {
    /// A Runge-Kutta step with its error test; after a failed evaluation (Newton iteration,
    /// singular block), a better partition or a smaller step.
    fn attempt(&mut self, state: &State, h: f64, output: &mut Output) -> Result<Attempt> {
        let t = state.time;
        self.singular_before = self.engine.singular_evaluations;
        if !self.first_derivative_valid {
            self.engine.derivative(t, &self.stages.y, &mut self.stages.k[0])?;
            self.first_derivative_valid = true;
        }
        let abandoned = self.newton.analytic_abandoned;
        let result = match self.runge_kutta_step(t, h) {
            Ok(err) => Ok(self.error_test(err, t, h)),
            Err(e) if retryable(&e) => self.after_failed_evaluation(e, h, output),
            Err(e) => Err(e),
        };
        if let (None, Some(time)) = (abandoned, self.newton.analytic_abandoned) {
            output.events.push(Event {
                time,
                kind: "iteration matrix".to_string(),
                message: "tr-bdf2: the analytic matrix of the joint coordinates did not converge \
                          (it leaves out the velocity-quadratic, gravity and geometric-stiffness \
                          terms, large here): the matrix by differences from now on"
                    .to_string(),
            });
        }
        result
    }

    /// The corrections of the strategy at the end of the step, the full state into `state`,
    /// the discrete variables advanced, and the singular-configuration event.
    fn accept(&mut self, state: &mut State, h: f64, output: &mut Output) -> Result<()> {
        let t = state.time;
        let t_new = t + h;
        std::mem::swap(&mut self.stages.y, &mut self.stages.y_new);
        let modified = self.correct(t_new, output)?;
        if modified {
            self.restart_stages();
        }
        let engine = &mut self.engine;
        engine.accepted_q.copy_from_slice(&engine.q);
        engine.accepted_qd.copy_from_slice(&engine.qd);
        if !modified && engine.last_time == t_new {
            // Dormand-Prince's last stage was evaluated at exactly this state.
            engine.accepted_qdd.copy_from_slice(&engine.qdd);
        }
        engine.accepted_time = t_new;
        state.time = t_new;
        state.coordinates.copy_from_slice(&engine.q);
        state.velocities.copy_from_slice(&engine.qd);
        let discrete_before = state.discrete.clone();
        update_discrete(engine.model, state, &mut engine.ws, false, &mut output.events)?;
        engine.discrete.copy_from_slice(&state.discrete);
        // First same as last: dy/dt at the new point, unless the state or the forces changed.
        self.first_derivative_valid = self.adaptive() && !modified && discrete_before == state.discrete;
        if self.first_derivative_valid {
            self.stages.reuse_last_derivative();
        }
        self.report_singular_configuration(t, t_new, output);
        Ok(())
    }

    /// The record with the accelerations and multipliers at `state`, and the constraint
    /// drift event when the violation first passes its threshold.
    fn record(&mut self, state: &mut State, output: &mut Output) -> Result<()> {
        self.engine.record(state, output)?;
        let explicit = self.engine.settings;
        let violation = output.constraint_violation.last().copied().unwrap_or(0.0);
        if !self.drift_reported && violation > explicit.drift_threshold {
            self.drift_reported = true;
            output.events.push(Event {
                time: state.time,
                kind: "constraint drift".to_string(),
                message: format!(
                    "constraint violation {violation:.3e} passed {:.1e} (strategy '{}' does not \
                     correct the positions{})",
                    explicit.drift_threshold,
                    explicit.strategy.name(),
                    if explicit.baumgarte.is_some() {
                        "; larger Baumgarte parameters hold it closer"
                    } else {
                        "; Baumgarte stabilization, or strategy 'partitioning' or 'projection', \
                         holds it"
                    }
                ),
            });
        }
        Ok(())
    }

    /// Keeps a copy of `state` for a failure later, and counts the evaluations.
    fn completed(&mut self, state: &State, output: &mut Output) {
        state.store_in(self.last_state);
        count_evaluations(&self.engine, &self.newton, &mut output.statistics);
    }
}

impl ExplicitSteps<'_, '_> {
    /// Whether the method controls the error (Dormand-Prince) or takes fixed steps (RK4).
    fn adaptive(&self) -> bool {
        self.engine.settings.method.adaptive()
    }

    /// The Runge-Kutta step from (t, y) with step h; returns its error norm. The end point of
    /// a step that passes the error test becomes the engine's full state, with the check that
    /// the dependent coordinates stayed on their branch.
    fn runge_kutta_step(&mut self, t: f64, h: f64) -> Result<f64> {
        let adaptive = self.adaptive();
        let engine = &mut self.engine;
        let explicit = engine.settings;
        let tolerances = (explicit.relative_tolerance, explicit.absolute_tolerance);
        let err = match explicit.method {
            ExplicitMethod::TrBdf2 => {
                match trbdf2::step(t, h, &mut self.stages, tolerances, &mut self.newton, &mut *engine)? {
                    Outcome::Error(err) => err,
                    // The step attempt fails: a shorter step (error control) follows.
                    Outcome::NotConverged => f64::INFINITY,
                }
            }
            method => {
                let derivative = |time: f64, y: &[f64], dy: &mut [f64]| engine.derivative(time, y, dy);
                runge_kutta::step(method, t, h, &mut self.stages, tolerances, derivative)?
            }
        };
        if (adaptive && err <= 1.0) || (!adaptive && err.is_finite()) {
            engine.check_branch = true;
            let result = engine.unpack(t + h, &self.stages.y_new);
            engine.check_branch = false;
            result?;
        }
        Ok(err)
    }

    /// Accepts or rejects a step from `t` of size `h` with error norm `err`: RK4 takes every
    /// finite step, Dormand-Prince those with err <= 1 and proposes the next step size.
    fn error_test(&self, err: f64, t: f64, h: f64) -> Attempt {
        if !self.adaptive() {
            if err.is_finite() {
                return Attempt::Passed { growth: Growth::Kept, newton_iterations: 0 };
            }
            let error = FlexmbdError::NonFinite { item: "the Runge-Kutta step".to_string(), time: t };
            return Attempt::Rejected(Retry::Fail(error));
        }
        let factor = if err.is_finite() { (0.9 * err.max(1e-10).powf(-0.2)).clamp(0.2, 5.0) } else { 0.2 };
        if err <= 1.0 {
            Attempt::Passed { growth: Growth::Scaled(factor), newton_iterations: 0 }
        } else {
            Attempt::Rejected(Retry::Shorter { step_size: h * factor.min(1.0), cause: None })
        }
    }

    /// After an evaluation of a step of size `h` failed with `error` (a Newton iteration, a
    /// singular block): first a better partition at the start of the step, then (error
    /// control) a quarter of the step. Without either the run fails with the error, and the
    /// attempt counts as no rejected step.
    fn after_failed_evaluation(
        &mut self,
        error: FlexmbdError,
        h: f64,
        output: &mut Output,
    ) -> Result<Attempt> {
        if let Some(event) = self.engine.repartition_after_failure()? {
            output.events.push(event);
            self.restart_stages();
            self.newton.invalidate();
            self.first_derivative_valid = false;
            return Ok(Attempt::Rejected(Retry::Again));
        }
        if !self.adaptive() || h * 0.25 < self.step_floor {
            return Err(error);
        }
        Ok(Attempt::Rejected(Retry::Shorter { step_size: h * 0.25, cause: None }))
    }

    /// The corrections after an accepted step at `t_new`: projection (strategy 3, and onto
    /// the cut joints of joint coordinates), rebased Cardan angles, a new partition or the
    /// passage of a singular configuration. Returns whether they changed the state or the
    /// integrated vector.
    fn correct(&mut self, t_new: f64, output: &mut Output) -> Result<bool> {
        let engine = &mut self.engine;
        let mut modified = false;
        if engine.mode == Strategy::Projection {
            engine.project(t_new)?;
            modified = true;
        }
        if engine.tree.as_ref().is_some_and(|t| !t.cut_rows.is_empty()) {
            engine.project_joint_coordinates(t_new)?;
            output.events.extend(engine.raise_loop_rank(t_new));
            modified = true;
        }
        if let Some(event) = engine.rebase_joint_coordinates(t_new)? {
            output.events.push(event);
            modified = true;
            // Other coordinates: the implicit method's Jacobian no longer applies.
            self.newton.invalidate();
        }
        let mode = engine.mode;
        let events = engine.update_partition(t_new)?;
        if !events.is_empty() || engine.mode != mode {
            modified = true;
            self.newton.invalidate();
        }
        output.events.extend(events);
        Ok(modified)
    }

    /// The integrated vector of the engine's state, and the stage buffers sized for it.
    fn restart_stages(&mut self) {
        self.engine.pack(&mut self.stages.y);
        self.stages.resize_to_y();
    }

    /// The event of a step from `t` to `t_new` that came near a singular configuration (once
    /// per passage).
    fn report_singular_configuration(&mut self, t: f64, t_new: f64, output: &mut Output) {
        if self.engine.singular_evaluations <= self.singular_before {
            self.near_singular = false;
            return;
        }
        if !self.near_singular {
            output.events.push(Event {
                time: t_new,
                kind: "singular configuration".to_string(),
                message: format!(
                    "ill-conditioned dependent block or near rank-deficient constraint Jacobian \
                     between t = {t} and {t_new}: accelerations by the null-space method (truncated \
                     SVD of C_q)"
                ),
            });
        }
        self.near_singular = true;
    }
}

/// Whether an error is a failure of one step attempt that a smaller step may avoid.
fn retryable(e: &FlexmbdError) -> bool {
    matches!(
        e,
        FlexmbdError::NewtonDiverged { .. }
            | FlexmbdError::SingularMatrix { .. }
            | FlexmbdError::NonFinite { .. }
    )
}

/// The evaluations and Newton iterations of the engine (and of the implicit method's stages)
/// so far into the statistics, and the implicit method's factorizations of its iteration
/// matrix.
fn count_evaluations(engine: &Engine, newton: &Newton, statistics: &mut Statistics) {
    statistics.function_evaluations = engine.evaluations;
    statistics.newton_iterations = engine.newton_iterations + newton.iterations;
    statistics.factorizations = newton.factorizations;
    statistics.jacobian_evaluations = newton.jacobians;
}

/// The right-hand side of the strategy for TR-BDF2, and in joint coordinates the tree's
/// linearized equations of motion for its iteration matrix.
impl trbdf2::Equations for Engine<'_> {
    fn derivative(&mut self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<()> {
        Engine::derivative(self, t, y, dy)
    }

    fn linearization(&mut self, t: f64, y: &[f64]) -> Result<Option<TreeLinearization>> {
        self.tree_linearization(t, y)
    }
}
