//! The loosely coupled (seed eq. 40) and decoupled (seed eq. 41) joint-elastic acceleration
//! equations of a tree of rigid and deformable bodies in joint plus elastic coordinates.
//!
//! With the reference accelerations q_dd_r of all bodies written through the joint and elastic
//! accelerations (eq. 33/39: q_dd_r = H_pp p_dd + H_pf q_dd_f + gamma_r), the equations of
//! motion of the bodies (eq. 35), the joint reactions on the reference coordinates F_r with
//! H_pp^T F_r = 0 and F_f = -H_pf^T F_r (eqs. 36-37) and the cut joints' constraints
//! C_r q_dd_r + C_f q_dd_f = gamma_c (multipliers mu) form the sparse symmetric system of
//! eq. 40, unknowns [q_dd_r, q_dd_f, -F_r, p_dd, mu]:
//!
//! ```text
//! [ M_rr   M_rf    I        0      C_r^T ]
//! [ M_fr   M_ff   -H_pf^T   0      C_f^T ]
//! [ I     -H_pf    0       -H_pp   0     ]  = [Q_r; Q_f; gamma_r; 0; gamma_c]
//! [ 0      0      -H_pp^T   0      0     ]
//! [ C_r    C_f     0        0      0     ]
//! ```
//!
//! M_ff of each deformable body is constant: factorized once, it is the pivot that removes
//! q_dd_f (eq. 38b, q_dd_f = M_ff^-1 (Q_f - M_fr q_dd_r + H_pf^T (-F_r) - C_f^T mu)) and leaves
//! eq. 41, whose dimension (2 n_r + n_p + n_c) does not depend on the number of elastic
//! coordinates. Its blocks are formed without any matrix of that size:
//!
//! - H_pf = sum over the deformed joint markers m of D_m S_m, with D_m = dq_r/d(u, theta) of
//!   the marker (6 columns, from the tree recursion) and S_m = [S_u; S_t] its shape matrix;
//!   W_m = M_ff^-1 S_m^T and S_m W_m' (6 x 6) are constant and computed once;
//! - X_b = M_ff^-1 [M_fr | Q_f] per body: 8 solves with the constant factor per evaluation;
//! - M_rf M_ff^-1 H_pf^T = sum_m (S_m X_b)^T D_m^T, H_pf M_ff^-1 H_pf^T = sum D_m (S_m W_m')
//!   D_m'^T.
//!
//! Departure from the paper: the reduced system is solved by a dense LU of its (small)
//! coefficient matrix instead of the recursive projection of references 19-21; both are
//! independent of the number of elastic coordinates, the projection would make the solve
//! linear in the number of bodies as well. With Euler parameters the reference coordinates
//! are 7 per body (3 for a point mass) instead of 6, so n_r counts 7 per body; the reaction
//! component along the Euler parameters (the normalization's) is part of F_r.

use faer::Mat;

use crate::assembly::{assemble, constraint_time_terms, MatrixCoefficients, Request, StateView};
use crate::body::marker::MarkerElastic;
use crate::body::BodyKind;
use crate::error::{FlexmbdError, Result};
use crate::formulation::augmented::{checked_lu_with, SINGULAR_VALUE_CUTOFF};
use crate::formulation::recursive::{StructuredState, Tree};
use crate::linalg::partition::minimum_norm_solve;
use crate::linalg::sparse::{PatternBuilder, SparseLu, SparsePattern};
use crate::linalg::symmetric::{CscRef, FactorKind, Ordering, SymmetricFactor};
use crate::system::{Model, Workspace};

/// Smallest ratio of LU pivots of the tree block of eq. 41 taken as regular.
const TREE_PIVOT_RATIO: f64 = 1e-14;

/// Which system gives the joint-coordinate accelerations.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TreeFormulation {
    /// (B^T M B) p_dd = B^T (f - M gamma_B) with B formed explicitly (dense; the strongly
    /// coupled system).
    JointSpace,
    /// Seed eq. 40: the loosely coupled sparse system (sparse LU).
    Coupled,
    /// Seed eq. 41: the reduced system after eliminating the elastic accelerations with the
    /// constant M_ff.
    Decoupled,
}

crate::named!(TreeFormulation { JointSpace => "joint-space", Coupled => "coupled", Decoupled => "decoupled" });

/// Accelerations and reactions from eq. 40 or 41.
#[derive(Clone, Debug, Default)]
pub struct TreeAccelerations {
    /// q_dd of every body (model coordinates).
    pub accelerations: Vec<f64>,
    /// Free joint accelerations, then elastic accelerations (the free coordinates' order).
    pub free_accelerations: Vec<f64>,
    /// -F_r: the joint reactions on the reference coordinates, with the sign of eq. 40
    /// (reference rows).
    pub reactions: Vec<f64>,
    /// Multipliers of the cut joints' rows.
    pub cut_multipliers: Vec<f64>,
}

/// One deformable body of the tree.
struct ElasticBody {
    /// First model index of its elastic coordinates.
    first: usize,
    /// First index among the free coordinates.
    free_first: usize,
    n: usize,
    /// Position of its reference coordinates among the reference rows.
    reference: usize,
    factor: SymmetricFactor,
    /// Its deformed joint markers: (index in StructuredState::markers, W_m = M_ff^-1 S_m^T
    /// column-major n x 6, shape).
    markers: Vec<(usize, Vec<f64>, MarkerElastic)>,
    /// S_m W_m' (6 x 6, row-major) for each pair of its markers (row-major over the pairs).
    couplings: Vec<[[f64; 6]; 6]>,
}

impl ElasticBody {
    /// Deformable body `body` of `model` with `n` elastic coordinates, the first at
    /// `free_first` among the free coordinates and its reference coordinates at `reference`
    /// among the reference rows: its factorized M_ff and the products with the shapes of
    /// its `deformed` joint markers (all of the tree's: (body, shape)).
    fn new(
        model: &Model,
        body: usize,
        free_first: usize,
        n: usize,
        reference: usize,
        deformed: &[(usize, &MarkerElastic)],
    ) -> Result<ElasticBody> {
        let BodyKind::Flexible(fb) = &model.bodies[body].kind else {
            unreachable!("elastic blocks are flexible")
        };
        let m = &fb.mass_matrix.matrix;
        let matrix = CscRef { n, col_ptr: &m.col_ptr, row_idx: &m.row_idx, values: &m.values };
        let ordering = match (&fb.dof_nodes, &fb.node_positions) {
            (Some(nodes), Some(positions)) => Ordering::NestedDissection { dof_nodes: nodes, positions },
            _ => Ordering::Amd,
        };
        let item = format!("mass matrix M_ff of body '{}'", model.bodies[body].name);
        let factor = SymmetricFactor::new(&item, matrix, ordering, FactorKind::Cholesky, 1)?;
        let mut markers = Vec::new();
        for (k, &(b, shape)) in deformed.iter().enumerate() {
            if b != body {
                continue;
            }
            // W_m = M_ff^-1 S_m^T.
            let mut w = vec![0.0; 6 * n];
            for (j, &idx) in shape.indices.iter().enumerate() {
                for c in 0..3 {
                    w[c * n + idx] = shape.translation.get(c, j);
                    w[(3 + c) * n + idx] = shape.rotation.get(c, j);
                }
            }
            factor.solve_in_place(&mut w)?;
            markers.push((k, w, shape.clone()));
        }
        let couplings = marker_couplings(&markers, n);
        let first = model.bodies[body].offset + 7;
        Ok(ElasticBody { first, free_first, n, reference, factor, markers, couplings })
    }
}

/// S_m W_m' (6 x 6, row-major) for each pair (m, m') of a body's `markers` (row-major over
/// the pairs), `n` the body's elastic coordinates.
fn marker_couplings(markers: &[(usize, Vec<f64>, MarkerElastic)], n: usize) -> Vec<[[f64; 6]; 6]> {
    let mut couplings = Vec::new();
    for (_, _, shape) in markers {
        for (_, w, _) in markers {
            let mut g = [[0.0; 6]; 6];
            for c in 0..6 {
                let s = shape_times(shape, &w[c * n..(c + 1) * n]);
                for r in 0..6 {
                    g[r][c] = s[r];
                }
            }
            couplings.push(g);
        }
    }
    couplings
}

/// S_m x for a column x over the body's elastic coordinates: 6 values.
fn shape_times(shape: &MarkerElastic, x: &[f64]) -> [f64; 6] {
    let mut out = [0.0; 6];
    for (j, &idx) in shape.indices.iter().enumerate() {
        for c in 0..3 {
            out[c] += shape.translation.get(c, j) * x[idx];
            out[3 + c] += shape.rotation.get(c, j) * x[idx];
        }
    }
    out
}

/// The acceleration solver of a tree in the loosely coupled or decoupled form.
pub struct TreeSolver {
    formulation: TreeFormulation,
    bodies: Vec<ElasticBody>,
    /// Reference rows (model indices) and, per body, its position among them.
    rows: Vec<usize>,
    row_of: Vec<usize>,
    free_joints: usize,
    cut_rows: Vec<usize>,
    /// Eq. 40: its sparse system (None for eq. 41).
    coupled: Option<CoupledSystem>,
    zero_q: Vec<f64>,
    zero_lambda: Vec<f64>,
}

/// The sparse system of eq. 40: where the model's coordinates and constraint rows go, the
/// pattern, its LU (symbolic analysis once) and the values of the current matrix.
struct CoupledSystem {
    /// The unknown of each model coordinate (a reference or elastic acceleration; usize::MAX
    /// for the other coordinates).
    unknown_of: Vec<usize>,
    /// The position among the cut rows of each constraint row (usize::MAX if not cut).
    cut_of: Vec<usize>,
    pattern: SparsePattern,
    lu: SparseLu,
    /// The matrix's values on `pattern` (nnz), filled by [`TreeSolver::coupled`].
    values: Vec<f64>,
}

/// Where the blocks of unknowns of eq. 40 start: [q_dd_r, q_dd_f, -F_r, p_dd, mu].
struct CoupledLayout {
    /// q_dd_f of each deformable body.
    elastic: Vec<usize>,
    /// -F_r.
    y0: usize,
    /// p_dd.
    p0: usize,
    /// mu.
    c0: usize,
}

/// The dense system of eq. 41, a z = rhs with z = [q_dd_r, -F_r, p_dd, mu], as it is formed.
struct ReducedSystem {
    a: Mat<f64>,
    rhs: Vec<f64>,
}

/// What eliminating a deformable body's elastic accelerations from eq. 40 leaves to recover
/// them (eq. 38b).
struct Elimination {
    /// X = M_ff^-1 [M_fr | Q_f] (n x 8, column-major).
    x: Vec<f64>,
    /// M_ff^-1 C_f^T per cut row (n values; empty where the row does not reach the body).
    cut_solves: Vec<Vec<f64>>,
}

impl std::fmt::Debug for TreeSolver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "TreeSolver({}, reduced size {})", self.formulation.name(), self.reduced_size())
    }
}

fn singular(context: &str, detail: String) -> FlexmbdError {
    FlexmbdError::SingularMatrix { time: f64::NAN, context: context.to_string(), detail }
}

impl TreeSolver {
    /// Factorizes the constant M_ff of every deformable body and the constant products with
    /// its joint markers' shapes; for eq. 40 also the sparse pattern.
    pub fn new(model: &Model, tree: &Tree, formulation: TreeFormulation) -> Result<TreeSolver> {
        let rows = tree.reference_rows().to_vec();
        let mut row_of = vec![usize::MAX; model.coordinate_count];
        for (i, &r) in rows.iter().enumerate() {
            row_of[r] = i;
        }
        let deformed = tree.deformed_markers();
        let bodies = tree
            .elastic_blocks()
            .into_iter()
            .map(|(body, free_first, n)| {
                let reference = row_of[model.bodies[body].offset];
                ElasticBody::new(model, body, free_first, n, reference, &deformed)
            })
            .collect::<Result<Vec<_>>>()?;
        let mut solver = TreeSolver {
            formulation,
            bodies,
            rows,
            row_of,
            free_joints: tree.free_joint_count(),
            cut_rows: tree.cut_rows.clone(),
            coupled: None,
            zero_q: vec![0.0; model.coordinate_count],
            zero_lambda: vec![0.0; model.constraint_count],
        };
        if formulation == TreeFormulation::Coupled {
            solver.coupled = Some(CoupledSystem::new(model, &solver)?);
        }
        Ok(solver)
    }

    /// Dimension of the system solved: 2 n_r + n_p + n_c for eq. 41 (independent of the
    /// elastic coordinates), plus n_f for eq. 40.
    pub fn reduced_size(&self) -> usize {
        let base = 2 * self.rows.len() + self.free_joints + self.cut_rows.len();
        match self.formulation {
            TreeFormulation::Coupled => base + self.bodies.iter().map(|b| b.n).sum::<usize>(),
            _ => base,
        }
    }

    /// Where the blocks of unknowns of eq. 40 start.
    fn coupled_layout(&self) -> CoupledLayout {
        let nr = self.rows.len();
        let mut elastic = Vec::with_capacity(self.bodies.len());
        let mut offset = nr;
        for b in &self.bodies {
            elastic.push(offset);
            offset += b.n;
        }
        let nf = offset - nr;
        let (y0, p0) = (nr + nf, 2 * nr + nf);
        CoupledLayout { elastic, y0, p0, c0: p0 + self.free_joints }
    }

    /// The accelerations at (time, q, q_dot) of the tree state `st`, with `ws` a workspace
    /// of `model` for evaluations.
    pub fn accelerations(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        st: &StructuredState,
        time: f64,
        discrete: &[f64],
    ) -> Result<TreeAccelerations> {
        let nq = model.coordinate_count;
        let view = StateView {
            time,
            q: &st.coordinates,
            qd: &st.velocities,
            qdd: &self.zero_q,
            lambda: &self.zero_lambda,
            discrete,
        };
        assemble(model, view, ws, &Request::matrix(MatrixCoefficients::ACCELERATION))?;
        let nc = self.cut_rows.len();
        let mut gamma_c = vec![0.0; nc];
        if nc > 0 {
            let mut rate = vec![0.0; model.constraint_count];
            let mut gamma = vec![0.0; model.constraint_count];
            constraint_time_terms(model, view, ws, &mut rate, Some(&mut gamma))?;
            for (a, &r) in self.cut_rows.iter().enumerate() {
                gamma_c[a] = gamma[r];
            }
        }
        let force: Vec<f64> = ws.residual[..nq].iter().map(|r| -r).collect();
        match self.formulation {
            TreeFormulation::Coupled => self.coupled(model, ws, st, &force, &gamma_c),
            _ => self.decoupled(model, ws, st, &force, &gamma_c),
        }
    }

    /// M_rr (reference rows x reference rows, block diagonal), M_fr per body (n x 7,
    /// column-major) and the cut rows' Jacobian C (n_c x model coordinates, by entries) from
    /// the assembled values.
    #[allow(clippy::type_complexity)]
    fn blocks(&self, model: &Model, ws: &Workspace) -> (Mat<f64>, Vec<Vec<f64>>, Vec<Vec<(usize, f64)>>) {
        let nq = model.coordinate_count;
        let nr = self.rows.len();
        let pattern = &model.layout.pattern;
        let mut m_rr = Mat::zeros(nr, nr);
        let mut m_fr: Vec<Vec<f64>> = self.bodies.iter().map(|b| vec![0.0; 7 * b.n]).collect();
        let mut cut: Vec<Vec<(usize, f64)>> = vec![Vec::new(); self.cut_rows.len()];
        let cut_of = |r: usize| self.cut_rows.iter().position(|&c| c == r);
        for (i, &c) in self.rows.iter().enumerate() {
            for k in pattern.col_ptr[c]..pattern.col_ptr[c + 1] {
                let r = pattern.row_idx[k];
                let v = ws.values[k];
                if r >= nq {
                    if let Some(a) = cut_of(r - nq) {
                        cut[a].push((c, v));
                    }
                } else if self.row_of[r] != usize::MAX {
                    m_rr[(self.row_of[r], i)] = v;
                } else if let Some(bk) =
                    self.bodies.iter().position(|b| (b.first..b.first + b.n).contains(&r))
                {
                    // The body's own reference columns (entries of other bodies' columns are
                    // couplings of the iteration matrix, zero in the mass matrix).
                    let b = &self.bodies[bk];
                    if (b.reference..b.reference + 7).contains(&i) {
                        m_fr[bk][(i - b.reference) * b.n + r - b.first] = v;
                    }
                }
            }
        }
        if !self.cut_rows.is_empty() {
            for b in &self.bodies {
                for c in b.first..b.first + b.n {
                    for k in pattern.col_ptr[c]..pattern.col_ptr[c + 1] {
                        let r = pattern.row_idx[k];
                        if r >= nq {
                            if let Some(a) = cut_of(r - nq) {
                                cut[a].push((c, ws.values[k]));
                            }
                        }
                    }
                }
            }
        }
        (m_rr, m_fr, cut)
    }

    /// Eq. 41: every body's elastic accelerations eliminated with its constant M_ff, the
    /// reduced system solved, and the elastic accelerations recovered (eq. 38b).
    fn decoupled(
        &mut self,
        model: &Model,
        ws: &Workspace,
        st: &StructuredState,
        force: &[f64],
        gamma_c: &[f64],
    ) -> Result<TreeAccelerations> {
        let (m_rr, m_fr, cut) = self.blocks(model, ws);
        let mut system = self.tree_system(&m_rr, &cut, st, force, gamma_c);
        let mut eliminated = Vec::with_capacity(self.bodies.len());
        for (b, m_fr) in self.bodies.iter().zip(&m_fr) {
            eliminated.push(self.eliminate_elastic(b, m_fr, force, st, &cut, &mut system)?);
        }
        let z = Self::solve_with_cut_rows(&system.a, &system.rhs, self.cut_start())?;
        Ok(self.decoupled_accelerations(st, &z, &eliminated))
    }

    /// Where the cut rows (mu) start in eq. 41: after q_dd_r, -F_r and p_dd.
    fn cut_start(&self) -> usize {
        2 * self.rows.len() + self.free_joints
    }

    /// Eq. 41 before the elastic accelerations are eliminated: M_rr, the identities and
    /// -H_pp between q_dd_r, -F_r and p_dd, the cut rows' C_r, and the right-hand side
    /// [Q_r; gamma_r; 0; gamma_c].
    fn tree_system(
        &self,
        m_rr: &Mat<f64>,
        cut: &[Vec<(usize, f64)>],
        st: &StructuredState,
        force: &[f64],
        gamma_c: &[f64],
    ) -> ReducedSystem {
        let nr = self.rows.len();
        let np = self.free_joints;
        let (y0, p0, c0) = (nr, 2 * nr, self.cut_start());
        let size = c0 + self.cut_rows.len();
        let mut a = Mat::<f64>::zeros(size, size);
        let mut rhs = vec![0.0; size];
        for i in 0..nr {
            for j in 0..nr {
                a[(i, j)] = m_rr[(i, j)];
            }
            a[(i, y0 + i)] = 1.0;
            a[(y0 + i, i)] = 1.0;
            rhs[i] = force[self.rows[i]];
            rhs[y0 + i] = st.gamma[self.rows[i]];
        }
        for i in 0..nr {
            for k in 0..np {
                a[(y0 + i, p0 + k)] = -st.joint_influence[(i, k)];
                a[(p0 + k, y0 + i)] = -st.joint_influence[(i, k)];
            }
        }
        // Cut rows: C_r.
        for (c, entries) in cut.iter().enumerate() {
            for &(q, v) in entries {
                let i = self.row_of[q];
                if i != usize::MAX {
                    a[(c0 + c, i)] += v;
                    a[(i, c0 + c)] += v;
                }
            }
            rhs[c0 + c] = gamma_c[c];
        }
        ReducedSystem { a, rhs }
    }

    /// Eliminates the elastic accelerations of body `b` (its M_fr `m_fr`, n x 7 column-major)
    /// from eq. 40 into `system`: X = M_ff^-1 [M_fr | Q_f], then the Schur complement's terms
    /// in the body's reference rows, in the -F_r rows through its markers and in the cut rows
    /// `cut` (entries per cut row, model coordinates).
    fn eliminate_elastic(
        &self,
        b: &ElasticBody,
        m_fr: &[f64],
        force: &[f64],
        st: &StructuredState,
        cut: &[Vec<(usize, f64)>],
        system: &mut ReducedSystem,
    ) -> Result<Elimination> {
        let n = b.n;
        let mut x = vec![0.0; 8 * n];
        x[..7 * n].copy_from_slice(m_fr);
        x[7 * n..].copy_from_slice(&force[b.first..b.first + n]);
        b.factor.solve_in_place(&mut x)?;
        subtract_reference_coupling(b, m_fr, &x, system);
        self.add_marker_terms(b, &x, st, system);
        let cut_solves =
            if cut.is_empty() { Vec::new() } else { self.add_cut_terms(b, &x, st, cut, system)? };
        Ok(Elimination { x, cut_solves })
    }

    /// The terms of body `b`'s markers in eq. 41 (X of the body: `x`): M_rf M_ff^-1 H_pf^T
    /// and its transpose, H_pf M_ff^-1 Q_f, and -H_pf M_ff^-1 H_pf^T over the pairs of its
    /// markers.
    fn add_marker_terms(&self, b: &ElasticBody, x: &[f64], st: &StructuredState, system: &mut ReducedSystem) {
        let (n, nr, r0) = (b.n, self.rows.len(), b.reference);
        let y0 = nr;
        let ReducedSystem { a, rhs } = system;
        // Markers: E_m = S_m X (6 x 8).
        for (mk, (index, _, shape)) in b.markers.iter().enumerate() {
            let d = &st.markers[*index];
            let e: Vec<[f64; 6]> = (0..8).map(|j| shape_times(shape, &x[j * n..(j + 1) * n])).collect();
            // M_rf M_ff^-1 H_pf^T (rows of the body) = E[:, :7]^T D^T, and its transpose.
            for i in 0..7 {
                for r in 0..nr {
                    let v: f64 = (0..6).map(|c| e[i][c] * d[(r, c)]).sum();
                    a[(r0 + i, y0 + r)] += v;
                    a[(y0 + r, r0 + i)] += v;
                }
            }
            // H_pf M_ff^-1 Q_f.
            for r in 0..nr {
                rhs[y0 + r] += (0..6).map(|c| d[(r, c)] * e[7][c]).sum::<f64>();
            }
            // -H_pf M_ff^-1 H_pf^T over the pairs of the body's markers.
            for (mk2, (index2, _, _)) in b.markers.iter().enumerate() {
                let d2 = &st.markers[*index2];
                let g = &b.couplings[mk * b.markers.len() + mk2];
                for r in 0..nr {
                    let dg: [f64; 6] = std::array::from_fn(|c2| (0..6).map(|c| d[(r, c)] * g[c][c2]).sum());
                    for s in 0..nr {
                        a[(y0 + r, y0 + s)] -= (0..6).map(|c2| dg[c2] * d2[(s, c2)]).sum::<f64>();
                    }
                }
            }
        }
    }

    /// The terms of the cut rows through body `b`'s elastic coordinates in eq. 41 (X of the
    /// body: `x`): -C_f X in the body's reference rows and the right-hand side, C_f W_m D_m^T
    /// in the -F_r columns, and -C_f M_ff^-1 C_f^T. Returns M_ff^-1 C_f^T per cut row (empty
    /// where the row does not reach the body).
    fn add_cut_terms(
        &self,
        b: &ElasticBody,
        x: &[f64],
        st: &StructuredState,
        cut: &[Vec<(usize, f64)>],
        system: &mut ReducedSystem,
    ) -> Result<Vec<Vec<f64>>> {
        let (n, nr, r0) = (b.n, self.rows.len(), b.reference);
        let (y0, c0) = (nr, self.cut_start());
        let ReducedSystem { a, rhs } = system;
        let mut cf_solves: Vec<Vec<f64>> = Vec::new();
        // C_f: the cut rows' entries on the body's elastic coordinates (body indices).
        let columns: Vec<Vec<(usize, f64)>> = cut
            .iter()
            .map(|e| {
                e.iter()
                    .filter(|(q, _)| (b.first..b.first + n).contains(q))
                    .map(|&(q, v)| (q - b.first, v))
                    .collect()
            })
            .collect();
        for (c, col) in columns.iter().enumerate() {
            if col.is_empty() {
                cf_solves.push(Vec::new());
                continue;
            }
            // V = C_f X (row c): 8 values.
            let v: Vec<f64> =
                (0..8).map(|j| col.iter().map(|&(f, w)| w * x[j * n + f]).sum::<f64>()).collect();
            for i in 0..7 {
                a[(c0 + c, r0 + i)] -= v[i];
                a[(r0 + i, c0 + c)] -= v[i];
            }
            rhs[c0 + c] -= v[7];
            // C_f W_m D_m^T (the y columns) and its transpose.
            for (index, w, _) in &b.markers {
                let d = &st.markers[*index];
                let cw: Vec<f64> =
                    (0..6).map(|k| col.iter().map(|&(f, wv)| wv * w[k * n + f]).sum::<f64>()).collect();
                for r in 0..nr {
                    let val: f64 = (0..6).map(|k| cw[k] * d[(r, k)]).sum();
                    a[(c0 + c, y0 + r)] += val;
                    a[(y0 + r, c0 + c)] += val;
                }
            }
            // M_ff^-1 C_f^T (column c).
            let mut z = vec![0.0; n];
            for &(f, w) in col {
                z[f] += w;
            }
            b.factor.solve_in_place(&mut z)?;
            cf_solves.push(z);
        }
        // -C_f M_ff^-1 C_f^T.
        for (c, z) in cf_solves.iter().enumerate() {
            if z.is_empty() {
                continue;
            }
            for (c2, col) in columns.iter().enumerate() {
                a[(c0 + c2, c0 + c)] -= col.iter().map(|&(f, w)| w * z[f]).sum::<f64>();
            }
        }
        Ok(cf_solves)
    }

    /// The accelerations from the solution `z` of eq. 41: q_dd_r, p_dd, -F_r and mu read
    /// off, the elastic accelerations of each body recovered from its `eliminated` solves
    /// (eq. 38b).
    fn decoupled_accelerations(
        &self,
        st: &StructuredState,
        z: &[f64],
        eliminated: &[Elimination],
    ) -> TreeAccelerations {
        let nr = self.rows.len();
        let np = self.free_joints;
        let (y0, p0, c0) = (nr, 2 * nr, self.cut_start());
        let nc = self.cut_rows.len();
        let mut qdd = st.gamma.clone();
        let mut free = vec![0.0; np + self.bodies.iter().map(|b| b.n).sum::<usize>()];
        free[..np].copy_from_slice(&z[p0..p0 + np]);
        for i in 0..nr {
            qdd[self.rows[i]] = z[i];
        }
        for (b, elimination) in self.bodies.iter().zip(eliminated) {
            let f = self.elastic_accelerations(b, elimination, st, z);
            qdd[b.first..b.first + b.n].copy_from_slice(&f);
            free[b.free_first..b.free_first + b.n].copy_from_slice(&f);
        }
        TreeAccelerations {
            accelerations: qdd,
            free_accelerations: free,
            reactions: z[y0..y0 + nr].to_vec(),
            cut_multipliers: z[c0..c0 + nc].to_vec(),
        }
    }

    /// Eq. 38b for body `b`: q_dd_f = M_ff^-1 (Q_f - M_fr q_dd_r + H_pf^T (-F_r) - C_f^T mu)
    /// from the solution `z` of eq. 41 and the body's `elimination` solves.
    fn elastic_accelerations(
        &self,
        b: &ElasticBody,
        elimination: &Elimination,
        st: &StructuredState,
        z: &[f64],
    ) -> Vec<f64> {
        let (n, nr, r0) = (b.n, self.rows.len(), b.reference);
        let (y0, c0) = (nr, self.cut_start());
        let x = &elimination.x;
        let mut f = x[7 * n..].to_vec();
        for j in 0..7 {
            let s = z[r0 + j];
            for (fi, xj) in f.iter_mut().zip(&x[j * n..(j + 1) * n]) {
                *fi -= xj * s;
            }
        }
        for (index, w, _) in &b.markers {
            let d = &st.markers[*index];
            for k in 0..6 {
                let s: f64 = (0..nr).map(|r| d[(r, k)] * z[y0 + r]).sum();
                for (fi, wk) in f.iter_mut().zip(&w[k * n..(k + 1) * n]) {
                    *fi += wk * s;
                }
            }
        }
        for (c, zc) in elimination.cut_solves.iter().enumerate() {
            if zc.is_empty() {
                continue;
            }
            let mu = z[c0 + c];
            for (fi, v) in f.iter_mut().zip(zc) {
                *fi -= v * mu;
            }
        }
        f
    }

    /// Solves the reduced system `a z = rhs` whose rows from `c0` on are the cut rows: LU of
    /// the tree block A_0 (regular), then the cut multipliers from their Schur complement
    /// S = E A_0^-1 E^T - D by a truncated SVD: at a singular configuration of a loop the cut
    /// rows become dependent and S singular, and the minimum-norm multipliers keep the
    /// accelerations (the joint-space solver's null-space method does the same with C B).
    fn solve_with_cut_rows(a: &Mat<f64>, rhs: &[f64], c0: usize) -> Result<Vec<f64>> {
        let size = rhs.len();
        let nc = size - c0;
        let context = "joint-coordinate accelerations (seed eq. 41)";
        // The tree block mixes units (masses, influence coefficients, inverse masses) and
        // its entries span many decades (a finely meshed link keeps little reference inertia
        // once its elastic coordinates are eliminated): it is equilibrated symmetrically,
        // D A_0 D with D_ii = max_j |A_0,ij|^-1/2, before the LU.
        let scale: Vec<f64> = (0..c0)
            .map(|i| {
                let m = (0..c0).fold(0.0f64, |m, j| m.max(a[(i, j)].abs()));
                if m > 0.0 {
                    1.0 / m.sqrt()
                } else {
                    1.0
                }
            })
            .collect();
        let a0 = Mat::from_fn(c0, c0, |i, j| scale[i] * a[(i, j)] * scale[j]);
        let lu = checked_lu_with(&a0, "the decoupled joint-elastic system (seed eq. 41)", TREE_PIVOT_RATIO)
            .map_err(|e| singular(context, e))?;
        let mut y =
            Mat::from_fn(c0, 1 + nc, |i, j| scale[i] * if j == 0 { rhs[i] } else { a[(i, c0 + j - 1)] });
        faer::linalg::solvers::Solve::solve_in_place(&lu, &mut y);
        for i in 0..c0 {
            for j in 0..=nc {
                y[(i, j)] *= scale[i];
            }
        }
        let mut z: Vec<f64> = (0..c0).map(|i| y[(i, 0)]).collect();
        if nc > 0 {
            let s = Mat::from_fn(nc, nc, |r, c| {
                (0..c0).map(|k| a[(c0 + r, k)] * y[(k, 1 + c)]).sum::<f64>() - a[(c0 + r, c0 + c)]
            });
            let g: Vec<f64> = (0..nc)
                .map(|r| (0..c0).map(|k| a[(c0 + r, k)] * y[(k, 0)]).sum::<f64>() - rhs[c0 + r])
                .collect();
            let mu = minimum_norm_solve(s.as_ref(), &g, SINGULAR_VALUE_CUTOFF);
            for (i, zi) in z.iter_mut().enumerate() {
                *zi -= (0..nc).map(|c| y[(i, 1 + c)] * mu[c]).sum::<f64>();
            }
            z.extend(mu);
        }
        Ok(z)
    }

    /// Eq. 40 (sparse LU): the matrix filled on its pattern, solved with equilibration, and
    /// the accelerations read off.
    fn coupled(
        &mut self,
        model: &Model,
        ws: &Workspace,
        st: &StructuredState,
        force: &[f64],
        gamma_c: &[f64],
    ) -> Result<TreeAccelerations> {
        let layout = self.coupled_layout();
        let nc = self.cut_rows.len();
        let mut rhs = vec![0.0; layout.c0 + nc];
        let system = self.coupled.as_mut().expect("eq. 40 system");
        system.values.iter_mut().for_each(|v| *v = 0.0);
        system.add_model_blocks(model, ws, force, layout.c0, &mut rhs);
        system.add_tree_blocks(&self.rows, self.free_joints, st, &layout, &mut rhs);
        system.add_elastic_influence(&self.bodies, self.rows.len(), st, &layout);
        rhs[layout.c0..layout.c0 + nc].copy_from_slice(gamma_c);
        system.solve_equilibrated(&mut rhs).map_err(|error| match error {
            // The sparse LU holds the cut rows' multipliers with the rest: dependent cut
            // equations (a redundant closure, a singular configuration of a loop) leave it
            // singular, where eq. 41 takes the minimum-norm multipliers.
            FlexmbdError::SingularMatrix { time, context, detail } if nc > 0 => {
                FlexmbdError::SingularMatrix {
                    time,
                    context,
                    detail: format!(
                        "{detail}; the cut joints' {nc} equations may be dependent (a redundant closure \
                     or a singular configuration of a loop), which eq. 40 cannot hold: \
                     formulation 'decoupled' (eq. 41) or 'joint-space' takes them"
                    ),
                }
            }
            other => other,
        })?;
        Ok(self.coupled_accelerations(st, &rhs, &layout))
    }

    /// The accelerations from the solution `z` of eq. 40 (unknowns at `layout`).
    fn coupled_accelerations(
        &self,
        st: &StructuredState,
        z: &[f64],
        layout: &CoupledLayout,
    ) -> TreeAccelerations {
        let nr = self.rows.len();
        let np = self.free_joints;
        let nf: usize = self.bodies.iter().map(|b| b.n).sum();
        let (y0, p0, c0) = (layout.y0, layout.p0, layout.c0);
        let nc = self.cut_rows.len();
        let mut qdd = st.gamma.clone();
        let mut free = vec![0.0; np + nf];
        free[..np].copy_from_slice(&z[p0..p0 + np]);
        for i in 0..nr {
            qdd[self.rows[i]] = z[i];
        }
        for (b, &o) in self.bodies.iter().zip(&layout.elastic) {
            qdd[b.first..b.first + b.n].copy_from_slice(&z[o..o + b.n]);
            free[b.free_first..b.free_first + b.n].copy_from_slice(&z[o..o + b.n]);
        }
        TreeAccelerations {
            accelerations: qdd,
            free_accelerations: free,
            reactions: z[y0..y0 + nr].to_vec(),
            cut_multipliers: z[c0..c0 + nc].to_vec(),
        }
    }
}

/// Rows of body `b`'s reference coordinates in eq. 41 (its M_fr `m_fr` and X `x`): M_rr -
/// M_rf X and Q_r - M_rf M_ff^-1 Q_f.
fn subtract_reference_coupling(b: &ElasticBody, m_fr: &[f64], x: &[f64], system: &mut ReducedSystem) {
    let (n, r0) = (b.n, b.reference);
    for i in 0..7 {
        let mi = &m_fr[i * n..(i + 1) * n];
        for j in 0..8 {
            let xj = &x[j * n..(j + 1) * n];
            let v: f64 = mi.iter().zip(xj).map(|(p, q)| p * q).sum();
            if j < 7 {
                system.a[(r0 + i, r0 + j)] -= v;
            } else {
                system.rhs[r0 + i] -= v;
            }
        }
    }
}

impl CoupledSystem {
    /// The unknowns, pattern and symbolic LU of eq. 40 for `solver`'s tree of `model`.
    fn new(model: &Model, solver: &TreeSolver) -> Result<CoupledSystem> {
        let mut unknown_of = solver.row_of.clone();
        let mut offset = solver.rows.len();
        for b in &solver.bodies {
            for (i, u) in unknown_of[b.first..b.first + b.n].iter_mut().enumerate() {
                *u = offset + i;
            }
            offset += b.n;
        }
        let mut cut_of = vec![usize::MAX; model.constraint_count];
        for (a, &r) in solver.cut_rows.iter().enumerate() {
            cut_of[r] = a;
        }
        let pattern = coupled_pattern(model, solver, &unknown_of, &cut_of);
        let lu = SparseLu::new(&pattern).map_err(|e| singular("eq. 40 (symbolic analysis)", e))?;
        let values = vec![0.0; pattern.nnz()];
        Ok(CoupledSystem { unknown_of, cut_of, pattern, lu, values })
    }

    /// The bodies' mass blocks (M restricted to each body) and the cut rows' Jacobian and its
    /// transpose (rows from `c0`) from the assembled values of `ws`; Q into `rhs`.
    fn add_model_blocks(&mut self, model: &Model, ws: &Workspace, force: &[f64], c0: usize, rhs: &mut [f64]) {
        let nq = model.coordinate_count;
        let mp = &model.layout.pattern;
        let CoupledSystem { unknown_of, cut_of, pattern, values, .. } = self;
        for c in 0..nq {
            let uc = unknown_of[c];
            if uc == usize::MAX {
                continue;
            }
            rhs[uc] = force[c];
            for k in mp.col_ptr[c]..mp.col_ptr[c + 1] {
                let r = mp.row_idx[k];
                let v = ws.values[k];
                if r < nq {
                    if unknown_of[r] != usize::MAX {
                        values[pattern.index(unknown_of[r], uc)] += v;
                    }
                } else if cut_of[r - nq] != usize::MAX {
                    let a = cut_of[r - nq];
                    values[pattern.index(c0 + a, uc)] += v;
                    values[pattern.index(uc, c0 + a)] += v;
                }
            }
        }
    }

    /// The identities between q_dd_r and -F_r, -H_pp and its transpose (`free_joints`
    /// columns of `st.joint_influence`), and gamma_r into `rhs`; `rows`: the reference rows.
    fn add_tree_blocks(
        &mut self,
        rows: &[usize],
        free_joints: usize,
        st: &StructuredState,
        layout: &CoupledLayout,
        rhs: &mut [f64],
    ) {
        let (y0, p0) = (layout.y0, layout.p0);
        let CoupledSystem { pattern, values, .. } = self;
        for i in 0..rows.len() {
            values[pattern.index(i, y0 + i)] += 1.0;
            values[pattern.index(y0 + i, i)] += 1.0;
            rhs[y0 + i] = st.gamma[rows[i]];
            for k in 0..free_joints {
                let h = st.joint_influence[(i, k)];
                values[pattern.index(y0 + i, p0 + k)] -= h;
                values[pattern.index(p0 + k, y0 + i)] -= h;
            }
        }
    }

    /// -H_pf = -sum D_m S_m over the `bodies`' markers in the -F_r rows (`nr` of them), and
    /// its transpose.
    fn add_elastic_influence(
        &mut self,
        bodies: &[ElasticBody],
        nr: usize,
        st: &StructuredState,
        layout: &CoupledLayout,
    ) {
        let y0 = layout.y0;
        let CoupledSystem { pattern, values, .. } = self;
        for (b, &o) in bodies.iter().zip(&layout.elastic) {
            for (index, _, shape) in &b.markers {
                let d = &st.markers[*index];
                for (j, &idx) in shape.indices.iter().enumerate() {
                    let col = o + idx;
                    for i in 0..nr {
                        let h: f64 = (0..3)
                            .map(|c| {
                                d[(i, c)] * shape.translation.get(c, j)
                                    + d[(i, 3 + c)] * shape.rotation.get(c, j)
                            })
                            .sum();
                        if h != 0.0 {
                            values[pattern.index(y0 + i, col)] -= h;
                            values[pattern.index(col, y0 + i)] -= h;
                        }
                    }
                }
            }
        }
    }

    /// Solves the filled system in place of `rhs` by the sparse LU of its symmetric
    /// equilibration D A D, D_ii = max_j |A_ij|^-1/2 (the values are left scaled).
    fn solve_equilibrated(&mut self, rhs: &mut [f64]) -> Result<()> {
        let context = "the loosely coupled joint-elastic system (seed eq. 40)";
        // Symmetric equilibration, D A D with D_ii = max_j |A_ij|^-1/2: the system mixes
        // nodal masses, identities and influence coefficients over many decades, and the
        // sparse LU's pivots lose accuracy on it unscaled (accelerations 7e-9 off relative
        // to the sparse augmented solution at 3000 elastic coordinates per link; 1.3e-9
        // scaled, where iterative refinement does not help further: the residual is at
        // round-off and the rest is the system's condition, which grows with the mesh).
        let CoupledSystem { pattern, lu, values, .. } = self;
        let size = rhs.len();
        let mut scale = vec![0.0f64; size];
        for c in 0..size {
            for k in pattern.col_ptr[c]..pattern.col_ptr[c + 1] {
                let v = values[k].abs();
                scale[c] = scale[c].max(v);
                scale[pattern.row_idx[k]] = scale[pattern.row_idx[k]].max(v);
            }
        }
        scale.iter_mut().for_each(|d| *d = if *d > 0.0 { 1.0 / d.sqrt() } else { 1.0 });
        for c in 0..size {
            for k in pattern.col_ptr[c]..pattern.col_ptr[c + 1] {
                values[k] *= scale[c] * scale[pattern.row_idx[k]];
            }
        }
        rhs.iter_mut().zip(&scale).for_each(|(x, d)| *x *= d);
        lu.factorize(values).map_err(|e| singular(context, e))?;
        lu.solve_in_place(rhs).map_err(|e| singular(context, e))?;
        rhs.iter_mut().zip(&scale).for_each(|(x, d)| *x *= d);
        Ok(())
    }
}

/// The sparsity pattern of eq. 40 for `solver`'s tree of `model`, with the unknown of each
/// model coordinate `unknown_of` and the position of each constraint row among the cut rows
/// `cut_of` (structural: every entry that can be non-zero).
fn coupled_pattern(
    model: &Model,
    solver: &TreeSolver,
    unknown_of: &[usize],
    cut_of: &[usize],
) -> SparsePattern {
    let nr = solver.rows.len();
    let CoupledLayout { elastic, y0, p0, c0 } = solver.coupled_layout();
    let mut pb = PatternBuilder::new(c0 + solver.cut_rows.len());
    // Mass blocks: the pattern of M restricted to each body.
    let pattern = &model.layout.pattern;
    let nq = model.coordinate_count;
    for c in 0..nq {
        let uc = unknown_of[c];
        if uc == usize::MAX {
            continue;
        }
        for k in pattern.col_ptr[c]..pattern.col_ptr[c + 1] {
            let r = pattern.row_idx[k];
            if r < nq {
                if unknown_of[r] != usize::MAX {
                    pb.add_entry(unknown_of[r], uc);
                }
            } else if cut_of[r - nq] != usize::MAX {
                let a = cut_of[r - nq];
                pb.add_entry(c0 + a, uc);
                pb.add_entry(uc, c0 + a);
            }
        }
    }
    for i in 0..nr {
        pb.add_entry(i, y0 + i);
        pb.add_entry(y0 + i, i);
    }
    // H_pp (dense over the reference rows) and H_pf (the rows the markers move, the
    // columns of their shapes).
    let joints: Vec<usize> = (p0..p0 + solver.free_joints).collect();
    let y_rows: Vec<usize> = (y0..y0 + nr).collect();
    pb.add_block(&y_rows, &joints);
    pb.add_block(&joints, &y_rows);
    for (b, &offset) in solver.bodies.iter().zip(&elastic) {
        for (_, _, shape) in &b.markers {
            let cols: Vec<usize> = shape.indices.iter().map(|&i| offset + i).collect();
            pb.add_block(&y_rows, &cols);
            pb.add_block(&cols, &y_rows);
        }
    }
    pb.build()
}
