//! `causal_arm_explainer`: explains a forward model written by `causal-arm train` on
//! transitions of a bag, publishes the relevance report latched on `/explainer/relevance`
//! and serves `/explainer/explain` (SHAP attributions of the caller's rows). Bad requests
//! get a `success: false` reply saying why, and the node keeps serving.

use std::path::PathBuf;
use std::time::SystemTime;

use anyhow::bail;
use causal_arm_dataset::{ActionSource, Cache, load_bags};
use causal_arm_explainer::report::DEFAULT_THRESHOLD;
use causal_arm_explainer::serve::{ExplainService, relevance_msg};
use causal_arm_explainer::{Explainer, Method, Settings, forward_inputs, relevance};
use causal_arm_msgs::builtin_interfaces::msg::Time;
use causal_arm_msgs::msg::Relevance as RelevanceMsg;
use causal_arm_msgs::srv::Explain;
use causal_arm_msgs::std_msgs::msg::Header;
use causal_arm_node::run::{Served, node_main, serve_until_stopped, stop_flag};
use causal_arm_node::{ParamSpec, ParamValue, RosArgs, RosNode, qos};
use causal_arm_trainer::load_model;
use rand::SeedableRng;
use rand::seq::SliceRandom;

const EXPLAIN: &str = "/explainer/explain";
const RELEVANCE: &str = "/explainer/relevance";
/// Rows of the bag kept as the background pool (a uniform sample).
const POOL_ROWS: usize = 20_000;

fn now() -> Time {
    let t = SystemTime::now()
        .duration_since(SystemTime::UNIX_EPOCH)
        .unwrap_or_default();
    Time {
        sec: t.as_secs() as i32,
        nanosec: t.subsec_nanos(),
    }
}

fn run(ros_args: &RosArgs) -> anyhow::Result<()> {
    // First of all: a SIGINT that arrives while the node starts up must not be lost (a
    // background job of a non-interactive shell starts with SIGINT ignored until then).
    let stop = stop_flag();
    let specs = [
        ParamSpec::new(
            "model_dir",
            ParamValue::String(String::new()),
            "directory written by `causal-arm train --out`",
        ),
        ParamSpec::new(
            "forward_model",
            ParamValue::String("fm".into()),
            "forward model file stem in model_dir",
        ),
        ParamSpec::new(
            "bag",
            ParamValue::String(String::new()),
            "bag the observations and background are drawn from (e.g. the training bag)",
        ),
        ParamSpec::new(
            "method",
            ParamValue::String("deep".into()),
            "method of the published relevance report: deep or kernel",
        ),
        ParamSpec::new(
            "samples",
            ParamValue::Integer(200),
            "observations of the relevance report",
        )
        .with_range(1.0, 100_000.0),
        ParamSpec::new(
            "threshold",
            ParamValue::Double(DEFAULT_THRESHOLD),
            "relevance threshold, a fraction of each state feature's standard deviation",
        )
        .with_range(1e-12, 1e6),
        ParamSpec::new("seed", ParamValue::Integer(0), "seed of the draws").with_range(0.0, 1e15),
        ParamSpec::new(
            "cache",
            ParamValue::String(String::new()),
            "dataset cache directory (empty: $CAUSAL_ARM_CACHE or ~/.cache/causal-arm)",
        ),
    ];
    let mut node = RosNode::new("causal_arm_explainer", &specs, ros_args)?;
    let params = node.params();
    let (dir, bag) = (params.string("model_dir"), params.string("bag"));
    if dir.is_empty() || bag.is_empty() {
        bail!(
            "parameters model_dir and bag are required: --ros-args -p model_dir:=DIR -p bag:=BAG (a directory written by `causal-arm train` and a bag of the same experiment)"
        );
    }
    let method: Method = params
        .string("method")
        .parse()
        .map_err(anyhow::Error::msg)?;
    let seed = params.integer("seed") as u64;
    let threshold = params.double("threshold");
    let cache = match params.string("cache") {
        "" => Cache::new(Cache::default_dir()),
        dir => Cache::new(dir),
    };
    let mut report_settings = Settings::for_method(method);
    report_settings.samples = params.integer("samples") as usize;
    report_settings.seed = seed;
    let model = load_model(std::path::Path::new(dir), params.string("forward_model"))?;
    let explainer = Explainer::new(model)?;
    let (data, _) = load_bags(
        &[PathBuf::from(bag)],
        Some(explainer.experiment()),
        ActionSource::Realized,
        Some(&cache),
    )?;

    let explanation = explainer.explain_dataset(&data, &report_settings, &mut |_, _| {})?;
    let report = relevance(&explanation, threshold);
    tracing::info!(
        "{} SHAP on {} observations in {:.2} s; not affected by any action: [{}]",
        method,
        explanation.attributions.n_obs,
        explanation.seconds,
        report.unaffected.join(", ")
    );
    let relevance_pub = node.publisher::<RelevanceMsg>(RELEVANCE, qos::latched())?;
    relevance_pub.publish(relevance_msg(
        &report,
        Header {
            stamp: now(),
            frame_id: String::new(),
        },
    ))?;

    // Background pool: a seeded uniform sample of the bag's transitions.
    let mut rows: Vec<usize> = (0..data.rows()).collect();
    rows.shuffle(&mut rand::rngs::StdRng::seed_from_u64(seed));
    rows.truncate(POOL_ROWS);
    let pool = forward_inputs(&data, &rows);
    let (mut deep, mut kernel) = (
        Settings::for_method(Method::Deep),
        Settings::for_method(Method::Kernel),
    );
    deep.seed = seed;
    kernel.seed = seed;
    let service = ExplainService::new(explainer, pool, deep, kernel);
    let server = node.server::<Explain>(EXPLAIN)?;
    tracing::info!("serving {EXPLAIN}; relevance report latched on {RELEVANCE}");
    serve_until_stopped(&stop, || async {
        Served::from_turn(
            server
                .async_receive_request()
                .await
                .map(|(id, req)| server.send_response(id, service.explain(&req)).is_ok()),
        )
    });
    tracing::info!("stopping");
    Ok(())
}

fn main() -> std::process::ExitCode {
    node_main(run)
}
