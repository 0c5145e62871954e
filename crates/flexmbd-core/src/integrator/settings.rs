//! Settings of a simulation: time span, step size and its control, Newton's method, output.

use crate::error::{FlexmbdError, Result};
use crate::formulation::augmented::Formulation;
use crate::formulation::decoupled::TreeFormulation;
use crate::linalg::partition::PartitionMethod;
use crate::system::Model;

/// When the Newton matrix is recomputed and refactorized.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JacobianUpdate {
    /// Every iteration (full Newton).
    EveryIteration,
    /// Kept across iterations and steps while the iteration contracts fast enough and the
    /// step size is unchanged (modified Newton).
    Modified,
    /// Refactorized once at the start of every step (at the predictor) and kept for the
    /// step's iterations while they contract fast enough.
    EveryStep,
}

crate::named!(JacobianUpdate { Modified => "modified", EveryStep => "step", EveryIteration => "full" });

/// Newton's method of the implicit integrator.
#[derive(Clone, Debug)]
pub struct NewtonSettings {
    /// Iterations per step attempt.
    pub max_iterations: usize,
    /// Convergence tolerance on the Newton increment of the accelerations relative to
    /// max(1, |q_dd|_inf).
    pub tolerance: f64,
    /// Newton's tolerance relative to the step's own error (kappa in [0, 1); 0, the default:
    /// off): the iteration has also converged when its estimated error in the positions is at
    /// most this fraction of the step's local error estimate
    /// h^2 max(|beta - 1/6|, 1/12) |q_dd(n+1) - q_dd(n)|_inf (that of the error-based step
    /// control; Hairer and Wanner, Solving ODEs II, section IV.8, stop the simplified Newton
    /// iteration at kappa = 0.01-0.1 of the step's error tolerance), and its multipliers' test
    /// is loosened by the same factor; `tolerance` still applies where the step's error is
    /// smaller (a body at rest, slowly varying motion). Off by default: it overrides a
    /// `tolerance` asked for explicitly, and two formulations of one model (modal and nodal)
    /// then agree to the iteration error it allows (4e-8 m on a test beam whose tolerance
    /// gives 1e-8), not to `tolerance`'s.
    pub error_fraction: f64,
    /// Matrix update policy.
    pub jacobian: JacobianUpdate,
    /// Contraction rate above which a reused matrix is refreshed.
    pub contraction_limit: f64,
    /// Steps after which a reused matrix is refreshed at the next predictor, however well it
    /// still contracts: a fresh matrix makes the first increment a Newton step, which saves
    /// iterations on the steps that follow (3.21 -> 3.00 per step on the flexible
    /// slider-crank, 3.87 -> 2.98 on a nodal solid body).
    pub max_matrix_age: usize,
    /// The same for the iteration matrix of models with condensed deformable bodies
    /// (`linear_system::condensed`), whose elastic blocks are the exact constant A: only the coupling
    /// with the reference coordinates ages (with the rotation of the body). Its refresh takes
    /// no solve with A and costs less than a Newton iteration, and a matrix refreshed at the
    /// predictor saves most of one, so the default is every step: the nodal pendulum bars of
    /// 960 and 9,408 elastic coordinates take 2.0 instead of 2.85 Newton iterations per step
    /// once their start is past, and those of 960 to 50,700 take 10 to 20 % less time per step
    /// (`benchmarks/README.md`).
    pub condensed_matrix_age: usize,
    /// Projection of the velocities onto C_q q_dot + C_t = 0 after every step.
    pub velocity_projection: VelocityProjection,
    /// Factorization of the Newton matrix.
    pub linear_solver: LinearSolver,
}

/// Factorization of the Newton matrix.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LinearSolver {
    /// LDL^T of the symmetrized matrix for reused (modified Newton) matrices, LU for exact
    /// Newton steps (full Newton, and the retry of a failed modified step).
    Auto,
    /// Sparse LU with partial pivoting of the exact Newton matrix, always.
    Lu,
    /// LDL^T of the symmetrized, regularized matrix (quasi-definite), also for full Newton.
    Ldlt,
}

crate::named!(LinearSolver { Auto => "auto", Lu => "lu", Ldlt => "ldlt" });

/// Whether velocities are projected onto the velocity constraints (in the metric of the mass
/// matrix) and the accelerations and multipliers recomputed from seed eq. 26 after each step:
/// one more factorization and three solves per step. Needed at spectral radius 1, where the
/// index-3 method has an undamped error mode along the constraint normals; numerical
/// dissipation (spectral radius < 1) damps that mode without it, except for a start-up layer
/// of the multipliers of about 1 / (1 - spectral radius) steps, which projecting removes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VelocityProjection {
    /// Project at spectral radius 1 only.
    Auto,
    /// Always project.
    Always,
    /// Never project.
    Never,
}

crate::named!(VelocityProjection { Auto => "auto", Always => "always", Never => "never" });

impl VelocityProjection {
    /// Resolves `Auto` for a spectral radius.
    pub fn enabled(self, spectral_radius: f64) -> bool {
        match self {
            VelocityProjection::Auto => spectral_radius >= 1.0,
            VelocityProjection::Always => true,
            VelocityProjection::Never => false,
        }
    }
}

impl Default for NewtonSettings {
    fn default() -> Self {
        NewtonSettings {
            max_iterations: 12,
            tolerance: 1e-6,
            error_fraction: 0.0,
            jacobian: JacobianUpdate::Modified,
            contraction_limit: 0.25,
            max_matrix_age: 5,
            condensed_matrix_age: 1,
            velocity_projection: VelocityProjection::Auto,
            linear_solver: LinearSolver::Auto,
        }
    }
}

/// Names of the step-size controls: "newton" ([`StepControl::Newton`]), "fixed" and "error".
pub const STEP_CONTROL_NAMES: [&str; 3] = ["newton", "fixed", "error"];

/// Step-size control.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StepControl {
    /// Constant step; a failed Newton iteration is an error.
    Fixed,
    /// Newton-based: a step whose iteration diverges or contracts too slowly to converge is
    /// retried with a quarter to a half of the step (by its contraction rate), and the step
    /// grows back (up to doubling) to the nominal one after steps that converge fast
    /// (`generalized_alpha::run`).
    Newton,
    /// Error-based: local error estimate h^2 |beta - 1/6| |q_dd(n+1) - q_dd(n)| in a weighted
    /// norm with these tolerances; steps with error > 1 are rejected.
    Error {
        /// Relative tolerance.
        relative_tolerance: f64,
        /// Absolute tolerance.
        absolute_tolerance: f64,
    },
}

impl StepControl {
    /// Default (relative, absolute) tolerances of the error-based control.
    pub const DEFAULT_ERROR_TOLERANCES: (f64, f64) = (1e-6, 1e-8);

    /// Name in settings ([`STEP_CONTROL_NAMES`]).
    pub fn name(&self) -> &'static str {
        match self {
            StepControl::Newton => "newton",
            StepControl::Fixed => "fixed",
            StepControl::Error { .. } => "error",
        }
    }
}

/// The time integrator.
#[derive(Clone, Debug, Default)]
pub enum Integrator {
    /// Implicit index-3 generalized-alpha on the augmented equations (sparse, all model sizes).
    #[default]
    GeneralizedAlpha,
    /// Explicit Runge-Kutta with one of the seed's three strategies (dense, small models).
    Explicit(ExplicitSettings),
}

/// All settings of `simulate`.
#[derive(Clone, Debug)]
pub struct SimulationSettings {
    /// Start time (s).
    pub start_time: f64,
    /// End time (s).
    pub end_time: f64,
    /// Nominal (initial) step size (s).
    pub step_size: f64,
    /// Smallest step size before giving up (s).
    pub min_step_size: f64,
    /// Largest step size (s); error control may grow the step up to it.
    pub max_step_size: f64,
    /// Output every this many seconds (steps land on these times); None: every step.
    pub output_interval: Option<f64>,
    /// Spectral radius at infinite frequency of generalized-alpha, in [0, 1].
    pub spectral_radius: f64,
    /// Newton's method.
    pub newton: NewtonSettings,
    /// Step-size control.
    pub step_control: StepControl,
    /// Initial conditions.
    pub initial: InitialSettings,
    /// Coordinates and velocities to start from instead of the model's initial ones (a state
    /// of equilibrium, or the last state of another run); None: the model's.
    pub start: Option<StartState>,
    /// The integrator.
    pub integrator: Integrator,
    /// Redundant constraints.
    pub redundancy: RedundancySettings,
}

impl SimulationSettings {
    /// Settings with defaults for everything but the time span and step.
    pub fn new(end_time: f64, step_size: f64) -> Self {
        SimulationSettings {
            start_time: 0.0,
            end_time,
            step_size,
            min_step_size: step_size * 1e-6,
            max_step_size: step_size,
            output_interval: None,
            spectral_radius: 0.9,
            newton: NewtonSettings::default(),
            step_control: StepControl::Newton,
            initial: InitialSettings::default(),
            start: None,
            integrator: Integrator::GeneralizedAlpha,
            redundancy: RedundancySettings::default(),
        }
    }

    /// Whether the run continues another from its last state (the start state has a time):
    /// that state was recorded by the other run and is not recorded again.
    pub fn continues(&self) -> bool {
        self.start.as_ref().is_some_and(|s| s.time.is_some())
    }

    /// The smallest step the time loops take: the minimum step size, and at least 64
    /// round-offs of the times of the run (a smaller step would not advance the time, and a
    /// loop of them would never end).
    pub fn step_floor(&self) -> f64 {
        let scale = self.start_time.abs().max(self.end_time.abs()).max(self.end_time - self.start_time);
        self.min_step_size.max(64.0 * f64::EPSILON * scale)
    }

    /// Checks the settings.
    pub fn validate(&self) -> Result<()> {
        let bad = |message: String| {
            Err(FlexmbdError::InvalidParameter { item: "simulation settings".to_string(), message })
        };
        let item = "simulation settings";
        let finite = [
            ("start time", self.start_time),
            ("end time", self.end_time),
            ("step size", self.step_size),
            ("minimum step size", self.min_step_size),
            ("maximum step size", self.max_step_size),
        ];
        if let Some((name, value)) = finite.iter().find(|(_, x)| !x.is_finite()) {
            return bad(format!("{name} must be finite, got {value}"));
        }
        if self.end_time < self.start_time {
            return bad(format!("end time {:e} is before start time {:e}", self.end_time, self.start_time));
        }
        if !(self.step_size > 0.0) || !(self.min_step_size > 0.0) || self.min_step_size > self.step_size {
            return bad(format!(
                "step size must be positive and at least the minimum step size (step {:e}, minimum {:e})",
                self.step_size, self.min_step_size
            ));
        }
        if self.step_size < 64.0 * f64::EPSILON * self.start_time.abs().max(self.end_time.abs()) {
            return bad(format!(
                "step size {:e} is below the round-off of the times of the run (t up to {:e}): \
                 a step would not advance the time",
                self.step_size,
                self.start_time.abs().max(self.end_time.abs())
            ));
        }
        if self.max_step_size < self.step_size {
            return bad(format!(
                "maximum step size {:e} is below the step size {:e}",
                self.max_step_size, self.step_size
            ));
        }
        if let Some(dt) = self.output_interval {
            if !(dt.is_finite() && dt > 0.0) {
                return bad(format!("output interval must be positive, got {dt}"));
            }
            let resolution = 2e-12 * (1.0 + self.end_time.abs());
            if dt <= resolution {
                return bad(format!(
                    "output interval {dt:e} is below the time resolution {resolution:e} of the run"
                ));
            }
            if dt < self.min_step_size {
                return bad(format!(
                    "output interval {dt:e} is below the minimum step size {:e}: the steps land \
                     on the output times",
                    self.min_step_size
                ));
            }
        }
        if self.newton.max_iterations == 0 {
            return bad("Newton needs at least one iteration (max_iterations 0)".to_string());
        }
        positive(item, "newton tolerance", self.newton.tolerance, 0.0)?;
        if !(0.0..1.0).contains(&self.newton.error_fraction) {
            return bad(format!(
                "Newton error fraction must be in [0, 1), got {}",
                self.newton.error_fraction
            ));
        }
        if !(self.redundancy.tolerance > 0.0 && self.redundancy.tolerance < 1.0) {
            return bad(format!("rank tolerance must be in (0, 1), got {:e}", self.redundancy.tolerance));
        }
        if let StepControl::Error { relative_tolerance, absolute_tolerance } = self.step_control {
            positive(item, "relative tolerance", relative_tolerance, 0.0)?;
            positive(item, "absolute tolerance", absolute_tolerance, 0.0)?;
        }
        Ok(())
    }
}

/// Checks that the setting `name` of `item` is a finite number above `floor`.
fn positive(item: &str, name: &str, value: f64, floor: f64) -> Result<()> {
    if value.is_finite() && value > floor {
        return Ok(());
    }
    Err(FlexmbdError::InvalidParameter {
        item: item.to_string(),
        message: format!("{name} must be a finite number > {floor}, got {value:e}"),
    })
}

// Explicit solvers -----------------------------------------------------------------------

/// Largest number of coordinates the (dense) explicit solvers accept.
pub const EXPLICIT_COORDINATE_LIMIT: usize = 2000;

/// The explicit integration method.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExplicitMethod {
    /// Classical Runge-Kutta of order 4, fixed step.
    Rk4,
    /// Dormand-Prince 5(4), error-controlled step.
    Dopri5,
    /// TR-BDF2, implicit (L-stable, second order), error-controlled step: for stiff
    /// deformable bodies.
    TrBdf2,
}

crate::named!(ExplicitMethod { Dopri5 => "dopri5", Rk4 => "rk4", TrBdf2 => "tr-bdf2" });

impl ExplicitMethod {
    /// Whether the method controls its error (Dormand-Prince, TR-BDF2: the step size given is
    /// only the first) or takes fixed steps (RK4).
    pub fn adaptive(self) -> bool {
        self != ExplicitMethod::Rk4
    }
}

/// The seed's strategies for the constrained equations.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Strategy {
    /// (1) Integrate all accelerations, dependent and independent.
    IntegrateAll,
    /// (2) Wehage's generalized coordinate partitioning.
    CoordinatePartitioning,
    /// (3) Integrate all, then project onto the position and velocity constraints.
    Projection,
    /// Joint coordinates (seed section 5): integrate the joint coordinates of an open tree;
    /// the body coordinates follow from them and satisfy the joints exactly.
    JointCoordinates,
}

crate::named!(Strategy {
    IntegrateAll => "integrate-all",
    CoordinatePartitioning => "partitioning",
    Projection => "projection",
    JointCoordinates => "joint-coordinates",
});

/// How TR-BDF2 forms the Jacobian of its iteration matrix.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IterationJacobian {
    /// In joint coordinates from the tree's linearized equations of motion (the mass matrix
    /// in joint and elastic coordinates, the elastic stiffness and damping), by forward
    /// differences of the right-hand side for the other strategies.
    Analytic,
    /// By forward differences of the right-hand side (one evaluation per integrated
    /// component), for every strategy: a check of the analytic one.
    Differences,
}

crate::named!(IterationJacobian { Analytic => "analytic", Differences => "differences" });

/// Settings of the explicit solvers.
#[derive(Clone, Debug)]
pub struct ExplicitSettings {
    /// Integration method.
    pub method: ExplicitMethod,
    /// Strategy for the constraints.
    pub strategy: Strategy,
    /// How the accelerations are solved for.
    pub formulation: Formulation,
    /// Joint coordinates: which system gives the accelerations (B^T M B, seed eq. 40 or 41).
    pub tree_formulation: TreeFormulation,
    /// Joint coordinates: the joints to cut (indices); None cuts every loop closure and
    /// every joint of a type the tree does not take.
    pub cut_joints: Option<Vec<usize>>,
    /// Decomposition that chooses the partition.
    pub partition: PartitionMethod,
    /// Independent coordinates given by the user (indices); None: chosen by `partition`.
    pub independent: Option<Vec<usize>>,
    /// Baumgarte stabilization (alpha, beta) of strategy (1).
    pub baumgarte: Option<(f64, f64)>,
    /// Relative tolerance of the error control (Dormand-Prince, TR-BDF2).
    pub relative_tolerance: f64,
    /// Absolute tolerance of the error control (Dormand-Prince, TR-BDF2).
    pub absolute_tolerance: f64,
    /// Tolerance on |C| of the dependent-coordinate Newton iteration and of the projection.
    pub constraint_tolerance: f64,
    /// Iterations of those Newton iterations.
    pub max_iterations: usize,
    /// After every step the decomposition proposes a partition at the new state; it replaces
    /// the current one when its condition (`Partition::condition`) is this factor smaller.
    pub repartition_ratio: f64,
    /// Relative tolerance of rank decisions.
    pub rank_tolerance: f64,
    /// A configuration counts as singular where even the best partition's condition exceeds
    /// this factor times the condition of the partition at the start: there the embedding
    /// uses an SVD null-space basis, coordinate partitioning takes projection steps.
    pub singular_factor: f64,
    /// Constraint violation at which the drift of strategy (1) is reported as an event.
    pub drift_threshold: f64,
    /// TR-BDF2: how the Jacobian of the iteration matrix is formed.
    pub jacobian: IterationJacobian,
}

impl Default for ExplicitSettings {
    fn default() -> Self {
        ExplicitSettings {
            method: ExplicitMethod::Dopri5,
            strategy: Strategy::CoordinatePartitioning,
            formulation: Formulation::Augmented,
            tree_formulation: TreeFormulation::JointSpace,
            cut_joints: None,
            partition: PartitionMethod::Lu,
            independent: None,
            baumgarte: None,
            relative_tolerance: 1e-8,
            absolute_tolerance: 1e-10,
            constraint_tolerance: 1e-12,
            max_iterations: 20,
            repartition_ratio: 2.0,
            rank_tolerance: crate::linalg::partition::DEFAULT_RANK_TOLERANCE,
            singular_factor: 4.0,
            drift_threshold: 1e-6,
            jacobian: IterationJacobian::Analytic,
        }
    }
}

impl ExplicitSettings {
    /// Checks the settings against the model.
    pub fn validate(&self, model: &Model) -> Result<()> {
        let bad = |message: String| {
            Err(FlexmbdError::InvalidParameter { item: "explicit solver settings".to_string(), message })
        };
        let structured = self.strategy == Strategy::JointCoordinates
            && self.tree_formulation != TreeFormulation::JointSpace;
        if self.tree_formulation != TreeFormulation::JointSpace && self.strategy != Strategy::JointCoordinates
        {
            return bad(format!(
                "the '{}' formulation is one of the joint-coordinate strategy, not of '{}'",
                self.tree_formulation.name(),
                self.strategy.name()
            ));
        }
        if model.coordinate_count > EXPLICIT_COORDINATE_LIMIT && !structured {
            let largest = model.bodies.iter().max_by_key(|b| b.dofs.len()).map(|b| b.name.clone());
            return bad(format!(
                "the explicit solvers use dense linear algebra and support models of up to \
                 {EXPLICIT_COORDINATE_LIMIT} coordinates; this model has {} (largest body '{}'). \
                 Use generalized-alpha, whose sparse and condensed solves handle large deformable bodies, \
                 or joint coordinates with the 'coupled' or 'decoupled' formulation (trees)",
                model.coordinate_count,
                largest.unwrap_or_default()
            ));
        }
        if self.baumgarte.is_some() && self.strategy != Strategy::IntegrateAll {
            return bad(format!(
                "Baumgarte stabilization applies to strategy 'integrate-all', not '{}' (which keeps \
                 the constraints by Newton iterations or projections)",
                self.strategy.name()
            ));
        }
        if let Some((alpha, beta)) = self.baumgarte {
            if !(alpha >= 0.0 && beta >= 0.0 && alpha.is_finite() && beta.is_finite()) {
                return bad(format!(
                    "Baumgarte parameters must be finite and non-negative, got ({alpha}, {beta})"
                ));
            }
        }
        let item = "explicit solver settings";
        positive(item, "relative tolerance", self.relative_tolerance, 0.0)?;
        positive(item, "absolute tolerance", self.absolute_tolerance, 0.0)?;
        positive(item, "constraint tolerance", self.constraint_tolerance, 0.0)?;
        positive(item, "repartition ratio", self.repartition_ratio, 1.0)?;
        positive(item, "rank tolerance", self.rank_tolerance, 0.0)?;
        positive(item, "drift threshold", self.drift_threshold, 0.0)?;
        positive(item, "singular factor", self.singular_factor, 1.0)?;
        if self.max_iterations == 0 {
            return bad("at least one Newton iteration is needed".to_string());
        }
        Ok(())
    }

    /// Whether the run uses the partition's coordinates (not only its rows).
    pub(crate) fn uses_coordinates(&self) -> bool {
        self.strategy == Strategy::CoordinatePartitioning
            || (self.formulation == Formulation::Embedding && self.strategy != Strategy::JointCoordinates)
    }
}

// Initial conditions ----------------------------------------------------------------------

/// Settings of the initial-condition solve.
#[derive(Clone, Debug)]
pub struct InitialSettings {
    /// Largest constraint violation accepted (m or dimensionless).
    pub tolerance: f64,
    /// Newton iterations for the positions.
    pub max_iterations: usize,
    /// Correct the positions (else they must already satisfy the constraints).
    pub correct_positions: bool,
    /// Correct the velocities.
    pub correct_velocities: bool,
    /// A coordinate or velocity moved by more than this times max(1, |value|) is reported as
    /// an "initial correction" event (the default Newton tolerance of the integrator).
    pub report_tolerance: f64,
    /// Refuse (`InitialCorrectionRefused`) instead of reporting such a correction.
    pub strict: bool,
}

impl Default for InitialSettings {
    fn default() -> Self {
        InitialSettings {
            tolerance: 1e-11,
            max_iterations: 50,
            correct_positions: true,
            correct_velocities: true,
            report_tolerance: 1e-6,
            strict: false,
        }
    }
}

/// Coordinates and velocities to start a run from (seed eq. 19 need not hold exactly: the
/// initial-condition solve makes them consistent, and reports what it moved).
#[derive(Clone, Debug, PartialEq)]
pub struct StartState {
    /// q (coordinate_count).
    pub coordinates: Vec<f64>,
    /// q_dot (coordinate_count).
    pub velocities: Vec<f64>,
    /// Time of the state, if later than the start time: the run continues another from
    /// there, on the output times of the start time's grid. None: the start time.
    pub time: Option<f64>,
    /// Discrete variables (the unwrapped spring angles) of a continued run; None: set from
    /// the coordinates.
    pub discrete: Option<Vec<f64>>,
    /// A state recorded by a run (`Result.state()`): its velocities are the integrator's,
    /// which satisfy the velocity constraints only to the step's error (generalized-alpha
    /// enforces the positions; strategies that integrate every coordinate let the positions
    /// drift too). Their projection onto the constraints is then a "continuation" event,
    /// neither an initial correction nor refused by strict settings.
    pub recorded: bool,
}

// Redundant constraints -------------------------------------------------------------------

/// What is done with redundant constraints.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RedundancyHandling {
    /// Remove them; their multipliers are zero.
    Remove,
    /// Remove them for the integration; report the minimum-norm multipliers of all rows.
    MinimumNorm,
    /// Stop with an error that lists them.
    Error,
}

crate::named!(RedundancyHandling { Remove => "remove", MinimumNorm => "minimum-norm", Error => "error" });

/// Settings of the redundancy analysis.
#[derive(Clone, Copy, Debug)]
pub struct RedundancySettings {
    /// Handling.
    pub handling: RedundancyHandling,
    /// Relative tolerance of the rank decision.
    pub tolerance: f64,
}

impl Default for RedundancySettings {
    fn default() -> Self {
        RedundancySettings { handling: RedundancyHandling::Remove, tolerance: 1e-9 }
    }
}
