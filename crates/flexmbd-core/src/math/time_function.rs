//! Scalar functions of time f(t) with their first and second derivatives, used by drivers
//! (prescribed joint coordinates) and by applied forces.

use std::fmt;
use std::sync::Arc;

/// A user function of time (implemented by the Python binding for Python callables).
pub trait TimeCallback: Send + Sync {
    /// Returns `f(t)`, or `[f, f', f'']` when `derivatives()` is true.
    fn evaluate(&self, time: f64) -> std::result::Result<[f64; 3], String>;
    /// True if `evaluate` returns exact derivatives; otherwise they are taken by central
    /// finite differences with step `1e-4 (1 + |t|)`.
    fn derivatives(&self) -> bool;
}

/// A scalar function of time.
#[derive(Clone)]
pub enum TimeFunction {
    /// f(t) = c.
    Constant(f64),
    /// f(t) = c0 + c1 t + c2 t^2 + ... (coefficients in increasing order).
    Polynomial(Vec<f64>),
    /// f(t) = offset + amplitude sin(frequency t + phase), frequency in rad/s.
    Harmonic {
        /// Amplitude.
        amplitude: f64,
        /// Angular frequency (rad/s).
        frequency: f64,
        /// Phase (rad).
        phase: f64,
        /// Constant offset.
        offset: f64,
    },
    /// Natural cubic spline through points; constant (zero derivatives) outside the range.
    Spline(Arc<CubicSpline>),
    /// A user callback.
    Callback(Arc<dyn TimeCallback>),
}

impl fmt::Debug for TimeFunction {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TimeFunction::Constant(c) => write!(f, "Constant({c})"),
            TimeFunction::Polynomial(c) => write!(f, "Polynomial({c:?})"),
            TimeFunction::Harmonic { amplitude, frequency, phase, offset } => write!(
                f,
                "Harmonic(amplitude={amplitude}, frequency={frequency}, phase={phase}, offset={offset})"
            ),
            TimeFunction::Spline(s) => write!(f, "Spline({} points)", s.times.len()),
            TimeFunction::Callback(_) => write!(f, "Callback"),
        }
    }
}

impl TimeFunction {
    /// Value, first and second derivative at `time`.
    pub fn evaluate(&self, time: f64) -> std::result::Result<[f64; 3], String> {
        match self {
            TimeFunction::Constant(c) => Ok([*c, 0.0, 0.0]),
            TimeFunction::Polynomial(c) => {
                // Horner's scheme for the value and both derivatives together.
                let (mut f, mut d1, mut d2) = (0.0, 0.0, 0.0);
                for &ck in c.iter().rev() {
                    d2 = d2 * time + 2.0 * d1;
                    d1 = d1 * time + f;
                    f = f * time + ck;
                }
                Ok([f, d1, d2])
            }
            TimeFunction::Harmonic { amplitude, frequency, phase, offset } => {
                let arg = frequency * time + phase;
                Ok([
                    offset + amplitude * arg.sin(),
                    amplitude * frequency * arg.cos(),
                    -amplitude * frequency * frequency * arg.sin(),
                ])
            }
            TimeFunction::Spline(s) => Ok(s.evaluate(time)),
            TimeFunction::Callback(cb) => {
                let v = cb.evaluate(time)?;
                if cb.derivatives() {
                    return Ok(v);
                }
                let h = 1e-4 * (1.0 + time.abs());
                let fp = cb.evaluate(time + h)?[0];
                let fm = cb.evaluate(time - h)?[0];
                Ok([v[0], (fp - fm) / (2.0 * h), (fp - 2.0 * v[0] + fm) / (h * h)])
            }
        }
    }

    /// Checks the parameters: finite numbers, a valid spline.
    pub fn validate(&self) -> std::result::Result<(), String> {
        let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
        match self {
            TimeFunction::Constant(c) if !c.is_finite() => Err(format!("constant {c} is not finite")),
            TimeFunction::Polynomial(c) if !finite(c) => Err(format!("coefficients {c:?} not finite")),
            TimeFunction::Harmonic { amplitude, frequency, phase, offset }
                if !finite(&[*amplitude, *frequency, *phase, *offset]) =>
            {
                Err("harmonic parameters must be finite".to_string())
            }
            _ => Ok(()),
        }
    }
}

/// Natural cubic spline (zero second derivative at both ends) through `(times, values)`.
#[derive(Clone, Debug)]
pub struct CubicSpline {
    times: Vec<f64>,
    values: Vec<f64>,
    /// Second derivatives at the knots.
    second: Vec<f64>,
}

impl CubicSpline {
    /// Builds the spline; times must be finite and strictly increasing, at least two points.
    pub fn new(times: Vec<f64>, values: Vec<f64>) -> std::result::Result<Self, String> {
        let n = times.len();
        if n < 2 || values.len() != n {
            return Err(format!(
                "a spline needs at least two points and as many values as times (got {} times, {} values)",
                n,
                values.len()
            ));
        }
        if !times.iter().chain(values.iter()).all(|x| x.is_finite()) {
            return Err("spline points must be finite".to_string());
        }
        if let Some(k) = (1..n).find(|&k| times[k] <= times[k - 1]) {
            return Err(format!("spline times must increase strictly (at index {k})"));
        }
        // Tridiagonal system for the second derivatives (Thomas algorithm).
        let mut second = vec![0.0; n];
        if n > 2 {
            let m = n - 2;
            let mut diag = vec![0.0; m];
            let mut rhs = vec![0.0; m];
            let mut upper = vec![0.0; m];
            for i in 0..m {
                let h0 = times[i + 1] - times[i];
                let h1 = times[i + 2] - times[i + 1];
                diag[i] = 2.0 * (h0 + h1);
                upper[i] = h1;
                rhs[i] = 6.0 * ((values[i + 2] - values[i + 1]) / h1 - (values[i + 1] - values[i]) / h0);
            }
            for i in 1..m {
                let lower = times[i + 1] - times[i];
                let w = lower / diag[i - 1];
                diag[i] -= w * upper[i - 1];
                rhs[i] -= w * rhs[i - 1];
            }
            second[m] = rhs[m - 1] / diag[m - 1];
            for i in (0..m - 1).rev() {
                second[i + 1] = (rhs[i] - upper[i] * second[i + 2]) / diag[i];
            }
        }
        Ok(CubicSpline { times, values, second })
    }

    /// Value and derivatives at `t`.
    pub fn evaluate(&self, t: f64) -> [f64; 3] {
        let n = self.times.len();
        if t <= self.times[0] {
            return [self.values[0], 0.0, 0.0];
        }
        if t >= self.times[n - 1] {
            return [self.values[n - 1], 0.0, 0.0];
        }
        let k = self.times.partition_point(|&x| x <= t) - 1;
        let (t0, t1) = (self.times[k], self.times[k + 1]);
        let h = t1 - t0;
        let (y0, y1) = (self.values[k], self.values[k + 1]);
        let (m0, m1) = (self.second[k], self.second[k + 1]);
        let a = (t1 - t) / h;
        let b = (t - t0) / h;
        let f = a * y0 + b * y1 + ((a * a * a - a) * m0 + (b * b * b - b) * m1) * h * h / 6.0;
        let d1 = (y1 - y0) / h + (-(3.0 * a * a - 1.0) * m0 + (3.0 * b * b - 1.0) * m1) * h / 6.0;
        let d2 = a * m0 + b * m1;
        [f, d1, d2]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::assert_close;

    fn fd_check(f: &TimeFunction, t: f64) {
        let h = 1e-5;
        let v = f.evaluate(t).unwrap();
        let p = f.evaluate(t + h).unwrap();
        let m = f.evaluate(t - h).unwrap();
        assert_close((p[0] - m[0]) / (2.0 * h), v[1], 1e-6, 1e-6, format_args!("velocity at {t}"));
        assert_close((p[1] - m[1]) / (2.0 * h), v[2], 1e-5, 1e-5, format_args!("acceleration at {t}"));
    }

    #[test]
    fn derivatives_are_consistent() {
        fd_check(&TimeFunction::Polynomial(vec![1.0, -2.0, 0.5, 3.0]), 0.7);
        fd_check(&TimeFunction::Harmonic { amplitude: 2.0, frequency: 3.0, phase: 0.2, offset: 1.0 }, 0.4);
        let s = CubicSpline::new(vec![0.0, 1.0, 2.5, 3.0], vec![0.0, 1.0, -1.0, 0.5]).unwrap();
        fd_check(&TimeFunction::Spline(Arc::new(s)), 1.7);
    }

    #[test]
    fn spline_interpolates_and_reproduces_cubics_inside() {
        let times: Vec<f64> = (0..6).map(|k| k as f64 * 0.5).collect();
        let values: Vec<f64> = times.iter().map(|t| 2.0 * t - 1.0).collect();
        let s = CubicSpline::new(times.clone(), values.clone()).unwrap();
        for (t, v) in times.iter().zip(values.iter()) {
            assert_close(s.evaluate(*t)[0], *v, 0.0, 1e-14, format_args!("spline at {t}"));
        }
        // A straight line is reproduced exactly by a natural spline.
        let e = s.evaluate(1.3);
        assert_close(e[0], 1.6, 0.0, 1e-13, "line value");
        assert_close(e[1], 2.0, 0.0, 1e-12, "line slope");
        assert_close(e[2], 0.0, 0.0, 1e-12, "line curvature");
        assert!(CubicSpline::new(vec![0.0, 0.0], vec![1.0, 2.0]).is_err());
    }
}
