//! Quadrature rules on the reference tetrahedron and the reference cube.
//!
//! The reference tetrahedron has the vertices (0,0,0), (1,0,0), (0,1,0), (0,0,1) and volume 1/6;
//! its rules are fully symmetric (invariant under the permutations of the barycentric
//! coordinates), have positive weights and points in the closed tetrahedron, and integrate
//! every polynomial up to their degree exactly (the exact integral of x^a y^b z^c is
//! a! b! c! / (a + b + c + 3)!). The reference cube is [-1, 1]^3 (volume 8); its rules are
//! tensor products of Gauss-Legendre rules, exact for x^a y^b z^c with a, b, c <= 2n - 1 for n
//! points per direction. Weights sum to the reference volume.

/// A point of a quadrature rule on a reference cell.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QuadraturePoint {
    /// Reference coordinates (xi, eta, zeta).
    pub coordinates: [f64; 3],
    /// Weight (reference volume units); the weights of a rule sum to the reference volume.
    pub weight: f64,
}

/// Tetrahedron, degree 1: the centroid (1 point).
pub const TETRAHEDRON_DEGREE_1: [QuadraturePoint; 1] =
    [QuadraturePoint { coordinates: [0.25, 0.25, 0.25], weight: 1.0 / 6.0 }];

// Barycentric coordinates (a, a, a, 1 - 3a) of the degree-2 rule: a = (5 - sqrt 5) / 20.
const TETRAHEDRON_2_SMALL: f64 = 0.1381966011250105;
const TETRAHEDRON_2_LARGE: f64 = 0.5854101966249684;

/// Tetrahedron, degree 2: 4 points at barycentric coordinates (a, a, a, 1 - 3a) and
/// permutations, a = (5 - sqrt 5) / 20, weights 1/24 (Keast 1986, rule 1; Zienkiewicz and
/// Taylor, The Finite Element Method, vol. 1, table 5.4).
pub const TETRAHEDRON_DEGREE_2: [QuadraturePoint; 4] = [
    QuadraturePoint {
        coordinates: [TETRAHEDRON_2_SMALL, TETRAHEDRON_2_SMALL, TETRAHEDRON_2_SMALL],
        weight: 1.0 / 24.0,
    },
    QuadraturePoint {
        coordinates: [TETRAHEDRON_2_LARGE, TETRAHEDRON_2_SMALL, TETRAHEDRON_2_SMALL],
        weight: 1.0 / 24.0,
    },
    QuadraturePoint {
        coordinates: [TETRAHEDRON_2_SMALL, TETRAHEDRON_2_LARGE, TETRAHEDRON_2_SMALL],
        weight: 1.0 / 24.0,
    },
    QuadraturePoint {
        coordinates: [TETRAHEDRON_2_SMALL, TETRAHEDRON_2_SMALL, TETRAHEDRON_2_LARGE],
        weight: 1.0 / 24.0,
    },
];

// Degree-3 rule: 4 points (a, a, a, 1 - 3a) of weight W1 / 6 and the 6 edge midpoints of weight
// W2 / 6, with (a, W1, W2) the real root of the symmetric moment equations
// 4 W1 + 6 W2 = 1, 4 W1 (3a^2 + (1-3a)^2) + 6 W2 / 2 = 2/5, 4 W1 (3a^3 + (1-3a)^3) + 6 W2 / 4 = 1/5;
// in closed form W1 = 1/10 + (t + 1/t) / 20 with t = (3 + 2 sqrt 2)^(1/3).
const TETRAHEDRON_3_SMALL: f64 = 0.1438564719343849;
const TETRAHEDRON_3_LARGE: f64 = 0.5684305841968453;
const TETRAHEDRON_3_INTERIOR_WEIGHT: f64 = 0.036294178313400996;
const TETRAHEDRON_3_EDGE_WEIGHT: f64 = 0.003581658902177112;

/// Tetrahedron, degree 3: 10 points with positive weights, 4 interior points and the 6 edge
/// midpoints (the rule listed as Keast #3 in J. Burkardt's `quadrature_rules_tet` tables and in
/// quadpy; the values here are the real root of its moment equations to full precision).
pub const TETRAHEDRON_DEGREE_3: [QuadraturePoint; 10] = [
    QuadraturePoint {
        coordinates: [TETRAHEDRON_3_SMALL, TETRAHEDRON_3_SMALL, TETRAHEDRON_3_SMALL],
        weight: TETRAHEDRON_3_INTERIOR_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [TETRAHEDRON_3_LARGE, TETRAHEDRON_3_SMALL, TETRAHEDRON_3_SMALL],
        weight: TETRAHEDRON_3_INTERIOR_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [TETRAHEDRON_3_SMALL, TETRAHEDRON_3_LARGE, TETRAHEDRON_3_SMALL],
        weight: TETRAHEDRON_3_INTERIOR_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [TETRAHEDRON_3_SMALL, TETRAHEDRON_3_SMALL, TETRAHEDRON_3_LARGE],
        weight: TETRAHEDRON_3_INTERIOR_WEIGHT,
    },
    QuadraturePoint { coordinates: [0.0, 0.5, 0.5], weight: TETRAHEDRON_3_EDGE_WEIGHT },
    QuadraturePoint { coordinates: [0.5, 0.0, 0.5], weight: TETRAHEDRON_3_EDGE_WEIGHT },
    QuadraturePoint { coordinates: [0.5, 0.5, 0.0], weight: TETRAHEDRON_3_EDGE_WEIGHT },
    QuadraturePoint { coordinates: [0.0, 0.0, 0.5], weight: TETRAHEDRON_3_EDGE_WEIGHT },
    QuadraturePoint { coordinates: [0.0, 0.5, 0.0], weight: TETRAHEDRON_3_EDGE_WEIGHT },
    QuadraturePoint { coordinates: [0.5, 0.0, 0.0], weight: TETRAHEDRON_3_EDGE_WEIGHT },
];

// Degree-5 rule (Keast 1986, rule 6), weights for the unit volume before the factor 1/6:
// centroid 6544/36015; face centroids (1/3, 1/3, 1/3, 0) 81/2240; (1/11, 1/11, 1/11, 8/11)
// 161051/2304960; (a, a, b, b) with a = 1/4 - sqrt(91)/52, b = 1/2 - a, 338/5145.
const TETRAHEDRON_5_CENTROID_WEIGHT: f64 = 6544.0 / 36015.0 / 6.0;
const TETRAHEDRON_5_FACE_WEIGHT: f64 = 81.0 / 2240.0 / 6.0;
const TETRAHEDRON_5_ELEVENTH_WEIGHT: f64 = 161051.0 / 2304960.0 / 6.0;
const TETRAHEDRON_5_EDGE_WEIGHT: f64 = 338.0 / 5145.0 / 6.0;
const THIRD: f64 = 1.0 / 3.0;
const ELEVENTH: f64 = 1.0 / 11.0;
const EIGHT_ELEVENTHS: f64 = 8.0 / 11.0;
const TETRAHEDRON_5_SMALL: f64 = 0.0665501535736643;
const TETRAHEDRON_5_LARGE: f64 = 0.4334498464263357;

/// Tetrahedron, degree 5: 15 points with positive weights (P. Keast, "Moderate-degree
/// tetrahedral quadrature formulas", Comput. Methods Appl. Mech. Engrg. 55 (1986) 339-348,
/// rule 6). Four of its points are face centroids.
pub const TETRAHEDRON_DEGREE_5: [QuadraturePoint; 15] = [
    QuadraturePoint { coordinates: [0.25, 0.25, 0.25], weight: TETRAHEDRON_5_CENTROID_WEIGHT },
    QuadraturePoint { coordinates: [THIRD, THIRD, THIRD], weight: TETRAHEDRON_5_FACE_WEIGHT },
    QuadraturePoint { coordinates: [0.0, THIRD, THIRD], weight: TETRAHEDRON_5_FACE_WEIGHT },
    QuadraturePoint { coordinates: [THIRD, 0.0, THIRD], weight: TETRAHEDRON_5_FACE_WEIGHT },
    QuadraturePoint { coordinates: [THIRD, THIRD, 0.0], weight: TETRAHEDRON_5_FACE_WEIGHT },
    QuadraturePoint { coordinates: [ELEVENTH, ELEVENTH, ELEVENTH], weight: TETRAHEDRON_5_ELEVENTH_WEIGHT },
    QuadraturePoint {
        coordinates: [EIGHT_ELEVENTHS, ELEVENTH, ELEVENTH],
        weight: TETRAHEDRON_5_ELEVENTH_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [ELEVENTH, EIGHT_ELEVENTHS, ELEVENTH],
        weight: TETRAHEDRON_5_ELEVENTH_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [ELEVENTH, ELEVENTH, EIGHT_ELEVENTHS],
        weight: TETRAHEDRON_5_ELEVENTH_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [TETRAHEDRON_5_SMALL, TETRAHEDRON_5_LARGE, TETRAHEDRON_5_LARGE],
        weight: TETRAHEDRON_5_EDGE_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [TETRAHEDRON_5_LARGE, TETRAHEDRON_5_SMALL, TETRAHEDRON_5_LARGE],
        weight: TETRAHEDRON_5_EDGE_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [TETRAHEDRON_5_LARGE, TETRAHEDRON_5_LARGE, TETRAHEDRON_5_SMALL],
        weight: TETRAHEDRON_5_EDGE_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [TETRAHEDRON_5_SMALL, TETRAHEDRON_5_SMALL, TETRAHEDRON_5_LARGE],
        weight: TETRAHEDRON_5_EDGE_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [TETRAHEDRON_5_SMALL, TETRAHEDRON_5_LARGE, TETRAHEDRON_5_SMALL],
        weight: TETRAHEDRON_5_EDGE_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [TETRAHEDRON_5_LARGE, TETRAHEDRON_5_SMALL, TETRAHEDRON_5_SMALL],
        weight: TETRAHEDRON_5_EDGE_WEIGHT,
    },
];

/// The tetrahedron rule with the fewest points that integrates every polynomial of total
/// degree `degree` exactly; `None` above degree 5.
pub fn tetrahedron_rule(degree: usize) -> Option<&'static [QuadraturePoint]> {
    match degree {
        0 | 1 => Some(&TETRAHEDRON_DEGREE_1),
        2 => Some(&TETRAHEDRON_DEGREE_2),
        3 => Some(&TETRAHEDRON_DEGREE_3),
        4 | 5 => Some(&TETRAHEDRON_DEGREE_5),
        _ => None,
    }
}

// Gauss-Legendre abscissae on [-1, 1]: 1/sqrt 3 (2 points), sqrt(3/5) (3 points).
const GAUSS_2_ABSCISSA: f64 = 0.5773502691896257;
const GAUSS_3_ABSCISSA: f64 = 0.7745966692414834;
const GAUSS_3_END_WEIGHT: f64 = 5.0 / 9.0;
const GAUSS_3_MIDDLE_WEIGHT: f64 = 8.0 / 9.0;

/// Gauss-Legendre rule on [-1, 1] with 1 point, as (abscissa, weight); exact to degree 1.
pub const GAUSS_LEGENDRE_1: [(f64, f64); 1] = [(0.0, 2.0)];
/// Gauss-Legendre rule on [-1, 1] with 2 points, as (abscissa, weight); exact to degree 3.
pub const GAUSS_LEGENDRE_2: [(f64, f64); 2] = [(-GAUSS_2_ABSCISSA, 1.0), (GAUSS_2_ABSCISSA, 1.0)];
/// Gauss-Legendre rule on [-1, 1] with 3 points, as (abscissa, weight); exact to degree 5.
pub const GAUSS_LEGENDRE_3: [(f64, f64); 3] = [
    (-GAUSS_3_ABSCISSA, GAUSS_3_END_WEIGHT),
    (0.0, GAUSS_3_MIDDLE_WEIGHT),
    (GAUSS_3_ABSCISSA, GAUSS_3_END_WEIGHT),
];

/// The Gauss-Legendre rule on [-1, 1] with `points` points (1 to 4), as (abscissa, weight).
pub fn gauss_legendre_rule(points: usize) -> Option<&'static [(f64, f64)]> {
    match points {
        1 => Some(&GAUSS_LEGENDRE_1),
        2 => Some(&GAUSS_LEGENDRE_2),
        3 => Some(&GAUSS_LEGENDRE_3),
        4 => Some(&GAUSS_LEGENDRE_4),
        _ => None,
    }
}

/// Cube [-1, 1]^3, 1 x 1 x 1 Gauss-Legendre point.
pub const HEXAHEDRON_GAUSS_1: [QuadraturePoint; 1] =
    [QuadraturePoint { coordinates: [0.0, 0.0, 0.0], weight: 8.0 }];

/// Cube [-1, 1]^3, 2 x 2 x 2 Gauss-Legendre points (xi fastest, then eta, then zeta).
pub const HEXAHEDRON_GAUSS_2: [QuadraturePoint; 8] = [
    QuadraturePoint { coordinates: [-GAUSS_2_ABSCISSA, -GAUSS_2_ABSCISSA, -GAUSS_2_ABSCISSA], weight: 1.0 },
    QuadraturePoint { coordinates: [GAUSS_2_ABSCISSA, -GAUSS_2_ABSCISSA, -GAUSS_2_ABSCISSA], weight: 1.0 },
    QuadraturePoint { coordinates: [-GAUSS_2_ABSCISSA, GAUSS_2_ABSCISSA, -GAUSS_2_ABSCISSA], weight: 1.0 },
    QuadraturePoint { coordinates: [GAUSS_2_ABSCISSA, GAUSS_2_ABSCISSA, -GAUSS_2_ABSCISSA], weight: 1.0 },
    QuadraturePoint { coordinates: [-GAUSS_2_ABSCISSA, -GAUSS_2_ABSCISSA, GAUSS_2_ABSCISSA], weight: 1.0 },
    QuadraturePoint { coordinates: [GAUSS_2_ABSCISSA, -GAUSS_2_ABSCISSA, GAUSS_2_ABSCISSA], weight: 1.0 },
    QuadraturePoint { coordinates: [-GAUSS_2_ABSCISSA, GAUSS_2_ABSCISSA, GAUSS_2_ABSCISSA], weight: 1.0 },
    QuadraturePoint { coordinates: [GAUSS_2_ABSCISSA, GAUSS_2_ABSCISSA, GAUSS_2_ABSCISSA], weight: 1.0 },
];

/// Cube [-1, 1]^3, 3 x 3 x 3 Gauss-Legendre points (xi fastest, then eta, then zeta).
pub const HEXAHEDRON_GAUSS_3: [QuadraturePoint; 27] = [
    QuadraturePoint {
        coordinates: [-GAUSS_3_ABSCISSA, -GAUSS_3_ABSCISSA, -GAUSS_3_ABSCISSA],
        weight: GAUSS_3_END_WEIGHT * GAUSS_3_END_WEIGHT * GAUSS_3_END_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [0.0, -GAUSS_3_ABSCISSA, -GAUSS_3_ABSCISSA],
        weight: GAUSS_3_MIDDLE_WEIGHT * GAUSS_3_END_WEIGHT * GAUSS_3_END_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [GAUSS_3_ABSCISSA, -GAUSS_3_ABSCISSA, -GAUSS_3_ABSCISSA],
        weight: GAUSS_3_END_WEIGHT * GAUSS_3_END_WEIGHT * GAUSS_3_END_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [-GAUSS_3_ABSCISSA, 0.0, -GAUSS_3_ABSCISSA],
        weight: GAUSS_3_END_WEIGHT * GAUSS_3_MIDDLE_WEIGHT * GAUSS_3_END_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [0.0, 0.0, -GAUSS_3_ABSCISSA],
        weight: GAUSS_3_MIDDLE_WEIGHT * GAUSS_3_MIDDLE_WEIGHT * GAUSS_3_END_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [GAUSS_3_ABSCISSA, 0.0, -GAUSS_3_ABSCISSA],
        weight: GAUSS_3_END_WEIGHT * GAUSS_3_MIDDLE_WEIGHT * GAUSS_3_END_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [-GAUSS_3_ABSCISSA, GAUSS_3_ABSCISSA, -GAUSS_3_ABSCISSA],
        weight: GAUSS_3_END_WEIGHT * GAUSS_3_END_WEIGHT * GAUSS_3_END_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [0.0, GAUSS_3_ABSCISSA, -GAUSS_3_ABSCISSA],
        weight: GAUSS_3_MIDDLE_WEIGHT * GAUSS_3_END_WEIGHT * GAUSS_3_END_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [GAUSS_3_ABSCISSA, GAUSS_3_ABSCISSA, -GAUSS_3_ABSCISSA],
        weight: GAUSS_3_END_WEIGHT * GAUSS_3_END_WEIGHT * GAUSS_3_END_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [-GAUSS_3_ABSCISSA, -GAUSS_3_ABSCISSA, 0.0],
        weight: GAUSS_3_END_WEIGHT * GAUSS_3_END_WEIGHT * GAUSS_3_MIDDLE_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [0.0, -GAUSS_3_ABSCISSA, 0.0],
        weight: GAUSS_3_MIDDLE_WEIGHT * GAUSS_3_END_WEIGHT * GAUSS_3_MIDDLE_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [GAUSS_3_ABSCISSA, -GAUSS_3_ABSCISSA, 0.0],
        weight: GAUSS_3_END_WEIGHT * GAUSS_3_END_WEIGHT * GAUSS_3_MIDDLE_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [-GAUSS_3_ABSCISSA, 0.0, 0.0],
        weight: GAUSS_3_END_WEIGHT * GAUSS_3_MIDDLE_WEIGHT * GAUSS_3_MIDDLE_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [0.0, 0.0, 0.0],
        weight: GAUSS_3_MIDDLE_WEIGHT * GAUSS_3_MIDDLE_WEIGHT * GAUSS_3_MIDDLE_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [GAUSS_3_ABSCISSA, 0.0, 0.0],
        weight: GAUSS_3_END_WEIGHT * GAUSS_3_MIDDLE_WEIGHT * GAUSS_3_MIDDLE_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [-GAUSS_3_ABSCISSA, GAUSS_3_ABSCISSA, 0.0],
        weight: GAUSS_3_END_WEIGHT * GAUSS_3_END_WEIGHT * GAUSS_3_MIDDLE_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [0.0, GAUSS_3_ABSCISSA, 0.0],
        weight: GAUSS_3_MIDDLE_WEIGHT * GAUSS_3_END_WEIGHT * GAUSS_3_MIDDLE_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [GAUSS_3_ABSCISSA, GAUSS_3_ABSCISSA, 0.0],
        weight: GAUSS_3_END_WEIGHT * GAUSS_3_END_WEIGHT * GAUSS_3_MIDDLE_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [-GAUSS_3_ABSCISSA, -GAUSS_3_ABSCISSA, GAUSS_3_ABSCISSA],
        weight: GAUSS_3_END_WEIGHT * GAUSS_3_END_WEIGHT * GAUSS_3_END_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [0.0, -GAUSS_3_ABSCISSA, GAUSS_3_ABSCISSA],
        weight: GAUSS_3_MIDDLE_WEIGHT * GAUSS_3_END_WEIGHT * GAUSS_3_END_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [GAUSS_3_ABSCISSA, -GAUSS_3_ABSCISSA, GAUSS_3_ABSCISSA],
        weight: GAUSS_3_END_WEIGHT * GAUSS_3_END_WEIGHT * GAUSS_3_END_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [-GAUSS_3_ABSCISSA, 0.0, GAUSS_3_ABSCISSA],
        weight: GAUSS_3_END_WEIGHT * GAUSS_3_MIDDLE_WEIGHT * GAUSS_3_END_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [0.0, 0.0, GAUSS_3_ABSCISSA],
        weight: GAUSS_3_MIDDLE_WEIGHT * GAUSS_3_MIDDLE_WEIGHT * GAUSS_3_END_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [GAUSS_3_ABSCISSA, 0.0, GAUSS_3_ABSCISSA],
        weight: GAUSS_3_END_WEIGHT * GAUSS_3_MIDDLE_WEIGHT * GAUSS_3_END_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [-GAUSS_3_ABSCISSA, GAUSS_3_ABSCISSA, GAUSS_3_ABSCISSA],
        weight: GAUSS_3_END_WEIGHT * GAUSS_3_END_WEIGHT * GAUSS_3_END_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [0.0, GAUSS_3_ABSCISSA, GAUSS_3_ABSCISSA],
        weight: GAUSS_3_MIDDLE_WEIGHT * GAUSS_3_END_WEIGHT * GAUSS_3_END_WEIGHT,
    },
    QuadraturePoint {
        coordinates: [GAUSS_3_ABSCISSA, GAUSS_3_ABSCISSA, GAUSS_3_ABSCISSA],
        weight: GAUSS_3_END_WEIGHT * GAUSS_3_END_WEIGHT * GAUSS_3_END_WEIGHT,
    },
];

/// Gauss-Legendre rule on [-1, 1] with 4 points, as (abscissa, weight); exact to degree 7.
pub const GAUSS_LEGENDRE_4: [(f64, f64); 4] = [
    (-0.8611363115940526, 0.3478548451374538),
    (-0.3399810435848563, 0.6521451548625461),
    (0.3399810435848563, 0.6521451548625461),
    (0.8611363115940526, 0.3478548451374538),
];

/// Point (i, j, k) of the 4 x 4 x 4 tensor-product rule.
macro_rules! gauss_4_point {
    ($i:literal, $j:literal, $k:literal) => {
        QuadraturePoint {
            coordinates: [GAUSS_LEGENDRE_4[$i].0, GAUSS_LEGENDRE_4[$j].0, GAUSS_LEGENDRE_4[$k].0],
            weight: GAUSS_LEGENDRE_4[$i].1 * GAUSS_LEGENDRE_4[$j].1 * GAUSS_LEGENDRE_4[$k].1,
        }
    };
}

/// Cube [-1, 1]^3, 4 x 4 x 4 Gauss-Legendre points (xi fastest, then eta, then zeta).
pub const HEXAHEDRON_GAUSS_4: [QuadraturePoint; 64] = [
    gauss_4_point!(0, 0, 0),
    gauss_4_point!(1, 0, 0),
    gauss_4_point!(2, 0, 0),
    gauss_4_point!(3, 0, 0),
    gauss_4_point!(0, 1, 0),
    gauss_4_point!(1, 1, 0),
    gauss_4_point!(2, 1, 0),
    gauss_4_point!(3, 1, 0),
    gauss_4_point!(0, 2, 0),
    gauss_4_point!(1, 2, 0),
    gauss_4_point!(2, 2, 0),
    gauss_4_point!(3, 2, 0),
    gauss_4_point!(0, 3, 0),
    gauss_4_point!(1, 3, 0),
    gauss_4_point!(2, 3, 0),
    gauss_4_point!(3, 3, 0),
    gauss_4_point!(0, 0, 1),
    gauss_4_point!(1, 0, 1),
    gauss_4_point!(2, 0, 1),
    gauss_4_point!(3, 0, 1),
    gauss_4_point!(0, 1, 1),
    gauss_4_point!(1, 1, 1),
    gauss_4_point!(2, 1, 1),
    gauss_4_point!(3, 1, 1),
    gauss_4_point!(0, 2, 1),
    gauss_4_point!(1, 2, 1),
    gauss_4_point!(2, 2, 1),
    gauss_4_point!(3, 2, 1),
    gauss_4_point!(0, 3, 1),
    gauss_4_point!(1, 3, 1),
    gauss_4_point!(2, 3, 1),
    gauss_4_point!(3, 3, 1),
    gauss_4_point!(0, 0, 2),
    gauss_4_point!(1, 0, 2),
    gauss_4_point!(2, 0, 2),
    gauss_4_point!(3, 0, 2),
    gauss_4_point!(0, 1, 2),
    gauss_4_point!(1, 1, 2),
    gauss_4_point!(2, 1, 2),
    gauss_4_point!(3, 1, 2),
    gauss_4_point!(0, 2, 2),
    gauss_4_point!(1, 2, 2),
    gauss_4_point!(2, 2, 2),
    gauss_4_point!(3, 2, 2),
    gauss_4_point!(0, 3, 2),
    gauss_4_point!(1, 3, 2),
    gauss_4_point!(2, 3, 2),
    gauss_4_point!(3, 3, 2),
    gauss_4_point!(0, 0, 3),
    gauss_4_point!(1, 0, 3),
    gauss_4_point!(2, 0, 3),
    gauss_4_point!(3, 0, 3),
    gauss_4_point!(0, 1, 3),
    gauss_4_point!(1, 1, 3),
    gauss_4_point!(2, 1, 3),
    gauss_4_point!(3, 1, 3),
    gauss_4_point!(0, 2, 3),
    gauss_4_point!(1, 2, 3),
    gauss_4_point!(2, 2, 3),
    gauss_4_point!(3, 2, 3),
    gauss_4_point!(0, 3, 3),
    gauss_4_point!(1, 3, 3),
    gauss_4_point!(2, 3, 3),
    gauss_4_point!(3, 3, 3),
];

/// Reference triangle (0,0), (1,0), (0,1), 3 points, exact to degree 2 (as (u, v, weight)).
pub const TRIANGLE_DEGREE_2: [(f64, f64, f64); 3] =
    [(1.0 / 6.0, 1.0 / 6.0, 1.0 / 6.0), (2.0 / 3.0, 1.0 / 6.0, 1.0 / 6.0), (1.0 / 6.0, 2.0 / 3.0, 1.0 / 6.0)];

// Dunavant's 6-point rule of degree 4 (Int. J. Numer. Meth. Eng. 21 (1985) 1129-1148): the
// barycentric points (a, a, 1 - 2a) of two orbits, weights relative to the area.
const DUNAVANT_4_A1: f64 = 0.445948490915965;
const DUNAVANT_4_W1: f64 = 0.223381589678011;
const DUNAVANT_4_A2: f64 = 0.091576213509771;
const DUNAVANT_4_W2: f64 = 0.109951743655322;

/// Reference triangle, 6 points, exact to degree 4 (as (u, v, weight)).
pub const TRIANGLE_DEGREE_4: [(f64, f64, f64); 6] = [
    (DUNAVANT_4_A1, DUNAVANT_4_A1, 0.5 * DUNAVANT_4_W1),
    (DUNAVANT_4_A1, 1.0 - 2.0 * DUNAVANT_4_A1, 0.5 * DUNAVANT_4_W1),
    (1.0 - 2.0 * DUNAVANT_4_A1, DUNAVANT_4_A1, 0.5 * DUNAVANT_4_W1),
    (DUNAVANT_4_A2, DUNAVANT_4_A2, 0.5 * DUNAVANT_4_W2),
    (DUNAVANT_4_A2, 1.0 - 2.0 * DUNAVANT_4_A2, 0.5 * DUNAVANT_4_W2),
    (1.0 - 2.0 * DUNAVANT_4_A2, DUNAVANT_4_A2, 0.5 * DUNAVANT_4_W2),
];

// Radon's 7-point rule of degree 5 (Dunavant's degree-5 rule): the centroid (weight 9/40 of
// the area) and two orbits (a, a, 1 - 2a), a = (6 -+ sqrt 15) / 21, weights (155 -+ sqrt 15)
// / 1200 of the area.
const RADON_5_A1: f64 = 0.10128650732345634;
const RADON_5_W1: f64 = 0.12593918054482714;
const RADON_5_A2: f64 = 0.4701420641051151;
const RADON_5_W2: f64 = 0.1323941527885062;

/// Reference triangle, 7 points, exact to degree 5 (as (u, v, weight)).
pub const TRIANGLE_DEGREE_5: [(f64, f64, f64); 7] = [
    (1.0 / 3.0, 1.0 / 3.0, 0.5 * 9.0 / 40.0),
    (RADON_5_A1, RADON_5_A1, 0.5 * RADON_5_W1),
    (RADON_5_A1, 1.0 - 2.0 * RADON_5_A1, 0.5 * RADON_5_W1),
    (1.0 - 2.0 * RADON_5_A1, RADON_5_A1, 0.5 * RADON_5_W1),
    (RADON_5_A2, RADON_5_A2, 0.5 * RADON_5_W2),
    (RADON_5_A2, 1.0 - 2.0 * RADON_5_A2, 0.5 * RADON_5_W2),
    (1.0 - 2.0 * RADON_5_A2, RADON_5_A2, 0.5 * RADON_5_W2),
];

/// Point (triangle point i, line point j) of a wedge rule: triangle x [-1, 1].
macro_rules! wedge_point {
    ($triangle:ident, $line:ident, $i:literal, $j:literal) => {
        QuadraturePoint {
            coordinates: [$triangle[$i].0, $triangle[$i].1, $line[$j].0],
            weight: $triangle[$i].2 * $line[$j].1,
        }
    };
}

/// Reference wedge (triangle (0,0), (1,0), (0,1)) x [-1, 1]: the degree-2 triangle rule times
/// 2-point Gauss (exact to degree 2 in (u, v) and 3 in w).
pub const WEDGE_TRIANGLE_2_GAUSS_2: [QuadraturePoint; 6] = [
    wedge_point!(TRIANGLE_DEGREE_2, GAUSS_LEGENDRE_2, 0, 0),
    wedge_point!(TRIANGLE_DEGREE_2, GAUSS_LEGENDRE_2, 1, 0),
    wedge_point!(TRIANGLE_DEGREE_2, GAUSS_LEGENDRE_2, 2, 0),
    wedge_point!(TRIANGLE_DEGREE_2, GAUSS_LEGENDRE_2, 0, 1),
    wedge_point!(TRIANGLE_DEGREE_2, GAUSS_LEGENDRE_2, 1, 1),
    wedge_point!(TRIANGLE_DEGREE_2, GAUSS_LEGENDRE_2, 2, 1),
];

/// Reference wedge: the degree-4 triangle rule times 3-point Gauss (exact to degree 4 in
/// (u, v) and 5 in w).
pub const WEDGE_TRIANGLE_4_GAUSS_3: [QuadraturePoint; 18] = [
    wedge_point!(TRIANGLE_DEGREE_4, GAUSS_LEGENDRE_3, 0, 0),
    wedge_point!(TRIANGLE_DEGREE_4, GAUSS_LEGENDRE_3, 1, 0),
    wedge_point!(TRIANGLE_DEGREE_4, GAUSS_LEGENDRE_3, 2, 0),
    wedge_point!(TRIANGLE_DEGREE_4, GAUSS_LEGENDRE_3, 3, 0),
    wedge_point!(TRIANGLE_DEGREE_4, GAUSS_LEGENDRE_3, 4, 0),
    wedge_point!(TRIANGLE_DEGREE_4, GAUSS_LEGENDRE_3, 5, 0),
    wedge_point!(TRIANGLE_DEGREE_4, GAUSS_LEGENDRE_3, 0, 1),
    wedge_point!(TRIANGLE_DEGREE_4, GAUSS_LEGENDRE_3, 1, 1),
    wedge_point!(TRIANGLE_DEGREE_4, GAUSS_LEGENDRE_3, 2, 1),
    wedge_point!(TRIANGLE_DEGREE_4, GAUSS_LEGENDRE_3, 3, 1),
    wedge_point!(TRIANGLE_DEGREE_4, GAUSS_LEGENDRE_3, 4, 1),
    wedge_point!(TRIANGLE_DEGREE_4, GAUSS_LEGENDRE_3, 5, 1),
    wedge_point!(TRIANGLE_DEGREE_4, GAUSS_LEGENDRE_3, 0, 2),
    wedge_point!(TRIANGLE_DEGREE_4, GAUSS_LEGENDRE_3, 1, 2),
    wedge_point!(TRIANGLE_DEGREE_4, GAUSS_LEGENDRE_3, 2, 2),
    wedge_point!(TRIANGLE_DEGREE_4, GAUSS_LEGENDRE_3, 3, 2),
    wedge_point!(TRIANGLE_DEGREE_4, GAUSS_LEGENDRE_3, 4, 2),
    wedge_point!(TRIANGLE_DEGREE_4, GAUSS_LEGENDRE_3, 5, 2),
];

/// Reference wedge: the degree-5 triangle rule times 4-point Gauss (exact to degree 5 in
/// (u, v) and 7 in w).
pub const WEDGE_TRIANGLE_5_GAUSS_4: [QuadraturePoint; 28] = [
    wedge_point!(TRIANGLE_DEGREE_5, GAUSS_LEGENDRE_4, 0, 0),
    wedge_point!(TRIANGLE_DEGREE_5, GAUSS_LEGENDRE_4, 1, 0),
    wedge_point!(TRIANGLE_DEGREE_5, GAUSS_LEGENDRE_4, 2, 0),
    wedge_point!(TRIANGLE_DEGREE_5, GAUSS_LEGENDRE_4, 3, 0),
    wedge_point!(TRIANGLE_DEGREE_5, GAUSS_LEGENDRE_4, 4, 0),
    wedge_point!(TRIANGLE_DEGREE_5, GAUSS_LEGENDRE_4, 5, 0),
    wedge_point!(TRIANGLE_DEGREE_5, GAUSS_LEGENDRE_4, 6, 0),
    wedge_point!(TRIANGLE_DEGREE_5, GAUSS_LEGENDRE_4, 0, 1),
    wedge_point!(TRIANGLE_DEGREE_5, GAUSS_LEGENDRE_4, 1, 1),
    wedge_point!(TRIANGLE_DEGREE_5, GAUSS_LEGENDRE_4, 2, 1),
    wedge_point!(TRIANGLE_DEGREE_5, GAUSS_LEGENDRE_4, 3, 1),
    wedge_point!(TRIANGLE_DEGREE_5, GAUSS_LEGENDRE_4, 4, 1),
    wedge_point!(TRIANGLE_DEGREE_5, GAUSS_LEGENDRE_4, 5, 1),
    wedge_point!(TRIANGLE_DEGREE_5, GAUSS_LEGENDRE_4, 6, 1),
    wedge_point!(TRIANGLE_DEGREE_5, GAUSS_LEGENDRE_4, 0, 2),
    wedge_point!(TRIANGLE_DEGREE_5, GAUSS_LEGENDRE_4, 1, 2),
    wedge_point!(TRIANGLE_DEGREE_5, GAUSS_LEGENDRE_4, 2, 2),
    wedge_point!(TRIANGLE_DEGREE_5, GAUSS_LEGENDRE_4, 3, 2),
    wedge_point!(TRIANGLE_DEGREE_5, GAUSS_LEGENDRE_4, 4, 2),
    wedge_point!(TRIANGLE_DEGREE_5, GAUSS_LEGENDRE_4, 5, 2),
    wedge_point!(TRIANGLE_DEGREE_5, GAUSS_LEGENDRE_4, 6, 2),
    wedge_point!(TRIANGLE_DEGREE_5, GAUSS_LEGENDRE_4, 0, 3),
    wedge_point!(TRIANGLE_DEGREE_5, GAUSS_LEGENDRE_4, 1, 3),
    wedge_point!(TRIANGLE_DEGREE_5, GAUSS_LEGENDRE_4, 2, 3),
    wedge_point!(TRIANGLE_DEGREE_5, GAUSS_LEGENDRE_4, 3, 3),
    wedge_point!(TRIANGLE_DEGREE_5, GAUSS_LEGENDRE_4, 4, 3),
    wedge_point!(TRIANGLE_DEGREE_5, GAUSS_LEGENDRE_4, 5, 3),
    wedge_point!(TRIANGLE_DEGREE_5, GAUSS_LEGENDRE_4, 6, 3),
];

/// The rule on the reference pyramid (base [-1, 1]^2 at zeta = 0, apex (0, 0, 1); volume 4/3)
/// of the cube [-1, 1]^2 x [0, 1] collapsed onto it (Duffy): the Gauss points (a, b) of
/// `$base` and t of `$height` go to xi = (1 - z) a, eta = (1 - z) b, zeta = z = (1 + t) / 2
/// with the weight w_a w_b w_t (1 - z)^2 / 2 (a const item's initializer: a `const fn` may not
/// do float arithmetic at the crate's MSRV). Exact for every f(a, b, z) (1 - z)^2 whose f is
/// a polynomial of the rules' degrees in a and b and in z: the shape functions of a pyramid
/// are such polynomials, though rational in (xi, eta, zeta).
macro_rules! collapsed_pyramid_rule {
    ($base:expr, $height:expr, $n:literal) => {{
        let base = $base;
        let height = $height;
        let mut points = [QuadraturePoint { coordinates: [0.0; 3], weight: 0.0 }; $n];
        let mut k = 0;
        while k < height.len() {
            let z = 0.5 * (1.0 + height[k].0);
            let shrink = 1.0 - z;
            let mut j = 0;
            while j < base.len() {
                let mut i = 0;
                while i < base.len() {
                    points[(k * base.len() + j) * base.len() + i] = QuadraturePoint {
                        coordinates: [shrink * base[i].0, shrink * base[j].0, z],
                        weight: base[i].1 * base[j].1 * height[k].1 * 0.5 * shrink * shrink,
                    };
                    i += 1;
                }
                j += 1;
            }
            k += 1;
        }
        points
    }};
}

/// Reference pyramid: 2 x 2 x 2 collapsed Gauss points (exact to degree 3 in a, b and 1 in
/// z besides the weight's (1 - z)^2).
pub const PYRAMID_GAUSS_2_2: [QuadraturePoint; 8] =
    collapsed_pyramid_rule!(GAUSS_LEGENDRE_2, GAUSS_LEGENDRE_2, 8);

/// Reference pyramid: 2 x 2 Gauss points in (a, b) times 4 in z (exact to degree 3 in a, b
/// and 5 in z besides the weight's (1 - z)^2).
pub const PYRAMID_GAUSS_2_4: [QuadraturePoint; 16] =
    collapsed_pyramid_rule!(GAUSS_LEGENDRE_2, GAUSS_LEGENDRE_4, 16);

/// Reference pyramid: 3 x 3 x 3 collapsed Gauss points (exact to degree 5 in a, b and 3 in
/// z besides the weight's (1 - z)^2).
pub const PYRAMID_GAUSS_3_3: [QuadraturePoint; 27] =
    collapsed_pyramid_rule!(GAUSS_LEGENDRE_3, GAUSS_LEGENDRE_3, 27);

/// Reference pyramid: 3 x 3 Gauss points in (a, b) times 4 in z (exact to degree 5 in a, b
/// and 5 in z besides the weight's (1 - z)^2).
pub const PYRAMID_GAUSS_3_4: [QuadraturePoint; 36] =
    collapsed_pyramid_rule!(GAUSS_LEGENDRE_3, GAUSS_LEGENDRE_4, 36);

/// The tensor-product Gauss-Legendre rule on [-1, 1]^3 with `points_per_direction` points per
/// direction (1 to 4); exact for x^a y^b z^c with a, b, c <= 2 points_per_direction - 1.
pub fn hexahedron_rule(points_per_direction: usize) -> Option<&'static [QuadraturePoint]> {
    match points_per_direction {
        1 => Some(&HEXAHEDRON_GAUSS_1),
        2 => Some(&HEXAHEDRON_GAUSS_2),
        3 => Some(&HEXAHEDRON_GAUSS_3),
        4 => Some(&HEXAHEDRON_GAUSS_4),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::assert_close;

    fn factorial(n: u32) -> f64 {
        (1..=n).map(f64::from).product()
    }

    /// Integral of x^a y^b z^c over the reference tetrahedron: a! b! c! / (a + b + c + 3)!.
    fn tetrahedron_monomial(a: u32, b: u32, c: u32) -> f64 {
        factorial(a) * factorial(b) * factorial(c) / factorial(a + b + c + 3)
    }

    /// Integral of x^a over [-1, 1].
    fn interval_monomial(a: u32) -> f64 {
        if a % 2 == 1 {
            0.0
        } else {
            2.0 / f64::from(a + 1)
        }
    }

    fn apply(rule: &[QuadraturePoint], a: u32, b: u32, c: u32) -> f64 {
        rule.iter()
            .map(|p| {
                let [x, y, z] = p.coordinates;
                p.weight * x.powi(a as i32) * y.powi(b as i32) * z.powi(c as i32)
            })
            .sum()
    }

    /// Largest relative error over the monomials of total degree `degree`.
    fn worst_error_at_degree(rule: &[QuadraturePoint], degree: u32) -> f64 {
        let mut worst: f64 = 0.0;
        for a in 0..=degree {
            for b in 0..=degree - a {
                let c = degree - a - b;
                let exact = tetrahedron_monomial(a, b, c);
                worst = worst.max((apply(rule, a, b, c) - exact).abs() / exact);
            }
        }
        worst
    }

    const TETRAHEDRON_RULES: [(&[QuadraturePoint], u32); 4] = [
        (&TETRAHEDRON_DEGREE_1, 1),
        (&TETRAHEDRON_DEGREE_2, 2),
        (&TETRAHEDRON_DEGREE_3, 3),
        (&TETRAHEDRON_DEGREE_5, 5),
    ];

    #[test]
    fn tetrahedron_rules_are_exact_up_to_their_degree() {
        for (rule, degree) in TETRAHEDRON_RULES {
            let total: f64 = rule.iter().map(|p| p.weight).sum();
            assert_close(total, 1.0 / 6.0, 0.0, 1e-15, format_args!("degree {degree}: sum of weights"));
            for d in 0..=degree {
                let error = worst_error_at_degree(rule, d);
                assert!(error < 1e-12, "degree {degree} rule at degree {d}: relative error {error}");
            }
            // The claimed degree is the true degree: the next one is not integrated exactly.
            let error = worst_error_at_degree(rule, degree + 1);
            assert!(error > 1e-3, "degree {degree} rule is exact at degree {}", degree + 1);
        }
    }

    #[test]
    fn tetrahedron_rules_have_positive_weights_and_points_in_the_cell() {
        for (rule, degree) in TETRAHEDRON_RULES {
            for (i, p) in rule.iter().enumerate() {
                let [x, y, z] = p.coordinates;
                let smallest = x.min(y).min(z).min(1.0 - x - y - z);
                assert!(p.weight > 0.0, "degree {degree}, point {i}: weight {}", p.weight);
                assert!(smallest > -1e-15, "degree {degree}, point {i} outside: {:?}", p.coordinates);
            }
        }
    }

    #[test]
    fn tetrahedron_rule_selection_meets_the_degree() {
        for degree in 0..=5 {
            let rule = tetrahedron_rule(degree).unwrap();
            for d in 0..=degree as u32 {
                assert!(worst_error_at_degree(rule, d) < 1e-12);
            }
        }
        assert!(tetrahedron_rule(6).is_none());
        assert_eq!(tetrahedron_rule(2).unwrap().len(), 4);
    }

    #[test]
    fn gauss_legendre_rules_are_exact_to_degree_2n_minus_1() {
        for n in 1..=4usize {
            let rule = gauss_legendre_rule(n).unwrap();
            assert_eq!(rule.len(), n);
            for a in 0..=(2 * n as u32 - 1) {
                let q: f64 = rule.iter().map(|&(x, w)| w * x.powi(a as i32)).sum();
                assert_close(q, interval_monomial(a), 0.0, 1e-14, format_args!("{n} points, x^{a}"));
            }
            let a = 2 * n as u32;
            let q: f64 = rule.iter().map(|&(x, w)| w * x.powi(a as i32)).sum();
            assert!((q - interval_monomial(a)).abs() > 1e-3, "{n} points exact at degree {a}");
        }
        assert!(gauss_legendre_rule(5).is_none());
    }

    #[test]
    fn triangle_and_wedge_rules_are_exact_to_their_degrees() {
        // int over the triangle of u^i v^j = i! j! / (i + j + 2)!.
        let triangle = |i: u32, j: u32| factorial(i) * factorial(j) / factorial(i + j + 2);
        for (rule, degree) in
            [(&TRIANGLE_DEGREE_2[..], 2u32), (&TRIANGLE_DEGREE_4[..], 4), (&TRIANGLE_DEGREE_5[..], 5)]
        {
            for i in 0..=degree {
                for j in 0..=degree - i {
                    let q: f64 = rule.iter().map(|&(u, v, w)| w * u.powi(i as i32) * v.powi(j as i32)).sum();
                    assert_close(q, triangle(i, j), 0.0, 1e-14, format_args!("degree {degree}: u^{i} v^{j}"));
                }
            }
            assert!(rule.iter().all(|&(u, v, w)| u > 0.0 && v > 0.0 && u + v < 1.0 && w > 0.0));
        }
        for (rule, degree, line) in [
            (&WEDGE_TRIANGLE_2_GAUSS_2[..], 2u32, 3u32),
            (&WEDGE_TRIANGLE_4_GAUSS_3[..], 4, 5),
            (&WEDGE_TRIANGLE_5_GAUSS_4[..], 5, 7),
        ] {
            for i in 0..=degree {
                for j in 0..=degree - i {
                    for k in 0..=line {
                        let exact = triangle(i, j) * interval_monomial(k);
                        let q = apply(rule, i, j, k);
                        assert_close(q, exact, 0.0, 1e-14, format_args!("wedge: u^{i} v^{j} w^{k}"));
                    }
                }
            }
        }
    }

    #[test]
    fn pyramid_rules_are_exact_for_their_collapsed_degrees() {
        // int over the pyramid of xi^i eta^j zeta^k, for even i and j, is
        // int_0^1 (1 - z)^(i + j + 2) z^k dz * 2/(i + 1) * 2/(j + 1) (zero for odd i or j),
        // and the beta integral int_0^1 (1 - z)^m z^k dz = m! k! / (m + k + 1)!.
        let exact = |i: u32, j: u32, k: u32| {
            interval_monomial(i) * interval_monomial(j) * factorial(i + j + 2) * factorial(k)
                / factorial(i + j + k + 3)
        };
        for (rule, base, height) in [
            (&PYRAMID_GAUSS_2_2[..], 2u32, 2u32),
            (&PYRAMID_GAUSS_2_4[..], 2, 4),
            (&PYRAMID_GAUSS_3_3[..], 3, 3),
            (&PYRAMID_GAUSS_3_4[..], 3, 4),
        ] {
            let total: f64 = rule.iter().map(|p| p.weight).sum();
            assert_close(total, 4.0 / 3.0, 0.0, 4e-15, format_args!("{height} points in z: volume"));
            for p in rule {
                let [x, y, z] = p.coordinates;
                assert!(p.weight > 0.0 && z > 0.0 && z < 1.0 && x.abs() < 1.0 - z && y.abs() < 1.0 - z);
            }
            // xi^i eta^j zeta^k = a^i b^j (1 - z)^(i + j) z^k: exact while i, j <= 2 base - 1
            // and i + j + k + 2 <= 2 height - 1 (the rule's degree in z).
            for i in 0..2 * base {
                for j in (0..2 * base).filter(|j| i + j + 2 < 2 * height) {
                    for k in 0..=2 * height - 1 - (i + j + 2) {
                        let q = apply(rule, i, j, k);
                        assert_close(q, exact(i, j, k), 0.0, 1e-14, format_args!("xi^{i} eta^{j} zeta^{k}"));
                    }
                }
            }
            // ... and not beyond it in z.
            let k = 2 * height - 2;
            assert!((apply(rule, 0, 0, k) - exact(0, 0, k)).abs() > 1e-6, "{height} points: zeta^{k}");
            // In the collapsed coordinates a = xi / (1 - z), b = eta / (1 - z): a^i b^j z^k
            // (1 - z)^2 exact while i, j <= 2 base - 1 and k + 2 <= 2 height - 1, with
            // int_0^1 z^k (1 - z)^2 dz = 2 k! / (k + 3)!; not at a^(2 base).
            let collapsed = |i: u32, j: u32, k: u32| -> f64 {
                rule.iter()
                    .map(|p| {
                        let [x, y, z] = p.coordinates;
                        let (a, b) = (x / (1.0 - z), y / (1.0 - z));
                        p.weight * a.powi(i as i32) * b.powi(j as i32) * z.powi(k as i32)
                    })
                    .sum()
            };
            let beta = |k: u32| 2.0 * factorial(k) / factorial(k + 3);
            for i in 0..2 * base {
                for j in 0..2 * base {
                    for k in 0..2 * height - 2 {
                        let expected = interval_monomial(i) * interval_monomial(j) * beta(k);
                        let q = collapsed(i, j, k);
                        assert_close(q, expected, 0.0, 1e-14, format_args!("a^{i} b^{j} z^{k}"));
                    }
                }
            }
            let i = 2 * base;
            let miss = (collapsed(i, 0, 0) - interval_monomial(i) * interval_monomial(0) * beta(0)).abs();
            assert!(miss > 1e-6, "{base} points in a: a^{i}");
        }
    }

    #[test]
    fn hexahedron_rules_are_exact_per_direction() {
        for n in 1..=4usize {
            let rule = hexahedron_rule(n).unwrap();
            assert_eq!(rule.len(), n * n * n);
            let total: f64 = rule.iter().map(|p| p.weight).sum();
            assert_close(total, 8.0, 0.0, 1e-14, format_args!("{n} points per direction: sum of weights"));
            let top = 2 * n as u32 - 1;
            for a in 0..=top {
                for b in 0..=top {
                    for c in 0..=top {
                        let exact = interval_monomial(a) * interval_monomial(b) * interval_monomial(c);
                        let q = apply(rule, a, b, c);
                        let scale = exact.abs().max(1.0);
                        assert_close(
                            q,
                            exact,
                            0.0,
                            1e-12 * scale,
                            format_args!("{n} points: x^{a} y^{b} z^{c}"),
                        );
                    }
                }
            }
            // The tensor rule matches the 1-D rule it is built from.
            let line = gauss_legendre_rule(n).unwrap();
            for (index, p) in rule.iter().enumerate() {
                let (i, j, k) = (index % n, (index / n) % n, index / (n * n));
                assert_eq!(p.coordinates, [line[i].0, line[j].0, line[k].0]);
                assert_close(
                    p.weight,
                    line[i].1 * line[j].1 * line[k].1,
                    0.0,
                    1e-15,
                    format_args!("weight {index}"),
                );
            }
        }
        assert!(hexahedron_rule(0).is_none());
    }
}
