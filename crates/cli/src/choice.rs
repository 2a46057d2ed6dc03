//! Typed choice arguments: one clap parser for every [`Choice`] type, so `--help` lists
//! the names the type itself declares and an unknown name gets the type's own message.

use std::ffi::OsStr;
use std::marker::PhantomData;

use causal_arm_protocol::{Choice, parse_choice};
use clap::builder::{PossibleValue, TypedValueParser};
use clap::error::ErrorKind;

/// The parser of `T`'s names (`#[arg(value_parser = choice::<T>())]`).
pub fn choice<T: Choice + Send + Sync>() -> ChoiceParser<T> {
    ChoiceParser(PhantomData)
}

/// See [`choice`].
#[derive(Debug)]
pub struct ChoiceParser<T>(PhantomData<fn() -> T>);

impl<T> Clone for ChoiceParser<T> {
    fn clone(&self) -> Self {
        Self(PhantomData)
    }
}

impl<T: Choice + Send + Sync> TypedValueParser for ChoiceParser<T> {
    type Value = T;

    fn parse_ref(
        &self,
        cmd: &clap::Command,
        arg: Option<&clap::Arg>,
        value: &OsStr,
    ) -> Result<T, clap::Error> {
        parse_choice::<T>(&value.to_string_lossy()).map_err(|message| {
            let flag = arg.map(|a| format!("{a}: ")).unwrap_or_default();
            clap::Error::raw(
                ErrorKind::InvalidValue,
                format!(
                    "{flag}{message}\n  [possible values: {}]\n",
                    T::names().join(", ")
                ),
            )
            .with_cmd(cmd)
        })
    }

    fn possible_values(&self) -> Option<Box<dyn Iterator<Item = PossibleValue> + '_>> {
        Some(Box::new(T::names().into_iter().map(PossibleValue::new)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use causal_arm_protocol::Experiment;
    use clap::Parser;

    #[derive(Debug, Parser)]
    struct Cli {
        #[arg(long, value_parser = choice::<Experiment>(), default_value = "exp1")]
        experiment: Experiment,
    }

    #[test]
    fn a_name_parses_to_its_value() {
        let cli = Cli::try_parse_from(["x", "--experiment", "exp2"]).unwrap();
        assert_eq!(cli.experiment, Experiment::Exp2);
        assert_eq!(
            Cli::try_parse_from(["x"]).unwrap().experiment,
            Experiment::Exp1
        );
    }

    #[test]
    fn help_lists_the_names_and_a_typo_gets_the_types_message() {
        use clap::CommandFactory;
        let help = Cli::command().render_long_help().to_string();
        assert!(help.contains("exp1") && help.contains("exp2"), "{help}");
        let err = Cli::try_parse_from(["x", "--experiment", "exp3"])
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("unknown experiment \"exp3\": expected exp1 or exp2"),
            "{err}"
        );
        assert!(err.contains("--experiment"), "{err}");
    }
}
