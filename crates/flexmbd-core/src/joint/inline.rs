//! In-line joint primitive: the origin of marker j stays on the z axis of marker i
//! (d . x_i = 0, d . y_i = 0); every rotation and the translation along the axis are free.
//! It closes planar loops in 3D without redundant equations (a planar four-bar needs only
//! the two in-plane position equations at its last pivot).

use crate::joint::equation::{Equation, Primitive};

/// Two equations.
pub(crate) fn equations() -> Vec<Equation> {
    vec![
        Equation::simple("offset x", Primitive::AxisDotOffset(0)),
        Equation::simple("offset y", Primitive::AxisDotOffset(1)),
    ]
}
