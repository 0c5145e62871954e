//! Rest-to-rest motion profiles: a value that rests at `start_value` until `start_time`,
//! moves to `end_value` by `end_time` and rests there, with exact first and second
//! derivatives. The shapes are the cam and robot-trajectory laws: the cubic step (zero end
//! velocity), the quintic step (zero end velocity and acceleration), the cycloidal law (zero
//! end velocity and acceleration, a sinusoidal acceleration) and the trapezoidal velocity
//! (constant acceleration, coast, constant deceleration: a linear segment with parabolic
//! blends).

use std::f64::consts::PI;

/// The law of a [`MotionProfile`] over its normalized time s in [0, 1].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ProfileShape {
    /// 3 s^2 - 2 s^3: velocity zero at both ends, acceleration jumps there.
    Cubic,
    /// 10 s^3 - 15 s^4 + 6 s^5: velocity and acceleration zero at both ends.
    Quintic,
    /// s - sin(2 pi s) / (2 pi): velocity and acceleration zero at both ends.
    Cycloidal,
    /// Constant acceleration over the fraction `blend` of the duration, constant velocity,
    /// constant deceleration over the last `blend` (0 < blend <= 1/2; 1/2: triangular velocity).
    Trapezoidal {
        /// Acceleration time over the duration.
        blend: f64,
    },
}

impl ProfileShape {
    /// The law p(s) with p(0) = 0, p(1) = 1, and its first and second derivatives in s.
    fn law(self, s: f64) -> [f64; 3] {
        match self {
            ProfileShape::Cubic => [s * s * (3.0 - 2.0 * s), 6.0 * s * (1.0 - s), 6.0 - 12.0 * s],
            ProfileShape::Quintic => {
                let s2 = s * s;
                [
                    s2 * s * (10.0 + s * (-15.0 + 6.0 * s)),
                    30.0 * s2 * (1.0 - s) * (1.0 - s),
                    60.0 * s * (1.0 - s) * (1.0 - 2.0 * s),
                ]
            }
            ProfileShape::Cycloidal => {
                let a = 2.0 * PI * s;
                [s - a.sin() / (2.0 * PI), 1.0 - a.cos(), 2.0 * PI * a.sin()]
            }
            ProfileShape::Trapezoidal { blend } => {
                let velocity = 1.0 / (1.0 - blend);
                let acceleration = velocity / blend;
                if s < blend {
                    [0.5 * acceleration * s * s, acceleration * s, acceleration]
                } else if s <= 1.0 - blend {
                    [0.5 * acceleration * blend * blend + velocity * (s - blend), velocity, 0.0]
                } else {
                    let r = 1.0 - s;
                    [1.0 - 0.5 * acceleration * r * r, acceleration * r, -acceleration]
                }
            }
        }
    }
}

/// A rest-to-rest motion from `start_value` at `start_time` to `end_value` at `end_time`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotionProfile {
    /// When the motion starts.
    pub start_time: f64,
    /// When it ends (after `start_time`).
    pub end_time: f64,
    /// The value before and at `start_time`.
    pub start_value: f64,
    /// The value at and after `end_time`.
    pub end_value: f64,
    /// The law in between.
    pub shape: ProfileShape,
}

impl MotionProfile {
    /// Checks the parameters: finite, `end_time > start_time`, a blend in (0, 1/2].
    pub fn new(
        start_time: f64,
        end_time: f64,
        start_value: f64,
        end_value: f64,
        shape: ProfileShape,
    ) -> std::result::Result<Self, String> {
        let profile = MotionProfile { start_time, end_time, start_value, end_value, shape };
        profile.validate()?;
        Ok(profile)
    }

    /// The checks of [`MotionProfile::new`].
    pub fn validate(&self) -> std::result::Result<(), String> {
        let numbers = [self.start_time, self.end_time, self.start_value, self.end_value];
        if !numbers.iter().all(|x| x.is_finite()) {
            return Err(format!("profile times and values must be finite, got {numbers:?}"));
        }
        if self.end_time <= self.start_time {
            return Err(format!(
                "a profile's end_time must be after its start_time, got {} <= {}",
                self.end_time, self.start_time
            ));
        }
        if let ProfileShape::Trapezoidal { blend } = self.shape {
            if !(blend > 0.0 && blend <= 0.5) {
                return Err(format!(
                    "a trapezoidal profile's blend (acceleration time over the duration) must be \
                     in (0, 0.5], got {blend}"
                ));
            }
        }
        Ok(())
    }

    /// Value, first and second derivative at `t`. At `start_time` the derivatives are those
    /// of the motion that begins there (the limits from the right: a cubic or trapezoidal
    /// profile starts with its acceleration, which a run from `start_time` and the efforts of
    /// inverse dynamics there need); before it, rest.
    pub fn evaluate(&self, t: f64) -> [f64; 3] {
        if t < self.start_time {
            return [self.start_value, 0.0, 0.0];
        }
        if t >= self.end_time {
            return [self.end_value, 0.0, 0.0];
        }
        let duration = self.end_time - self.start_time;
        let rise = self.end_value - self.start_value;
        let [p, dp, ddp] = self.shape.law((t - self.start_time) / duration);
        [self.start_value + rise * p, rise * dp / duration, rise * ddp / (duration * duration)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::assert_close;

    const SHAPES: [ProfileShape; 5] = [
        ProfileShape::Cubic,
        ProfileShape::Quintic,
        ProfileShape::Cycloidal,
        ProfileShape::Trapezoidal { blend: 0.2 },
        ProfileShape::Trapezoidal { blend: 0.5 },
    ];

    #[test]
    fn derivatives_equal_finite_differences_inside() {
        for shape in SHAPES {
            let p = MotionProfile::new(0.3, 1.7, -0.4, 2.1, shape).unwrap();
            for k in 1..40 {
                let t = 0.3 + 1.4 * (k as f64 + 0.37) / 40.0;
                let h = 1e-6;
                let (a, b, v) = (p.evaluate(t - h), p.evaluate(t + h), p.evaluate(t));
                let what = format_args!("{shape:?} at {t}");
                assert_close((b[0] - a[0]) / (2.0 * h), v[1], 1e-7, 1e-7, what);
                // The trapezoid's acceleration jumps at its blends: skip a step across one.
                if (a[2] - b[2]).abs() < 1e-3 * (1.0 + v[2].abs()) {
                    assert_close((b[1] - a[1]) / (2.0 * h), v[2], 1e-6, 1e-6, what);
                }
            }
        }
    }

    #[test]
    fn rest_at_both_ends_with_the_continuity_of_each_law() {
        for shape in SHAPES {
            let p = MotionProfile::new(1.0, 3.0, 0.5, -1.5, shape).unwrap();
            let (before, after) = (p.evaluate(1.0 + 1e-12), p.evaluate(3.0 - 1e-12));
            assert_close(before[0], 0.5, 0.0, 1e-12, format_args!("{shape:?} start"));
            assert_close(after[0], -1.5, 0.0, 1e-12, format_args!("{shape:?} end"));
            assert_close(before[1], 0.0, 0.0, 1e-10, format_args!("{shape:?} start velocity"));
            assert_close(after[1], 0.0, 0.0, 1e-10, format_args!("{shape:?} end velocity"));
            let smooth = matches!(shape, ProfileShape::Quintic | ProfileShape::Cycloidal);
            let jump = before[2].abs().max(after[2].abs());
            assert_eq!(jump < 1e-9, smooth, "{shape:?}: end accelerations {before:?} {after:?}");
            assert_eq!(p.evaluate(0.0), [0.5, 0.0, 0.0]);
            assert_eq!(p.evaluate(9.0), [-1.5, 0.0, 0.0]);
        }
        // The trapezoid's peak velocity and acceleration: D / (T (1 - b)), D / (T^2 b (1 - b)).
        let p = MotionProfile::new(0.0, 2.0, 0.0, 3.0, ProfileShape::Trapezoidal { blend: 0.25 }).unwrap();
        assert_close(p.evaluate(1.0)[1], 3.0 / (2.0 * 0.75), 1e-14, 0.0, "coast velocity");
        assert_close(p.evaluate(0.1)[2], 3.0 / (4.0 * 0.25 * 0.75), 1e-14, 0.0, "acceleration");
    }

    #[test]
    fn bad_parameters_are_refused() {
        assert!(MotionProfile::new(1.0, 1.0, 0.0, 1.0, ProfileShape::Cubic).is_err());
        assert!(MotionProfile::new(0.0, f64::NAN, 0.0, 1.0, ProfileShape::Cubic).is_err());
        for blend in [0.0, -0.1, 0.51, f64::NAN] {
            let shape = ProfileShape::Trapezoidal { blend };
            assert!(MotionProfile::new(0.0, 1.0, 0.0, 1.0, shape).is_err(), "blend {blend}");
        }
    }
}
