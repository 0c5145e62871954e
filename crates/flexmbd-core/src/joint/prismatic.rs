//! Prismatic joint along the z axis of marker i (seed eq. 24): a cylindrical joint whose
//! relative rotation about the axis is locked by n_i . n_j = 0 with n_i = x_i, n_j = y_j
//! (vectors perpendicular to the axis on each body).

use crate::joint::equation::{Equation, Primitive};

/// Cylindrical equations plus x_i . y_j = 0.
pub(crate) fn equations() -> Vec<Equation> {
    let mut eqs = crate::joint::cylindrical::equations();
    eqs.push(Equation::simple("twist", Primitive::AxisDotAxis(0, 1)));
    eqs
}
