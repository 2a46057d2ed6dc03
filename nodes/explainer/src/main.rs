//! `causal_arm_explainer`: explains a forward model written by `causal-arm train` on
//! transitions of a bag, publishes the relevance report latched on `/explainer/relevance`
//! (the default three-valued verdicts `<method>+cai+data`, by the library's one explain job
//! that `causal-arm explain` runs too) and serves `/explainer/explain` (SHAP attributions
//! of the caller's rows). Bad requests get a `success: false` reply saying why, and the
//! node keeps serving.

use std::path::PathBuf;
use std::time::{Instant, SystemTime};

use anyhow::bail;
use causal_arm_explain::Method;
use causal_arm_explain::job::{ExplainMethod, ExplainRequest};
use causal_arm_explain::serve::{ExplainService, relevance_msg};
use causal_arm_msgs::builtin_interfaces::msg::Time;
use causal_arm_msgs::msg::Relevance as RelevanceMsg;
use causal_arm_msgs::srv::Explain;
use causal_arm_msgs::std_msgs::msg::Header;
use causal_arm_node::replies::Replies;
use causal_arm_node::run::{node_main, serve_until_stopped, stop_flag};
use causal_arm_node::{Params, RosArgs, RosNode, qos, server_param_specs};
use futures::FutureExt;

const EXPLAIN: &str = "/explainer/explain";
const RELEVANCE: &str = "/explainer/relevance";

fn now() -> Time {
    let t = SystemTime::now()
        .duration_since(SystemTime::UNIX_EPOCH)
        .unwrap_or_default();
    Time {
        sec: t.as_secs() as i32,
        nanosec: t.subsec_nanos(),
    }
}

/// The job of `causal-arm explain --method <method>` as this node's parameters give it:
/// SHAP and the default verdicts on the same observations, no files written.
fn request(params: &Params) -> anyhow::Result<ExplainRequest> {
    let (dir, bag) = (params.string("model_dir"), params.string("bag"));
    if dir.is_empty() || bag.is_empty() {
        bail!(
            "parameters model_dir and bag are required: --ros-args -p model_dir:=DIR -p bag:=BAG (a directory written by `causal-arm train` and a bag of the same experiment)"
        );
    }
    let method = match params
        .string("method")
        .parse()
        .map_err(anyhow::Error::msg)?
    {
        Method::Deep => ExplainMethod::Deep,
        Method::Kernel => ExplainMethod::Kernel,
    };
    let request = ExplainRequest {
        model: PathBuf::from(dir),
        name: params.string("forward_model").to_owned(),
        bags: vec![PathBuf::from(bag)],
        method,
        samples: params.integer("samples") as usize,
        background: None,
        background_kind: None,
        kernel_samples: None,
        threshold: params.double("threshold"),
        action: None,
        seed: params.integer("seed") as u64,
        threads: None,
        pair_plots: false,
        also_models: Vec::new(),
        truth: None,
        kappa: params.double("kappa"),
        resamples: params.integer("resamples") as usize,
        horizon: None,
        out: None,
        cache: match params.string("cache") {
            "" => None,
            dir => Some(PathBuf::from(dir)),
        },
    };
    // Checked before the data is loaded: a bad setting costs no time.
    request.validate()?;
    Ok(request)
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
    let request = request(node.params())?;
    let started = Instant::now();
    let outcome = causal_arm_explain::run(&request, &mut |_, _| {})?;
    let Some(shap) = outcome.shap else {
        bail!("the explain job of a SHAP method made no SHAP report");
    };
    let report = shap.report;
    tracing::info!(
        "{} on {} observations in {:.2} s; not affected by any action: [{}]",
        report.decision_method,
        shap.explanation.attributions.n_obs,
        started.elapsed().as_secs_f64(),
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

    let service = ExplainService::on_data(outcome.explainer, &outcome.data, request.seed);
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
