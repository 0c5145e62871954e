//! Two-node Euler-Bernoulli beam in 3D: the seed's planar element (eq. 2) in both bending
//! planes, with axial extension and torsion. Node coordinates: [u (3), theta (3)] per node, in
//! body axes; theta are small rotations, the slopes of the seed (eq. 6: finite rotations would
//! need slopes sin(theta); the element describes small rotations relative to the body frame,
//! which is why the floating frame exists).
//!
//! In local axes (x along the beam, y and z principal axes of the section), with xi = x / L:
//!   v(x) = H1 v1 + H2 L thz1 + H3 v2 + H4 L thz2,   thz = dv/dx,
//!   w(x) = H1 w1 - H2 L thy1 + H3 w2 - H4 L thy2,   thy = -dw/dx,
//!   u(x) = (1 - xi) u1 + xi u2,   thx(x) = (1 - xi) thx1 + xi thx2,
//! with H1 = 1 - 3 xi^2 + 2 xi^3, H2 = xi - 2 xi^2 + xi^3, H3 = 3 xi^2 - 2 xi^3,
//! H4 = xi^3 - xi^2 (the rows of the seed's eq. 2). A point (y, z) of the section moves by
//! [u, v, w] + theta x (0, y, z): the section turns with the slopes, which gives the rotary
//! inertia of the Rayleigh beam (kinematic coupling, seed section 6).
//!
//! With `shear` (Timoshenko beam), the section rotations are interpolated with the
//! interdependent shape functions of Friedman and Kosmatka (Computers & Structures 47, 1993),
//! exact for a static Timoshenko beam, with phi = 12 E I / (kappa G A L^2): the section no
//! longer turns with the slope, the shear strain is dv/dx - thz, and the rotary inertia follows
//! the section rotation. phi = 0 gives the Euler-Bernoulli element back.
//!
//! Mass points: 4-point Gauss along the axis times 4 section points at (+-a, 0), (0, +-b)
//! with a = sqrt(2 Iz / A), b = sqrt(2 Iy / A), weight A / 4 each. They integrate exactly every
//! integrand of the mass matrix and the invariants (degree <= 6 in x, <= 2 in y, z).

use crate::math::dense::DenseMatrix;
use crate::math::{Mat3, Vec3};

use crate::fem::element::{mass_matrix, ElementError, ElementKernel, ElementResult, MassPoint};
use crate::fem::material::Material;
use crate::fem::section::Section;

/// A two-node Euler-Bernoulli beam element.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Beam {
    /// Cross-section.
    pub section: Section,
    /// A vector in the local x-y plane (not parallel to the beam) that fixes the section's y
    /// axis: y = normalize(v - (v . x) x), z = x cross y.
    pub orientation: Vec3,
    /// Shear-deformable (Timoshenko) instead of Euler-Bernoulli.
    pub shear: bool,
}

/// 4-point Gauss-Legendre rule on [0, 1] (abscissa, weight).
pub(crate) const GAUSS4: [(f64, f64); 4] = [
    (0.069_431_844_202_973_71, 0.173_927_422_568_726_93),
    (0.330_009_478_207_571_87, 0.326_072_577_431_273_07),
    (0.669_990_521_792_428_1, 0.326_072_577_431_273_07),
    (0.930_568_155_797_026_3, 0.173_927_422_568_726_93),
];

impl Beam {
    /// Length and local axes (rows: x, y, z in body coordinates).
    fn frame(&self, x: &[Vec3]) -> ElementResult<(f64, Mat3)> {
        if x.len() != 2 {
            return Err(ElementError::Invalid { detail: format!("a beam has 2 nodes, got {}", x.len()) });
        }
        let d = x[1] - x[0];
        let length = d.norm();
        if !(length > 0.0) || !length.is_finite() {
            return Err(ElementError::Degenerate { detail: format!("beam length {length}") });
        }
        let ex = d * (1.0 / length);
        if !self.orientation.0.iter().all(|c| c.is_finite()) || self.orientation.norm() == 0.0 {
            return Err(ElementError::Invalid {
                detail: format!("orientation {:?} must be a finite, non-zero vector", self.orientation.0),
            });
        }
        let v = self.orientation - ex * self.orientation.dot(&ex);
        let vn = v.norm();
        if !(vn > 1e-8 * self.orientation.norm()) {
            return Err(ElementError::Invalid {
                detail: format!("orientation {:?} is parallel to the beam axis", self.orientation.0),
            });
        }
        let ey = v * (1.0 / vn);
        let ez = ex.cross(&ey);
        Ok((length, Mat3([ex.0, ey.0, ez.0])))
    }

    /// Shear parameters phi = 12 E I / (kappa G A L^2) for bending in the x-y plane (with Iz)
    /// and in the x-z plane (with Iy); zeros for Euler-Bernoulli beams.
    fn shear_parameters(&self, material: &Material, length: f64) -> (f64, f64) {
        if !self.shear {
            return (0.0, 0.0);
        }
        let s = &self.section;
        let ga = s.shear_factor * material.shear_modulus() * s.area * length * length;
        (12.0 * material.young_modulus * s.iz / ga, 12.0 * material.young_modulus * s.iy / ga)
    }

    /// Bending interpolation of one plane (Friedman and Kosmatka 1993): deflection and section
    /// rotation rows over (v1, th1, v2, th2) at xi, for the shear parameter phi.
    fn bending_rows(length: f64, xi: f64, phi: f64) -> ([f64; 4], [f64; 4]) {
        let l = length;
        let (xi2, xi3) = (xi * xi, xi * xi * xi);
        let c = 1.0 / (1.0 + phi);
        let v = [
            c * (2.0 * xi3 - 3.0 * xi2 - phi * xi + 1.0 + phi),
            c * l * (xi3 - (2.0 + phi / 2.0) * xi2 + (1.0 + phi / 2.0) * xi),
            c * (-2.0 * xi3 + 3.0 * xi2 + phi * xi),
            c * l * (xi3 - (1.0 - phi / 2.0) * xi2 - phi / 2.0 * xi),
        ];
        let theta = [
            c * 6.0 / l * (xi2 - xi),
            c * (3.0 * xi2 - (4.0 + phi) * xi + 1.0 + phi),
            -c * 6.0 / l * (xi2 - xi),
            c * (3.0 * xi2 - (2.0 - phi) * xi),
        ];
        (v, theta)
    }

    /// Shape matrix in local axes (3 x 12, local coordinates) of the point (xi, y, z), for
    /// the shear parameters (phi_y, phi_z) of the two bending planes.
    fn local_shape(length: f64, xi: f64, y: f64, z: f64, phi: (f64, f64), rotary: bool) -> [[f64; 12]; 3] {
        let (bv, bt) = Beam::bending_rows(length, xi, phi.0);
        let (cv, ct) = Beam::bending_rows(length, xi, phi.1);
        let (n1, n2) = (1.0 - xi, xi);
        // Interpolation rows over [u1, v1, w1, thx1, thy1, thz1, u2, v2, w2, thx2, thy2, thz2].
        let mut u = [0.0; 12];
        let mut v = [0.0; 12];
        let mut w = [0.0; 12];
        let mut thx = [0.0; 12];
        let mut thy = [0.0; 12];
        let mut thz = [0.0; 12];
        u[0] = n1;
        u[6] = n2;
        thx[3] = n1;
        thx[9] = n2;
        // x-y plane: (v, thz) with (v1, thz1, v2, thz2) at (1, 5, 7, 11).
        for (k, &dof) in [1usize, 5, 7, 11].iter().enumerate() {
            v[dof] = bv[k];
            thz[dof] = bt[k];
        }
        // x-z plane: (w, psi = -thy) with (w1, psi1, w2, psi2) at (2, 4, 8, 10), psi = -thy.
        for (k, &dof) in [2usize, 4, 8, 10].iter().enumerate() {
            let sign = if k % 2 == 1 { -1.0 } else { 1.0 };
            w[dof] = sign * cv[k];
            thy[dof] = -sign * ct[k];
        }
        // Displacement of the section point: [u, v, w] + theta x (0, y, z); without the
        // rotary inertia of bending, the axial part of the section's turn is left out.
        let bend = if rotary { 1.0 } else { 0.0 };
        let mut s = [[0.0; 12]; 3];
        for k in 0..12 {
            s[0][k] = u[k] + bend * (z * thy[k] - y * thz[k]);
            s[1][k] = v[k] - z * thx[k];
            s[2][k] = w[k] + y * thx[k];
        }
        s
    }

    /// Local stiffness matrix (12 x 12).
    fn local_stiffness(&self, material: &Material, length: f64) -> [[f64; 12]; 12] {
        let (e, g) = (material.young_modulus, material.shear_modulus());
        let sec = &self.section;
        let l = length;
        let mut k = [[0.0; 12]; 12];
        // Axial and torsion.
        let (ka, kt) = (e * sec.area / l, g * sec.torsion_constant / l);
        for (i, j, v) in [
            (0, 0, ka),
            (6, 6, ka),
            (0, 6, -ka),
            (6, 0, -ka),
            (3, 3, kt),
            (9, 9, kt),
            (3, 9, -kt),
            (9, 3, -kt),
        ] {
            k[i][j] += v;
        }
        // Bending in the x-y plane (v, thz) with E Iz and in the x-z plane (w, psi = -thy)
        // with E Iy: E I / ((1 + phi) L^3) [[12, 6L, -12, 6L], [6L, (4 + phi) L^2, -6L,
        // (2 - phi) L^2], ...] (Przemieniecki; phi = 0: Euler-Bernoulli).
        let (phi_y, phi_z) = self.shear_parameters(material, l);
        for (inertia, phi, dofs, signs) in [
            (sec.iz, phi_y, [1usize, 5, 7, 11], [1.0, 1.0, 1.0, 1.0]),
            (sec.iy, phi_z, [2usize, 4, 8, 10], [1.0, -1.0, 1.0, -1.0]),
        ] {
            let c = e * inertia / ((1.0 + phi) * l.powi(3));
            let m = [
                [12.0, 6.0 * l, -12.0, 6.0 * l],
                [6.0 * l, (4.0 + phi) * l * l, -6.0 * l, (2.0 - phi) * l * l],
                [-12.0, -6.0 * l, 12.0, -6.0 * l],
                [6.0 * l, (2.0 - phi) * l * l, -6.0 * l, (4.0 + phi) * l * l],
            ];
            for a in 0..4 {
                for b in 0..4 {
                    k[dofs[a]][dofs[b]] += c * signs[a] * signs[b] * m[a][b];
                }
            }
        }
        k
    }

    /// The data of the co-rotational elastic forces of the element (`body::corotational`):
    /// its local axes (rows: x along the beam, y and z the section axes, in body
    /// coordinates), its length and its local stiffness matrix (12 x 12, over [u1 v1 w1 thx1
    /// thy1 thz1 u2 ...] in those axes, shear included for Timoshenko beams): the element's
    /// share of K_ff is T^T K_local T with T the block diagonal of the axes.
    pub fn corotational_terms(
        &self,
        material: &Material,
        x: &[Vec3],
    ) -> ElementResult<(Mat3, f64, [[f64; 12]; 12])> {
        let (length, r) = self.frame(x)?;
        Ok((r, length, self.local_stiffness(material, length)))
    }

    /// Rotates a local 3 x 12 shape matrix to body axes: S_body = R^T S_local T, with T the
    /// block diagonal of R (rows of R: local axes in body coordinates).
    fn body_shape(r: &Mat3, local: &[[f64; 12]; 3]) -> Vec<f64> {
        let mut out = vec![0.0; 36];
        for row in 0..3 {
            for block in 0..4 {
                for col in 0..3 {
                    // (R^T S T)[row][3 block + col] = sum_ij R[i][row] S[i][3 block + j] R[j][col].
                    let mut acc = 0.0;
                    for i in 0..3 {
                        for j in 0..3 {
                            acc += r.0[i][row] * local[i][3 * block + j] * r.0[j][col];
                        }
                    }
                    out[row * 12 + 3 * block + col] = acc;
                }
            }
        }
        out
    }
}

impl ElementKernel for Beam {
    fn node_count(&self) -> usize {
        2
    }

    fn dofs_per_node(&self) -> usize {
        6
    }

    fn stiffness(&self, material: &Material, x: &[Vec3], out: &mut DenseMatrix) -> ElementResult<()> {
        let (length, r) = self.frame(x)?;
        let local = self.local_stiffness(material, length);
        // K_body = T^T K_local T, block by block.
        *out = DenseMatrix::zeros(12, 12);
        for bi in 0..4 {
            for bj in 0..4 {
                for a in 0..3 {
                    for b in 0..3 {
                        let mut acc = 0.0;
                        for i in 0..3 {
                            for j in 0..3 {
                                acc += r.0[i][a] * local[3 * bi + i][3 * bj + j] * r.0[j][b];
                            }
                        }
                        out.add(3 * bi + a, 3 * bj + b, acc);
                    }
                }
            }
        }
        Ok(())
    }

    fn nodal_stresses(
        &self,
        material: &Material,
        x: &[Vec3],
        u: &[f64],
        out: &mut [[f64; 6]],
    ) -> ElementResult<()> {
        let (length, r) = self.frame(x)?;
        let local = self.local_stiffness(material, length);
        // Displacements in element axes, end forces f = K_local u_local on the element.
        let mut ul = [0.0; 12];
        for block in 0..4 {
            for i in 0..3 {
                ul[3 * block + i] = (0..3).map(|j| r.0[i][j] * u[3 * block + j]).sum();
            }
        }
        let f: [f64; 12] = std::array::from_fn(|i| (0..12).map(|j| local[i][j] * ul[j]).sum());
        // Resultants on the +x face: minus the end force at node 1, the end force at node 2.
        for k in 0..6 {
            out[0][k] = -f[k];
            out[1][k] = f[6 + k];
        }
        Ok(())
    }

    fn mass_points(&self, material: &Material, x: &[Vec3], out: &mut Vec<MassPoint>) -> ElementResult<()> {
        let (length, r) = self.frame(x)?;
        let phi = self.shear_parameters(material, length);
        let sec = &self.section;
        let a = (2.0 * sec.iz / sec.area).sqrt();
        let b = (2.0 * sec.iy / sec.area).sqrt();
        let section_points = [(a, 0.0), (-a, 0.0), (0.0, b), (0.0, -b)];
        let (ey, ez) = (Vec3(r.0[1]), Vec3(r.0[2]));
        let ex = Vec3(r.0[0]);
        for &(xi, wx) in &GAUSS4 {
            for &(y, z) in &section_points {
                let local = Beam::local_shape(length, xi, y, z, phi, sec.rotary_inertia);
                out.push(MassPoint {
                    weight: material.density * sec.area / 4.0 * length * wx,
                    position: x[0] + ex * (xi * length) + ey * y + ez * z,
                    shape: Beam::body_shape(&r, &local),
                });
            }
        }
        Ok(())
    }

    fn lumped_mass_points(
        &self,
        material: &Material,
        x: &[Vec3],
        out: &mut Vec<MassPoint>,
    ) -> ElementResult<()> {
        // HRZ lumping of the consistent mass: the diagonal of M in local axes scaled so that
        // each node carries half the mass; the rotational diagonal with the same factor. The
        // rotational inertia of a node is carried by six points at +-d_k along the local axes
        // around it (S = [I, -r~] on the node's coordinates), each of a sixth of the node mass.
        let (length, r) = self.frame(x)?;
        let phi = self.shear_parameters(material, length);
        // Local consistent mass from local shape matrices (local axes).
        let rot = Mat3::IDENTITY;
        let mut local_points = Vec::with_capacity(16);
        let sec = &self.section;
        let a = (2.0 * sec.iz / sec.area).sqrt();
        let b = (2.0 * sec.iy / sec.area).sqrt();
        for &(xi, wx) in &GAUSS4 {
            for &(y, z) in &[(a, 0.0), (-a, 0.0), (0.0, b), (0.0, -b)] {
                let local = Beam::local_shape(length, xi, y, z, phi, sec.rotary_inertia);
                local_points.push(MassPoint {
                    weight: material.density * sec.area / 4.0 * length * wx,
                    position: Vec3::ZERO,
                    shape: Beam::body_shape(&rot, &local),
                });
            }
        }
        let mut m = DenseMatrix::zeros(12, 12);
        mass_matrix(&local_points, 12, &mut m);
        let mass = material.density * sec.area * length;
        let translational: f64 = [0, 6].iter().map(|&k| m.get(k, k)).sum::<f64>();
        let scale = mass / translational;
        let (ex, ey, ez) = (Vec3(r.0[0]), Vec3(r.0[1]), Vec3(r.0[2]));
        for node in 0..2 {
            let node_mass = mass / 2.0;
            let inertia = [
                m.get(6 * node + 3, 6 * node + 3),
                m.get(6 * node + 4, 6 * node + 4),
                m.get(6 * node + 5, 6 * node + 5),
            ]
            .map(|v| v * scale);
            // Points at +-d_k e_k with mass node_mass / 6: inertia about e1 = node_mass/3 (d2^2 + d3^2).
            let sum = inertia[0] + inertia[1] + inertia[2];
            let d2 = [0, 1, 2].map(|k| (1.5 * (sum - 2.0 * inertia[k]) / node_mass).max(0.0));
            for (k, axis) in [ex, ey, ez].iter().enumerate() {
                for sign in [1.0, -1.0] {
                    let offset = *axis * (sign * d2[k].sqrt());
                    // Displacement u_n + theta_n x offset = u_n - offset~ theta_n.
                    let mut shape = vec![0.0; 36];
                    let skew = offset.skew();
                    for row in 0..3 {
                        shape[row * 12 + 6 * node + row] = 1.0;
                        for col in 0..3 {
                            shape[row * 12 + 6 * node + 3 + col] = -skew.0[row][col];
                        }
                    }
                    out.push(MassPoint { weight: node_mass / 6.0, position: x[node] + offset, shape });
                }
            }
        }
        Ok(())
    }

    fn volume(&self, x: &[Vec3]) -> ElementResult<f64> {
        let (length, _) = self.frame(x)?;
        Ok(self.section.area * length)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{assert_all_close, assert_close};

    fn beam() -> (Beam, Material, [Vec3; 2]) {
        let section = Section::rectangle("test", 0.02, 0.05).unwrap();
        let beam = Beam { section, orientation: Vec3([0.3, 1.0, -0.2]), shear: false };
        let material = Material::new("steel", 2.1e11, 0.3, 7850.0).unwrap();
        (beam, material, [Vec3([0.1, -0.2, 0.3]), Vec3([0.9, 0.4, 0.1])])
    }

    #[test]
    fn seed_eq4_rigid_translations_are_reproduced() {
        let (b, m, x) = beam();
        let mut points = Vec::new();
        b.mass_points(&m, &x, &mut points).unwrap();
        let t = Vec3([0.7, -1.3, 2.1]);
        let mut q = [0.0; 12];
        q[..3].copy_from_slice(&t.0);
        q[6..9].copy_from_slice(&t.0);
        for p in &points {
            let u: [f64; 3] = std::array::from_fn(|row| (0..12).map(|k| p.shape[row * 12 + k] * q[k]).sum());
            assert_all_close(&u, &t.0, 0.0, 1e-14, "S t at a mass point");
        }
        let mut k = DenseMatrix::zeros(12, 12);
        b.stiffness(&m, &x, &mut k).unwrap();
        let mut f = vec![0.0; 12];
        k.mul_vec_add(1.0, &q, &mut f);
        assert_all_close(&f, &[0.0; 12], 0.0, 1e-6 * 2.1e11 * 1e-3, "K t");
        // Infinitesimal rigid rotations w: u = w x X at the nodes, theta = w.
        for axis in 0..3 {
            let w = Vec3::unit(axis);
            let mut q = [0.0; 12];
            for n in 0..2 {
                q[6 * n..6 * n + 3].copy_from_slice(&w.cross(&x[n]).0);
                q[6 * n + 3..6 * n + 6].copy_from_slice(&w.0);
            }
            let mut f = vec![0.0; 12];
            k.mul_vec_add(1.0, &q, &mut f);
            assert_all_close(
                &f,
                &[0.0; 12],
                0.0,
                1e-9 * 2.1e11 * 1e-4,
                format_args!("K q, rotation about {axis}"),
            );
        }
    }

    #[test]
    fn seed_eq2_eq5_eq6_slopes_describe_finite_rotation_only_as_sines() {
        // Planar element along x: nodes (0,0), (l,0). Nodal coordinates of a rigid rotation by
        // theta with slopes sin(theta) reproduce x (cos, sin) exactly (eqs. 5-6); with slopes
        // theta (small-rotation coordinates) the error is O(theta^3).
        let l = 2.0;
        let theta: f64 = 0.4;
        let (s, c) = theta.sin_cos();
        for (slope, exact) in [(s, true), (theta, false)] {
            let mut q = [0.0; 12];
            // u, v of node 2 relative to the undeformed (l, 0): (l cos - l, l sin); slopes.
            q[6] = l * c - l;
            q[7] = l * s;
            q[5] = slope;
            q[11] = slope;
            let mut max_error: f64 = 0.0;
            for i in 0..=10 {
                let xi = i as f64 / 10.0;
                let sh = Beam::local_shape(l, xi, 0.0, 0.0, (0.0, 0.0), true);
                let u: f64 = (0..12).map(|k| sh[0][k] * q[k]).sum();
                let v: f64 = (0..12).map(|k| sh[1][k] * q[k]).sum();
                let x = xi * l;
                max_error = max_error.max(((x + u) - x * c).abs()).max((v - x * s).abs());
            }
            if exact {
                assert!(max_error < 1e-14, "{max_error}");
            } else {
                assert!(max_error > 1e-3 && max_error < theta.powi(3) * l);
            }
        }
    }

    #[test]
    fn stiffness_is_the_textbook_beam_matrix_in_local_axes() {
        // A beam along the body x axis with y up: the body matrix equals the local one, and
        // a tip force P at a clamped end gives P L^3 / (3 E Iz) and slope P L^2 / (2 E Iz).
        let section = Section::new("s", 1e-3, 2e-7, 3e-7, 4e-7).unwrap();
        let b = Beam { section, orientation: Vec3([0.0, 1.0, 0.0]), shear: false };
        let m = Material::new("m", 7e10, 0.3, 2700.0).unwrap();
        let l = 1.5;
        let x = [Vec3::ZERO, Vec3([l, 0.0, 0.0])];
        let mut k = DenseMatrix::zeros(12, 12);
        b.stiffness(&m, &x, &mut k).unwrap();
        // Free dofs of node 2: solve K22 u = f for f = P e_y.
        let p = 10.0;
        let k22 = [[k.get(7, 7), k.get(7, 11)], [k.get(11, 7), k.get(11, 11)]];
        let det = k22[0][0] * k22[1][1] - k22[0][1] * k22[1][0];
        let v = k22[1][1] * p / det;
        let th = -k22[1][0] * p / det;
        let ei = 7e10 * 3e-7;
        assert_close(v, p * l.powi(3) / (3.0 * ei), 0.0, 1e-12 * v.abs(), "tip deflection");
        assert_close(th, p * l * l / (2.0 * ei), 0.0, 1e-12 * th.abs(), "tip slope");
    }

    #[test]
    fn timoshenko_cantilever_tip_deflection_includes_shear() {
        // Exact for the interdependent interpolation: P L^3 / (3 E I) + P L / (kappa G A).
        let section = Section::rectangle("s", 0.05, 0.1).unwrap();
        let m = Material::new("m", 2e11, 0.3, 7850.0).unwrap();
        let l = 0.4;
        let x = [Vec3::ZERO, Vec3([l, 0.0, 0.0])];
        for (shear, inertia, plane) in [(true, section.iz, 7usize), (true, section.iy, 8)] {
            let b = Beam { section, orientation: Vec3([0.0, 1.0, 0.0]), shear };
            let mut k = DenseMatrix::zeros(12, 12);
            b.stiffness(&m, &x, &mut k).unwrap();
            // Condense the free node 2 and solve for a unit force along y or z.
            let free: Vec<usize> = (6..12).collect();
            let mut a = [[0.0; 6]; 6];
            for (i, &fi) in free.iter().enumerate() {
                for (j, &fj) in free.iter().enumerate() {
                    a[i][j] = k.get(fi, fj);
                }
            }
            let mut rhs = [0.0; 6];
            rhs[plane - 6] = 1.0;
            // Gaussian elimination (the matrix is small and definite).
            for c in 0..6 {
                for r in c + 1..6 {
                    let f = a[r][c] / a[c][c];
                    for cc in c..6 {
                        a[r][cc] -= f * a[c][cc];
                    }
                    rhs[r] -= f * rhs[c];
                }
            }
            let mut u = [0.0; 6];
            for r in (0..6).rev() {
                u[r] = (rhs[r] - (r + 1..6).map(|c| a[r][c] * u[c]).sum::<f64>()) / a[r][r];
            }
            let expected = l.powi(3) / (3.0 * m.young_modulus * inertia)
                + l / (section.shear_factor * m.shear_modulus() * section.area);
            assert_close(u[plane - 6], expected, 1e-12, 0.0, format_args!("tip deflection along {plane}"));
        }
    }

    #[test]
    fn timoshenko_rotation_interpolation_reduces_to_the_slope_without_shear() {
        for xi in [0.0, 0.3, 0.8, 1.0] {
            let (v, t) = Beam::bending_rows(1.7, xi, 0.0);
            let h = 1e-6;
            let (vp, _) = Beam::bending_rows(1.7, xi + h, 0.0);
            let (vm, _) = Beam::bending_rows(1.7, xi - h, 0.0);
            let slope: [f64; 4] = std::array::from_fn(|k| (vp[k] - vm[k]) / (2.0 * h * 1.7));
            assert_all_close(&slope, &t, 0.0, 1e-8, format_args!("rotation rows at {xi}"));
            let _ = v;
        }
    }

    #[test]
    fn mass_points_integrate_the_mass_and_rotary_inertia_exactly() {
        let (b, m, x) = beam();
        let mut points = Vec::new();
        b.mass_points(&m, &x, &mut points).unwrap();
        let length = (x[1] - x[0]).norm();
        let mass = m.density * b.section.area * length;
        let total: f64 = points.iter().map(|p| p.weight).sum();
        assert_close(total, mass, 1e-12, 0.0, "total mass");
        let centroid = points.iter().fold(Vec3::ZERO, |s, p| s + p.position * p.weight) * (1.0 / total);
        let mid = (x[0] + x[1]) * 0.5;
        assert_close((centroid - mid).norm(), 0.0, 0.0, 1e-12, "centroid distance from the midpoint");
        // Second moment about the centroid along the axis: m L^2 / 12 + section terms.
        let (_, r) = b.frame(&x).unwrap();
        let ex = Vec3(r.0[0]);
        let along: f64 = points.iter().map(|p| p.weight * (p.position - mid).dot(&ex).powi(2)).sum();
        assert_close(
            along,
            mass * length * length / 12.0,
            0.0,
            1e-12 * along,
            "second moment along the axis",
        );
        let ey = Vec3(r.0[1]);
        let across: f64 = points.iter().map(|p| p.weight * (p.position - mid).dot(&ey).powi(2)).sum();
        let expected = m.density * length * b.section.iz;
        assert_close(across, expected, 1e-10, 0.0, "second moment across the axis");
        // Consistent mass matrix: symmetric positive definite, translational mass per direction.
        let mut mm = DenseMatrix::zeros(12, 12);
        mass_matrix(&points, 12, &mut mm);
        let mut sum_x = 0.0;
        let entries: Vec<f64> = (0..144).map(|k| mm.get(k / 12, k % 12)).collect();
        let transposed: Vec<f64> = (0..144).map(|k| mm.get(k % 12, k / 12)).collect();
        assert_all_close(&entries, &transposed, 0.0, 1e-12 * mass, "M against M^T");
        for i in [0, 6] {
            for j in [0, 6] {
                sum_x += mm.get(i, j);
            }
        }
        assert_close(sum_x, mass, 1e-12, 0.0, "translational mass along x");
    }

    #[test]
    fn bending_mass_is_the_classical_consistent_mass_plus_the_rayleigh_rotary_inertia() {
        // Along x: local axes are global. v-thz block (dofs 1, 5, 7, 11): rho A L / 420 [...]
        // and, with rotary inertia, rho Iz / (30 L) [...] (Przemieniecki); torsion (3, 9):
        // rho (Iy + Iz) L / 6 [[2, 1], [1, 2]] either way.
        let section = Section::rectangle("test", 0.02, 0.05).unwrap();
        let m = Material::new("steel", 2.1e11, 0.3, 7850.0).unwrap();
        let l = 0.8;
        let x = [Vec3::ZERO, Vec3([l, 0.0, 0.0])];
        let consistent = [
            [156.0, 22.0 * l, 54.0, -13.0 * l],
            [22.0 * l, 4.0 * l * l, 13.0 * l, -3.0 * l * l],
            [54.0, 13.0 * l, 156.0, -22.0 * l],
            [-13.0 * l, -3.0 * l * l, -22.0 * l, 4.0 * l * l],
        ];
        let rotary = [
            [36.0, 3.0 * l, -36.0, 3.0 * l],
            [3.0 * l, 4.0 * l * l, -3.0 * l, -l * l],
            [-36.0, -3.0 * l, 36.0, -3.0 * l],
            [3.0 * l, -l * l, -3.0 * l, 4.0 * l * l],
        ];
        let dofs = [1usize, 5, 7, 11];
        for with_rotary in [true, false] {
            let section = if with_rotary { section } else { section.without_rotary_inertia() };
            let b = Beam { section, orientation: Vec3([0.0, 1.0, 0.0]), shear: false };
            let mut points = Vec::new();
            b.mass_points(&m, &x, &mut points).unwrap();
            let mut mm = DenseMatrix::zeros(12, 12);
            mass_matrix(&points, 12, &mut mm);
            let scale = m.density * section.area * l;
            for (i, &a) in dofs.iter().enumerate() {
                for (j, &c) in dofs.iter().enumerate() {
                    let mut expected = scale / 420.0 * consistent[i][j];
                    if with_rotary {
                        expected += m.density * section.iz / (30.0 * l) * rotary[i][j];
                    }
                    assert_close(
                        mm.get(a, c),
                        expected,
                        0.0,
                        1e-12 * scale,
                        format_args!("M[{a}][{c}], rotary inertia {with_rotary}"),
                    );
                }
            }
            let polar = m.density * (section.iy + section.iz) * l;
            assert_close(mm.get(3, 3), polar / 3.0, 0.0, 1e-12 * scale, "torsional inertia");
            assert_close(mm.get(3, 9), polar / 6.0, 0.0, 1e-12 * scale, "torsional coupling");
        }
    }

    #[test]
    fn lumped_points_carry_the_mass_and_the_hrz_rotational_inertia() {
        let (b, m, x) = beam();
        let mut points = Vec::new();
        b.lumped_mass_points(&m, &x, &mut points).unwrap();
        let mass = m.density * b.section.area * (x[1] - x[0]).norm();
        let total: f64 = points.iter().map(|p| p.weight).sum();
        assert_close(total, mass, 1e-12, 0.0, "lumped total mass");
        let mut mm = DenseMatrix::zeros(12, 12);
        mass_matrix(&points, 12, &mut mm);
        for i in 0..12 {
            assert!(mm.get(i, i) > 0.0);
        }
    }

    #[test]
    fn degenerate_beams_are_rejected() {
        let (b, m, _) = beam();
        let mut k = DenseMatrix::zeros(12, 12);
        let x = [Vec3([1.0, 1.0, 1.0]), Vec3([1.0, 1.0, 1.0])];
        assert!(matches!(b.stiffness(&m, &x, &mut k), Err(ElementError::Degenerate { .. })));
        let along = Beam { orientation: Vec3([1.0, 0.0, 0.0]), ..b };
        let x = [Vec3::ZERO, Vec3([2.0, 0.0, 0.0])];
        assert!(matches!(along.stiffness(&m, &x, &mut k), Err(ElementError::Invalid { .. })));
    }
}
