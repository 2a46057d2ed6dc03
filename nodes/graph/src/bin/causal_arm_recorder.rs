//! `causal_arm_recorder` node (see `causal_arm_graph::recorder_node`).
fn main() -> std::process::ExitCode {
    causal_arm_graph::node_main(causal_arm_graph::recorder_node::run)
}
