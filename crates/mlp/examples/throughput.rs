//! Training throughput of one MLP configuration on random data (samples/s).
//! `cargo run --release -p causal_arm_mlp --example throughput -- [inputs] [outputs] [batch] [rows]`
use causal_arm_mlp::{Fitter, Head, Mlp, MlpSpec, Optimizer, TrainConfig};
use rand::{Rng, SeedableRng, rngs::StdRng};

fn main() {
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .map(|a| a.parse().expect("numbers"))
        .collect();
    let inputs = *args.first().unwrap_or(&17);
    let outputs = *args.get(1).unwrap_or(&10);
    let batch = *args.get(2).unwrap_or(&256);
    let rows = *args.get(3).unwrap_or(&100_000);
    let spec = MlpSpec {
        inputs,
        hidden: vec![256; 3],
        heads: vec![Head {
            name: "y".into(),
            size: outputs,
        }],
    };
    let mut rng = StdRng::seed_from_u64(0);
    let x: Vec<f32> = (0..rows * inputs)
        .map(|_| rng.random_range(-1.0..1.0))
        .collect();
    let y: Vec<f32> = (0..rows * outputs)
        .map(|_| rng.random_range(-1.0..1.0))
        .collect();
    let config = TrainConfig {
        optimizer: Optimizer::AdamW {
            weight_decay: 0.004,
        },
        batch_size: batch,
        ..TrainConfig::default()
    };
    let mut fitter = Fitter::new(Mlp::new(spec, 0).unwrap(), config).unwrap();
    let start = std::time::Instant::now();
    let loss = fitter.epoch(&x, &y, |_| {}).unwrap();
    let secs = start.elapsed().as_secs_f64();
    println!(
        "{inputs}->3x256->{outputs} batch {batch}: {:.0} samples/s (loss {loss:.4})",
        rows as f64 / secs
    );
}
