//! The network: architecture, parameters, forward pass and (de)serialisation.

use std::collections::HashMap;

use candle_core::{DType, Device, Tensor};
use rand::{Rng, SeedableRng, rngs::StdRng};
use serde::{Deserialize, Serialize};

use crate::{MlpError, Result};

/// A named slice of the output vector with its own loss term.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Head {
    /// Name used in metrics (`theta`, `ef`, `obj_pos`, …).
    pub name: String,
    /// Number of outputs in this head.
    pub size: usize,
}

/// Architecture of a multi-head MLP; stored in every model file.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct MlpSpec {
    /// Input width.
    pub inputs: usize,
    /// Width of each tanh hidden layer, input side first.
    pub hidden: Vec<usize>,
    /// Output heads in output order.
    pub heads: Vec<Head>,
}

impl MlpSpec {
    /// Total output width (sum of head sizes).
    pub fn outputs(&self) -> usize {
        self.heads.iter().map(|h| h.size).sum()
    }

    /// Start column of each head in the output vector.
    pub fn head_offsets(&self) -> Vec<usize> {
        let mut offset = 0;
        self.heads
            .iter()
            .map(|h| {
                let start = offset;
                offset += h.size;
                start
            })
            .collect()
    }

    /// Refuses empty layers and heads, so a bad configuration fails before training.
    pub fn validate(&self) -> Result<()> {
        if self.inputs == 0 {
            return Err(MlpError::Shape("network has no inputs".into()));
        }
        if let Some(i) = self.hidden.iter().position(|&h| h == 0) {
            return Err(MlpError::Shape(format!("hidden layer {i} has width 0")));
        }
        if self.heads.is_empty() {
            return Err(MlpError::Shape("network has no output heads".into()));
        }
        if let Some(h) = self.heads.iter().find(|h| h.size == 0) {
            return Err(MlpError::Shape(format!("head {:?} has size 0", h.name)));
        }
        Ok(())
    }

    /// Multiply-adds of one forward pass for one sample (for FLOP accounting in benchmarks).
    pub fn macs_per_sample(&self) -> usize {
        let mut widths = vec![self.inputs];
        widths.extend(&self.hidden);
        widths.push(self.outputs());
        widths.windows(2).map(|w| w[0] * w[1]).sum()
    }

    /// Trainable weights and biases: what a smaller (reduced or factored) model saves.
    pub fn parameters(&self) -> usize {
        let biases: usize = self.hidden.iter().sum::<usize>() + self.outputs();
        self.macs_per_sample() + biases
    }
}

/// One affine layer, weights `[out, in]` as PyTorch and numpy readers expect.
#[derive(Debug, Clone)]
pub struct Layer {
    /// Weight matrix `[out, in]`.
    pub weight: Tensor,
    /// Bias `[out]`.
    pub bias: Tensor,
}

impl Layer {
    /// `x · Wᵀ + b` for a batch `[n, in]`.
    pub fn affine(&self, x: &Tensor) -> Result<Tensor> {
        Ok(x.matmul(&self.weight.t()?)?.broadcast_add(&self.bias)?)
    }
}

/// Tanh hidden layers and a linear multi-head output layer, f32 on the CPU.
#[derive(Debug, Clone)]
pub struct Mlp {
    spec: MlpSpec,
    /// Hidden layers then the output layer.
    layers: Vec<Layer>,
    /// The layers as plain row-major vectors for [`Mlp::forward_rows`], made on first use.
    flat: std::sync::OnceLock<Vec<(Vec<f32>, Vec<f32>)>>,
}

impl Mlp {
    /// Fresh weights drawn as PyTorch's `nn.Linear` does (U(±1/√fan_in) for weights and
    /// biases), so training curves are comparable with a PyTorch replica.
    pub fn new(spec: MlpSpec, seed: u64) -> Result<Self> {
        spec.validate()?;
        let mut rng = StdRng::seed_from_u64(seed);
        let mut widths = vec![spec.inputs];
        widths.extend(&spec.hidden);
        widths.push(spec.outputs());
        let layers = widths
            .windows(2)
            .map(|w| {
                let (fan_in, fan_out) = (w[0], w[1]);
                let bound = 1.0 / (fan_in as f32).sqrt();
                let mut uniform = |n: usize| -> Vec<f32> {
                    (0..n).map(|_| rng.random_range(-bound..bound)).collect()
                };
                let weight =
                    Tensor::from_vec(uniform(fan_out * fan_in), (fan_out, fan_in), &Device::Cpu)?;
                let bias = Tensor::from_vec(uniform(fan_out), fan_out, &Device::Cpu)?;
                Ok(Layer { weight, bias })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Self {
            spec,
            layers,
            flat: Default::default(),
        })
    }

    /// The architecture.
    pub fn spec(&self) -> &MlpSpec {
        &self.spec
    }

    /// Hidden layers then the output layer (for attribution methods walking the network).
    pub fn layers(&self) -> &[Layer] {
        &self.layers
    }

    /// Replaces the parameters (the trainer's optimizer owns them while fitting).
    pub(crate) fn set_layers(&mut self, layers: Vec<Layer>) {
        self.layers = layers;
        self.flat = std::sync::OnceLock::new();
    }

    fn flat_layers(&self) -> Result<&[(Vec<f32>, Vec<f32>)]> {
        if let Some(flat) = self.flat.get() {
            return Ok(flat);
        }
        let flat = self
            .layers
            .iter()
            .map(|l| {
                Ok((
                    l.weight.flatten_all()?.to_vec1::<f32>()?,
                    l.bias.to_vec1::<f32>()?,
                ))
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(self.flat.get_or_init(|| flat))
    }

    /// Outputs for row-major inputs `[rows, inputs]` through the training kernels (gemm
    /// with strides, fused bias + vectorised tanh): inference for services and attribution
    /// methods that evaluate the network on many rows. Agrees with [`Mlp::forward`] to
    /// the fast tanh's 3.4e-7 relative error.
    pub fn forward_rows(&self, x: &[f32]) -> Result<Vec<f32>> {
        let n_in = self.spec.inputs;
        if n_in == 0 || !x.len().is_multiple_of(n_in) {
            return Err(MlpError::Shape(format!(
                "input length {} is not a multiple of the {n_in} input features",
                x.len()
            )));
        }
        let rows = x.len() / n_in;
        let flat = self.flat_layers()?;
        let last = flat.len() - 1;
        let mut input = x.to_vec();
        let mut width = n_in;
        for (i, (weight, bias)) in flat.iter().enumerate() {
            let out = bias.len();
            let mut z = vec![0f32; rows * out];
            crate::kernels::matmul_nt(&mut z, &input, weight, rows, out, width);
            if i < last {
                crate::kernels::bias_tanh(&mut z, bias);
            } else {
                for row in z.chunks_exact_mut(out) {
                    row.iter_mut().zip(bias).for_each(|(v, b)| *v += b);
                }
            }
            input = z;
            width = out;
        }
        Ok(input)
    }

    /// Outputs `[n, outputs]` for inputs `[n, inputs]`.
    pub fn forward(&self, x: &Tensor) -> Result<Tensor> {
        let (_, width) = x.dims2()?;
        if width != self.spec.inputs {
            return Err(MlpError::Shape(format!(
                "expected {} input features, got {width}",
                self.spec.inputs
            )));
        }
        let mut h = x.to_dtype(DType::F32)?;
        let last = self.layers.len() - 1;
        for (i, layer) in self.layers.iter().enumerate() {
            h = layer.affine(&h)?;
            if i < last {
                h = h.tanh()?;
            }
        }
        Ok(h)
    }

    /// Parameters by name (`layers.{i}.weight|bias`), as stored in safetensors.
    pub fn tensors(&self) -> HashMap<String, Tensor> {
        let mut map = HashMap::new();
        for (i, layer) in self.layers.iter().enumerate() {
            map.insert(format!("layers.{i}.weight"), layer.weight.clone());
            map.insert(format!("layers.{i}.bias"), layer.bias.clone());
        }
        map
    }

    /// Rebuilds a network from [`Mlp::tensors`] output, checking every shape.
    pub fn from_tensors(spec: MlpSpec, tensors: &HashMap<String, Tensor>) -> Result<Self> {
        spec.validate()?;
        let mut widths = vec![spec.inputs];
        widths.extend(&spec.hidden);
        widths.push(spec.outputs());
        let mut layers = Vec::new();
        for (i, w) in widths.windows(2).enumerate() {
            let get = |name: String, shape: &[usize]| -> Result<Tensor> {
                let t = tensors
                    .get(&name)
                    .ok_or_else(|| MlpError::Format(format!("tensor {name} is missing")))?;
                if t.dims() != shape {
                    return Err(MlpError::Format(format!(
                        "tensor {name} has shape {:?}, expected {shape:?}",
                        t.dims()
                    )));
                }
                Ok(t.to_dtype(DType::F32)?)
            };
            layers.push(Layer {
                weight: get(format!("layers.{i}.weight"), &[w[1], w[0]])?,
                bias: get(format!("layers.{i}.bias"), &[w[1]])?,
            });
        }
        Ok(Self {
            spec,
            layers,
            flat: Default::default(),
        })
    }
}
