//! Bodies: ground, rigid bodies (seed eq. 15 with no elastic coordinates), point masses and
//! deformable bodies in the floating frame of reference (seed eq. 15), and the kinematics of
//! markers (frames on bodies).
//!
//! Each body owns a contiguous range of the system coordinates: a rigid body has
//! [R (3), p (4 Euler parameters)], a deformable body [R, p, q_f (n_f elastic coordinates)], a
//! point mass [R (3)], the ground none.

pub mod corotational;
pub mod element_map;
pub mod flexible;
pub mod marker;
pub mod point_mass;
pub mod rigid;
pub mod stiffening;

pub use flexible::FlexibleBody;
pub use rigid::RigidBody;

/// The kind of a body and its constant data.
#[derive(Clone, Debug, PartialEq)]
pub enum BodyKind {
    /// The fixed inertial frame; no coordinates.
    Ground,
    /// Rigid body with Euler parameters.
    Rigid(RigidBody),
    /// A particle: translation only, no orientation.
    PointMass {
        /// Mass (kg).
        mass: f64,
    },
    /// Deformable body in the floating frame of reference.
    Flexible(Box<FlexibleBody>),
}

impl BodyKind {
    /// Number of generalized coordinates.
    pub fn coordinate_count(&self) -> usize {
        match self {
            BodyKind::Ground => 0,
            BodyKind::Rigid(_) => rigid::RIGID_COORDINATES,
            BodyKind::PointMass { .. } => 3,
            BodyKind::Flexible(f) => f.coordinate_count(),
        }
    }

    /// True if the body has Euler parameters (and hence a normalization constraint).
    pub fn has_euler_parameters(&self) -> bool {
        matches!(self, BodyKind::Rigid(_) | BodyKind::Flexible(_))
    }

    /// Mass and centre of mass (body frame) for gravity and energy.
    pub fn mass_and_center(&self) -> Option<(f64, crate::math::Vec3)> {
        match self {
            BodyKind::Ground => None,
            BodyKind::Rigid(b) => Some((b.mass, b.center_of_mass)),
            BodyKind::PointMass { mass } => Some((*mass, crate::math::Vec3::ZERO)),
            BodyKind::Flexible(f) => Some((f.mass, f.first_moment * (1.0 / f.mass))),
        }
    }
}

/// A body of a compiled model.
#[derive(Clone, Debug)]
pub struct Body {
    /// User name (or `body <index>`).
    pub name: String,
    /// Kind and constant data.
    pub kind: BodyKind,
    /// First global coordinate index.
    pub offset: usize,
    /// Global coordinate indices of this body (empty for the ground).
    pub dofs: Vec<usize>,
}

/// Deformable bodies with at least this many elastic coordinates are condensed.
pub const CONDENSATION_THRESHOLD: usize = 300;

/// Whether a body is condensed: as its `condense` option says, else when it has at least
/// [`CONDENSATION_THRESHOLD`] elastic coordinates.
pub fn is_condensed(kind: &BodyKind) -> bool {
    match kind {
        BodyKind::Flexible(f) => {
            f.elastic_count > 0 && f.condense.unwrap_or(f.elastic_count >= CONDENSATION_THRESHOLD)
        }
        _ => false,
    }
}
