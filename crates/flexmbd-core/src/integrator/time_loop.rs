//! The time loop: consistent initial conditions, generalized-alpha steps with step-size
//! control, landing exactly on output times, recording. A failure returns everything recorded
//! up to it together with the error.

use std::cell::Cell;

use crate::error::{FlexmbdError, Result};
use crate::integrator::clock::OutputClock;
use crate::integrator::discrete::update_discrete;
use crate::integrator::explicit;
use crate::integrator::generalized_alpha::{step, GeneralizedAlpha, JacobianCache};
use crate::integrator::initial::{
    report_initial_correction, solve_accelerations, solve_initial_positions_and_velocities, starting_state,
};
use crate::integrator::progress::{Progress, Records};
use crate::integrator::redundancy::analyse;
use crate::integrator::settings::{Integrator, SimulationSettings, StepControl};
use crate::linear_system::LinearSolvers;
use crate::output::Output;
use crate::system::{Model, State, Workspace};

/// The result of `simulate`: what was recorded, and the error that stopped the run, if any.
#[derive(Debug)]
pub struct SimulationOutcome {
    /// Records up to the end or to the failure.
    pub output: Output,
    /// The state at the end (or at the last accepted step before a failure).
    pub final_state: Option<State>,
    /// The error that stopped the run.
    pub error: Option<FlexmbdError>,
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
    let c = h * h * (method.beta - 1.0 / 6.0).abs().max(1.0 / 12.0);
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

/// Runs a simulation of `model`. `observer` is called after every accepted step; returning
/// false stops the run with an `Interrupted` error (results so far are kept).
pub fn simulate(
    model: &Model,
    settings: &SimulationSettings,
    observer: &mut dyn FnMut(&Progress) -> bool,
) -> SimulationOutcome {
    let mut output = Output::new(model);
    let mut last_state = None;
    let error = match settings.validate().and_then(|_| analyse(model, settings)) {
        Err(e) => Some(e),
        Ok(None) => dispatch(model, settings, observer, &mut output, &mut last_state).err(),
        Ok(Some(reduction)) => {
            let mut reduced = Output::new(&reduction.model);
            let handling = settings.redundancy.handling;
            let mut expanding = |p: &Progress| {
                let records = p.records.expanded(model, &reduction, handling);
                observer(&Progress { records, ..*p })
            };
            let error =
                dispatch(&reduction.model, settings, &mut expanding, &mut reduced, &mut last_state).err();
            output = reduction.expand_output(model, reduced, handling);
            last_state = last_state.map(|s| reduction.expand_state(model, s));
            error
        }
    };
    SimulationOutcome { output, final_state: last_state, error }
}

/// Runs the integrator of the settings.
fn dispatch(
    model: &Model,
    settings: &SimulationSettings,
    observer: &mut dyn FnMut(&Progress) -> bool,
    output: &mut Output,
    last_state: &mut Option<State>,
) -> Result<()> {
    match &settings.integrator {
        Integrator::GeneralizedAlpha => run(model, settings, observer, output, last_state),
        Integrator::Explicit(explicit) => {
            explicit::run(model, settings, explicit, observer, output, last_state)
        }
    }
}

/// The time loop; keeps the last accepted state in `last_state` (also on failure).
fn run(
    model: &Model,
    settings: &SimulationSettings,
    observer: &mut dyn FnMut(&Progress) -> bool,
    output: &mut Output,
    last_state: &mut Option<State>,
) -> Result<()> {
    settings.validate()?;
    let method = GeneralizedAlpha::from_spectral_radius(settings.spectral_radius)?;
    let project_velocities = settings.newton.velocity_projection.enabled(settings.spectral_radius);
    let mut ws = Workspace::new(model);
    let mut solvers = LinearSolvers::new(model)?;
    let mut state = starting_state(model, settings.start_time, settings.start.as_ref())?;
    let (given_q, given_qd) = (state.coordinates.clone(), state.velocities.clone());
    let violated =
        solve_initial_positions_and_velocities(model, &mut state, &mut ws, &mut solvers, &settings.initial)?;
    report_initial_correction(model, &given_q, &given_qd, &state, &violated, settings, output)?;
    update_discrete(model, &mut state, &mut ws, true);
    solve_accelerations(model, &mut state, &mut ws, &mut solvers)?;
    let first_step = settings.step_size.min(settings.end_time - settings.start_time).max(f64::MIN_POSITIVE);
    start_algorithmic_accelerations(
        model,
        &method,
        first_step.min(settings.output_interval.unwrap_or(first_step)),
        &mut state,
        &mut ws,
        &mut solvers,
    )?;
    output.record(model, &state, &mut ws);
    // The loop keeps the last accepted state in `state` (also when it fails): no copy per step.
    let solving = Solving { method: &method, project_velocities, ws: &mut ws, solvers: &mut solvers };
    let result = time_loop(model, settings, solving, observer, output, &mut state);
    *last_state = Some(state);
    result
}

/// What the generalized-alpha steps of a run work with: the method, whether velocities are
/// projected, the workspace and the linear solvers.
struct Solving<'a> {
    method: &'a GeneralizedAlpha,
    project_velocities: bool,
    ws: &'a mut Workspace,
    solvers: &'a mut LinearSolvers,
}

/// The steps of [`run`] from the consistent initial state `state`, which holds the last
/// accepted state on return (also on failure).
fn time_loop(
    model: &Model,
    settings: &SimulationSettings,
    solving: Solving,
    observer: &mut dyn FnMut(&Progress) -> bool,
    output: &mut Output,
    state: &mut State,
) -> Result<()> {
    let Solving { method, project_velocities, ws, solvers } = solving;
    let mut clock = OutputClock::new(settings);
    let mut h = settings.step_size;
    let mut next = state.clone();
    let mut cache = JacobianCache::default();
    let release = Cell::new(0);
    output.statistics.min_step_size_used = f64::INFINITY;

    while clock.running(state.time) {
        // Land exactly on the end and on output times.
        let h_try = clock.step(state.time, h);
        let report = step(
            model,
            method,
            &settings.newton,
            project_velocities,
            h_try,
            state,
            &mut next,
            ws,
            solvers,
            &mut cache,
        )?;
        let stats = &mut output.statistics;
        stats.newton_iterations += report.iterations;
        stats.factorizations += report.factorizations;
        let mut accepted = report.converged;
        let mut factor = 1.0;
        if let (true, StepControl::Error { relative_tolerance, absolute_tolerance }) =
            (accepted, settings.step_control)
        {
            let err = error_norm(model, method, h_try, state, &next, relative_tolerance, absolute_tolerance);
            factor = (0.9 * err.max(1e-10).powf(-1.0 / 3.0)).clamp(0.2, 2.0);
            accepted = err <= 1.0;
        }
        if !accepted {
            stats.rejected_steps += 1;
            let diverged = || {
                let nq = model.coordinate_count;
                let item = if report.worst < nq {
                    model.coordinate_name(report.worst)
                } else {
                    model.constraint_name(report.worst - nq)
                };
                FlexmbdError::NewtonDiverged {
                    time: state.time,
                    step_size: h_try,
                    iterations: report.iterations,
                    residual: report.increment_norm,
                    item: format!(
                        "{item}; {}",
                        report.failure.clone().unwrap_or_else(|| "error test".into())
                    ),
                }
            };
            h = match settings.step_control {
                StepControl::Fixed => return Err(diverged()),
                StepControl::Error { .. } if report.converged => h_try * factor,
                _ => h_try * 0.25,
            };
            if h < settings.step_floor() {
                return Err(if report.converged {
                    FlexmbdError::StepSizeTooSmall {
                        time: state.time,
                        step_size: h,
                        min_step_size: settings.step_floor(),
                    }
                } else {
                    diverged()
                });
            }
            continue;
        }

        // Accept the step.
        std::mem::swap(state, &mut next);
        update_discrete(model, state, ws, false);
        stats.steps += 1;
        stats.min_step_size_used = stats.min_step_size_used.min(h_try);
        stats.max_step_size_used = stats.max_step_size_used.max(h_try);
        if let Some(k) = state.first_non_finite() {
            return Err(FlexmbdError::NonFinite { item: model.coordinate_name(k), time: state.time });
        }
        if clock.due(state.time) {
            output.record(model, state, ws);
        }
        // Next step size.
        match settings.step_control {
            StepControl::Fixed => {}
            StepControl::Newton => {
                if report.iterations <= 4 && h < settings.step_size {
                    h = (2.0 * h).min(settings.step_size);
                }
            }
            StepControl::Error { .. } => {
                // Steps shortened to land on an output time do not shrink the step size.
                if h_try >= h * (1.0 - 1e-12) {
                    h = (h_try * factor).min(settings.max_step_size);
                }
            }
        }
        let progress = Progress {
            time: state.time,
            step_size: h_try,
            newton_iterations: report.iterations,
            steps: output.statistics.steps,
            records: Records::new(output),
            release: &release,
        };
        if !observer(&progress) {
            return Err(FlexmbdError::Interrupted { time: state.time });
        }
        output.release_front(release.take());
    }
    Ok(())
}
