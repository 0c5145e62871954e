//! The explicit Runge-Kutta methods on the integrated vector y of a strategy: the classical
//! method of order 4 (fixed step) and the embedded Dormand-Prince 5(4) pair with its error
//! estimate (error-controlled step, first same as last).

use super::engine::Engine;
use crate::error::Result;
use crate::integrator::settings::ExplicitMethod;

/// Dormand-Prince 5(4) coefficients (Dormand and Prince 1980; Hairer, Norsett and Wanner,
/// Solving ODEs I, table 5.2).
const DP_C: [f64; 7] = [0.0, 1.0 / 5.0, 3.0 / 10.0, 4.0 / 5.0, 8.0 / 9.0, 1.0, 1.0];
const DP_A: [[f64; 6]; 7] = [
    [0.0; 6],
    [1.0 / 5.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [3.0 / 40.0, 9.0 / 40.0, 0.0, 0.0, 0.0, 0.0],
    [44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0, 0.0, 0.0, 0.0],
    [19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0, 0.0, 0.0],
    [9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0, 49.0 / 176.0, -5103.0 / 18656.0, 0.0],
    [35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0],
];
/// Fifth-order weights minus fourth-order weights (the error estimate).
const DP_E: [f64; 7] =
    [71.0 / 57600.0, 0.0, -71.0 / 16695.0, 71.0 / 1920.0, -17253.0 / 339200.0, 22.0 / 525.0, -1.0 / 40.0];

/// One step attempt of `method` from (t, y) with step h. `k[0]` must hold dy/dt at (t, y).
/// Writes y(t + h) into `y_new`, leaves dy/dt at (t + h, y_new) in `k[6]` for Dormand-Prince
/// (first same as last), and returns the error norm (0 for RK4).
#[allow(clippy::too_many_arguments)]
pub(super) fn attempt(
    engine: &mut Engine,
    method: ExplicitMethod,
    t: f64,
    h: f64,
    y: &[f64],
    k: &mut [Vec<f64>; 7],
    y_new: &mut [f64],
    stage: &mut [f64],
) -> Result<f64> {
    let n = y.len();
    match method {
        ExplicitMethod::Rk4 => {
            let half = 0.5 * h;
            for (s, c) in [(1usize, half), (2, half), (3, h)] {
                for i in 0..n {
                    stage[i] = y[i] + c * k[s - 1][i];
                }
                let (head, tail) = k.split_at_mut(s);
                let _ = head;
                engine.derivative(t + c, stage, &mut tail[0])?;
            }
            for i in 0..n {
                y_new[i] = y[i] + h / 6.0 * (k[0][i] + 2.0 * k[1][i] + 2.0 * k[2][i] + k[3][i]);
            }
            Ok(0.0)
        }
        ExplicitMethod::Dopri5 => {
            for s in 1..7 {
                for i in 0..n {
                    let mut v = y[i];
                    for j in 0..s {
                        v += h * DP_A[s][j] * k[j][i];
                    }
                    stage[i] = v;
                }
                if s == 6 {
                    y_new.copy_from_slice(stage);
                }
                let (_, tail) = k.split_at_mut(s);
                engine.derivative(t + DP_C[s] * h, stage, &mut tail[0])?;
            }
            let (rtol, atol) = (engine.settings.relative_tolerance, engine.settings.absolute_tolerance);
            let sum: f64 = (0..n)
                .map(|i| {
                    let e: f64 = h * (0..7).map(|s| DP_E[s] * k[s][i]).sum::<f64>();
                    let scale = atol + rtol * y[i].abs().max(y_new[i].abs());
                    (e / scale).powi(2)
                })
                .sum();
            Ok(if n == 0 { 0.0 } else { (sum / n as f64).sqrt() })
        }
    }
}
