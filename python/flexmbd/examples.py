"""Built-in example models with their published reference results.

Each builder returns an :class:`Example`: the system, the recommended simulation settings, the
ids of interesting items, and a ``check`` function that compares a result with the reference
(``../shared/reference`` R5: the IFToMM multibody benchmark problems).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from . import _boundary, _core
from .errors import InvalidParameterError
from .rotation import rotation
from .system import System

Array = NDArray[np.float64]


@dataclass
class Example:
    """A ready-to-run model."""

    name: str
    description: str
    system: System
    end_time: float
    step_size: float
    solver: _boundary.GeneralizedAlpha
    output_interval: float
    items: dict[str, Any] = field(default_factory=dict)
    reference: dict[str, Any] = field(default_factory=dict)
    check: Callable[[Any], dict[str, float]] | None = None


def pendulum() -> Example:
    """IFToMM A01: a 1 kg point mass on a massless 1 m link (a distance constraint), released at
    rest from x = +1 m, gravity 9.81 m/s^2 along -y. Exact positions at t = 0.5, 1, 5, 10 s."""
    system = System(gravity=(0.0, -9.81, 0.0))
    mass = system.add_point_mass(1.0, position=(1.0, 0.0, 0.0), name="mass")
    pivot = system.add_marker(system.ground, name="pivot")
    bob = system.add_marker(mass, name="bob")
    link = system.add_distance_joint(pivot, bob, 1.0, name="link")
    sensor = system.add_sensor(bob, "position", name="bob position")
    reference = {
        0.5: (0.391048791551, -0.920369948785),
        1.0: (-0.986291751132, -0.165010853126),
        5.0: (0.942305435044, -0.334754338414),
        10.0: (0.275087462576, -0.961419205099),
    }

    def check(result: Any) -> dict[str, float]:
        errors = {}
        for t, (x, y) in reference.items():
            k = int(np.argmin(np.abs(result.time - t)))
            if abs(result.time[k] - t) < 1e-9:
                p = result.sensor(sensor)[k]
                errors[f"position error at t = {t:g} s"] = float(max(abs(p[0] - x), abs(p[1] - y)))
        return errors

    return Example(
        name="pendulum",
        description="IFToMM A01 simple pendulum (point mass on a distance constraint)",
        system=system,
        end_time=10.0,
        step_size=5e-5,
        solver=_boundary.GeneralizedAlpha(1.0),
        output_interval=0.01,
        items={"mass": mass, "link": link, "bob": sensor},
        reference=reference,
        check=check,
    )


# The links of the four-bars: 1 kg, 1 m slender rods along their local x axis (the axial
# moment is irrelevant for planar motion).
FOUR_BAR_ROD = (5e-5, 1.0 / 12.0, 1.0 / 12.0)


def _four_bar_cranks(system: System, count: int) -> tuple[list, list, list]:
    """The vertical cranks of the four-bars at x = 0 .. count - 1, pivoted on the ground about
    z at y = 0, turning at -1 rad/s (B0 moves at 1 m/s along +x): bodies, top markers B<k> (axes
    parallel to the global ones) and pivot joints."""
    up = rotation("z", np.pi / 2)  # crank frame: local x points up
    to_joint = rotation("z", -np.pi / 2)  # marker axes parallel to the global axes
    cranks, tops, pivots = [], [], []
    for k in range(count):
        crank = system.add_rigid_body(
            1.0,
            FOUR_BAR_ROD,
            position=(k, 0.5, 0.0),
            orientation=up,
            velocity=(0.5, 0.0, 0.0),
            angular_velocity=(0.0, 0.0, -1.0),
            name=f"crank {k}",
        )
        ground_marker = system.add_marker(system.ground, position=(k, 0.0, 0.0))
        bottom = system.add_marker(crank, position=(-0.5, 0.0, 0.0), orientation=to_joint)
        pivots.append(system.add_revolute_joint(ground_marker, bottom, name=f"pivot {k}"))
        tops.append(
            system.add_marker(crank, position=(0.5, 0.0, 0.0), orientation=to_joint, name=f"B{k}")
        )
        cranks.append(crank)
    return cranks, tops, pivots


def four_bar(n: int = 2) -> Example:
    """IFToMM A02 N-four-bar in 3D: 2N+1 uniform 1 kg, 1 m links, gravity 9.81 m/s^2 along -y.
    Cranks stand vertically on pivots at x = 0..N, couplers lie horizontally at y = 1; the top
    of the first crank, B0, starts at 1 m/s along +x. Cranks: revolute joints to the ground;
    couplers: revolute joint to crank k and an in-line joint (in-plane position only) to crank
    k+1, so that the spatial model has no redundant equations. The mechanism passes singular
    configurations (cranks horizontal) twice per turn. Exact B0 at t = 10 s for N = 2."""
    if n < 1:
        raise InvalidParameterError(f"n must be at least 1, got {n}")
    system = System(gravity=(0.0, -9.81, 0.0))
    inertia = FOUR_BAR_ROD
    cranks, tops, pivots = _four_bar_cranks(system, n + 1)
    couplers = []
    for k in range(n):
        coupler = system.add_rigid_body(
            1.0,
            inertia,
            position=(k + 0.5, 1.0, 0.0),
            velocity=(1.0, 0.0, 0.0),
            name=f"coupler {k}",
        )
        left = system.add_marker(coupler, position=(-0.5, 0.0, 0.0))
        right = system.add_marker(coupler, position=(0.5, 0.0, 0.0))
        system.add_revolute_joint(tops[k], left, name=f"coupler {k} left")
        system.add_inline_joint(tops[k + 1], right, name=f"coupler {k} right")
        couplers.append(coupler)
    b0_position = system.add_sensor(tops[0], "position", name="B0 position")
    b0_velocity = system.add_sensor(tops[0], "velocity", name="B0 velocity")
    reference = {
        "position": (0.3284581115, 0.9445185382),
        "velocity": (1.4230514702, -0.4948688455),
    }

    def check(result: Any) -> dict[str, float]:
        if n != 2 or abs(result.time[-1] - 10.0) > 1e-9:
            return {}
        p = result.sensor(b0_position)[-1]
        v = result.sensor(b0_velocity)[-1]
        return {
            "B0 position error at t = 10 s": float(np.max(np.abs(p[:2] - reference["position"]))),
            "B0 velocity error at t = 10 s": float(np.max(np.abs(v[:2] - reference["velocity"]))),
        }

    return Example(
        name="four-bar",
        description=f"IFToMM A02 N-four-bar, N = {n} ({2 * n + 1} rigid links, 3D)",
        system=system,
        end_time=10.0,
        step_size=2e-4,
        solver=_boundary.GeneralizedAlpha(0.9),
        output_interval=0.01,
        items={
            "cranks": cranks,
            "couplers": couplers,
            "pivots": pivots,
            "B0 position": b0_position,
            "B0 velocity": b0_velocity,
        },
        reference=reference if n == 2 else {},
        check=check,
    )


def flexible_slider_crank(
    elements: int = 8,
    geometric_stiffness: bool = True,
    rod_diameter: float = 6e-3,
    crank_speed: float = 150.0,
) -> Example:
    """Reference R4 (Jonker / Simeon data set): a rigid crank (0.15 m) driven at constant
    150 rad/s, an elastic connecting rod (0.30 m, steel, solid circular section d = 6 mm) of
    `elements` beam elements in the floating frame of reference, a slider of half the rod mass
    on the x axis; no gravity, no damping; two crank turns. The rod's reference conditions are
    simply supported (body frame on the chord), so its elastic transverse displacement at the
    middle node is the deflection from the chord: max |v_mid| = 4.658e-3 m near t = 0.078 s.

    `rod_diameter` (m) and `crank_speed` (rad/s) vary the model for design studies (the
    reference holds for the defaults)."""
    from .fe import Material, Section, build_body, straight_beam

    crank_length, rod_length, omega = 0.15, 0.30, crank_speed
    nodes, conn = straight_beam(rod_length, elements)
    rod_data = build_body(
        nodes,
        conn,
        Material(2.0e11, 0.3, 7870.0),
        section=Section.circle(rod_diameter / 2),
        reference="simply-supported",
        reference_nodes=[0, elements],
    )
    system = System()
    crank = system.add_rigid_body(
        0.1,
        (1e-6, 0.1 * crank_length**2 / 12, 0.1 * crank_length**2 / 12),
        center_of_mass=(crank_length / 2, 0, 0),
        angular_velocity=(0, 0, omega),
        name="crank",
    )
    # Velocities of the rigid mechanism at crank angle 0: the rod turns about the slider end.
    rod = system.add_flexible_body(
        rod_data,
        position=(crank_length, 0, 0),
        velocity=(0, omega * crank_length, 0),
        angular_velocity=(0, 0, -omega * crank_length / rod_length),
        geometric_stiffness=geometric_stiffness,
        name="rod",
    )
    slider = system.add_point_mass(
        rod_data.invariants.mass / 2, position=(crank_length + rod_length, 0, 0), name="slider"
    )
    pivot, crank_root = system.add_marker(system.ground), system.add_marker(crank)
    system.add_revolute_joint(pivot, crank_root, name="bearing")
    drive = system.add_angle_driver(
        pivot, crank_root, _boundary.Polynomial([0.0, omega]), name="drive"
    )
    crank_pin = system.add_revolute_joint(
        system.add_marker(crank, position=(crank_length, 0, 0)),
        system.add_node_marker(rod, 1),
        name="crank pin",
    )
    wrist = system.add_spherical_joint(
        system.add_node_marker(rod, elements + 1), system.add_marker(slider), name="wrist pin"
    )
    guide = system.add_inline_joint(
        system.add_marker(system.ground, orientation=rotation("y", np.pi / 2)),
        system.add_marker(slider),
        name="guide",
    )
    middle = elements // 2 + 1
    reference = {"max |v_mid| (m)": 4.658e-3, "time of the maximum (s)": 0.078}

    def check(result: Any) -> dict[str, float]:
        if result.time[-1] < 2 * 2 * np.pi / omega - 1e-9:
            return {}  # the reference is the maximum over the first two turns of the crank
        v_mid = result.node_displacements(rod, [middle])[:, 0, 1]
        k = int(np.argmax(np.abs(v_mid)))
        return {
            "relative error of max |v_mid|": float(abs(abs(v_mid[k]) / 4.658e-3 - 1.0)),
            "time of the maximum - 0.078 s": float(abs(result.time[k] - 0.078)),
        }

    return Example(
        name="flexible-slider-crank",
        description="R4 flexible slider-crank: rigid crank at 150 rad/s, elastic rod (FFRF beam)",
        system=system,
        end_time=2 * 2 * np.pi / omega,
        step_size=2e-5,
        solver=_boundary.GeneralizedAlpha(0.9),
        output_interval=1e-4,
        items={
            "crank": crank,
            "rod": rod,
            "slider": slider,
            "middle node": middle,
            "drive": drive,
            "crank pin": crank_pin,
            "wrist pin": wrist,
            "guide": guide,
        },
        reference=reference,
        check=check,
    )


def _spin_up_hub_angle(t: float) -> tuple[float, float, float]:
    """The spin-up's hub angle, speed and acceleration: to 6 rad/s in 15 s (Simo and Vu-Quoc),
    a module function so that the model pickles."""
    ts, ws = 15.0, 6.0
    if t <= ts:
        c = ts / (2 * np.pi)
        theta = ws / ts * (t**2 / 2 + c**2 * (np.cos(t / c) - 1))
        return theta, ws / ts * (t - c * np.sin(t / c)), ws / ts * (1 - np.cos(t / c))
    return ws * (t - ts / 2), ws, 0.0


def spin_up(geometric_stiffness: bool | str = True, elements: int = 10, bodies: int = 1) -> Example:
    """Reference R3 (Kane, Ryan and Banerjee 1987): a 10 m beam (EA = 2.8e7 N,
    EI = 1.4e4 N m^2, rho A = 1.2 kg/m) clamped to a hub whose angle is prescribed,
    theta = (Ws/Ts) [t^2/2 + (Ts/2 pi)^2 (cos(2 pi t/Ts) - 1)] up to Ts = 15 s, then Ws = 6 rad/s.
    The tip lags behind the hub: min v_tip = -0.5737 m at 6.75 s (in the frame that turns with
    the hub). Needs the geometric stiffness of the centrifugal tension; without it the model
    diverges once the hub turns faster than the first bending frequency (3.7977 rad/s).

    `geometric_stiffness`: True (or "von-karman") for the von Karman strain, "corotational"
    for the co-rotational beam (geometrically exact elastic forces), False for none.
    `bodies` > 1 splits the beam into that many deformable bodies of `elements / bodies`
    elements each, joined by fixed joints. Under refinement one body with the von Karman
    strain converges to the answer of its second-order strain (-0.5759 m, 0.38 % more
    flexible than R3); with the co-rotational beam to R3 (-0.5742 / -0.5739 / -0.5738 m at
    10 / 20 / 80 elements); several von Karman bodies also reach R3 (8 bodies of 5 elements:
    -0.5736 m; ``benchmarks/spin_up_refinement.py``)."""
    from .fe import Material, Section, build_body, straight_beam

    hub_angle = _spin_up_hub_angle
    if bodies < 1 or elements % bodies:
        raise InvalidParameterError(
            f"elements ({elements}) must be a multiple of bodies ({bodies})"
        )
    per_body = elements // bodies
    length = 10.0 / bodies
    nodes, conn = straight_beam(length, per_body)
    data = build_body(
        nodes,
        conn,
        Material(7.0e10, 0.3, 3000.0),
        section=Section(4e-4, 2e-7, 2e-7, 4e-7),
        reference="clamped",
        reference_nodes=[0],
    )
    system = System()
    parts = [
        system.add_flexible_body(
            data,
            position=(k * length, 0.0, 0.0),
            geometric_stiffness=geometric_stiffness,
            name="beam" if bodies == 1 else f"beam {k + 1}",
        )
        for k in range(bodies)
    ]
    beam = parts[0]
    hub, root = system.add_marker(system.ground), system.add_node_marker(beam, 1)
    system.add_revolute_joint(hub, root, name="hub")
    drive = system.add_angle_driver(
        hub, root, _boundary.UserFunction(hub_angle, derivatives=True), name="drive"
    )
    for k, (inner, outer) in enumerate(zip(parts, parts[1:], strict=False)):
        system.add_fixed_joint(
            system.add_node_marker(inner, per_body + 1),
            system.add_node_marker(outer, 1),
            name=f"splice {k + 1}",
        )
    tip = per_body + 1
    reference = {"min v_tip (m)": -0.5737, "t of min (s)": 6.75, "v_tip(5 s)": -0.4684}

    def tip_lag(result: Any) -> NDArray[np.float64]:
        """v_tip (m) in the frame that turns with the hub."""
        if bodies == 1:
            return result.node_displacements(beam, [tip])[:, 0, 1]
        position = result.node_positions(parts[-1], [tip])[:, 0, :]
        theta = np.array([hub_angle(t)[0] for t in result.time])
        return -np.sin(theta) * position[:, 0] + np.cos(theta) * position[:, 1]

    def check(result: Any) -> dict[str, float]:
        if result.time[-1] < 7.5:
            return {}  # the reference is the minimum at 6.75 s, past which the tip rises
        v_tip = tip_lag(result)
        k = int(np.argmin(v_tip))
        errors = {
            "min v_tip error (m)": float(abs(v_tip[k] + 0.5737)),
            "time of the minimum - 6.75 s": float(abs(result.time[k] - 6.75)),
        }
        at5 = int(np.argmin(np.abs(result.time - 5.0)))
        errors["v_tip(5 s) error (m)"] = float(abs(v_tip[at5] + 0.4684))
        return errors

    return Example(
        name="spin-up",
        description="R3 spin-up of a flexible beam (geometric stiffness)",
        system=system,
        end_time=10.0,
        step_size=5e-3,
        solver=_boundary.GeneralizedAlpha(0.9),
        output_interval=0.05,
        items={"beam": beam, "tip node": tip, "drive": drive},
        reference=reference,
        check=check,
    )


def tetrahedral_pendulum(mode_count: int = 6) -> Example:
    """A pendulum whose arm is a deformable solid: an aluminium bar 0.5 x 0.03 x 0.03 m of
    4-node tetrahedra (20 x 2 x 2 cells), reduced by Craig-Bampton (`mode_count`
    fixed-interface modes, the body frame on the hinged end face x0), swinging under gravity
    (9.81 m/s^2 along -y) about a revolute joint at the centroid of that face, released
    horizontally. Without damping, at spectral radius 1, its energy is conserved."""
    from .fe import Material, build_body, shapes

    mesh = shapes.box((0.5, 0.03, 0.03), (20, 2, 2), "tet4")
    data = build_body(
        mesh.nodes,
        mesh.elements,
        Material(7.0e10, 0.33, 2700.0),
        node_sets=mesh.node_sets,
        reference="interface",
        modes="craig-bampton",
        mode_count=mode_count,
        interfaces=["x0"],
    )
    system = System(gravity=(0.0, -9.81, 0.0))
    # The body frame at the mesh's origin, the hinge at the centroid (0, 0.015, 0.015) of the
    # face x0: placed so that the hinge is at the global origin.
    arm = system.add_flexible_body(data, position=(0.0, -0.015, -0.015), name="arm")
    hinge = system.add_node_set_marker(arm, "x0")
    joint = system.add_revolute_joint(system.add_marker(system.ground), hinge, name="hinge")

    def check(result: Any) -> dict[str, float]:
        exchanged = float(np.ptp(result.potential_energy))
        drift = float(np.max(np.abs(result.total_energy - result.total_energy[0])))
        return {"energy drift relative to the energy exchanged": drift / exchanged}

    return Example(
        name="tetrahedral-pendulum",
        description="pendulum of a tetrahedral mesh reduced by Craig-Bampton (energy)",
        system=system,
        end_time=1.0,
        step_size=5e-4,
        solver=_boundary.GeneralizedAlpha(1.0),
        output_interval=0.01,
        items={"arm": arm, "hinge": joint, "body data": data},
        check=check,
    )


def rotating_beam(
    material: Any,
    section: Any,
    length: float,
    elements: int,
    *,
    speed: float = 0.0,
    geometric_stiffness: bool = False,
    orientation: Any = (0.0, 1.0, 0.0),
    name: str = "blade",
) -> System:
    """A uniform clamped-free beam turned about an axis through its clamped end: `elements`
    Euler-Bernoulli elements of `material` and `section` along x, `length` (m) long, the body
    frame clamped at its first node (the root), which the revolute joint "bearing" holds on
    the global z axis and the angle driver "hub" turns at `speed` (rad/s) from angle 0
    (:meth:`flexmbd.System.with_driver` changes its motion). `orientation` is the section's
    (:func:`flexmbd.fe.build_body`; the default puts the section's y axis along global y, so
    that bending about it, flap, moves the beam along z, out of the plane of rotation). The
    deformable body is named `name`; `geometric_stiffness` as in
    :meth:`flexmbd.System.add_flexible_body`. The blade of R2 (Wright et al. 1982), the rod of
    R6 (:func:`flexmbd.dispersion`)."""
    from .fe import build_body, straight_beam

    nodes, conn = straight_beam(length, elements)
    data = build_body(
        nodes,
        conn,
        material,
        section=section,
        orientation=orientation,
        reference="clamped",
        reference_nodes=[0],
    )
    system = System()
    beam = system.add_flexible_body(data, geometric_stiffness=geometric_stiffness, name=name)
    hub, root = system.add_marker(system.ground), system.add_node_marker(beam, 1)
    system.add_revolute_joint(hub, root, name="bearing")
    system.add_angle_driver(hub, root, _boundary.Polynomial([0.0, float(speed)]), name="hub")
    return system


def shaken_pendulum(
    amplitude: float,
    rate: float,
    *,
    upright: bool = False,
    angle: float = 0.0,
    length: float = 1.0,
    mass: float = 1.0,
    inertia: float = 1e-3,
) -> System:
    """A pendulum on a support shaken vertically as y = `amplitude` sin(`rate` t) (m, rad/s;
    the translation driver "shake" on the prismatic joint of the 1 kg body "support"):
    the body "bob" (`mass`, `inertia` about its centre on every axis) `length` from its
    revolute joint on the support's origin, hanging (or `upright`) and turned by `angle` about
    z at the start, moving up with the support. Gravity 9.81 m/s^2 along -y. Linearized about
    the hanging (upright) position: Mathieu's equation (m L^2 + I) theta_dd + (-) m L (g +
    y_dd(t)) theta = 0; the subject of :func:`flexmbd.floquet`'s tests and
    ``examples/shaken_pendulum.py`` (parametric resonance, Kapitza's pendulum)."""
    along_y = np.array([[1, 0, 0], [0, 0, 1], [0, -1, 0]], float)  # a marker's z along y
    system = System(gravity=(0.0, -9.81, 0.0))
    support = system.add_rigid_body(1.0, (1.0, 1.0, 1.0), name="support")
    rail = system.add_marker(system.ground, orientation=along_y)
    carried = system.add_marker(support, orientation=along_y)
    system.add_prismatic_joint(rail, carried)
    system.add_translation_driver(rail, carried, _boundary.Harmonic(amplitude, rate), name="shake")
    side = 1.0 if upright else -1.0
    turn = rotation("z", angle)
    bob = system.add_rigid_body(
        mass,
        (inertia, inertia, inertia),
        position=turn @ (0.0, side * length, 0.0),
        orientation=turn,
        velocity=(0.0, amplitude * rate, 0.0),
        name="bob",
    )
    system.add_revolute_joint(
        system.add_marker(support), system.add_marker(bob, position=(0.0, -side * length, 0.0))
    )
    return system


def shaken_pendulum_multipliers(
    amplitude: float,
    rate: float,
    *,
    upright: bool = False,
    length: float = 1.0,
    mass: float = 1.0,
    inertia: float = 1e-3,
) -> Array:
    """The Floquet multipliers of :func:`shaken_pendulum`'s small motions about hanging (or
    `upright`), from its linear periodic equation (Mathieu's), (m L^2 + I) theta_dd +- m L
    (g + y_dd(t)) theta = 0 with y = `amplitude` sin(`rate` t): the eigenvalues of its
    fundamental matrix over a period (scipy's DOP853 at 1e-12), independent of the
    simulation (the reference of :func:`flexmbd.floquet`'s tests and
    ``examples/shaken_pendulum.py``)."""
    from scipy.integrate import solve_ivp

    sign = -1.0 if upright else 1.0

    def rates(t: float, x: Array) -> Array:
        shake = -amplitude * rate**2 * np.sin(rate * t)
        k = sign * mass * length * (9.81 + shake) / (mass * length**2 + inertia)
        return (np.array([[0.0, 1.0], [-k, 0.0]]) @ x.reshape(2, 2)).ravel()

    period = 2 * np.pi / rate
    solution = solve_ivp(rates, (0, period), np.eye(2).ravel(), "DOP853", rtol=1e-12, atol=1e-14)
    return np.linalg.eigvals(solution.y[:, -1].reshape(2, 2))


def rotating_blade_flap_frequencies(
    g: float,
    geometric_stiffness: bool = True,
    elements: int = 40,
    count: int = 3,
    direction: str = "flap",
) -> np.ndarray:
    """Reference R2 (Wright et al. 1982): the first `count` nondimensional flap frequencies
    w sqrt(rho A L^4 / EI) of a uniform cantilever turned at the nondimensional speed
    g = W sqrt(rho A L^4 / EI) about an axis through its root (global z, the beam along x).
    With `direction="lag"`, the lead-lag (in-plane) frequencies instead, for a blade of the
    same bending stiffness in both planes (a square section).

    The blade (aluminium, 1 m, a slender 10 x 2 mm section with the flap stiffness EI_y,
    `elements` beams; :func:`rotating_beam`) is turned by an angle driver at constant speed;
    `flexmbd.equilibrium` finds the steadily rotating, stretched blade and `flexmbd.linearize`
    the motion about it. Flap modes are those that move the nodes along z, lead-lag modes
    along y."""
    if direction not in ("flap", "lag"):
        raise InvalidParameterError(f"direction must be 'flap' or 'lag', got {direction!r}")
    from .analysis import equilibrium, linearize
    from .fe import Material, Section

    width, height = (0.01, 0.002) if direction == "flap" else (0.002, 0.002)
    material = Material(7.0e10, 0.3, 2700.0)
    rho_a = material.density * width * height
    scale = np.sqrt(rho_a / (material.young_modulus * width * height**3 / 12))
    system = rotating_beam(
        material,
        Section.rectangle(width, height),  # iy = width height^3 / 12: flap
        1.0,
        elements,
        speed=g / scale,
        geometric_stiffness=geometric_stiffness,
    )
    frequencies, shapes = linearize(system, equilibrium(system)).modes()
    rows = np.concatenate([7 + 6 * k + np.arange(3) for k in range(elements)])
    moved = shapes[rows].reshape(elements, 3, -1)
    axis = 2 if direction == "flap" else 1
    selected = np.sum(moved[:, axis] ** 2, axis=0) / np.sum(moved**2, axis=(0, 1)) > 0.9
    return 2 * np.pi * frequencies[selected][:count] * scale


#: The disc of :func:`overhung_rotor`: steel (7850 kg/m^3), radius 0.15 m, 0.03 m thick.
DISC_MASS = 7850.0 * np.pi * 0.15**2 * 0.03
#: Its polar moment of inertia m r^2 / 2 (kg m^2).
DISC_POLAR_INERTIA = DISC_MASS * 0.15**2 / 2
#: Its diametral moment of inertia m r^2 / 4 + m t^2 / 12 (kg m^2).
DISC_DIAMETRAL_INERTIA = DISC_MASS * (0.15**2 / 4 + 0.03**2 / 12)


def _r8_whirl(speed: float, reference: dict[str, float]) -> tuple[Array, Array]:
    """Reference R8: the forward and the backward whirl frequencies (rad/s, ascending) of the
    overhung rotor of `reference` at `speed` (rad/s), the positive real roots w of
    (k11 - m w^2)(k22 - I_d w^2 + s I_p W w) - k12^2 = 0 (s = +1, -1)."""
    m, polar, diametral = (reference[k] for k in ("mass", "polar inertia", "diametral inertia"))
    k11, k12, k22 = (reference[k] for k in ("k11", "k12", "k22"))
    whirls = []
    for sense in (1.0, -1.0):
        quartic = np.polysub(
            np.polymul([-m, 0.0, k11], [-diametral, sense * polar * speed, k22]), [k12**2]
        )
        roots = np.roots(quartic)
        real = roots[(np.abs(roots.imag) <= 1e-9 * np.abs(roots)) & (roots.real > 0)].real
        whirls.append(np.sort(real))
    return whirls[0], whirls[1]


def overhung_rotor(
    *,
    speed: float = 0.0,
    length: float = 0.4,
    diameter: float = 0.02,
    young_modulus: float = 2.1e11,
    shaft_density: float = 7850.0e-5,
    elements: int = 4,
    disc_mass: float = DISC_MASS,
    polar_inertia: float = DISC_POLAR_INERTIA,
    diametral_inertia: float = DISC_DIAMETRAL_INERTIA,
    shaft_damping: float = 0.0,
) -> Example:
    """Reference R8, the overhung rotor: a rigid disc (`disc_mass` kg, `polar_inertia` and
    `diametral_inertia` kg m^2; by default a steel disc of radius 0.15 m, 0.03 m thick) at
    the free end of a cantilever shaft along global x (`length` m, a round section of
    `diameter` m, `young_modulus` Pa, `elements` Euler-Bernoulli beams), spinning at `speed`
    rad/s about its axis. The shaft is the deformable body "shaft", its frame clamped at its
    root, which the revolute joint "bearing" holds on the x axis and the angle driver "spin"
    turns; the disc is the rigid body "disc", welded (fixed joint "weld") to a marker on the
    shaft's tip node, which turns with the node's small rotations. All independent
    coordinates are then the shaft's elastic coordinates, in its rotating frame
    (:func:`flexmbd.linearize` with ``independent="elastic"``, :func:`flexmbd.campbell`).
    R8's shaft is massless: `shaft_density` (kg/m^3) defaults to 1e-5 of steel's, a shaft
    of 6e-7 of the disc's mass, which moves the whirl frequencies by 1.5e-7 to 4.3e-7 relative
    (0 to 800 rad/s).
    `shaft_damping` (s) is the shaft's stiffness-proportional damping D_ff = beta K_ff:
    internal damping, which turns with the shaft (it makes forward whirl unstable above its
    critical speed).

    `reference` holds R8's parameters (mass, polar inertia, diametral inertia, and the end
    stiffness k11 = 12 EI / L^3, k12 = -6 EI / L^2, k22 = 4 EI / L); `check` takes a
    :func:`flexmbd.campbell` diagram in the fixed frame and returns the largest relative
    differences of its forward and backward whirl frequencies from R8's, speed by speed
    (the lowest R8 roots of each direction, as many as the diagram has modes of it). The
    simulation settings are for a run of the spinning rotor from its steady rotation."""
    from .fe import Material, Section, build_body, straight_beam

    for label, value in (
        ("length", length),
        ("diameter", diameter),
        ("young_modulus", young_modulus),
        ("shaft_density", shaft_density),
        ("disc_mass", disc_mass),
        ("polar_inertia", polar_inertia),
        ("diametral_inertia", diametral_inertia),
    ):
        if not (np.isfinite(value) and value > 0):
            raise InvalidParameterError(f"{label} must be positive and finite, got {value}")
    if elements < 1:
        raise InvalidParameterError(f"elements must be at least 1, got {elements}")
    if not (np.isfinite(shaft_damping) and shaft_damping >= 0):
        raise InvalidParameterError(f"shaft_damping must be >= 0 and finite, got {shaft_damping}")
    section = Section.circle(diameter / 2)
    nodes, conn = straight_beam(length, elements)
    data = build_body(
        nodes,
        conn,
        Material(young_modulus, 0.3, shaft_density),
        section=section,
        reference="clamped",
        reference_nodes=[0],
    )
    system = System()
    shaft = system.add_flexible_body(
        data, rayleigh_damping=(0.0, shaft_damping) if shaft_damping else None, name="shaft"
    )
    # Joint frames with their z axes along the shaft (global x).
    along_x = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    hub = system.add_marker(system.ground, orientation=along_x, name="hub")
    root = system.add_node_marker(shaft, 1, orientation=along_x, name="root")
    bearing = system.add_revolute_joint(hub, root, name="bearing")
    spin = system.add_angle_driver(
        hub, root, _boundary.Polynomial([0.0, float(speed)]), name="spin"
    )
    tip = elements + 1
    disc = system.add_rigid_body(
        disc_mass,
        (polar_inertia, diametral_inertia, diametral_inertia),
        position=(length, 0.0, 0.0),
        name="disc",
    )
    weld = system.add_fixed_joint(
        system.add_node_marker(shaft, tip, name="tip"), system.add_marker(disc), name="weld"
    )
    bending = young_modulus * section.iy
    reference = {
        "mass": float(disc_mass),
        "polar inertia": float(polar_inertia),
        "diametral inertia": float(diametral_inertia),
        "k11": 12 * bending / length**3,
        "k12": -6 * bending / length**2,
        "k22": 4 * bending / length,
    }

    def check(diagram: Any) -> dict[str, float]:
        if diagram.frame != "fixed":
            raise ValueError("overhung_rotor's check needs a Campbell diagram in the fixed frame")
        worst = {"forward": 0.0, "backward": 0.0}
        for k, w in enumerate(diagram.speeds):
            analytic = dict(
                zip(("forward", "backward"), _r8_whirl(float(w), reference), strict=True)
            )
            for label in worst:
                found = np.sort(2 * np.pi * diagram.frequencies[k][diagram.whirl[k] == label])
                expected = analytic[label][: len(found)]
                if len(expected) < len(found):
                    worst[label] = np.inf
                elif len(found):
                    difference = float(np.max(np.abs(found / expected - 1.0)))
                    worst[label] = max(worst[label], difference)
        return {f"{label} whirl, largest relative difference": v for label, v in worst.items()}

    return Example(
        name="overhung-rotor",
        description="R8 overhung rotor: a disc on a cantilever shaft, forward and backward whirl",
        system=system,
        end_time=0.2,
        step_size=1e-4,
        solver=_boundary.GeneralizedAlpha(0.9),
        output_interval=1e-3,
        items={
            "shaft": shaft,
            "disc": disc,
            "bearing": bearing,
            "spin": spin,
            "weld": weld,
            "tip node": tip,
            "driver": "spin",
        },
        reference=reference,
        check=check,
    )


def _beam_link(length: float, elements: int, mode_count: int = 0) -> Any:
    """An aluminium link (circular section, radius 5 mm) of `elements` Euler-Bernoulli beam
    elements along x, the body frame clamped at its first node: nodal elastic coordinates, or
    the first `mode_count` fixed-interface (clamped) modes if `mode_count` > 0."""
    from .fe import Material, Section, build_body, straight_beam

    nodes, conn = straight_beam(length, elements)
    return build_body(
        nodes,
        conn,
        Material(7.0e10, 0.33, 2700.0),
        section=Section.circle(0.005),
        reference="clamped",
        reference_nodes=[0],
        modes="fixed-interface" if mode_count > 0 else None,
        mode_count=mode_count,
    )


def _energy_balance(result: Any, power: Any = None) -> float:
    """Largest |change of the total energy - work of the drives| over the run, relative to the
    largest kinetic energy (`power`: the drives' power at the output times, or None)."""
    energy = result.total_energy - result.total_energy[0]
    work = np.zeros_like(energy)
    if power is not None:
        steps = np.diff(result.time)
        work[1:] = np.cumsum(0.5 * (power[1:] + power[:-1]) * steps)
    return float(np.max(np.abs(energy - work)) / np.max(np.abs(result.kinetic_energy)))


def flexible_double_pendulum(elements: int = 4, mode_count: int = 0) -> Example:
    """Two elastic aluminium links (1 m, circular section of radius 5 mm, `elements` beam
    elements each, frames clamped at their first nodes) hinged to the ground and to each other
    by revolute joints about z, released from the horizontal under gravity (9.81 m/s^2 along
    -y); the second hinge is at the deformed tip of the first link (node marker). With
    `mode_count` > 0 each link keeps that many clamped modes instead of its nodal coordinates
    (without the axial and high bending modes the explicit solvers take large steps). No damping:
    the total (kinetic, strain and gravity) energy is conserved. A model for the
    joint-coordinate formulation with deformable bodies (seed section 5), which integrates the
    two hinge angles and the elastic coordinates."""
    system = System(gravity=(0, -9.81, 0))
    data = _beam_link(1.0, elements, mode_count)
    upper = system.add_flexible_body(data, name="upper link")
    lower = system.add_flexible_body(data, position=(1.0, 0, 0), name="lower link")
    tip = elements + 1
    shoulder = system.add_revolute_joint(
        system.add_marker(system.ground), system.add_node_marker(upper, 1), name="shoulder"
    )
    elbow = system.add_revolute_joint(
        system.add_node_marker(upper, tip), system.add_node_marker(lower, 1), name="elbow"
    )

    def check(result: Any) -> dict[str, float]:
        return {"energy change / max kinetic energy": _energy_balance(result)}

    return Example(
        name="flexible-double-pendulum",
        description="two elastic links hinged in series, swinging under gravity",
        system=system,
        end_time=2.0,
        step_size=1e-3,
        solver=_boundary.GeneralizedAlpha(1.0),
        output_interval=0.01,
        items={
            "upper link": upper,
            "lower link": lower,
            "tip node": tip,
            "shoulder": shoulder,
            "elbow": elbow,
        },
        reference={"energy change / max kinetic energy": 0.0},
        check=check,
    )


def flexible_robot_arm(elements: int = 4, mode_count: int = 0) -> Example:
    """A spatial arm of three elastic aluminium links (0.6, 0.5 and 0.4 m, circular section of
    radius 5 mm, `elements` beam elements each, frames clamped at their first nodes). The base
    joint turns the first link about the vertical y axis with the prescribed rest-to-rest
    profile 0.8 (3 (t/T)^2 - 2 (t/T)^3) rad, T = 1 s (an angle driver); the shoulder and
    the elbow (revolute joints about z at the deformed tips) swing freely under gravity
    (9.81 m/s^2 along -y). No damping: the work of the base drive equals the change of the
    total energy. `mode_count` > 0: that many clamped modes per link instead of the nodal
    coordinates. A model for the joint-coordinate formulation with deformable bodies (seed
    section 5)."""
    system = System(gravity=(0, -9.81, 0))
    lengths = (0.6, 0.5, 0.4)
    links, x = [], 0.0
    for k, length in enumerate(lengths):
        links.append(
            system.add_flexible_body(
                _beam_link(length, elements, mode_count), position=(x, 0, 0), name=f"link {k + 1}"
            )
        )
        x += length
    tip = elements + 1
    vertical = rotation("x", -np.pi / 2)  # marker z along the global y axis
    base = (
        system.add_marker(system.ground, orientation=vertical),
        system.add_node_marker(links[0], 1, orientation=vertical),
    )
    joints = [system.add_revolute_joint(*base, name="base")]
    for k, name in ((1, "shoulder"), (2, "elbow")):
        joints.append(
            system.add_revolute_joint(
                system.add_node_marker(links[k - 1], tip),
                system.add_node_marker(links[k], 1),
                name=name,
            )
        )
    angle = 0.8
    drive = system.add_angle_driver(
        *base, _boundary.Polynomial([0.0, 0.0, 3 * angle, -2 * angle]), name="drive"
    )

    def check(result: Any) -> dict[str, float]:
        t = result.time
        rate = 6 * angle * (t - t**2)
        power = result.reaction_torque(drive)[:, 2] * rate
        return {
            "energy balance error / max kinetic energy": _energy_balance(result, power),
            "largest constraint violation": float(np.max(result.constraint_violation)),
        }

    return Example(
        name="flexible-robot-arm",
        description="three elastic links, the base turned by a drive, shoulder and elbow free",
        system=system,
        end_time=1.0,
        step_size=1e-3,
        solver=_boundary.GeneralizedAlpha(1.0),
        output_interval=0.005,
        items={"links": links, "tip node": tip, "joints": joints, "drive": drive},
        reference={"energy balance error / max kinetic energy": 0.0},
        check=check,
    )


#: The space crane's joint angles at the end of its manoeuvre (rad): turret, shoulder, elbow.
SPACE_CRANE_MOVE = {"turret": 0.6, "shoulder": 0.5, "elbow": -1.0}


def space_crane(
    mode_count: int = 4,
    duration: float = 30.0,
    elements: int = 8,
    rigid: bool = False,
    shape: str = "quintic",
) -> Example:
    """The space crane of the seed's Figure 2 (section 3, control): in orbit (no gravity), a
    turret on the station turns about the station's y axis, and two booms of 15 m (aluminium
    tubes, outer radius 0.3 m, wall 10 mm: 753 kg each; `elements` Euler-Bernoulli beam
    elements, `mode_count` clamped modes each; 0: no elastic coordinates, the booms' rigid
    limit) hinged at the shoulder and the elbow about z carry a 2,000 kg payload (a cube of
    1 m) welded to the second boom's tip. The three joint angles follow rest-to-rest `shape`
    steps (:class:`flexmbd.Step`) over `duration` s to :data:`SPACE_CRANE_MOVE` (the arm
    leaves the x-y plane through the turret), then hold; the run ends `duration` / 2 later,
    when the payload swings on the held joints. Drivers "turret drive", "shoulder drive",
    "elbow drive" give the joint torques (inverse dynamics, :func:`flexmbd.inverse_dynamics`).

    `rigid=True` replaces each boom by a rigid body of the same mass, centre of mass and
    inertia (from the boom's invariants), the model whose torques the booms' rigid limit
    (`mode_count=0`) must give."""
    from .fe import Material, Section, build_body, straight_beam

    length, payload_mass, side = 15.0, 2000.0, 1.0
    nodes, conn = straight_beam(length, elements)
    boom = build_body(
        nodes,
        conn,
        Material(7.0e10, 0.33, 2700.0),
        section=Section.tube(0.3, 0.29),
        reference="clamped",
        reference_nodes=[0],
        modes="fixed-interface",
        mode_count=mode_count,
    )
    system = System()
    turret = system.add_rigid_body(50.0, (5.0, 5.0, 5.0), name="turret")
    bodies, roots, tips = [], [], []
    for k in range(2):
        position = (k * length, 0.0, 0.0)
        name = ("upper boom", "lower boom")[k]
        if rigid:
            inertia, com = _rigid_equivalent(boom)
            body = system.add_rigid_body(
                boom.invariants.mass, inertia, center_of_mass=com, position=position, name=name
            )
            roots.append(system.add_marker(body))
            tips.append(system.add_marker(body, position=(length, 0.0, 0.0)))
        else:
            body = system.add_flexible_body(boom, position=position, name=name)
            roots.append(system.add_node_marker(body, 1))
            tips.append(system.add_node_marker(body, elements + 1))
        bodies.append(body)
    payload = system.add_rigid_body(
        payload_mass,
        (payload_mass * side**2 / 6,) * 3,
        position=(2 * length + side / 2, 0.0, 0.0),
        name="payload",
    )
    station = system.add_marker(system.ground, orientation=rotation("x", -np.pi / 2))
    on_turret = system.add_marker(turret, orientation=rotation("x", -np.pi / 2))
    joints = {}
    axes = [(station, on_turret), (system.add_marker(turret), roots[0]), (tips[0], roots[1])]
    for name, (first, second) in zip(SPACE_CRANE_MOVE, axes, strict=True):
        joints[name] = system.add_revolute_joint(first, second, name=name)
        profile = _boundary.Step(0.0, duration, 0.0, SPACE_CRANE_MOVE[name], shape=shape)
        system.add_angle_driver(first, second, profile, name=f"{name} drive")
    holder = system.add_marker(payload, position=(-side / 2, 0.0, 0.0))
    system.add_fixed_joint(tips[1], holder, name="payload clamp")
    tip = system.add_sensor(system.add_marker(payload), "position", name="payload position")
    return Example(
        name="space-crane",
        description="a two-boom space crane moving a payload rest to rest (inverse dynamics)",
        system=system,
        end_time=1.5 * duration,
        step_size=duration / 2400,
        solver=_boundary.GeneralizedAlpha(1.0, step_control="fixed", velocity_projection="always"),
        output_interval=duration / 2400,
        items={"booms": bodies, "payload": payload, "joints": joints, "tip": tip},
    )


#: Satellite of :func:`satellite`: bus mass (kg) and side (m); panels' length and width (m),
#: thickness (m) and aluminium (E Pa, nu, rho kg/m^3).
SATELLITE = {
    "bus_mass": 500.0,
    "bus_side": 1.0,
    "panel_length": 2.0,
    "panel_width": 1.0,
    "panel_thickness": 5e-3,
    "material": (7.0e10, 0.33, 2700.0),
}


#: Duration (s) of the torque switches of :func:`satellite`.
SATELLITE_SWITCH = 0.1


def _satellite_inertia() -> float:
    """The satellite's moment of inertia about the slew axis x through the bus centre, rigid:
    the bus cube plus two panels from y = side / 2 to side / 2 + length (thin plates)."""
    s = SATELLITE
    half, length, width = s["bus_side"] / 2, s["panel_length"], s["panel_width"]
    panel = s["material"][2] * length * width * s["panel_thickness"]
    along = panel * ((half + length) ** 3 - half**3) / (3 * length)
    return s["bus_mass"] * s["bus_side"] ** 2 / 6 + 2 * along


def satellite_slew_torque(angle: float, duration: float) -> float:
    """The bang-bang torque (N m) that turns the rigid satellite by `angle` (rad) rest to rest
    in `duration` s: +T for half the time, -T for the other half, T = 4 angle I / duration^2."""
    return 4.0 * angle * _satellite_inertia() / duration**2


def satellite(
    angle: float = np.radians(30.0),
    duration: float = 20.0,
    coast: float = 10.0,
    mode_count: int = 6,
    divisions: tuple[int, int] = (4, 8),
    element: str = "quad4",
    modal_damping: float = 0.0,
) -> Example:
    """A rigid bus with two flexible solar panels slewed about x by a torque profile, in orbit
    (no gravity). The bus (:data:`SATELLITE`: a 500 kg cube of 1 m) carries on its faces
    y = +-0.5 m two aluminium panels of 2 x 1 m and 5 mm (27 kg each, first bending frequency
    about 1 Hz), meshed with `divisions` (across, along) `element` shells ("quad4" or "tri3")
    and reduced to `mode_count` modes clamped at their root edge, welded to the bus (fixed
    joints at the middle of each root edge). The torques "slew" and "slew stop" about the bus
    x axis make the bang-bang profile :func:`satellite_slew_torque` that would turn the rigid
    satellite by `angle` rest to rest in `duration` s; the run coasts `coast` s more, when the
    panels' residual vibration shows (undamped unless `modal_damping`, a ratio of every
    mode). Items: "bus", "panels" (body ids, +y first), "tips" (the node id at the middle of
    each panel's free edge), "torque" (N m), "panel data" (the panels' FlexibleBodyData)."""
    from .fe import Material, build_body, shapes

    s = SATELLITE
    length, width, half = s["panel_length"], s["panel_width"], s["bus_side"] / 2
    mesh = shapes.plate((width, length), divisions, element, origin=(-width / 2, 0.0, 0.0))
    panel = build_body(
        mesh.nodes,
        mesh.elements,
        Material(*s["material"]),
        shell=s["panel_thickness"],
        node_sets=mesh.node_sets,
        node_ids=mesh.node_ids,
        reference="clamped",
        reference_nodes="y0",
        modes="fixed-interface",
        mode_count=mode_count,
    )
    middle = np.abs(mesh.nodes[:, 0]) < 1e-9 * width
    root = int(mesh.node_ids[np.flatnonzero(middle & (np.abs(mesh.nodes[:, 1]) < 1e-9))[0]])
    free_edge = np.abs(mesh.nodes[:, 1] - length) < 1e-9
    tip = int(mesh.node_ids[np.flatnonzero(middle & free_edge)[0]])
    system = System()
    side = s["bus_side"]
    bus = system.add_rigid_body(s["bus_mass"], (s["bus_mass"] * side**2 / 6,) * 3, name="bus")
    panels = []
    for sign, name in ((1.0, "panel +y"), (-1.0, "panel -y")):
        turn = rotation("z", 0.0 if sign > 0 else np.pi)
        body = system.add_flexible_body(
            panel,
            position=(0.0, sign * half, 0.0),
            orientation=turn,
            modal_damping=modal_damping or None,
            name=name,
        )
        system.add_fixed_joint(
            system.add_marker(bus, position=(0.0, sign * half, 0.0), orientation=turn),
            system.add_node_marker(body, root),
            name=f"{name} root",
        )
        panels.append(body)
    torque = satellite_slew_torque(angle, duration)
    # Bang-bang as two torques: +T reversed to -T at duration / 2, and +T added at the end;
    # each switch a cubic step of SATELLITE_SWITCH s centred on its time (the impulses and the
    # rigid rest-to-rest motion are those of sharp switches).
    centre = system.add_marker(bus)
    switch = SATELLITE_SWITCH / 2
    middle, end = duration / 2, duration
    reverse = _boundary.Step(middle - switch, middle + switch, torque, -torque, shape="cubic")
    stop = _boundary.Step(end - switch, end + switch, 0.0, torque, shape="cubic")
    system.add_torque(centre, (reverse, 0.0, 0.0), frame="marker", name="slew")
    system.add_torque(centre, (stop, 0.0, 0.0), frame="marker", name="slew stop")
    return Example(
        name="satellite",
        description="a satellite with two flexible shell solar panels slewed by a torque",
        system=system,
        end_time=duration + coast,
        step_size=0.01,
        solver=_boundary.GeneralizedAlpha(0.9, step_control="fixed"),
        output_interval=0.05,
        items={
            "bus": bus,
            "panels": panels,
            "tips": [tip, tip],
            "torque": torque,
            "panel data": panel,
        },
        reference={"inertia": _satellite_inertia(), "angle": angle, "duration": duration},
    )


def satellite_quasi_static_tip(example: Example) -> float:
    """The tip deflection (m, along the panel normal) of a panel of :func:`satellite` held at
    its root under the d'Alembert load of the rigid satellite's angular acceleration
    4 angle / duration^2 in the first half of the slew: a static solution of the same shell
    mesh, which the dynamic tip deflection oscillates about while the torque is constant."""
    from .fe.preprocess import static_displacements

    body = example.items["panel data"]
    alpha = 4 * example.reference["angle"] / example.reference["duration"] ** 2
    # Acceleration of the rigid motion about global x through the bus centre, in the +y
    # panel's body axes (parallel to the global ones): alpha e_x x (X + (0, side / 2, 0)).
    offset = np.array([0.0, SATELLITE["bus_side"] / 2, 0.0])
    acceleration = np.zeros(body.dof_count)
    d = body.dofs_per_node
    for i, x in enumerate(np.asarray(body.nodes)):
        acceleration[d * i : d * i + 3] = np.cross([alpha, 0.0, 0.0], x + offset)
        acceleration[d * i + 3] = alpha
    u = static_displacements(body, -(body.mass @ acceleration))
    index = int(np.flatnonzero(np.asarray(body.node_ids) == example.items["tips"][0])[0])
    return float(u[d * index + 2])


def _rigid_equivalent(data: Any) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The inertia about the centre of mass (body axes) and the centre of mass of a
    deformable body's undeformed mass distribution, from its invariants."""
    inv = data.invariants
    mass = inv.mass
    com = np.asarray(inv.first_moment) / mass
    second = np.asarray(inv.second_moment)
    about_origin = np.trace(second) * np.eye(3) - second
    about_com = about_origin - mass * (com @ com * np.eye(3) - np.outer(com, com))
    return about_com, com


EXAMPLES: dict[str, Callable[[], Example]] = {
    "andrews": lambda: andrews(),
    "bricard": lambda: bricard(),
    "flexible-double-pendulum": flexible_double_pendulum,
    "flexible-robot-arm": flexible_robot_arm,
    "flexible-slider-crank": flexible_slider_crank,
    "four-bar": four_bar,
    "four-bar-spatial": lambda: four_bar_spatial(),
    "pendulum": pendulum,
    "satellite": lambda: satellite(),
    "space-crane": lambda: space_crane(),
    "spin-up": spin_up,
    "tetrahedral-pendulum": tetrahedral_pendulum,
}
"""Builders of the built-in examples, by name."""


def andrews() -> Example:
    """IFToMM A03, Andrews' squeezing mechanism (reference R5), with the data, coordinates and
    consistent initial angles of the IVP test set "andrews" (Hairer and Wanner, Solving ODEs II,
    section VII.7): seven bodies moving in the x-y plane, 1 degree of freedom, started at rest,
    driven by a torque of 0.033 N m on body 1 and a spring (4530 N/m, rest length 0.07785 m)
    between the fixed point C and the point D of body 3; no gravity.

    The test set's angles are beta (body 1 about O), Theta (body 2 relative to body 1), gamma
    (body 3 about B), Phi (body 4 relative to body 5), delta (body 5 about A), Omega (body 6
    relative to body 7) and epsilon (body 7 about A); its loop equations place the points
    F = rr e(beta), E = F - d e(beta + Theta) = B + ss (sin gamma, -cos gamma)
    = A + zt e(delta) + e (sin(Phi + delta), -cos(Phi + delta))
    = A + u (sin epsilon, -cos epsilon) + zf e(Omega + epsilon), with e(a) = (cos a, sin a).
    Each body frame sits on a pivot and turns by the body's absolute angle, so that its
    rotation about z is that angle. The mass matrix of the test set fixes only the distance of
    each centre of mass from the body's pivot; for bodies 3, 5 and 7 (about fixed pivots) the
    direction is free and taken as (sa, sb), (ta, tb) and (ua, ub) in the body frame. The
    inertias about the x and y axes equal those about z (the motion stays planar).

    In 3D, seven revolute joints (z axes) form a tree from the ground (O, F, the three joints
    at E, G, H) and in-line joints close the loops at the ground pivots B, A, A (in-plane
    position only), so that the spatial model has no redundant equations. ``check`` compares
    the seven angles at t = 0.03 s (beta and Theta unwrapped over the output, which must be fine
    enough: a step of body 1's angle between outputs below pi) with the test set's solution;
    ``items["angles"](result)`` returns them, (n, 7)."""
    # Test set data (m, kg, kg m^2).
    masses = (0.04325, 0.00365, 0.02373, 0.00706, 0.07050, 0.00706, 0.05498)
    inertias = (2.194e-6, 4.410e-7, 5.255e-6, 5.667e-7, 1.169e-5, 5.667e-7, 1.912e-5)
    xa, ya, xb, yb, xc, yc = -0.06934, -0.00227, -0.03635, 0.03273, 0.014, 0.072
    d, da, e, ea, rr, ra = 0.028, 0.0115, 0.02, 0.01421, 0.007, 0.00092
    ss, sa, sb, sc, sd = 0.035, 0.01874, 0.01043, 0.018, 0.02
    ta, tb, u, ua, ub = 0.02308, 0.00916, 0.04, 0.01228, 0.00449
    zf, zt, fa = 0.02, 0.04, 0.01421
    torque, stiffness, rest_length = 0.033, 4530.0, 0.07785
    initial = {
        "beta": -0.0617138900142764496358948458001,
        "Theta": 0.0,
        "gamma": 0.455279819163070380255912382449,
        "Phi": 0.222668390165885884674473185609,
        "delta": 0.487364979543842550225598953530,
        "Omega": -0.222668390165885884674473185609,
        "epsilon": 1.23054744454982119249735015568,
    }
    reference = {
        "beta": 15.81077119629904,
        "Theta": -15.75637105984298,
        "gamma": 0.04082224013073101,
        "Phi": -0.5347301163226948,
        "delta": 0.5244099658805304,
        "Omega": 0.5347301163226948,
        "epsilon": 1.048080741042263,
    }
    # Absolute angles of the seven bodies.
    beta, theta, gamma, phi, delta, omega, epsilon = initial.values()
    angles = (beta, beta + theta, gamma, phi + delta, delta, omega + epsilon, epsilon)

    def turned(k: int, local: tuple[float, float]) -> np.ndarray:
        """A vector fixed in body k (1-based), in global axes at the initial angles."""
        c, s = np.cos(angles[k - 1]), np.sin(angles[k - 1])
        return np.array([c * local[0] - s * local[1], s * local[0] + c * local[1], 0.0])

    point_a = np.array([xa, ya, 0.0])
    point_b = np.array([xb, yb, 0.0])
    point_f = turned(1, (rr, 0.0))
    point_g = point_a + turned(5, (zt, 0.0))
    point_h = point_a + turned(7, (0.0, -u))
    # Body frames: origin on the pivot, axes turned by the absolute angle.
    origins = (np.zeros(3), point_f, point_b, point_g, point_a, point_h, point_a)
    centres = ((ra, 0), (-da, 0), (sa, sb), (0, -(e - ea)), (ta, tb), (zf - fa, 0), (ua, ub))
    system = System()
    bodies = [
        system.add_rigid_body(
            masses[k - 1],
            (inertias[k - 1],) * 3,
            center_of_mass=(*centres[k - 1], 0.0),
            position=origins[k - 1],
            orientation=rotation("z", angles[k - 1]),
            name=f"body {k}",
        )
        for k in range(1, 8)
    ]

    def marker(k: int, local: tuple[float, float] = (0.0, 0.0)) -> _core.MarkerId:
        body = system.ground if k == 0 else bodies[k - 1]
        return system.add_marker(body, position=(*local, 0.0))

    ground = system.ground
    # Tree of revolute joints (z axes) from the ground.
    joints = {
        "O": system.add_revolute_joint(marker(0), marker(1), name="O"),
        "F": system.add_revolute_joint(marker(1, (rr, 0)), marker(2), name="F"),
        "E 2-3": system.add_revolute_joint(marker(2, (-d, 0)), marker(3, (0, -ss)), name="E 2-3"),
        "E 2-4": system.add_revolute_joint(marker(2, (-d, 0)), marker(4, (0, -e)), name="E 2-4"),
        "E 2-6": system.add_revolute_joint(marker(2, (-d, 0)), marker(6, (zf, 0)), name="E 2-6"),
        "G": system.add_revolute_joint(marker(4), marker(5, (zt, 0)), name="G"),
        "H": system.add_revolute_joint(marker(6), marker(7, (0, -u)), name="H"),
    }
    # Loop closures at the ground pivots: in-plane position only.
    for label, point, k in (("B", point_b, 3), ("A 5", point_a, 5), ("A 7", point_a, 7)):
        pivot = system.add_marker(ground, position=point)
        joints[label] = system.add_inline_joint(pivot, marker(k), name=label)
    drive = system.add_torque(marker(1), (0.0, 0.0, torque), name="driving torque")
    spring = system.add_spring_damper(
        system.add_marker(ground, position=(xc, yc, 0.0)),
        marker(3, (sd, -sc)),
        stiffness=stiffness,
        rest_length=rest_length,
        name="spring",
    )
    names = tuple(reference)

    def body_angles(result: Any) -> np.ndarray:
        """The test set's seven angles (rad) at every output, (n, 7): absolute body angles
        unwrapped through the output, then the relative ones as differences."""
        absolute = np.empty((len(result.time), 7))
        for k, body in enumerate(bodies):
            r = result.orientation(body)
            absolute[:, k] = np.unwrap(np.arctan2(r[:, 1, 0], r[:, 0, 0]))
        out = absolute.copy()
        out[:, 1] = absolute[:, 1] - absolute[:, 0]
        out[:, 3] = absolute[:, 3] - absolute[:, 4]
        out[:, 5] = absolute[:, 5] - absolute[:, 6]
        return out

    def check(result: Any) -> dict[str, float]:
        k = int(np.argmin(np.abs(result.time - 0.03)))
        if abs(result.time[k] - 0.03) > 1e-12:
            return {}
        values = dict(zip(names, body_angles(result)[k], strict=True))
        return {f"{n} error at t = 0.03 s": float(abs(v - reference[n])) for n, v in values.items()}

    return Example(
        name="andrews",
        description="IFToMM A03 Andrews' squeezing mechanism (7 rigid bodies, stiff spring, 3D)",
        system=system,
        end_time=0.03,
        step_size=2e-6,
        solver=_boundary.GeneralizedAlpha(0.9, newton_tolerance=1e-10),
        output_interval=1e-5,
        items={
            "bodies": bodies,
            "joints": joints,
            "driving torque": drive,
            "spring": spring,
            "initial angles": initial,
            "angles": body_angles,
        },
        reference=reference,
        check=check,
    )


def four_bar_spatial() -> Example:
    """A redundant model: the IFToMM A02 four-bar with N = 1 (two cranks and one coupler, uniform
    1 kg, 1 m links; gravity 9.81 m/s^2 along -y) closed by four spatial revolute joints with
    parallel z axes. The cranks stand vertically on pivots (0, 0) and (1, 0), the coupler lies
    horizontally at y = 1, and the top of the first crank, B0, starts at 1 m/s along +x (a
    velocity that satisfies the joints). In 3D each revolute joint has 5 equations: 20 for
    18 coordinates of motion and 1 degree of freedom, so 3 equations are redundant and the
    constraint Jacobian is rank deficient (the out-of-plane equations of a planar loop repeat
    each other). Needs a solver that handles redundant constraints.

    The motion has one degree of freedom: the cranks stay parallel at the angle theta from the
    vertical and the coupler translates, (5/3) theta'' = 2 g sin(theta), theta(0) = 0,
    theta'(0) = 1 rad/s. ``check`` compares B0 with that equation, solved by SciPy."""
    system = System(gravity=(0.0, -9.81, 0.0))
    inertia = FOUR_BAR_ROD
    cranks, tops, pivots = _four_bar_cranks(system, 2)
    coupler = system.add_rigid_body(
        1.0, inertia, position=(0.5, 1.0, 0.0), velocity=(1.0, 0.0, 0.0), name="coupler"
    )
    left = system.add_marker(coupler, position=(-0.5, 0.0, 0.0))
    right = system.add_marker(coupler, position=(0.5, 0.0, 0.0))
    couplings = [
        system.add_revolute_joint(tops[0], left, name="coupler left"),
        system.add_revolute_joint(tops[1], right, name="coupler right"),
    ]
    b0_position = system.add_sensor(tops[0], "position", name="B0 position")
    b0_velocity = system.add_sensor(tops[0], "velocity", name="B0 velocity")

    def check(result: Any) -> dict[str, float]:
        from scipy.integrate import solve_ivp

        # Lagrange's equation of the crank angle: (5/3) theta'' = 2 g sin(theta).
        solution = solve_ivp(
            lambda t, s: (s[1], 6.0 * 9.81 / 5.0 * np.sin(s[0])),
            (result.time[0], result.time[-1]),
            (0.0, 1.0),
            t_eval=result.time,
            rtol=1e-11,
            atol=1e-12,
        )
        theta = solution.y[0]
        exact = np.column_stack((np.sin(theta), np.cos(theta)))
        p = result.sensor(b0_position)[:, :2]
        return {"largest B0 position error (m)": float(np.max(np.abs(p - exact)))}

    return Example(
        name="four-bar-spatial",
        description="A02 four-bar, N = 1, with four spatial revolute joints (3 redundant)",
        system=system,
        end_time=10.0,
        step_size=2e-4,
        solver=_boundary.GeneralizedAlpha(0.9),
        output_interval=0.01,
        items={
            "cranks": cranks,
            "coupler": coupler,
            "pivots": pivots,
            "couplings": couplings,
            "B0 position": b0_position,
            "B0 velocity": b0_velocity,
            "redundant equations": 3,
        },
        check=check,
    )


def bricard(marker_twists: Any = None) -> Example:
    """A redundant model: Bricard's mechanism, IFToMM benchmark A04. Five uniform 1 kg, 1 m rods
    (square section 0.1 m) and the ground form a closed loop of six revolute joints along the
    edges of a unit cube, P0 = (0, 0, 0) -> (1, 0, 0) -> (1, -1, 0) -> (1, -1, 1) -> (0, -1, 1)
    -> P5 = (0, 0, 1), the ground closing P5 -> P0; each joint axis is perpendicular to both
    links it joins (y, z, x, y, z, x at P0 .. P5). Gravity 9.81 m/s^2 along -y; released at
    rest. Grubler's count gives 6 x 5 - 5 x 6 = 0 degrees of freedom, but the mechanism has
    one: one of the 30 joint equations is redundant and the constraint Jacobian is rank
    deficient everywhere on the motion. Needs a solver that handles redundant constraints.

    Source of the geometry and initial state: the IFToMM / MBS benchmark A04 (lim.ii.udc.es
    mbsbenchmark, Gonzalez et al. 2006) as implemented in the public models of
    MBSbenchmarksInOpenSim (A04), simEngine3D and Exudyn (bricardMechanism), which agree;
    the benchmark's own specification text was not available. ``check`` returns the drift of
    the total energy (conserved: no dissipation, spectral radius 1).

    ``marker_twists``: the same mechanism with other marker frames: each joint's two markers
    turned about the joint axis, by angles (rad) in an array of shape (6, 2) (joint k, marker of
    the lower / higher link), or one angle for all. Which equation is redundant, and which rows
    a solver keeps, depends on these frames; the motion does not."""
    given = 0.0 if marker_twists is None else marker_twists
    twists = np.broadcast_to(np.asarray(given, dtype=float), (6, 2))
    system = System(gravity=(0.0, -9.81, 0.0))
    corners = np.array(
        [[0, 0, 0], [1, 0, 0], [1, -1, 0], [1, -1, 1], [0, -1, 1], [0, 0, 1]], dtype=float
    )
    axes = np.array([[0, 1, 0], [0, 0, 1], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 0, 0]], float)
    section = 0.1
    inertia = (section**2 / 6.0, (1.0 + section**2) / 12.0, (1.0 + section**2) / 12.0)

    def frame(x_axis: np.ndarray, z_axis: np.ndarray) -> np.ndarray:
        """Rotation matrix with the given (orthogonal, unit) x and z axes as columns."""
        return np.column_stack((x_axis, np.cross(z_axis, x_axis), z_axis))

    links, frames = [], []
    for k in range(5):
        start, end = corners[k], corners[k + 1]
        along = end - start
        side = axes[k]  # perpendicular to the link: completes the body frame
        orientation = frame(along, side)
        links.append(
            system.add_rigid_body(
                1.0,
                inertia,
                position=(start + end) / 2,
                orientation=orientation,
                name=f"link {k + 1}",
            )
        )
        frames.append(orientation)

    def joint_marker(k: int, corner: int, twist: float = 0.0) -> _core.MarkerId:
        """Marker at `corner` on link k (1-based; 0 is the ground): z along the corner's joint
        axis, x along the link that leaves the corner (perpendicular to that axis) turned by
        `twist` about the joint axis."""
        leaving = corners[(corner + 1) % 6] - corners[corner]
        global_frame = rotation(axes[corner], twist) @ frame(leaving, axes[corner])
        if k == 0:
            return system.add_marker(
                system.ground, position=corners[corner], orientation=global_frame
            )
        centre = (corners[k - 1] + corners[k]) / 2
        to_local = frames[k - 1].T
        return system.add_marker(
            links[k - 1],
            position=to_local @ (corners[corner] - centre),
            orientation=to_local @ global_frame,
        )

    def joint(lower: int, higher: int, corner: int) -> _core.JointId:
        """The revolute joint at `corner` between links `lower` and `higher` (0: ground)."""
        return system.add_revolute_joint(
            joint_marker(lower, corner, twists[corner, 0]),
            joint_marker(higher, corner, twists[corner, 1]),
            name=f"joint {corner}",
        )

    joints = [joint(0, 1, 0)] + [joint(k, k + 1, k) for k in range(1, 5)] + [joint(5, 0, 5)]
    # The point the benchmark implementations record (between links 2 and 3).
    tracked = system.add_sensor(joint_marker(2, 2), "position", name="P3 position")

    def check(result: Any) -> dict[str, float]:
        energy = result.total_energy
        return {"largest energy drift (J)": float(np.max(np.abs(energy - energy[0])))}

    return Example(
        name="bricard",
        description="IFToMM A04 Bricard's mechanism (5 rods, 6 revolute joints, 1 redundant)",
        system=system,
        end_time=10.0,
        step_size=1e-3,
        solver=_boundary.GeneralizedAlpha(1.0),
        output_interval=0.01,
        items={"links": links, "joints": joints, "P3 position": tracked, "redundant equations": 1},
        check=check,
    )
