//! The generalized inertia force of seed eq. 15 from the invariants of motion: the quantities
//! s, J, P, J_f, N_kl of a state (in the scratch), the force, and the elastic mass term.

use super::*;

/// Levi-Civita symbol eps_ikl.
pub(crate) fn levi(i: usize, k: usize, l: usize) -> f64 {
    match (i, k, l) {
        (0, 1, 2) | (1, 2, 0) | (2, 0, 1) => 1.0,
        (0, 2, 1) | (2, 1, 0) | (1, 0, 2) => -1.0,
        _ => 0.0,
    }
}

/// Per-body buffers of the flexible-body kernels (each 9 n_f unless noted).
#[derive(Clone, Debug, Default)]
pub struct FlexibleScratch {
    /// y_kl = I_kl q_f.
    pub y: Vec<f64>,
    /// z_kl = I_kl qf_dot.
    pub z: Vec<f64>,
    /// A_m qf_dot (3 n_f), then A_m qf_dd (3 n_f).
    pub x: Vec<f64>,
    /// N_kl = Ibar_kl + y_lk (the rows int rho u_k S_l).
    pub n: Vec<f64>,
    /// Scratch rows, 3 n_f.
    pub rows: Vec<f64>,
    /// Scratch rows, 3 n_f.
    pub rows2: Vec<f64>,
    /// Bodies of solids: node-wise M_s [q_f, qf_dot, qf_dd] (nodes x 9), see [`ScalarMass`].
    pub nodal: Vec<f64>,
    /// The vectors of those products spread over the nodes (nodes x 9, zero outside the
    /// coordinates' entries: see [`ScalarMass::products`]).
    pub gathered: Vec<f64>,
    /// M_ff qf_dd of the last inertia force with [`ElasticMass::Separate`] (n_f).
    pub mass_term: Vec<f64>,
    /// The quantities of the last [`inertia_force_parts`] (see [`inertia_tangent_after_force`]).
    pub(crate) last: Option<Quantities>,
}

impl FlexibleScratch {
    /// Buffers for `body`.
    pub fn for_body(body: &FlexibleBody) -> Self {
        let mut scratch = Self::with_size(body.elastic_count);
        if let Some(sm) = &body.scalar_mass {
            scratch.nodal = vec![0.0; 9 * sm.nodes()];
            scratch.gathered = vec![0.0; 9 * sm.nodes()];
        }
        scratch
    }

    /// Buffers for a body with `n` elastic coordinates (and no scalar mass structure).
    pub fn with_size(n: usize) -> Self {
        FlexibleScratch {
            y: vec![0.0; 9 * n],
            z: vec![0.0; 9 * n],
            x: vec![0.0; 6 * n],
            n: vec![0.0; 9 * n],
            rows: vec![0.0; 3 * n],
            rows2: vec![0.0; 3 * n],
            nodal: Vec::new(),
            gathered: Vec::new(),
            mass_term: vec![0.0; n],
            last: None,
        }
    }
}

/// Configuration-dependent quantities of a body at one state (body frame).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Quantities {
    pub(crate) p: Quaternion,
    pub(crate) a: Mat3,
    pub(crate) l: Mat34,
    pub(crate) w: Vec3,
    pub(crate) alpha: Vec3,
    /// A^T R_dd.
    pub(crate) acc: Vec3,
    /// s = s0 + I1 q_f.
    pub(crate) s: Vec3,
    /// J = tr(U) I - U.
    pub(crate) j: Mat3,
    /// P_kl = N_kl qf_dot.
    pub(crate) pm: Mat3,
    /// J_f qf_dd.
    pub(crate) jf_qdd: Vec3,
    /// I1 qf_dot.
    pub(crate) i1_qfd: Vec3,
    /// I1 qf_dd.
    pub(crate) i1_qfdd: Vec3,
}

pub(crate) fn quat(q: &[f64]) -> Quaternion {
    [q[3], q[4], q[5], q[6]]
}

/// Dot product with four partial sums (vectorizable; a plain sum of f64 products is not).
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a4, b4) = (a[..n].chunks_exact(4), b[..n].chunks_exact(4));
    let (ra, rb) = (a4.remainder(), b4.remainder());
    let mut acc = [0.0f64; 4];
    for (x, y) in a4.zip(b4) {
        for k in 0..4 {
            acc[k] += x[k] * y[k];
        }
    }
    let tail: f64 = ra.iter().zip(rb).map(|(x, y)| x * y).sum();
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

/// The dot products of the nine rows of length n stacked in `rows` (row 3 k + l at
/// (3 k + l) n) with v, four rows at a time.
pub(crate) fn nine_dots(rows: &[f64], n: usize, v: &[f64]) -> [f64; 9] {
    let r = |i: usize| &rows[i * n..(i + 1) * n];
    let [a, b, c, d] = crate::linalg::simd::dot4([r(0), r(1), r(2), r(3)], &v[..n]);
    let [e, f, g, h] = crate::linalg::simd::dot4([r(4), r(5), r(6), r(7)], &v[..n]);
    [a, b, c, d, e, f, g, h, dot(r(8), v)]
}

pub(crate) fn row(v: &[f64], k: usize, l: usize, n: usize) -> &[f64] {
    &v[(3 * k + l) * n..(3 * k + l + 1) * n]
}

/// Whether [`quantities`] without the products takes the node-wise path of a body of solids
/// (see [`ScalarMass`]): it then leaves `scratch.y` and `scratch.n` unset, and the products
/// M_s [q_f, qf_dot, qf_dd] are in `scratch.nodal`.
pub(crate) fn nodewise(body: &FlexibleBody, scratch: &FlexibleScratch) -> bool {
    body.scalar_mass.is_some() && !body.solid_rows.is_empty() && !scratch.nodal.is_empty()
}

/// Bodies of solids: the products of I1 and Ibar with three elastic vectors in one pass over
/// the compressed rows, out[v][c] = [I1_c V_v, Ibar_0c V_v, Ibar_1c V_v, Ibar_2c V_v]
/// (so I1 V_v = out[v][.][0] and Ibar_kl . V_v = out[v][l][1 + k]).
pub(crate) fn solid_sums(body: &FlexibleBody, sm: &ScalarMass, vectors: [&[f64]; 3]) -> [[[f64; 4]; 3]; 3] {
    if body.whole_nodes {
        #[cfg(target_arch = "x86_64")]
        if crate::linalg::simd::has_avx2_fma() {
            // SAFETY: the CPU supports AVX2 and FMA (checked above).
            return unsafe { crate::linalg::simd::avx2::node_row_sums(&body.solid_rows, vectors) };
        }
        return node_row_sums_portable(&body.solid_rows, vectors);
    }
    let mut out = [[[0.0f64; 4]; 3]; 3];
    for (j, (row, &c)) in body.solid_rows.iter().zip(&sm.coordinates).enumerate() {
        let comp = c % 3;
        for (o, v) in out.iter_mut().zip(&vectors) {
            let x = v[j];
            for (ov, r) in o[comp].iter_mut().zip(row) {
                *ov += r * x;
            }
        }
    }
    out
}

/// [`solid_sums`] of a body whose coordinates are whole nodes, a node at a time, in portable
/// code (the AVX2 kernel `node_row_sums` forms the same sums in the same order).
pub(crate) fn node_row_sums_portable(rows: &[[f64; 4]], vectors: [&[f64]; 3]) -> [[[f64; 4]; 3]; 3] {
    let mut out = [[[0.0f64; 4]; 3]; 3];
    let [v0, v1, v2] = vectors.map(|v| v.chunks_exact(3));
    for (((rows, x0), x1), x2) in rows.chunks_exact(3).zip(v0).zip(v1).zip(v2) {
        for (o, x) in out.iter_mut().zip([x0, x1, x2]) {
            for ((oc, row), &xc) in o.iter_mut().zip(rows).zip(x) {
                for (ov, r) in oc.iter_mut().zip(row) {
                    *ov += r * xc;
                }
            }
        }
    }
    out
}

/// Returns the body quantities. With `with_products` (or for a body without the scalar mass
/// structure), fills y_kl = I_kl q_f and N_kl of `scratch` (and z_kl = I_kl qf_dot with the
/// products), which the Jacobians need; else, for a body of solids, takes every sum over the
/// elastic coordinates that involves y node by node (see [`nodewise`]), with the node-wise
/// M_s qf_dd only with `elastic_mass`.
pub(crate) fn quantities(
    body: &FlexibleBody,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    scratch: &mut FlexibleScratch,
    with_products: bool,
    elastic_mass: bool,
) -> Quantities {
    let nf = body.elastic_count;
    let r7 = REFERENCE_COORDINATES;
    let (qf, qfd, qfdd) = (&q[r7..r7 + nf], &qd[r7..r7 + nf], &qdd[r7..r7 + nf]);
    let p = quat(q);
    let a = euler::rotation_matrix(&p);
    let l = l_matrix(&p);
    let w = euler::body_angular_velocity(&p, &quat(qd));
    let alpha = euler::body_angular_velocity(&p, &quat(qdd));
    let acc = a.tr_mul_vec(&Vec3::from_slice(qdd));
    // y_kl[j] = delta(comp j, k) (M_s Q_f)[node j][l] for solids, so with V spread over the
    // nodes, V . y_kl = sum over nodes of V[node][k] Y0[node][l] =: g_V[k][l], for
    // V = q_f, qf_dot, qf_dd; and N_kl = Ibar_kl + y_lk.
    let node_sums = match &body.scalar_mass {
        Some(sm) if !with_products && nodewise(body, scratch) => {
            let g = if elastic_mass {
                sm.products::<9>([qf, qfd, qfdd], &mut scratch.gathered, &mut scratch.nodal)
            } else {
                sm.products::<6>([qf, qfd, qfdd], &mut scratch.gathered, &mut scratch.nodal)
            };
            Some((g, solid_sums(body, sm, [qf, qfd, qfdd])))
        }
        _ => {
            body.i_kl_products(qf, &mut scratch.y);
            if with_products {
                body.i_kl_products(qfd, &mut scratch.z);
            }
            for k in 0..3 {
                for l2 in 0..3 {
                    let dst = &mut scratch.n[(3 * k + l2) * nf..(3 * k + l2 + 1) * nf];
                    let ib = body.ibar_row(k, l2);
                    let y = row(&scratch.y, l2, k, nf);
                    for j in 0..nf {
                        dst[j] = ib[j] + y[j];
                    }
                }
            }
            None
        }
    };
    let [i1_qf, i1_qfd, i1_qfdd] = match &node_sums {
        Some((_, t)) => std::array::from_fn(|v| Vec3(std::array::from_fn(|c| t[v][c][0]))),
        None => [body.i1_times(qf), body.i1_times(qfd), body.i1_times(qfdd)],
    };
    let s = body.first_moment + i1_qf;
    let mut u = Mat3::ZERO;
    let mut pm = Mat3::ZERO;
    let mut n_qfdd = Mat3::ZERO;
    match &node_sums {
        Some((g, t)) => {
            // Ibar_kl . V_v = t[v][l][1 + k].
            for k in 0..3 {
                for l2 in 0..3 {
                    u.0[k][l2] =
                        body.second_moment.0[k][l2] + t[0][l2][1 + k] + t[0][k][1 + l2] + g[0][k][l2];
                    pm.0[k][l2] = t[1][l2][1 + k] + g[1][l2][k];
                    if k != l2 {
                        n_qfdd.0[k][l2] = t[2][l2][1 + k] + g[2][l2][k];
                    }
                }
            }
        }
        None => {
            let ibar_qf = nine_dots(&body.ibar, nf, qf);
            let y_qf = nine_dots(&scratch.y, nf, qf);
            let n_qfd = nine_dots(&scratch.n, nf, qfd);
            let n_dd = nine_dots(&scratch.n, nf, qfdd);
            for k in 0..3 {
                for l2 in 0..3 {
                    let (kl, lk) = (3 * k + l2, 3 * l2 + k);
                    u.0[k][l2] = body.second_moment.0[k][l2] + ibar_qf[kl] + ibar_qf[lk] + y_qf[kl];
                    pm.0[k][l2] = n_qfd[kl];
                    if k != l2 {
                        n_qfdd.0[k][l2] = n_dd[kl];
                    }
                }
            }
        }
    }
    let mut j = u.scale(-1.0);
    for k in 0..3 {
        j.0[k][k] += u.trace();
    }
    let mut jf_qdd = Vec3::ZERO;
    for i in 0..3 {
        let (k, l2) = ((i + 1) % 3, (i + 2) % 3);
        jf_qdd[i] = n_qfdd.0[k][l2] - n_qfdd.0[l2][k];
    }
    Quantities { p, a, l, w, alpha, acc, s, j, pm, jf_qdd, i1_qfd, i1_qfdd }
}

/// Fills `rows` (3 n_f) with the rows of J_f = int rho u~ S: row i = N_jk - N_kj for (i, j, k)
/// cyclic.
pub(crate) fn jf_rows(scratch: &FlexibleScratch, nf: usize, rows: &mut [f64]) {
    for i in 0..3 {
        let (k, l) = ((i + 1) % 3, (i + 2) % 3);
        let (a, b) = (row(&scratch.n, k, l, nf), row(&scratch.n, l, k, nf));
        for j in 0..nf {
            rows[i * nf + j] = a[j] - b[j];
        }
    }
}

pub(crate) fn map_rows_2lt(
    l: &Mat34,
    rows: &[f64],
    nf: usize,
    out: &mut [f64],
    out_row0: usize,
    out_cols: usize,
    col0: usize,
) {
    // out[(out_row0 + a) * out_cols + col0 + j] += sum_i 2 L[i][a] rows[i][j] for a in 0..4.
    for a in 0..4 {
        let dst = &mut out[(out_row0 + a) * out_cols + col0..(out_row0 + a) * out_cols + col0 + nf];
        for i in 0..3 {
            let c = 2.0 * l[i][a];
            if c != 0.0 {
                for (d, r) in dst.iter_mut().zip(&rows[i * nf..(i + 1) * nf]) {
                    *d += c * r;
                }
            }
        }
    }
}

/// Generalized inertia force f(q, q_dot, q_dd) of seed eq. 15 into `out` (7 + n_f).
pub fn inertia_force(
    body: &FlexibleBody,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    scratch: &mut FlexibleScratch,
    out: &mut [f64],
) {
    inertia_force_parts(body, q, qd, qdd, scratch, out, ElasticMass::Include, None);
}

/// Where [`inertia_force_parts`] puts the term M_ff qf_dd of the elastic rows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ElasticMass {
    /// In the force.
    Include,
    /// Nowhere (not formed).
    Skip,
    /// In `scratch.mass_term`, not in the force.
    Separate,
}

/// [`inertia_force`] with the term M_ff qf_dd of the elastic rows where `mass` says (see
/// [`add_linear_elastic_forces`]); with `gravity`, minus the generalized gravity force of
/// [`add_gravity_force`] (its elastic part I1^T A^T g in the pass of the inertia force's
/// I1^T a, and s = s0 + I1 q_f from the inertia quantities). Returns that s (for
/// [`gravity_jacobian_at`]).
#[allow(clippy::too_many_arguments)]
pub fn inertia_force_parts(
    body: &FlexibleBody,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    scratch: &mut FlexibleScratch,
    out: &mut [f64],
    mass: ElasticMass,
    gravity: Option<&Vec3>,
) -> Vec3 {
    let nf = body.elastic_count;
    let r7 = REFERENCE_COORDINATES;
    let mut k = quantities(body, q, qd, qdd, scratch, false, mass != ElasticMass::Skip);
    scratch.last = Some(k);
    let (w, alpha, s) = (k.w, k.alpha, k.s);
    // Translation: m R_dd + A (alpha x s + w x (w x s) + 2 w x I1 qf_dot + I1 qf_dd).
    let h_r = alpha.cross(&s) + w.cross(&w.cross(&s)) + w.cross(&k.i1_qfd) * 2.0 + k.i1_qfdd;
    let f_r = Vec3::from_slice(qdd) * body.mass + k.a.mul_vec(&h_r);
    // Rotation (body frame), mapped by 2 L^T.
    let g = rotation_force(&k);
    out[..3].copy_from_slice(&f_r.0);
    for a in 0..4 {
        out[3 + a] = 2.0 * (0..3).map(|i| k.l[i][a] * g[i]).sum::<f64>();
    }
    if let Some(gravity) = gravity {
        // Gravity: m g on R, d(A s)/dp^T g on p, I1^T A^T g on q_f (the last with the inertia
        // force's I1^T a: a - A^T g).
        let rt = rotate_transpose_jacobian(&k.p, gravity);
        for c in 0..3 {
            out[c] -= body.mass * gravity[c];
        }
        for c in 0..4 {
            out[3 + c] -= (0..3).map(|i| rt[i][c] * s[i]).sum::<f64>();
        }
        k.acc -= k.a.tr_mul_vec(gravity);
    }
    // Elastic: I1^T a + sum_kl E_kl N_lk (E = alpha~ + w~w~) + 2 sum_kl w~_kl I_kl qf_dot
    // + M_ff qf_dd, with sum_kl w~_kl I_kl = -sum_m w_m A_m.
    let f = &mut out[r7..r7 + nf];
    let e = alpha.skew() + w.skew().mul_mat(&w.skew());
    match &body.scalar_mass {
        Some(sm) if nodewise(body, scratch) => {
            // Node-wise: with the compressed rows (I1_c[j], Ibar_lc[j]) of coordinate j
            // (component c), I1^T a + sum_kl E_kl Ibar_lk is a_c I1_c[j] + sum_l E_cl
            // Ibar_lc[j]; then sum_kl E_kl y_kl + M_s (2 w x U_dot) + M_s U_dd from the
            // products of `quantities` (y_kl[j] = delta(comp j, k) Y0[node j][l]).
            if body.whole_nodes {
                // A node at a time: w x U_dot once per node (the same values).
                let nodes = f
                    .chunks_exact_mut(3)
                    .zip(sm.coordinates.chunks_exact(3))
                    .zip(body.solid_rows.chunks_exact(3));
                for (t, ((fs, cs), rows)) in nodes.enumerate() {
                    let node = cs[0] / 3;
                    let p = &scratch.nodal[9 * node..9 * node + 9];
                    let wy = w.cross(&Vec3([p[3], p[4], p[5]]));
                    for (comp, (fj, r)) in fs.iter_mut().zip(rows).enumerate() {
                        let ec = &e.0[comp];
                        let ey = ec[0] * (p[0] + r[1]) + ec[1] * (p[1] + r[2]) + ec[2] * (p[2] + r[3]);
                        *fj = k.acc[comp] * r[0] + ey + 2.0 * wy[comp];
                        match mass {
                            ElasticMass::Include => *fj += p[6 + comp],
                            ElasticMass::Separate => scratch.mass_term[3 * t + comp] = p[6 + comp],
                            ElasticMass::Skip => {}
                        }
                    }
                }
                return s;
            }
            for (j, ((fj, &c), r)) in f.iter_mut().zip(&sm.coordinates).zip(&body.solid_rows).enumerate() {
                let (node, comp) = (c / 3, c % 3);
                let p = &scratch.nodal[9 * node..9 * node + 9];
                let yd = Vec3([p[3], p[4], p[5]]);
                let ec = &e.0[comp];
                let ey = ec[0] * (p[0] + r[1]) + ec[1] * (p[1] + r[2]) + ec[2] * (p[2] + r[3]);
                *fj = k.acc[comp] * r[0] + ey + 2.0 * w.cross(&yd)[comp];
                match mass {
                    ElasticMass::Include => *fj += p[6 + comp],
                    ElasticMass::Separate => scratch.mass_term[j] = p[6 + comp],
                    ElasticMass::Skip => {}
                }
            }
        }
        _ => {
            f.iter_mut().for_each(|x| *x = 0.0);
            body.add_i1_transpose_times(&k.acc, f);
            for kk in 0..3 {
                for l in 0..3 {
                    let ce = e.0[kk][l];
                    if ce != 0.0 {
                        // N_lk = Ibar_lk + y_kl.
                        for (fj, nj) in f.iter_mut().zip(row(&scratch.n, l, kk, nf)) {
                            *fj += ce * nj;
                        }
                    }
                }
            }
            let qfd = &qd[r7..r7 + nf];
            for m in 0..3 {
                if w[m] != 0.0 {
                    body.antisymmetric[m].mul_vec_add(-2.0 * w[m], qfd, f);
                }
            }
            let qfdd = &qdd[r7..r7 + nf];
            match mass {
                ElasticMass::Include => body.mass_matrix.mul_vec_add(1.0, qfdd, f),
                ElasticMass::Separate => {
                    scratch.mass_term.iter_mut().for_each(|x| *x = 0.0);
                    body.mass_matrix.mul_vec_add(1.0, qfdd, &mut scratch.mass_term);
                }
                ElasticMass::Skip => {}
            }
        }
    }
    s
}

/// g = s x a + J alpha + w x J w + 2 (tr(P) w - P^T w) + J_f qf_dd (body frame).
pub(crate) fn rotation_force(k: &Quantities) -> Vec3 {
    let (w, alpha) = (k.w, k.alpha);
    let jw = k.j.mul_vec(&w);
    k.s.cross(&k.acc)
        + k.j.mul_vec(&alpha)
        + w.cross(&jw)
        + (w * k.pm.trace() - k.pm.tr_mul_vec(&w)) * 2.0
        + k.jf_qdd
}
