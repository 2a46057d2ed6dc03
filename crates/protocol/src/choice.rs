//! Closed sets of named values a user picks, on a command line or as a ROS parameter:
//! experiments, profiles, model kinds, methods. Each type names its values once
//! ([`choice!`]); parsing, display, error messages and the `--help` lists all come from
//! that one table.

/// A type whose values are picked by name.
pub trait Choice: Copy + PartialEq + Sized + 'static {
    /// What a value is called in error messages ("experiment", "model").
    const WHAT: &'static str;
    /// Every value with its name, in the order listings show them.
    const TABLE: &'static [(Self, &'static str)];

    /// The value's name.
    fn choice_name(self) -> &'static str {
        Self::TABLE
            .iter()
            .find(|(value, _)| *value == self)
            .map(|(_, name)| *name)
            .expect("every value is in its table")
    }

    /// Every name, in order.
    fn names() -> Vec<&'static str> {
        Self::TABLE.iter().map(|(_, name)| *name).collect()
    }
}

/// The value named `s`, or an error naming what was expected.
pub fn parse_choice<T: Choice>(s: &str) -> Result<T, String> {
    T::TABLE
        .iter()
        .find(|(_, name)| *name == s)
        .map(|(value, _)| *value)
        .ok_or_else(|| {
            format!(
                "unknown {} {s:?}: expected {}",
                T::WHAT,
                one_of(&T::names())
            )
        })
}

/// "a", "a or b", "a, b or c".
pub fn one_of(names: &[&str]) -> String {
    match names {
        [] => String::new(),
        [only] => (*only).to_owned(),
        [init @ .., last] => format!("{} or {last}", init.join(", ")),
    }
}

/// Implements [`Choice`], `FromStr` and `Display` for a type from one table of
/// `value => "name"` pairs.
///
/// ```
/// #[derive(Debug, Clone, Copy, PartialEq)]
/// enum Colour { Red, Blue }
/// causal_arm_protocol::choice!(Colour, "colour", [Colour::Red => "red", Colour::Blue => "blue"]);
/// assert_eq!("blue".parse::<Colour>(), Ok(Colour::Blue));
/// assert_eq!(Colour::Red.to_string(), "red");
/// assert_eq!(
///     "green".parse::<Colour>().unwrap_err(),
///     "unknown colour \"green\": expected red or blue"
/// );
/// ```
#[macro_export]
macro_rules! choice {
    ($ty:ty, $what:literal, [$($value:expr => $name:literal),+ $(,)?]) => {
        impl $crate::choice::Choice for $ty {
            const WHAT: &'static str = $what;
            const TABLE: &'static [(Self, &'static str)] = &[$(($value, $name)),+];
        }

        impl ::std::str::FromStr for $ty {
            type Err = ::std::string::String;
            fn from_str(s: &str) -> ::std::result::Result<Self, Self::Err> {
                $crate::choice::parse_choice(s)
            }
        }

        impl ::std::fmt::Display for $ty {
            fn fmt(&self, f: &mut ::std::fmt::Formatter<'_>) -> ::std::fmt::Result {
                f.write_str($crate::choice::Choice::choice_name(*self))
            }
        }
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, Clone, Copy, PartialEq)]
    enum Three {
        A,
        B,
        C,
    }
    crate::choice!(Three, "letter", [Three::A => "a", Three::B => "b", Three::C => "c"]);

    #[test]
    fn names_parse_and_print_from_one_table() {
        for (value, name) in Three::TABLE {
            assert_eq!(name.parse::<Three>(), Ok(*value));
            assert_eq!(value.to_string(), *name);
        }
        assert_eq!(Three::names(), vec!["a", "b", "c"]);
    }

    #[test]
    fn an_unknown_name_says_what_was_expected() {
        assert_eq!(
            "d".parse::<Three>().unwrap_err(),
            "unknown letter \"d\": expected a, b or c"
        );
        assert_eq!(one_of(&["x", "y"]), "x or y");
    }
}
