//! The solvers of the Newton systems that the integrator owns: the condensed solver, which
//! eliminates the elastic coordinates of large deformable bodies through their constant
//! factorized iteration matrices (the sparse LU of the whole matrix is in [`crate::linalg`]).

pub mod condensed;
