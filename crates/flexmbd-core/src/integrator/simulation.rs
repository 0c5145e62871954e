//! A simulation: the settings checked, the redundancy analysis (a model without its
//! redundant constraint rows, the results expanded back), and the run of the integrator the
//! settings choose. A failure returns everything recorded up to it together with the error.

use crate::error::{FlexmbdError, Result};
use crate::integrator::progress::Progress;
use crate::integrator::redundancy::analyse;
use crate::integrator::settings::{Integrator, SimulationSettings};
use crate::integrator::{explicit, generalized_alpha};
use crate::output::Output;
use crate::system::{Model, State};

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
        Integrator::GeneralizedAlpha => generalized_alpha::run(model, settings, observer, output, last_state),
        Integrator::Explicit(explicit) => {
            explicit::run(model, settings, explicit, observer, output, last_state)
        }
    }
}
