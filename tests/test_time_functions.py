"""Functions of time: values and derivatives against finite differences."""

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


def test_spline_interpolates_and_holds_outside(assert_close):
    s = fm.Spline([0.0, 1.0, 2.0], [1.0, 3.0, 2.0])
    values = [s(t) for t in (0.0, 1.0, 2.0)]
    assert_close(values, [1.0, 3.0, 2.0], rel=1e-6, abs=1e-12, what="spline at its points")
    assert s(-1.0) == 1.0 and s(5.0) == 2.0
    assert s.derivatives(5.0)[1:] == (0.0, 0.0)
