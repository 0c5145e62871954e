//! Velocity projection after a converged generalized-alpha step, in the metric of the mass
//! matrix: the correction dv solves
//!   [[M, C_q^T], [C_q, 0]] [dv; mu] = [0; -(C_q q_dot + C_t)],
//! the smallest change of kinetic energy that satisfies the velocity constraints. It removes
//! the undamped error mode along the constraint normals that the index-3 method has at
//! spectral radius 1 (the trapezoidal rule). The Newton matrix is no metric for it: with
//! gyroscopic and stiffness terms it need not be definite, and projecting with it destabilizes
//! fast-spinning bodies. The matrix is factorized by its own LDL^T (quasi-definite with the
//! normalization penalties), so that the next step may reuse the Newton matrix.

use super::newton::{factorize, solve};
use super::{Factorization, StepReport};
use crate::assembly::{assemble, MatrixCoefficients, Request, StateView};
use crate::error::Result;
use crate::linear_system::LinearSolvers;
use crate::system::{Model, State, Workspace};

/// Projects the velocities of the converged state `next` and makes its accelerations and
/// multipliers consistent with them. A singular matrix marks `report` as not converged, with
/// the failure; the factorization is counted in it.
pub(super) fn project(
    model: &Model,
    next: &mut State,
    ws: &mut Workspace,
    solvers: &mut LinearSolvers,
    report: &mut StepReport,
) -> Result<()> {
    let acceleration = MatrixCoefficients::ACCELERATION;
    assemble(model, StateView::of(next), ws, &Request::solving(Some(acceleration)))?;
    let kind = Factorization::Projection;
    if let Err(detail) = factorize(model, ws, solvers, kind, &acceleration, &next.coordinates) {
        report.converged = false;
        report.failure = Some(format!("singular mass matrix in the velocity projection: {detail}"));
        return Ok(());
    }
    report.factorizations += 1;
    if let Err(detail) = correct_velocities(model, next, ws, solvers) {
        report.converged = false;
        report.failure = Some(format!("velocity projection: {detail}"));
        return Ok(());
    }
    // Accelerations and multipliers consistent with the projected velocities (seed eq. 26,
    // with the matrix just factorized): otherwise q_dd, lambda and the auxiliary
    // accelerations carry the removed velocity error into the next step, which fast
    // gyroscopic bodies amplify.
    let nq = model.coordinate_count;
    let nc = model.constraint_count;
    next.accelerations.iter_mut().for_each(|x| *x = 0.0);
    next.multipliers.iter_mut().for_each(|x| *x = 0.0);
    let view = StateView::of(next);
    assemble(model, view, ws, &Request::solving(None))?;
    let mut gamma = std::mem::take(&mut ws.scratch[1]);
    let mut ct = std::mem::take(&mut ws.scratch[0]);
    let terms =
        crate::assembly::constraint_time_terms(model, view, ws, &mut ct[..nc], Some(&mut gamma[..nc]));
    for k in 0..nq {
        ws.solution[k] = -ws.residual[k];
    }
    ws.solution[nq..].copy_from_slice(&gamma[..nc]);
    ws.scratch[0] = ct;
    ws.scratch[1] = gamma;
    terms?;
    if let Err(detail) = solve(model, ws, solvers, kind, 1.0) {
        report.converged = false;
        report.failure = Some(format!("consistent accelerations after the projection: {detail}"));
        return Ok(());
    }
    next.accelerations.copy_from_slice(&ws.solution[..nq]);
    next.multipliers.copy_from_slice(&ws.solution[nq..]);
    Ok(())
}

/// Adds the correction dv (module documentation) to the velocities of `next`, with the
/// projection matrix factorized.
fn correct_velocities(
    model: &Model,
    next: &mut State,
    ws: &mut Workspace,
    solvers: &mut LinearSolvers,
) -> std::result::Result<(), String> {
    let nq = model.coordinate_count;
    let nc = model.constraint_count;
    let mut violation = std::mem::take(&mut ws.scratch[1]);
    crate::assembly::velocity_violation(model, &next.velocities, ws, &mut violation[..nc]);
    ws.solution[..nq].iter_mut().for_each(|x| *x = 0.0);
    for k in 0..nc {
        ws.solution[nq + k] = -violation[k];
    }
    ws.scratch[1] = violation;
    solve(model, ws, solvers, Factorization::Projection, 1.0)?;
    for k in 0..nq {
        next.velocities[k] += ws.solution[k];
    }
    Ok(())
}
