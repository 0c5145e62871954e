//! The one time loop of every integrator. From the consistent initial state to the end time it
//! lands each step exactly on the output times and the end (`clock`), asks the integrator for a
//! step attempt, accepts or rejects it (counting rejections, shortening the step down to the
//! step floor), records at the output times, reports `Progress` to the observer (which may stop
//! the run) and releases the records the observer stored. A failure returns its error; what was
//! recorded up to it stays in the output.
//!
//! An integrator takes part through [`Stepper`]: generalized-alpha with its Newton step
//! (`generalized_alpha::run`), the explicit Runge-Kutta methods with their strategies
//! (`explicit::run`).

use std::cell::Cell;

use crate::error::{FlexmbdError, Result};
use crate::integrator::clock::{step_above_output_interval, OutputClock};
use crate::integrator::progress::{Progress, Records};
use crate::integrator::settings::SimulationSettings;
use crate::output::{Output, Statistics};
use crate::system::{Model, State};

/// An integrator's part in the time loop: one step attempt from the last accepted state, the
/// acceptance of a step that passed, and the recording of an accepted state.
pub(crate) trait Stepper {
    /// Attempts a step of size `step_size` from the accepted `state` (left unchanged). The
    /// attempt adds its statistics (Newton iterations, factorizations) and events to `output`.
    /// `Err`: the run fails with it, without a rejected step counted.
    fn attempt(&mut self, state: &State, step_size: f64, output: &mut Output) -> Result<Attempt>;

    /// Moves `state` to the end of the attempt of size `step_size` that passed, with its
    /// discrete variables advanced; events of the acceptance go to `output`.
    fn accept(&mut self, state: &mut State, step_size: f64, output: &mut Output) -> Result<()>;

    /// Records the accepted `state` at an output time (completing it first where the
    /// integrator leaves its accelerations and multipliers out between records).
    fn record(&mut self, state: &mut State, output: &mut Output) -> Result<()>;

    /// After an accepted step was checked and recorded, before the observer sees it: the
    /// statistics the integrator keeps by itself, and the state kept for a failure later.
    fn completed(&mut self, state: &State, output: &mut Output);
}

/// What a step attempt gives the loop.
pub(crate) enum Attempt {
    /// The step passed and is accepted.
    Passed {
        /// How the step size changes for the next step.
        growth: Growth,
        /// Newton iterations of the step, for the observer (0 for explicit steps).
        newton_iterations: usize,
    },
    /// The step failed: a rejected step is counted, then the loop does what it says.
    Rejected(Retry),
}

/// How the step size changes after an accepted step.
pub(crate) enum Growth {
    /// Kept (fixed steps, or a Newton step that needed many iterations).
    Kept,
    /// Multiplied by the factor (at least 1), up to the step size of the settings, if below
    /// it (Newton-based control: a step that converged fast enough).
    Grown(f64),
    /// The step size of the step times the error controller's factor, at most the largest step
    /// size; kept if the step was shortened to land on an output time.
    Scaled(f64),
}

/// What the loop does after a rejected step attempt.
pub(crate) enum Retry {
    /// Attempts again from the same state with `step_size`; below the step floor the run fails
    /// with `cause` (the failure of the attempt), or `StepSizeTooSmall` without one.
    Shorter { step_size: f64, cause: Option<FlexmbdError> },
    /// Attempts again with the same step size (the attempt changed what the next one works
    /// with: a new partition of the coordinates).
    Again,
    /// The run fails with the error (fixed steps have no smaller step to try).
    Fail(FlexmbdError),
}

/// The steps of a run from the consistent, recorded initial `state` to the end time; `state`
/// holds the last accepted state on return (also on failure).
pub(crate) fn time_loop(
    model: &Model,
    settings: &SimulationSettings,
    stepper: &mut impl Stepper,
    observer: &mut dyn FnMut(&Progress) -> bool,
    output: &mut Output,
    state: &mut State,
) -> Result<()> {
    let mut clock = OutputClock::new(settings, state.time);
    output.events.extend(step_above_output_interval(settings, state.time));
    let mut h = settings.step_size;
    let release = Cell::new(0);
    output.statistics.min_step_size_used = f64::INFINITY;

    while clock.running(state.time) {
        // Land exactly on the end and on output times.
        let h_try = clock.step(state.time, h);
        let (growth, newton_iterations) = match stepper.attempt(state, h_try, output)? {
            Attempt::Passed { growth, newton_iterations } => (growth, newton_iterations),
            Attempt::Rejected(retry) => {
                output.statistics.rejected_steps += 1;
                h = step_size_after_rejection(retry, h, state.time, settings)?;
                continue;
            }
        };

        // Accept the step.
        let from = state.time;
        stepper.accept(state, h_try, output)?;
        state.time = clock.finish_step(from, h_try);
        count_step(&mut output.statistics, h_try);
        if let Some(k) = state.first_non_finite() {
            return Err(FlexmbdError::NonFinite { item: model.coordinate_name(k), time: state.time });
        }
        if clock.due(state.time) {
            stepper.record(state, output)?;
        }
        stepper.completed(state, output);
        h = step_size_after_acceptance(growth, h, h_try, settings);
        let progress = Progress {
            time: state.time,
            step_size: h_try,
            newton_iterations,
            steps: output.statistics.steps,
            state,
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

/// The step size of the next attempt after a rejected one at `time` with step size `h`, or the
/// error that ends the run.
fn step_size_after_rejection(retry: Retry, h: f64, time: f64, settings: &SimulationSettings) -> Result<f64> {
    match retry {
        Retry::Again => Ok(h),
        Retry::Fail(error) => Err(error),
        Retry::Shorter { step_size, cause } => {
            let floor = settings.step_floor();
            if step_size < floor {
                return Err(cause.unwrap_or(FlexmbdError::StepSizeTooSmall {
                    time,
                    step_size,
                    min_step_size: floor,
                }));
            }
            Ok(step_size)
        }
    }
}

/// The step size after an accepted step of size `h_try` taken with the step size `h`.
fn step_size_after_acceptance(growth: Growth, h: f64, h_try: f64, settings: &SimulationSettings) -> f64 {
    match growth {
        Growth::Kept => h,
        Growth::Grown(factor) if h < settings.step_size => (factor * h).min(settings.step_size),
        Growth::Grown(_) => h,
        // Steps shortened to land on an output time do not shrink the step size.
        Growth::Scaled(factor) if h_try >= h * (1.0 - 1e-12) => (h_try * factor).min(settings.max_step_size),
        Growth::Scaled(_) => h,
    }
}

/// Counts an accepted step of size `h` in the statistics.
fn count_step(statistics: &mut Statistics, h: f64) {
    statistics.steps += 1;
    statistics.min_step_size_used = statistics.min_step_size_used.min(h);
    statistics.max_step_size_used = statistics.max_step_size_used.max(h);
}
