//! Kernel SHAP: weighted least squares over feature coalitions with the Shapley kernel,
//! efficiency imposed exactly, the model evaluated on all (coalition × background) rows in
//! large parallel batches.

mod background;
mod coalitions;

use causal_arm_mlp::Regressor;
use rand::{Rng, SeedableRng, rngs::StdRng};
use rayon::prelude::*;

use crate::deep::check_offset;
use crate::linalg::solve_symmetric;
use crate::{Attributions, Result, ShapError, check_rows, pool};
pub use background::{Background, kmeans};
use coalitions::{Coalitions, composite_rows, exact_coalitions, sampled_coalitions};

/// A model evaluated on many rows at once; what Kernel SHAP explains. `Sync` because
/// batches are evaluated on several threads at once.
pub trait BatchModel: Sync {
    /// Input width.
    fn n_inputs(&self) -> usize;
    /// Output width.
    fn n_outputs(&self) -> usize;
    /// Outputs `[n_rows, n_outputs]` for row-major inputs `[n_rows, n_inputs]`.
    fn predict(&self, rows: &[f32], n_rows: usize) -> Result<Vec<f32>>;
}

/// Any closure `(rows [n × inputs], n) → outputs [n × outputs]` as a [`BatchModel`], for
/// models that are not a [`Regressor`] (and for tests).
pub struct FnModel<F> {
    n_inputs: usize,
    n_outputs: usize,
    f: F,
}

impl<F: Fn(&[f32], usize) -> Vec<f32> + Sync> FnModel<F> {
    /// Wraps `f`, which maps `n` row-major input rows to `n` row-major output rows.
    pub fn new(n_inputs: usize, n_outputs: usize, f: F) -> Self {
        Self {
            n_inputs,
            n_outputs,
            f,
        }
    }
}

impl<F: Fn(&[f32], usize) -> Vec<f32> + Sync> BatchModel for FnModel<F> {
    fn n_inputs(&self) -> usize {
        self.n_inputs
    }
    fn n_outputs(&self) -> usize {
        self.n_outputs
    }
    fn predict(&self, rows: &[f32], n_rows: usize) -> Result<Vec<f32>> {
        let out = (self.f)(rows, n_rows);
        check_output_len(out.len(), n_rows, self.n_outputs)?;
        Ok(out)
    }
}

/// A regressor in raw units plus a delta model's offset columns (output `j` gets
/// `+ x[offset[j]]`), evaluated with the trainer's fast f32 kernels: the forward model as
/// the services predict it (without angle wrapping).
pub struct RegressorModel<'a> {
    regressor: &'a Regressor,
    offset: Option<Vec<usize>>,
}

impl<'a> RegressorModel<'a> {
    /// Checks the offset columns (one per output, each an input column).
    pub fn new(regressor: &'a Regressor, offset: Option<&[usize]>) -> Result<Self> {
        let spec = regressor.mlp.spec();
        let offset = check_offset(offset, spec.inputs, spec.outputs())?;
        Ok(Self { regressor, offset })
    }
}

impl BatchModel for RegressorModel<'_> {
    fn n_inputs(&self) -> usize {
        self.regressor.mlp.spec().inputs
    }
    fn n_outputs(&self) -> usize {
        self.regressor.mlp.spec().outputs()
    }
    fn predict(&self, rows: &[f32], n_rows: usize) -> Result<Vec<f32>> {
        let (n_in, n_out) = (self.n_inputs(), self.n_outputs());
        if rows.len() != n_rows * n_in {
            return Err(ShapError::Shape(format!(
                "{} values for {n_rows} rows × {n_in} inputs",
                rows.len()
            )));
        }
        let mut y = self.regressor.predict(rows)?;
        if let Some(cols) = &self.offset {
            for (out, input) in y.chunks_exact_mut(n_out).zip(rows.chunks_exact(n_in)) {
                out.iter_mut().zip(cols).for_each(|(v, &c)| *v += input[c]);
            }
        }
        Ok(y)
    }
}

/// Observation `o` samples coalitions from the stream `seed + o · OBSERVATION_SEED_STRIDE`,
/// so a caller explaining rows `start..` in a separate call passes
/// `seed + start · OBSERVATION_SEED_STRIDE` and gets the same values as one call.
pub const OBSERVATION_SEED_STRIDE: u64 = 0x9E37_79B9_7F4A_7C15;

/// Settings of [`kernel_shap`].
#[derive(Debug, Clone)]
pub struct KernelOptions {
    /// Coalitions evaluated per observation; `None` = `2·M + 2048` (shap's "auto"), `M` the
    /// number of inputs that differ from the background. Capped at `2^M − 2`.
    pub nsamples: Option<usize>,
    /// Seed of the coalition sampler (observation `o` uses a stream derived from it).
    pub seed: u64,
    /// Enumerate all `2^M − 2` coalitions (exact Shapley values) when `M` is at most this
    /// (and at most 30), or whenever `2^M − 2 ≤ nsamples`.
    pub exact_max_inputs: usize,
    /// Worker threads (`None`: all cores).
    pub threads: Option<usize>,
    /// Model rows per batch call (coalitions × background rows); rounded to whole
    /// coalitions.
    pub batch_rows: usize,
}

impl Default for KernelOptions {
    fn default() -> Self {
        Self {
            nsamples: None,
            seed: 0,
            exact_max_inputs: 12,
            threads: None,
            batch_rows: 4096,
        }
    }
}

/// Kernel SHAP attributions of the observations `x` (`[n_obs, inputs]`) of `model`
/// against `background`. `expected` is the weighted background mean of the model;
/// efficiency holds exactly (f64) for every observation and output.
pub fn kernel_shap<M: BatchModel + ?Sized>(
    model: &M,
    background: &Background,
    x: &[f32],
    options: &KernelOptions,
) -> Result<Attributions> {
    let n_obs = check_inputs(model, background, x, options)?;
    let explainer = Explainer {
        model,
        pool: pool(options.threads)?,
        options,
        n_in: model.n_inputs(),
        n_out: model.n_outputs(),
        n_bg: background.rows(),
        bg: background.data(),
        bw: background.weights(),
    };
    let (n_in, n_out) = (explainer.n_in, explainer.n_out);
    let fx: Vec<f64> = explainer
        .pool
        .install(|| explainer.predict_checked(x, n_obs))?
        .into_iter()
        .map(f64::from)
        .collect();
    let fnull = explainer.expected_output()?;
    let mut values = vec![0f64; n_obs * n_in * n_out];
    for o in 0..n_obs {
        let observation = Observation {
            index: o,
            x: &x[o * n_in..(o + 1) * n_in],
            delta: (0..n_out).map(|j| fx[o * n_out + j] - fnull[j]).collect(),
        };
        let block = &mut values[o * n_in * n_out..(o + 1) * n_in * n_out];
        explainer.explain(&observation, &fnull, block)?;
    }
    Ok(Attributions {
        n_obs,
        n_inputs: n_in,
        n_outputs: n_out,
        values,
        expected: fnull,
        outputs: fx,
    })
}

/// Rejects inconsistent widths, bad observations and out-of-range options before any
/// model call, so bad input is an error and never a panic deep in the batches. Returns
/// the number of observations.
fn check_inputs<M: BatchModel + ?Sized>(
    model: &M,
    background: &Background,
    x: &[f32],
    options: &KernelOptions,
) -> Result<usize> {
    let n_in = model.n_inputs();
    if model.n_outputs() == 0 {
        return Err(ShapError::Shape("model has no outputs".into()));
    }
    if background.width() != n_in {
        return Err(ShapError::Shape(format!(
            "background rows have {} features, the model {n_in}",
            background.width()
        )));
    }
    let n_obs = check_rows("observations", x, n_in)?;
    if options.nsamples == Some(0) {
        return Err(ShapError::Option("nsamples must be at least 1".into()));
    }
    // Sampled coalitions feed a regression with one unknown per input (less the efficiency
    // constraint): fewer coalitions than inputs leave it underdetermined.
    if let Some(n) = options.nsamples
        && n_in > options.exact_max_inputs
        && n < n_in
        && (n_in > 30 || n < (1usize << n_in) - 2)
    {
        return Err(ShapError::Option(format!(
            "nsamples {n} is fewer than the model's {n_in} inputs: the Kernel SHAP regression needs at least one coalition per input"
        )));
    }
    if options.batch_rows == 0 {
        return Err(ShapError::Option("batch_rows must be at least 1".into()));
    }
    Ok(n_obs)
}

/// The error for a model that returned the wrong number of values, shared by
/// [`FnModel`] and the check on every batch.
fn check_output_len(len: usize, n_rows: usize, n_outputs: usize) -> Result<()> {
    if len != n_rows * n_outputs {
        return Err(ShapError::Shape(format!(
            "model returned {len} values for {n_rows} rows × {n_outputs} outputs"
        )));
    }
    Ok(())
}

/// Index drawn with probability ∝ `weights` (`total` their sum): the first whose
/// running sum passes a uniform draw, the last if rounding lets the draw pass them all.
/// One draw of the RNG, as k-means++ seeding and the coalition-size sampling need.
fn draw_weighted(weights: &[f64], total: f64, rng: &mut StdRng) -> usize {
    let target = rng.random::<f64>() * total;
    let mut acc = 0.0;
    weights
        .iter()
        .position(|&w| {
            acc += w;
            acc > target
        })
        .unwrap_or(weights.len() - 1)
}

/// What explaining every observation shares (model, background, pool, options), so the
/// per-observation steps take one context instead of eight parameters.
struct Explainer<'a, M: ?Sized> {
    model: &'a M,
    pool: rayon::ThreadPool,
    options: &'a KernelOptions,
    n_in: usize,
    n_out: usize,
    /// Background rows.
    n_bg: usize,
    /// Background data, row-major `[n_bg, n_in]`.
    bg: &'a [f32],
    /// Background weights, summing to 1.
    bw: &'a [f64],
}

/// One observation being explained: its position (which seeds its coalition sampler),
/// its inputs and its output minus the base value (what its attributions must sum to).
struct Observation<'a> {
    index: usize,
    x: &'a [f32],
    delta: Vec<f64>,
}

impl<M: BatchModel + ?Sized> Explainer<'_, M> {
    /// The model on `n` rows, with its output length and finiteness checked: a model
    /// error must surface as an error naming the row, not as NaN attributions.
    fn predict_checked(&self, rows: &[f32], n: usize) -> Result<Vec<f32>> {
        let n_out = self.n_out;
        let y = self.model.predict(rows, n)?;
        check_output_len(y.len(), n, n_out)?;
        if let Some(k) = y.iter().position(|v| !v.is_finite()) {
            return Err(ShapError::NonFinite(format!(
                "model output {} of row {} is {}",
                k % n_out,
                k / n_out,
                y[k]
            )));
        }
        Ok(y)
    }

    /// The base value: the model's weighted mean over the background, `v(∅)`.
    fn expected_output(&self) -> Result<Vec<f64>> {
        let fb = self
            .pool
            .install(|| self.predict_checked(self.bg, self.n_bg))?;
        let mut fnull = vec![0f64; self.n_out];
        for (row, &w) in fb.chunks_exact(self.n_out).zip(self.bw) {
            fnull
                .iter_mut()
                .zip(row)
                .for_each(|(e, &v)| *e += w * f64::from(v));
        }
        Ok(fnull)
    }

    /// Fills `block` (`[n_in, n_out]`, zero on entry) with the attributions of one
    /// observation; features that never differ from the background keep 0.
    fn explain(&self, obs: &Observation, fnull: &[f64], block: &mut [f64]) -> Result<()> {
        let n_out = self.n_out;
        let varying = varying_features(obs.x, self.bg, self.n_in);
        let m = varying.len();
        if m == 0 {
            return Ok(());
        }
        if m == 1 {
            block[varying[0] * n_out..(varying[0] + 1) * n_out].copy_from_slice(&obs.delta);
            return Ok(());
        }
        let coalitions = self.coalitions(m, obs.index);
        let ey = self.coalition_values(&coalitions, &varying, obs.x)?;
        let phi = constrained_least_squares(&coalitions, &ey, fnull, &obs.delta);
        let last = m - 1;
        for j in 0..n_out {
            let mut sum = 0.0;
            for c in 0..last {
                let v = phi[c * n_out + j];
                block[varying[c] * n_out + j] = v;
                sum += v;
            }
            block[varying[last] * n_out + j] = obs.delta[j] - sum;
        }
        Ok(())
    }

    /// The coalitions of `m` varying features for observation `o`: all of them (exact
    /// Shapley values) when few enough, else shap's budgeted sample from `o`'s own seed
    /// stream (so explaining rows in separate calls gives the same values).
    fn coalitions(&self, m: usize, o: usize) -> Coalitions {
        let options = self.options;
        let max_samples = if m <= 30 {
            (1usize << m) - 2
        } else {
            usize::MAX
        };
        let nsamples = options.nsamples.unwrap_or(2 * m + 2048).min(max_samples);
        let exact = m <= 30 && (m <= options.exact_max_inputs || nsamples >= max_samples);
        if exact {
            exact_coalitions(m)
        } else {
            let stream = options
                .seed
                .wrapping_add((o as u64).wrapping_mul(OBSERVATION_SEED_STRIDE));
            sampled_coalitions(m, nsamples, &mut StdRng::seed_from_u64(stream))
        }
    }

    /// v(S) for every coalition, row-major `[n_coal, n_out]`: the model on (x on S,
    /// background elsewhere), averaged over the weighted background. Rows are built and
    /// evaluated once per distinct composite (a coalition's features that equal the
    /// background row's values do not change the row), batch by batch on the pool.
    fn coalition_values(
        &self,
        coalitions: &Coalitions,
        varying: &[usize],
        xo: &[f32],
    ) -> Result<Vec<f64>> {
        let (n_in, n_out, n_bg, bg) = (self.n_in, self.n_out, self.n_bg, self.bg);
        let n_coal = coalitions.count();
        if n_coal.saturating_mul(n_bg) > u32::MAX as usize {
            return Err(ShapError::Option(format!(
                "{n_coal} coalitions × {n_bg} background rows is too many model rows"
            )));
        }
        let (index, unique) = composite_rows(coalitions, varying, xo, bg, n_in);
        let y = self.pool.install(|| -> Result<Vec<f32>> {
            let parts: Vec<Result<Vec<f32>>> = unique
                .par_chunks(self.options.batch_rows)
                .map(|batch| {
                    let mut rows = Vec::with_capacity(batch.len() * n_in);
                    for &(b, k) in batch {
                        let start = rows.len();
                        rows.extend_from_slice(&bg[b as usize * n_in..(b as usize + 1) * n_in]);
                        let row = &mut rows[start..];
                        for (&on, &i) in coalitions.mask(k as usize).iter().zip(varying) {
                            if on == 1 {
                                row[i] = xo[i];
                            }
                        }
                    }
                    self.predict_checked(&rows, batch.len())
                })
                .collect();
            let mut y = Vec::with_capacity(unique.len() * n_out);
            for part in parts {
                y.extend(part?);
            }
            Ok(y)
        })?;
        let mut ey = vec![0f64; n_coal * n_out];
        for (k, e) in ey.chunks_exact_mut(n_out).enumerate() {
            for (&u, &w) in index[k * n_bg..(k + 1) * n_bg].iter().zip(self.bw) {
                let row = &y[u as usize * n_out..(u as usize + 1) * n_out];
                e.iter_mut()
                    .zip(row)
                    .for_each(|(e, &v)| *e += w * f64::from(v));
            }
        }
        Ok(ey)
    }
}

/// Indices of the features of `xo` that differ from some background row: features equal
/// to every background value cannot change the output (np.isclose), so shap leaves them
/// out of the regression with attribution 0.
fn varying_features(xo: &[f32], bg: &[f32], n_in: usize) -> Vec<usize> {
    (0..n_in)
        .filter(|&i| {
            bg.chunks_exact(n_in).any(|b| {
                let (a, r) = (f64::from(xo[i]), f64::from(b[i]));
                (a - r).abs() > 1e-8 + 1e-5 * r.abs()
            })
        })
        .collect()
}

/// φ of all varying features but the last, row-major `[m − 1, n_out]`, from the weighted
/// least squares of the coalition values `ey` with Σφ = Δ imposed by eliminating the last
/// feature: v(S) − v(∅) − z_last·Δ = Σ_{c<last} φ_c (z_c − z_last). The last feature's φ
/// is Δ minus their sum.
fn constrained_least_squares(
    coalitions: &Coalitions,
    ey: &[f64],
    fnull: &[f64],
    delta: &[f64],
) -> Vec<f64> {
    let n_out = fnull.len();
    let last = coalitions.features() - 1;
    let mut a = vec![0f64; last * last];
    let mut rhs = vec![0f64; last * n_out];
    let mut e = vec![0f64; last];
    for k in 0..coalitions.count() {
        let mask = coalitions.mask(k);
        let w = coalitions.weights[k];
        let zl = f64::from(mask[last]);
        for c in 0..last {
            e[c] = f64::from(mask[c]) - zl;
        }
        for c in 0..last {
            let wc = w * e[c];
            if wc == 0.0 {
                continue;
            }
            for d in 0..last {
                a[c * last + d] += wc * e[d];
            }
            for j in 0..n_out {
                let y = ey[k * n_out + j] - fnull[j] - zl * delta[j];
                rhs[c * n_out + j] += wc * y;
            }
        }
    }
    solve_symmetric(&a, &rhs, last, n_out)
}
