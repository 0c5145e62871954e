//! The tree of a model: its joints ordered from the ground, the bodies they carry, the cut
//! joints that close loops, and the joint and elastic coordinates of the model's
//! configuration.
//!
//! [`Tree::new`] works in stages: the cut joints the caller lists ([`listed_cuts`]), a
//! spanning tree grown from the ground ([`spanning_order`]), the tree joints placed in the
//! model's configuration with their starting coordinates ([`super::placement`]), the
//! drivers that prescribe a joint coordinate ([`prescribed_coordinates`]), the joints left
//! to cut ([`cut_joints`]), the elastic coordinates ([`elastic_blocks`]), and a check that
//! the tree reproduces the configuration ([`Tree::check_configuration`]).

use super::placement::{is_point_mass, place_joints, Configuration, JointMarkers};
use super::*;
use crate::joint::Joint;
use crate::math::euler::{from_rotation_matrix, rotation_matrix};

impl Tree {
    /// The tree of `model`, with the joint and elastic coordinates of the model's
    /// configuration `q` (which must satisfy the joints). Errors name the body or joint the
    /// tree cannot take. `cut`: the joints to cut (loop closures); None cuts every joint that
    /// closes a loop or is not a tree joint type, a list makes any other such joint an error.
    pub fn new(model: &Model, q: &[f64], cut: Option<&[usize]>) -> Result<(Tree, Vec<f64>)> {
        let nb = model.bodies.len();
        let designated = listed_cuts(model, cut)?;
        let (order, mut used) = spanning_order(model, &designated);
        let configuration = Configuration::new(model, q);
        let placed = place_joints(&configuration, &order);
        let prescribed = prescribed_coordinates(model, &placed.joints, &placed.markers, &designated)?;
        for p in &prescribed {
            used[p.driver] = true;
        }
        let cut_joints = cut_joints(model, &used, &designated, cut.is_some())?;
        let cut_rows = constraint_rows(model, &cut_joints);
        // The elastic coordinates of the deformable bodies follow the joint coordinates.
        let mut p0 = placed.coordinates;
        let joint_coordinate_count = p0.len();
        let (elastic, elastic_coordinates) = elastic_blocks(model, q, joint_coordinate_count);
        p0.extend(elastic_coordinates);
        let coordinate_count = p0.len();
        let free: Vec<usize> =
            (0..coordinate_count).filter(|c| prescribed.iter().all(|p| p.coordinate != *c)).collect();
        let full_p0 = p0.clone();
        let p0: Vec<f64> = free.iter().map(|&c| p0[c]).collect();
        let Configuration { offsets, reference_parameters, .. } = configuration;
        let tree = Tree {
            reference_rows: reference_rows(model, &offsets),
            point_masses: (0..nb).map(|b| is_point_mass(model, b)).collect(),
            coordinate_count,
            joint_coordinate_count,
            joints: placed.joints,
            prescribed,
            free,
            cut_joints,
            cut_rows,
            offsets,
            reference_parameters,
            elastic,
        };
        tree.check_configuration(model, q, &full_p0, &placed.names)?;
        Ok((tree, p0))
    }

    /// Checks that the tree reproduces the model's configuration `q` at the joint and elastic
    /// coordinates `p0` (prescribed ones included): a joint whose markers are not aligned as
    /// its type assumes (a prismatic joint with opposite z axes, say) would otherwise move a
    /// body silently. `names`: the joints' names in messages, in the tree's order.
    fn check_configuration(&self, model: &Model, q: &[f64], p0: &[f64], names: &[String]) -> Result<()> {
        let (q_tree, _, _) = self.state(model.coordinate_count, p0, &vec![0.0; p0.len()]);
        for (joint, name) in self.joints.iter().zip(names) {
            let b = joint.child.body;
            let o = self.offsets[b];
            let position = (0..3).map(|k| (q_tree[o + k] - q[o + k]).abs()).fold(0.0, f64::max);
            let rotation = if is_point_mass(model, b) {
                0.0
            } else {
                let diff = |sign: f64| {
                    (0..4).map(|k| (q_tree[o + 3 + k] - sign * q[o + 3 + k]).abs()).fold(0.0, f64::max)
                };
                diff(1.0).min(diff(-1.0))
            };
            let scale = 1.0 + (0..3).map(|k| q[o + k].abs()).fold(0.0, f64::max);
            if position > 1e-8 * scale || rotation > 1e-8 {
                let turn = if is_point_mass(model, b) {
                    String::new()
                } else {
                    // The turn from the tree's orientation to the model's, A_tree^T A_model (body axes).
                    let parameters = |x: &[f64]| rotation_matrix(&[x[0], x[1], x[2], x[3]]);
                    let turn =
                        parameters(&q_tree[o + 3..o + 7]).transpose().mul_mat(&parameters(&q[o + 3..o + 7]));
                    let r = from_rotation_matrix(&turn);
                    let sine = (r[1] * r[1] + r[2] * r[2] + r[3] * r[3]).sqrt();
                    let angle = 2.0 * sine.atan2(r[0].abs()).to_degrees();
                    let axis = [r[1], r[2], r[3]].map(|v| v / sine.max(f64::MIN_POSITIVE) * r[0].signum());
                    format!(
                        " and turns it by {angle:.1} degrees about ({:.3}, {:.3}, {:.3}) in its frame",
                        axis[0], axis[1], axis[2]
                    )
                };
                return Err(invalid(
                    name.clone(),
                    format!(
                        "the joint-coordinate tree places body '{}' {position:.3e} m away from the model's \
                         configuration{turn}: a tree joint takes the child-side marker's frame as the \
                         parent-side one's moved only along the joint's own coordinates, and these markers' \
                         frames are turned otherwise (a weld or hinge with a marker turned half a turn is \
                         one; the augmented strategies hold such a joint as a constraint); turn the \
                         markers' frames to match, or cut the joint (cut_joints)",
                        model.bodies[b].name
                    ),
                ));
            }
        }
        Ok(())
    }
}

/// An invalid-model error naming `item`.
fn invalid(item: String, message: String) -> FlexmbdError {
    FlexmbdError::InvalidModel { item, message }
}

/// Whether joints of type `kind` can be tree joints.
fn is_tree_kind(kind: &JointKind) -> bool {
    matches!(
        kind,
        JointKind::Revolute
            | JointKind::Prismatic
            | JointKind::Cylindrical
            | JointKind::Fixed
            | JointKind::Universal
            | JointKind::Spherical
    )
}

/// Per joint of `model`, whether the caller lists it among the joints to cut (`cut`; None
/// lists none). An index beyond the model's joints, or one listed twice, is an error.
fn listed_cuts(model: &Model, cut: Option<&[usize]>) -> Result<Vec<bool>> {
    let mut designated = vec![false; model.joints.len()];
    for &k in cut.unwrap_or(&[]) {
        if k >= model.joints.len() {
            return Err(FlexmbdError::InvalidParameter {
                item: format!("cut joint {k}"),
                message: format!("the model has {} joints and drivers", model.joints.len()),
            });
        }
        if designated[k] {
            return Err(FlexmbdError::InvalidParameter {
                item: format!("cut joint '{}'", model.joints[k].name),
                message: "listed twice among the cut joints".to_string(),
            });
        }
        designated[k] = true;
    }
    Ok(designated)
}

/// A spanning tree of the bodies grown from the ground: how each body joins it, in order from
/// the ground, and per joint of `model` whether it is a tree joint. Tree joints are the joints
/// of a tree type not `designated` to be cut that reach a new body; a body they do not reach
/// floats on a free joint to the ground.
fn spanning_order(model: &Model, designated: &[bool]) -> (Vec<Link>, Vec<bool>) {
    let nb = model.bodies.len();
    let mut reached = vec![false; nb];
    reached[0] = true;
    let mut order: Vec<Link> = Vec::new();
    let mut used = vec![false; model.joints.len()];
    loop {
        let mut progress = false;
        for (k, joint) in model.joints.iter().enumerate() {
            if used[k] || designated[k] || !is_tree_kind(&joint.kind) {
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
            if is_point_mass(model, child) && !matches!(joint.kind, JointKind::Spherical) {
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
    (order, used)
}

/// The joint coordinates the drivers of `model` prescribe: a driver prescribes the coordinate
/// of the tree joint on the same markers (`joints`, with their `markers`). Two drivers on one
/// coordinate are an error; a driver on other markers, or one the caller `designated` to be
/// cut, is left to be cut (its equation a rheonomic cut constraint, as a loop joint's).
fn prescribed_coordinates(
    model: &Model,
    joints: &[TreeJoint],
    markers: &[Option<JointMarkers>],
    designated: &[bool],
) -> Result<Vec<Prescribed>> {
    let mut prescribed: Vec<Prescribed> = Vec::new();
    for (d, driver) in model.joints.iter().enumerate() {
        if driver.kind.function().is_none() || designated[d] {
            continue;
        }
        let found =
            joints.iter().zip(markers).find_map(|(tj, m)| driven_coordinate(model, driver, tj, m.as_ref()?));
        let Some((coordinate, sign)) = found else {
            // A driver on other markers: a rheonomic constraint cut like a loop joint.
            continue;
        };
        if prescribed.iter().any(|p| p.coordinate == coordinate) {
            return Err(invalid(
                format!("driver '{}'", driver.name),
                "a second driver on the same joint coordinate".to_string(),
            ));
        }
        prescribed.push(Prescribed { coordinate, driver: d, sign });
    }
    Ok(prescribed)
}

/// The coordinate of tree joint `tj` (on `markers`) that `driver` prescribes, and the sign of
/// the driver's function in it; None if the driver does not prescribe one of its coordinates.
fn driven_coordinate(
    model: &Model,
    driver: &Joint,
    tj: &TreeJoint,
    markers: &JointMarkers,
) -> Option<(usize, f64)> {
    let [di, dj] = driver.markers.map(|m| m.0);
    let angle = matches!(driver.kind, JointKind::AngleDriver(_));
    let elastic = driver.markers.iter().any(|m| model.markers[m.0].elastic.is_some());
    let JointMarkers { i, j, parent: pid, child: cid } = *markers;
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
        (true, TreeJointKind::Cylindrical) => (tj.first, if (di, dj) == (pid, cid) { 1.0 } else { -1.0 }),
        (false, TreeJointKind::Prismatic) => (tj.first, if (di, dj) == (i, j) { 1.0 } else { -1.0 }),
        (false, TreeJointKind::Cylindrical) => (tj.first + 1, if (di, dj) == (i, j) { 1.0 } else { -1.0 }),
        _ => return None,
    };
    let same_pair = (di, dj) == (i, j) || (di, dj) == (j, i);
    same_pair.then_some((slot, sign))
}

/// The joints and drivers of `model` the tree does not use (`used`): each closes a loop, and
/// its equations are cut constraints. When the caller `listed` the cuts, a joint among them
/// that is not `designated` is an error.
fn cut_joints(model: &Model, used: &[bool], designated: &[bool], listed: bool) -> Result<Vec<usize>> {
    let cut_joints: Vec<usize> = (0..model.joints.len()).filter(|&k| !used[k]).collect();
    if listed {
        if let Some(&k) =
            cut_joints.iter().find(|&&k| !designated[k] && model.joints[k].kind.function().is_none())
        {
            let joint = &model.joints[k];
            return Err(invalid(
                format!("joint '{}' ({})", joint.name, joint.kind.type_name()),
                "it closes a loop of the tree (or is of a type the tree does not take) but is \
                 not among the cut joints: add it to them, or leave them unset to cut such \
                 joints automatically"
                    .to_string(),
            ));
        }
    }
    Ok(cut_joints)
}

/// The constraint rows of the joints `joints` of `model`.
fn constraint_rows(model: &Model, joints: &[usize]) -> Vec<usize> {
    joints
        .iter()
        .flat_map(|&k| model.joints[k].row..model.joints[k].row + model.joints[k].equations.len())
        .collect()
}

/// The elastic coordinates of the deformable bodies of `model`, the first at `first` in p:
/// their blocks and their values in `q`.
fn elastic_blocks(model: &Model, q: &[f64], first: usize) -> (Vec<ElasticBlock>, Vec<f64>) {
    let mut blocks = Vec::new();
    let mut values = Vec::new();
    for (b, body) in model.bodies.iter().enumerate() {
        if let BodyKind::Flexible(f) = &body.kind {
            let o = body.offset + 7;
            blocks.push(ElasticBlock { body: b, first: first + values.len(), count: f.elastic_count });
            values.extend_from_slice(&q[o..o + f.elastic_count]);
        }
    }
    (blocks, values)
}

/// The q indices of the reference coordinates of the bodies of `model` (ground left out).
fn reference_rows(model: &Model, offsets: &[usize]) -> Vec<usize> {
    (1..model.bodies.len())
        .flat_map(|b| {
            let o = offsets[b];
            o..o + if is_point_mass(model, b) { 3 } else { 7 }
        })
        .collect()
}
