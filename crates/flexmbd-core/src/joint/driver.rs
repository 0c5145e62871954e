//! Driving constraints: a joint coordinate prescribed as a function of time f(t) (specified
//! motion, seed section 3; its multiplier is the driving force or torque of inverse dynamics).
//!
//! - Angle driver: the rotation theta of marker j's x axis relative to marker i's about the z
//!   axis of marker i follows f(t). Written as sin(theta - f) = (y_i . x_j) cos f - (x_i . x_j) sin f
//!   = 0, smooth for any number of turns and regular wherever theta = f (dC/dtheta = 1).
//! - Translation driver: the offset along the z axis of marker i, d . z_i - f(t) = 0.

use crate::joint::equation::{Coefficient, Equation, Offset, Primitive};

/// The angle equation.
pub(crate) fn angle_equations() -> Vec<Equation> {
    vec![Equation {
        label: "angle",
        terms: vec![
            (Coefficient::CosF, Primitive::AxisDotAxis(1, 0)),
            (Coefficient::NegSinF, Primitive::AxisDotAxis(0, 0)),
        ],
        offset: Offset::Zero,
    }]
}

/// The translation equation.
pub(crate) fn translation_equations() -> Vec<Equation> {
    vec![Equation {
        label: "translation",
        terms: vec![(Coefficient::One, Primitive::AxisDotOffset(2))],
        offset: Offset::NegF,
    }]
}
