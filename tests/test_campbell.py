"""Campbell diagrams (issue 32): the rotating cantilever's flap frequencies against R2, the
lead-lag frequencies sqrt(w_flap^2 - W^2) without Coriolis coupling, modes followed through a
crossing by their shapes, and the critical speeds of excitation orders."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import turntable_pendulum

import flexmbd as fm
from flexmbd.campbell import CampbellDiagram, campbell, plot_campbell
from flexmbd.fe import Material, Section

ELEMENTS = 20
# R2 (Wright et al. 1982): nondimensional flap frequencies at g = 0, 4, 8, 12.
R2 = {0: (3.5160, 22.0345, 61.6972), 4: (5.5850, 24.2733, 63.9668),
      8: (9.2568, 29.9954, 70.2930), 12: (13.1702, 37.6031, 79.6145)}  # fmt: skip


def blade(width, height):
    """A 1 m aluminium cantilever along x turned about global z by the driver "hub"; its
    nondimensional frequency scale sqrt(rho A L^4 / EI_flap)."""
    material = Material(7.0e10, 0.3, 2700.0)
    section = Section.rectangle(width, height)
    system = fm.examples.rotating_beam(material, section, 1.0, ELEMENTS, geometric_stiffness=True)
    flap = material.young_modulus * width * height**3 / 12
    return system, np.sqrt(material.density * width * height / flap)


def flap_fraction(diagram):
    """Per speed and mode, the share of the nodes' motion along z (flap)."""
    rows = np.concatenate([7 + 6 * k + np.arange(3) for k in range(ELEMENTS)])
    moved = np.abs(diagram.shapes[:, rows, :].reshape(len(diagram.speeds), ELEMENTS, 3, -1))
    return np.sum(moved[:, :, 2] ** 2, axis=1) / np.sum(moved**2, axis=(1, 2))


def test_flap_frequencies_against_r2_and_modes_followed_through_a_crossing(assert_close):
    system, scale = blade(0.01, 0.002)  # lead-lag 25 times stiffer than flap
    g = np.arange(0.0, 26.0, 2.0)
    diagram = campbell(system, "hub", g / scale, modes=4)
    w = 2 * np.pi * diagram.frequencies * scale
    flap = flap_fraction(diagram)
    # Each followed mode keeps its kind at every speed: flap, lead-lag, flap, flap.
    kinds = flap > 0.99
    assert np.all(kinds == kinds[0]) and list(kinds[0]) == [True, False, True, True]
    for k, reference in R2.items():
        row = list(g).index(k)
        assert_close(w[row, [0, 2, 3]], reference, rel=1e-3, what=f"flap frequencies at g = {k}")
    # The first flap mode rises through the first lead-lag mode near g = 18: sorting by
    # frequency would swap them there; the MAC of every match stays near 1.
    assert w[8, 0] < w[8, 1] and w[10, 0] > w[10, 1]
    assert diagram.mac.min() > 0.99
    # The damping ratios of an undamped blade vanish.
    assert np.abs(diagram.damping).max() < 1e-6
    data = diagram.to_xarray()
    assert data["frequency"].shape == (len(g), 4) and data.attrs["driver"] == "hub"


def test_lead_lag_without_coriolis_is_sqrt_flap_squared_minus_speed_squared(assert_close):
    # A square section: flap and lead-lag stiffness equal; the in-plane modes are softened by
    # the spin, w_lag^2 = w_flap^2 - W^2, when their Coriolis coupling with the axial motion
    # is left out.
    system, scale = blade(0.002, 0.002)
    g = np.array([0.0, 4.0, 8.0, 12.0])
    diagram = campbell(system, "hub", g / scale, modes=4, gyroscopic=False)
    w = 2 * np.pi * diagram.frequencies * scale
    flap = flap_fraction(diagram)[-1] > 0.99
    lag = flap_fraction(diagram)[-1] < 0.01
    for k in range(len(g)):
        flaps, lags = np.sort(w[k, flap]), np.sort(w[k, lag])
        assert_close(flaps, [R2[int(g[k])][0], R2[int(g[k])][1]], rel=1e-3, what="flap")
        assert_close(lags, np.sqrt(flaps**2 - g[k] ** 2), rel=1e-3, what="lead-lag")


def hinged_bob(offset, arm, hinge):
    """A hub driven at "drive" about z with a bob (point-like rigid body, 0.3 kg) on a free
    hinge at `offset` from the axis, `arm` beyond it: axis z (lag) or y (flap)."""
    system = fm.System()
    hub = system.add_rigid_body(1.0, (0.1, 0.1, 0.1), position=(offset / 2, 0, 0), name="hub")
    shaft = system.add_marker(system.ground), system.add_marker(hub, position=(-offset / 2, 0, 0))
    system.add_revolute_joint(*shaft, name="shaft")
    system.add_angle_driver(*shaft, fm.Polynomial([0.0, 10.0]), name="drive")
    bob = system.add_rigid_body(0.3, (1e-9, 1e-9, 1e-9), position=(offset + arm, 0, 0))
    turn = np.eye(3) if hinge == "lag" else fm.rotation("x", -np.pi / 2)
    system.add_revolute_joint(system.add_marker(hub, position=(offset / 2, 0, 0), orientation=turn),
                              system.add_marker(bob, position=(-arm, 0, 0), orientation=turn),
                              name="hinge")  # fmt: skip
    return system


@pytest.mark.parametrize("hinge", ["lag", "flap"])
def test_a_bob_on_a_free_hinge_of_a_turning_hub(hinge, assert_close):
    # A point mass on a hinge at offset e, l beyond it: w_lag^2 = W^2 e / l and
    # w_flap^2 = W^2 (1 + e / l). The bob's free rotation was an Euler parameter of the
    # linearization, which turns at W / 2: both squares were W^2 / 4 too high (a 10 % error
    # in the frequency of the lag hinge).
    offset, arm, speeds = 0.5, 0.2, np.array([2.0, 5.0, 10.0])
    ratio = offset / arm if hinge == "lag" else 1.0 + offset / arm
    system = hinged_bob(offset, arm, hinge)
    linear = fm.linearize(system, "steady-rotation")
    assert_close((2 * np.pi * linear.frequencies()) ** 2, [100.0 * ratio], rel=1e-6)
    diagram = campbell(system, "drive", speeds, modes=1)
    assert_close(2 * np.pi * diagram.frequencies[:, 0], speeds * np.sqrt(ratio), rel=1e-6)
    if hinge == "lag":
        # From rest: the lag hinge is free there ("0 oscillating modes at 0 rad/s"); the
        # diagram takes the limit W -> 0 of its frequency.
        diagram = campbell(system, "drive", [0.0, *speeds], modes=1)
        assert diagram.frequencies[0, 0] < 1e-5
        assert_close(2 * np.pi * diagram.frequencies[1:, 0], speeds * np.sqrt(ratio), rel=1e-6)


def test_a_mode_that_stops_oscillating_is_a_gap_of_nan(tmp_path, assert_close):
    # At 4 rad/s the hanging pendulum diverges (real eigenvalues): no oscillating mode is
    # left to follow, and linear_sum_assignment on an empty table raised a plain ValueError.
    speeds = np.array([0.0, 1.0, 2.0, 3.0, 4.0])
    diagram = campbell(turntable_pendulum(1.0), "spin", speeds, modes=1)
    expected = np.sqrt((9.81 - speeds[:4] ** 2) / (1.0 + 1e-6)) / (2 * np.pi)
    assert_close(diagram.frequencies[:4, 0], expected, rel=1e-7, what="sqrt(g - W^2)")
    assert np.isnan(diagram.frequencies[4, 0]) and np.isnan(diagram.damping[4, 0])
    assert np.isnan(diagram.mac[4, 0]) and np.all(np.isnan(diagram.shapes[4, :, 0]))
    assert diagram.whirl[4, 0] is None
    # The order-1 line W / 2 pi crosses the falling curve between 2 and 3 rad/s, and only there.
    crossings = diagram.critical_speeds(orders=(1,))
    assert [c["mode"] for c in crossings] == [0] and 2.0 < crossings[0]["speed"] < 3.0
    plot_campbell(diagram, tmp_path / "gap.png")
    assert (tmp_path / "gap.png").stat().st_size > 0


def test_critical_speeds_are_the_crossings_of_the_order_lines(assert_close):
    speeds = np.array([0.0, 150.0, 300.0])
    # A mode at 20 Hz, another rising as 30 + W / 150 Hz.
    frequencies = np.array([[20.0, 30.0], [20.0, 31.0], [20.0, 32.0]])
    shapes = np.ones((3, 2, 2), complex)
    diagram = CampbellDiagram(speeds, frequencies, 0 * frequencies, shapes, np.ones((3, 2)))
    found = diagram.critical_speeds(orders=(1, 4))
    # Order 1: W / 2 pi meets 20 Hz at W = 40 pi, 30 + W / 150 at W = 30 / (1 / 2 pi - 1 / 150).
    # Order 4 (4 W / 2 pi): 20 Hz at W = 10 pi, 30 + W / 150 at 30 / (4 / 2 pi - 1 / 150).
    expected = sorted(
        [(1, 0, 40 * np.pi), (1, 1, 30 / (1 / (2 * np.pi) - 1 / 150)),
         (4, 0, 10 * np.pi), (4, 1, 30 / (4 / (2 * np.pi) - 1 / 150))],
        key=lambda e: e[2],
    )  # fmt: skip
    assert [(c["order"], c["mode"]) for c in found] == [(k, m) for k, m, _ in expected]
    assert_close([c["speed"] for c in found], [w for _, _, w in expected], rel=1e-12)
    frequency = [c["order"] * c["speed"] / (2 * np.pi) for c in found]
    assert_close([c["frequency"] for c in found], frequency, rel=1e-12)


def test_plot_and_refusals(tmp_path):
    system, scale = blade(0.01, 0.002)
    diagram = campbell(system, "hub", np.array([0.0, 10.0, 20.0]) / scale, modes=2)
    # Drawn into a figure of its own: it switched the backend to Agg and left every figure
    # open in pyplot.
    import matplotlib
    import matplotlib.pyplot as plt

    backend, figures = matplotlib.get_backend(), len(plt.get_fignums())
    plot_campbell(diagram, tmp_path / "campbell.png")
    assert (tmp_path / "campbell.png").stat().st_size > 1000
    assert (matplotlib.get_backend(), len(plt.get_fignums())) == (backend, figures)
    with pytest.raises(fm.UnknownItemError, match="no driver named 'rotor'"):
        campbell(system, "rotor", [0.0, 1.0])
    with pytest.raises(fm.InvalidParameterError, match="ascending"):
        campbell(system, "hub", [2.0, 1.0])
    with pytest.raises(fm.InvalidParameterError, match="flexmbd.System"):
        campbell(system.compile(), "hub", [0.0])
    # "no" was taken as True, a 2-D array of speeds flattened.
    with pytest.raises(fm.ArgumentTypeError, match="gyroscopic must be True or False"):
        campbell(system, "hub", [0.0, 1.0], gyroscopic="no")
    with pytest.raises(fm.InvalidParameterError, match="one list of speeds"):
        campbell(system, "hub", [[0.0, 1.0], [2.0, 3.0]])


def test_the_campbell_command_on_the_rotating_blade_model_file(tmp_path, capsys, assert_close):
    from pathlib import Path

    from flexmbd.cli import main

    model = Path(__file__).parent.parent / "examples" / "models" / "rotating_blade.yaml"
    stem = tmp_path / "blade"
    code = main(["campbell", str(model), "--driver", "hub", "--speeds", "0:35.3:4",
                 "--modes", "3", "-o", str(stem)])  # fmt: skip
    out = capsys.readouterr().out
    assert code == 0, out
    assert stem.with_suffix(".png").stat().st_size > 1000
    import xarray as xr

    with xr.open_dataset(stem.with_suffix(".nc"), engine="scipy") as data:
        f = data["frequency"].values
    # g = 0.340 W: W = 35.3 rad/s is g = 12, where R2's first flap frequency is 13.1702.
    scale = np.sqrt(2700.0 * 0.01 * 0.002 / (7.0e10 * 0.01 * 0.002**3 / 12))
    assert_close(2 * np.pi * f[-1, 0] * scale, 13.1702, rel=2e-3)
    assert "critical speed: order" in out
    assert main(["campbell", str(model), "--driver", "rotor", "--speeds", "0:1:2"]) == 2
    assert "no driver named 'rotor'" in capsys.readouterr().err
    # The model's one angle driver is the default; a model without one is told to name it.
    code = main(["campbell", str(model), "--speeds", "0,35.3", "--modes", "1", "-o", str(stem)])
    assert code == 0 and "driver: hub" in capsys.readouterr().out
    with xr.open_dataset(stem.with_suffix(".nc"), engine="scipy") as data:
        assert_close(data["frequency"].values[-1, 0], f[-1, 0], rel=1e-9)
    # Negative speeds after a space: argparse took "-35.3:0:2" for an option ("expected one
    # argument"); only the "=" form worked.
    code = main(["campbell", str(model), "--speeds", "-35.3:0:2", "--modes", "1", "-o", str(stem)])
    assert code == 0, capsys.readouterr().err
    with xr.open_dataset(stem.with_suffix(".nc"), engine="scipy") as data:
        assert_close(data["frequency"].values[0, 0], f[-1, 0], rel=1e-6)
    assert main(["campbell", "four-bar", "--speeds", "0:1:2"]) == 2
    assert "no angle driver: name the one to turn with --driver" in capsys.readouterr().err
    # An output in a folder that does not exist is refused before the speeds are computed
    # (they were computed, then lost; found by a fault hunt).
    missing = tmp_path / "no such folder" / "blade"
    assert main(["campbell", str(model), "--speeds", "0:35.3:4", "-o", str(missing)]) == 2
    said = capsys.readouterr()
    assert "folder" in said.err and "does not exist" in said.err
    assert "frequencies in the" not in said.out and "driver:" not in said.out


def test_a_mode_without_a_continuation_is_a_gap_not_another_mode(assert_close):
    # A clamped shaft of a 2:1 rectangular section spinning about its axis (rotating frame):
    # its first bending mode does not oscillate between the two critical speeds w1 and w2
    # (s^4 + (w1^2 + w2^2 + 2 W^2) s^2 + (w1^2 - W^2)(w2^2 - W^2) = 0). The followed mode
    # took an unrelated 51 Hz mode at MAC 0.33 there and kept following it.
    from flexmbd.fe import build_body, straight_beam

    along_x = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    nodes, beams = straight_beam(1.0, 10)
    section = Section.rectangle(0.02, 0.01).without_rotary_inertia()
    data = build_body(
        nodes, beams, Material(2.1e11, 0.3, 7800.0), section=section, reference="clamped",
        reference_nodes=[0],
    )  # fmt: skip
    s = fm.System()
    shaft = s.add_flexible_body(data, name="shaft")
    hub, root = (
        s.add_marker(s.ground, orientation=along_x),
        s.add_node_marker(shaft, 1, orientation=along_x),
    )
    s.add_revolute_joint(hub, root, name="bearing")
    s.add_angle_driver(hub, root, fm.Polynomial([0.0, 0.0]), name="spin")
    w1, w2 = 2 * np.pi * fm.linearize(s, fm.equilibrium(s)).frequencies()[:2]
    speeds = np.array([0.0, 0.5, 0.9, 1.2, 1.5, 1.9, 2.2, 2.6, 3.0]) * w1  # w2 = 2 w1
    diagram = fm.campbell(s, "spin", speeds, modes=2)
    a = w1**2 + w2**2 + 2 * speeds**2
    b = (w1**2 - speeds**2) * (w2**2 - speeds**2)
    slow = -0.5 * a + np.sqrt(0.25 * a**2 - b + 0j)  # s^2 of the slower branch
    inside = (speeds > w1) & (speeds < w2)
    assert np.all(np.isnan(diagram.frequencies[inside, 0]))
    # Before the gap the branch; after it the branch again where its shape is found back
    # (MAC 0.5 with the last one before the gap), a gap until then, never another mode.
    before, after = speeds < w1, speeds > w2
    expected = np.sqrt(-slow.real.clip(max=0.0)) / (2 * np.pi)
    assert_close(diagram.frequencies[before, 0], expected[before], rel=1e-3, what="below w1")
    found = after & np.isfinite(diagram.frequencies[:, 0])
    assert found[-1]
    assert_close(diagram.frequencies[found, 0], expected[found], rel=1e-3, what="above w2")
