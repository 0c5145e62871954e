//! A simulation: the settings checked, the redundancy analysis (a model without its
//! redundant constraint rows, chosen again where they become ill-conditioned, the results
//! expanded back), and the run of the integrator the settings choose. A failure returns everything recorded up to it together with the error.

use crate::error::{FlexmbdError, Result};
use crate::integrator::initial::{check_angle_drivers, starting_state};
use crate::integrator::progress::Progress;
use crate::integrator::redundancy::analyse;
use crate::integrator::reselection::run_reduced;
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
    let error = match settings
        .validate()
        .and_then(|_| starting_state(model, settings.start_time, settings.start.as_ref()))
        .and_then(|state| check_angle_drivers(model, &state))
        .and_then(|_| analyse(model, settings))
    {
        Err(e) => Some(e),
        Ok(None) => dispatch(model, settings, observer, &mut output, &mut last_state).err(),
        Ok(Some(reduction)) => {
            run_reduced(model, settings, observer, reduction, dispatch, &mut output, &mut last_state)
        }
    };
    SimulationOutcome { output, final_state: last_state, error }
}

/// Runs the integrator of the settings.
pub(crate) fn dispatch(
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::force::ForceKind;
    use crate::integrator::settings::StartState;
    use crate::joint::JointKind;
    use crate::math::{Mat3, Vec3};
    use crate::testing::assert_all_close;
    use crate::SystemBuilder;

    /// A wheel turning at 10 rad/s on a hinge, held back by a weak torsional spring whose
    /// torque follows the unwrapped angle (a discrete variable): after 1 s it has turned
    /// more than once.
    fn wheel() -> Model {
        let mut sys = SystemBuilder::new();
        let inertia = Mat3::diagonal(Vec3([1.0, 1.0, 1.0]));
        let w = Vec3([0.0, 0.0, 10.0]);
        let wheel = sys
            .add_rigid_body("wheel", 1.0, inertia, Vec3::ZERO, Vec3::ZERO, Mat3::IDENTITY, Vec3::ZERO, w)
            .unwrap();
        let g = sys.add_marker("", sys.ground(), Vec3::ZERO, Mat3::IDENTITY).unwrap();
        let b = sys.add_marker("", wheel, Vec3::ZERO, Mat3::IDENTITY).unwrap();
        sys.add_joint("hinge", JointKind::Revolute, [g, b]).unwrap();
        let kind = ForceKind::RotationalSpringDamper {
            markers: [g, b],
            stiffness: 0.5,
            damping: 0.0,
            rest_angle: 0.0,
            preload: 0.0,
        };
        sys.add_force("spring", kind).unwrap();
        sys.compile().unwrap()
    }

    #[test]
    fn a_run_continued_from_another_s_last_state_goes_on_as_one_run() {
        let model = wheel();
        let mut settings = SimulationSettings::new(2.0, 1e-3);
        settings.output_interval = Some(0.1);
        let whole = simulate(&model, &settings, &mut |_| true);
        let mut first = settings.clone();
        first.end_time = 1.0;
        let half = simulate(&model, &first, &mut |_| true);
        let last = half.final_state.expect("the last state");
        assert!(last.discrete[0] > 2.0 * std::f64::consts::PI, "turned {}", last.discrete[0]);
        let mut second = settings.clone();
        second.start = Some(StartState {
            coordinates: last.coordinates.clone(),
            velocities: last.velocities.clone(),
            time: Some(last.time),
            discrete: Some(last.discrete.clone()),
            recorded: true,
        });
        let rest = simulate(&model, &second, &mut |_| true);
        assert!(rest.error.is_none(), "{:?}", rest.error);
        // The continued run records from the next output time on, on the same grid.
        let (a, b) = (&half.output, &rest.output);
        assert_eq!(a.len() + b.len(), whole.output.len());
        assert_all_close(&b.time, &whole.output.time[a.len()..], 1e-12, 0.0, "output times");
        // The same motion (restarting generalized-alpha's auxiliary accelerations changes it
        // within the integration error); the spring went on from the unwrapped angle.
        let n = model.coordinate_count;
        let tail = &whole.output.coordinates[a.len() * n..];
        assert_all_close(&b.coordinates, tail, 1e-6, 1e-6, "coordinates");
    }
}
