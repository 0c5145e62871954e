//! Elastic and gravity forces of a deformable body, their Jacobians, and its kinetic, strain
//! and gravity energies.

use super::*;

/// Kinetic energy 1/2 q_dot^T M q_dot.
pub fn kinetic_energy(body: &FlexibleBody, q: &[f64], qd: &[f64], scratch: &mut FlexibleScratch) -> f64 {
    let nf = body.elastic_count;
    let r7 = REFERENCE_COORDINATES;
    let zero = vec![0.0; q.len()];
    // J_f qf_dot from P_kl = N_kl qf_dot (row i of J_f is N_jk - N_kj, (i, j, k) cyclic): the
    // quantities of the residual, without the rows N_kl themselves.
    let k = quantities(body, q, qd, &zero, scratch, false, true);
    let qfd = &qd[r7..r7 + nf];
    let v = Vec3::from_slice(qd);
    let jf_qfd = Vec3(std::array::from_fn(|i| {
        let (j, l) = ((i + 1) % 3, (i + 2) % 3);
        k.pm.0[j][l] - k.pm.0[l][j]
    }));
    let mut m_qfd = vec![0.0; nf];
    body.mass_matrix.mul_vec_add(1.0, qfd, &mut m_qfd);
    let attached = if body.attached.is_empty() { 0.0 } else { attached_kinetic_energy(body, q, qd) };
    0.5 * body.mass * v.dot(&v)
        + v.dot(&k.a.mul_vec(&(k.w.cross(&k.s) + k.i1_qfd)))
        + 0.5 * k.w.dot(&k.j.mul_vec(&k.w))
        + k.w.dot(&jf_qfd)
        + 0.5 * dot(qfd, &m_qfd)
        + attached
}

/// Power of the structural damping, -qf_dot^T D_ff qf_dot (W; `qd` the body's velocities).
pub fn damping_power(body: &FlexibleBody, qd: &[f64]) -> f64 {
    let nf = body.elastic_count;
    let qfd = &qd[REFERENCE_COORDINATES..REFERENCE_COORDINATES + nf];
    let mut dq = vec![0.0; nf];
    body.damping.mul_vec_add(1.0, qfd, &mut dq);
    -dot(qfd, &dq)
}

/// Strain energy 1/2 q_f^T K_ff q_f plus the nonlinear part of the geometric stiffness.
pub fn strain_energy(body: &FlexibleBody, q: &[f64]) -> f64 {
    let nf = body.elastic_count;
    let qf = &q[REFERENCE_COORDINATES..REFERENCE_COORDINATES + nf];
    let mut kq = vec![0.0; nf];
    body.stiffness.mul_vec_add(1.0, qf, &mut kq);
    let nonlinear = add_stiffening(&body.stiffening, qf, &mut kq.clone(), None)
        + add_corotational(&body.corotational, qf, &mut kq.clone(), None);
    0.5 * dot(qf, &kq) + nonlinear
}

/// Adds the elastic forces K_ff q_f + D_ff qf_dot (only with `linear`; see
/// [`add_linear_elastic_forces`]) plus the nonlinear beam forces of the geometric stiffness
/// (von Karman or co-rotational) to `out` (n_f) and, with `tangent = Some((position, velocity, values))`, their Jacobians
/// position dF/dq_f + velocity dF/dqf_dot to the elastic pattern values.
pub fn add_elastic_forces(
    body: &FlexibleBody,
    qf: &[f64],
    qfd: &[f64],
    out: &mut [f64],
    tangent: Option<(f64, f64, &mut [f64])>,
    linear: bool,
) {
    if linear {
        body.stiffness.mul_vec_add(1.0, qf, out);
        body.damping.mul_vec_add(1.0, qfd, out);
    }
    match tangent {
        Some((position, velocity, values)) => {
            body.stiffness.add_to_pattern(position, values);
            body.damping.add_to_pattern(velocity, values);
            add_stiffening(&body.stiffening, qf, out, Some((position, values)));
            if !body.corotational.is_empty() {
                add_corotational(&body.corotational, qf, out, Some((position, values)));
            }
        }
        None => {
            add_stiffening(&body.stiffening, qf, out, None);
            if !body.corotational.is_empty() {
                add_corotational(&body.corotational, qf, out, None);
            }
        }
    }
}

/// Adds the terms of the elastic rows that are linear with constant matrices,
/// M_ff qf_dd + D_ff qf_dot + K_ff q_f, into `out` (n_f): what [`inertia_force_parts`]
/// (with [`ElasticMass::Separate`], whose `mass_term` is M_ff qf_dd) and
/// [`add_elastic_forces`] without `linear` leave out.
pub fn add_linear_elastic_forces(
    body: &FlexibleBody,
    qf: &[f64],
    qfd: &[f64],
    mass_term: &[f64],
    out: &mut [f64],
) {
    out.iter_mut().zip(mass_term).for_each(|(o, m)| *o += m);
    body.damping.mul_vec_add(1.0, qfd, out);
    body.stiffness.mul_vec_add(1.0, qf, out);
}

/// Adds the generalized gravity force Q = int rho (dr/dq)^T g dV into `out` (7 + n_f):
/// [m g, d(A s)/dp^T g, I1^T A^T g] with s = s0 + I1 q_f.
pub fn add_gravity_force(body: &FlexibleBody, q: &[f64], gravity: &Vec3, out: &mut [f64]) {
    let nf = body.elastic_count;
    let r7 = REFERENCE_COORDINATES;
    let p = quat(q);
    let s = body.first_moment + body.i1_times(&q[r7..r7 + nf]);
    let rt = rotate_transpose_jacobian(&p, gravity);
    for k in 0..3 {
        out[k] += body.mass * gravity[k];
    }
    for c in 0..4 {
        out[3 + c] += (0..3).map(|i| rt[i][c] * s[i]).sum::<f64>();
    }
    let local = euler::rotation_matrix(&p).tr_mul_vec(gravity);
    body.add_i1_transpose_times(&local, &mut out[r7..r7 + nf]);
}

/// dQ/dq of gravity: the (p, p) block (4 x 4), and with `coupling` the (p, f) (4 x n_f
/// row-major) and (f, p) (n_f x 4 row-major) blocks.
pub fn gravity_jacobian(
    body: &FlexibleBody,
    q: &[f64],
    gravity: &Vec3,
    coupling: Option<(&mut [f64], &mut [f64])>,
) -> [[f64; 4]; 4] {
    let nf = body.elastic_count;
    let s = body.first_moment + body.i1_times(&q[REFERENCE_COORDINATES..REFERENCE_COORDINATES + nf]);
    gravity_jacobian_at(body, q, gravity, s, coupling)
}

/// [`gravity_jacobian`] with s = s0 + I1 q_f given (that of the inertia quantities, as
/// [`inertia_force_parts`] returns it).
pub fn gravity_jacobian_at(
    body: &FlexibleBody,
    q: &[f64],
    gravity: &Vec3,
    s: Vec3,
    coupling: Option<(&mut [f64], &mut [f64])>,
) -> [[f64; 4]; 4] {
    let nf = body.elastic_count;
    let p = quat(q);
    let Some((pf, fp)) = coupling else {
        return bilinear_hessian(gravity, &s);
    };
    let rt = rotate_transpose_jacobian(&p, gravity);
    for c in 0..nf {
        for a in 0..4 {
            let v: f64 = (0..3).map(|i| rt[i][a] * body.i1[i * nf + c]).sum();
            pf[a * nf + c] = v;
            fp[c * 4 + a] = v;
        }
    }
    bilinear_hessian(gravity, &s)
}

/// Potential energy of gravity -g . (m R + A s) (J).
pub fn gravity_potential(body: &FlexibleBody, q: &[f64], gravity: &Vec3) -> f64 {
    let nf = body.elastic_count;
    let r7 = REFERENCE_COORDINATES;
    let s = body.first_moment + body.i1_times(&q[r7..r7 + nf]);
    let a = euler::rotation_matrix(&quat(q));
    let attached = if body.attached.is_empty() { 0.0 } else { attached_gravity_potential(body, q, gravity) };
    -gravity.dot(&(Vec3::from_slice(q) * body.mass + a.mul_vec(&s))) + attached
}
