//! Option enums named on the command line and in reports: each name written once, parsed and
//! printed by the same table, and a bad name answered with the list of good ones.

/// `FromStr`, `Display` and `name()` for an enum of unit variants from its `Variant => "name"`
/// table; `what` names the option in the parse error.
macro_rules! named_choices {
    ($ty:ident, $what:literal, { $($variant:ident => $name:literal),+ $(,)? }) => {
        impl $ty {
            /// Every name, in declaration order.
            pub const NAMES: &'static [&'static str] = &[$($name),+];

            /// The name the command line and the reports use.
            pub fn name(self) -> &'static str {
                match self {
                    $($ty::$variant => $name),+
                }
            }
        }

        impl std::str::FromStr for $ty {
            type Err = String;
            fn from_str(s: &str) -> std::result::Result<Self, String> {
                match s {
                    $($name => Ok($ty::$variant),)+
                    _ => Err(format!(
                        "{} must be one of {}, not '{s}'",
                        $what,
                        Self::NAMES.join(", ")
                    )),
                }
            }
        }

        impl std::fmt::Display for $ty {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(self.name())
            }
        }
    };
}
pub(crate) use named_choices;

#[cfg(test)]
mod tests {
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    enum Colour {
        Red,
        Light,
    }
    named_choices!(Colour, "colour", { Red => "red", Light => "light" });

    #[test]
    fn names_parse_print_and_list_the_choices() {
        assert_eq!("light".parse::<Colour>(), Ok(Colour::Light));
        assert_eq!(Colour::Red.to_string(), "red");
        assert_eq!(
            "blue".parse::<Colour>(),
            Err("colour must be one of red, light, not 'blue'".to_string())
        );
    }
}
