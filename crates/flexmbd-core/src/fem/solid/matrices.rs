//! The element matrices of a solid: the stiffness K = int B^T D B dV and the stresses D B u at
//! the nodes.

use super::geometry::physical_gradients;
use super::validation::validate;
use super::Isoparametric;
use crate::fem::element::ElementResult;
use crate::fem::material::Material;
use crate::math::dense::DenseMatrix;
use crate::math::Vec3;

/// Strain-displacement block B_a (6 x 3) of a node with physical gradient `g`: engineering
/// strains in Voigt order (xx, yy, zz, yz, xz, xy) per unit displacement of the node.
pub(super) fn strain_displacement(g: [f64; 3]) -> [[f64; 3]; 6] {
    let [gx, gy, gz] = g;
    [[gx, 0.0, 0.0], [0.0, gy, 0.0], [0.0, 0.0, gz], [0.0, gz, gy], [gz, 0.0, gx], [gy, gx, 0.0]]
}

/// K = int B^T D B dV (3N x 3N) with the stiffness rule.
pub(super) fn stiffness<E: Isoparametric<N>, const N: usize>(
    material: &Material,
    x: &[Vec3],
    out: &mut DenseMatrix,
) -> ElementResult<()> {
    validate::<E, N>(x, E::STIFFNESS_RULE)?;
    let n = 3 * N;
    if out.rows == n && out.cols == n && out.data.len() == n * n {
        out.fill_zero();
    } else {
        *out = DenseMatrix::zeros(n, n);
    }
    let d = material.elasticity();
    let mut b = [[[0.0; 3]; 6]; N];
    let mut db = [[[0.0; 3]; 6]; N];
    for point in E::STIFFNESS_RULE {
        let (g, determinant) = physical_gradients::<E, N>(x, point.coordinates);
        let dv = point.weight * determinant;
        // B_a and D B_a for every node.
        for a in 0..N {
            b[a] = strain_displacement(g[a]);
            for r in 0..6 {
                for j in 0..3 {
                    db[a][r][j] = (0..6).map(|s| d[r][s] * b[a][s][j]).sum();
                }
            }
        }
        // Upper triangle of B^T D B dV.
        for row in 0..n {
            let (a, i) = (row / 3, row % 3);
            for col in row..n {
                let (c, j) = (col / 3, col % 3);
                let v: f64 = (0..6).map(|r| b[a][r][i] * db[c][r][j]).sum();
                out.add(row, col, dv * v);
            }
        }
    }
    // Mirror the upper triangle: K is symmetric to the last bit.
    for row in 1..n {
        for col in 0..row {
            out.data[row * n + col] = out.data[col * n + row];
        }
    }
    Ok(())
}

/// Stress D B(xi_a) u at every node a of the element (Voigt order, body axes).
pub(super) fn nodal_stresses<E: Isoparametric<N>, const N: usize>(
    material: &Material,
    x: &[Vec3],
    u: &[f64],
    out: &mut [[f64; 6]],
) -> ElementResult<()> {
    validate::<E, N>(x, E::STIFFNESS_RULE)?;
    let d = material.elasticity();
    for (a, xi) in E::NODES.iter().enumerate() {
        let (g, _) = physical_gradients::<E, N>(x, *xi);
        let mut strain = [0.0; 6];
        for (b, gb) in g.iter().enumerate() {
            let bb = strain_displacement(*gb);
            for r in 0..6 {
                strain[r] += (0..3).map(|j| bb[r][j] * u[3 * b + j]).sum::<f64>();
            }
        }
        for r in 0..6 {
            out[a][r] = (0..6).map(|c| d[r][c] * strain[c]).sum();
        }
    }
    Ok(())
}
