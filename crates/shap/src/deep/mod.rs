//! Deep SHAP: DeepLIFT's rescale rule through the folded tanh network, averaged over a
//! background set, as large matrix products over (observation, reference, output) rows.

mod explain;
mod real;

use causal_arm_mlp::{Mlp, Regressor, Standardizer};

use crate::{Attributions, Result, ShapError, check_rows};
use real::matmul;

/// Arithmetic of the multiplier matrix products. Forward passes, multipliers and the
/// accumulation of attributions are always f64; this picks the type of the big products.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Precision {
    /// f64 products: efficiency holds to ≈1e-12 relative (the default, for exactness).
    #[default]
    F64,
    /// f32 products: about twice as fast. Each multiplier carries f32 rounding (measured
    /// ≈4e-9 of the largest attribution after averaging over 100 references); the
    /// resulting per-(reference, output) residual of the summation-to-delta is spread over
    /// the inputs in proportion to |attribution|, so efficiency still holds to f64
    /// rounding.
    F32,
}

/// Settings of [`DeepModel::explain`].
#[derive(Debug, Clone, Default)]
pub struct DeepOptions {
    /// Type of the large matrix products.
    pub precision: Precision,
    /// Worker threads (`None`: all cores). Observations are split between threads.
    pub threads: Option<usize>,
}

/// One affine layer in f64, weights row-major `[out, in]`.
#[derive(Debug, Clone)]
struct Affine {
    weight: Vec<f64>,
    bias: Vec<f64>,
    inputs: usize,
    outputs: usize,
}

/// A tanh MLP with the regressor's standardisation folded into its first and last layer
/// and the delta model's offset columns, evaluated in f64 from the stored f32 weights.
/// This is the function Deep SHAP explains exactly (it agrees with
/// [`Regressor::predict`] to f32 rounding).
#[derive(Debug, Clone)]
pub struct DeepModel {
    /// Hidden layers (followed by tanh) then the linear output layer.
    layers: Vec<Affine>,
    /// `offset[j]` = the input column added to output `j`.
    offset: Option<Vec<usize>>,
}

/// Pre-activations and activations of every hidden layer, and the outputs, for a batch.
struct Forward {
    rows: usize,
    /// `z[l]` is `[rows, width_l]` before tanh.
    z: Vec<Vec<f64>>,
    /// `h[l] = tanh(z[l])`.
    h: Vec<Vec<f64>>,
    /// Network outputs `[rows, outputs]` in raw units, before offsets.
    net: Vec<f64>,
    /// `[rows, outputs]`, offsets included.
    out: Vec<f64>,
}

impl DeepModel {
    /// The bare network (standardised units in and out, no offset).
    pub fn from_mlp(mlp: &Mlp) -> Result<Self> {
        let layers = mlp
            .layers()
            .iter()
            .map(|l| {
                let (outputs, inputs) = l.weight.dims2()?;
                let weight: Vec<f64> = l
                    .weight
                    .flatten_all()?
                    .to_vec1::<f32>()?
                    .into_iter()
                    .map(f64::from)
                    .collect();
                let bias: Vec<f64> = l
                    .bias
                    .to_vec1::<f32>()?
                    .into_iter()
                    .map(f64::from)
                    .collect();
                if bias.len() != outputs {
                    return Err(ShapError::Shape(format!(
                        "layer bias has {} entries for {outputs} outputs",
                        bias.len()
                    )));
                }
                if weight.iter().chain(&bias).any(|v| !v.is_finite()) {
                    return Err(ShapError::NonFinite("network parameter".into()));
                }
                Ok(Affine {
                    weight,
                    bias,
                    inputs,
                    outputs,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        if layers.is_empty() {
            return Err(ShapError::Shape("network has no layers".into()));
        }
        if let Some(w) = layers.windows(2).find(|w| w[0].outputs != w[1].inputs) {
            return Err(ShapError::Shape(format!(
                "layer widths do not chain: {} outputs into {} inputs",
                w[0].outputs, w[1].inputs
            )));
        }
        Ok(Self {
            layers,
            offset: None,
        })
    }

    /// The regressor in raw units: `(x − mean)/std` folded into the first layer,
    /// `y·std + mean` into the last, and with `offset = Some(cols)` output `j` gets
    /// `+ x[cols[j]]` (the trainer's `offset_columns` of a delta model; one column per
    /// output).
    pub fn from_regressor(regressor: &Regressor, offset: Option<&[usize]>) -> Result<Self> {
        let mut model = Self::from_mlp(&regressor.mlp)?;
        let n_in = model.n_inputs();
        let n_out = model.n_outputs();
        check_standardizer("input", &regressor.input, n_in)?;
        check_standardizer("output", &regressor.output, n_out)?;
        let first = &mut model.layers[0];
        for u in 0..first.outputs {
            let row = &mut first.weight[u * n_in..(u + 1) * n_in];
            let mut shift = 0f64;
            for (i, w) in row.iter_mut().enumerate() {
                *w /= f64::from(regressor.input.std[i]);
                shift += *w * f64::from(regressor.input.mean[i]);
            }
            first.bias[u] -= shift;
        }
        let last = model.layers.last_mut().expect("checked non-empty");
        let width = last.inputs;
        for j in 0..n_out {
            let (s, m) = (
                f64::from(regressor.output.std[j]),
                f64::from(regressor.output.mean[j]),
            );
            last.weight[j * width..(j + 1) * width]
                .iter_mut()
                .for_each(|w| *w *= s);
            last.bias[j] = last.bias[j] * s + m;
        }
        model.offset = check_offset(offset, n_in, n_out)?;
        Ok(model)
    }

    /// Input width.
    pub fn n_inputs(&self) -> usize {
        self.layers[0].inputs
    }

    /// Output width.
    pub fn n_outputs(&self) -> usize {
        self.layers.last().map_or(0, |l| l.outputs)
    }

    /// Outputs `[rows, outputs]` in f64 for raw row-major inputs: the function whose
    /// attributions [`DeepModel::explain`] returns.
    pub fn predict(&self, x: &[f32]) -> Result<Vec<f64>> {
        check_rows("inputs", x, self.n_inputs())?;
        Ok(self.forward(x).out)
    }

    fn forward(&self, x: &[f32]) -> Forward {
        let n_in = self.n_inputs();
        let rows = x.len() / n_in;
        let mut input: Vec<f64> = x.iter().map(|&v| f64::from(v)).collect();
        let (mut z, mut h) = (Vec::new(), Vec::new());
        let last = self.layers.len() - 1;
        for (l, layer) in self.layers.iter().enumerate() {
            let mut pre = vec![0f64; rows * layer.outputs];
            matmul(
                &mut pre,
                &input,
                &layer.weight,
                rows,
                layer.outputs,
                layer.inputs,
                true,
            );
            for row in pre.chunks_exact_mut(layer.outputs) {
                row.iter_mut().zip(&layer.bias).for_each(|(v, b)| *v += b);
            }
            if l < last {
                let act: Vec<f64> = pre.iter().map(|v| v.tanh()).collect();
                z.push(pre);
                h.push(act.clone());
                input = act;
            } else {
                input = pre;
            }
        }
        let net = input;
        let mut out = net.clone();
        if let Some(cols) = &self.offset {
            let n_out = self.n_outputs();
            for (r, row) in out.chunks_exact_mut(n_out).enumerate() {
                for (v, &c) in row.iter_mut().zip(cols) {
                    *v += f64::from(x[r * n_in + c]);
                }
            }
        }
        Forward {
            rows,
            z,
            h,
            net,
            out,
        }
    }
}

/// Deep SHAP of a regressor in raw units (see [`DeepModel::from_regressor`] and
/// [`DeepModel::explain`]), with f64 products on all cores.
pub fn deep_shap(
    regressor: &Regressor,
    offset: Option<&[usize]>,
    x: &[f32],
    background: &[f32],
) -> Result<Attributions> {
    DeepModel::from_regressor(regressor, offset)?.explain(x, background, &DeepOptions::default())
}

fn check_standardizer(name: &str, s: &Standardizer, width: usize) -> Result<()> {
    if s.mean.len() != width || s.std.len() != width {
        return Err(ShapError::Shape(format!(
            "{name} standardisation has {}/{} entries for width {width}",
            s.mean.len(),
            s.std.len()
        )));
    }
    if s.mean.iter().any(|m| !m.is_finite()) {
        return Err(ShapError::NonFinite(format!("{name} mean")));
    }
    if let Some(j) = s.std.iter().position(|v| !(v.is_finite() && *v > 0.0)) {
        return Err(ShapError::NonFinite(format!(
            "{name} std[{j}] = {} is not a positive number",
            s.std[j]
        )));
    }
    Ok(())
}

/// Validates offset columns: one input column per output.
pub(crate) fn check_offset(
    offset: Option<&[usize]>,
    n_in: usize,
    n_out: usize,
) -> Result<Option<Vec<usize>>> {
    let Some(cols) = offset else { return Ok(None) };
    if cols.len() != n_out {
        return Err(ShapError::Shape(format!(
            "{} offset columns for {n_out} outputs",
            cols.len()
        )));
    }
    if let Some(&c) = cols.iter().find(|&&c| c >= n_in) {
        return Err(ShapError::Shape(format!(
            "offset column {c} is not one of the {n_in} inputs"
        )));
    }
    Ok(Some(cols.to_vec()))
}
