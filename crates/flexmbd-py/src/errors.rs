//! Maps core errors to the Python exception classes of `flexmbd.errors`, with the item and
//! time attached. A Python exception raised inside a user callback is kept and chained as the
//! `__cause__` of the `CallbackError`.

use std::cell::RefCell;

use flexmbd_core::FlexmbdError;
use pyo3::prelude::*;
use pyo3::types::PyTuple;

thread_local! {
    /// The last exception raised by a Python callback on this thread.
    static CALLBACK_ERROR: RefCell<Option<PyErr>> = const { RefCell::new(None) };
}

/// Remembers a Python exception raised inside a callback and returns its message.
pub fn stash_callback_error(py: Python<'_>, err: PyErr) -> String {
    let message = err.value(py).to_string();
    let kind = err.get_type(py).name().map(|n| n.to_string()).unwrap_or_default();
    CALLBACK_ERROR.with(|slot| *slot.borrow_mut() = Some(err));
    format!("{kind}: {message}")
}

fn take_callback_error() -> Option<PyErr> {
    CALLBACK_ERROR.with(|slot| slot.borrow_mut().take())
}

fn class_and_data(err: &FlexmbdError) -> (&'static str, Option<String>, Option<f64>) {
    use FlexmbdError::*;
    match err {
        InvalidParameter { item, .. } => ("InvalidParameterError", Some(item.clone()), None),
        UnknownItem { kind, id, .. } => ("UnknownItemError", Some(format!("{kind} {id}")), None),
        InvalidModel { item, .. } => ("InvalidModelError", Some(item.clone()), None),
        InconsistentInitialConditions { time, item, .. } => {
            ("InitialConditionsError", Some(item.clone()), Some(*time))
        }
        InitialCorrectionRefused { time, item, .. } => {
            ("InitialConditionsError", Some(item.clone()), Some(*time))
        }
        VelocitiesOffTheTree { time, item, .. } => {
            ("InitialConditionsError", Some(item.clone()), Some(*time))
        }
        NewtonDiverged { time, item, .. } => ("NewtonDivergedError", Some(item.clone()), Some(*time)),
        StepSizeTooSmall { time, .. } => ("StepSizeTooSmallError", None, Some(*time)),
        SingularMatrix { time, context, .. } => ("SingularMatrixError", Some(context.clone()), Some(*time)),
        NonFinite { item, time } => ("NonFiniteError", Some(item.clone()), Some(*time)),
        Callback { item, time, .. } => ("CallbackError", Some(item.clone()), Some(*time)),
        ConflictingConstraints { time, item, .. } => {
            ("ConflictingConstraintsError", Some(item.clone()), Some(*time))
        }
        Interrupted { time } => ("SimulationInterrupted", None, Some(*time)),
    }
}

/// The Python exception object for a core error.
pub fn to_exception(py: Python<'_>, err: &FlexmbdError) -> PyErr {
    let (class, item, time) = class_and_data(err);
    let build = || -> PyResult<PyErr> {
        let module = py.import("flexmbd.errors")?;
        let cls = module.getattr(class)?;
        let args = PyTuple::new(py, [err.to_string().into_pyobject(py)?.into_any()])?;
        let obj = cls.call(args, None)?;
        obj.setattr("item", item.clone())?;
        obj.setattr("time", time)?;
        if let FlexmbdError::Callback { .. } = err {
            if let Some(cause) = take_callback_error() {
                obj.setattr("__cause__", cause.value(py))?;
            }
        }
        Ok(PyErr::from_value(obj))
    };
    build().unwrap_or_else(|e| e)
}

/// Converts a core result into a Python result.
pub fn check<T>(result: flexmbd_core::Result<T>) -> PyResult<T> {
    result.map_err(|e| Python::attach(|py| to_exception(py, &e)))
}

/// An `InvalidParameterError` for bad arguments found in the binding itself.
pub fn invalid(item: &str, message: impl Into<String>) -> PyErr {
    Python::attach(|py| {
        to_exception(py, &FlexmbdError::InvalidParameter { item: item.to_string(), message: message.into() })
    })
}

/// A number for a message: plain when short, in scientific notation when its plain form would
/// run to dozens of digits (1e300 is "1e300", not 301 digits).
pub fn shown(value: f64) -> String {
    if value != 0.0 && value.is_finite() && !(1e-4..1e15).contains(&value.abs()) {
        format!("{value:e}")
    } else {
        format!("{value}")
    }
}

/// Checks that the setting `name` of `item` is a finite number above `floor`: NaN, an
/// infinity or a value at or below the floor is an `InvalidParameterError` naming it.
pub fn above(item: &str, name: &str, value: f64, floor: f64) -> PyResult<()> {
    if value.is_finite() && value > floor {
        Ok(())
    } else {
        Err(invalid(item, format!("{name} must be a finite number > {}, got {}", shown(floor), shown(value))))
    }
}

/// A real-number argument that is not a bool: PyO3 takes True as 1.0 (`Material(True, ...)`
/// was a material of 1 Pa). A bool is the TypeError of a wrong type, which the Python boundary
/// names with the call and the argument (`ArgumentTypeError`).
#[derive(Clone, Copy)]
pub struct Real(pub f64);

impl<'a, 'py> FromPyObject<'a, 'py> for Real {
    type Error = PyErr;

    fn extract(obj: pyo3::Borrowed<'a, 'py, PyAny>) -> PyResult<Self> {
        if obj.is_instance_of::<pyo3::types::PyBool>() {
            return Err(pyo3::exceptions::PyTypeError::new_err("must be a real number, not bool"));
        }
        Ok(Real(obj.extract::<f64>()?))
    }
}

/// An integer argument of at least `min` (a count, an index): a negative number, a float or
/// another type is an `InvalidParameterError` naming the argument (PyO3's own conversion
/// raises OverflowError or TypeError without the name).
pub fn integer_argument(value: &Bound<'_, PyAny>, name: &str, min: usize) -> PyResult<usize> {
    let bad = |got: String| invalid(name, format!("{name} must be an integer >= {min}, got {got}"));
    if value.is_instance_of::<pyo3::types::PyBool>() {
        return Err(bad(value.repr().map(|r| r.to_string()).unwrap_or_default()));
    }
    match value.extract::<i128>() {
        Ok(v) if v >= min as i128 && v <= usize::MAX as i128 => Ok(v as usize),
        Ok(v) => Err(bad(v.to_string())),
        Err(_) => {
            let kind = value.get_type().name().map(|n| n.to_string()).unwrap_or_default();
            Err(bad(format!("{} ({kind})", value.repr().map(|r| r.to_string()).unwrap_or_default())))
        }
    }
}
