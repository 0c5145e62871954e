//! Tests of the hexahedron with incompatible modes beyond those it shares with the other
//! solids (symmetry, rigid-body modes, patch tests, mass, on the Hex8 shapes in `cases`): the
//! exact pure bending of Saint-Venant's solution, which the trilinear element cannot take.

use super::*;

/// Saint-Venant's pure bending of a prism about the y axis through (y0, z0), curvature kappa:
/// u = k x z', v = -nu k y' z', w = -k/2 (x^2 + nu (z'^2 - y'^2)), with sigma_xx = E k z' the
/// only stress (y' = y - y0, z' = z - z0).
fn pure_bending(p: Vec3, kappa: f64, nu: f64, y0: f64, z0: f64) -> Vec3 {
    let (x, y, z) = (p[0], p[1] - y0, p[2] - z0);
    v(kappa * x * z, -nu * kappa * y * z, -0.5 * kappa * (x * x + nu * (z * z - y * y)))
}

#[test]
fn rectangular_element_takes_pure_bending_exactly() {
    let material = steel();
    let (e, nu) = (2.1e11, 0.3);
    let kappa = 1e-3;
    // Elements as long as deep and longer: the trilinear one locks more the longer it is.
    for (a, b, c) in [(1.0, 0.5, 1.0), (4.0, 1.0, 1.0), (0.3, 0.2, 0.1)] {
        let x = box_hex(v(0.2, -0.1, 0.3), a, b, c);
        let (y0, z0) = (-0.1 + b / 2.0, 0.3 + c / 2.0);
        let u = nodal_field(&x, |p| pure_bending(p, kappa, nu, y0, z0));
        let exact = 0.5 * e * kappa * kappa * a * b * c * c * c / 12.0;
        let energy = |kernel: &dyn ElementKernel| {
            let mut k = DenseMatrix::default();
            kernel.stiffness(&material, &x, &mut k).unwrap();
            0.5 * k.quadratic_form(&u)
        };
        assert_close(energy(&Hex8Incompatible), exact, 1e-12, 0.0, format_args!("energy, {a} x {b} x {c}"));
        // The trilinear element locks in shear: a stiffer bending energy.
        let locked = energy(&Hex8);
        assert!(locked > 1.2 * exact, "Hex8 energy {locked} against {exact} ({a} x {b} x {c})");
        // The stress at every node is sigma_xx = E k z' alone.
        let mut stresses = vec![[0.0; 6]; 8];
        Hex8Incompatible.nodal_stresses(&material, &x, &u, &mut stresses).unwrap();
        for (node, (sigma, p)) in stresses.iter().zip(&x).enumerate() {
            let mut expected = [0.0; 6];
            expected[0] = e * kappa * (p[2] - z0);
            assert_all_close(
                sigma,
                &expected,
                0.0,
                1e-9 * e * kappa * c,
                format_args!("stress at node {node}, {a} x {b} x {c}"),
            );
        }
    }
}

#[test]
fn distorted_element_condenses_to_a_positive_stiffness_softer_than_hex8() {
    // Condensation removes energy: K_Hex8 - K_Hex8I is positive semi-definite (the compatible
    // part of Hex8I's matrix is Hex8's), and Hex8I keeps exactly six zero eigenvalues.
    let x = distorted_hex();
    let (mut k8, mut k8i) = (DenseMatrix::default(), DenseMatrix::default());
    Hex8.stiffness(&steel(), &x, &mut k8).unwrap();
    Hex8Incompatible.stiffness(&steel(), &x, &mut k8i).unwrap();
    let mut difference = k8.clone();
    difference.data.iter_mut().zip(&k8i.data).for_each(|(d, b)| *d -= b);
    let eigenvalues = symmetric_eigenvalues(&difference);
    let largest = max_abs(&k8.data);
    assert!(eigenvalues[0] > -1e-10 * largest, "K_Hex8 - K_Hex8I eigenvalues {eigenvalues:?}");
    assert!(eigenvalues[23] > 1e-3 * largest, "the modes changed nothing: {eigenvalues:?}");
}

#[test]
fn flat_element_is_refused_with_the_element_named() {
    let mut flat = box_hex(Vec3::ZERO, 1.0, 1.0, 1.0);
    for p in &mut flat[4..] {
        p[2] = 0.0;
    }
    let mut k = DenseMatrix::default();
    let error = Hex8Incompatible.stiffness(&steel(), &flat, &mut k).unwrap_err();
    assert!(matches!(error, ElementError::Degenerate { .. }), "{error:?}");
    // Named as the user's element type (it said "a Hex8 element", the routine's).
    assert!(error.to_string().contains("of a hex8i element"), "{error}");
    let mut points = Vec::new();
    let error = Hex8Incompatible.mass_points(&steel(), &flat, &mut points).unwrap_err();
    assert!(error.to_string().contains("of a hex8i element"), "{error}");
}
