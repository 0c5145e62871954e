//! Applied forces: gravity (per body), point forces and torques at markers, translational and
//! rotational spring-dampers between markers, joint actuators (PD servos), and user callbacks. Each force element gives its
//! generalized force Q (by virtual work) and the Jacobians -dQ/dq and -dQ/dq_dot that enter
//! the Newton matrix.

pub mod callback;
pub mod gravity;
pub mod joint_actuator;
pub mod point_load;
pub mod rotational_spring_damper;
pub mod spring_damper;

use std::sync::Arc;

use crate::body::marker::{Marker, MarkerKinematics};
use crate::body::Body;
use crate::error::{FlexmbdError, Result};
use crate::ids::{BodyId, MarkerId};
use crate::joint::equation::MarkerPair;
use crate::math::dense::DenseMatrix;
use crate::math::time_function::TimeFunction;
pub use callback::ForceCallback;
use joint_actuator::{ActuatedCoordinate, ServoLaw};

/// Axes in which vector components are given.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Frame {
    /// Global (inertial) axes.
    Global,
    /// Axes of the marker (they turn with the body).
    Marker,
}

/// The type of a force element and its parameters.
#[derive(Clone)]
pub enum ForceKind {
    /// Force (N) at the origin of a marker.
    PointForce {
        /// Point of application.
        marker: MarkerId,
        /// Components as functions of time.
        components: [TimeFunction; 3],
        /// Axes of the components.
        frame: Frame,
    },
    /// Torque (N m) on the body of a marker (on a deformable body the point matters).
    Torque {
        /// Where it acts.
        marker: MarkerId,
        /// Components as functions of time.
        components: [TimeFunction; 3],
        /// Axes of the components.
        frame: Frame,
    },
    /// Linear spring-damper between the origins of two markers, along the line joining them.
    SpringDamper {
        /// Markers i and j.
        markers: [MarkerId; 2],
        /// Stiffness (N/m).
        stiffness: f64,
        /// Damping (N s/m).
        damping: f64,
        /// Length at zero spring force (m).
        rest_length: f64,
        /// Constant tension added (N).
        preload: f64,
    },
    /// Torsional spring-damper about the z axis of marker i (angle of x_j from x_i).
    RotationalSpringDamper {
        /// Markers i and j.
        markers: [MarkerId; 2],
        /// Stiffness (N m/rad).
        stiffness: f64,
        /// Damping (N m s/rad).
        damping: f64,
        /// Angle at zero spring torque (rad).
        rest_angle: f64,
        /// Constant torque added (N m).
        preload: f64,
    },
    /// A PD servo on the angle or the slide of a joint's markers (see [`joint_actuator`]).
    JointActuator {
        /// Markers i and j (the joint's).
        markers: [MarkerId; 2],
        /// The coordinate it drives.
        coordinate: ActuatedCoordinate,
        /// Gains, set point, feed-forward effort and limit.
        law: ServoLaw,
    },
    /// User function Q(t, q, q_dot) on the coordinates of the listed bodies.
    Callback {
        /// Bodies whose coordinates the callback reads and loads (in this order).
        bodies: Vec<BodyId>,
        /// The function.
        callback: Arc<dyn ForceCallback>,
    },
}

impl std::fmt::Debug for ForceKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.type_name())
    }
}

impl ForceKind {
    /// Name of the type, as in the Python API.
    pub fn type_name(&self) -> &'static str {
        match self {
            ForceKind::PointForce { .. } => "point force",
            ForceKind::Torque { .. } => "torque",
            ForceKind::SpringDamper { .. } => "spring-damper",
            ForceKind::RotationalSpringDamper { .. } => "rotational spring-damper",
            ForceKind::JointActuator { .. } => "joint actuator",
            ForceKind::Callback { .. } => "callback force",
        }
    }

    /// The number of discrete variables of the element (unwrapped angles, saturation states).
    pub fn discrete_variables(&self) -> usize {
        match self {
            ForceKind::RotationalSpringDamper { .. } => 1,
            ForceKind::JointActuator { coordinate, .. } => coordinate.discrete_variables(),
            _ => 0,
        }
    }

    /// Markers the element acts on (one or two), none for callbacks.
    pub fn markers(&self) -> Vec<MarkerId> {
        match self {
            ForceKind::PointForce { marker, .. } | ForceKind::Torque { marker, .. } => vec![*marker],
            ForceKind::SpringDamper { markers, .. }
            | ForceKind::RotationalSpringDamper { markers, .. }
            | ForceKind::JointActuator { markers, .. } => markers.to_vec(),
            ForceKind::Callback { .. } => vec![],
        }
    }
}

/// A force element of a compiled model.
#[derive(Clone, Debug)]
pub struct ForceElement {
    /// User name (or `force <index>`).
    pub name: String,
    /// Type and parameters.
    pub kind: ForceKind,
    /// Global coordinates it loads (local column order).
    pub dofs: Vec<usize>,
    /// Number of coordinates of the first marker's body (pair elements).
    pub n_i: usize,
    /// Index of its discrete state variable (the unwrapped angle of rotational springs).
    pub discrete: Option<usize>,
}

/// Buffers of one force element: Q, -dQ/dq and -dQ/dq_dot in local coordinates.
#[derive(Clone, Debug, Default)]
pub struct ForceLocal {
    /// Generalized force Q.
    pub generalized: Vec<f64>,
    /// -dQ/dq.
    pub stiffness: DenseMatrix,
    /// -dQ/dq_dot.
    pub damping: DenseMatrix,
    /// Scratch vectors of local size.
    pub scratch: [Vec<f64>; 5],
}

impl ForceLocal {
    /// Buffers for `n` local coordinates.
    pub fn with_size(n: usize) -> Self {
        ForceLocal {
            generalized: vec![0.0; n],
            stiffness: DenseMatrix::zeros(n, n),
            damping: DenseMatrix::zeros(n, n),
            scratch: std::array::from_fn(|_| vec![0.0; n]),
        }
    }
}

/// What a force element can read: the model's bodies and markers and the current state.
pub struct ForceEnv<'a> {
    /// Bodies of the model.
    pub bodies: &'a [Body],
    /// Markers of the model.
    pub markers: &'a [Marker],
    /// Current marker kinematics.
    pub kinematics: &'a [MarkerKinematics],
    /// Global coordinates.
    pub q: &'a [f64],
    /// Global velocities.
    pub qd: &'a [f64],
    /// Time.
    pub time: f64,
    /// Discrete state variables.
    pub discrete: &'a [f64],
}

impl<'a> ForceEnv<'a> {
    /// The pair of markers of a two-marker element.
    pub fn pair(&self, markers: &[MarkerId; 2]) -> MarkerPair<'a> {
        let (mi, mj) = (&self.markers[markers[0].0], &self.markers[markers[1].0]);
        MarkerPair {
            body_i: &self.bodies[mi.body.0],
            marker_i: mi,
            kin_i: &self.kinematics[markers[0].0],
            body_j: &self.bodies[mj.body.0],
            marker_j: mj,
            kin_j: &self.kinematics[markers[1].0],
        }
    }

    /// Local copies of q and q_dot for the element's coordinates.
    pub fn gather(&self, dofs: &[usize], q: &mut [f64], qd: &mut [f64]) {
        for (k, &d) in dofs.iter().enumerate() {
            q[k] = self.q[d];
            qd[k] = self.qd[d];
        }
    }
}

/// Evaluates a time-function triple at `time`.
pub(crate) fn vector_function(item: &str, f: &[TimeFunction; 3], time: f64) -> Result<crate::math::Vec3> {
    let mut v = crate::math::Vec3::ZERO;
    for k in 0..3 {
        let value = f[k].evaluate(time).map_err(|message| FlexmbdError::Callback {
            item: item.to_string(),
            time,
            message,
        })?[0];
        if !value.is_finite() {
            return Err(FlexmbdError::NonFinite { item: item.to_string(), time });
        }
        v[k] = value;
    }
    Ok(v)
}

/// Evaluates Q (and, if `tangent`, -dQ/dq and -dQ/dq_dot) of a force element into `local`.
pub fn evaluate_force(
    force: &ForceElement,
    env: &ForceEnv,
    local: &mut ForceLocal,
    tangent: bool,
) -> Result<()> {
    local.generalized.iter_mut().for_each(|x| *x = 0.0);
    if tangent {
        local.stiffness.fill_zero();
        local.damping.fill_zero();
    }
    let item = format!("force '{}'", force.name);
    match &force.kind {
        ForceKind::PointForce { marker, components, frame } => {
            point_load::point_force(&item, env, *marker, components, *frame, local, tangent)
        }
        ForceKind::Torque { marker, components, frame } => {
            point_load::torque(&item, env, *marker, components, *frame, local, tangent)
        }
        ForceKind::SpringDamper { markers, stiffness, damping, rest_length, preload } => {
            let pair = env.pair(markers);
            spring_damper::evaluate(
                &item,
                &pair,
                env.time,
                [*stiffness, *damping, *rest_length, *preload],
                local,
                tangent,
            )
        }
        ForceKind::RotationalSpringDamper { markers, stiffness, damping, rest_angle, preload } => {
            let pair = env.pair(markers);
            let reference = env.discrete[force.discrete.expect("rotational spring has a discrete state")];
            rotational_spring_damper::evaluate(
                &pair,
                env.time,
                reference,
                [*stiffness, *damping, *rest_angle, *preload],
                local,
                tangent,
            )
        }
        ForceKind::JointActuator { markers, coordinate, law } => {
            let pair = env.pair(markers);
            let reference = match coordinate {
                ActuatedCoordinate::Angle => {
                    env.discrete[force.discrete.expect("an actuator has discrete states")]
                }
                ActuatedCoordinate::Slide => 0.0,
            };
            joint_actuator::evaluate(&item, &pair, *coordinate, law, reference, env.time, local, tangent)
        }
        ForceKind::Callback { callback, .. } => {
            callback::evaluate(&item, callback.as_ref(), force, env, local, tangent)
        }
    }
}

/// The power (W) of force element `force` at the state of `env` that no potential energy
/// accounts for: the whole power Q . q_dot of loads, actuators and callback forces, the
/// damper's of a spring-damper (whose spring's energy is in [`force_potential`]).
pub fn nonconservative_power(force: &ForceElement, env: &ForceEnv, local: &mut ForceLocal) -> Result<f64> {
    match &force.kind {
        ForceKind::SpringDamper { markers, damping, .. } => {
            local.generalized.iter_mut().for_each(|x| *x = 0.0);
            let item = format!("force '{}'", force.name);
            let pair = env.pair(markers);
            spring_damper::evaluate(&item, &pair, env.time, [0.0, *damping, 0.0, 0.0], local, false)?;
        }
        ForceKind::RotationalSpringDamper { markers, damping, .. } => {
            local.generalized.iter_mut().for_each(|x| *x = 0.0);
            let reference = env.discrete[force.discrete.expect("rotational spring has a discrete state")];
            let pair = env.pair(markers);
            rotational_spring_damper::evaluate(
                &pair,
                env.time,
                reference,
                [0.0, *damping, 0.0, 0.0],
                local,
                false,
            )?;
        }
        _ => evaluate_force(force, env, local, false)?,
    }
    Ok(force.dofs.iter().zip(&local.generalized).map(|(&d, &g)| g * env.qd[d]).sum())
}

/// Potential energy stored in a force element (springs); zero for the others.
pub fn force_potential(force: &ForceElement, env: &ForceEnv) -> f64 {
    match &force.kind {
        ForceKind::SpringDamper { markers, stiffness, rest_length, preload, .. } => {
            let l = env.pair(markers).offset().norm();
            0.5 * stiffness * (l - rest_length).powi(2) + preload * l
        }
        ForceKind::RotationalSpringDamper { markers, stiffness, rest_angle, preload, .. } => {
            let reference = env.discrete[force.discrete.expect("rotational spring has a discrete state")];
            let theta = rotational_spring_damper::unwrapped_angle(&env.pair(markers), reference);
            0.5 * stiffness * (theta - rest_angle).powi(2) + preload * theta
        }
        _ => 0.0,
    }
}
