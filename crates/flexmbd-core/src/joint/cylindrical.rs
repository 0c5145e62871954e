//! Cylindrical joint along the z axis of marker i (seed eq. 22): the axes are parallel
//! (z_j . x_i = 0, z_j . y_i = 0) and the origin of marker j stays on the axis of marker i
//! (d . x_i = 0, d . y_i = 0 with d = r_j - r_i). The dot-product form replaces the cross
//! products h_i x h_j and h_i x s_ij and stays regular even when d = 0.

use crate::joint::equation::{Equation, Primitive};

/// Four equations: two for the offset, two for the axis.
pub(crate) fn equations() -> Vec<Equation> {
    vec![
        Equation::simple("offset x", Primitive::AxisDotOffset(0)),
        Equation::simple("offset y", Primitive::AxisDotOffset(1)),
        Equation::simple("axis x", Primitive::AxisDotAxis(0, 2)),
        Equation::simple("axis y", Primitive::AxisDotAxis(1, 2)),
    ]
}
