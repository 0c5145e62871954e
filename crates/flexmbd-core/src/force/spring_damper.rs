//! Linear spring-damper between two marker origins. With d = r_j - r_i, length l = |d| and
//! l_dot = (dl/dq) q_dot, the tension f = k (l - l0) + c l_dot + f0 acts along the line and
//! gives Q = -f dl/dq. Then -dQ/dq = dl/dq^T (k dl/dq + c (d2l/dq2 q_dot)^T) + f d2l/dq2 and
//! -dQ/dq_dot = c dl/dq^T dl/dq.

use crate::error::{FlexmbdError, Result};
use crate::force::ForceLocal;
use crate::joint::equation::{primitive_gradient, primitive_hessian, MarkerPair, Primitive};

/// Evaluates the element; `parameters` = [stiffness, damping, rest length, preload].
pub fn evaluate(
    item: &str,
    pair: &MarkerPair,
    time: f64,
    parameters: [f64; 4],
    local: &mut ForceLocal,
    tangent: bool,
) -> Result<()> {
    let [k, c, l0, f0] = parameters;
    let length = pair.offset().norm();
    if length < 1e-12 {
        return Err(FlexmbdError::NonFinite {
            item: format!("{item} (zero length: direction undefined)"),
            time,
        });
    }
    let n = local.generalized.len();
    let [grad, qd_local, hq, _, _] = &mut local.scratch;
    grad.iter_mut().for_each(|x| *x = 0.0);
    primitive_gradient(&Primitive::Distance, pair, 1.0, grad);
    // Local velocities: relative velocity of the two points projected on the line.
    let d = pair.offset();
    let unit = d * (1.0 / length);
    let length_rate = unit.dot(&(pair.kin_j.velocity() - pair.kin_i.velocity()));
    let tension = k * (length - l0) + c * length_rate + f0;
    for a in 0..n {
        local.generalized[a] = -tension * grad[a];
    }
    if tangent {
        primitive_hessian(&Primitive::Distance, pair, 1.0, &mut local.damping);
        // The damping buffer temporarily holds d2l/dq2; form the stiffness from it.
        local_velocities(pair, qd_local);
        hq.iter_mut().for_each(|x| *x = 0.0);
        local.damping.mul_vec_add(1.0, qd_local, hq);
        for a in 0..n {
            for b in 0..n {
                let h_ab = local.damping.get(a, b);
                local.stiffness.add(a, b, grad[a] * (k * grad[b] + c * hq[b]) + tension * h_ab);
            }
        }
        local.damping.fill_zero();
        local.damping.add_outer(0, 0, c, grad, grad);
    }
    Ok(())
}

/// Local velocity vector of the pair: body i's coordinate velocities, then body j's.
pub(crate) fn local_velocities(pair: &MarkerPair, out: &mut [f64]) {
    let ni = pair.kin_i.jac_position.n;
    out[..ni].copy_from_slice(&pair.kin_i.body_velocity);
    out[ni..].copy_from_slice(&pair.kin_j.body_velocity);
}
