//! The state advanced by the integrators (house style 1): time, coordinates, velocities,
//! accelerations, multipliers, the generalized-alpha auxiliary accelerations, and discrete
//! variables (the unwrapped angles of rotational springs).

use crate::system::model::Model;

/// State of a simulation.
#[derive(Clone, Debug)]
pub struct State {
    /// Time (s).
    pub time: f64,
    /// Generalized coordinates q (coordinate_count).
    pub coordinates: Vec<f64>,
    /// Velocities q_dot (coordinate_count).
    pub velocities: Vec<f64>,
    /// Accelerations q_dd (coordinate_count).
    pub accelerations: Vec<f64>,
    /// Lagrange multipliers lambda (constraint_count).
    pub multipliers: Vec<f64>,
    /// Generalized-alpha auxiliary accelerations a (coordinate_count).
    pub algorithmic_accelerations: Vec<f64>,
    /// Discrete variables (discrete_count).
    pub discrete: Vec<f64>,
    /// Accelerations of the previous step (for the predictor).
    pub previous_accelerations: Vec<f64>,
    /// Multipliers of the previous step (for the predictor).
    pub previous_multipliers: Vec<f64>,
    /// Size of the step that led to this state (0 at the start).
    pub previous_step_size: f64,
}

impl State {
    /// The initial state as given by the user (constraints not yet enforced).
    pub fn initial(model: &Model, time: f64) -> Self {
        let n = model.coordinate_count;
        State {
            time,
            coordinates: model.initial_coordinates.clone(),
            velocities: model.initial_velocities.clone(),
            accelerations: vec![0.0; n],
            multipliers: vec![0.0; model.constraint_count],
            algorithmic_accelerations: vec![0.0; n],
            discrete: vec![0.0; model.discrete_count],
            previous_accelerations: vec![0.0; n],
            previous_multipliers: vec![0.0; model.constraint_count],
            previous_step_size: 0.0,
        }
    }

    /// Copies this state into `slot`, reusing the vectors of a state already there (no
    /// allocation per step where a loop keeps its last accepted state).
    pub fn store_in(&self, slot: &mut Option<State>) {
        let Some(kept) = slot else {
            *slot = Some(self.clone());
            return;
        };
        // Every field by name (a field added to the state does not compile here until copied).
        let State {
            time,
            coordinates,
            velocities,
            accelerations,
            multipliers,
            algorithmic_accelerations,
            discrete,
            previous_accelerations,
            previous_multipliers,
            previous_step_size,
        } = self;
        kept.time = *time;
        kept.coordinates.clone_from(coordinates);
        kept.velocities.clone_from(velocities);
        kept.accelerations.clone_from(accelerations);
        kept.multipliers.clone_from(multipliers);
        kept.algorithmic_accelerations.clone_from(algorithmic_accelerations);
        kept.discrete.clone_from(discrete);
        kept.previous_accelerations.clone_from(previous_accelerations);
        kept.previous_multipliers.clone_from(previous_multipliers);
        kept.previous_step_size = *previous_step_size;
    }

    /// Checks that every number is finite; returns the first offending coordinate index.
    pub fn first_non_finite(&self) -> Option<usize> {
        if crate::math::all_finite(&self.coordinates) && crate::math::all_finite(&self.velocities) {
            return None;
        }
        self.coordinates.iter().zip(&self.velocities).position(|(q, v)| !q.is_finite() || !v.is_finite())
    }
}
