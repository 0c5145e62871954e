//! `Model`: the compiled, immutable model, with a description of its layout.

use std::sync::Arc;

use flexmbd_core::body::BodyKind;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

/// A compiled model (from `System.compile()`); immutable, shareable between simulations.
#[pyclass(module = "flexmbd._core", frozen)]
pub struct Model {
    pub(crate) inner: Arc<flexmbd_core::Model>,
}

#[pymethods]
impl Model {
    /// Number of generalized coordinates (7 per rigid body, 3 per point mass).
    #[getter]
    fn coordinate_count(&self) -> usize {
        self.inner.coordinate_count
    }

    /// Number of constraint equations (one normalization per rigid body, plus the joints').
    #[getter]
    fn constraint_count(&self) -> usize {
        self.inner.constraint_count
    }

    /// Non-zeros of the sparse Newton matrix.
    #[getter]
    fn matrix_nonzeros(&self) -> usize {
        self.inner.layout.pattern.nnz()
    }

    /// The layout of the model as plain Python data: bodies (name, kind, coordinate offset and
    /// count, mass), markers, joints (name, type, first multiplier row, equation labels),
    /// forces, sensors (name, quantity, offset and size in the sensor record).
    fn describe<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let m = &self.inner;
        let d = PyDict::new(py);
        d.set_item("coordinate_count", m.coordinate_count)?;
        d.set_item("constraint_count", m.constraint_count)?;
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
