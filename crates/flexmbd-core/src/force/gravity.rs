//! Gravity: the weight m g applied at the centre of mass c of each body, by virtual work
//! Q = (dr_c/dq)^T m g with r_c = R + A(p) c. Its derivative with respect to p is the constant
//! Hessian of p -> (m g) . A(p) c. On a deformable body gravity is distributed: its virtual
//! work also loads the elastic coordinates (`body::flexible::add_gravity_force`).

use crate::body::{Body, BodyKind};
use crate::math::euler::{self, bilinear_hessian, rotate_jacobian, Mat44};
use crate::math::Vec3;

/// Adds the generalized gravity force of `body` to `out` (local coordinates).
pub fn add_gravity_force(body: &Body, q: &[f64], gravity: &Vec3, out: &mut [f64]) {
    match &body.kind {
        BodyKind::Ground => {}
        BodyKind::PointMass { mass } => {
            for k in 0..3 {
                out[k] += mass * gravity[k];
            }
        }
        BodyKind::Rigid(b) => {
            let o = body.offset;
            let p = [q[o + 3], q[o + 4], q[o + 5], q[o + 6]];
            let weight = *gravity * b.mass;
            let j = rotate_jacobian(&p, &b.center_of_mass);
            for k in 0..3 {
                out[k] += weight[k];
            }
            for k in 0..4 {
                out[3 + k] += (0..3).map(|i| j[i][k] * weight[i]).sum::<f64>();
            }
        }
        BodyKind::Flexible(f) => {
            let o = body.offset;
            crate::body::flexible::add_gravity_force(f, &q[o..o + body.dofs.len()], gravity, out);
        }
    }
}

/// dQ/dp of gravity on a rigid body (4 x 4 block on the Euler parameters); None otherwise.
pub fn gravity_jacobian(body: &Body, gravity: &Vec3) -> Option<Mat44> {
    match &body.kind {
        BodyKind::Rigid(b) => Some(bilinear_hessian(&(*gravity * b.mass), &b.center_of_mass)),
        _ => None,
    }
}

/// Potential energy -m g . r_c (J).
pub fn gravity_potential(body: &Body, q: &[f64], gravity: &Vec3) -> f64 {
    let o = body.offset;
    match &body.kind {
        BodyKind::Ground => 0.0,
        BodyKind::PointMass { mass } => -mass * gravity.dot(&Vec3::from_slice(&q[o..])),
        BodyKind::Rigid(b) => {
            let p = [q[o + 3], q[o + 4], q[o + 5], q[o + 6]];
            let rc = Vec3::from_slice(&q[o..]) + euler::rotation_matrix(&p).mul_vec(&b.center_of_mass);
            -b.mass * gravity.dot(&rc)
        }
        BodyKind::Flexible(f) => {
            crate::body::flexible::gravity_potential(f, &q[o..o + body.dofs.len()], gravity)
        }
    }
}
