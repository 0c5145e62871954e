//! Flat shell elements: the 4-node quadrilateral (MITC4 plate bending) and the 3-node triangle
//! (DKT plate bending), each a plane-stress membrane plus a plate, with a drilling rotation.
//! Node coordinates: [u (3), theta (3)] per node in body axes, like beams.
//!
//! Element axes: the normal n of the mean plane (quadrilateral: (x3 - x1) x (x4 - x2);
//! triangle: (x2 - x1) x (x3 - x1)), e1 along the mean of the edges 1-2 and 4-3 (triangle: the
//! edge 1-2) projected onto that plane, e2 = n x e1. The stiffness uses the nodes projected onto
//! the mean plane, each tied to its node by a rigid offset (`Frame::heights`: a warped
//! quadrilateral is flat but keeps its rigid motions exactly; its warp should stay a few per
//! cent of its size); the mass uses the true bilinear surface. In element axes, with
//! local coordinates [u, v, w, theta_x, theta_y, theta_z] per node, a point at height z above
//! the mid-surface moves by u_mid + theta x (z n): u = u_mid + z theta_y, v = v_mid - z theta_x.
//! So the rotations of the normal are beta = (theta_y, -theta_x) (Kirchhoff: beta = -grad w).
//!
//! - Membrane: bilinear plane stress (2 x 2 Gauss) or the constant-strain triangle, with
//!   D_m = E t / (1 - nu^2) [[1, nu, 0], [nu, 1, 0], [0, 0, (1 - nu) / 2]] over
//!   (eps_xx, eps_yy, gamma_xy).
//! - Bending: curvatures kappa = (beta_x,x, beta_y,y, beta_x,y + beta_y,x) with
//!   D_b = D_m t^2 / 12. Quadrilateral: Mindlin plate (bilinear w, theta) with the MITC4
//!   assumed transverse shear of Bathe and Dvorkin (IJNME 21, 1985): the covariant shear
//!   strains g_r = w,r + beta . x,r and g_s are sampled at the edge midpoints (0, +-1) and
//!   (+-1, 0) and interpolated linearly across, shear stiffness kappa G t (kappa = 5/6); no
//!   shear locking of thin plates. Triangle: the discrete Kirchhoff triangle of Batoz, Bathe
//!   and Ho (IJNME 15, 1980), constructed as defined there: beta quadratic over the six
//!   corner and mid-edge values; beta = -grad w at the corners; at each mid-edge the
//!   tangential component is -w,s of the cubic Hermite w along the edge and the normal
//!   component the mean of the corners'. Kirchhoff: no transverse shear.
//! - Drilling: theta_z has no stiffness of its own in a flat element. A penalty
//!   (1/2) k_d sum_i (theta_z,i - omega)^2 ties each node's theta_z to the element's in-plane
//!   rotation omega = (v,x - u,y) / 2 at its centre (zero for rigid motions, so the element
//!   keeps its six rigid-body modes and passes the membrane patch test), with
//!   k_d = [`DRILLING_STIFFNESS`] D_b, D_b = E t^3 / (12 (1 - nu^2)): small beside the
//!   bending stiffness of a nodal rotation, large enough to leave the stiffness matrix regular.
//!
//! Mass points: at each in-plane quadrature point (2 x 2 Gauss; triangle: the 3 mid-edge
//! points, exact to degree 2) six points of a sixth of rho t dA each, at +-t/2 along n (they
//! integrate rho z^2 exactly: the rotary inertia rho t^3 / 12 per area about the in-plane
//! axes) and at +-d along e1 and e2 with d = [`DRILLING_ARM`] t / 2: a fictitious inertia of the
//! drilling rotation, rho t d^2 2/3 per area, so that the mass matrix is regular; it adds
//! rho t d^2 / 3 per area to the second moments in the plane and to the rotary inertia (a
//! relative 1e-4 of t^2/12). Each point moves with u(p) + theta(p) x r, r its offset from the
//! mid-surface point p, with u and theta interpolated bilinearly (triangle: linearly, also the
//! w of the DKT plate): rigid motions are exact. Lumped: the element mass in proportion to
//! int N_i^2 dA (HRZ; thirds for the triangle), each node's share at the same six offsets
//! around the node.

use crate::math::dense::DenseMatrix;
use crate::math::{Mat3, Vec3};

use crate::fem::element::{ElementError, ElementKernel, ElementResult, MassPoint};
use crate::fem::material::Material;
use crate::fem::quadrature::GAUSS_LEGENDRE_2;
use crate::fem::section::ShellSection;

/// The drilling penalty k_d as a fraction of the plate's bending stiffness D_b (N m).
pub const DRILLING_STIFFNESS: f64 = 1e-2;
/// The arm of the drilling inertia's mass points as a fraction of the half thickness.
pub const DRILLING_ARM: f64 = 1e-2;

/// Four-node flat shell (MITC4 plate, bilinear membrane); nodes counter-clockwise about the
/// normal (Gmsh and Abaqus S4 order).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShellQuad4 {
    /// Thickness and shear factor.
    pub section: ShellSection,
}

/// Three-node flat shell (DKT plate, constant-strain membrane).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShellTri3 {
    /// Thickness and shear factor.
    pub section: ShellSection,
}

/// Corners of the quadrilateral in its natural coordinates (r, s).
const QUAD_CORNERS: [[f64; 2]; 4] = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];
/// Local coordinates of a 4-node element (24 = 4 x 6); triangles use the first 18.
const MAX_DOFS: usize = 24;

/// A row of a strain-displacement matrix over local element coordinates.
type Row = [f64; MAX_DOFS];

/// Element axes and the projected node coordinates.
struct Frame {
    /// Rows: e1, e2, n in body coordinates.
    axes: Mat3,
    /// Node coordinates (x, y) in element axes, relative to the centroid of the nodes.
    local: Vec<[f64; 2]>,
    /// Heights d of the nodes above the mean plane (along n; zero for a flat element). The
    /// element works with the projected nodes p = x - d n, each tied rigidly to its node: its
    /// motion is u_p = u + theta x (p - x) = u + d n x theta, in element axes
    /// (u - d theta_y, v + d theta_x, w). Without that offset a warped quadrilateral strains
    /// under rigid rotations about its in-plane axes and locks.
    heights: Vec<f64>,
}

impl Frame {
    /// K <- T^T K T over the first `n` local coordinates, T the rigid offsets of `heights`
    /// (u_p = u - d theta_y, v_p = v + d theta_x).
    fn offset_matrix(&self, k: &mut [[f64; MAX_DOFS]; MAX_DOFS], n: usize) {
        if self.heights.iter().all(|&d| d == 0.0) {
            return;
        }
        for row in k.iter_mut().take(n) {
            self.offset_row(row);
        }
        for (node, &d) in self.heights.iter().enumerate() {
            let b = 6 * node;
            for col in 0..n {
                k[b + 4][col] -= d * k[b][col];
                k[b + 3][col] += d * k[b + 1][col];
            }
        }
    }

    /// A row over the projected nodes' coordinates as a row over the nodes' own (row T).
    fn offset_row(&self, row: &mut [f64]) {
        for (node, &d) in self.heights.iter().enumerate() {
            let b = 6 * node;
            row[b + 4] -= d * row[b];
            row[b + 3] += d * row[b + 1];
        }
    }

    /// The projected nodes' coordinates from the nodes' own (T u).
    fn offset_displacements(&self, u: &mut Row) {
        for (node, &d) in self.heights.iter().enumerate() {
            let b = 6 * node;
            u[b] -= d * u[b + 4];
            u[b + 1] += d * u[b + 3];
        }
    }
}

fn frame(x: &[Vec3], corners: usize) -> ElementResult<Frame> {
    if x.len() != corners {
        return Err(ElementError::Invalid {
            detail: format!("a {corners}-node shell has {corners} nodes, got {}", x.len()),
        });
    }
    let (normal, along) = if corners == 4 {
        ((x[2] - x[0]).cross(&(x[3] - x[1])), (x[1] + x[2]) - (x[0] + x[3]))
    } else {
        ((x[1] - x[0]).cross(&(x[2] - x[0])), x[1] - x[0])
    };
    let size = x.iter().map(|p| (*p - x[0]).norm()).fold(0.0, f64::max);
    let area = normal.norm();
    if !(area > 1e-12 * size * size) || !area.is_finite() {
        return Err(ElementError::Degenerate { detail: format!("shell of area {:e}", area / 2.0) });
    }
    let n = normal * (1.0 / area);
    let along = along - n * along.dot(&n);
    let e1 = along * (1.0 / along.norm());
    let e2 = n.cross(&e1);
    let centre = x.iter().fold(Vec3::ZERO, |s, p| s + *p) * (1.0 / corners as f64);
    let local = x.iter().map(|p| [(*p - centre).dot(&e1), (*p - centre).dot(&e2)]).collect();
    let heights = if corners == 4 { x.iter().map(|p| (*p - centre).dot(&n)).collect() } else { vec![0.0; 3] };
    Ok(Frame { axes: Mat3([e1.0, e2.0, n.0]), local, heights })
}

/// Bilinear shape functions and their (r, s) derivatives.
fn quad_shape(r: f64, s: f64) -> ([f64; 4], [[f64; 4]; 2]) {
    let mut n = [0.0; 4];
    let mut d = [[0.0; 4]; 2];
    for (i, c) in QUAD_CORNERS.iter().enumerate() {
        n[i] = 0.25 * (1.0 + c[0] * r) * (1.0 + c[1] * s);
        d[0][i] = 0.25 * c[0] * (1.0 + c[1] * s);
        d[1][i] = 0.25 * c[1] * (1.0 + c[0] * r);
    }
    (n, d)
}

/// Jacobian J = [[x,r, y,r], [x,s, y,s]] of 2D coordinates and its determinant.
fn jacobian(local: &[[f64; 2]], d: &[[f64; 4]; 2]) -> ([[f64; 2]; 2], f64) {
    let mut j = [[0.0; 2]; 2];
    for (a, row) in j.iter_mut().enumerate() {
        for (i, p) in local.iter().enumerate() {
            row[0] += d[a][i] * p[0];
            row[1] += d[a][i] * p[1];
        }
    }
    (j, j[0][0] * j[1][1] - j[0][1] * j[1][0])
}

/// Cartesian derivatives (N,x; N,y) of the quadrilateral at (r, s), with det J.
fn quad_gradients(local: &[[f64; 2]], r: f64, s: f64) -> ElementResult<([f64; 4], [[f64; 4]; 2], f64)> {
    let (n, d) = quad_shape(r, s);
    let (j, det) = jacobian(local, &d);
    if !(det > 0.0) {
        return Err(ElementError::Degenerate {
            detail: format!("Jacobian determinant {det:e} at (r, s) = ({r}, {s})"),
        });
    }
    let mut g = [[0.0; 4]; 2];
    for i in 0..4 {
        g[0][i] = (j[1][1] * d[0][i] - j[0][1] * d[1][i]) / det;
        g[1][i] = (-j[1][0] * d[0][i] + j[0][0] * d[1][i]) / det;
    }
    Ok((n, g, det))
}

/// Membrane strain rows (eps_xx, eps_yy, gamma_xy) from shape-function gradients.
fn membrane_rows(g: &[[f64; 4]; 2], nodes: usize) -> [Row; 3] {
    let mut b = [[0.0; MAX_DOFS]; 3];
    for i in 0..nodes {
        b[0][6 * i] = g[0][i];
        b[1][6 * i + 1] = g[1][i];
        b[2][6 * i] = g[1][i];
        b[2][6 * i + 1] = g[0][i];
    }
    b
}

/// In-plane rotation omega = (v,x - u,y) / 2 as a row.
fn rotation_row(g: &[[f64; 4]; 2], nodes: usize) -> Row {
    let mut row = [0.0; MAX_DOFS];
    for i in 0..nodes {
        row[6 * i] = -0.5 * g[1][i];
        row[6 * i + 1] = 0.5 * g[0][i];
    }
    row
}

/// K += w B^T D B for rows B (3 x n) and D (3 x 3), or (2 x n) with a scalar diagonal.
fn add_btdb(k: &mut [[f64; MAX_DOFS]; MAX_DOFS], rows: &[Row], d: &[[f64; 3]; 3], w: f64, n: usize) {
    let m = rows.len();
    for a in 0..n {
        let mut db = [0.0; 3];
        for (p, dbp) in db.iter_mut().enumerate().take(m) {
            *dbp = (0..m).map(|q| d[p][q] * rows[q][a]).sum();
        }
        if db.iter().all(|&v| v == 0.0) {
            continue;
        }
        for b in 0..n {
            let v: f64 = (0..m).map(|p| rows[p][b] * db[p]).sum();
            k[b][a] += w * v;
        }
    }
}

/// Plane-stress elasticity E / (1 - nu^2) [[1, nu, 0], [nu, 1, 0], [0, 0, (1 - nu) / 2]].
fn plane_stress(material: &Material) -> [[f64; 3]; 3] {
    let (e, nu) = (material.young_modulus, material.poisson_ratio);
    let c = e / (1.0 - nu * nu);
    [[c, c * nu, 0.0], [c * nu, c, 0.0], [0.0, 0.0, c * (1.0 - nu) / 2.0]]
}

fn scaled(d: &[[f64; 3]; 3], s: f64) -> [[f64; 3]; 3] {
    d.map(|row| row.map(|v| v * s))
}

/// Curvature rows of a Mindlin plate with bilinear rotations.
fn quad_curvature_rows(g: &[[f64; 4]; 2]) -> [Row; 3] {
    let mut b = [[0.0; MAX_DOFS]; 3];
    for i in 0..4 {
        // beta_x = theta_y, beta_y = -theta_x.
        b[0][6 * i + 4] = g[0][i];
        b[1][6 * i + 3] = -g[1][i];
        b[2][6 * i + 4] = g[1][i];
        b[2][6 * i + 3] = -g[0][i];
    }
    b
}

/// Covariant transverse shear rows (g_r, g_s) of the displacement field at (r, s):
/// g_r = w,r + beta . x,r.
fn covariant_shear(local: &[[f64; 2]], r: f64, s: f64) -> [Row; 2] {
    let (n, d) = quad_shape(r, s);
    let (j, _) = jacobian(local, &d);
    let mut rows = [[0.0; MAX_DOFS]; 2];
    for (a, row) in rows.iter_mut().enumerate() {
        for i in 0..4 {
            row[6 * i + 2] = d[a][i];
            // beta . x,a = theta_y x,a - theta_x y,a.
            row[6 * i + 3] = -n[i] * j[a][1];
            row[6 * i + 4] = n[i] * j[a][0];
        }
    }
    rows
}

/// MITC4 Cartesian transverse shear rows (gamma_xz, gamma_yz) at (r, s).
fn mitc4_shear_rows(local: &[[f64; 2]], r: f64, s: f64) -> [Row; 2] {
    let top = covariant_shear(local, 0.0, 1.0)[0];
    let bottom = covariant_shear(local, 0.0, -1.0)[0];
    let right = covariant_shear(local, 1.0, 0.0)[1];
    let left = covariant_shear(local, -1.0, 0.0)[1];
    let (_, d) = quad_shape(r, s);
    let (j, det) = jacobian(local, &d);
    let mut out = [[0.0; MAX_DOFS]; 2];
    for k in 0..MAX_DOFS {
        let gr = 0.5 * (1.0 + s) * top[k] + 0.5 * (1.0 - s) * bottom[k];
        let gs = 0.5 * (1.0 + r) * right[k] + 0.5 * (1.0 - r) * left[k];
        // [g_r, g_s] = J [gamma_x, gamma_y].
        out[0][k] = (j[1][1] * gr - j[0][1] * gs) / det;
        out[1][k] = (-j[1][0] * gr + j[0][0] * gs) / det;
    }
    out
}

/// Drilling penalty (1/2) k sum_i (theta_z,i - omega)^2 for the rotation row `omega`.
fn add_drilling(k: &mut [[f64; MAX_DOFS]; MAX_DOFS], omega: &Row, stiffness: f64, nodes: usize) {
    for i in 0..nodes {
        let mut row = omega.map(|v| -v);
        row[6 * i + 5] += 1.0;
        for a in 0..6 * nodes {
            if row[a] == 0.0 {
                continue;
            }
            for b in 0..6 * nodes {
                k[a][b] += stiffness * row[a] * row[b];
            }
        }
    }
}

/// Bending stiffness D_b = E t^3 / (12 (1 - nu^2)) (N m).
fn plate_modulus(material: &Material, t: f64) -> f64 {
    material.young_modulus * t.powi(3) / (12.0 * (1.0 - material.poisson_ratio.powi(2)))
}

/// Local stiffness of the quadrilateral (24 x 24, element axes).
fn quad_local_stiffness(
    section: &ShellSection,
    material: &Material,
    local: &[[f64; 2]],
) -> ElementResult<[[f64; MAX_DOFS]; MAX_DOFS]> {
    let t = section.thickness;
    let dm = scaled(&plane_stress(material), t);
    let db = scaled(&plane_stress(material), t.powi(3) / 12.0);
    let shear = section.shear_factor * material.shear_modulus() * t;
    let ds = [[shear, 0.0, 0.0], [0.0, shear, 0.0], [0.0; 3]];
    let mut k = [[0.0; MAX_DOFS]; MAX_DOFS];
    for &(r, wr) in &GAUSS_LEGENDRE_2 {
        for &(s, ws) in &GAUSS_LEGENDRE_2 {
            let (_, g, det) = quad_gradients(local, r, s)?;
            let w = wr * ws * det;
            add_btdb(&mut k, &membrane_rows(&g, 4), &dm, w, MAX_DOFS);
            add_btdb(&mut k, &quad_curvature_rows(&g), &db, w, MAX_DOFS);
            add_btdb(&mut k, &mitc4_shear_rows(local, r, s), &ds, w, MAX_DOFS);
        }
    }
    let (_, g, _) = quad_gradients(local, 0.0, 0.0)?;
    add_drilling(&mut k, &rotation_row(&g, 4), DRILLING_STIFFNESS * plate_modulus(material, t), 4);
    Ok(k)
}

/// Triangle geometry: area and the constant gradients of the linear shape functions.
fn triangle_gradients(local: &[[f64; 2]]) -> ElementResult<(f64, [[f64; 4]; 2])> {
    let [x1, y1] = local[0];
    let [x2, y2] = local[1];
    let [x3, y3] = local[2];
    let twice = (x2 - x1) * (y3 - y1) - (x3 - x1) * (y2 - y1);
    if !(twice > 0.0) {
        return Err(ElementError::Degenerate { detail: format!("triangle of area {:e}", twice / 2.0) });
    }
    let g = [
        [(y2 - y3) / twice, (y3 - y1) / twice, (y1 - y2) / twice, 0.0],
        [(x3 - x2) / twice, (x1 - x3) / twice, (x2 - x1) / twice, 0.0],
    ];
    Ok((twice / 2.0, g))
}

/// Edges of the triangle (corner i, corner j) in the order of the mid-edge nodes 4, 5, 6.
const TRIANGLE_EDGES: [[usize; 2]; 3] = [[0, 1], [1, 2], [2, 0]];

/// The six DKT values of beta (corners, then mid-edges of `TRIANGLE_EDGES`) as rows over the
/// local coordinates: [node][component] -> row.
fn dkt_beta_nodes(local: &[[f64; 2]]) -> [[Row; 2]; 6] {
    let mut beta = [[[0.0; MAX_DOFS]; 2]; 6];
    for (i, b) in beta.iter_mut().enumerate().take(3) {
        // beta = (theta_y, -theta_x) at the corners.
        b[0][6 * i + 4] = 1.0;
        b[1][6 * i + 3] = -1.0;
    }
    for (e, &[i, j]) in TRIANGLE_EDGES.iter().enumerate() {
        let dx = local[j][0] - local[i][0];
        let dy = local[j][1] - local[i][1];
        let l = (dx * dx + dy * dy).sqrt();
        let (s, n) = ([dx / l, dy / l], [dy / l, -dx / l]);
        // beta_s = -1.5 (w_j - w_i) / l - (beta_i + beta_j) . s / 4, beta_n = (beta_i + beta_j) . n / 2.
        let mut bs = [0.0; MAX_DOFS];
        let mut bn = [0.0; MAX_DOFS];
        bs[6 * j + 2] = -1.5 / l;
        bs[6 * i + 2] = 1.5 / l;
        for k in 0..MAX_DOFS {
            let sum = [beta[i][0][k] + beta[j][0][k], beta[i][1][k] + beta[j][1][k]];
            bs[k] -= 0.25 * (sum[0] * s[0] + sum[1] * s[1]);
            bn[k] += 0.5 * (sum[0] * n[0] + sum[1] * n[1]);
        }
        for k in 0..MAX_DOFS {
            beta[3 + e][0][k] = bs[k] * s[0] + bn[k] * n[0];
            beta[3 + e][1][k] = bs[k] * s[1] + bn[k] * n[1];
        }
    }
    beta
}

/// Gradients (d/dx, d/dy) of the six quadratic shape functions at area coordinates L.
fn quadratic_gradients(l: [f64; 3], g: &[[f64; 4]; 2]) -> [[f64; 6]; 2] {
    let mut out = [[0.0; 6]; 2];
    for c in 0..2 {
        for i in 0..3 {
            // Corner: L_i (2 L_i - 1).
            out[c][i] = (4.0 * l[i] - 1.0) * g[c][i];
        }
        for (e, &[i, j]) in TRIANGLE_EDGES.iter().enumerate() {
            out[c][3 + e] = 4.0 * (l[i] * g[c][j] + l[j] * g[c][i]);
        }
    }
    out
}

/// DKT curvature rows at area coordinates L.
fn dkt_curvature_rows(beta: &[[Row; 2]; 6], l: [f64; 3], g: &[[f64; 4]; 2]) -> [Row; 3] {
    let dn = quadratic_gradients(l, g);
    let mut b = [[0.0; MAX_DOFS]; 3];
    for (node, bn) in beta.iter().enumerate() {
        for k in 0..MAX_DOFS {
            b[0][k] += dn[0][node] * bn[0][k];
            b[1][k] += dn[1][node] * bn[1][k];
            b[2][k] += dn[1][node] * bn[0][k] + dn[0][node] * bn[1][k];
        }
    }
    b
}

/// Mid-edge points: the 3-point rule of degree 2 on the triangle (weights A / 3).
const TRIANGLE_MIDPOINTS: [[f64; 3]; 3] = [[0.5, 0.5, 0.0], [0.0, 0.5, 0.5], [0.5, 0.0, 0.5]];

/// Local stiffness of the triangle (18 x 18 in the first rows and columns, element axes).
fn triangle_local_stiffness(
    section: &ShellSection,
    material: &Material,
    local: &[[f64; 2]],
) -> ElementResult<[[f64; MAX_DOFS]; MAX_DOFS]> {
    let t = section.thickness;
    let (area, g) = triangle_gradients(local)?;
    let dm = scaled(&plane_stress(material), t);
    let db = scaled(&plane_stress(material), t.powi(3) / 12.0);
    let mut k = [[0.0; MAX_DOFS]; MAX_DOFS];
    add_btdb(&mut k, &membrane_rows(&g, 3), &dm, area, 18);
    let beta = dkt_beta_nodes(local);
    for l in TRIANGLE_MIDPOINTS {
        add_btdb(&mut k, &dkt_curvature_rows(&beta, l, &g), &db, area / 3.0, 18);
    }
    add_drilling(&mut k, &rotation_row(&g, 3), DRILLING_STIFFNESS * plate_modulus(material, t), 3);
    Ok(k)
}

/// K_body = T^T K_local T with T the block diagonal of the element axes.
fn to_body(axes: &Mat3, local: &[[f64; MAX_DOFS]; MAX_DOFS], n: usize, out: &mut DenseMatrix) {
    let r = &axes.0;
    *out = DenseMatrix::zeros(n, n);
    let blocks = n / 3;
    for bi in 0..blocks {
        for bj in 0..blocks {
            for a in 0..3 {
                for b in 0..3 {
                    let mut acc = 0.0;
                    for i in 0..3 {
                        for j in 0..3 {
                            acc += r[i][a] * local[3 * bi + i][3 * bj + j] * r[j][b];
                        }
                    }
                    out.add(3 * bi + a, 3 * bj + b, acc);
                }
            }
        }
    }
}

/// Element coordinates rotated to element axes.
fn to_local(axes: &Mat3, u: &[f64]) -> Row {
    let mut out = [0.0; MAX_DOFS];
    for block in 0..u.len() / 3 {
        for i in 0..3 {
            out[3 * block + i] = (0..3).map(|j| axes.0[i][j] * u[3 * block + j]).sum();
        }
    }
    out
}

fn dot(row: &Row, u: &Row) -> f64 {
    row.iter().zip(u).map(|(a, b)| a * b).sum()
}

/// Offsets of the six mass points around a mid-surface point (element axes e1, e2, n).
fn fibre_offsets(axes: &Mat3, t: f64) -> [Vec3; 6] {
    let (e1, e2, n) = (Vec3(axes.0[0]), Vec3(axes.0[1]), Vec3(axes.0[2]));
    let d = DRILLING_ARM * t / 2.0;
    [n * (t / 2.0), n * (-t / 2.0), e1 * d, e1 * (-d), e2 * d, e2 * (-d)]
}

/// Mass point of weight w at p + r moving with sum_i N_i (u_i + theta_i x r).
fn fibre_point(weight: f64, p: Vec3, r: Vec3, shape_values: &[f64]) -> MassPoint {
    let n = 6 * shape_values.len();
    let mut shape = vec![0.0; 3 * n];
    let skew = r.skew();
    for (i, &ni) in shape_values.iter().enumerate() {
        if ni == 0.0 {
            continue;
        }
        for row in 0..3 {
            shape[row * n + 6 * i + row] = ni;
            for col in 0..3 {
                // theta x r = -r~ theta.
                shape[row * n + 6 * i + 3 + col] = -ni * skew.0[row][col];
            }
        }
    }
    MassPoint { weight, position: p + r, shape }
}

/// In-plane quadrature points of an element's true surface: (shape values, point, dA).
fn surface_points(x: &[Vec3]) -> Vec<(Vec<f64>, Vec3, f64)> {
    let mut out = Vec::new();
    if x.len() == 4 {
        for &(r, wr) in &GAUSS_LEGENDRE_2 {
            for &(s, ws) in &GAUSS_LEGENDRE_2 {
                let (n, d) = quad_shape(r, s);
                let mut p = Vec3::ZERO;
                let (mut xr, mut xs) = (Vec3::ZERO, Vec3::ZERO);
                for i in 0..4 {
                    p += x[i] * n[i];
                    xr += x[i] * d[0][i];
                    xs += x[i] * d[1][i];
                }
                out.push((n.to_vec(), p, wr * ws * xr.cross(&xs).norm()));
            }
        }
    } else {
        let area = 0.5 * (x[1] - x[0]).cross(&(x[2] - x[0])).norm();
        for l in TRIANGLE_MIDPOINTS {
            let p = x[0] * l[0] + x[1] * l[1] + x[2] * l[2];
            out.push((l.to_vec(), p, area / 3.0));
        }
    }
    out
}

fn shell_mass_points(
    section: &ShellSection,
    material: &Material,
    x: &[Vec3],
    corners: usize,
    out: &mut Vec<MassPoint>,
) -> ElementResult<()> {
    let f = frame(x, corners)?;
    let t = section.thickness;
    let offsets = fibre_offsets(&f.axes, t);
    for (n, p, da) in surface_points(x) {
        if !(da > 0.0) {
            return Err(ElementError::Degenerate { detail: format!("surface element dA = {da:e}") });
        }
        for r in offsets {
            out.push(fibre_point(material.density * t * da / 6.0, p, r, &n));
        }
    }
    Ok(())
}

fn shell_lumped_points(
    section: &ShellSection,
    material: &Material,
    x: &[Vec3],
    corners: usize,
    out: &mut Vec<MassPoint>,
) -> ElementResult<()> {
    let f = frame(x, corners)?;
    let t = section.thickness;
    // HRZ: nodal shares in proportion to int N_i^2 dA.
    let mut diagonal = vec![0.0; corners];
    let mut area = 0.0;
    for (n, _, da) in surface_points(x) {
        area += da;
        for i in 0..corners {
            diagonal[i] += n[i] * n[i] * da;
        }
    }
    let total: f64 = diagonal.iter().sum();
    let mass = material.density * t * area;
    for (i, di) in diagonal.iter().enumerate() {
        let mut n = vec![0.0; corners];
        n[i] = 1.0;
        for r in fibre_offsets(&f.axes, t) {
            out.push(fibre_point(mass * di / total / 6.0, x[i], r, &n));
        }
    }
    Ok(())
}

fn shell_area(x: &[Vec3], corners: usize) -> ElementResult<f64> {
    frame(x, corners)?;
    Ok(surface_points(x).iter().map(|p| p.2).sum())
}

/// Stresses at the top (z = t/2), middle and bottom of the shell at its nodes, Voigt order
/// (xx, yy, zz, yz, xz, xy) in body axes: plane stress D (eps_m + z kappa) with, at the
/// middle, the transverse shear 1.5 kappa_s G gamma (the peak of the parabolic distribution of
/// the shear force; zero for the Kirchhoff triangle).
fn shell_surface_stresses(
    section: &ShellSection,
    material: &Material,
    x: &[Vec3],
    u: &[f64],
    corners: usize,
    out: &mut [[[f64; 6]; 3]],
) -> ElementResult<()> {
    let f = frame(x, corners)?;
    let mut ul = to_local(&f.axes, u);
    f.offset_displacements(&mut ul);
    let t = section.thickness;
    let d = plane_stress(material);
    let shear = 1.5 * section.shear_factor * material.shear_modulus();
    let tri =
        if corners == 3 { Some((triangle_gradients(&f.local)?, dkt_beta_nodes(&f.local))) } else { None };
    for (node, stresses) in out.iter_mut().enumerate().take(corners) {
        let (membrane, curvature, gamma) = match &tri {
            Some(((_, g), beta)) => {
                let mut l = [0.0; 3];
                l[node] = 1.0;
                (membrane_rows(g, 3), dkt_curvature_rows(beta, l, g), None)
            }
            None => {
                let [r, s] = QUAD_CORNERS[node];
                let (_, g, _) = quad_gradients(&f.local, r, s)?;
                (membrane_rows(&g, 4), quad_curvature_rows(&g), Some(mitc4_shear_rows(&f.local, r, s)))
            }
        };
        let eps: [f64; 3] = std::array::from_fn(|k| dot(&membrane[k], &ul));
        let kappa: [f64; 3] = std::array::from_fn(|k| dot(&curvature[k], &ul));
        for (level, z) in [t / 2.0, 0.0, -t / 2.0].into_iter().enumerate() {
            let strain: [f64; 3] = std::array::from_fn(|k| eps[k] + z * kappa[k]);
            let s: [f64; 3] = std::array::from_fn(|a| (0..3).map(|b| d[a][b] * strain[b]).sum());
            let (txz, tyz) = match (&gamma, level) {
                (Some(rows), 1) => (shear * dot(&rows[0], &ul), shear * dot(&rows[1], &ul)),
                _ => (0.0, 0.0),
            };
            // Local tensor -> body axes: sigma_body = R^T sigma_local R.
            let local = [[s[0], s[2], txz], [s[2], s[1], tyz], [txz, tyz, 0.0]];
            let r = &f.axes.0;
            let body = |a: usize, b: usize| -> f64 {
                let mut acc = 0.0;
                for i in 0..3 {
                    for j in 0..3 {
                        acc += r[i][a] * local[i][j] * r[j][b];
                    }
                }
                acc
            };
            stresses[level] = [body(0, 0), body(1, 1), body(2, 2), body(1, 2), body(0, 2), body(0, 1)];
        }
    }
    Ok(())
}

/// Membrane stiffening terms of a shell element: element axes (rows e1, e2, n), linear strains
/// (3 x n_e), von Karman matrices (3 x n_e x n_e) and S (3 x 3), all row-major.
pub type MembraneStiffening = (Mat3, Vec<f64>, Vec<f64>, Vec<f64>);

/// The membrane stiffening terms of a shell element (`body::stiffening`): the element axes
/// (rows e1, e2, n), the element means of the linear membrane strains (3 x n_e, over the local
/// coordinates [u, v, w, theta_x, theta_y, theta_z] per node in element axes), the matrices
/// G_xx, G_yy, G_xy (3 x n_e x n_e) of the mean von Karman terms w,x^2 / 2, w,y^2 / 2,
/// w,x w,y = e^T G_k e / 2 (w bilinear; the triangle's linear in its corner values), and
/// S = area D_m (3 x 3), n_e = 6 x nodes.
pub fn membrane_stiffening(
    section: &ShellSection,
    material: &Material,
    x: &[Vec3],
) -> ElementResult<MembraneStiffening> {
    let corners = x.len();
    if corners != 3 && corners != 4 {
        return Err(ElementError::Invalid { detail: format!("a shell has 3 or 4 nodes, got {corners}") });
    }
    let f = frame(x, corners)?;
    let ne = 6 * corners;
    let mut linear = vec![0.0; 3 * ne];
    let mut slopes = vec![0.0; 3 * ne * ne];
    let mut area = 0.0;
    let mut add = |g: &[[f64; 4]; 2], weight: f64| {
        let rows = membrane_rows(g, corners);
        for c in 0..3 {
            for k in 0..ne {
                linear[c * ne + k] += weight * rows[c][k];
            }
        }
        for i in 0..corners {
            for j in 0..corners {
                let (a, b) = (6 * i + 2, 6 * j + 2);
                slopes[a * ne + b] += weight * g[0][i] * g[0][j];
                slopes[ne * ne + a * ne + b] += weight * g[1][i] * g[1][j];
                slopes[2 * ne * ne + a * ne + b] += weight * (g[0][i] * g[1][j] + g[1][i] * g[0][j]);
            }
        }
    };
    if corners == 4 {
        for &(r, wr) in &GAUSS_LEGENDRE_2 {
            for &(s, ws) in &GAUSS_LEGENDRE_2 {
                let (_, g, det) = quad_gradients(&f.local, r, s)?;
                add(&g, wr * ws * det);
                area += wr * ws * det;
            }
        }
    } else {
        let (a, g) = triangle_gradients(&f.local)?;
        add(&g, a);
        area = a;
    }
    linear.iter_mut().chain(slopes.iter_mut()).for_each(|v| *v /= area);
    // The von Karman terms take w alone, which the offsets leave as it is.
    for row in linear.chunks_mut(ne) {
        f.offset_row(row);
    }
    let d = scaled(&plane_stress(material), section.thickness * area);
    Ok((f.axes, linear, slopes, d.concat()))
}

/// Shell elements: stresses at the top, middle and bottom surfaces (see the module doc).
pub trait ShellKernel {
    /// Stresses [top, middle, bottom] at each node, Voigt order, body axes (Pa).
    fn surface_stresses(
        &self,
        material: &Material,
        x: &[Vec3],
        u: &[f64],
        out: &mut [[[f64; 6]; 3]],
    ) -> ElementResult<()>;
}

macro_rules! shell_kernel {
    ($type:ty, $corners:expr, $local_stiffness:ident) => {
        impl ElementKernel for $type {
            fn node_count(&self) -> usize {
                $corners
            }

            fn dofs_per_node(&self) -> usize {
                6
            }

            fn stiffness(&self, material: &Material, x: &[Vec3], out: &mut DenseMatrix) -> ElementResult<()> {
                let f = frame(x, $corners)?;
                let mut local = $local_stiffness(&self.section, material, &f.local)?;
                f.offset_matrix(&mut local, 6 * $corners);
                to_body(&f.axes, &local, 6 * $corners, out);
                Ok(())
            }

            fn mass_points(
                &self,
                material: &Material,
                x: &[Vec3],
                out: &mut Vec<MassPoint>,
            ) -> ElementResult<()> {
                shell_mass_points(&self.section, material, x, $corners, out)
            }

            fn lumped_mass_points(
                &self,
                material: &Material,
                x: &[Vec3],
                out: &mut Vec<MassPoint>,
            ) -> ElementResult<()> {
                shell_lumped_points(&self.section, material, x, $corners, out)
            }

            fn volume(&self, x: &[Vec3]) -> ElementResult<f64> {
                Ok(shell_area(x, $corners)? * self.section.thickness)
            }

            /// The mid-surface stresses (see [`ShellKernel::surface_stresses`]).
            fn nodal_stresses(
                &self,
                material: &Material,
                x: &[Vec3],
                u: &[f64],
                out: &mut [[f64; 6]],
            ) -> ElementResult<()> {
                let mut levels = [[[0.0; 6]; 3]; $corners];
                shell_surface_stresses(&self.section, material, x, u, $corners, &mut levels)?;
                for (o, l) in out.iter_mut().zip(&levels) {
                    *o = l[1];
                }
                Ok(())
            }
        }

        impl ShellKernel for $type {
            fn surface_stresses(
                &self,
                material: &Material,
                x: &[Vec3],
                u: &[f64],
                out: &mut [[[f64; 6]; 3]],
            ) -> ElementResult<()> {
                shell_surface_stresses(&self.section, material, x, u, $corners, out)
            }
        }
    };
}

shell_kernel!(ShellQuad4, 4, quad_local_stiffness);
shell_kernel!(ShellTri3, 3, triangle_local_stiffness);

#[cfg(test)]
mod tests;
