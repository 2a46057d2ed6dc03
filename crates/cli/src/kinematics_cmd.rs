//! `causal-arm fk` / `causal-arm ik`: kinematics of the iiwa URDF from the command line.
//! (stub — filled in by the kinematics work)

use clap::Args;

/// Arguments of `causal-arm fk`.
#[derive(Debug, Args)]
pub struct FkArgs {}

/// Arguments of `causal-arm ik`.
#[derive(Debug, Args)]
pub struct IkArgs {}

/// Runs `causal-arm fk`.
pub fn run_fk(_args: &FkArgs) -> anyhow::Result<()> {
    anyhow::bail!("not implemented")
}

/// Runs `causal-arm ik`.
pub fn run_ik(_args: &IkArgs) -> anyhow::Result<()> {
    anyhow::bail!("not implemented")
}
