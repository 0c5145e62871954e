"""Progress displays (flexmbd.progress) and the logging of a run's events: the terminal,
line and notebook styles, simulate(progress=...), rendering and VTU writing, the CLI."""

import importlib.machinery
import io
import logging
import os
import subprocess
import sys
import time
import types

import pytest

import flexmbd as fm
from flexmbd import progress as pg
from flexmbd.cli import main


class FakeTerminal(io.StringIO):
    """A stream that says it is a terminal."""

    def isatty(self):
        return True


class BrokenStream(io.StringIO):
    """A stream whose writes fail (a closed terminal, a full disk)."""

    def write(self, text):
        raise OSError("stream gone")


@pytest.fixture
def no_throttle(monkeypatch):
    """Every update redraws (the bar otherwise redraws at most every 0.1 s), on a terminal
    wide enough for the whole line."""
    monkeypatch.setattr(pg, "REDRAW_INTERVAL", 0.0)
    monkeypatch.setenv("COLUMNS", "200")


def explicit_pendulum_run(end_time, **options):
    """The A01 pendulum by RK4 with coordinate partitioning: about 0.3 s of wall time per
    simulated second here, repartitions (INFO events) at t = 0.485, 0.875, 1.67, ... s."""
    example = fm.examples.pendulum()
    solver = fm.ExplicitSolver("rk4", "partitioning")
    return fm.simulate(
        example.system, end_time, 5e-5, solver=solver, output_interval=0.01, **options
    )


def test_durations_read_as_seconds_minutes_and_hours():
    assert pg.duration(4.24) == "4.2 s"
    assert pg.duration(65.0) == "1:05"
    assert pg.duration(7265.0) == "2:01:05"
    assert pg.duration(float("nan")) == "?" and pg.duration(-1.0) == "?"


def test_the_remaining_time_is_the_elapsed_time_scaled_by_what_is_left():
    bar = pg.ProgressBar("task", stream=io.StringIO(), style="lines")
    assert bar.remaining() != bar.remaining()  # NaN before any progress
    bar.began = time.perf_counter() - 10.0
    bar.update(0.25)
    assert 29.9 < bar.remaining() < 30.5
    assert "10.0 s elapsed, 30.0 s left" in bar.text() or "30.1 s left" in bar.text()


def test_a_terminal_bar_redraws_one_line_and_ends_it_with_the_totals(no_throttle):
    stream = FakeTerminal()
    display = pg.SimulationProgress(0.0, 2.0, stream=stream)
    assert display.bar.style == "terminal"
    display(0.5, 1e-3, 4)
    display.steps = 700
    display(1.0, 2e-3, 3)
    shown = stream.getvalue()
    assert "\n" not in shown and shown.count("\r") == 2
    first, second = shown.split("\r")[1:]
    assert "25%" in first and "t = 0.5/2 s" in first and "h = 0.001 s" in first
    assert "4 Newton it" in first and "left" in first and "step 7" not in first
    assert "50%" in second and "[######......]" in second and "step 700" in second
    result = types.SimpleNamespace(
        time=[0.0, 2.0],
        statistics={"steps": 1500, "rejected_steps": 2, "newton_iterations": 4500},
        error=None,
    )
    display.finish(result)
    last = stream.getvalue().split("\r")[-1]
    assert last.endswith("\n") and "100%" in last and "left" not in last
    assert "1500 steps" in last and "2 rejected" in last and "3.00 Newton it/step" in last


def test_a_bar_that_is_no_terminal_writes_a_line_at_each_tenth():
    stream = io.StringIO()
    bar = pg.ProgressBar("job", stream=stream)
    assert bar.style == "lines"
    for fraction in (0.01, 0.05, 0.12, 0.13, 0.35, 0.99, 1.0):
        bar.update(fraction, f"at {fraction}")
    bar.close("all done")
    lines = stream.getvalue().splitlines()
    # 0 %, 10 %, 30 % and 90 % crossed; 100 % is the closing line only.
    assert [line.split()[1] for line in lines] == ["1%", "12%", "35%", "99%", "100%"]
    assert "\r" not in stream.getvalue() and "[" not in stream.getvalue()
    assert "left" in lines[1] and "at 0.12" in lines[1]
    assert lines[-1].endswith("all done") and "left" not in lines[-1]


def test_simulate_with_progress_true_writes_to_stderr_and_nothing_without(capsys):
    example = fm.examples.pendulum()
    fm.simulate(example.system, 0.5, 1e-3, output_interval=0.05, progress=True)
    err = capsys.readouterr().err
    assert "simulating" in err and "100%" in err and "t = 0.5/0.5 s" in err
    assert "steps" in err and "Newton it/step" in err  # the totals
    for quiet in (False, None):
        fm.simulate(example.system, 0.5, 1e-3, output_interval=0.05, progress=quiet)
        assert capsys.readouterr() == ("", "")


def test_a_given_display_gets_the_times_of_the_run_and_its_step_numbers(no_throttle):
    stream = FakeTerminal()
    display = pg.SimulationProgress(stream=stream, style="terminal")
    result = explicit_pendulum_run(1.0, progress=display)
    assert display.start_time == 0.0 and display.end_time == 1.0
    frames = stream.getvalue().split("\r")[1:]
    assert frames[0].startswith("simulating    0%") and "t = 0/1 s" in frames[0]
    middle = [f for f in frames[1:-1] if "left" in f]
    assert middle, frames  # the run takes several tenths of a second
    assert all("step " in f for f in middle[1:]) and "Newton" not in middle[-1]
    assert f"{result.statistics['steps']} steps" in frames[-1]
    assert "function evaluations" in frames[-1]


def test_a_progress_function_is_still_called_with_time_step_size_and_iterations():
    calls = []
    explicit_pendulum_run(0.5, progress=lambda t, h, its: calls.append((t, h, its)))
    assert calls and all(h == pytest.approx(5e-5) for _, h, _ in calls)
    times = [t for t, _, _ in calls]
    assert times == sorted(times) and 0 < times[-1] <= 0.5
    with pytest.raises(fm.InvalidParameterError, match="progress must be True"):
        fm.simulate(fm.examples.pendulum().system, 0.1, 1e-3, progress="yes")


def test_a_failing_display_is_switched_off_and_the_run_completes(caplog):
    # Decision: the built-in display is guarded (a closed terminal must not lose a long run);
    # a progress function of the user is not (its exception is a CallbackError, below).
    display = pg.SimulationProgress(stream=BrokenStream(), style="lines")
    with caplog.at_level(logging.WARNING, logger="flexmbd"):
        result = explicit_pendulum_run(0.5, progress=display)
    assert result.success and result.time[-1] == pytest.approx(0.5)
    warned = [r for r in caplog.records if r.name == "flexmbd.progress"]
    assert len(warned) == 1 and "switched off: OSError: stream gone" in warned[0].getMessage()
    assert warned[0].levelno == logging.WARNING

    def failing(t, h, its):
        raise ValueError("display bug")

    with pytest.raises(fm.CallbackError, match="progress function") as info:
        explicit_pendulum_run(0.5, progress=failing)
    assert isinstance(info.value.__cause__, ValueError) and len(info.value.result.time) >= 1


def test_ctrl_c_in_the_python_code_of_a_run_is_an_interruption():
    # Ctrl-C that lands while the progress display (or the results writer) runs reaches
    # Python as KeyboardInterrupt inside the callback: a CallbackError before, so that
    # `flexmbd run` said "failed" instead of "interrupted".
    def pressed(t, h, its):
        raise KeyboardInterrupt

    with pytest.raises(fm.SimulationInterrupted, match="interrupted at t = ") as info:
        explicit_pendulum_run(0.5, progress=pressed)
    assert isinstance(info.value.__cause__, KeyboardInterrupt)
    assert 0 < info.value.result.time[-1] <= info.value.time < 0.5


def test_events_are_logged_once_under_flexmbd_while_the_run_goes_on(caplog):
    seen = []  # the simulated time reached when each record was logged
    end = 3.0

    class Watch(logging.Handler):
        def emit(self, record):
            seen.append((record, calls[-1] if calls else 0.0))

    calls = []
    watch = Watch()
    logging.getLogger("flexmbd").addHandler(watch)
    try:
        with caplog.at_level(logging.INFO, logger="flexmbd"):
            result = explicit_pendulum_run(end, progress=lambda t, h, its: calls.append(t))
    finally:
        logging.getLogger("flexmbd").removeHandler(watch)
    events = [(r, t) for r, t in seen if hasattr(r, "event")]
    assert len(events) == len(result.events) >= 4  # each event once
    assert {r.event["kind"] for r, _ in events} == {"repartition"}
    assert all(r.name == "flexmbd.simulation" and r.levelno == logging.INFO for r, _ in events)
    first, reached = events[0]
    assert "repartition" in first.getMessage() and f"t = {first.event['time']:.6g} s" in (
        first.getMessage()
    )
    # Logged from the records delivered during the run, not only at its end.
    assert first.event["time"] <= reached < 0.9 * end
    summary = [r for r, _ in seen if r.getMessage().startswith("run done")]
    assert len(summary) == 1 and summary[0].levelno == logging.INFO
    assert f"{result.statistics['steps']} steps" in summary[0].getMessage()


def test_initial_corrections_are_warnings_and_routine_events_info(caplog):
    system = fm.System(gravity=(0, -9.81, 0))
    link = system.add_rigid_body(1.0, (1e-4, 1 / 12, 1 / 12), position=(0.5, 0.01, 0))
    end = system.add_marker(link, position=(-0.5, 0, 0))
    system.add_revolute_joint(system.add_marker(system.ground), end, name="hinge")
    with caplog.at_level(logging.INFO, logger="flexmbd"):
        with pytest.warns(fm.InitialCorrectionWarning):
            fm.simulate(system, 0.01, 1e-3)
    levels = {r.event["kind"]: r.levelno for r in caplog.records if hasattr(r, "event")}
    assert levels == {"initial correction": logging.WARNING}
    from flexmbd.simulation import EVENT_LEVELS

    assert EVENT_LEVELS["singular configuration"] == logging.WARNING
    assert EVENT_LEVELS["redundant constraints"] == logging.INFO


def test_the_library_adds_only_a_null_handler():
    handlers = logging.getLogger("flexmbd").handlers
    assert handlers and all(isinstance(h, logging.NullHandler) for h in handlers)
    for name in ("flexmbd.simulation", "flexmbd.progress"):
        assert logging.getLogger(name).handlers == []
    # In a fresh interpreter too, and importing flexmbd configures no root handler.
    code = (
        "import logging, flexmbd; root = logging.getLogger(); "
        "print(len(root.handlers), [type(h).__name__ for h in "
        "logging.getLogger('flexmbd').handlers])"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    ).stdout
    assert out.strip() == "0 ['NullHandler']"


def test_track_calls_a_function_or_shows_a_bar_and_refuses_anything_else(capsys):
    calls = []
    assert list(pg.track("abc", lambda done, total: calls.append((done, total)), "x")) == list(
        "abc"
    )
    assert calls == [(1, 3), (2, 3), (3, 3)]
    assert list(pg.track(range(4), True, "counting", unit="items")) == [0, 1, 2, 3]
    err = capsys.readouterr().err
    assert "counting    0%" in err and "counting  100%" in err and "4 of 4 items" in err
    assert list(pg.track(range(2), False, "silent")) == [0, 1]
    assert capsys.readouterr() == ("", "")
    with pytest.raises(fm.InvalidParameterError, match="progress must be"):
        pg.track(range(2), 3, "wrong")


def test_a_status_line_lives_on_a_terminal_only():
    stream = FakeTerminal()
    with pg.status("plotting", stream=stream):
        time.sleep(0.6)
    shown = stream.getvalue()
    assert "plotting ... 0." in shown and shown.endswith("\r")
    assert shown.split("\r")[-2].strip() == ""  # erased at the end
    quiet = io.StringIO()
    with pg.status("plotting", stream=quiet):
        time.sleep(0.3)
    assert quiet.getvalue() == ""


def fake_notebook(monkeypatch, widgets):
    """A Jupyter kernel's IPython (and, if `widgets`, an ipywidgets) in sys.modules."""
    shown = []
    ipython = types.ModuleType("IPython")
    ipython.get_ipython = lambda: types.SimpleNamespace(kernel=object())
    display = types.ModuleType("IPython.display")
    display.display = shown.append
    monkeypatch.setitem(sys.modules, "IPython", ipython)
    monkeypatch.setitem(sys.modules, "IPython.display", display)
    if widgets:
        module = types.ModuleType("ipywidgets")
        module.__spec__ = importlib.machinery.ModuleSpec("ipywidgets", None)
        module.FloatProgress = lambda **kw: types.SimpleNamespace(bar_style="", **kw)
        module.Label = lambda: types.SimpleNamespace(value="")
        module.HBox = lambda children: types.SimpleNamespace(children=children)
        monkeypatch.setitem(sys.modules, "ipywidgets", module)
    else:
        monkeypatch.setitem(sys.modules, "ipywidgets", None)
    return shown


def test_a_notebook_shows_a_widget_and_without_ipywidgets_a_redrawn_line(
    monkeypatch, no_throttle, capsys
):
    shown = fake_notebook(monkeypatch, widgets=True)
    display = pg.SimulationProgress(0.0, 2.0)
    assert display.bar.style == "widget"
    display(0.5, 1e-3, 3)
    (box,) = shown
    bar, label = box.children
    assert bar.value == 0.25 and "t = 0.5/2 s" in label.value and "left" in label.value
    display.bar.close(failed=True)
    assert bar.bar_style == "danger"
    assert capsys.readouterr().err == ""
    fake_notebook(monkeypatch, widgets=False)
    assert pg.ProgressBar("x").style == "terminal"  # Jupyter draws carriage returns


def test_render_animation_and_vtu_series_report_their_frames(tmp_path, capsys):
    from flexmbd.animation import render_animation, write_vtu_series

    example = fm.examples.flexible_slider_crank()
    result = fm.simulate(example.system, 2e-3, 1e-4, output_interval=5e-4)
    done = []
    render_animation(
        result, tmp_path / "a.gif", frames=3, progress=lambda k, n: done.append((k, n))
    )
    assert done == [(1, 3), (2, 3), (3, 3)]
    write_vtu_series(result, tmp_path / "vtu", progress=True)
    err = capsys.readouterr().err
    assert "writing" in err and f"{len(result.time)} of {len(result.time)} files" in err


def test_the_cli_shows_progress_and_events_of_run_and_animate(tmp_path):
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    command = [sys.executable, "-m", "flexmbd", "run", "pendulum", "--end", "1.5"]
    command += ["--solver", "rk4:partitioning", "--no-plot", "--no-animation", "-v"]
    run = subprocess.run(
        [*command, "-o", str(tmp_path / "a.h5")],
        capture_output=True,
        text=True,
        timeout=300,
        env=env,
    )
    assert run.returncode == 0, run.stderr
    lines = run.stderr.splitlines()
    bars = [line for line in lines if line.startswith("  simulating")]
    assert "100%" in bars[-1] and "t = 1.5/1.5 s" in bars[-1] and "steps" in bars[-1]
    assert any("left" in line for line in bars[:-1]), run.stderr  # lines every 10 %
    assert any("[INFO] t = 0.4853 s: repartition" in line for line in lines)
    assert any("[INFO] run done" in line for line in lines)
    animate = subprocess.run(
        [sys.executable, "-m", "flexmbd", "animate", str(tmp_path / "a.h5"), "--frames", "3"],
        capture_output=True,
        text=True,
        timeout=300,
        env=env,
        cwd=tmp_path,
    )
    assert animate.returncode == 0, animate.stderr
    assert "rendering" in animate.stderr and "100%" in animate.stderr
    assert "3 of 3 frames" in animate.stderr


def test_the_cli_is_quiet_with_q_and_shows_warnings_without_v(tmp_path, capsys):
    argv = ["run", "pendulum", "--end", "0.5", "--no-plot", "--no-animation"]
    assert main([*argv, "-o", str(tmp_path / "a.h5"), "-q"]) == 0
    assert capsys.readouterr().err == ""
    assert main([*argv, "-o", str(tmp_path / "b.h5"), "--solver", "rk4:partitioning"]) == 0
    err = capsys.readouterr().err
    assert "simulating" in err and "[INFO]" not in err  # routine events only with -v
    assert logging.getLogger("flexmbd").handlers == [
        h for h in logging.getLogger("flexmbd").handlers if isinstance(h, logging.NullHandler)
    ]
