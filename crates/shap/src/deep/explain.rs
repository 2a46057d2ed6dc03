//! The attribution pass: rescale multipliers of every (observation, reference, output)
//! row, pushed back through the network in blocks of matrix products on the thread pool.

use rayon::prelude::*;

use super::real::{Real, matmul};
use super::{DeepModel, DeepOptions, Forward, Precision};
use crate::{Attributions, Result, check_rows, pool};

/// Below this `|z_x − z_r|` a tanh unit's multiplier is its derivative at the midpoint
/// (shap's threshold); the difference quotient would lose digits to cancellation there,
/// and the midpoint derivative is within `Δz²/24` of it.
const RESCALE_EPS: f64 = 1e-6;

/// Rows (pairs × outputs) per block of matrix products: large enough for the matrix
/// kernels to run near peak, small enough (≈2 MB per f64 buffer at width 256) to stay in
/// cache-friendly memory per thread.
const BLOCK_ROWS: usize = 2048;

impl DeepModel {
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
