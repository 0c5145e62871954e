//! Preprocessor bindings: materials, beam sections and the assembly of a deformable body
//! (stiffness, mass and invariants of motion), returned as arrays for NumPy and SciPy.

use flexmbd_core::fem::{self, Element, ElementType, Ikl, Mesh};
use flexmbd_core::linalg;
use flexmbd_core::math::Vec3;
use numpy::{
    IntoPyArray, PyArray1, PyArrayDyn, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArrayDyn,
};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyTuple};

use crate::errors::{check, invalid, Real};

/// Isotropic linear elastic material: Young's modulus (Pa), Poisson's ratio, density (kg/m^3).
#[pyclass(module = "flexmbd._core", frozen, subclass, from_py_object)]
#[derive(Clone)]
pub struct Material {
    pub(crate) inner: fem::Material,
}

#[pymethods]
impl Material {
    #[new]
    #[pyo3(signature = (young_modulus, poisson_ratio, density, *, name = None))]
    fn new(young_modulus: Real, poisson_ratio: Real, density: Real, name: Option<String>) -> PyResult<Self> {
        let item = name.map(|n| format!("material '{n}'")).unwrap_or_else(|| "material".to_string());
        let (young_modulus, poisson_ratio, density) = (young_modulus.0, poisson_ratio.0, density.0);
        Ok(Material { inner: check(fem::Material::new(&item, young_modulus, poisson_ratio, density))? })
    }

    /// Young's modulus (Pa).
    #[getter]
    fn young_modulus(&self) -> f64 {
        self.inner.young_modulus
    }

    /// Poisson's ratio.
    #[getter]
    fn poisson_ratio(&self) -> f64 {
        self.inner.poisson_ratio
    }

    /// Density (kg/m^3).
    #[getter]
    fn density(&self) -> f64 {
        self.inner.density
    }

    /// Shear modulus E / (2 (1 + nu)) (Pa).
    #[getter]
    fn shear_modulus(&self) -> f64 {
        self.inner.shear_modulus()
    }

    fn __repr__(&self) -> String {
        format!(
            "Material(young_modulus={:e}, poisson_ratio={}, density={})",
            self.inner.young_modulus, self.inner.poisson_ratio, self.inner.density
        )
    }
}

/// Beam cross-section in its principal axes: area A, iy = int z^2 dA, iz = int y^2 dA and the
/// torsion constant J (m^2, m^4). Use `Section.rectangle`, `Section.circle`, `Section.tube` or
/// give the values.
#[pyclass(module = "flexmbd._core", frozen, from_py_object)]
#[derive(Clone)]
pub struct Section {
    pub(crate) inner: fem::Section,
}

#[pymethods]
impl Section {
    #[new]
    fn new(area: Real, iy: Real, iz: Real, torsion_constant: Real) -> PyResult<Self> {
        let [area, iy, iz, torsion_constant] = [area.0, iy.0, iz.0, torsion_constant.0];
        Ok(Section { inner: check(fem::Section::new("section", area, iy, iz, torsion_constant))? })
    }

    /// Solid rectangle of width b (along the section's y axis) and height h (along z).
    #[staticmethod]
    fn rectangle(b: f64, h: f64) -> PyResult<Self> {
        Ok(Section { inner: check(fem::Section::rectangle("rectangular section", b, h))? })
    }

    /// Solid circle of radius r.
    #[staticmethod]
    fn circle(r: f64) -> PyResult<Self> {
        Ok(Section { inner: check(fem::Section::circle("circular section", r))? })
    }

    /// Circular tube with radii outer > inner >= 0.
    #[staticmethod]
    fn tube(outer: f64, inner: f64) -> PyResult<Self> {
        Ok(Section { inner: check(fem::Section::tube("tube section", outer, inner))? })
    }

    /// Area (m^2).
    #[getter]
    fn area(&self) -> f64 {
        self.inner.area
    }

    /// int z^2 dA (m^4).
    #[getter]
    fn iy(&self) -> f64 {
        self.inner.iy
    }

    /// int y^2 dA (m^4).
    #[getter]
    fn iz(&self) -> f64 {
        self.inner.iz
    }

    /// Saint-Venant torsion constant (m^4).
    #[getter]
    fn torsion_constant(&self) -> f64 {
        self.inner.torsion_constant
    }

    /// Shear correction factor kappa of Timoshenko beams (shear area kappa A).
    #[getter]
    fn shear_factor(&self) -> f64 {
        self.inner.shear_factor
    }

    /// The same section with another shear correction factor, in (0, 1].
    fn with_shear_factor(&self, kappa: f64) -> PyResult<Self> {
        Ok(Section { inner: check(self.inner.with_shear_factor("section", kappa))? })
    }

    /// Whether beams of this section carry the rotary inertia of the section turning with
    /// the bending slopes (the Rayleigh beam, kinematic coupling; default True).
    #[getter]
    fn rotary_inertia(&self) -> bool {
        self.inner.rotary_inertia
    }

    /// The same section without the rotary inertia of bending: the classical consistent
    /// mass of the centroid line (the torsional inertia stays), to measure its effect.
    fn without_rotary_inertia(&self) -> Self {
        Section { inner: self.inner.without_rotary_inertia() }
    }

    fn __repr__(&self) -> String {
        let s = &self.inner;
        format!(
            "Section(area={:e}, iy={:e}, iz={:e}, torsion_constant={:e})",
            s.area, s.iy, s.iz, s.torsion_constant
        )
    }
}

/// Section of flat shell elements ("quad4", "tri3"): the thickness t (m) and the shear
/// correction factor of the Mindlin plate (5/6).
#[pyclass(module = "flexmbd._core", frozen, from_py_object)]
#[derive(Clone)]
pub struct ShellSection {
    pub(crate) inner: fem::ShellSection,
}

#[pymethods]
impl ShellSection {
    #[new]
    #[pyo3(signature = (thickness, *, shear_factor = 5.0 / 6.0))]
    fn new(thickness: f64, shear_factor: f64) -> PyResult<Self> {
        let inner = check(fem::ShellSection::new("shell section", thickness))?;
        Ok(ShellSection { inner: check(inner.with_shear_factor("shell section", shear_factor))? })
    }

    /// Thickness (m).
    #[getter]
    fn thickness(&self) -> f64 {
        self.inner.thickness
    }

    /// Shear correction factor kappa of the transverse shear stiffness kappa G t.
    #[getter]
    fn shear_factor(&self) -> f64 {
        self.inner.shear_factor
    }

    fn __repr__(&self) -> String {
        format!(
            "ShellSection(thickness={:e}, shear_factor={})",
            self.inner.thickness, self.inner.shear_factor
        )
    }
}

fn csc_tuple<'py>(py: Python<'py>, m: linalg::Csc) -> PyResult<Bound<'py, PyTuple>> {
    let to_i64 = |v: Vec<usize>| v.into_iter().map(|x| x as i64).collect::<Vec<i64>>();
    PyTuple::new(
        py,
        [
            PyArray1::from_vec(py, m.values).into_any(),
            PyArray1::from_vec(py, to_i64(m.row_idx)).into_any(),
            PyArray1::from_vec(py, to_i64(m.col_ptr)).into_any(),
            (m.nrows, m.ncols).into_pyobject(py)?.into_any(),
        ],
    )
}

/// Default section y axis of a beam along `axis`: global y, or global z for beams nearly
/// along y.
fn default_orientation(axis: Vec3) -> Vec3 {
    let a = axis * (1.0 / axis.norm());
    if a[1].abs() < 0.9 {
        Vec3([0.0, 1.0, 0.0])
    } else {
        Vec3([0.0, 0.0, 1.0])
    }
}

/// A finite-element mesh with its material, beam section and shell section, checked and
/// built once (`flexmbd_core::fem::Mesh`) for the functions that take it: `assemble_body`,
/// `recover_stresses`, `body_mass_points`. Nodes (n, 3) in the body frame, node ids (n,),
/// elements as a dict type -> (connectivity (n_e, nodes), ids (n_e,)) with types "beam2",
/// "tet4", "tet10" (Gmsh node order), "hex8", "hex8i" (with incompatible modes), "hex20",
/// "hex20r" (VTK node order; reduced integration), "hex27" (VTK node order), "wedge6" (Gmsh's prism), "wedge15"
/// (Abaqus C3D15 order), "wedge18" (wedge15's nodes, then the centres of the faces (0,1,4,3),
/// (1,2,5,4), (2,0,3,5)), "pyramid5" (Gmsh's pyramid), "pyramid13" (VTK node order),
/// "pyramid14" (pyramid13's nodes, then the base's centre), "quad4" and "tri3"; the beam
/// orientation is a
/// vector in the sections' x-y plane (default: global y, or global z for beams nearly along
/// y); `shear`: shear-deformable (Timoshenko) beams.
#[pyclass(name = "FeMesh", module = "flexmbd._core", frozen)]
pub struct FeMesh {
    inner: Mesh,
}

#[pymethods]
impl FeMesh {
    #[new]
    #[pyo3(signature = (nodes, node_ids, elements, material, section = None, orientation = None, shear = false, shell = None))]
    #[allow(clippy::too_many_arguments)]
    fn new<'py>(
        nodes: PyReadonlyArray2<'py, f64>,
        node_ids: PyReadonlyArray1<'py, i64>,
        elements: &Bound<'py, PyDict>,
        material: &Material,
        section: Option<Section>,
        orientation: Option<Vec<f64>>,
        shear: bool,
        shell: Option<ShellSection>,
    ) -> PyResult<Self> {
        let (section, orientation, shell) = (section.as_ref(), orientation.as_deref(), shell.as_ref());
        let nodes = nodes.as_array();
        if nodes.ncols() != 3 {
            return Err(invalid(
                "mesh",
                format!("nodes must be an (n, 3) array, got {} columns", nodes.ncols()),
            ));
        }
        let positions: Vec<Vec3> = nodes.rows().into_iter().map(|r| Vec3([r[0], r[1], r[2]])).collect();
        let mut list = Vec::new();
        for (key, value) in elements.iter() {
            let kind: String = key.extract()?;
            let (connectivity, ids): (PyReadonlyArray2<'py, i64>, PyReadonlyArray1<'py, i64>) =
                value.extract()?;
            let connectivity = connectivity.as_array();
            let ids = ids.as_array();
            if ids.len() != connectivity.nrows() {
                return Err(invalid(
                    "mesh",
                    format!("{} ids for {} {kind} elements", ids.len(), connectivity.nrows()),
                ));
            }
            for (row, &id) in connectivity.rows().into_iter().zip(ids.iter()) {
                let element_nodes: Vec<usize> = row
                    .iter()
                    .map(|&v| {
                        usize::try_from(v).map_err(|_| {
                            invalid(&format!("element {id}"), format!("negative node index {v}"))
                        })
                    })
                    .collect::<PyResult<_>>()?;
                let kind = match kind.as_str() {
                    "beam2" => {
                        let section = section.ok_or_else(|| {
                            invalid(&format!("element {id}"), "beam elements need a section")
                        })?;
                        let axis = match (element_nodes.first(), element_nodes.get(1)) {
                            (Some(&a), Some(&b)) if a < positions.len() && b < positions.len() => {
                                positions[b] - positions[a]
                            }
                            _ => Vec3([1.0, 0.0, 0.0]),
                        };
                        let o = match orientation {
                            Some(v) if v.len() == 3 => Vec3([v[0], v[1], v[2]]),
                            Some(v) => {
                                return Err(invalid(
                                    "beam orientation",
                                    format!("expected 3 components, got {}", v.len()),
                                ))
                            }
                            None => default_orientation(axis),
                        };
                        ElementType::Beam(fem::Beam { section: section.inner, orientation: o, shear })
                    }
                    "tet4" => ElementType::Tet4,
                    "tet10" => ElementType::Tet10,
                    "hex8" => ElementType::Hex8,
                    "hex8i" => ElementType::Hex8Incompatible,
                    "hex20" => ElementType::Hex20,
                    "hex20r" => ElementType::Hex20Reduced,
                    "hex27" => ElementType::Hex27,
                    "wedge6" => ElementType::Wedge6,
                    "wedge15" => ElementType::Wedge15,
                    "wedge18" => ElementType::Wedge18,
                    "pyramid5" => ElementType::Pyramid5,
                    "pyramid13" => ElementType::Pyramid13,
                    "pyramid14" => ElementType::Pyramid14,
                    "quad4" | "tri3" => {
                        let section = shell.ok_or_else(|| {
                            invalid(
                                &format!("element {id}"),
                                "shell elements need a shell section (thickness)",
                            )
                        })?;
                        if kind == "quad4" {
                            ElementType::Quad4(fem::ShellQuad4 { section: section.inner })
                        } else {
                            ElementType::Tri3(fem::ShellTri3 { section: section.inner })
                        }
                    }
                    other => {
                        return Err(invalid(
                            "mesh",
                            format!(
                            "unsupported element type '{other}' (use beam2, tet4, tet10, hex8, hex8i, hex20, hex20r, hex27, wedge6, wedge15, wedge18, pyramid5, pyramid13, pyramid14, quad4, tri3)"
                        ),
                        ))
                    }
                };
                list.push(Element { id, kind, nodes: element_nodes });
            }
        }
        let inner = Mesh {
            nodes: positions,
            node_ids: node_ids.as_array().to_vec(),
            elements: list,
            material: material.inner,
        };
        Ok(FeMesh { inner })
    }

    /// Coordinates per node: 3 for solids, 6 with beams or shells.
    #[getter]
    fn dofs_per_node(&self) -> usize {
        self.inner.dofs_per_node()
    }
}

/// Assembles a deformable body of `mesh`, with the mass lumped or consistent. Returns a dict
/// of arrays: "dofs_per_node", "stiffness" and "mass" as (data, indices, indptr, shape) of CSC
/// matrices, "mass_total", "first_moment", "second_moment", "i1" (3, n), "ibar" (3, 3, n), and
/// either "i_kl_scalar" (the scalar nodal mass matrix M_s of solid bodies: I_kl = M_s (x) e_k
/// e_l^T) or "i_kl" (nine CSC tuples).
#[pyfunction]
#[pyo3(signature = (mesh, lumped = false))]
pub fn assemble_body<'py>(py: Python<'py>, mesh: &FeMesh, lumped: bool) -> PyResult<Bound<'py, PyDict>> {
    let mesh = &mesh.inner;
    let body = py.detach(|| mesh.assemble(lumped));
    let body = check(body)?;
    let n = body.stiffness.nrows;
    let d = PyDict::new(py);
    d.set_item("dofs_per_node", body.dofs_per_node)?;
    d.set_item("stiffness", csc_tuple(py, body.stiffness)?)?;
    d.set_item("mass", csc_tuple(py, body.mass)?)?;
    let inv = body.invariants;
    d.set_item("mass_total", inv.mass)?;
    d.set_item("first_moment", PyArray1::from_vec(py, inv.first_moment.0.to_vec()))?;
    d.set_item("second_moment", PyArray1::from_vec(py, inv.second_moment.0.concat()).reshape([3, 3])?)?;
    d.set_item("i1", PyArray1::from_vec(py, inv.i1).reshape([3, n])?)?;
    d.set_item("ibar", PyArray1::from_vec(py, inv.ibar).reshape([3, 3, n])?)?;
    match inv.i_kl {
        Ikl::Scalar(ms) => d.set_item("i_kl_scalar", csc_tuple(py, ms)?)?,
        Ikl::Blocks(blocks) => {
            let list = PyList::empty(py);
            for m in blocks {
                list.append(csc_tuple(py, m)?)?;
            }
            d.set_item("i_kl", list)?;
        }
    }
    Ok(d)
}

/// Stresses recovered from nodal displacements of `mesh`, `displacements` (records, n_dofs)
/// node-major in body axes. Returns `(nodal, beams, shells)`: solid (and shell mid-surface)
/// stresses averaged at the nodes (records, nodes, 6) in Voigt order (xx, yy, zz, yz, xz, xy),
/// body axes, Pa; beam section resultants [N, V_y, V_z, T, M_y, M_z] at both ends of every beam
/// element (records, beams, 2, 6), element axes; and shell stresses at the top, middle and
/// bottom surfaces averaged at the nodes (records, nodes, 3, 6), body axes, zeros at nodes
/// without shells.
#[pyfunction]
pub fn recover_stresses<'py>(
    py: Python<'py>,
    mesh: &FeMesh,
    displacements: PyReadonlyArray2<'py, f64>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let mesh = &mesh.inner;
    let u = displacements.as_array();
    let records: Vec<Vec<f64>> = u.rows().into_iter().map(|r| r.to_vec()).collect();
    type Recovered = (Vec<f64>, Vec<f64>, Vec<f64>, usize);
    let result = py.detach(|| -> flexmbd_core::Result<Recovered> {
        let mut nodal = Vec::new();
        let mut beams = Vec::new();
        let mut shells = Vec::new();
        let mut count = 0;
        for r in &records {
            let s = mesh.recover_stresses(r)?;
            nodal.extend(s.nodal.iter().flatten());
            beams.extend(s.beams.iter().flatten().flatten());
            shells.extend(s.shells.iter().flatten().flatten());
            count = s.beams.len();
        }
        Ok((nodal, beams, shells, count))
    });
    let (nodal, beams, shells, count) = check(result)?;
    let n = mesh.nodes.len();
    let r = records.len();
    Ok((
        PyArray1::from_vec(py, nodal).reshape([r, n, 6])?.into_any(),
        PyArray1::from_vec(py, beams).reshape([r, count, 2, 6])?.into_any(),
        PyArray1::from_vec(py, shells).reshape([r, n, 3, 6])?.into_any(),
    ))
}

/// The mass points of a body of `mesh`: weights (P,) = rho dV, positions (P, 3) and the
/// shape matrices as the (data, indices, indptr, shape) of a CSR matrix (3 P, n_dofs) whose
/// rows 3 p .. 3 p + 3 are S of point p. For brute-force checks of the invariants.
#[pyfunction]
#[pyo3(signature = (mesh, lumped = false))]
pub fn body_mass_points<'py>(py: Python<'py>, mesh: &FeMesh, lumped: bool) -> PyResult<Bound<'py, PyTuple>> {
    let mesh = &mesh.inner;
    let n = mesh.nodes.len() * mesh.dofs_per_node();
    let mut weights = Vec::new();
    let mut positions = Vec::new();
    let (mut data, mut indices, mut indptr) = (Vec::new(), Vec::new(), vec![0i64]);
    check(mesh.for_each_mass_point(lumped, |p, dofs| {
        weights.push(p.weight);
        positions.extend_from_slice(&p.position.0);
        let ne = dofs.len();
        for row in 0..3 {
            for (a, &g) in dofs.iter().enumerate() {
                let v = p.shape[row * ne + a];
                if v != 0.0 {
                    data.push(v);
                    indices.push(g as i64);
                }
            }
            indptr.push(data.len() as i64);
        }
    }))?;
    let count = weights.len();
    PyTuple::new(
        py,
        [
            PyArray1::from_vec(py, weights).into_any(),
            PyArray1::from_vec(py, positions).reshape([count, 3])?.into_any(),
            PyTuple::new(
                py,
                [
                    PyArray1::from_vec(py, data).into_any(),
                    PyArray1::from_vec(py, indices).into_any(),
                    PyArray1::from_vec(py, indptr).into_any(),
                    (3 * count, n).into_pyobject(py)?.into_any(),
                ],
            )?
            .into_any(),
        ],
    )
}

/// The membrane stiffening terms of one shell element (geometric stiffness; see
/// `flexmbd_core::fem::membrane_stiffening`): for its nodes (3 or 4, 3) and the section and
/// material, returns `(axes (3, 3) rows e1 e2 n, linear (3, n_e), slopes (3, n_e, n_e),
/// stiffness (3, 3))` with n_e = 6 x nodes over the local coordinates in element axes.
#[pyfunction]
pub fn shell_membrane_stiffening<'py>(
    py: Python<'py>,
    nodes: PyReadonlyArray2<'py, f64>,
    shell: &ShellSection,
    material: &Material,
) -> PyResult<Bound<'py, PyTuple>> {
    let x: Vec<Vec3> = nodes.as_array().rows().into_iter().map(|r| Vec3([r[0], r[1], r[2]])).collect();
    if nodes.as_array().ncols() != 3 {
        return Err(invalid("shell element", "nodes must be a (3 or 4, 3) array"));
    }
    let (axes, linear, slopes, stiffness) = fem::membrane_stiffening(&shell.inner, &material.inner, &x)
        .map_err(|e| invalid("shell element", e.to_string()))?;
    let ne = 6 * x.len();
    PyTuple::new(
        py,
        [
            PyArray1::from_vec(py, axes.0.concat()).reshape([3, 3])?.into_any(),
            PyArray1::from_vec(py, linear).reshape([3, ne])?.into_any(),
            PyArray1::from_vec(py, slopes).reshape([3, ne, ne])?.into_any(),
            PyArray1::from_vec(py, stiffness).reshape([3, 3])?.into_any(),
        ],
    )
}

/// The co-rotational terms of one beam element (see `flexmbd_core::body::corotational`): for
/// its nodes (2, 3), section, material, section orientation (None: the preprocessor's
/// default) and beam theory (`shear`: Timoshenko), returns `(axes (3, 3) rows x y z, length,
/// stiffness (12, 12))`, the local stiffness matrix in those axes as the preprocessor
/// assembles it.
#[pyfunction]
#[pyo3(signature = (nodes, section, material, orientation = None, shear = false))]
pub fn beam_corotational_terms<'py>(
    py: Python<'py>,
    nodes: PyReadonlyArray2<'py, f64>,
    section: &Section,
    material: &Material,
    orientation: Option<Vec<f64>>,
    shear: bool,
) -> PyResult<Bound<'py, PyTuple>> {
    let a = nodes.as_array();
    if a.ncols() != 3 || a.nrows() != 2 {
        return Err(invalid("beam element", "nodes must be a (2, 3) array"));
    }
    let x: Vec<Vec3> = a.rows().into_iter().map(|r| Vec3([r[0], r[1], r[2]])).collect();
    let orientation = match orientation {
        Some(v) if v.len() == 3 => Vec3([v[0], v[1], v[2]]),
        Some(v) => {
            return Err(invalid("beam orientation", format!("expected 3 components, got {}", v.len())))
        }
        None => default_orientation(x[1] - x[0]),
    };
    let beam = fem::Beam { section: section.inner, orientation, shear };
    let (axes, length, stiffness) =
        beam.corotational_terms(&material.inner, &x).map_err(|e| invalid("beam element", e.to_string()))?;
    PyTuple::new(
        py,
        [
            PyArray1::from_vec(py, axes.0.concat()).reshape([3, 3])?.into_any(),
            length.into_pyobject(py)?.into_any(),
            PyArray1::from_vec(py, stiffness.concat()).reshape([12, 12])?.into_any(),
        ],
    )
}

/// Sparse symmetric factorization (Rust, faer): Cholesky of a positive definite matrix, or
/// regularized LDL^T of a quasi-definite saddle-point matrix whose first `positive` unknowns
/// form the definite block. The matrix is given as CSC arrays (only the lower triangle is
/// read). The elimination order is `ordering` (position -> unknown) when given; else, with
/// `dof_nodes` (node index of each unknown, -1 for none) and `positions` (node coordinates), a
/// geometric nested dissection of the mesh; else approximate minimum degree. `single`:
/// Cholesky in single precision of the Jacobi-scaled matrix (half the memory; accurate to
/// about 1e-7 times the condition number: a preconditioner). `threads` > 1 factorizes in
/// parallel.
#[pyclass(module = "flexmbd._core", frozen)]
pub struct SymmetricFactor {
    inner: linalg::SymmetricFactor,
}

#[pymethods]
impl SymmetricFactor {
    #[new]
    #[pyo3(signature = (n, indptr, indices, data, *, dof_nodes = None, positions = None, ordering = None, positive = None, single = false, threads = 1, name = "matrix".to_string()))]
    #[allow(clippy::too_many_arguments)]
    fn new<'py>(
        py: Python<'py>,
        n: usize,
        indptr: PyReadonlyArray1<'py, i64>,
        indices: PyReadonlyArray1<'py, i64>,
        data: PyReadonlyArray1<'py, f64>,
        dof_nodes: Option<PyReadonlyArray1<'py, i64>>,
        positions: Option<PyReadonlyArray2<'py, f64>>,
        ordering: Option<PyReadonlyArray1<'py, i64>>,
        positive: Option<usize>,
        single: bool,
        threads: usize,
        name: String,
    ) -> PyResult<Self> {
        let to_usize = |v: &[i64], what: &str| -> PyResult<Vec<usize>> {
            v.iter()
                .map(|&x| usize::try_from(x).map_err(|_| invalid(&name, format!("negative {what} {x}"))))
                .collect()
        };
        let col_ptr = to_usize(indptr.as_slice()?, "column pointer")?;
        let row_idx = to_usize(indices.as_slice()?, "row index")?;
        let values = data.as_slice()?.to_vec();
        let nodes: Option<Vec<usize>> = dof_nodes
            .map(|d| d.as_array().iter().map(|&k| usize::try_from(k).unwrap_or(usize::MAX)).collect());
        let coordinates: Option<Vec<Vec3>> =
            positions.map(|p| p.as_array().rows().into_iter().map(|r| Vec3([r[0], r[1], r[2]])).collect());
        let given: Option<Vec<usize>> = match ordering {
            Some(o) => Some(to_usize(o.as_slice()?, "ordering entry")?),
            None => None,
        };
        let kind = match (positive, single) {
            (Some(p), false) => linalg::FactorKind::QuasiDefinite { positive: p },
            (None, false) => linalg::FactorKind::Cholesky,
            (None, true) => linalg::FactorKind::CholeskySingle,
            (Some(_), true) => {
                return Err(invalid(&name, "single precision is for positive definite matrices only"))
            }
        };
        let result = py.detach(|| {
            let ordering = match (&given, &nodes, &coordinates) {
                (Some(g), _, _) => linalg::Ordering::Given(g),
                (None, Some(d), Some(x)) => linalg::Ordering::NestedDissection { dof_nodes: d, positions: x },
                _ => linalg::Ordering::Amd,
            };
            let matrix = linalg::CscRef { n, col_ptr: &col_ptr, row_idx: &row_idx, values: &values };
            linalg::SymmetricFactor::new(&name, matrix, ordering, kind, threads.max(1))
        });
        Ok(SymmetricFactor { inner: check(result)? })
    }

    /// Order of the matrix.
    #[getter]
    fn dim(&self) -> usize {
        self.inner.dim()
    }

    /// Number of stored entries of the factor.
    #[getter]
    fn factor_nnz(&self) -> usize {
        self.inner.factor_len()
    }

    /// Bytes held by the factor's values (8 per entry, 4 in single precision).
    #[getter]
    fn factor_bytes(&self) -> usize {
        self.inner.factor_bytes()
    }

    /// Solves A x = b for b of shape (n,) or (n, k); with `refine` > 0, iterative refinement
    /// steps against the unregularized matrix.
    #[pyo3(signature = (b, refine = 0))]
    fn solve<'py>(
        &self,
        py: Python<'py>,
        b: PyReadonlyArrayDyn<'py, f64>,
        refine: usize,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let b = b.as_array();
        let n = self.inner.dim();
        let shape = b.shape().to_vec();
        if shape.is_empty() || shape[0] != n || shape.len() > 2 {
            return Err(invalid(
                "right-hand side",
                format!("expected shape ({n},) or ({n}, k), got {shape:?}"),
            ));
        }
        let k = if shape.len() == 2 { shape[1] } else { 1 };
        if refine == 0 {
            let rows = b.as_standard_layout();
            let rows = rows.as_slice().expect("standard layout is contiguous");
            let x = check(py.detach(|| self.inner.solve_rows(rows, k)))?;
            let out = numpy::ndarray::ArrayD::from_shape_vec(shape, x)
                .map_err(|e| invalid("right-hand side", e.to_string()))?;
            return Ok(out.into_pyarray(py));
        }
        // Column-major copy.
        let mut x = vec![0.0; n * k];
        for (idx, v) in b.indexed_iter() {
            let (r, c) = if shape.len() == 2 { (idx[0], idx[1]) } else { (idx[0], 0) };
            x[c * n + r] = *v;
        }
        check(py.detach(|| self.inner.solve_refined(&mut x, refine)))?;
        let out = if shape.len() == 2 {
            numpy::ndarray::Array2::from_shape_fn((n, k), |(r, c)| x[c * n + r]).into_dyn()
        } else {
            numpy::ndarray::Array1::from_vec(x).into_dyn()
        };
        Ok(out.into_pyarray(py))
    }

    /// A x for the factorized symmetric matrix (without regularization), x of shape (n,) or
    /// (n, k).
    fn multiply<'py>(
        &self,
        py: Python<'py>,
        x: PyReadonlyArrayDyn<'py, f64>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let x = x.as_array();
        let n = self.inner.dim();
        let shape = x.shape().to_vec();
        if shape.is_empty() || shape[0] != n || shape.len() > 2 {
            return Err(invalid(
                "multiplied vector",
                format!("expected shape ({n},) or ({n}, k), got {shape:?}"),
            ));
        }
        let k = if shape.len() == 2 { shape[1] } else { 1 };
        let rows = x.as_standard_layout();
        let rows = rows.as_slice().expect("standard layout is contiguous");
        let y = check(py.detach(|| self.inner.multiply(rows, k)))?;
        let out = numpy::ndarray::ArrayD::from_shape_vec(shape, y)
            .map_err(|e| invalid("multiplied vector", e.to_string()))?;
        Ok(out.into_pyarray(py))
    }

    fn __repr__(&self) -> String {
        format!("SymmetricFactor(dim={}, factor_nnz={})", self.inner.dim(), self.inner.factor_len())
    }
}
