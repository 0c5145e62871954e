//! The discrete variables of a state (the unwrapped angles of rotational springs and joint
//! actuators, and the actuators' saturation states), set at the start and advanced after
//! every accepted step; an actuator whose effort reaches or leaves its limit gives an
//! "actuator saturation" event.

use crate::assembly::update_kinematics;
use crate::error::Result;
use crate::force::joint_actuator::{effort_at, ActuatedCoordinate};
use crate::force::rotational_spring_damper::{unwrapped_angle, wrapped_angle};
use crate::force::{ForceKind, ForceLocal};
use crate::integrator::settings::SimulationSettings;
use crate::output::Event;
use crate::system::{Model, State, Workspace};

/// Sets the discrete variables of the starting `state` from its coordinates, unless the run
/// continues another whose discrete variables the start state carries: those are advanced.
pub(crate) fn start_discrete(
    model: &Model,
    state: &mut State,
    ws: &mut Workspace,
    settings: &SimulationSettings,
    events: &mut Vec<Event>,
) -> Result<()> {
    let continued = settings.start.as_ref().is_some_and(|s| s.discrete.is_some());
    update_discrete(model, state, ws, !continued, events)
}

/// Sets or advances the discrete variables from the state, with the events of actuators
/// whose saturation changed.
pub(crate) fn update_discrete(
    model: &Model,
    state: &mut State,
    ws: &mut Workspace,
    initialize: bool,
    events: &mut Vec<Event>,
) -> Result<()> {
    if model.discrete_count == 0 {
        return Ok(());
    }
    update_kinematics(model, &state.coordinates, &state.velocities, ws);
    let env = model.force_env(state, ws);
    let angle = |markers, k: usize| {
        let pair = env.pair(markers);
        if initialize {
            wrapped_angle(&pair)
        } else {
            unwrapped_angle(&pair, state.discrete[k])
        }
    };
    let mut updates = Vec::new();
    for f in &model.forces {
        let Some(k) = f.discrete else { continue };
        match &f.kind {
            ForceKind::RotationalSpringDamper { markers, .. } => updates.push((k, angle(markers, k))),
            ForceKind::JointActuator { markers, coordinate, law } => {
                let (reference, flag) = match coordinate {
                    ActuatedCoordinate::Angle => {
                        let reference = angle(markers, k);
                        updates.push((k, reference));
                        (reference, k + 1)
                    }
                    ActuatedCoordinate::Slide => (0.0, k),
                };
                let item = format!("actuator '{}'", f.name);
                let mut local = ForceLocal::with_size(f.dofs.len());
                let effort = effort_at(
                    &item,
                    &env.pair(markers),
                    *coordinate,
                    law,
                    reference,
                    state.time,
                    &mut local,
                )?;
                let before = if initialize { 0.0 } else { state.discrete[flag] };
                if effort.saturation != before {
                    let unit = coordinate.effort_unit();
                    let message = if effort.saturation != 0.0 {
                        format!(
                            "{item} saturated: effort held at {:+} {unit} (the law asks for {:.6e} {unit})",
                            effort.effort, effort.demand
                        )
                    } else {
                        format!("{item} back within its limit: effort {:.6e} {unit}", effort.effort)
                    };
                    events.push(Event { time: state.time, kind: "actuator saturation".to_string(), message });
                }
                updates.push((flag, effort.saturation));
            }
            _ => {}
        }
    }
    for (k, value) in updates {
        state.discrete[k] = value;
    }
    Ok(())
}

/// The discrete variables at (`time`, `coordinates`, `velocities`) for the analyses that
/// move a state outside a run (an equilibrium's Newton iterates): set from the coordinates
/// (the wrapped angles) without `previous`, else advanced from `previous` as after an
/// accepted step (the angles continued from theirs, so that they pass +-pi).
pub fn discrete_at(
    model: &Model,
    ws: &mut Workspace,
    time: f64,
    coordinates: &[f64],
    velocities: &[f64],
    previous: Option<&[f64]>,
) -> Result<Vec<f64>> {
    let mut state = State::initial(model, time);
    state.coordinates.copy_from_slice(coordinates);
    state.velocities.copy_from_slice(velocities);
    if let Some(previous) = previous {
        state.discrete.copy_from_slice(previous);
    }
    update_discrete(model, &mut state, ws, previous.is_none(), &mut Vec::new())?;
    Ok(state.discrete)
}
