"""Nastran OP2 results (issue 35): the eigenvalues and eigenvectors of SOL 103 read from
binary OP2 files in both byte orders and word sizes, bodies made of a deck and its OP2 modes
against the preprocessor's own modes of the same mesh, and bad files named by table and byte.

The fixtures in tests/data/nastran were written by make_op2.py there: pyNastran's writer
(32-bit little-endian) and a writer by hand (big-endian, 64-bit), each read back by
pyNastran's reader; their modes are eigenpairs of flexmbd's K and M of the same decks, solved
densely by scipy. Here they are checked against those K and M again, without pyNastran."""

import dataclasses
import importlib.util
import shutil
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg as sla

import flexmbd as fm
from flexmbd.errors import (
    ArgumentTypeError,
    InvalidModelError,
    InvalidParameterError,
    UnknownItemError,
)
from flexmbd.fe import body_from_nastran, read_nastran, read_op2
from flexmbd.model_file import simulate_model

DATA = Path(__file__).parent / "data" / "nastran"
BLOCK_FILES = ["block.op2", "block_big.op2", "block_64.op2", "block_geometry.op2"]


def _writer_module():
    spec = importlib.util.spec_from_file_location("make_op2", DATA / "make_op2.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


Writer = _writer_module().Writer


@pytest.fixture(scope="module")
def block():
    """The block deck, its nodal body (K, M) and the dense eigenpairs of (K, M)."""
    deck = read_nastran(DATA / "block.bdf")
    nodal = deck.body()
    values, vectors = sla.eigh(nodal.stiffness.toarray(), nodal.mass.toarray())
    return deck, nodal, values, vectors


@pytest.fixture(scope="module")
def beam():
    return read_nastran(DATA / "beam.bdf")


def residual(nodal, vectors, eigenvalues):
    """max |K x - w^2 M x| / max |K x| over the modes (x: (n d, k))."""
    k_x = nodal.stiffness @ vectors
    m_x = nodal.mass @ vectors
    return np.abs(k_x - m_x * eigenvalues).max() / np.abs(k_x).max()


def nodal_vectors(results, d):
    """(n d, k) eigenvectors of the file, the first `d` components of each grid."""
    shapes = results.eigenvectors[:, :, :d]
    return shapes.reshape(shapes.shape[0], -1).T


# Reading ---------------------------------------------------------------------------------


@pytest.mark.parametrize("name", BLOCK_FILES)
def test_the_modes_of_the_file_are_eigenpairs_of_the_deck(name, block, assert_close):
    deck, nodal, values, _ = block
    results = read_op2(DATA / name)
    single = results.word_size == 4
    assert results.table == "BOUGV1" and results.basic and results.subcase == 1
    assert np.array_equal(results.node_ids, nodal.node_ids)  # grid ids 1000 + 7 k, sorted
    assert np.all(results.point_types == 1)
    assert results.eigenvectors.shape == (14, 42, 6)
    assert np.array_equal(results.eigenvector_modes, np.arange(1, 15))
    # Solids have no rotations; the vectors are mass-normalized eigenvectors of (K, M).
    assert np.all(results.eigenvectors[:, :, 3:] == 0.0)
    x = nodal_vectors(results, 3)
    elastic = slice(6, None)
    eigenvalues = results.eigenvalues
    tolerance = 3e-6 if single else 1e-11
    assert residual(nodal, x[:, elastic], eigenvalues[elastic]) < tolerance
    assert_close(x.T @ (nodal.mass @ x), np.eye(14), abs=10 * tolerance, what="phi^T M phi")
    assert_close(eigenvalues[elastic], values[6:14], rel=tolerance, what="eigenvalues")
    assert_close(results.cycles, np.sqrt(np.abs(eigenvalues)) / (2 * np.pi), rel=tolerance)
    assert_close(results.radians, 2 * np.pi * results.cycles, rel=tolerance, what="radians")
    if name == "block_geometry.op2":  # no LAMA: the values of the identification records
        assert results.tables == ["GEOM1", "GEOM2", "EPT", "MPT", "OUGV1", "BOUGV1"]
        assert np.all(np.isnan(results.generalized_mass))
    else:
        assert results.tables == ["LAMA", "BOUGV1"]
        assert_close(results.generalized_mass, 1.0, rel=tolerance, what="generalized mass")
        assert_close(results.generalized_stiffness, eigenvalues, rel=1e-6, abs=1e-3)


def test_both_byte_orders_and_word_sizes_read_the_same_modes():
    little = read_op2(DATA / "block.op2")
    big = read_op2(DATA / "block_big.op2")
    wide = read_op2(DATA / "block_64.op2")
    assert (little.byte_order, big.byte_order, wide.byte_order) == ("little", "big", "little")
    assert (little.word_size, big.word_size, wide.word_size) == (4, 4, 8)
    for field in ("eigenvalues", "cycles", "generalized_mass", "eigenvectors"):
        # The 32-bit files hold the 64-bit file's values rounded to single precision.
        assert np.array_equal(getattr(big, field), getattr(little, field)), field
        assert np.array_equal(getattr(wide, field).astype(np.float32), getattr(little, field))
    assert wide.version == little.version == "NX8.5"


def test_the_beam_file_has_six_components_and_the_clamped_grid_at_rest(beam, assert_close):
    results = read_op2(DATA / "beam.op2")
    assert results.table == "OUGV1" and not results.basic
    assert np.array_equal(results.node_ids, np.arange(11, 29, 2))
    assert np.all(results.eigenvectors[:, 0, :] == 0.0)  # grid 11, SPC1 123456
    nodal = beam.body()
    x = nodal_vectors(results, 6)[6:]
    kept = nodal.stiffness[6:, 6:]
    m_kept = nodal.mass[6:, 6:]
    residual = np.abs(kept @ x - (m_kept @ x) * results.eigenvalues).max()
    assert residual < 3e-6 * np.abs(kept @ x).max()
    assert_close(results.mode(3), results.eigenvectors[2], what="mode 3")
    with pytest.raises(UnknownItemError, match="no eigenvector of mode 9"):
        results.mode(9)


def test_summary_lists_tables_and_frequencies():
    text = read_op2(DATA / "block.op2").summary()
    assert "32-bit, little-endian" in text and "tables: LAMA, BOUGV1" in text
    assert "14 modes x 42 points (basic system)" in text and "2267.89" in text


# Bodies ----------------------------------------------------------------------------------


def aligned(body, reference):
    """Signs s (m,) that turn the modes of `body` into those of `reference`."""
    return np.sign(np.sum(body.modes * reference.modes, axis=0))


def check_same_body(body, reference, sign, rel, assert_close):
    """Same modes, modal matrices, invariants and frequencies, the modes of `body` flipped by
    `sign`."""
    scale = np.abs(reference.modes).max()
    assert_close(body.modes * sign, reference.modes, abs=rel * scale, what="modes")
    flip = np.outer(sign, sign)
    for name in ("k_ff", "m_ff"):
        a = np.asarray(getattr(body.invariants, name)) * flip
        b = np.asarray(getattr(reference.invariants, name))
        assert_close(a, b, abs=rel * np.abs(b).max(), what=name)
    for item in dataclasses.fields(reference.invariants):
        a, b = getattr(body.invariants, item.name), getattr(reference.invariants, item.name)
        if item.name in ("k_ff", "m_ff") or b is None or np.ndim(b) == 0:
            if np.ndim(b) == 0 and b is not None:
                assert_close(a, b, rel=1e-12, what=item.name)
            continue
        a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
        if a.shape[-1] == len(sign) and a.ndim >= 1:
            a = a * sign  # modal columns
            if a.ndim >= 2 and a.shape[-2] == len(sign):
                a = a * sign[:, None]
        # Terms that vanish for mean-axis modes (I1 B) are compared with sqrt(m) |B|_M.
        scale = max(np.abs(b).max(), np.sqrt(reference.invariants.mass))
        assert_close(a, b, abs=rel * scale, what=item.name)
    assert_close(body.frequencies, reference.frequencies, rel=rel, what="frequencies")


@pytest.mark.parametrize(("name", "rel"), [("block_64.op2", 1e-9), ("block.op2", 1e-6)])
def test_a_free_block_from_op2_is_the_preprocessors_free_free_body(name, rel, block, assert_close):
    deck = block[0]
    body = body_from_nastran(deck, DATA / name, 8)
    reference = deck.body(reference="mean-axis", modes="free-free", mode_count=8)
    assert body.mode_kind == "external" and body.reference.kind == "mean-axis"
    assert body.modes.shape == (126, 8)
    check_same_body(body, reference, aligned(body, reference), rel, assert_close)
    assert "block" in body.metadata["source"] and "modes 7, 8," in body.metadata["source"]
    # The rigid-body modes 1-6 are left out by default; mode numbers select.
    every = body_from_nastran(DATA / "block.bdf", DATA / name)
    assert every.modes.shape == (126, 8)
    picked = deck.modal_body(DATA / name, [9, 7])
    assert_close(picked.frequencies, body.frequencies[[2, 0]], rel=1e-15, what="picked")


def test_a_clamped_beam_from_op2_is_the_preprocessors_fixed_interface_body(beam, assert_close):
    body = body_from_nastran(beam, DATA / "beam.op2", reference="clamped", reference_nodes="spc1")
    reference = beam.body(
        reference="clamped", reference_nodes="spc1", modes="fixed-interface", mode_count=6
    )
    assert body.dofs_per_node == 6 and body.modes.shape == (48, 6)
    check_same_body(body, reference, aligned(body, reference), 1e-6, assert_close)


def test_eigenvectors_in_the_grids_displacement_systems_are_turned_to_basic(
    beam, tmp_path, assert_close
):
    # The beam's deck with every grid's CD a system turned 90 degrees about x then 30 about
    # z, and its OUGV1 eigenvectors written in that system: the same body as in basic.
    text = (DATA / "beam.bdf").read_text()
    c, s = np.cos(np.pi / 6), np.sin(np.pi / 6)
    axes = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]]) @ np.array(
        [[1, 0, 0], [0, 0, -1], [0, 1.0, 0]]
    )
    b, cpoint = axes[:, 2], axes[:, 0]
    system = "CORD2R,5,,0.,0.,0.," + ",".join(repr(float(v)) for v in b) + "\n,"
    system += ",".join(repr(float(v)) for v in cpoint) + "\n"
    lines = []
    # CBAR orientation vectors are given in GA's displacement system too.
    local_y = ",".join(repr(float(v)) for v in axes.T @ np.array([0.0, 1.0, 0.0]))
    for line in text.splitlines():
        if line.startswith("GRID,"):
            line += ",5"
        if line.startswith("CBAR,"):
            line = line.replace(",0.,1.,0.", "," + local_y)
        lines.append(line)
    turned = tmp_path / "turned.bdf"
    turned.write_text("\n".join(lines).replace("BEGIN BULK\n", "BEGIN BULK\n" + system) + "\n")
    deck = read_nastran(turned)
    assert set(deck.displacement_systems) == set(range(11, 29, 2))
    assert_close(deck.displacement_systems[13], axes, abs=1e-15, what="CD axes")
    results = read_op2(DATA / "beam.op2")
    local = results.eigenvectors.copy()
    local[:, :, :3] = local[:, :, :3] @ axes
    local[:, :, 3:] = local[:, :, 3:] @ axes
    in_cd = dataclasses.replace(results, eigenvectors=local)
    options = {"reference": "clamped", "reference_nodes": "spc1"}
    body = body_from_nastran(deck, in_cd, **options)
    basic = body_from_nastran(beam, results, **options)
    assert_close(body.modes, basic.modes, abs=1e-12, what="modes")
    # A CD system that is not a CORD2R: the deck reads, its OUGV1 modes cannot be turned.
    other = tmp_path / "cylindrical.bdf"
    # (grid 27, the tip, is no CBAR's GA, whose CD would also orient the CBAR)
    other.write_text(turned.read_text().replace("GRID,27,,1.0,0.,0.,5", "GRID,27,,1.0,0.,0.,8"))
    deck = read_nastran(other)
    with pytest.raises(InvalidModelError, match="that of grid 27 .* not a rectangular CORD2R"):
        body_from_nastran(deck, in_cd, **options)


def pendulum(body, node):
    system = fm.System(gravity=(0.0, -9.81, 0.0))
    flexible = system.add_flexible_body(body, name="block")
    system.add_spherical_joint(
        system.add_marker(system.ground, position=body.nodes[node]),
        system.add_node_marker(flexible, int(body.node_ids[node])),
    )
    return system


def test_the_op2_body_swings_like_the_preprocessors(block, assert_close):
    deck = block[0]
    body = body_from_nastran(deck, DATA / "block_64.op2", 4)
    reference = deck.body(reference="mean-axis", modes="free-free", mode_count=4)
    sign = aligned(body, reference)
    runs = [
        fm.simulate(pendulum(b, 0), end_time=0.05, step_size=5e-4, output_interval=0.005)
        for b in (body, reference)
    ]
    a, b = runs[0].coordinates, runs[1].coordinates
    assert_close(a[:, :7], b[:, :7], abs=1e-9, what="frame coordinates")
    assert_close(a[:, 7:] * sign, b[:, 7:], abs=1e-9 * np.abs(b[:, 7:]).max(), what="q_f")
    assert np.abs(b[-1, 3:7] - b[0, 3:7]).max() > 1e-2  # it swung about the corner
    assert np.abs(b[:, 7:]).max() > 0  # and deformed


# Bad bodies ------------------------------------------------------------------------------


def test_a_deck_that_is_not_the_analysed_one_is_refused(block, beam, tmp_path):
    with pytest.raises(UnknownItemError, match="no eigenvector of grid 11") as error:
        body_from_nastran(beam, DATA / "block.op2")
    assert error.value.item == "grid 11"
    softer = tmp_path / "soft.bdf"
    softer.write_text((DATA / "block.bdf").read_text().replace("2.1e11", "1.6e11"))
    with pytest.raises(InvalidModelError, match=r"mode 7 has 2267.89 Hz in the OP2 file and "):
        body_from_nastran(softer, DATA / "block.op2")
    body = body_from_nastran(softer, DATA / "block.op2", frequency_tolerance=None)
    assert body.modes.shape == (126, 8)
    # NaN compared false and let every frequency pass; -1 gave an odd message.
    for bad, message in ((float("nan"), "must be finite"), (-1, "must be >= 0"),
                         ("0.05", "must be a number")):  # fmt: skip
        with pytest.raises(InvalidParameterError, match=f"frequency_tolerance {message}"):
            body_from_nastran(softer, DATA / "block.op2", frequency_tolerance=bad)


def test_modes_on_held_coordinates_and_rigid_modes_are_refused(block):
    deck = block[0]
    with pytest.raises(InvalidModelError, match=r"mode 7 moves grid 1000 in T\d") as error:
        body_from_nastran(deck, DATA / "block.op2", reference="clamped", reference_nodes=[0])
    assert error.value.item == "grid 1000"
    with pytest.raises(InvalidModelError, match="mode 2 is a rigid-body motion"):
        body_from_nastran(deck, DATA / "block.op2", [7, 2])
    with pytest.raises(UnknownItemError, match="no eigenvector of mode 99"):
        body_from_nastran(deck, DATA / "block.op2", [99])
    with pytest.raises(InvalidModelError, match="9 elastic modes asked for, the file has 8"):
        body_from_nastran(deck, DATA / "block.op2", 9)
    with pytest.raises(InvalidParameterError, match="mode_count: body_from_nastran sets it"):
        body_from_nastran(deck, DATA / "block.op2", mode_count=3)
    # A float count was a raw TypeError.
    for bad in (2.5, "7", True, [7.5]):
        with pytest.raises((InvalidParameterError, ArgumentTypeError), match="modes"):
            body_from_nastran(deck, DATA / "block.op2", bad)
    assert body_from_nastran(deck, DATA / "block.op2", np.array([7, 8])).modes.shape[1] == 2


def test_a_mean_axis_frame_needs_modes_orthogonal_to_the_rigid_motions(beam):
    # The clamped beam's modes are not free-free: they move the beam's centre of mass.
    with pytest.raises(InvalidModelError, match="not mass-orthogonal to the rigid"):
        body_from_nastran(beam, DATA / "beam.op2", frequency_tolerance=None)
    body = body_from_nastran(beam, DATA / "beam.op2", reference="none")
    assert body.reference.kind == "none" and body.modes.shape == (54, 6)


# Bad files -------------------------------------------------------------------------------


def eigenvector_file(path, acode=21, tcode=7, num_wide=8, table=b"BOUGV1", values=6):
    """An OP2 file of one eigenvector subtable pair of two grids, by hand."""
    writer = Writer("<", 4)
    writer.header()
    ident = writer.identification(acode, tcode, 1, 1, 4.0, 0.3, num_wide)
    rows = b"".join(writer.words(f"2i{values}f", g * 10 + 1, 1, *range(values)) for g in (5, 6))
    writer.table(table, [ident, rows])
    writer.marker(0)
    path.write_bytes(bytes(writer.out))
    return path


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"tcode": 1007, "num_wide": 14, "values": 12}, "are complex"),
        ({"acode": 91, "tcode": 1007, "num_wide": 14, "values": 12}, "complex eigenvalues"),
        ({"tcode": 2007}, "SORT2"),
        ({"table": b"OUGV2"}, "SORT2"),
        ({"acode": 81}, "buckling"),
        ({"tcode": 4007}, "random"),
        ({"num_wide": 9, "values": 7}, "9 words per point, expected 8"),
    ],
)
def test_other_eigenvector_tables_are_refused_naming_table_and_byte(options, message, tmp_path):
    path = eigenvector_file(tmp_path / "other.op2", **options)
    with pytest.raises(InvalidModelError, match=message) as error:
        read_op2(path)
    table = (options.get("table") or b"BOUGV1").decode()
    assert f"table {table}, byte " in str(error.value)
    assert error.value.item == f"table {table} of '{path}'"


def test_a_hand_written_table_reads_and_other_table_codes_are_skipped(tmp_path, assert_close):
    results = read_op2(eigenvector_file(tmp_path / "one.op2"))
    assert np.array_equal(results.node_ids, [5, 6])
    assert_close(results.eigenvectors[0], np.tile(np.arange(6.0), (2, 1)), abs=0.0)
    assert_close(results.eigenvalues, 4.0, abs=0.0, what="eigenvalue of the record")
    assert_close(results.cycles, np.float32(0.3), abs=0.0, what="cycles of the record")
    static = eigenvector_file(tmp_path / "static.op2", acode=11, tcode=1)
    with pytest.raises(InvalidModelError, match=r"no real eigenvalues .* in the tables BOUGV1"):
        read_op2(static)
    # Eigenvalues without eigenvectors read, but make no body.
    writer = Writer("<", 4)
    writer.header()
    writer.lama(np.array([4.0, 9.0]))
    writer.marker(0)
    path = tmp_path / "lama.op2"
    path.write_bytes(bytes(writer.out))
    lama = read_op2(path)
    assert_close(lama.cycles, np.sqrt([4.0, 9.0]) / (2 * np.pi), rel=1e-7, what="cycles")
    assert lama.eigenvectors.shape[0] == 0 and lama.table == ""
    with pytest.raises(InvalidModelError, match="no eigenvectors .* DISPLACEMENT"):
        body_from_nastran(DATA / "block.bdf", lama)


def test_a_file_without_modes_is_refused(tmp_path):
    writer = Writer(">", 4)
    writer.header()
    writer.table(b"OES1X1", [b"\x00" * 16, b"\x00" * 32])
    writer.marker(0)
    path = tmp_path / "stress.op2"
    path.write_bytes(bytes(writer.out))
    with pytest.raises(InvalidModelError, match=r"no real eigenvalues \(LAMA\).*OES1X1"):
        read_op2(path)


def test_a_truncated_file_names_the_table_and_the_byte(tmp_path):
    data = (DATA / "block.op2").read_bytes()
    path = tmp_path / "cut.op2"
    path.write_bytes(data[:20000])
    with pytest.raises(InvalidModelError, match=r"table BOUGV1, byte \d+: .*truncated file"):
        read_op2(path)


def test_a_record_whose_byte_counts_differ_is_refused(tmp_path):
    data = bytearray((DATA / "block.op2").read_bytes())
    # The LAMA data record: 14 modes x 7 words; its closing byte count is overwritten.
    count = (14 * 28).to_bytes(4, "little")
    start = data.index(count + (1).to_bytes(4, "little"))
    end = start + 4 + 14 * 28
    data[end : end + 4] = (999).to_bytes(4, "little")
    path = tmp_path / "bad.op2"
    path.write_bytes(bytes(data))
    with pytest.raises(
        InvalidModelError, match=f"table LAMA, byte {start}: .* byte count 392 and ends with 999"
    ):
        read_op2(path)


def test_wrong_table_content_is_refused(tmp_path):
    writer = Writer("<", 4)
    writer.header()
    writer.table(b"LAMA", [writer.identification(21, 7, 1, 0, 0.0, 0.0, 7), b"\x00" * 40])
    writer.marker(0)
    path = tmp_path / "lama.op2"
    path.write_bytes(bytes(writer.out))
    with pytest.raises(InvalidModelError, match="40 bytes of eigenvalues, not a multiple of 7"):
        read_op2(path)


def test_not_an_op2_file(tmp_path):
    text = tmp_path / "deck.op2"
    shutil.copy(DATA / "block.bdf", text)
    with pytest.raises(InvalidModelError, match="not an OP2 file"):
        read_op2(text)
    with pytest.raises(FileNotFoundError):
        read_op2(tmp_path / "missing.op2")


def test_a_file_larger_than_the_free_memory_is_refused_before_reading(monkeypatch):
    import flexmbd.fe._memory as memory

    monkeypatch.setattr(memory, "available_memory", lambda: 1000)
    with pytest.raises(InvalidModelError, match=r"would take about .* GB of memory"):
        read_op2(DATA / "block.op2")


def test_several_subcases_need_a_choice(tmp_path):
    writer = Writer("<", 4)
    writer.header()
    pairs = []
    for subcase in (1, 2):
        pairs.append(writer.identification(21, 7, subcase, 1, 4.0 * subcase, 0.3, 8))
        pairs.append(b"".join(writer.words("2i6f", g * 10 + 1, 1, *[subcase] * 6) for g in (5,)))
    writer.table(b"OUGV1", pairs)
    writer.marker(0)
    path = tmp_path / "two.op2"
    path.write_bytes(bytes(writer.out))
    with pytest.raises(InvalidModelError, match="eigenvectors of subcases 1, 2: choose one"):
        read_op2(path)
    second = read_op2(path, subcase=2)
    assert second.subcase == 2 and second.eigenvalues[0] == 8.0
    assert np.all(second.eigenvectors == 2.0)
    with pytest.raises(UnknownItemError, match="no eigenvectors of subcase 3"):
        read_op2(path, subcase=3)


# Model files -----------------------------------------------------------------------------


MODEL = """
name: nastran pendulum
gravity: [0, -9.81, 0]
bodies:
  - name: block
    type: flexible
    nastran: block.bdf
    op2: block_64.op2
    mode_count: 4
markers:
  - {name: pivot, body: ground}
  - {name: corner, body: block, node: 1000}
joints:
  - {type: spherical, marker1: pivot, marker2: corner}
simulation: {end_time: 0.05, step_size: 5.0e-4, output_interval: 0.005}
"""


def test_a_model_file_reads_the_deck_and_its_op2_modes(tmp_path, block, assert_close):
    for name in ("block.bdf", "block_64.op2"):
        shutil.copy(DATA / name, tmp_path / name)
    path = tmp_path / "model.yaml"
    path.write_text(MODEL)
    result = simulate_model(path)
    reference = fm.simulate(
        pendulum(body_from_nastran(block[0], DATA / "block_64.op2", 4), 0),
        end_time=0.05,
        step_size=5e-4,
        output_interval=0.005,
    )
    assert_close(result.coordinates, reference.coordinates, abs=1e-12, what="coordinates")
    # A deck alone is preprocessed; op2 needs a deck; the deck has its material.
    path.write_text(MODEL.replace("    op2: block_64.op2\n", "    modes: free-free\n"))
    assert simulate_model(path).coordinates.shape == result.coordinates.shape
    path.write_text(
        MODEL.replace("nastran: block.bdf", "box: {lengths: [1, 1, 1], divisions: [1, 1, 1]}")
    )
    with pytest.raises(InvalidModelError, match="op2 results go with a Nastran deck"):
        simulate_model(path)
    path.write_text(
        MODEL.replace(
            "    op2:", "    material: {young_modulus: 1, poisson_ratio: 0.3, density: 1}\n    op2:"
        )
    )
    with pytest.raises(InvalidModelError, match="material: not used with nastran"):
        simulate_model(path)
    path.write_text(MODEL.replace("    mode_count: 4", "    mode_count: 40"))
    with pytest.raises(InvalidModelError, match="40 elastic modes asked for, the file has 8"):
        simulate_model(path)
    # A CONM2 is part of the body: the OP2's modes, computed without it, are not this body's.
    deck = (tmp_path / "block.bdf").read_text()
    (tmp_path / "block.bdf").write_text(deck.replace("ENDDATA", "CONM2,77,1000,,2.5\nENDDATA"))
    path.write_text(MODEL)
    with pytest.raises(InvalidModelError, match=r"mode 7 is not mass-orthogonal"):
        simulate_model(path)
    # Other concentrated masses are refused, or skipped knowingly (nastran_skip).
    (tmp_path / "block.bdf").write_text(deck.replace("ENDDATA", "CMASS2,77,2.5,1000,1\nENDDATA"))
    with pytest.raises(InvalidModelError, match=r"CMASS2 77: concentrated masses .* nastran_skip"):
        simulate_model(path)
    path.write_text(MODEL.replace("    op2:", "    nastran_skip: [CMASS2]\n    op2:"))
    assert_close(simulate_model(path).coordinates, reference.coordinates, abs=1e-12)
    path.write_text(
        MODEL.replace(
            "nastran: block.bdf", "box: {lengths: [1, 1, 1], divisions: [1, 1, 1]}"
        ).replace("    op2: block_64.op2\n", "    nastran_skip: [CONM2]\n")
    )
    with pytest.raises(InvalidModelError, match="nastran_skip goes with a Nastran deck"):
        simulate_model(path)
