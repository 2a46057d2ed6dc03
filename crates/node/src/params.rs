//! Node parameters on the wire: the typed, DDS-free parameters of `causal_arm_params` as
//! ros2-client's values and descriptors, so `ros2 param get/describe` report what the node
//! runs with and the bounds it was declared with.

pub use causal_arm_params::*;

/// The ROS 2 side of a parameter value, kept out of `causal_arm_params` so that libraries
/// reading parameters do not link DDS.
pub trait ToRos {
    /// Converts into ros2-client's value so the node's parameter services
    /// (`ros2 param get/list`) report what we run with.
    fn to_ros(&self) -> ros2_client::ParameterValue;
}

impl ToRos for ParamValue {
    fn to_ros(&self) -> ros2_client::ParameterValue {
        use ros2_client::ParameterValue as P;
        match self {
            ParamValue::Bool(v) => P::Boolean(*v),
            ParamValue::Integer(v) => P::Integer(*v),
            ParamValue::Double(v) => P::Double(*v),
            ParamValue::String(v) => P::String(v.clone()),
            ParamValue::DoubleArray(v) => P::DoubleArray(v.clone()),
            ParamValue::StringArray(v) => P::StringArray(v.clone()),
        }
    }
}

/// The descriptor a declared parameter is announced with.
pub trait Describe {
    /// What `ros2 param describe` shows and the parameter services enforce: the
    /// description, the range as rcl_interfaces' integer or floating-point range (bounds
    /// inclusive, any step), the choices as the additional constraints, as an rclcpp node
    /// declaring them would; and read-only, because our nodes read their parameters once at
    /// start (a set that changed nothing would be a lie), all but `use_sim_time`, which
    /// the node follows.
    fn descriptor(&self) -> ros2_client::parameters::ParameterDescriptor;
}

impl Describe for ParamSpec {
    fn descriptor(&self) -> ros2_client::parameters::ParameterDescriptor {
        use ros2_client::parameters::{NumericRange, ParameterDescriptor};
        let range = match (self.range, &self.default) {
            (Some((lo, hi)), ParamValue::Integer(_)) => NumericRange::IntegerRange {
                from_value: lo.ceil() as i64,
                to_value: hi.floor().min(i64::MAX as f64) as i64,
                step: 0,
            },
            (Some((lo, hi)), ParamValue::Double(_) | ParamValue::DoubleArray(_)) => {
                NumericRange::FloatingPointRange {
                    from_value: lo,
                    to_value: hi,
                    step: 0.0,
                }
            }
            _ => NumericRange::NotSpecified,
        };
        let additional_constraints = match self.choices.is_empty() {
            true => String::new(),
            false => format!("one of: {}", self.choices.join(", ")),
        };
        ParameterDescriptor {
            description: self.description.to_owned(),
            additional_constraints,
            range,
            read_only: self.name != use_sim_time_spec().name,
            ..ParameterDescriptor::from_value(self.name, &self.default.to_ros())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn string_arrays_reach_ros_as_string_arrays() {
        let spec = ParamSpec::new("bags", ParamValue::StringArray(vec![]), "b");
        assert_eq!(
            spec.parse("[bags/x]").unwrap().to_ros(),
            ros2_client::ParameterValue::StringArray(vec!["bags/x".into()])
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
}
