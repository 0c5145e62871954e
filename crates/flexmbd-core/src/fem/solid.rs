//! Solid elements: 4-node and 10-node tetrahedra, 8-node hexahedra.
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
//!
//! Quadrature: stiffness K = int B^T D B dV with the 1-point rule (`Tet4`, exact), the 4-point
//! degree-2 rule (`Tet10`, exact for straight edges) and 2 x 2 x 2 Gauss (`Hex8`, full
//! integration, no hourglass modes). Mass points (consistent mass, invariants of motion, volume)
//! use a rule that makes every integrand of `element.rs` exact: the 4-point degree-2 rule for
//! `Tet4`, the 15-point degree-5 rule for `Tet10` (exact for straight edges; an approximation
//! when mid-edge nodes are off the edge midpoints) and 3 x 3 x 3 Gauss for `Hex8` (exact for
//! every trilinear hexahedron: with a non-constant Jacobian determinant the integrands
//! N_a N_b det J and u0_k u0_l det J reach degree 4 per direction, beyond 2 x 2 x 2 Gauss).
//! Lumped masses are HRZ (Hinton, Rock, Zienkiewicz, "A note on mass lumping and related
//! processes in the finite element method", Earthquake Eng. Struct. Dyn. 4 (1976) 245-249):
//! the diagonal of the consistent mass matrix scaled so that its sum is the element mass.
//!
//! An element is degenerate or inverted (`ElementError::Degenerate`) when the Jacobian
//! determinant at a quadrature point of the rule in use, or at a node, is not above
//! 1e-12 h^3, with h the diagonal of the bounding box of the nodes.

use crate::fem::element::{ElementError, ElementKernel, ElementResult, MassPoint};
use crate::fem::material::Material;
use crate::fem::quadrature::{
    QuadraturePoint, HEXAHEDRON_GAUSS_2, HEXAHEDRON_GAUSS_3, TETRAHEDRON_DEGREE_1, TETRAHEDRON_DEGREE_2,
    TETRAHEDRON_DEGREE_5,
};
use crate::math::dense::DenseMatrix;
use crate::math::Vec3;

/// Linear 4-node tetrahedron (constant strain).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Tet4;

/// Quadratic 10-node tetrahedron (node order in the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Tet10;

/// Trilinear 8-node hexahedron (node order in the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Hex8;

/// Vertices joined by the edge of each mid-edge node 4..9 of a [`Tet10`] (Gmsh order).
pub const TET10_EDGES: [[usize; 2]; 6] = [[0, 1], [1, 2], [0, 2], [0, 3], [2, 3], [1, 3]];

/// Node permutation from the VTK/meshio quadratic tetrahedron to [`Tet10`]:
/// `tet10_nodes[i] = vtk_nodes[TET10_FROM_VTK_ORDER[i]]` (it is its own inverse).
pub const TET10_FROM_VTK_ORDER: [usize; 10] = [0, 1, 2, 3, 4, 5, 6, 7, 9, 8];

/// Relative threshold on the Jacobian determinant, in units of h^3 (h: bounding-box diagonal).
const DEGENERATE_TOLERANCE: f64 = 1e-12;

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

// Barycentric coordinates of the reference tetrahedron and their constant gradients.
fn barycentric(xi: [f64; 3]) -> [f64; 4] {
    [1.0 - xi[0] - xi[1] - xi[2], xi[0], xi[1], xi[2]]
}

const BARYCENTRIC_GRADIENTS: [[f64; 3]; 4] =
    [[-1.0, -1.0, -1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

impl Isoparametric<4> for Tet4 {
    const NAME: &'static str = "Tet4";
    const NODES: [[f64; 3]; 4] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    const STIFFNESS_RULE: &'static [QuadraturePoint] = &TETRAHEDRON_DEGREE_1;
    const MASS_RULE: &'static [QuadraturePoint] = &TETRAHEDRON_DEGREE_2;

    fn shape_functions(xi: [f64; 3]) -> [f64; 4] {
        barycentric(xi)
    }

    fn reference_gradients(_xi: [f64; 3]) -> [[f64; 3]; 4] {
        BARYCENTRIC_GRADIENTS
    }
}

impl Isoparametric<10> for Tet10 {
    const NAME: &'static str = "Tet10";
    const NODES: [[f64; 3]; 10] = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.5, 0.0, 0.0],
        [0.5, 0.5, 0.0],
        [0.0, 0.5, 0.0],
        [0.0, 0.0, 0.5],
        [0.0, 0.5, 0.5],
        [0.5, 0.0, 0.5],
    ];
    const STIFFNESS_RULE: &'static [QuadraturePoint] = &TETRAHEDRON_DEGREE_2;
    const MASS_RULE: &'static [QuadraturePoint] = &TETRAHEDRON_DEGREE_5;

    fn shape_functions(xi: [f64; 3]) -> [f64; 10] {
        let l = barycentric(xi);
        let mut n = [0.0; 10];
        // Vertices: lambda (2 lambda - 1); mid-edge nodes: 4 lambda_p lambda_q.
        for a in 0..4 {
            n[a] = l[a] * (2.0 * l[a] - 1.0);
        }
        for (e, [p, q]) in TET10_EDGES.iter().enumerate() {
            n[4 + e] = 4.0 * l[*p] * l[*q];
        }
        n
    }

    fn reference_gradients(xi: [f64; 3]) -> [[f64; 3]; 10] {
        let l = barycentric(xi);
        let dl = BARYCENTRIC_GRADIENTS;
        let mut g = [[0.0; 3]; 10];
        for a in 0..4 {
            for j in 0..3 {
                g[a][j] = (4.0 * l[a] - 1.0) * dl[a][j];
            }
        }
        for (e, [p, q]) in TET10_EDGES.iter().enumerate() {
            for j in 0..3 {
                g[4 + e][j] = 4.0 * (l[*q] * dl[*p][j] + l[*p] * dl[*q][j]);
            }
        }
        g
    }
}

impl Isoparametric<8> for Hex8 {
    const NAME: &'static str = "Hex8";
    const NODES: [[f64; 3]; 8] = [
        [-1.0, -1.0, -1.0],
        [1.0, -1.0, -1.0],
        [1.0, 1.0, -1.0],
        [-1.0, 1.0, -1.0],
        [-1.0, -1.0, 1.0],
        [1.0, -1.0, 1.0],
        [1.0, 1.0, 1.0],
        [-1.0, 1.0, 1.0],
    ];
    const STIFFNESS_RULE: &'static [QuadraturePoint] = &HEXAHEDRON_GAUSS_2;
    const MASS_RULE: &'static [QuadraturePoint] = &HEXAHEDRON_GAUSS_3;

    fn shape_functions(xi: [f64; 3]) -> [f64; 8] {
        let mut n = [0.0; 8];
        // N_a = (1 + xi xi_a)(1 + eta eta_a)(1 + zeta zeta_a) / 8.
        for (a, s) in Self::NODES.iter().enumerate() {
            n[a] = 0.125 * (1.0 + xi[0] * s[0]) * (1.0 + xi[1] * s[1]) * (1.0 + xi[2] * s[2]);
        }
        n
    }

    fn reference_gradients(xi: [f64; 3]) -> [[f64; 3]; 8] {
        let mut g = [[0.0; 3]; 8];
        for (a, s) in Self::NODES.iter().enumerate() {
            let f = [1.0 + xi[0] * s[0], 1.0 + xi[1] * s[1], 1.0 + xi[2] * s[2]];
            g[a] = [0.125 * s[0] * f[1] * f[2], 0.125 * s[1] * f[0] * f[2], 0.125 * s[2] * f[0] * f[1]];
        }
        g
    }
}

/// Jacobian J_ij = dx_i / dxi_j = sum_a x_a,i dN_a/dxi_j (3 x 3, row-major).
fn jacobian<const N: usize>(x: &[Vec3], reference: &[[f64; 3]; N]) -> [[f64; 3]; 3] {
    let mut j = [[0.0; 3]; 3];
    for (xa, ga) in x.iter().zip(reference) {
        for r in 0..3 {
            for c in 0..3 {
                j[r][c] += xa[r] * ga[c];
            }
        }
    }
    j
}

/// Cofactor matrix C of a 3 x 3 matrix (C = det(J) J^-T) and the determinant.
fn cofactor_and_determinant(j: &[[f64; 3]; 3]) -> ([[f64; 3]; 3], f64) {
    let rows = [Vec3(j[0]), Vec3(j[1]), Vec3(j[2])];
    // Row i of C is the cross product of the two other rows of J, in cyclic order.
    let c = [rows[1].cross(&rows[2]).0, rows[2].cross(&rows[0]).0, rows[0].cross(&rows[1]).0];
    let determinant = rows[0].dot(&Vec3(c[0]));
    (c, determinant)
}

/// Jacobian determinant at reference coordinates `xi`.
fn jacobian_determinant<E: Isoparametric<N>, const N: usize>(x: &[Vec3], xi: [f64; 3]) -> f64 {
    cofactor_and_determinant(&jacobian(x, &E::reference_gradients(xi))).1
}

/// Physical gradients dN_a/dx = J^-T dN_a/dxi and the Jacobian determinant at `xi`.
fn physical_gradients<E: Isoparametric<N>, const N: usize>(x: &[Vec3], xi: [f64; 3]) -> ([[f64; 3]; N], f64) {
    let reference = E::reference_gradients(xi);
    let (c, determinant) = cofactor_and_determinant(&jacobian(x, &reference));
    let mut g = [[0.0; 3]; N];
    for (ga, ra) in g.iter_mut().zip(&reference) {
        for i in 0..3 {
            ga[i] = (c[i][0] * ra[0] + c[i][1] * ra[1] + c[i][2] * ra[2]) / determinant;
        }
    }
    (g, determinant)
}

/// Checks the node count and coordinates, then the Jacobian determinant at every point of
/// `rule` and at every node; returns nothing or the first failure.
fn validate<E: Isoparametric<N>, const N: usize>(x: &[Vec3], rule: &[QuadraturePoint]) -> ElementResult<()> {
    if x.len() != N {
        return Err(ElementError::Invalid {
            detail: format!("a {} element needs {N} node positions, got {}", E::NAME, x.len()),
        });
    }
    if let Some(a) = x.iter().position(|p| !p.is_finite()) {
        return Err(ElementError::Invalid {
            detail: format!("node {a} of a {} element has a non-finite position {:?}", E::NAME, x[a].0),
        });
    }
    // Characteristic length: diagonal of the bounding box of the nodes.
    let (mut low, mut high) = (x[0], x[0]);
    for p in &x[1..] {
        for k in 0..3 {
            low[k] = low[k].min(p[k]);
            high[k] = high[k].max(p[k]);
        }
    }
    let length = (high - low).norm();
    let threshold = DEGENERATE_TOLERANCE * length * length * length;
    let degenerate = |determinant: f64, location: String| ElementError::Degenerate {
        detail: format!(
            "Jacobian determinant {determinant:.6e} at {location} of a {} element (must exceed \
             {threshold:.3e} = {DEGENERATE_TOLERANCE:e} h^3, h = {length:.6e} the bounding-box diagonal)",
            E::NAME
        ),
    };
    // Quadrature points of the rule in use, then the nodes.
    for (q, point) in rule.iter().enumerate() {
        let determinant = jacobian_determinant::<E, N>(x, point.coordinates);
        if !(determinant > threshold) {
            let location = format!("quadrature point {q} (reference coordinates {:?})", point.coordinates);
            return Err(degenerate(determinant, location));
        }
    }
    for (a, node) in E::NODES.iter().enumerate() {
        let determinant = jacobian_determinant::<E, N>(x, *node);
        if !(determinant > threshold) {
            return Err(degenerate(determinant, format!("node {a}")));
        }
    }
    Ok(())
}

/// Strain-displacement block B_a (6 x 3) of a node with physical gradient `g`: engineering
/// strains in Voigt order (xx, yy, zz, yz, xz, xy) per unit displacement of the node.
fn strain_displacement(g: [f64; 3]) -> [[f64; 3]; 6] {
    let [gx, gy, gz] = g;
    [[gx, 0.0, 0.0], [0.0, gy, 0.0], [0.0, 0.0, gz], [0.0, gz, gy], [gz, 0.0, gx], [gy, gx, 0.0]]
}

/// K = int B^T D B dV (3N x 3N) with the stiffness rule.
fn stiffness<E: Isoparametric<N>, const N: usize>(
    material: &Material,
    x: &[Vec3],
    out: &mut DenseMatrix,
) -> ElementResult<()> {
    validate::<E, N>(x, E::STIFFNESS_RULE)?;
    let n = 3 * N;
    if out.rows == n && out.cols == n && out.data.len() == n * n {
        out.fill_zero();
    } else {
        *out = DenseMatrix::zeros(n, n);
    }
    let d = material.elasticity();
    let mut b = [[[0.0; 3]; 6]; N];
    let mut db = [[[0.0; 3]; 6]; N];
    for point in E::STIFFNESS_RULE {
        let (g, determinant) = physical_gradients::<E, N>(x, point.coordinates);
        let dv = point.weight * determinant;
        // B_a and D B_a for every node.
        for a in 0..N {
            b[a] = strain_displacement(g[a]);
            for r in 0..6 {
                for j in 0..3 {
                    db[a][r][j] = (0..6).map(|s| d[r][s] * b[a][s][j]).sum();
                }
            }
        }
        // Upper triangle of B^T D B dV.
        for row in 0..n {
            let (a, i) = (row / 3, row % 3);
            for col in row..n {
                let (c, j) = (col / 3, col % 3);
                let v: f64 = (0..6).map(|r| b[a][r][i] * db[c][r][j]).sum();
                out.add(row, col, dv * v);
            }
        }
    }
    // Mirror the upper triangle: K is symmetric to the last bit.
    for row in 1..n {
        for col in 0..row {
            out.data[row * n + col] = out.data[col * n + row];
        }
    }
    Ok(())
}

/// Mass points of the mass rule: weight rho w det J, position sum N_a x_a, S = [N_a I].
fn mass_points<E: Isoparametric<N>, const N: usize>(
    material: &Material,
    x: &[Vec3],
    out: &mut Vec<MassPoint>,
) -> ElementResult<()> {
    validate::<E, N>(x, E::MASS_RULE)?;
    let n = 3 * N;
    out.reserve(E::MASS_RULE.len());
    for point in E::MASS_RULE {
        let shape = E::shape_functions(point.coordinates);
        let determinant = jacobian_determinant::<E, N>(x, point.coordinates);
        let mut position = Vec3::ZERO;
        let mut s = vec![0.0; 3 * n];
        for (a, (na, xa)) in shape.iter().zip(x).enumerate() {
            position += *na * *xa;
            for r in 0..3 {
                s[r * n + 3 * a + r] = *na;
            }
        }
        out.push(MassPoint { weight: material.density * point.weight * determinant, position, shape: s });
    }
    Ok(())
}

/// HRZ lumped masses at the nodes: m_a = m M_aa / sum_b M_bb with M_aa = int rho N_a^2 dV.
fn lumped_mass_points<E: Isoparametric<N>, const N: usize>(
    material: &Material,
    x: &[Vec3],
    out: &mut Vec<MassPoint>,
) -> ElementResult<()> {
    validate::<E, N>(x, E::MASS_RULE)?;
    let n = 3 * N;
    // Element mass and the diagonal of the consistent mass matrix.
    let mut mass = 0.0;
    let mut diagonal = [0.0; N];
    for point in E::MASS_RULE {
        let shape = E::shape_functions(point.coordinates);
        let dm = material.density * point.weight * jacobian_determinant::<E, N>(x, point.coordinates);
        mass += dm;
        for (da, na) in diagonal.iter_mut().zip(&shape) {
            *da += dm * na * na;
        }
    }
    let diagonal_sum: f64 = diagonal.iter().sum();
    // One point per node, its shape matrix selecting the node's displacement.
    out.reserve(N);
    for (a, (da, xa)) in diagonal.iter().zip(x).enumerate() {
        let mut s = vec![0.0; 3 * n];
        for r in 0..3 {
            s[r * n + 3 * a + r] = 1.0;
        }
        out.push(MassPoint { weight: mass * da / diagonal_sum, position: *xa, shape: s });
    }
    Ok(())
}

/// Volume int dV with the mass rule.
fn volume<E: Isoparametric<N>, const N: usize>(x: &[Vec3]) -> ElementResult<f64> {
    validate::<E, N>(x, E::MASS_RULE)?;
    Ok(E::MASS_RULE.iter().map(|p| p.weight * jacobian_determinant::<E, N>(x, p.coordinates)).sum())
}

/// Stress D B(xi_a) u at every node a of the element (Voigt order, body axes).
fn nodal_stresses<E: Isoparametric<N>, const N: usize>(
    material: &Material,
    x: &[Vec3],
    u: &[f64],
    out: &mut [[f64; 6]],
) -> ElementResult<()> {
    validate::<E, N>(x, E::STIFFNESS_RULE)?;
    let d = material.elasticity();
    for (a, xi) in E::NODES.iter().enumerate() {
        let (g, _) = physical_gradients::<E, N>(x, *xi);
        let mut strain = [0.0; 6];
        for (b, gb) in g.iter().enumerate() {
            let bb = strain_displacement(*gb);
            for r in 0..6 {
                strain[r] += (0..3).map(|j| bb[r][j] * u[3 * b + j]).sum::<f64>();
            }
        }
        for r in 0..6 {
            out[a][r] = (0..6).map(|c| d[r][c] * strain[c]).sum();
        }
    }
    Ok(())
}

// The element kernels delegate to the generic isoparametric routines above.
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
                stiffness::<$element, $nodes>(material, x, out)
            }

            fn mass_points(
                &self,
                material: &Material,
                x: &[Vec3],
                out: &mut Vec<MassPoint>,
            ) -> ElementResult<()> {
                mass_points::<$element, $nodes>(material, x, out)
            }

            fn lumped_mass_points(
                &self,
                material: &Material,
                x: &[Vec3],
                out: &mut Vec<MassPoint>,
            ) -> ElementResult<()> {
                lumped_mass_points::<$element, $nodes>(material, x, out)
            }

            fn volume(&self, x: &[Vec3]) -> ElementResult<f64> {
                volume::<$element, $nodes>(x)
            }

            fn nodal_stresses(
                &self,
                material: &Material,
                x: &[Vec3],
                u: &[f64],
                out: &mut [[f64; 6]],
            ) -> ElementResult<()> {
                nodal_stresses::<$element, $nodes>(material, x, u, out)
            }
        }
    };
}

solid_element_kernel!(Tet4, 4);
solid_element_kernel!(Tet10, 10);
solid_element_kernel!(Hex8, 8);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::element::mass_matrix;
    use crate::fem::quadrature::GAUSS_LEGENDRE_3;
    use crate::math::Mat3;

    const RELATIVE: f64 = 1e-12;

    fn steel() -> Material {
        Material::new("steel", 2.1e11, 0.3, 7850.0).unwrap()
    }

    fn v(x: f64, y: f64, z: f64) -> Vec3 {
        Vec3::new(x, y, z)
    }

    #[derive(Clone, Copy, Debug, PartialEq)]
    enum Kind {
        Tet4,
        Tet10,
        Hex8,
    }

    fn element(kind: Kind) -> &'static dyn ElementKernel {
        match kind {
            Kind::Tet4 => &Tet4,
            Kind::Tet10 => &Tet10,
            Kind::Hex8 => &Hex8,
        }
    }

    /// Volume, first moment int x dV and second moment int x x^T dV of a region.
    #[derive(Clone, Copy, Debug)]
    struct Moments {
        volume: f64,
        first: Vec3,
        second: [[f64; 3]; 3],
    }

    struct Case {
        name: &'static str,
        kind: Kind,
        nodes: Vec<Vec3>,
        /// Exact moments, from formulas independent of the element (None: not known).
        moments: Option<Moments>,
        /// Closed-form int N_a dV / V (consistent-mass row sums) and HRZ fractions m_a / m.
        fractions: Option<(Vec<f64>, Vec<f64>)>,
    }

    fn unit_tet() -> Vec<Vec3> {
        vec![v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0), v(0.0, 0.0, 1.0)]
    }

    fn distorted_tet() -> Vec<Vec3> {
        let offset = v(2.0, -1.0, 0.5);
        [v(0.1, -0.2, 0.05), v(1.3, 0.1, -0.1), v(0.2, 0.9, 0.3), v(-0.1, 0.25, 1.2)]
            .into_iter()
            .map(|p| p + offset)
            .collect()
    }

    /// A straight-sided Tet10: the vertices and the midpoints of the edges.
    fn tet10_from(vertices: &[Vec3]) -> Vec<Vec3> {
        let mut nodes = vertices.to_vec();
        for [p, q] in TET10_EDGES {
            nodes.push(0.5 * (vertices[p] + vertices[q]));
        }
        nodes
    }

    fn curved_tet10() -> Vec<Vec3> {
        let mut nodes = tet10_from(&distorted_tet());
        nodes[4] += v(0.03, -0.02, 0.04);
        nodes[8] += v(-0.02, 0.03, 0.01);
        nodes[9] += v(0.01, 0.02, -0.03);
        nodes
    }

    /// Hexahedron origin + i e1 + j e2 + k e3 over the corners (i, j, k) in Gmsh order.
    fn parallelepiped(origin: Vec3, e1: Vec3, e2: Vec3, e3: Vec3) -> Vec<Vec3> {
        Hex8::NODES
            .iter()
            .map(|s| {
                origin + (0.5 * (s[0] + 1.0)) * e1 + (0.5 * (s[1] + 1.0)) * e2 + (0.5 * (s[2] + 1.0)) * e3
            })
            .collect()
    }

    fn box_hex(origin: Vec3, a: f64, b: f64, c: f64) -> Vec<Vec3> {
        parallelepiped(origin, v(a, 0.0, 0.0), v(0.0, b, 0.0), v(0.0, 0.0, c))
    }

    fn distorted_hex() -> Vec<Vec3> {
        let perturbations = [
            v(0.1, -0.05, 0.08),
            v(-0.12, 0.07, -0.03),
            v(0.15, 0.1, 0.05),
            v(-0.06, -0.11, 0.09),
            v(0.08, 0.12, -0.1),
            v(-0.1, -0.04, 0.13),
            v(0.05, -0.09, -0.07),
            v(-0.14, 0.06, 0.02),
        ];
        box_hex(v(0.5, -0.3, 0.2), 2.0, 1.0, 1.5).into_iter().zip(perturbations).map(|(p, d)| p + d).collect()
    }

    /// Exact moments of a tetrahedron from its vertices: V = triple product / 6,
    /// int x = V centroid, int x x^T = V/20 (sum x_i x_i^T + (sum x_i)(sum x_i)^T).
    fn tetrahedron_moments(x: &[Vec3]) -> Moments {
        let volume = (x[1] - x[0]).dot(&(x[2] - x[0]).cross(&(x[3] - x[0]))) / 6.0;
        let sum = x[0] + x[1] + x[2] + x[3];
        let mut second = [[0.0; 3]; 3];
        for k in 0..3 {
            for l in 0..3 {
                let own: f64 = x[..4].iter().map(|p| p[k] * p[l]).sum();
                second[k][l] = volume / 20.0 * (own + sum[k] * sum[l]);
            }
        }
        Moments { volume, first: (volume / 4.0) * sum, second }
    }

    // Faces of a Hex8, each counter-clockwise seen from outside, and the corners of the
    // bilinear face map at (s, t) = (-1,-1), (1,-1), (1,1), (-1,1).
    const HEX_FACES: [[usize; 4]; 6] =
        [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]];
    const FACE_CORNERS: [[f64; 2]; 4] = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];

    /// Calls `f(face nodes, face shape functions, point, weighted outward area vector)` at the
    /// 3 x 3 Gauss points of every (bilinear) face of a hexahedron.
    fn hex_surface_quadrature(x: &[Vec3], mut f: impl FnMut(&[usize; 4], [f64; 4], Vec3, Vec3)) {
        for face in &HEX_FACES {
            for &(s, ws) in &GAUSS_LEGENDRE_3 {
                for &(t, wt) in &GAUSS_LEGENDRE_3 {
                    let (mut n, mut p, mut ds, mut dt) = ([0.0; 4], Vec3::ZERO, Vec3::ZERO, Vec3::ZERO);
                    for (i, c) in FACE_CORNERS.iter().enumerate() {
                        let xi = x[face[i]];
                        n[i] = 0.25 * (1.0 + s * c[0]) * (1.0 + t * c[1]);
                        p += n[i] * xi;
                        ds += (0.25 * c[0] * (1.0 + t * c[1])) * xi;
                        dt += (0.25 * c[1] * (1.0 + s * c[0])) * xi;
                    }
                    f(face, n, p, (ws * wt) * ds.cross(&dt));
                }
            }
        }
    }

    /// Exact moments of a trilinear hexahedron by the divergence theorem: for a homogeneous
    /// polynomial p of degree k, int p dV = 1/(3 + k) int p (x . n) dA (exact face quadrature).
    fn hexahedron_moments(x: &[Vec3]) -> Moments {
        let mut m = Moments { volume: 0.0, first: Vec3::ZERO, second: [[0.0; 3]; 3] };
        hex_surface_quadrature(x, |_, _, p, da| {
            let flux = p.dot(&da);
            m.volume += flux / 3.0;
            m.first += (flux / 4.0) * p;
            for k in 0..3 {
                for l in 0..3 {
                    m.second[k][l] += flux / 5.0 * p[k] * p[l];
                }
            }
        });
        m
    }

    fn cases() -> Vec<Case> {
        let tet4_fractions = (vec![0.25; 4], vec![0.25; 4]);
        let mut tet10_row_sums = vec![-1.0 / 20.0; 4];
        tet10_row_sums.extend([0.2; 6]);
        let mut tet10_lumped = vec![1.0 / 36.0; 4];
        tet10_lumped.extend([4.0 / 27.0; 6]);
        let tet10_fractions = (tet10_row_sums, tet10_lumped);
        let hex_fractions = (vec![0.125; 8], vec![0.125; 8]);
        let tet = |name, kind, nodes: Vec<Vec3>, fractions| {
            let moments = Some(tetrahedron_moments(&nodes));
            Case { name, kind, nodes, moments, fractions }
        };
        let hex = |name, nodes: Vec<Vec3>, fractions| {
            let moments = Some(hexahedron_moments(&nodes));
            Case { name, kind: Kind::Hex8, nodes, moments, fractions }
        };
        vec![
            tet("unit Tet4", Kind::Tet4, unit_tet(), Some(tet4_fractions.clone())),
            tet("distorted Tet4", Kind::Tet4, distorted_tet(), Some(tet4_fractions)),
            tet("unit Tet10", Kind::Tet10, tet10_from(&unit_tet()), Some(tet10_fractions.clone())),
            tet("distorted Tet10", Kind::Tet10, tet10_from(&distorted_tet()), Some(tet10_fractions)),
            Case {
                name: "curved Tet10",
                kind: Kind::Tet10,
                nodes: curved_tet10(),
                moments: None,
                fractions: None,
            },
            hex("unit cube Hex8", box_hex(Vec3::ZERO, 1.0, 1.0, 1.0), Some(hex_fractions.clone())),
            hex("box Hex8", box_hex(v(0.5, -0.3, 0.2), 2.0, 1.0, 0.5), Some(hex_fractions.clone())),
            hex(
                "parallelepiped Hex8",
                parallelepiped(v(-1.0, 0.5, 2.0), v(1.5, 0.2, 0.1), v(0.3, 1.0, -0.2), v(0.2, 0.3, 0.8)),
                Some(hex_fractions),
            ),
            hex("distorted Hex8", distorted_hex(), None),
        ]
    }

    fn stiffness_of(case: &Case) -> DenseMatrix {
        let mut k = DenseMatrix::default();
        element(case.kind).stiffness(&steel(), &case.nodes, &mut k).unwrap();
        k
    }

    fn mass_points_of(case: &Case) -> Vec<MassPoint> {
        let mut points = Vec::new();
        element(case.kind).mass_points(&steel(), &case.nodes, &mut points).unwrap();
        points
    }

    fn lumped_points_of(case: &Case) -> Vec<MassPoint> {
        let mut points = Vec::new();
        element(case.kind).lumped_mass_points(&steel(), &case.nodes, &mut points).unwrap();
        points
    }

    #[test]
    fn affine_displacements_give_their_exact_stress_at_every_node() {
        // u = E x + t: strain (E + E^T)/2 everywhere, stress D eps at every node, for every
        // element shape (curved and distorted ones included: the fields are in their spaces).
        let e = [[1e-3, 2e-4, -5e-4], [-3e-4, 7e-4, 1e-4], [4e-4, -2e-4, -6e-4]];
        let eps = [e[0][0], e[1][1], e[2][2], e[1][2] + e[2][1], e[0][2] + e[2][0], e[0][1] + e[1][0]];
        let d = steel().elasticity();
        let sigma: Vec<f64> = (0..6).map(|r| (0..6).map(|c| d[r][c] * eps[c]).sum()).collect();
        for case in cases() {
            let u = nodal_field(&case.nodes, |p| {
                Vec3(std::array::from_fn(|i| (0..3).map(|j| e[i][j] * p[j]).sum::<f64>() + 0.01 * i as f64))
            });
            let mut out = vec![[0.0; 6]; case.nodes.len()];
            element(case.kind).nodal_stresses(&steel(), &case.nodes, &u, &mut out).unwrap();
            for node in &out {
                for r in 0..6 {
                    assert!((node[r] - sigma[r]).abs() < 1e-9 * max_abs(&sigma), "{}: {node:?}", case.name);
                }
            }
        }
    }

    fn max_abs(values: &[f64]) -> f64 {
        values.iter().fold(0.0, |m, x| m.max(x.abs()))
    }

    fn times(k: &DenseMatrix, u: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; k.rows];
        k.mul_vec_add(1.0, u, &mut y);
        y
    }

    /// Nodal field u_a = f(x_a), node-major.
    fn nodal_field(x: &[Vec3], f: impl Fn(Vec3) -> Vec3) -> Vec<f64> {
        x.iter().flat_map(|p| f(*p).0).collect()
    }

    /// Displacement S q at a mass point.
    fn displacement(point: &MassPoint, q: &[f64]) -> Vec3 {
        let n = q.len();
        let mut u = Vec3::ZERO;
        for r in 0..3 {
            u[r] = (0..n).map(|c| point.shape[r * n + c] * q[c]).sum();
        }
        u
    }

    /// Eigenvalues of a symmetric matrix by cyclic Jacobi rotations, ascending.
    fn symmetric_eigenvalues(m: &DenseMatrix) -> Vec<f64> {
        let n = m.rows;
        let mut a = m.data.clone();
        for _ in 0..100 {
            let total: f64 = a.iter().map(|x| x * x).sum();
            let off: f64 = (0..n)
                .flat_map(|i| (0..n).filter(move |&j| j != i).map(move |j| (i, j)))
                .map(|(i, j)| a[i * n + j] * a[i * n + j])
                .sum();
            if off <= 1e-32 * total {
                break;
            }
            for p in 0..n {
                for q in p + 1..n {
                    let apq = a[p * n + q];
                    if apq == 0.0 {
                        continue;
                    }
                    // Rotation in the (p, q) plane that zeroes a_pq.
                    let theta = (a[q * n + q] - a[p * n + p]) / (2.0 * apq);
                    let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                    let c = 1.0 / (t * t + 1.0).sqrt();
                    let s = t * c;
                    for k in 0..n {
                        let (akp, akq) = (a[k * n + p], a[k * n + q]);
                        a[k * n + p] = c * akp - s * akq;
                        a[k * n + q] = s * akp + c * akq;
                    }
                    for k in 0..n {
                        let (apk, aqk) = (a[p * n + k], a[q * n + k]);
                        a[p * n + k] = c * apk - s * aqk;
                        a[q * n + k] = s * apk + c * aqk;
                    }
                }
            }
        }
        let mut eigenvalues: Vec<f64> = (0..n).map(|i| a[i * n + i]).collect();
        eigenvalues.sort_by(f64::total_cmp);
        eigenvalues
    }

    /// True if the Cholesky factorization of a symmetric matrix has positive pivots only.
    fn is_positive_definite(m: &DenseMatrix) -> bool {
        let n = m.rows;
        let mut l = vec![0.0; n * n];
        for j in 0..n {
            let pivot = m.get(j, j) - (0..j).map(|k| l[j * n + k] * l[j * n + k]).sum::<f64>();
            if !(pivot > 0.0) {
                return false;
            }
            l[j * n + j] = pivot.sqrt();
            for i in j + 1..n {
                let s = m.get(i, j) - (0..j).map(|k| l[i * n + k] * l[j * n + k]).sum::<f64>();
                l[i * n + j] = s / l[j * n + j];
            }
        }
        true
    }

    #[test]
    fn kernels_report_their_layout() {
        assert_eq!((Tet4.node_count(), Tet4.dofs_per_node()), (4, 3));
        assert_eq!((Tet10.node_count(), Tet10.dofs_per_node()), (10, 3));
        assert_eq!((Hex8.node_count(), Hex8.dofs_per_node()), (8, 3));
    }

    #[test]
    fn shape_functions_interpolate_the_nodes() {
        fn check<E: Isoparametric<N>, const N: usize>() {
            for (a, node) in E::NODES.iter().enumerate() {
                let n = E::shape_functions(*node);
                for (b, nb) in n.iter().enumerate() {
                    let expected = if a == b { 1.0 } else { 0.0 };
                    assert!((nb - expected).abs() < 1e-15, "{} N_{b} at node {a}: {nb}", E::NAME);
                }
            }
            // Reference gradients against central differences of the shape functions.
            let xi = [0.21, 0.17, 0.33];
            let g = E::reference_gradients(xi);
            for j in 0..3 {
                let h = 1e-6;
                let (mut plus, mut minus) = (xi, xi);
                plus[j] += h;
                minus[j] -= h;
                let (np, nm) = (E::shape_functions(plus), E::shape_functions(minus));
                for a in 0..N {
                    let fd = (np[a] - nm[a]) / (2.0 * h);
                    assert!((g[a][j] - fd).abs() < 1e-8, "{} dN_{a}/dxi_{j}: {} vs {fd}", E::NAME, g[a][j]);
                }
            }
        }
        check::<Tet4, 4>();
        check::<Tet10, 10>();
        check::<Hex8, 8>();
    }

    #[test]
    fn tet10_mid_edge_nodes_follow_the_gmsh_edges() {
        for (e, [p, q]) in TET10_EDGES.iter().enumerate() {
            let mid: Vec<f64> = (0..3).map(|j| 0.5 * (Tet10::NODES[*p][j] + Tet10::NODES[*q][j])).collect();
            assert_eq!(mid, Tet10::NODES[4 + e].to_vec());
        }
        // The VTK permutation swaps the nodes on edges (2,3) and (1,3) and is an involution.
        for i in 0..10 {
            assert_eq!(TET10_FROM_VTK_ORDER[TET10_FROM_VTK_ORDER[i]], i);
        }
        assert_eq!(TET10_EDGES[TET10_FROM_VTK_ORDER[8] - 4], [1, 3]);
    }

    #[test]
    fn rigid_translations_are_reproduced() {
        for case in cases() {
            let k = stiffness_of(&case);
            let scale = max_abs(&k.data);
            for direction in 0..3 {
                let t = Vec3::unit(direction);
                let q = nodal_field(&case.nodes, |_| t);
                // Every mass point moves with the translation (seed eq. 4).
                for point in mass_points_of(&case).iter().chain(&lumped_points_of(&case)) {
                    let u = displacement(point, &q);
                    assert!((u - t).norm() < 1e-14, "{}: S t = {:?}", case.name, u);
                }
                // A translation stores no strain energy.
                let force = times(&k, &q);
                assert!(max_abs(&force) < RELATIVE * scale, "{}: K t = {:?}", case.name, force);
            }
        }
    }

    #[test]
    fn stiffness_is_symmetric_with_exactly_six_rigid_body_modes() {
        for case in cases() {
            let k = stiffness_of(&case);
            let n = k.rows;
            assert_eq!(n, 3 * case.nodes.len());
            for i in 0..n {
                for j in 0..n {
                    assert_eq!(k.get(i, j), k.get(j, i), "{}: K not symmetric at ({i}, {j})", case.name);
                }
            }
            // Infinitesimal rotations u = w x X are strain-free.
            let scale = max_abs(&k.data);
            for axis in 0..3 {
                let w = Vec3::unit(axis);
                let q = nodal_field(&case.nodes, |p| w.cross(&p));
                let force = times(&k, &q);
                assert!(
                    max_abs(&force) < RELATIVE * scale * max_abs(&q),
                    "{}: K (w x X) = {force:?}",
                    case.name
                );
            }
            // Six zero eigenvalues, every other one positive.
            let eigenvalues = symmetric_eigenvalues(&k);
            let largest = eigenvalues[n - 1];
            let zero = eigenvalues.iter().filter(|l| l.abs() < 1e-10 * largest).count();
            assert_eq!(zero, 6, "{}: eigenvalues {eigenvalues:?}", case.name);
            assert!(eigenvalues[6] > 1e-6 * largest, "{}: eigenvalues {eigenvalues:?}", case.name);
        }
    }

    /// Physical strains (Voigt, engineering shear) at the stiffness points for nodal
    /// displacements `u`.
    fn strains_at_stiffness_points<E: Isoparametric<N>, const N: usize>(
        x: &[Vec3],
        u: &[f64],
    ) -> Vec<[f64; 6]> {
        E::STIFFNESS_RULE
            .iter()
            .map(|point| {
                let (g, _) = physical_gradients::<E, N>(x, point.coordinates);
                let mut strain = [0.0; 6];
                for a in 0..N {
                    let b = strain_displacement(g[a]);
                    for r in 0..6 {
                        strain[r] += (0..3).map(|j| b[r][j] * u[3 * a + j]).sum::<f64>();
                    }
                }
                strain
            })
            .collect()
    }

    /// int B^T sigma dV with the element's own stiffness rule.
    fn stress_forces_by_quadrature<E: Isoparametric<N>, const N: usize>(
        x: &[Vec3],
        sigma: &[[f64; 3]; 3],
    ) -> Vec<f64> {
        let mut f = vec![0.0; 3 * N];
        for point in E::STIFFNESS_RULE {
            let (g, determinant) = physical_gradients::<E, N>(x, point.coordinates);
            for a in 0..N {
                for i in 0..3 {
                    f[3 * a + i] +=
                        point.weight * determinant * (0..3).map(|j| sigma[i][j] * g[a][j]).sum::<f64>();
                }
            }
        }
        f
    }

    /// Outward area vector of the face of a tetrahedron opposite vertex `a`, and its vertices.
    fn tetrahedron_face(x: &[Vec3], a: usize) -> ([usize; 3], Vec3) {
        let mut f = [0; 3];
        for (slot, i) in (0..4).filter(|&i| i != a).enumerate() {
            f[slot] = i;
        }
        let area = 0.5 * (x[f[1]] - x[f[0]]).cross(&(x[f[2]] - x[f[0]]));
        let outward = if area.dot(&(x[a] - x[f[0]])) > 0.0 { -area } else { area };
        (f, outward)
    }

    /// Nodal forces int B_a^T sigma dV = sigma int grad N_a dV = sigma (surface integral of
    /// N_a n dA) of a constant stress, from the faces alone (None for a curved Tet10).
    fn stress_forces_from_faces(case: &Case, sigma: &[[f64; 3]; 3]) -> Option<Vec<f64>> {
        let x = &case.nodes;
        let mut f = vec![0.0; 3 * x.len()];
        let mut add = |node: usize, area: Vec3| {
            for i in 0..3 {
                f[3 * node + i] += (0..3).map(|j| sigma[i][j] * area[j]).sum::<f64>();
            }
        };
        match case.kind {
            // Linear triangle: int N_a dA = A / 3 on each face through the node.
            Kind::Tet4 => {
                for a in 0..4 {
                    let (face, area) = tetrahedron_face(x, a);
                    face.iter().for_each(|&b| add(b, area * (1.0 / 3.0)));
                }
            }
            // Quadratic triangle: int N dA = 0 at the corners and A / 3 at the mid-edge nodes.
            Kind::Tet10 => {
                case.moments?;
                for a in 0..4 {
                    let (face, area) = tetrahedron_face(x, a);
                    for (p, q) in [(face[0], face[1]), (face[1], face[2]), (face[0], face[2])] {
                        let e =
                            TET10_EDGES.iter().position(|edge| *edge == [p, q] || *edge == [q, p]).unwrap();
                        add(4 + e, area * (1.0 / 3.0));
                    }
                }
            }
            Kind::Hex8 => hex_surface_quadrature(x, |face, n, _, area| {
                for (i, node) in face.iter().enumerate() {
                    add(*node, n[i] * area);
                }
            }),
        }
        Some(f)
    }

    #[test]
    fn patch_test_linear_field_gives_constant_strain_and_stress_forces() {
        let a = [[1.0e-3, 2.0e-4, -3.0e-4], [5.0e-4, -2.0e-4, 1.0e-4], [-1.0e-4, 3.0e-4, 4.0e-4]];
        let shift = v(1.0e-3, -2.0e-3, 5.0e-4);
        let strain = [a[0][0], a[1][1], a[2][2], a[1][2] + a[2][1], a[0][2] + a[2][0], a[0][1] + a[1][0]];
        let d = steel().elasticity();
        let s: Vec<f64> = (0..6).map(|r| (0..6).map(|c| d[r][c] * strain[c]).sum()).collect();
        let sigma = [[s[0], s[5], s[4]], [s[5], s[1], s[3]], [s[4], s[3], s[2]]];
        for case in cases() {
            let x = &case.nodes;
            let u = nodal_field(x, |p| Mat3(a).mul_vec(&p) + shift);
            // The strain is the constant one at every stiffness point.
            let strains = match case.kind {
                Kind::Tet4 => strains_at_stiffness_points::<Tet4, 4>(x, &u),
                Kind::Tet10 => strains_at_stiffness_points::<Tet10, 10>(x, &u),
                Kind::Hex8 => strains_at_stiffness_points::<Hex8, 8>(x, &u),
            };
            for e in &strains {
                for r in 0..6 {
                    assert!(
                        (e[r] - strain[r]).abs() < RELATIVE * max_abs(&strain),
                        "{}: strain {e:?}",
                        case.name
                    );
                }
            }
            // Internal forces K u are the nodal forces of the constant stress.
            let k = stiffness_of(&case);
            let internal = times(&k, &u);
            let expected = stress_forces_from_faces(&case, &sigma).unwrap_or_else(|| match case.kind {
                Kind::Tet4 => stress_forces_by_quadrature::<Tet4, 4>(x, &sigma),
                Kind::Tet10 => stress_forces_by_quadrature::<Tet10, 10>(x, &sigma),
                Kind::Hex8 => stress_forces_by_quadrature::<Hex8, 8>(x, &sigma),
            });
            let scale = max_abs(&k.data) * max_abs(&u);
            for (i, (fi, ei)) in internal.iter().zip(&expected).enumerate() {
                assert!(
                    (fi - ei).abs() < RELATIVE * scale,
                    "{}: coordinate {i}: K u = {fi}, expected {ei}",
                    case.name
                );
            }
        }
    }

    /// Sum of the weights, first and second moments of a set of mass points.
    fn mass_moments(points: &[MassPoint]) -> Moments {
        let mut m = Moments { volume: 0.0, first: Vec3::ZERO, second: [[0.0; 3]; 3] };
        for p in points {
            m.volume += p.weight;
            m.first += p.weight * p.position;
            for k in 0..3 {
                for l in 0..3 {
                    m.second[k][l] += p.weight * p.position[k] * p.position[l];
                }
            }
        }
        m
    }

    fn largest_node_distance(x: &[Vec3]) -> f64 {
        let mut d: f64 = 0.0;
        for p in x {
            for q in x {
                d = d.max((*p - *q).norm());
            }
        }
        d
    }

    #[test]
    fn mass_points_integrate_volume_and_moments_exactly() {
        let rho = steel().density;
        for case in cases() {
            let points = mass_points_of(&case);
            let got = mass_moments(&points);
            let volume = element(case.kind).volume(&case.nodes).unwrap();
            assert!((got.volume - rho * volume).abs() < RELATIVE * rho * volume, "{}", case.name);
            let Some(exact) = case.moments else { continue };
            let (mass, length) =
                (rho * exact.volume, largest_node_distance(&case.nodes) + case.nodes[0].norm());
            assert!((volume - exact.volume).abs() < RELATIVE * exact.volume, "{}: V = {volume}", case.name);
            assert!((got.volume - mass).abs() < RELATIVE * mass, "{}: m = {}", case.name, got.volume);
            let first_error = (got.first - rho * exact.first).norm();
            assert!(first_error < RELATIVE * mass * length, "{}: s0 = {:?}", case.name, got.first);
            for k in 0..3 {
                for l in 0..3 {
                    let error = (got.second[k][l] - rho * exact.second[k][l]).abs();
                    assert!(
                        error < RELATIVE * mass * length * length,
                        "{}: J0[{k}][{l}] = {}",
                        case.name,
                        got.second[k][l]
                    );
                }
            }
        }
    }

    #[test]
    fn analytic_volumes_and_second_moments() {
        let rho = steel().density;
        let check = |kind: Kind, nodes: Vec<Vec3>, volume: f64, centroid: Vec3, second: [[f64; 3]; 3]| {
            let case = Case { name: "analytic", kind, nodes, moments: None, fractions: None };
            let got = mass_moments(&mass_points_of(&case));
            assert!((element(kind).volume(&case.nodes).unwrap() - volume).abs() < RELATIVE * volume);
            assert!(
                (got.volume - rho * volume).abs() < RELATIVE * rho * volume,
                "{kind:?}: m = {}",
                got.volume
            );
            assert!(
                (got.first - (rho * volume) * centroid).norm()
                    < RELATIVE * rho * volume * (1.0 + centroid.norm())
            );
            for k in 0..3 {
                for l in 0..3 {
                    let error = (got.second[k][l] - rho * second[k][l]).abs();
                    assert!(
                        error < RELATIVE * rho * second[k][l].abs(),
                        "{kind:?}: J0[{k}][{l}] = {}",
                        got.second[k][l]
                    );
                }
            }
        };
        // Unit tetrahedron: V = 1/6, int x^2 = 1/60, int x y = 1/120.
        let tet_second = [
            [1.0 / 60.0, 1.0 / 120.0, 1.0 / 120.0],
            [1.0 / 120.0, 1.0 / 60.0, 1.0 / 120.0],
            [1.0 / 120.0, 1.0 / 120.0, 1.0 / 60.0],
        ];
        let quarter = v(0.25, 0.25, 0.25);
        check(Kind::Tet4, unit_tet(), 1.0 / 6.0, quarter, tet_second);
        check(Kind::Tet10, tet10_from(&unit_tet()), 1.0 / 6.0, quarter, tet_second);
        // Unit cube: int x^2 = 1/3, int x y = 1/4.
        let cube_second = [[1.0 / 3.0, 0.25, 0.25], [0.25, 1.0 / 3.0, 0.25], [0.25, 0.25, 1.0 / 3.0]];
        check(Kind::Hex8, box_hex(Vec3::ZERO, 1.0, 1.0, 1.0), 1.0, v(0.5, 0.5, 0.5), cube_second);
        // Box a x b x c at the origin: int x_k^2 = V d_k^2 / 3, int x_k x_l = V d_k d_l / 4.
        let (a, b, c) = (2.0, 1.0, 0.5);
        let sides = [a, b, c];
        let mut box_second = [[0.0; 3]; 3];
        for k in 0..3 {
            for l in 0..3 {
                box_second[k][l] = a * b * c * sides[k] * sides[l] / if k == l { 3.0 } else { 4.0 };
            }
        }
        check(Kind::Hex8, box_hex(Vec3::ZERO, a, b, c), a * b * c, v(a / 2.0, b / 2.0, c / 2.0), box_second);
    }

    #[test]
    fn mass_points_reproduce_the_undeformed_geometry() {
        // Isoparametric elements: u0 = S q0 with q0 the nodal positions.
        for case in cases() {
            let q0: Vec<f64> = case.nodes.iter().flat_map(|p| p.0).collect();
            for point in mass_points_of(&case).iter().chain(&lumped_points_of(&case)) {
                let error = (displacement(point, &q0) - point.position).norm();
                assert!(error < 1e-14 * (1.0 + point.position.norm()), "{}: {:?}", case.name, point.position);
                assert_eq!(point.shape.len(), 3 * 3 * case.nodes.len());
            }
        }
    }

    #[test]
    fn consistent_mass_matrix_is_symmetric_positive_definite_with_the_element_mass() {
        for case in cases() {
            let points = mass_points_of(&case);
            let n = 3 * case.nodes.len();
            let mut m = DenseMatrix::default();
            mass_matrix(&points, n, &mut m);
            let mass: f64 = points.iter().map(|p| p.weight).sum();
            for i in 0..n {
                for j in 0..n {
                    assert_eq!(m.get(i, j), m.get(j, i), "{}: M not symmetric", case.name);
                }
            }
            assert!(is_positive_definite(&m), "{}: M not positive definite", case.name);
            // t_i^T M t_j = m delta_ij for unit translations t_i, t_j.
            for i in 0..3 {
                let ti = nodal_field(&case.nodes, |_| Vec3::unit(i));
                let mt = times(&m, &ti);
                for j in 0..3 {
                    let tj = nodal_field(&case.nodes, |_| Vec3::unit(j));
                    let value: f64 = mt.iter().zip(&tj).map(|(a, b)| a * b).sum();
                    let expected = if i == j { mass } else { 0.0 };
                    assert!(
                        (value - expected).abs() < RELATIVE * mass,
                        "{}: t{i} M t{j} = {value}",
                        case.name
                    );
                }
                // Row sums of the x-, y-, z-blocks: int rho N_a dV (closed form when known).
                if let Some((row_sums, _)) = &case.fractions {
                    for (a, fraction) in row_sums.iter().enumerate() {
                        for r in 0..3 {
                            let expected = if r == i { fraction * mass } else { 0.0 };
                            let value = mt[3 * a + r];
                            assert!(
                                (value - expected).abs() < RELATIVE * mass,
                                "{}: row {a}/{r}: {value}",
                                case.name
                            );
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn lumped_masses_are_hrz_positive_and_sum_to_the_element_mass() {
        for case in cases() {
            let consistent = mass_points_of(&case);
            let mass: f64 = consistent.iter().map(|p| p.weight).sum();
            let lumped = lumped_points_of(&case);
            assert_eq!(lumped.len(), case.nodes.len());
            let total: f64 = lumped.iter().map(|p| p.weight).sum();
            assert!((total - mass).abs() < RELATIVE * mass, "{}: lumped total {total} vs {mass}", case.name);
            let n = 3 * case.nodes.len();
            for (a, point) in lumped.iter().enumerate() {
                assert!(point.weight > 0.0, "{}: node {a} mass {}", case.name, point.weight);
                assert_eq!(point.position, case.nodes[a]);
                for r in 0..3 {
                    for c in 0..n {
                        let expected = if c == 3 * a + r { 1.0 } else { 0.0 };
                        assert_eq!(point.shape[r * n + c], expected, "{}: node {a}", case.name);
                    }
                }
            }
            // HRZ by its definition: proportional to the diagonal of the consistent mass matrix.
            let mut m = DenseMatrix::default();
            mass_matrix(&consistent, n, &mut m);
            let diagonal_sum: f64 = (0..case.nodes.len()).map(|a| m.get(3 * a, 3 * a)).sum();
            for (a, point) in lumped.iter().enumerate() {
                let expected = mass * m.get(3 * a, 3 * a) / diagonal_sum;
                assert!((point.weight - expected).abs() < RELATIVE * mass, "{}: node {a}", case.name);
            }
            // Closed forms: rho V / 4 (Tet4), rho V / 8 (parallelepiped Hex8), m / 36 at the
            // vertices and 4 m / 27 at the mid-edge nodes (straight Tet10).
            if let Some((_, fractions)) = &case.fractions {
                for (a, (point, fraction)) in lumped.iter().zip(fractions).enumerate() {
                    let error = (point.weight - fraction * mass).abs();
                    assert!(
                        error < RELATIVE * mass,
                        "{}: node {a}: {} vs {}",
                        case.name,
                        point.weight,
                        fraction * mass
                    );
                }
            }
        }
    }

    /// The four kernels on `nodes`, which must all fail with `Degenerate`; returns the details.
    fn degenerate_details(kind: Kind, nodes: &[Vec3]) -> Vec<String> {
        let (material, e) = (steel(), element(kind));
        let mut k = DenseMatrix::default();
        let mut points = Vec::new();
        let results = [
            e.stiffness(&material, nodes, &mut k).err(),
            e.mass_points(&material, nodes, &mut points).err(),
            e.lumped_mass_points(&material, nodes, &mut points).err(),
            e.volume(nodes).err(),
        ];
        assert!(points.is_empty(), "{kind:?}: mass points appended despite the error");
        results
            .into_iter()
            .map(|r| match r {
                Some(ElementError::Degenerate { detail }) => detail,
                other => panic!("{kind:?}: expected Degenerate, got {other:?}"),
            })
            .collect()
    }

    #[test]
    fn flat_and_inverted_tetrahedra_are_degenerate() {
        let flat = vec![v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0), v(0.3, 0.3, 0.0)];
        for detail in degenerate_details(Kind::Tet4, &flat) {
            assert!(detail.contains("quadrature point 0"), "{detail}");
        }
        degenerate_details(Kind::Tet10, &tet10_from(&flat));
        // Swapping two vertices inverts the element: det J = -1 everywhere.
        let mut inverted = unit_tet();
        inverted.swap(1, 2);
        for detail in degenerate_details(Kind::Tet4, &inverted) {
            assert!(detail.contains("Jacobian determinant -1.000000e0 at quadrature point 0"), "{detail}");
        }
        for detail in degenerate_details(Kind::Tet10, &tet10_from(&inverted)) {
            assert!(detail.contains("-1.000000e0 at quadrature point 0"), "{detail}");
        }
    }

    #[test]
    fn tet10_with_a_mid_edge_node_near_a_vertex_is_caught_at_the_node() {
        // Beyond the quarter point of edge (0, 1) the Jacobian determinant at vertex 0 turns
        // negative while it stays positive at every quadrature point.
        let mut nodes = tet10_from(&unit_tet());
        nodes[4] = v(0.2, 0.0, 0.0);
        for detail in degenerate_details(Kind::Tet10, &nodes) {
            assert!(detail.contains("at node 0"), "{detail}");
        }
    }

    #[test]
    fn hexahedra_with_collapsed_faces_are_degenerate() {
        // Top face collapsed onto the bottom face: zero volume.
        let mut flat = box_hex(Vec3::ZERO, 1.0, 1.0, 1.0);
        for a in 4..8 {
            flat[a] = flat[a - 4];
        }
        for detail in degenerate_details(Kind::Hex8, &flat) {
            assert!(detail.contains("quadrature point 0"), "{detail}");
        }
        // Top face collapsed to a point (a pyramid): zero determinant at the top corners.
        let mut pyramid = box_hex(Vec3::ZERO, 1.0, 1.0, 1.0);
        for p in &mut pyramid[4..] {
            *p = v(0.5, 0.5, 1.0);
        }
        for detail in degenerate_details(Kind::Hex8, &pyramid) {
            assert!(detail.contains("at node 4"), "{detail}");
        }
        // Mirrored (inverted) box.
        let inverted: Vec<Vec3> =
            box_hex(Vec3::ZERO, 1.0, 1.0, 1.0).into_iter().map(|p| v(p[0], p[1], -p[2])).collect();
        degenerate_details(Kind::Hex8, &inverted);
    }

    #[test]
    fn wrong_node_counts_and_non_finite_positions_are_invalid() {
        let material = steel();
        let mut k = DenseMatrix::default();
        let mut points = Vec::new();
        let three = &unit_tet()[..3];
        assert!(matches!(Tet4.stiffness(&material, three, &mut k), Err(ElementError::Invalid { .. })));
        assert!(matches!(
            Tet10.mass_points(&material, &unit_tet(), &mut points),
            Err(ElementError::Invalid { .. })
        ));
        assert!(matches!(Hex8.volume(&tet10_from(&unit_tet())), Err(ElementError::Invalid { .. })));
        let mut bad = unit_tet();
        bad[2] = v(0.0, f64::NAN, 0.0);
        match Tet4.lumped_mass_points(&material, &bad, &mut points) {
            Err(ElementError::Invalid { detail }) => assert!(detail.contains("node 2"), "{detail}"),
            other => panic!("expected Invalid, got {other:?}"),
        }
        assert!(points.is_empty());
    }

    #[test]
    fn stiffness_output_is_resized_and_overwritten() {
        let case = &cases()[1];
        let fresh = stiffness_of(case);
        let mut reused = DenseMatrix::zeros(12, 12);
        reused.data.iter_mut().for_each(|x| *x = 1.0);
        Tet4.stiffness(&steel(), &case.nodes, &mut reused).unwrap();
        assert_eq!(reused.data, fresh.data);
        let mut wrong_size = DenseMatrix::zeros(3, 5);
        Tet4.stiffness(&steel(), &case.nodes, &mut wrong_size).unwrap();
        assert_eq!((wrong_size.rows, wrong_size.cols), (12, 12));
        assert_eq!(wrong_size.data, fresh.data);
    }
}
