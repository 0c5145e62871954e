"""Plots of results: quantity names, the plotted data and the saved files."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import run_example
from PIL import Image

import flexmbd as fm
from flexmbd import plotting


@pytest.fixture(scope="module")
def slider_crank() -> fm.Result:
    return run_example("flexible-slider-crank", 0.02, 1e-3)


@pytest.fixture(scope="module")
def tet_pendulum() -> fm.Result:
    return run_example("tetrahedral-pendulum", 0.1, 0.01)


@pytest.fixture(scope="module")
def four_bar() -> fm.Result:
    return run_example("four-bar", 0.5, 0.01)


def assert_rich_image(path) -> None:
    """A valid PNG that is not blank."""
    with Image.open(path) as image:
        image.verify()
    with Image.open(path) as image:
        pixels = np.asarray(image.convert("RGB"), dtype=float)
    assert pixels.std() > 5.0
    assert len(np.unique(pixels.reshape(-1, 3), axis=0)) >= 8


def test_plot_result_writes_one_png_with_all_default_panels(slider_crank, tmp_path):
    files = plotting.plot_result(slider_crank, tmp_path / "crank.png")
    assert files == [tmp_path / "crank.png"]
    assert_rich_image(files[0])
    assert plotting.default_quantities(slider_crank) == [
        "energy",
        "violation",
        "bodies",
        "reactions",
        "efforts",
        "deflection:rod",
        "stress:rod",
    ]


def test_plot_result_writes_one_svg_per_quantity(slider_crank, tmp_path):
    quantities = ["energy", "reaction:crank pin", "deflection:rod:5"]
    files = plotting.plot_result(slider_crank, tmp_path / "plots", quantities, format="svg")
    assert [f.name for f in files] == [
        "energy.svg",
        "reaction-crank_pin.svg",
        "deflection-rod-5.svg",
    ]
    for file in files:
        assert "<svg" in file.read_text()


def test_comma_separated_quantities(four_bar, tmp_path):
    files = plotting.plot_result(four_bar, tmp_path, "violation, sensor:B0 position")
    assert [f.name for f in files] == ["violation.png", "sensor-B0_position.png"]
    for file in files:
        assert_rich_image(file)


@pytest.mark.parametrize(
    ("quantity", "panels"),
    [
        ("energy", 2),
        ("drift", 1),
        ("violation", 1),
        ("bodies", 3),
        ("position:crank", 1),
        ("velocity:slider", 1),
        ("angular-velocity:crank", 1),
        ("angular_velocity:1", 1),
        ("elastic:rod", 1),
        ("deflection:rod", 1),
        ("deflection:rod:5", 1),
        ("stress:rod", 2),
        ("reaction:crank pin", 2),
        ("reactions", 1),
    ],
)
def test_every_quantity_kind_draws(slider_crank, quantity, panels):
    assert len(plotting.quantity_panels(slider_crank, quantity)) == panels
    figure = plotting.plot_quantities(slider_crank, [quantity])
    assert len(figure.axes) == panels
    assert all(ax.get_lines() for ax in figure.axes)


def test_solid_stress_is_the_largest_von_mises_stress(tet_pendulum):
    from flexmbd.fe.stress import von_mises

    (ax,) = plotting.plot_stress(tet_pendulum, "arm")
    expected = von_mises(tet_pendulum.stresses("arm")).max(axis=1)
    np.testing.assert_allclose(ax.get_lines()[0].get_ydata(), expected)


def test_energy_panel_shows_the_result_energies(tet_pendulum):
    ax = plotting.plot_energy(tet_pendulum)
    kinetic, potential, total = (line.get_ydata() for line in ax.get_lines())
    np.testing.assert_array_equal(kinetic, tet_pendulum.kinetic_energy)
    np.testing.assert_array_equal(potential, tet_pendulum.potential_energy)
    np.testing.assert_array_equal(total, tet_pendulum.total_energy)
    drift = plotting.plot_energy_drift(tet_pendulum).get_lines()[0].get_ydata()
    np.testing.assert_array_equal(drift, tet_pendulum.total_energy - tet_pendulum.total_energy[0])


def test_deflection_picks_the_node_that_moves_most(slider_crank):
    # The simply supported rod bends most in its middle, node 5 of 9.
    ax = plotting.plot_deflections(slider_crank, "rod")
    lines = ax.get_lines()
    assert lines[1].get_label() == "u_y, node 5"
    np.testing.assert_array_equal(
        lines[1].get_ydata(), slider_crank.node_displacements("rod", [5])[:, 0, 1]
    )


def test_reaction_components_are_the_result_reactions(slider_crank):
    ax = plotting.plot_reaction(slider_crank, "crank pin", "torque")
    values = np.column_stack([line.get_ydata() for line in ax.get_lines()])
    np.testing.assert_array_equal(values, slider_crank.reaction_torque("crank pin"))


@pytest.mark.parametrize(
    ("quantity", "error", "message"),
    [
        ("bogus", fm.InvalidParameterError, "unknown quantity 'bogus'; known: energy"),
        ("energy:rod", fm.InvalidParameterError, "takes no item"),
        ("reaction", fm.InvalidParameterError, "needs an item"),
        ("position:nobody", fm.UnknownItemError, "no body named 'nobody'; known:"),
        ("reaction:hinge", fm.UnknownItemError, "no joint named 'hinge'"),
        ("sensor:tip", fm.UnknownItemError, "no sensor named 'tip'"),
        ("deflection:crank", fm.UnknownItemError, "not a deformable body"),
        ("elastic:slider", fm.UnknownItemError, "not a deformable body"),
        ("deflection:rod:99", fm.UnknownItemError, "no node with id 99"),
    ],
)
def test_bad_quantity_names_raise_typed_errors(slider_crank, quantity, error, message):
    with pytest.raises(error, match=message):
        plotting.quantity_panels(slider_crank, quantity)


def test_names_are_checked_before_anything_is_written(slider_crank, tmp_path):
    with pytest.raises(fm.UnknownItemError):
        plotting.plot_result(slider_crank, tmp_path / "out", ["energy", "position:nobody"])
    assert not (tmp_path / "out").exists()
    with pytest.raises(fm.InvalidParameterError, match="image format"):
        plotting.plot_result(slider_crank, tmp_path / "out.jpg", ["energy"])
    with pytest.raises(fm.InvalidParameterError, match="image format"):
        plotting.plot_result(slider_crank, tmp_path / "out", ["energy"], format="bmp")


def test_energy_panel_of_a_driven_model_is_called_a_change_not_a_drift(slider_crank, four_bar):
    # The crank's driver does work: E changes by design; the four-bar conserves it.
    driven = plotting.plot_energy_drift(slider_crank).get_title()
    assert driven.startswith("Change of the total energy (work of drivers and forces)")
    free = plotting.plot_energy_drift(four_bar).get_title()
    assert free.startswith("Drift of the total energy") and "kinetic energy" in free


def test_efforts_are_the_signed_driving_torques(slider_crank, tmp_path):
    panels = plotting.quantity_panels(slider_crank, "efforts")
    assert len(panels) == 1  # angle drivers only: one panel in N m
    ax = plotting.plot_efforts(slider_crank, "angle driver")
    line = ax.get_lines()[0]
    np.testing.assert_array_equal(line.get_ydata(), slider_crank.driver_effort("drive"))
    assert "N m" in ax.get_ylabel()
    with pytest.raises(fm.UnknownItemError, match="no translation drivers"):
        plotting.plot_efforts(slider_crank, "translation driver")
    with pytest.raises(fm.InvalidParameterError, match="not a driver"):
        slider_crank.driver_effort("crank pin")
