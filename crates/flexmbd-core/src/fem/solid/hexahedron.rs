//! The trilinear hexahedron [`Hex8`]: nodes, quadrature rules, shape functions and their
//! reference gradients.

use super::{Hex8, Isoparametric};
use crate::fem::quadrature::{QuadraturePoint, HEXAHEDRON_GAUSS_2, HEXAHEDRON_GAUSS_3};

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
