//! User force callbacks Q(t, q, q_dot) on the coordinates of a list of bodies. Their Jacobians
//! are taken by forward finite differences (the only place where finite differences replace
//! analytic derivatives; the step is 1e-7 (1 + |x|)).

use super::{ForceElement, ForceEnv, ForceLocal};
use crate::error::{FlexmbdError, Result};

/// A user force: writes the generalized force on the listed bodies' coordinates into `out`.
pub trait ForceCallback: Send + Sync {
    /// `q`, `qd` and `out` are the concatenated coordinates of the element's bodies.
    fn evaluate(&self, time: f64, q: &[f64], qd: &[f64], out: &mut [f64]) -> std::result::Result<(), String>;
}

fn call(item: &str, cb: &dyn ForceCallback, time: f64, q: &[f64], qd: &[f64], out: &mut [f64]) -> Result<()> {
    cb.evaluate(time, q, qd, out).map_err(|message| FlexmbdError::Callback {
        item: item.to_string(),
        time,
        message,
    })?;
    if out.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(FlexmbdError::NonFinite { item: format!("{item} (callback result)"), time })
    }
}

/// Evaluates the callback and, if `tangent`, its finite-difference Jacobians.
pub fn evaluate(
    item: &str,
    cb: &dyn ForceCallback,
    force: &ForceElement,
    env: &ForceEnv,
    local: &mut ForceLocal,
    tangent: bool,
) -> Result<()> {
    let n = force.dofs.len();
    let [q, qd, perturbed, _, _] = &mut local.scratch;
    env.gather(&force.dofs, q, qd);
    call(item, cb, env.time, q, qd, &mut local.generalized)?;
    if tangent {
        for col in 0..n {
            for (which, jac) in [(0, &mut local.stiffness), (1, &mut local.damping)] {
                let x = if which == 0 { &mut q[col] } else { &mut qd[col] };
                let saved = *x;
                let h = 1e-7 * (1.0 + saved.abs());
                *x = saved + h;
                let result = call(item, cb, env.time, q, qd, perturbed);
                if which == 0 {
                    q[col] = saved;
                } else {
                    qd[col] = saved;
                }
                result?;
                for row in 0..n {
                    jac.add(row, col, -(perturbed[row] - local.generalized[row]) / h);
                }
            }
        }
    }
    Ok(())
}
