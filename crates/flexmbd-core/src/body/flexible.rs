//! Deformable body in the floating frame of reference (seed sections 2-3, eqs. 7-9 and 15-18).
//!
//! Coordinates q = [R (3), p (4 Euler parameters), q_f (n_f elastic coordinates)]. A point with
//! undeformed body-frame position u0 is at u = u0 + S q_f in the body frame and at
//! r = R + A(p) u globally (seed eqs. 8-9). Everything the equations need of the mass
//! distribution is in the invariants of motion (`DESIGN.md`, seed eqs. 16-18), computed once
//! by the preprocessor: m, s0 = int rho u0, J0_kl = int rho u0_k u0_l, I1 = int rho S,
//! Ibar_kl = int rho u0_k S_l and I_kl = int rho S_k^T S_l; M_ff = sum_k I_kk. They hold in
//! nodal and in modal coordinates alike (seed eq. 18 only changes the basis).
//!
//! The generalized inertia force f = M(q) q_dd - F(q, q_dot) of seed eq. 15, from the virtual
//! work of the inertia forces (seed eqs. 11-13), with a = A^T R_dd, the body angular velocity
//! w = 2 L p_dot and acceleration alpha = 2 L p_dd (the rotation rows mapped by 2 L^T):
//!
//! ```text
//! f_R = m R_dd + A (alpha x s + w x (w x s) + 2 w x I1 qf_dot + I1 qf_dd)
//! f_p = 2 L^T (s x a + J alpha + w x J w + 2 (tr(P) w - P^T w) + J_f qf_dd)
//! f_f = I1^T a + int rho S^T (alpha~ + w~ w~) u + 2 sum_kl w~_kl I_kl qf_dot + M_ff qf_dd
//! ```
//!
//! with s = int rho u = s0 + I1 q_f, J = int rho u~^T u~ = tr(U) I - U, U_kl = int rho u_k u_l,
//! P = int rho u u_dot^T and J_f = int rho u~ S. With N_kl = int rho u_k S_l
//! = Ibar_kl + (I_lk q_f)^T (a row of n_f) all of them are sums of invariants:
//!
//! ```text
//! U_kl = J0_kl + (Ibar_kl + Ibar_lk) q_f + q_f^T I_kl q_f,   P_kl = N_kl qf_dot,
//! (J_f)_i = sum_kl eps_ikl N_kl,   int rho S_k^T u_l = N_lk^T.
//! ```
//!
//! The mass matrix blocks are those of `DESIGN.md` (m_RR = m I, m_Rth = -A s~ 2L, m_Rf = A I1,
//! m_thth = 4 L^T J L, m_thf = 2 L^T J_f, m_ff = M_ff). The tangent (mass, velocity and
//! position Jacobians) is analytic; its (f, f) blocks are sums c_kl I_kl with 3 x 3
//! coefficient matrices, so that large nodal bodies keep the sparsity of their mass matrix.
//! Elastic forces -K_ff q_f - D_ff qf_dot and gravity (by virtual work) complete the body.

use crate::body::stiffening::{add_stiffening, StiffeningElement};
use crate::error::{FlexmbdError, Result};
use crate::linalg::csc::Csc;
use crate::math::euler::{
    self, bilinear_hessian, l_jacobian, l_matrix, lt_jacobian, rotate_jacobian, rotate_transpose_jacobian,
    Mat34, Quaternion,
};
use crate::math::{Mat3, Vec3};

/// Number of reference coordinates [R, p] of a flexible body.
pub const REFERENCE_COORDINATES: usize = 7;

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

    fn union(n: usize, matrices: &[&Csc], blocks: &[&[usize]]) -> Self {
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

    fn position(&self, r: usize, c: usize) -> usize {
        let rows = &self.row_idx[self.col_ptr[c]..self.col_ptr[c + 1]];
        self.col_ptr[c] + rows.binary_search(&r).expect("entry in the elastic pattern")
    }
}

/// Sparse matrices up to this size with at least half their entries are multiplied in dense
/// form (see [`ElasticMatrix::dense`]).
const DENSE_PRODUCTS_SIZE: usize = 128;

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
    row_ptr: Vec<usize>,
    /// Block column of each block.
    columns: Vec<u32>,
    /// The blocks.
    values: Vec<[f64; 9]>,
    /// Only the blocks with block column >= block row are stored (of a symmetric matrix).
    symmetric: bool,
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
    fn block(&self, br: usize, bc: usize) -> Option<&[f64; 9]> {
        let range = self.row_ptr[br]..self.row_ptr[br + 1];
        let at = self.columns[range.clone()].binary_search(&(bc as u32)).ok()?;
        Some(&self.values[range.start + at])
    }

    /// Whether the (full) blocks form an exactly symmetric matrix.
    fn is_symmetric(&self) -> bool {
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
    fn upper(self) -> Self {
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
    fn mul_vec_add(&self, w: f64, x: &[f64], out: &mut [f64]) {
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
    fn mul_vec_add_portable(&self, w: f64, x: &[f64], out: &mut [f64]) {
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
    fn new(matrix: Csc, pattern: &ElasticPattern) -> Self {
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
    fn nodes(&self) -> usize {
        self.matrix.nrows
    }

    /// Node-wise products Y = M_s [V_0, V_1, V_2] of three elastic vectors (each spread over
    /// the nodes as nodes x 3, zero at the coordinates the reference conditions hold), into
    /// `out` (nodes x 9: per node Y_0, Y_1, Y_2; only the first `W` of the nine entries per
    /// node are formed, 6: Y_0 and Y_1, the others are left as they were). `gathered`
    /// (nodes x 9) receives the spread vectors at the coordinates' entries only: the others
    /// must be zero (as in [`FlexibleScratch::for_body`]), and stay so. Returns the sums over
    /// the nodes g[v][k][l] = V_v[node][k] Y_0[node][l].
    fn products<const W: usize>(
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
    fn multiply_portable<const W: usize>(&self, gathered: &[f64], out: &mut [f64]) -> [[[f64; 3]; 3]; 3] {
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

/// The invariants and matrices of a deformable body as given by the preprocessor.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FlexibleBodyInput {
    /// m = int rho dV (kg).
    pub mass: f64,
    /// s0 = int rho u0 dV (kg m).
    pub first_moment: Vec3,
    /// J0_kl = int rho u0_k u0_l dV (kg m^2).
    pub second_moment: Mat3,
    /// I1 = int rho S dV, 3 x n_f row-major.
    pub i1: Vec<f64>,
    /// Ibar_kl = int rho u0_k S_l dV, index [(3 k + l) n_f + j].
    pub ibar: Vec<f64>,
    /// I_kl = int rho S_k^T S_l dV, index 3 k + l (n_f x n_f each).
    pub i_kl: Vec<Csc>,
    /// K_ff (n_f x n_f).
    pub stiffness: Csc,
    /// D_ff (n_f x n_f); may have no entries.
    pub damping: Csc,
    /// Beam elements of the geometric stiffness (elastic coupling); empty: linear elasticity.
    pub stiffening: Vec<StiffeningElement>,
    /// Node of each elastic coordinate (nodal bodies), for the fill-reducing ordering of
    /// the factorizations of large bodies (`linear_system::condensed`); None: minimum degree.
    pub dof_nodes: Option<Vec<usize>>,
    /// Node positions that `dof_nodes` refer to.
    pub node_positions: Option<Vec<Vec3>>,
    /// Whether the linear solves condense the elastic coordinates out through a constant
    /// factorized matrix (`linear_system::condensed`); None: when n_f is at least
    /// `body::CONDENSATION_THRESHOLD`.
    pub condense: Option<bool>,
    /// Bodies of solids in nodal coordinates: the scalar mass matrix behind the I_kl
    /// (checked against them when the body is built).
    pub scalar_mass: Option<ScalarMass>,
}

impl FlexibleBodyInput {
    /// The invariants of a body of point masses, by the sums of `DESIGN.md`: point i has mass
    /// `masses[i]`, undeformed position `positions[i]` and shape rows `shapes[i]` (3 x n_f
    /// row-major), u_i = u0_i + S_i q_f. With the elastic matrices given, a complete body (used
    /// by the tests as the brute-force reference of the invariant-based equations).
    pub fn from_mass_points(
        masses: &[f64],
        positions: &[Vec3],
        shapes: &[Vec<f64>],
        stiffness: Csc,
        damping: Csc,
    ) -> Self {
        let n = stiffness.ncols;
        let mut inp = FlexibleBodyInput {
            i1: vec![0.0; 3 * n],
            ibar: vec![0.0; 9 * n],
            stiffness,
            damping,
            ..Default::default()
        };
        let mut ikl = vec![vec![0.0; n * n]; 9];
        for (i, &m) in masses.iter().enumerate() {
            let (u0, sh) = (positions[i], &shapes[i]);
            inp.mass += m;
            inp.first_moment += u0 * m;
            inp.second_moment = inp.second_moment + u0.outer(&u0).scale(m);
            for k in 0..3 {
                for j in 0..n {
                    inp.i1[k * n + j] += m * sh[k * n + j];
                }
                for l in 0..3 {
                    for j in 0..n {
                        inp.ibar[(3 * k + l) * n + j] += m * u0[k] * sh[l * n + j];
                        for jj in 0..n {
                            ikl[3 * k + l][j * n + jj] += m * sh[k * n + j] * sh[l * n + jj];
                        }
                    }
                }
            }
        }
        inp.i_kl = ikl.iter().map(|a| Csc::from_dense(n, n, |r, c| a[r * n + c])).collect();
        inp
    }
}

/// The constant data of a deformable body of a compiled model.
#[derive(Clone, Debug, PartialEq)]
pub struct FlexibleBody {
    /// m (kg).
    pub mass: f64,
    /// s0 (kg m).
    pub first_moment: Vec3,
    /// J0 (kg m^2).
    pub second_moment: Mat3,
    /// n_f.
    pub elastic_count: usize,
    /// I1, 3 x n_f row-major.
    pub i1: Vec<f64>,
    /// Ibar_kl, index [(3 k + l) n_f + j].
    pub ibar: Vec<f64>,
    /// Union pattern of the (f, f) matrices.
    pub pattern: ElasticPattern,
    /// I_kl, index 3 k + l.
    pub i_kl: Vec<ElasticMatrix>,
    /// M_ff = sum_k I_kk.
    pub mass_matrix: ElasticMatrix,
    /// A_m = I_{m+1,m+2} - I_{m+2,m+1} (indices mod 3), m = 0..3: sum_kl w~_kl I_kl = -sum_m w_m A_m.
    pub antisymmetric: Vec<ElasticMatrix>,
    /// K_ff.
    pub stiffness: ElasticMatrix,
    /// D_ff.
    pub damping: ElasticMatrix,
    /// Beam elements of the geometric stiffness (empty: linear elasticity).
    pub stiffening: Vec<StiffeningElement>,
    /// Node of each elastic coordinate (for orderings), see [`FlexibleBodyInput`].
    pub dof_nodes: Option<Vec<usize>>,
    /// Node positions (for orderings).
    pub node_positions: Option<Vec<Vec3>>,
    /// Condensation in the linear solves, see [`FlexibleBodyInput`].
    pub condense: Option<bool>,
    /// The scalar mass structure of a body of solids, see [`FlexibleBodyInput`].
    pub scalar_mass: Option<ScalarMass>,
    /// Bodies of solids: per elastic coordinate j (component c of a node), the entries of I1
    /// and Ibar that can be nonzero, [I1_c[j], Ibar_0c[j], Ibar_1c[j], Ibar_2c[j]] (S_l has
    /// no entry at j for l != c); empty otherwise. See [`solid_sums`].
    solid_rows: Vec<[f64; 4]>,
    /// Bodies of solids: whether the elastic coordinates are the three components of each
    /// of their nodes in order (3 a, 3 a + 1, 3 a + 2 together): the node-wise sums then take
    /// a node at a time.
    whole_nodes: bool,
    /// When every I_kl is stored full (modal bodies): the nine stacked, (9 n_f) x n_f
    /// column-major (column c = the columns c of I_00, I_01, ..., I_22), so that
    /// `i_kl_products` is one matrix-vector product by contiguous column updates.
    stacked_i_kl: Option<Vec<f64>>,
}

fn check_square(item: &str, what: &str, m: &Csc, n: usize) -> Result<()> {
    let bad = |message: String| FlexmbdError::InvalidParameter { item: item.to_string(), message };
    if m.nrows != n || m.ncols != n {
        return Err(bad(format!("{what} must be {n} x {n}, got {} x {}", m.nrows, m.ncols)));
    }
    if m.col_ptr.len() != n + 1 {
        return Err(bad(format!(
            "{what}: {} column pointers for {n} columns (expected {})",
            m.col_ptr.len(),
            n + 1
        )));
    }
    if m.row_idx.len() != m.values.len()
        || m.col_ptr[0] != 0
        || m.col_ptr[n] != m.values.len()
        || m.col_ptr.windows(2).any(|w| w[0] > w[1])
    {
        return Err(bad(format!(
            "{what}: inconsistent sparse storage (column pointers, row indices, values)"
        )));
    }
    for c in 0..n {
        let rows = &m.row_idx[m.col_ptr[c]..m.col_ptr[c + 1]];
        if rows.windows(2).any(|w| w[0] >= w[1]) || rows.iter().any(|&r| r >= n) {
            return Err(bad(format!("{what}: row indices of column {c} are not sorted and in range")));
        }
    }
    if let Some(k) = m.values.iter().position(|v| !v.is_finite()) {
        return Err(FlexmbdError::InvalidParameter {
            item: item.to_string(),
            message: format!("{what} has a non-finite entry (stored entry {k})"),
        });
    }
    Ok(())
}

/// Largest |A - B^T| relative to the largest entry.
fn transpose_mismatch(a: &Csc, b: &Csc) -> f64 {
    let scale = a.values.iter().chain(&b.values).fold(0.0f64, |m, v| m.max(v.abs())).max(f64::MIN_POSITIVE);
    let mut worst = 0.0f64;
    for c in 0..a.ncols {
        for k in a.col_ptr[c]..a.col_ptr[c + 1] {
            worst = worst.max((a.values[k] - b.get(c, a.row_idx[k])).abs());
        }
    }
    for c in 0..b.ncols {
        for k in b.col_ptr[c]..b.col_ptr[c + 1] {
            worst = worst.max((b.values[k] - a.get(c, b.row_idx[k])).abs());
        }
    }
    worst / scale
}

impl FlexibleBody {
    /// Checks the data (positive mass, finite values, shapes, I_kl^T = I_lk, symmetric K_ff and
    /// D_ff) and lays out the elastic pattern.
    pub fn new(item: &str, input: FlexibleBodyInput) -> Result<Self> {
        let bad = |message: String| FlexmbdError::InvalidParameter { item: item.to_string(), message };
        if !(input.mass.is_finite() && input.mass > 0.0) {
            return Err(bad(format!("mass must be positive and finite, got {}", input.mass)));
        }
        if !input.first_moment.is_finite() || !input.second_moment.is_finite() {
            return Err(bad("first and second moments must be finite".to_string()));
        }
        let n = input.i1.len() / 3;
        if input.i1.len() != 3 * n || input.ibar.len() != 9 * n || input.i_kl.len() != 9 {
            return Err(bad(format!(
                "invariants of inconsistent size: I1 has {} entries, Ibar {}, {} matrices I_kl \
                 (expected 3 n_f, 9 n_f and 9)",
                input.i1.len(),
                input.ibar.len(),
                input.i_kl.len()
            )));
        }
        if input.i1.iter().chain(&input.ibar).any(|v| !v.is_finite()) {
            return Err(bad("invariants I1 and Ibar must be finite".to_string()));
        }
        for (kl, m) in input.i_kl.iter().enumerate() {
            check_square(item, &format!("invariant I_{}{}", kl / 3 + 1, kl % 3 + 1), m, n)?;
        }
        check_square(item, "stiffness matrix", &input.stiffness, n)?;
        match (&input.dof_nodes, &input.node_positions) {
            (None, None) => {}
            (Some(d), Some(p)) if d.len() == n && d.iter().all(|&k| k < p.len()) => {}
            _ => {
                return Err(bad(format!(
                    "dof_nodes must give a node (of node_positions) for each of the {n} elastic coordinates"
                )))
            }
        }
        check_square(item, "damping matrix", &input.damping, n)?;
        for k in 0..3 {
            for l in k..3 {
                let mismatch = transpose_mismatch(&input.i_kl[3 * k + l], &input.i_kl[3 * l + k]);
                if mismatch > 1e-9 {
                    return Err(bad(format!(
                        "invariants I_{}{} and I_{}{} must be transposes of each other (mismatch {mismatch:.1e})",
                        k + 1,
                        l + 1,
                        l + 1,
                        k + 1
                    )));
                }
            }
        }
        for (what, m) in [("stiffness matrix", &input.stiffness), ("damping matrix", &input.damping)] {
            let mismatch = transpose_mismatch(m, m);
            if mismatch > 1e-9 {
                return Err(bad(format!("{what} must be symmetric (mismatch {mismatch:.1e})")));
            }
        }
        for (k, el) in input.stiffening.iter().enumerate() {
            let nl = el.indices.len();
            let ok = el.map.len() == 12 * nl
                && el.indices.iter().all(|&i| i < n)
                && el.map.iter().all(|v| v.is_finite())
                && el.length.is_finite()
                && el.length > 0.0
                && el.axial_stiffness.is_finite()
                && el.axial_stiffness > 0.0;
            if !ok {
                return Err(bad(format!(
                    "stiffening element {k}: needs a 12 x n_l map over existing elastic coordinates, \
                     a positive length and a positive axial stiffness"
                )));
            }
        }
        let mut all: Vec<&Csc> = input.i_kl.iter().collect();
        all.push(&input.stiffness);
        all.push(&input.damping);
        let blocks: Vec<&[usize]> = input.stiffening.iter().map(|e| e.indices.as_slice()).collect();
        let pattern = ElasticPattern::union(n, &all, &blocks);
        let mut stiffening = input.stiffening;
        for el in stiffening.iter_mut() {
            el.positions = el
                .indices
                .iter()
                .flat_map(|&r| el.indices.iter().map(move |&c| (r, c)))
                .map(|(r, c)| pattern.position(r, c))
                .collect();
        }
        let combination = |terms: &[(f64, usize)]| -> Csc {
            let mut values = vec![0.0; pattern.nnz()];
            for &(w, kl) in terms {
                let m = &input.i_kl[kl];
                for c in 0..n {
                    for k in m.col_ptr[c]..m.col_ptr[c + 1] {
                        values[pattern.position(m.row_idx[k], c)] += w * m.values[k];
                    }
                }
            }
            Csc {
                nrows: n,
                ncols: n,
                col_ptr: pattern.col_ptr.clone(),
                row_idx: pattern.row_idx.clone(),
                values,
            }
        };
        let mass_matrix = ElasticMatrix::new(combination(&[(1.0, 0), (1.0, 4), (1.0, 8)]), &pattern);
        let antisymmetric = (0..3)
            .map(|m| {
                let (a, b) = ((m + 1) % 3, (m + 2) % 3);
                ElasticMatrix::new(combination(&[(1.0, 3 * a + b), (-1.0, 3 * b + a)]), &pattern)
            })
            .collect();
        let i_kl = input.i_kl.into_iter().map(|m| ElasticMatrix::new(m, &pattern)).collect();
        let scalar_mass = input.scalar_mass;
        let mut body = FlexibleBody {
            mass: input.mass,
            first_moment: input.first_moment,
            second_moment: input.second_moment,
            elastic_count: n,
            i1: input.i1,
            ibar: input.ibar,
            stiffness: ElasticMatrix::new(input.stiffness, &pattern),
            damping: ElasticMatrix::new(input.damping, &pattern),
            stiffening,
            dof_nodes: input.dof_nodes,
            node_positions: input.node_positions,
            condense: input.condense,
            scalar_mass: None,
            solid_rows: Vec::new(),
            whole_nodes: false,
            stacked_i_kl: None,
            i_kl,
            mass_matrix,
            antisymmetric,
            pattern,
        };
        if let Some(sm) = scalar_mass {
            body.check_scalar_mass(item, &sm)?;
            body.solid_rows = body.compressed_solid_rows(&sm);
            body.whole_nodes = sm.coordinates.len() % 3 == 0
                && sm
                    .coordinates
                    .chunks_exact(3)
                    .all(|c| c[0] % 3 == 0 && c[1] == c[0] + 1 && c[2] == c[0] + 2);
            body.scalar_mass = Some(sm);
        }
        if n > 0 && body.i_kl.iter().all(|m| m.full) {
            let mut stacked = vec![0.0; 9 * n * n];
            for (kl, m) in body.i_kl.iter().enumerate() {
                for (c, column) in m.matrix.values.chunks_exact(n).enumerate() {
                    stacked[c * 9 * n + kl * n..c * 9 * n + (kl + 1) * n].copy_from_slice(column);
                }
            }
            body.stacked_i_kl = Some(stacked);
        }
        Ok(body)
    }

    /// Checks that the scalar mass matrix gives the body's I_kl (products with a test vector).
    fn check_scalar_mass(&self, item: &str, sm: &ScalarMass) -> Result<()> {
        let n = self.elastic_count;
        let bad = |message: String| FlexmbdError::InvalidParameter { item: item.to_string(), message };
        if sm.matrix.nrows != sm.matrix.ncols
            || sm.matrix.col_ptr.len() != sm.matrix.ncols + 1
            || sm.coordinates.len() != n
            || sm.coordinates.iter().any(|&c| c >= 3 * sm.nodes())
        {
            return Err(bad("scalar mass matrix: sizes do not match the elastic coordinates".to_string()));
        }
        let v: Vec<f64> = (0..n).map(|j| ((j * 7919 % 101) as f64 - 50.0) / 50.0).collect();
        let mut expected = vec![0.0; 9 * n];
        self.i_kl_products(&v, &mut expected);
        let mut gathered = vec![0.0; 9 * sm.nodes()];
        let mut nodal = vec![0.0; 9 * sm.nodes()];
        sm.products::<9>([&v, &v, &v], &mut gathered, &mut nodal);
        let scale = expected.iter().fold(0.0f64, |m, x| m.max(x.abs())).max(f64::MIN_POSITIVE);
        for (j, &c) in sm.coordinates.iter().enumerate() {
            let (node, comp) = (c / 3, c % 3);
            for k in 0..3 {
                for l in 0..3 {
                    let from_scalar = if comp == k { nodal[9 * node + l] } else { 0.0 };
                    if (expected[(3 * k + l) * n + j] - from_scalar).abs() > 1e-9 * scale {
                        return Err(bad(format!(
                            "the scalar mass matrix does not give the invariant I_{}{} (elastic coordinate {j})",
                            k + 1,
                            l + 1
                        )));
                    }
                }
            }
        }
        Ok(())
    }

    /// The rows of I1 and Ibar of a body of solids compressed to the entries that can be
    /// nonzero (see `solid_rows`), or none when another entry is not zero.
    fn compressed_solid_rows(&self, sm: &ScalarMass) -> Vec<[f64; 4]> {
        let n = self.elastic_count;
        let mut rows = Vec::with_capacity(n);
        for (j, &c) in sm.coordinates.iter().enumerate() {
            let comp = c % 3;
            for l in (0..3).filter(|&l| l != comp) {
                if self.i1[l * n + j] != 0.0 || (0..3).any(|k| self.ibar_row(k, l)[j] != 0.0) {
                    return Vec::new();
                }
            }
            rows.push([
                self.i1[comp * n + j],
                self.ibar_row(0, comp)[j],
                self.ibar_row(1, comp)[j],
                self.ibar_row(2, comp)[j],
            ]);
        }
        rows
    }

    /// Bodies of solids with compressed rows: the component of each elastic coordinate.
    fn solid_components(&self) -> Option<impl Iterator<Item = usize> + '_> {
        match &self.scalar_mass {
            Some(sm) if !self.solid_rows.is_empty() => Some(sm.coordinates.iter().map(|c| c % 3)),
            _ => None,
        }
    }

    /// Number of coordinates 7 + n_f.
    pub fn coordinate_count(&self) -> usize {
        REFERENCE_COORDINATES + self.elastic_count
    }

    /// Inertia tensor of the undeformed body about the body origin, tr(J0) I - J0 (kg m^2).
    pub fn undeformed_inertia(&self) -> Mat3 {
        let j0 = self.second_moment;
        let mut j = j0.scale(-1.0);
        for k in 0..3 {
            j.0[k][k] += j0.trace();
        }
        j
    }

    fn ibar_row(&self, k: usize, l: usize) -> &[f64] {
        let n = self.elastic_count;
        &self.ibar[(3 * k + l) * n..(3 * k + l + 1) * n]
    }

    /// I1 v (3-vector) for an elastic vector v.
    pub fn i1_times(&self, v: &[f64]) -> Vec3 {
        let n = self.elastic_count;
        let mut out = Vec3::ZERO;
        if self.whole_nodes {
            for (rows, x) in self.solid_rows.chunks_exact(3).zip(v.chunks_exact(3)) {
                for c in 0..3 {
                    out[c] += rows[c][0] * x[c];
                }
            }
            return out;
        }
        if let Some(components) = self.solid_components() {
            for ((r, c), x) in self.solid_rows.iter().zip(components).zip(v) {
                out[c] += r[0] * x;
            }
            return out;
        }
        for k in 0..3 {
            out[k] = self.i1[k * n..(k + 1) * n].iter().zip(v).map(|(a, b)| a * b).sum();
        }
        out
    }

    /// `out += I1^T c` for a 3-vector c.
    pub fn add_i1_transpose_times(&self, c: &Vec3, out: &mut [f64]) {
        let n = self.elastic_count;
        if self.whole_nodes {
            for (rows, o) in self.solid_rows.chunks_exact(3).zip(out.chunks_exact_mut(3)) {
                for k in 0..3 {
                    o[k] += c[k] * rows[k][0];
                }
            }
            return;
        }
        if let Some(components) = self.solid_components() {
            for ((r, k), o) in self.solid_rows.iter().zip(components).zip(out.iter_mut()) {
                *o += c[k] * r[0];
            }
            return;
        }
        for k in 0..3 {
            if c[k] != 0.0 {
                for (o, a) in out.iter_mut().zip(&self.i1[k * n..(k + 1) * n]) {
                    *o += c[k] * a;
                }
            }
        }
    }

    /// out[i n_f + j] += w (A_i v)[j] for i = 0..3, with the antisymmetric A_i = I_jk - I_kj
    /// ((i, j, k) cyclic) whose products give the deformation part of the rotation coupling
    /// (`out`: 3 n_f). A body of solids forms the three from one node-wise product Y = M_s V
    /// (see [`ScalarMass`]: (A_i v) at node and component c is delta(c, j) Y[node][k] -
    /// delta(c, k) Y[node][j]), a third of the work of one product with an assembled A_i.
    pub fn add_antisymmetric_products(&self, w: f64, v: &[f64], out: &mut [f64]) {
        let n = self.elastic_count;
        let Some(sm) = &self.scalar_mass else {
            for (a, o) in self.antisymmetric.iter().zip(out.chunks_exact_mut(n)) {
                a.mul_vec_add(w, v, o);
            }
            return;
        };
        let nodes = sm.nodes();
        let mut spread = vec![0.0; 4 * nodes];
        for (&c, &x) in sm.coordinates.iter().zip(v) {
            spread[4 * (c / 3) + c % 3] = x;
        }
        let m = &sm.matrix;
        let mut y = vec![0.0; 4 * nodes];
        crate::linalg::simd::node_products4(&m.col_ptr, &m.row_idx, &m.values, &spread, &mut y);
        for (j, &c) in sm.coordinates.iter().enumerate() {
            let (node, comp) = (c / 3, c % 3);
            let yn = &y[4 * node..4 * node + 3];
            // Component c is the j of A_(c+2) and the k of A_(c+1).
            let (next, last) = ((comp + 1) % 3, (comp + 2) % 3);
            out[last * n + j] += w * yn[next];
            out[next * n + j] -= w * yn[last];
        }
    }

    /// An upper bound of the 2-norms of the antisymmetric matrices A_i of
    /// [`Self::add_antisymmetric_products`]: the largest column sum of absolute values (the
    /// 1-norm; for a symmetric or antisymmetric matrix it equals the infinity norm, and the
    /// 2-norm is at most their geometric mean). A body of solids bounds them by M_s (A_i is
    /// M_s times a matrix of norm 1 on each node, restricted to the elastic coordinates).
    pub fn antisymmetric_norm_bound(&self) -> f64 {
        let column_sums = |m: &Csc| {
            (0..m.ncols)
                .map(|c| m.values[m.col_ptr[c]..m.col_ptr[c + 1]].iter().map(|v| v.abs()).sum::<f64>())
                .fold(0.0f64, f64::max)
        };
        match &self.scalar_mass {
            Some(sm) => column_sums(&sm.matrix),
            None => self.antisymmetric.iter().map(|a| column_sums(&a.matrix)).fold(0.0, f64::max),
        }
    }

    /// `out[kl] = I_kl v` for the nine invariants (out: 9 n_f, index (3 k + l) n_f + j), from
    /// six traversals: I_lk = I_kl^T.
    pub fn i_kl_products(&self, v: &[f64], out: &mut [f64]) {
        let n = self.elastic_count;
        if let Some(stacked) = &self.stacked_i_kl {
            let out = &mut out[..9 * n];
            out.iter_mut().for_each(|x| *x = 0.0);
            crate::linalg::simd::dense_mul_add(9 * n, stacked, 1.0, &v[..n], out);
            return;
        }
        out.iter_mut().for_each(|x| *x = 0.0);
        for k in 0..3 {
            for l in k..3 {
                let m = &self.i_kl[3 * k + l].matrix;
                if k == l {
                    let y = &mut out[(4 * k) * n..(4 * k + 1) * n];
                    if self.i_kl[3 * k + l].full {
                        for (c, column) in m.values.chunks_exact(n).enumerate() {
                            let vc = v[c];
                            for (yr, a) in y.iter_mut().zip(column) {
                                *yr += a * vc;
                            }
                        }
                        continue;
                    }
                    for c in 0..m.ncols {
                        let vc = v[c];
                        for e in m.col_ptr[c]..m.col_ptr[c + 1] {
                            y[m.row_idx[e]] += m.values[e] * vc;
                        }
                    }
                    continue;
                }
                // y_kl = I_kl v (by columns) and y_lk = I_kl^T v (by rows) in one pass.
                let (first, second) = out.split_at_mut((3 * l + k) * n);
                let y_kl = &mut first[(3 * k + l) * n..(3 * k + l + 1) * n];
                let y_lk = &mut second[..n];
                if self.i_kl[3 * k + l].full {
                    for (c, column) in m.values.chunks_exact(n).enumerate() {
                        let vc = v[c];
                        let mut acc = 0.0;
                        for ((y, a), vr) in y_kl.iter_mut().zip(column).zip(v) {
                            *y += a * vc;
                            acc += a * vr;
                        }
                        y_lk[c] += acc;
                    }
                    continue;
                }
                for c in 0..m.ncols {
                    let vc = v[c];
                    let mut acc = 0.0;
                    for e in m.col_ptr[c]..m.col_ptr[c + 1] {
                        let (r, value) = (m.row_idx[e], m.values[e]);
                        y_kl[r] += value * vc;
                        acc += value * v[r];
                    }
                    y_lk[c] += acc;
                }
            }
        }
    }

    /// `values += sum_kl c_kl I_kl` on the elastic pattern.
    pub fn add_i_kl_to_pattern(&self, c: &Mat3, values: &mut [f64]) {
        for (kl, m) in self.i_kl.iter().enumerate() {
            m.add_to_pattern(c.0[kl / 3][kl % 3], values);
        }
    }

    /// `out += sum_kl c_kl I_kl v`.
    pub fn add_i_kl_times(&self, c: &Mat3, v: &[f64], out: &mut [f64]) {
        for (kl, m) in self.i_kl.iter().enumerate() {
            let w = c.0[kl / 3][kl % 3];
            if w != 0.0 {
                m.mul_vec_add(w, v, out);
            }
        }
    }
}

/// Levi-Civita symbol eps_ikl.
fn levi(i: usize, k: usize, l: usize) -> f64 {
    match (i, k, l) {
        (0, 1, 2) | (1, 2, 0) | (2, 0, 1) => 1.0,
        (0, 2, 1) | (2, 1, 0) | (1, 0, 2) => -1.0,
        _ => 0.0,
    }
}

/// Per-body buffers of the flexible-body kernels (each 9 n_f unless noted).
#[derive(Clone, Debug, Default)]
pub struct FlexibleScratch {
    /// y_kl = I_kl q_f.
    pub y: Vec<f64>,
    /// z_kl = I_kl qf_dot.
    pub z: Vec<f64>,
    /// A_m qf_dot (3 n_f), then A_m qf_dd (3 n_f).
    pub x: Vec<f64>,
    /// N_kl = Ibar_kl + y_lk (the rows int rho u_k S_l).
    pub n: Vec<f64>,
    /// Scratch rows, 3 n_f.
    pub rows: Vec<f64>,
    /// Scratch rows, 3 n_f.
    pub rows2: Vec<f64>,
    /// Bodies of solids: node-wise M_s [q_f, qf_dot, qf_dd] (nodes x 9), see [`ScalarMass`].
    pub nodal: Vec<f64>,
    /// The vectors of those products spread over the nodes (nodes x 9, zero outside the
    /// coordinates' entries: see [`ScalarMass::products`]).
    pub gathered: Vec<f64>,
    /// M_ff qf_dd of the last inertia force with [`ElasticMass::Separate`] (n_f).
    pub mass_term: Vec<f64>,
    /// The quantities of the last [`inertia_force_parts`] (see [`inertia_tangent_after_force`]).
    last: Option<Quantities>,
}

impl FlexibleScratch {
    /// Buffers for `body`.
    pub fn for_body(body: &FlexibleBody) -> Self {
        let mut scratch = Self::with_size(body.elastic_count);
        if let Some(sm) = &body.scalar_mass {
            scratch.nodal = vec![0.0; 9 * sm.nodes()];
            scratch.gathered = vec![0.0; 9 * sm.nodes()];
        }
        scratch
    }

    /// Buffers for a body with `n` elastic coordinates (and no scalar mass structure).
    pub fn with_size(n: usize) -> Self {
        FlexibleScratch {
            y: vec![0.0; 9 * n],
            z: vec![0.0; 9 * n],
            x: vec![0.0; 6 * n],
            n: vec![0.0; 9 * n],
            rows: vec![0.0; 3 * n],
            rows2: vec![0.0; 3 * n],
            nodal: Vec::new(),
            gathered: Vec::new(),
            mass_term: vec![0.0; n],
            last: None,
        }
    }
}

/// Configuration-dependent quantities of a body at one state (body frame).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Quantities {
    p: Quaternion,
    a: Mat3,
    l: Mat34,
    w: Vec3,
    alpha: Vec3,
    /// A^T R_dd.
    acc: Vec3,
    /// s = s0 + I1 q_f.
    s: Vec3,
    /// J = tr(U) I - U.
    j: Mat3,
    /// P_kl = N_kl qf_dot.
    pm: Mat3,
    /// J_f qf_dd.
    jf_qdd: Vec3,
    /// I1 qf_dot.
    i1_qfd: Vec3,
    /// I1 qf_dd.
    i1_qfdd: Vec3,
}

fn quat(q: &[f64]) -> Quaternion {
    [q[3], q[4], q[5], q[6]]
}

/// Dot product with four partial sums (vectorizable; a plain sum of f64 products is not).
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a4, b4) = (a[..n].chunks_exact(4), b[..n].chunks_exact(4));
    let (ra, rb) = (a4.remainder(), b4.remainder());
    let mut acc = [0.0f64; 4];
    for (x, y) in a4.zip(b4) {
        for k in 0..4 {
            acc[k] += x[k] * y[k];
        }
    }
    let tail: f64 = ra.iter().zip(rb).map(|(x, y)| x * y).sum();
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

/// The dot products of the nine rows of length n stacked in `rows` (row 3 k + l at
/// (3 k + l) n) with v, four rows at a time.
fn nine_dots(rows: &[f64], n: usize, v: &[f64]) -> [f64; 9] {
    let r = |i: usize| &rows[i * n..(i + 1) * n];
    let [a, b, c, d] = crate::linalg::simd::dot4([r(0), r(1), r(2), r(3)], &v[..n]);
    let [e, f, g, h] = crate::linalg::simd::dot4([r(4), r(5), r(6), r(7)], &v[..n]);
    [a, b, c, d, e, f, g, h, dot(r(8), v)]
}

fn row(v: &[f64], k: usize, l: usize, n: usize) -> &[f64] {
    &v[(3 * k + l) * n..(3 * k + l + 1) * n]
}

/// Whether [`quantities`] without the products takes the node-wise path of a body of solids
/// (see [`ScalarMass`]): it then leaves `scratch.y` and `scratch.n` unset, and the products
/// M_s [q_f, qf_dot, qf_dd] are in `scratch.nodal`.
fn nodewise(body: &FlexibleBody, scratch: &FlexibleScratch) -> bool {
    body.scalar_mass.is_some() && !body.solid_rows.is_empty() && !scratch.nodal.is_empty()
}

/// Bodies of solids: the products of I1 and Ibar with three elastic vectors in one pass over
/// the compressed rows, out[v][c] = [I1_c V_v, Ibar_0c V_v, Ibar_1c V_v, Ibar_2c V_v]
/// (so I1 V_v = out[v][.][0] and Ibar_kl . V_v = out[v][l][1 + k]).
fn solid_sums(body: &FlexibleBody, sm: &ScalarMass, vectors: [&[f64]; 3]) -> [[[f64; 4]; 3]; 3] {
    if body.whole_nodes {
        #[cfg(target_arch = "x86_64")]
        if crate::linalg::simd::has_avx2_fma() {
            // SAFETY: the CPU supports AVX2 and FMA (checked above).
            return unsafe { crate::linalg::simd::avx2::node_row_sums(&body.solid_rows, vectors) };
        }
        return node_row_sums_portable(&body.solid_rows, vectors);
    }
    let mut out = [[[0.0f64; 4]; 3]; 3];
    for (j, (row, &c)) in body.solid_rows.iter().zip(&sm.coordinates).enumerate() {
        let comp = c % 3;
        for (o, v) in out.iter_mut().zip(&vectors) {
            let x = v[j];
            for (ov, r) in o[comp].iter_mut().zip(row) {
                *ov += r * x;
            }
        }
    }
    out
}

/// [`solid_sums`] of a body whose coordinates are whole nodes, a node at a time, in portable
/// code (the AVX2 kernel `node_row_sums` forms the same sums in the same order).
fn node_row_sums_portable(rows: &[[f64; 4]], vectors: [&[f64]; 3]) -> [[[f64; 4]; 3]; 3] {
    let mut out = [[[0.0f64; 4]; 3]; 3];
    let [v0, v1, v2] = vectors.map(|v| v.chunks_exact(3));
    for (((rows, x0), x1), x2) in rows.chunks_exact(3).zip(v0).zip(v1).zip(v2) {
        for (o, x) in out.iter_mut().zip([x0, x1, x2]) {
            for ((oc, row), &xc) in o.iter_mut().zip(rows).zip(x) {
                for (ov, r) in oc.iter_mut().zip(row) {
                    *ov += r * xc;
                }
            }
        }
    }
    out
}

/// Returns the body quantities. With `with_products` (or for a body without the scalar mass
/// structure), fills y_kl = I_kl q_f and N_kl of `scratch` (and z_kl = I_kl qf_dot with the
/// products), which the Jacobians need; else, for a body of solids, takes every sum over the
/// elastic coordinates that involves y node by node (see [`nodewise`]), with the node-wise
/// M_s qf_dd only with `elastic_mass`.
fn quantities(
    body: &FlexibleBody,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    scratch: &mut FlexibleScratch,
    with_products: bool,
    elastic_mass: bool,
) -> Quantities {
    let nf = body.elastic_count;
    let r7 = REFERENCE_COORDINATES;
    let (qf, qfd, qfdd) = (&q[r7..r7 + nf], &qd[r7..r7 + nf], &qdd[r7..r7 + nf]);
    let p = quat(q);
    let a = euler::rotation_matrix(&p);
    let l = l_matrix(&p);
    let w = euler::body_angular_velocity(&p, &quat(qd));
    let alpha = euler::body_angular_velocity(&p, &quat(qdd));
    let acc = a.tr_mul_vec(&Vec3::from_slice(qdd));
    // y_kl[j] = delta(comp j, k) (M_s Q_f)[node j][l] for solids, so with V spread over the
    // nodes, V . y_kl = sum over nodes of V[node][k] Y0[node][l] =: g_V[k][l], for
    // V = q_f, qf_dot, qf_dd; and N_kl = Ibar_kl + y_lk.
    let node_sums = match &body.scalar_mass {
        Some(sm) if !with_products && nodewise(body, scratch) => {
            let g = if elastic_mass {
                sm.products::<9>([qf, qfd, qfdd], &mut scratch.gathered, &mut scratch.nodal)
            } else {
                sm.products::<6>([qf, qfd, qfdd], &mut scratch.gathered, &mut scratch.nodal)
            };
            Some((g, solid_sums(body, sm, [qf, qfd, qfdd])))
        }
        _ => {
            body.i_kl_products(qf, &mut scratch.y);
            if with_products {
                body.i_kl_products(qfd, &mut scratch.z);
            }
            for k in 0..3 {
                for l2 in 0..3 {
                    let dst = &mut scratch.n[(3 * k + l2) * nf..(3 * k + l2 + 1) * nf];
                    let ib = body.ibar_row(k, l2);
                    let y = row(&scratch.y, l2, k, nf);
                    for j in 0..nf {
                        dst[j] = ib[j] + y[j];
                    }
                }
            }
            None
        }
    };
    let [i1_qf, i1_qfd, i1_qfdd] = match &node_sums {
        Some((_, t)) => std::array::from_fn(|v| Vec3(std::array::from_fn(|c| t[v][c][0]))),
        None => [body.i1_times(qf), body.i1_times(qfd), body.i1_times(qfdd)],
    };
    let s = body.first_moment + i1_qf;
    let mut u = Mat3::ZERO;
    let mut pm = Mat3::ZERO;
    let mut n_qfdd = Mat3::ZERO;
    match &node_sums {
        Some((g, t)) => {
            // Ibar_kl . V_v = t[v][l][1 + k].
            for k in 0..3 {
                for l2 in 0..3 {
                    u.0[k][l2] =
                        body.second_moment.0[k][l2] + t[0][l2][1 + k] + t[0][k][1 + l2] + g[0][k][l2];
                    pm.0[k][l2] = t[1][l2][1 + k] + g[1][l2][k];
                    if k != l2 {
                        n_qfdd.0[k][l2] = t[2][l2][1 + k] + g[2][l2][k];
                    }
                }
            }
        }
        None => {
            let ibar_qf = nine_dots(&body.ibar, nf, qf);
            let y_qf = nine_dots(&scratch.y, nf, qf);
            let n_qfd = nine_dots(&scratch.n, nf, qfd);
            let n_dd = nine_dots(&scratch.n, nf, qfdd);
            for k in 0..3 {
                for l2 in 0..3 {
                    let (kl, lk) = (3 * k + l2, 3 * l2 + k);
                    u.0[k][l2] = body.second_moment.0[k][l2] + ibar_qf[kl] + ibar_qf[lk] + y_qf[kl];
                    pm.0[k][l2] = n_qfd[kl];
                    if k != l2 {
                        n_qfdd.0[k][l2] = n_dd[kl];
                    }
                }
            }
        }
    }
    let mut j = u.scale(-1.0);
    for k in 0..3 {
        j.0[k][k] += u.trace();
    }
    let mut jf_qdd = Vec3::ZERO;
    for i in 0..3 {
        let (k, l2) = ((i + 1) % 3, (i + 2) % 3);
        jf_qdd[i] = n_qfdd.0[k][l2] - n_qfdd.0[l2][k];
    }
    Quantities { p, a, l, w, alpha, acc, s, j, pm, jf_qdd, i1_qfd, i1_qfdd }
}

/// Fills `rows` (3 n_f) with the rows of J_f = int rho u~ S: row i = N_jk - N_kj for (i, j, k)
/// cyclic.
fn jf_rows(scratch: &FlexibleScratch, nf: usize, rows: &mut [f64]) {
    for i in 0..3 {
        let (k, l) = ((i + 1) % 3, (i + 2) % 3);
        let (a, b) = (row(&scratch.n, k, l, nf), row(&scratch.n, l, k, nf));
        for j in 0..nf {
            rows[i * nf + j] = a[j] - b[j];
        }
    }
}

fn map_rows_2lt(
    l: &Mat34,
    rows: &[f64],
    nf: usize,
    out: &mut [f64],
    out_row0: usize,
    out_cols: usize,
    col0: usize,
) {
    // out[(out_row0 + a) * out_cols + col0 + j] += sum_i 2 L[i][a] rows[i][j] for a in 0..4.
    for a in 0..4 {
        let dst = &mut out[(out_row0 + a) * out_cols + col0..(out_row0 + a) * out_cols + col0 + nf];
        for i in 0..3 {
            let c = 2.0 * l[i][a];
            if c != 0.0 {
                for (d, r) in dst.iter_mut().zip(&rows[i * nf..(i + 1) * nf]) {
                    *d += c * r;
                }
            }
        }
    }
}

/// Generalized inertia force f(q, q_dot, q_dd) of seed eq. 15 into `out` (7 + n_f).
pub fn inertia_force(
    body: &FlexibleBody,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    scratch: &mut FlexibleScratch,
    out: &mut [f64],
) {
    inertia_force_parts(body, q, qd, qdd, scratch, out, ElasticMass::Include, None);
}

/// Where [`inertia_force_parts`] puts the term M_ff qf_dd of the elastic rows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ElasticMass {
    /// In the force.
    Include,
    /// Nowhere (not formed).
    Skip,
    /// In `scratch.mass_term`, not in the force.
    Separate,
}

/// [`inertia_force`] with the term M_ff qf_dd of the elastic rows where `mass` says (see
/// [`add_linear_elastic_forces`]); with `gravity`, minus the generalized gravity force of
/// [`add_gravity_force`] (its elastic part I1^T A^T g in the pass of the inertia force's
/// I1^T a, and s = s0 + I1 q_f from the inertia quantities). Returns that s (for
/// [`gravity_jacobian_at`]).
#[allow(clippy::too_many_arguments)]
pub fn inertia_force_parts(
    body: &FlexibleBody,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    scratch: &mut FlexibleScratch,
    out: &mut [f64],
    mass: ElasticMass,
    gravity: Option<&Vec3>,
) -> Vec3 {
    let nf = body.elastic_count;
    let r7 = REFERENCE_COORDINATES;
    let mut k = quantities(body, q, qd, qdd, scratch, false, mass != ElasticMass::Skip);
    scratch.last = Some(k);
    let (w, alpha, s) = (k.w, k.alpha, k.s);
    // Translation: m R_dd + A (alpha x s + w x (w x s) + 2 w x I1 qf_dot + I1 qf_dd).
    let h_r = alpha.cross(&s) + w.cross(&w.cross(&s)) + w.cross(&k.i1_qfd) * 2.0 + k.i1_qfdd;
    let f_r = Vec3::from_slice(qdd) * body.mass + k.a.mul_vec(&h_r);
    // Rotation (body frame), mapped by 2 L^T.
    let g = rotation_force(&k);
    out[..3].copy_from_slice(&f_r.0);
    for a in 0..4 {
        out[3 + a] = 2.0 * (0..3).map(|i| k.l[i][a] * g[i]).sum::<f64>();
    }
    if let Some(gravity) = gravity {
        // Gravity: m g on R, d(A s)/dp^T g on p, I1^T A^T g on q_f (the last with the inertia
        // force's I1^T a: a - A^T g).
        let rt = rotate_transpose_jacobian(&k.p, gravity);
        for c in 0..3 {
            out[c] -= body.mass * gravity[c];
        }
        for c in 0..4 {
            out[3 + c] -= (0..3).map(|i| rt[i][c] * s[i]).sum::<f64>();
        }
        k.acc -= k.a.tr_mul_vec(gravity);
    }
    // Elastic: I1^T a + sum_kl E_kl N_lk (E = alpha~ + w~w~) + 2 sum_kl w~_kl I_kl qf_dot
    // + M_ff qf_dd, with sum_kl w~_kl I_kl = -sum_m w_m A_m.
    let f = &mut out[r7..r7 + nf];
    let e = alpha.skew() + w.skew().mul_mat(&w.skew());
    match &body.scalar_mass {
        Some(sm) if nodewise(body, scratch) => {
            // Node-wise: with the compressed rows (I1_c[j], Ibar_lc[j]) of coordinate j
            // (component c), I1^T a + sum_kl E_kl Ibar_lk is a_c I1_c[j] + sum_l E_cl
            // Ibar_lc[j]; then sum_kl E_kl y_kl + M_s (2 w x U_dot) + M_s U_dd from the
            // products of `quantities` (y_kl[j] = delta(comp j, k) Y0[node j][l]).
            if body.whole_nodes {
                // A node at a time: w x U_dot once per node (the same values).
                let nodes = f
                    .chunks_exact_mut(3)
                    .zip(sm.coordinates.chunks_exact(3))
                    .zip(body.solid_rows.chunks_exact(3));
                for (t, ((fs, cs), rows)) in nodes.enumerate() {
                    let node = cs[0] / 3;
                    let p = &scratch.nodal[9 * node..9 * node + 9];
                    let wy = w.cross(&Vec3([p[3], p[4], p[5]]));
                    for (comp, (fj, r)) in fs.iter_mut().zip(rows).enumerate() {
                        let ec = &e.0[comp];
                        let ey = ec[0] * (p[0] + r[1]) + ec[1] * (p[1] + r[2]) + ec[2] * (p[2] + r[3]);
                        *fj = k.acc[comp] * r[0] + ey + 2.0 * wy[comp];
                        match mass {
                            ElasticMass::Include => *fj += p[6 + comp],
                            ElasticMass::Separate => scratch.mass_term[3 * t + comp] = p[6 + comp],
                            ElasticMass::Skip => {}
                        }
                    }
                }
                return s;
            }
            for (j, ((fj, &c), r)) in f.iter_mut().zip(&sm.coordinates).zip(&body.solid_rows).enumerate() {
                let (node, comp) = (c / 3, c % 3);
                let p = &scratch.nodal[9 * node..9 * node + 9];
                let yd = Vec3([p[3], p[4], p[5]]);
                let ec = &e.0[comp];
                let ey = ec[0] * (p[0] + r[1]) + ec[1] * (p[1] + r[2]) + ec[2] * (p[2] + r[3]);
                *fj = k.acc[comp] * r[0] + ey + 2.0 * w.cross(&yd)[comp];
                match mass {
                    ElasticMass::Include => *fj += p[6 + comp],
                    ElasticMass::Separate => scratch.mass_term[j] = p[6 + comp],
                    ElasticMass::Skip => {}
                }
            }
        }
        _ => {
            f.iter_mut().for_each(|x| *x = 0.0);
            body.add_i1_transpose_times(&k.acc, f);
            for kk in 0..3 {
                for l in 0..3 {
                    let ce = e.0[kk][l];
                    if ce != 0.0 {
                        // N_lk = Ibar_lk + y_kl.
                        for (fj, nj) in f.iter_mut().zip(row(&scratch.n, l, kk, nf)) {
                            *fj += ce * nj;
                        }
                    }
                }
            }
            let qfd = &qd[r7..r7 + nf];
            for m in 0..3 {
                if w[m] != 0.0 {
                    body.antisymmetric[m].mul_vec_add(-2.0 * w[m], qfd, f);
                }
            }
            let qfdd = &qdd[r7..r7 + nf];
            match mass {
                ElasticMass::Include => body.mass_matrix.mul_vec_add(1.0, qfdd, f),
                ElasticMass::Separate => {
                    scratch.mass_term.iter_mut().for_each(|x| *x = 0.0);
                    body.mass_matrix.mul_vec_add(1.0, qfdd, &mut scratch.mass_term);
                }
                ElasticMass::Skip => {}
            }
        }
    }
    s
}

/// g = s x a + J alpha + w x J w + 2 (tr(P) w - P^T w) + J_f qf_dd (body frame).
fn rotation_force(k: &Quantities) -> Vec3 {
    let (w, alpha) = (k.w, k.alpha);
    let jw = k.j.mul_vec(&w);
    k.s.cross(&k.acc)
        + k.j.mul_vec(&alpha)
        + w.cross(&jw)
        + (w * k.pm.trace() - k.pm.tr_mul_vec(&w)) * 2.0
        + k.jf_qdd
}

/// Analytic Jacobians of [`inertia_force`]: df/dq_dd (mass), df/dq_dot (velocity) and df/dq
/// (position). Reference blocks are dense; the (f, f) blocks are sum_kl c_kl I_kl with the
/// coefficient matrices below (the mass block has c = I: M_ff = sum_k I_kk).
#[derive(Clone, Debug, Default)]
pub struct FlexibleTangent {
    /// n_f.
    pub n: usize,
    /// (reference, reference) blocks of the mass, velocity and position Jacobians.
    pub reference: [[[f64; 7]; 7]; 3],
    /// (reference, f) blocks, 7 x n_f row-major, for mass, velocity and position.
    pub reference_elastic: [Vec<f64>; 3],
    /// (f, reference) blocks, n_f x 7 row-major, for mass, velocity and position.
    pub elastic_reference: [Vec<f64>; 3],
    /// Coefficients of the (f, f) velocity block sum_kl c_kl I_kl (2 w~).
    pub velocity_coefficients: Mat3,
    /// Coefficients of the (f, f) position block (alpha~ + w~ w~).
    pub position_coefficients: Mat3,
}

impl FlexibleTangent {
    /// Buffers for a body with `n` elastic coordinates.
    pub fn with_size(n: usize) -> Self {
        FlexibleTangent {
            n,
            reference_elastic: std::array::from_fn(|_| vec![0.0; 7 * n]),
            elastic_reference: std::array::from_fn(|_| vec![0.0; 7 * n]),
            ..Default::default()
        }
    }

    fn clear(&mut self) {
        self.reference = [[[0.0; 7]; 7]; 3];
        for b in self.reference_elastic.iter_mut().chain(self.elastic_reference.iter_mut()) {
            b.iter_mut().for_each(|x| *x = 0.0);
        }
    }
}

fn add34(out: &mut [[f64; 7]; 7], r0: usize, c0: usize, m: &[[f64; 4]; 3], w: f64) {
    for i in 0..3 {
        for j in 0..4 {
            out[r0 + i][c0 + j] += w * m[i][j];
        }
    }
}

fn mat3_times_34(a: &Mat3, b: &Mat34) -> Mat34 {
    crate::math::small::matmul(&a.0, b)
}

/// d(w x (w x s))/dw = w s^T + (w.s) I - 2 s w^T.
fn centripetal_jacobian(w: &Vec3, s: &Vec3) -> Mat3 {
    w.outer(s) + Mat3::IDENTITY.scale(w.dot(s)) - s.outer(w).scale(2.0)
}

/// Fills `t` with the Jacobians of [`inertia_force`] at (q, q_dot, q_dd). Without
/// `reference_elastic`, only the reference block and the coefficients of the elastic block:
/// the (reference, f) and (f, reference) blocks are left as they were, and so are the general
/// I_kl products only they need (a condensed body's Newton solver replaces them).
pub fn inertia_tangent(
    body: &FlexibleBody,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    scratch: &mut FlexibleScratch,
    t: &mut FlexibleTangent,
    reference_elastic: bool,
) {
    let k = quantities(body, q, qd, qdd, scratch, reference_elastic, true);
    tangent_from(body, qd, qdd, &k, scratch, t, reference_elastic);
}

/// [`inertia_tangent`] right after [`inertia_force_parts`] at the same state: without the
/// (reference, elastic) blocks it needs no other quantities than that force's (which the
/// scratch keeps), and a body of solids then takes no second pass over its scalar mass matrix.
pub fn inertia_tangent_after_force(
    body: &FlexibleBody,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    scratch: &mut FlexibleScratch,
    t: &mut FlexibleTangent,
    reference_elastic: bool,
) {
    match scratch.last.take() {
        Some(k) if !reference_elastic => tangent_from(body, qd, qdd, &k, scratch, t, false),
        _ => inertia_tangent(body, q, qd, qdd, scratch, t, reference_elastic),
    }
}

/// [`inertia_tangent`] from the quantities `k` of the state (q, qd, qdd).
fn tangent_from(
    body: &FlexibleBody,
    qd: &[f64],
    qdd: &[f64],
    k: &Quantities,
    scratch: &mut FlexibleScratch,
    t: &mut FlexibleTangent,
    reference_elastic: bool,
) {
    let nf = body.elastic_count;
    let (p, a, l, w, alpha, s, j) = (k.p, k.a, k.l, k.w, k.alpha, k.s, k.j);
    let pd = quat(qd);
    let pdd = quat(qdd);
    let r_dd = Vec3::from_slice(qdd);
    let two_l = crate::math::small::scaled(&l, 2.0);
    let dw_dp = crate::math::small::scaled(&l_jacobian(&pd), 2.0);
    let dalpha_dp = crate::math::small::scaled(&l_jacobian(&pdd), 2.0);
    let dacc_dp = rotate_transpose_jacobian(&p, &r_dd);
    let s_skew = s.skew();
    let jw = j.mul_vec(&w);
    if reference_elastic {
        t.clear();
    } else {
        t.reference = [[[0.0; 7]; 7]; 3];
    }
    t.n = nf;
    let [tm, tv, tx] = &mut t.reference;

    // (R, R), (R, p), (p, R), (p, p) of the mass matrix.
    let m_rp = mat3_times_34(&a.mul_mat(&s_skew), &two_l);
    for i in 0..3 {
        tm[i][i] = body.mass;
        for c in 0..4 {
            tm[i][3 + c] = -m_rp[i][c];
            tm[3 + c][i] = -m_rp[i][c];
        }
    }
    let m_pp = crate::math::small::tr_matmul(&two_l, &mat3_times_34(&j, &two_l));
    for r in 0..4 {
        for c in 0..4 {
            tm[3 + r][3 + c] = m_pp[r][c];
        }
    }

    // Velocity: f_R through w (and qf_dot), g through w (and qf_dot).
    let dh_dw = centripetal_jacobian(&w, &s) - k.i1_qfd.skew().scale(2.0);
    add34(tv, 0, 3, &mat3_times_34(&a.mul_mat(&dh_dw), &two_l), 1.0);
    let mut dg_dw = w.skew().mul_mat(&j) - jw.skew();
    dg_dw = dg_dw + Mat3::IDENTITY.scale(2.0 * k.pm.trace()) - k.pm.transpose().scale(2.0);
    let v_pp = crate::math::small::tr_matmul(&two_l, &mat3_times_34(&dg_dw, &two_l));
    for r in 0..4 {
        for c in 0..4 {
            tv[3 + r][3 + c] = v_pp[r][c];
        }
    }

    // Position: rotation of A, L and p inside w, alpha and a = A^T R_dd.
    let h_r = alpha.cross(&s) + w.cross(&w.cross(&s)) + w.cross(&k.i1_qfd) * 2.0 + k.i1_qfdd;
    let mut k_rp = rotate_jacobian(&p, &h_r);
    let inner = {
        let mut m = mat3_times_34(&dh_dw, &dw_dp);
        crate::math::small::add_scaled(&mut m, -1.0, &mat3_times_34(&s_skew, &dalpha_dp));
        m
    };
    crate::math::small::add_scaled(&mut k_rp, 1.0, &mat3_times_34(&a, &inner));
    add34(tx, 0, 3, &k_rp, 1.0);
    let g = rotation_force(k);
    let inner_p = {
        let mut m = mat3_times_34(&s_skew, &dacc_dp);
        crate::math::small::add_scaled(&mut m, 1.0, &mat3_times_34(&j, &dalpha_dp));
        crate::math::small::add_scaled(&mut m, 1.0, &mat3_times_34(&dg_dw, &dw_dp));
        m
    };
    let k_pp_a = lt_jacobian(&g);
    let k_pp_b = crate::math::small::tr_matmul(&two_l, &inner_p);
    for r in 0..4 {
        for c in 0..4 {
            tx[3 + r][3 + c] = 2.0 * k_pp_a[r][c] + k_pp_b[r][c];
        }
    }

    if nf == 0 {
        t.velocity_coefficients = Mat3::ZERO;
        t.position_coefficients = Mat3::ZERO;
        return;
    }
    // Coefficients of the elastic block: velocity 2 w~, position alpha~ + w~ w~.
    let ws = w.skew();
    let e_mat = alpha.skew() + ws.mul_mat(&ws);
    t.velocity_coefficients = ws.scale(2.0);
    t.position_coefficients = e_mat;
    if !reference_elastic {
        return;
    }

    // Rows of J_f and sum_k N_kk.
    let mut jf = std::mem::take(&mut scratch.rows);
    jf_rows(scratch, nf, &mut jf);
    let mut rows = std::mem::take(&mut scratch.rows2);
    let n_trace: Vec<f64> = (0..nf).map(|c| (0..3).map(|kk| row(&scratch.n, kk, kk, nf)[c]).sum()).collect();
    let [rm, rv, rx] = &mut t.reference_elastic;
    let [fm, fv, fx] = &mut t.elastic_reference;

    // Mass: (R, f) = A I1, (p, f) = 2 L^T J_f; the (f, R), (f, p) blocks are their transposes.
    for i in 0..3 {
        for c in 0..nf {
            rm[i * nf + c] = (0..3).map(|kk| a.0[i][kk] * body.i1[kk * nf + c]).sum();
        }
    }
    map_rows_2lt(&l, &jf, nf, rm, 3, nf, 0);
    for r in 0..7 {
        for c in 0..nf {
            fm[c * 7 + r] = rm[r * nf + c];
        }
    }

    // Velocity (R, f) = A 2 w~ I1; (p, f) = 2 L^T 2 (w (sum_k N_kk)^T - [sum_k w_k N_kl]_l).
    let aw = a.mul_mat(&ws);
    for i in 0..3 {
        for c in 0..nf {
            rv[i * nf + c] = (0..3).map(|m| aw.0[i][m] * 2.0 * body.i1[m * nf + c]).sum();
        }
    }
    for lrow in 0..3 {
        for c in 0..nf {
            let wn: f64 = (0..3).map(|kk| w[kk] * row(&scratch.n, kk, lrow, nf)[c]).sum();
            rows[lrow * nf + c] = 2.0 * (w[lrow] * n_trace[c] - wn);
        }
    }
    map_rows_2lt(&l, &rows, nf, rv, 3, nf, 0);

    // Velocity (f, p): d/dw of int rho S^T w~w~ u and of 2 sum w~_kl z_kl, times 2L.
    // Columns m: sum_l w_l N_lm + sum_k w_k N_mk - 2 w_m sum_k N_kk - 2 sum_kl eps_klm z_kl.
    let mut dfw = vec![0.0; 3 * nf];
    for m in 0..3 {
        for c in 0..nf {
            let mut v = -2.0 * w[m] * n_trace[c];
            for kk in 0..3 {
                v += w[kk] * (row(&scratch.n, kk, m, nf)[c] + row(&scratch.n, m, kk, nf)[c]);
                for l2 in 0..3 {
                    let e = levi(kk, l2, m);
                    if e != 0.0 {
                        v -= 2.0 * e * row(&scratch.z, kk, l2, nf)[c];
                    }
                }
            }
            dfw[m * nf + c] = v;
        }
    }
    for c in 0..nf {
        for col in 0..4 {
            fv[c * 7 + 3 + col] = (0..3).map(|m| dfw[m * nf + c] * two_l[m][col]).sum();
        }
    }

    // Position (R, f) = A (alpha~ + w~w~) I1.
    let ae = a.mul_mat(&e_mat);
    for i in 0..3 {
        for c in 0..nf {
            rx[i * nf + c] = (0..3).map(|m| ae.0[i][m] * body.i1[m * nf + c]).sum();
        }
    }
    // Position (p, f) = 2 L^T dg/dq_f.
    let acc_skew = k.acc.skew();
    // A_i qf_dd: row i of d(J_f qf_dd)/dq_f.
    let qfdd = &qdd[REFERENCE_COORDINATES..REFERENCE_COORDINATES + nf];
    scratch.x[3 * nf..].iter_mut().for_each(|x| *x = 0.0);
    body.add_antisymmetric_products(1.0, qfdd, &mut scratch.x[3 * nf..]);
    let z_trace: Vec<f64> = (0..nf).map(|c| (0..3).map(|kk| row(&scratch.z, kk, kk, nf)[c]).sum()).collect();
    // d(J v)_i/dq_f = 2 v_i sum_k N_kk - sum_l v_l (N_il + N_li).
    let dj = |v: &Vec3, i: usize, c: usize| -> f64 {
        2.0 * v[i] * n_trace[c]
            - (0..3)
                .map(|l2| v[l2] * (row(&scratch.n, i, l2, nf)[c] + row(&scratch.n, l2, i, nf)[c]))
                .sum::<f64>()
    };
    for c in 0..nf {
        let djw = Vec3([dj(&w, 0, c), dj(&w, 1, c), dj(&w, 2, c)]);
        let w_djw = w.cross(&djw);
        let i1c = Vec3([body.i1[c], body.i1[nf + c], body.i1[2 * nf + c]]);
        let sa = acc_skew.mul_vec(&i1c);
        for i in 0..3 {
            let wz: f64 = (0..3).map(|kk| w[kk] * row(&scratch.z, kk, i, nf)[c]).sum();
            let jfx = scratch.x[3 * nf + i * nf + c];
            rows[i * nf + c] = -sa[i] + dj(&alpha, i, c) + w_djw[i] + 2.0 * (w[i] * z_trace[c] - wz) + jfx;
        }
    }
    map_rows_2lt(&l, &rows, nf, rx, 3, nf, 0);

    // Position (f, p) = I1^T d(a)/dp + J_f^T dalpha/dp + (dfw) dw/dp.
    for c in 0..nf {
        for col in 0..4 {
            let mut v = 0.0;
            for m in 0..3 {
                v += body.i1[m * nf + c] * dacc_dp[m][col]
                    + jf[m * nf + c] * dalpha_dp[m][col]
                    + dfw[m * nf + c] * dw_dp[m][col];
            }
            fx[c * 7 + 3 + col] = v;
        }
    }
    scratch.rows = jf;
    scratch.rows2 = rows;
}

/// Kinetic energy 1/2 q_dot^T M q_dot.
pub fn kinetic_energy(body: &FlexibleBody, q: &[f64], qd: &[f64], scratch: &mut FlexibleScratch) -> f64 {
    let nf = body.elastic_count;
    let r7 = REFERENCE_COORDINATES;
    let zero = vec![0.0; q.len()];
    let k = quantities(body, q, qd, &zero, scratch, true, true);
    let qfd = &qd[r7..r7 + nf];
    let v = Vec3::from_slice(qd);
    let mut jf = std::mem::take(&mut scratch.rows);
    jf_rows(scratch, nf, &mut jf);
    let jf_qfd = Vec3([dot(&jf[..nf], qfd), dot(&jf[nf..2 * nf], qfd), dot(&jf[2 * nf..], qfd)]);
    scratch.rows = jf;
    let mut m_qfd = vec![0.0; nf];
    body.mass_matrix.mul_vec_add(1.0, qfd, &mut m_qfd);
    0.5 * body.mass * v.dot(&v)
        + v.dot(&k.a.mul_vec(&(k.w.cross(&k.s) + k.i1_qfd)))
        + 0.5 * k.w.dot(&k.j.mul_vec(&k.w))
        + k.w.dot(&jf_qfd)
        + 0.5 * dot(qfd, &m_qfd)
}

/// Strain energy 1/2 q_f^T K_ff q_f plus the nonlinear part of the geometric stiffness.
pub fn strain_energy(body: &FlexibleBody, q: &[f64]) -> f64 {
    let nf = body.elastic_count;
    let qf = &q[REFERENCE_COORDINATES..REFERENCE_COORDINATES + nf];
    let mut kq = vec![0.0; nf];
    body.stiffness.mul_vec_add(1.0, qf, &mut kq);
    let nonlinear = add_stiffening(&body.stiffening, qf, &mut kq.clone(), None);
    0.5 * dot(qf, &kq) + nonlinear
}

/// Adds the elastic forces K_ff q_f + D_ff qf_dot (only with `linear`; see
/// [`add_linear_elastic_forces`]) plus the nonlinear beam forces of the geometric stiffness
/// to `out` (n_f) and, with `tangent = Some((position, velocity, values))`, their Jacobians
/// position dF/dq_f + velocity dF/dqf_dot to the elastic pattern values.
pub fn add_elastic_forces(
    body: &FlexibleBody,
    qf: &[f64],
    qfd: &[f64],
    out: &mut [f64],
    tangent: Option<(f64, f64, &mut [f64])>,
    linear: bool,
) {
    if linear {
        body.stiffness.mul_vec_add(1.0, qf, out);
        body.damping.mul_vec_add(1.0, qfd, out);
    }
    match tangent {
        Some((position, velocity, values)) => {
            body.stiffness.add_to_pattern(position, values);
            body.damping.add_to_pattern(velocity, values);
            add_stiffening(&body.stiffening, qf, out, Some((position, values)));
        }
        None => {
            add_stiffening(&body.stiffening, qf, out, None);
        }
    }
}

/// Adds the terms of the elastic rows that are linear with constant matrices,
/// M_ff qf_dd + D_ff qf_dot + K_ff q_f, into `out` (n_f): what [`inertia_force_parts`]
/// (with [`ElasticMass::Separate`], whose `mass_term` is M_ff qf_dd) and
/// [`add_elastic_forces`] without `linear` leave out.
pub fn add_linear_elastic_forces(
    body: &FlexibleBody,
    qf: &[f64],
    qfd: &[f64],
    mass_term: &[f64],
    out: &mut [f64],
) {
    out.iter_mut().zip(mass_term).for_each(|(o, m)| *o += m);
    body.damping.mul_vec_add(1.0, qfd, out);
    body.stiffness.mul_vec_add(1.0, qf, out);
}

/// Adds the generalized gravity force Q = int rho (dr/dq)^T g dV into `out` (7 + n_f):
/// [m g, d(A s)/dp^T g, I1^T A^T g] with s = s0 + I1 q_f.
pub fn add_gravity_force(body: &FlexibleBody, q: &[f64], gravity: &Vec3, out: &mut [f64]) {
    let nf = body.elastic_count;
    let r7 = REFERENCE_COORDINATES;
    let p = quat(q);
    let s = body.first_moment + body.i1_times(&q[r7..r7 + nf]);
    let rt = rotate_transpose_jacobian(&p, gravity);
    for k in 0..3 {
        out[k] += body.mass * gravity[k];
    }
    for c in 0..4 {
        out[3 + c] += (0..3).map(|i| rt[i][c] * s[i]).sum::<f64>();
    }
    let local = euler::rotation_matrix(&p).tr_mul_vec(gravity);
    body.add_i1_transpose_times(&local, &mut out[r7..r7 + nf]);
}

/// dQ/dq of gravity: the (p, p) block (4 x 4), and with `coupling` the (p, f) (4 x n_f
/// row-major) and (f, p) (n_f x 4 row-major) blocks.
pub fn gravity_jacobian(
    body: &FlexibleBody,
    q: &[f64],
    gravity: &Vec3,
    coupling: Option<(&mut [f64], &mut [f64])>,
) -> [[f64; 4]; 4] {
    let nf = body.elastic_count;
    let s = body.first_moment + body.i1_times(&q[REFERENCE_COORDINATES..REFERENCE_COORDINATES + nf]);
    gravity_jacobian_at(body, q, gravity, s, coupling)
}

/// [`gravity_jacobian`] with s = s0 + I1 q_f given (that of the inertia quantities, as
/// [`inertia_force_parts`] returns it).
pub fn gravity_jacobian_at(
    body: &FlexibleBody,
    q: &[f64],
    gravity: &Vec3,
    s: Vec3,
    coupling: Option<(&mut [f64], &mut [f64])>,
) -> [[f64; 4]; 4] {
    let nf = body.elastic_count;
    let p = quat(q);
    let Some((pf, fp)) = coupling else {
        return bilinear_hessian(gravity, &s);
    };
    let rt = rotate_transpose_jacobian(&p, gravity);
    for c in 0..nf {
        for a in 0..4 {
            let v: f64 = (0..3).map(|i| rt[i][a] * body.i1[i * nf + c]).sum();
            pf[a * nf + c] = v;
            fp[c * 4 + a] = v;
        }
    }
    bilinear_hessian(gravity, &s)
}

/// Potential energy of gravity -g . (m R + A s) (J).
pub fn gravity_potential(body: &FlexibleBody, q: &[f64], gravity: &Vec3) -> f64 {
    let nf = body.elastic_count;
    let r7 = REFERENCE_COORDINATES;
    let s = body.first_moment + body.i1_times(&q[r7..r7 + nf]);
    let a = euler::rotation_matrix(&quat(q));
    -gravity.dot(&(Vec3::from_slice(q) * body.mass + a.mul_vec(&s)))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::math::dense::DenseMatrix;

    /// A body of mass points: point i has mass m_i, undeformed position u0_i and shape rows
    /// S_i (3 x n_f, row-major): u_i = u0_i + S_i q_f.
    pub struct PointBody {
        pub masses: Vec<f64>,
        pub positions: Vec<Vec3>,
        pub shapes: Vec<Vec<f64>>,
        pub n: usize,
    }

    pub struct Lcg(pub u64);
    impl Lcg {
        pub fn next(&mut self) -> f64 {
            self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((self.0 >> 11) as f64) / ((1u64 << 53) as f64) * 2.0 - 1.0
        }
    }

    /// A symmetric positive definite test matrix.
    fn spd(n: usize, scale: f64) -> Csc {
        Csc::from_dense(n, n, |r, c| {
            scale * if r == c { 2.0 + r as f64 } else { 0.3 / (1.0 + (r + c) as f64) }
        })
    }

    impl PointBody {
        pub fn random(points: usize, n: usize, seed: u64) -> Self {
            let mut g = Lcg(seed);
            let masses = (0..points).map(|_| 1.0 + 0.5 * g.next()).collect();
            let positions = (0..points).map(|_| Vec3([g.next(), 0.5 * g.next(), 0.3 * g.next()])).collect();
            let shapes = (0..points).map(|_| (0..3 * n).map(|_| 0.3 * g.next()).collect()).collect();
            PointBody { masses, positions, shapes, n }
        }

        pub fn input(&self, stiffness: f64, damping: f64) -> FlexibleBodyInput {
            FlexibleBodyInput::from_mass_points(
                &self.masses,
                &self.positions,
                &self.shapes,
                spd(self.n, stiffness),
                spd(self.n, damping),
            )
        }

        /// Brute-force inertia force by virtual work over the points (seed eqs. 11-13).
        pub fn inertia_force(&self, q: &[f64], qd: &[f64], qdd: &[f64]) -> Vec<f64> {
            let n = self.n;
            let p = quat(q);
            let a = euler::rotation_matrix(&p);
            let w = euler::body_angular_velocity(&p, &quat(qd));
            let alpha = euler::body_angular_velocity(&p, &quat(qdd));
            let l = l_matrix(&p);
            let mut out = vec![0.0; 7 + n];
            let mut g = Vec3::ZERO;
            for (i, &m) in self.masses.iter().enumerate() {
                let sh = &self.shapes[i];
                let su = |v: &[f64]| Vec3(std::array::from_fn(|k| dot(&sh[k * n..(k + 1) * n], v)));
                let u = self.positions[i] + su(&q[7..]);
                let ud = su(&qd[7..]);
                let udd = su(&qdd[7..]);
                let local = alpha.cross(&u) + w.cross(&w.cross(&u)) + w.cross(&ud) * 2.0 + udd;
                let r_dd = Vec3::from_slice(qdd) + a.mul_vec(&local);
                let b = a.tr_mul_vec(&r_dd);
                for k in 0..3 {
                    out[k] += m * r_dd[k];
                }
                g += u.cross(&b) * m;
                for j in 0..n {
                    out[7 + j] += m * (0..3).map(|k| sh[k * n + j] * b[k]).sum::<f64>();
                }
            }
            for c in 0..4 {
                out[3 + c] = 2.0 * (0..3).map(|i| l[i][c] * g[i]).sum::<f64>();
            }
            out
        }

        pub fn kinetic_energy(&self, q: &[f64], qd: &[f64]) -> f64 {
            let p = quat(q);
            let a = euler::rotation_matrix(&p);
            let w = euler::body_angular_velocity(&p, &quat(qd));
            let mut e = 0.0;
            let n = self.n;
            for (i, &m) in self.masses.iter().enumerate() {
                let sh = &self.shapes[i];
                let su = |v: &[f64]| Vec3(std::array::from_fn(|k| dot(&sh[k * n..(k + 1) * n], v)));
                let u = self.positions[i] + su(&q[7..]);
                let v = Vec3::from_slice(qd) + a.mul_vec(&(w.cross(&u) + su(&qd[7..])));
                e += 0.5 * m * v.dot(&v);
            }
            e
        }
    }

    pub fn random_state(n: usize, seed: u64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let mut g = Lcg(seed);
        let mut p = [0.8 + 0.1 * g.next(), 0.3 * g.next(), -0.4 + 0.1 * g.next(), 0.3 * g.next()];
        let norm = p.iter().map(|x| x * x).sum::<f64>().sqrt();
        p.iter_mut().for_each(|x| *x /= norm);
        let mut q = vec![0.5 * g.next(), g.next(), 2.0 * g.next(), p[0], p[1], p[2], p[3]];
        q.extend((0..n).map(|_| 0.2 * g.next()));
        let qd: Vec<f64> = (0..7 + n).map(|_| g.next()).collect();
        let qdd: Vec<f64> = (0..7 + n).map(|_| g.next()).collect();
        (q, qd, qdd)
    }

    /// Full dense tangent matrices (mass, velocity, position) of the inertia force.
    pub fn dense_tangent(body: &FlexibleBody, t: &FlexibleTangent) -> [DenseMatrix; 3] {
        let n = body.elastic_count;
        let size = 7 + n;
        std::array::from_fn(|b| {
            let mut m = DenseMatrix::zeros(size, size);
            for r in 0..7 {
                for c in 0..7 {
                    m.add(r, c, t.reference[b][r][c]);
                }
                for c in 0..n {
                    m.add(r, 7 + c, t.reference_elastic[b][r * n + c]);
                    m.add(7 + c, r, t.elastic_reference[b][c * 7 + r]);
                }
            }
            let coef = match b {
                0 => Mat3::IDENTITY,
                1 => t.velocity_coefficients,
                _ => t.position_coefficients,
            };
            let mut values = vec![0.0; body.pattern.nnz()];
            body.add_i_kl_to_pattern(&coef, &mut values);
            for c in 0..n {
                for k in body.pattern.col_ptr[c]..body.pattern.col_ptr[c + 1] {
                    m.add(7 + body.pattern.row_idx[k], 7 + c, values[k]);
                }
            }
            m
        })
    }

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol * (1.0 + a.abs().max(b.abs()))
    }

    #[test]
    fn inertia_force_equals_brute_force_sum_over_mass_points() {
        for (n, seed) in [(0, 1), (1, 2), (4, 3)] {
            let pts = PointBody::random(7, n, seed);
            let body = FlexibleBody::new("b", pts.input(1.0, 0.0)).unwrap();
            let (q, qd, qdd) = random_state(n, seed + 10);
            let mut scratch = FlexibleScratch::with_size(n);
            let mut f = vec![0.0; 7 + n];
            inertia_force(&body, &q, &qd, &qdd, &mut scratch, &mut f);
            let brute = pts.inertia_force(&q, &qd, &qdd);
            for i in 0..7 + n {
                assert!(close(f[i], brute[i], 1e-12), "n = {n}, entry {i}: {} vs {}", f[i], brute[i]);
            }
            let e = kinetic_energy(&body, &q, &qd, &mut scratch);
            assert!(close(e, pts.kinetic_energy(&q, &qd), 1e-12));
        }
    }

    #[test]
    fn node_row_sums_agree_with_plain_sums() {
        // Rows of four per coordinate, three vectors, whole nodes (0 to 7 of them).
        for nodes in 0..8usize {
            let n = 3 * nodes;
            let rows: Vec<[f64; 4]> =
                (0..n).map(|j| std::array::from_fn(|i| ((5 * j + 3 * i) % 7) as f64 - 3.0)).collect();
            let v: Vec<Vec<f64>> =
                (0..3).map(|k| (0..n).map(|j| 0.25 * (j + k) as f64 - 1.0).collect()).collect();
            let vectors = [&v[0][..], &v[1][..], &v[2][..]];
            let portable = node_row_sums_portable(&rows, vectors);
            #[cfg(target_arch = "x86_64")]
            let fast = if crate::linalg::simd::has_avx2_fma() {
                // SAFETY: the CPU supports AVX2 and FMA (checked).
                unsafe { crate::linalg::simd::avx2::node_row_sums(&rows, vectors) }
            } else {
                portable
            };
            #[cfg(not(target_arch = "x86_64"))]
            let fast = portable;
            for vv in 0..3 {
                for c in 0..3 {
                    for i in 0..4 {
                        let exact: f64 = (0..nodes).map(|nd| rows[3 * nd + c][i] * v[vv][3 * nd + c]).sum();
                        for got in [portable[vv][c][i], fast[vv][c][i]] {
                            assert!((got - exact).abs() <= 1e-12 * (1.0 + exact.abs()), "{nodes} nodes");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn elastic_matrix_products_agree_in_every_storage() {
        // Stored whole (full), with three quarters of its entries (dense copy), in 3 x 3 node
        // blocks, and as a sparse band (indexed): out += w A x against the plain CSC product.
        let value = |r: usize, c: usize| 1.0 + ((3 * r + 7 * c) % 5) as f64 - 0.25 * c as f64;
        // (n, entries kept, expected storage: full, dense copy, 3 x 3 blocks)
        type Case = (usize, fn(usize, usize) -> bool, [bool; 3]);
        let cases: [Case; 4] = [
            (10, |_, _| true, [true, false, false]),
            (18, |r, c| (r + 2 * c) % 4 != 1, [false, true, false]),
            (12, |r, c| r / 3 == c / 3 || r / 3 + 1 == c / 3, [false, false, true]),
            (20, |r, c| r.abs_diff(c) <= 1, [false, false, false]),
        ];
        for (n, keep, storage) in cases {
            let mut entries = Csc::from_dense(n, n, value);
            let (mut row_idx, mut values, mut col_ptr) = (Vec::new(), Vec::new(), vec![0]);
            for c in 0..n {
                for k in entries.col_ptr[c]..entries.col_ptr[c + 1] {
                    if keep(entries.row_idx[k], c) {
                        row_idx.push(entries.row_idx[k]);
                        values.push(entries.values[k]);
                    }
                }
                col_ptr.push(row_idx.len());
            }
            (entries.row_idx, entries.values, entries.col_ptr) = (row_idx, values, col_ptr);
            let pattern = ElasticPattern::union(n, &[&entries], &[]);
            let matrix = ElasticMatrix::new(entries.clone(), &pattern);
            let stored = [matrix.full, matrix.dense.is_some(), matrix.blocks.is_some()];
            assert_eq!(stored, storage, "n = {n}");
            let x: Vec<f64> = (0..n).map(|k| 0.3 * k as f64 - 1.0).collect();
            let start: Vec<f64> = (0..n).map(|k| 0.1 * k as f64).collect();
            let mut expected = vec![0.0; n];
            entries.mul_vec_add(&x, &mut expected);
            let mut out = start.clone();
            matrix.mul_vec_add(-1.5, &x, &mut out);
            for k in 0..n {
                let e = start[k] - 1.5 * expected[k];
                assert!(
                    (out[k] - e).abs() <= 1e-12 * (1.0 + e.abs()),
                    "n = {n}, row {k}: {} against {e}",
                    out[k]
                );
            }
        }
    }

    #[test]
    fn tangent_matches_finite_differences() {
        let n = 3;
        let pts = PointBody::random(6, n, 7);
        let body = FlexibleBody::new("b", pts.input(1.0, 0.0)).unwrap();
        let (q, qd, qdd) = random_state(n, 8);
        let mut scratch = FlexibleScratch::with_size(n);
        let mut t = FlexibleTangent::with_size(n);
        inertia_tangent(&body, &q, &qd, &qdd, &mut scratch, &mut t, true);
        let dense = dense_tangent(&body, &t);
        let h = 1e-6;
        for which in 0..3 {
            for c in 0..7 + n {
                let mut eval = |s: f64| {
                    let (mut a, mut b, mut d) = (q.clone(), qd.clone(), qdd.clone());
                    match which {
                        0 => d[c] += s,
                        1 => b[c] += s,
                        _ => a[c] += s,
                    }
                    let mut f = vec![0.0; 7 + n];
                    inertia_force(&body, &a, &b, &d, &mut scratch, &mut f);
                    f
                };
                let (fp, fm) = (eval(h), eval(-h));
                for r in 0..7 + n {
                    let fd = (fp[r] - fm[r]) / (2.0 * h);
                    let an = dense[which].get(r, c);
                    assert!(close(fd, an, 1e-7), "block {which} ({r}, {c}): fd {fd} vs analytic {an}");
                }
            }
        }
    }

    #[test]
    fn reference_only_tangent_equals_the_reference_block_of_the_whole() {
        // Without the coupling blocks the tangent takes the node-wise products of a solid
        // body (no general I_kl products): its reference block and the coefficients of the
        // elastic block must equal those of the whole tangent.
        for body in [solid_body(true, false).unwrap(), solid_body(false, false).unwrap()] {
            let n = body.elastic_count;
            let (q, qd, qdd) = random_state(n, 61);
            let mut scratch = FlexibleScratch::for_body(&body);
            let (mut whole, mut reference) = (FlexibleTangent::with_size(n), FlexibleTangent::with_size(n));
            inertia_tangent(&body, &q, &qd, &qdd, &mut scratch, &mut whole, true);
            inertia_tangent(&body, &q, &qd, &qdd, &mut scratch, &mut reference, false);
            // The same from the quantities of the inertia force at that state.
            let mut after = FlexibleTangent::with_size(n);
            let mut force = vec![0.0; 7 + n];
            inertia_force(&body, &q, &qd, &qdd, &mut scratch, &mut force);
            inertia_tangent_after_force(&body, &q, &qd, &qdd, &mut scratch, &mut after, false);
            assert_eq!(after.reference, reference.reference);
            assert!(scratch.last.is_none(), "the kept quantities are taken");
            for b in 0..3 {
                for r in 0..7 {
                    for c in 0..7 {
                        let (x, y) = (whole.reference[b][r][c], reference.reference[b][r][c]);
                        assert!(close(x, y, 1e-12), "block {b} ({r}, {c}): {x} vs {y}");
                    }
                }
            }
            for (x, y) in [
                (whole.velocity_coefficients, reference.velocity_coefficients),
                (whole.position_coefficients, reference.position_coefficients),
            ] {
                for r in 0..3 {
                    for c in 0..3 {
                        assert!(close(x.0[r][c], y.0[r][c], 1e-12));
                    }
                }
            }
            assert!(reference.reference_elastic.iter().all(|b| b.iter().all(|&x| x == 0.0)));
        }
    }

    #[test]
    fn mass_matrix_is_symmetric_and_gives_the_kinetic_energy() {
        let n = 4;
        let pts = PointBody::random(8, n, 11);
        let body = FlexibleBody::new("b", pts.input(1.0, 0.0)).unwrap();
        let (q, qd, qdd) = random_state(n, 12);
        let mut scratch = FlexibleScratch::with_size(n);
        let mut t = FlexibleTangent::with_size(n);
        inertia_tangent(&body, &q, &qd, &qdd, &mut scratch, &mut t, true);
        let m = &dense_tangent(&body, &t)[0];
        for r in 0..7 + n {
            for c in 0..7 + n {
                assert!(close(m.get(r, c), m.get(c, r), 1e-13));
            }
        }
        // f(q, q_dot, q_dd) - f(q, q_dot, 0) = M q_dd.
        let mut f = vec![0.0; 7 + n];
        let mut f0 = vec![0.0; 7 + n];
        inertia_force(&body, &q, &qd, &qdd, &mut scratch, &mut f);
        inertia_force(&body, &q, &qd, &vec![0.0; 7 + n], &mut scratch, &mut f0);
        let mut mq = vec![0.0; 7 + n];
        m.mul_vec_add(1.0, &qdd, &mut mq);
        for r in 0..7 + n {
            assert!(close(f[r] - f0[r], mq[r], 1e-12));
        }
        assert!(close(0.5 * m.quadratic_form(&qd), kinetic_energy(&body, &q, &qd, &mut scratch), 1e-12));
    }

    #[test]
    fn gravity_jacobian_matches_finite_differences_and_potential() {
        let n = 3;
        let pts = PointBody::random(5, n, 21);
        let body = FlexibleBody::new("b", pts.input(1.0, 0.0)).unwrap();
        let (q, _, _) = random_state(n, 22);
        let g = Vec3([0.3, -9.81, 1.2]);
        let mut pf = vec![0.0; 4 * n];
        let mut fp = vec![0.0; 4 * n];
        let pp = gravity_jacobian(&body, &q, &g, Some((&mut pf, &mut fp)));
        assert_eq!(gravity_jacobian(&body, &q, &g, None), pp);
        let h = 1e-6;
        for c in 3..7 + n {
            let eval = |s: f64| {
                let mut a = q.clone();
                a[c] += s;
                let mut out = vec![0.0; 7 + n];
                add_gravity_force(&body, &a, &g, &mut out);
                (out, gravity_potential(&body, &a, &g))
            };
            let ((fp1, v1), (fm1, v2)) = (eval(h), eval(-h));
            for r in 3..7 + n {
                let fd = (fp1[r] - fm1[r]) / (2.0 * h);
                let an = match (r < 7, c < 7) {
                    (true, true) => pp[r - 3][c - 3],
                    (true, false) => pf[(r - 3) * n + c - 7],
                    (false, true) => fp[(r - 7) * 4 + c - 3],
                    (false, false) => 0.0,
                };
                assert!(close(fd, an, 1e-7), "({r}, {c}): {fd} vs {an}");
            }
            // Q = -dV/dq.
            let mut out = vec![0.0; 7 + n];
            add_gravity_force(&body, &q, &g, &mut out);
            assert!(close(-(v1 - v2) / (2.0 * h), out[c], 1e-7));
        }
    }

    /// A body of solids: nodes with translations only, I_kl = P^T (M_s (x) e_k e_l^T) P over
    /// the kept coordinates (node 0 held), with or without its scalar mass structure.
    fn solid_body(with_scalar: bool, corrupt: bool) -> Result<FlexibleBody> {
        let nodes = 4;
        let ms =
            Csc::from_dense(
                nodes,
                nodes,
                |r, c| if r == c { 2.0 + r as f64 } else { 0.4 / (1 + r + c) as f64 },
            );
        let coordinates: Vec<usize> = (3..3 * nodes).collect();
        let n = coordinates.len();
        let positions: Vec<Vec3> =
            (0..nodes).map(|a| Vec3([0.3 * a as f64, 0.1 * (a % 2) as f64, 0.05])).collect();
        let mut input = FlexibleBodyInput {
            i1: vec![0.0; 3 * n],
            ibar: vec![0.0; 9 * n],
            stiffness: Csc::from_dense(n, n, |r, c| if r == c { 100.0 } else { 1.0 / (1 + r + c) as f64 }),
            damping: Csc::from_dense(n, n, |_, _| 0.0),
            ..Default::default()
        };
        // Moments from M_s (consistent with its row sums as the nodal masses).
        for a in 0..nodes {
            for b in 0..nodes {
                let m = ms.get(a, b);
                input.mass += m;
                input.first_moment += positions[b] * m;
                input.second_moment = input.second_moment + positions[a].outer(&positions[b]).scale(m);
            }
        }
        for (j, &c) in coordinates.iter().enumerate() {
            let (b, l) = (c / 3, c % 3);
            for a in 0..nodes {
                let m = ms.get(a, b);
                input.i1[l * n + j] += m;
                for k in 0..3 {
                    input.ibar[(3 * k + l) * n + j] += m * positions[a][k];
                }
            }
        }
        input.i_kl = (0..9)
            .map(|kl| {
                let (k, l) = (kl / 3, kl % 3);
                Csc::from_dense(n, n, |r, c| {
                    let (cr, cc) = (coordinates[r], coordinates[c]);
                    if cr % 3 == k && cc % 3 == l {
                        ms.get(cr / 3, cc / 3)
                    } else {
                        0.0
                    }
                })
            })
            .collect();
        if with_scalar {
            let mut matrix = ms.clone();
            if corrupt {
                matrix.values[5] *= 1.1;
            }
            input.scalar_mass = Some(ScalarMass { matrix, coordinates });
        }
        FlexibleBody::new("solid", input)
    }

    #[test]
    fn antisymmetric_norm_bound_bounds_the_products() {
        // For either storage (assembled antisymmetric matrices, M_s), |A_i v| <= b |v| for
        // vectors of several shapes, and b is the same order as the largest ratio met (the
        // condensed solver keeps its deformation solves on this bound, see `condensed.rs`).
        let (plain, fast) = (solid_body(false, false).unwrap(), solid_body(true, false).unwrap());
        let n = plain.elastic_count;
        let (b_plain, b_fast) = (plain.antisymmetric_norm_bound(), fast.antisymmetric_norm_bound());
        assert!(b_plain > 0.0 && b_fast > 0.0);
        let mut largest = 0.0f64;
        for seed in 0..8u64 {
            let (q, qd, _) = random_state(n, 60 + seed);
            for v in [&q[7..], &qd[7..]] {
                let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
                for (body, bound) in [(&plain, b_plain), (&fast, b_fast)] {
                    let mut out = vec![0.0; 3 * n];
                    body.add_antisymmetric_products(1.0, v, &mut out);
                    for row in out.chunks_exact(n) {
                        let r = row.iter().map(|x| x * x).sum::<f64>().sqrt();
                        assert!(r <= bound * norm * (1.0 + 1e-12), "{r} > {bound} * {norm}");
                        largest = largest.max(r / norm);
                    }
                }
            }
        }
        assert!(b_plain.max(b_fast) < 50.0 * largest, "bounds {b_plain}, {b_fast} against {largest}");
    }

    #[test]
    fn scalar_mass_products_equal_the_invariant_products() {
        let (plain, fast) = (solid_body(false, false).unwrap(), solid_body(true, false).unwrap());
        let n = plain.elastic_count;
        let (q, qd, qdd) = random_state(n, 51);
        let (mut a, mut b) = (vec![0.0; 7 + n], vec![0.0; 7 + n]);
        inertia_force(&plain, &q, &qd, &qdd, &mut FlexibleScratch::for_body(&plain), &mut a);
        inertia_force(&fast, &q, &qd, &qdd, &mut FlexibleScratch::for_body(&fast), &mut b);
        for k in 0..7 + n {
            assert!(close(a[k], b[k], 1e-12), "{k}: {} vs {}", a[k], b[k]);
        }
        assert!(!fast.solid_rows.is_empty(), "the compressed rows of a body of solids");
        // The elastic mass term apart: Include = Separate + mass_term, Skip = Separate.
        for body in [&plain, &fast] {
            let mut scratch = FlexibleScratch::for_body(body);
            let mut parts = [vec![0.0; 7 + n], vec![0.0; 7 + n], vec![0.0; 7 + n]];
            for (out, mass) in
                parts.iter_mut().zip([ElasticMass::Include, ElasticMass::Skip, ElasticMass::Separate])
            {
                inertia_force_parts(body, &q, &qd, &qdd, &mut scratch, out, mass, None);
            }
            let mass_term = scratch.mass_term.clone();
            assert!(mass_term.iter().any(|&m| m.abs() > 1e-3));
            for k in 0..7 + n {
                let separate = parts[2][k] + if k >= 7 { mass_term[k - 7] } else { 0.0 };
                assert!(close(parts[0][k], separate, 1e-12), "{k}: {} vs {separate}", parts[0][k]);
                assert_eq!(parts[1][k], parts[2][k], "{k}");
            }
        }
        // The antisymmetric products from M_s.
        let (mut a, mut b) = (vec![1.0; 3 * n], vec![1.0; 3 * n]);
        plain.add_antisymmetric_products(-0.5, &qd[7..], &mut a);
        fast.add_antisymmetric_products(-0.5, &qd[7..], &mut b);
        assert!(a.iter().any(|&x| (x - 1.0).abs() > 1e-3));
        for k in 0..3 * n {
            assert!(close(a[k], b[k], 1e-12), "antisymmetric {k}: {} vs {}", a[k], b[k]);
        }
        // Gravity (I1 products from the compressed rows).
        let gravity = Vec3([0.3, -9.81, 1.2]);
        let (mut a, mut b) = (vec![0.0; 7 + n], vec![0.0; 7 + n]);
        add_gravity_force(&plain, &q, &gravity, &mut a);
        add_gravity_force(&fast, &q, &gravity, &mut b);
        for k in 0..7 + n {
            assert!(close(a[k], b[k], 1e-12), "gravity {k}: {} vs {}", a[k], b[k]);
        }
        // The inertia force minus gravity in one call equals the two apart, and the first
        // moment it returns for the gravity Jacobian is that of the state.
        for body in [&plain, &fast] {
            let mut scratch = FlexibleScratch::for_body(body);
            let (mut apart, mut fused) = (vec![0.0; 7 + n], vec![0.0; 7 + n]);
            inertia_force_parts(body, &q, &qd, &qdd, &mut scratch, &mut apart, ElasticMass::Include, None);
            let mut weight = vec![0.0; 7 + n];
            add_gravity_force(body, &q, &gravity, &mut weight);
            let s = inertia_force_parts(
                body,
                &q,
                &qd,
                &qdd,
                &mut scratch,
                &mut fused,
                ElasticMass::Include,
                Some(&gravity),
            );
            for k in 0..7 + n {
                let expected = apart[k] - weight[k];
                assert!(
                    close(fused[k], expected, 1e-12),
                    "inertia - gravity {k}: {} vs {expected}",
                    fused[k]
                );
            }
            let (mut pf, mut fp, mut pf2, mut fp2) =
                (vec![0.0; 4 * n], vec![0.0; 4 * n], vec![0.0; 4 * n], vec![0.0; 4 * n]);
            let given = gravity_jacobian_at(body, &q, &gravity, s, Some((&mut pf, &mut fp)));
            let formed = gravity_jacobian(body, &q, &gravity, Some((&mut pf2, &mut fp2)));
            for (a, b) in given.iter().flatten().zip(formed.iter().flatten()).chain(pf.iter().zip(&pf2)) {
                assert!(close(*a, *b, 1e-12), "gravity Jacobian: {a} vs {b}");
            }
        }
        assert!(solid_body(true, true).is_err());
    }

    /// A sparse matrix of 3 x 3 node blocks (node pairs of a chain plus a few long-range
    /// pairs, some entries inside blocks left out), from a seed.
    fn node_block_matrix(nodes: usize, seed: u64) -> Csc {
        let mut rng = Lcg(seed);
        let coupled = |a: usize, b: usize| a.abs_diff(b) <= 1 || (a * 7 + b * 7) % 5 == 0;
        let mut col_ptr = vec![0];
        let (mut row_idx, mut values) = (Vec::new(), Vec::new());
        for c in 0..3 * nodes {
            for r in 0..3 * nodes {
                if coupled(r / 3, c / 3) && (r + 2 * c) % 7 != 3 {
                    row_idx.push(r);
                    values.push(rng.next());
                }
            }
            col_ptr.push(row_idx.len());
        }
        Csc { nrows: 3 * nodes, ncols: 3 * nodes, col_ptr, row_idx, values }
    }

    #[test]
    fn scalar_mass_products_equal_the_dense_sums() {
        // A symmetric 5 x 5 scalar mass with zeros, node 1 without its y component: the
        // node-wise products of three vectors (W = 6 and 9; the AVX2 kernel where the CPU has
        // it) against dense sums.
        let nodes = 5;
        let dense = |r: usize, c: usize| {
            if (r + 2 * c) % 3 == 1 && r != c {
                0.0
            } else {
                1.0 / (1.0 + (r + c) as f64)
            }
        };
        let sm = ScalarMass {
            matrix: Csc::from_dense(nodes, nodes, |r, c| dense(r.min(c), r.max(c))),
            coordinates: (0..3 * nodes).filter(|&c| c != 4).collect(),
        };
        let n = sm.coordinates.len();
        let v: Vec<Vec<f64>> =
            (0..3).map(|k| (0..n).map(|j| ((j * 7 + k * 5) % 11) as f64 - 5.0).collect()).collect();
        let mut spread = vec![0.0; 9 * nodes];
        for (j, &c) in sm.coordinates.iter().enumerate() {
            for k in 0..3 {
                spread[9 * (c / 3) + 3 * k + c % 3] = v[k][j];
            }
        }
        for w in [6, 9] {
            // Entries past W are left as they were (7); gathered is zero outside the
            // coordinates' entries before and after.
            let (mut gathered, mut out) = (vec![0.0; 9 * nodes], vec![7.0; 9 * nodes]);
            let g = if w == 6 {
                sm.products::<6>([&v[0], &v[1], &v[2]], &mut gathered, &mut out)
            } else {
                sm.products::<9>([&v[0], &v[1], &v[2]], &mut gathered, &mut out)
            };
            assert_eq!(gathered, spread);
            let mut portable = vec![7.0; 9 * nodes];
            let g_portable = if w == 6 {
                sm.multiply_portable::<6>(&gathered, &mut portable)
            } else {
                sm.multiply_portable::<9>(&gathered, &mut portable)
            };
            for i in 0..nodes {
                for k in 0..9 {
                    let expected: f64 = if k < w {
                        (0..nodes).map(|r| dense(r.min(i), r.max(i)) * spread[9 * r + k]).sum()
                    } else {
                        7.0
                    };
                    for got in [out[9 * i + k], portable[9 * i + k]] {
                        assert!(
                            (got - expected).abs() <= 1e-12,
                            "W = {w}, node {i}, entry {k}: {got} vs {expected}"
                        );
                    }
                }
            }
            // g[v][k][l] = sum over the nodes of V_v[node][k] Y_0[node][l].
            for vv in 0..3 {
                for k in 0..3 {
                    for l in 0..3 {
                        let expected: f64 =
                            (0..nodes).map(|i| spread[9 * i + 3 * vv + k] * out[9 * i + l]).sum();
                        for got in [g[vv][k][l], g_portable[vv][k][l]] {
                            assert!(
                                (got - expected).abs() <= 1e-10,
                                "g[{vv}][{k}][{l}]: {got} vs {expected}"
                            );
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn node_block_products_equal_the_compressed_column_products() {
        // A general matrix of node blocks and a symmetric one (M + M^T, kept as its upper
        // blocks).
        let general = node_block_matrix(9, 3);
        let n = general.nrows;
        let mut dense = vec![0.0; n * n];
        for c in 0..n {
            for k in general.col_ptr[c]..general.col_ptr[c + 1] {
                dense[c * n + general.row_idx[k]] += general.values[k];
                dense[general.row_idx[k] * n + c] += general.values[k];
            }
        }
        let mut symmetric =
            Csc { nrows: n, ncols: n, col_ptr: vec![0], row_idx: Vec::new(), values: Vec::new() };
        for c in 0..n {
            for r in 0..n {
                if dense[c * n + r] != 0.0 {
                    symmetric.row_idx.push(r);
                    symmetric.values.push(dense[c * n + r]);
                }
            }
            symmetric.col_ptr.push(symmetric.row_idx.len());
        }
        for (m, is_symmetric) in [(general, false), (symmetric, true)] {
            let pattern = ElasticPattern::union(m.nrows, &[&m], &[]);
            let blocked = ElasticMatrix::new(m.clone(), &pattern);
            let blocks = blocked.blocks.as_ref().expect("blocks");
            assert_eq!(blocks.symmetric, is_symmetric);
            if is_symmetric {
                // The node pairs of the pattern: the upper ones are stored, and only they.
                let mut pairs = std::collections::BTreeSet::new();
                for c in 0..n {
                    for &r in &m.row_idx[m.col_ptr[c]..m.col_ptr[c + 1]] {
                        pairs.insert((r / 3, c / 3));
                    }
                }
                let upper: Vec<(usize, usize)> = pairs.iter().copied().filter(|(r, c)| c >= r).collect();
                let stored: Vec<(usize, usize)> = (0..n / 3)
                    .flat_map(|br| {
                        let range = blocks.row_ptr[br]..blocks.row_ptr[br + 1];
                        blocks.columns[range].iter().map(move |&bc| (br, bc as usize))
                    })
                    .collect();
                assert_eq!(stored, upper);
                assert!(upper.len() < pairs.len());
            }
            let x: Vec<f64> = (0..27).map(|k| (0.37 * k as f64).sin()).collect();
            let mut expected: Vec<f64> = (0..27).map(|k| 0.1 * k as f64).collect();
            let mut got = expected.clone();
            blocked.mul_vec_add(-1.5, &x, &mut got);
            let mut product = vec![0.0; 27];
            m.mul_vec_add(&x, &mut product);
            for (e, p) in expected.iter_mut().zip(&product) {
                *e += -1.5 * p;
            }
            // The kernel chosen for this CPU (AVX2 where it has it) and the portable one; x
            // and out exactly 3 n_b long (the last node's entries read through the mask).
            let mut portable: Vec<f64> = (0..27).map(|k| 0.1 * k as f64).collect();
            blocks.mul_vec_add_portable(-1.5, &x, &mut portable);
            for k in 0..27 {
                assert!((got[k] - expected[k]).abs() <= 1e-14, "{k}: {} vs {}", got[k], expected[k]);
                assert!(
                    (portable[k] - expected[k]).abs() <= 1e-14,
                    "{k}: {} vs {}",
                    portable[k],
                    expected[k]
                );
            }
        }
        // Not made of node blocks (a diagonal): the compressed columns serve.
        let diagonal = Csc::from_dense(30, 30, |r, c| if r == c { 1.0 } else { 0.0 });
        let mut sparse = diagonal.clone();
        sparse.col_ptr = (0..=30).collect();
        sparse.row_idx = (0..30).collect();
        sparse.values = vec![1.0; 30];
        assert!(Blocks3::from_csc(&sparse).is_none());
        assert!(Blocks3::from_csc(&diagonal).is_some());
    }

    #[test]
    fn bad_data_is_rejected() {
        let pts = PointBody::random(4, 2, 31);
        let mut inp = pts.input(1.0, 0.0);
        inp.mass = -1.0;
        assert!(FlexibleBody::new("b", inp).is_err());
        let mut inp = pts.input(1.0, 0.0);
        inp.i_kl[1].values[0] += 1.0;
        assert!(FlexibleBody::new("b", inp).is_err());
        let mut inp = pts.input(1.0, 0.0);
        inp.stiffness.values[1] = f64::NAN;
        assert!(FlexibleBody::new("b", inp).is_err());
        let mut inp = pts.input(1.0, 0.0);
        inp.i1.pop();
        assert!(FlexibleBody::new("b", inp).is_err());
    }
}
