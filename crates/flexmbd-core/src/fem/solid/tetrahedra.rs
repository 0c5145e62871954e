//! The tetrahedra: nodes, quadrature rules, shape functions and their reference gradients of
//! [`Tet4`] (barycentric coordinates) and [`Tet10`] (quadratic, mid-edge nodes of
//! [`TET10_EDGES`]).

use super::{Isoparametric, Tet10, Tet4, TET10_EDGES};
use crate::fem::quadrature::{
    QuadraturePoint, TETRAHEDRON_DEGREE_1, TETRAHEDRON_DEGREE_2, TETRAHEDRON_DEGREE_5,
};

// Barycentric coordinates of the reference tetrahedron and their constant gradients.
fn barycentric(xi: [f64; 3]) -> [f64; 4] {
    [1.0 - xi[0] - xi[1] - xi[2], xi[0], xi[1], xi[2]]
}

const BARYCENTRIC_GRADIENTS: [[f64; 3]; 4] =
    [[-1.0, -1.0, -1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

impl Isoparametric<4> for Tet4 {
    const NAME: &'static str = "tet4";
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
    const NAME: &'static str = "tet10";
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
