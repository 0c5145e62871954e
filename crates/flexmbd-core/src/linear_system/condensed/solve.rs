//! The solves of a condensed solver with its last factorization,
//! y = A^-1 r_F, S_hat x_S = r_S - N_SF y, x_F = y - Z x_J, and the coupling images W x_J of
//! the last solve.

use super::kernels::{dots, gather_dot, subtract_combination};
use super::reference::{column_vector, eliminated_vector, row_vector, ROW_VECTORS};
use super::{Block, CondensedSolver};
use crate::linalg::simd::{dot4, update4, GROUP};

impl CondensedSolver {
    /// Per condensed body (body index): W x_J of the last solve, where W = N_FJ are the coupling columns the factorization
    /// eliminated with, so that the elastic part x_F of that solve has A x_F = b_F - W x_J
    /// (b: the right-hand side). Empty slices unless made `with_images`, and after a
    /// factorization until the next solve.
    pub fn coupling_images(&mut self) -> impl Iterator<Item = (usize, &[f64])> + '_ {
        for block in &mut self.blocks {
            let m = block.n;
            if block.last_x.is_empty() {
                block.image.clear();
                continue;
            }
            block.image.resize(m, 0.0);
            block.image.iter_mut().for_each(|v| *v = 0.0);
            if let Some(rc) = &block.structured {
                // The reference columns as eliminated: [I1, J_f, S_kl] (C x_ref).
                let (rows, factor) = (&block.reference_rows, &block.factors[block.current]);
                let x_ref = block.reference.map(|a| -block.last_x[a]);
                subtract_combination(
                    &mut block.image,
                    rc.column_count,
                    |v| eliminated_vector(rows, factor, rc.deformed, m, v),
                    &rc.combination(&x_ref),
                );
            }
            if let (Some(y_f), Some(rc)) = (&block.gyroscopic_coefficients, &block.structured) {
                // The coarse stage's correction V y_f, eliminated as -E y_f.
                let (rows, factor) = (&block.reference_rows, &block.factors[block.current]);
                subtract_combination(
                    &mut block.image,
                    y_f.len(),
                    |u| eliminated_vector(rows, factor, rc.deformed, m, u),
                    y_f,
                );
            }
            for (j, (&xj, w)) in block.last_x.iter().zip(block.w.chunks_exact(m)).enumerate() {
                if xj != 0.0 && !block.applied_from_kept(j) {
                    block.image.iter_mut().zip(w).for_each(|(o, wv)| *o += wv * xj);
                }
            }
        }
        self.blocks.iter().map(|b| (b.body, &b.image[..]))
    }

    /// Solves in place (global vector) with the last factorization.
    pub fn solve_in_place(&mut self, x: &mut [f64]) -> std::result::Result<(), String> {
        if !self.factorized {
            return Err("no valid factorization".to_string());
        }
        for (r, &g) in self.rhs.iter_mut().zip(&self.global_of) {
            *r = x[g];
        }
        for block in &mut self.blocks {
            block.gyroscopic_coefficients = None;
        }
        // y = A^-1 r_F of each body, and r_S -= N_SF y.
        let mut offset = 0;
        for block in &mut self.blocks {
            let y = &mut self.y[offset..offset + block.n];
            y.copy_from_slice(&x[block.first..block.first + block.n]);
            block.factors[block.current].solve_in_place(y).map_err(|e| e.to_string())?;
            block.subtract_coupling_rows(y, &self.reduced_of, &mut self.rhs);
            offset += block.n;
        }
        self.lu.solve_in_place(&mut self.rhs)?;
        for (&r, &g) in self.rhs.iter().zip(&self.global_of) {
            x[g] = r;
        }
        // x_F = y - Z x_J of each body.
        let mut offset = 0;
        for block in &mut self.blocks {
            let out = &mut x[block.first..block.first + block.n];
            out.copy_from_slice(&self.y[offset..offset + block.n]);
            if self.keep_image {
                block.last_x.clear();
                block.last_x.extend(block.coupling.iter().map(|&g| self.rhs[self.reduced_of[g]]));
            }
            block.subtract_coupling_columns(&self.rhs, &self.reduced_of, out);
            offset += block.n;
        }
        if !crate::math::all_finite(x) {
            return Err("the matrix is singular (the solution is not finite)".to_string());
        }
        Ok(())
    }
}

impl Block {
    /// rhs -= N_JF y at the reduced indices of the coupling unknowns (`reduced_of`: global
    /// index -> reduced index): the reference rows R (U^T y) when structured, the other rows
    /// as kept, dense ones four at a time (one pass over y for four of them).
    fn subtract_coupling_rows(&self, y: &[f64], reduced_of: &[usize], rhs: &mut [f64]) {
        let reduced = |a: usize| reduced_of[self.coupling[a]];
        if let Some(rc) = &self.structured {
            // The reference rows R (U^T y).
            let (m, factor) = (self.n, &self.factors[self.current]);
            let products: [f64; ROW_VECTORS] =
                dots(rc.row_count, |k| row_vector(&self.reference_rows, factor, rc.deformed, m, k), y);
            for (row, &a) in rc.rows.iter().zip(&self.reference) {
                rhs[reduced(a)] -= products.iter().zip(row).map(|(p, r)| p * r).sum::<f64>();
            }
        }
        // The other rows: dense ones four at a time.
        let mut dense = [0usize; GROUP];
        let mut count = 0;
        for (a, entries) in self.row_entries.iter().enumerate() {
            if self.applied_from_kept(a) {
                continue;
            }
            let stored = &self.row_values[a];
            if !self.dense_rows[a] {
                rhs[reduced(a)] -= gather_dot(entries, stored, y);
                continue;
            }
            dense[count] = a;
            count += 1;
            if count == GROUP {
                let rows = dense.map(|a| &self.row_values[a][..]);
                for (&a, sum) in dense.iter().zip(dot4(rows, y)) {
                    rhs[reduced(a)] -= sum;
                }
                count = 0;
            }
        }
        if count > 0 {
            // The last group filled up with its last row.
            let rows: [&[f64]; GROUP] =
                std::array::from_fn(|i| &self.row_values[dense[i.min(count - 1)]][..]);
            for (&a, sum) in dense[..count].iter().zip(dot4(rows, y)) {
                rhs[reduced(a)] -= sum;
            }
        }
    }

    /// out -= Z x_J with x_J from the reduced solution `rhs` (`reduced_of`: global index ->
    /// reduced index): the reference columns V (C x_ref) when structured, the others four
    /// columns of Z at a time (one pass over out for four).
    fn subtract_coupling_columns(&self, rhs: &[f64], reduced_of: &[usize], out: &mut [f64]) {
        let x_j = |a: usize| rhs[reduced_of[self.coupling[a]]];
        let n = self.n;
        if let Some(rc) = &self.structured {
            let factor = &self.factors[self.current];
            let x_ref = self.reference.map(x_j);
            subtract_combination(
                out,
                rc.column_count,
                |v| column_vector(factor, rc.deformed, n, v),
                &rc.combination(&x_ref),
            );
        }
        let column = |j: usize| &self.z[j * n..(j + 1) * n];
        let mut group = [(0usize, 0.0f64); GROUP];
        let mut count = 0;
        for j in 0..self.coupling.len() {
            let xj = x_j(j);
            if xj != 0.0 && !self.applied_from_kept(j) {
                group[count] = (j, xj);
                count += 1;
                if count == GROUP {
                    update4(out, group.map(|(_, x)| x), group.map(|(j, _)| column(j)));
                    count = 0;
                }
            }
        }
        for &(j, xj) in &group[..count] {
            for (o, zv) in out.iter_mut().zip(column(j)) {
                *o -= zv * xj;
            }
        }
    }
}
