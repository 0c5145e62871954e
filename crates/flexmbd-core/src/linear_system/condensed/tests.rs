//! Tests of the condensed solver: its solves against the sparse LU solve of the whole Newton
//! matrix, its structured coupling against the assembled rows and columns, and the kept
//! factorizations, deformation solves and coupling basis.

use super::factor::ReducedLu;
use super::reference::{COLUMN_VECTORS, ROW_VECTORS};
use super::{flexible, CondensedSolver};
use crate::assembly::MatrixCoefficients;
use crate::assembly::{assemble, ElasticRows, Request, StateView};
use crate::body::flexible::tests::PointBody;
use crate::body::flexible::{dot, FlexibleBody, REFERENCE_COORDINATES};
use crate::body::marker::MarkerElastic;
use crate::joint::JointKind;
use crate::linalg::sparse::SparseLu;
use crate::linear_system::LinearSolvers;
use crate::math::{Mat3, Vec3};
use crate::system::model::Model;
use crate::system::{State, SystemBuilder, Workspace};
use crate::testing::assert_all_close;

/// Iteration-matrix coefficients shared by the tests (s m = 1, as for generalized-alpha).
const ITERATION: MatrixCoefficients = MatrixCoefficients {
    mass: 4.0e4,
    velocity: 2.0e2,
    position: 1.0,
    identity: 0.0,
    elastic_identity: 0.0,
    scale: 2.5e-5,
};

/// A rigid link hinged to the ground and a deformable body hinged to it (at a reference
/// marker, or at an elastic one), the deformable body condensed or not.
fn model(condense: bool, elastic_marker: bool) -> Model {
    let mut sys = SystemBuilder::new();
    sys.set_gravity(Vec3([0.0, -9.81, 0.0])).unwrap();
    let link = sys
        .add_rigid_body(
            "link",
            2.0,
            Mat3::diagonal(Vec3([0.1, 0.2, 0.2])),
            Vec3::ZERO,
            Vec3([0.5, 0.0, 0.0]),
            Mat3::IDENTITY,
            Vec3::ZERO,
            Vec3::ZERO,
        )
        .unwrap();
    let mut input = PointBody::random(8, 6, 41).input(30.0, 0.5);
    input.condense = Some(condense);
    let body = FlexibleBody::new("flexible", input).unwrap();
    let fb = sys
        .add_flexible_body(
            "flexible",
            body,
            Vec3([1.0, 0.0, 0.0]),
            Mat3::IDENTITY,
            Vec3::ZERO,
            Vec3::ZERO,
            vec![0.01; 6],
            vec![],
        )
        .unwrap();
    let ground = sys.ground();
    let g = sys.add_marker("", ground, Vec3::ZERO, Mat3::IDENTITY).unwrap();
    let a = sys.add_marker("", link, Vec3([-0.5, 0.0, 0.0]), Mat3::IDENTITY).unwrap();
    let b = sys.add_marker("", link, Vec3([0.5, 0.0, 0.0]), Mat3::IDENTITY).unwrap();
    let c = if elastic_marker {
        let mut lcg = crate::body::flexible::tests::Lcg(7);
        let mut shape =
            || crate::math::dense::Jacobian3 { n: 6, data: (0..18).map(|_| 0.2 * lcg.next()).collect() };
        let elastic = MarkerElastic { indices: (0..6).collect(), translation: shape(), rotation: shape() };
        sys.add_flexible_marker("", fb, Vec3([0.3, 0.1, 0.0]), Mat3::IDENTITY, elastic).unwrap()
    } else {
        sys.add_marker("", fb, Vec3::ZERO, Mat3::IDENTITY).unwrap()
    };
    sys.add_joint("", JointKind::Revolute, [g, a]).unwrap();
    sys.add_joint("", JointKind::Revolute, [b, c]).unwrap();
    sys.compile().unwrap()
}

#[test]
fn condensed_solves_equal_the_direct_solves_where_the_elastic_block_is_constant() {
    // At rest (w = alpha = 0) the elastic block of the Newton matrix is exactly
    // s (m M_ff + v D_ff + p K_ff): the exact condensed solver must reproduce the LU solve.
    for elastic_marker in [false, true] {
        compare_solves(elastic_marker);
    }
}

#[test]
fn approximate_reference_coupling_is_exact_in_its_mass_part_for_a_deformed_body() {
    // With only the mass term (no velocity or position parts to leave out) the structured
    // coupling must reproduce the direct solve, also when the body is deformed: it uses
    // the deformed J_f = J_f0 + dJ(q_f), not the undeformed J_f0.
    let (direct, condensed) = (model(false, false), model(true, false));
    let mut state = State::initial(&direct, 0.0);
    let offset = direct.bodies[2].offset + REFERENCE_COORDINATES;
    for (k, x) in state.coordinates[offset..offset + 6].iter_mut().enumerate() {
        *x = 0.05 * (k as f64 - 2.5);
    }
    let rhs = test_rhs(direct.system_size());
    let c = MatrixCoefficients::ACCELERATION;
    let expected = direct_solve(&direct, &state, c, &rhs);
    let (x, _) = condensed_solve(&condensed, &state, c, &rhs, true);
    assert_all_close(&x, &expected, 0.0, 1e-9 * scale_of(&expected), "condensed against direct solve");
}

#[test]
fn elastic_rows_from_the_solve_equal_the_assembled_rows() {
    // One Newton iteration as the integrator makes it (rows kept at the first assembly,
    // structured coupling, update of q, q_dot, q_dd by (1, v, m) dq): the residual at the
    // new iterate from the solve's coupling image must equal the one assembled whole, in
    // a moving, deformed state with multipliers (joint at an elastic marker).
    let model = model(true, true);
    let mut state = moving_deformed_state(&model);
    state.multipliers.iter_mut().enumerate().for_each(|(k, l)| *l = 0.4 * k as f64 - 1.1);
    let offset = model.bodies[2].offset + REFERENCE_COORDINATES;
    let c = ITERATION;
    let (nq, s) = (model.coordinate_count, c.scale);
    let mut ws = Workspace::new(&model);
    let mut solvers = LinearSolvers::new(&model).unwrap();
    let keep =
        Request { structured_coupling: true, elastic_rows: ElasticRows::Keep, ..Request::solving(Some(c)) };
    assemble(&model, StateView::of(&state), &mut ws, &keep).unwrap();
    let before = scale_of(&ws.residual);
    let mut x: Vec<f64> =
        ws.residual.iter().enumerate().map(|(k, r)| if k < nq { -s * r } else { -r }).collect();
    let LinearSolvers::Condensed { newton, .. } = &mut solvers else { panic!("condensed solvers") };
    newton.factorize(&model, &ws.values, &c, &state.coordinates).unwrap();
    newton.solve_in_place(&mut x).unwrap();
    for k in 0..nq {
        state.coordinates[k] += x[k];
        state.velocities[k] += c.velocity * x[k];
        state.accelerations[k] += c.mass * x[k];
    }
    for (l, dl) in state.multipliers.iter_mut().zip(&x[nq..]) {
        *l += dl / s;
    }
    let images = solvers.coupling_images();
    let update =
        Request { elastic_rows: ElasticRows::Update { scale: s }, images: &images, ..Request::solving(None) };
    assemble(&model, StateView::of(&state), &mut ws, &update).unwrap();
    drop(images);
    let updated = ws.residual.clone();
    let mut whole = Workspace::new(&model);
    assemble(&model, StateView::of(&state), &mut whole, &Request::residual()).unwrap();
    let elastic = offset..offset + 6;
    let what = format!("updated rows against the whole residual (before {before})");
    assert_all_close(&updated, &whole.residual, 0.0, 1e-12 * before, what);
    // Not trivially equal: the elastic rows are not zero, and the image is not small.
    let rows = elastic.fold(0.0f64, |m, k| m.max(whole.residual[k].abs()));
    assert!(rows > 1e-3 * before, "{rows} vs {before}");
    let image = newton_image(&mut solvers, 2);
    assert!(image.iter().any(|&v| v.abs() > 1e-3 * before * s), "the coupling image is not needed");
}

#[test]
fn structured_reference_coupling_has_the_velocity_part_of_a_spinning_body() {
    // Undeformed, no elastic velocities, spinning about a skew axis: the structured
    // columns of the reference coordinates (as eliminated) and their rows must equal the
    // assembled mass and velocity parts of N_F,ref and N_ref,F exactly (no position part:
    // coefficient 0).
    let model = model(true, false);
    let mut state = State::initial(&model, 0.0);
    let o = model.bodies[2].offset;
    let w = [0.7, -1.3, 2.1];
    for i in 0..3 {
        state.velocities[o + 4 + i] = 0.5 * w[i];
    }
    let elastic = o + REFERENCE_COORDINATES..o + REFERENCE_COORDINATES + 6;
    state.coordinates[elastic.clone()].iter_mut().for_each(|x| *x = 0.0);
    state.velocities[elastic].iter_mut().for_each(|x| *x = 0.0);
    let c = MatrixCoefficients { position: 0.0, ..ITERATION };
    let ws = assembled(&model, &state, c);
    let mut mass_only = Workspace::new(&model);
    let mass = MatrixCoefficients { velocity: 0.0, ..c };
    assemble(&model, StateView::of(&state), &mut mass_only, &Request::matrix(mass)).unwrap();
    let mut solver = CondensedSolver::with_images(&model, true, true).unwrap();
    solver.set_angular_velocities(&model, &state.coordinates, &state.velocities);
    solver.factorize(&model, &ws.values, &c, &state.coordinates).unwrap();
    let block = &mut solver.blocks[0];
    let coupling = block.structured.expect("a structured coupling");
    block.form_reference(&coupling);
    let m = block.n;
    let mut velocity_part = 0.0f64;
    for col in 0..7 {
        let j = block.reference[col];
        let mut assembled = vec![0.0; m];
        for &(f, k) in &block.column_entries[j] {
            assembled[f] = ws.values[k];
        }
        let eliminated = &block.w[j * m..(j + 1) * m];
        let mass_column = |f: usize| {
            block.column_entries[j].iter().find(|e| e.0 == f).map_or(0.0, |&(_, k)| mass_only.values[k])
        };
        let scale = scale_of(&assembled);
        assert_all_close(eliminated, &assembled, 0.0, 1e-12 * scale, format_args!("column {col}, row"));
        if col >= 3 {
            let mass_only: f64 = (0..m).map(|f| (eliminated[f] - mass_column(f)).abs()).fold(0.0, f64::max);
            velocity_part = velocity_part.max(mass_only / scale);
        }
        // The row N_jF likewise.
        let mut assembled_row = vec![0.0; m];
        for &(f, k) in &block.row_entries[j] {
            assembled_row[f] = ws.values[k];
        }
        let row_scale = scale_of(&assembled_row);
        let theirs: Vec<f64> = block.row_entries[j].iter().map(|&(g, _)| assembled_row[g]).collect();
        let tolerance = 1e-12 * row_scale;
        assert_all_close(&block.row_values[j], &theirs, 0.0, tolerance, format_args!("row {col}, entry"));
    }
    // Not trivially equal: the velocity part is not negligible against the mass part.
    assert!(velocity_part > 1e-4, "velocity part {velocity_part}");
}

#[test]
fn reference_schur_block_from_the_small_products_equals_the_dot_products() {
    // Deformed (dJ solved) and spinning: the block N_JF Z of the reference rows and columns
    // from R G C (`reference_coupling`) equals the dot products of the rows and columns it
    // formed, and the factorization subtracted it (the solve test above covers that).
    let model = model(true, false);
    let state = moving_deformed_state(&model);
    let ws = assembled(&model, &state, ITERATION);
    let mut solver = CondensedSolver::with_images(&model, true, true).unwrap();
    solver.set_angular_velocities(&model, &state.coordinates, &state.velocities);
    assert!(solver.blocks[0].angular_velocity.0.iter().any(|&x| x.abs() > 0.1), "spinning");
    solver.factorize(&model, &ws.values, &ITERATION, &state.coordinates).unwrap();
    let block = &mut solver.blocks[0];
    let q = &state.coordinates[model.bodies[block.body].offset..];
    let structured = block.reference_coupling(flexible(&model, block.body), &ITERATION, q).unwrap();
    let structured = structured.expect("dense reference rows");
    assert!(!block.factors[block.current].deformation.is_empty(), "dJ solved");
    let coupling = block.structured.expect("a structured coupling");
    assert_eq!((coupling.row_count, coupling.column_count), (ROW_VECTORS, COLUMN_VECTORS));
    block.form_reference(&coupling);
    let m = block.n;
    let explicit: Vec<Vec<f64>> = block
        .reference
        .iter()
        .map(|&ja| {
            block
                .reference
                .iter()
                .map(|&jb| dot(&block.row_values[ja], &block.z[jb * m..(jb + 1) * m]))
                .collect()
        })
        .collect();
    let scale = explicit.iter().flatten().fold(0.0f64, |s, x| s.max(x.abs()));
    assert!(scale > 0.0);
    let explicit = explicit.concat();
    assert_all_close(structured.as_flattened(), &explicit, 0.0, 1e-11 * scale, "N_JF Z, 7 a + b");
}

#[test]
fn reference_coupling_applied_from_kept_vectors_equals_the_formed_one() {
    // Deformed, spinning, with a joint at an elastic marker (other coupling columns and
    // rows): the structured coupling applied from its kept vectors (Schur complement,
    // solves, coupling images) must equal the one formed in Z, W and the rows.
    let model = model(true, true);
    let state = moving_deformed_state(&model);
    let ws = assembled(&model, &state, ITERATION);
    let rhs = test_rhs(model.system_size());
    let mut results = Vec::new();
    for apply_kept in [true, false] {
        let mut solver = CondensedSolver::with_images(&model, true, true).unwrap();
        solver.blocks[0].apply_kept = apply_kept;
        solver.set_angular_velocities(&model, &state.coordinates, &state.velocities);
        solver.factorize(&model, &ws.values, &ITERATION, &state.coordinates).unwrap();
        assert_eq!(solver.blocks[0].structured.is_some(), apply_kept);
        let others = (0..solver.blocks[0].coupling.len()).filter(|j| !solver.blocks[0].reference.contains(j));
        assert!(others.count() > 0, "other coupling columns");
        let mut x = rhs.clone();
        solver.solve_in_place(&mut x).unwrap();
        let image: Vec<f64> = solver.coupling_images().next().unwrap().1.to_vec();
        results.push((solver.reduced_values.clone(), x, image));
    }
    let (kept, formed) = (&results[0], &results[1]);
    for (ours, theirs, what) in [
        (&kept.0, &formed.0, "reduced values"),
        (&kept.1, &formed.1, "solve"),
        (&kept.2, &formed.2, "coupling image"),
    ] {
        let scale = scale_of(theirs);
        assert!(scale > 0.0);
        assert_all_close(ours, theirs, 0.0, 1e-12 * scale, format_args!("kept against formed: {what}"));
    }
}

#[test]
fn dense_and_sparse_reduced_factorizations_give_the_same_solves() {
    // Small reduced systems are factorized dense, large ones sparse: both must solve alike.
    let model = model(true, true);
    let state = moving_deformed_state(&model);
    let c = ITERATION;
    let ws = assembled(&model, &state, c);
    let rhs = test_rhs(model.system_size());
    let mut solves = Vec::new();
    for sparse in [false, true] {
        let mut solver = CondensedSolver::new(&model, true).unwrap();
        if sparse {
            let ReducedLu::Dense { pattern, .. } = &solver.lu else { panic!("a small system is dense") };
            solver.lu = ReducedLu::Sparse(SparseLu::new(pattern).unwrap());
        }
        solver.factorize(&model, &ws.values, &c, &state.coordinates).unwrap();
        let mut x = rhs.clone();
        solver.solve_in_place(&mut x).unwrap();
        solves.push(x);
    }
    let what = "sparse against dense reduced solve";
    assert_all_close(&solves[1], &solves[0], 0.0, 1e-9 * scale_of(&solves[0]), what);
}

fn newton_image(solvers: &mut LinearSolvers, body: usize) -> Vec<f64> {
    let LinearSolvers::Condensed { newton, .. } = solvers else { panic!("condensed solvers") };
    newton.coupling_images().find(|(b, _)| *b == body).map(|(_, i)| i.to_vec()).unwrap()
}

#[test]
fn factorizations_of_a_serve_coefficients_equal_to_round_off() {
    // A step shortened by round-off (coefficients a few ulps off) keeps the factor of A;
    // other coefficients get their own (at most two are kept).
    let condensed = model(true, false);
    let mut solver = CondensedSolver::new(&condensed, true).unwrap();
    let mut ws = Workspace::new(&condensed);
    let state = State::initial(&condensed, 0.0);
    let method = crate::integrator::generalized_alpha::GeneralizedAlpha::from_spectral_radius(0.9).unwrap();
    let h = 1e-3;
    for (step, factors) in [(h, 1), (h * (1.0 - 4.0 * f64::EPSILON), 1), (h * (1.0 - 1e-9), 2)] {
        let c = method.coefficients(step);
        assemble(&condensed, StateView::of(&state), &mut ws, &Request::matrix(c)).unwrap();
        solver.factorize(&condensed, &ws.values, &c, &state.coordinates).unwrap();
        assert_eq!(solver.blocks[0].factors.len(), factors, "step {step:e}");
    }
}

#[test]
fn a_factor_of_a_refactorized_for_a_third_step_size_solves_as_a_fresh_one() {
    // A third step size takes the place of the older of the two kept factors of A and
    // refactorizes it numerically with its ordering and symbolic analysis: its solves equal
    // those of a solver that factorized A for that step size alone.
    let condensed = model(true, false);
    let state = moving_deformed_state(&condensed);
    let method = crate::integrator::generalized_alpha::GeneralizedAlpha::from_spectral_radius(0.9).unwrap();
    let rhs = test_rhs(condensed.system_size());
    let solve_after = |steps: &[f64]| {
        let mut solver = CondensedSolver::new(&condensed, true).unwrap();
        let mut x = rhs.clone();
        for &step in steps {
            let c = method.coefficients(step);
            let ws = assembled(&condensed, &state, c);
            solver.factorize(&condensed, &ws.values, &c, &state.coordinates).unwrap();
            x = rhs.clone();
            solver.solve_in_place(&mut x).unwrap();
        }
        assert_eq!(solver.blocks[0].factors.len(), steps.len().min(2));
        x
    };
    let recycled = solve_after(&[1e-3, 2.5e-4, 5e-4]);
    let fresh = solve_after(&[5e-4]);
    assert_all_close(&recycled, &fresh, 1e-12, 0.0, "solve with a refactorized A against a fresh one");
}

#[test]
fn deformation_solves_are_kept_while_the_deformation_coupling_changes_little() {
    // A factorization at a deformation close to that of the kept solves of dJ reuses them
    // (its solve is then close to, not equal to, the direct one); a larger change solves
    // again and is exact (mass part only, as above).
    let (direct, condensed) = (model(false, false), model(true, false));
    let c = MatrixCoefficients::ACCELERATION;
    let rhs = test_rhs(direct.system_size());
    let mut solver = CondensedSolver::new(&condensed, true).unwrap();
    let mut ws = Workspace::new(&condensed);
    let offset = direct.bodies[2].offset + REFERENCE_COORDINATES;
    let mut kept = Vec::new();
    for (factor, exact) in [(1.0, true), (1.0 + 1e-4, false), (2.0, true)] {
        let mut state = State::initial(&direct, 0.0);
        for (k, x) in state.coordinates[offset..offset + 6].iter_mut().enumerate() {
            *x = 0.05 * factor * (k as f64 - 2.5);
        }
        let expected = direct_solve(&direct, &state, c, &rhs);
        assemble(&condensed, StateView::of(&state), &mut ws, &Request::matrix(c)).unwrap();
        solver.factorize(&condensed, &ws.values, &c, &state.coordinates).unwrap();
        let mut x = rhs.clone();
        solver.solve_in_place(&mut x).unwrap();
        let scale = scale_of(&expected);
        if exact {
            assert_all_close(&x, &expected, 0.0, 1e-9 * scale, format_args!("factor {factor}"));
        } else {
            let worst = x.iter().zip(&expected).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            assert!(worst > 1e-12 * scale && worst < 1e-3 * scale, "factor {factor}: off by {worst}");
        }
        let block = &solver.blocks[0];
        kept.push(block.factors[block.current].deformation.clone());
    }
    assert_eq!(kept[0], kept[1], "the solves of dJ were made again for a small change");
    assert_ne!(kept[1], kept[2], "the solves of dJ were kept for a large change");
}

#[test]
fn marker_couplings_of_later_factorizations_come_from_the_coupling_basis() {
    // The joint at the elastic marker couples through A(p) times constant marker rows: the
    // first factorization spans them, later ones at other rotations reuse that span
    // (no solves) and still reproduce the direct solve (zero velocities and multipliers:
    // the elastic block is constant there).
    let (direct, condensed) = (model(false, true), model(true, true));
    let c = ITERATION;
    let rhs = test_rhs(direct.system_size());
    let mut solver = CondensedSolver::new(&condensed, false).unwrap();
    let mut ws = Workspace::new(&condensed);
    let axis = Vec3([0.3, -0.5, 0.8]) * (1.0 / Vec3([0.3, -0.5, 0.8]).norm());
    let mut sizes = Vec::new();
    for angle in [0.0f64, 0.4, 1.3, -2.0] {
        let mut state = State::initial(&direct, 0.0);
        for (body, turn) in [(1, 0.5 * angle), (2, angle)] {
            let o = direct.bodies[body].offset;
            let (cos, sin) = ((0.5 * turn).cos(), (0.5 * turn).sin());
            state.coordinates[o + 3..o + 7].copy_from_slice(&[
                cos,
                sin * axis[0],
                sin * axis[1],
                sin * axis[2],
            ]);
        }
        let expected = direct_solve(&direct, &state, c, &rhs);
        assemble(&condensed, StateView::of(&state), &mut ws, &Request::matrix(c)).unwrap();
        solver.factorize(&condensed, &ws.values, &c, &state.coordinates).unwrap();
        let mut x = rhs.clone();
        solver.solve_in_place(&mut x).unwrap();
        assert_all_close(&x, &expected, 0.0, 1e-9 * scale_of(&expected), "condensed against direct solve");
        let block = &solver.blocks[0];
        sizes.push((block.basis.len() / block.n, block.factors[block.current].basis_solved.len() / block.n));
    }
    assert!(sizes[0].0 > 0 && sizes[0].0 <= 6, "{sizes:?}");
    assert!(sizes.iter().all(|&s| s == (sizes[0].0, sizes[0].0)), "{sizes:?}");
}

#[test]
fn structured_solver_reads_no_assembled_reference_elastic_blocks() {
    // The Newton matrix assembled without the reference-elastic blocks of the condensed
    // body (as the integrator does) must give the structured solver the same solves as the
    // whole matrix, in a moving, deformed state.
    let model = model(true, true);
    let state = moving_deformed_state(&model);
    let c = ITERATION;
    let rhs = test_rhs(model.system_size());
    let solves: Vec<Vec<f64>> = [false, true]
        .into_iter()
        .map(|structured| {
            let mut ws = Workspace::new(&model);
            let request = Request { structured_coupling: structured, ..Request::solving(Some(c)) };
            assemble(&model, StateView::of(&state), &mut ws, &request).unwrap();
            let mut solver = CondensedSolver::new(&model, true).unwrap();
            solver.factorize(&model, &ws.values, &c, &state.coordinates).unwrap();
            let mut x = rhs.clone();
            solver.solve_in_place(&mut x).unwrap();
            x
        })
        .collect();
    let scale = scale_of(&solves[0]);
    assert_all_close(&solves[1], &solves[0], 0.0, 1e-12 * scale, "structured against assembled coupling");
}

/// A state of the test model with velocities, accelerations and the deformable
/// body's elastic coordinates set.
fn moving_deformed_state(model: &Model) -> State {
    let mut state = State::initial(model, 0.0);
    for (k, v) in state.velocities.iter_mut().enumerate() {
        *v = 0.3 * ((k * 7 % 5) as f64 - 2.0);
    }
    for (k, a) in state.accelerations.iter_mut().enumerate() {
        *a = 2.0 * ((k * 3 % 7) as f64 - 3.0);
    }
    let offset = model.bodies[2].offset + REFERENCE_COORDINATES;
    for (k, x) in state.coordinates[offset..offset + 6].iter_mut().enumerate() {
        *x = 0.02 * (k as f64 - 2.5);
    }
    state
}

/// A workspace with the residual and Newton matrix of `model` at `state` assembled with
/// the coefficients `c`.
fn assembled(model: &Model, state: &State, c: MatrixCoefficients) -> Workspace {
    let mut ws = Workspace::new(model);
    assemble(model, StateView::of(state), &mut ws, &Request::matrix(c)).unwrap();
    ws
}

fn test_rhs(n: usize) -> Vec<f64> {
    (0..n).map(|k| ((k * 37 % 11) as f64 - 5.0) * 0.1).collect()
}

/// The sparse LU solve of the assembled Newton matrix of `model` with coefficients `c`.
fn direct_solve(model: &Model, state: &State, c: MatrixCoefficients, rhs: &[f64]) -> Vec<f64> {
    let mut ws = Workspace::new(model);
    assemble(model, StateView::of(state), &mut ws, &Request::matrix(c)).unwrap();
    let mut lu = SparseLu::new(&model.layout.pattern).unwrap();
    lu.factorize(&ws.values).unwrap();
    let mut x = rhs.to_vec();
    lu.solve_in_place(&mut x).unwrap();
    x
}

/// The condensed solve (exact or structured reference coupling) and the reduced size.
fn condensed_solve(
    model: &Model,
    state: &State,
    c: MatrixCoefficients,
    rhs: &[f64],
    approximate_reference: bool,
) -> (Vec<f64>, usize) {
    let mut ws = Workspace::new(model);
    assemble(model, StateView::of(state), &mut ws, &Request::matrix(c)).unwrap();
    let mut solver = CondensedSolver::new(model, approximate_reference).unwrap();
    solver.factorize(model, &ws.values, &c, &state.coordinates).unwrap();
    let mut x = rhs.to_vec();
    solver.solve_in_place(&mut x).unwrap();
    (x, solver.reduced_size())
}

fn scale_of(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |m, x| m.max(x.abs()))
}

fn compare_solves(elastic_marker: bool) {
    let (direct, condensed) = (model(false, elastic_marker), model(true, elastic_marker));
    assert!(!direct.has_condensed_bodies() && condensed.has_condensed_bodies());
    let mut state = State::initial(&direct, 0.0);
    // Multipliers of joints at elastic markers enter N_FF through the constraint Hessian,
    // which A leaves out: zero there for an exact comparison.
    if !elastic_marker {
        state.multipliers.iter_mut().enumerate().for_each(|(k, l)| *l = 0.1 * k as f64 - 0.3);
    }
    let n = direct.system_size();
    let rhs = test_rhs(n);
    let coefficients = [MatrixCoefficients::ACCELERATION, ITERATION];
    for c in coefficients {
        let expected = direct_solve(&direct, &state, c, &rhs);
        let (x, reduced) = condensed_solve(&condensed, &state, c, &rhs, false);
        assert_eq!(reduced, n - 6);
        let scale = scale_of(&expected);
        assert_all_close(&x, &expected, 0.0, 1e-9 * scale, "condensed against direct solve");
        // The approximate reference coupling is an iteration matrix: its solve is close.
        let (y, _) = condensed_solve(&condensed, &state, c, &rhs, true);
        assert_all_close(&y, &expected, 0.0, 0.2 * scale, "approximate solve");
    }
}

#[test]
fn coarse_stage_solves_with_p_plus_g_where_its_space_is_the_whole_space() {
    // The deformable body has six elastic coordinates: the six kept vectors A^-1 [I1^T, J_f^T]
    // and the reduced unknowns span the whole space, so the Galerkin correction of the coarse
    // stage must be the solve with N' = P + G, G = -2 s gamma' sum_i w_i A_i (A_i = I_jk -
    // I_kj, w: the body-frame angular velocity); the rotation rows' difference of N' is zero
    // at a first factorization, whose solves of dJ are made at this q_f. P densely from its
    // solves of the unit vectors, G from the antisymmetric products of the unit vectors. (The
    // dense LU of the coarse system swapped rows of x against rows of L made before a later
    // interchange: 9e-3 off here.)
    let model = model(true, false);
    let mut state = moving_deformed_state(&model);
    // Spinning about a skew axis (the body's frame is the global one: w = 2 [0 | I] p_dot).
    let o = model.bodies[2].offset;
    state.velocities[o + 3] = 0.0;
    for (i, w) in [0.7, -1.3, 2.1].into_iter().enumerate() {
        state.velocities[o + 4 + i] = 0.5 * w;
    }
    let c = ITERATION;
    let ws = assembled(&model, &state, c);
    let mut solver = CondensedSolver::new(&model, true).unwrap();
    solver.set_angular_velocities(&model, &state.coordinates, &state.velocities);
    solver.set_gyroscopic(true);
    solver.factorize(&model, &ws.values, &c, &state.coordinates).unwrap();
    assert!(solver.coarse.is_some(), "a coarse stage");
    let n = model.system_size();
    let unit = |j: usize| (0..n).map(|k| if k == j { 1.0 } else { 0.0 }).collect::<Vec<f64>>();
    // Column-major P^-1, then P.
    let mut p_inverse = Vec::with_capacity(n * n);
    for j in 0..n {
        let mut e = unit(j);
        solver.solve_in_place(&mut e).unwrap();
        p_inverse.extend(e);
    }
    let mut n_prime = dense_inverse(&p_inverse, n);
    let block = &solver.blocks[0];
    let (first, m, w) = (block.first, block.n, block.angular_velocity);
    assert_all_close(&w.0, &[0.7, -1.3, 2.1], 0.0, 1e-14, "angular velocity");
    let fb = flexible(&model, block.body);
    for col in 0..m {
        let e: Vec<f64> = (0..m).map(|k| if k == col { 1.0 } else { 0.0 }).collect();
        let mut products = vec![0.0; 3 * m];
        fb.add_antisymmetric_products(1.0, &e, &mut products);
        for row in 0..m {
            let g: f64 = (0..3).map(|i| w[i] * products[i * m + row]).sum();
            n_prime[(first + col) * n + first + row] -= 2.0 * c.scale * c.velocity * g;
        }
    }
    let rhs = test_rhs(n);
    let expected = dense_solve(&n_prime, n, &rhs);
    let mut x = rhs.clone();
    solver.solve_gyroscopic(&mut x).unwrap();
    let scale = scale_of(&expected);
    assert_all_close(&x, &expected, 0.0, 1e-10 * scale, "coarse stage against the dense solve with P + G");
    // Not trivially: the plain solve with P differs.
    let mut plain = rhs.clone();
    solver.solve_in_place(&mut plain).unwrap();
    let difference = plain.iter().zip(&expected).fold(0.0f64, |d, (a, b)| d.max((a - b).abs()));
    assert!(difference > 1e-6 * scale, "G changes the solve: {difference} vs {scale}");
}

/// x with A x = b for the dense column-major n x n matrix A (Gaussian elimination with
/// partial pivoting).
fn dense_solve(a: &[f64], n: usize, b: &[f64]) -> Vec<f64> {
    let mut a = a.to_vec();
    let mut x = b.to_vec();
    for k in 0..n {
        let p = (k..n).max_by(|&i, &j| a[k * n + i].abs().total_cmp(&a[k * n + j].abs())).unwrap();
        for col in 0..n {
            a.swap(col * n + k, col * n + p);
        }
        x.swap(k, p);
        for i in k + 1..n {
            let f = a[k * n + i] / a[k * n + k];
            for col in k..n {
                a[col * n + i] -= f * a[col * n + k];
            }
            x[i] -= f * x[k];
        }
    }
    for k in (0..n).rev() {
        let sum: f64 = (k + 1..n).map(|col| a[col * n + k] * x[col]).sum();
        x[k] = (x[k] - sum) / a[k * n + k];
    }
    x
}

/// The inverse of the dense column-major n x n matrix `a`, column-major.
fn dense_inverse(a: &[f64], n: usize) -> Vec<f64> {
    (0..n)
        .flat_map(|j| {
            dense_solve(a, n, &(0..n).map(|k| if k == j { 1.0 } else { 0.0 }).collect::<Vec<f64>>())
        })
        .collect()
}
