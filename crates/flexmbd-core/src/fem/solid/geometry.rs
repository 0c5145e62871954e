//! The isoparametric map of a solid element: the Jacobian dx/dxi, its determinant and the
//! physical gradients of the shape functions.

use super::Isoparametric;
use crate::math::Vec3;

/// Jacobian J_ij = dx_i / dxi_j = sum_a x_a,i dN_a/dxi_j (3 x 3, row-major).
fn jacobian<const N: usize>(x: &[Vec3], reference: &[[f64; 3]; N]) -> [[f64; 3]; 3] {
    let mut j = [[0.0; 3]; 3];
    for (xa, ga) in x.iter().zip(reference) {
        for r in 0..3 {
            for c in 0..3 {
                j[r][c] += xa[r] * ga[c];
            }
        }
    }
    j
}

/// Cofactor matrix C of a 3 x 3 matrix (C = det(J) J^-T) and the determinant.
fn cofactor_and_determinant(j: &[[f64; 3]; 3]) -> ([[f64; 3]; 3], f64) {
    let rows = [Vec3(j[0]), Vec3(j[1]), Vec3(j[2])];
    // Row i of C is the cross product of the two other rows of J, in cyclic order.
    let c = [rows[1].cross(&rows[2]).0, rows[2].cross(&rows[0]).0, rows[0].cross(&rows[1]).0];
    let determinant = rows[0].dot(&Vec3(c[0]));
    (c, determinant)
}

/// The cofactor matrix det(J) J^-T and the determinant of the Jacobian at `xi`.
pub(super) fn cofactor_and_determinant_at<E: Isoparametric<N>, const N: usize>(
    x: &[Vec3],
    xi: [f64; 3],
) -> ([[f64; 3]; 3], f64) {
    cofactor_and_determinant(&jacobian(x, &E::reference_gradients(xi)))
}

/// Jacobian determinant at reference coordinates `xi`.
pub(super) fn jacobian_determinant<E: Isoparametric<N>, const N: usize>(x: &[Vec3], xi: [f64; 3]) -> f64 {
    cofactor_and_determinant(&jacobian(x, &E::reference_gradients(xi))).1
}

/// Physical gradients dN_a/dx = J^-T dN_a/dxi and the Jacobian determinant at `xi`.
pub(super) fn physical_gradients<E: Isoparametric<N>, const N: usize>(
    x: &[Vec3],
    xi: [f64; 3],
) -> ([[f64; 3]; N], f64) {
    let reference = E::reference_gradients(xi);
    let (c, determinant) = cofactor_and_determinant(&jacobian(x, &reference));
    let mut g = [[0.0; 3]; N];
    for (ga, ra) in g.iter_mut().zip(&reference) {
        for i in 0..3 {
            ga[i] = (c[i][0] * ra[0] + c[i][1] * ra[1] + c[i][2] * ra[2]) / determinant;
        }
    }
    (g, determinant)
}
