//! Solver settings and `simulate`, which runs with the GIL released. Python callbacks take
//! the GIL back when they run; Ctrl-C is checked about ten times a second and stops the run
//! cleanly, keeping the results computed so far.

use std::time::{Duration, Instant};

use crate::ids::JointId;
use flexmbd_core::formulation::augmented::Formulation;
use flexmbd_core::formulation::decoupled::TreeFormulation;
use flexmbd_core::integrator::settings::{
    ExplicitMethod, ExplicitSettings, InitialSettings, IterationJacobian, RedundancyHandling,
    RedundancySettings, StartState, Strategy, STEP_CONTROL_NAMES,
};
use flexmbd_core::integrator::{
    simulate as core_simulate, Integrator, JacobianUpdate, LinearSolver, NewtonSettings, SimulationSettings,
    StepControl, VelocityProjection,
};
use flexmbd_core::linalg::partition::PartitionMethod;
use flexmbd_core::output::Output;
use flexmbd_core::FlexmbdError;
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray1};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::errors::{above, integer_argument, invalid, shown, stash_callback_error, to_exception};
use crate::model::Model;

/// Implicit index-3 generalized-alpha integrator (Arnold and Bruls 2007) for the augmented
/// equations (seed eqs. 19-26), with sparse Newton matrix and analytic Jacobians.
///
/// - `spectral_radius` in [0, 1]: numerical dissipation at high frequencies (1: none). At
///   exactly 1 (the trapezoidal rule, whose index-3 form has an undamped error mode) the
///   velocities are projected onto the velocity constraints and the accelerations made
///   consistent after every step (see `velocity_projection`).
/// - `newton_tolerance`: tolerance on the Newton increment of the accelerations, relative to
///   max(1, |q_dd|).
/// - `newton_error_fraction` (kappa in [0, 1), default 0: off): Newton's iteration has also
///   converged when its estimated error in the positions is at most kappa times the step's
///   local error estimate h^2 max(|beta - 1/6|, 1/12) |q_dd(n+1) - q_dd(n)|_inf (Hairer and
///   Wanner's stopping rule, kappa = 0.01-0.1): fewer iterations where the step's own error is
///   far above `newton_tolerance` (soft bodies), at that fraction of the step's error.
/// - `jacobian`: "modified" (keep the factorized Newton matrix across iterations and steps
///   while it contracts well), "step" (refactorize once per step, at the predictor) or
///   "full" (refactorize every iteration).
/// - `step_control`: "newton" (retry steps whose Newton iteration diverges or contracts too
///   slowly with a quarter to a half of the step, grow back to the nominal step after fast
///   iterations), "fixed" (a failed step is an error), or "error" (local error
///   estimate with `relative_tolerance` and `absolute_tolerance`, steps up to
///   `max_step_size`).
/// - `velocity_projection`: "auto" (at spectral radius 1 only), "always" or "never". Projecting
///   costs one more factorization per step and removes the start-up layer of the multipliers
///   (reaction forces accurate from the first step).
/// - `linear_solver`: "auto" (LDL^T of the symmetrized matrix for modified Newton, LU of the
///   exact matrix for full Newton and for retrying a failed step), "lu" or "ldlt".
/// - `initial_tolerance`, `correct_initial_positions`, `correct_initial_velocities`: the
///   consistent initial conditions (minimum-norm corrections onto the constraints).
#[pyclass(module = "flexmbd._core", subclass, get_all, set_all, from_py_object)]
#[derive(Clone)]
pub struct GeneralizedAlpha {
    /// Spectral radius at infinite frequency.
    pub spectral_radius: f64,
    /// Newton tolerance.
    pub newton_tolerance: f64,
    /// Newton's tolerance as a fraction of the step's local error (0: off).
    pub newton_error_fraction: f64,
    /// Newton iterations per attempt.
    pub max_iterations: usize,
    /// "modified", "step" or "full".
    pub jacobian: String,
    /// "newton", "fixed" or "error".
    pub step_control: String,
    /// Relative tolerance of error control.
    pub relative_tolerance: f64,
    /// Absolute tolerance of error control.
    pub absolute_tolerance: f64,
    /// Smallest step size (default: 1e-6 of the step size).
    pub min_step_size: Option<f64>,
    /// Largest step size (default: the step size).
    pub max_step_size: Option<f64>,
    /// "auto", "always" or "never".
    pub velocity_projection: String,
    /// "auto", "lu" or "ldlt".
    pub linear_solver: String,
    /// Largest constraint violation accepted at the start.
    pub initial_tolerance: f64,
    /// Correct inconsistent initial positions.
    pub correct_initial_positions: bool,
    /// Correct inconsistent initial velocities.
    pub correct_initial_velocities: bool,
    /// "remove", "minimum-norm" or "error".
    pub redundant_constraints: String,
    /// Relative tolerance of the rank decision for redundant constraints.
    pub rank_tolerance: f64,
}

#[pymethods]
impl GeneralizedAlpha {
    /// Every setting left out (or None) takes the core's default (`GeneralizedAlpha()` shows
    /// them all).
    #[new]
    #[pyo3(signature = (spectral_radius = None, *, newton_tolerance = None, newton_error_fraction = None, max_iterations = None, jacobian = None,
                        step_control = None, relative_tolerance = None, absolute_tolerance = None,
                        min_step_size = None, max_step_size = None, velocity_projection = None, linear_solver = None,
                        initial_tolerance = None, correct_initial_positions = None, correct_initial_velocities = None,
                        redundant_constraints = None, rank_tolerance = None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        spectral_radius: Option<f64>,
        newton_tolerance: Option<f64>,
        newton_error_fraction: Option<f64>,
        max_iterations: Option<&Bound<'_, PyAny>>,
        jacobian: Option<String>,
        step_control: Option<String>,
        relative_tolerance: Option<f64>,
        absolute_tolerance: Option<f64>,
        min_step_size: Option<f64>,
        max_step_size: Option<f64>,
        velocity_projection: Option<String>,
        linear_solver: Option<String>,
        initial_tolerance: Option<f64>,
        correct_initial_positions: Option<bool>,
        correct_initial_velocities: Option<bool>,
        redundant_constraints: Option<String>,
        rank_tolerance: Option<f64>,
    ) -> PyResult<Self> {
        let d = GeneralizedAlpha::default();
        let given = [
            ("relative_tolerance", relative_tolerance.is_some()),
            ("absolute_tolerance", absolute_tolerance.is_some()),
            ("max_step_size", max_step_size.is_some()),
            ("min_step_size", min_step_size.is_some()),
        ];
        let s = GeneralizedAlpha {
            spectral_radius: spectral_radius.unwrap_or(d.spectral_radius),
            newton_tolerance: newton_tolerance.unwrap_or(d.newton_tolerance),
            newton_error_fraction: newton_error_fraction.unwrap_or(d.newton_error_fraction),
            max_iterations: max_iterations
                .map_or(Ok(d.max_iterations), |v| integer_argument(v, "max_iterations", 1))?,
            jacobian: jacobian.unwrap_or(d.jacobian),
            step_control: step_control.unwrap_or(d.step_control),
            relative_tolerance: relative_tolerance.unwrap_or(d.relative_tolerance),
            absolute_tolerance: absolute_tolerance.unwrap_or(d.absolute_tolerance),
            min_step_size,
            max_step_size,
            velocity_projection: velocity_projection.unwrap_or(d.velocity_projection),
            linear_solver: linear_solver.unwrap_or(d.linear_solver),
            initial_tolerance: initial_tolerance.unwrap_or(d.initial_tolerance),
            correct_initial_positions: correct_initial_positions.unwrap_or(d.correct_initial_positions),
            correct_initial_velocities: correct_initial_velocities.unwrap_or(d.correct_initial_velocities),
            redundant_constraints: redundant_constraints.unwrap_or(d.redundant_constraints),
            rank_tolerance: rank_tolerance.unwrap_or(d.rank_tolerance),
        };
        // The settings are checked here without a run's step size: a step within the bounds
        // given (a largest step below an assumed 1 ms was refused before any run).
        s.settings(1.0, s.min_step_size.or(s.max_step_size).unwrap_or(1e-3))?;
        if let Some(detail) = ignored_alpha_option(&s.step_control, &given) {
            return Err(invalid("GeneralizedAlpha", detail));
        }
        Ok(s)
    }

    /// The names each choice setting takes (`jacobian`, `step_control`, ...), from the core.
    #[staticmethod]
    fn choices<'py>(py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("jacobian", names(JacobianUpdate::NAMES))?;
        d.set_item("step_control", STEP_CONTROL_NAMES.to_vec())?;
        d.set_item("velocity_projection", names(VelocityProjection::NAMES))?;
        d.set_item("linear_solver", names(LinearSolver::NAMES))?;
        d.set_item("redundant_constraints", names(RedundancyHandling::NAMES))?;
        Ok(d)
    }

    fn __repr__(&self) -> String {
        format!(
            "GeneralizedAlpha(spectral_radius={}, newton_tolerance={:e}, jacobian='{}', step_control='{}')",
            self.spectral_radius, self.newton_tolerance, self.jacobian, self.step_control
        )
    }
}

#[pymethods]
impl GeneralizedAlpha {
    /// Pickling and copying: made again from all its settings, as keywords.
    fn __getnewargs_ex__<'py>(&self, py: Python<'py>) -> PyResult<((), Bound<'py, PyDict>)> {
        let d = PyDict::new(py);
        d.set_item("spectral_radius", self.spectral_radius)?;
        d.set_item("newton_tolerance", self.newton_tolerance)?;
        d.set_item("newton_error_fraction", self.newton_error_fraction)?;
        d.set_item("max_iterations", self.max_iterations)?;
        d.set_item("jacobian", self.jacobian.clone())?;
        d.set_item("step_control", self.step_control.clone())?;
        d.set_item("relative_tolerance", self.relative_tolerance)?;
        d.set_item("absolute_tolerance", self.absolute_tolerance)?;
        d.set_item("min_step_size", self.min_step_size)?;
        d.set_item("max_step_size", self.max_step_size)?;
        d.set_item("velocity_projection", self.velocity_projection.clone())?;
        d.set_item("linear_solver", self.linear_solver.clone())?;
        d.set_item("initial_tolerance", self.initial_tolerance)?;
        d.set_item("correct_initial_positions", self.correct_initial_positions)?;
        d.set_item("correct_initial_velocities", self.correct_initial_velocities)?;
        d.set_item("redundant_constraints", self.redundant_constraints.clone())?;
        d.set_item("rank_tolerance", self.rank_tolerance)?;
        // Options the step control ignores (set as attributes after construction) are left
        // out: the constructor would refuse them.
        for name in ["relative_tolerance", "absolute_tolerance", "max_step_size", "min_step_size"] {
            if ignored_alpha_option(&self.step_control, &[(name, true)]).is_some() {
                d.del_item(name)?;
            }
        }
        Ok(((), d))
    }
}

/// Why an option given to `GeneralizedAlpha(...)` would do nothing under `step_control`
/// (`given`: option name, whether given), or None: the error control's tolerances and
/// largest step under Newton's or a fixed control (whose steps return to the step size, the
/// largest they take), the smallest step under a fixed control (which never shortens one).
fn ignored_alpha_option(step_control: &str, given: &[(&str, bool)]) -> Option<String> {
    let is_given = |name: &str| given.iter().any(|&(n, g)| n == name && g);
    for name in ["relative_tolerance", "absolute_tolerance", "max_step_size"] {
        if step_control != "error" && is_given(name) {
            return Some(format!(
                "{name} is for step_control='error'; under '{step_control}' the steps return to \
                 the step size, which is also the largest they take"
            ));
        }
    }
    if step_control == "fixed" && is_given("min_step_size") {
        return Some(
            "min_step_size is for the step controls that shorten steps ('newton', 'error'); \
             'fixed' keeps the step size"
                .to_string(),
        );
    }
    None
}

impl Default for GeneralizedAlpha {
    /// The core's defaults (`SimulationSettings::new`).
    fn default() -> Self {
        let s = SimulationSettings::new(1.0, 1.0);
        let (relative_tolerance, absolute_tolerance) = StepControl::DEFAULT_ERROR_TOLERANCES;
        GeneralizedAlpha {
            spectral_radius: s.spectral_radius,
            newton_tolerance: s.newton.tolerance,
            newton_error_fraction: s.newton.error_fraction,
            max_iterations: s.newton.max_iterations,
            jacobian: s.newton.jacobian.name().to_string(),
            step_control: s.step_control.name().to_string(),
            relative_tolerance,
            absolute_tolerance,
            min_step_size: None,
            max_step_size: None,
            velocity_projection: s.newton.velocity_projection.name().to_string(),
            linear_solver: s.newton.linear_solver.name().to_string(),
            initial_tolerance: s.initial.tolerance,
            correct_initial_positions: s.initial.correct_positions,
            correct_initial_velocities: s.initial.correct_velocities,
            redundant_constraints: s.redundancy.handling.name().to_string(),
            rank_tolerance: s.redundancy.tolerance,
        }
    }
}

impl GeneralizedAlpha {
    fn settings(&self, end_time: f64, step_size: f64) -> PyResult<SimulationSettings> {
        let item = "GeneralizedAlpha";
        if !(0.0..=1.0).contains(&self.spectral_radius) {
            return Err(invalid(
                item,
                format!("spectral_radius must be in [0, 1], got {}", shown(self.spectral_radius)),
            ));
        }
        above(item, "newton_tolerance", self.newton_tolerance, 0.0)?;
        if !(0.0..1.0).contains(&self.newton_error_fraction) {
            return Err(invalid(
                item,
                format!("newton_error_fraction must be in [0, 1), got {}", shown(self.newton_error_fraction)),
            ));
        }
        above(item, "relative_tolerance", self.relative_tolerance, 0.0)?;
        above(item, "absolute_tolerance", self.absolute_tolerance, 0.0)?;
        above(item, "initial_tolerance", self.initial_tolerance, 0.0)?;
        step_bounds(item, self.min_step_size, self.max_step_size)?;
        let jacobian = choice(item, "jacobian", &self.jacobian, JacobianUpdate::NAMES)?;
        let velocity_projection =
            choice(item, "velocity_projection", &self.velocity_projection, VelocityProjection::NAMES)?;
        let linear_solver = choice(item, "linear_solver", &self.linear_solver, LinearSolver::NAMES)?;
        let step_control = match self.step_control.as_str() {
            "newton" => StepControl::Newton,
            "fixed" => StepControl::Fixed,
            "error" => StepControl::Error {
                relative_tolerance: self.relative_tolerance,
                absolute_tolerance: self.absolute_tolerance,
            },
            other => return Err(unknown_choice(item, "step_control", other, &STEP_CONTROL_NAMES)),
        };
        let mut s = SimulationSettings::new(end_time, step_size);
        s.spectral_radius = self.spectral_radius;
        s.newton = NewtonSettings {
            max_iterations: self.max_iterations,
            tolerance: self.newton_tolerance,
            error_fraction: self.newton_error_fraction,
            jacobian,
            velocity_projection,
            linear_solver,
            ..NewtonSettings::default()
        };
        s.step_control = step_control;
        if let Some(h) = self.min_step_size {
            s.min_step_size = h;
        }
        // Under the error control the step size is only the first step: a largest step below
        // it caps the first one too. Newton's control and fixed steps return to the step size
        // (a largest step below it was ignored without a word).
        s.max_step_size = match self.max_step_size {
            Some(max) if max < step_size && matches!(step_control, StepControl::Error { .. }) => {
                s.step_size = max;
                max
            }
            Some(max) if max < step_size => {
                return Err(invalid(
                    item,
                    format!(
                        "max_step_size {max:e} is below the step size {step_size:e}: under step_control \
                         '{}' the steps return to the step size (a smaller step size, or \
                         step_control='error')",
                        self.step_control
                    ),
                ))
            }
            Some(max) => max,
            // Under the error control the step size is only the first step (it was also the
            // largest: with rtol 1e-2 at h = 1e-4, 100,000 steps where dopri5 took 49).
            None if matches!(step_control, StepControl::Error { .. }) => f64::MAX,
            None => step_size,
        };
        s.initial = initial_settings(
            self.initial_tolerance,
            self.correct_initial_positions,
            self.correct_initial_velocities,
        );
        s.redundancy = redundancy_settings(item, &self.redundant_constraints, self.rank_tolerance)?;
        Ok(s)
    }
}

/// The optional smallest and largest step sizes: each finite and positive, the smallest not
/// above the largest.
fn step_bounds(item: &str, min_step_size: Option<f64>, max_step_size: Option<f64>) -> PyResult<()> {
    if let Some(h) = min_step_size {
        above(item, "min_step_size", h, 0.0)?;
    }
    if let Some(h) = max_step_size {
        above(item, "max_step_size", h, 0.0)?;
    }
    if let (Some(low), Some(high)) = (min_step_size, max_step_size) {
        if low > high {
            return Err(invalid(
                item,
                format!("min_step_size {} is above max_step_size {}", shown(low), shown(high)),
            ));
        }
    }
    Ok(())
}

fn initial_settings(tolerance: f64, positions: bool, velocities: bool) -> InitialSettings {
    InitialSettings {
        tolerance,
        correct_positions: positions,
        correct_velocities: velocities,
        ..InitialSettings::default()
    }
}

/// The value named `value` of the setting `name` (its table of names declared in the core).
fn choice<T: Copy>(item: &str, name: &str, value: &str, names: &[(&str, T)]) -> PyResult<T> {
    let names_only: Vec<&str> = names.iter().map(|(n, _)| *n).collect();
    names
        .iter()
        .find(|(n, _)| *n == value)
        .map(|(_, v)| *v)
        .ok_or_else(|| unknown_choice(item, name, value, &names_only))
}

/// The names of a table of the core.
fn names<T>(table: &[(&'static str, T)]) -> Vec<&'static str> {
    table.iter().map(|(n, _)| *n).collect()
}

/// The names of `ExplicitSolver.formulation`: the dense formulations, then the tree ones.
fn formulation_names() -> Vec<&'static str> {
    [names(Formulation::NAMES), names(TreeFormulation::NAMES)].concat()
}

fn unknown_choice(item: &str, name: &str, value: &str, names: &[&str]) -> PyErr {
    let list: Vec<String> = names.iter().map(|o| format!("'{o}'")).collect();
    invalid(item, format!("{name} must be one of {}, got '{value}'", list.join(", ")))
}

fn redundancy_settings(item: &str, handling: &str, tolerance: f64) -> PyResult<RedundancySettings> {
    let handling = choice(item, "redundant_constraints", handling, RedundancyHandling::NAMES)?;
    if !(tolerance > 0.0 && tolerance < 1.0) {
        return Err(invalid(item, format!("rank_tolerance must be in (0, 1), got {}", shown(tolerance))));
    }
    Ok(RedundancySettings { handling, tolerance })
}

/// Explicit Runge-Kutta integration of the constrained equations with one of the seed's three
/// strategies (section 4, "Numerical solution of the augmented equations"). Dense linear
/// algebra: for rigid and small deformable models (up to 2000 coordinates).
///
/// - `method`: "dopri5" (Dormand-Prince 5(4), error-controlled step with
///   `relative_tolerance` and `absolute_tolerance`, starting from the step size given to
///   `simulate`), "rk4" (classical Runge-Kutta, fixed step) or "tr-bdf2" (implicit, L-stable,
///   second order, error-controlled: for stiff deformable bodies).
/// - `strategy`: "integrate-all" (integrate all coordinates and velocities; the constraints
///   drift unless `baumgarte=(alpha, beta)` stabilizes them), "partitioning" (Wehage:
///   integrate the independent coordinates, solve the dependent ones by Newton-Raphson) or
///   "projection" (integrate all, then project onto the position and velocity constraints),
///   or "joint-coordinates" (seed section 5: integrate the joint and elastic coordinates of a
///   tree of rigid and deformable bodies and point masses with revolute, prismatic,
///   cylindrical, fixed, universal, spherical and free joints and drivers on them, loops closed
///   by cut joints; the tree joints hold exactly).
/// - `formulation`: "augmented" (seed eq. 26) or "embedding" (seed eqs. 27-30); with
///   "joint-coordinates": "joint-space" (the default there: (B^T M B) p_dd = B^T (f - M
///   gamma_B) with B formed, dense), "coupled" (the loosely coupled sparse system of seed eq.
///   40) or "decoupled" (seed eq. 41: the elastic accelerations eliminated with the constant
///   M_ff; its size, `statistics["reduced_system_size"]`, does not depend on the number of
///   elastic coordinates). "coupled" and "decoupled" have no model size limit.
/// - `cut_joints`: with "joint-coordinates", the joints to cut open (their equations become
///   constraints on the joint coordinates). None (default) cuts every joint that closes a loop
///   or is of a type the tree does not take; with a list, any other such joint is an error
///   naming it.
/// - `partition`: "lu" (full pivoting), "qr" (column pivoting) or "svd": how the independent
///   coordinates are chosen; `independent`: coordinate indices to use instead. The
///   coordinates are repartitioned (an event) when the decomposition proposes, after a step,
///   a partition whose dependent block is `repartition_ratio` times better conditioned.
/// - `singular_factor`: a configuration counts as singular (the constraint Jacobian near
///   rank-deficient, as at the change points of a parallelogram linkage) where even the best
///   partition's condition (|C_q|_F |C_qd^-1|_F) exceeds this factor times the condition at
///   the start: there the embedding uses an SVD null-space basis and coordinate partitioning
///   takes projection steps until the configuration is passed (reported as events).
/// - `constraint_tolerance`, `max_iterations`: the Newton iterations of the dependent
///   coordinates and of the projection.
/// - `jacobian`: how "tr-bdf2" forms the Jacobian of its Newton iteration matrix: "analytic"
///   (default: with "joint-coordinates" from the tree's mass matrix in joint and elastic
///   coordinates and the elastic stiffness and damping, the iteration matrix of the
///   coordinates' size; by forward differences for the other strategies) or "differences"
///   (forward differences of the right-hand side everywhere, one evaluation per integrated
///   component: a check).
/// - `redundant_constraints`, `rank_tolerance`, `initial_tolerance`,
///   `correct_initial_positions`, `correct_initial_velocities`: as for `GeneralizedAlpha`.
///
/// Options given that the method or strategy would not use are refused
/// (`InvalidParameterError`): tolerances with "rk4", `jacobian` without "tr-bdf2", `baumgarte`
/// or a dense formulation with "joint-coordinates".
#[pyclass(module = "flexmbd._core", subclass, get_all, set_all, from_py_object)]
#[derive(Clone)]
pub struct ExplicitSolver {
    /// "dopri5" or "rk4".
    pub method: String,
    /// "integrate-all", "partitioning", "projection" or "joint-coordinates".
    pub strategy: String,
    /// "augmented" or "embedding".
    pub formulation: String,
    /// "lu", "qr" or "svd".
    pub partition: String,
    /// Independent coordinate indices, or None.
    pub independent: Option<Vec<usize>>,
    /// Baumgarte (alpha, beta), or None.
    pub baumgarte: Option<(f64, f64)>,
    /// Relative tolerance of the error control.
    pub relative_tolerance: f64,
    /// Absolute tolerance of the error control.
    pub absolute_tolerance: f64,
    /// Tolerance on |C| of the Newton iterations.
    pub constraint_tolerance: f64,
    /// Newton iterations.
    pub max_iterations: usize,
    /// Factor by which a proposed partition must be better conditioned to replace the current.
    pub repartition_ratio: f64,
    /// Constraint violation reported as drift.
    pub drift_threshold: f64,
    /// Factor over the initial partition condition at which a configuration counts as singular.
    pub singular_factor: f64,
    /// Smallest step size (default: 1e-9 of the step size).
    pub min_step_size: Option<f64>,
    /// Largest step size (default: unbounded).
    pub max_step_size: Option<f64>,
    /// Largest constraint violation accepted at the start.
    pub initial_tolerance: f64,
    /// Correct inconsistent initial positions.
    pub correct_initial_positions: bool,
    /// Correct inconsistent initial velocities.
    pub correct_initial_velocities: bool,
    /// "remove", "minimum-norm" or "error".
    pub redundant_constraints: String,
    /// Relative tolerance of rank decisions.
    pub rank_tolerance: f64,
    /// Joint coordinates: the joints to cut, or None (every loop closure).
    pub cut_joints: Option<Vec<JointId>>,
    /// TR-BDF2: "analytic" or "differences".
    pub jacobian: String,
}

#[pymethods]
impl ExplicitSolver {
    /// Every setting left out (or None) takes the core's default (`ExplicitSolver()` shows
    /// them all); `independent`, `baumgarte`, the step bounds and `cut_joints` are off by
    /// default.
    #[new]
    #[pyo3(signature = (method = None, strategy = None, *, formulation = None, partition = None,
                        independent = None, baumgarte = None, relative_tolerance = None, absolute_tolerance = None,
                        constraint_tolerance = None, max_iterations = None, repartition_ratio = None,
                        drift_threshold = None, singular_factor = None, min_step_size = None, max_step_size = None,
                        initial_tolerance = None, correct_initial_positions = None, correct_initial_velocities = None,
                        redundant_constraints = None, rank_tolerance = None, cut_joints = None,
                        jacobian = None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        method: Option<String>,
        strategy: Option<String>,
        formulation: Option<String>,
        partition: Option<String>,
        independent: Option<Vec<usize>>,
        baumgarte: Option<(f64, f64)>,
        relative_tolerance: Option<f64>,
        absolute_tolerance: Option<f64>,
        constraint_tolerance: Option<f64>,
        max_iterations: Option<&Bound<'_, PyAny>>,
        repartition_ratio: Option<f64>,
        drift_threshold: Option<f64>,
        singular_factor: Option<f64>,
        min_step_size: Option<f64>,
        max_step_size: Option<f64>,
        initial_tolerance: Option<f64>,
        correct_initial_positions: Option<bool>,
        correct_initial_velocities: Option<bool>,
        redundant_constraints: Option<String>,
        rank_tolerance: Option<f64>,
        cut_joints: Option<Vec<JointId>>,
        jacobian: Option<String>,
    ) -> PyResult<Self> {
        let d = ExplicitSolver::default();
        let ignored = ignored_explicit_options(
            method.as_deref().unwrap_or(&d.method),
            strategy.as_deref().unwrap_or(&d.strategy),
            &[
                ("relative_tolerance", relative_tolerance.is_some()),
                ("absolute_tolerance", absolute_tolerance.is_some()),
                ("jacobian", jacobian.is_some()),
                ("baumgarte", baumgarte.is_some()),
                ("partition", partition.is_some()),
                ("independent", independent.is_some()),
                ("repartition_ratio", repartition_ratio.is_some()),
                ("singular_factor", singular_factor.is_some()),
            ],
            formulation.as_deref(),
        );
        if let Some(detail) = ignored {
            return Err(invalid("ExplicitSolver", detail));
        }
        // Joint coordinates run the joint-space formulation by default (the solver said
        // 'augmented', a value it then refused when given).
        let default_formulation = if strategy.as_deref() == Some("joint-coordinates") {
            "joint-space".to_string()
        } else {
            d.formulation.clone()
        };
        let s = ExplicitSolver {
            cut_joints,
            jacobian: jacobian.unwrap_or(d.jacobian),
            method: method.unwrap_or(d.method),
            strategy: strategy.unwrap_or(d.strategy),
            formulation: formulation.unwrap_or(default_formulation),
            partition: partition.unwrap_or(d.partition),
            independent,
            baumgarte,
            relative_tolerance: relative_tolerance.unwrap_or(d.relative_tolerance),
            absolute_tolerance: absolute_tolerance.unwrap_or(d.absolute_tolerance),
            constraint_tolerance: constraint_tolerance.unwrap_or(d.constraint_tolerance),
            max_iterations: max_iterations
                .map_or(Ok(d.max_iterations), |v| integer_argument(v, "max_iterations", 1))?,
            repartition_ratio: repartition_ratio.unwrap_or(d.repartition_ratio),
            drift_threshold: drift_threshold.unwrap_or(d.drift_threshold),
            singular_factor: singular_factor.unwrap_or(d.singular_factor),
            min_step_size,
            max_step_size,
            initial_tolerance: initial_tolerance.unwrap_or(d.initial_tolerance),
            correct_initial_positions: correct_initial_positions.unwrap_or(d.correct_initial_positions),
            correct_initial_velocities: correct_initial_velocities.unwrap_or(d.correct_initial_velocities),
            redundant_constraints: redundant_constraints.unwrap_or(d.redundant_constraints),
            rank_tolerance: rank_tolerance.unwrap_or(d.rank_tolerance),
        };
        s.settings(1.0, 1e-3)?;
        Ok(s)
    }

    /// The names each choice setting takes (`method`, `strategy`, `formulation`, ...), from
    /// the core.
    #[staticmethod]
    fn choices<'py>(py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("method", names(ExplicitMethod::NAMES))?;
        d.set_item("strategy", names(Strategy::NAMES))?;
        d.set_item("formulation", formulation_names())?;
        d.set_item("partition", names(PartitionMethod::NAMES))?;
        d.set_item("redundant_constraints", names(RedundancyHandling::NAMES))?;
        d.set_item("jacobian", names(IterationJacobian::NAMES))?;
        Ok(d)
    }

    fn __repr__(&self) -> String {
        format!(
            "ExplicitSolver(method='{}', strategy='{}', formulation='{}', partition='{}')",
            self.method, self.strategy, self.formulation, self.partition
        )
    }
}

#[pymethods]
impl ExplicitSolver {
    /// Pickling and copying: made again from all its settings, as keywords.
    fn __getnewargs_ex__<'py>(&self, py: Python<'py>) -> PyResult<((), Bound<'py, PyDict>)> {
        let d = PyDict::new(py);
        d.set_item("method", self.method.clone())?;
        d.set_item("strategy", self.strategy.clone())?;
        d.set_item("formulation", self.formulation.clone())?;
        d.set_item("partition", self.partition.clone())?;
        d.set_item("independent", self.independent.clone())?;
        d.set_item("baumgarte", self.baumgarte)?;
        d.set_item("relative_tolerance", self.relative_tolerance)?;
        d.set_item("absolute_tolerance", self.absolute_tolerance)?;
        d.set_item("constraint_tolerance", self.constraint_tolerance)?;
        d.set_item("max_iterations", self.max_iterations)?;
        d.set_item("repartition_ratio", self.repartition_ratio)?;
        d.set_item("drift_threshold", self.drift_threshold)?;
        d.set_item("singular_factor", self.singular_factor)?;
        d.set_item("min_step_size", self.min_step_size)?;
        d.set_item("max_step_size", self.max_step_size)?;
        d.set_item("initial_tolerance", self.initial_tolerance)?;
        d.set_item("correct_initial_positions", self.correct_initial_positions)?;
        d.set_item("correct_initial_velocities", self.correct_initial_velocities)?;
        d.set_item("redundant_constraints", self.redundant_constraints.clone())?;
        d.set_item("rank_tolerance", self.rank_tolerance)?;
        d.set_item("cut_joints", self.cut_joints.clone())?;
        d.set_item("jacobian", self.jacobian.clone())?;
        // Options the method or strategy ignores (values set as attributes after construction)
        // are left out: the constructor would refuse them.
        for name in [
            "relative_tolerance",
            "absolute_tolerance",
            "jacobian",
            "baumgarte",
            "partition",
            "independent",
            "repartition_ratio",
            "singular_factor",
        ] {
            if ignored_explicit_options(&self.method, &self.strategy, &[(name, true)], None).is_some() {
                d.del_item(name)?;
            }
        }
        if ignored_explicit_options(&self.method, &self.strategy, &[], Some(&self.formulation)).is_some() {
            d.del_item("formulation")?;
        }
        Ok(((), d))
    }
}

/// Why an option given to `ExplicitSolver(...)` would do nothing with the chosen `method` and
/// `strategy` (`given`: option name, whether given), or None. Checked where the constructor
/// can tell given options from defaults; an attribute set later is not checked.
fn ignored_explicit_options(
    method: &str,
    strategy: &str,
    given: &[(&str, bool)],
    formulation: Option<&str>,
) -> Option<String> {
    let is_given = |name: &str| given.iter().any(|&(n, g)| n == name && g);
    for name in ["relative_tolerance", "absolute_tolerance"] {
        if method == "rk4" && is_given(name) {
            return Some(format!(
                "{name} is for the error-controlled methods (dopri5, tr-bdf2); rk4 takes fixed steps"
            ));
        }
    }
    if method != "tr-bdf2" && is_given("jacobian") {
        return Some(format!(
            "jacobian is for tr-bdf2 (the matrix of its Newton iteration); {method} has none"
        ));
    }
    for name in ["partition", "independent", "repartition_ratio", "singular_factor"] {
        if strategy == "joint-coordinates" && is_given(name) {
            return Some(format!(
                "{name} is for the partition of the coordinates (strategies 'partitioning', \
                 'projection', 'integrate-all'); 'joint-coordinates' takes the joints' own"
            ));
        }
    }
    if strategy == "joint-coordinates" && is_given("baumgarte") {
        return Some(
            "baumgarte is for the strategies that integrate the constrained coordinates; with \
             'joint-coordinates' the tree joints hold exactly and the cut joints are projected"
                .to_string(),
        );
    }
    if let (Some(name), "joint-coordinates") = (formulation, strategy) {
        if Formulation::from_name(name).is_some() {
            return Some(format!(
                "formulation '{name}' is for the other strategies; 'joint-coordinates' takes {}",
                names(TreeFormulation::NAMES).iter().map(|n| format!("'{n}'")).collect::<Vec<_>>().join(", ")
            ));
        }
    }
    None
}

impl Default for ExplicitSolver {
    /// The core's defaults (`ExplicitSettings::default`, `InitialSettings::default`).
    fn default() -> Self {
        let e = ExplicitSettings::default();
        let initial = InitialSettings::default();
        ExplicitSolver {
            method: e.method.name().to_string(),
            strategy: e.strategy.name().to_string(),
            formulation: e.formulation.name().to_string(),
            partition: e.partition.name().to_string(),
            independent: None,
            baumgarte: None,
            relative_tolerance: e.relative_tolerance,
            absolute_tolerance: e.absolute_tolerance,
            constraint_tolerance: e.constraint_tolerance,
            max_iterations: e.max_iterations,
            repartition_ratio: e.repartition_ratio,
            drift_threshold: e.drift_threshold,
            singular_factor: e.singular_factor,
            min_step_size: None,
            max_step_size: None,
            initial_tolerance: initial.tolerance,
            correct_initial_positions: initial.correct_positions,
            correct_initial_velocities: initial.correct_velocities,
            redundant_constraints: RedundancySettings::default().handling.name().to_string(),
            rank_tolerance: e.rank_tolerance,
            cut_joints: None,
            jacobian: e.jacobian.name().to_string(),
        }
    }
}

impl ExplicitSolver {
    fn settings(&self, end_time: f64, step_size: f64) -> PyResult<SimulationSettings> {
        let item = "ExplicitSolver";
        above(item, "relative_tolerance", self.relative_tolerance, 0.0)?;
        above(item, "absolute_tolerance", self.absolute_tolerance, 0.0)?;
        above(item, "constraint_tolerance", self.constraint_tolerance, 0.0)?;
        above(item, "drift_threshold", self.drift_threshold, 0.0)?;
        above(item, "repartition_ratio", self.repartition_ratio, 1.0)?;
        above(item, "singular_factor", self.singular_factor, 1.0)?;
        above(item, "initial_tolerance", self.initial_tolerance, 0.0)?;
        step_bounds(item, self.min_step_size, self.max_step_size)?;
        let method = choice(item, "method", &self.method, ExplicitMethod::NAMES)?;
        let strategy = choice(item, "strategy", &self.strategy, Strategy::NAMES)?;
        let (formulation, tree_formulation) = match (
            Formulation::from_name(&self.formulation),
            TreeFormulation::from_name(&self.formulation),
        ) {
            (Some(formulation), _) => (formulation, TreeFormulation::JointSpace),
            (None, Some(tree)) => (Formulation::Augmented, tree),
            (None, None) => {
                return Err(unknown_choice(item, "formulation", &self.formulation, &formulation_names()))
            }
        };
        let tree_named = Formulation::from_name(&self.formulation).is_none();
        if self.cut_joints.is_some() && strategy != Strategy::JointCoordinates {
            return Err(invalid(item, "cut_joints belong to strategy 'joint-coordinates'".to_string()));
        }
        if tree_named && strategy != Strategy::JointCoordinates {
            return Err(invalid(
                item,
                format!(
                    "formulation '{}' belongs to strategy 'joint-coordinates'; the others take 'augmented' or 'embedding'",
                    self.formulation
                ),
            ));
        }
        let partition = choice(item, "partition", &self.partition, PartitionMethod::NAMES)?;
        let jacobian = choice(item, "jacobian", &self.jacobian, IterationJacobian::NAMES)?;
        let explicit = ExplicitSettings {
            method,
            strategy,
            formulation,
            tree_formulation,
            cut_joints: self.cut_joints.as_ref().map(|list| list.iter().map(|j| j.index).collect()),
            partition,
            independent: self.independent.clone(),
            baumgarte: self.baumgarte,
            relative_tolerance: self.relative_tolerance,
            absolute_tolerance: self.absolute_tolerance,
            constraint_tolerance: self.constraint_tolerance,
            max_iterations: self.max_iterations,
            repartition_ratio: self.repartition_ratio,
            rank_tolerance: self.rank_tolerance,
            drift_threshold: self.drift_threshold,
            singular_factor: self.singular_factor,
            jacobian,
        };
        let mut s = SimulationSettings::new(end_time, step_size);
        s.min_step_size = self.min_step_size.unwrap_or(step_size * 1e-9);
        s.max_step_size = match (method, self.max_step_size) {
            (ExplicitMethod::Rk4, None) => step_size,
            (ExplicitMethod::Rk4, Some(_)) => {
                return Err(invalid(
                    item,
                    "max_step_size is for the adaptive methods (dopri5, tr-bdf2); rk4 takes fixed steps \
                     of the step size"
                        .to_string(),
                ))
            }
            // The step size is only the first step: a largest step below it caps it too (it was
            // raised to the step size, the error control then switched off).
            (_, Some(max)) if max < step_size => {
                s.step_size = max;
                max
            }
            (_, max) => max.unwrap_or(f64::MAX),
        };
        s.initial = initial_settings(
            self.initial_tolerance,
            self.correct_initial_positions,
            self.correct_initial_velocities,
        );
        s.redundancy = redundancy_settings(item, &self.redundant_constraints, self.rank_tolerance)?;
        s.integrator = Integrator::Explicit(explicit);
        Ok(s)
    }
}

fn array2<'py>(py: Python<'py>, data: Vec<f64>, rows: usize, cols: usize) -> PyResult<Bound<'py, PyAny>> {
    Ok(PyArray1::from_vec(py, data).reshape([rows, cols])?.into_any())
}

fn output_dict<'py>(py: Python<'py>, out: Output) -> PyResult<Bound<'py, PyDict>> {
    let n = out.len();
    let d = PyDict::new(py);
    let width = *out.sensor_offsets.last().unwrap_or(&0);
    d.set_item("coordinates", array2(py, out.coordinates, n, out.coordinate_count)?)?;
    d.set_item("velocities", array2(py, out.velocities, n, out.coordinate_count)?)?;
    d.set_item("accelerations", array2(py, out.accelerations, n, out.coordinate_count)?)?;
    d.set_item("multipliers", array2(py, out.multipliers, n, out.constraint_count)?)?;
    d.set_item("reactions", PyArray1::from_vec(py, out.reactions).reshape([n, out.joint_count, 6])?)?;
    d.set_item("sensors", array2(py, out.sensors, n, width)?)?;
    d.set_item("energy", array2(py, out.energy, n, flexmbd_core::output::ENERGY_WIDTH)?)?;
    d.set_item("constraint_violation", PyArray1::from_vec(py, out.constraint_violation))?;
    d.set_item("discrete", array2(py, out.discrete, n, out.discrete_count)?)?;
    d.set_item("time", PyArray1::from_vec(py, out.time))?;
    d.set_item("released", out.released)?;
    let s = PyDict::new(py);
    let st = &out.statistics;
    s.set_item("steps", st.steps)?;
    s.set_item("rejected_steps", st.rejected_steps)?;
    s.set_item("newton_iterations", st.newton_iterations)?;
    s.set_item("factorizations", st.factorizations)?;
    s.set_item("min_step_size", if st.steps > 0 { st.min_step_size_used } else { f64::NAN })?;
    s.set_item("max_step_size", if st.steps > 0 { st.max_step_size_used } else { f64::NAN })?;
    s.set_item("function_evaluations", st.function_evaluations)?;
    s.set_item("jacobian_evaluations", st.jacobian_evaluations)?;
    s.set_item("reduced_system_size", st.reduced_system_size)?;
    d.set_item("statistics", s)?;
    let events = PyList::empty(py);
    for e in &out.events {
        let item = PyDict::new(py);
        item.set_item("time", e.time)?;
        item.set_item("kind", &e.kind)?;
        item.set_item("message", &e.message)?;
        events.append(item)?;
    }
    d.set_item("events", events)?;
    match &out.redundancy {
        None => d.set_item("redundancy", py.None())?,
        Some(r) => {
            let item = PyDict::new(py);
            item.set_item("time", r.time)?;
            item.set_item("rows", r.rows)?;
            item.set_item("rank", r.rank)?;
            item.set_item("removed_rows", r.removed_rows.clone())?;
            item.set_item("groups", r.groups.clone())?;
            item.set_item("joints", r.joints.clone())?;
            item.set_item("message", &r.message)?;
            d.set_item("redundancy", item)?;
        }
    }
    Ok(d)
}

/// Records held in memory at most before they go to the results file when the run keeps them
/// only there (`keep_in_memory` False): about 1 MB for a small model.
const RELEASE_BATCH: usize = 4096;

/// Runs a simulation of `model` from `start_time` to `end_time` with nominal step
/// `step_size`, recording every `output_interval` seconds (every step if None; steps land
/// on the output times). `progress(time, step_size, newton_iterations)` is called about ten
/// times a second if given; so is `records(raw_chunk)`, with the records added since its last
/// call (a dict like the raw results, with the statistics and events so far), for results
/// written during the run; with `keep_in_memory` False the records delivered to `records` are
/// dropped from memory (the raw results then hold only the later ones, and "released" says
/// how many came before them). An exception of `progress` or `records` stops the run with a
/// `CallbackError` (its `__cause__` the exception), Ctrl-C with `SimulationInterrupted`.
/// `coordinates` and `velocities` (both or neither) replace the model's initial ones, and
/// `discrete` (with them; a recorded state's) the discrete variables set from them, so a
/// run continued from a record goes on from its unwrapped angles. `initial_conditions` "correct" reports the corrections of the
/// consistent-initial-condition solve as events, "strict" refuses them. Returns
/// `(raw_results, error)`; `error` is None on success, otherwise the exception to raise (the
/// raw results then hold everything up to the failure).
#[pyfunction]
#[pyo3(signature = (model, end_time, step_size, *, start_time = 0.0, output_interval = None, solver = None, progress = None, records = None, coordinates = None, velocities = None, discrete = None, recorded = false, initial_conditions = "correct", keep_in_memory = true))]
#[allow(clippy::too_many_arguments)]
pub fn simulate<'py>(
    py: Python<'py>,
    model: &Model,
    end_time: f64,
    step_size: f64,
    start_time: f64,
    output_interval: Option<f64>,
    solver: Option<Bound<'py, PyAny>>,
    progress: Option<Py<PyAny>>,
    records: Option<Py<PyAny>>,
    coordinates: Option<PyReadonlyArray1<'py, f64>>,
    velocities: Option<PyReadonlyArray1<'py, f64>>,
    discrete: Option<PyReadonlyArray1<'py, f64>>,
    recorded: bool,
    initial_conditions: &str,
    keep_in_memory: bool,
) -> PyResult<(Bound<'py, PyDict>, Option<Py<PyAny>>)> {
    let mut settings = match solver {
        None => GeneralizedAlpha::default().settings(end_time, step_size)?,
        Some(s) => {
            if let Ok(g) = s.extract::<GeneralizedAlpha>() {
                let mut settings = g.settings(end_time, step_size)?;
                if let Some(h) = g.min_step_size {
                    settings.min_step_size = h;
                }
                settings
            } else if let Ok(e) = s.extract::<ExplicitSolver>() {
                e.settings(end_time, step_size)?
            } else {
                return Err(invalid(
                    "simulate",
                    format!(
                        "solver must be a GeneralizedAlpha or an ExplicitSolver, got {}",
                        s.get_type().name()?
                    ),
                ));
            }
        }
    };
    settings.start_time = start_time;
    settings.output_interval = output_interval;
    settings.start = match (coordinates, velocities) {
        (None, None) => None,
        (Some(q), Some(qd)) => Some(StartState {
            coordinates: q.as_slice()?.to_vec(),
            velocities: qd.as_slice()?.to_vec(),
            time: None,
            discrete: match &discrete {
                Some(values) => Some(values.as_slice()?.to_vec()),
                None => None,
            },
            recorded,
        }),
        _ => return Err(invalid("simulate", "give both the initial coordinates and velocities, or neither")),
    };
    settings.initial.strict = match initial_conditions {
        "correct" => false,
        "strict" => true,
        other => {
            return Err(invalid(
                "simulate",
                format!("initial_conditions must be 'correct' or 'strict', got {other:?}"),
            ))
        }
    };
    if !keep_in_memory && records.is_none() {
        return Err(invalid("simulate", "keep_in_memory=False needs a records callback (a results file)"));
    }
    let model_ref = model.inner.clone();
    // The Python exception that stopped the run, and the callback it came from (None: a
    // signal, Ctrl-C).
    let mut pending: Option<(PyErr, Option<&str>)> = None;
    let outcome = py.detach(|| {
        let mut last_check = Instant::now();
        let mut delivered = 0;
        let mut observer = |p: &flexmbd_core::integrator::Progress| -> bool {
            // About ten calls a second; records kept only in the file also go to it in
            // batches of at most RELEASE_BATCH, so that memory stays bounded on fast runs.
            let batch_full = !keep_in_memory && p.records.len() >= RELEASE_BATCH;
            if !batch_full && last_check.elapsed() < Duration::from_millis(100) {
                return true;
            }
            last_check = Instant::now();
            Python::attach(|py| {
                if let Err(e) = py.check_signals() {
                    pending = Some((e, None));
                    return false;
                }
                if let Some(cb) = &progress {
                    if let Err(e) = cb.call1(py, (p.time, p.step_size, p.newton_iterations)) {
                        pending = Some((e, Some("the progress function")));
                        return false;
                    }
                }
                if let Some(cb) = &records {
                    if p.records.len() > delivered {
                        let chunk = p.records.since(delivered);
                        if let Err(e) = output_dict(py, chunk).and_then(|d| cb.call1(py, (d,))) {
                            pending = Some((e, Some("the results writer")));
                            return false;
                        }
                        if keep_in_memory {
                            delivered = p.records.len();
                        } else {
                            p.release.set(p.records.len());
                        }
                    }
                }
                true
            })
        };
        core_simulate(&model_ref, &settings, &mut observer)
    });
    let raw = output_dict(py, outcome.output)?;
    let error = match outcome.error {
        None => None,
        Some(e) => {
            let (error, cause) = match (e, pending.take()) {
                (FlexmbdError::Interrupted { time }, Some((cause, Some(item)))) => {
                    // Chained as the CallbackError's __cause__ by to_exception.
                    let message = stash_callback_error(py, cause);
                    (FlexmbdError::Callback { item: item.to_string(), time, message }, None)
                }
                (e, pending) => (e, pending.map(|(cause, _)| cause)),
            };
            let exc = to_exception(py, &error);
            if let Some(cause) = cause {
                exc.value(py).setattr("__cause__", cause.value(py))?;
            }
            Some(exc.value(py).clone().into_any().unbind())
        }
    };
    Ok((raw, error))
}
