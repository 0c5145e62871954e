"""The command line runs the built-in examples and reports their reference errors."""

import subprocess
import sys

from flexmbd.cli import main


def test_examples_are_listed(capsys):
    assert main(["examples"]) == 0
    out = capsys.readouterr().out
    assert "four-bar" in out and "pendulum" in out


def test_run_pendulum_reports_the_reference_errors(capsys):
    assert main(["run", "pendulum", "--end", "1.0", "--step", "1e-3"]) == 0
    out = capsys.readouterr().out
    assert "position error at t = 0.5 s" in out and "steps" in out


def test_run_with_an_explicit_solver_reports_evaluations_and_events(capsys):
    argv = ["run", "pendulum", "--end", "1.0", "--step", "1e-3", "--solver", "rk4:partitioning"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "function evaluations" in out
    assert "(repartition)" in out
    error = float(out.split("position error at t = 1 s:")[1].split()[0])
    assert error < 1e-6


def test_run_in_joint_coordinates_prints_the_size_of_the_acceleration_system(capsys):
    for formulation in ("decoupled", "coupled"):
        argv = ["run", "flexible-robot-arm", "--end", "1e-8", "--step", "1e-9"]
        argv += ["--solver", f"rk4:joint-coordinates:{formulation}"]
        assert main(argv) == 0
        out = capsys.readouterr().out
        size = int(out.split("acceleration system of")[1].split()[0])
        # Eq. 41: 2 x 21 reference rows and 2 free joint coordinates; eq. 40 adds the
        # elastic accelerations (3 links, 4 nodes of 6 coordinates each).
        assert size == (44 if formulation == "decoupled" else 44 + 72)


def test_run_refuses_an_unknown_solver(capsys):
    assert main(["run", "pendulum", "--solver", "rk4:sideways"]) == 2
    assert "strategy must be one of" in capsys.readouterr().err
    assert main(["run", "pendulum", "--solver", "rk4"]) == 2


def test_python_dash_m_runs_the_default_example():
    run = subprocess.run(
        [sys.executable, "-m", "flexmbd", "run", "--end", "0.01", "--step", "1e-4"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 0, run.stderr
    assert "R4 flexible slider-crank" in run.stdout


def _write_abaqus_box(path):
    """A tet4 box as a flat Abaqus input file with the node sets x0 and x1 (1-based labels)."""
    import numpy as np

    from flexmbd.fe import shapes

    mesh = shapes.box((1.0, 0.1, 0.1), (8, 2, 2), "tet4")
    lines = ["*NODE"]
    lines += [f"{i + 1}, {x:.17g}, {y:.17g}, {z:.17g}" for i, (x, y, z) in enumerate(mesh.nodes)]
    lines.append("*ELEMENT, TYPE=C3D4, ELSET=BODY")
    tets = mesh.elements["tet4"]
    lines += [f"{e + 1}, " + ", ".join(str(n + 1) for n in t) for e, t in enumerate(tets)]
    for name in ("x0", "x1"):
        lines.append(f"*NSET, NSET={name}")
        chunks = np.array_split(mesh.node_sets[name], 3)
        lines += [", ".join(str(n + 1) for n in chunk) for chunk in chunks]
    path.write_text("\n".join(lines) + "\n")
    return mesh


def test_preprocess_writes_a_body_file_equal_to_the_python_api(tmp_path, capsys):
    import numpy as np

    from flexmbd.fe.body_file import load_body
    from flexmbd.fe.preprocess import Material, build_body

    mesh = _write_abaqus_box(tmp_path / "bar.inp")
    out = tmp_path / "bar.h5"
    material = ["-E", "2.1e11", "--poisson-ratio", "0.3", "--density", "7800"]
    modal = ["--reference", "interface", "--modes", "craig-bampton", "-n", "4"]
    command = ["preprocess", str(tmp_path / "bar.inp"), "-o", str(out), *material, *modal]
    assert main([*command, "--interfaces", "x0", "x1"]) == 0
    printed = capsys.readouterr().out
    assert "81 nodes, 192 tet4" in printed and "frequencies (Hz)" in printed
    body = load_body(out)
    same = build_body(
        mesh.nodes,
        mesh.elements,
        Material(2.1e11, 0.3, 7800.0),
        node_sets=mesh.node_sets,
        reference="interface",
        modes="craig-bampton",
        mode_count=4,
        interfaces=["x0", "x1"],
    )
    np.testing.assert_allclose(body.frequencies, same.frequencies, rtol=1e-10)
    assert body.metadata["source"] == str(tmp_path / "bar.inp")
    # A node set the mesh does not have: a clear message and exit status 1.
    assert main([*command, "--interfaces", "x0", "tip"]) == 1
    assert "tip" in capsys.readouterr().err
