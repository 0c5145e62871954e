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

use crate::body::corotational::{add_corotational, CorotationalBeam};
use crate::body::element_map::SparseMap;
use crate::body::stiffening::{add_stiffening, StiffeningElement};
use crate::error::{FlexmbdError, Result};
use crate::linalg::csc::Csc;
use crate::math::euler::{
    self, bilinear_hessian, l_jacobian, l_matrix, lt_jacobian, rotate_jacobian, rotate_transpose_jacobian,
    Mat34, Quaternion,
};
use crate::math::{Mat3, Vec3};

mod attached;
mod energy;
mod inertia;
mod storage;
mod tangent;
#[cfg(test)]
pub(crate) mod tests;

pub use attached::*;
pub use energy::*;
pub use inertia::*;
pub use storage::*;
pub use tangent::*;

/// Number of reference coordinates [R, p] of a flexible body.
pub const REFERENCE_COORDINATES: usize = 7;

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
    /// Beam elements of the co-rotational elastic forces (`body::corotational`; nodal
    /// bodies), the geometrically exact alternative to `stiffening`.
    pub corotational: Vec<CorotationalBeam>,
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
    /// Point masses with a rotary inertia or an offset at nodes with rotations: the second
    /// order of their motion about the node (see [`AttachedMass`]; the invariants hold them
    /// moving linearly).
    pub attached: Vec<AttachedMass>,
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
    /// Beam elements of the co-rotational elastic forces (empty: none).
    pub corotational: Vec<CorotationalBeam>,
    /// Node of each elastic coordinate (for orderings), see [`FlexibleBodyInput`].
    pub dof_nodes: Option<Vec<usize>>,
    /// Node positions (for orderings).
    pub node_positions: Option<Vec<Vec3>>,
    /// Condensation in the linear solves, see [`FlexibleBodyInput`].
    pub condense: Option<bool>,
    /// The scalar mass structure of a body of solids, see [`FlexibleBodyInput`].
    pub scalar_mass: Option<ScalarMass>,
    /// Attached masses, see [`FlexibleBodyInput`].
    pub attached: Vec<AttachedMass>,
    /// Bodies of solids: per elastic coordinate j (component c of a node), the entries of I1
    /// and Ibar that can be nonzero, [I1_c[j], Ibar_0c[j], Ibar_1c[j], Ibar_2c[j]] (S_l has
    /// no entry at j for l != c); empty otherwise. See [`solid_sums`].
    pub(crate) solid_rows: Vec<[f64; 4]>,
    /// Bodies of solids: whether the elastic coordinates are the three components of each
    /// of their nodes in order (3 a, 3 a + 1, 3 a + 2 together): the node-wise sums then take
    /// a node at a time.
    pub(crate) whole_nodes: bool,
    /// When every I_kl is stored full (modal bodies): the nine stacked, (9 n_f) x n_f
    /// column-major (column c = the columns c of I_00, I_01, ..., I_22), so that
    /// `i_kl_products` is one matrix-vector product by contiguous column updates.
    pub(crate) stacked_i_kl: Option<Vec<f64>>,
}

pub(crate) fn check_square(item: &str, what: &str, m: &Csc, n: usize) -> Result<()> {
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

/// Largest |A - B^T| relative to the largest entry of A and B.
pub(crate) fn transpose_mismatch(a: &Csc, b: &Csc) -> f64 {
    transpose_difference(a, b) / largest_entry([a, b])
}

/// The largest stored |entry| of the matrices (at least the smallest positive number).
fn largest_entry<'a>(matrices: impl IntoIterator<Item = &'a Csc>) -> f64 {
    matrices
        .into_iter()
        .flat_map(|m| m.values.iter())
        .fold(0.0f64, |m, v| m.max(v.abs()))
        .max(f64::MIN_POSITIVE)
}

/// Largest |A - B^T| over the stored entries of both.
fn transpose_difference(a: &Csc, b: &Csc) -> f64 {
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
    worst
}

impl FlexibleBodyInput {
    /// Checks the data of body `item` (positive mass, finite values, shapes, I_kl^T = I_lk,
    /// symmetric K_ff and D_ff, stiffening elements) and returns its number of elastic
    /// coordinates n_f. The scalar mass is checked against the I_kl once they are laid out
    /// ([`FlexibleBody::check_scalar_mass`]).
    fn validate(&self, item: &str) -> Result<usize> {
        let n = self.check_invariants(item)?;
        self.check_elastic_matrices(item, n)?;
        self.check_symmetry(item)?;
        self.check_stiffening(item, n)?;
        Ok(n)
    }

    /// Mass and moments, and the sizes and entries of the invariants; returns n_f.
    fn check_invariants(&self, item: &str) -> Result<usize> {
        let bad = |message: String| FlexmbdError::InvalidParameter { item: item.to_string(), message };
        if !(self.mass.is_finite() && self.mass > 0.0) {
            return Err(bad(format!("mass must be positive and finite, got {}", self.mass)));
        }
        if !self.first_moment.is_finite() || !self.second_moment.is_finite() {
            return Err(bad("first and second moments must be finite".to_string()));
        }
        let n = self.i1.len() / 3;
        if self.i1.len() != 3 * n || self.ibar.len() != 9 * n || self.i_kl.len() != 9 {
            return Err(bad(format!(
                "invariants of inconsistent size: I1 has {} entries, Ibar {}, {} matrices I_kl \
                 (expected 3 n_f, 9 n_f and 9)",
                self.i1.len(),
                self.ibar.len(),
                self.i_kl.len()
            )));
        }
        if self.i1.iter().chain(&self.ibar).any(|v| !v.is_finite()) {
            return Err(bad("invariants I1 and Ibar must be finite".to_string()));
        }
        for (kl, m) in self.i_kl.iter().enumerate() {
            check_square(item, &format!("invariant I_{}{}", kl / 3 + 1, kl % 3 + 1), m, n)?;
        }
        Ok(n)
    }

    /// K_ff and D_ff n_f x n_f, and a node for every elastic coordinate when nodes are given.
    fn check_elastic_matrices(&self, item: &str, n: usize) -> Result<()> {
        check_square(item, "stiffness matrix", &self.stiffness, n)?;
        match (&self.dof_nodes, &self.node_positions) {
            (None, None) => {}
            (Some(d), Some(p)) if d.len() == n && d.iter().all(|&k| k < p.len()) => {}
            _ => {
                return Err(FlexmbdError::InvalidParameter {
                    item: item.to_string(),
                    message: format!(
                    "dof_nodes must give a node (of node_positions) for each of the {n} elastic coordinates"
                ),
                })
            }
        }
        check_square(item, "damping matrix", &self.damping, n)
    }

    /// I_kl^T = I_lk (to 1e-9 of the largest entry of all nine: a pair that couples nothing,
    /// such as I_12 of the bending modes of a plate in the x-y plane, is round-off of the
    /// others' size), and symmetric K_ff and D_ff (to 1e-9 of the largest entry).
    fn check_symmetry(&self, item: &str) -> Result<()> {
        let bad = |message: String| FlexmbdError::InvalidParameter { item: item.to_string(), message };
        let scale = largest_entry(&self.i_kl);
        for k in 0..3 {
            for l in k..3 {
                let mismatch = transpose_difference(&self.i_kl[3 * k + l], &self.i_kl[3 * l + k]) / scale;
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
        for (what, m) in [("stiffness matrix", &self.stiffness), ("damping matrix", &self.damping)] {
            let mismatch = transpose_mismatch(m, m);
            if mismatch > 1e-9 {
                return Err(bad(format!("{what} must be symmetric (mismatch {mismatch:.1e})")));
            }
        }
        Ok(())
    }

    /// Stiffening elements: consistent sizes over existing elastic coordinates, finite values,
    /// a symmetric S with a positive diagonal.
    fn check_stiffening(&self, item: &str, n: usize) -> Result<()> {
        for (k, el) in self.stiffening.iter().enumerate() {
            if !el.is_consistent(n) {
                return Err(FlexmbdError::InvalidParameter {
                    item: item.to_string(),
                    message: format!(
                        "stiffening element {k}: needs an n_e x n_l map over existing elastic \
                         coordinates, m x n_e linear strains, m matrices n_e x n_e and a symmetric \
                         m x m stiffness with a positive diagonal (beams: a positive length and axial \
                         stiffness), all finite"
                    ),
                });
            }
        }
        for (k, mass) in self.attached.iter().enumerate() {
            if !mass.is_consistent(n) {
                return Err(FlexmbdError::InvalidParameter {
                    item: item.to_string(),
                    message: format!(
                        "attached mass {k}: needs 6 x n_l rows over existing elastic coordinates, \
                         a finite node position and finite mass points"
                    ),
                });
            }
        }
        for (k, el) in self.corotational.iter().enumerate() {
            if !el.is_consistent(n) {
                return Err(FlexmbdError::InvalidParameter {
                    item: item.to_string(),
                    message: format!(
                        "co-rotational beam element {k}: needs a 12 x n_l map over existing elastic \
                         coordinates, a positive length and a symmetric 12 x 12 stiffness matrix, all \
                         finite"
                    ),
                });
            }
        }
        Ok(())
    }
}

/// The positions of the (row, column) pairs of `indices` in `pattern`, row-major.
fn block_positions(indices: &[usize], pattern: &ElasticPattern) -> Vec<usize> {
    indices
        .iter()
        .flat_map(|&r| indices.iter().map(move |&c| (r, c)))
        .map(|(r, c)| pattern.position(r, c))
        .collect()
}

/// The stiffening elements with the positions of their (row, column) pairs in `pattern`.
fn placed_stiffening(
    mut stiffening: Vec<StiffeningElement>,
    pattern: &ElasticPattern,
) -> Vec<StiffeningElement> {
    for el in stiffening.iter_mut() {
        el.positions = block_positions(&el.indices, pattern);
        el.sparse_map = SparseMap::of(&el.map, el.local_count(), el.indices.len());
    }
    stiffening
}

/// sum w I_kl over the `terms` (w, 3 k + l) of the invariants `i_kl`, on `pattern` (n_f x
/// n_f).
fn i_kl_combination(i_kl: &[Csc], pattern: &ElasticPattern, terms: &[(f64, usize)]) -> Csc {
    let n = pattern.n;
    let mut values = vec![0.0; pattern.nnz()];
    for &(w, kl) in terms {
        let m = &i_kl[kl];
        for c in 0..n {
            for k in m.col_ptr[c]..m.col_ptr[c + 1] {
                values[pattern.position(m.row_idx[k], c)] += w * m.values[k];
            }
        }
    }
    Csc { nrows: n, ncols: n, col_ptr: pattern.col_ptr.clone(), row_idx: pattern.row_idx.clone(), values }
}

impl FlexibleBody {
    /// Checks the data (positive mass, finite values, shapes, I_kl^T = I_lk, symmetric K_ff and
    /// D_ff) and lays out the elastic pattern.
    pub fn new(item: &str, input: FlexibleBodyInput) -> Result<Self> {
        let n = input.validate(item)?;
        // One pattern for every (f, f) matrix: the I_kl, K_ff, D_ff and the stiffening blocks.
        let mut all: Vec<&Csc> = input.i_kl.iter().collect();
        all.push(&input.stiffness);
        all.push(&input.damping);
        let blocks: Vec<&[usize]> = input
            .stiffening
            .iter()
            .map(|e| e.indices.as_slice())
            .chain(input.corotational.iter().map(|e| e.indices.as_slice()))
            .chain(input.attached.iter().map(|e| e.indices.as_slice()))
            .collect();
        let pattern = ElasticPattern::union(n, &all, &blocks);
        let stiffening = placed_stiffening(input.stiffening, &pattern);
        let mut corotational = input.corotational;
        for el in corotational.iter_mut() {
            el.positions = block_positions(&el.indices, &pattern);
            el.sparse_map = SparseMap::of(&el.map, 12, el.indices.len());
        }
        let mut attached = input.attached;
        for mass in attached.iter_mut() {
            mass.positions = block_positions(&mass.indices, &pattern);
        }
        // M_ff = sum_k I_kk and A_m = I_{m+1,m+2} - I_{m+2,m+1}.
        let mass_matrix = ElasticMatrix::new(
            i_kl_combination(&input.i_kl, &pattern, &[(1.0, 0), (1.0, 4), (1.0, 8)]),
            &pattern,
        );
        let antisymmetric = (0..3)
            .map(|m| {
                let (a, b) = ((m + 1) % 3, (m + 2) % 3);
                let terms = [(1.0, 3 * a + b), (-1.0, 3 * b + a)];
                ElasticMatrix::new(i_kl_combination(&input.i_kl, &pattern, &terms), &pattern)
            })
            .collect();
        let i_kl = input.i_kl.into_iter().map(|m| ElasticMatrix::new(m, &pattern)).collect();
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
            corotational,
            dof_nodes: input.dof_nodes,
            node_positions: input.node_positions,
            condense: input.condense,
            scalar_mass: None,
            attached,
            solid_rows: Vec::new(),
            whole_nodes: false,
            stacked_i_kl: None,
            i_kl,
            mass_matrix,
            antisymmetric,
            pattern,
        };
        if let Some(sm) = input.scalar_mass {
            body.attach_scalar_mass(item, sm)?;
        }
        body.stacked_i_kl = body.stacked_full_i_kl();
        Ok(body)
    }

    /// Checks the scalar mass structure `sm` of a body of solids against the I_kl and keeps it
    /// with the rows and node grouping its sums use.
    fn attach_scalar_mass(&mut self, item: &str, sm: ScalarMass) -> Result<()> {
        self.check_scalar_mass(item, &sm)?;
        self.solid_rows = self.compressed_solid_rows(&sm);
        self.whole_nodes = sm.coordinates.len() % 3 == 0
            && sm.coordinates.chunks_exact(3).all(|c| c[0] % 3 == 0 && c[1] == c[0] + 1 && c[2] == c[0] + 2);
        self.scalar_mass = Some(sm);
        Ok(())
    }

    /// The nine I_kl stacked (see `stacked_i_kl`) when every one is stored full; None
    /// otherwise.
    fn stacked_full_i_kl(&self) -> Option<Vec<f64>> {
        let n = self.elastic_count;
        if n == 0 || !self.i_kl.iter().all(|m| m.full) {
            return None;
        }
        let mut stacked = vec![0.0; 9 * n * n];
        for (kl, m) in self.i_kl.iter().enumerate() {
            for (c, column) in m.matrix.values.chunks_exact(n).enumerate() {
                stacked[c * 9 * n + kl * n..c * 9 * n + (kl + 1) * n].copy_from_slice(column);
            }
        }
        Some(stacked)
    }

    /// Checks that the scalar mass matrix gives the body's I_kl (products with a test vector).
    pub(crate) fn check_scalar_mass(&self, item: &str, sm: &ScalarMass) -> Result<()> {
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
    pub(crate) fn compressed_solid_rows(&self, sm: &ScalarMass) -> Vec<[f64; 4]> {
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
    pub(crate) fn solid_components(&self) -> Option<impl Iterator<Item = usize> + '_> {
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

    pub(crate) fn ibar_row(&self, k: usize, l: usize) -> &[f64] {
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
