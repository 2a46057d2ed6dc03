//! `causal_arm_babbler` node (see `causal_arm_rig::babbler_node`).
fn main() -> std::process::ExitCode {
    causal_arm_rig::node_main(causal_arm_rig::babbler_node::run)
}
