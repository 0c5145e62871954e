//! Small dynamically sized dense matrices for element-level (local) Jacobians and Hessians.

use crate::math::euler::Mat44;
use crate::math::vec3::Vec3;

/// Row-major dense matrix.
#[derive(Clone, Debug, Default)]
pub struct DenseMatrix {
    /// Row count.
    pub rows: usize,
    /// Column count.
    pub cols: usize,
    /// Entries, row-major (`rows * cols`).
    pub data: Vec<f64>,
}

impl DenseMatrix {
    /// Zero matrix.
    pub fn zeros(rows: usize, cols: usize) -> Self {
        DenseMatrix { rows, cols, data: vec![0.0; rows * cols] }
    }

    /// Sets every entry to zero.
    pub fn fill_zero(&mut self) {
        self.data.iter_mut().for_each(|x| *x = 0.0);
    }

    /// Entry (i, j).
    #[inline]
    pub fn get(&self, i: usize, j: usize) -> f64 {
        self.data[i * self.cols + j]
    }

    /// Adds `v` to entry (i, j).
    #[inline]
    pub fn add(&mut self, i: usize, j: usize, v: f64) {
        self.data[i * self.cols + j] += v;
    }

    /// Adds `w * m` to the 4 x 4 block at (r0, c0).
    pub fn add_block44(&mut self, r0: usize, c0: usize, w: f64, m: &Mat44) {
        for i in 0..4 {
            for j in 0..4 {
                self.add(r0 + i, c0 + j, w * m[i][j]);
            }
        }
    }

    /// Adds `w * a^T b` at (r0, c0) for 3-row Jacobians `a` (3 x na) and `b` (3 x nb).
    pub fn add_jt_j(&mut self, r0: usize, c0: usize, w: f64, a: &Jacobian3, b: &Jacobian3) {
        for i in 0..a.n {
            for j in 0..b.n {
                let s = a.get(0, i) * b.get(0, j) + a.get(1, i) * b.get(1, j) + a.get(2, i) * b.get(2, j);
                self.add(r0 + i, c0 + j, w * s);
            }
        }
    }

    /// Adds `w * a^T m b` at (r0, c0) for a 3 x 3 matrix `m`.
    pub fn add_jt_m_j(
        &mut self,
        r0: usize,
        c0: usize,
        w: f64,
        a: &Jacobian3,
        m: &crate::math::Mat3,
        b: &Jacobian3,
    ) {
        for i in 0..a.n {
            let ai = Vec3([a.get(0, i), a.get(1, i), a.get(2, i)]);
            let mt_ai = m.tr_mul_vec(&ai);
            for j in 0..b.n {
                let s = mt_ai[0] * b.get(0, j) + mt_ai[1] * b.get(1, j) + mt_ai[2] * b.get(2, j);
                self.add(r0 + i, c0 + j, w * s);
            }
        }
    }

    /// Adds `w * u v^T` at (r0, c0) for vectors `u`, `v` given as slices.
    pub fn add_outer(&mut self, r0: usize, c0: usize, w: f64, u: &[f64], v: &[f64]) {
        for (i, ui) in u.iter().enumerate() {
            for (j, vj) in v.iter().enumerate() {
                self.add(r0 + i, c0 + j, w * ui * vj);
            }
        }
    }

    /// `y += w * self x` for a vector x (cols) and y (rows).
    pub fn mul_vec_add(&self, w: f64, x: &[f64], y: &mut [f64]) {
        for i in 0..self.rows {
            let row = &self.data[i * self.cols..(i + 1) * self.cols];
            y[i] += w * row.iter().zip(x).map(|(a, b)| a * b).sum::<f64>();
        }
    }

    /// Entry `col` of `self^T w` (w: rows).
    #[inline]
    pub fn column_dot(&self, col: usize, w: &[f64]) -> f64 {
        w.iter().enumerate().map(|(i, wi)| self.data[i * self.cols + col] * wi).sum()
    }

    /// Quadratic form `x^T self x`.
    pub fn quadratic_form(&self, x: &[f64]) -> f64 {
        let mut s = 0.0;
        for i in 0..self.rows {
            let row = &self.data[i * self.cols..(i + 1) * self.cols];
            s += x[i] * row.iter().zip(x).map(|(a, b)| a * b).sum::<f64>();
        }
        s
    }
}

/// A 3 x n Jacobian (row-major): the derivative of a 3-vector with respect to n coordinates.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Jacobian3 {
    /// Column count.
    pub n: usize,
    /// Entries, row-major (3 * n).
    pub data: Vec<f64>,
}

impl Jacobian3 {
    /// Zero Jacobian with `n` columns.
    pub fn zeros(n: usize) -> Self {
        Jacobian3 { n, data: vec![0.0; 3 * n] }
    }

    /// Entry (row, column).
    #[inline]
    pub fn get(&self, row: usize, col: usize) -> f64 {
        self.data[row * self.n + col]
    }

    /// Sets entry (row, column).
    #[inline]
    pub fn set(&mut self, row: usize, col: usize, v: f64) {
        self.data[row * self.n + col] = v;
    }

    /// Sets every entry to zero.
    pub fn fill_zero(&mut self) {
        self.data.iter_mut().for_each(|x| *x = 0.0);
    }

    /// `out[offset + j] += w * (v^T J)_j`.
    pub fn add_transpose_times(&self, w: f64, v: &Vec3, out: &mut [f64], offset: usize) {
        let n = self.n;
        let (r0, rest) = self.data.split_at(n);
        let (r1, r2) = rest.split_at(n);
        let (v0, v1, v2) = (w * v[0], w * v[1], w * v[2]);
        for (o, ((a, b), c)) in out[offset..offset + n].iter_mut().zip(r0.iter().zip(r1).zip(r2)) {
            *o += v0 * a + v1 * b + v2 * c;
        }
    }

    /// `J x` for a vector of n coordinates.
    pub fn times(&self, x: &[f64]) -> Vec3 {
        let n = self.n;
        let row =
            |i: usize| self.data[i * n..(i + 1) * n].iter().zip(&x[..n]).map(|(a, b)| a * b).sum::<f64>();
        Vec3([row(0), row(1), row(2)])
    }
}
