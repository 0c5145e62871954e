"""The interactive viewer: one self-contained HTML page of a result, opened in any browser.

:func:`view` writes the moving, deforming mechanism of a :class:`flexmbd.Result` (or of a
results file, or the mode shapes of a :class:`flexmbd.LinearizedSystem`) into an HTML file
that needs no server and no network: plotly.js (the ``plotly`` package,
``pip install flexmbd[view]``) is inlined and draws the 3D scene with WebGL. The page has a
time slider, play/pause and a speed choice, the deformation scale, the colour quantity
(elastic displacement magnitude or von Mises stress, with a colour bar) and, for mode shapes,
a choice of the mode. See ``docs/viewer.md``.

What is drawn is what :mod:`flexmbd.animation` draws (its :class:`~flexmbd.animation.Scene`
is reused): deformable bodies as their meshes (solids as their boundary faces with their
edges, beams as lines through their nodes), rigid bodies as their origin, their axes and lines
to their joint markers, joints as their markers and the lines between them.

The data in the page
--------------------
For every shown record the page holds each deformable body's pose (origin R and rotation A)
and the elastic displacements u of its nodes in body axes, and computes the drawn node
positions R + A (u0 + s u) itself, so that the deformation scale s can be changed in the page.
Rigid-body points (origins, axes, markers) are stored as global positions. Arrays are stored
as little-endian float32 in base64. At most `max_frames` records are stored (spread evenly
over the run; the page says how many of how many).
"""

from __future__ import annotations

import base64
import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .errors import ArgumentTypeError, InvalidParameterError

Array = NDArray[np.float64]

#: Default largest number of records stored in a page.
MAX_FRAMES = 200
#: Colour quantities of the page, by name; "none" draws the bodies in plain colours.
COLOR_QUANTITIES = ("displacement", "stress", "none")
#: Titles of the colour bars.
COLOR_TITLES = {
    "displacement": "elastic displacement |u<sub>f</sub>| (m)",
    "stress": "von Mises stress (Pa)",
}
#: Meshes with more boundary edges than this are drawn without their edges.
EDGE_LIMIT = 20000
#: Length of the drawn axes of rigid bodies, as a fraction of the model size.
AXIS_FRACTION = 0.06
#: Default number of modes shown of a linearized system.
MODE_COUNT = 6
#: Frames per period of an animated mode shape.
FRAMES_PER_PERIOD = 24
#: Size of the equal axes' box in plotly's scene units (the zoom of the orthographic camera).
ZOOM = 1.6
#: Plain colours of the bodies when no quantity is shown.
PLAIN_COLORS = {"mesh3d": "#b0c4de", "scatter3d": "#1f77b4"}


def view(
    source: Any,
    path: str | os.PathLike[str] | None = None,
    *,
    model: Any = None,
    max_frames: int = MAX_FRAMES,
    scale: float | str | None = None,
    color_by: str = "displacement",
    modes: int = MODE_COUNT,
    frames_per_period: int = FRAMES_PER_PERIOD,
    title: str | None = None,
) -> Path:
    """Writes the interactive viewer page of `source` and returns its path.

    `source`: a :class:`flexmbd.Result`, the path of a results file (``.h5``), or a
    :class:`flexmbd.LinearizedSystem` (then `model`, the :class:`flexmbd.System` or
    :class:`flexmbd.Model` it was linearized from, is needed): its first `modes` oscillating
    modes, each animated over one period of `frames_per_period` frames, chosen in the page.

    `path`: the HTML file (default: the results file with the suffix ``.html``, or
    ``flexmbd-view.html`` in the working directory). `max_frames`: the largest number of
    records stored (spread evenly over the run, the first and last included). `scale`: the
    initial deformation scale (None or ``"auto"``: the largest displacement is drawn at 10 %
    of the model size, see :mod:`flexmbd.animation`); the page can change it. `color_by`:
    the initial colour quantity, ``"displacement"`` (|u_f|, m), ``"stress"`` (von Mises, Pa;
    only where a deformable body has solid elements) or ``"none"``.

    Needs the ``plotly`` package (``pip install flexmbd[view]``). Raises
    :class:`flexmbd.InvalidParameterError` for unknown options and an empty result."""
    from .analysis import LinearizedSystem
    from .result import Result

    if not isinstance(source, LinearizedSystem | Result | str | os.PathLike):
        raise ArgumentTypeError(
            "source: a flexmbd.Result, a results file path or a LinearizedSystem, got "
            f"{type(source).__name__}",
            item="source",
        )
    if title is not None and not isinstance(title, str):
        raise ArgumentTypeError(
            f"title: a text, got {type(title).__name__} {title!r}", item="title"
        )
    default = Path("flexmbd-view.html")
    if isinstance(source, str | os.PathLike):
        default = Path(source).with_suffix(".html")
    elif isinstance(source, Result) and getattr(source, "file", None) is not None:
        default = Path(source.file).with_suffix(".html")
    out = _page_path(path, default)  # (refused before any work)
    if color_by not in COLOR_QUANTITIES:
        raise InvalidParameterError(
            f"unknown colour quantity {color_by!r}; known: "
            + ", ".join(map(repr, COLOR_QUANTITIES)),
            item=str(color_by),
        )
    for name, value in (("max_frames", max_frames), ("frames_per_period", frames_per_period)):
        if not isinstance(value, int | np.integer) or isinstance(value, bool) or value < 2:
            raise InvalidParameterError(
                f"{name} must be an integer of at least 2, got {value!r}", item=name
            )
    if isinstance(source, LinearizedSystem):
        datasets = _mode_datasets(source, model, modes, frames_per_period, scale)
        heading = title or "mode shapes"
    else:
        given = [
            name
            for name, value, unset in (
                ("model", model, None),
                ("modes", modes, MODE_COUNT),
                ("frames_per_period", frames_per_period, FRAMES_PER_PERIOD),
            )
            if value is not unset and value != unset
        ]
        if given:  # (they were ignored without a word)
            raise InvalidParameterError(
                f"{', '.join(given)}: for the modes of a LinearizedSystem, not a result",
                item=given[0],
            )
        if isinstance(source, str | os.PathLike):
            from .results_file import read_results

            heading = title or Path(source).stem
            source = read_results(source)
        else:
            heading = title or "flexmbd result"
        datasets = [_dataset(source, heading, int(max_frames), scale, phase=False)]
    available = [q for q in COLOR_QUANTITIES if any(q in d["colors"] for d in datasets)]
    if color_by == "stress" and "stress" not in available:
        raise InvalidParameterError(
            "colour quantity 'stress' is not available: no deformable body has solid elements; "
            f"available: {', '.join(map(repr, available))}",
            item="stress",
        )
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(_page(heading, datasets, color_by), encoding="utf-8")
    return out


def _page_path(path: Any, default: Path) -> Path:
    """The HTML file to write: an ``.html`` or ``.htm`` path that is not a folder (a page
    written over a results file, `flexmbd view run.h5 -o run.h5`, destroyed the run)."""
    out = Path(path) if path is not None else default
    if out.suffix.lower() not in (".html", ".htm"):
        raise InvalidParameterError(
            f"path: the viewer writes an HTML page, a path ending in .html, got '{out}' (a file "
            "of another kind is not replaced)",
            item="path",
        )
    if out.is_dir():
        raise InvalidParameterError(f"path: '{out}' is a folder", item="path")
    return out


# Data of one animation ---------------------------------------------------------------------
def _floats(array: Any) -> str:
    """An array as base64 of its little-endian float32 values (row-major)."""
    return base64.b64encode(np.ascontiguousarray(array, dtype="<f4").tobytes()).decode("ascii")


def _gaps(segments: list[tuple[int, int]]) -> list[int]:
    """Point indices of line segments, each followed by -1 (a gap)."""
    return [index for a, b in segments for index in (a, b, -1)]


def _dataset(
    result: Any,
    name: str,
    max_frames: int,
    scale: float | str | None,
    *,
    phase: bool,
) -> dict[str, Any]:
    """The page's data of one animation of `result`: the points per frame and the traces
    drawn through them (plotly trace dicts with a list of point indices, -1 for gaps)."""
    from .animation import (
        _boundary_faces,
        _scale_value,
        _spread,
        _view_angles,
        build_scene,
    )

    scene = build_scene(result)
    records = _spread(len(result.time), max_frames)
    count = len(records)
    bodies = result.layout["bodies"]
    marker_entries = result.layout["markers"]
    factor = _scale_value(scene, scale, records)

    # Deformable bodies: poses, undeformed nodes and elastic displacements (body axes).
    parts: list[dict[str, Any]] = []
    offsets: dict[int, int] = {}
    offset = 0
    base: list[Array] = []  # (k, points, 3) positions at scale 0, for the box of the view
    deformed: list[Array] = []  # (k, nodes, 3) at the initial scale, for the view direction
    largest = 0.0
    colors = ["none"]
    if scene.parts:
        colors.insert(0, "displacement")
    for part in scene.parts:
        position, rotation = scene.pose(part.body, records)
        u = scene.displacements(part, records)
        pose = np.concatenate([position, rotation.reshape(count, 9)], axis=1)
        entry: dict[str, Any] = {
            "name": part.name,
            "nodes": _floats(part.data.nodes),
            "count": len(part.data.nodes),
            "pose": _floats(pose),
            "u": _floats(u),
            "offset": offset,
        }
        magnitude = np.linalg.norm(u, axis=2)
        entry["range"] = {"displacement": float(magnitude.max()) if magnitude.size else 0.0}
        largest = max(largest, entry["range"]["displacement"])
        if part.has_solids:
            von_mises = result.von_mises(part.body, records).reshape(-1)
            entry["stress"] = _floats(von_mises.reshape(count, -1))
            entry["range"]["stress"] = float(von_mises.max()) if von_mises.size else 0.0
            if "stress" not in colors:
                colors.insert(1, "stress")
        offsets[part.body] = offset
        offset += entry["count"]
        base.append(position[:, None, :] + np.einsum("tij,nj->tni", rotation, part.data.nodes))
        deformed.append(base[-1] + factor * np.einsum("tij,tnj->tni", rotation, u))
        parts.append(entry)

    # Points of the mechanism, global: origins, axes tips and markers not on a node.
    tracks: list[Array] = []
    labels: list[str] = []

    def add_track(points: Array, label: str) -> int:
        tracks.append(points)
        labels.append(label)
        return offset + len(tracks) - 1

    origin_point: dict[int, int] = {}
    for body in scene.origins:
        origin_point[body] = add_track(scene.pose(body, records)[0], bodies[body]["name"])
    axis_length = AXIS_FRACTION * scene.size
    axes: list[list[tuple[int, int]]] = [[], [], []]
    for body in scene.origins:
        if bodies[body]["kind"] != "rigid":
            continue
        position, rotation = scene.pose(body, records)
        for j in range(3):
            tip = add_track(position + axis_length * rotation[:, :, j], bodies[body]["name"])
            axes[j].append((origin_point[body], tip))
    marker_tracks = scene.marker_tracks(records, 0.0)
    marker_point: dict[int, int] = {}
    for marker, (body, _, node, _) in scene.markers.items():
        if node is not None and body in offsets:
            marker_point[marker] = offsets[body] + node
        elif marker in marker_tracks:
            label = marker_entries[marker].get("name", f"marker {marker}")
            marker_point[marker] = add_track(marker_tracks[marker], label)
    track_array = np.stack(tracks, axis=1) if tracks else np.zeros((count, 0, 3))
    tips = {tip for pairs in axes for _, tip in pairs}
    drawn = [j for j in range(len(tracks)) if offset + j not in tips]
    # The plane of a planar mechanism: from the drawn points without the axes of the rigid
    # bodies, deformed at the initial scale (as the animation module chooses it).
    plane = np.concatenate(
        [b.reshape(-1, 3) for b in deformed] + [track_array[:, drawn].reshape(-1, 3)]
    )
    base.append(track_array)

    # Traces: plotly dicts (validated by plotly) and the points they pass through.
    traces: list[dict[str, Any]] = []
    for part, entry in zip(scene.parts, parts, strict=True):
        start = entry["offset"]
        nodes = list(range(start, start + entry["count"]))
        faces = _boundary_faces(part)
        if faces:
            triangles = np.concatenate(
                [group[:, [0, k, k + 1]] for group in faces for k in range(1, group.shape[1] - 1)]
            )
            traces.append(
                _trace(
                    "mesh3d",
                    nodes,
                    colored=True,
                    name=part.name,
                    i=triangles[:, 0].tolist(),
                    j=triangles[:, 1].tolist(),
                    k=triangles[:, 2].tolist(),
                    flatshading=True,
                    showlegend=True,
                    lighting={"ambient": 0.6, "diffuse": 0.6, "specular": 0.1},
                    hovertemplate=f"{part.name}<extra></extra>",
                )
            )
            edges = {
                tuple(sorted((int(a), int(b))))
                for group in faces
                for face in group
                for a, b in zip(face, np.roll(face, -1), strict=True)
            }
            if len(edges) <= EDGE_LIMIT:
                points = _gaps([(start + a, start + b) for a, b in sorted(edges)])
                traces.append(
                    _trace(
                        "scatter3d",
                        points,
                        name=f"{part.name} edges",
                        mode="lines",
                        line={"color": "#404040", "width": 1},
                        hoverinfo="skip",
                        showlegend=False,
                    )
                )
        beams = part.data.elements.get("beam2")
        if beams is not None and len(beams):
            segments = [(start + int(a), start + int(b)) for a, b in np.asarray(beams)]
            traces.append(
                _trace(
                    "scatter3d",
                    _gaps(segments),
                    colored=True,
                    name=part.name,
                    mode="lines+markers",
                    line={"width": 8},
                    marker={"size": 2, "color": "#303030"},
                    hovertemplate=f"{part.name}<extra></extra>",
                )
            )
    sticks = [
        (origin_point[body], marker_point[marker])
        for body, marker in scene.sticks
        if marker in marker_point
    ]
    if sticks:
        traces.append(
            _trace(
                "scatter3d",
                _gaps(sticks),
                name="rigid bodies",
                mode="lines",
                line={"color": "#262626", "width": 7},
                hoverinfo="skip",
            )
        )
    links = [(marker_point[a], marker_point[b]) for a, b in scene.links]
    if links:
        traces.append(
            _trace(
                "scatter3d",
                _gaps(links),
                name="joint lines",
                mode="lines",
                line={"color": "#d62728", "width": 3},
                hoverinfo="skip",
            )
        )
    connectors = [
        (origin_point[a], origin_point[b])
        for a, b in scene.connectors
        if a in origin_point and b in origin_point
    ]
    if connectors:
        traces.append(
            _trace(
                "scatter3d",
                _gaps(connectors),
                name="joints (between origins)",
                mode="lines",
                line={"color": "#808080", "width": 2, "dash": "dash"},
                hoverinfo="skip",
            )
        )
    for j, color in enumerate(("#e41a1c", "#4daf4a", "#377eb8")):
        if axes[j]:
            traces.append(
                _trace(
                    "scatter3d",
                    _gaps(axes[j]),
                    name="body axes (x, y, z)",
                    legendgroup="axes",
                    showlegend=j == 0,
                    mode="lines",
                    line={"color": color, "width": 4},
                    hoverinfo="skip",
                )
            )
    if origin_point:
        points = list(origin_point.values())
        traces.append(
            _trace(
                "scatter3d",
                points,
                name="body origins",
                mode="markers",
                marker={"size": 5, "color": "#ff7f0e", "line": {"color": "black", "width": 1}},
                text=[bodies[b]["name"] for b in origin_point],
                hovertemplate="%{text}<extra></extra>",
            )
        )
    grounded = [m for m in marker_point if bodies[scene.markers[m][0]]["kind"] == "ground"]
    moving = [m for m in marker_point if m not in grounded]
    for group, legend, marker in (
        (moving, "markers", {"size": 4, "color": "white", "line": {"color": "black", "width": 2}}),
        (grounded, "ground markers", {"size": 6, "color": "black", "symbol": "diamond"}),
    ):
        if group:
            traces.append(
                _trace(
                    "scatter3d",
                    [marker_point[m] for m in group],
                    name=legend,
                    mode="markers",
                    marker=marker,
                    text=[marker_entries[m].get("name", f"marker {m}") for m in group],
                    hovertemplate="%{text}<extra></extra>",
                )
            )

    # The box of the view at scale 0 and the camera angles of the animation module.
    cloud = np.concatenate([b.reshape(-1, 3) for b in base] + [np.zeros((1, 3))])
    low, high = cloud.min(axis=0), cloud.max(axis=0)
    extents = plane.max(axis=0) - plane.min(axis=0) if len(plane) else high - low
    elevation, azimuth = _view_angles("auto", extents)
    time = np.asarray(result.time)[records]
    return {
        "name": name,
        "records": int(len(result.time)),
        "times": [float(t) for t in time],
        "phase": phase,
        "scale": factor,
        "parts": parts,
        "points": offset + len(tracks),
        "tracks": _floats(track_array),
        "trackCount": len(tracks),
        "traces": traces,
        "colors": colors,
        "box": [low.tolist(), high.tolist()],
        "largest": largest,
        "view": [elevation, azimuth],
    }


def _trace(
    kind: str, points: list[int], *, colored: bool = False, **options: Any
) -> dict[str, Any]:
    """A plotly trace (checked by plotly.graph_objects) without its coordinates, with the
    indices of its points into the page's point table."""
    import plotly.graph_objects as go

    make = {"mesh3d": go.Mesh3d, "scatter3d": go.Scatter3d}[kind]
    trace = make(**options).to_plotly_json()
    return {"trace": trace, "points": points, "colored": colored}


def _mode_datasets(
    linear: Any,
    model: Any,
    modes: int,
    frames_per_period: int,
    scale: float | str | None,
) -> list[dict[str, Any]]:
    """One animation per oscillating mode of `linear` (at most `modes`)."""
    from ._core import Model, System
    from .state_space import mode_result

    if isinstance(model, System):
        model = model.compile()
    if not isinstance(model, Model):
        raise InvalidParameterError(
            "view of a LinearizedSystem needs model=, the System or Model it was linearized "
            f"from; got {type(model).__name__}",
            item="model",
        )
    if not isinstance(modes, int | np.integer) or isinstance(modes, bool) or modes < 1:
        raise InvalidParameterError(f"modes must be a positive integer, got {modes!r}")
    frequencies = linear.frequencies()
    if len(frequencies) == 0:
        raise InvalidParameterError("the linearized system has no oscillating mode", item="modes")
    datasets = []
    for k in range(min(int(modes), len(frequencies))):
        result = mode_result(linear, model, k, frames=int(frames_per_period))
        name = f"mode {k + 1}: {frequencies[k]:.5g} Hz"
        datasets.append(_dataset(result, name, int(frames_per_period), scale, phase=True))
    return datasets


# The page -----------------------------------------------------------------------------------
def _layout(dataset: dict[str, Any]) -> dict[str, Any]:
    """The plotly layout of the 3D scene: orthographic camera along the view of the animation
    module, equal axes (the page sets their ranges)."""
    import plotly.graph_objects as go

    elevation, azimuth = (math.radians(a) for a in dataset["view"])
    distance = 2.0
    eye = {
        "x": distance * math.cos(elevation) * math.cos(azimuth),
        "y": distance * math.cos(elevation) * math.sin(azimuth),
        "z": distance * math.sin(elevation),
    }
    up = {
        "x": -math.sin(elevation) * math.cos(azimuth),
        "y": -math.sin(elevation) * math.sin(azimuth),
        "z": math.cos(elevation),
    }
    axis = {"showbackground": True, "backgroundcolor": "#f4f4f8", "gridcolor": "white"}
    layout = go.Layout(
        margin={"l": 0, "r": 0, "t": 0, "b": 0},
        uirevision="keep",
        legend={"x": 0.01, "y": 0.99, "bgcolor": "rgba(255,255,255,0.7)"},
        scene={
            # Orthographic zoom is the size of the box: equal axes filling the plot.
            "aspectmode": "manual",
            "aspectratio": {"x": ZOOM, "y": ZOOM, "z": ZOOM},
            "camera": {"eye": eye, "up": up, "projection": {"type": "orthographic"}},
            "xaxis": {"title": {"text": "x (m)"}, **axis},
            "yaxis": {"title": {"text": "y (m)"}, **axis},
            "zaxis": {"title": {"text": "z (m)"}, **axis},
        },
    )
    return layout.to_plotly_json()


def _page(title: str, datasets: list[dict[str, Any]], color_by: str) -> str:
    """The HTML page: plotly.js, the data as JSON and the viewer's script."""
    import html

    from plotly.offline import get_plotlyjs

    data = {
        "title": title,
        "datasets": datasets,
        "layout": _layout(datasets[0]),
        "color": color_by,
        "colorTitles": COLOR_TITLES,
        "plainColors": PLAIN_COLORS,
    }
    payload = json.dumps(data, separators=(",", ":")).replace("</", "<\\/")
    shown = datasets[0]
    if shown["phase"]:
        note = f"{len(datasets)} mode shapes, {len(shown['times'])} frames per period."
    elif len(shown["times"]) < shown["records"]:
        note = (
            f"Showing {len(shown['times'])} of {shown['records']} records, spread evenly over "
            "the run (max_frames)."
        )
    else:
        note = f"Showing all {shown['records']} records."
    return (
        _TEMPLATE.replace("{{title}}", html.escape(title))
        .replace("{{note}}", html.escape(note))
        .replace("{{plotly}}", get_plotlyjs())
        .replace("{{data}}", payload)
        .replace("{{script}}", _SCRIPT)
    )


_TEMPLATE = """<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>{{title}} - flexmbd viewer</title>
<style>
body { margin: 0; font: 14px sans-serif; display: flex; flex-direction: column; height: 100vh; }
#flexmbd-controls { display: flex; flex-wrap: wrap; gap: 6px 14px; align-items: center;
  padding: 6px 10px; background: #eef0f4; border-bottom: 1px solid #ccd; }
#flexmbd-controls label { display: flex; gap: 4px; align-items: center; }
#flexmbd-frame { width: 28em; max-width: 60vw; }
#flexmbd-time { min-width: 11em; font-variant-numeric: tabular-nums; }
#flexmbd-scale { width: 7em; }
#flexmbd-plot { flex: 1; min-height: 300px; }
#flexmbd-note { padding: 3px 10px; color: #555; font-size: 12px; }
</style>
</head>
<body>
<div id="flexmbd-controls">
<strong>{{title}}</strong>
<label id="flexmbd-mode-label">mode <select id="flexmbd-mode"></select></label>
<button id="flexmbd-play" type="button">play</button>
<input id="flexmbd-frame" type="range" min="0" max="0" step="1" value="0"
  aria-label="frame">
<span id="flexmbd-time"></span>
<label>speed <select id="flexmbd-speed">
<option value="0.25">0.25x</option><option value="0.5">0.5x</option>
<option value="1" selected>1x</option><option value="2">2x</option>
<option value="4">4x</option></select></label>
<label id="flexmbd-scale-label">deformation scale
<input id="flexmbd-scale" type="number" min="0" step="any"></label>
<button id="flexmbd-true-scale" type="button">true scale</button>
<label id="flexmbd-color-label">colour <select id="flexmbd-color"></select></label>
</div>
<div id="flexmbd-plot"></div>
<div id="flexmbd-note">{{note}} Play shows 25 frames per second at 1x. Drag to turn,
scroll to zoom; click legend entries to hide items. The URL keeps the frame
(#frame=K&amp;mode=M&amp;scale=S&amp;color=C).</div>
<script>{{plotly}}</script>
<script id="flexmbd-data" type="application/json">{{data}}</script>
<script>{{script}}</script>
</body>
</html>
"""

_SCRIPT = r"""
(function () {
  "use strict";
  const DATA = JSON.parse(document.getElementById("flexmbd-data").textContent);
  const plot = document.getElementById("flexmbd-plot");
  const $ = (id) => document.getElementById("flexmbd-" + id);
  const state = { mode: 0, frame: 0, scale: 1, color: DATA.color, playing: false };
  const viewer = { ready: false, rendered: 0, state: state };
  window.flexmbdViewer = viewer;

  function floats(text) {
    const bytes = atob(text);
    const buffer = new Uint8Array(bytes.length);
    for (let i = 0; i < bytes.length; i++) buffer[i] = bytes.charCodeAt(i);
    return new Float32Array(buffer.buffer);
  }

  // Decoded arrays of each animation, on first use.
  function decoded(ds) {
    if (!ds.decoded) {
      ds.decoded = {
        tracks: floats(ds.tracks),
        parts: ds.parts.map((p) => ({
          nodes: floats(p.nodes), pose: floats(p.pose), u: floats(p.u),
          stress: p.stress ? floats(p.stress) : null,
        })),
      };
    }
    return ds.decoded;
  }

  // Positions (3 per point) and colour values of every point at a frame.
  function points(ds, frame, scale) {
    const dec = decoded(ds);
    const xyz = new Float64Array(3 * ds.points);
    const values = { displacement: new Float64Array(ds.points).fill(NaN),
                     stress: new Float64Array(ds.points).fill(NaN) };
    ds.parts.forEach((part, p) => {
      const d = dec.parts[p], n = part.count, o = part.offset;
      const pose = d.pose.subarray(12 * frame, 12 * frame + 12);
      for (let i = 0; i < n; i++) {
        const a = 3 * (frame * n + i);
        const ux = d.u[a], uy = d.u[a + 1], uz = d.u[a + 2];
        const lx = d.nodes[3 * i] + scale * ux, ly = d.nodes[3 * i + 1] + scale * uy,
              lz = d.nodes[3 * i + 2] + scale * uz;
        for (let r = 0; r < 3; r++) {
          xyz[3 * (o + i) + r] = pose[r] + pose[3 + 3 * r] * lx + pose[4 + 3 * r] * ly
            + pose[5 + 3 * r] * lz;
        }
        values.displacement[o + i] = Math.hypot(ux, uy, uz);
        if (d.stress) values.stress[o + i] = d.stress[frame * n + i];
      }
    });
    const m = ds.trackCount, start = ds.points - m;
    for (let j = 0; j < m; j++) {
      for (let r = 0; r < 3; r++) xyz[3 * (start + j) + r] = dec.tracks[3 * (frame * m + j) + r];
    }
    return { xyz: xyz, values: values };
  }

  function colorRange(ds, quantity) {
    let top = 0;
    ds.parts.forEach((p) => {
      if (p.range[quantity] !== undefined) top = Math.max(top, p.range[quantity]);
    });
    return top > 0 ? top : 1;
  }

  function traces(ds, frame) {
    const pts = points(ds, state.frame, state.scale);
    const quantity = ds.colors.includes(state.color) ? state.color : "none";
    const top = colorRange(ds, quantity);
    let bar = false;
    return ds.traces.map((entry) => {
      const t = Object.assign({}, entry.trace);
      const x = [], y = [], z = [], v = [];
      let colored = entry.colored && quantity !== "none";
      for (const index of entry.points) {
        if (index < 0) { x.push(null); y.push(null); z.push(null); v.push(null); continue; }
        x.push(pts.xyz[3 * index]); y.push(pts.xyz[3 * index + 1]); z.push(pts.xyz[3 * index + 2]);
        v.push(colored ? pts.values[quantity][index] : null);
      }
      if (colored && v.every((value) => value === null || Number.isNaN(value))) colored = false;
      t.x = x; t.y = y; t.z = z;
      const scale = { colorscale: "Viridis", cmin: 0, cmax: top };
      const colorbar = { title: { text: DATA.colorTitles[quantity] || "", side: "right" },
                         len: 0.8, exponentformat: "power" };
      if (t.type === "mesh3d") {
        if (colored) {
          Object.assign(t, scale, { intensity: v, showscale: !bar, colorbar: colorbar });
          bar = true;
        } else {
          Object.assign(t, { color: DATA.plainColors.mesh3d, showscale: false });
        }
      } else if (entry.colored) {
        const line = Object.assign({}, t.line);
        if (colored) {
          Object.assign(line, scale, { color: v.map((value) => (value === null ? 0 : value)),
                                       showscale: !bar, colorbar: colorbar });
          bar = true;
        } else {
          Object.assign(line, { color: DATA.plainColors.scatter3d, showscale: false });
        }
        t.line = line;
        // plotly's legend cannot draw a line of colour values: the colour bar names it.
        if (colored) t.showlegend = false;
      }
      return t;
    });
  }

  function layout(ds) {
    const grow = state.scale * ds.largest;
    const low = ds.box[0].map((v) => v - grow), high = ds.box[1].map((v) => v + grow);
    const half = 0.55 * Math.max(1e-9, ...high.map((v, r) => v - low[r]));
    const lay = JSON.parse(JSON.stringify(DATA.layout));
    ["xaxis", "yaxis", "zaxis"].forEach((axis, r) => {
      const centre = 0.5 * (low[r] + high[r]);
      lay.scene[axis].range = [centre - half, centre + half];
    });
    return lay;
  }

  function label(ds) {
    const t = ds.times[state.frame];
    const text = ds.phase ? "phase " + t.toFixed(3) + " period" : "t = " + t.toPrecision(6) + " s";
    return text + "  (" + (state.frame + 1) + "/" + ds.times.length + ")";
  }

  let drawing = null, pending = false;
  function draw() {
    // One redraw at a time; a request during a redraw is served when it ends.
    if (drawing) { pending = true; return drawing; }
    const ds = DATA.datasets[state.mode];
    $("time").textContent = label(ds);
    drawing = Plotly.react(plot, traces(ds), layout(ds), { responsive: true, displaylogo: false })
      .then(() => {
        viewer.rendered += 1;
        drawing = null;
        if (pending) { pending = false; return draw(); }
      });
    return drawing;
  }

  function remember() {
    const hash = "#frame=" + state.frame + "&mode=" + state.mode + "&scale=" + state.scale
      + "&color=" + state.color;
    if (window.location.hash !== hash) history.replaceState(null, "", hash);
  }

  function setFrame(frame) {
    const ds = DATA.datasets[state.mode];
    state.frame = Math.max(0, Math.min(ds.times.length - 1, frame | 0));
    $("frame").value = state.frame;
    draw();
  }

  function setMode(mode) {
    state.mode = Math.max(0, Math.min(DATA.datasets.length - 1, mode | 0));
    const ds = DATA.datasets[state.mode];
    $("mode").value = state.mode;
    $("frame").max = ds.times.length - 1;
    state.frame = Math.min(state.frame, ds.times.length - 1);
    $("frame").value = state.frame;
  }

  let timer = null;
  function play(on) {
    state.playing = on;
    $("play").textContent = on ? "pause" : "play";
    if (timer) { clearInterval(timer); timer = null; }
    if (on) {
      const speed = parseFloat($("speed").value);
      timer = setInterval(() => {
        const ds = DATA.datasets[state.mode];
        setFrame((state.frame + 1) % ds.times.length);
      }, 40 / speed);
    } else {
      remember();
    }
  }

  // Controls.
  DATA.datasets.forEach((ds, k) => $("mode").add(new Option(ds.name, k)));
  $("mode-label").style.display = DATA.datasets.length > 1 ? "" : "none";
  const colors = ["displacement", "stress", "none"]
    .filter((q) => DATA.datasets.some((ds) => ds.colors.includes(q)));
  colors.forEach((q) => $("color").add(new Option(q, q)));
  const deformable = DATA.datasets.some((ds) => ds.parts.length > 0);
  ["scale-label", "true-scale", "color-label"].forEach((id) => {
    $(id).style.display = deformable ? "" : "none";
  });

  const hash = new URLSearchParams(window.location.hash.slice(1));
  setMode(parseInt(hash.get("mode") || "0", 10));
  state.scale = DATA.datasets[state.mode].scale;
  if (hash.has("scale") && parseFloat(hash.get("scale")) >= 0) {
    state.scale = parseFloat(hash.get("scale"));
  }
  if (hash.has("color") && colors.includes(hash.get("color"))) state.color = hash.get("color");
  state.frame = Math.max(0, Math.min(DATA.datasets[state.mode].times.length - 1,
                                     parseInt(hash.get("frame") || "0", 10) || 0));
  $("frame").value = state.frame;
  $("scale").value = +state.scale.toPrecision(4);
  $("color").value = state.color;

  $("frame").addEventListener("input", () => { setFrame(parseInt($("frame").value, 10)); });
  $("frame").addEventListener("change", remember);
  $("play").addEventListener("click", () => play(!state.playing));
  $("speed").addEventListener("change", () => { if (state.playing) play(true); });
  $("scale").addEventListener("change", () => {
    const value = parseFloat($("scale").value);
    if (value >= 0) { state.scale = value; draw(); remember(); }
  });
  $("true-scale").addEventListener("click", () => {
    state.scale = 1; $("scale").value = 1; draw(); remember();
  });
  $("color").addEventListener("change", () => {
    state.color = $("color").value; draw(); remember();
  });
  $("mode").addEventListener("change", () => {
    setMode(parseInt($("mode").value, 10));
    state.scale = DATA.datasets[state.mode].scale;
    $("scale").value = +state.scale.toPrecision(4);
    draw(); remember();
  });
  viewer.setFrame = setFrame;
  viewer.play = play;
  draw().then(() => { viewer.ready = true; });
})();
"""
