//! Analytic Jacobians against central finite differences, in random (inconsistent)
//! configurations: the constraint Jacobian C_q of every joint type and driver, the blocks
//! dr/dq, dr/dq_dot, dr/dq_dd of the assembled Newton matrix (rigid and deformable bodies,
//! markers on deformable bodies, constraint Hessians, every force element, geometric
//! stiffness), and gamma of seed eq. 25 against the second time derivative of C.

mod common;

use std::sync::Arc;

use common::{assert_close, Rng};
use flexmbd_core::assembly::{assemble, constraint_time_terms, MatrixCoefficients, Request, StateView};
use flexmbd_core::body::corotational::CorotationalBeam;
use flexmbd_core::body::flexible::{AttachedMass, FlexibleBody, FlexibleBodyInput};
use flexmbd_core::body::marker::MarkerElastic;
use flexmbd_core::body::stiffening::StiffeningElement;
use flexmbd_core::force::joint_actuator::{ActuatedCoordinate, ServoLaw};
use flexmbd_core::force::{ForceCallback, ForceKind, Frame};
use flexmbd_core::joint::JointKind;
use flexmbd_core::linalg::csc::Csc;
use flexmbd_core::math::dense::Jacobian3;
use flexmbd_core::math::time_function::TimeFunction;
use flexmbd_core::math::{Mat3, Vec3};
use flexmbd_core::{BodyId, JointId, MarkerId, Model, State, SystemBuilder, Workspace};

struct Drag;
impl ForceCallback for Drag {
    fn evaluate(&self, time: f64, q: &[f64], qd: &[f64], out: &mut [f64]) -> Result<(), String> {
        for k in 0..q.len() {
            out[k] = -0.3 * qd[k] * qd[k].abs() + (time + q[k]).sin();
        }
        Ok(())
    }
}

fn harmonic(a: f64, w: f64) -> TimeFunction {
    TimeFunction::Harmonic { amplitude: a, frequency: w, phase: 0.3, offset: 0.1 }
}

/// A system with every joint type, driver and force element between random bodies, in a
/// random (inconsistent) state.
fn random_model(seed: u64) -> (Model, State) {
    let mut rng = Rng(seed);
    let mut sys = SystemBuilder::new();
    sys.set_gravity(Vec3([0.3, -9.81, 1.2])).unwrap();
    let bodies = add_bodies(&mut sys, &mut rng);
    let joints = add_joints(&mut sys, &mut rng, &bodies);
    add_forces(&mut sys, &mut rng, &bodies);
    add_actuators(&mut sys, &joints);
    let model = sys.compile().unwrap();
    let state = random_state(&model, &mut rng);
    (model, state)
}

/// The ground, six rigid bodies, a point mass (index 7) and two deformable bodies of random
/// mass points, deformed and moving (indices 8 and 9; the second with a beam element of
/// geometric stiffness).
fn add_bodies(sys: &mut SystemBuilder, rng: &mut Rng) -> Vec<BodyId> {
    let mut bodies = vec![sys.ground()];
    for k in 0..6 {
        let inertia = Mat3::diagonal(Vec3([0.2 + 0.1 * k as f64, 0.3, 0.25]));
        let b = sys
            .add_rigid_body(
                "",
                1.0 + k as f64,
                inertia,
                rng.vec3(0.3),
                rng.vec3(1.0),
                rng.rotation(),
                rng.vec3(1.0),
                rng.vec3(2.0),
            )
            .unwrap();
        bodies.push(b);
    }
    bodies.push(sys.add_point_mass("particle", 0.7, rng.vec3(1.0), rng.vec3(1.0)).unwrap());
    for (k, n) in [(0usize, 4usize), (1, 5)] {
        let body = random_deformable_body(rng, n, k == 1);
        let qf: Vec<f64> = (0..n).map(|_| 0.1 * rng.uniform()).collect();
        let qfd: Vec<f64> = (0..n).map(|_| rng.uniform()).collect();
        let id = sys
            .add_flexible_body("", body, rng.vec3(1.0), rng.rotation(), rng.vec3(1.0), rng.vec3(2.0), qf, qfd)
            .unwrap();
        bodies.push(id);
    }
    bodies
}

/// A deformable body of six random mass points with `n` elastic coordinates, with a beam
/// element of geometric stiffness of each kind (von Karman, co-rotational) and an attached
/// mass if `stiffening`.
fn random_deformable_body(rng: &mut Rng, n: usize, stiffening: bool) -> FlexibleBody {
    let points = 6;
    let masses: Vec<f64> = (0..points).map(|_| 1.0 + 0.3 * rng.uniform()).collect();
    let positions: Vec<Vec3> = (0..points).map(|_| rng.vec3(0.6)).collect();
    let shapes: Vec<Vec<f64>> =
        (0..points).map(|_| (0..3 * n).map(|_| 0.2 * rng.uniform()).collect()).collect();
    let stiffness =
        Csc::from_dense(
            n,
            n,
            |r, c| if r == c { 50.0 + 10.0 * r as f64 } else { 3.0 / (1.0 + (r + c) as f64) },
        );
    let damping = Csc::from_dense(n, n, |r, c| if r == c { 0.5 } else { 0.05 });
    let mut input = FlexibleBodyInput::from_mass_points(&masses, &positions, &shapes, stiffness, damping);
    if stiffening {
        let map = (0..36).map(|_| rng.uniform()).collect();
        input.stiffening = vec![StiffeningElement::beam(vec![0, 2, 3], map, 0.7, 400.0)];
        // And a co-rotational beam element (the other kind of geometric stiffness).
        let section = flexmbd_core::fem::Section::new("beam", 4e-3, 1e-3, 2e-3, 1.5e-3).unwrap();
        let material = flexmbd_core::fem::Material::new("beam", 1e5, 0.3, 1000.0).unwrap();
        let beam = flexmbd_core::fem::Beam { section, orientation: Vec3([0.0, 1.0, 0.0]), shear: false };
        let (_, length, k) =
            beam.corotational_terms(&material, &[Vec3::ZERO, Vec3([0.7, 0.0, 0.0])]).unwrap();
        let map = (0..36).map(|_| 2.0 * rng.uniform()).collect();
        input.corotational = vec![CorotationalBeam::new(vec![1, 2, 4], map, length, k.concat())];
        // And a point mass turning with a node to second order (an offset disc).
        input.attached = vec![AttachedMass {
            indices: vec![0, 3, 4],
            rows: (0..18).map(|_| 0.5 * rng.uniform()).collect(),
            node: rng.vec3(0.5),
            points: (0..3).map(|_| (0.5 + rng.uniform(), rng.vec3(0.3))).collect(),
            positions: Vec::new(),
        }];
    }
    FlexibleBody::new("flexible", input).unwrap()
}

/// A random marker on `body` (of `bodies`, as [`add_bodies`] makes them): on the deformable
/// bodies an elastic marker on some of the elastic coordinates, on the point mass at its
/// position.
fn add_marker(sys: &mut SystemBuilder, rng: &mut Rng, bodies: &[BodyId], body: BodyId) -> MarkerId {
    if body == bodies[8] || body == bodies[9] {
        // An elastic marker on some of the body's elastic coordinates.
        let indices = if body == bodies[8] { vec![0, 2, 3] } else { vec![4, 1] };
        let nl = indices.len();
        let mut translation = Jacobian3::zeros(nl);
        let mut rotation = Jacobian3::zeros(nl);
        for r in 0..3 {
            for c in 0..nl {
                translation.set(r, c, 0.3 * rng.uniform());
                rotation.set(r, c, 0.3 * rng.uniform());
            }
        }
        let elastic = MarkerElastic { indices, translation, rotation };
        return sys.add_flexible_marker("", body, rng.vec3(0.5), rng.rotation(), elastic).unwrap();
    }
    let pos = if body == bodies[7] { Vec3::ZERO } else { rng.vec3(0.5) };
    sys.add_marker("", body, pos, rng.rotation()).unwrap()
}

/// Every joint type and driver between the `bodies`, on random markers.
fn add_joints(sys: &mut SystemBuilder, rng: &mut Rng, bodies: &[BodyId]) -> Vec<JointId> {
    let kinds = vec![
        JointKind::Spherical,
        JointKind::Revolute,
        JointKind::Cylindrical,
        JointKind::Prismatic,
        JointKind::Fixed,
        JointKind::Universal,
        JointKind::Planar,
        JointKind::Inline,
        JointKind::Distance { distance: 0.8 },
        JointKind::AngleDriver(harmonic(0.7, 2.0)),
        JointKind::TranslationDriver(harmonic(0.2, 3.0)),
        JointKind::Revolute,
        JointKind::Spherical,
        JointKind::Revolute,
        JointKind::Prismatic,
        JointKind::Universal,
        JointKind::Distance { distance: 0.6 },
        JointKind::AngleDriver(harmonic(0.5, 1.5)),
        JointKind::Cylindrical,
    ];
    let pairs = [
        (0, 1),
        (1, 2),
        (2, 3),
        (3, 4),
        (4, 5),
        (5, 6),
        (6, 1),
        (0, 3),
        (2, 7),
        (1, 4),
        (5, 2),
        (7, 6),
        (0, 7),
        (8, 1),
        (3, 9),
        (9, 8),
        (0, 8),
        (9, 2),
        (8, 7),
    ];
    let mut joints = Vec::new();
    for (kind, (a, b)) in kinds.into_iter().zip(pairs) {
        let mi = add_marker(sys, rng, bodies, bodies[a]);
        let mj = add_marker(sys, rng, bodies, bodies[b]);
        joints.push(sys.add_joint("", kind, [mi, mj]).unwrap());
    }
    joints
}

/// Joint actuators on the revolute (rigid and deformable bodies), prismatic and both
/// coordinates of the cylindrical joints; one held at its limit (the gains drop out).
fn add_actuators(sys: &mut SystemBuilder, joints: &[JointId]) {
    let law = |kp: f64, kd: f64, limit: f64| ServoLaw {
        proportional_gain: kp,
        derivative_gain: kd,
        set_point: harmonic(0.4, 1.3),
        feed_forward: TimeFunction::Polynomial(vec![0.2, -0.5]),
        limit,
    };
    sys.add_joint_actuator("", joints[1], None, law(30.0, 2.0, f64::INFINITY)).unwrap();
    sys.add_joint_actuator("", joints[3], None, law(50.0, 3.0, f64::INFINITY)).unwrap();
    sys.add_joint_actuator("", joints[2], Some(ActuatedCoordinate::Angle), law(20.0, 1.0, f64::INFINITY))
        .unwrap();
    sys.add_joint_actuator("", joints[2], Some(ActuatedCoordinate::Slide), law(40.0, 0.5, 1e-3)).unwrap();
    sys.add_joint_actuator("", joints[13], None, law(10.0, 0.7, f64::INFINITY)).unwrap();
}

/// Three components of a force or torque as functions of time.
fn components() -> [TimeFunction; 3] {
    [harmonic(1.0, 1.0), TimeFunction::Constant(-2.0), TimeFunction::Polynomial(vec![0.5, 1.0])]
}

/// Every force element on the rigid bodies and the point mass, then loads on the deformable
/// bodies (a moment on a deformable body is not a free vector).
fn add_forces(sys: &mut SystemBuilder, rng: &mut Rng, bodies: &[BodyId]) {
    let m1 = add_marker(sys, rng, bodies, bodies[2]);
    let m2 = add_marker(sys, rng, bodies, bodies[5]);
    let m3 = add_marker(sys, rng, bodies, bodies[3]);
    let m4 = add_marker(sys, rng, bodies, bodies[7]);
    let m5 = add_marker(sys, rng, bodies, bodies[0]);
    sys.add_force("", ForceKind::PointForce { marker: m1, components: components(), frame: Frame::Global })
        .unwrap();
    sys.add_force("", ForceKind::PointForce { marker: m2, components: components(), frame: Frame::Marker })
        .unwrap();
    sys.add_force("", ForceKind::Torque { marker: m1, components: components(), frame: Frame::Global })
        .unwrap();
    sys.add_force("", ForceKind::Torque { marker: m3, components: components(), frame: Frame::Marker })
        .unwrap();
    sys.add_force(
        "",
        ForceKind::SpringDamper {
            markers: [m1, m2],
            stiffness: 50.0,
            damping: 3.0,
            rest_length: 0.4,
            preload: 2.0,
        },
    )
    .unwrap();
    sys.add_force(
        "",
        ForceKind::SpringDamper {
            markers: [m5, m4],
            stiffness: 20.0,
            damping: 1.0,
            rest_length: 0.1,
            preload: 0.0,
        },
    )
    .unwrap();
    sys.add_force(
        "",
        ForceKind::RotationalSpringDamper {
            markers: [m3, m2],
            stiffness: 7.0,
            damping: 0.5,
            rest_angle: 0.2,
            preload: 0.3,
        },
    )
    .unwrap();
    sys.add_force("", ForceKind::Callback { bodies: vec![bodies[4], bodies[7]], callback: Arc::new(Drag) })
        .unwrap();
    add_deformable_body_loads(sys, rng, bodies);
}

/// Point forces, torques and springs on the deformable bodies.
fn add_deformable_body_loads(sys: &mut SystemBuilder, rng: &mut Rng, bodies: &[BodyId]) {
    let f1 = add_marker(sys, rng, bodies, bodies[8]);
    let f2 = add_marker(sys, rng, bodies, bodies[9]);
    let r1 = add_marker(sys, rng, bodies, bodies[1]);
    sys.add_force("", ForceKind::PointForce { marker: f1, components: components(), frame: Frame::Marker })
        .unwrap();
    sys.add_force("", ForceKind::Torque { marker: f2, components: components(), frame: Frame::Marker })
        .unwrap();
    sys.add_force("", ForceKind::Torque { marker: f1, components: components(), frame: Frame::Global })
        .unwrap();
    sys.add_force(
        "",
        ForceKind::SpringDamper {
            markers: [f2, r1],
            stiffness: 30.0,
            damping: 2.0,
            rest_length: 0.2,
            preload: 1.0,
        },
    )
    .unwrap();
    sys.add_force(
        "",
        ForceKind::RotationalSpringDamper {
            markers: [f1, f2],
            stiffness: 4.0,
            damping: 0.3,
            rest_angle: 0.1,
            preload: 0.2,
        },
    )
    .unwrap();
}

/// The model's initial state at t = 0.37 with random accelerations and multipliers.
fn random_state(model: &Model, rng: &mut Rng) -> State {
    let mut state = State::initial(model, 0.37);
    for v in state.accelerations.iter_mut() {
        *v = rng.uniform() * 3.0;
    }
    for v in state.multipliers.iter_mut() {
        *v = rng.uniform() * 5.0;
    }
    // Reference angles of the rotational springs near their current angles.
    state.discrete.iter_mut().for_each(|x| *x = 0.0);
    state
}

fn dense(model: &Model, values: &[f64]) -> Vec<Vec<f64>> {
    let n = model.system_size();
    let p = &model.layout.pattern;
    let mut m = vec![vec![0.0; n]; n];
    for c in 0..n {
        for k in p.col_ptr[c]..p.col_ptr[c + 1] {
            m[p.row_idx[k]][c] = values[k];
        }
    }
    m
}

#[test]
fn newton_matrix_blocks_match_finite_differences() {
    for seed in [3u64, 11, 29] {
        let (model, state) = random_model(seed);
        let nq = model.coordinate_count;
        let n = model.system_size();
        let mut ws = Workspace::new(&model);
        let h = 1e-6;
        // which = 0: dr/dq (and C_q), 1: dr/dq_dot, 2: dr/dq_dd.
        for which in 0..3 {
            let only = MatrixCoefficients { mass: 0.0, ..MatrixCoefficients::ACCELERATION };
            let coef = match which {
                0 => MatrixCoefficients { position: 1.0, ..only },
                1 => MatrixCoefficients { velocity: 1.0, ..only },
                _ => MatrixCoefficients::ACCELERATION,
            };
            assemble(&model, StateView::of(&state), &mut ws, &Request::matrix(coef)).unwrap();
            let analytic = dense(&model, &ws.values);
            for col in 0..nq {
                let mut plus = state.clone();
                let mut minus = state.clone();
                let (p, m) = match which {
                    0 => (&mut plus.coordinates[col], &mut minus.coordinates[col]),
                    1 => (&mut plus.velocities[col], &mut minus.velocities[col]),
                    _ => (&mut plus.accelerations[col], &mut minus.accelerations[col]),
                };
                *p += h;
                *m -= h;
                assemble(&model, StateView::of(&plus), &mut ws, &Request::residual()).unwrap();
                let rp = ws.residual.clone();
                assemble(&model, StateView::of(&minus), &mut ws, &Request::residual()).unwrap();
                let rm = ws.residual.clone();
                let rows = if which == 0 { n } else { nq };
                for row in 0..rows {
                    let fd = (rp[row] - rm[row]) / (2.0 * h);
                    let an = analytic[row][col];
                    assert_close(
                        fd,
                        an,
                        1e-5,
                        1e-6,
                        format_args!(
                            "seed {seed}, block {which}: d residual[{row}] ({}) / d {}: fd against analytic",
                            if row < nq {
                                model.coordinate_name(row)
                            } else {
                                model.constraint_name(row - nq)
                            },
                            model.coordinate_name(col)
                        ),
                    );
                }
            }
            // The C_q^T block is the transpose of C_q.
            for r in nq..n {
                for c in 0..nq {
                    assert_eq!(analytic[r][c], analytic[c][r]);
                }
            }
        }
    }
}

#[test]
fn gamma_matches_second_time_derivative_of_constraints() {
    for seed in [5u64, 17] {
        let (model, state) = random_model(seed);
        let nq = model.coordinate_count;
        let nc = model.constraint_count;
        let mut ws = Workspace::new(&model);
        let eval = |tau: f64, ws: &mut Workspace| {
            let mut s = state.clone();
            s.time += tau;
            for k in 0..nq {
                s.coordinates[k] += tau * state.velocities[k] + 0.5 * tau * tau * state.accelerations[k];
                s.velocities[k] += tau * state.accelerations[k];
            }
            assemble(&model, StateView::of(&s), ws, &Request::residual()).unwrap();
            ws.residual[nq..].to_vec()
        };
        let h = 1e-4;
        let cp = eval(h, &mut ws);
        let cm = eval(-h, &mut ws);
        let c0 = eval(0.0, &mut ws);
        assemble(&model, StateView::of(&state), &mut ws, &Request::matrix(MatrixCoefficients::ACCELERATION))
            .unwrap();
        let values = ws.values.clone();
        let mut ct = vec![0.0; nc];
        let mut gamma = vec![0.0; nc];
        constraint_time_terms(&model, StateView::of(&state), &mut ws, &mut ct, Some(&mut gamma)).unwrap();
        let jac = dense(&model, &values);
        for r in 0..nc {
            let c_dd = (cp[r] - 2.0 * c0[r] + cm[r]) / (h * h);
            let cq_qdd: f64 = (0..nq).map(|k| jac[nq + r][k] * state.accelerations[k]).sum();
            let c_d = (cp[r] - cm[r]) / (2.0 * h);
            let cq_qd: f64 = (0..nq).map(|k| jac[nq + r][k] * state.velocities[k]).sum();
            let name = model.constraint_name(r);
            assert_close(c_dd, cq_qdd - gamma[r], 1e-5, 1e-5, format_args!("gamma of {name}: C_dd"));
            assert_close(c_d, cq_qd + ct[r], 1e-6, 1e-6, format_args!("C_t of {name}: C_d"));
        }
    }
}
