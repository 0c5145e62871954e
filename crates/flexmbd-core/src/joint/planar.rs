//! Planar joint: the origin of marker j stays in the x-y plane of marker i (d . z_i = 0) and
//! the z axes stay parallel (z_j . x_i = 0, z_j . y_i = 0). Free: two translations in the
//! plane and the rotation about the normal.

use crate::joint::equation::{Equation, Primitive};

/// Three equations.
pub(crate) fn equations() -> Vec<Equation> {
    vec![
        Equation::simple("offset z", Primitive::AxisDotOffset(2)),
        Equation::simple("axis x", Primitive::AxisDotAxis(0, 2)),
        Equation::simple("axis y", Primitive::AxisDotAxis(1, 2)),
    ]
}
