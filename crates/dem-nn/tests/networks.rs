//! The batched kernels against the slow f64 reference: forward outputs, and
//! every layer's gradients against central finite differences of the
//! reference's loss.

use dem_core::Dem;
use dem_nn::net::{DiscScratch, DiscTape, Discriminator, GenScratch, GenTape, Generator};
use dem_nn::reference;
use dem_nn::weights::{Arch, Conv2d, DiscriminatorWeights, GeneratorWeights, InstanceNorm, Linear};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn records(n: usize) -> Vec<Dem> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../testdata/real.npy");
    let all = dem_core::npy::read_all(path).expect("testdata");
    // Spread over the file: startup frames, obstacles, missing cells.
    let mut out: Vec<Dem> = (0..n).map(|i| all[(i * 131 + 7) % all.len()]).collect();
    // A recorded attitude, so the head's attitude weights matter.
    for (i, d) in out.iter_mut().enumerate() {
        for c in 0..5 {
            d[(20 * 5 + c) * 2] = 0.1 * (i as f32 + 1.0) - 0.05 * c as f32;
        }
    }
    out
}

fn split(batch: &[Dem]) -> (Vec<f32>, Vec<f32>) {
    let grid = batch.iter().flat_map(|d| d[..200].iter().copied()).collect();
    let att = batch.iter().flat_map(|d| d[200..].iter().copied()).collect();
    (grid, att)
}

/// Randomise the affine norm parameters too (PyTorch starts them at 1 / 0,
/// which would hide a swapped gamma and beta).
fn jitter_norms(rng: &mut ChaCha8Rng, n: &mut InstanceNorm) {
    n.gamma.iter_mut().for_each(|g| *g = rng.gen_range(0.5..1.5));
    n.beta.iter_mut().for_each(|b| *b = rng.gen_range(-0.3..0.3));
}

fn generator_weights(w: usize, seed: u64, arch: Arch) -> GeneratorWeights {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut g = GeneratorWeights::init_arch(&mut rng, w, arch);
    // The residual head starts its height correction at 0; give it one, so
    // the test sees the correction's weights and the gate at work.
    if arch == Arch::Residual {
        g.fc.weight[..100 * 210].iter_mut().for_each(|v| *v = rng.gen_range(-0.05..0.05));
        g.fc.bias[..100].iter_mut().for_each(|v| *v = rng.gen_range(-0.05..0.05));
    }
    let norms = g.enc_norm.iter_mut().chain(g.dec_norm.iter_mut()).chain(g.res.iter_mut().flat_map(|r| [&mut r.na, &mut r.nb]));
    norms.for_each(|n| jitter_norms(&mut rng, n));
    g
}

fn disc_weights(seed: u64) -> DiscriminatorWeights {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut d = DiscriminatorWeights::init(&mut rng);
    jitter_norms(&mut rng, &mut d.n2);
    jitter_norms(&mut rng, &mut d.n3);
    d
}

#[test]
fn generator_forward_matches_the_reference() {
    for (w, arch) in [(4, Arch::Thesis), (32, Arch::Thesis), (4, Arch::Residual), (32, Arch::Residual)] {
        let gw = generator_weights(w, 1, arch);
        let net = Generator::new(w, arch);
        assert_eq!(net.save(&net.load(&gw)), gw, "load/save round trip");
        let p = net.load(&gw);
        let batch = records(9);
        let (grid, att) = split(&batch);
        let mut tape = GenTape::default();
        net.forward(&p, &grid, &att, &mut tape);
        for (i, d) in batch.iter().enumerate() {
            let want = reference::generator_grid(&gw, d);
            for (j, (a, b)) in tape.out[i * 200..][..200].iter().zip(&want).enumerate() {
                assert!((*a as f64 - b).abs() < 1e-4, "width {w} {arch:?} record {i} value {j}: {a} vs {b}");
            }
        }
    }
}

#[test]
fn discriminator_forward_matches_the_reference() {
    let dw = disc_weights(2);
    let net = Discriminator::new();
    assert_eq!(net.save(&net.load(&dw)), dw, "load/save round trip");
    let p = net.load(&dw);
    let batch = records(5);
    let (grid, att) = split(&batch);
    let mut tape = DiscTape::default();
    net.forward(&p, &grid, &att, &mut tape);
    for (i, d) in batch.iter().enumerate() {
        let want = reference::discriminator(&dw, d);
        for (j, (l, b)) in tape.logits[i * 10..][..10].iter().zip(&want).enumerate() {
            let s = 1.0 / (1.0 + (-*l as f64).exp());
            assert!((s - b).abs() < 1e-5, "record {i} decision {j}: {s} vs {b}");
        }
    }
}

/// Every parameter tensor of a network in PyTorch layout, mutably.
fn gen_tensors(g: &mut GeneratorWeights) -> Vec<(&'static str, &mut Vec<f32>)> {
    let mut v: Vec<(&'static str, &mut Vec<f32>)> = Vec::new();
    fn conv<'a>(v: &mut Vec<(&'static str, &'a mut Vec<f32>)>, c: &'a mut Conv2d) {
        v.push(("conv.weight", &mut c.weight));
        v.push(("conv.bias", &mut c.bias));
    }
    fn norm<'a>(v: &mut Vec<(&'static str, &'a mut Vec<f32>)>, n: &'a mut InstanceNorm) {
        v.push(("norm.gamma", &mut n.gamma));
        v.push(("norm.beta", &mut n.beta));
    }
    fn lin<'a>(v: &mut Vec<(&'static str, &'a mut Vec<f32>)>, l: &'a mut Linear) {
        v.push(("linear.weight", &mut l.weight));
        v.push(("linear.bias", &mut l.bias));
    }
    for c in &mut g.enc {
        conv(&mut v, c);
    }
    for n in &mut g.enc_norm {
        norm(&mut v, n);
    }
    for r in &mut g.res {
        conv(&mut v, &mut r.a);
        norm(&mut v, &mut r.na);
        conv(&mut v, &mut r.b);
        norm(&mut v, &mut r.nb);
    }
    for c in &mut g.dec {
        conv(&mut v, c);
    }
    for n in &mut g.dec_norm {
        norm(&mut v, n);
    }
    lin(&mut v, &mut g.fc);
    v
}

fn disc_tensors(d: &mut DiscriminatorWeights) -> Vec<(&'static str, &mut Vec<f32>)> {
    vec![
        ("c1.weight", &mut d.c1.weight),
        ("c1.bias", &mut d.c1.bias),
        ("c2.weight", &mut d.c2.weight),
        ("c2.bias", &mut d.c2.bias),
        ("c3.weight", &mut d.c3.weight),
        ("c3.bias", &mut d.c3.bias),
        ("n2.gamma", &mut d.n2.gamma),
        ("n2.beta", &mut d.n2.beta),
        ("n3.gamma", &mut d.n3.gamma),
        ("n3.beta", &mut d.n3.beta),
        ("fa.weight", &mut d.fa.weight),
        ("fa.bias", &mut d.fa.bias),
        ("fo.weight", &mut d.fo.weight),
        ("fo.bias", &mut d.fo.bias),
    ]
}

/// The width of the central difference actually taken in f32 around `x`
/// (the reference computes in f64, so a tiny step is exact up to this).
fn step(x: f32, eps: f64) -> f64 {
    (x + eps as f32) as f64 - (x - eps as f32) as f64
}

/// Compare analytic and central-difference gradients; tolerant of the odd
/// parameter whose step crosses a (leaky) ReLU kink.
fn check(name: &str, analytic: f64, numeric: f64) -> bool {
    let ok = (analytic - numeric).abs() <= 2e-3 + 2e-2 * numeric.abs().max(analytic.abs());
    if !ok {
        eprintln!("{name}: analytic {analytic:.6} vs numeric {numeric:.6}");
    }
    ok
}

#[test]
fn generator_gradients_match_finite_differences() {
    generator_gradients(Arch::Thesis);
}

#[test]
fn residual_generator_gradients_match_finite_differences() {
    generator_gradients(Arch::Residual);
}

fn generator_gradients(arch: Arch) {
    let w = 4;
    let gw = generator_weights(w, 3, arch);
    let net = Generator::new(w, arch);
    let p = net.load(&gw);
    let batch = records(3);
    let (grid, att) = split(&batch);
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let r: Vec<f64> = (0..batch.len() * 200).map(|_| rng.gen_range(-1.0..1.0)).collect();
    // L = sum r . G(x), so dL/dout = r.
    let loss = |g: &GeneratorWeights, batch: &[Dem]| -> f64 {
        batch
            .iter()
            .enumerate()
            .map(|(i, d)| reference::generator_grid(g, d).iter().zip(&r[i * 200..]).map(|(a, b)| a * b).sum::<f64>())
            .sum()
    };
    let mut tape = GenTape::default();
    net.forward(&p, &grid, &att, &mut tape);
    let mut grads = vec![0.0; net.len];
    let dout: Vec<f32> = r.iter().map(|v| *v as f32).collect();
    let dx = net.backward(&p, &tape, &dout, &mut grads, true, &mut GenScratch::default()).expect("input grad");
    let mut analytic = net.save(&grads);
    let (eps, mut bad, mut total) = (1e-5, 0, 0);
    let mut probe = gw.clone();
    let n_tensors = gen_tensors(&mut probe).len();
    for t in 0..n_tensors {
        let len = gen_tensors(&mut probe)[t].1.len();
        for k in 0..3 {
            let idx = (k * 7919 + t * 31) % len;
            let orig = gen_tensors(&mut probe)[t].1[idx];
            gen_tensors(&mut probe)[t].1[idx] = orig + eps as f32;
            let up = loss(&probe, &batch);
            gen_tensors(&mut probe)[t].1[idx] = orig - eps as f32;
            let down = loss(&probe, &batch);
            gen_tensors(&mut probe)[t].1[idx] = orig;
            let numeric = (up - down) / step(orig, eps);
            let (name, a) = &gen_tensors(&mut analytic)[t];
            total += 1;
            if !check(&format!("tensor {t} ({name})[{idx}]"), a[idx] as f64, numeric) {
                bad += 1;
            }
        }
    }
    // Input gradient, at a few cells of each record (both channels).
    for (i, d) in batch.iter().enumerate() {
        for cell in [0, 57, 133, 199] {
            let mut b2 = batch.clone();
            b2[i][cell] = d[cell] + eps as f32;
            let up = loss(&gw, &b2);
            b2[i][cell] = d[cell] - eps as f32;
            let down = loss(&gw, &b2);
            total += 1;
            if !check(&format!("input {i}[{cell}]"), dx[i * 200 + cell] as f64, (up - down) / step(d[cell], eps)) {
                bad += 1;
            }
        }
    }
    // A step may still cross a (leaky) ReLU kink: allow one in fifty.
    assert!(bad * 50 <= total, "{bad} of {total} gradients disagree");
}

#[test]
fn discriminator_gradients_match_finite_differences() {
    let dw = disc_weights(5);
    let net = Discriminator::new();
    let p = net.load(&dw);
    let batch = records(3);
    let (grid, att) = split(&batch);
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    let r: Vec<f64> = (0..batch.len() * 10).map(|_| rng.gen_range(-1.0..1.0)).collect();
    // L = sum r . sigmoid(logits).
    let loss = |d: &DiscriminatorWeights, batch: &[Dem]| -> f64 {
        batch
            .iter()
            .enumerate()
            .map(|(i, x)| reference::discriminator(d, x).iter().zip(&r[i * 10..]).map(|(a, b)| a * b).sum::<f64>())
            .sum()
    };
    let mut tape = DiscTape::default();
    net.forward(&p, &grid, &att, &mut tape);
    let dlogits: Vec<f32> = tape
        .logits
        .iter()
        .zip(&r)
        .map(|(l, r)| {
            let s = 1.0 / (1.0 + (-*l as f64).exp());
            (r * s * (1.0 - s)) as f32
        })
        .collect();
    let mut grads = vec![0.0; net.len];
    let mut s = DiscScratch::default();
    net.backward(&p, &tape, &dlogits, Some(&mut grads), false, &mut s);
    // The generators' pass: input gradient only, and it must not touch grads.
    let before = grads.clone();
    let dx = net.backward(&p, &tape, &dlogits, None, true, &mut s).expect("input grad");
    assert_eq!(grads, before);
    let mut analytic = net.save(&grads);
    let (eps, mut bad, mut total) = (1e-5, 0, 0);
    let mut probe = dw.clone();
    for t in 0..disc_tensors(&mut probe).len() {
        let len = disc_tensors(&mut probe)[t].1.len();
        for k in 0..4 {
            let idx = (k * 7919 + t * 31) % len;
            let orig = disc_tensors(&mut probe)[t].1[idx];
            disc_tensors(&mut probe)[t].1[idx] = orig + eps as f32;
            let up = loss(&probe, &batch);
            disc_tensors(&mut probe)[t].1[idx] = orig - eps as f32;
            let down = loss(&probe, &batch);
            disc_tensors(&mut probe)[t].1[idx] = orig;
            let (name, a) = &disc_tensors(&mut analytic)[t];
            total += 1;
            if !check(&format!("{name}[{idx}]"), a[idx] as f64, (up - down) / step(orig, eps)) {
                bad += 1;
            }
        }
    }
    for (i, d) in batch.iter().enumerate() {
        for cell in [1, 40, 120, 198] {
            let mut b2 = batch.clone();
            b2[i][cell] = d[cell] + eps as f32;
            let up = loss(&dw, &b2);
            b2[i][cell] = d[cell] - eps as f32;
            let down = loss(&dw, &b2);
            total += 1;
            if !check(&format!("input {i}[{cell}]"), dx[i * 200 + cell] as f64, (up - down) / step(d[cell], eps)) {
                bad += 1;
            }
        }
    }
    // A step may still cross a (leaky) ReLU kink: allow one in fifty.
    assert!(bad * 50 <= total, "{bad} of {total} gradients disagree");
}
