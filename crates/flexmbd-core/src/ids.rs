//! Typed ids of model items (house style 5): an index into the model's list of that kind.

macro_rules! typed_id {
    ($(#[$doc:meta])* $name:ident, $kind:literal) => {
        $(#[$doc])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
        pub struct $name(pub usize);

        impl $name {
            /// The kind of item, for error messages.
            pub const KIND: &'static str = $kind;
            /// The index into the model's list.
            pub fn index(self) -> usize {
                self.0
            }
        }

        impl std::fmt::Display for $name {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                write!(f, "{} {}", $kind, self.0)
            }
        }
    };
}

typed_id!(
    /// A body; `BodyId(0)` is the ground.
    BodyId, "body"
);
typed_id!(
    /// A marker (frame fixed on a body).
    MarkerId, "marker"
);
typed_id!(
    /// A joint or a driving constraint.
    JointId, "joint"
);
typed_id!(
    /// An applied force element.
    ForceId, "force"
);
typed_id!(
    /// An output sensor.
    SensorId, "sensor"
);
