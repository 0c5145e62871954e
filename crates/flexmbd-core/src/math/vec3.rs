//! Small fixed-size vectors and matrices for kinematics kernels.
//!
//! `Vec3` is a column 3-vector, `Mat3` a row-major 3 x 3 matrix. Large and sparse linear
//! algebra lives in `faer`; these types exist so that the per-body kernels read like the
//! equations they implement and do not allocate.

use std::ops::{Add, AddAssign, Index, IndexMut, Mul, Neg, Sub, SubAssign};

/// Column vector of three components.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Vec3(pub [f64; 3]);

/// Row-major 3 x 3 matrix: `self.0[row][column]`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Mat3(pub [[f64; 3]; 3]);

impl Vec3 {
    /// The zero vector.
    pub const ZERO: Vec3 = Vec3([0.0; 3]);

    /// Vector from components.
    pub const fn new(x: f64, y: f64, z: f64) -> Self {
        Vec3([x, y, z])
    }

    /// Unit vector along axis `k` (0, 1 or 2).
    pub fn unit(k: usize) -> Self {
        let mut v = Vec3::ZERO;
        v.0[k] = 1.0;
        v
    }

    /// Vector from the first three entries of a slice.
    pub fn from_slice(s: &[f64]) -> Self {
        Vec3([s[0], s[1], s[2]])
    }

    /// Scalar product.
    pub fn dot(&self, other: &Vec3) -> f64 {
        self.0[0] * other.0[0] + self.0[1] * other.0[1] + self.0[2] * other.0[2]
    }

    /// Cross product `self x other`.
    pub fn cross(&self, other: &Vec3) -> Vec3 {
        let [a0, a1, a2] = self.0;
        let [b0, b1, b2] = other.0;
        Vec3([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])
    }

    /// Euclidean norm.
    pub fn norm(&self) -> f64 {
        self.dot(self).sqrt()
    }

    /// Skew-symmetric matrix `v~` with `v~ w = v x w`.
    pub fn skew(&self) -> Mat3 {
        let [x, y, z] = self.0;
        Mat3([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    }

    /// Outer product `self other^T`.
    pub fn outer(&self, other: &Vec3) -> Mat3 {
        let mut m = Mat3::default();
        for i in 0..3 {
            for j in 0..3 {
                m.0[i][j] = self.0[i] * other.0[j];
            }
        }
        m
    }

    /// True if every component is finite.
    pub fn is_finite(&self) -> bool {
        self.0.iter().all(|x| x.is_finite())
    }
}

impl Index<usize> for Vec3 {
    type Output = f64;
    fn index(&self, i: usize) -> &f64 {
        &self.0[i]
    }
}

impl IndexMut<usize> for Vec3 {
    fn index_mut(&mut self, i: usize) -> &mut f64 {
        &mut self.0[i]
    }
}

impl Add for Vec3 {
    type Output = Vec3;
    fn add(self, o: Vec3) -> Vec3 {
        Vec3([self.0[0] + o.0[0], self.0[1] + o.0[1], self.0[2] + o.0[2]])
    }
}

impl AddAssign for Vec3 {
    fn add_assign(&mut self, o: Vec3) {
        *self = *self + o;
    }
}

impl Sub for Vec3 {
    type Output = Vec3;
    fn sub(self, o: Vec3) -> Vec3 {
        Vec3([self.0[0] - o.0[0], self.0[1] - o.0[1], self.0[2] - o.0[2]])
    }
}

impl SubAssign for Vec3 {
    fn sub_assign(&mut self, o: Vec3) {
        *self = *self - o;
    }
}

impl Neg for Vec3 {
    type Output = Vec3;
    fn neg(self) -> Vec3 {
        Vec3([-self.0[0], -self.0[1], -self.0[2]])
    }
}

impl Mul<f64> for Vec3 {
    type Output = Vec3;
    fn mul(self, s: f64) -> Vec3 {
        Vec3([self.0[0] * s, self.0[1] * s, self.0[2] * s])
    }
}

impl Mul<Vec3> for f64 {
    type Output = Vec3;
    fn mul(self, v: Vec3) -> Vec3 {
        v * self
    }
}

impl Mat3 {
    /// The identity matrix.
    pub const IDENTITY: Mat3 = Mat3([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);
    /// Zero matrix.
    pub const ZERO: Mat3 = Mat3([[0.0; 3]; 3]);

    /// Diagonal matrix.
    pub fn diagonal(d: Vec3) -> Mat3 {
        Mat3([[d[0], 0.0, 0.0], [0.0, d[1], 0.0], [0.0, 0.0, d[2]]])
    }

    /// Matrix whose columns are the given vectors.
    pub fn from_columns(c0: Vec3, c1: Vec3, c2: Vec3) -> Mat3 {
        Mat3([[c0[0], c1[0], c2[0]], [c0[1], c1[1], c2[1]], [c0[2], c1[2], c2[2]]])
    }

    /// Column `k` as a vector.
    pub fn column(&self, k: usize) -> Vec3 {
        Vec3([self.0[0][k], self.0[1][k], self.0[2][k]])
    }

    /// Transpose.
    pub fn transpose(&self) -> Mat3 {
        let mut t = Mat3::default();
        for i in 0..3 {
            for j in 0..3 {
                t.0[i][j] = self.0[j][i];
            }
        }
        t
    }

    /// Matrix-vector product.
    pub fn mul_vec(&self, v: &Vec3) -> Vec3 {
        let m = &self.0;
        Vec3([
            m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
            m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
            m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2],
        ])
    }

    /// Transposed matrix-vector product `self^T v`.
    pub fn tr_mul_vec(&self, v: &Vec3) -> Vec3 {
        let m = &self.0;
        Vec3([
            m[0][0] * v[0] + m[1][0] * v[1] + m[2][0] * v[2],
            m[0][1] * v[0] + m[1][1] * v[1] + m[2][1] * v[2],
            m[0][2] * v[0] + m[1][2] * v[1] + m[2][2] * v[2],
        ])
    }

    /// Matrix product.
    pub fn mul_mat(&self, o: &Mat3) -> Mat3 {
        let mut r = Mat3::default();
        for i in 0..3 {
            for j in 0..3 {
                r.0[i][j] = (0..3).map(|k| self.0[i][k] * o.0[k][j]).sum();
            }
        }
        r
    }

    /// Sum of the diagonal.
    pub fn trace(&self) -> f64 {
        self.0[0][0] + self.0[1][1] + self.0[2][2]
    }

    /// Determinant.
    pub fn determinant(&self) -> f64 {
        let m = &self.0;
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    }

    /// Largest absolute entry of `self - other`.
    pub fn max_abs_diff(&self, other: &Mat3) -> f64 {
        let mut d: f64 = 0.0;
        for i in 0..3 {
            for j in 0..3 {
                d = d.max((self.0[i][j] - other.0[i][j]).abs());
            }
        }
        d
    }

    /// True if every entry is finite.
    pub fn is_finite(&self) -> bool {
        self.0.iter().flatten().all(|x| x.is_finite())
    }

    /// Scaled copy.
    pub fn scale(&self, s: f64) -> Mat3 {
        let mut r = *self;
        r.0.iter_mut().flatten().for_each(|x| *x *= s);
        r
    }
}

impl Add for Mat3 {
    type Output = Mat3;
    fn add(self, o: Mat3) -> Mat3 {
        let mut r = self;
        for i in 0..3 {
            for j in 0..3 {
                r.0[i][j] += o.0[i][j];
            }
        }
        r
    }
}

impl Sub for Mat3 {
    type Output = Mat3;
    fn sub(self, o: Mat3) -> Mat3 {
        self + o.scale(-1.0)
    }
}

/// Smallest eigenvalue of a symmetric 3 x 3 matrix (closed form, trigonometric method).
pub fn symmetric_min_eigenvalue(m: &Mat3) -> f64 {
    let a = &m.0;
    let p1 = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
    let q = m.trace() / 3.0;
    if p1 == 0.0 {
        return a[0][0].min(a[1][1]).min(a[2][2]);
    }
    let p2 = (a[0][0] - q).powi(2) + (a[1][1] - q).powi(2) + (a[2][2] - q).powi(2) + 2.0 * p1;
    let p = (p2 / 6.0).sqrt();
    let b = (*m - Mat3::IDENTITY.scale(q)).scale(1.0 / p);
    let r = (b.determinant() / 2.0).clamp(-1.0, 1.0);
    let phi = r.acos() / 3.0;
    // Eigenvalues are q + 2p cos(phi + 2 pi k / 3); k = 1 gives the smallest.
    q + 2.0 * p * (phi + 2.0 * std::f64::consts::PI / 3.0).cos()
}
