//! Mini-batch training with a hand-written backward pass and Adam / AdamW.

use candle_core::{Device, Tensor};
use rand::{SeedableRng, rngs::StdRng, seq::SliceRandom};
use serde::{Deserialize, Serialize};

use crate::{Layer, Mlp, MlpError, Result};

/// The paper's optimizers (PyTorch semantics: AdamW decays weights decoupled from the
/// gradient, Adam has no decay).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum Optimizer {
    /// Adam, β = (0.9, 0.999), ε = 1e-8.
    Adam,
    /// AdamW with the given decoupled weight decay (the paper uses 0.004).
    AdamW {
        /// Decay factor per unit learning rate.
        weight_decay: f64,
    },
}

/// How to fit; stored in model files so a result can be reproduced.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrainConfig {
    /// Optimizer and its decay.
    pub optimizer: Optimizer,
    /// Step size (the paper: 1e-3).
    pub learning_rate: f64,
    /// Rows per mini-batch.
    pub batch_size: usize,
    /// Seed of the per-epoch shuffles.
    pub seed: u64,
}

impl Default for TrainConfig {
    fn default() -> Self {
        Self {
            optimizer: Optimizer::Adam,
            learning_rate: 1e-3,
            batch_size: 256,
            seed: 0,
        }
    }
}

const BETA1: f64 = 0.9;
const BETA2: f64 = 0.999;
const EPSILON: f64 = 1e-8;

/// Owns a network while it is trained, with the optimizer's moment estimates.
pub struct Fitter {
    mlp: Mlp,
    config: TrainConfig,
    /// First and second moments per layer: (m_w, m_b, v_w, v_b).
    moments: Vec<[Tensor; 4]>,
    /// Loss weight per output column: 1 / size of its head.
    column_weight: Tensor,
    step: i32,
    rng: StdRng,
    /// Reused buffers of the shuffled epoch.
    shuffled_x: Vec<f32>,
    shuffled_y: Vec<f32>,
}

impl Fitter {
    /// Starts fitting `mlp` from its current weights.
    pub fn new(mlp: Mlp, config: TrainConfig) -> Result<Self> {
        if config.batch_size == 0 {
            return Err(MlpError::Shape("batch size must be at least 1".into()));
        }
        if !(config.learning_rate.is_finite() && config.learning_rate > 0.0) {
            return Err(MlpError::Shape(format!(
                "learning rate must be a positive number, got {}",
                config.learning_rate
            )));
        }
        let moments = mlp
            .layers()
            .iter()
            .map(|l| -> Result<[Tensor; 4]> {
                Ok([
                    l.weight.zeros_like()?,
                    l.bias.zeros_like()?,
                    l.weight.zeros_like()?,
                    l.bias.zeros_like()?,
                ])
            })
            .collect::<Result<Vec<_>>>()?;
        let weights: Vec<f32> = mlp
            .spec()
            .heads
            .iter()
            .flat_map(|h| std::iter::repeat_n(1.0 / h.size as f32, h.size))
            .collect();
        let n_out = weights.len();
        Ok(Self {
            column_weight: Tensor::from_vec(weights, n_out, &Device::Cpu)?,
            rng: StdRng::seed_from_u64(config.seed),
            mlp,
            config,
            moments,
            step: 0,
            shuffled_x: Vec::new(),
            shuffled_y: Vec::new(),
        })
    }

    /// The network as trained so far.
    pub fn mlp(&self) -> &Mlp {
        &self.mlp
    }

    /// Ends fitting and hands back the network.
    pub fn into_mlp(self) -> Mlp {
        self.mlp
    }

    fn check_data(&self, x: &[f32], y: &[f32]) -> Result<usize> {
        let (n_in, n_out) = (self.mlp.spec().inputs, self.mlp.spec().outputs());
        let rows = x.len() / n_in;
        if x.len() != rows * n_in || y.len() != rows * n_out || rows == 0 {
            return Err(MlpError::Shape(format!(
                "training data: {} input values and {} target values do not make whole rows of {n_in} inputs and {n_out} targets",
                x.len(),
                y.len()
            )));
        }
        Ok(rows)
    }

    /// One pass over row-major standardised data in a fresh random order, batch by batch;
    /// `on_batch(rows)` is called after each update. Returns the mean training loss.
    pub fn epoch(&mut self, x: &[f32], y: &[f32], mut on_batch: impl FnMut(usize)) -> Result<f64> {
        let rows = self.check_data(x, y)?;
        let (n_in, n_out) = (self.mlp.spec().inputs, self.mlp.spec().outputs());
        // Shuffle once per epoch into contiguous buffers so each batch is a plain slice.
        let mut order: Vec<usize> = (0..rows).collect();
        order.shuffle(&mut self.rng);
        self.shuffled_x.clear();
        self.shuffled_y.clear();
        for &r in &order {
            self.shuffled_x
                .extend_from_slice(&x[r * n_in..(r + 1) * n_in]);
            self.shuffled_y
                .extend_from_slice(&y[r * n_out..(r + 1) * n_out]);
        }
        let mut total = 0.0;
        let batch = self.config.batch_size;
        let mut start = 0;
        while start < rows {
            let n = batch.min(rows - start);
            let xb = Tensor::from_slice(
                &self.shuffled_x[start * n_in..(start + n) * n_in],
                (n, n_in),
                &Device::Cpu,
            )?;
            let yb = Tensor::from_slice(
                &self.shuffled_y[start * n_out..(start + n) * n_out],
                (n, n_out),
                &Device::Cpu,
            )?;
            let (loss, grads) = self.loss_and_gradients(&xb, &yb)?;
            self.apply(&grads)?;
            total += loss * n as f64;
            start += n;
            on_batch(n);
        }
        Ok(total / rows as f64)
    }

    /// Loss and parameter gradients `(dW, db)` per layer for one batch, without updating.
    pub fn loss_and_gradients(
        &self,
        x: &Tensor,
        y: &Tensor,
    ) -> Result<(f64, Vec<(Tensor, Tensor)>)> {
        let layers = self.mlp.layers();
        let last = layers.len() - 1;
        let mut activations = vec![x.clone()];
        for layer in &layers[..last] {
            let h = layer.affine(activations.last().expect("input"))?.tanh()?;
            activations.push(h);
        }
        let prediction = layers[last].affine(activations.last().expect("hidden"))?;
        let rows = x.dims2()?.0 as f64;
        let error = (prediction - y)?;
        let loss = error
            .sqr()?
            .broadcast_mul(&self.column_weight)?
            .sum_all()?
            .to_scalar::<f32>()? as f64
            / rows;
        // dL/dŷ = 2 w_j (ŷ − y) / n
        let mut grad = error.broadcast_mul(&(&self.column_weight * (2.0 / rows))?)?;
        let mut grads = Vec::with_capacity(layers.len());
        for i in (0..layers.len()).rev() {
            let input = &activations[i];
            let d_weight = grad.t()?.matmul(input)?;
            let d_bias = grad.sum(0)?;
            grads.push((d_weight, d_bias));
            if i > 0 {
                // Back through layer i's matrix, then through the tanh of layer i − 1.
                let upstream = grad.matmul(&layers[i].weight)?;
                let tanh_slope = (1.0 - input.sqr()?)?;
                grad = (upstream * tanh_slope)?;
            }
        }
        grads.reverse();
        Ok((loss, grads))
    }

    fn apply(&mut self, grads: &[(Tensor, Tensor)]) -> Result<()> {
        self.step += 1;
        let lr = self.config.learning_rate;
        let correction1 = 1.0 - BETA1.powi(self.step);
        let correction2 = 1.0 - BETA2.powi(self.step);
        let decay = match self.config.optimizer {
            Optimizer::Adam => 0.0,
            Optimizer::AdamW { weight_decay } => weight_decay,
        };
        let mut layers = Vec::with_capacity(grads.len());
        for ((layer, (d_weight, d_bias)), moments) in
            self.mlp.layers().iter().zip(grads).zip(&mut self.moments)
        {
            let mut update =
                |param: &Tensor, grad: &Tensor, m: usize, v: usize| -> Result<Tensor> {
                    let new_m = ((&moments[m] * BETA1)? + (grad * (1.0 - BETA1))?)?;
                    let new_v = ((&moments[v] * BETA2)? + (grad.sqr()? * (1.0 - BETA2))?)?;
                    let step =
                        ((&new_m / correction1)? / ((&new_v / correction2)?.sqrt()? + EPSILON)?)?;
                    let decayed = if decay > 0.0 {
                        (param * (1.0 - lr * decay))?
                    } else {
                        param.clone()
                    };
                    moments[m] = new_m;
                    moments[v] = new_v;
                    Ok((decayed - (step * lr)?)?)
                };
            let weight = update(&layer.weight, d_weight, 0, 2)?;
            let bias = update(&layer.bias, d_bias, 1, 3)?;
            layers.push(Layer { weight, bias });
        }
        self.mlp.set_layers(layers);
        Ok(())
    }

    /// Mean training loss over row-major standardised data, without updating.
    pub fn loss(&self, x: &[f32], y: &[f32]) -> Result<f64> {
        let rows = self.check_data(x, y)?;
        let (n_in, n_out) = (self.mlp.spec().inputs, self.mlp.spec().outputs());
        let xt = Tensor::from_slice(x, (rows, n_in), &Device::Cpu)?;
        let yt = Tensor::from_slice(y, (rows, n_out), &Device::Cpu)?;
        let error = (self.mlp.forward(&xt)? - yt)?;
        Ok(error
            .sqr()?
            .broadcast_mul(&self.column_weight)?
            .sum_all()?
            .to_scalar::<f32>()? as f64
            / rows as f64)
    }
}

#[cfg(test)]
mod tests;
