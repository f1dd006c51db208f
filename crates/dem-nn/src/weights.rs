//! The parameters of the networks of `docs/network.md`, in PyTorch's layout
//! (the layout of `scripts/peers/torch_cyclegan.py` and of ONNX), so a
//! checkpoint, an export and the reference all name the same numbers.
//!
//! Feature orders fixed by the spec (NCHW inside the network):
//! - generator head input (210): `h[c][r][col]` at `c*100 + r*5 + col` for the
//!   2x20x5 decoder output, then the attitude `a[c][col]` (row 20 of the
//!   record, channel c, column col) at `200 + c*5 + col`;
//! - generator head output (200): `o[c][r][col]` at `c*100 + r*5 + col`;
//!   tanh on channel 1 (the mask);
//! - discriminator head input (1344): the 128x5x2 feature map at
//!   `c*10 + r*2 + col`, then the 64 attitude features.
//!
//! Layer 1 (weights): uses nothing else of the crate.

use dem_core::format::{GRID_CELLS, GRID_LEN, RECORD_LEN};
use rand::Rng;
use serde::{Deserialize, Serialize};

/// Instance-norm epsilon (PyTorch's default).
pub const NORM_EPS: f32 = 1e-5;
/// Leaky ReLU slope.
pub const LEAK: f32 = 0.2;

/// A 2-D convolution: `weight[o][i][ky][kx]` at `((o*c_in + i)*k + ky)*k + kx`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Conv2d {
    /// Output channels.
    pub c_out: usize,
    /// Input channels.
    pub c_in: usize,
    /// Kernel size (square).
    pub k: usize,
    /// Stride (both axes).
    pub stride: usize,
    /// `c_out * c_in * k * k` weights.
    pub weight: Vec<f32>,
    /// `c_out` biases.
    pub bias: Vec<f32>,
}

/// Affine instance norm: `y = gamma * (x - mean) / sqrt(var + eps) + beta`,
/// mean and biased variance over the spatial positions of one sample and channel.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct InstanceNorm {
    /// Scale per channel.
    pub gamma: Vec<f32>,
    /// Shift per channel.
    pub beta: Vec<f32>,
}

/// A fully connected layer `y = W x + b`: `weight[o][i]` at `o*n_in + i`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Linear {
    /// Outputs.
    pub n_out: usize,
    /// Inputs.
    pub n_in: usize,
    /// `n_out * n_in` weights.
    pub weight: Vec<f32>,
    /// `n_out` biases.
    pub bias: Vec<f32>,
}

/// Residual block: `x + nb(b(relu(na(a(x)))))`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ResBlock {
    /// First 3x3 conv.
    pub a: Conv2d,
    /// Norm after `a`.
    pub na: InstanceNorm,
    /// Second 3x3 conv.
    pub b: Conv2d,
    /// Norm after `b`.
    pub nb: InstanceNorm,
}

/// The residual head's height correction is `s o_h` with this `s` (metres per
/// unit of the head's output). The head's outputs are of order 1 and move by
/// ~lr per Adam step per feature; heights are of order 0.1 m and a measured
/// DEM is smooth to a few millimetres, so without the scale every step
/// jitters heights by centimetres (docs/training.md has the numbers).
pub const CORRECTION_SCALE: f32 = 0.1;

/// Slope `k` of the residual head's height gate `sigmoid(k o_m)`.
pub const GATE_SHARPNESS: f32 = 20.0;

/// Which generator head: how the fully connected head's 200 outputs
/// `o = (o_h, o_m)` become the output grid (`x_h` is the input's height
/// channel, `m` the output mask).
///
/// - [`Arch::Thesis`] (`docs/network.md`): `h = o_h`, `m = tanh(o_m)`. The
///   head must produce every height from scratch, and nothing in the losses
///   weighs a height error of centimetres against a mask error (equation 7.1
///   prices 10 cm at 1e-4): its heights come out as +-20 cm speckle.
/// - [`Arch::Residual`]: `m = tanh(o_m)`, `h = (x_h + s o_h) g` with
///   `s =` [`CORRECTION_SCALE`] and the gate `g = sigmoid(k o_m)`,
///   `k =` [`GATE_SHARPNESS`]. The head predicts a height *correction* over
///   the input, which starts at zero (its height rows are initialised to 0),
///   so an untrained G_Y keeps the terrain. The gate writes height ~0 where
///   the cell is missing (`o_m << 0`, as the contract stores missing cells)
///   and the full height where it is valid; it is smooth, so the export's
///   check against tract cannot flip on a mask near 0, and sharp, so a cell
///   the model calls valid with a mask of 0.25 already keeps 99 % of its
///   height (a gate of `(1 + m) / 2` shrank 10 % of the valid cells by up to
///   half and doubled the roughness; docs/training.md).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Arch {
    /// The thesis's head (checkpoints without an `arch` are this).
    #[default]
    Thesis,
    /// Heights as a gated correction over the input's heights.
    Residual,
}

impl Arch {
    /// The name used on the command line and in files.
    pub fn name(self) -> &'static str {
        match self {
            Arch::Thesis => "thesis",
            Arch::Residual => "residual",
        }
    }
}

/// Generator G_X or G_Y of width w: see the module docs and `docs/network.md`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GeneratorWeights {
    /// Width w (channels of the first conv).
    pub width: usize,
    /// The head's architecture.
    #[serde(default)]
    pub arch: Arch,
    /// Encoder convs 2 -> w -> 2w -> 2w (3x3, stride 1, pad 1).
    pub enc: Vec<Conv2d>,
    /// Norms after each encoder conv.
    pub enc_norm: Vec<InstanceNorm>,
    /// Three residual blocks at 2w.
    pub res: Vec<ResBlock>,
    /// Decoder convs 2w -> 2w -> w -> 2.
    pub dec: Vec<Conv2d>,
    /// Norms after the first two decoder convs.
    pub dec_norm: Vec<InstanceNorm>,
    /// Head 210 -> 200.
    pub fc: Linear,
}

/// Discriminator D_X or D_Y: see the module docs and `docs/network.md`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DiscriminatorWeights {
    /// 4x4 stride 2, 2 -> 64.
    pub c1: Conv2d,
    /// 4x4 stride 2, 64 -> 128.
    pub c2: Conv2d,
    /// 4x4 stride 1, 128 -> 128.
    pub c3: Conv2d,
    /// Norm after c2.
    pub n2: InstanceNorm,
    /// Norm after c3.
    pub n3: InstanceNorm,
    /// Attitude 10 -> 64.
    pub fa: Linear,
    /// Head 1344 -> 10, sigmoid.
    pub fo: Linear,
}

/// PyTorch's default initialisation: weights and biases uniform in
/// `(-1/sqrt(fan_in), 1/sqrt(fan_in))` (kaiming uniform with a = sqrt(5)).
fn uniform(rng: &mut impl Rng, n: usize, fan_in: usize) -> Vec<f32> {
    let bound = 1.0 / (fan_in as f32).sqrt();
    (0..n).map(|_| rng.gen_range(-bound..bound)).collect()
}

impl Conv2d {
    /// A freshly initialised conv.
    pub fn init(rng: &mut impl Rng, c_in: usize, c_out: usize, k: usize, stride: usize) -> Self {
        let fan_in = c_in * k * k;
        let weight = uniform(rng, c_out * fan_in, fan_in);
        let bias = uniform(rng, c_out, fan_in);
        Conv2d { c_out, c_in, k, stride, weight, bias }
    }
}

impl InstanceNorm {
    /// Identity affine (gamma 1, beta 0), as PyTorch initialises it.
    pub fn init(c: usize) -> Self {
        InstanceNorm { gamma: vec![1.0; c], beta: vec![0.0; c] }
    }
}

impl Linear {
    /// A freshly initialised layer.
    pub fn init(rng: &mut impl Rng, n_in: usize, n_out: usize) -> Self {
        let weight = uniform(rng, n_out * n_in, n_in);
        let bias = uniform(rng, n_out, n_in);
        Linear { n_out, n_in, weight, bias }
    }
}

impl GeneratorWeights {
    /// A freshly initialised thesis generator of width `w`.
    pub fn init(rng: &mut impl Rng, w: usize) -> Self {
        Self::init_arch(rng, w, Arch::Thesis)
    }

    /// A freshly initialised generator of width `w` and head `arch`: PyTorch's
    /// default initialisation everywhere (the same random stream for both
    /// heads), then for [`Arch::Residual`] the head's height rows (outputs
    /// 0..100) and their biases set to 0, so the correction starts at zero.
    pub fn init_arch(rng: &mut impl Rng, w: usize, arch: Arch) -> Self {
        let enc_ch = [2, w, 2 * w, 2 * w];
        let dec_ch = [2 * w, 2 * w, w, 2];
        let enc = (0..3).map(|i| Conv2d::init(rng, enc_ch[i], enc_ch[i + 1], 3, 1)).collect();
        let enc_norm = (0..3).map(|i| InstanceNorm::init(enc_ch[i + 1])).collect();
        let res = (0..3)
            .map(|_| ResBlock {
                a: Conv2d::init(rng, 2 * w, 2 * w, 3, 1),
                na: InstanceNorm::init(2 * w),
                b: Conv2d::init(rng, 2 * w, 2 * w, 3, 1),
                nb: InstanceNorm::init(2 * w),
            })
            .collect();
        let dec = (0..3).map(|i| Conv2d::init(rng, dec_ch[i], dec_ch[i + 1], 3, 1)).collect();
        let dec_norm = (0..2).map(|i| InstanceNorm::init(dec_ch[i + 1])).collect();
        let mut fc = Linear::init(rng, RECORD_LEN, GRID_LEN);
        if arch == Arch::Residual {
            // The height rows of the head start at zero: the correction starts at none.
            fc.weight[..GRID_CELLS * RECORD_LEN].fill(0.0);
            fc.bias[..GRID_CELLS].fill(0.0);
        }
        GeneratorWeights { width: w, arch, enc, enc_norm, res, dec, dec_norm, fc }
    }
}

impl DiscriminatorWeights {
    /// A freshly initialised discriminator.
    pub fn init(rng: &mut impl Rng) -> Self {
        DiscriminatorWeights {
            c1: Conv2d::init(rng, 2, 64, 4, 2),
            c2: Conv2d::init(rng, 64, 128, 4, 2),
            c3: Conv2d::init(rng, 128, 128, 4, 1),
            n2: InstanceNorm::init(128),
            n3: InstanceNorm::init(128),
            fa: Linear::init(rng, 10, 64),
            fo: Linear::init(rng, 128 * 10 + 64, 10),
        }
    }
}
