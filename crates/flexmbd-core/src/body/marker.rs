//! Markers: frames fixed on bodies. Joints, forces and sensors act on markers.
//!
//! A marker on body i has a constant position u and orientation A_m in the body frame; its
//! global position is r = R + A(p) u and its axes are the columns of A(p) A_m. For every
//! marker the workspace holds these together with their exact Jacobians with respect to the
//! coordinates of its body, and the functions below add the second derivatives (contracted
//! with a vector) that the Newton matrix and the constraint acceleration terms need.

use super::{Body, BodyKind};
use crate::ids::BodyId;
use crate::math::dense::{DenseMatrix, Jacobian3};
use crate::math::euler::{self, bilinear_hessian, gt_jacobian, rotate_jacobian, Quaternion};
use crate::math::{Mat3, Vec3};

/// A marker of a compiled model.
#[derive(Clone, Debug)]
pub struct Marker {
    /// User name (or `marker <index>`).
    pub name: String,
    /// The body it is fixed on.
    pub body: BodyId,
    /// Position in the body frame (m).
    pub position: Vec3,
    /// Orientation in the body frame (columns: marker axes in body coordinates).
    pub rotation: Mat3,
    /// Whether some joint or force differentiates the marker's axes (else their Jacobians are
    /// not computed).
    pub axis_jacobians: bool,
}

/// Position, orientation, velocities and Jacobians of a marker at the current state.
/// Filled by [`marker_kinematics`]; Jacobians have one column per coordinate of the body.
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
    /// Velocities of the body's coordinates (n), copied for velocity-dependent elements.
    pub body_velocity: Vec<f64>,
}

impl MarkerKinematics {
    /// Buffers for a marker on a body with `n` coordinates.
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

/// Fills `out` for `marker` on `body` at coordinates `q` and velocities `qd` (global vectors).
pub fn marker_kinematics(body: &Body, marker: &Marker, q: &[f64], qd: &[f64], out: &mut MarkerKinematics) {
    let o = body.offset;
    let n = out.body_velocity.len();
    out.body_velocity.copy_from_slice(&qd[o..o + n]);
    match &body.kind {
        BodyKind::Ground => {
            out.position = marker.position;
            out.rotation = marker.rotation;
            out.velocity = Vec3::ZERO;
            out.angular_velocity = Vec3::ZERO;
        }
        BodyKind::PointMass { .. } => {
            out.position = Vec3::from_slice(&q[o..]) + marker.position;
            out.rotation = marker.rotation;
            out.velocity = Vec3::from_slice(&qd[o..]);
            out.angular_velocity = Vec3::ZERO;
            out.jac_position.fill_zero();
            for k in 0..3 {
                out.jac_position.set(k, k, 1.0);
            }
        }
        BodyKind::Rigid(_) => {
            let p = quaternion(q, o);
            let p_dot = quaternion(qd, o);
            let a = euler::rotation_matrix(&p);
            out.position = Vec3::from_slice(&q[o..]) + a.mul_vec(&marker.position);
            out.rotation = a.mul_mat(&marker.rotation);
            let jr = rotate_jacobian(&p, &marker.position);
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
            for k in 0..3 {
                if !marker.axis_jacobians {
                    break;
                }
                let jk = rotate_jacobian(&p, &marker.rotation.column(k));
                for i in 0..3 {
                    for j in 0..4 {
                        out.jac_axes[k].set(i, 3 + j, jk[i][j]);
                    }
                }
            }
            let body_qd = &qd[o..o + 7];
            out.velocity = out.jac_position.times(body_qd);
            out.angular_velocity = euler::global_angular_velocity(&p, &p_dot);
        }
    }
}

/// Adds `w * d^2 (v . r) / dq^2` of the marker position into `out` at (offset, offset).
pub fn add_position_hessian(
    body: &Body,
    marker: &Marker,
    v: &Vec3,
    w: f64,
    out: &mut DenseMatrix,
    offset: usize,
) {
    if let BodyKind::Rigid(_) = body.kind {
        out.add_block44(offset + 3, offset + 3, w, &bilinear_hessian(v, &marker.position));
    }
}

/// Adds `w * d^2 (v . axis_k) / dq^2` of marker axis k into `out` at (offset, offset).
pub fn add_axis_hessian(
    body: &Body,
    marker: &Marker,
    k: usize,
    v: &Vec3,
    w: f64,
    out: &mut DenseMatrix,
    offset: usize,
) {
    if let BodyKind::Rigid(_) = body.kind {
        out.add_block44(offset + 3, offset + 3, w, &bilinear_hessian(v, &marker.rotation.column(k)));
    }
}

/// Adds `w * d(J_w^T n)/dq` (the derivative of the generalized force of a constant global
/// torque n) into `out` at (offset, offset).
pub fn add_angular_jacobian_derivative(body: &Body, n: &Vec3, w: f64, out: &mut DenseMatrix, offset: usize) {
    if let BodyKind::Rigid(_) = body.kind {
        out.add_block44(offset + 3, offset + 3, 2.0 * w, &gt_jacobian(n));
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
        BodyKind::Rigid(_) => {
            let p = quaternion(q, o);
            let a = euler::rotation_matrix(&p);
            let w = euler::body_angular_velocity(&p, &quaternion(qd, o));
            let alpha = euler::body_angular_velocity(&p, &quaternion(qdd, o));
            let u = marker.position;
            let acc = Vec3::from_slice(&qdd[o..]) + a.mul_vec(&(alpha.cross(&u) + w.cross(&w.cross(&u))));
            (acc, a.mul_vec(&alpha))
        }
    }
}
