//! TR-BDF2, an implicit Runge-Kutta method on the integrated vector y of a strategy (the
//! joint coordinates and their rates, or the independent coordinates, ...): for the stiff
//! deformable bodies on which the explicit methods need steps of the order of the period of
//! their highest elastic mode. A trapezoidal stage to t + gamma h followed by a BDF2 stage to
//! t + h, written as a singly diagonally implicit method with an explicit first stage
//! (Hosea and Shampine 1996; Bank et al. 1985): L-stable, second order, stiffly accurate, with
//! an embedded third-order estimate filtered through the iteration matrix (Shampine's filter,
//! so that stiff components do not shrink the step).
//!
//! ```text
//!   c = (0, g, 1),  g = 2 - sqrt 2,  d = g / 2,  w = sqrt 2 / 4
//!   k1 = f(t, y)
//!   k2 = f(t + g h, y + h (d k1 + d k2))
//!   k3 = f(t + h,   y + h (w k1 + w k2 + d k3)),   y_new = y + h (w k1 + w k2 + d k3)
//!   error = (I - h d J)^-1 h ((4 w - 1) k1 / 3 - k2 / 3 + 2 d k3 / 3)
//! ```
//!
//! The implicit stages are solved by simplified Newton iterations with the matrix I - h d J, kept
//! over the steps while the iterations converge quickly and factorized again when h changes.
//! J = df/dy comes in one of two forms:
//!
//! - for y = [p; p_dot] of a tree in joint coordinates, from its linearized equations of motion
//!   ([`TreeLinearization`]): J = [[0, I], [-P K_t, -P D_t]] with the tree's mass matrix M_t,
//!   the elastic stiffness K_t and damping D_t, P the inverse of M_t on the null space N of the
//!   cut joints. The Schur complement on the rates reduces the Newton system to
//!   (M_t + c D_t + c^2 K_t) x_v = M_t r_v - c K_t r_p (c = h d; on N with cut joints), and
//!   x_p = r_p + c x_v: one matrix of the free coordinates' size, formed from one evaluation
//!   of M_t = B^T M B. The derivatives of M_t, of the velocity-quadratic, gravity and
//!   geometric-stiffness forces and of the cut joints are left out (a modified Newton
//!   method); the contraction of the iterations is watched, and a slow or diverging
//!   iteration forms the matrix again or shortens the step. The matrix is symmetric positive
//!   definite (Cholesky). Without stiffness and damping (rigid trees) the lower blocks of J
//!   vanish and the iteration is x_v = r_v: nothing is formed;
//! - otherwise by forward differences of f at the start of a step (one evaluation of f per
//!   component of y).

use faer::linalg::solvers::{Llt, PartialPivLu, Solve};
use faer::{Mat, Side};

use super::runge_kutta::Stages;
use crate::error::Result;
use crate::formulation::recursive::TreeLinearization;

const SQRT2: f64 = std::f64::consts::SQRT_2;
/// Stage abscissa gamma.
const GAMMA: f64 = 2.0 - SQRT2;
/// Diagonal coefficient d = gamma / 2.
const D: f64 = GAMMA / 2.0;
/// Weight w of the first two stages in the last.
const W: f64 = SQRT2 / 4.0;
/// Newton iterations per stage before the stage counts as failed.
const MAX_ITERATIONS: usize = 8;
/// Iterations of a stage above which the Jacobian is formed again for the next step: by
/// differences, and from the tree's linearization (one evaluation of the mass matrix).
const SLOW: usize = 4;
const SLOW_TREE: usize = 2;
/// A stage has converged when its Newton increment, in the error norm, is below this.
const NEWTON_TOLERANCE: f64 = 1e-2;
/// Contraction rate of the Newton iterations (the ratio of successive increments) above which
/// a stage counts as failed.
const DIVERGING: f64 = 0.9;

/// What TR-BDF2 integrates: y' = f(t, y), and, where y = [p; p_dot] of a tree in joint
/// coordinates, its linearized equations of motion.
pub(super) trait Equations {
    /// dy/dt at (t, y) into `dy`.
    fn derivative(&mut self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<()>;
    /// The linearized equations of motion at (t, y) (see the module), or None: the Jacobian
    /// is then formed by differences.
    fn linearization(&mut self, t: f64, y: &[f64]) -> Result<Option<TreeLinearization>>;
}

/// df/dy of a step (see the module).
enum Jacobian {
    /// By forward differences (n x n).
    Differences(Mat<f64>),
    /// From the linearized equations of motion of y = [p; p_dot].
    Tree(TreeLinearization),
}

/// The factorized iteration matrix for one c = h d.
enum Factor {
    /// I - c J.
    Differences(PartialPivLu<f64>),
    /// M_t + c D_t + c^2 K_t, or N^T (M_t + c D_t + c^2 K_t) N with cut joints.
    Tree(TreeFactor),
}

/// The factor of the tree's iteration matrix: Cholesky (symmetric positive definite, as it is
/// with symmetric stiffness and damping), else LU.
enum TreeFactor {
    Cholesky(Llt<f64>),
    Lu(PartialPivLu<f64>),
}

impl TreeFactor {
    /// Factorizes `a`.
    fn new(a: Mat<f64>) -> Self {
        match a.llt(Side::Lower) {
            Ok(llt) => TreeFactor::Cholesky(llt),
            Err(_) => TreeFactor::Lu(a.partial_piv_lu()),
        }
    }

    /// a^-1 `b`.
    fn solve(&self, b: Mat<f64>) -> Mat<f64> {
        match self {
            TreeFactor::Cholesky(llt) => llt.solve(b),
            TreeFactor::Lu(lu) => lu.solve(b),
        }
    }
}

/// The iteration matrix kept between the steps.
#[derive(Default)]
pub(super) struct Newton {
    /// df/dy at the start of the step it was formed in (None: form it at the next step).
    jacobian: Option<Jacobian>,
    /// The factorized iteration matrices of the last two step sizes and their c = h d (the
    /// controller's step and the one that lands on an output time alternate).
    factors: Vec<(f64, Factor)>,
    /// Newton iterations, Jacobians formed, factorizations and evaluations of f for Jacobians
    /// by differences, over the run.
    pub(super) iterations: usize,
    pub(super) jacobians: usize,
    pub(super) factorizations: usize,
    pub(super) difference_evaluations: usize,
    /// The time of the slope of the last converged second stage, held in `Stages::k[1]`
    /// (None: none, or the integrated vector changed since).
    second_stage: Option<f64>,
    /// When the tree's analytic matrix, fresh, did not converge and the run went on with
    /// differences (its velocity-quadratic, gravity and geometric-stiffness terms left out:
    /// a spinning beam's centrifugal stiffening and Coriolis coupling).
    pub(super) analytic_abandoned: Option<f64>,
}

impl Newton {
    /// Forgets the Jacobian (the integrated vector changed meaning or length).
    pub(super) fn invalidate(&mut self) {
        self.jacobian = None;
        self.factors.clear();
        self.second_stage = None;
    }

    /// The factorization for c = h d, formed if it is not one of the kept ones.
    fn factor(&mut self, c: f64) -> &Factor {
        if let Some(k) = self.factors.iter().position(|(fc, _)| *fc == c) {
            return &self.factors[k].1;
        }
        let factor = match self.jacobian.as_ref().expect("a Jacobian") {
            Jacobian::Differences(j) => {
                let n = j.nrows();
                let m = Mat::from_fn(n, n, |r, k| if r == k { 1.0 } else { 0.0 } - c * j[(r, k)]);
                Factor::Differences(m.partial_piv_lu())
            }
            Jacobian::Tree(lin) => {
                let a = &lin.mass + c * &lin.damping + (c * c) * &lin.stiffness;
                let a = match &lin.null_space {
                    Some(n) => n.transpose() * (&a * n),
                    None => a,
                };
                Factor::Tree(TreeFactor::new(a))
            }
        };
        self.factorizations += 1;
        if self.factors.len() >= 2 {
            self.factors.remove(0);
        }
        self.factors.push((c, factor));
        &self.factors.last().expect("just pushed").1
    }

    /// Solves (I - c J) x = r in place of `r` with the kept Jacobian and its factorization
    /// for c (formed by `factor`).
    fn solve(&self, c: f64, r: &mut [f64]) {
        let factor = &self.factors.iter().find(|(fc, _)| *fc == c).expect("factorized").1;
        match (factor, self.jacobian.as_ref().expect("a Jacobian")) {
            (Factor::Differences(lu), _) => {
                let x = lu.solve(Mat::from_fn(r.len(), 1, |i, _| r[i]));
                r.iter_mut().enumerate().for_each(|(i, v)| *v = x[(i, 0)]);
            }
            (Factor::Tree(lu), Jacobian::Tree(lin)) => solve_tree(lin, lu, c, r),
            (Factor::Tree(_), Jacobian::Differences(_)) => unreachable!("factors follow the Jacobian"),
        }
    }
}

/// (I - c J) x = r for y = [p; p_dot] with J from `lin` (see the module), `lu` the factorized
/// (N^T) (M_t + c D_t + c^2 K_t) (N): x_v from the Schur complement on the rates (with the cut
/// joints: x_v = x_r + N z, x_r = r_v - N N^T r_v the part of r_v the constraints fix), then
/// x_p = r_p + c x_v.
fn solve_tree(lin: &TreeLinearization, lu: &TreeFactor, c: f64, r: &mut [f64]) {
    let n = r.len() / 2;
    let (rp, rv) = r.split_at_mut(n);
    let r_p = Mat::from_fn(n, 1, |i, _| rp[i]);
    let r_v = Mat::from_fn(n, 1, |i, _| rv[i]);
    let b = &lin.mass * &r_v - c * (&lin.stiffness * &r_p);
    let x_v = match &lin.null_space {
        None => lu.solve(b),
        Some(null) => {
            let x_r = &r_v - null * (null.transpose() * &r_v);
            let a_x = &lin.mass * &x_r + c * (&lin.damping * &x_r) + (c * c) * (&lin.stiffness * &x_r);
            let z = lu.solve(null.transpose() * (b - a_x));
            x_r + null * z
        }
    };
    for i in 0..n {
        rv[i] = x_v[(i, 0)];
        rp[i] += c * x_v[(i, 0)];
    }
}

/// What a step attempt found.
pub(super) enum Outcome {
    /// The stages converged: the weighted error norm (<= 1 passes).
    Error(f64),
    /// Newton's iterations did not converge, with a Jacobian of this step.
    NotConverged,
}

/// One TR-BDF2 step from (t, y) with step h (see the module). `stages.k[0]` must hold dy/dt at
/// (t, y); the end point goes to `stages.y_new` and dy/dt there to `k[6]` (first same as
/// last). `tolerances` (relative, absolute) weigh the error and the Newton increments.
pub(super) fn step(
    t: f64,
    h: f64,
    stages: &mut Stages,
    tolerances: (f64, f64),
    newton: &mut Newton,
    equations: &mut impl Equations,
) -> Result<Outcome> {
    let n = stages.y.len();
    let size = match &newton.jacobian {
        Some(Jacobian::Differences(j)) => Some(j.nrows()),
        Some(Jacobian::Tree(lin)) => Some(2 * lin.mass.nrows()),
        None => None,
    };
    if size.is_some_and(|s| s != n) {
        newton.invalidate();
    }
    let mut fresh = false;
    loop {
        if newton.jacobian.is_none() {
            let tree = if newton.analytic_abandoned.is_none() {
                equations.linearization(t, &stages.y)?
            } else {
                None
            };
            newton.jacobian = Some(match tree {
                Some(lin) => Jacobian::Tree(lin),
                None => {
                    // The differences use k[1] for their columns.
                    newton.second_stage = None;
                    newton.difference_evaluations += n;
                    Jacobian::Differences(differences(t, stages, equations)?)
                }
            });
            newton.jacobians += 1;
            newton.factors.clear();
            fresh = true;
        }
        match attempt(t, h, stages, tolerances, newton, equations)? {
            Some(err) => return Ok(Outcome::Error(err)),
            // The analytic matrix of this very state does not converge: the terms it leaves
            // out matter here, and differences take them (for the rest of the run).
            None if fresh && matches!(newton.jacobian, Some(Jacobian::Tree(_))) => {
                newton.invalidate();
                newton.analytic_abandoned = Some(t);
            }
            None if fresh => {
                newton.invalidate();
                return Ok(Outcome::NotConverged);
            }
            // A Jacobian of an earlier step: form it again here and retry once.
            None => newton.invalidate(),
        }
    }
}

/// df/dy at (t, y) by forward differences (k[0] holds f(t, y)).
fn differences(t: f64, stages: &mut Stages, equations: &mut impl Equations) -> Result<Mat<f64>> {
    let n = stages.y.len();
    let mut j = Mat::zeros(n, n);
    let Stages { y, stage, k, .. } = stages;
    let (head, tail) = k.split_at_mut(1);
    let column = &mut tail[0];
    stage.copy_from_slice(y);
    for c in 0..n {
        let delta = f64::EPSILON.sqrt() * y[c].abs().max(1e-3);
        stage[c] = y[c] + delta;
        equations.derivative(t, stage, column)?;
        stage[c] = y[c];
        for r in 0..n {
            j[(r, c)] = (column[r] - head[0][r]) / delta;
        }
    }
    Ok(j)
}

/// The stages with the kept Jacobian: Some(error norm), or None if Newton failed.
fn attempt(
    t: f64,
    h: f64,
    stages: &mut Stages,
    tolerances: (f64, f64),
    newton: &mut Newton,
    equations: &mut impl Equations,
) -> Result<Option<f64>> {
    let n = stages.y.len();
    let c = h * D;
    newton.factor(c);
    let (rtol, atol) = tolerances;
    let scale: Vec<f64> = stages.y.iter().map(|v| atol + rtol * v.abs()).collect();
    let mut slowest = 0;
    let mut delta = vec![0.0; n];
    // Stage 2 at t + gamma h, then stage 3 at t + h; their explicit parts from k1 (and k2).
    for (s, abscissa) in [(1usize, GAMMA), (2, 1.0)] {
        let Stages { y, stage, k, .. } = stages;
        let base: Vec<f64> = (0..n)
            .map(|i| if s == 1 { y[i] + c * k[0][i] } else { y[i] + h * W * (k[0][i] + k[1][i]) })
            .collect();
        // Stage 2 starts from the line through k1 and the last converged second stage's slope
        // (of the previous step, or of a rejected attempt of this one) at t + gamma h, or
        // from k1; stage 3 from the line through k1 and k2 extended to t + h.
        let (done, rest) = k.split_at_mut(s);
        let ks = &mut rest[0];
        if s == 1 {
            match newton.second_stage.take() {
                Some(tau) if tau != t => {
                    let f = abscissa * h / (tau - t);
                    for i in 0..n {
                        ks[i] = done[0][i] + f * (ks[i] - done[0][i]);
                    }
                }
                _ => ks.copy_from_slice(&done[0]),
            }
        } else {
            for i in 0..n {
                ks[i] = done[0][i] + (done[1][i] - done[0][i]) / GAMMA;
            }
        }
        let mut f = vec![0.0; n];
        let mut converged = false;
        let mut previous = f64::INFINITY;
        for iteration in 1..=MAX_ITERATIONS {
            for i in 0..n {
                stage[i] = base[i] + c * ks[i];
            }
            equations.derivative(t + abscissa * h, stage, &mut f)?;
            newton.iterations += 1;
            for i in 0..n {
                delta[i] = f[i] - ks[i];
            }
            newton.solve(c, &mut delta);
            let mut norm = 0.0;
            for i in 0..n {
                ks[i] += delta[i];
                norm += (c * delta[i] / scale[i]).powi(2);
            }
            let norm = (norm / n.max(1) as f64).sqrt();
            if !norm.is_finite() {
                return Ok(None);
            }
            // The contraction rate: diverging or too slow to converge in the iterations left.
            let rate = norm / previous;
            if iteration > 2 && rate > DIVERGING {
                return Ok(None);
            }
            if norm <= NEWTON_TOLERANCE {
                slowest = slowest.max(iteration);
                converged = true;
                break;
            }
            // The increments fall as rate^k: too slowly to converge in the iterations left.
            let left = (MAX_ITERATIONS - iteration) as i32;
            if iteration > 2 && rate.powi(left) * norm > NEWTON_TOLERANCE {
                return Ok(None);
            }
            previous = norm;
        }
        if !converged {
            return Ok(None);
        }
        if s == 1 {
            newton.second_stage = Some(t + abscissa * h);
        }
    }
    let Stages { y, y_new, stage, k, .. } = stages;
    for i in 0..n {
        y_new[i] = y[i] + h * (W * (k[0][i] + k[1][i]) + D * k[2][i]);
    }
    // dy/dt at the end (first same as last): the converged third stage's slope.
    equations.derivative(t + h, y_new, stage)?;
    k[6].copy_from_slice(stage);
    let mut filtered: Vec<f64> = (0..n)
        .map(|i| h * ((4.0 * W - 1.0) / 3.0 * k[0][i] - k[1][i] / 3.0 + 2.0 * D / 3.0 * k[2][i]))
        .collect();
    newton.solve(c, &mut filtered);
    let sum: f64 = (0..n)
        .map(|i| {
            let s = atol + rtol * y[i].abs().max(y_new[i].abs());
            (filtered[i] / s).powi(2)
        })
        .sum();
    let slow = match newton.jacobian {
        Some(Jacobian::Tree(_)) => SLOW_TREE,
        _ => SLOW,
    };
    if slowest > slow {
        newton.jacobian = None;
    }
    Ok(Some(if n == 0 { 0.0 } else { (sum / n as f64).sqrt() }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::formulation::recursive::LoopClosure;
    use crate::testing::{assert_all_close, assert_close};
    use faer::linalg::solvers::DenseSolveCore;

    /// A right-hand side without a linearization (the Jacobian by differences).
    struct Function<F>(F);

    impl<F: FnMut(f64, &[f64], &mut [f64]) -> Result<()>> Equations for Function<F> {
        fn derivative(&mut self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<()> {
            (self.0)(t, y, dy)
        }
        fn linearization(&mut self, _: f64, _: &[f64]) -> Result<Option<TreeLinearization>> {
            Ok(None)
        }
    }

    /// Seeded entries in (-0.5, 0.5).
    fn sample(count: usize, seed: u64) -> Vec<f64> {
        let mut x = seed;
        (0..count)
            .map(|_| {
                x = x.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                ((x >> 11) as f64) / ((1u64 << 53) as f64) - 0.5
            })
            .collect()
    }

    /// A symmetric positive (semi-)definite n x n matrix A A^T + shift I from seeded entries.
    fn spd(n: usize, seed: u64, shift: f64) -> Mat<f64> {
        let a = sample(n * n, seed);
        Mat::from_fn(n, n, |i, j| (0..n).map(|k| a[i * n + k] * a[j * n + k]).sum::<f64>())
            + Mat::from_fn(n, n, |i, j| if i == j { shift } else { 0.0 })
    }

    /// The Schur complement on the rates solves the same system as the full iteration matrix
    /// I - c J, J = [[0, I], [-P K, -P D]] (P = M^-1, or N (N^T M N)^-1 N^T on the null
    /// space N of two constraint rows), formed and factorized densely.
    #[test]
    fn the_tree_iteration_matrix_solves_the_full_system() {
        let n = 6;
        let c = 0.013;
        let (mass, stiffness, damping) = (spd(n, 1, 0.5), spd(n, 2, 0.0) * 1e4, spd(n, 3, 0.0) * 3.0);
        let constraints = Mat::from_fn(2, n, |i, j| sample(2 * n, 4)[i * n + j]);
        let null = LoopClosure::new(constraints.as_ref(), 2, 0.0).unwrap().null_space();
        assert_eq!(null.ncols(), n - 2);
        for null_space in [None, Some(null)] {
            let inverse = match &null_space {
                None => mass.partial_piv_lu().inverse(),
                Some(v) => v * (v.transpose() * &mass * v).partial_piv_lu().inverse() * v.transpose(),
            };
            let (a_p, a_v) = (-(&inverse * &stiffness), -(&inverse * &damping));
            let full = Mat::from_fn(2 * n, 2 * n, |i, j| {
                let identity = if i == j { 1.0 } else { 0.0 };
                identity
                    - c * match (i < n, j < n) {
                        (true, true) => 0.0,
                        (true, false) => {
                            if j - n == i {
                                1.0
                            } else {
                                0.0
                            }
                        }
                        (false, true) => a_p[(i - n, j)],
                        (false, false) => a_v[(i - n, j - n)],
                    }
            });
            let r = sample(2 * n, 5);
            let expected = full.partial_piv_lu().solve(Mat::from_fn(2 * n, 1, |i, _| r[i]));
            let constrained = null_space.is_some();
            let lin = TreeLinearization {
                mass: mass.clone(),
                stiffness: stiffness.clone(),
                damping: damping.clone(),
                null_space,
            };
            let mut newton = Newton { jacobian: Some(Jacobian::Tree(lin)), ..Newton::default() };
            newton.factor(c);
            let mut x = r.clone();
            newton.solve(c, &mut x);
            let expected: Vec<f64> = (0..2 * n).map(|i| expected[(i, 0)]).collect();
            let what = format!("x (cut joints: {constrained})");
            assert_all_close(&x, &expected, 1e-10, 1e-12, what);
        }
    }

    /// Prothero and Robinson's stiff problem y' = -1e6 (y - cos t) - sin t, y(0) = 1, whose
    /// solution is cos t: explicit methods need h < 2e-6; TR-BDF2 follows cos t at h = 0.01.
    #[test]
    fn follows_a_stiff_problem_at_second_order() {
        let f = |t: f64, y: &[f64], dy: &mut [f64]| {
            dy[0] = -1e6 * (y[0] - t.cos()) - t.sin();
            Ok(())
        };
        let mut equations = Function(f);
        let mut errors = Vec::new();
        for h in [0.02, 0.01] {
            let mut stages = Stages::new(vec![1.0]);
            let mut newton = Newton::default();
            let mut t = 0.0;
            let mut k0 = [0.0];
            f(t, &stages.y, &mut k0).unwrap();
            stages.k[0][0] = k0[0];
            while t < 1.0 - 1e-12 {
                match step(t, h, &mut stages, (1e-3, 1e-6), &mut newton, &mut equations).unwrap() {
                    Outcome::Error(err) => assert!(err.is_finite()),
                    Outcome::NotConverged => panic!("Newton failed at t = {t}"),
                }
                std::mem::swap(&mut stages.y, &mut stages.y_new);
                stages.reuse_last_derivative();
                t += h;
            }
            // A linear problem: one Jacobian for the whole run.
            assert_eq!(newton.jacobians, 1);
            errors.push((stages.y[0] - 1.0f64.cos()).abs());
        }
        assert!(errors[0] < 1e-6, "{errors:?}");
        // The stiff part is damped at once (L-stable); the smooth part converges.
        assert_close(errors[1], 0.0, 0.0, 1e-6, "error at h = 0.01");
    }
}
