"""The cases of a study: parameter values on a grid, from a list, or sampled at random or by
Latin hypercube with a seed."""

from __future__ import annotations

import inspect
import itertools
from collections.abc import Mapping, Sequence
from typing import Any

from ..errors import InvalidParameterError

#: How the cases are made from the parameters.
SAMPLINGS = ("grid", "list", "random", "lhs")


def _number(value: Any, where: str) -> float:
    import numpy as np

    try:
        number = float(value)
    except (TypeError, ValueError):
        raise InvalidParameterError(f"{where}: expected a number, got {value!r}") from None
    if not np.isfinite(number):
        raise InvalidParameterError(f"{where}: expected a finite number, got {value!r}")
    return number


def make_cases(
    parameters: Mapping[str, Any] | Sequence[Mapping[str, Any]],
    sampling: str = "grid",
    samples: int | None = None,
    seed: int = 0,
) -> list[dict[str, Any]]:
    """The parameter values of every case.

    - ``"grid"``: `parameters` maps each key to a sequence of values; every combination,
      the first key varying slowest.
    - ``"list"``: `parameters` is a sequence of mappings, one case each (the same keys).
    - ``"random"``: `parameters` maps each key to a range (low, high); `samples` cases drawn
      uniformly with `seed`.
    - ``"lhs"``: as "random", by Latin hypercube sampling (one case in each of `samples`
      equal strata of every range).
    """
    import numpy as np

    if sampling not in SAMPLINGS:
        raise InvalidParameterError(
            f"sampling must be one of {', '.join(SAMPLINGS)}, got {sampling!r}", item="sampling"
        )
    if sampling in ("grid", "list") and samples is not None:
        raise InvalidParameterError(
            f"samples={samples!r} is for random and lhs sampling; a {sampling} has its own cases",
            item="samples",
        )
    if sampling == "list":
        if isinstance(parameters, Mapping) or not parameters:
            raise InvalidParameterError("sampling 'list' takes a non-empty list of mappings")
        if not all(isinstance(case, Mapping) for case in parameters):
            raise InvalidParameterError(
                "sampling 'list' takes a non-empty list of mappings (one per case), got "
                f"{next(c for c in parameters if not isinstance(c, Mapping))!r} in it"
            )
        # (numpy scalars were refused by JSON after the cluster had started)
        cases = [{k: plain(v) for k, v in case.items()} for case in parameters]
        keys = set(cases[0])
        for k, case in enumerate(cases):
            if set(case) != keys:
                raise InvalidParameterError(
                    f"case {k} has the parameters {sorted(case)}, case 0 {sorted(keys)}"
                )
        return cases
    if not isinstance(parameters, Mapping) or not parameters:
        raise InvalidParameterError(f"sampling {sampling!r} takes a mapping key -> values")
    if sampling == "grid":
        values = []
        for key, options in parameters.items():
            if isinstance(options, (set, frozenset)) or inspect.isgenerator(options):
                # (a set or a generator became one case holding it)
                raise InvalidParameterError(
                    f"parameter {key!r}: the values as a list or an array, got "
                    f"{type(options).__name__}",
                    item=key,
                )
            if isinstance(options, (list, tuple)):
                options = list(options)
            else:
                options = list(np.atleast_1d(options)) if np.ndim(options) else [options]
            if not options:
                raise InvalidParameterError(f"parameter {key!r}: no values", item=key)
            values.append([plain(v) for v in options])
        return [dict(zip(parameters, combo, strict=True)) for combo in itertools.product(*values)]
    whole = (
        isinstance(samples, int | float | np.integer | np.floating)
        and not isinstance(samples, bool)
        and bool(np.isfinite(samples))
        and int(samples) == samples
    )
    if not whole or samples < 1:  # (NaN was "cannot convert float NaN to integer")
        raise InvalidParameterError(
            f"sampling {sampling!r} needs samples >= 1, got {samples!r}", item="samples"
        )
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        # (numpy's ValueError or TypeError of its SeedSequence)
        raise InvalidParameterError(f"seed must be an integer >= 0, got {seed!r}", item="seed")
    ranges = []
    for key, bounds in parameters.items():
        if np.ndim(bounds) != 1 or len(bounds) != 2:
            raise InvalidParameterError(
                f"parameter {key!r}: a range (low, high) for sampling {sampling!r}, got {bounds!r}",
                item=key,
            )
        low, high = (_number(b, f"parameter {key!r}") for b in bounds)
        if not high > low:
            raise InvalidParameterError(
                f"parameter {key!r}: the range ({low:g}, {high:g}) is empty", item=key
            )
        ranges.append((low, high))
    rng = np.random.default_rng(seed)
    n, d = int(samples), len(ranges)
    if sampling == "random":
        unit = rng.random((n, d))
    else:
        # One point in each of n strata per dimension, the strata paired at random.
        unit = (np.argsort(rng.random((n, d)), axis=0) + rng.random((n, d))) / n
    low = np.array([r[0] for r in ranges])
    high = np.array([r[1] for r in ranges])
    points = low + unit * (high - low)
    return [{key: float(points[i, j]) for j, key in enumerate(parameters)} for i in range(n)]


def plain(value: Any) -> Any:
    """A numpy scalar or array as the Python number or list it holds (JSON and hashes take
    those)."""
    import numpy as np

    return value.tolist() if isinstance(value, (np.generic, np.ndarray)) else value
