//! Shared helpers of the integration tests: a seeded generator, random rotations, and the
//! core's tolerance helper.
#![allow(dead_code)]

use flexmbd_core::math::euler;
use flexmbd_core::math::{Mat3, Vec3};
// Each test crate uses what it needs of the helper.
#[allow(unused_imports)]
pub use flexmbd_core::testing::{assert_all_close, assert_close};

/// Small deterministic generator (PCG-like LCG), uniform in [-1, 1).
pub struct Rng(pub u64);

impl Rng {
    pub fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64) / ((1u64 << 53) as f64) * 2.0 - 1.0
    }

    pub fn vec3(&mut self, scale: f64) -> Vec3 {
        Vec3([self.uniform() * scale, self.uniform() * scale, self.uniform() * scale])
    }

    pub fn rotation(&mut self) -> Mat3 {
        let mut p = [self.uniform(), self.uniform(), self.uniform(), self.uniform()];
        let n = p.iter().map(|x| x * x).sum::<f64>().sqrt();
        p.iter_mut().for_each(|x| *x /= n);
        euler::rotation_matrix(&p)
    }
}
