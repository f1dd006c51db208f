//! Records/s of the native generator path (dem-nn's inference kernels) on
//! the calling thread, for several block sizes: what `DEFAULT_BLOCK` was
//! chosen with.
//!
//! ```sh
//! RAYON_NUM_THREADS=1 cargo run --release -p dem-onnx --example native_speed -- 8 16 32
//! ```
use dem_core::Dem;
use dem_nn::net::{GeneratorInference, InferScratch};
use dem_nn::weights::{Arch, GeneratorWeights};
use rand::SeedableRng;
use std::time::Instant;

fn main() {
    let w = GeneratorWeights::init_arch(&mut rand_chacha::ChaCha8Rng::seed_from_u64(1), 32, Arch::Residual);
    let recs: Vec<Dem> = (0..2048).map(|i| std::array::from_fn(|k| ((i * 7 + k * 13) % 17) as f32 / 17.0 - 0.5)).collect();
    let blocks: Vec<usize> = std::env::args().skip(1).map(|a| a.parse().expect("block sizes")).collect();
    for b in if blocks.is_empty() { vec![dem_nn::net::infer::DEFAULT_BLOCK] } else { blocks } {
        let g = GeneratorInference::with_block(&w, b);
        let (mut s, mut out) = (InferScratch::default(), Vec::new());
        g.run(&recs[..256], &mut s, &mut out);
        out.clear();
        let t = Instant::now();
        g.run(&recs, &mut s, &mut out);
        println!("block {b}: {:.0} records/s", recs.len() as f64 / t.elapsed().as_secs_f64());
    }
}
