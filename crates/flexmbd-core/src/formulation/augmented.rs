//! Dense form of the constrained equations of motion (seed eqs. 20, 25, 26), for the explicit
//! solvers and the redundancy analysis:
//!
//!   M(q) q_dd + C_q^T lambda = f(q, q_dot, t) = F + Q_e,   C_q q_dd = gamma,
//!
//! with M, f, C, C_q, C_t and gamma taken from the sparse assembly at q_dd = 0, lambda = 0.
//! On a partition (`linalg::partition`) of the constraints and coordinates the accelerations
//! come from either
//!
//! - the augmented system [[M, C_r^T], [C_r, 0]] [q_dd; lambda_r] = [f; gamma_r] over the
//!   independent rows r (seed eq. 26), or
//! - the embedding technique (seed eqs. 27-30): q_dd_d = B_di q_dd_i + C_qd^-1 gamma with
//!   B_di = -C_qd^-1 C_qi, so q_dd = B q_dd_i + g_hat with B = [I; B_di], and the reduced
//!   equations M_ii q_dd_i = R_i with M_ii = B^T M B, R_i = B^T (f - M g_hat); the multipliers
//!   follow from the dependent rows, C_qd^T lambda = f_d - (M q_dd)_d.
//!
//! Redundant rows (outside r) get zero multipliers.

use faer::linalg::solvers::{PartialPivLu, Solve};
use faer::{Mat, Side};

use crate::assembly::{assemble, constraint_time_terms, MatrixCoefficients, Request, StateView};
use crate::error::Result;
use crate::linalg::partition::{minimum_norm_solve, partition_condition, submatrix, Partition};
use crate::system::{Model, Workspace};

/// How the accelerations are solved for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Formulation {
    /// The augmented system of seed eq. 26 (dense LU).
    Augmented,
    /// The embedding technique of seed eqs. 27-30 (reduced mass matrix, Cholesky).
    Embedding,
}

crate::named!(Formulation { Augmented => "augmented", Embedding => "embedding" });

/// What `DenseEquations::evaluate` computes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Level {
    /// C and C_q.
    Position,
    /// And C_t.
    Velocity,
    /// And M, f and gamma.
    Acceleration,
}

/// Relative size of the smallest LU pivot below which a matrix is treated as ill-conditioned:
/// the solves then fall back to truncated singular value decompositions.
pub const ILL_CONDITIONED_PIVOT: f64 = 1e-7;
/// The same for the augmented matrix [[M, C_q^T], [C_q, 0]], whose pivots also span the
/// scales of the mass matrix. Behind the partition-condition test of `accelerations` this is
/// only a safeguard: on A02, Andrews' mechanism and the redundant four-bar the results are the
/// same with 1e-7 and 1e-13. Without that test, thresholds of 1e-9 and below let inaccurate LU
/// accelerations through near the change points of A02 (integrate-all with Dormand-Prince:
/// error 4.3e-6 against 2.1e-7; at 1e-10 the step size collapses), all measured.
pub const SINGULAR_AUGMENTED_PIVOT: f64 = 1e-7;

/// Relative cut-off of the singular values in those fallbacks (near-singular configurations:
/// directions in which the constraints have lost rank are left free for that evaluation).
pub const SINGULAR_VALUE_CUTOFF: f64 = 1e-5;

/// Dense LU with partial pivoting; errors if a pivot is below `ILL_CONDITIONED_PIVOT` times
/// the largest.
pub fn checked_lu(a: &Mat<f64>, what: &str) -> std::result::Result<PartialPivLu<f64>, String> {
    checked_lu_with(a, what, ILL_CONDITIONED_PIVOT)
}

/// `checked_lu` with the smallest admissible ratio of pivots `ratio`.
pub fn checked_lu_with(
    a: &Mat<f64>,
    what: &str,
    ratio: f64,
) -> std::result::Result<PartialPivLu<f64>, String> {
    let lu = a.partial_piv_lu();
    let u = lu.U();
    let (mut largest, mut smallest) = (0.0f64, f64::INFINITY);
    for k in 0..u.nrows() {
        let v = u[(k, k)].abs();
        largest = largest.max(v);
        smallest = smallest.min(v);
    }
    if u.nrows() > 0 && !(smallest > ratio * largest) {
        return Err(format!("{what} is singular (smallest LU pivot {smallest:.3e}, largest {largest:.3e})"));
    }
    Ok(lu)
}

/// The equations of motion at one state, dense.
#[derive(Clone, Debug)]
pub struct DenseEquations {
    /// Mass matrix M (n x n).
    pub mass: Mat<f64>,
    /// Generalized forces f = F + Q_e: quadratic velocity, applied and elastic forces (n).
    pub force: Vec<f64>,
    /// Constraint values C (m).
    pub constraints: Vec<f64>,
    /// Constraint Jacobian C_q (m x n).
    pub jacobian: Mat<f64>,
    /// C_t (m).
    pub rate: Vec<f64>,
    /// gamma of C_q q_dd = gamma (m).
    pub gamma: Vec<f64>,
    zero_coordinates: Vec<f64>,
    zero_multipliers: Vec<f64>,
}

impl DenseEquations {
    /// Buffers for `model`.
    pub fn new(model: &Model) -> Self {
        let (n, m) = (model.coordinate_count, model.constraint_count);
        DenseEquations {
            // Allocated at the first acceleration-level evaluation (the redundancy analysis of
            // large models needs only C_q).
            mass: Mat::zeros(0, 0),
            force: vec![0.0; n],
            constraints: vec![0.0; m],
            jacobian: Mat::zeros(m, n),
            rate: vec![0.0; m],
            gamma: vec![0.0; m],
            zero_coordinates: vec![0.0; n],
            zero_multipliers: vec![0.0; m],
        }
    }

    /// Evaluates the equations at (time, q, q_dot) up to `level`. `ws` must assemble the
    /// elastic blocks of every body (an assembly of `Request::matrix`).
    #[allow(clippy::too_many_arguments)]
    pub fn evaluate(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        time: f64,
        q: &[f64],
        qd: &[f64],
        discrete: &[f64],
        level: Level,
    ) -> Result<()> {
        self.evaluate_sparse(model, ws, time, q, qd, discrete, level)?;
        self.fill_dense(model, ws, level);
        Ok(())
    }

    /// [`DenseEquations::evaluate`] without the dense M and C_q: their values stay in the
    /// workspace's sparse matrix (`ws.values` in the model's pattern, C_q in the rows from n
    /// on), for the sparse joint-space evaluation
    /// ([`crate::formulation::recursive::SparseJointSpace`]). `mass` and `jacobian` keep the
    /// values of the last dense evaluation.
    #[allow(clippy::too_many_arguments)]
    pub fn evaluate_sparse(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        time: f64,
        q: &[f64],
        qd: &[f64],
        discrete: &[f64],
        level: Level,
    ) -> Result<()> {
        let nq = model.coordinate_count;
        let view =
            StateView { time, q, qd, qdd: &self.zero_coordinates, lambda: &self.zero_multipliers, discrete };
        let coefficients = if level == Level::Acceleration {
            MatrixCoefficients::ACCELERATION
        } else {
            MatrixCoefficients {
                mass: 0.0,
                velocity: 0.0,
                position: 0.0,
                identity: 0.0,
                elastic_identity: 0.0,
                scale: 1.0,
            }
        };
        assemble(model, view, ws, &Request::matrix(coefficients))?;
        self.constraints.copy_from_slice(&ws.residual[nq..]);
        if level == Level::Acceleration {
            for k in 0..nq {
                self.force[k] = -ws.residual[k];
            }
        }
        if level >= Level::Velocity {
            let gamma = if level == Level::Acceleration { Some(&mut self.gamma[..]) } else { None };
            constraint_time_terms(model, view, ws, &mut self.rate, gamma)?;
        }
        Ok(())
    }

    /// The dense M (acceleration level) and C_q from the workspace's sparse matrix.
    fn fill_dense(&mut self, model: &Model, ws: &Workspace, level: Level) {
        let nq = model.coordinate_count;
        let pattern = &model.layout.pattern;
        self.jacobian.fill(0.0);
        if level == Level::Acceleration {
            if self.mass.nrows() != nq {
                self.mass = Mat::zeros(nq, nq);
            }
            self.mass.fill(0.0);
        }
        for c in 0..nq {
            for k in pattern.col_ptr[c]..pattern.col_ptr[c + 1] {
                let r = pattern.row_idx[k];
                if r >= nq {
                    self.jacobian[(r - nq, c)] = ws.values[k];
                } else if level == Level::Acceleration {
                    self.mass[(r, c)] = ws.values[k];
                }
            }
        }
    }

    /// Velocity constraint violation C_q q_dot + C_t of row `row` (after a `Velocity` or
    /// `Acceleration` evaluation).
    pub fn velocity_violation(&self, row: usize, qd: &[f64]) -> f64 {
        (0..qd.len()).map(|j| self.jacobian[(row, j)] * qd[j]).sum::<f64>() + self.rate[row]
    }

    /// The accelerations on partition `p` with the right-hand side `gamma` (m entries: the
    /// evaluated one, or a stabilized one) into `qdd`. Near a singular configuration (a
    /// partition condition above `singular_condition`, or an ill-conditioned matrix) they come
    /// from the null-space method with a truncated SVD of C_q instead; returns whether that
    /// happened. The augmented matrix does not depend on the choice of dependent coordinates,
    /// but the partition's condition is kept as the test for both formulations: with the LU
    /// pivot test alone, Dormand-Prince's step size collapses at the change point of the
    /// redundant spatial four-bar (measured). Errors name the singular matrix.
    pub fn accelerations(
        &self,
        p: &Partition,
        formulation: Formulation,
        gamma: &[f64],
        singular_condition: f64,
        qdd: &mut [f64],
    ) -> std::result::Result<bool, String> {
        if !(partition_condition(self.jacobian.as_ref(), &p.rows, &p.dependent) <= singular_condition) {
            return self.null_space_accelerations(p, gamma, qdd).map(|_| true);
        }
        match self.accelerations_with(p, formulation, gamma, qdd) {
            Ok(()) => Ok(false),
            Err(first) => self
                .null_space_accelerations(p, gamma, qdd)
                .map(|_| true)
                .map_err(|second| format!("{first}; the truncated-SVD fallback failed too: {second}")),
        }
    }

    /// The null-space method on the partition's rows (see [`null_space_solve`]), singular
    /// values below `SINGULAR_VALUE_CUTOFF` times the largest treated as zero.
    fn null_space_accelerations(
        &self,
        p: &Partition,
        gamma: &[f64],
        qdd: &mut [f64],
    ) -> std::result::Result<(), String> {
        let n = self.force.len();
        let c = Mat::from_fn(p.rows.len(), n, |a, j| self.jacobian[(p.rows[a], j)]);
        let g: Vec<f64> = p.rows.iter().map(|&r| gamma[r]).collect();
        qdd.copy_from_slice(&null_space_solve(&self.mass, &self.force, &c, &g, SINGULAR_VALUE_CUTOFF)?);
        Ok(())
    }

    fn accelerations_with(
        &self,
        p: &Partition,
        formulation: Formulation,
        gamma: &[f64],
        qdd: &mut [f64],
    ) -> std::result::Result<(), String> {
        let n = self.force.len();
        let r = p.rows.len();
        match formulation {
            Formulation::Augmented => {
                let mut k = Mat::<f64>::zeros(n + r, n + r);
                for i in 0..n {
                    for j in 0..n {
                        k[(i, j)] = self.mass[(i, j)];
                    }
                }
                for (a, &row) in p.rows.iter().enumerate() {
                    for j in 0..n {
                        let v = self.jacobian[(row, j)];
                        k[(n + a, j)] = v;
                        k[(j, n + a)] = v;
                    }
                }
                let lu = checked_lu_with(
                    &k,
                    "augmented acceleration matrix [[M, C_q^T], [C_q, 0]]",
                    SINGULAR_AUGMENTED_PIVOT,
                )?;
                let mut x =
                    Mat::from_fn(n + r, 1, |i, _| if i < n { self.force[i] } else { gamma[p.rows[i - n]] });
                lu.solve_in_place(&mut x);
                for i in 0..n {
                    qdd[i] = x[(i, 0)];
                }
            }
            Formulation::Embedding => {
                let ni = p.independent.len();
                let cd = submatrix(self.jacobian.as_ref(), &p.rows, &p.dependent);
                let lu = checked_lu(&cd, "dependent block C_qd")?;
                // X = C_qd^-1 [C_qi | gamma_r].
                let mut x = Mat::from_fn(r, ni + 1, |a, k| {
                    if k < ni {
                        self.jacobian[(p.rows[a], p.independent[k])]
                    } else {
                        gamma[p.rows[a]]
                    }
                });
                lu.solve_in_place(&mut x);
                let mut b = Mat::<f64>::zeros(n, ni);
                let mut g_hat = vec![0.0; n];
                for (k, &c) in p.independent.iter().enumerate() {
                    b[(c, k)] = 1.0;
                }
                for (a, &d) in p.dependent.iter().enumerate() {
                    for k in 0..ni {
                        b[(d, k)] = -x[(a, k)];
                    }
                    g_hat[d] = x[(a, ni)];
                }
                let mb = &self.mass * &b;
                let m_ii = b.transpose() * &mb;
                let mut rhs = Mat::from_fn(n, 1, |i, _| {
                    self.force[i] - (0..n).map(|j| self.mass[(i, j)] * g_hat[j]).sum::<f64>()
                });
                rhs = b.transpose() * &rhs;
                let llt = m_ii.llt(Side::Lower).map_err(|_| {
                    "reduced mass matrix M_ii = B^T M B of seed eq. 30 is not positive definite".to_string()
                })?;
                llt.solve_in_place(&mut rhs);
                for i in 0..n {
                    qdd[i] = g_hat[i] + (0..ni).map(|k| b[(i, k)] * rhs[(k, 0)]).sum::<f64>();
                }
            }
        }
        if qdd.iter().any(|x| !x.is_finite()) {
            return Err("the accelerations are not finite".to_string());
        }
        Ok(())
    }

    /// Multipliers consistent with `qdd`: C_qd^T lambda_r = (f - M q_dd)_d over the partition's
    /// rows and dependent coordinates (minimum-norm least squares of C_r^T lambda_r = f - M q_dd
    /// if C_qd is ill-conditioned); zero on redundant rows.
    pub fn multipliers(
        &self,
        p: &Partition,
        qdd: &[f64],
        lambda: &mut [f64],
    ) -> std::result::Result<(), String> {
        let n = self.force.len();
        lambda.iter_mut().for_each(|x| *x = 0.0);
        if p.rows.is_empty() {
            return Ok(());
        }
        let residual: Vec<f64> =
            (0..n).map(|i| self.force[i] - (0..n).map(|j| self.mass[(i, j)] * qdd[j]).sum::<f64>()).collect();
        let cd = submatrix(self.jacobian.as_ref(), &p.rows, &p.dependent);
        if let Ok(lu) = checked_lu(&cd, "dependent block C_qd") {
            let mut g = Mat::from_fn(p.dependent.len(), 1, |a, _| residual[p.dependent[a]]);
            lu.solve_transpose_in_place(&mut g);
            for (a, &row) in p.rows.iter().enumerate() {
                lambda[row] = g[(a, 0)];
            }
        } else {
            let ct = Mat::from_fn(n, p.rows.len(), |j, a| self.jacobian[(p.rows[a], j)]);
            let l = minimum_norm_solve(ct.as_ref(), &residual, SINGULAR_VALUE_CUTOFF);
            for (a, &row) in p.rows.iter().enumerate() {
                lambda[row] = l[a];
            }
        }
        if lambda.iter().any(|x| !x.is_finite()) {
            return Err("the multipliers are not finite".to_string());
        }
        Ok(())
    }
}

/// Weight of a constraint row where rows compete (choice of the kept rows of redundant
/// constraints, least-squares initial projection): Euler-parameter normalizations first, then
/// drivers, then joints.
pub(crate) fn row_weight(model: &Model, row: usize) -> f64 {
    if model.normalizations.iter().any(|n| n.row == row) {
        return 1e4;
    }
    match model.joints.iter().find(|j| row >= j.row && row < j.row + j.equations.len()) {
        Some(j) if j.kind.function().is_some() => 1e2,
        _ => 1.0,
    }
}

/// The null-space method for M x + C^T mu = f, C x = g (M symmetric, positive definite on the
/// null space of C): C = U S V^T, x = V_1 S_1^-1 U_1^T g + V_2 z with
/// (V_2^T M V_2) z = V_2^T (f - M x_p); singular values below `cutoff` times the largest count
/// as zero (redundant rows, singular configurations). Errors say which step failed.
pub fn null_space_solve(
    mass: &Mat<f64>,
    force: &[f64],
    c: &Mat<f64>,
    g: &[f64],
    cutoff: f64,
) -> std::result::Result<Vec<f64>, String> {
    let n = force.len();
    let svd = crate::linalg::svd::svd(c.as_ref())
        .map_err(|_| "the SVD of the constraint Jacobian did not converge".to_string())?;
    let s = svd.S().column_vector();
    let largest = if s.nrows() > 0 { s[0] } else { 0.0 };
    let rank = (0..s.nrows()).take_while(|&k| s[k] > cutoff * largest).count();
    // Particular solution V_1 S_1^-1 U_1^T g.
    let (u, v) = (svd.U(), svd.V());
    let mut x = vec![0.0; n];
    for k in 0..rank {
        let coefficient = (0..g.len()).map(|i| u[(i, k)] * g[i]).sum::<f64>() / s[k];
        for (j, xj) in x.iter_mut().enumerate() {
            *xj += v[(j, k)] * coefficient;
        }
    }
    let v2 = v.subcols(rank, n - rank).to_owned();
    let reduced = v2.transpose() * (mass * &v2);
    let residual = Mat::from_fn(n, 1, |i, _| force[i] - (0..n).map(|j| mass[(i, j)] * x[j]).sum::<f64>());
    let mut z = v2.transpose() * &residual;
    let llt = reduced.llt(Side::Lower).map_err(|_| {
        "the mass matrix on the null space of the constraints is not positive definite".to_string()
    })?;
    llt.solve_in_place(&mut z);
    for (i, xi) in x.iter_mut().enumerate() {
        *xi += (0..n - rank).map(|k| v2[(i, k)] * z[(k, 0)]).sum::<f64>();
    }
    if x.iter().any(|v| !v.is_finite()) {
        return Err("the accelerations are not finite".to_string());
    }
    Ok(x)
}

/// Index and magnitude of the largest entry.
pub fn worst(values: &[f64]) -> (usize, f64) {
    values.iter().enumerate().fold((0, 0.0f64), |best, (k, v)| {
        if v.abs() > best.1 || v.is_nan() {
            (k, if v.is_nan() { f64::INFINITY } else { v.abs() })
        } else {
            best
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::initial::dense_initial_conditions;
    use crate::integrator::settings::InitialSettings;
    use crate::integrator::test_models::{ground_joint, unit_body};
    use crate::joint::JointKind;
    use crate::linalg::partition::{partition, PartitionMethod, DEFAULT_RANK_TOLERANCE};
    use crate::math::{Mat3, Vec3};
    use crate::system::State;
    use crate::testing::assert_all_close;
    use crate::SystemBuilder;

    fn rot_z(angle: f64) -> Mat3 {
        let (s, c) = angle.sin_cos();
        Mat3([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    }

    /// A spatial double pendulum of two rigid bodies (revolute to the ground, spherical
    /// between them), spinning and swinging, with gravity: a state with nonzero quadratic
    /// velocity terms and gamma.
    fn double_pendulum() -> (Model, State) {
        let mut sys = SystemBuilder::new();
        sys.set_gravity(Vec3([0.0, -9.81, 0.0])).unwrap();
        let inertia = Mat3::diagonal(Vec3([2e-3, 0.08, 0.09]));
        let first = sys
            .add_rigid_body(
                "first",
                1.0,
                inertia,
                Vec3::ZERO,
                Vec3([0.5, 0.0, 0.0]),
                rot_z(0.0),
                Vec3([0.0, 1.5, 0.0]),
                Vec3([0.0, 0.0, 3.0]),
            )
            .unwrap();
        let second = sys
            .add_rigid_body(
                "second",
                2.0,
                inertia,
                Vec3::ZERO,
                Vec3([1.5, 0.0, 0.0]),
                rot_z(0.3),
                Vec3([0.0, 3.0, 0.5]),
                Vec3([1.0, -2.0, 0.5]),
            )
            .unwrap();
        let g = sys.add_marker("", sys.ground(), Vec3::ZERO, Mat3::IDENTITY).unwrap();
        let a = sys.add_marker("", first, Vec3([-0.5, 0.0, 0.0]), Mat3::IDENTITY).unwrap();
        sys.add_joint("hinge", JointKind::Revolute, [g, a]).unwrap();
        let b = sys.add_marker("", first, Vec3([0.5, 0.0, 0.0]), Mat3::IDENTITY).unwrap();
        let c = sys.add_marker("", second, Vec3([-0.5, 0.0, 0.0]), Mat3::IDENTITY).unwrap();
        sys.add_joint("ball", JointKind::Spherical, [b, c]).unwrap();
        let model = sys.compile().unwrap();
        let mut ws = Workspace::new(&model);
        let mut eq = DenseEquations::new(&model);
        let mut state = State::initial(&model, 0.0);
        dense_initial_conditions(&model, &mut ws, &mut eq, &mut state, &InitialSettings::default()).unwrap();
        (model, state)
    }

    fn evaluated(model: &Model, state: &State) -> DenseEquations {
        let mut ws = Workspace::new(model);
        let mut eq = DenseEquations::new(model);
        eq.evaluate(
            model,
            &mut ws,
            0.0,
            &state.coordinates,
            &state.velocities,
            &state.discrete,
            Level::Acceleration,
        )
        .unwrap();
        eq
    }

    #[test]
    fn augmented_embedding_and_null_space_accelerations_agree_and_satisfy_eq_26() {
        let (model, state) = double_pendulum();
        let eq = evaluated(&model, &state);
        let (n, m) = (model.coordinate_count, model.constraint_count);
        assert!(state.velocities.iter().any(|v| v.abs() > 0.1));
        assert!(eq.gamma.iter().any(|g| g.abs() > 1e-3), "gamma must not vanish for this test");
        let mut results = Vec::new();
        for method in [PartitionMethod::Lu, PartitionMethod::Qr, PartitionMethod::Svd] {
            let p = partition(eq.jacobian.as_ref(), method, DEFAULT_RANK_TOLERANCE);
            assert_eq!(p.rank, m);
            for formulation in [Formulation::Augmented, Formulation::Embedding] {
                let mut qdd = vec![0.0; n];
                let fallback = eq.accelerations(&p, formulation, &eq.gamma, f64::INFINITY, &mut qdd).unwrap();
                assert!(!fallback);
                results.push(qdd);
            }
            let mut qdd = vec![0.0; n];
            eq.null_space_accelerations(&p, &eq.gamma, &mut qdd).unwrap();
            results.push(qdd);
        }
        let scale = results[0].iter().fold(0.0f64, |a, v| a.max(v.abs()));
        for (k, qdd) in results.iter().enumerate().skip(1) {
            assert_all_close(
                qdd,
                &results[0],
                0.0,
                1e-10 * scale,
                format_args!("q_dd of solve {k} against solve 0"),
            );
        }
        // Seed eq. 26 by residuals: C_q q_dd = gamma, and M q_dd + C_q^T lambda = f with the
        // multipliers recovered from the dependent rows (seed eq. 30).
        let qdd = &results[0];
        let lhs: Vec<f64> = (0..m).map(|r| (0..n).map(|j| eq.jacobian[(r, j)] * qdd[j]).sum()).collect();
        assert_all_close(&lhs, &eq.gamma, 0.0, 1e-10 * scale.max(1.0), "C_q q_dd against gamma");
        let p = partition(eq.jacobian.as_ref(), PartitionMethod::Lu, DEFAULT_RANK_TOLERANCE);
        let mut lambda = vec![0.0; m];
        eq.multipliers(&p, qdd, &mut lambda).unwrap();
        let force_scale = eq.force.iter().fold(1.0f64, |a, v| a.max(v.abs()));
        let lhs: Vec<f64> = (0..n)
            .map(|i| {
                (0..n).map(|j| eq.mass[(i, j)] * qdd[j]).sum::<f64>()
                    + (0..m).map(|r| eq.jacobian[(r, i)] * lambda[r]).sum::<f64>()
            })
            .collect();
        assert_all_close(&lhs, &eq.force, 0.0, 1e-9 * force_scale, "M q_dd + C_q^T lambda against f");
    }

    #[test]
    fn baumgarte_right_hand_side_changes_only_the_constraint_accelerations() {
        // gamma + delta: the accelerations move by a particular solution of C_q dq_dd = delta.
        let (model, state) = double_pendulum();
        let eq = evaluated(&model, &state);
        let (n, m) = (model.coordinate_count, model.constraint_count);
        let p = partition(eq.jacobian.as_ref(), PartitionMethod::Lu, DEFAULT_RANK_TOLERANCE);
        let shifted: Vec<f64> =
            eq.gamma.iter().enumerate().map(|(k, g)| g + 0.1 * (k as f64 + 1.0)).collect();
        for formulation in [Formulation::Augmented, Formulation::Embedding] {
            let mut qdd = vec![0.0; n];
            eq.accelerations(&p, formulation, &shifted, f64::INFINITY, &mut qdd).unwrap();
            let lhs: Vec<f64> = (0..m).map(|r| (0..n).map(|j| eq.jacobian[(r, j)] * qdd[j]).sum()).collect();
            assert_all_close(
                &lhs,
                &shifted,
                0.0,
                1e-9,
                format_args!("{formulation:?}: C_q q_dd against gamma + delta"),
            );
        }
    }

    #[test]
    fn weighted_initial_projection_names_the_conflicting_joints() {
        // A pinned body cannot also reach a ground point 5 m away with a marker 1 m from its
        // pin: the compromise keeps the normalization and names both joints.
        let mut sys = SystemBuilder::new();
        let body = unit_body(&mut sys, "body", Vec3::ZERO);
        ground_joint(&mut sys, "pin", JointKind::Revolute, body, Vec3::ZERO, Vec3::ZERO);
        ground_joint(
            &mut sys,
            "unreachable",
            JointKind::Spherical,
            body,
            Vec3([5.0, 0.0, 0.0]),
            Vec3([1.0, 0.0, 0.0]),
        );
        let model = sys.compile().unwrap();
        let mut ws = Workspace::new(&model);
        let mut eq = DenseEquations::new(&model);
        let mut state = State::initial(&model, 0.0);
        let error =
            dense_initial_conditions(&model, &mut ws, &mut eq, &mut state, &InitialSettings::default())
                .unwrap_err()
                .to_string();
        assert!(error.contains("'pin'") && error.contains("'unreachable'"), "{error}");
        assert!(!error.contains("normalization"), "{error}");
    }
}
