//! `causal_arm_reacher` node (see `causal_arm_graph::reacher_node`).
fn main() -> std::process::ExitCode {
    causal_arm_graph::node_main(causal_arm_graph::reacher_node::run)
}
