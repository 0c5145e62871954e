//! The Runge-Kutta methods on the integrated vector y of a strategy: the classical method of
//! order 4 (fixed step), the embedded Dormand-Prince 5(4) pair with its error estimate
//! (error-controlled step, first same as last), over stage buffers kept between steps (which
//! the implicit TR-BDF2 of `trbdf2` uses too).

use crate::error::{FlexmbdError, Result};
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

/// The buffers of the steps, all of the length of the integrated vector.
pub(super) struct Stages {
    /// y at the accepted state (start of the step).
    pub(super) y: Vec<f64>,
    /// y at the end of the step attempt.
    pub(super) y_new: Vec<f64>,
    /// The argument of the stage being evaluated.
    pub(super) stage: Vec<f64>,
    /// dy/dt of the stages; `k[0]` at (t, y), and for Dormand-Prince `k[6]` at (t + h, y_new).
    pub(super) k: [Vec<f64>; 7],
}

impl Stages {
    /// Buffers for the integrated vector `y`.
    pub(super) fn new(y: Vec<f64>) -> Self {
        let n = y.len();
        Stages { y_new: vec![0.0; n], stage: vec![0.0; n], k: std::array::from_fn(|_| vec![0.0; n]), y }
    }

    /// Sizes the buffers for `y` after it changed length (a new partition or strategy).
    pub(super) fn resize_to_y(&mut self) {
        let n = self.y.len();
        self.y_new.resize(n, 0.0);
        self.stage.resize(n, 0.0);
        self.k.iter_mut().for_each(|v| v.resize(n, 0.0));
    }

    /// First same as last: dy/dt at the end of the accepted Dormand-Prince step is the one at
    /// the start of the next.
    pub(super) fn reuse_last_derivative(&mut self) {
        let (head, tail) = self.k.split_at_mut(6);
        head[0].copy_from_slice(&tail[0]);
    }
}

/// One step attempt of `method` from (t, y) with step h, with `derivative(t, y, dy)` the
/// right-hand side. `stages.k[0]` must hold dy/dt at (t, y). Writes y(t + h) into
/// `stages.y_new`, leaves dy/dt at (t + h, y_new) in `k[6]` for Dormand-Prince (first same as
/// last), and returns the error norm with the `(relative, absolute)` tolerances (0 for RK4).
pub(super) fn step(
    method: ExplicitMethod,
    t: f64,
    h: f64,
    stages: &mut Stages,
    tolerances: (f64, f64),
    derivative: impl FnMut(f64, &[f64], &mut [f64]) -> Result<()>,
) -> Result<f64> {
    match method {
        // The implicit method steps in `trbdf2` (the caller dispatches it there).
        ExplicitMethod::TrBdf2 => Err(FlexmbdError::InvalidParameter {
            item: "explicit solver".to_string(),
            message: "tr-bdf2 is not an explicit Runge-Kutta method".to_string(),
        }),
        ExplicitMethod::Rk4 => {
            rk4_step(t, h, stages, derivative)?;
            Ok(0.0)
        }
        ExplicitMethod::Dopri5 => {
            dopri5_step(t, h, stages, derivative)?;
            let (rtol, atol) = tolerances;
            Ok(dopri5_error(h, stages, rtol, atol))
        }
    }
}

/// The classical Runge-Kutta step of order 4.
fn rk4_step(
    t: f64,
    h: f64,
    stages: &mut Stages,
    mut derivative: impl FnMut(f64, &[f64], &mut [f64]) -> Result<()>,
) -> Result<()> {
    let Stages { y, y_new, stage, k } = stages;
    let n = y.len();
    let half = 0.5 * h;
    for (s, c) in [(1usize, half), (2, half), (3, h)] {
        for i in 0..n {
            stage[i] = y[i] + c * k[s - 1][i];
        }
        let (_, tail) = k.split_at_mut(s);
        derivative(t + c, stage, &mut tail[0])?;
    }
    for i in 0..n {
        y_new[i] = y[i] + h / 6.0 * (k[0][i] + 2.0 * k[1][i] + 2.0 * k[2][i] + k[3][i]);
    }
    Ok(())
}

/// The stages of the Dormand-Prince step; the fifth-order solution is the argument of its
/// last stage.
fn dopri5_step(
    t: f64,
    h: f64,
    stages: &mut Stages,
    mut derivative: impl FnMut(f64, &[f64], &mut [f64]) -> Result<()>,
) -> Result<()> {
    let Stages { y, y_new, stage, k } = stages;
    let n = y.len();
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
        derivative(t + DP_C[s] * h, stage, &mut tail[0])?;
    }
    Ok(())
}

/// Weighted RMS norm of the difference of the fifth- and fourth-order solutions of a
/// Dormand-Prince step (converged at <= 1).
fn dopri5_error(h: f64, stages: &Stages, rtol: f64, atol: f64) -> f64 {
    let Stages { y, y_new, k, .. } = stages;
    let n = y.len();
    let sum: f64 = (0..n)
        .map(|i| {
            let e: f64 = h * (0..7).map(|s| DP_E[s] * k[s][i]).sum::<f64>();
            let scale = atol + rtol * y[i].abs().max(y_new[i].abs());
            (e / scale).powi(2)
        })
        .sum();
    if n == 0 {
        0.0
    } else {
        (sum / n as f64).sqrt()
    }
}
