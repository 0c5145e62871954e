"""Functions of time: values and derivatives against finite differences, motion profiles
(rest-to-rest steps and trapezoidal velocities) and spline end conditions."""

import math

import pytest

import flexmbd as fm


@pytest.mark.parametrize(
    "function",
    [
        fm.Constant(2.5),
        fm.Polynomial([1.0, -2.0, 0.5, 0.25]),
        fm.Harmonic(2.0, 3.0, phase=0.2, offset=-1.0),
        fm.Spline([0.0, 0.4, 1.1, 2.0], [0.0, 1.0, -0.5, 0.3]),
        fm.Spline([0.0, 0.4, 1.1, 2.0], [0.0, 1.0, -0.5, 0.3], end="clamped", slopes=(2.0, -1.0)),
        fm.Spline([0.0, 0.4, 1.1, 2.0], [0.0, 1.0, -0.5, 0.0], end="periodic"),
        fm.Step(0.1, 1.9, -0.5, 2.0, shape="cubic"),
        fm.Step(0.1, 1.9, -0.5, 2.0, shape="quintic"),
        fm.Step(0.1, 1.9, -0.5, 2.0, shape="cycloidal"),
        fm.Trapezoidal(0.1, 1.9, -0.5, 2.0, blend=0.3),
        fm.UserFunction(lambda t: (math.sin(t), math.cos(t), -math.sin(t)), derivatives=True),
        fm.UserFunction(math.exp),
    ],
)
def test_derivatives_match_finite_differences(function, assert_close):
    h = 1e-5
    for t in (0.3, 0.77, 1.5):
        f, d1, d2 = function.derivatives(t)
        assert_close(f, function(t), rel=1e-6, abs=1e-12, what="value")
        difference = (function(t + h) - function(t - h)) / (2 * h)
        assert_close(d1, difference, rel=1e-6, abs=1e-8, what="first derivative")
        fp, fm_ = function.derivatives(t + h)[1], function.derivatives(t - h)[1]
        assert_close(d2, (fp - fm_) / (2 * h), rel=1e-4, abs=1e-6, what="second derivative")


def test_harmonic_and_polynomial_values(assert_close):
    harmonic = fm.Harmonic(2.0, 3.0, 0.5, 1.0)(0.7)
    assert_close(harmonic, 1.0 + 2.0 * math.sin(2.1 + 0.5), rel=1e-6, abs=1e-12, what="harmonic")
    polynomial = fm.Polynomial([1.0, 2.0, 3.0])(2.0)
    assert_close(polynomial, 17.0, rel=1e-6, abs=1e-12, what="polynomial")


def test_spline_interpolates_and_goes_on_with_its_end_slopes(assert_close):
    s = fm.Spline([0.0, 1.0, 2.0], [1.0, 3.0, 2.0])
    values = [s(t) for t in (0.0, 1.0, 2.0)]
    assert_close(values, [1.0, 3.0, 2.0], rel=1e-6, abs=1e-12, what="spline at its points")
    # Natural end conditions: slopes 2.75 and -1.75 at the ends (M1 = -4.5), kept outside.
    assert_close(s.derivatives(-1.0), (1.0 - 2.75, 2.75, 0.0), rel=0, abs=1e-12, what="before")
    assert_close(s.derivatives(5.0), (2.0 - 3 * 1.75, -1.75, 0.0), rel=0, abs=1e-12, what="after")


def test_a_spline_ramp_has_no_velocity_jump_and_a_clamped_one_rests(assert_close):
    """A two-point spline to pi/2 at 0.5 s: it used to hold its value after the last knot, so
    its velocity dropped from pi to 0 there. The natural spline now goes on with its slope; a
    clamped one (zero end slopes by default) comes to rest."""
    ramp = fm.Spline([0.0, 0.5], [0.0, math.pi / 2])
    assert_close(ramp.derivatives(0.4999)[1], math.pi, rel=1e-12, abs=0, what="slope before")
    assert_close(ramp.derivatives(0.5001)[1], math.pi, rel=1e-12, abs=0, what="slope after")
    rest = fm.Spline([0.0, 0.5], [0.0, math.pi / 2], end="clamped")
    assert rest.slopes == (0.0, 0.0)
    assert_close(rest.derivatives(0.4999999)[1], 0.0, rel=0, abs=1e-5, what="arrival velocity")
    assert rest.derivatives(0.6) == (math.pi / 2, 0.0, 0.0)
    periodic = fm.Spline([0.0, 0.3, 0.7, 1.0], [0.0, 1.0, -1.0, 0.0], end="periodic")
    for t in (0.1, 0.55, 0.93):
        assert_close(
            periodic.derivatives(t + 3.0), periodic.derivatives(t), rel=0, abs=1e-12, what="period"
        )


@pytest.mark.parametrize("shape", ["cubic", "quintic", "cycloidal", "trapezoidal"])
def test_profiles_rest_before_and_after_and_join_smoothly(shape, assert_close):
    start, end, a, b = 0.5, 2.0, 0.3, -1.2
    if shape == "trapezoidal":
        profile = fm.Trapezoidal(start, end, a, b, blend=0.2)
    else:
        profile = fm.Step(start, end, a, b, shape=shape)
    assert profile.derivatives(0.0) == (a, 0.0, 0.0) and profile.derivatives(3.0) == (b, 0.0, 0.0)
    eps = 1e-9
    for at, value in ((start, a), (end, b)):
        inside = profile.derivatives(at + eps if at == start else at - eps)
        assert_close(inside[0], value, rel=0, abs=1e-8, what=f"{shape} value at {at}")
        assert_close(inside[1], 0.0, rel=0, abs=1e-6, what=f"{shape} velocity at {at}")
        # Quintic and cycloidal laws start and stop with zero acceleration; the cubic step
        # jumps to 6 (b - a) / T^2 and the trapezoid to its constant acceleration.
        duration, rise = end - start, b - a
        jump = {
            "quintic": 0.0,
            "cycloidal": 0.0,
            "cubic": 6 * rise / duration**2,
            "trapezoidal": rise / (duration**2 * 0.2 * 0.8),
        }[shape]
        sign = 1.0 if at == start else -1.0
        assert_close(inside[2], sign * jump, rel=1e-6, abs=1e-6, what=f"{shape} acceleration")
    # Halfway: half the rise (all four laws are symmetric).
    assert_close(profile((start + end) / 2), (a + b) / 2, rel=0, abs=1e-12, what="midpoint")


@pytest.mark.parametrize(
    "make, match",
    [
        (lambda: fm.Step(0.0, 1.0, 0.0, 1.0, shape="septic"), "shape must be"),
        (lambda: fm.Step(1.0, 1.0, 0.0, 1.0), "end_time must be after"),
        (lambda: fm.Step(0.0, float("nan"), 0.0, 1.0), "finite"),
        (lambda: fm.Trapezoidal(0.0, 1.0, 0.0, 1.0, blend=0.6), "blend"),
        (lambda: fm.Trapezoidal(0.0, 1.0, 0.0, 1.0, blend=0.0), "blend"),
        (lambda: fm.Spline([0, 1, 2], [0, 1, 0], end="cyclic"), "end must be"),
        (lambda: fm.Spline([0, 1, 2], [0, 1, 0], slopes=(0.0, 1.0)), "clamped"),
        (lambda: fm.Spline([0, 1, 2], [0, 1, 0.5], end="periodic"), "first and last values"),
        (lambda: fm.Spline([0, 1, 2], [0, 1, 0], end="clamped", slopes=(0, math.inf)), "finite"),
    ],
)
def test_bad_profiles_are_refused_naming_the_class(make, match):
    with pytest.raises(fm.InvalidParameterError, match=match):
        make()
