//! Compressed sparse column (CSC) matrices: the storage of the stiffness, mass and invariant
//! matrices of deformable bodies and of the Newton matrices.

/// Compressed sparse column matrix.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Csc {
    /// Rows.
    pub nrows: usize,
    /// Columns.
    pub ncols: usize,
    /// Column pointers (ncols + 1).
    pub col_ptr: Vec<usize>,
    /// Row indices, sorted in each column.
    pub row_idx: Vec<usize>,
    /// Values.
    pub values: Vec<f64>,
}

impl Csc {
    /// A dense `rows x cols` matrix with entries f(r, c) in compressed columns (every entry
    /// stored).
    pub fn from_dense(rows: usize, cols: usize, f: impl Fn(usize, usize) -> f64) -> Self {
        let mut col_ptr = vec![0];
        let mut row_idx = Vec::with_capacity(rows * cols);
        let mut values = Vec::with_capacity(rows * cols);
        for c in 0..cols {
            for r in 0..rows {
                row_idx.push(r);
                values.push(f(r, c));
            }
            col_ptr.push(row_idx.len());
        }
        Csc { nrows: rows, ncols: cols, col_ptr, row_idx, values }
    }

    /// `y += A x`.
    pub fn mul_vec_add(&self, x: &[f64], y: &mut [f64]) {
        for c in 0..self.ncols {
            for k in self.col_ptr[c]..self.col_ptr[c + 1] {
                y[self.row_idx[k]] += self.values[k] * x[c];
            }
        }
    }

    /// Entry (r, c), zero if not stored.
    pub fn get(&self, r: usize, c: usize) -> f64 {
        let rows = &self.row_idx[self.col_ptr[c]..self.col_ptr[c + 1]];
        rows.binary_search(&r).map(|k| self.values[self.col_ptr[c] + k]).unwrap_or(0.0)
    }
}
