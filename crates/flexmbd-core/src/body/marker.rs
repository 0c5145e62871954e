//! Markers: frames fixed on bodies. Joints, forces and sensors act on markers.
//!
//! A marker on a rigid body has a constant position u and orientation A_m in the body frame;
//! its global position is r = R + A(p) u and its axes are the columns of A(p) A_m.
//!
//! A marker on a deformable body is an intermediate joint frame (seed Figure 4): attached to a
//! point of the body (a node, or the average of a node set), it moves with the deformation,
//! u = u0 + S_u q_f, and turns by the small rotation theta = S_t q_f of that point, so that its
//! body-frame orientation is the infinitesimal rotation (I + theta~) A_m (seed section 4: the
//! matrices A_p of eq. 22 "expressed in terms of the slopes at the nodal points"). S_u and S_t
//! are 3 x n_l matrices over the n_l elastic coordinates the point depends on (the node's own
//! coordinates in a nodal body, every mode in a modal body).
//!
//! A marker's local coordinates are those of its body it depends on: all of a rigid body's,
//! the 7 reference coordinates and its n_l elastic coordinates of a deformable body. For every
//! marker the workspace holds its position, axes and velocities with their exact Jacobians
//! with respect to these, and the functions below add the second derivatives (contracted with
//! a vector) that the Newton matrix and the constraint acceleration terms need.

use super::{Body, BodyKind};
use crate::ids::BodyId;
use crate::math::dense::{DenseMatrix, Jacobian3};
use crate::math::euler::{
    self, bilinear_hessian, gt_jacobian, rotate_jacobian, rotate_transpose_jacobian, Quaternion,
};
use crate::math::{Mat3, Vec3};

/// The elastic part of a marker on a deformable body: u = u0 + S_u q_l, theta = S_t q_l with
/// q_l the elastic coordinates listed in `indices`.
#[derive(Clone, Debug, PartialEq)]
pub struct MarkerElastic {
    /// Indices of the elastic coordinates q_l (0-based among the body's n_f).
    pub indices: Vec<usize>,
    /// S_u (3 x n_l): displacement of the marker origin per coordinate (body axes).
    pub translation: Jacobian3,
    /// S_t (3 x n_l): small rotation of the marker frame per coordinate (body axes).
    pub rotation: Jacobian3,
}

/// A marker of a compiled model.
#[derive(Clone, Debug)]
pub struct Marker {
    /// User name (or `marker <index>`).
    pub name: String,
    /// The body it is fixed on.
    pub body: BodyId,
    /// Position in the body frame, undeformed (m).
    pub position: Vec3,
    /// Orientation in the body frame, undeformed (columns: marker axes in body coordinates).
    pub rotation: Mat3,
    /// Elastic motion of the marker on a deformable body.
    pub elastic: Option<MarkerElastic>,
    /// Global coordinate indices the marker depends on (its local column order).
    pub dofs: Vec<usize>,
    /// Per axis: whether some joint or force differentiates it (else its Jacobian is not
    /// computed).
    pub axis_jacobians: [bool; 3],
    /// Whether a torque or an angular-velocity sensor needs the angular-velocity Jacobian
    /// (else it is not computed, and [`MarkerKinematics::angular_velocity`] is not asked for).
    pub angular_jacobian: bool,
}

/// Position, orientation and Jacobians of a marker at the current state, and the velocities
/// of its local coordinates. Filled by [`marker_kinematics`]; Jacobians have one column per
/// local coordinate. The marker's velocities are formed on demand ([`Self::velocity`],
/// [`Self::angular_velocity`]): the assemblies of the Newton iterations need them only for
/// velocity-dependent force elements.
#[derive(Clone, Debug, Default)]
pub struct MarkerKinematics {
    /// Global position r (m).
    pub position: Vec3,
    /// Global orientation (columns: marker axes in the global frame).
    pub rotation: Mat3,
    /// dr/dq (3 x n).
    pub jac_position: Jacobian3,
    /// d(axis k)/dq (3 x n each).
    pub jac_axes: [Jacobian3; 3],
    /// Angular velocity Jacobian: w = J q_dot (3 x n).
    pub jac_angular: Jacobian3,
    /// Velocities of the local coordinates (n), copied for velocity-dependent elements.
    pub body_velocity: Vec<f64>,
    /// Euler parameters of the body (zero for the ground and point masses).
    pub euler: Quaternion,
    /// Position in the body frame, deformed: u = u0 + S_u q_l (m).
    pub local_position: Vec3,
    /// Axes in the body frame, deformed (columns).
    pub local_axes: Mat3,
}

impl MarkerKinematics {
    /// Buffers for a marker with `n` local coordinates.
    pub fn with_size(n: usize) -> Self {
        MarkerKinematics {
            jac_position: Jacobian3::zeros(n),
            jac_axes: [Jacobian3::zeros(n), Jacobian3::zeros(n), Jacobian3::zeros(n)],
            jac_angular: Jacobian3::zeros(n),
            body_velocity: vec![0.0; n],
            ..Default::default()
        }
    }

    /// Global velocity of the marker origin (m/s).
    pub fn velocity(&self) -> Vec3 {
        self.jac_position.times(&self.body_velocity)
    }

    /// Global angular velocity (rad/s); only for markers with `angular_jacobian`.
    pub fn angular_velocity(&self) -> Vec3 {
        self.jac_angular.times(&self.body_velocity)
    }

    /// Global axis k (column k of the rotation).
    pub fn axis(&self, k: usize) -> Vec3 {
        self.rotation.column(k)
    }
}

fn quaternion(q: &[f64], offset: usize) -> Quaternion {
    [q[offset + 3], q[offset + 4], q[offset + 5], q[offset + 6]]
}

/// The body-frame position and axes of a marker: undeformed, or moved by the elastic
/// coordinates of a deformable body.
fn local_frame(marker: &Marker, q: &[f64], offset: usize) -> (Vec3, Mat3) {
    match &marker.elastic {
        None => (marker.position, marker.rotation),
        Some(e) => {
            let ql = |j: usize| q[offset + 7 + e.indices[j]];
            let mut u = marker.position;
            let mut theta = Vec3::ZERO;
            for j in 0..e.indices.len() {
                let x = ql(j);
                for i in 0..3 {
                    u[i] += e.translation.get(i, j) * x;
                    theta[i] += e.rotation.get(i, j) * x;
                }
            }
            let mut axes = marker.rotation;
            for k in 0..3 {
                let c = marker.rotation.column(k) + theta.cross(&marker.rotation.column(k));
                for i in 0..3 {
                    axes.0[i][k] = c[i];
                }
            }
            (u, axes)
        }
    }
}

/// Fills `out` for `marker` on `body` at coordinates `q` and velocities `qd` (global vectors).
pub fn marker_kinematics(body: &Body, marker: &Marker, q: &[f64], qd: &[f64], out: &mut MarkerKinematics) {
    let o = body.offset;
    for (v, &d) in out.body_velocity.iter_mut().zip(&marker.dofs) {
        *v = qd[d];
    }
    match &body.kind {
        BodyKind::Ground => {
            out.position = marker.position;
            out.rotation = marker.rotation;
            out.local_position = marker.position;
            out.local_axes = marker.rotation;
        }
        BodyKind::PointMass { .. } => {
            out.position = Vec3::from_slice(&q[o..]) + marker.position;
            out.rotation = marker.rotation;
            out.local_position = marker.position;
            out.local_axes = marker.rotation;
            out.jac_position.fill_zero();
            for k in 0..3 {
                out.jac_position.set(k, k, 1.0);
            }
        }
        BodyKind::Rigid(_) | BodyKind::Flexible(_) => {
            let p = quaternion(q, o);
            let a = euler::rotation_matrix(&p);
            let (u, axes) = local_frame(marker, q, o);
            out.euler = p;
            out.local_position = u;
            out.local_axes = axes;
            out.position = Vec3::from_slice(&q[o..]) + a.mul_vec(&u);
            out.rotation = a.mul_mat(&axes);
            let jr = rotate_jacobian(&p, &u);
            let g = euler::g_matrix(&p);
            for i in 0..3 {
                for j in 0..3 {
                    out.jac_position.set(i, j, if i == j { 1.0 } else { 0.0 });
                }
                for j in 0..4 {
                    out.jac_position.set(i, 3 + j, jr[i][j]);
                    if marker.angular_jacobian {
                        out.jac_angular.set(i, 3 + j, 2.0 * g[i][j]);
                    }
                }
            }
            for k in 0..3 {
                if marker.axis_jacobians[k] {
                    let jk = rotate_jacobian(&p, &axes.column(k));
                    for i in 0..3 {
                        for j in 0..4 {
                            out.jac_axes[k].set(i, 3 + j, jk[i][j]);
                        }
                    }
                }
            }
            if let Some(e) = &marker.elastic {
                // dr/dq_l = A S_u; w = ... + A S_t q_l_dot; d(axis k)/dq_l = A (S_t e_j x c_k)
                // = A (-c_k~) S_t, exact also off |p| = 1 (where A(p) is a scaled rotation).
                set_product(&a, &e.translation, &mut out.jac_position, 7);
                if marker.angular_jacobian {
                    set_product(&a, &e.rotation, &mut out.jac_angular, 7);
                }
                for k in 0..3 {
                    if marker.axis_jacobians[k] {
                        let b = a.mul_mat(&marker.rotation.column(k).skew()).scale(-1.0);
                        set_product(&b, &e.rotation, &mut out.jac_axes[k], 7);
                    }
                }
            }
        }
    }
}

/// Columns `offset..offset + s.n` of `out` = m s (3 x 3 times 3 x n, row by row).
fn set_product(m: &Mat3, s: &Jacobian3, out: &mut Jacobian3, offset: usize) {
    let n = s.n;
    let (r0, r1, r2) = (&s.data[..n], &s.data[n..2 * n], &s.data[2 * n..3 * n]);
    for (i, mi) in m.0.iter().enumerate() {
        let start = i * out.n + offset;
        for (d, ((a, b), c)) in out.data[start..start + n].iter_mut().zip(r0.iter().zip(r1).zip(r2)) {
            *d = mi[0] * a + mi[1] * b + mi[2] * c;
        }
    }
}

/// Adds `w * d^2 (v . b) / dq_b dq_l` and its transpose for b = A(p) (c + S q_l) at
/// (offset + 3.., offset + 7..): the (p, q_l) blocks (s: 3 x n_l, the body-frame derivative).
fn add_cross_hessian(q: &Quaternion, s: &Jacobian3, v: &Vec3, w: f64, out: &mut DenseMatrix, offset: usize) {
    let rt = rotate_transpose_jacobian(q, v);
    for j in 0..s.n {
        for a in 0..4 {
            let h = w * (0..3).map(|i| rt[i][a] * s.get(i, j)).sum::<f64>();
            out.add(offset + 3 + a, offset + 7 + j, h);
            out.add(offset + 7 + j, offset + 3 + a, h);
        }
    }
}

/// -c~ S_t: the body-frame derivative of axis c + theta x c with respect to q_l.
fn axis_elastic_derivative(c: &Vec3, st: &Jacobian3) -> Jacobian3 {
    let mut out = Jacobian3::zeros(st.n);
    for j in 0..st.n {
        let t = Vec3([st.get(0, j), st.get(1, j), st.get(2, j)]);
        let col = t.cross(c);
        for i in 0..3 {
            out.set(i, j, col[i]);
        }
    }
    out
}

/// Adds `w * d^2 (v . r) / dq^2` of the marker position into `out` at (offset, offset).
pub fn add_position_hessian(
    body: &Body,
    marker: &Marker,
    kin: &MarkerKinematics,
    v: &Vec3,
    w: f64,
    out: &mut DenseMatrix,
    offset: usize,
) {
    if matches!(body.kind, BodyKind::Rigid(_) | BodyKind::Flexible(_)) {
        out.add_block44(offset + 3, offset + 3, w, &bilinear_hessian(v, &kin.local_position));
        if let Some(e) = &marker.elastic {
            add_cross_hessian(&kin.euler, &e.translation, v, w, out, offset);
        }
    }
}

/// Adds `w * d^2 (v . axis_k) / dq^2` of marker axis k into `out` at (offset, offset).
#[allow(clippy::too_many_arguments)]
pub fn add_axis_hessian(
    body: &Body,
    marker: &Marker,
    kin: &MarkerKinematics,
    k: usize,
    v: &Vec3,
    w: f64,
    out: &mut DenseMatrix,
    offset: usize,
) {
    if matches!(body.kind, BodyKind::Rigid(_) | BodyKind::Flexible(_)) {
        out.add_block44(offset + 3, offset + 3, w, &bilinear_hessian(v, &kin.local_axes.column(k)));
        if let Some(e) = &marker.elastic {
            let s = axis_elastic_derivative(&marker.rotation.column(k), &e.rotation);
            add_cross_hessian(&kin.euler, &s, v, w, out, offset);
        }
    }
}

/// Adds `w * d(J_w^T n)/dq` (the derivative of the generalized force of a constant global
/// torque n) into `out` at (offset, offset). On a deformable body the torque also loads the
/// elastic coordinates through S_t^T A^T n: a moment is not a free vector (seed section 3).
pub fn add_angular_jacobian_derivative(
    body: &Body,
    marker: &Marker,
    kin: &MarkerKinematics,
    n: &Vec3,
    w: f64,
    out: &mut DenseMatrix,
    offset: usize,
) {
    if matches!(body.kind, BodyKind::Rigid(_) | BodyKind::Flexible(_)) {
        out.add_block44(offset + 3, offset + 3, 2.0 * w, &gt_jacobian(n));
        if let Some(e) = &marker.elastic {
            let rt = rotate_transpose_jacobian(&kin.euler, n);
            for j in 0..e.indices.len() {
                for a in 0..4 {
                    let h: f64 = (0..3).map(|i| e.rotation.get(i, j) * rt[i][a]).sum();
                    out.add(offset + 7 + j, offset + 3 + a, w * h);
                }
            }
        }
    }
}

/// Acceleration of the marker origin and angular acceleration of the marker frame (global).
pub fn marker_accelerations(
    body: &Body,
    marker: &Marker,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
) -> (Vec3, Vec3) {
    let o = body.offset;
    match &body.kind {
        BodyKind::Ground => (Vec3::ZERO, Vec3::ZERO),
        BodyKind::PointMass { .. } => (Vec3::from_slice(&qdd[o..]), Vec3::ZERO),
        BodyKind::Rigid(_) | BodyKind::Flexible(_) => {
            let p = quaternion(q, o);
            let a = euler::rotation_matrix(&p);
            let w = euler::body_angular_velocity(&p, &quaternion(qd, o));
            let alpha = euler::body_angular_velocity(&p, &quaternion(qdd, o));
            let (u, _) = local_frame(marker, q, o);
            let (mut ud, mut udd, mut thd, mut thdd) = (Vec3::ZERO, Vec3::ZERO, Vec3::ZERO, Vec3::ZERO);
            if let Some(e) = &marker.elastic {
                for (j, &idx) in e.indices.iter().enumerate() {
                    let (v, acc) = (qd[o + 7 + idx], qdd[o + 7 + idx]);
                    for i in 0..3 {
                        ud[i] += e.translation.get(i, j) * v;
                        udd[i] += e.translation.get(i, j) * acc;
                        thd[i] += e.rotation.get(i, j) * v;
                        thdd[i] += e.rotation.get(i, j) * acc;
                    }
                }
            }
            let local = alpha.cross(&u) + w.cross(&w.cross(&u)) + w.cross(&ud) * 2.0 + udd;
            let acc = Vec3::from_slice(&qdd[o..]) + a.mul_vec(&local);
            (acc, a.mul_vec(&(alpha + thdd + w.cross(&thd))))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::flexible::tests::{random_state, PointBody};
    use crate::body::flexible::FlexibleBody;
    use crate::testing::{assert_all_close, assert_close};

    fn setup() -> (Body, Marker, Vec<f64>, Vec<f64>) {
        let n = 4;
        let body = FlexibleBody::new("b", PointBody::random(5, n, 3).input(1.0, 0.1)).unwrap();
        let body = Body {
            name: "b".into(),
            kind: BodyKind::Flexible(Box::new(body)),
            offset: 0,
            dofs: (0..7 + n).collect(),
        };
        let mut translation = Jacobian3::zeros(2);
        let mut rotation = Jacobian3::zeros(2);
        for (k, v) in [0.3, -0.2, 0.5, 0.1, 0.7, -0.4].iter().enumerate() {
            translation.data[k] = *v;
            rotation.data[k] = 0.5 * v + 0.1;
        }
        let p: [f64; 4] = [0.9, 0.1, -0.3, 0.2];
        let norm = p.iter().map(|x| x * x).sum::<f64>().sqrt();
        let c = crate::math::euler::rotation_matrix(&p.map(|x| x / norm));
        let marker = Marker {
            name: "m".into(),
            body: BodyId(1),
            position: Vec3([0.3, -0.1, 0.2]),
            rotation: c,
            elastic: Some(MarkerElastic { indices: vec![3, 1], translation, rotation }),
            dofs: vec![0, 1, 2, 3, 4, 5, 6, 10, 8],
            axis_jacobians: [true; 3],
            angular_jacobian: true,
        };
        let (q, qd, _) = random_state(n, 5);
        (body, marker, q, qd)
    }

    fn local(marker: &Marker, q: &[f64]) -> Vec<f64> {
        marker.dofs.iter().map(|&d| q[d]).collect()
    }

    #[test]
    fn jacobians_and_hessians_match_finite_differences() {
        let (body, marker, q, qd) = setup();
        let nl = marker.dofs.len();
        let mut kin = MarkerKinematics::with_size(nl);
        marker_kinematics(&body, &marker, &q, &qd, &mut kin);
        let v = Vec3([0.4, -1.1, 0.7]);
        let h = 1e-6;
        // Value of v . r and v . axis_k, and their gradients, at perturbed coordinates.
        let eval = |q: &[f64]| {
            let mut k = MarkerKinematics::with_size(nl);
            marker_kinematics(&body, &marker, q, &qd, &mut k);
            k
        };
        for (which, k) in [(0usize, 0usize), (1, 0), (1, 1), (1, 2)] {
            let mut hess = DenseMatrix::zeros(nl, nl);
            if which == 0 {
                add_position_hessian(&body, &marker, &kin, &v, 1.0, &mut hess, 0);
            } else {
                add_axis_hessian(&body, &marker, &kin, k, &v, 1.0, &mut hess, 0);
            }
            for (c, &d) in marker.dofs.iter().enumerate() {
                let (mut qp, mut qm) = (q.clone(), q.clone());
                qp[d] += h;
                qm[d] -= h;
                let (kp, km) = (eval(&qp), eval(&qm));
                let value = |kk: &MarkerKinematics| if which == 0 { kk.position } else { kk.axis(k) };
                let fd = (value(&kp) - value(&km)) * (1.0 / (2.0 * h));
                let jac = if which == 0 { &kin.jac_position } else { &kin.jac_axes[k] };
                let column: [f64; 3] = std::array::from_fn(|i| jac.get(i, c));
                assert_all_close(&fd.0, &column, 0.0, 1e-8, format_args!("jacobian {which}/{k}, column {c}"));
                // Hessian column c: d/dq_c of the gradient v^T J.
                let grad = |kk: &MarkerKinematics| {
                    let j = if which == 0 { &kk.jac_position } else { &kk.jac_axes[k] };
                    let mut g = vec![0.0; nl];
                    j.add_transpose_times(1.0, &v, &mut g, 0);
                    g
                };
                let (gp, gm) = (grad(&kp), grad(&km));
                let fd: Vec<f64> = (0..nl).map(|r| (gp[r] - gm[r]) / (2.0 * h)).collect();
                let column: Vec<f64> = (0..nl).map(|r| hess.get(r, c)).collect();
                assert_all_close(&fd, &column, 0.0, 1e-7, format_args!("hessian {which}/{k}, column {c}"));
            }
        }
        // Velocity and angular velocity, in an undeformed configuration (there the marker frame
        // is a rotation) moving with p . p_dot = 0: R_dot R^T = w~.
        let vel = |q: &[f64], qd: &[f64]| {
            let step = |s: f64| -> Vec<f64> { q.iter().zip(qd).map(|(a, b)| a + s * b).collect() };
            let dt = 1e-6;
            let (kp, km) = (eval(&step(dt)), eval(&step(-dt)));
            ((kp.position - km.position) * (1.0 / (2.0 * dt)), (kp.rotation - km.rotation).scale(0.5 / dt))
        };
        let (fd, _) = vel(&q, &qd);
        assert_close((fd - kin.velocity()).norm(), 0.0, 0.0, 1e-8, "|fd velocity - velocity|");
        let jq = kin.jac_position.times(&local(&marker, &qd));
        assert_close((jq - kin.velocity()).norm(), 0.0, 0.0, 1e-12, "|J q_dot - velocity|");
        let mut q0 = q.clone();
        q0[7..].iter_mut().for_each(|x| *x = 0.0);
        let mut qd0 = qd.clone();
        let pp: f64 = (3..7).map(|k| q0[k] * qd0[k]).sum();
        (3..7).for_each(|k| qd0[k] -= pp * q0[k]);
        let mut k0 = MarkerKinematics::with_size(nl);
        marker_kinematics(&body, &marker, &q0, &qd0, &mut k0);
        let (_, rdot) = vel(&q0, &qd0);
        let wt = rdot.mul_mat(&k0.rotation.transpose());
        let w = Vec3([wt.0[2][1], wt.0[0][2], wt.0[1][0]]);
        let what = format!("|{w:?} - {:?}|", k0.angular_velocity());
        assert_close((w - k0.angular_velocity()).norm(), 0.0, 0.0, 1e-7, what);
    }
}
