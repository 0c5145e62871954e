//! Joint coordinates (seed section 5): the tree of the model and its joint coordinates at the
//! start, the body state from the joint coordinates (with the dense influence coefficients or
//! the structured state of seed eqs. 40-41), the projection onto cut joints after each step,
//! and the rebasing of Cardan angles before their singularity.

use faer::Mat;

use super::engine::{converged, Engine};
use crate::error::{FlexmbdError, Result};
use crate::formulation::augmented::{worst, Level, SINGULAR_VALUE_CUTOFF};
use crate::formulation::decoupled::{TreeFormulation, TreeSolver};
use crate::formulation::recursive::{
    elastic_matrices, loop_rank, LoopClosure, SparseJointSpace, Tree, TreeLinearization, LOOP_DAMPING,
};
use crate::integrator::settings::{IterationJacobian, Strategy};
use crate::output::{Event, Output};
use crate::system::State;

/// Joint coordinates: the middle Cardan angle (rad) beyond which a spherical or free joint's
/// angles are rebased (their singularity is at 90 degrees).
const CARDAN_REBASE_ANGLE: f64 = 1.0;

/// Projection onto the cut joints: a residual this factor below the constraint tolerance ends
/// the Newton iteration without the polishing iteration.
const POLISHED: f64 = 1e-3;

/// What a projection's Newton iteration does after a residual ([`ProjectionIteration`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Next {
    /// Converged: correct the velocities and stop.
    Converged,
    /// Take another Newton step.
    Iterate,
    /// Too many iterations, or a residual that is not finite.
    Diverged,
}

/// The stopping rule of a projection onto the cut joints, shared by the sparse and the dense
/// iteration: one more iteration once the tolerance is met, unless the residual is round-off
/// already or stagnates.
#[derive(Clone, Copy, Debug)]
struct ProjectionIteration {
    iterations: usize,
    previous: f64,
    polished: bool,
}

impl ProjectionIteration {
    fn new() -> Self {
        ProjectionIteration { iterations: 0, previous: f64::INFINITY, polished: false }
    }

    /// The decision at a residual of largest entry `violation` (counting the iteration when
    /// it goes on).
    fn next(&mut self, violation: f64, tolerance: f64, max_iterations: usize) -> Next {
        let met = converged(violation, self.previous, tolerance);
        if met && (self.polished || violation <= POLISHED * tolerance || violation > 0.5 * self.previous) {
            return Next::Converged;
        }
        if self.iterations >= max_iterations || !violation.is_finite() {
            return Next::Diverged;
        }
        self.polished = met;
        self.previous = violation;
        self.iterations += 1;
        Next::Iterate
    }
}

/// Largest difference, relative to 1 + the largest speed, between the initial velocities and
/// those of the joint rates solved from them (the least-squares solve reproduces consistent
/// velocities to round-off).
const REPRESENTED_VELOCITY: f64 = 1e-8;

impl Engine<'_> {
    /// The tree and the joint coordinates of the consistent initial `state`; the body state is
    /// then recomputed from them (it satisfies the joints exactly) and written to `state`.
    pub(super) fn start_joint_coordinates(&mut self, state: &mut State, output: &mut Output) -> Result<()> {
        let (model, explicit) = (self.model, self.settings);
        let t0 = state.time;
        let (mut tree, mut p0) = Tree::new(model, &state.coordinates, explicit.cut_joints.as_deref())?;
        // Rebased before the rates are solved: at the Cardan singularity (middle angle +-90
        // degrees) the rates cannot hold every angular velocity, and the minimum-norm solve
        // dropped the part they cannot (a free body started with omega_z 0.7 lost it).
        let mut no_rates = vec![0.0; p0.len()];
        let rebased = tree.rebase(model, &mut p0, &mut no_rates, CARDAN_REBASE_ANGLE);
        let pd0 = tree.initial_rates(model, t0, &p0, &state.velocities)?;
        if !rebased.is_empty() {
            output.events.push(Event {
                time: t0,
                kind: "joint coordinates rebased".to_string(),
                message: format!("Cardan angles started at zero: {}", rebased.join(", ")),
            });
        }
        if explicit.tree_formulation != TreeFormulation::JointSpace {
            self.tree_solver = Some(TreeSolver::new(model, &tree, explicit.tree_formulation)?);
        } else {
            self.sparse = SparseJointSpace::new(model, &tree);
        }
        self.pdd = vec![0.0; p0.len()];
        self.p = p0;
        self.pd = pd0;
        output.statistics.reduced_system_size = match &self.tree_solver {
            Some(solver) => solver.reduced_size(),
            None => tree.free_count() + tree.cut_rows.len(),
        };
        self.tree = Some(tree);
        self.update_bodies_with_influence(t0)?;
        self.evaluate(t0, Level::Velocity)?;
        let cut_rows = self.tree.as_ref().map(|t| t.cut_rows.clone()).unwrap_or_default();
        self.loop_rank = loop_rank(&self.eq, &self.influence, &cut_rows, explicit.rank_tolerance);
        self.tree_start = t0;
        if explicit.tree_formulation == TreeFormulation::Coupled && self.loop_rank < cut_rows.len() {
            // Eq. 40's LU holds the cut multipliers with the rest: with dependent cut equations
            // it is singular (refused by the LU with rigid loops), or, with deformable bodies in
            // the loop, nearly so and solved to a wrong motion without a word (a four-bar with a
            // deformable coupler closed by a redundant revolute: its elastic coordinate -2.5e-8
            // instead of 6.4e-6 at t = 0.1 s).
            let tree = self.tree.as_ref().expect("joint-coordinate tree");
            let names: Vec<String> =
                tree.cut_joints.iter().map(|&j| format!("'{}'", model.joints[j].name)).collect();
            return Err(FlexmbdError::InvalidModel {
                item: format!("cut joints {}", names.join(", ")),
                message: format!(
                    "their {} equations have rank {} at t = {t0}: dependent (a redundant closure or a \
                     singular configuration of a loop), which formulation 'coupled' (eq. 40) cannot \
                     hold; formulation 'decoupled' (eq. 41) or 'joint-space' takes them",
                    cut_rows.len(),
                    self.loop_rank
                ),
            });
        }
        self.update_bodies(t0)?;
        self.check_represented_velocities(t0, &state.velocities)?;
        state.coordinates.copy_from_slice(&self.q);
        state.velocities.copy_from_slice(&self.qd);
        Ok(())
    }

    /// The body velocities of the joint rates (self.qd) are the `given` ones: velocities that
    /// violate the tree joints (left as given by `correct_initial_velocities` off) have no
    /// joint rates, and the least-squares rates would start the run from others without a word.
    fn check_represented_velocities(&self, t0: f64, given: &[f64]) -> Result<()> {
        let scale = 1.0 + worst(given).1;
        let change: Vec<f64> = self.qd.iter().zip(given).map(|(a, b)| a - b).collect();
        let (k, size) = worst(&change);
        if size <= REPRESENTED_VELOCITY * scale {
            return Ok(());
        }
        Err(FlexmbdError::VelocitiesOffTheTree { time: t0, item: self.model.coordinate_name(k), size })
    }

    /// Joint coordinates: the body state (q, q_dot, gamma_B and B) from self.p and self.pd.
    pub(super) fn update_bodies(&mut self, time: f64) -> Result<()> {
        if let (Some(tree), Some(_)) = (&self.tree, &self.tree_solver) {
            let st = tree.structured(self.model, time, &self.p, &self.pd)?;
            self.q.copy_from_slice(&st.coordinates);
            self.qd.copy_from_slice(&st.velocities);
            self.gamma_b.copy_from_slice(&st.gamma);
            self.structured = Some(st);
            return Ok(());
        }
        if let (Some(tree), Some(sparse)) = (&self.tree, &self.sparse) {
            let (full_p, full_pd, pdd) = tree.full_coordinates(self.model, time, &self.p, &self.pd)?;
            let (q, qd, gamma) = tree.state_with(self.q.len(), &full_p, &full_pd, &pdd);
            self.body_influence = sparse.influence(tree, &full_p);
            self.q = q;
            self.qd = qd;
            self.gamma_b = gamma;
            return Ok(());
        }
        self.update_bodies_with_influence(time)
    }

    /// Joint space of a rigid tree: the accelerations at (time, self.q, self.qd) body by body
    /// into self.pdd and self.qdd, from the body state of the last `update_bodies`. False
    /// (nothing set) where the cut joints are not regular there or have redundant equations:
    /// the dense path with the SVD of C_cut B takes over.
    pub(super) fn sparse_accelerations(&mut self, time: f64) -> Result<bool> {
        let (Some(tree), Some(sparse)) = (&self.tree, self.sparse.as_mut()) else { return Ok(false) };
        if self.loop_rank < tree.cut_rows.len() {
            return Ok(false);
        }
        self.eq.evaluate_sparse(
            self.model,
            &mut self.ws,
            time,
            &self.q,
            &self.qd,
            &self.discrete,
            Level::Acceleration,
        )?;
        if !sparse.closure(&self.ws, &self.body_influence, Some((&self.eq.gamma, &self.gamma_b))) {
            return Ok(false);
        }
        let Some(pdd) = sparse.accelerations(&self.ws, &self.body_influence, &self.eq.force, &self.gamma_b)
        else {
            return Ok(false);
        };
        sparse.body_accelerations(&self.body_influence, &self.gamma_b, &pdd, &mut self.qdd);
        self.pdd = pdd;
        Ok(true)
    }

    /// The error of a projection onto the cut joints that does not converge: the worst
    /// constraint row named. With cut equations dependent since the start, a conflict: a cut
    /// equation the tree's joints already decide, otherwise (an angle driver on the markers of
    /// a universal joint, which locks that angle; the augmented strategies name it so too).
    fn projection_diverged(&self, time: f64, iterations: usize, violation: f64, row: usize) -> FlexmbdError {
        let cut_rows = self.tree.as_ref().map_or(0, |t| t.cut_rows.len());
        if self.loop_rank < cut_rows {
            return FlexmbdError::ConflictingConstraints {
                time,
                item: self.model.constraint_name(row),
                violation,
                since: self.tree_start,
            };
        }
        FlexmbdError::NewtonDiverged {
            time,
            step_size: 0.0,
            iterations,
            residual: violation,
            item: format!("{}; joint coordinates onto the cut joints", self.model.constraint_name(row)),
        }
    }

    /// [`Self::project_joint_coordinates`] body by body for a rigid tree whose cut joints are
    /// regular (minimum-norm corrections, those of the SVD there). False where an iterate is
    /// not regular: the dense projection goes on from it.
    fn project_sparse(&mut self, time: f64, rows: &[usize]) -> Result<bool> {
        if self.sparse.is_none() || self.loop_rank < rows.len() {
            return Ok(false);
        }
        let mut iteration = ProjectionIteration::new();
        loop {
            self.update_bodies(time)?;
            self.eq.evaluate_sparse(
                self.model,
                &mut self.ws,
                time,
                &self.q,
                &self.qd,
                &self.discrete,
                Level::Velocity,
            )?;
            let sparse = self.sparse.as_mut().expect("checked above");
            if !sparse.closure(&self.ws, &self.body_influence, None) {
                self.dense_fallbacks += 1;
                return Ok(false);
            }
            let residual: Vec<f64> = rows.iter().map(|&r| self.eq.constraints[r]).collect();
            let (k, violation) = worst(&residual);
            match iteration.next(violation, self.settings.constraint_tolerance, self.settings.max_iterations)
            {
                Next::Converged => {
                    self.observed_loop_rank = rows.len();
                    let rate = sparse.cut_velocity_violation(&self.ws, &self.qd, &self.eq.rate);
                    for (x, d) in self.pd.iter_mut().zip(sparse.minimum_norm(&rate)) {
                        *x -= d;
                    }
                    self.update_bodies(time)?;
                    return Ok(true);
                }
                Next::Diverged => {
                    return Err(self.projection_diverged(time, iteration.iterations, violation, rows[k]))
                }
                Next::Iterate => {
                    for (x, d) in self.p.iter_mut().zip(sparse.minimum_norm(&residual)) {
                        *x -= d;
                    }
                    self.newton_iterations += 1;
                }
            }
        }
    }

    /// Joint coordinates: the body state with the dense influence coefficients B.
    pub(super) fn update_bodies_with_influence(&mut self, time: f64) -> Result<()> {
        if let Some(tree) = &self.tree {
            let state = tree.evaluate(self.model, time, &self.p, &self.pd)?;
            self.q = state.coordinates;
            self.qd = state.velocities;
            self.gamma_b = state.gamma;
            self.influence = state.influence;
        }
        Ok(())
    }

    /// Joint coordinates: the tree's equations of motion linearized at (time, y = [p; p_dot])
    /// for an implicit method's iteration matrix ([`TreeLinearization`]: M_t = B^T M B from one
    /// evaluation of M, the constant elastic stiffness and damping, the null space of the cut
    /// joints); without stiffness and damping ([`TreeLinearization::is_rigid`]) only the
    /// zero blocks. None for the other strategies, or when the settings ask for the Jacobian
    /// by differences.
    pub(super) fn tree_linearization(&mut self, time: f64, y: &[f64]) -> Result<Option<TreeLinearization>> {
        if self.mode != Strategy::JointCoordinates || self.settings.jacobian == IterationJacobian::Differences
        {
            return Ok(None);
        }
        let tree = self.tree.as_ref().expect("joint coordinates have a tree");
        let (stiffness, damping) = elastic_matrices(self.model, tree);
        let rigid = TreeLinearization { stiffness, damping, ..TreeLinearization::rigid(tree.free_count()) };
        if rigid.is_rigid() {
            // Without stiffness and damping the iteration does not depend on M_t.
            return Ok(Some(rigid));
        }
        self.unpack(time, y)?;
        self.update_bodies_with_influence(time)?;
        self.evaluate(time, Level::Acceleration)?;
        let tree = self.tree.as_ref().expect("joint coordinates have a tree");
        let linearization =
            TreeLinearization::new(self.model, tree, &self.eq, &self.influence, self.loop_rank).map_err(
                |e| match e {
                    FlexmbdError::SingularMatrix { context, detail, .. } => {
                        FlexmbdError::SingularMatrix { time, context, detail }
                    }
                    other => other,
                },
            )?;
        Ok(Some(linearization))
    }

    /// Joint coordinates with cut joints: projects p onto C_cut(q(p), t) = 0 and p_dot onto the
    /// cut joints' velocity constraints by Newton steps and a velocity correction that solve
    /// C_hat dx = residual through the SVD of C_hat = C_cut B ([`LoopClosure`]): with the
    /// loops' rank and the damped inverse singular values in the joint-space formulation;
    /// truncated with seed eqs. 40-41, which solve for their cut multipliers with a
    /// minimum-norm solve. The Newton iteration goes on to round-off: near a singular
    /// configuration of a loop a residual r leaves p off the branch by r / s along the
    /// vanishing singular direction (s its singular value), and the accelerations that keep
    /// that residual grow as 1 / s^3.
    pub(super) fn project_joint_coordinates(&mut self, time: f64) -> Result<()> {
        let Some(rows) = self.tree.as_ref().map(|t| t.cut_rows.clone()) else { return Ok(()) };
        if self.project_sparse(time, &rows)? {
            return Ok(());
        }
        let n = self.q.len();
        let mut iteration = ProjectionIteration::new();
        loop {
            self.update_bodies_with_influence(time)?;
            self.evaluate(time, Level::Velocity)?;
            let residual: Vec<f64> = rows.iter().map(|&r| self.eq.constraints[r]).collect();
            let (k, violation) = worst(&residual);
            let c_hat = Mat::from_fn(rows.len(), n, |a, j| self.eq.jacobian[(rows[a], j)]) * &self.influence;
            // Seed eqs. 40-41 solve for the cut multipliers with their own minimum-norm
            // solve: their projection truncates likewise.
            let closure = if self.tree_solver.is_some() {
                LoopClosure::truncated(c_hat.as_ref(), SINGULAR_VALUE_CUTOFF)
            } else {
                LoopClosure::new(c_hat.as_ref(), self.loop_rank, LOOP_DAMPING)
            }
            .map_err(|detail| self.singular(time, detail))?;
            match iteration.next(violation, self.settings.constraint_tolerance, self.settings.max_iterations)
            {
                Next::Converged => {
                    self.observed_loop_rank = closure.numerical_rank(self.settings.rank_tolerance);
                    // Velocities: C_cut (B p_dot + v_prescribed) + C_t = 0.
                    let rate: Vec<f64> =
                        rows.iter().map(|&r| self.eq.velocity_violation(r, &self.qd)).collect();
                    for (x, d) in self.pd.iter_mut().zip(closure.solve(&rate)) {
                        *x -= d;
                    }
                    return self.update_bodies(time);
                }
                Next::Diverged => {
                    return Err(self.projection_diverged(time, iteration.iterations, violation, rows[k]))
                }
                Next::Iterate => {
                    for (x, d) in self.p.iter_mut().zip(closure.solve(&residual)) {
                        *x -= d;
                    }
                    self.newton_iterations += 1;
                }
            }
        }
    }

    /// After an accepted (projected) step at `time`: a rank of C_cut B above the loops' rank
    /// (a run that started at a singular configuration of a loop) becomes the loops' rank.
    /// Returns the event.
    pub(super) fn raise_loop_rank(&mut self, time: f64) -> Option<Event> {
        if self.observed_loop_rank <= self.loop_rank {
            return None;
        }
        let before = std::mem::replace(&mut self.loop_rank, self.observed_loop_rank);
        Some(Event {
            time,
            kind: "loop rank".to_string(),
            message: format!(
                "the cut joints' equations have rank {} here, {before} before (the run started at \
                 a singular configuration of a loop): {} constrained directions from now on",
                self.loop_rank, self.loop_rank
            ),
        })
    }

    /// After an accepted step at `time`: Cardan angles of spherical and free joints restart at
    /// zero before their singularity, and the body state follows. Returns the event.
    pub(super) fn rebase_joint_coordinates(&mut self, time: f64) -> Result<Option<Event>> {
        let Some(tree) = self.tree.as_mut() else { return Ok(None) };
        let rebased = tree.rebase(self.model, &mut self.p, &mut self.pd, CARDAN_REBASE_ANGLE);
        if rebased.is_empty() {
            return Ok(None);
        }
        self.update_bodies(time)?;
        Ok(Some(Event {
            time,
            kind: "joint coordinates rebased".to_string(),
            message: format!(
                "Cardan angles restarted at zero (the middle angle passed {:.0} degrees): {}",
                CARDAN_REBASE_ANGLE.to_degrees(),
                rebased.join(", ")
            ),
        }))
    }
}
