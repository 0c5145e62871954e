//! Generalized coordinate partitioning (seed section 4, "Solution for the accelerations"): the
//! constraint Jacobian C_q (m x n) at a configuration is split into r = rank(C_q) independent
//! constraint rows, m - r redundant rows (linear combinations of the others), r dependent
//! coordinates q_d whose block C_qd (rows x dependent, r x r) is nonsingular, and n - r
//! independent coordinates q_i (the degrees of freedom).
//!
//! Three rank-revealing decompositions choose the partition:
//!
//! - `Lu`: Gaussian elimination with full (row and column) pivoting, Wehage's choice: the
//!   pivot rows are the independent rows, the pivot columns the dependent coordinates.
//! - `Qr`: Householder QR with column pivoting, of C_q^T for the rows and of the selected rows
//!   for the columns.
//! - `Svd`: the singular values give the rank; QR with column pivoting of the leading left
//!   (right) singular vectors picks the rows (the dependent coordinates) that span the row
//!   space (the column space) best.
//!
//! The rank counts the pivots (diagonal entries of R, singular values) above `tolerance`
//! times the largest. Dense linear algebra: the cost is O(m n min(m, n)).

use faer::linalg::solvers::Solve;
use faer::{Mat, MatRef};

/// Default relative tolerance of the rank decision.
pub const DEFAULT_RANK_TOLERANCE: f64 = 1e-9;

/// The decomposition that chooses a partition.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PartitionMethod {
    /// LU with full pivoting (Wehage and Haug).
    Lu,
    /// QR with column pivoting.
    Qr,
    /// Singular value decomposition.
    Svd,
}

crate::named!(PartitionMethod { Lu => "lu", Qr => "qr", Svd => "svd" });

/// A partition of the constraint rows and of the coordinates.
#[derive(Clone, Debug, PartialEq)]
pub struct Partition {
    /// The decomposition that chose it (None: independent coordinates given by the user).
    pub method: Option<PartitionMethod>,
    /// Rank of C_q.
    pub rank: usize,
    /// Independent constraint rows (rank of them), ascending.
    pub rows: Vec<usize>,
    /// Redundant constraint rows (combinations of `rows`), ascending.
    pub redundant_rows: Vec<usize>,
    /// Dependent coordinates (rank of them), ascending.
    pub dependent: Vec<usize>,
    /// Independent coordinates (the degrees of freedom), ascending.
    pub independent: Vec<usize>,
    /// Condition of the partition: |C_q[rows, :]|_F |C_qd^-1|_F, the Frobenius norm of the
    /// kept rows times that of the inverse of the dependent block C_qd = C_q[rows, dependent].
    /// It bounds how strongly the dependent coordinates react to the independent ones
    /// (|B_di| = |C_qd^-1 C_qi|) and grows without bound as the block becomes singular, also
    /// for a 1 x 1 block (where the ordinary condition number stays 1).
    pub condition: f64,
}

/// The leading `count` pivots of QR with column pivoting of `a` (its column indices in pivot
/// order), and the magnitudes of R's diagonal.
fn column_pivots(a: MatRef<'_, f64>) -> (Vec<usize>, Vec<f64>) {
    let (m, n) = a.shape();
    if m == 0 || n == 0 {
        return ((0..n).collect(), Vec::new());
    }
    let qr = a.col_piv_qr();
    let r = qr.R();
    let diagonal = (0..m.min(n)).map(|k| r[(k, k)].abs()).collect();
    (qr.P().arrays().0.to_vec(), diagonal)
}

/// Number of leading entries of a non-increasing magnitude sequence above `tolerance` times
/// its first.
fn numerical_rank(pivots: &[f64], tolerance: f64) -> usize {
    let Some(&first) = pivots.first() else { return 0 };
    if !(first > 0.0) {
        return 0;
    }
    pivots.iter().take_while(|&&p| p > tolerance * first).count()
}

/// The submatrix `a[rows, cols]`.
pub fn submatrix(a: MatRef<'_, f64>, rows: &[usize], cols: &[usize]) -> Mat<f64> {
    Mat::from_fn(rows.len(), cols.len(), |i, j| a[(rows[i], cols[j])])
}

/// The condition of a partition (see `Partition::condition`): |a[rows, :]|_F |a[rows,
/// dependent]^-1|_F; infinite if the block is singular, 1 if it is empty.
pub fn partition_condition(a: MatRef<'_, f64>, rows: &[usize], dependent: &[usize]) -> f64 {
    if rows.is_empty() {
        return 1.0;
    }
    let norm =
        rows.iter().map(|&r| (0..a.ncols()).map(|c| a[(r, c)].powi(2)).sum::<f64>()).sum::<f64>().sqrt();
    let block = submatrix(a, rows, dependent);
    let lu = block.partial_piv_lu();
    let u = lu.U();
    if (0..u.nrows()).any(|k| u[(k, k)] == 0.0 || !u[(k, k)].is_finite()) {
        return f64::INFINITY;
    }
    let mut inverse = Mat::<f64>::identity(rows.len(), rows.len());
    lu.solve_in_place(&mut inverse);
    let inverse_norm = inverse.norm_l2();
    if inverse_norm.is_finite() {
        norm * inverse_norm
    } else {
        f64::INFINITY
    }
}

fn sorted(mut v: Vec<usize>) -> Vec<usize> {
    v.sort_unstable();
    v
}

/// Completes a partition from its rows and dependent coordinates (in any order).
fn finish(
    a: MatRef<'_, f64>,
    method: Option<PartitionMethod>,
    rows: Vec<usize>,
    dependent: Vec<usize>,
) -> Partition {
    let (m, n) = a.shape();
    let rows = sorted(rows);
    let dependent = sorted(dependent);
    let mut is_row = vec![false; m];
    rows.iter().for_each(|&r| is_row[r] = true);
    let mut is_dependent = vec![false; n];
    dependent.iter().for_each(|&d| is_dependent[d] = true);
    let condition = partition_condition(a, &rows, &dependent);
    Partition {
        method,
        rank: rows.len(),
        redundant_rows: (0..m).filter(|&r| !is_row[r]).collect(),
        independent: (0..n).filter(|&c| !is_dependent[c]).collect(),
        rows,
        dependent,
        condition,
    }
}

/// Chooses the partition of `a` = C_q (m x n) with `method`; ranks decided with the relative
/// `tolerance`.
pub fn partition(a: MatRef<'_, f64>, method: PartitionMethod, tolerance: f64) -> Partition {
    let (m, n) = a.shape();
    if m == 0 || n == 0 {
        return finish(a, Some(method), Vec::new(), Vec::new());
    }
    let (rows, dependent) = match method {
        PartitionMethod::Lu => {
            let lu = a.full_piv_lu();
            let u = lu.U();
            let pivots: Vec<f64> = (0..m.min(n)).map(|k| u[(k, k)].abs()).collect();
            // Full pivoting keeps |u_kk| non-increasing up to rounding; the rank is the
            // number of pivots above the tolerance.
            let rank = numerical_rank(&pivots, tolerance);
            (lu.P().arrays().0[..rank].to_vec(), lu.Q().arrays().0[..rank].to_vec())
        }
        PartitionMethod::Qr => {
            let (row_order, pivots) = column_pivots(a.transpose());
            let rank = numerical_rank(&pivots, tolerance);
            let rows = row_order[..rank].to_vec();
            let selected = Mat::from_fn(rank, n, |i, j| a[(rows[i], j)]);
            let (columns, _) = column_pivots(selected.as_ref());
            (rows, columns[..rank].to_vec())
        }
        PartitionMethod::Svd => {
            let Ok(svd) = super::svd::thin_svd(a) else {
                // The SVD iteration did not converge (non-finite input): fall back to LU.
                return partition(a, PartitionMethod::Lu, tolerance);
            };
            let s = svd.S().column_vector();
            let values: Vec<f64> = (0..s.nrows()).map(|k| s[k]).collect();
            let rank = numerical_rank(&values, tolerance);
            let u1t = Mat::from_fn(rank, m, |i, j| svd.U()[(j, i)]);
            let v1t = Mat::from_fn(rank, n, |i, j| svd.V()[(j, i)]);
            let (rows, _) = column_pivots(u1t.as_ref());
            let (columns, _) = column_pivots(v1t.as_ref());
            (rows[..rank].to_vec(), columns[..rank].to_vec())
        }
    };
    finish(a, Some(method), rows, dependent)
}

/// The partition with the given independent coordinates: the rows are chosen by QR with
/// column pivoting of C_q^T, the dependent coordinates are the others. Errors (with the
/// reason) when their number is not the rank or their block is singular.
pub fn partition_with_independent(
    a: MatRef<'_, f64>,
    independent: &[usize],
    tolerance: f64,
) -> std::result::Result<Partition, String> {
    let (_, n) = a.shape();
    if let Some(&bad) = independent.iter().find(|&&c| c >= n) {
        return Err(format!("coordinate index {bad} is out of range (the model has {n} coordinates)"));
    }
    let mut is_independent = vec![false; n];
    for &c in independent {
        if is_independent[c] {
            return Err(format!("coordinate {c} is listed twice"));
        }
        is_independent[c] = true;
    }
    let (row_order, pivots) = column_pivots(a.transpose());
    let rank = numerical_rank(&pivots, tolerance);
    let dependent: Vec<usize> = (0..n).filter(|&c| !is_independent[c]).collect();
    if dependent.len() != rank {
        return Err(format!(
            "{} independent coordinates given, but the constraints leave {} degrees of freedom \
             ({} coordinates, constraint rank {rank})",
            independent.len(),
            n - rank,
            n
        ));
    }
    let p = finish(a, None, row_order[..rank].to_vec(), dependent);
    if !(p.condition < 1.0 / tolerance) {
        return Err(format!(
            "the dependent block C_qd is singular (condition number {:.3e}): the given \
             coordinates are not independent",
            p.condition
        ));
    }
    Ok(p)
}

/// Groups of constraint rows that are linearly dependent together: for each vector of the
/// left null space of `a` (m x n, from the SVD), the rows with a weight above 1e-6 of its
/// largest.
pub fn dependent_row_groups(a: MatRef<'_, f64>, tolerance: f64) -> Vec<Vec<usize>> {
    let (m, n) = a.shape();
    if m == 0 {
        return Vec::new();
    }
    // The left singular vectors of a are the right ones of a^T; the thin SVD of a^T (n x m)
    // has all m of them when n >= m and never forms an n x n factor.
    let decomposition = if n >= m { super::svd::thin_svd(a.transpose()) } else { super::svd::svd(a) };
    let Ok(svd) = decomposition else { return Vec::new() };
    let s = svd.S().column_vector();
    let values: Vec<f64> = (0..s.nrows()).map(|k| s[k]).collect();
    let rank = numerical_rank(&values, tolerance);
    let left = if n >= m { svd.V() } else { svd.U() };
    (rank..m)
        .map(|k| {
            let largest = (0..m).map(|i| left[(i, k)].abs()).fold(0.0, f64::max);
            (0..m).filter(|&i| left[(i, k)].abs() > 1e-6 * largest).collect()
        })
        .collect()
}

/// The `count` rows of `a` that QR with column pivoting of a^T takes first (the best
/// conditioned choice it finds), ascending.
pub fn leading_rows(a: MatRef<'_, f64>, count: usize) -> Vec<usize> {
    let (order, _) = column_pivots(a.transpose());
    sorted(order[..count.min(order.len())].to_vec())
}

/// The conditioning of the rows `rows` of `a`: their smallest singular value over their
/// largest (1 for no rows, 0 if they are dependent or the decomposition fails).
pub fn row_conditioning(a: MatRef<'_, f64>, rows: &[usize]) -> f64 {
    if rows.is_empty() {
        return 1.0;
    }
    let kept = Mat::from_fn(rows.len(), a.ncols(), |i, j| a[(rows[i], j)]);
    let Ok(s) = super::svd::singular_values(kept.as_ref()) else { return 0.0 };
    let largest = s.iter().copied().fold(0.0, f64::max);
    let smallest = if rows.len() > a.ncols() { 0.0 } else { s.iter().copied().fold(f64::INFINITY, f64::min) };
    if largest > 0.0 {
        smallest / largest
    } else {
        0.0
    }
}

/// Minimum-norm least-squares solution x of `a x = b` (m x n), singular values below
/// `tolerance` times the largest treated as zero (truncated pseudo-inverse).
pub fn minimum_norm_solve(a: MatRef<'_, f64>, b: &[f64], tolerance: f64) -> Vec<f64> {
    let (m, n) = a.shape();
    let mut x = vec![0.0; n];
    if m == 0 || n == 0 {
        return x;
    }
    let Ok(svd) = super::svd::thin_svd(a) else {
        return vec![f64::NAN; n];
    };
    let (u, v) = (svd.U(), svd.V());
    let s = svd.S().column_vector();
    let largest = s[0];
    for k in 0..s.nrows() {
        if !(s[k] > tolerance * largest) {
            break;
        }
        let coefficient = (0..m).map(|i| u[(i, k)] * b[i]).sum::<f64>() / s[k];
        for j in 0..n {
            x[j] += v[(j, k)] * coefficient;
        }
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::assert_close;

    const METHODS: [PartitionMethod; 3] = [PartitionMethod::Lu, PartitionMethod::Qr, PartitionMethod::Svd];

    /// A pseudo-random matrix (deterministic).
    fn random(m: usize, n: usize, seed: u64) -> Mat<f64> {
        let mut state = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        Mat::from_fn(m, n, |_, _| {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        })
    }

    /// 5 x 9 of rank 3: rows 3 and 4 are combinations of rows 0..3.
    fn rank_deficient() -> Mat<f64> {
        let base = random(3, 9, 7);
        Mat::from_fn(5, 9, |i, j| match i {
            0..=2 => base[(i, j)],
            3 => base[(0, j)] - 2.0 * base[(2, j)],
            _ => 0.5 * base[(1, j)] + base[(2, j)],
        })
    }

    #[test]
    fn full_rank_partition_has_a_well_conditioned_dependent_block() {
        let a = random(4, 10, 3);
        for method in METHODS {
            let p = partition(a.as_ref(), method, DEFAULT_RANK_TOLERANCE);
            assert_eq!(p.rank, 4, "{method:?}");
            assert_eq!(p.rows, vec![0, 1, 2, 3]);
            assert!(p.redundant_rows.is_empty());
            assert_eq!(p.dependent.len(), 4);
            assert_eq!(p.independent.len(), 6);
            assert!(p.condition < 1e3, "{method:?}: {}", p.condition);
            // Not below the ordinary condition number of the block.
            let block = submatrix(a.as_ref(), &p.rows, &p.dependent);
            let s = block.singular_values().unwrap();
            assert!(p.condition >= s[0] / s[3]);
        }
    }

    #[test]
    fn redundant_rows_are_found_by_every_method() {
        let a = rank_deficient();
        for method in METHODS {
            let p = partition(a.as_ref(), method, DEFAULT_RANK_TOLERANCE);
            assert_eq!(p.rank, 3, "{method:?}");
            assert_eq!(p.redundant_rows.len(), 2);
            assert_eq!(p.dependent.len(), 3);
            assert!(p.condition < 1e6, "{method:?}: {}", p.condition);
            // The kept rows span the removed ones: rank of the kept rows is 3.
            let kept = Mat::from_fn(3, 9, |i, j| a[(p.rows[i], j)]);
            let q = partition(kept.as_ref(), method, DEFAULT_RANK_TOLERANCE);
            assert_eq!(q.rank, 3);
        }
    }

    #[test]
    fn condition_grows_as_a_single_dependent_coordinate_loses_its_pivot() {
        // A pendulum x^2 + y^2 = 1 near the bottom: x = 1e-3, y = -1; with x dependent the
        // partition is poor even though a 1 x 1 block has condition number 1.
        let a = Mat::from_fn(1, 2, |_, j| [2e-3, -2.0][j]);
        // ||C_q||_F ||C_qd^-1||_F = sqrt(2e-3^2 + 2^2) / 2e-3.
        let expected = (4e-6f64 + 4.0).sqrt() / 2e-3;
        let condition = partition_condition(a.as_ref(), &[0], &[0]);
        assert_close(condition, expected, 1e-9, 0.0, "condition with x dependent");
        let p = partition(a.as_ref(), PartitionMethod::Lu, DEFAULT_RANK_TOLERANCE);
        assert_eq!(p.dependent, vec![1]);
        assert_close(p.condition, (4e-6f64 + 4.0).sqrt() / 2.0, 0.0, 1e-12, "condition with y dependent");
    }

    #[test]
    fn lu_partition_follows_the_largest_pivots() {
        // Row 0 depends most strongly on coordinate 2, row 1 on coordinate 0.
        let a = Mat::from_fn(2, 3, |i, j| [[0.1, 0.0, 5.0], [3.0, 0.2, 0.1]][i][j]);
        let p = partition(a.as_ref(), PartitionMethod::Lu, DEFAULT_RANK_TOLERANCE);
        assert_eq!(p.dependent, vec![0, 2]);
        assert_eq!(p.independent, vec![1]);
    }

    #[test]
    fn dependent_groups_name_the_rows_of_each_dependency() {
        let a = rank_deficient();
        let groups = dependent_row_groups(a.as_ref(), DEFAULT_RANK_TOLERANCE);
        assert_eq!(groups.len(), 2);
        let all: Vec<usize> = sorted(groups.concat());
        // Both dependencies involve only rows 0..5; row 1 only through the second.
        assert!(all.iter().all(|&r| r < 5));
        // A duplicated row: the dependency involves exactly the two copies.
        let d = Mat::from_fn(3, 4, |i, j| {
            [[1.0, 2.0, 0.0, 1.0], [0.0, 1.0, 1.0, 0.0], [1.0, 2.0, 0.0, 1.0]][i][j]
        });
        assert_eq!(dependent_row_groups(d.as_ref(), DEFAULT_RANK_TOLERANCE), vec![vec![0, 2]]);
    }

    #[test]
    fn given_independent_coordinates_are_checked() {
        let a = Mat::from_fn(2, 4, |i, j| [[1.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 1.0]][i][j]);
        let p = partition_with_independent(a.as_ref(), &[0, 2], DEFAULT_RANK_TOLERANCE).unwrap();
        assert_eq!(p.dependent, vec![1, 3]);
        let e = partition_with_independent(a.as_ref(), &[0, 1], DEFAULT_RANK_TOLERANCE).unwrap_err();
        assert!(e.contains("singular"), "{e}");
        let e = partition_with_independent(a.as_ref(), &[0], DEFAULT_RANK_TOLERANCE).unwrap_err();
        assert!(e.contains("2 degrees of freedom"), "{e}");
        let e = partition_with_independent(a.as_ref(), &[0, 7], DEFAULT_RANK_TOLERANCE).unwrap_err();
        assert!(e.contains("out of range"), "{e}");
    }

    #[test]
    fn minimum_norm_solution_of_a_rank_deficient_system() {
        let a = rank_deficient();
        let x0 = random(9, 1, 11);
        let b: Vec<f64> = (0..5).map(|i| (0..9).map(|j| a[(i, j)] * x0[(j, 0)]).sum()).collect();
        let x = minimum_norm_solve(a.as_ref(), &b, 1e-10);
        for i in 0..5 {
            let ax: f64 = (0..9).map(|j| a[(i, j)] * x[j]).sum();
            assert_close(ax, b[i], 0.0, 1e-12, format_args!("row {i}"));
        }
        // Minimum norm: x lies in the row space, so it is no longer than x0.
        let norm = |v: &[f64]| v.iter().map(|y| y * y).sum::<f64>().sqrt();
        let x0v: Vec<f64> = (0..9).map(|j| x0[(j, 0)]).collect();
        assert!(norm(&x) <= norm(&x0v) + 1e-12);
    }
}
