//! SHAP attributions for the forward model: which inputs (state features, actions) move
//! which outputs, in raw units, as the paper's knowledge-extraction step needs.
//!
//! Two methods, both returning [`Attributions`]:
//!
//! * **Deep SHAP** ([`deep_shap`], [`DeepModel`]): DeepLIFT with the *rescale* rule on the
//!   tanh MLP of a [`causal_arm_mlp::Regressor`], against every row of a background set and
//!   averaged over it — what `shap.DeepExplainer` computes for dense tanh networks. For one
//!   observation `x` and one reference `r`, every tanh unit gets the multiplier
//!   `(tanh z_x − tanh z_r) / (z_x − z_r)` (its derivative at the midpoint when
//!   `|z_x − z_r| < 1e-6`), linear layers pass multipliers through exactly, and the
//!   attribution of input `i` to output `j` is `(x_i − r_i) · m_ij`. Input and output
//!   standardisation are folded into the first and last layer, so attributions are in raw
//!   units, and the optional *offset* columns of a delta model (output `j` gets `+ x[c_j]`)
//!   are attributed exactly (`x_c − E[r_c]` to input `c`). The work is a chain of large
//!   matrix products over all (observation, reference, output) rows, in f64 by default.
//! * **Kernel SHAP** ([`kernel_shap`]): model-agnostic ([`BatchModel`]). The value of a
//!   coalition `S` is `v(S) = Σ_b w_b f(x_S, b_¬S)` over a weighted background (a plain
//!   sample via [`Background::sample`] or a k-means summary via [`kmeans`], as
//!   `shap.kmeans`); the Shapley values are the weighted least-squares fit of `v` over
//!   coalitions with the Shapley kernel weights, with the efficiency constraint imposed
//!   exactly by eliminating one variable (as `shap.KernelExplainer` does, without its L1
//!   feature selection). Few inputs: all `2^M − 2` coalitions are enumerated and the result
//!   is the exact Shapley value. Many inputs: coalition sizes that fit the budget are
//!   enumerated and the rest sampled from the kernel distribution (shap's scheme), seeded.
//!   Inputs equal to every background value are left out (attribution 0), as shap does.
//!
//! **Output layout.** [`Attributions::values`] is a flat row-major
//! `[n_obs, n_inputs, n_outputs]` array (`shap`'s layout for multi-output models since
//! 0.45): `values[(obs · n_inputs + input) · n_outputs + output]`, read with
//! [`Attributions::get`]. [`Attributions::expected`] holds the base value per output and
//! [`Attributions::outputs`] the model output per observation the attributions explain.
//!
//! **Efficiency.** For every observation and output,
//! `Σ_i φ(obs, i, j) = outputs(obs, j) − expected(j)` up to f64 rounding (≈1e-12
//! relative): in Kernel SHAP it is imposed on the regression; in Deep SHAP it is
//! DeepLIFT's summation-to-delta, exact with f64 products ([`Precision::F64`], the
//! default) and restored after f32 products by spreading their rounding residual
//! ([`Precision::F32`], about twice as fast; attributions then differ from f64 ones by
//! f32 rounding, ≈4e-9 of the largest attribution on a 31→3×256→23 model).
//! [`Attributions::efficiency_error`] measures it.

#![warn(missing_docs)]

mod deep;
mod kernel;
mod linalg;

pub use deep::{DeepModel, DeepOptions, Precision, deep_shap};
pub use kernel::{
    Background, BatchModel, FnModel, KernelOptions, OBSERVATION_SEED_STRIDE, RegressorModel,
    kernel_shap, kmeans,
};

/// Why attributions could not be computed; bad input is reported, never a panic.
#[derive(Debug, thiserror::Error)]
pub enum ShapError {
    /// Widths or lengths of the inputs disagree with the model or with each other.
    #[error("shape: {0}")]
    Shape(String),
    /// A set that must not be empty (observations, background) is empty.
    #[error("empty: {0}")]
    Empty(String),
    /// An input, weight or model output is NaN or infinite.
    #[error("not finite: {0}")]
    NonFinite(String),
    /// An option is out of range.
    #[error("option: {0}")]
    Option(String),
    /// The network could not be read or evaluated.
    #[error(transparent)]
    Model(#[from] causal_arm_mlp::MlpError),
    /// A tensor could not be read.
    #[error(transparent)]
    Candle(#[from] candle_core::Error),
    /// The worker threads could not be started.
    #[error("thread pool: {0}")]
    Threads(String),
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, ShapError>;

/// Attributions of many observations, the common output of both methods.
#[derive(Debug, Clone, PartialEq)]
pub struct Attributions {
    /// Number of explained observations.
    pub n_obs: usize,
    /// Number of model inputs (features).
    pub n_inputs: usize,
    /// Number of model outputs.
    pub n_outputs: usize,
    /// Row-major `[n_obs, n_inputs, n_outputs]`: `values[(o·n_inputs + i)·n_outputs + j]`
    /// is the contribution of input `i` to output `j` of observation `o`, in raw output units.
    pub values: Vec<f64>,
    /// Base value per output (`[n_outputs]`): the mean model output over the background
    /// (weighted for Kernel SHAP), the point the attributions start from.
    pub expected: Vec<f64>,
    /// Model output per observation, row-major `[n_obs, n_outputs]`, as evaluated by the
    /// explainer (f64 network for Deep SHAP, the caller's model for Kernel SHAP).
    pub outputs: Vec<f64>,
}

impl Attributions {
    /// Contribution of `input` to `output` for observation `obs` (panics when out of range,
    /// like slice indexing).
    pub fn get(&self, obs: usize, input: usize, output: usize) -> f64 {
        assert!(obs < self.n_obs && input < self.n_inputs && output < self.n_outputs);
        self.values[(obs * self.n_inputs + input) * self.n_outputs + output]
    }

    /// The `[n_inputs, n_outputs]` block of one observation.
    pub fn observation(&self, obs: usize) -> &[f64] {
        let block = self.n_inputs * self.n_outputs;
        &self.values[obs * block..(obs + 1) * block]
    }

    /// Model output `j` of observation `obs` that the attributions explain.
    pub fn output(&self, obs: usize, output: usize) -> f64 {
        self.outputs[obs * self.n_outputs + output]
    }

    /// Mean |φ| over observations, row-major `[n_inputs, n_outputs]`: the heat map of the
    /// paper's knowledge-extraction figure.
    pub fn mean_abs(&self) -> Vec<f64> {
        let block = self.n_inputs * self.n_outputs;
        let mut sum = vec![0f64; block];
        for o in 0..self.n_obs {
            for (s, v) in sum.iter_mut().zip(self.observation(o)) {
                *s += v.abs();
            }
        }
        let n = self.n_obs.max(1) as f64;
        sum.iter_mut().for_each(|s| *s /= n);
        sum
    }

    /// Largest violation of efficiency, `|Σ_i φ − (output − expected)|`, divided by
    /// `max(|output − expected|, floor)`, over all observations and outputs. `floor` keeps
    /// outputs that barely move from dominating (pass e.g. 1e-3 × the output scale).
    pub fn efficiency_error(&self, floor: f64) -> f64 {
        let mut worst = 0f64;
        for o in 0..self.n_obs {
            let block = self.observation(o);
            for j in 0..self.n_outputs {
                let sum: f64 = (0..self.n_inputs)
                    .map(|i| block[i * self.n_outputs + j])
                    .sum();
                let delta = self.output(o, j) - self.expected[j];
                let err = (sum - delta).abs() / delta.abs().max(floor);
                worst = worst.max(err);
            }
        }
        worst
    }
}

/// Checks a row-major matrix: non-empty, a whole number of rows of `width`, all finite.
/// Returns the row count.
pub(crate) fn check_rows(name: &str, data: &[f32], width: usize) -> Result<usize> {
    if width == 0 {
        return Err(ShapError::Shape(format!("{name}: width is 0")));
    }
    if data.is_empty() {
        return Err(ShapError::Empty(format!("{name} has no rows")));
    }
    if !data.len().is_multiple_of(width) {
        return Err(ShapError::Shape(format!(
            "{name}: length {} is not a multiple of the {width} input features",
            data.len()
        )));
    }
    if let Some(k) = data.iter().position(|v| !v.is_finite()) {
        return Err(ShapError::NonFinite(format!(
            "{name}[row {}, column {}] = {}",
            k / width,
            k % width,
            data[k]
        )));
    }
    Ok(data.len() / width)
}

/// A private pool whose threads flush subnormal floats to zero (DESIGN: subnormals slowed
/// PyTorch 10×); private so the setting never leaks into the caller's rayon pool.
pub(crate) fn pool(threads: Option<usize>) -> Result<rayon::ThreadPool> {
    let n = match threads {
        Some(0) => return Err(ShapError::Option("threads must be at least 1".into())),
        Some(n) => n,
        None => std::thread::available_parallelism().map_or(1, |n| n.get()),
    };
    rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .thread_name(|i| format!("shap-{i}"))
        .start_handler(|_| causal_arm_mlp::flush_denormals())
        .build()
        .map_err(|e| ShapError::Threads(e.to_string()))
}
