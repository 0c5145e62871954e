//! Typed errors. Every variant names the offending item (and the time, for run-time failures)
//! so that a user can find it in the model; the Python binding maps each variant to one
//! exception class under `flexmbd.FlexmbdError`.

use thiserror::Error;

/// A time in a message: 9 significant digits without trailing zeros for times from 1e-3 to
/// 1e6 s (and 0), else 7 significant digits in scientific notation (a time of 1e300 is not
/// written out in 301 digits).
#[derive(Clone, Copy, Debug)]
pub struct Seconds(pub f64);

impl std::fmt::Display for Seconds {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let t = self.0;
        if t == 0.0 {
            return write!(f, "0");
        }
        if !(t.is_finite() && (1e-3..1e6).contains(&t.abs())) {
            return write!(f, "{t:.6e}");
        }
        let decimals = (8 - t.abs().log10().floor() as i32).clamp(0, 12) as usize;
        let text = format!("{t:.decimals$}");
        let text = if text.contains('.') { text.trim_end_matches('0').trim_end_matches('.') } else { &text };
        write!(f, "{text}")
    }
}

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
        "inconsistent initial conditions at t = {}: {item} keeps a violation of {residual:.3e} \
         after {iterations} iterations"
    , Seconds(*.time))]
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
    #[error("initial conditions at t = {} need a correction of {size:.3e}, refused (strict): {item}", Seconds(*.time))]
    InitialCorrectionRefused {
        /// Simulation time of the start.
        time: f64,
        /// What the correction would move: joints violated, bodies moved.
        item: String,
        /// The largest move of a coordinate or velocity.
        size: f64,
    },
    /// Joint coordinates: the initial velocities violate the tree joints (left as given by the
    /// initial conditions), so no joint rates give them.
    #[error(
        "initial velocities at t = {} violate the tree joints: joint coordinates hold only \
         velocities that satisfy them ({item} would move by {size:.3e}). Velocities left as given \
         (correct_initial_velocities off): let the initial conditions correct them, or take an \
         augmented strategy, which integrates them as given. Velocities corrected that still \
         violate them: a constraint contradicts a tree joint (a driver of a coordinate the joint \
         locks, such as an angle driver on a universal joint's markers), which an augmented \
         strategy names"
    , Seconds(*.time))]
    VelocitiesOffTheTree {
        /// Simulation time of the start.
        time: f64,
        /// The coordinate whose velocity differs most.
        item: String,
        /// Its difference.
        size: f64,
    },
    /// The Newton iteration of a time step did not converge, even at the smallest step size.
    #[error(
        "Newton iteration diverged at t = {} (step size {step_size:.3e}) after {iterations} \
         iterations, residual {residual:.3e}; largest residual in {item}"
    , Seconds(*.time))]
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
    #[error("step size {step_size:.3e} fell below the minimum {min_step_size:.3e} at t = {}", Seconds(*.time))]
    StepSizeTooSmall {
        /// Time at which it happened.
        time: f64,
        /// Proposed step size.
        step_size: f64,
        /// The configured minimum.
        min_step_size: f64,
    },
    /// A linear system is singular (redundant constraints, a singular configuration, a zero mass).
    #[error("singular {context} at t = {}: {detail}", Seconds(*.time))]
    SingularMatrix {
        /// Time at which it happened.
        time: f64,
        /// Which system: `Newton matrix`, `acceleration system`, ...
        context: String,
        /// What the factorization reported.
        detail: String,
    },
    /// A NaN or infinity appeared in the state or in a computed quantity.
    #[error("non-finite value in {item} at t = {}", Seconds(*.time))]
    NonFinite {
        /// Where it was found.
        item: String,
        /// Time at which it was found.
        time: f64,
    },
    /// A user callback (time function, force) failed or returned a wrong shape.
    #[error("callback of {item} failed at t = {}: {message}", Seconds(*.time))]
    Callback {
        /// The item owning the callback.
        item: String,
        /// Time of the call.
        time: f64,
        /// The callback's own error message.
        message: String,
    },
    /// A constraint equation left out as redundant (a linear combination of the kept ones
    /// where it was chosen) is violated during the run: it contradicts the kept equations
    /// (a driver on a welded joint, two drivers of one joint), or it was dependent only at a
    /// singular configuration the mechanism has left.
    #[error(
        "conflicting constraints at t = {}: {item}, left out as redundant at t = {}, is violated by \
         {violation:.3e} (the kept equations hold): it contradicts them (a driver on a welded or \
         doubly driven joint), or it repeated them only at a singular configuration (a \
         mechanism started at a dead centre)",
        Seconds(*.time),
        Seconds(*.since)
    )]
    ConflictingConstraints {
        /// Time at which the violation was found.
        time: f64,
        /// The violated equation.
        item: String,
        /// Its violation.
        violation: f64,
        /// Time at which it was left out.
        since: f64,
    },
    /// The run was interrupted by the user (Ctrl-C in Python).
    #[error("interrupted at t = {}", Seconds(*.time))]
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn times_in_messages_are_short() {
        let text = |t: f64| Seconds(t).to_string();
        assert_eq!(text(0.0), "0");
        assert_eq!(text(0.5), "0.5");
        assert_eq!(text(0.045), "0.045");
        assert_eq!(text(0.1 + 0.2), "0.3");
        assert_eq!(text(6.099768672598418e-5), "6.099769e-5");
        assert_eq!(text(1234.56789012345), "1234.56789");
        assert_eq!(text(1e300), "1.000000e300");
        assert_eq!(text(-2.5), "-2.5");
        let message = FlexmbdError::Interrupted { time: 1e300 }.to_string();
        assert!(message.len() < 40, "{message}");
    }
}
