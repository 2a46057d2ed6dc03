//! Tests of the parent module.

use super::*;

fn args(items: &[&str]) -> Vec<String> {
    items.iter().map(|s| s.to_string()).collect()
}

fn specs() -> Vec<ParamSpec> {
    vec![
        ParamSpec::new("steps", ParamValue::Integer(100), "steps to run").with_range(1.0, 1e9),
        ParamSpec::new("sigma", ParamValue::Double(0.35), "spread"),
        ParamSpec::new("name", ParamValue::String("x".into()), "label"),
        ParamSpec::new("weights", ParamValue::DoubleArray(vec![]), "w"),
        ParamSpec::new("bags", ParamValue::StringArray(vec![]), "b"),
    ]
}

#[test]
fn string_arrays_parse_as_ros_lists_or_one_bare_value() {
    let specs = specs();
    let spec = specs.iter().find(|s| s.name == "bags").unwrap();
    let parse = |raw: &str| parse_value(spec, raw).unwrap();
    assert_eq!(
        parse("[a, 'b c', \"d\"]"),
        ParamValue::StringArray(vec!["a".into(), "b c".into(), "d".into()])
    );
    assert_eq!(parse("[]"), ParamValue::StringArray(vec![]));
    assert_eq!(parse(""), ParamValue::StringArray(vec![]));
    assert_eq!(
        parse("bags/x"),
        ParamValue::StringArray(vec!["bags/x".into()])
    );
}

#[test]
fn splits_ros_args_from_program_args() {
    let (ros, rest) = RosArgs::split(&args(&[
        "--out",
        "bags/a",
        "--ros-args",
        "-p",
        "steps:=5",
        "-r",
        "__node:=sim2",
        "-r",
        "/a:=/b",
        "--log-level",
        "debug",
        "--",
        "--verbose",
    ]))
    .unwrap();
    assert_eq!(rest, args(&["--out", "bags/a", "--verbose"]));
    assert_eq!(ros.params, vec![("steps".to_string(), "5".to_string())]);
    assert_eq!(ros.node_name.as_deref(), Some("sim2"));
    assert_eq!(ros.remaps, vec![("/a".to_string(), "/b".to_string())]);
    assert_eq!(ros.log_level.as_deref(), Some("debug"));
}

#[test]
fn empty_remap_target_is_named() {
    let err = RosArgs::split(&args(&["--ros-args", "-r", "__node:="])).unwrap_err();
    assert!(
        err.to_string()
            .contains("-r __node:= needs a name after :="),
        "{err}"
    );
}

#[test]
fn typed_values_are_parsed() {
    let over = vec![
        ("steps".to_string(), "7".to_string()),
        ("sigma".to_string(), "1".to_string()),
        ("name".to_string(), "'hello'".to_string()),
        ("weights".to_string(), "[1, 2.5]".to_string()),
        ("use_sim_time".to_string(), "True".to_string()),
    ];
    let p = Params::resolve("n", &specs(), &over).unwrap();
    assert_eq!(p.integer("steps"), 7);
    assert_eq!(p.double("sigma"), 1.0);
    assert_eq!(p.string("name"), "hello");
    assert_eq!(p.double_array("weights"), &[1.0, 2.5]);
    assert!(p.use_sim_time());
}

#[test]
fn unknown_parameter_is_named() {
    let err = Params::resolve("sim", &specs(), &[("stepz".into(), "1".into())]).unwrap_err();
    let text = err.to_string();
    assert!(text.contains("unknown parameter \"stepz\""), "{text}");
    assert!(
        text.contains("steps") && text.contains("use_sim_time"),
        "{text}"
    );
}

#[test]
fn wrong_type_and_range_are_named() {
    let err = Params::resolve("n", &specs(), &[("steps".into(), "ten".into())]).unwrap_err();
    assert_eq!(
        err.to_string(),
        "parameter \"steps\": expected integer, got \"ten\""
    );
    let err = Params::resolve("n", &specs(), &[("steps".into(), "0".into())]).unwrap_err();
    assert!(matches!(err, ParamError::OutOfRange { .. }), "{err}");
    let err = Params::resolve("n", &specs(), &[("sigma".into(), "nan".into())]).unwrap_err();
    assert!(matches!(err, ParamError::WrongType { .. }), "{err}");
    let seed = ParamSpec::new("seed", ParamValue::Integer(0), "").with_range(0.0, 9.3e18);
    assert_eq!(
        seed.parse("18446744073709551615").unwrap_err().to_string(),
        "parameter \"seed\" = 18446744073709551615 is outside its range [0, 9223372036854775807]"
    );
    assert_eq!(
        seed.parse("-1").unwrap_err().to_string(),
        "parameter \"seed\" = -1 is outside its range [0, 9223372036854775807]"
    );
}

#[test]
fn malformed_ros_args_are_rejected() {
    assert!(RosArgs::split(&args(&["--ros-args", "-p", "steps=5"])).is_err());
    assert!(RosArgs::split(&args(&["--ros-args", "-p"])).is_err());
    assert!(RosArgs::split(&args(&["--ros-args", "--params-file", "x"])).is_err());
    assert!(RosArgs::split(&args(&["--ros-args", "--enclave"])).is_err());
}

#[test]
fn enclave_is_taken_as_rcl_does() {
    let (ros, rest) = RosArgs::split(&args(&["run", "--ros-args", "-e", "/a/b", "--"])).unwrap();
    assert_eq!(ros.enclave.as_deref(), Some("/a/b"));
    assert_eq!(rest, vec!["run".to_string()]);
    let (ros, _) = RosArgs::split(&args(&["--ros-args", "--enclave", "/c"])).unwrap();
    assert_eq!(ros.enclave.as_deref(), Some("/c"));
}

const EMBEDDED: &str = include_str!("../../../launch_scripts/graph.toml");

fn field_line<'a>(code: &'a str, owner: &str, field: &str) -> &'a str {
    let start = code
        .find(&format!("pub struct {owner} {{"))
        .expect("owner struct");
    let body = &code[start..];
    let body = &body[..body.find("\n}").expect("struct end")];
    body.lines()
        .find(|l| l.trim_start().starts_with(&format!("pub {field}:")))
        .expect("field")
        .trim()
}

#[test]
fn a_field_takes_the_type_of_its_toml_default() {
    let code = crate::codegen::generate(EMBEDDED).unwrap();
    assert_eq!(
        field_line(&code, "ExplainerParams", "kappa"),
        "pub kappa: f64,"
    );
    assert_eq!(field_line(&code, "RunParams", "seed"), "pub seed: i64,");
    assert_eq!(
        field_line(&code, "TrainerParams", "bag"),
        "pub bag: Vec<String>,"
    );
    // `1` for `1.0` makes the field an integer: every use of it as a number of another
    // type is then a compile error, not a panic when the node reads it.
    let mistyped = EMBEDDED.replacen(
        "name = \"kappa\"\ndefault = 1.0",
        "name = \"kappa\"\ndefault = 1",
        1,
    );
    assert_ne!(mistyped, EMBEDDED, "the graph file's kappa moved");
    let code = crate::codegen::generate(&mistyped).unwrap();
    assert_eq!(
        field_line(&code, "ExplainerParams", "kappa"),
        "pub kappa: i64,"
    );
}

#[test]
fn names_that_cannot_be_fields_fail_the_build_naming_the_parameter() {
    let text = "[[run_params]]\nname = \"type\"\ndefault = 1\ndescription = \"x\"\n\n[[nodes]]\nname = \"n\"\n";
    let error = crate::codegen::generate(text).unwrap_err();
    assert!(error.contains("run parameter type"), "{error}");
    let text = "[[run_params]]\nname = \"mixed\"\ndefault = [1, \"a\"]\ndescription = \"x\"\n";
    let error = crate::codegen::generate(text).unwrap_err();
    assert!(error.contains("run parameter mixed: default"), "{error}");
}

/// The node's view: resolve `args` against the specs, read the struct back.
fn round_trip<T>(
    specs: Vec<ParamSpec>,
    args: Vec<String>,
    read: fn(&Params) -> Result<T, ParamError>,
) -> T {
    let overrides: Vec<(String, String)> = args
        .iter()
        .map(|a| {
            let (n, v) = a.split_once(":=").unwrap();
            (n.to_owned(), v.to_owned())
        })
        .collect();
    read(&Params::resolve("n", &specs, &overrides).unwrap()).unwrap()
}

#[test]
fn every_struct_reads_back_what_it_writes_as_ros_args() {
    let defaults = RunParams::default();
    let specs = RunParams::specs().unwrap();
    assert_eq!(
        round_trip(
            specs.clone(),
            defaults.to_ros_args(),
            RunParams::from_params
        ),
        defaults
    );
    let changed = RunParams {
        experiment: "exp2".into(),
        sigma: 0.123,
        seed: i64::MAX,
        move_while_switching: false,
        ..RunParams::default()
    };
    assert_eq!(
        round_trip(specs, changed.to_ros_args(), RunParams::from_params),
        changed
    );
    let trainer = TrainerParams {
        bag: vec!["bags/a".into(), "bags/b".into()],
        epochs: 3,
        ..TrainerParams::default()
    };
    assert_eq!(
        round_trip(
            TrainerParams::specs().unwrap(),
            trainer.to_ros_args(),
            TrainerParams::from_params
        ),
        trainer
    );
    let explainer = ExplainerParams {
        kappa: 1e-6,
        model_dir: "models/with space".into(),
        ..ExplainerParams::default()
    };
    assert_eq!(
        round_trip(
            ExplainerParams::specs().unwrap(),
            explainer.to_ros_args(),
            ExplainerParams::from_params
        ),
        explainer
    );
}

#[test]
fn a_node_declares_the_run_parameters_and_its_own() {
    let names = |specs: Vec<ParamSpec>| specs.iter().map(|s| s.name).collect::<Vec<_>>();
    let recorder = names(RecorderParams::specs().unwrap());
    assert_eq!(
        &recorder[..RunParams::DECLARED.len()],
        &names(RunParams::specs().unwrap())[..]
    );
    assert!(recorder.contains(&"land_every"));
    // Servers are not part of a run.
    assert!(!names(TrainerParams::specs().unwrap()).contains(&"sigma"));
}

#[test]
fn an_option_and_a_parameter_get_one_verdict() {
    let error = run::seed::parse("18446744073709551615").unwrap_err();
    assert_eq!(
        error.to_string(),
        "parameter \"seed\" = 18446744073709551615 is outside its range [0, 9223372036854775807]"
    );
    let node = Params::resolve(
        "n",
        &RunParams::specs().unwrap(),
        &[("seed".into(), "18446744073709551615".into())],
    )
    .unwrap_err();
    assert_eq!(node, error);
    assert_eq!(run::sigma::parse("0.5").unwrap(), 0.5);
    assert_eq!(explainer::kappa::default_text(), "1.0");
    assert!(matches!(
        explainer::kappa::parse("0"),
        Err(ParamError::OutOfRange { .. })
    ));
}

#[test]
fn a_value_read_as_another_type_is_an_error_not_a_panic() {
    let params = Params::resolve("n", &RunParams::specs().unwrap(), &[]).unwrap();
    let error = params.typed::<f64>("seed").unwrap_err();
    assert_eq!(
        error.to_string(),
        "parameter \"seed\" is declared integer, but this program reads a double"
    );
    assert!(params.typed::<bool>("nonexistent").is_err());
}
