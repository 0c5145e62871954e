//! The right-hand sides of the explicit integrators: the state of the evaluations (full
//! coordinates and velocities, the partition, the tree of joint coordinates, counters), the
//! integrated vector of each strategy (`pack`, `unpack`) and its derivative, the accelerations
//! (augmented or embedded, with Baumgarte's terms, or in joint coordinates) and the
//! multipliers that go with them.

use faer::Mat;

use crate::error::{FlexmbdError, Result};
use crate::formulation::augmented::{DenseEquations, Level, SINGULAR_VALUE_CUTOFF};
use crate::formulation::decoupled::{TreeAccelerations, TreeSolver};
use crate::formulation::recursive::{
    tree_joint_accelerations, BodyInfluence, SparseJointSpace, StructuredState, Tree,
};
use crate::integrator::settings::{ExplicitSettings, Strategy};
use crate::linalg::partition::{minimum_norm_solve, partition, Partition};
use crate::output::Output;
use crate::system::{Model, State, Workspace};

/// Evaluation of the right-hand sides, with its buffers and counters. n: coordinates, nc:
/// constraint rows, np: joint coordinates of the tree (joint-coordinate strategy only).
pub(super) struct Engine<'a> {
    pub(super) model: &'a Model,
    pub(super) settings: &'a ExplicitSettings,
    /// Buffers of the assembly (kinematics, the Jacobian values the tree multipliers read).
    pub(super) ws: Workspace,
    /// The dense equations (M, f, C, C_q, gamma) of the last evaluation, filled by `evaluate`.
    pub(super) eq: DenseEquations,
    /// The partition of the coordinates into dependent and independent ones.
    pub(super) partition: Partition,
    /// Full coordinates, velocities and accelerations of the last evaluation (n each).
    pub(super) q: Vec<f64>,
    pub(super) qd: Vec<f64>,
    pub(super) qdd: Vec<f64>,
    /// The accepted full state (start of the step): guesses for the dependent coordinates
    /// (n each).
    pub(super) accepted_q: Vec<f64>,
    pub(super) accepted_qd: Vec<f64>,
    /// Accelerations at the accepted state (for the dependent coordinates' predictor; n).
    pub(super) accepted_qdd: Vec<f64>,
    /// Time and accelerations of the last evaluation (first same as last: they become the
    /// accepted ones when that evaluation was at the accepted state).
    pub(super) last_time: f64,
    /// Whether `reconstruct` checks for a jump to another solution branch (only at the end
    /// of a step: the Runge-Kutta stages are not points of the trajectory).
    pub(super) check_branch: bool,
    /// Time of the accepted state (s).
    pub(super) accepted_time: f64,
    /// gamma of the acceleration constraints with Baumgarte's terms (nc), filled by
    /// `accelerations`.
    pub(super) gamma: Vec<f64>,
    /// The discrete variables of the accepted state (unwrapped spring angles).
    pub(super) discrete: Vec<f64>,
    /// Evaluations of the accelerations so far (`Statistics::function_evaluations`).
    pub(super) evaluations: usize,
    /// Newton iterations of the dependent coordinates and the projections so far.
    pub(super) newton_iterations: usize,
    /// Evaluations near a singular configuration (truncated-SVD accelerations).
    pub(super) singular_evaluations: usize,
    /// The strategy of the current steps: the chosen one, or projection while coordinate
    /// partitioning passes a singular configuration.
    pub(super) mode: Strategy,
    /// Partition condition above which a configuration counts as singular.
    pub(super) singular_limit: f64,
    /// Condition of the partition after the previous accepted step (its growth rate predicts
    /// the next step's, see `repartition`).
    pub(super) last_condition: f64,
    /// Joint coordinates: the tree, the joint coordinates, rates and accelerations (np each),
    /// and the velocity-quadratic accelerations gamma_B of the body coordinates (n).
    pub(super) tree: Option<Tree>,
    pub(super) p: Vec<f64>,
    pub(super) pd: Vec<f64>,
    pub(super) pdd: Vec<f64>,
    pub(super) gamma_b: Vec<f64>,
    /// Joint coordinates by seed eq. 40 or 41: the solver, the tree state with the influence
    /// coefficients in factored form, and the last reactions -F_r and cut multipliers.
    pub(super) tree_solver: Option<TreeSolver>,
    pub(super) structured: Option<StructuredState>,
    pub(super) tree_reactions: TreeAccelerations,
    /// Velocity influence coefficients B = dq/dp of the free joint coordinates at p (n x np),
    /// filled by `update_bodies_with_influence`.
    pub(super) influence: Mat<f64>,
    /// Joint coordinates: the number of independent cut equations where the loops are regular
    /// (the rank of C_cut B at the start, raised when a later state shows more; see
    /// `formulation::recursive::LoopClosure`).
    pub(super) loop_rank: usize,
    /// The numerical rank of C_cut B at the last projection (`project_joint_coordinates`).
    pub(super) observed_loop_rank: usize,
    /// Joint coordinates: the time of the start (where the cut equations' rank was found).
    pub(super) tree_start: f64,
    /// Joint space of a rigid tree: the evaluation body by body (without B and the model's
    /// dense matrices) and its influence coefficients at self.p; the dense path serves where
    /// the cut joints are not regular (`formulation::recursive::SparseJointSpace`).
    pub(super) sparse: Option<SparseJointSpace>,
    pub(super) body_influence: BodyInfluence,
    /// Evaluations and projection iterations that took the dense path although the sparse one
    /// exists (near singular configurations of the loops).
    pub(super) dense_fallbacks: usize,
}

impl<'a> Engine<'a> {
    /// The engine at the consistent initial `state`, with the start's `partition`.
    pub(super) fn new(
        model: &'a Model,
        settings: &'a ExplicitSettings,
        ws: Workspace,
        eq: DenseEquations,
        partition: Partition,
        state: &State,
    ) -> Self {
        let n = model.coordinate_count;
        Engine {
            model,
            settings,
            ws,
            eq,
            partition,
            q: state.coordinates.clone(),
            qd: state.velocities.clone(),
            qdd: vec![0.0; n],
            accepted_q: state.coordinates.clone(),
            accepted_qd: state.velocities.clone(),
            accepted_qdd: vec![0.0; n],
            last_time: f64::NAN,
            check_branch: false,
            accepted_time: state.time,
            gamma: vec![0.0; model.constraint_count],
            discrete: state.discrete.clone(),
            evaluations: 0,
            newton_iterations: 0,
            singular_evaluations: 0,
            mode: settings.strategy,
            singular_limit: 0.0,
            last_condition: f64::INFINITY,
            tree: None,
            p: Vec::new(),
            pd: Vec::new(),
            pdd: Vec::new(),
            gamma_b: vec![0.0; n],
            influence: Mat::zeros(0, 0),
            loop_rank: 0,
            observed_loop_rank: 0,
            tree_start: 0.0,
            tree_solver: None,
            structured: None,
            tree_reactions: TreeAccelerations::default(),
            sparse: None,
            body_influence: BodyInfluence::default(),
            dense_fallbacks: 0,
        }
    }

    /// The error of a singular acceleration system (or dependent block) at `time`.
    pub(super) fn singular(&self, time: f64, detail: String) -> FlexmbdError {
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

    /// The error of a failed solve for the joint accelerations: a state that is no longer
    /// finite (a step that diverged, above the method's stability limit: its NaN make B^T M B
    /// fail its Cholesky factorization) is `NonFinite`; otherwise the singular matrix, at
    /// `time`.
    fn tree_failure(&self, time: f64, error: FlexmbdError) -> FlexmbdError {
        if !self.q.iter().chain(&self.qd).chain(&self.eq.force).all(|v| v.is_finite()) {
            return FlexmbdError::NonFinite { item: "the state of the step (it diverged)".to_string(), time };
        }
        match error {
            FlexmbdError::SingularMatrix { context, detail, .. } => {
                self.singular(time, format!("{context}: {detail}"))
            }
            other => other,
        }
    }

    /// Accelerations at (time, self.q, self.qd) into self.qdd.
    pub(super) fn accelerations(&mut self, time: f64) -> Result<()> {
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
        if self.sparse.is_some() {
            self.evaluations += 1;
            if self.sparse_accelerations(time)? {
                return Ok(());
            }
            self.dense_fallbacks += 1;
            self.evaluations -= 1;
            self.update_bodies_with_influence(time)?;
        }
        self.evaluate(time, Level::Acceleration)?;
        self.evaluations += 1;
        if let Some(tree) = &self.tree {
            let n = self.q.len();
            let b = &self.influence;
            self.pdd = tree_joint_accelerations(&self.eq, b, &self.gamma_b, &tree.cut_rows, self.loop_rank)
                .map_err(|e| self.tree_failure(time, e))?;
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
        let mut null_space = result.map_err(|detail| self.singular(time, detail))?;
        if null_space && !self.settings.uses_coordinates() && self.settings.independent.is_none() {
            // Integrating all coordinates, the partition only pivots this solve. Chosen at the
            // start, its dependent block grows ill-conditioned as the mechanism moves far from
            // there (an open chain swinging through a quarter turn), with no singular
            // configuration: a fresh partition serves then, and the null-space method (and its
            // event) is left to configurations that no partition resolves.
            let fresh =
                partition(self.eq.jacobian.as_ref(), self.settings.partition, self.settings.rank_tolerance);
            if fresh.rank == self.partition.rank && fresh.condition <= self.singular_limit {
                self.partition = fresh;
                null_space = self
                    .eq
                    .accelerations(
                        &self.partition,
                        self.settings.formulation,
                        &self.gamma,
                        self.singular_limit,
                        &mut self.qdd,
                    )
                    .map_err(|detail| self.singular(time, detail))?;
            }
        }
        if null_space {
            self.singular_evaluations += 1;
        }
        Ok(())
    }

    /// Multipliers consistent with self.qdd (after `accelerations`).
    pub(super) fn multipliers(&self, time: f64, lambda: &mut [f64]) -> Result<()> {
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

    /// The integrated vector of the current full state.
    pub(super) fn pack(&self, y: &mut Vec<f64>) {
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

    /// Sets the full state from the integrated vector (Wehage: Newton for the dependent part).
    pub(super) fn unpack(&mut self, time: f64, y: &[f64]) -> Result<()> {
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
    pub(super) fn evaluate(&mut self, time: f64, level: Level) -> Result<()> {
        self.eq.evaluate(self.model, &mut self.ws, time, &self.q, &self.qd, &self.discrete, level)
    }

    /// dy/dt at (time, y).
    pub(super) fn derivative(&mut self, time: f64, y: &[f64], dy: &mut [f64]) -> Result<()> {
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

    /// Records `state` (at an output time) with the accelerations and multipliers of this
    /// engine at it.
    pub(super) fn record(&mut self, state: &mut State, output: &mut Output) -> Result<()> {
        self.complete(state)?;
        output.record(self.model, state, &mut self.ws);
        Ok(())
    }

    /// Sets the accelerations and multipliers of `state` from its coordinates and velocities.
    pub(super) fn complete(&mut self, state: &mut State) -> Result<()> {
        self.q.copy_from_slice(&state.coordinates);
        self.qd.copy_from_slice(&state.velocities);
        self.discrete.copy_from_slice(&state.discrete);
        self.accelerations(state.time)?;
        state.accelerations.copy_from_slice(&self.qdd);
        if let Some(sparse) = self.sparse.as_mut() {
            // The workspace holds the acceleration-level assembly at this state.
            if let Some(lambda) = sparse.multipliers(&self.ws, &self.eq.force, &self.qdd) {
                state.multipliers.copy_from_slice(&lambda);
                return Ok(());
            }
            // The dense path below reads the dense M and C_q.
            self.evaluate(state.time, Level::Acceleration)?;
        }
        self.multipliers(state.time, &mut state.multipliers)
    }

    /// The names of `coordinates`, for messages.
    pub(super) fn names(&self, coordinates: &[usize]) -> String {
        coordinates.iter().map(|&c| self.model.coordinate_name(c)).collect::<Vec<_>>().join(", ")
    }
}

/// Newton iterations on the constraints end at `tolerance`, or where they stagnate within
/// `STAGNATION_FACTOR` of it: the last digits of C are round-off (a body far from the origin,
/// a rank-deficient Jacobian near a singular configuration).
pub(super) fn converged(violation: f64, previous: f64, tolerance: f64) -> bool {
    violation <= tolerance || (violation <= STAGNATION_FACTOR * tolerance && violation > 0.5 * previous)
}

/// See `converged`.
const STAGNATION_FACTOR: f64 = 100.0;
