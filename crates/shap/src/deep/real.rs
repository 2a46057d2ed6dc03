//! Element type of the multiplier products (f64 or f32) and the single-threaded matrix
//! product both the forward pass and the attribution pass run on.

/// Element type of the multiplier products.
pub(super) trait Real: Copy + Send + Sync + 'static + std::ops::Mul<Output = Self> {
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
pub(super) fn matmul<T: Real>(
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
