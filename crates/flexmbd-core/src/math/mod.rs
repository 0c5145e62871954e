//! Rotations (Euler parameters), 3-vectors, small dense matrices, time functions, and the
//! vector kernels of the solves.

pub mod dense;
pub mod euler;
pub mod hyper_dual;
pub(crate) mod simd;
pub mod small;
pub mod time_function;
pub mod vec3;

pub use vec3::{Mat3, Vec3};
