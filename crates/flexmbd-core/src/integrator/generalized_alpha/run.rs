//! A run with the generalized-alpha method: consistent initial conditions, the starting
//! auxiliary accelerations, and the step attempts the time loop makes (the Newton step, the
//! error test of error control and the step-size proposals).

use super::{step, GeneralizedAlpha, JacobianCache, StepReport};
use crate::error::{FlexmbdError, Result};
use crate::integrator::discrete::{start_discrete, update_discrete};
use crate::integrator::initial::{
    report_initial_correction, solve_accelerations, solve_initial_positions_and_velocities, starting_state,
};
use crate::integrator::progress::Progress;
use crate::integrator::settings::{SimulationSettings, StepControl};
use crate::integrator::time_loop::{time_loop, Attempt, Growth, Retry, Stepper};
use crate::linear_system::LinearSolvers;
use crate::output::Output;
use crate::system::{Model, State, Workspace};

/// Runs the generalized-alpha method; keeps the last accepted state in `last_state` (also on
/// failure).
pub(crate) fn run(
    model: &Model,
    settings: &SimulationSettings,
    observer: &mut dyn FnMut(&Progress) -> bool,
    output: &mut Output,
    last_state: &mut Option<State>,
) -> Result<()> {
    settings.validate()?;
    let method = GeneralizedAlpha::from_spectral_radius(settings.spectral_radius)?;
    let mut ws = Workspace::new(model);
    let mut solvers = LinearSolvers::new(model)?;
    let mut state = starting_state(model, settings.start_time, settings.start.as_ref())?;
    let (given_q, given_qd) = (state.coordinates.clone(), state.velocities.clone());
    let violated =
        solve_initial_positions_and_velocities(model, &mut state, &mut ws, &mut solvers, &settings.initial)?;
    report_initial_correction(model, &given_q, &given_qd, &state, &violated, settings, output)?;
    start_discrete(model, &mut state, &mut ws, settings, &mut output.events)?;
    solve_accelerations(model, &mut state, &mut ws, &mut solvers)?;
    let first_step = settings.step_size.min(settings.end_time - state.time).max(f64::MIN_POSITIVE);
    start_algorithmic_accelerations(
        model,
        &method,
        first_step.min(settings.output_interval.unwrap_or(first_step)),
        &mut state,
        &mut ws,
        &mut solvers,
    )?;
    if !settings.continues() {
        output.record(model, &state, &mut ws);
    }
    let mut steps = GeneralizedAlphaSteps {
        model,
        settings,
        method,
        project_velocities: settings.newton.velocity_projection.enabled(settings.spectral_radius),
        ws,
        solvers,
        cache: JacobianCache::default(),
        next: state.clone(),
    };
    // The loop keeps the last accepted state in `state` (also when it fails): no copy per step.
    let result = time_loop(model, settings, &mut steps, observer, output, &mut state);
    *last_state = Some(state);
    result
}

/// Starting value of the generalized-alpha auxiliary accelerations (Arnold and Bruls 2007,
/// section 4): a(0) = q_dd(0) + (alpha_m - alpha_f) h q_ddd(0). With a(0) = q_dd(0) the method
/// is only first-order accurate in the accelerations and multipliers over an initial layer of
/// about 1/(1 - spectral radius) steps. The jerk q_ddd(0) is the difference quotient of two
/// solutions of seed eq. 26, at the start and at a Taylor-extrapolated state a short time later.
fn start_algorithmic_accelerations(
    model: &Model,
    method: &GeneralizedAlpha,
    h: f64,
    state: &mut State,
    ws: &mut Workspace,
    solvers: &mut LinearSolvers,
) -> Result<()> {
    let weight = (method.alpha_m - method.alpha_f) * h;
    if weight == 0.0 {
        state.algorithmic_accelerations.copy_from_slice(&state.accelerations);
        return Ok(());
    }
    let delta = 1e-3 * h;
    let mut later = state.clone();
    later.time += delta;
    for k in 0..model.coordinate_count {
        later.coordinates[k] += delta * state.velocities[k] + 0.5 * delta * delta * state.accelerations[k];
        later.velocities[k] += delta * state.accelerations[k];
    }
    solve_accelerations(model, &mut later, ws, solvers)?;
    for k in 0..model.coordinate_count {
        let jerk = (later.accelerations[k] - state.accelerations[k]) / delta;
        state.algorithmic_accelerations[k] = state.accelerations[k] + weight * jerk;
    }
    Ok(())
}

/// What the generalized-alpha steps of a run work with.
struct GeneralizedAlphaSteps<'a> {
    model: &'a Model,
    settings: &'a SimulationSettings,
    method: GeneralizedAlpha,
    /// Whether velocities are projected after every step (`projection`).
    project_velocities: bool,
    ws: Workspace,
    solvers: LinearSolvers,
    /// The factorized Newton matrix kept between steps.
    cache: JacobianCache,
    /// The end of the last step attempt: the next accepted state when it passed.
    next: State,
}

impl Stepper for GeneralizedAlphaSteps<'_> {
    /// The Newton step (`step`); with error control, its error test.
    fn attempt(&mut self, state: &State, h: f64, output: &mut Output) -> Result<Attempt> {
        let (model, settings) = (self.model, self.settings);
        let report = step(
            model,
            &self.method,
            &settings.newton,
            self.project_velocities,
            h,
            state,
            &mut self.next,
            &mut self.ws,
            &mut self.solvers,
            &mut self.cache,
        )?;
        let stats = &mut output.statistics;
        stats.newton_iterations += report.iterations;
        stats.factorizations += report.factorizations;
        if !report.converged {
            let nq = model.coordinate_count;
            let item = if report.worst < nq {
                model.coordinate_name(report.worst)
            } else {
                model.constraint_name(report.worst - nq)
            };
            let diverged = FlexmbdError::NewtonDiverged {
                time: state.time,
                step_size: h,
                iterations: report.iterations,
                residual: report.increment_norm,
                item: format!("{item}; {}", report.failure.clone().unwrap_or_else(|| "error test".into())),
            };
            return Ok(Attempt::Rejected(match settings.step_control {
                StepControl::Fixed => Retry::Fail(diverged),
                _ => Retry::Shorter { step_size: h * shortening(&report), cause: Some(diverged) },
            }));
        }
        let growth = match settings.step_control {
            StepControl::Fixed => Growth::Kept,
            StepControl::Newton => Growth::Grown(newton_growth(&report)),
            StepControl::Error { relative_tolerance, absolute_tolerance } => {
                let err = error_norm(
                    model,
                    &self.method,
                    h,
                    state,
                    &self.next,
                    relative_tolerance,
                    absolute_tolerance,
                );
                let factor = (0.9 * err.max(1e-10).powf(-1.0 / 3.0)).clamp(0.2, 2.0);
                if !(err <= 1.0) {
                    return Ok(Attempt::Rejected(Retry::Shorter { step_size: h * factor, cause: None }));
                }
                Growth::Scaled(factor)
            }
        };
        Ok(Attempt::Passed { growth, newton_iterations: report.iterations })
    }

    fn accept(&mut self, state: &mut State, _h: f64, output: &mut Output) -> Result<()> {
        std::mem::swap(state, &mut self.next);
        update_discrete(self.model, state, &mut self.ws, false, &mut output.events)?;
        Ok(())
    }

    fn record(&mut self, state: &mut State, output: &mut Output) -> Result<()> {
        output.record(self.model, state, &mut self.ws);
        Ok(())
    }

    /// Nothing: the attempts count the statistics, and `state` is the one kept.
    fn completed(&mut self, _state: &State, _output: &mut Output) {}
}

/// The contraction rate of Newton's method that the step sizes of Newton-based control aim at
/// (the default `NewtonSettings::contraction_limit`).
const TARGET_CONTRACTION: f64 = 0.25;

/// The factor of the step size after a step that converged in the report's iterations, with
/// the contraction rate theta it measured (`newton::convergence`): doubled after at most four
/// iterations; otherwise the step whose iterations would contract at `TARGET_CONTRACTION`
/// if theta grows in proportion to the step (Newton's contraction with a matrix that misses
/// terms of the Jacobian, and with the nonlinearity over a step), between 1 and 2. Slow
/// iterations that converge keep the step: a smaller one costs more steps for the same
/// iterations where theta does not fall with the step (the approximate iteration matrix of a
/// soft condensed body contracts at 0.1-0.3 at every step size).
fn newton_growth(report: &StepReport) -> f64 {
    if report.iterations <= 4 || report.contraction <= 0.0 {
        return 2.0;
    }
    (TARGET_CONTRACTION / report.contraction).clamp(1.0, 2.0)
}

/// The factor of the step size after a step whose Newton iteration failed: where it measured
/// its contraction rate theta (`newton::convergence`: increments growing, or shrinking too
/// slowly to converge in the iterations allowed), the step of `TARGET_CONTRACTION` for theta
/// in proportion to the step, between a quarter and a half; a quarter for other failures
/// (a singular matrix, a non-finite increment).
fn shortening(report: &StepReport) -> f64 {
    if report.contraction > 0.0 {
        (TARGET_CONTRACTION / report.contraction).clamp(0.25, 0.5)
    } else {
        0.25
    }
}

/// Weighted RMS norm of the generalized-alpha local error estimate.
fn error_norm(
    model: &Model,
    method: &GeneralizedAlpha,
    h: f64,
    current: &State,
    next: &State,
    rtol: f64,
    atol: f64,
) -> f64 {
    let c = h * h * method.local_error_constant();
    let n = model.coordinate_count;
    let sum: f64 = (0..n)
        .map(|k| {
            let e = c * (next.accelerations[k] - current.accelerations[k]);
            let w = atol + rtol * current.coordinates[k].abs().max(next.coordinates[k].abs());
            (e / w).powi(2)
        })
        .sum();
    (sum / n as f64).sqrt()
}
