//! Random streams fixed by (seed, record index): a record's draws do not
//! depend on chunking, threads or which other records are in the stream.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The random stream of record `index` under `seed`.
pub fn record_rng(seed: u64, index: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(index);
    rng
}

/// A uniform number in [0, 1) fixed by (seed, index): for keep/drop choices.
pub fn record_uniform(seed: u64, index: u64) -> f64 {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed_f111);
    rng.set_stream(index);
    rng.gen()
}
