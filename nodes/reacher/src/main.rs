//! `causal_arm_reacher` node (see `causal_arm_rig::reacher_node`).
fn main() -> std::process::ExitCode {
    causal_arm_rig::node_main(causal_arm_rig::reacher_node::run)
}
