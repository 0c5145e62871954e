//! Deformable bodies and their markers in a `System` (low-level: the public methods
//! `add_flexible_body`, `add_node_marker` and `add_node_set_marker` of `flexmbd.System` turn a
//! `FlexibleBodyData` into these calls).

use flexmbd_core::body::corotational::CorotationalBeam;
use flexmbd_core::body::flexible::{AttachedMass, FlexibleBody, FlexibleBodyInput, ScalarMass};
use flexmbd_core::body::marker::MarkerElastic;
use flexmbd_core::body::stiffening::StiffeningElement;
use flexmbd_core::linalg::csc::Csc;
use flexmbd_core::math::dense::Jacobian3;
use flexmbd_core::math::{Mat3, Vec3};
use numpy::{PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArrayDyn};
use pyo3::prelude::*;
use pyo3::types::PyTuple;

use crate::errors::{check, invalid};
use crate::ids::{BodyId, MarkerId};
use crate::system::{mat3, vec3, System};

/// A sparse matrix from a `(data, indices, indptr, n)` tuple of CSC arrays (sorted indices).
fn csc(obj: &Bound<'_, PyAny>, item: &str, what: &str) -> PyResult<Csc> {
    let t = obj
        .cast::<PyTuple>()
        .map_err(|_| invalid(item, format!("{what}: expected (data, indices, indptr, n)")))?;
    if t.len() != 4 {
        return Err(invalid(item, format!("{what}: expected (data, indices, indptr, n)")));
    }
    let data: PyReadonlyArray1<f64> = t.get_item(0)?.extract()?;
    let indices: PyReadonlyArray1<i64> = t.get_item(1)?.extract()?;
    let indptr: PyReadonlyArray1<i64> = t.get_item(2)?.extract()?;
    let n: usize = t.get_item(3)?.extract()?;
    let to_usize = |v: &[i64], part: &str| -> PyResult<Vec<usize>> {
        v.iter()
            .map(|&x| usize::try_from(x).map_err(|_| invalid(item, format!("{what}: negative {part} {x}"))))
            .collect()
    };
    Ok(Csc {
        nrows: n,
        ncols: n,
        col_ptr: to_usize(indptr.as_slice()?, "column pointer")?,
        row_idx: to_usize(indices.as_slice()?, "row index")?,
        values: data.as_slice()?.to_vec(),
    })
}

fn jacobian3(a: &PyReadonlyArray2<f64>, item: &str, what: &str) -> PyResult<Jacobian3> {
    let v = a.as_array();
    if v.nrows() != 3 {
        return Err(invalid(item, format!("{what} must have 3 rows, got {}", v.nrows())));
    }
    let mut j = Jacobian3::zeros(v.ncols());
    for r in 0..3 {
        for c in 0..v.ncols() {
            j.set(r, c, v[[r, c]]);
        }
    }
    Ok(j)
}

/// The first two items of an element tuple: `(indices (n_l,), map (n_e, n_l))` as the indices,
/// n_e and the map row-major; `bad` makes the error of a wrong shape or a negative index.
fn indices_and_map(
    t: &Bound<'_, PyTuple>,
    bad: impl Fn() -> PyErr,
) -> PyResult<(Vec<usize>, usize, Vec<f64>)> {
    let indices: PyReadonlyArray1<i64> = t.get_item(0)?.extract()?;
    let map: PyReadonlyArray2<f64> = t.get_item(1)?.extract()?;
    let indices = indices
        .as_slice()?
        .iter()
        .map(|&i| usize::try_from(i).map_err(|_| bad()))
        .collect::<PyResult<Vec<_>>>()?;
    let m = map.as_array();
    if m.ncols() != indices.len() {
        return Err(bad());
    }
    Ok((indices, m.nrows(), m.iter().copied().collect()))
}

/// A tuple of `len` items whose first two are (indices (n_l,), map (`rows`, n_l)): the tuple,
/// the indices and the map (row-major); `bad()` for anything else.
fn fixed_map_tuple<'py>(
    obj: &Bound<'py, PyAny>,
    len: usize,
    rows: usize,
    bad: impl Fn() -> PyErr,
) -> PyResult<(Bound<'py, PyTuple>, Vec<usize>, Vec<f64>)> {
    let t = obj.cast::<PyTuple>().map_err(|_| bad())?;
    if t.len() != len {
        return Err(bad());
    }
    let (indices, found, map) = indices_and_map(t, &bad)?;
    if found != rows {
        return Err(bad());
    }
    Ok((t.clone(), indices, map))
}

/// A stiffening element from a beam's `(indices, map (12, n_l), length, axial_stiffness)` or
/// a shell's `(indices, map (n_e, n_l), linear (m, n_e), slopes (m, n_e, n_e), stiffness
/// (m, m))` (see `flexmbd_core::body::stiffening`).
fn stiffening_element(obj: &Bound<'_, PyAny>, item: &str) -> PyResult<StiffeningElement> {
    let bad = || {
        invalid(
            item,
            "stiffening elements are (indices, map (12, n_l), length, EA) or (indices, map (n_e, n_l), \
             linear (m, n_e), slopes (m, n_e, n_e), stiffness (m, m)) tuples",
        )
    };
    let t = obj.cast::<PyTuple>().map_err(|_| bad())?;
    if t.len() != 4 && t.len() != 5 {
        return Err(bad());
    }
    let (indices, rows, map) = indices_and_map(t, bad)?;
    if t.len() == 4 {
        if rows != 12 {
            return Err(bad());
        }
        return Ok(StiffeningElement::beam(
            indices,
            map,
            t.get_item(2)?.extract()?,
            t.get_item(3)?.extract()?,
        ));
    }
    let linear: PyReadonlyArray2<f64> = t.get_item(2)?.extract()?;
    let slopes: PyReadonlyArrayDyn<f64> = t.get_item(3)?.extract()?;
    let stiffness: PyReadonlyArray2<f64> = t.get_item(4)?.extract()?;
    let (linear, slopes, stiffness) = (linear.as_array(), slopes.as_array(), stiffness.as_array());
    let (strains, ne) = (linear.nrows(), linear.ncols());
    if ne != rows || slopes.shape() != [strains, ne, ne] || stiffness.shape() != [strains, strains] {
        return Err(bad());
    }
    Ok(StiffeningElement {
        indices,
        map,
        linear: linear.iter().copied().collect(),
        slopes: slopes.iter().copied().collect(),
        stiffness: stiffness.iter().copied().collect(),
        positions: Vec::new(),
        sparse_map: None,
    })
}

/// A mass carried by a node with rotations from `(indices (n_l,), rows (6, n_l), node (3,),
/// masses (k,), offsets (k, 3))`: the node's [u; theta] = rows q_l, its undeformed position
/// and mass points relative to it (see `flexmbd_core::body::flexible::AttachedMass`).
fn attached_mass(obj: &Bound<'_, PyAny>, item: &str) -> PyResult<AttachedMass> {
    let bad = || {
        invalid(
            item,
            "attached masses are (indices (n_l,), rows (6, n_l), node (3,), masses (k,), offsets (k, 3)) \
             tuples",
        )
    };
    let (t, indices, map) = fixed_map_tuple(obj, 5, 6, bad)?;
    let masses: PyReadonlyArray1<f64> = t.get_item(3)?.extract()?;
    let offsets: PyReadonlyArray2<f64> = t.get_item(4)?.extract()?;
    let (masses, offsets) = (masses.as_array(), offsets.as_array());
    if offsets.ncols() != 3 || offsets.nrows() != masses.len() {
        return Err(bad());
    }
    Ok(AttachedMass {
        indices,
        rows: map,
        node: vec3(&t.get_item(2)?, item, "attached mass node")?,
        points: masses.iter().zip(offsets.rows()).map(|(&m, c)| (m, Vec3([c[0], c[1], c[2]]))).collect(),
        positions: Vec::new(),
    })
}

/// A co-rotational beam element from `(indices, map (12, n_l), length, stiffness (12, 12))`
/// (see `flexmbd_core::body::corotational`).
fn corotational_element(obj: &Bound<'_, PyAny>, item: &str) -> PyResult<CorotationalBeam> {
    let bad = || {
        invalid(
            item,
            "co-rotational beam elements are (indices, map (12, n_l), length, stiffness (12, 12)) tuples",
        )
    };
    let (t, indices, map) = fixed_map_tuple(obj, 4, 12, bad)?;
    let stiffness: PyReadonlyArray2<f64> = t.get_item(3)?.extract()?;
    if stiffness.as_array().shape() != [12, 12] {
        return Err(bad());
    }
    Ok(CorotationalBeam::new(
        indices,
        map,
        t.get_item(2)?.extract()?,
        stiffness.as_array().iter().copied().collect(),
    ))
}

#[pymethods]
impl System {
    /// Adds a deformable body from its invariants of motion (low level; use
    /// `flexmbd.System.add_flexible_body` with a `FlexibleBodyData`).
    ///
    /// `i1` is (3, n_f), `ibar` (9, n_f) (index 3 k + l), `i_kl` nine CSC tuples
    /// `(data, indices, indptr, n_f)`, `stiffness` and `damping` CSC tuples; `attached` the point
    /// masses turning with their nodes to second order (see `attached_mass`).
    #[pyo3(signature = (*, mass, first_moment, second_moment, i1, ibar, i_kl, stiffness, damping,
                        position = None, orientation = None, velocity = None, angular_velocity = None,
                        elastic_coordinates = None, elastic_velocities = None, stiffening = None,
                        corotational = None, dof_nodes = None, node_positions = None, condense = None, scalar_mass = None,
                        attached = None, name = None))]
    #[allow(clippy::too_many_arguments)]
    fn _add_flexible_body(
        &mut self,
        mass: f64,
        first_moment: &Bound<'_, PyAny>,
        second_moment: &Bound<'_, PyAny>,
        i1: PyReadonlyArray2<f64>,
        ibar: PyReadonlyArray2<f64>,
        i_kl: Vec<Bound<'_, PyAny>>,
        stiffness: &Bound<'_, PyAny>,
        damping: &Bound<'_, PyAny>,
        position: Option<&Bound<'_, PyAny>>,
        orientation: Option<&Bound<'_, PyAny>>,
        velocity: Option<&Bound<'_, PyAny>>,
        angular_velocity: Option<&Bound<'_, PyAny>>,
        elastic_coordinates: Option<PyReadonlyArray1<f64>>,
        elastic_velocities: Option<PyReadonlyArray1<f64>>,
        stiffening: Option<Vec<Bound<'_, PyAny>>>,
        corotational: Option<Vec<Bound<'_, PyAny>>>,
        dof_nodes: Option<PyReadonlyArray1<i64>>,
        node_positions: Option<PyReadonlyArray2<f64>>,
        condense: Option<bool>,
        scalar_mass: Option<(Bound<'_, PyAny>, PyReadonlyArray1<i64>)>,
        attached: Option<Vec<Bound<'_, PyAny>>>,
        name: Option<String>,
    ) -> PyResult<BodyId> {
        let index = self.inner.body_count();
        let item = match &name {
            Some(n) => format!("body '{n}'"),
            None => format!("body {index}"),
        };
        let i1 = i1.as_array();
        let ibar = ibar.as_array();
        if i1.nrows() != 3 || ibar.nrows() != 9 || ibar.ncols() != i1.ncols() {
            return Err(invalid(&item, "invariants I1 must be (3, n_f) and Ibar (9, n_f)"));
        }
        if i_kl.len() != 9 {
            return Err(invalid(&item, format!("nine invariants I_kl expected, got {}", i_kl.len())));
        }
        let input = FlexibleBodyInput {
            mass,
            first_moment: vec3(first_moment, &item, "first_moment")?,
            second_moment: mat3(second_moment, &item, "second_moment")?,
            i1: i1.iter().copied().collect(),
            ibar: ibar.iter().copied().collect(),
            i_kl: i_kl
                .iter()
                .enumerate()
                .map(|(kl, m)| csc(m, &item, &format!("I_{}{}", kl / 3 + 1, kl % 3 + 1)))
                .collect::<PyResult<_>>()?,
            stiffness: csc(stiffness, &item, "stiffness")?,
            damping: csc(damping, &item, "damping")?,
            stiffening: stiffening
                .unwrap_or_default()
                .iter()
                .map(|e| stiffening_element(e, &item))
                .collect::<PyResult<_>>()?,
            corotational: corotational
                .unwrap_or_default()
                .iter()
                .map(|e| corotational_element(e, &item))
                .collect::<PyResult<_>>()?,
            dof_nodes: match dof_nodes {
                Some(d) => Some(
                    d.as_slice()?
                        .iter()
                        .map(|&k| {
                            usize::try_from(k).map_err(|_| invalid(&item, format!("negative node index {k}")))
                        })
                        .collect::<PyResult<Vec<_>>>()?,
                ),
                None => None,
            },
            node_positions: match node_positions {
                Some(p) if p.as_array().ncols() != 3 => {
                    return Err(invalid(
                        &item,
                        format!("node positions must be (n, 3), got {:?}", p.as_array().shape()),
                    ))
                }
                Some(p) => Some(p.as_array().rows().into_iter().map(|r| Vec3([r[0], r[1], r[2]])).collect()),
                None => None,
            },
            condense,
            scalar_mass: match scalar_mass {
                Some((matrix, coordinates)) => Some(ScalarMass {
                    matrix: csc(&matrix, &item, "scalar mass matrix")?,
                    coordinates: coordinates
                        .as_slice()?
                        .iter()
                        .map(|&c| {
                            usize::try_from(c).map_err(|_| invalid(&item, format!("negative coordinate {c}")))
                        })
                        .collect::<PyResult<Vec<_>>>()?,
                }),
                None => None,
            },
            attached: attached
                .unwrap_or_default()
                .iter()
                .map(|e| attached_mass(e, &item))
                .collect::<PyResult<_>>()?,
        };
        let body = check(FlexibleBody::new(&item, input))?;
        let v = |o: Option<&Bound<'_, PyAny>>, what: &str| -> PyResult<Vec3> {
            o.filter(|x| !x.is_none()).map(|x| vec3(x, &item, what)).unwrap_or(Ok(Vec3::ZERO))
        };
        let orientation = match orientation.filter(|x| !x.is_none()) {
            Some(o) => mat3(o, &item, "orientation")?,
            None => Mat3::IDENTITY,
        };
        let id = check(self.inner.add_flexible_body(
            name.as_deref().unwrap_or(""),
            body,
            v(position, "position")?,
            orientation,
            v(velocity, "velocity")?,
            v(angular_velocity, "angular_velocity")?,
            elastic_coordinates.map(|a| a.as_array().to_vec()).unwrap_or_default(),
            elastic_velocities.map(|a| a.as_array().to_vec()).unwrap_or_default(),
        ))?;
        Ok(BodyId::of(id.0))
    }

    /// Adds a marker on a deformable body that moves with the deformation (low level; use
    /// `add_node_marker` or `add_node_set_marker`): undeformed `position` and `orientation`
    /// in the body frame, the elastic coordinates `indices` it depends on, and the
    /// displacement `translation` (3, n_l) and small rotation `rotation` (3, n_l) per
    /// coordinate.
    #[pyo3(signature = (body, *, position, indices, translation, rotation, orientation = None, name = None))]
    #[allow(clippy::too_many_arguments)]
    fn _add_flexible_marker(
        &mut self,
        body: BodyId,
        position: &Bound<'_, PyAny>,
        indices: PyReadonlyArray1<i64>,
        translation: PyReadonlyArray2<f64>,
        rotation: PyReadonlyArray2<f64>,
        orientation: Option<&Bound<'_, PyAny>>,
        name: Option<String>,
    ) -> PyResult<MarkerId> {
        let index = self.inner.item_counts()[0];
        let item = match &name {
            Some(n) => format!("marker '{n}'"),
            None => format!("marker {index}"),
        };
        let indices = indices
            .as_slice()?
            .iter()
            .map(|&i| {
                usize::try_from(i).map_err(|_| invalid(&item, format!("negative coordinate index {i}")))
            })
            .collect::<PyResult<Vec<_>>>()?;
        let elastic = MarkerElastic {
            indices,
            translation: jacobian3(&translation, &item, "translation")?,
            rotation: jacobian3(&rotation, &item, "rotation")?,
        };
        let orientation = match orientation.filter(|x| !x.is_none()) {
            Some(o) => mat3(o, &item, "orientation")?,
            None => Mat3::IDENTITY,
        };
        let id = check(self.inner.add_flexible_marker(
            name.as_deref().unwrap_or(""),
            body.into(),
            vec3(position, &item, "position")?,
            orientation,
            elastic,
        ))?;
        Ok(MarkerId::of(id.0))
    }
}
