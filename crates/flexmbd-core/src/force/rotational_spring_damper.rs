//! Torsional spring-damper about the z axis of marker i. The angle of x_j from x_i is
//! theta = atan2(s, c) with s = y_i . x_j and c = x_i . x_j, unwrapped against a reference angle
//! kept in the state (so that several turns accumulate). The torque t = k (theta - theta0) +
//! c_d theta_dot + t0 gives Q = -t dtheta/dq, with theta_dot = (dtheta/dq) q_dot.
//! dtheta = (c ds - s dc) / (s^2 + c^2), and its derivative follows from the Hessians of s, c.
//! The joint actuators act on the same angle through [`angle_derivatives`] and
//! [`apply_moment`].

use crate::error::Result;
use crate::force::spring_damper::local_velocities;
use crate::force::ForceLocal;
use crate::joint::equation::{primitive_gradient, primitive_hessian, primitive_value, MarkerPair, Primitive};

const SINE: Primitive = Primitive::AxisDotAxis(1, 0);
const COSINE: Primitive = Primitive::AxisDotAxis(0, 0);

/// Angle in (-pi, pi] of x_j from x_i about z_i.
pub fn wrapped_angle(pair: &MarkerPair) -> f64 {
    primitive_value(&SINE, pair).atan2(primitive_value(&COSINE, pair))
}

/// The angle continued from `reference` (the unwrapped angle at the last accepted step).
pub fn unwrapped_angle(pair: &MarkerPair, reference: f64) -> f64 {
    let two_pi = 2.0 * std::f64::consts::PI;
    let delta = wrapped_angle(pair) - reference;
    reference + delta - two_pi * (delta / two_pi).round()
}

/// The unwrapped angle and its rate; its gradient dtheta/dq goes to `local.scratch[2]`, the
/// pair's velocities to `scratch[3]` and, if `tangent`, its Hessian to `local.damping`
/// (scratch until [`apply_moment`]).
pub(crate) fn angle_derivatives(
    pair: &MarkerPair,
    reference: f64,
    local: &mut ForceLocal,
    tangent: bool,
) -> (f64, f64) {
    let n = local.generalized.len();
    let s = primitive_value(&SINE, pair);
    let co = primitive_value(&COSINE, pair);
    let rho2 = s * s + co * co;
    let theta = unwrapped_angle(pair, reference);
    let [grad_s, grad_c, grad, qd_local, _] = &mut local.scratch;
    grad_s.iter_mut().for_each(|x| *x = 0.0);
    grad_c.iter_mut().for_each(|x| *x = 0.0);
    primitive_gradient(&SINE, pair, 1.0, grad_s);
    primitive_gradient(&COSINE, pair, 1.0, grad_c);
    for a in 0..n {
        grad[a] = (co * grad_s[a] - s * grad_c[a]) / rho2;
    }
    local_velocities(pair, qd_local);
    let rate: f64 = grad.iter().zip(qd_local.iter()).map(|(g, v)| g * v).sum();
    if tangent {
        let h = &mut local.damping;
        h.fill_zero();
        primitive_hessian(&SINE, pair, co / rho2, h);
        primitive_hessian(&COSINE, pair, -s / rho2, h);
        for a in 0..n {
            for b in 0..n {
                let v = (grad_s[a] * grad_c[b] - grad_c[a] * grad_s[b]) / rho2
                    - grad[a] * 2.0 * (s * grad_s[b] + co * grad_c[b]) / rho2;
                h.add(a, b, v);
            }
        }
    }
    (theta, rate)
}

/// Loads a coordinate x of the pair (gradient in `local.scratch[2]`, the pair's velocities in
/// `scratch[3]`, its Hessian in `local.damping` if `tangent`) with the moment m(x, x_dot)
/// that resists it: Q = -m dx/dq; `stiffness` = dm/dx and `damping` = dm/dx_dot give
/// -dQ/dq = dx/dq (stiffness dx/dq + damping H q_dot)^T + m H and -dQ/dq_dot = damping dx/dq
/// dx/dq^T.
pub(crate) fn apply_moment(local: &mut ForceLocal, moment: f64, stiffness: f64, damping: f64, tangent: bool) {
    let n = local.generalized.len();
    let [_, _, grad, qd_local, hq] = &mut local.scratch;
    for a in 0..n {
        local.generalized[a] = -moment * grad[a];
    }
    if tangent {
        let h = &local.damping;
        hq.iter_mut().for_each(|x| *x = 0.0);
        h.mul_vec_add(1.0, qd_local, hq);
        for a in 0..n {
            for b in 0..n {
                local.stiffness.add(
                    a,
                    b,
                    grad[a] * (stiffness * grad[b] + damping * hq[b]) + moment * h.get(a, b),
                );
            }
        }
        local.damping.fill_zero();
        local.damping.add_outer(0, 0, damping, grad, grad);
    }
}

/// Evaluates the element; `parameters` = [stiffness, damping, rest angle, preload].
pub fn evaluate(
    pair: &MarkerPair,
    _time: f64,
    reference: f64,
    parameters: [f64; 4],
    local: &mut ForceLocal,
    tangent: bool,
) -> Result<()> {
    let [k, c, theta0, t0] = parameters;
    let (theta, rate) = angle_derivatives(pair, reference, local, tangent);
    apply_moment(local, k * (theta - theta0) + c * rate + t0, k, c, tangent);
    Ok(())
}
