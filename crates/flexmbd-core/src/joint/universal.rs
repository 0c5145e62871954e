//! Universal (Cardan) joint: coincident origins, and the cross axes x_i (fixed on body i) and
//! y_j (fixed on body j) stay perpendicular: x_i . y_j = 0. The shafts are the z axes of the
//! markers; the relative twist about them is locked, the two bending rotations are free.

use crate::joint::equation::{Equation, Primitive};

/// Spherical equations plus x_i . y_j = 0.
pub(crate) fn equations() -> Vec<Equation> {
    let mut eqs = crate::joint::spherical::equations();
    eqs.push(Equation::simple("cross", Primitive::AxisDotAxis(0, 1)));
    eqs
}
