//! A coarse stage after the condensed solves of an iteration matrix, for soft bodies (switched
//! on by the integrator, `CondensedSolver::set_gyroscopic`). The condensed matrix P leaves out
//! of the elastic rows the gyroscopic block G = s gamma' 2 int rho S^T w~ S, skew-symmetric,
//! which the Cholesky factor of A cannot hold; small against A, it is amplified in a soft
//! body's iteration by the nearly singular coupling of the frame's rotation with the elastic
//! coordinates into one slow pair of eigenvalues (benchmarks/README.md, "Soft bodies"). So
//! does the difference between the rotation rows J_f = J_f0 + dJ(q_f) at q_f and those of the
//! kept solves of dJ. After x0 = P^-1 b, a Galerkin correction with N' = P + G + that
//! difference on the space V of the reduced unknowns and, per body, the six kept vectors
//! A^-1 [I1^T, J_f^T] (the first column vectors of the structured coupling):
//!   x = x0 + V C^-1 V^T (b - N' x0),  C = V^T N' V,
//! where b - N' x0 = (P - N') x0 needs nine dot products with rows made at each factorization
//! (the rotation rows' difference, and V_u^T G from the products A_i V_u kept with the
//! factor), no solve with A. C is dense (the reduced size plus six per body, at most
//! `LIMIT`; beyond, no stage) and made at each factorization from the kept products G = U^T V
//! of the structured coupling and V_u^T A_i V_v, kept with the factor.

use super::kernels::subtract_combination;
use super::reference::column_vector;
use super::{flexible, CondensedSolver};
use crate::system::model::Model;

/// Vectors per body.
const PER_BODY: usize = 6;
/// Largest coarse system (dense LU at each factorization).
const LIMIT: usize = 96;

/// The factorized coarse system (dense LU with partial pivoting, column-major).
#[derive(Debug, Default)]
pub(super) struct Coarse {
    size: usize,
    lu: Vec<f64>,
    pivots: Vec<usize>,
    /// Per body, the rows of its part of the residual (P - N') x0.
    rows: Vec<BodyRows>,
    /// Scratch of the coarse unknowns.
    scratch: Vec<f64>,
}

/// The rows of one body's part of the coarse stage's residual.
#[derive(Debug, Default)]
struct BodyRows {
    /// The rotation rows at q_f less those of the kept solves, dJ(q_f) - dJ(kept) (3 n).
    difference: Vec<f64>,
    /// Their products with the six vectors V_u (3 x 6).
    dots: [[f64; PER_BODY]; 3],
    /// R_u (6 n) with R_u^T x = V_u^T G x.
    gyroscopic: Vec<f64>,
}

impl Coarse {
    fn factorize(size: usize, mut a: Vec<f64>) -> Option<Self> {
        let mut pivots = vec![0; size];
        for k in 0..size {
            let (p, big) =
                (k..size)
                    .map(|i| (i, a[k * size + i].abs()))
                    .fold((k, -1.0), |b, x| if x.1 > b.1 { x } else { b });
            if big == 0.0 || !big.is_finite() {
                return None;
            }
            pivots[k] = p;
            if p != k {
                for c in 0..size {
                    a.swap(c * size + k, c * size + p);
                }
            }
            let d = a[k * size + k];
            for i in k + 1..size {
                a[k * size + i] /= d;
            }
            for c in k + 1..size {
                let f = a[c * size + k];
                if f != 0.0 {
                    for i in k + 1..size {
                        a[c * size + i] -= f * a[k * size + i];
                    }
                }
            }
        }
        Some(Coarse { size, lu: a, pivots, rows: Vec::new(), scratch: Vec::new() })
    }

    fn solve(&self, x: &mut [f64]) {
        let n = self.size;
        // The row interchanges first: `factorize` swaps whole rows, the columns of L made
        // before included (P A = L U), so that a forward substitution interleaved with them
        // would pair a row of L with another row of x.
        for k in 0..n {
            x.swap(k, self.pivots[k]);
        }
        for k in 0..n {
            let xk = x[k];
            for i in k + 1..n {
                x[i] -= self.lu[k * n + i] * xk;
            }
        }
        for k in (0..n).rev() {
            x[k] /= self.lu[k * n + k];
            let xk = x[k];
            for i in 0..k {
                x[i] -= self.lu[k * n + i] * xk;
            }
        }
    }
}

impl CondensedSolver {
    /// Makes the coarse system at a factorization (`values`: the assembled global values;
    /// `reduced`: the reduced values before the Schur update), or none when a body's reference
    /// coupling is not structured or the system would be too large.
    pub(super) fn make_coarse(&mut self, model: &Model, values: &[f64], reduced: &[f64], q: &[f64]) {
        self.coarse = None;
        let r = self.global_of.len();
        let size = r + PER_BODY * self.blocks.len();
        if size > LIMIT || self.blocks.iter().any(|b| b.structured.is_none()) {
            return;
        }
        let mut c = vec![0.0; size * size];
        let at = |row: usize, col: usize| col * size + row;
        let pattern = &self.reduced_pattern;
        for col in 0..r {
            for k in pattern.col_ptr[col]..pattern.col_ptr[col + 1] {
                c[at(pattern.row_idx[k], col)] = reduced[k];
            }
        }
        let mut differences = Vec::new();
        for b in 0..self.blocks.len() {
            let o = r + PER_BODY * b;
            // The rotation rows at this q_f against those of the kept solves.
            let difference = {
                let block = &self.blocks[b];
                let n = block.n;
                let fb = flexible(model, block.body);
                let start = model.bodies[block.body].offset + crate::body::flexible::REFERENCE_COORDINATES;
                let mut exact = vec![0.0; 3 * n];
                fb.add_antisymmetric_products(-1.0, &q[start..start + n], &mut exact);
                let rc = block.structured.expect("structured");
                let factor = &block.factors[block.current];
                for i in 0..3 {
                    let kept =
                        super::reference::row_vector(&block.reference_rows, factor, rc.deformed, n, 3 + i);
                    let j0 = &block.reference_rows[(3 + i) * n..(4 + i) * n];
                    for ((e, k), z) in exact[i * n..(i + 1) * n].iter_mut().zip(kept).zip(j0) {
                        *e += z - k;
                    }
                }
                let mut dots = [[0.0; PER_BODY]; 3];
                for (i, row) in dots.iter_mut().enumerate() {
                    let sums: [f64; 8] = dots_of(
                        PER_BODY,
                        |u| column_vector(factor, rc.deformed, n, u),
                        &exact[i * n..(i + 1) * n],
                    );
                    row.copy_from_slice(&sums[..PER_BODY]);
                }
                (exact, dots)
            };
            // The products V_u^T A_i V_v, kept with the factor while its vectors stay.
            {
                let block = &mut self.blocks[b];
                let rc = block.structured.expect("structured");
                let n = block.n;
                let fb = flexible(model, block.body);
                let factor = &mut block.factors[block.current];
                if factor.antisymmetric_gram.is_empty() {
                    let mut products = vec![0.0; 3 * n];
                    let mut kept = vec![0.0; 3 * PER_BODY * PER_BODY];
                    let mut images = vec![0.0; 3 * PER_BODY * n];

                    for v in 0..PER_BODY {
                        products.iter_mut().for_each(|x| *x = 0.0);
                        fb.add_antisymmetric_products(
                            1.0,
                            column_vector(factor, rc.deformed, n, v),
                            &mut products,
                        );
                        for i in 0..3 {
                            images[(i * PER_BODY + v) * n..(i * PER_BODY + v + 1) * n]
                                .copy_from_slice(&products[i * n..(i + 1) * n]);
                            let sums: [f64; 8] = dots_of(
                                PER_BODY,
                                |u| column_vector(factor, rc.deformed, n, u),
                                &products[i * n..(i + 1) * n],
                            );
                            for (u, &sum) in sums[..PER_BODY].iter().enumerate() {
                                kept[(i * PER_BODY + u) * PER_BODY + v] = sum;
                            }
                        }
                    }
                    factor.antisymmetric_gram = kept;
                    factor.antisymmetric_images = images;
                }
            }
            let block = &self.blocks[b];
            let rc = block.structured.expect("structured");
            let (m, factor) = (block.n, &block.factors[block.current]);
            let gram = &factor.gram;
            let g = |k: usize, v: usize| gram[k * super::reference::COLUMN_VECTORS + v];
            let vf = |u: usize| column_vector(factor, rc.deformed, m, u);
            for (j, &gj) in block.coupling.iter().enumerate() {
                let rj = self.reduced_of[gj];
                if let Some(a) = block.reference.iter().position(|&x| x == j) {
                    for u in 0..PER_BODY {
                        // Row: sum_k R[a][k] U_k . V_u.
                        let d = &difference.1;
                        c[at(rj, o + u)] = (0..rc.row_count).map(|k| rc.rows[a][k] * g(k, u)).sum::<f64>()
                            + (0..3).map(|i| rc.rows[a][3 + i] * d[i][u]).sum::<f64>();
                        // Column: sum_v C[v][a] E_v . V_u.
                        c[at(o + u, rj)] = (0..rc.column_count)
                            .map(|v| rc.columns[v][a] * if v < PER_BODY { g(v, u) } else { g(u, v) })
                            .sum::<f64>()
                            + (0..3).map(|i| rc.columns[3 + i][a] * d[i][u]).sum::<f64>();
                    }
                } else {
                    for u in 0..PER_BODY {
                        let x = vf(u);
                        let row: f64 = block.row_entries[j]
                            .iter()
                            .zip(&block.row_values[j])
                            .map(|(&(f, _), v)| v * x[f])
                            .sum();
                        let col: f64 = block.column_entries[j].iter().map(|&(f, k)| values[k] * x[f]).sum();
                        c[at(rj, o + u)] = row;
                        c[at(o + u, rj)] = col;
                    }
                }
            }
            let (w, scale) = (block.angular_velocity, -2.0 * self.gyroscopic_scale);
            let kept = &factor.antisymmetric_gram;
            for u in 0..PER_BODY {
                for v in 0..PER_BODY {
                    let gyro: f64 = (0..3).map(|i| w[i] * kept[(i * PER_BODY + u) * PER_BODY + v]).sum();
                    c[at(o + u, o + v)] = g(u, v) + scale * gyro;
                }
            }
            // V_u^T G x = 2 s gamma' sum_i w_i (A_i V_u)^T x (A_i antisymmetric).
            let mut rows = vec![0.0; PER_BODY * m];
            for (u, row) in rows.chunks_exact_mut(m).enumerate() {
                for (i, &wi) in w.0.iter().enumerate() {
                    if wi != 0.0 {
                        let image =
                            &factor.antisymmetric_images[(i * PER_BODY + u) * m..(i * PER_BODY + u + 1) * m];
                        row.iter_mut().zip(image).for_each(|(o, a)| *o -= scale * wi * a);
                    }
                }
            }
            differences.push(BodyRows { difference: difference.0, dots: difference.1, gyroscopic: rows });
        }
        self.coarse = Coarse::factorize(size, c);
        if let Some(coarse) = &mut self.coarse {
            coarse.rows = differences;
        }
    }

    /// The coarse stage after a solve `x` = x0 = P^-1 b (see the module documentation); the
    /// images of the elastic update take -E y_f (kept as the coefficients y_f, applied in
    /// `coupling_images`).
    pub(super) fn coarse_stage(&mut self, x: &mut [f64]) {
        let Some(coarse) = self.coarse.as_mut() else { return };
        let (size, r) = (coarse.size, self.global_of.len());
        let mut y = std::mem::take(&mut coarse.scratch);
        y.clear();
        y.resize(size, 0.0);
        let coarse = self.coarse.as_ref().expect("checked");
        for b in 0..self.blocks.len() {
            let (first, n) = (self.blocks[b].first, self.blocks[b].n);
            let block = &self.blocks[b];
            let rc = block.structured.expect("structured");
            let BodyRows { difference, dots, gyroscopic: gyroscopic_rows } = &coarse.rows[b];
            // One pass over x0_F for the nine rows: the rotation rows' difference (first
            // three) and the rows R_u of V_u^T G.
            let products: [f64; 12] = dots_of(
                3 + PER_BODY,
                |k| {
                    if k < 3 {
                        &difference[k * n..(k + 1) * n]
                    } else {
                        &gyroscopic_rows[(k - 3) * n..(k - 2) * n]
                    }
                },
                &x[first..first + n],
            );
            // (Nm - P) x0: the rotation rows' difference on x0_F, its columns on x0_ref.
            let on_f: [f64; 3] = std::array::from_fn(|i| products[i]);
            for (a, &j) in block.reference.iter().enumerate() {
                let rj = self.reduced_of[block.coupling[j]];
                y[rj] -= (0..3).map(|i| rc.rows[a][3 + i] * on_f[i]).sum::<f64>();
            }
            let x_ref: [f64; 7] = std::array::from_fn(|a| {
                x[self.global_of[self.reduced_of[block.coupling[block.reference[a]]]]]
            });
            let column_weights: [f64; 3] =
                std::array::from_fn(|i| (0..7).map(|a| rc.columns[3 + i][a] * x_ref[a]).sum());
            for u in 0..PER_BODY {
                y[r + PER_BODY * b + u] =
                    -products[3 + u] - (0..3).map(|i| column_weights[i] * dots[i][u]).sum::<f64>();
            }
        }
        coarse.solve(&mut y);
        for (i, &g) in self.global_of.iter().enumerate() {
            x[g] += y[i];
        }
        for b in 0..self.blocks.len() {
            let block = &mut self.blocks[b];
            let (first, n) = (block.first, block.n);
            let rc = block.structured.expect("structured");
            let coefficients: [f64; PER_BODY] = std::array::from_fn(|u| y[r + PER_BODY * b + u]);
            let minus: [f64; PER_BODY] = coefficients.map(|c| -c);
            let factor = &block.factors[block.current];
            subtract_combination(
                &mut x[first..first + n],
                PER_BODY,
                |u| column_vector(factor, rc.deformed, n, u),
                &minus,
            );
            block.gyroscopic_coefficients = Some(coefficients);
        }
        if let Some(coarse) = self.coarse.as_mut() {
            coarse.scratch = y;
        }
    }
}

/// The dot products of `y` with `vector(0..count)` (see `kernels::dots`).
fn dots_of<'a, const N: usize>(count: usize, vector: impl Fn(usize) -> &'a [f64], y: &[f64]) -> [f64; N] {
    super::kernels::dots(count, vector, y)
}

#[cfg(test)]
mod tests {
    use super::Coarse;

    #[test]
    fn dense_lu_solves_where_later_columns_interchange_rows() {
        // A 4 x 4 matrix (column-major) whose pivots interchange rows at the first and the
        // later columns: the solve must give x with A x = b to round-off.
        let a = [
            1.0, 4.0, -2.0, 0.5, // column 0
            2.0, 1.0, 7.0, -3.0, // column 1
            0.0, -1.0, 3.0, 9.0, // column 2
            5.0, 0.2, 1.0, 2.0, // column 3
        ];
        let x_true = [0.3, -1.2, 2.5, 0.7];
        let b: Vec<f64> = (0..4).map(|i| (0..4).map(|k| a[k * 4 + i] * x_true[k]).sum()).collect();
        let coarse = Coarse::factorize(4, a.to_vec()).expect("regular");
        assert!(
            coarse.pivots.iter().enumerate().filter(|&(k, &p)| p != k).count() >= 2,
            "{:?}",
            coarse.pivots
        );
        let mut x = b.clone();
        coarse.solve(&mut x);
        crate::testing::assert_all_close(&x, &x_true, 0.0, 1e-14, "dense LU solve");
    }
}
