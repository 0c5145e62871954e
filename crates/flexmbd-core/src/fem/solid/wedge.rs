//! The linear wedge (triangular prism) [`Wedge6`]: nodes, quadrature rules, shape functions
//! and their reference gradients. N_a = L_a(u, v) (1 -+ w) / 2 with the barycentric
//! coordinates L = (1 - u - v, u, v) of the triangle and w in [-1, 1]: nodes 0, 1, 2 at
//! w = -1, counter-clockwise seen from w > 0, and 3, 4, 5 above them (Gmsh's prism, Abaqus'
//! C3D6 and meshio's wedge; VTK's wedge lists the triangles the other way round, which meshio
//! converts on reading and writing).

use super::{Isoparametric, Wedge6};
use crate::fem::quadrature::{QuadraturePoint, WEDGE_TRIANGLE_2_GAUSS_2, WEDGE_TRIANGLE_4_GAUSS_3};

impl Isoparametric<6> for Wedge6 {
    const NAME: &'static str = "Wedge6";
    const NODES: [[f64; 3]; 6] = [
        [0.0, 0.0, -1.0],
        [1.0, 0.0, -1.0],
        [0.0, 1.0, -1.0],
        [0.0, 0.0, 1.0],
        [1.0, 0.0, 1.0],
        [0.0, 1.0, 1.0],
    ];
    // B^T D B: degree 2 in (u, v) and in w.
    const STIFFNESS_RULE: &'static [QuadraturePoint] = &WEDGE_TRIANGLE_2_GAUSS_2;
    // N_a N_b det J and u0_k u0_l det J: degree 3 in (u, v) and 4 in w on a general wedge.
    const MASS_RULE: &'static [QuadraturePoint] = &WEDGE_TRIANGLE_4_GAUSS_3;

    fn shape_functions(xi: [f64; 3]) -> [f64; 6] {
        let l = [1.0 - xi[0] - xi[1], xi[0], xi[1]];
        let (below, above) = (0.5 * (1.0 - xi[2]), 0.5 * (1.0 + xi[2]));
        [l[0] * below, l[1] * below, l[2] * below, l[0] * above, l[1] * above, l[2] * above]
    }

    fn reference_gradients(xi: [f64; 3]) -> [[f64; 3]; 6] {
        let l = [1.0 - xi[0] - xi[1], xi[0], xi[1]];
        let dl = [[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]];
        let mut g = [[0.0; 3]; 6];
        for (a, ga) in g.iter_mut().enumerate() {
            let (t, sign) = if a < 3 { (0.5 * (1.0 - xi[2]), -0.5) } else { (0.5 * (1.0 + xi[2]), 0.5) };
            let k = a % 3;
            *ga = [dl[k][0] * t, dl[k][1] * t, l[k] * sign];
        }
        g
    }
}
