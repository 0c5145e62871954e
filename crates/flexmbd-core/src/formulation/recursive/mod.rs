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
use crate::formulation::augmented::DenseEquations;
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

mod frames;
mod kinematics;
mod linearization;
mod loops;
mod placement;
mod sparse;
#[cfg(test)]
mod tests;
mod topology;

use frames::*;
pub use linearization::{elastic_matrices, TreeLinearization};
pub use loops::{LoopClosure, LOOP_DAMPING};
pub use sparse::{BodyInfluence, SparseJointSpace, REGULAR_MARGIN};

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
pub(crate) fn joint_space(
    b: &Mat<f64>,
    mass: &Mat<f64>,
    force: &[f64],
    gamma: &[f64],
) -> (Mat<f64>, Vec<f64>) {
    let n = force.len();
    let reduced_mass = reduced_mass(mass, b);
    let rhs_full = Mat::from_fn(n, 1, |i, _| force[i] - (0..n).map(|j| mass[(i, j)] * gamma[j]).sum::<f64>());
    let rhs = b.transpose() * &rhs_full;
    (reduced_mass, (0..b.ncols()).map(|k| rhs[(k, 0)]).collect())
}

/// B^T M B for the bodies' mass matrix `mass` (n x n, block diagonal: each body's block) and
/// the influence coefficients `b` (n x free), block by block over the columns of B that move
/// the block's body (the joints between it and the ground, the elastic coordinates of the
/// markers on that path, its own), instead of the dense product (which on IFToMM A02 with
/// N = 40, 567 coordinates, cost a sixth of an evaluation).
pub(crate) fn reduced_mass(mass: &Mat<f64>, b: &Mat<f64>) -> Mat<f64> {
    let (n, nf) = (b.nrows(), b.ncols());
    let mut reduced = Mat::zeros(nf, nf);
    let mut first = 0;
    while first < n {
        // The diagonal block starting at `first`: it ends where no entry reaches further.
        let mut end = first + 1;
        let mut r = first;
        while r < end {
            if let Some(last) = (end..n).rev().find(|&c| mass[(r, c)] != 0.0 || mass[(c, r)] != 0.0) {
                end = last + 1;
            }
            r += 1;
        }
        let count = end - first;
        let columns: Vec<usize> = (0..nf).filter(|&k| (first..end).any(|r| b[(r, k)] != 0.0)).collect();
        if !columns.is_empty() {
            let bi = Mat::from_fn(count, columns.len(), |r, k| b[(first + r, columns[k])]);
            let mi = Mat::from_fn(count, count, |r, c| mass[(first + r, first + c)]);
            let product = bi.transpose() * (mi * &bi);
            for (a, &ka) in columns.iter().enumerate() {
                for (c, &kc) in columns.iter().enumerate() {
                    reduced[(ka, kc)] += product[(a, c)];
                }
            }
        }
        first = end;
    }
    reduced
}

/// Joint accelerations with cut-joint constraints: (B^T M B) p_dd + C_hat^T mu =
/// B^T (f - M gamma_B), C_hat p_dd = g_hat, with C_hat = C_cut B and g_hat = gamma_cut -
/// C_cut gamma_B, by the null-space method of `closure`, the SVD of C_hat
/// ([`LoopClosure::accelerations`]: redundant cut equations and singular configurations).
pub fn constrained_joint_accelerations(
    b: &Mat<f64>,
    mass: &Mat<f64>,
    force: &[f64],
    gamma_b: &[f64],
    closure: &LoopClosure,
    g_hat: &[f64],
) -> Result<Vec<f64>> {
    let (reduced_mass, reduced_force) = joint_space(b, mass, force, gamma_b);
    closure.accelerations(&reduced_mass, &reduced_force, g_hat).map_err(|detail| {
        FlexmbdError::SingularMatrix {
            time: f64::NAN,
            context: "joint-coordinate accelerations with cut joints".to_string(),
            detail,
        }
    })
}

/// The cut joints' equations in joint coordinates at the acceleration level, C_hat p_dd =
/// g_hat: C_hat = C_cut B (cut rows x free joint coordinates) and g_hat = gamma_cut - C_cut
/// gamma_B, from the constraint rows `cut_rows` of `eq`.
pub fn cut_equations(
    eq: &DenseEquations,
    b: &Mat<f64>,
    gamma_b: &[f64],
    cut_rows: &[usize],
) -> (Mat<f64>, Vec<f64>) {
    let n = b.nrows();
    let c_cut = Mat::from_fn(cut_rows.len(), n, |a, j| eq.jacobian[(cut_rows[a], j)]);
    let c_hat = &c_cut * b;
    let g_hat: Vec<f64> = cut_rows
        .iter()
        .enumerate()
        .map(|(a, &r)| eq.gamma[r] - (0..n).map(|j| c_cut[(a, j)] * gamma_b[j]).sum::<f64>())
        .collect();
    (c_hat, g_hat)
}

/// The number of independent cut equations at the state of `eq` and `b`: the singular values
/// of C_cut B above `tolerance` times the largest (0 without cut rows or where the SVD fails).
pub fn loop_rank(eq: &DenseEquations, b: &Mat<f64>, cut_rows: &[usize], tolerance: f64) -> usize {
    if cut_rows.is_empty() {
        return 0;
    }
    let (c_hat, _) = cut_equations(eq, b, &vec![0.0; b.nrows()], cut_rows);
    LoopClosure::new(c_hat.as_ref(), cut_rows.len(), LOOP_DAMPING).map_or(0, |c| c.numerical_rank(tolerance))
}

/// Joint accelerations of a tree whose loops are closed by the cut joints of the constraint
/// rows `cut_rows` of `eq` (evaluated at the acceleration level): [`joint_accelerations`]
/// without cut rows, otherwise [`constrained_joint_accelerations`] with C_cut (B p_dd +
/// gamma_B) = gamma_cut ([`cut_equations`]) and `rank` independent cut equations where the
/// loops are regular (see [`LoopClosure`]).
pub fn tree_joint_accelerations(
    eq: &DenseEquations,
    b: &Mat<f64>,
    gamma_b: &[f64],
    cut_rows: &[usize],
    rank: usize,
) -> Result<Vec<f64>> {
    if cut_rows.is_empty() {
        return joint_accelerations(b, &eq.mass, &eq.force, gamma_b);
    }
    let (c_hat, g_hat) = cut_equations(eq, b, gamma_b, cut_rows);
    let closure = LoopClosure::new(c_hat.as_ref(), rank, LOOP_DAMPING).map_err(|detail| {
        FlexmbdError::SingularMatrix {
            time: f64::NAN,
            context: "joint-coordinate accelerations with cut joints".to_string(),
            detail,
        }
    })?;
    constrained_joint_accelerations(b, &eq.mass, &eq.force, gamma_b, &closure, &g_hat)
}
