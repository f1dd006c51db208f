//! GFLOP/s of the GEMM shapes of a width-32 conv at batch 64.
use dem_nn::gemm::{matmul, Mat};
fn main() {
    let (m, k, n) = (6400, 576, 64);
    let a = vec![0.5f32; m * k];
    let b = vec![0.25f32; k * n];
    let dy = vec![0.1f32; m * n];
    let mut c = vec![0.0f32; m * n];
    let mut dw = vec![0.0f32; k * n];
    let mut dcol = vec![0.0f32; m * k];
    let reps = 20;
    let time = |name: &str, f: &mut dyn FnMut()| {
        f();
        let t = std::time::Instant::now();
        for _ in 0..reps {
            f();
        }
        let s = t.elapsed().as_secs_f64() / reps as f64;
        println!("{name}: {:.2} ms, {:.1} GFLOP/s", s * 1e3, 2.0 * (m * k * n) as f64 / s / 1e9);
    };
    time("forward  col[M,K] W[K,N]", &mut || matmul(&mut c, Mat::new(&a, m, k), Mat::new(&b, k, n), false));
    time("dW       col^T dY       ", &mut || matmul(&mut dw, Mat::new(&a, m, k).t(), Mat::new(&dy, m, n), true));
    time("dcol     dY W^T         ", &mut || matmul(&mut dcol, Mat::new(&dy, m, n), Mat::new(&b, k, n).t(), false));
}
