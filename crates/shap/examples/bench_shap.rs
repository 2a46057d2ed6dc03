//! Times Deep SHAP (200 observations × 100 background rows) and Kernel SHAP (per
//! observation, k-means background of 50, default 2·M + 2048 coalitions) on a random
//! 31 → 3×256 → 23 forward model, the sizes of the DESIGN benchmark against `shap`.
//!
//! `cargo run --release -p causal_arm_shap --example bench_shap [kernel_obs [threads]]`

use std::time::Instant;

use causal_arm_mlp::{Head, Mlp, MlpSpec, Regressor, Standardizer};
use causal_arm_shap::{
    Background, DeepModel, DeepOptions, KernelOptions, Precision, RegressorModel, kernel_shap,
    kmeans,
};
use rand::{Rng, SeedableRng, rngs::StdRng};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let kernel_obs: usize = std::env::args().nth(1).map_or(Ok(4), |s| s.parse())?;
    let threads: Option<usize> = std::env::args().nth(2).map(|s| s.parse()).transpose()?;
    let (n_in, n_out) = (31, 23);
    let spec = MlpSpec {
        inputs: n_in,
        hidden: vec![256; 3],
        heads: vec![Head {
            name: "state".into(),
            size: n_out,
        }],
    };
    let reg = Regressor {
        mlp: Mlp::new(spec, 1)?,
        input: Standardizer::identity(n_in),
        output: Standardizer::identity(n_out),
    };
    let offset: Vec<usize> = (0..n_out).collect();
    let mut rng = StdRng::seed_from_u64(2);
    let mut data =
        |n: usize| -> Vec<f32> { (0..n * n_in).map(|_| rng.random_range(-1.5..1.5)).collect() };
    let x = data(200);
    let bg = data(100);
    let pool_data = data(1000);

    let model = DeepModel::from_regressor(&reg, Some(&offset))?;
    let mut results = vec![];
    for precision in [Precision::F64, Precision::F32] {
        let options = DeepOptions { precision, threads };
        let t = Instant::now();
        let a = model.explain(&x, &bg, &options)?;
        let dt = t.elapsed().as_secs_f64();
        let scale = a.values.iter().fold(0f64, |m, v| m.max(v.abs()));
        println!(
            "deep shap {precision:?}: 200 obs × 100 background: {dt:.3} s; efficiency error {:.2e} (floor 1e-9), {:.2e} (floor 1e-3·max|φ|)",
            a.efficiency_error(1e-9),
            a.efficiency_error(1e-3 * scale)
        );
        results.push(a);
    }
    let scale = results[0].values.iter().fold(0f64, |m, v| m.max(v.abs()));
    let diff = results[0]
        .values
        .iter()
        .zip(&results[1].values)
        .fold(0f64, |m, (p, q)| m.max((p - q).abs()));
    println!(
        "deep shap F32 vs F64: max |Δφ| = {:.1e} × max |φ|",
        diff / scale
    );

    let background: Background = kmeans(&pool_data, n_in, 50, 0)?;
    let km = RegressorModel::new(&reg, Some(&offset))?;
    let t = Instant::now();
    let a = kernel_shap(
        &km,
        &background,
        &x[..kernel_obs * n_in],
        &KernelOptions {
            threads,
            ..Default::default()
        },
    )?;
    let dt = t.elapsed().as_secs_f64() / kernel_obs as f64;
    println!(
        "kernel shap: {dt:.3} s per observation ({kernel_obs} obs, 50 k-means rows, {} coalitions); efficiency error {:.1e}",
        2 * n_in + 2048,
        a.efficiency_error(1e-9)
    );
    Ok(())
}
