//! The one tolerance helper of the tests, for the unit tests beside the code and the
//! integration tests in `tests/`: `actual` is close to `expected` when
//! |actual - expected| <= abs + rel |expected| (NaN never is), and a failure names what was
//! compared, both values, the difference and the tolerance.

use std::fmt::Display;

/// Panics unless `actual` is within `abs + rel |expected|` of `expected`.
#[track_caller]
pub fn assert_close(actual: f64, expected: f64, rel: f64, abs: f64, what: impl Display) {
    let difference = (actual - expected).abs();
    let tolerance = abs + rel * expected.abs();
    if !(difference <= tolerance) {
        panic!(
            "{what}: {actual:e} against {expected:e}: |difference| {difference:e} > \
             {abs:e} + {rel:e} |expected| = {tolerance:e}"
        );
    }
}

/// Panics unless the slices have the same length and every entry of `actual` is within
/// `abs + rel |expected[i]|` of `expected[i]`; the message names the worst entry.
#[track_caller]
pub fn assert_all_close(actual: &[f64], expected: &[f64], rel: f64, abs: f64, what: impl Display) {
    assert_eq!(actual.len(), expected.len(), "{what}: lengths differ");
    let worst = actual
        .iter()
        .zip(expected)
        .enumerate()
        .map(|(i, (a, e))| (i, (a - e).abs() - (abs + rel * e.abs())))
        .fold(None, |best: Option<(usize, f64)>, (i, excess)| match best {
            Some((_, b)) if !(excess > b) && !excess.is_nan() => best,
            _ => Some((i, excess)),
        });
    if let Some((i, _)) = worst {
        assert_close(actual[i], expected[i], rel, abs, format_args!("{what}[{i}]"));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn close_values_pass_and_the_tolerance_is_relative_plus_absolute() {
        assert_close(1.0 + 1e-10, 1.0, 1e-9, 0.0, "relative");
        assert_close(1e-13, 0.0, 1e-9, 1e-12, "absolute floor");
        assert_all_close(&[1.0, 2.0, 3.0], &[1.0, 2.0 + 1e-12, 3.0], 1e-9, 0.0, "vector");
    }

    #[test]
    #[should_panic(expected = "x: 1.1e0 against 1e0")]
    fn a_far_value_fails_naming_both() {
        assert_close(1.1, 1.0, 1e-3, 0.0, "x");
    }

    #[test]
    #[should_panic(expected = "NaN")]
    fn nan_is_never_close() {
        assert_close(f64::NAN, 1.0, 1.0, 1.0, "nan");
    }

    #[test]
    #[should_panic(expected = "v[2]")]
    fn the_worst_entry_is_named() {
        assert_all_close(&[1.0, 2.1, 3.5, 4.0], &[1.0, 2.0, 3.0, 4.0], 1e-9, 0.0, "v");
    }

    #[test]
    #[should_panic(expected = "v[3]: NaN")]
    fn a_nan_entry_is_the_worst() {
        assert_all_close(&[1.0, 2.0, 3.5, f64::NAN], &[1.0, 2.0, 3.0, 4.0], 1e-9, 0.0, "v");
    }
}
