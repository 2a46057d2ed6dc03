//! How much of each action an inverse model cannot see: the part of the joint delta a(t)
//! that moves no effector coordinate the IM is given (the Jacobian's null space at θ(t)).
//!
//! The monolithic IM gets s(t) and s(t+1) without θ(t+1). To first order the effector
//! change is J(θ(t))·a, so the component of a in J's null space leaves no trace in its
//! inputs and can only be guessed from s(t). Its mean |·| per joint is the error of an IM
//! that recovers everything else perfectly and guesses 0 for it; set it beside the IM MAE.
//!
//! `cargo run --release -p causal_arm_models --example im_null_space -- BAG [ROWS]`

use anyhow::{Context, bail};
use causal_arm_dataset::{ActionSource, Cache, Experiment, load_bags};
use causal_arm_kinematics::ArmModel;
use nalgebra::{DMatrix, DVector};

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(bag) = args.first() else {
        bail!("usage: im_null_space BAG [ROWS]");
    };
    let limit: usize = match args.get(1) {
        Some(n) => n.parse().context("ROWS must be a number")?,
        None => 200_000,
    };
    let cache = Cache::new(Cache::default_dir());
    let (data, _) = load_bags(&[bag.into()], None, ActionSource::Realized, Some(&cache))?;
    let arm = ArmModel::embedded();
    let (sw, aw) = (data.state_width(), data.action_width());
    // θ columns, and which effector rows the IM sees: exp 1 gives ef position only,
    // exp 2 position and orientation.
    let (theta_at, seen_rows) = match data.experiment {
        Experiment::Exp1 => (0, 3),
        Experiment::Exp2 => (9, 6),
    };
    let step = (data.rows() / limit).max(1);
    let (mut hidden, mut total, mut count) = ([0f64; 7], [0f64; 7], 0usize);
    for r in (0..data.rows()).step_by(step) {
        let theta: Vec<f64> = data.states[r * sw + theta_at..r * sw + theta_at + 7]
            .iter()
            .map(|&v| v as f64)
            .collect();
        let a = DVector::from_iterator(
            7,
            data.actions[r * aw..r * aw + 7].iter().map(|&v| v as f64),
        );
        let jac = arm.jacobian(&theta)?;
        let seen = DMatrix::from_fn(seen_rows, 7, |i, j| jac[(i, j)]);
        // Projection onto the null space: I − J⁺J.
        let pinv = seen
            .clone()
            .pseudo_inverse(1e-9)
            .map_err(|e| anyhow::anyhow!("pseudo-inverse: {e}"))?;
        let null = &a - &pinv * (&seen * &a);
        for j in 0..7 {
            hidden[j] += null[j].abs();
            total[j] += a[j].abs();
        }
        count += 1;
    }
    let mean = |v: &[f64; 7]| v.iter().sum::<f64>() / (7 * count) as f64;
    println!(
        "{} ({} of {} transitions, effector rows seen by the IM: {seen_rows})",
        data.experiment,
        count,
        data.rows()
    );
    println!("{:>8} {:>14} {:>14}", "joint", "mean |a|", "mean |null a|");
    for j in 0..7 {
        println!(
            "{:>8} {:>14.4e} {:>14.4e}",
            format!("a{j}"),
            total[j] / count as f64,
            hidden[j] / count as f64
        );
    }
    println!(
        "{:>8} {:>14.4e} {:>14.4e}",
        "mean",
        mean(&total),
        mean(&hidden)
    );
    Ok(())
}
