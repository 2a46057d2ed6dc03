//! The forward and backward pass of one lane (a thread's share of a batch) over the flat
//! parameter buffer, into preallocated activations and partial gradients.

use std::ops::Range;

use crate::Mlp;
use crate::kernels;

/// Where each layer's parameters sit in the flat buffer.
#[derive(Debug, Clone)]
pub(super) struct Layout {
    /// Inputs, hidden widths, outputs.
    pub(super) widths: Vec<usize>,
    /// Start of each layer's weights `[out, in]`; its bias `[out]` follows them.
    pub(super) starts: Vec<usize>,
    /// Total parameter count.
    pub(super) len: usize,
}

impl Layout {
    pub(super) fn new(mlp: &Mlp) -> Self {
        let spec = mlp.spec();
        let mut widths = vec![spec.inputs];
        widths.extend(&spec.hidden);
        widths.push(spec.outputs());
        let mut starts = Vec::with_capacity(widths.len() - 1);
        let mut len = 0;
        for w in widths.windows(2) {
            starts.push(len);
            len += w[1] * w[0] + w[1];
        }
        Self {
            widths,
            starts,
            len,
        }
    }

    pub(super) fn layers(&self) -> usize {
        self.widths.len() - 1
    }

    pub(super) fn inputs(&self) -> usize {
        self.widths[0]
    }

    pub(super) fn outputs(&self) -> usize {
        self.widths[self.widths.len() - 1]
    }

    /// Widest hidden layer (size of the back-propagation scratch row).
    pub(super) fn widest_hidden(&self) -> usize {
        let hidden = &self.widths[1..self.widths.len() - 1];
        hidden.iter().copied().max().unwrap_or(0)
    }

    pub(super) fn weight(&self, layer: usize) -> Range<usize> {
        let start = self.starts[layer];
        start..start + self.widths[layer + 1] * self.widths[layer]
    }

    pub(super) fn bias(&self, layer: usize) -> Range<usize> {
        let end = self.weight(layer).end;
        end..end + self.widths[layer + 1]
    }
}

/// One thread's share of a batch: activations, back-propagation scratch and its partial
/// gradients, allocated once and reused every step.
pub(super) struct Lane {
    /// Output of each layer, `rows × width` (the last one is the output layer before bias,
    /// then its loss gradient).
    pub(super) acts: Vec<Vec<f32>>,
    /// Gradient with respect to a hidden layer's output, before the tanh slope.
    pub(super) scratch: Vec<f32>,
    /// Partial gradients in the parameter layout.
    pub(super) grads: Vec<f32>,
    /// Rows the buffers hold.
    pub(super) rows: usize,
    /// Unnormalised weighted squared error of the lane's rows.
    pub(super) loss: f64,
}

impl Lane {
    pub(super) fn new(layout: &Layout) -> Self {
        Self {
            acts: vec![Vec::new(); layout.layers()],
            scratch: Vec::new(),
            grads: vec![0.0; layout.len],
            rows: 0,
            loss: 0.0,
        }
    }

    /// Grows the buffers to hold `rows` rows (only on the first batches of a run).
    pub(super) fn reserve(&mut self, layout: &Layout, rows: usize) {
        if rows <= self.rows {
            return;
        }
        for (act, width) in self.acts.iter_mut().zip(&layout.widths[1..]) {
            act.resize(rows * width, 0.0);
        }
        self.scratch.resize(rows * layout.widest_hidden(), 0.0);
        self.rows = rows;
    }
}

/// Forward pass of `rows` rows of `x` into `acts`: tanh layers, then the output layer's
/// product without its bias (the loss kernels add it).
pub(super) fn forward(
    layout: &Layout,
    params: &[f32],
    acts: &mut [Vec<f32>],
    x: &[f32],
    rows: usize,
) {
    let last = layout.layers() - 1;
    for l in 0..layout.layers() {
        let (n_in, n_out) = (layout.widths[l], layout.widths[l + 1]);
        let (done, rest) = acts.split_at_mut(l);
        let input = if l == 0 {
            &x[..rows * n_in]
        } else {
            &done[l - 1][..rows * n_in]
        };
        let out = &mut rest[0][..rows * n_out];
        kernels::matmul_nt(out, input, &params[layout.weight(l)], rows, n_out, n_in);
        if l < last {
            kernels::bias_tanh(out, &params[layout.bias(l)]);
        }
    }
}

/// Per-column loss weights and the matching gradient factors of one batch.
pub(super) struct LossWeights<'a> {
    /// `w_j` = 1 / size of column j's head.
    pub(super) weight: &'a [f32],
    /// `2 w_j / batch rows`.
    pub(super) scale: &'a [f32],
}

/// Forward and backward pass of one lane's rows: leaves the partial gradients in
/// `lane.grads` and the rows' unnormalised loss in `lane.loss`.
pub(super) fn forward_backward(
    layout: &Layout,
    params: &[f32],
    loss: &LossWeights,
    lane: &mut Lane,
    x: &[f32],
    y: &[f32],
    rows: usize,
) {
    forward(layout, params, &mut lane.acts, x, rows);
    let last = layout.layers() - 1;
    for l in 0..layout.layers() {
        lane.grads[layout.bias(l)].fill(0.0);
    }
    let n_out = layout.outputs();
    lane.loss = kernels::output_delta(
        &mut lane.acts[last][..rows * n_out],
        &params[layout.bias(last)],
        &y[..rows * n_out],
        loss.weight,
        loss.scale,
        &mut lane.grads[layout.bias(last)],
    );
    for l in (0..layout.layers()).rev() {
        let (n_in, n_out) = (layout.widths[l], layout.widths[l + 1]);
        let (below, here) = lane.acts.split_at_mut(l);
        let delta = &here[0][..rows * n_out];
        let input = if l == 0 {
            &x[..rows * n_in]
        } else {
            &below[l - 1][..rows * n_in]
        };
        kernels::matmul_tn(
            &mut lane.grads[layout.weight(l)],
            delta,
            input,
            n_out,
            n_in,
            rows,
        );
        if l > 0 {
            let upstream = &mut lane.scratch[..rows * n_in];
            kernels::matmul_nn(
                upstream,
                delta,
                &params[layout.weight(l)],
                rows,
                n_in,
                n_out,
            );
            kernels::tanh_delta(
                upstream,
                &mut below[l - 1][..rows * n_in],
                &mut lane.grads[layout.bias(l - 1)],
            );
        }
    }
}

/// Row range of lane `lane` out of `lanes` for `rows` rows.
pub(super) fn lane_rows(rows: usize, lanes: usize, lane: usize) -> Range<usize> {
    lane * rows / lanes..(lane + 1) * rows / lanes
}
