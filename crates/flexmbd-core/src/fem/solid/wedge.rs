//! The linear wedge (triangular prism) [`Wedge6`], the 15-node serendipity wedge [`Wedge15`]
//! and the 18-node Lagrange wedge [`Wedge18`]: nodes, quadrature rules, shape functions and
//! their reference gradients. Wedge6: N_a = L_a(u, v) (1 -+ w) / 2 with the barycentric
//! coordinates L = (1 - u - v, u, v) of the triangle and w in [-1, 1]: nodes 0, 1, 2 at
//! w = -1, counter-clockwise seen from w > 0, and 3, 4, 5 above them (Gmsh's prism, Abaqus'
//! C3D6 and meshio's wedge; VTK's wedge lists the triangles the other way round, which meshio
//! converts on reading and writing).

use super::hexahedron::lagrange;
use super::{Isoparametric, Wedge15, Wedge18, Wedge6};
use crate::fem::quadrature::{
    QuadraturePoint, WEDGE_TRIANGLE_2_GAUSS_2, WEDGE_TRIANGLE_4_GAUSS_3, WEDGE_TRIANGLE_5_GAUSS_4,
};

impl Isoparametric<6> for Wedge6 {
    const NAME: &'static str = "wedge6";
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

/// Corner pairs of the mid-edge nodes 6..14 of a [`Wedge15`]: the bottom triangle's edges,
/// the top triangle's, then the vertical ones (Abaqus C3D15, meshio's wedge15, VTK's
/// quadratic wedge).
pub const WEDGE15_EDGES: [[usize; 2]; 9] =
    [[0, 1], [1, 2], [2, 0], [3, 4], [4, 5], [5, 3], [0, 3], [1, 4], [2, 5]];

/// Reference coordinates of the 15 nodes: the corners of [`Wedge6`], then the midpoints of
/// [`WEDGE15_EDGES`].
const WEDGE15_NODES: [[f64; 3]; 15] =
    corners_and_midpoints!(<Wedge6 as Isoparametric<6>>::NODES, WEDGE15_EDGES, 15);

/// Gradients (d/du, d/dv) of the barycentric coordinates L = (1 - u - v, u, v).
const BARYCENTRIC_GRADIENTS: [[f64; 2]; 3] = [[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]];

impl Isoparametric<15> for Wedge15 {
    const NAME: &'static str = "wedge15";
    const NODES: [[f64; 3]; 15] = WEDGE15_NODES;
    // B^T D B: degree 4 in (u, v) and in w on a wedge of constant Jacobian (exact there).
    const STIFFNESS_RULE: &'static [QuadraturePoint] = &WEDGE_TRIANGLE_4_GAUSS_3;
    // N_a N_b det J: degree 5 in (u, v) and 6 in w on a straight-edged wedge (exact).
    const MASS_RULE: &'static [QuadraturePoint] = &WEDGE_TRIANGLE_5_GAUSS_4;

    /// The serendipity wedge: at the corner of vertex k on the level s = -+1,
    /// N = L_k (2 L_k - 1)(1 + s w) / 2 - L_k (1 - w^2) / 2; at the mid-edge node of the
    /// triangle edge (i, j) on level s, N = 2 L_i L_j (1 + s w); at the vertical edge's of
    /// vertex k, N = L_k (1 - w^2).
    fn shape_functions(xi: [f64; 3]) -> [f64; 15] {
        let l = [1.0 - xi[0] - xi[1], xi[0], xi[1]];
        let w = xi[2];
        let mut n = [0.0; 15];
        for (a, value) in n.iter_mut().enumerate() {
            *value = match a {
                0..=5 => {
                    let (k, s) = (a % 3, if a < 3 { -1.0 } else { 1.0 });
                    0.5 * l[k] * (2.0 * l[k] - 1.0) * (1.0 + s * w) - 0.5 * l[k] * (1.0 - w * w)
                }
                6..=11 => {
                    let [i, j] = WEDGE15_EDGES[a - 6];
                    let s = if a < 9 { -1.0 } else { 1.0 };
                    2.0 * l[i % 3] * l[j % 3] * (1.0 + s * w)
                }
                _ => l[a - 12] * (1.0 - w * w),
            };
        }
        n
    }

    fn reference_gradients(xi: [f64; 3]) -> [[f64; 3]; 15] {
        let l = [1.0 - xi[0] - xi[1], xi[0], xi[1]];
        let dl = BARYCENTRIC_GRADIENTS;
        let w = xi[2];
        let mut g = [[0.0; 3]; 15];
        for (a, ga) in g.iter_mut().enumerate() {
            *ga = match a {
                0..=5 => {
                    let (k, s) = (a % 3, if a < 3 { -1.0 } else { 1.0 });
                    let along = 0.5 * (4.0 * l[k] - 1.0) * (1.0 + s * w) - 0.5 * (1.0 - w * w);
                    let up = 0.5 * l[k] * (2.0 * l[k] - 1.0) * s + l[k] * w;
                    [along * dl[k][0], along * dl[k][1], up]
                }
                6..=11 => {
                    let [i, j] = WEDGE15_EDGES[a - 6];
                    let (i, j) = (i % 3, j % 3);
                    let s = if a < 9 { -1.0 } else { 1.0 };
                    let t = 2.0 * (1.0 + s * w);
                    [
                        t * (dl[i][0] * l[j] + l[i] * dl[j][0]),
                        t * (dl[i][1] * l[j] + l[i] * dl[j][1]),
                        2.0 * l[i] * l[j] * s,
                    ]
                }
                _ => {
                    let k = a - 12;
                    [dl[k][0] * (1.0 - w * w), dl[k][1] * (1.0 - w * w), -2.0 * l[k] * w]
                }
            };
        }
        g
    }
}

/// Corners of the quadrilateral faces whose centres are the nodes 15..17 of a [`Wedge18`]:
/// the faces of the bottom triangle's edges (0,1), (1,2), (2,0) (VTK's biquadratic-quadratic
/// wedge lists its face nodes in this order of its own corners; Gmsh lists the second and
/// the third the other way round).
pub const WEDGE18_FACES: [[usize; 4]; 3] = [[0, 1, 4, 3], [1, 2, 5, 4], [2, 0, 3, 5]];

/// Reference coordinates of the 18 nodes: those of [`Wedge15`], then the centres of
/// [`WEDGE18_FACES`] (at w = 0, over the midpoints of the bottom triangle's edges).
const WEDGE18_NODES: [[f64; 3]; 18] = {
    let mut nodes = [[0.0; 3]; 18];
    let mut a = 0;
    while a < 15 {
        nodes[a] = WEDGE15_NODES[a];
        a += 1;
    }
    while a < 18 {
        nodes[a] = [WEDGE15_NODES[a - 9][0], WEDGE15_NODES[a - 9][1], 0.0];
        a += 1;
    }
    nodes
};

/// The node of the quadratic triangle (0..2 its vertices, 3..5 the midpoints of its edges
/// (0,1), (1,2), (2,0)) and the level w (-1, 0, 1) of each node of a [`Wedge18`].
const WEDGE18_LAYOUT: [(usize, f64); 18] = [
    (0, -1.0),
    (1, -1.0),
    (2, -1.0),
    (0, 1.0),
    (1, 1.0),
    (2, 1.0),
    (3, -1.0),
    (4, -1.0),
    (5, -1.0),
    (3, 1.0),
    (4, 1.0),
    (5, 1.0),
    (0, 0.0),
    (1, 0.0),
    (2, 0.0),
    (3, 0.0),
    (4, 0.0),
    (5, 0.0),
];

/// The quadratic triangle's shape function of node `k` (see [`WEDGE18_LAYOUT`]) and its
/// gradient (d/du, d/dv) at the barycentric coordinates `l`: L_k (2 L_k - 1) at a vertex,
/// 4 L_i L_j at the midpoint of the edge (i, j).
fn quadratic_triangle(k: usize, l: [f64; 3]) -> (f64, [f64; 2]) {
    let dl = BARYCENTRIC_GRADIENTS;
    if k < 3 {
        let slope = 4.0 * l[k] - 1.0;
        (l[k] * (2.0 * l[k] - 1.0), [slope * dl[k][0], slope * dl[k][1]])
    } else {
        let (i, j) = (k - 3, (k - 2) % 3);
        let value = 4.0 * l[i] * l[j];
        (value, std::array::from_fn(|c| 4.0 * (dl[i][c] * l[j] + l[i] * dl[j][c])))
    }
}

impl Isoparametric<18> for Wedge18 {
    const NAME: &'static str = "wedge18";
    const NODES: [[f64; 3]; 18] = WEDGE18_NODES;
    // B^T D B: degree 4 in (u, v) and in w on a wedge of constant Jacobian (exact there).
    const STIFFNESS_RULE: &'static [QuadraturePoint] = &WEDGE_TRIANGLE_4_GAUSS_3;
    // N_a N_b det J: degree 5 in (u, v) and 6 in w on a straight-edged wedge (exact).
    const MASS_RULE: &'static [QuadraturePoint] = &WEDGE_TRIANGLE_5_GAUSS_4;

    /// The Lagrange wedge: N = T_k(u, v) l_c(w), the quadratic triangle's function of the
    /// node's triangle node k times the quadratic Lagrange polynomial of its level c.
    fn shape_functions(xi: [f64; 3]) -> [f64; 18] {
        let l = [1.0 - xi[0] - xi[1], xi[0], xi[1]];
        std::array::from_fn(|a| {
            let (k, c) = WEDGE18_LAYOUT[a];
            quadratic_triangle(k, l).0 * lagrange(c, xi[2]).0
        })
    }

    fn reference_gradients(xi: [f64; 3]) -> [[f64; 3]; 18] {
        let l = [1.0 - xi[0] - xi[1], xi[0], xi[1]];
        std::array::from_fn(|a| {
            let (k, c) = WEDGE18_LAYOUT[a];
            let (t, dt) = quadratic_triangle(k, l);
            let (h, dh) = lagrange(c, xi[2]);
            [dt[0] * h, dt[1] * h, t * dh]
        })
    }
}
