//! Why the factored exp1 FM's ef head is worse than the full FM's: is a parent inside the
//! slice t+1 missing? ef(t+1) = FK(θ(t+1)), so the causal parent of ef(t+1) is θ(t+1), which
//! a head fed only (s(t), a(t)) must rebuild on its own, while the full network shares the
//! θ head's features. This trains, on fold 1 of the same folds as `causal-arm train`:
//! 1. the factored θ head (θ(t), ef(t), a → θ(t+1));
//! 2. an ef head fed θ(t+1) as well, teacher-forced (the true θ(t+1)) in training;
//!
//! and measures the ef head's held-out MAE with the true θ(t+1) and with the θ head's
//! prediction chained in (what a slice-ordered factored FM would do at prediction time);
//! 3. an ef head on its parents only (no a6) that also predicts θ0..θ5(t+1) as auxiliary
//!    outputs, to see whether the full network's edge is the other head's supervision.
//!
//! `cargo run --release -p causal_arm_models --example slice_parents -- BAG [EPOCHS] [SEED] [aux]`
//! (`aux`: experiment 3 only)

use anyhow::{Context, bail};
use causal_arm_dataset::{ActionSource, Cache, Experiment, load_bags};
use causal_arm_mlp::{LrSchedule, Optimizer, TrainConfig};
use causal_arm_models::fit::{
    FitSettings, FitWatch, Progress, fit, folds, head_mae, predict, take_rows, training_rows,
};
use causal_arm_models::problems::{FmTarget, Problem, forward_model, theta_columns};
use causal_arm_models::structure::reduce;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(bag) = args.first() else {
        bail!("usage: slice_parents BAG [EPOCHS] [SEED]");
    };
    let epochs: usize = args
        .get(1)
        .map_or(Ok(60), |e| e.parse())
        .context("EPOCHS")?;
    let seed: u64 = args.get(2).map_or(Ok(0), |s| s.parse()).context("SEED")?;
    let only_aux = args.get(3).is_some_and(|m| m == "aux");
    let cache = Cache::new(Cache::default_dir());
    let (data, _) = load_bags(
        &[bag.into()],
        Some(Experiment::Exp1),
        ActionSource::Realized,
        Some(&cache),
    )?;
    let fm = forward_model(&data, FmTarget::Delta);
    let test = folds(data.rows(), 5, seed).swap_remove(0);
    let train = training_rows(data.rows(), &test);
    let settings = FitSettings {
        hidden: vec![256; 3],
        train: TrainConfig {
            optimizer: Optimizer::Adam,
            learning_rate: 1e-3,
            batch_size: 256,
            seed,
            schedule: LrSchedule::Cosine { floor: 0.01 },
        },
        epochs,
    };
    let theta = theta_columns(Experiment::Exp1);
    let theta_problem = head_of(&fm, "theta", None);
    let ef_problem = head_of(
        &fm,
        "ef",
        Some((&data.next_states, data.state_width(), &theta)),
    );
    let mut quiet = |_: Progress| {};
    if only_aux {
        return auxiliary(&fm, &train, &test, &settings, seed);
    }
    let theta_model = fit(
        &theta_problem,
        &train,
        &settings,
        seed,
        "theta",
        watch(&mut quiet),
    )?;
    let ef_model = fit(
        &ef_problem,
        &train,
        &settings,
        seed,
        "ef",
        watch(&mut quiet),
    )?;
    // Held-out rows: θ(t+1) predicted by the θ head, then fed to the ef head.
    let n_theta_in = theta_problem.input_names.len();
    let theta_hat = predict(
        &theta_model,
        &take_rows(&theta_problem.inputs, n_theta_in, &test),
        theta_problem.offset_columns.as_deref(),
        &theta_problem.heads,
    )?;
    let n_ef_in = ef_problem.input_names.len();
    let true_inputs = take_rows(&ef_problem.inputs, n_ef_in, &test);
    let mut chained_inputs = true_inputs.clone();
    for (r, row) in chained_inputs.chunks_exact_mut(n_ef_in).enumerate() {
        row[n_ef_in - 7..].copy_from_slice(&theta_hat[r * 7..(r + 1) * 7]);
    }
    let truth = take_rows(&ef_problem.truth, 3, &test);
    let ef_mae = |inputs: &[f32]| -> anyhow::Result<f64> {
        let offsets = ef_problem.offset_columns.as_deref();
        let p = predict(&ef_model, inputs, offsets, &ef_problem.heads)?;
        Ok(head_mae(&p, &truth, &ef_problem.heads)[0])
    };
    let theta_truth = take_rows(&theta_problem.truth, 7, &test);
    println!(
        "exp1, fold 1 of 5, seed {seed}, {epochs} cosine epochs, 3x256 per head, {} held-out rows",
        test.len()
    );
    println!(
        "theta head (theta, ef, a):           theta MAE {:.3e} rad",
        head_mae(&theta_hat, &theta_truth, &theta_problem.heads)[0]
    );
    println!(
        "ef head fed the true theta(t+1):     ef MAE {:.3e} m",
        ef_mae(&true_inputs)?
    );
    println!(
        "ef head fed the predicted theta(t+1): ef MAE {:.3e} m (chained)",
        ef_mae(&chained_inputs)?
    );
    auxiliary(&fm, &train, &test, &settings, seed)
}

/// The ef head on its parents only (a6 does not drive ef) that also predicts θ0..θ5(t+1)
/// as auxiliary outputs (θ6(t+1) needs a6, so it would be noise here): only the ef figure
/// is this head's.
fn auxiliary(
    fm: &Problem,
    train: &[usize],
    test: &[usize],
    settings: &FitSettings,
    seed: u64,
) -> anyhow::Result<()> {
    let aux = without_output(&reduce(fm, &["a6".to_owned()])?, "theta6_next");
    let mut quiet = |_: Progress| {};
    let model = fit(&aux, train, settings, seed, "ef+aux", watch(&mut quiet))?;
    let p = predict(
        &model,
        &take_rows(&aux.inputs, aux.input_names.len(), test),
        aux.offset_columns.as_deref(),
        &aux.heads,
    )?;
    let truth = take_rows(&aux.truth, aux.output_names.len(), test);
    let mae = head_mae(&p, &truth, &aux.heads);
    let ef_at = aux
        .heads
        .iter()
        .position(|h| h.name == "ef")
        .expect("ef head");
    println!(
        "ef head on its parents, theta0..5(t+1) as auxiliary outputs: ef MAE {:.3e} m",
        mae[ef_at]
    );
    Ok(())
}

/// `problem` without the output column `name` (its head shrinks by one).
fn without_output(problem: &Problem, name: &str) -> Problem {
    let n_out = problem.output_names.len();
    let gone = problem
        .output_names
        .iter()
        .position(|n| n == name)
        .expect("output");
    let keep = |m: &[f32]| -> Vec<f32> {
        m.chunks_exact(n_out)
            .flat_map(|row| (0..n_out).filter(|&c| c != gone).map(|c| row[c]))
            .collect()
    };
    let mut out = problem.clone();
    out.truth = keep(&problem.truth);
    out.offset = problem.offset.as_deref().map(keep);
    if let Some(cols) = &mut out.offset_columns {
        cols.remove(gone);
    }
    out.output_names.remove(gone);
    for h in &mut out.heads {
        if (h.start..h.start + h.len).contains(&gone) {
            h.len -= 1;
        } else if h.start > gone {
            h.start -= 1;
        }
    }
    out
}

/// A fit without progress output or checkpoints.
fn watch<'a>(progress: &'a mut dyn FnMut(Progress)) -> FitWatch<'a> {
    FitWatch {
        progress,
        stop: None,
        checkpoint: None,
    }
}

/// The FM's head `name` as a problem of its own over every input of the FM, with the
/// columns `extra` of another matrix (e.g. θ(t+1)) appended to the inputs.
fn head_of(fm: &Problem, name: &str, extra: Option<(&[f32], usize, &[usize])>) -> Problem {
    let head = fm.heads.iter().find(|h| h.name == name).expect("FM head");
    let n_in = fm.input_names.len();
    let n_out = fm.output_names.len();
    let outputs: Vec<usize> = (head.start..head.start + head.len).collect();
    let rows = fm.truth.len() / n_out;
    let mut inputs = Vec::with_capacity(rows * (n_in + 7));
    let mut input_names = fm.input_names.clone();
    for r in 0..rows {
        inputs.extend_from_slice(&fm.inputs[r * n_in..(r + 1) * n_in]);
        if let Some((matrix, width, cols)) = extra {
            inputs.extend(cols.iter().map(|&c| matrix[r * width + c]));
        }
    }
    if let Some((_, _, cols)) = extra {
        input_names.extend(cols.iter().map(|c| format!("theta{c}_next")));
    }
    let pick = |m: &[f32]| -> Vec<f32> {
        m.chunks_exact(n_out)
            .flat_map(|row| outputs.iter().map(|&c| row[c]))
            .collect()
    };
    let mut heads = vec![head.clone()];
    heads[0].start = 0;
    Problem {
        inputs,
        truth: pick(&fm.truth),
        offset: fm.offset.as_deref().map(pick),
        offset_columns: fm
            .offset_columns
            .as_ref()
            .map(|c| outputs.iter().map(|&o| c[o]).collect()),
        input_names,
        output_names: outputs
            .iter()
            .map(|&o| fm.output_names[o].clone())
            .collect(),
        heads,
    }
}
