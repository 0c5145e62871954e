//! The names of the settings' choices ("modified", "lu", "joint-coordinates", ...), declared
//! once beside each enum with [`named!`](crate::named): the binding reads settings by them,
//! lists them in its errors and hands them to the model-file schema, and messages print them.

/// Implements `NAMES` (every value with its name, in the order of the documentation),
/// `name()` and `from_name()` for a field-less enum.
#[macro_export]
macro_rules! named {
    ($type:ty { $($variant:ident => $name:literal),+ $(,)? }) => {
        impl $type {
            /// Every value with its name in settings and messages.
            pub const NAMES: &'static [(&'static str, Self)] = &[$(($name, Self::$variant)),+];

            /// Name in settings and messages.
            pub fn name(self) -> &'static str {
                match self {
                    $(Self::$variant => $name),+
                }
            }

            /// The value of a name, None for an unknown name.
            pub fn from_name(name: &str) -> Option<Self> {
                Self::NAMES.iter().find(|(n, _)| *n == name).map(|(_, v)| *v)
            }
        }
    };
}

#[cfg(test)]
mod tests {
    #[derive(Clone, Copy, Debug, PartialEq)]
    enum Choice {
        First,
        Second,
    }
    crate::named!(Choice { First => "first", Second => "second-one" });

    #[test]
    fn names_and_values_map_both_ways() {
        assert_eq!(Choice::NAMES.len(), 2);
        for (name, value) in Choice::NAMES {
            assert_eq!(value.name(), *name);
            assert_eq!(Choice::from_name(name), Some(*value));
        }
        assert_eq!(Choice::Second.name(), "second-one");
        assert_eq!(Choice::from_name("third"), None);
    }
}
