//! Joint coordinates (seed section 5): open trees of rigid and deformable bodies and point
//! masses connected by revolute, prismatic, cylindrical, fixed, universal and spherical
//! joints, with angle and translation drivers on them (prescribed joint coordinates), in joint
//! plus elastic coordinates p. A body that these joints do not connect to the ground floats on
//! a free joint (the translation of its frame and three Cardan angles; a point mass: its
//! position); a point mass joins the tree only by a spherical joint.
//!
//! The bodies' reference coordinates q_r (origin and Euler parameters) follow from p body by
//! body from the ground to the tips; their elastic coordinates are entries of p. The joint
//! frames on a deformable body are its markers' intermediate frames (seed Figure 4): they move
//! with the deformation (u = u0 + S_u q_l, axes (I + theta~) A_m with theta = S_t q_l), so the
//! elastic coordinates of a body move the bodies beyond it. The recursion is evaluated in
//! hyper-dual numbers ([`crate::math::hyper_dual`]): one pass along (p_dot, p_dd) gives q,
//! q_dot = B p_dot and q_dd at zero free accelerations, gamma_B (the gamma of eq. 31, with the
//! prescribed accelerations), exactly; one pass per joint coordinate and per deformation
//! component of a joint marker gives the velocity influence coefficients B = dq/dp (the
//! matrices G and H of eq. 31 stacked for the tree; H_pp and H_pf of eq. 33). Projecting the
//! equations of motion of all bodies, M q_dd + C_q^T lambda = f, on B eliminates every joint
//! reaction (B^T C_q^T = 0 for the tree joints):
//!
//! ```text
//! (B^T M B) p_dd = B^T (f - M gamma_B).
//! ```
//!
//! This is the joint-coordinate system that the body-by-body elimination of eqs. 31-32
//! produces, here formed with B explicitly. Joints outside the tree (loop closures, other
//! joint types, drivers on other markers) are cut: their equations constrain p (see
//! [`constrained_joint_accelerations`]).
//!
//! Joint coordinates: for a revolute joint the angle an angle driver on its markers (i, j)
//! measures, atan2(y_i . x_j, x_i . x_j); for a prismatic joint the translation along the z
//! axis of marker i (the parent side is whichever marker is on the body nearer the ground); a
//! cylindrical joint has the angle about z from the parent-side to the child-side marker and
//! the translation, a fixed joint none; a universal joint the rotations a, b about its cross
//! axes, R_rel = R_x(a) R_y(b) from marker i to marker j (R_y(a) R_x(b) seen from marker j
//! when that is the parent side); a spherical joint the Cardan angles R_rel = R_x(a) R_y(b)
//! R_z(c) from the parent-side to the child-side marker frame after a constant rotation R_0,
//! which [`Tree::rebase`] resets before b reaches its singularity at +-90 degrees. A driver on
//! the markers of a tree joint prescribes its coordinate.
//!
//! Deformed marker axes are not exactly orthonormal (the small rotation is linearized, as in
//! the augmented formulation). A revolute joint there is placed so that its own equations
//! (x_i . z_j = 0, y_i . z_j = 0) and its driver's hold exactly: the child body's rotation maps
//! an orthonormal frame built from the child-side marker's deformed axes onto one built from
//! the parent side's, the normal of the plane of x_i and y_i being the common axis. The tree
//! therefore satisfies the augmented formulation's joints to round-off, and both give the same
//! accelerations. A fixed joint uses the same frames with the angle set by its twist equation
//! x_i . y_j = 0; prismatic and cylindrical joints use the fixed and the revolute frames and
//! translate along the normal of the plane of x_i, y_i by z_i . d / (z_i . n) (their coordinate
//! is the driver's z_i . d). A universal joint uses frames built with x_i first on marker i's
//! side and y_j first on marker j's, so that its cross equation x_i . y_j = 0 holds exactly. A
//! spherical joint constrains only the origins: any orthonormal frame built from the deformed
//! axes serves.

use faer::Mat;

use crate::body::marker::MarkerElastic;
use crate::body::BodyKind;
use crate::error::{FlexmbdError, Result};
use crate::formulation::augmented::{null_space_solve, DenseEquations};
use crate::joint::JointKind;
use crate::math::euler::rotation_matrix;
use crate::math::hyper_dual::{
    add, column, cross, dot, euler_parameters, from_columns, hmat, hvec, mul_mat, mul_transpose, mul_vec,
    normalize, scale, sub, values, HMat, HVec, HyperDual, HIDENTITY,
};
use crate::math::{Mat3, Vec3};
use crate::system::Model;

/// The kinds of joint the tree supports so far.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum TreeJointKind {
    Revolute,
    Prismatic,
    Cylindrical,
    Fixed,
    /// Universal joint with marker i on the parent side: R_rel = R_x(a) R_y(b).
    UniversalXY,
    /// Universal joint with marker j on the parent side: R_rel = R_y(a) R_x(b).
    UniversalYX,
    /// Spherical joint: three Cardan angles, R_rel = R_x(a) R_y(b) R_z(c).
    Spherical,
    /// Spherical joint with a point mass on the child side: no coordinate.
    SphericalPoint,
    /// A body the joints do not reach, on a free joint to the ground: the translation of its
    /// frame (global axes) and its Cardan angles.
    Free,
    /// A point mass the joints do not reach: its position.
    FreePoint,
}

/// How a body joins the tree.
#[derive(Clone, Copy, Debug)]
enum Link {
    /// By model joint k, marker i on the parent side or not.
    Joint(usize, bool),
    /// By a free joint to the ground.
    Free(usize),
}

/// One side of a tree joint: a marker on a body, moving with the body's deformation when the
/// body is deformable (u = u0 + S_u q_l, axes (I + theta~) A_m with theta = S_t q_l).
#[derive(Clone, Debug)]
struct Side {
    body: usize,
    position: Vec3,
    rotation: Mat3,
    elastic: Option<MarkerElastic>,
}

/// A joint of the tree, seen from its parent side.
#[derive(Clone, Debug)]
struct TreeJoint {
    kind: TreeJointKind,
    /// Index of its first coordinate in p.
    first: usize,
    /// Whether marker i of the joint is on the parent side.
    i_parent: bool,
    parent: Side,
    child: Side,
    /// Prismatic: the constant rotation from the parent-side to the child-side marker frame,
    /// and the sliding axis in the parent-side marker frame.
    rotation: Mat3,
    axis: Vec3,
    /// Whether a marker of the joint moves with a deformation (prismatic and cylindrical
    /// joints then use the frames that satisfy their equations exactly, and the coordinates
    /// their drivers measure).
    deformed: bool,
    /// Spherical and free joints: the rotation R_0 before the Cardan angles,
    /// R_rel = R_0 R_x(a) R_y(b) R_z(c). It absorbs the angles when b nears +-90 degrees
    /// (see [`Tree::rebase`]).
    base: Mat3,
}

/// The elastic coordinates of a deformable body in p.
#[derive(Clone, Copy, Debug)]
struct ElasticBlock {
    body: usize,
    /// First index in p.
    first: usize,
    count: usize,
}

/// A joint coordinate prescribed by a driver: p = sign f(t).
#[derive(Clone, Copy, Debug)]
struct Prescribed {
    coordinate: usize,
    driver: usize,
    sign: f64,
}

/// The body state of a tree at given joint coordinates (see [`Tree::evaluate`]).
#[derive(Clone, Debug)]
pub struct TreeState {
    /// Body coordinates q.
    pub coordinates: Vec<f64>,
    /// Body velocities q_dot.
    pub velocities: Vec<f64>,
    /// q_dd with the free joint and elastic accelerations zero: the velocity-quadratic terms
    /// and the prescribed joint accelerations.
    pub gamma: Vec<f64>,
    /// Velocity influence coefficients of the free coordinates (n x free).
    pub influence: Mat<f64>,
}

/// The body state of a tree with the influence coefficients of seed eq. 33 in factored form
/// (see [`Tree::structured`]).
#[derive(Clone, Debug)]
pub struct StructuredState {
    /// Body coordinates q.
    pub coordinates: Vec<f64>,
    /// Body velocities q_dot.
    pub velocities: Vec<f64>,
    /// q_dd at zero free accelerations (gamma_r on the reference rows, zero on the elastic).
    pub gamma: Vec<f64>,
    /// H_pp: the reference rows' influence coefficients of the free joint coordinates
    /// (reference rows x free joint coordinates).
    pub joint_influence: Mat<f64>,
    /// Per deformed joint marker m, D_m = dq_r/d(u - u0, theta) (reference rows x 6), so that
    /// H_pf = sum_m D_m S_m over the markers' shape matrices S_m = [S_u; S_t].
    pub markers: Vec<Mat<f64>>,
}

/// An open tree of rigid and deformable bodies in joint and elastic coordinates.
#[derive(Clone, Debug)]
pub struct Tree {
    joints: Vec<TreeJoint>,
    prescribed: Vec<Prescribed>,
    /// The free (integrated) coordinates, in p's order: joint coordinates, then elastic ones.
    free: Vec<usize>,
    /// Joints cut to open the loops (and drivers on other markers than a tree joint's), and
    /// their constraint rows, which the joint coordinates must satisfy.
    pub cut_joints: Vec<usize>,
    /// Constraint rows of the cut joints.
    pub cut_rows: Vec<usize>,
    /// First coordinate index of each body in q.
    offsets: Vec<usize>,
    /// Euler parameters of each body at the start: the sign of the parameters computed from
    /// rotation matrices follows them.
    reference_parameters: Vec<[f64; 4]>,
    /// Elastic coordinates of the deformable bodies, after the joint coordinates in p.
    elastic: Vec<ElasticBlock>,
    /// Number of joint coordinates (prescribed ones included).
    joint_coordinate_count: usize,
    /// Whether each body is a point mass (3 coordinates, no orientation).
    point_masses: Vec<bool>,
    /// q indices of the bodies' reference coordinates.
    reference_rows: Vec<usize>,
    coordinate_count: usize,
}

fn rot(axis: usize, angle: HyperDual) -> HMat {
    let (s, c) = (angle.sin(), angle.cos());
    let (o, z) = (HyperDual::ONE, HyperDual::ZERO);
    match axis {
        0 => [[o, z, z], [z, c, -s], [z, s, c]],
        1 => [[c, z, s], [z, o, z], [-s, z, c]],
        _ => [[c, -s, z], [s, c, z], [z, z, o]],
    }
}

/// The unit vector v in the plane of x and y with (x . v, y . v) a positive multiple of
/// (cos phi, sin phi): the direction an angle driver prescribes when x and y are the
/// (deformed, not exactly orthonormal) axes of its marker i. For orthonormal x, y it is
/// cos phi x + sin phi y.
fn driver_direction(x: &HVec, y: &HVec, phi: HyperDual) -> HVec {
    let (c, s) = (phi.cos(), phi.sin());
    let (g11, g12, g22) = (dot(x, x), dot(x, y), dot(y, y));
    let alpha = g22 * c - g12 * s;
    let beta = g11 * s - g12 * c;
    normalize(&add(&scale(x, alpha), &scale(y, beta)))
}

/// The orthonormal frame [w, z x w, z] with z along `z` and w along the part of `x`
/// perpendicular to it.
fn frame_from_z(z: &HVec, x: &HVec) -> HMat {
    let z = normalize(z);
    let w = normalize(&sub(x, &scale(&z, dot(x, &z))));
    from_columns(&w, &cross(&z, &w), &z)
}

/// The orthonormal frame [v, n x v, n] with n along x x y and v the driver direction of phi.
fn frame_from_plane(x: &HVec, y: &HVec, phi: HyperDual) -> HMat {
    let n = normalize(&cross(x, y));
    let v = driver_direction(x, y, phi);
    from_columns(&v, &cross(&n, &v), &n)
}

/// Orthonormal frames P (global, parent side) and Q (child body frame) with A_child Q = P
/// that satisfy a revolute joint's equations (x_i . z_j = 0, y_i . z_j = 0) and its angle (the
/// driver's) exactly, also for the deformed, not exactly orthonormal axes of markers on
/// deformable bodies. `x_p`: the parent-side marker's global axes; `xb_c`: the child-side
/// marker's axes in the child body frame; `i_parent`: whether marker i is the parent side.
fn revolute_frames(i_parent: bool, x_p: &HMat, xb_c: &HMat, phi: HyperDual) -> (HMat, HMat) {
    if i_parent {
        (
            frame_from_plane(&column(x_p, 0), &column(x_p, 1), phi),
            frame_from_z(&column(xb_c, 2), &column(xb_c, 0)),
        )
    } else {
        (
            frame_from_z(&column(x_p, 2), &column(x_p, 0)),
            frame_from_plane(&column(xb_c, 0), &column(xb_c, 1), phi),
        )
    }
}

/// The revolute's frames with the angle about the common axis fixed by the twist equation
/// x_i . y_j = 0 instead of a coordinate (exact for deformed axes too): fixed and prismatic
/// joints.
fn fixed_frames(i_parent: bool, x_p: &HMat, xb_c: &HMat) -> (HMat, HMat) {
    if i_parent {
        let (x_i, y_i) = (column(x_p, 0), column(x_p, 1));
        let n = normalize(&cross(&x_i, &y_i));
        let e1 = normalize(&x_i);
        let e2 = cross(&n, &e1);
        let q_frame = frame_from_z(&column(xb_c, 2), &column(xb_c, 0));
        let y_j = column(xb_c, 1);
        let (w1, w2) = (dot(&column(&q_frame, 0), &y_j), dot(&column(&q_frame, 1), &y_j));
        let r = (w1 * w1 + w2 * w2).sqrt().recip();
        let v = add(&scale(&e1, w2 * r), &scale(&e2, w1 * r));
        (from_columns(&v, &cross(&n, &v), &n), q_frame)
    } else {
        let z = normalize(&column(x_p, 2));
        let p1 = normalize(&cross(&column(x_p, 1), &z));
        let (x_i, y_i) = (column(xb_c, 0), column(xb_c, 1));
        let n = normalize(&cross(&x_i, &y_i));
        let e1 = normalize(&x_i);
        (from_columns(&p1, &cross(&z, &p1), &z), from_columns(&e1, &cross(&n, &e1), &n))
    }
}

/// The orthonormal frame [x^, z^ x x^, z^] with x^ along `x` and z^ along the part of `z`
/// perpendicular to it.
fn frame_x_first(x: &HVec, z: &HVec) -> HMat {
    let x = normalize(x);
    let z = normalize(&sub(z, &scale(&x, dot(z, &x))));
    from_columns(&x, &cross(&z, &x), &z)
}

/// The orthonormal frame [y^ x z^, y^, z^] with y^ along `y` and z^ along the part of `z`
/// perpendicular to it.
fn frame_y_first(y: &HVec, z: &HVec) -> HMat {
    let y = normalize(y);
    let z = normalize(&sub(z, &scale(&y, dot(z, &y))));
    from_columns(&cross(&y, &z), &y, &z)
}

/// The orthonormal frame [w, z x w, z] of marker axes (f64; see [`frame_from_z`]).
fn orthonormal(axes: &Mat3) -> Mat3 {
    let h = hmat(axes.0);
    Mat3(crate::math::hyper_dual::values(&frame_from_z(&column(&h, 2), &column(&h, 0))))
}

/// Cardan angles (a, b, c) of R = R_x(a) R_y(b) R_z(c).
fn cardan_angles(r: &Mat3) -> Vec<f64> {
    let m = &r.0;
    vec![
        (-m[1][2]).atan2(m[2][2]),
        m[0][2].atan2((m[0][0] * m[0][0] + m[0][1] * m[0][1]).sqrt()),
        (-m[0][1]).atan2(m[0][0]),
    ]
}

/// R_x(a) R_y(b) R_z(c).
fn cardan(a: HyperDual, b: HyperDual, c: HyperDual) -> HMat {
    mul_mat(&mul_mat(&rot(0, a), &rot(1, b)), &rot(2, c))
}

impl Side {
    /// The side's marker on `model`'s marker `m`.
    fn new(model: &Model, m: usize) -> Side {
        let marker = &model.markers[m];
        Side {
            body: marker.body.0,
            position: marker.position,
            rotation: marker.rotation,
            elastic: marker.elastic.clone(),
        }
    }

    /// Deformation (u - u0, theta) in the body frame for the body's elastic coordinates q_f.
    fn deformation(&self, qf: &[HyperDual]) -> [HVec; 2] {
        let mut out = [[HyperDual::ZERO; 3]; 2];
        if let Some(e) = &self.elastic {
            for (j, &idx) in e.indices.iter().enumerate() {
                for i in 0..3 {
                    out[0][i] = out[0][i] + qf[idx] * e.translation.get(i, j);
                    out[1][i] = out[1][i] + qf[idx] * e.rotation.get(i, j);
                }
            }
        }
        out
    }

    /// Body-frame position and axes for the deformation `d`.
    fn local_frame(&self, d: &[HVec; 2]) -> (HVec, HMat) {
        if self.elastic.is_none() {
            return (hvec(self.position.0), hmat(self.rotation.0));
        }
        let u = add(&hvec(self.position.0), &d[0]);
        let a = hmat(self.rotation.0);
        let cols: [HVec; 3] = std::array::from_fn(|k| {
            let c = column(&a, k);
            add(&c, &cross(&d[1], &c))
        });
        (u, from_columns(&cols[0], &cols[1], &cols[2]))
    }
}

/// The state of the bodies as hyper-dual numbers: rotation matrix and origin.
type Pose = (HMat, HVec);

impl Tree {
    /// The tree of `model`, with the joint and elastic coordinates of the model's
    /// configuration `q` (which must satisfy the joints). Errors name the body or joint the
    /// tree cannot take. `cut`: the joints to cut (loop closures); None cuts every joint that
    /// closes a loop or is not a tree joint type, a list makes any other such joint an error.
    pub fn new(model: &Model, q: &[f64], cut: Option<&[usize]>) -> Result<(Tree, Vec<f64>)> {
        let bad = |item: String, message: String| Err(FlexmbdError::InvalidModel { item, message });
        let nb = model.bodies.len();
        let mut designated = vec![false; model.joints.len()];
        for &k in cut.unwrap_or(&[]) {
            if k >= model.joints.len() {
                return Err(FlexmbdError::InvalidParameter {
                    item: format!("cut joint {k}"),
                    message: format!("the model has {} joints and drivers", model.joints.len()),
                });
            }
            designated[k] = true;
        }
        let point = |b: usize| matches!(model.bodies[b].kind, BodyKind::PointMass { .. });
        let mut reached = vec![false; nb];
        reached[0] = true;
        let mut order: Vec<Link> = Vec::new();
        let mut used = vec![false; model.joints.len()];
        let tree_kind = |k: &JointKind| {
            matches!(
                k,
                JointKind::Revolute
                    | JointKind::Prismatic
                    | JointKind::Cylindrical
                    | JointKind::Fixed
                    | JointKind::Universal
                    | JointKind::Spherical
            )
        };
        loop {
            let mut progress = false;
            for (k, joint) in model.joints.iter().enumerate() {
                if used[k] || designated[k] || !tree_kind(&joint.kind) {
                    continue;
                }
                let [bi, bj] = joint.markers.map(|m| model.markers[m.0].body.0);
                let i_parent = match (reached[bi], reached[bj]) {
                    // A joint between two bodies of the tree closes a loop: it is cut.
                    (true, true) | (false, false) => continue,
                    (parent_i, _) => parent_i,
                };
                // A point mass has no orientation: it joins the tree only by a spherical joint
                // (other joints to it are cut).
                let child = if i_parent { bj } else { bi };
                if point(child) && !matches!(joint.kind, JointKind::Spherical) {
                    continue;
                }
                used[k] = true;
                reached[bi] = true;
                reached[bj] = true;
                order.push(Link::Joint(k, i_parent));
                progress = true;
            }
            if progress {
                continue;
            }
            // A body the tree joints do not reach floats on a free joint to the ground (its
            // other joints are cut).
            match (1..nb).find(|&b| !reached[b]) {
                Some(b) => {
                    reached[b] = true;
                    order.push(Link::Free(b));
                }
                None => break,
            }
        }
        let offsets: Vec<usize> = model.bodies.iter().map(|b| b.offset).collect();
        let reference_parameters: Vec<[f64; 4]> = model
            .bodies
            .iter()
            .map(|b| match b.kind {
                BodyKind::Ground | BodyKind::PointMass { .. } => [1.0, 0.0, 0.0, 0.0],
                _ => [q[b.offset + 3], q[b.offset + 4], q[b.offset + 5], q[b.offset + 6]],
            })
            .collect();
        let pose = |body: usize| -> (Mat3, Vec3) {
            if body == 0 {
                (Mat3::IDENTITY, Vec3::ZERO)
            } else if point(body) {
                let o = offsets[body];
                (Mat3::IDENTITY, Vec3([q[o], q[o + 1], q[o + 2]]))
            } else {
                let o = offsets[body];
                (rotation_matrix(&reference_parameters[body]), Vec3([q[o], q[o + 1], q[o + 2]]))
            }
        };
        // The marker frame of a side in the current configuration (deformed axes).
        let marker_frame = |side: &Side| -> (Mat3, Vec3) {
            let (a, r) = pose(side.body);
            let qf: Vec<HyperDual> = match &model.bodies[side.body].kind {
                BodyKind::Flexible(f) => {
                    let o = offsets[side.body] + 7;
                    q[o..o + f.elastic_count].iter().map(|&x| HyperDual::constant(x)).collect()
                }
                _ => Vec::new(),
            };
            let (u, axes) = side.local_frame(&side.deformation(&qf));
            let axes = Mat3(crate::math::hyper_dual::values(&axes));
            let u = Vec3(u.map(|x| x.v));
            (a.mul_mat(&axes), r + a.mul_vec(&u))
        };
        let mut joints = Vec::new();
        let mut names: Vec<String> = Vec::new();
        let mut p0 = Vec::new();
        let mut tree_markers = Vec::new(); // (marker i, marker j, parent-side marker, child-side marker)
        for link in order {
            let (k, i_parent) = match link {
                Link::Joint(k, i_parent) => (k, i_parent),
                Link::Free(b) => {
                    let side = |body: usize| Side {
                        body,
                        position: Vec3::ZERO,
                        rotation: Mat3::IDENTITY,
                        elastic: None,
                    };
                    let (parent, child) = (side(0), side(b));
                    let first = p0.len();
                    let o = offsets[b];
                    p0.extend_from_slice(&q[o..o + 3]);
                    let kind = if point(b) {
                        TreeJointKind::FreePoint
                    } else {
                        p0.extend(cardan_angles(&pose(b).0));
                        TreeJointKind::Free
                    };
                    let (rotation, axis) = (Mat3::IDENTITY, Vec3::ZERO);
                    joints.push(TreeJoint {
                        kind,
                        first,
                        i_parent: true,
                        parent,
                        child,
                        rotation,
                        axis,
                        deformed: false,
                        base: Mat3::IDENTITY,
                    });
                    tree_markers.push((usize::MAX, usize::MAX, usize::MAX, usize::MAX));
                    names.push(format!("free joint of body '{}'", model.bodies[b].name));
                    continue;
                }
            };
            let joint = &model.joints[k];
            let [mi, mj] = joint.markers.map(|m| m.0);
            let (pid, cid) = if i_parent { (mi, mj) } else { (mj, mi) };
            let (parent, child) = (Side::new(model, pid), Side::new(model, cid));
            let (a_pm, o_pm) = marker_frame(&parent);
            let (a_cm, o_cm) = marker_frame(&child);
            let relative = a_pm.transpose().mul_mat(&a_cm);
            let offset = a_pm.tr_mul_vec(&(o_cm - o_pm));
            // The revolute angle is the one an angle driver on (i, j) measures, whichever side
            // is the parent: atan2(y_i . x_j, x_i . x_j).
            let (a_i, a_j) = if i_parent { (a_pm, a_cm) } else { (a_cm, a_pm) };
            let driver_angle = a_i.column(1).dot(&a_j.column(0)).atan2(a_i.column(0).dot(&a_j.column(0)));
            let angle = relative.0[1][0].atan2(relative.0[0][0]);
            // Translation along z of marker i: +z of the parent-side marker, or -z of the
            // child-side marker expressed in the parent-side frame (the same axis for a
            // cylindrical joint, whose rotation keeps z).
            let axis = if i_parent { Vec3::unit(2) } else { -relative.mul_vec(&Vec3::unit(2)) };
            let deformed = parent.elastic.is_some() || child.elastic.is_some();
            // Translation along z of marker i as a translation driver measures it, z_i . d.
            let driver_translation = {
                let d = if i_parent { o_cm - o_pm } else { o_pm - o_cm };
                a_i.column(2).dot(&d)
            };
            let (kind, values) = match joint.kind {
                JointKind::Revolute => (TreeJointKind::Revolute, vec![driver_angle]),
                JointKind::Prismatic if deformed => (TreeJointKind::Prismatic, vec![driver_translation]),
                JointKind::Cylindrical if deformed => {
                    (TreeJointKind::Cylindrical, vec![driver_angle, driver_translation])
                }
                JointKind::Prismatic => (TreeJointKind::Prismatic, vec![offset.dot(&axis)]),
                JointKind::Cylindrical => (TreeJointKind::Cylindrical, vec![angle, offset.dot(&axis)]),
                JointKind::Universal if deformed => {
                    // The angles between the frames the kinematics use (x_i or y_j first).
                    let h = |m: &Mat3| hmat(m.0);
                    let (x_first, y_first) = (
                        |m: &Mat3| Mat3(values(&frame_x_first(&column(&h(m), 0), &column(&h(m), 2)))),
                        |m: &Mat3| Mat3(values(&frame_y_first(&column(&h(m), 1), &column(&h(m), 2)))),
                    );
                    let r = if i_parent {
                        x_first(&a_pm).transpose().mul_mat(&y_first(&a_cm))
                    } else {
                        y_first(&a_pm).transpose().mul_mat(&x_first(&a_cm))
                    };
                    let r = &r.0;
                    if i_parent {
                        (TreeJointKind::UniversalXY, vec![r[2][1].atan2(r[1][1]), r[0][2].atan2(r[0][0])])
                    } else {
                        (
                            TreeJointKind::UniversalYX,
                            vec![(-r[2][0]).atan2(r[0][0]), (-r[1][2]).atan2(r[1][1])],
                        )
                    }
                }
                JointKind::Universal if i_parent => {
                    // R_x(a) R_y(b): b from the first row, a from the last column's rows.
                    let r = &relative.0;
                    (TreeJointKind::UniversalXY, vec![r[2][1].atan2(r[1][1]), r[0][2].atan2(r[0][0])])
                }
                JointKind::Universal => {
                    // R_y(a) R_x(b).
                    let r = &relative.0;
                    (TreeJointKind::UniversalYX, vec![(-r[2][0]).atan2(r[0][0]), (-r[1][2]).atan2(r[1][1])])
                }
                JointKind::Spherical if point(child.body) => (TreeJointKind::SphericalPoint, vec![]),
                JointKind::Spherical => {
                    // Cardan angles between orthonormal frames built from the markers' axes
                    // (deformed axes are not exactly orthonormal; the joint constrains only the
                    // origins).
                    let relative = orthonormal(&a_pm).transpose().mul_mat(&orthonormal(&a_cm));
                    (TreeJointKind::Spherical, cardan_angles(&relative))
                }
                _ => (TreeJointKind::Fixed, vec![]),
            };
            let first = p0.len();
            p0.extend(values);
            joints.push(TreeJoint {
                kind,
                first,
                i_parent,
                parent,
                child,
                rotation: if kind == TreeJointKind::Fixed { Mat3::IDENTITY } else { relative },
                axis,
                deformed,
                base: Mat3::IDENTITY,
            });
            tree_markers.push((mi, mj, pid, cid));
            names.push(format!("joint '{}' ({})", joint.name, joint.kind.type_name()));
        }
        // Drivers prescribe the coordinate of the tree joint on the same markers.
        let mut prescribed: Vec<Prescribed> = Vec::new();
        for (d, driver) in model.joints.iter().enumerate() {
            if driver.kind.function().is_none() {
                continue;
            }
            let [di, dj] = driver.markers.map(|m| m.0);
            let angle = matches!(driver.kind, JointKind::AngleDriver(_));
            let elastic = driver.markers.iter().any(|m| model.markers[m.0].elastic.is_some());
            let found = joints.iter().zip(&tree_markers).find_map(|(tj, &(i, j, pid, cid))| {
                if tj.deformed && tj.kind != TreeJointKind::Revolute {
                    // The coordinates of these joints are what drivers on (i, j) measure;
                    // reversed drivers measure something else with deformed axes (cut).
                    let slot = match (angle, tj.kind) {
                        (true, TreeJointKind::Cylindrical) | (false, TreeJointKind::Prismatic) => tj.first,
                        (false, TreeJointKind::Cylindrical) => tj.first + 1,
                        _ => return None,
                    };
                    return ((di, dj) == (i, j)).then_some((slot, 1.0));
                }
                let (slot, sign) = match (angle, tj.kind) {
                    // The revolute coordinate is the driver's angle on (i, j); reversed markers
                    // measure minus it only when both frames are orthonormal (rigid).
                    (true, TreeJointKind::Revolute) if (di, dj) == (i, j) => (tj.first, 1.0),
                    (true, TreeJointKind::Revolute) if !elastic => (tj.first, -1.0),
                    (true, TreeJointKind::Cylindrical) => {
                        (tj.first, if (di, dj) == (pid, cid) { 1.0 } else { -1.0 })
                    }
                    (false, TreeJointKind::Prismatic) => {
                        (tj.first, if (di, dj) == (i, j) { 1.0 } else { -1.0 })
                    }
                    (false, TreeJointKind::Cylindrical) => {
                        (tj.first + 1, if (di, dj) == (i, j) { 1.0 } else { -1.0 })
                    }
                    _ => return None,
                };
                let same_pair = (di, dj) == (i, j) || (di, dj) == (j, i);
                same_pair.then_some((slot, sign))
            });
            let Some((coordinate, sign)) = found else {
                // A driver on other markers: a rheonomic constraint cut like a loop joint.
                continue;
            };
            if prescribed.iter().any(|p| p.coordinate == coordinate) {
                return bad(
                    format!("driver '{}'", driver.name),
                    "a second driver on the same joint coordinate".to_string(),
                );
            }
            prescribed.push(Prescribed { coordinate, driver: d, sign });
            used[d] = true;
        }
        // Every other joint or driver closes a loop: its equations are cut constraints.
        let cut_joints: Vec<usize> = (0..model.joints.len()).filter(|&k| !used[k]).collect();
        if cut.is_some() {
            if let Some(&k) =
                cut_joints.iter().find(|&&k| !designated[k] && model.joints[k].kind.function().is_none())
            {
                let joint = &model.joints[k];
                return bad(
                    format!("joint '{}' ({})", joint.name, joint.kind.type_name()),
                    "it closes a loop of the tree (or is of a type the tree does not take) but is \
                     not among the cut joints: add it to them, or leave them unset to cut such \
                     joints automatically"
                        .to_string(),
                );
            }
        }
        let cut_rows: Vec<usize> = cut_joints
            .iter()
            .flat_map(|&k| model.joints[k].row..model.joints[k].row + model.joints[k].equations.len())
            .collect();
        // The elastic coordinates of the deformable bodies follow the joint coordinates.
        let joint_coordinate_count = p0.len();
        let mut elastic = Vec::new();
        for (b, body) in model.bodies.iter().enumerate() {
            if let BodyKind::Flexible(f) = &body.kind {
                let o = body.offset + 7;
                elastic.push(ElasticBlock { body: b, first: p0.len(), count: f.elastic_count });
                p0.extend_from_slice(&q[o..o + f.elastic_count]);
            }
        }
        let coordinate_count = p0.len();
        let free: Vec<usize> =
            (0..coordinate_count).filter(|c| prescribed.iter().all(|p| p.coordinate != *c)).collect();
        let full_p0 = p0.clone();
        let p0: Vec<f64> = free.iter().map(|&c| p0[c]).collect();
        let reference_rows: Vec<usize> = (1..nb)
            .flat_map(|b| {
                let o = offsets[b];
                o..o + if point(b) { 3 } else { 7 }
            })
            .collect();
        let tree = Tree {
            reference_rows,
            point_masses: (0..nb).map(point).collect(),
            coordinate_count,
            joint_coordinate_count,
            joints,
            prescribed,
            free,
            cut_joints,
            cut_rows,
            offsets,
            reference_parameters,
            elastic,
        };
        // The tree must reproduce the model's configuration: a joint whose markers are not
        // aligned as its type assumes (a prismatic joint with opposite z axes, say) would
        // otherwise move a body silently.
        let (q_tree, _, _) = tree.state(model.coordinate_count, &full_p0, &vec![0.0; full_p0.len()]);
        for (joint, name) in tree.joints.iter().zip(&names) {
            let b = joint.child.body;
            let o = tree.offsets[b];
            let position = (0..3).map(|k| (q_tree[o + k] - q[o + k]).abs()).fold(0.0, f64::max);
            let rotation = if point(b) {
                0.0
            } else {
                let diff = |sign: f64| {
                    (0..4).map(|k| (q_tree[o + 3 + k] - sign * q[o + 3 + k]).abs()).fold(0.0, f64::max)
                };
                diff(1.0).min(diff(-1.0))
            };
            let scale = 1.0 + (0..3).map(|k| q[o + k].abs()).fold(0.0, f64::max);
            if position > 1e-8 * scale || rotation > 1e-8 {
                return bad(
                    name.clone(),
                    format!(
                        "the joint-coordinate tree places body '{}' {position:.3e} m and {rotation:.3e} (Euler \
                         parameters) away from the model's configuration: the joint's markers are not aligned \
                         as its type assumes (for example opposite z axes)",
                        model.bodies[b].name
                    ),
                );
            }
        }
        Ok((tree, p0))
    }

    /// Number of coordinates: joint coordinates (prescribed ones included) and elastic ones.
    pub fn coordinate_count(&self) -> usize {
        self.coordinate_count
    }

    /// Number of joint coordinates (prescribed ones included).
    pub fn joint_coordinate_count(&self) -> usize {
        self.joint_coordinate_count
    }

    /// Number of free (integrated) coordinates.
    pub fn free_count(&self) -> usize {
        self.free.len()
    }

    /// The body state at time `time` for the free coordinates `p` and rates `pd`, the
    /// prescribed ones from their drivers.
    pub fn evaluate(&self, model: &Model, time: f64, p: &[f64], pd: &[f64]) -> Result<TreeState> {
        let n = model.coordinate_count;
        let (full_p, full_pd, pdd) = self.full_coordinates(model, time, p, pd)?;
        let (coordinates, velocities, gamma) = self.state_with(n, &full_p, &full_pd, &pdd);
        let influence = self.influence_columns(n, &full_p, &self.free);
        Ok(TreeState { coordinates, velocities, gamma, influence })
    }

    /// The body state at time `time` for the free coordinates `p` and rates `pd`, with the
    /// influence coefficients in the structure of seed eq. 33 instead of a dense B: H_pp over
    /// the reference rows and, for H_pf, the derivatives of the reference coordinates with
    /// respect to each deformed joint marker's deformation (H_pf = sum over the markers of
    /// D_m S_m). Its cost does not depend on the number of elastic coordinates.
    pub fn structured(&self, model: &Model, time: f64, p: &[f64], pd: &[f64]) -> Result<StructuredState> {
        let n = model.coordinate_count;
        let (full_p, full_pd, pdd) = self.full_coordinates(model, time, p, pd)?;
        let (coordinates, velocities, gamma) = self.state_with(n, &full_p, &full_pd, &pdd);
        let free_joints: Vec<usize> =
            self.free.iter().copied().filter(|&c| c < self.joint_coordinate_count).collect();
        let joints = self.joint_columns(n, &full_p, &free_joints);
        let rows = &self.reference_rows;
        let joint_influence = Mat::from_fn(rows.len(), free_joints.len(), |i, k| joints[(rows[i], k)]);
        let markers = self
            .marker_derivatives(n, &full_p)
            .into_iter()
            .map(|d| Mat::from_fn(rows.len(), 6, |i, c| d[(rows[i], c)]))
            .collect();
        Ok(StructuredState { coordinates, velocities, gamma, joint_influence, markers })
    }

    /// Spherical and free joints whose Cardan angle b is beyond `limit` (rad) from zero, near
    /// the singularity at +-90 degrees, are rebased: R_0 absorbs the current angles, which
    /// restart at zero, and the angle rates are transformed so that the relative angular
    /// velocity is unchanged (theta_dot' = R^T E(a, b) theta_dot, E the map from the Cardan
    /// rates to the angular velocity in the parent-side frame). The body state does not change.
    /// `p` and `pd` are the free coordinates and rates; returns the rebased joints' names.
    pub fn rebase(&mut self, model: &Model, p: &mut [f64], pd: &mut [f64], limit: f64) -> Vec<String> {
        let mut rebased = Vec::new();
        let position = |c: usize, free: &[usize]| free.iter().position(|&x| x == c);
        for joint in self.joints.iter_mut() {
            let angles = match joint.kind {
                TreeJointKind::Spherical => joint.first,
                TreeJointKind::Free => joint.first + 3,
                _ => continue,
            };
            let Some(k) = position(angles, &self.free) else { continue };
            let (a, b, c) = (p[k], p[k + 1], p[k + 2]);
            if b.abs() <= limit {
                continue;
            }
            let h = |x: f64| HyperDual::constant(x);
            let r = Mat3(values(&cardan(h(a), h(b), h(c))));
            // E(a, b): columns e_x, R_x(a) e_y, R_x(a) R_y(b) e_z.
            let rx = Mat3(values(&rot(0, h(a))));
            let rxy = rx.mul_mat(&Mat3(values(&rot(1, h(b)))));
            let omega = Vec3::unit(0) * pd[k] + rx.column(1) * pd[k + 1] + rxy.column(2) * pd[k + 2];
            let rates = r.tr_mul_vec(&omega);
            joint.base = joint.base.mul_mat(&r);
            for i in 0..3 {
                p[k + i] = 0.0;
                pd[k + i] = rates[i];
            }
            let body = &model.bodies[joint.child.body].name;
            rebased.push(if joint.kind == TreeJointKind::Free {
                format!("free joint of body '{body}'")
            } else {
                format!("spherical joint of body '{body}'")
            });
        }
        rebased
    }

    /// The free rates p_dot whose body velocities are `qd` (which must be consistent with the
    /// tree joints and drivers at `time`): the elastic rates are entries of q_dot; the joint
    /// rates solve H_pp p_dot_j = q_dot_r - H_pf qf_dot - (the prescribed part), a
    /// least-squares problem of the reference rows' size.
    pub fn initial_rates(&self, model: &Model, time: f64, p: &[f64], qd: &[f64]) -> Result<Vec<f64>> {
        let st = self.structured(model, time, p, &vec![0.0; p.len()])?;
        let nj = self.free_joint_count();
        let mut pd = vec![0.0; p.len()];
        for (body, first, count) in self.elastic_blocks() {
            let o = self.offsets[body] + 7;
            pd[first..first + count].copy_from_slice(&qd[o..o + count]);
        }
        let rows = &self.reference_rows;
        let mut rhs: Vec<f64> = rows.iter().map(|&r| qd[r] - st.velocities[r]).collect();
        for ((body, shape), d) in self.deformed_markers().into_iter().zip(&st.markers) {
            let o = self.offsets[body] + 7;
            let mut rate = [0.0; 6];
            for (j, &idx) in shape.indices.iter().enumerate() {
                for c in 0..3 {
                    rate[c] += shape.translation.get(c, j) * qd[o + idx];
                    rate[3 + c] += shape.rotation.get(c, j) * qd[o + idx];
                }
            }
            for (i, value) in rhs.iter_mut().enumerate() {
                *value -= (0..6).map(|c| d[(i, c)] * rate[c]).sum::<f64>();
            }
        }
        let joints = crate::linalg::partition::minimum_norm_solve(st.joint_influence.as_ref(), &rhs, 1e-12);
        pd[..nj].copy_from_slice(&joints);
        Ok(pd)
    }

    /// The q indices of the bodies' reference coordinates (the rows r of seed eq. 33), in body
    /// order.
    pub fn reference_rows(&self) -> &[usize] {
        &self.reference_rows
    }

    /// Number of free joint coordinates (the free coordinates start with them; the elastic
    /// coordinates follow).
    pub fn free_joint_count(&self) -> usize {
        self.free.iter().filter(|&&c| c < self.joint_coordinate_count).count()
    }

    /// The deformable bodies: (body, index of its first elastic coordinate among the free
    /// coordinates, count).
    pub fn elastic_blocks(&self) -> Vec<(usize, usize, usize)> {
        let shift = self.free_joint_count();
        self.elastic
            .iter()
            .map(|e| (e.body, shift + e.first - self.joint_coordinate_count, e.count))
            .collect()
    }

    /// The deformed joint markers (the order of [`StructuredState::markers`]): body and shape.
    pub fn deformed_markers(&self) -> Vec<(usize, &MarkerElastic)> {
        self.joints
            .iter()
            .flat_map(|j| [&j.parent, &j.child])
            .filter_map(|side| side.elastic.as_ref().map(|e| (side.body, e)))
            .collect()
    }

    /// Full p, p_dot and the prescribed p_dd from the free coordinates and the drivers.
    fn full_coordinates(
        &self,
        model: &Model,
        time: f64,
        p: &[f64],
        pd: &[f64],
    ) -> Result<(Vec<f64>, Vec<f64>, Vec<f64>)> {
        let np = self.coordinate_count;
        let (mut full_p, mut full_pd, mut pdd) = (vec![0.0; np], vec![0.0; np], vec![0.0; np]);
        for (k, &c) in self.free.iter().enumerate() {
            full_p[c] = p[k];
            full_pd[c] = pd[k];
        }
        for presc in &self.prescribed {
            let [f, fd, fdd] = model.joints[presc.driver].driver_values(time)?;
            full_p[presc.coordinate] = presc.sign * f;
            full_pd[presc.coordinate] = presc.sign * fd;
            pdd[presc.coordinate] = presc.sign * fdd;
        }
        Ok((full_p, full_pd, pdd))
    }

    /// Poses of all bodies for the joint coordinates `p` (hyper-dual) and the deformation of
    /// each joint's markers (`deformation[joint] = [parent side, child side]`).
    fn poses(&self, p: &[HyperDual], deformation: &[[[HVec; 2]; 2]]) -> Vec<Pose> {
        let mut poses: Vec<Pose> = vec![(HIDENTITY, [HyperDual::ZERO; 3]); self.offsets.len()];
        for (joint, d) in self.joints.iter().zip(deformation) {
            let (a_p, r_p) = poses[joint.parent.body];
            let (u_p, xb_p) = joint.parent.local_frame(&d[0]);
            let (u_c, xb_c) = joint.child.local_frame(&d[1]);
            let x_p = mul_mat(&a_p, &xb_p);
            let o_p = add(&r_p, &mul_vec(&a_p, &u_p));
            let f = joint.first;
            let (rotation, o_c) = match joint.kind {
                // Undeformed markers are orthonormal: the frames below reduce to these.
                TreeJointKind::Revolute if !joint.deformed => {
                    let angle = if joint.i_parent { p[f] } else { -p[f] };
                    (mul_transpose(&mul_mat(&x_p, &rot(2, angle)), &xb_c), o_p)
                }
                TreeJointKind::Fixed if !joint.deformed => (mul_transpose(&x_p, &xb_c), o_p),
                TreeJointKind::Revolute => {
                    let (p_frame, q_frame) = revolute_frames(joint.i_parent, &x_p, &xb_c, p[f]);
                    (mul_transpose(&p_frame, &q_frame), o_p)
                }
                TreeJointKind::Fixed => {
                    let (p_frame, q_frame) = fixed_frames(joint.i_parent, &x_p, &xb_c);
                    (mul_transpose(&p_frame, &q_frame), o_p)
                }
                TreeJointKind::Prismatic | TreeJointKind::Cylindrical if joint.deformed => {
                    // Orientation: the fixed joint's frames (prismatic) or the revolute's
                    // (cylindrical); translation along the normal n of the plane of x_i, y_i
                    // (d . x_i = 0, d . y_i = 0) with z_i . d equal to the coordinate.
                    let (p_frame, q_frame) = if joint.kind == TreeJointKind::Prismatic {
                        fixed_frames(joint.i_parent, &x_p, &xb_c)
                    } else {
                        revolute_frames(joint.i_parent, &x_p, &xb_c, p[f])
                    };
                    let s = p[if joint.kind == TreeJointKind::Prismatic { f } else { f + 1 }];
                    let origin = if joint.i_parent {
                        let n = normalize(&cross(&column(&x_p, 0), &column(&x_p, 1)));
                        add(&o_p, &scale(&n, s / dot(&column(&x_p, 2), &n)))
                    } else {
                        // d = r_j - r_i along A_child n_bar = z_j (unit).
                        let n = normalize(&cross(&column(&xb_c, 0), &column(&xb_c, 1)));
                        let z = normalize(&column(&x_p, 2));
                        sub(&o_p, &scale(&z, s / dot(&column(&xb_c, 2), &n)))
                    };
                    (mul_transpose(&p_frame, &q_frame), origin)
                }
                TreeJointKind::Spherical | TreeJointKind::Free => {
                    let p_frame = frame_from_z(&column(&x_p, 2), &column(&x_p, 0));
                    let q_frame = frame_from_z(&column(&xb_c, 2), &column(&xb_c, 0));
                    let (angles, origin) = if joint.kind == TreeJointKind::Free {
                        (f + 3, add(&o_p, &mul_vec(&p_frame, &[p[f], p[f + 1], p[f + 2]])))
                    } else {
                        (f, o_p)
                    };
                    let relative =
                        mul_mat(&hmat(joint.base.0), &cardan(p[angles], p[angles + 1], p[angles + 2]));
                    (mul_transpose(&mul_mat(&p_frame, &relative), &q_frame), origin)
                }
                TreeJointKind::UniversalXY | TreeJointKind::UniversalYX if joint.deformed => {
                    // Orthonormal frames keeping the cross axes exactly: x_i first on the side of
                    // marker i, y_j first on the side of marker j; then F = P R_x(a) R_y(b)
                    // (marker i the parent) keeps F's y perpendicular to x_i, and
                    // F = P R_y(a) R_x(b) (marker j the parent) keeps F's x perpendicular to y_j.
                    let (x_first, y_first) = (
                        |m: &HMat| frame_x_first(&column(m, 0), &column(m, 2)),
                        |m: &HMat| frame_y_first(&column(m, 1), &column(m, 2)),
                    );
                    let (p_frame, relative, q_frame) = if joint.kind == TreeJointKind::UniversalXY {
                        (x_first(&x_p), mul_mat(&rot(0, p[f]), &rot(1, p[f + 1])), y_first(&xb_c))
                    } else {
                        (y_first(&x_p), mul_mat(&rot(1, p[f]), &rot(0, p[f + 1])), x_first(&xb_c))
                    };
                    (mul_transpose(&mul_mat(&p_frame, &relative), &q_frame), o_p)
                }
                TreeJointKind::SphericalPoint => (HIDENTITY, o_p),
                TreeJointKind::FreePoint => (HIDENTITY, add(&o_p, &[p[f], p[f + 1], p[f + 2]])),
                kind => {
                    // Rigid markers: the child marker frame A_pm R_rel, moved along the axis.
                    let axis = mul_vec(&x_p, &hvec(joint.axis.0));
                    let (relative, translation) = match kind {
                        TreeJointKind::Prismatic => (hmat(joint.rotation.0), scale(&axis, p[f])),
                        TreeJointKind::Cylindrical => (rot(2, p[f]), scale(&axis, p[f + 1])),
                        TreeJointKind::UniversalXY => {
                            (mul_mat(&rot(0, p[f]), &rot(1, p[f + 1])), hvec([0.0; 3]))
                        }
                        TreeJointKind::UniversalYX => {
                            (mul_mat(&rot(1, p[f]), &rot(0, p[f + 1])), hvec([0.0; 3]))
                        }
                        _ => (HIDENTITY, hvec([0.0; 3])),
                    };
                    (mul_transpose(&mul_mat(&x_p, &relative), &xb_c), add(&o_p, &translation))
                }
            };
            let origin = sub(&o_c, &mul_vec(&rotation, &u_c));
            poses[joint.child.body] = (rotation, origin);
        }
        poses
    }

    /// Reference coordinates (origin, Euler parameters) of every body as hyper-dual numbers,
    /// in q's layout (the elastic entries are left zero).
    fn reference_coordinates(
        &self,
        n: usize,
        p: &[HyperDual],
        deformation: &[[[HVec; 2]; 2]],
    ) -> Vec<HyperDual> {
        let poses = self.poses(p, deformation);
        let mut q = vec![HyperDual::ZERO; n];
        for (b, (a, r)) in poses.iter().enumerate().skip(1) {
            let o = self.offsets[b];
            q[o..o + 3].copy_from_slice(r);
            if !self.point_masses[b] {
                q[o + 3..o + 7].copy_from_slice(&euler_parameters(a, &self.reference_parameters[b]));
            }
        }
        q
    }

    /// The marker deformations of every joint for elastic coordinates given per p index.
    fn deformations(&self, p: &[HyperDual]) -> Vec<[[HVec; 2]; 2]> {
        let qf = |body: usize| -> &[HyperDual] {
            match self.elastic.iter().find(|e| e.body == body) {
                Some(e) => &p[e.first..e.first + e.count],
                None => &[],
            }
        };
        self.joints
            .iter()
            .map(|j| [j.parent.deformation(qf(j.parent.body)), j.child.deformation(qf(j.child.body))])
            .collect()
    }

    /// Body coordinates q, velocities q_dot and accelerations q_dd at (p, p_dot, p_dd), all of
    /// length `n` (the model's coordinate count), with the elastic accelerations in p_dd taken
    /// zero: q_dd = gamma_B + B p_dd over the joint coordinates.
    fn state_with(&self, n: usize, p: &[f64], pd: &[f64], pdd: &[f64]) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let ph: Vec<HyperDual> = (0..p.len())
            .map(|k| {
                HyperDual::curve(p[k], pd[k], if k < self.joint_coordinate_count { pdd[k] } else { 0.0 })
            })
            .collect();
        let deformation = self.deformations(&ph);
        let qh = self.reference_coordinates(n, &ph, &deformation);
        let (mut q, mut qd, mut gamma): (Vec<f64>, Vec<f64>, Vec<f64>) = (
            qh.iter().map(|x| x.v).collect(),
            qh.iter().map(|x| x.e1).collect(),
            qh.iter().map(|x| x.e12).collect(),
        );
        for e in &self.elastic {
            let o = self.offsets[e.body] + 7;
            q[o..o + e.count].copy_from_slice(&p[e.first..e.first + e.count]);
            qd[o..o + e.count].copy_from_slice(&pd[e.first..e.first + e.count]);
            gamma[o..o + e.count].iter_mut().for_each(|g| *g = 0.0);
        }
        (q, qd, gamma)
    }

    /// Body coordinates q, velocities q_dot = B p_dot and gamma_B = B_dot p_dot at (p, p_dot),
    /// all of length `n` (the model's coordinate count).
    pub fn state(&self, n: usize, p: &[f64], pd: &[f64]) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        self.state_with(n, p, pd, &vec![0.0; p.len()])
    }

    /// The velocity influence coefficients B = dq/dp (n x coordinate_count) at p.
    pub fn influence(&self, n: usize, p: &[f64]) -> Mat<f64> {
        let all: Vec<usize> = (0..self.coordinate_count).collect();
        self.influence_columns(n, p, &all)
    }

    /// The columns `columns` of B at p. A joint coordinate's column takes one pass of the
    /// kinematics; the elastic coordinates act through the six deformation components of the
    /// joint markers on their body (one pass each), then through the markers' shape matrices:
    /// the identity on the body's own elastic coordinates, and dq_r/d(u, theta) S on the
    /// reference coordinates of the bodies beyond (the matrix H_pf of seed eq. 33).
    fn influence_columns(&self, n: usize, p: &[f64], columns: &[usize]) -> Mat<f64> {
        let mut b = Mat::zeros(n, columns.len());
        let njc = self.joint_coordinate_count;
        let joint_columns: Vec<usize> = columns.iter().copied().filter(|&k| k < njc).collect();
        let joints = self.joint_columns(n, p, &joint_columns);
        let mut column_of = vec![usize::MAX; self.coordinate_count];
        for (col, &k) in columns.iter().enumerate() {
            column_of[k] = col;
        }
        for (a, &k) in joint_columns.iter().enumerate() {
            for i in 0..n {
                b[(i, column_of[k])] = joints[(i, a)];
            }
        }
        for e in &self.elastic {
            for k in 0..e.count {
                let col = column_of[e.first + k];
                if col != usize::MAX {
                    b[(self.offsets[e.body] + 7 + k, col)] = 1.0;
                }
            }
        }
        // Elastic columns through each deformed joint marker: D_m S_m.
        for ((body, shape), d) in self.deformed_markers().into_iter().zip(self.marker_derivatives(n, p)) {
            let block = self.elastic.iter().find(|e| e.body == body).expect("a deformable body");
            for c in 0..6 {
                let s = if c < 3 { &shape.translation } else { &shape.rotation };
                for (j, &idx) in shape.indices.iter().enumerate() {
                    let (col, w) = (column_of[block.first + idx], s.get(c % 3, j));
                    if col == usize::MAX || w == 0.0 {
                        continue;
                    }
                    for i in 0..n {
                        b[(i, col)] += w * d[(i, c)];
                    }
                }
            }
        }
        b
    }

    /// dq/dp_k (n rows) for the joint coordinates `columns` at p: one pass each.
    fn joint_columns(&self, n: usize, p: &[f64], columns: &[usize]) -> Mat<f64> {
        let mut b = Mat::zeros(n, columns.len());
        let mut ph: Vec<HyperDual> = p.iter().map(|&x| HyperDual::constant(x)).collect();
        let deformation = self.deformations(&ph);
        for (col, &k) in columns.iter().enumerate() {
            ph[k] = HyperDual::curve(p[k], 1.0, 0.0);
            let q = self.reference_coordinates(n, &ph, &deformation);
            ph[k] = HyperDual::constant(p[k]);
            for (i, x) in q.iter().enumerate() {
                b[(i, col)] = x.e1;
            }
        }
        b
    }

    /// For each deformed joint marker (in the order of [`Tree::deformed_markers`]), the
    /// derivatives of q (n rows) with respect to its deformation (u - u0, theta) in the body
    /// frame (6 columns): one pass each.
    fn marker_derivatives(&self, n: usize, p: &[f64]) -> Vec<Mat<f64>> {
        let ph: Vec<HyperDual> = p.iter().map(|&x| HyperDual::constant(x)).collect();
        let deformation = self.deformations(&ph);
        let mut out = Vec::new();
        for (jk, joint) in self.joints.iter().enumerate() {
            for (s, side) in [&joint.parent, &joint.child].into_iter().enumerate() {
                if side.elastic.is_none() {
                    continue;
                }
                let mut d = Mat::zeros(n, 6);
                for c in 0..6 {
                    let mut def = deformation.clone();
                    let x = &mut def[jk][s][c / 3][c % 3];
                    *x = HyperDual::curve(x.v, 1.0, 0.0);
                    let q = self.reference_coordinates(n, &ph, &def);
                    for (i, x) in q.iter().enumerate() {
                        d[(i, c)] = x.e1;
                    }
                }
                out.push(d);
            }
        }
        out
    }
}

/// Joint accelerations from (B^T M B) p_dd = B^T (f - M gamma_B), given M and f of the
/// model at the tree's state (q, B p_dot).
pub fn joint_accelerations(b: &Mat<f64>, mass: &Mat<f64>, force: &[f64], gamma: &[f64]) -> Result<Vec<f64>> {
    let (reduced_mass, reduced_force) = joint_space(b, mass, force, gamma);
    let llt = reduced_mass.llt(faer::Side::Lower).map_err(|_| FlexmbdError::SingularMatrix {
        time: f64::NAN,
        context: "joint-space mass matrix B^T M B".to_string(),
        detail: "not positive definite".to_string(),
    })?;
    let mut rhs = Mat::from_fn(reduced_force.len(), 1, |k, _| reduced_force[k]);
    faer::linalg::solvers::Solve::solve_in_place(&llt, &mut rhs);
    Ok((0..b.ncols()).map(|k| rhs[(k, 0)]).collect())
}

/// The equations of motion projected on B: (B^T M B, B^T (f - M gamma)).
fn joint_space(b: &Mat<f64>, mass: &Mat<f64>, force: &[f64], gamma: &[f64]) -> (Mat<f64>, Vec<f64>) {
    let n = force.len();
    let reduced_mass = b.transpose() * (mass * b);
    let rhs_full = Mat::from_fn(n, 1, |i, _| force[i] - (0..n).map(|j| mass[(i, j)] * gamma[j]).sum::<f64>());
    let rhs = b.transpose() * &rhs_full;
    (reduced_mass, (0..b.ncols()).map(|k| rhs[(k, 0)]).collect())
}

/// Joint accelerations with cut-joint constraints: (B^T M B) p_dd + C_hat^T mu =
/// B^T (f - M gamma_B), C_hat p_dd = g_hat, with C_hat = C_cut B and g_hat = gamma_cut -
/// C_cut gamma_B, by the null-space method ([`null_space_solve`]; singular values below
/// `cutoff` of the largest treated as zero: redundant cut equations and singular
/// configurations).
pub fn constrained_joint_accelerations(
    b: &Mat<f64>,
    mass: &Mat<f64>,
    force: &[f64],
    gamma_b: &[f64],
    c_hat: &Mat<f64>,
    g_hat: &[f64],
    cutoff: f64,
) -> Result<Vec<f64>> {
    let (reduced_mass, reduced_force) = joint_space(b, mass, force, gamma_b);
    null_space_solve(&reduced_mass, &reduced_force, c_hat, g_hat, cutoff).map_err(|detail| {
        FlexmbdError::SingularMatrix {
            time: f64::NAN,
            context: "joint-coordinate accelerations with cut joints".to_string(),
            detail,
        }
    })
}

/// Joint accelerations of a tree whose loops are closed by the cut joints of the constraint
/// rows `cut_rows` of `eq` (evaluated at the acceleration level): [`joint_accelerations`]
/// without cut rows, otherwise [`constrained_joint_accelerations`] with C_cut (B p_dd +
/// gamma_B) = gamma_cut, i.e. C_hat = C_cut B and g_hat = gamma_cut - C_cut gamma_B.
pub fn tree_joint_accelerations(
    eq: &DenseEquations,
    b: &Mat<f64>,
    gamma_b: &[f64],
    cut_rows: &[usize],
    cutoff: f64,
) -> Result<Vec<f64>> {
    if cut_rows.is_empty() {
        return joint_accelerations(b, &eq.mass, &eq.force, gamma_b);
    }
    let n = b.nrows();
    let c_cut = Mat::from_fn(cut_rows.len(), n, |a, j| eq.jacobian[(cut_rows[a], j)]);
    let c_hat = &c_cut * b;
    let g_hat: Vec<f64> = cut_rows
        .iter()
        .enumerate()
        .map(|(a, &r)| eq.gamma[r] - (0..n).map(|j| c_cut[(a, j)] * gamma_b[j]).sum::<f64>())
        .collect();
    constrained_joint_accelerations(b, &eq.mass, &eq.force, gamma_b, &c_hat, &g_hat, cutoff)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::formulation::augmented::{Formulation, Level};
    use crate::integrator::initial::dense_initial_conditions;
    use crate::integrator::settings::InitialSettings;
    use crate::integrator::test_models::{ground_joint, unit_body};
    use crate::linalg::partition::{partition, PartitionMethod, DEFAULT_RANK_TOLERANCE};
    use crate::math::time_function::TimeFunction;
    use crate::system::{State, Workspace};
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
        let (g1, c0) =
            (m(&mut sys, g, Vec3::ZERO, rot_x(-0.3)), m(&mut sys, carriage, Vec3::ZERO, rot_x(-0.3)));
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
        let (s0, q1) = (
            m(&mut sys, sleeve, Vec3::ZERO, along_x()),
            m(&mut sys, pendulum, Vec3([0.2, 0.0, 0.0]), along_x()),
        );
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
            sys.add_flexible_body(name, body, x, Mat3::IDENTITY, Vec3::ZERO, Vec3::ZERO, vec![], vec![])
                .unwrap()
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
        let (b1, o0) = (
            m(&mut sys, ball, Vec3([0.4, -0.4, 0.1]), Mat3::IDENTITY),
            m(&mut sys, bob, Vec3::ZERO, along_x()),
        );
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
            for i in 0..n {
                let fd = (qp[i] - qm[i]) / (2.0 * eps);
                assert!((fd - b[(i, k)]).abs() < 1e-7, "dq{i}/dp{k}: {fd} vs {}", b[(i, k)]);
            }
        }
        // gamma_B = d(B p_dot)/dt at p_dd = 0.
        let (_, qd, gamma) = tree.state(n, &p, &pd);
        let plus: Vec<f64> = p.iter().zip(&pd).map(|(a, v)| a + eps * v).collect();
        let minus: Vec<f64> = p.iter().zip(&pd).map(|(a, v)| a - eps * v).collect();
        let (_, qd_plus, _) = tree.state(n, &plus, &pd);
        let (_, qd_minus, _) = tree.state(n, &minus, &pd);
        for i in 0..n {
            let fd = (qd_plus[i] - qd_minus[i]) / (2.0 * eps);
            assert!((fd - gamma[i]).abs() < 1e-5 * (1.0 + fd.abs()), "gamma {i}: {fd} vs {}", gamma[i]);
            let bpd: f64 = (0..np).map(|k| b[(i, k)] * pd[k]).sum();
            assert!((bpd - qd[i]).abs() < 1e-12);
        }
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
                    assert!(eq.constraints[r].abs() < 1e-12, "row {r}: {}", eq.constraints[r]);
                    assert!(eq.velocity_violation(r, qd).abs() < 1e-11, "row {r}");
                }
                let b = &state.influence;
                let pdd = tree_joint_accelerations(&eq, b, &state.gamma, &tree.cut_rows, 1e-12).unwrap();
                let qdd_tree: Vec<f64> = (0..n)
                    .map(|i| state.gamma[i] + (0..nf).map(|k| b[(i, k)] * pdd[k]).sum::<f64>())
                    .collect();
                let part = partition(eq.jacobian.as_ref(), PartitionMethod::Lu, DEFAULT_RANK_TOLERANCE);
                let mut qdd = vec![0.0; n];
                eq.accelerations(&part, Formulation::Augmented, &eq.gamma, f64::INFINITY, &mut qdd).unwrap();
                let scale = qdd.iter().fold(1.0f64, |a, v| a.max(v.abs()));
                for i in 0..n {
                    assert!(
                        (qdd[i] - qdd_tree[i]).abs() < 1e-10 * scale,
                        "case {case} seed {seed} q_dd[{i}]: {} vs {}",
                        qdd[i],
                        qdd_tree[i]
                    );
                }
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
                let pdd = tree_joint_accelerations(&eq, b, &state.gamma, &tree.cut_rows, 1e-12).unwrap();
                let st = tree.structured(model, time, &p, &pd).unwrap();
                assert!(st.coordinates.iter().zip(&state.coordinates).all(|(a, b)| (a - b).abs() < 1e-14));
                let r40 = coupled.accelerations(model, &mut ws, &st, time, &[]).unwrap();
                let r41 = decoupled.accelerations(model, &mut ws, &st, time, &[]).unwrap();
                let scale = pdd.iter().fold(1.0f64, |a, v| a.max(v.abs()));
                for k in 0..nf {
                    for (name, r) in [("eq. 40", &r40), ("eq. 41", &r41)] {
                        assert!(
                            (r.free_accelerations[k] - pdd[k]).abs() < 1e-10 * scale,
                            "case {case} seed {seed} {name} p_dd[{k}]: {} vs {}",
                            r.free_accelerations[k],
                            pdd[k]
                        );
                    }
                }
                // The same reactions -F_r and cut multipliers from both.
                let rscale = r40.reactions.iter().fold(1.0f64, |a, v| a.max(v.abs()));
                for (a, b) in r40
                    .reactions
                    .iter()
                    .zip(&r41.reactions)
                    .chain(r40.cut_multipliers.iter().zip(&r41.cut_multipliers))
                {
                    assert!((a - b).abs() < 1e-10 * rscale, "case {case}: reactions {a} vs {b}");
                }
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
                    let residual = mq[row] + r41.reactions[k] + cmu - eq.force[row];
                    assert!(residual.abs() < 1e-9 * rscale, "case {case} row {row}: {residual}");
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
            eq.evaluate(
                &model,
                &mut ws,
                0.4,
                &state.coordinates,
                &state.velocities,
                &[],
                Level::Acceleration,
            )
            .unwrap();
            let b = &state.influence;
            let pdd = tree_joint_accelerations(&eq, b, &state.gamma, &tree.cut_rows, 1e-12).unwrap();
            (0..n)
                .map(|i| state.gamma[i] + (0..nf).map(|k| b[(i, k)] * pdd[k]).sum::<f64>())
                .collect::<Vec<f64>>()
        };
        let (qdd_before, qdd_after) = (accelerations(&before), accelerations(&after));
        for i in 0..n {
            assert!((before.velocities[i] - after.velocities[i]).abs() < 1e-12, "q_dot[{i}]");
            assert!((qdd_before[i] - qdd_after[i]).abs() < 1e-9 * (1.0 + qdd_before[i].abs()), "q_dd[{i}]");
        }
        let same = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-12);
        for (b, body) in model.bodies.iter().enumerate().skip(1) {
            let o = body.offset;
            let (qa, qb) = (&before.coordinates[o..o + 3], &after.coordinates[o..o + 3]);
            assert!(same(qa, qb), "body {b}");
            if !matches!(body.kind, BodyKind::PointMass { .. }) {
                let (ea, eb) = (&before.coordinates[o + 3..o + 7], &after.coordinates[o + 3..o + 7]);
                let flipped: Vec<f64> = eb.iter().map(|x| -x).collect();
                assert!(same(ea, eb) || same(ea, &flipped), "body {b}");
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
}
