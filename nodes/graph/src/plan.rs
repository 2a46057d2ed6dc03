//! The run parameters every node of the graph takes, mapped onto the shared
//! [`GenerateOptions`] so the graph and `causal-arm generate` agree.

use causal_arm_datagen::GenerateOptions;
use causal_arm_node::{ParamSpec, ParamValue, Params};
use causal_arm_protocol::{Experiment, Profile, RunPlan};

/// Parameter declarations shared by sim, babbler and recorder.
pub fn run_param_specs() -> Vec<ParamSpec> {
    vec![
        ParamSpec::new(
            "experiment",
            ParamValue::String("exp1".into()),
            "exp1 or exp2",
        ),
        ParamSpec::new(
            "profile",
            ParamValue::String("quick".into()),
            "paper or quick",
        ),
        ParamSpec::new(
            "steps",
            ParamValue::Integer(0),
            "exp1 steps (0 = profile's)",
        )
        .with_range(0.0, 1e12),
        ParamSpec::new(
            "episodes",
            ParamValue::Integer(0),
            "exp2 episodes (0 = profile's)",
        )
        .with_range(0.0, 1e9),
        ParamSpec::new(
            "seed",
            ParamValue::Integer(0),
            "seed of simulator and babbler",
        )
        .with_range(0.0, 9.2e18),
        ParamSpec::new(
            "sigma",
            ParamValue::Double(0.35),
            "exp1 joint target spread, rad",
        )
        .with_range(0.0, 10.0),
        ParamSpec::new(
            "velocity_scale",
            ParamValue::Double(1.0),
            "scale of the URDF joint velocity limits in the simulator",
        )
        .with_range(0.01, 1000.0),
        ParamSpec::new(
            "move_while_switching",
            ParamValue::Bool(true),
            "exp2: move while switching the magnet (false: hold the arm still at every switch)",
        ),
    ]
}

/// Validated run parameters.
#[derive(Debug, Clone)]
pub struct RunParams {
    /// The options `generate` would use.
    pub options: GenerateOptions,
}

impl RunParams {
    /// From resolved parameters; `out` is only used by the recorder.
    pub fn from_params(params: &Params, out: &str) -> anyhow::Result<Self> {
        let experiment: Experiment = params
            .string("experiment")
            .parse()
            .map_err(anyhow::Error::msg)?;
        let profile: Profile = params
            .string("profile")
            .parse()
            .map_err(anyhow::Error::msg)?;
        let mut plan = RunPlan::for_profile(experiment, profile);
        let steps = params.integer("steps");
        let episodes = params.integer("episodes");
        if steps > 0 {
            plan.steps_per_episode = steps as u64;
        }
        if episodes > 0 {
            plan.episodes = episodes as u64;
        }
        let mut options =
            GenerateOptions::new(experiment, plan, params.integer("seed") as u64, out);
        options.exp1.sigma = params.double("sigma");
        options.sim.velocity_scale = params.double("velocity_scale");
        options.exp2.move_while_switching = params.bool("move_while_switching");
        Ok(Self { options })
    }

    /// Sim-time duration of one step, ns (to turn stamps into step counts).
    pub fn step_ns(&self) -> f64 {
        self.options.sim.dt * self.options.sim.substeps as f64 * 1e9
    }
}
