//! The trilinear hexahedron [`Hex8`], the 20-node serendipity hexahedron [`Hex20`] (and
//! [`Hex20Reduced`]) and the 27-node triquadratic (Lagrange) hexahedron [`Hex27`]: nodes,
//! quadrature rules, shape functions and their reference gradients.

use super::{Hex20, Hex20Reduced, Hex27, Hex8, Isoparametric};
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

/// Reference coordinates of the 27 nodes: those of [`Hex20`], then the centres of the faces
/// xi = -1, xi = +1, eta = -1, eta = +1, zeta = -1, zeta = +1, then the element's centre
/// (VTK's triquadratic hexahedron; meshio converts Gmsh's order to it on reading).
const HEX27_NODES: [[f64; 3]; 27] = {
    let mut nodes = [[0.0; 3]; 27];
    let mut a = 0;
    while a < 20 {
        nodes[a] = HEX20_NODES[a];
        a += 1;
    }
    let faces = [
        [-1.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, -1.0],
        [0.0, 0.0, 1.0],
        [0.0, 0.0, 0.0],
    ];
    while a < 27 {
        nodes[a] = faces[a - 20];
        a += 1;
    }
    nodes
};

/// The quadratic Lagrange polynomial of [-1, 1] that is 1 at the node `c` (-1, 0 or 1) and 0
/// at the other two, and its derivative, at `s`.
pub(super) fn lagrange(c: f64, s: f64) -> (f64, f64) {
    if c == 0.0 {
        (1.0 - s * s, -2.0 * s)
    } else {
        (0.5 * s * (s + c), s + 0.5 * c)
    }
}

impl Isoparametric<27> for Hex27 {
    const NAME: &'static str = "hex27";
    const NODES: [[f64; 3]; 27] = HEX27_NODES;
    // B^T D B: degree 4 per direction on an element of constant Jacobian (exact there).
    const STIFFNESS_RULE: &'static [QuadraturePoint] = &HEXAHEDRON_GAUSS_3;
    // N_a N_b det J: degree 4 + 2 per direction on a straight-edged element (exact).
    const MASS_RULE: &'static [QuadraturePoint] = &HEXAHEDRON_GAUSS_4;

    /// N_a = l_a(xi) l_a(eta) l_a(zeta), the products of the quadratic Lagrange polynomials
    /// of the node's reference coordinates.
    fn shape_functions(xi: [f64; 3]) -> [f64; 27] {
        std::array::from_fn(|a| (0..3).map(|k| lagrange(HEX27_NODES[a][k], xi[k]).0).product())
    }

    fn reference_gradients(xi: [f64; 3]) -> [[f64; 3]; 27] {
        std::array::from_fn(|a| {
            let l: [(f64, f64); 3] = std::array::from_fn(|k| lagrange(HEX27_NODES[a][k], xi[k]));
            [l[0].1 * l[1].0 * l[2].0, l[0].0 * l[1].1 * l[2].0, l[0].0 * l[1].0 * l[2].1]
        })
    }
}
