//! The trilinear hexahedron [`Hex8`] and the 20-node serendipity hexahedron [`Hex20`] (and
//! [`Hex20Reduced`]): nodes, quadrature rules, shape functions and their reference gradients.

use super::{Hex20, Hex20Reduced, Hex8, Isoparametric};
use crate::fem::quadrature::{QuadraturePoint, HEXAHEDRON_GAUSS_2, HEXAHEDRON_GAUSS_3, HEXAHEDRON_GAUSS_4};

impl Isoparametric<8> for Hex8 {
    const NAME: &'static str = "hex8";
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

/// Corner pairs of the mid-edge nodes 8..19 of a [`Hex20`]: the bottom face's edges, the top
/// face's, then the vertical ones (VTK's quadratic hexahedron, Abaqus C3D20).
pub const HEX20_EDGES: [[usize; 2]; 12] =
    [[0, 1], [1, 2], [2, 3], [3, 0], [4, 5], [5, 6], [6, 7], [7, 4], [0, 4], [1, 5], [2, 6], [3, 7]];

/// Reference coordinates of the 20 nodes: the corners of [`Hex8`], then the midpoints of
/// [`HEX20_EDGES`].
const HEX20_NODES: [[f64; 3]; 20] =
    corners_and_midpoints!(<Hex8 as Isoparametric<8>>::NODES, HEX20_EDGES, 20);

/// The serendipity shape functions of the 20-node hexahedron at `xi`: at a corner s (+-1
/// each) N = (1 + xi s_0)(1 + eta s_1)(1 + zeta s_2)(xi s_0 + eta s_1 + zeta s_2 - 2) / 8, at
/// a mid-edge node with s_m = 0 N = (1 - xi_m^2) prod_{k != m} (1 + xi_k s_k) / 4.
fn hex20_shape_functions(xi: [f64; 3]) -> [f64; 20] {
    let mut n = [0.0; 20];
    for (a, s) in HEX20_NODES.iter().enumerate() {
        let f: [f64; 3] = std::array::from_fn(|k| 1.0 + xi[k] * s[k]);
        n[a] = match s.iter().position(|&v| v == 0.0) {
            None => 0.125 * f[0] * f[1] * f[2] * (xi[0] * s[0] + xi[1] * s[1] + xi[2] * s[2] - 2.0),
            Some(m) => {
                0.25 * (1.0 - xi[m] * xi[m]) * (0..3).filter(|&k| k != m).map(|k| f[k]).product::<f64>()
            }
        };
    }
    n
}

/// dN_a / dxi of [`hex20_shape_functions`].
fn hex20_reference_gradients(xi: [f64; 3]) -> [[f64; 3]; 20] {
    let mut g = [[0.0; 3]; 20];
    for (a, s) in HEX20_NODES.iter().enumerate() {
        let f: [f64; 3] = std::array::from_fn(|k| 1.0 + xi[k] * s[k]);
        let others = |k: usize, skip: usize| -> f64 {
            (0..3).filter(|&j| j != k && j != skip).map(|j| f[j]).product()
        };
        g[a] = match s.iter().position(|&v| v == 0.0) {
            None => {
                let sum = xi[0] * s[0] + xi[1] * s[1] + xi[2] * s[2] - 2.0;
                let all = f[0] * f[1] * f[2];
                std::array::from_fn(|k| 0.125 * s[k] * (others(k, k) * sum + all))
            }
            Some(m) => {
                let bubble = 1.0 - xi[m] * xi[m];
                std::array::from_fn(|k| {
                    if k == m {
                        -0.5 * xi[m] * others(m, m)
                    } else {
                        0.25 * bubble * s[k] * others(k, m)
                    }
                })
            }
        };
    }
    g
}

impl Isoparametric<20> for Hex20 {
    const NAME: &'static str = "hex20";
    const NODES: [[f64; 3]; 20] = HEX20_NODES;
    const STIFFNESS_RULE: &'static [QuadraturePoint] = &HEXAHEDRON_GAUSS_3;
    const MASS_RULE: &'static [QuadraturePoint] = &HEXAHEDRON_GAUSS_4;

    fn shape_functions(xi: [f64; 3]) -> [f64; 20] {
        hex20_shape_functions(xi)
    }

    fn reference_gradients(xi: [f64; 3]) -> [[f64; 3]; 20] {
        hex20_reference_gradients(xi)
    }
}

impl Isoparametric<20> for Hex20Reduced {
    const NAME: &'static str = "hex20r";
    const NODES: [[f64; 3]; 20] = HEX20_NODES;
    const STIFFNESS_RULE: &'static [QuadraturePoint] = &HEXAHEDRON_GAUSS_2;
    const MASS_RULE: &'static [QuadraturePoint] = &HEXAHEDRON_GAUSS_4;

    fn shape_functions(xi: [f64; 3]) -> [f64; 20] {
        hex20_shape_functions(xi)
    }

    fn reference_gradients(xi: [f64; 3]) -> [[f64; 3]; 20] {
        hex20_reference_gradients(xi)
    }
}
