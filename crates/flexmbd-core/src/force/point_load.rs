//! Point forces and torques at markers, by virtual work (seed section 3).
//!
//! A force F at a marker origin r(q) gives Q = (dr/dq)^T F; a torque n gives Q = J_w^T n with
//! the angular velocity Jacobian J_w. Components in marker axes turn with the body, which adds
//! the derivative of the axes to -dQ/dq.

use super::{vector_function, ForceEnv, ForceLocal, Frame};
use crate::body::marker::{add_angular_jacobian_derivative, add_position_hessian};
use crate::error::Result;
use crate::ids::MarkerId;
use crate::math::time_function::TimeFunction;
use crate::math::Vec3;

/// Point force at the origin of `marker`.
pub fn point_force(
    item: &str,
    env: &ForceEnv,
    marker: MarkerId,
    components: &[TimeFunction; 3],
    frame: Frame,
    local: &mut ForceLocal,
    tangent: bool,
) -> Result<()> {
    let c = vector_function(item, components, env.time)?;
    let kin = &env.kinematics[marker.0];
    let m = &env.markers[marker.0];
    let body = &env.bodies[m.body.0];
    let force = match frame {
        Frame::Global => c,
        Frame::Marker => kin.rotation.mul_vec(&c),
    };
    kin.jac_position.add_transpose_times(1.0, &force, &mut local.generalized, 0);
    if tangent {
        add_position_hessian(body, m, kin, &force, -1.0, &mut local.stiffness, 0);
        if frame == Frame::Marker {
            for k in 0..3 {
                local.stiffness.add_jt_j(0, 0, -c[k], &kin.jac_position, &kin.jac_axes[k]);
            }
        }
    }
    Ok(())
}

/// Torque on the body of `marker`.
pub fn torque(
    item: &str,
    env: &ForceEnv,
    marker: MarkerId,
    components: &[TimeFunction; 3],
    frame: Frame,
    local: &mut ForceLocal,
    tangent: bool,
) -> Result<()> {
    let c = vector_function(item, components, env.time)?;
    let kin = &env.kinematics[marker.0];
    let m = &env.markers[marker.0];
    let body = &env.bodies[m.body.0];
    let torque: Vec3 = match frame {
        Frame::Global => c,
        Frame::Marker => kin.rotation.mul_vec(&c),
    };
    kin.jac_angular.add_transpose_times(1.0, &torque, &mut local.generalized, 0);
    if tangent {
        add_angular_jacobian_derivative(body, m, kin, &torque, -1.0, &mut local.stiffness, 0);
        if frame == Frame::Marker {
            for k in 0..3 {
                local.stiffness.add_jt_j(0, 0, -c[k], &kin.jac_angular, &kin.jac_axes[k]);
            }
        }
    }
    Ok(())
}
