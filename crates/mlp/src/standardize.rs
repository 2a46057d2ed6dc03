//! Per-feature standardisation stored with a network, so models predict in raw units.

use std::collections::HashMap;

use candle_core::{Device, Tensor};

use crate::{Mlp, MlpError, MlpSpec, Result};

/// `(x − mean) / std` per column; constant columns get std 1 so they map to 0, not NaN.
#[derive(Debug, Clone, PartialEq)]
pub struct Standardizer {
    /// Column means.
    pub mean: Vec<f32>,
    /// Column standard deviations (1 where a column is constant).
    pub std: Vec<f32>,
}

impl Standardizer {
    /// Statistics of a row-major `[rows, width]` matrix, accumulated in f64.
    pub fn fit(data: &[f32], width: usize) -> Self {
        let rows = (data.len() / width.max(1)).max(1);
        let mut sum = vec![0f64; width];
        let mut sq = vec![0f64; width];
        for row in data.chunks_exact(width) {
            for (j, &v) in row.iter().enumerate() {
                sum[j] += v as f64;
                sq[j] += (v as f64) * (v as f64);
            }
        }
        let mean: Vec<f64> = sum.iter().map(|s| s / rows as f64).collect();
        let std = sq
            .iter()
            .zip(&mean)
            .map(|(s, m)| {
                let var = (s / rows as f64 - m * m).max(0.0);
                let sd = var.sqrt();
                if sd > 1e-8 { sd as f32 } else { 1.0 }
            })
            .collect();
        Self {
            mean: mean.iter().map(|&m| m as f32).collect(),
            std,
        }
    }

    /// Identity transform of the given width.
    pub fn identity(width: usize) -> Self {
        Self {
            mean: vec![0.0; width],
            std: vec![1.0; width],
        }
    }

    /// Number of columns.
    pub fn width(&self) -> usize {
        self.mean.len()
    }

    /// Standardises a row-major matrix in place.
    pub fn apply_in_place(&self, data: &mut [f32]) {
        for row in data.chunks_exact_mut(self.width()) {
            for ((v, m), s) in row.iter_mut().zip(&self.mean).zip(&self.std) {
                *v = (*v - m) / s;
            }
        }
    }

    /// Maps standardised values back to raw units in place.
    pub fn invert_in_place(&self, data: &mut [f32]) {
        for row in data.chunks_exact_mut(self.width()) {
            for ((v, m), s) in row.iter_mut().zip(&self.mean).zip(&self.std) {
                *v = *v * s + m;
            }
        }
    }

    fn tensors(&self, prefix: &str, map: &mut HashMap<String, Tensor>) -> Result<()> {
        let n = self.width();
        map.insert(
            format!("{prefix}.mean"),
            Tensor::from_vec(self.mean.clone(), n, &Device::Cpu)?,
        );
        map.insert(
            format!("{prefix}.std"),
            Tensor::from_vec(self.std.clone(), n, &Device::Cpu)?,
        );
        Ok(())
    }

    fn from_tensors(prefix: &str, width: usize, map: &HashMap<String, Tensor>) -> Result<Self> {
        let get = |name: String| -> Result<Vec<f32>> {
            let t = map
                .get(&name)
                .ok_or_else(|| MlpError::Format(format!("tensor {name} is missing")))?;
            if t.dims() != [width] {
                return Err(MlpError::Format(format!(
                    "tensor {name} has shape {:?}, expected [{width}]",
                    t.dims()
                )));
            }
            Ok(t.to_vec1::<f32>()?)
        };
        let std = get(format!("{prefix}.std"))?;
        if let Some(j) = std.iter().position(|s| !(s.is_finite() && *s > 0.0)) {
            return Err(MlpError::Format(format!(
                "{prefix}.std[{j}] = {} is not a positive number",
                std[j]
            )));
        }
        Ok(Self {
            mean: get(format!("{prefix}.mean"))?,
            std,
        })
    }
}

/// A network with the input and output standardisation it was trained with.
#[derive(Debug, Clone)]
pub struct Regressor {
    /// The network, mapping standardised inputs to standardised outputs.
    pub mlp: Mlp,
    /// Input standardisation.
    pub input: Standardizer,
    /// Output standardisation.
    pub output: Standardizer,
}

impl Regressor {
    /// Predictions in raw units for raw row-major inputs `[rows, inputs]`.
    pub fn predict(&self, x: &[f32]) -> Result<Vec<f32>> {
        let width = self.mlp.spec().inputs;
        if width == 0 || !x.len().is_multiple_of(width) {
            return Err(MlpError::Shape(format!(
                "input length {} is not a multiple of the {width} input features",
                x.len()
            )));
        }
        let mut z = x.to_vec();
        self.input.apply_in_place(&mut z);
        let mut y = self.mlp.forward_rows(&z)?;
        self.output.invert_in_place(&mut y);
        Ok(y)
    }

    /// All tensors (network and statistics) for one safetensors file.
    pub fn tensors(&self) -> Result<HashMap<String, Tensor>> {
        let mut map = self.mlp.tensors();
        self.input.tensors("input", &mut map)?;
        self.output.tensors("output", &mut map)?;
        Ok(map)
    }

    /// Rebuilds a regressor from [`Regressor::tensors`] output.
    pub fn from_tensors(spec: MlpSpec, map: &HashMap<String, Tensor>) -> Result<Self> {
        let input = Standardizer::from_tensors("input", spec.inputs, map)?;
        let output = Standardizer::from_tensors("output", spec.outputs(), map)?;
        Ok(Self {
            mlp: Mlp::from_tensors(spec, map)?,
            input,
            output,
        })
    }

    /// Writes the tensors to a safetensors file.
    pub fn save(&self, path: &std::path::Path) -> Result<()> {
        candle_core::safetensors::save(&self.tensors()?, path)?;
        Ok(())
    }

    /// Reads a safetensors file written by [`Regressor::save`].
    pub fn load(spec: MlpSpec, path: &std::path::Path) -> Result<Self> {
        let map = candle_core::safetensors::load(path, &Device::Cpu)
            .map_err(|e| MlpError::Format(format!("{}: {e}", path.display())))?;
        Self::from_tensors(spec, &map)
    }
}
