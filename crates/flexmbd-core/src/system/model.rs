//! The compiled, immutable model (house style 1): bodies with their coordinate ranges,
//! markers, joints with their constraint rows, force elements, sensors, the initial state as
//! given, and the layout of the sparse Newton matrix.
//!
//! Global vectors: q has `coordinate_count` entries (bodies in order); lambda has
//! `constraint_count` entries: one Euler-parameter normalization row per rigid body first,
//! then the joints' equations in order. The Newton matrix is square of size
//! coordinate_count + constraint_count: [[S, C_q^T], [C_q, 0]].

use crate::body::flexible::REFERENCE_COORDINATES;
use crate::body::marker::Marker;
use crate::body::{Body, BodyKind};
use crate::error::{FlexmbdError, Result};
use crate::force::{ForceElement, ForceEnv, ForceKind, Frame};
use crate::ids::{BodyId, MarkerId};
use crate::joint::equation::Primitive;
use crate::joint::Joint;
use crate::linalg::sparse::{PatternBuilder, SparsePattern};
use crate::math::Vec3;
use crate::system::builder::SystemBuilder;
use crate::system::sensor::{Sensor, SensorQuantity};
use crate::system::{State, Workspace};

/// The normalization constraint p.p - 1 = 0 of one rigid body.
#[derive(Clone, Debug)]
pub struct Normalization {
    /// The body.
    pub body: BodyId,
    /// Constraint row (index into lambda).
    pub row: usize,
    /// Global indices of its Euler parameters.
    pub dofs: [usize; 4],
}

/// Value indices of a joint's entries in the Newton matrix.
#[derive(Clone, Debug)]
pub struct JointEntries {
    /// C_q block (equations x local coordinates), row-major.
    pub jacobian: Vec<usize>,
    /// C_q^T block, stored in the same (equation, coordinate) order.
    pub jacobian_transpose: Vec<usize>,
    /// Hessian block (local x local), row-major.
    pub hessian: Vec<usize>,
}

/// Value indices of a body's entries in the Newton matrix.
#[derive(Clone, Debug, Default)]
pub struct BodyEntries {
    /// Dense block over the body's reference coordinates (all of a rigid body or point mass,
    /// [R, p] of a deformable body), row-major.
    pub block: Vec<usize>,
    /// Diagonal entries of all its coordinates.
    pub diagonal: Vec<usize>,
    /// Deformable body: the (reference, elastic) block, 7 x n_f row-major.
    pub reference_elastic: Vec<usize>,
    /// Deformable body: the (elastic, reference) block, n_f x 7 row-major.
    pub elastic_reference: Vec<usize>,
    /// Deformable body: each entry of its elastic pattern.
    pub elastic: Vec<usize>,
}

/// Where each element writes in the Newton matrix.
#[derive(Clone, Debug)]
pub struct MatrixLayout {
    /// The pattern.
    pub pattern: SparsePattern,
    /// Per body (empty for the ground).
    pub bodies: Vec<BodyEntries>,
    /// Per normalization: its 4 C_q entries, then its 4 C_q^T entries.
    pub normalizations: Vec<[usize; 8]>,
    /// Per joint.
    pub joints: Vec<JointEntries>,
    /// Per force element: its square block, row-major.
    pub forces: Vec<Vec<usize>>,
}

/// A compiled multibody model. Never changes during a simulation.
#[derive(Clone, Debug)]
pub struct Model {
    /// Gravitational acceleration (m/s^2).
    pub gravity: Vec3,
    /// Bodies; index 0 is the ground.
    pub bodies: Vec<Body>,
    /// Markers.
    pub markers: Vec<Marker>,
    /// Joints and drivers.
    pub joints: Vec<Joint>,
    /// Force elements.
    pub forces: Vec<ForceElement>,
    /// Sensors.
    pub sensors: Vec<Sensor>,
    /// Number of generalized coordinates.
    pub coordinate_count: usize,
    /// Number of constraint equations (normalizations and joints).
    pub constraint_count: usize,
    /// Normalization constraints of the rigid bodies.
    pub normalizations: Vec<Normalization>,
    /// Number of discrete state variables.
    pub discrete_count: usize,
    /// Initial coordinates as given by the user (before the constraints are enforced).
    pub initial_coordinates: Vec<f64>,
    /// Initial velocities as given by the user.
    pub initial_velocities: Vec<f64>,
    /// Sparse matrix layout.
    pub layout: MatrixLayout,
}

impl Model {
    /// What the force elements read at `state`, with the marker kinematics of `ws` (up to
    /// date for the state).
    pub fn force_env<'a>(&'a self, state: &'a State, ws: &'a Workspace) -> ForceEnv<'a> {
        ForceEnv {
            bodies: &self.bodies,
            markers: &self.markers,
            kinematics: &ws.markers,
            q: &state.coordinates,
            qd: &state.velocities,
            time: state.time,
            discrete: &state.discrete,
        }
    }

    /// Whether the model has deformable bodies whose elastic coordinates the linear solves
    /// condense ([`crate::body::is_condensed`]).
    pub fn has_condensed_bodies(&self) -> bool {
        self.bodies.iter().any(|b| crate::body::is_condensed(&b.kind))
    }

    /// Dimension of the Newton matrix.
    pub fn system_size(&self) -> usize {
        self.coordinate_count + self.constraint_count
    }

    /// Describes a constraint row for messages: `joint 'pivot' (revolute) equation 'axis x'`.
    pub fn constraint_name(&self, row: usize) -> String {
        if let Some(n) = self.normalizations.iter().find(|n| n.row == row) {
            return format!("Euler-parameter normalization of body '{}'", self.bodies[n.body.0].name);
        }
        for j in &self.joints {
            if row >= j.row && row < j.row + j.equations.len() {
                return format!(
                    "joint '{}' ({}) equation '{}'",
                    j.name,
                    j.kind.type_name(),
                    j.equations[row - j.row].label
                );
            }
        }
        format!("constraint row {row}")
    }

    /// Describes a coordinate for messages: `body 'crank' coordinate 4 (e1)`.
    pub fn coordinate_name(&self, index: usize) -> String {
        for b in &self.bodies {
            if let Some(k) = b.dofs.iter().position(|&d| d == index) {
                let names = ["x", "y", "z", "e0", "e1", "e2", "e3"];
                return match names.get(k) {
                    Some(name) => format!("body '{}' coordinate {name}", b.name),
                    None => format!("body '{}' elastic coordinate {}", b.name, k - 7),
                };
            }
        }
        format!("coordinate {index}")
    }

    /// The model without the given joint equations (constraint rows), for redundant
    /// constraints: the remaining rows are renumbered in order and the matrix layout rebuilt.
    /// Also returns, for each row of the new model, its row in this one. Normalization rows
    /// cannot be removed.
    pub fn without_constraint_rows(&self, removed: &[usize]) -> Result<(Model, Vec<usize>)> {
        let mut drop = vec![false; self.constraint_count];
        for &r in removed {
            if r >= self.constraint_count || self.normalizations.iter().any(|n| n.row == r) {
                return Err(FlexmbdError::InvalidParameter {
                    item: "constraint removal".to_string(),
                    message: format!("cannot remove {}", self.constraint_name(r)),
                });
            }
            drop[r] = true;
        }
        let mut model = self.clone();
        let mut row_map: Vec<usize> = model.normalizations.iter().map(|n| n.row).collect();
        let mut row = row_map.len();
        for joint in &mut model.joints {
            let first = joint.row;
            let mut kept = Vec::with_capacity(joint.equations.len());
            for (e, eq) in joint.equations.drain(..).enumerate() {
                if !drop[first + e] {
                    kept.push(eq);
                    row_map.push(first + e);
                }
            }
            joint.equations = kept;
            joint.row = row;
            row += joint.equations.len();
        }
        model.constraint_count = row;
        model.layout = matrix_layout(
            &model.bodies,
            &model.normalizations,
            &model.joints,
            &model.forces,
            model.coordinate_count,
            model.constraint_count,
        );
        Ok((model, row_map))
    }

    /// Body of a marker.
    pub fn marker_body(&self, marker: MarkerId) -> &Body {
        &self.bodies[self.markers[marker.0].body.0]
    }
}

impl SystemBuilder {
    /// Checks the whole system and compiles the immutable [`Model`].
    pub fn compile(&self) -> Result<Model> {
        let (bodies, initial_coordinates, initial_velocities) = self.compiled_bodies()?;
        let coordinate_count = initial_coordinates.len();
        let markers = self.compiled_markers(&bodies);
        // Constraint rows: normalizations, then joints.
        let normalizations = normalizations(&bodies);
        let (joints, constraint_count) = self.compiled_joints(&markers, normalizations.len());
        let (forces, discrete_count) = self.compiled_forces(&bodies, &markers);
        let sensors = self
            .sensors
            .iter()
            .map(|s| Sensor { name: s.name.clone(), marker: s.marker, quantity: s.quantity })
            .collect();
        let layout =
            matrix_layout(&bodies, &normalizations, &joints, &forces, coordinate_count, constraint_count);
        Ok(Model {
            gravity: self.gravity,
            bodies,
            markers,
            joints,
            forces,
            sensors,
            coordinate_count,
            constraint_count,
            normalizations,
            discrete_count,
            initial_coordinates,
            initial_velocities,
            layout,
        })
    }

    /// The bodies with their coordinates (bodies in order), and the initial coordinates and
    /// velocities. A system without moving bodies is an error.
    fn compiled_bodies(&self) -> Result<(Vec<Body>, Vec<f64>, Vec<f64>)> {
        let mut bodies = Vec::with_capacity(self.bodies.len());
        let mut initial_coordinates = Vec::new();
        let mut initial_velocities = Vec::new();
        for def in &self.bodies {
            let offset = initial_coordinates.len();
            let (q, qd) = SystemBuilder::initial_body_state(def);
            let dofs: Vec<usize> = (offset..offset + q.len()).collect();
            initial_coordinates.extend(q);
            initial_velocities.extend(qd);
            bodies.push(Body { name: def.name.clone(), kind: def.kind.clone(), offset, dofs });
        }
        if initial_coordinates.is_empty() {
            return Err(FlexmbdError::InvalidModel {
                item: "system".to_string(),
                message: "the system has no moving bodies".to_string(),
            });
        }
        Ok((bodies, initial_coordinates, initial_velocities))
    }

    /// The markers with the coordinates they depend on (a marker on a deformable body: the
    /// reference coordinates and the elastic ones of its shape), and the Jacobians of their
    /// axes and angular velocity where something differentiates them.
    fn compiled_markers(&self, bodies: &[Body]) -> Vec<Marker> {
        let mut markers: Vec<Marker> = self
            .markers
            .iter()
            .map(|m| {
                let body = &bodies[m.body.0];
                let dofs = match (&body.kind, &m.elastic) {
                    (BodyKind::Flexible(_), elastic) => {
                        let mut d = body.dofs[..REFERENCE_COORDINATES].to_vec();
                        if let Some(e) = elastic {
                            d.extend(e.indices.iter().map(|&i| body.offset + REFERENCE_COORDINATES + i));
                        }
                        d
                    }
                    _ => body.dofs.clone(),
                };
                Marker {
                    name: m.name.clone(),
                    body: m.body,
                    position: m.position,
                    rotation: m.orientation,
                    elastic: m.elastic.clone(),
                    dofs,
                    axis_jacobians: [false; 3],
                    angular_jacobian: false,
                }
            })
            .collect();
        self.mark_differentiated_axes(&mut markers);
        markers
    }

    /// Sets the axis Jacobians of `markers` only where an equation or force differentiates
    /// the axes, and the angular-velocity Jacobian where a torque is applied or an angular
    /// velocity is observed.
    fn mark_differentiated_axes(&self, markers: &mut [Marker]) {
        for def in &self.joints {
            for eq in def.kind.equations() {
                for (_, primitive) in &eq.terms {
                    match primitive {
                        Primitive::AxisDotAxis(k, l) => {
                            markers[def.markers[0].0].axis_jacobians[*k] = true;
                            markers[def.markers[1].0].axis_jacobians[*l] = true;
                        }
                        Primitive::AxisDotOffset(k) => markers[def.markers[0].0].axis_jacobians[*k] = true,
                        _ => {}
                    }
                }
            }
        }
        for def in &self.forces {
            let uses_axes = match &def.kind {
                ForceKind::PointForce { frame, .. } | ForceKind::Torque { frame, .. } => {
                    *frame == Frame::Marker
                }
                ForceKind::RotationalSpringDamper { .. } | ForceKind::JointActuator { .. } => true,
                _ => false,
            };
            if uses_axes {
                for m in def.kind.markers() {
                    markers[m.0].axis_jacobians = [true; 3];
                }
            }
            if let ForceKind::Torque { .. } = def.kind {
                for m in def.kind.markers() {
                    markers[m.0].angular_jacobian = true;
                }
            }
        }
        for s in self.sensors.iter().filter(|s| s.quantity == SensorQuantity::AngularVelocity) {
            markers[s.marker.0].angular_jacobian = true;
        }
    }

    /// The joints with their equations, coordinates and first constraint row (from
    /// `first_row` on, in order), and the number of constraint rows in all.
    fn compiled_joints(&self, markers: &[Marker], first_row: usize) -> (Vec<Joint>, usize) {
        let mut row = first_row;
        let mut joints = Vec::with_capacity(self.joints.len());
        for def in &self.joints {
            let mi = &markers[def.markers[0].0];
            let mj = &markers[def.markers[1].0];
            let mut dofs = mi.dofs.clone();
            dofs.extend_from_slice(&mj.dofs);
            let equations = def.kind.equations();
            let count = equations.len();
            joints.push(Joint {
                name: def.name.clone(),
                kind: def.kind.clone(),
                markers: def.markers,
                equations,
                row,
                dofs,
                n_i: mi.dofs.len(),
            });
            row += count;
        }
        (joints, row)
    }

    /// The force elements with the coordinates they act on and their discrete variables,
    /// and the number of discrete variables.
    fn compiled_forces(&self, bodies: &[Body], markers: &[Marker]) -> (Vec<ForceElement>, usize) {
        let mut discrete_count = 0;
        let mut forces = Vec::with_capacity(self.forces.len());
        for def in &self.forces {
            let (dofs, n_i) = match &def.kind {
                ForceKind::Callback { bodies: list, .. } => {
                    (list.iter().flat_map(|b| bodies[b.0].dofs.clone()).collect::<Vec<_>>(), 0)
                }
                kind => {
                    let ms = kind.markers();
                    let first = markers[ms[0].0].dofs.clone();
                    let n_i = first.len();
                    let mut dofs = first;
                    for m in &ms[1..] {
                        dofs.extend_from_slice(&markers[m.0].dofs);
                    }
                    (dofs, n_i)
                }
            };
            let count = def.kind.discrete_variables();
            let discrete = (count > 0).then_some(discrete_count);
            discrete_count += count;
            forces.push(ForceElement { name: def.name.clone(), kind: def.kind.clone(), dofs, n_i, discrete });
        }
        (forces, discrete_count)
    }
}

/// The Euler-parameter normalizations of the `bodies` that have Euler parameters, their
/// constraint rows first.
fn normalizations(bodies: &[Body]) -> Vec<Normalization> {
    let mut normalizations = Vec::new();
    for (k, b) in bodies.iter().enumerate() {
        if b.kind.has_euler_parameters() {
            let o = b.offset;
            normalizations.push(Normalization {
                body: BodyId(k),
                row: normalizations.len(),
                dofs: [o + 3, o + 4, o + 5, o + 6],
            });
        }
    }
    normalizations
}

/// The sparse pattern of the Newton matrix [[S, C_q^T], [C_q, 0]] and where each element
/// writes in it.
fn matrix_layout(
    bodies: &[Body],
    normalizations: &[Normalization],
    joints: &[Joint],
    forces: &[ForceElement],
    coordinate_count: usize,
    constraint_count: usize,
) -> MatrixLayout {
    let n = coordinate_count + constraint_count;
    let mut pb = PatternBuilder::new(n);
    let all: Vec<usize> = (0..n).collect();
    for b in bodies {
        match &b.kind {
            BodyKind::Flexible(fb) => {
                let (reference, elastic) = b.dofs.split_at(REFERENCE_COORDINATES);
                pb.add_block(reference, reference);
                pb.add_block(reference, elastic);
                pb.add_block(elastic, reference);
                let ep = &fb.pattern;
                for c in 0..ep.n {
                    for &r in &ep.row_idx[ep.col_ptr[c]..ep.col_ptr[c + 1]] {
                        pb.add_entry(elastic[r], elastic[c]);
                    }
                }
            }
            _ => pb.add_block(&b.dofs, &b.dofs),
        }
    }
    for nz in normalizations {
        pb.add_block(&[coordinate_count + nz.row], &nz.dofs);
        pb.add_block(&nz.dofs, &[coordinate_count + nz.row]);
    }
    for j in joints {
        let rows: Vec<usize> = (0..j.equations.len()).map(|e| coordinate_count + j.row + e).collect();
        pb.add_block(&rows, &j.dofs);
        pb.add_block(&j.dofs, &rows);
        pb.add_block(&j.dofs, &j.dofs);
    }
    for f in forces {
        pb.add_block(&f.dofs, &f.dofs);
    }
    // Every coordinate has a diagonal entry (the projection matrices use it).
    pb.add_diagonal(&all[..coordinate_count]);
    let pattern = pb.build();
    MatrixLayout {
        bodies: bodies.iter().map(|b| body_entries(&pattern, b)).collect(),
        normalizations: normalizations
            .iter()
            .map(|nz| {
                let r = coordinate_count + nz.row;
                let mut e = [0usize; 8];
                for k in 0..4 {
                    e[k] = pattern.index(r, nz.dofs[k]);
                    e[4 + k] = pattern.index(nz.dofs[k], r);
                }
                e
            })
            .collect(),
        joints: joints
            .iter()
            .map(|j| {
                let rows: Vec<usize> = (0..j.equations.len()).map(|e| coordinate_count + j.row + e).collect();
                let mut transpose = Vec::with_capacity(rows.len() * j.dofs.len());
                for &r in &rows {
                    for &d in &j.dofs {
                        transpose.push(pattern.index(d, r));
                    }
                }
                JointEntries {
                    jacobian: pattern.block_indices(&rows, &j.dofs),
                    jacobian_transpose: transpose,
                    hessian: pattern.block_indices(&j.dofs, &j.dofs),
                }
            })
            .collect(),
        forces: forces.iter().map(|f| pattern.block_indices(&f.dofs, &f.dofs)).collect(),
        pattern,
    }
}

/// The entries of a body in the Newton matrix.
fn body_entries(pattern: &SparsePattern, b: &Body) -> BodyEntries {
    let diagonal = b.dofs.iter().map(|&d| pattern.index(d, d)).collect();
    match &b.kind {
        BodyKind::Flexible(fb) => {
            let (reference, elastic) = b.dofs.split_at(REFERENCE_COORDINATES);
            let ep = &fb.pattern;
            let mut entries = Vec::with_capacity(ep.nnz());
            for c in 0..ep.n {
                for &r in &ep.row_idx[ep.col_ptr[c]..ep.col_ptr[c + 1]] {
                    entries.push(pattern.index(elastic[r], elastic[c]));
                }
            }
            BodyEntries {
                block: pattern.block_indices(reference, reference),
                diagonal,
                reference_elastic: pattern.block_indices(reference, elastic),
                elastic_reference: pattern.block_indices(elastic, reference),
                elastic: entries,
            }
        }
        _ => BodyEntries { block: pattern.block_indices(&b.dofs, &b.dofs), diagonal, ..Default::default() },
    }
}

/// Mass of a body, for summaries.
pub fn body_mass(body: &Body) -> f64 {
    match &body.kind {
        BodyKind::Ground => 0.0,
        BodyKind::Rigid(r) => r.mass,
        BodyKind::PointMass { mass } => *mass,
        BodyKind::Flexible(f) => f.mass,
    }
}
