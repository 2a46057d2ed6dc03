//! Which coalitions Kernel SHAP evaluates, with their regression weights, and the distinct
//! model rows they need.

use std::collections::HashMap;

use rand::{Rng, rngs::StdRng};

use super::draw_weighted;

/// Coalitions over the `m` varying features and their regression weights.
pub(super) struct Coalitions {
    m: usize,
    /// Row-major `[count, m]` 0/1.
    masks: Vec<u8>,
    pub(super) weights: Vec<f64>,
}

impl Coalitions {
    /// No coalitions yet; both the exact and the sampled scheme start from here.
    fn new(m: usize) -> Self {
        Self {
            m,
            masks: Vec::new(),
            weights: Vec::new(),
        }
    }
    /// Number of varying features the masks range over.
    pub(super) fn features(&self) -> usize {
        self.m
    }
    pub(super) fn count(&self) -> usize {
        self.weights.len()
    }
    pub(super) fn mask(&self, k: usize) -> &[u8] {
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

/// The complementary coalition (features swapped in and out), which the paired sampling
/// scheme adds next to every coalition of a paired size.
fn complement(mask: &[u8]) -> Vec<u8> {
    mask.iter().map(|&b| 1 - b).collect()
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
pub(super) fn exact_coalitions(m: usize) -> Coalitions {
    let mut c = Coalitions::new(m);
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
pub(super) fn sampled_coalitions(m: usize, nsamples: usize, rng: &mut StdRng) -> Coalitions {
    let mut c = Coalitions::new(m);
    let sizes = SizeWeights::new(m);
    let num_full = sizes.enumerate_full_sizes(&mut c, nsamples);
    let samples_left = nsamples.saturating_sub(c.count());
    if num_full < sizes.num_sizes && samples_left > 0 {
        sizes.sample_remaining_sizes(&mut c, num_full, samples_left, rng);
    }
    c
}

/// The Shapley kernel's weight per coalition size, a size and its complement folded into
/// one entry: the budgeted scheme decides from it which sizes to enumerate and samples
/// the others from it.
struct SizeWeights {
    m: usize,
    /// Folded sizes `1..=num_sizes` (size `s` stands for `s` and `m − s`).
    num_sizes: usize,
    /// Sizes `1..=num_paired` have a distinct complement (`s ≠ m − s`).
    num_paired: usize,
    /// Kernel weight of each folded size, normalised to sum 1.
    weight_vector: Vec<f64>,
}

impl SizeWeights {
    /// Folded kernel weights `(m − 1) / (s · (m − s))`, doubled for paired sizes.
    fn new(m: usize) -> Self {
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
        Self {
            m,
            num_sizes,
            num_paired,
            weight_vector,
        }
    }

    /// Adds every coalition of the smallest sizes (and their complements) while the
    /// budget `nsamples` covers a whole size at its kernel weight, each at its exact
    /// kernel weight; returns how many sizes were enumerated.
    fn enumerate_full_sizes(&self, c: &mut Coalitions, nsamples: usize) -> usize {
        let m = self.m;
        let mut num_full = 0;
        let mut left = nsamples as f64;
        let mut remaining = self.weight_vector.clone();
        for s in 1..=self.num_sizes {
            let paired = s <= self.num_paired;
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
            let mut w = self.weight_vector[s - 1] / binomial(m, s);
            if paired {
                w /= 2.0;
            }
            for_each_combination(m, s, |mask| {
                c.push(mask, w);
                if paired {
                    c.push(&complement(mask), w);
                }
            });
        }
        num_full
    }

    /// Draws up to `samples_left` distinct coalitions of the sizes after the first
    /// `num_full` (paired sizes with their complements, at most `4 · samples_left`
    /// draws), counting repeats as weight, then scales the drawn weights to the kernel
    /// weight those sizes carry.
    fn sample_remaining_sizes(
        &self,
        c: &mut Coalitions,
        num_full: usize,
        mut samples_left: usize,
        rng: &mut StdRng,
    ) {
        let m = self.m;
        let nfixed = c.count();
        let mut dist = self.weight_vector.clone();
        dist[..self.num_paired].iter_mut().for_each(|w| *w /= 2.0);
        let dist = &dist[num_full..];
        let total: f64 = dist.iter().sum();
        let mut used: HashMap<Vec<u8>, usize> = HashMap::new();
        let mut perm: Vec<usize> = (0..m).collect();
        let mut mask = vec![0u8; m];
        let mut draws = samples_left.saturating_mul(4);
        while samples_left > 0 && draws > 0 {
            draws -= 1;
            // Subset size from the kernel distribution over the sizes not enumerated.
            let s = draw_weighted(dist, total, rng) + num_full + 1;
            // A uniformly random subset of that size (partial Fisher–Yates).
            for i in 0..s {
                let j = rng.random_range(i..m);
                perm.swap(i, j);
            }
            mask.fill(0);
            perm[..s].iter().for_each(|&i| mask[i] = 1);
            add_draw(c, &mut used, &mask, &mut samples_left);
            if s <= self.num_paired {
                add_draw(c, &mut used, &complement(&mask), &mut samples_left);
            }
        }
        // The sampled coalitions share the kernel weight of the sizes not enumerated.
        let weight_left: f64 = self.weight_vector[num_full..].iter().sum();
        let sampled: f64 = c.weights[nfixed..].iter().sum();
        if sampled > 0.0 {
            c.weights[nfixed..]
                .iter_mut()
                .for_each(|w| *w *= weight_left / sampled);
        }
    }
}

/// Counts one drawn coalition: a repeat adds 1 to its weight (shap merges repeated draws
/// instead of evaluating them twice), a new one is added with weight 1 while the budget
/// lasts.
fn add_draw(
    c: &mut Coalitions,
    used: &mut HashMap<Vec<u8>, usize>,
    mask: &[u8],
    samples_left: &mut usize,
) {
    match used.get(mask) {
        Some(&k) => c.weights[k] += 1.0,
        None if *samples_left > 0 => {
            used.insert(mask.to_vec(), c.push(mask, 1.0));
            *samples_left -= 1;
        }
        None => {}
    }
}

/// Distinct composite rows of all (coalition, background row) pairs: `index[k·n_bg + b]`
/// is the distinct row of coalition `k` on background row `b`, and `unique[u]` a
/// `(b, k)` that builds row `u`. Two coalitions give the same row on `b` when they agree
/// on the features where `x` and `b` differ (exact equality), which discrete features
/// (flags, categories) make common. More than 64 varying features: no merging.
pub(super) fn composite_rows(
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
