//! Tests of deformable bodies: brute-force sums over mass points for the inertia force and
//! energies, finite differences for the Jacobians.

use super::*;
use crate::math::dense::DenseMatrix;
use crate::testing::{assert_all_close, assert_close};

/// A body of mass points: point i has mass m_i, undeformed position u0_i and shape rows
/// S_i (3 x n_f, row-major): u_i = u0_i + S_i q_f.
pub struct PointBody {
    pub masses: Vec<f64>,
    pub positions: Vec<Vec3>,
    pub shapes: Vec<Vec<f64>>,
    pub n: usize,
}

pub struct Lcg(pub u64);
impl Lcg {
    pub fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64) / ((1u64 << 53) as f64) * 2.0 - 1.0
    }
}

/// A symmetric positive definite test matrix.
fn spd(n: usize, scale: f64) -> Csc {
    Csc::from_dense(n, n, |r, c| scale * if r == c { 2.0 + r as f64 } else { 0.3 / (1.0 + (r + c) as f64) })
}

impl PointBody {
    pub fn random(points: usize, n: usize, seed: u64) -> Self {
        let mut g = Lcg(seed);
        let masses = (0..points).map(|_| 1.0 + 0.5 * g.next()).collect();
        let positions = (0..points).map(|_| Vec3([g.next(), 0.5 * g.next(), 0.3 * g.next()])).collect();
        let shapes = (0..points).map(|_| (0..3 * n).map(|_| 0.3 * g.next()).collect()).collect();
        PointBody { masses, positions, shapes, n }
    }

    pub fn input(&self, stiffness: f64, damping: f64) -> FlexibleBodyInput {
        FlexibleBodyInput::from_mass_points(
            &self.masses,
            &self.positions,
            &self.shapes,
            spd(self.n, stiffness),
            spd(self.n, damping),
        )
    }

    /// Brute-force inertia force by virtual work over the points (seed eqs. 11-13).
    pub fn inertia_force(&self, q: &[f64], qd: &[f64], qdd: &[f64]) -> Vec<f64> {
        let n = self.n;
        let p = quat(q);
        let a = euler::rotation_matrix(&p);
        let w = euler::body_angular_velocity(&p, &quat(qd));
        let alpha = euler::body_angular_velocity(&p, &quat(qdd));
        let l = l_matrix(&p);
        let mut out = vec![0.0; 7 + n];
        let mut g = Vec3::ZERO;
        for (i, &m) in self.masses.iter().enumerate() {
            let sh = &self.shapes[i];
            let su = |v: &[f64]| Vec3(std::array::from_fn(|k| dot(&sh[k * n..(k + 1) * n], v)));
            let u = self.positions[i] + su(&q[7..]);
            let ud = su(&qd[7..]);
            let udd = su(&qdd[7..]);
            let local = alpha.cross(&u) + w.cross(&w.cross(&u)) + w.cross(&ud) * 2.0 + udd;
            let r_dd = Vec3::from_slice(qdd) + a.mul_vec(&local);
            let b = a.tr_mul_vec(&r_dd);
            for k in 0..3 {
                out[k] += m * r_dd[k];
            }
            g += u.cross(&b) * m;
            for j in 0..n {
                out[7 + j] += m * (0..3).map(|k| sh[k * n + j] * b[k]).sum::<f64>();
            }
        }
        for c in 0..4 {
            out[3 + c] = 2.0 * (0..3).map(|i| l[i][c] * g[i]).sum::<f64>();
        }
        out
    }

    pub fn kinetic_energy(&self, q: &[f64], qd: &[f64]) -> f64 {
        let p = quat(q);
        let a = euler::rotation_matrix(&p);
        let w = euler::body_angular_velocity(&p, &quat(qd));
        let mut e = 0.0;
        let n = self.n;
        for (i, &m) in self.masses.iter().enumerate() {
            let sh = &self.shapes[i];
            let su = |v: &[f64]| Vec3(std::array::from_fn(|k| dot(&sh[k * n..(k + 1) * n], v)));
            let u = self.positions[i] + su(&q[7..]);
            let v = Vec3::from_slice(qd) + a.mul_vec(&(w.cross(&u) + su(&qd[7..])));
            e += 0.5 * m * v.dot(&v);
        }
        e
    }
}

pub fn random_state(n: usize, seed: u64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let mut g = Lcg(seed);
    let mut p = [0.8 + 0.1 * g.next(), 0.3 * g.next(), -0.4 + 0.1 * g.next(), 0.3 * g.next()];
    let norm = p.iter().map(|x| x * x).sum::<f64>().sqrt();
    p.iter_mut().for_each(|x| *x /= norm);
    let mut q = vec![0.5 * g.next(), g.next(), 2.0 * g.next(), p[0], p[1], p[2], p[3]];
    q.extend((0..n).map(|_| 0.2 * g.next()));
    let qd: Vec<f64> = (0..7 + n).map(|_| g.next()).collect();
    let qdd: Vec<f64> = (0..7 + n).map(|_| g.next()).collect();
    (q, qd, qdd)
}

/// Full dense tangent matrices (mass, velocity, position) of the inertia force.
pub fn dense_tangent(body: &FlexibleBody, t: &FlexibleTangent) -> [DenseMatrix; 3] {
    let n = body.elastic_count;
    let size = 7 + n;
    std::array::from_fn(|b| {
        let mut m = DenseMatrix::zeros(size, size);
        for r in 0..7 {
            for c in 0..7 {
                m.add(r, c, t.reference[b][r][c]);
            }
            for c in 0..n {
                m.add(r, 7 + c, t.reference_elastic[b][r * n + c]);
                m.add(7 + c, r, t.elastic_reference[b][c * 7 + r]);
            }
        }
        let coef = match b {
            0 => Mat3::IDENTITY,
            1 => t.velocity_coefficients,
            _ => t.position_coefficients,
        };
        let mut values = vec![0.0; body.pattern.nnz()];
        body.add_i_kl_to_pattern(&coef, &mut values);
        for c in 0..n {
            for k in body.pattern.col_ptr[c]..body.pattern.col_ptr[c + 1] {
                m.add(7 + body.pattern.row_idx[k], 7 + c, values[k]);
            }
        }
        m
    })
}

#[test]
fn inertia_force_equals_brute_force_sum_over_mass_points() {
    for (n, seed) in [(0, 1), (1, 2), (4, 3)] {
        let pts = PointBody::random(7, n, seed);
        let body = FlexibleBody::new("b", pts.input(1.0, 0.0)).unwrap();
        let (q, qd, qdd) = random_state(n, seed + 10);
        let mut scratch = FlexibleScratch::with_size(n);
        let mut f = vec![0.0; 7 + n];
        inertia_force(&body, &q, &qd, &qdd, &mut scratch, &mut f);
        let brute = pts.inertia_force(&q, &qd, &qdd);
        assert_all_close(&f, &brute, 1e-12, 1e-12, format_args!("n = {n}: inertia force"));
        let e = kinetic_energy(&body, &q, &qd, &mut scratch);
        assert_close(e, pts.kinetic_energy(&q, &qd), 1e-12, 1e-12, format_args!("n = {n}: kinetic energy"));
    }
}

#[test]
fn node_row_sums_agree_with_plain_sums() {
    // Rows of four per coordinate, three vectors, whole nodes (0 to 7 of them).
    for nodes in 0..8usize {
        let n = 3 * nodes;
        let rows: Vec<[f64; 4]> =
            (0..n).map(|j| std::array::from_fn(|i| ((5 * j + 3 * i) % 7) as f64 - 3.0)).collect();
        let v: Vec<Vec<f64>> =
            (0..3).map(|k| (0..n).map(|j| 0.25 * (j + k) as f64 - 1.0).collect()).collect();
        let vectors = [&v[0][..], &v[1][..], &v[2][..]];
        let portable = node_row_sums_portable(&rows, vectors);
        #[cfg(target_arch = "x86_64")]
        let fast = if crate::linalg::simd::has_avx2_fma() {
            // SAFETY: the CPU supports AVX2 and FMA (checked).
            unsafe { crate::linalg::simd::avx2::node_row_sums(&rows, vectors) }
        } else {
            portable
        };
        #[cfg(not(target_arch = "x86_64"))]
        let fast = portable;
        for vv in 0..3 {
            for c in 0..3 {
                let exact: [f64; 4] = std::array::from_fn(|i| {
                    (0..nodes).map(|nd| rows[3 * nd + c][i] * v[vv][3 * nd + c]).sum()
                });
                for got in [portable[vv][c], fast[vv][c]] {
                    assert_all_close(
                        &got,
                        &exact,
                        1e-12,
                        1e-12,
                        format_args!("{nodes} nodes, v{vv}, c = {c}"),
                    );
                }
            }
        }
    }
}

#[test]
fn elastic_matrix_products_agree_in_every_storage() {
    // Stored whole (full), with three quarters of its entries (dense copy), in 3 x 3 node
    // blocks, and as a sparse band (indexed): out += w A x against the plain CSC product.
    let value = |r: usize, c: usize| 1.0 + ((3 * r + 7 * c) % 5) as f64 - 0.25 * c as f64;
    // (n, entries kept, expected storage: full, dense copy, 3 x 3 blocks)
    type Case = (usize, fn(usize, usize) -> bool, [bool; 3]);
    let cases: [Case; 4] = [
        (10, |_, _| true, [true, false, false]),
        (18, |r, c| (r + 2 * c) % 4 != 1, [false, true, false]),
        (12, |r, c| r / 3 == c / 3 || r / 3 + 1 == c / 3, [false, false, true]),
        (20, |r, c| r.abs_diff(c) <= 1, [false, false, false]),
    ];
    for (n, keep, storage) in cases {
        let mut entries = Csc::from_dense(n, n, value);
        let (mut row_idx, mut values, mut col_ptr) = (Vec::new(), Vec::new(), vec![0]);
        for c in 0..n {
            for k in entries.col_ptr[c]..entries.col_ptr[c + 1] {
                if keep(entries.row_idx[k], c) {
                    row_idx.push(entries.row_idx[k]);
                    values.push(entries.values[k]);
                }
            }
            col_ptr.push(row_idx.len());
        }
        (entries.row_idx, entries.values, entries.col_ptr) = (row_idx, values, col_ptr);
        let pattern = ElasticPattern::union(n, &[&entries], &[]);
        let matrix = ElasticMatrix::new(entries.clone(), &pattern);
        let stored = [matrix.full, matrix.dense.is_some(), matrix.blocks.is_some()];
        assert_eq!(stored, storage, "n = {n}");
        let x: Vec<f64> = (0..n).map(|k| 0.3 * k as f64 - 1.0).collect();
        let start: Vec<f64> = (0..n).map(|k| 0.1 * k as f64).collect();
        let mut expected = vec![0.0; n];
        entries.mul_vec_add(&x, &mut expected);
        let mut out = start.clone();
        matrix.mul_vec_add(-1.5, &x, &mut out);
        let e: Vec<f64> = (0..n).map(|k| start[k] - 1.5 * expected[k]).collect();
        assert_all_close(&out, &e, 1e-12, 1e-12, format_args!("n = {n}, row"));
    }
}

#[test]
fn tangent_matches_finite_differences() {
    let n = 3;
    let pts = PointBody::random(6, n, 7);
    let body = FlexibleBody::new("b", pts.input(1.0, 0.0)).unwrap();
    let (q, qd, qdd) = random_state(n, 8);
    let mut scratch = FlexibleScratch::with_size(n);
    let mut t = FlexibleTangent::with_size(n);
    inertia_tangent(&body, &q, &qd, &qdd, &mut scratch, &mut t, true);
    let dense = dense_tangent(&body, &t);
    let h = 1e-6;
    for which in 0..3 {
        for c in 0..7 + n {
            let mut eval = |s: f64| {
                let (mut a, mut b, mut d) = (q.clone(), qd.clone(), qdd.clone());
                match which {
                    0 => d[c] += s,
                    1 => b[c] += s,
                    _ => a[c] += s,
                }
                let mut f = vec![0.0; 7 + n];
                inertia_force(&body, &a, &b, &d, &mut scratch, &mut f);
                f
            };
            let (fp, fm) = (eval(h), eval(-h));
            let fd: Vec<f64> = (0..7 + n).map(|r| (fp[r] - fm[r]) / (2.0 * h)).collect();
            let an: Vec<f64> = (0..7 + n).map(|r| dense[which].get(r, c)).collect();
            assert_all_close(
                &fd,
                &an,
                1e-7,
                1e-7,
                format_args!("block {which}, column {c}: fd against analytic, row"),
            );
        }
    }
}

#[test]
fn reference_only_tangent_equals_the_reference_block_of_the_whole() {
    // Without the coupling blocks the tangent takes the node-wise products of a solid
    // body (no general I_kl products): its reference block and the coefficients of the
    // elastic block must equal those of the whole tangent.
    for body in [solid_body(true, false).unwrap(), solid_body(false, false).unwrap()] {
        let n = body.elastic_count;
        let (q, qd, qdd) = random_state(n, 61);
        let mut scratch = FlexibleScratch::for_body(&body);
        let (mut whole, mut reference) = (FlexibleTangent::with_size(n), FlexibleTangent::with_size(n));
        inertia_tangent(&body, &q, &qd, &qdd, &mut scratch, &mut whole, true);
        inertia_tangent(&body, &q, &qd, &qdd, &mut scratch, &mut reference, false);
        // The same from the quantities of the inertia force at that state.
        let mut after = FlexibleTangent::with_size(n);
        let mut force = vec![0.0; 7 + n];
        inertia_force(&body, &q, &qd, &qdd, &mut scratch, &mut force);
        inertia_tangent_after_force(&body, &q, &qd, &qdd, &mut scratch, &mut after, false);
        assert_eq!(after.reference, reference.reference);
        assert!(scratch.last.is_none(), "the kept quantities are taken");
        for b in 0..3 {
            let (x, y) = (whole.reference[b].as_flattened(), reference.reference[b].as_flattened());
            assert_all_close(x, y, 1e-12, 1e-12, format_args!("block {b}, 7 r + c"));
        }
        for (x, y, what) in [
            (whole.velocity_coefficients, reference.velocity_coefficients, "velocity coefficients"),
            (whole.position_coefficients, reference.position_coefficients, "position coefficients"),
        ] {
            assert_all_close(x.0.as_flattened(), y.0.as_flattened(), 1e-12, 1e-12, what);
        }
        assert!(reference.reference_elastic.iter().all(|b| b.iter().all(|&x| x == 0.0)));
    }
}

#[test]
fn mass_matrix_is_symmetric_and_gives_the_kinetic_energy() {
    let n = 4;
    let pts = PointBody::random(8, n, 11);
    let body = FlexibleBody::new("b", pts.input(1.0, 0.0)).unwrap();
    let (q, qd, qdd) = random_state(n, 12);
    let mut scratch = FlexibleScratch::with_size(n);
    let mut t = FlexibleTangent::with_size(n);
    inertia_tangent(&body, &q, &qd, &qdd, &mut scratch, &mut t, true);
    let m = &dense_tangent(&body, &t)[0];
    let size = 7 + n;
    let entries: Vec<f64> = (0..size * size).map(|k| m.get(k / size, k % size)).collect();
    let transposed: Vec<f64> = (0..size * size).map(|k| m.get(k % size, k / size)).collect();
    assert_all_close(&entries, &transposed, 1e-13, 1e-13, "M against M^T");
    // f(q, q_dot, q_dd) - f(q, q_dot, 0) = M q_dd.
    let mut f = vec![0.0; 7 + n];
    let mut f0 = vec![0.0; 7 + n];
    inertia_force(&body, &q, &qd, &qdd, &mut scratch, &mut f);
    inertia_force(&body, &q, &qd, &vec![0.0; 7 + n], &mut scratch, &mut f0);
    let mut mq = vec![0.0; 7 + n];
    m.mul_vec_add(1.0, &qdd, &mut mq);
    let difference: Vec<f64> = f.iter().zip(&f0).map(|(a, b)| a - b).collect();
    assert_all_close(&difference, &mq, 1e-12, 1e-12, "f(q_dd) - f(0) against M q_dd");
    let energy = kinetic_energy(&body, &q, &qd, &mut scratch);
    assert_close(0.5 * m.quadratic_form(&qd), energy, 1e-12, 1e-12, "kinetic energy from M");
}

#[test]
fn gravity_jacobian_matches_finite_differences_and_potential() {
    let n = 3;
    let pts = PointBody::random(5, n, 21);
    let body = FlexibleBody::new("b", pts.input(1.0, 0.0)).unwrap();
    let (q, _, _) = random_state(n, 22);
    let g = Vec3([0.3, -9.81, 1.2]);
    let mut pf = vec![0.0; 4 * n];
    let mut fp = vec![0.0; 4 * n];
    let pp = gravity_jacobian(&body, &q, &g, Some((&mut pf, &mut fp)));
    assert_eq!(gravity_jacobian(&body, &q, &g, None), pp);
    let h = 1e-6;
    for c in 3..7 + n {
        let eval = |s: f64| {
            let mut a = q.clone();
            a[c] += s;
            let mut out = vec![0.0; 7 + n];
            add_gravity_force(&body, &a, &g, &mut out);
            (out, gravity_potential(&body, &a, &g))
        };
        let ((fp1, v1), (fm1, v2)) = (eval(h), eval(-h));
        let fd: Vec<f64> = (3..7 + n).map(|r| (fp1[r] - fm1[r]) / (2.0 * h)).collect();
        let an: Vec<f64> = (3..7 + n)
            .map(|r| match (r < 7, c < 7) {
                (true, true) => pp[r - 3][c - 3],
                (true, false) => pf[(r - 3) * n + c - 7],
                (false, true) => fp[(r - 7) * 4 + c - 3],
                (false, false) => 0.0,
            })
            .collect();
        assert_all_close(&fd, &an, 1e-7, 1e-7, format_args!("column {c}: fd against analytic, row 3 +"));
        // Q = -dV/dq.
        let mut out = vec![0.0; 7 + n];
        add_gravity_force(&body, &q, &g, &mut out);
        assert_close(-(v1 - v2) / (2.0 * h), out[c], 1e-7, 1e-7, format_args!("-dV/dq{c}"));
    }
}

/// A body of solids: nodes with translations only, I_kl = P^T (M_s (x) e_k e_l^T) P over
/// the kept coordinates (node 0 held), with or without its scalar mass structure.
fn solid_body(with_scalar: bool, corrupt: bool) -> Result<FlexibleBody> {
    let nodes = 4;
    let ms =
        Csc::from_dense(nodes, nodes, |r, c| if r == c { 2.0 + r as f64 } else { 0.4 / (1 + r + c) as f64 });
    let coordinates: Vec<usize> = (3..3 * nodes).collect();
    let n = coordinates.len();
    let positions: Vec<Vec3> =
        (0..nodes).map(|a| Vec3([0.3 * a as f64, 0.1 * (a % 2) as f64, 0.05])).collect();
    let mut input = FlexibleBodyInput {
        i1: vec![0.0; 3 * n],
        ibar: vec![0.0; 9 * n],
        stiffness: Csc::from_dense(n, n, |r, c| if r == c { 100.0 } else { 1.0 / (1 + r + c) as f64 }),
        damping: Csc::from_dense(n, n, |_, _| 0.0),
        ..Default::default()
    };
    // Moments from M_s (consistent with its row sums as the nodal masses).
    for a in 0..nodes {
        for b in 0..nodes {
            let m = ms.get(a, b);
            input.mass += m;
            input.first_moment += positions[b] * m;
            input.second_moment = input.second_moment + positions[a].outer(&positions[b]).scale(m);
        }
    }
    for (j, &c) in coordinates.iter().enumerate() {
        let (b, l) = (c / 3, c % 3);
        for a in 0..nodes {
            let m = ms.get(a, b);
            input.i1[l * n + j] += m;
            for k in 0..3 {
                input.ibar[(3 * k + l) * n + j] += m * positions[a][k];
            }
        }
    }
    input.i_kl = (0..9)
        .map(|kl| {
            let (k, l) = (kl / 3, kl % 3);
            Csc::from_dense(n, n, |r, c| {
                let (cr, cc) = (coordinates[r], coordinates[c]);
                if cr % 3 == k && cc % 3 == l {
                    ms.get(cr / 3, cc / 3)
                } else {
                    0.0
                }
            })
        })
        .collect();
    if with_scalar {
        let mut matrix = ms.clone();
        if corrupt {
            matrix.values[5] *= 1.1;
        }
        input.scalar_mass = Some(ScalarMass { matrix, coordinates });
    }
    FlexibleBody::new("solid", input)
}

#[test]
fn antisymmetric_norm_bound_bounds_the_products() {
    // For either storage (assembled antisymmetric matrices, M_s), |A_i v| <= b |v| for
    // vectors of several shapes, and b is the same order as the largest ratio met (the
    // condensed solver keeps its deformation solves on this bound, see `condensed.rs`).
    let (plain, fast) = (solid_body(false, false).unwrap(), solid_body(true, false).unwrap());
    let n = plain.elastic_count;
    let (b_plain, b_fast) = (plain.antisymmetric_norm_bound(), fast.antisymmetric_norm_bound());
    assert!(b_plain > 0.0 && b_fast > 0.0);
    let mut largest = 0.0f64;
    for seed in 0..8u64 {
        let (q, qd, _) = random_state(n, 60 + seed);
        for v in [&q[7..], &qd[7..]] {
            let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
            for (body, bound) in [(&plain, b_plain), (&fast, b_fast)] {
                let mut out = vec![0.0; 3 * n];
                body.add_antisymmetric_products(1.0, v, &mut out);
                for row in out.chunks_exact(n) {
                    let r = row.iter().map(|x| x * x).sum::<f64>().sqrt();
                    assert!(r <= bound * norm * (1.0 + 1e-12), "{r} > {bound} * {norm}");
                    largest = largest.max(r / norm);
                }
            }
        }
    }
    assert!(b_plain.max(b_fast) < 50.0 * largest, "bounds {b_plain}, {b_fast} against {largest}");
}

#[test]
fn scalar_mass_products_equal_the_invariant_products() {
    let (plain, fast) = (solid_body(false, false).unwrap(), solid_body(true, false).unwrap());
    let n = plain.elastic_count;
    let (q, qd, qdd) = random_state(n, 51);
    let (mut a, mut b) = (vec![0.0; 7 + n], vec![0.0; 7 + n]);
    inertia_force(&plain, &q, &qd, &qdd, &mut FlexibleScratch::for_body(&plain), &mut a);
    inertia_force(&fast, &q, &qd, &qdd, &mut FlexibleScratch::for_body(&fast), &mut b);
    assert_all_close(&a, &b, 1e-12, 1e-12, "inertia force");
    assert!(!fast.solid_rows.is_empty(), "the compressed rows of a body of solids");
    // The elastic mass term apart: Include = Separate + mass_term, Skip = Separate.
    for body in [&plain, &fast] {
        let mut scratch = FlexibleScratch::for_body(body);
        let mut parts = [vec![0.0; 7 + n], vec![0.0; 7 + n], vec![0.0; 7 + n]];
        for (out, mass) in
            parts.iter_mut().zip([ElasticMass::Include, ElasticMass::Skip, ElasticMass::Separate])
        {
            inertia_force_parts(body, &q, &qd, &qdd, &mut scratch, out, mass, None);
        }
        let mass_term = scratch.mass_term.clone();
        assert!(mass_term.iter().any(|&m| m.abs() > 1e-3));
        let separate: Vec<f64> =
            (0..7 + n).map(|k| parts[2][k] + if k >= 7 { mass_term[k - 7] } else { 0.0 }).collect();
        assert_all_close(&parts[0], &separate, 1e-12, 1e-12, "Include against Separate + mass term");
        assert_eq!(parts[1], parts[2], "Skip against Separate");
    }
    // The antisymmetric products from M_s.
    let (mut a, mut b) = (vec![1.0; 3 * n], vec![1.0; 3 * n]);
    plain.add_antisymmetric_products(-0.5, &qd[7..], &mut a);
    fast.add_antisymmetric_products(-0.5, &qd[7..], &mut b);
    assert!(a.iter().any(|&x| (x - 1.0).abs() > 1e-3));
    assert_all_close(&a, &b, 1e-12, 1e-12, "antisymmetric");
    // Gravity (I1 products from the compressed rows).
    let gravity = Vec3([0.3, -9.81, 1.2]);
    let (mut a, mut b) = (vec![0.0; 7 + n], vec![0.0; 7 + n]);
    add_gravity_force(&plain, &q, &gravity, &mut a);
    add_gravity_force(&fast, &q, &gravity, &mut b);
    assert_all_close(&a, &b, 1e-12, 1e-12, "gravity");
    // The inertia force minus gravity in one call equals the two apart, and the first
    // moment it returns for the gravity Jacobian is that of the state.
    for body in [&plain, &fast] {
        let mut scratch = FlexibleScratch::for_body(body);
        let (mut apart, mut fused) = (vec![0.0; 7 + n], vec![0.0; 7 + n]);
        inertia_force_parts(body, &q, &qd, &qdd, &mut scratch, &mut apart, ElasticMass::Include, None);
        let mut weight = vec![0.0; 7 + n];
        add_gravity_force(body, &q, &gravity, &mut weight);
        let s = inertia_force_parts(
            body,
            &q,
            &qd,
            &qdd,
            &mut scratch,
            &mut fused,
            ElasticMass::Include,
            Some(&gravity),
        );
        let expected: Vec<f64> = apart.iter().zip(&weight).map(|(a, w)| a - w).collect();
        assert_all_close(&fused, &expected, 1e-12, 1e-12, "inertia - gravity");
        let (mut pf, mut fp, mut pf2, mut fp2) =
            (vec![0.0; 4 * n], vec![0.0; 4 * n], vec![0.0; 4 * n], vec![0.0; 4 * n]);
        let given = gravity_jacobian_at(body, &q, &gravity, s, Some((&mut pf, &mut fp)));
        let formed = gravity_jacobian(body, &q, &gravity, Some((&mut pf2, &mut fp2)));
        let given: Vec<f64> = given.as_flattened().iter().chain(&pf).copied().collect();
        let formed: Vec<f64> = formed.as_flattened().iter().chain(&pf2).copied().collect();
        assert_all_close(&given, &formed, 1e-12, 1e-12, "gravity Jacobian, then its coupling");
    }
    assert!(solid_body(true, true).is_err());
}

/// A sparse matrix of 3 x 3 node blocks (node pairs of a chain plus a few long-range
/// pairs, some entries inside blocks left out), from a seed.
fn node_block_matrix(nodes: usize, seed: u64) -> Csc {
    let mut rng = Lcg(seed);
    let coupled = |a: usize, b: usize| a.abs_diff(b) <= 1 || (a * 7 + b * 7) % 5 == 0;
    let mut col_ptr = vec![0];
    let (mut row_idx, mut values) = (Vec::new(), Vec::new());
    for c in 0..3 * nodes {
        for r in 0..3 * nodes {
            if coupled(r / 3, c / 3) && (r + 2 * c) % 7 != 3 {
                row_idx.push(r);
                values.push(rng.next());
            }
        }
        col_ptr.push(row_idx.len());
    }
    Csc { nrows: 3 * nodes, ncols: 3 * nodes, col_ptr, row_idx, values }
}

#[test]
fn scalar_mass_products_equal_the_dense_sums() {
    // A symmetric 5 x 5 scalar mass with zeros, node 1 without its y component: the
    // node-wise products of three vectors (W = 6 and 9; the AVX2 kernel where the CPU has
    // it) against dense sums.
    let nodes = 5;
    let dense = |r: usize, c: usize| {
        if (r + 2 * c) % 3 == 1 && r != c {
            0.0
        } else {
            1.0 / (1.0 + (r + c) as f64)
        }
    };
    let sm = ScalarMass {
        matrix: Csc::from_dense(nodes, nodes, |r, c| dense(r.min(c), r.max(c))),
        coordinates: (0..3 * nodes).filter(|&c| c != 4).collect(),
    };
    let n = sm.coordinates.len();
    let v: Vec<Vec<f64>> =
        (0..3).map(|k| (0..n).map(|j| ((j * 7 + k * 5) % 11) as f64 - 5.0).collect()).collect();
    let mut spread = vec![0.0; 9 * nodes];
    for (j, &c) in sm.coordinates.iter().enumerate() {
        for k in 0..3 {
            spread[9 * (c / 3) + 3 * k + c % 3] = v[k][j];
        }
    }
    for w in [6, 9] {
        // Entries past W are left as they were (7); gathered is zero outside the
        // coordinates' entries before and after.
        let (mut gathered, mut out) = (vec![0.0; 9 * nodes], vec![7.0; 9 * nodes]);
        let g = if w == 6 {
            sm.products::<6>([&v[0], &v[1], &v[2]], &mut gathered, &mut out)
        } else {
            sm.products::<9>([&v[0], &v[1], &v[2]], &mut gathered, &mut out)
        };
        assert_eq!(gathered, spread);
        let mut portable = vec![7.0; 9 * nodes];
        let g_portable = if w == 6 {
            sm.multiply_portable::<6>(&gathered, &mut portable)
        } else {
            sm.multiply_portable::<9>(&gathered, &mut portable)
        };
        let expected: Vec<f64> = (0..9 * nodes)
            .map(|e| {
                let (i, k) = (e / 9, e % 9);
                if k < w {
                    (0..nodes).map(|r| dense(r.min(i), r.max(i)) * spread[9 * r + k]).sum()
                } else {
                    7.0
                }
            })
            .collect();
        assert_all_close(&out, &expected, 0.0, 1e-12, format_args!("W = {w}, 9 node + entry"));
        assert_all_close(
            &portable,
            &expected,
            0.0,
            1e-12,
            format_args!("W = {w} (portable), 9 node + entry"),
        );
        // g[v][k][l] = sum over the nodes of V_v[node][k] Y_0[node][l].
        let expected: [[[f64; 3]; 3]; 3] = std::array::from_fn(|vv| {
            std::array::from_fn(|k| {
                std::array::from_fn(|l| (0..nodes).map(|i| spread[9 * i + 3 * vv + k] * out[9 * i + l]).sum())
            })
        });
        let expected = expected.as_flattened().as_flattened();
        for got in [g, g_portable] {
            assert_all_close(
                got.as_flattened().as_flattened(),
                expected,
                0.0,
                1e-10,
                format_args!("W = {w}: g, 9 v + 3 k + l"),
            );
        }
    }
}

#[test]
fn node_block_products_equal_the_compressed_column_products() {
    // A general matrix of node blocks and a symmetric one (M + M^T, kept as its upper
    // blocks).
    let general = node_block_matrix(9, 3);
    let n = general.nrows;
    let mut dense = vec![0.0; n * n];
    for c in 0..n {
        for k in general.col_ptr[c]..general.col_ptr[c + 1] {
            dense[c * n + general.row_idx[k]] += general.values[k];
            dense[general.row_idx[k] * n + c] += general.values[k];
        }
    }
    let mut symmetric = Csc { nrows: n, ncols: n, col_ptr: vec![0], row_idx: Vec::new(), values: Vec::new() };
    for c in 0..n {
        for r in 0..n {
            if dense[c * n + r] != 0.0 {
                symmetric.row_idx.push(r);
                symmetric.values.push(dense[c * n + r]);
            }
        }
        symmetric.col_ptr.push(symmetric.row_idx.len());
    }
    for (m, is_symmetric) in [(general, false), (symmetric, true)] {
        let pattern = ElasticPattern::union(m.nrows, &[&m], &[]);
        let blocked = ElasticMatrix::new(m.clone(), &pattern);
        let blocks = blocked.blocks.as_ref().expect("blocks");
        assert_eq!(blocks.symmetric, is_symmetric);
        if is_symmetric {
            // The node pairs of the pattern: the upper ones are stored, and only they.
            let mut pairs = std::collections::BTreeSet::new();
            for c in 0..n {
                for &r in &m.row_idx[m.col_ptr[c]..m.col_ptr[c + 1]] {
                    pairs.insert((r / 3, c / 3));
                }
            }
            let upper: Vec<(usize, usize)> = pairs.iter().copied().filter(|(r, c)| c >= r).collect();
            let stored: Vec<(usize, usize)> = (0..n / 3)
                .flat_map(|br| {
                    let range = blocks.row_ptr[br]..blocks.row_ptr[br + 1];
                    blocks.columns[range].iter().map(move |&bc| (br, bc as usize))
                })
                .collect();
            assert_eq!(stored, upper);
            assert!(upper.len() < pairs.len());
        }
        let x: Vec<f64> = (0..27).map(|k| (0.37 * k as f64).sin()).collect();
        let mut expected: Vec<f64> = (0..27).map(|k| 0.1 * k as f64).collect();
        let mut got = expected.clone();
        blocked.mul_vec_add(-1.5, &x, &mut got);
        let mut product = vec![0.0; 27];
        m.mul_vec_add(&x, &mut product);
        for (e, p) in expected.iter_mut().zip(&product) {
            *e += -1.5 * p;
        }
        // The kernel chosen for this CPU (AVX2 where it has it) and the portable one; x
        // and out exactly 3 n_b long (the last node's entries read through the mask).
        let mut portable: Vec<f64> = (0..27).map(|k| 0.1 * k as f64).collect();
        blocks.mul_vec_add_portable(-1.5, &x, &mut portable);
        assert_all_close(&got, &expected, 0.0, 1e-14, "node block product");
        assert_all_close(&portable, &expected, 0.0, 1e-14, "node block product (portable)");
    }
    // Not made of node blocks (a diagonal): the compressed columns serve.
    let diagonal = Csc::from_dense(30, 30, |r, c| if r == c { 1.0 } else { 0.0 });
    let mut sparse = diagonal.clone();
    sparse.col_ptr = (0..=30).collect();
    sparse.row_idx = (0..30).collect();
    sparse.values = vec![1.0; 30];
    assert!(Blocks3::from_csc(&sparse).is_none());
    assert!(Blocks3::from_csc(&diagonal).is_some());
}

#[test]
fn bad_data_is_rejected() {
    let pts = PointBody::random(4, 2, 31);
    let mut inp = pts.input(1.0, 0.0);
    inp.mass = -1.0;
    assert!(FlexibleBody::new("b", inp).is_err());
    let mut inp = pts.input(1.0, 0.0);
    inp.i_kl[1].values[0] += 1.0;
    assert!(FlexibleBody::new("b", inp).is_err());
    let mut inp = pts.input(1.0, 0.0);
    inp.stiffness.values[1] = f64::NAN;
    assert!(FlexibleBody::new("b", inp).is_err());
    let mut inp = pts.input(1.0, 0.0);
    inp.i1.pop();
    assert!(FlexibleBody::new("b", inp).is_err());
}

/// I_kl^T = I_lk is checked against the largest entry of all nine: a pair that is only
/// round-off (I_12 of bending modes normal to the x-y plane) passes, a real mismatch does not.
#[test]
fn the_transpose_check_of_i_kl_is_relative_to_all_nine() {
    let body = PointBody::random(6, 3, 11);
    let mut input = body.input(10.0, 0.0);
    assert!(input.validate("body").is_ok());
    // Round-off in I_12 (1e-13 of the largest entry) that is not I_21^T: accepted.
    let largest = largest_entry(&input.i_kl);
    let tiny = |value: f64| Csc::from_dense(3, 3, |r, c| if (r, c) == (0, 1) { value } else { 0.0 });
    input.i_kl[1] = tiny(1e-13 * largest);
    input.i_kl[3] = tiny(0.0);
    assert!(input.validate("body").is_ok());
    // A mismatch of 1e-6 of the largest entry: refused, naming the pair.
    input.i_kl[1] = tiny(1e-6 * largest);
    let error = input.validate("body").unwrap_err().to_string();
    assert!(error.contains("I_12 and I_21 must be transposes"), "{error}");
}
