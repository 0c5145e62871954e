//! TR-BDF2, an implicit Runge-Kutta method on the integrated vector y of a strategy (the
//! joint coordinates and their rates, or the independent coordinates, ...): for the stiff
//! deformable bodies on which the explicit methods need steps of the order of the period of
//! their highest elastic mode. A trapezoidal stage to t + gamma h followed by a BDF2 stage to
//! t + h, written as a singly diagonally implicit method with an explicit first stage
//! (Hosea and Shampine 1996; Bank et al. 1985): L-stable, second order, stiffly accurate, with
//! an embedded third-order estimate filtered through the iteration matrix (Shampine's filter,
//! so that stiff components do not shrink the step).
//!
//! ```text
//!   c = (0, g, 1),  g = 2 - sqrt 2,  d = g / 2,  w = sqrt 2 / 4
//!   k1 = f(t, y)
//!   k2 = f(t + g h, y + h (d k1 + d k2))
//!   k3 = f(t + h,   y + h (w k1 + w k2 + d k3)),   y_new = y + h (w k1 + w k2 + d k3)
//!   error = (I - h d J)^-1 h ((4 w - 1) k1 / 3 - k2 / 3 + 2 d k3 / 3)
//! ```
//!
//! The implicit stages are solved by simplified Newton iterations with the matrix
//! I - h d J, J = df/dy by forward differences at the start of a step (one evaluation of f
//! per component of y), kept over the steps while the iterations converge quickly and
//! factorized again when h changes.

use faer::linalg::solvers::{PartialPivLu, Solve};
use faer::Mat;

use super::runge_kutta::Stages;
use crate::error::Result;

const SQRT2: f64 = std::f64::consts::SQRT_2;
/// Stage abscissa gamma.
const GAMMA: f64 = 2.0 - SQRT2;
/// Diagonal coefficient d = gamma / 2.
const D: f64 = GAMMA / 2.0;
/// Weight w of the first two stages in the last.
const W: f64 = SQRT2 / 4.0;
/// Newton iterations per stage before the stage counts as failed.
const MAX_ITERATIONS: usize = 8;
/// Iterations of a stage above which the Jacobian is formed again for the next step.
const SLOW: usize = 4;
/// A stage has converged when its Newton increment, in the error norm, is below this.
const NEWTON_TOLERANCE: f64 = 1e-2;

/// The iteration matrix kept between the steps.
#[derive(Default)]
pub(super) struct Newton {
    /// df/dy at the start of the step it was formed in (None: form it at the next step).
    jacobian: Option<Mat<f64>>,
    /// The factorized I - h d J and its h.
    lu: Option<(f64, PartialPivLu<f64>)>,
    /// Newton iterations and evaluations of f for Jacobians, over the run.
    pub(super) iterations: usize,
    pub(super) jacobians: usize,
}

impl Newton {
    /// Forgets the Jacobian (the integrated vector changed meaning or length).
    pub(super) fn invalidate(&mut self) {
        self.jacobian = None;
        self.lu = None;
    }
}

/// What a step attempt found.
pub(super) enum Outcome {
    /// The stages converged: the weighted error norm (<= 1 passes).
    Error(f64),
    /// Newton's iterations did not converge, with a Jacobian of this step.
    NotConverged,
}

/// One TR-BDF2 step from (t, y) with step h (see the module). `stages.k[0]` must hold dy/dt at
/// (t, y); the end point goes to `stages.y_new` and dy/dt there to `k[6]` (first same as
/// last). `tolerances` (relative, absolute) weigh the error and the Newton increments.
pub(super) fn step(
    t: f64,
    h: f64,
    stages: &mut Stages,
    tolerances: (f64, f64),
    newton: &mut Newton,
    mut derivative: impl FnMut(f64, &[f64], &mut [f64]) -> Result<()>,
) -> Result<Outcome> {
    let n = stages.y.len();
    if newton.jacobian.as_ref().is_some_and(|j| j.nrows() != n) {
        newton.invalidate();
    }
    let mut fresh = false;
    loop {
        if newton.jacobian.is_none() {
            newton.jacobian = Some(jacobian(t, stages, &mut derivative)?);
            newton.jacobians += 1;
            newton.lu = None;
            fresh = true;
        }
        match attempt(t, h, stages, tolerances, newton, &mut derivative)? {
            Some(err) => return Ok(Outcome::Error(err)),
            None if fresh => {
                newton.invalidate();
                return Ok(Outcome::NotConverged);
            }
            // A Jacobian of an earlier step: form it again here and retry once.
            None => newton.invalidate(),
        }
    }
}

/// df/dy at (t, y) by forward differences (k[0] holds f(t, y)).
fn jacobian(
    t: f64,
    stages: &mut Stages,
    derivative: &mut impl FnMut(f64, &[f64], &mut [f64]) -> Result<()>,
) -> Result<Mat<f64>> {
    let n = stages.y.len();
    let mut j = Mat::zeros(n, n);
    let Stages { y, stage, k, .. } = stages;
    let (head, tail) = k.split_at_mut(1);
    let column = &mut tail[0];
    stage.copy_from_slice(y);
    for c in 0..n {
        let delta = f64::EPSILON.sqrt() * y[c].abs().max(1e-3);
        stage[c] = y[c] + delta;
        derivative(t, stage, column)?;
        stage[c] = y[c];
        for r in 0..n {
            j[(r, c)] = (column[r] - head[0][r]) / delta;
        }
    }
    Ok(j)
}

/// The stages with the kept Jacobian: Some(error norm), or None if Newton failed.
fn attempt(
    t: f64,
    h: f64,
    stages: &mut Stages,
    tolerances: (f64, f64),
    newton: &mut Newton,
    derivative: &mut impl FnMut(f64, &[f64], &mut [f64]) -> Result<()>,
) -> Result<Option<f64>> {
    let n = stages.y.len();
    if !newton.lu.as_ref().is_some_and(|(lu_h, _)| *lu_h == h) {
        let j = newton.jacobian.as_ref().expect("a Jacobian");
        let m = Mat::from_fn(n, n, |r, c| if r == c { 1.0 } else { 0.0 } - h * D * j[(r, c)]);
        newton.lu = Some((h, m.partial_piv_lu()));
    }
    let (rtol, atol) = tolerances;
    let scale: Vec<f64> = stages.y.iter().map(|v| atol + rtol * v.abs()).collect();
    let mut slowest = 0;
    // Stage 2 at t + gamma h, then stage 3 at t + h; their explicit parts from k1 (and k2).
    for (s, c) in [(1usize, GAMMA), (2, 1.0)] {
        let Stages { y, stage, k, .. } = stages;
        let base: Vec<f64> = (0..n)
            .map(|i| if s == 1 { y[i] + h * D * k[0][i] } else { y[i] + h * W * (k[0][i] + k[1][i]) })
            .collect();
        // Start from the previous stage's slope.
        let (done, rest) = k.split_at_mut(s);
        rest[0].copy_from_slice(&done[s - 1]);
        let ks = &mut rest[0];
        let mut f = vec![0.0; n];
        let mut converged = false;
        let mut previous = f64::INFINITY;
        for iteration in 1..=MAX_ITERATIONS {
            for i in 0..n {
                stage[i] = base[i] + h * D * ks[i];
            }
            derivative(t + c * h, stage, &mut f)?;
            newton.iterations += 1;
            let residual = Mat::from_fn(n, 1, |i, _| f[i] - ks[i]);
            let (_, lu) = newton.lu.as_ref().expect("factorized");
            let delta = lu.solve(&residual);
            let mut norm = 0.0;
            for i in 0..n {
                ks[i] += delta[(i, 0)];
                norm += (h * D * delta[(i, 0)] / scale[i]).powi(2);
            }
            let norm = (norm / n.max(1) as f64).sqrt();
            if !norm.is_finite() || (iteration > 2 && norm > previous) {
                return Ok(None);
            }
            if norm <= NEWTON_TOLERANCE {
                slowest = slowest.max(iteration);
                converged = true;
                break;
            }
            previous = norm;
        }
        if !converged {
            return Ok(None);
        }
    }
    let Stages { y, y_new, stage, k, .. } = stages;
    for i in 0..n {
        y_new[i] = y[i] + h * (W * (k[0][i] + k[1][i]) + D * k[2][i]);
    }
    // dy/dt at the end (first same as last): the converged third stage's slope.
    derivative(t + h, y_new, stage)?;
    k[6].copy_from_slice(stage);
    let raw = Mat::from_fn(n, 1, |i, _| {
        h * ((4.0 * W - 1.0) / 3.0 * k[0][i] - k[1][i] / 3.0 + 2.0 * D / 3.0 * k[2][i])
    });
    let (_, lu) = newton.lu.as_ref().expect("factorized");
    let filtered = lu.solve(&raw);
    let sum: f64 = (0..n)
        .map(|i| {
            let s = atol + rtol * y[i].abs().max(y_new[i].abs());
            (filtered[(i, 0)] / s).powi(2)
        })
        .sum();
    if slowest > SLOW {
        newton.jacobian = None;
    }
    Ok(Some(if n == 0 { 0.0 } else { (sum / n as f64).sqrt() }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::assert_close;

    /// Prothero and Robinson's stiff problem y' = -1e6 (y - cos t) - sin t, y(0) = 1, whose
    /// solution is cos t: explicit methods need h < 2e-6; TR-BDF2 follows cos t at h = 0.01.
    #[test]
    fn follows_a_stiff_problem_at_second_order() {
        let f = |t: f64, y: &[f64], dy: &mut [f64]| {
            dy[0] = -1e6 * (y[0] - t.cos()) - t.sin();
            Ok(())
        };
        let mut errors = Vec::new();
        for h in [0.02, 0.01] {
            let mut stages = Stages::new(vec![1.0]);
            let mut newton = Newton::default();
            let mut t = 0.0;
            let mut k0 = [0.0];
            f(t, &stages.y, &mut k0).unwrap();
            stages.k[0][0] = k0[0];
            while t < 1.0 - 1e-12 {
                match step(t, h, &mut stages, (1e-3, 1e-6), &mut newton, f).unwrap() {
                    Outcome::Error(err) => assert!(err.is_finite()),
                    Outcome::NotConverged => panic!("Newton failed at t = {t}"),
                }
                std::mem::swap(&mut stages.y, &mut stages.y_new);
                stages.reuse_last_derivative();
                t += h;
            }
            // A linear problem: one Jacobian for the whole run.
            assert_eq!(newton.jacobians, 1);
            errors.push((stages.y[0] - 1.0f64.cos()).abs());
        }
        assert!(errors[0] < 1e-6, "{errors:?}");
        // The stiff part is damped at once (L-stable); the smooth part converges.
        assert_close(errors[1], 0.0, 0.0, 1e-6, "error at h = 0.01");
    }
}
