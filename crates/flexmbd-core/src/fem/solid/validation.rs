//! Checks of an element's input before any kernel: the node count, finite positions, and a
//! Jacobian determinant above 1e-12 h^3 at every quadrature point of the rule in use and at
//! every node (degenerate and inverted elements).

use super::geometry::jacobian_determinant;
use super::Isoparametric;
use crate::fem::element::{ElementError, ElementResult};
use crate::fem::quadrature::QuadraturePoint;
use crate::math::Vec3;

/// Relative threshold on the Jacobian determinant, in units of h^3 (h: bounding-box diagonal).
const DEGENERATE_TOLERANCE: f64 = 1e-12;

/// Checks the node count and coordinates, then the Jacobian determinant at every point of
/// `rule` and at every node; returns nothing or the first failure.
pub(super) fn validate<E: Isoparametric<N>, const N: usize>(
    x: &[Vec3],
    rule: &[QuadraturePoint],
) -> ElementResult<()> {
    if x.len() != N {
        return Err(ElementError::Invalid {
            detail: format!("a {} element needs {N} node positions, got {}", E::NAME, x.len()),
        });
    }
    if let Some(a) = x.iter().position(|p| !p.is_finite()) {
        return Err(ElementError::Invalid {
            detail: format!("node {a} of a {} element has a non-finite position {:?}", E::NAME, x[a].0),
        });
    }
    // Characteristic length: diagonal of the bounding box of the nodes.
    let (mut low, mut high) = (x[0], x[0]);
    for p in &x[1..] {
        for k in 0..3 {
            low[k] = low[k].min(p[k]);
            high[k] = high[k].max(p[k]);
        }
    }
    let length = (high - low).norm();
    let threshold = DEGENERATE_TOLERANCE * length * length * length;
    let degenerate = |determinant: f64, location: String| ElementError::Degenerate {
        detail: format!(
            "Jacobian determinant {determinant:.6e} at {location} of a {} element (must exceed \
             {threshold:.3e} = {DEGENERATE_TOLERANCE:e} h^3, h = {length:.6e} the bounding-box diagonal)",
            E::NAME
        ),
    };
    // Quadrature points of the rule in use, then the nodes.
    for (q, point) in rule.iter().enumerate() {
        let determinant = jacobian_determinant::<E, N>(x, point.coordinates);
        if !(determinant > threshold) {
            let location = format!("quadrature point {q} (reference coordinates {:?})", point.coordinates);
            return Err(degenerate(determinant, location));
        }
    }
    for (a, node) in E::NODES.iter().enumerate() {
        let determinant = jacobian_determinant::<E, N>(x, *node);
        if !(determinant > threshold) {
            return Err(degenerate(determinant, format!("node {a}")));
        }
    }
    Ok(())
}
