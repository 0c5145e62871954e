//! Rigid body in absolute coordinates q = [R (3), p (4 Euler parameters)]: the generalized
//! Newton-Euler equations (seed eq. 15 without elastic coordinates) derived by the principle of
//! virtual work (seed eqs. 11-13), written as the generalized inertia force
//!
//!   f_R = m R_dd + A (alpha x s + w x (w x s))
//!   f_p = 2 L^T (s x A^T R_dd + J alpha + w x J w)
//!
//! with body angular velocity w = 2 L p_dot, angular acceleration alpha = 2 L p_dd, first moment
//! s = m c (c: centre of mass in the body frame) and inertia tensor J about the body origin, both
//! constant in the body frame (the invariants of a rigid body). f = M(q) q_dd - F(q, q_dot) with
//! mass matrix M = [[m I, -2 A s~ L], [2 L^T s~ A^T, 4 L^T J L]] and quadratic velocity vector F.
//! The 4 x 4 block is singular along p; the normalization constraint p.p = 1 takes that direction.

use crate::error::{FlexmbdError, Result};
use crate::math::euler::{
    self, l_jacobian, l_matrix, lt_jacobian, rotate_jacobian, rotate_transpose_jacobian, Mat34, Quaternion,
};
use crate::math::small::{matmul, tr_matmul};
use crate::math::vec3::{symmetric_min_eigenvalue, Mat3, Vec3};

/// Number of coordinates of a rigid body.
pub const RIGID_COORDINATES: usize = 7;

/// Constant inertia data of a rigid body.
#[derive(Clone, Debug, PartialEq)]
pub struct RigidBody {
    /// Mass (kg).
    pub mass: f64,
    /// Centre of mass in the body frame (m).
    pub center_of_mass: Vec3,
    /// Inertia tensor about the centre of mass, body axes (kg m^2).
    pub inertia_center: Mat3,
    /// First moment s = m c about the body origin (kg m).
    pub first_moment: Vec3,
    /// Inertia tensor J about the body origin, body axes (kg m^2).
    pub inertia: Mat3,
}

impl RigidBody {
    /// Checks the data (positive mass, symmetric positive definite inertia, finite values) and
    /// shifts the inertia to the body origin (parallel-axis theorem).
    pub fn new(item: &str, mass: f64, inertia_center: Mat3, center_of_mass: Vec3) -> Result<Self> {
        let bad = |message: String| FlexmbdError::InvalidParameter { item: item.to_string(), message };
        if !(mass.is_finite() && mass > 0.0) {
            return Err(bad(format!("mass must be positive and finite, got {mass}")));
        }
        if !inertia_center.is_finite() || !center_of_mass.is_finite() {
            return Err(bad("inertia and centre of mass must be finite".to_string()));
        }
        let asym = inertia_center.max_abs_diff(&inertia_center.transpose());
        let scale = inertia_center.0.iter().flatten().fold(0.0f64, |a, x| a.max(x.abs()));
        if asym > 1e-12 * scale.max(f64::MIN_POSITIVE) {
            return Err(bad(format!("inertia tensor is not symmetric: {:?}", inertia_center.0)));
        }
        let min_eig = symmetric_min_eigenvalue(&inertia_center);
        if !(min_eig > 0.0) {
            return Err(bad(format!(
                "inertia tensor about the centre of mass must be positive definite (smallest eigenvalue {min_eig:e})"
            )));
        }
        let c = center_of_mass;
        let mut shift = c.outer(&c).scale(-mass);
        for k in 0..3 {
            shift.0[k][k] += mass * c.dot(&c);
        }
        Ok(RigidBody {
            mass,
            center_of_mass,
            inertia_center,
            first_moment: c * mass,
            inertia: inertia_center + shift,
        })
    }
}

/// Jacobians of the generalized inertia force: mass matrix df/dq_dd, velocity Jacobian
/// df/dq_dot and position Jacobian df/dq (all 7 x 7, row-major).
#[derive(Clone, Debug, Default)]
pub struct RigidTangent {
    /// df/dq_dd = M(q).
    pub mass: [[f64; 7]; 7],
    /// df/dq_dot (gyroscopic and centrifugal terms).
    pub velocity: [[f64; 7]; 7],
    /// df/dq at fixed q_dot and q_dd.
    pub position: [[f64; 7]; 7],
}

fn quat(q: &[f64]) -> Quaternion {
    [q[3], q[4], q[5], q[6]]
}

fn scale34(m: &Mat34, s: f64) -> Mat34 {
    crate::math::small::scaled(m, s)
}

/// Generalized inertia force f(q, q_dot, q_dd) of a rigid body into `out` (7).
pub fn inertia_force(body: &RigidBody, q: &[f64], qd: &[f64], qdd: &[f64], out: &mut [f64]) {
    let p = quat(q);
    let a = euler::rotation_matrix(&p);
    let w = euler::body_angular_velocity(&p, &quat(qd));
    let alpha = euler::body_angular_velocity(&p, &quat(qdd));
    let s = body.first_moment;
    let r_dd = Vec3::from_slice(qdd);
    // Translation: m R_dd + A (alpha x s + w x (w x s)).
    let v1 = alpha.cross(&s) + w.cross(&w.cross(&s));
    let f_r = r_dd * body.mass + a.mul_vec(&v1);
    // Rotation in the body frame, mapped to Euler parameters by 2 L^T.
    let v2 =
        s.cross(&a.tr_mul_vec(&r_dd)) + body.inertia.mul_vec(&alpha) + w.cross(&body.inertia.mul_vec(&w));
    let l = l_matrix(&p);
    out[..3].copy_from_slice(&f_r.0);
    for j in 0..4 {
        out[3 + j] = 2.0 * (0..3).map(|i| l[i][j] * v2[i]).sum::<f64>();
    }
}

/// The three Jacobians of [`inertia_force`].
pub fn inertia_tangent(body: &RigidBody, q: &[f64], qd: &[f64], qdd: &[f64], t: &mut RigidTangent) {
    let p = quat(q);
    let pd = quat(qd);
    let pdd = quat(qdd);
    let a = euler::rotation_matrix(&p);
    let l = l_matrix(&p);
    let w = euler::body_angular_velocity(&p, &pd);
    let alpha = euler::body_angular_velocity(&p, &pdd);
    let s = body.first_moment;
    let j = body.inertia;
    let m = body.mass;
    let r_dd = Vec3::from_slice(qdd);
    let s_skew = s.skew();
    // d(w x (w x s))/dw and d(w x J w)/dw.
    let g_w = w.outer(&s) + Mat3::IDENTITY.scale(w.dot(&s)) - s.outer(&w).scale(2.0);
    let h_w = w.skew().mul_mat(&j) - j.mul_vec(&w).skew();
    let two_l = scale34(&l, 2.0);
    // dw/dp = -2 L(p_dot), dalpha/dp = -2 L(p_dd).
    let dw_dp = scale34(&l_jacobian(&pd), 2.0);
    let dalpha_dp = scale34(&l_jacobian(&pdd), 2.0);
    let v1 = alpha.cross(&s) + w.cross(&w.cross(&s));
    let v2 = s.cross(&a.tr_mul_vec(&r_dd)) + j.mul_vec(&alpha) + w.cross(&j.mul_vec(&w));

    *t = RigidTangent::default();
    // Mass matrix.
    let m_rp = scale34(&matmul(&a.mul_mat(&s_skew).0, &l), -2.0);
    let m_pp = tr_matmul(&two_l, &matmul(&j.0, &two_l));
    for i in 0..3 {
        t.mass[i][i] = m;
        for k in 0..4 {
            t.mass[i][3 + k] = m_rp[i][k];
            t.mass[3 + k][i] = m_rp[i][k];
        }
    }
    for i in 0..4 {
        for k in 0..4 {
            t.mass[3 + i][3 + k] = m_pp[i][k];
        }
    }
    // Velocity Jacobian: only through w = 2 L p_dot.
    let d_rp = matmul(&a.mul_mat(&g_w).0, &two_l);
    let d_pp = tr_matmul(&two_l, &matmul(&h_w.0, &two_l));
    for i in 0..3 {
        for k in 0..4 {
            t.velocity[i][3 + k] = d_rp[i][k];
        }
    }
    for i in 0..4 {
        for k in 0..4 {
            t.velocity[3 + i][3 + k] = d_pp[i][k];
        }
    }
    // Position Jacobian: A(p), L(p), and p inside w and alpha.
    let inner_r = {
        let mut m1 = matmul(&s_skew.scale(-1.0).0, &dalpha_dp);
        crate::math::small::add_scaled(&mut m1, 1.0, &matmul(&g_w.0, &dw_dp));
        m1
    };
    let mut k_rp = rotate_jacobian(&p, &v1);
    crate::math::small::add_scaled(&mut k_rp, 1.0, &matmul(&a.0, &inner_r));
    let inner_p = {
        let mut m2 = matmul(&s_skew.0, &rotate_transpose_jacobian(&p, &r_dd));
        crate::math::small::add_scaled(&mut m2, 1.0, &matmul(&j.0, &dalpha_dp));
        crate::math::small::add_scaled(&mut m2, 1.0, &matmul(&h_w.0, &dw_dp));
        m2
    };
    let k_pp_a = lt_jacobian(&v2);
    let k_pp_b = tr_matmul(&two_l, &inner_p);
    for i in 0..3 {
        for k in 0..4 {
            t.position[i][3 + k] = k_rp[i][k];
        }
    }
    for i in 0..4 {
        for k in 0..4 {
            t.position[3 + i][3 + k] = 2.0 * k_pp_a[i][k] + k_pp_b[i][k];
        }
    }
}

/// Kinetic energy 1/2 q_dot^T M q_dot.
pub fn kinetic_energy(body: &RigidBody, q: &[f64], qd: &[f64]) -> f64 {
    let p = quat(q);
    let a = euler::rotation_matrix(&p);
    let w = euler::body_angular_velocity(&p, &quat(qd));
    let v = Vec3::from_slice(qd);
    0.5 * body.mass * v.dot(&v)
        + v.dot(&a.mul_vec(&w.cross(&body.first_moment)))
        + 0.5 * w.dot(&body.inertia.mul_vec(&w))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{assert_all_close, assert_close};

    fn body() -> RigidBody {
        let inertia = Mat3([[0.3, 0.02, -0.01], [0.02, 0.5, 0.03], [-0.01, 0.03, 0.4]]);
        RigidBody::new("test", 2.5, inertia, Vec3([0.1, -0.2, 0.3])).unwrap()
    }

    fn state() -> ([f64; 7], [f64; 7], [f64; 7]) {
        let mut p = [0.8, 0.2, -0.4, 0.3];
        let n = p.iter().map(|x| x * x).sum::<f64>().sqrt();
        p.iter_mut().for_each(|x| *x /= n);
        let q = [0.5, -1.0, 2.0, p[0], p[1], p[2], p[3]];
        let qd = [0.3, 0.1, -0.7, 0.4, -0.2, 0.9, 0.1];
        let qdd = [1.1, -0.4, 0.6, -0.3, 0.8, 0.2, -0.5];
        (q, qd, qdd)
    }

    #[test]
    fn tangent_matches_finite_differences() {
        let b = body();
        let (q, qd, qdd) = state();
        let mut t = RigidTangent::default();
        inertia_tangent(&b, &q, &qd, &qdd, &mut t);
        let h = 1e-6;
        for which in 0..3 {
            for k in 0..7 {
                let (mut fp, mut fm) = ([0.0; 7], [0.0; 7]);
                let perturb = |s: f64, out: &mut [f64; 7]| {
                    let (mut a, mut b1, mut c) = (q, qd, qdd);
                    match which {
                        0 => c[k] += s,
                        1 => b1[k] += s,
                        _ => a[k] += s,
                    }
                    inertia_force(&b, &a, &b1, &c, out);
                };
                perturb(h, &mut fp);
                perturb(-h, &mut fm);
                let analytic = match which {
                    0 => &t.mass,
                    1 => &t.velocity,
                    _ => &t.position,
                };
                let fd: [f64; 7] = std::array::from_fn(|i| (fp[i] - fm[i]) / (2.0 * h));
                let column = analytic.map(|row| row[k]);
                assert_all_close(
                    &column,
                    &fd,
                    1e-7,
                    1e-7,
                    format_args!("block {which}, column {k}: analytic against fd"),
                );
            }
        }
    }

    #[test]
    fn force_is_mass_matrix_times_acceleration_plus_velocity_terms() {
        let b = body();
        let (q, qd, qdd) = state();
        let mut t = RigidTangent::default();
        inertia_tangent(&b, &q, &qd, &qdd, &mut t);
        let mut f = [0.0; 7];
        let mut f0 = [0.0; 7];
        inertia_force(&b, &q, &qd, &qdd, &mut f);
        inertia_force(&b, &q, &qd, &[0.0; 7], &mut f0);
        let difference: [f64; 7] = std::array::from_fn(|i| f[i] - f0[i]);
        let mq: [f64; 7] = std::array::from_fn(|i| (0..7).map(|k| t.mass[i][k] * qdd[k]).sum());
        assert_all_close(&difference, &mq, 0.0, 1e-12, "f(q_dd) - f(0) against M q_dd");
        // Symmetry of the mass matrix and kinetic energy = 1/2 qd^T M qd.
        let transposed: [[f64; 7]; 7] = std::array::from_fn(|i| std::array::from_fn(|k| t.mass[k][i]));
        assert_all_close(t.mass.as_flattened(), transposed.as_flattened(), 0.0, 1e-13, "M against M^T");
        let mut e = 0.0;
        for i in 0..7 {
            for k in 0..7 {
                e += 0.5 * qd[i] * t.mass[i][k] * qd[k];
            }
        }
        assert_close(e, kinetic_energy(&b, &q, &qd), 0.0, 1e-12, "kinetic energy from M");
    }

    #[test]
    fn bad_inertia_is_rejected() {
        assert!(RigidBody::new("b", 0.0, Mat3::IDENTITY, Vec3::ZERO).is_err());
        assert!(RigidBody::new("b", -1.0, Mat3::IDENTITY, Vec3::ZERO).is_err());
        assert!(RigidBody::new("b", 1.0, Mat3::diagonal(Vec3([1.0, 1.0, 0.0])), Vec3::ZERO).is_err());
        assert!(RigidBody::new("b", 1.0, Mat3::diagonal(Vec3([1.0, 1.0, f64::NAN])), Vec3::ZERO).is_err());
        let skew = Mat3([[1.0, 0.5, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);
        assert!(RigidBody::new("b", 1.0, skew, Vec3::ZERO).is_err());
    }
}
