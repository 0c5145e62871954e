//! Explicit integration of the constrained equations of motion: the three strategies of seed
//! section 4 ("Numerical solution of the augmented equations"), each with the accelerations
//! from the augmented system (seed eq. 26) or from the embedding technique (seed eqs. 27-30),
//! and a classical Runge-Kutta method of order 4 (fixed step) or the embedded Dormand-Prince
//! 5(4) pair (error-controlled step):
//!
//! 1. `IntegrateAll`: integrate q and q_dot, dependent and independent. The constraints hold
//!    only at the acceleration level, so C and C_q q_dot + C_t drift; Baumgarte's
//!    stabilization replaces gamma by gamma - 2 alpha (C_q q_dot + C_t) - beta^2 C. The drift
//!    is recorded (constraint violation of every output) and reported as an event when it
//!    passes a threshold.
//! 2. `CoordinatePartitioning` (Wehage and Haug): integrate the independent coordinates and
//!    velocities only; at every evaluation the dependent coordinates solve C(q, t) = 0 by
//!    Newton-Raphson and the dependent velocities C_qd qd_d = -(C_qi qd_i + C_t). The partition
//!    is chosen at the start and again (an event) when the dependent block becomes
//!    ill-conditioned.
//! 3. `Projection`: integrate all, then after each step project q onto C = 0 and q_dot onto the
//!    velocity constraints (minimum-norm corrections).
//!
//! The linear algebra is dense (`formulation::augmented`): explicit solvers are meant for rigid
//! and small deformable models, up to `EXPLICIT_COORDINATE_LIMIT` coordinates.

use faer::linalg::solvers::Solve;
use faer::Mat;

use crate::error::{FlexmbdError, Result};
use crate::formulation::augmented::{checked_lu, worst, DenseEquations, Level, SINGULAR_VALUE_CUTOFF};
use crate::formulation::decoupled::{TreeAccelerations, TreeFormulation, TreeSolver};
use crate::formulation::recursive::{tree_joint_accelerations, StructuredState, Tree};
use crate::integrator::clock::OutputClock;
use crate::integrator::discrete::update_discrete;
use crate::integrator::initial::{dense_initial_conditions, report_initial_correction, starting_state};
use crate::integrator::progress::{Progress, Records};
use crate::integrator::settings::{ExplicitMethod, ExplicitSettings, SimulationSettings, Strategy};
use crate::linalg::partition::{
    minimum_norm_solve, partition, partition_condition, partition_with_independent, submatrix, Partition,
};
use crate::output::{Event, Output};
use crate::system::{Model, State, Workspace};

/// Joint coordinates: the middle Cardan angle (rad) beyond which a spherical or free joint's
/// angles are rebased (their singularity is at 90 degrees).
const CARDAN_REBASE_ANGLE: f64 = 1.0;

/// Evaluation of the right-hand sides, with its buffers and counters.
struct Engine<'a> {
    model: &'a Model,
    settings: &'a ExplicitSettings,
    ws: Workspace,
    eq: DenseEquations,
    partition: Partition,
    /// Full coordinates, velocities and accelerations of the last evaluation.
    q: Vec<f64>,
    qd: Vec<f64>,
    qdd: Vec<f64>,
    /// The accepted full state (start of the step): guesses for the dependent coordinates.
    accepted_q: Vec<f64>,
    accepted_qd: Vec<f64>,
    /// Accelerations at the accepted state (for the dependent coordinates' predictor).
    accepted_qdd: Vec<f64>,
    /// Time and accelerations of the last evaluation (first same as last: they become the
    /// accepted ones when that evaluation was at the accepted state).
    last_time: f64,
    /// Whether `reconstruct` checks for a jump to another solution branch (only at the end
    /// of a step: the Runge-Kutta stages are not points of the trajectory).
    check_branch: bool,
    accepted_time: f64,
    gamma: Vec<f64>,
    discrete: Vec<f64>,
    evaluations: usize,
    newton_iterations: usize,
    /// Evaluations near a singular configuration (truncated-SVD accelerations).
    singular_evaluations: usize,
    /// The strategy of the current steps: the chosen one, or projection while coordinate
    /// partitioning passes a singular configuration.
    mode: Strategy,
    /// Partition condition above which a configuration counts as singular.
    singular_limit: f64,
    /// Condition of the partition after the previous accepted step (its growth rate predicts
    /// the next step's, see `repartition`).
    last_condition: f64,
    /// Joint coordinates: the tree, the joint coordinates, rates and accelerations, and the
    /// velocity-quadratic accelerations gamma_B of the body coordinates.
    tree: Option<Tree>,
    p: Vec<f64>,
    pd: Vec<f64>,
    pdd: Vec<f64>,
    gamma_b: Vec<f64>,
    /// Joint coordinates by seed eq. 40 or 41: the solver, the tree state with the influence
    /// coefficients in factored form, and the last reactions -F_r and cut multipliers.
    tree_solver: Option<TreeSolver>,
    structured: Option<StructuredState>,
    tree_reactions: TreeAccelerations,
    /// Velocity influence coefficients of the free joint coordinates at p.
    influence: Mat<f64>,
}

impl<'a> Engine<'a> {
    fn singular(&self, time: f64, detail: String) -> FlexmbdError {
        FlexmbdError::SingularMatrix {
            time,
            context: format!(
                "{} accelerations ({} strategy, {} partition)",
                self.settings.formulation.name(),
                self.settings.strategy.name(),
                self.partition.method.map_or("given", |m| m.name())
            ),
            detail,
        }
    }

    /// Accelerations at (time, self.q, self.qd) into self.qdd.
    fn accelerations(&mut self, time: f64) -> Result<()> {
        if let (Some(solver), Some(st)) = (self.tree_solver.as_mut(), self.structured.as_ref()) {
            self.evaluations += 1;
            let r = solver.accelerations(self.model, &mut self.ws, st, time, &self.discrete).map_err(
                |e| match e {
                    FlexmbdError::SingularMatrix { context, detail, .. } => {
                        FlexmbdError::SingularMatrix { time, context, detail }
                    }
                    other => other,
                },
            )?;
            self.qdd.copy_from_slice(&r.accelerations);
            self.pdd.copy_from_slice(&r.free_accelerations);
            self.tree_reactions = r;
            return Ok(());
        }
        self.evaluate(time, Level::Acceleration)?;
        self.evaluations += 1;
        if let Some(tree) = &self.tree {
            let n = self.q.len();
            let b = &self.influence;
            self.pdd =
                tree_joint_accelerations(&self.eq, b, &self.gamma_b, &tree.cut_rows, SINGULAR_VALUE_CUTOFF)
                    .map_err(|e| self.singular(time, e.to_string()))?;
            for i in 0..n {
                self.qdd[i] =
                    self.gamma_b[i] + (0..self.pdd.len()).map(|k| b[(i, k)] * self.pdd[k]).sum::<f64>();
            }
            return Ok(());
        }
        self.gamma.copy_from_slice(&self.eq.gamma);
        if let Some((alpha, beta)) = self.settings.baumgarte {
            for k in 0..self.gamma.len() {
                let rate = self.eq.velocity_violation(k, &self.qd);
                self.gamma[k] -= 2.0 * alpha * rate + beta * beta * self.eq.constraints[k];
            }
        }
        let result = self.eq.accelerations(
            &self.partition,
            self.settings.formulation,
            &self.gamma,
            self.singular_limit,
            &mut self.qdd,
        );
        if result.map_err(|detail| self.singular(time, detail))? {
            self.singular_evaluations += 1;
        }
        Ok(())
    }

    /// Multipliers consistent with self.qdd (after `accelerations`).
    fn multipliers(&self, time: f64, lambda: &mut [f64]) -> Result<()> {
        if let (Some(tree), Some(_)) = (&self.tree, &self.tree_solver) {
            // The reactions on the reference coordinates, -F_r = C_r^T lambda over the tree
            // joints' and normalizations' rows (from the assembly of the last evaluation);
            // the cut rows' multipliers come from the solve.
            let nq = self.q.len();
            let rows = tree.reference_rows();
            let mut row_of = vec![usize::MAX; nq];
            for (i, &r) in rows.iter().enumerate() {
                row_of[r] = i;
            }
            let kept: Vec<usize> =
                (0..self.model.constraint_count).filter(|r| !tree.cut_rows.contains(r)).collect();
            let mut position = vec![usize::MAX; self.model.constraint_count];
            for (a, &r) in kept.iter().enumerate() {
                position[r] = a;
            }
            let mut ct = Mat::<f64>::zeros(rows.len(), kept.len());
            let pattern = &self.model.layout.pattern;
            for (i, &c) in rows.iter().enumerate() {
                for k in pattern.col_ptr[c]..pattern.col_ptr[c + 1] {
                    let r = pattern.row_idx[k];
                    if r >= nq && position[r - nq] != usize::MAX {
                        ct[(i, position[r - nq])] = self.ws.values[k];
                    }
                }
            }
            let solution =
                minimum_norm_solve(ct.as_ref(), &self.tree_reactions.reactions, SINGULAR_VALUE_CUTOFF);
            lambda.iter_mut().for_each(|x| *x = 0.0);
            for (a, &r) in kept.iter().enumerate() {
                lambda[r] = solution[a];
            }
            for (a, &r) in tree.cut_rows.iter().enumerate() {
                lambda[r] = self.tree_reactions.cut_multipliers[a];
            }
            let _ = time;
            return Ok(());
        }
        if self.tree.is_some() {
            // C_q^T lambda = f - M q_dd over all rows (the joint reactions, eliminated from the
            // joint-coordinate equations, recovered here).
            let n = self.q.len();
            let residual: Vec<f64> = (0..n)
                .map(|i| self.eq.force[i] - (0..n).map(|j| self.eq.mass[(i, j)] * self.qdd[j]).sum::<f64>())
                .collect();
            let ct = self.eq.jacobian.transpose().to_owned();
            let solution = minimum_norm_solve(ct.as_ref(), &residual, SINGULAR_VALUE_CUTOFF);
            lambda.copy_from_slice(&solution);
            return Ok(());
        }
        self.eq.multipliers(&self.partition, &self.qdd, lambda).map_err(|detail| self.singular(time, detail))
    }

    /// Wehage: the full q and q_dot from the independent ones `y` = [q_i; qd_i] at `time`.
    fn reconstruct(&mut self, time: f64, y: &[f64]) -> Result<()> {
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
                if correction > BRANCH_JUMP_FRACTION * motion + 1e3 * self.settings.constraint_tolerance {
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

    /// The integrated vector of the current full state.
    fn pack(&self, y: &mut Vec<f64>) {
        y.clear();
        match self.mode {
            Strategy::CoordinatePartitioning => {
                y.extend(self.partition.independent.iter().map(|&c| self.q[c]));
                y.extend(self.partition.independent.iter().map(|&c| self.qd[c]));
            }
            Strategy::JointCoordinates => {
                y.extend_from_slice(&self.p);
                y.extend_from_slice(&self.pd);
            }
            _ => {
                y.extend_from_slice(&self.q);
                y.extend_from_slice(&self.qd);
            }
        }
    }

    /// Joint coordinates: the body state (q, q_dot, gamma_B and B) from self.p and self.pd.
    fn update_bodies(&mut self, time: f64) -> Result<()> {
        if let (Some(tree), Some(_)) = (&self.tree, &self.tree_solver) {
            let st = tree.structured(self.model, time, &self.p, &self.pd)?;
            self.q.copy_from_slice(&st.coordinates);
            self.qd.copy_from_slice(&st.velocities);
            self.gamma_b.copy_from_slice(&st.gamma);
            self.structured = Some(st);
            return Ok(());
        }
        self.update_bodies_with_influence(time)
    }

    /// Joint coordinates: the body state with the dense influence coefficients B.
    fn update_bodies_with_influence(&mut self, time: f64) -> Result<()> {
        if let Some(tree) = &self.tree {
            let state = tree.evaluate(self.model, time, &self.p, &self.pd)?;
            self.q = state.coordinates;
            self.qd = state.velocities;
            self.gamma_b = state.gamma;
            self.influence = state.influence;
        }
        Ok(())
    }

    /// Sets the full state from the integrated vector (Wehage: Newton for the dependent part).
    fn unpack(&mut self, time: f64, y: &[f64]) -> Result<()> {
        match self.mode {
            Strategy::CoordinatePartitioning => self.reconstruct(time, y),
            Strategy::JointCoordinates => {
                let np = self.p.len();
                self.p.copy_from_slice(&y[..np]);
                self.pd.copy_from_slice(&y[np..]);
                self.update_bodies(time)
            }
            _ => {
                let n = self.q.len();
                self.q.copy_from_slice(&y[..n]);
                self.qd.copy_from_slice(&y[n..]);
                Ok(())
            }
        }
    }

    /// Evaluates the equations at (time, self.q, self.qd) up to `level`.
    fn evaluate(&mut self, time: f64, level: Level) -> Result<()> {
        self.eq.evaluate(self.model, &mut self.ws, time, &self.q, &self.qd, &self.discrete, level)
    }

    /// dy/dt at (time, y).
    fn derivative(&mut self, time: f64, y: &[f64], dy: &mut [f64]) -> Result<()> {
        self.unpack(time, y)?;
        self.accelerations(time)?;
        self.last_time = time;
        if time == self.accepted_time {
            self.accepted_qdd.copy_from_slice(&self.qdd);
        }
        match self.mode {
            Strategy::CoordinatePartitioning => {
                let ni = self.partition.independent.len();
                for (k, &c) in self.partition.independent.iter().enumerate() {
                    dy[k] = self.qd[c];
                    dy[ni + k] = self.qdd[c];
                }
            }
            Strategy::JointCoordinates => {
                let np = self.p.len();
                dy[..np].copy_from_slice(&self.pd);
                dy[np..].copy_from_slice(&self.pdd);
            }
            _ => {
                let n = self.q.len();
                dy[..n].copy_from_slice(&self.qd);
                dy[n..].copy_from_slice(&self.qdd);
            }
        }
        Ok(())
    }

    /// Joint coordinates with cut joints: projects p onto C_cut(q(p), t) = 0 (Newton with
    /// minimum-norm steps) and p_dot onto the cut joints' velocity constraints.
    fn project_joint_coordinates(&mut self, time: f64) -> Result<()> {
        let Some(rows) = self.tree.as_ref().map(|t| t.cut_rows.clone()) else { return Ok(()) };
        let n = self.q.len();
        let mut iterations = 0;
        let mut previous = f64::INFINITY;
        loop {
            self.update_bodies_with_influence(time)?;
            self.evaluate(time, Level::Velocity)?;
            let residual: Vec<f64> = rows.iter().map(|&r| self.eq.constraints[r]).collect();
            let (k, violation) = worst(&residual);
            let c_hat = Mat::from_fn(rows.len(), n, |a, j| self.eq.jacobian[(rows[a], j)]) * &self.influence;
            if converged(violation, previous, self.settings.constraint_tolerance) {
                // Velocities: C_cut (B p_dot + v_prescribed) + C_t = 0.
                let rate: Vec<f64> = rows.iter().map(|&r| self.eq.velocity_violation(r, &self.qd)).collect();
                let dv = minimum_norm_solve(c_hat.as_ref(), &rate, SINGULAR_VALUE_CUTOFF);
                for (x, d) in self.pd.iter_mut().zip(&dv) {
                    *x -= d;
                }
                return self.update_bodies(time);
            }
            previous = violation;
            if iterations >= self.settings.max_iterations || !violation.is_finite() {
                return Err(FlexmbdError::NewtonDiverged {
                    time,
                    step_size: 0.0,
                    iterations,
                    residual: violation,
                    item: format!(
                        "{}; joint coordinates onto the cut joints",
                        self.model.constraint_name(rows[k])
                    ),
                });
            }
            let dp = minimum_norm_solve(c_hat.as_ref(), &residual, SINGULAR_VALUE_CUTOFF);
            for (x, d) in self.p.iter_mut().zip(&dp) {
                *x -= d;
            }
            iterations += 1;
            self.newton_iterations += 1;
        }
    }

    /// Projects self.q onto C = 0 (Newton with minimum-norm steps over the partition's rows)
    /// and self.qd onto C_q q_dot + C_t = 0.
    fn project(&mut self, time: f64) -> Result<()> {
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

    fn names(&self, coordinates: &[usize]) -> String {
        coordinates.iter().map(|&c| self.model.coordinate_name(c)).collect::<Vec<_>>().join(", ")
    }

    /// After an accepted step: a better partition if one is proposed, and for coordinate
    /// partitioning the passage through singular configurations. Where even the best
    /// partition has a condition above `singular_limit` (the constraint Jacobian is near
    /// rank-deficient, as at the change points of a parallelogram linkage, so that no choice
    /// of independent coordinates determines the dependent ones well), the steps are taken
    /// with strategy (3), integrate-all-then-project, until a partition below half of that
    /// limit exists again. Returns the events.
    fn update_partition(&mut self, time: f64) -> Result<Vec<Event>> {
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
    fn repartition_after_failure(&mut self) -> Result<Option<Event>> {
        self.q.copy_from_slice(&self.accepted_q);
        self.qd.copy_from_slice(&self.accepted_qd);
        self.repartition(self.accepted_time, true)
    }
}

/// Newton iterations on the constraints end at `tolerance`, or where they stagnate within
/// `STAGNATION_FACTOR` of it: the last digits of C are round-off (a body far from the origin,
/// a rank-deficient Jacobian near a singular configuration).
fn converged(violation: f64, previous: f64, tolerance: f64) -> bool {
    violation <= tolerance || (violation <= STAGNATION_FACTOR * tolerance && violation > 0.5 * previous)
}

/// See `converged`.
const STAGNATION_FACTOR: f64 = 100.0;

/// Largest Newton correction of the dependent coordinates, as a fraction of their predicted
/// motion over the step, that is taken for the same solution branch (see `reconstruct`).
const BRANCH_JUMP_FRACTION: f64 = 0.25;

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
fn attempt(
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

/// The integrated vector of the engine's state, and the stage buffers sized for it.
fn resize_for(
    engine: &mut Engine,
    y: &mut Vec<f64>,
    y_new: &mut Vec<f64>,
    stage: &mut Vec<f64>,
    k: &mut [Vec<f64>; 7],
) {
    engine.pack(y);
    y_new.resize(y.len(), 0.0);
    stage.resize(y.len(), 0.0);
    k.iter_mut().for_each(|v| v.resize(y.len(), 0.0));
}

/// Whether an error is a failure of one step attempt that a smaller step may avoid.
fn retryable(e: &FlexmbdError) -> bool {
    matches!(
        e,
        FlexmbdError::NewtonDiverged { .. }
            | FlexmbdError::SingularMatrix { .. }
            | FlexmbdError::NonFinite { .. }
    )
}

/// The explicit time loop; keeps the last accepted state in `last_state`.
pub fn run(
    model: &Model,
    settings: &SimulationSettings,
    explicit: &ExplicitSettings,
    observer: &mut dyn FnMut(&Progress) -> bool,
    output: &mut Output,
    last_state: &mut Option<State>,
) -> Result<()> {
    settings.validate()?;
    explicit.validate(model)?;
    let n = model.coordinate_count;
    let mut ws = Workspace::new(model);
    let mut eq = DenseEquations::new(model);
    let mut state = starting_state(model, settings.start_time, settings.start.as_ref())?;
    let (given_q, given_qd) = (state.coordinates.clone(), state.velocities.clone());
    let violated = dense_initial_conditions(model, &mut ws, &mut eq, &mut state, &settings.initial)?;
    report_initial_correction(model, &given_q, &given_qd, &state, &violated, settings, output)?;
    update_discrete(model, &mut state, &mut ws, true);

    // The partition at the start.
    let t0 = state.time;
    eq.evaluate(model, &mut ws, t0, &state.coordinates, &state.velocities, &state.discrete, Level::Position)?;
    let first = match &explicit.independent {
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
    };
    let mut engine = Engine {
        model,
        settings: explicit,
        ws,
        eq,
        partition: first,
        q: state.coordinates.clone(),
        qd: state.velocities.clone(),
        qdd: vec![0.0; n],
        accepted_q: state.coordinates.clone(),
        accepted_qd: state.velocities.clone(),
        accepted_qdd: vec![0.0; n],
        last_time: f64::NAN,
        check_branch: false,
        accepted_time: t0,
        gamma: vec![0.0; model.constraint_count],
        discrete: state.discrete.clone(),
        evaluations: 0,
        newton_iterations: 0,
        singular_evaluations: 0,
        mode: explicit.strategy,
        singular_limit: 0.0,
        last_condition: f64::INFINITY,
        tree: None,
        p: Vec::new(),
        pd: Vec::new(),
        pdd: Vec::new(),
        gamma_b: vec![0.0; n],
        influence: Mat::zeros(0, 0),
        tree_solver: None,
        structured: None,
        tree_reactions: TreeAccelerations::default(),
    };
    if explicit.strategy == Strategy::JointCoordinates {
        // The tree and the joint coordinates of the consistent initial state; the body state is
        // then recomputed from them (it satisfies the joints exactly).
        let (tree, p0) = Tree::new(model, &state.coordinates, explicit.cut_joints.as_deref())?;
        let mut p0 = p0;
        let mut pd0 = tree.initial_rates(model, t0, &p0, &state.velocities)?;
        let mut tree = tree;
        let rebased = tree.rebase(model, &mut p0, &mut pd0, CARDAN_REBASE_ANGLE);
        if !rebased.is_empty() {
            output.events.push(Event {
                time: t0,
                kind: "joint coordinates rebased".to_string(),
                message: format!("Cardan angles started at zero: {}", rebased.join(", ")),
            });
        }
        if explicit.tree_formulation != TreeFormulation::JointSpace {
            engine.tree_solver = Some(TreeSolver::new(model, &tree, explicit.tree_formulation)?);
        }
        engine.pdd = vec![0.0; p0.len()];
        engine.p = p0;
        engine.pd = pd0;
        output.statistics.reduced_system_size = match &engine.tree_solver {
            Some(solver) => solver.reduced_size(),
            None => tree.free_count() + tree.cut_rows.len(),
        };
        engine.tree = Some(tree);
        engine.update_bodies(t0)?;
        state.coordinates.copy_from_slice(&engine.q);
        state.velocities.copy_from_slice(&engine.qd);
    }
    engine.singular_limit = explicit.singular_factor * engine.partition.condition.max(1.0);
    if !engine.partition.redundant_rows.is_empty() {
        let names: Vec<String> =
            engine.partition.redundant_rows.iter().map(|&r| model.constraint_name(r)).collect();
        output.events.push(Event {
            time: t0,
            kind: "redundant constraints".to_string(),
            message: format!("rows without multipliers (dependent on the others): {}", names.join("; ")),
        });
    }

    // Record the start.
    let record = |engine: &mut Engine, state: &mut State, output: &mut Output| -> Result<()> {
        engine.q.copy_from_slice(&state.coordinates);
        engine.qd.copy_from_slice(&state.velocities);
        engine.discrete.copy_from_slice(&state.discrete);
        engine.accelerations(state.time)?;
        state.accelerations.copy_from_slice(&engine.qdd);
        engine.multipliers(state.time, &mut state.multipliers)?;
        output.record(model, state, &mut engine.ws);
        Ok(())
    };
    record(&mut engine, &mut state, output)?;
    *last_state = Some(state.clone());

    let mut clock = OutputClock::new(settings);
    let mut h = settings.step_size;
    let adaptive = explicit.method == ExplicitMethod::Dopri5;
    let mut y = Vec::new();
    engine.pack(&mut y);
    let mut y_new = vec![0.0; y.len()];
    let mut stage = vec![0.0; y.len()];
    let mut k: [Vec<f64>; 7] = std::array::from_fn(|_| vec![0.0; y.len()]);
    let mut first_derivative_valid = false;
    let mut drift_reported = false;
    output.statistics.min_step_size_used = f64::INFINITY;
    let release = std::cell::Cell::new(0);

    let mut near_singular = false;
    while clock.running(state.time) {
        let t = state.time;
        let singular_before = engine.singular_evaluations;
        let h_try = clock.step(t, h);
        if !first_derivative_valid {
            engine.derivative(t, &y, &mut k[0])?;
            first_derivative_valid = true;
        }
        let attempt_result =
            attempt(&mut engine, explicit.method, t, h_try, &y, &mut k, &mut y_new, &mut stage).and_then(
                |err| {
                    // The end point of a step that passes the error test: the full state, with
                    // the check that the dependent coordinates stayed on their branch.
                    if (adaptive && err <= 1.0) || (!adaptive && err.is_finite()) {
                        engine.check_branch = true;
                        let result = engine.unpack(t + h_try, &y_new);
                        engine.check_branch = false;
                        result?;
                    }
                    Ok(err)
                },
            );
        let (accepted, factor) = match attempt_result {
            Ok(err) if !adaptive => (err.is_finite(), 1.0),
            Ok(err) => {
                let factor =
                    if err.is_finite() { (0.9 * err.max(1e-10).powf(-0.2)).clamp(0.2, 5.0) } else { 0.2 };
                (err <= 1.0, factor)
            }
            Err(e) if retryable(&e) => {
                // A failed Newton iteration or a singular block: first try a better partition
                // at the start of the step, then (error control) a smaller step.
                if let Some(event) = engine.repartition_after_failure()? {
                    output.events.push(event);
                    output.statistics.rejected_steps += 1;
                    resize_for(&mut engine, &mut y, &mut y_new, &mut stage, &mut k);
                    first_derivative_valid = false;
                    continue;
                }
                if !adaptive || h_try * 0.25 < settings.step_floor() {
                    return Err(e);
                }
                (false, 0.25)
            }
            Err(e) => return Err(e),
        };
        if !accepted {
            output.statistics.rejected_steps += 1;
            if !adaptive {
                return Err(FlexmbdError::NonFinite { item: "the Runge-Kutta step".to_string(), time: t });
            }
            h = h_try * factor.min(1.0);
            if h < settings.step_floor() {
                return Err(FlexmbdError::StepSizeTooSmall {
                    time: t,
                    step_size: h,
                    min_step_size: settings.step_floor(),
                });
            }
            continue;
        }

        // Accept.
        let t_new = t + h_try;
        std::mem::swap(&mut y, &mut y_new);
        let mut modified = false;
        if engine.mode == Strategy::Projection {
            engine.project(t_new)?;
            modified = true;
        }
        if engine.tree.as_ref().is_some_and(|t| !t.cut_rows.is_empty()) {
            engine.project_joint_coordinates(t_new)?;
            modified = true;
        }
        if let Some(tree) = engine.tree.as_mut() {
            // Cardan angles of spherical and free joints restart before their singularity.
            let rebased = tree.rebase(model, &mut engine.p, &mut engine.pd, CARDAN_REBASE_ANGLE);
            if !rebased.is_empty() {
                engine.update_bodies(t_new)?;
                output.events.push(Event {
                    time: t_new,
                    kind: "joint coordinates rebased".to_string(),
                    message: format!(
                        "Cardan angles restarted at zero (the middle angle passed {:.0} degrees): {}",
                        CARDAN_REBASE_ANGLE.to_degrees(),
                        rebased.join(", ")
                    ),
                });
                modified = true;
            }
        }
        let mode = engine.mode;
        let events = engine.update_partition(t_new)?;
        if !events.is_empty() || engine.mode != mode {
            modified = true;
        }
        output.events.extend(events);
        if modified {
            resize_for(&mut engine, &mut y, &mut y_new, &mut stage, &mut k);
        }
        engine.accepted_q.copy_from_slice(&engine.q);
        engine.accepted_qd.copy_from_slice(&engine.qd);
        if !modified && engine.last_time == t_new {
            // Dormand-Prince's last stage was evaluated at exactly this state.
            engine.accepted_qdd.copy_from_slice(&engine.qdd);
        }
        engine.accepted_time = t_new;
        state.time = t_new;
        state.coordinates.copy_from_slice(&engine.q);
        state.velocities.copy_from_slice(&engine.qd);
        let discrete_before = state.discrete.clone();
        update_discrete(model, &mut state, &mut engine.ws, false);
        engine.discrete.copy_from_slice(&state.discrete);
        // First same as last: dy/dt at the new point, unless the state or the forces changed.
        first_derivative_valid = adaptive && !modified && discrete_before == state.discrete;
        if first_derivative_valid {
            let (head, tail) = k.split_at_mut(6);
            head[0].copy_from_slice(&tail[0]);
        }
        if engine.singular_evaluations > singular_before {
            if !near_singular {
                output.events.push(Event {
                    time: t_new,
                    kind: "singular configuration".to_string(),
                    message: format!(
                        "ill-conditioned dependent block or near rank-deficient constraint Jacobian \
                         between t = {t} and {t_new}: accelerations by the null-space method (truncated \
                         SVD of C_q)"
                    ),
                });
            }
            near_singular = true;
        } else {
            near_singular = false;
        }
        let stats = &mut output.statistics;
        stats.steps += 1;
        stats.min_step_size_used = stats.min_step_size_used.min(h_try);
        stats.max_step_size_used = stats.max_step_size_used.max(h_try);
        if let Some(k) = state.first_non_finite() {
            return Err(FlexmbdError::NonFinite { item: model.coordinate_name(k), time: state.time });
        }
        if clock.due(state.time) {
            record(&mut engine, &mut state, output)?;
            let violation = output.constraint_violation.last().copied().unwrap_or(0.0);
            if !drift_reported && violation > explicit.drift_threshold {
                drift_reported = true;
                output.events.push(Event {
                    time: state.time,
                    kind: "constraint drift".to_string(),
                    message: format!(
                        "constraint violation {violation:.3e} passed {:.1e} (strategy '{}' does not \
                         correct the positions{})",
                        explicit.drift_threshold,
                        explicit.strategy.name(),
                        if explicit.baumgarte.is_some() {
                            "; larger Baumgarte parameters hold it closer"
                        } else {
                            "; Baumgarte stabilization, or strategy 'partitioning' or 'projection', \
                             holds it"
                        }
                    ),
                });
            }
        }
        state.store_in(last_state);
        output.statistics.function_evaluations = engine.evaluations;
        output.statistics.newton_iterations = engine.newton_iterations;
        if adaptive && h_try >= h * (1.0 - 1e-12) {
            h = (h_try * factor).min(settings.max_step_size);
        }
        let progress = Progress {
            time: state.time,
            step_size: h_try,
            newton_iterations: 0,
            steps: output.statistics.steps,
            records: Records::new(output),
            release: &release,
        };
        if !observer(&progress) {
            return Err(FlexmbdError::Interrupted { time: state.time });
        }
        output.release_front(release.take());
    }
    output.statistics.function_evaluations = engine.evaluations;
    output.statistics.newton_iterations = engine.newton_iterations;
    Ok(())
}
