//! The one tolerance helper of the tests, for the unit tests beside the code and the
//! integration tests in `tests/`: `actual` is close to `expected` when
//! |actual - expected| <= abs + rel |expected| (NaN never is), and a failure names what was
//! compared, both values, the difference and the tolerance. Also the models both kinds of
//! tests share ([`a02_four_bar`]).

use std::fmt::Display;

use crate::joint::JointKind;
use crate::math::{Mat3, Vec3};
use crate::system::sensor::SensorQuantity;
use crate::{Model, SensorId, SystemBuilder};

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

/// IFToMM A02 with `n` four-bars in 3D (as `flexmbd.examples.four_bar`): 2n + 1 uniform 1 kg,
/// 1 m links; cranks vertical on revolute pivots at x = 0..n, couplers horizontal at y = 1 on
/// a revolute joint to crank k and an in-line (in-plane position) joint to crank k + 1, so the
/// 3D model has no redundant equations; gravity along -y; B0 (the top of crank 0) starts at
/// 1 m/s along x. The markers at the cranks' tops are "B0".."Bn"; the sensors "B0" and
/// "B0 velocity" (the first returned) follow B0.
pub fn a02_four_bar(n: usize) -> (Model, SensorId) {
    let rz = |angle: f64| {
        let (s, c) = angle.sin_cos();
        Mat3([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    };
    let (up, to_joint) = (rz(std::f64::consts::FRAC_PI_2), rz(-std::f64::consts::FRAC_PI_2));
    let mut sys = SystemBuilder::new();
    sys.set_gravity(Vec3([0.0, -9.81, 0.0])).unwrap();
    // Slender rods along their local x axes.
    let inertia = Mat3::diagonal(Vec3([5e-5, 1.0 / 12.0, 1.0 / 12.0]));
    let ground = sys.ground();
    let mut tops = Vec::new();
    let mut b0 = None;
    for k in 0..=n {
        let x = k as f64;
        let crank = sys
            .add_rigid_body(
                &format!("crank {k}"),
                1.0,
                inertia,
                Vec3::ZERO,
                Vec3([x, 0.5, 0.0]),
                up,
                Vec3([0.5, 0.0, 0.0]),
                Vec3([0.0, 0.0, -1.0]),
            )
            .unwrap();
        // Local x runs up the crank: the pivot is at local -0.5, the top at +0.5.
        let pivot = sys.add_marker("", ground, Vec3([x, 0.0, 0.0]), Mat3::IDENTITY).unwrap();
        let bottom = sys.add_marker("", crank, Vec3([-0.5, 0.0, 0.0]), to_joint).unwrap();
        sys.add_joint(&format!("pivot {k}"), JointKind::Revolute, [pivot, bottom]).unwrap();
        let top = sys.add_marker(&format!("B{k}"), crank, Vec3([0.5, 0.0, 0.0]), to_joint).unwrap();
        if k == 0 {
            b0 = Some(sys.add_sensor("B0", top, SensorQuantity::Position).unwrap());
            sys.add_sensor("B0 velocity", top, SensorQuantity::Velocity).unwrap();
        }
        tops.push(top);
    }
    for k in 0..n {
        let coupler = sys
            .add_rigid_body(
                &format!("coupler {k}"),
                1.0,
                inertia,
                Vec3::ZERO,
                Vec3([k as f64 + 0.5, 1.0, 0.0]),
                Mat3::IDENTITY,
                Vec3([1.0, 0.0, 0.0]),
                Vec3::ZERO,
            )
            .unwrap();
        let left = sys.add_marker("", coupler, Vec3([-0.5, 0.0, 0.0]), Mat3::IDENTITY).unwrap();
        let right = sys.add_marker("", coupler, Vec3([0.5, 0.0, 0.0]), Mat3::IDENTITY).unwrap();
        sys.add_joint(&format!("coupler {k} left"), JointKind::Revolute, [tops[k], left]).unwrap();
        sys.add_joint(&format!("coupler {k} right"), JointKind::Inline, [tops[k + 1], right]).unwrap();
    }
    (sys.compile().unwrap(), b0.expect("crank 0 exists"))
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
