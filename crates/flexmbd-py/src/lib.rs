//! Python bindings of flexmbd-core, built by maturin as `flexmbd._core`. Only bindings live
//! here; the public API is the `flexmbd` package, which re-exports these classes.

mod errors;
mod fem;
mod flexible;
mod ids;
mod integrator;
mod model;
mod system;
mod time_function;

use pyo3::prelude::*;

/// Rust core of flexmbd (private; use the `flexmbd` package).
#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    // faer's dense decompositions (redundancy analysis, partitioning, the SVD of joint
    // coordinates) on the calling thread: they are small, and rayon's global pool would hang
    // a process forked after them (Python's multiprocessing). The large sparse
    // factorizations run in flexmbd's own per-process pool (`linalg::parallel`).
    faer::set_global_parallelism(faer::Par::Seq);
    m.add_class::<system::System>()?;
    m.add_class::<model::Model>()?;
    m.add_class::<ids::BodyId>()?;
    m.add_class::<ids::MarkerId>()?;
    m.add_class::<ids::JointId>()?;
    m.add_class::<ids::ForceId>()?;
    m.add_class::<ids::SensorId>()?;
    m.add_class::<time_function::Constant>()?;
    m.add_class::<time_function::Polynomial>()?;
    m.add_class::<time_function::Harmonic>()?;
    m.add_class::<time_function::Spline>()?;
    m.add_class::<time_function::Step>()?;
    m.add_class::<time_function::Trapezoidal>()?;
    m.add_class::<time_function::UserFunction>()?;
    m.add_class::<integrator::GeneralizedAlpha>()?;
    m.add_class::<integrator::ExplicitSolver>()?;
    m.add_function(wrap_pyfunction!(integrator::simulate, m)?)?;
    m.add_class::<fem::Material>()?;
    m.add_class::<fem::Section>()?;
    m.add_class::<fem::ShellSection>()?;
    m.add_class::<fem::FeMesh>()?;
    m.add_function(wrap_pyfunction!(fem::assemble_body, m)?)?;
    m.add_function(wrap_pyfunction!(fem::body_mass_points, m)?)?;
    m.add_function(wrap_pyfunction!(fem::recover_stresses, m)?)?;
    m.add_function(wrap_pyfunction!(fem::shell_membrane_stiffening, m)?)?;
    m.add_function(wrap_pyfunction!(fem::beam_corotational_terms, m)?)?;
    m.add_class::<fem::SymmetricFactor>()?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
