//! Samples/s of the full training step on random batches, the measurement
//! of `scripts/peers/torch_cyclegan.py` (width, batch, steps as its
//! arguments): `cargo run --release -p dem-nn --example step_speed -- 32 64 30`.
//! A fourth argument `residual` builds dem-train's default network and
//! losses instead of the thesis's, the peer of `scripts/peers/torch_residual_step.py`.
use dem_core::Dem;
use dem_nn::train::{Batch, CycleGan, GanConfig};
use rand::{Rng, SeedableRng};

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let residual = args.last().is_some_and(|a| a == "residual");
    if residual {
        args.pop();
    }
    let args: Vec<usize> = args.iter().map(|a| a.parse().expect("number")).collect();
    let (w, b, steps) = (*args.first().unwrap_or(&32), *args.get(1).unwrap_or(&64), *args.get(2).unwrap_or(&30));
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
    let mut rec = || -> Dem { std::array::from_fn(|_| rng.gen_range(-1.0..1.0)) };
    let xs: Vec<Dem> = (0..b).map(|_| rec()).collect();
    let ys: Vec<Dem> = (0..b).map(|_| rec()).collect();
    let yp: Vec<Dem> = (0..b).map(|_| rec()).collect();
    // Every row paired with one real, as the peer's paired term.
    let pairs: Vec<Vec<&[f32]>> = yp.iter().map(|d| vec![&d[..200]]).collect();
    let batch = Batch::new(&xs.iter().collect::<Vec<_>>(), &ys.iter().collect::<Vec<_>>(), pairs);
    // The thesis network and losses (what the reference builds), or the
    // default residual head with its height term.
    let base = if residual { GanConfig::default() } else { GanConfig::thesis() };
    let mut gan = CycleGan::new(GanConfig { width: w, ..base }, 0);
    for _ in 0..3 {
        gan.step(&batch);
    }
    let t = std::time::Instant::now();
    for _ in 0..steps {
        gan.step(&batch);
    }
    let dt = t.elapsed().as_secs_f64();
    println!(
        "dem-nn threads={} width={w} batch={b} G_params={} arch={} samples/s={:.1}",
        rayon::current_num_threads(),
        gan.sizes()[1],
        if residual { "residual" } else { "thesis" },
        (steps * b) as f64 / dt
    );
}
