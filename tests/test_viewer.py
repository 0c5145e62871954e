"""The interactive viewer (flexmbd.viewer): the page's data against the result, the options,
and the page itself in a real headless Chromium (DevTools protocol over a pipe): it loads
without JavaScript errors, draws something, and the frame slider changes the picture."""

from __future__ import annotations

import base64
import fcntl
import io
import json
import os
import select
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import check_close, run_example
from PIL import Image

import flexmbd as fm
from flexmbd.fe.stress import von_mises

pytest.importorskip("plotly", reason="the viewer needs plotly (pip install flexmbd[view])")


@pytest.fixture(scope="module")
def slider_crank() -> fm.Result:
    # A quarter of a crank turn: the rod is visibly bent.
    return run_example("flexible-slider-crank", 0.02, 1e-4)


@pytest.fixture(scope="module")
def tet_pendulum() -> fm.Result:
    return run_example("tetrahedral-pendulum", 0.2, 0.01)


@pytest.fixture(scope="module")
def four_bar() -> fm.Result:
    return run_example("four-bar", 0.5, 0.05)


def page_data(path: Path) -> dict:
    """The JSON data of a written page."""
    text = path.read_text(encoding="utf-8")
    start = text.index('<script id="flexmbd-data" type="application/json">')
    start = text.index(">", start) + 1
    return json.loads(text[start : text.index("</script>", start)])


def floats(text: str, shape: tuple[int, ...]) -> np.ndarray:
    return np.frombuffer(base64.b64decode(text), dtype="<f4").reshape(shape)


# The page's data --------------------------------------------------------------------------------
def test_page_holds_the_deformed_nodes_of_the_shown_records(slider_crank, tmp_path):
    path = fm.view(slider_crank, tmp_path / "crank.html", max_frames=50)
    data = page_data(path)
    (dataset,) = data["datasets"]
    records = np.unique(np.round(np.linspace(0, len(slider_crank.time) - 1, 50)).astype(int))
    check_close(dataset["times"], slider_crank.time[records], rel=1e-12, what="times")
    assert dataset["records"] == len(slider_crank.time) > 50
    assert f"Showing 50 of {len(slider_crank.time)} records" in path.read_text()
    assert dataset["colors"] == ["displacement", "none"]
    (part,) = dataset["parts"]
    n, k = part["count"], len(records)
    # What the page computes, R + A (u0 + u), against the result's own node positions.
    pose = floats(part["pose"], (k, 12)).astype(float)
    nodes = floats(part["nodes"], (n, 3)).astype(float)
    u = floats(part["u"], (k, n, 3)).astype(float)
    local = nodes[None] + u
    drawn = pose[:, None, :3] + np.einsum("tij,tnj->tni", pose[:, 3:].reshape(k, 3, 3), local)
    expected = slider_crank.node_positions("rod")[records]
    check_close(drawn, expected, abs=1e-6, what="node positions")
    assert np.max(np.linalg.norm(u, axis=2)) > 1e-4  # the rod is bent
    check_close(part["range"]["displacement"], np.max(np.linalg.norm(u, axis=2)), rel=1e-6)


def test_page_holds_the_von_mises_stress_of_a_solid(tet_pendulum, tmp_path):
    path = fm.view(tet_pendulum, tmp_path / "tet.html", color_by="stress")
    data = page_data(path)
    assert data["color"] == "stress"
    (dataset,) = data["datasets"]
    assert dataset["colors"] == ["displacement", "stress", "none"]
    (part,) = dataset["parts"]
    k = len(tet_pendulum.time)
    stress = floats(part["stress"], (k, part["count"]))
    expected = von_mises(tet_pendulum.stresses("arm").reshape(-1, 6)).reshape(k, -1)
    check_close(stress, expected, rel=1e-6, abs=1e-6 * expected.max(), what="von Mises")
    kinds = [entry["trace"]["type"] for entry in dataset["traces"]]
    assert kinds.count("mesh3d") == 1


def test_rigid_model_has_no_colours_and_draws_its_bodies(four_bar, tmp_path):
    path = fm.view(four_bar, tmp_path / "four_bar.html")
    (dataset,) = page_data(path)["datasets"]
    assert dataset["parts"] == [] and dataset["colors"] == ["none"]
    names = {entry["trace"]["name"] for entry in dataset["traces"]}
    assert {"rigid bodies", "body origins", "ground markers"} <= names
    # Five links: five origins, each with three axes.
    assert dataset["trackCount"] >= 5 * 4


def test_page_is_self_contained(four_bar, tmp_path):
    text = fm.view(four_bar, tmp_path / "page.html").read_text()
    assert "<script src=" not in text and "Plotly.react" in text
    assert len(text) > 3_000_000  # plotly.js itself


def test_unknown_options_are_refused(slider_crank, four_bar, tmp_path):
    with pytest.raises(fm.InvalidParameterError, match="'colour'.*known: 'displacement'"):
        fm.view(slider_crank, tmp_path / "a.html", color_by="colour")
    with pytest.raises(fm.InvalidParameterError, match="'stress' is not available"):
        fm.view(slider_crank, tmp_path / "a.html", color_by="stress")
    with pytest.raises(fm.InvalidParameterError, match="max_frames"):
        fm.view(four_bar, tmp_path / "a.html", max_frames=1)
    assert not (tmp_path / "a.html").exists()


def test_a_page_never_replaces_a_file_of_another_kind(tmp_path):
    # Regression: `flexmbd view run.h5 -o run.h5` wrote the page over the results file it
    # read, and any path was replaced (a .txt by HTML); a title or source of the wrong type
    # was an AttributeError.
    example = fm.examples.EXAMPLES["pendulum"]()
    results = tmp_path / "run.h5"
    fm.simulate(example.system, 0.1, 1e-2, results_file=results)
    notes = tmp_path / "notes.txt"
    notes.write_text("mine")
    for target in (results, notes, tmp_path):
        with pytest.raises(fm.InvalidParameterError, match="path: the viewer writes an HTML"):
            fm.view(results, target)
    assert notes.read_text() == "mine" and len(fm.read_results(results).time) == 11
    run = subprocess.run(
        [sys.executable, "-m", "flexmbd", "view", str(results), "-o", str(results)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 2 and "path: the viewer writes an HTML page" in run.stderr
    assert len(fm.read_results(results).time) == 11
    (tmp_path / "folder.html").mkdir()
    with pytest.raises(fm.InvalidParameterError, match="is a folder"):
        fm.view(results, tmp_path / "folder.html")
    with pytest.raises(fm.ArgumentTypeError, match="title: a text"):
        fm.view(results, tmp_path / "a.html", title=5)
    with pytest.raises(fm.ArgumentTypeError, match="source: a flexmbd.Result"):
        fm.view(None, tmp_path / "a.html")
    # The options of mode shapes were ignored for a result.
    with pytest.raises(fm.InvalidParameterError, match="modes: for the modes of a Linearized"):
        fm.view(results, tmp_path / "a.html", modes=3)
    assert fm.view(results, tmp_path / "page.HTML").exists()


def test_results_file_gives_the_default_page_name(four_bar, tmp_path):
    example = fm.examples.EXAMPLES["pendulum"]()
    results = tmp_path / "pendulum.h5"
    fm.simulate(example.system, 0.1, 1e-2, results_file=results)
    path = fm.view(results)
    assert path == results.with_suffix(".html")
    assert page_data(path)["title"] == "pendulum"


def test_modes_of_a_linearized_system(tmp_path):
    example = fm.examples.EXAMPLES["tetrahedral-pendulum"]()
    model = example.system.compile()
    linear = fm.linearize(model, fm.equilibrium(model))
    with pytest.raises(fm.InvalidParameterError, match="model="):
        fm.view(linear, tmp_path / "modes.html")
    path = fm.view(linear, tmp_path / "modes.html", model=model, modes=3, frames_per_period=12)
    data = page_data(path)
    frequencies = linear.frequencies()[:3]
    assert [d["name"] for d in data["datasets"]] == [
        f"mode {k + 1}: {f:.5g} Hz" for k, f in enumerate(frequencies)
    ]
    for dataset in data["datasets"]:
        assert dataset["phase"] and len(dataset["times"]) == 12
        assert "stress" in dataset["colors"]


def test_modes_of_rigid_models_with_position_sensors(tmp_path, assert_close):
    # A01's point mass (with a position sensor) and A02's links: their mode results have no
    # sensor records, and the page took the sensor's empty track (a ValueError); A01's mass
    # swings at sqrt(g / l) / (2 pi) in both directions.
    for name in ("pendulum", "four-bar"):
        model = fm.examples.EXAMPLES[name]().system.compile()
        linear = fm.linearize(model, fm.equilibrium(model))
        path = fm.view(linear, tmp_path / f"{name}.html", model=model, modes=1)
        assert len(page_data(path)["datasets"]) == 1
    assert_close(linear.frequencies()[0], 0.538428, rel=1e-5, what="A02's mode")
    model = fm.examples.pendulum().system.compile()
    swing = fm.linearize(model, fm.equilibrium(model)).frequencies()
    assert_close(swing, [np.sqrt(9.81) / (2 * np.pi)] * 2, rel=1e-9, what="A01's swing")


def test_command_line_writes_the_page(tmp_path):
    example = fm.examples.EXAMPLES["pendulum"]()
    results = tmp_path / "run.h5"
    fm.simulate(example.system, 0.1, 1e-2, results_file=results)
    env = dict(os.environ, PYTHONPATH=str(Path(fm.__file__).parents[1]))
    out = subprocess.run(
        [sys.executable, "-m", "flexmbd", "view", str(results), "-o", str(tmp_path / "v.html")],
        capture_output=True,
        text=True,
        env=env,
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.startswith(f"written: {tmp_path / 'v.html'} (") and "MB)" in out.stdout
    bad = subprocess.run(
        [sys.executable, "-m", "flexmbd", "view", "pendulum"],
        capture_output=True,
        text=True,
        env=env,
    )
    assert bad.returncode == 2 and "--modes" in bad.stderr


# The page in a browser --------------------------------------------------------------------------
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
browser_only = pytest.mark.skipif(
    CHROMIUM is None, reason="no chromium here (CI installs it: apt-get install chromium)"
)


class Browser:
    """Headless Chromium driven through the DevTools protocol on a pipe (fds 3 and 4 of the
    browser: NUL-terminated JSON messages)."""

    def __init__(self) -> None:
        to_browser, self._writer = os.pipe()
        self._reader, from_browser = os.pipe()
        # Out of the way of 3 and 4, which the child needs.
        high = [fcntl.fcntl(fd, fcntl.F_DUPFD, 20) for fd in (to_browser, from_browser)]
        for fd in (to_browser, from_browser):
            os.close(fd)

        def pipes() -> None:
            os.dup2(high[0], 3)
            os.dup2(high[1], 4)

        self.process = subprocess.Popen(
            [
                CHROMIUM,
                "--headless",
                "--remote-debugging-pipe",
                "--no-sandbox",
                "--no-first-run",
                "--disable-gpu",
                "--enable-unsafe-swiftshader",
                "--hide-scrollbars",
                f"--user-data-dir={os.environ.get('TMPDIR', '/tmp')}/flexmbd-viewer-{os.getpid()}",
                "about:blank",
            ],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            pass_fds=(3, 4),
            preexec_fn=pipes,
        )
        for fd in high:
            os.close(fd)
        self._buffer = b""
        self._next = 0
        self.events: list[dict] = []
        target = self.call("Target.createTarget", url="about:blank")["targetId"]
        self.session = self.call("Target.attachToTarget", targetId=target, flatten=True)[
            "sessionId"
        ]
        for domain in ("Runtime", "Log", "Page"):
            self.call(f"{domain}.enable", session=True)
        self.call(
            "Emulation.setDeviceMetricsOverride",
            session=True,
            width=900,
            height=650,
            deviceScaleFactor=1,
            mobile=False,
        )

    def _message(self, timeout: float) -> dict:
        deadline = time.monotonic() + timeout
        while b"\0" not in self._buffer:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([self._reader], [], [], left)[0]:
                raise TimeoutError("chromium did not answer")
            chunk = os.read(self._reader, 1 << 20)
            if not chunk:
                raise RuntimeError("chromium closed the pipe")
            self._buffer += chunk
        text, self._buffer = self._buffer.split(b"\0", 1)
        return json.loads(text)

    def call(self, method: str, session: bool = False, timeout: float = 30.0, **params) -> dict:
        self._next += 1
        message = {"id": self._next, "method": method, "params": params}
        if session:
            message["sessionId"] = self.session
        os.write(self._writer, json.dumps(message).encode() + b"\0")
        while True:
            answer = self._message(timeout)
            if answer.get("id") == self._next:
                if "error" in answer:
                    raise RuntimeError(f"{method}: {answer['error']}")
                return answer.get("result", {})
            self.events.append(answer)

    def evaluate(self, expression: str):
        answer = self.call(
            "Runtime.evaluate", session=True, expression=expression, returnByValue=True
        )
        return answer["result"].get("value")

    def wait_for(self, expression: str, timeout: float = 20.0) -> None:
        deadline = time.monotonic() + timeout
        while not self.evaluate(expression):
            if time.monotonic() > deadline:
                raise TimeoutError(f"{expression} stayed false; errors: {self.errors()}")
            time.sleep(0.05)

    def open(self, url: str) -> None:
        # From a blank page, so that a new hash of the same page loads it anew.
        self.call("Page.navigate", session=True, url="about:blank")
        self.wait_for("window.flexmbdViewer === undefined")
        self.events.clear()
        self.call("Page.navigate", session=True, url=url)
        self.wait_for(
            "document.readyState === 'complete' && window.flexmbdViewer !== undefined"
            " && window.flexmbdViewer.ready"
        )

    def errors(self) -> list[str]:
        """Uncaught exceptions, console.error/assert calls and error log entries so far."""
        found = []
        for event in self.events:
            method, params = event.get("method"), event.get("params", {})
            if method == "Runtime.exceptionThrown":
                details = params["exceptionDetails"]
                found.append(details.get("exception", {}).get("description", details["text"]))
            elif method == "Runtime.consoleAPICalled" and params["type"] in ("error", "assert"):
                values = (a.get("value", a.get("description")) for a in params["args"])
                found.append(" ".join(map(str, values)))
            elif method == "Log.entryAdded" and params["entry"]["level"] == "error":
                found.append(params["entry"]["text"])
        return found

    def screenshot(self) -> np.ndarray:
        # Two animation frames so that WebGL has presented the last redraw.
        self.evaluate("new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
        png = base64.b64decode(self.call("Page.captureScreenshot", session=True)["data"])
        return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=float)

    def close(self) -> None:
        try:
            self.call("Browser.close", timeout=5.0)
        except (TimeoutError, RuntimeError):
            pass
        try:
            self.process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        os.close(self._writer)
        os.close(self._reader)
        shutil.rmtree(
            f"{os.environ.get('TMPDIR', '/tmp')}/flexmbd-viewer-{os.getpid()}", ignore_errors=True
        )


@pytest.fixture(scope="module")
def browser():
    if CHROMIUM is None:
        pytest.skip("no chromium here (CI installs it: apt-get install chromium)")
    browser = Browser()
    yield browser
    browser.close()


def plot_region(image: np.ndarray) -> np.ndarray:
    """The pixels below the controls (the 3D scene and its colour bar)."""
    return image[80:-40]


@browser_only
def test_page_loads_without_errors_and_draws_the_mechanism(browser, slider_crank, tmp_path):
    path = fm.view(slider_crank, tmp_path / "crank.html")
    browser.open(path.as_uri())
    assert browser.errors() == []
    assert browser.evaluate("document.querySelectorAll('#flexmbd-plot canvas').length") > 0
    image = plot_region(browser.screenshot())
    assert image.std() > 5.0
    assert len(np.unique(image.reshape(-1, 3), axis=0)) > 50
    # The colour bar's viridis yellow is there: the rod is coloured.
    assert np.any(np.all(np.abs(image - [253, 231, 37]) < 30, axis=2))


@browser_only
def test_a_javascript_error_in_the_page_is_caught(browser, four_bar, tmp_path):
    path = fm.view(four_bar, tmp_path / "broken.html")
    text = path.read_text().replace("</body>", "<script>notAFunctionOfThePage();</script></body>")
    path.write_text(text)
    browser.open(path.as_uri())
    errors = browser.errors()
    assert len(errors) == 1 and "ReferenceError: notAFunctionOfThePage" in errors[0]
    browser.evaluate("console.error('deliberate')")
    assert browser.errors()[-1] == "deliberate"


@browser_only
def test_moving_the_slider_changes_the_picture(browser, tet_pendulum, tmp_path):
    path = fm.view(tet_pendulum, tmp_path / "tet.html", color_by="stress")
    last = len(tet_pendulum.time) - 1
    browser.open(path.as_uri())
    first = plot_region(browser.screenshot())
    assert first.std() > 5.0
    # Drag the slider: set its value and send the input event a user's drag sends.
    rendered = browser.evaluate("flexmbdViewer.rendered")
    browser.evaluate(
        f"const s = document.getElementById('flexmbd-frame'); s.value = {last};"
        "s.dispatchEvent(new Event('input'));"
    )
    browser.wait_for(f"flexmbdViewer.rendered > {rendered} && flexmbdViewer.state.frame == {last}")
    moved = plot_region(browser.screenshot())
    changed = np.mean(np.any(np.abs(moved - first) > 30, axis=2))
    assert changed > 0.002, f"only {changed:.2%} of the pixels changed"
    assert browser.evaluate("document.getElementById('flexmbd-time').textContent").startswith(
        f"t = {tet_pendulum.time[-1]:.6g}"
    )
    # The URL's frame opens the same picture.
    browser.open(path.as_uri() + f"#frame={last}&color=stress")
    again = plot_region(browser.screenshot())
    assert np.mean(np.any(np.abs(again - moved) > 30, axis=2)) < 0.2 * changed
    # Play runs on from the last frame to the first ones, pause stops.
    browser.evaluate("document.getElementById('flexmbd-play').click()")
    browser.wait_for(f"flexmbdViewer.state.frame > 0 && flexmbdViewer.state.frame < {last}")
    browser.evaluate("document.getElementById('flexmbd-play').click()")
    assert not browser.evaluate("flexmbdViewer.state.playing")
    assert browser.errors() == []
