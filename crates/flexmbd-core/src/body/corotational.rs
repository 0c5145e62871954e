//! Co-rotational elastic forces of beam elements inside a nodal deformable body (the
//! `corotational` kind of geometric stiffness, beside the von Karman one of
//! [`crate::body::stiffening`]).
//!
//! In the body frame the nodal translations of a nodal body are exact positions, so the
//! element's elastic energy can be measured in the frame of its current chord: the axial
//! stretch from the chord length, the bending and the torsion from the nodal rotations
//! relative to the chord's rotation. The energy is then that of the linear element for the
//! deformation left once the element's rigid motion is removed, and an element turned rigidly
//! inside the body stores none: the body converges to the geometrically exact beam under
//! refinement, where the von Karman strain (second order in the slopes) stays too flexible at
//! large deflections (reference R3; `benchmarks/README.md`).
//!
//! Each element reads its local coordinates e = [u1 v1 w1 thx1 thy1 thz1 u2 ...] (translations
//! and nodal rotation parameters in its undeformed axes: x along the beam, y and z the
//! section's axes) through a constant map from the body's elastic coordinates, as the von
//! Karman elements do. With the chord d = (L + u2 - u1, v2 - v1, w2 - w1) and l = |d|:
//!
//! ```text
//! ubar = l - L                                        (axial stretch)
//! s = atan2(rho, d_x) / rho (0, -d_z, d_y),  rho = sqrt(d_y^2 + d_z^2)
//!                                                     (the chord's swing: the rotation vector
//!                                                      of the smallest turn from e_x to d / l)
//! tau = (thx1 + thx2) / 2                             (mean twist)
//! psi = s + tau e_x + tau (s x e_x) / 2               (the chord's rotation vector)
//! g_i = th_i - psi - (psi x th_i) / 2                 (deformational rotations of node i)
//! U = g^T K7 g / 2,  g = [ubar, g_1, g_2]
//! ```
//!
//! with K7 the rows and columns (u2, thx1, thy1, thz1, thx2, thy2, thz2) of the element's
//! linear stiffness matrix (`fem::Beam::corotational_terms`: Euler-Bernoulli or Timoshenko,
//! EA, E I_y, E I_z, G J). To first order g is e minus its rigid-body part, so U = e^T K e / 2
//! plus terms of third order: the linear part e^T K e / 2 is already in K_ff, and the element
//! contributes the rest, U - e^T K e / 2, its force J^T K7 g - K e (J = dg/de) and its
//! tangent J^T K7 J + sum_k (K7 g)_k d2g_k/de2 - K (analytic). The swing's factor
//! atan2(rho, d_x) / rho is smooth through rho = 0 (the undeformed chord), where it is
//! evaluated from its series in (rho / d_x)^2.
//!
//! Exactness and limits. The nodal rotation parameters are read as rotation vectors: psi is
//! the rotation vector of the chord's frame (swing composed with the mean twist, to second
//! order in tau |s|), and g_i = log(exp(-psi) exp(th_i)) to second order (Baker-Campbell-
//! Hausdorff). Exact (no energy for a rigid turn, the bending of the elastica) whenever the
//! rotations share one axis: bending in any plane through the element's axis, at any angle
//! below pi (the chord's swing is exact), and twist alone. For a rigid rotation with both
//! twist and swing, a spurious force of order E I tau |s|^2 / L (third order); a deformed
//! element turned as a whole (twist and swing) changes its energy at second order in the turn
//! (`benchmarks/README.md` has the figures). Undefined for a chord turned by pi. This suits the floating frame, whose body frame carries the large rotation.
//! The mass of the body is that of the linear FFRF body: exact for the nodal translations,
//! linear in the rotation parameters (the rotary inertia of the sections).

use crate::body::element_map::{add_elements, SparseMap};

/// Positions of g = [ubar, phi_1, phi_2] in the element's 12 local coordinates (the rows of
/// the local stiffness matrix that K7 keeps).
const REDUCED: [usize; 7] = [6, 3, 4, 5, 9, 10, 11];

/// One beam element of the co-rotational elastic forces.
#[derive(Clone, Debug, PartialEq)]
pub struct CorotationalBeam {
    /// Elastic coordinates of the body the element depends on (n_l).
    pub indices: Vec<usize>,
    /// e = map q_l: 12 x n_l, row-major.
    pub map: Vec<f64>,
    /// Undeformed length L.
    pub length: f64,
    /// The element's linear stiffness matrix in its axes (12 x 12, row-major, symmetric).
    pub stiffness: Vec<f64>,
    /// Positions of the (indices[i], indices[j]) pairs in the body's elastic pattern, row-major
    /// n_l x n_l (filled when the body is built).
    pub positions: Vec<usize>,
    /// The map's rows by their entries when they are few (filled when the body is built).
    pub sparse_map: Option<SparseMap>,
}

crate::mapped_element!(CorotationalBeam);

impl CorotationalBeam {
    /// An element of length L with local stiffness matrix `stiffness` (12 x 12, row-major)
    /// over e = map q_l (map: 12 x n_l).
    pub fn new(indices: Vec<usize>, map: Vec<f64>, length: f64, stiffness: Vec<f64>) -> Self {
        CorotationalBeam { indices, map, length, stiffness, positions: Vec::new(), sparse_map: None }
    }

    /// Whether the sizes agree (map 12 x n_l, stiffness 12 x 12 symmetric), the indices
    /// exist, the length is positive and every value finite.
    pub fn is_consistent(&self, elastic_count: usize) -> bool {
        let k = &self.stiffness;
        self.length > 0.0
            && self.length.is_finite()
            && k.len() == 144
            && self.map.len() == 12 * self.indices.len()
            && self.indices.iter().all(|&i| i < elastic_count)
            && self.map.iter().chain(k).all(|v| v.is_finite())
            && (0..12).all(|i| (0..12).all(|j| k[12 * i + j] == k[12 * j + i]))
    }
}

/// A function of the chord d lifted to the local coordinates: d = (L + e6 - e0, e7 - e1,
/// e8 - e2), so the gradient is (-g, 0, g, 0) by blocks of 3.
fn lift(g: [f64; 3]) -> [f64; 12] {
    let mut out = [0.0; 12];
    for i in 0..3 {
        out[i] = -g[i];
        out[6 + i] = g[i];
    }
    out
}

/// G(u, x) = atan2(sqrt(u), x) / sqrt(u) (the swing angle over sin-free length, u = d_y^2 +
/// d_z^2, x = d_x) with G_u and G_uu; G_x = -1/D, G_xx = 2 x / D^2, G_xu = 1/D^2 (D = x^2 + u)
/// need no care. Near the undeformed chord (x > 0, s = u / x^2 < 0.01) from the series of
/// h(s) = atan(sqrt(s)) / sqrt(s) = sum (-s)^k / (2k + 1), G = h / x, G_u = h' / x^3,
/// G_uu = h'' / x^5 (truncation below s^12); elsewhere in closed form.
fn swing_factor(u: f64, x: f64) -> (f64, f64, f64) {
    let d = x * x + u;
    if x > 0.0 && u < 0.01 * x * x {
        let s = u / (x * x);
        // h = sum (-s)^k / (2k + 1), h' = -sum_{k>=1} k / (2k + 1) (-s)^(k-1),
        // h'' = sum_{k>=2} k (k - 1) / (2k + 1) (-s)^(k-2).
        let (mut h, mut h1, mut h2) = (0.0, 0.0, 0.0);
        let mut power = 1.0;
        for k in 0..13 {
            h += power / (2 * k + 1) as f64;
            h1 -= (k + 1) as f64 / (2 * k + 3) as f64 * power;
            h2 += ((k + 2) * (k + 1)) as f64 / (2 * k + 5) as f64 * power;
            power *= -s;
        }
        let x3 = x * x * x;
        return (h / x, h1 / x3, h2 / (x3 * x * x));
    }
    let r = u.sqrt();
    let a = r.atan2(x);
    let g = a / r;
    let gu = x / (2.0 * d * u) - a / (2.0 * u * r);
    let guu = -x / (2.0 * d * d * u) - 3.0 * x / (4.0 * d * u * u) + 3.0 * a / (4.0 * u * u * r);
    (g, gu, guu)
}

/// Chord quantities: the stretch ubar = l - L and the swing (s_y, s_z) = G (-d_z, d_y), the
/// rotation vector of the smallest rotation taking e_x to the chord's direction, with their
/// gradients over d.
struct Chord {
    ubar: f64,
    sy: f64,
    sz: f64,
    n: [f64; 3],
    length: f64,
    grad_sy: [f64; 3],
    grad_sz: [f64; 3],
    /// Hessian of G over d.
    hess_g: [[f64; 3]; 3],
    /// Gradient of G over d.
    grad_g: [f64; 3],
}

impl Chord {
    fn new(e: &[f64], l0: f64) -> Self {
        let d = [l0 + e[6] - e[0], e[7] - e[1], e[8] - e[2]];
        let length = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let n = [d[0] / length, d[1] / length, d[2] / length];
        let u = d[1] * d[1] + d[2] * d[2];
        let x = d[0];
        let dd = x * x + u;
        let (g, gu, guu) = swing_factor(u, x);
        let (gx, gxx, gxu) = (-1.0 / dd, 2.0 * x / (dd * dd), 1.0 / (dd * dd));
        let grad_u = [0.0, 2.0 * d[1], 2.0 * d[2]];
        let grad_g = [gx, gu * grad_u[1], gu * grad_u[2]];
        let mut hess_g = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                let ex_i = if i == 0 { 1.0 } else { 0.0 };
                let ex_j = if j == 0 { 1.0 } else { 0.0 };
                hess_g[i][j] = gxx * ex_i * ex_j
                    + gxu * (ex_i * grad_u[j] + grad_u[i] * ex_j)
                    + guu * grad_u[i] * grad_u[j]
                    + if i == j && i > 0 { 2.0 * gu } else { 0.0 };
            }
        }
        // s_y = -G d_z, s_z = G d_y.
        let grad_sy = std::array::from_fn(|i| -d[2] * grad_g[i] - if i == 2 { g } else { 0.0 });
        let grad_sz = std::array::from_fn(|i| d[1] * grad_g[i] + if i == 1 { g } else { 0.0 });
        Chord { ubar: length - l0, sy: -g * d[2], sz: g * d[1], n, length, grad_sy, grad_sz, hess_g, grad_g }
    }

    /// Hessians over d: of l, s_y and s_z.
    fn hessians(&self, d: [f64; 3]) -> [[[f64; 3]; 3]; 3] {
        let mut hl = [[0.0; 3]; 3];
        for (i, row) in hl.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = ((i == j) as u8 as f64 - self.n[i] * self.n[j]) / self.length;
            }
        }
        let (hg, gg) = (&self.hess_g, &self.grad_g);
        let unit = |k: usize, i: usize| if k == i { 1.0 } else { 0.0 };
        let hy = std::array::from_fn(|i| {
            std::array::from_fn(|j| -d[2] * hg[i][j] - (unit(2, i) * gg[j] + gg[i] * unit(2, j)))
        });
        let hz = std::array::from_fn(|i| {
            std::array::from_fn(|j| d[1] * hg[i][j] + (unit(1, i) * gg[j] + gg[i] * unit(1, j)))
        });
        [hl, hy, hz]
    }
}

/// c = a x b.
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

/// The Levi-Civita symbol eps_abk.
fn levi_civita(a: usize, b: usize, k: usize) -> f64 {
    match (a, b, k) {
        (0, 1, 2) | (1, 2, 0) | (2, 0, 1) => 1.0,
        (0, 2, 1) | (2, 1, 0) | (1, 0, 2) => -1.0,
        _ => 0.0,
    }
}

/// Nonlinear part of the element (its co-rotational energy minus e^T K e / 2): internal force
/// f (12), tangent k (12 x 12, row-major, if given) and energy, at local coordinates e.
pub fn element_terms(el: &CorotationalBeam, e: &[f64], f: &mut [f64], k: Option<&mut [f64]>) -> f64 {
    let l0 = el.length;
    let kl = &el.stiffness;
    let chord = Chord::new(e, l0);
    let tau = 0.5 * (e[3] + e[9]);
    let (by, bz) = (chord.sy, chord.sz);
    let psi = [tau, by + 0.5 * tau * bz, bz - 0.5 * tau * by];
    let th = [[e[3], e[4], e[5]], [e[9], e[10], e[11]]];
    // g_i = th_i - psi - (psi x th_i) / 2: the rotation from the chord's frame to node i,
    // log(exp(-psi) exp(th_i)), to second order (Baker-Campbell-Hausdorff).
    let mut g = [0.0; 7];
    g[0] = chord.ubar;
    for (i, t) in th.iter().enumerate() {
        let c = cross(psi, *t);
        for a in 0..3 {
            g[1 + 3 * i + a] = t[a] - psi[a] - 0.5 * c[a];
        }
    }
    // Gradients over e of ubar, tau, by, bz and psi.
    let grad_ubar = lift(chord.n);
    let grad_by = lift(chord.grad_sy);
    let grad_bz = lift(chord.grad_sz);
    let mut grad_tau = [0.0; 12];
    grad_tau[3] = 0.5;
    grad_tau[9] = 0.5;
    let grad_psi = [
        grad_tau,
        std::array::from_fn(|i| grad_by[i] + 0.5 * (bz * grad_tau[i] + tau * grad_bz[i])),
        std::array::from_fn(|i| grad_bz[i] - 0.5 * (by * grad_tau[i] + tau * grad_by[i])),
    ];
    // J = dg/de (7 x 12): d(psi x th_i) = dpsi x th_i + psi x dth_i.
    let mut jac = [[0.0; 12]; 7];
    jac[0] = grad_ubar;
    for (i, t) in th.iter().enumerate() {
        let offset = 3 + 6 * i;
        for a in 0..3 {
            let row = &mut jac[1 + 3 * i + a];
            row[offset + a] += 1.0;
            for (m, r) in row.iter_mut().enumerate() {
                *r -= grad_psi[a][m];
            }
            // -(1/2) (psi x th)_a = -(1/2) eps_abk psi_b th_k.
            for b in 0..3 {
                for c in 0..3 {
                    let eps = levi_civita(a, b, c);
                    if eps != 0.0 {
                        for (m, r) in row.iter_mut().enumerate() {
                            *r -= 0.5 * eps * grad_psi[b][m] * t[c];
                        }
                        row[offset + c] -= 0.5 * eps * psi[b];
                    }
                }
            }
        }
    }
    let k7 = |a: usize, b: usize| kl[12 * REDUCED[a] + REDUCED[b]];
    let s: [f64; 7] = std::array::from_fn(|a| (0..7).map(|b| k7(a, b) * g[b]).sum());
    let ke: [f64; 12] = std::array::from_fn(|i| (0..12).map(|j| kl[12 * i + j] * e[j]).sum());
    for i in 0..12 {
        f[i] = (0..7).map(|a| jac[a][i] * s[a]).sum::<f64>() - ke[i];
    }
    if let Some(k) = k {
        // J^T K7 J - K.
        let kj: [[f64; 12]; 7] =
            std::array::from_fn(|a| std::array::from_fn(|j| (0..7).map(|b| k7(a, b) * jac[b][j]).sum()));
        for i in 0..12 {
            for j in 0..12 {
                k[12 * i + j] = (0..7).map(|a| jac[a][i] * kj[a][j]).sum::<f64>() - kl[12 * i + j];
            }
        }
        // sum_k s_k d2g_k/de2 = s_ubar d2l + sum_a w_a d2psi_a + the products of dpsi and dth
        // of the terms (psi x th_i) / 2, with w = -sum_i (s_i + (th_i x s_i) / 2) (s_i: the
        // forces of g_i).
        let mut w = [0.0; 3];
        for (i, t) in th.iter().enumerate() {
            let si = [s[1 + 3 * i], s[2 + 3 * i], s[3 + 3 * i]];
            let ts = cross(*t, si);
            for a in 0..3 {
                w[a] -= si[a] + 0.5 * ts[a];
            }
            // -(1/2) sum_abk eps_abk s_ia (dpsi_b dth_k^T + dth_k dpsi_b^T).
            for a in 0..3 {
                for b in 0..3 {
                    for c in 0..3 {
                        let eps = levi_civita(a, b, c);
                        if eps != 0.0 {
                            let v = -0.5 * eps * si[a];
                            let column = 3 + 6 * i + c;
                            for m in 0..12 {
                                k[12 * m + column] += v * grad_psi[b][m];
                                k[12 * column + m] += v * grad_psi[b][m];
                            }
                        }
                    }
                }
            }
        }
        // d2psi_y = d2by + tau/2 d2bz + (grad tau grad bz^T + grad bz grad tau^T)/2,
        // d2psi_z = d2bz - tau/2 d2by - (grad tau grad by^T + grad by grad tau^T)/2; psi_x is
        // linear.
        let (cy, cz) = (w[1], w[2]);
        let d = [l0 + e[6] - e[0], e[7] - e[1], e[8] - e[2]];
        let [hl, hy, hz] = chord.hessians(d);
        let (wy, wz) = (cy - 0.5 * tau * cz, cz + 0.5 * tau * cy);
        let slots = [0usize, 1, 2, 6, 7, 8];
        for &i in &slots {
            for &j in &slots {
                let (a, b) = (i % 6, j % 6);
                let h = s[0] * hl[a][b] + wy * hy[a][b] + wz * hz[a][b];
                k[12 * i + j] += sign_of(i) * sign_of(j) * h;
            }
        }
        for i in 0..12 {
            for j in 0..12 {
                k[12 * i + j] += 0.5 * cy * (grad_tau[i] * grad_bz[j] + grad_bz[i] * grad_tau[j])
                    - 0.5 * cz * (grad_tau[i] * grad_by[j] + grad_by[i] * grad_tau[j]);
            }
        }
    }
    let quadratic = |v: &[f64], n: usize, m: &dyn Fn(usize, usize) -> f64| -> f64 {
        (0..n).map(|a| v[a] * (0..n).map(|b| m(a, b) * v[b]).sum::<f64>()).sum()
    };
    0.5 * quadratic(&g, 7, &k7) - 0.5 * quadratic(e, 12, &|i, j| kl[12 * i + j])
}

/// -1 for the first node's translations (slots 0-2), +1 for the second's (6-8).
fn sign_of(i: usize) -> f64 {
    if i < 3 {
        -1.0
    } else {
        1.0
    }
}

/// Adds the nonlinear co-rotational forces of all elements to `out` (n_f) and, with
/// `tangent = Some((w, values))`, w times their tangent to the values of the elastic
/// pattern. Returns the nonlinear part of the strain energy.
pub fn add_corotational(
    elements: &[CorotationalBeam],
    qf: &[f64],
    out: &mut [f64],
    tangent: Option<(f64, &mut [f64])>,
) -> f64 {
    add_elements(elements, qf, out, tangent, |_| 12, element_terms)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::{Beam, Material, Section};
    use crate::math::Vec3;
    use crate::testing::{assert_all_close, assert_close};

    const LENGTH: f64 = 0.7;

    /// An element of a steel-like beam of unequal bending stiffnesses, Euler-Bernoulli or
    /// Timoshenko, in its own axes (e = q_l).
    fn element(shear: bool) -> CorotationalBeam {
        let section = Section::new("test", 2e-4, 3e-9, 8e-9, 5e-9).unwrap();
        let beam = Beam { section, orientation: Vec3([0.0, 1.0, 0.0]), shear };
        let material = Material::new("test", 2e11, 0.3, 7800.0).unwrap();
        let (axes, length, k) =
            beam.corotational_terms(&material, &[Vec3::ZERO, Vec3([LENGTH, 0.0, 0.0])]).unwrap();
        assert_eq!(axes.0, [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);
        let map = (0..144).map(|k| if k % 13 == 0 { 1.0 } else { 0.0 }).collect();
        CorotationalBeam::new((0..12).collect(), map, length, k.concat())
    }

    fn terms(el: &CorotationalBeam, e: &[f64], tangent: bool) -> (f64, Vec<f64>, Vec<f64>) {
        let mut f = vec![0.0; 12];
        let mut k = vec![0.0; 144];
        let u = element_terms(el, e, &mut f, if tangent { Some(&mut k) } else { None });
        (u, f, k)
    }

    /// Linear plus nonlinear: the element's whole energy and force.
    fn total(el: &CorotationalBeam, e: &[f64]) -> (f64, Vec<f64>) {
        let (u, f, _) = terms(el, e, false);
        let ke: Vec<f64> = (0..12).map(|i| (0..12).map(|j| el.stiffness[12 * i + j] * e[j]).sum()).collect();
        let linear = 0.5 * (0..12).map(|i| e[i] * ke[i]).sum::<f64>();
        (u + linear, f.iter().zip(&ke).map(|(a, b)| a + b).collect())
    }

    /// Rodrigues: the rotation vector omega applied to x.
    fn rotate(omega: [f64; 3], x: [f64; 3]) -> [f64; 3] {
        let w = Vec3(omega);
        let angle = w.norm();
        let k = w * (1.0 / angle);
        let v = Vec3(x);
        let r = v * angle.cos() + k.cross(&v) * angle.sin() + k * (k.dot(&v) * (1.0 - angle.cos()));
        r.0
    }

    /// Local coordinates of the element turned rigidly by omega and moved by t.
    fn rigid(omega: [f64; 3], t: [f64; 3]) -> [f64; 12] {
        let end = rotate(omega, [LENGTH, 0.0, 0.0]);
        let mut e = [0.0; 12];
        for i in 0..3 {
            e[i] = t[i];
            e[3 + i] = omega[i];
            e[6 + i] = t[i] + end[i] - if i == 0 { LENGTH } else { 0.0 };
            e[9 + i] = omega[i];
        }
        e
    }

    #[test]
    fn force_and_tangent_are_derivatives_of_the_energy() {
        for shear in [false, true] {
            let el = element(shear);
            for scale in [0.02, 0.3] {
                let e: Vec<f64> = (0..12)
                    .map(|k| scale * (((k * 7 % 5) as f64 - 2.0) * 0.4 + 0.1 * k as f64 - 0.5))
                    .collect();
                let (_, f, k) = terms(&el, &e, true);
                let h = 1e-6 * scale;
                let force_scale = f.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                let tangent_scale = k.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                for j in 0..12 {
                    let (mut ep, mut em) = (e.clone(), e.clone());
                    ep[j] += h;
                    em[j] -= h;
                    let (up, fp, _) = terms(&el, &ep, false);
                    let (um, fm, _) = terms(&el, &em, false);
                    let fd = (up - um) / (2.0 * h);
                    assert_close(
                        fd,
                        f[j],
                        1e-6,
                        1e-6 * force_scale,
                        format_args!("force {j}, scale {scale}"),
                    );
                    let kd: Vec<f64> = (0..12).map(|i| (fp[i] - fm[i]) / (2.0 * h)).collect();
                    let column: Vec<f64> = (0..12).map(|i| k[i * 12 + j]).collect();
                    assert_all_close(
                        &kd,
                        &column,
                        1e-5,
                        1e-6 * tangent_scale,
                        format_args!("tangent column {j}, scale {scale}, shear {shear}"),
                    );
                }
            }
        }
    }

    #[test]
    fn a_rigid_turn_in_a_plane_through_the_element_stores_nothing() {
        let el = element(false);
        let stiffness = el.stiffness.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for angle in [0.5, 1.5, -1.5] {
            // About y, about z, and about an oblique axis perpendicular to the element.
            let (c, s) = (0.4f64.cos(), 0.4f64.sin());
            for omega in [[0.0, 0.0, angle], [0.0, angle, 0.0], [0.0, angle * c, angle * s]] {
                let e = rigid(omega, [0.01, -0.02, 0.03]);
                let (u, f) = total(&el, &e);
                assert_close(
                    u,
                    0.0,
                    0.0,
                    1e-10 * stiffness * LENGTH * LENGTH,
                    format_args!("energy at {omega:?}"),
                );
                assert_all_close(
                    &f,
                    &[0.0; 12],
                    0.0,
                    1e-10 * stiffness * LENGTH,
                    format_args!("force at {omega:?}"),
                );
                // The linear element alone (von Karman or none) would resist the turn.
                let (linear, _, _) = terms(&el, &e, false);
                assert!(linear.abs() > 1e-3 * stiffness * LENGTH * LENGTH, "{linear}");
            }
        }
    }

    #[test]
    fn a_rigid_turn_in_3d_leaves_a_third_order_force() {
        // The spurious force of a rigid rotation shrinks as |Omega|^3: 8 times for half the
        // angle (its terms of orders 1 and 2 vanish).
        let el = element(false);
        let direction = [0.3, 0.5, -0.4];
        let force = |a: f64| {
            let e = rigid(direction.map(|w| a * w), [0.0; 3]);
            let (_, f) = total(&el, &e);
            f.iter().map(|v| v * v).sum::<f64>().sqrt()
        };
        let (large, small) = (force(0.2), force(0.1));
        let ratio = large / small;
        eprintln!("rigid 3D turn: force {large:e} at 0.2, {small:e} at 0.1");
        assert!((7.0..9.5).contains(&ratio), "ratio {ratio} ({large:e}, {small:e})");
        // Of the size of E I / L |Omega|^3 (4 E I / L is the diagonal of a nodal rotation).
        let ke = el.stiffness[12 * 5 + 5];
        let omega = 0.1 * direction.iter().map(|w| w * w).sum::<f64>().sqrt();
        assert!(small < ke * omega.powi(3), "force {small:e} against 4 EI/L {ke:e}");
    }

    #[test]
    fn the_swing_factor_series_meets_its_closed_form() {
        // At the switch (s = u / x^2 = 0.01) both forms agree, and G_u, G_uu are the
        // derivatives of G.
        let x = 0.8;
        for u in [0.01 * x * x * (1.0 - 1e-12), 0.01 * x * x * (1.0 + 1e-12)] {
            let (g, gu, guu) = swing_factor(u, x);
            let r = u.sqrt();
            assert_close(g, r.atan2(x) / r, 1e-14, 0.0, "G");
            let h = 1e-6 * u;
            let (gp, gup, _) = swing_factor(u + h, x);
            let (gm, gum, _) = swing_factor(u - h, x);
            assert_close(gu, (gp - gm) / (2.0 * h), 1e-7, 0.0, "G_u");
            assert_close(guu, (gup - gum) / (2.0 * h), 1e-6, 0.0, "G_uu");
        }
        // The undeformed chord: G = 1 / x, G_u = -1 / (3 x^3), G_uu = 2 / (5 x^5).
        let (g, gu, guu) = swing_factor(0.0, x);
        assert_close(g, 1.0 / x, 1e-15, 0.0, "G(0)");
        assert_close(gu, -1.0 / (3.0 * x.powi(3)), 1e-15, 0.0, "G_u(0)");
        assert_close(guu, 2.0 / (5.0 * x.powi(5)), 1e-15, 0.0, "G_uu(0)");
    }

    type Matrix = [[f64; 3]; 3];

    fn exp(w: [f64; 3]) -> Matrix {
        let (x, y, z) = (rotate(w, [1.0, 0.0, 0.0]), rotate(w, [0.0, 1.0, 0.0]), rotate(w, [0.0, 0.0, 1.0]));
        std::array::from_fn(|r| [x[r], y[r], z[r]])
    }

    fn log(m: Matrix) -> [f64; 3] {
        let angle = ((m[0][0] + m[1][1] + m[2][2] - 1.0) / 2.0).clamp(-1.0, 1.0).acos();
        let s = angle / (2.0 * angle.sin());
        [(m[2][1] - m[1][2]) * s, (m[0][2] - m[2][0]) * s, (m[1][0] - m[0][1]) * s]
    }

    fn product(a: Matrix, b: Matrix) -> Matrix {
        std::array::from_fn(|r| std::array::from_fn(|c| (0..3).map(|k| a[r][k] * b[k][c]).sum()))
    }

    /// The element of local coordinates e turned as a whole by omega about its first node's
    /// undeformed position: positions rotated, nodal rotations composed.
    fn turned(e: &[f64; 12], omega: [f64; 3]) -> [f64; 12] {
        let mut out = [0.0; 12];
        for node in 0..2 {
            let o = 6 * node;
            let x = [e[o] + if node == 1 { LENGTH } else { 0.0 }, e[o + 1], e[o + 2]];
            let y = rotate(omega, x);
            let th = log(product(exp(omega), exp([e[o + 3], e[o + 4], e[o + 5]])));
            for i in 0..3 {
                out[o + i] = y[i] - if node == 1 && i == 0 { LENGTH } else { 0.0 };
                out[o + 3 + i] = th[i];
            }
        }
        out
    }

    #[test]
    fn a_superposed_rigid_rotation_changes_the_energy_at_second_order() {
        // A bent and twisted element (deformational rotations of 0.01-0.02) turned as a whole
        // by omega: the exact co-rotational energy would not change; composing the rotations
        // to second order (the term (psi x th_i) / 2) leaves a change of order |omega|^2 (4
        // times smaller for half the angle), where subtracting rotation vectors alone would
        // change it at first order, by about |omega| |phi| / 2 relative.
        let el = element(false);
        let mut e = [0.0; 12];
        e[1] = 0.002;
        e[2] = -0.001;
        e[3..6].copy_from_slice(&[0.01, -0.02, 0.015]);
        e[6] = 1e-5;
        e[7] = 0.004;
        e[8] = 0.003;
        e[9..12].copy_from_slice(&[-0.01, 0.01, 0.02]);
        let (energy, _) = total(&el, &e);
        let direction = [0.3 / 0.707, 0.5 / 0.707, -0.4 / 0.707];
        let change = |a: f64| (total(&el, &turned(&e, direction.map(|w| a * w))).0 - energy).abs() / energy;
        let (large, small) = (change(0.2), change(0.1));
        eprintln!("superposed rotation: relative energy change {large:e} at 0.2, {small:e} at 0.1");
        assert!(large / small > 3.5, "ratio {} ({large:e}, {small:e})", large / small);
        assert!(small < 0.02, "relative change {small:e} at 0.1 rad");
    }

    #[test]
    fn a_stretched_element_has_the_string_stiffness() {
        // Axial stretch eps0 L: along the infinitesimal turn d (v2 = l theta, thz = theta, with
        // l = (1 + eps0) L the chord) the whole tangent's quadratic form is N l theta^2, with
        // N = EA eps0 (the stretch's second derivative; the bending stays zero).
        let el = element(false);
        let eps0 = 1e-3;
        let mut e = [0.0; 12];
        e[6] = eps0 * LENGTH;
        let (_, _, k) = terms(&el, &e, true);
        let theta = 0.2;
        let mut d = [0.0; 12];
        let chord = (1.0 + eps0) * LENGTH;
        d[7] = chord * theta;
        d[5] = theta;
        d[11] = theta;
        let whole = |i: usize, j: usize| k[12 * i + j] + el.stiffness[12 * i + j];
        let quad: f64 = (0..12).map(|i| (0..12).map(|j| d[i] * whole(i, j) * d[j]).sum::<f64>()).sum();
        let axial = el.stiffness[12 * 6 + 6] * LENGTH;
        let expected = axial * eps0 * chord * theta * theta;
        assert_close(quad, expected, 1e-9, 0.0, "quadratic form");
    }

    #[test]
    fn the_nonlinear_part_vanishes_to_second_order_at_rest() {
        let el = element(true);
        let e0: Vec<f64> = (0..12).map(|k| 1e-3 * ((k * 5 % 7) as f64 - 3.0)).collect();
        let norm = |e: &[f64]| terms(&el, e, false).1.iter().map(|v| v * v).sum::<f64>().sqrt();
        let half: Vec<f64> = e0.iter().map(|v| v / 2.0).collect();
        let ratio = norm(&e0) / norm(&half);
        assert!((3.5..4.5).contains(&ratio), "ratio {ratio}");
    }
}
