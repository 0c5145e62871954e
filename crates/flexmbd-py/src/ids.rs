//! Typed ids of model items, returned by the `System.add_*` methods.

use pyo3::prelude::*;

use crate::errors::integer_argument;

macro_rules! py_id {
    ($name:ident, $core:ty, $doc:literal) => {
        #[doc = $doc]
        ///
        /// Ids compare, hash and order by their index. An id returned by a `System` also
        /// carries that system's identity (`_system`; 0 for an id made by hand), by which
        /// the system and its results refuse the ids of another system.
        #[pyclass(module = "flexmbd._core", frozen, eq, hash, ord, from_py_object)]
        #[derive(Clone, Copy, Debug)]
        pub struct $name {
            /// Index into the model's list of items of this kind.
            #[pyo3(get)]
            pub index: usize,
            /// The identity of the system that made the id (0: none).
            #[pyo3(get, name = "_system")]
            pub system: u64,
        }

        impl $name {
            /// The id of item `index`, tied to no system.
            pub fn of(index: usize) -> Self {
                $name { index, system: 0 }
            }
        }

        impl PartialEq for $name {
            fn eq(&self, other: &Self) -> bool {
                self.index == other.index
            }
        }
        impl Eq for $name {}
        impl std::hash::Hash for $name {
            fn hash<H: std::hash::Hasher>(&self, state: &mut H) {
                self.index.hash(state)
            }
        }
        impl PartialOrd for $name {
            fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
                Some(self.cmp(other))
            }
        }
        impl Ord for $name {
            fn cmp(&self, other: &Self) -> std::cmp::Ordering {
                self.index.cmp(&other.index)
            }
        }

        #[pymethods]
        impl $name {
            #[new]
            #[pyo3(signature = (index, _system = 0))]
            fn new(index: &Bound<'_, PyAny>, _system: u64) -> PyResult<Self> {
                let index = integer_argument(index, concat!(stringify!($name), " index"), 0)?;
                Ok($name { index, system: _system })
            }

            fn __repr__(&self) -> String {
                format!("{}({})", stringify!($name), self.index)
            }

            fn __int__(&self) -> usize {
                self.index
            }

            /// Pickling and copying: the id is its index and its system's identity.
            fn __getnewargs__(&self) -> (usize, u64) {
                (self.index, self.system)
            }
        }

        impl From<$name> for $core {
            fn from(id: $name) -> $core {
                <$core>::from_index(id.index)
            }
        }
    };
}

trait FromIndex {
    fn from_index(i: usize) -> Self;
}
macro_rules! from_index {
    ($($t:ty),*) => { $(impl FromIndex for $t { fn from_index(i: usize) -> Self { Self(i) } })* };
}
from_index!(
    flexmbd_core::BodyId,
    flexmbd_core::MarkerId,
    flexmbd_core::JointId,
    flexmbd_core::ForceId,
    flexmbd_core::SensorId
);

py_id!(BodyId, flexmbd_core::BodyId, "A body; `BodyId(0)` is the ground.");
py_id!(MarkerId, flexmbd_core::MarkerId, "A marker: a frame fixed on a body.");
py_id!(JointId, flexmbd_core::JointId, "A joint or a driving constraint.");
py_id!(ForceId, flexmbd_core::ForceId, "An applied force element.");
py_id!(SensorId, flexmbd_core::SensorId, "An output sensor.");
