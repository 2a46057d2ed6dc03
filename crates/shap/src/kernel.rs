//! Kernel SHAP: weighted least squares over feature coalitions with the Shapley kernel,
//! efficiency imposed exactly, the model evaluated on all (coalition × background) rows in
//! large parallel batches.

use std::collections::HashMap;

use causal_arm_mlp::Regressor;
use rand::{Rng, SeedableRng, rngs::StdRng};
use rayon::prelude::*;

use crate::deep::check_offset;
use crate::linalg::solve_symmetric;
use crate::{Attributions, Result, ShapError, check_rows, pool};

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
        if out.len() != n_rows * self.n_outputs {
            return Err(ShapError::Shape(format!(
                "model returned {} values for {n_rows} rows × {} outputs",
                out.len(),
                self.n_outputs
            )));
        }
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

/// Weighted background rows that stand in for "feature unknown" (replaced features take
/// their values from these rows, weighted).
#[derive(Debug, Clone, PartialEq)]
pub struct Background {
    data: Vec<f32>,
    weights: Vec<f64>,
    width: usize,
}

impl Background {
    /// Rows with equal weights (a plain sample of the data).
    pub fn sample(data: &[f32], width: usize) -> Result<Self> {
        let rows = check_rows("background", data, width)?;
        Self::weighted(data, width, vec![1.0; rows])
    }

    /// Rows with the given non-negative weights (normalised to sum 1).
    pub fn weighted(data: &[f32], width: usize, weights: Vec<f64>) -> Result<Self> {
        let rows = check_rows("background", data, width)?;
        if weights.len() != rows {
            return Err(ShapError::Shape(format!(
                "{} weights for {rows} background rows",
                weights.len()
            )));
        }
        if weights.iter().any(|w| !(w.is_finite() && *w >= 0.0)) {
            return Err(ShapError::NonFinite(
                "background weights must be finite and non-negative".into(),
            ));
        }
        let total: f64 = weights.iter().sum();
        if total <= 0.0 {
            return Err(ShapError::Empty("background weights sum to 0".into()));
        }
        Ok(Self {
            data: data.to_vec(),
            weights: weights.iter().map(|w| w / total).collect(),
            width,
        })
    }

    /// Number of rows.
    pub fn rows(&self) -> usize {
        self.weights.len()
    }

    /// Row width (model inputs).
    pub fn width(&self) -> usize {
        self.width
    }

    /// Row-major rows `[rows, width]`.
    pub fn data(&self) -> &[f32] {
        &self.data
    }

    /// Weights, summing to 1.
    pub fn weights(&self) -> &[f64] {
        &self.weights
    }
}

/// Summarises `data` (`[rows, width]`) by `k` weighted k-means centres, as `shap.kmeans`:
/// k-means++ seeding (best of 3 runs of Lloyd's algorithm, seeded), then every centre
/// coordinate is snapped to the nearest value that column takes in the data (so
/// categorical or discrete features stay valid) and weighted by its cluster's size.
/// With `k ≥ rows` the data itself is returned with equal weights. Each iteration costs
/// `rows · k · width` (the assignment runs on rayon's global pool): subsample very large
/// data sets first.
pub fn kmeans(data: &[f32], width: usize, k: usize, seed: u64) -> Result<Background> {
    let n = check_rows("k-means data", data, width)?;
    if k == 0 {
        return Err(ShapError::Option("k-means needs k ≥ 1".into()));
    }
    if k >= n {
        return Background::sample(data, width);
    }
    let mut rng = StdRng::seed_from_u64(seed);
    let row = |i: usize| &data[i * width..(i + 1) * width];
    let dist = |a: &[f32], b: &[f64]| -> f64 {
        a.iter()
            .zip(b)
            .map(|(&x, &c)| (f64::from(x) - c).powi(2))
            .sum()
    };
    let mut best: Option<(f64, Vec<f64>, Vec<usize>)> = None;
    for _ in 0..3 {
        // k-means++ seeding.
        let mut centres: Vec<f64> = Vec::with_capacity(k * width);
        let first = rng.random_range(0..n);
        centres.extend(row(first).iter().map(|&v| f64::from(v)));
        let mut d2: Vec<f64> = (0..n).map(|i| dist(row(i), &centres[..width])).collect();
        for c in 1..k {
            let total: f64 = d2.iter().sum();
            let pick = if total > 0.0 {
                let target = rng.random::<f64>() * total;
                let mut acc = 0.0;
                d2.iter()
                    .position(|&d| {
                        acc += d;
                        acc > target
                    })
                    .unwrap_or(n - 1)
            } else {
                rng.random_range(0..n)
            };
            centres.extend(row(pick).iter().map(|&v| f64::from(v)));
            let centre = &centres[c * width..(c + 1) * width];
            for (i, d) in d2.iter_mut().enumerate() {
                *d = d.min(dist(row(i), centre));
            }
        }
        // Lloyd iterations.
        let mut labels = vec![usize::MAX; n];
        let mut inertia = 0.0;
        for _ in 0..300 {
            let mut changed = false;
            inertia = 0.0;
            // Nearest centre of every row, in parallel (per-row results, so the sums
            // below do not depend on the thread split).
            let nearest: Vec<(usize, f64)> = (0..n)
                .into_par_iter()
                .map(|i| {
                    let (mut bi, mut bd) = (0, f64::INFINITY);
                    for c in 0..k {
                        let d = dist(row(i), &centres[c * width..(c + 1) * width]);
                        if d < bd {
                            (bi, bd) = (c, d);
                        }
                    }
                    (bi, bd)
                })
                .collect();
            for (label, &(bi, bd)) in labels.iter_mut().zip(&nearest) {
                inertia += bd;
                if *label != bi {
                    *label = bi;
                    changed = true;
                }
            }
            if !changed {
                break;
            }
            let mut sum = vec![0f64; k * width];
            let mut count = vec![0usize; k];
            for (i, &l) in labels.iter().enumerate() {
                count[l] += 1;
                for (s, &v) in sum[l * width..(l + 1) * width].iter_mut().zip(row(i)) {
                    *s += f64::from(v);
                }
            }
            for c in 0..k {
                if count[c] == 0 {
                    // An empty cluster takes the point farthest from its centre.
                    let far = (0..n)
                        .max_by(|&a, &b| {
                            let da = dist(row(a), &centres[labels[a] * width..][..width]);
                            let db = dist(row(b), &centres[labels[b] * width..][..width]);
                            da.total_cmp(&db)
                        })
                        .unwrap_or(0);
                    for (dst, &v) in centres[c * width..(c + 1) * width].iter_mut().zip(row(far)) {
                        *dst = f64::from(v);
                    }
                } else {
                    for (dst, s) in centres[c * width..(c + 1) * width]
                        .iter_mut()
                        .zip(&sum[c * width..(c + 1) * width])
                    {
                        *dst = s / count[c] as f64;
                    }
                }
            }
        }
        if best.as_ref().is_none_or(|b| inertia < b.0) {
            best = Some((inertia, centres, labels));
        }
    }
    let (_, centres, labels) = best.expect("three runs were made");
    let mut weights = vec![0f64; k];
    labels.iter().for_each(|&l| weights[l] += 1.0);
    // Snap each coordinate to the nearest value of its column (first such row, as
    // numpy's argmin), and drop clusters that ended empty.
    let mut out = Vec::with_capacity(k * width);
    let mut out_w = Vec::with_capacity(k);
    for c in 0..k {
        if weights[c] == 0.0 {
            continue;
        }
        for j in 0..width {
            let target = centres[c * width + j];
            let mut best = (f64::INFINITY, 0f32);
            for i in 0..n {
                let v = data[i * width + j];
                let d = (f64::from(v) - target).abs();
                if d < best.0 {
                    best = (d, v);
                }
            }
            out.push(best.1);
        }
        out_w.push(weights[c]);
    }
    Background::weighted(&out, width, out_w)
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

/// Coalitions over the `m` varying features and their regression weights.
struct Coalitions {
    m: usize,
    /// Row-major `[count, m]` 0/1.
    masks: Vec<u8>,
    weights: Vec<f64>,
}

impl Coalitions {
    fn count(&self) -> usize {
        self.weights.len()
    }
    fn mask(&self, k: usize) -> &[u8] {
        &self.masks[k * self.m..(k + 1) * self.m]
    }
    fn push(&mut self, mask: &[u8], w: f64) -> usize {
        self.masks.extend_from_slice(mask);
        self.weights.push(w);
        self.weights.len() - 1
    }
}

fn binomial(n: usize, k: usize) -> f64 {
    let k = k.min(n - k);
    (0..k).fold(1.0, |acc, i| acc * (n - i) as f64 / (i + 1) as f64)
}

/// Calls `f` on every size-`s` subset of `0..m` as a 0/1 mask (lexicographic order).
fn for_each_combination(m: usize, s: usize, mut f: impl FnMut(&[u8])) {
    let mut idx: Vec<usize> = (0..s).collect();
    let mut mask = vec![0u8; m];
    loop {
        mask.fill(0);
        idx.iter().for_each(|&i| mask[i] = 1);
        f(&mask);
        // Advance to the next combination.
        let mut i = s;
        loop {
            if i == 0 {
                return;
            }
            i -= 1;
            if idx[i] < m - s + i {
                idx[i] += 1;
                for t in i + 1..s {
                    idx[t] = idx[t - 1] + 1;
                }
                break;
            }
            if i == 0 {
                return;
            }
        }
    }
}

/// All `2^m − 2` proper non-empty coalitions with the exact Shapley kernel weights
/// `(m − 1) / (C(m, s) · s · (m − s))`.
fn exact_coalitions(m: usize) -> Coalitions {
    let mut c = Coalitions {
        m,
        masks: Vec::new(),
        weights: Vec::new(),
    };
    for s in 1..m {
        let w = (m - 1) as f64 / (binomial(m, s) * (s * (m - s)) as f64);
        for_each_combination(m, s, |mask| {
            c.push(mask, w);
        });
    }
    c
}

/// shap's budgeted scheme: enumerate whole coalition sizes (with complements) while the
/// budget covers them at their kernel weight, sample the remaining sizes from the kernel
/// distribution (each draw with its complement), merging repeated draws into weights.
fn sampled_coalitions(m: usize, nsamples: usize, rng: &mut StdRng) -> Coalitions {
    let mut c = Coalitions {
        m,
        masks: Vec::new(),
        weights: Vec::new(),
    };
    let num_sizes = (m - 1).div_ceil(2);
    let num_paired = (m - 1) / 2;
    let mut weight_vector: Vec<f64> = (1..=num_sizes)
        .map(|s| (m - 1) as f64 / (s * (m - s)) as f64)
        .collect();
    weight_vector[..num_paired]
        .iter_mut()
        .for_each(|w| *w *= 2.0);
    let total: f64 = weight_vector.iter().sum();
    weight_vector.iter_mut().for_each(|w| *w /= total);

    let mut num_full = 0;
    let mut left = nsamples as f64;
    let mut remaining = weight_vector.clone();
    for s in 1..=num_sizes {
        let paired = s <= num_paired;
        let nsubsets = binomial(m, s) * if paired { 2.0 } else { 1.0 };
        if left * remaining[s - 1] / nsubsets < 1.0 - 1e-8 {
            break;
        }
        num_full += 1;
        left -= nsubsets;
        if remaining[s - 1] < 1.0 {
            let scale = 1.0 - remaining[s - 1];
            remaining.iter_mut().for_each(|w| *w /= scale);
        }
        let mut w = weight_vector[s - 1] / binomial(m, s);
        if paired {
            w /= 2.0;
        }
        for_each_combination(m, s, |mask| {
            c.push(mask, w);
            if paired {
                let comp: Vec<u8> = mask.iter().map(|&b| 1 - b).collect();
                c.push(&comp, w);
            }
        });
    }
    let nfixed = c.count();
    let mut samples_left = nsamples.saturating_sub(nfixed);
    if num_full < num_sizes && samples_left > 0 {
        let mut dist = weight_vector.clone();
        dist[..num_paired].iter_mut().for_each(|w| *w /= 2.0);
        let dist = &dist[num_full..];
        let total: f64 = dist.iter().sum();
        let mut used: HashMap<Vec<u8>, usize> = HashMap::new();
        let mut perm: Vec<usize> = (0..m).collect();
        let mut mask = vec![0u8; m];
        let mut draws = samples_left.saturating_mul(4);
        while samples_left > 0 && draws > 0 {
            draws -= 1;
            // Subset size from the kernel distribution over the sizes not enumerated.
            let target = rng.random::<f64>() * total;
            let mut acc = 0.0;
            let ind = dist
                .iter()
                .position(|&w| {
                    acc += w;
                    acc > target
                })
                .unwrap_or(dist.len() - 1);
            let s = ind + num_full + 1;
            // A uniformly random subset of that size (partial Fisher–Yates).
            for i in 0..s {
                let j = rng.random_range(i..m);
                perm.swap(i, j);
            }
            mask.fill(0);
            perm[..s].iter().for_each(|&i| mask[i] = 1);
            match used.get(&mask) {
                Some(&k) => c.weights[k] += 1.0,
                None => {
                    used.insert(mask.clone(), c.push(&mask, 1.0));
                    samples_left -= 1;
                }
            }
            if s <= num_paired {
                let comp: Vec<u8> = mask.iter().map(|&b| 1 - b).collect();
                match used.get(&comp) {
                    Some(&k) => c.weights[k] += 1.0,
                    None if samples_left > 0 => {
                        used.insert(comp.clone(), c.push(&comp, 1.0));
                        samples_left -= 1;
                    }
                    None => {}
                }
            }
        }
        // The sampled coalitions share the kernel weight of the sizes not enumerated.
        let weight_left: f64 = weight_vector[num_full..].iter().sum();
        let sampled: f64 = c.weights[nfixed..].iter().sum();
        if sampled > 0.0 {
            c.weights[nfixed..]
                .iter_mut()
                .for_each(|w| *w *= weight_left / sampled);
        }
    }
    c
}

/// Distinct composite rows of all (coalition, background row) pairs: `index[k·n_bg + b]`
/// is the distinct row of coalition `k` on background row `b`, and `unique[u]` a
/// `(b, k)` that builds row `u`. Two coalitions give the same row on `b` when they agree
/// on the features where `x` and `b` differ (exact equality), which discrete features
/// (flags, categories) make common. More than 64 varying features: no merging.
fn composite_rows(
    coalitions: &Coalitions,
    varying: &[usize],
    x: &[f32],
    bg: &[f32],
    n_in: usize,
) -> (Vec<u32>, Vec<(u32, u32)>) {
    let n_bg = bg.len() / n_in;
    let n_coal = coalitions.count();
    let mut index = Vec::with_capacity(n_coal * n_bg);
    let mut unique = Vec::new();
    if varying.len() > 64 {
        for k in 0..n_coal {
            for b in 0..n_bg {
                index.push(unique.len() as u32);
                unique.push((b as u32, k as u32));
            }
        }
        return (index, unique);
    }
    let differs: Vec<u64> = bg
        .chunks_exact(n_in)
        .map(|b| {
            varying
                .iter()
                .enumerate()
                .filter(|&(_, &i)| x[i] != b[i])
                .fold(0u64, |acc, (c, _)| acc | 1 << c)
        })
        .collect();
    let mut seen: Vec<HashMap<u64, u32>> = vec![HashMap::new(); n_bg];
    for k in 0..n_coal {
        let bits = coalitions
            .mask(k)
            .iter()
            .enumerate()
            .fold(0u64, |acc, (c, &on)| acc | u64::from(on) << c);
        for (b, (map, &d)) in seen.iter_mut().zip(&differs).enumerate() {
            let next = unique.len() as u32;
            let u = *map.entry(bits & d).or_insert(next);
            if u == next {
                unique.push((b as u32, k as u32));
            }
            index.push(u);
        }
    }
    (index, unique)
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
    let n_in = model.n_inputs();
    let n_out = model.n_outputs();
    if n_out == 0 {
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
    if options.batch_rows == 0 {
        return Err(ShapError::Option("batch_rows must be at least 1".into()));
    }
    let pool = pool(options.threads)?;
    let n_bg = background.rows();
    let bg = background.data();
    let bw = background.weights();

    let eval = |rows: &[f32], n: usize| -> Result<Vec<f32>> {
        let y = model.predict(rows, n)?;
        if y.len() != n * n_out {
            return Err(ShapError::Shape(format!(
                "model returned {} values for {n} rows × {n_out} outputs",
                y.len()
            )));
        }
        if let Some(k) = y.iter().position(|v| !v.is_finite()) {
            return Err(ShapError::NonFinite(format!(
                "model output {} of row {} is {}",
                k % n_out,
                k / n_out,
                y[k]
            )));
        }
        Ok(y)
    };
    let fx: Vec<f64> = pool
        .install(|| eval(x, n_obs))?
        .into_iter()
        .map(f64::from)
        .collect();
    let fb = pool.install(|| eval(bg, n_bg))?;
    let mut fnull = vec![0f64; n_out];
    for (row, &w) in fb.chunks_exact(n_out).zip(bw) {
        fnull
            .iter_mut()
            .zip(row)
            .for_each(|(e, &v)| *e += w * f64::from(v));
    }

    let mut values = vec![0f64; n_obs * n_in * n_out];
    for o in 0..n_obs {
        let xo = &x[o * n_in..(o + 1) * n_in];
        let block = &mut values[o * n_in * n_out..(o + 1) * n_in * n_out];
        let delta: Vec<f64> = (0..n_out).map(|j| fx[o * n_out + j] - fnull[j]).collect();
        // Features equal to every background value cannot change the output (np.isclose).
        let varying: Vec<usize> = (0..n_in)
            .filter(|&i| {
                bg.chunks_exact(n_in).any(|b| {
                    let (a, r) = (f64::from(xo[i]), f64::from(b[i]));
                    (a - r).abs() > 1e-8 + 1e-5 * r.abs()
                })
            })
            .collect();
        let m = varying.len();
        if m == 0 {
            continue;
        }
        if m == 1 {
            block[varying[0] * n_out..(varying[0] + 1) * n_out].copy_from_slice(&delta);
            continue;
        }
        let max_samples = if m <= 30 {
            (1usize << m) - 2
        } else {
            usize::MAX
        };
        let nsamples = options.nsamples.unwrap_or(2 * m + 2048).min(max_samples);
        let exact = m <= 30 && (m <= options.exact_max_inputs || nsamples >= max_samples);
        let coalitions = if exact {
            exact_coalitions(m)
        } else {
            let stream = options
                .seed
                .wrapping_add((o as u64).wrapping_mul(OBSERVATION_SEED_STRIDE));
            sampled_coalitions(m, nsamples, &mut StdRng::seed_from_u64(stream))
        };

        // v(S) for every coalition: the model on (x on S, background elsewhere), averaged
        // over the weighted background. Rows are built and evaluated once per distinct
        // composite (a coalition's features that equal the background row's values do not
        // change the row), batch by batch on the pool.
        let n_coal = coalitions.count();
        if n_coal.saturating_mul(n_bg) > u32::MAX as usize {
            return Err(ShapError::Option(format!(
                "{n_coal} coalitions × {n_bg} background rows is too many model rows"
            )));
        }
        let (index, unique) = composite_rows(&coalitions, &varying, xo, bg, n_in);
        let y = pool.install(|| -> Result<Vec<f32>> {
            let parts: Vec<Result<Vec<f32>>> = unique
                .par_chunks(options.batch_rows)
                .map(|batch| {
                    let mut rows = Vec::with_capacity(batch.len() * n_in);
                    for &(b, k) in batch {
                        let start = rows.len();
                        rows.extend_from_slice(&bg[b as usize * n_in..(b as usize + 1) * n_in]);
                        let row = &mut rows[start..];
                        for (&on, &i) in coalitions.mask(k as usize).iter().zip(&varying) {
                            if on == 1 {
                                row[i] = xo[i];
                            }
                        }
                    }
                    eval(&rows, batch.len())
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
            for (&u, &w) in index[k * n_bg..(k + 1) * n_bg].iter().zip(bw) {
                let row = &y[u as usize * n_out..(u as usize + 1) * n_out];
                e.iter_mut()
                    .zip(row)
                    .for_each(|(e, &v)| *e += w * f64::from(v));
            }
        }

        // Weighted least squares with Σφ = Δ imposed by eliminating the last feature:
        // v(S) − v(∅) − z_last·Δ = Σ_{c<last} φ_c (z_c − z_last).
        let last = m - 1;
        let mut a = vec![0f64; last * last];
        let mut rhs = vec![0f64; last * n_out];
        let mut e = vec![0f64; last];
        for k in 0..n_coal {
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
        let phi = solve_symmetric(&a, &rhs, last, n_out);
        for j in 0..n_out {
            let mut sum = 0.0;
            for c in 0..last {
                let v = phi[c * n_out + j];
                block[varying[c] * n_out + j] = v;
                sum += v;
            }
            block[varying[last] * n_out + j] = delta[j] - sum;
        }
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
