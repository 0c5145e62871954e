//! The trilinear hexahedron with incompatible modes [`Hex8Incompatible`] (Abaqus' C3D8I): the
//! displacement of [`Hex8`] enriched by the three bubble modes P_i = 1 - xi_i^2 per component,
//! u = sum_a N_a u_a + sum_i P_i alpha_i, whose nine amplitudes alpha are condensed out of
//! each element (Wilson, Taylor, Doherty and Ghaboussi, "Incompatible displacement models",
//! in Numerical and Computer Methods in Structural Mechanics, Academic Press 1973, 43-57).
//! The modes let an element bend: a rectangular element under pure bending takes the exact
//! linear stress through its depth, where the trilinear one locks in shear.
//!
//! The gradients of the modes are those of the element's centre scaled by the determinants,
//! grad P_i = (det J0 / det J) J0^-T dP_i/dxi (Taylor, Beresford and Wilson, "A non-conforming
//! element for stress analysis", Int. J. Numer. Meth. Eng. 10 (1976) 1211-1219): then
//! int grad P_i dV = det J0 J0^-T sum_g w_g dP_i/dxi(xi_g) = 0 on every element shape, so an
//! affine field leaves the modes at rest and the element passes the patch test distorted.
//!
//! Stiffness: K = K_uu - K_ua K_aa^-1 K_au over 2 x 2 x 2 Gauss (K_aa is positive definite on
//! every element the validation accepts). Mass, invariants and volume: those of [`Hex8`] (the
//! modes carry no mass, as in Abaqus). Nodal stresses: D (B_u(xi_a) u + B_a(xi_a) alpha) with
//! the condensed alpha = -K_aa^-1 K_au u.

use super::geometry::{cofactor_and_determinant_at, physical_gradients};
use super::matrices::strain_displacement;
use super::validation::validate;
use super::{mass, Hex8, Isoparametric};
use crate::fem::element::{ElementError, ElementKernel, ElementResult, MassPoint};
use crate::fem::material::Material;
use crate::math::dense::DenseMatrix;
use crate::math::Vec3;

/// Eight-node hexahedron with incompatible modes (node order of [`Hex8`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Hex8Incompatible;

/// Compatible (24) and incompatible (9) coordinates of the element.
const U: usize = 24;
const A: usize = 9;
const ALL: usize = U + A;

/// The strain-displacement matrix [B_u, B_a] (6 x 33) at `xi`, and det J there: columns
/// 3 a + j of node a, 24 + 3 i + j of the mode P_i in direction j (`centre`: the cofactor
/// matrix det J0 J0^-T at the centre).
fn strain_matrix(x: &[Vec3], xi: [f64; 3], centre: &[[f64; 3]; 3]) -> ([[f64; ALL]; 6], f64) {
    let (g, determinant) = physical_gradients::<Hex8, 8>(x, xi);
    let mut b = [[0.0; ALL]; 6];
    let mut put = |column: usize, gradient: [f64; 3]| {
        let block = strain_displacement(gradient);
        for (row, values) in b.iter_mut().zip(&block) {
            row[column..column + 3].copy_from_slice(values);
        }
    };
    for (a, ga) in g.iter().enumerate() {
        put(3 * a, *ga);
    }
    // grad P_i = C0 (dP_i/dxi) / det J with dP_i/dxi = -2 xi_i e_i.
    for i in 0..3 {
        let scale = -2.0 * xi[i] / determinant;
        put(U + 3 * i, std::array::from_fn(|k| centre[k][i] * scale));
    }
    (b, determinant)
}

/// The whole stiffness int [B_u, B_a]^T D [B_u, B_a] dV (33 x 33, upper triangle filled).
fn full_stiffness(material: &Material, x: &[Vec3]) -> ElementResult<Vec<[f64; ALL]>> {
    named(validate::<Hex8, 8>(x, Hex8::STIFFNESS_RULE))?;
    let (centre, _) = cofactor_and_determinant_at::<Hex8, 8>(x, [0.0; 3]);
    let d = material.elasticity();
    let mut k = vec![[0.0; ALL]; ALL];
    for point in Hex8::STIFFNESS_RULE {
        let (b, determinant) = strain_matrix(x, point.coordinates, &centre);
        let dv = point.weight * determinant;
        let mut db = [[0.0; ALL]; 6];
        for r in 0..6 {
            for c in 0..ALL {
                db[r][c] = (0..6).map(|s| d[r][s] * b[s][c]).sum();
            }
        }
        for row in 0..ALL {
            for col in row..ALL {
                k[row][col] += dv * (0..6).map(|r| b[r][row] * db[r][col]).sum::<f64>();
            }
        }
    }
    Ok(k)
}

/// K_aa^-1 K_au (9 x 24) from the whole stiffness, by the Cholesky factor of K_aa.
fn condensation(k: &[[f64; ALL]]) -> ElementResult<[[f64; U]; A]> {
    let mut l = [[0.0; A]; A];
    for i in 0..A {
        for j in 0..=i {
            let sum: f64 = k[U + j][U + i] - (0..j).map(|m| l[i][m] * l[j][m]).sum::<f64>();
            if i == j {
                if !(sum > 0.0) {
                    return Err(ElementError::Degenerate {
                        detail: format!(
                            "the incompatible modes of a {} element are not independent (pivot {sum:.3e})",
                            Hex8Incompatible::NAME
                        ),
                    });
                }
                l[i][i] = sum.sqrt();
            } else {
                l[i][j] = sum / l[j][j];
            }
        }
    }
    let mut out = [[0.0; U]; A];
    for c in 0..U {
        // Forward then backward substitution of column c of K_au (= row c of K_ua).
        let mut y = [0.0; A];
        for i in 0..A {
            y[i] = (k[c][U + i] - (0..i).map(|m| l[i][m] * y[m]).sum::<f64>()) / l[i][i];
        }
        for i in (0..A).rev() {
            y[i] = (y[i] - (i + 1..A).map(|m| l[m][i] * y[m]).sum::<f64>()) / l[i][i];
        }
        for (row, value) in out.iter_mut().zip(y) {
            row[c] = value;
        }
    }
    Ok(out)
}

impl Hex8Incompatible {
    /// Element name for error messages.
    const NAME: &'static str = "hex8i";
}

/// `result` of a routine of [`Hex8`] run for this element, its errors naming this element
/// (they said "a hex8 element" of a hex8i).
fn named<T>(result: ElementResult<T>) -> ElementResult<T> {
    let rename = |detail: String| {
        detail.replace(&format!("a {} element", Hex8::NAME), &format!("a {} element", Hex8Incompatible::NAME))
    };
    result.map_err(|error| match error {
        ElementError::Degenerate { detail } => ElementError::Degenerate { detail: rename(detail) },
        ElementError::Invalid { detail } => ElementError::Invalid { detail: rename(detail) },
    })
}

impl ElementKernel for Hex8Incompatible {
    fn node_count(&self) -> usize {
        8
    }

    fn dofs_per_node(&self) -> usize {
        3
    }

    fn stiffness(&self, material: &Material, x: &[Vec3], out: &mut DenseMatrix) -> ElementResult<()> {
        let k = full_stiffness(material, x)?;
        let z = condensation(&k)?;
        if out.rows == U && out.cols == U && out.data.len() == U * U {
            out.fill_zero();
        } else {
            *out = DenseMatrix::zeros(U, U);
        }
        // K_uu - K_ua (K_aa^-1 K_au), upper triangle, mirrored so that K is symmetric exactly.
        for row in 0..U {
            for col in row..U {
                let coupling: f64 = (0..A).map(|i| k[row][U + i] * z[i][col]).sum();
                out.data[row * U + col] = k[row][col] - coupling;
            }
        }
        for row in 1..U {
            for col in 0..row {
                out.data[row * U + col] = out.data[col * U + row];
            }
        }
        Ok(())
    }

    fn mass_points(&self, material: &Material, x: &[Vec3], out: &mut Vec<MassPoint>) -> ElementResult<()> {
        named(mass::mass_points::<Hex8, 8>(material, x, out))
    }

    fn lumped_mass_points(
        &self,
        material: &Material,
        x: &[Vec3],
        out: &mut Vec<MassPoint>,
    ) -> ElementResult<()> {
        named(mass::lumped_mass_points::<Hex8, 8>(material, x, out))
    }

    fn volume(&self, x: &[Vec3]) -> ElementResult<f64> {
        named(mass::volume::<Hex8, 8>(x))
    }

    fn nodal_stresses(
        &self,
        material: &Material,
        x: &[Vec3],
        u: &[f64],
        out: &mut [[f64; 6]],
    ) -> ElementResult<()> {
        let k = full_stiffness(material, x)?;
        let z = condensation(&k)?;
        let mut q = [0.0; ALL];
        q[..U].copy_from_slice(&u[..U]);
        for i in 0..A {
            q[U + i] = -(0..U).map(|c| z[i][c] * u[c]).sum::<f64>();
        }
        let (centre, _) = cofactor_and_determinant_at::<Hex8, 8>(x, [0.0; 3]);
        let d = material.elasticity();
        for (node, xi) in out.iter_mut().zip(Hex8::NODES) {
            let (b, _) = strain_matrix(x, xi, &centre);
            let strain: [f64; 6] = std::array::from_fn(|r| (0..ALL).map(|c| b[r][c] * q[c]).sum());
            for r in 0..6 {
                node[r] = (0..6).map(|c| d[r][c] * strain[c]).sum();
            }
        }
        Ok(())
    }
}
