//! Typed errors. Every variant names the offending item (and the time, for run-time failures)
//! so that a user can find it in the model; the Python binding maps each variant to one
//! exception class under `flexmbd.FlexmbdError`.

use thiserror::Error;

/// Every error the core can report.
#[derive(Debug, Clone, Error, PartialEq)]
pub enum FlexmbdError {
    /// A parameter is out of its physical or mathematical range (negative mass, NaN, ...).
    #[error("invalid parameter of {item}: {message}")]
    InvalidParameter {
        /// The item, e.g. `body 'crank'` or `joint 3`.
        item: String,
        /// What is wrong with it.
        message: String,
    },
    /// A reference to a body, marker, joint, force or sensor that does not exist.
    #[error("unknown {kind} {id}{context}")]
    UnknownItem {
        /// `body`, `marker`, `joint`, `force` or `sensor`.
        kind: &'static str,
        /// The id that was given.
        id: usize,
        /// Where it was used (may be empty).
        context: String,
    },
    /// The model is structurally wrong (a joint between a body and itself, ...).
    #[error("invalid model: {item}: {message}")]
    InvalidModel {
        /// The item concerned.
        item: String,
        /// What is wrong.
        message: String,
    },
    /// Newton's method could not make the initial positions or velocities satisfy the constraints.
    #[error(
        "inconsistent initial conditions at t = {time}: {item} keeps a violation of {residual:.3e} \
         after {iterations} iterations"
    )]
    InconsistentInitialConditions {
        /// Simulation time of the start.
        time: f64,
        /// The constraint with the largest remaining violation.
        item: String,
        /// Its violation.
        residual: f64,
        /// Iterations made.
        iterations: usize,
    },
    /// Strict initial conditions: the given positions or velocities violate the constraints
    /// by more than the report tolerance, and correcting them was refused.
    #[error("initial conditions at t = {time} need a correction of {size:.3e}, refused (strict): {item}")]
    InitialCorrectionRefused {
        /// Simulation time of the start.
        time: f64,
        /// What the correction would move: joints violated, bodies moved.
        item: String,
        /// The largest move of a coordinate or velocity.
        size: f64,
    },
    /// The Newton iteration of a time step did not converge, even at the smallest step size.
    #[error(
        "Newton iteration diverged at t = {time} (step size {step_size:.3e}) after {iterations} \
         iterations, residual {residual:.3e}; largest residual in {item}"
    )]
    NewtonDiverged {
        /// Start time of the failed step.
        time: f64,
        /// Step size of the last attempt.
        step_size: f64,
        /// Iterations made in the last attempt.
        iterations: usize,
        /// Scaled norm of the last residual or increment.
        residual: f64,
        /// The equation (body or constraint) with the largest residual.
        item: String,
    },
    /// The step-size controller went below the minimum step size.
    #[error("step size {step_size:.3e} fell below the minimum {min_step_size:.3e} at t = {time}")]
    StepSizeTooSmall {
        /// Time at which it happened.
        time: f64,
        /// Proposed step size.
        step_size: f64,
        /// The configured minimum.
        min_step_size: f64,
    },
    /// A linear system is singular (redundant constraints, a singular configuration, a zero mass).
    #[error("singular {context} at t = {time}: {detail}")]
    SingularMatrix {
        /// Time at which it happened.
        time: f64,
        /// Which system: `Newton matrix`, `acceleration system`, ...
        context: String,
        /// What the factorization reported.
        detail: String,
    },
    /// A NaN or infinity appeared in the state or in a computed quantity.
    #[error("non-finite value in {item} at t = {time}")]
    NonFinite {
        /// Where it was found.
        item: String,
        /// Time at which it was found.
        time: f64,
    },
    /// A user callback (time function, force) failed or returned a wrong shape.
    #[error("callback of {item} failed at t = {time}: {message}")]
    Callback {
        /// The item owning the callback.
        item: String,
        /// Time of the call.
        time: f64,
        /// The callback's own error message.
        message: String,
    },
    /// The run was interrupted by the user (Ctrl-C in Python).
    #[error("interrupted at t = {time}")]
    Interrupted {
        /// Time reached.
        time: f64,
    },
}

/// Shorthand for results carrying a [`FlexmbdError`].
pub type Result<T> = std::result::Result<T, FlexmbdError>;

/// Error for a parameter that must be finite.
pub(crate) fn check_finite(item: &str, what: &str, values: &[f64]) -> Result<()> {
    if values.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(FlexmbdError::InvalidParameter {
            item: item.to_string(),
            message: format!("{what} must be finite, got {values:?}"),
        })
    }
}
