"""A generator of docs/network.md built and exported by PyTorch, the way a
user with a PyTorch training pipeline would hand one to dem-apply.

    python scripts/peers/torch_export.py OUT.onnx [--width 32] [--seed 1] [--arch thesis|residual]

The network is scripts/peers/torch_cyclegan.py's `Gen` (the thesis
network) with the toolkit's I/O: input `dem` (N, 21, 5, 2), output `dem_out`
(N, 21, 5, 2), row 20 (the attitude) passed through; `--arch residual` adds
the residual head of docs/training.md (heights (x_h + 0.1 o_h) sigmoid(20 o_m),
masks tanh(o_m)). Weights are random (seeded), instance norms' affine
parameters too, so a wrong wiring cannot hide behind ones and zeros.
torch.onnx.export (TorchScript exporter, opset 17) writes the graph; its
nodes are PyTorch's, not dem-onnx's, which is the point of the benchmark.
"""
import argparse
import warnings

import torch
import torch.nn as nn
import torch.nn.functional as F


class Res(nn.Module):
    def __init__(s, c):
        super().__init__()
        s.a, s.b = nn.Conv2d(c, c, 3, 1, 1), nn.Conv2d(c, c, 3, 1, 1)
        s.na, s.nb = nn.InstanceNorm2d(c, affine=True), nn.InstanceNorm2d(c, affine=True)

    def forward(s, x):
        return x + s.nb(s.b(F.relu(s.na(s.a(x)))))


class Gen(nn.Module):
    """The reference's generator, channels-last in and out, row 20 through."""

    def __init__(s, w, residual):
        super().__init__()
        ch = [2, w, 2 * w, 2 * w]
        s.enc = nn.ModuleList([nn.Conv2d(ch[i], ch[i + 1], 3, 1, 1) for i in range(3)])
        s.en = nn.ModuleList([nn.InstanceNorm2d(ch[i + 1], affine=True) for i in range(3)])
        s.res = nn.Sequential(*[Res(2 * w) for _ in range(3)])
        dch = [2 * w, 2 * w, w, 2]
        s.dec = nn.ModuleList([nn.Conv2d(dch[i], dch[i + 1], 3, 1, 1) for i in range(3)])
        s.dn = nn.ModuleList([nn.InstanceNorm2d(dch[i + 1], affine=True) for i in range(2)])
        s.fc = nn.Linear(200 + 10, 200)
        s.residual = residual

    def forward(s, dem):
        x = dem.permute(0, 3, 1, 2)
        img, ang = x[:, :, :20], x[:, :, 20:]
        h = img
        for c, n in zip(s.enc, s.en):
            h = F.leaky_relu(n(c(h)), 0.2)
        h = s.res(h)
        for i, c in enumerate(s.dec):
            h = c(h)
            if i < 2:
                h = F.leaky_relu(s.dn[i](h), 0.2)
        o = s.fc(torch.cat([h.flatten(1), ang.flatten(1)], 1))
        heights, masks = o[:, :100], o[:, 100:]
        if s.residual:
            heights = (img[:, 0].flatten(1) + 0.1 * heights) * torch.sigmoid(20 * masks)
        out = torch.cat([heights, torch.tanh(masks)], 1).reshape(-1, 2, 20, 5)
        return torch.cat([out, ang], 2).permute(0, 2, 3, 1)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("out")
    ap.add_argument("--width", type=int, default=32)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--arch", choices=["thesis", "residual"], default="thesis")
    a = ap.parse_args()
    # InstanceNorm2d without running stats normalises by the input's own
    # statistics in eval mode too; the exporter warns about it all the same.
    warnings.filterwarnings("ignore", message=".*instance_norm.*")
    warnings.filterwarnings("ignore", category=DeprecationWarning)
    torch.manual_seed(a.seed)
    g = Gen(a.width, a.arch == "residual").eval()
    with torch.no_grad():
        for m in g.modules():
            if isinstance(m, nn.InstanceNorm2d):
                m.weight.uniform_(0.5, 1.5)
                m.bias.uniform_(-0.2, 0.2)
    x = torch.rand(8, 21, 5, 2) * 2 - 1
    kw = dict(input_names=["dem"], output_names=["dem_out"], dynamic_axes={"dem": {0: "N"}, "dem_out": {0: "N"}}, opset_version=17)
    try:
        torch.onnx.export(g, (x,), a.out, dynamo=False, **kw)
    except TypeError:  # torch < 2.5 has no `dynamo` argument
        torch.onnx.export(g, (x,), a.out, **kw)
    print(f"{a.out}: PyTorch {torch.__version__} export, arch {a.arch}, width {a.width}, seed {a.seed}")


if __name__ == "__main__":
    main()
