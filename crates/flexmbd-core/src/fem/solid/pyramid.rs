//! The linear pyramid [`Pyramid5`]: nodes, quadrature rules, shape functions and their
//! reference gradients.
//!
//! Reference pyramid: the base [-1, 1]^2 at zeta = 0 with the nodes 0, 1, 2, 3 at (-1,-1),
//! (1,-1), (1,1), (-1,1) (counter-clockwise seen from the apex), the apex 4 at (0, 0, 1)
//! (Gmsh's pyramid, VTK's and meshio's). No polynomial space of five functions fits a pyramid
//! whose triangular faces meet tetrahedra and whose base meets a hexahedron; the rational
//! functions of Bedrosian ("Shape functions and integration formulas for three-dimensional
//! finite element analysis", Int. J. Numer. Meth. Eng. 35 (1992) 95-108) do:
//! N_a = ((1 + xi_a xi)(1 + eta_a eta) - zeta + xi_a eta_a xi eta zeta / (1 - zeta)) / 4 at the
//! base, N_4 = zeta. They hold every linear field, are bilinear on the base and linear on the
//! triangles, and are polynomials of the collapsed coordinates a = xi / (1 - zeta),
//! b = eta / (1 - zeta), z = zeta, which the rules integrate exactly
//! (`quadrature::collapsed_pyramid_rule`).
//!
//! At the apex the rational term's gradient depends on the direction from which it is
//! approached; it is taken along the axis (xi = eta = 0), where it vanishes: the Jacobian and
//! the stresses at node 4 are those limits.

use super::{Isoparametric, Pyramid5};
use crate::fem::quadrature::{QuadraturePoint, PYRAMID_GAUSS_2_2, PYRAMID_GAUSS_2_4};

/// (xi_a, eta_a) of the base nodes 0..3.
const BASE: [[f64; 2]; 4] = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];

/// Distance 1 - zeta below which a point is the apex (the rational term and its gradient are
/// then their limits along the axis, zero).
const APEX: f64 = 1e-12;

impl Isoparametric<5> for Pyramid5 {
    const NAME: &'static str = "pyramid5";
    const NODES: [[f64; 3]; 5] =
        [[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    // B^T D B det J (1 - z)^2: degree 2 in a and b, 2 in z on a pyramid of parallelogram base
    // (constant Jacobian; exact there).
    const STIFFNESS_RULE: &'static [QuadraturePoint] = &PYRAMID_GAUSS_2_2;
    // N_a N_b det J (1 - z)^2 and u0_k u0_l det J (1 - z)^2: degree 3 in a and b (det J is
    // d0 + a d1 + b d2 + a b d3 on any pyramid) and 6 in z (exact).
    const MASS_RULE: &'static [QuadraturePoint] = &PYRAMID_GAUSS_2_4;

    fn shape_functions(xi: [f64; 3]) -> [f64; 5] {
        let [x, y, z] = xi;
        let ratio = if 1.0 - z > APEX { x * y * z / (1.0 - z) } else { 0.0 };
        let mut n = [0.0; 5];
        for (a, [xa, ya]) in BASE.iter().enumerate() {
            n[a] = 0.25 * ((1.0 + xa * x) * (1.0 + ya * y) - z + xa * ya * ratio);
        }
        n[4] = z;
        n
    }

    fn reference_gradients(xi: [f64; 3]) -> [[f64; 3]; 5] {
        let [x, y, z] = xi;
        // Gradient of the rational term r = xi eta zeta / (1 - zeta).
        let dr = if 1.0 - z > APEX {
            let s = 1.0 / (1.0 - z);
            [y * z * s, x * z * s, x * y * s * s]
        } else {
            [0.0; 3]
        };
        let mut g = [[0.0; 3]; 5];
        for (a, [xa, ya]) in BASE.iter().enumerate() {
            let c = xa * ya;
            g[a] = [
                0.25 * (xa * (1.0 + ya * y) + c * dr[0]),
                0.25 * (ya * (1.0 + xa * x) + c * dr[1]),
                0.25 * (-1.0 + c * dr[2]),
            ];
        }
        g[4] = [0.0, 0.0, 1.0];
        g
    }
}
