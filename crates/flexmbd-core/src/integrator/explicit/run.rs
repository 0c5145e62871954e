//! A run with an explicit integrator: consistent initial conditions (dense), the partition or
//! the joint coordinates at the start, and its time loop.

use faer::Mat;

use super::engine::Engine;
use super::joint_coordinates::CARDAN_REBASE_ANGLE;
use super::runge_kutta::attempt;
use crate::error::{FlexmbdError, Result};
use crate::formulation::augmented::{DenseEquations, Level};
use crate::formulation::decoupled::{TreeAccelerations, TreeFormulation, TreeSolver};
use crate::formulation::recursive::Tree;
use crate::integrator::clock::OutputClock;
use crate::integrator::discrete::update_discrete;
use crate::integrator::initial::{dense_initial_conditions, report_initial_correction, starting_state};
use crate::integrator::progress::{Progress, Records};
use crate::integrator::settings::{ExplicitMethod, ExplicitSettings, SimulationSettings, Strategy};
use crate::linalg::partition::{partition, partition_with_independent};
use crate::output::{Event, Output};
use crate::system::{Model, State, Workspace};

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
