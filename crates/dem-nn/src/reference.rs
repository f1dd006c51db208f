//! A slow, obviously correct forward pass of both networks, one sample at a
//! time in f64, straight from `docs/network.md` (and the PyTorch peer). The
//! fast kernels, the export and the ONNX runners are all tested against it.
//!
//! Layer 3 (reference): uses weights and layers; the crate's own code calls it only from tests.

use dem_core::Dem;

use crate::layers::conv::same_pad;
use crate::weights::{
    Arch, Conv2d, DiscriminatorWeights, GeneratorWeights, InstanceNorm, Linear, CORRECTION_SCALE, GATE_SHARPNESS, LEAK, NORM_EPS,
};

/// A feature map of one sample: `c` channels of `h x w`, NCHW order.
#[derive(Clone, Debug)]
struct Map {
    c: usize,
    h: usize,
    w: usize,
    v: Vec<f64>,
}

impl Map {
    fn at(&self, c: usize, y: isize, x: isize) -> f64 {
        if y < 0 || x < 0 || y as usize >= self.h || x as usize >= self.w {
            return 0.0;
        }
        self.v[(c * self.h + y as usize) * self.w + x as usize]
    }
}

fn conv(x: &Map, l: &Conv2d, pad_y: usize, pad_x: usize, oh: usize, ow: usize) -> Map {
    let mut v = vec![0.0; l.c_out * oh * ow];
    for o in 0..l.c_out {
        for y in 0..oh {
            for xx in 0..ow {
                let mut s = l.bias[o] as f64;
                for i in 0..l.c_in {
                    for ky in 0..l.k {
                        for kx in 0..l.k {
                            let iy = (y * l.stride + ky) as isize - pad_y as isize;
                            let ix = (xx * l.stride + kx) as isize - pad_x as isize;
                            let wgt = l.weight[((o * l.c_in + i) * l.k + ky) * l.k + kx] as f64;
                            s += wgt * x.at(i, iy, ix);
                        }
                    }
                }
                v[(o * oh + y) * ow + xx] = s;
            }
        }
    }
    Map { c: l.c_out, h: oh, w: ow, v }
}

fn conv3(x: &Map, l: &Conv2d) -> Map {
    conv(x, l, 1, 1, x.h, x.w)
}

fn conv_same(x: &Map, l: &Conv2d) -> Map {
    let (oh, py, _) = same_pad(x.h, l.k, l.stride);
    let (ow, px, _) = same_pad(x.w, l.k, l.stride);
    conv(x, l, py, px, oh, ow)
}

fn norm(mut x: Map, n: &InstanceNorm) -> Map {
    let hw = x.h * x.w;
    for c in 0..x.c {
        let s = &mut x.v[c * hw..(c + 1) * hw];
        let mean = s.iter().sum::<f64>() / hw as f64;
        let var = s.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / hw as f64;
        let inv = 1.0 / (var + NORM_EPS as f64).sqrt();
        for v in s.iter_mut() {
            *v = n.gamma[c] as f64 * (*v - mean) * inv + n.beta[c] as f64;
        }
    }
    x
}

fn leaky(mut x: Map) -> Map {
    x.v.iter_mut().for_each(|v| *v = if *v > 0.0 { *v } else { LEAK as f64 * *v });
    x
}

fn relu(mut x: Map) -> Map {
    x.v.iter_mut().for_each(|v| *v = v.max(0.0));
    x
}

fn linear(x: &[f64], l: &Linear) -> Vec<f64> {
    (0..l.n_out)
        .map(|o| {
            let row = &l.weight[o * l.n_in..(o + 1) * l.n_in];
            l.bias[o] as f64 + row.iter().zip(x).map(|(w, v)| *w as f64 * v).sum::<f64>()
        })
        .collect()
}

/// Rows 0..19 of a record as a 2x20x5 map and the attitude (2x5, channel-major).
fn split(dem: &Dem) -> (Map, Vec<f64>) {
    let mut v = vec![0.0; 200];
    let mut att = vec![0.0; 10];
    for c in 0..2 {
        for col in 0..5 {
            for r in 0..20 {
                v[(c * 20 + r) * 5 + col] = dem[(r * 5 + col) * 2 + c] as f64;
            }
            att[c * 5 + col] = dem[(20 * 5 + col) * 2 + c] as f64;
        }
    }
    (Map { c: 2, h: 20, w: 5, v }, att)
}

/// G(x) for one record: the spec's generator; row 20 passes through.
pub fn generator(g: &GeneratorWeights, dem: &Dem) -> Dem {
    let grid = generator_grid(g, dem);
    let mut out = *dem;
    out[..200].iter_mut().zip(&grid).for_each(|(o, v)| *o = *v as f32);
    out
}

/// Rows 0..19 of G(x) in f64, in record order (`(r*5 + col)*2 + c`).
pub fn generator_grid(g: &GeneratorWeights, dem: &Dem) -> Vec<f64> {
    let (mut h, att) = split(dem);
    for (c, n) in g.enc.iter().zip(&g.enc_norm) {
        h = leaky(norm(conv3(&h, c), n));
    }
    for r in &g.res {
        let t = norm(conv3(&relu(norm(conv3(&h, &r.a), &r.na)), &r.b), &r.nb);
        h.v.iter_mut().zip(&t.v).for_each(|(a, b)| *a += b);
    }
    for (i, c) in g.dec.iter().enumerate() {
        h = conv3(&h, c);
        if i < 2 {
            h = leaky(norm(h, &g.dec_norm[i]));
        }
    }
    let mut feat = h.v;
    feat.extend_from_slice(&att);
    let o = linear(&feat, &g.fc);
    let mut out = vec![0.0; 200];
    for r in 0..20 {
        for col in 0..5 {
            let (oh, om) = (o[r * 5 + col], o[(20 + r) * 5 + col]);
            let m = om.tanh();
            let h = match g.arch {
                Arch::Thesis => oh,
                Arch::Residual => {
                    let gate = 1.0 / (1.0 + (-(GATE_SHARPNESS as f64) * om).exp());
                    (dem[(r * 5 + col) * 2] as f64 + CORRECTION_SCALE as f64 * oh) * gate
                }
            };
            out[(r * 5 + col) * 2] = h;
            out[(r * 5 + col) * 2 + 1] = m;
        }
    }
    out
}

/// D(x) for one record: 10 decisions in (0, 1), the 5x2 grid row-major.
pub fn discriminator(d: &DiscriminatorWeights, dem: &Dem) -> [f64; 10] {
    let (img, att) = split(dem);
    let h = leaky(conv_same(&img, &d.c1));
    let h = leaky(norm(conv_same(&h, &d.c2), &d.n2));
    let h = leaky(norm(conv_same(&h, &d.c3), &d.n3));
    let a: Vec<f64> = linear(&att, &d.fa).into_iter().map(|v| if v > 0.0 { v } else { LEAK as f64 * v }).collect();
    let mut feat = h.v;
    feat.extend_from_slice(&a);
    let o = linear(&feat, &d.fo);
    let mut out = [0.0; 10];
    for (d, v) in out.iter_mut().zip(o) {
        *d = 1.0 / (1.0 + (-v).exp());
    }
    out
}
