//! Joints and driving constraints between two markers (seed section 4, eqs. 19-25).
//!
//! Each joint type is one file giving its scalar equations in terms of the primitives of
//! [`equation`]; evaluation (C, C_q, Hessian, gamma) is shared. The Euler-parameter
//! normalization p.p - 1 = 0 of every rigid body is a constraint too, handled by the assembly.

pub mod cylindrical;
pub mod distance;
pub mod driver;
pub mod equation;
pub mod fixed;
pub mod inline;
pub mod planar;
pub mod prismatic;
pub mod reaction;
pub mod revolute;
pub mod spherical;
pub mod universal;

use crate::error::{FlexmbdError, Result};
use crate::ids::MarkerId;
use crate::math::time_function::TimeFunction;
use equation::Equation;

/// The type of a joint and its parameters.
#[derive(Clone, Debug)]
pub enum JointKind {
    /// Coincident origins.
    Spherical,
    /// Rotation about the common z axis.
    Revolute,
    /// Rotation about and translation along the z axis of marker i.
    Cylindrical,
    /// Translation along the z axis of marker i.
    Prismatic,
    /// No relative motion.
    Fixed,
    /// Cardan joint with cross axes x_i and y_j.
    Universal,
    /// Motion in the x-y plane of marker i.
    Planar,
    /// Origin of marker j on the z axis of marker i.
    Inline,
    /// Constant distance between the origins (m, > 0).
    Distance {
        /// The distance.
        distance: f64,
    },
    /// Prescribed rotation angle about the z axis of marker i (rad).
    AngleDriver(TimeFunction),
    /// Prescribed translation along the z axis of marker i (m).
    TranslationDriver(TimeFunction),
}

impl JointKind {
    /// Name of the type, as in the Python API.
    pub fn type_name(&self) -> &'static str {
        match self {
            JointKind::Spherical => "spherical",
            JointKind::Revolute => "revolute",
            JointKind::Cylindrical => "cylindrical",
            JointKind::Prismatic => "prismatic",
            JointKind::Fixed => "fixed",
            JointKind::Universal => "universal",
            JointKind::Planar => "planar",
            JointKind::Inline => "inline",
            JointKind::Distance { .. } => "distance",
            JointKind::AngleDriver(_) => "angle driver",
            JointKind::TranslationDriver(_) => "translation driver",
        }
    }

    /// The scalar equations of this joint type.
    pub fn equations(&self) -> Vec<Equation> {
        match self {
            JointKind::Spherical => spherical::equations(),
            JointKind::Revolute => revolute::equations(),
            JointKind::Cylindrical => cylindrical::equations(),
            JointKind::Prismatic => prismatic::equations(),
            JointKind::Fixed => fixed::equations(),
            JointKind::Universal => universal::equations(),
            JointKind::Planar => planar::equations(),
            JointKind::Inline => inline::equations(),
            JointKind::Distance { distance } => distance::equations(*distance),
            JointKind::AngleDriver(_) => driver::angle_equations(),
            JointKind::TranslationDriver(_) => driver::translation_equations(),
        }
    }

    /// The driver function, for driving constraints.
    pub fn function(&self) -> Option<&TimeFunction> {
        match self {
            JointKind::AngleDriver(f) | JointKind::TranslationDriver(f) => Some(f),
            _ => None,
        }
    }
}

/// A joint of a compiled model.
#[derive(Clone, Debug)]
pub struct Joint {
    /// User name (or `joint <index>`).
    pub name: String,
    /// Type and parameters.
    pub kind: JointKind,
    /// Markers i and j.
    pub markers: [MarkerId; 2],
    /// Scalar equations, in order.
    pub equations: Vec<Equation>,
    /// Index of the first equation among all constraint rows (into lambda).
    pub row: usize,
    /// Global coordinates of the body of marker i, then of marker j (local column order).
    pub dofs: Vec<usize>,
    /// Number of coordinates of the body of marker i.
    pub n_i: usize,
}

impl Joint {
    /// (f, f', f'') of the driver function at `time`; zeros for joints without one.
    pub fn driver_values(&self, time: f64) -> Result<[f64; 3]> {
        match self.kind.function() {
            None => Ok([0.0; 3]),
            Some(f) => {
                let v = f.evaluate(time).map_err(|message| FlexmbdError::Callback {
                    item: format!("joint '{}'", self.name),
                    time,
                    message,
                })?;
                if v.iter().all(|x| x.is_finite()) {
                    Ok(v)
                } else {
                    Err(FlexmbdError::NonFinite {
                        item: format!("driver function of joint '{}'", self.name),
                        time,
                    })
                }
            }
        }
    }
}
