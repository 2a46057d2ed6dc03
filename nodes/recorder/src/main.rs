//! `causal_arm_recorder` node (see `causal_arm_rig::recorder_node`).
fn main() -> std::process::ExitCode {
    causal_arm_rig::node_main(causal_arm_rig::recorder_node::run)
}
