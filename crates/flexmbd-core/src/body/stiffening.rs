//! Elastic coupling of beams: geometric stiffness from the axial force (seed section 6).
//!
//! The linear K_ff of a beam has no coupling between its axial and transverse displacements,
//! so a beam spun faster than its first bending frequency has no restoring force left against
//! the centrifugal softening and diverges (reference R3). Each element therefore gets the
//! nonlinear (von Karman) axial strain, averaged over the element,
//!
//! ```text
//! eps = u' + b,   b = (1/L) int (v'^2 + w'^2) / 2 dx = e^T G e / 2,   U = EA L eps^2 / 2,
//! ```
//!
//! with G = (1/L) int (v'_e v'_e^T + w'_e w'_e^T) dx over the derivatives v'_e = dv'/de,
//! w'_e = dw'/de of the cubic Hermite fields of the beam element (`fem::beam`) and u linear.
//! Beyond the linear part EA L u'^2 / 2 (already in K_ff) the internal force gains
//! f = EA L [b a_e + eps G e] (a_e = du'/de), whose tangent
//! EA L [a_e (G e)^T + G e (a_e + G e)^T] plus N L G holds the geometric stiffness of the
//! axial force N = EA eps (consistent: the tangent of f). Averaging the quadratic term over the element is what lets a bent element
//! stay inextensible: with the pointwise strain, the linear axial field cannot follow the
//! quartic v'^2 and the element locks (membrane locking), far too stiff in bending once it is
//! deflected. The sum v'^2 + w'^2 does not depend on the orientation of the section axes, so
//! any pair perpendicular to the beam serves.
//!
//! Each element reads its 12 local nodal coordinates [u1, v1, w1, thx1, thy1, thz1, u2, ...]
//! from the body's elastic coordinates through a constant 12 x n_l matrix (rotation to
//! element axes times the selection of its nodes' coordinates, or times the mode shapes of a
//! modal body).

use crate::fem::beam::GAUSS4;

/// One beam element of the stiffening.
#[derive(Clone, Debug, PartialEq)]
pub struct StiffeningElement {
    /// Elastic coordinates of the body the element depends on (n_l).
    pub indices: Vec<usize>,
    /// e = map q_l: 12 x n_l, row-major.
    pub map: Vec<f64>,
    /// Length L (m).
    pub length: f64,
    /// Axial stiffness EA (N).
    pub axial_stiffness: f64,
    /// Positions of the (indices[i], indices[j]) pairs in the body's elastic pattern, row-major
    /// n_l x n_l (filled when the body is built).
    pub positions: Vec<usize>,
}

/// A sparse row of 4 (index, value) entries.
type SparseRow = [(usize, f64); 4];

/// Derivatives (index, value per unit e) of v' and w' at xi.
fn gradients(xi: f64, length: f64) -> (SparseRow, SparseRow) {
    let h1 = (-6.0 * xi + 6.0 * xi * xi) / length;
    let h2 = 1.0 - 4.0 * xi + 3.0 * xi * xi;
    let h3 = (6.0 * xi - 6.0 * xi * xi) / length;
    let h4 = 3.0 * xi * xi - 2.0 * xi;
    ([(1, h1), (5, h2), (7, h3), (11, h4)], [(2, h1), (4, -h2), (8, h3), (10, -h4)])
}

/// G = (1/L) int (v'_e v'_e^T + w'_e w'_e^T) dx (12 x 12).
pub fn slope_matrix(length: f64) -> [[f64; 12]; 12] {
    let mut g = [[0.0; 12]; 12];
    for &(xi, weight) in &GAUSS4 {
        let (gv, gw) = gradients(xi, length);
        for d in [&gv, &gw] {
            for &(i, vi) in d.iter() {
                for &(j, vj) in d.iter() {
                    g[i][j] += weight * vi * vj;
                }
            }
        }
    }
    g
}

/// Nonlinear part of the element: internal force f (12), tangent k (12 x 12, if given) and
/// strain energy, at local coordinates e.
pub fn element_terms(
    el: &StiffeningElement,
    e: &[f64; 12],
    f: &mut [f64; 12],
    k: Option<&mut [[f64; 12]; 12]>,
) -> f64 {
    let (l, ea) = (el.length, el.axial_stiffness);
    let g = slope_matrix(l);
    let ge: [f64; 12] = std::array::from_fn(|i| (0..12).map(|j| g[i][j] * e[j]).sum());
    let a = (e[6] - e[0]) / l;
    let b = 0.5 * (0..12).map(|i| e[i] * ge[i]).sum::<f64>();
    let eps = a + b;
    let w = ea * l;
    let mut a_e = [0.0; 12];
    a_e[0] = -1.0 / l;
    a_e[6] = 1.0 / l;
    for i in 0..12 {
        f[i] = w * (b * a_e[i] + eps * ge[i]);
    }
    if let Some(k) = k {
        for i in 0..12 {
            for j in 0..12 {
                k[i][j] = w * (a_e[i] * ge[j] + ge[i] * (a_e[j] + ge[j]) + eps * g[i][j]);
            }
        }
    }
    w * (a * b + 0.5 * b * b)
}

fn local(el: &StiffeningElement, qf: &[f64]) -> [f64; 12] {
    let n = el.indices.len();
    let mut e = [0.0; 12];
    for (r, er) in e.iter_mut().enumerate() {
        *er = (0..n).map(|j| el.map[r * n + j] * qf[el.indices[j]]).sum();
    }
    e
}

/// Adds the nonlinear internal forces of all elements to `out` (n_f) and, with
/// `tangent = Some((w, values))`, w times their tangent to the values of the elastic
/// pattern. Returns the nonlinear part of the strain energy.
pub fn add_stiffening(
    elements: &[StiffeningElement],
    qf: &[f64],
    out: &mut [f64],
    mut tangent: Option<(f64, &mut [f64])>,
) -> f64 {
    let mut energy = 0.0;
    let mut f = [0.0; 12];
    let mut k = [[0.0; 12]; 12];
    for el in elements {
        let n = el.indices.len();
        let e = local(el, qf);
        let want = tangent.is_some();
        energy += element_terms(el, &e, &mut f, if want { Some(&mut k) } else { None });
        for j in 0..n {
            out[el.indices[j]] += (0..12).map(|r| el.map[r * n + j] * f[r]).sum::<f64>();
        }
        if let Some((w, values)) = tangent.as_mut() {
            // B^T k B with B = map (12 x n_l).
            let mut kb = vec![0.0; 12 * n];
            for r in 0..12 {
                for j in 0..n {
                    kb[r * n + j] = (0..12).map(|s| k[r][s] * el.map[s * n + j]).sum();
                }
            }
            for i in 0..n {
                for j in 0..n {
                    let v: f64 = (0..12).map(|r| el.map[r * n + i] * kb[r * n + j]).sum();
                    values[el.positions[i * n + j]] += *w * v;
                }
            }
        }
    }
    energy
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{assert_all_close, assert_close};

    fn element() -> StiffeningElement {
        StiffeningElement {
            indices: (0..12).collect(),
            map: (0..144).map(|k| if k % 13 == 0 { 1.0 } else { 0.0 }).collect(),
            length: 0.7,
            axial_stiffness: 3.0e3,
            positions: (0..144).collect(),
        }
    }

    #[test]
    fn force_and_tangent_are_derivatives_of_the_energy() {
        let el = element();
        let e: [f64; 12] = std::array::from_fn(|k| 0.01 * ((k * 7 % 5) as f64 - 2.0) + 0.003 * k as f64);
        let mut f = [0.0; 12];
        let mut k = [[0.0; 12]; 12];
        element_terms(&el, &e, &mut f, Some(&mut k));
        let h = 1e-7;
        for j in 0..12 {
            let (mut ep, mut em) = (e, e);
            ep[j] += h;
            em[j] -= h;
            let (mut fp, mut fm) = ([0.0; 12], [0.0; 12]);
            let up = element_terms(&el, &ep, &mut fp, None);
            let um = element_terms(&el, &em, &mut fm, None);
            let fd = (up - um) / (2.0 * h);
            assert_close(fd, f[j], 1e-6, 1e-6, format_args!("force {j}"));
            let kd: [f64; 12] = std::array::from_fn(|i| (fp[i] - fm[i]) / (2.0 * h));
            assert_all_close(&kd, &k.map(|row| row[j]), 1e-5, 1e-5, format_args!("tangent column {j}"));
        }
    }

    #[test]
    fn inextensional_bending_stores_no_axial_energy() {
        // v = c x^2 (exact in the cubic element) with the ends drawn together by the mean of
        // v'^2 / 2: the averaged strain vanishes, so linear plus nonlinear axial energy is 0
        // (a pointwise von Karman strain would lock here).
        let el = element();
        let (l, c) = (el.length, 0.05);
        let mut e = [0.0; 12];
        e[7] = c * l * l;
        e[11] = 2.0 * c * l;
        let mean_half_slope_squared = 2.0 * c * c * l * l / 3.0;
        e[6] = -mean_half_slope_squared * l;
        let mut f = [0.0; 12];
        let nonlinear = element_terms(&el, &e, &mut f, None);
        let linear = 0.5 * el.axial_stiffness * l * (e[6] / l).powi(2);
        assert_close(nonlinear, -linear, 1e-12, 0.0, "nonlinear against minus linear axial energy");
        // And no axial force: the internal force has no axial components left.
        let axial = f[6] + el.axial_stiffness * e[6] / l;
        assert_close(axial, 0.0, 0.0, 1e-9 * el.axial_stiffness * mean_half_slope_squared, "axial force");
    }

    #[test]
    fn uniform_stretch_gives_the_string_stiffness() {
        // Axial strain eps0 and no bending: the transverse tangent is N (v'_e v'_e^T) with
        // N = EA eps0, whose Rayleigh quotient for a rigid rotation of the element
        // (v1 = 0, v2 = L theta, slopes theta) is N L theta^2.
        let el = element();
        let eps0 = 1e-3;
        let mut e = [0.0; 12];
        e[6] = eps0 * el.length;
        let mut f = [0.0; 12];
        let mut k = [[0.0; 12]; 12];
        element_terms(&el, &e, &mut f, Some(&mut k));
        let theta = 0.2;
        let mut d = [0.0; 12];
        d[7] = el.length * theta;
        d[5] = theta;
        d[11] = theta;
        let quad: f64 = (0..12).map(|i| (0..12).map(|j| d[i] * k[i][j] * d[j]).sum::<f64>()).sum();
        let expected = el.axial_stiffness * eps0 * el.length * theta * theta;
        assert_close(quad, expected, 1e-9, 0.0, "Rayleigh quotient");
    }
}
