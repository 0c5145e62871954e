//! Hyper-dual numbers x = a + b e1 + c e2 + d e1 e2 (e1^2 = e2^2 = 0), with 3-vectors and 3x3
//! matrices of them: a function evaluated at a + v e1 + v e2 + w e1 e2 carries its value, its
//! derivative along v (e1 and e2 parts) and v^T f'' v + f' w (e1 e2 part) exactly, without
//! truncation error. The joint-coordinate kinematics (`formulation::recursive`) use them for the
//! body velocities q_dot = B p_dot, the velocity-quadratic accelerations gamma_B = B_dot
//! p_dot (plus the prescribed accelerations) and the columns of B, from one definition of
//! q(p).

use std::ops::{Add, Div, Mul, Neg, Sub};

/// A hyper-dual number.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct HyperDual {
    /// Value.
    pub v: f64,
    /// First derivative part along e1.
    pub e1: f64,
    /// First derivative part along e2.
    pub e2: f64,
    /// Second derivative part (e1 e2).
    pub e12: f64,
}

impl HyperDual {
    /// Zero.
    pub const ZERO: HyperDual = HyperDual { v: 0.0, e1: 0.0, e2: 0.0, e12: 0.0 };
    /// One.
    pub const ONE: HyperDual = HyperDual { v: 1.0, e1: 0.0, e2: 0.0, e12: 0.0 };

    /// A constant.
    pub const fn constant(v: f64) -> Self {
        HyperDual { v, e1: 0.0, e2: 0.0, e12: 0.0 }
    }

    /// The point x + rate (e1 + e2) + second e1 e2: a curve x(t) at t = 0 with x' = rate and
    /// x'' = second.
    pub const fn curve(x: f64, rate: f64, second: f64) -> Self {
        HyperDual { v: x, e1: rate, e2: rate, e12: second }
    }

    /// f(self) for a scalar function with value f, first derivative d1 and second d2 at self.v.
    fn chain(self, f: f64, d1: f64, d2: f64) -> Self {
        HyperDual { v: f, e1: d1 * self.e1, e2: d1 * self.e2, e12: d1 * self.e12 + d2 * self.e1 * self.e2 }
    }

    /// Square root (of a positive value).
    pub fn sqrt(self) -> Self {
        let s = self.v.sqrt();
        self.chain(s, 0.5 / s, -0.25 / (s * self.v))
    }

    /// Sine.
    pub fn sin(self) -> Self {
        let (s, c) = self.v.sin_cos();
        self.chain(s, c, -s)
    }

    /// Cosine.
    pub fn cos(self) -> Self {
        let (s, c) = self.v.sin_cos();
        self.chain(c, -s, -c)
    }

    /// 1 / self.
    pub fn recip(self) -> Self {
        let r = 1.0 / self.v;
        self.chain(r, -r * r, 2.0 * r * r * r)
    }
}

impl Add for HyperDual {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        HyperDual { v: self.v + o.v, e1: self.e1 + o.e1, e2: self.e2 + o.e2, e12: self.e12 + o.e12 }
    }
}

impl Sub for HyperDual {
    type Output = Self;
    fn sub(self, o: Self) -> Self {
        HyperDual { v: self.v - o.v, e1: self.e1 - o.e1, e2: self.e2 - o.e2, e12: self.e12 - o.e12 }
    }
}

impl Neg for HyperDual {
    type Output = Self;
    fn neg(self) -> Self {
        HyperDual { v: -self.v, e1: -self.e1, e2: -self.e2, e12: -self.e12 }
    }
}

impl Mul for HyperDual {
    type Output = Self;
    fn mul(self, o: Self) -> Self {
        HyperDual {
            v: self.v * o.v,
            e1: self.v * o.e1 + self.e1 * o.v,
            e2: self.v * o.e2 + self.e2 * o.v,
            e12: self.v * o.e12 + self.e12 * o.v + self.e1 * o.e2 + self.e2 * o.e1,
        }
    }
}

impl Mul<f64> for HyperDual {
    type Output = Self;
    fn mul(self, s: f64) -> Self {
        HyperDual { v: self.v * s, e1: self.e1 * s, e2: self.e2 * s, e12: self.e12 * s }
    }
}

impl Div for HyperDual {
    type Output = Self;
    #[allow(clippy::suspicious_arithmetic_impl)]
    fn div(self, o: Self) -> Self {
        self * o.recip()
    }
}

/// A 3-vector of hyper-dual numbers.
pub type HVec = [HyperDual; 3];
/// A 3x3 matrix of hyper-dual numbers, by rows.
pub type HMat = [[HyperDual; 3]; 3];

/// A constant vector.
pub fn hvec(v: [f64; 3]) -> HVec {
    v.map(HyperDual::constant)
}

/// A constant matrix.
pub fn hmat(m: [[f64; 3]; 3]) -> HMat {
    m.map(|r| r.map(HyperDual::constant))
}

/// The identity matrix.
pub const HIDENTITY: HMat = [
    [HyperDual::ONE, HyperDual::ZERO, HyperDual::ZERO],
    [HyperDual::ZERO, HyperDual::ONE, HyperDual::ZERO],
    [HyperDual::ZERO, HyperDual::ZERO, HyperDual::ONE],
];

/// a + b.
pub fn add(a: &HVec, b: &HVec) -> HVec {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// a - b.
pub fn sub(a: &HVec, b: &HVec) -> HVec {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// s a.
pub fn scale(a: &HVec, s: HyperDual) -> HVec {
    [a[0] * s, a[1] * s, a[2] * s]
}

/// a . b.
pub fn dot(a: &HVec, b: &HVec) -> HyperDual {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// a x b.
pub fn cross(a: &HVec, b: &HVec) -> HVec {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

/// a / |a|.
pub fn normalize(a: &HVec) -> HVec {
    scale(a, dot(a, a).sqrt().recip())
}

/// Column k of m.
pub fn column(m: &HMat, k: usize) -> HVec {
    [m[0][k], m[1][k], m[2][k]]
}

/// The matrix with columns a, b, c.
pub fn from_columns(a: &HVec, b: &HVec, c: &HVec) -> HMat {
    [[a[0], b[0], c[0]], [a[1], b[1], c[1]], [a[2], b[2], c[2]]]
}

/// m v.
pub fn mul_vec(m: &HMat, v: &HVec) -> HVec {
    std::array::from_fn(|i| m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2])
}

/// a b.
pub fn mul_mat(a: &HMat, b: &HMat) -> HMat {
    std::array::from_fn(|i| {
        std::array::from_fn(|j| a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j])
    })
}

/// a b^T.
pub fn mul_transpose(a: &HMat, b: &HMat) -> HMat {
    std::array::from_fn(|i| {
        std::array::from_fn(|j| a[i][0] * b[j][0] + a[i][1] * b[j][1] + a[i][2] * b[j][2])
    })
}

/// Value parts.
pub fn values(m: &HMat) -> [[f64; 3]; 3] {
    m.map(|r| r.map(|x| x.v))
}

/// Euler parameters of a rotation matrix (Shepperd's method; the branch is chosen on the
/// values, so the derivative parts are those of the smooth branch), normalized, with the sign
/// that makes e . reference non-negative.
pub fn euler_parameters(a: &HMat, reference: &[f64; 4]) -> [HyperDual; 4] {
    let m = a;
    let tr = m[0][0] + m[1][1] + m[2][2];
    let candidates = [tr.v, m[0][0].v, m[1][1].v, m[2][2].v];
    let k = (0..4).fold(0, |best, i| if candidates[i] > candidates[best] { i } else { best });
    let one = HyperDual::ONE;
    let mut p = [HyperDual::ZERO; 4];
    if k == 0 {
        let s = (one + tr).sqrt() * 2.0;
        let r = s.recip();
        p = [s * 0.25, (m[2][1] - m[1][2]) * r, (m[0][2] - m[2][0]) * r, (m[1][0] - m[0][1]) * r];
    } else {
        let i = k - 1;
        let j = (i + 1) % 3;
        let l = (i + 2) % 3;
        let s = (one + m[i][i] - m[j][j] - m[l][l]).sqrt() * 2.0;
        let r = s.recip();
        p[0] = (m[l][j] - m[j][l]) * r;
        p[i + 1] = s * 0.25;
        p[j + 1] = (m[j][i] + m[i][j]) * r;
        p[l + 1] = (m[l][i] + m[i][l]) * r;
    }
    let norm = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2] + p[3] * p[3]).sqrt().recip();
    let sign = if (0..4).map(|c| p[c].v * reference[c]).sum::<f64>() < 0.0 { -1.0 } else { 1.0 };
    p.map(|x| x * norm * sign)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{assert_all_close, assert_close};

    /// f(x) = sqrt(1 + x^2) sin(x) / (2 + cos x) along x(t) = x0 + v t + w t^2 / 2: value,
    /// first and second time derivatives against central differences.
    #[test]
    fn derivatives_of_a_composition_match_finite_differences() {
        let f =
            |x: HyperDual| (HyperDual::ONE + x * x).sqrt() * x.sin() / (HyperDual::constant(2.0) + x.cos());
        let (x0, v, w) = (0.7, -1.3, 0.4);
        let y = f(HyperDual::curve(x0, v, w));
        let g = |t: f64| f(HyperDual::constant(x0 + v * t + 0.5 * w * t * t)).v;
        let h = 1e-4;
        let d1 = (g(h) - g(-h)) / (2.0 * h);
        let d2 = (g(h) - 2.0 * g(0.0) + g(-h)) / (h * h);
        assert_close(y.v, g(0.0), 0.0, 1e-15, "value");
        assert_close(y.e1, d1, 0.0, 1e-8, "first derivative");
        assert_eq!(y.e1, y.e2, "first derivative along e1 and e2");
        assert_close(y.e12, d2, 0.0, 1e-6, "second derivative");
    }

    #[test]
    fn euler_parameters_of_every_branch_reproduce_the_rotation() {
        use crate::math::euler::rotation_matrix;
        for p in
            [[0.9, 0.1, -0.3, 0.2], [0.1, 0.95, 0.2, -0.1], [0.05, -0.2, 0.9, 0.3], [0.1, 0.2, -0.3, -0.9]]
        {
            let n = p.iter().map(|x: &f64| x * x).sum::<f64>().sqrt();
            let p = p.map(|x| x / n);
            let e = euler_parameters(&hmat(rotation_matrix(&p).0), &p);
            assert_all_close(&e.map(|c| c.v), &p, 0.0, 1e-14, format_args!("{p:?}"));
        }
    }
}
