//! The joint-coordinate equations of motion linearized for the iteration matrix of an implicit
//! method: with y = [p; p_dot] over the free coordinates (joint, then elastic) and
//! M_t(p) p_dd = Q_t(p, p_dot) (seed eq. 32, M_t = B^T M B, Q_t = B^T (f - M gamma_B)) under the
//! cut joints' C_hat p_dd = g_hat, the stiff part of the Jacobian of the accelerations is
//!
//! ```text
//!   d p_dd / d p     = -P K_t,    d p_dd / d p_dot = -P D_t,
//!   P = N (N^T M_t N)^-1 N^T      (P = M_t^-1 without cut joints)
//! ```
//!
//! with K_t and D_t the elastic stiffness and damping of the deformable bodies (their K_ff and
//! D_ff on each body's elastic coordinates: the elastic force -K_ff q_f - D_ff qf_dot acts on
//! the body's own elastic coordinates only, whose rows of B are the identity) and N an
//! orthonormal basis of the null space of C_hat = C_cut B (with the loops' rank,
//! [`LoopClosure`]). Left out: the derivatives of M_t, of the velocity-quadratic and gravity
//! forces, of the geometric stiffness and of C_hat. They are of the order of the rigid-body
//! motion's frequencies and rates, which a step that resolves the motion keeps small, while the
//! elastic stiffness is what makes the equations stiff. At rest (p_dot = 0), undeformed, without
//! gravity and drivers the left-out terms vanish and the Jacobian above is exact.

use faer::Mat;

use super::{reduced_mass, LoopClosure, Tree, LOOP_DAMPING};
use crate::body::BodyKind;
use crate::error::{FlexmbdError, Result};
use crate::formulation::augmented::DenseEquations;
use crate::system::Model;

/// The linearized equations of motion of a tree in its free coordinates at one state (see the
/// module): the matrices an implicit method's iteration matrix is made of.
#[derive(Clone, Debug)]
pub struct TreeLinearization {
    /// M_t = B^T M B (free x free).
    pub mass: Mat<f64>,
    /// K_t: each deformable body's K_ff on its elastic coordinates, zero elsewhere (free x
    /// free; constant).
    pub stiffness: Mat<f64>,
    /// D_t: each deformable body's D_ff likewise (free x free; constant).
    pub damping: Mat<f64>,
    /// Orthonormal basis of the rates the cut joints allow (free x (free - loop rank)); None
    /// without cut joints.
    pub null_space: Option<Mat<f64>>,
}

impl TreeLinearization {
    /// The linearization at the body state of `eq` (evaluated at the acceleration level at the
    /// tree's state: M and C_q), with `b` the influence coefficients of the free coordinates
    /// there (n x free) and `rank` the loops' rank.
    pub fn new(model: &Model, tree: &Tree, eq: &DenseEquations, b: &Mat<f64>, rank: usize) -> Result<Self> {
        let mass = reduced_mass(&eq.mass, b);
        let (stiffness, damping) = elastic_matrices(model, tree);
        let null_space = if tree.cut_rows.is_empty() {
            None
        } else {
            let rows = &tree.cut_rows;
            let c_cut = Mat::from_fn(rows.len(), b.nrows(), |a, j| eq.jacobian[(rows[a], j)]);
            let c_hat = c_cut * b;
            let closure = LoopClosure::new(c_hat.as_ref(), rank, LOOP_DAMPING).map_err(|detail| {
                FlexmbdError::SingularMatrix {
                    time: f64::NAN,
                    context: "iteration matrix in joint coordinates (cut joints)".to_string(),
                    detail,
                }
            })?;
            Some(closure.null_space())
        };
        Ok(TreeLinearization { mass, stiffness, damping, null_space })
    }
}

impl TreeLinearization {
    /// Whether the stiffness and damping are zero (a tree of rigid bodies and point masses, or
    /// of deformable bodies without stiffness): J's lower blocks are then zero, and the Newton
    /// correction of the rates is the residual itself, whatever the mass matrix and the cut
    /// joints (x_v = r_v).
    pub fn is_rigid(&self) -> bool {
        let zero = |m: &Mat<f64>| (0..m.ncols()).all(|c| (0..m.nrows()).all(|r| m[(r, c)] == 0.0));
        zero(&self.stiffness) && zero(&self.damping)
    }

    /// The linearization of a tree whose stiffness and damping are zero (`is_rigid`), without
    /// its mass matrix: the identity stands for it, as the iteration does not depend on it
    /// (`free`: the free coordinates).
    pub fn rigid(free: usize) -> Self {
        TreeLinearization {
            mass: Mat::identity(free, free),
            stiffness: Mat::zeros(free, free),
            damping: Mat::zeros(free, free),
            null_space: None,
        }
    }
}

/// The elastic stiffness K_t and damping D_t of `tree` in its free coordinates (free x free):
/// each deformable body's K_ff and D_ff at its elastic coordinates, zero elsewhere.
pub fn elastic_matrices(model: &Model, tree: &Tree) -> (Mat<f64>, Mat<f64>) {
    let nf = tree.free_count();
    let mut stiffness = Mat::zeros(nf, nf);
    let mut damping = Mat::zeros(nf, nf);
    for (body, first, _) in tree.elastic_blocks() {
        let BodyKind::Flexible(fb) = &model.bodies[body].kind else {
            unreachable!("elastic blocks are flexible")
        };
        for (matrix, out) in [(&fb.stiffness.matrix, &mut stiffness), (&fb.damping.matrix, &mut damping)] {
            for c in 0..matrix.ncols {
                for k in matrix.col_ptr[c]..matrix.col_ptr[c + 1] {
                    out[(first + matrix.row_idx[k], first + c)] += matrix.values[k];
                }
            }
        }
    }
    (stiffness, damping)
}
