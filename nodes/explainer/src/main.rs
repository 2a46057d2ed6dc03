//! `causal_arm_explainer`: explains a forward model written by `causal-arm train` on
//! transitions of a bag, publishes the relevance report latched on `/explainer/relevance`
//! (the default three-valued verdicts `<method>+cai+data`, by the library's one explain job
//! that `causal-arm explain` runs too) and serves `/explainer/explain` (SHAP attributions
//! of the caller's rows). Bad requests get a `success: false` reply saying why, and the
//! node keeps serving.

use std::time::{Instant, SystemTime};

use anyhow::bail;
use causal_arm_explain::job::ExplainRequest;
use causal_arm_explain::serve::{ExplainService, relevance_msg};
use causal_arm_msgs::builtin_interfaces::msg::Time;
use causal_arm_msgs::msg::Relevance as RelevanceMsg;
use causal_arm_msgs::srv::Explain;
use causal_arm_msgs::std_msgs::msg::Header;
use causal_arm_node::params::ExplainerParams;
use causal_arm_node::replies::Replies;
use causal_arm_node::run::{node_main, serve_until_stopped, stop_flag};
use causal_arm_node::{RosArgs, RosNode, qos};
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

fn run(ros_args: &RosArgs) -> anyhow::Result<()> {
    // First of all: a SIGINT that arrives while the node starts up must not be lost (a
    // background job of a non-interactive shell starts with SIGINT ignored until then).
    let stop = stop_flag();
    let mut node = RosNode::new(ExplainerParams::NODE, &ExplainerParams::specs()?, ros_args)?;
    let request = ExplainRequest::try_from(&ExplainerParams::from_params(node.params())?)?;
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
