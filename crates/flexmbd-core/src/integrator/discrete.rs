//! The discrete variables of a state (the unwrapped angles of rotational springs), set at the
//! start and advanced after every accepted step.

use crate::assembly::update_kinematics;
use crate::force::rotational_spring_damper::{unwrapped_angle, wrapped_angle};
use crate::force::{ForceEnv, ForceKind};
use crate::integrator::settings::SimulationSettings;
use crate::system::{Model, State, Workspace};

/// Sets the discrete variables of the starting `state` from its coordinates, unless the run
/// continues another whose discrete variables the start state carries: those are advanced.
pub(crate) fn start_discrete(
    model: &Model,
    state: &mut State,
    ws: &mut Workspace,
    settings: &SimulationSettings,
) {
    let continued = settings.start.as_ref().is_some_and(|s| s.discrete.is_some());
    update_discrete(model, state, ws, !continued);
}

/// Sets or advances the discrete variables (unwrapped spring angles) from the state.
pub(crate) fn update_discrete(model: &Model, state: &mut State, ws: &mut Workspace, initialize: bool) {
    if model.discrete_count == 0 {
        return;
    }
    update_kinematics(model, &state.coordinates, &state.velocities, ws);
    let env = ForceEnv {
        bodies: &model.bodies,
        markers: &model.markers,
        kinematics: &ws.markers,
        q: &state.coordinates,
        qd: &state.velocities,
        time: state.time,
        discrete: &state.discrete,
    };
    let mut updates = Vec::new();
    for f in &model.forces {
        if let (ForceKind::RotationalSpringDamper { markers, .. }, Some(k)) = (&f.kind, f.discrete) {
            let pair = env.pair(markers);
            let angle =
                if initialize { wrapped_angle(&pair) } else { unwrapped_angle(&pair, state.discrete[k]) };
            updates.push((k, angle));
        }
    }
    for (k, angle) in updates {
        state.discrete[k] = angle;
    }
}
