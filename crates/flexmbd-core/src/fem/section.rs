//! Beam cross-sections: area, second moments, torsion constant.
//!
//! Local beam axes: x along the beam, y and z the principal axes of the section through its
//! centroid. Iy = int z^2 dA (bending about y: deflection w along z), Iz = int y^2 dA (bending
//! about z: deflection v along y). The polar moment of the mass distribution is Iy + Iz; the
//! torsion constant J (Saint-Venant) equals it only for circular sections.

use crate::error::{FlexmbdError, Result};

/// Cross-section properties of a beam.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Section {
    /// Area A (m^2).
    pub area: f64,
    /// Iy = int z^2 dA (m^4).
    pub iy: f64,
    /// Iz = int y^2 dA (m^4).
    pub iz: f64,
    /// Saint-Venant torsion constant J (m^4).
    pub torsion_constant: f64,
    /// Shear correction factor kappa of shear-deformable (Timoshenko) beams: the shear area
    /// is kappa A (5/6 for rectangles, 0.9 for solid circles, 0.5 for thin tubes; given
    /// sections default to 5/6).
    pub shear_factor: f64,
    /// Whether the beam's mass includes the rotary inertia of the section turning with the
    /// bending slopes (the Rayleigh beam, kinematic coupling; default). Without it the mass
    /// of bending is that of the section's centroid line (the classical consistent mass);
    /// the torsional inertia stays.
    pub rotary_inertia: bool,
}

impl Section {
    /// Section from given properties; all must be positive and finite.
    pub fn new(item: &str, area: f64, iy: f64, iz: f64, torsion_constant: f64) -> Result<Self> {
        for (name, v) in [("area", area), ("iy", iy), ("iz", iz), ("torsion constant", torsion_constant)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(FlexmbdError::InvalidParameter {
                    item: item.to_string(),
                    message: format!("section {name} must be positive and finite, got {v}"),
                });
            }
        }
        Ok(Section { area, iy, iz, torsion_constant, shear_factor: 5.0 / 6.0, rotary_inertia: true })
    }

    /// The same section with another shear correction factor (0 < kappa <= 1).
    pub fn with_shear_factor(self, item: &str, kappa: f64) -> Result<Self> {
        if !(kappa > 0.0 && kappa <= 1.0) {
            return Err(FlexmbdError::InvalidParameter {
                item: item.to_string(),
                message: format!("shear correction factor must be in (0, 1], got {kappa}"),
            });
        }
        Ok(Section { shear_factor: kappa, ..self })
    }

    /// The same section without the rotary inertia of bending (see `rotary_inertia`).
    pub fn without_rotary_inertia(self) -> Self {
        Section { rotary_inertia: false, ..self }
    }

    /// Solid rectangle of width b (along y) and height h (along z). Torsion constant by the
    /// series solution of Saint-Venant's problem (Timoshenko and Goodier), to 1e-10.
    pub fn rectangle(item: &str, b: f64, h: f64) -> Result<Self> {
        positive_dimension(item, "rectangle width", b)?;
        positive_dimension(item, "rectangle height", h)?;
        let (long, short) = if b >= h { (b, h) } else { (h, b) };
        // J = (a b^3 / 3) (1 - 192 b / (pi^5 a) sum_{n odd} tanh(n pi a / 2b) / n^5).
        let mut sum = 0.0;
        let mut n = 1.0;
        while n < 200.0 {
            sum += (n * std::f64::consts::PI * long / (2.0 * short)).tanh() / n.powi(5);
            n += 2.0;
        }
        let j =
            long * short.powi(3) / 3.0 * (1.0 - 192.0 * short / (std::f64::consts::PI.powi(5) * long) * sum);
        Section::new(item, b * h, b * h.powi(3) / 12.0, h * b.powi(3) / 12.0, j)
    }

    /// Solid circle of radius r.
    pub fn circle(item: &str, r: f64) -> Result<Self> {
        positive_dimension(item, "circle radius", r)?;
        let i = std::f64::consts::PI * r.powi(4) / 4.0;
        Section::new(item, std::f64::consts::PI * r * r, i, i, 2.0 * i)?.with_shear_factor(item, 0.9)
    }

    /// Circular tube with outer radius `outer` and inner radius `inner` < `outer`.
    pub fn tube(item: &str, outer: f64, inner: f64) -> Result<Self> {
        if !(inner >= 0.0 && inner < outer) {
            return Err(FlexmbdError::InvalidParameter {
                item: item.to_string(),
                message: format!("tube radii must satisfy 0 <= inner < outer, got {inner} and {outer}"),
            });
        }
        let i = std::f64::consts::PI * (outer.powi(4) - inner.powi(4)) / 4.0;
        let area = std::f64::consts::PI * (outer * outer - inner * inner);
        // Shear factor from 0.9 (solid) to 0.5 (thin-walled) with the wall ratio.
        let kappa = 0.5 + 0.4 * (inner / outer - 1.0).powi(2);
        Section::new(item, area, i, i, 2.0 * i)?.with_shear_factor(item, kappa)
    }
}

/// A length of a section's shape (radius, width, height), which must be positive and finite:
/// the area and second moments of a negative one would be positive, and wrong.
fn positive_dimension(item: &str, what: &str, value: f64) -> Result<()> {
    if value.is_finite() && value > 0.0 {
        return Ok(());
    }
    Err(FlexmbdError::InvalidParameter {
        item: item.to_string(),
        message: format!("{what} must be positive and finite, got {value}"),
    })
}

/// Section of a shell: its thickness (uniform over the element, the mid-surface at the nodes)
/// and the shear correction factor of Mindlin plates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShellSection {
    /// Thickness t (m).
    pub thickness: f64,
    /// Shear correction factor kappa of the transverse shear stiffness kappa G t (5/6).
    pub shear_factor: f64,
}

impl ShellSection {
    /// Shell of thickness t > 0 (finite), shear factor 5/6.
    pub fn new(item: &str, thickness: f64) -> Result<Self> {
        if !(thickness.is_finite() && thickness > 0.0) {
            return Err(FlexmbdError::InvalidParameter {
                item: item.to_string(),
                message: format!("shell thickness must be positive and finite, got {thickness}"),
            });
        }
        Ok(ShellSection { thickness, shear_factor: 5.0 / 6.0 })
    }

    /// The same section with another shear correction factor (0 < kappa <= 1).
    pub fn with_shear_factor(self, item: &str, kappa: f64) -> Result<Self> {
        if !(kappa > 0.0 && kappa <= 1.0) {
            return Err(FlexmbdError::InvalidParameter {
                item: item.to_string(),
                message: format!("shear correction factor must be in (0, 1], got {kappa}"),
            });
        }
        Ok(ShellSection { shear_factor: kappa, ..self })
    }
}
