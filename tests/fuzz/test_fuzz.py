"""The fuzz suite of issue 28: every case of ``corpus.py`` (model files, meshes, body files,
results files, API calls; more than 500) runs in worker subprocesses (``worker.py``), a few
groups per family, two or more at a time, with a time limit per case. Each case must give a
typed error naming the item or a right result: never a panic, crash, hang, other exception
or a changed or deleted input. A failure names the case and how to reproduce it; the
failures of code outside this suite's reach are xfail with their reason
(``corpus.KNOWN_FAILURES``).

    python -m pytest -q tests/fuzz                     # the corpus of seed 28
    FLEXMBD_FUZZ_SEED=7 python -m pytest -q tests/fuzz  # another corpus
"""

from __future__ import annotations

import os
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import corpus
import pytest
import worker

SEED = corpus.seed_from_environment()
CASES = {case.name: case for case in corpus.cases(SEED)}

#: Cases per worker process (each imports flexmbd and builds its base files once).
GROUP_SIZE = 100
#: Worker processes at a time (the suite is meant for a 2-core machine and more).
PARALLEL = max(2, min(4, os.cpu_count() or 2))


def _groups() -> list[list[str]]:
    """The cases split into a few groups per family (interleaved, so that the slow kinds of
    a family spread over its groups)."""
    groups = []
    for family in corpus.FAMILIES:
        names = [name for name, case in CASES.items() if case.family == family]
        count = max(1, round(len(names) / GROUP_SIZE))
        groups += [names[k::count] for k in range(count)]
    return groups


@pytest.fixture(scope="module")
def outcomes() -> dict[str, dict[str, Any]]:
    """The outcome of every case (the whole corpus runs at the first test that asks)."""
    start = time.perf_counter()
    results: dict[str, dict[str, Any]] = {}
    with ThreadPoolExecutor(PARALLEL) as pool:
        for part in pool.map(lambda names: worker.supervise(names, SEED), _groups()):
            results.update(part)
    seconds = time.perf_counter() - start
    print(f"\nfuzz corpus of seed {SEED}: {len(results)} cases in {seconds:.1f} s")
    return results


def test_the_corpus_is_large_seeded_and_reproducible():
    again = corpus.cases(SEED)
    assert [case.name for case in again] == list(CASES)
    assert len(CASES) >= 500
    for family in corpus.FAMILIES:
        assert sum(case.family == family for case in again) >= 50, family
    other = corpus.cases(SEED + 1)
    assert [case.name for case in other] != list(CASES) or len(other) != len(CASES)


@pytest.mark.parametrize("name", list(CASES))
def test_case(name: str, outcomes: dict[str, dict[str, Any]]) -> None:
    record = outcomes[name]
    if record["outcome"] in worker.GOOD:
        return
    case = CASES[name]
    known = corpus.known_failure(case, record["outcome"], record["message"])
    if known is not None:
        pytest.xfail(f"{known.reason} [{record['outcome']}: {record['message'][:300]}]")
    pytest.fail(
        f"{name}: {record['outcome']}: {record['message']}\n"
        f"reproduce: python -m tests.fuzz.worker --seed {SEED} --case '{name}' "
        "--keep /tmp/flexmbd-fuzz",
        pytrace=False,
    )


def test_the_supervisor_tells_crashes_hangs_and_tracebacks_apart():
    # Each self-test case names its expected outcome; a crash or a hang the alarm cannot
    # end costs the worker, and the next case runs in a new one.
    names = [case.name for case in corpus.all_cases(SEED) if case.family == "self-test"]
    results = worker.supervise(names, SEED, timeout=1.0, grace=2.0)
    for name in names:
        expected = name.split("/")[2]
        assert results[name]["outcome"] == expected, (name, results[name])
    assert "SIGSEGV" in results["self-test/crash/crash/007"]["message"]
