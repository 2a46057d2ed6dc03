//! Training throughput of the paper's forward models, for the side-by-side comparison with
//! PyTorch in `tests/bench/train_bench.py` (which runs this binary and PyTorch on the same
//! data and prints the table).
//!
//! Trains a warm-up epoch on the first `--warmup-rows` rows, then times one full epoch
//! (shuffle included) and prints one JSON line per model and batch size.
//!
//! ```text
//! cargo run --release -p causal_arm_mlp --example train_bench -- \
//!     [--model exp1|exp2|all] [--batch 256,1024] [--rows 200000] [--warmup-rows 20000]
//!     [--threads 2] [--x FILE --y FILE]
//! ```
//! `--x`/`--y` are raw little-endian f32 row-major files (one model only); without them
//! the data are uniform in [−1, 1) from a fixed seed.

use std::error::Error;
use std::time::Instant;

use causal_arm_mlp::{Fitter, Head, Mlp, MlpSpec, Optimizer, TrainConfig};
use rand::{Rng, SeedableRng, rngs::StdRng};

/// The paper's forward models: (name, inputs, heads).
fn spec(model: &str) -> Option<MlpSpec> {
    let (inputs, heads): (usize, &[(&str, usize)]) = match model {
        "exp1" => (17, &[("theta", 7), ("ef", 3)]),
        "exp2" => (
            31,
            &[
                ("obj_pos", 3),
                ("obj_rot", 3),
                ("colour", 3),
                ("theta", 7),
                ("ef_pos", 3),
                ("ef_rot", 3),
                ("magnet", 1),
            ],
        ),
        _ => return None,
    };
    Some(MlpSpec {
        inputs,
        hidden: vec![256; 3],
        heads: heads
            .iter()
            .map(|&(name, size)| Head {
                name: name.into(),
                size,
            })
            .collect(),
    })
}

struct Args {
    models: Vec<String>,
    batches: Vec<usize>,
    rows: usize,
    warmup_rows: usize,
    threads: usize,
    x: Option<String>,
    y: Option<String>,
}

fn parse() -> Result<Args, Box<dyn Error>> {
    let mut args = Args {
        models: vec!["exp1".into(), "exp2".into()],
        batches: vec![256, 1024],
        rows: 200_000,
        warmup_rows: 20_000,
        threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
        x: None,
        y: None,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut value = || it.next().ok_or_else(|| format!("{flag} needs a value"));
        match flag.as_str() {
            "--model" => {
                let v = value()?;
                if v != "all" {
                    args.models = v.split(',').map(String::from).collect();
                }
            }
            "--batch" => {
                args.batches = value()?
                    .split(',')
                    .map(str::parse)
                    .collect::<Result<_, _>>()?
            }
            "--rows" => args.rows = value()?.parse()?,
            "--warmup-rows" => args.warmup_rows = value()?.parse()?,
            "--threads" => args.threads = value()?.parse()?,
            "--x" => args.x = Some(value()?),
            "--y" => args.y = Some(value()?),
            _ => return Err(format!("unknown argument {flag}").into()),
        }
    }
    Ok(args)
}

fn read_f32(path: &str) -> Result<Vec<f32>, Box<dyn Error>> {
    let bytes = std::fs::read(path)?;
    if bytes.len() % 4 != 0 {
        return Err(format!("{path}: {} bytes is not a whole number of f32", bytes.len()).into());
    }
    Ok(bytes
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect())
}

fn main() -> Result<(), Box<dyn Error>> {
    let args = parse()?;
    if args.x.is_some() != args.y.is_some() || (args.x.is_some() && args.models.len() != 1) {
        return Err("--x and --y go together, with exactly one --model".into());
    }
    for model in &args.models {
        let spec = spec(model).ok_or_else(|| format!("unknown model {model}"))?;
        let (n_in, n_out) = (spec.inputs, spec.outputs());
        let (x, y) = match (&args.x, &args.y) {
            (Some(xp), Some(yp)) => (read_f32(xp)?, read_f32(yp)?),
            _ => {
                let mut rng = StdRng::seed_from_u64(0);
                let x = (0..args.rows * n_in)
                    .map(|_| rng.random_range(-1.0..1.0))
                    .collect();
                let y = (0..args.rows * n_out)
                    .map(|_| rng.random_range(-1.0..1.0))
                    .collect();
                (x, y)
            }
        };
        let rows = x.len() / n_in;
        let warmup = args.warmup_rows.clamp(1, rows);
        for &batch in &args.batches {
            let config = TrainConfig {
                optimizer: Optimizer::Adam,
                learning_rate: 1e-3,
                batch_size: batch,
                seed: 0,
                ..TrainConfig::default()
            };
            let mut fitter =
                Fitter::new(Mlp::new(spec.clone(), 0)?, config)?.with_threads(args.threads);
            fitter.epoch(&x[..warmup * n_in], &y[..warmup * n_out], |_| {})?;
            let start = Instant::now();
            let loss = fitter.epoch(&x, &y, |_| {})?;
            let seconds = start.elapsed().as_secs_f64();
            println!(
                "{{\"impl\":\"ours\",\"model\":\"{model}\",\"batch\":{batch},\"rows\":{rows},\"threads\":{},\"seconds\":{seconds:.4},\"samples_per_s\":{:.1},\"loss\":{loss:.6}}}",
                fitter.threads(),
                rows as f64 / seconds
            );
        }
    }
    Ok(())
}
