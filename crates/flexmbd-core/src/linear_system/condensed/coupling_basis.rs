//! The columns Z = A^-1 N_Fj of a condensed body's couplings other than its own reference
//! coordinates (joints and forces at its elastic markers), from an orthonormal basis of the
//! columns met so far, whose solves a factorization of A makes once.

use super::Block;
use crate::body::flexible::dot;
use crate::error::Result;

/// Largest size of a block's coupling basis (6 per marker on the body would need it).
const BASIS_LIMIT: usize = 24;

/// A coupling column is taken from the basis when the part of it outside the basis is at most
/// this fraction of it (round-off: the columns of a marker coupling lie in the basis exactly).
const SPAN_TOLERANCE: f64 = 1e-10;

impl Block {
    /// Z = A^-1 N_Fj of the coupling columns `columns` that are not the body's reference
    /// coordinates (joints and forces at its markers, and through them other bodies). A
    /// marker's kinematics depends on q_f through A(p) times constant body-frame rows of its
    /// Jacobians, so these columns stay in a space of dimension at most 6 per marker: each
    /// column is split over an orthonormal basis Q of the columns met so far (Gram-Schmidt,
    /// two passes, over the columns' support), a part outside it extends Q, and Z_j =
    /// (A^-1 Q) c_j with A^-1 Q solved once per factorization of A. After the first
    /// factorization, these columns need no solves.
    /// The reference columns of an exact solver (not in a fixed space) and columns met when
    /// Q is full are solved directly.
    pub(super) fn other_couplings(&mut self, columns: &[usize], values: &[f64]) -> Result<()> {
        if columns.is_empty() {
            return Ok(());
        }
        let m = self.n;
        if self.support.is_none() {
            self.make_support(columns);
        }
        let support = self.support.as_deref().unwrap_or(&[]);
        let ns = support.len();
        let mut direct = Vec::new();
        let mut split = Vec::with_capacity(columns.len());
        let mut v = vec![0.0; ns];
        for &j in columns {
            if self.reference.contains(&j) {
                direct.push(j);
                continue;
            }
            v.iter_mut().for_each(|x| *x = 0.0);
            for &(f, k) in &self.column_entries[j] {
                v[self.support_position[f]] = values[k];
            }
            let norm = dot(&v, &v).sqrt();
            let mut c = vec![0.0; self.basis.len() / m];
            if ns > 0 {
                for _pass in 0..2 {
                    for (ci, q) in c.iter_mut().zip(self.basis_compact.chunks_exact(ns)) {
                        let d = dot(q, &v);
                        *ci += d;
                        v.iter_mut().zip(q).for_each(|(x, qv)| *x -= d * qv);
                    }
                }
            }
            let outside = dot(&v, &v).sqrt();
            if outside > SPAN_TOLERANCE * norm {
                if c.len() >= BASIS_LIMIT {
                    direct.push(j);
                    continue;
                }
                let start = self.basis.len();
                self.basis.resize(start + m, 0.0);
                for (&f, x) in support.iter().zip(&v) {
                    self.basis[start + f] = x / outside;
                }
                self.basis_compact.extend(v.iter().map(|x| x / outside));
                c.push(outside);
            }
            split.push((j, c));
        }
        let factor = &mut self.factors[self.current];
        let solved = factor.basis_solved.len();
        if solved < self.basis.len() {
            let mut packed = self.basis[solved..].to_vec();
            factor.solve_in_place(&mut packed)?;
            factor.basis_solved.extend(packed);
        }
        let keep_image = !self.w.is_empty();
        for (j, c) in split {
            let z = &mut self.z[j * m..(j + 1) * m];
            z.iter_mut().for_each(|x| *x = 0.0);
            crate::linalg::simd::dense_mul_add(m, &factor.basis_solved[..c.len() * m], 1.0, &c, z);
            if keep_image {
                // The column as eliminated: Q c_j (A Z_j = Q c_j exactly), on the support.
                let w = &mut self.w[j * m..(j + 1) * m];
                w.iter_mut().for_each(|x| *x = 0.0);
                for (i, &f) in support.iter().enumerate() {
                    w[f] = c.iter().enumerate().map(|(k, ck)| ck * self.basis_compact[k * ns + i]).sum();
                }
            }
        }
        if !direct.is_empty() {
            let mut packed = vec![0.0; m * direct.len()];
            for (slot, &j) in direct.iter().enumerate() {
                for &(f, k) in &self.column_entries[j] {
                    packed[slot * m + f] = values[k];
                }
                if keep_image {
                    self.w[j * m..(j + 1) * m].copy_from_slice(&packed[slot * m..(slot + 1) * m]);
                }
            }
            factor.solve_in_place(&mut packed)?;
            for (slot, &j) in direct.iter().enumerate() {
                self.z[j * m..(j + 1) * m].copy_from_slice(&packed[slot * m..(slot + 1) * m]);
            }
        }
        Ok(())
    }

    /// The support of the coupling columns `columns` other than the reference coordinates
    /// (the union of their entries) and the position of each elastic coordinate in it.
    fn make_support(&mut self, columns: &[usize]) {
        let mut support: Vec<usize> = columns
            .iter()
            .filter(|j| !self.reference.contains(j))
            .flat_map(|&j| self.column_entries[j].iter().map(|e| e.0))
            .collect();
        support.sort_unstable();
        support.dedup();
        self.support_position = vec![usize::MAX; self.n];
        for (i, &f) in support.iter().enumerate() {
            self.support_position[f] = i;
        }
        self.support = Some(support);
    }
}
