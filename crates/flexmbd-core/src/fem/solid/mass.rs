//! The mass of a solid element: mass points of the mass rule (consistent mass, invariants of
//! motion), HRZ lumped masses at the nodes, and the volume.

use super::geometry::jacobian_determinant;
use super::validation::validate;
use super::Isoparametric;
use crate::fem::element::{ElementResult, MassPoint};
use crate::fem::material::Material;
use crate::math::Vec3;

/// Mass points of the mass rule: weight rho w det J, position sum N_a x_a, S = [N_a I].
pub(super) fn mass_points<E: Isoparametric<N>, const N: usize>(
    material: &Material,
    x: &[Vec3],
    out: &mut Vec<MassPoint>,
) -> ElementResult<()> {
    validate::<E, N>(x, E::MASS_RULE)?;
    let n = 3 * N;
    out.reserve(E::MASS_RULE.len());
    for point in E::MASS_RULE {
        let shape = E::shape_functions(point.coordinates);
        let determinant = jacobian_determinant::<E, N>(x, point.coordinates);
        let mut position = Vec3::ZERO;
        let mut s = vec![0.0; 3 * n];
        for (a, (na, xa)) in shape.iter().zip(x).enumerate() {
            position += *na * *xa;
            for r in 0..3 {
                s[r * n + 3 * a + r] = *na;
            }
        }
        out.push(MassPoint { weight: material.density * point.weight * determinant, position, shape: s });
    }
    Ok(())
}

/// HRZ lumped masses at the nodes: m_a = m M_aa / sum_b M_bb with M_aa = int rho N_a^2 dV.
pub(super) fn lumped_mass_points<E: Isoparametric<N>, const N: usize>(
    material: &Material,
    x: &[Vec3],
    out: &mut Vec<MassPoint>,
) -> ElementResult<()> {
    validate::<E, N>(x, E::MASS_RULE)?;
    let n = 3 * N;
    // Element mass and the diagonal of the consistent mass matrix.
    let mut mass = 0.0;
    let mut diagonal = [0.0; N];
    for point in E::MASS_RULE {
        let shape = E::shape_functions(point.coordinates);
        let dm = material.density * point.weight * jacobian_determinant::<E, N>(x, point.coordinates);
        mass += dm;
        for (da, na) in diagonal.iter_mut().zip(&shape) {
            *da += dm * na * na;
        }
    }
    let diagonal_sum: f64 = diagonal.iter().sum();
    // One point per node, its shape matrix selecting the node's displacement.
    out.reserve(N);
    for (a, (da, xa)) in diagonal.iter().zip(x).enumerate() {
        let mut s = vec![0.0; 3 * n];
        for r in 0..3 {
            s[r * n + 3 * a + r] = 1.0;
        }
        out.push(MassPoint { weight: mass * da / diagonal_sum, position: *xa, shape: s });
    }
    Ok(())
}

/// Volume int dV with the mass rule.
pub(super) fn volume<E: Isoparametric<N>, const N: usize>(x: &[Vec3]) -> ElementResult<f64> {
    validate::<E, N>(x, E::MASS_RULE)?;
    Ok(E::MASS_RULE.iter().map(|p| p.weight * jacobian_determinant::<E, N>(x, p.coordinates)).sum())
}
