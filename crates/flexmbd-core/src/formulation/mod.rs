//! The equations of motion in their three forms (seed sections 4 and 5): augmented (seed eq.
//! 26, dense, with the embedding of eq. 30), recursive in joint coordinates (eqs. 31-32, trees
//! of bodies with loops closed by cut joints), and the decoupled joint-elastic accelerations
//! (eqs. 33-41).

pub mod augmented;
pub mod decoupled;
pub mod recursive;
