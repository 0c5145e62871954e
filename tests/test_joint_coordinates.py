"""Joint coordinates (seed section 5): trees of rigid and deformable bodies and point masses
with revolute, prismatic, cylindrical, fixed, universal, spherical and free joints and drivers
on them, loops closed by cut joints, integrated in joint plus elastic coordinates, against the
augmented formulation."""

import numpy as np
import pytest

import flexmbd as fm


def rotation_x(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def robot(driven=False):
    """A spatial arm: shoulder about z, elbow about a tilted axis, a prismatic wrist, and a
    second branch (a carriage on an inclined rail carrying a pendulum with a sleeve on a
    cylindrical joint and a weight welded to it), with gravity. ``driven``: the shoulder angle
    is prescribed (an angle driver on the shoulder's markers)."""
    s = fm.System(gravity=(0.2, -9.81, 0.4))
    inertia = np.array([[0.05, 0.004, -0.002], [0.004, 0.08, 0.003], [-0.002, 0.003, 0.09]])

    def body(name, x):
        return s.add_rigid_body(
            1.3, inertia, center_of_mass=(0.1, 0.02, -0.03), position=(x, 0, 0), name=name
        )

    arm, forearm, wrist = body("arm", 0.5), body("forearm", 1.5), body("wrist", 2.2)
    carriage, pendulum = body("carriage", 0.0), body("pendulum", 0.4)
    along_x = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])  # marker z = body x
    sleeve, weight = body("sleeve", 0.6), body("weight", 0.9)
    shoulder = (s.add_marker(s.ground), s.add_marker(arm, position=(-0.5, 0, 0)))
    joints = [
        s.add_revolute_joint(*shoulder, name="shoulder"),
        s.add_revolute_joint(
            s.add_marker(arm, position=(0.5, 0, 0), orientation=rotation_x(0.4)),
            s.add_marker(forearm, position=(-0.5, 0, 0), orientation=rotation_x(0.4)),
            name="elbow",
        ),
        s.add_prismatic_joint(
            s.add_marker(forearm, position=(0.5, 0, 0), orientation=along_x),
            s.add_marker(wrist, position=(-0.2, 0, 0), orientation=along_x),
            name="wrist",
        ),
        s.add_prismatic_joint(
            s.add_marker(s.ground, orientation=rotation_x(-0.3)),
            s.add_marker(carriage, orientation=rotation_x(-0.3)),
            name="rail",
        ),
        s.add_revolute_joint(
            s.add_marker(pendulum, position=(-0.4, 0.1, 0), orientation=rotation_x(0.2)),
            s.add_marker(carriage, position=(0, 0.1, 0), orientation=rotation_x(0.2)),
            name="swing",
        ),
        s.add_cylindrical_joint(
            s.add_marker(sleeve, orientation=along_x),
            s.add_marker(pendulum, position=(0.2, 0, 0), orientation=along_x),
            name="sleeve",
        ),
        s.add_fixed_joint(
            s.add_marker(sleeve, position=(0.15, 0, 0), orientation=rotation_x(0.7)),
            s.add_marker(weight, position=(-0.15, 0, 0), orientation=rotation_x(0.7)),
            name="weld",
        ),
    ]
    if driven:
        joints.append(s.add_angle_driver(*shoulder, fm.Polynomial([0.0, 0.8, -1.5]), name="drive"))
    return s, [arm, forearm, wrist, carriage, pendulum, sleeve, weight], joints


def solver(strategy):
    return fm.ExplicitSolver("dopri5", strategy, relative_tolerance=1e-11, absolute_tolerance=1e-13)


@pytest.fixture(scope="module", params=[False, True], ids=["free", "driven"])
def runs(request):
    system, bodies, joints = robot(request.param)
    model = system.compile()
    tree = fm.simulate(model, 2.0, 1e-3, output_interval=0.01, solver=solver("joint-coordinates"))
    augmented = fm.simulate(model, 2.0, 1e-3, output_interval=0.01, solver=solver("projection"))
    return tree, augmented, bodies, joints


def test_trajectories_and_reactions_equal_the_augmented_formulation(runs, assert_close):
    tree, augmented, bodies, joints = runs
    for body in bodies:
        assert_close(tree.position(body), augmented.position(body), abs=1e-9, what="position")
        assert_close(tree.velocity(body), augmented.velocity(body), abs=1e-8, what="velocity")
    # The joint reactions, eliminated from the joint-coordinate equations, recovered after.
    for joint in joints:
        for a, b in zip(tree.reaction(joint), augmented.reaction(joint), strict=True):
            assert_close(a, b, abs=1e-7 * max(1.0, np.abs(b).max()), what="reaction")


def test_joints_hold_exactly_and_energy_is_conserved(runs, assert_close):
    tree, _, _, joints = runs
    assert tree.constraint_violation.max() < 1e-12
    if len(joints) == 7:  # not driven: no work done on the system
        energy = tree.total_energy
        scale = np.abs(tree.kinetic_energy).max()
        assert_close(energy, energy[0], abs=1e-9 * scale, what="total energy")


def slider_crank():
    """The rigid slider-crank of ``examples/slider_crank.py``: the crank driven at 20 rad/s
    (angle driver on the main bearing's markers), the loop closed by the wrist pin (in-line),
    which the joint-coordinate formulation cuts."""
    crank_length, rod_length = 0.15, 0.30
    s = fm.System(gravity=(0, -9.81, 0))
    crank = s.add_rigid_body(
        0.4,
        (1e-5, 0.4 * crank_length**2 / 12, 0.4 * crank_length**2 / 12),
        position=(crank_length / 2, 0, 0),
    )
    rod = s.add_rigid_body(
        0.8,
        (1e-5, 0.8 * rod_length**2 / 12, 0.8 * rod_length**2 / 12),
        position=(crank_length + rod_length / 2, 0, 0),
    )
    slider = s.add_rigid_body(0.5, (1e-3, 1e-3, 1e-3), position=(crank_length + rod_length, 0, 0))
    pivot, root = s.add_marker(s.ground), s.add_marker(crank, position=(-crank_length / 2, 0, 0))
    s.add_revolute_joint(pivot, root, name="main bearing")
    drive = s.add_angle_driver(pivot, root, fm.Polynomial([0.0, 20.0]), name="drive")
    s.add_revolute_joint(
        s.add_marker(crank, position=(crank_length / 2, 0, 0)),
        s.add_marker(rod, position=(-rod_length / 2, 0, 0)),
        name="crank pin",
    )
    along_x = fm.rotation("y", np.pi / 2)
    s.add_prismatic_joint(
        s.add_marker(s.ground, orientation=along_x),
        s.add_marker(slider, orientation=along_x),
        name="guide",
    )
    wrist = s.add_inline_joint(
        s.add_marker(slider), s.add_marker(rod, position=(rod_length / 2, 0, 0)), name="wrist pin"
    )
    return s, [crank, rod, slider], drive, wrist


def test_closed_loop_by_a_cut_joint_equals_the_augmented_formulation(assert_close):
    system, bodies, drive, wrist = slider_crank()
    model = system.compile()
    runs = [
        fm.simulate(model, 0.5, 1e-4, output_interval=1e-3, solver=solver(strategy))
        for strategy in ("joint-coordinates", "projection")
    ]
    tree, augmented = runs
    for body in bodies:
        assert_close(tree.position(body), augmented.position(body), abs=1e-9, what="position")
    torque = [run.reaction_torque(drive)[:, 2] for run in runs]
    assert_close(torque[0], torque[1], abs=1e-7 * np.abs(torque[1]).max(), what="drive torque")
    force = [run.reaction_force(wrist) for run in runs]
    assert_close(force[0], force[1], abs=1e-7 * np.abs(force[1]).max(), what="wrist force")
    # The cut joint is held by projection of the joint coordinates after each step.
    assert tree.constraint_violation.max() < 1e-11


def test_spherical_joints_point_masses_and_free_bodies_equal_the_augmented_formulation(
    assert_close,
):
    # A spherical pendulum of a rigid body carrying a point mass on a second spherical joint,
    # the IFToMM A01 pendulum (a point mass on a distance constraint: a free point mass and a
    # cut joint) and a tumbling free body.
    s = fm.System(gravity=(0.3, -9.81, 0.2))
    ball = s.add_rigid_body(
        1.2,
        (0.05, 0.08, 0.09),
        position=(0.3, -0.4, 0),
        angular_velocity=(0.5, -1.0, 2.0),
        name="ball",
    )
    bob = s.add_point_mass(0.5, position=(0.6, -0.9, 0.1), velocity=(0, 0, 1.0), name="bob")
    s.add_spherical_joint(
        s.add_marker(s.ground), s.add_marker(ball, position=(-0.3, 0.4, 0)), name="shoulder"
    )
    s.add_spherical_joint(
        s.add_marker(ball, position=(0.3, -0.5, 0.1)), s.add_marker(bob), name="wrist"
    )
    tumbler = s.add_rigid_body(
        2.0, (0.1, 0.2, 0.3), position=(3, 0, 0), angular_velocity=(0.3, 4.0, 0.2), name="tumbler"
    )
    a01 = fm.examples.pendulum()
    for system, bodies, end in (
        (a01.system, [a01.items["mass"]], 1.0),
        (s, [ball, bob, tumbler], 3.0),
    ):
        model = system.compile()
        tree, augmented = (
            fm.simulate(model, end, 1e-3, output_interval=0.01, solver=solver(strategy))
            for strategy in ("joint-coordinates", "projection")
        )
        for body in bodies:
            assert_close(tree.position(body), augmented.position(body), abs=1e-8, what="position")
            assert_close(tree.velocity(body), augmented.velocity(body), abs=1e-7, what="velocity")
        assert tree.constraint_violation.max() < 1e-11
    # The tumbler turns about y at 4 rad/s: its middle Cardan angle would reach its
    # singularity at 90 degrees after 0.4 s; the angles are rebased before (events).
    rebased = [e for e in tree.events if e["kind"] == "joint coordinates rebased"]
    assert len(rebased) >= 3 and any("tumbler" in e["message"] for e in rebased)


def flexible_solver(strategy):
    return fm.ExplicitSolver("dopri5", strategy, relative_tolerance=1e-9, absolute_tolerance=1e-11)


@pytest.mark.parametrize(
    "build, end, reaction_tolerance",
    [
        (lambda: fm.examples.flexible_double_pendulum(mode_count=4), 0.3, 1e-6),
        (lambda: fm.examples.flexible_robot_arm(mode_count=4), 0.1, 1e-6),
        # Nodal beam: its axial modes (about 3e4 rad/s) turn position differences of 1e-11 m
        # between the two runs into reaction differences of 1e-5 of the largest.
        (lambda: fm.examples.spin_up(elements=4), 0.3, 2e-4),
        (lambda: fm.examples.tetrahedral_pendulum(), 0.05, 1e-6),
    ],
    ids=["double-pendulum", "robot-arm", "spin-up", "tetrahedral-pendulum"],
)
def test_deformable_trees_equal_the_augmented_formulation(
    build, end, reaction_tolerance, assert_close
):
    # Joint plus elastic coordinates; the hinges sit at markers that move with the links'
    # deformation (beam node markers; a node-set marker on the solid).
    example = build()
    model = example.system.compile()
    tree, augmented = (
        fm.simulate(model, end, 1e-3, output_interval=end / 20, solver=flexible_solver(strategy))
        for strategy in ("joint-coordinates", "projection")
    )
    q_tree, q_aug = np.asarray(tree.coordinates), np.asarray(augmented.coordinates)
    assert_close(q_tree, q_aug, abs=1e-8 * max(1.0, np.abs(q_aug).max()), what="coordinates")
    assert tree.constraint_violation.max() < 1e-11
    a, b = tree._reactions, augmented._reactions
    assert_close(a, b, abs=reaction_tolerance * max(1.0, np.abs(b).max()), what="reactions")


def test_flexible_slider_crank_closed_by_cut_joints_equals_the_augmented_formulation(
    assert_close,
):
    # R4: the crank pin at the rod's deformed first node; the slider (a point mass) on the
    # spherical wrist pin at the rod's deformed last node; the guide (in-line) cut.
    example = fm.examples.flexible_slider_crank(elements=4)
    model = example.system.compile()
    tree, augmented = (
        fm.simulate(model, 1e-3, 1e-4, output_interval=1e-4, solver=flexible_solver(strategy))
        for strategy in ("joint-coordinates", "projection")
    )
    assert_close(tree.coordinates, augmented.coordinates, abs=1e-10, what="coordinates")
    torque = [run.reaction_torque(example.items["drive"])[:, 2] for run in (tree, augmented)]
    assert_close(torque[0], torque[1], abs=1e-6 * np.abs(torque[1]).max(), what="drive torque")
    assert tree.constraint_violation.max() < 1e-11


def four_bar_in_joint_coordinates(method, step_size, tolerance=None):
    """IFToMM A02 (N = 2) over its 10 s in joint coordinates (the in-line joints cut): B0's
    position and velocity errors at t = 10 s against the reference."""
    example = fm.examples.four_bar(2)
    options = {}
    if tolerance is not None:
        options = {"relative_tolerance": tolerance, "absolute_tolerance": 1e-2 * tolerance}
    solver = fm.ExplicitSolver(method, "joint-coordinates", **options)
    # Records every 0.04 s (RK4 steps divide it) or 1 s (Dormand-Prince's steps are free).
    interval = 0.04 if method == "rk4" else 1.0
    result = fm.simulate(example.system, 10.0, step_size, output_interval=interval, solver=solver)
    errors = example.check(result)
    return max(errors.values())


def test_rk4_converges_through_the_singular_configurations_of_the_four_bar(assert_close):
    # A02 lies flat 20 times in 10 s: two singular values of C_cut B pass through zero. The
    # exact inverse of the vanishing ones (and a projection that stopped at the constraint
    # tolerance, leaving p off the branch by residual / s) gave errors that grew as h fell:
    # 1.8e-6, 2.2e-6, 5.9e-7, 5.6e-5 at h = 8, 4, 2, 1 ms. Now they fall at fourth order to
    # the round-off floor (about 4e-9; 1.7e-7 at 8 ms).
    errors = {h: four_bar_in_joint_coordinates("rk4", h) for h in (8e-3, 4e-3, 1e-3)}
    for h, error in errors.items():
        assert_close(error, 0.0, abs=1e-5, what=f"B0 error at h = {h}")
    assert_close(errors[4e-3], 0.0, abs=errors[8e-3] / 8, what="B0 error at h = 4 ms")


def test_dopri5_converges_through_the_singular_configurations_of_the_four_bar(assert_close):
    # Dormand-Prince at relative tolerance 1e-9 ended 7.4e-2 off (537 rejected steps); now
    # its error falls with the tolerance (3.0e-7, 2.9e-8 at 1e-9, 1e-10).
    coarse = four_bar_in_joint_coordinates("dopri5", 1e-3, tolerance=1e-9)
    fine = four_bar_in_joint_coordinates("dopri5", 1e-3, tolerance=1e-10)
    assert_close(coarse, 0.0, abs=1e-5, what="B0 error at rtol 1e-9")
    assert_close(fine, 0.0, abs=coarse / 4, what="B0 error at rtol 1e-10")


def test_named_cut_joints_choose_the_tree_and_a_loop_left_uncut_is_an_error(assert_close):
    system, bodies, drive, wrist = slider_crank()
    model = system.compile()
    crank_pin = fm.JointId(2)  # main bearing, drive, crank pin, guide, wrist pin
    # Cutting the crank pin as well leaves the rod on a free joint, held by two cut joints.
    tree = fm.simulate(
        model,
        0.2,
        1e-4,
        output_interval=1e-3,
        solver=fm.ExplicitSolver(
            "dopri5",
            "joint-coordinates",
            relative_tolerance=1e-11,
            absolute_tolerance=1e-13,
            cut_joints=[crank_pin, wrist],
        ),
    )
    augmented = fm.simulate(model, 0.2, 1e-4, output_interval=1e-3, solver=solver("projection"))
    for body in bodies:
        assert_close(tree.position(body), augmented.position(body), abs=1e-8, what="position")
    with pytest.raises(
        fm.InvalidModelError, match="'wrist pin' \\(inline\\).*not among the cut joints"
    ):
        fm.simulate(
            model, 0.01, 1e-4, solver=fm.ExplicitSolver("rk4", "joint-coordinates", cut_joints=[])
        )
    with pytest.raises(fm.InvalidParameterError, match="cut_joints"):
        fm.simulate(
            model, 0.01, 1e-4, solver=fm.ExplicitSolver("rk4", "projection", cut_joints=[wrist])
        )


def test_a_tree_that_would_move_a_body_is_refused():
    # A weld whose markers are turned half a turn about x (z_j = -z_i, which the weld's
    # equations allow): the tree, which aligns the markers' z axes, would turn the plate over.
    s = fm.System()
    plate = s.add_rigid_body(1.0, (1, 1, 1), name="plate")
    s.add_fixed_joint(
        s.add_marker(s.ground), s.add_marker(plate, orientation=rotation_x(np.pi)), name="weld"
    )
    with pytest.raises(fm.InvalidModelError, match="'weld' \\(fixed\\).*'plate'") as error:
        fm.simulate(s, 0.1, 1e-3, solver=solver("joint-coordinates"))
    # The message says how far, and what to do (it gave "for example opposite z axes" also
    # for a weld turned about z, whose z axes agree).
    assert "turns it by 180.0 degrees about (1.000, 0.000, 0.000)" in str(error.value)
    assert "cut the joint (cut_joints)" in str(error.value)


@pytest.mark.parametrize(
    "build, end",
    [
        (lambda: fm.examples.flexible_double_pendulum(elements=3), 2e-3),
        (lambda: fm.examples.flexible_slider_crank(elements=4), 5e-4),
    ],
    ids=["double-pendulum", "slider-crank"],
)
def test_coupled_and_decoupled_systems_equal_the_joint_space_one(build, end, assert_close):
    # Seed eq. 40 (sparse) and eq. 41 (the elastic accelerations eliminated with the constant
    # M_ff) against (B^T M B) p_dd = B^T (f - M gamma_B): nodal beams, and R4's cut guide.
    model = build().system.compile()
    runs = {
        formulation: fm.simulate(
            model,
            end,
            1e-5,
            output_interval=end / 5,
            solver=fm.ExplicitSolver(
                "dopri5",
                "joint-coordinates",
                formulation=formulation,
                relative_tolerance=1e-9,
                absolute_tolerance=1e-11,
            ),
        )
        for formulation in ("joint-space", "coupled", "decoupled")
    }
    reference = runs["joint-space"]
    for formulation in ("coupled", "decoupled"):
        run = runs[formulation]
        assert_close(run.coordinates, reference.coordinates, abs=1e-12, what="coordinates")
        scale = np.abs(reference.accelerations).max()
        assert_close(
            run.accelerations, reference.accelerations, abs=1e-7 * scale, what="accelerations"
        )
        scale = max(1.0, np.abs(reference._reactions).max())
        assert_close(run._reactions, reference._reactions, abs=1e-8 * scale, what="reactions")


def test_the_decoupled_system_keeps_its_size_as_the_elastic_coordinates_grow():
    sizes = {}
    for elements in (2, 6):
        model = fm.examples.flexible_robot_arm(elements=elements).system.compile()
        for formulation in ("coupled", "decoupled"):
            solver = fm.ExplicitSolver("rk4", "joint-coordinates", formulation=formulation)
            result = fm.simulate(model, 2e-9, 1e-9, solver=solver)
            sizes[formulation, elements] = result.statistics["reduced_system_size"]
    # Three links: 2 free joint coordinates, 3 x 7 reference rows twice.
    assert sizes["decoupled", 2] == sizes["decoupled", 6] == 2 * 21 + 2
    # Eq. 40 carries the elastic accelerations: 6 per node, 4 more nodes in each of 3 links.
    assert sizes["coupled", 6] - sizes["coupled", 2] == 3 * 4 * 6
    with pytest.raises(fm.InvalidParameterError, match="'decoupled'.*joint-coordinates"):
        fm.simulate(
            model,
            1e-9,
            1e-9,
            solver=fm.ExplicitSolver("rk4", "projection", formulation="decoupled"),
        )


def test_dependent_cut_equations_in_eq_40_are_refused_with_the_formulations_that_take_them():
    # The spatial four-bar closed by a revolute cut joint has dependent cut equations: eq. 40
    # (its sparse LU holds the cut multipliers) failed with "SymbolicSingular { index: 41 }";
    # eq. 41 and the joint-space system take them.
    example = fm.examples.four_bar_spatial()

    def run(formulation):
        solver = fm.ExplicitSolver("rk4", "joint-coordinates", formulation=formulation)
        return fm.simulate(example.system, 0.01, 1e-3, solver=solver)

    # (Now refused before the run from the rank of the cut equations, which the start
    # computes: the LU's own refusal, "no pivot in column ..." with the same advice, stays for
    # a loop that passes a singular configuration later.)
    with pytest.raises(fm.InvalidModelError, match=r"have rank 2 at t = 0: dependent.*'decoupled'"):
        run("coupled")
    run("decoupled")


@pytest.mark.parametrize("tilt", [np.pi / 2, np.pi / 2 - 1e-3], ids=["singular", "near"])
def test_a_start_at_the_cardan_singularity_keeps_the_whole_angular_velocity(tilt, assert_close):
    # A free body turned 90 degrees about y: its Cardan angles' middle one is at the
    # singularity, where the rates cannot hold every angular velocity. The rates were solved
    # before the angles were rebased, by a minimum-norm solve that dropped omega_z (0.7 ->
    # 3e-17: kinetic energy 1.7535 instead of 1.778, orientation 0.73 off in 2 s).
    system = fm.System(gravity=(0.0, 0.0, 0.0))
    system.add_rigid_body(
        2.0, (0.1, 0.2, 0.3), position=(1, 2, 3), orientation=fm.rotation("y", tilt),
        velocity=(0.1, 0.2, 0.3), angular_velocity=(0.3, 4.0, 0.7), name="tumbler",
    )  # fmt: skip
    model = system.compile()
    tree = fm.simulate(model, 1.0, 1e-3, output_interval=0.05, solver=solver("joint-coordinates"))
    augmented = fm.simulate(model, 1.0, 1e-3, output_interval=0.05, solver=solver("projection"))
    assert_close(tree.angular_velocity("tumbler")[0], [0.3, 4.0, 0.7], abs=1e-12, what="omega(0)")
    energy = augmented.kinetic_energy[0]  # (1.778 at the singular tilt)
    assert_close(tree.kinetic_energy[0], energy, rel=1e-12, what="kinetic energy at the start")
    assert_close(
        tree.orientation("tumbler"), augmented.orientation("tumbler"), abs=1e-8, what="orientation"
    )


def test_initial_velocities_off_the_tree_joints_are_refused_not_changed():
    # correct_initial_velocities=False leaves velocities that break the elbow as given: the
    # augmented strategies integrate them, joint coordinates have no rates for them (they
    # started from the least-squares rates, body b2 at 2.375 m/s instead of 3, unsaid).
    system = fm.System(gravity=(0.0, -9.81, 0.0))
    inertia = (1e-3, 0.1, 0.1)
    b1 = system.add_rigid_body(
        1.0, inertia, position=(0.5, 0, 0), angular_velocity=(0, 0, 1.0), name="b1"
    )
    b2 = system.add_rigid_body(
        1.0, inertia, position=(1.5, 0, 0), velocity=(0, 3.0, 0.5), name="b2"
    )
    system.add_revolute_joint(
        system.add_marker(system.ground), system.add_marker(b1, position=(-0.5, 0, 0))
    )
    system.add_revolute_joint(
        system.add_marker(b1, position=(0.5, 0, 0)), system.add_marker(b2, position=(-0.5, 0, 0))
    )
    model = system.compile()
    left = fm.ExplicitSolver("rk4", "joint-coordinates", correct_initial_velocities=False)
    with pytest.raises(fm.InitialConditionsError, match="violate the tree joints") as error:
        fm.simulate(model, 0.01, 1e-3, initial_conditions="correct", solver=left)
    assert "would move by 8.750e-1" in str(error.value)
    # Corrected (the default), they are the joints' own and the run starts from them.
    corrected = fm.ExplicitSolver("rk4", "joint-coordinates")
    result = fm.simulate(model, 0.01, 1e-3, initial_conditions="correct", solver=corrected)
    assert result.success


def test_eq_40_refuses_dependent_cut_equations_with_a_deformable_body_in_the_loop():
    # A four-bar whose deformable coupler is closed to the rocker by a revolute joint (two of
    # its five cut equations dependent): with a rigid coupler eq. 40's LU is singular (the
    # test above); with a deformable one it was nearly so and solved to a wrong motion (the
    # coupler's elastic coordinate -2.5e-8 instead of 6.4e-6 at t = 0.1 s).
    from flexmbd.fe import Material, Section, build_body, straight_beam

    system = fm.System(gravity=(0.0, -9.81, 0.0))
    nodes, elements = straight_beam(0.6, 4)
    data = build_body(
        nodes, elements, Material(7e10, 0.33, 2700.0), section=Section.rectangle(0.02, 0.005),
        reference="clamped", reference_nodes=[0], modes="fixed-interface", mode_count=3,
    )  # fmt: skip
    crank = system.add_rigid_body(
        0.5, (1e-5, 1.7e-3, 1.7e-3), position=(0, 0.1, 0), orientation=fm.rotation("z", np.pi / 2),
        angular_velocity=(0, 0, 3.0),
    )  # fmt: skip
    # The coupler from (0, 0.2) along the x axis to (0.6, 0.2); the rocker from (0.6, 0) up.
    coupler = system.add_flexible_body(data, position=(0, 0.2, 0), name="coupler")
    rocker = system.add_rigid_body(
        0.8, (1e-5, 2.7e-3, 2.7e-3), position=(0.6, 0.1, 0), orientation=fm.rotation("z", np.pi / 2)
    )
    system.add_revolute_joint(
        system.add_marker(system.ground), system.add_marker(crank, position=(-0.1, 0, 0))
    )
    system.add_revolute_joint(
        system.add_marker(crank, position=(0.1, 0, 0)), system.add_node_marker(coupler, 1)
    )
    system.add_revolute_joint(
        system.add_marker(system.ground, position=(0.6, 0, 0)),
        system.add_marker(rocker, position=(-0.1, 0, 0)),
    )
    system.add_revolute_joint(
        system.add_node_marker(coupler, 5),
        system.add_marker(rocker, position=(0.1, 0, 0)),
        name="C",
    )
    model = system.compile()

    def run(formulation):
        solver = fm.ExplicitSolver("rk4", "joint-coordinates", formulation=formulation)
        return fm.simulate(model, 0.002, 1e-4, solver=solver)

    with pytest.raises(
        fm.InvalidModelError, match=r"cut joints 'C': their 5 equations have rank 4"
    ):
        run("coupled")
    assert run("decoupled").success


def test_a_driver_listed_among_the_cut_joints_is_cut_and_a_joint_listed_twice_is_refused(
    assert_close,
):
    # A driver on a tree joint's markers prescribes its coordinate; listed among the cut
    # joints it was still prescribed (the list did nothing). Cut, its equation is a rheonomic
    # cut constraint: the same motion and effort, with the cut system's multipliers.
    system = fm.System(gravity=(0.0, -9.81, 0.0))
    link = system.add_rigid_body(
        1.0,
        (1e-3, 0.1, 0.1),
        position=(0.5, 0, 0),
        velocity=(0, 0.5, 0),
        angular_velocity=(0, 0, 1),
    )
    ground, end = system.add_marker(system.ground), system.add_marker(link, position=(-0.5, 0, 0))
    hinge = system.add_revolute_joint(ground, end, name="hinge")
    drive = system.add_angle_driver(ground, end, fm.Polynomial([0.0, 1.0]), name="drive")
    model = system.compile()

    def run(cut):
        solver = fm.ExplicitSolver("rk4", "joint-coordinates", cut_joints=cut)
        return fm.simulate(model, 0.5, 1e-3, output_interval=0.1, solver=solver)

    prescribed, cut = run(None), run([drive])
    assert (
        prescribed.statistics["reduced_system_size"],
        cut.statistics["reduced_system_size"],
    ) == (
        0,
        2,
    )
    # Effort of theta = t: m g (l / 2) cos(t) + J theta'' = 4.9050 cos(0.5) at the end.
    assert_close(prescribed.driver_effort("drive")[-1], 9.81 * 0.5 * np.cos(0.5), rel=1e-9)
    assert_close(cut.driver_effort("drive"), prescribed.driver_effort("drive"), rel=1e-9)
    with pytest.raises(fm.InvalidParameterError, match="cut joint 'hinge': listed twice"):
        run([hinge, hinge])


def test_a_driver_that_contradicts_a_tree_joint_is_named_as_such():
    # An angle driver on a universal joint's markers turns about z_i, which the joint's cross
    # equation locks. The augmented strategies name the conflict; joint coordinates diverged
    # in the projection onto the cut driver ("step size 0.000e0"), now refused at the start:
    # the corrected velocities (the cross equation left out as redundant) break the tree joint.
    system = fm.System(gravity=(0.0, -9.81, 0.5))
    body = system.add_rigid_body(1.0, (0.02, 0.1, 0.1), position=(0.5, 0, 0))
    ground, end = system.add_marker(system.ground), system.add_marker(body, position=(-0.5, 0, 0))
    system.add_universal_joint(ground, end, name="u")
    system.add_angle_driver(ground, end, fm.Polynomial([0.0, 0.6]), name="d")
    model = system.compile()
    with pytest.raises(fm.ConflictingConstraintsError, match="joint 'u' .* equation 'cross'"):
        fm.simulate(model, 0.01, 1e-3, solver=fm.ExplicitSolver("rk4", "projection"))
    with pytest.raises(fm.InitialConditionsError, match="a constraint contradicts a tree joint"):
        fm.simulate(model, 0.01, 1e-3, solver=fm.ExplicitSolver("rk4", "joint-coordinates"))
