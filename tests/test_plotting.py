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
    # Chosen by what the model has: no constraint violation (round-off), no positions (the
    # crank's frame sits on its pivot; the joints' angles and slides say how it moves).
    assert plotting.default_quantities(slider_crank) == [
        "energy",
        "joints",
        "efforts",
        "reactions",
        "deflection:rod",
        "stress:rod",
    ]
    notes = plotting.overview_notes(slider_crank)
    assert notes[0].startswith("constraint violation at most") and "(round-off)" in notes[0]
    assert (
        "Note: constraint violation at most"
        in plotting.plot_quantities(slider_crank).get_supxlabel()
    )
    # A grid of three columns that fits a screen, every axis with its unit.
    with Image.open(files[0]) as image:
        width, height = image.size
    assert width <= 1920 and height <= 1200, (width, height)
    figure = plotting.plot_quantities(slider_crank)
    axes = [ax for ax in figure.axes if ax.get_visible()]
    assert len(axes) == 9 and len({round(ax.get_position().x0, 3) for ax in axes}) == 3
    for ax in axes:
        assert ax.get_ylabel().endswith(")"), ax.get_ylabel()


def test_legends_are_beside_the_curves_not_over_them(slider_crank):
    import matplotlib

    figure = plotting.plot_quantities(slider_crank, ["joints", "reactions"])
    figure.canvas = matplotlib.backends.backend_agg.FigureCanvasAgg(figure)
    renderer = figure.canvas.get_renderer()
    for ax in figure.axes:
        legend = ax.get_legend()
        assert legend is not None
        box, frame = legend.get_window_extent(renderer), ax.get_window_extent(renderer)
        assert box.x0 >= frame.x1 - 1.0, (ax.get_title(), box, frame)


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
        ("balance", 1),
        ("violation", 1),
        ("joints", 2),
        ("bodies", 3),
        ("position:crank", 1),
        ("velocity:slider", 1),
        ("angular-velocity:crank", 1),
        ("angular_velocity:1", 1),
        ("elastic:rod", 1),
        ("deflection:rod", 1),
        ("deflection:rod:5", 1),
        ("stress:rod", 2),
        ("reaction:crank pin", 1),  # a plane model's revolute: its torque is round-off
        ("reaction:guide", 1),
        ("reaction:drive", 1),  # an angle driver: a torque, no force
        ("reactions", 1),
        ("efforts", 1),
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
    kinetic, gravity, strain, total = (line.get_ydata() for line in ax.get_lines())
    np.testing.assert_array_equal(kinetic, tet_pendulum.kinetic_energy)
    np.testing.assert_array_equal(strain, tet_pendulum.strain_energy)
    np.testing.assert_array_equal(gravity + strain, tet_pendulum.potential_energy)
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
        # (it said "no body named 'rod:5.5'")
        ("deflection:rod:5.5", fm.InvalidParameterError, "the node must be a node id .*'5.5'"),
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
    assert driven.startswith("Change of the total energy (work done)")
    free = plotting.plot_energy_drift(four_bar).get_title()
    assert free.startswith("Energy drift") and "kinetic energy" in free
    # The overview's second energy panel: the balance with the drivers' work (driven), the
    # drift (conservative), never the change of E alone (the energy panel has the total).
    driven_panels = plotting.plot_quantities(slider_crank, ["energy"]).axes
    assert driven_panels[1].get_title().startswith("Energy balance")
    free_panels = plotting.plot_quantities(four_bar, ["energy"]).axes
    assert free_panels[1].get_title().startswith("Energy drift")


def _driven_arm(output_interval):
    """A rigid arm (inertia J about z) turned by an angle driver through a quintic step of
    1 rad in 1 s: the driver's work is the kinetic energy 0.5 J f'(t)^2."""
    system = fm.System()
    arm = system.add_rigid_body(2.0, (0.1, 0.1, 0.5), name="arm")
    ground, own = system.add_marker(system.ground), system.add_marker(arm)
    system.add_revolute_joint(ground, own, name="hinge")
    system.add_angle_driver(ground, own, fm.Step(0.0, 1.0, 0.0, 1.0, shape="quintic"), name="drive")
    return fm.simulate(system, 1.0, 1e-3, output_interval=output_interval)


def test_the_drivers_work_is_the_kinetic_energy_they_give(assert_close):
    from flexmbd.quantities import driver_work, joint_coordinates

    result = _driven_arm(1e-3)  # a record every step
    s = result.time
    rate = 30 * s**2 - 60 * s**3 + 30 * s**4  # f'(t) of 10 s^3 - 15 s^4 + 6 s^5
    # Largest kinetic energy 0.5 J (15/8)^2 = 0.88 J; trapezoidal work over the steps.
    assert_close(driver_work(result), 0.5 * 0.5 * rate**2, abs=1e-5, what="work of the driver")
    ((name, kind, angle, angle_rate),) = joint_coordinates(result)  # the driver is the hinge's
    assert (name, kind) == ("hinge", "angle")
    assert_close(angle, 10 * s**3 - 15 * s**4 + 6 * s**5, abs=1e-6, what="hinge angle")
    assert_close(angle_rate, rate, abs=5e-5, what="hinge angle rate")  # the solver: 1e-5
    ax = plotting.plot_energy_balance(result)
    change, work, difference = (line.get_ydata() for line in ax.get_lines())
    assert np.max(np.abs(difference)) < 1e-5 * np.max(work)
    np.testing.assert_array_equal(change, result.total_energy - result.total_energy[0])


def test_under_sampled_vibrations_are_noted(tet_pendulum, capsys):
    # The tetrahedral arm vibrates at ~2.4 kHz (its first modes); records 0.01 s apart.
    notes = plotting.sampling_notes(tet_pendulum)
    assert len(notes) == 1 and notes[0].startswith("arm: a mode at ")
    frequency = float(notes[0].split("a mode at ")[1].split()[0])
    assert 1000.0 < frequency < 5000.0
    figure = plotting.plot_quantities(tet_pendulum)
    assert "under-sampled" in figure.get_supxlabel()


def test_records_fine_enough_give_no_sampling_note():
    from conftest import run_example

    result = run_example("flexible-slider-crank", 0.004, 2e-5)
    assert plotting.sampling_notes(result) == []


def test_a_body_at_rest_gives_no_sampling_note():
    # A cantilever started in its static equilibrium under a tip load stays there; its
    # round-off "motion" made every mode count as moving, and the note asked for finer records.
    from flexmbd.fe import Material, Section, build_body, straight_beam

    nodes, elements = straight_beam(1.0, 10)
    steel = Material(2.1e11, 0.3, 7850.0)
    data = build_body(
        nodes, elements, steel, section=Section.rectangle(0.02, 0.01), reference="clamped",
        reference_nodes=[0],
    )  # fmt: skip
    system = fm.System()
    beam = system.add_flexible_body(data, name="beam")
    system.add_fixed_joint(system.add_marker(system.ground), system.add_node_marker(beam, 1))
    system.add_point_force(system.add_node_marker(beam, 11), (0.0, -100.0, 0.0))
    result = fm.simulate(system, 0.01, 1e-3, initial_state="equilibrium")
    tip = result.node_displacements(beam, [10])[:, 0, 1]
    assert np.ptp(tip) < 1e-12 * abs(tip[0]) and tip[0] < -1e-3  # bent, and at rest
    assert plotting.sampling_notes(result) == []


def test_a_violation_above_round_off_is_drawn_without_spikes(slider_crank):
    import copy

    assert "violation" not in plotting.default_quantities(slider_crank)
    drifting = copy.copy(slider_crank)
    drifting.constraint_violation = np.where(np.arange(len(slider_crank)) % 2, 1e-6, 0.0)
    assert "violation" in plotting.default_quantities(drifting)
    ax = plotting.plot_constraint_violation(drifting)
    low, high = ax.get_ylim()
    assert ax.get_yscale() == "log" and low >= 1e-14 and high >= 1e-6


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


def test_plot_result_refuses_a_bad_dpi_and_a_format_its_file_contradicts(slider_crank, tmp_path):
    # Regression: dpi 0 was matplotlib's bare ValueError, NaN "cannot convert float NaN to
    # integer", and format="svg" with a .png file wrote a PNG without a word.
    for dpi in (0, -5, float("nan"), True):
        with pytest.raises(fm.InvalidParameterError, match="dpi must be a number"):
            plotting.plot_result(slider_crank, tmp_path / "a.png", "energy", dpi=dpi)
    with pytest.raises(fm.InvalidParameterError, match="format 'svg' and the file"):
        plotting.plot_result(slider_crank, tmp_path / "a.png", "energy", format="svg")
    assert not (tmp_path / "a.png").exists()


def _named_bodies(names: list[str]) -> fm.Result:
    """A short run of pendulums named `names`, each hinged to the ground by a joint of the
    same name."""
    system = fm.System(gravity=(0, -9.81, 0))
    for k, name in enumerate(names):
        body = system.add_rigid_body(1.0, (1e-3,) * 3, position=(0.5, -k, 0), name=name)
        system.add_revolute_joint(
            system.add_marker(system.ground, position=(0, -k, 0)),
            system.add_marker(body, position=(-0.5, 0, 0)),
            name=name,
        )
    return fm.simulate(system, 0.02, 1e-3, output_interval=0.01)


def test_a_folder_of_plots_has_one_file_per_quantity_whatever_the_names(tmp_path):
    # "rotor α" and "rotor β" both became position-rotor.png (ASCII only), one file for two
    # figures; names that still give one file name are numbered.
    result = _named_bodies(["rotor α", "rotor β", "a b", "a_b"])
    quantities = [f"position:{name}" for name in ("rotor α", "rotor β", "a b", "a_b")]
    files = plotting.plot_result(result, tmp_path / "plots", quantities)
    assert [f.name for f in files] == [
        "position-rotor_α.png", "position-rotor_β.png", "position-a_b.png", "position-a_b-2.png",
    ]  # fmt: skip
    assert sorted(p.name for p in (tmp_path / "plots").iterdir()) == sorted(f.name for f in files)


def test_item_names_are_drawn_as_written(tmp_path):
    # A joint named "_aux" was left out of the legend (matplotlib hides labels that start
    # with "_"), and "$" in a name was read as mathtext: a ParseSyntaxException.
    names = ["_aux", "main", "arm $\\frac{1}$ v2"]
    result = _named_bodies(names)
    ax = plotting.plot_reactions(result)
    _, labels = ax.get_legend_handles_labels()
    assert len(labels) == 3 and labels[0].endswith("_aux")
    for quantity in ["reactions", "joints", f"position:{names[2]}", f"reaction:{names[2]}"]:
        plotting.plot_result(result, tmp_path / "names.png", [quantity])
    # Escaped once, also when two plots share the axes.
    ax = plotting.plot_body(result, names[2])
    plotting.plot_body(result, names[2], ax=ax)
    assert ax.get_title().count("\\$") == 2


def test_the_overview_notes_the_bodies_it_leaves_out():
    # Six free bodies: the overview draws four and said nothing of the other two.
    system = fm.System()
    for k in range(6):
        system.add_rigid_body(1.0, (1, 1, 1), velocity=(k + 1.0, 0, 0), name=f"ball {k}")
    result = fm.simulate(system, 0.02, 1e-2)
    assert plotting.default_quantities(result)[1:] == [f"position:ball {k}" for k in range(4)]
    notes = plotting.overview_notes(result)
    assert notes[0] == "2 more moving bodies not drawn (ball 4, ball 5): position:NAME draws one"


@pytest.mark.parametrize(
    "plot",
    [plotting.plot_energy, plotting.plot_energy_balance, plotting.plot_quantities],
    ids=["energy", "energy balance", "quantities"],
)
def test_a_result_without_records_is_refused_by_every_plot(plot):
    # A run refused at its start: plot_energy_balance raised a bare IndexError, the others
    # drew empty figures.
    system = fm.System()
    body = system.add_rigid_body(1.0, (1, 1, 1), position=(2, 0, 0))
    system.add_distance_joint(system.add_marker(system.ground), system.add_marker(body), 1.0)
    solver = fm.GeneralizedAlpha(correct_initial_positions=False)
    with pytest.raises(fm.FlexmbdError) as failure:
        fm.simulate(system, 0.1, 1e-3, solver=solver)
    result = failure.value.result
    assert len(result.time) == 0
    with pytest.raises(fm.InvalidParameterError, match="no records to plot"):
        plot(result)
