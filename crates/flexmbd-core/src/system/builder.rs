//! Building a model: bodies, markers, joints, forces and sensors are added one by one, each
//! checked as it is added (so a Python user sees the error at the offending line); `compile`
//! then lays out the coordinates and the sparse matrix pattern and returns the immutable Model.

use std::collections::HashSet;

use crate::body::marker::MarkerElastic;
use crate::body::{rigid::RigidBody, BodyKind, FlexibleBody};
use crate::error::{check_finite, FlexmbdError, Result};
use crate::force::joint_actuator::{ActuatedCoordinate, ServoLaw};
use crate::force::ForceKind;
use crate::ids::{BodyId, ForceId, JointId, MarkerId, SensorId};
use crate::joint::JointKind;
use crate::math::euler;
use crate::math::{Mat3, Vec3};
use crate::system::sensor::SensorQuantity;

/// Initial state of a body as given by the user.
#[derive(Clone, Debug)]
pub struct BodyDefinition {
    /// Name (unique; empty for the default `body <index>`).
    pub name: String,
    /// Kind and constant data.
    pub kind: BodyKind,
    /// Initial position of the body origin (m, global).
    pub position: Vec3,
    /// Initial orientation (body axes in global coordinates, as columns).
    pub orientation: Mat3,
    /// Initial velocity of the body origin (m/s, global).
    pub velocity: Vec3,
    /// Initial angular velocity (rad/s, global).
    pub angular_velocity: Vec3,
    /// Initial elastic coordinates q_f of a deformable body (empty otherwise).
    pub elastic_coordinates: Vec<f64>,
    /// Initial elastic velocities of a deformable body (empty otherwise).
    pub elastic_velocities: Vec<f64>,
}

/// A marker as given by the user.
#[derive(Clone, Debug)]
pub struct MarkerDefinition {
    /// Name.
    pub name: String,
    /// Body it is fixed on.
    pub body: BodyId,
    /// Position in the body frame (m).
    pub position: Vec3,
    /// Orientation in the body frame.
    pub orientation: Mat3,
    /// Elastic motion of a marker on a deformable body.
    pub elastic: Option<MarkerElastic>,
}

/// A joint as given by the user.
#[derive(Clone, Debug)]
pub struct JointDefinition {
    /// Name.
    pub name: String,
    /// Type and parameters.
    pub kind: JointKind,
    /// Markers i and j.
    pub markers: [MarkerId; 2],
}

/// A force element as given by the user.
#[derive(Clone, Debug)]
pub struct ForceDefinition {
    /// Name.
    pub name: String,
    /// Type and parameters.
    pub kind: ForceKind,
}

/// A sensor as given by the user.
#[derive(Clone, Debug)]
pub struct SensorDefinition {
    /// Name.
    pub name: String,
    /// Marker observed.
    pub marker: MarkerId,
    /// Quantity.
    pub quantity: SensorQuantity,
}

/// A multibody system under construction. Body 0 is the ground.
#[derive(Clone, Debug)]
pub struct SystemBuilder {
    /// Gravitational acceleration (m/s^2, global).
    pub gravity: Vec3,
    pub(crate) bodies: Vec<BodyDefinition>,
    pub(crate) markers: Vec<MarkerDefinition>,
    pub(crate) joints: Vec<JointDefinition>,
    pub(crate) forces: Vec<ForceDefinition>,
    pub(crate) sensors: Vec<SensorDefinition>,
    names: HashSet<(&'static str, String)>,
}

impl Default for SystemBuilder {
    fn default() -> Self {
        Self::new()
    }
}

fn check_rotation(item: &str, what: &str, r: &Mat3) -> Result<()> {
    check_finite(item, what, &r.0.concat())?;
    let err = r.transpose().mul_mat(r).max_abs_diff(&Mat3::IDENTITY);
    if err > 1e-9 || r.determinant() < 0.0 {
        return Err(FlexmbdError::InvalidParameter {
            item: item.to_string(),
            message: format!(
                "{what} must be a proper rotation matrix (orthonormal, determinant +1); |R^T R - I| = {err:.2e}, det = {:.6}",
                r.determinant()
            ),
        });
    }
    Ok(())
}

impl SystemBuilder {
    /// An empty system (ground only) with zero gravity.
    pub fn new() -> Self {
        SystemBuilder {
            gravity: Vec3::ZERO,
            bodies: vec![BodyDefinition {
                name: "ground".to_string(),
                kind: BodyKind::Ground,
                position: Vec3::ZERO,
                orientation: Mat3::IDENTITY,
                velocity: Vec3::ZERO,
                angular_velocity: Vec3::ZERO,
                elastic_coordinates: vec![],
                elastic_velocities: vec![],
            }],
            markers: Vec::new(),
            joints: Vec::new(),
            forces: Vec::new(),
            sensors: Vec::new(),
            names: HashSet::from([("body", "ground".to_string())]),
        }
    }

    /// The ground body.
    pub fn ground(&self) -> BodyId {
        BodyId(0)
    }

    /// Sets the gravitational acceleration (m/s^2).
    pub fn set_gravity(&mut self, gravity: Vec3) -> Result<()> {
        check_finite("system", "gravity", &gravity.0)?;
        self.gravity = gravity;
        Ok(())
    }

    fn unique_name(&mut self, kind: &'static str, name: &str, index: usize) -> Result<String> {
        let name = if name.is_empty() { format!("{kind} {index}") } else { name.to_string() };
        if !self.names.insert((kind, name.clone())) {
            return Err(FlexmbdError::InvalidModel {
                item: format!("{kind} '{name}'"),
                message: format!("another {kind} already has this name"),
            });
        }
        Ok(name)
    }

    fn check_body(&self, body: BodyId, context: &str) -> Result<()> {
        if body.0 < self.bodies.len() {
            Ok(())
        } else {
            Err(FlexmbdError::UnknownItem { kind: BodyId::KIND, id: body.0, context: context.to_string() })
        }
    }

    fn check_marker(&self, marker: MarkerId, context: &str) -> Result<()> {
        if marker.0 < self.markers.len() {
            Ok(())
        } else {
            Err(FlexmbdError::UnknownItem {
                kind: MarkerId::KIND,
                id: marker.0,
                context: context.to_string(),
            })
        }
    }

    /// Adds a rigid body. `inertia` is about the centre of mass in body axes; `center_of_mass`
    /// is in the body frame. Velocities are global; the angular velocity is global.
    #[allow(clippy::too_many_arguments)]
    pub fn add_rigid_body(
        &mut self,
        name: &str,
        mass: f64,
        inertia: Mat3,
        center_of_mass: Vec3,
        position: Vec3,
        orientation: Mat3,
        velocity: Vec3,
        angular_velocity: Vec3,
    ) -> Result<BodyId> {
        let index = self.bodies.len();
        let label = if name.is_empty() { format!("body {index}") } else { format!("body '{name}'") };
        let rigid = RigidBody::new(&label, mass, inertia, center_of_mass)?;
        self.add_body(name, BodyKind::Rigid(rigid), position, orientation, velocity, angular_velocity)
    }

    /// Adds a point mass (translation only).
    pub fn add_point_mass(
        &mut self,
        name: &str,
        mass: f64,
        position: Vec3,
        velocity: Vec3,
    ) -> Result<BodyId> {
        let index = self.bodies.len();
        if !(mass.is_finite() && mass > 0.0) {
            let label = if name.is_empty() { format!("body {index}") } else { format!("body '{name}'") };
            return Err(FlexmbdError::InvalidParameter {
                item: label,
                message: format!("mass must be positive and finite, got {mass}"),
            });
        }
        self.add_body(name, BodyKind::PointMass { mass }, position, Mat3::IDENTITY, velocity, Vec3::ZERO)
    }

    fn add_body(
        &mut self,
        name: &str,
        kind: BodyKind,
        position: Vec3,
        orientation: Mat3,
        velocity: Vec3,
        angular_velocity: Vec3,
    ) -> Result<BodyId> {
        let index = self.bodies.len();
        let label = if name.is_empty() { format!("body {index}") } else { format!("body '{name}'") };
        check_finite(&label, "position", &position.0)?;
        check_finite(&label, "velocity", &velocity.0)?;
        check_finite(&label, "angular velocity", &angular_velocity.0)?;
        check_rotation(&label, "orientation", &orientation)?;
        let name = self.unique_name("body", name, index)?;
        self.bodies.push(BodyDefinition {
            name,
            kind,
            position,
            orientation,
            velocity,
            angular_velocity,
            elastic_coordinates: vec![],
            elastic_velocities: vec![],
        });
        Ok(BodyId(index))
    }

    /// Adds a deformable body (floating frame of reference) with initial elastic coordinates
    /// and velocities (zeros if empty). Velocities are global; the angular velocity is global.
    #[allow(clippy::too_many_arguments)]
    pub fn add_flexible_body(
        &mut self,
        name: &str,
        body: FlexibleBody,
        position: Vec3,
        orientation: Mat3,
        velocity: Vec3,
        angular_velocity: Vec3,
        elastic_coordinates: Vec<f64>,
        elastic_velocities: Vec<f64>,
    ) -> Result<BodyId> {
        let index = self.bodies.len();
        let label = if name.is_empty() { format!("body {index}") } else { format!("body '{name}'") };
        let n = body.elastic_count;
        let fill = |v: Vec<f64>, what: &str| -> Result<Vec<f64>> {
            if v.is_empty() {
                return Ok(vec![0.0; n]);
            }
            if v.len() != n {
                return Err(FlexmbdError::InvalidParameter {
                    item: label.clone(),
                    message: format!(
                        "{what} must have {n} entries (one per elastic coordinate), got {}",
                        v.len()
                    ),
                });
            }
            check_finite(&label, what, &v)?;
            Ok(v)
        };
        let qf = fill(elastic_coordinates, "initial elastic coordinates")?;
        let qfd = fill(elastic_velocities, "initial elastic velocities")?;
        let id = self.add_body(
            name,
            BodyKind::Flexible(Box::new(body)),
            position,
            orientation,
            velocity,
            angular_velocity,
        )?;
        let def = self.bodies.last_mut().expect("just added");
        def.elastic_coordinates = qf;
        def.elastic_velocities = qfd;
        Ok(id)
    }

    /// Adds a marker on `body` at `position` with `orientation` (both in the body frame).
    pub fn add_marker(
        &mut self,
        name: &str,
        body: BodyId,
        position: Vec3,
        orientation: Mat3,
    ) -> Result<MarkerId> {
        let index = self.markers.len();
        let label = if name.is_empty() { format!("marker {index}") } else { format!("marker '{name}'") };
        self.check_body(body, &format!(" (used by {label})"))?;
        check_finite(&label, "position", &position.0)?;
        check_rotation(&label, "orientation", &orientation)?;
        if matches!(self.bodies[body.0].kind, BodyKind::PointMass { .. }) && position.norm() > 0.0 {
            return Err(FlexmbdError::InvalidParameter {
                item: label,
                message: "a marker on a point mass must be at its position (0, 0, 0)".to_string(),
            });
        }
        let name = self.unique_name("marker", name, index)?;
        self.markers.push(MarkerDefinition { name, body, position, orientation, elastic: None });
        Ok(MarkerId(index))
    }

    /// Adds a marker on a deformable body that moves with its deformation (an intermediate
    /// joint frame, seed Figure 4): undeformed `position` and `orientation` in the body frame,
    /// and `elastic` (displacement S_u and small rotation S_t per elastic coordinate).
    pub fn add_flexible_marker(
        &mut self,
        name: &str,
        body: BodyId,
        position: Vec3,
        orientation: Mat3,
        elastic: MarkerElastic,
    ) -> Result<MarkerId> {
        let index = self.markers.len();
        let label = if name.is_empty() { format!("marker {index}") } else { format!("marker '{name}'") };
        self.check_body(body, &format!(" (used by {label})"))?;
        let n = match &self.bodies[body.0].kind {
            BodyKind::Flexible(f) => f.elastic_count,
            _ => {
                return Err(FlexmbdError::InvalidModel {
                    item: label,
                    message: format!(
                        "body '{}' is not deformable: elastic markers need a flexible body",
                        self.bodies[body.0].name
                    ),
                })
            }
        };
        let nl = elastic.indices.len();
        if elastic.translation.n != nl || elastic.rotation.n != nl {
            return Err(FlexmbdError::InvalidParameter {
                item: label,
                message: format!(
                    "shape matrices must be 3 x {nl} (one column per listed coordinate), got 3 x {} and 3 x {}",
                    elastic.translation.n, elastic.rotation.n
                ),
            });
        }
        if let Some(&bad) = elastic.indices.iter().find(|&&i| i >= n) {
            return Err(FlexmbdError::UnknownItem {
                kind: "elastic coordinate",
                id: bad,
                context: format!(" of body '{}' (it has {n}; used by {label})", self.bodies[body.0].name),
            });
        }
        let mut sorted = elastic.indices.clone();
        sorted.sort_unstable();
        if sorted.windows(2).any(|w| w[0] == w[1]) {
            return Err(FlexmbdError::InvalidParameter {
                item: label,
                message: "an elastic coordinate is listed twice".to_string(),
            });
        }
        check_finite(&label, "displacement shape", &elastic.translation.data)?;
        check_finite(&label, "rotation shape", &elastic.rotation.data)?;
        check_finite(&label, "position", &position.0)?;
        check_rotation(&label, "orientation", &orientation)?;
        let name = self.unique_name("marker", name, index)?;
        self.markers.push(MarkerDefinition { name, body, position, orientation, elastic: Some(elastic) });
        Ok(MarkerId(index))
    }

    /// Initial global position of a marker origin.
    pub fn initial_marker_position(&self, marker: MarkerId) -> Result<Vec3> {
        self.check_marker(marker, "")?;
        let m = &self.markers[marker.0];
        let b = &self.bodies[m.body.0];
        let mut u = m.position;
        if let Some(e) = &m.elastic {
            for (j, &i) in e.indices.iter().enumerate() {
                for k in 0..3 {
                    u[k] += e.translation.get(k, j) * b.elastic_coordinates[i];
                }
            }
        }
        Ok(b.position + b.orientation.mul_vec(&u))
    }

    /// Adds a joint or driving constraint between markers i and j. For a distance joint with
    /// a non-positive distance, the initial distance between the markers is used.
    pub fn add_joint(&mut self, name: &str, mut kind: JointKind, markers: [MarkerId; 2]) -> Result<JointId> {
        let index = self.joints.len();
        let label = if name.is_empty() { format!("joint {index}") } else { format!("joint '{name}'") };
        for m in markers {
            self.check_marker(m, &format!(" (used by {label})"))?;
        }
        let (bi, bj) = (self.markers[markers[0].0].body, self.markers[markers[1].0].body);
        if bi == bj {
            let which =
                if bi.0 == 0 { "the ground".to_string() } else { format!("'{}'", self.bodies[bi.0].name) };
            return Err(FlexmbdError::InvalidModel {
                item: label,
                message: format!("both markers are on {which}: a joint connects two different bodies"),
            });
        }
        match &mut kind {
            JointKind::Distance { distance } => {
                if *distance <= 0.0 {
                    *distance = (self.initial_marker_position(markers[1])?
                        - self.initial_marker_position(markers[0])?)
                    .norm();
                }
                if !(distance.is_finite() && *distance > 1e-12) {
                    return Err(FlexmbdError::InvalidParameter {
                        item: label,
                        message: format!("distance must be positive and finite, got {distance}"),
                    });
                }
            }
            JointKind::AngleDriver(f) | JointKind::TranslationDriver(f) => {
                f.validate()
                    .map_err(|message| FlexmbdError::InvalidParameter { item: label.clone(), message })?;
            }
            _ => {}
        }
        let name = self.unique_name("joint", name, index)?;
        self.joints.push(JointDefinition { name, kind, markers });
        Ok(JointId(index))
    }

    /// Adds a force element.
    pub fn add_force(&mut self, name: &str, kind: ForceKind) -> Result<ForceId> {
        let index = self.forces.len();
        let label = if name.is_empty() { format!("force {index}") } else { format!("force '{name}'") };
        for m in kind.markers() {
            self.check_marker(m, &format!(" (used by {label})"))?;
        }
        let bad = |message: String| FlexmbdError::InvalidParameter { item: label.clone(), message };
        // A point mass has no rotation: a torque on it was dropped without a word (and the
        // reaction of a torsional spring on it, so angular momentum was not conserved).
        let torques = match &kind {
            ForceKind::Torque { marker, .. } => vec![*marker],
            ForceKind::RotationalSpringDamper { markers, .. } => markers.to_vec(),
            _ => vec![],
        };
        for m in torques {
            let body = &self.bodies[self.markers[m.0].body.0];
            if matches!(body.kind, BodyKind::PointMass { .. }) {
                return Err(FlexmbdError::InvalidModel {
                    item: label,
                    message: format!(
                        "a {} acts on '{}', a point mass, which has no rotation to take a torque \
                         (use a rigid body)",
                        kind.type_name(),
                        body.name
                    ),
                });
            }
        }
        match &kind {
            ForceKind::PointForce { components, .. } | ForceKind::Torque { components, .. } => {
                for c in components {
                    c.validate().map_err(bad)?;
                }
            }
            ForceKind::SpringDamper { markers, stiffness, damping, rest_length, preload }
            | ForceKind::RotationalSpringDamper {
                markers,
                stiffness,
                damping,
                rest_angle: rest_length,
                preload,
            } => {
                check_finite(&label, "parameters", &[*stiffness, *damping, *rest_length, *preload])?;
                if *stiffness < 0.0 || *damping < 0.0 {
                    return Err(bad(format!(
                        "stiffness and damping must be >= 0, got {stiffness} and {damping}"
                    )));
                }
                let (bi, bj) = (self.markers[markers[0].0].body, self.markers[markers[1].0].body);
                if bi == bj {
                    return Err(FlexmbdError::InvalidModel {
                        item: label,
                        message: "both markers are on the same body".to_string(),
                    });
                }
                if let ForceKind::SpringDamper { rest_length, .. } = &kind {
                    if *rest_length < 0.0 {
                        return Err(bad(format!("rest length must be >= 0, got {rest_length}")));
                    }
                    let l = (self.initial_marker_position(markers[1])?
                        - self.initial_marker_position(markers[0])?)
                    .norm();
                    if l < 1e-12 {
                        return Err(bad(
                            "the markers coincide initially: the spring direction is undefined".to_string()
                        ));
                    }
                }
            }
            ForceKind::JointActuator { markers, law, .. } => {
                law.validate().map_err(bad)?;
                if self.markers[markers[0].0].body == self.markers[markers[1].0].body {
                    return Err(FlexmbdError::InvalidModel {
                        item: label,
                        message: "both markers are on the same body".to_string(),
                    });
                }
            }
            ForceKind::Callback { bodies, .. } => {
                if bodies.is_empty() {
                    return Err(bad("a callback force needs at least one body".to_string()));
                }
                let mut seen = HashSet::new();
                for b in bodies {
                    self.check_body(*b, &format!(" (used by {label})"))?;
                    if b.0 == 0 {
                        return Err(bad("the ground has no coordinates to load".to_string()));
                    }
                    if !seen.insert(b.0) {
                        return Err(bad(format!("body {} is listed twice", b.0)));
                    }
                }
            }
        }
        let name = self.unique_name("force", name, index)?;
        self.forces.push(ForceDefinition { name, kind });
        Ok(ForceId(index))
    }

    /// Adds a joint actuator (a PD servo, [`crate::force::joint_actuator`]) on the markers of
    /// `joint`: on its angle for a revolute joint, on its slide for a prismatic joint, on
    /// either (`coordinate`, required) for a cylindrical joint.
    pub fn add_joint_actuator(
        &mut self,
        name: &str,
        joint: JointId,
        coordinate: Option<ActuatedCoordinate>,
        law: ServoLaw,
    ) -> Result<ForceId> {
        let index = self.forces.len();
        let label = if name.is_empty() { format!("force {index}") } else { format!("actuator '{name}'") };
        let Some(def) = self.joints.get(joint.0) else {
            return Err(FlexmbdError::UnknownItem {
                kind: JointId::KIND,
                id: joint.0,
                context: format!(" (used by {label})"),
            });
        };
        let bad = |message: String| FlexmbdError::InvalidParameter { item: label.clone(), message };
        let joint_label = format!("joint '{}'", def.name);
        let coordinate = match (&def.kind, coordinate) {
            (JointKind::Revolute, None | Some(ActuatedCoordinate::Angle)) => ActuatedCoordinate::Angle,
            (JointKind::Prismatic, None | Some(ActuatedCoordinate::Slide)) => ActuatedCoordinate::Slide,
            (JointKind::Cylindrical, Some(c)) => c,
            (JointKind::Cylindrical, None) => {
                return Err(bad(format!(
                    "{joint_label} is cylindrical: give the coordinate to drive ('angle' or 'slide')"
                )))
            }
            (JointKind::Revolute | JointKind::Prismatic, Some(c)) => {
                return Err(bad(format!(
                    "{joint_label} is {} and has no {} to drive",
                    def.kind.type_name(),
                    c.name()
                )))
            }
            (kind, _) => {
                return Err(bad(format!(
                    "an actuator drives a revolute, prismatic or cylindrical joint; {joint_label} is {}",
                    kind.type_name()
                )))
            }
        };
        let markers = def.markers;
        let force = self.add_force(name, ForceKind::JointActuator { markers, coordinate, law })?;
        // Its effort, recorded as a sensor.
        let sensor =
            if name.is_empty() { format!("actuator {index} effort") } else { format!("{name} effort") };
        let torque = coordinate == ActuatedCoordinate::Angle;
        self.add_sensor(&sensor, markers[1], SensorQuantity::Effort { force: force.0, torque })?;
        Ok(force)
    }

    /// Adds a sensor recording `quantity` of `marker`.
    pub fn add_sensor(&mut self, name: &str, marker: MarkerId, quantity: SensorQuantity) -> Result<SensorId> {
        let index = self.sensors.len();
        let label = if name.is_empty() { format!("sensor {index}") } else { format!("sensor '{name}'") };
        self.check_marker(marker, &format!(" (used by {label})"))?;
        let name = self.unique_name("sensor", name, index)?;
        self.sensors.push(SensorDefinition { name, marker, quantity });
        Ok(SensorId(index))
    }

    /// Number of bodies including the ground.
    pub fn body_count(&self) -> usize {
        self.bodies.len()
    }

    /// Numbers of markers, joints, force elements and sensors added so far.
    pub fn item_counts(&self) -> [usize; 4] {
        [self.markers.len(), self.joints.len(), self.forces.len(), self.sensors.len()]
    }

    /// Initial coordinates and velocities of a body as given.
    pub(crate) fn initial_body_state(def: &BodyDefinition) -> (Vec<f64>, Vec<f64>) {
        match &def.kind {
            BodyKind::Ground => (vec![], vec![]),
            BodyKind::PointMass { .. } => (def.position.0.to_vec(), def.velocity.0.to_vec()),
            BodyKind::Rigid(_) | BodyKind::Flexible(_) => {
                let p = euler::from_rotation_matrix(&def.orientation);
                let w_bar = def.orientation.tr_mul_vec(&def.angular_velocity);
                let pd = euler::rates_from_body_angular_velocity(&p, &w_bar);
                let mut q = def.position.0.to_vec();
                q.extend_from_slice(&p);
                q.extend_from_slice(&def.elastic_coordinates);
                let mut qd = def.velocity.0.to_vec();
                qd.extend_from_slice(&pd);
                qd.extend_from_slice(&def.elastic_velocities);
                (q, qd)
            }
        }
    }
}
