"""The explicit solvers of seed section 4: Runge-Kutta 4 and Dormand-Prince 5(4) with the three
strategies (integrate all accelerations, coordinate partitioning, projection), the augmented
and the embedding formulation, and the LU, QR and SVD partitions, against IFToMM A01 and A02
(reference R5) and against each other."""

import numpy as np
import pytest
from conftest import clamped_steel_beam

import flexmbd as fm

STRATEGIES = ["integrate-all", "partitioning", "projection"]
FORMULATIONS = ["augmented", "embedding"]


def explicit(method="dopri5", strategy="partitioning", tolerance=1e-10, **options):
    if method != "rk4":  # (rk4 takes fixed steps: tolerances are refused)
        options.update(relative_tolerance=tolerance, absolute_tolerance=1e-2 * tolerance)
    return fm.ExplicitSolver(method, strategy, **options)


@pytest.fixture(scope="module")
def a01():
    return fm.examples.pendulum()


@pytest.fixture(scope="module")
def a02():
    return fm.examples.four_bar(2)


@pytest.mark.parametrize("method", ["rk4", "dopri5"])
@pytest.mark.parametrize("formulation", FORMULATIONS)
@pytest.mark.parametrize("strategy", STRATEGIES)
def test_every_strategy_reproduces_the_pendulum(a01, strategy, formulation, method):
    # A01 over its 10 s against the exact solution (elliptic functions), to the foundation's
    # 1e-6. RK4 at a fixed 1 ms step; Dormand-Prince from 1 ms with error control.
    solver = explicit(method, strategy, formulation=formulation)
    result = fm.simulate(
        a01.system, a01.end_time, 1e-3, output_interval=a01.output_interval, solver=solver
    )
    errors = a01.check(result)
    assert len(errors) == 4
    for name, error in errors.items():
        assert error < 1e-6, name
    if strategy != "integrate-all":
        assert result.constraint_violation.max() < 1e-10
    assert result.statistics["function_evaluations"] >= 4 * result.statistics["steps"]


def test_pendulum_repartitions_as_it_swings_through_the_bottom(a01):
    # Released horizontally, the dependent coordinate is y's partner x at first (C_q = [2x,
    # 2y, 2z]); near the bottom x loses its pivot and the partition must change.
    result = fm.simulate(a01.system, 2.0, 1e-3, output_interval=0.01, solver=explicit())
    repartitions = [e for e in result.events if e["kind"] == "repartition"]
    assert repartitions, result.events
    assert "condition" in repartitions[0]["message"]
    assert max(a01.check(result).values()) < 1e-6


@pytest.mark.parametrize(
    ("strategy", "formulation", "method", "baumgarte"),
    [
        ("partitioning", "augmented", "dopri5", None),
        ("partitioning", "embedding", "rk4", None),
        ("projection", "augmented", "rk4", None),
        ("projection", "embedding", "rk4", None),
        ("integrate-all", "augmented", "dopri5", (20.0, 20.0)),
    ],
)
def test_strategies_reproduce_the_four_bar_through_its_singular_configurations(
    a02, strategy, formulation, method, baumgarte
):
    # A02, N = 2, over 10 s: the mechanism passes 20 singular (flat) configurations, where the
    # constraint Jacobian loses rank and every partition degenerates. Error at t = 10 s against
    # the one-degree-of-freedom solution, to the foundation's 1e-4.
    solver = explicit(method, strategy, formulation=formulation, baumgarte=baumgarte)
    result = fm.simulate(a02.system, 10.0, 1e-3, output_interval=0.01, solver=solver)
    errors = a02.check(result)
    assert errors["B0 position error at t = 10 s"] < 1e-4
    assert errors["B0 velocity error at t = 10 s"] < 1e-4
    if baumgarte is None:
        assert result.constraint_violation.max() < 1e-10
    else:
        assert result.constraint_violation.max() < 1e-5


def test_drift_of_integrate_all_grows_and_is_reported_while_the_others_hold_it(a02):
    # Strategy (1) without stabilization integrates q_ddot of the index-1 equations: the
    # position constraints drift (quadratically in time once the velocity drift sets in);
    # strategies (2) and (3) hold them to the Newton tolerance.
    end = 2.0
    result = fm.simulate(
        a02.system, end, 1e-3, output_interval=0.01, solver=explicit("rk4", "integrate-all")
    )
    violation = result.constraint_violation
    quarter = len(violation) // 4
    assert violation[:quarter].max() < violation[-quarter:].max() / 10
    assert violation.max() > 1e-6
    drift = [e for e in result.events if e["kind"] == "constraint drift"]
    assert drift and "baumgarte" in drift[0]["message"].lower()
    for strategy in ["partitioning", "projection"]:
        held = fm.simulate(
            a02.system, end, 1e-3, output_interval=0.01, solver=explicit("rk4", strategy)
        )
        assert held.constraint_violation.max() < 1e-10, strategy
        assert not [e for e in held.events if e["kind"] == "constraint drift"]


def test_baumgarte_stabilization_bounds_the_drift(a02):
    free = fm.simulate(
        a02.system, 2.0, 1e-3, output_interval=0.01, solver=explicit("rk4", "integrate-all")
    )
    stabilized = fm.simulate(
        a02.system,
        2.0,
        1e-3,
        output_interval=0.01,
        solver=explicit("rk4", "integrate-all", baumgarte=(20.0, 20.0)),
    )
    assert stabilized.constraint_violation.max() < free.constraint_violation.max() / 100


@pytest.mark.parametrize("partition", ["lu", "qr", "svd"])
def test_partition_methods_agree(a02, partition, assert_close):
    # Wehage's LU with full pivoting, QR with column pivoting and the SVD choose their
    # dependent coordinates differently; the motion is the same. 1.5 s crosses the first
    # singular configurations.
    solver = explicit(partition=partition)
    result = fm.simulate(a02.system, 1.5, 1e-3, output_interval=0.01, solver=solver)
    reference = fm.simulate(
        a02.system,
        1.5,
        1e-4,
        output_interval=0.01,
        solver=fm.GeneralizedAlpha(1.0, newton_tolerance=1e-10),
    )
    assert_close(result.coordinates, reference.coordinates, abs=1e-6, what="coordinates")
    assert result.constraint_violation.max() < 1e-10


def test_embedding_and_augmented_multipliers_agree(a02, assert_close):
    # The embedding formulation recovers the multipliers afterwards from C_qd^T lambda =
    # (Q - M q_ddot)_d (seed eq. 30); the augmented one solves for them with the
    # accelerations (eq. 26).
    runs = [
        fm.simulate(
            a02.system, 0.5, 1e-3, output_interval=0.05, solver=explicit(formulation=formulation)
        )
        for formulation in FORMULATIONS
    ]
    scale = np.abs(runs[0].multipliers).max()
    assert_close(runs[0].multipliers, runs[1].multipliers, abs=1e-6 * scale, what="multipliers")
    assert_close(runs[0].accelerations, runs[1].accelerations, abs=1e-6, what="accelerations")


def test_given_independent_coordinates_are_used_and_checked(a01):
    # The pendulum's point mass: q = (x, y, z), C = x^2 + y^2 + z^2 - L^2, released at
    # (L, 0, 0). y and z independent leave x dependent: a regular 1 x 1 block, until x passes
    # zero at the bottom; the given partition is kept, and the steps near the bottom are
    # taken by projection (a "singular configuration" event each way).
    result = fm.simulate(
        a01.system, 1.0, 1e-3, output_interval=0.01, solver=explicit(independent=[1, 2])
    )
    assert max(a01.check(result).values()) < 1e-6
    assert {e["kind"] for e in result.events} == {"singular configuration"}
    assert "the given independent coordinates" in result.events[0]["message"]
    assert "resumes" in result.events[-1]["message"]
    assert result.constraint_violation.max() < 1e-10
    # x and z independent leave y dependent, whose column of C_q is zero at the start.
    with pytest.raises(fm.InvalidParameterError, match="independent coordinates") as info:
        fm.simulate(a01.system, 0.3, 1e-3, solver=explicit(independent=[0, 2]))
    assert "singular" in str(info.value)
    assert "coordinate x" in str(info.value) and "coordinate z" in str(info.value)
    with pytest.raises(fm.InvalidParameterError, match="leave 2 degrees of freedom"):
        fm.simulate(a01.system, 0.3, 1e-3, solver=explicit(independent=[1]))
    with pytest.raises(fm.InvalidParameterError, match="out of range"):
        fm.simulate(a01.system, 0.3, 1e-3, solver=explicit(independent=[1, 7]))


def test_invalid_solver_choices_are_refused(a01):
    with pytest.raises(fm.InvalidParameterError, match="Baumgarte"):
        fm.simulate(
            a01.system, 0.1, 1e-3, solver=explicit(strategy="projection", baumgarte=(5.0, 5.0))
        )
    for bad in [
        {"method": "euler"},
        {"strategy": "stabilized"},
        {"formulation": "penalty"},
        {"partition": "cholesky"},
    ]:
        with pytest.raises(fm.InvalidParameterError):
            explicit(**bad)
    with pytest.raises(fm.InvalidParameterError, match="repartition_ratio must be .* > 1"):
        explicit(repartition_ratio=0.5)


def test_models_too_large_for_the_dense_explicit_solvers_are_refused():
    # A deformable body of more than 2000 coordinates: the explicit solvers are dense.
    example = fm.examples.spin_up(elements=400)
    with pytest.raises(fm.InvalidParameterError, match="up to 2000 coordinates") as info:
        fm.simulate(example.system, 0.1, 1e-3, solver=explicit())
    assert "generalized-alpha" in str(info.value)


def test_failed_explicit_run_keeps_the_results_so_far(a02):
    # A step-size floor that Dormand-Prince cannot keep through the four-bar's first change
    # point (near t = 0.714 s) at this tolerance.
    solver = explicit(tolerance=1e-12, min_step_size=5e-3)
    with pytest.raises(fm.StepSizeTooSmallError) as info:
        fm.simulate(a02.system, 1.0, 1e-2, output_interval=0.01, solver=solver)
    result = info.value.result
    assert 0.65 < result.time[-1] < 0.72
    assert result.constraint_violation.max() < 1e-10


# The stability limit of explicit methods on deformable bodies -------------------------------
def hinged_steel_beam(beta):
    """A 1 m steel beam of 10 nodal Euler-Bernoulli elements hinged at its first node, with
    stiffness-proportional damping beta (s) or none."""
    data = clamped_steel_beam(1.0, 10, fm.fe.Section.rectangle(0.02, 0.01))
    system = fm.System(gravity=(0.0, -9.81, 0.0))
    damping = None if beta is None else (0.0, beta)
    rod = system.add_flexible_body(data, name="rod", rayleigh_damping=damping)
    system.add_revolute_joint(system.add_marker(system.ground), system.add_node_marker(rod, 1))
    return system.compile()


@pytest.mark.parametrize("beta", [None, 1e-4], ids=["undamped", "damped"])
@pytest.mark.parametrize("strategy", ["joint-coordinates", "partitioning", "projection"])
def test_the_predicted_stability_limit_of_runge_kutta_4_is_where_it_diverges(beta, strategy):
    # The stiffest mode: undamped, omega = 1.78e5 rad/s on the imaginary axis (RK4's
    # boundary 2.83); damped by beta = 1e-4 s, overdamped with lambda = -3.14e6 1/s on the
    # real axis (boundary 2.79). 300 steps at 0.95 of the predicted step stay bounded, at 1.05
    # they diverge.
    from flexmbd.stability import explicit_step_limit

    model = hinged_steel_beam(beta)
    limit = explicit_step_limit(model, "rk4")
    assert limit.body == "rod"
    expected = 2.828 / 1.775e5 if beta is None else 2.785 / 3.1416e6
    assert limit.step == pytest.approx(expected, rel=2e-3)
    solver = fm.ExplicitSolver("rk4", strategy)
    failures = (fm.NonFiniteError, fm.NewtonDivergedError, fm.SingularMatrixError)
    with pytest.warns(fm.StepSizeWarning, match="diverges"):
        with pytest.raises(failures) as diverged:
            h = 1.05 * limit.step
            fm.simulate(model, 300 * h, h, output_interval=None, solver=solver)
    # The error says why (the projection's singular matrix was put down to a mass matrix
    # that is not positive definite).
    if not isinstance(diverged.value, fm.NewtonDivergedError):
        assert "the run diverged" in str(diverged.value)
        assert f"limit of about {limit.step:.2g} s" in str(diverged.value)
    h = 0.95 * limit.step
    result = fm.simulate(model, 300 * h, h, output_interval=None, solver=solver)
    assert np.abs(result.elastic_coordinates("rod")).max() < 1e-3
    # Far above the limit the error says when (it said "at t = NaN" in joint coordinates).
    with pytest.warns(fm.StepSizeWarning), pytest.raises(fm.SimulationError) as error:
        fm.simulate(model, 3e-3, 1e-3, solver=solver)
    assert "NaN" not in str(error.value) and error.value.time > 0


def test_dormand_prince_on_a_stiff_body_is_told_its_step_before_the_run(recwarn):
    # The damped beam's dopri5 steps (seen in runs: h = 1.05e-6 s) are predicted before the
    # run; generalized-alpha, and TR-BDF2, are not warned.
    model = hinged_steel_beam(1e-4)
    solver = fm.ExplicitSolver("dopri5", "partitioning")
    with pytest.warns(fm.StepSizeWarning, match=r"body 'rod'.* about 1.1e-06 s.*: 1,90\d steps"):
        result = fm.simulate(model, 2e-3, 1e-3, solver=solver)
    # Its error control finds the limit: the steps it took (accepted and rejected).
    steps = result.statistics["steps"] + result.statistics["rejected_steps"]
    assert 1800 < steps < 2100
    recwarn.clear()
    fm.simulate(model, 1e-2, 1e-3)
    fm.simulate(model, 1e-2, 1e-3, solver=fm.ExplicitSolver("tr-bdf2", "partitioning"))
    assert not [w for w in recwarn if issubclass(w.category, fm.StepSizeWarning)]


@pytest.mark.parametrize("strategy", ["integrate-all", "projection"])
def test_an_open_chain_reports_no_singular_configuration(strategy, assert_close):
    # A triple pendulum has none; integrating all coordinates, the partition chosen at the
    # start (which only pivots the acceleration solve) grew ill-conditioned as the links
    # swung, and each step there was reported as near a singular configuration.
    system = fm.System(gravity=(0.0, -9.81, 0.0))
    parent, x = system.ground, 0.0
    for k in range(3):
        link = system.add_rigid_body(1.0, (1e-3, 0.1, 0.1), position=(x + 0.5, 0, 0))
        system.add_revolute_joint(
            system.add_marker(parent, position=(0.5 if k else 0.0, 0, 0)),
            system.add_marker(link, position=(-0.5, 0, 0)),
        )
        parent, x = link, x + 1.0
    solver = fm.ExplicitSolver("rk4", strategy)
    result = fm.simulate(system, 2.0, 1e-3, output_interval=0.01, solver=solver)
    assert [e for e in result.events if e["kind"] == "singular configuration"] == []
    reference = fm.simulate(system, 2.0, 1e-3, output_interval=0.01, solver=explicit("rk4"))
    assert_close(result.coordinates, reference.coordinates, abs=1e-6, what="coordinates")


@pytest.mark.parametrize("shape", ["quintic", "cycloidal", "cubic"])
def test_a_driver_starting_from_rest_is_followed_by_fixed_partitioned_steps(shape, assert_close):
    # RK4 with partitioning stopped at its first step ("the dependent coordinates moved to
    # another solution of C = 0"): a motion starting from rest (zero velocity, and for the
    # quintic and cycloidal zero acceleration) is not in the predictor, and its O(h^3) motion
    # was compared with a predicted motion of zero. The cubic profile's acceleration at its
    # start is now that of the motion (it was 0, the rest before).
    system = fm.System()
    arm = system.add_rigid_body(1.0, (1e-4, 1 / 12, 1 / 12), position=(0.5, 0, 0), name="arm")
    ground, root = system.add_marker(system.ground), system.add_marker(arm, position=(-0.5, 0, 0))
    system.add_revolute_joint(ground, root, name="hinge")
    drive = fm.Step(0.0, 0.5, 0.0, 1.0, shape=shape)
    system.add_angle_driver(ground, root, drive, name="drive")
    solver = fm.ExplicitSolver("rk4", "partitioning")
    result = fm.simulate(system, 0.6, 1e-3, solver=solver, output_interval=0.1)
    turned = result.orientation("arm")
    angle = np.arctan2(turned[:, 1, 0], turned[:, 0, 0])
    exact = [drive.derivatives(t)[0] for t in result.time]
    assert_close(angle, exact, abs=1e-9, what="angle")
    if shape == "cubic":  # f = 3 s^2 - 2 s^3 over 0.5 s: f''(0+) = 6 / 0.25
        assert_close(drive.derivatives(0.0), [0.0, 0.0, 24.0], abs=1e-12, what="start")
