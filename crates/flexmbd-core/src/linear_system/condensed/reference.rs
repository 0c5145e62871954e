//! The coupling of a condensed body with its own seven reference coordinates [R, p] in an
//! iteration matrix: its mass part and the velocity part of the undeformed body, as
//! combinations of kept vectors of n_f entries ([`ReferenceCoupling`]), with the solves of the
//! deformation part of the rotation coupling (kept while it changes little) and the block
//! N_JF Z of the reference rows and columns from small products.

use super::factor::{coupling_rows, BlockFactor, SYMMETRIC_PAIRS};
use super::kernels::{dots, subtract_combination};
use super::Block;
use crate::assembly::MatrixCoefficients;
use crate::body::flexible::{FlexibleBody, REFERENCE_COORDINATES};
use crate::error::Result;
use crate::math::Vec3;

/// A factorization keeps A^-1 dJ^T of the deformation part of the rotation coupling while dJ
/// differs from the one solved by at most this fraction of the row J_f0 + dJ (see
/// `reference_coupling`).
pub(super) const DEFORMATION_TOLERANCE: f64 = 1e-2;

/// The same with the coarse stage (`coarse`), which takes the rotation rows at q_f exactly:
/// the kept solves only make P, and the soft tet beam (benchmarks/soft_beam.py, Newton's
/// tolerance at 0.1 of the step's error) takes the same iterations per step with them kept
/// to 5e-2 or 0.2 as to 1e-2 (1k, 2 s: 2.03; 10k, 0.5 s: 2.12-2.13), with 1 instead of 21
/// solves of dJ (three solves each) in the first 0.5 s at 10k.
pub(super) const COARSE_DEFORMATION_TOLERANCE: f64 = 5e-2;

/// Numbers of the row and column vectors of [`ReferenceCoupling`].
pub(super) const ROW_VECTORS: usize = 16;
pub(super) const COLUMN_VECTORS: usize = 12;

/// The structured coupling of a condensed body with its seven reference coordinates
/// (`Block::reference_coupling`), as combinations of kept vectors of n_f entries whose
/// coefficients depend on the rotation and angular velocity only:
/// - the rows N_jF: on the row vectors U = [I1 (3), J_f (3), T, Ibar_kl (9)], with J_f the
///   rows of J_f0 + dJ (deformed) or J_f0, and T = S_00 + S_11 + S_22;
/// - the columns as eliminated N_Fj: on [I1 (3), J_f (3), S_kl (6)], and their solves
///   Z_j = A^-1 N_Fj on the column vectors V = A^-1 of the same.
///
/// A solve applies them as they are (U^T y: sixteen dot products, V (C x_ref): twelve vector
/// updates) instead of forming the seven rows and columns at every refresh of the iteration
/// matrix (195 multiply-adds per elastic coordinate, more than the solves' extra ones), and
/// the block N_JF Z of the reference rows and columns is R G C with the kept G = U^T V.
#[derive(Clone, Copy, Debug)]
pub(super) struct ReferenceCoupling {
    /// R: the coefficients of the rows of the reference coordinates (in the order of
    /// `Block::reference`) on the row vectors.
    pub(super) rows: [[f64; ROW_VECTORS]; 7],
    /// C: the coefficients of the columns on the column vectors, `columns[v][b]`.
    pub(super) columns: [[f64; 7]; COLUMN_VECTORS],
    /// Whether J_f is that of the deformed body (the factor's `deformed_rows`).
    pub(super) deformed: bool,
    /// The vectors with nonzero coefficients are the first `row_count` and `column_count`
    /// (6 each without the velocity part).
    pub(super) row_count: usize,
    pub(super) column_count: usize,
}

impl ReferenceCoupling {
    /// C x: the coefficients on the column vectors of the reference columns' values `x`.
    pub(super) fn combination(&self, x: &[f64; 7]) -> [f64; COLUMN_VECTORS] {
        std::array::from_fn(|v| self.columns[v].iter().zip(x).map(|(c, x)| c * x).sum())
    }

    /// The coefficients at the Euler parameters `p` and the body-frame angular velocity `w`,
    /// with sm = s m and sv = s v of the coefficients of the matrix; `deformed`: whether J_f is
    /// that of the deformed body.
    fn at(p: &[f64; 4], w: Vec3, sm: f64, sv: f64, deformed: bool) -> Self {
        let a = crate::math::euler::rotation_matrix(p);
        let l = crate::math::euler::l_matrix(p);
        // The velocity part of the rotation columns (the centrifugal coupling of the undeformed
        // body; the Coriolis part from qf_dot and the deformation are left out).
        let spinning = sm != 0.0 && sv != 0.0 && (w[0] != 0.0 || w[1] != 0.0 || w[2] != 0.0);
        let two_l: [[f64; 4]; 3] = std::array::from_fn(|i| std::array::from_fn(|k| 2.0 * l[i][k]));
        // The coefficients, zero without the mass term (then the coupling is left out).
        let (row_count, column_count) = match (sm != 0.0, spinning) {
            (false, _) => (0, 0),
            (true, false) => (6, 6),
            (true, true) => (ROW_VECTORS, COLUMN_VECTORS),
        };
        let mut coupling = ReferenceCoupling {
            rows: [[0.0; ROW_VECTORS]; 7],
            columns: [[0.0; 7]; COLUMN_VECTORS],
            deformed,
            row_count,
            column_count,
        };
        // Columns R_k: s m A^-1 I1^T A^T e_k; columns p_c: s m A^-1 J_f^T 2L e_c and the
        // centrifugal part s v sum_m dfw_m (2 L)_mc on the six S_kl; the rows N_jF are their
        // transposes, with the velocity parts of the rows: (R, f) = A 2 w~ I1 (on the rows of
        // I1), and (p, f) = 2 L^T r with r_l = s v (w_l T - 2 sum_k w_k Ibar_kl) (undeformed).
        // Without the rows' velocity part the error operator of the iteration, though of about
        // the same spectral radius, is far from normal (the norm of its coordinate block 0.1
        // against 5.6e-3 with it: 1k pendulum bar at 5 rad/s, dense matrices), and the first
        // iteration of a step, from the predictor, contracts that much less.
        if sm != 0.0 {
            let aw = a.mul_mat(&w.skew());
            for o in 0..3 {
                for v in 0..3 {
                    coupling.columns[v][o] = sm * a.0[o][v];
                    coupling.rows[o][v] = sm * a.0[o][v] + if spinning { 2.0 * sv * aw.0[o][v] } else { 0.0 };
                }
            }
            for o in 0..4 {
                for v in 0..3 {
                    coupling.columns[3 + v][3 + o] = sm * two_l[v][o];
                    coupling.rows[3 + o][3 + v] = sm * two_l[v][o];
                }
            }
        }
        if spinning {
            for o in 0..4 {
                for (slot, g) in centrifugal_weights(&w, &two_l, o).into_iter().enumerate() {
                    coupling.columns[6 + slot][3 + o] = sv * g;
                }
                coupling.rows[3 + o][6] = (0..3).map(|k| two_l[k][o] * sv * w[k]).sum();
                for k in 0..3 {
                    for lr in 0..3 {
                        coupling.rows[3 + o][7 + 3 * k + lr] = -2.0 * sv * w[k] * two_l[lr][o];
                    }
                }
            }
        }
        coupling
    }
}

/// Row vector k of [`ReferenceCoupling`] (`rows`: `Block::reference_rows`, m = n_f).
pub(super) fn row_vector<'a>(
    rows: &'a [f64],
    factor: &'a BlockFactor,
    deformed: bool,
    m: usize,
    k: usize,
) -> &'a [f64] {
    match k {
        3..6 if deformed => &factor.deformed_rows[(k - 3) * m..(k - 2) * m],
        0..6 => &rows[k * m..(k + 1) * m],
        _ => &rows[(k + 6) * m..(k + 7) * m],
    }
}

/// Column vector v of [`ReferenceCoupling`]: A^-1 of the column as eliminated.
pub(super) fn column_vector(factor: &BlockFactor, deformed: bool, m: usize, v: usize) -> &[f64] {
    match v {
        3..6 if deformed => &factor.deformed_solved[(v - 3) * m..(v - 2) * m],
        _ => &factor.influence[v * m..(v + 1) * m],
    }
}

/// Column v as eliminated of [`ReferenceCoupling`] (the rows of `coupling_rows`, or J_f0 + dJ).
pub(super) fn eliminated_vector<'a>(
    rows: &'a [f64],
    factor: &'a BlockFactor,
    deformed: bool,
    m: usize,
    v: usize,
) -> &'a [f64] {
    match v {
        3..6 if deformed => &factor.deformed_rows[(v - 3) * m..(v - 2) * m],
        _ => &rows[v * m..(v + 1) * m],
    }
}

/// Coefficients over the S_kl of [`SYMMETRIC_PAIRS`] of the velocity part of the coupling
/// column of p_c of the undeformed body: sum_m dfw_m (2 L)_mc, with the derivative of the
/// elastic rows' inertia force by the angular velocity w,
/// dfw_m = sum_(k != m) (w_k S_km - w_m S_kk) (`body::flexible`'s velocity (f, p) block at
/// q_f = 0, qf_dot = 0).
fn centrifugal_weights(w: &Vec3, two_l: &[[f64; 4]; 3], col: usize) -> [f64; 6] {
    let mut g = [0.0; 6];
    for (slot, &(k, l)) in SYMMETRIC_PAIRS.iter().enumerate() {
        g[slot] = if k == l {
            -(0..3).filter(|&m| m != k).map(|m| w[m] * two_l[m][col]).sum::<f64>()
        } else {
            w[k] * two_l[l][col] + w[l] * two_l[k][col]
        };
    }
    g
}

impl Block {
    /// The coupling of the reference coordinates from their mass and velocity parts (see
    /// `factorize`), at the body coordinates `qb`, as the coefficients of a
    /// [`ReferenceCoupling`] (in `structured`, with its block N_JF Z of the reference rows and
    /// columns returned), or formed in `z`, `w` and `row_values` when the reference rows are
    /// not dense (None returned, `structured` None). The rotation coupling is that of the
    /// deformed body, J_f = J_f0 + dJ(q_f) with dJ_i^T = -(I_jk - I_kj) q_f: the undeformed J_f0
    /// alone errs by dJ, which is not small where J_f0 is (a slender beam about its own axis),
    /// and made the modified Newton iteration diverge at every step size (a modal beam hinged
    /// at a node). Its solves take three solves (A^-1 dJ^T, packed) when q_f != 0, which a
    /// factorization keeps for later refreshes while dJ moves by at most the block's
    /// `deformation_tolerance` of J_f: `DEFORMATION_TOLERANCE`, or
    /// `COARSE_DEFORMATION_TOLERANCE` with the coarse stage. The coupling of an iteration
    /// matrix is then as at the deformation of the solves, off by that fraction at most (a
    /// pendulum bar of solids changes dJ by 0.1-0.3 % of J_f between refreshes and needs the
    /// solves once).
    pub(super) fn reference_coupling(
        &mut self,
        fb: &FlexibleBody,
        c: &MatrixCoefficients,
        qb: &[f64],
    ) -> Result<Option<[[f64; 7]; 7]>> {
        let m = self.n;
        let sm = c.scale * c.mass;
        let qf = &qb[REFERENCE_COORDINATES..REFERENCE_COORDINATES + m];
        if self.reference_rows.is_empty() {
            self.make_reference_rows(fb);
        }
        let deformed = sm != 0.0 && qf.iter().any(|&x| x != 0.0);
        if deformed {
            self.update_deformation_solves(fb, qf)?;
        }
        let p = [qb[3], qb[4], qb[5], qb[6]];
        let coupling = ReferenceCoupling::at(&p, self.angular_velocity, sm, c.scale * c.velocity, deformed);
        if !self.apply_kept || !self.reference.iter().all(|&j| self.dense_rows[j]) {
            self.structured = None;
            self.form_reference(&coupling);
            return Ok(None);
        }
        self.structured = Some(coupling);
        Ok(Some(self.reference_schur_block(&coupling)))
    }

    /// The row vectors of the body kept for the structured coupling (`reference_rows`): the
    /// twelve `coupling_rows`, T = S_00 + S_11 + S_22 and the nine Ibar_kl.
    fn make_reference_rows(&mut self, fb: &FlexibleBody) {
        let m = self.n;
        self.reference_rows = (0..12).flat_map(|i| coupling_rows(fb, i)).collect();
        let s_kk = |k: usize| &self.reference_rows[(6 + k) * m..(7 + k) * m];
        let trace: Vec<f64> = (0..m).map(|f| s_kk(0)[f] + s_kk(1)[f] + s_kk(2)[f]).collect();
        self.reference_rows.extend(trace);
        self.reference_rows.extend_from_slice(&fb.ibar[..9 * m]);
    }

    /// Makes the current factor's solves of dJ_i^T, i = 0..3, at q_f = `qf` (nonzero), unless
    /// the kept ones are within the tolerance. Since dJ is linear in q_f,
    /// |dJ_i(q_f) - dJ_i(q_kept)| <= b |q_f - q_kept| with b a bound of the norms of the
    /// antisymmetric matrices (`FlexibleBody::antisymmetric_norm_bound`); with r the smallest
    /// row norm |J_f0 + dJ| at the kept deformation, d (1 + tol) <= tol r for
    /// d = b |q_f - q_kept| implies the test (|J_f0 + dJ(q_f)| >= r - d) without forming
    /// dJ(q_f), a product with the mass matrix (about a third of a refresh of the 1k pendulum
    /// bar); else dJ is formed and compared with the kept one row by row.
    fn update_deformation_solves(&mut self, fb: &FlexibleBody, qf: &[f64]) -> Result<()> {
        let m = self.n;
        if self.antisymmetric_bound.is_none() {
            self.antisymmetric_bound = Some(fb.antisymmetric_norm_bound());
        }
        let bound = self.antisymmetric_bound.unwrap_or(f64::INFINITY);
        let factor = &mut self.factors[self.current];
        let tolerance = self.deformation_tolerance;
        if factor.deformation_is_near(qf, bound, tolerance) {
            return Ok(());
        }
        self.deformation.resize(3 * m, 0.0);
        self.deformation.iter_mut().for_each(|x| *x = 0.0);
        fb.add_antisymmetric_products(-1.0, qf, &mut self.deformation);
        let rows = &self.reference_rows[3 * m..6 * m];
        if factor.keeps_deformation(&self.deformation, rows, m, tolerance) {
            return Ok(());
        }
        factor.solve_deformation(&self.deformation, rows, qf, m)
    }

    /// The block N_JF Z of the reference rows and columns, R G C: no pass over the
    /// n_f-vectors but when G is made.
    fn reference_schur_block(&mut self, coupling: &ReferenceCoupling) -> [[f64; 7]; 7] {
        let m = self.n;
        let factor = &mut self.factors[self.current];
        if factor.gram.is_empty() || factor.gram_deformed != coupling.deformed {
            factor.make_gram(&self.reference_rows, coupling.deformed, m);
        }
        // (R G) C, rows of R G first.
        let mut block = [[0.0; 7]; 7];
        for (ra, out) in coupling.rows.iter().zip(block.iter_mut()) {
            let mut rg = [0.0; COLUMN_VECTORS];
            for (&rk, g) in ra.iter().zip(factor.gram.chunks_exact(COLUMN_VECTORS)) {
                if rk != 0.0 {
                    rg.iter_mut().zip(g).for_each(|(x, gv)| *x += rk * gv);
                }
            }
            for (b, o) in out.iter_mut().enumerate() {
                *o = rg.iter().zip(&coupling.columns).map(|(x, col)| x * col[b]).sum();
            }
        }
        block
    }

    /// Forms the columns Z and W (as eliminated, with `keep_image`) and the rows N_jF of the
    /// reference coordinates from the coefficients of `coupling` (the rows at their entries).
    pub(super) fn form_reference(&mut self, coupling: &ReferenceCoupling) {
        let m = self.n;
        let (rows, factor, deformed) = (&self.reference_rows, &self.factors[self.current], coupling.deformed);
        for (b, &j) in self.reference.iter().enumerate() {
            let z = &mut self.z[j * m..(j + 1) * m];
            z.iter_mut().for_each(|x| *x = 0.0);
            let x: [f64; COLUMN_VECTORS] = std::array::from_fn(|v| -coupling.columns[v][b]);
            subtract_combination(z, coupling.column_count, |v| column_vector(factor, deformed, m, v), &x);
            if let Some(w) = self.w.get_mut(j * m..(j + 1) * m) {
                w.iter_mut().for_each(|x| *x = 0.0);
                subtract_combination(
                    w,
                    coupling.column_count,
                    |v| eliminated_vector(rows, factor, deformed, m, v),
                    &x,
                );
            }
            let row = &mut self.row_values[j];
            for (&(f, _), r) in self.row_entries[j].iter().zip(row.iter_mut()) {
                *r = (0..coupling.row_count)
                    .map(|k| coupling.rows[b][k] * row_vector(rows, factor, deformed, m, k)[f])
                    .sum();
            }
        }
    }
}

/// |J_f0 + dJ| of row `i` (m = n_f) from the rows of dJ^T (`deformation`) and J_f0 (`rows`).
fn deformed_row_norm(deformation: &[f64], rows: &[f64], i: usize, m: usize) -> f64 {
    deformation[i * m..(i + 1) * m]
        .iter()
        .zip(&rows[i * m..])
        .map(|(x, y)| (x + y) * (x + y))
        .sum::<f64>()
        .sqrt()
}

impl BlockFactor {
    /// Whether the kept solves of dJ serve q_f = `qf` by the bound alone: d (1 + tol) <= tol r
    /// with d = `bound` |q_f - q_kept| (see `Block::update_deformation_solves`).
    fn deformation_is_near(&self, qf: &[f64], bound: f64, tolerance: f64) -> bool {
        !self.deformation.is_empty() && {
            let d2: f64 = qf.iter().zip(&self.deformation_at).map(|(x, y)| (x - y) * (x - y)).sum();
            let d = bound * d2.sqrt();
            d * (1.0 + tolerance) <= tolerance * self.deformation_rows
        }
    }

    /// Whether the kept dJ^T is within `tolerance` of `deformation` (dJ^T, 3 n_f) in every
    /// row, relative to the row J_f0 + dJ (`rows`: J_f0, 3 n_f).
    fn keeps_deformation(&self, deformation: &[f64], rows: &[f64], m: usize, tolerance: f64) -> bool {
        !self.deformation.is_empty()
            && (0..3).all(|i| {
                let (new, old) = (&deformation[i * m..(i + 1) * m], &self.deformation[i * m..(i + 1) * m]);
                let change: f64 = new.iter().zip(old).map(|(x, y)| (x - y) * (x - y)).sum();
                change.sqrt() <= tolerance * deformed_row_norm(deformation, rows, i, m)
            })
    }

    /// Solves dJ^T (`deformation`, at q_f = `qf`) and keeps it with the deformed rows
    /// J_f0 + dJ (`rows`: J_f0), their solves and their smallest norm; G is made again.
    fn solve_deformation(&mut self, deformation: &[f64], rows: &[f64], qf: &[f64], m: usize) -> Result<()> {
        let mut solved = deformation.to_vec();
        self.solve_in_place(&mut solved)?;
        self.deformation.clear();
        self.deformation.extend_from_slice(deformation);
        self.deformed_rows = rows.iter().zip(&self.deformation).map(|(x, d)| x + d).collect();
        self.deformed_solved = self.influence[3 * m..6 * m].iter().zip(&solved).map(|(x, d)| x + d).collect();
        self.deformation_at.clear();
        self.deformation_at.extend_from_slice(qf);
        self.deformation_rows =
            (0..3).map(|i| deformed_row_norm(&self.deformation, rows, i, m)).fold(f64::INFINITY, f64::min);
        self.gram.clear();
        Ok(())
    }

    /// G = U^T V of the row vectors U and the column vectors V of the structured coupling
    /// (`rows`: `Block::reference_rows`, m = n_f; with J_f of the deformed body or not).
    fn make_gram(&mut self, rows: &[f64], deformed: bool, m: usize) {
        let mut gram = vec![0.0; ROW_VECTORS * COLUMN_VECTORS];
        for (k, g) in gram.chunks_exact_mut(COLUMN_VECTORS).enumerate() {
            let u = row_vector(rows, self, deformed, m, k);
            let sums: [f64; COLUMN_VECTORS] =
                dots(COLUMN_VECTORS, |v| column_vector(self, deformed, m, v), u);
            g.copy_from_slice(&sums);
        }
        self.gram = gram;
        self.gram_deformed = deformed;
        self.antisymmetric_gram.clear();
    }
}
