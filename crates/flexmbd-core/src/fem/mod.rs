//! Finite elements for the preprocessor (seed sections 2-3): materials, beam sections, element
//! kernels (stiffness, mass points, lumped masses), assembly of K_ff and M_ff through the
//! connectivity (the Boolean matrices of seed eq. 9), and the invariants of motion
//! (seed eqs. 16-17).

pub mod assembly;
pub mod beam;
pub mod element;
pub mod material;
pub mod quadrature;
pub mod section;
pub mod shell;
pub mod solid;

pub use assembly::{AssembledBody, Element, ElementType, Ikl, Mesh, NodalInvariants};
pub use beam::Beam;
pub use element::{ElementError, ElementKernel, ElementResult, MassPoint};
pub use material::Material;
pub use section::{Section, ShellSection};
pub use shell::{membrane_stiffening, ShellKernel, ShellQuad4, ShellTri3};
pub use solid::{
    Hex20, Hex20Reduced, Hex27, Hex8, Hex8Incompatible, Pyramid13, Pyramid14, Pyramid5, Tet10, Tet4, Wedge15,
    Wedge18, Wedge6,
};
