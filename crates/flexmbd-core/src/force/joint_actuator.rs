//! Joint actuators: a PD servo on a joint coordinate x, the angle of marker j's x axis from
//! marker i's about z_i (revolute and cylindrical joints; unwrapped over full turns like the
//! torsional spring) or the slide (r_j - r_i) . z_i (prismatic and cylindrical joints). Its
//! effort
//!
//! u = k_p (f(t) - x) + k_d (f'(t) - x_dot) + u_ff(t),
//!
//! with the set point f and its rate f' (velocity feed-forward) and a feed-forward effort
//! u_ff, limited to |u| <= u_max (saturation), acts on marker j's body (and -u on marker i's)
//! along x: Q = u dx/dq. Its Jacobians are analytic, with H the Hessian of x:
//! -dQ/dq = dx/dq (k_p dx/dq + k_d H q_dot)^T + (-u) H and -dQ/dq_dot = k_d dx/dq dx/dq^T,
//! the gains dropping out where the effort is saturated.

use crate::error::{FlexmbdError, Result};
use crate::force::rotational_spring_damper::{angle_derivatives, apply_moment};
use crate::force::spring_damper::local_velocities;
use crate::force::ForceLocal;
use crate::joint::equation::{primitive_gradient, primitive_hessian, primitive_value, MarkerPair, Primitive};
use crate::math::time_function::TimeFunction;

/// The slide of marker j along z_i.
const SLIDE: Primitive = Primitive::AxisDotOffset(2);

/// The joint coordinate an actuator drives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ActuatedCoordinate {
    /// The angle of x_j from x_i about z_i (rad); effort a torque (N m).
    Angle,
    /// The slide (r_j - r_i) . z_i (m); effort a force (N).
    Slide,
}

impl ActuatedCoordinate {
    /// "angle" or "slide".
    pub fn name(self) -> &'static str {
        match self {
            ActuatedCoordinate::Angle => "angle",
            ActuatedCoordinate::Slide => "slide",
        }
    }

    /// The unit of the effort.
    pub fn effort_unit(self) -> &'static str {
        match self {
            ActuatedCoordinate::Angle => "N m",
            ActuatedCoordinate::Slide => "N",
        }
    }

    /// The discrete variables of an actuator of this coordinate: the saturation state (-1,
    /// 0, +1), after the unwrapped reference angle for angles.
    pub fn discrete_variables(self) -> usize {
        match self {
            ActuatedCoordinate::Angle => 2,
            ActuatedCoordinate::Slide => 1,
        }
    }
}

/// The control law of a joint actuator.
#[derive(Clone, Debug)]
pub struct ServoLaw {
    /// k_p (N m/rad or N/m), >= 0.
    pub proportional_gain: f64,
    /// k_d (N m s/rad or N s/m), >= 0.
    pub derivative_gain: f64,
    /// The set point f(t) (its derivative is the velocity feed-forward).
    pub set_point: TimeFunction,
    /// The feed-forward effort u_ff(t).
    pub feed_forward: TimeFunction,
    /// The largest |u| (infinite: no limit), > 0.
    pub limit: f64,
}

/// The effort of a servo law at a state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Effort {
    /// The effort the law asks for, before the limit.
    pub demand: f64,
    /// The effort applied.
    pub effort: f64,
    /// -1 or +1 where the limit cuts the demand, 0 otherwise.
    pub saturation: f64,
}

impl ServoLaw {
    /// Checks the gains (finite, >= 0, not both zero) and the limit (> 0).
    pub fn validate(&self) -> std::result::Result<(), String> {
        let (kp, kd) = (self.proportional_gain, self.derivative_gain);
        if !(kp.is_finite() && kd.is_finite() && kp >= 0.0 && kd >= 0.0) {
            return Err(format!("the gains must be finite and >= 0, got {kp} and {kd}"));
        }
        if !(self.limit > 0.0) {
            return Err(format!("the effort limit must be > 0 (None for no limit), got {}", self.limit));
        }
        self.set_point.validate()?;
        self.feed_forward.validate()
    }

    /// The effort at time `time` for the coordinate `x` and its rate.
    pub fn effort(&self, item: &str, time: f64, x: f64, rate: f64) -> Result<Effort> {
        let callback = |message: String| FlexmbdError::Callback { item: item.to_string(), time, message };
        let [f, f_rate, _] = self.set_point.evaluate(time).map_err(callback)?;
        let [u_ff, _, _] = self.feed_forward.evaluate(time).map_err(callback)?;
        let demand = self.proportional_gain * (f - x) + self.derivative_gain * (f_rate - rate) + u_ff;
        if !demand.is_finite() {
            return Err(FlexmbdError::NonFinite { item: item.to_string(), time });
        }
        let effort = demand.clamp(-self.limit, self.limit);
        let saturation = if effort != demand { effort.signum() } else { 0.0 };
        Ok(Effort { demand, effort, saturation })
    }
}

/// The coordinate and its rate at a state (`reference`: the unwrapped angle kept in the
/// state, for angles); `local` gets the gradient and, if `tangent`, the Hessian.
fn coordinate(
    pair: &MarkerPair,
    which: ActuatedCoordinate,
    reference: f64,
    local: &mut ForceLocal,
    tangent: bool,
) -> (f64, f64) {
    match which {
        ActuatedCoordinate::Angle => angle_derivatives(pair, reference, local, tangent),
        ActuatedCoordinate::Slide => {
            let [_, _, grad, qd_local, _] = &mut local.scratch;
            grad.iter_mut().for_each(|x| *x = 0.0);
            primitive_gradient(&SLIDE, pair, 1.0, grad);
            local_velocities(pair, qd_local);
            let rate = grad.iter().zip(qd_local.iter()).map(|(g, v)| g * v).sum();
            if tangent {
                local.damping.fill_zero();
                primitive_hessian(&SLIDE, pair, 1.0, &mut local.damping);
            }
            (primitive_value(&SLIDE, pair), rate)
        }
    }
}

/// The effort of an actuator at a state (for the saturation events and the outputs).
pub fn effort_at(
    item: &str,
    pair: &MarkerPair,
    which: ActuatedCoordinate,
    law: &ServoLaw,
    reference: f64,
    time: f64,
    local: &mut ForceLocal,
) -> Result<Effort> {
    let (x, rate) = coordinate(pair, which, reference, local, false);
    law.effort(item, time, x, rate)
}

/// Evaluates Q (and, if `tangent`, -dQ/dq and -dQ/dq_dot) of an actuator into `local`.
#[allow(clippy::too_many_arguments)]
pub fn evaluate(
    item: &str,
    pair: &MarkerPair,
    which: ActuatedCoordinate,
    law: &ServoLaw,
    reference: f64,
    time: f64,
    local: &mut ForceLocal,
    tangent: bool,
) -> Result<()> {
    let (x, rate) = coordinate(pair, which, reference, local, tangent);
    let effort = law.effort(item, time, x, rate)?;
    let free = if effort.saturation == 0.0 { 1.0 } else { 0.0 };
    // The moment that resists x is -u; it grows with x by k_p and with x_dot by k_d.
    apply_moment(local, -effort.effort, free * law.proportional_gain, free * law.derivative_gain, tangent);
    Ok(())
}
