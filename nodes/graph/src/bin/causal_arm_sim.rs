//! `causal_arm_sim` node (see `causal_arm_graph::sim_node`).
fn main() -> std::process::ExitCode {
    causal_arm_graph::node_main(causal_arm_graph::sim_node::run)
}
