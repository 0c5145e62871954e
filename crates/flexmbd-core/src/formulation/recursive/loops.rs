//! The cut joints' equations in joint coordinates through singular configurations of the loops:
//! C_hat = C_cut B (cut rows x free joint coordinates) by its SVD, C_hat = U S V^T, at every
//! evaluation, with the rank of the loops where they are regular (`LoopClosure::rank`).
//!
//! Where the links of a loop align, singular values of C_hat pass through zero and the null
//! space of C_hat grows for an instant; the motion keeps to its branch and its number of
//! degrees of freedom. The accelerations therefore stay in the null space of the `rank` largest
//! singular directions, V_2 = V[:, rank..] (the null space of C_hat wherever the loops are
//! regular), and every part that divides by a singular value (the particular solution at the
//! acceleration level, the velocity correction, the Newton steps of the positions) uses the
//! damped inverse d(s) = 1 / s for s >= mu and s / mu^2 below, mu = `damping` times the
//! largest singular value: exact away from the singular configuration, bounded by 1 / mu near
//! it. Near s = 0 the exact 1 / s turns a residual of the cut joints r (round-off, the
//! truncation error of a step) into a motion r / s across the branch, and the accelerations
//! that keep it into r / s^3: errors that grow as the step size falls. Within mu the
//! components along the vanishing directions are held near zero, which is exact when the
//! branch is straight in joint coordinates there (parallel cranks, as in IFToMM A02) and an
//! error of the order of the acceleration along that direction times the time spent within
//! mu otherwise. Rows beyond `rank` (redundant cut equations) get minimum-norm multipliers.

use faer::linalg::solvers::Solve;
use faer::{Mat, MatRef, Side};

/// Damping of the inverse singular values of the cut joints' equations, relative to the largest
/// singular value (see the module documentation).
pub const LOOP_DAMPING: f64 = 1e-3;

/// The SVD of C_hat = C_cut B at one state, with the loops' regular rank.
pub struct LoopClosure {
    u: Mat<f64>,
    singular_values: Vec<f64>,
    v: Mat<f64>,
    /// The number of leading singular directions treated as constraints.
    rank: usize,
    /// mu (units of C_hat).
    damping: f64,
}

impl LoopClosure {
    /// The factorization of `c_hat` (cut rows x free joint coordinates) with `rank` constrained
    /// directions (at most the number of rows) and the relative `damping`.
    pub fn new(c_hat: MatRef<'_, f64>, rank: usize, damping: f64) -> std::result::Result<Self, String> {
        let svd = crate::linalg::svd::svd(c_hat)
            .map_err(|_| "the SVD of the cut joints' Jacobian C_cut B did not converge".to_string())?;
        let s = svd.S().column_vector();
        let singular_values: Vec<f64> = (0..s.nrows()).map(|k| s[k]).collect();
        let largest = singular_values.first().copied().unwrap_or(0.0);
        Ok(LoopClosure {
            u: svd.U().to_owned(),
            v: svd.V().to_owned(),
            rank: rank.min(singular_values.len()),
            damping: damping * largest,
            singular_values,
        })
    }

    /// The factorization of `c_hat` with the singular values above `cutoff` times the largest
    /// constrained and no damping: the truncated SVD (minimum-norm solutions).
    pub fn truncated(c_hat: MatRef<'_, f64>, cutoff: f64) -> std::result::Result<Self, String> {
        let mut closure = LoopClosure::new(c_hat, usize::MAX, 0.0)?;
        closure.rank = closure.numerical_rank(cutoff);
        Ok(closure)
    }

    /// Singular values of C_hat, largest first.
    pub fn singular_values(&self) -> &[f64] {
        &self.singular_values
    }

    /// The number of singular values above `tolerance` times the largest.
    pub fn numerical_rank(&self, tolerance: f64) -> usize {
        let largest = self.singular_values.first().copied().unwrap_or(0.0);
        self.singular_values.iter().take_while(|&&s| s > tolerance * largest).count()
    }

    /// The damped solution of C_hat x = b on the constrained directions:
    /// x = sum_{k < rank} d(s_k) (u_k . b) v_k with d(s) = 1 / s for s >= mu and s / mu^2 below
    /// (continuous, exact away from singular configurations, at most 1 / mu).
    pub fn solve(&self, b: &[f64]) -> Vec<f64> {
        let n = self.v.nrows();
        let mut x = vec![0.0; n];
        for k in 0..self.rank {
            let s = self.singular_values[k];
            let inverse = if s >= self.damping { 1.0 / s } else { s / (self.damping * self.damping) };
            let coefficient = inverse * (0..b.len()).map(|i| self.u[(i, k)] * b[i]).sum::<f64>();
            for (j, xj) in x.iter_mut().enumerate() {
                *xj += self.v[(j, k)] * coefficient;
            }
        }
        x
    }

    /// An orthonormal basis of the null space of the constrained directions: V_2 = V[:, rank..]
    /// (free joint coordinates x (free - rank)).
    pub fn null_space(&self) -> Mat<f64> {
        let n = self.v.nrows();
        self.v.subcols(self.rank, n - self.rank).to_owned()
    }

    /// The null-space method for M x + C_hat^T mu = f, C_hat x = g: x = x_p + V_2 z with the
    /// damped particular solution x_p ([`LoopClosure::solve`]) and (V_2^T M V_2) z =
    /// V_2^T (f - M x_p). `mass` symmetric, positive definite on the null space.
    pub fn accelerations(
        &self,
        mass: &Mat<f64>,
        force: &[f64],
        g: &[f64],
    ) -> std::result::Result<Vec<f64>, String> {
        let n = force.len();
        let mut x = self.solve(g);
        let v2 = self.null_space();
        let residual = Mat::from_fn(n, 1, |i, _| force[i] - (0..n).map(|j| mass[(i, j)] * x[j]).sum::<f64>());
        let mut z = v2.transpose() * &residual;
        let reduced = v2.transpose() * (mass * &v2);
        let llt = reduced.llt(Side::Lower).map_err(|_| {
            "the mass matrix on the null space of the cut joints is not positive definite".to_string()
        })?;
        llt.solve_in_place(&mut z);
        for (i, xi) in x.iter_mut().enumerate() {
            *xi += (0..n - self.rank).map(|k| v2[(i, k)] * z[(k, 0)]).sum::<f64>();
        }
        if x.iter().any(|v| !v.is_finite()) {
            return Err("the accelerations are not finite".to_string());
        }
        Ok(x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{assert_all_close, assert_close};

    /// 2 x 3, rank 2 with singular values 2 and `small`.
    fn jacobian(small: f64) -> Mat<f64> {
        Mat::from_fn(2, 3, |i, j| match (i, j) {
            (0, 0) => 2.0,
            (1, 1) => small,
            _ => 0.0,
        })
    }

    #[test]
    fn regular_loops_solve_exactly() {
        let closure = LoopClosure::new(jacobian(0.5).as_ref(), 2, LOOP_DAMPING).unwrap();
        assert_eq!(closure.numerical_rank(1e-9), 2);
        assert_all_close(&closure.solve(&[1.0, 1.0]), &[0.5, 2.0, 0.0], 0.0, 1e-9, "x");
    }

    #[test]
    fn vanishing_singular_values_stay_constrained() {
        // Next to the singular configuration the second direction keeps its zero velocity, and
        // a right-hand side that is not consistent there (a residual of 1e-9 against the
        // singular value 1e-12) moves it by less than 1e-9 / mu, not by 1e3.
        let closure = LoopClosure::new(jacobian(1e-12).as_ref(), 2, LOOP_DAMPING).unwrap();
        assert_eq!(closure.numerical_rank(1e-9), 1);
        let x = closure.solve(&[1.0, 1e-9]);
        assert_close(x[0], 0.5, 0.0, 1e-12, "x_0");
        assert!(x[1].abs() < 1e-9 / (2.0 * LOOP_DAMPING), "x_1 = {}", x[1]);
        let mass = Mat::<f64>::identity(3, 3);
        let a = closure.accelerations(&mass, &[1.0, 1.0, 1.0], &[4.0, 0.0]).unwrap();
        assert_all_close(&a, &[2.0, 0.0, 1.0], 0.0, 1e-15, "accelerations");
    }
}
