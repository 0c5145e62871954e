//! Typed ids of model items, returned by the `System.add_*` methods.

use pyo3::prelude::*;

use crate::errors::integer_argument;

macro_rules! py_id {
    ($name:ident, $core:ty, $doc:literal) => {
        #[doc = $doc]
        #[pyclass(module = "flexmbd._core", frozen, eq, hash, ord, from_py_object)]
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
        pub struct $name {
            /// Index into the model's list of items of this kind.
            #[pyo3(get)]
            pub index: usize,
        }

        #[pymethods]
        impl $name {
            #[new]
            fn new(index: &Bound<'_, PyAny>) -> PyResult<Self> {
                Ok($name { index: integer_argument(index, concat!(stringify!($name), " index"), 0)? })
            }

            fn __repr__(&self) -> String {
                format!("{}({})", stringify!($name), self.index)
            }

            fn __int__(&self) -> usize {
                self.index
            }

            /// Pickling and copying: the id is its index.
            fn __getnewargs__(&self) -> (usize,) {
                (self.index,)
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
