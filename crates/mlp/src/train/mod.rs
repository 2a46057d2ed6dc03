//! Mini-batch training with a hand-written backward pass and Adam / AdamW.
//!
//! While fitting, the parameters live in one flat `f32` buffer (each layer's weights
//! `[out, in]` then its bias) with the two Adam moments beside it, so the optimizer update
//! is one fused pass. A batch is split by rows across the trainer's threads; each thread
//! runs the forward and backward pass of its rows into its own preallocated buffers and
//! partial gradients, then the threads sum the partials and update disjoint halves of the
//! parameters. The split depends only on the batch size and the thread count, so a seed
//! gives bit-identical weights run to run on one machine with one thread count.
//! Candle tensors are made only when the network is asked for.

mod backprop;
mod config;

use std::ops::Range;
use std::sync::OnceLock;

use candle_core::{DType, Device, Tensor};
use rand::{SeedableRng, rngs::StdRng, seq::SliceRandom};
use rayon::prelude::*;

use crate::kernels::{self, AdamStep};
use crate::{Layer, Mlp, MlpError, Result};
use backprop::{Lane, Layout, LossWeights, forward, forward_backward, lane_rows};
use config::{BETA1, BETA2, EPSILON};
pub use config::{LrSchedule, Optimizer, TrainConfig};

/// Fewest rows worth giving a thread of their own: below this the wake-up and the
/// per-thread gradient sum cost more than the rows' matrix products.
const MIN_ROWS_PER_LANE: usize = 16;
/// Rows per forward block when evaluating the loss over a whole data set.
const EVAL_BLOCK: usize = 512;

/// Owns a network while it is trained, with the optimizer's moment estimates.
pub struct Fitter {
    /// Architecture, and the parameters the fit started from (replaced on materialising).
    template: Mlp,
    layout: Layout,
    config: TrainConfig,
    /// All parameters, in the [`Layout`] order.
    params: Vec<f32>,
    /// Adam's first and second moments, same layout.
    moment1: Vec<f32>,
    moment2: Vec<f32>,
    /// Loss weight per output column as a tensor, for the candle reference in tests.
    #[cfg(test)]
    column_weight: Tensor,
    /// Loss weight per output column: 1 / size of its head.
    weights: Vec<f32>,
    /// `2 w_j / rows` of the current batch.
    scale: Vec<f32>,
    step: i32,
    /// Batches the schedule spreads over, once planned.
    planned_batches: Option<u64>,
    rng: StdRng,
    /// Reused buffers of the shuffled epoch.
    shuffled_x: Vec<f32>,
    shuffled_y: Vec<f32>,
    /// Per-thread buffers.
    lanes: Vec<Lane>,
    threads: usize,
    /// Worker threads with denormals flushed; `None` falls back to rayon's global pool.
    pool: Option<rayon::ThreadPool>,
    /// Candle view of `params`, made on request and dropped by the next update.
    materialised: OnceLock<Mlp>,
}

impl Fitter {
    /// Starts fitting `mlp` from its current weights, on as many threads as the machine
    /// offers (see [`Fitter::with_threads`]).
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
        let layout = Layout::new(&mlp);
        let mut params = vec![0.0f32; layout.len];
        for (l, layer) in mlp.layers().iter().enumerate() {
            let weight = layer.weight.to_dtype(DType::F32)?.flatten_all()?;
            params[layout.weight(l)].copy_from_slice(&weight.to_vec1::<f32>()?);
            params[layout.bias(l)].copy_from_slice(&layer.bias.to_dtype(DType::F32)?.to_vec1()?);
        }
        let weights: Vec<f32> = mlp
            .spec()
            .heads
            .iter()
            .flat_map(|h| std::iter::repeat_n(1.0 / h.size as f32, h.size))
            .collect();
        let n_out = weights.len();
        let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
        let fitter = Self {
            #[cfg(test)]
            column_weight: Tensor::from_vec(weights.clone(), n_out, &Device::Cpu)?,
            scale: vec![0.0; n_out],
            weights,
            rng: StdRng::seed_from_u64(config.seed),
            moment1: vec![0.0; layout.len],
            moment2: vec![0.0; layout.len],
            params,
            template: mlp,
            layout,
            config,
            step: 0,
            planned_batches: None,
            shuffled_x: Vec::new(),
            shuffled_y: Vec::new(),
            lanes: Vec::new(),
            threads: 0,
            pool: None,
            materialised: OnceLock::new(),
        };
        Ok(fitter.with_threads(threads))
    }

    /// Trains on `threads` threads (at least 1). Results are reproducible for a given
    /// seed and thread count; a different count splits batches differently and so rounds
    /// gradient sums differently.
    pub fn with_threads(mut self, threads: usize) -> Self {
        let threads = threads.max(1);
        self.threads = threads;
        self.lanes = (0..threads).map(|_| Lane::new(&self.layout)).collect();
        self.pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .thread_name(|i| format!("mlp-train-{i}"))
            .start_handler(|_| kernels::flush_denormals())
            .build()
            .ok();
        self
    }

    /// Threads a batch is split across.
    pub fn threads(&self) -> usize {
        self.threads
    }

    /// The network as trained so far, as candle tensors (made on the first call after an
    /// update, then cached until the next epoch).
    pub fn mlp(&self) -> &Mlp {
        self.materialised.get_or_init(|| self.build_mlp())
    }

    /// Ends fitting and hands back the network.
    pub fn into_mlp(mut self) -> Mlp {
        match self.materialised.take() {
            Some(mlp) => mlp,
            None => self.build_mlp(),
        }
    }

    /// Copies the flat parameters into candle tensors.
    fn build_mlp(&self) -> Mlp {
        let layout = &self.layout;
        let tensor = |range: Range<usize>, shape: &[usize]| {
            Tensor::from_slice(&self.params[range], shape, &Device::Cpu)
                // Cannot fail: the layout gives every range exactly its shape's element count.
                .expect("parameter range matches its shape")
        };
        let layers = (0..layout.layers())
            .map(|l| {
                let (n_in, n_out) = (layout.widths[l], layout.widths[l + 1]);
                Layer {
                    weight: tensor(layout.weight(l), &[n_out, n_in]),
                    bias: tensor(layout.bias(l), &[n_out]),
                }
            })
            .collect();
        let mut mlp = self.template.clone();
        mlp.set_layers(layers);
        mlp
    }

    fn check_data(&self, x: &[f32], y: &[f32]) -> Result<usize> {
        let (n_in, n_out) = (self.layout.inputs(), self.layout.outputs());
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

    /// Threads used for a batch of `rows` rows.
    fn lanes_for(&self, rows: usize) -> usize {
        self.threads.min((rows / MIN_ROWS_PER_LANE).max(1))
    }

    /// Runs `work` on the trainer's threads (denormals flushed).
    fn run<R: Send>(pool: &Option<rayon::ThreadPool>, work: impl FnOnce() -> R + Send) -> R {
        match pool {
            Some(pool) => pool.install(work),
            None => work(),
        }
    }

    /// Tells the schedule how many batches the whole fit will run, e.g.
    /// `epochs × rows.div_ceil(batch_size)`; without it every schedule is constant.
    pub fn plan_batches(&mut self, batches: u64) {
        self.planned_batches = Some(batches);
    }

    /// Batches needed for `epochs` passes over `rows` rows at this fitter's batch size.
    pub fn batches_for(&self, epochs: usize, rows: usize) -> u64 {
        (epochs * rows.div_ceil(self.config.batch_size)) as u64
    }

    /// One pass over row-major standardised data in a fresh random order, batch by batch;
    /// `on_batch(rows)` is called after each update. Returns the mean training loss.
    pub fn epoch(&mut self, x: &[f32], y: &[f32], mut on_batch: impl FnMut(usize)) -> Result<f64> {
        let rows = self.check_data(x, y)?;
        let (n_in, n_out) = (self.layout.inputs(), self.layout.outputs());
        self.materialised.take();
        // Shuffle once per epoch into contiguous buffers so each batch is a plain slice.
        let mut order: Vec<usize> = (0..rows).collect();
        order.shuffle(&mut self.rng);
        self.shuffled_x.clear();
        self.shuffled_y.clear();
        self.shuffled_x.reserve(rows * n_in);
        self.shuffled_y.reserve(rows * n_out);
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
            total += self.train_step(start, n);
            start += n;
            on_batch(n);
        }
        Ok(total / rows as f64)
    }

    /// Forward, backward and optimizer update on shuffled rows `start..start + n`;
    /// returns the batch's unnormalised loss.
    fn train_step(&mut self, start: usize, n: usize) -> f64 {
        let used = self.lanes_for(n);
        let (n_in, n_out) = (self.layout.inputs(), self.layout.outputs());
        for (s, w) in self.scale.iter_mut().zip(&self.weights) {
            *s = 2.0 * w / n as f32;
        }
        self.step += 1;
        let adam = self.adam_step();
        let Self {
            layout,
            params,
            moment1,
            moment2,
            weights,
            scale,
            shuffled_x,
            shuffled_y,
            lanes,
            pool,
            ..
        } = self;
        let lanes = &mut lanes[..used];
        for (t, lane) in lanes.iter_mut().enumerate() {
            lane.reserve(layout, lane_rows(n, used, t).len());
        }
        let x = &shuffled_x[start * n_in..(start + n) * n_in];
        let y = &shuffled_y[start * n_out..(start + n) * n_out];
        let loss = LossWeights {
            weight: weights,
            scale,
        };
        let chunk = layout.len.div_ceil(used).next_multiple_of(64);
        Self::run(pool, || {
            let shared: &[f32] = params;
            lanes.par_iter_mut().enumerate().for_each(|(t, lane)| {
                let r = lane_rows(n, used, t);
                forward_backward(
                    layout,
                    shared,
                    &loss,
                    lane,
                    &x[r.start * n_in..r.end * n_in],
                    &y[r.start * n_out..r.end * n_out],
                    r.len(),
                );
            });
            let batch_loss = lanes.iter().map(|l| l.loss).sum::<f64>();
            if let Some((first, rest)) = lanes.split_first_mut() {
                let rest: &[Lane] = rest;
                params
                    .par_chunks_mut(chunk)
                    .zip(moment1.par_chunks_mut(chunk))
                    .zip(moment2.par_chunks_mut(chunk))
                    .zip(first.grads.par_chunks_mut(chunk))
                    .enumerate()
                    .for_each(|(i, (((p, m), v), g))| {
                        let span = i * chunk..i * chunk + g.len();
                        match rest {
                            [] => kernels::adam(p, m, v, g, &[], &adam),
                            [second] => kernels::adam(p, m, v, g, &second.grads[span], &adam),
                            _ => {
                                for other in rest.iter() {
                                    kernels::add_assign(g, &other.grads[span.clone()]);
                                }
                                kernels::adam(p, m, v, g, &[], &adam);
                            }
                        }
                    });
            }
            batch_loss
        })
    }

    fn adam_step(&self) -> AdamStep {
        // `step` was already advanced for this batch.
        let done = (self.step - 1).max(0) as u64;
        let lr =
            self.config.learning_rate * self.config.schedule.factor(done, self.planned_batches);
        let decay = match self.config.optimizer {
            Optimizer::Adam => 0.0,
            Optimizer::AdamW { weight_decay } => weight_decay,
        };
        AdamStep {
            beta1: BETA1 as f32,
            beta2: BETA2 as f32,
            scale_m: (1.0 / (1.0 - BETA1.powi(self.step))) as f32,
            scale_v: (1.0 / (1.0 - BETA2.powi(self.step))) as f32,
            lr: lr as f32,
            decay: (1.0 - lr * decay) as f32,
            eps: EPSILON as f32,
        }
    }

    /// Loss and parameter gradients `(dW, db)` per layer for one batch `x [n, inputs]`,
    /// `y [n, outputs]`, without updating (for checking the backward pass).
    pub fn loss_and_gradients(
        &self,
        x: &Tensor,
        y: &Tensor,
    ) -> Result<(f64, Vec<(Tensor, Tensor)>)> {
        let (rows, n_in) = x.dims2()?;
        let (y_rows, n_out) = y.dims2()?;
        if n_in != self.layout.inputs() || n_out != self.layout.outputs() || y_rows != rows {
            return Err(MlpError::Shape(format!(
                "batch of {:?} inputs and {:?} targets for a network of {} inputs and {} outputs",
                x.dims(),
                y.dims(),
                self.layout.inputs(),
                self.layout.outputs()
            )));
        }
        let xs = x.to_dtype(DType::F32)?.flatten_all()?.to_vec1::<f32>()?;
        let ys = y.to_dtype(DType::F32)?.flatten_all()?.to_vec1::<f32>()?;
        self.check_data(&xs, &ys)?;
        let used = self.lanes_for(rows);
        let scale: Vec<f32> = self.weights.iter().map(|w| 2.0 * w / rows as f32).collect();
        let loss = LossWeights {
            weight: &self.weights,
            scale: &scale,
        };
        let layout = &self.layout;
        let params: &[f32] = &self.params;
        let mut lanes: Vec<Lane> = (0..used).map(|_| Lane::new(layout)).collect();
        Self::run(&self.pool, || {
            lanes.par_iter_mut().enumerate().for_each(|(t, lane)| {
                let r = lane_rows(rows, used, t);
                lane.reserve(layout, r.len());
                forward_backward(
                    layout,
                    params,
                    &loss,
                    lane,
                    &xs[r.start * n_in..r.end * n_in],
                    &ys[r.start * n_out..r.end * n_out],
                    r.len(),
                );
            })
        });
        let total = lanes.iter().map(|l| l.loss).sum::<f64>() / rows as f64;
        let mut grads = vec![0.0f32; layout.len];
        for lane in &lanes {
            kernels::add_assign(&mut grads, &lane.grads);
        }
        let tensors = (0..layout.layers())
            .map(|l| {
                let (n_in, n_out) = (layout.widths[l], layout.widths[l + 1]);
                Ok((
                    Tensor::from_slice(&grads[layout.weight(l)], (n_out, n_in), &Device::Cpu)?,
                    Tensor::from_slice(&grads[layout.bias(l)], n_out, &Device::Cpu)?,
                ))
            })
            .collect::<Result<Vec<_>>>()?;
        Ok((total, tensors))
    }

    /// Mean training loss over row-major standardised data, without updating.
    pub fn loss(&self, x: &[f32], y: &[f32]) -> Result<f64> {
        let rows = self.check_data(x, y)?;
        let (n_in, n_out) = (self.layout.inputs(), self.layout.outputs());
        let used = self.threads.min(rows.div_ceil(EVAL_BLOCK)).max(1);
        let layout = &self.layout;
        let params: &[f32] = &self.params;
        let weights: &[f32] = &self.weights;
        let last = layout.layers() - 1;
        let losses: Vec<f64> = Self::run(&self.pool, || {
            (0..used)
                .into_par_iter()
                .map(|t| {
                    let r = lane_rows(rows, used, t);
                    let mut acts: Vec<Vec<f32>> = layout.widths[1..]
                        .iter()
                        .map(|w| vec![0.0; EVAL_BLOCK.min(r.len()) * w])
                        .collect();
                    let mut total = 0.0;
                    let mut start = r.start;
                    while start < r.end {
                        let n = EVAL_BLOCK.min(r.end - start);
                        forward(
                            layout,
                            params,
                            &mut acts,
                            &x[start * n_in..(start + n) * n_in],
                            n,
                        );
                        total += kernels::output_loss(
                            &acts[last][..n * n_out],
                            &params[layout.bias(last)],
                            &y[start * n_out..(start + n) * n_out],
                            weights,
                        );
                        start += n;
                    }
                    total
                })
                .collect()
        });
        Ok(losses.iter().sum::<f64>() / rows as f64)
    }
}

#[cfg(test)]
mod tests;
