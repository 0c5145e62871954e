"""Rotors (issue 32, reference R8): the overhung rotor, a rigid disc welded to the tip of a
nearly massless cantilever shaft that an angle driver spins. Its linearization about the
steady rotation in the rotating frame (the shaft's elastic coordinates independent, the
disc's absolute coordinates following the moving constraints), and its Campbell diagram in
the fixed frame with forward and backward whirl, against R8's frequency determinant.

R8's shaft is massless; the model's shaft has 1e-5 of steel's density (6e-7 of the disc's
mass), which moves the frequencies by 1.5e-7 relative up to 400 rad/s, 4.3e-7 at 800 rad/s
(measured; the difference falls in proportion to the shaft's density from 1.5e-4 at 1e-2 of
steel's). The tolerance, 1e-6, is
above that and far below the effect of any term of the equations: without the moving basis's
curvature (the centrifugal terms of the disc's translation) the frequencies are off by 400 %,
with the basis held fixed by 10 % and more."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import flexmbd as fm

RELATIVE = 1e-6
SPEEDS = np.array([0.0, 50.0, 100.0, 200.0, 400.0, 800.0])  # rad/s; forward critical near 71


def r8_whirl(reference, speed):
    """R8: forward and backward whirl frequencies (rad/s, ascending) at `speed` (rad/s): the
    positive roots of (k11 - m w^2)(k22 - I_d w^2 + s I_p W w) - k12^2 (s = +1 forward, -1
    backward), a quartic in w."""
    m, i_p, i_d = reference["mass"], reference["polar inertia"], reference["diametral inertia"]
    k11, k12, k22 = reference["k11"], reference["k12"], reference["k22"]
    roots = []
    for s in (1.0, -1.0):
        # (k11 - m w^2)(k22 + s I_p W w - I_d w^2) - k12^2, highest power first.
        quartic = [m * i_d, -s * m * i_p * speed, -(m * k22 + k11 * i_d),
                   s * k11 * i_p * speed, k11 * k22 - k12**2]  # fmt: skip
        w = np.roots(quartic)
        roots.append(np.sort(w[(np.abs(w.imag) < 1e-9 * np.abs(w)) & (w.real > 0)].real))
    return roots


def determinant(reference, speed, w, s):
    """R8's determinant at w, relative to its largest term."""
    m, i_p, i_d = reference["mass"], reference["polar inertia"], reference["diametral inertia"]
    k11, k12, k22 = reference["k11"], reference["k12"], reference["k22"]
    a, b = k11 - m * w**2, k22 - i_d * w**2 + s * i_p * speed * w
    return (a * b - k12**2) / max(abs(k11 * k22), abs(m * i_d * w**4))


# A thin disc (I_p = 2 I_d nearly, the default) and a long body (I_p < I_d).
ROTORS = {"disc": {}, "long body": {"polar_inertia": 0.05, "diametral_inertia": 0.2}}


@pytest.fixture(params=sorted(ROTORS))
def rotor(request):
    return fm.examples.overhung_rotor(**ROTORS[request.param])


def test_the_welded_disc_turns_with_the_tip_node(assert_close):
    # A torque T about z on the disc bends the shaft in the x-y plane: the tip turns by
    # T L / EI and moves by T L^2 / 2 EI. A disc that did not turn with the node's rotation
    # would not turn at all.
    example = fm.examples.overhung_rotor()
    system = example.system
    torque = 1.0
    system.add_torque(system.add_marker(example.items["disc"]), (0.0, 0.0, torque))
    model = system.compile()
    state = fm.equilibrium(model)
    disc = model.describe()["bodies"][example.items["disc"].index]
    x, y, _, e0, _, _, e3 = state.coordinates[disc["offset"] : disc["offset"] + 7]
    reference = example.reference
    bending = reference["k22"] * 0.4 / 4  # EI from k22 = 4 EI / L, L = 0.4 m
    assert_close(2 * np.arctan2(e3, e0), torque * 0.4 / bending, rel=1e-5, what="disc turn")
    assert_close(y, torque * 0.4**2 / (2 * bending), rel=1e-5, what="tip deflection")
    assert_close(x, 0.4, abs=1e-9, what="disc on the axis")


def test_linearized_in_the_rotating_frame_against_r8(rotor, assert_close):
    # In the frame that turns at W, forward whirl w_f appears at w_f - W (its sense reversed
    # below the critical speed), backward whirl w_b at w_b + W; torsion (no whirl) is left out
    # by taking the frequencies closest to those expected.
    for speed in SPEEDS:
        system = rotor.system.with_driver("spin", fm.Polynomial([0.0, speed]))
        model = system.compile()
        state = fm.steady_rotation(model) if speed else fm.equilibrium(model)
        found = 2 * np.pi * fm.linearize(model, state, independent="elastic").frequencies()
        if speed == 0.0:
            # At rest the two bases span the same space; the null space's columns mix stiff
            # and soft coordinates and split the first pair in round-off (1.2e-5).
            fixed = fm.linearize(model, state, independent="null-space").frequencies()
            assert_close(2 * np.pi * fixed[:4], found[:4], rel=1e-4, what="null space at rest")
            assert abs(found[1] / found[0] - 1.0) < 1e-9
        forward, backward = r8_whirl(rotor.reference, speed)
        expected = np.sort(np.abs(np.concatenate([forward - speed, backward + speed])))
        nearest = found[np.argmin(np.abs(found[:, None] - expected[None, :]), axis=0)]
        assert_close(nearest, expected, rel=RELATIVE, what=f"rotating frame at {speed:g} rad/s")
        if speed == 100.0:
            # Regression: with the null-space basis held fixed the disc's absolute
            # coordinates turn under it, and the frequencies are wrong by 10 % and more.
            frozen = 2 * np.pi * fm.linearize(model, state, independent="null-space").frequencies()
            near = frozen[np.argmin(np.abs(frozen[:, None] - expected[None, :]), axis=0)]
            assert np.max(np.abs(near / expected - 1.0)) > 0.1


def test_forward_and_backward_whirl_in_the_fixed_frame_against_r8(rotor, assert_close):
    diagram = fm.campbell(rotor.system, "spin", SPEEDS, modes=5, frame="fixed")
    labels = diagram.whirl_labels
    # Two whirl pairs (translation and tilt of the disc) and the torsion, which does not
    # whirl; every mode keeps its label across the speeds.
    assert [labels.count(x) for x in ("forward", "backward", None)] == [2, 2, 1]
    w = 2 * np.pi * diagram.frequencies
    forward = w[:, [m for m, label in enumerate(labels) if label == "forward"]]
    backward = w[:, [m for m, label in enumerate(labels) if label == "backward"]]
    forward, backward = np.sort(forward, axis=1), np.sort(backward, axis=1)
    for k, speed in enumerate(SPEEDS):
        r8_forward, r8_backward = r8_whirl(rotor.reference, speed)
        assert_close(forward[k], r8_forward, rel=RELATIVE, what=f"forward at {speed:g} rad/s")
        assert_close(backward[k], r8_backward, rel=RELATIVE, what=f"backward at {speed:g}")
        # The determinant itself vanishes at the computed frequencies.
        for s, found in ((1.0, forward[k]), (-1.0, backward[k])):
            residual = [determinant(rotor.reference, speed, f, s) for f in found]
            assert_close(residual, 0.0, abs=10 * RELATIVE, what="R8 determinant")
    # At rest both directions have the same frequencies; with speed forward whirl stiffens
    # and backward whirl softens.
    assert_close(forward[0], backward[0], rel=1e-10, what="forward = backward at W = 0")
    assert np.all(np.diff(forward, axis=0) > 0) and np.all(np.diff(backward, axis=0) < 0)
    assert np.all(diagram.whirl_ratio[:, [labels.index("forward")]] > 0.99)
    assert np.all(diagram.whirl_ratio[:, [labels.index("backward")]] < -0.99)
    # The shapes change with the speed (the share of the disc's tilt): MAC 0.90 for the step
    # from 400 to 800 rad/s, above 0.97 for the others.
    assert diagram.mac.min() > 0.85
    # The rotating frame's diagram: the same modes and labels, at |w - W| and w + W.
    turning = fm.campbell(rotor.system, "spin", SPEEDS, modes=5)
    assert turning.whirl_labels == labels and turning.frame == "rotating"
    shift = SPEEDS[:, None] / (2 * np.pi)
    sign = np.array([{"forward": -1.0, "backward": 1.0, None: 0.0}[x] for x in labels])
    assert_close(turning.frequencies, np.abs(diagram.frequencies + sign * shift), rel=1e-9)


def test_the_critical_speed_of_the_forward_whirl(rotor, assert_close):
    # Unbalance excites synchronous forward whirl, w_f(W) = W: R8's determinant at w = W,
    # (k11 - m W^2)(k22 + (I_p - I_d) W^2) = k12^2, a quadratic in W^2.
    ref = rotor.reference
    m, i_p, i_d = ref["mass"], ref["polar inertia"], ref["diametral inertia"]
    quadratic = [-m * (i_p - i_d), ref["k11"] * (i_p - i_d) - m * ref["k22"],
                 ref["k11"] * ref["k22"] - ref["k12"] ** 2]  # fmt: skip
    squares = np.roots(quadratic) if i_p != i_d else np.roots(quadratic[1:])
    analytic = np.sort(np.sqrt(squares[(squares.real > 0) & (np.abs(squares.imag) == 0)].real))
    coarse = fm.campbell(rotor.system, "spin", np.linspace(0.0, 1500.0, 16), modes=5,
                         frame="fixed")  # fmt: skip
    found = [c for c in coarse.critical_speeds(orders=(1,)) if c["whirl"] == "forward"]
    # The thin disc: one forward critical speed (its tilt whirl, I_p > I_d, runs ahead of 1x);
    # the long body: two.
    assert len(found) == len(analytic)
    for crossing, expected in zip(found, analytic, strict=True):
        # Refined by a second sweep across the bracket of the coarse one (linear
        # interpolation between speeds 1 rad/s apart).
        low = coarse.speeds[coarse.speeds < crossing["speed"]][-1]
        fine = fm.campbell(rotor.system, "spin", np.arange(low, low + 101.0, 1.0), modes=5,
                           frame="fixed")  # fmt: skip
        refined = [c for c in fine.critical_speeds(orders=(1,)) if c["whirl"] == "forward"]
        assert len(refined) == 1
        assert_close(crossing["speed"], expected, rel=1e-3, what="coarse critical speed")
        assert_close(refined[0]["speed"], expected, rel=RELATIVE, what="critical speed")


def test_internal_damping_destabilizes_forward_whirl_above_the_critical_speed(assert_close):
    # Damping that turns with the shaft (D_ff = beta K_ff) drags a forward whirl along with
    # the spin: below the critical speed it damps, above it (the whirl slower than the
    # shaft) it feeds the whirl, the classical instability; it changes sign where the whirl
    # stands still in the rotating frame, w_f(W) = W. Backward whirl and the tilt's forward
    # whirl (faster than the spin) stay damped.
    rotor = fm.examples.overhung_rotor(shaft_damping=1e-6)
    ref = rotor.reference
    m, i_p, i_d = ref["mass"], ref["polar inertia"], ref["diametral inertia"]
    squares = np.roots([-m * (i_p - i_d), ref["k11"] * (i_p - i_d) - m * ref["k22"],
                        ref["k11"] * ref["k22"] - ref["k12"] ** 2])  # fmt: skip
    critical = float(np.sqrt(squares[squares.real > 0].real)[0])
    speeds = np.arange(0.0, 160.0, 1.0)
    diagram = fm.campbell(rotor.system, "spin", speeds, modes=5, frame="fixed")
    labels = diagram.whirl_labels
    first = min((m for m, x in enumerate(labels) if x == "forward"),
                key=lambda m: diagram.frequencies[0, m])  # fmt: skip
    zeta = diagram.damping[:, first]
    change = np.flatnonzero(np.sign(zeta[:-1]) != np.sign(zeta[1:]))
    assert len(change) == 1 and zeta[0] > 0 and zeta[-1] < 0
    k = change[0]
    speed = speeds[k] + zeta[k] / (zeta[k] - zeta[k + 1]) * (speeds[k + 1] - speeds[k])
    assert_close(speed, critical, rel=1e-5, what="speed where forward whirl loses its damping")
    others = [m for m in range(diagram.mode_count) if m != first]
    assert np.all(diagram.damping[:, others] > 0)
    # The decay rate -Re s is that of both frames.
    turning = fm.campbell(rotor.system, "spin", speeds, modes=5)

    def decay(d):
        w = 2 * np.pi * d.frequencies
        return d.damping * w / np.sqrt(1 - d.damping**2)

    assert_close(decay(diagram), decay(turning), rel=1e-9, abs=1e-12, what="decay rate")


@pytest.mark.parametrize(("speed", "stable"), [(50.0, True), (400.0, False)])
def test_the_steady_rotation_of_a_damped_rotor_is_unstable_above_its_critical_speed(speed, stable):
    # R8's nearly massless shaft with damping that turns with it has overdamped modes of
    # |s| = 2.1e11: as the scale of 1e-9 they hid the forward whirl's growth (Re s = 1.1 at
    # 400 rad/s: stable None, the 130 rad/s whirl counted as a free motion) and left the
    # 10.4 and 20.7 Hz modes out of the frequencies.
    model = fm.examples.overhung_rotor(speed=speed, shaft_damping=1e-4).system.compile()
    state = fm.steady_rotation(model)
    assert (state.stable, state.unstable_directions) == (stable, 0 if stable else 1)
    linear = fm.linearize(model, state)
    values = linear.eigenvalues()[0]
    assert (np.max(values.real) > 1.0) is not stable and linear.free_motions() == 0
    slow = np.sort(np.abs(values[np.abs(values) < 500]))[::2]
    frequencies = linear.frequencies()
    assert np.all([np.min(np.abs(2 * np.pi * frequencies - s)) < 0.05 * s for s in slow])


def test_diagram_file_and_plot(tmp_path):
    import xarray as xr

    rotor = fm.examples.overhung_rotor()
    diagram = fm.campbell(rotor.system, "spin", [0.0, 100.0, 200.0], modes=5, frame="fixed")
    diagram.to_xarray().to_netcdf(tmp_path / "rotor.nc", engine="scipy")
    with xr.open_dataset(tmp_path / "rotor.nc", engine="scipy") as data:
        assert data.attrs["frame"] == "fixed"
        assert list(data["whirl_label"].values) == [x or "" for x in diagram.whirl_labels]
        assert set(np.ravel(data["whirl"].values)) == {"forward", "backward", ""}
    fm.plot_campbell(diagram, tmp_path / "rotor.png", orders=(1,))
    assert (tmp_path / "rotor.png").stat().st_size > 1000
    assert rotor.check(diagram)["forward whirl, largest relative difference"] < RELATIVE


def test_refusals():
    rotor = fm.examples.overhung_rotor()
    with pytest.raises(fm.InvalidParameterError, match="frame must be one of"):
        fm.campbell(rotor.system, "spin", [0.0, 1.0], frame="inertial")
    with pytest.raises(fm.InvalidParameterError, match="independent must be one of"):
        fm.linearize(rotor.system, independent="modal")
    with pytest.raises(ValueError, match="fixed frame"):
        rotor.check(fm.campbell(rotor.system, "spin", [0.0, 1.0], modes=2))
    # A translation driver does not turn a rotor.
    system = fm.System()
    block = system.add_rigid_body(1.0, (1.0, 1.0, 1.0), name="block")
    ground, mark = system.add_marker(system.ground), system.add_marker(block)
    system.add_prismatic_joint(ground, mark)
    system.add_translation_driver(ground, mark, fm.Polynomial([0.0, 0.0]), name="slide")
    with pytest.raises(fm.InvalidParameterError, match="translation driver"):
        fm.campbell(system, "slide", [0.0, 1.0])
    # A rotor of rigid bodies: no deformable body turns, no whirl, no fixed frame.
    system = fm.System()
    wheel = system.add_rigid_body(1.0, (2.0, 1.0, 1.0), name="wheel")
    ground, hub = system.add_marker(system.ground), system.add_marker(wheel)
    system.add_revolute_joint(ground, hub)
    system.add_angle_driver(ground, hub, fm.Polynomial([0.0, 0.0]), name="spin")
    with pytest.raises(fm.InvalidParameterError, match="turns no deformable body"):
        fm.campbell(system, "spin", [0.0, 1.0], frame="fixed")


def test_the_campbell_command_in_the_fixed_frame(tmp_path, capsys, assert_close):
    from pathlib import Path

    from flexmbd.cli import main

    model = Path(__file__).parent.parent / "examples" / "models" / "overhung_rotor.yaml"
    stem = tmp_path / "rotor"
    code = main(["campbell", str(model), "--driver", "spin", "--speeds", "0:400:5",
                 "--modes", "5", "--frame", "fixed", "--orders", "1", "-o", str(stem)])  # fmt: skip
    out = capsys.readouterr().out
    assert code == 0, out
    assert "frequencies in the fixed frame" in out and "forward whirl at" in out
    # The model file is the built-in example's model.
    builtin = fm.campbell(fm.examples.overhung_rotor().system, "spin", np.linspace(0, 400, 5),
                          modes=5, frame="fixed")  # fmt: skip
    import xarray as xr

    with xr.open_dataset(stem.with_suffix(".nc"), engine="scipy") as data:
        assert_close(data["frequency"].values, builtin.frequencies, rel=1e-9)


def test_the_modes_command_gives_the_rotating_frame_frequencies_of_r8(capsys, assert_close):
    # `flexmbd modes` on the model file (turning at 100 rad/s) linearizes about the steady
    # rotation in the rotating frame: the whirl of R8 seen there (the fixed null-space basis
    # gave 66.1 and 73.1 rad/s).
    from flexmbd.cli import main

    path = Path(__file__).parents[1] / "examples" / "models" / "overhung_rotor.yaml"
    assert main(["modes", str(path), "--count", "5"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert "about the steady rotation" in lines[0]
    found = np.array([2 * np.pi * float(line.split()[1]) for line in lines[2:7]])
    reference = fm.examples.overhung_rotor().reference
    forward, backward = r8_whirl(reference, 100.0)
    expected = np.sort(np.abs(np.concatenate([forward - 100.0, backward + 100.0])))
    # The five lowest: the four of R8 and the shaft's torsion (130.1 rad/s), left out.
    nearest = found[np.argmin(np.abs(found[:, None] - expected[None, :]), axis=0)]
    assert len(set(nearest)) == 4
    assert_close(nearest, expected, rel=1e-5, what="modes command at 100 rad/s")
