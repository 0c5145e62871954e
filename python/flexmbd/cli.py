"""The ``flexmbd`` command.

* ``flexmbd run [MODEL]``: simulate a model file (YAML, ``docs/model-files.md``) or a built-in
  example (default: the flexible slider-crank), writing a results file (HDF5, written during
  the run), a plot and an animation; Ctrl-C stops cleanly and keeps what was computed.
* ``flexmbd preprocess MESH -o BODY.h5``: a deformable-body file from a mesh
  (``docs/preprocessor.md``).
* ``flexmbd info FILE``: summarize a model, body, results, mesh or Nastran OP2 file (or a
  built-in example).
* ``flexmbd plot RESULTS`` and ``flexmbd animate RESULTS``: figures, ParaView series and
  rendered animations from a results file (``docs/plots-and-animations.md``).
* ``flexmbd examples``: the built-in examples; ``flexmbd schema``: the model file schema.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import sys
import time
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from . import __version__, _boundary
from ._checks import duration_argument, time_argument
from .errors import (
    FlexmbdError,
    InitialCorrectionWarning,
    InvalidParameterError,
    ResultsFileError,
    SimulationInterrupted,
    StepSizeWarning,
)
from .progress import SimulationProgress, status
from .study.command import add_sweep_parser, sweep


def _solver(text: str | None, default: Any) -> Any:
    """The solver named by ``--solver``: "generalized-alpha" (the model's settings of it, such
    as its spectral radius, when it has them: they were replaced by the defaults), or
    METHOD:STRATEGY[:FORMULATION] for an explicit solver, e.g. "dopri5:partitioning:embedding"."""
    if text is None:
        return default
    if text == "generalized-alpha":
        if isinstance(default, _boundary.GeneralizedAlpha):
            return default
        return _boundary.GeneralizedAlpha()
    parts = text.split(":")
    if not 2 <= len(parts) <= 3:
        raise argparse.ArgumentTypeError(
            f"--solver {text!r}: expected generalized-alpha or METHOD:STRATEGY[:FORMULATION]"
        )
    default = "joint-space" if parts[1] == "joint-coordinates" else "augmented"
    formulation = parts[2] if len(parts) == 3 else default
    return _boundary.ExplicitSolver(parts[0], parts[1], formulation=formulation)


def _every(text: str) -> int:
    """A positive whole number of records (``--vtu-every``)."""
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive whole number, got {text!r}")
    return value


def _whole(text: str) -> int:
    """A whole number, 0 or more (``--settle``)."""
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a whole number (0 or more), got {text!r}")
    return value


def _times(text: str) -> tuple[float, float]:
    """A time window START:END in s (``--vtu-times``); an empty side is open."""
    parts = text.split(":")
    try:
        if len(parts) != 2:
            raise ValueError
        start = float(parts[0]) if parts[0].strip() else -math.inf
        end = float(parts[1]) if parts[1].strip() else math.inf
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected START:END in s, got {text!r}") from None
    if not start <= end:
        raise argparse.ArgumentTypeError(f"START must not be after END, got {text!r}")
    return start, end


def _write_paraview(
    result: Any, directory: Path, name: str, every: int, times: Any, **options: Any
) -> Path:
    """Writes the ParaView series of `result` after saying what is being written (the one
    place where the command line writes VTU files)."""
    from .animation import LARGE_VTU_SERIES, vtu_series_size, write_vtu_series

    # The series is named after the results file, without its leading dots: a hidden
    # results file (-o .run.h5) made a hidden series name, refused after the whole run.
    name = name.lstrip(".") or "result"
    files, size = vtu_series_size(result, every, times=times)
    print(f"  writing {files} VTU files (~{size / 1e6:.3g} MB) to {directory}", flush=True)
    if size > LARGE_VTU_SERIES:
        print(
            "  (--vtu-every N, --vtu-times A:B or --no-vtu write less; the model file's "
            "paraview section sets them too)",
            flush=True,
        )
    return write_vtu_series(result, directory, every, name=name, times=times, **options)


@dataclass
class _Job:
    """What ``run`` simulates: a built-in example or a model file."""

    name: str
    description: str
    system: Any
    end_time: float
    step_size: float
    output_interval: float | None
    solver: Any
    check: Any = None
    source: str = ""
    plots: list[str] | None = None
    outputs: Any = None
    start_time: float = 0.0
    start: str = "given"
    #: The stem of the output files' names (never a path).
    stem: str = "results"
    #: The outputs of a model file (:class:`flexmbd.model_file.building.Output`), for units.
    output_specs: list[Any] | None = None
    #: The model file's ParaView series settings (model_file.ParaViewOutput); None: defaults.
    paraview: Any = None


def _job(model: str) -> _Job:
    from .examples import EXAMPLES

    if model in EXAMPLES:
        example = EXAMPLES[model]()
        return _Job(
            example.name,
            example.description,
            example.system,
            example.end_time,
            example.step_size,
            example.output_interval,
            example.solver,
            example.check,
            source=f"built-in example {model!r}",
            stem=example.name,
        )
    path = Path(model)
    if path.suffix.lower() not in (".yaml", ".yml"):
        known = ", ".join(sorted(EXAMPLES))
        raise FlexmbdError(
            f"{model!r} is neither a model file (.yaml, .yml) nor a built-in example ({known})",
            item=model,
        )
    from .model_file import load_model

    loaded = load_model(path)
    return _Job(
        loaded.name or path.stem,
        loaded.description or f"model file {path}",
        loaded.system,
        loaded.end_time,
        loaded.step_size,
        loaded.output_interval,
        loaded.solver,
        source=str(path),
        plots=list(getattr(loaded, "plots", None) or []) or None,
        outputs=loaded.output_values,
        start_time=loaded.start_time,
        start=loaded.start,
        stem=_model_stem(loaded.file_stem),
        output_specs=list(loaded.outputs),
        paraview=loaded.paraview,
    )


def _model_stem(stem: str) -> str:
    """The stem of a model file's output files: its file stem, with ``_model`` appended when
    that is the name of a built-in example (whose files ``flexmbd run NAME`` writes)."""
    from .examples import EXAMPLES

    return f"{stem}_model" if stem in EXAMPLES else stem


def _plot_failed_run(results: Path, plot: Path | None, quantities: Any) -> None:
    """The plot of a failed run's records (to see how it got there), as a finished run's;
    a plot that cannot be made is said, the run's failure stays the exit status."""
    from .plotting import plot_result
    from .results_file import read_results

    try:
        written = plot_result(
            read_results(results), plot or results.with_suffix(".png"), quantities=quantities
        )
    except (FlexmbdError, OSError, ValueError) as error:
        print(f"  no plot of the records: {error}", file=sys.stderr)
        return
    print(f"  plot of the records: {', '.join(str(p) for p in written)}", file=sys.stderr)


def _kept(error: FlexmbdError) -> tuple[Path, int, str] | None:
    """Where a stopped run's records are, how many, and up to when (from its file); None for
    a run refused before it wrote any (the file of an earlier run at the same path, if any,
    was not touched: its records are not this run's)."""
    from .results_file import read_results_metadata

    kept = getattr(error, "result", None)
    where = getattr(kept, "file", None)
    if where is None:
        return None
    try:
        header = read_results_metadata(where)
        count, end = int(header["records"]), header["last_time"]
    except (FlexmbdError, OSError):
        count, end = 0, None
    # (the records of a run that kept them only in the file: the file's last time, not the
    # result's, which held none after a failure and said "up to the start")
    if end is None and kept is not None and len(kept):
        end = float(kept.time[-1])
    last = f"t = {end:.6g} s" if end is not None and count else "the start"
    return Path(where), count, last


def _read_back(result: Any) -> Any:
    """The whole run from its results file, with the statistics and events of the run."""
    from .results_file import read_results

    full = read_results(result.file)
    full.statistics, full.events = result.statistics, result.events
    return full


def _print_summary(result: Any, elapsed: float) -> None:
    stats = result.statistics
    if stats.get("function_evaluations"):
        work = f"{stats['function_evaluations']} function evaluations"
        if stats.get("reduced_system_size"):
            work += f", acceleration system of {stats['reduced_system_size']} unknowns"
    else:
        work = (
            f"{stats['newton_iterations'] / max(stats['steps'], 1):.2f} Newton iterations per "
            f"step, {stats['factorizations']} factorizations"
        )
    print(f"  done in {elapsed:.3f} s: {stats['steps']} steps, {work}")
    for event in result.events[:10]:
        print(f"  event at t = {event['time']:.6g} s ({event['kind']}): {event['message']}")
    if len(result.events) > 10:
        print(f"  ... {len(result.events) - 10} more events")
    if len(result):
        energy = result.total_energy
        print(f"  largest constraint violation {result.constraint_violation.max():.2e} m or rad")
        print(f"  total energy {energy[0]:.6f} J -> {energy[-1]:.6f} J")


def _print_outputs(outputs: dict[str, Any], result: Any, specs: list[Any] | None = None) -> None:
    """Each output of a model file summed up in one line, in SI units, by the kind of its
    quantity (:func:`flexmbd.quantities.summarize`): positions by where they went, vectors by
    their largest magnitude, energies by their extremes, ..."""
    import numpy as np

    from .quantities import OUTPUT_UNITS, SENSOR_UNITS, summarize

    times = result.time
    kinds = {spec.label: spec for spec in specs or []}
    sensors = {s["name"]: s.get("quantity") for s in result.layout["sensors"]}
    for label, values in outputs.items():
        values = np.asarray(values, dtype=float)
        if values.size == 0 or not len(times):
            continue
        spec = kinds.get(label)
        if spec is not None and spec.kind == "sensor":
            quantity = str(sensors.get(spec.item, ""))
            unit = SENSOR_UNITS.get(quantity, "")
            quantity = quantity.replace(" ", "_")
        else:
            quantity = str(getattr(spec, "quantity", "") or "")
            unit = OUTPUT_UNITS.get(quantity, "")
        print(f"  {label}: {summarize(values, times, quantity, unit)}")


def _stop_on_sigterm() -> None:
    """SIGTERM (a batch system's time limit, ``kill``) stops a run like Ctrl-C: cleanly, with
    the records kept and the results file marked interrupted."""
    import signal

    def interrupt(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt(f"signal {signum}")

    if hasattr(signal, "SIGTERM"):
        signal.signal(signal.SIGTERM, interrupt)


#: Suffixes of results files (HDF5) that the commands write and read.
RESULTS_SUFFIXES = (".h5", ".hdf5")


def _checked_outputs(args: argparse.Namespace, results: Path) -> str | None:
    """Why the output files of `run` cannot be written, checked before the run (None: they
    can): the results file's folder, the plot's and the animation's formats."""
    from .plotting import IMAGE_SUFFIXES

    if results.is_dir():
        return f"{results} is a folder; give a results file name such as run.h5 with -o"
    if results.suffix.lower() not in RESULTS_SUFFIXES:
        return (
            f"-o {results}: the results file is HDF5, its name ends in .h5 (a table of the "
            "results: flexmbd.read_results(...).to_dataframe().to_csv(...))"
        )
    if not results.parent.is_dir():
        return f"cannot write {results}: its folder {results.parent} does not exist"
    if args.plot and not args.no_plot and Path(args.plot).suffix.lower() not in IMAGE_SUFFIXES:
        known = ", ".join(sorted(IMAGE_SUFFIXES))
        return f"unknown plot format {Path(args.plot).suffix!r} of {args.plot!r}; use {known}"
    if args.animation and not args.no_animation:
        if Path(args.animation).suffix.lower() not in (".gif", ".png"):
            return f"unknown animation format of {args.animation!r}; use .gif or .png"
    return None


def _run(args: argparse.Namespace) -> int:
    try:
        job = _job(args.model)
        solver = _solver(args.solver, job.solver)
    except (argparse.ArgumentTypeError, FlexmbdError, OSError) as error:
        print(f"flexmbd run: {error}", file=sys.stderr)
        return 2
    end = args.end if args.end is not None else job.end_time
    step = args.step if args.step is not None else job.step_size
    interval = args.output_interval if args.output_interval is not None else job.output_interval
    results = Path(args.output) if args.output else Path(f"{job.stem}.h5")
    problem = _checked_outputs(args, results)
    start_time = job.start_time or 0.0
    if problem is None and not end > start_time:
        # (--end 0 ran no step and said done; --end -1 failed as a run, not as a usage error)
        problem = f"--end {end:g} s must be after the start time {start_time:g} s"
    if problem is not None:
        print(f"flexmbd run: {problem}", file=sys.stderr)
        return 2
    print(f"flexmbd {__version__}: {job.description}")
    try:
        model = job.system.compile()
    except FlexmbdError as error:
        print(f"flexmbd run: {error}", file=sys.stderr)
        return 2
    print(f"  {model!r}")
    print(f"  simulating to t = {end:g} s with step {step:g} s ({solver!r})")
    sys.stdout.flush()  # before the progress bar on stderr
    bar = None if args.quiet else SimulationProgress(label="  simulating")
    _stop_on_sigterm()
    from ._boundary import solver_settings

    metadata = {
        "source": job.source,
        "name": job.name,
        "start_time": job.start_time,
        "start": args.start or job.start,
        "end_time": end,
        "step_size": step,
        "output_interval": interval,
        "solver": solver_settings(solver),
    }
    from .simulation import simulate

    start = time.perf_counter()
    try:
        with warnings.catch_warnings():
            # The events and warnings are logged (printed as they come) and the events listed
            # below; no Python warning on top of them.
            warnings.simplefilter("ignore", InitialCorrectionWarning)
            warnings.simplefilter("ignore", StepSizeWarning)
            result = simulate(
                model,
                end,
                step,
                start_time=job.start_time,
                initial_state=args.start or job.start,
                initial_conditions="strict" if args.strict else "correct",
                output_interval=interval,
                solver=solver,
                progress=bar,
                results_file=results,
                metadata=metadata,
                keep_in_memory=False,
                protect=(job.source,) if Path(job.source).is_file() else (),
            )
    except SimulationInterrupted as error:
        kept = _kept(error)
        if kept is not None:
            where, count, last = kept
            print(f"  interrupted: {count} records up to {last} kept in {where}", file=sys.stderr)
        return 130
    except ResultsFileError as error:
        print(f"  failed: {error}", file=sys.stderr)
        return 1
    except FlexmbdError as error:
        kept = _kept(error)
        print(f"  failed: {error}", file=sys.stderr)
        if kept is not None:
            where, count, last = kept
            print(f"  {count} records up to {last} kept in {where}", file=sys.stderr)
            if count >= 2 and not args.no_plot:
                _plot_failed_run(where, Path(args.plot) if args.plot else None, job.plots)
        return 1
    # The records were kept only in the file (memory flat on any run length): read them.
    with status("  reading the results", enabled=not args.quiet):
        result = _read_back(result)
    _print_summary(result, time.perf_counter() - start)
    if job.check is not None:
        for name, value in job.check(result).items():
            print(f"  {name}: {value:.2e}")
    if job.outputs is not None:
        _print_outputs(job.outputs(result), result, job.output_specs)
    print(f"  results: {results}")
    if not args.no_plot:
        from .plotting import plot_result

        plot = Path(args.plot) if args.plot else results.with_suffix(".png")
        with status(f"  plotting {plot}", enabled=not args.quiet):
            written = plot_result(result, plot, quantities=job.plots)
        print(f"  plot: {', '.join(str(p) for p in written)}", flush=True)
        _print_notes(result, job.plots)
    if not args.no_animation:
        from .animation import render_animation

        movie = Path(args.animation) if args.animation else results.with_suffix(".gif")
        written = render_animation(result, movie, progress=not args.quiet)
        # (a .png animation is frames NAME_0000.png ...: it said "animation: x.png")
        print(f"  animation: {_written_frames(movie, written)}", flush=True)
    paraview = job.paraview
    explicit = args.vtu_every is not None or args.vtu_times is not None
    if result.flexible and not args.no_vtu and (paraview is None or paraview.write or explicit):
        every = args.vtu_every or (paraview.every if paraview else 1)
        times = args.vtu_times or (paraview.times if paraview else None)
        directory = results.with_name(f"{results.stem}_vtu")
        try:
            pvd = _write_paraview(
                result, directory, results.stem, every, times, progress=not args.quiet
            )
        except FlexmbdError as error:
            print(f"flexmbd run: ParaView series: {error}", file=sys.stderr)
            return 2
        print(f"  ParaView series: {pvd}")
    return 0


def _info(args: argparse.Namespace) -> int:
    from .examples import EXAMPLES

    target = args.file
    try:
        if Path(target).is_dir():
            from .study.command import info_study

            return info_study(Path(target))
        if target in EXAMPLES or Path(target).suffix.lower() in (".yaml", ".yml"):
            job = _job(target)
            model = job.system.compile()
            print(f"{target}: {job.description}")
            print(f"  {model!r}")
            _print_layout(model.describe())
            interval = job.output_interval
            print(
                f"  simulation: to t = {job.end_time:g} s, step {job.step_size:g} s, output "
                f"{'every step' if interval is None else f'every {interval:g} s'}, "
                f"{job.solver!r}"
            )
            return 0
        path = Path(target)
        if not path.exists():
            print(f"flexmbd info: no such file or example: {target}", file=sys.stderr)
            return 2
        from .fe.mesh_io import MESH_FORMATS

        if path.suffix.lower() in MESH_FORMATS:
            return _info_mesh(path)
        if path.suffix.lower() == ".op2":
            from .fe.op2 import read_op2

            print(read_op2(path).summary())
            return 0
        if path.suffix.lower() in NASTRAN_SUFFIXES:
            return _info_nastran(path)
        if path.suffix.lower() == ".sid":
            from .fe.sid import read_sid

            _print_body(read_sid(path), f"{path}: SID file (a modal body),")
            return 0
        import h5py

        if not h5py.is_hdf5(path):
            print(
                f"flexmbd info: {target}: not a model, body, results, mesh, Nastran, OP2 or SID "
                "file",
                file=sys.stderr,
            )
            return 2
        try:
            with h5py.File(path, "r", swmr=True) as file:
                kind = file.attrs.get("format")
        except OSError as error:
            print(
                f"flexmbd info: {target}: cannot open the HDF5 file (damaged or truncated: "
                f"{error})",
                file=sys.stderr,
            )
            return 2
        if kind == "flexmbd-results":
            return _info_results(path)
        if kind == "flexmbd-body":
            return _info_body(path)
        shown = "it has none" if kind is None else f"it is {kind!r}"
        print(
            f"flexmbd info: {target}: an HDF5 file, but not a flexmbd body or results file "
            f"(their 'format' attribute is 'flexmbd-body' or 'flexmbd-results'; {shown})",
            file=sys.stderr,
        )
        return 2
    except BrokenPipeError:
        raise
    except (FlexmbdError, OSError) as error:
        print(f"flexmbd info: {error}", file=sys.stderr)
        return 2


def _print_layout(layout: dict[str, Any]) -> None:
    bodies = [b for b in layout["bodies"] if b["kind"] != "ground"]
    print(
        f"  {len(bodies)} bodies, {len(layout['joints'])} joints, {len(layout['forces'])} "
        f"forces, {len(layout['sensors'])} sensors; {layout['coordinate_count']} coordinates, "
        f"{layout['constraint_count']} constraint equations"
    )
    for body in bodies:
        print(
            f"    body {body['name']!r}: {body['kind']}, {body['mass']:.6g} kg, "
            f"{body['count']} coordinates"
        )
    for joint in layout["joints"]:
        print(f"    joint {joint['name']!r}: {joint['type']} ({len(joint['equations'])} equations)")


def _info_results(path: Path) -> int:
    from .results_file import read_results_metadata

    header = read_results_metadata(path)
    status = header["status"] or {}
    print(f"{path}: flexmbd results file (version {header['version']}, {header['writer']})")
    source = header["metadata"].get("source")
    if source:
        print(f"  model: {source}")
    state = status.get("state", "?")
    if state == "running":
        state = "running, or stopped without closing the file (killed)"
    elif status.get("error"):
        state += f" ({status['error']}: {status.get('message', '')})"
    print(f"  status: {state}")
    units = header.get("units") or {}
    if units:
        print("  units: " + ", ".join(f"{k} {v}" for k, v in units.items()))
    _print_layout(header["layout"])
    count = header["records"]
    if count:
        from .results_file import read_results

        results = read_results(path)
        times = results.time
        if len(times):
            print(f"  {count} records, t = {times[0]:g} .. {times[-1]:g} s")
        if isinstance(results.error, ResultsFileError):
            print(f"  damaged: {results.error}")
    else:
        print("  no records")
    stats = header["statistics"]
    if stats:
        shown = ", ".join(
            f"{k} {v:g}" if isinstance(v, float) else f"{k} {v}"
            for k, v in stats.items()
            if not (isinstance(v, float) and math.isnan(v))
        )
        print(f"  statistics: {shown}")
    if header["events"]:
        print(f"  {len(header['events'])} events, first: {header['events'][0]['message']}")
    if header["flexible"]:
        print(f"  deformable body data of bodies {header['flexible']}")
    return 0


#: Suffixes of Nastran bulk data files (`flexmbd info`).
NASTRAN_SUFFIXES = (".bdf", ".nas", ".dat", ".pch", ".blk")


def _info_nastran(path: Path) -> int:
    """A Nastran deck: its mesh and node sets (as a mesh file), material, sections, DMIG
    matrices."""
    import numpy as np

    from .fe.nastran import read_nastran

    deck = read_nastran(path)
    _print_mesh(path, "Nastran bulk data", deck.mesh)
    if deck.element_properties:
        material = deck.material()
        print(
            f"  material: E {material.young_modulus:.6g}, nu {material.poisson_ratio:.6g}, "
            f"rho {material.density:.6g} (deck units, WTMASS applied)"
        )
    section, orientation = deck.section()
    if section is not None:
        print(
            f"  beam section: A {section.area:.6g}, Iy {section.iy:.6g}, Iz {section.iz:.6g}, "
            f"J {section.torsion_constant:.6g}; orientation "
            f"({', '.join(f'{v:.6g}' for v in orientation)})"
        )
        for what, values in (("offsets", deck.beam_offsets), ("pin flags", deck.beam_releases)):
            if values is not None:
                count = int(np.count_nonzero(np.any(values.reshape(len(values), -1), axis=1)))
                print(f"  beams with {what}: {count} of {len(values)}")
    shell = deck.shell()
    if shell is not None:
        print(f"  shell thickness {shell.thickness:.6g}")
    for name, matrix in deck.matrices.items():
        print(f"  DMIG {name}: {len(matrix.values)} entries (form {matrix.form})")
    return 0


def _info_mesh(path: Path) -> int:
    """A mesh file: its nodes (ids, bounding box), elements by type, and its groups (node
    sets; for each, the elements whose nodes all belong to it: an element set)."""
    from .fe.mesh_io import MESH_FORMATS, read_mesh

    _print_mesh(path, f"{MESH_FORMATS[path.suffix.lower()]} mesh", read_mesh(path))
    return 0


def _print_mesh(path: Path, kind: str, mesh: Any) -> None:
    """Nodes (ids, bounding box), elements by type and groups of a mesh (see `_info_mesh`)."""
    import numpy as np

    elements = ", ".join(f"{len(c)} {t}" for t, c in mesh.elements.items()) or "no elements"
    print(f"{path}: {kind}, {mesh.node_count} nodes, {elements}")
    if mesh.node_count:
        ids = np.asarray(mesh.node_ids)
        low, high = mesh.nodes.min(axis=0), mesh.nodes.max(axis=0)
        box = ", ".join(
            f"{a} {lo:.6g} .. {hi:.6g}" for a, lo, hi in zip("xyz", low, high, strict=True)
        )
        print(f"  node ids {ids.min()} .. {ids.max()}; bounding box {box} (mesh units)")
    if not mesh.node_sets:
        print("  no groups (node or element sets)")
    for name, members in mesh.node_sets.items():
        inside = np.zeros(mesh.node_count, dtype=bool)
        inside[np.asarray(members, dtype=np.int64)] = True
        counts = [
            f"{int(np.all(inside[c], axis=1).sum())} {t}"
            for t, c in mesh.elements.items()
            if len(c) and np.any(np.all(inside[c], axis=1))
        ]
        held = (
            f"; elements: {', '.join(counts)}"
            if counts
            else "; no elements (a face, edge or point set)"
        )
        print(f"  group {name!r}: {len(members)} nodes{held}")


def _info_body(path: Path) -> int:
    from .fe.body_file import load_body

    body = load_body(path)
    _print_body(body, f"{path}: flexmbd body file,")
    if body.node_sets:
        print(f"  node sets: {', '.join(sorted(body.node_sets))}")
    return 0


def _print_body(body: Any, title: str, more: str = "") -> None:
    """Nodes, elements, mass, elastic coordinates and the first frequencies of a body."""
    elements = ", ".join(f"{len(c)} {kind}" for kind, c in body.elements.items())
    print(f"{title} {body.node_count} nodes, {elements or 'no elements'}")
    print(
        f"  mass {body.invariants.mass:.6g} kg, {body.elastic_coordinate_count} elastic "
        f"coordinates ({body.mode_kind or 'nodal'}){more}"
    )
    if body.frequencies is not None:
        shown = ", ".join(f"{f:.4g}" for f in body.frequencies[:8])
        tail = " ..." if len(body.frequencies) > 8 else ""
        print(f"  frequencies (Hz): {shown}{tail}")
    import numpy as np

    reference = body.reference
    weights = reference.interface_weights or []
    for k, (members, w) in enumerate(zip(reference.interfaces or [], weights, strict=False)):
        centroid = np.asarray(w) @ body.nodes[np.asarray(members, dtype=np.int64)]
        at = ", ".join(f"{v:.6g}" for v in centroid)
        kind = reference.interface_kind
        print(f"  interface {k} ({kind}): {len(members)} nodes, weighted centroid ({at}) m")
    record = body.point_masses
    if record is not None and len(record["nodes"]):
        count = len(record["nodes"])
        turning = int(
            np.sum(
                np.any(record["inertia"] != 0, axis=(1, 2)) | np.any(record["offset"] != 0, axis=1)
            )
        )
        print(
            f"  point masses: {count} ({float(np.sum(record['mass'])):.6g} kg), "
            f"{turning} with a rotary inertia or an offset; at node ids "
            + ", ".join(str(int(body.node_ids[n])) for n in record["nodes"][:8])
            + (" ..." if count > 8 else "")
        )


def _plot(args: argparse.Namespace) -> int:
    from .plotting import plot_result
    from .results_file import read_results

    try:
        if Path(args.results).is_dir():
            from .study.command import plot_study

            if len(args.quantity) != 1:
                raise InvalidParameterError("a study folder: give one OUTPUT to plot")
            written = plot_study(Path(args.results), args.quantity[0], args.against, args.output)
        else:
            if args.against is not None:
                raise InvalidParameterError("--against is for study folders")
            result = read_results(args.results)
            output = Path(args.output) if args.output else Path(args.results).with_suffix(".png")
            _check_folder(output)
            written = plot_result(result, output, quantities=args.quantity or None)
            _print_notes(result, args.quantity)
    except BrokenPipeError:
        raise
    except (FlexmbdError, OSError) as error:
        print(f"flexmbd plot: {error}", file=sys.stderr)
        return 2
    for path in written:
        print(f"written: {path}")
    return 0


def _print_notes(result: Any, quantities: Any) -> None:
    """The notes of the plot (:func:`flexmbd.plotting.overview_notes`, or the sampling notes
    for chosen quantities)."""
    from .plotting import overview_notes, sampling_notes

    notes = overview_notes(result) if not quantities else sampling_notes(result)
    for note in notes:
        print(f"  note: {note}")


def _animate(args: argparse.Namespace) -> int:
    from .animation import render_animation
    from .results_file import read_results

    try:
        with status(f"reading {args.results}", enabled=not args.quiet):
            result = read_results(args.results)
        results = Path(args.results)
        options: dict[str, Any] = {}
        if args.scale is not None:
            if not math.isfinite(args.scale):
                # (checked before any file: NaN was refused after 101 frames were written)
                raise InvalidParameterError(f"--scale must be a finite number, got {args.scale}")
            options["scale"] = args.scale
        if args.vtu:
            _check_folder(Path(args.vtu))
        if args.output and not args.no_render:
            _check_folder(Path(args.output))
            if Path(args.output).resolve() == results.resolve():
                # ("[Errno 17] File exists: 'p3.h5'")
                raise InvalidParameterError(
                    f"-o {args.output} is the results file: name the animation (.gif, or .png "
                    "for frames)"
                )
        if args.vtu or not args.no_vtu and result.flexible:
            directory = Path(args.vtu) if args.vtu else results.with_name(f"{results.stem}_vtu")
            every, times = args.vtu_every or 1, args.vtu_times
            pvd = _write_paraview(
                result, directory, results.stem, every, times, progress=not args.quiet, **options
            )
            print(f"written: {pvd}", flush=True)
        if not args.no_render:
            movie = Path(args.output) if args.output else results.with_suffix(".gif")
            if args.frames is not None:
                options["frames"] = args.frames
            written = render_animation(
                result, movie, backend=args.backend, progress=not args.quiet, **options
            )
            print(f"written: {_written_frames(movie, written)}")
    except BrokenPipeError:
        raise
    except (FlexmbdError, OSError) as error:
        print(f"flexmbd animate: {error}", file=sys.stderr)
        return 2
    return 0


def _check_folder(path: Path) -> None:
    """Refuses an output in a folder that does not exist, as `run` does (plot and animate
    created it, and `-o /nonexistent/p.png` a folder at the root)."""
    if not path.parent.is_dir():
        raise InvalidParameterError(f"cannot write {path}: its folder {path.parent} does not exist")


def _written_frames(path: Path, written: Any) -> str:
    """What `render_animation` wrote to `path`: the GIF, or the PNG frames (it said "written:
    run.png" of a sequence run_0000.png ..., and of a folder of frames named like a movie)."""
    files = [Path(f) for f in written] if isinstance(written, list | tuple) else [path]
    text = (
        str(files[0]) if len(files) == 1 else f"{len(files)} frames {files[0]} .. {files[-1].name}"
    )
    if path.is_dir() and path.suffix:
        text += f" (the folder {path}: only .gif and .png name files)"
    return text


def _speeds(text: str) -> Any:
    """--speeds START:STOP:COUNT (rad/s) or a comma-separated list."""
    import numpy as np

    parts = text.split(":")
    try:
        if len(parts) == 3:
            return np.linspace(float(parts[0]), float(parts[1]), int(parts[2]))
        return np.array([float(v) for v in text.split(",")])
    except ValueError:
        raise InvalidParameterError(
            f"--speeds {text!r}: expected START:STOP:COUNT or V1,V2,... (rad/s)"
        ) from None


def _only_angle_driver(system: Any) -> str:
    """The name of the model's angle driver when it has one (`--driver` may then be left
    out); InvalidParameterError naming them otherwise."""
    joints = system.compile().describe()["joints"]
    drivers = [j["name"] for j in joints if j["type"] == "angle driver"]
    if len(drivers) != 1:
        which = f"angle drivers {drivers}" if drivers else "no angle driver"
        raise InvalidParameterError(f"the model has {which}: name the one to turn with --driver")
    print(f"driver: {drivers[0]}")
    return drivers[0]


def _campbell(args: argparse.Namespace) -> int:
    from .campbell import campbell, plot_campbell

    try:
        job = _job(args.model)
        stem = Path(args.output) if args.output else Path(Path(args.model).stem + "_campbell")
        _check_folder(stem)  # (before the speeds are computed: after, they were lost)
        driver = args.driver or _only_angle_driver(job.system)
        diagram = campbell(
            job.system,
            driver,
            _speeds(args.speeds),
            modes=args.modes,
            frame=args.frame,
            progress=True,
        )
        plot_campbell(diagram, stem.with_suffix(".png"), orders=args.orders)
        diagram.to_xarray().to_netcdf(stem.with_suffix(".nc"), engine="scipy")
    except (FlexmbdError, OSError) as error:
        print(f"flexmbd campbell: {error}", file=sys.stderr)
        return 2
    modes = range(diagram.mode_count)
    print(f"frequencies in the {diagram.frame} frame")
    print("speed (rad/s)" + "".join(f"  mode {m + 1:<2d} (Hz)" for m in modes))
    whirl = {"forward": "forward", "backward": "backward", None: "-"}
    print(f"{'whirl':>13s}" + "".join(f"  {whirl[w]:>12s}" for w in diagram.whirl_labels))
    for k, w in enumerate(diagram.speeds):
        print(f"{w:13.4g}" + "".join(f"  {f:12.5g}" for f in diagram.frequencies[k]))
    for c in diagram.critical_speeds(args.orders):
        kind = f", {c['whirl']} whirl" if c["whirl"] else ""
        print(
            f"critical speed: order {c['order']:g} meets mode {c['mode'] + 1}{kind} at "
            f"{c['speed']:.5g} rad/s ({c['frequency']:.5g} Hz)"
        )
    print(f"written: {stem.with_suffix('.png')}, {stem.with_suffix('.nc')}")
    return 0


#: Damping ratios of at most this size are printed as 0 by `flexmbd modes`: round-off of an
#: undamped mode's eigenvalues, about 1e-16 times the largest eigenvalue over the mode's own
#: (the spin-up beam's first pair: +-6e-12); the modal damping users give is 1e-4 or more.
UNDAMPED = 1e-9


def _index(text: str) -> int:
    """A node index of the command line; a typed error for anything else."""
    try:
        return int(text)
    except ValueError:
        raise InvalidParameterError(
            f"--reference-nodes: {text!r} is not a node index (one node set name, or indices)",
            item="--reference-nodes",
        ) from None


def _linearized(system: Any) -> tuple[Any, Any, str]:
    """The modes' linearization of `system` (a flexmbd.System), its compiled model and what
    it is about: the steady rotation, else the static equilibrium, else (a free-flying
    structure, which has neither) the initial configuration at rest with the loads left out
    (`flexmbd.linearize_at_rest`: the free-free modes)."""
    from .analysis import equilibrium, linearize, linearize_at_rest, steady_rotation
    from .errors import FreeMotionError, InvalidModelError

    model = system.compile()
    try:
        return linearize(model, steady_rotation(model)), model, "the steady rotation"
    except InvalidModelError:
        pass
    try:
        state = equilibrium(model)
        about = "the static equilibrium"
        accelerations = state.accelerations if state.accelerations is not None else ()
        if any(a != 0.0 for a in accelerations):
            # (A driver accelerating at t = 0 loads the structure with its inertia: the state
            # is deflected by it, which "static equilibrium" did not say; found by a fault
            # hunt.)
            about = (
                "the equilibrium at t = 0 with the drivers' accelerations (quasi-static: their "
                "inertia loads deflect it)"
            )
        return linearize(model, state), model, about
    except FreeMotionError:
        unloaded = system.without_loads()
        linear = linearize_at_rest(unloaded)
        count = linear.free_motions()
        about = (
            "the initial configuration at rest, loads and gravity left out (free-free: no "
            f"static equilibrium; {count} rigid-body mode{'s' if count != 1 else ''} at 0 Hz)"
        )
        return linear, unloaded.compile(), about


def _start_state(model: Any, start: str, time: float) -> Any:
    """The state `start` ("given", "equilibrium" or "steady-rotation") of `model` at `time`."""
    from .analysis import equilibrium, steady_rotation
    from .state import State

    if start == "equilibrium":
        return equilibrium(model, time)
    if start == "steady-rotation":
        return steady_rotation(model, time)
    return State.of_model(model, time)


def _floquet(args: argparse.Namespace) -> int:
    from .floquet import NEUTRAL, SPECTRAL_RADIUS, floquet
    from .simulation import simulate

    try:
        job = _job(args.model)
        model = job.system.compile()
        period = args.period
        step = period / args.steps
        # The model's start (a model file's `start` and `start_time`, or --start): a rotor
        # starts in its steady rotation, not from rest with its driver at speed.
        start = args.start or job.start
        state = _start_state(model, start, job.start_time or 0.0)
        if args.settle:
            # Onto the periodic motion first: the model's solver over whole periods.
            settled = simulate(
                model,
                state.time + args.settle * period,
                step,
                solver=job.solver,
                output_interval=period,
                initial_state=state,
            )
            state = settled.state(-1)
        analysis = floquet(
            model, state, period, step, progress=not args.quiet, workers=args.workers
        )
    except (FlexmbdError, OSError) as error:
        print(f"flexmbd floquet: {error}", file=sys.stderr)
        return 2
    count = len(analysis.multipliers)
    print(
        f"{job.name}: {count} Floquet multiplier{'s' if count != 1 else ''} over the period "
        f"{period:g} s ({args.steps} steps; start at t = {analysis.state.time:g} s)"
    )
    radius = getattr(analysis.solver, "spectral_radius", None)
    if radius is not None and radius != SPECTRAL_RADIUS:
        print(
            f"(spectral radius {radius:.4g}: the steps leave modes up to |s| h = "
            f"{analysis.stiffest:.3g} unresolved, damped within the period)"
            if not analysis.fallback
            else f"(a run diverged at a spectral radius of {SPECTRAL_RADIUS} or lower: every "
            f"run made again at {radius:.4g})"
        )
    print("   k  multiplier                    |mu|        growth (1/s)  note")
    drifts = analysis.drifts
    for k, (mu, exponent) in enumerate(zip(analysis.multipliers, analysis.exponents, strict=True)):
        note = "drift" if drifts[k] else ("grows" if abs(mu) > 1.0 + analysis.neutral else "")
        print(
            f"{k + 1:4d}  {mu.real:+.6e} {mu.imag:+.6e}i  {abs(mu):.8f}  {exponent.real:+.4e}  "
            f"{note}"
        )
    if analysis.stable:
        print("stable: no multiplier outside the unit circle (the small motions do not grow)")
    else:
        n = analysis.unstable_directions
        print(f"unstable: {n} growing motion{'s' if n != 1 else ''}")
    if analysis.periodicity > 0.0:
        print(f"periodicity: the start state came back within {analysis.periodicity:.2g}")
    if analysis.neutral > NEUTRAL:
        print(
            f"(multipliers within {analysis.neutral:.2g} of the unit circle, the runs' error "
            "shown by the periodicity, are taken as neutral; more steps narrow it)"
        )
    return 0


def _modes(args: argparse.Namespace) -> int:
    import numpy as np

    from .animation import render_animation
    from .state_space import body_shapes, mode_result

    try:
        job = _job(args.model)
        linear, model, about = _linearized(job.system)
        frequencies, damping, shapes = linear.oscillating()
        count = len(frequencies)
        print(f"{job.name}: {count} oscillating mode{'s' if count != 1 else ''} about {about}")
        print("mode  frequency (Hz)  damping ratio  moves most")
        for k in range(min(args.count, len(frequencies))):
            parts = body_shapes(model, shapes[:, k], linear.state)
            share = {
                name: float(sum(np.sum(np.abs(v) ** 2) for v in part.values()))
                for name, part in parts.items()
            }
            most = max(share, key=lambda name: share[name])
            # An undamped mode's ratio is round-off (1e-17, or -0.0): it reads 0.
            ratio = damping[k] if abs(damping[k]) > UNDAMPED else 0.0
            print(f"{k + 1:4d}  {frequencies[k]:14.6g}  {ratio:13.3g}  {most}")
        stem = Path(args.output) if args.output else Path(job.stem)
        for k in args.animate:
            if not 1 <= k <= len(frequencies):
                raise InvalidParameterError(
                    f"--animate {k}: the modes are numbered 1 to {len(frequencies)}",
                    item="--animate",
                )
            result = mode_result(linear, model, k - 1, frames=args.frames)
            movie = stem.with_name(f"{stem.name}_mode{k}.gif")
            render_animation(result, movie, frames=args.frames, progress=True)
            print(f"written: {movie}")
            if result.flexible:
                folder = stem.with_name(f"{stem.name}_mode{k}_vtu")
                print(f"written: {_write_paraview(result, folder, f'mode{k}', 1, None)}")
    except (FlexmbdError, OSError) as error:
        print(f"flexmbd modes: {error}", file=sys.stderr)
        return 2
    return 0


def _view(args: argparse.Namespace) -> int:
    from .viewer import view

    options = {"max_frames": args.max_frames, "scale": args.scale, "color_by": args.color}
    try:
        if Path(args.source).suffix.lower() in RESULTS_SUFFIXES:  # (run -o writes .hdf5 too)
            if args.modes is not None:
                raise InvalidParameterError("--modes is for a model file or built-in example")
            written = view(args.source, args.output, **options)
        elif args.modes is None:
            raise InvalidParameterError(
                f"{args.source!r} is not a results file (.h5, .hdf5): give --modes to view "
                "the mode shapes of a model, or run it (flexmbd run) and view its results file"
            )
        else:
            job = _job(args.source)
            linear, model, _ = _linearized(job.system)
            output = args.output or f"{job.stem}_modes.html"
            written = view(linear, output, model=model, modes=args.modes, **options)
    except BrokenPipeError:
        raise
    except (FlexmbdError, OSError) as error:
        print(f"flexmbd view: {error}", file=sys.stderr)
        return 2
    except ImportError as error:
        print(f"flexmbd view: {error} (pip install flexmbd[view])", file=sys.stderr)
        return 2
    print(f"written: {written} ({written.stat().st_size / 1e6:.1f} MB)")
    return 0


def _schema(args: argparse.Namespace) -> int:
    from .model_file import model_schema

    text = json.dumps(model_schema(), indent=2)
    if args.output:
        Path(args.output).write_text(text + "\n")
        print(f"written: {args.output}")
    else:
        print(text)
    return 0


#: The beam sections of `flexmbd preprocess --section KIND:VALUES`: the values each takes.
SECTION_KINDS = {"circle": 1, "rectangle": 2, "tube": 2, "general": 4}


def _section_argument(text: str) -> Any:
    """A beam section from KIND:VALUES (`SECTION_KINDS`), for argparse."""
    from .fe import Section

    kind, _, values = text.partition(":")
    if kind not in SECTION_KINDS:
        raise argparse.ArgumentTypeError(
            f"{text!r}: the kind must be one of {', '.join(SECTION_KINDS)} (e.g. circle:0.01)"
        )
    try:
        numbers = [float(v) for v in values.split(",")]
    except ValueError:
        numbers = []
    if len(numbers) != SECTION_KINDS[kind]:
        raise argparse.ArgumentTypeError(
            f"{text!r}: {kind} takes {SECTION_KINDS[kind]} comma-separated numbers"
        )
    try:
        if kind == "general":
            return Section(*numbers)
        return getattr(Section, kind)(*numbers)
    except (FlexmbdError, ValueError) as error:
        raise argparse.ArgumentTypeError(f"{text!r}: {error}") from None


def _preprocess(args: argparse.Namespace) -> int:
    from .fe.body_file import is_body_file, save_body
    from .fe.mesh_io import read_mesh
    from .fe.preprocess import Material, body_from_mesh

    options = {
        "mass": args.mass,
        "reference": args.reference,
        "modes": None if args.modes == "none" else args.modes,
        "mode_count": args.count,
        "interfaces": args.interfaces,
        "interface_kind": args.interface_kind,
        "interface_weights": args.interface_weights,
        "precision": args.precision,
        "beam_theory": args.beam_theory,
    }
    if args.section is not None:
        options["section"] = args.section
    if args.section_orientation is not None:
        options["orientation"] = args.section_orientation
    if args.thickness is not None:
        options["shell"] = args.thickness
    if args.orient_shells:
        options["orient_shells"] = True
    output = Path(args.output)
    # The body file's path, checked before the (long) preprocessing.
    problem = None
    if output.is_dir():
        problem = f"{output} is a folder; give a body file name such as body.h5 with -o"
    elif not output.parent.is_dir():
        problem = f"cannot write {output}: its folder {output.parent} does not exist"
    elif output.exists() and output.resolve() == Path(args.mesh).resolve():
        problem = f"{output} is the mesh file; the body file needs another name"
    elif output.exists() and not is_body_file(output):
        problem = f"{output} exists and is not a flexmbd body file: it is not replaced"
    elif not os.access(output.parent, os.W_OK):
        problem = f"cannot write {output}: its folder {output.parent} is not writable"
    if problem is not None:
        print(f"flexmbd preprocess: {problem}", file=sys.stderr)
        return 2
    given = [
        flag
        for flag, value in (
            ("-E", args.young_modulus),
            ("--poisson-ratio", args.poisson_ratio),
            ("--density", args.density),
            ("--section", args.section),
            ("--section-orientation", args.section_orientation),
            ("--thickness", args.thickness),
        )
        if value is not None
    ]
    deck = Path(args.mesh).suffix.lower() in NASTRAN_SUFFIXES
    if args.incompatible_modes:
        given.append("--incompatible-modes")
    if deck and given:
        print(
            f"flexmbd preprocess: {' '.join(given)}: a Nastran deck has its own material, "
            "sections, thickness and element formulations (MAT1, PBAR/PBEAM, PSHELL)",
            file=sys.stderr,
        )
        return 2
    missing = [
        flag
        for flag, value in (
            ("-E", args.young_modulus),
            ("--poisson-ratio", args.poisson_ratio),
            ("--density", args.density),
        )
        if value is None
    ]
    if not deck and missing:
        print(
            "flexmbd preprocess: the material needs -E (Pa), --poisson-ratio and --density "
            f"(kg/m^3); not given: {', '.join(missing)}",
            file=sys.stderr,
        )
        return 2
    timings: dict[str, float] = {}
    start = time.perf_counter()
    try:
        if args.reference_nodes:
            nodes = args.reference_nodes
            # One word is a node set's name unless it is an index ("5" was taken for a set).
            named = len(nodes) == 1 and not nodes[0].lstrip("-").isdigit()
            options["reference_nodes"] = nodes[0] if named else [_index(n) for n in nodes]
        if deck:
            from .fe.nastran import read_nastran

            body = read_nastran(args.mesh).body(timings=timings, **options)
        else:
            material = Material(args.young_modulus, args.poisson_ratio, args.density)
            mesh: Any = args.mesh
            if args.incompatible_modes:
                mesh = read_mesh(args.mesh).with_incompatible_modes()
            body = body_from_mesh(mesh, material, timings=timings, **options)
            if args.incompatible_modes:
                body = body.with_metadata(source=str(args.mesh))
    except (FlexmbdError, ValueError, OSError) as error:
        hint = ""
        if "beam elements need a section" in str(error):
            hint = " (give one with --section, e.g. --section circle:0.01)"
        print(f"flexmbd preprocess: {error}{hint}", file=sys.stderr)
        return 1
    elapsed = time.perf_counter() - start
    _print_body(body, f"flexmbd {__version__}: {args.mesh}:", f", reference {args.reference}")
    print("  " + ", ".join(f"{k} {v:.2f} s" for k, v in timings.items()) + f"; {elapsed:.2f} s")
    try:
        save_body(body, output)
    except (FlexmbdError, OSError) as error:
        print(f"flexmbd preprocess: cannot write {output}: {error}", file=sys.stderr)
        return 1
    print(f"  written to {output}")
    return 0


@contextmanager
def _logging_to_stderr(verbose: int, quiet: bool) -> Iterator[None]:
    """Shows the records of the "flexmbd" loggers on stderr while a command runs: warnings
    (the events that ask for a look), with ``-v`` also the routine events and the run's
    summary (INFO), with ``-vv`` DEBUG; with ``--quiet`` errors only."""
    import logging

    log = logging.getLogger("flexmbd")
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("  [%(levelname)s] %(message)s"))
    level = logging.ERROR if quiet else [logging.WARNING, logging.INFO][min(verbose, 1)]
    if verbose >= 2:
        level = logging.DEBUG
    before = log.level
    log.setLevel(level)
    log.addHandler(handler)
    try:
        yield
    finally:
        log.removeHandler(handler)
        log.setLevel(before)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``flexmbd`` command."""
    shown = warnings.formatwarning
    warnings.formatwarning = _command_line_warning
    try:
        return _main(argv)
    except BrokenPipeError:
        # The reader of the output went away (``flexmbd examples | head``): stop quietly.
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    finally:
        warnings.formatwarning = shown


def _command_line_warning(
    message: Warning | str, category: type[Warning], filename: str, lineno: int, line=None
) -> str:
    """A warning of the command line: its category and message, at the model file's line when
    it points at one (the package's own source lines mean nothing to the user)."""
    where = "" if filename.endswith(".py") else f"{filename}:{lineno}: "
    return f"flexmbd: {where}{category.__name__}: {message}\n"


def _main(argv: list[str] | None) -> int:
    parser = argparse.ArgumentParser(prog="flexmbd", description="Flexible multibody dynamics.")
    parser.add_argument("--version", action="version", version=f"flexmbd {__version__}")
    sub = parser.add_subparsers(dest="command")
    run = sub.add_parser(
        "run",
        help="simulate a model file or a built-in example (default: flexible-slider-crank)",
        description="Simulate a model file (.yaml) or a built-in example; write the results "
        "(HDF5, during the run), a plot, an animation (GIF) and, for deformable bodies, a "
        "ParaView series next to them. Ctrl-C stops and keeps what was computed.",
    )
    run.add_argument(
        "model",
        nargs="?",
        default="flexible-slider-crank",
        help="model file (.yaml) or built-in example (flexmbd examples lists them)",
    )
    run.add_argument("-o", "--output", help="results file (default: NAME.h5)")
    run.add_argument("--end", type=time_argument, help="end time (s)")
    run.add_argument("--step", type=duration_argument, help="step size (s)")
    run.add_argument("--output-interval", type=duration_argument, help="time between records (s)")
    run.add_argument(
        "--start",
        choices=("given", "equilibrium", "steady-rotation"),
        help="the state at the start time (default: the model file's `start`, else given)",
    )
    run.add_argument(
        "--strict",
        action="store_true",
        help="refuse initial positions or velocities that need a correction (default: correct "
        "them and report each joint and body as an event)",
    )
    run.add_argument(
        "--solver",
        help="generalized-alpha (default: the model's settings; with the model's spectral radius "
        "and tolerances when it sets them), or an explicit solver "
        "METHOD:STRATEGY[:FORMULATION] with METHOD rk4, dopri5 or tr-bdf2, STRATEGY integrate-all, "
        "partitioning, projection or joint-coordinates, FORMULATION augmented or embedding "
        "(joint-coordinates: joint-space, coupled or decoupled)",
    )
    run.add_argument("--plot", help="plot file (.png, .svg or .pdf; default: NAME.png)")
    run.add_argument("--animation", help="animation file (.gif; default: NAME.gif)")
    run.add_argument("--no-plot", action="store_true", help="write no plot")
    run.add_argument(
        "--no-animation",
        action="store_true",
        help="render no animation GIF (the ParaView series is written still: --no-vtu)",
    )
    run.add_argument(
        "--no-vtu",
        action="store_true",
        help="write no ParaView series (a .vtu file per record and a .pvd, NAME_vtu/) of the "
        "deformable bodies",
    )
    run.add_argument(
        "--vtu-every",
        type=_every,
        metavar="N",
        help="ParaView series: every N-th record and the last (default: the model file's "
        "paraview.every, else 1)",
    )
    run.add_argument(
        "--vtu-times",
        type=_times,
        metavar="A:B",
        help="ParaView series: only the records from time A to B (s; A or B may be left out; "
        "default: the model file's paraview.times, else all)",
    )
    run.add_argument("-q", "--quiet", action="store_true", help="no progress bars; log errors only")
    run.add_argument(
        "-v", "--verbose", action="count", default=0, help="log every event of the run (-vv: debug)"
    )
    info = sub.add_parser("info", help="summarize a model, body, results or mesh file, or a study")
    info.add_argument(
        "file",
        help="model file (.yaml), body or results file (.h5), mesh file (.msh, .inp, .vtu, "
        ".vtk), Nastran OP2 results (.op2: modes and frequencies), example, or study folder",
    )
    plot = sub.add_parser("plot", help="plot a results file, or an output of a study")
    plot.add_argument("results", help="results file (.h5) or study folder")
    plot.add_argument(
        "-o",
        "--output",
        help="image file (.png, .svg or .pdf; default: RESULTS.png), or a folder that gets one "
        "figure per quantity",
    )
    plot.add_argument(
        "quantity",
        nargs="*",
        help="what to plot, e.g. energy violation position:crank reaction:guide "
        "deflection:rod (default: an overview); for a study folder, one output",
    )
    plot.add_argument("--against", metavar="KEY", help="study folder: the parameter of the x axis")
    animate = sub.add_parser(
        "animate", help="render an animation and write a ParaView series of a results file"
    )
    animate.add_argument("results", help="results file (.h5)")
    animate.add_argument("-o", "--output", help="animation file (.gif; default: RESULTS.gif)")
    animate.add_argument("--vtu", help="folder of the ParaView series (default: RESULTS_vtu)")
    animate.add_argument("--no-vtu", action="store_true", help="write no ParaView series")
    animate.add_argument(
        "--vtu-every", type=_every, metavar="N", help="ParaView series: every N-th record"
    )
    animate.add_argument(
        "--vtu-times",
        type=_times,
        metavar="A:B",
        help="ParaView series: only the records from time A to B (s; A or B may be left out)",
    )
    animate.add_argument("--no-render", action="store_true", help="render no animation")
    animate.add_argument("--frames", type=_every, help="number of frames rendered")
    animate.add_argument(
        "--scale",
        type=float,
        help="deformation scale of the animation (default: automatic) and of the ParaView "
        "series' geometry (default: 1; its displacement field stays true to scale)",
    )
    animate.add_argument("-q", "--quiet", action="store_true", help="no progress bars")
    animate.add_argument(
        "--backend",
        choices=("matplotlib", "pyvista", "auto"),
        default="matplotlib",
        help="renderer: matplotlib (default), pyvista off screen (pip install flexmbd[render]; "
        "needs an OpenGL/EGL library), or auto (pyvista if it renders, else matplotlib)",
    )
    schema = sub.add_parser("schema", help="print the JSON schema of model files")
    schema.add_argument("-o", "--output", help="file to write it to")
    sub.add_parser("examples", help="list the built-in examples")
    pre = sub.add_parser(
        "preprocess",
        help="build a deformable body file from a mesh (Gmsh .msh, Abaqus .inp, VTK) or a "
        "Nastran deck (.bdf, .nas, .dat)",
        description="Element matrices, invariants of motion, reference conditions and modes "
        "of a body meshed with solid, beam or shell elements, saved as an HDF5 body file.",
    )
    pre.add_argument("mesh", help="mesh file")
    pre.add_argument("-o", "--output", required=True, help="body file to write (.h5)")
    pre.add_argument(
        "-E", "--young-modulus", type=float, help="Pa (not for Nastran decks: from their MAT1)"
    )
    pre.add_argument("--poisson-ratio", type=float)
    pre.add_argument("--density", type=float, help="kg/m^3")
    pre.add_argument("--mass", choices=("consistent", "lumped"), default="consistent")
    pre.add_argument(
        "--section",
        type=_section_argument,
        metavar="KIND:VALUES",
        help="beam section: circle:R, rectangle:WIDTH,HEIGHT (along the section's y, z), "
        "tube:OUTER,INNER (radii) or general:AREA,IY,IZ,J (m, m^2, m^4)",
    )
    pre.add_argument(
        "--section-orientation",
        type=float,
        nargs=3,
        metavar=("X", "Y", "Z"),
        help="beam sections' y axis, a vector across the beams (default: chosen)",
    )
    pre.add_argument(
        "--beam-theory", choices=("euler-bernoulli", "timoshenko"), default="euler-bernoulli"
    )
    pre.add_argument(
        "--thickness",
        type=float,
        help="shell thickness (m; default: the mesh's own, an Abaqus *SHELL SECTION)",
    )
    pre.add_argument(
        "--orient-shells",
        action="store_true",
        help="turn the shells of each connected surface to one side (their stresses are "
        "averaged at the nodes top with top)",
    )
    pre.add_argument(
        "--incompatible-modes",
        action="store_true",
        help="the mesh's hexahedra as hex8i, with incompatible modes (they bend on coarse "
        "meshes; Abaqus C3D8I elements are hex8i without it)",
    )
    pre.add_argument(
        "--reference",
        choices=("none", "clamped", "3-2-1", "simply-supported", "mean-axis", "interface"),
        default="none",
        help="reference conditions: the body frame (default none)",
    )
    pre.add_argument(
        "--reference-nodes", nargs="+", help="a node set name, or node indices (0-based)"
    )
    pre.add_argument(
        "--modes",
        choices=("none", "fixed-interface", "free-free", "craig-bampton"),
        default="none",
        help="modal reduction (default none: nodal elastic coordinates)",
    )
    pre.add_argument("-n", "--count", type=int, default=0, help="number of eigenmodes")
    pre.add_argument("--interfaces", nargs="+", default=[], help="Craig-Bampton node sets")
    pre.add_argument(
        "--interface-kind",
        choices=("rbe2", "rbe3", "nodal"),
        default="rbe2",
        help="rbe2: each interface moves rigidly; rbe3: its weighted average motion; nodal: "
        "every node's (default rbe2)",
    )
    pre.add_argument(
        "--interface-weights",
        choices=("auto", "area", "length", "volume", "uniform"),
        default="auto",
        help="weights of the interfaces' nodes (default auto: area on faces, length on edges, "
        "volume on volumes)",
    )
    pre.add_argument("--precision", choices=("auto", "double", "single"), default="auto")
    add_sweep_parser(sub)
    camp = sub.add_parser(
        "campbell",
        help="Campbell diagram: mode frequencies against the speed of a driver",
        description="At each speed the driver turns at that constant speed; the modes of the "
        "steady rotation are followed across the speeds by their shapes (MAC).",
    )
    camp.add_argument("model", help="model file (.yaml) or built-in example")
    camp.add_argument(
        "--driver", help="name of the angle driver (default: the model's one angle driver)"
    )
    camp.add_argument("--speeds", required=True, help="START:STOP:COUNT or V1,V2,... (rad/s)")
    camp.add_argument("--modes", type=int, default=6, help="modes followed (default 6)")
    camp.add_argument(
        "--orders", type=float, nargs="+", default=[1.0, 2.0, 3.0], help="excitation orders"
    )
    camp.add_argument(
        "--frame",
        choices=("rotating", "fixed"),
        default="rotating",
        help="frame of the frequencies: rotating (blades; default) or fixed (rotor whirl: "
        "forward at w_rotating + W, backward at w_rotating - W)",
    )
    camp.add_argument("-o", "--output", help="output stem (default: MODEL_campbell)")
    floq = sub.add_parser(
        "floquet",
        help="Floquet analysis: the stability of a periodic motion (multipliers over a period)",
        description="Runs the model over one period from small changes of each independent "
        "coordinate and velocity; the eigenvalues of the monodromy matrix (the multipliers) "
        "outside the unit circle are growing motions.",
    )
    floq.add_argument("model", help="model file (.yaml) or built-in example")
    floq.add_argument(
        "--period", required=True, type=duration_argument, help="period of the motion (s)"
    )
    floq.add_argument("--steps", type=_every, default=400, help="steps per period (default 400)")
    floq.add_argument(
        "--settle",
        type=_whole,
        default=0,
        help="periods run first, to settle onto the periodic motion (default 0: the model's "
        "start state)",
    )
    floq.add_argument(
        "--start",
        choices=("given", "equilibrium", "steady-rotation"),
        help="the state the analysis (or --settle) starts from (default: the model file's "
        "`start`, else given)",
    )
    floq.add_argument(
        "--workers",
        type=_every,
        default=None,
        help="runs made at once, in threads (default: the processors available)",
    )
    floq.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    modes = sub.add_parser(
        "modes",
        help="modes of the assembly about its equilibrium or steady rotation (free-free modes "
        "of a free-flying model), and animations",
    )
    modes.add_argument("model", help="model file (.yaml) or built-in example")
    modes.add_argument("--count", type=_every, default=10, help="modes listed (default 10)")
    modes.add_argument(
        "--animate", type=_every, nargs="*", default=[], metavar="K", help="modes to animate (1 ..)"
    )
    modes.add_argument("--frames", type=_every, default=24, help="frames per period (default 24)")
    modes.add_argument("-o", "--output", help="output stem (default: the model's name)")
    view = sub.add_parser(
        "view",
        help="write an interactive viewer (one HTML page, opens offline) of a results file, or "
        "of a model's mode shapes",
    )
    view.add_argument("source", help="results file (.h5), or with --modes a model or example")
    view.add_argument("-o", "--output", help="HTML file (default: RESULTS.html)")
    view.add_argument(
        "--max-frames", type=int, default=200, help="most records stored (default 200)"
    )
    view.add_argument("--scale", type=float, help="deformation scale (default: automatic)")
    view.add_argument(
        "--color",
        default="displacement",
        help="colour: displacement (default), stress (solids) or none",
    )
    view.add_argument(
        "--modes", type=int, help="view this many mode shapes of a model (as flexmbd modes)"
    )
    args, extra = parser.parse_known_args(_negative_values_joined(parser, argv))
    if args.command == "plot" and not any(text.startswith("-") for text in extra):
        # Quantities after an option (``plot R.h5 -o x.svg deflection:rod``): argparse has
        # already closed the positional list at the option.
        args.quantity = [*args.quantity, *extra]
    elif extra:
        parser.error(f"unrecognized arguments: {' '.join(extra)}")
    with _logging_to_stderr(getattr(args, "verbose", 0), getattr(args, "quiet", False)):
        return _command(parser, args)


def _negative_values_joined(parser: argparse.ArgumentParser, argv: list[str] | None) -> list[str]:
    """`argv` with a value that starts with a minus sign and a digit joined to its option
    (``--speeds -60:60:5`` -> ``--speeds=-60:60:5``): argparse takes such a value for an
    option unless it is a plain negative number, so ``--step -1e-3`` failed too."""
    tokens = list(sys.argv[1:] if argv is None else argv)
    single = set()
    parsers = [parser]
    while parsers:
        for action in parsers.pop()._actions:
            if isinstance(action, argparse._SubParsersAction):
                parsers.extend(action.choices.values())
            elif action.option_strings and action.nargs is None:
                single.update(action.option_strings)
    joined: list[str] = []
    k = 0
    while k < len(tokens):
        token = tokens[k]
        following = tokens[k + 1] if k + 1 < len(tokens) else ""
        if token in single and re.match(r"-[0-9.]", following):
            joined.append(f"{token}={following}")
            k += 2
        else:
            joined.append(token)
            k += 1
    return joined


def _command(parser: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    commands = {
        "sweep": sweep,
        "campbell": _campbell,
        "floquet": _floquet,
        "modes": _modes,
        "preprocess": _preprocess,
        "info": _info,
        "plot": _plot,
        "animate": _animate,
        "schema": _schema,
        "view": _view,
    }
    if args.command in commands:
        return commands[args.command](args)
    if args.command == "examples":
        from .examples import EXAMPLES

        for name, builder in sorted(EXAMPLES.items()):
            print(f"{name}: {builder().description}")
        return 0
    if args.command in (None, "run"):
        if args.command is None:
            args = parser.parse_args(["run"])
        return _run(args)
    return 2


if __name__ == "__main__":
    raise SystemExit(main())
