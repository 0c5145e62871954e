//! Scalar constraint equations between two markers i and j, built from four primitives:
//!
//! - `PositionComponent(u)`: u . d with d = r_j - r_i (u a constant global unit vector);
//! - `AxisDotAxis(k, l)`: a_i,k . a_j,l (axis k of marker i, axis l of marker j);
//! - `AxisDotOffset(k)`: a_i,k . d;
//! - `Distance`: |d|.
//!
//! An equation is C(q, t) = sum_k c_k(t) P_k(q) + c_0(t), where the time coefficients are 1 for
//! joints and cos f(t), -sin f(t), -f(t) for drivers. This covers the joints of seed eqs. 21-24
//! in their dot-product form (no cross products, hence no singular configurations) and gives
//! C, the Jacobian C_q, the Hessian (for the Newton matrix and for gamma of seed eq. 25), C_t,
//! C_qt and C_tt from one definition. Local coordinates: those of marker i, then of marker j
//! (see [`crate::body::marker`]).

use crate::body::marker::{add_axis_hessian, add_position_hessian, Marker, MarkerKinematics};
use crate::body::Body;
use crate::math::dense::DenseMatrix;
use crate::math::{Mat3, Vec3};

/// A scalar function of the two markers' configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Primitive {
    /// u . (r_j - r_i) for a constant global vector u.
    PositionComponent(Vec3),
    /// (axis k of marker i) . (axis l of marker j).
    AxisDotAxis(usize, usize),
    /// (axis k of marker i) . (r_j - r_i).
    AxisDotOffset(usize),
    /// |r_j - r_i|.
    Distance,
}

/// Time coefficient of a term.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Coefficient {
    /// 1.
    One,
    /// cos f(t).
    CosF,
    /// -sin f(t).
    NegSinF,
}

/// Constant or time-dependent part c_0(t) of an equation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Offset {
    /// 0.
    Zero,
    /// A constant.
    Constant(f64),
    /// -f(t).
    NegF,
}

/// One scalar constraint equation.
#[derive(Clone, Debug, PartialEq)]
pub struct Equation {
    /// Short label used in messages and outputs (`x`, `axis`, `angle`, ...).
    pub label: &'static str,
    /// Terms c_k(t) P_k(q).
    pub terms: Vec<(Coefficient, Primitive)>,
    /// c_0(t).
    pub offset: Offset,
}

impl Equation {
    /// An equation with the single term P(q) = 0.
    pub fn simple(label: &'static str, primitive: Primitive) -> Self {
        Equation { label, terms: vec![(Coefficient::One, primitive)], offset: Offset::Zero }
    }
}

/// Two markers (of a joint or of a two-point force element) at the current state.
pub struct MarkerPair<'a> {
    /// Body of marker i.
    pub body_i: &'a Body,
    /// Marker i.
    pub marker_i: &'a Marker,
    /// Kinematics of marker i.
    pub kin_i: &'a MarkerKinematics,
    /// Body of marker j.
    pub body_j: &'a Body,
    /// Marker j.
    pub marker_j: &'a Marker,
    /// Kinematics of marker j.
    pub kin_j: &'a MarkerKinematics,
}

impl MarkerPair<'_> {
    fn ni(&self) -> usize {
        self.kin_i.jac_position.n
    }

    /// d = r_j - r_i.
    pub fn offset(&self) -> Vec3 {
        self.kin_j.position - self.kin_i.position
    }
}

/// Values (f, f', f'') of a coefficient, given (f, f', f'') of the driver function.
fn coefficient(c: Coefficient, f: &[f64; 3]) -> [f64; 3] {
    let (s, co) = f[0].sin_cos();
    let (d1, d2) = (f[1], f[2]);
    match c {
        Coefficient::One => [1.0, 0.0, 0.0],
        Coefficient::CosF => [co, -s * d1, -co * d1 * d1 - s * d2],
        Coefficient::NegSinF => [-s, -co * d1, s * d1 * d1 - co * d2],
    }
}

fn offset_values(o: Offset, f: &[f64; 3]) -> [f64; 3] {
    match o {
        Offset::Zero => [0.0; 3],
        Offset::Constant(c) => [c, 0.0, 0.0],
        Offset::NegF => [-f[0], -f[1], -f[2]],
    }
}

/// Value of a primitive.
pub fn primitive_value(p: &Primitive, ctx: &MarkerPair) -> f64 {
    let d = ctx.offset();
    match *p {
        Primitive::PositionComponent(u) => u.dot(&d),
        Primitive::AxisDotAxis(k, l) => ctx.kin_i.axis(k).dot(&ctx.kin_j.axis(l)),
        Primitive::AxisDotOffset(k) => ctx.kin_i.axis(k).dot(&d),
        Primitive::Distance => d.norm(),
    }
}

/// Adds `w * dP/dq` to `grad` (local coordinates).
pub fn primitive_gradient(p: &Primitive, ctx: &MarkerPair, w: f64, grad: &mut [f64]) {
    let ni = ctx.ni();
    let (ki, kj) = (ctx.kin_i, ctx.kin_j);
    let d = ctx.offset();
    match *p {
        Primitive::PositionComponent(u) => {
            ki.jac_position.add_transpose_times(-w, &u, grad, 0);
            kj.jac_position.add_transpose_times(w, &u, grad, ni);
        }
        Primitive::AxisDotAxis(k, l) => {
            ki.jac_axes[k].add_transpose_times(w, &kj.axis(l), grad, 0);
            kj.jac_axes[l].add_transpose_times(w, &ki.axis(k), grad, ni);
        }
        Primitive::AxisDotOffset(k) => {
            let a = ki.axis(k);
            ki.jac_axes[k].add_transpose_times(w, &d, grad, 0);
            ki.jac_position.add_transpose_times(-w, &a, grad, 0);
            kj.jac_position.add_transpose_times(w, &a, grad, ni);
        }
        Primitive::Distance => {
            let n = d * (1.0 / d.norm());
            ki.jac_position.add_transpose_times(-w, &n, grad, 0);
            kj.jac_position.add_transpose_times(w, &n, grad, ni);
        }
    }
}

/// Adds `w * d^2 P / dq^2` to `out` (local coordinates, square).
pub fn primitive_hessian(p: &Primitive, ctx: &MarkerPair, w: f64, out: &mut DenseMatrix) {
    let mut sums = MarkerSecondDerivatives::default();
    add_primitive_hessian(p, ctx, w, out, &mut sums);
    sums.add_to(ctx, out);
}

/// The vectors v that the second derivatives d^2 (v . r) / dq^2 of each marker's position r
/// and d^2 (v . a_k) / dq^2 of its axes a_k are taken with. Those derivatives are linear in v,
/// so the terms of several primitives and equations on one marker quantity are summed here
/// and differentiated once (a joint between deformable bodies: one pass over the elastic
/// coordinates of each marker quantity instead of one per equation).
#[derive(Clone, Copy, Debug, Default)]
struct MarkerSecondDerivatives {
    /// Of the positions of markers i and j.
    position: [Vec3; 2],
    /// Of the axes of markers i and j.
    axes: [[Vec3; 3]; 2],
}

impl MarkerSecondDerivatives {
    /// Adds the summed second derivatives to `out`.
    fn add_to(&self, ctx: &MarkerPair, out: &mut DenseMatrix) {
        let sides =
            [(ctx.body_i, ctx.marker_i, ctx.kin_i, 0), (ctx.body_j, ctx.marker_j, ctx.kin_j, ctx.ni())];
        for (side, (body, marker, kin, offset)) in sides.into_iter().enumerate() {
            let v = &self.position[side];
            if *v != Vec3::ZERO {
                add_position_hessian(body, marker, kin, v, 1.0, out, offset);
            }
            for (k, v) in self.axes[side].iter().enumerate() {
                if *v != Vec3::ZERO {
                    add_axis_hessian(body, marker, kin, k, v, 1.0, out, offset);
                }
            }
        }
    }
}

/// Adds `w * d^2 P / dq^2` to `out`, the parts with the second derivatives of the marker
/// quantities as their vectors to `sums`.
fn add_primitive_hessian(
    p: &Primitive,
    ctx: &MarkerPair,
    w: f64,
    out: &mut DenseMatrix,
    sums: &mut MarkerSecondDerivatives,
) {
    let ni = ctx.ni();
    let (ki, kj) = (ctx.kin_i, ctx.kin_j);
    let d = ctx.offset();
    let [position_i, position_j] = &mut sums.position;
    let [axes_i, axes_j] = &mut sums.axes;
    match *p {
        Primitive::PositionComponent(u) => {
            *position_i += u * -w;
            *position_j += u * w;
        }
        Primitive::AxisDotAxis(k, l) => {
            let (a, b) = (ki.axis(k), kj.axis(l));
            axes_i[k] += b * w;
            axes_j[l] += a * w;
            out.add_jt_j(0, ni, w, &ki.jac_axes[k], &kj.jac_axes[l]);
            out.add_jt_j(ni, 0, w, &kj.jac_axes[l], &ki.jac_axes[k]);
        }
        Primitive::AxisDotOffset(k) => {
            let a = ki.axis(k);
            axes_i[k] += d * w;
            *position_i += a * -w;
            out.add_jt_j(0, 0, -w, &ki.jac_axes[k], &ki.jac_position);
            out.add_jt_j(0, 0, -w, &ki.jac_position, &ki.jac_axes[k]);
            out.add_jt_j(0, ni, w, &ki.jac_axes[k], &kj.jac_position);
            out.add_jt_j(ni, 0, w, &kj.jac_position, &ki.jac_axes[k]);
            *position_j += a * w;
        }
        Primitive::Distance => {
            let rho = d.norm();
            let n = d * (1.0 / rho);
            // Projector (I - n n^T) / |d| sandwiched between the Jacobians of d = r_j - r_i.
            let mut proj = n.outer(&n).scale(-1.0 / rho);
            for k in 0..3 {
                proj.0[k][k] += 1.0 / rho;
            }
            distance_projector_hessian(ctx, &proj, w, out);
            *position_i += n * -w;
            *position_j += n * w;
        }
    }
}

/// Adds `w * J_d^T P J_d` with J_d = [-J_ri, J_rj] (the Jacobian of d = r_j - r_i).
pub fn distance_projector_hessian(ctx: &MarkerPair, proj: &Mat3, w: f64, out: &mut DenseMatrix) {
    let ni = ctx.ni();
    let (ji, jj) = (&ctx.kin_i.jac_position, &ctx.kin_j.jac_position);
    out.add_jt_m_j(0, 0, w, ji, proj, ji);
    out.add_jt_m_j(0, ni, -w, ji, proj, jj);
    out.add_jt_m_j(ni, 0, -w, jj, proj, ji);
    out.add_jt_m_j(ni, ni, w, jj, proj, jj);
}

/// Value C, C_t and C_tt of an equation at the driver values `f` = (f, f', f'').
pub fn equation_value(eq: &Equation, ctx: &MarkerPair, f: &[f64; 3]) -> [f64; 3] {
    let mut v = offset_values(eq.offset, f);
    for (c, p) in &eq.terms {
        let cv = coefficient(*c, f);
        let pv = primitive_value(p, ctx);
        for k in 0..3 {
            v[k] += cv[k] * pv;
        }
    }
    v
}

/// Adds `w * C_q` to `grad`, and `w * C_qt` to `grad_t` if given.
pub fn equation_gradient(
    eq: &Equation,
    ctx: &MarkerPair,
    f: &[f64; 3],
    w: f64,
    grad: &mut [f64],
    grad_t: Option<&mut [f64]>,
) {
    for (c, p) in &eq.terms {
        primitive_gradient(p, ctx, w * coefficient(*c, f)[0], grad);
    }
    if let Some(gt) = grad_t {
        for (c, p) in &eq.terms {
            let cd = coefficient(*c, f)[1];
            if cd != 0.0 {
                primitive_gradient(p, ctx, w * cd, gt);
            }
        }
    }
}

/// Adds `sum_e w_e C_e,qq` to `out` for the equations with their weights (the multipliers,
/// for the Newton matrix; 1 for the Hessian of one equation).
pub fn equations_hessian<'e>(
    equations: impl IntoIterator<Item = (&'e Equation, f64)>,
    ctx: &MarkerPair,
    f: &[f64; 3],
    out: &mut DenseMatrix,
) {
    let mut sums = MarkerSecondDerivatives::default();
    for (eq, w) in equations.into_iter().filter(|(_, w)| *w != 0.0) {
        for (c, p) in &eq.terms {
            let cv = coefficient(*c, f)[0];
            if cv != 0.0 {
                add_primitive_hessian(p, ctx, w * cv, out, &mut sums);
            }
        }
    }
    sums.add_to(ctx, out);
}
