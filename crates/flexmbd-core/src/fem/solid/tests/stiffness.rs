//! Tests of the stiffness matrices and nodal stresses: symmetry and exactly six rigid-body
//! modes, patch tests (constant strain and the nodal forces of a constant stress from the
//! faces), exact stresses of affine fields.

use super::*;

#[test]
fn affine_displacements_give_their_exact_stress_at_every_node() {
    // u = E x + t: strain (E + E^T)/2 everywhere, stress D eps at every node, for every
    // element shape (curved and distorted ones included: the fields are in their spaces).
    let e = [[1e-3, 2e-4, -5e-4], [-3e-4, 7e-4, 1e-4], [4e-4, -2e-4, -6e-4]];
    let eps = [e[0][0], e[1][1], e[2][2], e[1][2] + e[2][1], e[0][2] + e[2][0], e[0][1] + e[1][0]];
    let d = steel().elasticity();
    let sigma: Vec<f64> = (0..6).map(|r| (0..6).map(|c| d[r][c] * eps[c]).sum()).collect();
    for case in cases() {
        let u = nodal_field(&case.nodes, |p| {
            Vec3(std::array::from_fn(|i| (0..3).map(|j| e[i][j] * p[j]).sum::<f64>() + 0.01 * i as f64))
        });
        let mut out = vec![[0.0; 6]; case.nodes.len()];
        element(case.kind).nodal_stresses(&steel(), &case.nodes, &u, &mut out).unwrap();
        for (a, node) in out.iter().enumerate() {
            assert_all_close(
                node,
                &sigma,
                0.0,
                1e-9 * max_abs(&sigma),
                format_args!("{}: stress at node {a}", case.name),
            );
        }
    }
}

#[test]
fn stiffness_is_symmetric_with_exactly_six_rigid_body_modes() {
    for case in cases() {
        let k = stiffness_of(&case);
        let n = k.rows;
        assert_eq!(n, 3 * case.nodes.len());
        for i in 0..n {
            for j in 0..n {
                assert_eq!(k.get(i, j), k.get(j, i), "{}: K not symmetric at ({i}, {j})", case.name);
            }
        }
        // Infinitesimal rotations u = w x X are strain-free.
        let scale = max_abs(&k.data);
        for axis in 0..3 {
            let w = Vec3::unit(axis);
            let q = nodal_field(&case.nodes, |p| w.cross(&p));
            let force = times(&k, &q);
            let zero = vec![0.0; force.len()];
            let tolerance = RELATIVE * scale * max_abs(&q);
            assert_all_close(
                &force,
                &zero,
                0.0,
                tolerance,
                format_args!("{}: K (w x X), axis {axis}", case.name),
            );
        }
        // Six zero eigenvalues, every other one positive; the reduced Hex20 has six more, the
        // known zero-energy modes of a lone element (see
        // `reduced_hex20_modes_pass_along_a_row_of_elements`).
        let eigenvalues = symmetric_eigenvalues(&k);
        let largest = eigenvalues[n - 1];
        let zero = eigenvalues.iter().filter(|l| l.abs() < 1e-10 * largest).count();
        let expected = if case.kind == Kind::Hex20R { 12 } else { 6 };
        assert_eq!(zero, expected, "{}: eigenvalues {eigenvalues:?}", case.name);
        assert!(eigenvalues[expected] > 1e-6 * largest, "{}: eigenvalues {eigenvalues:?}", case.name);
    }
}

/// Physical strains (Voigt, engineering shear) at the stiffness points for nodal
/// displacements `u`.
fn strains_at_stiffness_points<E: Isoparametric<N>, const N: usize>(x: &[Vec3], u: &[f64]) -> Vec<[f64; 6]> {
    E::STIFFNESS_RULE
        .iter()
        .map(|point| {
            let (g, _) = physical_gradients::<E, N>(x, point.coordinates);
            let mut strain = [0.0; 6];
            for a in 0..N {
                let b = strain_displacement(g[a]);
                for r in 0..6 {
                    strain[r] += (0..3).map(|j| b[r][j] * u[3 * a + j]).sum::<f64>();
                }
            }
            strain
        })
        .collect()
}

/// int B^T sigma dV with the element's own stiffness rule.
fn stress_forces_by_quadrature<E: Isoparametric<N>, const N: usize>(
    x: &[Vec3],
    sigma: &[[f64; 3]; 3],
) -> Vec<f64> {
    let mut f = vec![0.0; 3 * N];
    for point in E::STIFFNESS_RULE {
        let (g, determinant) = physical_gradients::<E, N>(x, point.coordinates);
        for a in 0..N {
            for i in 0..3 {
                f[3 * a + i] +=
                    point.weight * determinant * (0..3).map(|j| sigma[i][j] * g[a][j]).sum::<f64>();
            }
        }
    }
    f
}

/// Outward area vector of the face of a tetrahedron opposite vertex `a`, and its vertices.
fn tetrahedron_face(x: &[Vec3], a: usize) -> ([usize; 3], Vec3) {
    let mut f = [0; 3];
    for (slot, i) in (0..4).filter(|&i| i != a).enumerate() {
        f[slot] = i;
    }
    let area = 0.5 * (x[f[1]] - x[f[0]]).cross(&(x[f[2]] - x[f[0]]));
    let outward = if area.dot(&(x[a] - x[f[0]])) > 0.0 { -area } else { area };
    (f, outward)
}

/// Nodal forces int B_a^T sigma dV = sigma int grad N_a dV = sigma (surface integral of
/// N_a n dA) of a constant stress, from the faces alone (None for a curved Tet10).
fn stress_forces_from_faces(case: &Case, sigma: &[[f64; 3]; 3]) -> Option<Vec<f64>> {
    let x = &case.nodes;
    let mut f = vec![0.0; 3 * x.len()];
    let mut add = |node: usize, area: Vec3| {
        for i in 0..3 {
            f[3 * node + i] += (0..3).map(|j| sigma[i][j] * area[j]).sum::<f64>();
        }
    };
    match case.kind {
        // Linear triangle: int N_a dA = A / 3 on each face through the node.
        Kind::Tet4 => {
            for a in 0..4 {
                let (face, area) = tetrahedron_face(x, a);
                face.iter().for_each(|&b| add(b, area * (1.0 / 3.0)));
            }
        }
        // Quadratic triangle: int N dA = 0 at the corners and A / 3 at the mid-edge nodes.
        Kind::Tet10 => {
            case.moments?;
            for a in 0..4 {
                let (face, area) = tetrahedron_face(x, a);
                for (p, q) in [(face[0], face[1]), (face[1], face[2]), (face[0], face[2])] {
                    let e = TET10_EDGES.iter().position(|edge| *edge == [p, q] || *edge == [q, p]).unwrap();
                    add(4 + e, area * (1.0 / 3.0));
                }
            }
        }
        Kind::Hex8 | Kind::Hex8I => hex_surface_quadrature(x, |face, n, _, area| {
            for (i, node) in face.iter().enumerate() {
                add(*node, n[i] * area);
            }
        }),
        // (the quadratic faces are not integrated here: the element's own rule serves)
        // A pyramid of planar faces: the triangles' A / 3 at their corners, the parallelogram
        // base's A / 4.
        Kind::Pyramid5 => {
            case.fractions.as_ref()?;
            let base = 0.5 * (x[3] - x[1]).cross(&(x[2] - x[0]));
            (0..4).for_each(|a| add(a, base * 0.25));
            for a in 0..4 {
                let b = (a + 1) % 4;
                let area = 0.5 * (x[b] - x[a]).cross(&(x[4] - x[a]));
                [a, b, 4].iter().for_each(|&c| add(c, area * (1.0 / 3.0)));
            }
        }
        // Quadratic faces of the wedges and pyramids of planar, parallelogram faces:
        // int N dA / A = 0 at a triangle's corners and 1/3 at its mid-edge nodes; -1/12 and
        // 1/3 on an 8-node parallelogram, 1/36, 1/9 and 4/9 (centre) on a 9-node one
        // (products of Simpson's weights).
        Kind::Wedge18 | Kind::Pyramid13 | Kind::Pyramid14 => {
            case.fractions.as_ref()?;
            let (edges, offset, faces): (&[[usize; 2]], usize, Vec<Vec<usize>>) = match case.kind {
                Kind::Wedge18 => {
                    let mut faces = vec![vec![0, 2, 1], vec![3, 4, 5]];
                    faces.extend(WEDGE18_FACES.iter().map(|f| f.to_vec()));
                    (&WEDGE15_EDGES, 6, faces)
                }
                _ => (
                    &PYRAMID13_EDGES,
                    5,
                    vec![vec![0, 3, 2, 1], vec![0, 1, 4], vec![1, 2, 4], vec![2, 3, 4], vec![3, 0, 4]],
                ),
            };
            let count = x.len();
            let centroid = (1.0 / count as f64) * x.iter().fold(Vec3::ZERO, |s, p| s + *p);
            for corners in &faces {
                let k = corners.len();
                let mut area = Vec3::ZERO;
                for i in 0..k {
                    area += 0.5 * x[corners[i]].cross(&x[corners[(i + 1) % k]]);
                }
                if area.dot(&(x[corners[0]] - centroid)) < 0.0 {
                    area = -area;
                }
                let lagrange = k == 4 && (case.kind == Kind::Pyramid14 || case.kind == Kind::Wedge18);
                let (corner, middle) = match (k, lagrange) {
                    (3, _) => (0.0, 1.0 / 3.0),
                    (_, false) => (-1.0 / 12.0, 1.0 / 3.0),
                    (_, true) => (1.0 / 36.0, 1.0 / 9.0),
                };
                for i in 0..k {
                    let (p, q) = (corners[i], corners[(i + 1) % k]);
                    let e = edges.iter().position(|edge| *edge == [p, q] || *edge == [q, p]).unwrap();
                    add(p, area * corner);
                    add(offset + e, area * middle);
                }
                if lagrange {
                    // The face's centre: the pyramid's node 13, or the wedge's 15 + face.
                    let centre = match case.kind {
                        Kind::Pyramid14 => 13,
                        _ => 15 + WEDGE18_FACES.iter().position(|f| f[..] == corners[..]).unwrap(),
                    };
                    add(centre, area * (4.0 / 9.0));
                }
            }
        }
        Kind::Hex20 | Kind::Hex20R | Kind::Hex27 | Kind::Wedge6 | Kind::Wedge15 => return None,
    }
    Some(f)
}

#[test]
fn patch_test_linear_field_gives_constant_strain_and_stress_forces() {
    let a = [[1.0e-3, 2.0e-4, -3.0e-4], [5.0e-4, -2.0e-4, 1.0e-4], [-1.0e-4, 3.0e-4, 4.0e-4]];
    let shift = v(1.0e-3, -2.0e-3, 5.0e-4);
    let strain = [a[0][0], a[1][1], a[2][2], a[1][2] + a[2][1], a[0][2] + a[2][0], a[0][1] + a[1][0]];
    let d = steel().elasticity();
    let s: Vec<f64> = (0..6).map(|r| (0..6).map(|c| d[r][c] * strain[c]).sum()).collect();
    let sigma = [[s[0], s[5], s[4]], [s[5], s[1], s[3]], [s[4], s[3], s[2]]];
    for case in cases() {
        let x = &case.nodes;
        let u = nodal_field(x, |p| Mat3(a).mul_vec(&p) + shift);
        // The strain is the constant one at every stiffness point.
        let strains = match case.kind {
            Kind::Tet4 => strains_at_stiffness_points::<Tet4, 4>(x, &u),
            Kind::Tet10 => strains_at_stiffness_points::<Tet10, 10>(x, &u),
            Kind::Hex8 | Kind::Hex8I => strains_at_stiffness_points::<Hex8, 8>(x, &u),
            Kind::Hex20 => strains_at_stiffness_points::<Hex20, 20>(x, &u),
            Kind::Hex20R => strains_at_stiffness_points::<Hex20Reduced, 20>(x, &u),
            Kind::Hex27 => strains_at_stiffness_points::<Hex27, 27>(x, &u),
            Kind::Wedge6 => strains_at_stiffness_points::<Wedge6, 6>(x, &u),
            Kind::Wedge15 => strains_at_stiffness_points::<Wedge15, 15>(x, &u),
            Kind::Wedge18 => strains_at_stiffness_points::<Wedge18, 18>(x, &u),
            Kind::Pyramid5 => strains_at_stiffness_points::<Pyramid5, 5>(x, &u),
            Kind::Pyramid13 => strains_at_stiffness_points::<Pyramid13, 13>(x, &u),
            Kind::Pyramid14 => strains_at_stiffness_points::<Pyramid14, 14>(x, &u),
        };
        for (p, e) in strains.iter().enumerate() {
            assert_all_close(
                e,
                &strain,
                0.0,
                RELATIVE * max_abs(&strain),
                format_args!("{}: strain at point {p}", case.name),
            );
        }
        // Internal forces K u are the nodal forces of the constant stress.
        let k = stiffness_of(&case);
        let internal = times(&k, &u);
        let expected = stress_forces_from_faces(&case, &sigma).unwrap_or_else(|| match case.kind {
            Kind::Tet4 => stress_forces_by_quadrature::<Tet4, 4>(x, &sigma),
            Kind::Tet10 => stress_forces_by_quadrature::<Tet10, 10>(x, &sigma),
            Kind::Hex8 | Kind::Hex8I => stress_forces_by_quadrature::<Hex8, 8>(x, &sigma),
            Kind::Hex20 => stress_forces_by_quadrature::<Hex20, 20>(x, &sigma),
            Kind::Hex20R => stress_forces_by_quadrature::<Hex20Reduced, 20>(x, &sigma),
            Kind::Hex27 => stress_forces_by_quadrature::<Hex27, 27>(x, &sigma),
            Kind::Wedge6 => stress_forces_by_quadrature::<Wedge6, 6>(x, &sigma),
            Kind::Wedge15 => stress_forces_by_quadrature::<Wedge15, 15>(x, &sigma),
            Kind::Wedge18 => stress_forces_by_quadrature::<Wedge18, 18>(x, &sigma),
            Kind::Pyramid5 => stress_forces_by_quadrature::<Pyramid5, 5>(x, &sigma),
            Kind::Pyramid13 => stress_forces_by_quadrature::<Pyramid13, 13>(x, &sigma),
            Kind::Pyramid14 => stress_forces_by_quadrature::<Pyramid14, 14>(x, &sigma),
        });
        let scale = max_abs(&k.data) * max_abs(&u);
        assert_all_close(&internal, &expected, 0.0, RELATIVE * scale, format_args!("{}: K u", case.name));
    }
}

#[test]
fn stiffness_output_is_resized_and_overwritten() {
    let case = &cases()[1];
    let fresh = stiffness_of(case);
    let mut reused = DenseMatrix::zeros(12, 12);
    reused.data.iter_mut().for_each(|x| *x = 1.0);
    Tet4.stiffness(&steel(), &case.nodes, &mut reused).unwrap();
    assert_eq!(reused.data, fresh.data);
    let mut wrong_size = DenseMatrix::zeros(3, 5);
    Tet4.stiffness(&steel(), &case.nodes, &mut wrong_size).unwrap();
    assert_eq!((wrong_size.rows, wrong_size.cols), (12, 12));
    assert_eq!(wrong_size.data, fresh.data);
}

#[test]
fn reduced_hex20_modes_pass_along_a_row_of_elements() {
    // Two reduced Hex20 side by side (sharing the face x = 1): three of the six zero-energy
    // modes of a lone element pass to its neighbour (a row of elements one thick keeps them,
    // as Abaqus' C3D20R does; a mesh two elements thick in both other directions has none:
    // tests/test_quadratic_hexahedra.py).
    let left = hex20_from(&box_hex(Vec3::ZERO, 1.0, 1.0, 1.0));
    let right: Vec<Vec3> = left.iter().map(|p| *p + v(1.0, 0.0, 0.0)).collect();
    // Global nodes: the left element's 20, then those of the right one not on the shared face.
    let mut nodes = left.clone();
    let mut map = Vec::new();
    for p in &right {
        match nodes.iter().position(|q| (*q - *p).norm() < 1e-12) {
            Some(i) => map.push(i),
            None => {
                nodes.push(*p);
                map.push(nodes.len() - 1);
            }
        }
    }
    assert_eq!(nodes.len(), 32);
    let n = 3 * nodes.len();
    let mut k = DenseMatrix::zeros(n, n);
    for (x, global) in [(&left, (0..20).collect::<Vec<_>>()), (&right, map)] {
        let mut ke = DenseMatrix::default();
        Hex20Reduced.stiffness(&steel(), x, &mut ke).unwrap();
        for a in 0..60 {
            for b in 0..60 {
                k.add(3 * global[a / 3] + a % 3, 3 * global[b / 3] + b % 3, ke.get(a, b));
            }
        }
    }
    let eigenvalues = symmetric_eigenvalues(&k);
    let largest = eigenvalues[n - 1];
    let zero = eigenvalues.iter().filter(|l| l.abs() < 1e-10 * largest).count();
    assert_eq!(zero, 9, "eigenvalues {:?}", &eigenvalues[..14]);
}
