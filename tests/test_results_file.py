"""HDF5 results files: exact round trips, records written during the run, runs that fail, are
interrupted or are killed keep what was computed, and tables for pandas and xarray."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time

import h5py
import numpy as np
import pytest

import flexmbd as fm
from flexmbd.examples import EXAMPLES
from flexmbd.results_file import read_results_metadata

FIELDS = ("time", "coordinates", "velocities", "accelerations", "multipliers")


def assert_same_records(a: fm.Result, b: fm.Result, count: int | None = None) -> None:
    count = len(a) if count is None else count
    for name in FIELDS + ("constraint_violation",):
        np.testing.assert_array_equal(getattr(a, name)[:count], getattr(b, name)[:count], name)
    np.testing.assert_array_equal(a._reactions[:count], b._reactions[:count])
    np.testing.assert_array_equal(a._sensors[:count], b._sensors[:count])
    np.testing.assert_array_equal(a._energy[:count], b._energy[:count])


def test_round_trip_of_a_flexible_model_is_exact(tmp_path):
    example = EXAMPLES["flexible-slider-crank"]()
    path = tmp_path / "crank.h5"
    result = fm.simulate(
        example.system,
        0.01,
        example.step_size,
        output_interval=example.output_interval,
        results_file=path,
        metadata={"example": "flexible-slider-crank"},
    )
    back = fm.read_results(path)
    assert back.success and len(back) == len(result) == 101
    assert_same_records(result, back)
    assert back.statistics == result.statistics
    assert back.layout["joints"][0]["name"] == "bearing"
    # The deformable body's data travel with the results: node outputs from the file alone.
    np.testing.assert_array_equal(back.node_positions("rod"), result.node_positions("rod"))
    np.testing.assert_array_equal(back.section_forces("rod"), result.section_forces("rod"))
    np.testing.assert_array_equal(back.reaction_force("guide"), result.reaction_force("guide"))
    header = read_results_metadata(path)
    assert header["metadata"] == {"example": "flexible-slider-crank"}
    assert header["status"]["state"] == "complete" and header["records"] == 101
    assert header["flexible"] == [2]
    assert header["units"] == {
        "length": "m",
        "mass": "kg",
        "time": "s",
        "angle": "rad",
        "force": "N",
    }


def test_round_trip_keeps_sensors_events_and_redundancy(tmp_path):
    example = EXAMPLES["four-bar-spatial"]()
    path = tmp_path / "fourbar.h5"
    result = fm.simulate(example.system, 0.2, 1e-3, output_interval=0.01, results_file=path)
    back = fm.read_results(path)
    assert_same_records(result, back)
    assert back.redundancy is not None and back.redundancy["rank"] == result.redundancy["rank"]
    assert back.redundancy["removed_rows"] == result.redundancy["removed_rows"]
    assert [e["kind"] for e in back.events] == [e["kind"] for e in result.events]
    assert "redundant constraints" in [e["kind"] for e in back.events]


@pytest.mark.parametrize(
    "solver, end",
    [(None, 1.0), (fm.ExplicitSolver("rk4", "projection"), 0.2)],
    ids=["generalized-alpha", "rk4"],
)
def test_records_reach_the_file_while_the_run_goes_on(tmp_path, solver, end):
    system = fm.System(gravity=(0, -9.81, 0))
    mass = system.add_point_mass(1.0, position=(1, 0, 0), name="mass")
    system.add_distance_joint(system.add_marker(system.ground), system.add_marker(mass))

    def slow_force(t, q, qd):
        time.sleep(0.002)  # a run long enough for several flushes
        return np.zeros(3)

    system.add_callback_force([mass], slow_force, name="slow")
    path = tmp_path / "running.h5"
    seen: list[int] = []

    def progress(t, h, iterations):
        # The file is readable by another reader during the run, with the records so far.
        seen.append(read_results_metadata(path)["records"])

    result = fm.simulate(
        system,
        end,
        0.005,
        output_interval=0.01,
        results_file=path,
        progress=progress,
        solver=solver,
    )
    assert len(seen) >= 3, seen
    assert seen[-1] > 0 and seen[-1] < len(result), seen
    assert seen == sorted(seen)
    assert_same_records(result, fm.read_results(path))


def test_a_write_interval_writes_less_often_and_loses_nothing(tmp_path):
    """``results_write_interval`` holds deliveries back and writes them together: nothing
    reaches the file during a run shorter than the interval, and the file ends with every
    record (kept in memory or not), also when the run fails."""
    system = fm.System(gravity=(0, -9.81, 0))
    mass = system.add_point_mass(1.0, position=(1, 0, 0), name="mass")
    system.add_distance_joint(system.add_marker(system.ground), system.add_marker(mass))

    def slow_force(t, q, qd):
        time.sleep(0.002)  # several deliveries
        if t > 0.4 and q[0] == q[0] and failing:
            raise ZeroDivisionError("user bug")
        return np.zeros(3)

    failing = False
    system.add_callback_force([mass], slow_force, name="slow")
    seen: list[int] = []
    path = tmp_path / "held.h5"

    def progress(t, h, iterations):
        seen.append(read_results_metadata(path)["records"])

    settings = {"output_interval": 0.01, "results_write_interval": 3600.0}
    kept = fm.simulate(system, 0.5, 0.005, results_file=path, progress=progress, **settings)
    assert len(seen) >= 3 and set(seen) == {0}, seen
    assert_same_records(kept, fm.read_results(path))
    lean = fm.simulate(
        system, 0.5, 0.005, results_file=tmp_path / "lean.h5", keep_in_memory=False, **settings
    )
    assert len(lean) < len(kept)
    assert_same_records(kept, fm.read_results(tmp_path / "lean.h5"))
    failing = True
    with pytest.raises(fm.CallbackError) as info:
        fm.simulate(system, 0.5, 0.005, results_file=tmp_path / "failed.h5", **settings)
    back = fm.read_results(tmp_path / "failed.h5")
    assert not back.success and len(back) == len(info.value.result) > 30
    assert_same_records(info.value.result, back)
    for bad in (-1.0, float("nan"), float("inf"), "1"):
        with pytest.raises(fm.InvalidParameterError, match="write_interval"):
            fm.simulate(
                system, 0.01, 0.005, results_file=tmp_path / "x.h5", results_write_interval=bad
            )


def test_a_failed_run_keeps_its_records_and_says_why(tmp_path, assert_close):
    system = fm.System()
    body = system.add_point_mass(1.0, name="mass")

    def force(t, q, qd):
        if t > 0.05:
            raise ZeroDivisionError("user bug")
        return np.array([1.0, 0.0, 0.0])

    system.add_callback_force([body], force, name="user")
    path = tmp_path / "failed.h5"
    with pytest.raises(fm.CallbackError) as info:
        fm.simulate(system, 1.0, 0.01, results_file=path)
    back = fm.read_results(path)
    assert not back.success and isinstance(back.error, fm.CallbackError)
    assert "user bug" in str(back.error)
    # (the error's item and time read back too: they were None)
    assert (back.error.item, back.error.time) == (info.value.item, info.value.time)
    assert back.error.item == "force 'user'" and back.error.time > 0.05
    assert_close(back.time[-1], 0.05, rel=1e-6, abs=1e-12, what="last time")
    assert_same_records(info.value.result, back)
    assert read_results_metadata(path)["status"]["state"] == "failed"


KILLED_RUN = textwrap.dedent(
    """
    import sys
    import flexmbd as fm
    from flexmbd.examples import EXAMPLES

    example = EXAMPLES["flexible-slider-crank"]()
    fm.simulate(example.system, 100.0, example.step_size,
                output_interval=example.output_interval, results_file=sys.argv[1])
    """
)


@pytest.mark.parametrize("kill", [signal.SIGKILL, signal.SIGINT])
def test_a_killed_run_keeps_every_record_written_before_the_kill(tmp_path, kill, assert_close):
    path = tmp_path / "killed.h5"
    process = subprocess.Popen([sys.executable, "-c", KILLED_RUN, str(path)])
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            if path.exists():
                try:
                    if read_results_metadata(path)["records"] > 200:
                        break
                except (OSError, KeyError, fm.FlexmbdError):
                    pass  # the writer is still creating the file
            time.sleep(0.05)
        else:
            pytest.fail("the run wrote no records in 120 s")
        os.kill(process.pid, kill)
        process.wait(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    back = fm.read_results(path)
    count = len(back)
    assert count > 200
    assert not back.success and isinstance(back.error, fm.SimulationInterrupted)
    state = read_results_metadata(path)["status"]["state"]
    assert state == ("running" if kill == signal.SIGKILL else "interrupted")
    # Every record is complete and valid: the same as an uninterrupted run to that time.
    example = EXAMPLES["flexible-slider-crank"]()
    reference = fm.simulate(
        example.system, back.time[-1], example.step_size, output_interval=example.output_interval
    )
    assert len(reference) == count
    assert_close(back.time, reference.time, abs=1e-15, what="time")
    for name in ("coordinates", "velocities", "multipliers"):
        scale = np.abs(getattr(reference, name)).max()
        assert_close(getattr(back, name), getattr(reference, name), abs=1e-9 * scale, what=name)


def test_a_text_field_caught_mid_write_reads_as_not_written(tmp_path):
    # The writer of a running simulation rewrites statistics, events, redundancy and status
    # with each chunk (resize, then write); a reader in between sees bytes that do not decode.
    example = EXAMPLES["four-bar-spatial"]()
    path = tmp_path / "torn.h5"
    fm.simulate(example.system, 0.05, 1e-3, output_interval=0.01, results_file=path)
    with h5py.File(path, "r+") as file:
        torn = np.frombuffer(b'{"steps": 50, "rejec', dtype=np.uint8)
        file["statistics"].resize((len(torn),))
        file["statistics"][:] = torn
        file["status"].resize((3,))
        file["status"][:] = np.frombuffer(b'{"s', dtype=np.uint8)
    header = read_results_metadata(path)
    assert header["statistics"] == {} and header["status"] is None
    assert header["records"] == 6
    back = fm.read_results(path)
    assert len(back) == 6 and not back.success  # no status: a run still going


def test_files_that_are_not_results_files_are_refused(tmp_path):
    text = tmp_path / "notes.h5"
    text.write_text("not hdf5")
    with pytest.raises(fm.InvalidModelError, match="not an HDF5 file"):
        fm.read_results(text)
    other = tmp_path / "other.h5"
    with h5py.File(other, "w", libver="latest") as file:
        file.attrs["format"] = "something else"
    with pytest.raises(fm.InvalidModelError, match="not a flexmbd results file"):
        fm.read_results(other)
    with pytest.raises(FileNotFoundError):
        fm.read_results(tmp_path / "missing.h5")
    # Both a ResultsFileError (an OSError, as documented) and an InvalidModelError.
    with pytest.raises(OSError, match="not a flexmbd results file") as caught:
        fm.read_results(other)
    assert isinstance(caught.value, fm.NotAResultsFileError | fm.ResultsFileError)
    with pytest.raises(fm.ResultsFileError, match="not a regular file"):
        fm.read_results(tmp_path)


def test_metadata_a_results_file_cannot_hold_is_refused_before_the_file(tmp_path):
    # A set in the metadata was a raw TypeError and left a file without records.
    path = tmp_path / "run.h5"
    example = fm.examples.pendulum()
    with pytest.raises(fm.InvalidParameterError, match=r"metadata\['tags'\]: cannot store set"):
        fm.simulate(example.system, 0.01, 1e-3, results_file=path, metadata={"tags": {"a"}})
    assert not path.exists()


def test_tables_for_pandas_and_xarray(tmp_path):
    example = EXAMPLES["flexible-slider-crank"]()
    path = tmp_path / "crank.h5"
    fm.simulate(example.system, 0.005, example.step_size, output_interval=1e-3, results_file=path)
    result = fm.read_results(path)
    frame = result.to_dataframe()
    assert len(frame) == len(result)
    np.testing.assert_array_equal(frame.index.to_numpy(), result.time)
    np.testing.assert_array_equal(frame["crank.position.x"], result.position("crank")[:, 0])
    np.testing.assert_array_equal(
        frame["guide.reaction_force.y"], result.reaction_force("guide")[:, 1]
    )
    np.testing.assert_array_equal(frame["rod.elastic.3"], result.elastic_coordinates("rod")[:, 3])
    np.testing.assert_array_equal(frame["kinetic_energy"], result.kinetic_energy)
    # (the strain energy and the power of the non-conservative forces were left out, and
    # nothing said a failed run's records end early)
    np.testing.assert_array_equal(frame["strain_energy"], result.strain_energy)
    np.testing.assert_array_equal(frame["nonconservative_power"], result.nonconservative_power)
    assert result.strain_energy.max() > 0 and frame.attrs["success"] is True
    data = result.to_xarray()
    np.testing.assert_array_equal(data["coordinates"].to_numpy(), result.coordinates)
    np.testing.assert_array_equal(data["strain_energy"].to_numpy(), result.strain_energy)
    force = data["reactions"].sel(joint="bearing", component="force y").to_numpy()
    np.testing.assert_array_equal(force, result.reaction_force("bearing")[:, 1])
    assert data["multipliers"].sel(constraint="drive: angle").shape == (len(result),)


def test_sensor_values_are_labelled_by_axis_in_tables():
    # Columns "tip.0", "tip.1", ... and an unlabelled xarray dimension before.
    system = fm.System(gravity=(0, -9.81, 0))
    bob = system.add_rigid_body(1.0, (0.01, 0.01, 0.01), position=(1, 0, 0), name="bob")
    system.add_revolute_joint(system.add_marker(system.ground),
                              system.add_marker(bob, position=(-1, 0, 0)))  # fmt: skip
    tip = system.add_marker(bob, position=(0.5, 0, 0))
    system.add_sensor(tip, "position", name="tip")
    system.add_sensor(tip, "orientation", name="turn")
    result = fm.simulate(system, 0.05, 1e-2)
    frame = result.to_dataframe()
    np.testing.assert_array_equal(frame["tip.y"], result.sensor("tip")[:, 1])
    np.testing.assert_array_equal(frame["turn.yx"], result.sensor("turn")[:, 1, 0])
    data = result.to_xarray()
    values = data["sensors"].sel(sensor_value="tip.z").to_numpy()
    np.testing.assert_array_equal(values, result.sensor("tip")[:, 2])
    # A sensor named like a body's series overwrote its column without a word.
    system.add_sensor(tip, "position", name="bob.position")
    result = fm.simulate(system, 0.05, 1e-2)
    with pytest.raises(fm.InvalidModelError, match="two time series are named 'bob.position.x'"):
        result.to_dataframe()


# Faults (issue 28) ------------------------------------------------------------------------


def pendulum() -> fm.System:
    system = fm.System(gravity=(0, -9.81, 0))
    mass = system.add_point_mass(1.0, position=(1, 0, 0), name="mass")
    system.add_distance_joint(system.add_marker(system.ground), system.add_marker(mass))
    return system


def test_a_results_path_that_is_a_folder_a_missing_folder_or_another_file_is_refused(tmp_path):
    with pytest.raises(fm.ResultsFileError, match="is a folder"):
        fm.simulate(pendulum(), 0.01, 1e-3, results_file=tmp_path)
    with pytest.raises(fm.ResultsFileError, match="its folder .*missing.* does not exist"):
        fm.simulate(pendulum(), 0.01, 1e-3, results_file=tmp_path / "missing" / "r.h5")
    # A model file given as the output is never replaced (flexmbd run -o model.yaml).
    model = tmp_path / "model.yaml"
    model.write_text("name: x\n")
    with pytest.raises(fm.ResultsFileError, match="not a flexmbd results file: it is not"):
        fm.simulate(pendulum(), 0.01, 1e-3, results_file=model)
    assert model.read_text() == "name: x\n"
    results = tmp_path / "r.h5"
    fm.simulate(pendulum(), 0.01, 1e-3, results_file=results)
    with pytest.raises(fm.ResultsFileError, match="is the model file of the run"):
        fm.simulate(pendulum(), 0.01, 1e-3, results_file=results, protect=(results,))
    readonly = tmp_path / "readonly"
    readonly.mkdir()
    readonly.chmod(0o555)
    try:
        if os.access(readonly, os.W_OK):
            pytest.skip("running as a user who may write read-only folders")
        with pytest.raises(fm.ResultsFileError, match="cannot write"):
            fm.simulate(pendulum(), 0.01, 1e-3, results_file=readonly / "r.h5")
    finally:
        readonly.chmod(0o755)


def test_a_second_writer_of_the_same_file_is_refused_and_the_first_file_stays_whole(tmp_path):
    from flexmbd.results_file import ResultsWriter

    path = tmp_path / "same.h5"
    model = pendulum().compile()
    first = ResultsWriter(path, model)
    try:
        with pytest.raises(
            fm.ResultsFileError, match=f"being written by another run .*{os.getpid()}"
        ):
            fm.simulate(model, 0.01, 1e-3, results_file=path)
    finally:
        first.close()
    # The same in two processes: the second run is refused, the first one's file is whole.
    script = textwrap.dedent(
        """
        import sys, time
        import numpy as np
        import flexmbd as fm
        system = fm.System(gravity=(0, -9.81, 0))
        mass = system.add_point_mass(1.0, position=(1, 0, 0))
        system.add_distance_joint(system.add_marker(system.ground), system.add_marker(mass))
        system.add_callback_force([mass], lambda t, q, qd: time.sleep(0.001) or np.zeros(3))
        fm.simulate(system, 1.0, 1e-3, output_interval=1e-3, results_file=sys.argv[1])
        """
    )
    process = subprocess.Popen([sys.executable, "-c", script, str(path)])
    try:
        deadline = time.monotonic() + 60
        while not path.with_name(f".{path.name}.lock").exists() and time.monotonic() < deadline:
            time.sleep(0.02)
        time.sleep(0.3)
        with pytest.raises(fm.ResultsFileError, match=f"process {process.pid}"):
            fm.simulate(pendulum(), 0.01, 1e-3, results_file=path)
        assert process.wait(timeout=120) == 0
    finally:
        if process.poll() is None:
            process.kill()
    back = fm.read_results(path)
    assert back.success and len(back) == 1001


def test_a_failed_rerun_leaves_the_earlier_results_in_place(tmp_path):
    path = tmp_path / "run.h5"
    first = fm.simulate(pendulum(), 1.0, 1e-3, output_interval=1e-3, results_file=path)
    assert len(fm.read_results(path)) == len(first) == 1001
    failing = pendulum()

    def force(t, q, qd):
        raise ZeroDivisionError("user bug at the start")

    failing.add_callback_force([fm.BodyId(1)], force, name="bug")
    with pytest.raises(fm.CallbackError):
        fm.simulate(failing, 1.0, 1e-3, output_interval=1e-3, results_file=path)
    # Regression: the earlier 1001 records were replaced by the failed run's one record.
    back = fm.read_results(path)
    assert back.success and len(back) == 1001
    assert_same_records(first, back)
    assert not (tmp_path / "run.h5.partial").exists()
    # A re-run that gets going replaces it.
    fm.simulate(pendulum(), 0.5, 1e-3, output_interval=1e-3, results_file=path)
    assert len(fm.read_results(path)) == 501


def test_records_kept_only_in_the_file_are_the_same_records(tmp_path):
    example = EXAMPLES["flexible-slider-crank"]()
    kept = fm.simulate(example.system, 0.05, example.step_size, results_file=tmp_path / "a.h5")
    lean = fm.simulate(
        example.system,
        0.05,
        example.step_size,
        results_file=tmp_path / "b.h5",
        keep_in_memory=False,
        progress=lambda *args: time.sleep(0.02),  # several deliveries to the file
    )
    assert 1 <= len(lean) < len(kept)
    assert lean.file == tmp_path / "b.h5"
    np.testing.assert_array_equal(lean.coordinates[-1], kept.coordinates[-1])
    assert_same_records(kept, fm.read_results(tmp_path / "b.h5"))
    with pytest.raises(fm.InvalidParameterError, match="results_file"):
        fm.simulate(example.system, 0.01, example.step_size, keep_in_memory=False)


DAMAGED = textwrap.dedent(
    """
    import sys, time
    import flexmbd as fm
    start = time.perf_counter()
    try:
        result = fm.read_results(sys.argv[1])
        print("read", len(result), type(result.error).__name__)
    except fm.FlexmbdError as error:
        print("error", type(error).__name__)
    print(f"seconds {time.perf_counter() - start:.3f}")
    """
)


def test_damaged_results_files_are_read_quickly_as_far_as_they_can_be(tmp_path):
    path = tmp_path / "ok.h5"
    fm.simulate(pendulum(), 1.0, 1e-3, output_interval=1e-3, results_file=path)
    data = path.read_bytes()
    cases = {}
    for fraction in (0.1, 0.5, 0.9, 0.99):
        cases[f"truncated {fraction}"] = data[: int(len(data) * fraction)]
    flipped = bytearray(data)
    for k in range(4096, len(flipped), 1531):
        flipped[k] ^= 0x5A
    cases["bit flips"] = bytes(flipped)
    for name, content in cases.items():
        damaged = tmp_path / "damaged.h5"
        damaged.write_bytes(content)
        # Regression: a truncated file kept the reader waiting on HDF5's retries > 10 min.
        run = subprocess.run(
            [sys.executable, "-c", DAMAGED, str(damaged)],
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert run.returncode == 0 and "Traceback" not in run.stderr, (name, run.stderr)
        seconds = float(run.stdout.split("seconds")[1])
        assert seconds < 5, (name, seconds)
        assert run.stdout.startswith(("read", "error")), (name, run.stdout)
        if run.stdout.startswith("read"):
            assert "ResultsFileError" in run.stdout or "None" in run.stdout, run.stdout
    # A negative record count is refused, not read as "drop the last records".
    with h5py.File(path, "r+") as file:
        file["records"][0] = -5
    with pytest.raises(fm.ResultsFileError, match="record count of -5"):
        fm.read_results(path)


def test_a_file_cut_near_its_end_never_reads_lost_data_as_zeros(tmp_path):
    # Regression: HDF5 reads the part of a chunk beyond the end of a cut file as zeros, without
    # an error: a run cut at 91-96 % of its file was read as complete, its constraint
    # violations all 0 and its statistics empty. Every record read now equals the run's, and
    # whatever is lost is a ResultsFileError.
    path = tmp_path / "ok.h5"
    example = EXAMPLES["tetrahedral-pendulum"]()
    fm.simulate(example.system, 0.2, 1e-3, output_interval=0.01, results_file=path)
    whole = fm.read_results(path)
    data = path.read_bytes()
    fields = ("time", "coordinates", "velocities", "multipliers", "constraint_violation")
    checked_info = 0
    for fraction in np.linspace(0.80, 0.999, 30):
        damaged = tmp_path / "cut.h5"
        damaged.write_bytes(data[: int(len(data) * fraction)])
        try:
            back = fm.read_results(damaged)
        except fm.ResultsFileError:
            continue
        count = len(back.time)
        for name in fields:
            assert np.array_equal(getattr(back, name), getattr(whole, name)[:count]), (
                fraction,
                name,
            )
        lost = count < len(whole.time) or back.statistics != whole.statistics
        assert lost == isinstance(back.error, fm.ResultsFileError), (fraction, back.error)
        checked_info += 1
        if checked_info % 6:
            continue
        info = subprocess.run(
            [sys.executable, "-m", "flexmbd", "info", str(damaged)],
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert "Traceback" not in info.stderr, info.stderr
        assert ("damaged:" in info.stdout) == lost, info.stdout


FULL_DISK = textwrap.dedent(
    """
    import resource, sys
    import flexmbd as fm
    resource.setrlimit(resource.RLIMIT_FSIZE, (int(sys.argv[2]), int(sys.argv[2])))
    system = fm.System(gravity=(0, -9.81, 0))
    mass = system.add_point_mass(1.0, position=(1, 0, 0))
    system.add_distance_joint(system.add_marker(system.ground), system.add_marker(mass))
    try:
        fm.simulate(system, 200.0, 1e-3, output_interval=1e-3, results_file=sys.argv[1])
        print("no error")
    except fm.ResultsFileError as error:
        print("kept", len(error.result), str(error).split("(")[0])
    """
)


def test_a_full_disk_is_a_typed_error_and_the_file_keeps_what_was_committed(tmp_path, assert_close):
    path = tmp_path / "full.h5"
    run = subprocess.run(
        [sys.executable, "-c", FULL_DISK, str(path), str(4 << 20)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    # Regression: OSError tracebacks, then a segmentation fault at exit, and a file left
    # "running" with 0 records.
    assert run.returncode == 0, run.stderr
    assert run.stdout.startswith("kept"), run.stdout + run.stderr
    assert "Traceback" not in run.stderr
    back = fm.read_results(path)
    assert 0 < len(back) < 200_001
    assert isinstance(back.error, fm.ResultsFileError) and "file size limit" in str(back.error)
    # Every committed record is a valid record of the run.
    reference = fm.simulate(pendulum(), back.time[-1], 1e-3, output_interval=1e-3)
    assert_close(back.coordinates, reference.coordinates, abs=1e-12, what="coordinates")


DAMAGED_HEADER = textwrap.dedent(
    """
    import sys, time
    import flexmbd as fm
    from flexmbd.results_file import read_results_metadata
    for read in (read_results_metadata, fm.read_results):
        start = time.perf_counter()
        try:
            read(sys.argv[1])
            print("read", end=" ")
        except fm.ResultsFileError as error:
            print("error", "global heap" in str(error), end=" ")
        print(f"{time.perf_counter() - start:.3f}")
    """
)


def test_a_file_cut_in_its_string_heap_is_refused_at_once(tmp_path):
    # Regression (fuzz suite): a results file cut inside the global heap of its string
    # attributes made HDF5 loop for ever in read_results_metadata (and a flipped byte there
    # can crash the process): the heap is checked before HDF5 reads it.
    path = tmp_path / "r.h5"
    fm.simulate(pendulum(), 0.01, 1e-3, results_file=path)
    data = path.read_bytes()
    heap = data.index(b"GCOL\x01\x00\x00\x00")
    damaged = tmp_path / "cut.h5"
    damaged.write_bytes(data[: heap + 64])
    run = subprocess.run(
        [sys.executable, "-c", DAMAGED_HEADER, str(damaged)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert run.returncode == 0, run.stderr
    for line in run.stdout.splitlines():
        outcome, named, seconds = line.split()
        assert (outcome, named) == ("error", "True") and float(seconds) < 5, run.stdout


def damage(path, change) -> None:
    with h5py.File(path, "r+") as file:
        change(file)


def test_record_times_that_are_not_finite_or_decrease_end_the_readable_records(tmp_path):
    # Regression (fuzz suite): a NaN or a decreasing time was read as a record like any other.
    path = tmp_path / "r.h5"
    fm.simulate(pendulum(), 0.01, 1e-3, results_file=path)
    good = fm.read_results(path)

    def nan_at_4(file):
        file["time"][4] = np.nan

    damage(path, nan_at_4)
    result = fm.read_results(path)
    assert len(result) == 4 and isinstance(result.error, fm.ResultsFileError)
    assert "4 of its 11 records" in str(result.error) and "record 4 has the time nan" in str(
        result.error
    )
    assert_same_records(good, result, 4)

    def back_in_time(file):
        file["time"][4] = file["time"][2]

    damage(path, back_in_time)
    result = fm.read_results(path)
    assert len(result) == 4 and "before the one of record 3" in str(result.error)


def test_damaged_sizes_and_shapes_of_datasets_are_read_as_damage(tmp_path):
    # Regression (fuzz suite): a record dataset replaced by a scalar raised IndexError; a
    # text field declared of 1 TiB made the reader allocate it (MemoryError); a record count
    # and dataset sizes beyond what the file holds were read as zeros.
    path = tmp_path / "r.h5"
    fm.simulate(pendulum(), 0.01, 1e-3, results_file=path)

    def scalar_velocities(file):
        del file["velocities"]
        file["velocities"] = 2.5

    damage(path, scalar_velocities)
    result = fm.read_results(path)
    assert len(result) == 0 and "0 of its 11 records" in str(result.error)

    path = tmp_path / "s.h5"
    fm.simulate(pendulum(), 0.01, 1e-3, results_file=path)

    def huge(file):
        del file["statistics"]
        file.create_dataset("statistics", shape=(2**20, 2**20), dtype="u1", chunks=(64, 64))
        del file["time"]
        file.create_dataset("time", shape=(2**40,), dtype="f8", chunks=(1024,))
        file["records"][0] = 2**40

    damage(path, huge)
    result = fm.read_results(path)
    assert result.statistics == {} and isinstance(result.error, fm.ResultsFileError)
    assert len(result) <= path.stat().st_size // 8


@pytest.mark.parametrize(
    "name, match",
    [("r\x00.h5", "NUL character"), ("r" * 300 + ".h5", "name too long")],
)
def test_a_results_path_the_system_refuses_is_a_results_file_error(name, match, tmp_path):
    # Regression (fuzz suite): a NUL raised ValueError and a long name OSError from pathlib.
    with pytest.raises(fm.ResultsFileError, match=match):
        fm.simulate(pendulum(), 0.01, 1e-3, results_file=f"{tmp_path}/{name}")
    assert list(tmp_path.iterdir()) == []


# Bodies stored once per distinct content ---------------------------------------------------------
def _three_links():
    """A chain of three beam links: the first two of the same content (one a deep copy, not
    the same object), the third longer."""
    import copy

    from flexmbd.examples import _beam_link

    system = fm.System(gravity=(0, -9.81, 0))
    short = _beam_link(1.0, 4, 0)
    links = [
        system.add_flexible_body(data, position=(x, 0, 0), name=f"link {k}")
        for k, (data, x) in enumerate([(short, 0.0), (copy.deepcopy(short), 1.0)])
    ]
    links.append(system.add_flexible_body(_beam_link(1.5, 4, 0), position=(2, 0, 0), name="long"))
    previous = system.add_marker(system.ground)
    for k, link in enumerate(links):
        system.add_revolute_joint(previous, system.add_node_marker(link, 1), name=f"hinge {k}")
        previous = system.add_node_marker(link, 5)
    return system


def _copy_per_body(path) -> None:
    """Rewrites the ``flexible`` group of a results file in the layout written before bodies
    were shared: an independent copy of the body data under every body index."""
    with h5py.File(path, "r+") as file:
        group = file["flexible"]
        for name in list(group):
            group.copy(group[name], group, name=f"{name}-copy")
            del group[name]
            group.move(f"{name}-copy", name)


def test_bodies_of_the_same_content_are_stored_once(tmp_path):
    from test_body_file import assert_identical

    system = _three_links()
    model = system.compile()
    path = tmp_path / "chain.h5"
    result = fm.simulate(model, 0.005, 1e-3, results_file=path)
    with h5py.File(path, "r") as file:
        groups = [file["flexible"][str(index)] for index in sorted(model.flexible_bodies)]
        assert groups[0].id == groups[1].id  # one group, two names (HDF5 hard links)
        assert groups[0].id != groups[2].id
    shared = tmp_path / "shared.h5"
    shared.write_bytes(path.read_bytes())
    _copy_per_body(path)
    assert shared.stat().st_size < path.stat().st_size
    for file in (shared, path):
        back = fm.read_results(file)
        assert_same_records(result, back)
        assert sorted(back.flexible) == sorted(model.flexible_bodies)
        for index, data in model.flexible_bodies.items():
            assert_identical(back.flexible[index], data, f"body {index}")
        np.testing.assert_array_equal(
            back.node_positions("link 1"), result.node_positions("link 1")
        )
    # Read once, the shared body is one object, as it is in the model it came from.
    back = fm.read_results(shared)
    first, second, third = (back.flexible[i] for i in sorted(back.flexible))
    assert first is second and third is not first


def test_large_body_arrays_are_compressed_in_results_files(tmp_path):
    from flexmbd.fe import Material, build_body, shapes

    mesh = shapes.box((1.0, 0.1, 0.1), (12, 3, 3), "tet4")
    # Clamped at x0 (reference 'none' leaves its frame unheld, refused before a run).
    data = build_body(
        mesh.nodes,
        mesh.elements,
        Material(7e10, 0.3, 2700.0),
        node_sets=mesh.node_sets,
        reference="clamped",
        reference_nodes="x0",
    )
    system = fm.System()
    system.add_flexible_body(data, name="bar")
    system.add_flexible_body(data, position=(0, 1, 0), name="twin")
    path = tmp_path / "bar.h5"
    fm.simulate(system, 2e-3, 1e-3, results_file=path)
    with h5py.File(path, "r") as file:
        stiffness = file["flexible"]["1"]["stiffness"]["data"]
        assert stiffness.nbytes >= 64 * 1024 and stiffness.compression == "gzip"
        assert stiffness.id.get_storage_size() < stiffness.nbytes


def test_a_path_that_is_no_path_and_a_bool_item_are_named():
    # Regression: read_results(None) was a bare TypeError of pathlib; result.position(True)
    # was body 1; a NaN given to a state's with_* said only "expected 3 finite values".
    for path in (None, 3):
        with pytest.raises(fm.ArgumentTypeError, match="path: a results file's path"):
            fm.read_results(path)
        with pytest.raises(fm.ArgumentTypeError, match="path: a results file's path"):
            read_results_metadata(path)
    system = pendulum()
    result = fm.simulate(system, 0.01, 1e-3)
    with pytest.raises(fm.UnknownItemError, match="got True"):
        result.position(True)
    # A float, or another kind's id: the error names it (its item was None).
    body = system.add_rigid_body(1.0, (1, 1, 1))
    for wrong, ask in ((1.0, result.position), (body, result.sensor)):
        with pytest.raises(fm.UnknownItemError) as error:
            ask(wrong)
        assert error.value.item == str(wrong)
    with pytest.raises(fm.InvalidParameterError, match="entry 1 is nan"):
        result.state().with_position("mass", [1.0, np.nan, 0.0])


def test_a_failed_run_that_kept_its_records_in_the_file_says_up_to_when(tmp_path, caplog):
    # Kept only in the file, a failed run's records had all gone to it: `flexmbd run` said
    # "62 records up to the start kept" and the log "t = 0 .. 0 s" for records up to 0.61 s.
    from flexmbd.cli import _kept
    from flexmbd.results_file import read_results_metadata

    system = fm.System()
    body = system.add_point_mass(1.0, name="mass")

    def force(t, q, qd):
        time.sleep(1e-4)  # (deliveries to the file on the way)
        if t > 0.3:
            raise ZeroDivisionError("user bug")
        return np.array([1.0, 0.0, 0.0])

    system.add_callback_force([body], force, name="user")
    path = tmp_path / "run.h5"
    with caplog.at_level("INFO", logger="flexmbd.simulation"):
        with pytest.raises(fm.CallbackError) as error:
            fm.simulate(system, 1.0, 0.01, results_file=path, keep_in_memory=False)
    written = fm.read_results(path)
    end = float(written.time[-1])
    assert len(written) > 1 and read_results_metadata(path)["last_time"] == end
    where, count, last = _kept(error.value)
    assert (where, count, last) == (path, len(written), f"t = {end:.6g} s")
    summary = [r.getMessage() for r in caplog.records if "run stopped" in r.getMessage()]
    assert summary and f".. {end:.6g} s" in summary[0]
