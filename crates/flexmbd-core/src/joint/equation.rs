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
    let ni = ctx.ni();
    let (ki, kj) = (ctx.kin_i, ctx.kin_j);
    let (bi, bj, mi, mj) = (ctx.body_i, ctx.body_j, ctx.marker_i, ctx.marker_j);
    let d = ctx.offset();
    match *p {
        Primitive::PositionComponent(u) => {
            add_position_hessian(bi, mi, ki, &u, -w, out, 0);
            add_position_hessian(bj, mj, kj, &u, w, out, ni);
        }
        Primitive::AxisDotAxis(k, l) => {
            let (a, b) = (ki.axis(k), kj.axis(l));
            add_axis_hessian(bi, mi, ki, k, &b, w, out, 0);
            add_axis_hessian(bj, mj, kj, l, &a, w, out, ni);
            out.add_jt_j(0, ni, w, &ki.jac_axes[k], &kj.jac_axes[l]);
            out.add_jt_j(ni, 0, w, &kj.jac_axes[l], &ki.jac_axes[k]);
        }
        Primitive::AxisDotOffset(k) => {
            let a = ki.axis(k);
            add_axis_hessian(bi, mi, ki, k, &d, w, out, 0);
            add_position_hessian(bi, mi, ki, &a, -w, out, 0);
            out.add_jt_j(0, 0, -w, &ki.jac_axes[k], &ki.jac_position);
            out.add_jt_j(0, 0, -w, &ki.jac_position, &ki.jac_axes[k]);
            out.add_jt_j(0, ni, w, &ki.jac_axes[k], &kj.jac_position);
            out.add_jt_j(ni, 0, w, &kj.jac_position, &ki.jac_axes[k]);
            add_position_hessian(bj, mj, kj, &a, w, out, ni);
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
            add_position_hessian(bi, mi, ki, &n, -w, out, 0);
            add_position_hessian(bj, mj, kj, &n, w, out, ni);
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

/// Adds `w * C_qq` to `out`.
pub fn equation_hessian(eq: &Equation, ctx: &MarkerPair, f: &[f64; 3], w: f64, out: &mut DenseMatrix) {
    for (c, p) in &eq.terms {
        let cv = coefficient(*c, f)[0];
        if cv != 0.0 {
            primitive_hessian(p, ctx, w * cv, out);
        }
    }
}
