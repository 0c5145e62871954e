//! Strategy (3): integrate all coordinates, then after each step project q onto C = 0 and
//! q_dot onto the velocity constraints by minimum-norm corrections.

use faer::Mat;

use super::engine::{converged, Engine};
use crate::error::{FlexmbdError, Result};
use crate::formulation::augmented::{worst, Level, SINGULAR_VALUE_CUTOFF};
use crate::linalg::partition::minimum_norm_solve;

impl Engine<'_> {
    /// Projects self.q onto C = 0 (Newton with minimum-norm steps over the partition's rows)
    /// and self.qd onto C_q q_dot + C_t = 0.
    pub(super) fn project(&mut self, time: f64) -> Result<()> {
        let rows = self.partition.rows.clone();
        let n = self.q.len();
        let mut iterations = 0;
        let mut previous = f64::INFINITY;
        let mut level = Level::Position;
        loop {
            self.evaluate(time, level)?;
            let residual: Vec<f64> = if level == Level::Position {
                rows.iter().map(|&r| self.eq.constraints[r]).collect()
            } else {
                rows.iter().map(|&r| self.eq.velocity_violation(r, &self.qd)).collect()
            };
            let (k, violation) = worst(&residual);
            if level == Level::Position && converged(violation, previous, self.settings.constraint_tolerance)
            {
                level = Level::Velocity;
                continue;
            }
            previous = violation;
            if level == Level::Position
                && (iterations >= self.settings.max_iterations || !violation.is_finite())
            {
                return Err(FlexmbdError::NewtonDiverged {
                    time,
                    step_size: 0.0,
                    iterations,
                    residual: violation,
                    item: format!("{}; projection onto the constraints", self.model.constraint_name(rows[k])),
                });
            }
            // Minimum-norm correction dx = C_r^+ residual (truncated near singular
            // configurations).
            let c = Mat::from_fn(rows.len(), n, |a, j| self.eq.jacobian[(rows[a], j)]);
            let dx = minimum_norm_solve(c.as_ref(), &residual, SINGULAR_VALUE_CUTOFF);
            if dx.iter().any(|v| !v.is_finite()) {
                return Err(self.singular(time, "the projection correction is not finite".to_string()));
            }
            if level == Level::Position {
                for j in 0..n {
                    self.q[j] -= dx[j];
                }
                iterations += 1;
                self.newton_iterations += 1;
            } else {
                for j in 0..n {
                    self.qd[j] -= dx[j];
                }
                return Ok(());
            }
        }
    }
}
