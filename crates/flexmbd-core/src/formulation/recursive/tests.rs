//! Tests of the joint-coordinate formulation against the augmented one.

use super::*;
use crate::formulation::augmented::{Formulation, Level};
use crate::integrator::initial::dense_initial_conditions;
use crate::integrator::settings::InitialSettings;
use crate::integrator::test_models::{ground_joint, unit_body};
use crate::linalg::partition::{partition, PartitionMethod, DEFAULT_RANK_TOLERANCE};
use crate::math::time_function::TimeFunction;
use crate::system::{State, Workspace};
use crate::testing::{a02_four_bar, assert_all_close, assert_close};
use crate::SystemBuilder;

fn rot_x(angle: f64) -> Mat3 {
    let (s, c) = angle.sin_cos();
    Mat3([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
}

/// Ground -revolute (z)- arm -revolute (tilted axis)- forearm -prismatic- slider, and a
/// second branch: ground -prismatic- carriage -revolute- pendulum (marker i on the child
/// side). Gravity, offset centres of mass and full inertia tensors.
fn tree_model(driven: bool) -> Model {
    let mut sys = SystemBuilder::new();
    sys.set_gravity(Vec3([0.3, -9.81, 0.5])).unwrap();
    let inertia = Mat3([[0.05, 0.004, -0.002], [0.004, 0.08, 0.003], [-0.002, 0.003, 0.09]]);
    let g = sys.ground();
    let body = |sys: &mut SystemBuilder, name: &str, x: f64, rotation: Mat3| {
        sys.add_rigid_body(
            name,
            1.3,
            inertia,
            Vec3([0.1, 0.02, -0.03]),
            Vec3([x, 0.0, 0.0]),
            rotation,
            Vec3::ZERO,
            Vec3::ZERO,
        )
        .unwrap()
    };
    let arm = body(&mut sys, "arm", 0.5, Mat3::IDENTITY);
    let forearm = body(&mut sys, "forearm", 1.5, Mat3::IDENTITY);
    let slider = body(&mut sys, "slider", 2.2, Mat3::IDENTITY);
    let carriage = body(&mut sys, "carriage", 0.0, Mat3::IDENTITY);
    let pendulum = body(&mut sys, "pendulum", 0.4, Mat3::IDENTITY);
    let m = |sys: &mut SystemBuilder, b, s: Vec3, r: Mat3| sys.add_marker("", b, s, r).unwrap();
    let (g0, a0) = (
        m(&mut sys, g, Vec3::ZERO, Mat3::IDENTITY),
        m(&mut sys, arm, Vec3([-0.5, 0.0, 0.0]), Mat3::IDENTITY),
    );
    sys.add_joint("shoulder", JointKind::Revolute, [g0, a0]).unwrap();
    let (a1, f0) = (
        m(&mut sys, arm, Vec3([0.5, 0.0, 0.0]), rot_x(0.4)),
        m(&mut sys, forearm, Vec3([-0.5, 0.0, 0.0]), rot_x(0.4)),
    );
    sys.add_joint("elbow", JointKind::Revolute, [a1, f0]).unwrap();
    let (f1, s0) = (
        m(
            &mut sys,
            forearm,
            Vec3([0.5, 0.0, 0.0]),
            Mat3([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]),
        ),
        m(
            &mut sys,
            slider,
            Vec3([-0.2, 0.0, 0.0]),
            Mat3([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]),
        ),
    );
    sys.add_joint("slide", JointKind::Prismatic, [f1, s0]).unwrap();
    let (g1, c0) = (m(&mut sys, g, Vec3::ZERO, rot_x(-0.3)), m(&mut sys, carriage, Vec3::ZERO, rot_x(-0.3)));
    sys.add_joint("rail", JointKind::Prismatic, [g1, c0]).unwrap();
    // Marker i on the pendulum (the child side).
    let (p0, c1) = (
        m(&mut sys, pendulum, Vec3([-0.4, 0.1, 0.0]), rot_x(0.2)),
        m(&mut sys, carriage, Vec3([0.0, 0.1, 0.0]), rot_x(0.2)),
    );
    sys.add_joint("swing", JointKind::Revolute, [p0, c1]).unwrap();
    // A sleeve on the pendulum (cylindrical, marker i on the child side) and a weight
    // welded to the sleeve (fixed).
    let sleeve = body(&mut sys, "sleeve", 0.6, Mat3::IDENTITY);
    let weight = body(&mut sys, "weight", 0.9, Mat3::IDENTITY);
    let (s0, q1) =
        (m(&mut sys, sleeve, Vec3::ZERO, along_x()), m(&mut sys, pendulum, Vec3([0.2, 0.0, 0.0]), along_x()));
    sys.add_joint("sleeve", JointKind::Cylindrical, [s0, q1]).unwrap();
    let (s1, w0) = (
        m(&mut sys, sleeve, Vec3([0.15, 0.0, 0.0]), rot_x(0.7)),
        m(&mut sys, weight, Vec3([-0.15, 0.0, 0.0]), rot_x(0.7)),
    );
    sys.add_joint("weld", JointKind::Fixed, [s1, w0]).unwrap();
    // Two Cardan-jointed shafts on the forearm, marker i on each side in turn.
    let shaft = body(&mut sys, "shaft", 1.5, Mat3::IDENTITY);
    let tip = body(&mut sys, "tip", 1.5, Mat3::IDENTITY);
    let (f2, h0) = (
        m(&mut sys, forearm, Vec3([0.0, 0.3, 0.0]), rot_x(-1.2)),
        m(&mut sys, shaft, Vec3([0.0, 0.3, 0.0]), rot_x(-1.2)),
    );
    sys.add_joint("cardan", JointKind::Universal, [f2, h0]).unwrap();
    let (t0, h1) = (
        m(&mut sys, tip, Vec3([0.0, 0.2, 0.1]), rot_x(0.3)),
        m(&mut sys, shaft, Vec3([0.0, 0.2, 0.1]), rot_x(0.3)),
    );
    sys.add_joint("cardan 2", JointKind::Universal, [t0, h1]).unwrap();
    if driven {
        // The shoulder angle prescribed (markers in the revolute's order), the rail
        // translation prescribed with the markers reversed.
        sys.add_joint(
            "shoulder drive",
            JointKind::AngleDriver(TimeFunction::Polynomial(vec![0.0, 0.8, -1.5])),
            [g0, a0],
        )
        .unwrap();
        sys.add_joint(
            "rail drive",
            JointKind::TranslationDriver(TimeFunction::Polynomial(vec![0.0, -0.3, 0.9])),
            [c0, g1],
        )
        .unwrap();
    }
    sys.compile().unwrap()
}

fn along_x() -> Mat3 {
    // Marker z along body x.
    Mat3([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
}

/// Three deformable links and two rigid bodies: ground -revolute- link 1 (child marker
/// deformed) -revolute- link 2 (both markers deformed) -revolute- tip (marker i on the
/// rigid child, j on the deformed parent) and link 3 (both deformed, marker i on the
/// child); a slider on an undeformed marker of link 2 (prismatic). Gravity.
fn flexible_tree_model(driven: bool) -> Model {
    flexible_tree_model_with(driven, false, 4)
}

/// `flexible_tree_model` (with two rigid bodies welded at deformed markers), with
/// `closed`: a distance joint from link 3's deformed tip to
/// the tip body closing a loop (cut); `elastic`: elastic coordinates per link (>= 4).
fn flexible_tree_model_with(driven: bool, closed: bool, elastic_count: usize) -> Model {
    use crate::body::flexible::tests::{Lcg, PointBody};
    use crate::body::flexible::FlexibleBody;
    use crate::math::dense::Jacobian3;
    let mut sys = SystemBuilder::new();
    sys.set_gravity(Vec3([0.2, -9.81, 0.4])).unwrap();
    let g = sys.ground();
    let link = |sys: &mut SystemBuilder, name: &str, seed: u64, x: Vec3| {
        let body =
            FlexibleBody::new(name, PointBody::random(6, elastic_count, seed).input(50.0, 0.1)).unwrap();
        sys.add_flexible_body(name, body, x, Mat3::IDENTITY, Vec3::ZERO, Vec3::ZERO, vec![], vec![]).unwrap()
    };
    let l1 = link(&mut sys, "link 1", 3, Vec3([0.5, 0.0, 0.0]));
    let l2 = link(&mut sys, "link 2", 5, Vec3([1.5, 0.0, 0.0]));
    let l3 = link(&mut sys, "link 3", 7, Vec3([1.5, 0.3, 0.0]));
    let inertia = Mat3([[0.05, 0.004, -0.002], [0.004, 0.08, 0.003], [-0.002, 0.003, 0.09]]);
    let rigid = |sys: &mut SystemBuilder, name: &str, x: Vec3| {
        sys.add_rigid_body(
            name,
            1.1,
            inertia,
            Vec3([0.05, 0.02, 0.0]),
            x,
            Mat3::IDENTITY,
            Vec3::ZERO,
            Vec3::ZERO,
        )
        .unwrap()
    };
    let tip = rigid(&mut sys, "tip", Vec3([2.3, 0.0, 0.0]));
    let slider = rigid(&mut sys, "slider", Vec3([1.5, 0.0, 0.0]));
    let mut rng = Lcg(17);
    let mut elastic = |indices: Vec<usize>| {
        let nl = indices.len();
        let mut shape = || Jacobian3 { n: nl, data: (0..3 * nl).map(|_| 0.4 * rng.next()).collect() };
        MarkerElastic { translation: shape(), rotation: shape(), indices }
    };
    let mut fm = |sys: &mut SystemBuilder, b, s: Vec3, r: Mat3, idx: Vec<usize>| {
        sys.add_flexible_marker("", b, s, r, elastic(idx)).unwrap()
    };
    let g0 = sys.add_marker("", g, Vec3::ZERO, Mat3::IDENTITY).unwrap();
    let l1a = fm(&mut sys, l1, Vec3([-0.5, 0.0, 0.0]), Mat3::IDENTITY, vec![0, 2, 3]);
    sys.add_joint("root", JointKind::Revolute, [g0, l1a]).unwrap();
    let l1b = fm(&mut sys, l1, Vec3([0.5, 0.0, 0.0]), rot_x(0.4), vec![0, 1, 2, 3]);
    let l2a = fm(&mut sys, l2, Vec3([-0.5, 0.0, 0.0]), rot_x(0.4), vec![1, 3]);
    sys.add_joint("elbow", JointKind::Revolute, [l1b, l2a]).unwrap();
    let t0 = sys.add_marker("", tip, Vec3([-0.3, 0.0, 0.0]), rot_x(-0.7)).unwrap();
    let l2b = fm(&mut sys, l2, Vec3([0.5, 0.0, 0.0]), rot_x(-0.7), vec![0, 1, 2]);
    sys.add_joint("wrist", JointKind::Revolute, [t0, l2b]).unwrap();
    let l3a = fm(&mut sys, l3, Vec3::ZERO, rot_x(-1.2), vec![0, 1, 2, 3]);
    let l2c = fm(&mut sys, l2, Vec3([0.0, 0.3, 0.0]), rot_x(-1.2), vec![2, 3]);
    sys.add_joint("branch", JointKind::Revolute, [l3a, l2c]).unwrap();
    // Rigid bodies welded at deformed markers: a clamp on link 1 (marker i on the link, the
    // parent side) and a cap on link 3 (marker i on the cap, the child side).
    let clamp = rigid(&mut sys, "clamp", Vec3([0.5, 0.2, 0.0]));
    let l1c = fm(&mut sys, l1, Vec3([0.0, 0.2, 0.0]), rot_x(0.9), vec![0, 1, 3]);
    let c0 = sys.add_marker("", clamp, Vec3::ZERO, rot_x(0.9)).unwrap();
    sys.add_joint("clamp weld", JointKind::Fixed, [l1c, c0]).unwrap();
    let cap = rigid(&mut sys, "cap", Vec3([1.6, 0.4, 0.0]));
    let k0 = sys.add_marker("", cap, Vec3([0.1, 0.0, 0.0]), rot_x(0.3)).unwrap();
    let l3c = fm(&mut sys, l3, Vec3([0.2, 0.1, 0.0]), rot_x(0.3), vec![0, 2, 3]);
    sys.add_joint("cap weld", JointKind::Fixed, [k0, l3c]).unwrap();
    // A slider on link 2 (prismatic, marker i on the deformed link) and a sleeve on link 1
    // (cylindrical, marker i on the sleeve, j on the deformed link).
    let slider2 = rigid(&mut sys, "slider 2", Vec3([1.7, -0.1, 0.0]));
    let l2e = fm(&mut sys, l2, Vec3([0.2, -0.1, 0.0]), along_x(), vec![0, 2, 3]);
    let s2 = sys.add_marker("", slider2, Vec3::ZERO, along_x()).unwrap();
    sys.add_joint("rail 2", JointKind::Prismatic, [l2e, s2]).unwrap();
    let sleeve = rigid(&mut sys, "sleeve", Vec3([0.6, -0.1, 0.0]));
    let v0 = sys.add_marker("", sleeve, Vec3::ZERO, rot_x(0.6)).unwrap();
    let l1d = fm(&mut sys, l1, Vec3([0.1, -0.1, 0.0]), rot_x(0.6), vec![1, 2]);
    sys.add_joint("sleeve joint", JointKind::Cylindrical, [v0, l1d]).unwrap();
    if driven {
        sys.add_joint(
            "rail 2 drive",
            JointKind::TranslationDriver(TimeFunction::Polynomial(vec![0.0, 0.2, -0.4])),
            [l2e, s2],
        )
        .unwrap();
    }
    // Cardan joints at deformed markers: a shaft on link 2 (marker i on the link, the
    // parent side) and a knuckle on link 3 (marker i on the knuckle, the child side).
    let shaft = rigid(&mut sys, "shaft", Vec3([1.4, 0.2, 0.0]));
    let l2f = fm(&mut sys, l2, Vec3([-0.1, 0.2, 0.0]), rot_x(0.5), vec![1, 2, 3]);
    let h0 = sys.add_marker("", shaft, Vec3::ZERO, rot_x(0.5)).unwrap();
    sys.add_joint("cardan 1", JointKind::Universal, [l2f, h0]).unwrap();
    let knuckle = rigid(&mut sys, "knuckle", Vec3([1.8, 0.2, 0.0]));
    let n0 = sys.add_marker("", knuckle, Vec3::ZERO, rot_x(-0.8)).unwrap();
    let l3e = fm(&mut sys, l3, Vec3([0.3, -0.1, 0.0]), rot_x(-0.8), vec![0, 3]);
    sys.add_joint("cardan 2", JointKind::Universal, [n0, l3e]).unwrap();
    // A fourth link welded to the cap at a deformed marker on the link (the child side).
    let fin = link(&mut sys, "fin", 11, Vec3([1.6, 0.7, 0.0]));
    let k1 = sys.add_marker("", cap, Vec3([0.0, 0.3, 0.0]), rot_x(-0.4)).unwrap();
    let f0 = fm(&mut sys, fin, Vec3::ZERO, rot_x(-0.4), vec![0, 1, 2, 3]);
    sys.add_joint("fin weld", JointKind::Fixed, [k1, f0]).unwrap();
    if closed {
        let l3b = fm(&mut sys, l3, Vec3([0.4, -0.3, 0.0]), Mat3::IDENTITY, vec![1, 3]);
        let t1 = sys.add_marker("", tip, Vec3([-0.4, 0.3, 0.0]), Mat3::IDENTITY).unwrap();
        sys.add_joint("strut", JointKind::Distance { distance: 0.3 }, [l3b, t1]).unwrap();
    }
    let l2d = sys.add_marker("", l2, Vec3::ZERO, along_x()).unwrap();
    let s0 = sys.add_marker("", slider, Vec3::ZERO, along_x()).unwrap();
    sys.add_joint("slide", JointKind::Prismatic, [l2d, s0]).unwrap();
    if driven {
        sys.add_joint(
            "root drive",
            JointKind::AngleDriver(TimeFunction::Polynomial(vec![0.0, 0.8, -1.5])),
            [g0, l1a],
        )
        .unwrap();
        // Marker i of the elbow moves with link 1's deformation: its angle is measured
        // with deformed axes.
        sys.add_joint(
            "elbow drive",
            JointKind::AngleDriver(TimeFunction::Polynomial(vec![0.3, -0.5, 0.7])),
            [l1b, l2a],
        )
        .unwrap();
    }
    sys.compile().unwrap()
}

/// Spherical joints, point masses and free bodies: ground -spherical- ball -spherical- bob
/// (a point mass); ball -spherical- plate (deformable, its marker moving with the
/// deformation); a free point mass on a distance to the ground (cut); a free rigid body
/// without joints. Gravity.
fn floating_tree_model() -> Model {
    use crate::body::flexible::tests::{Lcg, PointBody};
    use crate::body::flexible::FlexibleBody;
    use crate::math::dense::Jacobian3;
    let mut sys = SystemBuilder::new();
    sys.set_gravity(Vec3([0.2, -9.81, 0.4])).unwrap();
    let g = sys.ground();
    let inertia = Mat3([[0.05, 0.004, -0.002], [0.004, 0.08, 0.003], [-0.002, 0.003, 0.09]]);
    let rigid = |sys: &mut SystemBuilder, name: &str, x: Vec3| {
        sys.add_rigid_body(
            name,
            1.1,
            inertia,
            Vec3([0.05, 0.02, 0.0]),
            x,
            Mat3::IDENTITY,
            Vec3::ZERO,
            Vec3::ZERO,
        )
        .unwrap()
    };
    let ball = rigid(&mut sys, "ball", Vec3([0.0, -0.5, 0.0]));
    let floater = rigid(&mut sys, "floater", Vec3([2.0, 1.0, 0.5]));
    let _ = floater;
    let bob = sys.add_point_mass("bob", 0.7, Vec3([0.4, -0.9, 0.1]), Vec3::ZERO).unwrap();
    let drone = sys.add_point_mass("drone", 0.3, Vec3([1.0, 0.0, 0.0]), Vec3::ZERO).unwrap();
    let body = FlexibleBody::new("plate", PointBody::random(6, 4, 9).input(50.0, 0.1)).unwrap();
    let plate = sys
        .add_flexible_body(
            "plate",
            body,
            Vec3([-0.6, -0.5, 0.0]),
            Mat3::IDENTITY,
            Vec3::ZERO,
            Vec3::ZERO,
            vec![],
            vec![],
        )
        .unwrap();
    let m = |sys: &mut SystemBuilder, b, s: Vec3, r: Mat3| sys.add_marker("", b, s, r).unwrap();
    let (g0, b0) =
        (m(&mut sys, g, Vec3::ZERO, rot_x(0.3)), m(&mut sys, ball, Vec3([0.0, 0.5, 0.0]), rot_x(-0.2)));
    sys.add_joint("shoulder", JointKind::Spherical, [g0, b0]).unwrap();
    let (b1, o0) =
        (m(&mut sys, ball, Vec3([0.4, -0.4, 0.1]), Mat3::IDENTITY), m(&mut sys, bob, Vec3::ZERO, along_x()));
    sys.add_joint("bob joint", JointKind::Spherical, [o0, b1]).unwrap();
    let mut rng = Lcg(23);
    let mut shape = || Jacobian3 { n: 3, data: (0..9).map(|_| 0.4 * rng.next()).collect() };
    let elastic = MarkerElastic { indices: vec![0, 2, 3], translation: shape(), rotation: shape() };
    let p0 = sys.add_flexible_marker("", plate, Vec3([0.6, 0.0, 0.0]), rot_x(0.5), elastic).unwrap();
    let b2 = m(&mut sys, ball, Vec3::ZERO, Mat3::IDENTITY);
    sys.add_joint("plate joint", JointKind::Spherical, [b2, p0]).unwrap();
    let (g1, d0) =
        (m(&mut sys, g, Vec3::ZERO, Mat3::IDENTITY), m(&mut sys, drone, Vec3::ZERO, Mat3::IDENTITY));
    sys.add_joint("tether", JointKind::Distance { distance: 1.0 }, [g1, d0]).unwrap();
    sys.compile().unwrap()
}

fn consistent(model: &Model) -> Vec<f64> {
    let mut ws = Workspace::new(model);
    let mut eq = DenseEquations::new(model);
    let mut state = State::initial(model, 0.0);
    dense_initial_conditions(model, &mut ws, &mut eq, &mut state, &InitialSettings::default()).unwrap();
    state.coordinates
}

fn sample(np: usize, seed: u64, scale: f64) -> Vec<f64> {
    let mut x = seed;
    (0..np)
        .map(|_| {
            x = x.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            scale * (((x >> 11) as f64) / ((1u64 << 53) as f64) - 0.5)
        })
        .collect()
}

/// x + a random perturbation of the free coordinates of `tree` (entries within scale / 2,
/// a tenth of that for the elastic coordinates).
fn perturbed(tree: &Tree, x: &[f64], seed: u64, scale: f64) -> Vec<f64> {
    let elastic = tree.coordinate_count() - tree.joint_coordinate_count();
    let joints = x.len() - elastic;
    x.iter()
        .zip(sample(x.len(), seed, scale))
        .enumerate()
        .map(|(k, (a, b))| a + if k < joints { b } else { 0.1 * b })
        .collect()
}

#[test]
fn influence_coefficients_and_quadratic_terms_match_finite_differences() {
    let cases =
        [(tree_model(false), 11), (flexible_tree_model(false), 12 + 16), (floating_tree_model(), 15 + 4)];
    for (model, count) in cases {
        influence_check(&model, count);
    }
}

fn influence_check(model: &Model, count: usize) {
    let (tree, p0) = Tree::new(model, &consistent(model), None).unwrap();
    let (n, np) = (model.coordinate_count, tree.coordinate_count());
    assert_eq!(np, count);
    let p = perturbed(&tree, &p0, 3, 1.0);
    let pd = perturbed(&tree, &vec![0.0; np], 7, 4.0);
    let b = tree.influence(n, &p);
    let eps = 1e-6;
    for k in 0..np {
        let (mut plus, mut minus) = (p.clone(), p.clone());
        plus[k] += eps;
        minus[k] -= eps;
        let (qp, _, _) = tree.state(n, &plus, &pd);
        let (qm, _, _) = tree.state(n, &minus, &pd);
        let fd: Vec<f64> = (0..n).map(|i| (qp[i] - qm[i]) / (2.0 * eps)).collect();
        let column: Vec<f64> = (0..n).map(|i| b[(i, k)]).collect();
        assert_all_close(&fd, &column, 0.0, 1e-7, format_args!("dq/dp{k}"));
    }
    // gamma_B = d(B p_dot)/dt at p_dd = 0.
    let (_, qd, gamma) = tree.state(n, &p, &pd);
    let plus: Vec<f64> = p.iter().zip(&pd).map(|(a, v)| a + eps * v).collect();
    let minus: Vec<f64> = p.iter().zip(&pd).map(|(a, v)| a - eps * v).collect();
    let (_, qd_plus, _) = tree.state(n, &plus, &pd);
    let (_, qd_minus, _) = tree.state(n, &minus, &pd);
    let fd: Vec<f64> = (0..n).map(|i| (qd_plus[i] - qd_minus[i]) / (2.0 * eps)).collect();
    assert_all_close(&gamma[..n], &fd, 1e-5, 1e-5, "gamma against fd");
    let bpd: Vec<f64> = (0..n).map(|i| (0..np).map(|k| b[(i, k)] * pd[k]).sum()).collect();
    assert_all_close(&bpd, &qd[..n], 0.0, 1e-12, "B p_dot against q_dot");
}

#[test]
fn joint_coordinate_accelerations_equal_the_augmented_ones() {
    let cases = [
        (tree_model(false), 11),
        (tree_model(true), 9),
        (flexible_tree_model(false), 28),
        (flexible_tree_model(true), 25),
        (floating_tree_model(), 19),
    ];
    for (case, (model, free)) in cases.into_iter().enumerate() {
        let (tree, p0) = Tree::new(&model, &consistent(&model), None).unwrap();
        let n = model.coordinate_count;
        let nf = tree.free_count();
        assert_eq!(nf, free);
        for seed in 0..5 {
            let time = 0.1 + 0.3 * seed as f64;
            let p = perturbed(&tree, &p0, 11 + seed, 2.0);
            let pd = perturbed(&tree, &vec![0.0; nf], 29 + seed, 6.0);
            let state = tree.evaluate(&model, time, &p, &pd).unwrap();
            let (q, qd) = (&state.coordinates, &state.velocities);
            let mut ws = Workspace::new(&model);
            let mut eq = DenseEquations::new(&model);
            eq.evaluate(&model, &mut ws, time, q, qd, &[], Level::Acceleration).unwrap();
            // The tree state satisfies every tree joint and driver, at position and velocity
            // level (the cut ones constrain the accelerations below).
            for r in (0..model.constraint_count).filter(|r| !tree.cut_rows.contains(r)) {
                assert_close(eq.constraints[r], 0.0, 0.0, 1e-12, format_args!("row {r}: constraint"));
                assert_close(
                    eq.velocity_violation(r, qd),
                    0.0,
                    0.0,
                    1e-11,
                    format_args!("row {r}: velocity"),
                );
            }
            let b = &state.influence;
            let pdd = tree_joint_accelerations(
                &eq,
                b,
                &state.gamma,
                &tree.cut_rows,
                loop_rank(&eq, b, &tree.cut_rows, 1e-12),
            )
            .unwrap();
            let qdd_tree: Vec<f64> =
                (0..n).map(|i| state.gamma[i] + (0..nf).map(|k| b[(i, k)] * pdd[k]).sum::<f64>()).collect();
            let part = partition(eq.jacobian.as_ref(), PartitionMethod::Lu, DEFAULT_RANK_TOLERANCE);
            let mut qdd = vec![0.0; n];
            eq.accelerations(&part, Formulation::Augmented, &eq.gamma, f64::INFINITY, &mut qdd).unwrap();
            let scale = qdd.iter().fold(1.0f64, |a, v| a.max(v.abs()));
            assert_all_close(
                &qdd_tree,
                &qdd,
                0.0,
                1e-10 * scale,
                format_args!("case {case} seed {seed}: q_dd"),
            );
        }
    }
}

#[test]
fn decoupled_and_coupled_systems_equal_the_joint_space_one() {
    use crate::formulation::decoupled::{TreeFormulation, TreeSolver};
    let models = [
        flexible_tree_model(false),
        flexible_tree_model(true),
        floating_tree_model(),
        flexible_tree_model_with(true, true, 5),
    ];
    for (case, model) in models.iter().enumerate() {
        let (tree, p0) = Tree::new(model, &consistent(model), None).unwrap();
        let n = model.coordinate_count;
        let nf = tree.free_count();
        let mut coupled = TreeSolver::new(model, &tree, TreeFormulation::Coupled).unwrap();
        let mut decoupled = TreeSolver::new(model, &tree, TreeFormulation::Decoupled).unwrap();
        let mut ws = Workspace::new(model);
        for seed in 0..3 {
            let time = 0.2 + 0.3 * seed as f64;
            let p = perturbed(&tree, &p0, 41 + seed, 2.0);
            let pd = perturbed(&tree, &vec![0.0; nf], 53 + seed, 6.0);
            // Joint space: (B^T M B) p_dd = B^T (f - M gamma_B) (with the cut rows).
            let state = tree.evaluate(model, time, &p, &pd).unwrap();
            let mut eq = DenseEquations::new(model);
            eq.evaluate(
                model,
                &mut ws,
                time,
                &state.coordinates,
                &state.velocities,
                &[],
                Level::Acceleration,
            )
            .unwrap();
            let b = &state.influence;
            let pdd = tree_joint_accelerations(
                &eq,
                b,
                &state.gamma,
                &tree.cut_rows,
                loop_rank(&eq, b, &tree.cut_rows, 1e-12),
            )
            .unwrap();
            let st = tree.structured(model, time, &p, &pd).unwrap();
            assert_all_close(&st.coordinates, &state.coordinates, 0.0, 1e-14, "structured coordinates");
            let r40 = coupled.accelerations(model, &mut ws, &st, time, &[]).unwrap();
            let r41 = decoupled.accelerations(model, &mut ws, &st, time, &[]).unwrap();
            let scale = pdd.iter().fold(1.0f64, |a, v| a.max(v.abs()));
            for (name, r) in [("eq. 40", &r40), ("eq. 41", &r41)] {
                let what = format!("case {case} seed {seed} {name}: p_dd");
                assert_all_close(&r.free_accelerations[..nf], &pdd[..nf], 0.0, 1e-10 * scale, what);
            }
            // The same reactions -F_r and cut multipliers from both.
            let rscale = r40.reactions.iter().fold(1.0f64, |a, v| a.max(v.abs()));
            let what = format!("case {case}: reactions, then cut multipliers");
            let r40_all = [&r40.reactions[..], &r40.cut_multipliers[..]].concat();
            let r41_all = [&r41.reactions[..], &r41.cut_multipliers[..]].concat();
            assert_all_close(&r41_all, &r40_all, 0.0, 1e-10 * rscale, what);
            // F_r = -y balances M q_dd - Q on the reference rows with the cut rows' C^T mu:
            // M_r q_dd + y + C_r^T mu = Q_r.
            let mq: Vec<f64> =
                (0..n).map(|i| (0..n).map(|j| eq.mass[(i, j)] * r41.accelerations[j]).sum()).collect();
            for (k, &row) in tree.reference_rows().iter().enumerate() {
                let cmu: f64 = tree
                    .cut_rows
                    .iter()
                    .enumerate()
                    .map(|(a, &r)| eq.jacobian[(r, row)] * r41.cut_multipliers[a])
                    .sum();
                let lhs = mq[row] + r41.reactions[k] + cmu;
                let what = format!("case {case} row {row}: M_r q_dd + y + C_r^T mu against Q_r");
                assert_close(lhs, eq.force[row], 0.0, 1e-9 * rscale, what);
            }
        }
    }
    // The size of eq. 41 does not depend on the elastic coordinates; eq. 40 grows with them.
    let size = |elastic: usize, formulation| {
        let model = flexible_tree_model_with(false, false, elastic);
        let (tree, _) = Tree::new(&model, &model.initial_coordinates, None).unwrap();
        TreeSolver::new(&model, &tree, formulation).unwrap().reduced_size()
    };
    assert_eq!(size(4, TreeFormulation::Decoupled), size(9, TreeFormulation::Decoupled));
    assert_eq!(size(9, TreeFormulation::Coupled) - size(4, TreeFormulation::Coupled), 4 * 5);
}

#[test]
fn rebasing_cardan_angles_keeps_the_body_state() {
    let model = floating_tree_model();
    let (mut tree, p0) = Tree::new(&model, &consistent(&model), None).unwrap();
    let nf = tree.free_count();
    let mut p = perturbed(&tree, &p0, 61, 1.0);
    let mut pd = perturbed(&tree, &vec![0.0; nf], 67, 6.0);
    // Middle Cardan angles past the limit: shoulder (coordinates 0-2), plate joint (3-5),
    // and the floating body's free joint (6-11, its angles 9-11).
    for k in [1, 4, 10] {
        p[k] = 1.3;
    }
    let before = tree.evaluate(&model, 0.4, &p, &pd).unwrap();
    let rebased = tree.rebase(&model, &mut p, &mut pd, 1.0);
    assert_eq!(rebased.len(), 3, "{rebased:?}");
    assert!([0, 1, 2, 3, 4, 5, 9, 10, 11].iter().all(|&k| p[k] == 0.0));
    let after = tree.evaluate(&model, 0.4, &p, &pd).unwrap();
    // The same state, hence the same accelerations (gamma_B and B differ: they belong to
    // the parametrization).
    let n = model.coordinate_count;
    let mut ws = Workspace::new(&model);
    let mut accelerations = |state: &TreeState| {
        let mut eq = DenseEquations::new(&model);
        eq.evaluate(&model, &mut ws, 0.4, &state.coordinates, &state.velocities, &[], Level::Acceleration)
            .unwrap();
        let b = &state.influence;
        let pdd = tree_joint_accelerations(
            &eq,
            b,
            &state.gamma,
            &tree.cut_rows,
            loop_rank(&eq, b, &tree.cut_rows, 1e-12),
        )
        .unwrap();
        (0..n)
            .map(|i| state.gamma[i] + (0..nf).map(|k| b[(i, k)] * pdd[k]).sum::<f64>())
            .collect::<Vec<f64>>()
    };
    let (qdd_before, qdd_after) = (accelerations(&before), accelerations(&after));
    assert_all_close(&after.velocities[..n], &before.velocities[..n], 0.0, 1e-12, "q_dot");
    assert_all_close(&qdd_after, &qdd_before, 1e-9, 1e-9, "q_dd");
    for (b, body) in model.bodies.iter().enumerate().skip(1) {
        let o = body.offset;
        let (qa, qb) = (&before.coordinates[o..o + 3], &after.coordinates[o..o + 3]);
        assert_all_close(qb, qa, 0.0, 1e-12, format_args!("body {b}: position"));
        if !matches!(body.kind, BodyKind::PointMass { .. }) {
            // Euler parameters p and -p are the same rotation.
            let (ea, eb) = (&before.coordinates[o + 3..o + 7], &after.coordinates[o + 3..o + 7]);
            let sign = if ea.iter().zip(eb).map(|(x, y)| x * y).sum::<f64>() < 0.0 { -1.0 } else { 1.0 };
            let eb: Vec<f64> = eb.iter().map(|x| sign * x).collect();
            assert_all_close(&eb, ea, 0.0, 1e-12, format_args!("body {b}: Euler parameters up to sign"));
        }
    }
}

#[test]
fn unsupported_trees_are_refused_and_loops_are_cut() {
    // A weld whose markers are turned half a turn about x (z_j = -z_i, which its equations
    // allow): the tree, which aligns them, would move the body; refused.
    let mut sys = SystemBuilder::new();
    let body = unit_body(&mut sys, "plate", Vec3::ZERO);
    let base = sys.add_marker("", sys.ground(), Vec3::ZERO, Mat3::IDENTITY).unwrap();
    let flipped = sys.add_marker("", body, Vec3::ZERO, rot_x(std::f64::consts::PI)).unwrap();
    sys.add_joint("weld", JointKind::Fixed, [base, flipped]).unwrap();
    let model = sys.compile().unwrap();
    let error = Tree::new(&model, &model.initial_coordinates, None).unwrap_err().to_string();
    assert!(error.contains("'weld' (fixed)") && error.contains("'plate'"), "{error}");

    let mut sys = SystemBuilder::new();
    let body = unit_body(&mut sys, "link", Vec3::ZERO);
    for name in ["first", "second"] {
        ground_joint(&mut sys, name, JointKind::Revolute, body, Vec3::ZERO, Vec3::ZERO);
    }
    let model = sys.compile().unwrap();
    // The second hinge closes a loop: it is cut, its five equations constrain the tree.
    let (tree, _) = Tree::new(&model, &model.initial_coordinates, None).unwrap();
    assert_eq!(tree.cut_joints, vec![1]);
    assert_eq!(tree.cut_rows.len(), 5);
    // Named cut joints: the first hinge cut instead; a loop left without a named cut
    // joint is an error naming the joint; an index out of range too.
    let (tree, _) = Tree::new(&model, &model.initial_coordinates, Some(&[0])).unwrap();
    assert_eq!(tree.cut_joints, vec![0]);
    let error = Tree::new(&model, &model.initial_coordinates, Some(&[])).unwrap_err().to_string();
    assert!(error.contains("'second' (revolute)") && error.contains("closes a loop"), "{error}");
    let error = Tree::new(&model, &model.initial_coordinates, Some(&[7])).unwrap_err().to_string();
    assert!(error.contains("cut joint 7"), "{error}");
}

/// The linearized equations of motion of implicit methods ([`TreeLinearization`]) against
/// central differences of the joint accelerations: at rest, undeformed, without gravity and
/// drivers the terms it leaves out vanish, so that d p_dd / d p = -P K_t and
/// d p_dd / d p_dot = -P D_t hold exactly (P = M_t^-1 with M_t = B^T M B, or its inverse on
/// the null space of the cut joints). A wrong mass matrix, stiffness, damping or null space
/// fails it.
#[test]
fn linearized_equations_match_finite_differences_at_rest() {
    use faer::linalg::solvers::DenseSolveCore;
    for closed in [false, true] {
        let mut model = flexible_tree_model_with(false, closed, 5);
        model.gravity = Vec3::ZERO;
        let (tree, p0) = Tree::new(&model, &consistent(&model), None).unwrap();
        assert_eq!(!tree.cut_rows.is_empty(), closed);
        let (nf, nj) = (tree.free_count(), tree.free_joint_count());
        let mut p = perturbed(&tree, &p0, 61, 0.6);
        p[nj..].iter_mut().for_each(|x| *x = 0.0);
        let rest = vec![0.0; nf];
        let mut ws = Workspace::new(&model);
        let mut eq = DenseEquations::new(&model);
        let mut evaluate = |p: &[f64], pd: &[f64], eq: &mut DenseEquations| {
            let state = tree.evaluate(&model, 0.0, p, pd).unwrap();
            eq.evaluate(
                &model,
                &mut ws,
                0.0,
                &state.coordinates,
                &state.velocities,
                &[],
                Level::Acceleration,
            )
            .unwrap();
            state
        };
        let state = evaluate(&p, &rest, &mut eq);
        let rank = loop_rank(&eq, &state.influence, &tree.cut_rows, 1e-12);
        let lin = TreeLinearization::new(&model, &tree, &eq, &state.influence, rank).unwrap();
        assert_eq!(lin.null_space.as_ref().map(|n| n.ncols()), closed.then(|| nf - rank));
        // M_t formed body by body is the dense B^T M B.
        let dense = state.influence.transpose() * (&eq.mass * &state.influence);
        for k in 0..nf {
            let column: Vec<f64> = (0..nf).map(|i| lin.mass[(i, k)]).collect();
            let expected: Vec<f64> = (0..nf).map(|i| dense[(i, k)]).collect();
            assert_all_close(&column, &expected, 1e-12, 1e-12, format_args!("B^T M B column {k}"));
        }
        let inverse = match &lin.null_space {
            None => lin.mass.partial_piv_lu().inverse(),
            Some(v) => v * (v.transpose() * &lin.mass * v).partial_piv_lu().inverse() * v.transpose(),
        };
        let mut accelerations = |p: &[f64], pd: &[f64]| {
            let state = evaluate(p, pd, &mut eq);
            tree_joint_accelerations(&eq, &state.influence, &state.gamma, &tree.cut_rows, rank).unwrap()
        };
        let at_rest = accelerations(&p, &rest);
        assert_all_close(&at_rest, &rest, 0.0, 1e-12, "accelerations at rest");
        let eps = 1e-6;
        for (name, matrix, of_rates) in
            [("stiffness", &lin.stiffness, false), ("damping", &lin.damping, true)]
        {
            let expected = -(&inverse * matrix);
            let scale = (0..nf)
                .flat_map(|i| (0..nf).map(move |k| (i, k)))
                .fold(0.0f64, |m, (i, k)| m.max(expected[(i, k)].abs()));
            for k in 0..nf {
                let (mut plus, mut minus) =
                    if of_rates { (rest.clone(), rest.clone()) } else { (p.clone(), p.clone()) };
                plus[k] += eps;
                minus[k] -= eps;
                let (a_plus, a_minus) = if of_rates {
                    (accelerations(&p, &plus), accelerations(&p, &minus))
                } else {
                    (accelerations(&plus, &rest), accelerations(&minus, &rest))
                };
                let fd: Vec<f64> = (0..nf).map(|i| (a_plus[i] - a_minus[i]) / (2.0 * eps)).collect();
                let column: Vec<f64> = (0..nf).map(|i| expected[(i, k)]).collect();
                let what = format!("closed {closed}: -P {name}, column {k}");
                assert_all_close(&fd, &column, 0.0, 1e-6 * scale, what);
            }
        }
    }
}

/// The sparse joint-space evaluation (body by body, range-space solve) against the dense one
/// (B, M and C_q of the model's size, the SVD of C_cut B) on IFToMM A02 with 2 to 10
/// four-bars: the influence coefficients, the accelerations, the minimum-norm corrections and
/// the multipliers at random states along the mechanism's motion (cranks at 0.3 and 1.1 rad,
/// within 0.05 and 0.01 rad of horizontal) and off it, and the singular configuration (cranks
/// horizontal), where the sparse path must refuse and leave it to the SVD.
#[test]
fn sparse_joint_space_equals_the_dense_one_on_a02() {
    for n in [2, 5, 10] {
        let (model, _) = a02_four_bar(n);
        let (tree, p0) = Tree::new(&model, &consistent(&model), None).unwrap();
        let (nq, nf, nc) = (model.coordinate_count, tree.free_count(), tree.cut_rows.len());
        assert_eq!((nf, nc), (2 * n + 1, 2 * n));
        let mut sparse = SparseJointSpace::new(&model, &tree).expect("a rigid tree");
        let mut ws = Workspace::new(&model);
        let mut eq = DenseEquations::new(&model);
        // The motion: p0 + theta d along the null space of C_cut B (a straight branch),
        // scaled so that the first crank turns by theta.
        let start = tree.evaluate(&model, 0.0, &p0, &vec![0.0; nf]).unwrap();
        eq.evaluate(&model, &mut ws, 0.0, &start.coordinates, &start.velocities, &[], Level::Velocity)
            .unwrap();
        let (c_hat, _) = cut_equations(&eq, &start.influence, &vec![0.0; nq], &tree.cut_rows);
        let rank = loop_rank(&eq, &start.influence, &tree.cut_rows, 1e-12);
        assert_eq!(rank, nc);
        let d = LoopClosure::new(c_hat.as_ref(), nc, 0.0).unwrap().null_space();
        let crank = (0..nf).find(|&k| d[(k, 0)].abs() > 1e-3).unwrap();
        let direction: Vec<f64> = (0..nf).map(|k| d[(k, 0)] / d[(crank, 0)].abs()).collect();
        let half_pi = std::f64::consts::FRAC_PI_2;
        let mut sparse_states = 0;
        for (case, (theta, scale)) in [
            (0.3, 0.0),
            (1.1, 0.0),
            (0.3, 0.2),
            (1.1, 0.1),
            (half_pi - 0.05, 0.0),
            (half_pi - 0.01, 0.0),
            (half_pi, 0.0),
        ]
        .into_iter()
        .enumerate()
        {
            let seed = 100 * n as u64 + case as u64;
            let on_branch: Vec<f64> = p0.iter().zip(&direction).map(|(a, b)| a + theta * b).collect();
            let p = perturbed(&tree, &on_branch, seed, scale);
            let pd = perturbed(&tree, &vec![0.0; nf], seed + 7, 3.0);
            let time = 0.1 * case as f64;
            let context = format!("N = {n}, theta = {theta}, perturbation {scale}");
            // Dense.
            let state = tree.evaluate(&model, time, &p, &pd).unwrap();
            eq.evaluate(
                &model,
                &mut ws,
                time,
                &state.coordinates,
                &state.velocities,
                &[],
                Level::Acceleration,
            )
            .unwrap();
            let b = &state.influence;
            let pdd = tree_joint_accelerations(&eq, b, &state.gamma, &tree.cut_rows, rank).unwrap();
            let (c_hat, _) = cut_equations(&eq, b, &vec![0.0; nq], &tree.cut_rows);
            let closure = LoopClosure::new(c_hat.as_ref(), rank, LOOP_DAMPING).unwrap();
            let s = closure.singular_values();
            let ratio = s[nc - 1] / s[0];
            // Sparse.
            let (full_p, full_pd, _) = tree.full_coordinates(&model, time, &p, &pd).unwrap();
            let influence = sparse.influence(&tree, &full_p);
            assert_eq!(full_pd.len(), full_p.len());
            let dense_b = sparse.dense(&influence, nq);
            for i in 0..nq {
                let row: Vec<f64> = (0..nf).map(|k| dense_b[(i, k)]).collect();
                let expected: Vec<f64> = (0..nf).map(|k| b[(i, k)]).collect();
                assert_all_close(&row, &expected, 0.0, 1e-14, format_args!("{context}: B row {i}"));
            }
            let mut eq_sparse = DenseEquations::new(&model);
            let mut ws_sparse = Workspace::new(&model);
            eq_sparse
                .evaluate_sparse(
                    &model,
                    &mut ws_sparse,
                    time,
                    &state.coordinates,
                    &state.velocities,
                    &[],
                    Level::Acceleration,
                )
                .unwrap();
            let regular = sparse.closure(&ws_sparse, &influence, Some((&eq_sparse.gamma, &state.gamma)));
            if theta == half_pi {
                assert!(ratio < LOOP_DAMPING, "{context}: singular values {s:?}");
                assert!(!regular, "{context}: the sparse path must refuse a singular configuration");
                continue;
            }
            if theta < 1.2 {
                assert!(regular, "{context}: regular loops (ratio {ratio:.2e}) must take the sparse path");
            }
            if !regular {
                continue;
            }
            // Taken only where the damping band does not act.
            assert!(ratio >= LOOP_DAMPING, "{context}: ratio {ratio:.2e} within the band");
            sparse_states += 1;
            let pdd_sparse =
                sparse.accelerations(&ws_sparse, &influence, &eq_sparse.force, &state.gamma).unwrap();
            let scale_pdd = pdd.iter().fold(1.0f64, |a, v| a.max(v.abs()));
            assert_all_close(&pdd_sparse, &pdd, 0.0, 1e-10 * scale_pdd, format_args!("{context}: p_dd"));
            let mut qdd = vec![0.0; nq];
            sparse.body_accelerations(&influence, &state.gamma, &pdd_sparse, &mut qdd);
            let qdd_dense: Vec<f64> =
                (0..nq).map(|i| state.gamma[i] + (0..nf).map(|k| b[(i, k)] * pdd[k]).sum::<f64>()).collect();
            assert_all_close(&qdd, &qdd_dense, 0.0, 1e-10 * scale_pdd, format_args!("{context}: q_dd"));
            // The corrections of the projection: the SVD's solve where the band does not act.
            let residual = sample(nc, seed + 3, 1e-3);
            assert_all_close(
                &sparse.minimum_norm(&residual),
                &closure.solve(&residual),
                0.0,
                1e-12,
                format_args!("{context}: minimum-norm correction"),
            );
            // The multipliers against the dense minimum-norm solve of C_q^T lambda = f - M q_dd.
            let lambda = sparse.multipliers(&ws_sparse, &eq_sparse.force, &qdd_dense).unwrap();
            let r: Vec<f64> = (0..nq)
                .map(|i| eq.force[i] - (0..nq).map(|j| eq.mass[(i, j)] * qdd_dense[j]).sum::<f64>())
                .collect();
            let expected = crate::linalg::partition::minimum_norm_solve(
                eq.jacobian.transpose().to_owned().as_ref(),
                &r,
                crate::formulation::augmented::SINGULAR_VALUE_CUTOFF,
            );
            let scale_lambda = expected.iter().fold(1.0f64, |a, v| a.max(v.abs()));
            assert_all_close(&lambda, &expected, 0.0, 1e-9 * scale_lambda, format_args!("{context}: lambda"));
        }
        assert!(sparse_states >= 4, "N = {n}: {sparse_states} states took the sparse path");
    }
}
