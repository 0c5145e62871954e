//! Linear algebra: compressed sparse columns, sparse LU and LDL^T of Newton matrices (pattern
//! and symbolic analysis once), dense LU, the symmetric (supernodal and envelope) Cholesky and
//! LDL^T factors of elastic matrices, the partitions of constraint Jacobians (LU, QR, SVD), the
//! vector kernels (the one AVX2 dispatch) and the worker threads of parallel factorizations.

pub mod csc;
pub mod dense;
pub mod envelope;
pub mod parallel;
pub mod partition;
pub(crate) mod simd;
pub mod sparse;
pub mod svd;
pub mod symmetric;

pub use csc::Csc;
pub use symmetric::{CscRef, FactorKind, Ordering, SymmetricFactor};
