//! Fixed joint: coincident origins and aligned frames. The three orientation equations
//! z_j . x_i = 0, z_j . y_i = 0, y_j . x_i = 0 are regular near the aligned configuration the
//! joint maintains.

use crate::joint::equation::{Equation, Primitive};

/// Six equations.
pub(crate) fn equations() -> Vec<Equation> {
    let mut eqs = crate::joint::revolute::equations();
    eqs.push(Equation::simple("twist", Primitive::AxisDotAxis(0, 1)));
    eqs
}
