"""Model files (docs/model-files.md): a YAML model gives the same simulation as the Python model
it describes, bit for bit; its units are converted to SI; every malformed file gives one
ModelFileError naming the line and key path; nothing in a model file is executed."""

from __future__ import annotations

import inspect
import json
import math
import re
import warnings
from pathlib import Path

import numpy as np
import pytest

import flexmbd as fm
from flexmbd.errors import ModelError, ModelFileError
from flexmbd.model_file import (
    ExplicitSolverSpec,
    FlexibleBodySpec,
    GeneralizedAlphaSpec,
    JointSpec,
    SensorSpec,
    load_model,
    model_schema,
    simulate_model,
)

ROOT = Path(__file__).parents[1]
MODELS = ROOT / "examples" / "models"
RECORDS = ("time", "coordinates", "velocities", "accelerations", "multipliers")


def assert_same_run(from_file: fm.Result, from_python: fm.Result) -> None:
    """Bit-for-bit equal records of two runs."""
    for name in RECORDS:
        a, b = getattr(from_file, name), getattr(from_python, name)
        assert a.shape == b.shape, name
        np.testing.assert_array_equal(a, b, err_msg=name)


def run_example(example: fm.examples.Example, end_time: float, solver=None) -> fm.Result:
    return fm.simulate(
        example.system,
        end_time,
        example.step_size,
        output_interval=example.output_interval,
        solver=example.solver if solver is None else solver,
    )


# The same simulation from a file and from Python ----------------------------------------------


def test_pendulum_file_is_the_python_pendulum():
    model = load_model(MODELS / "pendulum.yaml")
    assert (model.end_time, model.step_size, model.output_interval) == (10.0, 5e-5, 0.01)
    result = simulate_model(model, end_time=0.5)
    assert_same_run(result, run_example(fm.examples.pendulum(), 0.5))
    np.testing.assert_array_equal(
        model.output_values(result)["bob position"], result.sensor("bob position")
    )


def test_four_bar_file_is_the_python_four_bar():
    model = load_model(MODELS / "four_bar.yaml")
    assert list(model.bodies) == ["crank 0", "crank 1", "crank 2", "coupler 0", "coupler 1"]
    assert_same_run(simulate_model(model, end_time=0.5), run_example(fm.examples.four_bar(2), 0.5))


def test_flexible_slider_crank_file_is_the_python_model(tmp_path):
    model = load_model(MODELS / "flexible_slider_crank.yaml")
    result = simulate_model(model, end_time=0.01)
    example = fm.examples.flexible_slider_crank()
    assert_same_run(result, run_example(example, 0.01))
    outputs = model.output_values(result)
    np.testing.assert_array_equal(outputs["midpoint deflection"], result.deflection("rod", 5))
    np.testing.assert_array_equal(outputs["drive reaction_torque"], result.reaction_torque("drive"))
    assert model.plots == ["deflection:rod:5", "reaction:drive", "energy"]
    # A deflection from a chord has no plot of its own: its place was taken by the node's
    # deflection from the body frame (0.057 m drawn for a chord deflection of 0.15 m).
    text = (MODELS / "flexible_slider_crank.yaml").read_text()
    node = "    quantity: deflection\n    node: 5\n"
    chorded = text.replace(node, node + "    chord: [1, 9]\n")
    assert chorded != text
    (tmp_path / "chord.yaml").write_text(chorded)
    assert load_model(tmp_path / "chord.yaml").plots == ["reaction:drive", "energy"]


def test_tetrahedral_pendulum_file_is_the_python_model():
    model = load_model(MODELS / "tetrahedral_pendulum.yaml")
    result = simulate_model(model, end_time=0.05)
    assert_same_run(result, run_example(fm.examples.tetrahedral_pendulum(), 0.05))


@pytest.mark.parametrize("path", sorted(MODELS.glob("*.yaml")), ids=lambda path: path.stem)
def test_every_example_model_file_loads_and_runs(path):
    if "cylinder:" in path.read_text():
        pytest.importorskip("gmsh")
    model = load_model(path)
    assert model.name and model.description and model.outputs
    result = simulate_model(model, end_time=model.start_time + 10 * model.step_size)
    assert result.success and len(result.time) >= 2
    for label, values in model.output_values(result).items():
        assert len(values) == len(result.time) and np.all(np.isfinite(values)), label


def test_explicit_solver_settings_are_those_of_the_python_solver(tmp_path):
    text = (MODELS / "four_bar.yaml").read_text()
    explicit = (
        "solver:\n  type: explicit\n  method: rk4\n  strategy: joint-coordinates\n"
        "  formulation: decoupled\n  cut_joints: [coupler 0 right, coupler 1 right]\n"
    )
    text = re.sub(r"solver:\n  type: generalized-alpha\n  spectral_radius: 0.9\n", explicit, text)
    (tmp_path / "four_bar.yaml").write_text(text)
    model = load_model(tmp_path / "four_bar.yaml")
    example = fm.examples.four_bar(2)
    cut = [model.joints["coupler 0 right"], model.joints["coupler 1 right"]]
    solver = fm.ExplicitSolver("rk4", "joint-coordinates", formulation="decoupled", cut_joints=cut)
    assert_same_run(simulate_model(model, end_time=0.2), run_example(example, 0.2, solver))


def test_body_file_and_mesh_file_give_the_same_bodies(tmp_path, monkeypatch):
    import meshio

    from flexmbd.fe import save_body, shapes

    # The slider-crank's rod from a body file in a subfolder, named relative to the model file.
    example = fm.examples.flexible_slider_crank()
    (tmp_path / "bodies").mkdir()
    save_body(example.system._flexible[example.items["rod"].index], tmp_path / "bodies/rod.h5")
    text = (MODELS / "flexible_slider_crank.yaml").read_text()
    preprocessed = re.compile(r"    beam: .*?reference_nodes: \[0, 8\][^\n]*\n", re.DOTALL)
    assert preprocessed.search(text)
    (tmp_path / "crank.yaml").write_text(preprocessed.sub("    body_file: bodies/rod.h5\n", text))
    # The tetrahedral pendulum's bar from a VTK mesh file (no node sets: node lists instead).
    mesh = shapes.box((0.5, 0.03, 0.03), (20, 2, 2), "tet4")
    meshio.write_points_cells(tmp_path / "bar.vtu", mesh.nodes, [("tetra", mesh.elements["tet4"])])
    face = mesh.node_sets["x0"]
    text = (MODELS / "tetrahedral_pendulum.yaml").read_text()
    text = text.replace(
        "box: {lengths: [0.5, 0.03, 0.03], divisions: [20, 2, 2], element: tet4}", "mesh: bar.vtu"
    )
    text = text.replace("interfaces: [x0]", f"interfaces: [{face.tolist()}]")
    text = text.replace("node_set: x0", f"node_set: {(face + 1).tolist()}")
    (tmp_path / "bar.yaml").write_text(text)
    monkeypatch.chdir(ROOT)  # relative file names are relative to the model file, not here

    crank = load_model(tmp_path / "crank.yaml")
    assert_same_run(simulate_model(crank, end_time=0.005), run_example(example, 0.005))
    bar = load_model(tmp_path / "bar.yaml")
    pendulum = fm.examples.tetrahedral_pendulum()
    assert_same_run(simulate_model(bar, end_time=0.02), run_example(pendulum, 0.02))


def test_a_mesh_in_millimetres_in_a_file_in_metres(tmp_path, assert_close):
    # The bar's mesh written in mm, read by an SI model file with mesh_unit: mm, is the same
    # body as the mesh in metres.
    import meshio

    from flexmbd.fe import shapes

    mesh = shapes.box((0.5, 0.03, 0.03), (10, 2, 2), "tet4")
    for name, scale in (("bar_m.vtu", 1.0), ("bar_mm.vtu", 1e3)):
        meshio.write_points_cells(tmp_path / name, mesh.nodes * scale,
                                  [("tetra", mesh.elements["tet4"])])  # fmt: skip
    body = (
        "bodies:\n  - name: bar\n    type: flexible\n    mesh: {mesh}\n"
        "    material: {{young_modulus: 7.0e+10, poisson_ratio: 0.33, density: 2700.0}}\n"
        "    reference: clamped\n    reference_nodes: {nodes}\n"
        "simulation: {{end_time: 0.01, step_size: 0.001}}\n"
    )
    nodes = mesh.node_sets["x0"].tolist()
    data = {}
    for name, extra in (("bar_m.vtu", ""), ("bar_mm.vtu", "\n    mesh_unit: mm")):
        path = tmp_path / f"{name}.yaml"
        path.write_text(body.format(mesh=name + extra, nodes=nodes))
        data[name] = load_model(path).body_data["bar"]
    assert_close(data["bar_mm.vtu"].nodes, data["bar_m.vtu"].nodes, rel=1e-12, what="nodes")
    assert_close(data["bar_mm.vtu"].invariants.mass, 0.5 * 0.03 * 0.03 * 2700.0, rel=1e-12)
    box = tmp_path / "box.yaml"
    box.write_text(body.format(mesh="bar_m.vtu", nodes=nodes).replace(
        "mesh: bar_m.vtu", "box: {lengths: [0.5, 0.03, 0.03], divisions: [10, 2, 2]}\n"
        "    mesh_unit: mm"))  # fmt: skip
    with pytest.raises(ModelFileError, match="line 5: bodies\\[0\\].mesh_unit: mesh_unit goes"):
        load_model(box)


# Units ------------------------------------------------------------------------------------------

# A model that uses every converted quantity: a free rigid arm on a spring-damper and a
# torsional spring-damper, loaded by a harmonic and a spline force and a polynomial torque,
# carrying a point mass on a distance joint; a slider moved by a translation driver and a
# wheel turned by an angle driver. SI values; `twin` writes them in cm, g, ms and degrees.
UNITS_MODEL = """\
units: {{length: {m}, mass: {kg}, time: {s}, angle: {rad}}}
gravity: [0.0, {gravity}, 0.0]
functions:
  wheel angle: {{type: polynomial, coefficients: [0.0, {wheel_rate}]}}
bodies:
  - {{name: arm, type: rigid, mass: {arm_mass}, inertia: [{i1}, {i2}, {i3}],
     center_of_mass: [{com}, 0.0, 0.0], position: [{x_arm}, {y_arm}, 0.0],
     orientation: {{axis: z, angle: {arm_angle}}}, velocity: [0.0, {v_arm}, 0.0],
     angular_velocity: [0.0, 0.0, {w_arm}]}}
  - {{name: bob, type: point-mass, mass: {bob_mass}, position: [{x_arm}, {y_bob}, 0.0]}}
  - {{name: slider, type: rigid, mass: {arm_mass}, inertia: [{i3}, {i3}, {i3}],
     orientation: {{axis: y, angle: {quarter}}}}}
  - {{name: wheel, type: rigid, mass: {arm_mass}, inertia: [{i3}, {i3}, {i3}],
     position: [{x_wheel}, 0.0, 0.0]}}
joints:
  - {{type: distance, marker1: {{body: arm}}, marker2: {{body: bob}}, distance: {distance}}}
  - {{name: rail, type: prismatic, marker1: &rail {{body: ground, orientation: {{axis: y,
     angle: {quarter}}}}}, marker2: {{body: slider}}}}
  - {{type: translation-driver, marker1: *rail, marker2: {{body: slider}},
     displacement: {{type: polynomial, coefficients: [0.0, {slide_rate}, {slide_acceleration}]}}}}
  - {{type: revolute, marker1: &axle {{body: ground, position: [{x_wheel}, 0.0, 0.0]}},
     marker2: {{body: wheel}}}}
  - {{name: motor, type: angle-driver, marker1: *axle, marker2: {{body: wheel}},
     angle: wheel angle}}
forces:
  - {{type: spring-damper, marker1: {{body: ground, position: [0.0, {y_anchor}, 0.0]}},
     marker2: {{body: arm, position: [{com}, 0.0, 0.0]}}, stiffness: {k}, damping: {c},
     rest_length: {rest}, preload: {preload}}}
  - {{type: rotational-spring-damper, marker1: {{body: ground}}, marker2: {{body: arm}},
     stiffness: {k_rot}, damping: {c_rot}, rest_angle: {rest_angle}, preload: {preload_rot}}}
  - {{type: point-force, marker: {{body: bob}}, force: [{{type: harmonic, amplitude: {f_amp},
     frequency: {f_freq}, phase: {f_phase}, offset: {f_offset}}}, 0.0, {{type: spline,
     times: [0.0, {t1}, {t2}], values: [0.0, {f1}, {f2}]}}]}}
  - {{type: torque, marker: {{body: arm}}, torque: [0.0, 0.0, {{type: polynomial,
     coefficients: [{c0}, {c1}, {c2}]}}]}}
sensors:
  - {{name: bob velocity, marker: {{body: bob}}, quantity: velocity}}
solver: {{type: generalized-alpha, step_control: error, min_step_size: {min_step},
  max_step_size: {step}}}
simulation: {{end_time: {end}, step_size: {step}, output_interval: {output}}}
"""

SI_VALUES = {
    "gravity": -9.81,
    "wheel_rate": 2.0,
    "arm_mass": 2.0,
    "i1": 0.01,
    "i2": 0.2,
    "i3": 0.25,
    "com": 0.1,
    "x_arm": 0.5,
    "y_arm": 0.2,
    "arm_angle": 0.5,
    "v_arm": 0.1,
    "w_arm": 0.2,
    "bob_mass": 0.5,
    "y_bob": -0.3,
    "quarter": math.pi / 2,
    "x_wheel": 2.0,
    "distance": 0.5,
    "slide_rate": 0.1,
    "slide_acceleration": 0.05,
    "y_anchor": 1.0,
    "k": 50.0,
    "c": 0.5,
    "rest": 0.6,
    "preload": 1.0,
    "k_rot": 2.0,
    "c_rot": 0.05,
    "rest_angle": 0.3,
    "preload_rot": 0.1,
    "f_amp": 1.0,
    "f_freq": 30.0,
    "f_phase": 0.1,
    "f_offset": 0.5,
    "t1": 0.1,
    "t2": 0.2,
    "f1": 1.0,
    "f2": 0.5,
    "c0": 0.1,
    "c1": 2.0,
    "c2": 3.0,
    "min_step": 1e-6,
    "step": 1e-3,
    "end": 0.2,
    "output": 0.01,
}


def twin(values: dict[str, float]) -> dict[str, float]:
    """The values of SI_VALUES in cm, g, ms and degrees (factors written out by hand)."""
    cm, g, ms, deg = 100.0, 1000.0, 1000.0, 180.0 / math.pi  # per m, kg, s, rad
    newton = g * cm / ms**2
    scale = {
        "gravity": cm / ms**2,
        "wheel_rate": deg / ms,
        "arm_mass": g,
        "bob_mass": g,
        "i1": g * cm**2,
        "i2": g * cm**2,
        "i3": g * cm**2,
        "arm_angle": deg,
        "quarter": deg,
        "rest_angle": deg,
        "f_phase": deg,
        "v_arm": cm / ms,
        "w_arm": deg / ms,
        "slide_rate": cm / ms,
        "slide_acceleration": cm / ms**2,
        "k": newton / cm,
        "c": newton * ms / cm,
        "preload": newton,
        "k_rot": newton * cm / deg,
        "c_rot": newton * cm * ms / deg,
        "preload_rot": newton * cm,
        "f_amp": newton,
        "f_offset": newton,
        "f1": newton,
        "f2": newton,
        "f_freq": deg / ms,
        "c0": newton * cm,
        "c1": newton * cm / ms,
        "c2": newton * cm / ms**2,
    }
    times = ("t1", "t2", "min_step", "step", "end", "output")
    lengths = ("com", "x_arm", "y_arm", "y_bob", "x_wheel", "distance", "y_anchor", "rest")
    scale.update({key: ms for key in times})
    scale.update({key: cm for key in lengths})
    assert set(scale) == set(values)
    return {key: value * scale[key] for key, value in values.items()}


def test_units_are_converted_to_si(tmp_path, assert_close):
    si, other = tmp_path / "si.yaml", tmp_path / "cgs.yaml"
    si.write_text(UNITS_MODEL.format(m="m", kg="kg", s="s", rad="rad", **SI_VALUES))
    other.write_text(UNITS_MODEL.format(m="cm", kg="g", s="ms", rad="deg", **twin(SI_VALUES)))
    first, second = load_model(si), load_model(other)
    assert second.units == {"length": "cm", "mass": "g", "time": "ms", "angle": "deg"}
    assert_close(second.end_time, 0.2, rel=1e-15, what="end time")
    assert_close(second.step_size, 1e-3, rel=1e-15, what="step size")
    a, b = simulate_model(first), simulate_model(second)
    assert a.statistics["steps"] == b.statistics["steps"] == 200
    # The model moves: the springs, forces and drivers act.
    assert np.ptp(a.coordinates, axis=0).max() > 0.05
    assert_close(b.time, a.time, rel=1e-14, what="time")
    assert_close(b.coordinates, a.coordinates, abs=1e-9, what="coordinates")
    velocity = a.sensor("bob velocity")
    assert_close(b.sensor("bob velocity"), velocity, rel=1e-7, abs=1e-9, what="bob velocity")
    # (Round-off of the parameters' conversion, amplified in the index-3 multipliers: 1.06e-9
    # of the largest since the step times are t0 + k h, below 1e-9 before.)
    scale = np.max(np.abs(a.multipliers))
    assert_close(b.multipliers, a.multipliers, abs=3e-9 * scale, what="multipliers")


PROFILES_MODEL = """\
units: {length: mm, time: ms, angle: deg}
functions:
  lift: {type: step, start_time: 100, end_time: 400, start_value: 0, end_value: 90,
         shape: cycloidal}
  slide: {type: trapezoidal, start_time: 0, end_time: 500, start_value: 0, end_value: 50,
          blend: 0.3}
  sway: {type: spline, times: [0, 200, 500], values: [0, 30, 10], end: clamped,
         slopes: [0.1, 0]}
  loop: {type: spline, times: [0, 250, 500], values: [0, 20, 0], end: periodic}
bodies:
  - {name: wheel, type: rigid, mass: 1.0, inertia: [1.0, 1.0, 1.0]}
  - {name: carriage, type: rigid, mass: 1.0, inertia: [1.0, 1.0, 1.0]}
  - {name: arm, type: rigid, mass: 1.0, inertia: [1.0, 1.0, 1.0], position: [0, 500, 0],
     angular_velocity: [0, 0, 0.1]}
  - {name: shuttle, type: rigid, mass: 1.0, inertia: [1.0, 1.0, 1.0], position: [0, 0, 500]}
joints:
  - {type: revolute, marker1: &axle {body: ground}, marker2: {body: wheel}}
  - {name: lift, type: angle-driver, marker1: *axle, marker2: {body: wheel}, angle: lift}
  - {type: prismatic, marker1: &rail {body: ground}, marker2: {body: carriage}}
  - {name: slide, type: translation-driver, marker1: *rail, marker2: {body: carriage},
     displacement: slide}
  - {type: revolute, marker1: &arm {body: ground, position: [0, 500, 0]}, marker2: {body: arm}}
  - {name: sway, type: angle-driver, marker1: *arm, marker2: {body: arm}, angle: sway}
  - {type: prismatic, marker1: &track {body: ground, position: [0, 0, 500]},
     marker2: {body: shuttle}}
  - {name: loop, type: translation-driver, marker1: *track, marker2: {body: shuttle},
     displacement: loop}
simulation: {end_time: 500, step_size: 1}
"""


def test_motion_profiles_and_spline_ends_in_model_files(tmp_path, assert_close):
    """Steps, trapezoids and clamped and periodic splines in a model file, in ms, mm and
    degrees, are the Python functions in SI."""
    path = tmp_path / "profiles.yaml"
    path.write_text(PROFILES_MODEL)
    system = load_model(path).system
    deg = math.pi / 180
    functions = {name: system.driver_function(name) for name in ("lift", "slide", "sway", "loop")}
    assert isinstance(functions["lift"], fm.Step)
    assert isinstance(functions["slide"], fm.Trapezoidal)
    expected = {
        "lift": fm.Step(0.1, 0.4, 0.0, 90 * deg, shape="cycloidal"),
        "slide": fm.Trapezoidal(0.0, 0.5, 0.0, 0.05, blend=0.3),
        # 0.1 degree per millisecond: 100 degrees per second.
        "sway": fm.Spline(
            [0.0, 0.2, 0.5], [0.0, 30 * deg, 10 * deg], end="clamped", slopes=(100 * deg, 0.0)
        ),
        "loop": fm.Spline([0.0, 0.25, 0.5], [0.0, 0.02, 0.0], end="periodic"),
    }
    for t in (0.05, 0.2, 0.33, 0.45, 0.7):
        for name, function in functions.items():
            assert_close(
                function.derivatives(t),
                expected[name].derivatives(t),
                rel=1e-12,
                abs=1e-15,
                what=f"{name} at {t}",
            )
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a consistent start: no correction
        result = simulate_model(load_model(path))
    assert result.success


def test_point_masses_of_a_body_in_millimetres_and_tonnes(tmp_path, assert_close):
    # A tip mass with its rotary inertia on a beam, the file in mm and t: the body of build_body's
    # point_masses in SI.
    text = """\
units: {length: mm, mass: t, time: s}
bodies:
  - name: arm
    type: flexible
    beam: {length: 1000.0, elements: 10}
    section: {type: circle, radius: 10.0}
    material: {young_modulus: 2.1e+5, poisson_ratio: 0.3, density: 7.8e-9}
    reference: clamped
    reference_nodes: [0]
    modes: fixed-interface
    mode_count: 4
    point_masses:
      - {node: 10, mass: 1.2e-3, inertia: [0.1, 0.05, 0.05]}
simulation: {end_time: 0.01, step_size: 1.0e-3}
"""
    (tmp_path / "model.yaml").write_text(text)
    body = load_model(tmp_path / "model.yaml").body_data["arm"]
    from flexmbd.fe import build_body, straight_beam

    nodes, elements = straight_beam(1.0, 10)
    expected = build_body(
        nodes,
        elements,
        fm.fe.Material(2.1e11, 0.3, 7800.0),
        section=fm.fe.Section.circle(0.01),
        reference="clamped",
        reference_nodes=[0],
        modes="fixed-interface",
        mode_count=4,
        point_masses={10: (1.2, np.diag([1e-4, 5e-5, 5e-5]))},
    )
    assert_close(body.frequencies, expected.frequencies, rel=1e-9, what="frequencies")
    assert_close(body.invariants.mass, expected.invariants.mass, rel=1e-12, what="mass")
    assert_close(body.invariants.mass, np.pi * 1e-4 * 7800.0 + 1.2, rel=1e-12, what="mass")
    twice = text + "      - {node: 10, mass: 1.0}\n"
    twice = twice.replace("simulation: {end_time: 0.01, step_size: 1.0e-3}\n", "") + (
        "simulation: {end_time: 0.01, step_size: 1.0e-3}\n"
    )
    (tmp_path / "model.yaml").write_text(twice)
    with pytest.raises(ModelFileError, match=r"point_masses\[1\]\.node: node 10 has a point"):
        load_model(tmp_path / "model.yaml")
    # A mass whose centre is offset from its node (mm), about its centre.
    offset = text.replace(
        "inertia: [0.1, 0.05, 0.05]}", "inertia: [0.1, 0.05, 0.05], offset: [0, 50, 20]}"
    )
    (tmp_path / "model.yaml").write_text(offset)
    body = load_model(tmp_path / "model.yaml").body_data["arm"]
    expected = build_body(
        nodes, elements, fm.fe.Material(2.1e11, 0.3, 7800.0), section=fm.fe.Section.circle(0.01),
        reference="clamped", reference_nodes=[0], modes="fixed-interface", mode_count=4,
        point_masses={10: (1.2, np.diag([1e-4, 5e-5, 5e-5]), (0.0, 0.05, 0.02))},
    )  # fmt: skip
    assert_close(body.frequencies, expected.frequencies, rel=1e-9, what="frequencies")
    assert_close(
        body.invariants.first_moment, expected.invariants.first_moment, rel=1e-12, what="S"
    )


def test_mesh_files_and_materials_in_millimetres_tonnes_and_seconds(tmp_path, assert_close):
    import meshio

    from flexmbd.fe import shapes

    mesh = shapes.box((0.5, 0.03, 0.03), (10, 1, 1), "tet4")
    face = mesh.node_sets["x0"].tolist()
    body = (
        "bodies:\n  - name: bar\n    type: flexible\n    mesh: {file}\n"
        "    material: {{young_modulus: {e}, poisson_ratio: 0.33, density: {rho}}}\n"
        f"    reference: interface\n    modes: craig-bampton\n    mode_count: 3\n"
        f"    interfaces: [{face}]\n"
        "simulation: {{end_time: 1.0, step_size: 0.1}}\n"
    )
    cells = [("tetra", mesh.elements["tet4"])]
    meshio.write_points_cells(tmp_path / "m.vtu", mesh.nodes, cells)
    meshio.write_points_cells(tmp_path / "mm.vtu", mesh.nodes * 1000.0, cells)
    (tmp_path / "m.yaml").write_text(body.format(file="m.vtu", e="7.0e+10", rho="2700.0"))
    (tmp_path / "mm.yaml").write_text(
        "units: {length: mm, mass: t}\n" + body.format(file="mm.vtu", e="7.0e+4", rho="2.7e-9")
    )
    si = load_model(tmp_path / "m.yaml").body_data["bar"]
    mm = load_model(tmp_path / "mm.yaml").body_data["bar"]
    assert_close(mm.nodes, si.nodes, abs=1e-15, what="nodes")
    assert_close(mm.invariants["mass"], 2700 * 0.5 * 0.03**2, rel=1e-12, what="mass")
    assert_close(mm.invariants["mass"], si.invariants["mass"], rel=1e-12, what="mass")
    assert_close(mm.frequencies, si.frequencies, rel=1e-9, what="frequencies")


# Malformed files: one error with the line and the key path --------------------------------------

PENDULUM = """\
gravity: [0.0, -9.81, 0.0]
bodies:
  - name: mass
    type: point-mass
    mass: 1.0
    position: [1.0, 0.0, 0.0]
markers:
  - {name: pivot, body: ground}
  - {name: bob, body: mass}
joints:
  - name: link
    type: distance
    marker1: pivot
    marker2: bob
simulation:
  end_time: 1.0
  step_size: 1.0e-3
"""
FLEXIBLE = """\
    type: flexible
    beam: {length: 1.0, elements: 2}
    material: {young_modulus: 1.0e+9, poisson_ratio: 0.3, density: 1000.0}
    section: {type: circle, radius: 0.01}
    reference: clamped
    reference_nodes: [0]
"""
POINT_MASS = "    type: point-mass\n    mass: 1.0\n    position: [1.0, 0.0, 0.0]\n"
BOX = """\
    type: flexible
    box: {lengths: [1.0, 0.1, 0.1], divisions: [4, 1, 1], element: tet4}
    material: {young_modulus: 1.0e+9, poisson_ratio: 0.3, density: 1000.0}
"""
CLAMPED = "    reference: clamped\n    reference_nodes: x0\n"

MALFORMED = {
    "YAML syntax": (
        ("mass: 1.0", "mass: [1.0"),
        "model.yaml: line 6, column 13: YAML syntax error: expected ',' or ']'",
    ),
    "tab": (("    mass: 1.0", "\tmass: 1.0"), "model.yaml: line 5, column 1: YAML syntax error"),
    "unknown key": (
        ("    mass: 1.0", "    mas: 1.0"),
        "model.yaml: line 5: bodies[0].mas: unknown key 'mas' (allowed: type, name, mass, "
        "position, velocity); did you mean 'mass'?",
    ),
    "unknown top-level key": (
        ("simulation:", "simulaton: {}\nsimulation:"),
        "model.yaml: line 15: simulaton: unknown key 'simulaton'",
    ),
    "string for a number": (
        ("mass: 1.0", "mass: heavy"),
        "model.yaml: line 5: bodies[0].mass: Input should be a valid number, got 'heavy'",
    ),
    "quoted number": (
        ("mass: 1.0", "mass: '1.0'"),
        "model.yaml: line 5: bodies[0].mass: Input should be a",
    ),
    "boolean for a number": (
        ("mass: 1.0", "mass: true"),
        "model.yaml: line 5: bodies[0].mass: Input should",
    ),
    "short vector": (
        ("position: [1.0, 0.0, 0.0]", "position: [1.0, 0.0]"),
        "model.yaml: line 6: bodies[0].position: expected exactly 3 items, got 2",
    ),
    "negative mass": (
        ("mass: 1.0", "mass: -1.0"),
        "model.yaml: line 5: bodies[0].mass: Input should be greater than 0, got -1.0",
    ),
    "zero step size": (
        ("step_size: 1.0e-3", "step_size: 0"),
        "model.yaml: line 17: simulation.step_size: Input should be greater than 0, got 0",
    ),
    "end before start": (
        ("end_time: 1.0", "end_time: -1.0"),
        "model.yaml: line 16: simulation.end_time: end_time must be after start_time",
    ),
    "missing section": (
        ("simulation:\n  end_time: 1.0\n  step_size: 1.0e-3\n", ""),
        "model.yaml: line 1: missing key 'simulation'",
    ),
    "missing key": (("    mass: 1.0\n", ""), "model.yaml: line 3: bodies[0]: missing key 'mass'"),
    "missing type": (
        ("    type: distance\n", ""),
        "model.yaml: line 11: joints[0]: missing key 'type'",
    ),
    "unknown type": (
        ("type: distance", "type: hinge"),
        "model.yaml: line 12: joints[0].type: unknown type 'hinge' (one of: spherical, revolute",
    ),
    "unknown marker": (
        ("marker2: bob", "marker2: bobb"),
        "model.yaml: line 14: joints[0].marker2: unknown marker 'bobb' (markers: pivot, bob)",
    ),
    "unknown body": (
        ("{name: bob, body: mass}", "{name: bob, body: crank}"),
        "model.yaml: line 9: markers[1].body: unknown body 'crank' (bodies: ground, mass)",
    ),
    "duplicate body": (
        ("markers:", "  - {name: mass, type: point-mass, mass: 2.0}\nmarkers:"),
        "model.yaml: line 7: bodies[1].name: duplicate body name 'mass' (first at line 3)",
    ),
    "duplicate marker, inline": (
        ("marker2: bob", "marker2: {name: pivot, body: mass}"),
        "model.yaml: line 14: joints[0].marker2.name: duplicate marker name 'pivot' (first at "
        "line 8)",
    ),
    "body named ground": (
        ("name: mass\n", "name: ground\n"),
        "model.yaml: line 3: bodies[0].name: 'ground'",
    ),
    "duplicate key": (
        ("    mass: 1.0\n", "    mass: 1.0\n    mass: 2.0\n"),
        "model.yaml: line 6: bodies[0].mass: duplicate key 'mass' (first at line 5)",
    ),
    "unknown unit": (
        ("gravity:", "units: {length: inch}\ngravity:"),
        "model.yaml: line 1: units.length: Input should be 'm', 'cm' or 'mm', got 'inch'",
    ),
    "unknown unit key": (
        ("gravity:", "units:\n  length: mm\n  force: N\ngravity:"),
        "model.yaml: line 3: units.force: unknown key 'force' (allowed: length, mass, time, angle)",
    ),
    "unknown function": (
        (
            "marker2: bob\n",
            "marker2: bob\n  - {type: angle-driver, marker1: pivot, marker2: bob, angle: swing}\n",
        ),
        "model.yaml: line 15: joints[1].angle: unknown function 'swing' (functions: none)",
    ),
    "unknown function type": (
        (
            "marker2: bob\n",
            "marker2: bob\n  - {type: angle-driver, marker1: pivot, "
            "marker2: bob, angle: {type: sine}}\n",
        ),
        "model.yaml: line 15: joints[1].angle.type: unknown type 'sine' (one of: constant, "
        "polynomial, harmonic, spline, step, trapezoidal)",
    ),
    "error of the Python API": (
        ("{name: bob, body: mass}", "{name: bob, body: mass, position: [0.0, 1.0, 0.0]}"),
        "model.yaml: line 9: markers[1]: invalid parameter of marker 'bob': a marker on a point "
        "mass must be at its position",
    ),
    "node marker on a rigid body": (
        ("{name: bob, body: mass}", "{name: bob, body: mass, node: 2}"),
        "model.yaml: line 9: markers[1].node: body 'mass' is not a flexible body",
    ),
    "unknown node": (
        (POINT_MASS, FLEXIBLE, "{name: bob, body: mass}", "{name: bob, body: mass, node: 7}"),
        "model.yaml: line 12: markers[1].node: marker 'bob': the body has no node with id 7",
    ),
    "missing body file": (
        (POINT_MASS, "    type: flexible\n    body_file: bodies/rod.h5\n"),
        "model.yaml: line 5: bodies[0].body_file: no such file: 'bodies/rod.h5' (looked for ",
    ),
    "missing mesh file": (
        (POINT_MASS, FLEXIBLE.replace("beam: {length: 1.0, elements: 2}", "mesh: arm.msh")),
        "model.yaml: line 5: bodies[0].mesh: no such file: 'arm.msh'",
    ),
    "two body sources": (
        (POINT_MASS, FLEXIBLE + "    box: {lengths: [1.0, 1.0, 1.0], divisions: [1, 1, 1]}\n"),
        "model.yaml: line 3: bodies[0]: a flexible body needs exactly one of body_file, beam, "
        "mesh, nastran, box, plate, cylinder (got beam, box)",
    ),
    "elastic coordinates in other units": (
        (
            "gravity:",
            "units: {length: mm}\ngravity:",
            POINT_MASS,
            FLEXIBLE + "    elastic_coordinates: [0.0]\n",
        ),
        "model.yaml: line 11: bodies[0].elastic_coordinates: elastic_coordinates are not converted",
    ),
    "unknown output": (
        ("simulation:", "outputs:\n  - {joint: hinge, quantity: reaction_force}\nsimulation:"),
        "model.yaml: line 16: outputs[0].joint: unknown joint 'hinge' (joints: link)",
    ),
    "unknown solver option": (
        ("simulation:", "solver: {type: generalized-alpha, rho: 0.5}\nsimulation:"),
        "model.yaml: line 15: solver.rho: unknown key 'rho'",
    ),
    "unknown cut joint": (
        ("simulation:", "solver: {type: explicit, cut_joints: [hinge]}\nsimulation:"),
        "model.yaml: line 15: solver.cut_joints[0]: unknown joint 'hinge' (joints: link)",
    ),
    "paraview every zero": (
        ("simulation:", "paraview: {every: 0}\nsimulation:"),
        "model.yaml: line 15: paraview.every: Input should be greater than or equal to 1, got 0",
    ),
    "paraview every not whole": (
        ("simulation:", "paraview: {every: 2.5}\nsimulation:"),
        "model.yaml: line 15: paraview.every: Input should be a valid integer, got 2.5",
    ),
    "paraview times reversed": (
        ("simulation:", "paraview: {times: [1.0, 0.5]}\nsimulation:"),
        "model.yaml: line 15: paraview.times: times must be [start, end] with start <= end, "
        "got [1.0, 0.5]",
    ),
    "paraview times after the run": (
        ("simulation:", "paraview: {times: [5.0, 6.0]}\nsimulation:"),
        "model.yaml: line 15: paraview.times: times [5, 6] hold no record of the run (from 0 to 1)",
    ),
    "paraview times three numbers": (
        ("simulation:", "paraview: {times: [0.1, 0.2, 0.3]}\nsimulation:"),
        "model.yaml: line 15: paraview.times: expected exactly 2 items, got 3",
    ),
    "paraview times one number": (
        ("simulation:", "paraview: {times: [1.0]}\nsimulation:"),
        "model.yaml: line 15: paraview.times: expected exactly 2 items, got 1",
    ),
    "paraview unknown key": (
        ("simulation:", "paraview: {evry: 2}\nsimulation:"),
        "model.yaml: line 15: paraview.evry: unknown key 'evry' (allowed: write, every, times); "
        "did you mean 'every'?",
    ),
    "paraview write not a flag": (
        ("simulation:", "paraview: {write: maybe}\nsimulation:"),
        "model.yaml: line 15: paraview.write: Input should be a valid boolean, got 'maybe'",
    ),
    # Keys the chosen body would ignore: refused at their line.
    "beam orientation of a solid": (
        (POINT_MASS, BOX + CLAMPED + "    section_orientation: [0.0, 0.0, 1.0]\n"),
        "model.yaml: line 9: bodies[0].section_orientation: orientation: the mesh has no beam "
        "elements (it has tet4)",
    ),
    "beam theory of a solid": (
        (POINT_MASS, BOX + CLAMPED + "    beam_theory: timoshenko\n"),
        "model.yaml: line 9: bodies[0].beam_theory: beam_theory: the mesh has no beam elements",
    ),
    "reference nodes of an unheld frame": (
        (POINT_MASS, BOX + "    reference_nodes: x0\n"),
        "model.yaml: line 7: bodies[0].reference_nodes: reference_nodes with reference='none'",
    ),
    "interface kind without interfaces": (
        (POINT_MASS, BOX + CLAMPED + "    interface_kind: rbe3\n"),
        "model.yaml: line 9: bodies[0].interface_kind: interface_kind='rbe3' is for "
        "Craig-Bampton interfaces",
    ),
    "not a mapping": ((PENDULUM, "- 1\n- 2\n"), "model.yaml: line 1: a model file is a mapping"),
    "empty": ((PENDULUM, ""), "model.yaml: the model file is empty"),
}


def edited(*replacements: str) -> str:
    text = PENDULUM
    for old, new in zip(replacements[::2], replacements[1::2], strict=True):
        assert old in text, old
        text = text.replace(old, new, 1)
    return text


@pytest.mark.parametrize("case", list(MALFORMED))
def test_malformed_model_files_give_one_error_with_line_and_key_path(case, tmp_path, monkeypatch):
    replacements, expected = MALFORMED[case]
    (tmp_path / "model.yaml").write_text(edited(*replacements))
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ModelFileError) as caught:
        load_model("model.yaml")
    message = str(caught.value)
    assert message.startswith(expected), message
    assert "\n" not in message
    assert isinstance(caught.value, ModelError) and isinstance(caught.value, ValueError)
    assert caught.value.file == "model.yaml"
    line = re.match(r"model\.yaml: line (\d+)", message)
    assert caught.value.line == (int(line.group(1)) if line else None)


def test_paraview_section_in_the_files_time_unit(tmp_path):
    text = "units: {time: ms}\nparaview: {every: 3, times: [100, 250]}\n" + edited(
        "end_time: 1.0", "end_time: 1000.0", "step_size: 1.0e-3", "step_size: 1.0"
    )
    (tmp_path / "model.yaml").write_text(text)
    paraview = load_model(tmp_path / "model.yaml").paraview
    assert (paraview.write, paraview.every) == (True, 3)
    assert paraview.times == pytest.approx((0.1, 0.25), rel=1e-15)
    (tmp_path / "model.yaml").write_text(
        edited("simulation:", "paraview: {write: false}\nsimulation:")
    )
    paraview = load_model(tmp_path / "model.yaml").paraview
    assert (paraview.write, paraview.every, paraview.times) == (False, 1, None)
    # Without the section: every record.
    (tmp_path / "model.yaml").write_text(PENDULUM)
    paraview = load_model(tmp_path / "model.yaml").paraview
    assert (paraview.write, paraview.every, paraview.times) == (True, 1, None)


def test_the_unedited_base_model_loads_and_runs(tmp_path):
    """The base of the malformed cases is valid: each case fails for its own edit."""
    (tmp_path / "model.yaml").write_text(PENDULUM)
    result = simulate_model(tmp_path / "model.yaml", end_time=0.01)
    assert len(result.time) == 11


def test_missing_model_file(tmp_path):
    with pytest.raises(ModelFileError, match=r"nothere\.yaml: no such model file"):
        load_model(tmp_path / "nothere.yaml")


@pytest.mark.parametrize(
    "tag",
    [
        "!!python/object/apply:os.mkdir ['{path}']",
        "!!python/object/new:os.mkdir ['{path}']",
        "!!python/name:os.mkdir",
        "!include '{path}'",
    ],
)
def test_nothing_is_executed_from_a_model_file(tag, tmp_path):
    target = tmp_path / "created"
    text = edited("mass: 1.0", "mass: " + tag.format(path=target))
    (tmp_path / "model.yaml").write_text(text)
    with pytest.raises(ModelFileError, match=r"line 5, column 11: the tag '!.*' is not allowed"):
        load_model(tmp_path / "model.yaml")
    assert not target.exists()


def test_yaml_1_2_floats_without_a_dot_are_numbers(tmp_path):
    (tmp_path / "model.yaml").write_text(edited("step_size: 1.0e-3", "step_size: 1e-3"))
    assert load_model(tmp_path / "model.yaml").step_size == 1e-3


# The schema and the reference ---------------------------------------------------------------------


def test_schema_is_json_and_validates_the_examples():
    jsonschema = pytest.importorskip("jsonschema")
    import yaml

    schema = json.loads(json.dumps(model_schema()))
    jsonschema.Draft202012Validator.check_schema(schema)
    validator = jsonschema.Draft202012Validator(schema)
    files = sorted(MODELS.glob("*.yaml"))
    assert len(files) >= 4
    for path in files:
        data = yaml.safe_load(path.read_text())
        assert not list(validator.iter_errors(data)), path.name
        data["bodies"][0]["mass_of_the_moon"] = 7.3e22
        assert list(validator.iter_errors(data)), path.name


def schema_keys(schema: dict) -> set[str]:
    keys = set()

    def visit(node):
        if isinstance(node, dict):
            keys.update(node.get("properties", {}))
            for value in node.values():
                visit(value)
        elif isinstance(node, list):
            for value in node:
                visit(value)

    visit(schema)
    return keys


def test_every_key_is_in_the_reference():
    reference = (ROOT / "docs" / "model-files.md").read_text()
    missing = {key for key in schema_keys(model_schema()) if f"`{key}`" not in reference}
    assert not missing


def test_the_format_covers_the_python_api():
    joints = {
        name[4:-6].replace("_", "-")
        for name in dir(fm.System)
        if name.startswith("add_") and name.endswith("_joint")
    }
    assert joints == set(JointSpec.model_fields["type"].annotation.__args__) | {"distance"}
    for spec, solver in (
        (GeneralizedAlphaSpec, fm.GeneralizedAlpha),
        (ExplicitSolverSpec, fm.ExplicitSolver),
    ):
        options = set(inspect.signature(solver).parameters)
        assert options == set(spec.model_fields) - {"type"}, solver.__name__
    placement = set(inspect.signature(fm.System.add_flexible_body).parameters) - {"self", "body"}
    assert placement <= set(FlexibleBodySpec.model_fields)
    from flexmbd.fe import build_body

    # Not in model files: the mesh itself (a source key instead), external mode matrices
    # (use a body file), timings; the mesh is always checked. The beams' offsets and pin
    # flags, arrays per element, come with the mesh of a Nastran deck (its CBAR cards).
    left_out = {"nodes", "elements", "node_ids", "element_ids", "node_sets", "external_modes"}
    left_out |= {"check_mesh", "timings", "beam_offsets", "beam_releases"}
    renamed = {"orientation": "section_orientation", "mass": "mass_matrix"}
    renamed["shell"] = "shell_thickness"
    options = set(inspect.signature(build_body).parameters) - left_out
    assert {renamed.get(o, o) for o in options} <= set(FlexibleBodySpec.model_fields)
    quantities = set(SensorSpec.model_fields["quantity"].annotation.__args__)
    assert "angular_acceleration" in quantities and len(quantities) == 6


def test_simulate_model_takes_a_path_and_overrides_in_si(tmp_path, assert_close):
    result = simulate_model(MODELS / "pendulum.yaml", end_time=0.1, step_size=1e-3)
    assert_close(result.time[-1], 0.1, rel=1e-6, abs=1e-12, what="last time")
    assert result.statistics["steps"] == 100


def test_warnings_of_building_point_to_the_model_file_line(tmp_path):
    # An inertia no mass distribution has is warned of at the file's line and key (it
    # pointed into building.py).
    path = tmp_path / "lopsided.yaml"
    path.write_text(
        "name: lopsided\n"
        "bodies:\n"
        "  - {name: b, type: rigid, mass: 1, inertia: [1, 1, 5]}\n"
        "simulation: {end_time: 0.1, step_size: 0.01}\n"
    )
    with pytest.warns(fm.InertiaWarning, match=r"^bodies\[0\]: body 'b': the largest") as caught:
        load_model(path)
    (warning,) = [w for w in caught if issubclass(w.category, fm.InertiaWarning)]
    assert (warning.filename, warning.lineno) == (str(path), 3)


def test_an_actuators_effort_sensor_is_an_output(tmp_path, assert_close):
    # A joint actuator's effort is recorded as the sensor "NAME effort" (docs/joints.md), and
    # the run's result has it, but an output naming it was refused: "unknown sensor".
    text = (
        "bodies:\n  - {name: arm, type: rigid, mass: 1.0, inertia: [0.1, 0.1, 0.1]}\n"
        "markers:\n  - {name: pivot, body: ground}\n  - {name: root, body: arm}\n"
        "joints:\n  - {name: hinge, type: revolute, marker1: pivot, marker2: root}\n"
        "forces:\n  - {name: servo, type: joint-actuator, joint: hinge, set_point: 1.0,\n"
        "     proportional_gain: 10.0, derivative_gain: 1.0, limit: 5.0}\n"
        "simulation: {end_time: 0.5, step_size: 1.0e-3, output_interval: 0.1}\n"
        "outputs:\n  - sensor: servo effort\n"
    )
    path = tmp_path / "servo.yaml"
    path.write_text(text)
    model = load_model(path)
    result = simulate_model(model)
    values = np.asarray(model.output_values(result)["servo effort"]).ravel()
    assert_close(values, result.sensor("servo effort")[:, 0], rel=0, abs=0)
    assert values[0] == 5.0  # saturated at the start (10 N m/rad x 1 rad, limit 5)


def test_a_bad_point_mass_is_named_at_its_entry_and_line(tmp_path):
    # The error named the body's line and "point_masses[3]" (the node), which reads as the
    # fourth entry: now the entry's key path and line.
    text = """\
bodies:
  - name: arm
    type: flexible
    beam: {length: 1.0, elements: 4}
    section: {type: circle, radius: 0.01}
    material: {young_modulus: 2.1e+11, poisson_ratio: 0.3, density: 7800.0}
    reference: clamped
    reference_nodes: [0]
    point_masses:
      - {node: 1, mass: 1.0}
      - {node: 2, mass: 1.0}
      - {node: 3, mass: 1.0, inertia: [[1, 2, 0], [0, 1, 0], [0, 0, 1]]}
simulation: {end_time: 0.002, step_size: 1.0e-3}
"""
    (tmp_path / "model.yaml").write_text(text)
    with pytest.raises(
        ModelFileError, match=r"line 12: bodies\[0\]\.point_masses\[2\]: .*symmetric and positive"
    ):
        load_model(tmp_path / "model.yaml")


def test_a_steady_rotation_start_after_the_driver_has_moved(tmp_path, assert_close):
    # The rotating blade of the examples started in its steady rotation at start_time 0.5 s
    # (the hub 25 rad on from the file's configuration): refused ("the starting coordinates
    # violate driver 'hub'"); now the blade is turned to the hub's angle first, and its
    # stretched state is the one at t = 0 (the rotation is steady).
    text = (MODELS / "rotating_blade.yaml").read_text()
    later = text.replace("  start: steady-rotation", "  start: steady-rotation\n  start_time: 0.5")
    later = later.replace("end_time: 1.0", "end_time: 0.52")
    assert later != text
    (tmp_path / "later.yaml").write_text(later)
    (tmp_path / "now.yaml").write_text(text.replace("end_time: 1.0", "end_time: 0.02"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a consistent start: no correction
        turned = simulate_model(load_model(tmp_path / "later.yaml"))
    at_start = simulate_model(load_model(tmp_path / "now.yaml"))
    assert turned.success and turned.time[0] == 0.5
    elastic = slice(7, None)  # (the blade's elastic coordinates after its frame's seven)
    assert_close(turned.coordinates[0][elastic], at_start.coordinates[0][elastic], rel=1e-8,
                 abs=1e-12, what="stretched blade")  # fmt: skip
    hub = turned.orientation("blade")[0]
    assert_close(np.arctan2(hub[1, 0], hub[0, 0]), np.angle(np.exp(25j)), abs=1e-9, what="hub")


def test_an_override_through_a_yaml_alias_changes_only_its_item():
    # The four-bar's bodies share their inertia list and the cranks their orientation through
    # YAML aliases and merge keys: an override of crank 0's (a study's parameter) set all
    # five inertias and turned all three cranks, while the study named crank 0 alone.
    def rigid_bodies(overrides):
        model = load_model(MODELS / "four_bar.yaml", overrides)
        return {
            kwargs["name"]: (args[1], kwargs.get("orientation"))
            for name, args, kwargs in model.system.building_calls
            if name == "add_rigid_body"
        }

    plain = rigid_bodies({})
    assert len(plain) == 5
    changed = rigid_bodies({"bodies.crank 0.inertia.1": 1.0})
    assert changed["crank 0"][0][1] == 1.0
    assert all(changed[n][0] == plain[n][0] for n in plain if n != "crank 0")
    turned = rigid_bodies({"bodies.crank 0.orientation.angle": 1.0})
    assert turned["crank 0"][1][0, 0] == pytest.approx(np.cos(1.0), abs=1e-15)
    assert all(np.array_equal(turned[n][1], plain[n][1]) for n in plain if n != "crank 0")
