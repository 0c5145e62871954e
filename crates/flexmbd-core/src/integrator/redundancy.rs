//! Redundant constraints: equations that are linear combinations of the others on the
//! constraint manifold (a planar four-bar modelled with spatial revolute joints, the Bricard
//! mechanism, a parallel crank). Their Jacobian C_q is rank deficient, so the augmented matrix
//! of seed eq. 26 is singular and the multipliers are not unique.
//!
//! Before a run, the initial configuration is brought onto the constraints with minimum-norm
//! Gauss-Newton corrections (truncated pseudo-inverse, which converges with redundant rows) and
//! the rank of C_q is decided by QR with column pivoting of C_q^T. Rows are chosen in the
//! order: Euler-parameter normalizations, driver equations, joint equations, so the removed
//! rows are always joint equations. The run continues on the model without the redundant rows
//! (`Model::without_constraint_rows`), which has the same motion; the results are mapped back
//! to all rows, with the multipliers of the removed rows either zero (`Remove`) or the
//! minimum-norm multipliers of the same constraint forces C_q^T lambda (`MinimumNorm`). The
//! analysis is reported (rank, removed rows, the groups of rows that are dependent together
//! and their joints).
//!
//! The analysis is dense: models where it would cost more than about `ANALYSIS_FLOPS` are not
//! analysed (a singular Newton matrix then reports redundant or conflicting constraints).

use crate::assembly::{joint_pair, update_kinematics};
use crate::error::{FlexmbdError, Result};
use crate::formulation::augmented::{row_weight, DenseEquations, Level};
use crate::integrator::initial::{dense_initial_conditions, starting_state};
use crate::integrator::settings::{RedundancyHandling, SimulationSettings};
use crate::joint::reaction::joint_reaction;
use crate::linalg::partition::{
    dependent_row_groups, leading_rows, minimum_norm_solve, partition, PartitionMethod,
};
use crate::output::{Event, Output, Redundancy};
use crate::system::{Model, State, Workspace};

/// Largest m n min(m, n) of C_q for which the analysis runs.
pub const ANALYSIS_FLOPS: f64 = 2e9;

/// A model with its redundant rows removed.
pub struct Reduction {
    /// The reduced model (initial coordinates on the constraints).
    pub model: Model,
    /// Row of the original model of each reduced row.
    pub row_map: Vec<usize>,
    /// The analysis.
    pub report: Redundancy,
    /// Relative tolerance of the rank decisions.
    pub tolerance: f64,
    /// Kind of the event that reports it: "redundant constraints" at the start,
    /// "redundancy re-selected" during the run.
    pub event: &'static str,
}

/// Analyses the model at its initial configuration. Ok(None) if the constraints are
/// independent (or the model too large to analyse densely).
pub fn analyse(model: &Model, settings: &SimulationSettings) -> Result<Option<Reduction>> {
    let (n, m) = (model.coordinate_count, model.constraint_count);
    if m == 0 || (m as f64) * (n as f64) * (m.min(n) as f64) > ANALYSIS_FLOPS {
        return Ok(None);
    }
    let mut ws = Workspace::new(model);
    let mut eq = DenseEquations::new(model);
    let mut state = starting_state(model, settings.start_time, settings.start.as_ref())?;
    let mut initial = settings.initial.clone();
    initial.correct_velocities = false;
    dense_initial_conditions(model, &mut ws, &mut eq, &mut state, &initial)?;
    let reduction = select(model, &mut ws, &mut eq, &state, settings.redundancy.tolerance, None)?;
    if let Some(reduction) = &reduction {
        if settings.redundancy.handling == RedundancyHandling::Error {
            let message = reduction.report.message.clone();
            return Err(FlexmbdError::InvalidModel { item: "constraints".to_string(), message });
        }
    }
    Ok(reduction)
}

/// The rows of `model`'s constraint Jacobian kept at `state` (on the constraints): the
/// independent ones, chosen by QR with column pivoting of the weighted C_q^T (see
/// `row_weight`). None if all rows are independent. `again`: when the rows are chosen again
/// during the run, why, and how many are kept: the rank found at the start (the mechanism's;
/// a rank decided again at a singular configuration passed would drop an independent row).
pub(crate) fn select(
    model: &Model,
    ws: &mut Workspace,
    eq: &mut DenseEquations,
    state: &State,
    tolerance: f64,
    again: Option<(&str, usize)>,
) -> Result<Option<Reduction>> {
    let (n, m) = (model.coordinate_count, model.constraint_count);
    let t = state.time;
    eq.evaluate(model, ws, t, &state.coordinates, &state.velocities, &state.discrete, Level::Position)?;
    let mut weighted = eq.jacobian.clone();
    for r in 0..m {
        let w = row_weight(model, r);
        for c in 0..n {
            weighted[(r, c)] *= w;
        }
    }
    let (rank, redundant_rows) = match again {
        None => {
            let p = partition(weighted.as_ref(), PartitionMethod::Qr, tolerance);
            (p.rank, p.redundant_rows)
        }
        Some((_, rank)) => {
            let kept = leading_rows(weighted.as_ref(), rank);
            (rank, (0..m).filter(|r| kept.binary_search(r).is_err()).collect())
        }
    };
    if redundant_rows.is_empty() {
        return Ok(None);
    }
    let groups = dependent_row_groups(eq.jacobian.as_ref(), tolerance);
    let mut joints: Vec<usize> = groups
        .iter()
        .flatten()
        .filter_map(|&r| model.joints.iter().position(|j| r >= j.row && r < j.row + j.equations.len()))
        .collect();
    joints.sort_unstable();
    joints.dedup();
    let joint_names: Vec<String> = joints.iter().map(|&j| format!("'{}'", model.joints[j].name)).collect();
    let removed: Vec<String> = redundant_rows.iter().map(|&r| model.constraint_name(r)).collect();
    let mut message = format!(
        "{} of {m} constraint equations are redundant (rank of C_q {} at t = {t}); they involve joints {}; \
         removed: {}",
        redundant_rows.len(),
        rank,
        joint_names.join(", "),
        removed.join("; ")
    );
    if let Some((reason, _)) = again {
        message = format!("{reason}; {message}");
    }
    let report =
        Redundancy { time: t, rows: m, rank, removed_rows: redundant_rows.clone(), groups, joints, message };
    let (mut reduced, row_map) = model.without_constraint_rows(&redundant_rows)?;
    reduced.initial_coordinates.copy_from_slice(&state.coordinates);
    let event = if again.is_some() { "redundancy re-selected" } else { "redundant constraints" };
    Ok(Some(Reduction { model: reduced, row_map, report, tolerance, event }))
}

impl Reduction {
    /// Multipliers of all rows of `original` from those of the reduced model.
    fn expand_multipliers(&self, reduced: &[f64], full: &mut [f64]) {
        full.iter_mut().for_each(|x| *x = 0.0);
        for (k, &row) in self.row_map.iter().enumerate() {
            full[row] = reduced[k];
        }
    }

    /// A state of the reduced model as a state of `original`.
    pub fn expand_state(&self, original: &Model, mut state: State) -> State {
        let mut full = vec![0.0; original.constraint_count];
        self.expand_multipliers(&state.multipliers, &mut full);
        state.multipliers = full;
        let mut previous = vec![0.0; original.constraint_count];
        self.expand_multipliers(&state.previous_multipliers, &mut previous);
        state.previous_multipliers = previous;
        state
    }

    /// The output of the reduced model as an output of `original`: multipliers of all rows
    /// (zero or minimum-norm on the removed ones), reactions from them, and the constraint
    /// violation over all rows; an event reports the redundancy.
    pub fn expand_output(&self, original: &Model, reduced: Output, handling: RedundancyHandling) -> Output {
        let mut out = reduced;
        self.expand_records(original, &mut out, handling);
        out
    }

    /// The records of `reduced` from index `from` on, expanded as by `expand_output`.
    pub fn expand_since(
        &self,
        original: &Model,
        reduced: &Output,
        from: usize,
        handling: RedundancyHandling,
    ) -> Output {
        let mut out = reduced.since(from);
        self.expand_records(original, &mut out, handling);
        out
    }

    /// Expands the multipliers (and reactions, violations) of `out`'s records in place and
    /// adds the redundancy event and report.
    fn expand_records(&self, original: &Model, out: &mut Output, handling: RedundancyHandling) {
        let (n, m) = (original.coordinate_count, original.constraint_count);
        let records = out.len();
        let mr = self.model.constraint_count;
        let mut multipliers = vec![0.0; records * m];
        let mut ws = Workspace::new(original);
        let mut eq = DenseEquations::new(original);
        let no_discrete = vec![0.0; original.discrete_count];
        for k in 0..records {
            let lambda = &mut multipliers[k * m..(k + 1) * m];
            self.expand_multipliers(&out.multipliers[k * mr..(k + 1) * mr], lambda);
            let q = &out.coordinates[k * n..(k + 1) * n];
            let qd = &out.velocities[k * n..(k + 1) * n];
            let t = out.time[k];
            if eq.evaluate(original, &mut ws, t, q, qd, &no_discrete, Level::Position).is_err() {
                continue;
            }
            let removed_violation =
                self.report.removed_rows.iter().map(|&r| eq.constraints[r].abs()).fold(0.0, f64::max);
            out.constraint_violation[k] = out.constraint_violation[k].max(removed_violation);
            if handling == RedundancyHandling::MinimumNorm {
                // The same constraint forces C_q^T lambda, distributed with minimum norm.
                let mut force = vec![0.0; n];
                for r in 0..m {
                    for c in 0..n {
                        force[c] += eq.jacobian[(r, c)] * lambda[r];
                    }
                }
                let transpose = eq.jacobian.transpose().to_owned();
                let spread = minimum_norm_solve(transpose.as_ref(), &force, self.tolerance);
                lambda.copy_from_slice(&spread);
                update_kinematics(original, q, qd, &mut ws);
                for (j, joint) in original.joints.iter().enumerate() {
                    let driver = joint.driver_values(t).unwrap_or([f64::NAN; 3]);
                    let mut scratch = std::mem::take(&mut ws.joints[j].scratch);
                    let pair = joint_pair(original, &ws.markers, j);
                    let l = &lambda[joint.row..joint.row + joint.equations.len()];
                    let (f, tq) = joint_reaction(joint, &pair, &driver, l, q, &mut scratch);
                    ws.joints[j].scratch = scratch;
                    let base = (k * original.joints.len() + j) * 6;
                    out.reactions[base..base + 3].copy_from_slice(&f.0);
                    out.reactions[base + 3..base + 6].copy_from_slice(&tq.0);
                }
            }
        }
        out.multipliers = multipliers;
        out.constraint_count = m;
        out.events.insert(
            0,
            Event {
                time: self.report.time,
                kind: self.event.to_string(),
                message: self.report.message.clone(),
            },
        );
        out.redundancy = Some(self.report.clone());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::test_models::{ground_joint, unit_body};
    use crate::joint::JointKind;
    use crate::math::{Mat3, Vec3};
    use crate::SystemBuilder;

    /// A body on two revolute joints with the same axis (5 of their 10 equations redundant)
    /// and a spherical joint of a second body to it.
    fn doubly_hinged() -> Model {
        let mut sys = SystemBuilder::new();
        sys.set_gravity(Vec3([0.0, -9.81, 0.0])).unwrap();
        let inertia = Mat3::diagonal(Vec3([0.01, 0.1, 0.1]));
        let body = sys
            .add_rigid_body(
                "arm",
                1.0,
                inertia,
                Vec3::ZERO,
                Vec3([0.5, 0.0, 0.0]),
                Mat3::IDENTITY,
                Vec3::ZERO,
                Vec3::ZERO,
            )
            .unwrap();
        let tip = sys
            .add_rigid_body(
                "tip",
                1.0,
                inertia,
                Vec3::ZERO,
                Vec3([1.5, 0.0, 0.0]),
                Mat3::IDENTITY,
                Vec3::ZERO,
                Vec3::ZERO,
            )
            .unwrap();
        for (name, z) in [("front", 0.1), ("back", -0.1)] {
            let g = sys.add_marker("", sys.ground(), Vec3([0.0, 0.0, z]), Mat3::IDENTITY).unwrap();
            let b = sys.add_marker("", body, Vec3([-0.5, 0.0, z]), Mat3::IDENTITY).unwrap();
            sys.add_joint(name, JointKind::Revolute, [g, b]).unwrap();
        }
        let a = sys.add_marker("", body, Vec3([0.5, 0.0, 0.0]), Mat3::IDENTITY).unwrap();
        let b = sys.add_marker("", tip, Vec3([-0.5, 0.0, 0.0]), Mat3::IDENTITY).unwrap();
        sys.add_joint("ball", JointKind::Spherical, [a, b]).unwrap();
        sys.compile().unwrap()
    }

    #[test]
    fn redundant_rows_are_found_reported_and_removed() {
        let model = doubly_hinged();
        // 2 normalizations + 5 + 5 + 3 joint equations; rank 10.
        assert_eq!(model.constraint_count, 15);
        let settings = SimulationSettings::new(1.0, 1e-3);
        let reduction = analyse(&model, &settings).unwrap().expect("redundant");
        let report = &reduction.report;
        assert_eq!((report.rows, report.rank), (15, 10));
        assert_eq!(report.removed_rows.len(), 5);
        // Only joint equations of the two hinges are removed; the ball is not involved.
        let hinges: Vec<usize> =
            model.joints.iter().enumerate().filter(|(_, j)| j.name != "ball").map(|(k, _)| k).collect();
        assert_eq!(report.joints, hinges);
        for &r in &report.removed_rows {
            assert!(
                model.constraint_name(r).contains("joint 'front'")
                    || model.constraint_name(r).contains("joint 'back'")
            );
        }
        assert!(report.message.contains("'front'") && report.message.contains("'back'"));
        assert!(!report.message.contains("'ball'"));
        // The reduced model keeps the other rows in order.
        assert_eq!(reduction.model.constraint_count, 10);
        assert_eq!(reduction.row_map.len(), 10);
        assert!(reduction.row_map.windows(2).all(|w| w[0] < w[1]));
        assert!(reduction.row_map.iter().all(|r| !report.removed_rows.contains(r)));
    }

    #[test]
    fn records_delivered_during_the_run_are_the_final_records() {
        let model = doubly_hinged();
        for handling in [RedundancyHandling::Remove, RedundancyHandling::MinimumNorm] {
            let mut settings = SimulationSettings::new(0.2, 1e-3);
            settings.output_interval = Some(0.01);
            settings.redundancy.handling = handling;
            let mut delivered = Output::default();
            let mut calls = 0;
            let outcome = crate::integrator::simulate(&model, &settings, &mut |p| {
                if calls % 7 == 0 {
                    let chunk = p.records.since(delivered.len());
                    delivered.time.extend(chunk.time);
                    delivered.multipliers.extend(chunk.multipliers);
                    delivered.reactions.extend(chunk.reactions);
                    delivered.constraint_violation.extend(chunk.constraint_violation);
                    assert_eq!(chunk.events[0].kind, "redundant constraints");
                }
                calls += 1;
                true
            });
            assert!(outcome.error.is_none());
            let out = outcome.output;
            let k = delivered.len();
            assert!(k > 10 && k <= out.len(), "{k} of {} records", out.len());
            // The same values as the final output, multipliers of the full model included.
            assert_eq!(delivered.time, out.time[..k]);
            assert_eq!(delivered.multipliers, out.multipliers[..k * model.constraint_count]);
            assert_eq!(delivered.reactions, out.reactions[..k * model.joints.len() * 6]);
            assert_eq!(delivered.constraint_violation, out.constraint_violation[..k]);
        }
    }

    #[test]
    fn error_handling_refuses_the_model_and_independent_models_pass() {
        let model = doubly_hinged();
        let mut settings = SimulationSettings::new(1.0, 1e-3);
        settings.redundancy.handling = RedundancyHandling::Error;
        let error = analyse(&model, &settings).err().expect("refused").to_string();
        assert!(error.contains("5 of 15 constraint equations are redundant"), "{error}");
        // A model without redundancy gives None.
        let mut sys = SystemBuilder::new();
        let body = unit_body(&mut sys, "arm", Vec3::ZERO);
        ground_joint(&mut sys, "hinge", JointKind::Revolute, body, Vec3::ZERO, Vec3::ZERO);
        let single = sys.compile().unwrap();
        assert!(analyse(&single, &SimulationSettings::new(1.0, 1e-3)).unwrap().is_none());
    }
}
