//! Assembly of the residual and of the Newton matrix of the augmented formulation
//! (seed eqs. 20 and 26):
//!
//!   r(q, q_dot, q_dd, lambda, t) = M(q) q_dd - F(q, q_dot) - Q_e(q, q_dot, t) + C_q^T lambda
//!   Phi(q, t) = C(q, t)
//!
//! and of the matrix [[s (m M + v D + p K + i I), C_q^T], [C_q, 0]] where D = dr/dq_dot,
//! K = dr/dq (including the constraint Hessian term sum lambda_e C_e,qq and the force
//! Jacobians), and the coefficients (m, v, p, i, s) select the use: the generalized-alpha
//! Newton matrix, the acceleration system of seed eq. 26, or the projections onto the
//! constraint manifold.

use crate::body::flexible::{self, ElasticMass, FlexibleBody, REFERENCE_COORDINATES};
use crate::body::is_condensed;
use crate::body::marker::{marker_kinematics, MarkerKinematics};
use crate::body::{point_mass, rigid, BodyKind};
use crate::error::{FlexmbdError, Result};
use crate::force::gravity::{add_gravity_force, gravity_jacobian};
use crate::force::{evaluate_force, ForceEnv};
use crate::joint::equation::{equation_gradient, equation_value, equations_hessian, MarkerPair};
use crate::math::Mat3;
use crate::system::model::BodyEntries;
use crate::system::workspace::FlexibleWork;
use crate::system::workspace::JointLocal;
use crate::system::{Model, Workspace};

/// Coefficients of the blocks of the assembled matrix.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MatrixCoefficients {
    /// Factor of the mass matrix M = dr/dq_dd.
    pub mass: f64,
    /// Factor of D = dr/dq_dot.
    pub velocity: f64,
    /// Factor of K = dr/dq.
    pub position: f64,
    /// Factor of the identity on the reference coordinates (and rigid bodies, point masses).
    pub identity: f64,
    /// Factor of the identity on the elastic coordinates of deformable bodies: the metric of
    /// the minimum-norm projections weighs their changes separately (see `PROJECTION`).
    pub elastic_identity: f64,
    /// Scale of the whole coordinate block (constraint scaling).
    pub scale: f64,
}

/// Weight of the elastic coordinates' changes against the reference coordinates' in the
/// minimum-norm corrections of initial conditions (`MatrixCoefficients::PROJECTION`).
pub const ELASTIC_PROJECTION_WEIGHT: f64 = 1e6;

impl MatrixCoefficients {
    /// [[M, C_q^T], [C_q, 0]] of seed eq. 26.
    pub const ACCELERATION: MatrixCoefficients = MatrixCoefficients {
        mass: 1.0,
        velocity: 0.0,
        position: 0.0,
        identity: 0.0,
        elastic_identity: 0.0,
        scale: 1.0,
    };
    /// [[W, C_q^T], [C_q, 0]] of the minimum-norm projections of the initial conditions:
    /// W = I on the reference coordinates, `ELASTIC_PROJECTION_WEIGHT` I on the elastic ones,
    /// so that a correction moves and turns bodies rather than deforms them (a joint's marker
    /// 5 cm off a CB interface bent the aluminium link with 9 kJ of strain energy and the run
    /// diverged); a violation that only a deformation can remove still is.
    pub const PROJECTION: MatrixCoefficients = MatrixCoefficients {
        mass: 0.0,
        velocity: 0.0,
        position: 0.0,
        identity: 1.0,
        elastic_identity: ELASTIC_PROJECTION_WEIGHT,
        scale: 1.0,
    };
}

/// What an assembly forms besides the residual, and how (house style 6: the integrator's
/// requests are arguments, never workspace flags). `Request::residual()` and
/// `Request::matrix(c)` assemble everything, as analyses need; the integrator of a model with
/// condensed bodies leaves out the blocks their condensed solves replace.
#[derive(Clone, Copy, Debug)]
pub struct Request<'a> {
    /// The Newton matrix with these coefficients into `ws.values`, or only the residual.
    pub matrix: Option<MatrixCoefficients>,
    /// Whether the elastic blocks of condensed bodies are written into the Newton matrix
    /// (their condensed solves never read them).
    pub condensed_blocks: bool,
    /// Whether the matrix is the Newton iteration matrix of a model with condensed bodies,
    /// whose solver takes the coupling of each condensed body with its own reference
    /// coordinates from its structured mass part (`CondensedSolver::factorize`): those blocks,
    /// and the inertia products only they need, are left out.
    pub structured_coupling: bool,
    /// How the elastic rows of condensed bodies are formed.
    pub elastic_rows: ElasticRows,
    /// For `ElasticRows::Update`: the images of the coupling columns of the last condensed
    /// solve, by body ([`crate::linear_system::LinearSolvers::coupling_images`]).
    pub images: &'a [(usize, &'a [f64])],
}

impl Request<'static> {
    /// The residual of every equation.
    pub fn residual() -> Self {
        Request {
            matrix: None,
            condensed_blocks: true,
            structured_coupling: false,
            elastic_rows: ElasticRows::Whole,
            images: &[],
        }
    }

    /// The residual and the whole Newton matrix with the coefficients `c`.
    pub fn matrix(c: MatrixCoefficients) -> Self {
        Request { matrix: Some(c), ..Self::residual() }
    }

    /// The residual, and the matrix with `c` if given.
    pub fn with(matrix: Option<MatrixCoefficients>) -> Self {
        Request { matrix, ..Self::residual() }
    }

    /// What the integrator's linear solvers read: the residual, and the matrix with `c` if
    /// given, without the elastic blocks of condensed bodies, which their condensed solves
    /// replace.
    pub fn solving(matrix: Option<MatrixCoefficients>) -> Self {
        Request { condensed_blocks: false, ..Self::with(matrix) }
    }
}

/// How the assembly forms the elastic rows of condensed bodies. Their linear part
/// L = M_ff qf_dd + D_ff qf_dot + K_ff q_f changes in a Newton iteration that updates
/// (q, q_dot, q_dd) by (1, v, m) dq by exactly (m M_ff + v D_ff + K_ff) dq_f = A dq_f / s, and
/// the condensed solve gives A dq_f = b_F - W dq_J (W: the coupling columns it eliminated with,
/// b_F = -s r_F). So with the rest of the rows N (everything but L) kept from the last
/// assembly, the rows at the new iterate are N' - N - W dq_J / s: no products with K_ff and
/// M_ff after the first iteration of a step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ElasticRows {
    /// Assembled whole (every assembly outside the Newton iterations).
    Whole,
    /// Assembled whole, and N kept (first iteration of a step).
    Keep,
    /// From the last solve of the condensed Newton solver, whose right-hand side had the
    /// scale `scale` (later iterations; valid only right after such a solve and update).
    Update {
        /// s of the Newton matrix.
        scale: f64,
    },
}

/// The marker pair of joint `j`.
pub fn joint_pair<'a>(model: &'a Model, kinematics: &'a [MarkerKinematics], j: usize) -> MarkerPair<'a> {
    let joint = &model.joints[j];
    let (a, b) = (joint.markers[0].0, joint.markers[1].0);
    MarkerPair {
        body_i: &model.bodies[model.markers[a].body.0],
        marker_i: &model.markers[a],
        kin_i: &kinematics[a],
        body_j: &model.bodies[model.markers[b].body.0],
        marker_j: &model.markers[b],
        kin_j: &kinematics[b],
    }
}

/// Fills the kinematics of every marker.
pub fn update_kinematics(model: &Model, q: &[f64], qd: &[f64], ws: &mut Workspace) {
    for (k, m) in model.markers.iter().enumerate() {
        marker_kinematics(&model.bodies[m.body.0], m, q, qd, &mut ws.markers[k]);
    }
}

/// The state vectors an assembly reads.
#[derive(Clone, Copy)]
pub struct StateView<'a> {
    /// Time.
    pub time: f64,
    /// Coordinates.
    pub q: &'a [f64],
    /// Velocities.
    pub qd: &'a [f64],
    /// Accelerations.
    pub qdd: &'a [f64],
    /// Multipliers.
    pub lambda: &'a [f64],
    /// Discrete variables.
    pub discrete: &'a [f64],
}

impl<'a> StateView<'a> {
    /// The view of a whole state.
    pub fn of(state: &'a crate::system::State) -> Self {
        StateView {
            time: state.time,
            q: &state.coordinates,
            qd: &state.velocities,
            qdd: &state.accelerations,
            lambda: &state.multipliers,
            discrete: &state.discrete,
        }
    }
}

/// Assembles the residual into `ws.residual` and, if the request asks for it, the Newton
/// matrix into `ws.values`. Updates the marker kinematics first.
pub fn assemble(model: &Model, s: StateView, ws: &mut Workspace, request: &Request) -> Result<()> {
    update_kinematics(model, s.q, s.qd, ws);
    ws.residual.iter_mut().for_each(|x| *x = 0.0);
    if request.matrix.is_some() {
        ws.zero_matrix(model, request.condensed_blocks, request.structured_coupling);
    }
    let c = request.matrix.unwrap_or(MatrixCoefficients {
        mass: 0.0,
        velocity: 0.0,
        position: 0.0,
        identity: 0.0,
        elastic_identity: 0.0,
        scale: 0.0,
    });
    assemble_bodies(model, &s, ws, request, &c);
    assemble_normalizations(model, &s, ws, request.matrix.is_some(), &c);
    assemble_joints(model, &s, ws, request.matrix.is_some(), &c)?;
    assemble_forces(model, &s, ws, request.matrix.is_some(), &c)?;
    if request.elastic_rows != ElasticRows::Whole {
        finish_elastic_rows(model, &s, ws, request.elastic_rows, request.images);
    }
    check_finite_residual(model, ws, s.time)
}

impl MatrixCoefficients {
    /// Whether the matrix has a mass, velocity or position Jacobian term.
    fn needs_tangent(&self) -> bool {
        self.mass != 0.0 || self.velocity != 0.0 || self.position != 0.0
    }
}

/// Bodies: inertia forces minus gravity (plus the elastic forces of deformable bodies), and
/// their Jacobians when `request` asks for the matrix (coefficients `c`).
fn assemble_bodies(
    model: &Model,
    s: &StateView,
    ws: &mut Workspace,
    request: &Request,
    c: &MatrixCoefficients,
) {
    for (bi, body) in model.bodies.iter().enumerate() {
        if body.dofs.is_empty() {
            continue;
        }
        if let BodyKind::Flexible(_) = &body.kind {
            let work = ws.flexible[bi].as_mut().expect("workspace of a flexible body");
            assemble_flexible(model, bi, s, work, (&mut ws.residual, &mut ws.values), request, c);
        } else {
            assemble_rigid(model, bi, s, ws, request.matrix.is_some(), c);
        }
    }
}

/// Residual and Newton-matrix entries (if `matrix`) of rigid body or point mass `bi`: its
/// inertia force minus gravity.
fn assemble_rigid(
    model: &Model,
    bi: usize,
    s: &StateView,
    ws: &mut Workspace,
    matrix: bool,
    c: &MatrixCoefficients,
) {
    let body = &model.bodies[bi];
    let nb = body.dofs.len();
    let o = body.offset;
    let f = &mut ws.body_force[..nb];
    match &body.kind {
        BodyKind::Rigid(rb) => rigid::inertia_force(rb, &s.q[o..], &s.qd[o..], &s.qdd[o..], f),
        BodyKind::PointMass { mass } => point_mass::inertia_force(*mass, &s.qdd[o..], f),
        BodyKind::Ground | BodyKind::Flexible(_) => {}
    }
    for v in f.iter_mut() {
        *v = -*v;
    }
    add_gravity_force(body, s.q, &model.gravity, f);
    for k in 0..nb {
        ws.residual[o + k] -= f[k];
    }
    if !matrix {
        return;
    }
    let entries = &model.layout.bodies[bi];
    let idx = &entries.block;
    if c.needs_tangent() {
        match &body.kind {
            BodyKind::Rigid(rb) => {
                rigid::inertia_tangent(rb, &s.q[o..], &s.qd[o..], &s.qdd[o..], &mut ws.rigid);
                let g = gravity_jacobian(body, &model.gravity).expect("rigid body");
                for a in 0..7 {
                    for b in 0..7 {
                        let mut k = ws.rigid.position[a][b];
                        if a >= 3 && b >= 3 {
                            k -= g[a - 3][b - 3];
                        }
                        ws.values[idx[a * 7 + b]] += c.scale
                            * (c.mass * ws.rigid.mass[a][b]
                                + c.velocity * ws.rigid.velocity[a][b]
                                + c.position * k);
                    }
                }
            }
            BodyKind::PointMass { mass } => {
                for a in 0..3 {
                    ws.values[idx[a * 3 + a]] += c.scale * c.mass * mass;
                }
            }
            BodyKind::Ground | BodyKind::Flexible(_) => {}
        }
    }
    if c.identity != 0.0 {
        for &d in &entries.diagonal {
            ws.values[d] += c.scale * c.identity;
        }
    }
}

/// Euler-parameter normalization p.p - 1 = 0: its rows, its multiplier's terms in the
/// parameters' rows, and their Jacobians (if `matrix`).
fn assemble_normalizations(
    model: &Model,
    s: &StateView,
    ws: &mut Workspace,
    matrix: bool,
    c: &MatrixCoefficients,
) {
    let nq = model.coordinate_count;
    for (k, nz) in model.normalizations.iter().enumerate() {
        let lambda = s.lambda[nz.row];
        let mut pp = 0.0;
        for (a, &d) in nz.dofs.iter().enumerate() {
            let p = s.q[d];
            pp += p * p;
            ws.residual[d] += 2.0 * p * lambda;
            if matrix {
                let e = &model.layout.normalizations[k];
                ws.values[e[a]] += 2.0 * p;
                ws.values[e[4 + a]] += 2.0 * p;
                let diag = model.layout.bodies[nz.body.0].block[(3 + a) * 7 + 3 + a];
                ws.values[diag] += c.scale * c.position * 2.0 * lambda;
            }
        }
        ws.residual[nq + nz.row] = pp - 1.0;
    }
}

/// Joints: C, C_q^T lambda, and (if `matrix`) C_q and the Hessian term.
fn assemble_joints(
    model: &Model,
    s: &StateView,
    ws: &mut Workspace,
    matrix: bool,
    c: &MatrixCoefficients,
) -> Result<()> {
    let nq = model.coordinate_count;
    for j in 0..model.joints.len() {
        let joint = &model.joints[j];
        let driver = joint.driver_values(s.time)?;
        let pair = joint_pair(model, &ws.markers, j);
        let local = &mut ws.joints[j];
        local.driver = driver;
        local.jacobian.fill_zero();
        let ne = joint.equations.len();
        let nd = joint.dofs.len();
        for (e, eq) in joint.equations.iter().enumerate() {
            local.values[e] = equation_value(eq, &pair, &driver)[0];
            let row = &mut local.jacobian.data[e * nd..(e + 1) * nd];
            equation_gradient(eq, &pair, &driver, 1.0, row, None);
        }
        let lambdas = &s.lambda[joint.row..joint.row + ne];
        if matrix && c.position != 0.0 {
            local.hessian.fill_zero();
            equations_hessian(
                joint.equations.iter().zip(lambdas.iter().copied()),
                &pair,
                &driver,
                &mut local.hessian,
            );
        }
        ws.residual[nq + joint.row..nq + joint.row + ne].copy_from_slice(&local.values[..ne]);
        // C_q^T lambda, summed over the equations before it is added to each coordinate.
        for (a, &d) in joint.dofs.iter().enumerate() {
            ws.residual[d] += local.jacobian.column_dot(a, lambdas);
        }
        if matrix {
            let entries = &model.layout.joints[j];
            for (k, &v) in local.jacobian.data.iter().enumerate() {
                ws.values[entries.jacobian[k]] += v;
                ws.values[entries.jacobian_transpose[k]] += v;
            }
            if c.position != 0.0 {
                // Rows and columns of translations, and the blocks between the two markers'
                // rotations, are often structurally zero: they are not added.
                for (k, &v) in local.hessian.data.iter().enumerate().filter(|(_, v)| **v != 0.0) {
                    ws.values[entries.hessian[k]] += c.scale * c.position * v;
                }
            }
        }
    }
    Ok(())
}

/// Applied force elements: their generalized forces, and (if `matrix`) their stiffness and
/// damping.
fn assemble_forces(
    model: &Model,
    s: &StateView,
    ws: &mut Workspace,
    matrix: bool,
    c: &MatrixCoefficients,
) -> Result<()> {
    if model.forces.is_empty() {
        return Ok(());
    }
    let needs_tangent = c.needs_tangent();
    let env = ForceEnv {
        bodies: &model.bodies,
        markers: &model.markers,
        kinematics: &ws.markers,
        q: s.q,
        qd: s.qd,
        time: s.time,
        discrete: s.discrete,
    };
    for (k, force) in model.forces.iter().enumerate() {
        let local = &mut ws.forces[k];
        evaluate_force(force, &env, local, needs_tangent && matrix)?;
        for (a, &d) in force.dofs.iter().enumerate() {
            ws.residual[d] -= local.generalized[a];
        }
        if matrix && needs_tangent {
            let idx = &model.layout.forces[k];
            for (m, (&kv, &dv)) in local.stiffness.data.iter().zip(&local.damping.data).enumerate() {
                ws.values[idx[m]] += c.scale * (c.position * kv + c.velocity * dv);
            }
        }
    }
    Ok(())
}

/// A typed error naming the first equation whose residual is not finite.
fn check_finite_residual(model: &Model, ws: &Workspace, time: f64) -> Result<()> {
    if crate::math::all_finite(&ws.residual) {
        return Ok(());
    }
    let nq = model.coordinate_count;
    let k = ws.residual.iter().position(|x| !x.is_finite()).unwrap_or(0);
    let item = if k < nq { model.coordinate_name(k) } else { model.constraint_name(k - nq) };
    Err(FlexmbdError::NonFinite { item: format!("the equation of {item}"), time })
}

/// Completes the elastic rows of the condensed bodies, assembled without their linear part
/// (see [`ElasticRows`]): adds it (`Keep`, or `Update` without the image of a condensed
/// solve) or takes the rows from the last condensed solve (`Update`), and keeps the rest of
/// the rows for the next update.
fn finish_elastic_rows(
    model: &Model,
    s: &StateView,
    ws: &mut Workspace,
    elastic_rows: ElasticRows,
    images: &[(usize, &[f64])],
) {
    let Workspace { residual, flexible: works, .. } = ws;
    for (bi, body) in model.bodies.iter().enumerate() {
        let BodyKind::Flexible(fb) = &body.kind else { continue };
        if !is_condensed(&body.kind) {
            continue;
        }
        let n = fb.elastic_count;
        let range = body.offset + REFERENCE_COORDINATES..body.offset + REFERENCE_COORDINATES + n;
        let rows = &mut residual[range.clone()];
        let work = works[bi].as_mut().expect("workspace of a flexible body");
        let image = images.iter().find(|(b, i)| *b == bi && i.len() == n).map(|(_, i)| *i);
        match (elastic_rows, image) {
            (ElasticRows::Update { scale }, Some(image)) if work.rows_kept => {
                for ((r, kept), w) in rows.iter_mut().zip(work.nonlinear.iter_mut()).zip(image) {
                    let rest = *r;
                    *r = rest - *kept - w / scale;
                    *kept = rest;
                }
            }
            (rows_mode, _) => {
                if let ElasticRows::Update { .. } = rows_mode {
                    // No update possible (no image, or no rows kept): M_ff qf_dd was skipped.
                    work.scratch.mass_term.iter_mut().for_each(|x| *x = 0.0);
                    fb.mass_matrix.mul_vec_add(1.0, &s.qdd[range.clone()], &mut work.scratch.mass_term);
                }
                work.nonlinear.copy_from_slice(rows);
                let (q, qd) = (&s.q[range.clone()], &s.qd[range]);
                flexible::add_linear_elastic_forces(fb, q, qd, &work.scratch.mass_term, rows);
                work.rows_kept = true;
            }
        }
    }
}

/// Which blocks of a deformable body's Newton-matrix entries are assembled (the reference
/// block always is).
#[derive(Clone, Copy, Debug)]
struct FlexibleBlocks {
    /// The (f, f) block (condensed solves replace it).
    elastic: bool,
    /// The (reference, f) and (f, reference) blocks (the structured coupling of the condensed
    /// Newton solver replaces them).
    reference_elastic: bool,
    /// The linear part M_ff qf_dd + D_ff qf_dot + K_ff q_f of the elastic rows of the residual
    /// (see [`ElasticRows`]).
    linear: bool,
}

impl FlexibleBlocks {
    /// The blocks `request` asks for of a deformable body, `condensed` or not.
    fn new(request: &Request, condensed: bool) -> Self {
        FlexibleBlocks {
            elastic: request.condensed_blocks || !condensed,
            reference_elastic: !(request.structured_coupling && condensed),
            linear: !(condensed && request.elastic_rows != ElasticRows::Whole),
        }
    }
}

/// Residual and Newton-matrix entries of deformable body `bi`: the inertia force of seed
/// eq. 15 minus gravity plus the elastic forces K_ff q_f + D_ff qf_dot, and their Jacobians
/// when `request` asks for the matrix (coefficients `c`).
fn assemble_flexible(
    model: &Model,
    bi: usize,
    s: &StateView,
    work: &mut FlexibleWork,
    (residual, values): (&mut [f64], &mut [f64]),
    request: &Request,
    c: &MatrixCoefficients,
) {
    let body = &model.bodies[bi];
    let BodyKind::Flexible(fb) = &body.kind else { unreachable!("a deformable body") };
    let blocks = FlexibleBlocks::new(request, is_condensed(&body.kind));
    let o = body.offset;
    let nb = body.dofs.len();
    let r7 = REFERENCE_COORDINATES;
    let (q, qd, qdd) = (&s.q[o..o + nb], &s.qd[o..o + nb], &s.qdd[o..o + nb]);
    let mass = match (blocks.linear, request.elastic_rows) {
        (true, _) => ElasticMass::Include,
        (false, ElasticRows::Update { .. }) => ElasticMass::Skip,
        (false, _) => ElasticMass::Separate,
    };
    // The inertia force minus gravity.
    let gravity = &model.gravity;
    let first_moment = flexible::inertia_force_parts(
        fb,
        q,
        qd,
        qdd,
        &mut work.scratch,
        &mut work.force,
        mass,
        Some(gravity),
    );
    // Point masses turning with their nodes to second order (usually none).
    flexible::add_attached_forces(fb, q, qd, qdd, gravity, &mut work.force);
    for (r, f) in residual[o..o + nb].iter_mut().zip(&work.force) {
        *r += f;
    }
    // The elastic forces, with their Jacobians into the elastic values if the matrix needs
    // the (f, f) block.
    let rows = &mut residual[o + r7..o + nb];
    // The attached masses' Jacobians (local, column-major), for the blocks below; where the
    // condensed solves replace the elastic block of a condensed body, their matrix leaves the
    // attached masses out altogether, as its other nonlinear terms (with only their reference
    // block, or their coupling at the projections, a tumbling soft beam's iteration diverged).
    let elastic_tangent = request.matrix.is_some() && c.needs_tangent() && blocks.elastic;
    let attached: Vec<Vec<f64>> = if elastic_tangent {
        let mc = [c.mass, c.velocity, c.position];
        fb.attached.iter().map(|m| flexible::attached_jacobian(m, q, qd, qdd, gravity, mc)).collect()
    } else {
        Vec::new()
    };
    if elastic_tangent {
        let ev = &mut work.elastic_values;
        ev.iter_mut().for_each(|x| *x = 0.0);
        let tangent = Some((c.position, c.velocity, &mut ev[..]));
        flexible::add_elastic_forces(fb, &q[r7..], &qd[r7..], rows, tangent, blocks.linear);
        add_attached_elastic_block(fb, &attached, &mut work.elastic_values);
    } else {
        flexible::add_elastic_forces(fb, &q[r7..], &qd[r7..], rows, None, blocks.linear);
    }
    if request.matrix.is_none() {
        return;
    }
    let entries = &model.layout.bodies[bi];
    if c.needs_tangent() {
        let (scratch, t) = (&mut work.scratch, &mut work.tangent);
        flexible::inertia_tangent_after_force(fb, q, qd, qdd, scratch, t, blocks.reference_elastic);
        let coupling =
            blocks.reference_elastic.then_some((&mut work.gravity_pf[..], &mut work.gravity_fp[..]));
        let gpp = flexible::gravity_jacobian_at(fb, q, gravity, first_moment, coupling);
        add_reference_block(&work.tangent.reference, &gpp, entries, c, values);
        if blocks.reference_elastic {
            add_reference_elastic_blocks(fb.elastic_count, work, entries, c, values);
        }
        add_attached_reference_blocks(fb, &attached, c, entries, blocks.reference_elastic, values);
        if blocks.elastic {
            add_elastic_block(fb, work, entries, c, values);
        }
    }
    if c.identity != 0.0 || c.elastic_identity != 0.0 {
        for (k, &d) in entries.diagonal.iter().enumerate() {
            values[d] += c.scale * if k < r7 { c.identity } else { c.elastic_identity };
        }
    }
}

/// The (reference, reference) block of a deformable body: its inertia tangent
/// `reference` (mass, velocity, position) with the gravity Jacobian `gpp` over the Euler
/// parameters.
fn add_reference_block(
    reference: &[[[f64; 7]; 7]; 3],
    gpp: &[[f64; 4]; 4],
    entries: &BodyEntries,
    c: &MatrixCoefficients,
    values: &mut [f64],
) {
    let [tm, tv, tx] = reference;
    for a in 0..7 {
        for b in 0..7 {
            let mut k = tx[a][b];
            if a >= 3 && b >= 3 {
                k -= gpp[a - 3][b - 3];
            }
            values[entries.block[a * 7 + b]] +=
                c.scale * (c.mass * tm[a][b] + c.velocity * tv[a][b] + c.position * k);
        }
    }
}

/// The (f, f) entries of the Jacobians `jacobians` of the attached masses of `fb`
/// ([`flexible::attached_jacobian`]) into its elastic values (unscaled, as the elastic forces'
/// Jacobians there).
fn add_attached_elastic_block(fb: &FlexibleBody, jacobians: &[Vec<f64>], elastic_values: &mut [f64]) {
    for (mass, j) in fb.attached.iter().zip(jacobians) {
        let n = mass.indices.len();
        let size = 7 + n;
        for a in 0..n {
            for b in 0..n {
                elastic_values[mass.positions[a * n + b]] += j[(7 + b) * size + 7 + a];
            }
        }
    }
}

/// The (reference, reference) entries of the Jacobians `jacobians` of the attached masses of
/// `fb`, and with `coupling` the (reference, f) and (f, reference) ones.
fn add_attached_reference_blocks(
    fb: &FlexibleBody,
    jacobians: &[Vec<f64>],
    c: &MatrixCoefficients,
    entries: &BodyEntries,
    coupling: bool,
    values: &mut [f64],
) {
    let nf = fb.elastic_count;
    for (mass, j) in fb.attached.iter().zip(jacobians) {
        let size = 7 + mass.indices.len();
        for a in 0..7 {
            for b in 0..7 {
                values[entries.block[a * 7 + b]] += c.scale * j[b * size + a];
            }
        }
        if !coupling {
            continue;
        }
        for (i, &e) in mass.indices.iter().enumerate() {
            for a in 0..7 {
                values[entries.reference_elastic[a * nf + e]] += c.scale * j[(7 + i) * size + a];
                values[entries.elastic_reference[e * 7 + a]] += c.scale * j[a * size + 7 + i];
            }
        }
    }
}

/// The (reference, f) and (f, reference) blocks of a deformable body with `nf` elastic
/// coordinates, from the tangent and the gravity Jacobian blocks in `work`.
fn add_reference_elastic_blocks(
    nf: usize,
    work: &FlexibleWork,
    entries: &BodyEntries,
    c: &MatrixCoefficients,
    values: &mut [f64],
) {
    let t = &work.tangent;
    let [rm, rv, rx] = &t.reference_elastic;
    let [fm, fv, fx] = &t.elastic_reference;
    for a in 0..7 {
        for j in 0..nf {
            let (re, er) = (a * nf + j, j * 7 + a);
            let (mut k_re, mut k_er) = (rx[re], fx[er]);
            if a >= 3 {
                k_re -= work.gravity_pf[(a - 3) * nf + j];
                k_er -= work.gravity_fp[j * 4 + a - 3];
            }
            values[entries.reference_elastic[re]] +=
                c.scale * (c.mass * rm[re] + c.velocity * rv[re] + c.position * k_re);
            values[entries.elastic_reference[er]] +=
                c.scale * (c.mass * fm[er] + c.velocity * fv[er] + c.position * k_er);
        }
    }
}

/// (f, f): sum_kl (m I + v 2 w~ + p (alpha~ + w~ w~))_kl I_kl, added to the elastic force
/// Jacobians v D_ff + p (K_ff + geometric stiffness) already in `work.elastic_values`.
fn add_elastic_block(
    fb: &FlexibleBody,
    work: &mut FlexibleWork,
    entries: &BodyEntries,
    c: &MatrixCoefficients,
    values: &mut [f64],
) {
    let t = &work.tangent;
    let ev = &mut work.elastic_values;
    let coefficients = Mat3::IDENTITY.scale(c.mass)
        + t.velocity_coefficients.scale(c.velocity)
        + t.position_coefficients.scale(c.position);
    fb.add_i_kl_to_pattern(&coefficients, ev);
    for (&e, &v) in entries.elastic.iter().zip(ev.iter()) {
        values[e] += c.scale * v;
    }
}

/// Time derivatives of the constraints: C_t into `ct` and, if `gamma` is given, the
/// acceleration right-hand side gamma = -(q_dot^T C_qq q_dot + 2 C_qt q_dot + C_tt) of seed
/// eq. 25, C_q q_dd = gamma. Uses the kinematics of the last `assemble`; overwrites the joints'
/// Hessian buffers.
pub fn constraint_time_terms(
    model: &Model,
    s: StateView,
    ws: &mut Workspace,
    ct: &mut [f64],
    mut gamma: Option<&mut [f64]>,
) -> Result<()> {
    ct.iter_mut().for_each(|x| *x = 0.0);
    for nz in &model.normalizations {
        if let Some(g) = gamma.as_deref_mut() {
            g[nz.row] = -2.0 * nz.dofs.iter().map(|&d| s.qd[d] * s.qd[d]).sum::<f64>();
        }
    }
    for j in 0..model.joints.len() {
        let joint = &model.joints[j];
        let driver = joint.driver_values(s.time)?;
        let pair = joint_pair(model, &ws.markers, j);
        let local = &mut ws.joints[j];
        for (a, &d) in joint.dofs.iter().enumerate() {
            local.scratch[a] = s.qd[d];
        }
        for (e, eq) in joint.equations.iter().enumerate() {
            let v = equation_value(eq, &pair, &driver);
            ct[joint.row + e] = v[1];
            if let Some(g) = gamma.as_deref_mut() {
                local.hessian.fill_zero();
                equations_hessian([(eq, 1.0)], &pair, &driver, &mut local.hessian);
                local.gradient.iter_mut().for_each(|x| *x = 0.0);
                local.gradient_time.iter_mut().for_each(|x| *x = 0.0);
                equation_gradient(
                    eq,
                    &pair,
                    &driver,
                    1.0,
                    &mut local.gradient,
                    Some(&mut local.gradient_time),
                );
                let cqt_qd: f64 = local.gradient_time.iter().zip(&local.scratch).map(|(a, b)| a * b).sum();
                g[joint.row + e] = -(local.hessian.quadratic_form(&local.scratch) + 2.0 * cqt_qd + v[2]);
            }
        }
    }
    Ok(())
}

/// Velocity constraint violation C_q q_dot + C_t into `out` (constraints), using the
/// Jacobians, kinematics and driver values of the last `assemble`.
pub fn velocity_violation(model: &Model, qd: &[f64], ws: &Workspace, out: &mut [f64]) {
    for nz in &model.normalizations {
        // d/dt (p.p - 1) = 2 p . p_dot; the assembled Jacobian row is 2p.
        out[nz.row] = 0.0;
    }
    for (j, joint) in model.joints.iter().enumerate() {
        let local = &ws.joints[j];
        let nd = joint.dofs.len();
        let has_driver = joint.kind.function().is_some();
        let pair = if has_driver { Some(joint_pair(model, &ws.markers, j)) } else { None };
        for (e, eq) in joint.equations.iter().enumerate() {
            let row = &local.jacobian.data[e * nd..(e + 1) * nd];
            let mut v: f64 = row.iter().zip(&joint.dofs).map(|(c, &d)| c * qd[d]).sum();
            if let Some(p) = &pair {
                v += equation_value(eq, p, &local.driver)[1];
            }
            out[joint.row + e] = v;
        }
    }
}

/// `out += C_q^T w` for a vector `w` over the constraint rows, with the joint Jacobians of the
/// last `assemble` (`joints`, at coordinates `q`).
pub fn add_constraint_forces(model: &Model, q: &[f64], joints: &[JointLocal], w: &[f64], out: &mut [f64]) {
    add_constraint_force_pair(model, q, joints, [w, w], [out, &mut []]);
}

/// `out[0] += C_q^T w[0]` and, unless `out[1]` is empty, `out[1] += C_q^T w[1]` in one pass
/// over the constraint Jacobians.
pub fn add_constraint_force_pair(
    model: &Model,
    q: &[f64],
    joints: &[JointLocal],
    w: [&[f64]; 2],
    out: [&mut [f64]; 2],
) {
    let [out0, out1] = out;
    let both = !out1.is_empty();
    for nz in &model.normalizations {
        for &d in &nz.dofs {
            out0[d] += 2.0 * q[d] * w[0][nz.row];
            if both {
                out1[d] += 2.0 * q[d] * w[1][nz.row];
            }
        }
    }
    for (j, joint) in model.joints.iter().enumerate() {
        let jac = &joints[j].jacobian;
        let nd = joint.dofs.len();
        for e in 0..joint.equations.len() {
            let (w0, w1) = (w[0][joint.row + e], if both { w[1][joint.row + e] } else { 0.0 });
            if w0 == 0.0 && w1 == 0.0 {
                continue;
            }
            let row = &jac.data[e * nd..(e + 1) * nd];
            for (&c, &d) in row.iter().zip(&joint.dofs) {
                out0[d] += c * w0;
                if both {
                    out1[d] += c * w1;
                }
            }
        }
    }
}
