//! Strategy (2), Wehage and Haug's generalized coordinate partitioning: the partition at the
//! start, the dependent coordinates and velocities from the independent ones at every
//! evaluation (with the check that they stay on their solution branch), and the partition
//! chosen anew when its dependent block becomes ill-conditioned, when a step fails, or when a
//! singular configuration is passed by projection steps.

use faer::linalg::solvers::Solve;
use faer::Mat;

use super::engine::{converged, Engine};
use crate::error::{FlexmbdError, Result};
use crate::formulation::augmented::{checked_lu, worst, DenseEquations, Level, SINGULAR_VALUE_CUTOFF};
use crate::integrator::settings::{ExplicitSettings, Strategy};
use crate::linalg::partition::{
    minimum_norm_solve, partition, partition_condition, partition_with_independent, submatrix, Partition,
};
use crate::output::Event;
use crate::system::{Model, State, Workspace};

/// The partition at the consistent initial `state`: of the given independent coordinates, or
/// the one the decomposition chooses.
pub(super) fn first_partition(
    model: &Model,
    explicit: &ExplicitSettings,
    ws: &mut Workspace,
    eq: &mut DenseEquations,
    state: &State,
) -> Result<Partition> {
    let n = model.coordinate_count;
    let t0 = state.time;
    eq.evaluate(model, ws, t0, &state.coordinates, &state.velocities, &state.discrete, Level::Position)?;
    Ok(match &explicit.independent {
        Some(list) => partition_with_independent(eq.jacobian.as_ref(), list, explicit.rank_tolerance)
            .map_err(|m| {
                let names: Vec<String> =
                    list.iter().filter(|&&c| c < n).map(|&c| model.coordinate_name(c)).collect();
                FlexmbdError::InvalidParameter {
                    item: format!("independent coordinates [{}]", names.join(", ")),
                    message: m,
                }
            })?,
        None => partition(eq.jacobian.as_ref(), explicit.partition, explicit.rank_tolerance),
    })
}

/// The event that reports the rows of the partition without multipliers, if any.
pub(super) fn redundant_rows_event(model: &Model, partition: &Partition, time: f64) -> Option<Event> {
    if partition.redundant_rows.is_empty() {
        return None;
    }
    let names: Vec<String> = partition.redundant_rows.iter().map(|&r| model.constraint_name(r)).collect();
    Some(Event {
        time,
        kind: "redundant constraints".to_string(),
        message: format!("rows without multipliers (dependent on the others): {}", names.join("; ")),
    })
}

impl Engine<'_> {
    /// Wehage: the full q and q_dot from the independent ones `y` = [q_i; qd_i] at `time`.
    pub(super) fn reconstruct(&mut self, time: f64, y: &[f64]) -> Result<()> {
        let p = &self.partition;
        let ni = p.independent.len();
        let dt = time - self.accepted_time;
        for (k, &c) in p.independent.iter().enumerate() {
            self.q[c] = y[k];
            self.qd[c] = y[ni + k];
        }
        // Second-order predictor: the Newton correction is then O(dt^3), and a correction of
        // the size of the step's motion means the iteration went to another root of C = 0
        // (another assembly branch) where a dependent coordinate passes a turning point.
        let mut motion = 0.0f64;
        for &d in &p.dependent {
            let step = dt * self.accepted_qd[d] + 0.5 * dt * dt * self.accepted_qdd[d];
            self.q[d] = self.accepted_q[d] + step;
            motion = motion.max(step.abs());
        }
        let predicted: Vec<f64> = p.dependent.iter().map(|&d| self.q[d]).collect();
        let mut iterations = 0;
        let mut previous = f64::INFINITY;
        loop {
            self.evaluate(time, Level::Position)?;
            let residual: Vec<f64> = self.partition.rows.iter().map(|&r| self.eq.constraints[r]).collect();
            let (k, violation) = worst(&residual);
            if converged(violation, previous, self.settings.constraint_tolerance) {
                if !self.check_branch {
                    break;
                }
                let (a, correction) = self
                    .partition
                    .dependent
                    .iter()
                    .zip(&predicted)
                    .map(|(&d, x)| (self.q[d] - x).abs())
                    .enumerate()
                    .fold((0, 0.0f64), |best, (a, v)| if v > best.1 { (a, v) } else { best });
                // (A motion the predictor does not see, such as a driver starting from rest
                // with its jerk, moves the dependent coordinates by O(dt^3): below a millionth
                // of their size it is taken for the same branch.)
                let size = self.partition.dependent.iter().map(|&d| self.q[d].abs()).fold(0.0f64, f64::max);
                let floor = (BRANCH_SIZE_FRACTION * size).max(1e3 * self.settings.constraint_tolerance);
                if correction > BRANCH_JUMP_FRACTION * motion + floor {
                    return Err(FlexmbdError::NewtonDiverged {
                        time,
                        step_size: dt,
                        iterations,
                        residual: correction,
                        item: format!(
                            "{}: the dependent coordinates moved to another solution of C = 0 (correction \
                             {correction:.3e} against a predicted motion of {motion:.3e})",
                            self.model.coordinate_name(self.partition.dependent[a])
                        ),
                    });
                }
                break;
            }
            previous = violation;
            if iterations >= self.settings.max_iterations || !violation.is_finite() {
                return Err(FlexmbdError::NewtonDiverged {
                    time,
                    step_size: dt,
                    iterations,
                    residual: violation,
                    item: format!(
                        "{}; the dependent coordinates (coordinate partitioning) did not converge",
                        self.model.constraint_name(self.partition.rows[k])
                    ),
                });
            }
            let step = dependent_solve(&self.eq, &self.partition, &residual);
            for (a, &d) in self.partition.dependent.iter().enumerate() {
                self.q[d] -= step[a];
            }
            iterations += 1;
            self.newton_iterations += 1;
        }
        // Dependent velocities: C_qd qd_d = -(C_qi qd_i + C_t).
        self.evaluate(time, Level::Velocity)?;
        let p = &self.partition;
        for &d in &p.dependent {
            self.qd[d] = 0.0;
        }
        let rhs: Vec<f64> = p.rows.iter().map(|&r| -self.eq.velocity_violation(r, &self.qd)).collect();
        let x = dependent_solve(&self.eq, p, &rhs);
        for (a, &d) in p.dependent.iter().enumerate() {
            self.qd[d] = x[a];
        }
        if x.iter().any(|v| !v.is_finite()) {
            return Err(self.singular(time, "the dependent velocities are not finite".to_string()));
        }
        Ok(())
    }

    /// Replaces the partition by the one the decomposition proposes at the current state if
    /// that is `repartition_ratio` times better conditioned (`force`: if it is better at all).
    /// Returns the event.
    fn repartition(&mut self, time: f64, force: bool) -> Result<Option<Event>> {
        if !self.settings.uses_coordinates() || self.settings.independent.is_some() {
            return Ok(None);
        }
        self.evaluate(time, Level::Position)?;
        let p = &self.partition;
        let condition = partition_condition(self.eq.jacobian.as_ref(), &p.rows, &p.dependent);
        // Where a dependent coordinate approaches a turning point its pivot falls roughly
        // linearly and the condition grows like 1 / (t_turn - t), by a large factor within one
        // fixed step: the condition expected after the next step (the growth of the last one
        // repeated) is compared, so that the partition changes one step early.
        let growth =
            if self.last_condition.is_finite() { (condition / self.last_condition).max(1.0) } else { 1.0 };
        self.last_condition = condition;
        let expected = condition * growth;
        let fresh =
            partition(self.eq.jacobian.as_ref(), self.settings.partition, self.settings.rank_tolerance);
        let ratio = if force { 1.0 } else { self.settings.repartition_ratio };
        if !(fresh.condition * ratio < expected) || fresh.rank != p.rank || fresh.independent == p.independent
        {
            return Ok(None);
        }
        let reason = if force { "a step failed" } else { "the dependent block became ill-conditioned" };
        let event = Event {
            time,
            kind: "repartition".to_string(),
            message: format!(
                "{reason}: new independent coordinates [{}] (condition {:.3e}, was {condition:.3e}), were [{}]",
                self.names(&fresh.independent),
                fresh.condition,
                self.names(&p.independent)
            ),
        };
        self.last_condition = fresh.condition;
        self.partition = fresh;
        Ok(Some(event))
    }

    /// After an accepted step: a better partition if one is proposed, and for coordinate
    /// partitioning the passage through singular configurations. Where even the best
    /// partition has a condition above `singular_limit` (the constraint Jacobian is near
    /// rank-deficient, as at the change points of a parallelogram linkage, so that no choice
    /// of independent coordinates determines the dependent ones well), the steps are taken
    /// with strategy (3), integrate-all-then-project, until a partition below half of that
    /// limit exists again. Returns the events.
    pub(super) fn update_partition(&mut self, time: f64) -> Result<Vec<Event>> {
        let mut events = Vec::new();
        let wehage = self.settings.strategy == Strategy::CoordinatePartitioning;
        let limit = self.singular_limit;
        if wehage && self.mode == Strategy::Projection {
            self.evaluate(time, Level::Position)?;
            let jacobian = self.eq.jacobian.as_ref();
            let fresh = match &self.settings.independent {
                Some(list) => partition_with_independent(jacobian, list, self.settings.rank_tolerance).ok(),
                None => Some(partition(jacobian, self.settings.partition, self.settings.rank_tolerance)),
            };
            if let Some(fresh) = fresh.filter(|f| f.condition < 0.5 * limit && f.rank == self.partition.rank)
            {
                events.push(Event {
                    time,
                    kind: "singular configuration".to_string(),
                    message: format!(
                        "passed: coordinate partitioning resumes with independent coordinates [{}] (condition {:.3e})",
                        self.names(&fresh.independent),
                        fresh.condition
                    ),
                });
                self.last_condition = fresh.condition;
                self.partition = fresh;
                self.mode = Strategy::CoordinatePartitioning;
            }
            return Ok(events);
        }
        events.extend(self.repartition(time, false)?);
        if wehage {
            self.evaluate(time, Level::Position)?;
            let p = &self.partition;
            let condition = partition_condition(self.eq.jacobian.as_ref(), &p.rows, &p.dependent);
            if condition > limit {
                events.push(Event {
                    time,
                    kind: "singular configuration".to_string(),
                    message: format!(
                        "partition condition {condition:.3e} above {limit:.3e} with {}: steps by integration \
                         of all coordinates with projection until a partition below half the limit exists",
                        if self.settings.independent.is_some() {
                            "the given independent coordinates"
                        } else {
                            "the best partition (the constraint Jacobian is near rank-deficient)"
                        }
                    ),
                });
                self.mode = Strategy::Projection;
            }
        }
        Ok(events)
    }

    /// After a failed step attempt: back to the accepted state, and a new partition there if
    /// a better one exists.
    pub(super) fn repartition_after_failure(&mut self) -> Result<Option<Event>> {
        self.q.copy_from_slice(&self.accepted_q);
        self.qd.copy_from_slice(&self.accepted_qd);
        self.repartition(self.accepted_time, true)
    }
}

/// Largest Newton correction of the dependent coordinates, as a fraction of their predicted
/// motion over the step, that is taken for the same solution branch (see `reconstruct`).
const BRANCH_JUMP_FRACTION: f64 = 0.25;

/// Corrections below this fraction of the dependent coordinates' largest value are taken for
/// the same solution branch whatever the predicted motion (see `reconstruct`).
const BRANCH_SIZE_FRACTION: f64 = 1e-6;

/// Solves C_qd x = rhs for the partition's dependent block: LU, or the minimum-norm solution
/// with a truncated SVD when the block is ill-conditioned (near a singular configuration the
/// smallest change of the dependent coordinates that satisfies the constraints keeps the
/// motion on its branch).
fn dependent_solve(eq: &DenseEquations, p: &Partition, rhs: &[f64]) -> Vec<f64> {
    let cd = submatrix(eq.jacobian.as_ref(), &p.rows, &p.dependent);
    match checked_lu(&cd, "dependent block C_qd") {
        Ok(lu) => {
            let mut x = Mat::from_fn(rhs.len(), 1, |i, _| rhs[i]);
            lu.solve_in_place(&mut x);
            (0..rhs.len()).map(|i| x[(i, 0)]).collect()
        }
        Err(_) => minimum_norm_solve(cd.as_ref(), rhs, SINGULAR_VALUE_CUTOFF),
    }
}
