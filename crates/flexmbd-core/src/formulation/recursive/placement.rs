//! The tree joints placed in the model's configuration: the marker frames of each joint,
//! the tree joint kind it becomes, and its starting joint coordinates (see the module
//! documentation of [`super`] for the coordinates of each joint type).

use super::*;

/// Whether body `b` of `model` is a point mass (no orientation).
pub(super) fn is_point_mass(model: &Model, b: usize) -> bool {
    matches!(model.bodies[b].kind, BodyKind::PointMass { .. })
}

/// The model's configuration q as the tree's construction reads it: body poses and marker
/// frames.
pub(super) struct Configuration<'a> {
    model: &'a Model,
    /// Body coordinates q (model.coordinate_count).
    q: &'a [f64],
    /// First coordinate index of each body in q.
    pub(super) offsets: Vec<usize>,
    /// Euler parameters of each body in q ([1, 0, 0, 0] for the ground and point masses).
    pub(super) reference_parameters: Vec<[f64; 4]>,
}

impl<'a> Configuration<'a> {
    pub(super) fn new(model: &'a Model, q: &'a [f64]) -> Self {
        let offsets: Vec<usize> = model.bodies.iter().map(|b| b.offset).collect();
        let reference_parameters: Vec<[f64; 4]> = model
            .bodies
            .iter()
            .map(|b| match b.kind {
                BodyKind::Ground | BodyKind::PointMass { .. } => [1.0, 0.0, 0.0, 0.0],
                _ => [q[b.offset + 3], q[b.offset + 4], q[b.offset + 5], q[b.offset + 6]],
            })
            .collect();
        Configuration { model, q, offsets, reference_parameters }
    }

    /// The rotation matrix and origin of body `body`'s frame.
    fn pose(&self, body: usize) -> (Mat3, Vec3) {
        let q = self.q;
        if body == 0 {
            (Mat3::IDENTITY, Vec3::ZERO)
        } else if is_point_mass(self.model, body) {
            let o = self.offsets[body];
            (Mat3::IDENTITY, Vec3([q[o], q[o + 1], q[o + 2]]))
        } else {
            let o = self.offsets[body];
            (rotation_matrix(&self.reference_parameters[body]), Vec3([q[o], q[o + 1], q[o + 2]]))
        }
    }

    /// The marker frame of a side (axes and origin, global), deformed axes included.
    fn marker_frame(&self, side: &Side) -> (Mat3, Vec3) {
        let (a, r) = self.pose(side.body);
        let qf: Vec<HyperDual> = match &self.model.bodies[side.body].kind {
            BodyKind::Flexible(f) => {
                let o = self.offsets[side.body] + 7;
                self.q[o..o + f.elastic_count].iter().map(|&x| HyperDual::constant(x)).collect()
            }
            _ => Vec::new(),
        };
        let (u, axes) = side.local_frame(&side.deformation(&qf));
        let axes = Mat3(crate::math::hyper_dual::values(&axes));
        let u = Vec3(u.map(|x| x.v));
        (a.mul_mat(&axes), r + a.mul_vec(&u))
    }
}

/// The model markers of a tree joint that a model joint places.
#[derive(Clone, Copy, Debug)]
pub(super) struct JointMarkers {
    /// Markers i and j of the model joint.
    pub(super) i: usize,
    pub(super) j: usize,
    /// The parent-side and the child-side marker (i and j in some order).
    pub(super) parent: usize,
    pub(super) child: usize,
}

/// The tree joints placed in the model's configuration.
pub(super) struct PlacedJoints {
    pub(super) joints: Vec<TreeJoint>,
    /// Per tree joint, the markers of its model joint (None: a free joint).
    pub(super) markers: Vec<Option<JointMarkers>>,
    /// Per tree joint, its name in messages.
    pub(super) names: Vec<String>,
    /// The joint coordinates of the configuration, prescribed ones included.
    pub(super) coordinates: Vec<f64>,
}

/// The tree joints of `order`, placed in `configuration`, with their starting coordinates.
pub(super) fn place_joints(configuration: &Configuration, order: &[Link]) -> PlacedJoints {
    let model = configuration.model;
    let mut placed =
        PlacedJoints { joints: Vec::new(), markers: Vec::new(), names: Vec::new(), coordinates: Vec::new() };
    for &link in order {
        let first = placed.coordinates.len();
        let (joint, values, markers, name) = match link {
            Link::Free(b) => {
                let (joint, values) = free_joint(configuration, b, first);
                (joint, values, None, format!("free joint of body '{}'", model.bodies[b].name))
            }
            Link::Joint(k, i_parent) => {
                let (joint, values, markers) = model_joint(configuration, k, i_parent, first);
                let name = format!("joint '{}' ({})", model.joints[k].name, model.joints[k].kind.type_name());
                (joint, values, Some(markers), name)
            }
        };
        placed.coordinates.extend(values);
        placed.joints.push(joint);
        placed.markers.push(markers);
        placed.names.push(name);
    }
    placed
}

/// The free joint from the ground to body `b` with its first coordinate at `first` in p, and
/// its coordinates: the origin of the body, then (a body with an orientation) its Cardan
/// angles.
fn free_joint(configuration: &Configuration, b: usize, first: usize) -> (TreeJoint, Vec<f64>) {
    let side = |body: usize| Side { body, position: Vec3::ZERO, rotation: Mat3::IDENTITY, elastic: None };
    let (parent, child) = (side(0), side(b));
    let o = configuration.offsets[b];
    let mut values = configuration.q[o..o + 3].to_vec();
    let kind = if is_point_mass(configuration.model, b) {
        TreeJointKind::FreePoint
    } else {
        values.extend(cardan_angles(&configuration.pose(b).0));
        TreeJointKind::Free
    };
    let joint = TreeJoint {
        kind,
        first,
        i_parent: true,
        parent,
        child,
        rotation: Mat3::IDENTITY,
        axis: Vec3::ZERO,
        deformed: false,
        base: Mat3::IDENTITY,
    };
    (joint, values)
}

/// The relative placement of a joint's marker frames in the model's configuration, from which
/// its starting coordinates follow.
struct JointPlacement {
    /// Whether marker i of the joint is on the parent side.
    i_parent: bool,
    /// Whether a marker of the joint moves with a deformation.
    deformed: bool,
    /// Whether the child body is a point mass.
    point_child: bool,
    /// Axes of the parent-side and of the child-side marker frame (global).
    parent_axes: Mat3,
    child_axes: Mat3,
    /// Rotation from the parent-side to the child-side marker frame.
    relative: Mat3,
    /// Child-side marker origin from the parent-side one, in the parent-side frame.
    offset: Vec3,
    /// Translation axis of marker i's z in the parent-side frame.
    axis: Vec3,
    /// Angle about z from the parent-side to the child-side frame.
    angle: f64,
    /// The angle an angle driver on (i, j) measures, atan2(y_i . x_j, x_i . x_j).
    driver_angle: f64,
    /// The translation a translation driver on (i, j) measures, z_i . d.
    driver_translation: f64,
}

/// Tree joint from model joint `k` (marker i on the parent side or not) with its first
/// coordinate at `first` in p, its starting coordinates, and its markers.
fn model_joint(
    configuration: &Configuration,
    k: usize,
    i_parent: bool,
    first: usize,
) -> (TreeJoint, Vec<f64>, JointMarkers) {
    let model = configuration.model;
    let joint = &model.joints[k];
    let [mi, mj] = joint.markers.map(|m| m.0);
    let (pid, cid) = if i_parent { (mi, mj) } else { (mj, mi) };
    let (parent, child) = (Side::new(model, pid), Side::new(model, cid));
    let (a_pm, o_pm) = configuration.marker_frame(&parent);
    let (a_cm, o_cm) = configuration.marker_frame(&child);
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
    let placement = JointPlacement {
        i_parent,
        deformed,
        point_child: is_point_mass(model, child.body),
        parent_axes: a_pm,
        child_axes: a_cm,
        relative,
        offset,
        axis,
        angle,
        driver_angle,
        driver_translation,
    };
    let (kind, values) = starting_coordinates(&joint.kind, &placement);
    let tree_joint = TreeJoint {
        kind,
        first,
        i_parent,
        parent,
        child,
        rotation: if kind == TreeJointKind::Fixed { Mat3::IDENTITY } else { relative },
        axis,
        deformed,
        base: Mat3::IDENTITY,
    };
    (tree_joint, values, JointMarkers { i: mi, j: mj, parent: pid, child: cid })
}

/// The tree joint kind of a model joint of type `kind` and its coordinates at `placement`.
fn starting_coordinates(kind: &JointKind, placement: &JointPlacement) -> (TreeJointKind, Vec<f64>) {
    let JointPlacement { i_parent, deformed, driver_angle, driver_translation, angle, .. } = *placement;
    let (offset, axis) = (placement.offset, placement.axis);
    match kind {
        JointKind::Revolute => (TreeJointKind::Revolute, vec![driver_angle]),
        JointKind::Prismatic if deformed => (TreeJointKind::Prismatic, vec![driver_translation]),
        JointKind::Cylindrical if deformed => {
            (TreeJointKind::Cylindrical, vec![driver_angle, driver_translation])
        }
        JointKind::Prismatic => (TreeJointKind::Prismatic, vec![offset.dot(&axis)]),
        JointKind::Cylindrical => (TreeJointKind::Cylindrical, vec![angle, offset.dot(&axis)]),
        JointKind::Universal if deformed => deformed_universal_angles(placement),
        JointKind::Universal if i_parent => {
            // R_x(a) R_y(b): b from the first row, a from the last column's rows.
            let r = &placement.relative.0;
            (TreeJointKind::UniversalXY, vec![r[2][1].atan2(r[1][1]), r[0][2].atan2(r[0][0])])
        }
        JointKind::Universal => {
            // R_y(a) R_x(b).
            let r = &placement.relative.0;
            (TreeJointKind::UniversalYX, vec![(-r[2][0]).atan2(r[0][0]), (-r[1][2]).atan2(r[1][1])])
        }
        JointKind::Spherical if placement.point_child => (TreeJointKind::SphericalPoint, vec![]),
        JointKind::Spherical => {
            // Cardan angles between orthonormal frames built from the markers' axes
            // (deformed axes are not exactly orthonormal; the joint constrains only the
            // origins).
            let relative =
                orthonormal(&placement.parent_axes).transpose().mul_mat(&orthonormal(&placement.child_axes));
            (TreeJointKind::Spherical, cardan_angles(&relative))
        }
        _ => (TreeJointKind::Fixed, vec![]),
    }
}

/// The angles of a universal joint on a deformed marker: between the frames the kinematics
/// use (x_i or y_j first).
fn deformed_universal_angles(placement: &JointPlacement) -> (TreeJointKind, Vec<f64>) {
    let (a_pm, a_cm) = (&placement.parent_axes, &placement.child_axes);
    let h = |m: &Mat3| hmat(m.0);
    let (x_first, y_first) = (
        |m: &Mat3| Mat3(values(&frame_x_first(&column(&h(m), 0), &column(&h(m), 2)))),
        |m: &Mat3| Mat3(values(&frame_y_first(&column(&h(m), 1), &column(&h(m), 2)))),
    );
    let r = if placement.i_parent {
        x_first(a_pm).transpose().mul_mat(&y_first(a_cm))
    } else {
        y_first(a_pm).transpose().mul_mat(&x_first(a_cm))
    };
    let r = &r.0;
    if placement.i_parent {
        (TreeJointKind::UniversalXY, vec![r[2][1].atan2(r[1][1]), r[0][2].atan2(r[0][0])])
    } else {
        (TreeJointKind::UniversalYX, vec![(-r[2][0]).atan2(r[0][0]), (-r[1][2]).atan2(r[1][1])])
    }
}
