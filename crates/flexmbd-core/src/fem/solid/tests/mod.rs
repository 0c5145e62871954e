//! Tests of the solid elements against independent results: exact moments of tetrahedra and
//! of trilinear hexahedra (by the divergence theorem), closed-form mass fractions, rigid-body
//! modes, patch tests, and the degenerate and invalid elements they must refuse. This file
//! holds the test elements and helpers, and the tests of the shape functions.

use super::geometry::physical_gradients;
use super::matrices::strain_displacement;
use super::*;
use crate::fem::element::{mass_matrix, ElementError};
use crate::fem::quadrature::{GAUSS_LEGENDRE_3, TRIANGLE_DEGREE_4};
use crate::math::Mat3;
use crate::testing::{assert_all_close, assert_close};

mod incompatible;
mod mass;
mod stiffness;
mod validation;

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
    /// [`Hex8Incompatible`], on the same shapes as Hex8.
    Hex8I,
    /// [`Hex20`] and [`Hex20Reduced`], on the same shapes as Hex8 (mid-edge nodes at the
    /// edges' midpoints).
    Hex20,
    Hex20R,
    /// [`Hex27`] on the shapes of Hex8 (edge, face and centre nodes where the trilinear map
    /// puts them).
    Hex27,
    Wedge6,
    /// [`Wedge15`] on the shapes of Wedge6 (mid-edge nodes at the edges' midpoints).
    Wedge15,
    /// [`Wedge18`] on the shapes of Wedge6 (mid-edge and face nodes where the map of Wedge6
    /// puts them).
    Wedge18,
    Pyramid5,
    /// [`Pyramid13`] and [`Pyramid14`] on the shapes of Pyramid5 (mid-edge nodes at the edges'
    /// midpoints, the base's centre the mean of its corners).
    Pyramid13,
    Pyramid14,
}

fn element(kind: Kind) -> &'static dyn ElementKernel {
    match kind {
        Kind::Tet4 => &Tet4,
        Kind::Tet10 => &Tet10,
        Kind::Hex8 => &Hex8,
        Kind::Hex8I => &Hex8Incompatible,
        Kind::Hex20 => &Hex20,
        Kind::Hex20R => &Hex20Reduced,
        Kind::Hex27 => &Hex27,
        Kind::Wedge6 => &Wedge6,
        Kind::Wedge15 => &Wedge15,
        Kind::Wedge18 => &Wedge18,
        Kind::Pyramid5 => &Pyramid5,
        Kind::Pyramid13 => &Pyramid13,
        Kind::Pyramid14 => &Pyramid14,
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

/// A straight-sided quadratic element: the corners, then the midpoints of `edges`.
fn with_midpoints(corners: &[Vec3], edges: &[[usize; 2]]) -> Vec<Vec3> {
    let mut nodes = corners.to_vec();
    nodes.extend(edges.iter().map(|&[p, q]| 0.5 * (corners[p] + corners[q])));
    nodes
}

/// A straight-sided Tet10: the vertices and the midpoints of the edges.
fn tet10_from(vertices: &[Vec3]) -> Vec<Vec3> {
    with_midpoints(vertices, &TET10_EDGES)
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
        .map(|s| origin + (0.5 * (s[0] + 1.0)) * e1 + (0.5 * (s[1] + 1.0)) * e2 + (0.5 * (s[2] + 1.0)) * e3)
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

/// Exact moments of a region bounded by flat triangles and bilinear quadrilaterals (the
/// faces `faces` of the nodes `x`, counter-clockwise seen from outside) by the divergence
/// theorem, as `hexahedron_moments`: the degree-4 triangle rule and 3 x 3 Gauss on the faces
/// are exact for p (x . n) dA with p of degree 2.
fn polyhedron_moments(x: &[Vec3], faces: &[&[usize]]) -> Moments {
    let mut m = Moments { volume: 0.0, first: Vec3::ZERO, second: [[0.0; 3]; 3] };
    let mut add = |p: Vec3, da: Vec3| {
        let flux = p.dot(&da);
        m.volume += flux / 3.0;
        m.first += (flux / 4.0) * p;
        for k in 0..3 {
            for l in 0..3 {
                m.second[k][l] += flux / 5.0 * p[k] * p[l];
            }
        }
    };
    for face in faces {
        if let [a, b, c] = face[..] {
            let normal = (x[b] - x[a]).cross(&(x[c] - x[a]));
            for &(u, v, w) in &TRIANGLE_DEGREE_4 {
                add(x[a] + u * (x[b] - x[a]) + v * (x[c] - x[a]), w * normal);
            }
            continue;
        }
        for &(s, ws) in &GAUSS_LEGENDRE_3 {
            for &(t, wt) in &GAUSS_LEGENDRE_3 {
                let (mut p, mut ds, mut dt) = (Vec3::ZERO, Vec3::ZERO, Vec3::ZERO);
                for (i, c) in FACE_CORNERS.iter().enumerate() {
                    let xi = x[face[i]];
                    p += (0.25 * (1.0 + s * c[0]) * (1.0 + t * c[1])) * xi;
                    ds += (0.25 * c[0] * (1.0 + t * c[1])) * xi;
                    dt += (0.25 * c[1] * (1.0 + s * c[0])) * xi;
                }
                add(p, (ws * wt) * ds.cross(&dt));
            }
        }
    }
    m
}

/// The faces of a wedge and of a pyramid, counter-clockwise seen from outside.
const WEDGE_FACES: [&[usize]; 5] = [&[0, 2, 1], &[3, 4, 5], &[0, 1, 4, 3], &[1, 2, 5, 4], &[2, 0, 3, 5]];
const PYRAMID_FACES: [&[usize]; 5] = [&[0, 3, 2, 1], &[0, 1, 4], &[1, 2, 4], &[2, 3, 4], &[3, 0, 4]];

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
    let mut cases = vec![
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
    ];
    // The same hexahedra with incompatible modes: their mass is that of Hex8, and every affine
    // field leaves the modes at rest.
    let incompatible: Vec<Case> = cases
        .iter()
        .filter(|c| c.kind == Kind::Hex8)
        .map(|c| Case {
            name: match c.name {
                "unit cube Hex8" => "unit cube Hex8I",
                "box Hex8" => "box Hex8I",
                "parallelepiped Hex8" => "parallelepiped Hex8I",
                _ => "distorted Hex8I",
            },
            kind: Kind::Hex8I,
            nodes: c.nodes.clone(),
            moments: c.moments,
            fractions: c.fractions.clone(),
        })
        .collect();
    cases.extend(incompatible);
    // The same hexahedra with 20 nodes: the geometry (trilinear) is the same, so are the
    // moments; on the parallelepipeds (constant det J) the consistent-mass row sums are -1/8
    // of the mass at a corner and 1/6 at a mid-edge node, the HRZ masses 7/248 and 2/31
    // (int N_a^2 over the cube: 28/135 and 64/135).
    let quadratic: Vec<Case> = cases
        .iter()
        .filter(|c| c.kind == Kind::Hex8)
        .flat_map(|c| {
            let fractions = c.fractions.as_ref().map(|_| {
                let mut row_sums = vec![-1.0 / 8.0; 8];
                row_sums.extend([1.0 / 6.0; 12]);
                let mut lumped = vec![7.0 / 248.0; 8];
                lumped.extend([2.0 / 31.0; 12]);
                (row_sums, lumped)
            });
            let nodes = hex20_from(&c.nodes);
            let names = match c.name {
                "unit cube Hex8" => ["unit cube Hex20", "unit cube Hex20R"],
                "box Hex8" => ["box Hex20", "box Hex20R"],
                "parallelepiped Hex8" => ["parallelepiped Hex20", "parallelepiped Hex20R"],
                _ => ["distorted Hex20", "distorted Hex20R"],
            };
            [(Kind::Hex20, names[0]), (Kind::Hex20R, names[1])].map(|(kind, name)| Case {
                name,
                kind,
                nodes: nodes.clone(),
                moments: c.moments,
                fractions: fractions.clone(),
            })
        })
        .collect();
    cases.extend(quadratic);
    // And with 27 nodes: on the parallelepipeds the row sums are the products of the 1-D
    // ones (1/6 at an end, 2/3 in the middle): 1/216 of the mass at a corner, 4/216 at a
    // mid-edge node, 16/216 at a face's centre and 64/216 at the element's; the HRZ masses
    // the same (int l^2 over [-1, 1]: 4/15 at an end, 16/15 in the middle, also 1 : 4).
    let triquadratic: Vec<Case> = cases
        .iter()
        .filter(|c| c.kind == Kind::Hex8)
        .map(|c| {
            let fractions = c.fractions.as_ref().map(|_| {
                let mut sums = vec![1.0 / 216.0; 8];
                sums.extend([4.0 / 216.0; 12]);
                sums.extend([16.0 / 216.0; 6]);
                sums.push(64.0 / 216.0);
                (sums.clone(), sums)
            });
            let name = match c.name {
                "unit cube Hex8" => "unit cube Hex27",
                "box Hex8" => "box Hex27",
                "parallelepiped Hex8" => "parallelepiped Hex27",
                _ => "distorted Hex27",
            };
            Case { name, kind: Kind::Hex27, nodes: hex27_from(&c.nodes), moments: c.moments, fractions }
        })
        .collect();
    cases.extend(triquadratic);
    // Wedges: a right prism, an oblique one (top triangle shifted: constant Jacobian, so each
    // node carries a sixth of the mass in both forms) and a distorted one. The exact moments
    // of the first two from three tetrahedra, of the third by the divergence theorem.
    let right = wedge([v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0)], v(0.0, 0.0, 1.0));
    let oblique = wedge([v(0.3, -0.2, 0.1), v(1.6, 0.1, 0.0), v(0.5, 1.2, 0.2)], v(0.2, 0.3, 0.9));
    let mut distorted = oblique.clone();
    distorted[4] += v(0.1, -0.05, 0.08);
    distorted[5] += v(-0.06, 0.1, -0.05);
    let sixth = Some((vec![1.0 / 6.0; 6], vec![1.0 / 6.0; 6]));
    for (name, nodes, fractions) in [
        ("right Wedge6", right, sixth.clone()),
        ("oblique Wedge6", oblique, sixth),
        ("distorted Wedge6", distorted, None),
    ] {
        // (the distorted one's by the divergence theorem: its side faces are not planar)
        let moments = match fractions {
            Some(_) => prism_moments(&nodes),
            None => polyhedron_moments(&nodes, &WEDGE_FACES),
        };
        cases.push(Case { name, kind: Kind::Wedge6, nodes, moments: Some(moments), fractions });
    }
    // The same wedges with 15 nodes (the geometry is the same, so are the moments). With a
    // constant Jacobian the consistent-mass row sums are -1/9 of the mass at a corner, 1/6 at
    // a triangle's mid-edge node and 2/9 at a vertical one; the HRZ masses 1/34, 4/51 and
    // 2/17 (int N_a^2 over the reference wedge: 1/90, 4/135 and 2/45; sympy).
    let quadratic: Vec<Case> = cases
        .iter()
        .filter(|c| c.kind == Kind::Wedge6)
        .map(|c| {
            let fractions = c.fractions.as_ref().map(|_| {
                let mut row_sums = vec![-1.0 / 9.0; 6];
                row_sums.extend([1.0 / 6.0; 6]);
                row_sums.extend([2.0 / 9.0; 3]);
                let mut lumped = vec![1.0 / 34.0; 6];
                lumped.extend([4.0 / 51.0; 6]);
                lumped.extend([2.0 / 17.0; 3]);
                (row_sums, lumped)
            });
            let name = match c.name {
                "right Wedge6" => "right Wedge15",
                "oblique Wedge6" => "oblique Wedge15",
                _ => "distorted Wedge15",
            };
            let nodes = with_midpoints(&c.nodes, &WEDGE15_EDGES);
            Case { name, kind: Kind::Wedge15, nodes, moments: c.moments, fractions }
        })
        .collect();
    cases.extend(quadratic);
    // And with 18 nodes: with a constant Jacobian the row sums are the products of the
    // quadratic triangle's (0 at a vertex, 1/3 at a mid-edge node) and the line's (1/6 at an
    // end, 2/3 in the middle): 0 at the corners and the vertical edges' nodes, 1/18 at the
    // triangles' mid-edge nodes, 2/9 at the faces' centres; the HRZ masses are proportional
    // to the products of int T^2 over the triangle (1/60 at a vertex, 4/45 at a mid-edge
    // node) and int l^2 over [-1, 1] (4/15 at an end, 16/15 in the middle): 1/114 at a
    // corner, 8/171 at a triangle's mid-edge node, 2/57 at a vertical edge's, 32/171 at a
    // face's centre (sympy).
    let lagrange: Vec<Case> = cases
        .iter()
        .filter(|c| c.kind == Kind::Wedge6)
        .map(|c| {
            let fractions = c.fractions.as_ref().map(|_| {
                let mut row_sums = vec![0.0; 6];
                row_sums.extend([1.0 / 18.0; 6]);
                row_sums.extend([0.0; 3]);
                row_sums.extend([2.0 / 9.0; 3]);
                let mut lumped = vec![1.0 / 114.0; 6];
                lumped.extend([8.0 / 171.0; 6]);
                lumped.extend([2.0 / 57.0; 3]);
                lumped.extend([32.0 / 171.0; 3]);
                (row_sums, lumped)
            });
            let name = match c.name {
                "right Wedge6" => "right Wedge18",
                "oblique Wedge6" => "oblique Wedge18",
                _ => "distorted Wedge18",
            };
            Case { name, kind: Kind::Wedge18, nodes: wedge18_from(&c.nodes), moments: c.moments, fractions }
        })
        .collect();
    cases.extend(lagrange);
    // Pyramids: a right one, an oblique one (parallelogram base, apex off its centre: constant
    // Jacobian, so the mass fractions of the reference pyramid, 3/16 at a base node and 1/4
    // at the apex, HRZ 2/11 and 3/11; sympy) and a distorted one (base not planar, not a
    // parallelogram). The exact moments of the first two from two tetrahedra, of the third by
    // the divergence theorem.
    let right =
        vec![v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(1.0, 1.0, 0.0), v(0.0, 1.0, 0.0), v(0.5, 0.5, 0.8)];
    let (corner, e1, e2) = (v(0.2, -0.1, 0.3), v(1.3, 0.2, -0.1), v(-0.3, 0.9, 0.2));
    let oblique = vec![corner, corner + e1, corner + e1 + e2, corner + e2, v(0.9, 0.1, 1.4)];
    let mut distorted = oblique.clone();
    distorted[2] += v(0.1, -0.05, 0.12);
    distorted[3] += v(-0.08, 0.06, -0.04);
    let fractions = Some((
        vec![3.0 / 16.0, 3.0 / 16.0, 3.0 / 16.0, 3.0 / 16.0, 0.25],
        vec![2.0 / 11.0, 2.0 / 11.0, 2.0 / 11.0, 2.0 / 11.0, 3.0 / 11.0],
    ));
    for (name, nodes, fractions) in [
        ("right Pyramid5", right, fractions.clone()),
        ("oblique Pyramid5", oblique, fractions),
        ("distorted Pyramid5", distorted, None),
    ] {
        let moments = match fractions {
            Some(_) => pyramid_moments(&nodes),
            None => polyhedron_moments(&nodes, &PYRAMID_FACES),
        };
        cases.push(Case { name, kind: Kind::Pyramid5, nodes, moments: Some(moments), fractions });
    }
    // The same pyramids with 13 and 14 nodes (the geometry of Pyramid5, so the same moments).
    // With a constant Jacobian the row sums of the 13-node one are -7/80 of the mass at a
    // base corner, -1/20 at the apex, 1/5 at a base edge's node and 3/20 at an apex edge's,
    // its HRZ masses 11, 9, 48 and 32 in 373; those of the 14-node one -1/48, -1/20, 1/15,
    // 3/20 and 4/15 at the base's centre, HRZ 43/3078, 5/171, 32/513, 160/1539 and 128/513
    // (integrals of N and N^2 in the collapsed coordinates; sympy).
    let quadratic: Vec<Case> = cases
        .iter()
        .filter(|c| c.kind == Kind::Pyramid5)
        .flat_map(|c| {
            let with = |corner: f64, apex: f64, base: f64, side: f64, centre: Option<f64>| {
                let mut v = vec![corner; 4];
                v.push(apex);
                v.extend([base; 4]);
                v.extend([side; 4]);
                v.extend(centre);
                v
            };
            let fractions13 = c.fractions.as_ref().map(|_| {
                let hrz = with(11.0, 9.0, 48.0, 32.0, None).iter().map(|m| m / 373.0).collect();
                (with(-7.0 / 80.0, -1.0 / 20.0, 0.2, 0.15, None), hrz)
            });
            let fractions14 = c.fractions.as_ref().map(|_| {
                let hrz = with(43.0 / 3078.0, 5.0 / 171.0, 32.0 / 513.0, 160.0 / 1539.0, Some(128.0 / 513.0));
                (with(-1.0 / 48.0, -1.0 / 20.0, 1.0 / 15.0, 0.15, Some(4.0 / 15.0)), hrz)
            });
            let names = match c.name {
                "right Pyramid5" => ["right Pyramid13", "right Pyramid14"],
                "oblique Pyramid5" => ["oblique Pyramid13", "oblique Pyramid14"],
                _ => ["distorted Pyramid13", "distorted Pyramid14"],
            };
            let nodes13 = with_midpoints(&c.nodes, &PYRAMID13_EDGES);
            let mut nodes14 = nodes13.clone();
            nodes14.push(0.25 * (c.nodes[0] + c.nodes[1] + c.nodes[2] + c.nodes[3]));
            [
                Case {
                    name: names[0],
                    kind: Kind::Pyramid13,
                    nodes: nodes13,
                    moments: c.moments,
                    fractions: fractions13,
                },
                Case {
                    name: names[1],
                    kind: Kind::Pyramid14,
                    nodes: nodes14,
                    moments: c.moments,
                    fractions: fractions14,
                },
            ]
        })
        .collect();
    cases.extend(quadratic);
    cases
}

/// A Wedge18 of the geometry of the Wedge6 `corners`: the Wedge15's nodes, then the means of
/// the corners of each quadrilateral face.
fn wedge18_from(corners: &[Vec3]) -> Vec<Vec3> {
    let mut nodes = with_midpoints(corners, &WEDGE15_EDGES);
    nodes.extend(
        WEDGE18_FACES.iter().map(|f| 0.25 * (corners[f[0]] + corners[f[1]] + corners[f[2]] + corners[f[3]])),
    );
    nodes
}

/// Moments of a pyramid with a planar base: the tetrahedra (0,1,2,4) and (0,2,3,4).
fn pyramid_moments(x: &[Vec3]) -> Moments {
    tetrahedra_moments(x, &[[0, 1, 2, 4], [0, 2, 3, 4]])
}

/// A wedge over the triangle `bottom` (counter-clockwise seen from the side of `height`),
/// its top triangle shifted by `height`.
fn wedge(bottom: [Vec3; 3], height: Vec3) -> Vec<Vec3> {
    let mut nodes = bottom.to_vec();
    nodes.extend(bottom.iter().map(|p| *p + height));
    nodes
}

/// Moments of a prism with planar faces: the tetrahedra (0,1,2,3), (1,2,3,4), (2,3,4,5).
fn prism_moments(x: &[Vec3]) -> Moments {
    tetrahedra_moments(x, &[[0, 1, 2, 3], [1, 2, 3, 4], [2, 3, 4, 5]])
}

/// The sum of the moments of the tetrahedra `tets` of the nodes `x` (each turned positive).
fn tetrahedra_moments(x: &[Vec3], tets: &[[usize; 4]]) -> Moments {
    let mut total = Moments { volume: 0.0, first: Vec3::ZERO, second: [[0.0; 3]; 3] };
    for tet in tets {
        let mut corners: Vec<Vec3> = tet.iter().map(|&a| x[a]).collect();
        if (corners[1] - corners[0]).dot(&(corners[2] - corners[0]).cross(&(corners[3] - corners[0]))) < 0.0 {
            corners.swap(1, 2);
        }
        let m = tetrahedron_moments(&corners);
        total.volume += m.volume;
        total.first += m.first;
        for k in 0..3 {
            for l in 0..3 {
                total.second[k][l] += m.second[k][l];
            }
        }
    }
    total
}

/// A Hex27 of the trilinear geometry of the Hex8 `corners`: the Hex20's nodes, then the
/// means of each face's corners and of all eight.
fn hex27_from(corners: &[Vec3]) -> Vec<Vec3> {
    let mut nodes = hex20_from(corners);
    for centre in &Hex27::NODES[20..] {
        let on = |a: &usize| (0..3).all(|k| centre[k] == 0.0 || Hex8::NODES[*a][k] == centre[k]);
        let members: Vec<usize> = (0..8).filter(on).collect();
        let sum = members.iter().fold(Vec3::ZERO, |s, &a| s + corners[a]);
        nodes.push((1.0 / members.len() as f64) * sum);
    }
    nodes
}

/// A straight-edged Hex20: the corners and the midpoints of the edges.
fn hex20_from(corners: &[Vec3]) -> Vec<Vec3> {
    with_midpoints(corners, &HEX20_EDGES)
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
pub(crate) fn symmetric_eigenvalues(m: &DenseMatrix) -> Vec<f64> {
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
            let expected: [f64; N] = std::array::from_fn(|b| if a == b { 1.0 } else { 0.0 });
            assert_all_close(&n, &expected, 0.0, 1e-15, format_args!("{} N at node {a}", E::NAME));
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
            let fd: [f64; N] = std::array::from_fn(|a| (np[a] - nm[a]) / (2.0 * h));
            assert_all_close(&g.map(|row| row[j]), &fd, 0.0, 1e-8, format_args!("{} dN/dxi_{j}", E::NAME));
        }
    }
    check::<Tet4, 4>();
    check::<Tet10, 10>();
    check::<Hex8, 8>();
    check::<Hex20, 20>();
    check::<Hex27, 27>();
    check::<Wedge6, 6>();
    check::<Wedge15, 15>();
    check::<Wedge18, 18>();
    check::<Pyramid5, 5>();
    check::<Pyramid13, 13>();
    check::<Pyramid14, 14>();
}

#[test]
fn pyramid5_holds_linear_fields_and_meets_tetrahedra_and_hexahedra() {
    // Every linear field is interpolated exactly (the rational term cancels on it).
    let f = |p: [f64; 3]| 0.3 - 1.2 * p[0] + 0.7 * p[1] + 2.1 * p[2];
    let values: Vec<f64> = Pyramid5::NODES.iter().map(|&p| f(p)).collect();
    for xi in [[0.21, -0.17, 0.33], [-0.5, 0.4, 0.05], [0.01, 0.02, 0.97], [0.0, 0.0, 1.0]] {
        let n = Pyramid5::shape_functions(xi);
        let sum: f64 = n.iter().sum();
        let value: f64 = n.iter().zip(&values).map(|(a, b)| a * b).sum();
        assert_close(sum, 1.0, 0.0, 1e-15, format_args!("sum of N at {xi:?}"));
        assert_close(value, f(xi), 0.0, 1e-14, format_args!("linear field at {xi:?}"));
    }
    // On a triangular face the functions are those of the face's linear triangle (as the
    // tetrahedron's): for the face (1, 2, 4) (xi = 1 - zeta), barycentric weights of its
    // corners; the other nodes' functions vanish there.
    let (p1, p2, p4) = (Pyramid5::NODES[1], Pyramid5::NODES[2], Pyramid5::NODES[4]);
    for (s, t) in [(0.2, 0.3), (0.6, 0.1), (0.05, 0.9)] {
        let xi: [f64; 3] = std::array::from_fn(|k| (1.0 - s - t) * p1[k] + s * p2[k] + t * p4[k]);
        let n = Pyramid5::shape_functions(xi);
        assert_all_close(&n, &[0.0, 1.0 - s - t, s, 0.0, t], 0.0, 1e-15, format_args!("face at {xi:?}"));
    }
    // On the base, the bilinear functions of the hexahedron's face.
    for (x, y) in [(0.3, -0.6), (-0.9, 0.2)] {
        let n = Pyramid5::shape_functions([x, y, 0.0]);
        let h = Hex8::shape_functions([x, y, -1.0]);
        assert_all_close(&n[..4], &h[..4], 0.0, 1e-15, format_args!("base at ({x}, {y})"));
        assert_eq!(n[4], 0.0);
    }
}

#[test]
fn wedge15_interpolates_every_quadratic_field() {
    // The serendipity wedge holds the complete quadratic polynomials in (u, v, w): a
    // quadratic taken at the nodes is interpolated exactly inside.
    let f = |p: [f64; 3]| {
        let [u, v, w] = p;
        1.0 + 2.0 * u - v + 0.5 * w + 3.0 * u * u - 2.0 * u * v + v * v + 0.7 * u * w - 1.1 * v * w
            + 0.9 * w * w
    };
    let values: Vec<f64> = Wedge15::NODES.iter().map(|&p| f(p)).collect();
    for xi in [[0.2, 0.3, -0.4], [0.6, 0.1, 0.8], [0.05, 0.9, 0.0]] {
        let n = Wedge15::shape_functions(xi);
        let interpolated: f64 = n.iter().zip(&values).map(|(a, b)| a * b).sum();
        assert_close(interpolated, f(xi), 0.0, 1e-14, format_args!("quadratic at {xi:?}"));
    }
    // The mid-edge nodes are the midpoints of their edges.
    for (e, [p, q]) in WEDGE15_EDGES.iter().enumerate() {
        let mid: [f64; 3] = std::array::from_fn(|j| 0.5 * (Wedge6::NODES[*p][j] + Wedge6::NODES[*q][j]));
        assert_eq!(mid, Wedge15::NODES[6 + e]);
    }
}

#[test]
fn wedge18_interpolates_every_product_of_quadratics() {
    // The Lagrange wedge holds p(u, v) q(w) for every quadratic p and q (u^2 w^2, u v w^2, ...);
    // the serendipity Wedge15 holds the complete quadratics only.
    let f = |p: [f64; 3]| {
        let [u, v, w] = p;
        1.0 + 2.0 * u - v + 0.5 * w + 3.0 * u * u - 2.0 * u * v + v * v + 0.7 * u * w - 1.1 * v * w
            + 0.9 * w * w
            - 1.3 * u * u * w * w
            + 0.8 * u * v * w * w
            + 0.6 * v * v * w
            - 0.4 * v * w * w
    };
    let values: Vec<f64> = Wedge18::NODES.iter().map(|&p| f(p)).collect();
    let serendipity: Vec<f64> = Wedge15::NODES.iter().map(|&p| f(p)).collect();
    let mut missed: f64 = 0.0;
    for xi in [[0.2, 0.3, -0.4], [0.6, 0.1, 0.8], [0.05, 0.9, 0.0], [0.3, 0.3, 0.55]] {
        let n = Wedge18::shape_functions(xi);
        let sum: f64 = n.iter().sum();
        assert_close(sum, 1.0, 0.0, 1e-15, format_args!("sum of N at {xi:?}"));
        let interpolated: f64 = n.iter().zip(&values).map(|(a, b)| a * b).sum();
        assert_close(interpolated, f(xi), 0.0, 1e-14, format_args!("biquadratic at {xi:?}"));
        let by_wedge15: f64 = Wedge15::shape_functions(xi).iter().zip(&serendipity).map(|(a, b)| a * b).sum();
        missed = missed.max((by_wedge15 - f(xi)).abs());
    }
    assert!(missed > 1e-3, "wedge15 interpolates u^2 w^2 ({missed})");
    // Nodes 0..14 are Wedge15's; 15..17 the centres of the faces (0,1,4,3), (1,2,5,4), (2,0,3,5).
    assert_eq!(Wedge18::NODES[..15], Wedge15::NODES);
    for (f, face) in WEDGE18_FACES.iter().enumerate() {
        let centre: [f64; 3] =
            std::array::from_fn(|k| face.iter().map(|&a| Wedge6::NODES[a][k]).sum::<f64>() / 4.0);
        assert_eq!(centre, Wedge18::NODES[15 + f], "face {face:?}");
    }
    // On a quadrilateral face the functions are the 9-node Lagrange quadrilateral's (those of
    // Hex27's face eta = -1 for the face (0,1,4,3): u along xi, w along zeta), and on the
    // triangles the 6-node triangle's (zero for the other nodes): the faces of hex27 and tet10.
    let on_face = [(0, 0), (1, 1), (4, 5), (3, 4), (6, 8), (13, 17), (9, 12), (12, 16), (15, 22)];
    for (u, w) in [(0.3, -0.6), (0.85, 0.2)] {
        let n = Wedge18::shape_functions([u, 0.0, w]);
        let h = Hex27::shape_functions([2.0 * u - 1.0, -1.0, w]);
        for a in 0..18 {
            let expected = on_face.iter().find(|(b, _)| *b == a).map_or(0.0, |&(_, c)| h[c]);
            assert_close(n[a], expected, 0.0, 1e-15, format_args!("face (0,1,4,3) at ({u}, {w}): N_{a}"));
        }
    }
    for (u, v) in [(0.2, 0.3), (0.6, 0.1)] {
        let n = Wedge18::shape_functions([u, v, 1.0]);
        let t = Tet10::shape_functions([u, v, 0.0]);
        // Top triangle 3, 4, 5 with mid-edge nodes 9, 10, 11 against Tet10's face 0, 1, 2 with
        // the mid-edge nodes 4 (0,1), 5 (1,2), 6 (0,2).
        let expected: Vec<f64> = (0..18)
            .map(|a| match a {
                3..=5 => t[a - 3],
                9..=11 => t[a - 5],
                _ => 0.0,
            })
            .collect();
        assert_all_close(&n, &expected, 0.0, 1e-15, format_args!("top triangle at ({u}, {v})"));
    }
}

#[test]
fn quadratic_pyramids_hold_quadratic_fields_and_meet_tetrahedra_and_hexahedra() {
    // Every quadratic field is interpolated exactly; Pyramid14 also holds xi^2 eta^2 /
    // (1 - zeta)^2 (a^2 b^2 in the collapsed coordinates), Pyramid13 does not.
    let f = |p: [f64; 3]| {
        let [x, y, z] = p;
        0.3 - 1.2 * x + 0.7 * y + 2.1 * z + 0.4 * x * x - 0.9 * y * y + 1.3 * z * z + 0.6 * x * y
            - 0.8 * x * z
            + 1.1 * y * z
    };
    let bubble = |p: [f64; 3]| if p[2] < 1.0 { (p[0] * p[1] / (1.0 - p[2])).powi(2) } else { 0.0 };
    let points =
        [[0.21, -0.17, 0.33], [-0.5, 0.4, 0.05], [0.01, 0.02, 0.97], [0.0, 0.0, 1.0], [0.6, -0.3, 0.2]];
    let mut missed: f64 = 0.0;
    for xi in points {
        let n13 = Pyramid13::shape_functions(xi);
        let n14 = Pyramid14::shape_functions(xi);
        for (name, n) in [("pyramid13", &n13[..]), ("pyramid14", &n14[..])] {
            let nodes: &[[f64; 3]] = if n.len() == 13 { &Pyramid13::NODES } else { &Pyramid14::NODES };
            let sum: f64 = n.iter().sum();
            assert_close(sum, 1.0, 0.0, 1e-14, format_args!("{name}: sum of N at {xi:?}"));
            let value: f64 = n.iter().zip(nodes).map(|(a, p)| a * f(*p)).sum();
            assert_close(value, f(xi), 0.0, 1e-14, format_args!("{name}: quadratic field at {xi:?}"));
        }
        let with_centre: f64 = n14.iter().zip(&Pyramid14::NODES).map(|(a, p)| a * bubble(*p)).sum();
        assert_close(with_centre, bubble(xi), 0.0, 1e-14, format_args!("pyramid14: a^2 b^2 at {xi:?}"));
        let without: f64 = n13.iter().zip(&Pyramid13::NODES).map(|(a, p)| a * bubble(*p)).sum();
        missed = missed.max((without - bubble(xi)).abs());
    }
    assert!(missed > 1e-3, "pyramid13 interpolates a^2 b^2 ({missed})");
    // On a triangular face the functions are the 6-node triangle's (as Tet10's faces): for the
    // face (1, 2, 4) with its mid-edge nodes 6 (1,2), 10 (1,4) and 11 (2,4); the other nodes'
    // functions vanish there.
    let (p1, p2, p4) = (Pyramid5::NODES[1], Pyramid5::NODES[2], Pyramid5::NODES[4]);
    for (s, t) in [(0.2, 0.3), (0.6, 0.1), (0.05, 0.9)] {
        let xi: [f64; 3] = std::array::from_fn(|k| (1.0 - s - t) * p1[k] + s * p2[k] + t * p4[k]);
        let l = [1.0 - s - t, s, t];
        let mut expected = [0.0; 14];
        for (node, k) in [(1, 0), (2, 1), (4, 2)] {
            expected[node] = l[k] * (2.0 * l[k] - 1.0);
        }
        for (node, i, j) in [(6, 0, 1), (10, 0, 2), (11, 1, 2)] {
            expected[node] = 4.0 * l[i] * l[j];
        }
        let n13 = Pyramid13::shape_functions(xi);
        assert_all_close(&n13, &expected[..13], 0.0, 1e-14, format_args!("pyramid13 face at {xi:?}"));
        let n14 = Pyramid14::shape_functions(xi);
        assert_all_close(&n14, &expected, 0.0, 1e-14, format_args!("pyramid14 face at {xi:?}"));
    }
    // On the base, the functions of Hex20's face zeta = -1 (8-node serendipity) and Hex27's
    // (9-node Lagrange, its centre the node 24); the apex's and the apex edges' vanish.
    for (x, y) in [(0.3, -0.6), (-0.9, 0.2)] {
        let n13 = Pyramid13::shape_functions([x, y, 0.0]);
        let n14 = Pyramid14::shape_functions([x, y, 0.0]);
        let h20 = Hex20::shape_functions([x, y, -1.0]);
        let h27 = Hex27::shape_functions([x, y, -1.0]);
        let face = [0, 1, 2, 3, 8, 9, 10, 11];
        let base = [0, 1, 2, 3, 5, 6, 7, 8];
        for (&a, &h) in base.iter().zip(&face) {
            assert_close(n13[a], h20[h], 0.0, 1e-15, format_args!("pyramid13 base at ({x}, {y}): N_{a}"));
            assert_close(n14[a], h27[h], 0.0, 1e-15, format_args!("pyramid14 base at ({x}, {y}): N_{a}"));
        }
        assert_close(n14[13], h27[24], 0.0, 1e-15, format_args!("pyramid14 base centre at ({x}, {y})"));
        for a in [4, 9, 10, 11, 12] {
            assert_eq!((n13[a], n14[a]), (0.0, 0.0), "node {a} on the base");
        }
    }
    // Nodes: the corners of Pyramid5, the midpoints of PYRAMID13_EDGES, the base's centre.
    assert_eq!(Pyramid13::NODES[..5], Pyramid5::NODES);
    for (e, [p, q]) in PYRAMID13_EDGES.iter().enumerate() {
        let mid: [f64; 3] = std::array::from_fn(|j| 0.5 * (Pyramid5::NODES[*p][j] + Pyramid5::NODES[*q][j]));
        assert_eq!(mid, Pyramid13::NODES[5 + e]);
    }
    assert_eq!(Pyramid14::NODES[..13], Pyramid13::NODES);
    assert_eq!(Pyramid14::NODES[13], [0.0; 3]);
    // Gradients near the apex (where d/dxi = D_a holds the cancelled 1 / (1 - z)) against
    // central differences, and at the apex the limit along the axis.
    fn near_apex<E: Isoparametric<N>, const N: usize>() {
        let h = 1e-7;
        for xi in [[0.02, -0.01, 0.95], [0.0, 0.0, 0.999]] {
            let g = E::reference_gradients(xi);
            for j in 0..3 {
                let (mut plus, mut minus) = (xi, xi);
                plus[j] += h;
                minus[j] -= h;
                let (np, nm) = (E::shape_functions(plus), E::shape_functions(minus));
                let fd: [f64; N] = std::array::from_fn(|a| (np[a] - nm[a]) / (2.0 * h));
                assert_all_close(
                    &g.map(|r| r[j]),
                    &fd,
                    0.0,
                    1e-6,
                    format_args!("{} at {xi:?}: d/dxi_{j}", E::NAME),
                );
            }
        }
        let axis = E::reference_gradients([0.0, 0.0, 1.0 - 1e-9]);
        let apex = E::reference_gradients([0.0, 0.0, 1.0]);
        assert_all_close(
            apex.as_flattened(),
            axis.as_flattened(),
            0.0,
            1e-7,
            format_args!("{} apex", E::NAME),
        );
    }
    near_apex::<Pyramid13, 13>();
    near_apex::<Pyramid14, 14>();
}

#[test]
fn hex27_interpolates_every_triquadratic_field() {
    // The Lagrange hexahedron holds x^i y^j z^k for i, j, k <= 2 (the serendipity Hex20 does
    // not: x^2 y^2 is not in its space).
    let f = |p: [f64; 3]| {
        let [x, y, z] = p;
        1.0 - x + 2.0 * y * z + 0.5 * x * x * y - 1.5 * x * x * y * y * z * z + 0.3 * y * y * z
    };
    let values: Vec<f64> = Hex27::NODES.iter().map(|&p| f(p)).collect();
    let serendipity: Vec<f64> = Hex20::NODES.iter().map(|&p| f(p)).collect();
    let mut missed: f64 = 0.0;
    for xi in [[0.2, 0.3, -0.4], [0.6, -0.1, 0.8], [-0.95, 0.9, 0.0]] {
        let interpolated: f64 = Hex27::shape_functions(xi).iter().zip(&values).map(|(a, b)| a * b).sum();
        assert_close(interpolated, f(xi), 0.0, 1e-14, format_args!("triquadratic at {xi:?}"));
        let by_hex20: f64 = Hex20::shape_functions(xi).iter().zip(&serendipity).map(|(a, b)| a * b).sum();
        missed = missed.max((by_hex20 - f(xi)).abs());
    }
    assert!(missed > 1e-3, "hex20 interpolates x^2 y^2 z^2 ({missed})");
    // Nodes 20..26: the faces' centres (VTK's order: xi -+1, eta -+1, zeta -+1), the centre.
    let expected = [[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]];
    assert_eq!(Hex27::NODES[20..25], expected);
    assert_eq!(Hex27::NODES[25..], [[0.0, 0.0, 1.0], [0.0, 0.0, 0.0]]);
    assert_eq!(Hex27::NODES[..20], Hex20::NODES);
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
                assert_close((u - t).norm(), 0.0, 0.0, 1e-14, format_args!("{}: |S t - t|", case.name));
            }
            // A translation stores no strain energy.
            let force = times(&k, &q);
            let zero = vec![0.0; force.len()];
            assert_all_close(&force, &zero, 0.0, RELATIVE * scale, format_args!("{}: K t", case.name));
        }
    }
}
