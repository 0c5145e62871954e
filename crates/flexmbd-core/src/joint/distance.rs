//! Distance constraint: |r_j - r_i| - L = 0 (a massless rigid link with spherical ends).
//! Written with the norm, not its square, so that the multiplier is the force in the link (N).
//! Requires L > 0: at L = 0 the gradient of the norm is undefined.

use crate::joint::equation::{Equation, Offset, Primitive};

/// One equation.
pub(crate) fn equations(distance: f64) -> Vec<Equation> {
    vec![Equation {
        label: "distance",
        terms: vec![(crate::joint::equation::Coefficient::One, Primitive::Distance)],
        offset: Offset::Constant(-distance),
    }]
}
