//! Records/s of the native generator at several block sizes, one thread.
use dem_nn::net::{GeneratorInference, InferScratch};
use dem_nn::weights::{Arch, GeneratorWeights};
use rand::SeedableRng;
use std::time::Instant;

fn main() {
    let w = GeneratorWeights::init_arch(&mut rand_chacha::ChaCha8Rng::seed_from_u64(1), 32, Arch::Residual);
    let recs: Vec<[f32; 210]> = (0..2048).map(|i| std::array::from_fn(|k| ((i * 7 + k * 13) % 17) as f32 / 17.0 - 0.5)).collect();
    let args: Vec<String> = std::env::args().skip(1).collect();
    for b in args[1..].iter().map(|a| a.parse::<usize>().unwrap()) {
        let g = GeneratorInference::with_block(&w, b);
        let mut s = InferScratch::default();
        let mut out = Vec::new();
        g.run(&recs[..256], &mut s, &mut out);
        let t = Instant::now();
        out.clear();
        g.run(&recs, &mut s, &mut out);
        let secs = t.elapsed().as_secs_f64();
        println!("{} block {b}: {:.0} records/s", args[0], recs.len() as f64 / secs);
    }
}
