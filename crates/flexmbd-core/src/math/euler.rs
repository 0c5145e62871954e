//! Euler parameters (unit quaternions) p = [e0, e1, e2, e3] and their exact derivatives.
//!
//! The rotation matrix is evaluated in the homogeneous quadratic form
//! A(p) = E(p) L(p)^T = (e0^2 - e.e) I + 2 e e^T + 2 e0 e~, which equals the usual
//! (2 e0^2 - 1) I + 2 (e e^T + e0 e~) when |p| = 1. Being a homogeneous quadratic in p makes
//! every second derivative a constant matrix (`bilinear_hessian`), which the Newton matrix and
//! the constraint acceleration terms (seed eq. 25) use.
//!
//! Angular velocities (Nikravesh 1988, ch. 6): body frame w_bar = 2 L(p) p_dot, global frame
//! w = 2 G(p) p_dot, with L = [-e, -e~ + e0 I] and G = [-e, e~ + e0 I]. Because L(p_dot) p_dot = 0,
//! the body angular acceleration is exactly 2 L(p) p_ddot.

use crate::math::small::matvec;
use crate::math::vec3::{Mat3, Vec3};

/// Euler parameters [e0, e1, e2, e3].
pub type Quaternion = [f64; 4];
/// 3 x 4 matrix, row-major.
pub type Mat34 = [[f64; 4]; 3];
/// 4 x 4 matrix, row-major.
pub type Mat44 = [[f64; 4]; 4];

fn vector_part(p: &Quaternion) -> Vec3 {
    Vec3([p[1], p[2], p[3]])
}

/// Rotation matrix A(p) (body to global), homogeneous quadratic form E L^T.
pub fn rotation_matrix(p: &Quaternion) -> Mat3 {
    let e0 = p[0];
    let e = vector_part(p);
    let d = e0 * e0 - e.dot(&e);
    let mut a = e.outer(&e).scale(2.0) + e.skew().scale(2.0 * e0);
    for k in 0..3 {
        a.0[k][k] += d;
    }
    a
}

/// L(p) = [-e, -e~ + e0 I] (3 x 4): body angular velocity w_bar = 2 L p_dot.
pub fn l_matrix(p: &Quaternion) -> Mat34 {
    let e0 = p[0];
    let e = vector_part(p);
    let s = e.skew();
    let mut l = [[0.0; 4]; 3];
    for i in 0..3 {
        l[i][0] = -e[i];
        for j in 0..3 {
            l[i][j + 1] = -s.0[i][j] + if i == j { e0 } else { 0.0 };
        }
    }
    l
}

/// G(p) = [-e, e~ + e0 I] (3 x 4): global angular velocity w = 2 G p_dot.
pub fn g_matrix(p: &Quaternion) -> Mat34 {
    let e0 = p[0];
    let e = vector_part(p);
    let s = e.skew();
    let mut g = [[0.0; 4]; 3];
    for i in 0..3 {
        g[i][0] = -e[i];
        for j in 0..3 {
            g[i][j + 1] = s.0[i][j] + if i == j { e0 } else { 0.0 };
        }
    }
    g
}

/// Body-frame angular velocity 2 L(p) p_dot.
pub fn body_angular_velocity(p: &Quaternion, p_dot: &Quaternion) -> Vec3 {
    let w = matvec(&l_matrix(p), p_dot);
    Vec3([2.0 * w[0], 2.0 * w[1], 2.0 * w[2]])
}

/// Global angular velocity 2 G(p) p_dot.
pub fn global_angular_velocity(p: &Quaternion, p_dot: &Quaternion) -> Vec3 {
    let w = matvec(&g_matrix(p), p_dot);
    Vec3([2.0 * w[0], 2.0 * w[1], 2.0 * w[2]])
}

/// Euler-parameter rates for a body-frame angular velocity: p_dot = L^T w_bar / 2 (|p| = 1).
pub fn rates_from_body_angular_velocity(p: &Quaternion, w_bar: &Vec3) -> Quaternion {
    let l = l_matrix(p);
    let mut pd = [0.0; 4];
    for i in 0..3 {
        for j in 0..4 {
            pd[j] += 0.5 * l[i][j] * w_bar[i];
        }
    }
    pd
}

/// Euler parameters of a proper rotation matrix (Shepperd's method, e0 >= 0).
pub fn from_rotation_matrix(a: &Mat3) -> Quaternion {
    let m = &a.0;
    let tr = a.trace();
    let candidates = [tr, m[0][0], m[1][1], m[2][2]];
    let (k, _) =
        candidates
            .iter()
            .enumerate()
            .fold((0, f64::NEG_INFINITY), |best, (i, &v)| if v > best.1 { (i, v) } else { best });
    let mut p = [0.0; 4];
    match k {
        0 => {
            let s = (1.0 + tr).sqrt() * 2.0;
            p = [0.25 * s, (m[2][1] - m[1][2]) / s, (m[0][2] - m[2][0]) / s, (m[1][0] - m[0][1]) / s];
        }
        _ => {
            let i = k - 1;
            let j = (i + 1) % 3;
            let l = (i + 2) % 3;
            let s = (1.0 + m[i][i] - m[j][j] - m[l][l]).sqrt() * 2.0;
            p[0] = (m[l][j] - m[j][l]) / s;
            p[i + 1] = 0.25 * s;
            p[j + 1] = (m[j][i] + m[i][j]) / s;
            p[l + 1] = (m[l][i] + m[i][l]) / s;
        }
    }
    if p[0] < 0.0 {
        p.iter_mut().for_each(|x| *x = -*x);
    }
    let n = p.iter().map(|x| x * x).sum::<f64>().sqrt();
    p.map(|x| x / n)
}

/// Constant Hessian 2 H(v, a) of the scalar p -> v . A(p) a (4 x 4, symmetric).
///
/// With H = [[v.a, (a x v)^T], [a x v, v a^T + a v^T - (v.a) I]] one has v . A(p) a = p^T H p.
pub fn bilinear_hessian(v: &Vec3, a: &Vec3) -> Mat44 {
    let va = v.dot(a);
    let c = a.cross(v);
    let mut h = [[0.0; 4]; 4];
    h[0][0] = 2.0 * va;
    for i in 0..3 {
        h[0][i + 1] = 2.0 * c[i];
        h[i + 1][0] = 2.0 * c[i];
        for j in 0..3 {
            let diag = if i == j { va } else { 0.0 };
            h[i + 1][j + 1] = 2.0 * (v[i] * a[j] + a[i] * v[j] - diag);
        }
    }
    h
}

/// Jacobian d(A(p) a)/dp (3 x 4) for a constant body vector `a`, in closed form:
/// 2 [e0 a + e x a, (a.e) I + e a^T - a e^T - e0 a~] (row k is 2 H(e_k, a) p).
pub fn rotate_jacobian(p: &Quaternion, a: &Vec3) -> Mat34 {
    let [e0, e1, e2, e3] = *p;
    let [a0, a1, a2] = a.0;
    let ae = a0 * e1 + a1 * e2 + a2 * e3;
    // Column 0: e0 a + e x a. Columns 1..3: (a.e) I + e a^T - a e^T - e0 a~.
    let (c0, c1, c2) =
        (e0 * a0 + e2 * a2 - e3 * a1, e0 * a1 + e3 * a0 - e1 * a2, e0 * a2 + e1 * a1 - e2 * a0);
    let m = [
        [ae + e1 * a0 - a0 * e1, e1 * a1 - a0 * e2 + e0 * a2, e1 * a2 - a0 * e3 - e0 * a1],
        [e2 * a0 - a1 * e1 - e0 * a2, ae + e2 * a1 - a1 * e2, e2 * a2 - a1 * e3 + e0 * a0],
        [e3 * a0 - a2 * e1 + e0 * a1, e3 * a1 - a2 * e2 - e0 * a0, ae + e3 * a2 - a2 * e3],
    ];
    [
        [2.0 * c0, 2.0 * m[0][0], 2.0 * m[0][1], 2.0 * m[0][2]],
        [2.0 * c1, 2.0 * m[1][0], 2.0 * m[1][1], 2.0 * m[1][2]],
        [2.0 * c2, 2.0 * m[2][0], 2.0 * m[2][1], 2.0 * m[2][2]],
    ]
}

/// Jacobian d(A(p)^T x)/dp (3 x 4) for a constant global vector `x`: A(p)^T = A(p*) with the
/// conjugate p* = [e0, -e], so it is `rotate_jacobian(p*, x)` with columns 1..3 negated.
pub fn rotate_transpose_jacobian(p: &Quaternion, x: &Vec3) -> Mat34 {
    let mut j = rotate_jacobian(&[p[0], -p[1], -p[2], -p[3]], x);
    for row in j.iter_mut() {
        for v in row[1..].iter_mut() {
            *v = -*v;
        }
    }
    j
}

/// Jacobian d(L(p)^T v)/dp = [[0, -v^T], [v, -v~]] (4 x 4) for a constant `v`.
pub fn lt_jacobian(v: &Vec3) -> Mat44 {
    let s = v.skew();
    let mut m = [[0.0; 4]; 4];
    for i in 0..3 {
        m[0][i + 1] = -v[i];
        m[i + 1][0] = v[i];
        for j in 0..3 {
            m[i + 1][j + 1] = -s.0[i][j];
        }
    }
    m
}

/// Jacobian d(G(p)^T v)/dp = [[0, -v^T], [v, v~]] (4 x 4) for a constant `v`.
pub fn gt_jacobian(v: &Vec3) -> Mat44 {
    let s = v.skew();
    let mut m = [[0.0; 4]; 4];
    for i in 0..3 {
        m[0][i + 1] = -v[i];
        m[i + 1][0] = v[i];
        for j in 0..3 {
            m[i + 1][j + 1] = s.0[i][j];
        }
    }
    m
}

/// Jacobian d(L(p) w)/dp = -L(w) (3 x 4) for a constant 4-vector `w`.
pub fn l_jacobian(w: &Quaternion) -> Mat34 {
    let mut m = l_matrix(w);
    m.iter_mut().flatten().for_each(|x| *x = -*x);
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::small::{matmul, tr_matmul};
    use crate::testing::{assert_all_close, assert_close};

    fn random_unit(seed: u64) -> Quaternion {
        let mut s = seed;
        let mut next = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((s >> 11) as f64) / ((1u64 << 53) as f64) * 2.0 - 1.0
        };
        let p = [next(), next(), next(), next()];
        let n = p.iter().map(|x| x * x).sum::<f64>().sqrt();
        p.map(|x| x / n)
    }

    /// Central difference (f(p + h e_k) - f(p - h e_k)) / 2h from `pp` = p + h e_k, `pm` = p - h e_k.
    fn central<const N: usize>(
        f: impl Fn(&Quaternion) -> [f64; N],
        pp: &Quaternion,
        pm: &Quaternion,
        h: f64,
    ) -> [f64; N] {
        let (fp, fm) = (f(pp), f(pm));
        std::array::from_fn(|i| (fp[i] - fm[i]) / (2.0 * h))
    }

    #[test]
    fn rotation_is_orthonormal_and_matches_standard_form() {
        for seed in 1..20 {
            let p = random_unit(seed);
            let a = rotation_matrix(&p);
            let ata = a.transpose().mul_mat(&a);
            assert_all_close(ata.0.as_flattened(), Mat3::IDENTITY.0.as_flattened(), 0.0, 1e-14, "A^T A");
            assert_close(a.determinant(), 1.0, 0.0, 1e-14, "det A");
            let e = Vec3([p[1], p[2], p[3]]);
            let mut std = e.outer(&e).scale(2.0) + e.skew().scale(2.0 * p[0]);
            for k in 0..3 {
                std.0[k][k] += 2.0 * p[0] * p[0] - 1.0;
            }
            assert_all_close(a.0.as_flattened(), std.0.as_flattened(), 0.0, 1e-14, "A, standard form");
            let back = from_rotation_matrix(&a);
            let sign = if back[0] * p[0] < 0.0 { -1.0 } else { 1.0 };
            assert_all_close(&back, &p.map(|x| sign * x), 0.0, 1e-12, "p from A");
        }
    }

    #[test]
    fn l_and_g_identities() {
        let p = random_unit(7);
        let l = l_matrix(&p);
        let g = g_matrix(&p);
        // L L^T = I, G = A L, L p = 0.
        let llt = matmul(&l, &{
            let mut t = [[0.0; 3]; 4];
            for i in 0..3 {
                for j in 0..4 {
                    t[j][i] = l[i][j];
                }
            }
            t
        });
        assert_all_close(llt.as_flattened(), Mat3::IDENTITY.0.as_flattened(), 0.0, 1e-14, "L L^T");
        let al = matmul(&rotation_matrix(&p).0, &l);
        assert_all_close(al.as_flattened(), g.as_flattened(), 0.0, 1e-14, "A L");
        assert_all_close(&matvec(&l, &p), &[0.0; 3], 0.0, 1e-15, "L p");
        let _ = tr_matmul(&l, &l);
    }

    #[test]
    fn closed_form_jacobians_equal_the_hessian_construction() {
        let p = [0.3, -0.5, 0.7, 0.2];
        let a = Vec3([0.4, -1.1, 0.9]);
        let j = rotate_jacobian(&p, &a);
        let jt = rotate_transpose_jacobian(&p, &a);
        for k in 0..3 {
            let row = matvec(&bilinear_hessian(&Vec3::unit(k), &a), &p);
            let row_t = matvec(&bilinear_hessian(&a, &Vec3::unit(k)), &p);
            assert_all_close(&row, &j[k], 0.0, 1e-14, format_args!("rotate_jacobian row {k}"));
            assert_all_close(&row_t, &jt[k], 0.0, 1e-14, format_args!("rotate_transpose_jacobian row {k}"));
        }
    }

    #[test]
    fn derivatives_match_finite_differences() {
        let p = [0.3, -0.5, 0.7, 0.2]; // deliberately not unit: derivatives are exact off the sphere
        let a = Vec3([0.4, -1.1, 0.9]);
        let v = Vec3([-0.7, 0.25, 1.3]);
        let w = [0.1, 0.2, -0.3, 0.4];
        let h = 1e-6;
        let jr = rotate_jacobian(&p, &a);
        let jrt = rotate_transpose_jacobian(&p, &v);
        let jlt = lt_jacobian(&v);
        let jl = l_jacobian(&w);
        let jgt = gt_jacobian(&v);
        for k in 0..4 {
            let mut pp = p;
            let mut pm = p;
            pp[k] += h;
            pm[k] -= h;
            let d_rot = (rotation_matrix(&pp).mul_vec(&a) - rotation_matrix(&pm).mul_vec(&a)) * (0.5 / h);
            let d_rott =
                (rotation_matrix(&pp).tr_mul_vec(&v) - rotation_matrix(&pm).tr_mul_vec(&v)) * (0.5 / h);
            let lt = |q: &Quaternion| crate::math::small::tr_matvec(&l_matrix(q), &v.0);
            let gt = |q: &Quaternion| crate::math::small::tr_matvec(&g_matrix(q), &v.0);
            let lw = |q: &Quaternion| matvec(&l_matrix(q), &w);
            let column = |m: &[[f64; 4]; 3]| m.map(|row| row[k]);
            let column4 = |m: &[[f64; 4]; 4]| m.map(|row| row[k]);
            assert_all_close(&d_rot.0, &column(&jr), 0.0, 1e-8, format_args!("d(A a)/dp{k}"));
            assert_all_close(&d_rott.0, &column(&jrt), 0.0, 1e-8, format_args!("d(A^T v)/dp{k}"));
            assert_all_close(
                &central(lw, &pp, &pm, h),
                &column(&jl),
                0.0,
                1e-8,
                format_args!("d(L w)/dp{k}"),
            );
            assert_all_close(
                &central(lt, &pp, &pm, h),
                &column4(&jlt),
                0.0,
                1e-8,
                format_args!("d(L^T v)/dp{k}"),
            );
            assert_all_close(
                &central(gt, &pp, &pm, h),
                &column4(&jgt),
                0.0,
                1e-8,
                format_args!("d(G^T v)/dp{k}"),
            );
            // Hessian of v . A a is the derivative of its gradient 2 H p.
            let hess = bilinear_hessian(&v, &a);
            let grad = |q: &Quaternion| matvec(&bilinear_hessian(&v, &a), q);
            assert_all_close(
                &central(grad, &pp, &pm, h),
                &column4(&hess),
                0.0,
                1e-8,
                format_args!("d(2 H p)/dp{k}"),
            );
        }
        // v . A a = p^T H p / 2 * 2: value check.
        let val = v.dot(&rotation_matrix(&p).mul_vec(&a));
        let hp = matvec(&bilinear_hessian(&v, &a), &p);
        let quad: f64 = (0..4).map(|i| p[i] * hp[i]).sum::<f64>() * 0.5;
        assert_close(val, quad, 0.0, 1e-14, "v . A a");
    }
}
