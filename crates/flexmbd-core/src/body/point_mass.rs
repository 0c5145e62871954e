//! Point mass: q = R (3), inertia force m R_dd, constant mass matrix m I.

/// Generalized inertia force m R_dd into `out` (3).
pub fn inertia_force(mass: f64, qdd: &[f64], out: &mut [f64]) {
    for k in 0..3 {
        out[k] = mass * qdd[k];
    }
}

/// Kinetic energy m |R_dot|^2 / 2.
pub fn kinetic_energy(mass: f64, qd: &[f64]) -> f64 {
    0.5 * mass * (qd[0] * qd[0] + qd[1] * qd[1] + qd[2] * qd[2])
}
