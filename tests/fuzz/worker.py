"""Runs cases of the fuzz corpus and prints one JSON line per case: ``name``, ``outcome``,
``message``, ``seconds`` (and ``family``, ``kind``).

Outcomes: ``ok`` (a right result), ``error`` (a typed error naming the item), and the
failures ``unnamed`` (a typed error whose message is empty or names nothing the case
expects), ``garbled`` (a typed error whose message holds a number of dozens of digits or
thousands of characters), ``wrong`` (a result that is not right, an input that should have
been refused, code executed), ``panic`` (a Rust panic), ``internal`` (any other exception),
``hang`` (the case ran longer than its time limit), ``lost-file`` (an input file changed or
deleted) and, from :func:`supervise`, ``crash`` (the process died in the case).

By hand, from the repository root::

    python -m tests.fuzz.worker --family model-files         # one family (in this process)
    python -m tests.fuzz.worker --family api --failures      # only the cases that fail
    python -m tests.fuzz.worker --case NAME --keep /tmp/x     # one case; inputs kept in /tmp/x
    python -m tests.fuzz.worker --list --family meshes       # the names of the cases
    python -m tests.fuzz.worker --supervised --family meshes # in worker subprocesses, as CI

``--seed`` (default ``FLEXMBD_FUZZ_SEED`` or 28) selects the corpus; ``--timeout`` the
limit per case (s). A case that crashes the process is best reproduced with ``--case``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import queue
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import traceback
import warnings
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

try:
    from . import corpus
except ImportError:  # run as a script: python tests/fuzz/worker.py
    import corpus  # type: ignore[no-redef]

#: Time limit of one case, s (the worker's alarm; the supervisor kills later).
CASE_TIMEOUT = 15.0
#: Extra time the supervisor allows before it kills a worker that does not answer, s.
KILL_GRACE = 10.0
#: Time a worker may take to start (imports) before its first case counts, s.
STARTUP = 60.0
#: Address space of a worker, bytes: a runaway allocation fails instead of swapping.
MEMORY_LIMIT = 8 * 1024**3

#: Outcomes that are right.
GOOD = ("ok", "error")


class CaseTimeout(BaseException):
    """Raised by the alarm of a case that runs longer than its limit."""


def _snapshot(folder: Path) -> dict[str, str]:
    """Hashes of the regular files under `folder` (symbolic links and special files by
    their kind), by relative path."""
    found: dict[str, str] = {}
    for path in folder.rglob("*"):
        relative = str(path.relative_to(folder))
        if path.is_symlink():
            found[relative] = f"link:{os.readlink(path)}"
        elif path.is_file():
            found[relative] = hashlib.sha256(path.read_bytes()).hexdigest()
        elif path.is_dir():
            found[relative] = "folder"
        else:
            found[relative] = "special"
    return found


def _typed(error: BaseException, case: corpus.Case) -> bool:
    """A typed error of flexmbd: a FlexmbdError or a ValueError subclass defined by flexmbd
    (or one of the case's allowed types)."""
    from flexmbd.errors import FlexmbdError

    if isinstance(error, FlexmbdError) or isinstance(error, case.allowed):
        return True
    return isinstance(error, ValueError) and type(error).__module__.startswith("flexmbd")


def _named(error: BaseException, case: corpus.Case) -> bool:
    """The message is not empty and names an item: one of the case's names, or, for a
    failed simulation, the time of the failure."""
    from flexmbd.errors import SimulationError

    message = str(error).strip()
    if not message:
        return False
    if isinstance(error, SimulationError) and (error.time is not None or "t = " in message):
        return True
    lowered = message.lower()
    for name in case.names:
        name = name.lower()
        forms = {name, name.replace("_", " "), name.removesuffix("s").replace("_", " ")}
        if any(form and form in lowered for form in forms):
            return True
    return False


#: Longest message that reads as one, characters.
MESSAGE_LIMIT = 2000


def _garbled(message: str) -> str | None:
    """Why a message is not readable (a number of dozens of digits, a huge echo of the
    input), or None."""
    digits = re.search(r"\d{25,}", message)
    if digits:
        return f"the message holds a number of {len(digits.group())} digits"
    if len(message) > MESSAGE_LIMIT:
        return f"the message has {len(message)} characters"
    return None


def _describe(error: BaseException) -> str:
    text = f"{type(error).__module__}.{type(error).__qualname__}: {error}"
    return text if len(text) <= 600 else text[:600] + " ..."


def run_case(case: corpus.Case, root: Path, timeout: float = CASE_TIMEOUT) -> dict[str, Any]:
    """Runs one case in a new folder under `root` and classifies what happened."""
    folder = root / case.name.replace("/", "__")
    folder.mkdir(parents=True)
    start = time.perf_counter()
    limit = timeout if case.timeout is None else min(timeout, case.timeout)
    outcome, message = _execute(case, folder, limit)
    return {
        "name": case.name,
        "family": case.family,
        "kind": case.kind,
        "outcome": outcome,
        "message": message,
        "seconds": round(time.perf_counter() - start, 3),
    }


def _execute(case: corpus.Case, folder: Path, timeout: float) -> tuple[str, str]:
    try:
        case.prepare(folder)
    except BaseException as error:  # a fault of the corpus, not of flexmbd
        return "internal", f"the case's inputs could not be written: {_describe(error)}"
    before = _snapshot(folder)
    fired = []

    def alarm(signum: int, frame: Any) -> None:
        fired.append(True)
        raise CaseTimeout(f"more than {timeout:g} s")

    previous = signal.signal(signal.SIGALRM, alarm)
    here = os.getcwd()
    os.chdir(folder)
    outcome, message = "ok", ""
    try:
        signal.setitimer(signal.ITIMER_REAL, timeout)
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                case.operate(folder)
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
        if case.must_fail:
            outcome, message = "wrong", "the input was accepted; it should have been refused"
    except CaseTimeout:
        outcome, message = "hang", f"ran more than {timeout:g} s"
    except corpus.WrongResult as error:
        outcome, message = "wrong", str(error)
    except BaseException as error:
        message = _describe(error)
        if fired:
            outcome, message = "hang", f"ran more than {timeout:g} s, then {message}"
        elif type(error).__name__ == "PanicException":
            outcome = "panic"
        elif _typed(error, case):
            outcome = "error" if _named(error, case) else "unnamed"
            garbled = _garbled(str(error))
            if outcome == "error" and garbled:
                outcome, message = "garbled", f"{garbled}: {message}"
        else:
            outcome = "internal"
            frames = traceback.extract_tb(error.__traceback__)[-3:]
            where = "; ".join(f"{Path(f.filename).name}:{f.lineno} {f.name}" for f in frames)
            message = f"{message} [at {where}]"
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
        os.chdir(here)
    if (folder / corpus.CODE_MARKER).exists():
        return "wrong", "code in the input was executed (it created a file)"
    after = _snapshot(folder)
    lost = [name for name, digest in before.items() if after.get(name) != digest]
    if lost:
        return "lost-file", f"input files changed or deleted: {lost}; then: {outcome} {message}"
    return outcome, message


def _limit_memory() -> None:
    try:
        import resource

        soft, hard = resource.getrlimit(resource.RLIMIT_AS)
        limit = MEMORY_LIMIT if hard == resource.RLIM_INFINITY else min(MEMORY_LIMIT, hard)
        resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
    except (ImportError, ValueError, OSError):
        pass


def serve(names: Sequence[str], seed: int, timeout: float, keep: Path | None = None) -> int:
    """Runs the named cases in this process, one JSON line each on the original stdout (the
    cases' own output, also that of C libraries, goes to stderr)."""
    import faulthandler

    faulthandler.enable()
    out = os.fdopen(os.dup(1), "w", buffering=1)
    os.dup2(2, 1)
    sys.stdout = sys.stderr
    _limit_memory()
    import flexmbd  # noqa: F401  (imported before the first case is timed)

    by_name = {case.name: case for case in corpus.all_cases(seed)}
    missing = [name for name in names if name not in by_name]
    if missing:
        raise SystemExit(f"unknown cases: {missing[:5]}")
    root = keep or Path(tempfile.mkdtemp(prefix="flexmbd-fuzz-"))
    root.mkdir(parents=True, exist_ok=True)
    try:
        for name in names:
            record = run_case(by_name[name], root, timeout)
            out.write(json.dumps(record) + "\n")
            out.flush()
    finally:
        if keep is None:
            shutil.rmtree(root, ignore_errors=True)
    return 0


def supervise(
    names: Sequence[str],
    seed: int,
    timeout: float = CASE_TIMEOUT,
    grace: float = KILL_GRACE,
) -> dict[str, dict[str, Any]]:
    """Runs the named cases in worker subprocesses, in order: a worker that dies, or that
    does not answer within `timeout` + `grace` seconds, is charged to the case it was
    running (``crash`` or ``hang``) and a new worker goes on with the next case."""
    results: dict[str, dict[str, Any]] = {}
    pending = list(names)
    # Everything the workers write (also what a killed worker leaves) is in one folder.
    with tempfile.TemporaryDirectory(prefix="flexmbd-fuzz-") as root:
        while pending:
            _supervise_worker(pending, results, seed, timeout, grace, root)
    return results


def _supervise_worker(
    pending: list[str],
    results: dict[str, dict[str, Any]],
    seed: int,
    timeout: float,
    grace: float,
    root: str,
) -> None:
    """Runs one worker on the `pending` cases, moving each done case to `results`; a case
    that kills the worker or that it does not finish in time is recorded and removed."""
    with tempfile.TemporaryFile() as log:
        command = [sys.executable, str(Path(__file__).resolve()), "--serve", "--seed", str(seed)]
        command += ["--timeout", str(timeout), *pending]
        process = subprocess.Popen(
            command,
            stdout=subprocess.PIPE,
            stderr=log,
            stdin=subprocess.DEVNULL,
            cwd=root,
            env={**os.environ, "TMPDIR": root},
            start_new_session=True,
            text=True,
        )
        lines: queue.Queue[str | None] = queue.Queue()

        def read(stream: Any = process.stdout, sink: queue.Queue = lines) -> None:
            for line in stream:
                sink.put(line)
            sink.put(None)

        reader = threading.Thread(target=read, daemon=True)
        reader.start()
        deadline = time.monotonic() + STARTUP + timeout + grace
        failure: tuple[str, str] | None = None
        while pending:
            try:
                line = lines.get(timeout=max(deadline - time.monotonic(), 0.01))
            except queue.Empty:
                os.killpg(process.pid, signal.SIGKILL)
                failure = ("hang", f"no answer in {timeout + grace:g} s: the worker was killed")
                break
            if line is None:
                break
            try:
                record = json.loads(line)
            except json.JSONDecodeError:
                continue
            if record.get("name") != pending[0]:
                continue
            results[record["name"]] = record
            pending.pop(0)
            deadline = time.monotonic() + timeout + grace
        process.wait()
        reader.join(timeout=5)
        process.stdout.close()
        log.seek(0)
        tail = log.read().decode("utf-8", "replace")[-1500:]
    if not pending:
        return
    if failure is None:
        signal_number = -process.returncode if process.returncode < 0 else None
        cause = (
            f"signal {signal.Signals(signal_number).name}"
            if signal_number
            else f"exit status {process.returncode}"
        )
        failure = ("crash", f"the worker died ({cause}); its last output: {tail}")
    name = pending.pop(0)
    results[name] = {
        "name": name,
        "family": name.split("/")[0],
        "kind": name.split("/")[2],
        "outcome": failure[0],
        "message": failure[1],
        "seconds": None,
    }


def _selected(args: argparse.Namespace, seed: int) -> list[str]:
    everything = corpus.cases(seed)
    if args.case:
        return list(args.case)
    chosen = [c for c in everything if not args.family or c.family in args.family]
    return [c.name for c in chosen]


def _summary(records: Iterable[dict[str, Any]]) -> str:
    counts: dict[str, dict[str, int]] = {}
    for record in records:
        family = counts.setdefault(record["family"], {})
        family[record["outcome"]] = family.get(record["outcome"], 0) + 1
    return "; ".join(f"{family}: {outcomes}" for family, outcomes in counts.items())


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("names", nargs="*", help=argparse.SUPPRESS)
    parser.add_argument("--family", action="append", choices=corpus.FAMILIES)
    parser.add_argument("--case", action="append", help="a case name (repeatable)")
    parser.add_argument("--seed", type=int, default=corpus.seed_from_environment())
    parser.add_argument("--timeout", type=float, default=CASE_TIMEOUT)
    parser.add_argument("--keep", type=Path, help="keep the inputs of the cases in this folder")
    parser.add_argument("--list", action="store_true", help="print the case names")
    parser.add_argument("--failures", action="store_true", help="print only failed cases")
    parser.add_argument("--supervised", action="store_true", help="run in worker processes")
    parser.add_argument("--serve", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.serve:
        return serve(args.names, args.seed, args.timeout)
    names = _selected(args, args.seed)
    if args.list:
        print("\n".join(names))
        return 0
    if args.supervised:
        records = list(supervise(names, args.seed, args.timeout).values())
    else:
        import flexmbd  # noqa: F401

        by_name = {case.name: case for case in corpus.all_cases(args.seed)}
        root = args.keep or Path(tempfile.mkdtemp(prefix="flexmbd-fuzz-"))
        root.mkdir(parents=True, exist_ok=True)
        records = []
        for name in names:
            record = run_case(by_name[name], root, args.timeout)
            records.append(record)
            if not args.failures or record["outcome"] not in GOOD:
                print(json.dumps(record), flush=True)
        if args.keep is None:
            shutil.rmtree(root, ignore_errors=True)
        print(_summary(records), file=sys.stderr)
        return 0 if all(r["outcome"] in GOOD for r in records) else 1
    for record in records:
        if not args.failures or record["outcome"] not in GOOD:
            print(json.dumps(record))
    print(_summary(records), file=sys.stderr)
    return 0 if all(r["outcome"] in GOOD for r in records) else 1


if __name__ == "__main__":
    sys.exit(main())
