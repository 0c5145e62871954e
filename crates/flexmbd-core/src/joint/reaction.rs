//! Joint reaction forces and torques from the Lagrange multipliers.
//!
//! The constraint forces on the coordinates are -C_q^T lambda (seed eq. 20). On a rigid body
//! they are equivalent to a force F (the translational part) and a torque about the body
//! origin n_bar = L Q_p / 2 (inverse of Q_p = 2 L^T n_bar, as L L^T = I); the torque is moved to
//! the marker origin. Reported: the force and torque that the joint exerts on the body of
//! marker j, about the origin of marker j, in the axes of marker j. When marker j is on the
//! ground the values come from body i by action and reaction (the constraints depend only on
//! the relative configuration of the two bodies, so the joint forces balance).

use crate::body::{Body, BodyKind};
use crate::joint::equation::{equation_gradient, MarkerPair};
use crate::joint::Joint;
use crate::math::euler;
use crate::math::Vec3;

/// Force and torque (global axes) about `point` equivalent to the generalized force `gen`
/// (local coordinates of `body`). None for the ground.
pub fn generalized_to_wrench(body: &Body, q: &[f64], gen: &[f64], point: Vec3) -> Option<(Vec3, Vec3)> {
    let o = body.offset;
    match body.kind {
        BodyKind::Ground => None,
        BodyKind::PointMass { .. } => {
            let f = Vec3::from_slice(gen);
            let origin = Vec3::from_slice(&q[o..]);
            Some((f, -(point - origin).cross(&f)))
        }
        BodyKind::Rigid(_) | BodyKind::Flexible(_) => {
            // For a deformable body: the marker's first 7 local coordinates are R and p.
            let f = Vec3::from_slice(gen);
            let p = [q[o + 3], q[o + 4], q[o + 5], q[o + 6]];
            let l = euler::l_matrix(&p);
            let mut n_bar = Vec3::ZERO;
            for i in 0..3 {
                n_bar[i] = 0.5 * (0..4).map(|k| l[i][k] * gen[3 + k]).sum::<f64>();
            }
            let n_origin = euler::rotation_matrix(&p).mul_vec(&n_bar);
            let origin = Vec3::from_slice(&q[o..]);
            Some((f, n_origin - (point - origin).cross(&f)))
        }
    }
}

/// Force and torque on the body of marker j, about marker j's origin, in marker j's axes.
/// `lambda` holds this joint's multipliers; `scratch` is a buffer of the joint's local size.
pub fn joint_reaction(
    joint: &Joint,
    ctx: &MarkerPair,
    f: &[f64; 3],
    lambda: &[f64],
    q: &[f64],
    scratch: &mut [f64],
) -> (Vec3, Vec3) {
    scratch.iter_mut().for_each(|x| *x = 0.0);
    for (eq, &l) in joint.equations.iter().zip(lambda) {
        equation_gradient(eq, ctx, f, -l, scratch, None);
    }
    let point_j = ctx.kin_j.position;
    let (force, torque) =
        if let Some(w) = generalized_to_wrench(ctx.body_j, q, &scratch[joint.n_i..], point_j) {
            w
        } else if let Some((fi, ni)) =
            generalized_to_wrench(ctx.body_i, q, &scratch[..joint.n_i], ctx.kin_i.position)
        {
            let point_i = ctx.kin_i.position;
            (-fi, -ni - (point_i - point_j).cross(&fi))
        } else {
            (Vec3::ZERO, Vec3::ZERO)
        };
    let r = ctx.kin_j.rotation;
    (r.tr_mul_vec(&force), r.tr_mul_vec(&torque))
}
