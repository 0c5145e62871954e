//! The linear pyramid [`Pyramid5`] and the quadratic ones [`Pyramid13`] (serendipity) and
//! [`Pyramid14`] (with the base's centre): nodes, quadrature rules, shape functions and their
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
//! The quadratic pyramids are Bedrosian's 13-node element (also Zgainski, Coulomb et al.,
//! "A new family of finite elements: the pyramidal elements", IEEE Trans. Magn. 32 (1996)) and
//! the same with a node at the base's centre. In the collapsed coordinates, with s = 1 - z,
//! P = 1 + xi_a a, Q = 1 + eta_a b for a node over the base corner (xi_a, eta_a):
//! - base corner: N = s P Q (s (xi_a a + eta_a b) - 1) / 4
//!   (= N_Pyramid5 (xi_a xi + eta_a eta - 1));
//! - apex: N = z (2 z - 1);
//! - midpoint of a base edge, at (0, eta_m): N = s^2 (1 - a^2)(1 + eta_m b) / 2 (and with a
//!   and b swapped for those at (xi_m, 0));
//! - midpoint of the edge from the base corner (xi_a, eta_a) to the apex: N = z s P Q.
//!
//! They hold every quadratic polynomial of (xi, eta, zeta) and the functions of `Pyramid5`,
//! are the 8-node serendipity quadrilateral's on the base and the 6-node triangle's on the
//! triangular faces (so that they meet `Hex20` and `Tet10`). `Pyramid14` adds the base's
//! bubble B = s^2 (1 - a^2)(1 - b^2) (1 at the centre), adds B / 4 to the corner functions
//! and takes B / 2 off the base's mid-edge ones, which makes them zero at the centre: on the
//! base they are the 9-node Lagrange quadrilateral's (which meets `Hex27`), and the element
//! also holds xi^2 eta^2 / (1 - zeta)^2.
//!
//! At the apex the rational term's gradient depends on the direction from which it is
//! approached; it is taken along the axis (xi = eta = 0), where it vanishes: the Jacobian and
//! the stresses at node 4 are those limits. The quadratic pyramids' gradients are evaluated the
//! same way, from the derivatives in (a, b, z) with the factor 1 / (1 - z) of d/dxi = d/da /
//! (1 - z) cancelled in closed form: d/dxi = D_a, d/deta = D_b, d/dzeta = dN/dz + a D_a + b D_b.

use super::{Isoparametric, Pyramid13, Pyramid14, Pyramid5};
use crate::fem::quadrature::{
    QuadraturePoint, PYRAMID_GAUSS_2_2, PYRAMID_GAUSS_2_4, PYRAMID_GAUSS_3_3, PYRAMID_GAUSS_3_4,
};

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

/// Corner pairs of the mid-edge nodes 5..12 of a [`Pyramid13`] or [`Pyramid14`]: the base's
/// edges, then those from the base's corners to the apex (VTK's quadratic pyramid and meshio's
/// pyramid13, which converts Gmsh's order on reading; not Gmsh's own order, nor meshio's
/// pyramid14, which keeps Gmsh's).
pub const PYRAMID13_EDGES: [[usize; 2]; 8] = [[0, 1], [1, 2], [2, 3], [3, 0], [0, 4], [1, 4], [2, 4], [3, 4]];

/// Reference coordinates of the 13 nodes: the corners of [`Pyramid5`], then the midpoints of
/// [`PYRAMID13_EDGES`].
const PYRAMID13_NODES: [[f64; 3]; 13] =
    corners_and_midpoints!(<Pyramid5 as Isoparametric<5>>::NODES, PYRAMID13_EDGES, 13);

/// Reference coordinates of the 14 nodes: those of [`Pyramid13`], then the base's centre.
const PYRAMID14_NODES: [[f64; 3]; 14] = {
    let mut nodes = [[0.0; 3]; 14];
    let mut a = 0;
    while a < 13 {
        nodes[a] = PYRAMID13_NODES[a];
        a += 1;
    }
    nodes
};

/// Collapsed coordinates (a, b, z) = (xi / (1 - zeta), eta / (1 - zeta), zeta) of a point of
/// the reference pyramid; (0, 0, z) at the apex (within [`APEX`]).
fn collapsed(xi: [f64; 3]) -> [f64; 3] {
    let [x, y, z] = xi;
    if 1.0 - z > APEX {
        [x / (1.0 - z), y / (1.0 - z), z]
    } else {
        [0.0, 0.0, z]
    }
}

/// A function of the collapsed coordinates: its value N, D_a = (dN/da) / (1 - z),
/// D_b = (dN/db) / (1 - z) and dN/dz.
type Collapsed = (f64, f64, f64, f64);

/// Value and reference gradient (d/dxi, d/deta, d/dzeta) of a function given in the
/// collapsed coordinates [a, b, z] (see the module doc).
fn reference_value_and_gradient(f: Collapsed, [a, b, _]: [f64; 3]) -> (f64, [f64; 3]) {
    let (n, da, db, dz) = f;
    (n, [da, db, dz + a * da + b * db])
}

/// The functions of [`Pyramid13`] at the collapsed coordinates `c`, and the base's bubble
/// B = s^2 (1 - a^2)(1 - b^2) last (module doc).
fn quadratic_pyramid(c: [f64; 3]) -> [Collapsed; 14] {
    let [a, b, z] = c;
    let s = 1.0 - z;
    let mut f = [(0.0, 0.0, 0.0, 0.0); 14];
    for (k, [p, q]) in BASE.iter().enumerate() {
        let (big_p, big_q, t) = (1.0 + p * a, 1.0 + q * b, p * a + q * b);
        // Base corner k.
        f[k] = (
            0.25 * s * big_p * big_q * (s * t - 1.0),
            0.25 * p * big_q * (s * t - 1.0 + s * big_p),
            0.25 * q * big_p * (s * t - 1.0 + s * big_q),
            -0.25 * big_p * big_q * (2.0 * s * t - 1.0),
        );
        // Midpoint of the edge from corner k to the apex.
        f[9 + k] = (z * s * big_p * big_q, z * p * big_q, z * q * big_p, (1.0 - 2.0 * z) * big_p * big_q);
        // Midpoint of the base edge (k, k + 1), at (xi_m, eta_m) with one of them zero.
        let [r, t] = BASE[(k + 1) % 4];
        let (xm, ym) = (0.5 * (p + r), 0.5 * (q + t));
        f[5 + k] = if xm == 0.0 {
            let (along, across) = (1.0 - a * a, 1.0 + ym * b);
            (0.5 * s * s * along * across, -s * a * across, 0.5 * s * along * ym, -s * along * across)
        } else {
            let (along, across) = (1.0 - b * b, 1.0 + xm * a);
            (0.5 * s * s * along * across, 0.5 * s * along * xm, -s * b * across, -s * along * across)
        };
    }
    f[4] = (z * (2.0 * z - 1.0), 0.0, 0.0, 4.0 * z - 1.0);
    let (u, v) = (1.0 - a * a, 1.0 - b * b);
    f[13] = (s * s * u * v, -2.0 * s * a * v, -2.0 * s * b * u, -2.0 * s * u * v);
    f
}

/// The functions of [`Pyramid14`]: those of [`Pyramid13`] made zero at the base's centre by
/// the bubble (module doc), and the bubble.
fn quadratic_pyramid_with_centre(c: [f64; 3]) -> [Collapsed; 14] {
    let mut f = quadratic_pyramid(c);
    let bubble = f[13];
    for (k, fk) in f.iter_mut().enumerate().take(9) {
        // Values of the 13-node functions at the base's centre: -1/4 at the corners, 1/2 at
        // the base's mid-edge nodes, 0 at the apex (k = 4).
        let at_centre = match k {
            0..=3 => -0.25,
            4 => 0.0,
            _ => 0.5,
        };
        fk.0 -= at_centre * bubble.0;
        fk.1 -= at_centre * bubble.1;
        fk.2 -= at_centre * bubble.2;
        fk.3 -= at_centre * bubble.3;
    }
    f
}

impl Isoparametric<13> for Pyramid13 {
    const NAME: &'static str = "pyramid13";
    const NODES: [[f64; 3]; 13] = PYRAMID13_NODES;
    // B^T D B det J (1 - z)^2: degree 4 in a and b, 4 in z on a pyramid of constant Jacobian
    // (exact there).
    const STIFFNESS_RULE: &'static [QuadraturePoint] = &PYRAMID_GAUSS_3_3;
    // N_a N_b det J (1 - z)^2: degree 5 in a and b, 6 in z on a straight-edged pyramid (exact).
    const MASS_RULE: &'static [QuadraturePoint] = &PYRAMID_GAUSS_3_4;

    fn shape_functions(xi: [f64; 3]) -> [f64; 13] {
        let f = quadratic_pyramid(collapsed(xi));
        std::array::from_fn(|k| f[k].0)
    }

    fn reference_gradients(xi: [f64; 3]) -> [[f64; 3]; 13] {
        let c = collapsed(xi);
        let f = quadratic_pyramid(c);
        std::array::from_fn(|k| reference_value_and_gradient(f[k], c).1)
    }
}

impl Isoparametric<14> for Pyramid14 {
    const NAME: &'static str = "pyramid14";
    const NODES: [[f64; 3]; 14] = PYRAMID14_NODES;
    // As Pyramid13's: the bubble is of the same degrees.
    const STIFFNESS_RULE: &'static [QuadraturePoint] = &PYRAMID_GAUSS_3_3;
    const MASS_RULE: &'static [QuadraturePoint] = &PYRAMID_GAUSS_3_4;

    fn shape_functions(xi: [f64; 3]) -> [f64; 14] {
        quadratic_pyramid_with_centre(collapsed(xi)).map(|f| f.0)
    }

    fn reference_gradients(xi: [f64; 3]) -> [[f64; 3]; 14] {
        let c = collapsed(xi);
        quadratic_pyramid_with_centre(c).map(|f| reference_value_and_gradient(f, c).1)
    }
}
