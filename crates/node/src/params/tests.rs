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
    assert_eq!(
        parse("[bags/x]").to_ros(),
        ros2_client::ParameterValue::StringArray(vec!["bags/x".into()])
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
fn descriptors_carry_description_range_and_choices() {
    use ros2_client::parameters::NumericRange;
    let steps = ParamSpec::new("steps", ParamValue::Integer(5), "steps").with_range(1.0, 1e30);
    let d = steps.descriptor();
    assert_eq!(
        (d.name.as_str(), d.description.as_str()),
        ("steps", "steps")
    );
    assert!(matches!(
        d.range,
        NumericRange::IntegerRange {
            from_value: 1,
            to_value: i64::MAX,
            step: 0
        }
    ));
    let sigma = ParamSpec::new("sigma", ParamValue::Double(0.3), "").with_range(0.0, 10.0);
    assert!(matches!(
        sigma.descriptor().range,
        NumericRange::FloatingPointRange {
            from_value: 0.0,
            to_value: 10.0,
            ..
        }
    ));
    let exp = ParamSpec::new("experiment", ParamValue::String("exp1".into()), "")
        .with_choices(["exp1", "exp2"]);
    let d = exp.descriptor();
    assert_eq!(d.additional_constraints, "one of: exp1, exp2");
    assert!(matches!(d.range, NumericRange::NotSpecified));
    // Read once at start: read-only, but for use_sim_time, which the node follows.
    assert!(steps.descriptor().read_only && d.read_only);
    assert!(!use_sim_time_spec().descriptor().read_only);
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
