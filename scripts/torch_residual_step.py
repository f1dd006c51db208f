"""The PyTorch peer of dem-train's default network (`--arch residual`): one
full Cycle GAN + paired step (2 G, 2 D) on random batches, samples/s.

    python scripts/torch_residual_step.py [WIDTH] [BATCH] [STEPS]

shared/reference/torch_cyclegan.py builds the thesis network; since issue 11
dem-train's default differs in the generator's head and the paired losses
(docs/training.md, "A generator that keeps the terrain"):

    heights = (x_h + 0.1 o_h) * sigmoid(20 o_m), masks = tanh(o_m)
    L_G += 30 (e71(yp, G_Y(x)) + |G_X(y) - x|^2 / 100) + 3 H(yp, G_Y(x))

e71 the equation 7.1 error (height error where yp is valid, mask error
everywhere), H the mean absolute height error in cm on yp's valid cells.
Everything else is the reference's, line for line (its structure too: the
paired G_Y term runs G_Y(x) again, as the reference does), so
scripts/bench_train.sh can set this against `step_speed ... residual` as it
sets the reference against the thesis network.
"""
import sys
import time

import torch
import torch.nn as nn
import torch.nn.functional as F

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

    def forward(s, x):
        img, ang = x[:, :, :20], x[:, :, 20].flatten(1)
        h = F.leaky_relu(s.c1(same_pad(img, 4, 2)), 0.2)
        h = F.leaky_relu(s.n2(s.c2(same_pad(h, 4, 2))), 0.2)
        h = F.leaky_relu(s.n3(s.c3(same_pad(h, 4, 1))), 0.2)
        a = F.leaky_relu(s.fa(ang), 0.2)
        return torch.sigmoid(s.fo(torch.cat([h.flatten(1), a], 1)))


class Res(nn.Module):
    def __init__(s, c):
        super().__init__()
        s.a, s.b = nn.Conv2d(c, c, 3, 1, 1), nn.Conv2d(c, c, 3, 1, 1)
        s.na, s.nb = nn.InstanceNorm2d(c, affine=True), nn.InstanceNorm2d(c, affine=True)

    def forward(s, x):
        return x + s.nb(s.b(F.relu(s.na(s.a(x)))))


class Gen(nn.Module):
    """The reference's generator with the residual head."""

    def __init__(s, w):
        super().__init__()
        ch = [2, w, 2 * w, 2 * w]
        s.enc = nn.ModuleList([nn.Conv2d(ch[i], ch[i + 1], 3, 1, 1) for i in range(3)])
        s.en = nn.ModuleList([nn.InstanceNorm2d(ch[i + 1], affine=True) for i in range(3)])
        s.res = nn.Sequential(*[Res(2 * w) for _ in range(3)])
        dch = [2 * w, 2 * w, w, 2]
        s.dec = nn.ModuleList([nn.Conv2d(dch[i], dch[i + 1], 3, 1, 1) for i in range(3)])
        s.dn = nn.ModuleList([nn.InstanceNorm2d(dch[i + 1], affine=True) for i in range(2)])
        s.fc = nn.Linear(200 + 10, 200)

    def forward(s, x):
        img, ang = x[:, :, :20], x[:, :, 20]
        h = img
        for c, n in zip(s.enc, s.en):
            h = F.leaky_relu(n(c(h)), 0.2)
        h = s.res(h)
        for i, c in enumerate(s.dec):
            h = c(h)
            if i < 2:
                h = F.leaky_relu(s.dn[i](h), 0.2)
        o = s.fc(torch.cat([h.flatten(1), ang.flatten(1)], 1)).view(-1, 2, 20, 5)
        heights = (img[:, 0] + 0.1 * o[:, 0]) * torch.sigmoid(20 * o[:, 1])
        o = torch.stack([heights, torch.tanh(o[:, 1])], 1)
        return torch.cat([o, torch.zeros_like(ang).unsqueeze(2)], 2)


GX, GY, DX, DY = Gen(W), Gen(W), Disc(), Disc()
og = torch.optim.Adam(list(GX.parameters()) + list(GY.parameters()), 2e-4, betas=(0.5, 0.999))
od = torch.optim.Adam(list(DX.parameters()) + list(DY.parameters()), 2e-4, betas=(0.5, 0.999))
bce = lambda d, t: F.binary_cross_entropy(d, torch.full_like(d, t))


def paired(p, y):
    """30 e71(y, p) + 3 H(y, p), means over the batch."""
    valid = (y[:, 1, :20] > 0).float()
    dh, dm = p[:, 0, :20] - y[:, 0, :20], p[:, 1, :20] - y[:, 1, :20]
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


x, y, yp = torch.randn(B, 2, 21, 5), torch.randn(B, 2, 21, 5), torch.randn(B, 2, 21, 5)
for _ in range(3):
    step(x, y, yp)
t = time.perf_counter()
for _ in range(STEPS):
    step(x, y, yp)
dt = time.perf_counter() - t
params = sum(p.numel() for p in GY.parameters())
print(f"torch {torch.__version__} threads={torch.get_num_threads()} width={W} batch={B} G_params={params} arch=residual samples/s={STEPS * B / dt:.1f}")
