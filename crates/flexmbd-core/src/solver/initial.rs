//! Consistent initial conditions and the acceleration-level augmented system (seed eq. 26).
//!
//! - Positions: Newton's method on C(q, t0) = 0 with minimum-norm corrections,
//!   [[I, C_q^T], [C_q, 0]] [dq; mu] = [0; -C].
//! - Velocities: the velocity closest to the given one that satisfies C_q q_dot = -C_t,
//!   [[I, C_q^T], [C_q, 0]] [q_dot; mu] = [q_dot_given; -C_t].
//! - Accelerations and multipliers: [[M, C_q^T], [C_q, 0]] [q_dd; lambda] = [Q_e + F; gamma].

use super::assembly::{assemble, constraint_time_terms, MatrixCoefficients, StateView};
use super::generalized_alpha::NO_SOLVERS;
use crate::error::{FlexmbdError, Result};
use crate::system::workspace::LinearSolvers;
use crate::system::{Model, State, Workspace};

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
}

impl Default for InitialSettings {
    fn default() -> Self {
        InitialSettings {
            tolerance: 1e-11,
            max_iterations: 50,
            correct_positions: true,
            correct_velocities: true,
        }
    }
}

/// Factorizes the matrix assembled in `ws.values` with the coefficients `coef`: by LU, or by
/// the condensed solver for models with large deformable bodies.
fn factorize(
    model: &Model,
    ws: &mut Workspace,
    coef: &MatrixCoefficients,
    q: &[f64],
    time: f64,
    context: &str,
) -> Result<()> {
    let result = match &mut ws.linear {
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

fn solve(ws: &mut Workspace, time: f64, context: &str) -> Result<()> {
    let mut x = std::mem::take(&mut ws.solution);
    let r = match &mut ws.linear {
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

/// Makes the state's positions and velocities consistent with the constraints.
pub fn solve_initial_positions_and_velocities(
    model: &Model,
    state: &mut State,
    ws: &mut Workspace,
    settings: &InitialSettings,
) -> Result<()> {
    let nq = model.coordinate_count;
    let t = state.time;
    state.multipliers.iter_mut().for_each(|x| *x = 0.0);
    // Positions.
    let mut iterations = 0;
    loop {
        assemble(model, StateView::of(state), ws, Some(MatrixCoefficients::PROJECTION))?;
        let (row, violation) = worst_constraint(model, ws);
        if violation <= settings.tolerance {
            break;
        }
        if !settings.correct_positions || iterations >= settings.max_iterations || !violation.is_finite() {
            return Err(FlexmbdError::InconsistentInitialConditions {
                time: t,
                item: model.constraint_name(row),
                residual: violation,
                iterations,
            });
        }
        factorize(
            model,
            ws,
            &MatrixCoefficients::PROJECTION,
            &state.coordinates,
            t,
            "initial position correction",
        )?;
        ws.solution[..nq].iter_mut().for_each(|x| *x = 0.0);
        for k in 0..model.constraint_count {
            ws.solution[nq + k] = -ws.residual[nq + k];
        }
        solve(ws, t, "initial position correction")?;
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
                &MatrixCoefficients::PROJECTION,
                &state.coordinates,
                t,
                "initial velocity correction",
            )?;
            ws.solution[..nq].copy_from_slice(&state.velocities);
            for k in 0..model.constraint_count {
                ws.solution[nq + k] = -ct[k];
            }
            solve(ws, t, "initial velocity correction")?;
            state.velocities.copy_from_slice(&ws.solution[..nq]);
        }
    }
    Ok(())
}

/// Solves seed eq. 26 for the accelerations and multipliers at the state's q, q_dot.
pub fn solve_accelerations(model: &Model, state: &mut State, ws: &mut Workspace) -> Result<()> {
    let nq = model.coordinate_count;
    let t = state.time;
    state.accelerations.iter_mut().for_each(|x| *x = 0.0);
    state.multipliers.iter_mut().for_each(|x| *x = 0.0);
    assemble(model, StateView::of(state), ws, Some(MatrixCoefficients::ACCELERATION))?;
    let mut gamma = vec![0.0; model.constraint_count];
    let mut ct = vec![0.0; model.constraint_count];
    constraint_time_terms(model, StateView::of(state), ws, &mut ct, Some(&mut gamma))?;
    factorize(
        model,
        ws,
        &MatrixCoefficients::ACCELERATION,
        &state.coordinates,
        t,
        "acceleration system (seed eq. 26)",
    )?;
    for k in 0..nq {
        ws.solution[k] = -ws.residual[k];
    }
    ws.solution[nq..].copy_from_slice(&gamma);
    solve(ws, t, "acceleration system (seed eq. 26)")?;
    state.accelerations.copy_from_slice(&ws.solution[..nq]);
    state.multipliers.copy_from_slice(&ws.solution[nq..]);
    Ok(())
}
