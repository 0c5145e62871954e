//! Tests of the shell elements: rigid-body modes, membrane and bending patch tests on distorted
//! patches in a general orientation, the mass and rotary inertia of the mass points against
//! the plate's, and refused degenerate elements.

use super::*;
use crate::fem::assembly::{Element, ElementType, Mesh};
use crate::fem::element::mass_matrix;
use crate::fem::solid::tests::symmetric_eigenvalues;
use crate::testing::{assert_all_close, assert_close};

fn aluminium() -> Material {
    Material::new("aluminium", 7e10, 0.3, 2700.0).unwrap()
}

fn section(t: f64) -> ShellSection {
    ShellSection::new("shell", t).unwrap()
}

/// Orthonormal axes of a plane in a general orientation (rows a1, a2, a3 = normal).
fn plane_axes() -> Mat3 {
    let a1 = Vec3::new(0.6, 0.48, 0.64);
    let a1 = a1 * (1.0 / a1.norm());
    let helper = Vec3::new(-0.3, 0.9, 0.1);
    let a2 = helper - a1 * helper.dot(&a1);
    let a2 = a2 * (1.0 / a2.norm());
    Mat3([a1.0, a2.0, a1.cross(&a2).0])
}

/// A point of the plane at local (x, y).
fn place(axes: &Mat3, x: f64, y: f64) -> Vec3 {
    Vec3::new(0.3, -0.2, 0.5) + Vec3(axes.0[0]) * x + Vec3(axes.0[1]) * y
}

fn kernel(kind: &ElementType) -> &dyn ElementKernel {
    match kind {
        ElementType::Quad4(s) => s,
        ElementType::Tri3(s) => s,
        _ => unreachable!(),
    }
}

fn quad(t: f64) -> ElementType {
    ElementType::Quad4(ShellQuad4 { section: section(t) })
}

fn tri(t: f64) -> ElementType {
    ElementType::Tri3(ShellTri3 { section: section(t) })
}

/// The six rigid motions of nodes `x` (translations, then rotations u = w x X, theta = w).
fn rigid_motions(x: &[Vec3]) -> Vec<Vec<f64>> {
    let mut out = Vec::new();
    for k in 0..6 {
        let mut q = vec![0.0; 6 * x.len()];
        for (i, p) in x.iter().enumerate() {
            if k < 3 {
                q[6 * i + k] = 1.0;
            } else {
                let w = Vec3::unit(k - 3);
                q[6 * i..6 * i + 3].copy_from_slice(&w.cross(p).0);
                q[6 * i + 3..6 * i + 6].copy_from_slice(&w.0);
            }
        }
        out.push(q);
    }
    out
}

#[test]
fn flat_elements_have_six_rigid_body_modes_of_zero_energy_and_no_other() {
    let axes = plane_axes();
    let quad_nodes =
        [place(&axes, 0.0, 0.0), place(&axes, 1.1, 0.1), place(&axes, 0.9, 0.8), place(&axes, -0.1, 1.0)];
    let tri_nodes = [place(&axes, 0.0, 0.0), place(&axes, 1.1, 0.1), place(&axes, 0.3, 0.9)];
    for (kind, x) in [(quad(0.05), &quad_nodes[..]), (tri(0.05), &tri_nodes[..])] {
        let element = kernel(&kind);
        let mut k = DenseMatrix::zeros(1, 1);
        element.stiffness(&aluminium(), x, &mut k).unwrap();
        let n = 6 * x.len();
        let largest = symmetric_eigenvalues(&k)[n - 1];
        for (m, q) in rigid_motions(x).iter().enumerate() {
            let mut f = vec![0.0; n];
            k.mul_vec_add(1.0, q, &mut f);
            assert_all_close(
                &f,
                &vec![0.0; n],
                0.0,
                1e-12 * largest,
                format_args!("K q for rigid motion {m}"),
            );
        }
        let values = symmetric_eigenvalues(&k);
        assert!(values[5].abs() < 1e-11 * largest, "{kind:?}: eigenvalue 6 {:e}", values[5]);
        assert!(values[6] > 1e-9 * largest, "{kind:?}: eigenvalue 7 {:e} of {largest:e}", values[6]);
        let entries: Vec<f64> = (0..n * n).map(|i| k.get(i / n, i % n)).collect();
        let transposed: Vec<f64> = (0..n * n).map(|i| k.get(i % n, i / n)).collect();
        assert_all_close(&entries, &transposed, 0.0, 1e-14 * largest, "K against K^T");
    }
}

/// A distorted patch of four quadrilaterals (or eight triangles) around the interior node 4,
/// in the plane of `plane_axes`.
fn patch(triangles: bool, t: f64) -> Mesh {
    let axes = plane_axes();
    let local = [
        [0.0, 0.0],
        [1.1, 0.0],
        [2.0, 0.0],
        [0.0, 1.05],
        [1.15, 0.9],
        [2.0, 0.95],
        [0.0, 2.0],
        [0.9, 2.0],
        [2.0, 2.0],
    ];
    let nodes: Vec<Vec3> = local.iter().map(|p| place(&axes, p[0], p[1])).collect();
    let quads = [[0, 1, 4, 3], [1, 2, 5, 4], [3, 4, 7, 6], [4, 5, 8, 7]];
    let mut elements = Vec::new();
    for (id, q) in quads.iter().enumerate() {
        if triangles {
            for (k, tri_nodes) in [[q[0], q[1], q[2]], [q[0], q[2], q[3]]].iter().enumerate() {
                elements.push(Element { id: (2 * id + k) as i64, kind: tri(t), nodes: tri_nodes.to_vec() });
            }
        } else {
            elements.push(Element { id: id as i64, kind: quad(t), nodes: q.to_vec() });
        }
    }
    Mesh { node_ids: (1..=9).collect(), nodes, elements, material: aluminium() }
}

/// Solves A x = b (dense, Gaussian elimination with partial pivoting).
fn solve(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Vec<f64> {
    let n = b.len();
    for c in 0..n {
        let p = (c..n).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs())).unwrap();
        a.swap(c, p);
        b.swap(c, p);
        for r in c + 1..n {
            let f = a[r][c] / a[c][c];
            for k in c..n {
                a[r][k] -= f * a[c][k];
            }
            b[r] -= f * b[c];
        }
    }
    let mut x = vec![0.0; n];
    for r in (0..n).rev() {
        x[r] = (b[r] - (r + 1..n).map(|k| a[r][k] * x[k]).sum::<f64>()) / a[r][r];
    }
    x
}

/// Displacements of the patch with the boundary nodes given by `exact` and the interior node 4
/// solved from K; compares the interior node with `exact`.
fn patch_solution(mesh: &Mesh, exact: &[f64]) -> Vec<f64> {
    let body = mesh.assemble(false).unwrap();
    let k = &body.stiffness;
    let n = k.nrows;
    let mut dense = vec![vec![0.0; n]; n];
    for c in 0..n {
        for p in k.col_ptr[c]..k.col_ptr[c + 1] {
            dense[k.row_idx[p]][c] = k.values[p];
        }
    }
    let interior: Vec<usize> = (24..30).collect();
    let a: Vec<Vec<f64>> =
        interior.iter().map(|&i| interior.iter().map(|&j| dense[i][j]).collect()).collect();
    let b: Vec<f64> = interior
        .iter()
        .map(|&i| -(0..n).filter(|j| !interior.contains(j)).map(|j| dense[i][j] * exact[j]).sum::<f64>())
        .collect();
    let x = solve(a, b);
    let mut u = exact.to_vec();
    for (k, &i) in interior.iter().enumerate() {
        u[i] = x[k];
    }
    u
}

/// The exact nodal values of a plate field: in-plane displacement (ux, uy) and w with their
/// rotations, as functions of the local coordinates.
fn field(mesh: &Mesh, f: impl Fn(f64, f64) -> ([f64; 3], [f64; 3])) -> Vec<f64> {
    let axes = plane_axes();
    let origin = place(&axes, 0.0, 0.0);
    let mut q = Vec::new();
    for p in &mesh.nodes {
        let d = *p - origin;
        let (u, theta) = f(d.dot(&Vec3(axes.0[0])), d.dot(&Vec3(axes.0[1])));
        q.extend_from_slice(&axes.tr_mul_vec(&Vec3(u)).0);
        q.extend_from_slice(&axes.tr_mul_vec(&Vec3(theta)).0);
    }
    q
}

/// Local plane stress tensor [[xx, xy, 0], [xy, yy, 0], 0] to body Voigt order.
fn body_stress(xx: f64, yy: f64, xy: f64) -> [f64; 6] {
    let a = plane_axes().0;
    let local = [[xx, xy, 0.0], [xy, yy, 0.0], [0.0; 3]];
    let s = |p: usize, q: usize| -> f64 {
        let mut acc = 0.0;
        for i in 0..3 {
            for j in 0..3 {
                acc += a[i][p] * local[i][j] * a[j][q];
            }
        }
        acc
    };
    [s(0, 0), s(1, 1), s(2, 2), s(1, 2), s(0, 2), s(0, 1)]
}

#[test]
fn membrane_patch_test_reproduces_constant_strain() {
    // u = 1e-3 (2 x + 0.5 y), v = 1e-3 (-0.7 x + 1.5 y): omega = (v,x - u,y) / 2.
    let m = aluminium();
    let (exx, eyy, gxy) = (2e-3, 1.5e-3, -0.2e-3);
    let omega = 0.5 * (-0.7e-3 - 0.5e-3);
    let c = m.young_modulus / (1.0 - 0.09);
    let expected = body_stress(c * (exx + 0.3 * eyy), c * (eyy + 0.3 * exx), c * 0.35 * gxy);
    for triangles in [false, true] {
        let mesh = patch(triangles, 0.01);
        let exact = field(&mesh, |x, y| {
            ([1e-3 * (2.0 * x + 0.5 * y), 1e-3 * (-0.7 * x + 1.5 * y), 0.0], [0.0, 0.0, omega])
        });
        let u = patch_solution(&mesh, &exact);
        assert_all_close(
            &u[24..30],
            &exact[24..30],
            1e-9,
            1e-15,
            format_args!("interior node, triangles {triangles}"),
        );
        let stresses = mesh.recover_stresses(&u).unwrap();
        for (node, levels) in stresses.shells.iter().enumerate() {
            for level in levels {
                assert_all_close(
                    level,
                    &expected,
                    0.0,
                    1e-8 * c * exx,
                    format_args!("stress at node {node}"),
                );
            }
        }
    }
}

#[test]
fn bending_patch_test_reproduces_constant_curvature() {
    // w = (a x^2 + b y^2) / 2 + c x y; theta_x = w,y, theta_y = -w,x; kappa = -(a, b, 2 c).
    let m = aluminium();
    let t = 0.02;
    let (a, b, c) = (1e-3, -2e-3, 0.7e-3);
    let modulus = m.young_modulus / (1.0 - 0.09);
    let (kx, ky, kxy) = (-a, -b, -2.0 * c);
    let z = t / 2.0;
    let top =
        body_stress(modulus * z * (kx + 0.3 * ky), modulus * z * (ky + 0.3 * kx), modulus * z * 0.35 * kxy);
    for triangles in [false, true] {
        let mesh = patch(triangles, t);
        let exact = field(&mesh, |x, y| {
            let w = 0.5 * (a * x * x + b * y * y) + c * x * y;
            ([0.0, 0.0, w], [b * y + c * x, -(a * x + c * y), 0.0])
        });
        let u = patch_solution(&mesh, &exact);
        assert_all_close(
            &u[24..30],
            &exact[24..30],
            1e-8,
            1e-14,
            format_args!("interior node, triangles {triangles}"),
        );
        let stresses = mesh.recover_stresses(&u).unwrap();
        let scale = modulus * z * a;
        for (node, levels) in stresses.shells.iter().enumerate() {
            let bottom = top.map(|v| -v);
            assert_all_close(&levels[0], &top, 0.0, 1e-7 * scale, format_args!("top stress at node {node}"));
            assert_all_close(
                &levels[1],
                &[0.0; 6],
                0.0,
                1e-7 * scale,
                format_args!("mid stress at node {node}"),
            );
            assert_all_close(
                &levels[2],
                &bottom,
                0.0,
                1e-7 * scale,
                format_args!("bottom stress at node {node}"),
            );
        }
    }
}

#[test]
fn mass_points_carry_the_plate_mass_moments_and_rotary_inertia() {
    // A rectangle a x b of thickness t in a general orientation.
    let axes = plane_axes();
    let (a, b, t) = (0.8, 0.5, 0.01);
    let m = aluminium();
    let x = [place(&axes, 0.0, 0.0), place(&axes, a, 0.0), place(&axes, a, b), place(&axes, 0.0, b)];
    let mass = m.density * a * b * t;
    let centre = place(&axes, a / 2.0, b / 2.0);
    let d = DRILLING_ARM * t / 2.0;
    for lumped in [false, true] {
        let element = ShellQuad4 { section: section(t) };
        let mut points = Vec::new();
        if lumped {
            element.lumped_mass_points(&m, &x, &mut points).unwrap();
        } else {
            element.mass_points(&m, &x, &mut points).unwrap();
        }
        let total: f64 = points.iter().map(|p| p.weight).sum();
        assert_close(total, mass, 1e-13, 0.0, "mass");
        let first = points.iter().fold(Vec3::ZERO, |s, p| s + p.position * p.weight);
        assert_close((first * (1.0 / mass) - centre).norm(), 0.0, 0.0, 1e-14, "centre of mass");
        // Second moments about the centre in plane axes: m a^2/12 (+ m d^2/3 of the drilling
        // arms), m b^2/12 (+ m d^2/3), m t^2/12 through the thickness (consistent mass).
        let moment = |k: usize| -> f64 {
            let axis = Vec3(axes.0[k]);
            points.iter().map(|p| p.weight * (p.position - centre).dot(&axis).powi(2)).sum()
        };
        if !lumped {
            assert_close(moment(0), mass * (a * a / 12.0 + d * d / 3.0), 1e-12, 0.0, "second moment along a");
            assert_close(moment(1), mass * (b * b / 12.0 + d * d / 3.0), 1e-12, 0.0, "second moment along b");
            assert_close(moment(2), mass * t * t / 12.0, 1e-12, 0.0, "second moment through the thickness");
        }
        // Rotary inertia: theta = e1 at all nodes, no translation: rho A (t^3/12 + t d^2/3);
        // drilling theta = n: rho A t 2 d^2 / 3.
        let mut mm = DenseMatrix::zeros(24, 24);
        mass_matrix(&points, 24, &mut mm);
        for (k, expected) in [(0, t * t / 12.0 + d * d / 3.0), (2, 2.0 * d * d / 3.0)] {
            let mut q = vec![0.0; 24];
            for i in 0..4 {
                q[6 * i + 3..6 * i + 6].copy_from_slice(&axes.0[k]);
            }
            assert_close(
                mm.quadratic_form(&q),
                mass * expected,
                1e-12,
                0.0,
                format_args!("rotary inertia {k}"),
            );
        }
        // Rigid translations are exact: the translational mass in every direction is m.
        for k in 0..3 {
            let mut q = vec![0.0; 24];
            for i in 0..4 {
                q[6 * i + k] = 1.0;
            }
            assert_close(mm.quadratic_form(&q), mass, 1e-13, 0.0, "translational mass");
        }
    }
}

#[test]
fn consistent_mass_of_a_rectangle_is_the_bilinear_mass_matrix() {
    // Translations: rho t a b / 36 [[4, 2, 1, 2], ...] per direction.
    let (a, b, t) = (0.6, 0.4, 0.003);
    let m = aluminium();
    let x = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(a, 0.0, 0.0), Vec3::new(a, b, 0.0), Vec3::new(0.0, b, 0.0)];
    let mut points = Vec::new();
    ShellQuad4 { section: section(t) }.mass_points(&m, &x, &mut points).unwrap();
    let mut mm = DenseMatrix::zeros(24, 24);
    mass_matrix(&points, 24, &mut mm);
    let pattern = [[4.0, 2.0, 1.0, 2.0], [2.0, 4.0, 2.0, 1.0], [1.0, 2.0, 4.0, 2.0], [2.0, 1.0, 2.0, 4.0]];
    let scale = m.density * t * a * b / 36.0;
    for i in 0..4 {
        for j in 0..4 {
            for c in 0..3 {
                assert_close(mm.get(6 * i + c, 6 * j + c), scale * pattern[i][j], 1e-12, 0.0, "M_ij");
            }
        }
    }
}

#[test]
fn degenerate_shells_are_refused() {
    let m = aluminium();
    let mut k = DenseMatrix::zeros(1, 1);
    let line = [Vec3::ZERO, Vec3::new(1.0, 0.0, 0.0), Vec3::new(2.0, 0.0, 0.0)];
    let element = ShellTri3 { section: section(0.01) };
    assert!(matches!(element.stiffness(&m, &line, &mut k), Err(ElementError::Degenerate { .. })));
    // A bow-tie quadrilateral: the Jacobian changes sign.
    let bow = [Vec3::ZERO, Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0), Vec3::new(1.0, 1.0, 0.0)];
    let element = ShellQuad4 { section: section(0.01) };
    assert!(element.stiffness(&m, &bow, &mut k).is_err());
    assert!(ShellSection::new("s", 0.0).is_err());
    assert!(ShellSection::new("s", f64::NAN).is_err());
}

#[test]
fn membrane_stiffening_terms_are_the_mean_von_karman_strains() {
    // In element axes: u = eps0 x, w = p x + r y + c x y. Linear strains (eps0, 0, 0); the
    // means over the rectangle [0, a] x [0, b] of w,x^2 / 2 = (p + c y)^2 / 2,
    // w,y^2 / 2 = (r + c x)^2 / 2 and w,x w,y = (p + c y)(r + c x).
    let (a, b, t) = (0.6, 0.4, 0.003);
    let m = aluminium();
    let (eps0, p, r, c) = (1e-3, 0.02, -0.01, 0.05);
    for corners in [4usize, 3] {
        let all =
            [Vec3::new(0.0, 0.0, 0.0), Vec3::new(a, 0.0, 0.0), Vec3::new(a, b, 0.0), Vec3::new(0.0, b, 0.0)];
        let x: Vec<Vec3> = if corners == 4 { all.to_vec() } else { vec![all[0], all[1], all[2]] };
        let (axes, linear, slopes, stiffness) = membrane_stiffening(&section(t), &m, &x).unwrap();
        let ne = 6 * corners;
        // Local coordinates: the element axes are the body axes here (e1 along x).
        assert_all_close(&axes.0.concat(), &Mat3::IDENTITY.0.concat(), 0.0, 1e-15, "axes");
        let mut e = vec![0.0; ne];
        for (i, node) in x.iter().enumerate() {
            let (px, py) = (node[0], node[1]);
            e[6 * i] = eps0 * px;
            e[6 * i + 2] = p * px + r * py + if corners == 4 { c * px * py } else { 0.0 };
        }
        let strain: Vec<f64> = (0..3).map(|k| (0..ne).map(|j| linear[k * ne + j] * e[j]).sum()).collect();
        assert_all_close(
            &strain,
            &[eps0, 0.0, 0.0],
            0.0,
            1e-15,
            format_args!("linear strains, {corners} nodes"),
        );
        let quadratic: Vec<f64> = (0..3)
            .map(|k| {
                let g = &slopes[k * ne * ne..(k + 1) * ne * ne];
                0.5 * (0..ne).map(|i| e[i] * (0..ne).map(|j| g[i * ne + j] * e[j]).sum::<f64>()).sum::<f64>()
            })
            .collect();
        let expected = if corners == 4 {
            // Means: (p + c y)^2 over y in [0, b], (r + c x)^2 over x in [0, a], and the product.
            let my = |f: &dyn Fn(f64) -> f64, l: f64| (f(0.0) + 4.0 * f(l / 2.0) + f(l)) / 6.0;
            [
                0.5 * my(&|y| (p + c * y).powi(2), b),
                0.5 * my(&|x| (r + c * x).powi(2), a),
                (p + c * b / 2.0) * (r + c * a / 2.0),
            ]
        } else {
            [0.5 * p * p, 0.5 * r * r, p * r]
        };
        assert_all_close(
            &quadratic,
            &expected,
            1e-12,
            0.0,
            format_args!("von Karman terms, {corners} nodes"),
        );
        let area = if corners == 4 { a * b } else { a * b / 2.0 };
        let modulus = m.young_modulus * t / (1.0 - 0.09) * area;
        assert_close(stiffness[0], modulus, 1e-12, 0.0, "S_11 = area E t / (1 - nu^2)");
    }
}

#[test]
fn warped_quadrilaterals_keep_their_rigid_motions_exactly() {
    // Node 3 lifted off the plane of the others by `warp` (relative to the size 1). The
    // element's projected nodes are tied rigidly to the nodes (`Frame::heights`), so rigid
    // motions of the warped nodes strain nothing: no force, no stress, no membrane strain of
    // the geometric stiffness. Without the offsets the rotations about the in-plane axes
    // gave forces of 1.2 % of K's largest entry at a warp of 5e-2 (and the twisted beam of
    // tests/test_shells.py locked) and stresses of 8e7 Pa at a warp of 1e-3; the element
    // mean of the membrane strain, an hourglass pattern then, was zero with or without.
    let axes = plane_axes();
    let n = Vec3(axes.0[2]);
    let material = aluminium();
    for warp in [0.0, 1e-3, 1e-2, 5e-2, 0.2] {
        let x = [
            place(&axes, 0.0, 0.0),
            place(&axes, 1.1, 0.1),
            place(&axes, 0.9, 0.8) + n * warp,
            place(&axes, -0.1, 1.0),
        ];
        let mut k_matrix = DenseMatrix::zeros(1, 1);
        let element = quad(0.05);
        kernel(&element).stiffness(&material, &x, &mut k_matrix).unwrap();
        let values = symmetric_eigenvalues(&k_matrix);
        let largest = values[23];
        assert!(values[5].abs() < 1e-11 * largest && values[6] > 1e-9 * largest, "warp {warp}");
        let ElementType::Quad4(shell) = &element else { unreachable!() };
        let (axes_e, linear, _, _) = membrane_stiffening(&shell.section, &material, &x).unwrap();
        let scale = material.young_modulus;
        for (m, q) in rigid_motions(&x).iter().enumerate() {
            let mut f = vec![0.0; 24];
            k_matrix.mul_vec_add(1.0, q, &mut f);
            assert_all_close(
                &f,
                &[0.0; 24],
                0.0,
                1e-12 * largest,
                format_args!("K q, motion {m}, warp {warp}"),
            );
            let mut stresses = [[[0.0; 6]; 3]; 4];
            shell.surface_stresses(&material, &x, q, &mut stresses).unwrap();
            let flat: Vec<f64> = stresses.iter().flatten().flatten().copied().collect();
            assert_all_close(
                &flat,
                &[0.0; 72],
                0.0,
                1e-12 * scale,
                format_args!("stress, motion {m}, warp {warp}"),
            );
            let local = to_local(&axes_e, q);
            let strains: Vec<f64> =
                linear.chunks(24).map(|row| dot(row.try_into().unwrap(), &local)).collect();
            assert_all_close(
                &strains,
                &[0.0; 3],
                0.0,
                1e-12,
                format_args!("membrane strain, motion {m}, warp {warp}"),
            );
        }
    }
}
