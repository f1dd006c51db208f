"""Reference Cycle GAN step for 21x5x2 DEMs in PyTorch (CPU), the peer a user
would pick instead of a Rust trainer. Same network as docs/network.md.
Prints training samples/s for one full Cycle GAN + paired step (2 G, 2 D)."""
import sys, time, torch, torch.nn as nn, torch.nn.functional as F

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
        s.fa = nn.Linear(10, 64); s.fo = nn.Linear(128 * 10 + 64, 10)
    def forward(s, x):
        img, ang = x[:, :, :20], x[:, :, 20].flatten(1)
        h = F.leaky_relu(s.c1(same_pad(img, 4, 2)), 0.2)
        h = F.leaky_relu(s.n2(s.c2(same_pad(h, 4, 2))), 0.2)
        h = F.leaky_relu(s.n3(s.c3(same_pad(h, 4, 1))), 0.2)
        a = F.leaky_relu(s.fa(ang), 0.2)
        return torch.sigmoid(s.fo(torch.cat([h.flatten(1), a], 1)))

class Res(nn.Module):
    def __init__(s, c):
        super().__init__(); s.a, s.b = nn.Conv2d(c, c, 3, 1, 1), nn.Conv2d(c, c, 3, 1, 1)
        s.na, s.nb = nn.InstanceNorm2d(c, affine=True), nn.InstanceNorm2d(c, affine=True)
    def forward(s, x):
        return x + s.nb(s.b(F.relu(s.na(s.a(x)))))

class Gen(nn.Module):
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
        for c, n in zip(s.enc, s.en): h = F.leaky_relu(n(c(h)), 0.2)
        h = s.res(h)
        for i, c in enumerate(s.dec):
            h = c(h)
            if i < 2: h = F.leaky_relu(s.dn[i](h), 0.2)
        o = s.fc(torch.cat([h.flatten(1), ang.flatten(1)], 1)).view(-1, 2, 20, 5)
        o = torch.stack([o[:, 0], torch.tanh(o[:, 1])], 1)
        return torch.cat([o, torch.zeros_like(ang).unsqueeze(2)], 2)

GX, GY, DX, DY = Gen(W), Gen(W), Disc(), Disc()
og = torch.optim.Adam(list(GX.parameters()) + list(GY.parameters()), 2e-4, betas=(0.5, 0.999))
od = torch.optim.Adam(list(DX.parameters()) + list(DY.parameters()), 2e-4, betas=(0.5, 0.999))
bce = lambda d, t: F.binary_cross_entropy(d, torch.full_like(d, t))

def step(x, y, yp):
    fy, fx = GY(x), GX(y)
    lg = bce(DY(fy), 0.9) + bce(DX(fx), 0.9) + 10 * ((GX(fy) - x).abs().mean() + (GY(fx) - y).abs().mean())
    lg = lg + ((GY(x) - yp) ** 2).mean()  # paired term (one option per key here)
    og.zero_grad(); lg.backward(); og.step()
    ld = bce(DY(y), 0.9) + bce(DY(fy.detach()), 0.0) + bce(DX(x), 0.9) + bce(DX(fx.detach()), 0.0)
    od.zero_grad(); ld.backward(); od.step()

x, y, yp = torch.randn(B, 2, 21, 5), torch.randn(B, 2, 21, 5), torch.randn(B, 2, 21, 5)
for _ in range(3): step(x, y, yp)
t = time.perf_counter()
for _ in range(STEPS): step(x, y, yp)
dt = time.perf_counter() - t
params = sum(p.numel() for p in GY.parameters())
print(f"torch {torch.__version__} threads={torch.get_num_threads()} width={W} batch={B} G_params={params} samples/s={STEPS * B / dt:.1f}")
