"""SID export and import (issue 35): the fields' meaning checked against brute-force sums over
the mass points of a beam and a solid, the round trip body -> SID -> body, simulations of the
round-tripped body, damping, node selection, and bad files."""

import numpy as np
import pytest

import flexmbd as fm
import flexmbd.fe.preprocess as pp
from flexmbd._core import Material, Section
from flexmbd.errors import InvalidModelError, UnknownItemError
from flexmbd.fe import read_sid, shapes, write_sid
from flexmbd.fe.sid import SidData, load_sid_data
from flexmbd.system import elastic_basis

STEEL = Material(2.1e11, 0.3, 7800.0)


def curved_beam_parts():
    # A beam along a circular arc, out of its plane: every coupling term is non-zero.
    angles = np.linspace(0.0, np.pi / 2, 7)
    nodes = np.column_stack([np.cos(angles), np.sin(angles), 0.1 * angles])
    elements = {"beam2": np.column_stack([np.arange(6), np.arange(1, 7)])}
    return nodes, elements, dict(section=Section.rectangle(0.02, 0.04), orientation=(0.0, 0.0, 1.0))


@pytest.fixture(scope="module")
def beam():
    nodes, elements, props = curved_beam_parts()
    body = pp.build_body(
        nodes,
        elements,
        STEEL,
        reference="clamped",
        reference_nodes=[0],
        modes="fixed-interface",
        mode_count=5,
        **props,
    )
    weights, positions, shape = pp.mass_points(nodes, elements, STEEL, **props)
    return body, weights, positions, shape @ elastic_basis(body).toarray()


@pytest.fixture(scope="module")
def solid():
    mesh = shapes.box((0.6, 0.1, 0.05), (6, 2, 1), "tet4")
    nodes = mesh.nodes + np.array([0.1, -0.03, 0.02])  # the frame off the body's centre
    body = pp.build_body(
        nodes, mesh.elements, STEEL, reference="mean-axis", modes="free-free", mode_count=4
    )
    weights, positions, shape = pp.mass_points(nodes, mesh.elements, STEEL)
    return body, weights, positions, shape @ elastic_basis(body).toarray()


def brute_force_forces(weights, positions, phi, q, q_dot, q_ddot, w, w_dot):
    """The inertia forces of a body whose frame turns at w (angular acceleration w_dot) about
    its fixed origin, summed over the mass points: translation sum w a, rotation sum w u x a,
    elastic sum w Phi^T a, with a = w_dot x u + w x (w x u) + 2 w x Phi q' + Phi q''."""
    n = len(q)
    u = positions + (phi @ q).reshape(-1, 3)
    v_el = (phi @ q_dot).reshape(-1, 3)
    a = (
        np.cross(w_dot, u)
        + np.cross(w, np.cross(w, u))
        + 2 * np.cross(w, v_el)
        + (phi @ q_ddot).reshape(-1, 3)
    )
    wa = weights[:, None] * a
    elastic = phi.T @ wa.ravel()
    return wa.sum(axis=0), np.cross(u, wa).sum(axis=0), elastic.reshape(n)


def sid_forces(sid, q, q_dot, q_ddot, w, w_dot):
    """The same forces from the SID fields (docs/sid.md, "Equations of motion")."""
    f = sid.fields
    n = len(q)
    md, ct, cr, j = f["mdCM"].at(q)[:, 0], f["Ct"].at(q), f["Cr"].at(q), f["J"].at(q)
    gr, ge = f["Gr"].at(q), f["Ge"].at(q)
    omega_products = np.array(
        [w[0] ** 2, w[1] ** 2, w[2] ** 2, w[0] * w[1], w[1] * w[2], w[0] * w[2]]
    )
    skew = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    translation = (
        np.cross(w_dot, md)
        + np.cross(w, np.cross(w, md))
        + 2 * skew @ (ct.T @ q_dot)
        + ct.T @ q_ddot
    )
    gyro_r = sum(gr[:, 3 * k : 3 * k + 3] @ w * q_dot[k] for k in range(n))
    gyro_e = sum(ge[:, 3 * k : 3 * k + 3] @ w * q_dot[k] for k in range(n))
    rotation = j @ w_dot + cr.T @ q_ddot + np.cross(w, j @ w) + gyro_r
    elastic = cr @ w_dot + f["Me"].at(q) @ q_ddot + f["Oe"].at(q) @ omega_products + gyro_e
    return translation, rotation, elastic


@pytest.mark.parametrize("kind", ["beam", "solid"])
def test_the_fields_give_the_inertia_forces_of_the_mass_points(kind, request, assert_close):
    body, weights, positions, phi = request.getfixturevalue(kind)
    sid = SidData.from_body(body)
    n = body.elastic_coordinate_count
    rng = np.random.default_rng(3)
    scale = np.abs(phi).max()
    for _ in range(3):
        q = rng.normal(size=n) * 0.05 / scale
        q_dot, q_ddot = rng.normal(size=n) / scale, rng.normal(size=n) / scale
        w, w_dot = rng.normal(size=3) * 4, rng.normal(size=3) * 10
        expected = brute_force_forces(weights, positions, phi, q, q_dot, q_ddot, w, w_dot)
        actual = sid_forces(sid, q, q_dot, q_ddot, w, w_dot)
        for name, a, e in zip(
            ("translation", "rotation", "elastic"), actual, expected, strict=True
        ):
            assert_close(a, e, abs=1e-10 * np.abs(e).max(), what=f"{kind} {name} forces")
    # The static terms by their definitions: mass, first moment and inertia tensor at q.
    u = positions + (phi @ q).reshape(-1, 3)
    assert_close(sid.mass, weights.sum(), rel=1e-12, what="mass")
    assert_close(sid.fields["mdCM"].at(q)[:, 0], weights @ u, abs=1e-12 * body.invariants.mass)
    inertia = sum(
        wt * (p @ p * np.eye(3) - np.outer(p, p)) for wt, p in zip(weights, u, strict=True)
    )
    assert_close(sid.fields["J"].at(q), inertia, abs=1e-12 * np.abs(inertia).max(), what="J(q)")
    # Node origins move with their modes: origin(q) = position + phi q.
    node = sid.nodes[3]
    index = int(np.flatnonzero(body.node_ids == node.id)[0])
    dofs = body.dofs_per_node
    displacement = elastic_basis(body).toarray()[dofs * index : dofs * index + 3] @ q
    assert_close(node.origin.at(q)[:, 0], body.nodes[index] + displacement, abs=1e-14)


@pytest.mark.parametrize("kind", ["beam", "solid"])
def test_a_round_trip_gives_the_same_invariants(kind, request, tmp_path, assert_close):
    body = request.getfixturevalue(kind)[0]
    path = write_sid(body, tmp_path / f"{kind}.sid")
    back = read_sid(path)
    inv, got = body.invariants, back.invariants
    for name in ("mass", "first_moment", "second_moment", "i1", "ibar", "k_ff", "m_ff"):
        want = np.asarray(
            getattr(inv, name).toarray()
            if hasattr(getattr(inv, name), "toarray")
            else getattr(inv, name)
        )
        assert_close(
            getattr(got, name), want, abs=1e-13 * max(np.abs(want).max(), 1e-300), what=name
        )
    for a in range(3):
        for b in range(3):
            want = np.asarray(
                inv.i_kl[a][b].toarray() if hasattr(inv.i_kl[a][b], "toarray") else inv.i_kl[a][b]
            )
            assert_close(
                got.i_kl[a][b], want, abs=1e-13 * np.abs(want).max(), what=f"i_kl[{a}][{b}]"
            )
    assert back.dofs_per_node == body.dofs_per_node
    assert_close(back.frequencies, body.frequencies, rel=1e-9, what="frequencies")
    assert_close(back.nodes, body.nodes, abs=0.0, what="nodes")
    assert_close(back.modes, elastic_basis(body).toarray(), abs=0.0, what="modes")
    # The file written from the imported body is the same file.
    again = write_sid(back, tmp_path / "again.sid")
    first, second = load_sid_data(path), load_sid_data(again)
    for name, field in first.fields.items():
        terms = [t for t in (field.m0, field.m1, field.m2) if t is not None]
        scale = max(float(np.abs(t).max(initial=0.0)) for t in terms)
        for term in ("m0", "m1", "m2"):
            a, b = getattr(field, term), getattr(second.fields[name], term)
            if a is not None:
                assert_close(b, a, abs=1e-12 * scale, what=f"{name}.{term}")


def pendulum(body):
    system = fm.System(gravity=(0.0, -9.81, 0.0))
    flexible = system.add_flexible_body(body, name="arm")
    system.add_revolute_joint(
        system.add_marker(system.ground, position=body.nodes[0]),
        system.add_node_marker(flexible, int(body.node_ids[0])),
    )
    return system


def test_the_imported_body_simulates_like_the_original(beam, tmp_path, assert_close):
    body = beam[0]
    back = read_sid(write_sid(body, tmp_path / "beam.sid"))
    runs = [
        fm.simulate(pendulum(b), end_time=0.2, step_size=1e-3, output_interval=0.01)
        for b in (body, back)
    ]
    assert_close(runs[1].coordinates, runs[0].coordinates, abs=1e-12, what="coordinates")
    assert np.abs(runs[0].coordinates[-1] - runs[0].coordinates[0]).max() > 0.1  # it moved


def test_damping_travels_as_rayleigh_and_modal(solid, tmp_path, assert_close):
    body = solid[0].with_damping(rayleigh=(2.0, 1e-5), modal=0.02)
    back = read_sid(write_sid(body, tmp_path / "damped.sid"))
    assert_close(back.damping["rayleigh"], (2.0, 1e-5), rel=1e-8, what="rayleigh")
    assert_close(back.damping["modal"], 0.02, rel=1e-8, what="modal ratio")
    assert read_sid(write_sid(solid[0], tmp_path / "undamped.sid")).damping is None
    # Each kind alone comes back alone: the tetrahedral pendulum's arm came back with modal
    # damping of ratio 3.5e-17 besides its Rayleigh damping, and alpha 1.5e-12 besides 0.02.
    example = fm.examples.tetrahedral_pendulum()
    arm = example.system._flexible[example.items["arm"].index]
    for damping in ({"rayleigh": (2.0, 1e-5)}, {"modal": 0.02}):
        back = read_sid(write_sid(arm.with_damping(**damping), tmp_path / "one.sid"))
        assert {k for k, v in back.damping.items() if v is not None} == set(damping), damping


def test_a_selection_of_nodes_keeps_markers_on_them(beam, tmp_path, assert_close):
    body = beam[0]
    ids = [int(body.node_ids[0]), int(body.node_ids[-1])]
    back = read_sid(write_sid(body, tmp_path / "two.sid", nodes=ids))
    assert back.node_ids.tolist() == ids
    full, part = (
        fm.simulate(pendulum(b), end_time=0.05, step_size=1e-3, output_interval=0.05)
        for b in (body, back)
    )
    assert_close(part.coordinates, full.coordinates, abs=1e-12, what="coordinates")
    with pytest.raises(UnknownItemError, match="no node with id 999"):
        write_sid(body, tmp_path / "x.sid", nodes=[999])
    with pytest.raises(UnknownItemError, match="no node set 'tip'"):
        write_sid(body, tmp_path / "x.sid", nodes=["tip"])


def test_large_nodal_bodies_are_refused(tmp_path):
    mesh = shapes.box((1.0, 0.1, 0.1), (12, 3, 3), "tet4")
    nodal = pp.build_body(mesh.nodes, mesh.elements, STEEL)
    with pytest.raises(InvalidModelError, match="624 elastic coordinates; SID export takes"):
        write_sid(nodal, tmp_path / "nodal.sid")


def edited(path, old, new, count=1):
    text = path.read_text()
    assert old in text, old
    path.write_text(text.replace(old, new, count))
    return path


def test_bad_files_name_the_line_or_the_field(solid, tmp_path):
    path = write_sid(solid[0], tmp_path / "s.sid")
    lines = path.read_text().splitlines()
    # Gr of the opposite sign convention (its largest entry flipped): Gr follows from J.
    start = lines.index("      Gr")
    end = lines.index("      end Gr")
    entries = [i for i in range(start, end) if lines[i].strip().startswith(("m0(", "m1("))]
    entry = max(entries, key=lambda i: abs(float(lines[i].split("=")[1])))
    key, value = lines[entry].split("=")
    flipped = list(lines)
    flipped[entry] = f"{key}= {-float(value)!r}"
    bad = tmp_path / "flipped.sid"
    bad.write_text("\n".join(flipped))
    with pytest.raises(InvalidModelError, match="field Gr") as error:
        read_sid(bad)
    assert error.value.item == "Gr"
    # J without its second-order terms.
    no_second = "\n".join(line for line in lines if not line.strip().startswith("m2("))
    bad.write_text(
        no_second.replace("order     = 2", "order     = 1").replace(
            f"nqn       = {4}", "nqn       = 0"
        )
    )
    with pytest.raises(InvalidModelError, match="field J has order 1"):
        read_sid(bad)
    # A syntax error names the line.
    broken = list(lines)
    broken[7] = "   this is not SID"
    bad.write_text("\n".join(broken))
    with pytest.raises(InvalidModelError, match=r"line 8: "):
        read_sid(bad)
    edited(path, "      Ke\n", "      Kx\n")
    with pytest.raises(InvalidModelError, match="unknown section 'Kx'"):
        read_sid(path)
    with pytest.raises(FileNotFoundError):
        read_sid(tmp_path / "missing.sid")


def test_fortran_numbers_and_comments_are_read(solid, tmp_path, assert_close):
    path = write_sid(solid[0], tmp_path / "s.sid")
    text = path.read_text()
    mass = load_sid_data(path).mass
    text = text.replace(
        f"mass      = {mass!r}", f"mass      = {mass:.16E}".replace("E", "D") + "  ! kg"
    )
    path.write_text(text)
    assert_close(load_sid_data(path).mass, mass, rel=1e-15, what="mass")


def test_a_model_file_takes_a_sid_body(tmp_path):
    from pathlib import Path

    from flexmbd.model_file import load_model

    # The tetrahedral pendulum's arm through a SID file, hinged at the centre node of its face
    # x0 (at the origin), in a model file and in Python: the same run, bit for bit.
    example = fm.examples.tetrahedral_pendulum()
    arm = example.system._flexible[example.items["arm"].index]
    write_sid(arm, tmp_path / "arm.sid")
    centre = int(np.flatnonzero(np.all(np.isclose(arm.nodes, [0.0, 0.015, 0.015]), axis=1))[0])
    node_id = int(arm.node_ids[centre])
    models = Path(__file__).parents[1] / "examples" / "models"
    text = (models / "tetrahedral_pendulum.yaml").read_text()
    start, end = text.index("    box:"), text.index("    position:")
    text = text[:start] + "    body_file: arm.sid\n" + text[end:]
    text = text.replace(
        "marker2: {body: arm, node_set: x0}", f"marker2: {{body: arm, node: {node_id}}}"
    )
    (tmp_path / "arm.yaml").write_text(text)
    from_file = load_model(tmp_path / "arm.yaml").system
    system = fm.System(gravity=(0.0, -9.81, 0.0))
    body = system.add_flexible_body(
        read_sid(tmp_path / "arm.sid"), name="arm", position=(0.0, -0.015, -0.015)
    )
    system.add_revolute_joint(
        system.add_marker(system.ground), system.add_node_marker(body, node_id), name="hinge"
    )
    runs = [
        fm.simulate(
            s,
            end_time=0.05,
            step_size=5e-4,
            output_interval=0.01,
            solver=fm.GeneralizedAlpha(spectral_radius=1.0),
        )
        for s in (from_file, system)
    ]
    np.testing.assert_array_equal(runs[0].coordinates, runs[1].coordinates)
    assert np.abs(runs[0].coordinates[-1] - runs[0].coordinates[0]).max() > 1e-3


def test_a_sid_file_larger_than_the_free_memory_is_refused(solid, tmp_path, monkeypatch):
    import flexmbd.fe._memory as memory

    path = write_sid(solid[0], tmp_path / "s.sid")
    monkeypatch.setattr(memory, "available_memory", lambda: 1000)
    with pytest.raises(InvalidModelError, match="SID file"):
        read_sid(path)


def test_flexmbd_info_describes_a_sid_file(solid, tmp_path, capsys):
    # `flexmbd info` said a SID file was "not a model, body, results, mesh, Nastran or OP2
    # file", though model files and read_sid take it.
    from flexmbd.cli import main

    write_sid(solid[0], tmp_path / "block.sid")
    assert main(["info", str(tmp_path / "block.sid")]) == 0
    printed = capsys.readouterr().out
    body = read_sid(tmp_path / "block.sid")
    assert f"SID file (a modal body), {body.node_count} nodes, no elements" in printed
    assert f"{body.elastic_coordinate_count} elastic coordinates" in printed
    assert f"{body.frequencies[0]:.4g}" in printed


def test_a_run_of_a_sid_body_plots_without_stresses(beam, tmp_path):
    # `flexmbd run` of a model with a SID (or body-file) body simulated, then failed in its
    # overview plot with a traceback: it asked for the stresses of a body without elements.
    # Their recovery now refuses such bodies with a typed error, and the overview leaves
    # them out.
    import matplotlib

    from flexmbd.errors import InvalidParameterError
    from flexmbd.fe import recover_stresses, shell_stresses
    from flexmbd.plotting import default_quantities, plot_result

    matplotlib.use("Agg")
    back = read_sid(write_sid(beam[0], tmp_path / "beam.sid"))
    result = fm.simulate(pendulum(back), end_time=0.01, step_size=1e-3)
    assert "deflection:arm" in default_quantities(result)
    assert "stress:arm" not in default_quantities(result)
    assert "stress:arm" in default_quantities(
        fm.simulate(pendulum(beam[0]), end_time=0.01, step_size=1e-3)
    )
    plot_result(result, tmp_path / "overview.png")
    for recover in (recover_stresses, shell_stresses):
        with pytest.raises(InvalidParameterError, match="no elements with a material"):
            recover(back, np.zeros(back.dof_count))


def test_malformed_nodes_and_selections_are_refused_by_name(beam, tmp_path, assert_close):
    # From a fault hunt: each gave an untyped Python error, or was taken silently.
    import re

    from flexmbd.errors import ArgumentTypeError, InvalidParameterError

    body = beam[0]
    path = write_sid(body, tmp_path / "beam.sid")
    text = path.read_text()
    # The frequencies travel in the modes' names, now exactly (10 digits before: 5e-11).
    np.testing.assert_array_equal(read_sid(path).frequencies, body.frequencies)
    # A psi of the wrong width (ValueError: could not broadcast).
    bad = re.sub(r"(psi\n\s*order\s*= 0\n\s*nrow\s*= 3\n\s*ncol\s*)= 5", r"\1= 2", text, count=1)
    bad = re.sub(r"\n\s*m0\([123],[345]\) = [^\n]*(?=[^e]*end psi)", "", bad, count=9)
    (tmp_path / "psi.sid").write_text(bad)
    with pytest.raises(InvalidModelError, match=r"node 1: psi has shape \(3, 2\), expected"):
        read_sid(tmp_path / "psi.sid")
    # A node without psi among nodes with one: its rotations were taken as zero.
    start = text.index("            psi")
    (tmp_path / "nopsi.sid").write_text(text[:start] + text[text.index("end psi", start) + 8 :])
    with pytest.raises(InvalidModelError, match="node 1 has no psi"):
        read_sid(tmp_path / "nopsi.sid")
    # A node defined twice (refused only later, by add_flexible_body).
    first = text.index("         new node")
    block = text[first : text.index("end node", first) + len("end node\n")]
    (tmp_path / "twice.sid").write_text(text.replace(block, block + block, 1))
    with pytest.raises(InvalidModelError, match="is defined twice"):
        read_sid(tmp_path / "twice.sid")
    # A name that is no frequency: the frequencies come from Ke and Me (ValueError before).
    (tmp_path / "name.sid").write_text(
        re.sub(r"Eigen Mode 1 : [^\n]*", "Eigen Mode 1 : 1.2.3 Hz", text)
    )
    assert_close(read_sid(tmp_path / "name.sid").frequencies, body.frequencies, rel=1e-8)
    # Sizes beyond the memory are refused before they are allocated (MemoryError: 65 TiB).
    header = "   order = 2\n   nrow = 3\n   ncol = 3\n   nq = 1000000\n   nqn = 1000000\n"
    huge = "part\n new modal\n  refmod\n   mass = 1.0\n   nelastq = 1000000\n  end refmod\n"
    huge += f"  J\n{header}   structure = 2\n   m0(1,1) = 1.0\n  end J\n end modal\nend part\n"
    (tmp_path / "huge.sid").write_text(huge)
    with pytest.raises(InvalidModelError, match="more memory than is available"):
        read_sid(tmp_path / "huge.sid")
    # A node frame turned from the body axes (AP) was dropped without a word.
    turned = text.replace(
        "m0(1,1) = 1.0\n               m0(2,2) = 1.0",
        "m0(1,2) = -1.0\n               m0(2,1) = 1.0",
        1,
    )
    (tmp_path / "turned.sid").write_text(turned)
    with pytest.warns(UserWarning, match="frames of 1 node.*AP"):
        read_sid(tmp_path / "turned.sid")
    # Gr of order 0 (a first-order file leaves out its terms in q): named as such, not as a
    # sign convention.
    start = text.index("      Gr\n")
    end = text.index("      end Gr", start)
    lines = [line for line in text[start:end].splitlines() if not line.strip().startswith("m1(")]
    order0 = "\n".join(lines).replace("order     = 1", "order     = 0", 1)
    (tmp_path / "gr.sid").write_text(
        text[:start] + order0.replace("nq        = 5", "nq        = 0", 1) + "\n" + text[end:]
    )
    with pytest.raises(InvalidModelError, match="field Gr has order 0, but its order-1 terms"):
        read_sid(tmp_path / "gr.sid")
    # write_sid's node selection: ids and set names only, in a list, not empty.
    for nodes, error in (([5.7], ArgumentTypeError), ([True], ArgumentTypeError),
                         (7, ArgumentTypeError), ([], InvalidParameterError)):  # fmt: skip
        with pytest.raises(error, match="SID nodes"):
            write_sid(body, tmp_path / "x.sid", nodes=nodes)
