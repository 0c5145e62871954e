//! Joint coordinates (seed section 5), first part: open trees of rigid bodies connected by
//! revolute, prismatic, cylindrical, fixed and universal joints, with angle and translation drivers on
//! them (prescribed joint coordinates).
//!
//! The bodies' reference coordinates q (origin and Euler parameters) follow from the joint
//! coordinates p body by body from the ground to the tips. Differentiating that recursion gives
//! the velocity influence coefficients B = dq/dp (q_dot = B p_dot, the matrices G and H of
//! seed eq. 31 stacked for the whole tree) and the terms quadratic in the velocities,
//! gamma_B = B_dot p_dot (the gamma of eq. 31), so that q_dd = B p_dd + gamma_B. Projecting
//! the equations of motion of all bodies, M q_dd + C_q^T lambda = f, on B eliminates every
//! joint reaction (B^T C_q^T = 0 for the tree joints):
//!
//! ```text
//! (B^T M B) p_dd = B^T (f - M gamma_B).
//! ```
//!
//! This is the joint-coordinate system that the body-by-body elimination of eqs. 31-32
//! produces; here it is formed with B explicitly. Joints outside the tree (loop closures,
//! other joint types, drivers on other markers) are cut: their equations constrain p (see
//! [`constrained_joint_accelerations`]). The recursive elimination, deformable bodies with the
//! elastic motion of the joint frames, the other tree joint types and the decoupled
//! formulation of eqs. 33-41 are the next parts of issue 6.
//!
//! Joint coordinates: for a revolute joint the angle about the common z axis of its markers
//! from the parent-side marker to the child-side marker; for a prismatic joint the
//! translation along the z axis of marker i (the parent side is whichever marker is on the
//! body nearer the ground); a cylindrical joint has both (angle first), a fixed joint none; a
//! universal joint the rotations a, b about its cross axes, R_rel = R_x(a) R_y(b) from marker i
//! to marker j (R_y(a) R_x(b) seen from marker j when that is the parent side).
//! A driver on the markers of a tree joint prescribes its coordinate: p_d = f(t), and
//! q_dd = B_free p_dd_free + B_d f''(t) + gamma_B.

use faer::Mat;

use super::dense_system::null_space_solve;
use crate::body::BodyKind;
use crate::error::{FlexmbdError, Result};
use crate::joint::JointKind;
use crate::math::euler::{from_rotation_matrix, g_matrix, rotation_matrix, Quaternion};
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
}

impl TreeJointKind {
    /// Number of joint coordinates (the angle first).
    fn coordinate_count(self) -> usize {
        match self {
            TreeJointKind::Revolute | TreeJointKind::Prismatic => 1,
            TreeJointKind::Cylindrical | TreeJointKind::UniversalXY | TreeJointKind::UniversalYX => 2,
            TreeJointKind::Fixed => 0,
        }
    }
}

/// A joint of the tree, seen from its parent side.
#[derive(Clone, Debug)]
struct TreeJoint {
    kind: TreeJointKind,
    /// Index of its first coordinate in p.
    first: usize,
    /// Parent body (0: ground) and child body.
    parent: usize,
    child: usize,
    /// Marker positions and orientations in their body frames, parent side and child side.
    parent_marker: (Vec3, Mat3),
    child_marker: (Vec3, Mat3),
    /// Prismatic: the constant rotation from the parent-side to the child-side marker frame,
    /// and the sliding axis in the parent-side marker frame.
    rotation: Mat3,
    axis: Vec3,
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
    /// q_dd with the free joint accelerations zero: the velocity-quadratic terms and the
    /// prescribed joint accelerations.
    pub gamma: Vec<f64>,
    /// Velocity influence coefficients of the free joint coordinates (n x free).
    pub influence: Mat<f64>,
}

/// An open tree of rigid bodies in joint coordinates.
#[derive(Clone, Debug)]
pub struct Tree {
    joints: Vec<TreeJoint>,
    prescribed: Vec<Prescribed>,
    /// The free (integrated) joint coordinates, in p's order.
    free: Vec<usize>,
    /// Joints cut to open the loops (and drivers on other markers than a tree joint's), and
    /// their constraint rows, which the joint coordinates must satisfy.
    pub cut_joints: Vec<usize>,
    /// Constraint rows of the cut joints.
    pub cut_rows: Vec<usize>,
    /// First coordinate index of each body in q (rigid bodies: 7 coordinates).
    offsets: Vec<usize>,
    /// Euler parameters of each body at the start: the sign of the parameters computed from
    /// rotation matrices follows them.
    reference_parameters: Vec<Quaternion>,
    coordinate_count: usize,
}

/// Pose, velocity and velocity-quadratic acceleration of a body.
#[derive(Clone, Copy, Debug)]
struct Motion {
    rotation: Mat3,
    origin: Vec3,
    omega: Vec3,
    velocity: Vec3,
    alpha: Vec3,
    acceleration: Vec3,
}

const REST: Motion = Motion {
    rotation: Mat3::IDENTITY,
    origin: Vec3::ZERO,
    omega: Vec3::ZERO,
    velocity: Vec3::ZERO,
    alpha: Vec3::ZERO,
    acceleration: Vec3::ZERO,
};

fn rot_x(angle: f64) -> Mat3 {
    let (s, c) = angle.sin_cos();
    Mat3([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
}

fn rot_y(angle: f64) -> Mat3 {
    let (s, c) = angle.sin_cos();
    Mat3([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
}

fn rot_z(angle: f64) -> Mat3 {
    let (s, c) = angle.sin_cos();
    Mat3([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
}

impl Tree {
    /// The tree of `model`, with the joint coordinates of the model's configuration `q`
    /// (which must satisfy the joints). Errors name the body or joint the tree cannot take.
    pub fn new(model: &Model, q: &[f64]) -> Result<(Tree, Vec<f64>)> {
        let bad = |item: String, message: String| Err(FlexmbdError::InvalidModel { item, message });
        let nb = model.bodies.len();
        for body in &model.bodies[1..] {
            if !matches!(body.kind, BodyKind::Rigid(_)) {
                return bad(
                    format!("body '{}'", body.name),
                    "the joint-coordinate formulation takes rigid bodies so far".to_string(),
                );
            }
        }
        let mut reached = vec![false; nb];
        reached[0] = true;
        let mut order: Vec<(usize, bool)> = Vec::new(); // (joint, marker i on the parent side)
        let mut used = vec![false; model.joints.len()];
        let tree_kind = |k: &JointKind| {
            matches!(
                k,
                JointKind::Revolute
                    | JointKind::Prismatic
                    | JointKind::Cylindrical
                    | JointKind::Fixed
                    | JointKind::Universal
            )
        };
        loop {
            let mut progress = false;
            for (k, joint) in model.joints.iter().enumerate() {
                if used[k] || !tree_kind(&joint.kind) {
                    continue;
                }
                let [bi, bj] = joint.markers.map(|m| model.markers[m.0].body.0);
                let i_parent = match (reached[bi], reached[bj]) {
                    // A joint between two bodies of the tree closes a loop: it is cut.
                    (true, true) | (false, false) => continue,
                    (parent_i, _) => parent_i,
                };
                used[k] = true;
                reached[bi] = true;
                reached[bj] = true;
                order.push((k, i_parent));
                progress = true;
            }
            if !progress {
                break;
            }
        }
        if let Some(b) = (1..nb).find(|&b| !reached[b]) {
            let attached: Vec<String> = model
                .joints
                .iter()
                .filter(|j| j.markers.iter().any(|m| model.markers[m.0].body.0 == b))
                .map(|j| format!("'{}' ({})", j.name, j.kind.type_name()))
                .collect();
            return bad(
                format!("body '{}'", model.bodies[b].name),
                format!(
                    "it is not connected to the ground by revolute, prismatic, cylindrical, fixed or universal joints, \
                     which the joint-coordinate formulation takes as tree joints so far (its joints: {})",
                    if attached.is_empty() { "none".to_string() } else { attached.join(", ") }
                ),
            );
        }
        let offsets: Vec<usize> = model.bodies.iter().map(|b| b.offset).collect();
        let reference_parameters: Vec<Quaternion> = model
            .bodies
            .iter()
            .map(|b| match b.kind {
                BodyKind::Ground => [1.0, 0.0, 0.0, 0.0],
                _ => [q[b.offset + 3], q[b.offset + 4], q[b.offset + 5], q[b.offset + 6]],
            })
            .collect();
        let pose = |body: usize| -> (Mat3, Vec3) {
            if body == 0 {
                (Mat3::IDENTITY, Vec3::ZERO)
            } else {
                let o = offsets[body];
                (rotation_matrix(&reference_parameters[body]), Vec3([q[o], q[o + 1], q[o + 2]]))
            }
        };
        let mut joints = Vec::new();
        let mut p0 = Vec::new();
        let mut tree_markers = Vec::new(); // (marker i, marker j, parent-side marker, child-side marker)
        for (k, i_parent) in order {
            let joint = &model.joints[k];
            let [mi, mj] = joint.markers.map(|m| &model.markers[m.0]);
            let (pm, cm) = if i_parent { (mi, mj) } else { (mj, mi) };
            let (parent, child) = (pm.body.0, cm.body.0);
            let (a_p, r_p) = pose(parent);
            let (a_c, r_c) = pose(child);
            let a_pm = a_p.mul_mat(&pm.rotation);
            let a_cm = a_c.mul_mat(&cm.rotation);
            let relative = a_pm.transpose().mul_mat(&a_cm);
            let offset =
                a_pm.tr_mul_vec(&(r_c + a_c.mul_vec(&cm.position) - r_p - a_p.mul_vec(&pm.position)));
            let angle = relative.0[1][0].atan2(relative.0[0][0]);
            // Translation along z of marker i: +z of the parent-side marker, or -z of the
            // child-side marker expressed in the parent-side frame (the same axis for a
            // cylindrical joint, whose rotation keeps z).
            let axis = if i_parent { Vec3::unit(2) } else { -relative.mul_vec(&Vec3::unit(2)) };
            let (kind, values) = match joint.kind {
                JointKind::Revolute => (TreeJointKind::Revolute, vec![angle]),
                JointKind::Prismatic => (TreeJointKind::Prismatic, vec![offset.dot(&axis)]),
                JointKind::Cylindrical => (TreeJointKind::Cylindrical, vec![angle, offset.dot(&axis)]),
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
                _ => (TreeJointKind::Fixed, vec![]),
            };
            let first = p0.len();
            p0.extend(values);
            joints.push(TreeJoint {
                kind,
                first,
                parent,
                child,
                parent_marker: (pm.position, pm.rotation),
                child_marker: (cm.position, cm.rotation),
                rotation: if kind == TreeJointKind::Fixed { Mat3::IDENTITY } else { relative },
                axis,
            });
            let [i, j] = joint.markers.map(|m| m.0);
            let (pid, cid) = if i_parent { (i, j) } else { (j, i) };
            tree_markers.push((i, j, pid, cid));
        }
        // Drivers prescribe the coordinate of the tree joint on the same markers.
        let mut prescribed: Vec<Prescribed> = Vec::new();
        for (d, driver) in model.joints.iter().enumerate() {
            if driver.kind.function().is_none() {
                continue;
            }
            let [di, dj] = driver.markers.map(|m| m.0);
            let angle = matches!(driver.kind, JointKind::AngleDriver(_));
            let found = joints.iter().zip(&tree_markers).find_map(|(tj, &(i, j, pid, cid))| {
                let (slot, sign) = match (angle, tj.kind) {
                    (true, TreeJointKind::Revolute | TreeJointKind::Cylindrical) => {
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
        let cut_rows: Vec<usize> = cut_joints
            .iter()
            .flat_map(|&k| model.joints[k].row..model.joints[k].row + model.joints[k].equations.len())
            .collect();
        let free: Vec<usize> =
            (0..p0.len()).filter(|c| prescribed.iter().all(|p| p.coordinate != *c)).collect();
        let p0: Vec<f64> = free.iter().map(|&c| p0[c]).collect();
        let coordinate_count = joints.iter().map(|j| j.kind.coordinate_count()).sum();
        let tree = Tree {
            coordinate_count,
            joints,
            prescribed,
            free,
            cut_joints,
            cut_rows,
            offsets,
            reference_parameters,
        };
        Ok((tree, p0))
    }

    /// Number of joint coordinates, prescribed ones included.
    pub fn coordinate_count(&self) -> usize {
        self.coordinate_count
    }

    /// Number of free (integrated) joint coordinates.
    pub fn free_count(&self) -> usize {
        self.free.len()
    }

    /// The body state at time `time` for the free joint coordinates `p` and rates `pd`, the
    /// prescribed ones from their drivers.
    pub fn evaluate(&self, model: &Model, time: f64, p: &[f64], pd: &[f64]) -> Result<TreeState> {
        let n = model.coordinate_count;
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
        let (coordinates, velocities, mut gamma) = self.state(n, &full_p, &full_pd);
        let b = self.influence(n, &full_p);
        for presc in &self.prescribed {
            let a = pdd[presc.coordinate];
            for (i, g) in gamma.iter_mut().enumerate() {
                *g += b[(i, presc.coordinate)] * a;
            }
        }
        let influence = Mat::from_fn(n, self.free.len(), |i, k| b[(i, self.free[k])]);
        Ok(TreeState { coordinates, velocities, gamma, influence })
    }

    /// Motions of all bodies for joint coordinates p, rates p_dot and p_dd = 0 (the
    /// accelerations are then the velocity-quadratic terms).
    fn motions(&self, p: &[f64], pd: &[f64]) -> Vec<Motion> {
        let nb = self.offsets.len();
        let mut m = vec![REST; nb];
        for joint in &self.joints {
            let parent = m[joint.parent];
            let (s_p, a_pm_bar) = joint.parent_marker;
            let (s_c, a_cm_bar) = joint.child_marker;
            let a_pm = parent.rotation.mul_mat(&a_pm_bar);
            let rho_p = parent.rotation.mul_vec(&s_p);
            // The parent-side marker frame.
            let o_pm = parent.origin + rho_p;
            let v_pm = parent.velocity + parent.omega.cross(&rho_p);
            let acc_pm = parent.acceleration
                + parent.alpha.cross(&rho_p)
                + parent.omega.cross(&parent.omega.cross(&rho_p));
            // The child-side marker frame relative to it.
            let z = a_pm.column(2);
            let axis = a_pm.mul_vec(&joint.axis);
            let f = joint.first;
            let (relative, translation, rate, omega, alpha) = match joint.kind {
                TreeJointKind::Revolute => (
                    rot_z(p[f]),
                    Vec3::ZERO,
                    Vec3::ZERO,
                    parent.omega + z * pd[f],
                    parent.alpha + parent.omega.cross(&(z * pd[f])),
                ),
                TreeJointKind::Prismatic => {
                    (joint.rotation, axis * p[f], axis * pd[f], parent.omega, parent.alpha)
                }
                TreeJointKind::Cylindrical => (
                    rot_z(p[f]),
                    axis * p[f + 1],
                    axis * pd[f + 1],
                    parent.omega + z * pd[f],
                    parent.alpha + parent.omega.cross(&(z * pd[f])),
                ),
                TreeJointKind::Fixed => (Mat3::IDENTITY, Vec3::ZERO, Vec3::ZERO, parent.omega, parent.alpha),
                TreeJointKind::UniversalXY | TreeJointKind::UniversalYX => {
                    let (first, second) =
                        if joint.kind == TreeJointKind::UniversalXY { (0, 1) } else { (1, 0) };
                    let rot = |axis: usize, angle: f64| if axis == 0 { rot_x(angle) } else { rot_y(angle) };
                    let r1 = rot(first, p[f]);
                    let u1 = a_pm.column(first);
                    let u2 = a_pm.mul_mat(&r1).column(second);
                    let (w1, w2) = (u1 * pd[f], u2 * pd[f + 1]);
                    (
                        r1.mul_mat(&rot(second, p[f + 1])),
                        Vec3::ZERO,
                        Vec3::ZERO,
                        parent.omega + w1 + w2,
                        parent.alpha + parent.omega.cross(&w1) + (parent.omega + w1).cross(&w2),
                    )
                }
            };
            let a_cm = a_pm.mul_mat(&relative);
            let o_cm = o_pm + translation;
            let v_cm = v_pm + parent.omega.cross(&translation) + rate;
            let acc_cm = acc_pm
                + parent.alpha.cross(&translation)
                + parent.omega.cross(&parent.omega.cross(&translation))
                + parent.omega.cross(&rate) * 2.0;
            // The child body.
            let rotation = a_cm.mul_mat(&a_cm_bar.transpose());
            let rho_c = rotation.mul_vec(&s_c);
            m[joint.child] = Motion {
                rotation,
                origin: o_cm - rho_c,
                omega,
                velocity: v_cm - omega.cross(&rho_c),
                alpha,
                acceleration: acc_cm - alpha.cross(&rho_c) - omega.cross(&omega.cross(&rho_c)),
            };
        }
        m
    }

    /// Body coordinates q, velocities q_dot = B p_dot and gamma_B = B_dot p_dot at (p, p_dot),
    /// all of length `n` (the model's coordinate count).
    pub fn state(&self, n: usize, p: &[f64], pd: &[f64]) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let motions = self.motions(p, pd);
        let (mut q, mut qd, mut gamma) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        for (b, m) in motions.iter().enumerate().skip(1) {
            let o = self.offsets[b];
            let mut e = from_rotation_matrix(&m.rotation);
            let reference = &self.reference_parameters[b];
            if (0..4).map(|k| e[k] * reference[k]).sum::<f64>() < 0.0 {
                e.iter_mut().for_each(|x| *x = -*x);
            }
            let g = g_matrix(&e);
            // e_dot = G^T omega / 2; e_dd = G^T omega_dot / 2 - |e_dot|^2 e (unit e).
            let ed: Vec<f64> =
                (0..4).map(|c| 0.5 * (0..3).map(|r| g[r][c] * m.omega[r]).sum::<f64>()).collect();
            let ed2: f64 = ed.iter().map(|x| x * x).sum();
            for k in 0..3 {
                q[o + k] = m.origin[k];
                qd[o + k] = m.velocity[k];
                gamma[o + k] = m.acceleration[k];
            }
            for c in 0..4 {
                q[o + 3 + c] = e[c];
                qd[o + 3 + c] = ed[c];
                gamma[o + 3 + c] = 0.5 * (0..3).map(|r| g[r][c] * m.alpha[r]).sum::<f64>() - ed2 * e[c];
            }
        }
        (q, qd, gamma)
    }

    /// The velocity influence coefficients B = dq/dp (n x coordinate_count) at p.
    pub fn influence(&self, n: usize, p: &[f64]) -> Mat<f64> {
        let np = self.coordinate_count;
        let mut b = Mat::zeros(n, np);
        let mut unit = vec![0.0; np];
        for k in 0..np {
            unit[k] = 1.0;
            let (_, column, _) = self.state(n, p, &unit);
            for (i, v) in column.iter().enumerate() {
                b[(i, k)] = *v;
            }
            unit[k] = 0.0;
        }
        b
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::time_function::TimeFunction;
    use crate::solver::dense_system::{dense_initial_conditions, DenseEquations, Formulation, Level};
    use crate::solver::initial::InitialSettings;
    use crate::solver::partition::{partition, PartitionMethod, DEFAULT_RANK_TOLERANCE};
    use crate::solver::test_models::{ground_joint, unit_body};
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

    fn consistent(model: &Model) -> Vec<f64> {
        let mut ws = Workspace::for_evaluation(model);
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

    #[test]
    fn influence_coefficients_and_quadratic_terms_match_finite_differences() {
        let model = tree_model(false);
        let (tree, p0) = Tree::new(&model, &consistent(&model)).unwrap();
        let (n, np) = (model.coordinate_count, tree.coordinate_count());
        assert_eq!(np, 11);
        let p: Vec<f64> = p0.iter().zip(sample(np, 3, 1.0)).map(|(a, b)| a + b).collect();
        let pd = sample(np, 7, 4.0);
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
        for driven in [false, true] {
            let model = tree_model(driven);
            let (tree, p0) = Tree::new(&model, &consistent(&model)).unwrap();
            let n = model.coordinate_count;
            let nf = tree.free_count();
            assert_eq!(nf, if driven { 9 } else { 11 });
            for seed in 0..5 {
                let time = 0.1 + 0.3 * seed as f64;
                let p: Vec<f64> = p0.iter().zip(sample(nf, 11 + seed, 2.0)).map(|(a, b)| a + b).collect();
                let pd = sample(nf, 29 + seed, 6.0);
                let state = tree.evaluate(&model, time, &p, &pd).unwrap();
                let (q, qd) = (&state.coordinates, &state.velocities);
                let mut ws = Workspace::for_evaluation(&model);
                let mut eq = DenseEquations::new(&model);
                eq.evaluate(&model, &mut ws, time, q, qd, &[], Level::Acceleration).unwrap();
                // The tree state satisfies every joint and driver, at position and velocity level.
                assert!(eq.constraints.iter().all(|c| c.abs() < 1e-12), "{:?}", eq.constraints);
                for r in 0..model.constraint_count {
                    assert!(eq.velocity_violation(r, qd).abs() < 1e-11, "row {r}");
                }
                let b = &state.influence;
                let pdd = joint_accelerations(b, &eq.mass, &eq.force, &state.gamma).unwrap();
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
                        "driven {driven} seed {seed} q_dd[{i}]: {} vs {}",
                        qdd[i],
                        qdd_tree[i]
                    );
                }
            }
        }
    }

    #[test]
    fn unsupported_trees_are_refused_and_loops_are_cut() {
        let mut sys = SystemBuilder::new();
        let body = unit_body(&mut sys, "link", Vec3::ZERO);
        ground_joint(&mut sys, "ball", JointKind::Spherical, body, Vec3::ZERO, Vec3::ZERO);
        let model = sys.compile().unwrap();
        let error = Tree::new(&model, &model.initial_coordinates).unwrap_err().to_string();
        assert!(error.contains("'ball'") && error.contains("spherical"), "{error}");

        let mut sys = SystemBuilder::new();
        let body = unit_body(&mut sys, "link", Vec3::ZERO);
        for name in ["first", "second"] {
            ground_joint(&mut sys, name, JointKind::Revolute, body, Vec3::ZERO, Vec3::ZERO);
        }
        let model = sys.compile().unwrap();
        // The second hinge closes a loop: it is cut, its five equations constrain the tree.
        let (tree, _) = Tree::new(&model, &model.initial_coordinates).unwrap();
        assert_eq!(tree.cut_joints, vec![1]);
        assert_eq!(tree.cut_rows.len(), 5);
    }
}
