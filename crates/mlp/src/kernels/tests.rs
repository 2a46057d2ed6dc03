use candle_core::{Device, Tensor};
use rand::{Rng, SeedableRng, rngs::StdRng};

use super::*;

fn random(n: usize, scale: f32, seed: u64) -> Vec<f32> {
    let mut rng = StdRng::seed_from_u64(seed);
    (0..n).map(|_| rng.random_range(-scale..scale)).collect()
}

fn tensor(v: &[f32], shape: (usize, usize)) -> Tensor {
    Tensor::from_slice(v, shape, &Device::Cpu).unwrap()
}

fn flat(t: &Tensor) -> Vec<f32> {
    t.flatten_all().unwrap().to_vec1().unwrap()
}

fn max_abs_diff(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

#[test]
fn fast_tanh_is_within_half_a_micro_of_exact_everywhere() {
    // Dense grid over ±12 plus a log grid of small magnitudes down to 1e-30.
    let grid = (0..=2_400_000).map(|i| -12.0 + i as f64 * 1e-5);
    let small = (0..=3000).flat_map(|i| {
        let x = 10f64.powf(-30.0 + i as f64 * 0.01);
        [x, -x]
    });
    let mut worst = (0.0f64, 0.0f64);
    for x in grid.chain(small) {
        let x = x as f32;
        let exact = (x as f64).tanh();
        let fast = tanh_fast(x) as f64;
        assert!(fast.abs() <= 1.0, "|tanh({x})| = {fast} > 1");
        let rel = (fast - exact).abs() / exact.abs().max(f64::MIN_POSITIVE);
        if rel > worst.0 {
            worst = (rel, x as f64);
        }
    }
    assert!(worst.0 < 5e-7, "relative error {} at {}", worst.0, worst.1);
    assert_eq!(tanh_fast(0.0), 0.0);
    assert_eq!(tanh_fast(f32::INFINITY), 1.0);
    assert_eq!(tanh_fast(f32::NEG_INFINITY), -1.0);
    assert!(tanh_fast(f32::NAN).is_nan());
}

#[test]
fn bias_tanh_matches_candle() {
    let (rows, width) = (37, 19);
    let z = random(rows * width, 4.0, 1);
    let b = random(width, 1.0, 2);
    let expected = tensor(&z, (rows, width))
        .broadcast_add(&Tensor::from_slice(&b, width, &Device::Cpu).unwrap())
        .unwrap()
        .tanh()
        .unwrap();
    let mut ours = z.clone();
    bias_tanh(&mut ours, &b);
    assert!(max_abs_diff(&ours, &flat(&expected)) < 1e-6);
}

#[test]
fn tanh_delta_matches_candle() {
    let (rows, width) = (29, 21);
    let up = random(rows * width, 2.0, 3);
    let h: Vec<f32> = random(rows * width, 3.0, 4)
        .iter()
        .map(|v| v.tanh())
        .collect();
    let ht = tensor(&h, (rows, width));
    let expected = (tensor(&up, (rows, width)) * (1.0 - ht.sqr().unwrap()).unwrap()).unwrap();
    let mut ours = h.clone();
    let mut db = vec![0.5f32; width];
    tanh_delta(&up, &mut ours, &mut db);
    assert!(max_abs_diff(&ours, &flat(&expected)) < 1e-6);
    let sums = (expected.sum(0).unwrap() + 0.5).unwrap();
    assert!(max_abs_diff(&db, &flat(&sums)) < 1e-5);
}

#[test]
fn output_delta_and_loss_match_candle() {
    let (rows, width) = (23, 10);
    let z = random(rows * width, 2.0, 5);
    let y = random(rows * width, 2.0, 6);
    let b = random(width, 1.0, 7);
    let w: Vec<f32> = (0..width)
        .map(|j| if j < 7 { 1.0 / 7.0 } else { 1.0 / 3.0 })
        .collect();
    let scale: Vec<f32> = w.iter().map(|w| 2.0 * w / rows as f32).collect();
    let wt = Tensor::from_slice(&w, width, &Device::Cpu).unwrap();
    let error = (tensor(&z, (rows, width))
        .broadcast_add(&Tensor::from_slice(&b, width, &Device::Cpu).unwrap())
        .unwrap()
        - tensor(&y, (rows, width)))
    .unwrap();
    let loss = error
        .sqr()
        .unwrap()
        .broadcast_mul(&wt)
        .unwrap()
        .sum_all()
        .unwrap()
        .to_scalar::<f32>()
        .unwrap() as f64;
    let grad = error
        .broadcast_mul(&(&wt * (2.0 / rows as f64)).unwrap())
        .unwrap();
    assert!((output_loss(&z, &b, &y, &w) - loss).abs() < 1e-5 * loss);
    let mut ours = z.clone();
    let mut db = vec![0.0f32; width];
    let ours_loss = output_delta(&mut ours, &b, &y, &w, &scale, &mut db);
    assert!((ours_loss - loss).abs() < 1e-5 * loss);
    assert!(max_abs_diff(&ours, &flat(&grad)) < 1e-6);
    assert!(max_abs_diff(&db, &flat(&grad.sum(0).unwrap())) < 1e-6);
}

#[test]
fn matmuls_match_candle() {
    let (m, n, k) = (33, 17, 45);
    let a = random(m * k, 1.0, 8);
    let b_nk = random(n * k, 1.0, 9);
    let a_km = random(k * m, 1.0, 10);
    let b_kn = random(k * n, 1.0, 11);
    let mut dst = vec![f32::NAN; m * n];
    matmul_nt(&mut dst, &a, &b_nk, m, n, k);
    let expected = tensor(&a, (m, k))
        .matmul(&tensor(&b_nk, (n, k)).t().unwrap())
        .unwrap();
    assert!(max_abs_diff(&dst, &flat(&expected)) < 1e-5);
    matmul_tn(&mut dst, &a_km, &b_kn, m, n, k);
    let expected = tensor(&a_km, (k, m))
        .t()
        .unwrap()
        .matmul(&tensor(&b_kn, (k, n)))
        .unwrap();
    assert!(max_abs_diff(&dst, &flat(&expected)) < 1e-5);
    matmul_nn(&mut dst, &a, &b_kn, m, n, k);
    let expected = tensor(&a, (m, k)).matmul(&tensor(&b_kn, (k, n))).unwrap();
    assert!(max_abs_diff(&dst, &flat(&expected)) < 1e-5);
    // An empty inner dimension gives zeros, not stale values.
    matmul_nn(&mut dst, &[], &[], m, n, 0);
    assert!(dst.iter().all(|&v| v == 0.0));
}

#[test]
fn adam_matches_the_textbook_update_in_f64() {
    let n = 1000;
    let mut p = random(n, 1.0, 12);
    let mut m = random(n, 0.1, 13);
    let mut v: Vec<f32> = random(n, 0.1, 14).iter().map(|x| x * x).collect();
    let g = random(n, 1.0, 15);
    let (lr, wd, t) = (1e-3f64, 0.004f64, 7);
    let s = AdamStep {
        beta1: 0.9,
        beta2: 0.999,
        scale_m: (1.0 / (1.0 - 0.9f64.powi(t))) as f32,
        scale_v: (1.0 / (1.0 - 0.999f64.powi(t))) as f32,
        lr: lr as f32,
        decay: (1.0 - lr * wd) as f32,
        eps: 1e-8,
    };
    let expected: Vec<(f64, f64, f64)> = (0..n)
        .map(|i| {
            let (p, m, v, g) = (p[i] as f64, m[i] as f64, v[i] as f64, g[i] as f64);
            let m = 0.9 * m + 0.1 * g;
            let v = 0.999 * v + 0.001 * g * g;
            let m_hat = m / (1.0 - 0.9f64.powi(t));
            let v_hat = v / (1.0 - 0.999f64.powi(t));
            (
                p * (1.0 - lr * wd) - lr * m_hat / (v_hat.sqrt() + 1e-8),
                m,
                v,
            )
        })
        .collect();
    // Once with the whole gradient, once with it split into two partial sums.
    let half: Vec<f32> = g.iter().map(|g| g * 0.5).collect();
    let (mut p2, mut m2, mut v2) = (p.clone(), m.clone(), v.clone());
    adam(&mut p, &mut m, &mut v, &g, &[], &s);
    adam(&mut p2, &mut m2, &mut v2, &half, &half, &s);
    for (i, (ep, em, ev)) in expected.iter().enumerate() {
        assert!((p[i] as f64 - ep).abs() < 1e-6, "p[{i}]");
        assert!((m[i] as f64 - em).abs() < 1e-6, "m[{i}]");
        assert!((v[i] as f64 - ev).abs() < 1e-6, "v[{i}]");
    }
    assert_eq!((p, m, v), (p2, m2, v2));
}

#[test]
fn add_assign_adds() {
    let mut a = vec![1.0f32, 2.0, 3.0];
    add_assign(&mut a, &[0.5, -2.0, 1.0]);
    assert_eq!(a, [1.5, 0.0, 4.0]);
}

#[test]
fn flushing_denormals_turns_subnormal_results_to_zero() {
    // On a fresh thread so the test runner's own thread keeps its floating-point mode.
    let flushed = std::thread::spawn(|| {
        flush_denormals();
        let tiny = std::hint::black_box(f32::MIN_POSITIVE);
        std::hint::black_box(tiny) * std::hint::black_box(0.5f32)
    })
    .join()
    .unwrap();
    if cfg!(target_arch = "x86_64") {
        assert_eq!(flushed, 0.0);
    }
}
