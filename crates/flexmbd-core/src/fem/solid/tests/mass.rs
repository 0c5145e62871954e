//! Tests of the mass points and lumped masses: exact volumes and moments, the undeformed
//! geometry, the consistent mass matrix, and HRZ lumping with its closed forms.

use super::*;

/// Sum of the weights, first and second moments of a set of mass points.
fn mass_moments(points: &[MassPoint]) -> Moments {
    let mut m = Moments { volume: 0.0, first: Vec3::ZERO, second: [[0.0; 3]; 3] };
    for p in points {
        m.volume += p.weight;
        m.first += p.weight * p.position;
        for k in 0..3 {
            for l in 0..3 {
                m.second[k][l] += p.weight * p.position[k] * p.position[l];
            }
        }
    }
    m
}

fn largest_node_distance(x: &[Vec3]) -> f64 {
    let mut d: f64 = 0.0;
    for p in x {
        for q in x {
            d = d.max((*p - *q).norm());
        }
    }
    d
}

#[test]
fn mass_points_integrate_volume_and_moments_exactly() {
    let rho = steel().density;
    for case in cases() {
        let points = mass_points_of(&case);
        let got = mass_moments(&points);
        let volume = element(case.kind).volume(&case.nodes).unwrap();
        assert_close(got.volume, rho * volume, RELATIVE, 0.0, format_args!("{}: m", case.name));
        let Some(exact) = case.moments else { continue };
        let (mass, length) = (rho * exact.volume, largest_node_distance(&case.nodes) + case.nodes[0].norm());
        assert_close(volume, exact.volume, RELATIVE, 0.0, format_args!("{}: V", case.name));
        assert_close(got.volume, mass, RELATIVE, 0.0, format_args!("{}: m against exact", case.name));
        let first_error = (got.first - rho * exact.first).norm();
        assert_close(
            first_error,
            0.0,
            0.0,
            RELATIVE * mass * length,
            format_args!("{}: |s0 error|", case.name),
        );
        let second = exact.second.map(|row| row.map(|x| rho * x));
        let tolerance = RELATIVE * mass * length * length;
        assert_all_close(
            got.second.as_flattened(),
            second.as_flattened(),
            0.0,
            tolerance,
            format_args!("{}: J0", case.name),
        );
    }
}

#[test]
fn analytic_volumes_and_second_moments() {
    let rho = steel().density;
    let check = |kind: Kind, nodes: Vec<Vec3>, volume: f64, centroid: Vec3, second: [[f64; 3]; 3]| {
        let case = Case { name: "analytic", kind, nodes, moments: None, fractions: None };
        let got = mass_moments(&mass_points_of(&case));
        assert_close(
            element(kind).volume(&case.nodes).unwrap(),
            volume,
            RELATIVE,
            0.0,
            format_args!("{kind:?}: V"),
        );
        assert_close(got.volume, rho * volume, RELATIVE, 0.0, format_args!("{kind:?}: m"));
        let first_error = (got.first - (rho * volume) * centroid).norm();
        let tolerance = RELATIVE * rho * volume * (1.0 + centroid.norm());
        assert_close(first_error, 0.0, 0.0, tolerance, format_args!("{kind:?}: |s0 error|"));
        let second = second.map(|row| row.map(|x| rho * x));
        assert_all_close(
            got.second.as_flattened(),
            second.as_flattened(),
            RELATIVE,
            0.0,
            format_args!("{kind:?}: J0"),
        );
    };
    // Unit tetrahedron: V = 1/6, int x^2 = 1/60, int x y = 1/120.
    let tet_second = [
        [1.0 / 60.0, 1.0 / 120.0, 1.0 / 120.0],
        [1.0 / 120.0, 1.0 / 60.0, 1.0 / 120.0],
        [1.0 / 120.0, 1.0 / 120.0, 1.0 / 60.0],
    ];
    let quarter = v(0.25, 0.25, 0.25);
    check(Kind::Tet4, unit_tet(), 1.0 / 6.0, quarter, tet_second);
    check(Kind::Tet10, tet10_from(&unit_tet()), 1.0 / 6.0, quarter, tet_second);
    // Unit cube: int x^2 = 1/3, int x y = 1/4.
    let cube_second = [[1.0 / 3.0, 0.25, 0.25], [0.25, 1.0 / 3.0, 0.25], [0.25, 0.25, 1.0 / 3.0]];
    check(Kind::Hex8, box_hex(Vec3::ZERO, 1.0, 1.0, 1.0), 1.0, v(0.5, 0.5, 0.5), cube_second);
    // Box a x b x c at the origin: int x_k^2 = V d_k^2 / 3, int x_k x_l = V d_k d_l / 4.
    let (a, b, c) = (2.0, 1.0, 0.5);
    let sides = [a, b, c];
    let mut box_second = [[0.0; 3]; 3];
    for k in 0..3 {
        for l in 0..3 {
            box_second[k][l] = a * b * c * sides[k] * sides[l] / if k == l { 3.0 } else { 4.0 };
        }
    }
    check(Kind::Hex8, box_hex(Vec3::ZERO, a, b, c), a * b * c, v(a / 2.0, b / 2.0, c / 2.0), box_second);
}

#[test]
fn mass_points_reproduce_the_undeformed_geometry() {
    // Isoparametric elements: u0 = S q0 with q0 the nodal positions.
    for case in cases() {
        let q0: Vec<f64> = case.nodes.iter().flat_map(|p| p.0).collect();
        for point in mass_points_of(&case).iter().chain(&lumped_points_of(&case)) {
            let error = (displacement(point, &q0) - point.position).norm();
            let tolerance = 1e-14 * (1.0 + point.position.norm());
            assert_close(
                error,
                0.0,
                0.0,
                tolerance,
                format_args!("{}: |S q0 - x| at {:?}", case.name, point.position),
            );
            assert_eq!(point.shape.len(), 3 * 3 * case.nodes.len());
        }
    }
}

#[test]
fn consistent_mass_matrix_is_symmetric_positive_definite_with_the_element_mass() {
    for case in cases() {
        let points = mass_points_of(&case);
        let n = 3 * case.nodes.len();
        let mut m = DenseMatrix::default();
        mass_matrix(&points, n, &mut m);
        let mass: f64 = points.iter().map(|p| p.weight).sum();
        for i in 0..n {
            for j in 0..n {
                assert_eq!(m.get(i, j), m.get(j, i), "{}: M not symmetric", case.name);
            }
        }
        assert!(is_positive_definite(&m), "{}: M not positive definite", case.name);
        // t_i^T M t_j = m delta_ij for unit translations t_i, t_j.
        for i in 0..3 {
            let ti = nodal_field(&case.nodes, |_| Vec3::unit(i));
            let mt = times(&m, &ti);
            let values: [f64; 3] = std::array::from_fn(|j| {
                let tj = nodal_field(&case.nodes, |_| Vec3::unit(j));
                mt.iter().zip(&tj).map(|(a, b)| a * b).sum()
            });
            let expected: [f64; 3] = std::array::from_fn(|j| if i == j { mass } else { 0.0 });
            assert_all_close(
                &values,
                &expected,
                0.0,
                RELATIVE * mass,
                format_args!("{}: t{i} M t_j", case.name),
            );
            // Row sums of the x-, y-, z-blocks: int rho N_a dV (closed form when known).
            if let Some((row_sums, _)) = &case.fractions {
                let expected: Vec<f64> = row_sums
                    .iter()
                    .flat_map(|fraction| (0..3).map(move |r| if r == i { fraction * mass } else { 0.0 }))
                    .collect();
                assert_all_close(
                    &mt,
                    &expected,
                    0.0,
                    RELATIVE * mass,
                    format_args!("{}: M t{i}, node/row", case.name),
                );
            }
        }
    }
}

#[test]
fn lumped_masses_are_hrz_positive_and_sum_to_the_element_mass() {
    for case in cases() {
        let consistent = mass_points_of(&case);
        let mass: f64 = consistent.iter().map(|p| p.weight).sum();
        let lumped = lumped_points_of(&case);
        assert_eq!(lumped.len(), case.nodes.len());
        let total: f64 = lumped.iter().map(|p| p.weight).sum();
        assert_close(total, mass, RELATIVE, 0.0, format_args!("{}: lumped total", case.name));
        let n = 3 * case.nodes.len();
        for (a, point) in lumped.iter().enumerate() {
            assert!(point.weight > 0.0, "{}: node {a} mass {}", case.name, point.weight);
            assert_eq!(point.position, case.nodes[a]);
            for r in 0..3 {
                for c in 0..n {
                    let expected = if c == 3 * a + r { 1.0 } else { 0.0 };
                    assert_eq!(point.shape[r * n + c], expected, "{}: node {a}", case.name);
                }
            }
        }
        // HRZ by its definition: proportional to the diagonal of the consistent mass matrix.
        let mut m = DenseMatrix::default();
        mass_matrix(&consistent, n, &mut m);
        let diagonal_sum: f64 = (0..case.nodes.len()).map(|a| m.get(3 * a, 3 * a)).sum();
        let weights: Vec<f64> = lumped.iter().map(|p| p.weight).collect();
        let expected: Vec<f64> =
            (0..lumped.len()).map(|a| mass * m.get(3 * a, 3 * a) / diagonal_sum).collect();
        assert_all_close(
            &weights,
            &expected,
            0.0,
            RELATIVE * mass,
            format_args!("{}: HRZ node masses", case.name),
        );
        // Closed forms: rho V / 4 (Tet4), rho V / 8 (parallelepiped Hex8), m / 36 at the
        // vertices and 4 m / 27 at the mid-edge nodes (straight Tet10).
        if let Some((_, fractions)) = &case.fractions {
            let expected: Vec<f64> = fractions.iter().map(|fraction| fraction * mass).collect();
            assert_all_close(
                &weights,
                &expected,
                0.0,
                RELATIVE * mass,
                format_args!("{}: closed-form node masses", case.name),
            );
        }
    }
}
