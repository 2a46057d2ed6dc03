//! Fused CPU kernels of the training step on plain `f32` slices.
//!
//! candle runs every element-wise op as its own pass over freshly allocated memory, its tanh
//! is a scalar libm call, and the optimizer update takes a dozen tensor ops per parameter.
//! Here each element-wise stage of a layer is one pass over buffers that stay in cache, with a
//! rational tanh the compiler vectorises, and the matrix products go straight to the `gemm`
//! crate (what candle uses internally) with strides instead of transposed copies.
//!
//! Element-wise kernels are compiled three times (AVX-512, AVX2+FMA, baseline) and picked at
//! run time, so the binary stays portable. They never reorder a sum across rows in a way
//! that depends on the instruction set, so results are the same on every path up to the
//! rounding of individual operations, which no path changes (no fused multiply-add is
//! introduced by the compiler in Rust).

/// Defines a safe function whose body is compiled for AVX-512 and AVX2 and dispatched on
/// the features the CPU reports, falling back to the baseline build.
macro_rules! multiversion {
    ($(#[$meta:meta])* $vis:vis fn $name:ident($($arg:ident: $ty:ty),* $(,)?) $(-> $ret:ty)? $body:block) => {
        $(#[$meta])*
        $vis fn $name($($arg: $ty),*) $(-> $ret)? {
            #[inline(always)]
            fn generic($($arg: $ty),*) $(-> $ret)? $body

            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx512f,avx512vl,avx2,fma")]
                fn avx512($($arg: $ty),*) $(-> $ret)? {
                    generic($($arg),*)
                }
                #[target_feature(enable = "avx2,fma")]
                fn avx2($($arg: $ty),*) $(-> $ret)? {
                    generic($($arg),*)
                }
                if std::arch::is_x86_feature_detected!("avx512f")
                    && std::arch::is_x86_feature_detected!("avx512vl")
                {
                    // SAFETY: the CPU reports every feature `avx512` is compiled for.
                    return unsafe { avx512($($arg),*) };
                }
                if std::arch::is_x86_feature_detected!("avx2")
                    && std::arch::is_x86_feature_detected!("fma")
                {
                    // SAFETY: the CPU reports every feature `avx2` is compiled for.
                    return unsafe { avx2($($arg),*) };
                }
            }
            generic($($arg),*)
        }
    };
}

/// Beyond this |x| the rational approximation is clamped; tanh there is 1 within 2e-7.
const TANH_CLAMP: f32 = 7.905_311;
const TANH_NUM: [f32; 7] = [
    4.893_524_6e-3,
    6.372_619_3e-4,
    1.485_722_4e-5,
    5.122_297e-8,
    -8.604_672e-11,
    2.000_188e-13,
    -2.760_768_5e-16,
];
const TANH_DEN: [f32; 4] = [4.893_525e-3, 2.268_434_6e-3, 1.185_347e-4, 1.198_258_4e-6];

/// tanh as a branch-free [13/6] rational function (Eigen's float tanh): within 4e-7
/// relative error of the exact value and never above 1 in magnitude, so `1 − tanh²` stays a
/// valid slope. Branch-free so loops over it vectorise.
#[inline(always)]
pub fn tanh_fast(x: f32) -> f32 {
    let x = x.clamp(-TANH_CLAMP, TANH_CLAMP);
    let x2 = x * x;
    let mut p = TANH_NUM[6];
    p = p * x2 + TANH_NUM[5];
    p = p * x2 + TANH_NUM[4];
    p = p * x2 + TANH_NUM[3];
    p = p * x2 + TANH_NUM[2];
    p = p * x2 + TANH_NUM[1];
    p = p * x2 + TANH_NUM[0];
    let mut q = TANH_DEN[3];
    q = q * x2 + TANH_DEN[2];
    q = q * x2 + TANH_DEN[1];
    q = q * x2 + TANH_DEN[0];
    x * p / q
}

multiversion! {
    /// Hidden-layer activation in one pass: each row of `z` becomes `tanh(z + bias)`.
    pub fn bias_tanh(z: &mut [f32], bias: &[f32]) {
        for row in z.chunks_exact_mut(bias.len()) {
            for (v, b) in row.iter_mut().zip(bias) {
                *v = tanh_fast(*v + b);
            }
        }
    }
}

multiversion! {
    /// Weighted squared error `Σ_rows Σ_j w_j (z + b − y)²` of the output layer's
    /// pre-bias values `z` (not divided by the row count).
    pub fn output_loss(z: &[f32], bias: &[f32], y: &[f32], weight: &[f32]) -> f64 {
        let width = bias.len();
        let mut total = 0.0f64;
        for (zr, yr) in z.chunks_exact(width).zip(y.chunks_exact(width)) {
            let mut row = 0.0f32;
            for (((z, b), y), w) in zr.iter().zip(bias).zip(yr).zip(weight) {
                let e = z + b - y;
                row += w * e * e;
            }
            total += row as f64;
        }
        total
    }
}

multiversion! {
    /// Output layer of the backward pass in one pass: with `e = z + b − y`, adds
    /// `Σ w_j e²` to the returned loss, turns `z` into the loss gradient `scale_j · e`
    /// (`scale_j = 2 w_j / batch rows`) and adds it to the bias gradient `db`.
    pub fn output_delta(
        z: &mut [f32],
        bias: &[f32],
        y: &[f32],
        weight: &[f32],
        scale: &[f32],
        db: &mut [f32],
    ) -> f64 {
        let width = bias.len();
        let mut total = 0.0f64;
        for (zr, yr) in z.chunks_exact_mut(width).zip(y.chunks_exact(width)) {
            let mut row = 0.0f32;
            for (((((z, b), y), w), s), d) in zr
                .iter_mut()
                .zip(bias)
                .zip(yr)
                .zip(weight)
                .zip(scale)
                .zip(db.iter_mut())
            {
                let e = *z + b - y;
                row += w * e * e;
                *z = s * e;
                *d += *z;
            }
            total += row as f64;
        }
        total
    }
}

multiversion! {
    /// Back through a tanh layer in one pass: `h` (the layer's output) becomes
    /// `upstream · (1 − h²)`, and each row of it is added to the bias gradient `db`.
    pub fn tanh_delta(upstream: &[f32], h: &mut [f32], db: &mut [f32]) {
        let width = db.len();
        for (ur, hr) in upstream.chunks_exact(width).zip(h.chunks_exact_mut(width)) {
            for ((u, h), d) in ur.iter().zip(hr.iter_mut()).zip(db.iter_mut()) {
                let g = u * (1.0 - *h * *h);
                *h = g;
                *d += g;
            }
        }
    }
}

multiversion! {
    /// `dst += src`, to reduce the per-thread partial gradients.
    pub fn add_assign(dst: &mut [f32], src: &[f32]) {
        for (d, s) in dst.iter_mut().zip(src) {
            *d += s;
        }
    }
}

/// Per-step constants of an Adam / AdamW update (PyTorch and candle-nn semantics).
#[derive(Debug, Clone, Copy)]
pub struct AdamStep {
    /// β₁, the first-moment decay.
    pub beta1: f32,
    /// β₂, the second-moment decay.
    pub beta2: f32,
    /// 1 / (1 − β₁ᵗ).
    pub scale_m: f32,
    /// 1 / (1 − β₂ᵗ).
    pub scale_v: f32,
    /// Step size.
    pub lr: f32,
    /// Decoupled decay factor `1 − lr · weight_decay` (1 for Adam).
    pub decay: f32,
    /// ε added to √v̂.
    pub eps: f32,
}

multiversion! {
    /// One fused Adam / AdamW update over a parameter buffer and its moments, with the
    /// gradient `g = g0 + g1` (two threads' partial sums; pass an empty `g1` for one):
    /// `m ← β₁m + (1−β₁)g`, `v ← β₂v + (1−β₂)g²`, `p ← decay·p − lr·m̂/(√v̂ + ε)`.
    pub fn adam(p: &mut [f32], m: &mut [f32], v: &mut [f32], g0: &[f32], g1: &[f32], s: &AdamStep) {
        #[inline(always)]
        fn update(p: &mut f32, m: &mut f32, v: &mut f32, g: f32, s: &AdamStep) {
            let nm = *m * s.beta1 + g * (1.0 - s.beta1);
            let nv = *v * s.beta2 + g * g * (1.0 - s.beta2);
            *m = nm;
            *v = nv;
            let step = (nm * s.scale_m) / ((nv * s.scale_v).sqrt() + s.eps);
            *p = *p * s.decay - step * s.lr;
        }
        let params = p.iter_mut().zip(m.iter_mut()).zip(v.iter_mut());
        if g1.is_empty() {
            for (((p, m), v), g) in params.zip(g0) {
                update(p, m, v, *g, s);
            }
        } else {
            for ((((p, m), v), g0), g1) in params.zip(g0).zip(g1) {
                update(p, m, v, g0 + g1, s);
            }
        }
    }
}

/// Row-major `dst[m×n] = a[m×k] · b[n×k]ᵀ` (a layer's forward product with weights
/// stored `[out, in]`), read through strides, no transposed copy.
pub fn matmul_nt(dst: &mut [f32], a: &[f32], b: &[f32], m: usize, n: usize, k: usize) {
    assert!(dst.len() >= m * n && a.len() >= m * k && b.len() >= n * k);
    // SAFETY: the assertion above keeps every element the strides reach inside the slices:
    // dst (i, j) at i·n + j, a (i, l) at i·k + l, bᵀ (l, j) at j·k + l.
    unsafe {
        raw_gemm(
            m, n, k, dst, 1, n as isize, a, 1, k as isize, b, k as isize, 1,
        )
    }
}

/// Row-major `dst[m×n] = a[k×m]ᵀ · b[k×n]` (a weight gradient `δᵀ · input`).
pub fn matmul_tn(dst: &mut [f32], a: &[f32], b: &[f32], m: usize, n: usize, k: usize) {
    assert!(dst.len() >= m * n && a.len() >= k * m && b.len() >= k * n);
    // SAFETY: as in `matmul_nt`: aᵀ (i, l) at l·m + i, b (l, j) at l·n + j.
    unsafe {
        raw_gemm(
            m, n, k, dst, 1, n as isize, a, m as isize, 1, b, 1, n as isize,
        )
    }
}

/// Row-major `dst[m×n] = a[m×k] · b[k×n]` (a gradient sent back through a layer).
pub fn matmul_nn(dst: &mut [f32], a: &[f32], b: &[f32], m: usize, n: usize, k: usize) {
    assert!(dst.len() >= m * n && a.len() >= m * k && b.len() >= k * n);
    // SAFETY: as in `matmul_nt`: a (i, l) at i·k + l, b (l, j) at l·n + j.
    unsafe {
        raw_gemm(
            m, n, k, dst, 1, n as isize, a, 1, k as isize, b, 1, n as isize,
        )
    }
}

/// Overwrites `dst` with `lhs · rhs`, single-threaded (the trainer splits work across
/// threads by rows, which beats splitting each small product).
///
/// # Safety
/// Every `(i, j)` with `i < m`, `j < n` must address inside `dst` via the strides, and
/// likewise `(i, l)` in `lhs` and `(l, j)` in `rhs` for `l < k`.
#[allow(clippy::too_many_arguments)]
unsafe fn raw_gemm(
    m: usize,
    n: usize,
    k: usize,
    dst: &mut [f32],
    dst_cs: isize,
    dst_rs: isize,
    lhs: &[f32],
    lhs_cs: isize,
    lhs_rs: isize,
    rhs: &[f32],
    rhs_cs: isize,
    rhs_rs: isize,
) {
    if m == 0 || n == 0 {
        return;
    }
    if k == 0 {
        dst[..m * n].fill(0.0);
        return;
    }
    // SAFETY: the caller guarantees the strided accesses stay inside the three slices, and
    // `dst` is borrowed mutably so it aliases neither input.
    unsafe {
        gemm::gemm(
            m,
            n,
            k,
            dst.as_mut_ptr(),
            dst_cs,
            dst_rs,
            false,
            lhs.as_ptr(),
            lhs_cs,
            lhs_rs,
            rhs.as_ptr(),
            rhs_cs,
            rhs_rs,
            0.0,
            1.0,
            false,
            false,
            false,
            gemm::Parallelism::None,
        )
    }
}

/// Makes the calling thread flush subnormal floats to zero (FTZ and DAZ in MXCSR).
///
/// Adam's second moments and the gradients of saturated tanh units decay into the
/// subnormal range, where every operation takes a slow microcode path (a 10× slowdown was
/// seen in PyTorch on this machine). Called only on worker threads of private pools (the
/// trainer's, and `causal_arm_shap`'s), never on a caller's thread.
pub fn flush_denormals() {
    #[cfg(target_arch = "x86_64")]
    {
        #[allow(deprecated)]
        use core::arch::x86_64::{_mm_getcsr, _mm_setcsr};
        const FTZ_DAZ: u32 = 0x8040;
        // SAFETY: setting FTZ/DAZ only changes how this thread rounds subnormal results and
        // inputs (to zero); it cannot break memory safety. The threads that call this belong
        // to private pools (training, SHAP) that run only numeric code, for which flushing
        // values below 1.2e-38 (f32) or 2.2e-308 (f64) is harmless.
        #[allow(deprecated)]
        unsafe {
            _mm_setcsr(_mm_getcsr() | FTZ_DAZ)
        };
    }
}

#[cfg(test)]
mod tests;
