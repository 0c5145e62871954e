"""State-space models (issue 32): named inputs and outputs of the linearized motion; a
cantilever's tip-force-to-tip-displacement frequency response against the modal sum of its FE
model, B against the generalized force of the load, A against finite differences of the
nonlinear equations about a point of a trajectory."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import scipy.linalg as sla

import flexmbd as fm
from flexmbd.fe import Material, Section, build_body, straight_beam
from flexmbd.system import elastic_basis

ELEMENTS = 12
TIP = ELEMENTS + 1  # node ids 1 .. ELEMENTS + 1


def cantilever():
    """A clamped aluminium strip (1 m, 10 x 2 mm) on a hinge held by a driver at rest."""
    nodes, conn = straight_beam(1.0, ELEMENTS)
    data = build_body(
        nodes, conn, Material(7.0e10, 0.3, 2700.0), section=Section.rectangle(0.01, 0.002),
        orientation=(0.0, 1.0, 0.0), reference="clamped", reference_nodes=[0],
    )  # fmt: skip
    system = fm.System()
    body = system.add_flexible_body(data, name="strip")
    hub, root = system.add_marker(system.ground), system.add_node_marker(body, 1)
    system.add_revolute_joint(hub, root, name="hinge")
    system.add_angle_driver(hub, root, fm.Constant(0.0), name="hold")
    tip = system.add_node_marker(body, TIP)
    return system, data, tip


def tip_linearization():
    """The strip linearized with a vertical tip force in and the vertical tip deflection out,
    and its FE model: the squared frequencies w2 of K_ff, M_ff (mass-normalized modes) and
    each mode's share of the tip's vertical displacement."""
    system, data, tip = cantilever()
    linear = fm.linearize(
        system,
        inputs=[fm.PointLoad(tip, (0, 0, 1), name="F_z")],
        outputs=[fm.NodeDisplacement("strip", TIP, (0, 0, 1), name="w_tip")],
    )
    w2, phi = sla.eigh(data.invariants.k_ff.toarray(), data.invariants.m_ff.toarray())
    tip_row = np.asarray(elastic_basis(data)[(TIP - 1) * data.dofs_per_node + 2].toarray()).ravel()
    return linear, w2, tip_row @ phi


def test_tip_frequency_response_is_the_modal_sum_of_the_fe_model(assert_close):
    linear, w2, share = tip_linearization()
    ss = linear.state_space()
    assert ss.inputs == ["F_z"] and ss.outputs == ["w_tip"]
    frequencies = np.array([0.3, 1.0, 2.5, 7.0, 30.0, 120.0])  # Hz, between resonances
    omega = 2 * np.pi * frequencies
    modal = np.array([np.sum(share**2 / (w2 - o**2)) for o in omega])
    response = ss.frequency_response(frequencies)[:, 0, 0]
    assert_close(response.imag, 0.0, abs=1e-12 * np.abs(modal).max(), what="undamped: real")
    assert_close(response.real, modal, rel=1e-8, what="H(w) against the modal sum")


def test_a_stiff_damped_strip_has_a_finite_response_equal_to_its_modal_sum(assert_close):
    # A clamped steel strip of 80 elements: its A has a reciprocal condition number of about
    # 1e-17 at every frequency (its stiffest modes far above its first), which was taken for
    # an undamped resonance: inf at 5 and 30 Hz, and at its 1 %-damped first resonance.
    elements = 80
    nodes, conn = straight_beam(1.0, elements)
    data = build_body(
        nodes, conn, Material(2.1e11, 0.3, 7850.0), section=Section.rectangle(0.02, 0.01),
        reference="clamped", reference_nodes=[0],
    )  # fmt: skip
    k, m = data.invariants.k_ff.toarray(), data.invariants.m_ff.toarray()
    w2, phi = sla.eigh(k, m)
    beta = 2 * 0.01 / np.sqrt(w2[0])  # stiffness-proportional: 1 % in the first mode
    system = fm.System()
    body = system.add_flexible_body(data, name="beam", rayleigh_damping=(0.0, beta))
    system.add_fixed_joint(system.add_marker(system.ground), system.add_node_marker(body, 1))
    tip = system.add_node_marker(body, elements + 1)
    space = fm.linearize(
        system,
        inputs=[fm.PointLoad(tip, (0, 0, 1))],
        outputs=[fm.NodeDisplacement("beam", elements + 1, (0, 0, 1))],
    ).state_space()
    frequencies = np.array([1.0, np.sqrt(w2[0]) / (2 * np.pi), 5.0, 30.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error", fm.ResonanceWarning)
        response = space.frequency_response(frequencies)[:, 0, 0]
    # The modal sum: sum_i c_i^2 / (w_i^2 - w^2 + i beta w_i^2 w), c_i the tip row of mode i.
    row = elastic_basis(data)[elements * data.dofs_per_node + 2].toarray().ravel() @ phi
    omega = 2 * np.pi * frequencies
    modal = np.array([np.sum(row**2 / (w2 - o**2 + 1j * beta * w2 * o)) for o in omega])
    # (the solves' round-off at a condition number of 1e15: 2e-5 at the resonance)
    error = np.abs(response - modal) / np.abs(modal)
    assert_close(error, 0.0, abs=2e-4, what="|H - modal| / |modal|")


def test_undamped_symmetric_modes_equal_those_of_the_first_order_matrix(assert_close):
    # Undamped with symmetric M and K, the eigenvalues come from the symmetric problem of n
    # (an 1,800-coordinate solid: 132 s for the nonsymmetric one of 2 n). Against the
    # eigenvalues of the state-space A, computed by the general nonsymmetric solver, and the
    # shapes against K phi = w^2 M phi.
    system, _, _ = cantilever()
    linear = fm.linearize(system)
    assert not np.any(linear.damping)
    values, shapes = linear.eigenvalues()
    general = np.linalg.eigvals(linear.state_space().a)
    assert_close(values.real, 0.0, abs=0.0, what="Re s (undamped)")
    found, expected = np.sort(values.imag), np.sort(general.imag)
    assert_close(found, expected, rel=1e-8, abs=1e-9, what="Im s against the general solver")
    frequencies, _, modes = linear.oscillating()
    z = np.linalg.lstsq(linear.basis, modes, rcond=None)[0]  # back to the coordinates z
    w2 = (2 * np.pi * frequencies) ** 2
    residual = linear.stiffness @ z - linear.mass @ z * w2[None, :]
    size = np.abs(linear.stiffness @ z).max(axis=0)
    ratio = np.abs(residual).max(axis=0) / size
    # (the highest modes' shapes of the inverted problem, M phi = K phi / w^2: 2e-7)
    assert_close(ratio, 0.0, abs=1e-6, what="|K phi - w^2 M phi| / |K phi|")
    assert_close(ratio[:6], 0.0, abs=1e-10, what="|K phi - w^2 M phi| / |K phi|, first six")


def test_input_columns_are_the_generalized_forces_of_the_loads(assert_close):
    system, data, tip = cantilever()
    model = system.compile()
    linear = fm.linearize(
        system, inputs=[fm.PointLoad(tip, (0, 0, 2)), fm.PointLoad(tip, (0, 1, 0), "torque")]
    )
    q = linear.input_forces
    layout = model.describe()["bodies"]
    offset = layout[1]["offset"] + 7
    elastic = slice(offset, offset + data.invariants.k_ff.shape[0])
    d = data.dofs_per_node
    basis = elastic_basis(data)
    # A unit force along z at the tip node: its z row of the elastic basis; a unit torque about
    # y: its rotation row (the direction is normalized).
    assert_close(q[elastic, 0], basis[(TIP - 1) * d + 2].toarray().ravel(), abs=1e-12)
    assert_close(q[elastic, 1], basis[(TIP - 1) * d + 4].toarray().ravel(), abs=1e-12)


def test_about_a_point_of_a_trajectory_a_matches_finite_differences(assert_close):
    # A double pendulum of rigid bodies (nonlinear): linearized about a state in mid-swing,
    # the stiffness and damping of the z-coordinates match central differences of the
    # equations of motion restricted to the same basis.
    system = fm.System(gravity=(0, -9.81, 0))
    a = system.add_rigid_body(1.0, (1e-3, 0.1, 0.1), position=(0.5, 0, 0), name="a")
    b = system.add_rigid_body(1.0, (1e-3, 0.1, 0.1), position=(1.5, 0, 0), name="b")
    system.add_revolute_joint(system.add_marker(system.ground),
                              system.add_marker(a, position=(-0.5, 0, 0)))  # fmt: skip
    system.add_revolute_joint(system.add_marker(a, position=(0.5, 0, 0)),
                              system.add_marker(b, position=(-0.5, 0, 0)))  # fmt: skip
    model = system.compile()
    result = fm.simulate(model, 0.4, 1e-4, output_interval=0.1,
                         solver=fm.GeneralizedAlpha(newton_tolerance=1e-12))  # fmt: skip
    state = result.state(-1)
    linear = fm.linearize(
        model, state, outputs=[fm.BodyPosition("b", (0, 1, 0))], independent="null-space"
    )
    # Residual of M q_dd - F + C_q^T lambda along the basis, with the accelerations and
    # multipliers of the state held: its derivatives along z give K and D.
    basis = linear.basis

    def projected(dq, dqd):
        r = model.evaluate(state.time, state.coordinates + basis @ dq,
                           state.velocities + basis @ dqd, state.accelerations,
                           state.multipliers)["residual"][: model.coordinate_count]  # fmt: skip
        return basis.T @ r

    h = 1e-6
    n = basis.shape[1]
    stiffness = np.column_stack([(projected(h * e, 0 * e) - projected(-h * e, 0 * e)) / (2 * h)
                                 for e in np.eye(n)])  # fmt: skip
    damping = np.column_stack([(projected(0 * e, h * e) - projected(0 * e, -h * e)) / (2 * h)
                               for e in np.eye(n)])  # fmt: skip
    scale = np.abs(linear.stiffness).max()
    assert_close(linear.stiffness, stiffness, abs=1e-6 * scale, what="K")
    assert_close(linear.damping, damping, abs=1e-6 * max(1.0, np.abs(linear.damping).max()))
    ss = linear.state_space()
    assert ss.a.shape == (2 * n, 2 * n) and ss.c.shape == (1, 2 * n)
    # The output row: y of body b's origin.
    y_row = np.zeros(model.coordinate_count)
    y_row[model.describe()["bodies"][2]["offset"] + 1] = 1.0
    assert_close(ss.c[0, :n], y_row @ basis, abs=1e-15)


@pytest.mark.parametrize(
    "solver", [None, fm.ExplicitSolver("rk4", "joint-coordinates")], ids=["alpha", "joints"]
)
def test_a_swinging_pendulum_linearized_about_a_state_of_its_swing(solver, assert_close):
    # A bar (1 m, 1 kg) on a hinge at its end, released horizontal: at angle theta below the
    # horizontal the swing's variational equation is d_theta_dd = -(3 g / 2 L) sin(theta)
    # d_theta, undamped. The independent coordinate was a global coordinate of the turning bar,
    # whose relation to the angle changes along the swing: eigenvalues -3.23 +- 6.80i (damped)
    # instead of +- 2.99i.
    g = 9.81
    system = fm.System(gravity=(0, -g, 0))
    bar = system.add_rigid_body(1.0, (1e-4, 1 / 12, 1 / 12), position=(0.5, 0, 0), name="bar")
    system.add_revolute_joint(system.add_marker(system.ground),
                              system.add_marker(bar, position=(-0.5, 0, 0)))  # fmt: skip
    result = fm.simulate(system, 0.3, 1e-4, solver=solver, output_interval=0.1)
    turn = result.orientation(bar)[-1]
    theta = np.arctan2(-turn[1, 0], turn[0, 0])
    expected = np.sqrt(1.5 * g * np.sin(theta))
    values = fm.linearize(system, result.state(-1)).eigenvalues()[0]
    assert_close(np.sort(values.imag), [-expected, expected], rel=1e-5, what="frequency")
    assert np.max(np.abs(values.real)) < 1e-5 * expected


def test_bad_inputs_and_outputs_are_refused():
    system, _, tip = cantilever()
    with pytest.raises(fm.InvalidParameterError, match="flexmbd.System"):
        fm.linearize(system.compile(), inputs=[fm.PointLoad(tip, (0, 0, 1))])
    with pytest.raises(fm.InvalidParameterError, match="non-zero 3-vector"):
        fm.linearize(system, inputs=[fm.PointLoad(tip, (0, 0, 0))])
    with pytest.raises(fm.UnknownItemError, match="no body named 'rod'"):
        fm.linearize(system, outputs=[fm.NodeDisplacement("rod", 2, (0, 0, 1))])
    with pytest.raises(fm.UnknownItemError, match="no node with id 99"):
        fm.linearize(system, outputs=[fm.NodeDisplacement("strip", 99, (0, 0, 1))])


def test_assembly_modes_map_to_node_displacements_and_animate(tmp_path, assert_close):
    from flexmbd.animation import read_pvd, render_animation, write_vtu_series
    from flexmbd.state_space import body_shapes, mode_result

    system, data, _ = cantilever()
    model = system.compile()
    linear = fm.linearize(model)
    frequencies, damping, shapes = linear.oscillating()
    k, m = (np.asarray(getattr(x, "toarray", lambda x=x: x)()) for x in
            (data.invariants.k_ff, data.invariants.m_ff))  # fmt: skip
    fe = np.sqrt(sla.eigh(k, m, eigvals_only=True)) / (2 * np.pi)
    assert_close(frequencies[:6], fe[:6], rel=1e-8, what="assembly against FE frequencies")
    assert_close(damping[:6], 0.0, abs=1e-9)
    parts = body_shapes(model, shapes[:, 0], linear.state)
    assert set(parts) == {"strip"}
    offset = model.describe()["bodies"][1]["offset"] + 7
    q_f = shapes[offset : offset + k.shape[0], 0]
    expected = (elastic_basis(data) @ q_f).reshape(-1, data.dofs_per_node)[:, :3]
    difference = np.abs(parts["strip"]["displacements"] - expected)  # complex shapes
    assert_close(difference, 0.0, abs=1e-15, what="node displacements of the shape")
    # The clamped end does not move; the first mode bends about y (flap, along z).
    assert_close(np.abs(parts["strip"]["displacements"][0]), 0.0, abs=1e-15)
    tip = np.abs(parts["strip"]["displacements"][-1])
    assert tip[2] > 100 * max(tip[0], tip[1])
    # One period of the mode as a result: the animation and the ParaView series.
    result = mode_result(linear, model, 0, frames=4)
    assert len(result) == 4 and result.statistics["frequency"] == frequencies[0]
    written = render_animation(result, tmp_path / "mode1.gif", frames=4)
    assert all(p.stat().st_size > 0 for p in written)
    assert len(read_pvd(write_vtu_series(result, tmp_path / "vtu", name="mode1"))) == 4
    with pytest.raises(fm.InvalidParameterError, match="oscillating modes"):
        mode_result(linear, model, 10_000)


def test_body_shapes_read_the_rotation_with_the_states_euler_parameters(assert_close):
    # A rod (1 m) on a spherical joint at its top, built tilted 60 degrees about x, hangs
    # straight down at its equilibrium (body axes = global). Its swings turn it about the
    # pivot: its centre, 0.5 m below, moves by rotation x (0, -0.5, 0). Read with the
    # initial (tilted) Euler parameters the rotation of the swing about x was reported about
    # (0, 0.5, 0.87) of the body axes.
    from flexmbd.state_space import body_shapes

    tilt = np.radians(60.0)
    turn = np.array([[1, 0, 0], [0, np.cos(tilt), -np.sin(tilt)], [0, np.sin(tilt), np.cos(tilt)]])
    system = fm.System(gravity=(0, -9.81, 0))
    inertia = 1.0 / 12.0
    rod = system.add_rigid_body(
        1.0, (inertia, 1e-4, inertia), position=tuple(-turn @ [0, 0.5, 0]), orientation=turn,
        name="rod",
    )  # fmt: skip
    pivot = system.add_marker(rod, position=(0, 0.5, 0))
    system.add_spherical_joint(system.add_marker(system.ground), pivot, name="ball")
    model = system.compile()
    state = fm.equilibrium(model)
    assert_close(state.coordinates[3:7], [1, 0, 0, 0], abs=1e-9, what="hanging straight")
    linear = fm.linearize(model, state)
    frequencies, _, shapes = linear.oscillating()
    swing = np.sqrt(9.81 * 0.5 / (inertia + 0.25)) / (2 * np.pi)
    assert_close(frequencies, [swing, swing], rel=1e-9, what="swing")
    for k in range(2):
        part = body_shapes(model, shapes[:, k], state)["rod"]
        moved = np.cross(part["rotation"], [0.0, -0.5, 0.0])
        size = np.max(np.abs(part["translation"]))
        assert_close(np.abs(part["translation"] - moved), 0.0, abs=1e-9 * size, what="arm")
        assert_close(abs(part["rotation"][1]), 0.0, abs=1e-9 * size, what="about the rod")


def test_the_modes_command(tmp_path, capsys):
    from pathlib import Path

    from flexmbd.cli import main

    model = Path(__file__).parent.parent / "examples" / "models" / "rotating_blade.yaml"
    stem = tmp_path / "blade"
    code = main(["modes", str(model), "--count", "3", "--animate", "1", "--frames", "4",
                 "-o", str(stem)])  # fmt: skip
    out = capsys.readouterr().out
    assert code == 0, out
    assert "about the steady rotation" in out and "blade" in out
    assert (tmp_path / "blade_mode1.gif").stat().st_size > 0
    assert (tmp_path / "blade_mode1_vtu" / "mode1.pvd").exists()


def test_the_modes_command_on_a_mechanism_with_redundant_joints(capsys):
    # The spatial four-bar (3 redundant joint equations) has one mode about its hanging
    # equilibrium, undamped (its ratio printed 0, not -0); its equilibrium used to be refused.
    # The cranks, which swing and turn, move most (the coupler translates only); read with
    # the initial configuration's Euler parameters the cranks' turn was 0, and it said
    # "coupler".
    from flexmbd.cli import main

    assert main(["modes", "four-bar-spatial"]) == 0
    out = capsys.readouterr().out
    row = out.splitlines()[-1].split()
    assert row[0] == "1" and row[2] == "0" and row[3] == "crank"
    assert float(row[1]) == pytest.approx(0.546066, rel=1e-5)


def test_the_modes_command_prints_round_off_damping_as_zero(capsys):
    # The spin-up beam (undamped) printed +6.27e-12 and -6.24e-12 for its first pair: the
    # round-off of eigenvalues 1e-16 of the largest.
    from flexmbd.cli import main

    assert main(["modes", "spin-up", "--count", "2"]) == 0
    rows = [line.split() for line in capsys.readouterr().out.splitlines()[-2:]]
    assert [row[2] for row in rows] == ["0", "0"]


def test_the_modes_command_on_a_point_mass(tmp_path, capsys):
    # A01's point mass: the mode table read its body kind as "point-mass" (the layout says
    # "point_mass") and took Euler parameters it does not have.
    from flexmbd.cli import main

    assert (
        main(["modes", "pendulum", "--animate", "1", "--frames", "4", "-o", str(tmp_path / "a01")])
        == 0
    )
    rows = [
        line.split()
        for line in capsys.readouterr().out.splitlines()
        if line[:4].strip() in ("1", "2")
    ]
    assert [row[3] for row in rows] == ["mass", "mass"]
    assert float(rows[0][1]) == pytest.approx(np.sqrt(9.81) / (2 * np.pi), rel=1e-5)
    assert (tmp_path / "a01_mode1.gif").stat().st_size > 0


def test_ids_of_another_system_are_refused_and_names_label_the_channels():
    # Regression: linearize took a body of another System as this one's body of that index
    # (and a load on its marker as a load on this system's marker), and labelled the
    # channels "position of body BodyId(1)".
    def arm(name):
        system = fm.System(gravity=(0, -9.81, 0))
        body = system.add_rigid_body(1.0, (0.1, 0.1, 0.1), position=(0.5, 0, 0), name=name)
        pivot = system.add_marker(system.ground)
        pin = system.add_marker(body, position=(-0.5, 0, 0), name=f"{name} pin")
        system.add_revolute_joint(pivot, pin)
        return system, body, pin

    system, body, pin = arm("arm")
    other, other_body, other_pin = arm("other")
    state = fm.equilibrium(system)
    for inputs, outputs in (
        ([], [fm.BodyPosition(other_body, (0, 1, 0))]),
        ([fm.PointLoad(other_pin, (0, 1, 0))], []),
    ):
        with pytest.raises(fm.UnknownItemError, match="linearize: .* of another System"):
            fm.linearize(system, state, inputs=inputs, outputs=outputs)
    linear = fm.linearize(
        system,
        state,
        inputs=[fm.PointLoad(pin, (0, 1, 0))],
        outputs=[fm.BodyPosition(body, (0, 1, 0))],
    )
    assert linear.input_names == ["force at marker arm pin"]
    assert linear.output_names == ["position of body arm"]


@pytest.mark.parametrize("rotor_first", [False, True])
def test_a_gimballed_rotor_has_the_same_frequencies_whatever_the_order_of_its_bodies(
    rotor_first, assert_close
):
    # A symmetric rotor (I_p 0.2, I_t 0.12 kg m^2) spun at W = 100 rad/s in two light gimbals
    # held by springs k = 50 N m/rad: I_t w^2 -+ I_p W w - k = 0 in the gimbal angles, 0.392
    # and 26.918 Hz (a simulation's spectrum has them). With the rotor added last its small
    # rotations in its own spinning axes were the independent coordinates, whose equations
    # are periodic: 11.0 and 16.3 Hz, the same modes seen from the rotor.
    ip, it, k, speed = 0.2, 0.12, 50.0, 100.0
    about_x = np.column_stack([[0, 1, 0], [0, 0, 1], [1, 0, 0]]).astype(float)
    about_y = np.column_stack([[0, 0, 1], [1, 0, 0], [0, 1, 0]]).astype(float)
    system = fm.System(gravity=(0, 0, 0))
    if rotor_first:
        rotor = system.add_rigid_body(5.0, (it, it, ip), name="rotor")
    outer = system.add_rigid_body(1e-6, (1e-6, 1e-6, 1e-6), name="outer")
    inner = system.add_rigid_body(1e-6, (1e-6, 1e-6, 1e-6), name="inner")
    if not rotor_first:
        rotor = system.add_rigid_body(5.0, (it, it, ip), name="rotor")
    for a, b, turn in ((system.ground, outer, about_x), (outer, inner, about_y)):
        pair = system.add_marker(a, orientation=turn), system.add_marker(b, orientation=turn)
        system.add_revolute_joint(*pair)
        system.add_rotational_spring_damper(*pair, stiffness=k)
    spin = system.add_marker(inner), system.add_marker(rotor)
    system.add_revolute_joint(*spin)
    system.add_angle_driver(*spin, fm.Polynomial([0.0, speed]), name="drive")
    root = np.sqrt((ip * speed) ** 2 + 4 * it * k)
    expected = np.sort([(root - ip * speed), (root + ip * speed)]) / (2 * it * 2 * np.pi)
    found = fm.linearize(system, "steady-rotation").frequencies()
    assert_close(found, expected, rel=1e-4, what="gimbal frequencies")


def test_the_response_at_a_mode_the_load_does_not_drive_is_finite(assert_close):
    # A vertical tip force and the vertical tip deflection of the strip: at the frequency of a
    # lateral bending mode (which they neither drive nor see) the response is the modal sum of
    # the vertical modes; it was inf with a ResonanceWarning (any eigenvalue near i w counted).
    linear, w2, share = tip_linearization()
    lateral = int(np.flatnonzero(np.abs(share) < 1e-6 * np.abs(share).max())[0])
    f = linear.frequencies()
    at = f[np.argmin(np.abs(f - np.sqrt(w2[lateral]) / (2 * np.pi)))]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        response = linear.state_space().frequency_response([at])[0, 0, 0]
    vertical = np.abs(share) >= 1e-6 * np.abs(share).max()
    modal = np.sum(share[vertical] ** 2 / (w2[vertical] - (2 * np.pi * at) ** 2))
    assert_close(response.real, modal, rel=1e-6, what="H at the lateral mode's frequency")
    # At a vertical mode's own frequency the response is unbounded.
    with pytest.warns(fm.ResonanceWarning):
        assert np.isinf(linear.state_space().frequency_response([f[0]])[0, 0, 0])
