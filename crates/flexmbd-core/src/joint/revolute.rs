//! Revolute joint about the common z axis of the two markers (seed eq. 23): coincident origins
//! (spherical joint) and parallel z axes. The cross product h_i x h_j = 0 is replaced by the
//! two dot products z_j . x_i = 0 and z_j . y_i = 0, which are independent in every
//! configuration (no singular configurations, no selection of components needed).

use crate::joint::equation::{Equation, Primitive};

/// Spherical equations plus the two axis-alignment equations.
pub(crate) fn equations() -> Vec<Equation> {
    let mut eqs = crate::joint::spherical::equations();
    eqs.push(Equation::simple("axis x", Primitive::AxisDotAxis(0, 2)));
    eqs.push(Equation::simple("axis y", Primitive::AxisDotAxis(1, 2)));
    eqs
}
