//! Tests of the refusal of degenerate, inverted and invalid elements by every kernel.

use super::*;

/// The four kernels on `nodes`, which must all fail with `Degenerate`; returns the details.
fn degenerate_details(kind: Kind, nodes: &[Vec3]) -> Vec<String> {
    let (material, e) = (steel(), element(kind));
    let mut k = DenseMatrix::default();
    let mut points = Vec::new();
    let results = [
        e.stiffness(&material, nodes, &mut k).err(),
        e.mass_points(&material, nodes, &mut points).err(),
        e.lumped_mass_points(&material, nodes, &mut points).err(),
        e.volume(nodes).err(),
    ];
    assert!(points.is_empty(), "{kind:?}: mass points appended despite the error");
    results
        .into_iter()
        .map(|r| match r {
            Some(ElementError::Degenerate { detail }) => detail,
            other => panic!("{kind:?}: expected Degenerate, got {other:?}"),
        })
        .collect()
}

#[test]
fn flat_and_inverted_tetrahedra_are_degenerate() {
    let flat = vec![v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0), v(0.3, 0.3, 0.0)];
    for detail in degenerate_details(Kind::Tet4, &flat) {
        assert!(detail.contains("quadrature point 0"), "{detail}");
    }
    degenerate_details(Kind::Tet10, &tet10_from(&flat));
    // Swapping two vertices inverts the element: det J = -1 everywhere.
    let mut inverted = unit_tet();
    inverted.swap(1, 2);
    for detail in degenerate_details(Kind::Tet4, &inverted) {
        assert!(detail.contains("Jacobian determinant -1.000000e0 at quadrature point 0"), "{detail}");
    }
    for detail in degenerate_details(Kind::Tet10, &tet10_from(&inverted)) {
        assert!(detail.contains("-1.000000e0 at quadrature point 0"), "{detail}");
    }
}

#[test]
fn tet10_with_a_mid_edge_node_near_a_vertex_is_caught_at_the_node() {
    // Beyond the quarter point of edge (0, 1) the Jacobian determinant at vertex 0 turns
    // negative while it stays positive at every quadrature point.
    let mut nodes = tet10_from(&unit_tet());
    nodes[4] = v(0.2, 0.0, 0.0);
    for detail in degenerate_details(Kind::Tet10, &nodes) {
        assert!(detail.contains("at node 0"), "{detail}");
    }
}

#[test]
fn hexahedra_with_collapsed_faces_are_degenerate() {
    // Top face collapsed onto the bottom face: zero volume.
    let mut flat = box_hex(Vec3::ZERO, 1.0, 1.0, 1.0);
    for a in 4..8 {
        flat[a] = flat[a - 4];
    }
    for detail in degenerate_details(Kind::Hex8, &flat) {
        assert!(detail.contains("quadrature point 0"), "{detail}");
    }
    // Top face collapsed to a point (a pyramid): zero determinant at the top corners.
    let mut pyramid = box_hex(Vec3::ZERO, 1.0, 1.0, 1.0);
    for p in &mut pyramid[4..] {
        *p = v(0.5, 0.5, 1.0);
    }
    for detail in degenerate_details(Kind::Hex8, &pyramid) {
        assert!(detail.contains("at node 4"), "{detail}");
    }
    // Mirrored (inverted) box.
    let inverted: Vec<Vec3> =
        box_hex(Vec3::ZERO, 1.0, 1.0, 1.0).into_iter().map(|p| v(p[0], p[1], -p[2])).collect();
    degenerate_details(Kind::Hex8, &inverted);
}

#[test]
fn flat_and_inverted_pyramids_are_degenerate() {
    let base = [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(1.0, 1.0, 0.0), v(0.0, 1.0, 0.0)];
    let pyramid = |apex: Vec3| -> Vec<Vec3> { base.iter().copied().chain([apex]).collect() };
    // The apex in the base's plane: zero volume.
    for detail in degenerate_details(Kind::Pyramid5, &pyramid(v(0.5, 0.5, 0.0))) {
        assert!(detail.contains("quadrature point 0"), "{detail}");
    }
    // Below it (the base clockwise seen from the apex): det J = -0.8 / 4 everywhere.
    for detail in degenerate_details(Kind::Pyramid5, &pyramid(v(0.5, 0.5, -0.8))) {
        assert!(detail.contains("Jacobian determinant -2.000000e-1 at quadrature point 0"), "{detail}");
    }
    // A base node pulled across the apex's axis folds the element.
    let mut folded = pyramid(v(0.5, 0.5, 0.6));
    folded[2] = v(0.2, 0.2, 0.0);
    degenerate_details(Kind::Pyramid5, &folded);
}

#[test]
fn wrong_node_counts_and_non_finite_positions_are_invalid() {
    let material = steel();
    let mut k = DenseMatrix::default();
    let mut points = Vec::new();
    let three = &unit_tet()[..3];
    assert!(matches!(Tet4.stiffness(&material, three, &mut k), Err(ElementError::Invalid { .. })));
    assert!(matches!(
        Tet10.mass_points(&material, &unit_tet(), &mut points),
        Err(ElementError::Invalid { .. })
    ));
    assert!(matches!(Hex8.volume(&tet10_from(&unit_tet())), Err(ElementError::Invalid { .. })));
    let mut bad = unit_tet();
    bad[2] = v(0.0, f64::NAN, 0.0);
    match Tet4.lumped_mass_points(&material, &bad, &mut points) {
        Err(ElementError::Invalid { detail }) => assert!(detail.contains("node 2"), "{detail}"),
        other => panic!("expected Invalid, got {other:?}"),
    }
    assert!(points.is_empty());
}

#[test]
fn inverted_and_folded_quadratic_wedges_and_pyramids_are_degenerate_by_name() {
    // A Wedge18 whose top triangle is below the bottom one (the triangle clockwise seen from
    // the other): det J = -1/2 everywhere; the message names the element.
    let right = wedge([v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0)], v(0.0, 0.0, 1.0));
    let inverted = wedge([v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0)], v(0.0, 0.0, -1.0));
    for detail in degenerate_details(Kind::Wedge18, &wedge18_from(&inverted)) {
        assert!(detail.contains("Jacobian determinant -5.000000e-1 at quadrature point 0"), "{detail}");
        assert!(detail.contains("of a wedge18 element"), "{detail}");
    }
    // A face node pulled across the element folds it near that face.
    let mut folded = wedge18_from(&right);
    folded[15] = v(0.5, 1.2, 0.5);
    for detail in degenerate_details(Kind::Wedge18, &folded) {
        assert!(detail.contains("of a wedge18 element"), "{detail}");
    }
    // Pyramids with the apex below the base: det J = -0.8 / 4 everywhere (as Pyramid5's).
    let base = [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(1.0, 1.0, 0.0), v(0.0, 1.0, 0.0)];
    let corners: Vec<Vec3> = base.iter().copied().chain([v(0.5, 0.5, -0.8)]).collect();
    let below = with_midpoints(&corners, &PYRAMID13_EDGES);
    let mut below14 = below.clone();
    below14.push(v(0.5, 0.5, 0.0));
    for (kind, nodes, name) in
        [(Kind::Pyramid13, below, "pyramid13"), (Kind::Pyramid14, below14, "pyramid14")]
    {
        for detail in degenerate_details(kind, &nodes) {
            assert!(detail.contains("Jacobian determinant -2.000000e-1 at quadrature point 0"), "{detail}");
            assert!(detail.contains(&format!("of a {name} element")), "{detail}");
        }
    }
    // A mid-edge node of an apex edge moved beyond the quarter point next to the apex (at
    // 0.85 of the edge; a quadratic edge folds beyond 3/4): the determinant turns negative
    // near the apex, at the quadrature points next to that edge.
    let corners: Vec<Vec3> = base.iter().copied().chain([v(0.5, 0.5, 0.8)]).collect();
    let mut near_apex = with_midpoints(&corners, &PYRAMID13_EDGES);
    near_apex[9] = 0.15 * corners[0] + 0.85 * corners[4];
    for detail in degenerate_details(Kind::Pyramid13, &near_apex) {
        assert!(detail.contains("at quadrature point"), "{detail}");
        assert!(detail.contains("of a pyramid13 element"), "{detail}");
    }
}
