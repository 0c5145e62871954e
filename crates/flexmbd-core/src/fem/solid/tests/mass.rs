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
        assert!((got.volume - rho * volume).abs() < RELATIVE * rho * volume, "{}", case.name);
        let Some(exact) = case.moments else { continue };
        let (mass, length) = (rho * exact.volume, largest_node_distance(&case.nodes) + case.nodes[0].norm());
        assert!((volume - exact.volume).abs() < RELATIVE * exact.volume, "{}: V = {volume}", case.name);
        assert!((got.volume - mass).abs() < RELATIVE * mass, "{}: m = {}", case.name, got.volume);
        let first_error = (got.first - rho * exact.first).norm();
        assert!(first_error < RELATIVE * mass * length, "{}: s0 = {:?}", case.name, got.first);
        for k in 0..3 {
            for l in 0..3 {
                let error = (got.second[k][l] - rho * exact.second[k][l]).abs();
                assert!(
                    error < RELATIVE * mass * length * length,
                    "{}: J0[{k}][{l}] = {}",
                    case.name,
                    got.second[k][l]
                );
            }
        }
    }
}

#[test]
fn analytic_volumes_and_second_moments() {
    let rho = steel().density;
    let check = |kind: Kind, nodes: Vec<Vec3>, volume: f64, centroid: Vec3, second: [[f64; 3]; 3]| {
        let case = Case { name: "analytic", kind, nodes, moments: None, fractions: None };
        let got = mass_moments(&mass_points_of(&case));
        assert!((element(kind).volume(&case.nodes).unwrap() - volume).abs() < RELATIVE * volume);
        assert!((got.volume - rho * volume).abs() < RELATIVE * rho * volume, "{kind:?}: m = {}", got.volume);
        assert!(
            (got.first - (rho * volume) * centroid).norm()
                < RELATIVE * rho * volume * (1.0 + centroid.norm())
        );
        for k in 0..3 {
            for l in 0..3 {
                let error = (got.second[k][l] - rho * second[k][l]).abs();
                assert!(
                    error < RELATIVE * rho * second[k][l].abs(),
                    "{kind:?}: J0[{k}][{l}] = {}",
                    got.second[k][l]
                );
            }
        }
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
            assert!(error < 1e-14 * (1.0 + point.position.norm()), "{}: {:?}", case.name, point.position);
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
            for j in 0..3 {
                let tj = nodal_field(&case.nodes, |_| Vec3::unit(j));
                let value: f64 = mt.iter().zip(&tj).map(|(a, b)| a * b).sum();
                let expected = if i == j { mass } else { 0.0 };
                assert!((value - expected).abs() < RELATIVE * mass, "{}: t{i} M t{j} = {value}", case.name);
            }
            // Row sums of the x-, y-, z-blocks: int rho N_a dV (closed form when known).
            if let Some((row_sums, _)) = &case.fractions {
                for (a, fraction) in row_sums.iter().enumerate() {
                    for r in 0..3 {
                        let expected = if r == i { fraction * mass } else { 0.0 };
                        let value = mt[3 * a + r];
                        assert!(
                            (value - expected).abs() < RELATIVE * mass,
                            "{}: row {a}/{r}: {value}",
                            case.name
                        );
                    }
                }
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
        assert!((total - mass).abs() < RELATIVE * mass, "{}: lumped total {total} vs {mass}", case.name);
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
        for (a, point) in lumped.iter().enumerate() {
            let expected = mass * m.get(3 * a, 3 * a) / diagonal_sum;
            assert!((point.weight - expected).abs() < RELATIVE * mass, "{}: node {a}", case.name);
        }
        // Closed forms: rho V / 4 (Tet4), rho V / 8 (parallelepiped Hex8), m / 36 at the
        // vertices and 4 m / 27 at the mid-edge nodes (straight Tet10).
        if let Some((_, fractions)) = &case.fractions {
            for (a, (point, fraction)) in lumped.iter().zip(fractions).enumerate() {
                let error = (point.weight - fraction * mass).abs();
                assert!(
                    error < RELATIVE * mass,
                    "{}: node {a}: {} vs {}",
                    case.name,
                    point.weight,
                    fraction * mass
                );
            }
        }
    }
}
