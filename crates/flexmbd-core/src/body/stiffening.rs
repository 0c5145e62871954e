//! Elastic coupling of beams and shells: geometric stiffness from the axial (membrane) force
//! (seed section 6).
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
//! Each element reads its n_e local nodal coordinates e = [u1, v1, w1, thx1, thy1, thz1, u2,
//! ...] from the body's elastic coordinates through a constant n_e x n_l matrix (rotation to
//! element axes times the selection of its nodes' coordinates, or times the mode shapes of a
//! modal body).
//!
//! The kernel is that of any element with m strains eps = A e + b, b_k = e^T G_k e / 2, and the
//! energy eps^T S eps / 2 (S: the stiffness times the element's size), of which the linear
//! part (A e)^T S (A e) / 2 is in K_ff: the nonlinear energy a^T S b + b^T S b / 2 (a = A e),
//! the force f = A^T S b + sum_k N_k G_k e with N = S eps, the tangent
//! A^T S B + B^T S A + B^T S B + sum_k N_k G_k with B_k = (G_k e)^T. The beam is m = 1 with
//! S = EA L. A flat shell (`fem::shell`, 24 or 18 coordinates) is m = 3: the membrane strains
//! (eps_xx, eps_yy, gamma_xy) with the element means of the linear strains and of the von
//! Karman terms (w,x^2 / 2, w,y^2 / 2, w,x w,y) of its w field (bilinear; the triangle's
//! linear in its corner values), and S = area D_m: averaged over the element like the beam's,
//! which keeps a bent element free of membrane locking.

use crate::body::element_map::{add_elements, SparseMap};
use crate::fem::beam::GAUSS4;

/// One element of the stiffening (beam or shell).
#[derive(Clone, Debug, PartialEq)]
pub struct StiffeningElement {
    /// Elastic coordinates of the body the element depends on (n_l).
    pub indices: Vec<usize>,
    /// e = map q_l: n_e x n_l, row-major.
    pub map: Vec<f64>,
    /// Linear strains a = A e: m x n_e, row-major.
    pub linear: Vec<f64>,
    /// The m matrices G_k (n_e x n_e each, row-major) of the quadratic strains e^T G_k e / 2.
    pub slopes: Vec<f64>,
    /// S (m x m, row-major, symmetric positive definite): the energy is eps^T S eps / 2.
    pub stiffness: Vec<f64>,
    /// Positions of the (indices[i], indices[j]) pairs in the body's elastic pattern, row-major
    /// n_l x n_l (filled when the body is built).
    pub positions: Vec<usize>,
    /// The map's rows by their nonzero entries, when they are few (a nodal beam's rotation to
    /// element axes: at most three per row); filled when the body is built.
    pub sparse_map: Option<SparseMap>,
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

/// G = (1/L) int (v'_e v'_e^T + w'_e w'_e^T) dx (12 x 12) of a beam element.
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

impl StiffeningElement {
    /// A beam element of length L and axial stiffness EA over e = map q_l (map: 12 x n_l):
    /// eps = u' + (1/L) int (v'^2 + w'^2) / 2 dx, S = EA L.
    pub fn beam(indices: Vec<usize>, map: Vec<f64>, length: f64, axial_stiffness: f64) -> Self {
        let mut linear = vec![0.0; 12];
        linear[0] = -1.0 / length;
        linear[6] = 1.0 / length;
        StiffeningElement {
            indices,
            map,
            linear,
            slopes: slope_matrix(length).concat(),
            stiffness: vec![axial_stiffness * length],
            positions: Vec::new(),
            sparse_map: None,
        }
    }

    /// Number of local coordinates n_e.
    pub fn local_count(&self) -> usize {
        self.linear.len() / self.strain_count().max(1)
    }

    /// Number of strains m.
    pub fn strain_count(&self) -> usize {
        (self.stiffness.len() as f64).sqrt().round() as usize
    }

    /// Whether the sizes agree (map n_e x n_l, A m x n_e, G m n_e^2, S m^2) and every value is
    /// finite, with S symmetric and a positive diagonal.
    pub fn is_consistent(&self, elastic_count: usize) -> bool {
        let m = self.strain_count();
        let ne = self.local_count();
        let nl = self.indices.len();
        m > 0
            && self.stiffness.len() == m * m
            && self.linear.len() == m * ne
            && self.slopes.len() == m * ne * ne
            && self.map.len() == ne * nl
            && self.indices.iter().all(|&i| i < elastic_count)
            && [&self.map, &self.linear, &self.slopes, &self.stiffness]
                .iter()
                .all(|v| v.iter().all(|x| x.is_finite()))
            && (0..m).all(|k| self.stiffness[k * m + k] > 0.0)
            && (0..m).all(|i| (0..m).all(|j| self.stiffness[i * m + j] == self.stiffness[j * m + i]))
    }
}

/// Scratch of [`element_terms`]: G_k e (m x n_e), the strains and the forces N.
#[derive(Default)]
pub struct Scratch {
    ge: Vec<f64>,
}

/// Nonlinear part of the element: internal force f (n_e), tangent k (n_e x n_e, row-major,
/// if given) and strain energy, at local coordinates e.
pub fn element_terms(
    el: &StiffeningElement,
    e: &[f64],
    f: &mut [f64],
    k: Option<&mut [f64]>,
    scratch: &mut Scratch,
) -> f64 {
    let m = el.strain_count();
    let ne = el.local_count();
    let s = &el.stiffness;
    scratch.ge.clear();
    scratch.ge.resize(m * ne, 0.0);
    let ge = &mut scratch.ge;
    let mut a = [0.0; 3];
    let mut b = [0.0; 3];
    for c in 0..m {
        let g = &el.slopes[c * ne * ne..(c + 1) * ne * ne];
        for i in 0..ne {
            ge[c * ne + i] = (0..ne).map(|j| g[i * ne + j] * e[j]).sum();
        }
        a[c] = (0..ne).map(|j| el.linear[c * ne + j] * e[j]).sum();
        b[c] = 0.5 * (0..ne).map(|i| e[i] * ge[c * ne + i]).sum::<f64>();
    }
    let row = |r: usize, v: &[f64; 3]| -> f64 {
        if r < m {
            (0..m).map(|c| s[r * m + c] * v[c]).sum()
        } else {
            0.0
        }
    };
    let strain: [f64; 3] = std::array::from_fn(|c| a[c] + b[c]);
    let sb: [f64; 3] = std::array::from_fn(|r| row(r, &b));
    let force: [f64; 3] = std::array::from_fn(|r| row(r, &strain));
    for (i, fi) in f.iter_mut().enumerate().take(ne) {
        *fi = (0..m).map(|c| el.linear[c * ne + i] * sb[c] + force[c] * ge[c * ne + i]).sum();
    }
    if let Some(k) = k {
        for i in 0..ne {
            for j in 0..ne {
                let mut v = 0.0;
                for p in 0..m {
                    let (ap_i, bp_i) = (el.linear[p * ne + i], ge[p * ne + i]);
                    v += force[p] * el.slopes[p * ne * ne + i * ne + j];
                    for q in 0..m {
                        let spq = s[p * m + q];
                        let (aq_j, bq_j) = (el.linear[q * ne + j], ge[q * ne + j]);
                        v += spq * (ap_i * bq_j + bp_i * aq_j + bp_i * bq_j);
                    }
                }
                k[i * ne + j] = v;
            }
        }
    }
    (0..m).map(|r| a[r] * sb[r] + 0.5 * b[r] * sb[r]).sum()
}

/// Adds the nonlinear internal forces of all elements to `out` (n_f) and, with
/// `tangent = Some((w, values))`, w times their tangent to the values of the elastic
/// pattern. Returns the nonlinear part of the strain energy.
pub fn add_stiffening(
    elements: &[StiffeningElement],
    qf: &[f64],
    out: &mut [f64],
    tangent: Option<(f64, &mut [f64])>,
) -> f64 {
    let mut scratch = Scratch::default();
    add_elements(elements, qf, out, tangent, StiffeningElement::local_count, |el, e, f, k| {
        element_terms(el, e, f, k, &mut scratch)
    })
}

crate::mapped_element!(StiffeningElement);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{assert_all_close, assert_close};

    const LENGTH: f64 = 0.7;
    const AXIAL: f64 = 3.0e3;

    fn element() -> StiffeningElement {
        let map = (0..144).map(|k| if k % 13 == 0 { 1.0 } else { 0.0 }).collect();
        StiffeningElement::beam((0..12).collect(), map, LENGTH, AXIAL)
    }

    /// A shell-like element: three strains over 24 coordinates, random symmetric G_k and a
    /// symmetric positive definite S.
    fn shell_element() -> StiffeningElement {
        let ne = 24;
        let value = |k: usize| ((k * 7919 % 1013) as f64 / 1013.0) - 0.5;
        let mut slopes = vec![0.0; 3 * ne * ne];
        for c in 0..3 {
            for i in 0..ne {
                for j in 0..ne {
                    slopes[c * ne * ne + i * ne + j] = value(c * 1000 + i.min(j) * 31 + i.max(j));
                }
            }
        }
        let map = (0..ne * ne).map(|k| if k % (ne + 1) == 0 { 1.0 } else { 0.0 }).collect();
        StiffeningElement {
            indices: (0..ne).collect(),
            map,
            linear: (0..3 * ne).map(|k| value(5000 + k)).collect(),
            slopes,
            stiffness: vec![4.0, 1.0, 0.0, 1.0, 3.0, 0.5, 0.0, 0.5, 2.0],
            positions: (0..ne * ne).collect(),
            sparse_map: None,
        }
    }

    fn terms(el: &StiffeningElement, e: &[f64], tangent: bool) -> (f64, Vec<f64>, Vec<f64>) {
        let ne = el.local_count();
        let mut f = vec![0.0; ne];
        let mut k = vec![0.0; ne * ne];
        let u =
            element_terms(el, e, &mut f, if tangent { Some(&mut k) } else { None }, &mut Scratch::default());
        (u, f, k)
    }

    #[test]
    fn force_and_tangent_are_derivatives_of_the_energy() {
        for el in [element(), shell_element()] {
            let ne = el.local_count();
            let e: Vec<f64> = (0..ne).map(|k| 0.01 * ((k * 7 % 5) as f64 - 2.0) + 0.003 * k as f64).collect();
            let (_, f, k) = terms(&el, &e, true);
            let h = 1e-7;
            for j in 0..ne {
                let (mut ep, mut em) = (e.clone(), e.clone());
                ep[j] += h;
                em[j] -= h;
                let (up, fp, _) = terms(&el, &ep, false);
                let (um, fm, _) = terms(&el, &em, false);
                let fd = (up - um) / (2.0 * h);
                assert_close(fd, f[j], 1e-6, 1e-6, format_args!("force {j} of {ne}"));
                let kd: Vec<f64> = (0..ne).map(|i| (fp[i] - fm[i]) / (2.0 * h)).collect();
                let column: Vec<f64> = (0..ne).map(|i| k[i * ne + j]).collect();
                assert_all_close(&kd, &column, 1e-5, 1e-5, format_args!("tangent column {j} of {ne}"));
            }
        }
    }

    #[test]
    fn sparse_map_rows_give_the_dense_products() {
        // A beam element turned by a rotation about an oblique axis (three entries per map
        // row), over 14 body coordinates of which two are not its own: force, tangent and
        // energy from the sparse rows equal the dense map's.
        let (c, sn) = (0.6_f64, 0.8_f64);
        let rot = [
            [c, -sn * 0.6, sn * 0.8],
            [sn * 0.6, c + 0.4 * 0.36, -0.4 * 0.48],
            [-sn * 0.8, -0.4 * 0.48, c + 0.4 * 0.64],
        ];
        let nl = 14;
        let mut map = vec![0.0; 12 * nl];
        for block in 0..4 {
            for i in 0..3 {
                for j in 0..3 {
                    map[(3 * block + i) * nl + 3 * block + j + 1] = rot[i][j];
                }
            }
        }
        let mut dense = StiffeningElement::beam((0..nl).collect(), map.clone(), LENGTH, AXIAL);
        dense.positions = (0..nl * nl).collect();
        let mut sparse = dense.clone();
        sparse.sparse_map = SparseMap::of(&map, 12, nl);
        assert!(sparse.sparse_map.is_some());
        let q: Vec<f64> = (0..nl).map(|k| 0.02 * ((k * 5 % 7) as f64 - 3.0)).collect();
        let run = |el: &StiffeningElement| {
            let (mut f, mut k) = (vec![0.0; nl], vec![0.0; nl * nl]);
            let u = add_stiffening(std::slice::from_ref(el), &q, &mut f, Some((0.7, &mut k)));
            (u, f, k)
        };
        let (ud, fd, kd) = run(&dense);
        let (us, fs, ks) = run(&sparse);
        assert_close(us, ud, 1e-13, 1e-300, "energy");
        assert_all_close(&fs, &fd, 1e-12, 1e-15, "force");
        assert_all_close(&ks, &kd, 1e-12, 1e-12, "tangent");
        assert!(kd.iter().any(|v| v.abs() > 1.0) && fd.iter().any(|v| v.abs() > 1e-3));
    }

    #[test]
    fn inextensional_bending_stores_no_axial_energy() {
        // v = c x^2 (exact in the cubic element) with the ends drawn together by the mean of
        // v'^2 / 2: the averaged strain vanishes, so linear plus nonlinear axial energy is 0
        // (a pointwise von Karman strain would lock here).
        let el = element();
        let (l, c) = (LENGTH, 0.05);
        let mut e = [0.0; 12];
        e[7] = c * l * l;
        e[11] = 2.0 * c * l;
        let mean_half_slope_squared = 2.0 * c * c * l * l / 3.0;
        e[6] = -mean_half_slope_squared * l;
        let (nonlinear, f, _) = terms(&el, &e, false);
        let linear = 0.5 * AXIAL * l * (e[6] / l).powi(2);
        assert_close(nonlinear, -linear, 1e-12, 0.0, "nonlinear against minus linear axial energy");
        // And no axial force: the internal force has no axial components left.
        let axial = f[6] + AXIAL * e[6] / l;
        assert_close(axial, 0.0, 0.0, 1e-9 * AXIAL * mean_half_slope_squared, "axial force");
    }

    #[test]
    fn uniform_stretch_gives_the_string_stiffness() {
        // Axial strain eps0 and no bending: the transverse tangent is N (v'_e v'_e^T) with
        // N = EA eps0, whose Rayleigh quotient for a rigid rotation of the element
        // (v1 = 0, v2 = L theta, slopes theta) is N L theta^2.
        let el = element();
        let eps0 = 1e-3;
        let mut e = [0.0; 12];
        e[6] = eps0 * LENGTH;
        let (_, _, k) = terms(&el, &e, true);
        let theta = 0.2;
        let mut d = [0.0; 12];
        d[7] = LENGTH * theta;
        d[5] = theta;
        d[11] = theta;
        let quad: f64 = (0..12).map(|i| (0..12).map(|j| d[i] * k[i * 12 + j] * d[j]).sum::<f64>()).sum();
        let expected = AXIAL * eps0 * LENGTH * theta * theta;
        assert_close(quad, expected, 1e-9, 0.0, "Rayleigh quotient");
    }
}
