//! Point masses with a rotary inertia or an offset, carried by a node with rotations: the
//! second-order motion of the mass about its node.
//!
//! The invariants of motion hold such a mass as a set of mass points that move with the
//! node's displacement u and small rotation theta linearly, c -> c + theta x c (c: a point
//! relative to the node), as the elements' own mass does. A rigid mass turns instead: to
//! second order its points move by theta x c + (1/2) theta x (theta x c). The linear motion
//! misses what the inertia forces of the frame's motion and gravity do through the quadratic
//! term: a disc spun about its axis is softened in torsion by I_p W^2 (its points move out
//! along the tangents, and the centrifugal force pulls them), which the quadratic term, pulling
//! them back onto their circle, cancels exactly; an offset mass hanging under gravity lacks
//! its pendulum stiffness m g e.
//!
//! This module adds, for every such mass, the difference of the generalized inertia-minus-
//! gravity forces of its mass points moving to second order and moving linearly: for a point
//! of mass m at rho = x_node + c + u + theta x c (+ (1/2) theta x (theta x c)) in the body
//! frame, with rho's rates u_dot, u_dd of the same kinematics,
//!
//! ```text
//! a   = A^T R_dd + alpha x rho + w x (w x rho) + 2 w x u_dot + u_dd,   F = m (a - A^T g),
//! Q_R = A F,   Q_p = 2 L^T (rho x F),   Q_u = F,   Q_theta = (d rho / d theta)^T F,
//! ```
//!
//! Newton's law projected on the coordinates (exactly Lagrange's equations of the points'
//! kinetic energy and gravity for that kinematics, so the sum conserves energy). Any set of
//! points with the mass's mass, centre and second moments gives the same forces (they are of
//! degree two in c), so the Python side passes a few points that reproduce them. Its
//! Jacobians are the forward-mode derivatives of the same expressions (no truncation error).

use super::*;
use std::ops::{Add, Mul, Neg, Sub};

/// A mass carried by a node with rotations (a point mass with a rotary inertia or an offset;
/// see the module).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AttachedMass {
    /// The elastic coordinates its node's motion depends on (n_l).
    pub indices: Vec<usize>,
    /// The node's displacement and small rotation [u; theta] = rows q_l: 6 x n_l, row-major.
    pub rows: Vec<f64>,
    /// The node's undeformed position in the body frame.
    pub node: Vec3,
    /// Mass points (mass, position relative to the node in body axes) with the mass's mass,
    /// centre and second moments (masses may be negative: only those moments count).
    pub points: Vec<(f64, Vec3)>,
    /// Positions of the (indices[i], indices[j]) pairs in the body's elastic pattern,
    /// row-major n_l x n_l (filled when the body is built).
    pub positions: Vec<usize>,
}

impl AttachedMass {
    /// Whether the sizes agree (rows 6 x n_l over existing elastic coordinates) and every value
    /// is finite.
    pub fn is_consistent(&self, elastic_count: usize) -> bool {
        self.rows.len() == 6 * self.indices.len()
            && self.indices.iter().all(|&i| i < elastic_count)
            && self.rows.iter().all(|x| x.is_finite())
            && self.node.is_finite()
            && self.points.iter().all(|(m, c)| m.is_finite() && c.is_finite())
    }

    /// The node's [u; theta] (6) from the body's elastic coordinates `qf`.
    fn node_motion(&self, qf: &[f64]) -> [f64; 6] {
        let n = self.indices.len();
        std::array::from_fn(|r| (0..n).map(|i| self.rows[r * n + i] * qf[self.indices[i]]).sum())
    }
}

/// The arithmetic the correction is written in: f64 for the forces, [`Lanes`] for their
/// derivatives.
trait Number: Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Neg<Output = Self> {
    fn of(x: f64) -> Self;
    fn times(self, s: f64) -> Self;
}

impl Number for f64 {
    fn of(x: f64) -> Self {
        x
    }
    fn times(self, s: f64) -> Self {
        self * s
    }
}

/// A number with its derivatives along the 13 directions of [`attached_jacobian`] (forward
/// mode, all at once).
#[derive(Clone, Copy, Debug)]
struct Lanes {
    v: f64,
    d: [f64; LANES],
}

/// The directions of [`attached_jacobian`]: the 7 frame coordinates and the node's 6.
const LANES: usize = 13;

impl Number for Lanes {
    fn of(x: f64) -> Self {
        Lanes { v: x, d: [0.0; LANES] }
    }
    fn times(self, s: f64) -> Self {
        Lanes { v: self.v * s, d: self.d.map(|x| x * s) }
    }
}

impl Add for Lanes {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        Lanes { v: self.v + o.v, d: std::array::from_fn(|k| self.d[k] + o.d[k]) }
    }
}

impl Sub for Lanes {
    type Output = Self;
    fn sub(self, o: Self) -> Self {
        Lanes { v: self.v - o.v, d: std::array::from_fn(|k| self.d[k] - o.d[k]) }
    }
}

impl Mul for Lanes {
    type Output = Self;
    #[allow(clippy::suspicious_arithmetic_impl)] // (the product rule)
    fn mul(self, o: Self) -> Self {
        Lanes { v: self.v * o.v, d: std::array::from_fn(|k| self.v * o.d[k] + self.d[k] * o.v) }
    }
}

impl Neg for Lanes {
    type Output = Self;
    fn neg(self) -> Self {
        Lanes { v: -self.v, d: self.d.map(|x| -x) }
    }
}

type V<T> = [T; 3];

fn plus<T: Number>(a: &V<T>, b: &V<T>) -> V<T> {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn minus<T: Number>(a: &V<T>, b: &V<T>) -> V<T> {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn scaled<T: Number>(a: &V<T>, s: f64) -> V<T> {
    [a[0].times(s), a[1].times(s), a[2].times(s)]
}

fn dot<T: Number>(a: &V<T>, b: &V<T>) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross<T: Number>(a: &V<T>, b: &V<T>) -> V<T> {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn constant<T: Number>(v: &Vec3) -> V<T> {
    v.0.map(T::of)
}

/// The frame coordinates [R, p] (value 0, rates 1, accelerations 2; R only as its
/// accelerations) and the node's [u, theta] at the three levels.
#[derive(Clone, Copy)]
struct Motion<T> {
    frame: [[T; 7]; 3],
    node: [[T; 6]; 3],
}

impl<T: Number> Motion<T> {
    /// The motion of the body's coordinates q, q_dot, q_dd for `mass`.
    fn of(mass: &AttachedMass, q: &[f64], qd: &[f64], qdd: &[f64]) -> Self {
        let r7 = REFERENCE_COORDINATES;
        let level = |v: &[f64]| -> ([T; 7], [T; 6]) {
            let node = mass.node_motion(&v[r7..]);
            (std::array::from_fn(|k| T::of(v[k])), node.map(T::of))
        };
        let (f0, n0) = level(q);
        let (f1, n1) = level(qd);
        let (f2, n2) = level(qdd);
        Motion { frame: [f0, f1, f2], node: [n0, n1, n2] }
    }
}

/// The rotation matrix A(p) (rows) and 2 L(p) (see `math::euler`).
fn frame_matrices<T: Number>(p: &[T; 4]) -> ([[T; 3]; 3], [[T; 4]; 3]) {
    let zero = T::of(0.0);
    let (e0, e) = (p[0], [p[1], p[2], p[3]]);
    let d = e0 * e0 - dot(&e, &e);
    let skew = [[zero, -e[2], e[1]], [e[2], zero, -e[0]], [-e[1], e[0], zero]];
    let a = std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            let diagonal = if i == j { d } else { zero };
            diagonal + (e[i] * e[j] + e0 * skew[i][j]).times(2.0)
        })
    });
    let l2 = std::array::from_fn(|i| {
        let mut row = [e[i].times(-2.0), zero, zero, zero];
        for j in 0..3 {
            let diagonal = if i == j { e0 } else { zero };
            row[j + 1] = (diagonal - skew[i][j]).times(2.0);
        }
        row
    });
    (a, l2)
}

fn times<T: Number>(m: &[[T; 3]; 3], v: &V<T>) -> V<T> {
    std::array::from_fn(|i| m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2])
}

fn transpose_times<T: Number>(m: &[[T; 3]; 3], v: &V<T>) -> V<T> {
    std::array::from_fn(|i| m[0][i] * v[0] + m[1][i] * v[1] + m[2][i] * v[2])
}

fn part<T: Number>(v: &[T], start: usize) -> V<T> {
    [v[start], v[start + 1], v[start + 2]]
}

/// The correction of the generalized inertia-minus-gravity force of `mass` (see the module):
/// its frame rows [R (3), p (4)] and its node's rows [u (3), theta (3)].
fn correction<T: Number>(mass: &AttachedMass, s: &Motion<T>, gravity: &Vec3) -> ([T; 7], [T; 6]) {
    let zero = T::of(0.0);
    let sum = |terms: [T; 4]| terms[0] + terms[1] + terms[2] + terms[3];
    let p: [T; 4] = std::array::from_fn(|k| s.frame[0][3 + k]);
    let (a, l2) = frame_matrices(&p);
    let angular = |level: usize| -> V<T> {
        std::array::from_fn(|i| sum(std::array::from_fn(|k| l2[i][k] * s.frame[level][3 + k])))
    };
    let (w, alpha) = (angular(1), angular(2));
    let frame_acceleration = transpose_times(&a, &part(&s.frame[2], 0));
    let weight = transpose_times(&a, &constant(gravity));
    let [n0, n1, n2] = &s.node;
    let (u, th, ud, thd, udd, thdd) =
        (part(n0, 0), part(n0, 3), part(n1, 0), part(n1, 3), part(n2, 0), part(n2, 3));
    let base = plus(&constant(&mass.node), &u);
    let mut frame = [zero; 7];
    let mut rows = [zero; 6];
    for &(m, c) in &mass.points {
        let c = constant(&c);
        let tc = cross(&th, &c);
        let tdc = cross(&thd, &c);
        let tddc = cross(&thdd, &c);
        // The first and second order parts of the point's motion relative to the node.
        let first = [plus(&c, &tc), tdc, tddc];
        let second = [
            scaled(&cross(&th, &tc), 0.5),
            scaled(&plus(&cross(&thd, &tc), &cross(&th, &tdc)), 0.5),
            plus(&scaled(&plus(&cross(&thdd, &tc), &cross(&th, &tddc)), 0.5), &cross(&thd, &tdc)),
        ];
        for (sign, quadratic) in [(1.0, true), (-1.0, false)] {
            let at = |k: usize, from: &V<T>| -> V<T> {
                let v = plus(from, &first[k]);
                if quadratic {
                    plus(&v, &second[k])
                } else {
                    v
                }
            };
            let rho = at(0, &base);
            let (velocity, acceleration) = (at(1, &ud), at(2, &udd));
            let inertial = plus(
                &plus(&frame_acceleration, &cross(&alpha, &rho)),
                &plus(
                    &cross(&w, &cross(&w, &rho)),
                    &plus(&scaled(&cross(&w, &velocity), 2.0), &acceleration),
                ),
            );
            let f = scaled(&minus(&inertial, &weight), m * sign);
            let global = times(&a, &f);
            let moment = cross(&rho, &f);
            for i in 0..3 {
                frame[i] = frame[i] + global[i];
                rows[i] = rows[i] + f[i];
            }
            for k in 0..4 {
                frame[3 + k] =
                    frame[3 + k] + l2[0][k] * moment[0] + l2[1][k] * moment[1] + l2[2][k] * moment[2];
            }
            // (d rho / d theta)^T F: c x F, and for the quadratic term
            // (1/2) ((theta . c) F + c (theta . F) - 2 theta (c . F)).
            let mut turn = cross(&c, &f);
            if quadratic {
                let (tc_, tf, cf) = (dot(&th, &c), dot(&th, &f), dot(&c, &f));
                for i in 0..3 {
                    turn[i] = turn[i] + (tc_ * f[i] + c[i] * tf - (th[i] * cf).times(2.0)).times(0.5);
                }
            }
            for i in 0..3 {
                rows[3 + i] = rows[3 + i] + turn[i];
            }
        }
    }
    (frame, rows)
}

/// Adds the corrections of the body's attached masses to its force `out` (7 + n_f: its
/// residual rows, inertia minus gravity) at q, q_dot, q_dd.
pub fn add_attached_forces(
    body: &FlexibleBody,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    gravity: &Vec3,
    out: &mut [f64],
) {
    let r7 = REFERENCE_COORDINATES;
    for mass in &body.attached {
        let (frame, rows) = correction::<f64>(mass, &Motion::of(mass, q, qd, qdd), gravity);
        for k in 0..7 {
            out[k] += frame[k];
        }
        let n = mass.indices.len();
        for (i, &j) in mass.indices.iter().enumerate() {
            out[r7 + j] += (0..6).map(|r| mass.rows[r * n + i] * rows[r]).sum::<f64>();
        }
    }
}

/// The Jacobian of the correction of `mass` with the coefficients (mass, velocity, position)
/// of its accelerations, rates and coordinates, on its local coordinates [R, p, q_l]
/// (7 + n_l; rows and columns), column-major.
pub fn attached_jacobian(
    mass: &AttachedMass,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    gravity: &Vec3,
    [cm, cv, cp]: [f64; 3],
) -> Vec<f64> {
    let n = mass.indices.len();
    let size = 7 + n;
    // Lane k moves frame coordinate k (k < 7; R only through R_dd) or node coordinate k - 7 at
    // the three levels by the coefficients: its derivative is column k of the Jacobian.
    let mut s = Motion::<Lanes>::of(mass, q, qd, qdd);
    for (level, c) in [cp, cv, cm].into_iter().enumerate() {
        for k in 0..7 {
            if k >= 3 || level == 2 {
                s.frame[level][k].d[k] = c;
            }
        }
        for k in 0..6 {
            s.node[level][k].d[7 + k] = c;
        }
    }
    let (frame, rows) = correction(mass, &s, gravity);
    let mut jacobian = vec![0.0; size * size];
    let mut put = |column: usize, f: [f64; 7], r: [f64; 6]| {
        let col = &mut jacobian[column * size..(column + 1) * size];
        col[..7].copy_from_slice(&f);
        for i in 0..n {
            col[7 + i] = (0..6).map(|k| mass.rows[k * n + i] * r[k]).sum();
        }
    };
    for k in 0..7 {
        put(k, frame.map(|x| x.d[k]), rows.map(|x| x.d[k]));
    }
    for i in 0..n {
        // Column of q_l[i]: the node's directions weighted by its rows.
        let along = |x: &Lanes| (0..6).map(|k| mass.rows[k * n + i] * x.d[7 + k]).sum::<f64>();
        put(7 + i, frame.map(|x| along(&x)), rows.map(|x| along(&x)));
    }
    jacobian
}

/// The kinetic energy of the attached masses' points moving to second order less that of
/// their linear motion (which the invariants hold).
pub fn attached_kinetic_energy(body: &FlexibleBody, q: &[f64], qd: &[f64]) -> f64 {
    let p = [q[3], q[4], q[5], q[6]];
    let a = euler::rotation_matrix(&p);
    let w = euler::body_angular_velocity(&p, &[qd[3], qd[4], qd[5], qd[6]]);
    let v0 = a.tr_mul_vec(&Vec3::from_slice(qd));
    let r7 = REFERENCE_COORDINATES;
    let mut kinetic = 0.0;
    for mass in &body.attached {
        let [u0, u1, u2, t0, t1, t2] = mass.node_motion(&q[r7..]);
        let [v0n, v1n, v2n, d0, d1, d2] = mass.node_motion(&qd[r7..]);
        let (u, th, ud, thd) =
            (Vec3([u0, u1, u2]), Vec3([t0, t1, t2]), Vec3([v0n, v1n, v2n]), Vec3([d0, d1, d2]));
        for &(m, c) in &mass.points {
            let tc = th.cross(&c);
            let rho = mass.node + c + u + tc;
            let quadratic = th.cross(&tc) * 0.5;
            let rate = (thd.cross(&tc) + th.cross(&thd.cross(&c))) * 0.5;
            let linear = v0 + w.cross(&rho) + ud + thd.cross(&c);
            let turned = linear + w.cross(&quadratic) + rate;
            kinetic += 0.5 * m * (turned.dot(&turned) - linear.dot(&linear));
        }
    }
    kinetic
}

/// The gravity potential -m g . r of the attached masses' points moving to second order less
/// that of their linear motion.
pub fn attached_gravity_potential(body: &FlexibleBody, q: &[f64], gravity: &Vec3) -> f64 {
    let g = euler::rotation_matrix(&[q[3], q[4], q[5], q[6]]).tr_mul_vec(gravity);
    let mut potential = 0.0;
    for mass in &body.attached {
        let [_, _, _, t0, t1, t2] = mass.node_motion(&q[REFERENCE_COORDINATES..]);
        let th = Vec3([t0, t1, t2]);
        for &(m, c) in &mass.points {
            potential -= m * g.dot(&(th.cross(&th.cross(&c)) * 0.5));
        }
    }
    potential
}
