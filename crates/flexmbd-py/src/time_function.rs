//! Functions of time for drivers and forces: constants, polynomials, harmonics, splines,
//! motion profiles and Python callables.

use std::sync::Arc;

use flexmbd_core::math::profile::{MotionProfile, ProfileShape};
use flexmbd_core::math::time_function::{CubicSpline, SplineEnd, TimeCallback, TimeFunction};
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

/// Cubic spline through (times, values) with end conditions `end`: "natural" (zero second
/// derivative at the ends), "clamped" (first derivatives `slopes` at the ends, default zero)
/// or "periodic" (first and last values equal; value, slope and curvature continuous across
/// the period, which repeats). Outside its knots a periodic spline repeats; the others go on
/// as the straight line of their end value and slope (value and velocity continuous; a
/// clamped spline with zero end slopes rests).
#[pyclass(module = "flexmbd._core", frozen, subclass)]
#[derive(Clone)]
pub struct Spline {
    /// Knot times (strictly increasing).
    #[pyo3(get)]
    pub times: Vec<f64>,
    /// Values at the knots.
    #[pyo3(get)]
    pub values: Vec<f64>,
    /// End conditions: "natural", "clamped" or "periodic".
    #[pyo3(get)]
    pub end: String,
    /// First derivatives at the first and the last knot of a clamped spline (None otherwise).
    #[pyo3(get)]
    pub slopes: Option<(f64, f64)>,
    inner: Arc<CubicSpline>,
}

/// A rest-to-rest step from `start_value` at `start_time` to `end_value` at `end_time` (at
/// rest before and after), of `shape` "cubic" (3 s^2 - 2 s^3 of the normalized time s: zero
/// end velocities), "quintic" (10 s^3 - 15 s^4 + 6 s^5: zero end velocities and
/// accelerations) or "cycloidal" (s - sin(2 pi s) / (2 pi): zero end velocities and
/// accelerations), with exact derivatives.
#[pyclass(module = "flexmbd._core", frozen, subclass)]
#[derive(Clone)]
pub struct Step {
    /// When the step starts.
    #[pyo3(get)]
    pub start_time: f64,
    /// When it ends.
    #[pyo3(get)]
    pub end_time: f64,
    /// The value before and at `start_time`.
    #[pyo3(get)]
    pub start_value: f64,
    /// The value at and after `end_time`.
    #[pyo3(get)]
    pub end_value: f64,
    /// "cubic", "quintic" or "cycloidal".
    #[pyo3(get)]
    pub shape: String,
    inner: MotionProfile,
}

/// A rest-to-rest motion with a trapezoidal velocity: constant acceleration over the fraction
/// `blend` of the duration, constant velocity, constant deceleration over the last `blend`
/// (a linear segment with parabolic blends; 0 < blend <= 0.5, 0.5: a triangular velocity).
/// Peak velocity (end_value - start_value) / (T (1 - blend)), acceleration that over
/// (blend T), T = end_time - start_time.
#[pyclass(module = "flexmbd._core", frozen, subclass)]
#[derive(Clone)]
pub struct Trapezoidal {
    /// When the motion starts.
    #[pyo3(get)]
    pub start_time: f64,
    /// When it ends.
    #[pyo3(get)]
    pub end_time: f64,
    /// The value before and at `start_time`.
    #[pyo3(get)]
    pub start_value: f64,
    /// The value at and after `end_time`.
    #[pyo3(get)]
    pub end_value: f64,
    /// Acceleration time over the duration.
    #[pyo3(get)]
    pub blend: f64,
    inner: MotionProfile,
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
    #[pyo3(signature = (times, values, end = "natural", slopes = None))]
    fn new(times: Vec<f64>, values: Vec<f64>, end: &str, slopes: Option<(f64, f64)>) -> PyResult<Self> {
        let condition = match (end, slopes) {
            ("natural", None) => SplineEnd::Natural,
            ("periodic", None) => SplineEnd::Periodic,
            ("clamped", None) => SplineEnd::Clamped(0.0, 0.0),
            ("clamped", Some((first, last))) => SplineEnd::Clamped(first, last),
            ("natural" | "periodic", Some(_)) => {
                return Err(invalid(
                    "Spline",
                    format!("slopes are the end conditions of a clamped spline, not of a {end} one"),
                ))
            }
            (other, _) => {
                return Err(invalid(
                    "Spline",
                    format!("end must be 'natural', 'clamped' or 'periodic', got {other:?}"),
                ))
            }
        };
        let inner =
            CubicSpline::new(times.clone(), values.clone(), condition).map_err(|m| invalid("Spline", m))?;
        let slopes = match condition {
            SplineEnd::Clamped(first, last) => Some((first, last)),
            _ => None,
        };
        Ok(Spline { times, values, end: end.to_string(), slopes, inner: Arc::new(inner) })
    }
    fn __repr__(&self) -> String {
        format!(
            "Spline({} points from t = {} to {}, end={:?})",
            self.times.len(),
            self.times[0],
            self.times[self.times.len() - 1],
            self.end
        )
    }
}

#[pymethods]
impl Step {
    #[new]
    #[pyo3(signature = (start_time, end_time, start_value, end_value, shape = "quintic"))]
    fn new(start_time: f64, end_time: f64, start_value: f64, end_value: f64, shape: &str) -> PyResult<Self> {
        let law = match shape {
            "cubic" => ProfileShape::Cubic,
            "quintic" => ProfileShape::Quintic,
            "cycloidal" => ProfileShape::Cycloidal,
            other => {
                return Err(invalid(
                    "Step",
                    format!("shape must be 'cubic', 'quintic' or 'cycloidal', got {other:?}"),
                ))
            }
        };
        let inner = MotionProfile::new(start_time, end_time, start_value, end_value, law)
            .map_err(|m| invalid("Step", m))?;
        Ok(Step { start_time, end_time, start_value, end_value, shape: shape.to_string(), inner })
    }
    fn __repr__(&self) -> String {
        format!(
            "Step({}, {}, {}, {}, shape={:?})",
            self.start_time, self.end_time, self.start_value, self.end_value, self.shape
        )
    }
    fn __getnewargs__(&self) -> (f64, f64, f64, f64, String) {
        (self.start_time, self.end_time, self.start_value, self.end_value, self.shape.clone())
    }
}

#[pymethods]
impl Trapezoidal {
    #[new]
    #[pyo3(signature = (start_time, end_time, start_value, end_value, blend = 0.25))]
    fn new(start_time: f64, end_time: f64, start_value: f64, end_value: f64, blend: f64) -> PyResult<Self> {
        let inner = MotionProfile::new(
            start_time,
            end_time,
            start_value,
            end_value,
            ProfileShape::Trapezoidal { blend },
        )
        .map_err(|m| invalid("Trapezoidal", m))?;
        Ok(Trapezoidal { start_time, end_time, start_value, end_value, blend, inner })
    }
    fn __repr__(&self) -> String {
        format!(
            "Trapezoidal({}, {}, {}, {}, blend={})",
            self.start_time, self.end_time, self.start_value, self.end_value, self.blend
        )
    }
    fn __getnewargs__(&self) -> (f64, f64, f64, f64, f64) {
        (self.start_time, self.end_time, self.start_value, self.end_value, self.blend)
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
impl Step {
    fn core(&self) -> TimeFunction {
        TimeFunction::Profile(self.inner)
    }
}
impl Trapezoidal {
    fn core(&self) -> TimeFunction {
        TimeFunction::Profile(self.inner)
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
common_methods!(Step);
common_methods!(Trapezoidal);
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
    if let Ok(c) = obj.cast::<Step>() {
        return Ok(c.get().core());
    }
    if let Ok(c) = obj.cast::<Trapezoidal>() {
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
            "expected a number, a callable or a time function (Constant, Polynomial, Harmonic, Spline, Step, Trapezoidal, UserFunction), got {}",
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
    #[allow(clippy::type_complexity)]
    fn __getnewargs__(&self) -> (Vec<f64>, Vec<f64>, String, Option<(f64, f64)>) {
        (self.times.clone(), self.values.clone(), self.end.clone(), self.slopes)
    }
}

#[pymethods]
impl UserFunction {
    fn __getnewargs__(&self, py: Python<'_>) -> (Py<PyAny>, bool) {
        (self.function.clone_ref(py), self.derivatives)
    }
}
