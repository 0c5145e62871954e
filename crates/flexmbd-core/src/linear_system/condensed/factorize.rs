//! The factorization of a condensed solver: per condensed body, a factorization of A (made or
//! kept), the columns Z = A^-1 N_FJ and rows N_JF of its couplings, and their product
//! subtracted from N_SS; then the LU of the reduced system S_hat = N_SS - N_SF Z.

use super::kernels::{dots, gather_dot};
use super::reference::{column_vector, row_vector, ReferenceCoupling, COLUMN_VECTORS, ROW_VECTORS};
use super::{flexible, Block, CondensedSolver};
use crate::assembly::MatrixCoefficients;
use crate::body::flexible::FlexibleBody;
use crate::error::{FlexmbdError, Result};
use crate::linalg::simd::{dot4, GROUP};
use crate::system::model::Model;

impl CondensedSolver {
    /// Factorizes the iteration matrix with the assembled `values` (global pattern) and the
    /// constant blocks A for the coefficients `c`, at coordinates `q`.
    ///
    /// With `approximate_reference`, the coupling of each body with its own reference
    /// coordinates enters through its mass part s m [I1^T A^T, J_f^T 2L] (and the
    /// transpose), with J_f = int rho u~ S = J_f0 + dJ(q_f): the undeformed part of Z comes
    /// from the influence A^-1 [I1^T, J_f0^T] kept with the factorization, the deformation
    /// part from three solves; and through the velocity part of the undeformed body at the
    /// angular velocity of `set_angular_velocities` (relative size h w against the mass part:
    /// with it a step of the 1k pendulum bar takes 2.85 instead of 2.98 Newton iterations over
    /// 3 s, see `reference_coupling`). The position part left out is of relative size h^2 (g / L);
    /// the other couplings (joints and forces at elastic markers) are taken as assembled, one
    /// solve per coupling column.
    pub fn factorize(
        &mut self,
        model: &Model,
        values: &[f64],
        c: &MatrixCoefficients,
        q: &[f64],
    ) -> Result<()> {
        self.factorized = false;
        self.gyroscopic_scale = if self.approximate_reference { c.scale * c.velocity } else { 0.0 };
        for (r, &g) in self.reduced_values.iter_mut().zip(&self.copy_from) {
            *r = if g == usize::MAX { 0.0 } else { values[g] };
        }
        let coarse = self.gyroscopic && self.gyroscopic_scale != 0.0;
        let before_schur = if coarse { self.reduced_values.clone() } else { Vec::new() };
        for block in &mut self.blocks {
            block.last_x.clear();
            block.gyroscopic_coefficients = None;
            block.structured = None;
            block.deformation_tolerance = if coarse {
                super::reference::COARSE_DEFORMATION_TOLERANCE
            } else {
                super::reference::DEFORMATION_TOLERANCE
            };
            let fb = flexible(model, block.body);
            block.select_factor(fb, c)?;
            let qb = &q[model.bodies[block.body].offset..];
            let reference_block = block.eliminate_couplings(fb, values, c, qb, self.approximate_reference)?;
            block.subtract_coupling_product(reference_block.as_ref(), &mut self.reduced_values);
        }
        self.lu.factorize(&self.reduced_values).map_err(|detail| FlexmbdError::SingularMatrix {
            time: 0.0,
            context: "condensed Newton matrix".to_string(),
            detail,
        })?;
        self.factorized = true;
        self.coarse = None;
        if coarse {
            self.make_coarse(model, values, &before_schur, q);
        }
        Ok(())
    }
}

impl Block {
    /// The columns Z = A^-1 N_FJ and the rows N_JF of the coupling unknowns at the assembled
    /// `values`; with `structured` (an iteration matrix), those of the body's reference
    /// coordinates from `reference_coupling` at the body coordinates `qb` (its block N_JF Z of
    /// the reference rows and columns returned when applied from the kept vectors), the others
    /// as assembled.
    fn eliminate_couplings(
        &mut self,
        fb: &FlexibleBody,
        values: &[f64],
        c: &MatrixCoefficients,
        qb: &[f64],
        structured: bool,
    ) -> Result<Option<[[f64; 7]; 7]>> {
        let nj = self.coupling.len();
        let reference = self.reference;
        let is_reference = |j: usize| structured && reference.contains(&j);
        // Z = A^-1 N_FJ of the other coupling columns.
        let others: Vec<usize> = (0..nj).filter(|&j| !is_reference(j)).collect();
        self.other_couplings(&others, values)?;
        for (j, (stored, entries)) in self.row_values.iter_mut().zip(&self.row_entries).enumerate() {
            if !is_reference(j) {
                for (v, &(_, k)) in stored.iter_mut().zip(entries) {
                    *v = values[k];
                }
            }
        }
        if structured {
            self.reference_coupling(fb, c, qb)
        } else {
            Ok(None)
        }
    }

    /// S_hat(J, J) -= N_JF Z: the reference block, when structured, from `reference_coupling`
    /// (`reference_block`), the other rows against the reference columns and the reference
    /// rows against the other columns through the kept vectors; the rest a dense row against
    /// four columns of Z at a time.
    fn subtract_coupling_product(&self, reference_block: Option<&[[f64; 7]; 7]>, reduced_values: &mut [f64]) {
        let nj = self.coupling.len();
        if let Some(rb) = reference_block {
            for (ra, &ja) in self.reference.iter().enumerate() {
                for (rc, &jb) in self.reference.iter().enumerate() {
                    reduced_values[self.schur_entries[ja * nj + jb]] -= rb[ra][rc];
                }
            }
        }
        // The columns of Z: all but the reference ones applied from the kept vectors.
        let columns: Vec<usize> = (0..nj).filter(|&j| !self.applied_from_kept(j)).collect();
        for a in 0..nj {
            if self.applied_from_kept(a) {
                continue;
            }
            let schur = &self.schur_entries[a * nj..(a + 1) * nj];
            self.subtract_row_times_z(a, &columns, schur, reduced_values);
            if let Some(rc) = &self.structured {
                self.subtract_row_times_reference_columns(a, rc, schur, reduced_values);
            }
        }
        if let Some(rc) = &self.structured {
            self.subtract_reference_rows_times_z(rc, &columns, reduced_values);
        }
    }

    /// S_hat(a, b) -= N_aF Z_b for the coupling row `a` and the `columns` b of Z (`schur`: the
    /// reduced value index of each (a, b)): a dense row against four columns at a time.
    fn subtract_row_times_z(&self, a: usize, columns: &[usize], schur: &[usize], reduced_values: &mut [f64]) {
        let m = self.n;
        let column = |b: usize| &self.z[b * m..(b + 1) * m];
        let (entries, stored) = (&self.row_entries[a], &self.row_values[a]);
        if self.dense_rows[a] {
            // Groups of four columns; the last group filled up with its last column.
            for group in columns.chunks(GROUP) {
                let count = group.len();
                let sums = dot4(std::array::from_fn(|i| column(group[i.min(count - 1)])), stored);
                for (&b, sum) in group.iter().zip(sums) {
                    reduced_values[schur[b]] -= sum;
                }
            }
        } else {
            for &b in columns {
                reduced_values[schur[b]] -= gather_dot(entries, stored, column(b));
            }
        }
    }

    /// S_hat(a, ref) -= N_aF Z_ref = (N_aF V) C for the coupling row `a` (not a reference
    /// coordinate's) and the structured coupling `rc`.
    fn subtract_row_times_reference_columns(
        &self,
        a: usize,
        rc: &ReferenceCoupling,
        schur: &[usize],
        reduced_values: &mut [f64],
    ) {
        let m = self.n;
        let factor = &self.factors[self.current];
        let (entries, stored) = (&self.row_entries[a], &self.row_values[a]);
        let vector = |v: usize| column_vector(factor, rc.deformed, m, v);
        let products: [f64; COLUMN_VECTORS] = if self.dense_rows[a] {
            dots(rc.column_count, vector, stored)
        } else {
            std::array::from_fn(|v| {
                if v < rc.column_count {
                    gather_dot(entries, stored, vector(v))
                } else {
                    0.0
                }
            })
        };
        for (b, &jb) in self.reference.iter().enumerate() {
            let sum: f64 = products.iter().zip(&rc.columns).map(|(p, col)| p * col[b]).sum();
            reduced_values[schur[jb]] -= sum;
        }
    }

    /// S_hat(ref, b) -= N_ref,F Z_b = R (U^T Z_b) for the `columns` b of Z and the structured
    /// coupling `rc`.
    fn subtract_reference_rows_times_z(
        &self,
        rc: &ReferenceCoupling,
        columns: &[usize],
        reduced_values: &mut [f64],
    ) {
        let (m, nj) = (self.n, self.coupling.len());
        let factor = &self.factors[self.current];
        for &b in columns {
            let products: [f64; ROW_VECTORS] = dots(
                rc.row_count,
                |k| row_vector(&self.reference_rows, factor, rc.deformed, m, k),
                &self.z[b * m..(b + 1) * m],
            );
            for (row, &ja) in rc.rows.iter().zip(&self.reference) {
                let sum: f64 = products.iter().zip(row).map(|(p, r)| p * r).sum();
                reduced_values[self.schur_entries[ja * nj + b]] -= sum;
            }
        }
    }
}
