//! `causal_arm_sim` node (see `causal_arm_rig::sim_node`).
fn main() -> std::process::ExitCode {
    causal_arm_rig::node_main(causal_arm_rig::sim_node::run)
}
