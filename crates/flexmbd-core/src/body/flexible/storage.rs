//! Storage of the matrices of a deformable body: the elastic pattern, block-sparse and dense
//! matrices (with their AVX2 products), and the scalar mass matrix of bodies of solids.

use super::*;

/// Compressed sparse column pattern over the elastic coordinates of a body: the union of the
/// patterns of its I_kl, K_ff and D_ff.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ElasticPattern {
    /// Dimension n_f.
    pub n: usize,
    /// Column pointers (n + 1).
    pub col_ptr: Vec<usize>,
    /// Row indices, sorted in each column.
    pub row_idx: Vec<usize>,
}

impl ElasticPattern {
    /// Number of entries.
    pub fn nnz(&self) -> usize {
        self.row_idx.len()
    }

    pub(crate) fn union(n: usize, matrices: &[&Csc], blocks: &[&[usize]]) -> Self {
        let mut extra: Vec<Vec<usize>> = vec![Vec::new(); n];
        for b in blocks {
            for &c in b.iter() {
                extra[c].extend_from_slice(b);
            }
        }
        let mut col_ptr = vec![0usize; n + 1];
        let mut row_idx = Vec::new();
        let mut rows: Vec<usize> = Vec::new();
        for c in 0..n {
            rows.clear();
            rows.extend_from_slice(&extra[c]);
            for m in matrices {
                rows.extend_from_slice(&m.row_idx[m.col_ptr[c]..m.col_ptr[c + 1]]);
            }
            rows.sort_unstable();
            rows.dedup();
            row_idx.extend_from_slice(&rows);
            col_ptr[c + 1] = row_idx.len();
        }
        ElasticPattern { n, col_ptr, row_idx }
    }

    pub(crate) fn position(&self, r: usize, c: usize) -> usize {
        let rows = &self.row_idx[self.col_ptr[c]..self.col_ptr[c + 1]];
        self.col_ptr[c] + rows.binary_search(&r).expect("entry in the elastic pattern")
    }
}

/// Sparse matrices up to this size with at least half their entries are multiplied in dense
/// form (see [`ElasticMatrix::dense`]).
pub(crate) const DENSE_PRODUCTS_SIZE: usize = 128;

/// A constant sparse n_f x n_f matrix of a body, with the position of each of its entries in
/// the body's [`ElasticPattern`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ElasticMatrix {
    /// The matrix.
    pub matrix: Csc,
    /// Pattern position of each stored entry (same order as `matrix.values`).
    pub positions: Vec<usize>,
    /// Every entry is stored (a modal body's matrices): `matrix.values` is the dense matrix in
    /// column-major order, and the products skip the row indices.
    pub full: bool,
    /// A dense copy (column-major) of a small matrix that is not `full` but has at least half
    /// its entries (a Craig-Bampton stiffness, whose boundary-internal block is zero): dense
    /// products in vectors of four beat the indexed ones there.
    pub dense: Option<Vec<f64>>,
    /// The same matrix in 3 x 3 blocks, when its entries come in such blocks (the stiffness of
    /// solid elements, node by node): the products read one block index per nine entries.
    pub blocks: Option<Blocks3>,
}

/// A square sparse matrix of size 3 n_b stored in block rows of dense 3 x 3 blocks (row-major
/// within a block); entries missing in a stored block are zeros. A matrix that is exactly
/// symmetric (a stiffness matrix) keeps only its upper blocks: its products then read half the
/// memory, which matters where they share the cache with the factor of A (the 10k bar's
/// stiffness is 6.5 MB in full blocks, its envelope factor 11 MB).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Blocks3 {
    /// Start of each block row in `columns` and `values` (n_b + 1).
    pub(crate) row_ptr: Vec<usize>,
    /// Block column of each block.
    pub(crate) columns: Vec<u32>,
    /// The blocks.
    pub(crate) values: Vec<[f64; 9]>,
    /// Only the blocks with block column >= block row are stored (of a symmetric matrix).
    pub(crate) symmetric: bool,
}

impl Blocks3 {
    /// The blocked form of `m`, or None when it is not square of size 3 n_b or when the
    /// blocks would store more than 1.5 times its entries (a pattern not made of node blocks).
    pub fn from_csc(m: &Csc) -> Option<Self> {
        let n = m.nrows;
        if n == 0 || m.ncols != n || n % 3 != 0 || u32::try_from(n / 3).is_err() {
            return None;
        }
        let nb = n / 3;
        // Block columns of each block row, then the blocks in block-row order.
        let mut rows: Vec<Vec<u32>> = vec![Vec::new(); nb];
        let mut count = 0;
        for c in 0..n {
            for &r in &m.row_idx[m.col_ptr[c]..m.col_ptr[c + 1]] {
                let (br, bc) = (r / 3, (c / 3) as u32);
                if rows[br].last() != Some(&bc) && !rows[br].contains(&bc) {
                    rows[br].push(bc);
                    count += 1;
                }
            }
            if 9 * count > 3 * m.values.len() / 2 + 9 {
                return None;
            }
        }
        let mut row_ptr = Vec::with_capacity(nb + 1);
        row_ptr.push(0);
        let mut columns = Vec::new();
        for r in &mut rows {
            r.sort_unstable();
            columns.extend_from_slice(r);
            row_ptr.push(columns.len());
        }
        let mut values = vec![[0.0; 9]; columns.len()];
        for c in 0..n {
            for k in m.col_ptr[c]..m.col_ptr[c + 1] {
                let r = m.row_idx[k];
                let br = r / 3;
                let slot = &columns[row_ptr[br]..row_ptr[br + 1]];
                let b = row_ptr[br] + slot.binary_search(&((c / 3) as u32)).expect("block of the pattern");
                values[b][3 * (r % 3) + c % 3] += m.values[k];
            }
        }
        let full = Blocks3 { row_ptr, columns, values, symmetric: false };
        Some(if full.is_symmetric() { full.upper() } else { full })
    }

    /// The block (br, bc), if stored.
    pub(crate) fn block(&self, br: usize, bc: usize) -> Option<&[f64; 9]> {
        let range = self.row_ptr[br]..self.row_ptr[br + 1];
        let at = self.columns[range.clone()].binary_search(&(bc as u32)).ok()?;
        Some(&self.values[range.start + at])
    }

    /// Whether the (full) blocks form an exactly symmetric matrix.
    pub(crate) fn is_symmetric(&self) -> bool {
        (0..self.row_ptr.len() - 1).all(|br| {
            (self.row_ptr[br]..self.row_ptr[br + 1]).all(|k| {
                let (bc, b) = (self.columns[k] as usize, &self.values[k]);
                let zero = [0.0; 9];
                let t = self.block(bc, br).unwrap_or(&zero);
                (0..3).all(|i| (0..3).all(|j| b[3 * i + j] == t[3 * j + i]))
            })
        })
    }

    /// The upper blocks (block column >= block row) of a symmetric matrix.
    pub(crate) fn upper(self) -> Self {
        let mut row_ptr = Vec::with_capacity(self.row_ptr.len());
        let (mut columns, mut values) = (Vec::new(), Vec::new());
        row_ptr.push(0);
        for br in 0..self.row_ptr.len() - 1 {
            for k in self.row_ptr[br]..self.row_ptr[br + 1] {
                if self.columns[k] as usize >= br {
                    columns.push(self.columns[k]);
                    values.push(self.values[k]);
                }
            }
            row_ptr.push(columns.len());
        }
        Blocks3 { row_ptr, columns, values, symmetric: true }
    }

    /// `out += w * A x`, block row by block row (in the AVX2 kernel where the CPU has it).
    pub(crate) fn mul_vec_add(&self, w: f64, x: &[f64], out: &mut [f64]) {
        #[cfg(target_arch = "x86_64")]
        if crate::linalg::simd::has_avx2_fma() {
            // SAFETY: the CPU supports AVX2 and FMA (checked above).
            let (r, c, v) = (&self.row_ptr, &self.columns, &self.values);
            return unsafe {
                if self.symmetric {
                    crate::linalg::simd::avx2::blocks3_mul_add::<true>(r, c, v, w, x, out)
                } else {
                    crate::linalg::simd::avx2::blocks3_mul_add::<false>(r, c, v, w, x, out)
                }
            };
        }
        self.mul_vec_add_portable(w, x, out);
    }

    /// `out += w * A x` in portable code.
    pub(crate) fn mul_vec_add_portable(&self, w: f64, x: &[f64], out: &mut [f64]) {
        let (x, out) = (&x[..3 * (self.row_ptr.len() - 1)], &mut out[..3 * (self.row_ptr.len() - 1)]);
        for (br, o) in out.chunks_exact_mut(3).enumerate() {
            let mut sum = [0.0; 3];
            let range = self.row_ptr[br]..self.row_ptr[br + 1];
            for (&bc, b) in self.columns[range.clone()].iter().zip(&self.values[range]) {
                let xc = &x[3 * bc as usize..3 * bc as usize + 3];
                sum[0] += b[0] * xc[0] + b[1] * xc[1] + b[2] * xc[2];
                sum[1] += b[3] * xc[0] + b[4] * xc[1] + b[5] * xc[2];
                sum[2] += b[6] * xc[0] + b[7] * xc[1] + b[8] * xc[2];
            }
            for (o, s) in o.iter_mut().zip(sum) {
                *o += w * s;
            }
        }
        if self.symmetric {
            // The lower blocks: B^T of each upper off-diagonal block, into the rows of its
            // column.
            for br in 0..self.row_ptr.len() - 1 {
                let xr = [x[3 * br], x[3 * br + 1], x[3 * br + 2]];
                for k in self.row_ptr[br]..self.row_ptr[br + 1] {
                    let (bc, b) = (self.columns[k] as usize, &self.values[k]);
                    if bc != br {
                        for j in 0..3 {
                            out[3 * bc + j] += w * (b[j] * xr[0] + b[3 + j] * xr[1] + b[6 + j] * xr[2]);
                        }
                    }
                }
            }
        }
    }
}

impl ElasticMatrix {
    pub(crate) fn new(matrix: Csc, pattern: &ElasticPattern) -> Self {
        let mut positions = Vec::with_capacity(matrix.values.len());
        for c in 0..matrix.ncols {
            for k in matrix.col_ptr[c]..matrix.col_ptr[c + 1] {
                positions.push(pattern.position(matrix.row_idx[k], c));
            }
        }
        let n = matrix.nrows;
        let full = n > 0 && matrix.values.len() == n * matrix.ncols;
        let dense = (!full && n <= DENSE_PRODUCTS_SIZE && 2 * matrix.values.len() >= n * n).then(|| {
            let mut dense = vec![0.0; n * n];
            for c in 0..matrix.ncols {
                for k in matrix.col_ptr[c]..matrix.col_ptr[c + 1] {
                    dense[c * n + matrix.row_idx[k]] += matrix.values[k];
                }
            }
            dense
        });
        let blocks = if full || dense.is_some() { None } else { Blocks3::from_csc(&matrix) };
        ElasticMatrix { matrix, positions, full, dense, blocks }
    }

    /// `out += w * A x`.
    pub fn mul_vec_add(&self, w: f64, x: &[f64], out: &mut [f64]) {
        let m = &self.matrix;
        let dense = if self.full { Some(&m.values[..]) } else { self.dense.as_deref() };
        if let Some(dense) = dense {
            crate::linalg::simd::dense_mul_add(m.nrows, dense, w, &x[..m.ncols], out);
            return;
        }
        if let Some(blocks) = &self.blocks {
            blocks.mul_vec_add(w, x, out);
            return;
        }
        for c in 0..m.ncols {
            let xc = w * x[c];
            if xc != 0.0 {
                for k in m.col_ptr[c]..m.col_ptr[c + 1] {
                    out[m.row_idx[k]] += m.values[k] * xc;
                }
            }
        }
    }

    /// `values[positions] += w * A` (values on the body's elastic pattern).
    pub fn add_to_pattern(&self, w: f64, values: &mut [f64]) {
        if w != 0.0 {
            for (&p, &v) in self.positions.iter().zip(&self.matrix.values) {
                values[p] += w * v;
            }
        }
    }
}

/// The structure of the invariants of a body of solid elements: S = [N_1 I, N_2 I, ...] makes
/// I_kl = P^T (M_s (x) e_k e_l^T) P with the scalar nodal mass matrix M_s and the selection P
/// of the kept nodal coordinates (`DESIGN.md`). The products the inertia force needs,
/// I_kl q_f, sum_kl w~_kl I_kl qf_dot and M_ff qf_dd, then all come from one pass over M_s
/// with the node-wise vectors (q_f, qf_dot, qf_dd) instead of ten passes over the I_kl.
#[derive(Clone, Debug, PartialEq)]
pub struct ScalarMass {
    /// M_s (nodes x nodes).
    pub matrix: Csc,
    /// Nodal coordinate (3 node + component) of each elastic coordinate.
    pub coordinates: Vec<usize>,
}

impl ScalarMass {
    /// Node count.
    pub(crate) fn nodes(&self) -> usize {
        self.matrix.nrows
    }

    /// Node-wise products Y = M_s [V_0, V_1, V_2] of three elastic vectors (each spread over
    /// the nodes as nodes x 3, zero at the coordinates the reference conditions hold), into
    /// `out` (nodes x 9: per node Y_0, Y_1, Y_2; only the first `W` of the nine entries per
    /// node are formed, 6: Y_0 and Y_1, the others are left as they were). `gathered`
    /// (nodes x 9) receives the spread vectors at the coordinates' entries only: the others
    /// must be zero (as in [`FlexibleScratch::for_body`]), and stay so. Returns the sums over
    /// the nodes g[v][k][l] = V_v[node][k] Y_0[node][l].
    pub(crate) fn products<const W: usize>(
        &self,
        vectors: [&[f64]; 3],
        gathered: &mut [f64],
        out: &mut [f64],
    ) -> [[[f64; 3]; 3]; 3] {
        let [v0, v1, v2] = vectors;
        for (((&c, &x0), &x1), &x2) in self.coordinates.iter().zip(v0).zip(v1).zip(v2) {
            let at = &mut gathered[(c / 3) * 9 + c % 3..][..7];
            (at[0], at[3], at[6]) = (x0, x1, x2);
        }
        // M_s is symmetric (a mass matrix; `check_scalar_mass` compares these products with
        // the I_kl): node i's row of the product is gathered from column i, summed in
        // registers and stored once, instead of scattered entry by entry.
        #[cfg(target_arch = "x86_64")]
        if (W == 6 || W == 9) && crate::linalg::simd::has_avx2_fma() {
            let m = &self.matrix;
            // SAFETY: the CPU supports AVX2 and FMA (checked above).
            let sums = unsafe {
                crate::linalg::simd::avx2::node_products::<W>(
                    &m.col_ptr, &m.row_idx, &m.values, gathered, out,
                )
            };
            return std::array::from_fn(|v| {
                std::array::from_fn(|k| std::array::from_fn(|l| sums[3 * v + k][l]))
            });
        }
        self.multiply_portable::<W>(gathered, out)
    }

    /// The products of [`Self::products`] from the gathered vectors, in portable code.
    pub(crate) fn multiply_portable<const W: usize>(
        &self,
        gathered: &[f64],
        out: &mut [f64],
    ) -> [[[f64; 3]; 3]; 3] {
        let m = &self.matrix;
        let mut g = [[[0.0f64; 3]; 3]; 3];
        for (col, node_out) in out.chunks_exact_mut(9).enumerate().take(m.ncols) {
            let mut sum = [0.0f64; W];
            for e in m.col_ptr[col]..m.col_ptr[col + 1] {
                let (row, value) = (m.row_idx[e], m.values[e]);
                let source = &gathered[9 * row..9 * row + W];
                for (s, x) in sum.iter_mut().zip(source) {
                    *s += value * x;
                }
            }
            node_out[..W].copy_from_slice(&sum);
            let own = &gathered[9 * col..9 * col + 9];
            for (gv, vv) in g.iter_mut().zip(own.chunks_exact(3)) {
                for (row, &x) in gv.iter_mut().zip(vv) {
                    for (o, &y) in row.iter_mut().zip(&sum[..3]) {
                        *o += x * y;
                    }
                }
            }
        }
        g
    }
}
