//! Consistent initial conditions and the acceleration-level augmented system (seed eq. 26).
//!
//! - Positions: Newton's method on C(q, t0) = 0 with minimum-norm corrections,
//!   [[I, C_q^T], [C_q, 0]] [dq; mu] = [0; -C].
//! - Velocities: the velocity closest to the given one that satisfies C_q q_dot = -C_t,
//!   [[I, C_q^T], [C_q, 0]] [q_dot; mu] = [q_dot_given; -C_t].
//! - Accelerations and multipliers: [[M, C_q^T], [C_q, 0]] [q_dd; lambda] = [Q_e + F; gamma].
//!
//! Nothing is corrected silently: [`correction_events`] names every joint the given positions
//! violate and every body whose coordinates or velocities the correction moves by more than
//! the report tolerance; with `strict` settings such a correction is refused instead.

use faer::Mat;

use crate::assembly::{
    assemble, constraint_time_terms, MatrixCoefficients, Request, StateView, ELASTIC_PROJECTION_WEIGHT,
};
use crate::body::flexible::REFERENCE_COORDINATES;
use crate::body::BodyKind;
use crate::error::{FlexmbdError, Result};
use crate::formulation::augmented::{row_weight, worst, DenseEquations, Level};
use crate::integrator::settings::{InitialSettings, SimulationSettings, StartState};
use crate::linalg::partition::minimum_norm_solve;
use crate::linear_system::{LinearSolvers, NO_SOLVERS};
use crate::output::{Event, Output};
use crate::system::{Model, State, Workspace};

/// Refuses a start with an angle driver's joint more than a quarter turn from the prescribed
/// angle. Its equation sin(theta - f) = 0 holds half a turn from f too: a joint started near
/// theta = f + pi is consistent with it, and the run would drive the joint on that branch
/// (an arm held pointing the other way, its torque of the opposite sign) without a word, or
/// the corrections of another solver would turn it over.
pub fn check_angle_drivers(model: &Model, state: &State) -> Result<()> {
    // (Made at the first angle driver: a model without one pays nothing.)
    let mut ws: Option<Workspace> = None;
    for (j, joint) in model.joints.iter().enumerate() {
        let crate::joint::JointKind::AngleDriver(f) = &joint.kind else { continue };
        let Ok([target, _, _]) = f.evaluate(state.time) else { continue };
        let ws = ws.get_or_insert_with(|| {
            let mut ws = Workspace::new(model);
            crate::assembly::update_kinematics(model, &state.coordinates, &state.velocities, &mut ws);
            ws
        });
        let pair = crate::assembly::joint_pair(model, &ws.markers, j);
        let theta = crate::force::rotational_spring_damper::wrapped_angle(&pair);
        // The joint angle continued from the prescribed one: their difference in (-pi, pi].
        let off = crate::force::rotational_spring_damper::unwrapped_angle(&pair, target) - target;
        if off.abs() > std::f64::consts::FRAC_PI_2 {
            return Err(FlexmbdError::InconsistentInitialConditions {
                time: state.time,
                item: format!(
                    "angle driver '{}' (its joint starts at {theta:.4} rad, {off:.4} rad from the \
                     prescribed {target:.4} rad: the driver's equation sin(theta - f) = 0 holds half \
                     a turn from f too, and the run would drive the joint on that branch, its torque \
                     of the opposite sign; start the joint within a quarter turn of the prescribed \
                     angle)",
                    joint.name
                ),
                residual: off.abs(),
                iterations: 0,
            });
        }
    }
    Ok(())
}

/// The state a run starts from at `time`: `start`'s coordinates and velocities, or the
/// model's initial ones. Errors name a wrong length or the first non-finite entry.
pub fn starting_state(model: &Model, time: f64, start: Option<&StartState>) -> Result<State> {
    let mut state = State::initial(model, time);
    let Some(start) = start else {
        return Ok(state);
    };
    let n = model.coordinate_count;
    for (what, values) in [("coordinates", &start.coordinates), ("velocities", &start.velocities)] {
        if values.len() != n {
            return Err(FlexmbdError::InvalidParameter {
                item: "initial state".to_string(),
                message: format!("{} {what} given for a model of {n} coordinates", values.len()),
            });
        }
        if let Some(k) = values.iter().position(|v| !v.is_finite()) {
            return Err(FlexmbdError::InvalidParameter {
                item: "initial state".to_string(),
                message: format!("{what}: {} is {}", model.coordinate_name(k), values[k]),
            });
        }
    }
    state.coordinates.copy_from_slice(&start.coordinates);
    state.velocities.copy_from_slice(&start.velocities);
    if let Some(t) = start.time {
        if !(t >= time) {
            return Err(FlexmbdError::InvalidParameter {
                item: "initial state".to_string(),
                message: format!("its time {t:e} is before the start time {time:e}"),
            });
        }
        state.time = t;
    }
    if let Some(discrete) = &start.discrete {
        if discrete.len() != model.discrete_count {
            return Err(FlexmbdError::InvalidParameter {
                item: "initial state".to_string(),
                message: format!(
                    "{} discrete variables given for a model of {}",
                    discrete.len(),
                    model.discrete_count
                ),
            });
        }
        state.discrete.copy_from_slice(discrete);
    }
    Ok(state)
}

/// The constraint rows whose |C| exceeds `tolerance`, with their values: what the given
/// positions violate before the correction.
pub(crate) fn violated_rows(constraints: &[f64], tolerance: f64) -> Vec<(usize, f64)> {
    constraints.iter().enumerate().filter(|(_, c)| c.abs() > tolerance).map(|(r, &c)| (r, c)).collect()
}

/// Largest move of a recorded state (`StartState::recorded`; relative to max(1, |q|), as the
/// report tolerance) taken as the drift of the integrator that recorded it: explicit strategies
/// that integrate every coordinate leave the constraints by up to 5.9e-6 in a second
/// (tr-bdf2); more is an initial correction (the state of another model).
pub const RECORDED_DRIFT: f64 = 1e-3;

/// The "initial correction" events of a consistent-initial-condition solve that went from the
/// given coordinates and velocities (`given_q`, `given_qd`) to `state`: one per joint (or
/// normalization) the given positions violated by more than the report tolerance (`violated`
/// from the solve), and one per body whose coordinates or velocities moved by more than it.
/// Returns them with the largest move (0 when there is nothing to report).
pub fn correction_events(
    model: &Model,
    given_q: &[f64],
    given_qd: &[f64],
    state: &State,
    violated: &[(usize, f64)],
    settings: &InitialSettings,
    recorded: bool,
) -> (Vec<Event>, f64) {
    let tol = settings.report_tolerance;
    // What a recorded state may be moved by as the integrator's drift; beyond it the move is
    // an initial correction (a state of another model: a hinge elsewhere moved its body by
    // 0.3 m as "drift").
    let drift = if recorded { RECORDED_DRIFT.max(tol) } else { tol };
    // The velocities of a recorded state projected onto the constraints (`StartState::recorded`),
    // and its positions: the largest change and its body.
    let mut projected: Option<(f64, &str)> = None;
    let mut placed: Option<(f64, &str)> = None;
    let time = state.time;
    let mut events = Vec::new();
    let mut largest = 0.0f64;
    let event = |message: String| Event { time, kind: "initial correction".to_string(), message };
    // Joints (and Euler-parameter normalizations) violated by the given positions.
    let mut reported_joint = vec![false; model.joints.len()];
    for &(row, value) in violated {
        // (a recorded state's violations up to `drift` are the integrator's: reported with
        // the positions below)
        if value.abs() <= drift {
            continue;
        }
        if let Some(j) = model.joints.iter().position(|j| row >= j.row && row < j.row + j.equations.len()) {
            if reported_joint[j] {
                continue;
            }
            reported_joint[j] = true;
            let joint = &model.joints[j];
            let rows = joint.row..joint.row + joint.equations.len();
            let (worst_row, worst) = violated
                .iter()
                .filter(|(r, _)| rows.contains(r))
                .fold((row, 0.0f64), |b, &(r, v)| if v.abs() > b.1 { (r, v.abs()) } else { b });
            events.push(event(format!(
                "joint '{}' ({}): the given positions violate it by {worst:.3e} (equation '{}')",
                joint.name,
                joint.kind.type_name(),
                joint.equations[worst_row - joint.row].label
            )));
        } else {
            events.push(event(format!(
                "{}: the given positions violate it by {:.3e}",
                model.constraint_name(row),
                value.abs()
            )));
        }
    }
    // Bodies moved by the correction.
    for body in &model.bodies {
        if body.dofs.is_empty() {
            continue;
        }
        // (relative change, tested against `tol`; absolute change, reported: a position of
        // 1.5 m moved by 0.5 m said 0.333).
        let moved = |given: &[f64], now: &[f64], range: std::ops::Range<usize>| -> (f64, f64) {
            body.dofs[range.start.min(body.dofs.len())..range.end.min(body.dofs.len())]
                .iter()
                .map(|&k| {
                    let change = (now[k] - given[k]).abs();
                    (change / given[k].abs().max(1.0), change)
                })
                .fold((0.0, 0.0), |a, b| (a.0.max(b.0), a.1.max(b.1)))
        };
        let n = body.dofs.len();
        let rigid = n >= 7;
        let parts: [(&str, (f64, f64)); 4] = [
            ("position", moved(given_q, &state.coordinates, 0..3)),
            (
                "orientation (Euler parameters)",
                if rigid { moved(given_q, &state.coordinates, 3..7) } else { (0.0, 0.0) },
            ),
            (
                "elastic coordinates",
                if n > 7 { moved(given_q, &state.coordinates, 7..n) } else { (0.0, 0.0) },
            ),
            ("velocities", moved(given_qd, &state.velocities, 0..n)),
        ];
        if recorded {
            // The integrator's own drift: positions that an explicit strategy integrating all
            // coordinates lets leave the constraints (5.9e-6 of the Euler parameters' norm
            // with tr-bdf2 after 1 s), velocities off the velocity constraints.
            for (k, (_, (relative, change))) in parts.iter().enumerate() {
                let slot = if k == 3 { &mut projected } else { &mut placed };
                if *relative > tol && *relative <= drift && slot.map_or(true, |(c, _)| *change > c) {
                    *slot = Some((*change, body.name.as_str()));
                }
            }
        }
        let over: Vec<String> = parts
            .iter()
            .filter(|(_, (relative, _))| *relative > drift)
            .map(|(what, (_, change))| format!("{what} by up to {change:.3e}"))
            .collect();
        largest = parts.iter().map(|p| p.1 .0).filter(|&r| r > drift).fold(largest, f64::max);
        if !over.is_empty() {
            events.push(event(format!(
                "body '{}': the consistent initial conditions move its {}",
                body.name,
                over.join(", its ")
            )));
        }
    }
    if events.is_empty() {
        largest = 0.0;
    }
    if let Some((change, body)) = placed {
        events.push(Event {
            time,
            kind: "continuation".to_string(),
            message: format!(
                "the positions of the recorded state projected onto the constraints, by up to \
                 {change:.3e} (body '{body}'): the integrator's own drift of the constraints, \
                 not an initial correction"
            ),
        });
    }
    if let Some((change, body)) = projected {
        events.push(Event {
            time,
            kind: "continuation".to_string(),
            message: format!(
                "the velocities of the recorded state projected onto the velocity constraints, by \
                 up to {change:.3e} (body '{body}'): the integrator's own drift of the velocity \
                 constraints, not an initial correction"
            ),
        });
    }
    (events, largest)
}

/// Factorizes the matrix assembled in `ws.values` with the coefficients `coef`: by LU, or by
/// the condensed solver for models with large deformable bodies.
fn factorize(
    model: &Model,
    ws: &mut Workspace,
    solvers: &mut LinearSolvers,
    coef: &MatrixCoefficients,
    q: &[f64],
    time: f64,
    context: &str,
) -> Result<()> {
    let result = match solvers {
        LinearSolvers::Direct { lu, .. } => lu.factorize(&ws.values),
        LinearSolvers::Dense { projection, .. } => projection.factorize(&model.layout.pattern, &ws.values),
        LinearSolvers::Condensed { projection, .. } => {
            projection.factorize(model, &ws.values, coef, q).map_err(|e| e.to_string())
        }
        LinearSolvers::None => Err(NO_SOLVERS.to_string()),
    };
    result.map_err(|detail| FlexmbdError::SingularMatrix {
        time,
        context: context.to_string(),
        detail: format!("{detail} (redundant or conflicting constraints, or a singular configuration)"),
    })
}

fn solve(ws: &mut Workspace, solvers: &mut LinearSolvers, time: f64, context: &str) -> Result<()> {
    let mut x = std::mem::take(&mut ws.solution);
    let r = match solvers {
        LinearSolvers::Direct { lu, .. } => lu.solve_in_place(&mut x),
        LinearSolvers::Dense { projection, .. } => projection.solve_in_place(&mut x),
        LinearSolvers::Condensed { projection, .. } => projection.solve_in_place(&mut x),
        LinearSolvers::None => Err(NO_SOLVERS.to_string()),
    };
    ws.solution = x;
    r.map_err(|detail| FlexmbdError::SingularMatrix {
        time,
        context: context.to_string(),
        detail: format!("{detail} (redundant or conflicting constraints, or a singular configuration)"),
    })
}

/// Largest constraint violation and its row.
fn worst_constraint(model: &Model, ws: &Workspace) -> (usize, f64) {
    let nq = model.coordinate_count;
    ws.residual[nq..]
        .iter()
        .enumerate()
        .fold((0, 0.0f64), |best, (k, v)| if v.abs() > best.1 { (k, v.abs()) } else { best })
}

/// Makes the state's positions and velocities consistent with the constraints. Returns the
/// constraint rows the given positions violated (beyond the solve's tolerance), with their
/// values, for [`correction_events`].
pub fn solve_initial_positions_and_velocities(
    model: &Model,
    state: &mut State,
    ws: &mut Workspace,
    solvers: &mut LinearSolvers,
    settings: &InitialSettings,
) -> Result<Vec<(usize, f64)>> {
    let nq = model.coordinate_count;
    let t = state.time;
    state.multipliers.iter_mut().for_each(|x| *x = 0.0);
    // Positions.
    let mut iterations = 0;
    let mut violated = None;
    loop {
        assemble(model, StateView::of(state), ws, &Request::solving(Some(MatrixCoefficients::PROJECTION)))?;
        if violated.is_none() {
            violated = Some(violated_rows(&ws.residual[nq..], settings.tolerance));
        }
        let (_, violation) = worst_constraint(model, ws);
        if violation <= settings.tolerance {
            break;
        }
        if !settings.correct_positions || iterations >= settings.max_iterations || !violation.is_finite() {
            let (item, residual) = violated_constraints(model, &ws.residual[nq..], settings.tolerance);
            return Err(FlexmbdError::InconsistentInitialConditions { time: t, item, residual, iterations });
        }
        factorize(
            model,
            ws,
            solvers,
            &MatrixCoefficients::PROJECTION,
            &state.coordinates,
            t,
            "initial position correction",
        )?;
        ws.solution[..nq].iter_mut().for_each(|x| *x = 0.0);
        for k in 0..model.constraint_count {
            ws.solution[nq + k] = -ws.residual[nq + k];
        }
        solve(ws, solvers, t, "initial position correction")?;
        for k in 0..nq {
            state.coordinates[k] += ws.solution[k];
        }
        iterations += 1;
    }
    // Velocities.
    if model.constraint_count > 0 {
        let mut ct = vec![0.0; model.constraint_count];
        constraint_time_terms(model, StateView::of(state), ws, &mut ct, None)?;
        if settings.correct_velocities {
            factorize(
                model,
                ws,
                solvers,
                &MatrixCoefficients::PROJECTION,
                &state.coordinates,
                t,
                "initial velocity correction",
            )?;
            // The projection of q_dot in the metric W of the matrix: W q_dot on the right
            // (q_dot itself would divide the elastic velocities by their weight).
            for ((x, v), w) in
                ws.solution[..nq].iter_mut().zip(&state.velocities).zip(projection_weights(model))
            {
                *x = w * v;
            }
            for k in 0..model.constraint_count {
                ws.solution[nq + k] = -ct[k];
            }
            solve(ws, solvers, t, "initial velocity correction")?;
            state.velocities.copy_from_slice(&ws.solution[..nq]);
        }
    }
    Ok(violated.unwrap_or_default())
}

/// Solves seed eq. 26 for the accelerations and multipliers at the state's q, q_dot.
pub fn solve_accelerations(
    model: &Model,
    state: &mut State,
    ws: &mut Workspace,
    solvers: &mut LinearSolvers,
) -> Result<()> {
    let nq = model.coordinate_count;
    let t = state.time;
    state.accelerations.iter_mut().for_each(|x| *x = 0.0);
    state.multipliers.iter_mut().for_each(|x| *x = 0.0);
    assemble(model, StateView::of(state), ws, &Request::solving(Some(MatrixCoefficients::ACCELERATION)))?;
    let mut gamma = vec![0.0; model.constraint_count];
    let mut ct = vec![0.0; model.constraint_count];
    constraint_time_terms(model, StateView::of(state), ws, &mut ct, Some(&mut gamma))?;
    factorize(
        model,
        ws,
        solvers,
        &MatrixCoefficients::ACCELERATION,
        &state.coordinates,
        t,
        "acceleration system (seed eq. 26)",
    )?;
    for k in 0..nq {
        ws.solution[k] = -ws.residual[k];
    }
    ws.solution[nq..].copy_from_slice(&gamma);
    solve(ws, solvers, t, "acceleration system (seed eq. 26)")?;
    state.accelerations.copy_from_slice(&ws.solution[..nq]);
    state.multipliers.copy_from_slice(&ws.solution[nq..]);
    Ok(())
}

/// The diagonal of the metric W of the minimum-norm corrections
/// (`MatrixCoefficients::PROJECTION`): 1 for the reference coordinates,
/// ELASTIC_PROJECTION_WEIGHT for the elastic ones.
fn projection_weights(model: &Model) -> Vec<f64> {
    let mut weights = vec![1.0; model.coordinate_count];
    for body in &model.bodies {
        if matches!(body.kind, BodyKind::Flexible(_)) {
            for &d in &body.dofs[REFERENCE_COORDINATES..] {
                weights[d] = ELASTIC_PROJECTION_WEIGHT;
            }
        }
    }
    weights
}

/// The column scales of the dense minimum-norm corrections: 1 / sqrt of the metric's weights
/// (`projection_weights`; a change y of a scaled column is a change y s of its coordinate,
/// whose square then weighs 1 / s^2).
fn projection_column_scales(model: &Model) -> Vec<f64> {
    projection_weights(model).into_iter().map(|w| 1.0 / w.sqrt()).collect()
}

/// Relative singular-value cut-off of the minimum-norm corrections.
const PSEUDO_INVERSE_TOLERANCE: f64 = 1e-10;

/// Consistent initial positions and velocities with dense minimum-norm corrections (truncated
/// pseudo-inverse of C_q), which also converge for redundant constraints:
/// q <- q - C_q^+ C(q) until |C| <= tolerance, then q_dot <- q_dot - C_q^+ (C_q q_dot + C_t).
/// Returns the constraint rows the given positions violated, with their values.
pub fn dense_initial_conditions(
    model: &Model,
    ws: &mut Workspace,
    eq: &mut DenseEquations,
    state: &mut State,
    settings: &InitialSettings,
) -> Result<Vec<(usize, f64)>> {
    let t = state.time;
    let columns = projection_column_scales(model);
    let mut iterations = 0;
    let mut violated = None;
    loop {
        eq.evaluate(model, ws, t, &state.coordinates, &state.velocities, &state.discrete, Level::Position)?;
        if violated.is_none() {
            violated = Some(violated_rows(&eq.constraints, settings.tolerance));
        }
        let (_, violation) = worst(&eq.constraints);
        if violation <= settings.tolerance {
            break;
        }
        if !settings.correct_positions || iterations >= settings.max_iterations || !violation.is_finite() {
            let (item, residual) = violated_constraints(model, &eq.constraints, settings.tolerance);
            return Err(FlexmbdError::InconsistentInitialConditions { time: t, item, residual, iterations });
        }
        // Weighted rows: where the constraints cannot all be met, the least-squares compromise
        // keeps the normalizations and drivers and leaves the violation on the joints.
        let rows: Vec<f64> = (0..model.constraint_count).map(|r| row_weight(model, r)).collect();
        subtract_correction(&eq.jacobian, &eq.constraints, &rows, &columns, &mut state.coordinates);
        iterations += 1;
    }
    if model.constraint_count > 0 && settings.correct_velocities {
        eq.evaluate(model, ws, t, &state.coordinates, &state.velocities, &state.discrete, Level::Velocity)?;
        let violation: Vec<f64> =
            (0..model.constraint_count).map(|k| eq.velocity_violation(k, &state.velocities)).collect();
        let rows = vec![1.0; model.constraint_count];
        subtract_correction(&eq.jacobian, &violation, &rows, &columns, &mut state.velocities);
    }
    Ok(violated.unwrap_or_default())
}

/// x <- x - S (W J S)^+ W r: the minimum-norm correction of `x` that removes the residual `r`
/// of the rows of `jacobian` J to first order, rows weighted by `rows` (W) and changes
/// measured in the metric of the column scales `columns` (S, `projection_column_scales`:
/// the elastic coordinates' changes weigh ELASTIC_PROJECTION_WEIGHT times the reference
/// coordinates', as in `MatrixCoefficients::PROJECTION`).
fn subtract_correction(jacobian: &Mat<f64>, residual: &[f64], rows: &[f64], columns: &[f64], x: &mut [f64]) {
    let scaled =
        Mat::from_fn(jacobian.nrows(), jacobian.ncols(), |r, c| rows[r] * jacobian[(r, c)] * columns[c]);
    let weighted: Vec<f64> = residual.iter().zip(rows).map(|(v, w)| v * w).collect();
    let dx = minimum_norm_solve(scaled.as_ref(), &weighted, PSEUDO_INVERSE_TOLERANCE);
    for ((x, d), scale) in x.iter_mut().zip(&dx).zip(columns) {
        *x -= d * scale;
    }
}

/// The worst violated joint row (a normalization of Euler parameters only when no joint is
/// violated: where joints cannot close, the compromise of the corrections also leaves the
/// normalizations violated, and they are not the cause), named with the other joints left
/// violated with it (when constraints conflict, the least-squares compromise spreads the
/// violation over all joints involved), and its violation.
fn violated_constraints(model: &Model, constraints: &[f64], tolerance: f64) -> (String, f64) {
    // NaN counts as the largest; the violation returned is the row's own (NaN stays NaN).
    let size = |r: usize| if constraints[r].is_nan() { f64::INFINITY } else { constraints[r].abs() };
    let largest = |rows: &mut dyn Iterator<Item = usize>| {
        let row = rows.fold(None, |best: Option<usize>, r| match best {
            Some(b) if size(b) >= size(r) => Some(b),
            _ => Some(r),
        });
        row.map_or((0, 0.0), |r| (r, constraints[r].abs()))
    };
    let (joint_row, joint_violation) =
        largest(&mut model.joints.iter().flat_map(|j| j.row..j.row + j.equations.len()));
    let (worst_row, violation) = if joint_violation > tolerance || joint_violation.is_nan() {
        (joint_row, joint_violation)
    } else {
        largest(&mut (0..constraints.len()))
    };
    let mut item = model.constraint_name(worst_row);
    let threshold = tolerance.max(1e-6 * violation);
    let mut others: Vec<String> = Vec::new();
    for j in &model.joints {
        let violated = (j.row..j.row + j.equations.len()).any(|r| constraints[r].abs() > threshold);
        let name = format!("'{}'", j.name);
        if violated
            && !(worst_row >= j.row && worst_row < j.row + j.equations.len())
            && !others.contains(&name)
        {
            others.push(name);
        }
    }
    if !others.is_empty() {
        item.push_str(&format!(" (also violated: joint {})", others.join(", ")));
    }
    (item, violation)
}

/// Adds the "initial correction" events of the consistent-initial-condition solve that took
/// the given coordinates and velocities to `state` to `output`, or, with strict settings,
/// refuses the correction.
pub(crate) fn report_initial_correction(
    model: &Model,
    given_q: &[f64],
    given_qd: &[f64],
    state: &State,
    violated: &[(usize, f64)],
    settings: &SimulationSettings,
    output: &mut Output,
) -> Result<()> {
    let recorded = settings.start.as_ref().is_some_and(|start| start.recorded);
    let (events, largest) =
        correction_events(model, given_q, given_qd, state, violated, &settings.initial, recorded);
    let corrections: Vec<&str> =
        events.iter().filter(|e| e.kind == "initial correction").map(|e| e.message.as_str()).collect();
    if settings.initial.strict && !corrections.is_empty() {
        let item = corrections.join("; ");
        return Err(FlexmbdError::InitialCorrectionRefused { time: state.time, item, size: largest });
    }
    output.events.extend(events);
    Ok(())
}
