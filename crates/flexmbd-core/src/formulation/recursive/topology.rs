//! The tree of a model: its joints ordered from the ground, the bodies they carry, the cut
//! joints that close loops, and the joint and elastic coordinates of the model's
//! configuration.

use super::*;

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
}
