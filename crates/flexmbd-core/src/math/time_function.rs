//! Scalar functions of time f(t) with their first and second derivatives, used by drivers
//! (prescribed joint coordinates) and by applied forces.

use std::fmt;
use std::sync::Arc;

use super::profile::MotionProfile;

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
    /// Cubic spline through points with end conditions (see [`CubicSpline`]).
    Spline(Arc<CubicSpline>),
    /// A rest-to-rest motion profile (cubic, quintic, cycloidal or trapezoidal velocity).
    Profile(MotionProfile),
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
            TimeFunction::Spline(s) => write!(f, "Spline({} points, {:?})", s.times.len(), s.end),
            TimeFunction::Profile(p) => write!(f, "{p:?}"),
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
            TimeFunction::Profile(p) => Ok(p.evaluate(time)),
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

/// The end conditions of a [`CubicSpline`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SplineEnd {
    /// Zero second derivative at both ends.
    Natural,
    /// Given first derivatives at the first and the last knot.
    Clamped(f64, f64),
    /// Value, slope and curvature the same at both ends (the first and last values must be
    /// equal); the spline repeats with the period of its knots.
    Periodic,
}

/// Cubic spline through `(times, values)` with end conditions. Outside its knots a periodic
/// spline repeats; the others go on as the straight line of their end value and slope, so
/// that value and velocity stay continuous (a clamped spline with zero end slopes rests).
#[derive(Clone, Debug)]
pub struct CubicSpline {
    times: Vec<f64>,
    values: Vec<f64>,
    end: SplineEnd,
    /// Second derivatives at the knots.
    second: Vec<f64>,
}

/// Solves the tridiagonal system with sub-, main and super-diagonals `lower`, `diag`,
/// `upper` (`lower[0]` and `upper[n - 1]` unused) by the Thomas algorithm (the spline
/// systems are diagonally dominant).
fn tridiagonal(lower: &[f64], diag: &[f64], upper: &[f64], rhs: &[f64]) -> Vec<f64> {
    let n = diag.len();
    let (mut d, mut r) = (diag.to_vec(), rhs.to_vec());
    for i in 1..n {
        let w = lower[i] / d[i - 1];
        d[i] -= w * upper[i - 1];
        r[i] -= w * r[i - 1];
    }
    let mut x = vec![0.0; n];
    x[n - 1] = r[n - 1] / d[n - 1];
    for i in (0..n - 1).rev() {
        x[i] = (r[i] - upper[i] * x[i + 1]) / d[i];
    }
    x
}

impl CubicSpline {
    /// Builds the spline; times must be finite and strictly increasing, at least two points
    /// (three for a periodic spline, whose first and last values must be equal).
    pub fn new(times: Vec<f64>, values: Vec<f64>, end: SplineEnd) -> std::result::Result<Self, String> {
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
        let h: Vec<f64> = (0..n - 1).map(|i| times[i + 1] - times[i]).collect();
        let d: Vec<f64> = (0..n - 1).map(|i| (values[i + 1] - values[i]) / h[i]).collect();
        let second = match end {
            SplineEnd::Natural => {
                let mut second = vec![0.0; n];
                if n > 2 {
                    let m = n - 2;
                    let lower: Vec<f64> = (0..m).map(|i| h[i]).collect();
                    let diag: Vec<f64> = (0..m).map(|i| 2.0 * (h[i] + h[i + 1])).collect();
                    let upper: Vec<f64> = (0..m).map(|i| h[i + 1]).collect();
                    let rhs: Vec<f64> = (0..m).map(|i| 6.0 * (d[i + 1] - d[i])).collect();
                    second[1..n - 1].copy_from_slice(&tridiagonal(&lower, &diag, &upper, &rhs));
                }
                second
            }
            SplineEnd::Clamped(first, last) => {
                if !(first.is_finite() && last.is_finite()) {
                    return Err(format!("spline end slopes must be finite, got ({first}, {last})"));
                }
                let (mut lower, mut diag, mut upper, mut rhs) =
                    (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
                diag[0] = 2.0 * h[0];
                upper[0] = h[0];
                rhs[0] = 6.0 * (d[0] - first);
                for i in 1..n - 1 {
                    lower[i] = h[i - 1];
                    diag[i] = 2.0 * (h[i - 1] + h[i]);
                    upper[i] = h[i];
                    rhs[i] = 6.0 * (d[i] - d[i - 1]);
                }
                lower[n - 1] = h[n - 2];
                diag[n - 1] = 2.0 * h[n - 2];
                rhs[n - 1] = 6.0 * (last - d[n - 2]);
                tridiagonal(&lower, &diag, &upper, &rhs)
            }
            SplineEnd::Periodic => {
                if n < 3 {
                    return Err("a periodic spline needs at least three points".to_string());
                }
                let scale = values.iter().fold(0.0f64, |a, v| a.max(v.abs()));
                if (values[n - 1] - values[0]).abs() > 1e-12 * scale {
                    return Err(format!(
                        "a periodic spline's first and last values must be equal, got {} and {}",
                        values[0],
                        values[n - 1]
                    ));
                }
                // Unknowns M_0 .. M_{m-1}, m = n - 1 (M_{n-1} = M_0): a cyclic tridiagonal
                // system, solved by Sherman-Morrison around the Thomas algorithm.
                let m = n - 1;
                let prev = |i: usize| if i == 0 { m - 1 } else { i - 1 };
                let (mut lower, mut diag, mut upper, mut rhs) =
                    (vec![0.0; m], vec![0.0; m], vec![0.0; m], vec![0.0; m]);
                for i in 0..m {
                    lower[i] = h[prev(i)];
                    diag[i] = 2.0 * (h[prev(i)] + h[i]);
                    upper[i] = h[i];
                    rhs[i] = 6.0 * (d[i] - d[prev(i)]);
                }
                // Corners: row 0 couples M_{m-1} (lower[0]), row m-1 couples M_0 (upper[m-1]).
                let (alpha, beta) = (upper[m - 1], lower[0]);
                let gamma = -diag[0];
                let mut modified = diag.clone();
                modified[0] -= gamma;
                modified[m - 1] -= alpha * beta / gamma;
                let x = tridiagonal(&lower, &modified, &upper, &rhs);
                let mut u = vec![0.0; m];
                u[0] = gamma;
                u[m - 1] = alpha;
                let z = tridiagonal(&lower, &modified, &upper, &u);
                let factor = (x[0] + beta * x[m - 1] / gamma) / (1.0 + z[0] + beta * z[m - 1] / gamma);
                let mut second: Vec<f64> = (0..m).map(|i| x[i] - factor * z[i]).collect();
                second.push(second[0]);
                second
            }
        };
        Ok(CubicSpline { times, values, end, second })
    }

    /// Value and derivatives at `t`.
    pub fn evaluate(&self, t: f64) -> [f64; 3] {
        let n = self.times.len();
        let (first, last) = (self.times[0], self.times[n - 1]);
        let t = if self.end == SplineEnd::Periodic && !(first..last).contains(&t) {
            let period = last - first;
            first + (t - first).rem_euclid(period)
        } else {
            t
        };
        if t < first || t > last {
            // Straight on with the end value and slope.
            let (k, at) = if t < first { (0, first) } else { (n - 2, last) };
            let [value, slope, _] = self.segment(k, at);
            return [value + slope * (t - at), slope, 0.0];
        }
        let k = (self.times.partition_point(|&x| x <= t) - 1).min(n - 2);
        self.segment(k, t)
    }

    /// Value and derivatives of the cubic of segment `k` at `t`.
    fn segment(&self, k: usize, t: f64) -> [f64; 3] {
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
        let s = CubicSpline::new(vec![0.0, 1.0, 2.5, 3.0], vec![0.0, 1.0, -1.0, 0.5], SplineEnd::Natural)
            .unwrap();
        fd_check(&TimeFunction::Spline(Arc::new(s)), 1.7);
    }

    #[test]
    fn spline_interpolates_and_reproduces_cubics_inside() {
        let times: Vec<f64> = (0..6).map(|k| k as f64 * 0.5).collect();
        let values: Vec<f64> = times.iter().map(|t| 2.0 * t - 1.0).collect();
        let s = CubicSpline::new(times.clone(), values.clone(), SplineEnd::Natural).unwrap();
        for (t, v) in times.iter().zip(values.iter()) {
            assert_close(s.evaluate(*t)[0], *v, 0.0, 1e-14, format_args!("spline at {t}"));
        }
        // A straight line is reproduced exactly by a natural spline.
        let e = s.evaluate(1.3);
        assert_close(e[0], 1.6, 0.0, 1e-13, "line value");
        assert_close(e[1], 2.0, 0.0, 1e-12, "line slope");
        assert_close(e[2], 0.0, 0.0, 1e-12, "line curvature");
        assert!(CubicSpline::new(vec![0.0, 0.0], vec![1.0, 2.0], SplineEnd::Natural).is_err());
    }

    #[test]
    fn clamped_spline_reproduces_a_cubic_and_continues_with_its_end_slopes() {
        let cubic =
            |t: f64| [1.0 - 2.0 * t + 0.5 * t * t + 0.3 * t * t * t, -2.0 + t + 0.9 * t * t, 1.0 + 1.8 * t];
        let times = vec![-1.0, -0.2, 0.5, 1.1, 2.0];
        let values: Vec<f64> = times.iter().map(|&t| cubic(t)[0]).collect();
        let s = CubicSpline::new(times, values, SplineEnd::Clamped(cubic(-1.0)[1], cubic(2.0)[1])).unwrap();
        for t in [-0.9, -0.2, 0.13, 0.77, 1.5, 1.99] {
            let (e, x) = (s.evaluate(t), cubic(t));
            for k in 0..3 {
                assert_close(e[k], x[k], 0.0, 1e-12, format_args!("derivative {k} at {t}"));
            }
        }
        let end = cubic(2.0);
        let after = s.evaluate(3.0);
        assert_close(after[0], end[0] + end[1], 0.0, 1e-12, "value after the end");
        assert_close(after[1], end[1], 0.0, 1e-12, "slope after the end");
        assert_eq!(after[2], 0.0);
        // Zero end slopes: rest before and after.
        let rest = CubicSpline::new(vec![0.0, 0.5], vec![0.0, 1.0], SplineEnd::Clamped(0.0, 0.0)).unwrap();
        assert_eq!(rest.evaluate(0.7), [1.0, 0.0, 0.0]);
        assert_close(rest.evaluate(0.5 - 1e-9)[1], 0.0, 0.0, 1e-7, "velocity at the end");
        fd_check(&TimeFunction::Spline(Arc::new(s)), 0.6);
    }

    #[test]
    fn natural_spline_goes_on_with_its_end_slope() {
        // Two points: the straight line, which the spline continues (no velocity jump).
        let s = CubicSpline::new(vec![0.0, 0.5], vec![0.0, 1.0], SplineEnd::Natural).unwrap();
        assert_close(s.evaluate(0.4999)[1], 2.0, 0.0, 1e-12, "slope before the end");
        assert_close(s.evaluate(0.5001)[1], 2.0, 0.0, 1e-12, "slope after the end");
        assert_close(s.evaluate(-1.0)[0], -2.0, 0.0, 1e-12, "value before the start");
    }

    #[test]
    fn periodic_spline_repeats_smoothly_and_follows_a_sine() {
        let n = 41;
        let times: Vec<f64> = (0..n).map(|k| 0.3 + k as f64 / (n - 1) as f64).collect();
        let values: Vec<f64> = times.iter().map(|&t| (2.0 * std::f64::consts::PI * t).sin()).collect();
        let s = CubicSpline::new(times, values, SplineEnd::Periodic).unwrap();
        let (first, last) = (s.evaluate(0.3), s.evaluate(1.3 - 1e-12));
        for k in 0..3 {
            assert_close(first[k], last[k], 0.0, 1e-9 * 40.0, format_args!("derivative {k} at the wrap"));
        }
        let w = 2.0 * std::f64::consts::PI;
        for t in [-2.05, 0.31, 0.77, 1.3, 4.12] {
            let e = s.evaluate(t);
            assert_close(e[0], (w * t).sin(), 0.0, 2e-6, format_args!("value at {t}"));
            assert_close(e[1], w * (w * t).cos(), 0.0, 2e-4, format_args!("slope at {t}"));
            assert_close(e[2], -w * w * (w * t).sin(), 0.0, 0.1, format_args!("curvature at {t}"));
        }
        fd_check(&TimeFunction::Spline(Arc::new(s)), 1.3);
        let open = CubicSpline::new(vec![0.0, 1.0, 2.0], vec![0.0, 1.0, 0.5], SplineEnd::Periodic);
        assert!(open.unwrap_err().contains("first and last values"));
        assert!(CubicSpline::new(vec![0.0, 1.0], vec![0.0, 0.0], SplineEnd::Periodic).is_err());
    }
}
