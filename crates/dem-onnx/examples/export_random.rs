//! Export a randomly initialised generator (PyTorch's initialisation, a
//! seed), checked against the f64 reference forward on bundled records:
//! a model for benchmarks and demos when no trained one is at hand. With a
//! sensor model JSON it is a whole virtual sensor (the input's heights
//! under the network's holes, then that model; `dem-train export
//! --heights input --residual JSON`'s graph).
//!
//!     cargo run --release -p dem-onnx --example export_random -- OUT.onnx [WIDTH] [SEED] [RESIDUAL.json]

use dem_nn::{reference, weights::GeneratorWeights};
use dem_onnx::sensor::Stored;
use dem_onnx::Heights;
use rand::SeedableRng;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(out) = args.first() else {
        return Err("usage: export_random OUT.onnx [WIDTH=32] [SEED=1] [RESIDUAL.json]".into());
    };
    let width = args.get(1).map_or(Ok(32), |s| s.parse())?;
    let seed = args.get(2).map_or(Ok(1), |s| s.parse())?;
    let stored = match args.get(3) {
        Some(json) => Stored { residual: Some(dem_sensor::SensorModel::read(json)?), heights: Heights::Input },
        None => Stored::default(),
    };
    let w = GeneratorWeights::init(&mut rand_chacha::ChaCha8Rng::seed_from_u64(seed), width);
    let sim = dem_core::npy::read_all(dem_testkit::testdata("sim.npy").to_str().ok_or("path")?)?;
    let check: Vec<_> = sim.iter().step_by(sim.len() / 16).copied().collect();
    let want: Vec<_> = check.iter().map(|d| reference::generator(&w, d)).collect();
    let r = dem_onnx::export::export_sensor_checked(&w, &stored, &check, &want, out, &[])?;
    eprintln!(
        "export_random: width {width}, seed {seed} -> {} ({} bytes), max |tract - reference| = {:e} over {} records{}",
        r.path,
        r.bytes,
        r.max_abs_diff,
        r.records,
        stored.residual.map_or(String::new(), |m| format!(", with the residual {}", m.summary()))
    );
    Ok(())
}
