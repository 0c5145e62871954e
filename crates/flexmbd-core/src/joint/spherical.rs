//! Spherical joint (seed eq. 21): the origins of the two markers coincide,
//! R_i + A_i u_i - R_j - A_j u_j = 0, written as its three global components. Three relative
//! rotations are free.

use crate::joint::equation::{Equation, Primitive};
use crate::math::Vec3;

/// The three equations x, y, z of d = r_j - r_i = 0.
pub(crate) fn equations() -> Vec<Equation> {
    vec![
        Equation::simple("x", Primitive::PositionComponent(Vec3::unit(0))),
        Equation::simple("y", Primitive::PositionComponent(Vec3::unit(1))),
        Equation::simple("z", Primitive::PositionComponent(Vec3::unit(2))),
    ]
}
