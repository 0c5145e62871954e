//! Rotations (Euler parameters), 3-vectors, small dense matrices, time functions.

pub mod dense;
pub mod euler;
pub mod hyper_dual;
pub mod small;
pub mod time_function;
pub mod vec3;

pub use vec3::{Mat3, Vec3};
