//! `Model`: the compiled, immutable model, with a description of its layout.

use std::sync::{Arc, Mutex};

use flexmbd_core::assembly::{assemble, constraint_time_terms, MatrixCoefficients, Request, StateView};
use flexmbd_core::body::BodyKind;
use flexmbd_core::Workspace;
use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::errors::{check, invalid};

/// A compiled model (from `System.compile()`); immutable, shareable between simulations.
#[pyclass(module = "flexmbd._core", frozen)]
pub struct Model {
    pub(crate) inner: Arc<flexmbd_core::Model>,
    /// The data of the deformable bodies (body index -> `flexmbd.fe.FlexibleBodyData`), which
    /// stresses, results files and analyses need beside the compiled model.
    flexible_bodies: Py<PyDict>,
    /// How the model was built (`flexmbd.System`'s record of its building calls), from which
    /// a pickled model is built again; None for a model of a bare `flexmbd._core.System`.
    source: Option<Py<PyAny>>,
    /// Workspace of `evaluate`, made at its first call.
    workspace: Mutex<Option<Workspace>>,
}

impl Model {
    /// Wraps a compiled model with the data of its deformable bodies and its source.
    pub fn new(model: flexmbd_core::Model, flexible_bodies: Py<PyDict>, source: Option<Py<PyAny>>) -> Self {
        Model { inner: Arc::new(model), flexible_bodies, source, workspace: Mutex::new(None) }
    }
}

fn vector(a: &PyReadonlyArray1<f64>, n: usize, what: &str) -> PyResult<Vec<f64>> {
    let v = a.as_slice()?.to_vec();
    if v.len() != n {
        return Err(invalid("model", format!("{what} must have {n} entries, got {}", v.len())));
    }
    Ok(v)
}

#[pymethods]
impl Model {
    /// The data of the deformable bodies, body index -> `flexmbd.fe.FlexibleBodyData` (a new
    /// dict at each call; the bodies' data is immutable).
    #[getter]
    fn flexible_bodies<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        self.flexible_bodies.bind(py).copy()
    }

    /// Evaluates the augmented equations (seed eqs. 20, 25, 26) at a state, for analyses
    /// (statics, steady states, linearization). Returns a dict with
    ///
    /// - `residual`: [M q_dd - F - Q_e + C_q^T lambda; C(q, t)] (coordinates + constraints);
    /// - `constraint_rate`: C_t; `gamma`: the right-hand side of C_q q_dd = gamma (seed eq. 25);
    /// - `matrix` (if any coefficient is non-zero): the CSC tuple (data, indices, indptr, n) of
    ///   [[mass M + velocity D + position K, C_q^T], [C_q, 0]] with D = dr/dq_dot and
    ///   K = dr/dq (including the constraint Hessian term of the multipliers).
    ///
    /// `discrete`: the state's discrete variables (`discrete_variables`, a recorded state's
    /// `State.discrete`: the unwrapped spring and actuator angles, the actuators' saturation
    /// states); None: those of the coordinates (angles in (-pi, pi], no saturation).
    #[pyo3(signature = (time, coordinates, velocities, accelerations, multipliers, *, mass = 0.0, velocity = 0.0, position = 0.0, discrete = None))]
    #[allow(clippy::too_many_arguments)]
    fn evaluate<'py>(
        &self,
        py: Python<'py>,
        time: f64,
        coordinates: PyReadonlyArray1<f64>,
        velocities: PyReadonlyArray1<f64>,
        accelerations: PyReadonlyArray1<f64>,
        multipliers: PyReadonlyArray1<f64>,
        mass: f64,
        velocity: f64,
        position: f64,
        discrete: Option<PyReadonlyArray1<f64>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let m = &self.inner;
        let (nq, nc) = (m.coordinate_count, m.constraint_count);
        let q = vector(&coordinates, nq, "coordinates")?;
        let qd = vector(&velocities, nq, "velocities")?;
        let qdd = vector(&accelerations, nq, "accelerations")?;
        let lambda = vector(&multipliers, nc, "multipliers")?;
        let discrete = match &discrete {
            Some(values) => vector(values, m.discrete_count, "discrete")?,
            None => vec![0.0; m.discrete_count],
        };
        let mut guard = self.workspace.lock().map_err(|_| invalid("model", "workspace poisoned"))?;
        if guard.is_none() {
            *guard = Some(Workspace::new(m));
        }
        let ws = guard.as_mut().expect("workspace");
        let view = StateView { time, q: &q, qd: &qd, qdd: &qdd, lambda: &lambda, discrete: &discrete };
        let with_matrix = mass != 0.0 || velocity != 0.0 || position != 0.0;
        let coefficients =
            MatrixCoefficients { mass, velocity, position, identity: 0.0, elastic_identity: 0.0, scale: 1.0 };
        check(assemble(m, view, ws, &Request::with(with_matrix.then_some(coefficients))))?;
        let d = PyDict::new(py);
        d.set_item("residual", PyArray1::from_slice(py, &ws.residual))?;
        if with_matrix {
            let p = &m.layout.pattern;
            let indices: Vec<i64> = p.row_idx.iter().map(|&r| r as i64).collect();
            let indptr: Vec<i64> = p.col_ptr.iter().map(|&c| c as i64).collect();
            d.set_item(
                "matrix",
                (
                    PyArray1::from_slice(py, &ws.values),
                    PyArray1::from_vec(py, indices),
                    PyArray1::from_vec(py, indptr),
                    p.n,
                ),
            )?;
        }
        let mut ct = vec![0.0; nc];
        let mut gamma = vec![0.0; nc];
        check(constraint_time_terms(m, view, ws, &mut ct, Some(&mut gamma)))?;
        d.set_item("constraint_rate", PyArray1::from_vec(py, ct))?;
        d.set_item("gamma", PyArray1::from_vec(py, gamma))?;
        Ok(d)
    }

    /// The discrete variables at a state (the unwrapped angles of rotational springs and
    /// angle actuators, the actuators' saturation states, as a run keeps them): set from the
    /// coordinates without `previous` (angles in (-pi, pi]), else advanced from `previous`
    /// as after a step (each angle continued from its previous value, so that it passes
    /// +-pi). For analyses that move a state step by step (an equilibrium's iterates).
    #[pyo3(signature = (time, coordinates, velocities, previous = None))]
    fn discrete_variables<'py>(
        &self,
        py: Python<'py>,
        time: f64,
        coordinates: PyReadonlyArray1<f64>,
        velocities: PyReadonlyArray1<f64>,
        previous: Option<PyReadonlyArray1<f64>>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let m = &self.inner;
        let nq = m.coordinate_count;
        let q = vector(&coordinates, nq, "coordinates")?;
        let qd = vector(&velocities, nq, "velocities")?;
        let previous = match &previous {
            Some(values) => Some(vector(values, m.discrete_count, "previous")?),
            None => None,
        };
        let mut guard = self.workspace.lock().map_err(|_| invalid("model", "workspace poisoned"))?;
        if guard.is_none() {
            *guard = Some(Workspace::new(m));
        }
        let ws = guard.as_mut().expect("workspace");
        let values = check(flexmbd_core::integrator::discrete::discrete_at(
            m,
            ws,
            time,
            &q,
            &qd,
            previous.as_deref(),
        ))?;
        Ok(PyArray1::from_vec(py, values))
    }

    /// Number of discrete variables (an unwrapped angle per rotational spring, an angle and a
    /// saturation state per angle actuator, a saturation state per slide actuator).
    #[getter]
    fn discrete_count(&self) -> usize {
        self.inner.discrete_count
    }

    /// Number of generalized coordinates (7 per rigid body, 3 per point mass, 7 + n_f per
    /// deformable body).
    #[getter]
    fn coordinate_count(&self) -> usize {
        self.inner.coordinate_count
    }

    /// Number of constraint equations (one normalization per rigid or deformable body, plus the
    /// joints').
    #[getter]
    fn constraint_count(&self) -> usize {
        self.inner.constraint_count
    }

    /// Initial coordinates q as given by the user (before the constraints are enforced).
    #[getter]
    fn initial_coordinates<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.inner.initial_coordinates)
    }

    /// Initial velocities as given by the user.
    #[getter]
    fn initial_velocities<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.inner.initial_velocities)
    }

    /// Non-zeros of the sparse Newton matrix.
    #[getter]
    fn matrix_nonzeros(&self) -> usize {
        self.inner.layout.pattern.nnz()
    }

    /// The layout of the model as plain Python data: bodies (name, kind, coordinate offset and
    /// count, mass), markers (name, body, undeformed position and orientation in the body
    /// frame), joints (name, type, first multiplier row, equation labels),
    /// forces, sensors (name, quantity, offset and size in the sensor record).
    fn describe<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let m = &self.inner;
        let d = PyDict::new(py);
        d.set_item("coordinate_count", m.coordinate_count)?;
        d.set_item("constraint_count", m.constraint_count)?;
        d.set_item("discrete_count", m.discrete_count)?;
        d.set_item("gravity", m.gravity.0.to_vec())?;
        let bodies = PyList::empty(py);
        for b in &m.bodies {
            let e = PyDict::new(py);
            e.set_item("name", &b.name)?;
            e.set_item(
                "kind",
                match b.kind {
                    BodyKind::Ground => "ground",
                    BodyKind::Rigid(_) => "rigid",
                    BodyKind::PointMass { .. } => "point_mass",
                    BodyKind::Flexible(_) => "flexible",
                },
            )?;
            e.set_item("offset", b.offset)?;
            e.set_item("count", b.dofs.len())?;
            e.set_item("mass", flexmbd_core::system::model::body_mass(b))?;
            bodies.append(e)?;
        }
        d.set_item("bodies", bodies)?;
        let markers = PyList::empty(py);
        for mk in &m.markers {
            let e = PyDict::new(py);
            e.set_item("name", &mk.name)?;
            e.set_item("body", mk.body.0)?;
            e.set_item("position", mk.position.0.to_vec())?;
            let rows: Vec<Vec<f64>> = mk.rotation.0.iter().map(|row| row.to_vec()).collect();
            e.set_item("orientation", rows)?;
            markers.append(e)?;
        }
        d.set_item("markers", markers)?;
        let joints = PyList::empty(py);
        for j in &m.joints {
            let e = PyDict::new(py);
            e.set_item("name", &j.name)?;
            e.set_item("type", j.kind.type_name())?;
            e.set_item("row", j.row)?;
            e.set_item("equations", j.equations.iter().map(|q| q.label).collect::<Vec<_>>())?;
            e.set_item("markers", (j.markers[0].0, j.markers[1].0))?;
            joints.append(e)?;
        }
        d.set_item("joints", joints)?;
        let forces = PyList::empty(py);
        for f in &m.forces {
            let e = PyDict::new(py);
            e.set_item("name", &f.name)?;
            e.set_item("type", f.kind.type_name())?;
            forces.append(e)?;
        }
        d.set_item("forces", forces)?;
        let sensors = PyList::empty(py);
        let mut offset = 0;
        for s in &m.sensors {
            let e = PyDict::new(py);
            e.set_item("name", &s.name)?;
            e.set_item("quantity", s.quantity.name())?;
            e.set_item("marker", s.marker.0)?;
            e.set_item("offset", offset)?;
            e.set_item("size", s.quantity.size())?;
            offset += s.quantity.size();
            sensors.append(e)?;
        }
        d.set_item("sensors", sensors)?;
        Ok(d)
    }

    /// What `flexmbd.System.compile` gave as the model's source (its class, building calls
    /// and identity), or None.
    #[getter]
    fn _source(&self, py: Python<'_>) -> Option<Py<PyAny>> {
        self.source.as_ref().map(|s| s.clone_ref(py))
    }

    /// Pickling: the model is compiled again from the record of the calls that built its
    /// system (`flexmbd.System`), which gives the same model bit for bit.
    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyAny>, (Py<PyAny>,))> {
        let Some(source) = &self.source else {
            return Err(pyo3::exceptions::PyTypeError::new_err(
                "cannot pickle a Model compiled from a bare flexmbd._core.System: build it with \
                 flexmbd.System, which records how it was built",
            ));
        };
        Ok((py.import("flexmbd.system")?.getattr("_compiled")?, (source.clone_ref(py),)))
    }

    /// The model itself: it is immutable.
    fn __copy__(slf: Py<Self>) -> Py<Self> {
        slf
    }

    /// The model itself: it is immutable.
    fn __deepcopy__(slf: Py<Self>, _memo: &Bound<'_, PyAny>) -> Py<Self> {
        slf
    }

    fn __repr__(&self) -> String {
        format!(
            "Model({} bodies, {} joints, {} forces, {} coordinates, {} constraints)",
            self.inner.bodies.len() - 1,
            self.inner.joints.len(),
            self.inner.forces.len(),
            self.inner.coordinate_count,
            self.inner.constraint_count
        )
    }
}
