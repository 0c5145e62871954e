//! Results of a simulation: the state at every output time, and the derived quantities users
//! ask for (joint reactions, sensors, energies, constraint violation), stored as flat
//! time-major arrays (`[output index][item]`).

use crate::assembly::{joint_pair, update_kinematics};
use crate::body::marker::marker_accelerations;
use crate::body::{flexible, point_mass, rigid, BodyKind};
use crate::force::gravity::gravity_potential;
use crate::force::joint_actuator::{effort_at, ActuatedCoordinate};
use crate::force::{force_potential, nonconservative_power, ForceKind, ForceLocal};
use crate::joint::equation::equation_value;
use crate::joint::reaction::joint_reaction;
use crate::system::sensor::SensorQuantity;
use crate::system::{Model, State, Workspace};

/// Counters of a run.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Statistics {
    /// Accepted steps.
    pub steps: usize,
    /// Rejected step attempts (Newton failure or error test).
    pub rejected_steps: usize,
    /// Newton iterations over all attempts.
    pub newton_iterations: usize,
    /// Numeric factorizations of the Newton matrix.
    pub factorizations: usize,
    /// Smallest step size used (s).
    pub min_step_size_used: f64,
    /// Largest step size used (s).
    pub max_step_size_used: f64,
    /// Evaluations of the accelerations (explicit integrators).
    pub function_evaluations: usize,
    /// TR-BDF2: Jacobians of the iteration matrix formed (by differences or from the tree's
    /// linearized equations of motion).
    pub jacobian_evaluations: usize,
    /// Joint coordinates: the dimension of the acceleration system solved per evaluation
    /// (joint space: the free coordinates plus the cut rows; seed eq. 40 or 41: see
    /// `TreeSolver::reduced_size`); 0 otherwise.
    pub reduced_system_size: usize,
}

/// Something that happened during a run and is reported with the results: a repartition of
/// the coordinates, constraint drift beyond a threshold, redundant constraints removed.
#[derive(Clone, Debug, PartialEq)]
pub struct Event {
    /// Time (s).
    pub time: f64,
    /// Kind: "repartition", "constraint drift", "redundant constraints".
    pub kind: String,
    /// Description.
    pub message: String,
}

/// The result of the analysis of a redundant model.
#[derive(Clone, Debug, PartialEq)]
pub struct Redundancy {
    /// Time of the analysis (the start).
    pub time: f64,
    /// Number of constraint rows.
    pub rows: usize,
    /// Rank of C_q.
    pub rank: usize,
    /// Removed rows.
    pub removed_rows: Vec<usize>,
    /// Groups of rows that are linearly dependent together (one per null vector of C_q^T).
    pub groups: Vec<Vec<usize>>,
    /// Joints with rows in a group.
    pub joints: Vec<usize>,
    /// Human-readable summary.
    pub message: String,
}

/// Energies per record: kinetic, potential (strain included), strain, and the power of what
/// stores no energy (see [`Output::energy`]).
pub const ENERGY_WIDTH: usize = 4;

/// Recorded results.
#[derive(Clone, Debug, Default)]
pub struct Output {
    /// Number of coordinates per record.
    pub coordinate_count: usize,
    /// Number of multipliers per record.
    pub constraint_count: usize,
    /// Number of joints.
    pub joint_count: usize,
    /// Number of discrete variables per record.
    pub discrete_count: usize,
    /// Output times (s).
    pub time: Vec<f64>,
    /// q, time-major (records x coordinates).
    pub coordinates: Vec<f64>,
    /// q_dot.
    pub velocities: Vec<f64>,
    /// q_dd.
    pub accelerations: Vec<f64>,
    /// lambda (records x constraints).
    pub multipliers: Vec<f64>,
    /// Per record and joint: force (3) and torque (3) on marker j's body at marker j, in
    /// marker j's axes (records x joints x 6).
    pub reactions: Vec<f64>,
    /// Sensor values, per record the sensors' values concatenated.
    pub sensors: Vec<f64>,
    /// Offset of each sensor within a record's sensor values; last entry = record width.
    pub sensor_offsets: Vec<usize>,
    /// Kinetic energy, potential energy (gravity, springs and strain) and the strain energy
    /// of the deformable bodies in it (J), then the power (W) of the forces no potential
    /// accounts for: point forces, torques, actuators and callback forces, the dampers of the
    /// spring-dampers and the structural damping of the deformable bodies (records x
    /// [`ENERGY_WIDTH`]). The drivers' power is not in it (their efforts are multipliers).
    /// NaN where a callback force cannot be evaluated again at the record.
    pub energy: Vec<f64>,
    /// Largest absolute position-level constraint violation per record.
    pub constraint_violation: Vec<f64>,
    /// The discrete variables of the state (unwrapped spring and actuator angles, actuator
    /// saturation states; records x `discrete_count`): a run continued from a record goes on
    /// from them.
    pub discrete: Vec<f64>,
    /// Counters.
    pub statistics: Statistics,
    /// Events, in order.
    pub events: Vec<Event>,
    /// The redundant constraints found at the start, if any.
    pub redundancy: Option<Redundancy>,
    /// Records released from the front by [`Output::release_front`] (stored elsewhere by the
    /// caller during the run): the first record held is record `released` of the run.
    pub released: usize,
}

impl Output {
    /// Empty output for `model`.
    pub fn new(model: &Model) -> Self {
        let mut offsets = vec![0];
        for s in &model.sensors {
            offsets.push(offsets.last().unwrap() + s.quantity.size());
        }
        Output {
            coordinate_count: model.coordinate_count,
            constraint_count: model.constraint_count,
            joint_count: model.joints.len(),
            discrete_count: model.discrete_count,
            sensor_offsets: offsets,
            ..Default::default()
        }
    }

    /// Number of records.
    pub fn len(&self) -> usize {
        self.time.len()
    }

    /// True if nothing was recorded.
    pub fn is_empty(&self) -> bool {
        self.time.is_empty()
    }

    /// The records from index `from` on (none if `from >= len`), with the statistics, events
    /// and redundancy report so far: what a results file written during the run appends.
    pub fn since(&self, from: usize) -> Output {
        let from = from.min(self.len());
        let width = *self.sensor_offsets.last().unwrap_or(&0);
        let rows = |data: &Vec<f64>, per: usize| data[from * per..].to_vec();
        Output {
            coordinate_count: self.coordinate_count,
            constraint_count: self.constraint_count,
            joint_count: self.joint_count,
            discrete_count: self.discrete_count,
            time: rows(&self.time, 1),
            coordinates: rows(&self.coordinates, self.coordinate_count),
            velocities: rows(&self.velocities, self.coordinate_count),
            accelerations: rows(&self.accelerations, self.coordinate_count),
            multipliers: rows(&self.multipliers, self.constraint_count),
            reactions: rows(&self.reactions, self.joint_count * 6),
            sensors: rows(&self.sensors, width),
            sensor_offsets: self.sensor_offsets.clone(),
            energy: rows(&self.energy, ENERGY_WIDTH),
            constraint_violation: rows(&self.constraint_violation, 1),
            discrete: rows(&self.discrete, self.discrete_count),
            statistics: self.statistics.clone(),
            events: self.events.clone(),
            redundancy: self.redundancy.clone(),
            released: self.released + from,
        }
    }

    /// Appends the records of `later` (a run continued from this one's end), its events and
    /// its counts; the redundancy report stays this one's if it has one. Records `later`
    /// released were released after all of this one's (which then holds none).
    pub fn append(&mut self, later: Output) {
        debug_assert!(later.released == 0 || self.is_empty());
        self.released += later.released;
        self.time.extend(later.time);
        self.coordinates.extend(later.coordinates);
        self.velocities.extend(later.velocities);
        self.accelerations.extend(later.accelerations);
        self.multipliers.extend(later.multipliers);
        self.reactions.extend(later.reactions);
        self.sensors.extend(later.sensors);
        self.energy.extend(later.energy);
        self.constraint_violation.extend(later.constraint_violation);
        self.discrete.extend(later.discrete);
        self.events.extend(later.events);
        self.redundancy = self.redundancy.take().or(later.redundancy);
        let (s, l) = (&mut self.statistics, later.statistics);
        s.steps += l.steps;
        s.rejected_steps += l.rejected_steps;
        s.newton_iterations += l.newton_iterations;
        s.factorizations += l.factorizations;
        s.function_evaluations += l.function_evaluations;
        s.jacobian_evaluations += l.jacobian_evaluations;
        s.min_step_size_used = s.min_step_size_used.min(l.min_step_size_used);
        s.max_step_size_used = s.max_step_size_used.max(l.max_step_size_used);
        s.reduced_system_size = s.reduced_system_size.max(l.reduced_system_size);
    }

    /// Drops the first `count` records held (at most all of them): a caller that stored them
    /// elsewhere (a results file) keeps the memory of a run flat however long it is.
    pub fn release_front(&mut self, count: usize) {
        let count = count.min(self.len());
        if count == 0 {
            return;
        }
        let width = *self.sensor_offsets.last().unwrap_or(&0);
        let n = self.coordinate_count;
        let drop = |data: &mut Vec<f64>, per: usize| {
            data.drain(..count * per);
        };
        drop(&mut self.time, 1);
        drop(&mut self.coordinates, n);
        drop(&mut self.velocities, n);
        drop(&mut self.accelerations, n);
        drop(&mut self.multipliers, self.constraint_count);
        drop(&mut self.reactions, self.joint_count * 6);
        drop(&mut self.sensors, width);
        drop(&mut self.energy, ENERGY_WIDTH);
        drop(&mut self.constraint_violation, 1);
        drop(&mut self.discrete, self.discrete_count);
        self.released += count;
    }

    /// Appends a record of `state`. Updates the workspace's marker kinematics.
    pub fn record(&mut self, model: &Model, state: &State, ws: &mut Workspace) {
        let (q, qd, qdd) = (&state.coordinates, &state.velocities, &state.accelerations);
        update_kinematics(model, q, qd, ws);
        self.time.push(state.time);
        self.coordinates.extend_from_slice(q);
        self.velocities.extend_from_slice(qd);
        self.accelerations.extend_from_slice(qdd);
        self.multipliers.extend_from_slice(&state.multipliers);
        self.discrete.extend_from_slice(&state.discrete);

        // Reactions and constraint violation.
        let mut violation = 0.0f64;
        for nz in &model.normalizations {
            let pp: f64 = nz.dofs.iter().map(|&d| q[d] * q[d]).sum();
            violation = violation.max((pp - 1.0).abs());
        }
        for j in 0..model.joints.len() {
            let joint = &model.joints[j];
            let driver = joint.driver_values(state.time).unwrap_or([f64::NAN; 3]);
            let mut scratch = std::mem::take(&mut ws.joints[j].scratch);
            let pair = joint_pair(model, &ws.markers, j);
            for eq in &joint.equations {
                violation = violation.max(equation_value(eq, &pair, &driver)[0].abs());
            }
            let lambda = &state.multipliers[joint.row..joint.row + joint.equations.len()];
            let (force, torque) = joint_reaction(joint, &pair, &driver, lambda, q, &mut scratch);
            ws.joints[j].scratch = scratch;
            self.reactions.extend_from_slice(&force.0);
            self.reactions.extend_from_slice(&torque.0);
        }
        self.constraint_violation.push(violation);

        // Sensors.
        for s in &model.sensors {
            let m = &model.markers[s.marker.0];
            let body = &model.bodies[m.body.0];
            let kin = &ws.markers[s.marker.0];
            match s.quantity {
                SensorQuantity::Position => self.sensors.extend_from_slice(&kin.position.0),
                SensorQuantity::Velocity => self.sensors.extend_from_slice(&kin.velocity().0),
                SensorQuantity::Orientation => {
                    for row in kin.rotation.0 {
                        self.sensors.extend_from_slice(&row);
                    }
                }
                SensorQuantity::AngularVelocity => self.sensors.extend_from_slice(&kin.angular_velocity().0),
                SensorQuantity::Effort { force, .. } => {
                    self.sensors.push(actuator_effort(model, state, ws, force))
                }
                SensorQuantity::Acceleration | SensorQuantity::AngularAcceleration => {
                    let (acc, ang) = marker_accelerations(body, m, q, qd, qdd);
                    let v = if s.quantity == SensorQuantity::Acceleration { acc } else { ang };
                    self.sensors.extend_from_slice(&v.0);
                }
            }
        }

        // Energies.
        let mut kinetic = 0.0;
        let mut potential = 0.0;
        let mut strain = 0.0;
        for (bi, body) in model.bodies.iter().enumerate() {
            let o = body.offset;
            let n = body.dofs.len();
            kinetic += match &body.kind {
                BodyKind::Ground => 0.0,
                BodyKind::Rigid(rb) => rigid::kinetic_energy(rb, &q[o..], &qd[o..]),
                BodyKind::PointMass { mass } => point_mass::kinetic_energy(*mass, &qd[o..]),
                BodyKind::Flexible(fb) => {
                    let work = ws.flexible[bi].as_mut().expect("workspace of a flexible body");
                    strain += flexible::strain_energy(fb, &q[o..o + n]);
                    flexible::kinetic_energy(fb, &q[o..o + n], &qd[o..o + n], &mut work.scratch)
                }
            };
            potential += gravity_potential(body, q, &model.gravity);
        }
        let mut power: f64 = model
            .bodies
            .iter()
            .map(|body| match &body.kind {
                BodyKind::Flexible(fb) => {
                    flexible::damping_power(fb, &qd[body.offset..body.offset + body.dofs.len()])
                }
                _ => 0.0,
            })
            .sum();
        let mut locals = std::mem::take(&mut ws.forces);
        let env = model.force_env(state, ws);
        for (f, local) in model.forces.iter().zip(locals.iter_mut()) {
            potential += force_potential(f, &env);
            power += nonconservative_power(f, &env, local).unwrap_or(f64::NAN);
        }
        ws.forces = locals;
        self.energy.push(kinetic);
        self.energy.push(potential + strain);
        self.energy.push(strain);
        self.energy.push(power);
    }
}

/// The effort of the joint actuator that is force element `force` at `state` (the marker
/// kinematics of `ws` up to date); NaN where its set point cannot be evaluated.
fn actuator_effort(model: &Model, state: &State, ws: &Workspace, force: usize) -> f64 {
    let element = &model.forces[force];
    let ForceKind::JointActuator { markers, coordinate, law } = &element.kind else {
        return f64::NAN;
    };
    let env = model.force_env(state, ws);
    let reference = match (coordinate, element.discrete) {
        (ActuatedCoordinate::Angle, Some(k)) => state.discrete[k],
        _ => 0.0,
    };
    let mut local = ForceLocal::with_size(element.dofs.len());
    let item = format!("actuator '{}'", element.name);
    effort_at(&item, &env.pair(markers), *coordinate, law, reference, state.time, &mut local)
        .map_or(f64::NAN, |e| e.effort)
}
