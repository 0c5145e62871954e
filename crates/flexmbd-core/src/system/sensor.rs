//! Sensors: quantities recorded at every output time in addition to the coordinates,
//! multipliers, reactions and energies that every result holds.

use crate::ids::MarkerId;

/// A kinematic quantity of a marker, in global axes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SensorQuantity {
    /// Position of the origin (m), 3 values.
    Position,
    /// Velocity of the origin (m/s), 3 values.
    Velocity,
    /// Acceleration of the origin (m/s^2), 3 values.
    Acceleration,
    /// Rotation matrix of the marker axes, 9 values row-major.
    Orientation,
    /// Angular velocity (rad/s), 3 values.
    AngularVelocity,
    /// Angular acceleration (rad/s^2), 3 values.
    AngularAcceleration,
    /// The effort of the joint actuator that is force element `force` (added with it, on its
    /// second marker): a torque (N m) if `torque`, else a force (N), 1 value.
    Effort {
        /// Index of the force element.
        force: usize,
        /// Whether the effort is a torque (the actuator drives an angle).
        torque: bool,
    },
}

impl SensorQuantity {
    /// Number of values recorded per output time.
    pub fn size(self) -> usize {
        match self {
            SensorQuantity::Orientation => 9,
            SensorQuantity::Effort { .. } => 1,
            _ => 3,
        }
    }

    /// Name as in the Python API.
    pub fn name(self) -> &'static str {
        match self {
            SensorQuantity::Position => "position",
            SensorQuantity::Velocity => "velocity",
            SensorQuantity::Acceleration => "acceleration",
            SensorQuantity::Orientation => "orientation",
            SensorQuantity::AngularVelocity => "angular_velocity",
            SensorQuantity::AngularAcceleration => "angular_acceleration",
            SensorQuantity::Effort { torque: true, .. } => "actuator torque (N m)",
            SensorQuantity::Effort { torque: false, .. } => "actuator force (N)",
        }
    }

    /// Parses the Python name (of the marker quantities; actuator efforts come with their
    /// actuators).
    pub fn from_name(name: &str) -> Option<Self> {
        [
            SensorQuantity::Position,
            SensorQuantity::Velocity,
            SensorQuantity::Acceleration,
            SensorQuantity::Orientation,
            SensorQuantity::AngularVelocity,
            SensorQuantity::AngularAcceleration,
        ]
        .into_iter()
        .find(|q| q.name() == name)
    }
}

/// A sensor of a compiled model.
#[derive(Clone, Debug)]
pub struct Sensor {
    /// User name (or `sensor <index>`).
    pub name: String,
    /// The marker observed.
    pub marker: MarkerId,
    /// The quantity.
    pub quantity: SensorQuantity,
}
