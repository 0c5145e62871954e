//! Isotropic linear elastic materials.

use crate::error::{FlexmbdError, Result};

/// Isotropic linear elastic material.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// Young's modulus E (Pa).
    pub young_modulus: f64,
    /// Poisson's ratio nu, in (-1, 0.5).
    pub poisson_ratio: f64,
    /// Mass density rho (kg/m^3).
    pub density: f64,
}

impl Material {
    /// Checks E > 0, rho > 0, -1 < nu < 0.5, all finite.
    pub fn new(item: &str, young_modulus: f64, poisson_ratio: f64, density: f64) -> Result<Self> {
        let bad = |message: String| Err(FlexmbdError::InvalidParameter { item: item.to_string(), message });
        if !(young_modulus.is_finite() && young_modulus > 0.0) {
            return bad(format!("Young's modulus must be positive and finite, got {young_modulus}"));
        }
        if !(density.is_finite() && density > 0.0) {
            return bad(format!("density must be positive and finite, got {density}"));
        }
        if !(poisson_ratio.is_finite() && poisson_ratio > -1.0 && poisson_ratio < 0.5) {
            return bad(format!("Poisson's ratio must be in (-1, 0.5), got {poisson_ratio}"));
        }
        Ok(Material { young_modulus, poisson_ratio, density })
    }

    /// Shear modulus G = E / (2 (1 + nu)).
    pub fn shear_modulus(&self) -> f64 {
        self.young_modulus / (2.0 * (1.0 + self.poisson_ratio))
    }

    /// Isotropic elasticity matrix in Voigt order (xx, yy, zz, yz, xz, xy) with engineering
    /// shear strains (gamma = 2 epsilon).
    pub fn elasticity(&self) -> [[f64; 6]; 6] {
        let (e, nu) = (self.young_modulus, self.poisson_ratio);
        let lambda = e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
        let mu = self.shear_modulus();
        let mut d = [[0.0; 6]; 6];
        for i in 0..3 {
            for j in 0..3 {
                d[i][j] = lambda;
            }
            d[i][i] = lambda + 2.0 * mu;
            d[i + 3][i + 3] = mu;
        }
        d
    }
}
