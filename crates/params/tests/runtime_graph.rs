//! A graph file given at run time (`CAUSAL_ARM_GRAPH`) may change defaults, ranges and
//! descriptions, but not what this program was built with: a parameter of another type,
//! missing or added is refused when a node declares its parameters, naming it, instead of
//! failing (or panicking) when it is read.

use causal_arm_params::{ExplainerParams, ParamError, RunParams, TrainerParams};

const EMBEDDED: &str = include_str!("../../../launch_scripts/graph.toml");

#[test]
fn a_runtime_graph_file_that_changes_a_type_is_refused_naming_the_parameter() {
    let changed = EMBEDDED
        .replacen(
            "name = \"kappa\"\ndefault = 1.0",
            "name = \"kappa\"\ndefault = 1",
            1,
        )
        .replacen(
            "name = \"sigma\"\ndefault = 0.35",
            "name = \"sigma\"\ndefault = 0.5",
            1,
        )
        .replacen(
            "[[servers.params]]\nname = \"cache\"",
            "[[servers.params]]\nname = \"cache_dir\"",
            1,
        );
    assert_ne!(changed, EMBEDDED);
    let path = std::env::temp_dir().join(format!("causal-arm-graph-{}.toml", std::process::id()));
    std::fs::write(&path, &changed).unwrap();
    // SAFETY: the only test of this binary, run before anything reads the environment.
    unsafe { std::env::set_var("CAUSAL_ARM_GRAPH", &path) };

    // Defaults follow the file in use.
    let run = RunParams::specs().unwrap();
    let sigma = run.iter().find(|s| s.name == "sigma").unwrap();
    assert_eq!(sigma.default, causal_arm_params::ParamValue::Double(0.5));
    assert_eq!(causal_arm_params::run::sigma::default_text(), "0.5");

    let error = ExplainerParams::specs().unwrap_err().to_string();
    assert!(
        error.contains(&format!("graph file {}", path.display()))
            && error.contains("causal_arm_explainer parameter kappa: default of type integer; this program was built with kappa of type double"),
        "{error}"
    );
    let error = TrainerParams::specs().unwrap_err();
    assert!(matches!(error, ParamError::Graph(_)));
    assert!(error.to_string().contains("cache_dir"), "{error}");
    std::fs::remove_file(&path).unwrap();
}
