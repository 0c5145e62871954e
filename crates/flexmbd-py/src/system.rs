//! `System`: building a multibody model from Python. Every `add_*` method checks its input
//! immediately and returns a typed id; `compile()` returns the immutable `Model`.

use std::sync::Arc;

use flexmbd_core::force::joint_actuator::{ActuatedCoordinate, ServoLaw};
use flexmbd_core::force::{ForceCallback, ForceKind, Frame};
use flexmbd_core::joint::JointKind;
use flexmbd_core::math::time_function::TimeFunction;
use flexmbd_core::math::{Mat3, Vec3};
use flexmbd_core::system::sensor::SensorQuantity;
use flexmbd_core::SystemBuilder;
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::errors::{check, invalid, stash_callback_error};
use crate::ids::{BodyId, ForceId, JointId, MarkerId, SensorId};
use crate::model::Model;
use crate::time_function::{to_time_function, to_vector_function};

fn numbers(obj: &Bound<'_, PyAny>, item: &str, what: &str) -> PyResult<Vec<f64>> {
    let np = obj.py().import("numpy")?;
    let arr = np
        .call_method1("asarray", (obj, "float64"))
        .map_err(|_| invalid(item, format!("{what} must be numeric")))?;
    let flat = arr.call_method0("ravel")?;
    flat.extract::<Vec<f64>>().map_err(|_| invalid(item, format!("{what} must be numeric")))
}

/// A 3-vector from any sequence or array of three numbers.
pub fn vec3(obj: &Bound<'_, PyAny>, item: &str, what: &str) -> PyResult<Vec3> {
    let v = numbers(obj, item, what)?;
    if v.len() != 3 {
        return Err(invalid(item, format!("{what} must have 3 components, got {}", v.len())));
    }
    Ok(Vec3([v[0], v[1], v[2]]))
}

/// A 3 x 3 matrix from nested sequences or an array.
pub fn mat3(obj: &Bound<'_, PyAny>, item: &str, what: &str) -> PyResult<Mat3> {
    let v = numbers(obj, item, what)?;
    if v.len() != 9 {
        return Err(invalid(item, format!("{what} must be a 3 x 3 matrix, got {} numbers", v.len())));
    }
    Ok(Mat3([[v[0], v[1], v[2]], [v[3], v[4], v[5]], [v[6], v[7], v[8]]]))
}

fn optional_mat3(obj: Option<&Bound<'_, PyAny>>, item: &str, what: &str) -> PyResult<Mat3> {
    match obj {
        None => Ok(Mat3::IDENTITY),
        Some(o) if o.is_none() => Ok(Mat3::IDENTITY),
        Some(o) => mat3(o, item, what),
    }
}

fn label(kind: &str, name: &Option<String>, index: usize) -> String {
    match name {
        Some(n) => format!("{kind} '{n}'"),
        None => format!("{kind} {index}"),
    }
}

struct PyForceCallback {
    function: Py<PyAny>,
}

impl ForceCallback for PyForceCallback {
    fn evaluate(&self, time: f64, q: &[f64], qd: &[f64], out: &mut [f64]) -> Result<(), String> {
        Python::attach(|py| {
            let qa = PyArray1::from_slice(py, q);
            let qda = PyArray1::from_slice(py, qd);
            let value = self.function.call1(py, (time, qa, qda)).map_err(|e| stash_callback_error(py, e))?;
            let np = py.import("numpy").map_err(|e| stash_callback_error(py, e))?;
            let arr = np
                .call_method1("asarray", (value, "float64"))
                .and_then(|a| a.call_method0("ravel"))
                .and_then(|a| a.extract::<Vec<f64>>())
                .map_err(|e| stash_callback_error(py, e))?;
            if arr.len() != out.len() {
                return Err(format!(
                    "returned {} values, expected {} (one per coordinate)",
                    arr.len(),
                    out.len()
                ));
            }
            out.copy_from_slice(&arr);
            Ok(())
        })
    }
}

/// A multibody system under construction. Body 0 (`system.ground`) is the fixed frame.
///
/// Units are SI by convention (m, kg, s, N, rad). Orientations are 3 x 3 rotation matrices
/// whose columns are the local axes in the parent frame. Marker z axes are joint axes.
#[pyclass(module = "flexmbd._core", subclass)]
pub struct System {
    pub(crate) inner: SystemBuilder,
}

#[pymethods]
impl System {
    /// A system containing only the ground, with gravitational acceleration `gravity` (m/s^2).
    #[new]
    #[pyo3(signature = (gravity = None))]
    fn new(gravity: Option<&Bound<'_, PyAny>>) -> PyResult<Self> {
        let mut inner = SystemBuilder::new();
        if let Some(g) = gravity {
            check(inner.set_gravity(vec3(g, "system", "gravity")?))?;
        }
        Ok(System { inner })
    }

    /// The ground body (no coordinates).
    #[getter]
    fn ground(&self) -> BodyId {
        BodyId::of(0)
    }

    /// Gravitational acceleration (m/s^2, global axes).
    #[getter]
    fn gravity(&self) -> (f64, f64, f64) {
        let g = self.inner.gravity;
        (g[0], g[1], g[2])
    }

    #[setter]
    fn set_gravity(&mut self, value: &Bound<'_, PyAny>) -> PyResult<()> {
        check(self.inner.set_gravity(vec3(value, "system", "gravity")?))
    }

    /// Adds a rigid body.
    ///
    /// `inertia` is the inertia tensor about the centre of mass in body axes: a 3 x 3 matrix or
    /// the three principal moments. `center_of_mass` is in the body frame. `position` and
    /// `orientation` place the body frame; `velocity` (of the body origin) and
    /// `angular_velocity` are in global axes. Initial velocities that violate the joints are
    /// projected onto them (minimum-norm change) when a simulation starts.
    #[pyo3(signature = (mass, inertia, *, center_of_mass = None, position = None, orientation = None,
                        velocity = None, angular_velocity = None, name = None))]
    #[allow(clippy::too_many_arguments)]
    fn add_rigid_body(
        &mut self,
        mass: f64,
        inertia: &Bound<'_, PyAny>,
        center_of_mass: Option<&Bound<'_, PyAny>>,
        position: Option<&Bound<'_, PyAny>>,
        orientation: Option<&Bound<'_, PyAny>>,
        velocity: Option<&Bound<'_, PyAny>>,
        angular_velocity: Option<&Bound<'_, PyAny>>,
        name: Option<String>,
    ) -> PyResult<BodyId> {
        let item = label("body", &name, self.inner.body_count());
        let values = numbers(inertia, &item, "inertia")?;
        let inertia = match values.len() {
            3 => Mat3::diagonal(Vec3([values[0], values[1], values[2]])),
            9 => Mat3([
                [values[0], values[1], values[2]],
                [values[3], values[4], values[5]],
                [values[6], values[7], values[8]],
            ]),
            n => {
                return Err(invalid(
                    &item,
                    format!("inertia must be 3 principal moments or a 3 x 3 matrix, got {n} numbers"),
                ))
            }
        };
        let v = |o: Option<&Bound<'_, PyAny>>, what: &str| -> PyResult<Vec3> {
            o.filter(|x| !x.is_none()).map(|x| vec3(x, &item, what)).unwrap_or(Ok(Vec3::ZERO))
        };
        let id = check(self.inner.add_rigid_body(
            name.as_deref().unwrap_or(""),
            mass,
            inertia,
            v(center_of_mass, "center_of_mass")?,
            v(position, "position")?,
            optional_mat3(orientation, &item, "orientation")?,
            v(velocity, "velocity")?,
            v(angular_velocity, "angular_velocity")?,
        ))?;
        Ok(BodyId::of(id.0))
    }

    /// Adds a point mass (translation only; markers on it must be at its position, and torques
    /// and rotational spring-dampers on it are refused).
    #[pyo3(signature = (mass, *, position = None, velocity = None, name = None))]
    fn add_point_mass(
        &mut self,
        mass: f64,
        position: Option<&Bound<'_, PyAny>>,
        velocity: Option<&Bound<'_, PyAny>>,
        name: Option<String>,
    ) -> PyResult<BodyId> {
        let item = label("body", &name, self.inner.body_count());
        let v = |o: Option<&Bound<'_, PyAny>>, what: &str| -> PyResult<Vec3> {
            o.filter(|x| !x.is_none()).map(|x| vec3(x, &item, what)).unwrap_or(Ok(Vec3::ZERO))
        };
        let id = check(self.inner.add_point_mass(
            name.as_deref().unwrap_or(""),
            mass,
            v(position, "position")?,
            v(velocity, "velocity")?,
        ))?;
        Ok(BodyId::of(id.0))
    }

    /// Adds a marker (a frame fixed on `body`) at `position` with `orientation`, both in the
    /// body frame. Joints act about and along the z axes of their markers.
    #[pyo3(signature = (body, *, position = None, orientation = None, name = None))]
    fn add_marker(
        &mut self,
        body: BodyId,
        position: Option<&Bound<'_, PyAny>>,
        orientation: Option<&Bound<'_, PyAny>>,
        name: Option<String>,
    ) -> PyResult<MarkerId> {
        let item = label("marker", &name, self.inner.item_counts()[0]);
        let pos = match position.filter(|x| !x.is_none()) {
            Some(p) => vec3(p, &item, "position")?,
            None => Vec3::ZERO,
        };
        let id = check(self.inner.add_marker(
            name.as_deref().unwrap_or(""),
            body.into(),
            pos,
            optional_mat3(orientation, &item, "orientation")?,
        ))?;
        Ok(MarkerId::of(id.0))
    }

    /// Spherical joint: the origins of the two markers coincide (seed eq. 21).
    #[pyo3(signature = (marker1, marker2, *, name = None))]
    fn add_spherical_joint(
        &mut self,
        marker1: MarkerId,
        marker2: MarkerId,
        name: Option<String>,
    ) -> PyResult<JointId> {
        self.joint(JointKind::Spherical, marker1, marker2, name)
    }

    /// Revolute joint about the common z axis of the two markers (seed eq. 23).
    #[pyo3(signature = (marker1, marker2, *, name = None))]
    fn add_revolute_joint(
        &mut self,
        marker1: MarkerId,
        marker2: MarkerId,
        name: Option<String>,
    ) -> PyResult<JointId> {
        self.joint(JointKind::Revolute, marker1, marker2, name)
    }

    /// Cylindrical joint along the z axis of `marker1` (seed eq. 22).
    #[pyo3(signature = (marker1, marker2, *, name = None))]
    fn add_cylindrical_joint(
        &mut self,
        marker1: MarkerId,
        marker2: MarkerId,
        name: Option<String>,
    ) -> PyResult<JointId> {
        self.joint(JointKind::Cylindrical, marker1, marker2, name)
    }

    /// Prismatic joint along the z axis of `marker1` (seed eq. 24).
    #[pyo3(signature = (marker1, marker2, *, name = None))]
    fn add_prismatic_joint(
        &mut self,
        marker1: MarkerId,
        marker2: MarkerId,
        name: Option<String>,
    ) -> PyResult<JointId> {
        self.joint(JointKind::Prismatic, marker1, marker2, name)
    }

    /// Fixed joint: no relative motion between the marker frames.
    #[pyo3(signature = (marker1, marker2, *, name = None))]
    fn add_fixed_joint(
        &mut self,
        marker1: MarkerId,
        marker2: MarkerId,
        name: Option<String>,
    ) -> PyResult<JointId> {
        self.joint(JointKind::Fixed, marker1, marker2, name)
    }

    /// Universal (Cardan) joint: coincident origins; the cross axes x of `marker1` and y of
    /// `marker2` stay perpendicular (the shafts are the z axes).
    #[pyo3(signature = (marker1, marker2, *, name = None))]
    fn add_universal_joint(
        &mut self,
        marker1: MarkerId,
        marker2: MarkerId,
        name: Option<String>,
    ) -> PyResult<JointId> {
        self.joint(JointKind::Universal, marker1, marker2, name)
    }

    /// Planar joint: motion in the x-y plane of `marker1`.
    #[pyo3(signature = (marker1, marker2, *, name = None))]
    fn add_planar_joint(
        &mut self,
        marker1: MarkerId,
        marker2: MarkerId,
        name: Option<String>,
    ) -> PyResult<JointId> {
        self.joint(JointKind::Planar, marker1, marker2, name)
    }

    /// In-line joint primitive: the origin of `marker2` stays on the z axis of `marker1`.
    #[pyo3(signature = (marker1, marker2, *, name = None))]
    fn add_inline_joint(
        &mut self,
        marker1: MarkerId,
        marker2: MarkerId,
        name: Option<String>,
    ) -> PyResult<JointId> {
        self.joint(JointKind::Inline, marker1, marker2, name)
    }

    /// Distance constraint between the marker origins (a massless rigid link with ball ends).
    /// Without `distance`, the initial distance is kept.
    #[pyo3(signature = (marker1, marker2, distance = None, *, name = None))]
    fn add_distance_joint(
        &mut self,
        marker1: MarkerId,
        marker2: MarkerId,
        distance: Option<f64>,
        name: Option<String>,
    ) -> PyResult<JointId> {
        if let Some(d) = distance {
            if !(d.is_finite() && d > 0.0) {
                let item = label("joint", &name, self.inner.item_counts()[1]);
                return Err(invalid(&item, format!("distance must be positive and finite, got {d}")));
            }
        }
        self.joint(JointKind::Distance { distance: distance.unwrap_or(0.0) }, marker1, marker2, name)
    }

    /// Driving constraint: the rotation angle (rad) of `marker2`'s x axis from `marker1`'s,
    /// about `marker1`'s z axis, follows `angle`, a number, a time function or a callable
    /// f(t). Its multiplier is the driving torque (inverse dynamics).
    #[pyo3(signature = (marker1, marker2, angle, *, name = None))]
    fn add_angle_driver(
        &mut self,
        marker1: MarkerId,
        marker2: MarkerId,
        angle: &Bound<'_, PyAny>,
        name: Option<String>,
    ) -> PyResult<JointId> {
        let f = to_time_function(angle, &label("joint", &name, self.inner.item_counts()[1]))?;
        self.joint(JointKind::AngleDriver(f), marker1, marker2, name)
    }

    /// Driving constraint: the offset of `marker2`'s origin along `marker1`'s z axis follows
    /// `displacement` (m) as a function of time.
    #[pyo3(signature = (marker1, marker2, displacement, *, name = None))]
    fn add_translation_driver(
        &mut self,
        marker1: MarkerId,
        marker2: MarkerId,
        displacement: &Bound<'_, PyAny>,
        name: Option<String>,
    ) -> PyResult<JointId> {
        let f = to_time_function(displacement, &label("joint", &name, self.inner.item_counts()[1]))?;
        self.joint(JointKind::TranslationDriver(f), marker1, marker2, name)
    }

    /// Force (N) at the origin of `marker`: three components, each a number, a time function
    /// or a callable f(t); in global axes (`frame="global"`) or in the marker's axes
    /// (`frame="marker"`, turning with the body).
    #[pyo3(signature = (marker, force, *, frame = "global", name = None))]
    fn add_point_force(
        &mut self,
        marker: MarkerId,
        force: &Bound<'_, PyAny>,
        frame: &str,
        name: Option<String>,
    ) -> PyResult<ForceId> {
        let item = label("force", &name, self.inner.item_counts()[2]);
        let components = to_vector_function(force, &item)?;
        let frame = parse_frame(frame, &item)?;
        self.force(ForceKind::PointForce { marker: marker.into(), components, frame }, name)
    }

    /// Torque (N m) on the body of `marker`, components as for `add_point_force`.
    #[pyo3(signature = (marker, torque, *, frame = "global", name = None))]
    fn add_torque(
        &mut self,
        marker: MarkerId,
        torque: &Bound<'_, PyAny>,
        frame: &str,
        name: Option<String>,
    ) -> PyResult<ForceId> {
        let item = label("force", &name, self.inner.item_counts()[2]);
        let components = to_vector_function(torque, &item)?;
        let frame = parse_frame(frame, &item)?;
        self.force(ForceKind::Torque { marker: marker.into(), components, frame }, name)
    }

    /// Linear spring-damper between the marker origins: tension
    /// k (l - rest_length) + c dl/dt + preload along the line. Without `rest_length` the
    /// initial length is used.
    #[pyo3(signature = (marker1, marker2, *, stiffness, damping = 0.0, rest_length = None, preload = 0.0, name = None))]
    #[allow(clippy::too_many_arguments)]
    fn add_spring_damper(
        &mut self,
        marker1: MarkerId,
        marker2: MarkerId,
        stiffness: f64,
        damping: f64,
        rest_length: Option<f64>,
        preload: f64,
        name: Option<String>,
    ) -> PyResult<ForceId> {
        let rest_length = match rest_length {
            Some(l) => l,
            None => {
                let a = check(self.inner.initial_marker_position(marker1.into()))?;
                let b = check(self.inner.initial_marker_position(marker2.into()))?;
                (b - a).norm()
            }
        };
        let markers = [marker1.into(), marker2.into()];
        self.force(ForceKind::SpringDamper { markers, stiffness, damping, rest_length, preload }, name)
    }

    /// Torsional spring-damper about the z axis of `marker1`, acting on the angle of
    /// `marker2`'s x axis from `marker1`'s: torque k (angle - rest_angle) + c d(angle)/dt +
    /// preload. The angle is continued over full turns.
    #[pyo3(signature = (marker1, marker2, *, stiffness, damping = 0.0, rest_angle = 0.0, preload = 0.0, name = None))]
    #[allow(clippy::too_many_arguments)]
    fn add_rotational_spring_damper(
        &mut self,
        marker1: MarkerId,
        marker2: MarkerId,
        stiffness: f64,
        damping: f64,
        rest_angle: f64,
        preload: f64,
        name: Option<String>,
    ) -> PyResult<ForceId> {
        let markers = [marker1.into(), marker2.into()];
        self.force(
            ForceKind::RotationalSpringDamper { markers, stiffness, damping, rest_angle, preload },
            name,
        )
    }

    /// Joint actuator: a PD servo on the angle (revolute joint) or the slide (prismatic
    /// joint) of `joint`'s markers, for a cylindrical joint on the `coordinate` given
    /// ("angle" or "slide"). Its effort u = proportional_gain (f(t) - x) + derivative_gain
    /// (f'(t) - x_dot) + feed_forward(t), with `set_point` f (a time function; its rate f' is
    /// the velocity feed-forward), held within +/- `limit` (None: no limit; a reached limit
    /// gives an "actuator saturation" event), turns (N m) or pushes (N) marker 2's body
    /// about or along the z axis of marker 1 (and marker 1's body back). Analytic Jacobians.
    /// Its effort is recorded as the sensor "NAME effort" ("actuator K effort" unnamed;
    /// `Result.actuator_effort(NAME)`).
    #[pyo3(signature = (joint, set_point, *, proportional_gain, derivative_gain = 0.0, feed_forward = None, limit = None, coordinate = None, name = None))]
    #[allow(clippy::too_many_arguments)]
    fn add_joint_actuator(
        &mut self,
        joint: JointId,
        set_point: Bound<'_, PyAny>,
        proportional_gain: f64,
        derivative_gain: f64,
        feed_forward: Option<Bound<'_, PyAny>>,
        limit: Option<f64>,
        coordinate: Option<&str>,
        name: Option<String>,
    ) -> PyResult<ForceId> {
        let label = label("actuator", &name, self.inner.item_counts()[2]);
        let coordinate = match coordinate {
            None => None,
            Some("angle") => Some(ActuatedCoordinate::Angle),
            Some("slide") => Some(ActuatedCoordinate::Slide),
            Some(other) => {
                return Err(invalid(&label, format!("coordinate must be 'angle' or 'slide', got {other:?}")))
            }
        };
        let law = ServoLaw {
            proportional_gain,
            derivative_gain,
            set_point: to_time_function(&set_point, &format!("{label} set_point"))?,
            feed_forward: match feed_forward {
                None => TimeFunction::Constant(0.0),
                Some(f) => to_time_function(&f, &format!("{label} feed_forward"))?,
            },
            limit: limit.unwrap_or(f64::INFINITY),
        };
        let id = check(self.inner.add_joint_actuator(
            name.as_deref().unwrap_or(""),
            joint.into(),
            coordinate,
            law,
        ))?;
        Ok(ForceId::of(id.0))
    }

    /// User force: `function(t, q, q_dot)` returns the generalized force on the coordinates of
    /// `bodies` (concatenated in that order: 7 per rigid body [x, y, z, e0..e3], 3 per point
    /// mass). Its Jacobians are taken by finite differences.
    #[pyo3(signature = (bodies, function, *, name = None))]
    fn add_callback_force(
        &mut self,
        bodies: Vec<BodyId>,
        function: Bound<'_, PyAny>,
        name: Option<String>,
    ) -> PyResult<ForceId> {
        if !function.is_callable() {
            return Err(invalid(
                &label("force", &name, self.inner.item_counts()[2]),
                "function must be callable",
            ));
        }
        let callback = Arc::new(PyForceCallback { function: function.unbind() });
        let bodies = bodies.into_iter().map(Into::into).collect();
        self.force(ForceKind::Callback { bodies, callback }, name)
    }

    /// Records `quantity` of `marker` at every output time: "position", "velocity",
    /// "acceleration", "orientation" (3 x 3), "angular_velocity" or "angular_acceleration",
    /// all in global axes.
    #[pyo3(signature = (marker, quantity, *, name = None))]
    fn add_sensor(&mut self, marker: MarkerId, quantity: &str, name: Option<String>) -> PyResult<SensorId> {
        let q = SensorQuantity::from_name(quantity).ok_or_else(|| {
            invalid(
                &label("sensor", &name, self.inner.item_counts()[3]),
                format!("unknown quantity '{quantity}'; use position, velocity, acceleration, orientation, angular_velocity or angular_acceleration"),
            )
        })?;
        let id = check(self.inner.add_sensor(name.as_deref().unwrap_or(""), marker.into(), q))?;
        Ok(SensorId::of(id.0))
    }

    /// Checks the whole system and returns the compiled, immutable model; `flexible_bodies`
    /// (body index -> `flexmbd.fe.FlexibleBodyData`) is kept in it for stresses, results
    /// files and analyses, `source` (how the system was built) for pickling.
    #[pyo3(signature = (*, flexible_bodies = None, source = None))]
    fn compile(
        &self,
        py: Python<'_>,
        flexible_bodies: Option<Bound<'_, PyDict>>,
        source: Option<Py<PyAny>>,
    ) -> PyResult<Model> {
        let bodies = match flexible_bodies {
            Some(d) => d.copy()?.unbind(),
            None => PyDict::new(py).unbind(),
        };
        Ok(Model::new(check(self.inner.compile())?, bodies, source))
    }

    fn __repr__(&self) -> String {
        format!("System({} bodies including the ground)", self.inner.body_count())
    }
}

fn parse_frame(frame: &str, item: &str) -> PyResult<Frame> {
    match frame {
        "global" => Ok(Frame::Global),
        "marker" => Ok(Frame::Marker),
        other => Err(invalid(item, format!("frame must be 'global' or 'marker', got '{other}'"))),
    }
}

impl System {
    fn joint(
        &mut self,
        kind: JointKind,
        m1: MarkerId,
        m2: MarkerId,
        name: Option<String>,
    ) -> PyResult<JointId> {
        let id = check(self.inner.add_joint(name.as_deref().unwrap_or(""), kind, [m1.into(), m2.into()]))?;
        Ok(JointId::of(id.0))
    }

    fn force(&mut self, kind: ForceKind, name: Option<String>) -> PyResult<ForceId> {
        let id = check(self.inner.add_force(name.as_deref().unwrap_or(""), kind))?;
        Ok(ForceId::of(id.0))
    }
}
