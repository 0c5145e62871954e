//! The system: building (`SystemBuilder`), the compiled `Model`, the `State` and the
//! `Workspace`.

pub mod builder;
pub mod model;
pub mod sensor;
pub mod state;
pub mod workspace;

pub use builder::SystemBuilder;
pub use model::Model;
pub use state::State;
pub use workspace::Workspace;
