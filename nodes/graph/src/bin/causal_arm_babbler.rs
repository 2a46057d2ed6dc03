//! `causal_arm_babbler` node (see `causal_arm_graph::babbler_node`).
fn main() -> std::process::ExitCode {
    causal_arm_graph::node_main(causal_arm_graph::babbler_node::run)
}
