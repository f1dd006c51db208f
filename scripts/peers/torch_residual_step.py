"""The PyTorch peer of dem-train's default network (`--arch residual`): one
full Cycle GAN + paired step (2 G, 2 D) on random batches, samples/s.

    python scripts/peers/torch_residual_step.py [WIDTH] [BATCH] [STEPS]

scripts/peers/torch_cyclegan.py builds the thesis network; dem-train's default
(`--arch residual`) differs in the generator's head and the paired losses
(docs/training.md, "A generator that keeps the terrain"):

    heights = (x_h + 0.1 o_h) * sigmoid(20 o_m), masks = tanh(o_m)
    L_G += 30 (e71(yp, G_Y(x)) + |G_X(y) - x|^2 / 100) + 3 H(yp, G_Y(x))

e71 the equation 7.1 error (height error where yp is valid, mask error
everywhere), H the mean absolute height error in cm on yp's valid cells.
The generator is torch_export.py's (the reference's with that head,
channels last in and out as the toolkit's files are: one permute each way,
and the discriminators permute their input); the rest is the reference's,
line for line (its structure too: the paired G_Y term runs G_Y(x) again,
as the reference does), so
scripts/bench/train.sh can set this against `step_speed ... residual` as it
sets the reference against the thesis network.
"""
import os
import sys
import time

import torch
import torch.nn as nn
import torch.nn.functional as F

# torch_export.py's generator: the reference's, with the residual head.
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from torch_export import Gen  # noqa: E402

W = int(sys.argv[1]) if len(sys.argv) > 1 else 32
B = int(sys.argv[2]) if len(sys.argv) > 2 else 64
STEPS = int(sys.argv[3]) if len(sys.argv) > 3 else 30
torch.manual_seed(0)


def same_pad(x, k, s):
    h, w = x.shape[-2:]
    oh, ow = -(-h // s), -(-w // s)
    ph, pw = max((oh - 1) * s + k - h, 0), max((ow - 1) * s + k - w, 0)
    return F.pad(x, (pw // 2, pw - pw // 2, ph // 2, ph - ph // 2))


class Disc(nn.Module):
    def __init__(s):
        super().__init__()
        s.c1, s.c2, s.c3 = nn.Conv2d(2, 64, 4, 2), nn.Conv2d(64, 128, 4, 2), nn.Conv2d(128, 128, 4, 1)
        s.n2, s.n3 = nn.InstanceNorm2d(128, affine=True), nn.InstanceNorm2d(128, affine=True)
        s.fa = nn.Linear(10, 64)
        s.fo = nn.Linear(128 * 10 + 64, 10)

    def forward(s, dem):
        x = dem.permute(0, 3, 1, 2)
        img, ang = x[:, :, :20], x[:, :, 20].flatten(1)
        h = F.leaky_relu(s.c1(same_pad(img, 4, 2)), 0.2)
        h = F.leaky_relu(s.n2(s.c2(same_pad(h, 4, 2))), 0.2)
        h = F.leaky_relu(s.n3(s.c3(same_pad(h, 4, 1))), 0.2)
        a = F.leaky_relu(s.fa(ang), 0.2)
        return torch.sigmoid(s.fo(torch.cat([h.flatten(1), a], 1)))


GX, GY, DX, DY = Gen(W, residual=True), Gen(W, residual=True), Disc(), Disc()
og = torch.optim.Adam(list(GX.parameters()) + list(GY.parameters()), 2e-4, betas=(0.5, 0.999))
od = torch.optim.Adam(list(DX.parameters()) + list(DY.parameters()), 2e-4, betas=(0.5, 0.999))
bce = lambda d, t: F.binary_cross_entropy(d, torch.full_like(d, t))


def paired(p, y):
    """30 e71(y, p) + 3 H(y, p), means over the batch (channels last)."""
    valid = (y[:, :20, :, 1] > 0).float()
    dh, dm = p[:, :20, :, 0] - y[:, :20, :, 0], p[:, :20, :, 1] - y[:, :20, :, 1]
    e71 = ((valid * dh) ** 2 + dm ** 2).sum((1, 2)) / 100
    h = (valid * dh.abs()).sum((1, 2)) / (valid.sum((1, 2)).clamp(min=1) * 0.01)
    return 30 * e71.mean() + 3 * h.mean()


def step(x, y, yp):
    fy, fx = GY(x), GX(y)
    lg = bce(DY(fy), 0.9) + bce(DX(fx), 0.9) + 10 * ((GX(fy) - x).abs().mean() + (GY(fx) - y).abs().mean())
    # G_X's paired term reuses fx (G_X of the batch's reals), as dem-nn does;
    # the reference has no G_X term, so there is no line of its to copy.
    lg = lg + paired(GY(x), yp) + 30 * ((fx - x) ** 2).sum((1, 2, 3)).mean() / 100
    og.zero_grad()
    lg.backward()
    og.step()
    ld = bce(DY(y), 0.9) + bce(DY(fy.detach()), 0.0) + bce(DX(x), 0.9) + bce(DX(fx.detach()), 0.0)
    od.zero_grad()
    ld.backward()
    od.step()


x, y, yp = torch.randn(B, 21, 5, 2), torch.randn(B, 21, 5, 2), torch.randn(B, 21, 5, 2)
for _ in range(3):
    step(x, y, yp)
t = time.perf_counter()
for _ in range(STEPS):
    step(x, y, yp)
dt = time.perf_counter() - t
params = sum(p.numel() for p in GY.parameters())
print(f"torch {torch.__version__} threads={torch.get_num_threads()} width={W} batch={B} G_params={params} arch=residual samples/s={STEPS * B / dt:.1f}")
