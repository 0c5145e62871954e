//! The joint-space accelerations of a rigid tree with cut joints body by body, without the
//! dense matrices of the model's size: the influence coefficients B in blocks (for each body,
//! its rows and the free joint coordinates that move it: the joints between it and the ground),
//! M_t = B^T M B and B^T (f - M gamma_B) summed over the bodies' mass blocks, C_hat = C_cut B
//! from the cut joints' Jacobian entries in the workspace's sparse matrix, and the equations
//!
//! ```text
//! M_t p_dd + C_hat^T mu = B^T (f - M gamma_B),   C_hat p_dd = g_hat
//! ```
//!
//! by the range-space method: M_t = L L^T (envelope Cholesky: for a tree M_t couples only a
//! joint with those on its path to the ground), the Schur complement S = C_hat M_t^-1 C_hat^T
//! (cut rows coupled only through the bodies of one subtree of the ground), S mu =
//! C_hat M_t^-1 r - g_hat, p_dd = M_t^-1 (r - C_hat^T mu). The position and velocity
//! corrections of the cut joints take the minimum-norm solution C_hat^T (C_hat C_hat^T)^-1 r.
//!
//! This is exact where C_hat has full row rank, and equal there to the SVD of
//! [`super::LoopClosure`] when every singular value is above its damping band (mu = 1e-3 of the
//! largest): the damped inverse is then the inverse. [`SparseJointSpace::closure`] therefore
//! estimates the smallest singular value (inverse iteration on C_hat C_hat^T, whose Cholesky
//! factor it needs anyway) against a bound of the largest (sqrt(|C|_1 |C|_inf)); within
//! `REGULAR_MARGIN` of the band, with redundant cut equations or a factorization that fails,
//! the caller takes the dense path with the SVD (singular configurations, issue 30).

use super::kinematics::joint_pose;
use super::{Pose, Tree, LOOP_DAMPING};
use crate::linalg::envelope::{reverse_cuthill_mckee, EnvelopeCholesky};
use crate::math::hyper_dual::{euler_parameters, HyperDual};
use crate::system::{Model, Workspace};

/// The sparse path is taken where the estimated smallest singular value of C_hat is above this
/// factor times the damping band of [`super::LoopClosure`] (bounded from above): the estimate
/// comes from a few inverse iterations and is high where the smallest singular values cluster
/// (the singular values of A02's loops fall to about 2e-2 of the largest in regular
/// configurations, to within the band at its singular ones).
pub const REGULAR_MARGIN: f64 = 2.0;

/// The multipliers come from the normal equations where the estimated ratio of the smallest to
/// the largest singular value of C_q is above this (they lose its square in digits).
pub const MULTIPLIER_CONDITION: f64 = 1e-3;

/// Inverse iterations of the smallest singular value estimate.
const INVERSE_ITERATIONS: usize = 8;

/// A symmetric positive definite matrix of fixed pattern (lower triangle, CSC) with its
/// envelope Cholesky factor in reverse Cuthill-McKee order.
#[derive(Clone, Debug)]
struct Symmetric {
    ptr: Vec<usize>,
    idx: Vec<usize>,
    values: Vec<f64>,
    factor: EnvelopeCholesky,
    scratch: Vec<f64>,
}

impl Symmetric {
    /// The pattern of the entries `lower` (row >= column; the diagonal is added).
    fn new(n: usize, lower: &[(usize, usize)]) -> Self {
        let mut columns: Vec<Vec<usize>> = (0..n).map(|c| vec![c]).collect();
        for &(r, c) in lower {
            debug_assert!(r >= c);
            columns[c].push(r);
        }
        let mut ptr = vec![0];
        let mut idx = Vec::new();
        for mut rows in columns {
            rows.sort_unstable();
            rows.dedup();
            idx.extend(rows);
            ptr.push(idx.len());
        }
        let order = reverse_cuthill_mckee(n, &ptr, &idx);
        let factor = EnvelopeCholesky::new(n, &ptr, &idx, order);
        Symmetric { values: vec![0.0; idx.len()], ptr, idx, factor, scratch: vec![0.0; n] }
    }

    /// Index of entry (r, c), r >= c, in `values`.
    fn slot(&self, r: usize, c: usize) -> usize {
        let (r, c) = if r >= c { (r, c) } else { (c, r) };
        let rows = &self.idx[self.ptr[c]..self.ptr[c + 1]];
        self.ptr[c] + rows.binary_search(&r).expect("an entry of the pattern")
    }

    fn factorize(&mut self) -> bool {
        self.factor.factorize(&self.ptr, &self.idx, &self.values).is_ok()
    }

    fn solve(&mut self, x: &mut [f64]) {
        self.factor.solve(x, &mut self.scratch);
    }
}

/// Forms A A^T into `gram` (its pattern: the rows of A with a column in common) for the sparse
/// rows of A (`columns[a]`, `values[a]`; `width` columns), factorizes it and returns the
/// estimated ratio of the smallest singular value of A to a bound of the largest: the
/// smallest from `INVERSE_ITERATIONS` inverse iterations on A A^T (an estimate from above),
/// the largest bounded by sqrt(|A|_1 |A|_inf). None where the factorization fails.
fn gram_ratio(
    gram: &mut Symmetric,
    columns: &[Vec<usize>],
    values: &[Vec<f64>],
    width: usize,
) -> Option<f64> {
    let nc = columns.len();
    let mut dense = vec![0.0; width];
    let mut column_sums = vec![0.0; width];
    let mut row_norm_inf = 0.0f64;
    for (cols, vals) in columns.iter().zip(values) {
        row_norm_inf = row_norm_inf.max(vals.iter().map(|v| v.abs()).sum());
        for (&col, &v) in cols.iter().zip(vals) {
            column_sums[col] += v.abs();
        }
    }
    let largest_bound = (row_norm_inf * column_sums.iter().fold(0.0f64, |m, &v| m.max(v))).sqrt();
    for a in 0..nc {
        for (&col, &v) in columns[a].iter().zip(&values[a]) {
            dense[col] = v;
        }
        for k in gram.ptr[a]..gram.ptr[a + 1] {
            let b = gram.idx[k];
            gram.values[k] = columns[b].iter().zip(&values[b]).map(|(&col, &v)| dense[col] * v).sum();
        }
        for &col in &columns[a] {
            dense[col] = 0.0;
        }
    }
    if !(largest_bound > 0.0) || !gram.factorize() {
        return None;
    }
    // Inverse iteration from a vector of no special direction.
    let mut x: Vec<f64> = (0..nc).map(|i| 1.0 + 0.5 * ((i as f64) * 0.7548776662).fract()).collect();
    let norm = x.iter().map(|v| v * v).sum::<f64>().sqrt();
    x.iter_mut().for_each(|v| *v /= norm);
    let mut rayleigh = 0.0;
    for _ in 0..INVERSE_ITERATIONS {
        let mut y = x.clone();
        gram.solve(&mut y);
        rayleigh = x.iter().zip(&y).map(|(a, b)| a * b).sum::<f64>();
        let norm = y.iter().map(|v| v * v).sum::<f64>().sqrt();
        if !(norm.is_finite() && norm > 0.0) {
            return None;
        }
        x = y.into_iter().map(|v| v / norm).collect();
    }
    // rayleigh <= 1 / s_min^2.
    let smallest = (1.0 / rayleigh).sqrt();
    smallest.is_finite().then_some(smallest / largest_bound)
}

/// The influence coefficients B of a rigid tree in blocks: for each body (index 0, the
/// ground, empty), its rows x the free joint coordinates that move it (row-major).
#[derive(Clone, Debug, Default)]
pub struct BodyInfluence {
    blocks: Vec<Vec<f64>>,
}

/// The structure of the sparse joint-space evaluation of a rigid tree (fixed by the tree and
/// the model's pattern) and its buffers. See the module documentation.
#[derive(Clone, Debug)]
pub struct SparseJointSpace {
    /// Free joint coordinates.
    nf: usize,
    /// Per body: first row in q and count (0 for the ground).
    rows: Vec<(usize, usize)>,
    /// Per body: the free columns that move it, increasing.
    columns: Vec<Vec<usize>>,
    /// Per q row: its body.
    body_of_row: Vec<usize>,
    /// Per free column: its coordinate in the full p, the joints placed again when it moves
    /// (its joint and those beyond, in tree order), and the moved bodies with the position of
    /// the column in each one's `columns`.
    coordinate: Vec<usize>,
    joints: Vec<Vec<usize>>,
    moved: Vec<Vec<(usize, usize)>>,
    /// Per body: value indices of its mass block (row-major, usize::MAX where not stored).
    mass: Vec<Vec<usize>>,
    /// Value indices of the pattern's entries between the coordinates of two bodies (the
    /// Newton matrix's force and constraint Hessian blocks): zero at the acceleration level,
    /// or the dense path serves.
    coupling: Vec<usize>,
    /// Per body: the slots in `reduced` of the pairs of its columns (row-major, lower half
    /// used).
    reduced_slots: Vec<Vec<usize>>,
    /// Per cut row: (q column, value index) of its Jacobian entries, and its C_hat columns.
    cut_entries: Vec<Vec<(usize, usize)>>,
    cut_columns: Vec<Vec<usize>>,
    /// Cut rows of the model (constraint indices).
    cut_rows: Vec<usize>,
    /// Per constraint row: its Jacobian entries (q column, value index), the columns alone,
    /// and C_q C_q^T (for the multipliers).
    constraint_entries: Vec<Vec<(usize, usize)>>,
    constraint_columns: Vec<Vec<usize>>,
    constraint_gram: Symmetric,
    /// M_t, C_hat C_hat^T and S.
    reduced: Symmetric,
    gram: Symmetric,
    schur: Symmetric,
    /// C_hat rows (values over `cut_columns`) of the last [`SparseJointSpace::closure`].
    c_hat: Vec<Vec<f64>>,
    g_hat: Vec<f64>,
}

impl SparseJointSpace {
    /// The structure for `tree` in `model`; None where the tree has elastic coordinates (the
    /// dense path then serves).
    pub fn new(model: &Model, tree: &Tree) -> Option<Self> {
        if !tree.elastic.is_empty() {
            return None;
        }
        let nq = model.coordinate_count;
        let nb = tree.offsets.len();
        let rows: Vec<(usize, usize)> =
            (0..nb)
                .map(|b| {
                    if b == 0 {
                        (0, 0)
                    } else {
                        (tree.offsets[b], if tree.point_masses[b] { 3 } else { 7 })
                    }
                })
                .collect();
        let mut body_of_row = vec![usize::MAX; nq];
        for (b, &(o, count)) in rows.iter().enumerate() {
            for r in o..o + count {
                body_of_row[r] = b;
            }
        }
        if body_of_row.contains(&usize::MAX) {
            return None;
        }
        // Each free column moves its joint's child and the bodies beyond it.
        let nf = tree.free.len();
        let mut joints = Vec::with_capacity(nf);
        let mut moved_bodies = Vec::with_capacity(nf);
        let mut columns: Vec<Vec<usize>> = vec![Vec::new(); nb];
        for (k, &c) in tree.free.iter().enumerate() {
            let start = tree.joint_of_coordinate(c);
            let mut moved = vec![false; nb];
            let mut list = Vec::new();
            let mut bodies = Vec::new();
            for (j, joint) in tree.joints.iter().enumerate().skip(start) {
                if j == start || moved[joint.parent.body] {
                    moved[joint.child.body] = true;
                    list.push(j);
                    bodies.push(joint.child.body);
                    columns[joint.child.body].push(k);
                }
            }
            joints.push(list);
            moved_bodies.push(bodies);
        }
        let moved: Vec<Vec<(usize, usize)>> = moved_bodies
            .iter()
            .enumerate()
            .map(|(k, bodies)| {
                bodies
                    .iter()
                    .map(|&b| (b, columns[b].iter().position(|&x| x == k).expect("a column of the body")))
                    .collect()
            })
            .collect();
        // Mass blocks: M must not couple bodies.
        let pattern = &model.layout.pattern;
        let mut mass: Vec<Vec<usize>> = rows.iter().map(|&(_, n)| vec![usize::MAX; n * n]).collect();
        let mut cut_of = vec![usize::MAX; model.constraint_count];
        for (a, &r) in tree.cut_rows.iter().enumerate() {
            cut_of[r] = a;
        }
        let mut cut_entries: Vec<Vec<(usize, usize)>> = vec![Vec::new(); tree.cut_rows.len()];
        let mut coupling = Vec::new();
        let mut constraint_entries: Vec<Vec<(usize, usize)>> = vec![Vec::new(); model.constraint_count];
        for c in 0..nq {
            let b = body_of_row[c];
            for k in pattern.col_ptr[c]..pattern.col_ptr[c + 1] {
                let r = pattern.row_idx[k];
                if r < nq {
                    if body_of_row[r] != b {
                        coupling.push(k);
                        continue;
                    }
                    let o = rows[b].0;
                    mass[b][(r - o) * rows[b].1 + (c - o)] = k;
                } else {
                    constraint_entries[r - nq].push((c, k));
                    if cut_of[r - nq] != usize::MAX {
                        cut_entries[cut_of[r - nq]].push((c, k));
                    }
                }
            }
        }
        // M_t couples the columns that move one body.
        let mut lower = Vec::new();
        for cols in &columns {
            for &a in cols {
                for &b in cols {
                    if a >= b {
                        lower.push((a, b));
                    }
                }
            }
        }
        let reduced = Symmetric::new(nf, &lower);
        let reduced_slots = columns
            .iter()
            .map(|cols| {
                let r = &reduced;
                cols.iter().flat_map(|&a| cols.iter().map(move |&b| r.slot(a, b))).collect::<Vec<_>>()
            })
            .collect();
        let cut_columns: Vec<Vec<usize>> = cut_entries
            .iter()
            .map(|entries| {
                let mut cols: Vec<usize> =
                    entries.iter().flat_map(|&(c, _)| columns[body_of_row[c]].clone()).collect();
                cols.sort_unstable();
                cols.dedup();
                cols
            })
            .collect();
        // C_hat C_hat^T couples cut rows with a column in common; S those with columns in one
        // connected component of M_t's graph (M_t^-1 couples a component throughout).
        let mut component: Vec<usize> = (0..nf).collect();
        fn find(component: &mut [usize], mut x: usize) -> usize {
            while component[x] != x {
                component[x] = component[component[x]];
                x = component[x];
            }
            x
        }
        for &(a, b) in &lower {
            let (ra, rb) = (find(&mut component, a), find(&mut component, b));
            component[ra] = rb;
        }
        let nc = tree.cut_rows.len();
        let mut gram_lower = Vec::new();
        let mut schur_lower = Vec::new();
        let groups: Vec<Vec<usize>> = cut_columns
            .iter()
            .map(|cols| {
                let mut g: Vec<usize> = cols.iter().map(|&c| find(&mut component, c)).collect();
                g.sort_unstable();
                g.dedup();
                g
            })
            .collect();
        let shares = |x: &[usize], y: &[usize]| x.iter().any(|v| y.binary_search(v).is_ok());
        for a in 0..nc {
            for b in 0..a {
                if shares(&cut_columns[a], &cut_columns[b]) {
                    gram_lower.push((a, b));
                }
                if shares(&groups[a], &groups[b]) {
                    schur_lower.push((a, b));
                }
            }
        }
        // C_q C_q^T couples the rows with a coordinate in common.
        let mut rows_of_column: Vec<Vec<usize>> = vec![Vec::new(); nq];
        for (r, entries) in constraint_entries.iter().enumerate() {
            for &(c, _) in entries {
                rows_of_column[c].push(r);
            }
        }
        let mut constraint_lower = Vec::new();
        for list in &rows_of_column {
            for &a in list {
                for &b in list {
                    if a > b {
                        constraint_lower.push((a, b));
                    }
                }
            }
        }
        let constraint_columns: Vec<Vec<usize>> =
            constraint_entries.iter().map(|e| e.iter().map(|&(c, _)| c).collect()).collect();
        Some(SparseJointSpace {
            constraint_gram: Symmetric::new(model.constraint_count, &constraint_lower),
            constraint_columns,
            constraint_entries,
            nf,
            rows,
            columns,
            body_of_row,
            coordinate: tree.free.clone(),
            joints,
            moved,
            mass,
            coupling,
            reduced_slots,
            cut_entries,
            c_hat: cut_columns.iter().map(|c| vec![0.0; c.len()]).collect(),
            cut_columns,
            cut_rows: tree.cut_rows.clone(),
            reduced,
            gram: Symmetric::new(nc, &gram_lower),
            schur: Symmetric::new(nc, &schur_lower),
            g_hat: vec![0.0; nc],
        })
    }

    /// The influence coefficients at the full joint coordinates `full_p` (see
    /// [`Tree::full_coordinates`]): one hyper-dual pass per free coordinate over the bodies it
    /// moves.
    pub fn influence(&self, tree: &Tree, full_p: &[f64]) -> BodyInfluence {
        let mut ph: Vec<HyperDual> = full_p.iter().map(|&x| HyperDual::constant(x)).collect();
        let deformation = tree.deformations(&ph);
        let base: Vec<Pose> = tree.poses(&ph, &deformation);
        let mut poses = base.clone();
        let mut blocks: Vec<Vec<f64>> =
            self.rows.iter().zip(&self.columns).map(|(&(_, n), cols)| vec![0.0; n * cols.len()]).collect();
        for k in 0..self.nf {
            let c = self.coordinate[k];
            ph[c] = HyperDual::curve(full_p[c], 1.0, 0.0);
            for &j in &self.joints[k] {
                let joint = &tree.joints[j];
                poses[joint.child.body] = joint_pose(joint, &poses[joint.parent.body], &ph, &deformation[j]);
            }
            ph[c] = HyperDual::constant(full_p[c]);
            for &(b, position) in &self.moved[k] {
                let m = self.columns[b].len();
                let (a, r) = &poses[b];
                let block = &mut blocks[b];
                for i in 0..3 {
                    block[i * m + position] = r[i].e1;
                }
                if !tree.point_masses[b] {
                    let e = euler_parameters(a, &tree.reference_parameters[b]);
                    for i in 0..4 {
                        block[(3 + i) * m + position] = e[i].e1;
                    }
                }
                poses[b] = base[b];
            }
        }
        BodyInfluence { blocks }
    }

    /// q_dd = gamma_B + B p_dd.
    pub fn body_accelerations(
        &self,
        influence: &BodyInfluence,
        gamma_b: &[f64],
        pdd: &[f64],
        qdd: &mut [f64],
    ) {
        qdd.copy_from_slice(gamma_b);
        for (b, cols) in self.columns.iter().enumerate() {
            let (o, n) = self.rows[b];
            let block = &influence.blocks[b];
            for i in 0..n {
                qdd[o + i] +=
                    cols.iter().enumerate().map(|(a, &k)| block[i * cols.len() + a] * pdd[k]).sum::<f64>();
            }
        }
    }

    /// C_hat = C_cut B and g_hat = gamma_cut - C_cut `gamma_b` from the Jacobian entries in
    /// `ws` (and `gamma`, the model's, where given), then C_hat C_hat^T and its factor. Returns
    /// whether the cut equations are regular: a factor, and the estimated smallest singular
    /// value above `REGULAR_MARGIN` times the damping band of the largest.
    pub fn closure(
        &mut self,
        ws: &Workspace,
        influence: &BodyInfluence,
        gamma: Option<(&[f64], &[f64])>,
    ) -> bool {
        let nc = self.cut_rows.len();
        if nc == 0 {
            return true;
        }
        let mut dense = vec![0.0; self.nf];
        for a in 0..nc {
            let mut g = gamma.map_or(0.0, |(model_gamma, _)| model_gamma[self.cut_rows[a]]);
            for &(c, k) in &self.cut_entries[a] {
                let v = ws.values[k];
                let b = self.body_of_row[c];
                let (o, _) = self.rows[b];
                let cols = &self.columns[b];
                let block = &influence.blocks[b];
                for (i, &col) in cols.iter().enumerate() {
                    dense[col] += v * block[(c - o) * cols.len() + i];
                }
                if let Some((_, gamma_b)) = gamma {
                    g -= v * gamma_b[c];
                }
            }
            self.g_hat[a] = g;
            for (value, &col) in self.c_hat[a].iter_mut().zip(&self.cut_columns[a]) {
                *value = dense[col];
                dense[col] = 0.0;
            }
        }
        gram_ratio(&mut self.gram, &self.cut_columns, &self.c_hat, self.nf)
            .is_some_and(|ratio| ratio >= REGULAR_MARGIN * LOOP_DAMPING)
    }

    /// The minimum-norm solution of C_hat x = `r` after a regular [`Self::closure`].
    pub fn minimum_norm(&mut self, r: &[f64]) -> Vec<f64> {
        let mut y = r.to_vec();
        if !y.is_empty() {
            self.gram.solve(&mut y);
        }
        let mut x = vec![0.0; self.nf];
        for (a, ya) in y.iter().enumerate() {
            for (&col, &v) in self.cut_columns[a].iter().zip(&self.c_hat[a]) {
                x[col] += v * ya;
            }
        }
        x
    }

    /// The joint accelerations after a regular [`Self::closure`] with `gamma`: M_t and
    /// B^T (f - M gamma_B) from the mass blocks in `ws`, then the range-space solve (module
    /// documentation). None where M_t or S is not positive definite.
    pub fn accelerations(
        &mut self,
        ws: &Workspace,
        influence: &BodyInfluence,
        force: &[f64],
        gamma_b: &[f64],
    ) -> Option<Vec<f64>> {
        let nf = self.nf;
        if self.coupling.iter().any(|&k| ws.values[k] != 0.0) {
            return None;
        }
        self.reduced.values.iter_mut().for_each(|v| *v = 0.0);
        let mut rhs = vec![0.0; nf];
        let mut mb = Vec::new();
        let mut residual = Vec::new();
        for (b, cols) in self.columns.iter().enumerate() {
            let m = cols.len();
            if m == 0 {
                continue;
            }
            let n = self.rows[b].1;
            let o = self.rows[b].0;
            let block = &influence.blocks[b];
            let mass = |i: usize, j: usize| {
                let k = self.mass[b][i * n + j];
                if k == usize::MAX {
                    0.0
                } else {
                    ws.values[k]
                }
            };
            // M_b B_b (n x m) and f_b - M_b gamma_b.
            mb.clear();
            mb.resize(n * m, 0.0);
            residual.clear();
            for i in 0..n {
                let mut r = force[o + i];
                for j in 0..n {
                    let mij = mass(i, j);
                    if mij != 0.0 {
                        r -= mij * gamma_b[o + j];
                        for c in 0..m {
                            mb[i * m + c] += mij * block[j * m + c];
                        }
                    }
                }
                residual.push(r);
            }
            let slots = &self.reduced_slots[b];
            for a in 0..m {
                for c in 0..=a {
                    let v: f64 = (0..n).map(|i| block[i * m + a] * mb[i * m + c]).sum();
                    self.reduced.values[slots[a * m + c]] += v;
                }
                rhs[cols[a]] += (0..n).map(|i| block[i * m + a] * residual[i]).sum::<f64>();
            }
        }
        if !self.reduced.factorize() {
            return None;
        }
        let mut x = rhs;
        self.reduced.solve(&mut x);
        let nc = self.cut_rows.len();
        if nc == 0 {
            return Some(x);
        }
        // W = M_t^-1 C_hat^T by columns; S = C_hat W over its pattern.
        let mut w = vec![vec![0.0; nf]; nc];
        for a in 0..nc {
            for (&col, &v) in self.cut_columns[a].iter().zip(&self.c_hat[a]) {
                w[a][col] = v;
            }
            self.reduced.solve(&mut w[a]);
        }
        for a in 0..nc {
            for k in self.schur.ptr[a]..self.schur.ptr[a + 1] {
                let b = self.schur.idx[k];
                self.schur.values[k] =
                    self.cut_columns[b].iter().zip(&self.c_hat[b]).map(|(&col, &v)| w[a][col] * v).sum();
            }
        }
        if !self.schur.factorize() {
            return None;
        }
        let mut mu: Vec<f64> = (0..nc)
            .map(|a| {
                self.cut_columns[a].iter().zip(&self.c_hat[a]).map(|(&col, &v)| v * x[col]).sum::<f64>()
                    - self.g_hat[a]
            })
            .collect();
        self.schur.solve(&mut mu);
        for (a, &m) in mu.iter().enumerate() {
            for (xi, wi) in x.iter_mut().zip(&w[a]) {
                *xi -= m * wi;
            }
        }
        x.iter().all(|v| v.is_finite()).then_some(x)
    }

    /// The multipliers of all constraint rows, C_q^T lambda = f - M q_dd, in the least-squares
    /// sense by the normal equations (C_q C_q^T) lambda = C_q (f - M q_dd), from the values in
    /// `ws` (an acceleration-level assembly at the state of `qdd`): the minimum-norm solution
    /// of the dense path where C_q has full row rank. None where the estimated ratio of its
    /// smallest to its largest singular value is below `MULTIPLIER_CONDITION` (the normal
    /// equations would lose digits; the dense truncated SVD serves).
    pub fn multipliers(&mut self, ws: &Workspace, force: &[f64], qdd: &[f64]) -> Option<Vec<f64>> {
        if self.coupling.iter().any(|&k| ws.values[k] != 0.0) {
            return None;
        }
        let nq = force.len();
        let mut residual = force.to_vec();
        for (b, &(o, n)) in self.rows.iter().enumerate() {
            for i in 0..n {
                for j in 0..n {
                    let k = self.mass[b][i * n + j];
                    if k != usize::MAX {
                        residual[o + i] -= ws.values[k] * qdd[o + j];
                    }
                }
            }
        }
        let values: Vec<Vec<f64>> =
            self.constraint_entries.iter().map(|e| e.iter().map(|&(_, k)| ws.values[k]).collect()).collect();
        let ratio = gram_ratio(&mut self.constraint_gram, &self.constraint_columns, &values, nq)?;
        if ratio < MULTIPLIER_CONDITION {
            return None;
        }
        let mut lambda: Vec<f64> = self
            .constraint_columns
            .iter()
            .zip(&values)
            .map(|(cols, vals)| cols.iter().zip(vals).map(|(&c, &v)| v * residual[c]).sum())
            .collect();
        if !lambda.is_empty() {
            self.constraint_gram.solve(&mut lambda);
        }
        lambda.iter().all(|v| v.is_finite()).then_some(lambda)
    }

    /// C_cut q_dot + C_t of the cut rows from the Jacobian entries in `ws` and `rate` (the
    /// model's C_t).
    pub fn cut_velocity_violation(&self, ws: &Workspace, qd: &[f64], rate: &[f64]) -> Vec<f64> {
        self.cut_entries
            .iter()
            .zip(&self.cut_rows)
            .map(|(entries, &r)| entries.iter().map(|&(c, k)| ws.values[k] * qd[c]).sum::<f64>() + rate[r])
            .collect()
    }

    /// The dense B (n x free) of `influence`, for tests.
    #[cfg(test)]
    pub fn dense(&self, influence: &BodyInfluence, n: usize) -> faer::Mat<f64> {
        let mut b = faer::Mat::zeros(n, self.nf);
        for (body, cols) in self.columns.iter().enumerate() {
            let (o, rows) = self.rows[body];
            for i in 0..rows {
                for (a, &k) in cols.iter().enumerate() {
                    b[(o + i, k)] = influence.blocks[body][i * cols.len() + a];
                }
            }
        }
        b
    }
}
