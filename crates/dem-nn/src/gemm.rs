//! Matrix products for the layers: a bounds-checked wrapper over the `gemm`
//! crate's packed kernels (AVX-512/AVX2/FMA picked at run time).
//!
//! The kernel takes raw pointers and strides; this module is the only place
//! in the workspace allowed `unsafe`, and every call first checks that the
//! largest index each stride pattern reaches lies inside its slice. The one
//! other `unsafe` here, [`with_avx2`], calls a `target_feature` function
//! after checking the CPU has the features.
//!
//! Layer 0 (gemm), the bottom: uses nothing else of the crate.
#![allow(unsafe_code)]

use gemm::Parallelism;

/// A row-major matrix view, optionally read transposed.
#[derive(Clone, Copy, Debug)]
pub struct Mat<'a> {
    data: &'a [f32],
    rows: usize,
    cols: usize,
    /// Distance between consecutive rows / columns of the *logical* matrix.
    rs: isize,
    cs: isize,
}

impl<'a> Mat<'a> {
    /// `data` as a `rows x cols` row-major matrix.
    pub fn new(data: &'a [f32], rows: usize, cols: usize) -> Self {
        assert!(data.len() >= rows * cols, "matrix {rows}x{cols} over {} values", data.len());
        Mat { data, rows, cols, rs: cols as isize, cs: 1 }
    }

    /// `rows x cols` values of `data` with consecutive rows `row_stride >= cols`
    /// apart (a column block of a wider row-major matrix).
    pub fn strided(data: &'a [f32], rows: usize, cols: usize, row_stride: usize) -> Self {
        assert!(row_stride >= cols, "row stride {row_stride} below {cols} columns");
        assert!(
            rows == 0 || data.len() >= (rows - 1) * row_stride + cols,
            "matrix {rows}x{cols} (stride {row_stride}) over {} values",
            data.len()
        );
        Mat { data, rows, cols, rs: row_stride as isize, cs: 1 }
    }

    /// The transpose (a view, nothing moves).
    pub fn t(self) -> Self {
        Mat { data: self.data, rows: self.cols, cols: self.rows, rs: self.cs, cs: self.rs }
    }
}

fn parallelism(work: usize) -> Parallelism {
    // Inside a parallel task (a micro-batch) the threads are already busy;
    // below ~1 MFLOP the fork-join costs more than it saves.
    if work < 1 << 20 || rayon::current_thread_index().is_some() {
        Parallelism::None
    } else {
        Parallelism::Rayon(0)
    }
}

/// `dst (m x n, row-major) = a * b`, or `dst += a * b` with `accumulate`.
pub fn matmul(dst: &mut [f32], a: Mat, b: Mat, accumulate: bool) {
    let (m, k, n) = (a.rows, a.cols, b.cols);
    assert_eq!(b.rows, k, "inner dimensions {k} and {}", b.rows);
    assert!(dst.len() >= m * n, "destination {m}x{n} over {} values", dst.len());
    if m == 0 || n == 0 {
        return;
    }
    if k == 0 {
        if !accumulate {
            dst[..m * n].fill(0.0);
        }
        return;
    }
    // Largest element each view touches: (rows-1)*rs + (cols-1)*cs, all strides >= 0.
    let reach = |x: &Mat| (x.rows - 1) as isize * x.rs + (x.cols - 1) as isize * x.cs;
    assert!(reach(&a) < a.data.len() as isize && reach(&b) < b.data.len() as isize);
    // SAFETY: the views' extents were checked against their slices above,
    // `dst` holds m x n values and is exclusively borrowed, and the inputs
    // are shared borrows that cannot alias it.
    unsafe {
        gemm::gemm(
            m,
            n,
            k,
            dst.as_mut_ptr(),
            1,
            n as isize,
            accumulate,
            a.data.as_ptr(),
            a.cs,
            a.rs,
            b.data.as_ptr(),
            b.cs,
            b.rs,
            1.0,
            1.0,
            false,
            false,
            false,
            parallelism(m * n * k),
        );
    }
}

/// Work to run with wider vector instructions by [`with_avx2`]: implement
/// [`Widened::run`] with `#[inline(always)]`, and mark the functions it calls
/// that should be widened `#[inline(always)]` too.
pub trait Widened {
    /// What the work returns.
    type Output;
    /// Do the work.
    fn run(self) -> Self::Output;
}

/// Run `work` with the compiler allowed AVX2 and FMA instructions in the
/// code inlined into it, when the CPU has them (checked at run time;
/// otherwise it runs as compiled for the baseline target).
///
/// The workspace compiles for baseline x86-64 (SSE2), where the element-wise
/// loops of the inference kernels (Winograd transforms, norms) run 4 lanes
/// wide; the matrix products pick their kernels at run time already.
#[inline]
pub fn with_avx2<W: Widened>(work: W) -> W::Output {
    #[cfg(target_arch = "x86_64")]
    {
        #[target_feature(enable = "avx2,fma")]
        fn avx2<W: Widened>(work: W) -> W::Output {
            work.run()
        }
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
            // SAFETY: the only requirement of a `target_feature` function is
            // that the CPU has the features, checked on the line above.
            return unsafe { avx2(work) };
        }
    }
    work.run()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn naive(a: &[f32], b: &[f32], m: usize, k: usize, n: usize) -> Vec<f32> {
        let mut c = vec![0.0; m * n];
        for i in 0..m {
            for j in 0..n {
                c[i * n + j] = (0..k).map(|l| a[i * k + l] * b[l * n + j]).sum();
            }
        }
        c
    }

    #[test]
    fn products_and_transposes_match_the_naive_loop() {
        let (m, k, n) = (37, 19, 23);
        let a: Vec<f32> = (0..m * k).map(|i| ((i * 7 % 13) as f32 - 6.0) / 5.0).collect();
        let b: Vec<f32> = (0..k * n).map(|i| ((i * 5 % 11) as f32 - 5.0) / 3.0).collect();
        let want = naive(&a, &b, m, k, n);
        let mut c = vec![1.0; m * n];
        matmul(&mut c, Mat::new(&a, m, k), Mat::new(&b, k, n), false);
        c.iter().zip(&want).for_each(|(x, y)| assert!((x - y).abs() < 1e-4));
        // Accumulate: c += a b.
        matmul(&mut c, Mat::new(&a, m, k), Mat::new(&b, k, n), true);
        c.iter().zip(&want).for_each(|(x, y)| assert!((x - 2.0 * y).abs() < 1e-4));
        // (b^T a^T)^T = a b: read both operands transposed.
        let at: Vec<f32> = (0..k * m).map(|i| a[(i % m) * k + i / m]).collect();
        let bt: Vec<f32> = (0..n * k).map(|i| b[(i % k) * n + i / k]).collect();
        let mut c2 = vec![0.0; m * n];
        matmul(&mut c2, Mat::new(&at, k, m).t(), Mat::new(&bt, n, k).t(), false);
        c2.iter().zip(&want).for_each(|(x, y)| assert!((x - y).abs() < 1e-4));
    }
}
