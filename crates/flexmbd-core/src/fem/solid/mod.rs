//! Solid elements: 4-node and 10-node tetrahedra, 8-node hexahedra (also with incompatible
//! modes, [`Hex8Incompatible`]), 20- and 27-node hexahedra, 6-, 15- and 18-node wedges, 5-,
//! 13- and 14-node pyramids.
//!
//! Isoparametric, small-strain, linear elastic. Element coordinates are node-major with the 3
//! displacements of every node in body axes (see `element.rs`), so an element with n nodes has
//! n_e = 3 n coordinates and its shape matrix is S = [N_1 I, N_2 I, ..., N_n I] (3 x n_e).
//!
//! Node orderings (those of Gmsh's `.msh` format):
//! - [`Tet4`]: vertices 0, 1, 2, 3 (reference (0,0,0), (1,0,0), (0,1,0), (0,0,1)), positively
//!   oriented: (x1 - x0) . ((x2 - x0) x (x3 - x0)) > 0. VTK and meshio use the same order.
//! - [`Tet10`]: vertices 0..3 as for `Tet4`, then the mid-edge nodes 4..9 on the edges
//!   (0,1), (1,2), (0,2), (0,3), (2,3), (1,3) ([`TET10_EDGES`]). VTK's quadratic tetrahedron,
//!   and therefore meshio, lists the last two the other way round ((1,3), then (2,3)):
//!   permute a meshio/VTK cell with [`TET10_FROM_VTK_ORDER`] before using it here.
//! - [`Hex8`]: bottom face 0, 1, 2, 3 counter-clockwise seen from +z (from above), top face
//!   4, 5, 6, 7 above them (reference corners (-1,-1,-1), (1,-1,-1), (1,1,-1), (-1,1,-1), then
//!   the same with zeta = +1). VTK and meshio use the same order.
//! - [`Hex20`], [`Hex20Reduced`]: the corners of `Hex8`, then the mid-edge nodes 8..19 on
//!   the bottom face's edges (0,1), (1,2), (2,3), (3,0), the top face's (4,5), (5,6), (6,7),
//!   (7,4) and the vertical ones (0,4), (1,5), (2,6), (3,7) ([`HEX20_EDGES`]): VTK's quadratic
//!   hexahedron, Abaqus C3D20 and meshio (which converts Gmsh's order on reading; not
//!   Gmsh's own order).
//! - [`Hex27`]: the nodes of `Hex20`, then the centres of the faces xi = -1, xi = +1,
//!   eta = -1, eta = +1, zeta = -1, zeta = +1 and the element's centre: VTK's triquadratic
//!   hexahedron and meshio's hexahedron27 (which converts Gmsh's order on reading).
//! - [`Wedge6`]: the triangle 0, 1, 2 counter-clockwise seen from the other one, 3, 4, 5
//!   above them (reference (0,0,-1), (1,0,-1), (0,1,-1), then w = +1): Gmsh's prism, Abaqus
//!   C3D6 and meshio's wedge (VTK's wedge lists each triangle the other way round; meshio
//!   converts).
//! - [`Wedge15`]: the corners of `Wedge6`, then the mid-edge nodes 6..14 on the bottom
//!   triangle's edges (0,1), (1,2), (2,0), the top one's (3,4), (4,5), (5,3) and the vertical
//!   ones (0,3), (1,4), (2,5) ([`WEDGE15_EDGES`]): Abaqus C3D15 and meshio's wedge15 (which
//!   converts Gmsh's order on reading; VTK's quadratic wedge has these edges with its
//!   triangles listed the other way round).
//! - [`Wedge18`]: the nodes of `Wedge15`, then the centres of the quadrilateral faces
//!   (0,1,4,3), (1,2,5,4), (2,0,3,5) ([`WEDGE18_FACES`]): VTK's biquadratic-quadratic wedge
//!   with its triangles listed the other way round (as `Wedge15` has VTK's quadratic
//!   wedge's). Gmsh's 18-node prism, which meshio passes on in Gmsh's order, numbers its edges
//!   otherwise and its faces (0,1,4,3), (0,2,5,3), (1,2,5,4).
//! - [`Pyramid5`]: the base 0, 1, 2, 3 counter-clockwise seen from the apex 4 (reference
//!   (-1,-1,0), (1,-1,0), (1,1,0), (-1,1,0), (0,0,1)): Gmsh's pyramid, VTK's and meshio's.
//! - [`Pyramid13`]: the corners of `Pyramid5`, then the mid-edge nodes 5..12 on the base's
//!   edges (0,1), (1,2), (2,3), (3,0) and on (0,4), (1,4), (2,4), (3,4) ([`PYRAMID13_EDGES`]):
//!   VTK's quadratic pyramid and meshio's pyramid13 (which converts Gmsh's order on reading).
//! - [`Pyramid14`]: the nodes of `Pyramid13`, then the base's centre (Gmsh's 14-node pyramid
//!   has the same nodes in Gmsh's edge order, which meshio keeps).
//!
//! Quadrature: stiffness K = int B^T D B dV with the 1-point rule (`Tet4`, exact), the 4-point
//! degree-2 rule (`Tet10`, exact for straight edges), 2 x 2 x 2 Gauss (`Hex8`, full
//! integration, no hourglass modes; `Hex20Reduced`), 3 x 3 x 3 Gauss (`Hex20`, `Hex27`) and the
//! degree-2 triangle rule times 2-point Gauss (`Wedge6`, exact) and the degree-4 triangle
//! rule times 3-point Gauss (`Wedge15`, `Wedge18`, exact for a constant Jacobian) and 2 x 2 x 2
//! Gauss points of the cube collapsed onto the pyramid (`Pyramid5`, exact for a constant
//! Jacobian), 3 x 3 x 3 of them (`Pyramid13`, `Pyramid14`, exact for a constant Jacobian).
//! Mass points (consistent mass, invariants of motion, volume)
//! use a rule that makes every integrand of `element.rs` exact: the 4-point degree-2 rule for
//! `Tet4`, the 15-point degree-5 rule for `Tet10` (exact for straight edges; an approximation
//! when mid-edge nodes are off the edge midpoints) and 3 x 3 x 3 Gauss for `Hex8` (exact for
//! every trilinear hexahedron: with a non-constant Jacobian determinant the integrands
//! N_a N_b det J and u0_k u0_l det J reach degree 4 per direction, beyond 2 x 2 x 2 Gauss),
//! 4 x 4 x 4 Gauss for `Hex20` and `Hex27` (exact for straight edges: degree 6 per direction), the
//! degree-4 triangle rule times 3-point Gauss for `Wedge6` (exact), the degree-5 triangle
//! rule times 4-point Gauss for `Wedge15` and `Wedge18` (exact for straight edges), the
//! collapsed 2 x 2 x 4 Gauss points for `Pyramid5` (exact) and 3 x 3 x 4 for `Pyramid13` and
//! `Pyramid14` (exact for straight edges).
//! Lumped masses are HRZ (Hinton, Rock, Zienkiewicz, "A note on mass lumping and related
//! processes in the finite element method", Earthquake Eng. Struct. Dyn. 4 (1976) 245-249):
//! the diagonal of the consistent mass matrix scaled so that its sum is the element mass.
//!
//! An element is degenerate or inverted (`ElementError::Degenerate`) when the Jacobian
//! determinant at a quadrature point of the rule in use, or at a node, is not above
//! 1e-12 h^3, with h the diagonal of the bounding box of the nodes.
//!
//! Files: `tetrahedra` and `hexahedron` (nodes, rules and shape functions of each element),
//! `geometry` (the isoparametric map: Jacobian, physical gradients), `validation` (node count,
//! positions, degenerate and inverted elements), `matrices` (stiffness and nodal stresses),
//! `mass` (mass points, HRZ lumped masses, volume), `incompatible` (the hexahedron with
//! incompatible modes, on the shape functions, rules and mass of `Hex8`), `wedge` and
//! `pyramid`.

use crate::fem::element::{ElementKernel, ElementResult, MassPoint};
use crate::fem::material::Material;
use crate::fem::quadrature::QuadraturePoint;
use crate::math::dense::DenseMatrix;
use crate::math::Vec3;

/// The reference coordinates of a quadratic element's `$n` nodes: the corners `$corners`,
/// then the midpoints of the corner pairs `$edges` (a const item's initializer: a `const fn`
/// may not do float arithmetic at the crate's MSRV).
macro_rules! corners_and_midpoints {
    ($corners:expr, $edges:expr, $n:literal) => {{
        let c = $corners;
        let edges = $edges;
        let mut nodes = [[0.0; 3]; $n];
        let mut a = 0;
        while a < c.len() {
            nodes[a] = c[a];
            a += 1;
        }
        let mut e = 0;
        while e < edges.len() {
            let [p, q] = edges[e];
            let mut k = 0;
            while k < 3 {
                nodes[c.len() + e][k] = 0.5 * (c[p][k] + c[q][k]);
                k += 1;
            }
            e += 1;
        }
        nodes
    }};
}

mod geometry;
mod hexahedron;
mod incompatible;
mod mass;
mod matrices;
mod pyramid;
#[cfg(test)]
pub(crate) mod tests;
mod tetrahedra;
mod validation;
mod wedge;

pub use hexahedron::HEX20_EDGES;
pub use incompatible::Hex8Incompatible;
pub use pyramid::PYRAMID13_EDGES;
pub use wedge::{WEDGE15_EDGES, WEDGE18_FACES};

/// Linear 4-node tetrahedron (constant strain).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Tet4;

/// Quadratic 10-node tetrahedron (node order in the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Tet10;

/// Trilinear 8-node hexahedron (node order in the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Hex8;

/// Quadratic 20-node hexahedron (serendipity; node order in the module doc), 3 x 3 x 3 Gauss
/// stiffness.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Hex20;

/// [`Hex20`] with the reduced 2 x 2 x 2 Gauss stiffness (Abaqus' C3D20R): softer, with
/// zero-energy modes in a lone element that a mesh of two or more does not share.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Hex20Reduced;

/// Quadratic 27-node (triquadratic Lagrange) hexahedron (node order in the module doc),
/// 3 x 3 x 3 Gauss stiffness.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Hex27;

/// Linear wedge (triangular prism, node order in the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Wedge6;

/// Quadratic 15-node wedge (serendipity; node order in the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Wedge15;

/// Quadratic 18-node (Lagrange: quadratic triangle times quadratic line) wedge (node order
/// in the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Wedge18;

/// Linear pyramid (node order in the module doc; rational shape functions, see `pyramid`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Pyramid5;

/// Quadratic 13-node pyramid (serendipity, Bedrosian's rational functions; node order in the
/// module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Pyramid13;

/// Quadratic 14-node pyramid: [`Pyramid13`] with a node at the base's centre (node order in
/// the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Pyramid14;

/// Vertices joined by the edge of each mid-edge node 4..9 of a [`Tet10`] (Gmsh order).
pub const TET10_EDGES: [[usize; 2]; 6] = [[0, 1], [1, 2], [0, 2], [0, 3], [2, 3], [1, 3]];

/// Node permutation from the VTK/meshio quadratic tetrahedron to [`Tet10`]:
/// `tet10_nodes[i] = vtk_nodes[TET10_FROM_VTK_ORDER[i]]` (it is its own inverse).
pub const TET10_FROM_VTK_ORDER: [usize; 10] = [0, 1, 2, 3, 4, 5, 6, 7, 9, 8];

/// Shape functions of an isoparametric solid element with `N` nodes.
trait Isoparametric<const N: usize> {
    /// Element name for error messages.
    const NAME: &'static str;
    /// Reference coordinates of the nodes.
    const NODES: [[f64; 3]; N];
    /// Rule of the stiffness matrix.
    const STIFFNESS_RULE: &'static [QuadraturePoint];
    /// Rule of the mass points, the lumped masses and the volume.
    const MASS_RULE: &'static [QuadraturePoint];
    /// Shape functions N_a at reference coordinates `xi`.
    fn shape_functions(xi: [f64; 3]) -> [f64; N];
    /// Reference gradients dN_a / dxi at reference coordinates `xi`.
    fn reference_gradients(xi: [f64; 3]) -> [[f64; 3]; N];
}

// The element kernels delegate to the generic isoparametric routines of `matrices` and `mass`.
macro_rules! solid_element_kernel {
    ($element:ty, $nodes:literal) => {
        impl ElementKernel for $element {
            fn node_count(&self) -> usize {
                $nodes
            }

            fn dofs_per_node(&self) -> usize {
                3
            }

            fn stiffness(&self, material: &Material, x: &[Vec3], out: &mut DenseMatrix) -> ElementResult<()> {
                matrices::stiffness::<$element, $nodes>(material, x, out)
            }

            fn mass_points(
                &self,
                material: &Material,
                x: &[Vec3],
                out: &mut Vec<MassPoint>,
            ) -> ElementResult<()> {
                mass::mass_points::<$element, $nodes>(material, x, out)
            }

            fn lumped_mass_points(
                &self,
                material: &Material,
                x: &[Vec3],
                out: &mut Vec<MassPoint>,
            ) -> ElementResult<()> {
                mass::lumped_mass_points::<$element, $nodes>(material, x, out)
            }

            fn volume(&self, x: &[Vec3]) -> ElementResult<f64> {
                mass::volume::<$element, $nodes>(x)
            }

            fn nodal_stresses(
                &self,
                material: &Material,
                x: &[Vec3],
                u: &[f64],
                out: &mut [[f64; 6]],
            ) -> ElementResult<()> {
                matrices::nodal_stresses::<$element, $nodes>(material, x, u, out)
            }
        }
    };
}

solid_element_kernel!(Tet4, 4);
solid_element_kernel!(Tet10, 10);
solid_element_kernel!(Hex8, 8);
solid_element_kernel!(Hex20, 20);
solid_element_kernel!(Hex20Reduced, 20);
solid_element_kernel!(Wedge6, 6);
solid_element_kernel!(Pyramid5, 5);
solid_element_kernel!(Hex27, 27);
solid_element_kernel!(Wedge15, 15);
solid_element_kernel!(Wedge18, 18);
solid_element_kernel!(Pyramid13, 13);
solid_element_kernel!(Pyramid14, 14);
