use candle_core::{DType, Var};
use candle_nn::{AdamW, Optimizer as _, ParamsAdamW};

use super::*;
use crate::{Head, MlpSpec, Regressor, Standardizer};

fn spec() -> MlpSpec {
    MlpSpec {
        inputs: 5,
        hidden: vec![16, 12],
        heads: vec![
            Head {
                name: "a".into(),
                size: 3,
            },
            Head {
                name: "b".into(),
                size: 1,
            },
        ],
    }
}

fn data(rows: usize, seed: u64) -> (Vec<f32>, Vec<f32>) {
    let mut rng = StdRng::seed_from_u64(seed);
    let x: Vec<f32> = (0..rows * 5)
        .map(|_| rand::Rng::random_range(&mut rng, -1.0..1.0))
        .collect();
    let y = x
        .chunks(5)
        .flat_map(|r| [r[0].sin(), r[1] * r[2], r[3] - r[4], 10.0 * r[0] * r[0]])
        .collect();
    (x, y)
}

/// Reference loss through candle's autograd on the same parameters.
fn autograd_loss(vars: &[(Var, Var)], x: &Tensor, y: &Tensor, weight: &Tensor) -> Tensor {
    let mut h = x.clone();
    for (i, (w, b)) in vars.iter().enumerate() {
        h = h
            .matmul(&w.as_tensor().t().unwrap())
            .unwrap()
            .broadcast_add(b.as_tensor())
            .unwrap();
        if i + 1 < vars.len() {
            h = h.tanh().unwrap();
        }
    }
    let rows = x.dims2().unwrap().0 as f64;
    ((h - y)
        .unwrap()
        .sqr()
        .unwrap()
        .broadcast_mul(weight)
        .unwrap()
        .sum_all()
        .unwrap()
        / rows)
        .unwrap()
}

fn vars_of(mlp: &Mlp) -> Vec<(Var, Var)> {
    mlp.layers()
        .iter()
        .map(|l| {
            (
                Var::from_tensor(&l.weight).unwrap(),
                Var::from_tensor(&l.bias).unwrap(),
            )
        })
        .collect()
}

fn max_abs_diff(a: &Tensor, b: &Tensor) -> f32 {
    (a - b)
        .unwrap()
        .abs()
        .unwrap()
        .flatten_all()
        .unwrap()
        .max(0)
        .unwrap()
        .to_scalar::<f32>()
        .unwrap()
}

#[test]
fn gradients_match_candle_autograd() {
    let mlp = Mlp::new(spec(), 7).unwrap();
    let fitter = Fitter::new(mlp.clone(), TrainConfig::default()).unwrap();
    let (x, y) = data(33, 1);
    let xt = Tensor::from_vec(x, (33, 5), &Device::Cpu).unwrap();
    let yt = Tensor::from_vec(y, (33, 4), &Device::Cpu).unwrap();
    let (loss, grads) = fitter.loss_and_gradients(&xt, &yt).unwrap();
    let vars = vars_of(&mlp);
    let reference = autograd_loss(&vars, &xt, &yt, &fitter.column_weight);
    assert!((reference.to_scalar::<f32>().unwrap() as f64 - loss).abs() < 1e-5 * loss.max(1.0));
    let store = reference.backward().unwrap();
    for ((w, b), (dw, db)) in vars.iter().zip(&grads) {
        let rw = store.get(w.as_tensor()).unwrap();
        let rb = store.get(b.as_tensor()).unwrap();
        assert!(
            max_abs_diff(rw, dw) < 1e-5,
            "weight gradient differs by {}",
            max_abs_diff(rw, dw)
        );
        assert!(
            max_abs_diff(rb, db) < 1e-5,
            "bias gradient differs by {}",
            max_abs_diff(rb, db)
        );
    }
}

#[test]
fn adamw_steps_match_candle_nn() {
    let mlp = Mlp::new(spec(), 3).unwrap();
    let config = TrainConfig {
        optimizer: Optimizer::AdamW {
            weight_decay: 0.004,
        },
        learning_rate: 1e-2,
        batch_size: 64,
        seed: 5,
        ..TrainConfig::default()
    };
    let mut fitter = Fitter::new(mlp.clone(), config).unwrap();
    let vars = vars_of(&mlp);
    let mut reference = AdamW::new(
        vars.iter()
            .flat_map(|(w, b)| [w.clone(), b.clone()])
            .collect(),
        ParamsAdamW {
            lr: 1e-2,
            beta1: 0.9,
            beta2: 0.999,
            eps: 1e-8,
            weight_decay: 0.004,
        },
    )
    .unwrap();
    let (x, y) = data(64, 2);
    let xt = Tensor::from_vec(x.clone(), (64, 5), &Device::Cpu).unwrap();
    let yt = Tensor::from_vec(y.clone(), (64, 4), &Device::Cpu).unwrap();
    for _ in 0..5 {
        // One batch holding every row: the shuffle does not change the gradient.
        fitter.epoch(&x, &y, |_| {}).unwrap();
        let loss = autograd_loss(&vars, &xt, &yt, &fitter.column_weight);
        reference.backward_step(&loss).unwrap();
    }
    for (layer, (w, b)) in fitter.mlp().layers().iter().zip(&vars) {
        assert!(max_abs_diff(&layer.weight, w.as_tensor()) < 1e-5);
        assert!(max_abs_diff(&layer.bias, b.as_tensor()) < 1e-5);
    }
}

#[test]
fn training_fits_a_smooth_function_reproducibly() {
    let (x, y) = data(2000, 4);
    let mut out = Standardizer::fit(&y, 4);
    let mut ys = y.clone();
    out.apply_in_place(&mut ys);
    let run = || {
        let mut fitter = Fitter::new(
            Mlp::new(spec(), 11).unwrap(),
            TrainConfig {
                batch_size: 32,
                ..TrainConfig::default()
            },
        )
        .unwrap();
        let before = fitter.loss(&x, &ys).unwrap();
        for _ in 0..40 {
            fitter.epoch(&x, &ys, |_| {}).unwrap();
        }
        (before, fitter.loss(&x, &ys).unwrap(), fitter.into_mlp())
    };
    let (before, after, mlp) = run();
    assert!(after < 0.05 * before, "loss {before} -> {after}");
    let (_, again, _) = run();
    assert_eq!(after, again, "same seed, same result");

    // Save and load through safetensors: same raw predictions.
    out = Standardizer::fit(&y, 4);
    let model = Regressor {
        mlp,
        input: Standardizer::identity(5),
        output: out,
    };
    let dir = std::env::temp_dir().join(format!("mlp-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("m.safetensors");
    model.save(&path).unwrap();
    let loaded = Regressor::load(spec(), &path).unwrap();
    assert_eq!(
        model.predict(&x[..50]).unwrap(),
        loaded.predict(&x[..50]).unwrap()
    );
    let wrong = MlpSpec {
        hidden: vec![16, 13],
        ..spec()
    };
    let err = Regressor::load(wrong, &path).unwrap_err().to_string();
    assert!(
        err.contains("layers.1.weight") && err.contains("[13, 16]"),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_shapes_are_refused() {
    let mut fitter = Fitter::new(Mlp::new(spec(), 0).unwrap(), TrainConfig::default()).unwrap();
    let err = fitter
        .epoch(&[0.0; 9], &[0.0; 4], |_| {})
        .unwrap_err()
        .to_string();
    assert!(err.contains("5 inputs"), "{err}");
    let model = Regressor {
        mlp: fitter.into_mlp(),
        input: Standardizer::identity(5),
        output: Standardizer::identity(4),
    };
    assert!(
        model
            .predict(&[1.0; 7])
            .unwrap_err()
            .to_string()
            .contains("multiple of the 5")
    );
    let bad = MlpSpec {
        hidden: vec![0],
        ..spec()
    };
    assert!(Mlp::new(bad, 0).is_err());
    assert_eq!(
        Tensor::zeros(1, DType::F32, &Device::Cpu).unwrap().dims(),
        [1]
    );
}

#[test]
fn thread_counts_agree_and_each_is_reproducible() {
    let (x, y) = data(500, 8);
    let fit = |threads: usize| {
        let mut fitter = Fitter::new(
            Mlp::new(spec(), 2).unwrap(),
            TrainConfig {
                batch_size: 100,
                seed: 9,
                ..TrainConfig::default()
            },
        )
        .unwrap()
        .with_threads(threads);
        assert_eq!(fitter.threads(), threads);
        let mut seen = 0;
        for _ in 0..3 {
            fitter.epoch(&x, &y, |n| seen += n).unwrap();
        }
        assert_eq!(seen, 1500);
        let flat = |m: &Mlp| -> Vec<f32> {
            m.layers()
                .iter()
                .flat_map(|l| {
                    let mut v: Vec<f32> = l.weight.flatten_all().unwrap().to_vec1().unwrap();
                    v.extend(l.bias.to_vec1::<f32>().unwrap());
                    v
                })
                .collect()
        };
        let via_ref = flat(fitter.mlp());
        let owned = flat(&fitter.into_mlp());
        assert_eq!(via_ref, owned);
        owned
    };
    let one = fit(1);
    let two = fit(2);
    let three = fit(3);
    assert_eq!(two, fit(2), "same seed and thread count, same bits");
    for other in [&two, &three] {
        let diff = one
            .iter()
            .zip(other.iter())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        assert!(diff < 1e-3, "thread counts differ by {diff}");
    }
}

#[test]
fn loss_matches_the_candle_forward_pass() {
    let mlp = Mlp::new(spec(), 5).unwrap();
    let fitter = Fitter::new(mlp.clone(), TrainConfig::default()).unwrap();
    let (x, y) = data(1300, 3);
    let xt = Tensor::from_vec(x.clone(), (1300, 5), &Device::Cpu).unwrap();
    let yt = Tensor::from_vec(y.clone(), (1300, 4), &Device::Cpu).unwrap();
    let reference = ((mlp.forward(&xt).unwrap() - yt).unwrap())
        .sqr()
        .unwrap()
        .broadcast_mul(&fitter.column_weight)
        .unwrap()
        .sum_all()
        .unwrap()
        .to_scalar::<f32>()
        .unwrap() as f64
        / 1300.0;
    let ours = fitter.loss(&x, &y).unwrap();
    assert!(
        (ours - reference).abs() < 1e-5 * reference,
        "{ours} vs {reference}"
    );
    let bad = Tensor::zeros((3, 4), DType::F32, &Device::Cpu).unwrap();
    assert!(fitter.loss_and_gradients(&bad, &bad).is_err());
}

#[test]
fn fast_row_forward_matches_candle_forward() {
    let mlp = Mlp::new(spec(), 21).unwrap();
    let (x, _) = data(300, 8);
    let reference = mlp
        .forward(&Tensor::from_vec(x.clone(), (300, 5), &Device::Cpu).unwrap())
        .unwrap()
        .flatten_all()
        .unwrap()
        .to_vec1::<f32>()
        .unwrap();
    let fast = mlp.forward_rows(&x).unwrap();
    assert_eq!(fast.len(), reference.len());
    for (a, b) in fast.iter().zip(&reference) {
        assert!((a - b).abs() <= 1e-5 * (1.0 + b.abs()), "{a} vs {b}");
    }
    assert!(mlp.forward_rows(&x[..7]).is_err());
}

#[test]
fn cosine_schedule_runs_from_the_rate_to_its_floor() {
    let cosine = LrSchedule::Cosine { floor: 0.01 };
    assert_eq!(cosine.factor(0, Some(100)), 1.0);
    assert!((cosine.factor(50, Some(100)) - 0.505).abs() < 1e-12);
    assert!((cosine.factor(100, Some(100)) - 0.01).abs() < 1e-12);
    assert!((cosine.factor(1000, Some(100)) - 0.01).abs() < 1e-12);
    let mut last = 2.0;
    for done in 0..=100 {
        let f = cosine.factor(done, Some(100));
        assert!(f <= last, "not decreasing at {done}");
        last = f;
    }
    // Unplanned, every schedule is constant.
    assert_eq!(cosine.factor(70, None), 1.0);
    assert_eq!(LrSchedule::Constant.factor(70, Some(100)), 1.0);
}

#[test]
fn schedules_parse_and_print_back() {
    for text in ["constant", "cosine:0.01", "cosine:0"] {
        let parsed: LrSchedule = text.parse().unwrap();
        assert_eq!(parsed.to_string(), text);
    }
    assert_eq!(
        "cosine".parse::<LrSchedule>().unwrap(),
        LrSchedule::Cosine { floor: 0.01 }
    );
    for bad in ["linear", "cosine:2", "cosine:x", "constant:1", ""] {
        let err = bad.parse::<LrSchedule>().unwrap_err();
        assert!(err.contains("expected constant, cosine"), "{bad}: {err}");
    }
}

#[test]
fn planned_cosine_fit_decays_and_a_floor_of_one_is_constant() {
    let (x, y) = data(400, 4);
    let fit = |schedule: LrSchedule| {
        let mut fitter = Fitter::new(
            Mlp::new(spec(), 4).unwrap(),
            TrainConfig {
                batch_size: 50,
                schedule,
                ..TrainConfig::default()
            },
        )
        .unwrap()
        .with_threads(1);
        let planned = fitter.batches_for(3, 400);
        assert_eq!(planned, 24);
        fitter.plan_batches(planned);
        for _ in 0..3 {
            fitter.epoch(&x, &y, |_| {}).unwrap();
        }
        fitter.into_mlp().layers()[0]
            .weight
            .flatten_all()
            .unwrap()
            .to_vec1::<f32>()
            .unwrap()
    };
    let constant = fit(LrSchedule::Constant);
    assert_eq!(fit(LrSchedule::Cosine { floor: 1.0 }), constant);
    assert_ne!(fit(LrSchedule::Cosine { floor: 0.0 }), constant);
}
