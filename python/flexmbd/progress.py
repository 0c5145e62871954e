"""Progress displays of long tasks: simulations, rendered animations, written files.

* :class:`ProgressBar`: one display of a task's progress (a fraction, a detail text, the
  elapsed and the estimated remaining wall time) in one of three styles: ``"terminal"``
  redraws one line with carriage returns (a terminal; a notebook without ipywidgets),
  ``"lines"`` writes a plain line at every tenth of the task and at its end (a pipe, a log
  file, a batch job's output), ``"widget"`` shows an ipywidgets bar in a Jupyter notebook.
  ``"auto"`` (the default) chooses by where it runs.
* :class:`SimulationProgress`: the ``progress(time, step_size, newton_iterations)`` callable
  of :func:`flexmbd.simulate` behind ``progress=True``: simulated time of end time, step
  number, step size and Newton iterations of the last step.
* :func:`track`: a loop over frames or files with a bar (``progress=True``) or a callable
  ``progress(done, total)``.
* :func:`status`: a line "label ... 3 s" kept alive on a terminal while a task without
  steps of its own runs (a plot).

A display that fails (a closed stream, a widget error) switches itself off with one warning
of the ``"flexmbd.progress"`` logger: a progress display never stops the task it shows. A
callable given by the user is not guarded that way: its exception stops the task (in
:func:`flexmbd.simulate` as a :class:`flexmbd.CallbackError` that keeps the results).

Nothing heavy is imported here: ipywidgets only when a notebook asks for a widget.
"""

from __future__ import annotations

import logging
import math
import shutil
import sys
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from typing import IO, Any, TypeVar

logger = logging.getLogger("flexmbd.progress")

#: The display styles; "auto" chooses one of the others.
STYLES = ("auto", "terminal", "lines", "widget")

#: Seconds between two redraws of a terminal line or a widget (the simulation calls its
#: progress function about ten times a second).
REDRAW_INTERVAL = 0.1

#: Characters of the bar of the "terminal" style.
BAR_WIDTH = 12

T = TypeVar("T")


def duration(seconds: float) -> str:
    """A wall time for people: "4.2 s", "1:05" (min:s), "2:01:05" (h:min:s), "?" if unknown."""
    if not math.isfinite(seconds) or seconds < 0:
        return "?"
    if seconds < 60:
        return f"{seconds:.1f} s"
    whole = int(round(seconds))
    hours, rest = divmod(whole, 3600)
    minutes, secs = divmod(rest, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}" if hours else f"{minutes}:{secs:02d}"


def in_notebook() -> bool:
    """True inside a Jupyter kernel (IPython with a kernel; not a terminal IPython)."""
    module = sys.modules.get("IPython")  # imported by the kernel: never imported here
    if module is None:
        return False
    try:
        shell = module.get_ipython()
    except Exception:  # noqa: BLE001 - an odd IPython: no notebook
        return False
    return shell is not None and getattr(shell, "kernel", None) is not None


def _widgets_available() -> bool:
    from importlib.util import find_spec

    return find_spec("ipywidgets") is not None


def _is_terminal(stream: IO[str]) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):
        return False


class ProgressBar:
    """A display of the progress of one task.

    ``label``: what runs ("simulating", "rendering x.gif"). ``stream``: where the text goes
    (default: ``sys.stderr`` when the bar is made). ``style``: one of :data:`STYLES`;
    ``"auto"`` takes ``"widget"`` in a Jupyter notebook with ipywidgets installed (when no
    stream is given), ``"terminal"`` on a terminal or in a notebook without ipywidgets, and
    ``"lines"`` elsewhere. ``every``: the fraction between two lines of the ``"lines"``
    style (default a tenth).

    :meth:`update` gives the fraction done (0 .. 1) and a detail text; :meth:`close` ends
    the display with its final state (a terminal line is kept, ended by a newline).
    The remaining time is the elapsed time times (1 - fraction) / fraction."""

    def __init__(
        self,
        label: str = "",
        *,
        stream: IO[str] | None = None,
        style: str = "auto",
        every: float = 0.1,
    ):
        if style not in STYLES:
            raise ValueError(f"style must be one of {STYLES}, got {style!r}")
        if not 0 < every <= 1:
            raise ValueError(f"every must be in (0, 1], got {every!r}")
        self.label = label
        self.stream: IO[str] = sys.stderr if stream is None else stream
        if style == "auto":
            if in_notebook():
                style = "widget" if stream is None and _widgets_available() else "terminal"
            else:
                style = "terminal" if _is_terminal(self.stream) else "lines"
        self.style = style
        self.every = every
        self.began = time.perf_counter()
        self.fraction = 0.0
        self.detail = ""
        self.closed = False
        self.failed: BaseException | None = None
        self._drawn_at = -math.inf
        self._width = 0  # characters of the terminal line shown now (0: none)
        self._step = -1  # the last tenth written by the "lines" style
        self._widget: Any = None
        self._lock = threading.Lock()

    # The display itself never stops the task: its failures switch it off.
    def _guarded(self, draw: Callable[[], None]) -> None:
        if self.failed is not None:
            return
        try:
            with self._lock:
                draw()
        except Exception as error:  # noqa: BLE001 - any failure of a display
            self.failed = error
            logger.warning(
                "progress display of %r switched off: %s: %s",
                self.label,
                type(error).__name__,
                error,
            )

    def elapsed(self) -> float:
        """Wall time since the bar was made (s)."""
        return time.perf_counter() - self.began

    def remaining(self) -> float:
        """Estimated wall time to the end (s; NaN before any progress)."""
        if self.fraction <= 0:
            return math.nan
        return self.elapsed() * (1.0 - self.fraction) / self.fraction

    def text(self, *, bar: bool = True) -> str:
        """The line shown: label, percentage, bar, elapsed and remaining time, detail."""
        parts = [self.label] if self.label else []
        percent = f"{100 * self.fraction:3.0f}%"
        if bar:
            filled = int(BAR_WIDTH * self.fraction)
            percent += f" [{'#' * filled}{'.' * (BAR_WIDTH - filled)}]"
        parts.append(percent)
        # The times before the detail: a line cut to the terminal's width keeps them.
        times = f"{duration(self.elapsed())} elapsed"
        if not self.closed:
            times += f", {duration(self.remaining())} left"
        parts.append(times)
        if self.detail:
            parts.append(self.detail)
        return "  ".join(parts)

    def update(self, fraction: float, detail: str = "", *, force: bool = False) -> None:
        """Shows `fraction` (clipped to 0 .. 1) done and `detail`; a terminal or widget is
        redrawn at most every :data:`REDRAW_INTERVAL` s unless `force`."""
        if self.closed:
            return
        self.fraction = min(1.0, max(0.0, float(fraction))) if fraction == fraction else 0.0
        self.detail = detail
        self._guarded(lambda: self._draw(force))

    def _draw(self, force: bool) -> None:
        now = time.perf_counter()
        if self.style == "lines":
            # A line at each `every` of the task; the last one is written by close.
            step = int(self.fraction / self.every + 1e-9)
            if (step > self._step or force) and self.fraction < 1.0:
                self._step = step
                self.stream.write(self.text(bar=False) + "\n")
                self.stream.flush()
            return
        if not force and now - self._drawn_at < REDRAW_INTERVAL:
            return
        self._drawn_at = now
        if self.style == "widget":
            self._draw_widget()
            return
        line = self._line()
        self.stream.write("\r" + line + " " * max(0, self._width - len(line)))
        self.stream.flush()
        self._width = len(line)

    def _line(self) -> str:
        """The terminal line, cut to the terminal's width: a wrapped line cannot be redrawn."""
        columns = shutil.get_terminal_size((100, 24)).columns
        return self.text()[: max(columns - 1, 20)]

    def _draw_widget(self) -> None:
        if self._widget is None:
            import ipywidgets
            from IPython.display import display

            bar = ipywidgets.FloatProgress(value=0.0, min=0.0, max=1.0, description=self.label)
            label = ipywidgets.Label()
            self._widget = (bar, label)
            display(ipywidgets.HBox([bar, label]))
        bar, label = self._widget
        bar.value = self.fraction
        label.value = self.text(bar=False)[len(self.label) :].strip()

    def clear(self) -> None:
        """Erases the terminal line (before other output to the same terminal); the next
        update draws it again."""
        if self.style != "terminal" or not self._width or self.failed is not None:
            return

        def erase() -> None:
            self.stream.write("\r" + " " * self._width + "\r")
            self.stream.flush()
            self._width = 0
            self._drawn_at = -math.inf

        self._guarded(erase)

    def close(self, detail: str | None = None, *, failed: bool = False) -> None:
        """Ends the display, showing `detail` (default: the last one) with the elapsed
        time; `failed` marks a task that stopped early (a red widget). Idempotent."""
        if self.closed:
            return
        self.closed = True
        if detail is not None:
            self.detail = detail

        def end() -> None:
            if self.style == "lines":
                self.stream.write(self.text(bar=False) + "\n")
            elif self.style == "widget":
                self._draw_widget()
                self._widget[0].bar_style = "danger" if failed else "success"
                return
            else:
                line = self._line()
                self.stream.write("\r" + line + " " * max(0, self._width - len(line)) + "\n")
                self._width = 0
            self.stream.flush()

        self._guarded(end)


class SimulationProgress:
    """The progress function ``progress(time, step_size, newton_iterations)`` of
    :func:`flexmbd.simulate` with a :class:`ProgressBar`: simulated time of the end time,
    step number, step size, Newton iterations of the last step (left out for explicit
    solvers), elapsed and remaining wall time.

    ``simulate(..., progress=True)`` makes one; give one yourself to choose the stream or the
    style: ``simulate(..., progress=SimulationProgress(stream=f, style="lines"))`` (the start
    and end times then come from ``simulate``); one display per run. The step number comes
    from the records of the run as they are delivered (about ten times a second); at the end
    the totals of the run."""

    def __init__(
        self,
        start_time: float | None = None,
        end_time: float | None = None,
        *,
        label: str = "simulating",
        stream: IO[str] | None = None,
        style: str = "auto",
        every: float = 0.1,
    ):
        self.start_time, self.end_time = start_time, end_time
        self.bar = ProgressBar(label, stream=stream, style=style, every=every)
        #: Accepted steps so far, where known.
        self.steps: int | None = None
        self.time = start_time
        self.step_size = math.nan
        self.newton_iterations = 0
        self._implicit = False

    def __call__(self, time: float, step_size: float, newton_iterations: int) -> None:
        self.time, self.step_size = float(time), float(step_size)
        self.newton_iterations = int(newton_iterations)
        self._implicit |= self.newton_iterations > 0
        self.bar.update(self._fraction(), self._detail())

    def begin(self, start_time: float) -> None:
        """Starts the clock and shows the bar (a terminal or widget; nothing on "lines");
        `start_time`: that of the run unless one was given."""
        if self.start_time is None:
            self.start_time = self.time = start_time
        self.bar.began = time.perf_counter()
        if self.bar.style != "lines":
            self.bar.update(0.0, self._detail(), force=True)

    def _fraction(self) -> float:
        start, end, t = self.start_time, self.end_time, self.time
        if start is None or end is None or t is None:
            return 0.0
        return (t - start) / (end - start) if end > start else 1.0

    def _detail(self) -> str:
        end = "?" if self.end_time is None else f"{self.end_time:.6g}"
        t = "?" if self.time is None else f"{self.time:.6g}"
        parts = [f"t = {t}/{end} s"]
        if self.steps is not None:
            parts.append(f"step {self.steps}")
        if math.isfinite(self.step_size):
            parts.append(f"h = {self.step_size:.3g} s")
        if self._implicit:
            parts.append(f"{self.newton_iterations} Newton it")
        return "  ".join(parts)

    def clear(self) -> None:
        """Erases a terminal line before other output (log records)."""
        self.bar.clear()

    def finish(self, result: Any) -> None:
        """Ends the display with the run's totals (`result`: the run's :class:`Result`)."""
        stats = getattr(result, "statistics", None) or {}
        if len(getattr(result, "time", ())):
            self.time = float(result.time[-1])
        steps = int(stats.get("steps", self.steps or 0))
        parts = [f"t = {self.time:.6g}/{self.end_time:.6g} s", f"{steps} steps"]
        if stats.get("rejected_steps"):
            parts.append(f"{stats['rejected_steps']} rejected")
        if stats.get("function_evaluations"):
            parts.append(f"{stats['function_evaluations']} function evaluations")
        elif stats.get("newton_iterations"):
            parts.append(f"{stats['newton_iterations'] / max(steps, 1):.2f} Newton it/step")
        failed = getattr(result, "error", None) is not None
        if failed:
            parts.append(f"stopped: {type(result.error).__name__}")
        self.bar.fraction = self._fraction() if failed else 1.0
        self.bar.close("  ".join(parts), failed=failed)

    def close(self) -> None:
        """Ends the display as it is (a run that ended without a result)."""
        self.bar.close(failed=True)


def simulation_progress(
    progress: Any, end_time: float
) -> tuple[Callable[[float, float, int], object] | None, SimulationProgress | None]:
    """What :func:`flexmbd.simulate` does with its ``progress`` argument: (the function the
    run calls, the display to finish; either None). None or False: nothing; True: a
    :class:`SimulationProgress`; a :class:`SimulationProgress`: that one, its missing end
    time filled in (the start time is set by :meth:`SimulationProgress.begin`); another
    callable: called as given."""
    from .errors import InvalidParameterError

    if progress is None or progress is False:
        return None, None
    if progress is True:
        display = SimulationProgress(None, end_time)
        return display, display
    if isinstance(progress, SimulationProgress):
        if progress.end_time is None:
            progress.end_time = end_time
        return progress, progress
    if callable(progress):
        return progress, None
    raise InvalidParameterError(
        f"progress must be True, False, None or a function progress(time, step_size, "
        f"newton_iterations), got {type(progress).__name__}",
        item="progress",
    )


def track(
    items: Sequence[T] | Iterable[T],
    progress: bool | Callable[[int, int], object] | None,
    label: str,
    *,
    total: int | None = None,
    unit: str = "",
) -> Iterator[T]:
    """Yields `items`, showing the progress: `progress` True shows a :class:`ProgressBar`
    ("label  40% [...]  24 of 60 frames ..."), a callable is called as ``progress(done,
    total)`` after each item, None or False shows nothing. `total` defaults to
    ``len(items)``."""
    if total is None:
        total = len(items)  # type: ignore[arg-type]
    if progress is None or progress is False:
        return iter(items)
    if progress is not True and not callable(progress):
        from .errors import InvalidParameterError

        raise InvalidParameterError(
            f"progress must be True, False, None or a function progress(done, total), got "
            f"{type(progress).__name__}",
            item="progress",
        )
    return _tracked(items, progress, label, total, unit)


def _tracked(
    items: Iterable[T],
    progress: bool | Callable[[int, int], object],
    label: str,
    total: int,
    unit: str,
) -> Iterator[T]:
    bar = ProgressBar(label) if progress is True else None
    done = 0
    suffix = f" {unit}" if unit else ""
    try:
        if bar is not None:
            bar.update(0.0, f"0 of {total}{suffix}", force=True)
        for item in items:
            yield item
            done += 1
            if bar is not None:
                bar.update(done / max(total, 1), f"{done} of {total}{suffix}")
            else:
                progress(done, total)  # type: ignore[operator]
    finally:
        if bar is not None:
            bar.close(f"{done} of {total}{suffix}", failed=done < total)


@contextmanager
def status(label: str, *, enabled: bool = True, stream: IO[str] | None = None) -> Iterator[None]:
    """Keeps "label ... 2.5 s" alive on a terminal while the block runs (redrawn from a
    thread every quarter second, erased at the end), so that a task without steps of its
    own never leaves a silent terminal. Shows nothing when not `enabled`, on a stream that
    is not a terminal, or in a notebook."""
    out: IO[str] = sys.stderr if stream is None else stream
    if not enabled or not _is_terminal(out) or in_notebook():
        yield
        return
    began = time.perf_counter()
    done = threading.Event()
    width = 0

    def draw() -> None:
        nonlocal width
        while not done.wait(0.25):
            line = f"{label} ... {duration(time.perf_counter() - began)}"
            try:
                out.write("\r" + line + " " * max(0, width - len(line)))
                out.flush()
            except Exception:  # noqa: BLE001 - a display that fails stays silent
                return
            width = len(line)

    thread = threading.Thread(target=draw, name="flexmbd-status", daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()
        thread.join()
        if width:
            try:
                out.write("\r" + " " * width + "\r")
                out.flush()
            except Exception:  # noqa: BLE001
                pass
