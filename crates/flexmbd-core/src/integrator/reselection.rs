//! A run of a model with redundant constraints, whose kept rows are chosen again when they
//! become ill-conditioned. Which rows of a redundant set are independent depends on the
//! configuration: rows chosen at the start (Bricard's mechanism with some marker frames) can
//! become nearly dependent while the whole set keeps its rank, and the solution near there
//! loses accuracy (the multipliers of the kept rows grow, energy jumps). After accepted steps
//! the conditioning of the kept rows (their smallest singular value over their largest) is
//! compared with its value when they were chosen; below `DEGRADATION` times that, the rows
//! are chosen again at the reached state and, if the new choice is better conditioned by
//! `IMPROVEMENT`, the run continues from that state on the model without the newly chosen
//! redundant rows. Each such segment is reported as a "redundancy re-selected" event; its
//! records continue those of the segments before (the same output times, multipliers of all
//! rows), also for an observer that stores them during the run.
//!
//! The conditioning (a singular value decomposition of the kept rows) costs more than a step
//! of a small model, so it is not computed after every step: the next check is at half the
//! time its trend (linear, from the last two checks) takes to reach the threshold, and at most
//! `MAX_STRIDE` nominal steps later.

use std::cell::Cell;

use crate::error::{FlexmbdError, Result};
use crate::formulation::augmented::{DenseEquations, Level};
use crate::integrator::progress::Progress;
use crate::integrator::redundancy::{select, Reduction};
use crate::integrator::settings::{SimulationSettings, StartState};
use crate::linalg::partition::row_conditioning;
use crate::output::Output;
use crate::system::{Model, State, Workspace};

/// The kept rows are chosen again when their conditioning falls below this fraction of its
/// value when they were chosen.
pub const DEGRADATION: f64 = 0.1;

/// A new choice of rows is taken if its conditioning is at least this factor better.
pub const IMPROVEMENT: f64 = 2.0;

/// Longest time between two checks of the conditioning, in nominal step sizes.
pub const MAX_STRIDE: f64 = 50.0;

/// Largest violation (m or rad) of a left-out row at a check before the run stops with
/// `ConflictingConstraints`. Rows that repeat the kept ones stay at round-off (1e-15 on
/// Bricard's mechanism and the spatial four-bar over 5 s); a driver on a welded joint leaves
/// the weld's row violated by its drive angle.
pub const CONFLICT_LIMIT: f64 = 1e-6;

/// The conditioning of the kept rows of a reduction along the run.
struct Monitor {
    ws: Workspace,
    eq: DenseEquations,
    /// Rows of the original model kept by the reduction.
    kept: Vec<usize>,
    /// Conditioning below which the rows are chosen again.
    threshold: f64,
    /// Time and conditioning of the last check.
    last: (f64, f64),
    /// Time of the next check.
    next_check: f64,
    /// Longest time between checks.
    max_wait: f64,
    /// Rows of the original model left out, and the time they were chosen.
    removed: Vec<usize>,
    since: f64,
}

impl Monitor {
    /// The monitor of `reduction` of `model`, with its conditioning at `state`.
    fn new(model: &Model, reduction: &Reduction, state: &State, step_size: f64) -> Result<Self> {
        let mut monitor = Monitor {
            ws: Workspace::new(model),
            eq: DenseEquations::new(model),
            kept: reduction.row_map.clone(),
            threshold: 0.0,
            last: (state.time, 0.0),
            next_check: state.time,
            max_wait: MAX_STRIDE * step_size,
            removed: (0..model.constraint_count).filter(|r| !reduction.row_map.contains(r)).collect(),
            since: reduction.report.time,
        };
        let now = monitor.conditioning(model, state)?;
        monitor.threshold = DEGRADATION * now;
        monitor.last.1 = now;
        Ok(monitor)
    }

    /// Schedules the next check after one at `time` that found `now` (above the threshold).
    fn schedule(&mut self, time: f64, now: f64) {
        let (t0, v0) = self.last;
        let rate = if time > t0 { (v0 - now) / (time - t0) } else { 0.0 };
        let wait = if rate > 0.0 { 0.5 * (now - self.threshold) / rate } else { self.max_wait };
        self.next_check = time + wait.min(self.max_wait);
        self.last = (time, now);
    }

    /// The conditioning of the kept rows at `state`.
    fn conditioning(&mut self, model: &Model, state: &State) -> Result<f64> {
        let (ws, eq) = (&mut self.ws, &mut self.eq);
        eq.evaluate(
            model,
            ws,
            state.time,
            &state.coordinates,
            &state.velocities,
            &state.discrete,
            Level::Position,
        )?;
        Ok(row_conditioning(eq.jacobian.as_ref(), &self.kept))
    }

    /// The left-out row violated most, if by more than `CONFLICT_LIMIT`, at the state of the
    /// last `conditioning`.
    fn conflict(&self) -> Option<(usize, f64)> {
        let violations = self.removed.iter().map(|&r| (r, self.eq.constraints[r].abs()));
        violations.filter(|&(_, v)| v > CONFLICT_LIMIT || v.is_nan()).max_by(|a, b| a.1.total_cmp(&b.1))
    }

    /// A better choice of rows at `state`, if the kept ones have become ill-conditioned there
    /// and another choice is better by `IMPROVEMENT`; else None (the threshold follows a
    /// conditioning that no choice improves, so it is not tried again at every step).
    fn better_choice(&mut self, model: &Model, state: &State, tolerance: f64) -> Result<Option<Reduction>> {
        if state.time < self.next_check {
            return Ok(None);
        }
        let now = self.conditioning(model, state)?;
        if let Some((row, violation)) = self.conflict() {
            return Err(FlexmbdError::ConflictingConstraints {
                time: state.time,
                item: model.constraint_name(row),
                violation,
                since: self.since,
            });
        }
        if now >= self.threshold {
            self.schedule(state.time, now);
            return Ok(None);
        }
        let reason = format!(
            "the kept constraint rows became ill-conditioned (smallest singular value {now:.3e} of the \
             largest, below {:.3e})",
            self.threshold
        );
        let again = Some((reason.as_str(), self.kept.len()));
        let candidate = select(model, &mut self.ws, &mut self.eq, state, tolerance, again)?;
        if let Some(next) = candidate {
            if row_conditioning(self.eq.jacobian.as_ref(), &next.row_map) >= IMPROVEMENT * now {
                return Ok(Some(next));
            }
        }
        self.threshold = DEGRADATION * now;
        self.last = (state.time, now);
        Ok(None)
    }
}

/// A run of an integrator on a model (`simulation::dispatch`).
pub(crate) type Dispatch = fn(
    &Model,
    &SimulationSettings,
    &mut dyn FnMut(&Progress) -> bool,
    &mut Output,
    &mut Option<State>,
) -> Result<()>;

/// Runs `model` without the redundant rows of `first`, choosing the kept rows again where
/// they become ill-conditioned; the records (of all rows) go to `output`, the last accepted
/// state to `last_state`. Returns the error that stopped the run, if any.
pub(crate) fn run_reduced(
    model: &Model,
    settings: &SimulationSettings,
    observer: &mut dyn FnMut(&Progress) -> bool,
    first: Reduction,
    dispatch: Dispatch,
    output: &mut Output,
    last_state: &mut Option<State>,
) -> Option<FlexmbdError> {
    let handling = settings.redundancy.handling;
    let tolerance = settings.redundancy.tolerance;
    let mut reduction = first;
    let mut segment_settings = settings.clone();
    // The expanded records of the segments before the current one.
    let mut earlier: Option<Output> = None;
    loop {
        let start = State::initial(&reduction.model, reduction.report.time);
        let mut monitor = match Monitor::new(model, &reduction, &start, settings.step_size) {
            Ok(m) => m,
            Err(e) => return Some(e),
        };
        let mut reduced = Output::new(&reduction.model);
        let mut segment_last = None;
        let mut next: Option<Reduction> = None;
        let mut failure: Option<FlexmbdError> = None;
        let release = Cell::new(0);
        let error = {
            let mut watching = |p: &Progress| {
                match monitor.better_choice(model, p.state, tolerance) {
                    Ok(Some(choice)) => {
                        next = Some(choice);
                        return false;
                    }
                    Ok(None) => {}
                    Err(e) => {
                        failure = Some(e);
                        return false;
                    }
                }
                let records = p.records.expanded(model, &reduction, handling);
                let before = earlier.as_ref().map_or(0, |e| e.statistics.steps);
                let go_on = match &earlier {
                    None => observer(&Progress { records, release: &release, ..*p }),
                    Some(e) => {
                        let records = records.after(e);
                        observer(&Progress { records, steps: before + p.steps, release: &release, ..*p })
                    }
                };
                // Released records are the earlier segments' first.
                let count = release.take();
                let from_earlier = earlier.as_ref().map_or(0, |e| count.min(e.len()));
                if let Some(e) = earlier.as_mut() {
                    e.release_front(from_earlier);
                }
                p.release.set(count - from_earlier);
                go_on
            };
            dispatch(&reduction.model, &segment_settings, &mut watching, &mut reduced, &mut segment_last)
                .err()
        };
        let expanded = reduction.expand_output(model, reduced, handling);
        let combined = match earlier.take() {
            None => expanded,
            Some(mut e) => {
                e.append(expanded);
                e
            }
        };
        let state = segment_last.map(|s| reduction.expand_state(model, s));
        let interrupted = matches!(error, Some(FlexmbdError::Interrupted { .. }));
        match (next, failure, state) {
            (Some(choice), None, Some(state)) if interrupted => {
                segment_settings.start = Some(StartState {
                    coordinates: state.coordinates,
                    velocities: state.velocities,
                    time: Some(state.time),
                    discrete: Some(state.discrete),
                    recorded: true,
                });
                segment_settings.initial.strict = false;
                reduction = choice;
                earlier = Some(combined);
            }
            (_, failure, state) => {
                *output = combined;
                *last_state = state;
                return failure.or(error);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::simulation::dispatch;
    use crate::joint::JointKind;
    use crate::math::{Mat3, Vec3};
    use crate::output::Redundancy;
    use crate::SystemBuilder;

    /// Bricard's mechanism (`flexmbd.examples.bricard`) with every joint marker turned a
    /// quarter turn about its joint axis. Which row the analysis removes at the start is a near
    /// tie between joint 0's 'y' and joint 5's 'x' equations; without joint 0's 'y', the kept
    /// rows become nearly dependent near t = 1.15 s.
    fn bricard_turned() -> Model {
        let corners =
            [[0., 0., 0.], [1., 0., 0.], [1., -1., 0.], [1., -1., 1.], [0., -1., 1.], [0., 0., 1.]].map(Vec3);
        let axes =
            [[0., 1., 0.], [0., 0., 1.], [1., 0., 0.], [0., 1., 0.], [0., 0., 1.], [1., 0., 0.]].map(Vec3);
        let frame = |x: Vec3, z: Vec3| Mat3::from_columns(x, z.cross(&x), z);
        let quarter_turn = |a: Vec3| {
            let k = a.skew();
            let k2 = k.mul_mat(&k);
            Mat3(std::array::from_fn(|i| {
                std::array::from_fn(|j| Mat3::IDENTITY.0[i][j] + k.0[i][j] + k2.0[i][j])
            }))
        };
        let along = |k: usize| {
            let (a, b) = (corners[k], corners[(k + 1) % 6]);
            Vec3([b.0[0] - a.0[0], b.0[1] - a.0[1], b.0[2] - a.0[2]])
        };
        let mut sys = SystemBuilder::new();
        sys.set_gravity(Vec3([0.0, -9.81, 0.0])).unwrap();
        let inertia = Mat3::diagonal(Vec3([0.01 / 6.0, 1.01 / 12.0, 1.01 / 12.0]));
        let mut links = vec![sys.ground()];
        let mut frames = vec![Mat3::IDENTITY];
        let mut centres = vec![Vec3::ZERO];
        for k in 0..5 {
            let centre = Vec3(std::array::from_fn(|i| 0.5 * (corners[k].0[i] + corners[k + 1].0[i])));
            let orientation = frame(along(k), axes[k]);
            let name = format!("link {}", k + 1);
            links.push(
                sys.add_rigid_body(
                    &name,
                    1.0,
                    inertia,
                    Vec3::ZERO,
                    centre,
                    orientation,
                    Vec3::ZERO,
                    Vec3::ZERO,
                )
                .unwrap(),
            );
            frames.push(orientation);
            centres.push(centre);
        }
        let marker = |sys: &mut SystemBuilder, link: usize, corner: usize| {
            let global = quarter_turn(axes[corner]).mul_mat(&frame(along(corner), axes[corner]));
            let offset = Vec3(std::array::from_fn(|i| corners[corner].0[i] - centres[link].0[i]));
            let to_local = frames[link].transpose();
            sys.add_marker("", links[link], to_local.mul_vec(&offset), to_local.mul_mat(&global)).unwrap()
        };
        for (lower, higher, corner) in [(0, 1, 0), (1, 2, 1), (2, 3, 2), (3, 4, 3), (4, 5, 4), (5, 0, 5)] {
            let a = marker(&mut sys, lower, corner);
            let b = marker(&mut sys, higher, corner);
            sys.add_joint(&format!("joint {corner}"), JointKind::Revolute, [a, b]).unwrap();
        }
        sys.compile().unwrap()
    }

    /// The run of `model` starting without joint 0's 'y' equation.
    fn run_without_joint_0_y(
        model: &Model,
        settings: &SimulationSettings,
        observer: &mut dyn FnMut(&Progress) -> bool,
    ) -> (Output, Option<FlexmbdError>) {
        let m = model.constraint_count;
        let row = (0..m)
            .find(|&r| model.constraint_name(r) == "joint 'joint 0' (revolute) equation 'y'")
            .expect("the row");
        let (reduced, row_map) = model.without_constraint_rows(&[row]).unwrap();
        let message = "joint 0's 'y' removed".to_string();
        let report = Redundancy {
            time: 0.0,
            rows: m,
            rank: m - 1,
            removed_rows: vec![row],
            groups: vec![],
            joints: vec![],
            message,
        };
        let first =
            Reduction { model: reduced, row_map, report, tolerance: 1e-9, event: "redundant constraints" };
        let (mut output, mut last) = (Output::default(), None);
        let error = run_reduced(model, settings, observer, first, dispatch, &mut output, &mut last);
        (output, error)
    }

    #[test]
    fn records_delivered_and_released_across_a_re_selection_are_the_run_s_records() {
        let model = bricard_turned();
        let mut settings = SimulationSettings::new(2.0, 1e-3);
        settings.output_interval = Some(0.01);
        settings.spectral_radius = 1.0;
        let (whole, error) = run_without_joint_0_y(&model, &settings, &mut |_| true);
        assert!(error.is_none(), "{error:?}");
        let kinds: Vec<&str> = whole.events.iter().map(|e| e.kind.as_str()).collect();
        assert_eq!(kinds, ["redundant constraints", "redundancy re-selected"], "{:?}", whole.events);
        assert!(whole.events[1].time > 1.0 && whole.events[1].time < 1.2);
        assert_eq!(whole.len(), 201);
        assert_eq!(whole.multipliers.len(), 201 * model.constraint_count);

        // An observer that stores the records held at every third call and releases them.
        let mut delivered = Output::default();
        let mut calls = 0;
        let (rest, error) = run_without_joint_0_y(&model, &settings, &mut |p| {
            calls += 1;
            if calls % 3 == 0 {
                let chunk = p.records.since(0);
                assert_eq!(chunk.released, delivered.len());
                delivered.time.extend(&chunk.time);
                delivered.coordinates.extend(&chunk.coordinates);
                delivered.multipliers.extend(&chunk.multipliers);
                p.release.set(p.records.len());
            }
            true
        });
        assert!(error.is_none());
        assert_eq!(rest.released, delivered.len());
        delivered.time.extend(&rest.time);
        delivered.coordinates.extend(&rest.coordinates);
        delivered.multipliers.extend(&rest.multipliers);
        assert_eq!(delivered.time, whole.time);
        assert_eq!(delivered.coordinates, whole.coordinates);
        assert_eq!(delivered.multipliers, whole.multipliers);
        assert_eq!(rest.statistics, whole.statistics);
        assert_eq!(rest.events, whole.events);
    }
}
