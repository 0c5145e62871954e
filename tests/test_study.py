"""Design studies (issue 31): cases from grids, lists and samples; outputs by name; the runs
on a real dask.distributed LocalCluster of two worker processes; failures recorded without
stopping the others; re-runs that do no work; refusals before anything runs."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import flexmbd as fm
from flexmbd.quantities import output_unit, output_value, parse_output
from flexmbd.study.sampling import make_cases

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE))
from study_models.arm import swinging_arm  # noqa: E402

PENDULUM_FILE = HERE.parent / "examples" / "models" / "pendulum.yaml"


@pytest.fixture
def worker_path(monkeypatch):
    """The worker processes import the test models (spawned, they inherit the environment)."""
    paths = [str(HERE), os.environ.get("PYTHONPATH", "")]
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(p for p in paths if p))


# Sampling --------------------------------------------------------------------------------------
def test_a_grid_is_every_combination_the_first_key_slowest():
    cases = make_cases({"a": [1, 2], "b": ["x", "y", "z"]})
    assert cases == [{"a": a, "b": b} for a in (1, 2) for b in ("x", "y", "z")]
    assert make_cases({"a": np.array([1.5, 2.5])}) == [{"a": 1.5}, {"a": 2.5}]


@pytest.mark.parametrize("sampling", ["random", "lhs"])
def test_samples_are_reproducible_with_the_seed_and_in_range(sampling):
    ranges = {"a": (0.0, 1.0), "b": (10.0, 20.0)}
    first = make_cases(ranges, sampling, samples=32, seed=7)
    assert first == make_cases(ranges, sampling, samples=32, seed=7)
    assert first != make_cases(ranges, sampling, samples=32, seed=8)
    b = np.array([case["b"] for case in first])
    assert np.all((b >= 10.0) & (b <= 20.0))


def test_latin_hypercube_puts_one_case_in_each_stratum():
    cases = make_cases({"a": (0.0, 1.0), "b": (-1.0, 1.0)}, "lhs", samples=50, seed=3)
    for key, (low, high) in {"a": (0.0, 1.0), "b": (-1.0, 1.0)}.items():
        strata = np.floor((np.array([c[key] for c in cases]) - low) / (high - low) * 50)
        assert sorted(strata) == list(range(50))


def test_bad_parameters_are_refused_naming_them():
    with pytest.raises(fm.InvalidParameterError, match="'a'.*empty"):
        make_cases({"a": (1.0, 1.0)}, "lhs", samples=4)
    with pytest.raises(fm.InvalidParameterError, match="samples"):
        make_cases({"a": (0.0, 1.0)}, "random")
    with pytest.raises(fm.InvalidParameterError, match="case 1"):
        make_cases([{"a": 1}, {"b": 2}], "list")
    with pytest.raises(fm.InvalidParameterError, match="sampling"):
        make_cases({"a": [1]}, "sobol")
    with pytest.raises(fm.InvalidParameterError, match="samples=5 is for random and lhs"):
        make_cases({"a": [1, 2]}, samples=5)  # ignored before
    with pytest.raises(fm.InvalidParameterError, match="n must be at least 1"):
        fm.examples.four_bar(0)  # a raw ValueError before
    # numpy's raw errors for a bad seed or a NaN count; a set became one case.
    for options in ({"samples": 3, "seed": -1}, {"samples": 3, "seed": "abc"}):
        with pytest.raises(fm.InvalidParameterError, match="seed must be an integer"):
            make_cases({"a": (0.0, 1.0)}, "lhs", **options)
    with pytest.raises(fm.InvalidParameterError, match="needs samples >= 1, got nan"):
        make_cases({"a": (0.0, 1.0)}, "lhs", samples=float("nan"))
    with pytest.raises(fm.InvalidParameterError, match="as a list or an array, got set"):
        make_cases({"a": {1.0, 2.0}})
    assert len(make_cases({"a": (0.0, 1.0)}, "lhs", samples=2.0)) == 2


def test_run_settings_are_checked_before_any_case_runs(tmp_path):
    # They failed every case, which then counted as done (nothing left to run).
    folder = tmp_path / "study"
    for options, match in (
        ({"end_time": float("nan")}, "end_time must be finite"),
        ({"end_time": -1.0}, "end_time must be > 0"),
        ({"step_size": 0.0}, "step_size must be > 0"),
        ({"step_size": "1e-3"}, "step_size must be a number"),
        ({"solver": "banana"}, "solver: a flexmbd.GeneralizedAlpha"),
    ):
        with pytest.raises(fm.InvalidParameterError, match=match):
            fm.Study(PENDULUM_FILE, {"bodies.mass.mass": [1.0]}, folder=folder, **options)
    with pytest.raises(fm.ArgumentTypeError, match="model: a build function"):
        fm.Study(42, {"a": [1.0]}, folder=folder)
    with pytest.raises(fm.ArgumentTypeError, match="folder: a path"):
        fm.Study(PENDULUM_FILE, {"bodies.mass.mass": [1.0]}, folder=None)
    assert not folder.exists()


def _returns_nothing(length: float) -> None:
    """A build function whose `return` was forgotten."""
    fm.examples.pendulum()


def test_studies_refuse_repeated_cases_taken_names_and_builds_without_a_model(tmp_path):
    # Found by a fault hunt: a repeated case crashed the Dask bookkeeping (KeyError), an
    # output named "status" was overwritten by the case status, one named like a parameter
    # failed after every case had run, a build function returning None failed every case
    # with an AttributeError, and 1 and 1.0 were two cases (run twice).
    folder = tmp_path / "study"
    with pytest.raises(fm.InvalidParameterError, match="cases 0 and 2 are the same case"):
        fm.Study(PENDULUM_FILE, {"bodies.mass.mass": [1.0, 2.0, 1]}, folder=folder)
    for name in ("status", "elapsed", "case", "bodies.mass.mass", " "):
        with pytest.raises(fm.InvalidParameterError, match="output|outputs"):
            fm.Study(
                PENDULUM_FILE,
                {"bodies.mass.mass": [1.0, 2.0]},
                outputs={name: "final(position:mass[y])"},
                folder=folder,
            )
    study = fm.Study(_returns_nothing, {"length": [1.0]}, folder=folder, end_time=0.1)
    with pytest.raises(fm.InvalidParameterError, match="returned NoneType None, not a System"):
        study.check()
    whole = fm.Study(PENDULUM_FILE, {"bodies.mass.mass": [1, 2]}, folder=folder, end_time=1)
    real = fm.Study(PENDULUM_FILE, {"bodies.mass.mass": [1.0, 2.0]}, folder=folder, end_time=1.0)
    assert whole.keys == real.keys


def test_sweep_refuses_a_parameter_or_an_output_given_twice(tmp_path, capsys):
    from flexmbd.cli import main

    base = ["sweep", str(PENDULUM_FILE), "-o", str(tmp_path / "s"), "--end", "0.1"]
    twice = ["--set", "bodies.mass.mass=1,2", "--set", "bodies.mass.mass=3"]
    assert main([*base, *twice]) == 2
    assert "bodies.mass.mass is set twice" in capsys.readouterr().err
    outputs = ["--output", "x=max(position:mass[x])", "--output", "x=min(position:mass[x])"]
    assert main([*base, "--set", "bodies.mass.mass=1,2", *outputs]) == 2
    assert "an output named 'x' is given twice" in capsys.readouterr().err


# Outputs ---------------------------------------------------------------------------------------
def test_outputs_are_the_plot_quantities_reduced_over_time(assert_close):
    system = swinging_arm(length=1.0)
    result = fm.simulate(system, 0.5, 1e-3, output_interval=0.01)
    tip = result.sensor("tip")
    assert_close(output_value(result, "min(sensor:tip[y])"), tip[:, 1].min(), rel=0.0)
    assert_close(output_value(result, "max-abs(sensor:tip[1])"), np.abs(tip[:, 1]).max(), rel=0)
    assert_close(output_value(result, "final(position:arm[x])"), result.position("arm")[-1, 0])
    assert_close(output_value(result, "series(energy[total])"), result.total_energy, rel=0.0)
    force = result.reaction_force("hinge")
    rms = np.sqrt(np.mean(force[:, 1] ** 2))
    assert_close(output_value(result, "rms(reaction:hinge[fy])"), rms)
    assert_close(output_value(result, "max(violation)"), result.constraint_violation.max())
    # Lengths of vectors: a sensor's or position's magnitude, a reaction's force and torque.
    pull = np.linalg.norm(force, axis=1).max()
    assert_close(output_value(result, "max(reaction:hinge[force])"), pull, rel=1e-15)
    twist = np.linalg.norm(result.reaction_torque("hinge"), axis=1).max()
    assert_close(output_value(result, "max(reaction:hinge[torque])"), twist, rel=1e-15)
    reach = np.linalg.norm(tip, axis=1).min()
    assert_close(output_value(result, "min(sensor:tip[magnitude])"), reach, rel=1e-15)
    units = [output_unit(f"max(reaction:hinge[{part}])") for part in ("force", "torque", "fy")]
    assert units == ["N", "N m", "N"]
    assert output_unit("max(position:arm[magnitude])") == "m"
    assert output_unit("final(energy[total])") == "J"


def test_a_model_file_sweep_reports_the_model_files_outputs():
    # Without --output, `flexmbd sweep` records the model file's outputs as `flexmbd run`
    # sums them up (vectors by their largest length), besides the violation and the energy.
    from flexmbd.model_file import load_model
    from flexmbd.study.command import model_file_outputs

    crank = load_model(
        Path(__file__).parents[1] / "examples" / "models" / "flexible_slider_crank.yaml"
    )
    assert model_file_outputs(crank) == {
        "largest midpoint deflection": "max(deflection:rod:5[magnitude])",
        "largest drive reaction_torque": "max(reaction:drive[torque])",
    }
    assert model_file_outputs(load_model(PENDULUM_FILE)) == {
        "largest link reaction_force": "max(reaction:link[force])"
    }


@pytest.mark.parametrize(
    "spec, message",
    [
        ("max(sensor:tip)", "choose one"),
        ("largest(sensor:tip[y])", "unknown reduction"),
        ("max(speed:arm[x])", "unknown quantity"),
        ("max(sensor:tip[w])", "no component 'w'"),
        ("max(sensor:nose[y])", "no sensor named 'nose'"),
    ],
)
def test_bad_outputs_name_what_is_wrong(spec, message):
    result = fm.simulate(swinging_arm(), 0.01, 1e-3)
    with pytest.raises((fm.InvalidParameterError, fm.UnknownItemError), match=message):
        parse_output(spec)
        output_value(result, spec)


# Refusals before any case runs -----------------------------------------------------------------
def test_unknown_key_paths_and_bad_values_are_refused_before_any_case_runs(tmp_path, worker_path):
    for parameters, message in [
        ({"bodies.bob.mass": [1.0, 2.0]}, r"bodies.*no item 'bob'.*\['mass'\]"),
        ({"bodies.mass.weight": [1.0]}, r"bodies\[0\]\.weight"),
        ({"bodies.mass.mass": [1.0, -2.0]}, r"case 1 .*bodies\[0\]\.mass"),
        ({"simulation.stop.at": [1.0]}, "no 'stop' here"),
    ]:
        study = fm.Study(PENDULUM_FILE, parameters, folder=tmp_path / "s", end_time=0.1)
        with pytest.raises(fm.ModelFileError, match=message):
            study.run(workers=1)
        assert not (tmp_path / "s" / "cases").exists()
    with pytest.raises(fm.InvalidParameterError, match="'width'.*takes"):
        fm.Study(swinging_arm, {"width": [1.0]}, folder=tmp_path / "t")
    with pytest.raises(fm.InvalidParameterError, match="unknown reduction"):
        fm.Study(swinging_arm, {"length": [1.0]}, folder=tmp_path / "t", outputs=["top(x)"])
    study = fm.Study(swinging_arm, {"mass": [1.0, -1.0]}, folder=tmp_path / "u", end_time=0.1)
    # A local cluster of -2 (or 0) workers waited for them forever.
    for workers in (-2, 0, 1.5, True):
        with pytest.raises(fm.InvalidParameterError, match="workers must be"):
            study.run(workers=workers)
    with pytest.raises(fm.InvalidParameterError, match=r"case 1 \{'mass': -1.0\}"):
        study.run(workers=1)
    assert not (tmp_path / "u" / "cases").exists()


# Runs on a LocalCluster ------------------------------------------------------------------------
def test_a_sixteen_case_study_on_two_worker_processes(tmp_path, worker_path, assert_close):
    lengths = [0.5, 0.75, 1.0, 1.25, 1.5, 1.75, 2.0, 2.25]
    cases = [{"length": L, "mass": m, "fail_at": None} for L in lengths for m in (1.0, 2.0)]
    cases[5]["fail_at"] = 0.2  # one case fails deliberately at t = 0.2 s
    outputs = {
        "lowest tip": "min(sensor:tip[y])",
        "hinge force": "max-abs(reaction:hinge[fy])",
        "tip height": "series(sensor:tip[y])",
    }
    study = fm.Study(
        swinging_arm,
        cases,
        sampling="list",
        outputs=outputs,
        folder=tmp_path / "arm",
        end_time=0.5,
        step_size=1e-3,
        output_interval=0.01,
    )
    started = time.perf_counter()
    data = study.run(workers=2, progress=False)
    first_run = time.perf_counter() - started
    status = list(data["status"].values)
    assert status.count("complete") == 15 and status[5] == "failed"
    assert "CallbackError" in str(data["error"].values[5]) and "deliberate" in str(
        data["error"].values[5]
    )
    # The failed case kept its partial results (file and outputs up to t = 0.2 s).
    cases_folder = tmp_path / "arm" / "cases"
    summary = json.loads((cases_folder / f"case-{study.keys[5]}.json").read_text())
    assert 15 < summary["records"] < 25
    partial = fm.read_results(tmp_path / "arm" / "cases" / f"case-{study.keys[5]}.h5")
    assert 0.15 < partial.time[-1] < 0.25
    series = data["tip height"].values
    assert np.isnan(series[5, -1]) and not np.isnan(series[5, 10])
    # Two worker processes ran the cases.
    pids = {
        json.loads(p.read_text())["worker_pid"] for p in (tmp_path / "arm" / "cases").glob("*.json")
    }
    assert len(pids) == 2 and os.getpid() not in pids
    # Each case's outputs are those of the same run made here.
    for k in (0, 9):
        system = swinging_arm(**{**cases[k], "fail_at": None})
        result = fm.simulate(system, 0.5, 1e-3, output_interval=0.01)
        assert_close(data["lowest tip"].values[k], result.sensor("tip")[:, 1].min(), rel=1e-12)
        assert_close(data["tip height"].values[k], result.sensor("tip")[:, 1], rel=1e-12)
    assert list(data["length"].values) == [c["length"] for c in cases]
    # The dataset was saved with the study, and a re-run does no work.
    saved, description = fm.load_study(tmp_path / "arm")
    assert list(saved["status"].values) == status and description["parameters"] == [
        "length",
        "mass",
        "fail_at",
    ]
    stamps = {p: p.stat().st_mtime_ns for p in (tmp_path / "arm" / "cases").iterdir()}
    assert study.pending() == []
    started = time.perf_counter()
    again = fm.Study(
        swinging_arm,
        cases,
        sampling="list",
        outputs=outputs,
        folder=tmp_path / "arm",
        end_time=0.5,
        step_size=1e-3,
        output_interval=0.01,
    ).run(workers=2, progress=False)
    assert time.perf_counter() - started < 0.5 * first_run
    assert {p: p.stat().st_mtime_ns for p in (tmp_path / "arm" / "cases").iterdir()} == stamps
    assert list(again["status"].values) == status
    # A model file study on the same kind of cluster: the key path replaces the value.
    files = fm.Study(
        PENDULUM_FILE,
        {"joints.link.distance": [0.5, 2.0]},
        folder=tmp_path / "file",
        outputs={"period proxy": "min(sensor:bob position[y])"},
        end_time=0.3,
    ).run(workers=2, progress=False)
    assert list(files["status"].values) == ["complete", "complete"]
    shutil.rmtree(tmp_path / "arm")


def test_the_sweep_info_and_plot_commands(tmp_path, capsys):
    from flexmbd.cli import main

    folder = tmp_path / "pendulum-study"
    code = main(
        [
            "sweep",
            str(PENDULUM_FILE),
            "--set",
            "joints.link.distance=0.5,1.0,2.0",
            # Longer than the model's output interval of 0.01 s: each case warns.
            "--set",
            "simulation.step_size=0.02",
            # A text value: read back from study.nc, it is a coordinate made again, first.
            "--set",
            "solver.type=generalized-alpha",
            "--output",
            "lowest=min(sensor:bob position[y])",
            "--output",
            "pull=max(reaction:link[force])",
            "--end",
            "0.3",
            "--workers",
            "1",
            "-o",
            str(folder),
            "-q",
        ]
    )
    out = capsys.readouterr().out
    assert code == 0, out
    assert "3 cases, 3 complete, 0 failed" in out
    order = ["joints.link.distance", "simulation.step_size", "solver.type"]

    def parameters(text: str) -> list[str]:
        return re.findall(r"^  parameter (.+?): ", text, re.MULTILINE)

    assert parameters(out) == order, out
    assert main(["info", str(folder)]) == 0
    out = capsys.readouterr().out
    # info lists the parameters in the study's order, as the sweep's summary does.
    assert parameters(out) == order, out
    assert "parameter joints.link.distance: 0.5, 1.0, 2.0" in out and "output lowest:" in out
    assert re.search(r"output pull: \S+ \.\. \S+ N\n", out), out
    # The workers' warnings are kept with the cases: Python's warnings are not seen there.
    assert (
        "3 case(s) warned (0, 1, 2): step size: the step size 2e-2 s is longer than the output "
        "interval 1e-2 s: the steps end on the output times, so they are 1e-2 s" in out
    )
    image = tmp_path / "lowest.png"
    assert (
        main(["plot", str(folder), "lowest", "--against", "joints.link.distance", "-o", str(image)])
        == 0
    )
    assert image.stat().st_size > 1000
    # The lowest point of the bob: about -distance for a pendulum released horizontally.
    data, _ = fm.load_study(folder)
    assert np.all(data["lowest"].values < 0.0)
    # Also the initial corrections of the cases whose distance differs from the model's.
    warned = [str(w).split("\n") for w in data["warnings"].values]
    assert [[w.split(":")[0] for w in case] for case in warned] == [
        ["initial correction", "step size"],
        ["step size"],
        ["initial correction", "step size"],
    ]
    assert "joint 'link' (distance): the given positions violate it by 5.000e-1" in warned[0][0]
    # Bad requests are refused with exit code 2, naming what is wrong.
    assert (
        main(
            [
                "sweep",
                str(PENDULUM_FILE),
                "--set",
                "joints.hinge.distance=1",
                "-o",
                str(tmp_path / "x"),
                "-q",
            ]
        )
        == 2
    )
    assert "no item 'hinge'" in capsys.readouterr().err
    assert main(["plot", str(folder), "highest", "--against", "joints.link.distance"]) == 2
    assert "no output 'highest'" in capsys.readouterr().err
    # Of this study of two parameters, without --against: the output is named first (it said
    # "--against: one of the parameters").
    assert main(["plot", str(folder), "nothere", "-o", str(tmp_path / "n.png")]) == 2
    assert "no output 'nothere'" in capsys.readouterr().err


def test_set_values_are_numbers_text_and_lists():
    from flexmbd.study.command import _parameters

    grid = _parameters(["a=5e-3,2,x", "f.coefficients=[0, 100],[0,150]"], "grid")
    assert grid == {"a": [5e-3, 2, "x"], "f.coefficients": [[0, 100], [0, 150]]}
    assert _parameters(["a=1e-3:2e-3"], "lhs") == {"a": (1e-3, 2e-3)}
    with pytest.raises(fm.InvalidParameterError, match="LOW:HIGH"):
        _parameters(["a=1,2"], "lhs")
    with pytest.raises(fm.InvalidParameterError, match="KEY=V1"):
        _parameters(["a"], "grid")
    # A range without --sample was read as YAML 1.1's base-60 number: 1:2 swept the value 62.
    with pytest.raises(fm.InvalidParameterError, match="range to sample: give --sample"):
        _parameters(["bodies.link.mass=1:2"], "grid")
    assert _parameters(["label=a:b,1:x"], "grid") == {"label": ["a:b", "1:x"]}


def test_an_existing_scheduler_runs_the_same_study(tmp_path, worker_path):
    # A cluster started elsewhere (here: in this test) is used by its address, the same path
    # as a remote one; the study does not stop it.
    from dask.distributed import LocalCluster

    with LocalCluster(
        n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster:
        study = fm.Study(
            swinging_arm, {"length": [0.5, 1.0]}, folder=tmp_path / "remote",
            outputs={"lowest tip": "min(sensor:tip[y])"}, end_time=0.2, step_size=1e-3,
        )  # fmt: skip
        data = study.run(scheduler=cluster.scheduler_address, progress=False)
        assert list(data["status"].values) == ["complete", "complete"]
        assert cluster.scheduler is not None and len(cluster.workers) == 1
    assert np.all(data["lowest tip"].values < 0.0)


def test_cases_go_to_the_workers_in_batches_of_decreasing_size():
    from flexmbd.study import GUIDED_FACTOR, batch_sizes

    assert GUIDED_FACTOR == 2
    # Each batch takes the cases left over twice the workers: a few large batches, then
    # single cases, so the workers end within about one case of each other.
    assert batch_sizes(64, 2) == [16, 12, 9, 7, 5, 4, 3, 2, 2, 1, 1, 1, 1]
    assert batch_sizes(16, 2) == [4, 3, 3, 2, 1, 1, 1, 1]
    assert batch_sizes(3, 8) == [1, 1, 1]
    assert batch_sizes(0, 2) == []
    assert batch_sizes(10, 0) == [5, 3, 1, 1]  # no worker known yet: as for one


def test_studies_one_after_another_in_a_script_print_only_their_progress(tmp_path):
    # A script (as a user writes it, guarded for the spawned workers) runs two studies back to
    # back: the second cluster starts while the first one closes. Dask's scheduler and nannies
    # stay quiet in both (most runs before printed 7-26 of their log lines), and the second
    # does not find the first's port taken.
    script = tmp_path / "two_studies.py"
    script.write_text(
        "import sys\n"
        "import flexmbd as fm\n"
        "if __name__ == '__main__':\n"
        "    for name in ('a', 'b'):\n"
        "        data = fm.Study(sys.argv[1], {'joints.link.distance': [0.5, 1.0, 1.5]},\n"
        "                        folder=sys.argv[2] + '/' + name,\n"
        "                        outputs={'low': 'min(sensor:bob position[y])'}).run(workers=2)\n"
        "        print(name, [str(s) for s in data['status'].values])\n"
    )
    run = subprocess.run(
        [sys.executable, str(script), str(PENDULUM_FILE), str(tmp_path)],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr[-3000:]
    statuses = [f"{name} {['complete'] * 3}" for name in "ab"]
    assert run.stdout.split("\n")[:2] == statuses, run.stdout
    assert " - INFO - " not in run.stderr and "already in use" not in run.stderr, run.stderr[:3000]
    assert run.stderr.count("3/3 cases, 0 failed") == 2


def test_a_script_without_the_main_guard_is_told_to_add_it(tmp_path):
    # Spawned workers import the script; unguarded, each would start a study of its own.
    # The workers refuse, and the study says why its cluster did not start.
    script = tmp_path / "unguarded.py"
    script.write_text(
        "import sys\n"
        "import flexmbd as fm\n"
        "fm.Study(sys.argv[1], {'joints.link.distance': [0.5, 1.0]}, folder=sys.argv[2],\n"
        "         outputs={'low': 'min(sensor:bob position[y])'}).run(workers=1)\n"
    )
    run = subprocess.run(
        [sys.executable, str(script), str(PENDULUM_FILE), str(tmp_path / "s")],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert run.returncode == 1
    last = run.stderr.strip().splitlines()[-1]
    assert last.startswith("flexmbd.errors.StudyError: the local cluster's 1 worker process(es)")
    assert f"if {str(script)!r} runs the study" in last and 'if __name__ == "__main__":' in last
    assert "a worker process started a study as it imported the script" in run.stderr
    assert not (tmp_path / "s" / "cases").exists()


def test_sampled_cases_are_plotted_as_points_coloured_by_the_other_parameter(tmp_path, monkeypatch):
    # Latin-hypercube cases share no value of the other parameter: one line per case (with a
    # legend of six entries) said nothing; points coloured by it, with a colour bar, do.
    import matplotlib.pyplot as plt

    from flexmbd.study.command import plot_study

    study = fm.Study(
        swinging_arm, {"length": (0.5, 2.0), "mass": (1.0, 3.0)}, sampling="lhs", samples=6,
        seed=3, outputs={"lowest tip": "min(sensor:tip[y])"}, folder=tmp_path / "s",
    )  # fmt: skip
    (tmp_path / "s" / "cases").mkdir(parents=True)
    study._write_description()
    for k, case in enumerate(study.cases):  # the summaries of runs, as the workers write them
        summary = {"status": "complete" if k else "failed", "error": None, "time": None}
        summary |= {"outputs": {"lowest tip": -case["length"]}, "elapsed": 0.1, "warnings": []}
        study._summary(study.keys[k]).write_text(json.dumps(summary))
    study.gather()
    figures = []
    monkeypatch.setattr(plt, "close", figures.append)
    [image] = plot_study(tmp_path / "s", "lowest tip", "length", None)
    assert image.stat().st_size > 1000
    [axes, bar] = figures[0].axes
    assert bar.get_ylabel() == "mass" and len(axes.collections) == 1
    assert len(axes.collections[0].get_offsets()) == 5  # the complete cases; the failed one:
    assert [t.get_text() for t in axes.get_legend().get_texts()] == ["failed"]
    with pytest.raises(fm.InvalidParameterError, match="no output 'warnings'"):
        plot_study(tmp_path / "s", "warnings", "length", None)


def test_a_case_that_kills_its_worker_is_recorded_and_the_others_run(tmp_path, worker_path):
    # A case whose worker process dies (here by os._exit in a callback at t = 0.15 s; the
    # out-of-memory killer or a crash in native code alike) is recorded as failed, with the
    # records its file kept; the cases of its batch after it, and of the batches the dead
    # worker had queued, run on the workers left. Before, the study raised Dask's KilledWorker
    # (after running the case on four workers) and gathered nothing.
    cases = [{"length": 0.5 + 0.1 * k, "die_at": 0.15 if k == 2 else None} for k in range(7)]
    study = fm.Study(
        swinging_arm, cases, sampling="list", outputs={"lowest tip": "min(sensor:tip[y])"},
        folder=tmp_path / "s", end_time=0.3, step_size=1e-3, output_interval=0.01,
    )  # fmt: skip
    data = study.run(workers=2, progress=False)
    status = [str(s) for s in data["status"].values]
    assert status == ["complete"] * 2 + ["failed"] + ["complete"] * 4
    assert str(data["error"].values[2]).startswith("WorkerDied: the worker process died")
    summary = json.loads((tmp_path / "s" / "cases" / f"case-{study.keys[2]}.json").read_text())
    assert summary["error"]["class"] == "WorkerDied" and summary["records"] <= 16
    # Its output from the records its file kept: none (the file is written every 2 s of
    # wall time) leaves no value.
    assert np.isnan(data["lowest tip"].values[2]) == (summary["records"] == 0)
    assert not list((tmp_path / "s" / "cases").glob("*.started"))
    assert np.all(data["lowest tip"].values[[0, 1, 3, 4, 5, 6]] < 0.0)
    assert study.pending() == []
    # A case whose worker dies as its model is built, in the checks: a StudyError naming the
    # cases, before anything runs.
    cases = [{"length": 0.5 + 0.1 * k, "die_building": k == 4} for k in range(7)]
    broken = fm.Study(swinging_arm, cases, sampling="list", folder=tmp_path / "b", end_time=0.1)
    with pytest.raises(fm.StudyError, match=r"died while building the models of the cases \[.*4"):
        broken.run(workers=2, progress=False)
    assert not (tmp_path / "b" / "cases").exists()


def test_an_interrupted_sweep_says_what_is_done_and_the_same_command_finishes(tmp_path):
    # Ctrl-C (SIGINT) during `flexmbd sweep`: no traceback, exit code 130, the cases done kept
    # (files and summaries), and the same command runs only the others.
    import signal

    folder = tmp_path / "sweep"
    command = [sys.executable, "-m", "flexmbd", "sweep", str(PENDULUM_FILE), "--set"]
    command += ["joints.link.distance=0.6,0.7,0.8,0.9", "--end", "20", "--workers", "1"]
    command += ["-o", str(folder)]
    sweep = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not list(folder.glob("cases/*.json")) and time.monotonic() < deadline:
        time.sleep(0.05)
    sweep.send_signal(signal.SIGINT)
    _, err = sweep.communicate(timeout=120)
    assert sweep.returncode == 130, err[-3000:]
    # Nor what the worker logs as the cluster closes with its case running (the cancelled
    # task's warning in every run, a heartbeat's traceback in some: `cases.dask_setup`).
    assert "Traceback" not in err and "distributed." not in err, err[-3000:]
    # (A case running as the cluster stops may still finish: the message counts those done
    # when it was written.)
    done = len(list(folder.glob("cases/*.json")))
    said = re.search(r"flexmbd sweep: interrupted; (\d) of 4 cases are done in", err)
    assert said is not None and 1 <= int(said.group(1)) <= done < 4, err[-3000:]
    # The folder has no study.nc yet: load_study (and info, plot) gather the cases done
    # (a raw FileNotFoundError before).
    assert not (folder / "study.nc").exists()
    data, _ = fm.load_study(folder)
    assert list(data["status"].values).count("complete") == done
    assert list(data["status"].values).count("pending") == 4 - done
    again = subprocess.run(command + ["-q"], capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stderr[-3000:]
    assert f"{4 - done} to run" in again.stdout and "4 cases, 4 complete" in again.stdout


def test_a_worker_leaves_out_only_what_its_cluster_closing_causes():
    import logging

    from distributed.comm.core import CommClosedError
    from tornado.iostream import StreamClosedError

    from flexmbd.study.cases import is_closing_noise

    def record(message: str, error: BaseException | None = None) -> logging.LogRecord:
        info = (type(error), error, None) if error is not None else None
        return logging.LogRecord("distributed.worker", logging.ERROR, "", 0, message, (), info)

    closed = CommClosedError("in <TCP (closed) heartbeat_worker>: Stream is closed")
    closed.__cause__ = StreamClosedError()
    wrapped = OSError("heartbeat failed")
    wrapped.__cause__ = closed
    assert is_closing_noise(record("Failed to communicate with scheduler", closed))
    assert is_closing_noise(record("Failed to communicate with scheduler", wrapped))
    assert is_closing_noise(record("Async instruction for <Task> ended with CancelledError"))
    # A worker's other messages stay: memory, an error of its own, an unrelated OSError.
    assert not is_closing_noise(record("Worker is at 85% memory usage"))
    assert not is_closing_noise(record("Compute failed", ValueError("bad input")))
    assert not is_closing_noise(record("heartbeat failed", OSError("no route to host")))
    assert not is_closing_noise(record("timed out", TimeoutError()))


def test_outputs_are_checked_before_the_runs_and_computed_again_when_they_change(
    tmp_path, worker_path, assert_close
):
    from flexmbd.study.cases import refresh_outputs

    cases = [{"length": 1.0, "fail_at": None}, {"length": 2.0, "fail_at": 0.2}]
    run = {"sampling": "list", "folder": tmp_path / "s", "end_time": 0.4, "step_size": 1e-3}
    # A mistyped item failed every case after its whole run; now nothing runs.
    typo = fm.Study(swinging_arm, cases, outputs={"low": "min(sensor:tipp[y])"}, **run)
    with pytest.raises(fm.InvalidParameterError, match=r"output 'low'.*case 0.*no sensor named"):
        typo.run(workers=1, progress=False)
    assert not (tmp_path / "s" / "cases").exists()
    with pytest.raises(fm.InvalidParameterError, match="no sensor named 'tipp'"):
        typo.check()
    first = fm.Study(swinging_arm, cases, outputs={"low": "min(sensor:tip[y])"}, **run)
    data = first.run(workers=1, progress=False)
    assert list(data["status"].values) == ["complete", "failed"]
    results = {p: p.stat().st_mtime_ns for p in (tmp_path / "s" / "cases").glob("*.h5")}
    # An output that failed on a case (here made so by hand, as a case-dependent item or an
    # older version could) is computed again once corrected, and a new output is computed for
    # every case done, from the results files: no case runs again.
    summary = json.loads(first._summary(first.keys[0]).read_text())
    bad = fm.Study(swinging_arm, cases, outputs={"low": "min(sensor:tip[w])"}, **run)
    failed = refresh_outputs(bad._task(0), summary)
    assert failed["status"] == "failed" and "no component 'w'" in failed["error"]["message"]
    outputs = {"low": "min(sensor:tip[y])", "end x": "final(sensor:tip[x])"}
    again = fm.Study(swinging_arm, cases, outputs=outputs, **run).run(workers=1, progress=False)
    assert list(again["status"].values) == ["complete", "failed"]
    assert "deliberate failure" in str(again["error"].values[1])  # the run's own error
    assert {p: p.stat().st_mtime_ns for p in (tmp_path / "s" / "cases").glob("*.h5")} == results
    # With every case done, a mistyped output marked them all failed; now it is refused first.
    summaries = {p: p.read_text() for p in (tmp_path / "s" / "cases").glob("*.json")}
    typo = fm.Study(swinging_arm, cases, outputs={"low": "min(sensor:tipp[y])"}, **run)
    with pytest.raises(fm.InvalidParameterError, match=r"output 'low'.*case 0.*no sensor named"):
        typo.run(workers=1, progress=False)
    assert {p: p.read_text() for p in (tmp_path / "s" / "cases").glob("*.json")} == summaries
    complete = fm.simulate(swinging_arm(length=1.0), 0.4, 1e-3)
    partial = fm.read_results(tmp_path / "s" / "cases" / f"case-{first.keys[1]}.h5")
    assert 0.15 < partial.time[-1] < 0.25  # the failed case's records, up to its failure
    for k, result in enumerate([complete, partial]):
        assert_close(again["end x"].values[k], result.sensor("tip")[-1, 0], rel=1e-12)
        assert_close(again["low"].values[k], data["low"].values[k], rel=1e-12)
    # A case whose results file is gone runs again.
    (tmp_path / "s" / "cases" / f"case-{first.keys[0]}.h5").unlink()
    third = fm.Study(swinging_arm, cases, outputs={"low": "max(sensor:tip[y])"}, **run)
    third.refresh()
    assert third.pending() == [0]


def test_cases_recording_at_other_times_keep_their_own_times(tmp_path, assert_close):
    # Found by a fault hunt: a series of a case recording every 0.05 s was stored at the first
    # case's times 0, 0.01, 0.02, ... (NaN after); a swept run setting the study replaced
    # made every case alike; another study in the folder was replaced; numpy values of a
    # list were refused by JSON after the cluster had started; one output as a string was
    # read a character at a time.
    folder = tmp_path / "study"
    with pytest.raises(fm.InvalidParameterError, match="the study's step_size replaces the"):
        fm.Study(PENDULUM_FILE, {"simulation.step_size": [1e-3, 1e-2]}, folder=folder,
                 end_time=0.1, step_size=1e-4)  # fmt: skip
    study = fm.Study(
        PENDULUM_FILE,
        [{"simulation.output_interval": np.float64(0.01)}, {"simulation.output_interval": 0.05}],
        sampling="list",
        folder=folder,
        outputs="series(position:mass[x])",
        end_time=0.2,
    )
    data = study.run(workers=1, progress=False)
    assert list(data.status.values) == ["complete", "complete"]
    model = fm.model_file.load_model(PENDULUM_FILE)
    coarse = fm.simulate(model.system, 0.2, model.step_size, output_interval=0.05)
    series = data["series(position:mass[x])"]
    at = [int(np.argmin(np.abs(data.time.values - t))) for t in coarse.time]
    assert_close(series.values[1, at], coarse.position("mass")[:, 0], rel=1e-9)
    assert_close(data.time.values[at], coarse.time, abs=1e-12)
    assert np.isnan(series.values[1, 1])  # no record of that case at t = 0.01
    other = fm.Study(PENDULUM_FILE, {"bodies.mass.mass": [1.0]}, folder=folder, end_time=0.1)
    with pytest.raises(fm.InvalidParameterError, match="holds another study"):
        other.run(workers=1, progress=False)
    assert fm.load_study(folder)[1]["parameters"] == ["simulation.output_interval"]


def _pendulum(mass=1.0, length=1.0):
    system = fm.System(gravity=(0.0, -9.81, 0.0))
    bob = system.add_point_mass(mass, position=(length, 0.0, 0.0), name="bob")
    system.add_distance_joint(system.add_marker(system.ground), system.add_marker(bob), length)
    return system


_LENGTH = 1.0


def _pendulum_of_the_module_length(mass):
    return _pendulum(mass, _LENGTH)


def test_a_case_key_sees_what_the_model_and_the_solver_are(tmp_path, monkeypatch):
    # From a fault hunt, each gave a study's re-run the old results: a solver that differs in
    # a setting its repr does not show (the tolerances of an error-controlled run), build
    # functions that differ in a partial's arguments, a closure's value or a module-level
    # value they read, and a model file whose mesh was written again.
    import functools

    from flexmbd.study.cases import ModelSource, case_key

    def key(source, **settings):
        return case_key(source.identity(), {"mass": 1.0}, settings)

    plain = ModelSource(build=_pendulum)
    loose = fm.GeneralizedAlpha(step_control="error", relative_tolerance=1e-2)
    tight = fm.GeneralizedAlpha(step_control="error", relative_tolerance=1e-8)
    assert repr(loose) == repr(tight)
    assert key(plain, solver=loose) != key(plain, solver=tight)
    assert key(plain, solver=loose) == key(plain, solver=fm.GeneralizedAlpha(
        step_control="error", relative_tolerance=1e-2))  # fmt: skip
    partial = [ModelSource(build=functools.partial(_pendulum, length=v)) for v in (1.0, 2.0)]
    assert key(partial[0]) != key(partial[1])

    def closure(length):
        return lambda mass: _pendulum(mass, length)

    assert key(ModelSource(build=closure(1.0))) != key(ModelSource(build=closure(2.0)))
    assert key(ModelSource(build=closure(1.0))) == key(ModelSource(build=closure(1.0)))
    before = key(ModelSource(build=_pendulum_of_the_module_length))
    monkeypatch.setattr(sys.modules[__name__], "_LENGTH", 2.0)
    assert key(ModelSource(build=_pendulum_of_the_module_length)) != before
    arrays = [ModelSource(build=_pendulum, arguments={"table": np.arange(2000.0) + d})
              for d in (0.0, 1e-9)]  # fmt: skip
    assert key(arrays[0]) != key(arrays[1])  # (their reprs are the same)
    # A model file and the mesh it names.
    (tmp_path / "rod.inp").write_text("*NODE\n1, 0, 0, 0\n")
    text = (
        "materials:\n  steel: {young_modulus: 2.1e+11, poisson_ratio: 0.3, density: 7800.0}\n"
        "bodies:\n  - {name: rod, type: flexible, mesh: rod.inp, material: steel}\n"
        "simulation: {end_time: 0.01, step_size: 1.0e-3}\n"
    )
    (tmp_path / "model.yaml").write_text(text)
    source = ModelSource(path=str(tmp_path / "model.yaml"))
    first = source.identity()
    (tmp_path / "rod.inp").write_text("*NODE\n1, 0, 0, 0\n2, 1, 0, 0\n")
    assert source.identity() != first


def test_a_study_extended_and_stopped_is_not_shown_by_its_old_dataset(tmp_path, worker_path):
    # A study of 2 cases, extended to 4 and stopped before it gathered (Ctrl-C): its study.nc
    # of the 2 cases stayed, and load_study (flexmbd info/plot) showed "2 cases, 2
    # complete". A run now removes it before dispatching, and a dataset older than the
    # description or a summary is gathered again.
    run = {"folder": tmp_path / "s", "end_time": 0.1, "step_size": 1e-3}
    first = fm.Study(PENDULUM_FILE, {"bodies.mass.mass": [1.0, 2.0]}, **run)
    first.run(workers=1, progress=False)
    data, _ = fm.load_study(tmp_path / "s")
    assert len(data["status"]) == 2
    time.sleep(0.05)  # (a later modification time)
    extended = fm.Study(PENDULUM_FILE, {"bodies.mass.mass": [1.0, 2.0, 3.0, 4.0]}, **run)
    extended._write_description()  # (as run() does before the cases are dispatched)
    data, _ = fm.load_study(tmp_path / "s")
    assert sorted(data["status"].values) == ["complete", "complete", "pending", "pending"]


def test_an_output_named_with_a_slash_is_plotted_into_the_study_folder(tmp_path, worker_path):
    # "force/mass" made the image's name a path into a folder that does not exist.
    from flexmbd.study.command import plot_study

    outputs = {"force/mass": "max(reaction:link[force])"}
    study = fm.Study(PENDULUM_FILE, {"bodies.mass.mass": [1.0, 2.0]}, outputs=outputs,
                     folder=tmp_path / "s", end_time=0.05, step_size=1e-3)  # fmt: skip
    study.run(workers=1, progress=False)
    (path,) = plot_study(tmp_path / "s", "force/mass", None, None)
    assert path.parent == tmp_path / "s" and path.stat().st_size > 1000
