"""ParaView time series and rendered animations of short runs of the built-in examples."""

from __future__ import annotations

import copy
import xml.etree.ElementTree as ElementTree

import meshio
import numpy as np
import pytest
from conftest import run_example
from PIL import Image

import flexmbd as fm
from flexmbd import animation
from flexmbd.fe.stress import von_mises


@pytest.fixture(scope="module")
def slider_crank() -> fm.Result:
    # A quarter of a crank turn: the rod is visibly bent.
    return run_example("flexible-slider-crank", 0.02, 2e-3)


@pytest.fixture(scope="module")
def tet_pendulum() -> fm.Result:
    return run_example("tetrahedral-pendulum", 0.1, 0.01)


@pytest.fixture(scope="module")
def four_bar() -> fm.Result:
    return run_example("four-bar", 0.5, 0.05)


def assert_rich_image(path, colours: int = 8) -> None:
    """A valid image that is not blank: several colours and a spread of intensities."""
    with Image.open(path) as image:
        image.verify()
    with Image.open(path) as image:
        pixels = np.asarray(image.convert("RGB"), dtype=float)
    assert pixels.std() > 5.0
    assert len(np.unique(pixels.reshape(-1, 3), axis=0)) >= colours


# VTU / PVD ------------------------------------------------------------------------------------
def test_vtu_series_has_the_deformed_rod_at_every_written_record(slider_crank, tmp_path):
    result = slider_crank
    pvd = animation.write_vtu_series(result, tmp_path / "vtk", every=3)
    entries = animation.read_pvd(pvd)
    records = [0, 3, 6, 9, 10]  # every third record and the last one
    np.testing.assert_array_equal([t for t, _ in entries], result.time[records])
    nodes = result.node_positions("rod")
    rotation = result.orientation("rod")
    displacement = np.einsum("tij,tnj->tni", rotation, result.node_displacements("rod"))
    for (_, file), record in zip(entries, records, strict=True):
        mesh = meshio.read(file)
        np.testing.assert_allclose(mesh.points[:9], nodes[record], rtol=0, atol=1e-12)
        np.testing.assert_allclose(
            mesh.point_data["displacement"][:9], displacement[record], rtol=0, atol=1e-12
        )
        assert np.all(mesh.point_data["body"][:9] == 2)
        lines = [block for block in mesh.cells if block.type == "line"]
        beams = np.column_stack([np.arange(8), 1 + np.arange(8)])
        np.testing.assert_array_equal(lines[0].data, beams)
        assert "von_mises" not in mesh.point_data  # beams only
        # The mechanism: the crank and slider origins as vertices, lines for the rest.
        vertices = [block for block in mesh.cells if block.type == "vertex"]
        assert len(vertices) == 1 and len(vertices[0].data) == 2
        np.testing.assert_allclose(
            mesh.points[vertices[0].data[:, 0]],
            [result.position("crank")[record], result.position("slider")[record]],
            atol=1e-12,
        )


def test_pvd_is_a_vtk_collection_with_relative_file_names(slider_crank, tmp_path):
    pvd = animation.write_vtu_series(slider_crank, tmp_path, every=5, name="crank")
    root = ElementTree.parse(pvd).getroot()
    assert root.tag == "VTKFile" and root.get("type") == "Collection"
    files = [entry.get("file") for entry in root.iter("DataSet")]
    assert files == ["crank_00000.vtu", "crank_00001.vtu", "crank_00002.vtu"]
    assert all((tmp_path / f).is_file() for f in files)


def test_vtu_solid_has_tetrahedra_and_von_mises_stress(tet_pendulum, tmp_path):
    result = tet_pendulum
    data = result.flexible[1]
    entries = animation.read_pvd(animation.write_vtu_series(result, tmp_path, every=5))
    assert len(entries) == 3
    record = 5
    mesh = meshio.read(entries[1][1])
    count = len(data.nodes)
    assert len(mesh.points) >= count
    np.testing.assert_allclose(
        mesh.points[:count], result.node_positions("arm")[record], rtol=0, atol=1e-12
    )
    tetra = [block for block in mesh.cells if block.type == "tetra"]
    np.testing.assert_array_equal(tetra[0].data, data.elements["tet4"])
    expected = von_mises(result.stresses("arm", [record])[0])
    np.testing.assert_allclose(mesh.point_data["von_mises"][:count], expected, rtol=1e-12)
    # The stress tensor is written in global axes: its invariant von Mises value is kept.
    s = mesh.point_data["stress"][:count]  # ParaView order xx, yy, zz, xy, yz, xz
    voigt = np.column_stack([s[:, 0], s[:, 1], s[:, 2], s[:, 4], s[:, 5], s[:, 3]])
    np.testing.assert_allclose(von_mises(voigt), expected, rtol=1e-9, atol=1e-9 * expected.max())


def test_vtu_scale_magnifies_the_elastic_displacement_only(slider_crank, tmp_path):
    result = slider_crank
    entries = animation.read_pvd(animation.write_vtu_series(result, tmp_path, every=10, scale=5))
    data = result.flexible[2]
    record = 10
    local = data.nodes + 5.0 * result.node_displacements("rod")[record]
    expected = result.position("rod")[record] + local @ result.orientation("rod")[record].T
    mesh = meshio.read(entries[-1][1])
    np.testing.assert_allclose(mesh.points[:9], expected, rtol=0, atol=1e-12)


def test_vtu_rejects_a_bad_stride(slider_crank, tmp_path):
    with pytest.raises(fm.InvalidParameterError, match="every"):
        animation.write_vtu_series(slider_crank, tmp_path, every=0)
    with pytest.raises(fm.InvalidParameterError, match="scale"):
        animation.write_vtu_series(slider_crank, tmp_path, scale=-1.0)


def test_vtu_series_names_and_folders_are_checked_and_stale_frames_removed(slider_crank, tmp_path):
    # Regression: a name "a/b" was a raw FileNotFoundError, "" wrote hidden files, a file as
    # the folder a raw FileExistsError; a shorter series over a longer one left its frames.
    for name in ("a/b", "", ".hidden"):
        with pytest.raises(fm.InvalidParameterError, match="name: the file name of the series"):
            animation.write_vtu_series(slider_crank, tmp_path / "v", name=name)
    (tmp_path / "file").write_text("mine")
    with pytest.raises(fm.InvalidParameterError, match="is a file, not a folder"):
        animation.write_vtu_series(slider_crank, tmp_path / "file")
    folder = tmp_path / "series"
    animation.write_vtu_series(slider_crank, folder, every=2)
    (folder / "notes_00099.vtu").write_text("another series")
    many = len(list(folder.glob("result_*.vtu")))
    pvd = animation.write_vtu_series(slider_crank, folder, every=10)
    kept = sorted(folder.glob("result_*.vtu"))
    assert len(kept) == len(animation.read_pvd(pvd)) < many
    assert (folder / "notes_00099.vtu").exists()


def test_vtu_times_window_then_every_nth_record_and_the_windows_last(slider_crank, tmp_path):
    # Records every 2 ms over 0 .. 20 ms: the window 5 .. 15 ms holds 6, 8, 10, 12, 14 ms;
    # every 3rd from its first is 6 and 12 ms, and the window's last, 14 ms, is added.
    entries = animation.read_pvd(
        animation.write_vtu_series(slider_crank, tmp_path, every=3, times=(0.005, 0.015))
    )
    np.testing.assert_allclose([t for t, _ in entries], [0.006, 0.012, 0.014], rtol=1e-12)
    mesh = meshio.read(entries[0][1])
    expected = slider_crank.node_positions("rod")[3]
    np.testing.assert_allclose(mesh.points[: len(expected)], expected, rtol=0, atol=1e-12)
    # A window's ends are inclusive; an open end is infinite.
    ends = animation.read_pvd(
        animation.write_vtu_series(slider_crank, tmp_path / "b", times=(0.016, np.inf))
    )
    np.testing.assert_allclose([t for t, _ in ends], [0.016, 0.018, 0.02], rtol=1e-12)


@pytest.mark.parametrize(
    ("times", "message"),
    [
        ((0.5, 1.0), r"no record in times 0\.5 \.\. 1 s \(the records: 0 \.\. 0\.02 s\)"),
        ((0.01, 0.005), "start <= end"),
        ((np.nan, 1.0), "start <= end"),
        ((0.01,), r"times must be \(start, end\)"),
        ("0:1", r"times must be \(start, end\)"),
    ],
)
def test_vtu_rejects_a_bad_time_window(slider_crank, tmp_path, times, message):
    with pytest.raises(fm.InvalidParameterError, match=message):
        animation.write_vtu_series(slider_crank, tmp_path, times=times)
    with pytest.raises(fm.InvalidParameterError, match=message):
        animation.vtu_series_size(slider_crank, times=times)
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("stress", [True, False])
def test_vtu_series_size_counts_the_files_and_estimates_their_size(tet_pendulum, tmp_path, stress):
    files, size = animation.vtu_series_size(tet_pendulum, 2, times=(0.02, 0.1), stress=stress)
    pvd = animation.write_vtu_series(tet_pendulum, tmp_path, 2, times=(0.02, 0.1), stress=stress)
    written = [path for _, path in animation.read_pvd(pvd)]
    assert files == len(written) == 5  # 0.02, 0.04, 0.06, 0.08 and 0.1 s
    actual = sum(path.stat().st_size for path in written)
    assert actual / 1.5 < size < actual * 1.5, (size, actual)


# Markers located from the motion ----------------------------------------------------------------
def test_joint_markers_are_located_from_the_motion(four_bar):
    # The four-bar's geometry: ground pivots at x = 0, 1, 2; crank ends at +-0.5 m on the local
    # x axis; coupler ends at +-0.5 m. Only B0 has a sensor; the rest is fitted.
    scene = animation.build_scene(four_bar)
    records = np.arange(len(four_bar.time))
    tracks = scene.marker_tracks(records)
    layout = four_bar.layout
    ground = [m for m, e in enumerate(layout["markers"]) if e["body"] == 0]
    assert len(ground) == 3
    for k, marker in enumerate(ground):
        pivot = np.tile([k, 0.0, 0.0], (len(records), 1))
        np.testing.assert_allclose(tracks[marker], pivot, atol=1e-9)
    for joint in layout["joints"]:
        m1, m2 = joint["markers"]
        np.testing.assert_allclose(tracks[m1][:, :2], tracks[m2][:, :2], atol=1e-9)
    for body, local, node, _ in scene.markers.values():
        if body != 0:
            assert node is None
            np.testing.assert_allclose(np.abs(local), [0.5, 0.0, 0.0], atol=1e-9)
    assert not scene.connectors


def test_markers_are_drawn_where_the_model_puts_them(slider_crank):
    scene = animation.build_scene(slider_crank)
    # The layout gives every marker's position: the crank pin at the crank's tip, the guide's
    # markers at the ground origin and the slider, no guessed connector.
    assert scene.connectors == []
    np.testing.assert_array_equal(scene.markers[2][1], [0.15, 0.0, 0.0])
    nodes = {body: node for body, _, node, _ in scene.markers.values() if node is not None}
    assert set(nodes) == {2}
    on_rod = sorted(node for body, _, node, _ in scene.markers.values() if body == 2)
    assert on_rod == [0, 8]


def test_slider_guide_is_drawn_between_body_origins_without_marker_positions(slider_crank):
    # A layout without marker positions (results of an older writer): the markers of a joint
    # are fitted to the recorded motion, and the guide's, which slide apart, are drawn as a
    # connector between the body origins.
    stripped = copy.copy(slider_crank)
    stripped.layout = copy.deepcopy(slider_crank.layout)
    for marker in stripped.layout["markers"]:
        marker.pop("position", None)
        marker.pop("orientation", None)
    scene = animation.build_scene(stripped)
    # The in-line guide's markers slide apart: no common point; the crank pin sits on node 1
    # and the wrist pin on node 9 of the rod.
    assert scene.connectors == [(0, 3)]
    nodes = {body: node for body, _, node, _ in scene.markers.values() if node is not None}
    assert set(nodes) == {2}
    on_rod = sorted(node for body, _, node, _ in scene.markers.values() if body == 2)
    assert on_rod == [0, 8]


def test_auto_scale_makes_the_largest_displacement_a_tenth_of_the_model(tet_pendulum):
    scene = animation.build_scene(tet_pendulum)
    records = np.arange(len(tet_pendulum.time))
    scale = scene.auto_scale(records)
    largest = np.max(np.linalg.norm(tet_pendulum.node_displacements("arm"), axis=2))
    assert scale > 1000.0  # micrometres on a half-metre bar
    assert scale * largest == pytest.approx(0.1 * scene.size, rel=1e-12)


# Rendering ----------------------------------------------------------------------------------------
def test_gif_has_the_requested_frames(slider_crank, tmp_path):
    files = animation.render_animation(slider_crank, tmp_path / "crank.gif", frames=4)
    assert files == [tmp_path / "crank.gif"]
    with Image.open(files[0]) as image:
        assert image.n_frames == 4
    assert_rich_image(files[0])


def test_png_sequence_of_the_tet_pendulum_coloured_by_stress(tet_pendulum, tmp_path):
    files = animation.render_animation(
        tet_pendulum, tmp_path / "frames", frames=3, color_by="stress", view="iso"
    )
    assert [f.name for f in files] == ["frame_0000.png", "frame_0001.png", "frame_0002.png"]
    for file in files:
        assert_rich_image(file)
    named = animation.render_animation(tet_pendulum, tmp_path / "arm.png", frames=2)
    assert [f.name for f in named] == ["arm_0000.png", "arm_0001.png"]


def test_render_image_and_frame(four_bar, tmp_path):
    png = animation.render_image(four_bar, tmp_path / "four_bar.png", record=3)
    assert_rich_image(png, colours=4)
    svg = animation.render_image(four_bar, tmp_path / "four_bar.svg")
    assert svg.read_text().lstrip().startswith("<?xml")
    ax = animation.render_frame(four_bar, 0, view=(30.0, -45.0))
    assert "t = 0 s" in ax.get_title()


def test_title_states_the_deformation_scale(slider_crank):
    ax = animation.render_frame(slider_crank, -1, scale=20.0)
    assert "deformation x20" in ax.get_title()
    ax = animation.render_frame(slider_crank, -1, scale=1.0)
    assert "true scale" in ax.get_title()


def test_render_rejects_bad_arguments(slider_crank, tmp_path):
    with pytest.raises(fm.InvalidParameterError, match="unknown view"):
        animation.render_frame(slider_crank, view="top")
    with pytest.raises(fm.InvalidParameterError, match="record"):
        animation.render_frame(slider_crank, record=len(slider_crank.time))
    with pytest.raises(fm.InvalidParameterError, match="backend"):
        animation.render_animation(slider_crank, tmp_path / "a.gif", backend="povray")
    with pytest.raises(fm.InvalidParameterError, match="frames"):
        animation.render_animation(slider_crank, tmp_path / "a.gif", frames=0)
    with pytest.raises(fm.InvalidParameterError, match="color_by"):
        animation.render_frame(slider_crank, color_by="temperature")
    with pytest.raises(fm.InvalidParameterError, match="image format"):
        animation.render_image(slider_crank, tmp_path / "a.jpg")


@pytest.mark.skipif(not animation.pyvista_available(), reason="pyvista cannot render here")
def test_pyvista_renders_the_same_frames(slider_crank, tmp_path):
    files = animation.render_animation(slider_crank, tmp_path / "pv", frames=2, backend="pyvista")
    assert len(files) == 2
    for file in files:
        assert_rich_image(file, colours=3)


def test_colouring_by_stress_without_solids_is_refused(slider_crank):
    # Regression: a beam-only model coloured by displacement under "stress" without a word
    # (fm.view refused it).
    with pytest.raises(fm.InvalidParameterError, match="color_by 'stress' needs a deformable"):
        animation.render_frame(slider_crank, -1, color_by="stress")


def test_a_node_marker_with_a_sensor_moves_with_the_magnified_node():
    # Regression: the sensor's true-scale track took priority, drawing the tip marker of a
    # beam magnified 712 times 0.1 m off its own node.
    from flexmbd.fe import Material, Section, build_body, straight_beam

    nodes, elements = straight_beam(1.0, 4)
    data = build_body(
        nodes, elements, Material(2.1e9, 0.3, 7800.0), section=Section.circle(0.01),
        reference="clamped", reference_nodes=[0],
    )  # fmt: skip
    system = fm.System(gravity=(0, -9.81, 0))
    beam = system.add_flexible_body(data, name="arm")
    system.add_revolute_joint(system.add_marker(system.ground), system.add_node_marker(beam, 1))
    system.add_sensor(system.add_node_marker(beam, 5), "position", name="tip")
    result = fm.simulate(system, 0.05, 1e-3, output_interval=0.01)
    scene = animation.build_scene(result)
    records = np.arange(len(result.time))
    (part,) = scene.parts
    tip = next(m for m, (_, _, node, sensor) in scene.markers.items() if sensor is not None)
    node = scene.markers[tip][2]
    for scale in (1.0, 50.0):
        drawn = scene.nodes(part, records, scale)[0][:, node]
        np.testing.assert_allclose(scene.marker_tracks(records, scale)[tip], drawn, atol=1e-12)
    np.testing.assert_allclose(
        scene.marker_tracks(records, 1.0)[tip], result.sensor("tip")[records], atol=1e-9
    )


@pytest.mark.parametrize("target", ["anim {x}/run.png", "frames{}dir", "run{0}.png"])
def test_frames_are_written_whatever_characters_their_path_holds(four_bar, tmp_path, target):
    # The frame names were a str.format pattern of the whole path: braces raised KeyError,
    # IndexError or ValueError after every frame was rendered.
    files = animation.render_animation(four_bar, tmp_path / target, frames=2)
    assert len(files) == 2 and all(f.is_file() for f in files)
    assert files[1].name.endswith("_0001.png")


@pytest.mark.parametrize("target", ["seq.png", "folder"])
def test_a_shorter_sequence_replaces_the_frames_of_a_longer_one(four_bar, tmp_path, target):
    # Five frames then two left frames 2-4 of the first beside the new ones.
    animation.render_animation(four_bar, tmp_path / target, frames=5)
    files = animation.render_animation(four_bar, tmp_path / target, frames=2)
    folder = files[0].parent
    assert sorted(p.name for p in folder.iterdir() if p.suffix == ".png") == [f.name for f in files]


@pytest.mark.parametrize(
    ("call", "item"),
    [
        (lambda r, d: animation.render_animation(r, d / "a.gif", frames=2, dpi=0), "dpi"),
        (lambda r, d: animation.render_animation(r, d / "a.gif", frames=2, fps="10"), "fps"),
        (lambda r, d: animation.render_animation(r, d / "a.gif", frames=True), "frames"),
        (lambda r, d: animation.render_frame(r, view=30), "view"),
        (lambda r, d: animation.render_frame(r, scale=-1), "scale"),
        (lambda r, d: animation.write_vtu_series(r, d / "v", scale=[2]), "scale"),
        (lambda r, d: animation.write_vtu_series(r, d / "v", every=0), "every"),
        (lambda r, d: animation.write_vtu_series(r, d / "v", times="01"), "times"),
        (lambda r, d: animation.render_image(r, d / "a.png", record=True), "True"),
    ],
    ids=["dpi 0", "fps text", "frames True", "view number", "scale negative", "scale list",
         "every 0", "times text", "record True"],
)  # fmt: skip
def test_bad_rendering_options_are_refused_by_name(slider_crank, tmp_path, call, item):
    # Bare TypeError / ValueError of matplotlib, errors without an item, or silently taken
    # ("01" as the window (0, 1), record True as record 1).
    with pytest.raises(fm.InvalidParameterError) as error:
        call(slider_crank, tmp_path)
    assert error.value.item == item


def test_an_animation_into_an_existing_file_is_refused(slider_crank, tmp_path):
    # (a bare FileExistsError after the scene was built)
    existing = tmp_path / "notes.txt"
    existing.write_text("x")
    with pytest.raises(fm.InvalidParameterError, match="is a file, not a folder"):
        animation.render_animation(slider_crank, existing, frames=2)
