//! Functions of time for drivers and forces: constants, polynomials, harmonics, splines and
//! Python callables.

use std::sync::Arc;

use flexmbd_core::math::time_function::{CubicSpline, TimeCallback, TimeFunction};
use pyo3::prelude::*;

use crate::errors::{invalid, stash_callback_error};

/// f(t) = value.
#[pyclass(module = "flexmbd._core", frozen, subclass)]
#[derive(Clone)]
pub struct Constant {
    /// The value.
    #[pyo3(get)]
    pub value: f64,
}

/// f(t) = c0 + c1 t + c2 t^2 + ... (coefficients in increasing order).
#[pyclass(module = "flexmbd._core", frozen, subclass)]
#[derive(Clone)]
pub struct Polynomial {
    /// Coefficients c0, c1, ...
    #[pyo3(get)]
    pub coefficients: Vec<f64>,
}

/// f(t) = offset + amplitude sin(frequency t + phase); frequency in rad/s.
#[pyclass(module = "flexmbd._core", frozen, subclass)]
#[derive(Clone)]
pub struct Harmonic {
    /// Amplitude.
    #[pyo3(get)]
    pub amplitude: f64,
    /// Angular frequency (rad/s).
    #[pyo3(get)]
    pub frequency: f64,
    /// Phase (rad).
    #[pyo3(get)]
    pub phase: f64,
    /// Constant offset.
    #[pyo3(get)]
    pub offset: f64,
}

/// Natural cubic spline through (times, values); constant outside the range of times.
#[pyclass(module = "flexmbd._core", frozen, subclass)]
#[derive(Clone)]
pub struct Spline {
    /// Knot times (strictly increasing).
    #[pyo3(get)]
    pub times: Vec<f64>,
    /// Values at the knots.
    #[pyo3(get)]
    pub values: Vec<f64>,
    inner: Arc<CubicSpline>,
}

/// A Python function of time. With `derivatives=True` it must return (f, f', f''); otherwise
/// it returns f and the derivatives are taken by central finite differences.
#[pyclass(module = "flexmbd._core", frozen, subclass)]
pub struct UserFunction {
    /// The callable.
    #[pyo3(get)]
    pub function: Py<PyAny>,
    /// Whether it returns its derivatives.
    #[pyo3(get)]
    pub derivatives: bool,
}

struct PyTimeCallback {
    function: Py<PyAny>,
    derivatives: bool,
}

impl TimeCallback for PyTimeCallback {
    fn evaluate(&self, time: f64) -> Result<[f64; 3], String> {
        Python::attach(|py| {
            let value = self.function.call1(py, (time,)).map_err(|e| stash_callback_error(py, e))?;
            if self.derivatives {
                let v: (f64, f64, f64) =
                    value.bind(py).extract().map_err(|e: PyErr| stash_callback_error(py, e))?;
                Ok([v.0, v.1, v.2])
            } else {
                let v: f64 = value.bind(py).extract().map_err(|e: PyErr| stash_callback_error(py, e))?;
                Ok([v, 0.0, 0.0])
            }
        })
    }

    fn derivatives(&self) -> bool {
        self.derivatives
    }
}

fn evaluate(f: &TimeFunction, t: f64) -> PyResult<[f64; 3]> {
    f.evaluate(t).map_err(|m| invalid("time function", m))
}

macro_rules! common_methods {
    ($t:ty) => {
        #[pymethods]
        impl $t {
            /// Value at time `t`.
            fn __call__(&self, t: f64) -> PyResult<f64> {
                Ok(evaluate(&self.core(), t)?[0])
            }

            /// (f, f', f'') at time `t`.
            fn derivatives(&self, t: f64) -> PyResult<(f64, f64, f64)> {
                let v = evaluate(&self.core(), t)?;
                Ok((v[0], v[1], v[2]))
            }
        }
    };
}

#[pymethods]
impl Constant {
    #[new]
    fn new(value: f64) -> PyResult<Self> {
        if !value.is_finite() {
            return Err(invalid("Constant", format!("value must be finite, got {value}")));
        }
        Ok(Constant { value })
    }
    fn __repr__(&self) -> String {
        format!("Constant({})", self.value)
    }
}

#[pymethods]
impl Polynomial {
    #[new]
    fn new(coefficients: Vec<f64>) -> PyResult<Self> {
        if coefficients.is_empty() || !coefficients.iter().all(|c| c.is_finite()) {
            return Err(invalid("Polynomial", "coefficients must be a non-empty list of finite numbers"));
        }
        Ok(Polynomial { coefficients })
    }
    fn __repr__(&self) -> String {
        format!("Polynomial({:?})", self.coefficients)
    }
}

#[pymethods]
impl Harmonic {
    #[new]
    #[pyo3(signature = (amplitude, frequency, phase = 0.0, offset = 0.0))]
    fn new(amplitude: f64, frequency: f64, phase: f64, offset: f64) -> PyResult<Self> {
        if ![amplitude, frequency, phase, offset].iter().all(|c| c.is_finite()) {
            return Err(invalid("Harmonic", "parameters must be finite"));
        }
        Ok(Harmonic { amplitude, frequency, phase, offset })
    }
    fn __repr__(&self) -> String {
        format!(
            "Harmonic(amplitude={}, frequency={}, phase={}, offset={})",
            self.amplitude, self.frequency, self.phase, self.offset
        )
    }
}

#[pymethods]
impl Spline {
    #[new]
    fn new(times: Vec<f64>, values: Vec<f64>) -> PyResult<Self> {
        let inner = CubicSpline::new(times.clone(), values.clone()).map_err(|m| invalid("Spline", m))?;
        Ok(Spline { times, values, inner: Arc::new(inner) })
    }
    fn __repr__(&self) -> String {
        format!(
            "Spline({} points from t = {} to {})",
            self.times.len(),
            self.times[0],
            self.times[self.times.len() - 1]
        )
    }
}

#[pymethods]
impl UserFunction {
    #[new]
    #[pyo3(signature = (function, derivatives = false))]
    fn new(function: Bound<'_, PyAny>, derivatives: bool) -> PyResult<Self> {
        if !function.is_callable() {
            return Err(invalid("UserFunction", "function must be callable"));
        }
        Ok(UserFunction { function: function.unbind(), derivatives })
    }
    fn __repr__(&self) -> String {
        format!("UserFunction(derivatives={})", self.derivatives)
    }
}

impl Constant {
    fn core(&self) -> TimeFunction {
        TimeFunction::Constant(self.value)
    }
}
impl Polynomial {
    fn core(&self) -> TimeFunction {
        TimeFunction::Polynomial(self.coefficients.clone())
    }
}
impl Harmonic {
    fn core(&self) -> TimeFunction {
        TimeFunction::Harmonic {
            amplitude: self.amplitude,
            frequency: self.frequency,
            phase: self.phase,
            offset: self.offset,
        }
    }
}
impl Spline {
    fn core(&self) -> TimeFunction {
        TimeFunction::Spline(self.inner.clone())
    }
}
impl UserFunction {
    fn core(&self) -> TimeFunction {
        Python::attach(|py| {
            TimeFunction::Callback(Arc::new(PyTimeCallback {
                function: self.function.clone_ref(py),
                derivatives: self.derivatives,
            }))
        })
    }
}
common_methods!(Constant);
common_methods!(Polynomial);
common_methods!(Harmonic);
common_methods!(Spline);
common_methods!(UserFunction);

/// Converts a number, a time-function object or a callable into a core time function.
pub fn to_time_function(obj: &Bound<'_, PyAny>, item: &str) -> PyResult<TimeFunction> {
    if let Ok(c) = obj.cast::<Constant>() {
        return Ok(c.get().core());
    }
    if let Ok(c) = obj.cast::<Polynomial>() {
        return Ok(c.get().core());
    }
    if let Ok(c) = obj.cast::<Harmonic>() {
        return Ok(c.get().core());
    }
    if let Ok(c) = obj.cast::<Spline>() {
        return Ok(c.get().core());
    }
    if let Ok(c) = obj.cast::<UserFunction>() {
        return Ok(c.get().core());
    }
    if let Ok(v) = obj.extract::<f64>() {
        if !v.is_finite() {
            return Err(invalid(item, format!("value must be finite, got {v}")));
        }
        return Ok(TimeFunction::Constant(v));
    }
    if obj.is_callable() {
        return Ok(TimeFunction::Callback(Arc::new(PyTimeCallback {
            function: obj.clone().unbind(),
            derivatives: false,
        })));
    }
    Err(invalid(
        item,
        format!(
            "expected a number, a callable or a time function (Constant, Polynomial, Harmonic, Spline, UserFunction), got {}",
            obj.get_type().name().map(|n| n.to_string()).unwrap_or_default()
        ),
    ))
}

/// Converts three components (each anything `to_time_function` accepts) into core functions.
pub fn to_vector_function(obj: &Bound<'_, PyAny>, item: &str) -> PyResult<[TimeFunction; 3]> {
    let parts: Vec<Bound<'_, PyAny>> =
        obj.try_iter().map_err(|_| invalid(item, "expected three components"))?.collect::<PyResult<_>>()?;
    if parts.len() != 3 {
        return Err(invalid(item, format!("expected three components, got {}", parts.len())));
    }
    Ok([
        to_time_function(&parts[0], item)?,
        to_time_function(&parts[1], item)?,
        to_time_function(&parts[2], item)?,
    ])
}

// Pickling and copying: each function is made again from its arguments (a `UserFunction`
// pickles its callable by reference, as pickle does; a lambda or a local function cannot be).
#[pymethods]
impl Constant {
    fn __getnewargs__(&self) -> (f64,) {
        (self.value,)
    }
}

#[pymethods]
impl Polynomial {
    fn __getnewargs__(&self) -> (Vec<f64>,) {
        (self.coefficients.clone(),)
    }
}

#[pymethods]
impl Harmonic {
    fn __getnewargs__(&self) -> (f64, f64, f64, f64) {
        (self.amplitude, self.frequency, self.phase, self.offset)
    }
}

#[pymethods]
impl Spline {
    fn __getnewargs__(&self) -> (Vec<f64>, Vec<f64>) {
        (self.times.clone(), self.values.clone())
    }
}

#[pymethods]
impl UserFunction {
    fn __getnewargs__(&self, py: Python<'_>) -> (Py<PyAny>, bool) {
        (self.function.clone_ref(py), self.derivatives)
    }
}
