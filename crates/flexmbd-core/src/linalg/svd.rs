//! Singular value decompositions that converge: faer's, retried without the entries below the
//! round-off of the largest where its iteration fails.

use faer::linalg::solvers::{Svd, SvdError};
use faer::{Mat, MatRef};

/// `a` with the entries below the round-off of its largest (`f64::EPSILON` times it) zeroed, or
/// None if it has none. faer's SVD iteration fails to converge on some well-conditioned
/// matrices that carry such entries, and converges without them: a constraint Jacobian of the
/// planar four-bar (34 x 35, singular values 3.4 to 0.028) with entries of 2e-23 to 1e-22
/// beside ones of 2 ended a run of Runge-Kutta 4 with partitioning in "the SVD of the constraint
/// Jacobian did not converge". Zeroing them changes `a` by less than the round-off of its
/// decomposition.
fn flushed(a: MatRef<'_, f64>) -> Option<Mat<f64>> {
    let largest =
        (0..a.ncols()).flat_map(|j| (0..a.nrows()).map(move |i| a[(i, j)].abs())).fold(0.0, f64::max);
    let floor = f64::EPSILON * largest;
    let tiny = |x: f64| x != 0.0 && x.abs() < floor;
    let any = (0..a.ncols()).any(|j| (0..a.nrows()).any(|i| tiny(a[(i, j)])));
    any.then(|| Mat::from_fn(a.nrows(), a.ncols(), |i, j| if tiny(a[(i, j)]) { 0.0 } else { a[(i, j)] }))
}

/// The full SVD of `a` (see [`flushed`]).
pub fn svd(a: MatRef<'_, f64>) -> Result<Svd<f64>, SvdError> {
    a.svd().or_else(|error| flushed(a).map_or(Err(error), |b| b.svd()))
}

/// The thin SVD of `a` (see [`flushed`]).
pub fn thin_svd(a: MatRef<'_, f64>) -> Result<Svd<f64>, SvdError> {
    a.thin_svd().or_else(|error| flushed(a).map_or(Err(error), |b| b.thin_svd()))
}

/// The singular values of `a`, largest first (see [`flushed`]).
pub fn singular_values(a: MatRef<'_, f64>) -> Result<Vec<f64>, SvdError> {
    a.singular_values().or_else(|error| flushed(a).map_or(Err(error), |b| b.singular_values()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A matrix on which faer's SVD iteration fails: the 34 x 35 constraint Jacobian of the
    /// four-bar example at t = 0.701325 s of a run of Runge-Kutta 4 with partitioning at
    /// h = 5e-5 (`svd_failure.txt`: rows of entries, written on the failure).
    fn four_bar_jacobian() -> Mat<f64> {
        let text = include_str!("svd_failure.txt");
        let rows: Vec<Vec<f64>> = text
            .lines()
            .map(|l| l.split_whitespace().map(|v| v.parse().expect("a number")).collect())
            .collect();
        Mat::from_fn(rows.len(), rows[0].len(), |i, j| rows[i][j])
    }

    #[test]
    fn a_jacobian_with_entries_below_round_off_is_decomposed() {
        let a = four_bar_jacobian();
        assert!(a.svd().is_err() && a.thin_svd().is_err(), "faer's own iteration converges now");
        for decomposition in [svd(a.as_ref()).expect("svd"), thin_svd(a.as_ref()).expect("thin svd")] {
            // U S V^T reproduces a to round-off; the singular values are numpy's (LAPACK's).
            let (u, v) = (decomposition.U(), decomposition.V());
            let s = decomposition.S().column_vector();
            let k = s.nrows();
            let rebuilt = Mat::from_fn(a.nrows(), a.ncols(), |i, j| {
                (0..k).map(|r| u[(i, r)] * s[r] * v[(j, r)]).sum::<f64>()
            });
            let error = (0..a.ncols())
                .flat_map(|j| (0..a.nrows()).map(move |i| (i, j)))
                .fold(0.0f64, |m, (i, j)| m.max((rebuilt[(i, j)] - a[(i, j)]).abs()));
            assert!(error < 1e-14, "U S V^T off by {error:e}");
            assert!((s[0] - 3.38286899).abs() < 1e-8 && (s[k - 1] - 0.02804397).abs() < 1e-8);
        }
        let values = singular_values(a.as_ref()).expect("singular values");
        assert_eq!(values.len(), 34);
        // Nothing below round-off: the matrix as it is.
        assert!(flushed(Mat::<f64>::identity(3, 3).as_ref()).is_none());
    }
}
