//! Rotations (Euler parameters), 3-vectors, small dense matrices, hyper-dual numbers,
//! functions of time and motion profiles.

pub mod dense;
pub mod euler;
pub mod hyper_dual;
pub mod profile;
pub mod small;
pub mod time_function;
pub mod vec3;

pub use vec3::{Mat3, Vec3};

/// Whether every entry of `x` is finite, in one pass without an early exit: the OR of the bits
/// of 0 v but its sign, zero for a finite v and a NaN otherwise, a loop the compiler
/// vectorizes (the checks of residuals, solutions and states run at every Newton iteration).
pub fn all_finite(x: &[f64]) -> bool {
    x.iter().fold(0u64, |bits, v| bits | ((v * 0.0).to_bits() << 1)) == 0
}

/// Whether a step size or an iteration-matrix coefficient `kept` with a factorization serves
/// `wanted`: equal to 1e-12 of `wanted` (a step shortened by round-off to land on an output
/// time differs in its last bits, and refactorizing for it would cost more than many steps).
pub fn equal_to_round_off(kept: f64, wanted: f64) -> bool {
    (kept - wanted).abs() <= 1e-12 * wanted.abs()
}

#[cfg(test)]
mod tests {
    #[test]
    fn all_finite_finds_every_kind_of_non_finite_entry_anywhere() {
        let finite = [0.0, -0.0, 1.0, -3.5e300, f64::MAX, f64::MIN_POSITIVE, 5e-324, -7.25];
        assert!(crate::math::all_finite(&finite));
        assert!(crate::math::all_finite(&[]));
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, -f64::NAN] {
            for at in 0..finite.len() {
                let mut x = finite.to_vec();
                x[at] = bad;
                assert!(!crate::math::all_finite(&x), "{bad} at {at}");
            }
        }
    }
}
