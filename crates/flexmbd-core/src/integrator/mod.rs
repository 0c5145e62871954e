//! Integration in time: the settings of a run, consistent initial conditions and the
//! acceleration system (seed eq. 26), the redundancy analysis, the index-3 generalized-alpha
//! integrator, the explicit Runge-Kutta integrators with the seed's strategies, and the one
//! time loop both make their steps in.

pub mod clock;
pub mod discrete;
pub mod explicit;
pub mod generalized_alpha;
pub mod initial;
pub mod progress;
pub mod redundancy;
pub mod reselection;
pub mod settings;
pub mod simulation;
pub mod time_loop;

pub use progress::{Progress, Records};
pub use settings::{
    Integrator, JacobianUpdate, LinearSolver, NewtonSettings, SimulationSettings, StepControl,
    VelocityProjection,
};
pub use simulation::{simulate, SimulationOutcome};

/// Small models shared by the solver tests.
#[cfg(test)]
pub(crate) mod test_models {
    use crate::joint::JointKind;
    use crate::math::{Mat3, Vec3};
    use crate::{BodyId, SystemBuilder};

    /// A rigid body of unit mass and inertia, at rest at `position` with the global axes.
    pub fn unit_body(sys: &mut SystemBuilder, name: &str, position: Vec3) -> BodyId {
        sys.add_rigid_body(
            name,
            1.0,
            Mat3::IDENTITY,
            Vec3::ZERO,
            position,
            Mat3::IDENTITY,
            Vec3::ZERO,
            Vec3::ZERO,
        )
        .unwrap()
    }

    /// A joint `kind` from a ground marker at `at_ground` to a marker of `body` at `on_body`
    /// (both with the global axes).
    pub fn ground_joint(
        sys: &mut SystemBuilder,
        name: &str,
        kind: JointKind,
        body: BodyId,
        at_ground: Vec3,
        on_body: Vec3,
    ) {
        let g = sys.add_marker("", sys.ground(), at_ground, Mat3::IDENTITY).unwrap();
        let b = sys.add_marker("", body, on_body, Mat3::IDENTITY).unwrap();
        sys.add_joint(name, kind, [g, b]).unwrap();
    }
}
