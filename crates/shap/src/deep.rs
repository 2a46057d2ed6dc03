//! Deep SHAP: DeepLIFT's rescale rule through the folded tanh network, averaged over a
//! background set, as large matrix products over (observation, reference, output) rows.

use causal_arm_mlp::{Mlp, Regressor, Standardizer};
use rayon::prelude::*;

use crate::{Attributions, Result, ShapError, check_rows, pool};

/// Below this `|z_x − z_r|` a tanh unit's multiplier is its derivative at the midpoint
/// (shap's threshold); the difference quotient would lose digits to cancellation there,
/// and the midpoint derivative is within `Δz²/24` of it.
const RESCALE_EPS: f64 = 1e-6;

/// Rows (pairs × outputs) per block of matrix products: large enough for the matrix
/// kernels to run near peak, small enough (≈2 MB per f64 buffer at width 256) to stay in
/// cache-friendly memory per thread.
const BLOCK_ROWS: usize = 2048;

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

    /// Deep SHAP attributions of the observations `x` (`[n_obs, inputs]`, raw units)
    /// against every row of `background` (`[n_ref, inputs]`), averaged over the background.
    /// `expected` is the plain mean of the model over the background.
    pub fn explain(
        &self,
        x: &[f32],
        background: &[f32],
        options: &DeepOptions,
    ) -> Result<Attributions> {
        let n_in = self.n_inputs();
        let n_out = self.n_outputs();
        let n_obs = check_rows("observations", x, n_in)?;
        let n_ref = check_rows("background", background, n_in)?;
        let fx = self.forward(x);
        let fr = self.forward(background);
        let mut expected = vec![0f64; n_out];
        for row in fr.out.chunks_exact(n_out) {
            expected.iter_mut().zip(row).for_each(|(e, v)| *e += v);
        }
        expected.iter_mut().for_each(|e| *e /= n_ref as f64);
        let mut values = vec![0f64; n_obs * n_in * n_out];
        let pool = pool(options.threads)?;
        pool.install(|| match options.precision {
            Precision::F64 => self.explain_all::<f64>(x, background, &fx, &fr, &mut values),
            Precision::F32 => self.explain_all::<f32>(x, background, &fx, &fr, &mut values),
        });
        // The offset input enters output j linearly with slope 1: its rescale multiplier is
        // exactly 1, so it contributes x_c − r_c, averaged over the background.
        if let Some(cols) = &self.offset {
            for (j, &c) in cols.iter().enumerate() {
                let mean_r = (0..n_ref)
                    .map(|r| f64::from(background[r * n_in + c]))
                    .sum::<f64>()
                    / n_ref as f64;
                for o in 0..n_obs {
                    values[(o * n_in + c) * n_out + j] += f64::from(x[o * n_in + c]) - mean_r;
                }
            }
        }
        Ok(Attributions {
            n_obs,
            n_inputs: n_in,
            n_outputs: n_out,
            values,
            expected,
            outputs: fx.out,
        })
    }

    /// Fills `values` (one `[inputs, outputs]` block per observation), in parallel over
    /// observations on the current pool.
    fn explain_all<T: Real>(
        &self,
        x: &[f32],
        background: &[f32],
        fx: &Forward,
        fr: &Forward,
        values: &mut [f64],
    ) {
        let n_in = self.n_inputs();
        let n_out = self.n_outputs();
        let weights: Vec<Vec<T>> = self
            .layers
            .iter()
            .map(|l| l.weight.iter().map(|&w| T::of(w)).collect())
            .collect();
        values
            .par_chunks_mut(n_in * n_out)
            .enumerate()
            .for_each_init(Workspace::<T>::default, |ws, (o, block)| {
                self.explain_one(o, x, background, fx, fr, &weights, ws, block);
            });
    }

    /// Attributions of observation `o` into `block` (`[inputs, outputs]`).
    #[allow(clippy::too_many_arguments)]
    fn explain_one<T: Real>(
        &self,
        o: usize,
        x: &[f32],
        background: &[f32],
        fx: &Forward,
        fr: &Forward,
        weights: &[Vec<T>],
        ws: &mut Workspace<T>,
        block: &mut [f64],
    ) {
        let n_in = self.n_inputs();
        let n_out = self.n_outputs();
        let n_ref = fr.rows;
        let hidden = self.layers.len() - 1;
        let xo = &x[o * n_in..(o + 1) * n_in];
        block.fill(0.0);
        let delta = |r: usize, i: usize| f64::from(xo[i]) - f64::from(background[r * n_in + i]);
        if hidden == 0 {
            // A linear model: the multiplier is the weight itself.
            let w = &self.layers[0].weight;
            for r in 0..n_ref {
                for i in 0..n_in {
                    let d = delta(r, i);
                    for j in 0..n_out {
                        block[i * n_out + j] += d * w[j * n_in + i];
                    }
                }
            }
        } else {
            let refs_per_block = (BLOCK_ROWS / n_out).max(1);
            let mut r0 = 0;
            while r0 < n_ref {
                let r1 = (r0 + refs_per_block).min(n_ref);
                self.block_multipliers(o, r0, r1, fx, fr, weights, ws);
                // ws.x is now [(pair, output), inputs]: the multiplier of each input.
                let z = &ws.x;
                let t = &mut ws.t;
                for (p, r) in (r0..r1).enumerate() {
                    for j in 0..n_out {
                        let m = &z[(p * n_out + j) * n_in..(p * n_out + j + 1) * n_in];
                        t.clear();
                        t.extend(m.iter().enumerate().map(|(i, &m)| delta(r, i) * m.f64()));
                        if T::REDISTRIBUTE {
                            // f32 products leave a rounding residual in Σ_i t_i = Δf; spread
                            // it over the inputs in proportion to |t_i| (each moves by at
                            // most the residual, itself ≈1e-6 of Σ|t_i|).
                            let target = fx.net[o * n_out + j] - fr.net[r * n_out + j];
                            let sum: f64 = t.iter().sum();
                            let abs: f64 = t.iter().map(|v| v.abs()).sum();
                            if abs > 0.0 {
                                let k = (target - sum) / abs;
                                t.iter_mut().for_each(|v| *v += k * v.abs());
                            }
                        }
                        for (i, v) in t.iter().enumerate() {
                            block[i * n_out + j] += v;
                        }
                    }
                }
                r0 = r1;
            }
        }
        block.iter_mut().for_each(|v| *v /= n_ref as f64);
    }

    /// Multipliers of every input for every (reference in `r0..r1`, output) row of
    /// observation `o`, left in `ws.x` as `[(r − r0)·outputs + j, inputs]`: the output
    /// layer's weights scaled by the last tanh layer's rescale multipliers, then back
    /// through each hidden layer (matrix product, then the next rescale multipliers).
    #[allow(clippy::too_many_arguments)]
    fn block_multipliers<T: Real>(
        &self,
        o: usize,
        r0: usize,
        r1: usize,
        fx: &Forward,
        fr: &Forward,
        weights: &[Vec<T>],
        ws: &mut Workspace<T>,
    ) {
        let n_out = self.n_outputs();
        let hidden = self.layers.len() - 1;
        let pairs = r1 - r0;
        let rows = pairs * n_out;
        // Rescale multipliers of each hidden layer for each pair.
        ws.c.resize(hidden, Vec::new());
        for l in 0..hidden {
            let w = self.layers[l].outputs;
            let c = &mut ws.c[l];
            c.clear();
            let (zx, hx) = (&fx.z[l][o * w..(o + 1) * w], &fx.h[l][o * w..(o + 1) * w]);
            for r in r0..r1 {
                let (zr, hr) = (&fr.z[l][r * w..(r + 1) * w], &fr.h[l][r * w..(r + 1) * w]);
                c.extend((0..w).map(|u| T::of(rescale(zx[u], zr[u], hx[u], hr[u]))));
            }
        }
        // Output layer: row (p, j) is W_out[j, :] ⊙ c_last[p, :].
        let out_layer = &self.layers[hidden];
        let width = out_layer.inputs;
        ws.x.clear();
        ws.x.resize(rows * width, T::ZERO);
        for p in 0..pairs {
            let c = &ws.c[hidden - 1][p * width..(p + 1) * width];
            for j in 0..n_out {
                let wrow = &weights[hidden][j * width..(j + 1) * width];
                let dst = &mut ws.x[(p * n_out + j) * width..(p * n_out + j + 1) * width];
                for ((d, &w), &cu) in dst.iter_mut().zip(wrow).zip(c) {
                    *d = w * cu;
                }
            }
        }
        // Back through hidden layers l = hidden−1 … 0: multiply by W_l, then (except for
        // the first layer, whose inputs are the raw inputs) by the rescale multipliers of
        // the layer below.
        for l in (0..hidden).rev() {
            let layer = &self.layers[l];
            ws.y.clear();
            ws.y.resize(rows * layer.inputs, T::ZERO);
            matmul(
                &mut ws.y,
                &ws.x,
                &weights[l],
                rows,
                layer.inputs,
                layer.outputs,
                false,
            );
            if l > 0 {
                let w = layer.inputs;
                for p in 0..pairs {
                    let c = &ws.c[l - 1][p * w..(p + 1) * w];
                    for j in 0..n_out {
                        let row = &mut ws.y[(p * n_out + j) * w..(p * n_out + j + 1) * w];
                        row.iter_mut().zip(c).for_each(|(v, &cu)| *v = *v * cu);
                    }
                }
            }
            std::mem::swap(&mut ws.x, &mut ws.y);
        }
    }
}

/// DeepLIFT rescale multiplier of one tanh unit between an observation and a reference.
fn rescale(zx: f64, zr: f64, hx: f64, hr: f64) -> f64 {
    let dz = zx - zr;
    if dz.abs() < RESCALE_EPS {
        let t = (0.5 * (zx + zr)).tanh();
        1.0 - t * t
    } else {
        (hx - hr) / dz
    }
}

/// Per-thread buffers reused across observations.
struct Workspace<T> {
    /// Rescale multipliers per hidden layer, `[pairs, width]`.
    c: Vec<Vec<T>>,
    /// Current multiplier matrix.
    x: Vec<T>,
    /// Next multiplier matrix.
    y: Vec<T>,
    /// Attributions of one (pair, output) row.
    t: Vec<f64>,
}

impl<T> Default for Workspace<T> {
    fn default() -> Self {
        Self {
            c: Vec::new(),
            x: Vec::new(),
            y: Vec::new(),
            t: Vec::new(),
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

/// Element type of the multiplier products.
pub(crate) trait Real: Copy + Send + Sync + 'static + std::ops::Mul<Output = Self> {
    const ZERO: Self;
    const ONE: Self;
    /// Whether the summation-to-delta residual of the products is large enough (f32) to
    /// be redistributed.
    const REDISTRIBUTE: bool;
    fn of(v: f64) -> Self;
    fn f64(self) -> f64;
}

impl Real for f64 {
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    const REDISTRIBUTE: bool = false;
    fn of(v: f64) -> Self {
        v
    }
    fn f64(self) -> f64 {
        self
    }
}

impl Real for f32 {
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    const REDISTRIBUTE: bool = true;
    fn of(v: f64) -> Self {
        v as f32
    }
    fn f64(self) -> f64 {
        f64::from(self)
    }
}

/// Row-major `dst[m×n] = a[m×k] · B`, where `B` is `b` as `[k×n]`, or `bᵀ` of a `[n×k]`
/// `b` when `b_transposed`; single-threaded (callers parallelise over blocks).
fn matmul<T: Real>(
    dst: &mut [T],
    a: &[T],
    b: &[T],
    m: usize,
    n: usize,
    k: usize,
    b_transposed: bool,
) {
    assert!(dst.len() >= m * n && a.len() >= m * k && b.len() >= k * n);
    if m == 0 || n == 0 {
        return;
    }
    if k == 0 {
        dst[..m * n].fill(T::ZERO);
        return;
    }
    let (rhs_cs, rhs_rs) = if b_transposed {
        (k as isize, 1)
    } else {
        (1, n as isize)
    };
    // SAFETY: the assertion above keeps every strided access inside its slice: dst (i, j)
    // at i·n + j, a (i, l) at i·k + l, B (l, j) at l·n + j or (transposed) j·k + l, all
    // below m·n, m·k and k·n. `dst` is borrowed mutably, so it aliases neither input, and
    // gemm dispatches on T's type (f32 or f64 here) with `read_dst = false`.
    unsafe {
        gemm::gemm(
            m,
            n,
            k,
            dst.as_mut_ptr(),
            1,
            n as isize,
            false,
            a.as_ptr(),
            1,
            k as isize,
            b.as_ptr(),
            rhs_cs,
            rhs_rs,
            T::ZERO,
            T::ONE,
            false,
            false,
            false,
            gemm::Parallelism::None,
        )
    }
}
