//! The tangent of the inertia force: mass, velocity and position Jacobians of seed eq. 15,
//! analytic (checked against finite differences in the tests).

use super::*;

/// Analytic Jacobians of [`inertia_force`]: df/dq_dd (mass), df/dq_dot (velocity) and df/dq
/// (position). Reference blocks are dense; the (f, f) blocks are sum_kl c_kl I_kl with the
/// coefficient matrices below (the mass block has c = I: M_ff = sum_k I_kk).
#[derive(Clone, Debug, Default)]
pub struct FlexibleTangent {
    /// n_f.
    pub n: usize,
    /// (reference, reference) blocks of the mass, velocity and position Jacobians.
    pub reference: [[[f64; 7]; 7]; 3],
    /// (reference, f) blocks, 7 x n_f row-major, for mass, velocity and position.
    pub reference_elastic: [Vec<f64>; 3],
    /// (f, reference) blocks, n_f x 7 row-major, for mass, velocity and position.
    pub elastic_reference: [Vec<f64>; 3],
    /// Coefficients of the (f, f) velocity block sum_kl c_kl I_kl (2 w~).
    pub velocity_coefficients: Mat3,
    /// Coefficients of the (f, f) position block (alpha~ + w~ w~).
    pub position_coefficients: Mat3,
}

impl FlexibleTangent {
    /// Buffers for a body with `n` elastic coordinates.
    pub fn with_size(n: usize) -> Self {
        FlexibleTangent {
            n,
            reference_elastic: std::array::from_fn(|_| vec![0.0; 7 * n]),
            elastic_reference: std::array::from_fn(|_| vec![0.0; 7 * n]),
            ..Default::default()
        }
    }

    pub(crate) fn clear(&mut self) {
        self.reference = [[[0.0; 7]; 7]; 3];
        for b in self.reference_elastic.iter_mut().chain(self.elastic_reference.iter_mut()) {
            b.iter_mut().for_each(|x| *x = 0.0);
        }
    }
}

pub(crate) fn add34(out: &mut [[f64; 7]; 7], r0: usize, c0: usize, m: &[[f64; 4]; 3], w: f64) {
    for i in 0..3 {
        for j in 0..4 {
            out[r0 + i][c0 + j] += w * m[i][j];
        }
    }
}

pub(crate) fn mat3_times_34(a: &Mat3, b: &Mat34) -> Mat34 {
    crate::math::small::matmul(&a.0, b)
}

/// d(w x (w x s))/dw = w s^T + (w.s) I - 2 s w^T.
pub(crate) fn centripetal_jacobian(w: &Vec3, s: &Vec3) -> Mat3 {
    w.outer(s) + Mat3::IDENTITY.scale(w.dot(s)) - s.outer(w).scale(2.0)
}

/// Fills `t` with the Jacobians of [`inertia_force`] at (q, q_dot, q_dd). Without
/// `reference_elastic`, only the reference block and the coefficients of the elastic block:
/// the (reference, f) and (f, reference) blocks are left as they were, and so are the general
/// I_kl products only they need (a condensed body's Newton solver replaces them).
pub fn inertia_tangent(
    body: &FlexibleBody,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    scratch: &mut FlexibleScratch,
    t: &mut FlexibleTangent,
    reference_elastic: bool,
) {
    let k = quantities(body, q, qd, qdd, scratch, reference_elastic, true);
    tangent_from(body, qd, qdd, &k, scratch, t, reference_elastic);
}

/// [`inertia_tangent`] right after [`inertia_force_parts`] at the same state: without the
/// (reference, elastic) blocks it needs no other quantities than that force's (which the
/// scratch keeps), and a body of solids then takes no second pass over its scalar mass matrix.
pub fn inertia_tangent_after_force(
    body: &FlexibleBody,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    scratch: &mut FlexibleScratch,
    t: &mut FlexibleTangent,
    reference_elastic: bool,
) {
    match scratch.last.take() {
        Some(k) if !reference_elastic => tangent_from(body, qd, qdd, &k, scratch, t, false),
        _ => inertia_tangent(body, q, qd, qdd, scratch, t, reference_elastic),
    }
}

/// [`inertia_tangent`] from the quantities `k` of the state (q, qd, qdd).
pub(crate) fn tangent_from(
    body: &FlexibleBody,
    qd: &[f64],
    qdd: &[f64],
    k: &Quantities,
    scratch: &mut FlexibleScratch,
    t: &mut FlexibleTangent,
    reference_elastic: bool,
) {
    let nf = body.elastic_count;
    let d = RotationDerivatives::new(k, qd, qdd);
    if reference_elastic {
        t.clear();
    } else {
        t.reference = [[[0.0; 7]; 7]; 3];
    }
    t.n = nf;
    let [tm, tv, tx] = &mut t.reference;
    reference_mass_block(body, k, &d, tm);
    reference_velocity_block(k, &d, tv);
    reference_position_block(k, &d, tx);

    if nf == 0 {
        t.velocity_coefficients = Mat3::ZERO;
        t.position_coefficients = Mat3::ZERO;
        return;
    }
    // Coefficients of the elastic block: velocity 2 w~, position alpha~ + w~ w~.
    let ws = k.w.skew();
    t.velocity_coefficients = ws.scale(2.0);
    t.position_coefficients = k.alpha.skew() + ws.mul_mat(&ws);
    if reference_elastic {
        reference_elastic_blocks(body, qdd, k, &d, scratch, t);
    }
}

/// Derivatives of the rotational kinematics that the blocks of the tangent share.
struct RotationDerivatives {
    /// 2 L (w = 2 L p_dot).
    two_l: Mat34,
    /// dw/dp = 2 d(L p_dot)/dp.
    dw_dp: Mat34,
    /// dalpha/dp = 2 d(L p_dd)/dp.
    dalpha_dp: Mat34,
    /// d(A^T R_dd)/dp.
    dacc_dp: Mat34,
    /// s~.
    s_skew: Mat3,
    /// dh/dw for h = w x (w x s) + 2 w x (I1 qf_dot), the velocity terms of the translational
    /// force in the body frame.
    dh_dw: Mat3,
    /// dg/dw, g the rotational force.
    dg_dw: Mat3,
}

impl RotationDerivatives {
    fn new(k: &Quantities, qd: &[f64], qdd: &[f64]) -> Self {
        let (w, s, j) = (k.w, k.s, k.j);
        let pd = quat(qd);
        let pdd = quat(qdd);
        let r_dd = Vec3::from_slice(qdd);
        let two_l = crate::math::small::scaled(&k.l, 2.0);
        let dw_dp = crate::math::small::scaled(&l_jacobian(&pd), 2.0);
        let dalpha_dp = crate::math::small::scaled(&l_jacobian(&pdd), 2.0);
        let dacc_dp = rotate_transpose_jacobian(&k.p, &r_dd);
        let s_skew = s.skew();
        let jw = j.mul_vec(&w);
        let dh_dw = centripetal_jacobian(&w, &s) - k.i1_qfd.skew().scale(2.0);
        let mut dg_dw = w.skew().mul_mat(&j) - jw.skew();
        dg_dw = dg_dw + Mat3::IDENTITY.scale(2.0 * k.pm.trace()) - k.pm.transpose().scale(2.0);
        RotationDerivatives { two_l, dw_dp, dalpha_dp, dacc_dp, s_skew, dh_dw, dg_dw }
    }
}

/// (R, R), (R, p), (p, R), (p, p) of the mass matrix into `tm`.
fn reference_mass_block(
    body: &FlexibleBody,
    k: &Quantities,
    d: &RotationDerivatives,
    tm: &mut [[f64; 7]; 7],
) {
    let m_rp = mat3_times_34(&k.a.mul_mat(&d.s_skew), &d.two_l);
    for i in 0..3 {
        tm[i][i] = body.mass;
        for c in 0..4 {
            tm[i][3 + c] = -m_rp[i][c];
            tm[3 + c][i] = -m_rp[i][c];
        }
    }
    let m_pp = crate::math::small::tr_matmul(&d.two_l, &mat3_times_34(&k.j, &d.two_l));
    for r in 0..4 {
        for c in 0..4 {
            tm[3 + r][3 + c] = m_pp[r][c];
        }
    }
}

/// Velocity Jacobian's reference block into `tv`: f_R through w (and qf_dot), g through w
/// (and qf_dot).
fn reference_velocity_block(k: &Quantities, d: &RotationDerivatives, tv: &mut [[f64; 7]; 7]) {
    add34(tv, 0, 3, &mat3_times_34(&k.a.mul_mat(&d.dh_dw), &d.two_l), 1.0);
    let v_pp = crate::math::small::tr_matmul(&d.two_l, &mat3_times_34(&d.dg_dw, &d.two_l));
    for r in 0..4 {
        for c in 0..4 {
            tv[3 + r][3 + c] = v_pp[r][c];
        }
    }
}

/// Position Jacobian's reference block into `tx`: rotation of A, L and p inside w, alpha and
/// a = A^T R_dd.
fn reference_position_block(k: &Quantities, d: &RotationDerivatives, tx: &mut [[f64; 7]; 7]) {
    let (w, alpha, s) = (k.w, k.alpha, k.s);
    let h_r = alpha.cross(&s) + w.cross(&w.cross(&s)) + w.cross(&k.i1_qfd) * 2.0 + k.i1_qfdd;
    let mut k_rp = rotate_jacobian(&k.p, &h_r);
    let inner = {
        let mut m = mat3_times_34(&d.dh_dw, &d.dw_dp);
        crate::math::small::add_scaled(&mut m, -1.0, &mat3_times_34(&d.s_skew, &d.dalpha_dp));
        m
    };
    crate::math::small::add_scaled(&mut k_rp, 1.0, &mat3_times_34(&k.a, &inner));
    add34(tx, 0, 3, &k_rp, 1.0);
    let g = rotation_force(k);
    let inner_p = {
        let mut m = mat3_times_34(&d.s_skew, &d.dacc_dp);
        crate::math::small::add_scaled(&mut m, 1.0, &mat3_times_34(&k.j, &d.dalpha_dp));
        crate::math::small::add_scaled(&mut m, 1.0, &mat3_times_34(&d.dg_dw, &d.dw_dp));
        m
    };
    let k_pp_a = lt_jacobian(&g);
    let k_pp_b = crate::math::small::tr_matmul(&d.two_l, &inner_p);
    for r in 0..4 {
        for c in 0..4 {
            tx[3 + r][3 + c] = 2.0 * k_pp_a[r][c] + k_pp_b[r][c];
        }
    }
}

/// The (reference, f) and (f, reference) blocks of the mass, velocity and position
/// Jacobians into `t` (a body with elastic coordinates).
fn reference_elastic_blocks(
    body: &FlexibleBody,
    qdd: &[f64],
    k: &Quantities,
    d: &RotationDerivatives,
    scratch: &mut FlexibleScratch,
    t: &mut FlexibleTangent,
) {
    let nf = body.elastic_count;
    let (a, l, w) = (k.a, k.l, k.w);
    // Rows of J_f and sum_k N_kk.
    let mut jf = std::mem::take(&mut scratch.rows);
    jf_rows(scratch, nf, &mut jf);
    let mut rows = std::mem::take(&mut scratch.rows2);
    let n_trace: Vec<f64> = (0..nf).map(|c| (0..3).map(|kk| row(&scratch.n, kk, kk, nf)[c]).sum()).collect();
    let [rm, rv, rx] = &mut t.reference_elastic;
    let [fm, fv, fx] = &mut t.elastic_reference;

    // Mass: (R, f) = A I1, (p, f) = 2 L^T J_f; the (f, R), (f, p) blocks are their transposes.
    rotated_i1(body, &a, 1.0, rm);
    map_rows_2lt(&l, &jf, nf, rm, 3, nf, 0);
    for r in 0..7 {
        for c in 0..nf {
            fm[c * 7 + r] = rm[r * nf + c];
        }
    }

    // Velocity (R, f) = A 2 w~ I1; (p, f) = 2 L^T 2 (w (sum_k N_kk)^T - [sum_k w_k N_kl]_l).
    rotated_i1(body, &a.mul_mat(&w.skew()), 2.0, rv);
    for lrow in 0..3 {
        for c in 0..nf {
            let wn: f64 = (0..3).map(|kk| w[kk] * row(&scratch.n, kk, lrow, nf)[c]).sum();
            rows[lrow * nf + c] = 2.0 * (w[lrow] * n_trace[c] - wn);
        }
    }
    map_rows_2lt(&l, &rows, nf, rv, 3, nf, 0);
    // Velocity (f, p): the derivative in w times 2L.
    let dfw = elastic_force_rotation_rate(&w, scratch, &n_trace, nf);
    for c in 0..nf {
        for col in 0..4 {
            fv[c * 7 + 3 + col] = (0..3).map(|m| dfw[m * nf + c] * d.two_l[m][col]).sum();
        }
    }

    // Position (R, f) = A (alpha~ + w~w~) I1; (p, f) = 2 L^T dg/dq_f.
    rotated_i1(body, &a.mul_mat(&t.position_coefficients), 1.0, rx);
    rotation_force_elastic_rows(body, qdd, k, scratch, &n_trace, &mut rows);
    map_rows_2lt(&l, &rows, nf, rx, 3, nf, 0);

    // Position (f, p) = I1^T d(a)/dp + J_f^T dalpha/dp + (dfw) dw/dp.
    for c in 0..nf {
        for col in 0..4 {
            let mut v = 0.0;
            for m in 0..3 {
                v += body.i1[m * nf + c] * d.dacc_dp[m][col]
                    + jf[m * nf + c] * d.dalpha_dp[m][col]
                    + dfw[m * nf + c] * d.dw_dp[m][col];
            }
            fx[c * 7 + 3 + col] = v;
        }
    }
    scratch.rows = jf;
    scratch.rows2 = rows;
}

/// The first three rows of a (reference, f) block: (`m` `factor`) I1 (3 x n_f, row-major)
/// into `out`.
fn rotated_i1(body: &FlexibleBody, m: &Mat3, factor: f64, out: &mut [f64]) {
    let nf = body.elastic_count;
    for i in 0..3 {
        for c in 0..nf {
            out[i * nf + c] = (0..3).map(|kk| m.0[i][kk] * factor * body.i1[kk * nf + c]).sum();
        }
    }
}

/// d/dw of the elastic force's rotational terms, int rho S^T w~w~ u and 2 sum w~_kl z_kl
/// (3 x n_f, row-major): column m is sum_l w_l N_lm + sum_k w_k N_mk - 2 w_m sum_k N_kk -
/// 2 sum_kl eps_klm z_kl.
fn elastic_force_rotation_rate(w: &Vec3, scratch: &FlexibleScratch, n_trace: &[f64], nf: usize) -> Vec<f64> {
    let mut dfw = vec![0.0; 3 * nf];
    for m in 0..3 {
        for c in 0..nf {
            let mut v = -2.0 * w[m] * n_trace[c];
            for kk in 0..3 {
                v += w[kk] * (row(&scratch.n, kk, m, nf)[c] + row(&scratch.n, m, kk, nf)[c]);
                for l2 in 0..3 {
                    let e = levi(kk, l2, m);
                    if e != 0.0 {
                        v -= 2.0 * e * row(&scratch.z, kk, l2, nf)[c];
                    }
                }
            }
            dfw[m * nf + c] = v;
        }
    }
    dfw
}

/// dg/dq_f, the rotational force's derivative in the elastic coordinates (3 x n_f,
/// row-major), into `rows`; `n_trace`: sum_k N_kk.
fn rotation_force_elastic_rows(
    body: &FlexibleBody,
    qdd: &[f64],
    k: &Quantities,
    scratch: &mut FlexibleScratch,
    n_trace: &[f64],
    rows: &mut [f64],
) {
    let nf = body.elastic_count;
    let (w, alpha) = (k.w, k.alpha);
    let acc_skew = k.acc.skew();
    // A_i qf_dd: row i of d(J_f qf_dd)/dq_f.
    let qfdd = &qdd[REFERENCE_COORDINATES..REFERENCE_COORDINATES + nf];
    scratch.x[3 * nf..].iter_mut().for_each(|x| *x = 0.0);
    body.add_antisymmetric_products(1.0, qfdd, &mut scratch.x[3 * nf..]);
    let z_trace: Vec<f64> = (0..nf).map(|c| (0..3).map(|kk| row(&scratch.z, kk, kk, nf)[c]).sum()).collect();
    // d(J v)_i/dq_f = 2 v_i sum_k N_kk - sum_l v_l (N_il + N_li).
    let dj = |v: &Vec3, i: usize, c: usize| -> f64 {
        2.0 * v[i] * n_trace[c]
            - (0..3)
                .map(|l2| v[l2] * (row(&scratch.n, i, l2, nf)[c] + row(&scratch.n, l2, i, nf)[c]))
                .sum::<f64>()
    };
    for c in 0..nf {
        let djw = Vec3([dj(&w, 0, c), dj(&w, 1, c), dj(&w, 2, c)]);
        let w_djw = w.cross(&djw);
        let i1c = Vec3([body.i1[c], body.i1[nf + c], body.i1[2 * nf + c]]);
        let sa = acc_skew.mul_vec(&i1c);
        for i in 0..3 {
            let wz: f64 = (0..3).map(|kk| w[kk] * row(&scratch.z, kk, i, nf)[c]).sum();
            let jfx = scratch.x[3 * nf + i * nf + c];
            rows[i * nf + c] = -sa[i] + dj(&alpha, i, c) + w_djw[i] + 2.0 * (w[i] * z_trace[c] - wz) + jfx;
        }
    }
}
