//! The element interface: every element type gives its stiffness matrix, its mass points and
//! its lumped masses, for nodal coordinates given in the body frame.
//!
//! Element coordinates q_e are node-major: [u_1 (3), (theta_1 (3)), u_2, ...] with 3 coordinates
//! per node for solids and 6 (3 displacements, 3 small rotations) for beams, all in body axes.
//!
//! Mass points are a quadrature of the element volume that integrates exactly every integrand
//! the invariants of motion need (seed eqs. 16-17 and `DESIGN.md`): at each point the weight
//! w = rho dV, the undeformed position u0 and the shape matrix S (3 x n_e, displacement of the
//! point = S q_e). Then, for the element:
//!   m = sum w,  s0 = sum w u0,  J0_kl = sum w u0_k u0_l,  I1 = sum w S,
//!   I_kl = sum w S_k^T S_l,  Ibar_kl = sum w u0_k S_l,  and the consistent mass M = sum w S^T S.
//! Shape functions reproduce rigid translations exactly (seed eq. 4): the rows of S for the
//! translation of every node sum to the identity.

use crate::math::dense::DenseMatrix;
use crate::math::Vec3;

use crate::fem::material::Material;

/// A quadrature point of an element's mass distribution.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MassPoint {
    /// rho dV (kg).
    pub weight: f64,
    /// Undeformed position in the body frame (m).
    pub position: Vec3,
    /// Shape matrix S (3 x n_e, row-major): displacement of the point = S q_e.
    pub shape: Vec<f64>,
}

/// Why an element cannot be evaluated.
#[derive(Clone, Debug, PartialEq)]
pub enum ElementError {
    /// Zero or negative volume (or Jacobian determinant at a quadrature point): a degenerate or
    /// inverted element.
    Degenerate {
        /// What was found (e.g. `Jacobian determinant -0.02 at quadrature point 3`).
        detail: String,
    },
    /// Wrong number of nodes or inconsistent data.
    Invalid {
        /// What is wrong.
        detail: String,
    },
}

impl std::fmt::Display for ElementError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ElementError::Degenerate { detail } => write!(f, "degenerate or inverted element: {detail}"),
            ElementError::Invalid { detail } => write!(f, "{detail}"),
        }
    }
}

/// Result of an element kernel.
pub type ElementResult<T> = std::result::Result<T, ElementError>;

/// The kernels every element type provides (implemented in `beam.rs` and `solid.rs`).
pub trait ElementKernel {
    /// Number of nodes.
    fn node_count(&self) -> usize;
    /// Coordinates per node (3 for solids, 6 for beams).
    fn dofs_per_node(&self) -> usize;
    /// Element stiffness matrix (n_e x n_e, body axes) for node positions `x`.
    fn stiffness(&self, material: &Material, x: &[Vec3], out: &mut DenseMatrix) -> ElementResult<()>;
    /// Mass points of the consistent mass distribution (appended to `out`).
    fn mass_points(&self, material: &Material, x: &[Vec3], out: &mut Vec<MassPoint>) -> ElementResult<()>;
    /// Lumped mass distribution as mass points at (or, for rotational inertia, around) the
    /// nodes (appended to `out`); their total mass is the element mass.
    fn lumped_mass_points(
        &self,
        material: &Material,
        x: &[Vec3],
        out: &mut Vec<MassPoint>,
    ) -> ElementResult<()>;
    /// Volume (m^3).
    fn volume(&self, x: &[Vec3]) -> ElementResult<f64>;
    /// Stresses recovered at the element's nodes from its nodal displacements `u` (element
    /// order, `dofs_per_node` each, body axes), one row of 6 per node into `out`. Solids: the
    /// stress of the displacement field evaluated at the node, in Voigt order
    /// (xx, yy, zz, yz, xz, xy), body axes (Pa). Beams: the section resultants
    /// [N, V_y, V_z, T, M_y, M_z] at the two ends, in element axes (N, N m), acting on the
    /// section face whose outward normal is +x (tension positive).
    fn nodal_stresses(
        &self,
        material: &Material,
        x: &[Vec3],
        u: &[f64],
        out: &mut [[f64; 6]],
    ) -> ElementResult<()>;
}

/// Consistent mass matrix M = sum w S^T S from mass points (n_e x n_e).
pub fn mass_matrix(points: &[MassPoint], n: usize, out: &mut DenseMatrix) {
    *out = DenseMatrix::zeros(n, n);
    for p in points {
        for a in 0..n {
            let (s0, s1, s2) = (p.shape[a], p.shape[n + a], p.shape[2 * n + a]);
            if s0 == 0.0 && s1 == 0.0 && s2 == 0.0 {
                continue;
            }
            for b in 0..n {
                let v = s0 * p.shape[b] + s1 * p.shape[n + b] + s2 * p.shape[2 * n + b];
                out.add(a, b, p.weight * v);
            }
        }
    }
}
