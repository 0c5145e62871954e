"""The study commands of ``flexmbd``: ``sweep`` runs a study of a model file or a built-in
example, ``info DIR`` summarizes a study folder, ``plot DIR OUTPUT --against KEY`` draws an
output against a parameter."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from .._checks import duration_argument, time_argument
from ..errors import FlexmbdError, InvalidParameterError
from .sampling import plain

DEFAULT_OUTPUTS = {"largest violation": "max(violation)", "final energy": "final(energy[total])"}


def model_file_outputs(model: Any) -> dict[str, str]:
    """The study outputs of a model file's `outputs` (a :class:`flexmbd.model_file.ModelFile`):
    each as ``flexmbd run`` sums it up, a number per case. Vectors by their largest length over
    the run (deflection of a node, velocities, the force and the torque of a reaction, a
    sensor's velocity or acceleration), a beam body's stresses by its largest axial force and
    bending moment, other bodies' by their largest von Mises stress, energies by their largest
    value; positions, orientations and elastic coordinates have no one number and are left
    out."""
    compiled = model.system.compile()
    layout = compiled.describe()
    sensors = {s["name"]: s["quantity"] for s in layout["sensors"]}
    beams = {
        layout["bodies"][index]["name"]: all(kind == "beam2" for kind in data.elements)
        for index, data in compiled.flexible_bodies.items()
    }
    outputs: dict[str, str] = {}
    for output in model.outputs:
        item, quantity, label = output.item, output.quantity, f"largest {output.label}"
        if output.kind == "sensor":
            if sensors.get(item) not in ("position", "orientation"):
                outputs[label] = f"max(sensor:{item}[magnitude])"
        elif output.kind == "joint" and quantity in ("reaction_force", "reaction_torque"):
            outputs[label] = f"max(reaction:{item}[{quantity.removeprefix('reaction_')}])"
        elif (
            output.kind == "system" and quantity.endswith("_energy") and quantity != "total_energy"
        ):
            outputs[label] = f"max(energy[{quantity.removesuffix('_energy')}])"
        elif quantity == "deflection" and output.chord is None:
            outputs[label] = f"max(deflection:{item}:{output.node}[magnitude])"
        elif quantity in ("velocity", "angular_velocity"):
            outputs[label] = f"max({quantity.replace('_', '-')}:{item}[magnitude])"
        elif quantity == "stresses" and beams.get(item):
            outputs[f"{label} axial force"] = f"max(stress:{item}[axial])"
            outputs[f"{label} bending moment"] = f"max(stress:{item}[bending])"
        elif quantity == "stresses":
            outputs[label] = f"max(stress:{item})"
    return outputs


def add_sweep_parser(sub: Any) -> None:
    """The ``sweep`` subcommand's arguments."""
    sweep = sub.add_parser(
        "sweep",
        help="run a parameter study of a model file or a built-in example on Dask",
        description="Runs a study: every combination of the --set values (a grid), or "
        "--sample random:N / lhs:N cases in the --set ranges; each case's results file and the "
        "gathered dataset (study.nc) go to the folder -o. Cases done are not run again.",
    )
    sweep.add_argument("model", help="model file (.yaml) or built-in example name")
    sweep.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUES",
        help="a parameter: KEY=V1,V2,... (grid) or KEY=LOW:HIGH (with --sample); KEY is a "
        "model-file key path (bodies.rod.section.radius) or an example's argument",
    )
    sweep.add_argument("--sample", metavar="KIND:N", help="random:N or lhs:N samples")
    sweep.add_argument("--seed", type=int, default=0, help="seed of the samples (default 0)")
    sweep.add_argument(
        "--output",
        action="append",
        default=[],
        metavar="[NAME=]SPEC",
        help="an output, e.g. 'deflection=max-abs(deflection:rod:5[y])' (default: the largest "
        "constraint violation, the final energy and a model file's outputs, each as `flexmbd "
        "run` sums it up)",
    )
    sweep.add_argument("--workers", type=int, help="worker processes (default: CPUs)")
    sweep.add_argument("--scheduler", help="address of an existing Dask scheduler")
    sweep.add_argument("-o", "--folder", required=True, help="study folder")
    sweep.add_argument("--end", type=time_argument, help="end time (s)")
    sweep.add_argument("--step", type=duration_argument, help="step size (s)")
    sweep.add_argument("--output-interval", type=duration_argument, help="time between records (s)")
    sweep.add_argument("-q", "--quiet", action="store_true", help="no progress bar")


def _value(text: str) -> Any:
    """A value of --set: a number, else as model files read YAML (booleans, text, [lists];
    YAML 1.2 numbers: 5e-3 is a number, 1:2 is text, not the base-60 number 62)."""
    import yaml

    from ..model_file.reading import yaml_value

    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    try:
        return yaml_value(text) if text.strip() else text
    except yaml.YAMLError as error:
        raise InvalidParameterError(f"--set value {text!r} is not a value: {error}") from None


def _split(values: str) -> list[str]:
    """The comma-separated values of --set, commas inside brackets kept ("[0, 1],[0, 2]")."""
    parts, depth, start = [], 0, 0
    for k, c in enumerate(values):
        depth += (c in "[{") - (c in "]}")
        if c == "," and depth == 0:
            parts.append(values[start:k])
            start = k + 1
    parts.append(values[start:])
    return parts


def _parameters(settings: list[str], sampling: str) -> dict[str, Any]:
    parameters: dict[str, Any] = {}
    for item in settings:
        key, sep, values = item.partition("=")
        if not sep or not key.strip() or not values.strip():
            raise InvalidParameterError(f"--set {item!r}: expected KEY=V1,V2,... or KEY=LOW:HIGH")
        key = key.strip()
        if key in parameters:
            raise InvalidParameterError(
                f"--set {item!r}: {key} is set twice; give its values in one --set"
            )
        if sampling == "grid":
            low, colon, high = values.partition(":")
            if colon and all(isinstance(_value(v), (int, float)) for v in (low, high)):
                raise InvalidParameterError(
                    f"--set {item!r}: LOW:HIGH is a range to sample: give --sample random:N "
                    "or lhs:N, or the values as V1,V2,..."
                )
            parameters[key] = [_value(v) for v in _split(values)]
        else:
            low, sep, high = values.partition(":")
            if not sep:
                raise InvalidParameterError(f"--set {item!r}: --sample needs a range LOW:HIGH")
            parameters[key] = (_value(low), _value(high))
    if not parameters:
        raise InvalidParameterError("no parameter: give at least one --set KEY=VALUES")
    return parameters


def sweep(args: argparse.Namespace) -> int:
    """``flexmbd sweep``."""
    from ..examples import EXAMPLES
    from . import Study

    study = None
    try:
        sampling, samples = "grid", None
        if args.sample:
            kind, _, count = args.sample.partition(":")
            if not count.isdigit():
                raise InvalidParameterError(f"--sample {args.sample!r}: expected random:N or lhs:N")
            sampling, samples = kind, int(count)
        outputs = {}
        for item in args.output:
            name, sep, spec = item.partition("=")
            label = name.strip() if sep else item
            if label in outputs:
                raise InvalidParameterError(
                    f"--output {item!r}: an output named {label!r} is given twice"
                )
            outputs[label] = spec.strip() if sep else item
        model: Any = EXAMPLES[args.model] if args.model in EXAMPLES else args.model
        if model is args.model and not Path(model).is_file():
            known = ", ".join(sorted(EXAMPLES))
            raise InvalidParameterError(f"no model file or example {model!r} (examples: {known})")
        if not outputs and model is args.model:
            from ..model_file import load_model

            outputs = {**DEFAULT_OUTPUTS, **model_file_outputs(load_model(model))}
        study = Study(
            model,
            _parameters(args.set, sampling),
            sampling=sampling,
            samples=samples,
            seed=args.seed,
            outputs=outputs or DEFAULT_OUTPUTS,
            folder=args.folder,
            end_time=args.end,
            step_size=args.step,
            output_interval=args.output_interval,
        )
        print(f"{study!r}: {len(study.pending())} to run")
        data = study.run(workers=args.workers, scheduler=args.scheduler, progress=not args.quiet)
    except (FlexmbdError, OSError) as error:
        # OSError: a folder that is a file, no permission to write it.
        print(f"flexmbd sweep: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        # The cases done keep their files and summaries; the cluster is stopped.
        if study is None:
            print("flexmbd sweep: interrupted", file=sys.stderr)
        else:
            total = len(study.cases)
            done = total - len(study.pending())
            print(
                f"flexmbd sweep: interrupted; {done} of {total} cases are done in "
                f"{str(args.folder)!r}: the same command runs the others",
                file=sys.stderr,
            )
        return 130
    _print_study(data, {"model": args.model, "parameters": study.parameter_names})
    return 0 if all(s == "complete" for s in data["status"].values) else 1


#: The variables of a study's dataset that are not outputs: each case's run.
CASE_FIELDS = ("status", "error", "warnings", "elapsed")


def _print_study(data: Any, description: dict[str, Any]) -> None:
    import numpy as np

    status = [str(s) for s in data["status"].values]
    print(
        f"{description.get('model')}: {len(status)} cases, {status.count('complete')} complete, "
        f"{status.count('failed')} failed, {status.count('pending')} pending"
    )
    # In the study's own order (a study folder's dataset read back has its coordinates in
    # another: string-valued ones come back as variables and are made coordinates again).
    names = [n for n in data.coords if n not in ("case", "time")]
    order = [n for n in description.get("parameters", ()) if n in names]
    for name in order + [n for n in names if n not in order]:
        values = data.coords[name].values
        shown = np.unique(values)
        text = (
            f"{len(shown)} values from {shown.min():g} to {shown.max():g}"
            if shown.dtype.kind == "f" and len(shown) > 4
            else ", ".join(str(v) for v in shown)
        )
        print(f"  parameter {name}: {text}")
    complete = np.array(status) == "complete"
    for name, variable in data.data_vars.items():
        if name in CASE_FIELDS or "time" in variable.dims:
            continue
        if not np.issubdtype(variable.dtype, np.number):
            continue
        values = variable.values[complete]
        values = values[np.isfinite(values)]
        if len(values):
            unit = variable.attrs.get("units", "")
            unit = f" {unit}" if unit else ""
            print(f"  output {name}: {values.min():.6g} .. {values.max():.6g}{unit}")
    for k in np.flatnonzero(np.array(status) == "failed"):
        print(f"  case {k} failed: {data['error'].values[k]}")
    warned = _warned_cases(data)
    for text, cases in warned.items():
        shown = ", ".join(str(k) for k in cases[:8]) + (", ..." if len(cases) > 8 else "")
        print(f"  {len(cases)} case(s) warned ({shown}): {text}")


def _warned_cases(data: Any) -> dict[str, list[int]]:
    """The warnings of a study's cases (`run_case`), by kind: the first case's text of each
    kind and the cases that had it. Studies gathered before cases kept warnings have none."""
    if "warnings" not in data.data_vars:
        return {}
    warned: dict[str, tuple[str, list[int]]] = {}
    for k, line in enumerate(data["warnings"].values):
        for text in filter(None, str(line).split("\n")):
            kind = text.split(":", 1)[0]
            warned.setdefault(kind, (text, []))[1].append(k)
    return dict(warned.values())


def info_study(folder: Path) -> int:
    """``flexmbd info DIR`` of a study folder."""
    import numpy as np

    from . import load_study

    data, description = load_study(folder)
    _print_study(data, description)
    elapsed = data["elapsed"].values
    if np.any(np.isfinite(elapsed)):
        print(f"  run time per case: {np.nanmean(elapsed):.3g} s (mean)")
    return 0


def plot_study(folder: Path, output: str, against: str | None, image: str | None) -> list[Path]:
    """Draws `output` of a study against the parameter `against` (one line per combination of
    the other parameters; sampled cases, which share none, as points coloured by the first
    other parameter; failed cases crossed); returns the image written."""
    import matplotlib
    import numpy as np

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from . import load_study

    data, description = load_study(folder)
    names = [n for n in description["parameters"]]
    # (the output first: an unknown one was answered with "--against: one of the parameters")
    if output not in data.data_vars or output in CASE_FIELDS:
        outputs = [n for n in data.data_vars if n not in CASE_FIELDS]
        raise InvalidParameterError(f"no output {output!r}; outputs: {outputs}")
    if against is None:
        if len(names) != 1:
            raise InvalidParameterError(
                f"--against: one of the parameters {names} (the study has {len(names)})"
            )
        against = names[0]
    if against not in names:
        raise InvalidParameterError(f"--against {against!r}: the parameters are {names}")
    variable = data[output]
    if "time" in variable.dims:
        raise InvalidParameterError(f"{output!r} is a time series: plot a reduced output")
    others = [n for n in names if n != against]
    groups: dict[tuple[Any, ...], list[int]] = {}
    for k in range(data.sizes["case"]):
        key = tuple(plain(data[n].values[k]) for n in others)
        groups.setdefault(key, []).append(k)
    fig, ax = plt.subplots(figsize=(7, 4.5))
    x_all = data[against].values
    status = data["status"].values
    numeric = [n for n in others if np.issubdtype(data[n].dtype, np.number)]
    sampled = bool(numeric) and len(groups) > 1 and all(len(c) == 1 for c in groups.values())
    if sampled:
        # Sampled cases (random, Latin hypercube): no two share the other parameters, so no
        # lines; points coloured by the first other parameter instead of a legend per case.
        colour = numeric[0]
        ok = status == "complete"
        points = ax.scatter(x_all[ok], variable.values[ok], c=data[colour].values[ok])
        fig.colorbar(points, ax=ax, label=colour)
        bad = status == "failed"
        if bad.any():
            ax.plot(x_all[bad], variable.values[bad], "kx", label="failed")
    else:
        for group, cases in groups.items():
            cases = sorted(cases, key=lambda k: x_all[k])
            ok = [k for k in cases if status[k] == "complete"]
            label = (
                ", ".join(
                    f"{n} = {v:g}" if isinstance(v, float) else f"{n} = {v}"
                    for n, v in zip(others, group, strict=True)
                )
                or None
            )
            ax.plot(x_all[ok], variable.values[ok], "o-", label=label)
            bad = [k for k in cases if status[k] == "failed"]
            if bad:
                mark = "failed" if label is None else None
                ax.plot(x_all[bad], variable.values[bad], "kx", label=mark)
    ax.set_xlabel(against)
    unit = variable.attrs.get("units", "")
    ax.set_ylabel(f"{output} ({unit})" if unit else output)
    ax.set_title(f"{output} against {against} ({len(x_all)} cases)")
    ax.grid(True, alpha=0.3)
    if (len(groups) > 1 and not sampled) or any(status == "failed"):
        ax.legend(fontsize=8)
    from ..plotting import _slug

    # (an output named "force/mass" was a folder of the file name that does not exist)
    path = Path(image) if image else Path(folder) / f"{_slug(output)}_{_slug(against)}.png"
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return [path]
