"""Nastran decks (issue 35): the three field formats, Nastran numbers, coordinate systems,
continuations and INCLUDE files read into the same mesh, K, M and modes as the preprocessor
on the mesh itself; beams with their sections; node sets of the interfaces; DMIG matrices;
bad decks named by file, line and card."""

import numpy as np
import pytest

import flexmbd.fe.preprocess as pp
from flexmbd._core import Material, Section
from flexmbd.errors import InvalidModelError, InvalidParameterError, UnknownItemError
from flexmbd.fe import read_nastran, shapes
from flexmbd.fe.nastran import parse_real, read_dmig

STEEL = Material(2.1e11, 0.3, 7800.0)
NASTRAN_NAMES = {
    "tet4": "CTETRA", "tet10": "CTETRA", "hex8": "CHEXA", "hex20": "CHEXA", "quad4": "CQUAD4",
    "tri3": "CTRIA3", "wedge6": "CPENTA", "wedge15": "CPENTA", "pyramid5": "CPYRAM",
}  # fmt: skip


def number(x, width):
    """The shortest Nastran real of `x` that fits in `width` characters."""
    text = repr(float(x))
    if len(text) <= width and ("." in text or "e" in text):
        return text
    for digits in range(width, 0, -1):
        text = f"{x:.{digits}e}".replace("e+0", "+").replace("e-0", "-").replace("e", "")
        if len(text) <= width:
            return text
    raise ValueError(x)


def card(name, fields, form):
    """One card in the small (8), large (16, with *) or free (commas) field format."""
    if form == "free":
        head, rest = fields[:8], fields[8:]
        lines = [",".join([name] + [str(f) for f in head])]
        while rest:
            lines.append(",".join([""] + [str(f) for f in rest[:8]]))
            rest = rest[8:]
        return "\n".join(lines) + "\n"
    width, per_line = (8, 8) if form == "small" else (16, 4)
    text = []
    first = f"{name}*" if form == "large" else name
    chunks = [fields[i : i + per_line] for i in range(0, max(len(fields), 1), per_line)]
    for k, chunk in enumerate(chunks):
        lead = first if k == 0 else ("*" if form == "large" else "+")
        cells = [(number(f, width) if isinstance(f, float) else str(f)).ljust(width) for f in chunk]
        text.append(lead.ljust(8) + "".join(cells))
    return "\n".join(text) + "\n"


def deck_of(mesh, form, *, aset=(), ids=None, shift=(0.0, 0.0, 0.0), system=None):
    """A bulk data deck of a solid mesh of STEEL (MAT1 1, PSOLID 1), grids in `system`
    (a CORD2R card's fields) when given."""
    ids = np.arange(1, mesh.node_count + 1) * 3 + 100 if ids is None else ids
    lines = ["SOL 103\nCEND\nBEGIN BULK\n$ a comment\n"]
    if system is not None:
        lines.append(card("CORD2R", system["fields"], form))
    for gid, x in zip(ids, mesh.nodes, strict=True):
        local = system["to_local"](x) if system is not None else x
        cp = system["fields"][0] if system is not None else ""
        lines.append(card("GRID", [int(gid), cp] + [float(v) for v in local], form))
    eid = 1
    for kind, connectivity in mesh.elements.items():
        name = NASTRAN_NAMES[kind]
        for nodes in connectivity:
            grid = [int(ids[n]) for n in nodes]
            if kind == "tet10":
                grid[8], grid[9] = grid[9], grid[8]
            if kind == "hex20":  # G13-G16 on the vertical edges, G17-G20 on the top face's
                grid = grid[:12] + grid[16:20] + grid[12:16]
            if kind == "wedge15":  # G10-G12 on the vertical edges, G13-G15 on the top's
                grid = grid[:9] + grid[12:15] + grid[9:12]
            lines.append(card(name, [eid, 1] + grid, form))
            eid += 1
    lines.append(card("MAT1", [1, 2.1e11, "", 0.3, 7800.0], form))
    if any(kind in mesh.elements for kind in ("quad4", "tri3")):
        lines.append(card("PSHELL", [1, 1, 0.002, 1], form))
    else:
        lines.append(card("PSOLID", [1, 1], form))
    if len(aset):
        lines.append(card("ASET1", [123] + [int(ids[n]) for n in aset], form))
    lines.append(card("PARAM", ["POST", -1], form))
    lines.append("ENDDATA\n")
    return "".join(lines)


@pytest.fixture(scope="module")
def bracket():
    return shapes.box((0.6, 0.1, 0.05), (6, 2, 1), "tet4")


def dense(m):
    return m.toarray() if hasattr(m, "toarray") else np.asarray(m)


@pytest.mark.parametrize("form", ["small", "large", "free"])
def test_a_deck_gives_the_preprocessors_body(form, bracket, tmp_path, assert_close):
    face = bracket.node_sets["x0"]
    path = tmp_path / "bracket.bdf"
    path.write_text(deck_of(bracket, form, aset=face))
    deck = read_nastran(path)
    assert_close(deck.mesh.nodes, bracket.nodes, abs=1e-12, what="nodes")
    np.testing.assert_array_equal(deck.mesh.elements["tet4"], bracket.elements["tet4"])
    np.testing.assert_array_equal(deck.mesh.node_sets["aset"], np.sort(face))
    assert deck.mesh.node_ids[:3].tolist() == [103, 106, 109]
    options = dict(reference="interface", modes="craig-bampton", mode_count=4)
    body = deck.body(interfaces=["aset"], **options)
    direct = pp.build_body(bracket.nodes, bracket.elements, STEEL, interfaces=[face], **options)
    for name in ("k_ff", "m_ff"):
        want = dense(getattr(direct.invariants, name))
        got = dense(getattr(body.invariants, name))
        assert_close(got, want, abs=1e-9 * np.abs(want).max(), what=name)
    assert_close(body.frequencies, direct.frequencies, rel=1e-9, what="frequencies")
    assert_close(dense(body.stiffness), dense(direct.stiffness), abs=1e-9 * direct.stiffness.max())
    assert_close(dense(body.mass), dense(direct.mass), abs=1e-9 * direct.mass.max(), what="M")


def test_tet10_and_hex8_and_a_rotated_system(tmp_path, assert_close):
    tet10 = shapes.box((0.4, 0.1, 0.1), (2, 1, 1), "tet10")
    angle = 0.3
    rot = np.array(
        [[np.cos(angle), -np.sin(angle), 0.0], [np.sin(angle), np.cos(angle), 0.0], [0, 0, 1.0]]
    )
    origin = np.array([1.0, 2.0, 3.0])
    # CORD2R 5: A = origin, B on its z axis, C in its x-z plane.
    a, b, c = origin, origin + rot[:, 2], origin + rot[:, 0]
    system = {
        "fields": [5, 0] + [float(v) for v in (*a, *b, *c)],
        "to_local": lambda x: rot.T @ (x - origin),
    }
    path = tmp_path / "tet10.bdf"
    path.write_text(deck_of(tet10, "large", system=system))
    deck = read_nastran(path)
    # Local coordinates in 16 characters: 11 significant digits.
    assert_close(deck.mesh.nodes, tet10.nodes, abs=1e-10, what="nodes")
    np.testing.assert_array_equal(deck.mesh.elements["tet10"], tet10.elements["tet10"])
    # CHEXA of 8 and of 20 grids (G9-G12 on the bottom face's edges, G13-G16 on the vertical
    # ones, G17-G20 on the top face's).
    for kind, form in (("hex8", "small"), ("hex20", "large")):
        hexa = shapes.box((0.4, 0.1, 0.1), (2, 1, 1), kind)
        path.write_text(deck_of(hexa, form))
        deck = read_nastran(path)
        np.testing.assert_array_equal(deck.mesh.elements[kind], hexa.elements[kind])
        stiffness = dense(deck.body().stiffness)
        direct = pp.build_body(hexa.nodes, hexa.elements, STEEL)
        assert_close(stiffness, dense(direct.stiffness), abs=1e-9 * direct.stiffness.max())
    quadratic = hexa
    # A mid-edge grid left blank (G20, the last field of the card's third line) is refused,
    # not read as some other element.
    lines = deck_of(quadratic, "free").splitlines()
    third = lines.index(next(line for line in lines if line.startswith("CHEXA"))) + 2
    lines[third] = ",".join(lines[third].split(",")[:-1] + [""])
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(InvalidModelError, match="19 grids: .*CHEXA of 8 or 20, CPENTA"):
        read_nastran(path)


def test_chexa20_grids_by_the_nastran_figure(tmp_path, assert_close):
    # A unit cube written by hand as the CHEXA figure numbers it: G9-G12 on G1-G2 .. G4-G1,
    # G13-G16 on G1-G5 .. G4-G8, G17-G20 on G5-G6 .. G8-G5 (grid k at its point; G13 at
    # (0, 0, 0.5)). Read (the order of Gmsh's and meshio's Nastran readers too), node 8 + e of
    # the hex20 is the midpoint of its edge e.
    nastran_edges = [(0, 1), (1, 2), (2, 3), (3, 0), (0, 4), (1, 5), (2, 6), (3, 7),
                     (4, 5), (5, 6), (6, 7), (7, 4)]  # fmt: skip
    check_figure_element(tmp_path, "CHEXA", shapes.HEX8_CORNERS, nastran_edges, "hex20",
                         shapes.HEX20_EDGES, 1.0, assert_close)  # fmt: skip


def check_figure_element(tmp_path, name, corners, nastran_edges, kind, edges, volume, close):
    """One element `name` written by hand as its Nastran figure numbers it (the corners, then
    the midpoints of `nastran_edges`): read as `kind`, its mid-edge nodes are the midpoints
    of `edges` (the kind's order) and its mass that of `volume` of steel."""
    points = [np.array(c, dtype=float) for c in corners]
    points += [0.5 * (points[p] + points[q]) for p, q in nastran_edges]
    lines = ["BEGIN BULK\n"] + [card("GRID", [k + 1, ""] + [float(v) for v in x], "large")
                               for k, x in enumerate(points)]  # fmt: skip
    lines.append(card(name, [1, 1] + list(range(1, len(points) + 1)), "large"))
    lines += [card("MAT1", [1, 2.1e11, "", 0.3, 7800.0], "large"), card("PSOLID", [1, 1], "large")]
    path = tmp_path / "element.bdf"
    path.write_text("".join(lines) + "ENDDATA\n")
    deck = read_nastran(path)
    nodes = deck.mesh.nodes[deck.mesh.elements[kind][0]]
    for e, (p, q) in enumerate(edges):
        first = len(corners) + e
        close(nodes[first], 0.5 * (nodes[p] + nodes[q]), abs=1e-15, what=f"edge {e}")
    close(deck.body().invariants.mass, 7800.0 * volume, rel=1e-12, what="mass")


def test_cpenta_of_6_and_15_grids(tmp_path, assert_close):
    # CPENTA was refused. G1-G3 a triangle, G4-G6 the other (G4 opposite G1); of 15 grids,
    # G7-G9 on G1-G2, G2-G3, G3-G1, G10-G12 on G1-G4 .. G3-G6, G13-G15 on G4-G5, G5-G6,
    # G6-G4 (the order of meshio's Nastran reader). A right prism written by hand as the
    # figure numbers it: read, every wedge15 mid-edge node is the midpoint of its edge.
    nastran_edges = [(0, 1), (1, 2), (2, 0), (0, 3), (1, 4), (2, 5), (3, 4), (4, 5), (5, 3)]
    corners = ((0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 2), (1, 0, 2), (0, 1, 2))
    check_figure_element(tmp_path, "CPENTA", corners, nastran_edges, "wedge15",
                         shapes.WEDGE15_EDGES, 1.0, assert_close)  # fmt: skip
    path = tmp_path / "prism.bdf"
    # Meshes of both: the same elements and stiffness as the preprocessor's.
    for kind in ("wedge6", "wedge15"):
        prisms = shapes.box((0.4, 0.1, 0.1), (2, 1, 1), kind)
        path.write_text(deck_of(prisms, "free"))
        deck = read_nastran(path)
        np.testing.assert_array_equal(deck.mesh.elements[kind], prisms.elements[kind])
        direct = pp.build_body(prisms.nodes, prisms.elements, STEEL)
        assert_close(dense(deck.body().stiffness), dense(direct.stiffness),
                     abs=1e-9 * direct.stiffness.max())  # fmt: skip


def test_cpyram_of_5_grids(tmp_path, assert_close):
    # CPYRAM was an unknown card. G1-G4 the base, G5 the apex: a mesh of pyramids through a
    # deck has the preprocessor's elements and stiffness; one written by hand (base of 2 x 1,
    # height 0.6) the mass of its volume. Other grid counts (13: the quadratic pyramid) are
    # refused by name.
    path = tmp_path / "pyramids.bdf"
    pyramids = shapes.box((0.4, 0.1, 0.1), (2, 1, 1), "pyramid5")
    path.write_text(deck_of(pyramids, "small"))
    deck = read_nastran(path)
    np.testing.assert_array_equal(deck.mesh.elements["pyramid5"], pyramids.elements["pyramid5"])
    direct = pp.build_body(pyramids.nodes, pyramids.elements, STEEL)
    assert_close(dense(deck.body().stiffness), dense(direct.stiffness),
                 abs=1e-9 * direct.stiffness.max())  # fmt: skip
    corners = ((0, 0, 0), (2, 0, 0), (2, 1, 0), (0, 1, 0), (0.7, 0.4, 0.6))
    check_figure_element(tmp_path, "CPYRAM", corners, [], "pyramid5", [], 0.4, assert_close)
    text = path.read_text()
    first = next(line for line in text.splitlines() if line.startswith("CPYRAM"))
    path.write_text(text.replace(first, first + "106"))
    with pytest.raises(InvalidModelError, match="6 grids: .*CPYRAM of 5"):
        read_nastran(path)


def beam_deck(form, property_card):
    lines = ["BEGIN BULK\n"]
    for k in range(5):
        lines.append(card("GRID", [k + 1, "", 0.25 * k, 0.0, 0.0], form))
    for k in range(4):
        lines.append(card("CBAR", [10 + k, 7, k + 1, k + 2, 0.0, 1.0, 1.0], form))
    lines.append(card("MAT1", [3, 2.1e11, 8.1e10, "", 7800.0], form))
    lines.append(card(*property_card, form))
    lines.append(card("SPC1", [1, 123456, 1], form))
    lines.append(card("RBE2", [900, 99, 123456, 5], form))
    lines.append(card("GRID", [99, "", 1.2, 0.0, 0.0], form))
    return "".join(lines)


@pytest.mark.parametrize(
    ("property_card", "section"),
    [
        (("PBAR", [7, 3, 2e-4, 3e-8, 5e-8, 4e-8]), Section(2e-4, 5e-8, 3e-8, 4e-8)),
        (("PBARL", [7, 3, "", "BAR", "", "", "", "", 0.02, 0.01]), Section.rectangle(0.02, 0.01)),
    ],
)
def test_beams_with_their_sections_and_orientation(property_card, section, tmp_path, assert_close):
    path = tmp_path / "beam.bdf"
    path.write_text(beam_deck("small", property_card))
    deck = read_nastran(path)
    got_section, orientation = deck.section()
    assert_close(orientation, [0.0, 1.0, 1.0], abs=0.0, what="orientation")
    material = deck.material()
    assert_close(material.poisson_ratio, 2.1e11 / (2 * 8.1e10) - 1, rel=1e-14, what="nu from G")
    body = deck.body(reference="clamped", reference_nodes="spc1")
    nodes = np.column_stack([0.25 * np.arange(5), np.zeros(5), np.zeros(5)])
    elements = {"beam2": np.column_stack([np.arange(4), np.arange(1, 5)])}
    nu = 2.1e11 / (2 * 8.1e10) - 1
    direct = pp.build_body(
        nodes, elements, Material(2.1e11, nu, 7800.0), section=section,
        orientation=(0.0, 1.0, 1.0), reference="clamped", reference_nodes=[0],
    )  # fmt: skip
    assert_close(dense(body.stiffness), dense(direct.stiffness), abs=1e-9 * direct.stiffness.max())
    assert_close(dense(body.mass), dense(direct.mass), abs=1e-9 * direct.mass.max(), what="M")
    # The RBE2's reference grid 99 belongs to no element: not a node; its dependent is.
    assert 99 not in deck.mesh.node_ids.tolist()
    assert deck.mesh.node_ids[deck.mesh.node_sets["rbe2_900"]].tolist() == [5]


def test_offset_conm2_on_beam_grids(tmp_path, assert_close):
    # CONM2 with its centre of gravity offset (X1-X3 in the basic system, CID -1 the centre
    # itself) on the grids of beams, which rotate: masses of the body whose centres move with
    # the grid's rotation (build_body's point_masses with offsets); two on one grid add up.
    property_card = ("PBAR", [7, 3, 2e-4, 3e-8, 5e-8, 4e-8])
    inertia = [0.02, 0.001, 0.03, 0.0, 0.002, 0.04]  # I11 I21 I22 I31 I32 I33
    j = np.array([[0.02, -0.001, 0.0], [-0.001, 0.03, -0.002], [0.0, -0.002, 0.04]])
    first = card("CONM2", [901, 5, "", 2.0, 0.1, 0.0, 0.05, ""] + inertia, "small")
    centre = card("CONM2", [902, 3, -1, 1.5, 0.5, 0.2, 0.0], "small")
    second = card("CONM2", [903, 5, "", 1.0, 0.0, -0.1, 0.0], "small")
    path = tmp_path / "beam.bdf"
    path.write_text(beam_deck("small", property_card) + first + centre + second)
    deck = read_nastran(path)
    body = deck.body(reference="clamped", reference_nodes="spc1")
    bare = read_nastran(_written(tmp_path, "bare.bdf", beam_deck("small", property_card)))
    plain = bare.body(reference="clamped", reference_nodes="spc1")
    parts = {4: [(2.0, j, np.array([0.1, 0.0, 0.05])), (1.0, np.zeros((3, 3)), [0.0, -0.1, 0.0])]}
    parts[2] = [(1.5, np.zeros((3, 3)), np.array([0.0, 0.2, 0.0]))]  # grid 3 is at (0.5, 0, 0)
    extra = sum(
        pp.point_mass_matrix({node: part}, 5, 6) for node, group in parts.items() for part in group
    )
    assert_close(dense(body.mass), dense(plain.mass + extra), abs=1e-12, what="mass matrix")
    assert_close(body.invariants.mass, plain.invariants.mass + 4.5, rel=1e-12, what="mass")
    moment = 2.0 * np.array([1.1, 0.0, 0.05]) + 1.5 * np.array([0.5, 0.2, 0.0])
    moment += 1.0 * np.array([1.0, -0.1, 0.0])
    assert_close(body.invariants.first_moment - plain.invariants.first_moment, moment, abs=1e-12)


def hinged_beam_deck(form, *, name="CBAR", offt="", pin="56", offset=0.02, extra=()):
    """Grids 1-5 along x (1 m; grid 3's displacement system turned by CORD2R 5: x' = x, y' =
    z, z' = -y), clamped at grids 1 and 5 (SPC1 1), four beams 10-13 whose axis runs `offset`
    above the grids (WA = WB = (0, 0, offset) in the grids' displacement systems: (0, offset,
    0) at grid 3), the pin flags `pin` at end B of beam 11 (a hinge at grid 3). `extra`:
    (index, value) fields of beam 10 replaced (0-based data fields)."""
    pbar = ("PBAR", [7, 3, 2e-4, 3e-8, 5e-8, 4e-8])
    pbeam = ("PBEAM", [7, 3, 2e-4, 3e-8, 5e-8, "", 4e-8])
    lines = [
        "BEGIN BULK\n",
        card("CORD2R", [5, "", 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 1.0, 0.0, 0.0], form),
    ]
    for k in range(5):
        lines.append(card("GRID", [k + 1, "", 0.25 * k, 0.0, 0.0, 5 if k == 2 else ""], form))
    for k in range(4):
        ga, gb = k + 1, k + 2
        w = [(0.0, offset, 0.0) if g == 3 else (0.0, 0.0, offset) for g in (ga, gb)]
        # y of the basic system, in GA's displacement system unless OFFT is B..
        v = (0.0, 0.0, -1.0) if ga == 3 and not offt.startswith("B") else (0.0, 1.0, 0.0)
        fields = [10 + k, 7, ga, gb, *v, offt, "", pin if k == 1 else "", *w[0], *w[1]]
        for index, value in extra if k == 0 else ():
            fields += [""] * (index + 1 - len(fields))
            fields[index] = value
        lines.append(card(name, fields, form))
    lines.append(card("MAT1", [3, 2.1e11, 8.1e10, "", 7800.0], form))
    lines.append(card(*(pbar if name == "CBAR" else pbeam), form))
    lines.append(card("SPC1", [1, 123456, 1, 5], form))
    return "".join(lines)


@pytest.mark.parametrize(
    ("form", "name"), [("small", "CBAR"), ("large", "CBEAM"), ("free", "CBAR")]
)
def test_beam_offsets_and_pin_flags_of_a_deck(form, name, tmp_path, assert_close):
    # The deck's offsets (turned from grid 3's displacement system to the basic one) and pin
    # flags give build_body's body with the same beam_offsets and beam_releases: matrices
    # and frequencies. A force P along z at the hinge: each half, clamped at its far end, is
    # a cantilever whose tip the hinge frees (the offsets along z take no moment from it, and
    # the axial shifts of both halves at the hinge are equal), w = P a^3 / (6 E I_y), a =
    # 0.5 m; without the pin flags the beam is clamped at both ends: P L^3 / (192 E I_y).
    path = tmp_path / "hinge.bdf"
    path.write_text(hinged_beam_deck(form, name=name))
    deck = read_nastran(path)
    offsets = np.zeros((4, 2, 3))
    offsets[:, :, 2] = 0.02
    assert_close(deck.beam_offsets, offsets, abs=1e-15, what="offsets")
    releases = np.zeros((4, 12), dtype=bool)
    releases[1, [10, 11]] = True
    assert deck.beam_releases.tolist() == releases.tolist()
    options = dict(reference="clamped", modes="fixed-interface", mode_count=6)
    body = deck.body(reference_nodes="spc1", **options)
    nodes = np.column_stack([0.25 * np.arange(5), np.zeros(5), np.zeros(5)])
    elements = {"beam2": np.column_stack([np.arange(4), np.arange(1, 5)])}
    nu = 2.1e11 / (2 * 8.1e10) - 1
    direct = pp.build_body(
        nodes, elements, Material(2.1e11, nu, 7800.0), section=Section(2e-4, 5e-8, 3e-8, 4e-8),
        orientation=(0.0, 1.0, 0.0), beam_offsets=offsets, beam_releases=releases,
        reference_nodes=[0, 4], **options,
    )  # fmt: skip
    assert_close(dense(body.stiffness), dense(direct.stiffness), abs=1e-9 * direct.stiffness.max())
    assert_close(dense(body.mass), dense(direct.mass), abs=1e-9 * direct.mass.max(), what="M")
    assert_close(body.frequencies, direct.frequencies, rel=1e-9, what="frequencies")
    force, ei = 100.0, 2.1e11 * 5e-8
    f = np.zeros(30)
    f[6 * 2 + 2] = force
    nodal = deck.body(reference="clamped", reference_nodes="spc1")
    w = pp.static_displacements(nodal, f)[14]
    assert_close(w, force * 0.5**3 / (6 * ei), rel=1e-9, what="deflection at the hinge")
    path.write_text(hinged_beam_deck(form, name=name, pin=""))
    whole = read_nastran(path).body(reference="clamped", reference_nodes="spc1")
    assert read_nastran(path).beam_releases is None
    w = pp.static_displacements(whole, f)[14]
    assert_close(w, force / (192 * ei), rel=1e-9, what="deflection without the hinge")


@pytest.mark.parametrize(
    ("name", "extra", "error", "match"),
    [
        ("CBAR", [(7, "GOO")], InvalidModelError, r"OFFT GOO: the offset at end A in the element"),
        ("CBAR", [(7, "GXG")], InvalidModelError, r"OFFT 'GXG' \(field 9\) is not one of GGG"),
        ("CBAR", [(8, "7")], InvalidModelError, r"pin flag PA = '7' \(field 10\)"),
        ("CBAR", [(8, "123456")], InvalidModelError, r"pin flag PA = '123456'"),
        ("CBAR", [(8, "11")], InvalidModelError, r"pin flag PA = '11'"),
        ("CBEAM", [(7, 1.5)], InvalidModelError, r"BIT = 1.5 \(built-in twist, field 9\)"),
        ("CBEAM", [(16, 101)], InvalidModelError, r"SA, SB \(scalar points of warping"),
    ],
)
def test_refused_beam_options_name_the_file_line_and_card(name, extra, error, match, tmp_path):
    path = tmp_path / "bad.bdf"
    path.write_text(hinged_beam_deck("small", name=name, extra=extra))
    with pytest.raises(error, match=rf"bad.bdf, line \d+: {name}: element 10: {match}"):
        read_nastran(path)


def test_offsets_in_an_undefined_displacement_system_are_refused(tmp_path):
    path = tmp_path / "bad.bdf"
    text = hinged_beam_deck("small").replace(
        "GRID    2               0.25    0.0     0.0",
        "GRID    2               0.25    0.0     0.0     9",
    )
    path.write_text(text)
    with pytest.raises(UnknownItemError, match=r"line \d+: CBAR uses coordinate system 9"):
        read_nastran(path)
    # OFFT BGG: the orientation vector in the basic system (also at grid 3), the offsets in
    # the grids' displacement systems.
    path.write_text(hinged_beam_deck("small", offt="BGG"))
    deck = read_nastran(path)
    assert deck.section()[1].tolist() == [0.0, 1.0, 0.0]
    assert deck.beam_offsets[2, 0].tolist() == [0.0, 0.0, 0.02]


def test_nastran_numbers():
    for text, value in [
        ("1.5", 1.5), ("1.5-3", 1.5e-3), ("-2.5+4", -2.5e4), ("7.+10", 7e10), ("1.D5", 1e5),
        (".5E-2", 0.005), ("3", 3.0), ("-.25-1", -0.025),
    ]:  # fmt: skip
        assert parse_real(text) == value, text
    assert parse_real("abc") is None and parse_real("1.2.3") is None


def test_dmig_matrices(tmp_path, assert_close):
    rng = np.random.default_rng(2)
    a = rng.normal(size=(6, 6))
    k = a @ a.T
    dofs = [(g, c) for g in (11, 12) for c in (1, 2, 3)]
    lines = ["BEGIN BULK\n", card("DMIG", ["KAAX", 0, 6, 2, "", "", "", 6], "free")]
    for j, (gj, cj) in enumerate(dofs):
        entries = []
        for i in range(j, 6):  # the lower triangle of column j
            entries += [dofs[i][0], dofs[i][1], float(k[i, j]), ""]
        lines.append(card("DMIG", ["KAAX", gj, cj, ""] + entries, "large"))
    path = tmp_path / "k.pch"
    path.write_text("".join(lines))
    matrix = read_dmig(path)["KAAX"]
    assert matrix.form == 6
    assert_close(matrix.to_matrix(dofs).toarray(), k, rel=1e-10, what="K from DMIG")
    with pytest.raises(UnknownItemError, match="grid 11 component 1"):
        matrix.to_matrix(dofs[1:])


def test_include_files_and_continuation_markers(bracket, tmp_path, assert_close):
    text = deck_of(bracket, "small")
    head, rest = text.split("BEGIN BULK\n")
    (tmp_path / "part").mkdir()
    (tmp_path / "part" / "mesh.bdf").write_text(rest.replace("ENDDATA\n", ""))
    (tmp_path / "main.bdf").write_text(head + "BEGIN BULK\nINCLUDE 'part/mesh.bdf'\nENDDATA\n")
    deck = read_nastran(tmp_path / "main.bdf")
    assert_close(deck.mesh.nodes, bracket.nodes, abs=1e-12, what="nodes")


def test_bad_decks_name_the_file_line_and_card(bracket, tmp_path):
    path = tmp_path / "bad.bdf"
    text = deck_of(bracket, "small")
    path.write_text(text.replace("PARAM   POST", "CQUAD8  POST"))
    with pytest.raises(InvalidModelError, match=r"bad.bdf, line \d+: CQUAD8: unsupported card"):
        read_nastran(path)
    lines = text.splitlines()
    ctetra = next(i for i, line in enumerate(lines) if line.startswith("CTETRA"))
    broken = list(lines)
    broken[ctetra] = broken[ctetra][:32] + "99999".ljust(8) + broken[ctetra][40:]
    path.write_text("\n".join(broken))
    with pytest.raises(UnknownItemError, match="refers to grid 99999"):
        read_nastran(path)
    path.write_text(text.replace("MAT1    1 ", "MAT1    2 "))
    with pytest.raises(UnknownItemError, match="material 1, which no MAT1 defines"):
        read_nastran(path).material()
    mat1 = next(line for line in lines if line.startswith("MAT1"))
    path.write_text(text.replace(mat1, mat1[:16] + "abc".ljust(8) + mat1[24:]))
    with pytest.raises(InvalidModelError, match=r"MAT1: field 3 \(E\) is not a number: 'abc'"):
        read_nastran(path)
    path.write_text("BEGIN BULK\n        1       2\n")
    with pytest.raises(InvalidModelError, match="line 2: a continuation line without a card"):
        read_nastran(path)
    with pytest.raises(FileNotFoundError):
        read_nastran(tmp_path / "missing.bdf")


def test_wtmass_scales_the_mass_and_concentrated_masses_are_not_left_out(
    bracket, tmp_path, assert_close
):
    # Before, PARAM,WTMASS and CONM2 were skipped: a deck in lb-in-s units with a 10 kg
    # CONM2 made a body of 1.56 kg instead of 11.56, its first frequency 8.4 Hz for about 1.6.
    text = deck_of(bracket, "small")
    steel = read_nastran(_written(tmp_path, "steel.bdf", text)).body()
    mat1 = card("MAT1", [1, 2.1e11, "", 0.3, 7800.0], "small")
    scaled = text.replace(mat1, card("MAT1", [1, 2.1e11, "", 0.3, 7800.0 * 4], "small"))
    scaled = scaled.replace("ENDDATA", card("PARAM", ["WTMASS", 0.25], "small") + "ENDDATA")
    deck = read_nastran(_written(tmp_path, "scaled.bdf", scaled))
    assert_close(deck.material().density, 7800.0, rel=1e-12, what="RHO x WTMASS")
    body = deck.body()
    assert_close(body.invariants.mass, steel.invariants.mass, rel=1e-12, what="mass")
    bad = scaled.replace("WTMASS  0.25", "WTMASS  -1.")
    with pytest.raises(InvalidModelError, match="WTMASS must be a positive number, got -1"):
        read_nastran(_written(tmp_path, "bad.bdf", bad))

    # CONM2 at a grid of the elements: a point mass of the body (WTMASS applied, as Nastran
    # does to its whole structural mass), the body of build_body's point_masses.
    conm2 = card("CONM2", [900, 103, "", 10.0], "small")
    path = _written(tmp_path, "conm2.bdf", text.replace("ENDDATA", conm2 + "ENDDATA"))
    with_mass = read_nastran(path).body()
    assert_close(with_mass.invariants.mass, steel.invariants.mass + 10.0, rel=1e-12, what="m")
    direct = pp.build_body(bracket.nodes, bracket.elements, STEEL, point_masses={0: 10.0})
    for name in ("first_moment", "second_moment", "i1", "ibar"):
        assert_close(
            getattr(with_mass.invariants, name),
            getattr(direct.invariants, name),
            rel=1e-12,
            abs=1e-12,
            what=name,
        )
    scaled_path = _written(
        tmp_path, "conm2_scaled.bdf", scaled.replace("ENDDATA", conm2 + "ENDDATA")
    )
    assert_close(
        read_nastran(scaled_path).body().invariants.mass,
        steel.invariants.mass + 2.5,
        rel=1e-12,
        what="CONM2 mass x WTMASS",
    )
    # Where the body cannot carry it: refused, naming the card and the way out.
    for fields, match in (
        (
            [900, 103, "", 10.0, 0.1],
            r"CONM2 900: an offset \[0.1, 0.0, 0.0\] on grid 103, a node of",
        ),
        ([900, 103, "", 10.0, "", "", "", "", 1.0], r"a rotary inertia on grid 103, a node of"),
        ([900, 99999, "", 10.0], r"CONM2 900 refers to grid 99999"),
        ([900, 103, "", 1.0, "", "", "", "", -1.0], r"rotary inertia .* is not positive semi"),
    ):
        bad_path = _written(
            tmp_path,
            "conm2_bad.bdf",
            text.replace("ENDDATA", card("CONM2", fields, "small") + "ENDDATA"),
        )
        with pytest.raises((InvalidModelError, UnknownItemError), match=match) as info:
            read_nastran(bad_path)
        assert (
            "skip=['CONM2']" in str(info.value)
            or "99999" in str(info.value)
            or "semi" in str(info.value)
        )
    twice = conm2 + card("CONM2", [900, 106, "", 1.0], "small")
    bad_path = _written(tmp_path, "twice.bdf", text.replace("ENDDATA", twice + "ENDDATA"))
    with pytest.raises(InvalidModelError, match=r"element id 900 is defined twice"):
        read_nastran(bad_path)
    cmass = card("CMASS2", [901, 10.0, 103, 1], "small")
    path = _written(tmp_path, "cmass.bdf", text.replace("ENDDATA", cmass + "ENDDATA"))
    with pytest.raises(
        InvalidModelError, match=r"cmass.bdf, line \d+: CMASS2: CMASS2 901: concentrated masses"
    ) as info:
        read_nastran(path)
    assert "skip=['CMASS2']" in str(info.value)
    # Skipped knowingly: the body without the mass.
    skipped = read_nastran(path, skip=["cmass2"]).body()
    assert_close(skipped.invariants.mass, steel.invariants.mass, rel=1e-12, what="mass")
    with pytest.raises(InvalidParameterError, match="skip: GRID cannot be skipped"):
        read_nastran(path, skip="GRID")
    with pytest.raises(InvalidParameterError, match="skip: card names"):
        read_nastran(path, skip=5)


def _written(folder, name, text):
    path = folder / name
    path.write_text(text)
    return path


def test_a_deck_larger_than_the_free_memory_is_refused_before_reading(
    bracket, tmp_path, monkeypatch
):
    import flexmbd.fe._memory as memory

    path = tmp_path / "big.bdf"
    path.write_text(deck_of(bracket, "small"))
    monkeypatch.setattr(memory, "available_memory", lambda: 1000)
    with pytest.raises(InvalidModelError, match=r"would take about .* GB of memory; 0.0 GB"):
        read_nastran(path)


@pytest.mark.parametrize("element", ["quad4", "tri3"])
def test_shells_from_cquad4_ctria3_and_pshell(element, tmp_path, assert_close):
    plate = shapes.plate((0.4, 0.2), (4, 2), element)
    path = tmp_path / "plate.bdf"
    path.write_text(deck_of(plate, "free"))
    deck = read_nastran(path)
    np.testing.assert_array_equal(deck.mesh.elements[element], plate.elements[element])
    assert deck.shell().thickness == pytest.approx(0.002, rel=1e-15)
    body = deck.body()
    direct = pp.build_body(plate.nodes, plate.elements, STEEL, shell=0.002)
    assert_close(dense(body.stiffness), dense(direct.stiffness), abs=1e-9 * direct.stiffness.max())
    assert_close(dense(body.mass), dense(direct.mass), abs=1e-9 * direct.mass.max(), what="M")
    path.write_text(deck_of(plate, "free").replace("PSHELL,1,1,0.002,1", "PSHELL,1,1,0.002,1,2."))
    with pytest.raises(InvalidModelError, match=r"12I/T\*\*3 = 2.0 is not supported"):
        read_nastran(path).body()
    # A membrane (MID2 blank) had full bending stiffness; a non-structural mass and corner
    # thicknesses were ignored (the mass lost, a 4 mm plate taken as 2 mm).
    for pshell, match in (
        ("PSHELL,1,1,0.002", "MID2 is blank: in Nastran a membrane"),
        ("PSHELL,1,1,0.002,1,,1,,5.0", r"NSM = 5.0 \(non-structural mass per area\)"),
    ):
        path.write_text(deck_of(plate, "free").replace("PSHELL,1,1,0.002,1", pshell))
        with pytest.raises(InvalidModelError, match=match):
            read_nastran(path).body()
    name = NASTRAN_NAMES[element]
    count = 4 if element == "quad4" else 3
    first = deck_of(plate, "free").split(f"\n{name},", 1)
    line, rest = first[1].split("\n", 1)
    corners = ",".join(["0.004"] * count)
    path.write_text(f"{first[0]}\n{name},{line}\n,,,{corners}\n{rest}")
    with pytest.raises(InvalidModelError, match=r"corner thicknesses \(TFLAG, T1-T"):
        read_nastran(path)


def write_op4(path, matrices, sparse=False):
    """ASCII OP4 (OUTPUT4, FORMATTED) of real double matrices: {name: (form, dense array)}."""
    lines = []

    def numbers(values):
        for k in range(0, len(values), 3):
            lines.append("".join(f"{v:23.16E}" for v in values[k : k + 3]))

    for name, (form, a) in matrices.items():
        nrow, ncol = a.shape
        lines.append(f"{ncol:8d}{nrow:8d}{form:8d}{2:8d}{name:<8s}1P,3E23.16")
        for j in range(ncol):
            rows = np.flatnonzero(a[:, j])
            if not len(rows):
                continue
            if not sparse:
                first, last = rows[0], rows[-1]
                lines.append(f"{j + 1:8d}{first + 1:8d}{last - first + 1:8d}")
                numbers(a[first : last + 1, j])
                continue
            strips = np.split(rows, np.flatnonzero(np.diff(rows) > 1) + 1)
            lines.append(f"{j + 1:8d}{0:8d}{sum(1 + len(s) for s in strips):8d}")
            for s in strips:
                lines.append(f"{65536 * (len(s) + 1) + s[0] + 1:d}")
                numbers(a[s, j])
        lines.append(f"{ncol + 1:8d}{1:8d}{1:8d}")
        numbers([1.0])
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize("sparse", [False, True])
def test_op4_matrices(sparse, tmp_path, assert_close):
    from flexmbd.fe.nastran import read_op4

    rng = np.random.default_rng(5)
    k = rng.normal(size=(7, 7))
    k = k @ k.T
    k[np.abs(k) < 1.0] = 0.0  # gaps: several strips per column
    rect = np.zeros((4, 3))
    rect[1, 0], rect[3, 2] = -2.5e-7, 4.0
    path = write_op4(tmp_path / "kaa.op4", {"KAA": (6, k), "PHIX": (2, rect)}, sparse=sparse)
    matrices = read_op4(path)
    assert sorted(matrices) == ["KAA", "PHIX"]
    form, got = matrices["KAA"]
    assert form == 6
    assert_close(got.toarray(), k, rel=1e-15, what="KAA")
    assert_close(matrices["PHIX"][1].toarray(), rect, rel=1e-15, what="PHIX")
    text = path.read_text().splitlines()
    text[0] = text[0][:24] + f"{4:8d}" + text[0][32:]  # complex
    path.write_text("\n".join(text))
    with pytest.raises(InvalidModelError, match=r"kaa.op4, line 1: matrix KAA: type 4"):
        read_op4(path)
    path.write_bytes(b"\x18\x00\x00\x00binary")
    with pytest.raises(InvalidModelError, match="binary OP4"):
        read_op4(path)
