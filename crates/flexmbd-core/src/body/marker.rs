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
    /// Whether some joint or force differentiates the marker's axes (else their Jacobians are
    /// not computed).
    pub axis_jacobians: bool,
}

/// Position, orientation, velocities and Jacobians of a marker at the current state.
/// Filled by [`marker_kinematics`]; Jacobians have one column per local coordinate.
#[derive(Clone, Debug, Default)]
pub struct MarkerKinematics {
    /// Global position r (m).
    pub position: Vec3,
    /// Global orientation (columns: marker axes in the global frame).
    pub rotation: Mat3,
    /// Global velocity of the marker origin (m/s).
    pub velocity: Vec3,
    /// Global angular velocity (rad/s).
    pub angular_velocity: Vec3,
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
            out.velocity = Vec3::ZERO;
            out.angular_velocity = Vec3::ZERO;
        }
        BodyKind::PointMass { .. } => {
            out.position = Vec3::from_slice(&q[o..]) + marker.position;
            out.rotation = marker.rotation;
            out.local_position = marker.position;
            out.local_axes = marker.rotation;
            out.velocity = Vec3::from_slice(&qd[o..]);
            out.angular_velocity = Vec3::ZERO;
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
                    out.jac_angular.set(i, 3 + j, 2.0 * g[i][j]);
                }
            }
            if marker.axis_jacobians {
                for k in 0..3 {
                    let jk = rotate_jacobian(&p, &axes.column(k));
                    for i in 0..3 {
                        for j in 0..4 {
                            out.jac_axes[k].set(i, 3 + j, jk[i][j]);
                        }
                    }
                }
            }
            if let Some(e) = &marker.elastic {
                // dr/dq_l = A S_u; d(axis k)/dq_l = A (S_t e_j x c_k); w = ... + A S_t q_l_dot.
                for j in 0..e.indices.len() {
                    let su = a.mul_vec(&Vec3([
                        e.translation.get(0, j),
                        e.translation.get(1, j),
                        e.translation.get(2, j),
                    ]));
                    let st =
                        a.mul_vec(&Vec3([e.rotation.get(0, j), e.rotation.get(1, j), e.rotation.get(2, j)]));
                    for i in 0..3 {
                        out.jac_position.set(i, 7 + j, su[i]);
                        out.jac_angular.set(i, 7 + j, st[i]);
                    }
                    if marker.axis_jacobians {
                        for k in 0..3 {
                            let col = st.cross(&a.mul_vec(&marker.rotation.column(k)));
                            for i in 0..3 {
                                out.jac_axes[k].set(i, 7 + j, col[i]);
                            }
                        }
                    }
                }
            }
            out.velocity = out.jac_position.times(&out.body_velocity);
            out.angular_velocity = out.jac_angular.times(&out.body_velocity);
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
