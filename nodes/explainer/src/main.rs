//! `causal_arm_explainer`: explains a forward model written by `causal-arm train` on
//! transitions of a bag, publishes the relevance report latched on `/explainer/relevance`
//! (verdicts `<method>+cai`, as `causal-arm explain` decides them: SHAP by today's rule
//! united with CAI against the model's error, with each edge's score and interval) and serves `/explainer/explain` (SHAP attributions of the caller's rows). Bad requests
//! get a `success: false` reply saying why, and the node keeps serving.

use std::path::PathBuf;
use std::time::{Instant, SystemTime};

use anyhow::bail;
use causal_arm_dataset::{ActionSource, Cache, Dataset, load_bags};
use causal_arm_explain::influence::InfluenceSettings;
use causal_arm_explain::serve::{ExplainService, relevance_msg};
use causal_arm_explain::verdicts::shap_and_cai_claims;
use causal_arm_explain::{
    Explainer, Method, Relevance, Settings, calibrated_relevance, forward_inputs,
};
use causal_arm_models::load_model;
use causal_arm_msgs::builtin_interfaces::msg::Time;
use causal_arm_msgs::msg::Relevance as RelevanceMsg;
use causal_arm_msgs::srv::Explain;
use causal_arm_msgs::std_msgs::msg::Header;
use causal_arm_node::replies::Replies;
use causal_arm_node::run::{node_main, serve_until_stopped, stop_flag};
use causal_arm_node::{Params, RosArgs, RosNode, qos, server_param_specs};
use futures::FutureExt;
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

/// The relevance report of `explainer` on `data` as `causal-arm explain --method <method>`
/// makes it: SHAP and CAI on the same observations, verdicts `<method>+cai`.
fn make_report(
    explainer: &Explainer,
    data: &Dataset,
    params: &Params,
) -> anyhow::Result<Relevance> {
    let method: Method = params
        .string("method")
        .parse()
        .map_err(anyhow::Error::msg)?;
    let seed = params.integer("seed") as u64;
    let threshold = params.double("threshold");
    let samples = params.integer("samples") as usize;
    let mut settings = Settings::for_method(method);
    settings.samples = samples;
    settings.seed = seed;
    let influence = InfluenceSettings {
        observations: samples,
        resamples: params.integer("resamples") as usize,
        kappa: params.double("kappa"),
        seed,
        ..InfluenceSettings::default()
    };
    let started = Instant::now();
    let explanation = explainer.explain_dataset(data, &settings, &mut |_, _| {})?;
    let claims = shap_and_cai_claims(explainer, data, &explanation, threshold, &influence)?;
    let report = calibrated_relevance(&explanation, threshold, &claims)?;
    tracing::info!(
        "{} on {} observations in {:.2} s; not affected by any action: [{}]",
        report.decision_method,
        explanation.attributions.n_obs,
        started.elapsed().as_secs_f64(),
        report.unaffected.join(", ")
    );
    Ok(report)
}

fn run(ros_args: &RosArgs) -> anyhow::Result<()> {
    // First of all: a SIGINT that arrives while the node starts up must not be lost (a
    // background job of a non-interactive shell starts with SIGINT ignored until then).
    let stop = stop_flag();
    let mut node = RosNode::new(
        "causal_arm_explainer",
        &server_param_specs("causal_arm_explainer")?,
        ros_args,
    )?;
    let params = node.params();
    let (dir, bag) = (params.string("model_dir"), params.string("bag"));
    if dir.is_empty() || bag.is_empty() {
        bail!(
            "parameters model_dir and bag are required: --ros-args -p model_dir:=DIR -p bag:=BAG (a directory written by `causal-arm train` and a bag of the same experiment)"
        );
    }
    // Checked before the data is loaded: a misspelt method costs no time.
    params
        .string("method")
        .parse::<Method>()
        .map_err(anyhow::Error::msg)?;
    let seed = params.integer("seed") as u64;
    let cache = match params.string("cache") {
        "" => Cache::new(Cache::default_dir()),
        dir => Cache::new(dir),
    };
    let model = load_model(std::path::Path::new(dir), params.string("forward_model"))?;
    let explainer = Explainer::new(model)?;
    let (data, _) = load_bags(
        &[PathBuf::from(bag)],
        Some(explainer.experiment()),
        ActionSource::Realized,
        Some(&cache),
    )?;

    let report = make_report(&explainer, &data, params)?;
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
    let replies = Replies::default();
    serve_until_stopped(&stop, || async {
        futures::select! {
            r = server.async_receive_request().fuse() => replies.reply(&server, r, |req| service.explain(req)),
            served = replies.resend_due().fuse() => served,
        }
    });
    replies.finish();
    tracing::info!("stopping");
    Ok(())
}

fn main() -> std::process::ExitCode {
    node_main(run)
}
